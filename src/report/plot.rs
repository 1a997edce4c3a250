//! Line plots with markers and line styles, optional ±1σ error bars, labelled axes and a
//! legend, drawn once as SVG (plotters' SVG backend) and written as SVG, PDF (for LaTeX) and
//! PNG; the PNG and the PDF are renderings of that SVG (`report::svg`), so all three agree.
//!
//! Text uses the embedded DejaVu Sans, so rendering needs no system font. The legend sits in a
//! band below the axes, in as many columns as fit, so it never covers data and leaves the axes
//! the figure's whole width. Figures carry no title: the caption belongs to the page or paper
//! that shows them ([`LinePlot::title`] is kept for that caption and for alt text).
//!
//! Each series has a colour (Okabe–Ito), a marker shape and a dash pattern, all cycling with
//! different periods, so curves that coincide (single-arm and SCB on a balanced bench) stay
//! visible under each other and series stay distinct in grayscale print.

use std::ops::Range;
use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::types::RangedCoordf64;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::font::{self, FAMILY};
use crate::error::{Error, Result};

/// One curve: points `(x[i], y[i])` joined in order, each with an optional ±`y_err[i]` bar.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    /// Half-length of each error bar (for example one standard error); NaN or 0 draws none.
    pub y_err: Option<Vec<f64>>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct LinePlot {
    /// The figure's caption: not drawn in the figure (captions go in the page), kept for the
    /// page that shows it.
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Logarithmic x axis (points with x ≤ 0 cannot be shown and are skipped).
    pub log_x: bool,
}

/// The default figure's size in SVG user units (half points, `report::svg`): a single-column
/// figure, 3.5 × 2.6 in.
pub const PLOT_WIDTH_PX: u32 = 504;
pub const PLOT_HEIGHT_PX: u32 = 374;

/// Text at print size, in plotters' size unit: plotters rounds a size down to whole units and
/// writes `font-size = size / 1.24`, and one SVG unit is half a point, so 22 gives 8.87 pt
/// (axis descriptions) and 20 gives 8.06 pt (tick labels and legend).
const AXIS_DESC_SIZE: f64 = 22.0;
const TICK_SIZE: f64 = 20.0;
const LEGEND_SIZE: f64 = 20.0;
const MARGIN_PX: i32 = 14;
const LEGEND_LINE_PX: i32 = 22;
const LEGEND_GAP_PX: i32 = 20;
const LEGEND_SAMPLE_PX: i32 = 40;
/// At most about this many markers per series: a long series gets a marker on every k-th
/// point, each series starting at a different point, so that markers of curves that lie on
/// each other alternate along them instead of hiding each other.
const MARKERS_PER_SERIES: usize = 12;

/// A filled area drawn behind the curves against a secondary scale on the right, from 0 (the
/// bottom of the axes) to 1: a spectrum or a responsivity normalised to its peak, for example.
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    pub label: String,
    pub x: Vec<f64>,
    /// Values on the secondary scale (0 to 1; others are clipped to it).
    pub y: Vec<f64>,
}

/// What a plot may carry besides its curves.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlotOptions {
    /// The printed size; `None` chooses it from the plot ([`default_size`]).
    pub size: Option<super::svg::FigureSize>,
    /// Filled areas behind the curves, with their scale on the right.
    pub areas: Vec<Area>,
    /// The secondary scale's label (used when there are areas).
    pub area_label: String,
}

pub use super::svg::FigureSize;

/// Dash patterns (dash, gap) in px, cycled with a period (5) coprime to the palette's (7) and
/// the markers' (6); `None` is a solid line.
const DASHES: [Option<(i32, i32)>; 5] = [
    None,
    Some((12, 6)),
    Some((3, 4)),
    Some((20, 5)),
    Some((7, 3)),
];

/// Okabe–Ito colours, distinguishable with the common colour-vision deficiencies.
const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
];

/// Marker shapes, cycled with a period coprime to the palette's so that series stay distinct
/// in grayscale print too.
const MARKERS: usize = 6;

/// A series reduced to what can be drawn: runs of consecutive plottable points (a missing
/// point breaks the line) with their error half-lengths (0 = no bar).
struct Prepared {
    label: String,
    runs: Vec<Vec<(f64, f64, f64)>>,
}

/// The drawable series with the x and y ranges to show.
type PreparedPlot = (Vec<Prepared>, Range<f64>, Range<f64>);

