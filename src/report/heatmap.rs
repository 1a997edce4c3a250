//! Heatmaps of a quantity over a 2-D grid of two variables (a sweep), with a colour bar in the
//! quantity's units and a marked reference point (the nominal bench); and per-unit maps of the
//! pattern area ([`UnitMap`]: x_j, g±_j, k±_j) whose colour range comes from the units that
//! carry light. Both are drawn once as SVG; the PNG is that SVG rendered (`report::svg`).

use std::path::Path;

use plotters::prelude::*;

use super::font::{self, FAMILY};
use crate::error::{Error, Result};

/// A quantity on a grid: `values[i * ys.len() + j]` at (`xs[i]`, `ys[j]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Heatmap {
    pub x_label: String,
    pub y_label: String,
    /// The colour bar's label, with the unit.
    pub value_label: String,
    pub xs: Vec<f64>,
    pub ys: Vec<f64>,
    pub values: Vec<f64>,
    /// A point to mark (the nominal bench), when it lies on the drawn area.
    pub mark: Option<(f64, f64)>,
}

/// A single-column figure (3.5 × 2.8 in, SVG units of half a point, `report::svg`).
const WIDTH: u32 = 504;
const HEIGHT: u32 = 403;
/// Text at print size in plotters' whole size units (1.24 × the SVG font size, two SVG units
/// per point): 8.06 pt ticks, 8.87 pt axis descriptions.
const TICK_SIZE: f64 = 20.0;
const DESC_SIZE: f64 = 22.0;
/// Width of the colour bar's column (bar, ticks and label).
const BAR_AREA: i32 = 150;
const MARGIN: i32 = 14;
const X_LABEL_AREA: i32 = 48;
const Y_LABEL_AREA: i32 = 76;

/// The viridis colour map (van der Walt and Smith, matplotlib 2015), sampled at nine stops and
/// interpolated linearly: perceptually uniform and readable in grayscale.
const VIRIDIS: [(u8, u8, u8); 9] = [
    (68, 1, 84),
    (71, 44, 122),
    (59, 81, 139),
    (44, 113, 142),
    (33, 144, 141),
    (39, 173, 129),
    (92, 200, 99),
    (170, 220, 50),
    (253, 231, 37),
];

