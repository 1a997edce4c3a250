use super::*;
use crate::acquisition::hadamard::HadamardOrdering;
use crate::acquisition::patterns::{hadamard_set, random_set};

/// A deterministic non-trivial 0–255 object.
fn object(n: usize) -> Vec<f64> {
    (0..n).map(|i| ((i * 97 + 13) % 256) as f64).collect()
}

/// The base patterns as dense 0/1 rows.
fn dense(set: &PatternSet) -> Vec<Vec<f64>> {
    let p = set.base_patterns();
    (0..p.rows())
        .map(|r| (0..p.cols()).map(|c| p.get(r, c) as u8 as f64).collect())
        .collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(u, v)| u * v).sum()
}

fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= 1e-12 * scale.max(1.0)
}

/// Paper Eqs. (6)–(12) evaluated with dense patterns, their dense complements and the same
/// noise draws, sample by sample.
fn dense_equations(
    scheme: Scheme,
    x: &[f64],
    p: &[Vec<f64>],
    arms: &ScalarArms,
    e: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let ScalarArms {
        k_plus: kp,
        k_minus: km,
        b_plus: bp,
        b_minus: bm,
    } = *arms;
    let (mut y, mut s) = (Vec::new(), Vec::new());
    if scheme == Scheme::DoubleArmCalibrated {
        // Eqs. (6) and (7) on every frame: 8 × (all on, all off), then the patterns; the
        // calibration values averaged, each arm mapped to its fraction of the object.
        let total: f64 = x.iter().sum();
        let lead = 2 * CALIBRATION_PAIRS;
        let mut v = Vec::new();
        for t in 0..lead + p.len() {
            let (on, off) = if t < lead {
                if t.is_multiple_of(2) {
                    (total, 0.0)
                } else {
                    (0.0, total)
                }
            } else {
                let a = dot(&p[t - lead], x);
                (a, total - a)
            };
            let yp = kp * (on + e[2 * t]) + bp;
            let ym = km * (off + e[2 * t + 1]) + bm;
            s.extend([yp, ym]);
            v.push((yp, ym));
        }
        let mean = |f: &dyn Fn(&(f64, f64)) -> f64, parity: usize| {
            (0..CALIBRATION_PAIRS)
                .map(|k| f(&v[2 * k + parity]))
                .sum::<f64>()
                / CALIBRATION_PAIRS as f64
        };
        let (p1, p0) = (mean(&|a| a.0, 0), mean(&|a| a.0, 1));
        let (m1, m0) = (mean(&|a| a.1, 0), mean(&|a| a.1, 1));
        for &(yp, ym) in &v[lead..] {
            y.push((yp - p0) / (p1 - p0) - (ym - m1) / (m0 - m1));
        }
        return (y, s);
    }
    for (i, row) in p.iter().enumerate() {
        let a_plus = row.clone();
        let a_minus: Vec<f64> = row.iter().map(|v| 1.0 - v).collect();
        match scheme {
            Scheme::DoubleArmCalibrated => unreachable!("returned above"),
            Scheme::Traditional | Scheme::TraditionalZeroMean => {
                let v = kp * (dot(&a_plus, x) + e[i]) + bp;
                s.push(v);
                y.push(v);
            }
            Scheme::SingleArmComplementary => {
                let v1 = kp * (dot(&a_plus, x) + e[2 * i]) + bp;
                let v2 = kp * (dot(&a_minus, x) + e[2 * i + 1]) + bp;
                s.extend([v1, v2]);
                y.push(v1 - v2);
            }
            Scheme::DoubleArm | Scheme::DoubleArmOffset => {
                // Eqs. (6) and (7): y'⁺ − y'⁻ on one frame.
                let yp = kp * (dot(&a_plus, x) + e[2 * i]) + bp;
                let ym = km * (dot(&a_minus, x) + e[2 * i + 1]) + bm;
                s.extend([yp, ym]);
                y.push(yp - ym);
            }
            Scheme::SecondaryComplementaryBalancing => {
                // Eqs. (10)–(12) with the noise on each RF sample.
                let b1 = kp * dot(&a_plus, x) + bp - (km * dot(&a_minus, x) + bm) + e[2 * i];
                let b2 = kp * dot(&a_minus, x) + bp - (km * dot(&a_plus, x) + bm) + e[2 * i + 1];
                s.extend([b1, b2]);
                y.push(b1 - b2);
            }
        }
    }
    (y, s)
}

