//! Experiment files for `spibench simulate`: the paper's idealised simulations (scalar k±, b±,
//! additive noise, no optics).
//!
//! An experiment is the Cartesian product objects × sampling ratios × cases, where a case is one
//! acquisition scheme with its arm gains, offsets and noise. Each product cell is simulated,
//! reconstructed and scored; a montage and curves summarise the grid the way the paper's figures
//! do. Values are in the object's units (grey levels 0–255 per unit), so k± are dimensionless
//! and b± and noise standard deviations are in grey-level sums, as in the paper's Eqs. (6)–(9).
//!
//! ```ron
//! Experiment(
//!     title: "Fig. 1",
//!     width: 128, height: 128,
//!     objects: [(name: "phantom", object: Phantom)],
//!     sampling_ratios: [0.25],
//!     cases: [(label: "SCB", scheme: SecondaryComplementaryBalancing,
//!              arms: (k_plus: 1.01, k_minus: 1.02, b_plus: 1, b_minus: 5))],
//! )
//! ```

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::acquisition::{AdditiveNoise, HadamardOrdering, ScalarArms, Scheme};
use crate::error::{Error, Result};
use crate::objects::ObjectSpec;
use crate::reconstruction::ZeroOneHandling;
use crate::reconstruction::tval3::Tval3Options;
use crate::scene::locate;
use crate::scene::numbers::{Count, Positive, checked, via};

/// An image side in pattern units (the product of the two is checked against [`MAX_UNITS`]).
pub type Side = Count<1, { MAX_UNITS as u64 }>;

checked!(
    /// A DMD pattern rate (Hz): positive and at most [`MAX_DMD_RATE_HZ`].
    DmdRateHz,
    above 0.0,
    at_most MAX_DMD_RATE_HZ,
    |v| format!("the DMD rate must be positive and at most {MAX_DMD_RATE_HZ:e} Hz, got {v:e}")
);

checked!(
    /// An arm gain k± (dimensionless): positive and at most [`MAX_ARM_GAIN`].
    ArmGain,
    above 0.0,
    at_most MAX_ARM_GAIN,
    |v| format!("an arm gain must be finite, > 0 and at most {MAX_ARM_GAIN:e}, got {v:e}")
);

checked!(
    /// An arm offset b± (grey levels summed over units): within ±[`MAX_ARM_OFFSET`].
    ArmOffset,
    |v| v.abs() <= MAX_ARM_OFFSET,
    |v| format!("an arm offset must lie within ±{MAX_ARM_OFFSET:e} grey levels, got {v:e}")
);

/// The largest image an experiment may ask for, in pattern units (a 1024×1024 grid: the whole
/// DMD at one mirror per unit). Larger grids are almost certainly a typing error.
pub const MAX_UNITS: usize = 1 << 20;

/// The largest arm gain k± (dimensionless; the paper's are near 1).
pub const MAX_ARM_GAIN: f64 = 1e3;

/// The largest |b±| and noise standard deviation, in grey levels summed over units: far above
/// the largest possible signal (255 × 2²⁰ ≈ 2.7e8), and far from overflowing when squared.
pub const MAX_ARM_OFFSET: f64 = 1e12;

/// The largest DMD pattern rate, Hz (DMDs reach a few tens of kHz).
pub const MAX_DMD_RATE_HZ: f64 = 1e6;

/// The most TVAL3 outer iterations and inner-loop restarts an experiment may ask for.
pub const MAX_SOLVER_ITERATIONS: usize = 1_000_000;

