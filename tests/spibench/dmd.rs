//! The DMD's diffraction seen through a bench variable: turning the illumination across the
//! mirrors' hinge, with the arms following their states' specular directions
//! (`illumination.tracked_turn_deg.across`), moves the blaze condition; in a narrow band at the
//! lamp band's centre each arm's collection peaks where an order meets the specular direction,
//! while the geometric model collects the same at every angle (docs/dmd_diffraction.md,
//! "Blaze matching").

use std::path::Path;

use spibench::optics::{Arm, Bench};
use spibench::scene::doc::{BenchDoc, DmdModel};
use spibench::trace::collection::collection;

/// The band's centre (m) and the narrow band traced around it (nm): over it the blaze detuning
/// moves by ±0.07 of an order, so the band acts as one wavelength.
const CENTRE: f64 = 750e-9;
const BAND_NM: (f64, f64) = (740.0, 760.0);
/// A DLP7000 (the paper bench's DMD): pitch (m) and tilt (degrees).
const PITCH: f64 = 13.68e-6;
const TILT_DEG: f64 = 12.0;
/// Rays per point: about half a second each in the dev profile.
const RAYS: u64 = 20_000;

/// The paper bench with the diffractive model, traced in the narrow band.
fn narrow_diffractive() -> BenchDoc {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let mut doc = BenchDoc::read(&path).unwrap();
    doc.set_dmd_model(DmdModel::Diffractive).unwrap();
    doc.set("band_nm.0", BAND_NM.0).unwrap();
    doc.set("band_nm.1", BAND_NM.1).unwrap();
    doc
}

/// The blaze detuning at the band's centre after a tracked turn δ across the hinge, in orders:
/// the incidence on either facet is cos φ = cos δ·cos θt, and the envelope's peak lies
/// c = 2·cos φ·sin θt·p/(√2·λ) = c₀·cos δ orders (along the diagonal) from the zeroth, c₀ =
/// sin 2θt·p/(√2·λ) = 5.246; the detuning is c minus the nearest whole order (docs/
/// dmd_diffraction.md, "Blaze matching").
fn c0() -> f64 {
    (2.0 * TILT_DEG.to_radians()).sin() * PITCH / (2f64.sqrt() * CENTRE)
}

/// The turn that puts the envelope's peak `x` orders above order 5 (x = 0: the blaze).
fn turn_for_detuning(x: f64) -> f64 {
    ((5.0 + x) / c0()).acos().to_degrees()
}

/// Each arm's own collection (the share of its state's reflected light on its diode) at a
/// tracked turn, diffractive and geometric on the same rays.
fn shares(doc: &BenchDoc, turn: f64, geometric: bool) -> ([f64; 2], Option<[f64; 2]>) {
    let bench = doc
        .with(&[("illumination.tracked_turn_deg.across".to_string(), turn)])
        .unwrap()
        .build()
        .unwrap();
    let own = |b: &Bench| {
        let c = collection(b, RAYS, 5, 1).unwrap();
        Arm::ALL.map(|a| c.share(a, a))
    };
    let d = own(&bench);
    let g = geometric.then(|| own(&bench.with_geometric_dmd()));
    eprintln!("turn {turn:5.2}°: diffractive {d:.3?}, geometric {g:.3?}");
    (d, g)
}

