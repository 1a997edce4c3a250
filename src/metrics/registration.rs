//! Registration of an image against the analytic USAF chart: finds the map from chart
//! millimetres to image pixels that the resolution read-out ([`super::resolution`]) needs.
//!
//! The traced bench images the chart onto the DMD through a real lens, so the map is known only
//! approximately from the geometry: the lens inverts the image, the DMD frame's axes differ from
//! the chart's, and the magnification is near but not exactly the paraxial one. The read-out
//! samples bar profiles a few pixels wide, so a map that is off by a pixel would misread the
//! finest elements. This module therefore starts from the geometric guess and refines it against
//! the image itself: it maximises the normalised cross-correlation (Pearson's r) between the
//! image and the chart rendered through the candidate map, over the eight axis-aligned
//! orientations (the dihedral group of the square), the scale and the offset.
//!
//! Used on the ideal object x_j (the traced power on each unit), the correlation is high (above
//! 0.9 on the paper's bench), and the map found is then applied to every reconstruction.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::objects::usaf::{Region, UsafChart};
use crate::raster::Raster;

use super::resolution::ChartToImage;

/// The result of a registration.
#[derive(Debug, Clone, Copy)]
pub struct Registration {
    /// Chart millimetres to image pixel coordinates (pixel centres at +0.5).
    pub map: ChartToImage,
    /// Pearson correlation between the image and the chart seen through `map`, in [−1, 1].
    pub correlation: f64,
}

/// Samples per pixel along each axis when the chart is seen through a candidate map. The bars
/// of the finest elements are under two pixels wide; with 2 × 2 samples the pixel averages
/// alias and the correlation peaks 0.6 % away from the true scale, with 4 × 4 they do not.
/// The coarse search (orientation, whole-pixel offsets) only needs 2 × 2.
const FINE_SAMPLES: usize = 4;
const COARSE_SAMPLES: usize = 2;

/// Oversampling of the reference render: chart samples per image pixel along each axis.
const OVERSAMPLE: usize = 8;

/// A chart rendered once over the region the search can reach, sampled bilinearly afterwards,
/// so that a candidate map costs a few lookups per pixel instead of analytic bar tests.
struct Reference {
    raster: Raster,
    x0_mm: f64,
    y1_mm: f64,
    mm_per_px: f64,
}

impl Reference {
    fn new(chart: &UsafChart, center: [f64; 2], half_mm: f64, mm_per_px: f64) -> Result<Self> {
        let n = ((2.0 * half_mm / mm_per_px).ceil() as usize).max(2);
        let size = n as f64 * mm_per_px;
        let region = Region::new(center[0], center[1], size, size)?;
        Ok(Reference {
            raster: chart.render(&region, n, n),
            x0_mm: center[0] - size / 2.0,
            y1_mm: center[1] + size / 2.0,
            mm_per_px,
        })
    }

    /// Bilinear value at chart point (x, y) mm; 0 outside the rendered square.
    fn at(&self, x_mm: f64, y_mm: f64) -> f64 {
        let c = (x_mm - self.x0_mm) / self.mm_per_px - 0.5;
        let r = (self.y1_mm - y_mm) / self.mm_per_px - 0.5;
        let (w, h) = (self.raster.width, self.raster.height);
        if !(c >= 0.0 && r >= 0.0 && c < (w - 1) as f64 && r < (h - 1) as f64) {
            return 0.0;
        }
        // c, r ≥ 0 here, so truncation is the floor (and no call to libm's floor).
        let (c0, r0) = (c as usize, r as usize);
        let (fc, fr) = (c - c0 as f64, r - r0 as f64);
        let g = |rr: usize, cc: usize| self.raster.data[rr * w + cc];
        (1.0 - fr) * ((1.0 - fc) * g(r0, c0) + fc * g(r0, c0 + 1))
            + fr * ((1.0 - fc) * g(r0 + 1, c0) + fc * g(r0 + 1, c0 + 1))
    }
}

/// One candidate: image pixel p ↦ chart point c + (1/s)·Dᵀ·(p − p_c − offset), with D one of the
/// eight signed permutation matrices.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    orientation: usize,
    pixels_per_mm: f64,
    offset_px: [f64; 2],
}

