//! The outputs of `spibench tolerance` (docs/outputs.md, "tolerance"), all written from the
//! run's records (`scene::tolerance::ShardFile`), so the same records give the same files and
//! `--merge` of a run's shards writes exactly the unsharded run's: `summary.json` (nominal
//! metrics, sensitivity rows, RSS, percentiles, yields, one row per trial), `sensitivity.csv`,
//! `trials.csv`, `trials.ron` (the records) with `trials.ron.sha256` (which the merge checks,
//! [`read_shard_record`]), histogram and CDF plots ([`plots`]) and `report.html` ([`report`]).
//! `trial_K.ron` is the bench of one trial ([`trial_ron`]).

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::report::csv::write_csv;
use crate::report::html::{Page, write_page};
use crate::report::output::OutputDir;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{
    Compensator, QualityLimit, SensitivityRecord, ShardFile, Tolerance, ToleranceLimit,
    ToleranceSet, shard_to_ron,
};
use crate::tolerance::{Analysis, SENSITIVITY_METRICS, analyse};

use super::rows::Row;

pub mod budget;
mod plots;
mod report;

/// The shard record's checksum file beside `trials.ron` (`sha256sum` format).
pub const CHECKSUM_FILE: &str = "trials.ron.sha256";

/// `trials.ron.sha256`: the SHA-256 of `trials.ron`, as `sha256sum` writes it.
fn checksum_line(trials_ron: &str) -> String {
    format!(
        "{}  trials.ron\n",
        crate::provenance::sha256_hex(trials_ron.as_bytes())
    )
}

/// Reads the shard record of the tolerance output folder `dir` (named on the command line, so
/// trusted; what it holds is not): `trials.ron` and its checksum file, inside the folder (no
/// symbolic link out), the record matching its SHA-256. Returns the record's path and text.
pub fn read_shard_record(dir: &Path) -> crate::Result<(PathBuf, String)> {
    use crate::report::untrusted::{Folder, bad_field, is_sha256_hex};
    let folder = Folder::new(dir)?;
    let sum_path = dir.join(CHECKSUM_FILE);
    let (_, sum) = folder.read(Path::new(CHECKSUM_FILE), &sum_path, CHECKSUM_FILE)?;
    let sum = String::from_utf8_lossy(&sum);
    let want = match sum.trim_end().split_once("  ") {
        Some((h, "trials.ron")) if is_sha256_hex(h) => h.to_string(),
        _ => {
            return Err(bad_field(
                &sum_path,
                "sha256",
                "not a checksum line `SHA256  trials.ron` (a folder made by an older spibench? \
                 run the shard again)",
            ));
        }
    };
    let rec = dir.join("trials.ron");
    let (_, bytes) = folder.read(Path::new("trials.ron"), &rec, "trials.ron")?;
    if crate::provenance::sha256_hex(&bytes) != want {
        return Err(crate::Error::input(format!(
            "the record was edited or is damaged: its SHA-256 differs from the one in \
             {CHECKSUM_FILE}; run the shard again"
        ))
        .in_file(&rec));
    }
    let text = String::from_utf8(bytes)
        .map_err(|_| crate::Error::input("the record is not UTF-8 text").in_file(&rec))?;
    Ok((rec, text))
}

