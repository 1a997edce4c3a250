use std::path::{Path, PathBuf};

use glam::DVec3;

use super::*;
use crate::optics::glass::Glass;

/// The symmetric test bench with `glasses` added before its lamp and its + arm's lens made
/// of the glass `lens_glass`.
fn with_glasses(glasses: &str, lens_glass: &str) -> (String, PathBuf) {
    let (text, path) = base();
    let text = text
        .replacen(
            "(\n    lamp: (",
            &format!("(\n    glasses: [{glasses}],\n    lamp: ("),
            1,
        )
        .replacen("glass: \"N-BK7\"", &format!("glass: \"{lens_glass}\""), 1);
    (text, path)
}

const MY_BK7: &str = "(name: \"MY-BK7\", sellmeier_b: (1.03961212, 0.231792344, 1.01046945), \
     sellmeier_c_um2: (0.00600069867, 0.0200179144, 103.560653))";

/// A bench's own glass with N-BK7's coefficients builds the same media as the catalogue's
/// N-BK7, traces bit-identically, and survives the canonical RON writer.
#[test]
fn user_glass_equals_the_catalogue_glass_it_copies() {
    let (text, path) = with_glasses(MY_BK7, "my_bk7");
    let own = parse_bench(&text, &path).unwrap();
    let (plain, _) = base();
    let cat = parse_bench(&plain, &path).unwrap();
    let glasses = |b: &Bench| -> Vec<Glass> { b.media().iter().map(|m| m.glass.clone()).collect() };
    assert_eq!(glasses(&own), glasses(&cat));
    let opts = crate::trace::TraceOptions::new(20_480, 3);
    let (a, b) = (
        crate::trace::trace(&own, &opts).unwrap(),
        crate::trace::trace(&cat, &opts).unwrap(),
    );
    let (ta, tb) = (
        crate::transport::Transport::from_tallies(&own, &a),
        crate::transport::Transport::from_tallies(&cat, &b),
    );
    assert_eq!(ta.k[0].value.to_bits(), tb.k[0].value.to_bits());
    assert_eq!(ta.k[1].value.to_bits(), tb.k[1].value.to_bits());
    // Round trip: written as canonical RON and read back, the glass is still there.
    let doc = crate::scene::doc::BenchDoc::parse(&text, &path).unwrap();
    let ron = doc.to_ron().unwrap();
    assert!(ron.contains("MY-BK7"), "{ron}");
    let back = parse_bench(&ron, &path).unwrap();
    assert_eq!(glasses(&back), glasses(&own));
    // A bench without glasses writes no `glasses` field.
    let plain_doc = crate::scene::doc::BenchDoc::parse(&plain, &path).unwrap();
    assert!(!plain_doc.to_ron().unwrap().contains("glasses"));
}

/// Bad glasses are located input errors naming the field and line.
#[test]
fn bad_user_glasses_are_located() {
    let check = |glasses: &str, lens: &str, marker: &str, field: &str, words: &str| {
        let (text, path) = with_glasses(glasses, lens);
        let (msg, line) = fails_at(&text, &path, marker);
        assert!(msg.contains(&format!("line {line}")), "{msg} (line {line})");
        assert!(msg.contains("symmetric_arms.ron"), "{msg}");
        assert!(msg.contains(field), "{msg}");
        assert!(msg.contains(words), "{msg}");
    };
    // A catalogue name may not be redefined.
    check(
        &MY_BK7.replace("MY-BK7", "n_sf5"),
        "N-BK7",
        "name: \"n_sf5\"",
        "glasses[0].name",
        "catalogue glass N-SF5",
    );
    // A resonance inside the traced band (C = 0.36 µm²: 600 nm).
    check(
        &MY_BK7.replace("0.0200179144", "0.36"),
        "MY-BK7",
        "name: \"MY-BK7\"",
        "glasses[0].sellmeier_c_um2",
        "600.0 nm",
    );
    // Coefficients that give n < 1 somewhere in the band (C in nm² by mistake).
    check(
        "(name: \"WRONG\", sellmeier_b: (1.0, 0.2, 1.0), sellmeier_c_um2: (6000.0, 20000.0, 1.0e8))",
        "WRONG",
        "name: \"WRONG\"",
        "glasses[0].sellmeier_b",
        "µm²",
    );
    // Twice the same name.
    check(
        &format!("{MY_BK7}, {}", MY_BK7.replace("MY-BK7", "my bk7")),
        "MY-BK7",
        "name: \"my bk7\"",
        "glasses[1].name",
        "twice",
    );
    // A negative coefficient is refused by its type.
    let (text, path) = with_glasses(&MY_BK7.replace("1.03961212", "-1.0"), "MY-BK7");
    let msg = parse_bench(&text, &path).unwrap_err().to_string();
    assert!(
        msg.contains("non-negative") && msg.contains("glasses") && msg.contains("line "),
        "{msg}"
    );
    // An unknown glass names the catalogue and the bench's own glasses.
    let (text, path) = with_glasses(MY_BK7, "MY-BK8");
    let msg = parse_bench(&text, &path).unwrap_err().to_string();
    assert!(
        msg.contains("N-LAK22") && msg.contains("this bench's glasses (MY-BK7)"),
        "{msg}"
    );
}

