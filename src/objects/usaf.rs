//! The 1951 USAF resolution chart (MIL-STD-150A geometry), analytic.
//!
//! The chart is a set of axis-aligned rectangles (bars) in millimetres, in chart coordinates
//! with the origin at the centre of the plate, x to the right and y up. It is shared by the
//! object renderer (area-averaged rasters) and the optical bench (point transmittance).
//!
//! # Geometry (MIL-STD-150A)
//!
//! Element `e` (1..=6) of group `g` has the spatial frequency R(g, e) = 2^(g + (e − 1)/6)
//! line pairs per millimetre. Its bars are w = 1/(2R) mm wide, separated by spaces of the same
//! width, and 5w long; an element is a triplet of horizontal bars (long in x) next to a triplet
//! of vertical bars (long in y). Source: MIL-STD-150A §5.1.1.7 as quoted in docs/bench-facts.md §5.1.
//!
//! # Layout
//!
//! MIL-STD-150A fixes the bars but not the exact coordinates of the elements on the plate, so
//! the layout follows R. Caspary's parametric chart generator (`chart()`, MIT licence, 2024),
//! re-implemented here from its description in docs/bench-facts.md §5.1 (no code copied). In the
//! "period units" of a layer (one unit = the period 2^(−g) mm of element 1 of the layer's even
//! group g, u to the right, v downwards from the layer's top-left corner):
//!
//! - an element drawn at scale s occupies a 6s × 2.5s box: horizontal bars at
//!   u ∈ [0, 2.5s], v ∈ [is, (i + 0.5)s] (i = 0, 1, 2), vertical bars at u ∈ [(3.5 + i)s,
//!   (4 + i)s], v ∈ [0, 2.5s]; element e has s = F^(e−1) with F = 2^(−1/6);
//! - the even group g runs down the left column: element e (2..=6) at u = 0,
//!   v = 3.5·(F + … + F^(e−2)), so consecutive elements stack every 3.5 units of the previous
//!   element's scale; the column ends at the field side S = 3.5(F + F² + F³ + F⁴) + 2.5F⁵
//!   = 11.979 units;
//! - element 1 of the even group sits in the lower-right corner, mirrored left–right (vertical
//!   triplet on the left, horizontal triplet on the right): u ∈ [S − 6, S], v ∈ [S − 2.5, S];
//! - the odd group g + 1 runs down the right column at half scale, mirrored, right-aligned at
//!   u = S: element e (1..=6) at v = 1.75·(1 + F + … + F^(e−2)), scale 0.5·F^(e−1);
//! - the next layer (groups g + 2, g + 3) is the same pattern scaled by 1/4 with its top-left
//!   corner at (6.5F, 3.5F + 1.25F²) = (5.791, 4.110) units.
//!
//! The outermost layer (groups −2 and −1, 4 mm per unit, 47.92 mm square) is centred on the
//! plate: its field spans x, y ∈ [−23.958, 23.958] mm of the 76.2 mm (3″) plate, and the
//! coordinates of every bar do not depend on which groups a chart includes. Groups −2..=9 are
//! supported (the extended series, 0.25 to 912.3 lp/mm); the Thorlabs R3L3S1N carries −2..=7.
//! Group numerals, the reference square of some charts and the plate edge are not modelled:
//! the pattern is bars only, and the caller decides what lies beyond the plate edge.
//!
//! Landmarks of the paper's experiments (chart mm, x0..x1 × y0..y1, computed from this layout
//! and checked by `documented_landmarks_hold`):
//!
//! | what | element bounding box | [`PaperRegion`] square: centre, side |
//! |---|---|---|
//! | group −1 elements 5–6 (Figs. 6a, 8a; "stripes separated by 1.26 mm"), right column of the outer layer | x 16.398..23.958, y −7.000..0.216 | `Fig6`: (20.178, −3.392), 8.819 |
//! | group 0 elements 4–6 (Fig. 8b), left column of the second layer | x −0.794..3.448, y −4.462..1.621 | `Fig8b`: (1.327, −1.421), 6.790 |
//! | groups 1–3 (Fig. 8c), right column of the second layer and the third layer | x 4.996..11.184, y −0.223..7.517 | `Fig8c`: (8.893, 3.647), 8.239 |
//!
//! The second layer (groups 0 and 1) spans x −0.794..11.184, y −4.462..7.517; the third
//! (groups 2 and 3) x 4.996..7.991, y 0.412..3.406.

