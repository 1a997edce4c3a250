//! `spibench reconstruct`: TVAL3 on measurements that came from elsewhere. The arrays it reads
//! are checked here; the files it writes are crate::outputs::reconstruct's.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::{Args, ValueEnum};

use crate::error::Error;
use crate::metrics;
use crate::outputs::reconstruct::{ReconstructSummary, range_rule, range_warnings, write};
use crate::raster::Raster;
use crate::reconstruction::tval3::Tval3Options;
use crate::reconstruction::{BitMatrix, PackedOperator, PatternForm, Solver};
use crate::report::npy::{self, NpyData};
use crate::report::output::OutputDir;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormArg {
    /// The measurements are P·x (one detector, one frame per pattern).
    #[value(name = "01")]
    ZeroOne,
    /// The measurements are (2P − 1)·x (a complementary or balanced difference).
    #[value(name = "pm1")]
    PlusMinusOne,
}

#[derive(Debug, Args)]
pub struct ReconstructArgs {
    /// Patterns: an M×N uint8 array of 0/1 values, or numpy.packbits(P, axis=1) bytes
    /// (M×ceil(N/8) uint8, detected from the shape).
    #[arg(long)]
    pub patterns: PathBuf,
    /// Measurements: M float64 values.
    #[arg(long)]
    pub measurements: PathBuf,
    /// Image size WxH in pattern units, N = W·H (row-major vectorisation).
    #[arg(long, value_parser = parse_size)]
    pub size: (usize, usize),
    /// How the patterns enter the measurements.
    #[arg(long, value_enum, default_value = "pm1")]
    pub form: FormArg,
    /// With --form 01: how the 0/1 system is solved.
    #[arg(long, value_enum, default_value = "zero-mean")]
    pub zero_one: super::ZeroOneArg,
    /// Ground truth (an H×W array, or N values) to score PSNR and MSSIM against, on the truth's
    /// own range [min, max] unless --data-range is given.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// With --truth: the range the truth's values are meant to span, LO:HI (for example 0:255
    /// or 0:1), or HI alone for 0:HI. The normalised image is clipped to it; it is PSNR's peak
    /// (HI − LO) and SSIM's dynamic range.
    #[arg(long, value_parser = parse_data_range, requires = "truth")]
    pub data_range: Option<(f64, f64)>,
    /// Output folder. Default: out/reconstruct.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// TVAL3 weight mu of ‖Au − b‖² (default 2^8).
    #[arg(long)]
    pub mu: Option<f64>,
    /// TVAL3 weight beta of ‖Du − w‖² (default 2^5).
    #[arg(long)]
    pub beta: Option<f64>,
    /// Maximum TVAL3 iterations.
    #[arg(long)]
    pub maxit: Option<usize>,
    /// Do not project onto u ≥ 0.
    #[arg(long)]
    pub allow_negative: bool,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

fn parse_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X', '×'])
        .ok_or_else(|| format!("size must be WxH (for example 128x128), got '{s}'"))?;
    let w: usize = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in '{s}'"))?;
    let h: usize = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in '{s}'"))?;
    if w == 0 || h == 0 || w.saturating_mul(h) > crate::scene::experiment::MAX_UNITS {
        return Err(format!(
            "size {w}x{h} must have between 1 and {} units",
            crate::scene::experiment::MAX_UNITS
        ));
    }
    Ok((w, h))
}

fn parse_data_range(s: &str) -> std::result::Result<(f64, f64), String> {
    let num = |t: &str| -> std::result::Result<f64, String> {
        t.trim()
            .parse::<f64>()
            .map_err(|_| format!("'{t}' in --data-range '{s}' is not a number"))
    };
    let (lo, hi) = match s.split_once(':') {
        Some((a, b)) => (num(a)?, num(b)?),
        None => (0.0, num(s)?),
    };
    metrics::DataRange::new(lo, hi).map_err(|e| e.to_string())?;
    Ok((lo, hi))
}

fn load_patterns(path: &Path, n: usize) -> crate::Result<(BitMatrix, &'static str)> {
    // The bit rows made of it: M rows of N bits in 64-bit words.
    let rows = |h: &npy::Header| {
        let m = h.shape.first().copied().unwrap_or(0) as f64;
        (m * (n.div_ceil(64) * 8) as f64, "of bit rows".to_string())
    };
    let arr = npy::read_bounded(path, "the pattern array", rows)?;
    let bad = |msg: String| Error::input(msg).in_file(path);
    if arr.shape.len() != 2 {
        return Err(bad(format!(
            "patterns must be a 2-D array, got shape {:?}",
            arr.shape
        )));
    }
    let (m, cols) = (arr.shape[0], arr.shape[1]);
    let bytes = match &arr.data {
        NpyData::U8(b) | NpyData::Bool(b) => b,
        _ => {
            return Err(bad(format!(
                "patterns must be uint8 (0/1 or packbits), got {}",
                arr.dtype()
            )));
        }
    };
    if m == 0 {
        return Err(bad("the pattern array has no rows".into()));
    }
    if cols == n {
        if let Some(pos) = bytes.iter().position(|&b| b > 1) {
            return Err(bad(format!(
                "a {m}×{n} pattern array must hold 0 and 1 only; element {pos} is {}",
                bytes[pos]
            )));
        }
        Ok((BitMatrix::from_bytes01(m, n, bytes)?, "uint8_01"))
    } else if cols == n.div_ceil(8) {
        Ok((BitMatrix::from_packbits(m, n, bytes)?, "packbits"))
    } else {
        Err(bad(format!(
            "patterns have {cols} columns, but an image of {n} units needs {n} (0/1 bytes) or {} (packbits)",
            n.div_ceil(8)
        )))
    }
}

