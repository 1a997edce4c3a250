//! `spibench trace SCENE [--rays N] [--seed S] [--out DIR]`: transport only — k±, b±, the
//! per-unit maps and the flux ledger of a traced bench.
//!
//! Output (DIR): `summary.json` (keys documented on [`TraceSummary`]), `maps.exr` (one
//! multi-channel EXR of the per-unit maps, f32, row-major, row 0 = the top row of the pattern
//! area) and one figure per map (`NAME.svg`, its rendering `NAME.png` and `NAME.pdf`: one square
//! per unit, axes of unit indices, a colour bar in the map's unit, dark units hatched,
//! `report::heatmap::UnitMap`). With the diffractive DMD model (docs/dmd_diffraction.md) it also
//! traces the collection of the DMD's reflected light with and without diffraction:
//! `summary.json` gains `dmd_diffraction`, and `collection.svg`/`.png`/`.pdf` plot each arm's
//! collection against wavelength, the lamp's light and the diodes' responsivity shaded behind.
//! Everything is computed in memory and written into a staging
//! directory that is renamed into place at the end, so bad input or a failed write leaves no
//! partial output.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::optics::{Arm, Bench};
use crate::pipeline::summary::{CollectionShares, DiffractionSummary, TraceSummary, summarize};
use crate::pipeline::{TraceRequest, trace_stage};
use crate::report::exr::write_channels;
use crate::report::heatmap::{UnitMap, write_unit_map};
use crate::report::output::OutputDir;
use crate::report::plot::{Area, LinePlot, PlotOptions, Series, write_plot_with};
use crate::scene::bench::read_bench;
use crate::trace::collection::{Collection, collection};
use crate::transport::Transport;
use rayon::prelude::*;