fn prepare(plot: &LinePlot) -> Result<PreparedPlot> {
    let mut out = Vec::with_capacity(plot.series.len());
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for (i, s) in plot.series.iter().enumerate() {
        if s.x.len() != s.y.len() {
            return Err(Error::field(
                format!("series[{i}].y"),
                format!(
                    "series {:?} has {} x values but {} y values",
                    s.label,
                    s.x.len(),
                    s.y.len()
                ),
            ));
        }
        if let Some(err) = &s.y_err {
            if err.len() != s.y.len() {
                return Err(Error::field(
                    format!("series[{i}].y_err"),
                    format!(
                        "series {:?} has {} error values for {} points",
                        s.label,
                        err.len(),
                        s.y.len()
                    ),
                ));
            }
            if let Some(bad) = err.iter().find(|e| **e < 0.0) {
                return Err(Error::field(
                    format!("series[{i}].y_err"),
                    format!("error bar half-lengths must not be negative, got {bad}"),
                ));
            }
        }
        let mut runs = Vec::new();
        let mut run = Vec::new();
        for k in 0..s.x.len() {
            let (x, y) = (s.x[k], s.y[k]);
            let ok = x.is_finite() && y.is_finite() && (!plot.log_x || x > 0.0);
            if !ok {
                if !run.is_empty() {
                    runs.push(std::mem::take(&mut run));
                }
                continue;
            }
            let e = s
                .y_err
                .as_ref()
                .map(|v| v[k])
                .filter(|e| e.is_finite())
                .unwrap_or(0.0);
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y - e);
            y1 = y1.max(y + e);
            run.push((x, y, e));
        }
        if !run.is_empty() {
            runs.push(run);
        }
        out.push(Prepared {
            label: s.label.clone(),
            runs,
        });
    }
    // x0 stays +∞ when no point was plottable.
    if !x0.is_finite() {
        return Err(Error::field(
            "series",
            "the plot has no point with finite coordinates (and x > 0 on a log axis)",
        ));
    }
    let x = if plot.log_x {
        // Pad by 4 % of the decades shown, at least a factor 1.25 for a single x value.
        let pad = ((x1 / x0).ln() * 0.04).max(0.0);
        let pad = if x1 > x0 { pad } else { 1.25f64.ln() };
        x0 * (-pad).exp()..x1 * pad.exp()
    } else {
        pad_range(x0, x1, 0.04)
    };
    Ok((out, x, pad_range(y0, y1, 0.06)))
}

/// `[lo, hi]` widened by `frac` of its span on each side; a single value gets a span of its
/// own size (or 1 at zero).
fn pad_range(lo: f64, hi: f64, frac: f64) -> Range<f64> {
    if hi > lo {
        let p = (hi - lo) * frac;
        lo - p..hi + p
    } else {
        let p = if lo == 0.0 { 1.0 } else { lo.abs() * 0.5 };
        lo - p..hi + p
    }
}

/// Tick text: plain decimals for moderate magnitudes, `1.5e-4` style otherwise; at most six
/// significant digits, so float noise in tick positions (0.30000000000000004) never shows.
pub fn format_tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { v.to_string() };
    }
    if needs_scientific(v) {
        return scientific(v);
    }
    let digits = v.abs().log10().floor() as i32;
    let decimals = (5 - digits).clamp(0, 9) as usize;
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" { "0".into() } else { s }
}

/// How one axis writes its tick values, chosen once per axis so that all its labels share a
/// style (never "1000, 10000, 1e5" side by side).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TickStyle {
    /// [`format_tick`]: plain decimals.
    Plain,
    /// Every non-zero tick as `2.5e-4`.
    Scientific,
    /// Every tick as `10⁻³`: for whole decades on a log axis.
    PowerOfTen,
}

fn needs_scientific(v: f64) -> bool {
    v != 0.0 && v.is_finite() && !(-3..5).contains(&(v.abs().log10().floor() as i32))
}

fn tick_style(ticks: &[f64]) -> TickStyle {
    let is_decade = |t: f64| t > 0.0 && (t.log10() - t.log10().round()).abs() < 1e-9;
    if !ticks.iter().any(|&t| needs_scientific(t)) {
        TickStyle::Plain
    } else if ticks.iter().all(|&t| is_decade(t)) {
        TickStyle::PowerOfTen
    } else {
        TickStyle::Scientific
    }
}

fn scientific(v: f64) -> String {
    let s = format!("{v:.5e}");
    // Trim trailing zeros of the mantissa: 2.50000e-4 → 2.5e-4.
    match s.split_once('e') {
        Some((m, e)) => {
            let m = m.trim_end_matches('0').trim_end_matches('.');
            format!("{m}e{e}")
        }
        None => s,
    }
}

fn format_styled(v: f64, style: TickStyle) -> String {
    match style {
        TickStyle::Plain => format_tick(v),
        TickStyle::Scientific if v != 0.0 && v.is_finite() => scientific(v),
        TickStyle::PowerOfTen if v > 0.0 && v.is_finite() => {
            let sup = super::superscript(v.log10().round() as i32);
            format!("10{sup}")
        }
        _ => format_tick(v),
    }
}

/// "Nice" tick positions covering `[lo, hi]`: the finest step of 1, 2 or 5 × 10^k that gives
/// at most eight intervals.
pub(crate) fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = hi - lo;
    if span <= 0.0 || !span.is_finite() {
        return vec![lo];
    }
    let mag = 10f64.powf((span / 8.0).log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|step| span / step <= 8.0)
        .unwrap_or(10.0 * mag);
    let (first, last) = ((lo / step).ceil() as i64, (hi / step).floor() as i64);
    // Integer multiples of the step, so that positions do not accumulate rounding error.
    (first..=last).map(|i| i as f64 * step).collect()
}