fn colour(t: f64) -> RGBColor {
    if !t.is_finite() {
        return RGBColor(200, 200, 200);
    }
    let t = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f64;
    let i = (t.floor() as usize).min(VIRIDIS.len() - 2);
    let f = t - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + f * (q as f64 - p as f64)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Cell edges around centres (midpoints, extended by half a step at the ends).
fn edges(c: &[f64]) -> Vec<f64> {
    if c.len() == 1 {
        return vec![c[0] - 0.5, c[0] + 0.5];
    }
    let mut e = Vec::with_capacity(c.len() + 1);
    e.push(c[0] - 0.5 * (c[1] - c[0]));
    for w in c.windows(2) {
        e.push(0.5 * (w[0] + w[1]));
    }
    let n = c.len();
    e.push(c[n - 1] + 0.5 * (c[n - 1] - c[n - 2]));
    e
}

fn check(h: &Heatmap) -> Result<(f64, f64)> {
    if h.xs.is_empty() || h.ys.is_empty() || h.values.len() != h.xs.len() * h.ys.len() {
        return Err(Error::Numerical(format!(
            "a heatmap of {}×{} cells needs {} values, got {}",
            h.xs.len(),
            h.ys.len(),
            h.xs.len() * h.ys.len(),
            h.values.len()
        )));
    }
    let finite = h.values.iter().copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() {
        return Ok((0.0, 1.0));
    }
    Ok(if hi > lo {
        (lo, hi)
    } else {
        (lo - 0.5, lo + 0.5)
    })
}

/// A circle drawn over a heatmap in its axes' units (an outline, e.g. a diode's active area).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    pub centre: (f64, f64),
    pub radius: f64,
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    h: &Heatmap,
    (lo, hi): (f64, f64),
    circles: &[Circle],
) -> std::result::Result<(), String> {
    if !font::ensure_registered() {
        return Err(font::unavailable().to_string());
    }
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (main, bar) = root.split_horizontally(root.dim_in_pixel().0 as i32 - BAR_AREA);
    let (ex, ey) = (edges(&h.xs), edges(&h.ys));
    let xr = ex[0].min(ex[ex.len() - 1])..ex[0].max(ex[ex.len() - 1]);
    let yr = ey[0].min(ey[ey.len() - 1])..ey[0].max(ey[ey.len() - 1]);
    let mut chart = ChartBuilder::on(&main)
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(xr.clone(), yr.clone())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(h.x_label.as_str())
        .y_desc(h.y_label.as_str())
        .axis_desc_style((FAMILY, DESC_SIZE))
        .label_style((FAMILY, TICK_SIZE))
        // Five x ticks: labels of a few characters at tick size fill the map's width at ten
        // (plotters' default), which overlap on a 64-bin map's range.
        .x_labels(5)
        .x_label_formatter(&|v| super::plot::format_tick(*v).replace('-', "−"))
        .y_label_formatter(&|v| super::plot::format_tick(*v).replace('-', "−"))
        .draw()
        .map_err(|e| e.to_string())?;
    let ny = h.ys.len();
    for i in 0..h.xs.len() {
        for j in 0..ny {
            let v = h.values[i * ny + j];
            let c = colour((v - lo) / (hi - lo));
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(ex[i], ey[j]), (ex[i + 1], ey[j + 1])],
                    c.filled(),
                )))
                .map_err(|e| e.to_string())?;
        }
    }
    for c in circles {
        // A white line under a thin black one: visible on any colour of the map.
        let ring = |style: ShapeStyle| {
            PathElement::new(
                (0..=128)
                    .map(|k| {
                        let t = std::f64::consts::TAU * k as f64 / 128.0;
                        (
                            c.centre.0 + c.radius * t.cos(),
                            c.centre.1 + c.radius * t.sin(),
                        )
                    })
                    .collect::<Vec<_>>(),
                style,
            )
        };
        chart
            .draw_series([
                ring(ShapeStyle::from(&WHITE).stroke_width(3)),
                ring(ShapeStyle::from(&BLACK).stroke_width(1)),
            ])
            .map_err(|e| e.to_string())?;
    }
    if let Some((mx, my)) = h.mark
        && xr.contains(&mx)
        && yr.contains(&my)
    {
        let style = ShapeStyle::from(&WHITE).stroke_width(3);
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((mx, my)) + Cross::new((0, 0), 7, style),
            ))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((mx, my))
                    + Cross::new((0, 0), 6, ShapeStyle::from(&BLACK).stroke_width(1)),
            ))
            .map_err(|e| e.to_string())?;
    }
    // The colour bar: a column of 100 steps from lo to hi, with its own value axis, its ticks
    // in units of 10ᵉ (named in its label) where the values need an exponent, so that a tick
    // is a few characters wide and fits the bar's column.
    let e = common_exponent(lo, hi);
    let scale = 10f64.powi(e);
    let bar_label = if e == 0 {
        h.value_label.clone()
    } else {
        format!("{} ×10{}", h.value_label, crate::report::superscript(e))
    };
    let mut cb = ChartBuilder::on(&bar)
        .margin_top(MARGIN)
        .margin_bottom(MARGIN + X_LABEL_AREA)
        .margin_right(4)
        .y_label_area_size(BAR_AREA - 40)
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(|e| e.to_string())?;
    cb.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(bar_label.as_str())
        .axis_desc_style((FAMILY, DESC_SIZE))
        .label_style((FAMILY, TICK_SIZE))
        .y_label_formatter(&|v| super::plot::format_tick(v / scale).replace('-', "−"))
        .draw()
        .map_err(|e| e.to_string())?;
    let steps = 100;
    for k in 0..steps {
        let a = lo + (hi - lo) * k as f64 / steps as f64;
        let b = lo + (hi - lo) * (k + 1) as f64 / steps as f64;
        cb.draw_series(std::iter::once(Rectangle::new(
            [(0.0, a), (1.0, b)],
            colour((k as f64 + 0.5) / steps as f64).filled(),
        )))
        .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())
}

