//! The USAF 1951 resolution read-out of a reconstructed image: per element, the Michelson
//! contrast of its horizontal-bar and vertical-bar triplets, whether it is resolved, and the
//! finest element resolved.
//!
//! # Geometry
//!
//! The chart is [`UsafChart`] (chart millimetres, x right, y up). [`ChartToImage`] maps chart
//! millimetres to continuous image coordinates (column, row): pixel (c, r) covers
//! [c, c + 1) × [r, r + 1) and its centre is at (c + 0.5, r + 0.5). The map is any
//! non-singular affine map, so it can mirror (a lens inverts the image), swap axes (a DMD frame
//! that differs from the chart frame) or rotate; [`ChartToImage::for_render`] is the map of
//! [`UsafChart::render`] (row 0 at the top), and [`ChartToImage::mirrored_cols`],
//! [`ChartToImage::mirrored_rows`], [`ChartToImage::rotated_180`] and
//! [`ChartToImage::transposed`] compose the usual image flips with it.
//!
//! Only elements whose two triplets (their bounding boxes) lie fully inside the image,
//! [0, width] × [0, height], are read; an element cut by the image edge is skipped rather than
//! misread.
//!
//! # Criterion
//!
//! For each triplet, the image is sampled with bilinear interpolation (between pixel centres,
//! clamped to the edge pixels) along profiles across the three bars. The profile is averaged
//! along the bar length over the middle 60 % of it ([`ResolutionOptions::length_fraction`]),
//! which averages noise down while staying one bar width away from the bar ends, where the
//! blur of the ends would otherwise lower the peaks. Across, each of the five windows (three
//! bars, two gaps, one bar width each) is sampled at ≥ 8 and ≤ 64 evenly spaced points
//! (≥ 4 per pixel where that stays within 64). The contrast is the Michelson contrast of the
//! bar pattern as it is read for a square-wave target (its contrast transfer function, CTF):
//!
//! > C = (mean of the bright windows' maxima − mean of the dark windows' minima)
//! >   / (mean of the bright windows' maxima + mean of the dark windows' minima),
//!
//! capped at twice the same contrast read on window means (a guard against noise, which
//! raises maxima but not means; on real bars the cap is inactive, see `triplet_contrast`),
//! where the bright windows are the three bars of a negative chart (clear bars in chrome, as
//! the paper's Thorlabs R3L3S1N) or the two gaps of a positive chart, and the dark windows the
//! others. The sign is kept: an image whose bars come out darker than their gaps (the contrast
//! reversal of "spurious resolution" in a defocused bar image, or a chart read with the wrong
//! polarity) has C < 0 and is not resolved. C is NaN when the denominator is not positive
//! (an image without a physical zero, e.g. all zeros), and NaN is never resolved. The image
//! should be an intensity (non-negative up to noise), for example a reconstruction after the
//! normalisation rule of [`crate::metrics`].
//!
//! An element is resolved when both triplets have C > [`DEFAULT_THRESHOLD`] = 0.2, the
//! contrast is significant against the image's noise (below) and its bars are more than one
//! pixel wide (see below). Why 0.2: near the resolution limit only the
//! fundamental of a bar pattern passes, and then the square-wave contrast is 4/π times the
//! sine-wave modulation (MTF) at the same frequency (J. W. Coltman, "The specification of
//! imaging properties by response to a sine wave input", J. Opt. Soc. Am. 44, 468–471, 1954).
//! C = 0.2 is thus an MTF of 0.2·π/4 = 0.157, the same as the Michelson contrast of the
//! Rayleigh criterion: two equal Airy patterns at the Rayleigh distance dip to 73.5 % between
//! their peaks (M. Born and E. Wolf, Principles of Optics, 7th ed., §7.6.3), i.e.
//! (1 − 0.735)/(1 + 0.735) = 0.153. So "C > 0.2" is a Rayleigh-like, MTF ≈ 15 % criterion for
//! a three-bar target.
//!
//! # Significance against noise
//!
//! A noisy image (a reconstruction from noisy measurements, with TV's blotches) can show a
//! contrast above the threshold by chance. Each triplet's window-mean contrast is therefore
//! read again on 4 equal parts of the averaged bar length; along a bar the true image is
//! constant (the middle of the bar, away from its ends), so the parts differ only by noise,
//! and their spread gives the reading's standard error SE = sd/√4. The contrast is significant
//! when the parts' mean reading exceeds t·SE in both orientations, t = 2.353 (Student's t, 3 degrees of freedom, one-sided
//! 95 %); an element is resolved only then. Noise correlated over more than a part's length
//! (about 0.15 of the bar length, one or two pixels on the smallest elements read) shifts all
//! parts together and is not caught: on blotchy noise as strong as the signal (white noise
//! blurred over 1.5 px, 16 images of 128 × 128) 6 of the 11 chance readings above the
//! threshold still pass.
//!
//! Where the truth is known (`spibench run`), the noise is measured directly:
//! [`read_resolution_against`] takes the residual (normalised reconstruction less truth) and
//! reads the same window-mean contrast of each triplet on it, with the triplet's geometry
//! shifted to up to 8 × 8 placements over the image (bright − dark window means of the
//! residual, over the image's own bright + dark). These readings are the contrast the image's
//! noise alone produces at that element's size and orientation, blotches of any correlation
//! length included; the element is resolved only if its contrast on the image exceeds their
//! 95th percentile in both orientations (a one-sided 5 % false-alarm rate per orientation). The
//! residual also holds the reconstruction's blur and bias where the image has structure, which
//! can only raise the null: the test errs towards "not resolved".
//!
//! # Sampling limit
//!
//! A pixel grid cannot represent a bar pattern whose period is two pixels or less (the Nyquist
//! limit): any contrast seen there is an alias (a beat with the pixel grid whose size depends
//! on the phase), not resolution. So an element whose bars are at most one pixel wide is
//! reported with its measured contrasts but flagged `aliased` and never resolved. The width in
//! pixels is measured along the grid axis across which the bars' stripes vary fastest (exact
//! for maps that are axis-aligned up to flips and swaps; for a rotated map it is the width
//! that the Nyquist condition |k_col|, |k_row| < 1/2 per pixel constrains).