/// Tick positions for a logarithmic axis over `[lo, hi]` (both > 0): 1-2-5 (or 1-2-3-5) per
/// decade over a few decades, whole decades (thinned to about eight) over many, and plain linear
/// ticks when the range spans too little of a decade to hold two such positions.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let (d0, d1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let decades = d1 - d0;
    let mantissas: &[f64] = match decades {
        ..=1 => &[1.0, 2.0, 3.0, 5.0],
        2..=3 => &[1.0, 2.0, 5.0],
        _ => &[1.0],
    };
    let every = (decades / 8 + 1).max(1);
    let ticks: Vec<f64> = (d0..=d1)
        .filter(|d| (d - d0) % every == 0)
        .flat_map(|d| mantissas.iter().map(move |m| m * 10f64.powi(d)))
        .filter(|t| (lo..=hi).contains(t))
        .collect();
    if ticks.len() >= 2 {
        ticks
    } else {
        linear_ticks(lo, hi)
    }
}

/// An axis with the tick positions chosen here (plotters' own choice on log axes is too
/// sparse over two decades); it maps values like the axis it wraps.
struct Ticked<R> {
    inner: R,
    ticks: Vec<f64>,
}

impl<R: Ranged<ValueType = f64>> Ranged for Ticked<R> {
    type ValueType = f64;
    type FormatOption = DefaultFormatting;

    fn range(&self) -> Range<f64> {
        self.inner.range()
    }

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        // Bold grid lines and labels at the ticks; no light (minor) grid.
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn axis_pixel_range(&self, limit: (i32, i32)) -> Range<i32> {
        self.inner.axis_pixel_range(limit)
    }
}

fn draw_marker<DB, CT>(
    area: &DrawingArea<DB, CT>,
    at: CT::From,
    kind: usize,
    color: RGBColor,
) -> std::result::Result<(), String>
where
    DB: DrawingBackend,
    CT: plotters::coord::CoordTranslate,
{
    let filled = ShapeStyle::from(&color).filled();
    let outline = ShapeStyle::from(&color).stroke_width(2);
    let r = match kind % MARKERS {
        0 => area.draw(&(EmptyElement::at(at) + Circle::new((0, 0), 5, filled))),
        1 => area.draw(&(EmptyElement::at(at) + TriangleMarker::new((0, 0), 7, filled))),
        2 => area.draw(&(EmptyElement::at(at) + Rectangle::new([(-5, -5), (5, 5)], filled))),
        3 => area.draw(
            &(EmptyElement::at(at) + Polygon::new(vec![(0, -7), (7, 0), (0, 7), (-7, 0)], filled)),
        ),
        4 => area.draw(&(EmptyElement::at(at) + Cross::new((0, 0), 5, outline))),
        _ => area.draw(&(EmptyElement::at(at) + Circle::new((0, 0), 5, outline))),
    };
    r.map_err(|e| e.to_string())
}

/// Draws a polyline in series `i`'s colour and dash pattern.
fn draw_line<DB, CT>(
    area: &DrawingArea<DB, CT>,
    points: Vec<CT::From>,
    i: usize,
) -> std::result::Result<(), String>
where
    DB: DrawingBackend,
    CT: plotters::coord::CoordTranslate,
    CT::From: Clone,
{
    let style = PALETTE[i % PALETTE.len()].stroke_width(2);
    match DASHES[i % DASHES.len()] {
        None => area.draw(&PathElement::new(points, style)),
        Some((dash, gap)) => area.draw(&DashedPathElement::new(points, dash, gap, style)),
    }
    .map_err(|e| e.to_string())
}