/// Writes every output of a run from its records into `out` (a staging folder) and returns
/// the count of files; the same records give the same files.
pub fn write(
    s: &ShardFile,
    set: &ToleranceSet,
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<(usize, crate::outputs::card::Card)> {
    let analysis = analyse(set, &s.records, s.sensitivity.as_deref());
    let mut files: Vec<String> = [
        "summary.json",
        "trials.ron",
        CHECKSUM_FILE,
        "trials.csv",
        "report.html",
    ]
    .map(String::from)
    .to_vec();
    let path = out.path("trials.ron");
    let record = shard_to_ron(s)?;
    std::fs::write(&path, &record).map_err(|e| crate::Error::write(&path, e))?;
    let path = out.path(CHECKSUM_FILE);
    std::fs::write(&path, checksum_line(&record)).map_err(|e| crate::Error::write(&path, e))?;
    // Every trial's numbers in the metric rows sweep and align write too.
    let values: Vec<Row> = s
        .records
        .iter()
        .map(|r| Row::from_values(&r.values, &s.nominal))
        .collect();
    write_trials_csv(s, set, &values, out)?;
    let mut blocks = vec![report::intro_block(s, set, &analysis)];
    if let Some(sens) = &s.sensitivity {
        files.push("sensitivity.csv".into());
        write_sensitivity_csv(sens, out)?;
        let tornado = plots::tornado_plot(sens, set, out, &mut files)?;
        blocks.extend(report::sensitivity_blocks(sens, set, tornado));
    }
    if !s.records.is_empty() {
        blocks.extend(report::monte_carlo_blocks(&analysis, set));
        blocks.extend(plots::distribution_plots(
            s, set, &analysis, out, &mut files,
        )?);
    }
    let summary = ToleranceSummary {
        command: "tolerance",
        spibench_version: env!("CARGO_PKG_VERSION"),
        scene: &s.scene,
        tolerances_file: &s.tolerances_path,
        rays: s.rays,
        seed: s.seed,
        trials: s.trials,
        shard: [s.shard.0, s.shard.1],
        quality: s.quality,
        tolerances: &set.tolerances,
        compensators: &set.compensators,
        attenuator: &set.attenuator,
        limits: &set.limits,
        quality_limit: &set.quality,
        nominal: Row::from_values(&s.nominal, &s.nominal),
        sensitivity: s
            .sensitivity
            .iter()
            .flatten()
            .map(|r| SensitivitySummary {
                path: &r.path,
                min: r.min,
                max: r.max,
                rays: r.rays,
                at_min: Row(r.at_min.clone()),
                at_max: Row(r.at_max.clone()),
            })
            .collect(),
        analysis: &analysis,
        trial_rows: s
            .records
            .iter()
            .zip(values)
            .map(|(r, values)| TrialSummary {
                index: r.index,
                deviations: Row(r.deviations.clone()),
                compensators: Row(r.compensators.clone()),
                values,
                error: r.error.as_deref(),
                needed_travel: &r.needed_travel,
            })
            .collect(),
        files: &files,
    };
    let json = serde_json::to_value(&summary)
        .map_err(|e| crate::Error::Numerical(format!("the tolerance summary as JSON: {e}")))?;
    let card = card(&json);
    blocks.insert(0, card.block());
    let blocks = crate::report::html::fold_long_paragraphs(blocks, 320);
    write_page(
        &out.path("report.html"),
        &Page {
            title: format!("spibench tolerance of {}", s.scene),
            blocks,
        },
    )?;
    super::summary::write_summary(out, &summary, provenance)?;
    Ok((files.len(), card))
}

/// The summary card of `tolerance` (from its summary.json as a value): each yield with its
/// 95 % Wilson interval (a limit on the imbalance judged on the electrical imbalance, the
/// optical one beside it), the five tolerances that cause most failing trials (or, where none
/// fails or there is no sensitivity table, that move the imbalance most), the device
/// specifications that cannot be tightened, and how often each compensator ran out of travel
/// with the travel it would need.
pub fn card(summary: &serde_json::Value) -> crate::outputs::card::Card {
    use crate::outputs::card::{Card, array_len};
    let mut c = Card::new("summary");
    for i in 0..array_len(summary, "/analysis/yields") {
        let y = format!("/analysis/yields/{i}");
        let mut keys: Vec<String> = ["limit", "passed", "trials", "fraction", "ci95"]
            .map(|k| format!("{y}/{k}"))
            .to_vec();
        keys.extend(["passed", "fraction"].map(|k| format!("{y}/optical/{k}")));
        c.line(summary, "yield", &keys, yield_text);
    }
    card_causes(&mut c, summary);
    let fixed: Vec<String> = (0..array_len(summary, "/tolerances"))
        .filter(|i| summary.pointer(&format!("/tolerances/{i}/fixed")) == Some(&true.into()))
        .map(|i| format!("/tolerances/{i}/path"))
        .collect();
    if !fixed.is_empty() {
        c.line(summary, "cannot be tightened", &fixed, |v| {
            format!(
                "{} (device specifications, `fixed` in the tolerance file)",
                names(v).join(", ")
            )
        });
    }
    for i in 0..array_len(summary, "/analysis/compensators") {
        let m = format!("/analysis/compensators/{i}");
        let keys = ["path", "at_min", "at_max", "trials", "min", "max", "short"]
            .map(|k| format!("{m}/{k}"));
        c.line(summary, "compensator", &keys, compensator_text);
    }
    let keys = [
        "trials",
        "in_plus",
        "in_minus",
        "at_min",
        "min_transmission",
        "transmission_mean",
        "transmission_min",
        "k_prime_mean_before",
        "k_prime_mean_after",
    ]
    .map(|k| format!("/analysis/attenuator/{k}"));
    if summary.pointer("/analysis/attenuator/trials").is_some() {
        c.line(summary, "attenuator", &keys, attenuator_text);
    }
    c
}

/// "set in 38 of 40 trials (+ 30, − 8), mean T 0.80, least 0.50, at its darkest (0.5) in 2
/// ⚠; k′ 0.253 → 0.231 (−8.7 %)".
fn attenuator_text(v: &[serde_json::Value]) -> String {
    use crate::outputs::card::num;
    let (p, m) = (v[1].as_u64().unwrap_or(0), v[2].as_u64().unwrap_or(0));
    let at = v[3].as_u64().unwrap_or(0);
    let (k0, k1) = (num(&v[7]), num(&v[8]));
    format!(
        "set in {} of {} trials (+ {p}, − {m}), mean T {:.3}, least {:.3}, at its darkest ({}) \
         in {at}{}; k′ {k0:.4} → {k1:.4} ({:+.1} %)",
        p + m,
        v[0],
        num(&v[5]),
        num(&v[6]),
        v[4],
        if at > 0 { " ⚠" } else { "" },
        100.0 * (k1 / k0 - 1.0)
    )
}

/// The string values of `v`, in order.
fn names(v: &[serde_json::Value]) -> Vec<&str> {
    v.iter().filter_map(|p| p.as_str()).collect()
}

/// "|imbalance| ≤ 0.01, electrical: 12 of 20 trials (0.60, 95 % interval 0.39 … 0.78);
/// optical: 15 of 20 (0.75)".
fn yield_text(v: &[serde_json::Value]) -> String {
    use crate::outputs::card::num;
    let ci = v[4]
        .as_array()
        .filter(|a| a.len() == 2)
        .map_or_else(String::new, |a| {
            format!(", 95 % interval {:.2} … {:.2}", num(&a[0]), num(&a[1]))
        });
    let head = format!(
        "{}{}: {} of {} trials ({:.2}{ci})",
        v[0].as_str().unwrap_or(""),
        if v[5].is_null() { "" } else { ", electrical" },
        v[1],
        v[2],
        num(&v[3])
    );
    if v[5].is_null() {
        head
    } else {
        format!("{head}; optical: {} of {} ({:.2})", v[5], v[2], num(&v[6]))
    }
}

/// The card's line of the tolerances that cause most failures (the five first), or that move
/// the imbalance most where nothing failed or there is no sensitivity table.
fn card_causes(c: &mut crate::outputs::card::Card, summary: &serde_json::Value) {
    use crate::outputs::card::array_len;
    let causes = array_len(summary, "/analysis/failure_causes").min(5);
    if causes > 0 {
        let mut keys = vec!["/analysis/failing_trials".to_string()];
        for i in 0..causes {
            let f = format!("/analysis/failure_causes/{i}");
            keys.extend(["path", "failures", "fixed"].map(|k| format!("{f}/{k}")));
        }
        c.line(summary, "most failures from", &keys, |v| {
            let list: Vec<String> = v[1..]
                .chunks(3)
                .map(|t| {
                    format!(
                        "{} {}{}",
                        t[0].as_str().unwrap_or(""),
                        t[1],
                        if t[2] == true {
                            " (fixed: cannot be tightened)"
                        } else {
                            ""
                        }
                    )
                })
                .collect();
            format!("{} (of {} failing trials)", list.join(", "), v[0])
        });
        return;
    }
    let top = array_len(summary, "/sensitivity").min(5);
    if top > 0 {
        let keys: Vec<String> = (0..top).map(|i| format!("/sensitivity/{i}/path")).collect();
        c.line(summary, "most imbalance from", &keys, |v| {
            names(v).join(", ")
        });
    }
}

/// "d.x: at its travel limit (−1.5 … 1.5) in 5 of 8 trials ⚠; would need −2.1 … +2.4 (trials
/// 0, 2, 3, 5, 7)".
fn compensator_text(v: &[serde_json::Value]) -> String {
    use crate::outputs::card::num;
    let at = v[1].as_u64().unwrap_or(0) + v[2].as_u64().unwrap_or(0);
    let mut text = format!(
        "{}: at its travel limit ({} … {}) in {at} of {} trials{}",
        v[0].as_str().unwrap_or(""),
        v[4],
        v[5],
        v[3],
        if at > 0 { " ⚠" } else { "" }
    );
    let short = v[6].as_array().map_or(&[][..], Vec::as_slice);
    if !short.is_empty() {
        let needs: Vec<String> = short
            .iter()
            .map(|s| {
                let n = num(&s["needed"]);
                format!(
                    "trial {}: {}{}",
                    s["trial"],
                    if n.is_finite() {
                        format!("{n:+.3}")
                    } else {
                        "no valid wider adjustment".into()
                    },
                    if s["beyond"] == true { " or more" } else { "" }
                )
            })
            .collect();
        text += &format!("; the travel it would need: {}", needs.join(", "));
    }
    text
}

/// `trials.csv`: index, deviations, compensators, each trial's metric row, error.
fn write_trials_csv(
    s: &ShardFile,
    set: &ToleranceSet,
    values: &[Row],
    out: &OutputDir,
) -> crate::Result<()> {
    let mut header: Vec<String> = vec!["index".into()];
    header.extend(set.tolerances.iter().map(|t| t.path.clone()));
    header.extend(
        set.compensators
            .iter()
            .map(|c| format!("compensator:{}", c.path)),
    );
    let value_names: Vec<String> = s
        .records
        .iter()
        .zip(values)
        .find(|(r, _)| r.error.is_none())
        .map_or_else(Vec::new, |(_, v)| v.keys().map(String::from).collect());
    header.extend(value_names.iter().cloned());
    header.push("error".into());
    let rows: Vec<Vec<String>> = s
        .records
        .iter()
        .zip(values)
        .map(|(r, v)| {
            let mut row = vec![r.index.to_string()];
            row.extend(r.deviations.iter().map(|(_, v)| format!("{v:e}")));
            for c in &set.compensators {
                row.push(
                    r.compensators
                        .iter()
                        .find(|(p, _)| *p == c.path)
                        .map_or_else(String::new, |(_, v)| format!("{v:e}")),
                );
            }
            for n in &value_names {
                row.push(v.get(n).map_or_else(String::new, |v| format!("{v:e}")));
            }
            row.push(r.error.clone().unwrap_or_default());
            row
        })
        .collect();
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    write_csv(&out.path("trials.csv"), &h, &rows)?;
    Ok(())
}

/// `sensitivity.csv`: each tolerance alone at its min and max, the change of every
/// sensitivity metric with its paired standard error.
fn write_sensitivity_csv(sens: &[SensitivityRecord], out: &OutputDir) -> crate::Result<()> {
    let mut header = vec![
        "path".to_string(),
        "min".into(),
        "max".into(),
        "rays_at_min".into(),
        "rays_at_max".into(),
    ];
    for end in ["min", "max"] {
        for m in SENSITIVITY_METRICS {
            header.push(format!("{m}_diff_at_{end}"));
            header.push(format!("{m}_diff_stderr_at_{end}"));
        }
    }
    let rows: Vec<Vec<String>> = sens
        .iter()
        .map(|r| {
            let mut row = vec![
                r.path.clone(),
                format!("{}", r.min),
                format!("{}", r.max),
                format!("{}", r.rays[0]),
                format!("{}", r.rays[1]),
            ];
            for high in [false, true] {
                for m in SENSITIVITY_METRICS {
                    row.push(format!("{:e}", r.at(high, &format!("{m}_diff"))));
                    row.push(format!("{:e}", r.at(high, &format!("{m}_diff_stderr"))));
                }
            }
            row
        })
        .collect();
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    write_csv(&out.path("sensitivity.csv"), &h, &rows)?;
    Ok(())
}

/// `summary.json` of `tolerance`.
#[derive(Serialize)]
struct ToleranceSummary<'a> {
    command: &'static str,
    spibench_version: &'static str,
    scene: &'a str,
    tolerances_file: &'a str,
    rays: u64,
    seed: u64,
    trials: u64,
    /// [I, N] of `--shard I/N` ([0, 1] unsharded).
    shard: [u64; 2],
    quality: bool,
    tolerances: &'a [Tolerance],
    compensators: &'a [Compensator],
    /// The variable attenuator among the compensators (null without one).
    attenuator: &'a Option<crate::scene::tolerance::Attenuator>,
    limits: &'a [ToleranceLimit],
    quality_limit: &'a Option<QualityLimit>,
    /// The nominal bench's metric row (differences against itself).
    nominal: Row,
    sensitivity: Vec<SensitivitySummary<'a>>,
    /// NaN written as null.
    analysis: &'a Analysis,
    trial_rows: Vec<TrialSummary<'a>>,
    files: &'a [String],
}

#[derive(Serialize)]
struct SensitivitySummary<'a> {
    path: &'a str,
    min: f64,
    max: f64,
    rays: [u64; 2],
    at_min: Row,
    at_max: Row,
}

#[derive(Serialize)]
struct TrialSummary<'a> {
    index: u64,
    deviations: Row,
    compensators: Row,
    values: Row,
    error: Option<&'a str>,
    /// The compensators at a limit of their travel, with the travel they would need.
    needed_travel: &'a [crate::scene::tolerance::NeededTravel],
}

/// `trial_K.ron` of `--trial K`: the bench of trial `k` (perturbed and compensated) as RON,
/// headed by comments saying which run it comes from (`run`: the command words that made it)
/// and each deviation and compensator move.
pub fn trial_ron(
    k: u64,
    run: &str,
    bench: &BenchDoc,
    moves: &[(String, f64)],
) -> crate::Result<String> {
    let mut text = format!("// Trial {k} of `{run}`.\n");
    for (p, v) in moves {
        text += &format!("//   {p}: {v:+.6e}\n");
    }
    text += &bench.to_ron()?;
    Ok(text)
}
