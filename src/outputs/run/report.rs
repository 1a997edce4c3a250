//! `report.html` of `spibench run`: one self-contained page (crate::report::html) that a reader
//! can open with no network: what was traced, where the light went, what the detector saw, what
//! each scheme reconstructed, and the settings that reproduce it.
//!
//! The page is assembled from the run's outcome and from the plots and montage already written
//! into the staging folder (read back and embedded), so the page shows exactly the files beside
//! it.

use crate::detector::bap::Bap;
use crate::error::{Error, Result};
use crate::report::heatmap::{UnitMap, unit_map_svg};
use crate::report::html::{Block, Page, concise_unit, eng, render};
use crate::report::output::OutputDir;
use crate::run::RunOutcome;

use super::summary::RunSummary;
use super::{RunPage, element_text};
use crate::run::findings::{Findings, Score, pct};
use crate::run::repeats::Repeats;

/// Reads a file already written into the staging folder.
fn staged(out: &OutputDir, name: &str) -> Result<Vec<u8>> {
    let p = out.path(name);
    std::fs::read(&p).map_err(|e| Error::read(&p, e))
}

/// An SVG written into the staging folder, as a block (skipped when absent).
fn staged_svg(out: &OutputDir, name: &str, caption: &str) -> Result<Option<Block>> {
    if !out.path(name).exists() {
        return Ok(None);
    }
    let bytes = staged(out, name)?;
    Ok(Some(Block::Svg {
        caption: caption.to_string(),
        svg: String::from_utf8_lossy(&bytes).into_owned(),
    }))
}

fn sci(v: f64, se: f64, unit: &str) -> String {
    concise_unit(v, se, unit)
}

/// The sums over the pattern units that double-arm's offset is made of, per diode d (0 = +).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmSums {
    /// Σ_j T[d][s][j] (A): diode d's light from units in state s.
    pub t_a: [[f64; 2]; 2],
    /// Traced light that never met the pattern units (A): mirrors outside the pattern, the
    /// window, ghosts.
    pub outside_a: [f64; 2],
    pub ambient_a: [f64; 2],
    pub dark_a: [f64; 2],
}

impl ArmSums {
    pub fn of(t: &crate::transport::Transport) -> ArmSums {
        let units = t.units_across * t.units_down;
        let sum = |d: usize, s: usize| t.t_a[(d * 2 + s) * units..][..units].iter().sum::<f64>();
        ArmSums {
            t_a: [[sum(0, 0), sum(0, 1)], [sum(1, 0), sum(1, 1)]],
            outside_a: [t.c_traced[0].value, t.c_traced[1].value],
            ambient_a: t.ambient_a,
            dark_a: t.dark_a,
        }
    }
}

