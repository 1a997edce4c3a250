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
use super::npy::write_atomic;
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

/// Default figure size in pixels (the SVG uses the same user units).
pub const PLOT_WIDTH_PX: u32 = 960;
pub const PLOT_HEIGHT_PX: u32 = 600;

const AXIS_DESC_SIZE: f64 = 22.0;
const TICK_SIZE: f64 = 17.0;
const LEGEND_SIZE: f64 = 18.0;
const MARGIN_PX: i32 = 18;
const LEGEND_LINE_PX: i32 = 26;
const LEGEND_GAP_PX: i32 = 28;
const LEGEND_SAMPLE_PX: i32 = 52;

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
    let mut chart = ChartBuilder::on(area)
        .margin(MARGIN_PX)
        .x_label_area_size(58)
        .y_label_area_size(tick_w + 52)
        .build_cartesian_2d(
            x,
            Ticked {
                inner: RangedCoordf64::from(y),
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
    let area = chart.plotting_area();
    for (i, s) in series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
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
                                + PathElement::new(vec![(-5, 0), (5, 0)], style)),
                        )
                        .map_err(|e| e.to_string())?;
                    }
                }
                draw_marker(area, (x, y), i, color)?;
            }
        }
    }
    Ok(())
}

/// The legend's entries (series index, label) placed in rows: each row holds as many
/// entries as fit in `width`, left to right.
fn legend_rows(series: &[Prepared], width: u32) -> Vec<Vec<(usize, String)>> {
    let max_text = width.saturating_sub(LEGEND_SAMPLE_PX as u32 + 3 * LEGEND_GAP_PX as u32);
    let mut rows: Vec<Vec<(usize, String)>> = Vec::new();
    let mut used = 0u32;
    for (i, s) in series.iter().enumerate() {
        if s.label.trim().is_empty() {
            continue;
        }
        let label = font::fit_text(&s.label, LEGEND_SIZE, max_text);
        let w = entry_width(&label);
        if rows.is_empty() || used + w > width.saturating_sub(2 * MARGIN_PX as u32) {
            rows.push(Vec::new());
            used = 0;
        }
        used += w;
        rows.last_mut().expect("a row was pushed").push((i, label));
    }
    rows
}

fn entry_width(label: &str) -> u32 {
    LEGEND_SAMPLE_PX as u32 + 8 + font::text_width(label, LEGEND_SIZE) + LEGEND_GAP_PX as u32
}

/// Draws the whole figure on `root` (already `width × height`).
fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plot: &LinePlot,
    series: &[Prepared],
    x: Range<f64>,
    y: Range<f64>,
) -> std::result::Result<(), String> {
    if !font::ensure_registered() {
        return Err(font::unavailable().to_string());
    }
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (w, h) = root.dim_in_pixel();
    let rows = legend_rows(series, w);
    let legend_h = if rows.is_empty() {
        0
    } else {
        rows.len() as i32 * LEGEND_LINE_PX + MARGIN_PX
    };
    let (chart_area, legend_area) = root.split_vertically(h as i32 - legend_h);
    if plot.log_x {
        let ticks = log_ticks(x.start, x.end);
        let inner: LogCoord<f64> = x.log_scale().into();
        draw_chart(&chart_area, plot, series, Ticked { inner, ticks }, y)?;
    } else {
        let ticks = linear_ticks(x.start, x.end);
        let inner = RangedCoordf64::from(x);
        draw_chart(&chart_area, plot, series, Ticked { inner, ticks }, y)?;
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
        for (i, label) in row {
            let color = PALETTE[i % PALETTE.len()];
            draw_line(
                &legend_area,
                vec![(left, yc), (left + LEGEND_SAMPLE_PX, yc)],
                *i,
            )?;
            draw_marker(&legend_area, (left + LEGEND_SAMPLE_PX / 2, yc), *i, color)?;
            legend_area
                .draw(&Text::new(
                    label.clone(),
                    (left + LEGEND_SAMPLE_PX + 8, yc),
                    style.clone(),
                ))
                .map_err(|e| e.to_string())?;
            left += entry_width(label) as i32;
        }
    }
    root.present().map_err(|e| e.to_string())
}