use std::sync::OnceLock;

use crate::error::{Error, Result};
use crate::raster::Raster;

/// Side of the square Thorlabs R3L3S1N plate (3″), in millimetres.
pub const PLATE_SIDE_MM: f64 = 76.2;
/// The smallest group the layout holds (the outermost layer starts with it).
pub const MIN_SUPPORTED_GROUP: i32 = -2;
/// The largest group the layout holds (the end of the extended series, 912.3 lp/mm).
pub const MAX_SUPPORTED_GROUP: i32 = 9;

/// Clear bars in chrome (negative, as the paper's Thorlabs R3L3S1N) or chrome bars on glass.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Polarity {
    /// Clear bars in chrome.
    Negative,
    /// Chrome bars on clear glass.
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

impl Bar {
    /// The bar as a point set is half-open, [x0, x1) × [y0, y1), so that a point on the shared
    /// edge of two abutting rectangles would belong to exactly one (bars never abut, but the
    /// convention keeps point queries well defined).
    #[inline]
    pub fn contains(&self, x_mm: f64, y_mm: f64) -> bool {
        x_mm >= self.x0_mm && x_mm < self.x1_mm && y_mm >= self.y0_mm && y_mm < self.y1_mm
    }

    pub fn width_mm(&self) -> f64 {
        (self.x1_mm - self.x0_mm).min(self.y1_mm - self.y0_mm)
    }

    pub fn length_mm(&self) -> f64 {
        (self.x1_mm - self.x0_mm).max(self.y1_mm - self.y0_mm)
    }

    pub fn area_mm2(&self) -> f64 {
        (self.x1_mm - self.x0_mm) * (self.y1_mm - self.y0_mm)
    }

    /// The area this bar shares with `region`, in mm².
    pub fn overlap_area_mm2(&self, region: &Region) -> f64 {
        overlap(self.x0_mm, self.x1_mm, region.x0_mm(), region.x1_mm())
            * overlap(self.y0_mm, self.y1_mm, region.y0_mm(), region.y1_mm())
    }
}

/// A rectangular region of the chart in millimetres (centre and size).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    pub center_x_mm: f64,
    pub center_y_mm: f64,
    pub width_mm: f64,
    pub height_mm: f64,
}

impl Region {
    /// A region with a finite centre and a finite, positive size.
    pub fn new(center_x_mm: f64, center_y_mm: f64, width_mm: f64, height_mm: f64) -> Result<Self> {
        let region = Region {
            center_x_mm,
            center_y_mm,
            width_mm,
            height_mm,
        };
        region.validate()?;
        Ok(region)
    }

