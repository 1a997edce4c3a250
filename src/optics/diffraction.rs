//! The micromirror array as a blazed two-dimensional grating (docs/dmd_diffraction.md).
//!
//! A ray that meets a mirror front is one plane-wave component of the illumination. The array
//! (pitch p along x and y, square mirrors of side s tilted about their diagonal) reflects it into
//! discrete orders (m, n) whose direction cosines in the array plane obey the grating equation
//!
//!   α_mn = d_x + m·λ/p,   β_mn = d_y + n·λ/p,   γ_mn = +√(1 − α² − β²),
//!
//! evanescent when α² + β² ≥ 1. The share of each order is the squared Fourier coefficient of the
//! reflected field in the array plane z = 0. One mirror reflects a plane wave specularly, into
//! u_s = d − 2(d·N)N; carried along u_s down to z = 0, its field fills the mirror's shadow along
//! u_s (a parallelogram spanned by E₁, E₂, the mirror's edges projected along u_s) with the
//! transverse wavevector k·u_s,xy (the local-plane-wave form of the Kirchhoff integral, equal to
//! it to first order in the distance from the specular direction). The Fourier coefficient of
//! that footprint gives the single-mirror Fraunhofer envelope
//!
//!   P_mn = (|E₁ × E₂| / p²) · sinc²(K·E₁/2) · sinc²(K·E₂/2),   K = k·(α_mn − u_s,x, β_mn − u_s,y),
//!
//! which peaks where an order meets the mirror's specular direction (the blaze condition). By
//! Parseval the P_mn of all orders, evanescent ones included, sum to 1: the orders share the
//! power the mirror reflects, R(λ) times what its front intercepts. Evanescent orders carry no
//! power away; their share is booked as absorbed by the aluminium (the ledger stays balanced ray
//! by ray).
//!
//! Sampling (one uniform per mirror hit): the 5 × 5 orders around the envelope's peak are
//! evaluated exactly for the ray's own direction and wavelength (about 90 % of the power); the
//! rest, the tail, takes its exact total mass 1 − Σ core but its shape from a table computed once
//! per bench, mirror state and wavelength bin at normal incidence (docs/dmd_diffraction.md,
//! "Sampling").

use glam::{DMat3, DVec3};

/// Orders on each side of the envelope's peak evaluated exactly per ray (a 5 × 5 core).
pub const CORE_RADIUS: i32 = 2;
const CORE_SIDE: usize = (2 * CORE_RADIUS + 1) as usize;
const CORE: usize = CORE_SIDE * CORE_SIDE;

/// The largest order offset from the peak that the tail table holds: it covers every
/// propagating order of any incidence while 2p/λ ≤ 96 (p ≤ 17 µm at 350 nm); beyond, the
/// remainder (under 1 % of the power) is booked as evanescent. i8 offsets.
pub const TAIL_RADIUS_MAX: i32 = 96;

/// Below this γ of the specular direction (about 87° from the normal) a reflection is too grazing
/// for the projected footprint: the mirror reflects geometrically.
const GRAZING_GAMMA: f64 = 0.05;

/// One mirror state's facet: its normal and the unit vectors along its two edges (flat, the edges
/// are x and y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Facet {
    pub normal: DVec3,
    pub e1: DVec3,
    pub e2: DVec3,
}

impl Facet {
    /// The facet of a flat mirror rotated by `rot`.
    pub fn rotated(rot: DMat3) -> Facet {
        Facet {
            normal: rot * DVec3::Z,
            e1: rot * DVec3::X,
            e2: rot * DVec3::Y,
        }
    }
}

/// The grating: mirror pitch and side (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grating {
    pub pitch: f64,
    pub side: f64,
}

/// sinc²(x) = (sin x / x)².
#[inline]
fn sinc2(x: f64) -> f64 {
    if x.abs() < 1e-8 {
        1.0
    } else {
        let s = x.sin() / x;
        s * s
    }
}

