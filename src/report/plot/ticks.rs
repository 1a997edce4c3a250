//! Axis ticks: where they go (linear and logarithmic) and how their labels are written.

use std::ops::Range;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};

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
pub(super) enum TickStyle {
    /// [`format_tick`]: plain decimals.
    Plain,
    /// Every non-zero tick as `2.5e-4`.
    Scientific,
    /// Every tick as `10⁻³`: for whole decades on a log axis.
    PowerOfTen,
}

pub(super) fn needs_scientific(v: f64) -> bool {
    v != 0.0 && v.is_finite() && !(-3..5).contains(&(v.abs().log10().floor() as i32))
}

pub(super) fn tick_style(ticks: &[f64]) -> TickStyle {
    let is_decade = |t: f64| t > 0.0 && (t.log10() - t.log10().round()).abs() < 1e-9;
    if !ticks.iter().any(|&t| needs_scientific(t)) {
        TickStyle::Plain
    } else if ticks.iter().all(|&t| is_decade(t)) {
        TickStyle::PowerOfTen
    } else {
        TickStyle::Scientific
    }
}

pub(super) fn scientific(v: f64) -> String {
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

pub(super) fn format_styled(v: f64, style: TickStyle) -> String {
    match style {
        TickStyle::Plain => format_tick(v),
        TickStyle::Scientific if v != 0.0 && v.is_finite() => scientific(v),
        TickStyle::PowerOfTen if v > 0.0 && v.is_finite() => {
            let sup = crate::report::superscript(v.log10().round() as i32);
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
pub(super) fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
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
pub(super) struct Ticked<R> {
    pub(super) inner: R,
    pub(super) ticks: Vec<f64>,
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
