//! The profiled misfit on synthetic frames: frames made from the model's light by known
//! nuisances give those nuisances back and a zero misfit; noise of the measured size gives
//! χ²/dof near 1.

use super::measured::{Measured, MeasuredSequence};
use super::model::{ModelFrames, SlowTerms, profile};
use crate::acquisition::Sequence;

fn synthetic(noise: f64) -> (ModelFrames, Measured) {
    let m = 64;
    let light: Vec<[f64; 2]> = (0..m)
        .map(|i| {
            let t = i as f64 / m as f64;
            [1e-6 * (1.0 + t), 2e-6 * (1.5 - t * t)]
        })
        .collect();
    let nu = [3e3, 2.9e3, 0.01, 1e4, 0.02, 1.1e4, -0.03];
    let mut state = 12345u64;
    let mut gauss = || {
        let mut s = 0.0;
        for _ in 0..12 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            s += (state >> 11) as f64 / (1u64 << 53) as f64;
        }
        s - 6.0
    };
    let values = light
        .iter()
        .map(|l| {
            [
                nu[0] * l[0] - nu[1] * l[1] + nu[2] + noise * gauss(),
                nu[3] * l[0] + nu[4] + noise * gauss(),
                nu[5] * l[1] + nu[6] + noise * gauss(),
            ]
        })
        .collect();
    let model = ModelFrames {
        light_a: vec![light],
        var_a2: vec![vec![[0.0; 2]; m]],
    };
    let measured = Measured {
        dir: std::path::PathBuf::from("."),
        units: (8, 8),
        base_patterns: m,
        sequences: vec![MeasuredSequence {
            sequence: Sequence::Base,
            values,
            start_s: (0..m).map(|i| 44e-6 * i as f64).collect(),
            flagged: vec![false; m],
            patterns_sha256: String::new(),
        }],
        noise_v: [noise.max(1e-9); 3],
        noise_dof: 14,
    };
    (model, measured)
}

#[test]
fn profiled_nuisances_are_recovered_and_chi2_follows_the_noise() {
    let (model, measured) = synthetic(0.0);
    let p = profile(&model, &measured, None, &SlowTerms::default()).unwrap();
    let want = [3e3, 2.9e3, 0.01, 1e4, 0.02, 1.1e4, -0.03];
    for (a, b) in p.nuisances.iter().zip(want) {
        assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0), "{a} vs {b}");
    }
    assert!(p.chi2 < 1e-6, "{}", p.chi2);
    let (model, measured) = synthetic(1e-3);
    let p = profile(&model, &measured, None, &SlowTerms::default()).unwrap();
    let dof = (3 * 64 - 7) as f64;
    let r = p.chi2 / dof;
    assert!((0.7..1.3).contains(&r), "χ²/dof {r}");
}

/// Under a gain prior consistent with the synthetic frames' scales (nominal × a lamp scale of
/// 1.7) the same nuisances come back with the lamp scale, the prior's four rows count in the
/// degrees of freedom, and noise gives χ²/dof near 1.
#[test]
fn a_consistent_gain_prior_recovers_the_scales_and_the_lamp_power() {
    use super::gains::{GainPrior, PRIOR_ROWS};
    let want = [3e3, 2.9e3, 0.01, 1e4, 0.02, 1.1e4, -0.03];
    let prior = GainPrior {
        nominal: [want[0], want[1], want[3], want[5]].map(|s| s / 1.7),
        tolerance: 0.05,
    };
    let (model, measured) = synthetic(0.0);
    let p = profile(&model, &measured, Some(&prior), &SlowTerms::default()).unwrap();
    for (a, b) in p.nuisances.iter().zip(want) {
        assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0), "{a} vs {b}");
    }
    let lamp = p.lamp_scale.unwrap();
    assert!((lamp - 1.7).abs() < 1e-6, "lamp scale {lamp}");
    assert!(p.chi2 < 1e-6, "{}", p.chi2);
    assert_eq!(p.prior_rows, PRIOR_ROWS);
    assert_eq!(p.residuals.len(), 3 * 64 + PRIOR_ROWS);
    assert_eq!(p.linear_parameters(), 7);
    assert_eq!(p.dof(2), 3 * 64 + PRIOR_ROWS - 7 - 2);
    let (model, measured) = synthetic(1e-3);
    let p = profile(&model, &measured, Some(&prior), &SlowTerms::default()).unwrap();
    let r = p.chi2 / p.dof(0) as f64;
    assert!((0.7..1.3).contains(&r), "χ²/dof {r}");
}

