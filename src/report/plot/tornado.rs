//! Tornado charts: one row per input (a tolerance), a horizontal bar from 0 to the change it
//! causes at each end of its range, with the change's ±1 standard error as a whisker, in one
//! or more panels side by side (one per output), rows largest first from the top. The labels
//! of the rows sit in a column at the left, shared by the panels. Written like the line plots:
//! one SVG at print size, then PNG (288 dpi, pHYs) and PDF renderings of it.

use std::ops::Range;
use std::path::Path;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::lines::{AXIS_DESC_SIZE, LEGEND_SIZE, MARGIN_PX, PALETTE, TICK_SIZE, fitted_desc};
use super::ticks::{Ticked, format_styled, linear_ticks, tick_style};
use crate::error::{Error, Result};
use crate::report::font::{self, FAMILY};
use crate::report::svg::{FigureSize, UNITS_PER_IN};

/// The change one input causes in one output at each end of its range, each with its standard
/// error: `[value, stderr]` at the low end and at the high end (NaN draws nothing).
pub type TornadoBar = [[f64; 2]; 2];

/// One panel: an output's axis description and each row's bars (in the chart's row order).
#[derive(Debug, Clone, PartialEq)]
pub struct TornadoPanel {
    pub x_label: String,
    pub bars: Vec<TornadoBar>,
}

/// A tornado chart: the row labels (largest first), the panels, and what the two ends are
/// called in the legend.
#[derive(Debug, Clone, PartialEq)]
pub struct Tornado {
    pub rows: Vec<String>,
    pub panels: Vec<TornadoPanel>,
    pub ends: [String; 2],
}

/// The height of one row, in SVG units (half points).
const ROW_UNITS: f64 = 26.0;
/// The figure's height beyond its rows: the axes' ticks and descriptions, the legend.
const FRAME_UNITS: f64 = 150.0;
/// The widest the label column may be, as a share of the figure's width.
const LABEL_SHARE: f64 = 0.34;

impl Tornado {
    /// The printed size: the page's width, a row's height per input.
    pub fn size(&self) -> FigureSize {
        let h = (FRAME_UNITS + ROW_UNITS * self.rows.len().max(1) as f64) / UNITS_PER_IN;
        FigureSize {
            width_in: FigureSize::DOUBLE_COLUMN_IN,
            height_in: h.max(2.0),
        }
    }

    fn check(&self) -> Result<()> {
        if self.rows.is_empty() || self.panels.is_empty() {
            return Err(Error::field(
                "rows",
                "a tornado chart needs a row and a panel",
            ));
        }
        for (i, p) in self.panels.iter().enumerate() {
            if p.bars.len() != self.rows.len() {
                return Err(Error::field(
                    format!("panels[{i}].bars"),
                    format!("{} bars for {} rows", p.bars.len(), self.rows.len()),
                ));
            }
        }
        Ok(())
    }
}

/// The x range of a panel: 0 and every bar's end with its whisker, padded by 5 %.
fn x_range(p: &TornadoPanel) -> Range<f64> {
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for end in p.bars.iter().flatten() {
        let (v, se) = (end[0], if end[1].is_finite() { end[1] } else { 0.0 });
        if v.is_finite() {
            lo = lo.min(v - se);
            hi = hi.max(v + se);
        }
    }
    if hi - lo <= 0.0 {
        return -1.0..1.0;
    }
    let pad = 0.05 * (hi - lo);
    lo - pad..hi + pad
}

/// The SVG text of a tornado chart at its print size, text as outlines.
pub fn render_tornado_svg(t: &Tornado) -> Result<String> {
    t.check()?;
    let (width, height) = t.size().units();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        draw(&root, t).map_err(Error::Numerical)?;
    }
    crate::report::svg::at_print_size(&crate::report::outline::outline_text(&svg)?)
}