/// The blaze matching, from the physics of the model (docs/dmd_diffraction.md, "Blaze
/// matching"). Each diode relays the filament's image 1:1 and accepts about ±17 mrad around
/// its arm's specular direction, a fifth of an order spacing along the diagonal (77 mrad at
/// 750 nm), so it collects the one order nearest the specular direction, weighted by the
/// envelope there: P ≈ sinc⁴(π·x) for a detuning of x orders (0.86 at x = 0.15), and further cut
/// where the order's filament image walks off the diode (x ≳ 0.2).
///
/// - At the predicted blaze turn (17.6°; c₀ = 5.246 at 750 nm) one order carries nearly all the
///   reflected light onto the diode: the diffractive collection is at least 0.85 of the
///   geometric one, and it exceeds the collection at no turn and at 27° (detunings +0.25 and
///   −0.33 orders) by a tenth of the geometric collection.
/// - The peak's place: the parabola through the collections at detunings +0.15, 0, −0.15 has
///   its vertex within 1.5° of the predicted turn for the + arm (aligned; 1° measured: the
///   order's filament image walks off the diode a little faster on one side). The − arm's
///   built-in misalignments (its fold tilted by (0.2, −0.1)°, which moves its beam about 1 mm
///   on the diode, its diode 0.3 mm off) displace its acceptance by up to 0.13 of an order
///   (7.9 mm a diagonal order at the diode), 36° of turn an order here: its vertex within 3.5°
///   (2.3° measured).
/// - Geometric mirrors have no orders: the arms, turned rigidly onto the specular directions
///   with the balanced detector moved as one mount (refocused) and the folds re-aimed, collect
///   nearly alike at every turn: within 8 % over 0–27° (4 % and 7 % measured, a slow geometric
///   decline with the turn), while the diffractive collection varies by more than half its
///   peak.
#[test]
fn tracked_illumination_turn_shows_the_blaze_matching() {
    let doc = narrow_diffractive();
    let blaze = turn_for_detuning(0.0);
    assert!((blaze - 17.61).abs() < 0.01, "{blaze}");
    let (at_blaze, geo_blaze) = shares(&doc, blaze, true);
    let (at_zero, geo_zero) = shares(&doc, 0.0, true);
    let (at_27, geo_27) = shares(&doc, 27.0, true);
    let (above, _) = shares(&doc, turn_for_detuning(0.15), false);
    let (below, _) = shares(&doc, turn_for_detuning(-0.15), false);
    let geo = [geo_blaze, geo_zero, geo_27].map(Option::unwrap);
    for arm in Arm::ALL {
        let k = arm.index();
        let label = arm.label();
        assert!(
            at_blaze[k] > 0.85 * geo[0][k],
            "arm {label}: at the blaze {} against geometric {}",
            at_blaze[k],
            geo[0][k]
        );
        for (turn, off) in [(0.0, at_zero[k]), (27.0, at_27[k])] {
            assert!(
                off < at_blaze[k] - 0.1 * geo[0][k],
                "arm {label}: {off} at {turn}° against {} at the blaze",
                at_blaze[k]
            );
        }
        // Vertex of the parabola through (x, share) at x = +h, 0, −h, in orders.
        let h = 0.15;
        let curvature = above[k] - 2.0 * at_blaze[k] + below[k];
        assert!(curvature < 0.0, "arm {label}: no peak");
        let vertex = h * (below[k] - above[k]) / (2.0 * curvature);
        let peak = turn_for_detuning(vertex.clamp(-0.3, 0.3));
        let within = if arm == Arm::Plus { 1.5 } else { 3.5 };
        assert!(
            (peak - blaze).abs() < within,
            "arm {label}: peak at {peak:.2}° (detuning {vertex:.3}), predicted {blaze:.2}°"
        );
        let (lo, hi) = geo.iter().fold((f64::MAX, 0.0f64), |(lo, hi), g| {
            (lo.min(g[k]), hi.max(g[k]))
        });
        assert!(hi - lo < 0.08 * hi, "arm {label}: geometric {geo:?}");
        let low = at_zero[k].min(at_27[k]);
        assert!(
            at_blaze[k] - low > 0.5 * at_blaze[k],
            "arm {label}: diffractive {at_zero:?} {at_blaze:?} {at_27:?}"
        );
    }
}

#[test]
#[ignore = "prints the collection over a fine grid of turns (for docs/dmd_diffraction.md)"]
fn blaze_matching_grid() {
    let doc = narrow_diffractive();
    for x in [
        0.25, 0.2, 0.15, 0.1, 0.05, 0.0, -0.05, -0.1, -0.15, -0.2, -0.25, -0.3,
    ] {
        let turn = if x > 0.245 { 0.0 } else { turn_for_detuning(x) };
        eprint!("x {x:+.2} ");
        shares(&doc, turn, true);
    }
}