/// The file as written. Every field is documented because the file is the user interface.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, rename = "Experiment")]
pub struct ExperimentFile {
    /// Shown on plots and montages.
    pub title: String,
    /// Image width in pattern units (pixels of the reconstruction).
    #[serde(deserialize_with = "via::<Side, _, _>")]
    pub width: usize,
    /// Image height in pattern units.
    #[serde(deserialize_with = "via::<Side, _, _>")]
    pub height: usize,
    /// The objects, each with a short name used in file names.
    pub objects: Vec<ObjectEntry>,
    /// The base patterns; random 0/1 by default.
    #[serde(default)]
    pub patterns: PatternsSpec,
    /// Sampling ratios M/N, each in (0, 1] (M base patterns for N units).
    pub sampling_ratios: Vec<Ratio>,
    /// The acquisition cases (scheme, arms, noise).
    pub cases: Vec<CaseSpec>,
    /// TVAL3 options; unset fields take TVAL3's defaults.
    #[serde(default)]
    pub solver: Tval3Options,
    /// How traditional (0/1) measurements are solved: `ZeroMean` (the default, the exactly
    /// equivalent zero-mean system, which converges like the ±1 schemes) or `Plain` (A = P as
    /// measured, the paper's handling). The ±1 schemes are not affected.
    #[serde(default)]
    pub zero_one: ZeroOneHandling,
    /// DMD binary pattern rate used for acquisition times, Hz (22 727 Hz = 44 µs frames).
    #[serde(
        default = "default_dmd_rate",
        deserialize_with = "via::<DmdRateHz, _, _>"
    )]
    pub dmd_rate_hz: f64,
    /// Seed of the noise streams (one stream per cell).
    #[serde(default)]
    pub seed: u64,
    /// How the reconstructions are laid out in `montage.png`.
    #[serde(default)]
    pub montage: Option<MontageSpec>,
    /// Curves to plot (mean and standard deviation over objects).
    #[serde(default)]
    pub curves: Vec<CurveSpec>,
}

fn default_dmd_rate() -> f64 {
    crate::acquisition::DEFAULT_DMD_RATE_HZ
}

/// A sampling ratio in (0, 1], validated while parsing so that errors carry line and column.
pub use crate::scene::numbers::Ratio;

/// One object of an experiment.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectEntry {
    /// Short name, used in file names and tables (letters, digits, `-` and `_`).
    pub name: String,
    /// The object itself (an image file, a test image, a phantom, a USAF chart, …).
    pub object: ObjectSpec,
}

/// The base patterns of an acquisition.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub enum PatternsSpec {
    /// Random 0/1 patterns from a seeded SplitMix64 sequence; the same patterns serve every
    /// case of an object, so cases differ only by scheme, arms and noise.
    Random {
        /// Seed of the pattern sequence (default 1).
        seed: u64,
    },
    /// Sylvester Hadamard patterns (2^m × 2^m images only) in the given ordering.
    Hadamard {
        /// The order of the Hadamard rows.
        ordering: HadamardOrdering,
    },
}

impl Default for PatternsSpec {
    fn default() -> Self {
        PatternsSpec::Random { seed: 1 }
    }
}

impl PatternsSpec {
    /// The pattern family it names.
    pub fn family(&self) -> crate::acquisition::PatternFamily {
        match *self {
            PatternsSpec::Random { seed } => crate::acquisition::PatternFamily::Random { seed },
            PatternsSpec::Hadamard { ordering } => {
                crate::acquisition::PatternFamily::Hadamard { ordering }
            }
        }
    }
}

/// One acquisition case.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseSpec {
    /// Label on montages, curves and in summary.json.
    pub label: String,
    /// The acquisition scheme (the paper's four and the fairer baselines).
    pub scheme: Scheme,
    /// Arm gains and offsets (Eqs. 6–9); ideal arms by default.
    #[serde(default)]
    pub arms: ArmsSpec,
    /// Additive noise on every recorded detector sample; none by default.
    #[serde(default)]
    pub noise: Option<NoiseSpec>,
}

/// k± (dimensionless) and b± (object units) of the two arms, validated while parsing so that
/// an error points at the case that holds it.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(try_from = "ArmsFields")]
pub struct ArmsSpec(pub ScalarArms);