fn draw_chart<DB, XR>(
    area: &DrawingArea<DB, Shift>,
    plot: &LinePlot,
    series: &[Prepared],
    extras: &Extras,
    x: Ticked<XR>,
    y: Range<f64>,
) -> std::result::Result<(), String>
where
    DB: DrawingBackend,
    XR: Ranged<ValueType = f64>,
{
    // The y label area holds the widest tick text and the rotated axis description.
    let y_ticks = linear_ticks(y.start, y.end);
    let (x_style, y_style) = (tick_style(&x.ticks), tick_style(&y_ticks));
    let tick_w = y_ticks
        .iter()
        .map(|t| font::text_width(&format_styled(*t, y_style).replace('-', "−"), TICK_SIZE))
        .max()
        .unwrap_or(0);
    let right = if extras.areas.is_empty() {
        0
    } else {
        font::text_width("0.75", TICK_SIZE) as i32 + 44
    };
    // The secondary scale sits in a right margin, not a label area: plotters would repeat the
    // primary axis' labels in a right label area.
    let mut chart = ChartBuilder::on(area)
        .margin(MARGIN_PX)
        .margin_right(MARGIN_PX + right)
        .x_label_area_size(48)
        .y_label_area_size(tick_w as i32 + 44)
        .build_cartesian_2d(
            x,
            Ticked {
                inner: RangedCoordf64::from(y.clone()),
                ticks: y_ticks,
            },
        )
        .map_err(|e| e.to_string())?;
    // Tick text uses the typographic minus sign (U+2212), as a printed figure would.
    let x_formatter = |v: &f64| format_styled(*v, x_style).replace('-', "−");
    let y_formatter = |v: &f64| format_styled(*v, y_style).replace('-', "−");
    chart
        .configure_mesh()
        .x_desc(plot.x_label.as_str())
        .y_desc(plot.y_label.as_str())
        .axis_desc_style((FAMILY, AXIS_DESC_SIZE))
        .label_style((FAMILY, TICK_SIZE))
        .x_label_formatter(&x_formatter)
        .y_label_formatter(&y_formatter)
        .bold_line_style(RGBColor(0, 0, 0).mix(0.12))
        .draw()
        .map_err(|e| e.to_string())?;
    if !extras.areas.is_empty() {
        draw_areas(area, &chart, extras, &y)?;
    }
    let area = chart.plotting_area();
    for (i, s) in series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let points: usize = s.runs.iter().map(Vec::len).sum();
        let step = points.div_ceil(MARKERS_PER_SERIES).max(1);
        let mut k = 0usize;
        for run in &s.runs {
            if run.len() > 1 {
                draw_line(area, run.iter().map(|&(x, y, _)| (x, y)).collect(), i)?;
            }
            for &(x, y, e) in run {
                if e > 0.0 {
                    let style = color.stroke_width(2);
                    area.draw(&PathElement::new(vec![(x, y - e), (x, y + e)], style))
                        .map_err(|e| e.to_string())?;
                    for end in [y - e, y + e] {
                        area.draw(
                            &(EmptyElement::at((x, end))
                                + PathElement::new(vec![(-4, 0), (4, 0)], style)),
                        )
                        .map_err(|e| e.to_string())?;
                    }
                }
                if (k + i).is_multiple_of(step) {
                    draw_marker(area, (x, y), i, color)?;
                }
                k += 1;
            }
        }
    }
    Ok(())
}

/// The colour of area `i`: light tints, unlike the curves' colours, so that the curves stay in
/// front.
const AREA_FILL: [RGBColor; 4] = [
    RGBColor(230, 159, 0),
    RGBColor(0, 114, 178),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
];
const AREA_OPACITY: f64 = 0.22;

/// The filled areas behind the curves, on the secondary scale: 0 at the bottom of the axes, 1
/// at the top of the primary range's data (so the scale's ticks 0 … 1 sit on the right axis).
fn draw_areas<DB, XR>(
    root: &DrawingArea<DB, Shift>,
    chart: &ChartContext<DB, Cartesian2d<Ticked<XR>, Ticked<RangedCoordf64>>>,
    extras: &Extras,
    y: &Range<f64>,
) -> std::result::Result<(), String>
where
    DB: DrawingBackend,
    XR: Ranged<ValueType = f64>,
{
    let to_y = |r: f64| y.start + r.clamp(0.0, 1.0) * (y.end - y.start) / SECONDARY_TOP;
    let plotting = chart.plotting_area();
    for (k, a) in extras.areas.iter().enumerate() {
        let color = AREA_FILL[k % AREA_FILL.len()];
        if a.pts.len() < 2 {
            continue;
        }
        let mut poly: Vec<(f64, f64)> = a.pts.iter().map(|&(x, r)| (x, to_y(r))).collect();
        let (first, last) = (a.pts[0].0, a.pts[a.pts.len() - 1].0);
        poly.push((last, y.start));
        poly.push((first, y.start));
        plotting
            .draw(&Polygon::new(poly, color.mix(AREA_OPACITY).filled()))
            .map_err(|e| e.to_string())?;
        let edge: Vec<(f64, f64)> = a.pts.iter().map(|&(x, r)| (x, to_y(r))).collect();
        plotting
            .draw(&PathElement::new(edge, color.mix(0.7).stroke_width(1)))
            .map_err(|e| e.to_string())?;
    }
    // The secondary scale on the right: ticks, labels and its description.
    let base = root.get_base_pixel();
    let x_right = plotting.get_x_range().end;
    let style = TextStyle::from((FAMILY, TICK_SIZE).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for t in [0.0, 0.25, 0.5, 0.75, 1.0] {
        let (px, py) = chart.backend_coord(&(x_right, to_y(t)));
        let (px, py) = (px - base.0, py - base.1);
        root.draw(&PathElement::new(
            vec![(px, py), (px + 5, py)],
            BLACK.stroke_width(1),
        ))
        .map_err(|e| e.to_string())?;
        root.draw(&Text::new(format_tick(t), (px + 8, py), style.clone()))
            .map_err(|e| e.to_string())?;
    }
    let (px, top) = chart.backend_coord(&(x_right, y.end));
    let (_, bottom) = chart.backend_coord(&(x_right, y.start));
    let (_, h) = root.dim_in_pixel();
    let label_x = px - base.0 + font::text_width("0.75", TICK_SIZE) as i32 + 22;
    let label_y = ((top + bottom) / 2 - base.1).clamp(0, h as i32);
    let rotated = TextStyle::from((FAMILY, AXIS_DESC_SIZE).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Center))
        .transform(FontTransform::Rotate90);
    root.draw(&Text::new(
        extras.area_label.clone(),
        (label_x, label_y),
        rotated,
    ))
    .map_err(|e| e.to_string())?;
    Ok(())
}

