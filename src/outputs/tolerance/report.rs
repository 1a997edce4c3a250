//! The blocks of `tolerance`'s `report.html`: what was traced, the sensitivity table and the
//! Monte Carlo tables (percentiles, yields, tails, compensators, RSS against Monte Carlo).

use crate::report::html::Block;
use crate::scene::tolerance::{SensitivityRecord, ShardFile, ToleranceSet};
use crate::tolerance::{Analysis, SENSITIVITY_METRICS};

/// `value ± stderr` in engineering notation: one power of ten that is a multiple of 3 for
/// both, the standard error to two significant digits and the value to the same place
/// ("(−814.6 ± 2.5)×10⁻³"); without a finite standard error, the value to four digits.
pub(super) fn pm(v: f64, se: f64) -> String {
    if !v.is_finite() {
        return "–".into();
    }
    let mag = if v != 0.0 {
        v.abs()
    } else if se.is_finite() && se > 0.0 {
        se
    } else {
        return "0".into();
    };
    let e3 = 3 * (mag.log10().floor() as i32).div_euclid(3);
    let scale = 10f64.powi(e3);
    let (m, ms) = (v / scale, se / scale);
    let body = if ms.is_finite() && ms > 0.0 {
        let d = (1 - ms.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{m:+.d$} ± {ms:.d$}")
    } else {
        let d = (3 - m.abs().log10().floor() as i32).clamp(0, 6) as usize;
        format!("{m:+.d$}")
    };
    let body = body.replace('-', "−");
    if e3 == 0 {
        body
    } else {
        format!("({body})×10{}", crate::report::superscript(e3))
    }
}

/// A tolerance's name in the report: its path, and "(fixed: cannot be tightened)" for a
/// device specification.
pub(super) fn tolerance_name(set: &ToleranceSet, path: &str) -> String {
    if set
        .tolerances
        .iter()
        .any(|t| t.path == path && t.is_fixed())
    {
        format!("{path} (fixed: cannot be tightened)")
    } else {
        path.to_string()
    }
}

/// The report's opening paragraph: what was traced, how often, and how many trials failed.
pub(super) fn intro_block(s: &ShardFile, set: &ToleranceSet, analysis: &Analysis) -> Block {
    Block::Paragraph(format!(
        "{}: {} tolerance(s) from {}, {} compensator(s); every bench traced with {} rays and \
         seed {} (common random numbers: differences from the nominal bench carry paired \
         standard errors); {} Monte Carlo trial(s){}{}.",
        s.scene,
        set.tolerances.len(),
        s.tolerances_path,
        set.compensator_count(),
        s.rays,
        s.seed,
        s.records.len(),
        if s.quality {
            ", each through the whole pipeline"
        } else {
            ""
        },
        if analysis.failed_trials > 0 {
            format!(
                " ({} gave a bench that is not valid and count as failures)",
                analysis.failed_trials
            )
        } else {
            String::new()
        }
    ))
}

/// The sensitivity table of the report (after its tornado chart, `tornado`).
pub(super) fn sensitivity_blocks(
    sens: &[SensitivityRecord],
    set: &ToleranceSet,
    tornado: Option<Block>,
) -> Vec<Block> {
    let mut blocks = Vec::new();
    blocks.push(Block::Heading {
        level: 2,
        text: "Sensitivity".into(),
    });
    blocks.extend(tornado);
    blocks.push(Block::Table {
        caption: Some(
            "Each tolerance alone at its min / max: change from the nominal bench ± its \
             paired standard error, in engineering notation, sorted by the largest |Δ \
             imbalance| (optical); ι′ is the electrical imbalance, the diodes' responsivity \
             mismatch included; the rays of the row's traces (more than the run's where \
             --resolve asked for them)"
                .into(),
        ),
        header: [
            "tolerance",
            "range",
            "rays",
            "Δ ι′ (electrical)",
            "Δ imbalance",
            "Δ k' (A/W)",
            "Δ(b₋ − b₊) (A)",
            "Δ leak +",
            "Δ leak −",
            "Δ CMRR (dB)",
        ]
        .map(String::from)
        .to_vec(),
        rows: sens
            .iter()
            .flat_map(|r| {
                [false, true].map(|high| {
                    let e = crate::scene::tolerance::IMBALANCE_ELECTRICAL;
                    let mut row = vec![
                        if high {
                            String::new()
                        } else {
                            tolerance_name(set, &r.path)
                        },
                        format!("{}", if high { r.max } else { r.min }),
                        r.rays[usize::from(high)].to_string(),
                        pm(
                            r.at(high, &format!("{e}_diff")),
                            r.at(high, &format!("{e}_diff_stderr")),
                        ),
                    ];
                    for m in SENSITIVITY_METRICS {
                        row.push(pm(
                            r.at(high, &format!("{m}_diff")),
                            r.at(high, &format!("{m}_diff_stderr")),
                        ));
                    }
                    row
                })
            })
            .collect(),
    });
    blocks
}

/// The Monte Carlo tables of the report: percentiles, yields, the causes of the failures, RSS
/// against Monte Carlo.
pub(super) fn monte_carlo_blocks(analysis: &Analysis, set: &ToleranceSet) -> Vec<Block> {
    let mut blocks = Vec::new();
    blocks.push(Block::Heading {
        level: 2,
        text: "Monte Carlo".into(),
    });
    blocks.push(Block::Table {
        caption: Some(
            "Distribution over the trials (percentiles of the value and of its magnitude). \
             The leaks here are the recorded ratios P_wrong/P_own, unbounded where a part \
             blinds the own arm; the tails table and the figures show them as the bounded \
             fraction P_wrong/(P_own + P_wrong), 0 … 1"
                .into(),
        ),
        header: [
            "metric",
            "unit",
            "mean",
            "std dev",
            "median",
            "90 %",
            "97.7 %",
            "|·| median",
            "|·| 90 %",
            "|·| 97.7 %",
        ]
        .map(String::from)
        .to_vec(),
        rows: analysis
            .percentiles
            .iter()
            .map(|p| {
                let mut r = vec![p.metric.clone(), unit_of(&p.metric)];
                r.extend(
                    [
                        p.mean,
                        p.std_dev,
                        p.p50,
                        p.p90,
                        p.p97_7,
                        p.abs_p50,
                        p.abs_p90,
                        p.abs_p97_7,
                    ]
                    .map(|v| format!("{v:.4e}")),
                );
                r
            })
            .collect(),
    });
    let yield_cells = |y: &crate::tolerance::YieldRow| {
        vec![
            format!("{}/{}", y.passed, y.trials),
            format!("{:.1} % ± {:.1} %", 100.0 * y.fraction, 100.0 * y.stderr),
            format!("{:.1} … {:.1} %", 100.0 * y.ci95[0], 100.0 * y.ci95[1]),
        ]
    };
    let mut yrows: Vec<Vec<String>> = analysis
        .yields
        .iter()
        .map(|y| {
            let mut r = vec![y.limit.clone()];
            r.extend(yield_cells(y));
            r.push(y.optical.as_ref().map_or_else(
                || "–".into(),
                |o| format!("{}/{} ({:.1} %)", o.passed, o.trials, 100.0 * o.fraction),
            ));
            r
        })
        .collect();
    yrows.extend(analysis.quality_yields.iter().map(|(scheme, y)| {
        let mut r = vec![format!("{scheme}: {}", y.limit)];
        r.extend(yield_cells(y));
        r.push("–".into());
        r
    }));
    if !yrows.is_empty() {
        blocks.push(Block::Table {
            caption: Some(
                "Yield: the fraction of trials meeting each limit (± binomial standard \
                 error; the 95 % Wilson interval). A limit on the imbalance is judged on the \
                 electrical imbalance ι′ = (s₊k₊ − s₋k₋)/(s₊k₊ + s₋k₋), what the balanced \
                 detector's difference output sees with the diodes' responsivity mismatch; \
                 the same limit on the optical imbalance (k₊ − k₋)/(k₊ + k₋) is beside it. \
                 Image quality per scheme side by side"
                    .into(),
            ),
            header: [
                "limit",
                "trials passing",
                "yield",
                "95 % interval",
                "on the optical imbalance",
            ]
            .map(String::from)
            .to_vec(),
            rows: yrows,
        });
    }
    blocks.extend(causes_block(analysis, set));
    blocks.extend(tail_block(analysis));
    blocks.extend(compensator_block(analysis));
    if !analysis.rss.is_empty() {
        blocks.push(Block::Table {
            caption: Some(format!(
                "Root-sum-square spread from the sensitivity table (linear, independent \
                 tolerances) against the Monte Carlo spread: a large gap means the \
                 tolerances interact or act nonlinearly. The RSS is flagged where a tolerance \
                 whose change reaches {:.0} % of the largest has a one-sided range, moves the \
                 metric the same way at both ends, or has a quadratic term above {:.0} % of its \
                 linear term at the range end (fitted through the nominal bench and both ends, \
                 beyond 2 standard errors): there an agreement with the Monte Carlo σ can be a \
                 coincidence",
                100.0 * crate::tolerance::summaries::RELEVANT_FRACTION,
                100.0 * crate::tolerance::summaries::CURVATURE_LIMIT
            )),
            header: [
                "metric",
                "RSS σ",
                "Monte Carlo σ",
                "dominant tolerance",
                "its share",
                "RSS model",
            ]
            .map(String::from)
            .to_vec(),
            rows: analysis
                .rss
                .iter()
                .map(|r| {
                    vec![
                        r.metric.clone(),
                        format!("{:.3e}", r.rss_std_dev),
                        format!("{:.3e}", r.monte_carlo_std_dev),
                        r.dominant.clone(),
                        format!("{:.0} %", 100.0 * r.dominant_share),
                        if r.linearity_flags.is_empty() {
                            "linear, two-sided".into()
                        } else {
                            format!("FLAGGED: {}", r.linearity_flags.join("; "))
                        },
                    ]
                })
                .collect(),
        });
    }
    blocks
}

/// The tolerances that cause the failing trials (`summaries::failure_causes`).
fn causes_block(analysis: &Analysis, set: &ToleranceSet) -> Option<Block> {
    if analysis.failure_causes.is_empty() {
        return None;
    }
    Some(Block::Table {
        caption: Some(format!(
            "What causes the {} failing trials: in each, the tolerance whose predicted change \
             of the failing metric (its secant slope across the sensitivity table times the \
             trial's deviation, the RSS's linear model; the electrical imbalance for a limit \
             on the imbalance) is the largest. A fixed tolerance is a device specification: it \
             cannot be tightened, so its failures call for a compensator or a wider limit",
            analysis.failing_trials
        )),
        header: ["tolerance", "failing trials it leads"]
            .map(String::from)
            .to_vec(),
        rows: analysis
            .failure_causes
            .iter()
            .map(|c| {
                vec![
                    tolerance_name(set, &c.path),
                    format!("{} of {}", c.failures, analysis.failing_trials),
                ]
            })
            .collect(),
    })
}

/// A metric's unit for the report (the leaks as bounded fractions).
fn unit_of(metric: &str) -> String {
    if crate::tolerance::summaries::is_fraction(metric) {
        return "ratio P_wrong/P_own".into();
    }
    metric
        .parse::<crate::quantities::BenchMetric>()
        .map_or_else(
            |_| {
                if metric.ends_with("_db") {
                    "dB".into()
                } else {
                    String::new()
                }
            },
            |m| m.unit().to_string(),
        )
}

/// The tail that matters of each metric: where the worst 10 % and 2.3 % of built benches lie.
fn tail_block(analysis: &Analysis) -> Option<Block> {
    use crate::tolerance::summaries::Tail;
    if analysis.tails.is_empty() {
        return None;
    }
    Some(Block::Table {
        caption: Some(
            "The tail that matters: for k', k±, powers, CMRR and image scores the low values \
             (10th and 2.3rd percentiles, the lowest trial), for the imbalance, offsets and \
             leaks the large |values| (90th and 97.7th percentiles of |·|, the largest); the \
             leaks as the bounded fraction P_wrong/(P_own + P_wrong), 0 … 1; the fraction of \
             trials beyond the file's limits on the metric"
                .into(),
        ),
        header: [
            "metric",
            "unit",
            "tail",
            "worst 10 % beyond",
            "worst 2.3 % beyond",
            "worst trial",
            "beyond the limits",
        ]
        .map(String::from)
        .to_vec(),
        rows: analysis
            .tails
            .iter()
            .map(|t| {
                vec![
                    t.metric.clone(),
                    if crate::tolerance::summaries::is_fraction(&t.metric) {
                        "fraction, 0–1".into()
                    } else {
                        unit_of(&t.metric)
                    },
                    match t.tail {
                        Tail::Lower => "lower".into(),
                        Tail::UpperAbs => "upper of |·|".into(),
                    },
                    format!("{:.4e}", t.worst_10_percent),
                    format!("{:.4e}", t.worst_2_3_percent),
                    format!("{:.4e}", t.worst),
                    t.beyond_limits
                        .map_or_else(|| "–".into(), |f| format!("{:.1} %", 100.0 * f)),
                ]
            })
            .collect(),
    })
}

/// The compensators' settled moves.
fn compensator_block(analysis: &Analysis) -> Option<Block> {
    if analysis.compensators.is_empty() {
        return None;
    }
    Some(Block::Table {
        caption: Some(format!(
            "Compensator moves over the trials (from the value after the tolerances are \
             applied); at a bound: within {} of the range of min or max, where the compensator \
             ran out of travel; for those trials, the deviation the same adjustment settles at \
             when its range is {}× as wide about its centre (\"or more\": at that wider bound \
             too)",
            crate::tolerance::summaries::AT_BOUND_FRACTION,
            crate::tolerance::WIDER_TRAVEL
        )),
        header: [
            "compensator",
            "range",
            "mean",
            "SD",
            "lowest",
            "highest",
            "at min / at max",
            "at a bound",
            "travel it would need (trial: deviation)",
        ]
        .map(String::from)
        .to_vec(),
        rows: analysis
            .compensators
            .iter()
            .map(|c| {
                vec![
                    c.path.clone(),
                    format!("{} … {}", c.min, c.max),
                    format!("{:+.4e}", c.mean),
                    format!("{:.4e}", c.std_dev),
                    format!("{:+.4e}", c.lowest),
                    format!("{:+.4e}", c.highest),
                    format!("{} / {}", c.at_min, c.at_max),
                    format!("{:.1} % of {}", 100.0 * c.at_bound_fraction, c.trials),
                    if c.short.is_empty() {
                        "–".into()
                    } else {
                        c.short
                            .iter()
                            .map(|t| {
                                format!(
                                    "{}: {}{}",
                                    t.trial,
                                    if t.needed.is_finite() {
                                        format!("{:+.4e}", t.needed)
                                    } else {
                                        "no valid wider adjustment".into()
                                    },
                                    if t.beyond { " or more" } else { "" }
                                )
                            })
                            .collect::<Vec<_>>()
                            .join(", ")
                    },
                ]
            })
            .collect(),
    })
}
