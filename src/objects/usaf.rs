//! The 1951 USAF resolution chart (MIL-STD-150A geometry), analytic.
//!
//! The chart is a set of axis-aligned rectangles (bars) in millimetres, in chart coordinates
//! with the origin at the centre of the plate, x to the right and y up. It is shared by the
//! object renderer (area-averaged rasters) and the optical bench (point transmittance).
//!
//! API CONTRACT (implementation pending): see the doc comments below.

use crate::raster::Raster;

/// Clear bars in chrome (negative, as the paper's Thorlabs R3L3S1N) or chrome bars on glass.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Polarity {
    Negative,
    Positive,
}

/// One bar: an axis-aligned rectangle in chart millimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bar {
    pub x0_mm: f64,
    pub y0_mm: f64,
    pub x1_mm: f64,
    pub y1_mm: f64,
    pub group: i32,
    pub element: u8,
    /// True for the three bars that run horizontally (they resolve vertical detail).
    pub horizontal: bool,
}

/// A rectangular region of the chart in millimetres (centre and size).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    pub center_x_mm: f64,
    pub center_y_mm: f64,
    pub width_mm: f64,
    pub height_mm: f64,
}

#[derive(Debug, Clone)]
pub struct UsafChart {
    pub min_group: i32,
    pub max_group: i32,
    pub polarity: Polarity,
}

impl UsafChart {
    /// Every bar of groups `min_group..=max_group`.
    pub fn bars(&self) -> Vec<Bar> {
        todo!("USAF layout")
    }

    /// True where the chart is clear glass (a bar for a negative chart, the field for a positive one).
    pub fn is_clear(&self, _x_mm: f64, _y_mm: f64) -> bool {
        todo!("USAF point query")
    }

    /// The bounding box of one element (both bar triplets), for choosing imaging regions.
    pub fn element_region(&self, _group: i32, _element: u8) -> Option<Region> {
        todo!("USAF element box")
    }

    /// The fraction of clear area in each pixel of a `width`×`height` raster covering `region`
    /// (row 0 at the top, i.e. at the largest y), computed exactly from the rectangles.
    pub fn render(&self, _region: &Region, _width: usize, _height: usize) -> Raster {
        todo!("USAF area-averaged render")
    }
}