/// Double-arm's offset (V) split into its causes, and the offset computed directly.
///
/// Double-arm reads y = V₊(P) − V₋(P) from the two monitors, with
/// V± = G±·(s±·(light± + ambient±) + dark±) + offset± (`detector::bap`). With g±_j = T[±][±]_j − T[±][∓]_j, diode + sees
/// ΣT[+][−] + g₊·P + c₊ and diode − sees ΣT[−][+] + g₋·(1 − P) + c₋. Its offset is y at the
/// pattern that splits the light in half (g·P = Σg/2, i.e. Âx = 0, where a balanced scheme reads
/// 0), which is exactly the sum of:
/// - arm imbalance: ḡ·(Σg₊ − Σg₋)/2, with ḡ = (G₊s₊ + G₋s₋)/2 (k₊ ≠ k₋ from the optics);
/// - responsivity and monitor-gain mismatch: (G₊s₊ − G₋s₋)·(Σg₊ + Σg₋)/4;
/// - off-arm leak: G₊s₊·ΣT[+][−] − G₋s₋·ΣT[−][+] (light of one arm reaching the other diode);
/// - light outside the pattern: G₊s₊·c₊ − G₋s₋·c₋;
/// - ambient light: G₊s₊·a₊ − G₋s₋·a₋; dark current: G₊·d₊ − G₋·d₋;
/// - amplifier offsets: offset₊ − offset₋.
pub fn double_arm_offset(a: &ArmSums, bap: &Bap) -> (Vec<(&'static str, f64)>, f64) {
    let gs = [0, 1].map(|d| bap.monitors[d].gain_v_per_a * bap.responsivity_scale[d]);
    let g = [a.t_a[0][0] - a.t_a[0][1], a.t_a[1][1] - a.t_a[1][0]];
    let mean_gs = 0.5 * (gs[0] + gs[1]);
    let diff = |v: [f64; 2]| gs[0] * v[0] - gs[1] * v[1];
    let parts = vec![
        ("arm imbalance, k₊ ≠ k₋", mean_gs * (g[0] - g[1]) / 2.0),
        (
            "responsivity and monitor-gain mismatch",
            (gs[0] - gs[1]) * (g[0] + g[1]) / 4.0,
        ),
        ("off-arm leak", diff([a.t_a[0][1], a.t_a[1][0]])),
        ("light from outside the pattern", diff(a.outside_a)),
        ("ambient light", diff(a.ambient_a)),
        (
            "dark current",
            bap.monitors[0].gain_v_per_a * a.dark_a[0] - bap.monitors[1].gain_v_per_a * a.dark_a[1],
        ),
        (
            "amplifier offsets",
            bap.monitors[0].offset_v - bap.monitors[1].offset_v,
        ),
    ];
    // The direct value: both monitors at the half-light pattern.
    let light = [
        a.t_a[0][1] + g[0] / 2.0 + a.outside_a[0],
        a.t_a[1][0] + g[1] / 2.0 + a.outside_a[1],
    ];
    let i = bap.diode_currents(light, a.ambient_a, a.dark_a);
    let direct = bap.monitors[0].ideal_v(i[0]) - bap.monitors[1].ideal_v(i[1]);
    (parts, direct)
}

/// The page's "why double-arm fails" section: the offset's parts in volts and as a share of
/// the offset, beside the signal it sits on.
fn double_arm_blocks(t: &crate::transport::Transport, bap: &Bap) -> Vec<Block> {
    let sums = ArmSums::of(t);
    let (parts, total) = double_arm_offset(&sums, bap);
    let gs = [0, 1].map(|d| bap.monitors[d].gain_v_per_a * bap.responsivity_scale[d]);
    let g = [
        sums.t_a[0][0] - sums.t_a[0][1],
        sums.t_a[1][1] - sums.t_a[1][0],
    ];
    // The largest signal double-arm sees: (k'/2)·Σx through the mean monitor gain.
    let signal = 0.5 * (gs[0] + gs[1]) * (g[0] + g[1]) / 2.0;
    let leak = if sums.t_a[0][0] > 0.0 {
        sums.t_a[1][0] / sums.t_a[0][0]
    } else {
        f64::NAN
    };
    let all_plus = &t.ledger.worlds[0].detected_w;
    let ledger_ratio = if all_plus[0] > 0.0 {
        all_plus[1] / all_plus[0]
    } else {
        f64::NAN
    };
    let mut rows: Vec<Vec<String>> = parts
        .iter()
        .map(|(name, v)| {
            vec![
                name.to_string(),
                eng(*v, "V"),
                format!("{:.1} %", 100.0 * v / total).replace('-', "−"),
            ]
        })
        .collect();
    let sum: f64 = parts.iter().map(|(_, v)| v).sum();
    rows.push(vec![
        "sum of the parts".into(),
        eng(sum, "V"),
        format!("{:.1} %", 100.0 * sum / total),
    ]);
    rows.push(vec![
        "offset, both monitors computed directly".into(),
        eng(total, "V"),
        "100 %".into(),
    ]);
    vec![
        Block::Heading {
            level: 2,
            text: "Why double-arm fails".into(),
        },
        Block::Paragraph(format!(
            "Double-arm subtracts the two monitor outputs of one frame, V₊(P) − V₋(P). Unlike \
             the complementary schemes it never cancels what does not depend on the pattern, so \
             its measurements carry an offset: the value read when the pattern splits the light \
             in half, where a balanced scheme reads 0. On this bench the offset is {} against a \
             largest signal of {} ({:.0} % of it), and TV reconstruction cannot tell a constant \
             offset from a bright object. With every pattern unit in state +, the − diode \
             receives {:.1} % of the + diode's power (flux ledger), but the pattern units in state + \
             send it only {:.2} % of the + diode's current (the off-arm leak proper): the rest \
             comes from the mirrors outside the pattern, which stay in state − and feed arm − \
             whatever the pattern. \
             The parts below are computed from the traced transport and the electronics and add \
             up to the offset.",
            eng(total, "V"),
            eng(signal, "V"),
            100.0 * (total / signal).abs(),
            100.0 * ledger_ratio,
            100.0 * leak
        )),
        Block::Table {
            caption: Some("Double-arm's offset by cause (monitor volts)".into()),
            header: vec!["cause".into(), "offset".into(), "share".into()],
            rows,
        },
    ]
}

/// What the sections of `report.html` are drawn from.
struct ReportInput<'a> {
    name: &'a str,
    bench: &'a crate::optics::Bench,
    o: &'a RunOutcome,
    summary: &'a RunSummary<'a>,
    settings_ron: &'a str,
    findings: &'a Findings,
    repeats: Option<&'a Repeats>,
    out: &'a OutputDir,
}