use std::collections::BTreeMap;

use crate::error::{Error, Result};
use crate::objects::usaf::{Bar, Polarity, Region, UsafChart, spatial_frequency_lp_per_mm};
use crate::raster::Raster;

/// The contrast an element must exceed in both orientations to be resolved (see module docs).
pub const DEFAULT_THRESHOLD: f64 = 0.2;
/// The middle fraction of the bar length over which the profile is averaged.
pub const DEFAULT_LENGTH_FRACTION: f64 = 0.6;

/// The criterion in one sentence, for summaries and reports.
pub const CRITERION: &str = "Michelson contrast (mean bright-window maximum − mean dark-window minimum)/(sum) of the bilinear profile across each three-bar triplet, averaged over the middle 60 % of the bar length, capped at twice the same contrast of window means (a noise guard); resolved when both triplets exceed the threshold (0.2 ≈ Rayleigh's dip via Coltman's CTF = 4/π·MTF), the contrast exceeds 2.353 standard errors of its reading on 4 parts of the bar length (significant against the image's noise) and, where the truth is known, exceeds the 95th percentile of the same reading of the residual (reconstruction − truth) at shifted placements; and the bars are wider than one pixel";

/// USAF 1951 spatial frequency R = 2^(group + (element − 1)/6), in line pairs per mm.
pub fn usaf_lp_per_mm(group: i32, element: u8) -> f64 {
    spatial_frequency_lp_per_mm(group, element)
}

/// The affine map px = m·mm + t from chart millimetres (x, y) to continuous image coordinates
/// (column, row), pixel centres at +0.5.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ChartToImage {
    pub m: [[f64; 2]; 2],
    pub t: [f64; 2],
}

impl ChartToImage {
    /// A map with finite coefficients and a non-singular matrix.
    pub fn new(m: [[f64; 2]; 2], t: [f64; 2]) -> Result<Self> {
        let map = ChartToImage { m, t };
        map.validate()?;
        Ok(map)
    }