/// The power of ten the colour bar's ticks are written in: 0 where the larger magnitude of the
/// range lies in [10⁻², 10⁴) (plain decimals of a few characters), else its decade, so that
/// 2.5e-7 … 1.5e-6 W/m² reads 0.25 … 1.5 under "×10⁻⁶".
fn common_exponent(lo: f64, hi: f64) -> i32 {
    let m = lo.abs().max(hi.abs());
    if m == 0.0 || !m.is_finite() || (1e-2..1e4).contains(&m) {
        0
    } else {
        m.log10().floor() as i32
    }
}

/// The SVG text (print size, text as outlines) of a heatmap.
pub fn heatmap_svg(h: &Heatmap) -> Result<String> {
    heatmap_svg_with(h, &[])
}

/// The SVG text of a heatmap with circles drawn over it.
/// With circles (a diode's outline on a map in metres) the plotting area is square
/// ([`INSET_SIZE`]), so that a circle on a square map is drawn round.
pub fn heatmap_svg_with(h: &Heatmap, circles: &[Circle]) -> Result<String> {
    let range = check(h)?;
    let size = if circles.is_empty() {
        (WIDTH, HEIGHT)
    } else {
        INSET_SIZE
    };
    super::svg::at_print_size(&drawn(h, range, circles, size)?)
}

/// The size of an inset heatmap in SVG units (half points): [`heatmap_inset_svg`]'s viewBox,
/// for a figure that scales it into place. As wide as a heatmap figure, and as high as makes
/// the plotting area square, so that a square map has square cells and a circle stays round.
pub const INSET_SIZE: (u32, u32) = (
    WIDTH,
    WIDTH - (BAR_AREA + Y_LABEL_AREA - X_LABEL_AREA) as u32,
);

/// A heatmap with circles drawn over it as an inset of a larger figure: its colours spread
/// over `range` (a scale shared with the figure's other maps, so that equal colours are equal
/// values) instead of its own values' range, at [`INSET_SIZE`] (its own `<svg>` element with
/// that viewBox, not at print size), text as glyph outlines.
pub fn heatmap_inset_svg(h: &Heatmap, circles: &[Circle], range: (f64, f64)) -> Result<String> {
    check(h)?;
    if !(range.0.is_finite() && range.1.is_finite() && range.1 > range.0) {
        return Err(Error::Numerical(format!(
            "a heatmap's colour range must be an interval, got {range:?}"
        )));
    }
    drawn(h, range, circles, INSET_SIZE)
}

/// The heatmap drawn by plotters over `range` at `size`, text as glyph outlines.
fn drawn(h: &Heatmap, range: (f64, f64), circles: &[Circle], size: (u32, u32)) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        draw(&root, h, range, circles).map_err(Error::Numerical)?;
    }
    super::outline::outline_text(&svg)
}

/// The SVG text and the PNG bytes (the SVG rendered, `report::svg::PNG_DPI`) of a heatmap.
pub fn render(h: &Heatmap) -> Result<(String, Vec<u8>)> {
    let svg = heatmap_svg(h)?;
    let (w, hh, rgb) = super::svg::print_to_rgb(&svg)?;
    let png = super::png::encode_rgb8_at_dpi(w, hh, &rgb, super::svg::PNG_DPI)?;
    Ok((svg, png))
}

/// Writes the heatmap as SVG, its PNG rendering and PDF (beside the SVG).
pub fn write_heatmap(h: &Heatmap, svg_path: &Path, png_path: &Path) -> Result<()> {
    write_heatmap_with(h, &[], svg_path, png_path)
}

/// Writes the heatmap with circles drawn over it, as [`write_heatmap`] does.
pub fn write_heatmap_with(
    h: &Heatmap,
    circles: &[Circle],
    svg_path: &Path,
    png_path: &Path,
) -> Result<()> {
    let svg = heatmap_svg_with(h, circles).map_err(|e| e.in_file(svg_path))?;
    super::svg::write_figure(&svg, svg_path, png_path, true)
}

/// Units whose incident power x_j is below this fraction of the mean x_j are "dark": they are
/// hatched on per-unit maps and left out of the colour range. A ratio such as k_j = g_j / x_j
/// over a unit that a few stray rays reach is dominated by those rays (the paper bench has
/// units with 2e-12 W whose k₊_j exceeds silicon's peak responsivity), so it says nothing about
/// the bench.
pub const DARK_FRACTION: f64 = 0.1;

