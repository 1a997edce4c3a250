use super::moves::*;
use super::turns::*;
use super::*;
use crate::scene::bench::{BenchFile, ChartSpec, ElementSpec, LensSpec, MirrorSpec};
use glam::{DMat3, DVec3};
use std::path::Path;

fn paper() -> BenchFile {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    crate::scene::parse_ron(&text, &path).unwrap()
}

#[test]
fn field_paths_get_and_set() {
    let mut f = paper();
    let x = get(&f, "detectors.minus.position_mm.x").unwrap();
    set(&mut f, "detectors.minus.position_mm.x", x + 1.5).unwrap();
    assert_eq!(f.detectors.minus.position_mm.0, x + 1.5);
    assert_eq!(get(&f, "detectors.minus.position_mm.x").unwrap(), x + 1.5);
    set(&mut f, "dmd.tilt_deg", 11.0).unwrap();
    assert_eq!(f.dmd.as_ref().unwrap().tilt_deg.0, 11.0);
    // An integer field takes whole numbers only.
    set(&mut f, "dmd.pattern.units_across", 32.0).unwrap();
    assert_eq!(f.dmd.as_ref().unwrap().pattern.units_across.get(), 32);
    assert!(set(&mut f, "dmd.pattern.units_across", 32.5).is_err());
}

#[test]
fn every_listed_path_reads() {
    let f = paper();
    let all = list(&f);
    assert!(all.len() > 50, "{}", all.len());
    for p in &all {
        get(&f, p).unwrap_or_else(|e| panic!("{p}: {e}"));
    }
    assert!(all.iter().any(|p| p == "detectors.minus.despace_mm"));
}

#[test]
fn bad_paths_and_values_are_input_errors_naming_the_path() {
    let mut f = paper();
    let e = set(&mut f, "detectors.minus.positon_mm.x", 1.0).unwrap_err();
    let s = e.to_string();
    assert!(e.is_user_error());
    assert!(
        s.contains("positon_mm") && s.contains("detectors.minus.position_mm.x"),
        "{s}"
    );
    let e = set(&mut f, "no_such_lens.position_mm.x", 1.0).unwrap_err();
    assert!(e.to_string().contains("detectors.plus"), "{e}");
    // Outside the field's valid range: refused by the file's own rule.
    let e = set(&mut f, "dmd.tilt_deg", -3.0).unwrap_err();
    assert!(e.to_string().contains("positive"), "{e}");
    assert!(set(&mut f, "dmd.tilt_deg", f64::NAN).is_err());
    assert!(set(&mut f, "dmd.decenter_mm.x", 1.0).is_err());
}

#[test]
fn moves_are_rigid_and_in_the_parts_frame() {
    let f0 = paper();
    let mut f = f0.clone();
    let d0 = f0.detectors.minus.clone();
    set(&mut f, "detectors.minus.despace_mm", 2.0).unwrap();
    let n = d0.normal.to_unit().unwrap();
    let p = f.detectors.minus.position_mm;
    let moved = DVec3::new(
        p.0 - d0.position_mm.0,
        p.1 - d0.position_mm.1,
        p.2 - d0.position_mm.2,
    );
    assert!((moved - 2.0 * n).length() < 1e-12, "{moved:?}");
    // A decentre is perpendicular to the normal and 1 mm long.
    let mut g = f0.clone();
    set(&mut g, "detectors.minus.decenter_mm.y", 1.0).unwrap();
    let p = g.detectors.minus.position_mm;
    let moved = DVec3::new(
        p.0 - d0.position_mm.0,
        p.1 - d0.position_mm.1,
        p.2 - d0.position_mm.2,
    );
    assert!((moved.length() - 1.0).abs() < 1e-12 && moved.dot(n).abs() < 1e-12);
    // A tilt turns the normal by the angle, about an axis perpendicular to it.
    let mut h = f0.clone();
    set(&mut h, "detectors.minus.tilt_deg.x", 3.0).unwrap();
    let n2 = h.detectors.minus.normal.to_unit().unwrap();
    assert!((n.dot(n2).acos().to_degrees() - 3.0).abs() < 1e-9);
    assert_eq!(h.detectors.minus.position_mm, d0.position_mm);
    // Moves read as 0 and zero moves change nothing.
    assert_eq!(get(&h, "detectors.minus.tilt_deg.x").unwrap(), 0.0);
    let mut z = f0.clone();
    set(&mut z, "detectors.minus.decenter_mm.x", 0.0).unwrap();
    assert_eq!(z.detectors.minus.position_mm, d0.position_mm);
}