/// The secondary scale's 1 sits at this fraction of the primary range's height.
const SECONDARY_TOP: f64 = 1.0;

/// A legend entry: a curve (by series index) or a filled area (by area index).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Entry {
    Curve(usize),
    Area(usize),
}

/// The legend's entries placed in rows: each row holds as many entries as fit in `width`,
/// left to right; the curves first, then the areas.
fn legend_rows(series: &[Prepared], extras: &Extras, width: u32) -> Vec<Vec<(Entry, String)>> {
    let max_text = width.saturating_sub(LEGEND_SAMPLE_PX as u32 + 3 * LEGEND_GAP_PX as u32);
    let mut rows: Vec<Vec<(Entry, String)>> = Vec::new();
    let mut used = 0u32;
    let entries = series
        .iter()
        .enumerate()
        .map(|(i, s)| (Entry::Curve(i), &s.label))
        .chain(
            extras
                .areas
                .iter()
                .enumerate()
                .map(|(k, a)| (Entry::Area(k), &a.label)),
        );
    for (entry, label) in entries {
        if label.trim().is_empty() {
            continue;
        }
        let label = font::fit_text(label, LEGEND_SIZE, max_text);
        let w = entry_width(&label);
        if rows.is_empty() || used + w > width.saturating_sub(2 * MARGIN_PX as u32) {
            rows.push(Vec::new());
            used = 0;
        }
        used += w;
        rows.last_mut()
            .expect("a row was pushed")
            .push((entry, label));
    }
    rows
}

fn entry_width(label: &str) -> u32 {
    LEGEND_SAMPLE_PX as u32 + 6 + font::text_width(label, LEGEND_SIZE) + LEGEND_GAP_PX as u32
}

fn legend_height(rows: usize) -> i32 {
    if rows == 0 {
        0
    } else {
        rows as i32 * LEGEND_LINE_PX + MARGIN_PX / 2
    }
}

/// The filled areas reduced to what can be drawn: finite points in order of x, clipped to
/// the secondary scale.
struct PreparedArea {
    label: String,
    pts: Vec<(f64, f64)>,
}

struct Extras {
    areas: Vec<PreparedArea>,
    area_label: String,
}

fn prepare_extras(opts: &PlotOptions, log_x: bool) -> Result<Extras> {
    let mut areas = Vec::with_capacity(opts.areas.len());
    for (k, a) in opts.areas.iter().enumerate() {
        if a.x.len() != a.y.len() {
            return Err(Error::field(
                format!("areas[{k}].y"),
                format!(
                    "area {:?} has {} x values but {} y values",
                    a.label,
                    a.x.len(),
                    a.y.len()
                ),
            ));
        }
        let mut pts: Vec<(f64, f64)> =
            a.x.iter()
                .zip(&a.y)
                .filter(|(x, y)| x.is_finite() && y.is_finite() && (!log_x || **x > 0.0))
                .map(|(&x, &y)| (x, y.clamp(0.0, 1.0)))
                .collect();
        pts.sort_by(|p, q| p.0.total_cmp(&q.0));
        areas.push(PreparedArea {
            label: a.label.clone(),
            pts,
        });
    }
    Ok(Extras {
        areas,
        area_label: opts.area_label.clone(),
    })
}

/// The printed size a plot gets by default: one column, unless its legend needs more than three
/// rows there, then the page's width; the height grows by the legend's rows beyond the first.
pub fn default_size(plot: &LinePlot, opts: &PlotOptions) -> FigureSize {
    let Ok((series, _, _)) = prepare(plot) else {
        return FigureSize::SINGLE;
    };
    let Ok(extras) = prepare_extras(opts, plot.log_x) else {
        return FigureSize::SINGLE;
    };
    let rows_at = |size: FigureSize| legend_rows(&series, &extras, size.units().0).len();
    let size = if rows_at(FigureSize::SINGLE) > 3 {
        FigureSize::DOUBLE
    } else {
        FigureSize::SINGLE
    };
    let extra_rows = rows_at(size).saturating_sub(1);
    size.taller(extra_rows as f64 * f64::from(LEGEND_LINE_PX) / super::svg::UNITS_PER_IN)
}