    /// The map of [`UsafChart::render`]`(region, width, height)`: column c spans
    /// x ∈ [x0 + c·Δx, x0 + (c + 1)·Δx], row r spans y ∈ [y1 − (r + 1)·Δy, y1 − r·Δy].
    pub fn for_render(region: &Region, width: usize, height: usize) -> Result<Self> {
        region.validate()?;
        if width == 0 || height == 0 {
            return Err(Error::input(format!(
                "a {width}×{height} image has no pixels"
            )));
        }
        let sx = width as f64 / region.width_mm;
        let sy = height as f64 / region.height_mm;
        ChartToImage::new(
            [[sx, 0.0], [0.0, -sy]],
            [-region.x0_mm() * sx, region.y1_mm() * sy],
        )
    }

    /// Checks that the coefficients are finite and the matrix invertible.
    pub fn validate(&self) -> Result<()> {
        let finite = self
            .m
            .iter()
            .flatten()
            .chain(&self.t)
            .all(|v| v.is_finite());
        let det = self.det();
        if !finite || !det.is_finite() || det == 0.0 {
            return Err(Error::field(
                "chart_to_image",
                format!(
                    "the chart-to-image map needs finite coefficients and an invertible matrix, got m = {:?}, t = {:?}",
                    self.m, self.t
                ),
            ));
        }
        Ok(())
    }

    fn det(&self) -> f64 {
        self.m[0][0] * self.m[1][1] - self.m[0][1] * self.m[1][0]
    }

    /// Image coordinates (column, row) of the chart point (x, y) in mm.
    #[inline]
    pub fn apply(&self, x_mm: f64, y_mm: f64) -> [f64; 2] {
        [
            self.m[0][0] * x_mm + self.m[0][1] * y_mm + self.t[0],
            self.m[1][0] * x_mm + self.m[1][1] * y_mm + self.t[1],
        ]
    }

    /// This map followed by the pixel map px' = a·px + b.
    pub fn then(&self, a: [[f64; 2]; 2], b: [f64; 2]) -> ChartToImage {
        let mut m = [[0.0; 2]; 2];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = a[i][0] * self.m[0][j] + a[i][1] * self.m[1][j];
            }
        }
        let t = [
            a[0][0] * self.t[0] + a[0][1] * self.t[1] + b[0],
            a[1][0] * self.t[0] + a[1][1] * self.t[1] + b[1],
        ];
        ChartToImage { m, t }
    }

    /// The map onto the image mirrored left–right (column c becomes width − 1 − c).
    pub fn mirrored_cols(&self, width: usize) -> ChartToImage {
        self.then([[-1.0, 0.0], [0.0, 1.0]], [width as f64, 0.0])
    }

    /// The map onto the image mirrored top–bottom (row r becomes height − 1 − r).
    pub fn mirrored_rows(&self, height: usize) -> ChartToImage {
        self.then([[1.0, 0.0], [0.0, -1.0]], [0.0, height as f64])
    }

    /// The map onto the image turned by 180° (the inversion of a single imaging lens).
    pub fn rotated_180(&self, width: usize, height: usize) -> ChartToImage {
        self.mirrored_cols(width).mirrored_rows(height)
    }

    /// The map onto the transposed image (column and row swapped).
    pub fn transposed(&self) -> ChartToImage {
        self.then([[0.0, 1.0], [1.0, 0.0]], [0.0, 0.0])
    }

    /// Rows of m⁻¹: row k is the gradient of chart coordinate k (x or y) in mm per pixel.
    fn inverse(&self) -> [[f64; 2]; 2] {
        let d = self.det();
        [
            [self.m[1][1] / d, -self.m[0][1] / d],
            [-self.m[1][0] / d, self.m[0][0] / d],
        ]
    }
}

/// Settings of the read-out.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResolutionOptions {
    /// Contrast both triplets must exceed, in (0, 1).
    pub threshold: f64,
    /// Middle fraction of the bar length averaged, in (0, 1].
    pub length_fraction: f64,
}

impl Default for ResolutionOptions {
    fn default() -> Self {
        ResolutionOptions {
            threshold: DEFAULT_THRESHOLD,
            length_fraction: DEFAULT_LENGTH_FRACTION,
        }
    }
}

/// A chart element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
pub struct UsafElement {
    pub group: i32,
    pub element: u8,
}

impl UsafElement {
    pub fn lp_per_mm(&self) -> f64 {
        usaf_lp_per_mm(self.group, self.element)
    }
}

