//! Every figure kind rendered as a command writes it: its PNG states the resolution it is drawn
//! at (`pHYs`), nothing drawn (text above all) leaves the canvas, every measured point of a
//! sweep carries a marker, and limits are one shaded band with one legend entry.

use std::path::{Path, PathBuf};

use super::heatmap::{Heatmap, UnitMap, write_heatmap, write_unit_map};
use super::montage::{EmptyCell, Montage, montage_dpi, montage_layout, write_montage_figure};
use super::plot::{
    Band, BandAxis, LinePlot, Mark, Markers, PlotOptions, ScopePlot, Series, write_plot_with,
    write_scope,
};
use super::png::phys_dpi;
use super::svg::PNG_DPI;
use crate::raster::Raster;

fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spibench-figures-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The canvas (the viewBox) and the bounding box of everything drawn, in SVG units.
fn drawn_extent(svg: &str) -> ((f32, f32), (f32, f32, f32, f32)) {
    let tree = super::svg::parse(svg).unwrap();
    let size = tree.size();
    let b = tree.root().abs_bounding_box();
    let vb: Vec<f32> = {
        let doc = roxmltree::Document::parse(svg).unwrap();
        doc.root_element()
            .attribute("viewBox")
            .unwrap()
            .split(' ')
            .map(|t| t.parse().unwrap())
            .collect()
    };
    // usvg scales the viewBox to the stated size; back to viewBox units.
    let k = vb[2] / size.width();
    (
        (vb[2], vb[3]),
        (b.left() * k, b.top() * k, b.right() * k, b.bottom() * k),
    )
}

/// Every glyph outline (`<path aria-label=…>`, the text of the figure) and everything else
/// drawn lies on the canvas.
fn assert_on_canvas(svg: &str, what: &str) {
    let ((w, h), (l, t, r, b)) = drawn_extent(svg);
    // usvg's bounding box of an embedded, scaled `<image>` (a montage's tiles) is not in the
    // canvas' units: a montage is checked by its text alone.
    assert!(
        svg.contains("<image") || (l >= -0.5 && t >= -0.5 && r <= w + 0.5 && b <= h + 0.5),
        "{what}: drawn over ({l:.1}, {t:.1})–({r:.1}, {b:.1}) on a {w}×{h} canvas"
    );
    // Text alone: each outlined label inside the canvas too (a stricter message).
    let doc = roxmltree::Document::parse(svg).unwrap();
    for n in doc
        .descendants()
        .filter(|n| n.has_tag_name("path") && n.attribute("aria-label").is_some())
    {
        // The path with its own transform and those of its groups (a rotated label).
        let transforms: Vec<String> = n
            .ancestors()
            .filter_map(|a| a.attribute("transform"))
            .map(|t| format!(r#"<g transform="{t}">"#))
            .collect();
        let one = format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}">{}<path d="{}"/>{}</svg>"#,
            transforms.iter().rev().cloned().collect::<String>(),
            n.attribute("d").unwrap(),
            "</g>".repeat(transforms.len())
        );
        let tree = resvg::usvg::Tree::from_str(&one, &resvg::usvg::Options::default()).unwrap();
        let bb = tree.root().abs_bounding_box();
        assert!(
            bb.left() >= -0.5
                && bb.top() >= -0.5
                && bb.right() <= w + 0.5
                && bb.bottom() <= h + 0.5,
            "{what}: the text {:?} leaves the canvas ({:.1}, {:.1})–({:.1}, {:.1})",
            n.attribute("aria-label").unwrap(),
            bb.left(),
            bb.top(),
            bb.right(),
            bb.bottom()
        );
    }
}

fn assert_png_dpi(path: &Path, dpi: f64) {
    let bytes = std::fs::read(path).unwrap();
    let got = phys_dpi(&bytes).unwrap_or_else(|| panic!("{} has no pHYs", path.display()));
    assert!((got - dpi).abs() < 0.05, "{}: {got} dpi", path.display());
    image::load_from_memory(&bytes).unwrap();
}

/// Writes a plot and checks its PNG's resolution and its canvas; returns the SVG.
fn write_checked(dir: &Path, stem: &str, plot: &LinePlot, opts: &PlotOptions) -> String {
    let (svg, png) = (
        dir.join(format!("{stem}.svg")),
        dir.join(format!("{stem}.png")),
    );
    write_plot_with(plot, opts, &svg, &png).unwrap();
    assert_png_dpi(&png, PNG_DPI);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert_on_canvas(&text, stem);
    text
}

