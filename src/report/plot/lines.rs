//! Line plots: series with markers, dashes and error bars, filled areas on a secondary scale and
//! the legend band, drawn on a plotters area (the writers are `write.rs`).

use std::ops::Range;

use plotters::coord::Shift;
use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::ticks::{Ticked, format_styled, format_tick, linear_ticks, log_ticks, tick_style};
use crate::error::{Error, Result};
use crate::report::font::{self, FAMILY};

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
pub(super) const AXIS_DESC_SIZE: f64 = 22.0;
pub(super) const TICK_SIZE: f64 = 20.0;
pub(super) const LEGEND_SIZE: f64 = 20.0;
pub(super) const MARGIN_PX: i32 = 14;
pub(super) const LEGEND_LINE_PX: i32 = 22;
pub(super) const LEGEND_GAP_PX: i32 = 20;
pub(super) const LEGEND_SAMPLE_PX: i32 = 40;
/// A series of up to this many points has a marker on every point (measured points: a sweep's
/// grid, a scheme's sampling ratios, trials); a longer one is a sampled curve (a spectrum), which
/// gets about [`MARKERS_PER_SERIES`] markers, each series starting at a different point, so that
/// markers of curves that lie on each other alternate along them instead of hiding each other.
pub const MARK_EVERY_POINT_UP_TO: usize = 64;
pub(super) const MARKERS_PER_SERIES: usize = 12;

/// Where a plot's series carry markers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Markers {
    /// On every point of a series of up to [`MARK_EVERY_POINT_UP_TO`] points, spread along a
    /// longer one.
    #[default]
    Auto,
    /// None: outlines, such as a histogram's, whose corners are not measured points.
    None,
}

/// Which axis a [`Band`] spans.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BandAxis {
    /// A horizontal band between two y values.
    Y,
    /// A vertical band between two x values.
    X,
}

/// A shaded band behind the curves: the region a limit allows (for |m| ≤ L, from −L to L).
/// An infinite end reaches the edge of the axes; a finite one is drawn as a thin line and kept
/// in view.
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    pub label: String,
    pub axis: BandAxis,
    pub lo: f64,
    pub hi: f64,
}

/// A point marked on top of the curves (a limit crossing), with an optional interval along x
/// (its 95 % interval).
#[derive(Debug, Clone, PartialEq)]
pub struct Mark {
    pub x: f64,
    pub y: f64,
    pub x_interval: Option<[f64; 2]>,
}

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
    pub size: Option<crate::report::svg::FigureSize>,
    /// Filled areas behind the curves, with their scale on the right.
    pub areas: Vec<Area>,
    /// The secondary scale's label (used when there are areas).
    pub area_label: String,
    /// Shaded bands behind the curves (limits), one legend entry each.
    pub bands: Vec<Band>,
    /// Points marked on top of the curves (limit crossings), one legend entry for all.
    pub marks: Vec<Mark>,
    /// The legend entry of the marks.
    pub mark_label: String,
    /// Where the series carry markers.
    pub markers: Markers,
    /// Each series drawn as steps (a value held until the next point, as an empirical CDF).
    pub steps: bool,
    /// A second panel below the first, on the same x axis, its series drawn in the same styles
    /// as the first panel's of the same index (a difference to the best curve, for example);
    /// its x label is the figure's, and the legend is the first panel's.
    pub lower: Option<Box<LinePlot>>,
}

use crate::report::svg::FigureSize;

/// Dash patterns (dash, gap) in px, cycled with a period (5) coprime to the palette's (7) and
/// the markers' (6); `None` is a solid line.
pub(super) const DASHES: [Option<(i32, i32)>; 5] = [
    None,
    Some((12, 6)),
    Some((3, 4)),
    Some((20, 5)),
    Some((7, 3)),
];

