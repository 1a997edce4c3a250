//! The DMD's diffraction seen through a bench variable: turning the illumination across the
//! mirrors' hinge, with the arms following their states' specular directions
//! (`illumination.tracked_turn_deg.across`), moves the blaze condition; in a narrow band at the
//! lamp band's centre each arm's collection peaks where an order meets the specular direction,
//! while the geometric model collects the same at every angle (docs/dmd_diffraction.md,
//! "Blaze matching").

use std::path::Path;

use spibench::optics::Arm;
use spibench::scene::doc::BenchDoc;
use spibench::trace::collection::collection;

/// The band's centre (m) and the narrow band traced around it (nm).
const CENTRE: f64 = 750e-9;
const BAND_NM: (f64, f64) = (740.0, 760.0);
/// The turns traced (degrees).
const TURNS: [f64; 10] = [0.0, 3.0, 6.0, 9.0, 12.0, 15.0, 18.0, 21.0, 24.0, 27.0];
const RAYS: u64 = 40_000;

/// The paper bench with the diffractive model, traced in the narrow band.
fn narrow_diffractive() -> BenchDoc {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "package_mm: (40.0, 32.0),",
        "package_mm: (40.0, 32.0),\n        model: Diffractive(tail_bin_nm: 10.0),",
    );
    let mut doc = BenchDoc::parse(&text, &path).unwrap();
    doc.set("band_nm.0", BAND_NM.0).unwrap();
    doc.set("band_nm.1", BAND_NM.1).unwrap();
    doc
}

/// The blaze condition for a tracked turn δ across the hinge: the incidence on either facet is
/// cos φ = cos δ·cos θt, and an order (m, −m) leaves along the specular direction when
/// 2·cos φ·sin θt = √2·m·λ/p. The peak order at δ = 0 lies c₀ = sin 2θt·p/(√2·λ) orders
/// from the zeroth; the turn that brings the nearest lower whole order onto the specular
/// direction is acos(⌊c₀⌋/c₀).
fn predicted_peak_deg(pitch: f64, tilt_deg: f64) -> f64 {
    let c0 = (2.0 * tilt_deg.to_radians()).sin() * pitch / (2f64.sqrt() * CENTRE);
    (c0.floor() / c0).acos().to_degrees()
}

#[test]
#[ignore = "at a 12° tracked turn the two diodes, each turned with its own arm, overlap (the bench is refused): the arms' detectors need a shared mount or the turn a smaller range; see docs/dmd_diffraction.md"]
fn tracked_illumination_turn_shows_the_blaze_matching() {
    let doc = narrow_diffractive();
    let peak = predicted_peak_deg(13.68e-6, 12.0);
    assert!((peak - 17.59).abs() < 0.05, "{peak}");
    let mut shares = Vec::new();
    for turn in TURNS {
        let bench = doc
            .with(&[("illumination.tracked_turn_deg.across".to_string(), turn)])
            .unwrap()
            .build()
            .unwrap();
        let own = |b: &spibench::optics::Bench| {
            let c = collection(b, RAYS, 5, 1).unwrap();
            Arm::ALL.map(|a| c.share(a, a))
        };
        let (d, g) = (own(&bench), own(&bench.with_geometric_dmd()));
        eprintln!("turn {turn:5.1}°: diffractive {d:?}, geometric {g:?}");
        shares.push((d, g));
    }
    for arm in Arm::ALL {
        let k = arm.index();
        let diffractive: Vec<f64> = shares.iter().map(|s| s.0[k]).collect();
        let geometric: Vec<f64> = shares.iter().map(|s| s.1[k]).collect();
        let (best, top) =
            diffractive.iter().enumerate().fold(
                (0, 0.0),
                |acc, (i, v)| if *v > acc.1 { (i, *v) } else { acc },
            );
        // The peak within 1.5 grid steps of the blaze condition's turn.
        assert!(
            (TURNS[best] - peak).abs() <= 4.5,
            "arm {}: peak at {}° (predicted {peak:.1}°): {diffractive:?}",
            arm.label(),
            TURNS[best]
        );
        // A quarter of an order off the blaze at no turn: the order misses much of the diode.
        assert!(
            top > 1.3 * diffractive[0],
            "arm {}: {diffractive:?}",
            arm.label()
        );
        // Geometric mirrors: no order structure, the arms collect alike at every turn.
        let (lo, hi) = geometric
            .iter()
            .fold((f64::MAX, 0.0f64), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
        assert!(hi - lo < 0.1 * hi, "arm {}: {geometric:?}", arm.label());
        assert!(
            lo > top,
            "arm {}: {geometric:?} vs {diffractive:?}",
            arm.label()
        );
    }
}