/// Filled discs of series 0's colour (its marker shape) in a plot's SVG.
fn discs(svg: &str) -> usize {
    svg.matches("<circle")
        .zip(svg.split("<circle").skip(1))
        .filter(|(_, rest)| {
            let tag = &rest[..rest.find('>').unwrap()];
            tag.contains("#0072B2") && !tag.contains(r#"fill="none""#)
        })
        .count()
}

/// A sweep's figure: 13 measured points, each with a marker; the limit |m| ≤ L is one shaded
/// band with one legend entry, and its two crossings are marked; the x axis says the variable in
/// words with its unit, and a long description is fitted rather than clipped.
#[test]
fn sweep_figures_mark_every_point_and_shade_the_limit() {
    let dir = scratch("sweep");
    let x: Vec<f64> = (0..13).map(|k| -1.5 + 0.25 * f64::from(k)).collect();
    let plot = LinePlot {
        title: String::new(),
        x_label: "− diode decentre x (mm)".into(),
        y_label: "imbalance (k₊ − k₋)/(k₊ + k₋) of a very long description indeed".into(),
        series: vec![Series {
            label: String::new(),
            y: x.iter().map(|v| 0.004 * v * v - 0.002).collect(),
            y_err: Some(vec![2e-4; 13]),
            x,
        }],
        log_x: false,
    };
    let opts = PlotOptions {
        bands: vec![Band {
            label: "|imbalance| ≤ 0.003".into(),
            axis: BandAxis::Y,
            lo: -0.003,
            hi: 0.003,
        }],
        marks: vec![
            Mark {
                x: -1.118,
                y: 0.003,
                x_interval: Some([-1.2, -1.05]),
            },
            Mark {
                x: 1.118,
                y: 0.003,
                x_interval: None,
            },
        ],
        mark_label: "crossing (95 % interval)".into(),
        ..PlotOptions::default()
    };
    let svg = write_checked(&dir, "sweep", &plot, &opts);
    assert_eq!(discs(&svg), 13, "a marker on each of the 13 points");
    assert!(
        svg.contains("− diode decentre x (mm)"),
        "the axis in words with its unit"
    );
    assert_eq!(
        svg.matches("|imbalance| ≤ 0.003").count(),
        1,
        "one legend entry"
    );
    assert_eq!(
        svg.matches(r#"aria-label="crossing (95 % interval)""#)
            .count(),
        1
    );
    // Two crossing rings on the axes and one in the legend.
    assert_eq!(svg.matches(r#"r="8""#).count(), 3);
    // The band is shaded in its colour.
    assert!(svg.contains("#009E73"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A figure of curves that coincide carries a difference panel below, with the same styles;
/// histograms are outlines without markers; empirical CDFs are steps with a marker per trial;
/// a log axis and bands on x stay on the canvas.
#[test]
fn panels_histograms_and_cdfs_render_on_the_canvas() {
    let dir = scratch("kinds");
    let ratios = vec![0.05, 0.1, 0.2, 0.3, 0.5];
    let same = |label: &str, d: f64| Series {
        label: label.into(),
        x: ratios.clone(),
        y: ratios.iter().map(|r| 0.5 + 0.4 * r - d).collect(),
        y_err: None,
    };
    let plot = LinePlot {
        title: String::new(),
        x_label: "sampling ratio M/N".into(),
        y_label: "MSSIM".into(),
        series: vec![same("single detector", 0.0), same("SCB", 1e-4)],
        log_x: false,
    };
    let lower = LinePlot {
        title: String::new(),
        x_label: plot.x_label.clone(),
        y_label: "Δ to best".into(),
        series: vec![same("single detector", 0.0), same("SCB", 1e-4)]
            .into_iter()
            .map(|mut s| {
                let top = s.y.clone();
                s.y = top
                    .iter()
                    .zip(&ratios)
                    .map(|(y, r)| y - (0.5 + 0.4 * r))
                    .collect();
                s
            })
            .collect(),
        log_x: false,
    };
    let opts = PlotOptions {
        lower: Some(Box::new(lower)),
        ..PlotOptions::default()
    };
    let svg = write_checked(&dir, "panels", &plot, &opts);
    assert!(svg.contains(r#"aria-label="Δ to best""#));
    // One legend for both panels: each label once.
    assert_eq!(svg.matches(r#"aria-label="SCB""#).count(), 1);
    // Markers on every point of both panels (5 + 5) and the legend's sample.
    assert_eq!(discs(&svg), 11);

    let hist = LinePlot {
        title: String::new(),
        x_label: "off-arm leak, all units +: P₋/(P₊ + P₋) (fraction, 0–1), a long label".into(),
        y_label: "trials".into(),
        series: vec![Series {
            label: String::new(),
            x: vec![0.0, 0.0, 0.1, 0.1, 0.2, 0.2, 0.3, 0.3],
            y: vec![0.0, 4.0, 4.0, 9.0, 9.0, 7.0, 7.0, 0.0],
            y_err: None,
        }],
        log_x: false,
    };
    let opts = PlotOptions {
        bands: vec![Band {
            label: "leak ≤ 0.25".into(),
            axis: BandAxis::X,
            lo: f64::NEG_INFINITY,
            hi: 0.25,
        }],
        markers: Markers::None,
        ..PlotOptions::default()
    };
    let svg = write_checked(&dir, "hist", &hist, &opts);
    assert_eq!(
        discs(&svg),
        0,
        "a histogram's corners are not measured points"
    );

    let v: Vec<f64> = (1..=20).map(|k| 1e-4 * f64::from(k * k)).collect();
    let cdf = LinePlot {
        title: String::new(),
        x_label: "|imbalance| (log scale)".into(),
        y_label: "fraction of trials ≤ x".into(),
        series: vec![Series {
            label: String::new(),
            y: (1..=20).map(|k| f64::from(k) / 20.0).collect(),
            x: v,
            y_err: None,
        }],
        log_x: true,
    };
    let opts = PlotOptions {
        bands: vec![Band {
            label: "|imbalance| ≤ 0.01".into(),
            axis: BandAxis::X,
            lo: f64::NEG_INFINITY,
            hi: 0.01,
        }],
        steps: true,
        ..PlotOptions::default()
    };
    let svg = write_checked(&dir, "cdf", &cdf, &opts);
    assert_eq!(discs(&svg), 20, "a marker at each trial");
    // Steps: the line holds each value until the next trial (two vertices per trial).
    let longest = svg
        .split("points=\"")
        .skip(1)
        .map(|p| p[..p.find('"').unwrap()].split(' ').count())
        .max()
        .unwrap();
    assert!(longest >= 39, "the CDF's line has {longest} vertices");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Oscilloscope panels, heatmaps, per-unit maps and montages: pHYs and the canvas; a montage
/// states the resolution that fills a two-column page and shows a blank cell as background.
#[test]
fn other_figure_kinds_state_their_resolution() {
    let dir = scratch("others");
    let t_us: Vec<f64> = (0..200).map(|i| f64::from(i) * 0.1).collect();
    let scope = ScopePlot {
        channels: vec![("RF".into(), t_us.iter().map(|t| (t / 3.0).sin()).collect())],
        t_us,
        frame_us: 5.0,
        settling_us: 1.0,
    };
    let (svg, png) = (dir.join("scope.svg"), dir.join("scope.png"));
    write_scope(&scope, &svg, &png).unwrap();
    assert_png_dpi(&png, PNG_DPI);
    assert_on_canvas(&std::fs::read_to_string(&svg).unwrap(), "scope");

    let h = Heatmap {
        x_label: "+ diode decentre x (mm)".into(),
        y_label: "+ diode decentre y (mm)".into(),
        value_label: "imbalance (k₊ − k₋)/(k₊ + k₋)".into(),
        xs: vec![-1.0, 0.0, 1.0],
        ys: vec![0.0, 2.0],
        values: vec![0.1, 0.2, 0.3, f64::NAN, 0.5, 0.6],
        mark: Some((0.0, 0.0)),
    };
    let (svg, png) = (dir.join("heat.svg"), dir.join("heat.png"));
    write_heatmap(&h, &svg, &png).unwrap();
    assert_png_dpi(&png, PNG_DPI);
    assert_on_canvas(&std::fs::read_to_string(&svg).unwrap(), "heatmap");

    let m = UnitMap {
        label: "k₊_j".into(),
        unit: "A/W".into(),
        width: 4,
        height: 3,
        values: (0..12).map(f64::from).collect(),
        light_w: vec![1.0; 12],
        from_zero: true,
    };
    let (svg, png) = (dir.join("units.svg"), dir.join("units.png"));
    write_unit_map(&m, &svg, &png).unwrap();
    assert_png_dpi(&png, PNG_DPI);
    assert_on_canvas(&std::fs::read_to_string(&svg).unwrap(), "unit map");

    let tile = Raster::from_fn(8, 8, |r, c| ((r * 31 + c * 17) % 256) as f64);
    let montage = Montage {
        title: String::new(),
        row_labels: vec!["(a) single detector".into(), "(b) SCB".into()],
        col_labels: vec!["object".into(), "10 %".into(), "25 %".into()],
        tiles: vec![
            vec![Some(tile.clone()), Some(tile.clone()), Some(tile.clone())],
            vec![None, Some(tile.clone()), Some(tile)],
        ],
        captions: vec![
            vec![
                "ideal object x".into(),
                "20.1 dB / 0.61".into(),
                "22.0 dB / 0.70".into(),
            ],
            vec![
                String::new(),
                "20.3 dB / 0.62".into(),
                "22.4 dB / 0.72".into(),
            ],
        ],
        empty: EmptyCell::Blank,
    };
    let (svg, png) = (dir.join("montage.svg"), dir.join("montage.png"));
    write_montage_figure(&montage, 64, &svg, &png).unwrap();
    let lay = montage_layout(&montage, 64).unwrap();
    assert_png_dpi(&png, montage_dpi(&lay));
    assert_on_canvas(&std::fs::read_to_string(&svg).unwrap(), "montage");
    let img = image::open(&png).unwrap().to_rgb8();
    let (x0, y0) = lay.cell_origin(1, 0);
    assert_eq!(
        img.get_pixel(x0 + 32, y0 + 32).0,
        [255; 3],
        "a blank cell is background"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The tolerance run's tornado chart: pHYs, everything on the canvas (long row labels are
/// fitted into their column), one bar per end of each row, the rows' labels in the figure.
#[test]
fn tornado_charts_render_on_the_canvas() {
    use super::plot::{Tornado, TornadoPanel, write_tornado};
    let dir = scratch("tornado");
    let rows = [
        "dmd.tilt_deg (fixed)",
        "electronics.detector.responsivity_scale_minus",
        "detectors.minus.decenter_mm.x",
        "a_very_long_element_name_that_cannot_fit.decenter_mm.x",
    ];
    let t = Tornado {
        rows: rows.iter().map(|s| s.to_string()).collect(),
        panels: vec![
            TornadoPanel {
                x_label: "Δ imbalance ι′ (electrical)".into(),
                bars: vec![
                    [[-0.81, 0.0025], [0.85, 0.06]],
                    [[-0.01, 1e-9], [0.01, 1e-9]],
                    [[2e-3, 4e-4], [-2.5e-3, 4e-4]],
                    [[f64::NAN, f64::NAN], [1e-4, 1e-4]],
                ],
            },
            TornadoPanel {
                x_label: "Δ k′ (A/W)".into(),
                bars: vec![
                    [[-0.45, 0.01], [-0.7, 0.01]],
                    [[0.0, 0.0], [0.0, 0.0]],
                    [[-1e-3, 2e-4], [-1.2e-3, 2e-4]],
                    [[0.0, 0.0], [0.0, 0.0]],
                ],
            },
        ],
        ends: ["tolerance at its min".into(), "at its max".into()],
    };
    let (svg, png) = (dir.join("tornado.svg"), dir.join("tornado.png"));
    write_tornado(&t, &svg, &png).unwrap();
    assert_png_dpi(&png, PNG_DPI);
    assert!(svg.with_extension("pdf").exists());
    let text = std::fs::read_to_string(&svg).unwrap();
    assert_on_canvas(&text, "tornado");
    for label in ["dmd.tilt_deg (fixed)", "detectors.minus.decenter_mm.x"] {
        assert!(text.contains(label), "no row label {label:?}");
    }
    // A row whose bars do not match the rows is refused.
    let mut bad = t.clone();
    bad.panels[1].bars.pop();
    assert!(super::plot::render_tornado_svg(&bad).is_err());
}
