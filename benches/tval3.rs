//! Speed of the TVAL3 reconstruction on the 25 % noisy phantom problem against TVAL3 beta2.4.
//!
//! Run with `cargo bench --bench tval3`. Plain `std::time`, no harness: every figure is the best
//! of a few runs, printed next to the reference solver's (validation/tval3-phantom/README.md).

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use spibench::reconstruction::{
    LinearOperator, PackedOperator, PatternForm, Tval3Options, Tval3Output, tval3,
};

/// TVAL3 beta2.4 on the same data (single-threaded CPU seconds, best of three).
const TVAL3_CPU_S: f64 = 6.53;
const TVAL3_ITERATIONS: usize = 100;
const TVAL3_PRODUCTS: usize = 265;
const TVAL3_PSNR_DB: f64 = 55.90;
const RUNS: usize = 3;

fn read(name: &str) -> Vec<f64> {
    let path = format!(
        "{}/validation/tval3-phantom/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    spibench::report::npy::read(Path::new(&path))
        .expect("reference data")
        .to_f64()
}

fn psnr(u: &[f64], x: &[f64]) -> f64 {
    let mse = u
        .iter()
        .zip(x)
        .map(|(a, b)| (a.clamp(0.0, 255.0) - b).powi(2))
        .sum::<f64>()
        / x.len() as f64;
    10.0 * (255.0 * 255.0 / mse).log10()
}

/// Wall time spent inside the operator, to split the solve into products and the rest.
struct Timed<'a> {
    op: &'a dyn LinearOperator,
    ns: AtomicU64,
}

impl LinearOperator for Timed<'_> {
    fn rows(&self) -> usize {
        self.op.rows()
    }
    fn cols(&self) -> usize {
        self.op.cols()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let t = Instant::now();
        self.op.apply(x, y);
        self.ns
            .fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
    }
    fn apply_adjoint(&self, y: &[f64], x: &mut [f64]) {
        let t = Instant::now();
        self.op.apply_adjoint(y, x);
        self.ns
            .fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
    }
}

/// A plain dense f64 matrix, the baseline: row-wise dot products for A x, row-wise axpy for
/// Aᵀ y, single-threaded, as a BLAS-free dense code would do it.
struct Dense {
    rows: usize,
    cols: usize,
    a: Vec<f64>,
}

impl Dense {
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        for (yr, row) in y.iter_mut().zip(self.a.chunks_exact(self.cols)) {
            // Four partial sums, as any optimised dot product.
            let mut s = [0.0f64; 4];
            for (a, b) in row.chunks_exact(4).zip(x.chunks_exact(4)) {
                for k in 0..4 {
                    s[k] += a[k] * b[k];
                }
            }
            *yr = (s[0] + s[1]) + (s[2] + s[3]);
        }
    }
    fn apply_adjoint(&self, y: &[f64], x: &mut [f64]) {
        x.iter_mut().for_each(|v| *v = 0.0);
        for (&yr, row) in y.iter().zip(self.a.chunks_exact(self.cols)) {
            for (xc, &a) in x.iter_mut().zip(row) {
                *xc += a * yr;
            }
        }
    }
}

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..runs {
        let t = Instant::now();
        let v = f();
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(v);
    }
    (best, last.expect("at least one run"))
}

