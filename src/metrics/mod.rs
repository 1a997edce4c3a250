//! Image-quality scores (PSNR, MSSIM) and the rule that brings a reconstruction to the ground
//! truth's scale before it is scored.
//!
//! # Normalisation rule (the same for every scheme)
//!
//! A reconstruction x̃ carries an unknown gain (for example k' = k₊ + k₋ after secondary
//! complementary balancing, or the detector's responsivity and transimpedance) and sometimes an
//! offset (for example the uncancelled DC term of imbalanced double-arm detection). Before
//! scoring, every reconstruction is mapped onto the ground truth x (on [0, 255]) by the affine
//! map with the least squared error,
//!
//! > g, o = argmin Σᵢ (g·x̃ᵢ + o − xᵢ)², i.e. g = cov(x̃, x) / var(x̃), o = mean(x) − g·mean(x̃),
//!
//! and the mapped image g·x̃ + o is clipped to [0, 255]. A constant reconstruction
//! (var(x̃) = 0) gets g = 0 and o = mean(x). PSNR (peak 255) and MSSIM are then computed between
//! the ground truth and the clipped image ([`score`]).
//!
//! A truth made elsewhere (`reconstruct --truth`) is scored on its own range instead
//! ([`DataRange`], [`score_in`]): the clip is to [min, max] of the truth (or a range the user
//! gives), PSNR's peak and SSIM's L are max − min. PSNR's peak is the range of the data, not
//! a fixed 255, and SSIM's C1 = (K1·L)², C2 = (K2·L)² are defined for L = "the dynamic range
//! of the pixel values" (Wang et al. 2004, eq. 7); scikit-image's `data_range` is the same
//! number.
//!
//! Why this rule: it removes exactly the two unknowns that the measurement model leaves free
//! (gain and offset), whatever the scheme, so the scores compare image structure rather than
//! calibration. It uses the truth, so it is the best any affine calibration could do (an
//! upper bound for a real bench), and it cannot make an image better than its structure
//! allows: a reconstruction uncorrelated with the truth maps to a near-constant image.
//!
//! # Scores
//!
//! - PSNR = 10·log₁₀(peak² / MSE), MSE = mean((x − y)²); +∞ for identical images.
//! - MSSIM = the mean of the SSIM map of Wang, Bovik, Sheikh and Simoncelli, IEEE Trans. Image
//!   Process. 13(4):600–612 (2004), exactly as their reference `ssim_index.m`: 11×11 Gaussian
//!   window with σ = 1.5 normalised to sum 1, K1 = 0.01, K2 = 0.03, L = 255, local statistics
//!   by 'valid' filtering (an (H − 10) × (W − 10) map), biased window-weighted variances
//!   (σ² = E[x²] − μ²). Not the multi-scale MS-SSIM. See [`ssim`].
//!
//! Both are validated against scikit-image in `validation/metrics/` (see the README-style
//! header of `make_reference.py` there).

pub mod normalize;
pub mod registration;
pub mod resolution;
pub mod ssim;

pub use normalize::{Normalized, normalize_to_truth, normalize_to_truth_in};
pub use ssim::{mssim, mssim_in, ssim_map, ssim_map_in};

use crate::error::{Error, Result};
use crate::raster::Raster;

/// The normalisation rule in one sentence, for summaries and reports.
pub const NORMALIZATION_RULE: &str = "least-squares gain and offset mapping the reconstruction onto the ground truth, then clipping to [0, 255]; PSNR with peak 255, MSSIM as Wang et al. 2004";

/// The peak value of objects and normalised reconstructions (the paper's 255²/MSE).
pub const PEAK_255: f64 = 255.0;

/// The range [lo, hi] a truth's values are meant to span: the clip of the normalisation, the
/// peak hi − lo of PSNR and the dynamic range L of SSIM. The simulated objects are on
/// [0, 255]; an image made elsewhere may be on [0, 1] or any other scale, and scoring it with
/// peak 255 would add 20·log₁₀(255) ≈ 48 dB to its PSNR and push its MSSIM towards 1.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DataRange {
    pub lo: f64,
    pub hi: f64,
}

