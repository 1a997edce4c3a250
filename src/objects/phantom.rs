//! The modified Shepp–Logan head phantom, exactly as MATLAB `phantom(n)` (default
//! 'Modified Shepp-Logan') draws it.
//!
//! The ten ellipses are Shepp and Logan's (IEEE Trans. Nucl. Sci. 21:21–43, 1974) with the
//! higher-contrast intensities of P. Toft, "The Radon Transform: Theory and Implementation",
//! PhD thesis, DTU 1996, pp. 199–200, as tabulated in MATLAB's and Octave's `phantom.m`.
//!
//! Grid (MATLAB's): pixel centres sample [−1, 1] inclusively, so column c of an n-pixel row
//! sits at x = (c − (n − 1)/2) / ((n − 1)/2) and row r at y = −(r − (n − 1)/2) / ((n − 1)/2)
//! (row 0 at the top, y up). A pixel takes the sum of the intensities of every ellipse whose
//! closed interior contains its centre (point sampling, no anti-aliasing), added in table
//! order so that the floating-point sums match MATLAB's bit for bit.
//!
//! Values lie in [0, 1] (levels 0, 0.1, 0.2, 0.3, 0.4 and 1, up to round-off of the sums,
//! which is clamped away); [`phantom_255`] multiplies by 255 after summing, as the TVAL3
//! reference data `validation/tval3-phantom/phantom_x.npy` did.

use crate::error::{Error, Result};
use crate::raster::Raster;

/// One ellipse: intensity A, semi-axes a (along x before rotation) and b, centre (x0, y0), and
/// rotation φ in degrees (counter-clockwise).
struct Ellipse {
    intensity: f64,
    a: f64,
    b: f64,
    x0: f64,
    y0: f64,
    phi_deg: f64,
}

/// Toft's modified Shepp–Logan table (MATLAB `phantom`, 'Modified Shepp-Logan').
#[rustfmt::skip]
const MODIFIED_SHEPP_LOGAN: [Ellipse; 10] = [
    Ellipse { intensity: 1.0, a: 0.69, b: 0.92, x0: 0.0, y0: 0.0, phi_deg: 0.0 },
    Ellipse { intensity: -0.8, a: 0.6624, b: 0.8740, x0: 0.0, y0: -0.0184, phi_deg: 0.0 },
    Ellipse { intensity: -0.2, a: 0.1100, b: 0.3100, x0: 0.22, y0: 0.0, phi_deg: -18.0 },
    Ellipse { intensity: -0.2, a: 0.1600, b: 0.4100, x0: -0.22, y0: 0.0, phi_deg: 18.0 },
    Ellipse { intensity: 0.1, a: 0.2100, b: 0.2500, x0: 0.0, y0: 0.35, phi_deg: 0.0 },
    Ellipse { intensity: 0.1, a: 0.0460, b: 0.0460, x0: 0.0, y0: 0.1, phi_deg: 0.0 },
    Ellipse { intensity: 0.1, a: 0.0460, b: 0.0460, x0: 0.0, y0: -0.1, phi_deg: 0.0 },
    Ellipse { intensity: 0.1, a: 0.0460, b: 0.0230, x0: -0.08, y0: -0.605, phi_deg: 0.0 },
    Ellipse { intensity: 0.1, a: 0.0230, b: 0.0230, x0: 0.0, y0: -0.606, phi_deg: 0.0 },
    Ellipse { intensity: 0.1, a: 0.0230, b: 0.0460, x0: 0.06, y0: -0.605, phi_deg: 0.0 },
];

/// Unclamped sums, exactly as MATLAB computes them (needed for bit-exact ×255 values).
fn raw(n: usize) -> Result<Vec<f64>> {
    if n < 2 {
        return Err(Error::input(format!(
            "the phantom needs at least 2×2 pixels (its grid puts pixel centres at −1 and +1), got {n}×{n}"
        )));
    }
    if n > super::MAX_OBJECT_SIDE {
        return Err(Error::input(format!(
            "a {n}×{n} phantom is larger than the {max}×{max} limit",
            max = super::MAX_OBJECT_SIDE
        )));
    }
    let half = (n as f64 - 1.0) / 2.0;
    // MATLAB: xax = ((0:n-1) - (n-1)/2) / ((n-1)/2); y = rot90(xg), i.e. y = xax(n - r).
    let axis: Vec<f64> = (0..n).map(|i| (i as f64 - half) / half).collect();
    let mut p = vec![0.0; n * n];
    for e in &MODIFIED_SHEPP_LOGAN {
        let (asq, bsq) = (e.a * e.a, e.b * e.b);
        let phi = e.phi_deg * std::f64::consts::PI / 180.0;
        let (cosp, sinp) = (phi.cos(), phi.sin());
        for r in 0..n {
            let y = axis[n - 1 - r] - e.y0;
            for c in 0..n {
                let x = axis[c] - e.x0;
                let u = x * cosp + y * sinp;
                let v = y * cosp - x * sinp;
                if (u * u) / asq + (v * v) / bsq <= 1.0 {
                    p[r * n + c] += e.intensity;
                }
            }
        }
    }
    Ok(p)
}

