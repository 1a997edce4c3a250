//! The outputs of `spibench reconstruct` (docs/outputs.md, "reconstruct"): the image as
//! computed (`reconstruction.npy`, float64, row-major), as pictures scaled over its own range
//! (`reconstruction.png`, `reconstruction16.png`, `reconstruction.exr`) and `summary.json`
//! ([`ReconstructSummary`]).

use serde::Serialize;

use crate::metrics;
use crate::raster::Raster;
use crate::reconstruction::tval3::{StopReason, Tval3Options};
use crate::report::output::OutputDir;

/// `summary.json` of `reconstruct`.
#[derive(Serialize)]
pub struct ReconstructSummary {
    pub command: &'static str,
    pub spibench_version: &'static str,
    pub width: usize,
    pub height: usize,
    /// Patterns M and units N.
    pub measurements: usize,
    pub units: usize,
    /// "01" or "pm1".
    pub form: &'static str,
    /// "uint8_01" or "packbits".
    pub patterns_encoding: &'static str,
    /// With form "01": "zero-mean" or "plain" (how the 0/1 system was solved).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub zero_one_handling: Option<&'static str>,
    pub iterations: usize,
    pub forward_applications: usize,
    pub adjoint_applications: usize,
    /// True only when TVAL3 met its outer tolerance (`stop` is "Tolerance").
    pub converged: bool,
    pub stop: StopReason,
    /// ‖A u − y‖ / ‖y‖.
    pub relative_residual: f64,
    /// Solver CPU time, s.
    pub time_s: f64,
    /// Only with --truth: scores after the normalisation rule, on `data_range`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub psnr_db: Option<f64>,
    /// Only with --truth: [lo, hi], the clip, PSNR's peak (hi − lo) and SSIM's L.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data_range: Option<metrics::DataRange>,
    /// Where the data range came from: "truth" (its own min and max) or the command line's flag.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data_range_from: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mssim: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normalization: Option<String>,
    pub solver: Tval3Options,
}

/// Warnings when the truth's range looks unlike the scale it is scored on or the image's.
pub fn range_warnings(truth: &Raster, image: &Raster, range: metrics::DataRange) -> Vec<String> {
    let (lo, hi) = (truth.min(), truth.max());
    let mut w = Vec::new();
    if lo < range.lo || hi > range.hi {
        w.push(format!(
            "the truth's values [{lo:.4e}, {hi:.4e}] leave the data range [{}, {}]: the scores \
             compare a clipped image with values it cannot reach",
            range.lo, range.hi
        ));
    } else if hi - lo < 0.25 * range.span() {
        w.push(format!(
            "the truth spans [{lo:.4e}, {hi:.4e}], under a quarter of the data range [{}, {}]: \
             PSNR and MSSIM will look better than the image's structure is",
            range.lo, range.hi
        ));
    }
    let (ilo, ihi) = (image.min(), image.max());
    let (ts, is) = (hi - lo, ihi - ilo);
    if ts > 0.0 && is > 0.0 && (ts / is > 100.0 || is / ts > 100.0) {
        w.push(format!(
            "the truth spans {ts:.4e} and the reconstruction {is:.4e} (a factor {:.0}): the \
             reconstruction is mapped onto the truth by a fitted gain and offset before scoring, \
             so check that the truth is the object these measurements saw",
            (ts / is).max(is / ts)
        ));
    }
    w
}

/// The normalisation rule as applied on `r`.
pub fn range_rule(r: metrics::DataRange) -> String {
    format!(
        "least-squares gain and offset mapping the reconstruction onto the ground truth, then \
         clipping to the data range [{}, {}]; PSNR with peak {} (the range's span), MSSIM as \
         Wang et al. 2004 with L = {}",
        r.lo,
        r.hi,
        r.span(),
        r.span()
    )
}

/// Writes the image and `summary.json` into `out` (a staging folder).
pub fn write(
    img: &Raster,
    summary: &ReconstructSummary,
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<()> {
    let (w, h) = (img.width, img.height);
    crate::report::npy::write_f64(&out.path("reconstruction.npy"), &[h, w], &img.data)?;
    let (lo, hi) = (img.min(), img.max());
    let hi = if hi > lo { hi } else { lo + 1.0 };
    crate::report::png::write_gray8(&out.path("reconstruction.png"), img, lo, hi)?;
    crate::report::png::write_gray16(&out.path("reconstruction16.png"), img, lo, hi)?;
    let data32: Vec<f32> = img.data.iter().map(|&v| v as f32).collect();
    crate::report::exr::write_channels(&out.path("reconstruction.exr"), w, h, &[("Y", &data32)])?;
    super::summary::write_summary(out, summary, provenance)
}