fn element_position(f: &BenchFile, name: &str) -> DVec3 {
    let el = f.elements.iter().find(|e| e.name() == name).unwrap();
    match el {
        ElementSpec::Lens(LensSpec { position_mm, .. })
        | ElementSpec::Mirror(MirrorSpec { position_mm, .. })
        | ElementSpec::Chart(ChartSpec { position_mm, .. }) => v3(*position_mm),
        _ => panic!("{name}"),
    }
}

#[test]
fn turns_find_the_illumination_and_the_arms_of_the_paper_bench() {
    let f = paper();
    let g = groups(
        &f,
        DVec3::NEG_Z,
        [1.0, -1.0].map(|s| {
            DMat3::from_axis_angle(
                DVec3::new(1.0, 1.0, 0.0).normalize(),
                s * 12f64.to_radians(),
            ) * DVec3::Z
        }),
        "t",
    )
    .unwrap();
    let mut ill = g.illumination.clone();
    ill.sort();
    assert_eq!(
        ill,
        [
            "chart",
            "collimator",
            "field_stop",
            "imaging_iris",
            "imaging_lens",
            "imaging_lens_tube",
            "lamp_tube",
            "nd_od1",
            "nd_od2"
        ]
    );
    assert_eq!(g.arms[0], ["arm_plus_lens", "arm_plus_fold"]);
    assert_eq!(g.arms[1], ["arm_minus_lens", "arm_minus_fold"]);
    let all = list(&f);
    for p in [
        "illumination.turn_deg.hinge",
        "illumination.tracked_turn_deg.across",
    ] {
        assert!(all.iter().any(|x| x == p), "{p}");
        assert_eq!(get(&f, p).unwrap(), 0.0);
    }
    let mut no_dmd = f.clone();
    no_dmd.dmd = None;
    let e = set(&mut no_dmd, "illumination.turn_deg.across", 3.0).unwrap_err();
    assert!(
        e.is_user_error() && e.to_string().contains("no `dmd`"),
        "{e}"
    );
    let e = set(&mut f.clone(), "illumination.turn_deg.sideways", 3.0).unwrap_err();
    assert!(
        e.to_string().contains("illumination.turn_deg.across"),
        "{e}"
    );
}

/// A tracked turn keeps each arm on its state's specular reflection of the incoming chief
/// direction; a plain turn leaves the arms where they were. Both turn the illumination
/// rigidly by the angle.
#[test]
fn tracked_turns_keep_the_arms_on_the_specular_directions() {
    let f0 = paper();
    let hinge = DVec3::new(1.0, 1.0, 0.0).normalize();
    let n = [1.0, -1.0].map(|s| DMat3::from_axis_angle(hinge, s * 12f64.to_radians()) * DVec3::Z);
    let off = |f: &BenchFile, k: usize, name: &str| {
        let d = -v3(f.lamp.position_mm).normalize();
        let u = reflect(d, n[k]);
        // sin of the angle (acos near 1 would lose the small offsets)
        element_position(f, name).normalize().cross(u).length()
    };
    let names = ["arm_plus_lens", "arm_minus_lens"];
    for across in ["across", "hinge"] {
        let mut f = f0.clone();
        set(
            &mut f,
            &format!("illumination.tracked_turn_deg.{across}"),
            10.0,
        )
        .unwrap();
        let (a, b) = (v3(f0.lamp.position_mm), v3(f.lamp.position_mm));
        assert!((a.angle_between(b).to_degrees() - 10.0).abs() < 1e-9);
        assert!((a.length() - b.length()).abs() < 1e-9);
        let (c0, c1) = (
            element_position(&f0, "chart"),
            element_position(&f, "chart"),
        );
        assert!(
            (c0.angle_between(c1).to_degrees() - 10.0).abs() < 1e-9,
            "{across}"
        );
        for (k, name) in names.iter().enumerate() {
            // The − arm lens sits 0.3 mm off its line by design: the offset is kept.
            assert!(
                (off(&f, k, name) - off(&f0, k, name)).abs() < 1e-9,
                "{across} {name}"
            );
        }
        let mut g = f0.clone();
        set(&mut g, &format!("illumination.turn_deg.{across}"), 10.0).unwrap();
        for name in names {
            assert_eq!(element_position(&g, name), element_position(&f0, name));
        }
        assert_eq!(g.lamp.position_mm, f.lamp.position_mm);
    }
    // Across the hinge the incidence on both facets stays the same (the blaze is symmetric).
    let mut f = f0.clone();
    set(&mut f, "illumination.turn_deg.across", 10.0).unwrap();
    let d = -v3(f.lamp.position_mm).normalize();
    assert!((d.dot(n[0]) - d.dot(n[1])).abs() < 1e-12);
    assert!(
        (d.dot(n[0]).abs() - 10f64.to_radians().cos() * 12f64.to_radians().cos()).abs() < 1e-12
    );
}

