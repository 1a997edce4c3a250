//! The optimiser's unit tests (closed-form objectives and searches).

use super::*;

/// An evaluation with the given metrics and matched diodes.
fn evaluation(metrics: BenchMetrics) -> Evaluation {
    Evaluation {
        settings: Vec::new(),
        metrics,
        cmrr: None,
        cmrr_electronics_db: None,
        responsivity_scale: Some([1.0, 1.0]),
        arrivals: 0,
        quality: None,
        spots: None,
    }
}

#[test]
fn free_parses() {
    let f = Free::parse("a.b=-1:2.5").unwrap();
    assert_eq!((f.lo, f.hi), (-1.0, 2.5));
    for bad in ["a", "a=1", "a=2:1", "a=x:1", "a=1:inf"] {
        assert!(Free::parse(bad).unwrap_err().is_user_error(), "{bad}");
    }
}

/// Balance means the imbalance: the offset enters only with a weight the user gives.
#[test]
fn balance_terms_are_explicit_and_the_offset_is_off_by_default() {
    let n = [10u64; 4];
    let metric = |v: f64| crate::transport::metrics::TracedValue::total(&n, &[v / 4.0; 4]);
    // k₊ = 1.0, k₋ = 0.98: imbalance 0.0101; b₊ = 1, b₋ = 10: offset term 9/11 = 0.818.
    let values = [
        metric(1.0),
        metric(0.98),
        metric(1.98),
        metric(0.02 / 1.98),
        metric(1.0),
        metric(10.0),
        metric(9.0),
        metric(1.0),
        metric(1.0),
        metric(0.0),
        metric(0.0),
        metric(1.0),
    ];
    let m = evaluation(BenchMetrics { values });
    let t = terms(&Objective::BALANCE, &m, 1.0, None);
    assert_eq!(t.len(), 2, "{t:?}");
    let (f, _) = objective(&Objective::BALANCE, &m, 1.0, None);
    assert!((f - 0.02 / 1.98).abs() < 1e-12, "{f}");
    let with_offset = Objective::Balance {
        min_fraction: 0.9,
        offset_weight: 0.5,
    };
    let t = terms(&with_offset, &m, 1.0, None);
    assert_eq!(t.len(), 3);
    assert!((t[1].value - 0.5 * 9.0 / 11.0).abs() < 1e-12, "{t:?}");
}

/// A bench whose k₊ = 1 and k₋ = 0.9 + 0.2·u (A/W) over the unit box, traced in four
/// batches with a small per-batch spread (so the imbalance has a standard error), with
/// diode responsivity scales `scale`.
fn closed_form(u: f64, scale: [f64; 2]) -> Evaluation {
    use crate::transport::metrics::TracedValue;
    let n = [10u64; 4];
    let spread = [1.0 + 1e-5, 1.0 - 1e-5, 1.0 + 2e-5, 1.0 - 2e-5];
    let kp: Vec<f64> = spread.iter().map(|s| 0.25 * s).collect();
    let km: Vec<f64> = spread
        .iter()
        .rev()
        .map(|s| (0.9 + 0.2 * u) / 4.0 * s)
        .collect();
    let diff: Vec<f64> = kp.iter().zip(&km).map(|(a, b)| a - b).collect();
    let sum: Vec<f64> = kp.iter().zip(&km).map(|(a, b)| a + b).collect();
    let flat = |v: f64| TracedValue::total(&n, &[v / 4.0; 4]);
    let mut values = std::array::from_fn(|_| flat(1.0));
    values[BenchMetric::KPlus as usize] = TracedValue::total(&n, &kp);
    values[BenchMetric::KMinus as usize] = TracedValue::total(&n, &km);
    values[BenchMetric::KPrime as usize] = TracedValue::total(&n, &sum);
    values[BenchMetric::Imbalance as usize] = TracedValue::ratio(&diff, &sum);
    Evaluation {
        responsivity_scale: Some(scale),
        ..evaluation(BenchMetrics { values })
    }
}