/// Writes the chart as SVG, PNG and PDF (beside the SVG), all rendered in memory first.
pub fn write_tornado(t: &Tornado, svg_path: &Path, png_path: &Path) -> Result<()> {
    let svg = render_tornado_svg(t).map_err(|e| match e {
        Error::Numerical(msg) => Error::write(svg_path, std::io::Error::other(msg)),
        other => other.in_file(svg_path),
    })?;
    crate::report::svg::write_figure(&svg, svg_path, png_path, true)
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

fn draw(root: &Area, t: &Tornado) -> std::result::Result<(), String> {
    if !font::ensure_registered() {
        return Err(font::unavailable().to_string());
    }
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (w, h) = root.dim_in_pixel();
    let legend_h = 30;
    let (body, legend) = root.split_vertically(h as i32 - legend_h);
    let widest = t
        .rows
        .iter()
        .map(|r| font::text_width(r, TICK_SIZE))
        .max()
        .unwrap_or(0);
    let label_w = (widest + 12).min((f64::from(w) * LABEL_SHARE) as u32);
    let (labels, panels) = body.split_horizontally(label_w as i32);
    let n = t.panels.len();
    let pw = panels.dim_in_pixel().0 as i32 / n as i32;
    let mut row_px: Vec<i32> = Vec::new();
    let mut rest = panels;
    for (k, p) in t.panels.iter().enumerate() {
        let (area, right) = if k + 1 < n {
            rest.split_horizontally(pw)
        } else {
            (rest.clone(), rest.clone())
        };
        row_px = draw_panel(&area, p, t.rows.len())?;
        rest = right;
    }
    // The row labels, right-aligned against the first panel, at its rows' heights.
    let style = TextStyle::from((FAMILY, TICK_SIZE).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Right, VPos::Center));
    for (label, &y) in t.rows.iter().zip(&row_px) {
        let text = font::fit_text(label, TICK_SIZE, label_w.saturating_sub(12));
        labels
            .draw(&Text::new(text, (label_w as i32 - 6, y), style.clone()))
            .map_err(|e| e.to_string())?;
    }
    // The legend: the two ends' colours and what the whiskers are.
    let style = TextStyle::from((FAMILY, LEGEND_SIZE).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    let entries = [
        (Some(PALETTE[0]), t.ends[0].clone()),
        (Some(PALETTE[1]), t.ends[1].clone()),
        (None, "whiskers: ±1 standard error (paired)".to_string()),
    ];
    let total: u32 = entries
        .iter()
        .map(|(c, l)| font::text_width(l, LEGEND_SIZE) + if c.is_some() { 40 } else { 0 } + 20)
        .sum();
    let mut x = (w.saturating_sub(total) / 2) as i32;
    let yc = legend_h / 2;
    for (color, label) in entries {
        if let Some(c) = color {
            legend
                .draw(&Rectangle::new([(x, yc - 6), (x + 30, yc + 6)], c.filled()))
                .map_err(|e| e.to_string())?;
            x += 40;
        }
        legend
            .draw(&Text::new(label.clone(), (x, yc), style.clone()))
            .map_err(|e| e.to_string())?;
        x += font::text_width(&label, LEGEND_SIZE) as i32 + 20;
    }
    root.present().map_err(|e| e.to_string())
}

/// Draws one panel and returns the pixel heights (in the figure) of its rows' centres.
fn draw_panel(area: &Area, p: &TornadoPanel, rows: usize) -> std::result::Result<Vec<i32>, String> {
    let x = x_range(p);
    let ticks = linear_ticks(x.start, x.end);
    let style = tick_style(&ticks);
    let (w, _) = area.dim_in_pixel();
    let (desc, size) = fitted_desc(&p.x_label, w as i32 - 2 * MARGIN_PX);
    let mut chart = ChartBuilder::on(area)
        .margin(MARGIN_PX)
        .margin_left(MARGIN_PX / 2)
        .x_label_area_size(48)
        .y_label_area_size(0)
        .build_cartesian_2d(
            Ticked {
                inner: RangedCoordf64::from(x.clone()),
                ticks,
            },
            0.0..rows as f64,
        )
        .map_err(|e| e.to_string())?;
    let formatter = |v: &f64| format_styled(*v, style).replace('-', "−");
    chart
        .configure_mesh()
        .disable_y_mesh()
        .disable_y_axis()
        .x_desc(desc.as_str())
        .axis_desc_style((FAMILY, size.min(AXIS_DESC_SIZE)))
        .label_style((FAMILY, TICK_SIZE))
        .x_label_formatter(&formatter)
        .bold_line_style(RGBColor(0, 0, 0).mix(0.12))
        .draw()
        .map_err(|e| e.to_string())?;
    let plot = chart.plotting_area();
    let err = |e: DrawingAreaErrorKind<_>| e.to_string();
    plot.draw(&PathElement::new(
        vec![(0.0, 0.0), (0.0, rows as f64)],
        BLACK.stroke_width(1),
    ))
    .map_err(err)?;
    let mut centres = Vec::with_capacity(rows);
    for (i, bar) in p.bars.iter().enumerate() {
        // Row 0 at the top.
        let top = (rows - i) as f64;
        centres.push(chart.backend_coord(&(x.start, top - 0.5)).1);
        for (k, end) in bar.iter().enumerate() {
            let (v, se) = (end[0], end[1]);
            if !v.is_finite() {
                continue;
            }
            let (y0, y1) = (top - 0.12 - 0.38 * k as f64, top - 0.46 - 0.38 * k as f64);
            plot.draw(&Rectangle::new(
                [(0.0, y0), (v, y1)],
                PALETTE[k].mix(0.85).filled(),
            ))
            .map_err(err)?;
            if se.is_finite() && se > 0.0 {
                let ym = 0.5 * (y0 + y1);
                let cap = 0.1;
                for path in [
                    vec![(v - se, ym), (v + se, ym)],
                    vec![(v - se, ym - cap), (v - se, ym + cap)],
                    vec![(v + se, ym - cap), (v + se, ym + cap)],
                ] {
                    plot.draw(&PathElement::new(path, BLACK.stroke_width(1)))
                        .map_err(err)?;
                }
            }
        }
    }
    Ok(centres)
}
