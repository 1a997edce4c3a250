//! The irradiance maps' tests.

use super::*;
use crate::optics::Arm;
use crate::trace::tally::{EXTRA_SLOTS, slot_detected};

/// A named surface must exist and be named once; the error names the field, not a flag.
#[test]
fn unknown_or_repeated_surface_names_are_refused() {
    let bench = crate::trace::testing::paper_bench_with_mask();
    let first = bench.elements()[bench.surfaces()[0].element].clone();
    assert_eq!(
        surface_maps(&bench, std::slice::from_ref(&first))
            .unwrap()
            .len(),
        1
    );
    let e = surface_maps(&bench, &["no_such".into()])
        .unwrap_err()
        .to_string();
    assert!(e.contains("no_such") && e.contains(&first), "{e}");
    let e = surface_maps(&bench, &[first.clone(), first])
        .unwrap_err()
        .to_string();
    assert!(e.contains("twice"), "{e}");
}

/// The map summed over each diode's active area is the ledger's detected power of each
/// mirror state (the same paths: equal to rounding, far inside the standard error), the
/// tallies are those of the plain trace, and the light lands near the diode's centre.
#[test]
fn the_active_area_sums_to_the_detected_power() {
    let bench = crate::trace::testing::paper_bench_with_mask();
    let o = TraceOptions::new(20_000, 3);
    let (t, maps) = trace_with_maps(&bench, &o, DEFAULT_BINS).unwrap();
    let plain = super::super::trace(&bench, &o).unwrap();
    assert_eq!(t, plain);
    let n_el = bench.elements().len();
    for arm in Arm::ALL {
        let slot = n_el + slot_detected(arm);
        let common = t.ledger[COMMON][slot];
        let want = [
            common + t.ledger[BRANCH_PLUS][slot],
            common + t.ledger[BRANCH_MINUS][slot],
            common,
        ];
        for (s, w) in want.into_iter().enumerate() {
            let st = maps.stats(arm.index(), s);
            assert!(
                (st.active_w - w).abs() <= 1e-12 * w.abs().max(1e-30),
                "{arm:?} {}: {} vs {w}",
                STATES[s],
                st.active_w
            );
            assert!((st.active_w - w).abs() <= st.active_stderr_w.max(1e-300));
            assert!((0.0..=1.0).contains(&st.spill));
        }
        let own = maps.stats(arm.index(), arm.index());
        assert!(own.active_w > 0.0);
        assert!(
            own.centroid_m[0].hypot(own.centroid_m[1]) < maps.windows[arm.index()].half_width_m
        );
    }
    assert_eq!(EXTRA_SLOTS, t.ledger[COMMON].len() - n_el);
}