/// The arms as written: every field optional, ideal arms by default.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmsFields {
    /// Gain k₊ of arm + (dimensionless; 1 for an ideal arm).
    #[serde(deserialize_with = "via::<ArmGain, _, _>")]
    pub k_plus: f64,
    /// Gain k₋ of arm −.
    #[serde(deserialize_with = "via::<ArmGain, _, _>")]
    pub k_minus: f64,
    /// Offset b₊ of arm + (grey levels summed over units; 0 for an ideal arm).
    #[serde(deserialize_with = "via::<ArmOffset, _, _>")]
    pub b_plus: f64,
    /// Offset b₋ of arm −.
    #[serde(deserialize_with = "via::<ArmOffset, _, _>")]
    pub b_minus: f64,
}

impl Default for ArmsFields {
    fn default() -> Self {
        ArmsFields {
            k_plus: 1.0,
            k_minus: 1.0,
            b_plus: 0.0,
            b_minus: 0.0,
        }
    }
}

impl Default for ArmsSpec {
    fn default() -> Self {
        ArmsSpec(ScalarArms::ideal())
    }
}

impl TryFrom<ArmsFields> for ArmsSpec {
    type Error = String;
    fn try_from(a: ArmsFields) -> std::result::Result<Self, String> {
        let arms = ScalarArms {
            k_plus: a.k_plus,
            k_minus: a.k_minus,
            b_plus: a.b_plus,
            b_minus: a.b_minus,
        };
        arms.validate().map_err(|e| e.to_string())?;
        for (name, k) in [("k_plus", a.k_plus), ("k_minus", a.k_minus)] {
            if k > MAX_ARM_GAIN {
                return Err(format!(
                    "field `{name}`: an arm gain must be at most {MAX_ARM_GAIN:e}, got {k:e}"
                ));
            }
        }
        for (name, b) in [("b_plus", a.b_plus), ("b_minus", a.b_minus)] {
            if b.abs() > MAX_ARM_OFFSET {
                return Err(format!(
                    "field `{name}`: an arm offset must lie within ±{MAX_ARM_OFFSET:e} grey levels, got {b:e}"
                ));
            }
        }
        Ok(ArmsSpec(arms))
    }
}

/// Additive noise on every recorded detector sample, validated while parsing.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, serde::Serialize)]
#[serde(try_from = "AdditiveNoise", into = "AdditiveNoise")]
pub struct NoiseSpec(pub AdditiveNoise);

impl From<NoiseSpec> for AdditiveNoise {
    fn from(v: NoiseSpec) -> AdditiveNoise {
        v.0
    }
}

impl TryFrom<AdditiveNoise> for NoiseSpec {
    type Error = String;
    fn try_from(n: AdditiveNoise) -> std::result::Result<Self, String> {
        n.validate().map_err(|e| e.to_string())?;
        if n.std > MAX_ARM_OFFSET {
            return Err(format!(
                "field `std`: the noise standard deviation must be at most {MAX_ARM_OFFSET:e} grey levels, got {:e}",
                n.std
            ));
        }
        Ok(NoiseSpec(n))
    }
}

/// A dimension of the experiment's grid, laid out along a montage's rows or columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
pub enum Axis {
    /// One row or column per object.
    Object,
    /// One per acquisition case.
    Case,
    /// One per sampling ratio.
    Ratio,
}

/// The layout of `montage.png`: which dimension runs down and which across (the third is
/// repeated in blocks).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MontageSpec {
    /// The dimension along the rows.
    pub rows: Axis,
    /// The dimension along the columns.
    pub columns: Axis,
    /// Side of one tile in screen pixels.
    #[serde(
        default = "default_tile_px",
        deserialize_with = "via::<Count<1, 1024>, _, _>"
    )]
    pub tile_px: u32,
}

fn default_tile_px() -> u32 {
    128
}

/// The x axis of a curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
pub enum CurveX {
    /// Sampling ratio M/N.
    Ratio,
    /// k' = k₊ + k₋ of the case.
    KPrime,
}

/// An image-quality score of a reconstruction against its object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
pub enum Metric {
    /// Peak signal-to-noise ratio (dB).
    Psnr,
    /// Mean structural similarity (Wang et al. 2004), in [−1, 1].
    Mssim,
}