fn main() {
    let x = read("phantom_x.npy");
    let b = read("phantom_r25_y_noisy.npy");
    let t = Instant::now();
    let patterns = spibench::acquisition::patterns::random(4096, 16384, 0x5EED_0001);
    let t_patterns = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let op = PackedOperator::new(patterns, PatternForm::PlusMinusOne);
    let t_op = t.elapsed().as_secs_f64();
    println!("25 % noisy phantom: A = 4096 × 16384 (±1), image 128 × 128");
    println!(
        "setup: patterns {:.3} s, operator layout (row and column blocks) {:.3} s",
        t_patterns, t_op
    );

    let opts = Tval3Options::reference();
    println!();
    println!(
        "{:<22} {:>8} {:>8} {:>6} {:>9} {:>8} {:>9} {:>8}",
        "solver", "CPU s", "wall s", "iter", "products", "PSNR dB", "ms/prod", "CPU ×"
    );
    println!(
        "{:<22} {:>8.3} {:>8} {:>6} {:>9} {:>8.2} {:>9.1} {:>8}",
        "TVAL3 beta2.4 (1 thr)",
        TVAL3_CPU_S,
        "–",
        TVAL3_ITERATIONS,
        format!("≈{TVAL3_PRODUCTS}"),
        TVAL3_PSNR_DB,
        22.0,
        "1.0"
    );
    let mut products = 0;
    let mut lut_ms = [0.0f64; 2];
    for (k, threads) in [1usize, 2].into_iter().enumerate() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let timed = Timed {
            op: &op,
            ns: AtomicU64::new(0),
        };
        let mut best_cpu = f64::INFINITY;
        let mut best_product_s = f64::INFINITY;
        let (wall, out): (f64, Tval3Output) = best_of(RUNS, || {
            timed.ns.store(0, Ordering::Relaxed);
            let out = pool
                .install(|| tval3(&timed, &b, 128, 128, &opts))
                .expect("valid problem");
            best_cpu = best_cpu.min(out.cpu_time_s);
            best_product_s = best_product_s.min(timed.ns.load(Ordering::Relaxed) as f64 * 1e-9);
            out
        });
        products = out.forward_applications + out.adjoint_applications;
        lut_ms[k] = best_product_s / products as f64 * 1e3;
        println!(
            "{:<22} {:>8.3} {:>8.3} {:>6} {:>9} {:>8.2} {:>9.2} {:>8.1}",
            format!("spibench ({threads} thr)"),
            best_cpu,
            wall,
            out.iterations,
            format!("{}+{}", out.forward_applications, out.adjoint_applications),
            psnr(&out.image.data, &x),
            lut_ms[k],
            TVAL3_CPU_S / best_cpu
        );
        println!(
            "{:<22} products {:.3} s wall ({:.0} %), the rest {:.3} s; {} line-search failures, \
             {} inner loops",
            "",
            best_product_s,
            100.0 * best_product_s / wall,
            wall - best_product_s,
            out.line_search_failures,
            out.outer_iterations
        );
    }

    // Single products, best of many, outside the solver.
    println!();
    let xs: Vec<f64> = x.clone();
    let mut y = vec![0.0; 4096];
    let mut z = vec![0.0; 16384];
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let (f, _) = pool.install(|| best_of(50, || op.apply(&xs, &mut y)));
        let (a, _) = pool.install(|| best_of(50, || op.apply_adjoint(&y, &mut z)));
        println!(
            "LUT kernel, {threads} thread(s): A x {:.3} ms, Aᵀ y {:.3} ms (best of 50)",
            f * 1e3,
            a * 1e3
        );
    }

    // Baseline: the same products with a dense f64 matrix (512 MiB), single-threaded.
    let t = Instant::now();
    let p = op.patterns();
    let mut a = vec![0.0f64; 4096 * 16384];
    for (r, row) in a.chunks_exact_mut(16384).enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = if p.get(r, c) { 1.0 } else { -1.0 };
        }
    }
    let dense = Dense {
        rows: 4096,
        cols: 16384,
        a,
    };
    let t_dense = t.elapsed().as_secs_f64();
    let mut yd = vec![0.0; dense.rows];
    let mut zd = vec![0.0; dense.cols];
    let (df, _) = best_of(5, || dense.apply(&xs, &mut yd));
    let (da, _) = best_of(5, || dense.apply_adjoint(&yd, &mut zd));
    let agree = y
        .iter()
        .zip(&yd)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max);
    println!(
        "dense f64 baseline (1 thread, 512 MiB, built in {t_dense:.2} s): A x {:.2} ms, Aᵀ y {:.2} ms \
         (best of 5); max |LUT − dense| on A x = {agree:.2e}",
        df * 1e3,
        da * 1e3
    );
    let per = 0.5 * (df + da);
    println!(
        "  {} products of this solve: dense {:.2} s, LUT {:.2} s (1 thread) → kernel speed-up {:.1}×",
        products,
        per * products as f64,
        lut_ms[0] * 1e-3 * products as f64,
        per * 1e3 / lut_ms[0]
    );
}