    /// Checks that the centre is finite and the size finite and positive.
    pub fn validate(&self) -> Result<()> {
        if !(self.center_x_mm.is_finite() && self.center_y_mm.is_finite()) {
            return Err(Error::input(format!(
                "a chart region needs a finite centre, got ({}, {}) mm",
                self.center_x_mm, self.center_y_mm
            )));
        }
        for (name, v) in [("width_mm", self.width_mm), ("height_mm", self.height_mm)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::field(
                    name,
                    format!("a chart region needs a finite, positive size, got {v} mm"),
                ));
            }
        }
        Ok(())
    }

    /// The region spanned by two corners (in any order).
    pub fn from_corners(x0_mm: f64, y0_mm: f64, x1_mm: f64, y1_mm: f64) -> Self {
        let (xa, xb) = (x0_mm.min(x1_mm), x0_mm.max(x1_mm));
        let (ya, yb) = (y0_mm.min(y1_mm), y0_mm.max(y1_mm));
        Region {
            center_x_mm: 0.5 * (xa + xb),
            center_y_mm: 0.5 * (ya + yb),
            width_mm: xb - xa,
            height_mm: yb - ya,
        }
    }

    pub fn x0_mm(&self) -> f64 {
        self.center_x_mm - 0.5 * self.width_mm
    }

    pub fn x1_mm(&self) -> f64 {
        self.center_x_mm + 0.5 * self.width_mm
    }

    pub fn y0_mm(&self) -> f64 {
        self.center_y_mm - 0.5 * self.height_mm
    }

    pub fn y1_mm(&self) -> f64 {
        self.center_y_mm + 0.5 * self.height_mm
    }

    pub fn area_mm2(&self) -> f64 {
        self.width_mm * self.height_mm
    }

    /// The smallest region containing both.
    pub fn union(&self, other: &Region) -> Region {
        Region::from_corners(
            self.x0_mm().min(other.x0_mm()),
            self.y0_mm().min(other.y0_mm()),
            self.x1_mm().max(other.x1_mm()),
            self.y1_mm().max(other.y1_mm()),
        )
    }

    /// The region grown by `margin_mm` on every side.
    pub fn expanded(&self, margin_mm: f64) -> Region {
        Region {
            width_mm: self.width_mm + 2.0 * margin_mm,
            height_mm: self.height_mm + 2.0 * margin_mm,
            ..*self
        }
    }

    /// The square with the same centre whose side is the larger of width and height.
    pub fn to_square(&self) -> Region {
        let side = self.width_mm.max(self.height_mm);
        Region {
            width_mm: side,
            height_mm: side,
            ..*self
        }
    }

    /// The square centred on the union of `boxes`, with side = the larger extent of the union
    /// plus `margin_mm` on each side (a square because the paper's patterns are n×n units).
    /// `None` for an empty list.
    pub fn square_around(boxes: &[Region], margin_mm: f64) -> Option<Region> {
        let first = boxes.first()?;
        let union = boxes[1..].iter().fold(*first, |u, b| u.union(b));
        Some(union.to_square().expanded(margin_mm))
    }
}

/// The chart regions that the paper's experiments image (its Figs. 6 and 8).
///
/// Each is a square (the paper's patterns are 48×48 or 96×96 units) centred on the bounding
/// box of the named elements, with side = the larger extent of that box plus a margin of one
/// bar width of the coarsest element named on every side. The paper gives the elements, not
/// the squares' exact corners, so these are the tightest such squares; each shows every bar
/// of its elements and no bar of any other element, except that Fig. 8c also holds the inner
/// layers (groups 4 to 9, 0.17 mm across in all), which sit inside group 2's field. Fig. 8c's
/// square is 2 mm wider than its elements and is shifted right so that it stops short of
/// group 0 element 2 (see [`PaperRegion::region`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PaperRegion {
    /// Figs. 6a and 8a (red square): group −1 elements 5 and 6.
    Fig6,
    /// Fig. 8b (green square): group 0 elements 4, 5 and 6.
    Fig8b,
    /// Fig. 8c: groups 1 to 3 (the second layer's right column and the whole third layer).
    Fig8c,
}

impl PaperRegion {
    /// The (group, element) pairs the region is built around.
    pub fn elements(self) -> Vec<(i32, u8)> {
        match self {
            PaperRegion::Fig6 => vec![(-1, 5), (-1, 6)],
            PaperRegion::Fig8b => vec![(0, 4), (0, 5), (0, 6)],
            PaperRegion::Fig8c => (1..=3).flat_map(|g| (1..=6).map(move |e| (g, e))).collect(),
        }
    }

    /// The square region of the chart, in chart millimetres.
    pub fn region(self) -> Region {
        let elements = self.elements();
        let boxes: Vec<Region> = elements
            .iter()
            .filter_map(|&(g, e)| element_box(g, e))
            .collect();
        // The coarsest element named comes first in every list.
        let (g, e) = elements[0];
        let margin = bar_width_mm(g, e);
        let mut square =
            Region::square_around(&boxes, margin).expect("every paper region names chart elements");
        if self == PaperRegion::Fig8c {
            // The named elements are 6.19 mm wide and 7.74 mm tall, so a centred square would
            // reach 1.27 mm to the left of group 2 and take in the last vertical bar of group 0
            // element 2, only 0.445 mm away. Nothing lies within 3 mm to the right, so the
            // square's left edge goes to the middle of that gap instead.
            let union = boxes[1..].iter().fold(boxes[0], |u, b| u.union(b));
            let neighbour = element_box(0, 2).expect("group 0 element 2 exists");
            let x0 = 0.5 * (neighbour.x1_mm() + union.x0_mm());
            square.center_x_mm = x0 + 0.5 * square.width_mm;
        }
        square
    }
}

