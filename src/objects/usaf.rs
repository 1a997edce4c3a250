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
mod tests {
    use super::*;

    fn full_chart(polarity: Polarity) -> UsafChart {
        UsafChart::new(MIN_SUPPORTED_GROUP, MAX_SUPPORTED_GROUP, polarity).unwrap()
    }

    #[test]
    fn bar_widths_match_the_paper() {
        // The paper's widths (Experiments section), in µm.
        let paper = [
            (-1, 5, 629.96),
            (-1, 6, 561.23),
            (0, 4, 353.55),
            (0, 5, 314.98),
            (0, 6, 280.62),
        ];
        let chart = UsafChart::thorlabs_r3l3s1n();
        for (g, e, w_um) in paper {
            let bars: Vec<Bar> = chart
                .bars()
                .into_iter()
                .filter(|b| b.group == g && b.element == e)
                .collect();
            assert_eq!(bars.len(), 6);
            assert_eq!(bars.iter().filter(|b| b.horizontal).count(), 3);
            for b in &bars {
                let measured_um = b.width_mm() * 1e3;
                // The paper quotes two decimals, so the rounding error is at most 0.005 µm.
                assert!(
                    (measured_um - w_um).abs() <= 0.005 + 1e-9,
                    "group {g} element {e}: {measured_um} µm vs {w_um} µm"
                );
                assert!((b.width_mm() - bar_width_mm(g, e)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn bars_are_five_widths_long_and_oriented() {
        for b in full_chart(Polarity::Negative).bars() {
            let w = bar_width_mm(b.group, b.element);
            let (dx, dy) = (b.x1_mm - b.x0_mm, b.y1_mm - b.y0_mm);
            let (long, short) = if b.horizontal { (dx, dy) } else { (dy, dx) };
            assert!((short - w).abs() <= 1e-12 * w.max(1.0), "{b:?}");
            assert!((long - 5.0 * w).abs() <= 1e-12 * w.max(1.0), "{b:?}");
        }
    }

    #[test]
    fn bars_in_a_triplet_are_one_width_apart() {
        let chart = full_chart(Polarity::Negative);
        let bars = chart.bars();
        for chunk in bars.chunks(3) {
            let w = bar_width_mm(chunk[0].group, chunk[0].element);
            let mut starts: Vec<f64> = chunk
                .iter()
                .map(|b| if b.horizontal { b.y0_mm } else { b.x0_mm })
                .collect();
            starts.sort_by(f64::total_cmp);
            for pair in starts.windows(2) {
                // Period = bar + space = 2w.
                assert!((pair[1] - pair[0] - 2.0 * w).abs() < 1e-12 * w.max(1.0));
            }
        }
    }

    #[test]
    fn no_two_bars_overlap_and_all_fit_on_the_plate() {
        let bars = full_chart(Polarity::Negative).bars();
        assert_eq!(bars.len(), 12 * 6 * 6);
        for (i, a) in bars.iter().enumerate() {
            for b in &bars[i + 1..] {
                let ox = overlap(a.x0_mm, a.x1_mm, b.x0_mm, b.x1_mm);
                let oy = overlap(a.y0_mm, a.y1_mm, b.y0_mm, b.y1_mm);
                assert!(ox * oy == 0.0, "{a:?} overlaps {b:?}");
            }
            let half = 0.5 * PLATE_SIDE_MM;
            assert!(a.x0_mm > -half && a.x1_mm < half && a.y0_mm > -half && a.y1_mm < half);
        }
    }

    #[test]
    fn elements_of_different_groups_do_not_overlap() {
        // Stronger than bar disjointness: whole element boxes are apart, so no element's
        // bars interleave with another's.
        let mut boxes = Vec::new();
        for g in MIN_SUPPORTED_GROUP..=MAX_SUPPORTED_GROUP {
            for e in 1..=6 {
                boxes.push(((g, e), element_box(g, e).unwrap()));
            }
        }
        for (i, (ka, a)) in boxes.iter().enumerate() {
            for (kb, b) in &boxes[i + 1..] {
                let ox = overlap(a.x0_mm(), a.x1_mm(), b.x0_mm(), b.x1_mm());
                let oy = overlap(a.y0_mm(), a.y1_mm(), b.y0_mm(), b.y1_mm());
                assert!(ox * oy == 0.0, "{ka:?} box overlaps {kb:?}");
            }
        }
    }

    #[test]
    fn outer_layer_is_centred_on_the_plate() {
        let outer = UsafChart::new(-2, -1, Polarity::Negative).unwrap();
        let b = bbox(&outer.bars());
        let half = 2.0 * field_side();
        for (v, want) in b.iter().zip([-half, -half, half, half]) {
            assert!((v - want).abs() < 1e-12, "{b:?}");
        }
        assert!((half - 23.958).abs() < 5e-4);
    }

    #[test]
    fn layout_follows_the_spiral() {
        // Even group: element 1 at the lower right, 2..6 down the left column; odd group down
        // the right column from the top. Checked on the outer layer's element centres.
        let c = |g, e| element_box(g, e).unwrap();
        assert!(c(-2, 1).center_x_mm > 0.0 && c(-2, 1).center_y_mm < -15.0);
        for e in 2..=6 {
            assert!(c(-2, e).center_x_mm < -10.0);
            if e > 2 {
                assert!(c(-2, e).center_y_mm < c(-2, e - 1).center_y_mm);
            }
        }
        for e in 1..=6 {
            assert!(c(-1, e).center_x_mm > 15.0);
            if e > 1 {
                assert!(c(-1, e).center_y_mm < c(-1, e - 1).center_y_mm);
            }
        }
        // The odd group's element 1 and the even group's element 2 start at the top.
        assert!((c(-1, 1).y1_mm() - c(-2, 2).y1_mm()).abs() < 1e-12);
        // Each inner layer is the same pattern at a quarter of the size.
        for g in 0..=MAX_SUPPORTED_GROUP {
            for e in 1..=6 {
                let (outer, inner) = (c(g - 2, e), c(g, e));
                assert!((outer.width_mm / inner.width_mm - 4.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn render_conserves_area() {
        let chart = full_chart(Polarity::Negative);
        let regions = [
            PaperRegion::Fig6.region(),
            PaperRegion::Fig8b.region(),
            PaperRegion::Fig8c.region(),
            Region::new(0.3, -1.7, 31.0, 17.0).unwrap(),
            Region::new(0.0, 0.0, PLATE_SIDE_MM, PLATE_SIDE_MM).unwrap(),
        ];
        for region in regions {
            for (w, h) in [(48, 48), (96, 96), (37, 53), (1, 1)] {
                let raster = chart.render(&region, w, h);
                let pixel_area = region.area_mm2() / (w * h) as f64;
                let rendered = raster.sum() * pixel_area;
                let exact = chart.bar_area_in(&region);
                assert!(exact > 0.0);
                assert!(
                    (rendered - exact).abs() <= 1e-9 * exact,
                    "{region:?} {w}×{h}: {rendered} vs {exact}"
                );
                assert!(raster.min() >= 0.0 && raster.max() <= 1.0);
            }
        }
    }

    #[test]
    fn a_pixel_inside_a_bar_is_fully_clear() {
        // A pixel strictly inside one bar: the coverage is 1 up to round-off.
        let chart = full_chart(Polarity::Negative);
        let b = chart.bars()[0];
        let region = Region::from_corners(
            b.x0_mm + 0.1 * b.width_mm(),
            b.y0_mm + 0.1 * b.width_mm(),
            b.x0_mm + 0.2 * b.width_mm(),
            b.y0_mm + 0.2 * b.width_mm(),
        );
        let r = chart.render(&region, 1, 1);
        assert!((r.data[0] - 1.0).abs() < 1e-12);
        // Half a pixel over the left edge of the bar: half covered.
        let half = Region::new(
            b.x0_mm,
            b.center_y(),
            0.1 * b.width_mm(),
            0.1 * b.width_mm(),
        )
        .unwrap();
        let r = chart.render(&half, 2, 1);
        assert!(r.data[0].abs() < 1e-12 && (r.data[1] - 1.0).abs() < 1e-12);
        let r = chart.render(&half, 1, 1);
        assert!((r.data[0] - 0.5).abs() < 1e-12);
    }

    impl Bar {
        fn center_y(&self) -> f64 {
            0.5 * (self.y0_mm + self.y1_mm)
        }
    }

    #[test]
    fn point_queries_agree_with_the_render() {
        let chart = full_chart(Polarity::Negative);
        let mut checked = 0;
        for region in [
            PaperRegion::Fig6.region(),
            PaperRegion::Fig8c.region(),
            // Around the finest layers (groups 6..9), where the point index is busiest.
            element_box(6, 1)
                .unwrap()
                .union(&element_box(9, 6).unwrap())
                .expanded(0.01),
        ] {
            let (w, h) = (400, 400);
            let raster = chart.render(&region, w, h);
            let dx = region.width_mm / w as f64;
            let dy = region.height_mm / h as f64;
            for r in 0..h {
                for c in 0..w {
                    let v = raster.get(r, c);
                    let x = region.x0_mm() + (c as f64 + 0.5) * dx;
                    let y = region.y1_mm() - (r as f64 + 0.5) * dy;
                    if (v - 1.0).abs() < 1e-9 {
                        assert!(chart.is_clear(x, y), "({x}, {y}) should be clear");
                        checked += 1;
                    } else if v.abs() < 1e-9 {
                        assert!(!chart.is_clear(x, y), "({x}, {y}) should be chrome");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 400_000);
    }

    #[test]
    fn point_queries_agree_with_a_linear_scan() {
        // The bucket grid must give exactly the answer of testing every bar, including for
        // partial group ranges. Points: a deterministic low-discrepancy sweep over the field
        // plus every bar's corners (inside and just outside).
        let charts = [
            full_chart(Polarity::Negative),
            UsafChart::new(0, 3, Polarity::Negative).unwrap(),
            UsafChart::new(-1, -1, Polarity::Negative).unwrap(),
            UsafChart::new(5, 9, Polarity::Negative).unwrap(),
        ];
        let all = full_chart(Polarity::Negative).bars();
        let mut points = Vec::new();
        let golden = 0.618_033_988_749_894_9_f64;
        for k in 0..200_000 {
            let u = (k as f64 * golden).fract();
            let v = (k as f64 * 0.754_877_666_246_692_7).fract();
            // Denser near the centre, where the inner layers sit.
            let scale = if k % 2 == 0 { 25.0 } else { 2.0 };
            points.push(((2.0 * u - 1.0) * scale, (2.0 * v - 1.0) * scale));
        }
        for b in &all {
            let eps = 1e-6 * b.width_mm();
            points.push((b.x0_mm, b.y0_mm));
            points.push((b.x1_mm - eps, b.y1_mm - eps));
            points.push((b.x0_mm - eps, b.y0_mm));
            points.push((b.x1_mm, b.y1_mm - eps));
        }
        for chart in &charts {
            let bars = chart.bars();
            for &(x, y) in &points {
                let scan = bars.iter().any(|b| b.contains(x, y));
                assert_eq!(chart.in_bar(x, y), scan, "{chart:?} at ({x}, {y})");
            }
        }
    }

    #[test]
    fn polarity_flips_coverage() {
        let neg = UsafChart::thorlabs_r3l3s1n();
        let pos = UsafChart {
            polarity: Polarity::Positive,
            ..neg.clone()
        };
        let region = PaperRegion::Fig8b.region();
        let (a, b) = (neg.render(&region, 96, 96), pos.render(&region, 96, 96));
        for (n, p) in a.data.iter().zip(&b.data) {
            assert_eq!(*p, 1.0 - n);
        }
        assert!(a.max() == 1.0 || (a.max() - 1.0).abs() < 1e-12);
        for (x, y) in [(20.0, 0.0), (19.0, 2.9), (0.0, 0.0), (-30.0, 30.0)] {
            assert_ne!(neg.is_clear(x, y), pos.is_clear(x, y));
        }
    }

    #[test]
    fn group_range_limits_bars_and_regions() {
        let chart = UsafChart::new(0, 1, Polarity::Negative).unwrap();
        assert!(chart.bars().iter().all(|b| (0..=1).contains(&b.group)));
        assert_eq!(chart.bars().len(), 72);
        assert!(chart.element_region(-1, 5).is_none());
        assert!(chart.element_region(0, 7).is_none());
        assert!(chart.element_region(0, 0).is_none());
        assert!(chart.element_region(1, 6).is_some());
        // A point in a group −1 bar is chrome on a chart without group −1.
        let b = element_bars(-1, 5).unwrap()[0];
        let (x, y) = (0.5 * (b.x0_mm + b.x1_mm), b.center_y());
        assert!(UsafChart::thorlabs_r3l3s1n().is_clear(x, y));
        assert!(!chart.is_clear(x, y));
    }

    #[test]
    fn invalid_ranges_and_regions_are_input_errors() {
        for (lo, hi) in [(-3, 7), (-2, 10), (3, 2)] {
            let e = UsafChart::new(lo, hi, Polarity::Negative).unwrap_err();
            assert!(e.is_user_error(), "{e}");
        }
        for (w, h) in [
            (0.0, 1.0),
            (1.0, -1.0),
            (f64::NAN, 1.0),
            (1.0, f64::INFINITY),
        ] {
            assert!(Region::new(0.0, 0.0, w, h).unwrap_err().is_user_error());
        }
        assert!(Region::new(f64::NAN, 0.0, 1.0, 1.0).is_err());
        // A degenerate region renders as background, without panicking.
        let bad = Region {
            center_x_mm: 0.0,
            center_y_mm: 0.0,
            width_mm: 0.0,
            height_mm: 1.0,
        };
        assert_eq!(UsafChart::thorlabs_r3l3s1n().render(&bad, 4, 4).max(), 0.0);
        assert_eq!(
            UsafChart::thorlabs_r3l3s1n()
                .render(&PaperRegion::Fig6.region(), 0, 3)
                .len(),
            0
        );
    }

    #[test]
    fn paper_regions_hold_their_elements() {
        let chart = UsafChart::thorlabs_r3l3s1n();
        for which in [PaperRegion::Fig6, PaperRegion::Fig8b, PaperRegion::Fig8c] {
            let region = which.region();
            assert!((region.width_mm - region.height_mm).abs() < 1e-12);
            for (g, e) in which.elements() {
                let b = chart.element_region(g, e).unwrap();
                assert!(b.x0_mm() > region.x0_mm() && b.x1_mm() < region.x1_mm());
                assert!(b.y0_mm() > region.y0_mm() && b.y1_mm() < region.y1_mm());
            }
            eprintln!(
                "{which:?}: centre ({:.3}, {:.3}) mm, side {:.3} mm",
                region.center_x_mm, region.center_y_mm, region.width_mm
            );
        }
        // Fig. 6: the paper's "stripes separated by 1.26 mm" is the period of group −1
        // element 5 (2 × 629.96 µm).
        assert!((2.0 * bar_width_mm(-1, 5) - 1.26).abs() < 0.005);
    }

    #[test]
    fn paper_regions_show_only_their_elements() {
        let chart = full_chart(Polarity::Negative);
        for which in [PaperRegion::Fig6, PaperRegion::Fig8b, PaperRegion::Fig8c] {
            let region = which.region();
            let named = which.elements();
            let inner_from = named.iter().map(|&(g, _)| g).max().unwrap() + 1;
            for b in chart.bars() {
                let fraction = b.overlap_area_mm2(&region) / b.area_mm2();
                if named.contains(&(b.group, b.element)) {
                    assert_eq!(fraction, 1.0, "{which:?}: {b:?} is cut");
                } else if which == PaperRegion::Fig8c && b.group >= inner_from {
                    // Inner layers nested in group 2's field.
                    assert_eq!(fraction, 1.0, "{which:?}: {b:?} is cut");
                } else {
                    assert_eq!(fraction, 0.0, "{which:?} shows {b:?}");
                }
            }
        }
    }

    #[test]
    fn documented_landmarks_hold() {
        // The coordinates quoted in the module documentation (to 1 µm).
        let union = |list: &[(i32, u8)]| {
            let boxes: Vec<Region> = list
                .iter()
                .map(|&(g, e)| element_box(g, e).unwrap())
                .collect();
            boxes[1..].iter().fold(boxes[0], |u, b| u.union(b))
        };
        let groups_1_to_3: Vec<(i32, u8)> = PaperRegion::Fig8c.elements();
        let mut results = Vec::new();
        for (list, want) in [
            (vec![(-1, 5), (-1, 6)], [16.398, -7.000, 23.958, 0.216]),
            (vec![(0, 4), (0, 5), (0, 6)], [-0.794, -4.462, 3.448, 1.621]),
            (groups_1_to_3, [4.996, -0.223, 11.184, 7.517]),
            (
                (0..=1).flat_map(|g| (1..=6).map(move |e| (g, e))).collect(),
                [-0.794, -4.462, 11.184, 7.517],
            ),
            (
                (2..=3).flat_map(|g| (1..=6).map(move |e| (g, e))).collect(),
                [4.996, 0.412, 7.991, 3.406],
            ),
        ] {
            let u = union(&list);
            let got = [u.x0_mm(), u.y0_mm(), u.x1_mm(), u.y1_mm()];
            results.push((got, want));
        }
        for (which, centre_x, centre_y, side) in [
            (PaperRegion::Fig6, 20.178, -3.392, 8.819),
            (PaperRegion::Fig8b, 1.327, -1.421, 6.790),
            (PaperRegion::Fig8c, 8.893, 3.647, 8.239),
        ] {
            let r = which.region();
            results.push((
                [r.center_x_mm, r.center_y_mm, r.width_mm, r.height_mm],
                [centre_x, centre_y, side, side],
            ));
        }
        for (got, want) in results {
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() < 5e-4, "{got:?} vs {want:?}");
            }
        }
    }
}