/// The signal spill: its active-area sums are the ledger's branch detected powers (the
/// same paths), it equals the plate's share of the state's map less the
/// pattern-independent one to rounding, and its standard error agrees with the scatter of
/// 8 independent traces: the sample standard deviation over the mean reported error lies
/// within the 99 % band of a χ² with 7 degrees of freedom, √(0.99/7) … √(20.3/7) =
/// 0.38 … 1.70. Pooling the 8 (`merge`) divides the error by about √8.
#[test]
fn the_signal_spill_and_its_error_match_the_scatter_of_seeds() {
    let bench = crate::trace::testing::paper_bench_with_mask();
    let n_el = bench.elements().len();
    let mut spills = [Vec::new(), Vec::new()];
    let mut errors = [Vec::new(), Vec::new()];
    let mut pooled: Option<IrradianceMaps> = None;
    for seed in 0..8 {
        let (t, maps) = trace_with_maps(&bench, &TraceOptions::new(8192, 40 + seed), 32).unwrap();
        for arm in Arm::ALL {
            let (d, b) = (arm.index(), arm.index());
            let slot = n_el + slot_detected(arm);
            let world = [BRANCH_PLUS, BRANCH_MINUS][b];
            let active: f64 = (0..32 * 32)
                .map(|i| maps.branch_w[branch_index(32, d, b, 0, i)])
                .sum();
            let want = t.ledger[world][slot];
            assert!(
                (active - want).abs() <= 1e-12 * want.abs(),
                "{active} vs {want}"
            );
            let (own, common) = (maps.stats(d, b), maps.stats(d, 2));
            let (pa, pp) = (own.active_w - common.active_w, own.plate_w - common.plate_w);
            let (spill, se) = maps.signal_spill(d, b);
            assert!(
                (spill - pp / (pa + pp)).abs() < 1e-9,
                "{spill} vs {}",
                pp / (pa + pp)
            );
            assert!(se > 0.0 && spill > 0.0 && spill < 1.0, "{spill} ± {se}");
            spills[d].push(spill);
            errors[d].push(se);
        }
        match &mut pooled {
            None => pooled = Some(maps),
            Some(p) => p.merge(&maps).unwrap(),
        }
    }
    let pooled = pooled.unwrap();
    for d in 0..2 {
        let n = spills[d].len() as f64;
        let mean = spills[d].iter().sum::<f64>() / n;
        let sd = (spills[d].iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let se = errors[d].iter().sum::<f64>() / n;
        assert!(
            (0.38..=1.70).contains(&(sd / se)),
            "diode {d}: sd {sd:e}, se {se:e}"
        );
        let (p, pse) = pooled.signal_spill(d, d);
        assert!((p - mean).abs() < 4.0 * pse, "{p} vs {mean}");
        // Each replica's error is estimated from its 8 batches (relative scatter about
        // 1/√(2·7) ≈ 0.27), their mean to ≈ 0.1 and the pooled one's from 64 batches to
        // ≈ 0.09: 0.3 is about 2.2 standard deviations of the ratio.
        assert!(
            (pse * 8f64.sqrt() / se - 1.0).abs() < 0.3,
            "{pse:e} vs {se:e}"
        );
    }
}

/// The centroid's standard error in closed form: two bins of powers w₁, w₂ at x₁, x₂ with
/// errors s₁, s₂ put the centroid at (w₁x₁ + w₂x₂)/W, and ∂c/∂w₁ = w₂(x₁ − x₂)/W²,
/// ∂c/∂w₂ = w₁(x₂ − x₁)/W², so var c = (x₁ − x₂)²(w₂²s₁² + w₁²s₂²)/W⁴. Two batches of
/// totals a, b give a bin the error |a − b| (batch means, n/(n − 1) = 2).
#[test]
fn the_centroid_error_of_two_bins_is_the_closed_form() {
    let window = Window {
        frame: Frame::new(DVec3::ZERO, DVec3::Z, None),
        radius_m: 1e-3,
        half_width_m: 2e-3,
        housing: None,
    };
    let bins = 4;
    let mut maps = IrradianceMaps::new([window; 2], Vec::new(), bins);
    maps.batches = 2;
    // Bin (row 0, col 0) in the active layer with batch totals 3 and 1 (w₁ = 4, s₁ = 2);
    // bin (row 2, col 3) on the plate with 0.5 and 1.5 (w₂ = 2, s₂ = 1); diode 1, state 1.
    let (b1, b2) = (0, 2 * bins + 3);
    for (l, i, a, b) in [(0, b1, 3.0, 1.0), (1, b2, 0.5, 1.5)] {
        let k = index(bins, 1, 1, l, i);
        maps.power_w[k] = a + b;
        maps.sum_sq[k] = a * a + b * b;
    }
    let st = maps.stats(1, 1);
    let (w1, s1, w2, s2, total) = (4.0, 2.0, 2.0, 1.0, 6.0);
    let (x1, y1) = window.bin_centre(bins, 0, 0);
    let (x2, y2) = window.bin_centre(bins, 2, 3);
    let want = |p1: f64, p2: f64| {
        ((p1 - p2).powi(2) * (w2 * w2 * s1 * s1 + w1 * w1 * s2 * s2)).sqrt() / (total * total)
    };
    assert!((st.centroid_m[0] - (w1 * x1 + w2 * x2) / total).abs() < 1e-18);
    for (got, want) in st
        .centroid_stderr_m
        .iter()
        .zip([want(x1, x2), want(y1, y2)])
    {
        assert!((got - want).abs() <= 1e-12 * want, "{got:e} vs {want:e}");
    }
    // Nothing mapped: no centroid and no error.
    assert_eq!(maps.stats(0, 0).centroid_stderr_m, [0.0, 0.0]);
}

/// The maps are bit-identical on one and two threads.
#[test]
fn maps_are_identical_on_one_and_two_threads() {
    let bench = crate::trace::testing::paper_bench_with_mask();
    let o = TraceOptions::new(6_000, 11);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| trace_with_maps(&bench, &o, 32).unwrap())
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.1.power_w, b.1.power_w);
    assert_eq!(a.1.sum_sq, b.1.sum_sq);
    assert_eq!(a.0, b.0);
}

