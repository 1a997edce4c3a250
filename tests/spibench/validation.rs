//! Validation against Mitsuba 3 (validation/README.md, "Mitsuba 3 references"): spibench traces
//! every case of validation/mitsuba/references.json, the reference powers that Mitsuba 3.9.1
//! rendered from the same benches exported by `spibench export-mitsuba`, and the two are
//! compared by z-tests on the combined standard error with a Šidák correction. The references
//! are only read here: nothing in the test suite writes them (regenerate.sh does, by hand).
//!
//! Statistics. For a quantity with spibench estimate a ± s_a (batch means) and Mitsuba estimate
//! b ± s_b (per-ray or per-render spread), independent, z = (a − b)/√(s_a² + s_b²) is standard
//! normal when both are unbiased for the same value. A family of m such comparisons is tested
//! at a family-wise error rate α = 0.01 with the Šidák per-comparison level
//! α₁ = 1 − (1 − α)^(1/m) and the two-sided critical value z* = Φ⁻¹(1 − α₁/2) (computed below;
//! for the 26 comparisons of the agreement test α₁ = 3.87e-4 and z* = 3.549). The traces are
//! seeded, so the outcome is deterministic.
//!
//! Precision rules: wherever the reference's own relative standard error is below 0.2 %, the
//! relative difference must also be at most 0.5 %; the ray counts below give spibench standard
//! errors of 0.1 % or less on those cases, so a true agreement passes that rule by more than 3
//! combined standard errors. The cases in [`TIGHT`] are held tighter: their references must
//! carry a relative standard error of at most 0.1 % (`TIGHT_REFERENCE_SE`; run_references.py
//! re-centres every case so that Mitsuba's ray offset does not bias them, and renders them with
//! enough rays), spibench traces them to under 0.1 % too, and the relative difference must be
//! at most `TIGHT_REL` = 0.4 %: about 3 combined standard errors of at most
//! √(0.1² + 0.1²) = 0.14 %. Those are lens_focus (a lens 200 mm from the bench file's origin,
//! reference ±0.044 %), chart_lens (±0.043 %, 1.6e8 rays) and the paper bench (±0.093 % per
//! diode, 5e8 rays, traced here with 8e6 rays to ±0.08 %).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use serde_json::Value;
use spibench::export::DmdPattern;
use spibench::optics::monochromatic::{MonochromaticOptions, monochromatic};
use spibench::trace::{PatternMode, Sampling, TraceOptions, trace};
use spibench::transport::{Estimate, fixed_pattern_currents};

/// Family-wise error rate of every family of comparisons here.
const ALPHA: f64 = 0.01;

/// Cases held to the tight precision rule (module documentation).
const TIGHT: [&str; 3] = ["lens_focus", "chart_lens", "paper_bench"];
/// The largest relative standard error a reference of a [`TIGHT`] case may carry.
const TIGHT_REFERENCE_SE: f64 = 0.001;
/// The largest relative difference allowed on a [`TIGHT`] case.
const TIGHT_REL: f64 = 0.004;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// One reference case.
#[derive(Debug, Clone)]
struct Case {
    name: String,
    bench: String,
    pattern: String,
    wavelength_nm: Option<f64>,
    reference: [Estimate; 2],
    closed_form: Option<[f64; 2]>,
}

fn estimate(v: &Value) -> Estimate {
    Estimate {
        value: v["value"].as_f64().expect("value"),
        stderr: v["stderr"].as_f64().expect("stderr"),
    }
}

fn references() -> (Value, Vec<Case>) {
    let path = root().join("validation/mitsuba/references.json");
    let text = std::fs::read_to_string(&path).expect("validation/mitsuba/references.json");
    let v: Value = serde_json::from_str(&text).expect("references.json is JSON");
    let cases = v["cases"]
        .as_array()
        .expect("cases")
        .iter()
        .map(|c| Case {
            name: c["name"].as_str().unwrap().to_string(),
            bench: c["bench"].as_str().unwrap().to_string(),
            pattern: c["pattern"].as_str().unwrap().to_string(),
            wavelength_nm: c["substitute_wavelength_nm"].as_f64(),
            reference: [estimate(&c["plus"]), estimate(&c["minus"])],
            closed_form: c["closed_form"]
                .as_array()
                .map(|a| [a[0].as_f64().unwrap(), a[1].as_f64().unwrap()]),
        })
        .collect();
    (v, cases)
}