/// The SVG text of a plot.
pub fn render_svg(plot: &LinePlot, width: u32, height: u32) -> Result<String> {
    let (series, x, y) = prepare(plot)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        draw_figure(&root, plot, &series, x, y).map_err(Error::Numerical)?;
    }
    super::outline::outline_text(&svg)
}

/// The SVG text and the RGB pixels (row-major, 3 bytes each) of a plot; the pixels are the
/// SVG rendered by resvg.
fn render(plot: &LinePlot, width: u32, height: u32) -> Result<(String, Vec<u8>)> {
    let svg = render_svg(plot, width, height)?;
    let (_, _, rgb) = super::svg::svg_to_rgb(&svg)?;
    Ok((svg, rgb))
}

/// Writes the plot as SVG, PNG and PDF at the default size ([`PLOT_WIDTH_PX`] ×
/// [`PLOT_HEIGHT_PX`]); the PDF goes beside the SVG, with the extension `.pdf`.
pub fn write_plot(plot: &LinePlot, svg_path: &Path, png_path: &Path) -> Result<()> {
    write_plot_sized(plot, svg_path, png_path, PLOT_WIDTH_PX, PLOT_HEIGHT_PX)
}

/// Writes the plot as SVG, PNG and PDF (beside the SVG) of `width × height` pixels (each from
/// 320 to 8000). All three are rendered in memory first, so a drawing failure writes none.
pub fn write_plot_sized(
    plot: &LinePlot,
    svg_path: &Path,
    png_path: &Path,
    width: u32,
    height: u32,
) -> Result<()> {
    if !(320..=8000).contains(&width) || !(240..=8000).contains(&height) {
        return Err(Error::input(format!(
            "a {width}×{height} plot is outside the supported 320–8000 × 240–8000 pixels"
        ))
        .in_file(png_path));
    }
    let fail = |e: Error| match e {
        Error::Numerical(msg) => Error::write(svg_path, std::io::Error::other(msg)),
        other => other.in_file(svg_path),
    };
    let (svg, rgb) = render(plot, width, height).map_err(fail)?;
    let pdf = super::svg::svg_to_pdf(&svg).map_err(fail)?;
    write_atomic(svg_path, svg.as_bytes())?;
    write_atomic(&svg_path.with_extension("pdf"), &pdf)?;
    super::png::write_rgb8(png_path, width, height, &rgb)
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

/// Width and height of a scope figure (px, SVG user units).
pub const SCOPE_WIDTH_PX: u32 = 960;
pub const SCOPE_PANEL_PX: u32 = 220;
/// The band under the bottom panel for the shared time axis' ticks and label.
const SCOPE_AXIS_PX: u32 = 76;

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
    // The bottom panel also holds the shared time axis' labels.
    let axis_h = SCOPE_AXIS_PX as i32;
    let panel_h = (h as i32 - axis_h) / n as i32;
    let mut rest = root.clone();
    for (k, (name, v)) in p.channels.iter().enumerate() {
        let last = k + 1 == n;
        let (panel, below) = if last {
            (rest.clone(), rest.clone())
        } else {
            rest.split_vertically(panel_h)
        };
        rest = below;
        let finite = v.iter().copied().filter(|y| y.is_finite());
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
            .margin_top(if k == 0 { MARGIN_PX } else { 4 })
            .margin_bottom(if last { MARGIN_PX } else { 4 })
            .x_label_area_size(if last { axis_h - MARGIN_PX } else { 0 })
            .y_label_area_size(140.max(tick_w + 52))
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
        let y_desc = format!("{name} (V)");
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
            .zip(v)
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

/// The SVG of an oscilloscope figure.
pub fn scope_svg(p: &ScopePlot) -> Result<String> {
    if p.channels.iter().any(|(_, v)| v.len() != p.t_us.len()) || p.t_us.is_empty() {
        return Err(Error::Numerical(
            "every oscilloscope channel needs one value per sample time".into(),
        ));
    }
    let h = SCOPE_PANEL_PX * p.channels.len().max(1) as u32 + SCOPE_AXIS_PX;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (SCOPE_WIDTH_PX, h)).into_drawing_area();
        draw_scope(&root, p).map_err(Error::Numerical)?;
    }
    super::outline::outline_text(&svg)
}

