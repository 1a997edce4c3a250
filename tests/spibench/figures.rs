//! Figures for a paper, read back from the files the commands write: every figure of `trace`
//! (per-unit maps, the collection figure of a diffractive bench) and of `layout` comes as SVG,
//! PNG and PDF, as the README says; each is one journal column (3.5 in) or the page's width
//! (7.2 in), on the PDF page and in the SVG; its text is 8 to 9 pt at that size; the PNG is the
//! SVG at 288 dpi.

use std::path::{Path, PathBuf};

use crate::common::{TempDir, spibench, stderr};

/// The page size (width, height in points) of a one-page PDF: its `/MediaBox`.
fn pdf_page_pt(pdf: &[u8]) -> (f64, f64) {
    let text = String::from_utf8_lossy(pdf);
    let at = text.find("/MediaBox").expect("a MediaBox") + "/MediaBox".len();
    let inside = &text[at..];
    let (open, close) = (inside.find('[').unwrap(), inside.find(']').unwrap());
    let v: Vec<f64> = inside[open + 1..close]
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect();
    (v[2] - v[0], v[3] - v[1])
}

/// What one written figure states about its size: (width in inches from the SVG, the PDF
/// page's width in points, the PNG's width in pixels, the viewBox width, the text sizes in pt).
struct Measured {
    svg_width_in: f64,
    pdf_width_pt: f64,
    png_width_px: u32,
    view_box_width: f64,
    text_pt: Vec<(String, f64)>,
}

fn measure(svg_path: &Path) -> Measured {
    let text = std::fs::read_to_string(svg_path).unwrap();
    let doc = roxmltree::Document::parse(&text).expect("well-formed SVG");
    let root = doc.root_element();
    let width = root.attribute("width").unwrap();
    let svg_width_in: f64 = width
        .strip_suffix("in")
        .unwrap_or_else(|| panic!("{}: width {width:?} not in inches", svg_path.display()))
        .parse()
        .unwrap();
    let view_box_width: f64 = root
        .attribute("viewBox")
        .unwrap()
        .split(' ')
        .nth(2)
        .unwrap()
        .parse()
        .unwrap();
    let pt_per_unit = svg_width_in * 72.0 / view_box_width;
    let text_pt = doc
        .descendants()
        .filter_map(|n| Some((n.attribute("aria-label")?, n.attribute("font-size")?)))
        .map(|(t, s)| (t.to_string(), s.parse::<f64>().unwrap() * pt_per_unit))
        .collect();
    let pdf = std::fs::read(svg_path.with_extension("pdf"))
        .unwrap_or_else(|_| panic!("no PDF beside {}", svg_path.display()));
    let png = image::open(svg_path.with_extension("png"))
        .unwrap_or_else(|_| panic!("no PNG beside {}", svg_path.display()));
    Measured {
        svg_width_in,
        pdf_width_pt: pdf_page_pt(&pdf).0,
        png_width_px: png.width(),
        view_box_width,
        text_pt,
    }
}

/// Checks every figure (SVG) of a folder: PNG and PDF beside it, a column's or the page's
/// width in the SVG, on the PDF page and at 288 dpi in the PNG, text 8–9 pt. Returns the
/// figures' stems and widths (in).
fn check_figures(dir: &Path) -> Vec<(String, f64)> {
    let mut svgs: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "svg"))
        .collect();
    svgs.sort();
    assert!(!svgs.is_empty(), "no figure in {}", dir.display());
    let mut out = Vec::new();
    for svg in svgs {
        let name = svg.file_stem().unwrap().to_string_lossy().to_string();
        let m = measure(&svg);
        let column = [3.5, 7.2]
            .into_iter()
            .find(|w| (m.svg_width_in - w).abs() < 0.01);
        assert!(column.is_some(), "{name}: {} in wide", m.svg_width_in);
        assert!(
            (m.pdf_width_pt - 72.0 * m.svg_width_in).abs() < 0.5,
            "{name}: PDF page {} pt for a {} in figure",
            m.pdf_width_pt,
            m.svg_width_in
        );
        assert_eq!(
            f64::from(m.png_width_px),
            (2.0 * m.view_box_width).round(),
            "{name}: PNG not at 288 dpi"
        );
        assert!(m.text_pt.len() > 5, "{name}: {} texts", m.text_pt.len());
        for (t, pt) in &m.text_pt {
            assert!((7.99..=9.01).contains(pt), "{name}: {t:?} at {pt:.2} pt");
        }
        out.push((name, m.svg_width_in));
    }
    out
}

