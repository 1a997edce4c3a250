//! SSIM map and MSSIM exactly as Wang et al. (2004) and their reference `ssim_index.m`.
//!
//! SSIM(x, y) = [(2μxμy + C1)(2σxy + C2)] / [(μx² + μy² + C1)(σx² + σy² + C2)] with local
//! statistics weighted by the 11×11 Gaussian window w (σ = 1.5, `fspecial('gaussian', 11,
//! 1.5)`, normalised to sum 1): μx = Σ w·x, σx² = Σ w·x² − μx², σxy = Σ w·x·y − μxμy
//! (biased, window-weighted), C1 = (K1·L)² = 6.5025, C2 = (K2·L)² = 58.5225 with K1 = 0.01,
//! K2 = 0.03, L = 255. The window is applied only where it fits ('valid' filtering), so an
//! H×W image gives an (H − 10)×(W − 10) map; MSSIM is its plain mean (`mean2(ssim_map)`).
//!
//! The 2009 reference code first down-samples by f = max(1, round(min(H, W)/256)), which is 1
//! (no-op) for images below 384 pixels on the short side, i.e. every image in the paper; this
//! module never down-samples, so it is Wang's 2004 definition at every size.
//!
//! The 2-D window is separable (w = g gᵀ with g the normalised 1-D Gaussian, since both are
//! normalised exponentials of x² + y²), so filtering runs as a row pass then a column pass;
//! a test compares it with the direct 2-D sum.

use crate::error::{Error, Result};
use crate::raster::Raster;

/// Window side (pixels).
pub const WINDOW: usize = 11;
/// Gaussian window standard deviation (pixels).
pub const SIGMA: f64 = 1.5;
pub const K1: f64 = 0.01;
pub const K2: f64 = 0.03;
/// Dynamic range L of the images (8-bit scale).
pub const DYNAMIC_RANGE: f64 = 255.0;

/// The normalised 1-D Gaussian g(i) ∝ exp(−i²/(2σ²)), i = −5..=5, summing to 1.
pub fn gaussian_window_1d() -> [f64; WINDOW] {
    let half = (WINDOW / 2) as f64;
    let mut g = [0.0; WINDOW];
    for (i, v) in g.iter_mut().enumerate() {
        let x = i as f64 - half;
        *v = (-x * x / (2.0 * SIGMA * SIGMA)).exp();
    }
    let sum: f64 = g.iter().sum();
    for v in &mut g {
        *v /= sum;
    }
    g
}

/// 'Valid' correlation of a `w`×`h` row-major image with the separable window g gᵀ.
fn filter_valid(data: &[f64], w: usize, h: usize, g: &[f64; WINDOW]) -> Vec<f64> {
    let (ow, oh) = (w - WINDOW + 1, h - WINDOW + 1);
    let mut rows = vec![0.0; h * ow];
    for r in 0..h {
        let line = &data[r * w..(r + 1) * w];
        for c in 0..ow {
            rows[r * ow + c] = g.iter().zip(&line[c..c + WINDOW]).map(|(a, b)| a * b).sum();
        }
    }
    let mut out = vec![0.0; oh * ow];
    for r in 0..oh {
        for c in 0..ow {
            out[r * ow + c] = g
                .iter()
                .enumerate()
                .map(|(k, a)| a * rows[(r + k) * ow + c])
                .sum();
        }
    }
    out
}

fn check(truth: &Raster, test: &Raster) -> Result<()> {
    super::check_same_size(truth, test)?;
    if truth.width < WINDOW || truth.height < WINDOW {
        return Err(Error::input(format!(
            "SSIM needs images of at least {WINDOW}×{WINDOW} pixels (its window), got {}×{}",
            truth.width, truth.height
        )));
    }
    if truth.data.iter().chain(&test.data).any(|v| !v.is_finite()) {
        return Err(Error::Numerical(
            "cannot compute SSIM of an image with non-finite values".into(),
        ));
    }
    Ok(())
}

/// The SSIM map, (W − 10)×(H − 10) pixels; pixel (r, c) is the window centred on image pixel
/// (r + 5, c + 5).
///
/// Errors: different sizes or a side below 11 pixels ([`Error::Input`]); non-finite values
/// ([`Error::Numerical`]).
pub fn ssim_map(truth: &Raster, test: &Raster) -> Result<Raster> {
    ssim_map_in(truth, test, DYNAMIC_RANGE)
}

/// The SSIM map for images whose dynamic range is `range` (L of C1 = (K1·L)², C2 = (K2·L)²;
/// 255 for 8-bit images, 1 for images on [0, 1]): Wang et al.'s constants scale with the
/// range, so an image on [0, 1] scored with L = 255 gets C1, C2 that swamp every local
/// statistic and an MSSIM near 1 whatever its structure.
pub fn ssim_map_in(truth: &Raster, test: &Raster, range: f64) -> Result<Raster> {
    check(truth, test)?;
    if !(range.is_finite() && range > 0.0) {
        return Err(Error::input(format!(
            "SSIM needs a positive finite dynamic range, got {range}"
        )));
    }
    let (w, h) = (truth.width, truth.height);
    let g = gaussian_window_1d();
    let x = &truth.data;
    let y = &test.data;
    let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
    let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
    let xy: Vec<f64> = x.iter().zip(y).map(|(a, b)| a * b).collect();
    let mu_x = filter_valid(x, w, h, &g);
    let mu_y = filter_valid(y, w, h, &g);
    let e_xx = filter_valid(&xx, w, h, &g);
    let e_yy = filter_valid(&yy, w, h, &g);
    let e_xy = filter_valid(&xy, w, h, &g);
    let c1 = (K1 * range) * (K1 * range);
    let c2 = (K2 * range) * (K2 * range);
    let map: Vec<f64> = (0..mu_x.len())
        .map(|i| {
            let (mx, my) = (mu_x[i], mu_y[i]);
            let sxx = e_xx[i] - mx * mx;
            let syy = e_yy[i] - my * my;
            let sxy = e_xy[i] - mx * my;
            ((2.0 * mx * my + c1) * (2.0 * sxy + c2))
                / ((mx * mx + my * my + c1) * (sxx + syy + c2))
        })
        .collect();
    Raster::new(w - WINDOW + 1, h - WINDOW + 1, map)
}

/// MSSIM: the mean of the SSIM map (summed in index order, deterministic).
pub fn mssim(truth: &Raster, test: &Raster) -> Result<f64> {
    mssim_in(truth, test, DYNAMIC_RANGE)
}

/// MSSIM for images of dynamic range `range` (see [`ssim_map_in`]).
pub fn mssim_in(truth: &Raster, test: &Raster, range: f64) -> Result<f64> {
    let map = ssim_map_in(truth, test, range)?;
    Ok(map.data.iter().sum::<f64>() / map.data.len() as f64)
}
