//! Transmittance masks for the chart plane: the analytic 1951 USAF chart, an image, or clear
//! glass. A mask answers one question per ray: the fraction of clear glass at a chart point.

use crate::objects::usaf::UsafChart;
use crate::raster::Raster;

/// What is printed on the chrome side of a chart plate.
#[derive(Debug, Clone)]
pub enum ChartMask {
    /// No chrome anywhere: a plain glass plate.
    Clear,
    /// The analytic 1951 USAF chart (crate::objects::usaf), chart millimetres with the origin at
    /// the plate centre.
    Usaf(UsafChart),
    /// An image as a transmittance mask: pixel values in [0, 1] are the clear-area fraction of
    /// each pixel (1 = clear glass, 0 = chrome). The image has the given physical size, is
    /// centred on the plate centre, row 0 at the top (largest v); outside it the plate is chrome.
    Image {
        raster: Raster,
        width_m: f64,
        height_m: f64,
    },
}

impl ChartMask {
    /// The fraction of clear glass at chart coordinates (x, y) in metres from the plate centre.
    #[inline]
    pub fn clear_fraction(&self, x_m: f64, y_m: f64) -> f64 {
        match self {
            ChartMask::Clear => 1.0,
            ChartMask::Usaf(chart) => {
                if chart.is_clear(x_m * 1e3, y_m * 1e3) {
                    1.0
                } else {
                    0.0
                }
            }
            ChartMask::Image {
                raster,
                width_m,
                height_m,
            } => {
                let fx = x_m / width_m + 0.5;
                let fy = 0.5 - y_m / height_m;
                if !(0.0..1.0).contains(&fx) || !(0.0..1.0).contains(&fy) {
                    return 0.0;
                }
                let c = ((fx * raster.width as f64) as usize).min(raster.width - 1);
                let r = ((fy * raster.height as f64) as usize).min(raster.height - 1);
                raster.get(r, c)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_mask_orientation_and_outside() {
        // 2×2 image: top-left 1, others 0; 2 mm square.
        let r = Raster::new(2, 2, vec![1.0, 0.0, 0.0, 0.25]).unwrap();
        let m = ChartMask::Image {
            raster: r,
            width_m: 2e-3,
            height_m: 2e-3,
        };
        assert_eq!(m.clear_fraction(-0.5e-3, 0.5e-3), 1.0); // top left
        assert_eq!(m.clear_fraction(0.5e-3, -0.5e-3), 0.25); // bottom right
        assert_eq!(m.clear_fraction(0.5e-3, 0.5e-3), 0.0);
        assert_eq!(m.clear_fraction(1.5e-3, 0.0), 0.0); // outside: chrome
        assert_eq!(ChartMask::Clear.clear_fraction(5.0, 5.0), 1.0);
    }
}
