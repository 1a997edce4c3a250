use super::lines::*;
use super::scope::*;
use super::ticks::*;
use super::write::*;
use super::*;
use plotters::prelude::*;

fn example() -> LinePlot {
    let x: Vec<f64> = vec![0.01, 0.02, 0.05, 0.1, 0.2, 0.5];
    LinePlot {
        title: "PSNR versus sampling ratio".into(),
        x_label: "sampling ratio M/N".into(),
        y_label: "PSNR (dB)".into(),
        series: vec![
            Series {
                label: "single detector".into(),
                x: x.clone(),
                y: x.iter().map(|r| 14.0 + 4.0 * (r * 100.0f64).ln()).collect(),
                y_err: Some(vec![0.8, 0.7, 0.6, 0.5, 0.4, 0.3]),
            },
            Series {
                label: "secondary complementary balancing".into(),
                x: x.clone(),
                y: x.iter().map(|r| 17.0 + 4.5 * (r * 100.0f64).ln()).collect(),
                y_err: None,
            },
            Series {
                label: "k₊ & k₋ <balanced>".into(),
                x,
                y: vec![15.0, 18.0, f64::NAN, 24.0, 27.0, 30.0],
                y_err: Some(vec![1.0, f64::NAN, 1.0, 0.0, 1.0, 1.0]),
            },
        ],
        log_x: true,
    }
}