/// The read-out of one element.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ElementReadout {
    pub group: i32,
    pub element: u8,
    pub lp_per_mm: f64,
    /// Bar width in pixels (the smaller of the two orientations; see module docs).
    pub bar_width_px: f64,
    /// Contrast of the three horizontal bars (long in x; they resolve detail along y).
    pub contrast_horizontal: f64,
    /// Contrast of the three vertical bars (long in y; they resolve detail along x).
    pub contrast_vertical: f64,
    /// Standard errors of the two contrasts from the image's noise (the spread of the reading
    /// between parts of the bar length; see the module docs).
    pub contrast_horizontal_stderr: f64,
    pub contrast_vertical_stderr: f64,
    /// With a residual ([`read_resolution_against`]): the [`NULL_QUANTILE`] point of the
    /// window-mean contrast the residual's noise shows at the triplet's geometry.
    pub noise_contrast_horizontal: Option<f64>,
    pub noise_contrast_vertical: Option<f64>,
    /// Bars at most one pixel wide: beyond the pixel grid's Nyquist limit, never resolved.
    pub aliased: bool,
    /// Both contrasts exceed [`SIGNIFICANCE_T`] standard errors and, with a residual, the
    /// noise null's [`NULL_QUANTILE`] point: bars, not noise.
    pub significant: bool,
    pub resolved: bool,
}

/// The read-out of a whole image.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ResolutionReadout {
    pub threshold: f64,
    pub length_fraction: f64,
    /// Every element fully inside the image, from coarse to fine.
    pub elements: Vec<ElementReadout>,
    /// The resolved element with the highest spatial frequency, if any.
    pub finest_resolved: Option<UsafElement>,
}

impl ResolutionReadout {
    /// The spatial frequency of [`ResolutionReadout::finest_resolved`], in lp/mm.
    pub fn finest_lp_per_mm(&self) -> Option<f64> {
        self.finest_resolved.map(|e| e.lp_per_mm())
    }
}

/// Reads the resolution of `image`, an image of `chart` through `map` (see the module docs for
/// the criterion). Bad input (an inconsistent raster, a singular or non-finite map, options out
/// of range) is `Error::Input`.
pub fn read_resolution(
    image: &Raster,
    chart: &UsafChart,
    map: &ChartToImage,
    options: &ResolutionOptions,
) -> Result<ResolutionReadout> {
    read_resolution_against(image, None, chart, map, options)
}

