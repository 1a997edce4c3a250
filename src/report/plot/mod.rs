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
//!
//! The module's files: `lines.rs` (line plots), `write.rs` (their SVG, PNG and PDF writers),
//! `ticks.rs` (tick positions and labels), `scope.rs` (oscilloscope panels), `tornado.rs`
//! (tornado charts of a sensitivity table).

mod lines;
mod scope;
#[cfg(test)]
mod tests;
mod ticks;
mod tornado;
mod write;

pub use super::svg::FigureSize;
pub use lines::{
    Area, Band, BandAxis, LinePlot, MARK_EVERY_POINT_UP_TO, Mark, Markers, PLOT_HEIGHT_PX,
    PLOT_WIDTH_PX, PlotOptions, Series, default_size,
};
pub use scope::{SCOPE_PANEL_PX, SCOPE_WIDTH_PX, ScopePlot, scope_svg, write_scope};
pub use ticks::format_tick;
pub(crate) use ticks::linear_ticks;
pub use tornado::{Tornado, TornadoBar, TornadoPanel, render_tornado_svg, write_tornado};
pub use write::{render_svg, render_svg_with, write_plot, write_plot_sized, write_plot_with};