/// What the prior is for: a model whose − arm collects 20 % less light than the bench's is
/// explained exactly by free channel scales (the − scales take the loss), but not under a 1 %
/// prior on the gains, where the arms' ratio must come from the light. The held fit costs at
/// most the prior's penalty at the free fit's scales, Σ(ρ − ρ̄)²/(τ·ρ̄)² (keeping the free
/// scales is one of the fits it chooses among; ≈ 4·0.125²/(0.01·1.125)² ≈ 494 for scales
/// exactly (1, 1.25, 1, 1.25), less where the noise moves the RF pair), and more than five of
/// χ²'s own standard deviations, 5·√(2·dof) ≈ 96, where the frames (noise 10⁻⁴ V) pin the
/// scales to about the prior's width.
#[test]
fn a_gain_prior_keeps_an_arm_s_loss_out_of_its_gains() {
    use super::gains::GainPrior;
    let want = [3e3, 2.9e3, 0.01, 1e4, 0.02, 1.1e4, -0.03];
    let tolerance = 0.01;
    let nominal = [want[0], want[1], want[3], want[5]];
    let prior = GainPrior { nominal, tolerance };
    let (mut model, measured) = synthetic(1e-4);
    for l in &mut model.light_a[0] {
        l[1] *= 0.8;
    }
    let free = profile(&model, &measured, None, &SlowTerms::default()).unwrap();
    let r = free.chi2 / free.dof(0) as f64;
    assert!(
        (0.7..1.3).contains(&r),
        "free scales absorb the loss: χ²/dof {r}"
    );
    let rho: Vec<f64> = [0, 1, 3, 5]
        .iter()
        .zip(nominal)
        .map(|(&at, n)| free.nuisances[at] / n)
        .collect();
    let mean = rho.iter().sum::<f64>() / 4.0;
    let penalty: f64 = rho
        .iter()
        .map(|p| ((p - mean) / (tolerance * mean)).powi(2))
        .sum();
    let held = profile(&model, &measured, Some(&prior), &SlowTerms::default()).unwrap();
    let excess = held.chi2 - free.chi2;
    let spread = (2.0 * free.dof(0) as f64).sqrt();
    assert!(
        excess > 5.0 * spread && excess <= penalty * (1.0 + 1e-9),
        "the prior holds the gains: χ² {} against {} free, penalty {penalty}",
        held.chi2,
        free.chi2
    );
}

/// The equally good range along a scan spans every point within the limit, a second valley
/// across a ridge included, not only the stretch around the optimum.
#[test]
fn the_equally_good_range_reaches_a_second_valley_across_a_ridge() {
    use super::identify::equally_good;
    let ts: Vec<f64> = (0..13).map(|k| -0.3 + 0.1 * k as f64).collect();
    // The optimum at t = 0 (index 3), a ridge, the mirror valley at indices 9 and 10.
    let d = [
        30.0, 12.0, 2.0, 0.0, 3.0, 40.0, 90.0, 60.0, 9.0, 1.0, 2.5, 20.0, 50.0,
    ];
    // Around the optimum alone, indices 2..=4 (1..=5 with one point beyond): the old range.
    assert_eq!(equally_good(&ts, &d, 4.0), (1, 11));
    // A scan point below the optimum lowers the floor: the optimum's neighbours (2 and 3 above
    // it) now count against −3 and fall out, the optimum's own index is always held: 3..=9.
    let d2 = [
        30.0, 12.0, 2.0, 0.0, 3.0, 40.0, 90.0, 60.0, 9.0, -3.0, 2.5, 20.0, 50.0,
    ];
    assert_eq!(equally_good(&ts, &d2, 4.0), (2, 10));
    // Nothing else within the limit: the optimum and one point each way.
    let mut d3 = vec![30.0; 13];
    d3[3] = 0.0;
    assert_eq!(equally_good(&ts, &d3, 4.0), (2, 4));
    // The optimum at the scan's end: the range stops at the bound.
    let mut d4 = vec![30.0; 13];
    d4[12] = 0.0;
    let ts4: Vec<f64> = (0..13).map(|k| -1.2 + 0.1 * k as f64).collect();
    assert_eq!(equally_good(&ts4, &d4, 4.0), (11, 12));
}