/// [`read_resolution`] with the image's noise known from `residual` (the reconstruction less
/// its truth, on the image's scale, same size): an element is resolved only if, in both
/// orientations, its window-mean contrast also exceeds the [`NULL_QUANTILE`] point of the same
/// reading of the residual at shifted placements of the triplet (see the module docs).
pub fn read_resolution_against(
    image: &Raster,
    residual: Option<&Raster>,
    chart: &UsafChart,
    map: &ChartToImage,
    options: &ResolutionOptions,
) -> Result<ResolutionReadout> {
    if let Some(r) = residual
        && (r.width != image.width || r.height != image.height || r.data.len() != image.data.len())
    {
        return Err(Error::input(format!(
            "the residual is {}×{} but the image {}×{}",
            r.width, r.height, image.width, image.height
        )));
    }
    if image.width == 0 || image.height == 0 || image.data.len() != image.width * image.height {
        return Err(Error::input(format!(
            "the image holds {} values but claims {}×{}",
            image.data.len(),
            image.width,
            image.height
        )));
    }
    map.validate()?;
    if !(options.threshold > 0.0 && options.threshold < 1.0) {
        return Err(Error::field(
            "threshold",
            format!(
                "the contrast threshold must lie in (0, 1), got {}",
                options.threshold
            ),
        ));
    }
    if !(options.length_fraction > 0.0 && options.length_fraction <= 1.0) {
        return Err(Error::field(
            "length_fraction",
            format!(
                "the averaged fraction of the bar length must lie in (0, 1], got {}",
                options.length_fraction
            ),
        ));
    }
    // Bars come ordered by group, element, horizontal first; the map keeps (group, element)
    // order, which is the order of increasing frequency.
    let mut by_element: BTreeMap<(i32, u8), Vec<Bar>> = BTreeMap::new();
    for b in chart.bars() {
        by_element.entry((b.group, b.element)).or_default().push(b);
    }
    let inverse = map.inverse();
    let mut elements = Vec::new();
    for ((group, element), bars) in by_element {
        let horizontal: Vec<Bar> = bars.iter().filter(|b| b.horizontal).copied().collect();
        let vertical: Vec<Bar> = bars.iter().filter(|b| !b.horizontal).copied().collect();
        if horizontal.len() != 3 || vertical.len() != 3 {
            continue;
        }
        if !inside(image, map, &horizontal) || !inside(image, map, &vertical) {
            continue;
        }
        let w_mm = horizontal[0].width_mm();
        // Horizontal bars vary along y: their stripes' gradient in pixels is row 1 of m⁻¹.
        let width_px = |row: [f64; 2]| w_mm / row[0].abs().max(row[1].abs());
        let bar_width_px = width_px(inverse[1]).min(width_px(inverse[0]));
        let polarity = chart.polarity;
        let frac = options.length_fraction;
        let (contrast_horizontal, mean_h, se_h) =
            triplet_contrast(image, map, &horizontal, polarity, frac);
        let (contrast_vertical, mean_v, se_v) =
            triplet_contrast(image, map, &vertical, polarity, frac);
        let aliased = bar_width_px <= 1.0;
        // The window-mean reading is the one whose spread SE measures.
        let mut significant = mean_h > SIGNIFICANCE_T * se_h && mean_v > SIGNIFICANCE_T * se_v;
        let (mut noise_h, mut noise_v) = (None, None);
        if let Some(res) = residual {
            let (ch, qh) = noise_null(image, res, map, &horizontal, polarity, frac);
            let (cv, qv) = noise_null(image, res, map, &vertical, polarity, frac);
            noise_h = Some(qh);
            noise_v = Some(qv);
            // NaN compares false: an unreadable triplet is not significant.
            significant &= ch > qh && cv > qv;
        }
        // NaN compares false, so an undefined contrast is never resolved.
        let resolved = !aliased
            && significant
            && contrast_horizontal > options.threshold
            && contrast_vertical > options.threshold;
        elements.push(ElementReadout {
            group,
            element,
            lp_per_mm: usaf_lp_per_mm(group, element),
            bar_width_px,
            contrast_horizontal,
            contrast_vertical,
            contrast_horizontal_stderr: se_h,
            contrast_vertical_stderr: se_v,
            noise_contrast_horizontal: noise_h,
            noise_contrast_vertical: noise_v,
            aliased,
            significant,
            resolved,
        });
    }
    let finest_resolved = elements
        .iter()
        .filter(|e| e.resolved)
        .map(|e| UsafElement {
            group: e.group,
            element: e.element,
        })
        .max();
    Ok(ResolutionReadout {
        threshold: options.threshold,
        length_fraction: options.length_fraction,
        elements,
        finest_resolved,
    })
}

/// The bounding box of a triplet in chart mm: [x0, y0, x1, y1].
fn triplet_box(bars: &[Bar]) -> [f64; 4] {
    crate::objects::usaf::bbox(bars)
}

/// True if the triplet's box maps into [0, width] × [0, height] (an affine map sends the box to
/// a parallelogram, which lies inside the image rectangle iff its four corners do). A slack of
/// 1e-9 pixel absorbs round-off for a box that touches the edge exactly.
fn inside(image: &Raster, map: &ChartToImage, bars: &[Bar]) -> bool {
    let [x0, y0, x1, y1] = triplet_box(bars);
    let (w, h) = (image.width as f64, image.height as f64);
    let eps = 1e-9;
    [(x0, y0), (x0, y1), (x1, y0), (x1, y1)]
        .iter()
        .all(|&(x, y)| {
            let [c, r] = map.apply(x, y);
            c >= -eps && c <= w + eps && r >= -eps && r <= h + eps
        })
}

