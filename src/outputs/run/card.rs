//! The summary card of `spibench run`: the bench's gains, imbalances, offsets and CMRR, the
//! leading scheme at each sampling ratio with its margin, and whether the solves converged, all
//! read from `summary.json`'s values.

use serde_json::Value;

use crate::outputs::card::{Card, num, pm, sig};

/// The card of a run, from its summary.json as a value.
pub fn card(summary: &Value) -> Card {
    let mut c = Card::new("summary");
    let t = "/transport";
    let pmv = |v: &[Value], unit: &str| pm(num(&v[0]), num(&v[1]), unit);
    c.line(
        summary,
        "k₊, k₋",
        &[
            &format!("{t}/k_plus"),
            &format!("{t}/k_plus_stderr"),
            &format!("{t}/k_minus"),
            &format!("{t}/k_minus_stderr"),
        ],
        |v| format!("{}, {}", pmv(&v[..2], "A/W"), pmv(&v[2..], "A/W")),
    );
    c.line(
        summary,
        "k′ = k₊ + k₋",
        &[&format!("{t}/k_prime"), &format!("{t}/k_prime_stderr")],
        |v| pmv(v, "A/W"),
    );
    c.line(
        summary,
        "imbalance, optical",
        &[&format!("{t}/imbalance"), &format!("{t}/imbalance_stderr")],
        |v| format!("{} ((k₊ − k₋)/(k₊ + k₋))", pmv(v, "")),
    );
    c.line(
        summary,
        "imbalance, electrical",
        &[
            "/electronics/imbalance_electrical",
            "/electronics/imbalance_electrical_stderr",
        ],
        |v| format!("{} (with the diodes' responsivity mismatch)", pmv(v, "")),
    );
    c.line(
        summary,
        "b₊, b₋",
        &[
            &format!("{t}/b_plus"),
            &format!("{t}/b_plus_stderr"),
            &format!("{t}/b_minus"),
            &format!("{t}/b_minus_stderr"),
        ],
        |v| format!("{}, {}", pmv(&v[..2], "A"), pmv(&v[2..], "A")),
    );
    c.line(
        summary,
        "CMRR",
        &[
            "/electronics/cmrr_db",
            "/electronics/cmrr_db_stderr",
            "/electronics/cmrr_electronics_db",
        ],
        |v| {
            format!(
                "{} with the optics; electronics alone {}",
                pm(num(&v[0]), num(&v[1]), "dB"),
                pm(num(&v[2]), f64::NAN, "dB")
            )
        },
    );
    let standings = summary
        .pointer("/findings/mssim/at_ratios")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    let repeats = summary
        .pointer("/findings/repeats")
        .map_or(1, |v| v.as_u64().unwrap_or(1));
    for i in 0..standings {
        let at = format!("/findings/mssim/at_ratios/{i}");
        let m = format!("{at}/margins/0");
        let ratio = num(summary
            .pointer(&format!("{at}/ratio"))
            .unwrap_or(&Value::Null));
        c.line(
            summary,
            format!("MSSIM at {}", crate::run::findings::pct(ratio)),
            &[
                &format!("{at}/best"),
                &format!("{at}/best_mean"),
                &format!("{m}/scheme"),
                &format!("{m}/mean"),
                &format!("{m}/ci95"),
                &format!("{m}/verdict"),
            ],
            |v| leader(v, repeats),
        );
    }
    c.line(
        summary,
        "solver",
        &[
            "/findings/solves_at_cap",
            "/findings/solves",
            "/settings/solver/maxcnt",
            "/settings/solver/maxit",
        ],
        |v| {
            let (cap, all) = (v[0].as_u64().unwrap_or(0), v[1].as_u64().unwrap_or(0));
            if cap == 0 {
                format!("TVAL3 met its tolerance in all {all} solves")
            } else {
                format!(
                    "⚠ {cap} of {all} solves ended on a cap (maxcnt {}, maxit {}), not converged",
                    v[2], v[3]
                )
            }
        },
    );
    c
}

/// "SCB 0.9873, +0.0005 [−0.0010, +0.0019] over cal. double-arm: not distinguished".
fn leader(v: &[Value], repeats: u64) -> String {
    let scheme = |x: &Value| {
        serde_json::from_value::<crate::acquisition::Scheme>(x.clone()).map_or_else(
            |_| x.to_string(),
            |s| crate::run::findings::short(s).to_string(),
        )
    };
    let head = format!("{} {}", scheme(&v[0]), sig(num(&v[1]), 4));
    if v[2].is_null() {
        return head;
    }
    let margin = format!("{:+.4}", num(&v[3]));
    match v[4].as_array() {
        Some(ci) if ci.len() == 2 => {
            let verdict = if v[5] == "ahead" {
                "ahead (95 % interval excludes 0)"
            } else {
                "not distinguished"
            };
            format!(
                "{head}, {margin} [{:+.4}, {:+.4}] over {}: {verdict}",
                num(&ci[0]),
                num(&ci[1]),
                scheme(&v[2])
            )
        }
        _ => format!(
            "{head}, {margin} over {}: untested ({repeats} run)",
            scheme(&v[2])
        ),
    }
}