/// The percentiles of the lit units' values that bound a per-unit map's colour range, so that a
/// handful of outliers does not wash out the rest (matplotlib users pass `vmin`/`vmax` from
/// `np.percentile(v, [1, 99])` for the same reason).
pub const RANGE_PERCENTILES: (f64, f64) = (1.0, 99.0);

/// A per-unit map of the pattern area (row-major, row 0 = the top row), drawn with one square
/// per unit (nearest-neighbour enlargement), a colour bar in `unit`, and the dark units
/// hatched (see [`DARK_FRACTION`]).
#[derive(Debug, Clone, PartialEq)]
pub struct UnitMap {
    /// What is shown, e.g. "k₊_j".
    pub label: String,
    /// The unit of the values, e.g. "A/W".
    pub unit: String,
    pub width: usize,
    pub height: usize,
    pub values: Vec<f64>,
    /// x_j (W), which decides the dark units.
    pub light_w: Vec<f64>,
    /// Start the colour range at 0 when all lit values are ≥ 0 (powers, responsivities).
    pub from_zero: bool,
}

/// The units that carry light: x_j ≥ `fraction` × mean x_j (and x_j > 0).
pub fn lit_units(light_w: &[f64], fraction: f64) -> Vec<bool> {
    let finite: Vec<f64> = light_w.iter().copied().filter(|v| v.is_finite()).collect();
    let mean = if finite.is_empty() {
        0.0
    } else {
        finite.iter().sum::<f64>() / finite.len() as f64
    };
    light_w
        .iter()
        .map(|&x| x.is_finite() && x > 0.0 && x >= fraction * mean)
        .collect()
}

/// The `p`-th percentile (0–100) of sorted values, by linear interpolation between closest
/// ranks (numpy's default).
fn percentile(sorted: &[f64], p: f64) -> f64 {
    let pos = (p / 100.0).clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (i, f) = (pos.floor() as usize, pos.fract());
    if i + 1 < sorted.len() {
        sorted[i] + f * (sorted[i + 1] - sorted[i])
    } else {
        sorted[i]
    }
}

