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

use std::fmt::Write as _;

use glam::DVec3;

use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::optics::dmd::MirrorState;
use crate::optics::outline::{ElementKind, element_outlines};
use crate::trace::fan::{DESIGN_WAVELENGTH_M, DmdAxes, Fate, RayFan, chief_ray, dmd_axes};

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

/// Largest drawing height and total drawing width (px) of the three views.
const MAX_VIEW_HEIGHT: f64 = 760.0;
const MAX_TOTAL_WIDTH: f64 = 1700.0;
const MARGIN: f64 = 24.0;
const TITLE_BAND: f64 = 56.0;
const FOOT_BAND: f64 = 116.0;

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

/// The SVG of the bench's layout with a traced ray fan (see the module notes). `title` heads
/// the drawing (e.g. the bench file's name). Fails (bad input) when the bench has no DMD or the
/// chief ray from the lamp does not reach it, since the arm plane needs both.
pub fn layout_svg(bench: &Bench, fan: &RayFan, title: &str) -> Result<String> {
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
    let mut ext = Vec::new();
    for v in &views {
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
        ext.push(((lo.0 - pad, lo.1 - pad), (hi.0 + pad, hi.1 + pad)));
    }
    let widths: Vec<f64> = ext.iter().map(|(l, h)| h.0 - l.0).collect();
    let heights: Vec<f64> = ext.iter().map(|(l, h)| h.1 - l.1).collect();
    let max_h = heights.iter().copied().fold(0.0, f64::max);
    let scale = (MAX_VIEW_HEIGHT / max_h).min(MAX_TOTAL_WIDTH / widths.iter().sum::<f64>());
    let panel_w: Vec<f64> = widths.iter().map(|w| (w * scale).max(220.0)).collect();
    let draw_h = max_h * scale;
    let total_w = panel_w.iter().sum::<f64>() + MARGIN * (views.len() as f64 + 1.0);
    let total_h = TITLE_BAND + draw_h + FOOT_BAND + 2.0 * MARGIN;

    let mut s = String::new();
    let _ = writeln!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}" font-family="DejaVu Sans, sans-serif">"##,
        w = total_w.ceil(),
        h = total_h.ceil()
    );
    let _ = writeln!(s, r##"<rect width="100%" height="100%" fill="#ffffff"/>"##);
    let counts = fan.counts();
    let _ = writeln!(
        s,
        r##"<text x="{MARGIN}" y="{y:.1}" font-size="18">{t}</text>"##,
        y = MARGIN + 12.0,
        t = escape(title)
    );
    let _ = writeln!(
        s,
        r##"<text x="{MARGIN}" y="{y:.1}" font-size="12" fill="#444">{n} lamp rays (seed {seed}): half with every pattern unit in state +, half in state −; dashed: chief rays at {wl:.0} nm</text>"##,
        y = MARGIN + 32.0,
        n = fan.rays.len(),
        seed = fan.seed,
        wl = DESIGN_WAVELENGTH_M * 1e9
    );

    let mut x0 = MARGIN;
    let y0 = MARGIN + TITLE_BAND;
    for (k, v) in views.iter().enumerate() {
        let ((min1, _), (_, max2)) = ext[k];
        let pw = panel_w[k];
        // Centre narrow views in their panel.
        let off = 0.5 * (pw - widths[k] * scale);
        let px = |p: DVec3| {
            let (a, b) = v.project(p);
            (x0 + off + (a - min1) * scale, y0 + (max2 - b) * scale)
        };
        let path_of = |lines: &mut dyn Iterator<Item = &Vec<DVec3>>| {
            let mut d = String::new();
            for line in lines {
                for (i, p) in line.iter().enumerate() {
                    let (x, y) = px(*p);
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
            x = x0,
            y = y0,
            w = pw,
            h = draw_h
        );
        let _ = writeln!(
            s,
            r##"<text x="{x:.2}" y="{y:.2}" font-size="14">{t}</text>"##,
            x = x0,
            y = y0 - 8.0,
            t = escape(&v.title)
        );
        let _ = writeln!(
            s,
            r##"<rect x="{x:.2}" y="{y:.2}" width="{w:.2}" height="{h:.2}" fill="none" stroke="#cccccc"/>"##,
            x = x0,
            y = y0,
            w = pw,
            h = draw_h
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
        for o in &outlines {
            let strong = matches!(o.kind, ElementKind::Dmd | ElementKind::Photodiode);
            let d = path_of(&mut o.polylines.iter());
            let _ = writeln!(
                s,
                r##"<path class="element {kind}" d="{d}" fill="none" stroke="{col}" stroke-width="{sw}"><title>{name} ({kn})</title></path>"##,
                kind = o.kind.name().to_lowercase(),
                col = if strong { "#000000" } else { "#555555" },
                sw = if strong { 1.2 } else { 0.9 },
                name = escape(&o.name),
                kn = o.kind.name()
            );
        }
        for c in &chiefs {
            let d = path_of(&mut std::iter::once(c));
            let _ = writeln!(
                s,
                r##"<path class="chief" d="{d}" fill="none" stroke="#000000" stroke-width="0.6" stroke-dasharray="6 4"/>"##
            );
        }
        let _ = writeln!(s, "</g>");
        // Scale bar (about a quarter of the panel) and the axis names.
        let bar_m = nice_below(0.25 * pw / scale * 1e3) * 1e-3;
        let by = y0 + draw_h + 22.0;
        let _ = writeln!(
            s,
            r##"<path class="scale-bar" d="M{a:.2} {by:.2} L{b:.2} {by:.2} M{a:.2} {t:.2} L{a:.2} {u:.2} M{b:.2} {t:.2} L{b:.2} {u:.2}" stroke="#000000" stroke-width="1.5"/>"##,
            a = x0,
            b = x0 + bar_m * scale,
            t = by - 4.0,
            u = by + 4.0
        );
        let _ = writeln!(
            s,
            r##"<text x="{x:.2}" y="{y:.2}" font-size="12">{mm} mm</text>"##,
            x = x0 + bar_m * scale + 8.0,
            y = by + 4.0,
            mm = bar_m * 1e3
        );
        let _ = writeln!(
            s,
            r##"<text x="{x:.2}" y="{y:.2}" font-size="11" fill="#444">→ {h}, ↑ {v}</text>"##,
            x = x0,
            y = by + 22.0,
            h = escape(&v.labels.0),
            v = escape(&v.labels.1)
        );
        let _ = writeln!(s, "</g>");
        x0 += pw + MARGIN;
    }

    // Legend: the fates that occur, with their counts.
    let ly = y0 + draw_h + 70.0;
    let mut lx = MARGIN;
    let _ = writeln!(s, r##"<g class="legend">"##);
    for (i, fate) in Fate::ALL.iter().enumerate() {
        if counts[i] == 0 {
            continue;
        }
        let label = format!("{} ({})", fate.label(), counts[i]);
        let _ = writeln!(
            s,
            r##"<path d="M{a:.2} {ly:.2} L{b:.2} {ly:.2}" stroke="{col}" stroke-width="3"/><text x="{t:.2}" y="{y:.2}" font-size="12">{label}</text>"##,
            a = lx,
            b = lx + 24.0,
            t = lx + 30.0,
            y = ly + 4.0,
            col = fate_colour(*fate)
        );
        lx += 60.0 + 7.0 * label.chars().count() as f64;
    }
    // The outline key on a line of its own, so that the legend fits the narrowest drawing.
    let _ = lx;
    let _ = writeln!(
        s,
        r##"<path d="M{a:.2} {ly:.2} L{b:.2} {ly:.2}" stroke="#555555" stroke-width="1"/><text x="{t:.2}" y="{y:.2}" font-size="12">element outlines (black: DMD and photodiodes; hover an outline in a browser for its name)</text>"##,
        a = MARGIN,
        b = MARGIN + 24.0,
        t = MARGIN + 30.0,
        ly = ly + 20.0,
        y = ly + 24.0
    );
    let _ = writeln!(s, "</g>");
    let _ = writeln!(s, "</svg>");
    Ok(s)
}

/// Renders SVG text to PNG bytes at its own size (1 px per SVG unit) with resvg, text set in the
/// embedded DejaVu Sans (no system fonts are consulted); see `report::svg`.
#[cfg(feature = "figures")]
pub fn svg_to_png(svg: &str) -> Result<Vec<u8>> {
    super::svg::svg_to_png(svg)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(feature = "figures")]
    use crate::trace::fan::ray_fan;

    #[test]
    fn nice_lengths() {
        assert_eq!(nice_below(73.0), 50.0);
        assert_eq!(nice_below(19.9), 10.0);
        assert_eq!(nice_below(0.25), 0.2);
    }

    /// The arm-plane view's axes are orthonormal, and the outgoing chief rays of the paper
    /// bench lie in its plane: both have no component along e1 × e2.
    #[test]
    fn arm_plane_contains_both_arms_and_the_incoming_axis() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let axes = dmd_axes(&bench, DESIGN_WAVELENGTH_M).unwrap();
        let v = &views(&axes)[2];
        assert!(v.e1.dot(v.e2).abs() < 1e-12);
        let n = v.e1.cross(v.e2);
        for d in [axes.outgoing[0], axes.outgoing[1], axes.incoming] {
            assert!(d.dot(n).abs() < 1e-9, "{d:?}");
        }
        // The + arm is to the right: its chief ray has a positive horizontal component.
        assert!(axes.outgoing[0].dot(v.e1) > 0.3);
    }

    /// The SVG has three views, a path for every ray in each, and renders to a PNG of its size.
    #[test]
    #[cfg(feature = "figures")]
    fn svg_and_png_of_the_test_bench() {
        let bench = crate::trace::testing::bench_with("tests/symmetric_arms.ron", &[]);
        let fan = ray_fan(&bench, 60, 1).unwrap();
        let svg = layout_svg(&bench, &fan, "symmetric <arms> & co").unwrap();
        assert_eq!(svg.matches(r#"class="view""#).count(), 3);
        assert_eq!(svg.matches(r#"class="ray "#).count(), 3 * fan.rays.len());
        assert!(svg.contains("&lt;arms&gt; &amp; co"));
        let png = svg_to_png(&svg).unwrap();
        let img = image::load_from_memory(&png).unwrap();
        let w: f64 = svg
            .split("width=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(img.width() as f64, w);
        // Not blank: some pixels carry ray colours.
        let rgb = img.to_rgb8();
        assert!(
            rgb.pixels().any(|p| p.0[2] > 150 && p.0[0] < 100),
            "no blue ray drawn"
        );
    }
}
