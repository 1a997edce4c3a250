//! Tests of PSNR, SSIM and the normalisation rule.

use std::path::{Path, PathBuf};

use super::ssim::{WINDOW, gaussian_window_1d};
use super::*;
use crate::report::npy;

const C1: f64 = 6.5025;
const C2: f64 = 58.5225;

fn ramp(w: usize, h: usize) -> Raster {
    Raster::from_fn(w, h, |r, c| ((r * 37 + c * 101) % 256) as f64)
}

#[test]
fn psnr_closed_forms() {
    let zero = Raster::zeros(8, 4);
    let one = zero.map(|_| 1.0);
    // MSE = 1: PSNR = 20·log10(255) = 48.1308… dB.
    assert!((psnr(&zero, &one, 255.0) - 20.0 * 255f64.log10()).abs() < 1e-12);
    assert!((psnr(&zero, &one, 255.0) - 48.130_803_608_679_1).abs() < 1e-9);
    // MSE = 100 at peak 1.
    let ten = zero.map(|_| 10.0);
    assert!((psnr(&zero, &ten, 1.0) - (-20.0)).abs() < 1e-12);
    assert_eq!(psnr(&one, &one, 255.0), f64::INFINITY);
}

#[test]
fn window_is_the_normalised_fspecial_gaussian() {
    let g = gaussian_window_1d();
    assert!((g.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    // fspecial('gaussian', 11, 1.5): centre weight of the 2-D window = 1 / Σ exp(−(x²+y²)/4.5).
    let mut total = 0.0;
    for i in -5..=5 {
        for j in -5..=5 {
            total += (-f64::from(i * i + j * j) / 4.5).exp();
        }
    }
    assert!((g[5] * g[5] - 1.0 / total).abs() < 1e-15);
    // Symmetric.
    for k in 0..WINDOW {
        assert_eq!(g[k], g[WINDOW - 1 - k]);
    }
}

#[test]
fn ssim_of_uniform_images_is_the_luminance_term() {
    // σ = 0 everywhere: SSIM = (2ab + C1) / (a² + b² + C1) at every pixel.
    let (a, b) = (100.0, 140.0);
    let x = Raster::from_fn(20, 13, |_, _| a);
    let y = Raster::from_fn(20, 13, |_, _| b);
    let map = ssim_map(&x, &y).unwrap();
    assert_eq!((map.width, map.height), (10, 3));
    let want = (2.0 * a * b + C1) / (a * a + b * b + C1);
    for v in &map.data {
        assert!((v - want).abs() < 1e-12, "{v} vs {want}");
    }
    assert!((mssim(&x, &y).unwrap() - want).abs() < 1e-12);
}

#[test]
fn ssim_of_identical_images_is_one() {
    let x = ramp(30, 17);
    let v = mssim(&x, &x).unwrap();
    assert!((v - 1.0).abs() < 1e-15, "{v}");
}

/// The direct definition: a 2-D window sum at every valid position, window built from its
/// 2-D formula (not from the separable 1-D factor the implementation uses).
fn ssim_direct(x: &Raster, y: &Raster) -> Vec<f64> {
    let mut w2 = [[0.0; WINDOW]; WINDOW];
    let mut total = 0.0;
    for (i, row) in w2.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let (di, dj) = (i as f64 - 5.0, j as f64 - 5.0);
            *v = (-(di * di + dj * dj) / (2.0 * 1.5 * 1.5)).exp();
            total += *v;
        }
    }
    let mut out = Vec::new();
    for r in 0..=x.height - WINDOW {
        for c in 0..=x.width - WINDOW {
            let (mut mx, mut my, mut xx, mut yy, mut xy) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for (i, row) in w2.iter().enumerate() {
                for (j, &w) in row.iter().enumerate() {
                    let w = w / total;
                    let (a, b) = (x.get(r + i, c + j), y.get(r + i, c + j));
                    mx += w * a;
                    my += w * b;
                    xx += w * a * a;
                    yy += w * b * b;
                    xy += w * a * b;
                }
            }
            let (sx, sy, sxy) = (xx - mx * mx, yy - my * my, xy - mx * my);
            out.push(
                ((2.0 * mx * my + C1) * (2.0 * sxy + C2))
                    / ((mx * mx + my * my + C1) * (sx + sy + C2)),
            );
        }
    }
    out
}

#[test]
fn separable_filtering_equals_the_direct_window_sum() {
    let x = ramp(23, 15);
    let y = Raster::from_fn(23, 15, |r, c| ((r * r * 7 + c * 13) % 251) as f64);
    let map = ssim_map(&x, &y).unwrap();
    let direct = ssim_direct(&x, &y);
    assert_eq!(map.data.len(), direct.len());
    assert_eq!((map.width, map.height), (13, 5));
    for (a, b) in map.data.iter().zip(&direct) {
        // Different summation orders of ~121 products of size ≤ 255²: ~1e-13 relative.
        assert!((a - b).abs() < 1e-10, "{a} vs {b}");
    }
}

#[test]
fn ssim_rejects_small_or_mismatched_images() {
    let a = ramp(11, 11);
    assert!(mssim(&a, &a).is_ok());
    for (w, h) in [(10, 11), (11, 10), (4, 4)] {
        let b = ramp(w, h);
        assert!(mssim(&b, &b).unwrap_err().is_user_error());
    }
    let e = mssim(&ramp(12, 12), &ramp(12, 13)).unwrap_err();
    assert!(e.is_user_error(), "{e}");
    let mut nan = ramp(12, 12);
    nan.data[3] = f64::NAN;
    assert!(matches!(
        mssim(&nan, &ramp(12, 12)),
        Err(Error::Numerical(_))
    ));
}

