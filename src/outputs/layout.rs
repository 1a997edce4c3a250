//! The bench drawn like a lens designer's 2-D layout: three orthographic views (top, side and
//! the plane of the two arms) of every element's outline and a fan of traced rays coloured by
//! fate, as SVG text built by hand ([`layout_svg`]) and rendered to PNG by resvg with the
//! embedded DejaVu Sans ([`svg_to_png`]), so the PNG is the SVG.
//!
//! The views (bench frame: +z is the DMD normal, pointing up toward the illumination, which
//! comes down the z axis):
//! - top: seen from +z, x to the right, y up;
//! - side: seen from −y, x to the right, z up;
//! - arms: the plane through the pattern centre spanned by the two outgoing chief rays (the
//!   reflections of the incoming chief ray by mirrors in state + and −, traced from the bench,
//!   `trace::fan::dmd_axes`); horizontal = the direction from arm − to arm +, vertical = their
//!   bisector (away from the DMD). The incoming axis lies in this plane too (both mirror normals
//!   lie in the plane perpendicular to the hinge), so it shows the whole unfolded path.
//!
//! Points off a view's plane are projected orthogonally onto it. All views share one scale.
//!
//! `spibench layout` writes the drawing alone ([`figure`], [`write_figure`]); the reports of `run`, `sweep`
//! and `align` embed it ([`layout_block`]).

use std::fmt::Write as _;

use glam::DVec3;

use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::optics::dmd::MirrorState;
use crate::optics::outline::{ElementKind, element_outlines};
use crate::trace::TraceOptions;
use crate::trace::fan::{DESIGN_WAVELENGTH_M, DmdAxes, Fate, RayFan, chief_ray, dmd_axes};
use crate::trace::irradiance::{DEFAULT_BINS, IrradianceMaps, index, trace_with_maps};
use crate::transport::Estimate;

/// One orthographic view: 2-D coordinates (p·e1, p·e2).
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// `top`, `side` or `arms` (the SVG group's id is `view-KEY`).
    pub key: &'static str,
    pub title: String,
    pub e1: DVec3,
    pub e2: DVec3,
    /// Names of the horizontal and vertical directions.
    pub labels: (String, String),
}

impl View {
    fn project(&self, p: DVec3) -> (f64, f64) {
        (p.dot(self.e1), p.dot(self.e2))
    }
}

/// The three views of a bench with a DMD whose chief ray reaches it.
pub fn views(axes: &DmdAxes) -> [View; 3] {
    let [plus, minus] = axes.outgoing;
    let e1 = (plus - minus).normalize();
    let e2 = (plus + minus).normalize();
    [
        View {
            key: "top",
            title: "top view (from +z)".into(),
            e1: DVec3::X,
            e2: DVec3::Y,
            labels: ("x".into(), "y".into()),
        },
        View {
            key: "side",
            title: "side view (from −y)".into(),
            e1: DVec3::X,
            e2: DVec3::Z,
            labels: ("x".into(), "z".into()),
        },
        View {
            key: "arms",
            title: "plane of the two arms".into(),
            e1,
            e2,
            labels: ("arm − → arm +".into(), "away from the DMD".into()),
        },
    ]
}

/// The colour of a fate: detected + blue, detected − orange, absorbed grey, escaped light red,
/// the interaction cap purple.
pub fn fate_colour(f: Fate) -> &'static str {
    match f {
        Fate::DetectedPlus => "#1f5fbf",
        Fate::DetectedMinus => "#f07f0a",
        Fate::Absorbed => "#9a9a9a",
        Fate::Escaped => "#f2a0a0",
        Fate::PathCap => "#8e44ad",
    }
}

/// Drawing order: the stray and absorbed light first, the detected beams on top.
const DRAW_ORDER: [Fate; 5] = [
    Fate::Absorbed,
    Fate::Escaped,
    Fate::PathCap,
    Fate::DetectedMinus,
    Fate::DetectedPlus,
];

/// The drawing's width: the page's (7.2 in at 144 SVG units per inch, half points; see
/// `report::svg`), and the tallest the views may be drawn.
const TOTAL_WIDTH: f64 = 1037.0;
const MAX_DRAW_HEIGHT: f64 = 1150.0;
const MARGIN: f64 = 14.0;
/// Above the views: the title (9 pt) and a note line (8 pt).
const HEAD_BAND: f64 = 60.0;
/// Above each view its name; below it the scale bar and the axis names.
const VIEW_TITLE: f64 = 24.0;
const VIEW_FOOT: f64 = 52.0;
/// The top view is drawn at least this high (SVG units), so that a flat bench stays legible
/// at the common scale: the view is centred in it.
const MIN_VIEW_HEIGHT: f64 = 120.0;
/// Text sizes (SVG units: 18 = 9 pt, 16 = 8 pt).
const TITLE_FONT: f64 = 18.0;
const TEXT_FONT: f64 = 16.0;