/// The truth: an H×W array, or the N = W·H values as a vector (one row or column). Any other
/// shape is an input error even when it holds N values: a (4, 8, 8) stack or an 8 × 32 array
/// for a 16 × 16 image is not that image.
fn load_truth(path: &Path, w: usize, h: usize) -> crate::Result<Raster> {
    let shape = npy::read_bounded(path, "the truth array", |_| (0.0, String::new()))?.shape;
    let n = w * h;
    let fits = match shape.as_slice() {
        [k] => *k == n,
        [a, b] => (*a, *b) == (h, w) || (*a, *b) == (1, n) || (*a, *b) == (n, 1),
        _ => false,
    };
    if !fits {
        return Err(Error::input(format!(
            "the truth has shape {shape:?}; an image of --size {w}x{h} needs shape [{h}, {w}] \
             (rows, columns) or [{n}]"
        ))
        .in_file(path));
    }
    Raster::new(w, h, load_vector(path, "truth", false)?)
}

fn load_vector(path: &Path, what: &str, one_d: bool) -> crate::Result<Vec<f64>> {
    let as_f64 = |h: &npy::Header| {
        let n = h.count().map_or(f64::INFINITY, |c| c as f64);
        (8.0 * n, "as float64".to_string())
    };
    let arr = npy::read_bounded(path, &format!("the {what} array"), as_f64)?;
    // Measurements are 1-D, or a column or row (M, 1) / (1, M): a (64, 2) array is not 128
    // measurements. A truth image may be 2-D (its size is checked against --size).
    let vector = match arr.shape.as_slice() {
        [_] => true,
        [a, b] => *a == 1 || *b == 1,
        _ => false,
    };
    if one_d && !vector {
        return Err(Error::input(format!(
            "{what} must be a 1-D array (or one row or column), got shape {:?}",
            arr.shape
        ))
        .in_file(path));
    }
    let v = arr.to_f64();
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(
            Error::input(format!("{what} element {i} is {} (not finite)", v[i])).in_file(path),
        );
    }
    Ok(v)
}

/// A warning when the measurements look like the other `--form`. For a non-negative object,
/// 0/1 patterns with about half the mirrors on give y_i = P_i·x ≈ Σx/2 for every i, a mean far
/// above the spread between measurements, and never a negative value; ±1 patterns give
/// y_i = (2P_i − 1)·x, which scatters around 0 (random patterns: mean ≈ 0, spread ≈ ‖x‖;
/// Hadamard rows other than the first sum to 0). A mean above 3 standard deviations with
/// every y ≥ 0 is taken as 0/1 data, a mean below one standard deviation with a tenth or more
/// of the values negative as ±1 data.
pub fn form_hint(y: &[f64], form: PatternForm) -> Option<String> {
    if y.len() < 8 {
        return None;
    }
    let n = y.len() as f64;
    let mean = y.iter().sum::<f64>() / n;
    let sd = (y.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0)).sqrt();
    let negative = y.iter().filter(|v| **v < 0.0).count() as f64 / n;
    match form {
        PatternForm::PlusMinusOne if negative == 0.0 && mean > 3.0 * sd => Some(format!(
            "the measurements look like 0/1 data (all ≥ 0, mean {mean:.4e} = {:.1} standard \
             deviations): if they are P·x, pass --form 01",
            mean / sd.max(f64::MIN_POSITIVE)
        )),
        PatternForm::ZeroOne if negative >= 0.1 && mean.abs() < sd => Some(format!(
            "{:.0} % of the measurements are negative and their mean is within one standard \
             deviation of 0, as (2P − 1)·x data are: if they are, pass --form pm1",
            100.0 * negative
        )),
        _ => None,
    }
}