/// Where an arm's chief line (from the DMD's centre along its state's specular direction,
/// folded by the arm's fold mirror as written in the file) meets its diode's plane, from
/// the diode's centre (mm).
fn chief_ray_offset(f: &BenchFile, k: usize) -> DVec3 {
    let hinge = DVec3::new(1.0, 1.0, 0.0).normalize();
    let s = [1.0, -1.0][k];
    let n = DMat3::from_axis_angle(hinge, s * 12f64.to_radians()) * DVec3::Z;
    let u = reflect(-v3(f.lamp.position_mm).normalize(), n);
    let fold = ["arm_plus_fold", "arm_minus_fold"][k];
    let Some(ElementSpec::Mirror(MirrorSpec {
        position_mm,
        normal,
        ..
    })) = f.elements.iter().find(|e| e.name() == fold)
    else {
        panic!("{fold}")
    };
    let (p, m) = (v3(*position_mm), unit(*normal, "t").unwrap());
    let hit = u * (p.dot(m) / u.dot(m));
    let out = reflect(u, m);
    let det = [&f.detectors.plus, &f.detectors.minus][k];
    let (c, w) = (v3(det.position_mm), unit(det.normal, "t").unwrap());
    hit + out * ((c - hit).dot(w) / out.dot(w)) - c
}

/// The balanced detector's two diodes move as one rigid mount under a tracked turn, and
/// each arm's re-aimed fold still brings its chief ray onto its diode (the − arm's built-in
/// offset kept): at 18° across the hinge, where turning each diode with its own arm would
/// make them overlap.
#[test]
fn tracked_turns_move_the_detector_pair_as_one_mount() {
    let f0 = paper();
    let pair = |f: &BenchFile| {
        let (a, b) = (&f.detectors.plus, &f.detectors.minus);
        let (na, nb) = (unit(a.normal, "t").unwrap(), unit(b.normal, "t").unwrap());
        (
            v3(a.position_mm).distance(v3(b.position_mm)),
            na.angle_between(nb),
        )
    };
    for across in ["across", "hinge"] {
        let mut f = f0.clone();
        let turn = if across == "across" { 18.0 } else { 2.0 };
        set(
            &mut f,
            &format!("illumination.tracked_turn_deg.{across}"),
            turn,
        )
        .unwrap();
        let (s0, s1) = (pair(&f0), pair(&f));
        assert!((s0.0 - s1.0).abs() < 1e-9 && (s0.1 - s1.1).abs() < 1e-12);
        for k in 0..2 {
            let (o0, o1) = (chief_ray_offset(&f0, k), chief_ray_offset(&f, k));
            assert!(
                (o0.length() - o1.length()).abs() < 0.05,
                "{across} {k}: {o0} {o1}"
            );
        }
        assert!(chief_ray_offset(&f, 0).length() < 0.05);
        // In focus: each fold's distance to its diode kept (to 0.2 mm: the pair is rigid,
        // the two distances are matched on average).
        for (fold, det) in [
            ("arm_plus_fold", [&f0.detectors.plus, &f.detectors.plus]),
            ("arm_minus_fold", [&f0.detectors.minus, &f.detectors.minus]),
        ] {
            let l0 = element_position(&f0, fold).distance(v3(det[0].position_mm));
            let l1 = element_position(&f, fold).distance(v3(det[1].position_mm));
            assert!((l0 - l1).abs() < 0.2, "{across} {fold}: {l0} {l1}");
        }
    }
    // Across the hinge the pair turns about the turn's own axis (the bench is symmetric
    // under the exchange of the arms; the refocusing slide stays in the symmetry plane), by
    // about the turn (0.915 of it, and the slide moves the pair's midpoint a little further).
    let mut f = f0.clone();
    set(&mut f, "illumination.tracked_turn_deg.across", 18.0).unwrap();
    let mid = |f: &BenchFile| v3(f.detectors.plus.position_mm) + v3(f.detectors.minus.position_mm);
    let (m0, m1) = (mid(&f0), mid(&f));
    let axis = m0.cross(m1).normalize();
    assert!(
        axis.dot(DVec3::new(1.0, -1.0, 0.0).normalize()).abs() > 0.999,
        "{axis}"
    );
    let angle = m0.angle_between(m1).to_degrees();
    assert!(angle > 15.0 && angle < 20.0, "{angle}");
}