/// One plot: the metric against x, one series per scheme, mean ± standard deviation over the
/// objects, using only the cells at the given ratio or k' when those are set.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurveSpec {
    /// File stem of the plot (`NAME.svg`, `NAME.png`).
    pub name: String,
    /// What runs along x.
    pub x: CurveX,
    /// What runs along y.
    pub metric: Metric,
    /// Only the cells at this sampling ratio (for curves against k').
    #[serde(default, deserialize_with = "via::<Option<Ratio>, _, _>")]
    pub at_ratio: Option<f64>,
    /// Only the cases with this k' = k₊ + k₋ (for curves against the ratio).
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    pub at_k_prime: Option<f64>,
    /// Plot x on a logarithmic axis.
    #[serde(default)]
    pub log_x: bool,
}

/// A validated experiment: every field checked, ready to run.
#[derive(Debug, Clone)]
pub struct Experiment {
    pub title: String,
    pub width: usize,
    pub height: usize,
    pub objects: Vec<ObjectEntry>,
    pub patterns: PatternsSpec,
    pub sampling_ratios: Vec<f64>,
    pub cases: Vec<Case>,
    pub solver: Tval3Options,
    pub zero_one: ZeroOneHandling,
    pub dmd_rate_hz: f64,
    pub seed: u64,
    pub montage: Option<MontageSpec>,
    pub curves: Vec<CurveSpec>,
    /// Folder that relative object paths resolve against.
    pub base_dir: PathBuf,
    /// The file (or `<built-in NAME>`) and its text, to locate errors found later.
    pub source_path: PathBuf,
    pub source_text: String,
}

impl Experiment {
    /// Gives an input error found after validation (rendering an object, say) the experiment's
    /// file and the line and column of its field.
    pub fn locate(&self, e: Error) -> Error {
        locate(e, &self.source_text, &self.source_path)
    }
}

#[derive(Debug, Clone)]
pub struct Case {
    pub label: String,
    pub scheme: Scheme,
    pub arms: ScalarArms,
    pub noise: Option<AdditiveNoise>,
}

/// The experiments shipped with spibench, one per figure of the paper's simulation section.
pub const BUILT_IN: &[(&str, &str)] = &[
    ("fig1", include_str!("../../scenes/fig1.ron")),
    ("fig2", include_str!("../../scenes/fig2.ron")),
    ("fig3", include_str!("../../scenes/fig3.ron")),
    ("fig4", include_str!("../../scenes/fig4.ron")),
];

/// Loads an experiment from a file, or a built-in one by name (`fig1` … `fig4`).
pub fn load(name_or_path: &str) -> Result<Experiment> {
    let path = Path::new(name_or_path);
    // A built-in name wins only when no file of that name exists. Built-ins use embedded test
    // images, so relative paths in them (there are none) would resolve against the working folder.
    if !path.exists()
        && let Some((name, text)) = BUILT_IN.iter().find(|(n, _)| *n == name_or_path)
    {
        return parse(
            text,
            &PathBuf::from(format!("<built-in {name}>")),
            Path::new("."),
        );
    }
    let text = super::read_text(path).map_err(|e| {
        let Error::Io { source: e, .. } = e else {
            return e;
        };
        let names: Vec<&str> = BUILT_IN.iter().map(|(n, _)| *n).collect();
        match e.kind() {
            std::io::ErrorKind::NotFound => Error::input(format!(
                "no experiment file {} (built-in experiments: {})",
                path.display(),
                names.join(", ")
            )),
            _ => Error::read(path, e),
        }
    })?;
    let base = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    parse(&text, path, base)
}

/// Parses and validates experiment text; `path` names it in errors, `base_dir` resolves files.
pub fn parse(text: &str, path: &Path, base_dir: &Path) -> Result<Experiment> {
    let file: ExperimentFile = super::parse_ron(text, path)?;
    let mut exp = validate(file, base_dir).map_err(|e| locate(e, text, path))?;
    exp.source_path = path.to_path_buf();
    exp.source_text = text.to_string();
    Ok(exp)
}