/// Spatial frequency R(g, e) = 2^(g + (e − 1)/6) of a group and element, in line pairs per mm.
pub fn spatial_frequency_lp_per_mm(group: i32, element: u8) -> f64 {
    (f64::from(group) + (f64::from(element) - 1.0) / 6.0).exp2()
}

/// Bar width w = 1/(2R) of a group and element, in mm (the spaces have the same width).
pub fn bar_width_mm(group: i32, element: u8) -> f64 {
    0.5 / spatial_frequency_lp_per_mm(group, element)
}

/// F^j with F = 2^(−1/6), the element-to-element scale step.
fn f_pow(j: i32) -> f64 {
    (-f64::from(j) / 6.0).exp2()
}

/// Side of a layer's field in its period units: 3.5(F + F² + F³ + F⁴) + 2.5F⁵.
fn field_side() -> f64 {
    3.5 * (f_pow(1) + f_pow(2) + f_pow(3) + f_pow(4)) + 2.5 * f_pow(5)
}

/// Where an element sits: chart-mm position of its local origin, mm per local unit (one unit =
/// one period of the element), and whether local x runs leftwards (mirrored elements).
#[derive(Debug, Clone, Copy)]
struct ElementFrame {
    origin_x_mm: f64,
    origin_y_mm: f64,
    mm_per_unit: f64,
    mirrored: bool,
}

impl ElementFrame {
    /// Chart coordinates of the local point (lx, ly); ly runs downwards on the chart.
    fn map(&self, lx: f64, ly: f64) -> (f64, f64) {
        let dx = self.mm_per_unit * lx;
        let x = if self.mirrored {
            self.origin_x_mm - dx
        } else {
            self.origin_x_mm + dx
        };
        (x, self.origin_y_mm - self.mm_per_unit * ly)
    }

    /// The chart rectangle of the local rectangle [lx0, lx1] × [ly0, ly1].
    fn rect(&self, lx0: f64, ly0: f64, lx1: f64, ly1: f64) -> [f64; 4] {
        let (xa, ya) = self.map(lx0, ly0);
        let (xb, yb) = self.map(lx1, ly1);
        [xa.min(xb), ya.min(yb), xa.max(xb), ya.max(yb)]
    }
}

/// The frame of element `element` of `group`, or `None` outside the supported range.
fn element_frame(group: i32, element: u8) -> Option<ElementFrame> {
    if !(MIN_SUPPORTED_GROUP..=MAX_SUPPORTED_GROUP).contains(&group) || !(1..=6).contains(&element)
    {
        return None;
    }
    let side = field_side();
    let even = group - group.rem_euclid(2);
    let layer = (even - MIN_SUPPORTED_GROUP) / 2;
    // Top-left corner of the layer in chart mm: the outer layer is centred on the plate, and
    // each inner layer sits at (6.5F, 3.5F + 1.25F²) units of its parent, scaled by 1/4.
    let mut unit_mm = (-f64::from(MIN_SUPPORTED_GROUP)).exp2();
    let mut ox = -0.5 * side * unit_mm;
    let mut oy = 0.5 * side * unit_mm;
    for _ in 0..layer {
        ox += 6.5 * f_pow(1) * unit_mm;
        oy -= (3.5 * f_pow(1) + 1.25 * f_pow(2)) * unit_mm;
        unit_mm *= 0.25;
    }
    let e = i32::from(element);
    // (u, v) of the element's local origin in layer units, its scale, mirroring.
    let (u, v, scale, mirrored) = if group == even {
        if element == 1 {
            (side, side - 2.5, 1.0, true)
        } else {
            let v: f64 = (1..=e - 2).map(|j| 3.5 * f_pow(j)).sum();
            (0.0, v, f_pow(e - 1), false)
        }
    } else {
        let v: f64 = (0..=e - 2).map(|j| 1.75 * f_pow(j)).sum();
        (side, v, 0.5 * f_pow(e - 1), true)
    };
    Some(ElementFrame {
        origin_x_mm: ox + u * unit_mm,
        origin_y_mm: oy - v * unit_mm,
        mm_per_unit: scale * unit_mm,
        mirrored,
    })
}