/// Bilinear interpolation between pixel centres at continuous (col, row); outside the centres'
/// hull the edge pixels hold (so a sample between an edge pixel's centre and the image edge
/// takes that pixel's value).
#[inline]
fn bilinear(image: &Raster, col: f64, row: f64) -> f64 {
    let (w, h) = (image.width, image.height);
    let x = (col - 0.5).clamp(0.0, (w - 1) as f64);
    let y = (row - 0.5).clamp(0.0, (h - 1) as f64);
    let c0 = (x.floor() as usize).min(w.saturating_sub(2));
    let r0 = (y.floor() as usize).min(h.saturating_sub(2));
    let (c1, r1) = ((c0 + 1).min(w - 1), (r0 + 1).min(h - 1));
    let (fx, fy) = (x - c0 as f64, y - r0 as f64);
    let top = image.get(r0, c0) * (1.0 - fx) + image.get(r0, c1) * fx;
    let bottom = image.get(r1, c0) * (1.0 - fx) + image.get(r1, c1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Ratio of the window-mean reading to the peak reading below which a contrast is taken for
/// noise (see `triplet_contrast`).
const MEAN_READING_CAP: f64 = 2.0;

/// The signed Michelson contrast of one triplet (see the module docs), its window-mean
/// reading averaged over the parts of the bar length and that reading's standard error from
/// the spread between the parts (the noise test of the module docs).
fn triplet_contrast(
    image: &Raster,
    map: &ChartToImage,
    bars: &[Bar],
    polarity: Polarity,
    length_fraction: f64,
) -> (f64, f64, f64) {
    let horizontal = bars[0].horizontal;
    // (across interval, along interval) of a bar: horizontal bars are long in x.
    let spans = |b: &Bar| {
        if horizontal {
            ((b.y0_mm, b.y1_mm), (b.x0_mm, b.x1_mm))
        } else {
            ((b.x0_mm, b.x1_mm), (b.y0_mm, b.y1_mm))
        }
    };
    let mut across: Vec<(f64, f64)> = bars.iter().map(|b| spans(b).0).collect();
    across.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (along0, along1) = spans(&bars[0]).1;
    let centre = 0.5 * (along0 + along1);
    let half = 0.5 * length_fraction * (along1 - along0);
    let point = |a: f64, l: f64| if horizontal { (l, a) } else { (a, l) };

    // Sample counts from the pixel lengths of one bar width across and of the averaged length.
    let px_len = |(x0, y0): (f64, f64), (x1, y1): (f64, f64)| {
        let [c0, r0] = map.apply(x0, y0);
        let [c1, r1] = map.apply(x1, y1);
        (c1 - c0).hypot(r1 - r0)
    };
    let w_px = px_len(point(across[0].0, centre), point(across[0].1, centre));
    let len_px = px_len(
        point(across[0].0, centre - half),
        point(across[0].0, centre + half),
    );
    let per_window = ((4.0 * w_px).ceil() as usize).clamp(8, 64);
    let n_along = ((2.0 * len_px).ceil() as usize).clamp(8, 256);

    // Mean of the image along the bar length at one across position.
    let profile = |a: f64| {
        let mut sum = 0.0;
        for k in 0..n_along {
            let l = centre - half + (k as f64 + 0.5) * (2.0 * half) / n_along as f64;
            let (x, y) = point(a, l);
            let [c, r] = map.apply(x, y);
            sum += bilinear(image, c, r);
        }
        sum / n_along as f64
    };
    let extreme = |(lo, hi): (f64, f64), bright: bool| {
        let mut best = if bright {
            f64::NEG_INFINITY
        } else {
            f64::INFINITY
        };
        for k in 0..per_window {
            let v = profile(lo + (k as f64 + 0.5) * (hi - lo) / per_window as f64);
            if v.is_nan() {
                return f64::NAN;
            }
            best = if bright { best.max(v) } else { best.min(v) };
        }
        best
    };
    let bar_windows = across.clone();
    let gap_windows: Vec<(f64, f64)> = across.windows(2).map(|p| (p[0].1, p[1].0)).collect();
    let (bright, dark) = match polarity {
        Polarity::Negative => (bar_windows, gap_windows),
        Polarity::Positive => (gap_windows, bar_windows),
    };
    let average = |(lo, hi): (f64, f64)| {
        (0..per_window)
            .map(|k| profile(lo + (k as f64 + 0.5) * (hi - lo) / per_window as f64))
            .sum::<f64>()
            / per_window as f64
    };
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let hi = mean(&bright.iter().map(|&w| extreme(w, true)).collect::<Vec<_>>());
    let lo = mean(&dark.iter().map(|&w| extreme(w, false)).collect::<Vec<_>>());
    let sum = hi + lo;
    if !(sum > 0.0 && sum.is_finite()) {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let peak = (hi - lo) / sum;
    // Noise guard: the maximum of noisy samples exceeds their mean, so on a noisy image the
    // peak reading shows contrast where there is none. The same reading on window means does
    // not. For a blurred bar profile the window-mean contrast is a fixed fraction of the peak
    // one: 1 for a square wave, 2/π for its fundamental alone (the mean of a half period of a
    // sine), 1/2 for a triangle wave (a square wave box-blurred over one bar width, smoother
    // blurs lie between the triangle and the sine); so min(peak, 2 · mean reading) equals the
    // peak reading on real bars and falls to the noise floor on noise.
    let hi_m = mean(&bright.iter().map(|&w| average(w)).collect::<Vec<_>>());
    let lo_m = mean(&dark.iter().map(|&w| average(w)).collect::<Vec<_>>());
    let sum_m = hi_m + lo_m;
    if !(sum_m > 0.0 && sum_m.is_finite()) {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let contrast = peak.min(MEAN_READING_CAP * (hi_m - lo_m) / sum_m);
    // Significance against the image's noise: the window-mean contrast read on SEGMENTS equal
    // parts of the averaged bar length. On a noise-free bar image every part reads the same;
    // on noise (including the blotches a TV-regularised solve leaves, correlated over a few
    // pixels) the parts scatter, and their spread is an empirical standard error of the
    // contrast that includes noise correlated over less than a part's length.
    let mut parts = [0.0; SEGMENTS];
    for (s, part) in parts.iter_mut().enumerate() {
        let from = centre - half + s as f64 * 2.0 * half / SEGMENTS as f64;
        let n_part = (n_along / SEGMENTS).max(2);
        let seg_profile = |a: f64| {
            (0..n_part)
                .map(|k| {
                    let l = from + (k as f64 + 0.5) * (2.0 * half) / (SEGMENTS * n_part) as f64;
                    let (x, y) = point(a, l);
                    let [c, r] = map.apply(x, y);
                    bilinear(image, c, r)
                })
                .sum::<f64>()
                / n_part as f64
        };
        let window = |(lo, hi): (f64, f64)| {
            (0..per_window)
                .map(|k| seg_profile(lo + (k as f64 + 0.5) * (hi - lo) / per_window as f64))
                .sum::<f64>()
                / per_window as f64
        };
        let b = mean(&bright.iter().map(|&w| window(w)).collect::<Vec<_>>());
        let d = mean(&dark.iter().map(|&w| window(w)).collect::<Vec<_>>());
        *part = (b - d) / sum_m;
    }
    let m = parts.iter().sum::<f64>() / SEGMENTS as f64;
    let var = parts.iter().map(|c| (c - m) * (c - m)).sum::<f64>() / (SEGMENTS - 1) as f64;
    (contrast, m, (var / SEGMENTS as f64).sqrt())
}

/// How many equal parts of the averaged bar length the significance test reads.
const SEGMENTS: usize = 4;

/// Placements per axis of a triplet's geometry on the residual (the noise null: up to
/// NULL_SIDE² readings per triplet).
const NULL_SIDE: usize = 8;

/// The quantile of the noise null a contrast must exceed (one-sided 5 % false alarms).
pub const NULL_QUANTILE: f64 = 0.95;

/// The means of a triplet's bright and dark windows (the window-mean reading, on a coarser
/// sampling than [`triplet_contrast`]'s: ≥ 2 points per pixel across, 1 along, capped) with
/// the map shifted by `shift` pixels.
fn window_means(
    image: &Raster,
    map: &ChartToImage,
    bars: &[Bar],
    polarity: Polarity,
    length_fraction: f64,
    shift: [f64; 2],
) -> (f64, f64) {
    let horizontal = bars[0].horizontal;
    let spans = |b: &Bar| {
        if horizontal {
            ((b.y0_mm, b.y1_mm), (b.x0_mm, b.x1_mm))
        } else {
            ((b.x0_mm, b.x1_mm), (b.y0_mm, b.y1_mm))
        }
    };
    let mut across: Vec<(f64, f64)> = bars.iter().map(|b| spans(b).0).collect();
    across.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (along0, along1) = spans(&bars[0]).1;
    let centre = 0.5 * (along0 + along1);
    let half = 0.5 * length_fraction * (along1 - along0);
    let point = |a: f64, l: f64| {
        let (x, y) = if horizontal { (l, a) } else { (a, l) };
        let [c, r] = map.apply(x, y);
        [c + shift[0], r + shift[1]]
    };
    let px = |p: [f64; 2], q: [f64; 2]| (q[0] - p[0]).hypot(q[1] - p[1]);
    let w_px = px(point(across[0].0, centre), point(across[0].1, centre));
    let len_px = px(
        point(across[0].0, centre - half),
        point(across[0].0, centre + half),
    );
    let per_window = ((2.0 * w_px).ceil() as usize).clamp(4, 16);
    let n_along = (len_px.ceil() as usize).clamp(4, 32);
    let average = |(lo, hi): (f64, f64)| {
        let mut sum = 0.0;
        for k in 0..per_window {
            let a = lo + (k as f64 + 0.5) * (hi - lo) / per_window as f64;
            for m in 0..n_along {
                let l = centre - half + (m as f64 + 0.5) * (2.0 * half) / n_along as f64;
                let [c, r] = point(a, l);
                sum += bilinear(image, c, r);
            }
        }
        sum / (per_window * n_along) as f64
    };
    let bars_w = across.clone();
    let gaps: Vec<(f64, f64)> = across.windows(2).map(|p| (p[0].1, p[1].0)).collect();
    let (bright, dark) = match polarity {
        Polarity::Negative => (bars_w, gaps),
        Polarity::Positive => (gaps, bars_w),
    };
    let mean = |v: &[(f64, f64)]| v.iter().map(|&w| average(w)).sum::<f64>() / v.len() as f64;
    (mean(&bright), mean(&dark))
}

/// The noise test of one triplet against a residual (see the module docs): the triplet's
/// window-mean contrast on `image`, and the [`NULL_QUANTILE`] point of the same reading on
/// `residual` (bright − dark, over the image's own bright + dark) at up to NULL_SIDE² shifts of
/// the triplet that keep it inside the image.
fn noise_null(
    image: &Raster,
    residual: &Raster,
    map: &ChartToImage,
    bars: &[Bar],
    polarity: Polarity,
    length_fraction: f64,
) -> (f64, f64) {
    let (b, d) = window_means(image, map, bars, polarity, length_fraction, [0.0; 2]);
    let sum = b + d;
    if !(sum > 0.0 && sum.is_finite()) {
        return (f64::NAN, f64::NAN);
    }
    // The triplet's pixel bounding box, and the shifts that keep it inside.
    let [x0, y0, x1, y1] = triplet_box(bars);
    let corners = [(x0, y0), (x0, y1), (x1, y0), (x1, y1)].map(|(x, y)| map.apply(x, y));
    let lo = |k: usize| corners.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min);
    let hi = |k: usize| {
        corners
            .iter()
            .map(|p| p[k])
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let size = [residual.width as f64, residual.height as f64];
    let range = |k: usize| (-lo(k), size[k] - hi(k));
    let steps = |(a, z): (f64, f64)| -> Vec<f64> {
        if z - a < 1.0 {
            return vec![0.5 * (a + z)];
        }
        (0..NULL_SIDE)
            .map(|i| a + (z - a) * i as f64 / (NULL_SIDE - 1) as f64)
            .collect()
    };
    let mut null = Vec::new();
    for dr in steps(range(1)) {
        for dc in steps(range(0)) {
            let (nb, nd) = window_means(residual, map, bars, polarity, length_fraction, [dc, dr]);
            null.push((nb - nd) / sum);
        }
    }
    null.sort_by(f64::total_cmp);
    let k = ((NULL_QUANTILE * null.len() as f64).ceil() as usize).clamp(1, null.len()) - 1;
    ((b - d) / sum, null[k])
}

/// One-sided 95 % point of Student's t with SEGMENTS − 1 = 3 degrees of freedom: a contrast
/// is significant when it exceeds this many standard errors of its part-to-part spread.
pub const SIGNIFICANCE_T: f64 = 2.353;

#[cfg(test)]
mod tests;