/// Writes `report.html` into the staging folder.
pub fn write_report(
    page: &RunPage<'_>,
    o: &RunOutcome,
    summary: &RunSummary<'_>,
    card: &crate::outputs::card::Card,
    out: &OutputDir,
) -> Result<()> {
    let r = ReportInput {
        name: page.name,
        bench: page.bench,
        o,
        summary,
        settings_ron: page.settings_ron,
        findings: page.findings,
        repeats: page.repeats,
        out,
    };
    let name = r.name;
    let mut blocks = vec![card.block()];
    blocks.extend(intro_blocks(&r));
    findings_section(&mut blocks, &r);
    bench_section(&mut blocks, &r)?;
    ledger_section(&mut blocks, &r);
    signals_section(&mut blocks, &r)?;
    reconstructions_section(&mut blocks, &r)?;
    curves_section(&mut blocks, &r)?;
    settings_section(&mut blocks, &r);
    let s = &o.settings;
    // The run's title defaults to "spibench run"; the page never says it twice.
    let title = if s.title.trim().is_empty() || s.title.trim() == "spibench run" {
        format!("spibench run: {name}")
    } else if s.title.starts_with("spibench") {
        s.title.clone()
    } else {
        format!("spibench run: {}", s.title)
    };
    // The card says what matters; long explanations wait, folded, for the reader who wants them.
    let blocks = crate::report::html::fold_long_paragraphs(blocks, LONG_PARAGRAPH_CHARS);
    let page = Page { title, blocks };
    let path = out.path("report.html");
    std::fs::write(&path, render(&page)).map_err(|e| Error::write(&path, e))
}

/// Paragraphs longer than this (characters) are folded into collapsible sections.
pub const LONG_PARAGRAPH_CHARS: usize = 320;

/// The opening paragraph and any saturation warnings.
fn intro_blocks(r: &ReportInput<'_>) -> Vec<Block> {
    let (name, o) = (r.name, r.o);
    let (t, s) = (&o.transport, &o.settings);
    let (w, h) = (t.units_across, t.units_down);
    let mut blocks = Vec::new();
    blocks.push(Block::Paragraph(format!(
        "Scene {name}: {w}×{h} pattern units, {} lamp rays traced (seed {}), {} scheme(s) at {} \
         sampling ratio(s). Every number below is in summary.json beside this page; the traced \
         ones carry their Monte Carlo standard error.",
        t.rays,
        o.seed,
        s.schemes.len(),
        s.sampling_ratios.len()
    )));
    if !o.saturation.is_empty() {
        blocks.push(Block::Heading {
            level: 2,
            text: "Saturation".into(),
        });
        for sat in &o.saturation {
            blocks.push(Block::Paragraph(format!("SATURATION: {}", sat.message)));
        }
    }
    blocks
}