/// With diodes of responsivity ratio r = s₊/s₋ ≠ 1, the detector's output balances where
/// s₊k₊ = s₋k₋, at the optical imbalance ι = (1 − r)/(1 + r), not at ι = 0. On the closed-form
/// bench (k₊ = 1, k₋ = 0.9 + 0.2u, s = [1, 0.97]) that is k₋ = 1/0.97, u* = (1/0.97 − 0.9)/0.2
/// = 0.6546, while the optical balance is at u = 0.5. The search finds u* within its
/// stopping size (1e-3 of the box) plus one last shrink step (2e-3 in all), i.e. ι within
/// 2e-3·|dι/du| (|dι/du| = 0.4·k₊/(k₊ + k₋)² < 0.11 here). The electrical term's standard
/// error is the optical one's times dι′/dι = 4r/(r(1 + ι) + (1 − ι))² (delta method).
#[test]
fn balance_balances_the_detector_not_the_optics() {
    let s = [1.0, 0.97];
    let r = s[0] / s[1];
    let mut f = |u: &[f64]| -> Result<(f64, f64)> {
        Ok(objective(
            &Objective::BALANCE,
            &closed_form(u[0], s),
            1.0,
            None,
        ))
    };
    let (u, _) = nelder_mead(&mut f, &[0.3], 0.25, 500).unwrap();
    let u_star = (1.0 / 0.97 - 0.9) / 0.2;
    assert!((u[0] - u_star).abs() < 2e-3, "u = {}, u* = {u_star}", u[0]);
    let at = closed_form(u[0], s);
    let iota = at.metrics[BenchMetric::Imbalance].value;
    let target = (1.0 - r) / (1.0 + r);
    assert!(
        (iota - target).abs() < 2e-3 * 0.11,
        "ι = {iota}, (1 − r)/(1 + r) = {target}"
    );
    let e = at.electrical_imbalance().unwrap();
    // dι′/dι = 4r/(r(1 + ι) + (1 − ι))² is 1.00 at ι = (1 − r)/(1 + r).
    assert!(e.value.abs() < 2e-3 * 0.11 * 1.01, "ι′ = {}", e.value);
    // The term is the electrical imbalance with its propagated standard error.
    let start = closed_form(0.3, s);
    let t = terms(&Objective::BALANCE, &start, 1.0, None);
    let i0 = &start.metrics[BenchMetric::Imbalance];
    let slope = 4.0 * r / (r * (1.0 + i0.value) + (1.0 - i0.value)).powi(2);
    let e0 = start.electrical_imbalance().unwrap();
    assert_eq!(t[0].name, BALANCE_TERM);
    assert!((t[0].value - e0.value.abs()).abs() < 1e-15, "{t:?}");
    assert!(i0.stderr() > 0.0);
    assert!(
        (t[0].stderr / (slope * i0.stderr()) - 1.0).abs() < 1e-9,
        "{t:?}"
    );
    // Matched diodes: the optical balance, u = 0.5.
    let mut g = |u: &[f64]| -> Result<(f64, f64)> {
        Ok(objective(
            &Objective::BALANCE,
            &closed_form(u[0], [1.0, 1.0]),
            1.0,
            None,
        ))
    };
    let (u, _) = nelder_mead(&mut g, &[0.3], 0.25, 500).unwrap();
    assert!((u[0] - 0.5).abs() < 2e-3, "u = {}", u[0]);
}

#[test]
fn nelder_mead_finds_a_quadratic_minimum() {
    let mut f = |u: &[f64]| -> Result<(f64, f64)> {
        Ok(((u[0] - 0.3).powi(2) + 2.0 * (u[1] - 0.7).powi(2), 0.0))
    };
    let (u, stop) = nelder_mead(&mut f, &[0.5, 0.5], 0.25, 500).unwrap();
    assert_eq!(stop, SearchStop::SimplexSize);
    assert!(
        (u[0] - 0.3).abs() < 2e-3 && (u[1] - 0.7).abs() < 2e-3,
        "{u:?}"
    );
}

