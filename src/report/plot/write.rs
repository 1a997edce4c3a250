//! The line plots' writers: a plot rendered to SVG at print size (its ranges widened to keep
//! limits and marks in view), and written as SVG, PNG and PDF.

use std::ops::Range;
use std::path::Path;

use plotters::prelude::*;

use super::lines::{
    BandAxis, LinePlot, PlotOptions, default_size, draw_figure, prepare, prepare_extras,
};
use crate::error::{Error, Result};
use crate::report::svg::FigureSize;

/// `r` widened, if needed, to hold `v` (kept in view with a small pad beyond it).
fn include(r: Range<f64>, v: f64, log: bool) -> Range<f64> {
    if !v.is_finite() || r.contains(&v) || (log && v <= 0.0) {
        return r;
    }
    if log {
        let (lo, hi) = (r.start.min(v), r.end.max(v));
        let pad = (hi / lo).ln() * 0.03;
        return if v < r.start {
            lo * (-pad).exp()..r.end
        } else {
            r.start..hi * pad.exp()
        };
    }
    let pad = (r.end.max(v) - r.start.min(v)) * 0.04;
    if v < r.start {
        v - pad..r.end
    } else {
        r.start..v + pad
    }
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
    let (series, mut x, mut y) = prepare(plot)?;
    let extras = prepare_extras(opts, plot.log_x)?;
    // The x range covers the areas too.
    for a in &extras.areas {
        if let (Some(f), Some(l)) = (a.pts.first(), a.pts.last()) {
            x = x.start.min(f.0)..x.end.max(l.0);
        }
    }
    // Limits and their crossings stay in view.
    for b in &extras.bands {
        for v in [b.lo, b.hi] {
            match b.axis {
                BandAxis::Y => y = include(y, v, false),
                BandAxis::X => x = include(x, v, plot.log_x),
            }
        }
    }
    for m in &extras.marks {
        x = include(x, m.x, plot.log_x);
        y = include(y, m.y, false);
    }
    let lower = match &opts.lower {
        None => None,
        Some(lp) => {
            let (ls, lx, ly) = prepare(lp)?;
            x = x.start.min(lx.start)..x.end.max(lx.end);
            Some((lp.as_ref(), ls, ly))
        }
    };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        draw_figure(&root, plot, &series, &extras, lower, x, y).map_err(Error::Numerical)?;
    }
    crate::report::svg::at_print_size(&crate::report::outline::outline_text(&svg)?)
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
    crate::report::svg::write_figure(&svg, svg_path, png_path, true)
}