/// The envelope of one incidence direction, wavelength and facet: the two linear forms
/// A = K·E₁/2, B = K·E₂/2 in the order offsets (i, j) from the peak order (m₀, n₀).
#[derive(Debug, Clone, Copy)]
pub struct Envelope {
    /// |E₁ × E₂| / p²: the footprint's area over the cell's.
    pub scale: f64,
    /// A = a[0] + i·a[1] + j·a[2]; B likewise.
    a: [f64; 3],
    b: [f64; 3],
    /// The order nearest the specular direction.
    pub m0: i32,
    pub n0: i32,
    /// The specular direction.
    pub specular: DVec3,
}

impl Envelope {
    /// The envelope for a ray along `d` (unit, towards the array) meeting `facet` at wavelength
    /// `wl` (m); None when the specular reflection is too grazing (see [`GRAZING_GAMMA`]).
    pub fn new(g: Grating, facet: &Facet, d: DVec3, wl: f64) -> Option<Envelope> {
        let n = facet.normal;
        let us = d - 2.0 * d.dot(n) * n;
        if us.z < GRAZING_GAMMA {
            return None;
        }
        // The edges carried along u_s down to z = 0.
        let shear = |e: DVec3| (e.x - e.z * us.x / us.z, e.y - e.z * us.y / us.z);
        let (e1, e2) = (shear(facet.e1), shear(facet.e2));
        let (e1, e2) = (
            (g.side * e1.0, g.side * e1.1),
            (g.side * e2.0, g.side * e2.1),
        );
        let det = (e1.0 * e2.1 - e1.1 * e2.0).abs();
        // The peak in order units: c = (u_s,xy − d_xy)·p/λ.
        let cx = (us.x - d.x) * g.pitch / wl;
        let cy = (us.y - d.y) * g.pitch / wl;
        let (m0, n0) = (cx.round(), cy.round());
        let (dx, dy) = (cx - m0, cy - n0);
        // K = (2π/p)·((i, j) − δ): A = (π/p)·((i − δx)·E₁x + (j − δy)·E₁y).
        let f = std::f64::consts::PI / g.pitch;
        let form = |e: (f64, f64)| [-f * (dx * e.0 + dy * e.1), f * e.0, f * e.1];
        Some(Envelope {
            scale: det / (g.pitch * g.pitch),
            a: form(e1),
            b: form(e2),
            m0: m0 as i32,
            n0: n0 as i32,
            specular: us,
        })
    }

    /// P of the order at offset (i, j) from the peak order.
    #[inline]
    pub fn probability(&self, i: i32, j: i32) -> f64 {
        let (i, j) = (i as f64, j as f64);
        let a = self.a[0] + i * self.a[1] + j * self.a[2];
        let b = self.b[0] + i * self.b[1] + j * self.b[2];
        self.scale * sinc2(a) * sinc2(b)
    }

    /// P of the 5 × 5 core orders, row-major in (i, j) from (−2, −2), and their sum (at most 1:
    /// scaled down in the degenerate case of a footprint larger than the cell). The sines come
    /// from angle addition (14 sin/cos pairs instead of 50 sines): this runs once per mirror hit.
    #[inline]
    fn core(&self) -> ([f64; CORE], f64) {
        let mut p = self.core_raw();
        let sum: f64 = p.iter().sum();
        if sum > 1.0 {
            for v in &mut p {
                *v /= sum;
            }
            return (p, 1.0);
        }
        (p, sum)
    }

    #[inline]
    fn core_raw(&self) -> [f64; CORE] {
        let sa = Forms::new(&self.a);
        let sb = Forms::new(&self.b);
        let mut p = [0.0; CORE];
        for (k, pk) in p.iter_mut().enumerate() {
            let (ii, jj) = (k / CORE_SIDE, k % CORE_SIDE);
            *pk = self.scale * sa.sinc2(ii, jj) * sb.sinc2(ii, jj);
        }
        p
    }
}

/// sin and value of a linear form x = c + i·u + j·v on the core's offsets.
struct Forms {
    /// (sin, cos) of c + i·u for each row i.
    rows: [(f64, f64); CORE_SIDE],
    /// (sin, cos) of j·v for each column j.
    cols: [(f64, f64); CORE_SIDE],
    f: [f64; 3],
}