/// A bench that images a uniformly lit Lambertian disk 1:1 through a stop and a weak
/// symmetric lens of constant index (no dispersion, no reflections) onto a diode: the
/// image is a disk of the same radius, uniformly lit (the view factor of the stop varies by
/// (ρ/s)² ~ 1e-5 over the source), and every bin's expected power is the image's irradiance
/// times the bin's overlap with the disk. Returns the bench, the image radius (m) and the mean view
/// factor of the stop from the source.
fn imaged_disk() -> (Bench, f64, f64) {
    // Thick-lens numbers (n = 1.5, R₁ = −R₂ = 200 mm, t = 2 mm): power, principal planes
    // (inside the lens, δ = f(n−1)t/(nR) from each vertex) and the 2f–2f conjugates.
    let (n, r, t) = (1.5f64, 200.0f64, 2.0f64);
    let phi = (n - 1.0) * (2.0 / r - (n - 1.0) * t / (n * r * r));
    let f = 1.0 / phi;
    let delta = f * (n - 1.0) * t / (n * r);
    let front = 2.0 * f - delta;
    let image = front + t - delta + 2.0 * f;
    let stop = front - 1.0;
    let text = format!(
        r#"(
lamp: (
    position_mm: (0.0, 0.0, 0.0),
    axis: Vector((0.0, 0.0, 1.0)),
    filament: Disk(diameter_mm: 2.0),
    spectrum: Table([(350.0, 1.0), (1150.0, 1.0)]),
    power: InBand(watts: 2.0),
    emission: Cone(half_angle_deg: 1.0),
),
elements: [
    Aperture(name: "stop", position_mm: (0.0, 0.0, {stop}), axis: Vector((0.0, 0.0, 1.0)),
        inner_diameter_mm: 10.0, outer_diameter_mm: 40.0),
    Lens(name: "lens", position_mm: (0.0, 0.0, {front}), axis: Vector((0.0, 0.0, 1.0)),
        front_radius_mm: Some({r}), back_radius_mm: Some(-{r}), thickness_mm: {t},
        diameter_mm: 20.0, glass: "1.5", coating: Reflectance(Constant(0.0))),
],
detectors: (
    plus: (position_mm: (0.0, 0.0, {image}), normal: Vector((0.0, 0.0, -1.0)),
        diameter_mm: 2.4, responsivity: Constant(0.5), housing_diameter_mm: Some(4.0)),
    minus: (position_mm: (0.0, 0.0, -100.0), normal: Vector((0.0, 0.0, -1.0)),
        diameter_mm: 5.0, responsivity: Constant(0.5)),
),
)"#
    );
    let bench = crate::scene::bench::parse_bench(&text, std::path::Path::new("disk.ron")).unwrap();
    // The power through the stop: the view factor of a disk of radius a at distance s from
    // a point at ρ on a parallel plane (F = ½[1 − (s² + ρ² − a²)/√((s² + ρ² + a²)² −
    // 4a²ρ²)]), averaged over the uniformly emitting source disk (radius 1 mm).
    let (a, s_stop, rs) = (5e-3, stop * 1e-3, 1e-3);
    let view = |rho: f64| {
        let q = s_stop * s_stop + rho * rho;
        0.5 * (1.0 - (q - a * a) / ((q + a * a).powi(2) - 4.0 * a * a * rho * rho).sqrt())
    };
    let k = 2000;
    let mean = (0..k)
        .map(|i| {
            let rho = rs * (i as f64 + 0.5) / k as f64;
            view(rho) * 2.0 * rho / (rs * rs) * rs / k as f64
        })
        .sum::<f64>();
    (bench, rs, mean)
}