/// Draws the whole figure on `root` (already `width × height`).
fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plot: &LinePlot,
    series: &[Prepared],
    extras: &Extras,
    x: Range<f64>,
    y: Range<f64>,
) -> std::result::Result<(), String> {
    if !font::ensure_registered() {
        return Err(font::unavailable().to_string());
    }
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (w, h) = root.dim_in_pixel();
    let rows = legend_rows(series, extras, w);
    let legend_h = legend_height(rows.len());
    let (chart_area, legend_area) = root.split_vertically(h as i32 - legend_h);
    if plot.log_x {
        let ticks = log_ticks(x.start, x.end);
        let inner: LogCoord<f64> = x.log_scale().into();
        draw_chart(
            &chart_area,
            plot,
            series,
            extras,
            Ticked { inner, ticks },
            y,
        )?;
    } else {
        let ticks = linear_ticks(x.start, x.end);
        let inner = RangedCoordf64::from(x);
        draw_chart(
            &chart_area,
            plot,
            series,
            extras,
            Ticked { inner, ticks },
            y,
        )?;
    }
    let style = TextStyle::from((FAMILY, LEGEND_SIZE).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (r, row) in rows.iter().enumerate() {
        // Each row is centred under the figure.
        let row_w: u32 =
            row.iter().map(|(_, l)| entry_width(l)).sum::<u32>() - LEGEND_GAP_PX as u32;
        let mut left = (w.saturating_sub(row_w) / 2) as i32;
        let yc = r as i32 * LEGEND_LINE_PX + LEGEND_LINE_PX / 2;
        for (entry, label) in row {
            match *entry {
                Entry::Curve(i) => {
                    let color = PALETTE[i % PALETTE.len()];
                    draw_line(
                        &legend_area,
                        vec![(left, yc), (left + LEGEND_SAMPLE_PX, yc)],
                        i,
                    )?;
                    draw_marker(&legend_area, (left + LEGEND_SAMPLE_PX / 2, yc), i, color)?;
                }
                Entry::Area(k) => {
                    let color = AREA_FILL[k % AREA_FILL.len()];
                    let r = [(left, yc - 7), (left + LEGEND_SAMPLE_PX, yc + 7)];
                    legend_area
                        .draw(&Rectangle::new(r, color.mix(AREA_OPACITY).filled()))
                        .map_err(|e| e.to_string())?;
                    legend_area
                        .draw(&Rectangle::new(r, color.mix(0.7).stroke_width(1)))
                        .map_err(|e| e.to_string())?;
                }
            }
            legend_area
                .draw(&Text::new(
                    label.clone(),
                    (left + LEGEND_SAMPLE_PX + 6, yc),
                    style.clone(),
                ))
                .map_err(|e| e.to_string())?;
            left += entry_width(label) as i32;
        }
    }
    root.present().map_err(|e| e.to_string())
}

/// The SVG text of a plot of `width × height` user units (half points), text as outlines.
pub fn render_svg(plot: &LinePlot, width: u32, height: u32) -> Result<String> {
    render_svg_with(plot, &PlotOptions::default(), width, height)
}

/// [`render_svg`] with filled areas.
pub fn render_svg_with(
    plot: &LinePlot,
    opts: &PlotOptions,
    width: u32,
    height: u32,
) -> Result<String> {
    let (series, mut x, y) = prepare(plot)?;
    let extras = prepare_extras(opts, plot.log_x)?;
    // The x range covers the areas too.
    for a in &extras.areas {
        if let (Some(f), Some(l)) = (a.pts.first(), a.pts.last()) {
            x = x.start.min(f.0)..x.end.max(l.0);
        }
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        draw_figure(&root, plot, &series, &extras, x, y).map_err(Error::Numerical)?;
    }
    super::svg::at_print_size(&super::outline::outline_text(&svg)?)
}

/// Writes the plot as SVG, PNG and PDF at its default size ([`default_size`]); the PDF goes
/// beside the SVG, with the extension `.pdf`.
pub fn write_plot(plot: &LinePlot, svg_path: &Path, png_path: &Path) -> Result<()> {
    write_plot_with(plot, &PlotOptions::default(), svg_path, png_path)
}

/// Writes the plot as SVG, PNG and PDF (beside the SVG) of `width × height` SVG units (half
/// points; each from 320 to 8000 and 240 to 8000).
pub fn write_plot_sized(
    plot: &LinePlot,
    svg_path: &Path,
    png_path: &Path,
    width: u32,
    height: u32,
) -> Result<()> {
    if !(320..=8000).contains(&width) || !(240..=8000).contains(&height) {
        return Err(Error::input(format!(
            "a {width}×{height} plot is outside the supported 320–8000 × 240–8000 units"
        ))
        .in_file(png_path));
    }
    let opts = PlotOptions {
        size: Some(FigureSize::of_units(width, height)),
        ..PlotOptions::default()
    };
    write_plot_with(plot, &opts, svg_path, png_path)
}

/// Writes the plot with its options as SVG, PNG and PDF (beside the SVG). All three are
/// rendered in memory first, so a drawing failure writes none.
pub fn write_plot_with(
    plot: &LinePlot,
    opts: &PlotOptions,
    svg_path: &Path,
    png_path: &Path,
) -> Result<()> {
    let size = opts.size.unwrap_or_else(|| default_size(plot, opts));
    let (width, height) = size.units();
    let fail = |e: Error| match e {
        Error::Numerical(msg) => Error::write(svg_path, std::io::Error::other(msg)),
        other => other.in_file(svg_path),
    };
    let svg = render_svg_with(plot, opts, width, height).map_err(fail)?;
    super::svg::write_figure(&svg, svg_path, png_path, true)
}

/// Oscilloscope channels over the first frames of a sequence: one panel per channel on a
/// shared time axis, each drawn as a line, with the frame boundaries marked and the settled
/// window of every frame (the samples that are averaged) shaded.
#[derive(Debug, Clone, PartialEq)]
pub struct ScopePlot {
    /// Sample times (µs).
    pub t_us: Vec<f64>,
    /// (channel name, volts at each sample), one panel each, top to bottom.
    pub channels: Vec<(String, Vec<f64>)>,
    /// Frame period and the excluded start of each frame (µs); frame f spans
    /// [f·frame_us, (f+1)·frame_us) and its settled window starts settling_us after its start.
    pub frame_us: f64,
    pub settling_us: f64,
}

/// Width and height of a scope figure (SVG units, half points): the page's width (7.2 in),
/// 1.1 in per channel.
pub const SCOPE_WIDTH_PX: u32 = 1037;
pub const SCOPE_PANEL_PX: u32 = 158;
/// The band under the bottom panel for the shared time axis' ticks and label.
const SCOPE_AXIS_PX: u32 = 62;
/// The band above the top panel for the frame numbers.
const SCOPE_FRAMES_PX: u32 = 24;

/// Which frames get their number written: every k-th, so that numbers keep a gap of at least
/// their own width between them (`frame_w` is the frame's width in SVG units).
fn frame_label_step(frame_w: f64, frames: i64) -> i64 {
    let digits = frames.max(1).to_string().len() as f64;
    let label_w = digits * 0.64 * 8.0 * 2.0 + 8.0;
    let mut step = 1i64;
    while (step as f64) * frame_w < 2.0 * label_w && step < frames.max(1) {
        step = match step {
            1 => 2,
            2 => 5,
            s => s * 2,
        };
    }
    step
}

fn draw_scope<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    p: &ScopePlot,
) -> std::result::Result<(), String> {
    if !font::ensure_registered() {
        return Err(font::unavailable().to_string());
    }
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (t0, t1) = (
        p.t_us.first().copied().unwrap_or(0.0),
        p.t_us.last().copied().unwrap_or(1.0),
    );
    let x = if t1 > t0 { t0..t1 } else { t0..t0 + 1.0 };
    let n = p.channels.len().max(1);
    let (_, h) = root.dim_in_pixel();
    // The bottom panel also holds the shared time axis' labels; the frame numbers sit above
    // the top panel.
    let axis_h = SCOPE_AXIS_PX as i32;
    let frames_h = SCOPE_FRAMES_PX as i32;
    let panel_h = (h as i32 - axis_h - frames_h) / n as i32;
    let (frames_band, mut rest) = root.split_vertically(frames_h);
    for (k, (name, v)) in p.channels.iter().enumerate() {
        let last = k + 1 == n;
        let (panel, below) = if last {
            (rest.clone(), rest.clone())
        } else {
            rest.split_vertically(panel_h)
        };
        rest = below;
        // Millivolts: the detector outputs are tens to hundreds of mV.
        let v_mv: Vec<f64> = v.iter().map(|y| y * 1e3).collect();
        let finite = v_mv.iter().copied().filter(|y| y.is_finite());
        let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
        let y = if lo.is_finite() {
            pad_range(lo, hi, 0.08)
        } else {
            -1.0..1.0
        };
        let y_ticks = linear_ticks(y.start, y.end);
        let y_style = tick_style(&y_ticks);
        let tick_w = y_ticks
            .iter()
            .map(|t| font::text_width(&format_styled(*t, y_style).replace('-', "−"), TICK_SIZE))
            .max()
            .unwrap_or(0);
        let x_ticks = linear_ticks(x.start, x.end);
        let x_style = tick_style(&x_ticks);
        let mut chart = ChartBuilder::on(&panel)
            .margin_left(MARGIN_PX)
            .margin_right(MARGIN_PX)
            .margin_top(4)
            .margin_bottom(if last { MARGIN_PX / 2 } else { 4 })
            .x_label_area_size(if last { axis_h - MARGIN_PX / 2 } else { 0 })
            .y_label_area_size(110.max(tick_w as i32 + 44))
            .build_cartesian_2d(
                Ticked {
                    inner: RangedCoordf64::from(x.clone()),
                    ticks: x_ticks,
                },
                Ticked {
                    inner: RangedCoordf64::from(y.clone()),
                    ticks: y_ticks,
                },
            )
            .map_err(|e| e.to_string())?;
        let x_formatter = |v: &f64| format_styled(*v, x_style).replace('-', "−");
        let y_formatter = |v: &f64| format_styled(*v, y_style).replace('-', "−");
        let y_desc = format!("{name} (mV)");
        let mut mesh = chart.configure_mesh();
        mesh.y_desc(y_desc.as_str())
            .axis_desc_style((FAMILY, AXIS_DESC_SIZE))
            .label_style((FAMILY, TICK_SIZE))
            .x_label_formatter(&x_formatter)
            .y_label_formatter(&y_formatter)
            .bold_line_style(RGBColor(0, 0, 0).mix(0.10));
        if last {
            mesh.x_desc("time (µs)");
        } else {
            mesh.x_labels(0);
        }
        mesh.draw().map_err(|e| e.to_string())?;
        if k == 0 {
            draw_frame_numbers(&frames_band, &chart, p, &x)?;
        }
        let area = chart.plotting_area();
        // The settled windows (averaged) shaded, the frame boundaries as grey lines.
        if p.frame_us > 0.0 {
            let first = (x.start / p.frame_us).floor() as i64;
            let last_f = (x.end / p.frame_us).ceil() as i64;
            for f in first..last_f {
                let a = (f as f64 * p.frame_us + p.settling_us).max(x.start);
                let b = ((f + 1) as f64 * p.frame_us).min(x.end);
                if b > a {
                    area.draw(&Rectangle::new(
                        [(a, y.start), (b, y.end)],
                        RGBColor(0, 114, 178).mix(0.10).filled(),
                    ))
                    .map_err(|e| e.to_string())?;
                }
                let edge = f as f64 * p.frame_us;
                if edge >= x.start && edge <= x.end {
                    area.draw(&PathElement::new(
                        vec![(edge, y.start), (edge, y.end)],
                        RGBColor(90, 90, 90).stroke_width(1),
                    ))
                    .map_err(|e| e.to_string())?;
                }
            }
        }
        let pts: Vec<(f64, f64)> = p
            .t_us
            .iter()
            .zip(&v_mv)
            .filter(|(_, y)| y.is_finite())
            .map(|(&t, &y)| (t, y))
            .collect();
        area.draw(&PathElement::new(pts, BLACK.stroke_width(1)))
            .map_err(|e| e.to_string())?;
        if last {
            break;
        }
    }
    root.present().map_err(|e| e.to_string())
}