/// The joint scan's ranges: on a 7 × 7 grid two separate patches within the limit (one around
/// levels (1, 5), one at (5, 2)) give each variable the span of both, one level further each
/// way; a grid point below the optimum lowers the floor; nothing within the limit gives None.
#[test]
fn the_grid_ranges_span_every_equally_good_patch() {
    use super::identify::grid_ranges;
    let points = 7;
    let levels: Vec<Vec<usize>> = (0..points * points)
        .map(|f| vec![f % points, f / points])
        .collect();
    let mut d = vec![100.0; points * points];
    let at = |a: usize, b: usize| a + points * b;
    d[at(1, 5)] = 3.0;
    d[at(2, 5)] = 5.0;
    d[at(5, 2)] = 1.0;
    assert_eq!(
        grid_ranges(&levels, &d, points, 4.0),
        vec![Some((0, 6)), Some((1, 6))]
    );
    // A point 10 below the optimum: the others (3, 1 above 0) are now 13 and 11 above it.
    d[at(6, 0)] = -10.0;
    assert_eq!(
        grid_ranges(&levels, &d, points, 4.0),
        vec![Some((5, 6)), Some((0, 1))]
    );
    assert_eq!(
        grid_ranges(&levels, &[100.0; 49], points, 4.0),
        vec![None, None]
    );
}

/// The unshared trace noise's σ: with no such noise and χ²/dof ≤ 1 it is 1/s, the standard
/// deviation of independent noise of the weights' size; it grows as √(4 + 2√2·sd)/(2s).
#[test]
fn the_unshared_sigma_reduces_to_independent_noise() {
    use super::identify::{At, unshared_sigma};
    let at = |chi2_dof: f64, chi2_sd: f64| At {
        chi2: 0.0,
        chi2_dof,
        chi2_sd,
    };
    assert!((unshared_sigma(at(0.8, 0.0), 40.0) - 1.0 / 40.0).abs() < 1e-15);
    assert!((unshared_sigma(at(2.25, 0.0), 40.0) - 1.5 / 40.0).abs() < 1e-15);
    let want = (4.0 + 2.0 * 2f64.sqrt() * 200.0).sqrt() / 80.0;
    assert!((unshared_sigma(at(0.8, 200.0), 40.0) - want).abs() < 1e-15);
    assert!(unshared_sigma(at(0.8, 0.0), 0.0).is_infinite());
}