pub fn run(args: &ReconstructArgs) -> Result<()> {
    let (w, h) = args.size;
    let n = w * h;
    let (patterns, encoding) = load_patterns(&args.patterns, n)?;
    let y = load_vector(&args.measurements, "measurement", true)?;
    if y.len() != patterns.rows() {
        return Err(Error::input(format!(
            "{} measurements for {} patterns: the counts must match",
            y.len(),
            patterns.rows()
        ))
        .in_file(&args.measurements)
        .into());
    }
    let truth = match &args.truth {
        None => None,
        Some(p) => Some(load_truth(p, w, h)?),
    };
    let range = match (&truth, args.data_range) {
        (None, _) => None,
        (Some(_), Some((lo, hi))) => Some((metrics::DataRange::new(lo, hi)?, "--data-range")),
        (Some(t), None) => Some((
            metrics::DataRange::of(t)
                .map_err(|e| e.in_file(args.truth.as_deref().unwrap_or(Path::new("truth"))))?,
            "truth",
        )),
    };

    let mut opts = Tval3Options::reference();
    if let Some(mu) = args.mu {
        opts.mu = mu;
    }
    if let Some(beta) = args.beta {
        opts.beta = beta;
    }
    if let Some(maxit) = args.maxit {
        opts.maxit = maxit;
    }
    opts.nonneg = !args.allow_negative;
    let form = match args.form {
        FormArg::ZeroOne => PatternForm::ZeroOne,
        FormArg::PlusMinusOne => PatternForm::PlusMinusOne,
    };
    if let Some(hint) = form_hint(&y, form) {
        eprintln!("warning: {hint}");
    }
    let out = OutputDir::create(args.out.as_deref().unwrap_or(Path::new("out/reconstruct")))?;
    let solver = Solver::new(opts, args.zero_one.into());
    let op = PackedOperator::new(patterns, form);
    let sol = solver.solve(&op, &y, w, h, form)?;

    let scores = match (&truth, range) {
        (Some(t), Some((r, _))) => {
            for warning in range_warnings(t, &sol.image, r) {
                eprintln!("warning: {warning}");
            }
            Some(metrics::score_in(t, &sol.image, r)?)
        }
        _ => None,
    };
    let (psnr_db, mssim) = (
        scores.as_ref().map(|s| s.psnr_db),
        scores.as_ref().map(|s| s.mssim),
    );

    let summary = ReconstructSummary {
        command: "reconstruct",
        spibench_version: env!("CARGO_PKG_VERSION"),
        width: w,
        height: h,
        measurements: y.len(),
        units: n,
        form: match form {
            PatternForm::ZeroOne => "01",
            PatternForm::PlusMinusOne => "pm1",
        },
        patterns_encoding: encoding,
        zero_one_handling: (form == PatternForm::ZeroOne).then(|| solver.zero_one.name()),
        iterations: sol.iterations,
        forward_applications: sol.forward_applications,
        adjoint_applications: sol.adjoint_applications,
        converged: sol.converged,
        stop: sol.stop,
        relative_residual: sol.relative_residual,
        time_s: sol.cpu_time_s,
        psnr_db,
        data_range: range.map(|r| r.0),
        data_range_from: range.map(|r| r.1),
        mssim,
        normalization: range.map(|(r, _)| range_rule(r)),
        solver: solver.tval3.clone(),
    };
    let mut provenance = crate::provenance::Provenance::new(&[])
        .file(&args.patterns)?
        .file(&args.measurements)?;
    if let Some(t) = &args.truth {
        provenance = provenance.file(t)?;
    }
    write(&sol.image, &summary, &provenance, &out)?;
    let dir = out.commit()?;
    println!(
        "reconstructed {w}x{h} from {} measurements: {} iterations, {} + {} operator applications, {:.2} s; stopped because {}",
        y.len(),
        sol.iterations,
        sol.forward_applications,
        sol.adjoint_applications,
        sol.cpu_time_s,
        sol.stop.describe(&solver.tval3)
    );
    if let (Some(p), Some(s), Some((r, from))) = (psnr_db, mssim, range) {
        let from = if from == "truth" {
            "the truth's own min and max"
        } else {
            "--data-range"
        };
        println!(
            "PSNR {p:.2} dB, MSSIM {s:.4} (after normalisation; data range [{}, {}] from {from})",
            r.lo, r.hi
        );
    }
    println!("wrote {}", dir.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warns_when_the_data_look_like_the_other_form() {
        // 0/1 patterns on a positive object: every y near Σx/2.
        let zero_one: Vec<f64> = (0..64).map(|i| 100.0 + (i % 7) as f64).collect();
        assert!(form_hint(&zero_one, PatternForm::PlusMinusOne).is_some());
        assert!(form_hint(&zero_one, PatternForm::ZeroOne).is_none());
        // ±1 data scatter around 0.
        let pm: Vec<f64> = (0..64)
            .map(|i| ((i * 37 % 17) as f64 - 8.0) * 3.0)
            .collect();
        assert!(form_hint(&pm, PatternForm::PlusMinusOne).is_none());
        assert!(form_hint(&pm, PatternForm::ZeroOne).is_some());
    }
}