impl DataRange {
    /// The 8-bit scale of the simulated objects.
    pub const EIGHT_BIT: DataRange = DataRange { lo: 0.0, hi: 255.0 };

    /// A range with finite ends and hi > lo (an input error otherwise).
    pub fn new(lo: f64, hi: f64) -> Result<DataRange> {
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(Error::input(format!(
                "a data range needs finite ends with high above low, got [{lo}, {hi}]"
            )));
        }
        Ok(DataRange { lo, hi })
    }

    /// The truth's own range [min, max]; an input error for a constant truth (no scale).
    pub fn of(truth: &Raster) -> Result<DataRange> {
        let (lo, hi) = (truth.min(), truth.max());
        if lo.is_nan() || hi.is_nan() || hi <= lo {
            return Err(Error::input(format!(
                "the truth is constant ({lo}): it has no range to score against; give one with `data_range`"
            )));
        }
        DataRange::new(lo, hi)
    }

    /// hi − lo: PSNR's peak and SSIM's L.
    pub fn span(&self) -> f64 {
        self.hi - self.lo
    }
}

/// An input error unless the two images have the same size.
pub fn check_same_size(truth: &Raster, test: &Raster) -> Result<()> {
    if (truth.width, truth.height) != (test.width, test.height)
        || truth.data.len() != test.data.len()
    {
        return Err(Error::input(format!(
            "cannot compare a {}×{} image with a {}×{} image",
            truth.width, truth.height, test.width, test.height
        )));
    }
    Ok(())
}

/// Mean squared error, summed in index order (deterministic).
///
/// # Panics
/// If the sizes differ (a programming error: callers build both images at one size; use
/// [`check_same_size`] first when sizes come from input).
pub fn mse(truth: &Raster, test: &Raster) -> f64 {
    assert!(
        check_same_size(truth, test).is_ok(),
        "mse of a {}×{} and a {}×{} image",
        truth.width,
        truth.height,
        test.width,
        test.height
    );
    let sum: f64 = truth
        .data
        .iter()
        .zip(&test.data)
        .map(|(a, b)| (a - b) * (a - b))
        .sum();
    sum / truth.data.len() as f64
}

/// PSNR = 10·log₁₀(peak² / MSE) in dB; +∞ when the images are identical.
///
/// # Panics
/// If the sizes differ (see [`mse`]).
pub fn psnr(truth: &Raster, test: &Raster, peak: f64) -> f64 {
    let mse = mse(truth, test);
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (peak * peak / mse).log10()
    }
}

/// The scores of one reconstruction after the normalisation rule.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Scores {
    /// PSNR with peak 255, in dB (+∞ for a perfect match, serialised by serde_json as null).
    pub psnr_db: f64,
    /// Mean of the SSIM map (Wang et al. 2004).
    pub mssim: f64,
    /// The least-squares gain applied to the reconstruction.
    pub gain: f64,
    /// The least-squares offset applied after the gain.
    pub offset: f64,
    /// The reconstruction after the normalisation, on the truth's 0–255 scale: what was scored,
    /// and what a report shows.
    #[serde(skip)]
    pub image: Raster,
}

/// Normalises `recon` to `truth` (module rule) and scores it: PSNR (peak 255) and MSSIM. The
/// normalised image is returned with the scores, so no caller re-implements the rule.
pub fn score(truth: &Raster, recon: &Raster) -> Result<Scores> {
    score_in(truth, recon, DataRange::EIGHT_BIT)
}

/// As [`score`] for a truth on `range`: the mapped image is clipped to it, PSNR's peak and
/// SSIM's L are its span.
pub fn score_in(truth: &Raster, recon: &Raster, range: DataRange) -> Result<Scores> {
    let n = normalize_to_truth_in(recon, truth, range)?;
    Ok(Scores {
        psnr_db: psnr(truth, &n.image, range.span()),
        mssim: mssim_in(truth, &n.image, range.span())?,
        gain: n.gain,
        offset: n.offset,
        image: n.image,
    })
}

#[cfg(test)]
mod tests;
