//! `report.html` of `spibench run`: one self-contained page (crate::report::html) that a reader
//! can open with no network: what was traced, where the light went, what the detector saw, what
//! each scheme reconstructed, and the settings that reproduce it.
//!
//! The page is assembled from the run's outcome and from the plots and montage already written
//! into the staging folder (read back and embedded), so the page shows exactly the files beside
//! it.

use crate::error::{Error, Result};
use crate::raster::Raster;
use crate::report::html::{Block, Page, render};
use crate::report::output::OutputDir;
use crate::run::RunOutcome;

use super::run::{element_text, pct};
use crate::run::summary::RunSummary;

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
    format!("{v:.5e} ± {se:.1e} {unit}")
}

/// Writes `report.html` into the staging folder.
pub fn write_report(
    name: &str,
    bench: &crate::optics::Bench,
    o: &RunOutcome,
    summary: &RunSummary<'_>,
    out: &OutputDir,
) -> Result<()> {
    let t = &o.transport;
    let s = &o.settings;
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

    // ---- The bench.
    blocks.push(Block::Heading {
        level: 2,
        text: "Bench: gains and offsets from the trace".into(),
    });
    let (layout, svg) = super::layout::layout_block(bench, name)?;
    let path = out.path("layout.svg");
    std::fs::write(&path, &svg).map_err(|e| crate::Error::write(&path, e))?;
    blocks.push(layout);
    let cmrr = o.detector.cmrr_db();
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
            "CMRR from the diodes' mismatch".into(),
            if cmrr.is_finite() {
                format!("{cmrr:.1} dB")
            } else {
                "infinite (matched diodes)".into()
            },
        ),
    ]));
    let kmax = t.k_map[0]
        .iter()
        .chain(&t.k_map[1])
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        .max(1e-30);
    let xr = Raster::new(w, h, t.x_w.clone())?;
    let kp = Raster::new(w, h, t.k_map[0].clone())?;
    let km = Raster::new(w, h, t.k_map[1].clone())?;
    blocks.push(Block::Figures(vec![
        Block::gray_image(
            format!("ideal object x_j (0 … {:.3e} W)", o.x.max()),
            &xr,
            0.0,
            o.x.max().max(1e-300),
        )?,
        Block::gray_image(
            format!("k₊_j = g₊_j / x_j (0 … {kmax:.3} A/W)"),
            &kp,
            0.0,
            kmax,
        )?,
        Block::gray_image(
            format!("k₋_j = g₋_j / x_j (0 … {kmax:.3} A/W)"),
            &km,
            0.0,
            kmax,
        )?,
    ]));

    // ---- The ledger.
    blocks.push(Block::Heading {
        level: 2,
        text: "Flux ledger".into(),
    });
    let l = &t.ledger;
    blocks.push(Block::Paragraph(format!(
        "Emitted in the traced band: {:.6e} W (nominal {:.6e} W; {:.6e} W outside the traced \
         cone, booked to the lamp housing). Each column is one world: every pattern unit in \
         state + or every unit in state −.",
        l.emitted_w, l.emitted_nominal_w, l.outside_cone_w
    )));
    let mut rows: Vec<Vec<String>> = l.worlds[0]
        .absorbed_w
        .iter()
        .zip(&l.worlds[1].absorbed_w)
        .map(|((n, a), (_, b))| {
            vec![
                format!("absorbed: {n}"),
                format!("{a:.6e}"),
                format!("{b:.6e}"),
            ]
        })
        .collect();
    for (label, f) in [
        (
            "escaped",
            (|w: &crate::transport::LedgerWorld| w.escaped_w) as fn(&_) -> f64,
        ),
        ("path cap", |w| w.path_cap_w),
        ("detected, diode +", |w| w.detected_w[0]),
        ("detected, diode −", |w| w.detected_w[1]),
        ("residual", |w| w.residual_w),
    ] {
        rows.push(vec![
            label.to_string(),
            format!("{:.6e}", f(&l.worlds[0])),
            format!("{:.6e}", f(&l.worlds[1])),
        ]);
    }
    blocks.push(Block::Table {
        caption: Some("Where the light went (W)".into()),
        header: vec!["".into(), "all units +".into(), "all units −".into()],
        rows,
    });

    // ---- The detector's signals.
    blocks.push(Block::Heading {
        level: 2,
        text: "Signals as the oscilloscope sampled them".into(),
    });
    for (q, _) in &o.traces {
        let file = format!("signals_{}.svg", q.key());
        if let Some(b) = staged_svg(out, &file, &format!("{} sequence, first frames", q.key()))? {
            blocks.push(b);
        }
    }

    // ---- Reconstructions.
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
        "iterations",
        "saturated",
    ];
    let rows = o
        .results
        .iter()
        .map(|r| {
            vec![
                r.scheme.label().to_string(),
                pct(r.ratio),
                r.measurements.to_string(),
                r.dmd_frames.to_string(),
                format!("{:.2}", r.acquisition_time_s * 1e3),
                format!("{:.2}", r.psnr_db),
                format!("{:.4}", r.mssim),
                element_text(r.finest_resolved),
                format!(
                    "{}{}",
                    r.iterations,
                    if r.converged { "" } else { " (cap)" }
                ),
                if r.saturated { "yes" } else { "" }.to_string(),
            ]
        })
        .collect();
    blocks.push(Block::Table {
        caption: Some("Every scheme at every ratio".into()),
        header: header.iter().map(|h| h.to_string()).collect(),
        rows,
    });
    if let Some(c) = &o.resolution {
        blocks.push(Block::Paragraph(format!(
            "Resolution read-out: {} Threshold {:.2}. The chart was registered against x \
             (correlation {:.3}); x itself resolves {} (group/element).",
            c.criterion,
            c.threshold,
            c.registration_correlation,
            element_text(c.ideal_finest_resolved)
        )));
    }

    // ---- Curves.
    blocks.push(Block::Heading {
        level: 2,
        text: "Quality against sampling ratio (the paper's Fig. 7)".into(),
    });
    let mut figs = Vec::new();
    for (file, cap) in [
        ("mssim_vs_ratio.svg", "MSSIM against sampling ratio"),
        ("psnr_vs_ratio.svg", "PSNR against sampling ratio"),
    ] {
        if let Some(b) = staged_svg(out, file, cap)? {
            figs.push(b);
        }
    }
    blocks.push(Block::Figures(figs));
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

    // ---- Settings.
    blocks.push(Block::Heading {
        level: 2,
        text: "Settings that reproduce this page".into(),
    });
    let scene_arg = if name.starts_with('<') {
        String::new()
    } else {
        format!(" {name}")
    };
    blocks.push(Block::Preformatted(format!(
        "spibench run{scene_arg} --seed {} --rays {}",
        o.seed, t.rays
    )));
    let settings = serde_json::to_string_pretty(&serde_json::json!({
        "run": summary.settings,
        "electronics": &summary.electronics,
        "frame_timing": summary.frame_timing,
    }))
    .map_err(|e| Error::Numerical(format!("cannot encode the settings: {e}")))?;
    blocks.push(Block::Preformatted(settings));

    let page = Page {
        title: format!("spibench run: {}", s.title),
        blocks,
    };
    let path = out.path("report.html");
    std::fs::write(&path, render(&page)).map_err(|e| Error::write(&path, e))
}