#[test]
fn writes_svg_and_png_with_text_and_content() {
    let dir = std::env::temp_dir().join(format!("spibench-plot-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for log_x in [true, false] {
        let mut plot = example();
        plot.log_x = log_x;
        let svg_path = dir.join(format!("p{log_x}.svg"));
        let png_path = dir.join(format!("p{log_x}.png"));
        write_plot(&plot, &svg_path, &png_path).unwrap();
        let svg = std::fs::read_to_string(&svg_path).unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        // No title in the figure: the caption belongs to the page.
        assert!(!svg.contains("PSNR versus sampling ratio"));
        for text in [
            "sampling ratio M/N",
            "PSNR (dB)",
            "single detector",
            "secondary complementary balancing",
            "k₊ &amp; k₋ &lt;balanced&gt;",
        ] {
            assert!(svg.contains(text), "SVG lacks {text:?}");
        }
        let pdf = std::fs::read(svg_path.with_extension("pdf")).unwrap();
        assert!(pdf.starts_with(b"%PDF-") && pdf.len() > 1000);
        let img = image::open(&png_path).unwrap().to_rgb8();
        let _ = std::fs::remove_file(&svg_path);
        let _ = std::fs::remove_file(&png_path);
        let _ = std::fs::remove_file(svg_path.with_extension("pdf"));
        // The PNG is the SVG file rendered at 288 dpi: pixel for pixel the same.
        let (w, h, rgb) = crate::report::svg::print_to_rgb(&svg).unwrap();
        assert_eq!((w, h), img.dimensions());
        assert_eq!(w, 1008, "a single column at 288 dpi");
        assert!(rgb == img.as_raw().as_slice(), "PNG and SVG differ");
        // Every series colour appears (lines and markers were drawn), not just text.
        for c in &PALETTE[..3] {
            let n = img.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count();
            assert!(n > 50, "colour {c:?} drawn on only {n} pixels");
        }
        // The legend sits below the axes: the bottom band holds series colours.
        let bottom = (0..w)
            .flat_map(|x| (h - h / 8..h).map(move |y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0 == [PALETTE[1].0, PALETTE[1].1, PALETTE[1].2])
            .count();
        assert!(bottom > 20, "no legend sample below the axes ({bottom} px)");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The printed size a file states: the root's width and height (in inches) and its viewBox.
pub(crate) fn print_size(svg: &str) -> ((f64, f64), (f64, f64)) {
    let doc = roxmltree::Document::parse(svg).unwrap();
    let root = doc.root_element();
    let inches = |name: &str| -> f64 {
        let v = root.attribute(name).unwrap();
        v.strip_suffix("in")
            .unwrap_or_else(|| panic!("{name} = {v:?} is not in inches"))
            .parse()
            .unwrap()
    };
    let vb: Vec<f64> = root
        .attribute("viewBox")
        .unwrap()
        .split(' ')
        .map(|t| t.parse().unwrap())
        .collect();
    ((inches("width"), inches("height")), (vb[2], vb[3]))
}

/// Every text of a print-size SVG: (text, size in points at print size, height of its ink
/// in points).
pub(crate) fn text_sizes_pt(svg: &str) -> Vec<(String, f64, f64)> {
    let ((w_in, _), (w_units, _)) = print_size(svg);
    let pt_per_unit = w_in * 72.0 / w_units;
    let doc = roxmltree::Document::parse(svg).unwrap();
    doc.descendants()
        .filter(|n| n.has_tag_name("path") && n.attribute("aria-label").is_some())
        .map(|n| {
            let size: f64 = n.attribute("font-size").unwrap().parse().unwrap();
            let ys: Vec<f64> = n
                .attribute("d")
                .unwrap()
                .split(|c: char| c.is_ascii_alphabetic() || c == ' ')
                .filter_map(|t| t.parse().ok())
                .skip(1)
                .step_by(2)
                .collect();
            let lo = ys.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (
                n.attribute("aria-label").unwrap().to_string(),
                size * pt_per_unit,
                (hi - lo) * pt_per_unit,
            )
        })
        .collect()
}

/// The written SVG and PDF have the column's width (3.5 in single, 7.2 in double) and
/// every text is 8 to 9 pt at that size; digits are drawn at the stated size (their ink
/// is DejaVu Sans' digit height, 0.73 em).
#[test]
fn figures_have_print_sizes_and_8_to_9_pt_text() {
    let dir = std::env::temp_dir().join(format!("spibench-plot-size-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (size, width_pt) in [(FigureSize::SINGLE, 252.0), (FigureSize::DOUBLE, 518.4)] {
        let svg_path = dir.join("s.svg");
        let opts = PlotOptions {
            size: Some(size),
            ..PlotOptions::default()
        };
        write_plot_with(&example(), &opts, &svg_path, &dir.join("s.png")).unwrap();
        let svg = std::fs::read_to_string(&svg_path).unwrap();
        let ((w_in, h_in), _) = print_size(&svg);
        assert!((w_in - size.width_in).abs() < 0.01 && (h_in - size.height_in).abs() < 0.01);
        let pdf = std::fs::read(svg_path.with_extension("pdf")).unwrap();
        let (pw, ph) = crate::report::svg::tests::pdf_page_pt(&pdf);
        assert!((pw - width_pt).abs() < 0.5, "PDF page {pw} pt wide");
        assert!(
            (ph - 72.0 * size.height_in).abs() < 0.5,
            "PDF page {ph} pt high"
        );
        let texts = text_sizes_pt(&svg);
        assert!(texts.len() > 10);
        for (text, pt, _) in &texts {
            assert!((7.99..=9.01).contains(pt), "{text:?} at {pt:.2} pt");
        }
        let digits: Vec<_> = texts
            .iter()
            .filter(|(t, _, _)| !t.is_empty() && t.chars().all(|c| c.is_ascii_digit()))
            .collect();
        assert!(!digits.is_empty());
        for (t, pt, ink) in digits {
            assert!(
                (ink / pt - 0.73).abs() < 0.03,
                "{t:?}: ink {ink:.2} pt at {pt:.2} pt"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A plot whose legend does not fit three rows in one column is drawn across the page.
#[test]
fn default_size_follows_the_legend() {
    assert_eq!(
        default_size(&example(), &PlotOptions::default()).width_in,
        3.5
    );
    let mut many = example();
    for k in 0..6 {
        let mut s = many.series[1].clone();
        s.label = format!("a long series label number {k} of many");
        many.series.push(s);
    }
    let size = default_size(&many, &PlotOptions::default());
    assert_eq!(size.width_in, 7.2);
    assert!(size.height_in > FigureSize::DOUBLE.height_in);
}

/// The shape of the marker series `i` draws.
fn marker_shape(i: usize) -> &'static str {
    let svg = render_svg(
        &LinePlot {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            series: (0..=i)
                .map(|k| Series {
                    label: String::new(),
                    x: vec![k as f64],
                    y: vec![0.0],
                    y_err: None,
                })
                .collect(),
            log_x: false,
        },
        504,
        374,
    )
    .unwrap();
    // The last element drawn is series i's marker.
    let body = &svg[..svg.rfind("</svg>").unwrap()];
    let tag = &body[body.rfind('<').unwrap()..];
    let name = tag[1..].split([' ', '/', '>']).next().unwrap();
    match (name, tag.contains(r#"fill="none""#)) {
        ("circle", false) => "disc",
        ("circle", true) => "ring",
        ("polygon", _) if tag.matches(',').count() == 3 => "triangle",
        ("polygon", _) => "diamond",
        ("rect", _) => "square",
        ("line" | "polyline" | "path", _) => "cross",
        _ => panic!("unknown marker {tag}"),
    }
}

/// Curves that lie on each other stay apart: each of the first six series has a marker
/// shape of its own, and on two identical 40-point curves both colours' markers show
/// (markers alternate along the curves).
#[test]
fn series_get_distinct_markers() {
    let shapes: Vec<&str> = (0..MARKERS).map(marker_shape).collect();
    let mut unique = shapes.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), MARKERS, "{shapes:?}");
    let x: Vec<f64> = (0..40).map(f64::from).collect();
    let y: Vec<f64> = x.iter().map(|v| (v / 6.0).sin()).collect();
    let same = |label: &str| Series {
        label: label.into(),
        x: x.clone(),
        y: y.clone(),
        y_err: None,
    };
    let plot = LinePlot {
        title: String::new(),
        x_label: "x".into(),
        y_label: "y".into(),
        series: vec![same("first"), same("second")],
        log_x: false,
    };
    let svg = render_svg(&plot, 504, 374).unwrap();
    let (_, _, rgb) = crate::report::svg::print_to_rgb(&svg).unwrap();
    let count = |c: RGBColor| {
        rgb.chunks_exact(3)
            .filter(|p| *p == [c.0, c.1, c.2])
            .count()
    };
    // The second curve's line covers the first's, but the first's markers show between the
    // second's.
    assert!(
        count(PALETTE[0]) > 400,
        "first curve hidden: {}",
        count(PALETTE[0])
    );
    assert!(count(PALETTE[1]) > 400);
}

/// A filled area is drawn behind the curves with its scale on the right and an entry in
/// the legend; a wrong-length area is an input error naming it.
#[test]
fn areas_are_shaded_behind_the_curves() {
    let x: Vec<f64> = (0..50).map(|k| 400.0 + 14.0 * f64::from(k)).collect();
    let opts = PlotOptions {
        size: None,
        areas: vec![Area {
            label: "lamp spectrum".into(),
            x: x.clone(),
            y: x.iter()
                .map(|l| (-((l - 800.0) / 200.0).powi(2)).exp())
                .collect(),
        }],
        area_label: "relative spectrum".into(),
        ..PlotOptions::default()
    };
    let mut plot = example();
    plot.log_x = false;
    plot.series.truncate(1);
    plot.series[0].x = vec![450.0, 700.0, 1000.0];
    plot.series[0].y = vec![0.2, 0.5, 0.3];
    plot.series[0].y_err = None;
    let svg = render_svg_with(&plot, &opts, 504, 374).unwrap();
    for text in ["relative spectrum", "lamp spectrum", "0.5", "1"] {
        assert!(svg.contains(&format!(r#"aria-label="{text}""#)), "{text}");
    }
    let plain = render_svg(&plot, 504, 374).unwrap();
    let tinted = |svg: &str| {
        let (_, _, rgb) = crate::report::svg::print_to_rgb(svg).unwrap();
        // The orange tint over white: red high, blue well below it.
        rgb.chunks_exact(3)
            .filter(|p| p[0] > 240 && p[1] > 200 && p[1] < 240 && p[2] < 210)
            .count()
    };
    assert!(tinted(&svg) > 20_000, "{}", tinted(&svg));
    assert_eq!(tinted(&plain), 0);
    let mut bad = opts.clone();
    bad.areas[0].y.pop();
    let dir = std::env::temp_dir();
    let e = write_plot_with(
        &plot,
        &bad,
        &dir.join("spibench-area-bad.svg"),
        &dir.join("spibench-area-bad.png"),
    )
    .unwrap_err();
    assert!(
        e.is_user_error() && e.to_string().contains("areas[0].y"),
        "{e}"
    );
}

/// A label rendered inside a plot has the width the font's advances give it and no gap
/// inside a word (the bitmap backend's "bal ancing" / "0.3 85").
#[test]
fn rendered_label_matches_the_reference_rendering() {
    let label = "balancing";
    let plot = LinePlot {
        title: String::new(),
        x_label: label.into(),
        y_label: String::new(),
        series: vec![Series {
            label: String::new(),
            x: vec![0.0, 1.0],
            y: vec![0.0, 1.0],
            y_err: None,
        }],
        log_x: false,
    };
    let svg = render_svg(&plot, 640, 400).unwrap();
    let (w, h, rgb) = crate::report::svg::print_to_rgb(&svg).unwrap();
    // The x-axis description sits in the bottom BAND px, alone on its rows (2 px per unit).
    const BAND: u32 = 64;
    let band: Vec<u8> = rgb[(w * (h - BAND) * 3) as usize..].to_vec();
    let cols = crate::report::svg::tests::ink_columns(w, BAND, &band);
    let ink =
        (cols.iter().rposition(|&c| c).unwrap() - cols.iter().position(|&c| c).unwrap() + 1) as f64;
    // plotters writes font-size = size / 1.24 into the SVG; the PNG has 2 px per unit.
    let px = 2.0 * AXIS_DESC_SIZE / 1.24;
    let advance = crate::report::svg::tests::advance_px(label, px);
    assert!(
        ink <= advance + 1.0 && ink > advance - 0.2 * px,
        "ink {ink} px against advances {advance:.1} px"
    );
    let gap = crate::report::svg::tests::widest_inner_gap(&cols) as f64;
    assert!(gap < 0.3 * px, "a {gap} px gap inside {label:?}");
    // And the same label outlined alone, at the same place, gives the same pixels.
    let axis_text = svg
        .split("</path>")
        .find(|t| t.contains(&format!(r#"aria-label="{label}""#)))
        .map(|t| format!("{}</path>", &t[t.rfind("<path").unwrap()..]))
        .unwrap();
    let root = &svg[..svg.find('>').unwrap() + 1];
    let reference = format!("{root}{axis_text}</svg>");
    let (_, _, ref_rgb) = crate::report::svg::print_to_rgb(&reference).unwrap();
    let ref_band = &ref_rgb[(w * (h - BAND) * 3) as usize..];
    assert!(
        band == ref_band,
        "the label differs from its reference rendering"
    );
}

#[test]
fn bad_series_are_input_errors() {
    let dir = std::env::temp_dir();
    let svg = dir.join("spibench-plot-bad.svg");
    let png = dir.join("spibench-plot-bad.png");
    let mut p = example();
    p.series[1].y.pop();
    let e = write_plot(&p, &svg, &png).unwrap_err();
    assert!(
        e.is_user_error() && e.to_string().contains("series[1].y"),
        "{e}"
    );
    let mut p = example();
    p.series[0].y_err = Some(vec![-1.0; 6]);
    assert!(write_plot(&p, &svg, &png).unwrap_err().is_user_error());
    let mut p = example();
    for s in &mut p.series {
        s.x = vec![-1.0; s.x.len()];
    }
    // Only x ≤ 0 on a log axis: nothing to draw.
    assert!(write_plot(&p, &svg, &png).unwrap_err().is_user_error());
    assert!(!svg.exists() && !png.exists());
}

/// Three panels, one line each (no markers), shaded settled windows, values in mV, the
/// frames numbered from 1, at the page's width.
#[test]
fn scope_has_a_panel_per_channel() {
    let t_us: Vec<f64> = (0..300).map(|i| i as f64 * 0.1).collect();
    let sq = |a: f64| {
        t_us.iter()
            .map(|t| a * ((t / 10.0).floor() % 2.0))
            .collect()
    };
    let p = ScopePlot {
        channels: vec![
            ("RF".into(), sq(0.25)),
            ("MONITOR+".into(), sq(0.5)),
            ("MONITOR−".into(), sq(-0.5)),
        ],
        t_us,
        frame_us: 10.0,
        settling_us: 2.0,
    };
    let svg = scope_svg(&p).unwrap();
    for name in ["RF (mV)", "MONITOR+ (mV)", "MONITOR− (mV)", "time (µs)"] {
        assert!(svg.contains(name), "{name}");
    }
    assert!(!svg.contains("(V)"));
    assert_eq!(svg.matches("time (µs)").count(), 1, "one shared time axis");
    assert!(!svg.contains("<circle"), "samples are a line, not markers");
    // 0.25 V is drawn as 250 mV: the RF panel has a tick at 250.
    assert!(svg.contains(r#"aria-label="250""#));
    // Frames 1, 2 and 3 (the window holds 0 to 29.9 µs) are numbered above the panels.
    for f in ["frame", "1", "2", "3"] {
        assert!(
            svg.contains(&format!(r#"aria-label="{f}""#)),
            "frame label {f}"
        );
    }
    let ((w_in, _), (w, h)) = print_size(&svg);
    assert!((w_in - 7.2).abs() < 0.01);
    assert_eq!(
        (w as u32, h as u32),
        (
            SCOPE_WIDTH_PX,
            3 * SCOPE_PANEL_PX + SCOPE_AXIS_PX + SCOPE_FRAMES_PX
        )
    );
    for (text, pt, _) in text_sizes_pt(&svg) {
        assert!((7.99..=9.01).contains(&pt), "{text:?} at {pt:.2} pt");
    }
    // Narrow frames: numbers thin out to every 2nd, 5th, 10th … frame.
    assert_eq!(frame_label_step(200.0, 3), 1);
    assert!(frame_label_step(4.0, 500) >= 10);
}

#[test]
fn tick_text() {
    assert_eq!(format_tick(0.30000000000000004), "0.3");
    assert_eq!(format_tick(-0.0), "0");
    assert_eq!(format_tick(25.0), "25");
    assert_eq!(format_tick(1234.5), "1234.5");
    assert_eq!(format_tick(0.00025), "2.5e-4");
    assert_eq!(format_tick(3.0e6), "3e6");
    assert_eq!(format_tick(-0.125), "-0.125");
    let decades = [1e3, 1e4, 1e5, 1e6];
    assert_eq!(tick_style(&decades), TickStyle::PowerOfTen);
    let t: Vec<String> = decades
        .iter()
        .map(|&v| format_styled(v, TickStyle::PowerOfTen))
        .collect();
    assert_eq!(t, ["10³", "10⁴", "10⁵", "10⁶"]);
    assert_eq!(format_styled(1e-3, TickStyle::PowerOfTen), "10⁻³");
    let mixed = [0.0, 5e4, 1e5, 1.5e5];
    assert_eq!(tick_style(&mixed), TickStyle::Scientific);
    let t: Vec<String> = mixed
        .iter()
        .map(|&v| format_styled(v, TickStyle::Scientific))
        .collect();
    assert_eq!(t, ["0", "5e4", "1e5", "1.5e5"]);
    assert_eq!(tick_style(&[0.0, 0.5, 1.0]), TickStyle::Plain);
}

#[test]
fn ticks_are_nice_and_inside() {
    assert_eq!(linear_ticks(0.0, 10.0), vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
    assert_eq!(linear_ticks(-0.13, 0.31).len(), 5); // step 0.1: -0.1 … 0.3
    let t: Vec<String> = log_ticks(0.008, 0.6)
        .iter()
        .map(|v| format_tick(*v))
        .collect();
    assert_eq!(t, ["0.01", "0.02", "0.05", "0.1", "0.2", "0.5"]);
    let t = log_ticks(1.0, 1e12);
    assert_eq!(t.len(), 7); // every second decade: 1, 1e2, …, 1e12
    assert!(log_ticks(0.3, 0.45).len() >= 2);
}