/// Okabe–Ito colours, distinguishable with the common colour-vision deficiencies.
pub(super) const PALETTE: [RGBColor; 7] = [
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
pub(super) const MARKERS: usize = 6;

/// A series reduced to what can be drawn: runs of consecutive plottable points (a missing
/// point breaks the line) with their error half-lengths (0 = no bar).
pub(super) struct Prepared {
    label: String,
    runs: Vec<Vec<(f64, f64, f64)>>,
}

/// The drawable series with the x and y ranges to show.
pub(super) type PreparedPlot = (Vec<Prepared>, Range<f64>, Range<f64>);

pub(super) fn prepare(plot: &LinePlot) -> Result<PreparedPlot> {
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
pub(super) fn pad_range(lo: f64, hi: f64, frac: f64) -> Range<f64> {
    if hi > lo {
        let p = (hi - lo) * frac;
        lo - p..hi + p
    } else {
        let p = if lo == 0.0 { 1.0 } else { lo.abs() * 0.5 };
        lo - p..hi + p
    }
}

pub(super) fn draw_marker<DB, CT>(
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
pub(super) fn draw_line<DB, CT>(
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

/// The width of the y label area for a y range: the widest tick text and the rotated axis
/// description.
pub(super) fn y_label_width(y: &Range<f64>) -> i32 {
    let y_ticks = linear_ticks(y.start, y.end);
    let y_style = tick_style(&y_ticks);
    let tick_w = y_ticks
        .iter()
        .map(|t| font::text_width(&format_styled(*t, y_style).replace('-', "−"), TICK_SIZE))
        .max()
        .unwrap_or(0);
    tick_w as i32 + 44
}

/// An axis description that fits in `avail` units: at its size if it fits, else at a smaller
/// size down to the tick labels' (8 pt), else shortened with an ellipsis at that size.
pub(super) fn fitted_desc(text: &str, avail: i32) -> (String, f64) {
    let avail = avail.max(0) as u32;
    if font::text_width(text, AXIS_DESC_SIZE) <= avail {
        return (text.to_string(), AXIS_DESC_SIZE);
    }
    if font::text_width(text, TICK_SIZE) <= avail {
        return (text.to_string(), TICK_SIZE);
    }
    (font::fit_text(text, TICK_SIZE, avail), TICK_SIZE)
}

/// One panel of a figure: its series, the axes' ranges and descriptions.
pub(super) struct Panel<'a> {
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: &'a [Prepared],
    pub extras: &'a Extras,
    pub y: Range<f64>,
    /// The y label area's width, shared by the panels so that their axes line up.
    pub label_w: i32,
}

/// The band's ends clipped to the axis range.
fn clip(lo: f64, hi: f64, r: &Range<f64>) -> Option<(f64, f64)> {
    let (a, b) = (lo.max(r.start), hi.min(r.end));
    (a < b).then_some((a, b))
}

/// The shade of a limit band and the colour of its finite edges.
pub(super) const BAND_FILL: RGBColor = RGBColor(0, 158, 115);
pub(super) const BAND_OPACITY: f64 = 0.14;
/// The colour of limit crossings.
pub(super) const MARK_COLOR: RGBColor = RGBColor(0, 0, 0);

pub(super) fn draw_chart<DB, XR>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    x: Ticked<XR>,
    x_range: Range<f64>,
) -> std::result::Result<(), String>
where
    DB: DrawingBackend,
    XR: Ranged<ValueType = f64>,
{
    let (series, extras, y) = (panel.series, panel.extras, panel.y.clone());
    let y_ticks = linear_ticks(y.start, y.end);
    let (x_style, y_style) = (tick_style(&x.ticks), tick_style(&y_ticks));
    let right = if extras.areas.is_empty() {
        0
    } else {
        font::text_width("0.75", TICK_SIZE) as i32 + 44
    };
    let (w, h) = area.dim_in_pixel();
    let x_label_h = if panel.x_label.is_empty() { 28 } else { 48 };
    let (x_desc, x_size) = fitted_desc(
        panel.x_label,
        w as i32 - panel.label_w - 2 * MARGIN_PX - right,
    );
    let (y_desc, y_size) = fitted_desc(panel.y_label, h as i32 - x_label_h - 2 * MARGIN_PX);
    // The secondary scale sits in a right margin, not a label area: plotters would repeat the
    // primary axis' labels in a right label area.
    let mut chart = ChartBuilder::on(area)
        .margin(MARGIN_PX)
        .margin_right(MARGIN_PX + right)
        .x_label_area_size(x_label_h)
        .y_label_area_size(panel.label_w)
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
    // One size for both descriptions: the smaller of the two fits.
    let desc_size = x_size.min(y_size);
    chart
        .configure_mesh()
        .x_desc(x_desc.as_str())
        .y_desc(y_desc.as_str())
        .axis_desc_style((FAMILY, desc_size))
        .label_style((FAMILY, TICK_SIZE))
        .x_label_formatter(&x_formatter)
        .y_label_formatter(&y_formatter)
        .bold_line_style(RGBColor(0, 0, 0).mix(0.12))
        .draw()
        .map_err(|e| e.to_string())?;
    if !extras.areas.is_empty() {
        draw_areas(area, &chart, extras, &y)?;
    }
    let plot_area = chart.plotting_area();
    for b in &extras.bands {
        let (range, other) = match b.axis {
            BandAxis::Y => (&y, &x_range),
            BandAxis::X => (&x_range, &y),
        };
        let Some((lo, hi)) = clip(b.lo, b.hi, range) else {
            continue;
        };
        let corner = |v: f64, o: f64| match b.axis {
            BandAxis::Y => (o, v),
            BandAxis::X => (v, o),
        };
        plot_area
            .draw(&Rectangle::new(
                [corner(lo, other.start), corner(hi, other.end)],
                BAND_FILL.mix(BAND_OPACITY).filled(),
            ))
            .map_err(|e| e.to_string())?;
        for edge in [b.lo, b.hi] {
            if edge.is_finite() && range.contains(&edge) {
                plot_area
                    .draw(&PathElement::new(
                        vec![corner(edge, other.start), corner(edge, other.end)],
                        BAND_FILL.mix(0.8).stroke_width(1),
                    ))
                    .map_err(|e| e.to_string())?;
            }
        }
    }
    for (i, s) in series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let points: usize = s.runs.iter().map(Vec::len).sum();
        let step = if points <= MARK_EVERY_POINT_UP_TO {
            1
        } else {
            points.div_ceil(MARKERS_PER_SERIES).max(1)
        };
        let mut k = 0usize;
        for run in &s.runs {
            if run.len() > 1 {
                let mut line: Vec<(f64, f64)> = Vec::with_capacity(2 * run.len());
                for (j, &(x, y, _)) in run.iter().enumerate() {
                    if extras.steps && j > 0 {
                        line.push((x, run[j - 1].1));
                    }
                    line.push((x, y));
                }
                draw_line(plot_area, line, i)?;
            }
            for &(x, y, e) in run {
                if e > 0.0 {
                    let style = color.stroke_width(2);
                    plot_area
                        .draw(&PathElement::new(vec![(x, y - e), (x, y + e)], style))
                        .map_err(|e| e.to_string())?;
                    for end in [y - e, y + e] {
                        plot_area
                            .draw(
                                &(EmptyElement::at((x, end))
                                    + PathElement::new(vec![(-4, 0), (4, 0)], style)),
                            )
                            .map_err(|e| e.to_string())?;
                    }
                }
                if extras.markers == Markers::Auto && (k + i).is_multiple_of(step) {
                    draw_marker(plot_area, (x, y), i, color)?;
                }
                k += 1;
            }
        }
    }
    for m in &extras.marks {
        draw_mark(plot_area, m, &x_range, &y)?;
    }
    Ok(())
}

/// A limit crossing: a thin dotted line across the axes at its x, its interval as a bar, and
/// a ring at the crossing.
pub(super) fn draw_mark<DB, CT>(
    area: &DrawingArea<DB, CT>,
    m: &Mark,
    x_range: &Range<f64>,
    y: &Range<f64>,
) -> std::result::Result<(), String>
where
    DB: DrawingBackend,
    CT: plotters::coord::CoordTranslate<From = (f64, f64)>,
{
    let style = MARK_COLOR.stroke_width(1);
    area.draw(&DashedPathElement::new(
        vec![(m.x, y.start), (m.x, y.end)],
        2,
        4,
        style,
    ))
    .map_err(|e| e.to_string())?;
    if let Some([a, b]) = m.x_interval
        && let Some((a, b)) = clip(a, b, x_range)
    {
        let bar = MARK_COLOR.stroke_width(2);
        area.draw(&PathElement::new(vec![(a, m.y), (b, m.y)], bar))
            .map_err(|e| e.to_string())?;
        for end in [a, b] {
            area.draw(
                &(EmptyElement::at((end, m.y)) + PathElement::new(vec![(0, -5), (0, 5)], bar)),
            )
            .map_err(|e| e.to_string())?;
        }
    }
    draw_mark_symbol(area, (m.x, m.y))
}

/// The ring that marks a crossing (also its legend sample).
pub(super) fn draw_mark_symbol<DB, CT>(
    area: &DrawingArea<DB, CT>,
    at: CT::From,
) -> std::result::Result<(), String>
where
    DB: DrawingBackend,
    CT: plotters::coord::CoordTranslate,
{
    area.draw(&(EmptyElement::at(at) + Circle::new((0, 0), 8, MARK_COLOR.stroke_width(2))))
        .map_err(|e| e.to_string())
}

/// The colour of area `i`: light tints, unlike the curves' colours, so that the curves stay in
/// front.
pub(super) const AREA_FILL: [RGBColor; 4] = [
    RGBColor(230, 159, 0),
    RGBColor(0, 114, 178),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
];
pub(super) const AREA_OPACITY: f64 = 0.22;

/// The filled areas behind the curves, on the secondary scale: 0 at the bottom of the axes, 1
/// at the top of the primary range's data (so the scale's ticks 0 … 1 sit on the right axis).
pub(super) fn draw_areas<DB, XR>(
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
pub(super) const SECONDARY_TOP: f64 = 1.0;

/// A legend entry: a curve (by series index) or a filled area (by area index).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Entry {
    Curve(usize),
    Area(usize),
    Band(usize),
    Mark,
}

/// The legend's entries placed in rows: each row holds as many entries as fit in `width`,
/// left to right; the curves first, then the areas.
pub(super) fn legend_rows(
    series: &[Prepared],
    extras: &Extras,
    width: u32,
) -> Vec<Vec<(Entry, String)>> {
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
        )
        .chain(
            extras
                .bands
                .iter()
                .enumerate()
                .map(|(k, b)| (Entry::Band(k), &b.label)),
        )
        .chain((!extras.marks.is_empty()).then_some((Entry::Mark, &extras.mark_label)));
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

pub(super) fn entry_width(label: &str) -> u32 {
    LEGEND_SAMPLE_PX as u32 + 6 + font::text_width(label, LEGEND_SIZE) + LEGEND_GAP_PX as u32
}

pub(super) fn legend_height(rows: usize) -> i32 {
    if rows == 0 {
        0
    } else {
        rows as i32 * LEGEND_LINE_PX + MARGIN_PX / 2
    }
}

/// The filled areas reduced to what can be drawn: finite points in order of x, clipped to
/// the secondary scale.
pub(super) struct PreparedArea {
    label: String,
    pub(super) pts: Vec<(f64, f64)>,
}

pub(super) struct Extras {
    pub(super) areas: Vec<PreparedArea>,
    area_label: String,
    pub(super) bands: Vec<Band>,
    pub(super) marks: Vec<Mark>,
    mark_label: String,
    markers: Markers,
    steps: bool,
}

impl Extras {
    /// The drawing options of a lower panel: the same markers and steps, nothing else.
    fn for_lower(&self) -> Extras {
        Extras {
            areas: Vec::new(),
            area_label: String::new(),
            bands: Vec::new(),
            marks: Vec::new(),
            mark_label: String::new(),
            markers: self.markers,
            steps: self.steps,
        }
    }
}

pub(super) fn prepare_extras(opts: &PlotOptions, log_x: bool) -> Result<Extras> {
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
    for (k, b) in opts.bands.iter().enumerate() {
        if b.lo.is_nan() || b.hi.is_nan() || b.hi < b.lo {
            return Err(Error::field(
                format!("bands[{k}]"),
                format!(
                    "band {:?} needs lo ≤ hi, got {} and {}",
                    b.label, b.lo, b.hi
                ),
            ));
        }
    }
    Ok(Extras {
        areas,
        area_label: opts.area_label.clone(),
        bands: opts.bands.clone(),
        marks: opts
            .marks
            .iter()
            .filter(|m| m.x.is_finite() && m.y.is_finite() && (!log_x || m.x > 0.0))
            .cloned()
            .collect(),
        mark_label: opts.mark_label.clone(),
        markers: opts.markers,
        steps: opts.steps,
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
    let size = size
        .taller(extra_rows as f64 * f64::from(LEGEND_LINE_PX) / crate::report::svg::UNITS_PER_IN);
    // A lower panel adds its share of the axes' height.
    if opts.lower.is_some() {
        size.taller(LOWER_EXTRA_IN)
    } else {
        size
    }
}

/// The lower panel's share of the axes' height.
const LOWER_SHARE: f64 = 0.4;
/// The height a lower panel adds to a figure's default size.
const LOWER_EXTRA_IN: f64 = 1.4;

/// A prepared lower panel: its plot, series and y range.
pub(super) type Lower<'a> = (&'a LinePlot, Vec<Prepared>, Range<f64>);

/// Draws one panel on its area, on a linear or logarithmic x axis.
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    log_x: bool,
    x: Range<f64>,
) -> std::result::Result<(), String> {
    if log_x {
        let ticks = log_ticks(x.start, x.end);
        let inner: LogCoord<f64> = x.clone().log_scale().into();
        draw_chart(area, panel, Ticked { inner, ticks }, x)
    } else {
        let ticks = linear_ticks(x.start, x.end);
        let inner = RangedCoordf64::from(x.clone());
        draw_chart(area, panel, Ticked { inner, ticks }, x)
    }
}

/// Draws the whole figure on `root` (already `width × height`).
pub(super) fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plot: &LinePlot,
    series: &[Prepared],
    extras: &Extras,
    lower: Option<Lower>,
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
    let label_w = lower
        .as_ref()
        .map_or(0, |(_, _, ly)| y_label_width(ly))
        .max(y_label_width(&y));
    let upper = Panel {
        x_label: if lower.is_some() { "" } else { &plot.x_label },
        y_label: &plot.y_label,
        series,
        extras,
        y,
        label_w,
    };
    match &lower {
        None => draw_panel(&chart_area, &upper, plot.log_x, x)?,
        Some((lp, lseries, ly)) => {
            let ch = f64::from(chart_area.dim_in_pixel().1);
            let (top, bottom) = chart_area.split_vertically((ch * (1.0 - LOWER_SHARE)) as i32);
            draw_panel(&top, &upper, plot.log_x, x.clone())?;
            let lextras = extras.for_lower();
            let panel = Panel {
                x_label: &plot.x_label,
                y_label: &lp.y_label,
                series: lseries,
                extras: &lextras,
                y: ly.clone(),
                label_w,
            };
            draw_panel(&bottom, &panel, plot.log_x, x)?;
        }
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
            let sample = [(left, yc - 7), (left + LEGEND_SAMPLE_PX, yc + 7)];
            let shade = |color: RGBColor, opacity: f64| {
                legend_area
                    .draw(&Rectangle::new(sample, color.mix(opacity).filled()))
                    .and_then(|_| {
                        legend_area.draw(&Rectangle::new(sample, color.mix(0.7).stroke_width(1)))
                    })
                    .map_err(|e| e.to_string())
            };
            match *entry {
                Entry::Curve(i) => {
                    let color = PALETTE[i % PALETTE.len()];
                    draw_line(
                        &legend_area,
                        vec![(left, yc), (left + LEGEND_SAMPLE_PX, yc)],
                        i,
                    )?;
                    if extras.markers == Markers::Auto {
                        draw_marker(&legend_area, (left + LEGEND_SAMPLE_PX / 2, yc), i, color)?;
                    }
                }
                Entry::Area(k) => shade(AREA_FILL[k % AREA_FILL.len()], AREA_OPACITY)?,
                Entry::Band(_) => shade(BAND_FILL, BAND_OPACITY)?,
                Entry::Mark => draw_mark_symbol(&legend_area, (left + LEGEND_SAMPLE_PX / 2, yc))?,
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