/// Adds the file and, for a named field, the line and column where that field (by its full
/// path, `cases[1].label`) is written; a field left at its default is located at the nearest
/// enclosing field that is written.
fn locate(e: Error, text: &str, path: &Path) -> Error {
    let e = image_file_into_message(e, path).in_file(path);
    let field = match &e {
        Error::Input { location, .. } if location.line.is_none() => location.field.clone(),
        _ => None,
    };
    if let Some(field) = field {
        let mut probe = field.as_str();
        loop {
            if let Some(pos) = locate::find_path(text, probe) {
                return locate::at(e, text, Some(pos));
            }
            // Up one level: `a.b[2].c` → `a.b[2]` → `a.b` → `a`.
            match probe.rfind(['.', '[']) {
                Some(i) => probe = &probe[..i],
                None => break,
            }
        }
        let top = field.split(['[', '.']).next().unwrap_or(&field);
        if let Some(pos) = locate::find_path(text, top) {
            return locate::at(e, text, Some(pos));
        }
        // A field not written at all: the top of the file.
        return e.at_line(1, 1);
    }
    e
}

/// An error about a field of the experiment that names another file (an object's image that
/// cannot be decoded): the file goes into the message, so that the location (the experiment's
/// file, line and field) is the experiment's and the image is named after it, not before a line
/// of the experiment.
fn image_file_into_message(e: Error, path: &Path) -> Error {
    match e {
        Error::Input {
            mut location,
            message,
        } if location.field.is_some() && location.file.as_deref().is_some_and(|f| f != path) => {
            let other = location.file.take().unwrap_or_default();
            Error::Input {
                location,
                message: format!("{}: {message}", other.display()),
            }
        }
        e => e,
    }
}

/// A curve's `at_ratio` must be one of the sampling ratios and its `at_k_prime` the k' of a case
/// (as `simulation::curve` matches them): otherwise the curve has no point, and the plot failed
/// after the whole simulation, naming a file of the output folder.
fn check_curves(f: &ExperimentFile) -> Result<()> {
    const MATCH: f64 = 1e-9;
    for (i, c) in f.curves.iter().enumerate() {
        if let Some(r) = c.at_ratio
            && !f.sampling_ratios.iter().any(|s| (s.0 - r).abs() < MATCH)
        {
            return Err(Error::field(
                format!("curves[{i}].at_ratio"),
                format!("{r} is not one of the sampling ratios: the curve would have no point"),
            ));
        }
        if let Some(k) = c.at_k_prime
            && !f
                .cases
                .iter()
                .any(|cs| (cs.arms.0.k_plus + cs.arms.0.k_minus - k).abs() < MATCH)
        {
            return Err(Error::field(
                format!("curves[{i}].at_k_prime"),
                format!("{k} is not the k' = k₊ + k₋ of any case: the curve would have no point"),
            ));
        }
    }
    Ok(())
}

/// Random patterns for the highest sampling ratio must fit the pattern store
/// (`acquisition::patterns::MAX_RANDOM_BITS`). Checked here, so that the error names the
/// image size the user wrote (at `width`, the ratio in the message), not a field
/// `measurements` that no file has.
fn check_pattern_sizes(f: &ExperimentFile) -> Result<()> {
    use crate::acquisition::patterns::{MAX_RANDOM_BITS, patterns_for_ratio};
    if !matches!(f.patterns, PatternsSpec::Random { .. }) {
        return Ok(());
    }
    let n = f.width * f.height;
    let r = f.sampling_ratios.iter().map(|r| r.0).fold(0.0, f64::max);
    let m = patterns_for_ratio(r, n);
    if m.saturating_mul(n) > MAX_RANDOM_BITS {
        return Err(Error::field(
            "width",
            format!(
                "{m} random patterns of {}×{} units (ratio {r}) would take {:.1} GiB of bits \
                 (limit {} GiB): lower the ratio or the image size",
                f.width,
                f.height,
                m as f64 * n as f64 / 8.0 / (1u64 << 30) as f64,
                MAX_RANDOM_BITS >> 33
            ),
        ));
    }
    Ok(())
}