/// The six bars of an element: three horizontal, then three vertical, each from the element's
/// outer edge inwards as the generator draws them.
fn element_bars(group: i32, element: u8) -> Option<[Bar; 6]> {
    let frame = element_frame(group, element)?;
    let make = |r: [f64; 4], horizontal: bool| Bar {
        x0_mm: r[0],
        y0_mm: r[1],
        x1_mm: r[2],
        y1_mm: r[3],
        group,
        element,
        horizontal,
    };
    let mut bars = [make([0.0; 4], true); 6];
    for i in 0..3 {
        let fi = i as f64;
        bars[i] = make(frame.rect(0.0, fi, 2.5, fi + 0.5), true);
        bars[3 + i] = make(frame.rect(3.5 + fi, 0.0, 4.0 + fi, 2.5), false);
    }
    Some(bars)
}

/// The bounding box of both triplets of an element, independent of any chart's group range.
pub fn element_box(group: i32, element: u8) -> Option<Region> {
    let frame = element_frame(group, element)?;
    let r = frame.rect(0.0, 0.0, 6.0, 2.5);
    Some(Region::from_corners(r[0], r[1], r[2], r[3]))
}

/// Length of the overlap of [a0, a1] and [b0, b1] (0 when disjoint).
#[inline]
fn overlap(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    (a1.min(b1) - a0.max(b0)).max(0.0)
}

/// Cells per side of each layer's bucket grid. A layer's finest bar (odd group, element 6) is
/// 0.14 units wide in a 12-unit field, so 64 cells (0.19 units) hold at most a few bars each.
const GRID_CELLS: usize = 64;

/// A point-query index over one layer (an even group and the odd group after it).
#[derive(Debug)]
struct LayerIndex {
    even_group: i32,
    /// Bounding box of this layer's bars and of all inner layers: a point outside it lies in
    /// no bar of this or any finer group.
    extent: [f64; 4],
    /// Bounding box of this layer's own bars, split into GRID_CELLS² cells.
    grid: [f64; 4],
    cell_w: f64,
    cell_h: f64,
    /// Bars of cell (row, col) are `ids[starts[k]..starts[k + 1]]`, k = row·GRID_CELLS + col.
    starts: Vec<u32>,
    ids: Vec<u16>,
}

impl LayerIndex {
    #[inline]
    fn cell(&self, x: f64, y: f64) -> Option<&[u16]> {
        let [x0, y0, x1, y1] = self.grid;
        if !(x >= x0 && x <= x1 && y >= y0 && y <= y1) {
            return None;
        }
        let col = (((x - x0) / self.cell_w) as usize).min(GRID_CELLS - 1);
        let row = (((y - y0) / self.cell_h) as usize).min(GRID_CELLS - 1);
        let k = row * GRID_CELLS + col;
        Some(&self.ids[self.starts[k] as usize..self.starts[k + 1] as usize])
    }
}

/// Every bar of the supported groups and the per-layer point-query grids, built once.
#[derive(Debug)]
struct Layout {
    /// Ordered by group, element, then horizontal bars before vertical ones.
    bars: Vec<Bar>,
    layers: Vec<LayerIndex>,
}

/// The bounding box of a set of bars in chart mm: [x0, y0, x1, y1].
pub fn bbox(bars: &[Bar]) -> [f64; 4] {
    bars.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, r| {
            [
                b[0].min(r.x0_mm),
                b[1].min(r.y0_mm),
                b[2].max(r.x1_mm),
                b[3].max(r.y1_mm),
            ]
        },
    )
}

