//! The least-squares gain and offset that map a reconstruction onto the ground truth, then a
//! clip to the truth's data range, [0, 255] for the simulated objects (the rule stated in the `metrics` module documentation).

use crate::error::{Error, Result};
use crate::raster::Raster;

/// A reconstruction on the ground truth's scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Normalized {
    /// clip(gain · recon + offset, 0, 255).
    pub image: Raster,
    pub gain: f64,
    pub offset: f64,
}

/// Fits truth ≈ gain · recon + offset by least squares and returns the clipped mapped image.
///
/// The fit uses centred sums (two passes), which keeps full precision when the reconstruction
/// has a large common offset (for example an uncancelled DC term). A constant reconstruction
/// has no defined gain: it gets gain 0 and offset = mean(truth), the best constant.
///
/// Errors: different sizes ([`Error::Input`]); non-finite values in either image
/// ([`Error::Numerical`], e.g. a diverged solver).
pub fn normalize_to_truth(recon: &Raster, truth: &Raster) -> Result<Normalized> {
    normalize_to_truth_in(recon, truth, super::DataRange::EIGHT_BIT)
}

/// As [`normalize_to_truth`], clipping to `range` instead of [0, 255].
pub fn normalize_to_truth_in(
    recon: &Raster,
    truth: &Raster,
    range: super::DataRange,
) -> Result<Normalized> {
    super::check_same_size(truth, recon)?;
    if recon.data.is_empty() {
        return Err(Error::input("cannot normalise an empty image"));
    }
    if recon.data.iter().chain(&truth.data).any(|v| !v.is_finite()) {
        return Err(Error::Numerical(
            "cannot normalise a reconstruction with non-finite values".into(),
        ));
    }
    let n = recon.data.len() as f64;
    let mean_r = recon.data.iter().sum::<f64>() / n;
    let mean_t = truth.data.iter().sum::<f64>() / n;
    let (mut srr, mut srt) = (0.0, 0.0);
    for (r, t) in recon.data.iter().zip(&truth.data) {
        let dr = r - mean_r;
        srr += dr * dr;
        srt += dr * (t - mean_t);
    }
    let constant = recon.data.iter().all(|&v| v == recon.data[0]);
    let (gain, offset) = if constant || srr == 0.0 {
        (0.0, mean_t)
    } else {
        let gain = srt / srr;
        (gain, mean_t - gain * mean_r)
    };
    let image = recon.map(|v| (gain * v + offset).clamp(range.lo, range.hi));
    Ok(Normalized {
        image,
        gain,
        offset,
    })
}