fn small_sets() -> Vec<PatternSet> {
    vec![
        random_set(8, 8, 20, 0x5EED_0001).unwrap(),
        hadamard_set(8, HadamardOrdering::CakeCutting, 20).unwrap(),
    ]
}

#[test]
fn every_scheme_matches_the_dense_equations() {
    let x = object(64);
    let scale = x.iter().sum::<f64>() * 3.0;
    for set in small_sets() {
        let p = dense(&set);
        for noise in [
            None,
            Some(AdditiveNoise::gaussian(3.0)),
            Some(AdditiveNoise::exponential(2.0)),
            Some(AdditiveNoise::poisson(4.0)),
        ] {
            for arms in [
                ScalarArms::paper_imbalanced(),
                ScalarArms::from_k_prime(20.0),
            ] {
                for scheme in Scheme::all() {
                    let a = acquire(scheme, &x, &set, &arms, noise.as_ref(), 9, 1e3).unwrap();
                    let e = match &noise {
                        Some(n) => n.samples(9, scheme.detector_samples(20)),
                        None => vec![0.0; scheme.detector_samples(20)],
                    };
                    let (y, s) = dense_equations(scheme, &x, &p, &arms, &e);
                    assert_eq!(a.y.len(), 20);
                    assert_eq!(a.samples.len(), scheme.detector_samples(20));
                    for (u, v) in a.y.iter().zip(&y).chain(a.samples.iter().zip(&s)) {
                        assert!(close(*u, *v, scale), "{scheme:?} {noise:?}: {u} vs {v}");
                    }
                }
            }
        }
    }
}

#[test]
fn noise_free_schemes_follow_their_affine_models() {
    // SCB: B₁ − B₂ = k'·Âx; double-arm: (k'/2)·Âx + ((k₊ − k₋)/2)·Σx + b₊ − b₋; the
    // others as in the module documentation. Âx and Px are evaluated densely.
    let x = object(64);
    let sum: f64 = x.iter().sum();
    for set in small_sets() {
        let p = dense(&set);
        for arms in [
            ScalarArms::paper_imbalanced(),
            ScalarArms::from_k_prime(3.0),
            ScalarArms {
                k_plus: 0.37,
                k_minus: 2.9,
                b_plus: -4.0,
                b_minus: 11.0,
            },
        ] {
            for scheme in Scheme::all() {
                let a = acquire(scheme, &x, &set, &arms, None, 0, 1e3).unwrap();
                let model = scheme.model(&arms, sum);
                for (row, &yi) in p.iter().zip(&a.y) {
                    let ax = match scheme.form() {
                        PatternForm::ZeroOne => dot(row, &x),
                        PatternForm::PlusMinusOne => {
                            row.iter().zip(&x).map(|(r, v)| (2.0 * r - 1.0) * v).sum()
                        }
                    };
                    let expect = model.gain * ax + model.sum_coefficient * sum + model.constant;
                    assert!(close(yi, expect, 4.0 * sum), "{scheme:?}: {yi} vs {expect}");
                }
            }
            // The stated closed forms of the two paper identities.
            let scb = Scheme::SecondaryComplementaryBalancing.model(&arms, sum);
            assert_eq!(scb.gain, arms.k_prime());
            assert_eq!((scb.sum_coefficient, scb.constant), (0.0, 0.0));
            let da = Scheme::DoubleArm.model(&arms, sum);
            assert_eq!(da.gain, arms.k_prime() / 2.0);
            assert_eq!(da.sum_coefficient, (arms.k_plus - arms.k_minus) / 2.0);
            assert_eq!(da.constant, arms.b_plus - arms.b_minus);
        }
    }
}