fn layout() -> &'static Layout {
    static LAYOUT: OnceLock<Layout> = OnceLock::new();
    LAYOUT.get_or_init(|| {
        let mut bars = Vec::new();
        for g in MIN_SUPPORTED_GROUP..=MAX_SUPPORTED_GROUP {
            for e in 1..=6 {
                bars.extend(element_bars(g, e).expect("supported group and element"));
            }
        }
        let mut layers = Vec::new();
        for even in (MIN_SUPPORTED_GROUP..=MAX_SUPPORTED_GROUP).step_by(2) {
            let own: Vec<(usize, &Bar)> = bars
                .iter()
                .enumerate()
                .filter(|(_, b)| b.group == even || b.group == even + 1)
                .collect();
            let inner: Vec<Bar> = bars.iter().filter(|b| b.group >= even).copied().collect();
            let own_bars: Vec<Bar> = own.iter().map(|(_, b)| **b).collect();
            let grid = bbox(&own_bars);
            let cell_w = (grid[2] - grid[0]) / GRID_CELLS as f64;
            let cell_h = (grid[3] - grid[1]) / GRID_CELLS as f64;
            let span = |lo: f64, hi: f64, origin: f64, cell: f64| {
                let a = (((lo - origin) / cell).max(0.0) as usize).min(GRID_CELLS - 1);
                let b = (((hi - origin) / cell).max(0.0) as usize).min(GRID_CELLS - 1);
                a..=b
            };
            let mut cells: Vec<Vec<u16>> = vec![Vec::new(); GRID_CELLS * GRID_CELLS];
            for &(id, b) in &own {
                for row in span(b.y0_mm, b.y1_mm, grid[1], cell_h) {
                    for col in span(b.x0_mm, b.x1_mm, grid[0], cell_w) {
                        cells[row * GRID_CELLS + col].push(id as u16);
                    }
                }
            }
            let mut starts = Vec::with_capacity(cells.len() + 1);
            let mut ids = Vec::new();
            starts.push(0u32);
            for c in &cells {
                ids.extend_from_slice(c);
                starts.push(ids.len() as u32);
            }
            layers.push(LayerIndex {
                even_group: even,
                extent: bbox(&inner),
                grid,
                cell_w,
                cell_h,
                starts,
                ids,
            });
        }
        Layout { bars, layers }
    })
}

#[derive(Debug, Clone)]
pub struct UsafChart {
    pub min_group: i32,
    pub max_group: i32,
    pub polarity: Polarity,
}

impl UsafChart {
    /// A chart carrying groups `min_group..=max_group` (within −2..=9).
    pub fn new(min_group: i32, max_group: i32, polarity: Polarity) -> Result<Self> {
        let supported = MIN_SUPPORTED_GROUP..=MAX_SUPPORTED_GROUP;
        if !supported.contains(&min_group) {
            return Err(Error::field(
                "min_group",
                format!(
                    "the chart layout holds groups {MIN_SUPPORTED_GROUP} to {MAX_SUPPORTED_GROUP}, got {min_group}"
                ),
            ));
        }
        if !supported.contains(&max_group) {
            return Err(Error::field(
                "max_group",
                format!(
                    "the chart layout holds groups {MIN_SUPPORTED_GROUP} to {MAX_SUPPORTED_GROUP}, got {max_group}"
                ),
            ));
        }
        if min_group > max_group {
            return Err(Error::field(
                "max_group",
                format!("max_group ({max_group}) must not be below min_group ({min_group})"),
            ));
        }
        Ok(UsafChart {
            min_group,
            max_group,
            polarity,
        })
    }

    /// The paper's target: a negative chart (Thorlabs R3L3S1N) with groups −2 to 7.
    pub fn thorlabs_r3l3s1n() -> Self {
        UsafChart {
            min_group: -2,
            max_group: 7,
            polarity: Polarity::Negative,
        }
    }

    /// The groups this chart draws: its range clipped to the supported −2..=9.
    fn groups(&self) -> std::ops::RangeInclusive<i32> {
        self.min_group.max(MIN_SUPPORTED_GROUP)..=self.max_group.min(MAX_SUPPORTED_GROUP)
    }

    /// Every bar of groups `min_group..=max_group`.
    pub fn bars(&self) -> Vec<Bar> {
        let groups = self.groups();
        layout()
            .bars
            .iter()
            .filter(|b| groups.contains(&b.group))
            .copied()
            .collect()
    }