/// The frame numbers (1 for the frame starting at t = 0) above the top panel, centred on each
/// frame, every k-th when frames are narrow ([`frame_label_step`]).
fn draw_frame_numbers<DB, CT>(
    band: &DrawingArea<DB, Shift>,
    chart: &ChartContext<DB, CT>,
    p: &ScopePlot,
    x: &Range<f64>,
) -> std::result::Result<(), String>
where
    DB: DrawingBackend,
    CT: plotters::coord::CoordTranslate<From = (f64, f64)>,
{
    if p.frame_us <= 0.0 {
        return Ok(());
    }
    let first = (x.start / p.frame_us).floor() as i64;
    let last = (x.end / p.frame_us).ceil() as i64;
    let px = |t: f64| chart.as_coord_spec().translate(&(t, 0.0)).0 - band.get_base_pixel().0;
    let frame_w = f64::from(px(p.frame_us) - px(0.0));
    let step = frame_label_step(frame_w, last);
    let (_, h) = band.dim_in_pixel();
    let style = TextStyle::from((FAMILY, TICK_SIZE).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Center));
    let left = TextStyle::from((FAMILY, TICK_SIZE).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Right, VPos::Center));
    let y = h as i32 / 2 + 2;
    let mut labelled = false;
    for f in first..last {
        let (a, b) = (
            (f as f64 * p.frame_us).max(x.start),
            ((f + 1) as f64 * p.frame_us).min(x.end),
        );
        // Frames cut by the window's end get no number; numbers count from 1.
        if f % step != 0 || b - a < 0.5 * p.frame_us {
            continue;
        }
        let xc = px(0.5 * (a + b));
        if !labelled {
            band.draw(&Text::new("frame", (px(a) - 6, y), left.clone()))
                .map_err(|e| e.to_string())?;
            labelled = true;
        }
        band.draw(&Text::new((f + 1).to_string(), (xc, y), style.clone()))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// The SVG of an oscilloscope figure (volts in, millivolts drawn), at the page's width.
pub fn scope_svg(p: &ScopePlot) -> Result<String> {
    if p.channels.iter().any(|(_, v)| v.len() != p.t_us.len()) || p.t_us.is_empty() {
        return Err(Error::Numerical(
            "every oscilloscope channel needs one value per sample time".into(),
        ));
    }
    let h = SCOPE_PANEL_PX * p.channels.len().max(1) as u32 + SCOPE_AXIS_PX + SCOPE_FRAMES_PX;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (SCOPE_WIDTH_PX, h)).into_drawing_area();
        draw_scope(&root, p).map_err(Error::Numerical)?;
    }
    super::svg::at_print_size(&super::outline::outline_text(&svg)?)
}

/// Writes an oscilloscope figure as SVG, its PNG rendering, and PDF beside the SVG.
pub fn write_scope(p: &ScopePlot, svg_path: &Path, png_path: &Path) -> Result<()> {
    let svg = scope_svg(p).map_err(|e| e.in_file(svg_path))?;
    super::svg::write_figure(&svg, svg_path, png_path, true)
}

#[cfg(test)]
mod tests {
    use super::*;

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
                .filter(|&(x, y)| {
                    img.get_pixel(x, y).0 == [PALETTE[1].0, PALETTE[1].1, PALETTE[1].2]
                })
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
        let ink = (cols.iter().rposition(|&c| c).unwrap() - cols.iter().position(|&c| c).unwrap()
            + 1) as f64;
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
}