#[test]
fn scb_identity_holds_to_rounding_and_double_arm_offset_is_visible() {
    let x = object(64);
    let arms = ScalarArms::paper_imbalanced();
    for set in small_sets() {
        let scb = acquire(
            Scheme::SecondaryComplementaryBalancing,
            &x,
            &set,
            &arms,
            None,
            0,
            DEFAULT_DMD_RATE_HZ,
        )
        .unwrap();
        let mut ahat = vec![0.0; 20];
        scb.operator.apply(&x, &mut ahat);
        let sum: f64 = x.iter().sum();
        for (y, a) in scb.y.iter().zip(&ahat) {
            // A few roundings of values up to k'·Σx ≈ 3e4: 1e-12 relative of that.
            assert!((y - arms.k_prime() * a).abs() <= 1e-12 * arms.k_prime() * sum);
        }
        let da = acquire(Scheme::DoubleArm, &x, &set, &arms, None, 0, 1e3).unwrap();
        let offset = (arms.k_plus - arms.k_minus) / 2.0 * sum + arms.b_plus - arms.b_minus;
        // −0.005·Σx − 4 ≈ −45 here: far above rounding, so the check below sees it.
        assert!(offset < -40.0, "{offset}");
        for (y, a) in da.y.iter().zip(&ahat) {
            assert!((y - (arms.k_prime() / 2.0 * a + offset)).abs() <= 1e-12 * 3.0 * sum);
        }
    }
}

#[test]
fn frames_samples_and_time_per_scheme() {
    let x = object(64);
    let set = random_set(8, 8, 20, 1).unwrap();
    let expect = [
        (Scheme::Traditional, 20, 20),
        (Scheme::SingleArmComplementary, 40, 40),
        (Scheme::DoubleArm, 20, 40),
        (Scheme::SecondaryComplementaryBalancing, 40, 40),
        (Scheme::TraditionalZeroMean, 20, 20),
        (Scheme::DoubleArmCalibrated, 36, 72),
        (Scheme::DoubleArmOffset, 20, 40),
    ];
    for (scheme, frames, samples) in expect {
        let a = acquire(
            scheme,
            &x,
            &set,
            &ScalarArms::ideal(),
            None,
            0,
            DEFAULT_DMD_RATE_HZ,
        )
        .unwrap();
        assert_eq!(a.measurements, 20);
        assert_eq!((a.dmd_frames, a.detector_samples), (frames, samples));
        assert_eq!(a.samples.len(), samples);
        assert_eq!(a.acquisition_time_s, frames as f64 / 22_727.0);
        assert_eq!(a.operator.rows(), 20);
        assert_eq!(a.operator.cols(), 64);
    }
}

#[test]
fn seeds_repeat_and_differ() {
    let x = object(64);
    let set = random_set(8, 8, 20, 1).unwrap();
    let noise = AdditiveNoise::poisson(3.0);
    let arms = ScalarArms::paper_imbalanced();
    for scheme in Scheme::all() {
        let run = |seed| {
            acquire(scheme, &x, &set, &arms, Some(&noise), seed, 1e3)
                .unwrap()
                .y
        };
        let a = run(5);
        let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a), bits(&run(5)));
        assert_ne!(a, run(6));
    }
}

#[test]
fn noise_means_cancel_only_in_complementary_differences() {
    // Exponential noise with σ = 10 has mean 10. Over M = 4096 measurements the residual
    // y − (noise-free y) has mean k·10 for traditional and 0 for the differences. Standard
    // error of the residual mean: k·σ/√M (one draw) or σ·√(k₊² + k±²)/√M (two draws), at
    // most 0.32 here; tolerance 5 SE.
    let x = object(1024);
    let set = random_set(32, 32, 4096, 8).unwrap();
    let arms = ScalarArms::ideal();
    let noise = AdditiveNoise::exponential(10.0);
    for scheme in Scheme::all() {
        let clean = acquire(scheme, &x, &set, &arms, None, 0, 1e3).unwrap();
        let noisy = acquire(scheme, &x, &set, &arms, Some(&noise), 3, 1e3).unwrap();
        // The calibrated scheme's measurements are fractions of the object total: scale
        // them back. Its calibration means (8 frames each) are shared by every
        // measurement, so their error does not average out over M.
        let scale = match scheme {
            Scheme::DoubleArmCalibrated => x.iter().sum::<f64>(),
            _ => 1.0,
        };
        let mean = noisy
            .y
            .iter()
            .zip(&clean.y)
            .map(|(a, b)| (a - b) * scale)
            .sum::<f64>()
            / 4096.0;
        let expected = match scheme {
            Scheme::Traditional | Scheme::TraditionalZeroMean => 10.0,
            _ => 0.0,
        };
        let se = match scheme {
            Scheme::DoubleArmCalibrated => 10.0 * (2.0 / 8.0 + 2.0 / 4096f64).sqrt(),
            _ => 10.0 * 2f64.sqrt() / 64.0,
        };
        assert!((mean - expected).abs() < 5.0 * se, "{scheme:?}: {mean}");
    }
}