/// spibench rays per case: chosen for standard errors of ≤ 0.1 % where the reference is better
/// than 0.2 % (measured at 4e6 rays: lens_focus 0.10 %, so it gets 6e6; chart_lens 0.085 %; the
/// paper bench 0.12 % per diode, so it gets 8e6), within a total of about 30 s on two cores
/// (measured rates:
/// 1e6 rays of the small DMD bench in 1.1 s, of the paper bench in 1.9 s).
fn rays(name: &str) -> u64 {
    match name {
        "disk_to_disk" | "spectral_disk" => 1_000_000,
        "lens_focus" => 6_000_000,
        "chart_lens" => 4_000_000,
        "ghost_plate" | "paper_bench" => 8_000_000,
        n if n.starts_with("paper") => 4_000_000,
        _ => 1_000_000,
    }
}

/// Traces one case as the references were rendered: the monochromatic substitute at the stated
/// wavelength (or the bench as it is), the DMD in the case's pattern, no splitting.
fn trace_case(case: &Case, seed: u64) -> [Estimate; 2] {
    let path = root().join(&case.bench);
    let bench = spibench::scene::bench::read_bench(&path).expect("case bench");
    let bench = match case.wavelength_nm {
        Some(nm) => {
            monochromatic(&bench, &MonochromaticOptions::at_nm(nm))
                .unwrap()
                .bench
        }
        None => bench,
    };
    let bits = case
        .pattern
        .parse::<DmdPattern>()
        .unwrap()
        .bits(bench.units(), &root())
        .unwrap();
    let opts = TraceOptions {
        rays: rays(&case.name),
        seed,
        mode: PatternMode::Fixed(&bits),
        sampling: sampling(),
        ..TraceOptions::new(0, 0)
    };
    fixed_pattern_currents(&bench, &trace(&bench, &opts).unwrap())
}

/// The tracer's default sampling, or the analogue tracer with `SPIBENCH_SAMPLING=independent`
/// (to compare the two estimators on every case by hand; the suite runs the default).
fn sampling() -> Sampling {
    match std::env::var("SPIBENCH_SAMPLING").as_deref() {
        Ok("independent") => Sampling::Independent,
        _ => Sampling::default(),
    }
}

/// Every case traced once (seeds 100, 101, ... in file order: independent between cases), shared
/// by the tests of this file.
fn traced() -> &'static Vec<(Case, [Estimate; 2])> {
    static CELL: OnceLock<Vec<(Case, [Estimate; 2])>> = OnceLock::new();
    CELL.get_or_init(|| {
        let (_, cases) = references();
        cases
            .into_iter()
            .enumerate()
            .map(|(i, c)| {
                let e = trace_case(&c, 100 + i as u64);
                (c, e)
            })
            .collect()
    })
}

/// erfc(x) (Numerical Recipes' erfcc, fractional error below 1.2e-7 everywhere).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let ans = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 { ans } else { 2.0 - ans }
}

