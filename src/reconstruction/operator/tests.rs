use super::*;
use crate::rng::SplitMix64;

/// A reproducible pseudo-random 0/1 matrix (density about 1/2).
fn random_bits(rows: usize, cols: usize, seed: u64) -> BitMatrix {
    let mut m = BitMatrix::zeros(rows, cols);
    let mut g = SplitMix64::new(seed);
    for r in 0..rows {
        for c in 0..cols {
            if g.next_u64() >> 63 == 1 {
                m.set(r, c, true);
            }
        }
    }
    m
}

/// Reproducible values in [−1, 1).
fn random_vec(n: usize, seed: u64) -> Vec<f64> {
    let mut g = SplitMix64::new(seed);
    (0..n)
        .map(|_| (g.next_u64() >> 11) as f64 / (1u64 << 52) as f64 - 1.0)
        .collect()
}

/// The row layout, built a block at a time, equals the layout's definition byte by byte:
/// byte (row r, group g) at `index(r, g)` holds columns 8g .. 8g + 7 of row r. Widths
/// below, at and above one block, and not a multiple of 8.
#[test]
fn row_layout_matches_its_definition() {
    for (rows, cols) in [(3, 5), (7, 128), (9, 129), (33, 8 * BLOCK_GROUPS * 3 + 13)] {
        let m = random_bits(rows, cols, 11 + cols as u64);
        let b = ByteBlocks::from_rows(&m);
        assert_eq!(b.bytes.len(), rows * cols.div_ceil(8));
        for r in 0..rows {
            for g in 0..cols.div_ceil(8) {
                let want = (0..8)
                    .filter(|&k| 8 * g + k < cols && m.get(r, 8 * g + k))
                    .fold(0u8, |acc, k| acc | (1 << k));
                assert_eq!(
                    b.bytes[b.index(r, g)],
                    want,
                    "{rows}x{cols} row {r} group {g}"
                );
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

/// The simple reference: iterate the set bits of every row (no tables, no blocking).
fn reference_apply(p: &BitMatrix, form: PatternForm, x: &[f64]) -> Vec<f64> {
    let total: f64 = x.iter().sum();
    (0..p.rows())
        .map(|r| {
            let mut s = 0.0;
            for (wi, &w) in p.row_words(r).iter().enumerate() {
                let mut bits = w;
                while bits != 0 {
                    s += x[wi * 64 + bits.trailing_zeros() as usize];
                    bits &= bits - 1;
                }
            }
            match form {
                PatternForm::ZeroOne => s,
                PatternForm::PlusMinusOne => 2.0 * s - total,
            }
        })
        .collect()
}

fn reference_adjoint(p: &BitMatrix, form: PatternForm, y: &[f64]) -> Vec<f64> {
    let mut x = vec![0.0; p.cols()];
    for (r, &yr) in y.iter().enumerate() {
        for (wi, &w) in p.row_words(r).iter().enumerate() {
            let mut bits = w;
            while bits != 0 {
                x[wi * 64 + bits.trailing_zeros() as usize] += yr;
                bits &= bits - 1;
            }
        }
    }
    let ysum: f64 = y.iter().sum();
    if form == PatternForm::PlusMinusOne {
        x.iter_mut().for_each(|v| *v = 2.0 * *v - ysum);
    }
    x
}

/// Shapes that exercise a short last byte group, a short last block, fewer rows than one
/// table group and exact multiples of 64.
const SHAPES: [(usize, usize); 7] = [
    (1, 1),
    (3, 5),
    (7, 64),
    (13, 100),
    (64, 129),
    (130, 200),
    (257, 1031),
];
const FORMS: [PatternForm; 2] = [PatternForm::ZeroOne, PatternForm::PlusMinusOne];

#[test]
fn transpose8_transposes() {
    let mut g = SplitMix64::new(7);
    for _ in 0..100 {
        let x = g.next_u64();
        let t = transpose8(x);
        for i in 0..8 {
            for j in 0..8 {
                assert_eq!((x >> (8 * i + j)) & 1, (t >> (8 * j + i)) & 1);
            }
        }
    }
}

#[test]
fn packed_adjoint_satisfies_dot_product_identity() {
    // <A x, y> = <x, Aᵀ y> holds exactly in real arithmetic; in floating point both sides
    // carry rounding of order eps · Σ|A_ij x_j y_i| ≤ eps · ||x||_1 ||y||_1, far below 1e-12
    // of that scale for these sizes.
    for (k, &(rows, cols)) in SHAPES.iter().enumerate() {
        let p = random_bits(rows, cols, 100 + k as u64);
        let x = random_vec(cols, 200 + k as u64);
        let y = random_vec(rows, 300 + k as u64);
        for form in FORMS {
            let op = PackedOperator::new(p.clone(), form);
            let mut ax = vec![0.0; rows];
            let mut aty = vec![0.0; cols];
            op.apply(&x, &mut ax);
            op.apply_adjoint(&y, &mut aty);
            let scale: f64 =
                x.iter().map(|v| v.abs()).sum::<f64>() * y.iter().map(|v| v.abs()).sum::<f64>();
            let (l, r) = (dot(&ax, &y), dot(&x, &aty));
            assert!(
                (l - r).abs() <= 1e-12 * scale,
                "{rows}×{cols} {form:?}: {l} vs {r}"
            );
        }
    }
}

#[test]
fn packed_kernels_match_bit_iteration() {
    for (k, &(rows, cols)) in SHAPES.iter().enumerate() {
        let p = random_bits(rows, cols, 400 + k as u64);
        let x = random_vec(cols, 500 + k as u64);
        let y = random_vec(rows, 600 + k as u64);
        for form in FORMS {
            let op = PackedOperator::new(p.clone(), form);
            let mut ax = vec![f64::NAN; rows];
            let mut aty = vec![f64::NAN; cols];
            op.apply(&x, &mut ax);
            op.apply_adjoint(&y, &mut aty);
            let ax_ref = reference_apply(&p, form, &x);
            let aty_ref = reference_adjoint(&p, form, &y);
            // Both are sums of the same terms in different orders: the difference is rounding,
            // of order eps · sqrt(terms) relative, so 1e-12 of the norm has a wide margin
            // while any wrong bit (an entry of size ~1) would show as ~1/||Ax|| ≥ 1e-3.
            let e1 = norm(
                &ax.iter()
                    .zip(&ax_ref)
                    .map(|(a, b)| a - b)
                    .collect::<Vec<_>>(),
            );
            let e2 = norm(
                &aty.iter()
                    .zip(&aty_ref)
                    .map(|(a, b)| a - b)
                    .collect::<Vec<_>>(),
            );
            assert!(
                e1 <= 1e-12 * norm(&ax_ref),
                "{rows}×{cols} {form:?} forward {e1}"
            );
            assert!(
                e2 <= 1e-12 * norm(&aty_ref),
                "{rows}×{cols} {form:?} adjoint {e2}"
            );
        }
    }
}

#[test]
fn packed_products_are_bit_identical_on_one_and_two_threads() {
    let (rows, cols) = (301, 1000);
    let p = random_bits(rows, cols, 11);
    let x = random_vec(cols, 12);
    let y = random_vec(rows, 13);
    for form in FORMS {
        let op = PackedOperator::new(p.clone(), form);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            pool.install(|| {
                let mut ax = vec![0.0; rows];
                let mut aty = vec![0.0; cols];
                op.apply(&x, &mut ax);
                op.apply_adjoint(&y, &mut aty);
                (ax, aty)
            })
        };
        let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        let (a1, t1) = run(1);
        for threads in [2, 3] {
            let (a2, t2) = run(threads);
            assert_eq!(bits(&a1), bits(&a2), "{form:?} forward, {threads} threads");
            assert_eq!(bits(&t1), bits(&t2), "{form:?} adjoint, {threads} threads");
        }
    }
}

/// The explicit Sylvester matrix entry.
fn h(i: usize, j: usize) -> f64 {
    if (i & j).count_ones().is_multiple_of(2) {
        1.0
    } else {
        -1.0
    }
}

#[test]
fn fwht_equals_the_explicit_sylvester_product() {
    let mut n = 1;
    while n <= 1024 {
        let x = random_vec(n, n as u64);
        let mut t = x.clone();
        fwht(&mut t);
        for (i, &ti) in t.iter().enumerate() {
            let direct: f64 = x.iter().enumerate().map(|(j, &xj)| h(i, j) * xj).sum();
            // Sums of n terms of size ≤ 1: rounding ≤ n · log2(n) · eps.
            assert!((ti - direct).abs() <= 1e-12 * n as f64, "n = {n}, row {i}");
        }
        n *= 2;
    }
}

#[test]
fn hadamard_operator_matches_explicit_rows_and_its_adjoint() {
    let order = 256;
    let rows: Vec<usize> = vec![0, 3, 17, 255, 128, 64, 77];
    let x = random_vec(order, 21);
    let y = random_vec(rows.len(), 22);
    for form in FORMS {
        let op = HadamardOperator::new(order, rows.clone(), form);
        let entry = |r: usize, j: usize| match form {
            PatternForm::PlusMinusOne => h(rows[r], j),
            PatternForm::ZeroOne => 0.5 * (1.0 + h(rows[r], j)),
        };
        let mut ax = vec![0.0; rows.len()];
        let mut aty = vec![0.0; order];
        op.apply(&x, &mut ax);
        op.apply_adjoint(&y, &mut aty);
        for (r, &v) in ax.iter().enumerate() {
            let direct: f64 = (0..order).map(|j| entry(r, j) * x[j]).sum();
            assert!(
                (v - direct).abs() <= 1e-12 * order as f64,
                "{form:?} row {r}"
            );
        }
        for (j, &v) in aty.iter().enumerate() {
            let direct: f64 = (0..rows.len()).map(|r| entry(r, j) * y[r]).sum();
            assert!(
                (v - direct).abs() <= 1e-12 * order as f64,
                "{form:?} column {j}"
            );
        }
        let scale: f64 =
            x.iter().map(|v| v.abs()).sum::<f64>() * y.iter().map(|v| v.abs()).sum::<f64>();
        assert!((dot(&ax, &y) - dot(&x, &aty)).abs() <= 1e-12 * scale);
    }
}

#[test]
fn reproduces_the_tval3_reference_measurements() {
    // The reference y = (2P − 1) x of validation/tval3-phantom was computed in float64 by
    // NumPy from the SplitMix64 patterns; matching it to 1e-9 proves the pattern convention
    // (bit order, row-major flattening, seed) and the ±1 form. A single wrong bit in a row
    // would change that element by 2·x_j, up to 510, about 5 % of a typical |y|.
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/validation/tval3-phantom/");
    let read = |name: &str| {
        crate::report::npy::read(std::path::Path::new(&format!("{dir}{name}")))
            .expect("reference data")
            .to_f64()
    };
    let x = read("phantom_x.npy");
    let y_ref = read("phantom_r25_y.npy");
    let p = crate::acquisition::patterns::random(4096, 16384, 0x5EED_0001);
    let op = PackedOperator::new(p, PatternForm::PlusMinusOne);
    let mut y = vec![0.0; 4096];
    op.apply(&x, &mut y);
    let err = norm(&y.iter().zip(&y_ref).map(|(a, b)| a - b).collect::<Vec<_>>());
    assert!(
        err <= 1e-9 * norm(&y_ref),
        "relative error {}",
        err / norm(&y_ref)
    );
    let worst = y
        .iter()
        .zip(&y_ref)
        .map(|(a, b)| (a - b).abs() / b.abs().max(1.0))
        .fold(0.0, f64::max);
    assert!(worst <= 1e-9, "worst element relative error {worst}");
}
