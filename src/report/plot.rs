//! Line plots with markers, optional ±1σ error bars, labelled axes and a legend, written as SVG
//! (for papers) and PNG (for quick looks) from the same drawing code.
//!
//! Text uses the embedded DejaVu Sans (see `font`), so rendering needs no system font. The
//! legend sits in its own column to the right of the axes, so it never covers data.

use std::ops::Range;
use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::types::RangedCoordf64;
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

const TITLE_SIZE: f64 = 28.0;
const AXIS_DESC_SIZE: f64 = 22.0;
const TICK_SIZE: f64 = 17.0;
const LEGEND_SIZE: f64 = 18.0;
const MARGIN_PX: i32 = 18;
const LEGEND_LINE_PX: i32 = 22;
const LEGEND_GAP_PX: i32 = 12;
const LEGEND_SAMPLE_PX: i32 = 36;

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
            let sup: String = (v.log10().round() as i32)
                .to_string()
                .chars()
                .map(|c| match c {
                    '-' => '⁻',
                    '0' => '⁰',
                    '1' => '¹',
                    '2' => '²',
                    '3' => '³',
                    '4' => '⁴',
                    '5' => '⁵',
                    '6' => '⁶',
                    '7' => '⁷',
                    '8' => '⁸',
                    _ => '⁹',
                })
                .collect();
            format!("10{sup}")
        }
        _ => format_tick(v),
    }
}

/// "Nice" tick positions covering `[lo, hi]`: the finest step of 1, 2 or 5 × 10^k that gives
/// at most eight intervals.
fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
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
                area.draw(&PathElement::new(
                    run.iter().map(|&(x, y, _)| (x, y)).collect::<Vec<_>>(),
                    color.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?;
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
    let (w, _) = root.dim_in_pixel();
    let body = if plot.title.trim().is_empty() {
        root.clone()
    } else {
        let title = font::fit_text(&plot.title, TITLE_SIZE, w.saturating_sub(40));
        root.margin(MARGIN_PX / 2, 0, 0, 0)
            .titled(&title, (FAMILY, TITLE_SIZE))
            .map_err(|e| e.to_string())?
    };
    // The legend column is as wide as its longest label, but at most 2/5 of the figure.
    let labelled: Vec<(usize, &Prepared)> = series
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.label.trim().is_empty())
        .collect();
    let text_px = labelled
        .iter()
        .map(|(_, s)| font::text_width(&s.label, LEGEND_SIZE))
        .max()
        .unwrap_or(0);
    let legend_w = if labelled.is_empty() {
        0
    } else {
        (text_px + LEGEND_SAMPLE_PX as u32 + 30).min(w * 2 / 5)
    };
    let (chart_area, legend_area) = body.split_horizontally(w - legend_w);
    if plot.log_x {
        let ticks = log_ticks(x.start, x.end);
        let inner: LogCoord<f64> = x.log_scale().into();
        draw_chart(&chart_area, plot, series, Ticked { inner, ticks }, y)?;
    } else {
        let ticks = linear_ticks(x.start, x.end);
        let inner = RangedCoordf64::from(x);
        draw_chart(&chart_area, plot, series, Ticked { inner, ticks }, y)?;
    }
    if legend_w > 0 {
        let max_text = legend_w.saturating_sub(LEGEND_SAMPLE_PX as u32 + 24);
        let style = TextStyle::from((FAMILY, LEGEND_SIZE).into_font())
            .color(&BLACK)
            .pos(Pos::new(HPos::Left, VPos::Center));
        // Long labels wrap onto up to three lines rather than being cut.
        let mut top = MARGIN_PX;
        for (i, s) in &labelled {
            let color = PALETTE[i % PALETTE.len()];
            let lines = font::wrap_text(&s.label, LEGEND_SIZE, max_text, 3);
            let yc = top + LEGEND_LINE_PX / 2;
            legend_area
                .draw(&PathElement::new(
                    vec![(4, yc), (4 + LEGEND_SAMPLE_PX, yc)],
                    color.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?;
            draw_marker(&legend_area, (4 + LEGEND_SAMPLE_PX / 2, yc), *i, color)?;
            for (k, line) in lines.iter().enumerate() {
                let y = yc + k as i32 * LEGEND_LINE_PX;
                legend_area
                    .draw(&Text::new(
                        line.clone(),
                        (LEGEND_SAMPLE_PX + 14, y),
                        style.clone(),
                    ))
                    .map_err(|e| e.to_string())?;
            }
            top += lines.len() as i32 * LEGEND_LINE_PX + LEGEND_GAP_PX;
        }
    }
    root.present().map_err(|e| e.to_string())
}

/// The SVG text and the RGB pixels (row-major, 3 bytes each) of a plot.
fn render(plot: &LinePlot, width: u32, height: u32) -> Result<(String, Vec<u8>)> {
    let (series, x, y) = prepare(plot)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        draw_figure(&root, plot, &series, x.clone(), y.clone()).map_err(Error::Numerical)?;
    }
    let mut rgb = vec![255u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        draw_figure(&root, plot, &series, x, y).map_err(Error::Numerical)?;
    }
    Ok((svg, rgb))
}

/// Writes the plot as SVG and PNG at the default size ([`PLOT_WIDTH_PX`] × [`PLOT_HEIGHT_PX`]).
pub fn write_plot(plot: &LinePlot, svg_path: &Path, png_path: &Path) -> Result<()> {
    write_plot_sized(plot, svg_path, png_path, PLOT_WIDTH_PX, PLOT_HEIGHT_PX)
}

/// Writes the plot as SVG and PNG of `width × height` pixels (each from 320 to 8000).
/// Both are rendered in memory first, so a drawing failure writes neither.
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
    let (svg, rgb) = render(plot, width, height).map_err(|e| match e {
        Error::Numerical(msg) => Error::write(svg_path, std::io::Error::other(msg)),
        other => other.in_file(svg_path),
    })?;
    write_atomic(svg_path, svg.as_bytes())?;
    super::png::write_rgb8(png_path, width, height, &rgb)
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
            for text in [
                "PSNR versus sampling ratio",
                "sampling ratio M/N",
                "PSNR (dB)",
                "single detector",
                "secondary complementary balancing",
                "k₊ &amp; k₋ &lt;balanced&gt;",
            ] {
                assert!(svg.contains(text), "SVG lacks {text:?}");
            }
            let img = image::open(&png_path).unwrap().to_rgb8();
            let _ = std::fs::remove_file(&svg_path);
            let _ = std::fs::remove_file(&png_path);
            assert_eq!(img.dimensions(), (PLOT_WIDTH_PX, PLOT_HEIGHT_PX));
            let first = img.get_pixel(0, 0);
            assert!(img.pixels().any(|p| p != first), "PNG is a single colour");
            // Every series colour appears (lines and markers were drawn), not just text.
            for c in &PALETTE[..3] {
                let n = img.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count();
                assert!(n > 50, "colour {c:?} drawn on only {n} pixels");
            }
            // Dark pixels exist (text and axes) in the title band at the top.
            let dark_in_title = (0..PLOT_WIDTH_PX)
                .flat_map(|x| (0..40).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0.iter().all(|&v| v < 100))
                .count();
            assert!(
                dark_in_title > 100,
                "title band has {dark_in_title} dark pixels"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
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