/// The n×n modified Shepp–Logan phantom with values in [0, 1].
///
/// Only square grids exist: MATLAB's phantom is defined on a square [−1, 1]² grid, and
/// stretching it to a rectangle would distort the ellipses.
pub fn phantom(n: usize) -> Result<Raster> {
    let p = raw(n)?;
    // Sums such as 1 − 0.8 − 0.2 leave ±6e-17 where the level is 0; clamp to the exact range.
    Raster::new(n, n, p.into_iter().map(|v| v.clamp(0.0, 1.0)).collect())
}

/// The phantom times 255, with values in [0, 255]: MATLAB's `255 * phantom(n)`.
pub fn phantom_255(n: usize) -> Result<Raster> {
    let p = raw(n)?;
    Raster::new(
        n,
        n,
        p.into_iter()
            .map(|v| (255.0 * v).clamp(0.0, 255.0))
            .collect(),
    )
}

/// The phantom for a `width`×`height` raster: an input error unless the raster is square.
pub fn phantom_sized(width: usize, height: usize, times_255: bool) -> Result<Raster> {
    if width != height {
        return Err(Error::input(format!(
            "the Shepp–Logan phantom is defined on a square grid, but a {width}×{height} image was asked for"
        )));
    }
    if times_255 {
        phantom_255(width)
    } else {
        phantom(width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::npy;
    use std::path::Path;

    #[test]
    fn matches_the_tval3_reference_phantom() {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/validation/tval3-phantom/phantom_x.npy"
        ));
        let reference = npy::read(path).unwrap();
        assert_eq!(reference.shape, vec![128, 128]);
        let want = reference.to_f64();
        let got = phantom_255(128).unwrap();
        let mut max_diff: f64 = 0.0;
        for (g, w) in got.data.iter().zip(&want) {
            max_diff = max_diff.max((g - w).abs());
        }
        // Same ellipse table, grid and summation order, so the values agree bit for bit
        // (1e-9 would also allow a different but exact-enough summation order).
        assert!(max_diff <= 1e-9, "max |Δ| = {max_diff}");
        assert_eq!(max_diff, 0.0);
    }

    #[test]
    fn levels_range_and_symmetry() {
        let p = phantom(64).unwrap();
        assert_eq!(p.min(), 0.0);
        assert_eq!(p.max(), 1.0);
        let levels = [0.0, 0.1, 0.2, 0.3, 0.4, 1.0];
        for v in &p.data {
            assert!(levels.iter().any(|l| (v - l).abs() < 1e-12), "level {v}");
        }
        // The corners lie outside the skull; the centre is brain (0.2).
        assert_eq!(p.get(0, 0), 0.0);
        assert!((p.get(32, 32) - 0.2).abs() < 1e-12 || (p.get(31, 31) - 0.2).abs() < 1e-12);
        // Toft's ellipses 3 and 4 make the image asymmetric left–right, but the skull
        // (ellipse 1) is symmetric: the outermost nonzero columns mirror each other.
        let nonzero_cols: Vec<usize> = (0..64)
            .filter(|&c| (0..64).any(|r| p.get(r, c) > 0.0))
            .collect();
        assert_eq!(nonzero_cols[0], 63 - nonzero_cols[nonzero_cols.len() - 1]);
    }

    #[test]
    fn ones_and_255_differ_by_the_factor() {
        let (a, b) = (phantom(50).unwrap(), phantom_255(50).unwrap());
        for (x, y) in a.data.iter().zip(&b.data) {
            assert!((255.0 * x - y).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_sizes_are_input_errors() {
        for n in [0, 1] {
            assert!(phantom(n).unwrap_err().is_user_error());
        }
        assert!(phantom_sized(64, 32, true).unwrap_err().is_user_error());
        assert!(
            phantom(super::super::MAX_OBJECT_SIDE + 1)
                .unwrap_err()
                .is_user_error()
        );
        assert_eq!(phantom_sized(16, 16, false).unwrap(), phantom(16).unwrap());
    }
}