/// Writes an oscilloscope figure as SVG, its PNG rendering, and PDF beside the SVG.
pub fn write_scope(p: &ScopePlot, svg_path: &Path, png_path: &Path) -> Result<()> {
    let svg = scope_svg(p).map_err(|e| e.in_file(svg_path))?;
    let png = super::svg::svg_to_png(&svg)?;
    let pdf = super::svg::svg_to_pdf(&svg)?;
    write_atomic(svg_path, svg.as_bytes())?;
    write_atomic(&svg_path.with_extension("pdf"), &pdf)?;
    write_atomic(png_path, &png)
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
            assert_eq!(img.dimensions(), (PLOT_WIDTH_PX, PLOT_HEIGHT_PX));
            // The PNG is the SVG file rendered: pixel for pixel the same.
            let (w, h, rgb) = crate::report::svg::svg_to_rgb(&svg).unwrap();
            assert_eq!((w, h), img.dimensions());
            assert!(rgb == img.as_raw().as_slice(), "PNG and SVG differ");
            // Every series colour appears (lines and markers were drawn), not just text.
            for c in &PALETTE[..3] {
                let n = img.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count();
                assert!(n > 50, "colour {c:?} drawn on only {n} pixels");
            }
            // The legend sits below the axes: the bottom band holds series colours.
            let bottom = (0..PLOT_WIDTH_PX)
                .flat_map(|x| (PLOT_HEIGHT_PX - 60..PLOT_HEIGHT_PX).map(move |y| (x, y)))
                .filter(|&(x, y)| {
                    img.get_pixel(x, y).0 == [PALETTE[1].0, PALETTE[1].1, PALETTE[1].2]
                })
                .count();
            assert!(bottom > 20, "no legend sample below the axes ({bottom} px)");
        }
        let _ = std::fs::remove_dir_all(&dir);
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
        let (w, h, rgb) = crate::report::svg::svg_to_rgb(&svg).unwrap();
        // The x-axis description sits in the bottom BAND px, alone on its rows.
        const BAND: u32 = 48;
        let band: Vec<u8> = rgb[(w * (h - BAND) * 3) as usize..].to_vec();
        let cols = crate::report::svg::tests::ink_columns(w, BAND, &band);
        let ink = (cols.iter().rposition(|&c| c).unwrap() - cols.iter().position(|&c| c).unwrap()
            + 1) as f64;
        // plotters writes font-size = size / 1.24 into the SVG.
        let px = AXIS_DESC_SIZE / 1.24;
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
        let reference = format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}">{axis_text}</svg>"#
        );
        let (_, _, ref_rgb) = crate::report::svg::svg_to_rgb(&reference).unwrap();
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

    /// Three panels, one line each (no markers), shaded settled windows.
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
                ("RF".into(), sq(1.0)),
                ("MONITOR+".into(), sq(0.5)),
                ("MONITOR−".into(), sq(-0.5)),
            ],
            t_us,
            frame_us: 10.0,
            settling_us: 2.0,
        };
        let svg = scope_svg(&p).unwrap();
        for name in ["RF (V)", "MONITOR+ (V)", "MONITOR− (V)", "time (µs)"] {
            assert!(svg.contains(name), "{name}");
        }
        assert_eq!(svg.matches("time (µs)").count(), 1, "one shared time axis");
        assert!(!svg.contains("<circle"), "samples are a line, not markers");
        let (w, h, _) = crate::report::svg::svg_to_rgb(&svg).unwrap();
        assert_eq!((w, h), (SCOPE_WIDTH_PX, 3 * SCOPE_PANEL_PX + SCOPE_AXIS_PX));
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