impl Forms {
    #[inline]
    fn new(f: &[f64; 3]) -> Forms {
        let mut rows = [(0.0, 0.0); CORE_SIDE];
        let mut cols = [(0.0, 0.0); CORE_SIDE];
        for (k, row) in rows.iter_mut().enumerate() {
            let o = k as f64 - CORE_RADIUS as f64;
            *row = (f[0] + o * f[1]).sin_cos();
        }
        for k in 0..=CORE_RADIUS as usize {
            let o = k as f64;
            let (s, c) = (o * f[2]).sin_cos();
            cols[CORE_RADIUS as usize + k] = (s, c);
            cols[CORE_RADIUS as usize - k] = (-s, c);
        }
        Forms { rows, cols, f: *f }
    }

    #[inline]
    fn sinc2(&self, ii: usize, jj: usize) -> f64 {
        let x = self.f[0]
            + (ii as f64 - CORE_RADIUS as f64) * self.f[1]
            + (jj as f64 - CORE_RADIUS as f64) * self.f[2];
        if x.abs() < 1e-8 {
            return 1.0;
        }
        let (sr, cr) = self.rows[ii];
        let (sc, cc) = self.cols[jj];
        let s = (sr * cc + cr * sc) / x;
        s * s
    }
}

/// One entry of a tail table: the cumulative share up to and including this order, and its
/// offset from the peak order. The last entry of every table is the remainder beyond the table
/// (offsets `FAR`), booked as evanescent.
#[derive(Debug, Clone, Copy)]
struct TailEntry {
    cdf: f32,
    i: i8,
    j: i8,
}

const FAR: i8 = i8::MIN;

/// The diffractive model of an array: its grating, the facets of the three mirror states and,
/// per state and wavelength bin, the tail table.
#[derive(Debug, Clone)]
pub struct Diffraction {
    grating: Grating,
    facets: [Facet; 3],
    band: (f64, f64),
    bin: f64,
    bins: usize,
    /// tails[bin][state]: None for a state no mirror of the bench takes.
    tails: Vec<[Option<Vec<TailEntry>>; 3]>,
}

/// The orders a ray can reach, (m, n, probability), and the share that leaves nowhere.
pub type Distribution = (Vec<(i32, i32, f64)>, f64);

/// Where a drawn order sends a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Order {
    /// A propagating order, its unit direction and (m, n).
    Propagating { direction: DVec3, m: i32, n: i32 },
    /// An evanescent order, or one that would leave below the facet's own plane: no power leaves.
    Evanescent,
    /// Too grazing for the model: the mirror reflects geometrically.
    Specular,
}

impl Diffraction {
    /// The model for `grating`, the facets of the states (index [`super::dmd::state_index`]),
    /// the traced band (m) cut into bins of `bin` (m) for the tail tables, built for the states
    /// flagged in `used`.
    pub fn new(
        grating: Grating,
        facets: [Facet; 3],
        band: (f64, f64),
        bin: f64,
        used: [bool; 3],
    ) -> Diffraction {
        let (bins, bin) = bins_of(band, bin);
        let tails = (0..bins)
            .map(|b| {
                let wl = band.0 + (b as f64 + 0.5) * bin;
                std::array::from_fn(|s| used[s].then(|| tail_table(grating, &facets[s], wl)))
            })
            .collect();
        Diffraction {
            grating,
            facets,
            band,
            bin,
            bins,
            tails,
        }
    }

    pub fn grating(&self) -> Grating {
        self.grating
    }

    pub fn facet(&self, state: usize) -> &Facet {
        &self.facets[state]
    }

    fn bin_of(&self, wl: f64) -> usize {
        (((wl - self.band.0) / self.bin).floor().max(0.0) as usize).min(self.bins - 1)
    }

    /// Draws the order of a ray along `d` meeting a mirror in state `state` at wavelength `wl`
    /// from one uniform `u` in [0, 1).
    pub fn draw(&self, state: usize, d: DVec3, wl: f64, u: f64) -> Order {
        let facet = &self.facets[state];
        let Some(env) = Envelope::new(self.grating, facet, d, wl) else {
            return Order::Specular;
        };
        let (core, core_sum) = env.core();
        let mut acc = 0.0;
        let mut offset = None;
        for (k, p) in core.iter().enumerate() {
            acc += p;
            if u < acc {
                offset = Some((
                    (k / CORE_SIDE) as i32 - CORE_RADIUS,
                    (k % CORE_SIDE) as i32 - CORE_RADIUS,
                ));
                break;
            }
        }
        let (i, j) = match offset {
            Some(o) => o,
            None => {
                let Some(tail) = &self.tails[self.bin_of(wl)][state] else {
                    return Order::Evanescent;
                };
                // The rest of u, uniform on the tail.
                let v = ((u - core_sum) / (1.0 - core_sum)) as f32;
                let k = tail.partition_point(|e| e.cdf <= v).min(tail.len() - 1);
                let e = tail[k];
                if e.i == FAR {
                    return Order::Evanescent;
                }
                (e.i as i32, e.j as i32)
            }
        };
        self.order(facet, d, wl, env.m0 + i, env.n0 + j)
    }