/// A spot offset by d from the diode's centre: moving the diode by x leaves the centroid at
/// d − x, so the margin R − |d − x| − k·σ is largest at x = d. The search finds it within
/// its stopping size (1e-3 of the box) plus one step of the simplex's last shrink.
#[test]
fn the_centre_objective_moves_the_diode_onto_its_spot() {
    let (r, sigma, d, range) = (1.5e-3, 0.2e-3, 1.15e-3, 4e-3);
    let spot = |x: f64| crate::trace::irradiance::MapStats {
        active_w: 1.0,
        active_stderr_w: 0.0,
        plate_w: 0.0,
        centroid_m: [d - x, 0.0],
        centroid_stderr_m: [0.0, 0.0],
        rms_radius_m: sigma,
        spill: 0.0,
    };
    // The other diode's spot centred (its margin R − kσ, never the smaller one), or 0.3 mm
    // off its centre: then the smaller margin alone would be flat wherever the moved
    // diode's offset is below 0.3 mm, and the average still pulls it to the centre.
    let centred = centre_margin_m(&spot(d), r, CENTRE_RMS_RADII);
    assert!((centred - (r - 2.0 * sigma)).abs() < 1e-15);
    for other in [centred, centred - 0.3e-3] {
        let mut f = |u: &[f64]| -> Result<(f64, f64)> {
            let x = -range / 2.0 + u[0] * range;
            let m = centre_margin_m(&spot(x), r, CENTRE_RMS_RADII);
            Ok((centre_value([m, other], [r, r]), 0.0))
        };
        let (u, _) = nelder_mead(&mut f, &[0.5], 0.25, 500).unwrap();
        let x = -range / 2.0 + u[0] * range;
        assert!(
            (x - d).abs() < 2e-3 * range,
            "x = {x}, d = {d}, other {other}"
        );
    }
    // The value in closed form: m = 1, 3 over R = 2: −(1 + 2)/4; its error weights the
    // smaller margin's by 3/4 and the larger's by 1/4.
    assert_eq!(centre_value([3.0, 1.0], [2.0, 5.0]), -0.75);
    let se = centre_value_stderr([3.0, 1.0], [0.4, 0.2], [2.0, 5.0]);
    assert!((se - (0.15f64).hypot(0.1) / 2.0).abs() < 1e-15, "{se}");
    // No light mapped: −∞, the worst margin.
    let dark = crate::trace::irradiance::MapStats {
        active_w: 0.0,
        ..spot(0.0)
    };
    assert_eq!(
        centre_margin_m(&dark, r, CENTRE_RMS_RADII),
        f64::NEG_INFINITY
    );
    // At the start (x = 0) the margin is R − d − kσ; at the optimum R − kσ.
    let before = centre_margin_m(&spot(0.0), r, CENTRE_RMS_RADII);
    assert!((before - (r - d - 2.0 * sigma)).abs() < 1e-15);
}