/// The chip and its package are opaque from behind, as on the real device (a silicon chip on a
/// ceramic carrier): with the illumination turned by 180° about the hinge (the lamp and its
/// optics behind the array) no light reaches the mirrors or, through the array, the diodes
/// (before, k± read 0.32 A/W, light passing the array from behind): a sweep's point has no
/// detected power and no k±, and `trace` of a bench file with the lamp behind reports that no
/// light reaches the pattern area. A turn outside ±360° is refused, as every angle of a bench
/// file is.
#[test]
fn no_light_passes_the_array_from_behind() {
    use crate::common::{TempDir, read_json, spibench, stderr};
    let t = TempDir::new("dmd-behind");
    let out = t.join("sweep");
    let o = spibench(
        &[
            "sweep",
            "--vary",
            "illumination.turn_deg.hinge=0:180:2",
            "--rays",
            "20000",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = read_json(&out.join("summary.json"))["rows"].clone();
    let k = |r: &serde_json::Value, key: &str| r[key].as_f64();
    // Lit from the front the + arm collects (0.16 A/W with the diffractive DMD, 0.35 with
    // plane mirrors).
    assert!(k(&rows[0], "k_plus").unwrap() > 0.1, "{}", rows[0]);
    let behind = &rows[1];
    for key in ["power_plus_w", "power_minus_w", "x_total_w"] {
        assert_eq!(k(behind, key), Some(0.0), "{key}: {behind}");
    }
    // k± = detected / incident on the mirrors: none incident, so none reported.
    for key in ["k_plus", "k_minus"] {
        assert!(
            k(behind, key).is_none_or(|v| v.abs() < 1e-3),
            "{key}: {behind}"
        );
    }
    // A bench file with the lamp behind the DMD: no light reaches the pattern area, which
    // `trace` reports as the input error it is (before, it traced k± of 0.33 A/W).
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let mut doc = BenchDoc::read(&path).unwrap();
    doc.set("illumination.turn_deg.hinge", 180.0).unwrap();
    let scene = t.join("behind.ron");
    std::fs::write(&scene, doc.to_ron().unwrap()).unwrap();
    let out = t.join("trace");
    let o = spibench(
        &[
            "trace",
            scene.to_str().unwrap(),
            "--rays",
            "20000",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no traced light reached the DMD's pattern area")
            && err.contains("0 arrivals"),
        "{err}"
    );
    // Turns are angles of a bench: within ±360°.
    for (args, value) in [
        (
            vec!["sweep", "--vary", "illumination.turn_deg.hinge=0:1e20:2"],
            "1e20",
        ),
        (
            vec![
                "align",
                "--free",
                "illumination.turn_deg.across=-1e300:1e300",
            ],
            "1e300",
        ),
    ] {
        let out = t.join("refused");
        let mut a = args.clone();
        a.extend(["--rays", "20000", "--out", out.to_str().unwrap()]);
        let o = spibench(&a, &[]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("illumination.turn_deg") && err.contains("±360") && err.contains(value),
            "{args:?}: {err}"
        );
        assert!(!out.exists());
    }
}

/// The DMD's tilt tolerance moves the blaze: a bench whose `dmd.tilt_deg` a variable set (as a
/// tolerance trial, a sweep or align sets it) builds its diffraction tables from the tilt it
/// was set to, so it diffracts exactly as a bench written with that tilt and not as the
/// nominal one (derived state is built from the edited file, never kept). At 11° the blaze
/// condition λ = p·sin 2θt/(√2·m) puts order 5 on the specular direction at 724.7 nm, where
/// the nominal 12° tilt is 0.43 of an order off its blaze.
#[test]
fn a_set_dmd_tilt_rebuilds_the_diffraction_and_moves_the_blaze() {
    use glam::DVec3;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let nominal = BenchDoc::read(&path).unwrap();
    let set = nominal.with(&[("dmd.tilt_deg".to_string(), 11.0)]).unwrap();
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("tilt_deg: 12.0,", "tilt_deg: 11.0,");
    let written = BenchDoc::parse(&text, &path).unwrap();
    let [nominal, set, written] = [nominal, set, written].map(|d| d.build().unwrap());
    let wl = PITCH * (22f64.to_radians()).sin() / (2f64.sqrt() * 5.0);
    let down = DVec3::new(0.0, 0.0, -1.0);
    for state in [0, 1] {
        let dist = |b: &Bench, wl: f64| {
            let d = b.dmd().unwrap().dmd.diffraction().expect("diffractive");
            d.distribution(state, down, wl).expect("not grazing")
        };
        let best = |(orders, _): &(Vec<(i32, i32, f64)>, f64)| {
            orders.iter().map(|o| o.2).fold(0.0, f64::max)
        };
        // Identical to the bench written at 11°, every order (the tail tables' included).
        for w in [wl, 400e-9, 1100e-9] {
            assert_eq!(dist(&set, w), dist(&written, w), "state {state} at {w:e} m");
            assert_ne!(dist(&set, w), dist(&nominal, w), "state {state} at {w:e} m");
        }
        // At the 11° blaze one order holds nearly all the reflected light (the footprint's
        // share of it, ~0.98); 0.43 of an order off, the best order holds well under half of it.
        let (at_blaze, off_blaze) = (best(&dist(&set, wl)), best(&dist(&nominal, wl)));
        assert!(at_blaze > 0.9, "state {state}: {at_blaze}");
        assert!(off_blaze < 0.6, "state {state}: {off_blaze}");
    }
}

/// The centre objective on the shipped bench, the DMD as built: each diode's housing plate
/// takes a large share of its own state's pattern light (the diffraction orders the diode
/// does not collect, one order spacing or more off: docs/dmd_diffraction.md), and all of the
/// light around the diode has a centroid and an RMS radius that put its margin below −1 mm.
/// The objective's spot is the collected light (the pattern light on the active area): the
/// collected order's filament image (2.0 × 1.2 mm) with the parts of its neighbours (one order
/// spacing, 2.6 mm and more, away) that reach the 5 mm diode, so its RMS radius lies below the
/// R/√2 of a uniformly lit active area and its centroid within R/2 of the centre, its margin is
/// at least 2 mm above the one of all the light, and the evaluation `align` scores is that
/// spot, from the same trace.
#[test]
fn the_centre_objective_reads_the_collected_order_on_the_shipped_bench() {
    use spibench::pipeline::evaluate::{EvaluateOptions, evaluate_mapped};
    use spibench::pipeline::optimise::{CENTRE_RMS_RADII, centre_margin_m, spot};
    use spibench::trace::TraceOptions;
    use spibench::trace::irradiance::{DEFAULT_BINS, trace_with_maps};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let doc = BenchDoc::read(&path).unwrap();
    assert_eq!(doc.dmd_model(), Some(DmdModel::Diffractive));
    let (rays, seed) = (RAYS, 7);
    let bench = doc.build().unwrap();
    let (_, maps) = trace_with_maps(&bench, &TraceOptions::new(rays, seed), DEFAULT_BINS).unwrap();
    let o = EvaluateOptions {
        rays,
        seed,
        quality: false,
    };
    let scored = evaluate_mapped(&doc, Vec::new(), &o)
        .unwrap()
        .spots
        .unwrap();
    for (d, scored) in scored.iter().enumerate() {
        let s = spot(&maps, d, CENTRE_RMS_RADII);
        assert_eq!(&s, scored);
        let all = maps.stats(d, d);
        let r = s.active_radius_m;
        let old = centre_margin_m(&all, r, CENTRE_RMS_RADII);
        eprintln!(
            "diode {d}: spill {:.3}, collected offset {:.3} mm, RMS {:.3} mm, margin {:.3} ± \
             {:.3} mm; all light: offset {:.3} mm, RMS {:.3} mm, margin {:.3} mm",
            s.stats.spill,
            s.offset_m * 1e3,
            s.stats.rms_radius_m * 1e3,
            s.margin_m * 1e3,
            s.margin_stderr_m * 1e3,
            all.centroid_m[0].hypot(all.centroid_m[1]) * 1e3,
            all.rms_radius_m * 1e3,
            old * 1e3
        );
        assert!(s.stats.spill > 0.3, "diode {d}: {}", s.stats.spill);
        assert!(old < -1e-3, "diode {d}: {old}");
        assert!(all.rms_radius_m > r, "diode {d}: {}", all.rms_radius_m);
        assert!(
            s.stats.rms_radius_m < r / 2f64.sqrt(),
            "diode {d}: {}",
            s.stats.rms_radius_m
        );
        assert!(s.offset_m < r / 2.0, "diode {d}: {}", s.offset_m);
        assert!(
            s.margin_m > old + 2e-3,
            "diode {d}: {} vs {old}",
            s.margin_m
        );
    }
}