    /// True if (x, y) lies inside a bar of this chart's groups, whatever the polarity.
    ///
    /// Cost: one bounding-box test per layer down to the point's layer, then the few bars of
    /// one grid cell, so a few tens of comparisons and no allocation.
    pub fn in_bar(&self, x_mm: f64, y_mm: f64) -> bool {
        let groups = self.groups();
        let layout = layout();
        for layer in &layout.layers {
            let [x0, y0, x1, y1] = layer.extent;
            // Inner layers lie inside outer extents, so outside this one nothing finer is hit.
            if !(x_mm >= x0 && x_mm <= x1 && y_mm >= y0 && y_mm <= y1)
                || layer.even_group > *groups.end()
            {
                return false;
            }
            if layer.even_group + 1 < *groups.start() {
                continue;
            }
            if let Some(ids) = layer.cell(x_mm, y_mm) {
                for &id in ids {
                    let b = &layout.bars[id as usize];
                    if groups.contains(&b.group) && b.contains(x_mm, y_mm) {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// True where the chart is clear glass (a bar for a negative chart, the field for a positive one).
    #[inline]
    pub fn is_clear(&self, x_mm: f64, y_mm: f64) -> bool {
        let in_bar = self.in_bar(x_mm, y_mm);
        match self.polarity {
            Polarity::Negative => in_bar,
            Polarity::Positive => !in_bar,
        }
    }

    /// The bounding box of one element (both bar triplets), for choosing imaging regions.
    /// `None` for an element outside 1..=6 or a group this chart does not carry.
    pub fn element_region(&self, group: i32, element: u8) -> Option<Region> {
        if !self.groups().contains(&group) {
            return None;
        }
        element_box(group, element)
    }

    /// The total area of this chart's bars inside `region`, in mm² (the clear area of a
    /// negative chart).
    pub fn bar_area_in(&self, region: &Region) -> f64 {
        self.bars().iter().map(|b| b.overlap_area_mm2(region)).sum()
    }

    /// The fraction of clear area in each pixel of a `width`×`height` raster covering `region`
    /// (row 0 at the top, i.e. at the largest y), computed exactly from the rectangles.
    ///
    /// Column c spans x ∈ [x0 + c·Δx, x0 + (c + 1)·Δx] with Δx = width_mm / width, and row r
    /// spans y ∈ [y1 − (r + 1)·Δy, y1 − r·Δy]; pixels need not be square. Every bar adds its
    /// overlap area with each pixel divided by the pixel area; the bars never overlap each
    /// other, so the sum is the bar fraction (clamped to at most 1 against round-off of a few
    /// ulps). A positive chart gives 1 minus that. An invalid region (see
    /// [`Region::validate`]) or a zero size has no well-defined fraction and renders as the
    /// chrome background everywhere (0 for a negative chart, 1 for a positive one).
    pub fn render(&self, region: &Region, width: usize, height: usize) -> Raster {
        let mut out = Raster::zeros(width, height);
        if width > 0 && height > 0 && region.validate().is_ok() {
            let (x0, y1) = (region.x0_mm(), region.y1_mm());
            let dx = region.width_mm / width as f64;
            let dy = region.height_mm / height as f64;
            let pixel_area = dx * dy;
            let col_edge = |c: usize| x0 + c as f64 * dx;
            let row_edge = |r: usize| y1 - r as f64 * dy;
            for b in self.bars() {
                if b.overlap_area_mm2(region) <= 0.0 {
                    continue;
                }
                let c0 = (((b.x0_mm - x0) / dx).floor().max(0.0) as usize).min(width - 1);
                let c1 = (((b.x1_mm - x0) / dx).ceil().max(0.0) as usize).min(width);
                let r0 = (((y1 - b.y1_mm) / dy).floor().max(0.0) as usize).min(height - 1);
                let r1 = (((y1 - b.y0_mm) / dy).ceil().max(0.0) as usize).min(height);
                for r in r0..r1 {
                    let oy = overlap(b.y0_mm, b.y1_mm, row_edge(r + 1), row_edge(r));
                    if oy <= 0.0 {
                        continue;
                    }
                    for c in c0..c1 {
                        let ox = overlap(b.x0_mm, b.x1_mm, col_edge(c), col_edge(c + 1));
                        out.data[r * width + c] += ox * oy / pixel_area;
                    }
                }
            }
        }
        for v in &mut out.data {
            let fraction = v.min(1.0);
            *v = match self.polarity {
                Polarity::Negative => fraction,
                Polarity::Positive => 1.0 - fraction,
            };
        }
        out
    }
}

#[cfg(test)]
mod tests;