    /// The direction of order (m, n) for a ray along `d` at `wl`.
    fn order(&self, facet: &Facet, d: DVec3, wl: f64, m: i32, n: i32) -> Order {
        let q = wl / self.grating.pitch;
        let (a, b) = (d.x + m as f64 * q, d.y + n as f64 * q);
        let g2 = 1.0 - a * a - b * b;
        if g2 <= 0.0 {
            return Order::Evanescent;
        }
        let direction = DVec3::new(a, b, g2.sqrt());
        if direction.dot(facet.normal) <= 0.0 {
            return Order::Evanescent;
        }
        Order::Propagating { direction, m, n }
    }

    /// The distribution the sampler draws from for a ray along `d` at `wl` in state `state`:
    /// every order it can reach, with its probability, and the share that goes nowhere
    /// (evanescent orders, orders below the facet, the remainder beyond the table). The
    /// probabilities and that share sum to 1. None when the reflection is geometric (grazing).
    pub fn distribution(&self, state: usize, d: DVec3, wl: f64) -> Option<Distribution> {
        let facet = &self.facets[state];
        let env = Envelope::new(self.grating, facet, d, wl)?;
        let (core, core_sum) = env.core();
        let mut orders = Vec::new();
        let mut lost = 0.0;
        let mut put = |i: i32, j: i32, p: f64, lost: &mut f64| match self.order(
            facet,
            d,
            wl,
            env.m0 + i,
            env.n0 + j,
        ) {
            Order::Propagating { m, n, .. } => orders.push((m, n, p)),
            _ => *lost += p,
        };
        for (k, p) in core.iter().enumerate() {
            let (i, j) = (
                (k / CORE_SIDE) as i32 - CORE_RADIUS,
                (k % CORE_SIDE) as i32 - CORE_RADIUS,
            );
            put(i, j, *p, &mut lost);
        }
        let tail_mass = 1.0 - core_sum;
        match &self.tails[self.bin_of(wl)][state] {
            None => lost += tail_mass,
            Some(tail) => {
                let mut prev = 0.0f64;
                for e in tail {
                    let p = (e.cdf as f64 - prev) * tail_mass;
                    prev = e.cdf as f64;
                    if e.i == FAR {
                        lost += p;
                    } else {
                        put(e.i as i32, e.j as i32, p, &mut lost);
                    }
                }
            }
        }
        Some((orders, lost))
    }
}

/// The tail table of one facet at wavelength `wl`, at normal incidence: every order offset within
/// the table radius outside the core, with its share of the tail, then the remainder.
fn tail_table(g: Grating, facet: &Facet, wl: f64) -> Vec<TailEntry> {
    let d = DVec3::new(0.0, 0.0, -1.0);
    let Some(env) = Envelope::new(g, facet, d, wl) else {
        return vec![TailEntry {
            cdf: 1.0,
            i: FAR,
            j: FAR,
        }];
    };
    let r = tail_radius(g, wl);
    let core_sum = env.core().1;
    let tail_mass = 1.0 - core_sum;
    let mut entries = Vec::with_capacity(((2 * r + 1) * (2 * r + 1)) as usize);
    let mut acc = 0.0f64;
    for i in -r..=r {
        for j in -r..=r {
            if i.abs() <= CORE_RADIUS && j.abs() <= CORE_RADIUS {
                continue;
            }
            let p = env.probability(i, j);
            if p <= 0.0 {
                continue;
            }
            acc += p;
            entries.push((acc, i as i8, j as i8));
        }
    }
    // Shares of the tail; the remainder (≥ 0 up to rounding) is the evanescent far field.
    let norm = if tail_mass > acc { tail_mass } else { acc };
    let mut table: Vec<TailEntry> = entries
        .into_iter()
        .map(|(c, i, j)| TailEntry {
            cdf: (c / norm) as f32,
            i,
            j,
        })
        .collect();
    table.push(TailEntry {
        cdf: 1.0,
        i: FAR,
        j: FAR,
    });
    table
}