#[test]
fn bad_inputs_name_their_fields() {
    let set = random_set(8, 8, 20, 1).unwrap();
    let x = object(64);
    let arms = ScalarArms::ideal();
    let t = Scheme::DoubleArm;
    let field = |r: Result<Acquisition>| {
        let e = r.unwrap_err();
        assert!(e.is_user_error());
        e.to_string()
    };
    assert!(field(acquire(t, &x[..63], &set, &arms, None, 0, 1e3)).contains("`object`"));
    let mut bad = x.clone();
    bad[7] = f64::NAN;
    assert!(field(acquire(t, &bad, &set, &arms, None, 0, 1e3)).contains("`object`"));
    for rate in [0.0, -1.0, f64::INFINITY, f64::NAN] {
        assert!(field(acquire(t, &x, &set, &arms, None, 0, rate)).contains("`dmd_rate_hz`"));
    }
    let noise = AdditiveNoise::gaussian(-1.0);
    assert!(field(acquire(t, &x, &set, &arms, Some(&noise), 0, 1e3)).contains("`noise.std`"));
    let arms_bad = ScalarArms {
        k_minus: 0.0,
        ..arms
    };
    assert!(field(acquire(t, &x, &set, &arms_bad, None, 0, 1e3)).contains("`k_minus`"));
    let arms_bad = ScalarArms {
        b_plus: f64::INFINITY,
        ..arms
    };
    assert!(field(acquire(t, &x, &set, &arms_bad, None, 0, 1e3)).contains("`b_plus`"));
}

#[test]
fn reproduces_the_tval3_reference_measurements() {
    // validation/tval3-phantom (README there): 10 % random set (1638 patterns, seed
    // 0x5EED0001) on the 128×128 phantom. y = Âx (ideal single-arm), y_imb = the paper's
    // imbalanced double-arm case, y_bal = SCB with the same arms = 2.03·y.
    use crate::report::npy;
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/validation/tval3-phantom/");
    let load = |name: &str| {
        npy::read(std::path::Path::new(&format!("{dir}{name}")))
            .unwrap()
            .to_f64()
    };
    let x = load("phantom_x.npy");
    let set = random_set(128, 128, 1638, 0x5EED_0001).unwrap();
    let sum: f64 = x.iter().sum();
    for (scheme, arms, file) in [
        (
            Scheme::SingleArmComplementary,
            ScalarArms::ideal(),
            "phantom_r10_y.npy",
        ),
        (
            Scheme::DoubleArm,
            ScalarArms::paper_imbalanced(),
            "phantom_r10_y_imb.npy",
        ),
        (
            Scheme::SecondaryComplementaryBalancing,
            ScalarArms::paper_imbalanced(),
            "phantom_r10_y_bal.npy",
        ),
    ] {
        let reference = load(file);
        let a = acquire(scheme, &x, &set, &arms, None, 0, DEFAULT_DMD_RATE_HZ).unwrap();
        assert_eq!(a.y.len(), reference.len());
        for (u, v) in a.y.iter().zip(&reference) {
            // Sums of up to 16384 values of at most 255 in another order: 1e-12 of 3·Σx.
            assert!((u - v).abs() <= 1e-12 * 3.0 * sum, "{scheme:?}: {u} vs {v}");
        }
    }
}

#[test]
fn experiment_files_spell_schemes_and_arms() {
    use crate::scene::parse_ron;
    use std::path::Path;
    let p = Path::new("e.ron");
    for s in Scheme::all() {
        assert_eq!(parse_ron::<Scheme>(&format!("{s:?}"), p).unwrap(), s);
    }
    let arms: ScalarArms = parse_ron(
        "(k_plus: 1.01, k_minus: 1.02, b_plus: 1.0, b_minus: 5.0)",
        p,
    )
    .unwrap();
    assert_eq!(arms, ScalarArms::paper_imbalanced());
    assert!(parse_ron::<Scheme>("scb", p).is_err());
}