/// The findings, first: which scheme scores best at each ratio and at equal frames, its margin
/// over every other scheme (the fair baselines included) and, with repeats, the paired 95 %
/// intervals that decide whether a lead is a lead (crate::run::findings).
fn findings_section(blocks: &mut Vec<Block>, r: &ReportInput<'_>) {
    let f = r.findings;
    blocks.push(Block::Heading {
        level: 2,
        text: "Findings".into(),
    });
    blocks.push(Block::Paragraph(f.basis()));
    for (score, ratios, frames) in &f.by_score {
        if *score == Score::Mssim {
            for list in [ratios, frames] {
                let text: Vec<String> = list.iter().map(|st| st.sentence(*score)).collect();
                if !text.is_empty() {
                    blocks.push(Block::Paragraph(text.join(" ")));
                }
            }
        }
        for (what, list) in [
            ("at each sampling ratio", ratios),
            ("at equal DMD frames", frames),
        ] {
            if list.is_empty() {
                continue;
            }
            let (header, rows) = f.table(*score, list);
            blocks.push(Block::Table {
                caption: Some(format!(
                    "{} {what}: the best scheme ({}) and its margin over every other, best − \
                     scheme{}{}",
                    score.label(),
                    if f.repeats > 1 {
                        format!("mean ± SD of {} repeats", f.repeats)
                    } else {
                        "one run".into()
                    },
                    if f.repeats > 1 {
                        " [paired Student-t 95 % interval]"
                    } else {
                        " (no interval: one run)"
                    },
                    if what.contains("frames") {
                        "; each scheme's score interpolated in log(frames) between its ratios, \
                         at the frames SCB shows (calibration included); schemes whose frames \
                         do not reach a budget are left out (–)"
                    } else {
                        ""
                    }
                )),
                header,
                rows,
            });
        }
    }
}

/// The bench: the layout, the traced gains and offsets, the per-unit maps and the
/// double-arm offsets.
fn bench_section(blocks: &mut Vec<Block>, r: &ReportInput<'_>) -> Result<()> {
    let (name, bench, o, out) = (r.name, r.bench, r.o, r.out);
    let t = &o.transport;
    let (w, h) = (t.units_across, t.units_down);
    blocks.push(Block::Heading {
        level: 2,
        text: "Bench: gains and offsets from the trace".into(),
    });
    let (layout, svg) = crate::outputs::layout::layout_block(bench, name)?;
    let path = out.path("layout.svg");
    std::fs::write(&path, &svg).map_err(|e| crate::Error::write(&path, e))?;
    blocks.push(layout);
    let cmrr = o.cmrr();
    let electronics_only = o.detector.cmrr_db();
    let db = |v: f64| {
        if v.is_finite() {
            format!("{v:.1} dB")
        } else {
            "infinite (matched)".into()
        }
    };
    blocks.push(Block::KeyValues(vec![
        ("k₊ (arm +)".into(), sci(t.k[0].value, t.k[0].stderr, "A/W")),
        ("k₋ (arm −)".into(), sci(t.k[1].value, t.k[1].stderr, "A/W")),
        ("b₊".into(), sci(t.b[0].value, t.b[0].stderr, "A")),
        ("b₋".into(), sci(t.b[1].value, t.b[1].stderr, "A")),
        (
            "k' = k₊ + k₋".into(),
            sci(t.k_prime.value, t.k_prime.stderr, "A/W"),
        ),
        (
            "imbalance (k₊ − k₋)/(k₊ + k₋)".into(),
            sci(t.imbalance.value, t.imbalance.stderr, ""),
        ),
        (
            "power on the pattern, Σx".into(),
            sci(t.x_total.value, t.x_total.stderr, "W"),
        ),
        (
            "RF transimpedance, swing".into(),
            format!(
                "{:.3e} V/A, ±{} V",
                o.detector.rf.gain_v_per_a, o.detector.rf.swing_v
            ),
        ),
        (
            "CMRR of the bench (arms' k± and diodes)".into(),
            if cmrr.value.is_finite() {
                format!("{:.1} ± {:.1} dB", cmrr.value, cmrr.stderr())
            } else {
                db(cmrr.value)
            },
        ),
        (
            "CMRR of the electronics alone (diodes' mismatch)".into(),
            db(electronics_only),
        ),
    ]));
    let mut maps = Vec::new();
    for (label, unit, values, caption) in [
        ("x_j", "W", &t.x_w, "power on each pattern unit, x_j"),
        ("k₊_j", "A/W", &t.k_map[0], "k₊_j = g₊_j / x_j"),
        ("k₋_j", "A/W", &t.k_map[1], "k₋_j = g₋_j / x_j"),
    ] {
        let svg = unit_map_svg(&UnitMap {
            label: label.into(),
            unit: unit.into(),
            width: w,
            height: h,
            values: values.clone(),
            light_w: t.x_w.clone(),
            from_zero: true,
        })?;
        maps.push(Block::Svg {
            caption: caption.into(),
            svg,
        });
    }
    blocks.push(Block::Figures(maps));
    blocks.extend(double_arm_blocks(t, &o.detector));
    Ok(())
}