fn validate(f: ExperimentFile, base_dir: &Path) -> Result<Experiment> {
    if f.width.saturating_mul(f.height) > MAX_UNITS {
        return Err(Error::field(
            "width",
            format!(
                "{}×{} units is more than the {} units of a 1024×1024 grid (at most 1024 × 1024 units)",
                f.width, f.height, MAX_UNITS
            ),
        ));
    }
    if f.objects.is_empty() {
        return Err(Error::field("objects", "at least one object is needed"));
    }
    for (i, o) in f.objects.iter().enumerate() {
        let ok = !o.name.is_empty()
            && o.name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
        if !ok {
            return Err(Error::field(
                format!("objects[{i}].name"),
                format!(
                    "object name {:?} must be non-empty letters, digits, '-' or '_'",
                    o.name
                ),
            ));
        }
        if f.objects[..i].iter().any(|p| p.name == o.name) {
            return Err(Error::field(
                format!("objects[{i}].name"),
                format!("object name {:?} is used twice", o.name),
            ));
        }
    }
    if f.sampling_ratios.is_empty() {
        return Err(Error::field(
            "sampling_ratios",
            "at least one sampling ratio is needed",
        ));
    }
    if f.cases.is_empty() {
        return Err(Error::field("cases", "at least one case is needed"));
    }
    let mut cases = Vec::with_capacity(f.cases.len());
    for (i, c) in f.cases.iter().enumerate() {
        if f.cases[..i].iter().any(|p| p.label == c.label) {
            return Err(Error::field(
                format!("cases[{i}].label"),
                format!("case label {:?} is used twice", c.label),
            ));
        }
        cases.push(Case {
            label: c.label.clone(),
            scheme: c.scheme,
            arms: c.arms.0,
            noise: c.noise.map(|n| n.0),
        });
    }
    f.solver.validate().map_err(|e| e.within("solver"))?;
    for (name, n) in [("maxit", f.solver.maxit), ("maxcnt", f.solver.maxcnt)] {
        if n > MAX_SOLVER_ITERATIONS {
            return Err(Error::field(
                format!("solver.{name}"),
                format!("must be at most {MAX_SOLVER_ITERATIONS}, got {n}"),
            ));
        }
    }
    check_curves(&f)?;
    check_pattern_sizes(&f)?;
    for (i, o) in f.objects.iter().enumerate() {
        if let ObjectSpec::File { path } = &o.object {
            let full = base_dir.join(path);
            if !full.is_file() {
                return Err(Error::field(
                    format!("objects[{i}].object"),
                    format!("no image file {}", full.display()),
                ));
            }
        }
    }
    if let PatternsSpec::Hadamard { .. } = f.patterns {
        let side = f.width;
        if f.width != f.height || !side.is_power_of_two() {
            return Err(Error::field(
                "patterns",
                format!(
                    "Hadamard patterns need a 2^m × 2^m image, got {}×{}; use Random patterns for other sizes",
                    f.width, f.height
                ),
            ));
        }
    }
    if let Some(m) = &f.montage
        && m.rows == m.columns
    {
        return Err(Error::field(
            "montage.columns",
            "montage rows and columns must be different axes",
        ));
    }
    for (i, c) in f.curves.iter().enumerate() {
        let ok = !c.name.is_empty()
            && c.name
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_');
        if !ok {
            return Err(Error::field(
                format!("curves[{i}].name"),
                format!("curve name {:?} is not a file stem", c.name),
            ));
        }
    }
    Ok(Experiment {
        title: f.title,
        width: f.width,
        height: f.height,
        objects: f.objects,
        patterns: f.patterns,
        sampling_ratios: f.sampling_ratios.iter().map(|r| r.0).collect(),
        cases,
        solver: f.solver,
        zero_one: f.zero_one,
        dmd_rate_hz: f.dmd_rate_hz,
        seed: f.seed,
        montage: f.montage,
        curves: f.curves,
        base_dir: base_dir.to_path_buf(),
        source_path: PathBuf::new(),
        source_text: String::new(),
    })
}