/// The tail tables' wavelength bins: the band cut into `bins` equal bins of at most `bin` (m).
fn bins_of(band: (f64, f64), bin: f64) -> (usize, f64) {
    let bins = (((band.1 - band.0) / bin).ceil() as usize).max(1);
    (bins, (band.1 - band.0) / bins as f64)
}

/// The orders on each side of the peak that the tail table at `wl` holds: every propagating
/// order of any incidence (2p/λ + 1), within the core's edge and [`TAIL_RADIUS_MAX`].
fn tail_radius(g: Grating, wl: f64) -> i32 {
    ((2.0 * g.pitch / wl).ceil() as i32 + 1).clamp(CORE_RADIUS + 1, TAIL_RADIUS_MAX)
}

/// The memory the tail tables of [`Diffraction::new`] take at most, and the settings that make
/// it: every order within each bin's table radius, in each state used, plus the one table being
/// built (its entries in f64) and each bin's slots. Estimated in closed form before anything is
/// allocated (a loop over the bins, none over the orders).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableSize {
    pub bytes: f64,
    pub bins: usize,
    /// The width of a bin (m) and the band (m).
    pub bin: f64,
    pub band: (f64, f64),
    pub states: usize,
    /// The orders of the largest table.
    pub largest: usize,
    pub pitch: f64,
}

impl TableSize {
    pub fn new(g: Grating, band: (f64, f64), bin: f64, used: [bool; 3]) -> TableSize {
        let (bins, bin) = bins_of(band, bin);
        let states = used.iter().filter(|u| **u).count();
        let side = |r: i32| (2 * r as usize + 1).pow(2);
        let most = side(TAIL_RADIUS_MAX) - CORE + 1;
        // Beyond a million bins every table is taken at the largest size (an upper bound
        // without a long loop).
        let (entries, largest) = if bins > 1_000_000 {
            (bins as f64 * most as f64, most)
        } else {
            let (mut sum, mut largest) = (0.0, 0);
            for b in 0..bins {
                let wl = band.0 + (b as f64 + 0.5) * bin;
                let n = side(tail_radius(g, wl)) - CORE + 1;
                sum += n as f64;
                largest = largest.max(n);
            }
            (sum, largest)
        };
        let bytes = states as f64 * entries * std::mem::size_of::<TailEntry>() as f64
            + largest as f64 * std::mem::size_of::<(f64, i8, i8)>() as f64
            + bins as f64 * std::mem::size_of::<[Option<Vec<TailEntry>>; 3]>() as f64;
        TableSize {
            bytes,
            bins,
            bin,
            band,
            states,
            largest,
            pitch: g.pitch,
        }
    }

    /// The settings in words: "5400 wavelength bins of 0.5 nm over 300–3000 nm × 3 mirror
    /// states × up to 37249 orders each (a 60 µm pitch)".
    pub fn settings(&self) -> String {
        format!(
            "{} wavelength bins of {} nm over {}–{} nm × {} mirror states × up to {} orders \
             each (a {} µm pitch)",
            self.bins,
            round(self.bin * 1e9),
            round(self.band.0 * 1e9),
            round(self.band.1 * 1e9),
            self.states,
            self.largest,
            round(self.pitch * 1e6)
        )
    }
}

/// A length in a unit, rounded to what a file would write (floating-point noise dropped).
fn round(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// The probability of the absolute order (m, n) under the envelope for a ray along `d` at `wl`
/// (for validation and reports; the sampler uses [`Diffraction::draw`]). None when grazing.
pub fn order_probability(
    g: Grating,
    facet: &Facet,
    d: DVec3,
    wl: f64,
    m: i32,
    n: i32,
) -> Option<f64> {
    let env = Envelope::new(g, facet, d, wl)?;
    Some(env.probability(m - env.m0, n - env.n0))
}

#[cfg(test)]
mod tests;
