//! The reader and the tracer against validation/lenses/: rayoptics' and optiland's numbers
//! (reference.json), the bad files, the test catalogue.

use std::path::{Path, PathBuf};

use super::*;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn bad(name: &str) -> PathBuf {
    root()
        .join("validation/lenses/test_prescriptions/bad")
        .join(name)
}

fn catalogue() -> agf::Catalogue {
    agf::Catalogue::read(&root().join("validation/lenses/test_catalogue.agf")).unwrap()
}

/// Every entry of reference.json: EFL, BFL, FFL within 1e-6 relative, fan intercepts within
/// 1e-6 mm and directions within 1e-9, against both references (which agree to 3e-16).
#[test]
fn every_prescription_matches_rayoptics_and_optiland() {
    let text = std::fs::read_to_string(root().join("validation/lenses/reference.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let entries = json["entries"].as_array().unwrap();
    assert_eq!(entries.len(), 34);
    for e in entries {
        let file = e["file"].as_str().unwrap();
        let wl = e["wavelength_nm"].as_f64().unwrap();
        let lens = read_zmx(&root().join(file), &GlassOptions::default()).unwrap();
        let heights: Vec<f64> = e["rayoptics"]["rays"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["height_mm"].as_f64().unwrap())
            .collect();
        let r = report::report(&lens, wl, Some(&heights)).unwrap();
        let image = e["image_distance_mm"].as_f64().unwrap();
        assert!(
            (r.image_distance_mm.unwrap() - image).abs() < 1e-9,
            "{file}"
        );
        // The r² file's library paraxial numbers ignore PARM 1 (README); the hand trace's do not.
        let first_order = if file.contains("r2_term") {
            &e["numpy_paraxial"]
        } else {
            &e["rayoptics"]
        };
        for (key, ours) in [
            ("efl_mm", r.efl_mm),
            ("bfl_mm", r.bfl_mm),
            ("ffl_mm", r.ffl_mm),
        ] {
            match first_order[key].as_f64() {
                None => assert_eq!(ours, None, "{file} {wl} {key}"),
                Some(v) => {
                    let ours = ours.unwrap();
                    assert!(
                        (ours - v).abs() <= 1e-6 * v.abs(),
                        "{file} {wl} {key}: {ours} vs {v}"
                    );
                    assert!(
                        (e["numpy_paraxial"][key].as_f64().unwrap() - v).abs() < 1e-6 * v.abs()
                    );
                }
            }
        }
        for lib in ["rayoptics", "optiland"] {
            for (ours, theirs) in r.rays.iter().zip(e[lib]["rays"].as_array().unwrap()) {
                let y = theirs["y_mm"].as_f64().unwrap();
                let got = ours.y_mm.unwrap();
                assert!(
                    (got - y).abs() < 1e-6,
                    "{file} {wl} {lib} h {}: {got} vs {y}",
                    ours.height_mm
                );
                let d = ours.direction.unwrap();
                for (a, b) in d.iter().zip(theirs["direction"].as_array().unwrap()) {
                    assert!((a - b.as_f64().unwrap()).abs() < 1e-9, "{file} {lib}");
                }
            }
        }
    }
}

/// Each bad file of test_prescriptions/bad is a located error naming the line and operand the
/// README table gives.
#[test]
fn bad_files_are_located_errors() {
    for (file, line, operand, words) in [
        ("missing_disz.zmx", Some(15), "DISZ", "no DISZ"),
        ("curv_nan.zmx", Some(18), "CURV", "not a finite number"),
        ("curv_absurd.zmx", Some(18), "CURV", "below any lens"),
        ("crossing_surfaces.zmx", Some(19), "DISZ", "cross"),
        (
            "aperture_beyond_sphere.zmx",
            Some(21),
            "DIAM",
            "larger than the surface allows",
        ),
        (
            "aperture_beyond_conic.zmx",
            Some(22),
            "DIAM",
            "larger than the surface allows",
        ),
        ("unknown_glass_no_ndvd.zmx", Some(20), "GLAS", "no nd/Vd"),
        (
            "unknown_glass_with_ndvd.zmx",
            Some(20),
            "GLAS",
            "substitution is allowed",
        ),
        ("parm9.zmx", Some(27), "PARM", "beyond 8"),
        ("toroidal.zmx", Some(17), "TYPE", "TOROIDAL"),
        ("coordbrk.zmx", Some(23), "TYPE", "COORDBRK"),
        ("mode_nsc.zmx", Some(2), "MODE", "SEQ"),
        ("utf16_odd_length.zmx", None, "", "odd length"),
    ] {
        let path = bad(file);
        let err = read_zmx(&path, &GlassOptions::default()).unwrap_err();
        let Error::Input { location, message } = &err else {
            panic!("{file}: {err}");
        };
        assert_eq!(location.file.as_deref(), Some(path.as_path()), "{file}");
        assert_eq!(location.line, line, "{file}: {err}");
        assert_eq!(
            location.field.as_deref().unwrap_or(""),
            operand,
            "{file}: {err}"
        );
        assert!(message.contains(words), "{file}: {err}");
    }
}

#[test]
fn substitution_only_when_allowed_and_always_reported() {
    let opts = GlassOptions {
        allow_substitution: true,
        ..GlassOptions::default()
    };
    let lens = read_zmx(&bad("unknown_glass_with_ndvd.zmx"), &opts).unwrap();
    assert_eq!(lens.substitutions.len(), 1);
    let s = &lens.substitutions[0];
    assert_eq!(
        (s.glass.as_str(), s.nd, s.vd, s.line),
        ("NOT-A-GLASS", 1.6, 45.0, 20)
    );
    let n = lens.prescription.surfaces[0]
        .medium_after
        .index(587.5618e-9)
        .unwrap();
    assert!((n - 1.6).abs() < 1e-12);
    // No nd/Vd: still an error.
    assert!(read_zmx(&bad("unknown_glass_no_ndvd.zmx"), &opts).is_err());
}

#[test]
fn catalogue_files_sellmeier_schott_and_ranges() {
    let cat = catalogue();
    let nd = |name: &str| {
        let m = cat.medium(name).unwrap().unwrap();
        m.index(587.5618e-9).unwrap()
    };
    // reference.json → test_catalogue_nd.
    for (name, v) in [
        ("N-SF6HT", 1.8051802),
        ("S-LAH64", 1.7880008),
        ("BK7", 1.5167997),
        ("NARROW-BK7", 1.5168000),
    ] {
        assert!((nd(name) - v).abs() < 1e-7, "{name}: {}", nd(name));
    }
    // Sellmeier coefficients read interleaved: the built-in N-SF6HT exactly.
    let sf6 = cat.medium("n-sf6ht").unwrap().unwrap();
    assert_eq!(sf6.glass, crate::optics::glass::N_SF6HT);
    let narrow = cat.medium("NARROW-BK7").unwrap().unwrap();
    let e = narrow.index(850e-9).unwrap_err().to_string();
    assert!(
        e.contains("test_catalogue.agf, line") && e.contains("outside"),
        "{e}"
    );
    assert!(cat.medium("N-BK7").is_none());
}

/// A prescription whose glass is in a catalogue file, found through it, and a wavelength
/// outside that glass's range refused by the report.
#[test]
fn glasses_resolve_through_catalogue_files_first() {
    let text = std::fs::read_to_string(
        root().join("validation/lenses/test_prescriptions/sphere_biconvex.zmx"),
    )
    .unwrap()
    .replace("GLAS N-BK7", "GLAS NARROW-BK7");
    let opts = GlassOptions {
        catalogues: vec![catalogue()],
        allow_substitution: false,
    };
    let lens = from_bytes(text.as_bytes(), Path::new("narrow.zmx"), &opts).unwrap();
    assert!(
        lens.prescription.surfaces[0]
            .medium_after
            .source
            .contains("test_catalogue.agf")
    );
    assert!(report::report(&lens, 587.5618, None).is_ok());
    assert!(report::report(&lens, 850.0, None).is_err());
    // Ignored operands are listed.
    assert!(lens.ignored.iter().any(|(op, _)| op == "WAVM"));
}

/// An operand that may change the geometry inside a surface block is refused, located.
#[test]
fn unknown_surface_operands_are_refused() {
    let text = std::fs::read_to_string(
        root().join("validation/lenses/test_prescriptions/sphere_biconvex.zmx"),
    )
    .unwrap()
    .replacen("  DISZ 6", "  SQAP 5 5\n  DISZ 6", 1);
    let e = from_bytes(
        text.as_bytes(),
        Path::new("sq.zmx"),
        &GlassOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("SQAP") && e.contains("sq.zmx, line"), "{e}");
}