/// The flux ledger: where the emitted light went in each world.
fn ledger_section(blocks: &mut Vec<Block>, r: &ReportInput<'_>) {
    let t = &r.o.transport;
    blocks.push(Block::Heading {
        level: 2,
        text: "Flux ledger".into(),
    });
    let l = &t.ledger;
    blocks.push(Block::Paragraph(format!(
        "Emitted in the traced band: {} (nominal {}; {} outside the traced cone, booked to the \
         lamp housing). Each column is one world: every pattern unit in state + or every unit \
         in state −.",
        eng(l.emitted_w, "W"),
        eng(l.emitted_nominal_w, "W"),
        eng(l.outside_cone_w, "W")
    )));
    let mut rows: Vec<Vec<String>> = l.worlds[0]
        .absorbed_w
        .iter()
        .zip(&l.worlds[1].absorbed_w)
        .map(|((n, a), (_, b))| vec![format!("absorbed: {n}"), eng(*a, "W"), eng(*b, "W")])
        .collect();
    for (label, f) in [
        (
            "escaped",
            (|w: &crate::transport::LedgerWorld| w.escaped_w) as fn(&_) -> f64,
        ),
        ("path cap", |w| w.path_cap_w),
        ("detected, diode +", |w| w.detected_w[0]),
        ("detected, diode −", |w| w.detected_w[1]),
        ("added by sampled reflections", |w| w.sampled_w),
        ("residual", |w| w.residual_w),
    ] {
        rows.push(vec![
            label.to_string(),
            eng(f(&l.worlds[0]), "W"),
            eng(f(&l.worlds[1]), "W"),
        ]);
    }
    blocks.push(Block::Table {
        caption: Some("Where the light went".into()),
        header: vec!["".into(), "all units +".into(), "all units −".into()],
        rows,
    });
}

/// The oscilloscope panels of each recorded sequence.
fn signals_section(blocks: &mut Vec<Block>, r: &ReportInput<'_>) -> Result<()> {
    let (o, out) = (r.o, r.out);
    blocks.push(Block::Heading {
        level: 2,
        text: "Signals as the oscilloscope sampled them".into(),
    });
    for (q, _) in &o.traces {
        let file = format!("signals_{}.svg", q.key());
        if let Some(b) = staged_svg(
            out,
            &file,
            &format!(
                "{} sequence, first frames: one panel per output; shaded, the settled window of \
             each frame that is averaged; grey lines, frame boundaries",
                q.key()
            ),
        )? {
            blocks.push(b);
        }
    }
    Ok(())
}