/// Where the fit goes on from: a scanned point beats the optimum outright only by more than the
/// equally good Δχ² (`better_point`), while above the χ² band any point below the optimum is a
/// start (`lowest_below`), an extra grid's included; nothing below gives None.
#[test]
fn a_restart_needs_a_clear_gain_inside_the_band_and_any_gain_above_it() {
    use super::identify::{GridScan, Identification, Unidentified};
    let line = Unidentified {
        singular_value: 1.0,
        direction: vec![1.0, 0.0],
        range_lo: vec![0.0, 0.0],
        range_hi: vec![1.0, 0.0],
        scan_values: vec![vec![0.0, 0.0], vec![0.5, 0.0], vec![1.0, 0.0]],
        scan_delta_chi2: vec![30.0, -40.0, 5.0],
        delta_chi2_limit: 100.0,
    };
    let grid = |values: Vec<Vec<f64>>, d: Vec<f64>| GridScan {
        variables: vec![0, 1],
        scan_values: values,
        scan_delta_chi2: d,
        delta_chi2_limit: 100.0,
        range_lo: vec![0.0, 0.0],
        range_hi: vec![1.0, 1.0],
    };
    let id = Identification {
        stderr: vec![f64::NAN; 2],
        correlation: vec![vec![1.0, 0.0], vec![0.0, 1.0]],
        singular_values: vec![1.0, 0.0],
        identified: vec![false, true],
        unidentified: vec![line],
        grid: None,
        limit: 100.0,
    };
    // −40 is within the limit of 100: not clearly better, but below the optimum.
    assert_eq!(id.better_point(), None);
    assert_eq!(id.lowest_below(None), Some(vec![0.5, 0.0]));
    // A grid traced about the optimum with a lower point wins; one without does not.
    let extra = grid(vec![vec![0.2, 0.8], vec![0.9, 0.1]], vec![-75.0, 12.0]);
    assert_eq!(id.lowest_below(Some(&extra)), Some(vec![0.2, 0.8]));
    let higher = grid(vec![vec![0.2, 0.8]], vec![3.0]);
    assert_eq!(id.lowest_below(Some(&higher)), Some(vec![0.5, 0.0]));
    // The identification's own grid 150 below: clearly better.
    let deep = Identification {
        grid: Some(grid(vec![vec![0.7, 0.3]], vec![-150.0])),
        ..id.clone()
    };
    assert_eq!(deep.better_point(), Some(vec![0.7, 0.3]));
    // Nothing below the optimum anywhere.
    let flat = Identification {
        unidentified: Vec::new(),
        ..id
    };
    assert_eq!(flat.lowest_below(Some(&higher)), None);
}

/// The replicas' spread replaces the batches' sd(χ²) only where it is larger; it is the sample
/// standard deviation (n − 1), and fewer than two finite replicas leave the estimate alone.
#[test]
fn replicas_raise_the_chi2_spread_only_above_the_batch_estimate() {
    use super::chi2::Expected;
    let e = Expected {
        measurement: 40.0,
        trace: 1900.0,
        sd: 225.0,
        sd_batches: 225.0,
        sd_replicas: 0.0,
    };
    // Sample sd of [2000, 2400, 2800, 3200] about 2600: √((2·600² + 2·200²)/3) = 516.40.
    let wide = e.with_replicas(&[2000.0, 2400.0, 2800.0, 3200.0]);
    let want = (((600.0f64).powi(2) * 2.0 + (200.0f64).powi(2) * 2.0) / 3.0).sqrt();
    assert!(
        (wide.sd_replicas - want).abs() < 1e-9,
        "{}",
        wide.sd_replicas
    );
    assert_eq!(wide.sd, wide.sd_replicas);
    assert_eq!(wide.sd_batches, 225.0);
    assert_eq!(wide.upper(), 1940.0 + 2.0 * want);
    let narrow = e.with_replicas(&[2100.0, 2150.0, 2200.0]);
    assert!((narrow.sd_replicas - 50.0).abs() < 1e-9);
    assert_eq!(narrow.sd, 225.0);
    for few in [&[2100.0][..], &[2100.0, f64::INFINITY]] {
        let same = e.with_replicas(few);
        assert_eq!((same.sd, same.sd_replicas), (225.0, 0.0));
    }
}