/// The colour range of a per-unit map: [`RANGE_PERCENTILES`] of the finite values of the lit
/// units (all finite values when no unit is lit), from 0 when `from_zero` and none is
/// negative; always a non-empty interval.
pub fn unit_range(values: &[f64], lit: &[bool], from_zero: bool) -> (f64, f64) {
    let pick = |only_lit: bool| -> Vec<f64> {
        let mut v: Vec<f64> = values
            .iter()
            .zip(lit)
            .filter(|(v, l)| v.is_finite() && (**l || !only_lit))
            .map(|(v, _)| *v)
            .collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let mut v = pick(true);
    if v.is_empty() {
        v = pick(false);
    }
    if v.is_empty() {
        return (0.0, 1.0);
    }
    let mut lo = percentile(&v, RANGE_PERCENTILES.0);
    let hi = percentile(&v, RANGE_PERCENTILES.1);
    if from_zero && v[0] >= 0.0 {
        lo = 0.0;
    }
    if hi > lo {
        (lo, hi)
    } else {
        let p = if lo == 0.0 { 1.0 } else { lo.abs() * 0.5 };
        (lo - p, lo + p)
    }
}

fn hex(c: RGBColor) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The per-unit map's layout in SVG units (half points, `report::svg`): a single-column
/// figure, 3.5 in wide. The map takes what the axes and the colour bar leave.
const MAP_FIGURE_W: f64 = 504.0;
const MAP_LEFT: f64 = 72.0;
const MAP_TOP: f64 = 14.0;
const MAP_BAR_GAP: f64 = 12.0;
const MAP_BAR_W: f64 = 16.0;
/// Room right of the bar for its tick labels and rotated label.
const MAP_BAR_TEXT: f64 = 86.0;
/// 8 pt tick labels and notes, 9 pt axis descriptions.
const MAP_TICK_FONT: f64 = 16.0;
const MAP_DESC_FONT: f64 = 18.0;

/// Whole-number ticks over unit indices `0 ..= n − 1`.
fn index_ticks(n: usize) -> Vec<usize> {
    super::plot::linear_ticks(0.0, n.saturating_sub(1) as f64)
        .into_iter()
        .filter(|t| t.fract() == 0.0 && *t >= 0.0)
        .map(|t| t as usize)
        .collect()
}

/// The SVG of a per-unit map (see [`UnitMap`]) at print size: one square per unit, axes of
/// unit column (left to right) and unit row (top to bottom, row 0 the top row of the pattern)
/// and a colour bar in the map's unit.
pub fn unit_map_svg(m: &UnitMap) -> Result<String> {
    use std::fmt::Write as _;
    let n = m.width * m.height;
    if n == 0 || m.values.len() != n || m.light_w.len() != n {
        return Err(Error::Numerical(format!(
            "a {}×{} unit map needs {n} values and {n} powers, got {} and {}",
            m.width,
            m.height,
            m.values.len(),
            m.light_w.len()
        )));
    }
    let lit = lit_units(&m.light_w, DARK_FRACTION);
    let (lo, hi) = unit_range(&m.values, &lit, m.from_zero);
    // Every unit is an s × s square, the map as wide as the column allows.
    let avail = MAP_FIGURE_W - MAP_LEFT - MAP_BAR_GAP - MAP_BAR_W - MAP_BAR_TEXT;
    let s = avail / m.width.max(m.height) as f64;
    let (mw, mh) = (m.width as f64 * s, m.height as f64 * s);
    let (left, top) = (MAP_LEFT, MAP_TOP);
    let bar_x = left + mw + MAP_BAR_GAP;
    let bar_h = mh.max(160.0);
    let total_w = MAP_FIGURE_W;
    let notes_y = top + bar_h + 70.0;
    let total_h = (notes_y + 2.0 * 20.0 + 4.0).ceil();
    let mut out = String::new();
    let _ = writeln!(
        out,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{total_w}" height="{total_h}" viewBox="0 0 {total_w} {total_h}" font-family="DejaVu Sans, sans-serif">"##
    );
    let _ = writeln!(
        out,
        r##"<defs><pattern id="dark" patternUnits="userSpaceOnUse" width="5" height="5"><rect width="5" height="5" fill="#e6e6e6"/><path d="M-1,1 l2,-2 M0,5 l5,-5 M4,6 l2,-2" stroke="#8c8c8c" stroke-width="0.8"/></pattern></defs>"##
    );
    let _ = writeln!(
        out,
        r##"<rect width="{total_w}" height="{total_h}" fill="#ffffff"/>"##
    );
    // Each row: runs of units of the same colour as one rectangle (crisp edges, small file).
    let _ = writeln!(
        out,
        r##"<g class="units" shape-rendering="crispEdges" transform="translate({left},{top})">"##
    );
    let mut dark = 0usize;
    let fill = |j: usize| -> String {
        if !lit[j] {
            "url(#dark)".into()
        } else {
            hex(colour((m.values[j] - lo) / (hi - lo)))
        }
    };
    for r in 0..m.height {
        let mut c = 0;
        while c < m.width {
            let j = r * m.width + c;
            let f = fill(j);
            let mut e = c + 1;
            while e < m.width && fill(r * m.width + e) == f {
                e += 1;
            }
            if !lit[j] {
                dark += e - c;
            }
            let _ = writeln!(
                out,
                r##"<rect x="{:.3}" y="{:.3}" width="{:.3}" height="{s:.3}" fill="{f}"/>"##,
                c as f64 * s,
                r as f64 * s,
                (e - c) as f64 * s
            );
            c = e;
        }
    }
    let _ = writeln!(
        out,
        r##"<rect width="{mw:.3}" height="{mh:.3}" fill="none" stroke="#000000" stroke-width="1"/></g>"##
    );
    // The axes: unit indices at the centres of their units.
    let _ = writeln!(out, r##"<g class="axes">"##);
    for c in index_ticks(m.width) {
        let x = left + (c as f64 + 0.5) * s;
        let _ = writeln!(
            out,
            r##"<line x1="{x:.2}" y1="{y0:.2}" x2="{x:.2}" y2="{y1:.2}" stroke="#000000"/><text x="{x:.2}" y="{ty:.2}" text-anchor="middle" font-size="{MAP_TICK_FONT}">{c}</text>"##,
            y0 = top + mh,
            y1 = top + mh + 5.0,
            ty = top + mh + 5.0 + MAP_TICK_FONT
        );
    }
    for r in index_ticks(m.height) {
        let y = top + (r as f64 + 0.5) * s;
        let _ = writeln!(
            out,
            r##"<line x1="{x0:.2}" y1="{y:.2}" x2="{left:.2}" y2="{y:.2}" stroke="#000000"/><text x="{tx:.2}" y="{y:.2}" dy="0.35em" text-anchor="end" font-size="{MAP_TICK_FONT}">{r}</text>"##,
            x0 = left - 5.0,
            tx = left - 8.0
        );
    }
    let _ = writeln!(
        out,
        r##"<text x="{x:.2}" y="{y:.2}" text-anchor="middle" font-size="{MAP_DESC_FONT}">unit column</text>"##,
        x = left + mw / 2.0,
        y = top + mh + 5.0 + MAP_TICK_FONT + 22.0
    );
    let _ = writeln!(
        out,
        r##"<text transform="translate({x:.2},{y:.2}) rotate(-90)" text-anchor="middle" font-size="{MAP_DESC_FONT}">unit row (0 = top)</text>"##,
        x = 22.0,
        y = top + mh / 2.0
    );
    let _ = writeln!(out, "</g>");
    colour_bar(&mut out, m, (lo, hi), (bar_x, top, bar_h), total_w);
    let notes = [
        format!(
            "hatched: {dark} of {n} units with x_j < {:.0} % of the mean x_j",
            DARK_FRACTION * 100.0
        ),
        format!(
            "colour range: the {}–{} % percentiles of the other units",
            RANGE_PERCENTILES.0, RANGE_PERCENTILES.1
        ),
    ];
    for (k, note) in notes.iter().enumerate() {
        let _ = writeln!(
            out,
            r##"<text x="14" y="{:.2}" font-size="{MAP_TICK_FONT}">{}</text>"##,
            notes_y + 20.0 * k as f64,
            esc(note)
        );
    }
    let _ = writeln!(out, "</svg>");
    super::svg::at_print_size(&super::outline::outline_text(&out)?)
}

/// The colour bar of a unit map at `(x, top, height)`: the colour scale in 64 steps, ticks over
/// `range` with one power of ten for the whole bar, and the map's label and unit beside it.
fn colour_bar(
    out: &mut String,
    m: &UnitMap,
    (lo, hi): (f64, f64),
    (bar_x, top, bar_h): (f64, f64, f64),
    total_w: f64,
) {
    use std::fmt::Write as _;
    // The colour bar with ticks in the map's unit.
    let steps = 64;
    let _ = writeln!(
        out,
        r##"<g class="colour-bar" shape-rendering="crispEdges">"##
    );
    for k in 0..steps {
        let y0 = top + bar_h * (1.0 - (k + 1) as f64 / steps as f64);
        let _ = writeln!(
            out,
            r##"<rect x="{bar_x:.2}" y="{y0:.2}" width="{MAP_BAR_W}" height="{:.2}" fill="{}"/>"##,
            bar_h / steps as f64 + 0.5,
            hex(colour((k as f64 + 0.5) / steps as f64))
        );
    }
    let _ = writeln!(
        out,
        r##"<rect x="{bar_x:.2}" y="{top}" width="{MAP_BAR_W}" height="{bar_h:.2}" fill="none" stroke="#000000"/></g>"##
    );
    let ticks = super::plot::linear_ticks(lo, hi);
    let scale = ticks
        .iter()
        .map(|t| t.abs())
        .fold(0.0f64, f64::max)
        .max(hi.abs());
    // One power of ten for the whole bar, so tick text stays short ("1.2", "× 1e-6").
    let exp = if scale > 0.0 && !(1e-2..1e4).contains(&scale) {
        (scale.log10().floor() as i32 / 3) * 3
    } else {
        0
    };
    let div = 10f64.powi(exp);
    let bar_r = bar_x + MAP_BAR_W;
    for t in &ticks {
        let y = top + bar_h * (1.0 - (t - lo) / (hi - lo));
        let _ = writeln!(
            out,
            r##"<line x1="{bar_r:.2}" y1="{y:.2}" x2="{:.2}" y2="{y:.2}" stroke="#000000"/><text x="{:.2}" y="{y:.2}" dy="0.35em" font-size="{MAP_TICK_FONT}">{}</text>"##,
            bar_r + 4.0,
            bar_r + 6.0,
            esc(&super::plot::format_tick(t / div).replace('-', "−"))
        );
    }
    let unit = if exp == 0 {
        m.unit.clone()
    } else {
        format!("10{} {}", super::superscript(exp), m.unit)
    };
    let _ = writeln!(
        out,
        r##"<text transform="translate({:.2},{:.2}) rotate(-90)" text-anchor="middle" font-size="{MAP_DESC_FONT}">{} ({})</text>"##,
        total_w - 10.0,
        top + bar_h / 2.0,
        esc(&m.label),
        esc(&unit)
    );
}

/// Writes a per-unit map as SVG, its PNG rendering and PDF (beside the SVG).
pub fn write_unit_map(m: &UnitMap, svg_path: &Path, png_path: &Path) -> Result<()> {
    let svg = unit_map_svg(m).map_err(|e| e.in_file(svg_path))?;
    super::svg::write_figure(&svg, svg_path, png_path, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_with_a_mark_and_rejects_a_wrong_grid() {
        let h = Heatmap {
            x_label: "x (mm)".into(),
            y_label: "y (mm)".into(),
            value_label: "imbalance".into(),
            xs: vec![-1.0, 0.0, 1.0],
            ys: vec![0.0, 2.0],
            values: vec![0.1, 0.2, 0.3, f64::NAN, 0.5, 0.6],
            mark: Some((0.0, 0.0)),
        };
        let (svg, png) = render(&h).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("imbalance"));
        assert_eq!(&png[1..4], b"PNG");
        let bad = Heatmap {
            values: vec![1.0],
            ..h
        };
        assert!(render(&bad).is_err());
        assert_eq!(colour(0.0), RGBColor(68, 1, 84));
        assert_eq!(colour(1.0), RGBColor(253, 231, 37));
    }

    /// The colour bar's ticks take a common power of ten outside [10⁻², 10⁴), and a map with
    /// circles (a diode's outline) is drawn with a square plotting area: its viewBox is
    /// [`INSET_SIZE`], not the sweep heatmap's.
    #[test]
    fn colour_bars_share_an_exponent_and_outlined_maps_are_square() {
        assert_eq!(common_exponent(0.0, 0.5), 0);
        assert_eq!(common_exponent(-3.0, 9999.0), 0);
        assert_eq!(common_exponent(2.5e-7, 1.5e-6), -6);
        assert_eq!(common_exponent(-4.2e-3, 1e-3), -3);
        assert_eq!(common_exponent(0.0, 3.2e5), 5);
        let n = 8;
        let c: Vec<f64> = (0..n).map(|i| (i as f64 - 3.5) * 1e-3).collect();
        let h = Heatmap {
            x_label: "x (mm)".into(),
            y_label: "y (mm)".into(),
            value_label: "irradiance (W/m²)".into(),
            xs: c.clone(),
            ys: c.clone(),
            values: (0..n * n).map(|k| 1e-6 * k as f64).collect(),
            mark: None,
        };
        let view_box = |svg: &str| {
            let v = svg.split("viewBox=\"").nth(1).unwrap();
            let v: Vec<f64> = v
                .split('"')
                .next()
                .unwrap()
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            (v[2], v[3])
        };
        let plain = heatmap_svg(&h).unwrap();
        assert_eq!(view_box(&plain), (WIDTH as f64, HEIGHT as f64));
        let ring = Circle {
            centre: (0.0, 0.0),
            radius: 2e-3,
        };
        let round = heatmap_svg_with(&h, &[ring]).unwrap();
        assert_eq!(view_box(&round), (INSET_SIZE.0 as f64, INSET_SIZE.1 as f64));
    }

    /// A few dark units with a huge ratio (stray light over 2e-12 W) do not set the colour
    /// range; the lit units do, and the dark ones are hatched.
    #[test]
    fn map_colour_range_ignores_dark_units() {
        let (w, h) = (10, 10);
        let mut light = vec![1e-6; w * h];
        let mut k: Vec<f64> = (0..w * h).map(|j| 0.30 + 0.001 * (j % 10) as f64).collect();
        for j in [0, 1, 2, 99] {
            light[j] = 2e-12;
            k[j] = 1.15;
        }
        let lit = lit_units(&light, DARK_FRACTION);
        assert_eq!(lit.iter().filter(|l| !**l).count(), 4);
        let (lo, hi) = unit_range(&k, &lit, true);
        assert_eq!(lo, 0.0);
        assert!(hi < 0.31 && hi > 0.30, "hi = {hi}");
        // Without the mask the outliers would have set the top of the range.
        let all = vec![true; w * h];
        assert!(unit_range(&k, &all, true).1 > 1.0);
        let m = UnitMap {
            label: "k₊_j".into(),
            unit: "A/W".into(),
            width: w,
            height: h,
            values: k,
            light_w: light,
            from_zero: true,
        };
        let svg = unit_map_svg(&m).unwrap();
        assert!(svg.contains("k₊_j (A/W)"));
        assert_eq!(svg.matches("url(#dark)").count(), 2); // a run of 3 and a single unit
        let (pw, ph, _) = crate::report::svg::print_to_rgb(&svg).unwrap();
        assert!(pw >= 480 && ph >= 480, "{pw}×{ph}");
    }

    /// A per-unit map is a single-column figure with 8–9 pt text, axes of unit indices (0 and
    /// the last index of a 48 × 48 map among the ticks) and a colour bar with its label; the
    /// heatmap too, and both are written with a PDF.
    #[test]
    fn maps_have_axes_a_colour_bar_and_print_size() {
        let (w, h) = (48, 48);
        let m = UnitMap {
            label: "x_j".into(),
            unit: "W".into(),
            width: w,
            height: h,
            values: (0..w * h).map(|j| 1e-6 * (1.0 + (j % 7) as f64)).collect(),
            light_w: vec![1e-6; w * h],
            from_zero: true,
        };
        let svg = unit_map_svg(&m).unwrap();
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let root = doc.root_element();
        assert_eq!(root.attribute("width"), Some("3.5in"));
        let labels: Vec<&str> = doc
            .descendants()
            .filter_map(|n| n.attribute("aria-label"))
            .collect();
        for l in [
            "unit column",
            "unit row (0 = top)",
            "x_j (10⁻⁶ W)",
            "0",
            "40",
            "7",
        ] {
            assert!(labels.contains(&l), "{l} missing from {labels:?}");
        }
        for n in doc
            .descendants()
            .filter(|n| n.attribute("aria-label").is_some())
        {
            let size: f64 = n.attribute("font-size").unwrap().parse().unwrap();
            // Two units per point.
            assert!(
                (16.0..=18.0).contains(&size),
                "{:?}",
                n.attribute("aria-label")
            );
        }
        assert!(svg.contains(r#"class="colour-bar""#));
        let dir = std::env::temp_dir().join(format!("spibench-maps-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        write_unit_map(&m, &dir.join("x.svg"), &dir.join("x.png")).unwrap();
        let hm = Heatmap {
            x_label: "x (mm)".into(),
            y_label: "y (mm)".into(),
            value_label: "imbalance".into(),
            xs: vec![-1.0, 0.0, 1.0],
            ys: vec![0.0, 2.0],
            values: vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
            mark: None,
        };
        write_heatmap(&hm, &dir.join("h.svg"), &dir.join("h.png")).unwrap();
        for stem in ["x", "h"] {
            let pdf = std::fs::read(dir.join(format!("{stem}.pdf"))).unwrap();
            let (pw, _) = crate::report::svg::tests::pdf_page_pt(&pdf);
            assert!((pw - 252.0).abs() < 0.5, "{stem}: {pw} pt");
            let png = image::open(dir.join(format!("{stem}.png"))).unwrap();
            assert_eq!(png.width(), 1008);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