/// The eight signed permutation matrices (rotations and reflections of the square).
fn orientation(k: usize) -> [[f64; 2]; 2] {
    let base = if k & 4 == 0 {
        [[1.0, 0.0], [0.0, 1.0]]
    } else {
        [[0.0, 1.0], [1.0, 0.0]]
    };
    let sx = if k & 1 == 0 { 1.0 } else { -1.0 };
    let sy = if k & 2 == 0 { 1.0 } else { -1.0 };
    [
        [base[0][0] * sx, base[0][1] * sx],
        [base[1][0] * sy, base[1][1] * sy],
    ]
}

/// The forward map (chart mm → pixel) of a candidate around chart point `c` and pixel `pc`.
fn map_of(k: &Candidate, c: [f64; 2], pc: [f64; 2]) -> ChartToImage {
    let d = orientation(k.orientation);
    let s = k.pixels_per_mm;
    let m = [[s * d[0][0], s * d[0][1]], [s * d[1][0], s * d[1][1]]];
    let t = [
        pc[0] + k.offset_px[0] - (m[0][0] * c[0] + m[0][1] * c[1]),
        pc[1] + k.offset_px[1] - (m[1][0] * c[0] + m[1][1] * c[1]),
    ];
    ChartToImage { m, t }
}

/// Pearson correlation between the image and the chart through the inverse of `map`, with
/// `samples`² samples per pixel.
fn correlation(image: &Raster, reference: &Reference, map: &ChartToImage, samples: usize) -> f64 {
    let [[a, b], [c, d]] = map.m;
    let det = a * d - b * c;
    let inv = [[d / det, -b / det], [-c / det, a / det]];
    let (mut sx, mut sy, mut sxx, mut syy, mut sxy, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    // The sample offsets within a pixel, the same values for every pixel.
    let offsets: Vec<f64> = (0..samples)
        .map(|i| (i as f64 + 0.5) / samples as f64)
        .collect();
    // Index loops, not ranges: the test profile builds this crate at opt-level 1, which does not
    // inline a range's `next` (README, "The test suite's time"). The same operations in the same
    // order either way.
    let mut row = 0;
    while row < image.height {
        let mut col = 0;
        while col < image.width {
            let x = image.data[row * image.width + col];
            if x.is_finite() {
                let mut y = 0.0;
                let mut i = 0;
                while i < samples {
                    let mut j = 0;
                    while j < samples {
                        let p = [
                            col as f64 + offsets[i] - map.t[0],
                            row as f64 + offsets[j] - map.t[1],
                        ];
                        let mm_x = inv[0][0] * p[0] + inv[0][1] * p[1];
                        let mm_y = inv[1][0] * p[0] + inv[1][1] * p[1];
                        y += reference.at(mm_x, mm_y);
                        j += 1;
                    }
                    i += 1;
                }
                y /= (samples * samples) as f64;
                sx += x;
                sy += y;
                sxx += x * x;
                syy += y * y;
                sxy += x * y;
                n += 1.0;
            }
            col += 1;
        }
        row += 1;
    }
    let cov = sxy - sx * sy / n;
    let vx = sxx - sx * sx / n;
    let vy = syy - sy * sy / n;
    if n < 2.0 || vx <= 0.0 || vy <= 0.0 {
        return f64::NAN;
    }
    cov / (vx * vy).sqrt()
}

/// Registers `image` against `chart`, starting from the chart point `center_mm` that the
/// geometry puts at the image centre and the geometric scale `pixels_per_mm`. The search covers
/// all eight orientations, offsets of ±`max_offset_px` pixels and scales within ±12 % of the
/// guess. Errors: an empty image or a non-positive scale (input errors); a flat image gives a
/// NaN correlation, which the caller treats as "not registered".
pub fn register_chart(
    image: &Raster,
    chart: &UsafChart,
    center_mm: [f64; 2],
    pixels_per_mm: f64,
    max_offset_px: f64,
) -> Result<Registration> {
    if image.width == 0 || image.height == 0 {
        return Err(Error::input("registration needs a non-empty image"));
    }
    if !(pixels_per_mm.is_finite() && pixels_per_mm > 0.0) {
        return Err(Error::field(
            "pixels_per_mm",
            "the scale guess must be finite and positive",
        ));
    }
    let pc = [image.width as f64 / 2.0, image.height as f64 / 2.0];
    let mm_per_px = 1.0 / pixels_per_mm;
    let half_mm = (image.width.max(image.height) as f64 / 2.0 + max_offset_px.max(0.0) + 2.0)
        * mm_per_px
        * 1.2;
    let reference = Reference::new(chart, center_mm, half_mm, mm_per_px / OVERSAMPLE as f64)?;
    let score = |k: &Candidate, samples: usize| {
        let r = correlation(image, &reference, &map_of(k, center_mm, pc), samples);
        if r.is_nan() { f64::NEG_INFINITY } else { r }
    };

    // Coarse: every orientation, three scales, offsets on a one-pixel grid. The candidates are
    // scored in parallel and then taken in this order, each replacing the best only when it
    // scores strictly higher: the first best, as a sequential scan finds it, on any thread count.
    let reach = max_offset_px.max(0.0).floor() as i64;
    let mut coarse = Vec::new();
    for o in 0..8 {
        for scale in [0.94, 1.0, 1.06] {
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    coarse.push(Candidate {
                        orientation: o,
                        pixels_per_mm: pixels_per_mm * scale,
                        offset_px: [dx as f64, dy as f64],
                    });
                }
            }
        }
    }
    let scores: Vec<f64> = coarse
        .par_iter()
        .map(|k| score(k, COARSE_SAMPLES))
        .collect();
    let mut best = Candidate {
        orientation: 0,
        pixels_per_mm,
        offset_px: [0.0, 0.0],
    };
    let mut best_score = f64::NEG_INFINITY;
    for (k, &s) in coarse.iter().zip(&scores) {
        if s > best_score {
            best_score = s;
            best = *k;
        }
    }

    // Fine: the correlation is flat along the scale, and a search that moves scale and offset
    // one at a time stalls (a scale change about the image centre must be met by an offset
    // change), so scan the scale on a 0.25 % grid and, at each scale, refine the offset with a
    // pattern search of halving steps.
    let refine_offset = |mut k: Candidate, mut s: f64| {
        let mut step = 0.5;
        while step > 0.01 {
            let mut improved = true;
            while improved {
                improved = false;
                for (dx, dy) in [(step, 0.0), (-step, 0.0), (0.0, step), (0.0, -step)] {
                    let c = Candidate {
                        offset_px: [k.offset_px[0] + dx, k.offset_px[1] + dy],
                        ..k
                    };
                    let v = score(&c, FINE_SAMPLES);
                    if v > s {
                        (k, s) = (c, v);
                        improved = true;
                    }
                }
            }
            step /= 2.0;
        }
        (k, s)
    };
    let coarse = best;
    best_score = score(&coarse, FINE_SAMPLES);
    // The coarse scales are 6 % apart, so ±4 % around the coarse one reaches every scale. Each
    // scale's search is independent of the others: run in parallel, taken in order as above.
    let starts: Vec<Candidate> = (-16..=16)
        .map(|i| coarse.pixels_per_mm / pixels_per_mm * (1.0 + 0.0025 * i as f64))
        .filter(|ratio| (0.88..=1.12).contains(ratio))
        .map(|ratio| Candidate {
            pixels_per_mm: pixels_per_mm * ratio,
            ..coarse
        })
        .collect();
    let refined: Vec<(Candidate, f64)> = starts
        .par_iter()
        .map(|&start| refine_offset(start, score(&start, FINE_SAMPLES)))
        .collect();
    for (k, v) in refined {
        if v > best_score {
            (best, best_score) = (k, v);
        }
    }
    Ok(Registration {
        map: map_of(&best, center_mm, pc),
        correlation: if best_score.is_finite() {
            best_score
        } else {
            f64::NAN
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::usaf::Polarity;

    fn chart() -> UsafChart {
        UsafChart::new(-2, 3, Polarity::Negative).unwrap()
    }

    /// Renders the chart through a known map by 4×4 point sampling per pixel.
    fn render_through(map: &ChartToImage, w: usize, h: usize) -> Raster {
        let c = chart();
        let [[a, b], [cc, d]] = map.m;
        let det = a * d - b * cc;
        let mut out = Raster::zeros(w, h);
        for row in 0..h {
            for col in 0..w {
                let mut v = 0.0;
                for i in 0..4 {
                    for j in 0..4 {
                        let p = [
                            col as f64 + (i as f64 + 0.5) / 4.0 - map.t[0],
                            row as f64 + (j as f64 + 0.5) / 4.0 - map.t[1],
                        ];
                        let x = (d * p[0] - b * p[1]) / det;
                        let y = (-cc * p[0] + a * p[1]) / det;
                        if c.is_clear(x, y) {
                            v += 1.0 / 16.0;
                        }
                    }
                }
                out.data[row * w + col] = v;
            }
        }
        out
    }

    #[test]
    fn recovers_a_flipped_shifted_and_scaled_map() {
        // Truth: the chart's group −1 elements 5–6 region seen rotated by 180° (a lens's
        // inversion), 3 % larger than the guess, shifted by (1.3, −0.8) px.
        let center = crate::objects::usaf::UsafChart::new(-2, 3, Polarity::Negative)
            .unwrap()
            .element_region(-1, 5)
            .map(|r| [r.center_x_mm, r.center_y_mm])
            .unwrap();
        let guess_ppmm = 1.0 / 0.16416;
        let (w, h) = (48, 48);
        let truth_k = Candidate {
            orientation: 3,
            pixels_per_mm: guess_ppmm * 1.03,
            offset_px: [1.3, -0.8],
        };
        let truth = map_of(&truth_k, center, [24.0, 24.0]);
        let image = render_through(&truth, w, h);
        let reg = register_chart(&image, &chart(), center, guess_ppmm, 3.0).unwrap();
        assert!(reg.correlation > 0.97, "correlation {}", reg.correlation);
        // Every chart point of the test maps to within 0.1 px of where the truth puts it. The
        // search's resolution sets the budget: the scale grid (0.25 %) misses by at most half a
        // step, 0.125 % of the 26.6 px from the image centre to the farthest test point, i.e.
        // 0.033 px, and the offset search stops at 1/64 px; the rest is left for the sampling
        // difference between the reference render and this one.
        for (x, y) in [
            (-3.0, -3.0),
            (3.0, -3.0),
            (-3.0, 3.0),
            (3.0, 3.0),
            (0.0, 0.0),
        ] {
            let p = [center[0] + x, center[1] + y];
            let a = reg.map.apply(p[0], p[1]);
            let b = truth.apply(p[0], p[1]);
            let err = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
            assert!(err < 0.1, "at {p:?}: {a:?} vs {b:?} ({err} px)");
        }
    }

    #[test]
    fn the_parallel_search_finds_the_same_map_on_one_and_three_threads() {
        // Candidates are scored in parallel and taken in order: the map and the correlation
        // are the same bits on any thread count.
        let c = chart();
        let center = c
            .element_region(-1, 6)
            .map(|r| [r.center_x_mm, r.center_y_mm])
            .unwrap();
        let guess_ppmm = 1.0 / 0.16416;
        let truth_k = Candidate {
            orientation: 5,
            pixels_per_mm: guess_ppmm * 0.97,
            offset_px: [-0.6, 2.2],
        };
        let image = render_through(&map_of(&truth_k, center, [20.0, 16.0]), 40, 32);
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| register_chart(&image, &c, center, guess_ppmm, 3.0).unwrap())
        };
        let (a, b) = (on(1), on(3));
        assert!(a.correlation > 0.95, "correlation {}", a.correlation);
        assert_eq!(a.correlation.to_bits(), b.correlation.to_bits());
        assert_eq!(a.map.m, b.map.m);
        assert_eq!(a.map.t, b.map.t);
    }

    #[test]
    fn a_flat_image_does_not_register_and_bad_input_is_an_error() {
        let flat = Raster::new(16, 16, vec![1.0; 256]).unwrap();
        let reg = register_chart(&flat, &chart(), [0.0, 0.0], 5.0, 1.0).unwrap();
        assert!(reg.correlation.is_nan());
        assert!(
            register_chart(&flat, &chart(), [0.0, 0.0], 0.0, 1.0)
                .unwrap_err()
                .is_user_error()
        );
    }
}