/// 1, 2 or 5 × 10^k, the largest not above `x` (x > 0).
fn nice_below(x: f64) -> f64 {
    let p = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * p)
        .find(|v| *v <= x)
        .unwrap_or(p)
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The width of `text` at `font` SVG units, from the embedded font's advances.
fn text_width(text: &str, font: f64) -> f64 {
    #[cfg(feature = "figures")]
    {
        f64::from(crate::report::font::text_width(text, font * 1.24))
    }
    #[cfg(not(feature = "figures"))]
    {
        0.6 * font * text.chars().count() as f64
    }
}

/// A view's data extent (m): ((min e1, min e2), (max e1, max e2)).
type Extent = ((f64, f64), (f64, f64));

/// Where a view is drawn: its panel (SVG units) and the data point at the panel's top-left.
#[derive(Debug, Clone, Copy)]
struct Panel {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
    /// Data coordinates (m) shown at the panel's left edge and top edge.
    left_m: f64,
    top_m: f64,
}

/// Width kept right of the arm-plane view for the elements' names.
const LABEL_COLUMN: f64 = 170.0;

/// The views laid out at one scale (SVG units per metre), whichever of two arrangements draws
/// them larger within the page's width and [`MAX_DRAW_HEIGHT`]: the three side by side (side,
/// top, arm plane; for tall benches), or the side view with the top view under it, sharing its
/// x range and aligned with it as in an engineering drawing, and the arm plane beside them (for
/// flat ones). The arm plane is always rightmost, with the names' column after it. Returns the
/// panels (in `views` order: top, side, arms), the scale and the drawing's height.
fn arrange(ext: &[Extent; 3]) -> ([Panel; 3], f64, f64) {
    let (top, side, arms) = (ext[0], ext[1], ext[2]);
    let w = |e: &Extent| e.1.0 - e.0.0;
    let h = |e: &Extent| e.1.1 - e.0.1;
    let bands = VIEW_TITLE + VIEW_FOOT;
    let avail_w = TOTAL_WIDTH - 4.0 * MARGIN - LABEL_COLUMN;
    let fit = |k0: f64, height: &dyn Fn(f64) -> f64| {
        let mut k = k0;
        while height(k) > MAX_DRAW_HEIGHT && k > 1e-6 {
            k *= 0.97;
        }
        k
    };
    // Side by side.
    let row_h = |k: f64| {
        (h(&side) * k)
            .max((h(&top) * k).max(MIN_VIEW_HEIGHT))
            .max(h(&arms) * k)
            + bands
    };
    let k_row = fit(avail_w / (w(&side) + w(&top) + w(&arms)), &row_h);
    // Side over top, sharing x.
    let xa = (top.0.0.min(side.0.0), top.1.0.max(side.1.0));
    let col_h = |k: f64| {
        let a = h(&side) * k + (h(&top) * k).max(MIN_VIEW_HEIGHT) + 2.0 * bands;
        a.max(h(&arms) * k + bands)
    };
    let k_col = fit((avail_w + MARGIN) / (xa.1 - xa.0 + w(&arms)), &col_h);
    let y0 = HEAD_BAND + VIEW_TITLE;
    // `min_h`: the top view's minimum height, 0 for the others.
    let panel =
        |(x, y): (f64, f64), e: &Extent, k: f64, (left_m, width_m): (f64, f64), min_h: f64| {
            let ph = (h(e) * k).max(min_h);
            Panel {
                x,
                y,
                w: width_m * k,
                h: ph,
                left_m,
                // A short view is centred in its panel.
                top_m: e.1.1 + 0.5 * (ph / k - h(e)),
            }
        };
    if k_row >= k_col {
        let k = k_row;
        let side_p = panel((MARGIN, y0), &side, k, (side.0.0, w(&side)), 0.0);
        let top_x = side_p.x + side_p.w + MARGIN;
        let top_p = panel((top_x, y0), &top, k, (top.0.0, w(&top)), MIN_VIEW_HEIGHT);
        let arms_x = top_p.x + top_p.w + MARGIN;
        let arms_p = panel((arms_x, y0), &arms, k, (arms.0.0, w(&arms)), 0.0);
        ([top_p, side_p, arms_p], k, HEAD_BAND + row_h(k))
    } else {
        let k = k_col;
        let shared = (xa.0, xa.1 - xa.0);
        let side_p = panel((MARGIN, y0), &side, k, shared, 0.0);
        let top_y = y0 + side_p.h + bands;
        let top_p = panel((MARGIN, top_y), &top, k, shared, MIN_VIEW_HEIGHT);
        let arms_x = side_p.x + side_p.w + MARGIN;
        let arms_p = panel((arms_x, y0), &arms, k, (arms.0.0, w(&arms)), 0.0);
        ([top_p, side_p, arms_p], k, HEAD_BAND + col_h(k))
    }
}