/// The records' slow terms: the synthetic frames split into two records, the second with its
/// offsets shifted and both with a 100 Hz hum of known amplitude and phase on each channel.
/// With the slow terms the shifts and amplitudes come back exactly and χ² is 0 without noise;
/// without them the same frames leave a misfit of the hum's size.
#[test]
fn the_records_offset_shifts_and_hum_are_fitted() {
    let (model, mut measured) = synthetic(0.0);
    let m = measured.sequences[0].values.len();
    let half = m / 2;
    let mut second = measured.sequences[0].clone();
    second.sequence = Sequence::Complementary;
    let first = &mut measured.sequences[0];
    second.values = first.values.split_off(half);
    second.flagged = first.flagged.split_off(half);
    second.start_s = first.start_s.split_off(half);
    // Each record's clock starts at its trigger.
    let t0 = second.start_s[0];
    second.start_s.iter_mut().for_each(|t| *t -= t0);
    let shift = [2e-3, -1e-3, 5e-4];
    let amplitude = [3e-3, 1.5e-3, 1e-3];
    let hum = |t: f64, o: usize, r: usize| {
        amplitude[o] * (std::f64::consts::TAU * 100.0 * t + 0.4 + 1.1 * (o + 3 * r) as f64).sin()
    };
    for (r, q) in [&mut *first, &mut second].into_iter().enumerate() {
        for (v, &t) in q.values.iter_mut().zip(&q.start_s) {
            for o in 0..3 {
                v[o] += hum(t, o, r) + if r == 1 { shift[o] } else { 0.0 };
            }
        }
    }
    measured.sequences.push(second);
    let split = |l: &Vec<Vec<[f64; 2]>>| vec![l[0][..half].to_vec(), l[0][half..].to_vec()];
    let model = ModelFrames {
        light_a: split(&model.light_a),
        var_a2: split(&model.var_a2),
    };
    let slow = SlowTerms {
        hum_hz: vec![100.0],
    };
    let p = profile(&model, &measured, None, &slow).unwrap();
    assert!(p.chi2 < 1e-6, "{}", p.chi2);
    assert_eq!(p.linear_parameters(), 7 + 3 + 2 * 6);
    let (shifts, amps) = slow.split(2, &p.slow);
    for o in 0..3 {
        assert_eq!(shifts[0][o], 0.0);
        assert!((shifts[1][o] - shift[o]).abs() < 1e-9, "{shifts:?}");
        for r in 0..2 {
            assert!((amps[r][0][o] - amplitude[o]).abs() < 1e-9, "{amps:?}");
        }
    }
    // Without the hum terms the frames' hum is left in the misfit: at the 1e-9 V noise floor
    // of the synthetic frames, far above any χ² of noise.
    let without = profile(&model, &measured, None, &SlowTerms::default()).unwrap();
    assert!(without.chi2 > 1e6, "{}", without.chi2);
}

/// A joint mirror valley: two lens decentres fitted at (−3, −3) mm with the second identified
/// at ± 0.4 mm; a 7 × 7 grid point equally good at (+1, +1) mm lies 4 mm away, beyond
/// 2 SE + one grid step (1.8 mm), so the second is another valley's too. The same point beyond
/// the limit, or one within reach, leaves it identified.
#[test]
fn an_equally_good_joint_grid_point_far_off_unidentifies_a_variable() {
    use super::identify::{GridScan, joint_second_valleys};
    use crate::pipeline::optimise::Free;
    let lens = |path: &str| Free {
        path: path.into(),
        lo: -3.0,
        hi: 3.0,
    };
    let free = [lens("a"), lens("b")];
    let u = [0.0, 0.0];
    let grid = |point: [f64; 2], d: f64| GridScan {
        variables: vec![0, 1],
        scan_values: vec![vec![-3.0, -3.0], point.to_vec()],
        scan_delta_chi2: vec![0.0, d],
        delta_chi2_limit: 100.0,
        range_lo: vec![-3.0, -3.0],
        range_hi: vec![3.0, 3.0],
    };
    let identified = [false, true];
    let stderr = [f64::NAN, 0.4];
    assert_eq!(
        joint_second_valleys(&free, &u, &grid([1.0, 1.0], 60.0), 7, &identified, &stderr),
        vec![1]
    );
    assert!(
        joint_second_valleys(&free, &u, &grid([1.0, 1.0], 160.0), 7, &identified, &stderr)
            .is_empty()
    );
    assert!(
        joint_second_valleys(&free, &u, &grid([1.0, -1.5], 10.0), 7, &identified, &stderr)
            .is_empty()
    );
}