/// The spot is the collected light: on a map of the − diode (active radius 2 mm, 1 mm bins)
/// whose − branch puts 1 W on each of two active bins at (0.5, ±0.5) mm and 3 W of another
/// diffraction order on the housing's plate at (−3.5, 0.5) mm, with 1 W of pattern-independent
/// light on the active area at (−0.5, −0.5) mm, the spot's centroid is (0.5, 0) mm and its RMS
/// radius 0.5 mm, so the margin is 2 − 0.5 − 2·0.5 = 0.5 mm, and neither the plate's nor the
/// pattern-independent light's power or noise moves it; the share of the branch on the plate
/// is 3/5. All of the state's light on both layers (the definition before the collected spot)
/// puts the centroid at (−5/3, 1/6) mm and the RMS radius at 1.92 mm, so the margin at −3.5 mm:
/// the plate light swamps the spot.
#[test]
fn the_spot_is_the_collected_light_not_the_plate_or_the_pattern_independent_light() {
    use crate::trace::irradiance::{IrradianceMaps, Window, branch_index, index};
    let window = Window {
        frame: crate::optics::geometry::Frame::new(glam::DVec3::ZERO, glam::DVec3::Z, None),
        radius_m: 2e-3,
        half_width_m: 4e-3,
        housing: Some(0),
    };
    let bins = 8;
    // Row 0 at +v, column 0 at −u: centres at ±0.5, ±1.5, … mm.
    let bin = |x_mm: f64, y_mm: f64| {
        let col = (x_mm + 4.0).floor() as usize;
        let row = bins - 1 - (y_mm + 4.0).floor() as usize;
        row * bins + col
    };
    let build = |plate_totals: (f64, f64), common_totals: (f64, f64)| {
        let mut maps = IrradianceMaps::new([window; 2], Vec::new(), bins);
        maps.batches = 2;
        let (d, b) = (1, 1);
        let mut put = |world: usize, l: usize, i: usize, (a, c): (f64, f64)| {
            // The state's map (state 1: every unit −) holds the branch and the common light,
            // the branch sums the branch alone.
            for s in if world == 2 { vec![0, 1, 2] } else { vec![b] } {
                let k = index(bins, d, s, l, i);
                maps.power_w[k] += a + c;
                maps.sum_sq[k] += a * a + c * c;
            }
            if world != 2 {
                let k = branch_index(bins, d, b, l, i);
                maps.branch_w[k] += a + c;
                maps.branch_sum_sq[k] += a * a + c * c;
            }
        };
        put(1, 0, bin(0.5, 0.5), (0.6, 0.4));
        put(1, 0, bin(0.5, -0.5), (0.3, 0.7));
        put(1, 1, bin(-3.5, 0.5), plate_totals);
        put(2, 0, bin(-0.5, -0.5), common_totals);
        maps
    };
    let maps = build((1.0, 2.0), (0.5, 0.5));
    let s = spot(&maps, 1, CENTRE_RMS_RADII);
    let close = |a: f64, b: f64| (a - b).abs() < 1e-15;
    assert!(close(s.stats.centroid_m[0], 0.5e-3) && close(s.stats.centroid_m[1], 0.0));
    assert!(
        close(s.stats.rms_radius_m, 0.5e-3),
        "{}",
        s.stats.rms_radius_m
    );
    assert!(close(s.margin_m, 0.5e-3), "{}", s.margin_m);
    assert!(close(s.offset_m, 0.5e-3) && s.margin_stderr_m > 0.0);
    assert_eq!((s.stats.active_w, s.stats.plate_w), (2.0, 3.0));
    assert!((s.stats.spill - 0.6).abs() < 1e-12, "{}", s.stats.spill);
    // Other plate and pattern-independent light, other noise: the same spot and errors.
    let other = spot(&build((2.9, 0.1), (0.0, 4.0)), 1, CENTRE_RMS_RADII);
    assert_eq!(
        (other.margin_m, other.margin_stderr_m, other.offset_stderr_m),
        (s.margin_m, s.margin_stderr_m, s.offset_stderr_m)
    );
    // The state's light on both layers: pulled 2.2 mm toward the plate's order.
    let all = maps.stats(1, 1);
    assert!(close(all.centroid_m[0], -5e-3 / 3.0) && close(all.centroid_m[1], 1e-3 / 6.0));
    assert!(centre_margin_m(&all, 2e-3, CENTRE_RMS_RADII) < -3e-3);
    // No pattern light on the active area (only on the plate): no spot, −∞.
    let mut dark = IrradianceMaps::new([window; 2], Vec::new(), bins);
    dark.batches = 2;
    dark.branch_w[branch_index(bins, 1, 1, 1, bin(-3.5, 0.5))] = 3.0;
    assert_eq!(spot(&dark, 1, CENTRE_RMS_RADII).margin_m, f64::NEG_INFINITY);
}