/// `trace` on a bench with the diffractive DMD: the five per-unit maps and the collection
/// figure, each as SVG, PNG and PDF at print size; the maps have axes and a colour bar; the
/// collection figure shades the lamp's light and the responsivity.
#[test]
fn trace_writes_print_size_figures_with_pdfs() {
    let tmp = TempDir::new("figures-trace");
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron");
    let text = std::fs::read_to_string(&src)
        .unwrap()
        .replace("model: Geometric,", "model: Diffractive(),");
    assert!(text.contains("Diffractive"));
    let scene = tmp.join("bench.ron");
    std::fs::write(&scene, text).unwrap();
    let out = tmp.join("out");
    let o = spibench(
        &[
            "trace",
            scene.to_str().unwrap(),
            "--rays",
            "20000",
            "--seed",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let figures = check_figures(&out);
    let stems: Vec<&str> = figures.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        stems,
        [
            "collection",
            "g_minus",
            "g_plus",
            "irradiance_minus",
            "irradiance_plus",
            "k_minus",
            "k_plus",
            "x"
        ]
    );
    // The maps are single-column figures with axes and a colour bar: the per-unit maps in
    // units, the irradiance maps in mm on the diode's plane.
    for (name, w) in &figures[1..] {
        assert_eq!(*w, 3.5, "{name}");
        let svg = std::fs::read_to_string(out.join(format!("{name}.svg"))).unwrap();
        let parts = match name.strip_prefix("irradiance_") {
            Some(arm) => vec![
                format!(r#"aria-label="u on pd_{arm} (mm)""#),
                r#"aria-label="v (mm)""#.to_string(),
                format!(
                    r#"aria-label="irradiance, all units {} (W/m²)""#,
                    if arm == "plus" { "+" } else { "−" }
                ),
            ],
            None => vec![
                r#"aria-label="unit column""#.to_string(),
                r#"aria-label="unit row (0 = top)""#.to_string(),
                r#"class="colour-bar""#.to_string(),
            ],
        };
        for part in parts {
            assert!(svg.contains(&part), "{name}: {part}");
        }
    }
    let svg = std::fs::read_to_string(out.join("collection.svg")).unwrap();
    for label in ["lamp light on the pattern", "relative (peak = 1)"] {
        assert!(svg.contains(&format!(r#"aria-label="{label}""#)), "{label}");
    }
    // summary.json lists every file written.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let listed: Vec<&str> = summary["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    for (name, _) in &figures {
        for ext in ["svg", "png", "pdf"] {
            let f = format!("{name}.{ext}");
            assert!(listed.contains(&f.as_str()), "{f} not listed");
        }
    }
}

/// `layout`: one 7.2 in figure as SVG, PNG and PDF, each element named in it.
#[test]
fn layout_is_a_page_wide_figure_with_labelled_elements() {
    let tmp = TempDir::new("figures-layout");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let out = tmp.join("out");
    let o = spibench(
        &[
            "layout",
            scene.to_str().unwrap(),
            "--rays",
            "100",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let figures = check_figures(&out);
    assert_eq!(figures.len(), 1);
    assert_eq!(figures[0].0, "layout");
    // 1037 units of half a point: 7.2 in to a hundredth.
    assert!((figures[0].1 - 7.2).abs() < 0.01, "{figures:?}");
    let bench = spibench::scene::bench::read_bench(&scene).unwrap();
    let svg = std::fs::read_to_string(out.join("layout.svg")).unwrap();
    for o in spibench::optics::outline::element_outlines(&bench) {
        assert!(
            svg.contains(&format!(r#"aria-label="{}""#, o.name)),
            "{} not labelled",
            o.name
        );
    }
}

/// The README's sentence on figures says what the commands write: SVG, PNG and PDF for every
/// figure but the montage, at a column's or the page's width.
#[test]
fn readme_states_the_figure_formats() {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let flat = readme.split_whitespace().collect::<Vec<_>>().join(" ");
    for claim in [
        "Every figure is an SVG with its PNG rendering at 288 dpi and a PDF",
        "3.5 in",
        "7.2 in",
        "8–9 pt",
    ] {
        assert!(flat.contains(claim), "README lacks {claim:?}");
    }
}