fn base() -> (String, PathBuf) {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron");
    (std::fs::read_to_string(&p).unwrap(), p)
}

/// Applies one edit and parses; returns the error text and the 1-based line where `marker`
/// (a string of the edited text) sits.
fn fails(from: &str, to: &str, marker: &str) -> (String, usize) {
    let (text, path) = base();
    assert_eq!(text.matches(from).count(), 1, "edit {from}");
    fails_at(&text.replacen(from, to, 1), &path, marker)
}

/// Parses `text`, which must fail as a user error; returns the error text and the 1-based
/// line where `marker` sits.
fn fails_at(text: &str, path: &Path, marker: &str) -> (String, usize) {
    let line = text[..text.find(marker).expect("marker")]
        .matches('\n')
        .count()
        + 1;
    let err = parse_bench(text, path).expect_err("must fail");
    assert!(err.is_user_error());
    (err.to_string(), line)
}

fn expect(from: &str, to: &str, marker: &str, field: &str, words: &str) {
    let (msg, line) = fails(from, to, marker);
    assert!(
        msg.contains(&format!("line {line}")),
        "{msg} (expected line {line})"
    );
    assert!(
        msg.contains("field `")
            && (msg.contains(&format!("{field}`")) || msg.contains(&format!("{field}["))),
        "{msg}"
    );
    assert!(msg.contains(words), "{msg}");
    assert!(msg.contains("symmetric_arms.ron"), "{msg}");
}

/// Numbers that would reach the tracer as NaN, infinity, an overflow or a wrapped size are
/// refused where they are written, naming the field and the line.
#[test]
fn non_finite_huge_and_wrapping_numbers_are_refused_where_written() {
    expect(
        "position_mm: (0.0, 0.0, 100.0),",
        "position_mm: (0.0, NaN, 100.0),",
        "position_mm: (0.0, NaN",
        "position_mm",
        "finite",
    );
    expect(
        "position_mm: (39.0011, -39.0011, 123.8823),",
        "position_mm: (39.0011, -39.0011, 1e308),",
        "1e308",
        "position_mm",
        "within",
    );
    expect(
        "position_mm: (-17.2564, 17.2564, 54.8127),",
        "position_mm: (-17.2564, inf, 54.8127),",
        "inf, 54",
        "position_mm",
        "finite",
    );
    expect(
        "axis: Vector((0.0, 0.0, -1.0)),",
        "axis: Vector((0.0, 0.0, -1e300)),",
        "-1e300",
        "axis",
        "within",
    );
    expect(
        "temperature_k: 2800.0",
        "temperature_k: 1e9",
        "1e9",
        "temperature_k",
        "4000",
    );
    let (msg, _) = fails(
        "units_across: 4, units_down: 4, mirrors_per_unit: 8",
        "units_across: 4, units_down: 4, mirrors_per_unit: 4611686018427387904",
        "mirrors_per_unit: 46",
    );
    assert!(
        msg.contains("mirrors_per_unit") && msg.contains("from 1 to 100000"),
        "{msg}"
    );
    // The angles of a polar direction are checked alike (φ was not, while θ was).
    for bad in ["NaN", "-inf", "1e308"] {
        expect(
            "theta_deg: 24.0, phi_deg: -45.0",
            &format!("theta_deg: 24.0, phi_deg: {bad}"),
            &format!("phi_deg: {bad}"),
            "phi_deg",
            "360",
        );
    }
}

#[test]
fn the_test_benches_and_the_paper_bench_parse() {
    let (text, path) = base();
    let b = parse_bench(&text, &path).unwrap();
    assert_eq!(b.units(), 16);
    assert_eq!(b.elements()[b.lamp_housing()], "lamp_housing");
    // The paper bench parses as far as its chart (the USAF geometry is another module's).
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let file: BenchFile = crate::scene::read_ron(&p).unwrap();
    assert_eq!(file.elements.len(), 13);
    let d = file.dmd.as_ref().unwrap();
    assert_eq!(
        d.pattern.units_across.get() * d.pattern.mirrors_per_unit.get(),
        576
    );
}

