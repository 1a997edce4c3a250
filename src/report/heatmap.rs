//! Heatmaps of a quantity over a 2-D grid of two variables (a sweep), with a colour bar in the
//! quantity's units and a marked reference point (the nominal bench). SVG and PNG are drawn
//! by the same code on plotters' two backends.

use std::path::Path;

use plotters::prelude::*;

use super::font::{self, FAMILY};
use super::npy::write_atomic;
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

const WIDTH: u32 = 900;
const HEIGHT: u32 = 680;
const TICK_SIZE: f64 = 17.0;
const DESC_SIZE: f64 = 21.0;

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

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    h: &Heatmap,
    (lo, hi): (f64, f64),
) -> std::result::Result<(), String> {
    if !font::ensure_registered() {
        return Err(font::unavailable().to_string());
    }
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (main, bar) = root.split_horizontally(WIDTH as i32 - 190);
    let (ex, ey) = (edges(&h.xs), edges(&h.ys));
    let xr = ex[0].min(ex[ex.len() - 1])..ex[0].max(ex[ex.len() - 1]);
    let yr = ey[0].min(ey[ey.len() - 1])..ey[0].max(ey[ey.len() - 1]);
    let mut chart = ChartBuilder::on(&main)
        .margin(18)
        .x_label_area_size(58)
        .y_label_area_size(90)
        .build_cartesian_2d(xr.clone(), yr.clone())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(h.x_label.as_str())
        .y_desc(h.y_label.as_str())
        .axis_desc_style((FAMILY, DESC_SIZE))
        .label_style((FAMILY, TICK_SIZE))
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
    if let Some((mx, my)) = h.mark
        && xr.contains(&mx)
        && yr.contains(&my)
    {
        let style = ShapeStyle::from(&WHITE).stroke_width(3);
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((mx, my)) + Cross::new((0, 0), 9, style),
            ))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((mx, my))
                    + Cross::new((0, 0), 7, ShapeStyle::from(&BLACK).stroke_width(1)),
            ))
            .map_err(|e| e.to_string())?;
    }
    // The colour bar: a column of 100 steps from lo to hi, with its own value axis.
    let mut cb = ChartBuilder::on(&bar)
        .margin_top(18)
        .margin_bottom(76)
        .margin_right(8)
        .y_label_area_size(110)
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(|e| e.to_string())?;
    cb.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(h.value_label.as_str())
        .axis_desc_style((FAMILY, DESC_SIZE))
        .label_style((FAMILY, TICK_SIZE))
        .y_label_formatter(&|v| {
            let s = if v.abs() >= 1e4 || (v.abs() < 1e-2 && *v != 0.0) {
                format!("{v:.2e}")
            } else {
                super::plot::format_tick(*v)
            };
            s.replace('-', "−")
        })
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

/// The SVG text and the PNG bytes of a heatmap.
pub fn render(h: &Heatmap) -> Result<(String, Vec<u8>)> {
    let range = check(h)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, HEIGHT)).into_drawing_area();
        draw(&root, h, range).map_err(Error::Numerical)?;
    }
    let mut rgb = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (WIDTH, HEIGHT)).into_drawing_area();
        draw(&root, h, range).map_err(Error::Numerical)?;
    }
    let png = super::png::encode_rgb8(WIDTH, HEIGHT, &rgb)?;
    Ok((svg, png))
}

/// Writes the heatmap as SVG and PNG.
pub fn write_heatmap(h: &Heatmap, svg_path: &Path, png_path: &Path) -> Result<()> {
    let (svg, png) = render(h)?;
    write_atomic(svg_path, svg.as_bytes())?;
    write_atomic(png_path, &png)
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
}