/// The reconstructions (the paper's Fig. 6), every scheme at every ratio and the
/// resolution read-out.
fn reconstructions_section(blocks: &mut Vec<Block>, r: &ReportInput<'_>) -> Result<()> {
    let (o, out) = (r.o, r.out);
    blocks.push(Block::Heading {
        level: 2,
        text: "Reconstructions (the paper's Fig. 6)".into(),
    });
    blocks.push(Block::Image {
        caption: "Reconstructions against sampling ratio, PSNR / MSSIM under each tile".into(),
        png: staged(out, "montage.png")?,
        alt: "montage of reconstructions".into(),
        width_px: None,
    });
    blocks.push(Block::Paragraph(format!(
        "Scores: {}",
        crate::metrics::NORMALIZATION_RULE
    )));
    let header = [
        "scheme",
        "ratio",
        "M",
        "DMD frames",
        "acquisition (ms)",
        "PSNR (dB)",
        "MSSIM",
        "finest resolved",
        "iterations (stop)",
        "saturated",
    ];
    let stat = |res: &crate::pipeline::SchemeResult| {
        r.repeats.and_then(|rp| {
            rp.stats
                .iter()
                .find(|x| x.scheme == res.scheme && x.ratio == res.ratio)
        })
    };
    let rows = o
        .results
        .iter()
        .map(|r| {
            let (psnr, mssim) = match stat(r) {
                Some(x) => (
                    format!("{:.2} ± {:.2}", x.psnr_db_mean, x.psnr_db_sd),
                    format!("{:.4} ± {:.4}", x.mssim_mean, x.mssim_sd),
                ),
                None => (format!("{:.2}", r.psnr_db), format!("{:.4}", r.mssim)),
            };
            vec![
                r.scheme.label().to_string(),
                pct(r.ratio),
                r.measurements.to_string(),
                r.dmd_frames.to_string(),
                format!("{:.2}", r.acquisition_time_s * 1e3),
                psnr,
                mssim,
                element_text(r.finest_resolved),
                iterations_cell(r),
                if r.saturated { "yes" } else { "no" }.to_string(),
            ]
        })
        .collect();
    let (header, caption) = match r.repeats {
        Some(rp) => (
            header.map(|h| match h {
                "PSNR (dB)" => "PSNR (dB), mean ± SD",
                "MSSIM" => "MSSIM, mean ± SD",
                other => other,
            }),
            format!(
                "Every scheme at every ratio. PSNR and MSSIM: mean ± sample SD over {} repeats \
                 (repeats.csv); the other columns, the images above and results.csv are \
                 repeat 1's, the plain run (seed {})",
                rp.repeats, o.seed
            ),
        ),
        None => (
            header,
            format!(
                "Every scheme at every ratio: one run (seed {}), so the scores carry no spread \
                 (--repeats N gives mean ± SD)",
                o.seed
            ),
        ),
    };
    blocks.push(Block::Table {
        caption: Some(caption),
        header: header.iter().map(|h| h.to_string()).collect(),
        rows,
    });
    blocks.push(Block::Paragraph(stop_note(o)));
    if let Some(c) = &o.resolution {
        blocks.push(Block::Paragraph(format!(
            "Resolution read-out: {}. Threshold {:.2}. The chart was registered against x \
             (correlation {:.3}); x itself resolves {} (group/element).",
            c.criterion.trim().trim_end_matches('.'),
            c.threshold,
            c.registration_correlation,
            element_text(c.ideal_finest_resolved)
        )));
    }
    Ok(())
}

/// A solve's iteration count and the test that stopped it (TVAL3's stop reason, not a
/// converged flag: the reference runs end on `maxcnt` inner loops, which is neither the
/// iteration cap nor convergence).
fn iterations_cell(r: &crate::pipeline::SchemeResult) -> String {
    format!("{} ({})", r.iterations, r.stop.short())
}

/// What each stop reason of the table means, with the solver's settings, and how many solves
/// ended on each.
fn stop_note(o: &RunOutcome) -> String {
    use crate::reconstruction::StopReason;
    let solver = &o.settings.solver;
    let mut parts = Vec::new();
    for reason in [
        StopReason::Tolerance,
        StopReason::MaxOuter,
        StopReason::MaxIterations,
    ] {
        let n = o.results.iter().filter(|r| r.stop == reason).count();
        if n > 0 {
            parts.push(format!(
                "{n} of {} solves stopped on \"{}\": {}",
                o.results.len(),
                reason.short(),
                reason.describe(solver)
            ));
        }
    }
    format!("TVAL3's stops: {}.", parts.join("; "))
}