/// The SVG of the bench's layout with a traced ray fan (see the module notes), 7.2 in wide
/// (the page's width) with 8–9 pt text. `title` heads the drawing (e.g. the bench file's name).
/// Fails (bad input) when the bench has no DMD or the chief ray from the lamp does not reach
/// it, since the arm plane needs both.
pub fn layout_svg(bench: &Bench, fan: &RayFan, title: &str) -> Result<String> {
    layout_svg_with(bench, fan, title, None)
}

/// [`layout_svg`] with, when `insets` are given, each diode's irradiance map drawn as an inset
/// in a band under the views ([`Insets`]).
pub fn layout_svg_with(
    bench: &Bench,
    fan: &RayFan,
    title: &str,
    insets: Option<&Insets>,
) -> Result<String> {
    let axes = dmd_axes(bench, DESIGN_WAVELENGTH_M)
        .map_err(|m| Error::field("dmd", format!("cannot draw the arm plane: {m}")))?;
    let views = views(&axes);
    let outlines = element_outlines(bench);
    let lamp = &bench.lamp().frame;
    let chiefs: Vec<Vec<DVec3>> = [MirrorState::Plus, MirrorState::Minus]
        .into_iter()
        .map(|s| chief_ray(bench, lamp.origin, lamp.w, DESIGN_WAVELENGTH_M, s).points)
        .collect();

    // Extents of every view over outlines and rays (m), then one scale for all.
    let ext: [Extent; 3] = std::array::from_fn(|k| {
        let v = &views[k];
        let mut lo = (f64::INFINITY, f64::INFINITY);
        let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        let all = outlines
            .iter()
            .flat_map(|o| o.polylines.iter().flatten())
            .chain(fan.rays.iter().flat_map(|r| r.points.iter()));
        for p in all {
            let (a, b) = v.project(*p);
            lo = (lo.0.min(a), lo.1.min(b));
            hi = (hi.0.max(a), hi.1.max(b));
        }
        // A 4 % border, and at least 10 mm across.
        let pad = 0.04 * (hi.0 - lo.0).max(hi.1 - lo.1).max(0.01);
        ((lo.0 - pad, lo.1 - pad), (hi.0 + pad, hi.1 + pad))
    });
    let (panels, scale, draw_h) = arrange(&ext);
    let legend_rows = legend_lines(fan);
    let total_w = TOTAL_WIDTH;
    let band_h = insets.map_or(0.0, |_| inset_band_height());
    let total_h = (draw_h + band_h + MARGIN + 22.0 * legend_rows.len() as f64 + 24.0).ceil();

    let mut s = String::new();
    let _ = writeln!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{total_w:.0}" height="{total_h:.0}" viewBox="0 0 {total_w:.0} {total_h:.0}" font-family="DejaVu Sans, sans-serif">"##
    );
    let _ = writeln!(s, r##"<rect width="100%" height="100%" fill="#ffffff"/>"##);
    let _ = writeln!(
        s,
        r##"<text x="{MARGIN}" y="{y:.1}" font-size="{TITLE_FONT}">{t}</text>"##,
        y = MARGIN + TITLE_FONT,
        t = escape(title)
    );
    let _ = writeln!(
        s,
        r##"<text x="{MARGIN}" y="{y:.1}" font-size="{TEXT_FONT}" fill="#444">{n} lamp rays (seed {seed}): half with every pattern unit in state +, half in state −; dashed: chief rays at {wl:.0} nm</text>"##,
        y = MARGIN + TITLE_FONT + 22.0,
        n = fan.rays.len(),
        seed = fan.seed,
        wl = DESIGN_WAVELENGTH_M * 1e9
    );
    for (k, v) in views.iter().enumerate() {
        let labels = v.key == "arms";
        draw_view(
            &mut s, v, &panels[k], scale, fan, &outlines, &chiefs, labels,
        );
    }
    if let Some(ins) = insets {
        let (arms, p) = (&views[2], &panels[2]);
        // Where each diode's centre is drawn in the arm plane, for the inset's leader line.
        let at = |d: usize| {
            let (a, b) = arms.project(bench.detectors()[d].frame.origin);
            (p.x + (a - p.left_m) * scale, p.y + (p.top_m - b) * scale)
        };
        draw_insets(&mut s, ins, draw_h + MARGIN, [at(0), at(1)])?;
    }
    draw_legend(&mut s, &legend_rows, draw_h + band_h + MARGIN);
    let _ = writeln!(s, "</svg>");
    Ok(s)
}