/// Arguments of `spibench trace`.
#[derive(Debug, Clone, clap::Args)]
#[command(
    mut_arg("rays", |a| a.default_value("2000000").help("Number of lamp rays to trace")),
    mut_arg("seed", |a| a.default_value("1")),
    mut_arg("out", |a| a.default_value("out/trace")),
)]
pub struct TraceArgs {
    /// Bench file (RON, millimetres and degrees; see scenes/paper_bench.ron).
    pub scene: PathBuf,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// `trace`'s default ray count (also set on the flag, for `--help`).
const DEFAULT_RAYS: u64 = 2_000_000;

/// The per-unit maps written to the EXR (channel name, values).
pub fn maps(t: &Transport) -> Vec<(&'static str, Vec<f64>)> {
    vec![
        ("x_w", t.x_w.clone()),
        ("g_plus_a", t.g_a[0].clone()),
        ("g_minus_a", t.g_a[1].clone()),
        ("k_plus_a_per_w", t.k_map[0].clone()),
        ("k_minus_a_per_w", t.k_map[1].clone()),
        ("k_plus_stderr", t.k_map_stderr[0].clone()),
        ("k_minus_stderr", t.k_map_stderr[1].clone()),
        ("x_stderr_w", t.x_map_stderr.clone()),
        ("g_plus_stderr_a", t.g_map_stderr[0].clone()),
        ("g_minus_stderr_a", t.g_map_stderr[1].clone()),
    ]
}

/// Runs `spibench trace`.
pub fn run(args: &TraceArgs) -> anyhow::Result<()> {
    let bench = read_bench(&args.scene)?;
    if bench.dmd().is_none() {
        return Err(Error::field("dmd", "`trace` needs a bench with a DMD")
            .in_file(&args.scene)
            .into());
    }
    let rays = args
        .opts
        .rays_or(DEFAULT_RAYS, super::args::MIN_RAYS_WITH_STDERR)?;
    let seed = args.opts.seed();
    let out = args.opts.out_or("out/trace");
    let start = std::time::Instant::now();
    let bar = super::progress::bar(rays, "rays");
    let report = |done: u64, _: u64| bar.set_position(done);
    let traced = trace_stage(
        &bench,
        &TraceRequest {
            progress: Some(&report),
            ..TraceRequest::new(rays, seed)
        },
    )?;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    // No light on the pattern area is the bench's fault, not a result: exit 2, naming the cause.
    traced.truth().map_err(|e| e.in_file(&args.scene))?;
    let t = &traced.transport;
    let mut summary = summarize(
        &args.scene.display().to_string(),
        &bench,
        t,
        &traced.metrics,
        traced.arrivals(),
    );
    let mut provenance = crate::provenance::Provenance::new(&[seed]).file(&args.scene)?;
    for f in crate::scene::doc::BenchDoc::read(&args.scene)?.input_files() {
        provenance = provenance.file(&f)?;
    }
    let collections = match bench.dmd().and_then(|s| s.dmd.diffraction()) {
        Some(_) => {
            let (shares, c) = diffraction_comparison(&bench, rays, seed)?;
            summary.dmd_diffraction = Some(shares);
            Some(c)
        }
        None => None,
    };
    write_outputs(
        &out,
        t,
        &mut summary,
        &provenance,
        collections.as_ref(),
        &bench,
    )?;
    print_table(&summary, seconds);
    if let Some(d) = &summary.dmd_diffraction {
        print_diffraction(d);
    }
    // The folder and a count: the file list is in summary.json (`files`), and a line per file
    // would not fit a terminal.
    println!(
        "wrote {} ({} files: summary.json, maps.exr and the per-unit maps x, g±, k± as SVG, PNG and PDF)",
        out.display(),
        summary.files.len() + 1
    );
    Ok(())
}

fn print_table(s: &TraceSummary, seconds: f64) {
    let pm = |v: f64, e: f64| format!("{v:.6e} ± {e:.1e}");
    println!(
        "{}: {} rays (seed {}) in {seconds:.1} s",
        s.scene, s.rays, s.seed
    );
    println!("  {:<10} {:>28} {:>28}", "", "arm +", "arm −");
    println!(
        "  {:<10} {:>28} {:>28}",
        "k (A/W)",
        pm(s.k_plus, s.k_plus_stderr),
        pm(s.k_minus, s.k_minus_stderr)
    );
    println!(
        "  {:<10} {:>28} {:>28}",
        "b (A)",
        pm(s.b_plus, s.b_plus_stderr),
        pm(s.b_minus, s.b_minus_stderr)
    );
    println!(
        "  k' = {} A/W, imbalance = {}",
        pm(s.k_prime, s.k_prime_stderr),
        pm(s.imbalance, s.imbalance_stderr)
    );
    println!(
        "  x total = {} W on the pattern; ledger residual {:.1e} / {:.1e} W",
        pm(s.x_total_w, s.x_total_w_stderr),
        s.ledger
            .all_plus
            .residual_w
            .abs()
            .max(s.ledger.all_minus.residual_w.abs()),
        s.ledger.emitted_w
    );
}

/// Wavelength bins of the collection figure (20 nm over the default band).
const COLLECTION_BINS: usize = 40;

/// The collection of the bench's reflected light with geometric mirrors and with its diffractive
/// model ([`crate::trace::collection`]), each from a quarter of the trace's rays (at least
/// 50 000): the shares are ratios of powers on the same rays, well resolved by fewer rays.
fn diffraction_comparison(
    bench: &Bench,
    rays: u64,
    seed: u64,
) -> Result<(DiffractionSummary, [Collection; 2])> {
    let n = (rays / 4).max(50_000);
    let geometric = collection(&bench.with_geometric_dmd(), n, seed, COLLECTION_BINS)?;
    let diffractive = collection(bench, n, seed, COLLECTION_BINS)?;
    let summary = DiffractionSummary {
        rays: n,
        geometric: CollectionShares::of(&geometric),
        diffractive: CollectionShares::of(&diffractive),
    };
    Ok((summary, [geometric, diffractive]))
}

fn print_diffraction(d: &DiffractionSummary) {
    println!(
        "  DMD diffraction: share of the pattern mirrors' reflected power on each diode ({} rays per model)",
        d.rays
    );
    println!("  {:<22} {:>12} {:>12}", "", "geometric", "diffractive");
    let (g, f) = (&d.geometric, &d.diffractive);
    for (label, a, b) in [
        ("diode + from state +", g.plus_from_plus, f.plus_from_plus),
        ("diode − from state +", g.minus_from_plus, f.minus_from_plus),
        ("diode + from state −", g.plus_from_minus, f.plus_from_minus),
        (
            "diode − from state −",
            g.minus_from_minus,
            f.minus_from_minus,
        ),
    ] {
        println!("  {label:<22} {a:>12.4} {b:>12.4}");
    }
}

/// The figure of each arm's collection against wavelength, both models, with the spectrum of
/// the light on the pattern (the lamp's, after the optics before the DMD) and each diode's
/// responsivity shaded behind the curves, each normalised to a peak of 1 on the right-hand
/// scale. Diodes with one responsivity curve share one shaded area.
fn collection_plot(c: &[Collection; 2], bench: &Bench) -> (LinePlot, PlotOptions) {
    let [geometric, diffractive] = c;
    let x: Vec<f64> = (0..geometric.bins)
        .map(|b| geometric.wavelength_m(b) * 1e9)
        .collect();
    let mut series = Vec::new();
    for arm in Arm::ALL {
        for (name, col) in [("geometric", geometric), ("diffractive", diffractive)] {
            series.push(Series {
                label: format!("arm {} ({name})", arm.label()),
                x: x.clone(),
                y: (0..col.bins).map(|b| col.share_in(b, arm, arm)).collect(),
                y_err: None,
            });
        }
    }
    let scaled = |v: Vec<f64>| {
        let peak = v.iter().cloned().fold(0.0, f64::max);
        v.into_iter()
            .map(|y| if peak > 0.0 { y / peak } else { 0.0 })
            .collect::<Vec<f64>>()
    };
    // The shaded curves on a finer grid than the bins, so that their shapes show.
    let fine: Vec<f64> = {
        let (lo, hi) = (geometric.band_m.0 * 1e9, geometric.band_m.1 * 1e9);
        (0..=200)
            .map(|k| lo + (hi - lo) * f64::from(k) / 200.0)
            .collect()
    };
    let mut areas = vec![Area {
        label: "lamp light on the pattern".into(),
        x: x.clone(),
        y: scaled(diffractive.incident_w.clone()),
    }];
    let resp: Vec<Vec<f64>> = Arm::ALL
        .iter()
        .map(|&arm| {
            let r = &bench.detectors()[arm].responsivity;
            scaled(fine.iter().map(|nm| r.at(nm * 1e-9)).collect())
        })
        .collect();
    if resp[0] == resp[1] {
        areas.push(Area {
            label: "diode responsivity".into(),
            x: fine.clone(),
            y: resp[0].clone(),
        });
    } else {
        for (arm, y) in Arm::ALL.iter().zip(resp) {
            areas.push(Area {
                label: format!("diode {} responsivity", arm.label()),
                x: fine.clone(),
                y,
            });
        }
    }
    let plot = LinePlot {
        title: "Each arm's collection of the DMD-reflected light against wavelength".into(),
        x_label: "wavelength (nm)".into(),
        y_label: "share on the arm's diode".into(),
        series,
        log_x: false,
    };
    let opts = PlotOptions {
        size: None,
        areas,
        area_label: "relative (peak = 1)".into(),
    };
    (plot, opts)
}

/// Writes every output into a staging directory beside `out` ([`OutputDir`]) and moves it into
/// place only when everything has been written, so a failure leaves no partial output.
fn write_outputs(
    out: &Path,
    t: &Transport,
    summary: &mut TraceSummary,
    provenance: &crate::provenance::Provenance,
    collections: Option<&[Collection; 2]>,
    bench: &Bench,
) -> Result<()> {
    let dir = OutputDir::create(out)?;
    let mut files = Vec::new();
    let (w, h) = (t.units_across, t.units_down);
    let maps = maps(t);
    let f32s: Vec<Vec<f32>> = maps
        .iter()
        .map(|(_, v)| v.iter().map(|&x| x as f32).collect())
        .collect();
    let channels: Vec<(&str, &[f32])> = maps
        .iter()
        .zip(&f32s)
        .map(|((n, _), v)| (*n, v.as_slice()))
        .collect();
    let unit_maps = [
        ("x", "x_j", "W", &t.x_w, true),
        ("g_plus", "g₊_j", "A", &t.g_a[0], false),
        ("g_minus", "g₋_j", "A", &t.g_a[1], false),
        ("k_plus", "k₊_j", "A/W", &t.k_map[0], true),
        ("k_minus", "k₋_j", "A/W", &t.k_map[1], true),
    ];
    // The EXR and the five maps (SVG, PNG and PDF each; the PNG and PDF compression is most of
    // the time) are independent files, written side by side: serial, they were the largest
    // serial part of `trace` on many threads.
    let (exr, written) = rayon::join(
        || write_channels(&dir.path("maps.exr"), w, h, &channels),
        || {
            unit_maps
                .par_iter()
                .map(|&(stem, label, unit, values, from_zero)| {
                    let map = UnitMap {
                        label: label.into(),
                        unit: unit.into(),
                        width: w,
                        height: h,
                        values: values.clone(),
                        light_w: t.x_w.clone(),
                        from_zero,
                    };
                    let (svg, png) = (format!("{stem}.svg"), format!("{stem}.png"));
                    write_unit_map(&map, &dir.path(&svg), &dir.path(&png))?;
                    Ok([svg, png, format!("{stem}.pdf")])
                })
                .collect::<Vec<Result<_>>>()
        },
    );
    exr?;
    files.push("maps.exr".to_string());
    // The first failing map's error in order, on any thread count.
    files.extend(crate::error::in_order(written)?.into_iter().flatten());
    if let Some(c) = collections {
        let (plot, opts) = collection_plot(c, bench);
        write_plot_with(
            &plot,
            &opts,
            &dir.path("collection.svg"),
            &dir.path("collection.png"),
        )?;
        for ext in ["svg", "png", "pdf"] {
            files.push(format!("collection.{ext}"));
        }
    }
    summary.files = files;
    super::provenance::write_summary(&dir, &*summary, provenance)?;
    dir.commit()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("spibench-trace-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// A bench with the diffractive DMD model: `summary.json` gains `dmd_diffraction` (shares
    /// in [0, 1], each arm collecting most of its own light with geometric mirrors) and the
    /// collection figure is written.
    #[test]
    fn diffractive_bench_reports_the_collection() {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron");
        let text = std::fs::read_to_string(&src).unwrap().replace(
            "package_mm: (10.0, 10.0),",
            "package_mm: (10.0, 10.0),\n        model: Diffractive(),",
        );
        let dir = tmp("diffractive");
        std::fs::create_dir_all(&dir).unwrap();
        let scene = dir.join("bench.ron");
        std::fs::write(&scene, text).unwrap();
        let out = dir.join("out");
        let args = TraceArgs {
            scene,
            work: Default::default(),
            opts: super::super::args::RunOpts {
                rays: Some(20_000),
                seed: Some(3),
                out: Some(out.clone()),
            },
        };
        run(&args).unwrap();
        let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let d = &v["dmd_diffraction"];
        for model in ["geometric", "diffractive"] {
            for key in [
                "plus_from_plus",
                "minus_from_plus",
                "plus_from_minus",
                "minus_from_minus",
            ] {
                let s = d[model][key].as_f64().unwrap();
                assert!((0.0..=1.0).contains(&s), "{model} {key}: {s}");
            }
        }
        assert!(d["geometric"]["plus_from_plus"].as_f64().unwrap() > 0.5);
        assert!(out.join("collection.png").is_file() && out.join("collection.pdf").is_file());
        // The lamp's light and the responsivity are shaded, with their scale on the right.
        let svg = std::fs::read_to_string(out.join("collection.svg")).unwrap();
        for label in [
            "lamp light on the pattern",
            "diode responsivity",
            "relative (peak = 1)",
            "arm + (diffractive)",
        ] {
            assert!(svg.contains(&format!(r#"aria-label="{label}""#)), "{label}");
        }
        assert!(svg.contains("<polygon"), "no filled area");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn writes_summary_maps_and_images() {
        let out = tmp("ok");
        let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron");
        let args = TraceArgs {
            scene,
            work: Default::default(),
            opts: super::super::args::RunOpts {
                rays: Some(20_000),
                seed: Some(3),
                out: Some(out.clone()),
            },
        };
        run(&args).unwrap();
        let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        for key in [
            "k_plus",
            "k_minus",
            "b_plus",
            "b_minus",
            "k_plus_stderr",
            "k_minus_stderr",
            "b_plus_stderr",
            "b_minus_stderr",
            "k_prime",
            "imbalance",
            "rays",
            "ledger",
        ] {
            assert!(v.get(key).is_some(), "missing {key}");
        }
        assert_eq!(v["rays"], 20_000);
        assert!(v["k_plus"].as_f64().unwrap() > 0.0);
        assert!(
            v["ledger"]["all_plus"]["absorbed_w"]["dmd_gaps"]
                .as_f64()
                .unwrap()
                > 0.0
        );
        for f in [
            "maps.exr",
            "x.png",
            "g_plus.png",
            "g_minus.png",
            "k_plus.png",
            "k_minus.png",
        ] {
            assert!(out.join(f).is_file(), "{f}");
        }
        // The map is enlarged to a readable size, with its SVG beside it.
        let img = image::open(out.join("k_plus.png")).unwrap();
        assert!(img.width() >= 480 && img.height() >= 480);
        assert!(out.join("k_plus.svg").is_file());
        // The EXR holds the ten channels at 4 × 4: the maps and their standard errors.
        let exr = exr::prelude::read_all_data_from_file(out.join("maps.exr")).unwrap();
        let layer = &exr.layer_data[0];
        assert_eq!(layer.size, exr::prelude::Vec2(4, 4));
        assert_eq!(layer.channel_data.list.len(), 10);
        let names: Vec<String> = layer
            .channel_data
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect();
        for n in ["x_stderr_w", "g_plus_stderr_a", "g_minus_stderr_a"] {
            assert!(names.iter().any(|c| c == n), "{n} in {names:?}");
        }
        // Running again over an existing directory replaces the files and leaves no staging.
        run(&args).unwrap();
        let leftovers: Vec<_> = std::fs::read_dir(out.parent().unwrap())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains("partial"))
            .filter(|e| e.file_name().to_string_lossy().contains("spibench-trace"))
            .collect();
        assert!(leftovers.is_empty());
        let _ = std::fs::remove_dir_all(&out);
    }

    /// The numbers behind the per-unit standard errors on the paper bench (run by hand:
    /// `cargo test --lib cli::trace::tests::paper_bench_unresolved_units -- --ignored
    /// --nocapture`; SPIBENCH_RAYS sets the ray count, default 2 × 10⁶ as `trace`).
    #[test]
    #[ignore]
    fn paper_bench_unresolved_units() {
        let rays = std::env::var("SPIBENCH_RAYS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(2_000_000);
        let doc = crate::scene::doc::BenchDoc::parse(
            super::super::run::PAPER_BENCH,
            Path::new("paper_bench.ron"),
        )
        .unwrap();
        let bench = doc.build().unwrap();
        let traced = trace_stage(&bench, &TraceRequest::new(rays, 1)).unwrap();
        let t = &traced.transport;
        let lit = crate::report::heatmap::lit_units(&t.x_w, crate::report::heatmap::DARK_FRACTION);
        for d in 0..2 {
            let nonzero = t.k_map[d].iter().filter(|k| **k != 0.0).count();
            let unresolved: Vec<usize> = (0..t.k_map[d].len())
                .filter(|&j| t.k_map[d][j] != 0.0 && t.k_map_stderr[d][j].is_infinite())
                .collect();
            let zero_se = (0..t.k_map[d].len())
                .filter(|&j| t.k_map[d][j] != 0.0 && t.k_map_stderr[d][j] == 0.0)
                .count();
            let max_x = unresolved.iter().map(|&j| t.x_w[j]).fold(0.0, f64::max);
            let max_k = unresolved
                .iter()
                .map(|&j| t.k_map[d][j])
                .fold(0.0, f64::max);
            let mean_x = t.x_w.iter().sum::<f64>() / t.x_w.len() as f64;
            println!(
                "arm {d}: {rays} rays, {} units, {nonzero} with k != 0, {} unresolved (light in \
                 one batch only), {zero_se} with SE exactly 0 otherwise; unresolved units: x_j \
                 <= {max_x:.3e} W (mean x_j {mean_x:.3e} W), k_j <= {max_k:.3} A/W, {} of them lit",
                t.k_map[d].len(),
                unresolved.len(),
                unresolved.iter().filter(|&&j| lit[j]).count()
            );
        }
    }

    #[test]
    fn bad_input_leaves_no_output() {
        let out = tmp("bad");
        let dir = tmp("bad-scene");
        std::fs::create_dir_all(&dir).unwrap();
        let scene = dir.join("bad.ron");
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron"),
        )
        .unwrap()
        .replace(
            "diameter_mm: 5.0,\n        ),\n        minus",
            "diameter_mm: -5.0,\n        ),\n        minus",
        );
        std::fs::write(&scene, text).unwrap();
        let args = TraceArgs {
            scene,
            work: Default::default(),
            opts: super::super::args::RunOpts {
                rays: Some(1000),
                seed: Some(1),
                out: Some(out.clone()),
            },
        };
        let err = run(&args).unwrap_err();
        let e = err.downcast_ref::<Error>().expect("a library error");
        assert!(e.is_user_error());
        assert!(e.to_string().contains("diameter_mm"), "{e}");
        assert!(!out.exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