/// The area (m²) of the square [x0, x1] × [y0, y1] inside the disk of radius r at the
/// origin, by the chord integral (midpoint rule, 400 steps: exact to ~1e-6 of a bin).
fn overlap(x0: f64, x1: f64, y0: f64, y1: f64, r: f64) -> f64 {
    let k = 400;
    let dx = (x1 - x0) / k as f64;
    (0..k)
        .map(|i| {
            let x = x0 + (i as f64 + 0.5) * dx;
            let h = (r * r - x * x).max(0.0).sqrt();
            (y1.min(h) - y0.max(-h)).max(0.0) * dx
        })
        .sum()
}

/// The closed-form case: a uniformly lit disk imaged 1:1 by a thin lens. Every bin of the
/// map holds the analytic irradiance × its overlap with the image disk (χ² with each bin's
/// batch standard error, over the bins at least half inside the image, within 5 standard
/// deviations of its degrees of freedom; the emission is stratified, so the binomial
/// variance of a count would overstate the noise), the total is the power through the stop
/// (within 4 binomial standard errors of a count of equal-weight rays, an upper bound on the
/// stratified error), and no light lands farther than 10 µm
/// beyond the image's edge (the lens's transverse spherical aberration at NA 0.0125 is
/// h·LSA/s' = 1.75 µm, LSA = h²n²/(8f(n−1)²) for a symmetric lens at unit magnification).
#[test]
fn a_uniformly_lit_disk_images_to_its_analytic_irradiance() {
    let (bench, r_img, through) = imaged_disk();
    let o = TraceOptions::new(400_000, 5);
    let (t, maps) = trace_with_maps(&bench, &o, DEFAULT_BINS).unwrap();
    let n_el = bench.elements().len();
    let traced = t.ledger[COMMON][n_el + crate::trace::tally::SLOT_EMITTED];
    // Every ray starts with the same weight: the cone's power over the rays.
    let w0 = traced / o.rays as f64;
    // The power into the stop: the lamp's 2 W times the view factor (the traced cone holds
    // all of it: the stop subtends 0.72° of the cone's 1°).
    let expected_total = 2.0 * through;
    let e0 = expected_total / (std::f64::consts::PI * r_img * r_img);
    let bins = maps.bins;
    let w = &maps.windows[0];
    let step = 2.0 * w.half_width_m / bins as f64;
    let (mut chi2, mut dof, mut outside) = (0.0, 0usize, 0.0);
    for row in 0..bins {
        for col in 0..bins {
            let (x, y) = w.bin_centre(bins, row, col);
            let (x0, y0) = (x - 0.5 * step, y - 0.5 * step);
            let got = maps.power_w[index(bins, 0, 2, 0, row * bins + col)]
                + maps.power_w[index(bins, 0, 2, 1, row * bins + col)];
            let nearest = (x.abs() - 0.5 * step)
                .max(0.0)
                .hypot((y.abs() - 0.5 * step).max(0.0));
            if nearest > r_img + 10e-6 {
                outside += got;
                continue;
            }
            let mu = e0 * overlap(x0, x0 + step, y0, y0 + step, r_img);
            // Bins at least half inside the image: their batch standard error is well
            // determined (~250 rays each); the thin slivers at the edge are left to the
            // total and to the zero outside.
            if mu >= 0.5 * e0 * step * step {
                let k = index(bins, 0, 2, 0, row * bins + col);
                let se = maps.stderr_w(k);
                chi2 += ((got - mu) / se).powi(2);
                dof += 1;
            }
        }
    }
    let dof_f = dof as f64;
    assert!(dof > 700, "{dof} bins inside the image");
    assert!(
        (chi2 - dof_f).abs() < 5.0 * (2.0 * dof_f).sqrt(),
        "χ² {chi2:.1} over {dof} bins"
    );
    assert_eq!(outside, 0.0, "light beyond the image's edge");
    let st = maps.stats(0, 2);
    let se = (expected_total * w0).sqrt();
    assert!(
        (st.active_w - expected_total).abs() < 4.0 * se,
        "{} W on the diode against {expected_total} ± {se}",
        st.active_w
    );
    assert_eq!(st.plate_w, 0.0);
    assert!(st.centroid_m[0].abs() < 4.0 * r_img / (st.active_w / w0).sqrt());
    // A uniform disk's RMS radius is r/√2; binning at the bin centres adds step²/6 to its
    // square (0.13 % of the radius here) and the noise is ~0.2 %.
    assert!((st.rms_radius_m - r_img / 2f64.sqrt()).abs() < 0.01 * r_img);
}