/// Draws one view in its panel: the rays by fate, the element outlines, the chief rays, the
/// scale bar and the axis names; with `labels`, each element's name beside it.
#[allow(clippy::too_many_arguments)]
fn draw_view(
    s: &mut String,
    v: &View,
    p: &Panel,
    scale: f64,
    fan: &RayFan,
    outlines: &[crate::optics::outline::ElementOutline],
    chiefs: &[Vec<DVec3>],
    labels: bool,
) {
    let px = |q: DVec3| {
        let (a, b) = v.project(q);
        (p.x + (a - p.left_m) * scale, p.y + (p.top_m - b) * scale)
    };
    let path_of = |lines: &mut dyn Iterator<Item = &Vec<DVec3>>| {
        let mut d = String::new();
        for line in lines {
            for (i, q) in line.iter().enumerate() {
                let (x, y) = px(*q);
                let _ = write!(d, "{}{x:.2} {y:.2}", if i == 0 { "M" } else { " L" });
            }
        }
        d
    };
    let _ = writeln!(s, r##"<g class="view" id="view-{}">"##, v.key);
    let _ = writeln!(
        s,
        r##"<clipPath id="clip-{key}"><rect x="{x:.2}" y="{y:.2}" width="{w:.2}" height="{h:.2}"/></clipPath>"##,
        key = v.key,
        x = p.x,
        y = p.y,
        w = p.w,
        h = p.h
    );
    let _ = writeln!(
        s,
        r##"<text x="{x:.2}" y="{y:.2}" font-size="{TITLE_FONT}">{t}</text>"##,
        x = p.x,
        y = p.y - 7.0,
        t = escape(&v.title)
    );
    let _ = writeln!(
        s,
        r##"<rect x="{x:.2}" y="{y:.2}" width="{w:.2}" height="{h:.2}" fill="none" stroke="#cccccc"/>"##,
        x = p.x,
        y = p.y,
        w = p.w,
        h = p.h
    );
    let _ = writeln!(s, r##"<g clip-path="url(#clip-{})">"##, v.key);
    for fate in DRAW_ORDER {
        for r in fan.rays.iter().filter(|r| r.fate == fate) {
            let d = path_of(&mut std::iter::once(&r.points));
            let _ = writeln!(
                s,
                r##"<path class="ray {c}" d="{d}" fill="none" stroke="{col}" stroke-width="0.7" stroke-opacity="0.6"/>"##,
                c = fate.key(),
                col = fate_colour(fate)
            );
        }
    }
    for o in outlines {
        let strong = matches!(o.kind, ElementKind::Dmd | ElementKind::Photodiode);
        let d = path_of(&mut o.polylines.iter());
        let _ = writeln!(
            s,
            r##"<path class="element {kind}" d="{d}" fill="none" stroke="{col}" stroke-width="{sw}"><title>{name} ({kn})</title></path>"##,
            kind = o.kind.name().to_lowercase(),
            col = if strong { "#000000" } else { "#555555" },
            sw = if strong { 1.6 } else { 1.1 },
            name = escape(&o.name),
            kn = o.kind.name()
        );
    }
    for c in chiefs {
        let d = path_of(&mut std::iter::once(c));
        let _ = writeln!(
            s,
            r##"<path class="chief" d="{d}" fill="none" stroke="#000000" stroke-width="0.8" stroke-dasharray="6 4"/>"##
        );
    }
    let _ = writeln!(s, "</g>");
    if labels {
        draw_element_labels(s, p, outlines, &px);
    }
    // Scale bar (about a quarter of the panel, at most 100 mm) and the axis names.
    let bar_m = nice_below((0.25 * p.w / scale * 1e3).min(100.0)) * 1e-3;
    let by = p.y + p.h + 16.0;
    let _ = writeln!(
        s,
        r##"<path class="scale-bar" data-mm="{mm}" d="M{a:.3} {by:.2} L{b:.3} {by:.2} M{a:.3} {t:.2} L{a:.3} {u:.2} M{b:.3} {t:.2} L{b:.3} {u:.2}" stroke="#000000" stroke-width="1.5"/>"##,
        mm = bar_m * 1e3,
        a = p.x,
        b = p.x + bar_m * scale,
        t = by - 4.0,
        u = by + 4.0
    );
    let _ = writeln!(
        s,
        r##"<text x="{x:.2}" y="{y:.2}" font-size="{TEXT_FONT}">{mm} mm</text>"##,
        x = p.x + bar_m * scale + 8.0,
        y = by + 5.0,
        mm = bar_m * 1e3
    );
    let _ = writeln!(
        s,
        r##"<text x="{x:.2}" y="{y:.2}" font-size="{TEXT_FONT}" fill="#444">→ {h}, ↑ {v}</text>"##,
        x = p.x,
        y = by + 26.0,
        h = escape(&v.labels.0),
        v = escape(&v.labels.1)
    );
    let _ = writeln!(s, "</g>");
}

/// Each element's name in a column right of the panel, at the height of the element's middle
/// (pushed apart so that names do not overlap), joined to the element's right edge by a thin
/// leader line.
fn draw_element_labels(
    s: &mut String,
    p: &Panel,
    outlines: &[crate::optics::outline::ElementOutline],
    px: &dyn Fn(DVec3) -> (f64, f64),
) {
    let line = TEXT_FONT + 3.0;
    // (anchor x, anchor y, name) of every element with an outline.
    let mut items: Vec<(f64, f64, &str)> = outlines
        .iter()
        .filter_map(|o| {
            let pts: Vec<(f64, f64)> = o.polylines.iter().flatten().map(|q| px(*q)).collect();
            let x_hi = pts.iter().map(|q| q.0).fold(f64::NEG_INFINITY, f64::max);
            let (y_lo, y_hi) = pts
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| {
                    (a.min(q.1), b.max(q.1))
                });
            x_hi.is_finite().then(|| {
                let x = x_hi.clamp(p.x, p.x + p.w);
                (
                    x,
                    (0.5 * (y_lo + y_hi)).clamp(p.y, p.y + p.h),
                    o.name.as_str(),
                )
            })
        })
        .collect();
    items.sort_by(|a, b| a.1.total_cmp(&b.1));
    // Baselines: each at its anchor, at least a line below the previous; then the whole column
    // moved up if it runs past the panel's bottom.
    let mut ys: Vec<f64> = Vec::with_capacity(items.len());
    for it in &items {
        let want = it.1 + 0.35 * TEXT_FONT;
        let y = ys.last().map_or(want, |&prev: &f64| want.max(prev + line));
        ys.push(y);
    }
    let bottom = p.y + p.h + VIEW_FOOT - 8.0;
    if let Some(&last) = ys.last()
        && last > bottom
    {
        let shift = last - bottom;
        for y in &mut ys {
            *y -= shift;
        }
    }
    let x_text = p.x + p.w + 14.0;
    let _ = writeln!(s, r##"<g class="element-labels">"##);
    for ((ax, ay, name), y) in items.iter().zip(&ys) {
        let _ = writeln!(
            s,
            r##"<path d="M{ax:.2} {ay:.2} L{bx:.2} {ay:.2} L{cx:.2} {cy:.2}" stroke="#999999" stroke-width="0.6" fill="none"/><text class="element-label" x="{x_text:.2}" y="{y:.2}" font-size="{TEXT_FONT}" fill="#222">{n}</text>"##,
            bx = p.x + p.w + 2.0,
            cx = x_text - 3.0,
            cy = y - 0.35 * TEXT_FONT,
            n = escape(name)
        );
    }
    let _ = writeln!(s, "</g>");
}

/// The legend's entries (colour, text) in lines that fit the drawing's width.
fn legend_lines(fan: &RayFan) -> Vec<Vec<(&'static str, String)>> {
    let counts = fan.counts();
    let mut entries: Vec<(&'static str, String)> = Fate::ALL
        .iter()
        .enumerate()
        .filter(|(i, _)| counts[*i] > 0)
        .map(|(i, f)| (fate_colour(*f), format!("{} ({})", f.label(), counts[i])))
        .collect();
    entries.push((
        "#555555",
        "element outlines (black: DMD and photodiodes; names beside the arm plane)".into(),
    ));
    let mut lines: Vec<Vec<(&'static str, String)>> = vec![Vec::new()];
    let mut used = 0.0;
    for e in entries {
        let w = 36.0 + text_width(&e.1, TEXT_FONT) + 20.0;
        if used + w > TOTAL_WIDTH - 2.0 * MARGIN && !lines.last().is_some_and(Vec::is_empty) {
            lines.push(Vec::new());
            used = 0.0;
        }
        used += w;
        lines.last_mut().expect("one line").push(e);
    }
    lines
}

fn draw_legend(s: &mut String, lines: &[Vec<(&'static str, String)>], top: f64) {
    let _ = writeln!(s, r##"<g class="legend">"##);
    for (r, line) in lines.iter().enumerate() {
        let ly = top + 14.0 + 22.0 * r as f64;
        let mut lx = MARGIN;
        for (col, label) in line {
            let _ = writeln!(
                s,
                r##"<path d="M{a:.2} {ly:.2} L{b:.2} {ly:.2}" stroke="{col}" stroke-width="3"/><text x="{t:.2}" y="{y:.2}" font-size="{TEXT_FONT}">{l}</text>"##,
                a = lx,
                b = lx + 28.0,
                t = lx + 36.0,
                y = ly + 5.5,
                l = escape(label)
            );
            lx += 36.0 + text_width(label, TEXT_FONT) + 20.0;
        }
    }
    let _ = writeln!(s, "</g>");
}

/// Renders the layout's SVG to PNG bytes at print size (`report::svg::PNG_DPI`) with resvg,
/// text set as outlines of the embedded DejaVu Sans (no system fonts are consulted).
#[cfg(feature = "figures")]
pub fn svg_to_png(svg: &str) -> Result<Vec<u8>> {
    let svg = crate::report::svg::at_print_size(&crate::report::outline::outline_text(svg)?)?;
    let (w, h, rgb) = crate::report::svg::print_to_rgb(&svg)?;
    crate::report::png::encode_rgb8_at_dpi(w, h, &rgb, crate::report::svg::PNG_DPI)
}

/// The bench's layout (three views with a ray fan of `trace::fan::DEFAULT_FAN_RAYS` rays, seed 1) as a
/// report block, and the SVG text to write beside the report (`run`, `sweep` and `align` embed
/// it).
#[cfg(feature = "figures")]
pub fn layout_block(bench: &Bench, title: &str) -> Result<(crate::report::html::Block, String)> {
    let fan = crate::trace::fan::ray_fan(bench, crate::trace::fan::DEFAULT_FAN_RAYS, 1)?;
    let svg = crate::report::svg::at_print_size(&crate::report::outline::outline_text(
        &layout_svg(bench, &fan, title)?,
    )?)?;
    Ok((
        crate::report::html::Block::Svg {
            caption: format!(
                "The bench: top view, side view and the plane of the two arms, with {} lamp rays \
                 coloured by fate (layout.svg).",
                fan.rays.len()
            ),
            svg: svg.clone(),
        },
        svg,
    ))
}

/// The figure of `spibench layout`: the bench and `fan` drawn under `title`, its text as
/// glyph outlines.
#[cfg(feature = "figures")]
pub fn figure(bench: &Bench, fan: &RayFan, title: &str, insets: Option<&Insets>) -> Result<String> {
    crate::report::outline::outline_text(&layout_svg_with(bench, fan, title, insets)?)
}

/// Writes the figure as `layout.svg`, `layout.png` and `layout.pdf` into `out`.
#[cfg(feature = "figures")]
pub fn write_figure(svg: &str, out: &crate::report::output::OutputDir) -> Result<()> {
    crate::report::svg::write_figure(svg, &out.path("layout.svg"), &out.path("layout.png"), true)
}

/// What `spibench layout` prints: with the insets a line per diode of its spill and centroid,
/// then the fan's rays by fate and the files written.
pub fn printed(name: &str, fan: &RayFan, insets: Option<&Insets>, dir: &std::path::Path) -> String {
    let mut lines = String::new();
    if let Some(ins) = insets {
        for d in [0, 1] {
            let st = ins.stats(d);
            let _ = writeln!(
                lines,
                "{}, all units {}: spill {}, centroid {} ({} lamp rays)",
                DIODES[d],
                ["+", "−"][d],
                st.spill_text(),
                st.centroid_text(),
                ins.rays
            );
        }
    }
    lines + &printed_fan(name, fan, dir)
}

fn printed_fan(name: &str, fan: &RayFan, dir: &std::path::Path) -> String {
    let fates: Vec<String> = Fate::ALL
        .iter()
        .zip(fan.counts())
        .filter(|(_, n)| *n > 0)
        .map(|(f, n)| format!("{} {n}", f.label()))
        .collect();
    format!(
        "{name}: {} rays ({}); wrote {}/layout.svg, layout.png and layout.pdf",
        fan.rays.len(),
        fates.join(", "),
        dir.display()
    )
}

/// The diodes' names in the insets, in the bench's order (+, −).
const DIODES: [&str; 2] = ["pd_plus", "pd_minus"];

/// The irradiance maps on the two diodes from a trace of their own (`trace::irradiance`),
/// which `spibench layout --irradiance-rays N` draws as insets under the views: each diode's
/// map in its own arm's state (pd_plus with every pattern unit +, pd_minus with every unit −).
#[derive(Debug, Clone)]
pub struct Insets {
    maps: IrradianceMaps,
    rays: u64,
    #[cfg_attr(not(feature = "figures"), allow(dead_code))] // drawn only with the figures
    seed: u64,
}

/// An inset's numbers: one diode in its own arm's state, with their standard errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InsetStats {
    /// Light on the front plate outside the active area ÷ all light on the diode's map.
    pub spill: Estimate,
    /// The centre of the light on the diode's plane, (u, v) from the active area's centre (m).
    pub centroid_m: [Estimate; 2],
}

/// A positive number to three significant digits.
#[cfg_attr(not(feature = "figures"), allow(dead_code))] // drawn only with the figures
fn sig3(x: f64) -> String {
    let digits = 2 - x.log10().floor() as i32;
    if x > 0.0 && (-2..=6).contains(&digits) {
        format!("{x:.*}", digits.max(0) as usize)
    } else {
        format!("{x:.2e}")
    }
}

/// A length in mm to the micrometre, with a true minus sign.
fn mm(x_m: f64) -> String {
    format!("{:.3}", 1e3 * x_m).replace('-', "−")
}

impl InsetStats {
    fn spill_text(&self) -> String {
        let Estimate { value, stderr } = self.spill;
        format!("{:.2} ± {:.2} %", 100.0 * value, 100.0 * stderr)
    }

    fn centroid_text(&self) -> String {
        let [u, v] = self
            .centroid_m
            .map(|c| format!("{} ± {}", mm(c.value), mm(c.stderr)));
        format!("(u, v) = ({u}, {v}) mm")
    }
}

impl Insets {
    /// Traces `rays` lamp rays with `seed` (the trace's own streams: bit-identical on any
    /// number of threads) and maps the light on the diodes. `rays` must lie between two
    /// batches (so that every number has a standard error) and the trace's limit, else an
    /// input error of the field `irradiance_rays`.
    pub fn trace(bench: &Bench, rays: u64, seed: u64) -> Result<Insets> {
        use crate::scene::run::{MAX_RAYS, MIN_RAYS};
        if !(MIN_RAYS..=MAX_RAYS).contains(&rays) {
            return Err(Error::field(
                "irradiance_rays",
                format!(
                    "must lie between {MIN_RAYS} (two batches, so that every number has a \
                     standard error) and {MAX_RAYS}, got {rays}"
                ),
            ));
        }
        let options = TraceOptions::new(rays, seed);
        let (_, maps) = trace_with_maps(bench, &options, DEFAULT_BINS)?;
        Ok(Insets { maps, rays, seed })
    }

    /// The lamp rays traced.
    pub fn rays(&self) -> u64 {
        self.rays
    }

    /// Diode d's numbers in its own state d (d = 0: pd_plus, 1: pd_minus), the errors by
    /// first-order propagation of the bins' batch standard errors. Spill and centroid are
    /// ratios of sums over the bins, so the fluctuation that all bins share (the lamp rays'
    /// total) drops out of them; the bins are taken as independent otherwise, as
    /// `trace::irradiance::MapStats` takes them for the active power's error.
    pub fn stats(&self, d: usize) -> InsetStats {
        let m = &self.maps;
        let st = m.stats(d, d);
        let (bins, w) = (m.bins, m.window(d));
        let total = st.active_w + st.plate_w;
        let (mut var_s, mut var_u, mut var_v) = (0.0, 0.0, 0.0);
        for i in 0..bins * bins {
            let va = m.stderr_w(index(bins, d, d, 0, i)).powi(2);
            let vp = m.stderr_w(index(bins, d, d, 1, i)).powi(2);
            // T·∂spill/∂a_i = −spill, T·∂spill/∂p_i = 1 − spill; T·∂c/∂(a_i, p_i) = x_i − c.
            var_s += st.spill.powi(2) * va + (1.0 - st.spill).powi(2) * vp;
            let (x, y) = w.bin_centre(bins, i / bins, i % bins);
            var_u += (x - st.centroid_m[0]).powi(2) * (va + vp);
            var_v += (y - st.centroid_m[1]).powi(2) * (va + vp);
        }
        let est = |value: f64, var: f64| Estimate {
            value,
            stderr: if total > 0.0 { var.sqrt() / total } else { 0.0 },
        };
        InsetStats {
            spill: est(st.spill, var_s),
            centroid_m: [est(st.centroid_m[0], var_u), est(st.centroid_m[1], var_v)],
        }
    }

    /// The common colour scale (W/m²): from 0 to the higher peak of the two maps drawn.
    #[cfg_attr(not(feature = "figures"), allow(dead_code))] // drawn only with the figures
    fn range(&self) -> (f64, f64) {
        let peak = (0..2)
            .flat_map(|d| self.maps.irradiance(d, d).0)
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        (0.0, if peak > 0.0 { peak } else { 1.0 })
    }
}

/// The inset band's parts (SVG units): a note over both maps, three caption lines over each,
/// and the two heatmaps side by side, scaled to the page's width.
#[cfg_attr(not(feature = "figures"), allow(dead_code))] // drawn only with the figures
const INSET_NOTE: f64 = 24.0;
#[cfg_attr(not(feature = "figures"), allow(dead_code))] // drawn only with the figures
const INSET_LINE: f64 = 20.0;
#[cfg_attr(not(feature = "figures"), allow(dead_code))] // drawn only with the figures
const INSET_CAPTION_LINES: f64 = 4.0;

/// The heatmaps' scale in the band: two side by side between the margins.
#[cfg(feature = "figures")]
fn inset_scale() -> f64 {
    let (w, _) = crate::report::heatmap::INSET_SIZE;
    (TOTAL_WIDTH - 3.0 * MARGIN) / (2.0 * f64::from(w))
}

#[cfg(feature = "figures")]
fn inset_band_height() -> f64 {
    let (_, h) = crate::report::heatmap::INSET_SIZE;
    INSET_NOTE + INSET_LINE * INSET_CAPTION_LINES + inset_scale() * f64::from(h) + MARGIN
}

#[cfg(not(feature = "figures"))]
fn inset_band_height() -> f64 {
    0.0
}

/// Draws the band of insets at `top`: pd_minus's map on the left and pd_plus's on the right,
/// as the arms run in the arm-plane view, each under its caption and joined by a thin leader
/// line to its diode at `diode_at` (the + diode's point, then the − diode's).
#[cfg(feature = "figures")]
fn draw_insets(s: &mut String, ins: &Insets, top: f64, diode_at: [(f64, f64); 2]) -> Result<()> {
    use crate::report::heatmap::{Circle, Heatmap, INSET_SIZE, heatmap_inset_svg};
    let (lo, hi) = ins.range();
    let k = inset_scale();
    let w = k * f64::from(INSET_SIZE.0);
    let _ = writeln!(s, r##"<g class="irradiance-insets">"##);
    let _ = writeln!(
        s,
        r##"<text x="{MARGIN}" y="{y:.1}" font-size="{TEXT_FONT}" fill="#444">Irradiance on each diode's plane, all units in its arm's state ({n} lamp rays, seed {seed}); ring: active area, ×: centroid</text>"##,
        y = top + 16.0,
        n = ins.rays,
        seed = ins.seed,
    );
    for (slot, d) in [1usize, 0].into_iter().enumerate() {
        let x = MARGIN + slot as f64 * (w + MARGIN);
        let st = ins.stats(d);
        let caption = [
            format!("{}, all units {}", DIODES[d], ["+", "−"][d]),
            format!("colour: 0–{} W/m² (one scale for both maps)", sig3(hi)),
            format!("spill (front plate ÷ map) {}", st.spill_text()),
            format!("centroid {}", st.centroid_text()),
        ];
        let y0 = top + INSET_NOTE;
        let _ = writeln!(
            s,
            r##"<g class="irradiance-inset" id="inset-{key}">"##,
            key = ["plus", "minus"][d]
        );
        let (ax, ay) = diode_at[d];
        let _ = writeln!(
            s,
            r##"<path class="inset-leader" d="M{ax:.2} {ay:.2} L{bx:.2} {by:.2}" stroke="#999999" stroke-width="0.6" stroke-dasharray="3 3" fill="none"/>"##,
            bx = x + 0.5 * w,
            by = y0 + 2.0
        );
        for (j, line) in caption.iter().enumerate() {
            let _ = writeln!(
                s,
                r##"<text x="{x:.2}" y="{y:.2}" font-size="{TEXT_FONT}">{t}</text>"##,
                y = y0 + INSET_LINE * (j as f64 + 0.8),
                t = escape(line)
            );
        }
        let (values, mark, mm_axis, radius) = own_map(ins, d);
        let map = Heatmap {
            mark: Some(mark),
            values,
            xs: mm_axis.clone(),
            ys: mm_axis,
            value_label: "irradiance (W/m²)".into(),
            y_label: "v (mm)".into(),
            x_label: format!("u on {} (mm)", DIODES[d]),
        };
        let outline = Circle {
            centre: (0.0, 0.0),
            radius,
        };
        let svg = heatmap_inset_svg(&map, &[outline], (lo, hi))?;
        let body = &svg[svg.find("<svg").unwrap_or(0)..];
        let _ = writeln!(
            s,
            r##"<g transform="translate({x:.2} {y:.2}) scale({k:.5})">{body}</g>"##,
            y = y0 + INSET_LINE * INSET_CAPTION_LINES + 4.0
        );
        let _ = writeln!(s, "</g>");
    }
    let _ = writeln!(s, "</g>");
    Ok(())
}

#[cfg(not(feature = "figures"))]
fn draw_insets(_: &mut String, _: &Insets, _: f64, _: [(f64, f64); 2]) -> Result<()> {
    Err(Error::Numerical(
        "the irradiance insets are drawn by the `figures` build".into(),
    ))
}

/// Diode d's own-state map as heatmap cells (x-major, v ascending: the map's rows run from +v
/// down), its centroid and bin centres (mm), and the active radius (mm).
#[cfg(feature = "figures")]
fn own_map(ins: &Insets, d: usize) -> (Vec<f64>, (f64, f64), Vec<f64>, f64) {
    let m = &ins.maps;
    let (bins, w) = (m.bins, m.window(d));
    let (e, _) = m.irradiance(d, d);
    let mut cells = Vec::with_capacity(bins * bins);
    for col in 0..bins {
        cells.extend((0..bins).rev().map(|row| e[row * bins + col]));
    }
    let axis = (0..bins)
        .map(|col| 1e3 * w.bin_centre(bins, 0, col).0)
        .collect();
    let c = m.stats(d, d).centroid_m;
    (cells, (1e3 * c[0], 1e3 * c[1]), axis, 1e3 * w.radius_m)
}

#[cfg(test)]
mod tests;