#[test]
fn normalisation_undoes_gain_and_offset() {
    let truth = ramp(16, 16);
    // A reconstruction with the SCB gain k' = 2.03 and a DC offset.
    let recon = truth.map(|v| 2.03 * v - 17.5);
    let n = normalize_to_truth(&recon, &truth).unwrap();
    assert!((n.gain - 1.0 / 2.03).abs() < 1e-12);
    assert!((n.offset - 17.5 / 2.03).abs() < 1e-9);
    for (a, b) in n.image.data.iter().zip(&truth.data) {
        assert!((a - b).abs() < 1e-9);
    }
    let s = score(&truth, &recon).unwrap();
    assert!(s.psnr_db > 150.0 && (s.mssim - 1.0).abs() < 1e-12, "{s:?}");
}

#[test]
fn normalisation_is_the_least_squares_fit() {
    // Before clipping, any other gain or offset gives a larger squared error.
    let truth = ramp(12, 9);
    let recon = Raster::from_fn(12, 9, |r, c| ((r * 5 + c * 3) % 17) as f64 * 0.1 + 2.0);
    let n = normalize_to_truth(&recon, &truth).unwrap();
    let sse = |g: f64, o: f64| -> f64 {
        recon
            .data
            .iter()
            .zip(&truth.data)
            .map(|(r, t)| (g * r + o - t).powi(2))
            .sum()
    };
    let best = sse(n.gain, n.offset);
    for (dg, dof) in [(1e-3, 0.0), (-1e-3, 0.0), (0.0, 1e-3), (0.0, -1e-3)] {
        assert!(sse(n.gain + dg, n.offset + dof) > best);
    }
    // Normal equations: the residual is orthogonal to 1 and to the reconstruction.
    let res: Vec<f64> = recon
        .data
        .iter()
        .zip(&truth.data)
        .map(|(r, t)| n.gain * r + n.offset - t)
        .collect();
    let s1: f64 = res.iter().sum();
    let sr: f64 = res.iter().zip(&recon.data).map(|(e, r)| e * r).sum();
    assert!(s1.abs() < 1e-9 && sr.abs() < 1e-8, "{s1} {sr}");
    assert!(n.image.min() >= 0.0 && n.image.max() <= 255.0);
}

#[test]
fn normalisation_clips_and_handles_constants() {
    let truth = Raster::new(2, 2, vec![0.0, 0.0, 255.0, 255.0]).unwrap();
    let constant = Raster::new(2, 2, vec![7.0; 4]).unwrap();
    let n = normalize_to_truth(&constant, &truth).unwrap();
    assert_eq!((n.gain, n.offset), (0.0, 127.5));
    assert_eq!(n.image.data, vec![127.5; 4]);
    // A fit that overshoots is clipped to [0, 255].
    let recon = Raster::new(2, 2, vec![0.0, 1.0, 2.0, 3.0]).unwrap();
    let n = normalize_to_truth(&recon, &truth).unwrap();
    assert!(n.image.min() == 0.0 && n.image.max() == 255.0);
    assert!(n.gain > 0.0);
    // Errors.
    assert!(
        normalize_to_truth(&ramp(3, 3), &truth)
            .unwrap_err()
            .is_user_error()
    );
    let mut bad = recon.clone();
    bad.data[0] = f64::INFINITY;
    assert!(matches!(
        normalize_to_truth(&bad, &truth),
        Err(Error::Numerical(_))
    ));
}

#[derive(serde::Deserialize)]
struct Reference {
    #[serde(rename = "scikit-image")]
    scikit_image: String,
    cases: Vec<Case>,
}

#[derive(serde::Deserialize)]
struct Case {
    name: String,
    truth: String,
    test: String,
    shape: Vec<usize>,
    psnr_db: Option<f64>,
    ssim: f64,
}

fn reference_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/metrics")
}

fn load_pair_image(name: &str, shape: &[usize]) -> Raster {
    let a = npy::read(&reference_dir().join(name)).unwrap();
    assert_eq!(a.shape, shape, "{name}");
    // .npy arrays are row-major (C order): element (r, c) at r·W + c, as in Raster.
    Raster::new(shape[1], shape[0], a.to_f64()).unwrap()
}

#[test]
fn matches_scikit_image_reference() {
    let text = std::fs::read_to_string(reference_dir().join("reference.json")).unwrap();
    let reference: Reference = serde_json::from_str(&text).unwrap();
    assert!(!reference.scikit_image.is_empty());
    assert!(reference.cases.len() >= 8);
    for case in &reference.cases {
        let truth = load_pair_image(&case.truth, &case.shape);
        let test = load_pair_image(&case.test, &case.shape);
        // Both sides compute in float64 from the same stored values; the only differences are
        // summation orders (separable vs scipy's separable with reflect padding, pairwise vs
        // sequential means), which cost ~1e-13 here. 1e-6 is far above that round-off and far
        // below any definitional slip (sample vs population covariance alone changes SSIM by
        // ~1e-3; a 7×7 or unnormalised window by more).
        let ssim = mssim(&truth, &test).unwrap();
        assert!(
            (ssim - case.ssim).abs() <= 1e-6,
            "{}: SSIM {ssim} vs skimage {}",
            case.name,
            case.ssim
        );
        let p = psnr(&truth, &test, 255.0);
        match case.psnr_db {
            Some(want) => assert!(
                (p - want).abs() <= 1e-6,
                "{}: PSNR {p} vs skimage {want}",
                case.name
            ),
            None => assert_eq!(p, f64::INFINITY, "{}", case.name),
        }
    }
}