#[test]
fn directions() {
    let v = Direction::Polar {
        theta_deg: crate::scene::numbers::DirectionDeg(24.0),
        phi_deg: crate::scene::numbers::DirectionDeg(-45.0),
    }
    .to_unit()
    .unwrap();
    assert!((v - DVec3::new(0.287_606, -0.287_606, 0.913_545)).length() < 1e-6);
    assert!(Direction::Vector(Mm3(0.0, 0.0, 0.0)).to_unit().is_err());
    // Huge but finite components normalise without overflow.
    let u = Direction::Vector(Mm3(1e300, 1e300, 0.0)).to_unit().unwrap();
    assert!((u.length() - 1.0).abs() < 1e-12);
}

#[test]
fn single_value_errors_carry_line_and_field() {
    expect(
        "power: InBand(watts: 1.0),",
        "power: InBand(watts: -1.0),",
        "watts: -1.0",
        "watts",
        "positive",
    );
    expect(
        "            diameter_mm: 5.0,\n        ),\n        minus",
        "            diameter_mm: 0.0,\n        ),\n        minus",
        "diameter_mm: 0.0",
        "diameter_mm",
        "positive",
    );
    expect(
        "spectrum: Tungsten(temperature_k: 2800.0),",
        "spectrum: Table([(500.0, 1.0), (400.0, 2.0)]),",
        "Table([(500.0",
        "spectrum",
        "strictly increasing",
    );
    expect(
        "        pitch_um: 100.0,",
        "        pitch_um: 100.0,\n        pich_um: 3.0,",
        "pich_um",
        "pich_um",
        "pich_um",
    );
}

#[test]
fn geometry_errors_carry_line_and_field() {
    // A lens too thin for its radius and diameter: the faces would cross before the rim.
    expect(
        "            thickness_mm: 5.34,\n            diameter_mm: 25.4,\n            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
        "            thickness_mm: 2.0,\n            diameter_mm: 25.4,\n            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
        "thickness_mm: 2.0",
        "thickness_mm",
        "faces cross",
    );
    // A radius that cannot span the diameter.
    expect(
        "            front_radius_mm: 25.75,\n            thickness_mm: 5.34,\n            diameter_mm: 25.4,\n            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
        "            front_radius_mm: 10.0,\n            thickness_mm: 5.34,\n            diameter_mm: 25.4,\n            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
        "front_radius_mm: 10.0",
        "front_radius_mm",
        "cannot span",
    );
    // Overlapping elements: move the − lens onto the + lens.
    expect(
        "position_mm: (-17.2564, 17.2564, 54.8127),",
        "position_mm: (17.2564, -17.2564, 56.0),",
        "position_mm: (17.2564, -17.2564, 56.0)",
        "position_mm",
        "overlaps",
    );
    // A pattern area larger than the array.
    expect(
        "units_across: 4,",
        "units_across: 5,",
        "pattern: (origin",
        "pattern",
        "does not fit",
    );
    // An unknown glass.
    expect(
        "            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
        "            glass: \"N-BK8\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
        "glass: \"N-BK8\"",
        "glass",
        "unknown glass",
    );
    // Emission toward an element that does not exist.
    expect(
        "emission: Cone(half_angle_deg: 3.0),",
        "emission: Toward(element: \"nothing\"),",
        "emission: Toward",
        "emission",
        "nothing",
    );
    // A field target outside the emission cone.
    expect(
        "center_mm: (0.0, 0.0, 0.0),",
        "center_mm: (30.0, 0.0, 0.0),",
        "field_sampling: (",
        "field_sampling",
        "outside the emission cone",
    );
}

#[test]
fn unsorted_nd_table_is_rejected_at_its_line() {
    // An ND filter added to the test bench with an unsorted OD table.
    let filter = "        Filter(\n            name: \"nd\",\n            position_mm: (0.0, 0.0, 80.0),\n            axis: Vector((0.0, 0.0, -1.0)),\n            outline: Round(diameter_mm: 10.0),\n            thickness_mm: 2.0,\n            glass: \"N-BK7\",\n            od: Table([(400.0, 1.0), (900.0, 0.6), (700.0, 0.8)]),\n        ),\n    ],\n    dmd:";
    expect(
        "    ],\n    dmd:",
        filter,
        "od: Table",
        "od",
        "strictly increasing",
    );
}