/// The Šidák two-sided critical z for m comparisons at family-wise level `alpha`:
/// P(|Z| > z) = 1 − (1 − alpha)^(1/m), solved by bisection on erfc(z/√2).
fn sidak_z(m: usize, alpha: f64) -> f64 {
    let a1 = 1.0 - (1.0 - alpha).powf(1.0 / m as f64);
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if erfc(mid / std::f64::consts::SQRT_2) > a1 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// (z, relative difference) of a against b; both exactly zero gives z = 0.
fn compare(a: Estimate, b: Estimate) -> (f64, f64) {
    let diff = a.value - b.value;
    let se = a.stderr.hypot(b.stderr);
    let z = if diff == 0.0 {
        0.0
    } else if se > 0.0 {
        diff / se
    } else {
        f64::INFINITY
    };
    let rel = if b.value != 0.0 { diff / b.value } else { 0.0 };
    (z, rel)
}

#[test]
fn sidak_critical_values() {
    // One comparison at α = 0.05: the familiar 1.95996; 20 at 0.05: 1 − 0.95^(1/20) = 2.561e-3,
    // z = 3.0157 (tables of the Šidák correction).
    assert!((sidak_z(1, 0.05) - 1.959_96).abs() < 1e-4);
    assert!((sidak_z(20, 0.05) - 3.0157).abs() < 2e-3);
}

#[test]
fn references_cover_the_required_cases() {
    let (v, cases) = references();
    assert!(cases.len() >= 10, "{} cases", cases.len());
    let names: Vec<&str> = cases.iter().map(|c| c.name.as_str()).collect();
    for required in [
        "disk_to_disk",
        "lens_focus",
        "chart_lens",
        "dmd_all_plus",
        "dmd_all_minus",
        "dmd_random",
        "dmd_complement",
        "paper_bench",
        "paper_all_plus",
        "misaligned_all_minus",
        "ghost_plate",
        "spectral_disk",
    ] {
        assert!(names.contains(&required), "missing case {required}");
    }
    for c in v["cases"].as_array().unwrap() {
        assert_eq!(c["mitsuba_version"], "3.9.1", "{}", c["name"]);
        assert!(
            c["variant"]
                .as_str()
                .is_some_and(|s| s.starts_with("llvm_ad_"))
        );
        assert!(c["samples"].as_u64().is_some_and(|n| n > 0));
        for d in ["plus", "minus"] {
            let e = estimate(&c[d]);
            assert!(e.value >= 0.0 && e.stderr >= 0.0 && e.value.is_finite());
        }
        assert!(Path::new(&root().join(c["bench"].as_str().unwrap())).exists());
    }
}

/// Mitsuba cannot render the diffractive DMD: every case bench with a DMD states the geometric
/// model, and the paper bench's cases trace the shipped bench itself with plane mirrors, field
/// for field (a change to scenes/paper_bench.ron must be made to the validation copy too, and
/// the references rendered again).
#[test]
fn validation_paper_bench_is_the_shipped_one_with_plane_mirrors() {
    use spibench::scene::doc::{BenchDoc, DmdModel};
    for c in references().1 {
        let doc = BenchDoc::read(&root().join(&c.bench)).unwrap();
        if doc.file.dmd.is_some() {
            assert_eq!(doc.dmd_model(), Some(DmdModel::Geometric), "{}", c.name);
            let text = std::fs::read_to_string(root().join(&c.bench)).unwrap();
            assert!(text.contains("model: Geometric"), "{}: not stated", c.name);
        }
    }
    let mut shipped = BenchDoc::read(&root().join("scenes/paper_bench.ron")).unwrap();
    assert_eq!(shipped.dmd_model(), Some(DmdModel::Diffractive));
    shipped.set_dmd_model(DmdModel::Geometric).unwrap();
    let copy = BenchDoc::read(&root().join("validation/mitsuba/cases/paper_bench.ron")).unwrap();
    assert_eq!(copy.file, shipped.file);
}

#[test]
fn spibench_agrees_with_mitsuba_on_every_case() {
    let results = traced();
    let m = 2 * results.len();
    let z_crit = sidak_z(m, ALPHA);
    let mut failures = Vec::new();
    eprintln!(
        "{:<22} {:>5} {:>24} {:>24} {:>7} {:>8}",
        "case", "diode", "spibench", "Mitsuba", "z", "rel"
    );
    for (case, ours) in results {
        for (d, (&mine, &r)) in ours.iter().zip(&case.reference).enumerate() {
            let (z, rel) = compare(mine, r);
            eprintln!(
                "{:<22} {:>5} {:>14.6e} ± {:>7.1e} {:>14.6e} ± {:>7.1e} {:>7.2} {:>7.3}%",
                case.name,
                if d == 0 { "+" } else { "-" },
                mine.value,
                mine.stderr,
                r.value,
                r.stderr,
                z,
                100.0 * rel
            );
            if z.abs() > z_crit {
                failures.push(format!("{} diode {d}: z = {z:.2} > {z_crit:.2}", case.name));
            }
            if TIGHT.contains(&case.name.as_str()) && r.value > 0.0 {
                if r.stderr > TIGHT_REFERENCE_SE * r.value {
                    failures.push(format!(
                        "{} diode {d}: the reference's standard error {:.3} % is above {:.1} %",
                        case.name,
                        100.0 * r.stderr / r.value,
                        100.0 * TIGHT_REFERENCE_SE
                    ));
                }
                if rel.abs() > TIGHT_REL {
                    failures.push(format!(
                        "{} diode {d}: relative difference {:.3} % > {:.1} %",
                        case.name,
                        100.0 * rel,
                        100.0 * TIGHT_REL
                    ));
                }
            }
            if r.value > 0.0 && r.stderr < 0.002 * r.value && rel.abs() > 0.005 {
                failures.push(format!(
                    "{} diode {d}: relative difference {:.3} % > 0.5 % with a {:.3} % reference",
                    case.name,
                    100.0 * rel,
                    100.0 * r.stderr / r.value
                ));
            }
        }
    }
    eprintln!("{m} comparisons, α = {ALPHA}, Šidák z* = {z_crit:.3}");
    for name in TIGHT {
        assert!(
            results.iter().any(|(c, _)| c.name == name),
            "tight case {name} missing"
        );
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn closed_form_case_matches_both_renderers() {
    // The disk-to-disk exchange: spibench and Mitsuba each against Φ·F₁₂, 2 comparisons per
    // renderer (only the lit diode), Šidák at α over the 2.
    let results = traced();
    let z_crit = sidak_z(2, ALPHA);
    let (case, ours) = results
        .iter()
        .find(|(c, _)| c.name == "disk_to_disk")
        .expect("disk_to_disk case");
    let exact = case.closed_form.expect("closed form")[0];
    for e in [ours[0], case.reference[0]] {
        let z = (e.value - exact) / e.stderr;
        assert!(z.abs() < z_crit, "{e:?} vs Φ·F = {exact}: z = {z:.2}");
    }
}

fn find<'a>(results: &'a [(Case, [Estimate; 2])], name: &str) -> &'a (Case, [Estimate; 2]) {
    results
        .iter()
        .find(|(c, _)| c.name == name)
        .unwrap_or_else(|| panic!("case {name}"))
}

/// a/b with its delta-method standard error (independent a, b).
fn ratio(a: Estimate, b: Estimate) -> Estimate {
    let r = a.value / b.value;
    Estimate {
        value: r,
        stderr: r.abs() * (a.relative_stderr().powi(2) + b.relative_stderr().powi(2)).sqrt(),
    }
}

fn sum(terms: &[(f64, Estimate)]) -> Estimate {
    Estimate {
        value: terms.iter().map(|(c, e)| c * e.value).sum(),
        stderr: terms
            .iter()
            .map(|(c, e)| (c * e.stderr).powi(2))
            .sum::<f64>()
            .sqrt(),
    }
}

#[test]
fn structure_agrees_flip_leak_and_complements() {
    // Structure, not only totals (every case traced with its own seed, so the terms below are
    // independent and their variances add):
    // - flip: P₊(all +) / P₋(all −), the arm balance, on the symmetric and the misaligned bench;
    // - leak: the off arm's power as a fraction of the on arm's, P₋(all +)/P₊(all +) and
    //   P₊(all −)/P₋(all −) (exactly 0 on the small bench without a window: both must be 0);
    // - complements: D_d = P_d(S) + P_d(Sᶜ) − P_d(all +) − P_d(all −) for each diode, which
    //   linearity makes 0; spibench's D against Mitsuba's D, and each against 0.
    // - the paper bench's leak P₋(all +)/P₊(all +): light of the mirrors outside the pattern
    //   area (parked in state −), window and stray paths, compared as a ratio;
    // Family: 2 flips + 1 leak + 2 complement differences + 4 D-against-0 = 9 z-tests, Šidák at
    // α (z* = 3.26).
    let results = traced();
    let z_crit = sidak_z(9, ALPHA);
    let mut failures = Vec::new();
    let mut check = |label: &str, a: Estimate, b: Estimate| {
        let (z, rel) = compare(a, b);
        eprintln!(
            "{label:<34} spibench {:.6e} ± {:.1e}  Mitsuba {:.6e} ± {:.1e}  z {z:.2} ({:.3} %)",
            a.value,
            a.stderr,
            b.value,
            b.stderr,
            100.0 * rel
        );
        if z.abs() > z_crit {
            failures.push(format!("{label}: z = {z:.2} > {z_crit:.2}"));
        }
    };
    for (plus, minus) in [
        ("dmd_all_plus", "dmd_all_minus"),
        ("misaligned_all_plus", "misaligned_all_minus"),
    ] {
        let (cp, sp) = find(results, plus);
        let (cm, sm) = find(results, minus);
        check(
            &format!("flip {plus}/{minus}"),
            ratio(sp[0], sm[1]),
            ratio(cp.reference[0], cm.reference[1]),
        );
        // Leak: no path from the + facets to the − diode exists on this bench; both renderers
        // must find exactly none.
        for (label, a, b) in [
            ("leak P-(all+)", sp[1], cp.reference[1]),
            ("leak P+(all-)", sm[0], cm.reference[0]),
        ] {
            assert!(
                a.value == 0.0 && b.value == 0.0,
                "{plus}: {label}: {a:?} vs {b:?}"
            );
        }
    }
    let (pc, ps) = find(results, "paper_all_plus");
    check(
        "leak paper P-(all+)/P+(all+)",
        ratio(ps[1], ps[0]),
        ratio(pc.reference[1], pc.reference[0]),
    );
    let get = |n: &str| find(results, n).clone();
    let (s, ssp) = get("dmd_random");
    let (sc, sscp) = get("dmd_complement");
    let (on, onsp) = get("dmd_all_plus");
    let (off, offsp) = get("dmd_all_minus");
    for d in 0..2 {
        let ours = sum(&[
            (1.0, ssp[d]),
            (1.0, sscp[d]),
            (-1.0, onsp[d]),
            (-1.0, offsp[d]),
        ]);
        let theirs = sum(&[
            (1.0, s.reference[d]),
            (1.0, sc.reference[d]),
            (-1.0, on.reference[d]),
            (-1.0, off.reference[d]),
        ]);
        check(&format!("P(S)+P(Sc)-P(+)-P(-) diode {d}"), ours, theirs);
        check(&format!("spibench D_{d} vs 0"), ours, Estimate::exact(0.0));
        check(&format!("Mitsuba D_{d} vs 0"), theirs, Estimate::exact(0.0));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
