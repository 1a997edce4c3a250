//! Oscilloscope panels: one channel per panel on a shared time axis, frames numbered and their
//! settled windows shaded.

use std::ops::Range;
use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::lines::{AXIS_DESC_SIZE, MARGIN_PX, TICK_SIZE, pad_range};
use super::ticks::{Ticked, format_styled, linear_ticks, tick_style};
use crate::error::{Error, Result};
use crate::report::font::{self, FAMILY};

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
pub(super) const SCOPE_AXIS_PX: u32 = 62;
/// The band above the top panel for the frame numbers.
pub(super) const SCOPE_FRAMES_PX: u32 = 24;

/// Which frames get their number written: every k-th, so that numbers keep a gap of at least
/// their own width between them (`frame_w` is the frame's width in SVG units).
pub(super) fn frame_label_step(frame_w: f64, frames: i64) -> i64 {
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

pub(super) fn draw_scope<DB: DrawingBackend>(
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
pub(super) fn draw_frame_numbers<DB, CT>(
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
    crate::report::svg::at_print_size(&crate::report::outline::outline_text(&svg)?)
}

/// Writes an oscilloscope figure as SVG, its PNG rendering, and PDF beside the SVG.
pub fn write_scope(p: &ScopePlot, svg_path: &Path, png_path: &Path) -> Result<()> {
    let svg = scope_svg(p).map_err(|e| e.in_file(svg_path))?;
    crate::report::svg::write_figure(&svg, svg_path, png_path, true)
}