/// Quality against sampling ratio (the paper's Fig. 7) and what it shows.
fn curves_section(blocks: &mut Vec<Block>, r: &ReportInput<'_>) -> Result<()> {
    let out = r.out;
    let summary = r.summary;
    blocks.push(Block::Heading {
        level: 2,
        text: "Quality against sampling ratio (the paper's Fig. 7)".into(),
    });
    let mut figs = Vec::new();
    for (file, cap) in [
        (
            "mssim_vs_ratio.svg",
            "MSSIM against sampling ratio; lower panel: each scheme's difference to the best \
             scheme at that ratio, so that curves that coincide above can be told apart",
        ),
        (
            "psnr_vs_ratio.svg",
            "PSNR against sampling ratio; lower panel: each scheme's difference to the best \
             scheme at that ratio (dB)",
        ),
    ] {
        if let Some(b) = staged_svg(out, file, cap)? {
            figs.push(b);
        }
    }
    blocks.push(Block::Figures(figs));
    if let Some(rp) = r.repeats {
        blocks.push(Block::Paragraph(format!(
            "The curves above are repeat 1's (the plain run). Below, every scheme's mean score \
             over {} repeats against the DMD frames it showed (calibration frames included), \
             with error bars of ± one sample SD: schemes that show a pattern and its complement \
             are compared with those that show it once at equal cost.",
            rp.repeats
        )));
        let mut bars = Vec::new();
        for (file, cap) in [
            (
                "mssim_vs_frames.svg",
                "MSSIM against DMD frames, mean ± SD over the repeats",
            ),
            (
                "psnr_vs_frames.svg",
                "PSNR against DMD frames, mean ± SD over the repeats",
            ),
        ] {
            if let Some(b) = staged_svg(out, file, cap)? {
                bars.push(b);
            }
        }
        blocks.push(Block::Figures(bars));
    }
    let f = &summary.findings;
    let mut text = String::new();
    if !f.scb_beats_double_arm_at.is_empty() || !f.scb_not_above_double_arm_at.is_empty() {
        text.push_str(&format!(
            "Secondary complementary balancing has a higher MSSIM than double-arm dual-pixel at \
             {} of {} ratios. ",
            f.scb_beats_double_arm_at.len(),
            f.scb_beats_double_arm_at.len() + f.scb_not_above_double_arm_at.len()
        ));
    }
    if let Some(d) = f.scb_minus_traditional_mssim_at_max_ratio {
        text.push_str(&format!(
            "At the highest ratio, SCB's MSSIM minus traditional CS's is {d:+.4} (reported, not \
             tuned: see the iteration counts above, traditional CS reconstructs from 0/1 \
             patterns whose DC term slows the solver)."
        ));
    }
    if !text.is_empty() {
        blocks.push(Block::Paragraph(text));
    }
    Ok(())
}

/// The settings that reproduce the page.
fn settings_section(blocks: &mut Vec<Block>, r: &ReportInput<'_>) {
    let o = r.o;
    let settings_ron = r.settings_ron;
    blocks.push(Block::Heading {
        level: 2,
        text: "Settings that reproduce this page".into(),
    });
    blocks.push(Block::Paragraph(
        "The effective bench, with every default written out and the ray count of this run, is \
         bench.ron beside this page (and below). Run it again with:"
            .into(),
    ));
    blocks.push(Block::Preformatted(format!(
        "spibench run bench.ron --seed {}",
        o.seed
    )));
    blocks.push(Block::Preformatted(settings_ron.to_string()));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The parts of double-arm's offset add up to the offset computed from both monitors.
    #[test]
    fn double_arm_offset_parts_sum_to_the_offset() {
        let sums = ArmSums {
            t_a: [[3.1e-6, 2.0e-8], [2.1e-7, 2.9e-6]],
            outside_a: [4.0e-8, 7.0e-8],
            ambient_a: [1.0e-9, 1.2e-9],
            dark_a: [1.5e-9, 1.8e-9],
        };
        let stage = |gain: f64, offset: f64| crate::detector::bap::OutputStage {
            gain_v_per_a: gain,
            swing_v: 10.0,
            offset_v: offset,
            bandwidth_hz: 1e6,
            input_noise_a_per_rthz: 2.3e-12,
        };
        let bap = Bap {
            load: crate::detector::bap::Load::HighImpedance,
            rf: stage(350e3, 2e-3),
            monitors: [stage(17.5e3, 1e-3), stage(17.7e3, -1e-3)],
            responsivity_scale: [1.0, 0.97],
            shot_noise: true,
        };
        let (parts, direct) = double_arm_offset(&sums, &bap);
        let sum: f64 = parts.iter().map(|(_, v)| v).sum();
        assert!(
            (sum - direct).abs() <= 1e-12 * direct.abs().max(1e-9),
            "{sum} vs {direct}"
        );
        assert!(parts.iter().all(|(_, v)| *v != 0.0));
    }
}
