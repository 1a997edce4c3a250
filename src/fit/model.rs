//! The model's frame values and the misfit to the measured ones.
//!
//! A bench traced with (rays, seed) gives every frame's light on each diode,
//! u±(f) = Σ_j P_fj·g±_j plus c± (crate::transport::Transport::frame_currents, the
//! calibration frames as all-on/all-off pairs), and its Monte Carlo variance Σ_j P_fj·se(g±_j)² + se(c±)² (the units' batch sums taken
//! as independent). What a lab does not know enters linearly and is profiled out by weighted
//! least squares at every evaluation (variable projection: G. H. Golub and V. Pereyra, "The
//! differentiation of pseudo-inverses and nonlinear least squares problems whose variables
//! separate", *SIAM J. Numer. Anal.* 10, 413–432, 1973):
//!
//! - MONITOR+ = a₊·u₊ + b₊ and MONITOR− = a₋·u₋ + b₋: a± the lamp's absolute power times the
//!   monitor's transimpedance and the diode's responsivity, b± the offsets, ambient and dark;
//! - RF = r₊·u₊ − r₋·u₋ + b_RF: the RF transimpedance times each diode's responsivity.
//!
//! Seven nuisances in all, reported as scales relative to the bench's nominal electronics and
//! offsets in volts. Besides them each record has slow terms of its own ([`SlowTerms`]: an
//! offset shift per channel after the first record, and the room light's flicker as a sine and
//! a cosine per channel), without which the model misses what an acquisition adds: with the
//! model's trace the same as the recorded bench's (the same rays and seed, so that no trace
//! noise is left), χ² was 369 against the 111 the measured noise gives (3 120 values at
//! 300 000 rays); with them, 107. Left free, a change that only scales one arm's light (a
//! uniform loss of collection) is indistinguishable from that arm's gain, and the frames
//! constrain only the shape of each arm's per-unit collection map over the chart; a prior on
//! the four scales about the lamp's common unknown power ([`super::gains`], the default) lets
//! the arms' ratio speak too. The fit reports directions the frames do not fix as unidentified.
//!
//! Each frame value is weighted by 1 / (σ_c² + Σ_k a_k²·var u_k(f)): the measured noise of its
//! channel plus the model's Monte Carlo variance carried through the fitted scales, so that
//! χ²/dof ≈ 1 means "explained within the noise".

// Arm pairs [+, −] indexed as the formulas are written.
#![allow(clippy::needless_range_loop)]

use crate::acquisition::Sequence;
use crate::acquisition::schemes::CALIBRATION_PAIRS;
use crate::detector::Bap;
use crate::error::{Error, Result};
use crate::reconstruction::{BitMatrix, LinearOperator, PackedOperator, PatternForm};
use crate::transport::Transport;

use super::measured::Measured;

/// The nuisance names, in the order of [`Profiled::nuisances`].
pub const NUISANCES: [&str; 7] = [
    "rf_scale_plus",
    "rf_scale_minus",
    "rf_offset_v",
    "monitor_plus_scale",
    "monitor_plus_offset_v",
    "monitor_minus_scale",
    "monitor_minus_offset_v",
];

/// The model's light on the diodes for every measured frame, sequence by sequence.
#[derive(Debug, Clone)]
pub struct ModelFrames {
    /// [u₊, u₋] per frame (A), in the measured sequences' order.
    pub light_a: Vec<Vec<[f64; 2]>>,
    /// Their Monte Carlo variances (A²).
    pub var_a2: Vec<Vec<[f64; 2]>>,
}

/// The frames of sequence `q` as packed rows (frames × ⌈units/8⌉, most significant bit first),
/// as `run --scope-record` writes `patterns.npy`: what intake's `patterns_sha256` hashes.
pub fn packed_rows(bits: &BitMatrix, q: Sequence) -> Vec<u8> {
    let (m, units) = (bits.rows(), bits.cols());
    let lead = q.lead_frames();
    let frames = q.frames(m);
    let row_bytes = units.div_ceil(8);
    let mut data = vec![0u8; frames * row_bytes];
    for f in 0..frames {
        for j in 0..units {
            let on = match q {
                Sequence::Base => bits.get(f, j),
                Sequence::Complementary => bits.get(f / 2, j) != (f % 2 == 1),
                Sequence::CalibratedBase if f < lead => f.is_multiple_of(2),
                Sequence::CalibratedBase => bits.get(f - lead, j),
            };
            if on {
                data[f * row_bytes + j / 8] |= 0x80 >> (j % 8);
            }
        }
    }
    data
}

/// Σ_j P_ij·v_j for every row.
fn products(op: &PackedOperator, v: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; op.rows()];
    op.apply(v, &mut out);
    out
}

/// The light [u₊, u₋] (A) of every measured frame, sequence by sequence, from per-unit gains
/// g± (A), the pattern-independent light c± (A) and the gains' pattern products `pg` (Σ_j P_ij·g±_j
/// for every base pattern): the forward model of [`Transport::frame_currents_of`], with the
/// calibration frames as all-on/all-off pairs.
fn frame_lights(
    g: [&[f64]; 2],
    c: [f64; 2],
    pg: &[Vec<f64>; 2],
    measured: &Measured,
) -> Vec<Vec<[f64; 2]>> {
    let total = [g[0].iter().sum::<f64>(), g[1].iter().sum::<f64>()];
    let base = |i: usize| [pg[0][i] + c[0], total[1] - pg[1][i] + c[1]];
    let inverse = |i: usize| [total[0] - pg[0][i] + c[0], pg[1][i] + c[1]];
    let m = pg[0].len();
    measured
        .sequences
        .iter()
        .map(|q| match q.sequence {
            Sequence::Base => (0..m).map(base).collect(),
            Sequence::Complementary => (0..m).flat_map(|i| [base(i), inverse(i)]).collect(),
            Sequence::CalibratedBase => {
                let (all, none) = ([total[0] + c[0], c[1]], [c[0], total[1] + c[1]]);
                let mut l: Vec<[f64; 2]> =
                    (0..CALIBRATION_PAIRS).flat_map(|_| [all, none]).collect();
                l.extend((0..m).map(base));
                l
            }
        })
        .collect()
}

/// Whether frame `f` of sequence `q` is a calibration frame (all on or all off) rather than a
/// pattern: the two classes of [`VarianceScale`].
pub fn is_calibration_frame(q: Sequence, f: usize) -> bool {
    q == Sequence::CalibratedBase && f < 2 * CALIBRATION_PAIRS
}

/// The ratio of the frames' batch-means Monte Carlo variance to the sum of their units'
/// variances, per frame class (calibration frames, pattern frames) and arm ([`batch_frames`]).
/// The per-unit sum leaves out the covariances of the units: the rays of a batch are spread
/// over the lamp and the chart by one scrambled Sobol' sequence and each lands on one unit, so
/// their units' errors are anticorrelated and a frame's sum varies less than its units do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VarianceScale(pub [[f64; 2]; 2]);

impl Default for VarianceScale {
    fn default() -> Self {
        VarianceScale([[1.0; 2]; 2])
    }
}

/// The model's frames of every measured sequence for a traced transport, their Monte Carlo
/// variances the per-unit sums times `scale`.
pub fn model_frames(
    t: &Transport,
    bits: &BitMatrix,
    measured: &Measured,
    scale: &VarianceScale,
) -> ModelFrames {
    let op = PackedOperator::new(bits.clone(), PatternForm::ZeroOne);
    let light_a = frame_lights(
        [&t.g_a[0], &t.g_a[1]],
        [t.c_traced[0].value, t.c_traced[1].value],
        &t.pattern_products_of(&op),
        measured,
    );
    let mut var_a2 = naive_variances(t, &op, measured);
    for (q, v) in measured.sequences.iter().zip(&mut var_a2) {
        for (f, vf) in v.iter_mut().enumerate() {
            let class = usize::from(!is_calibration_frame(q.sequence, f));
            for a in 0..2 {
                vf[a] *= scale.0[class][a];
            }
        }
    }
    ModelFrames { light_a, var_a2 }
}

/// Each frame's Monte Carlo variance as the sum of its units' (and c±'s) variances.
fn naive_variances(t: &Transport, op: &PackedOperator, measured: &Measured) -> Vec<Vec<[f64; 2]>> {
    let finite2 = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .map(|s| if s.is_finite() { s * s } else { 0.0 })
            .collect()
    };
    let se2 = [finite2(&t.g_map_stderr[0]), finite2(&t.g_map_stderr[1])];
    let pv = [products(op, &se2[0]), products(op, &se2[1])];
    let c_v = [0, 1].map(|a| {
        let s = t.c_traced[a].stderr;
        if s.is_finite() { s * s } else { 0.0 }
    });
    // Variance of frame with pattern P: arm + sees the units on, arm − those off; the same
    // forward model with the variances in place of the gains.
    frame_lights([&se2[0], &se2[1]], c_v, &pv, measured)
}

/// A trace whose batches' frames are kept: for every measured frame, each batch's light less
/// its share of the total, [u₊, u₋] (A), frames in the measured order (flagged ones included).
pub struct BatchFrames {
    pub deviations: Vec<Vec<[f64; 2]>>,
    /// The batch-means factor B/(B − 1): the variance of a total is factor·Σ_b deviation².
    pub factor: f64,
}

impl BatchFrames {
    /// The batch-means variance of every frame (A²), sequences flattened in order.
    pub fn variances(&self) -> Vec<[f64; 2]> {
        let n = self.deviations.first().map_or(0, Vec::len);
        let mut v = vec![[0.0; 2]; n];
        for d in &self.deviations {
            for (vi, di) in v.iter_mut().zip(d) {
                for a in 0..2 {
                    vi[a] += di[a] * di[a];
                }
            }
        }
        for vi in &mut v {
            for a in 0..2 {
                vi[a] *= self.factor;
            }
        }
        v
    }

    /// The [`VarianceScale`] of these batches against the per-unit sums of `model`: per class
    /// and arm, Σ batch-means variance / Σ per-unit sum over the frames.
    pub fn scale(&self, model: &ModelFrames, measured: &Measured) -> VarianceScale {
        let exact = self.variances();
        let (mut num, mut den) = ([[0.0; 2]; 2], [[0.0; 2]; 2]);
        let mut i = 0;
        for (s, q) in measured.sequences.iter().enumerate() {
            for f in 0..q.values.len() {
                let class = usize::from(!is_calibration_frame(q.sequence, f));
                for a in 0..2 {
                    num[class][a] += exact[i][a];
                    den[class][a] += model.var_a2[s][f][a];
                }
                i += 1;
            }
        }
        let mut out = VarianceScale::default();
        for class in 0..2 {
            for a in 0..2 {
                if den[class][a] > 0.0 && num[class][a].is_finite() {
                    out.0[class][a] = num[class][a] / den[class][a];
                }
            }
        }
        out
    }
}

/// The trace of `bench` with (rays, seed), the same tallies as [`crate::trace::trace`] (the
/// same batches, absorbed in order), keeping each batch's frames ([`BatchFrames`]).
pub fn batch_frames(
    bench: &crate::optics::bench::Bench,
    rays: u64,
    seed: u64,
    bits: &BitMatrix,
    measured: &Measured,
) -> Result<(crate::pipeline::Traced, BatchFrames)> {
    use crate::trace::{RAYS_PER_BATCH, Tallies, TraceOptions, path};
    let opts = TraceOptions::new(rays.max(1), seed);
    let (across, down) = bench.units_shape();
    let mut tallies = Tallies::new(
        across,
        down,
        bench.elements().len(),
        seed,
        bench.lamp().power_outside_cone(),
    );
    let n = opts.rays;
    let n_batches = n.div_ceil(RAYS_PER_BATCH);
    let inv = 1.0 / n as f64;
    let op = PackedOperator::new(bits.clone(), PatternForm::ZeroOne);
    let units = bits.cols();
    let mut lights: Vec<Vec<[f64; 2]>> = Vec::with_capacity(n_batches as usize);
    crate::trace::batches_in_order(
        n_batches,
        |b| {
            let rays_b = RAYS_PER_BATCH.min(n - b * RAYS_PER_BATCH);
            let t = path::run_batch(bench, opts.mode, opts.sampling, seed, b, rays_b, inv);
            let g = crate::optics::Arm::ALL.map(|arm| {
                let (on, off) = (arm.state(), arm.other().state());
                (0..units)
                    .map(|j| {
                        t.t[crate::trace::BatchTally::t_index(units, arm, on, j)]
                            - t.t[crate::trace::BatchTally::t_index(units, arm, off, j)]
                    })
                    .collect::<Vec<f64>>()
            });
            let c = crate::optics::Arm::ALL.map(|arm| t.offset_sum(arm));
            let pg = [products(&op, &g[0]), products(&op, &g[1])];
            let l: Vec<[f64; 2]> = frame_lights([&g[0], &g[1]], c, &pg, measured)
                .into_iter()
                .flatten()
                .collect();
            (t, l)
        },
        |_, (t, l)| {
            tallies.absorb(&t);
            lights.push(l);
        },
        |_| {},
    );
    // Each batch's expected share of a total is its share of the rays (the last batch may be
    // short): the deviations are taken from that share.
    let nb = lights.len();
    let mut total = vec![[0.0; 2]; lights.first().map_or(0, Vec::len)];
    for l in &lights {
        for (m, v) in total.iter_mut().zip(l) {
            for a in 0..2 {
                m[a] += v[a];
            }
        }
    }
    for (b, l) in lights.iter_mut().enumerate() {
        let share = tallies.batches[b].rays as f64 / n as f64;
        for (v, m) in l.iter_mut().zip(&total) {
            for a in 0..2 {
                v[a] -= share * m[a];
            }
        }
    }
    let factor = crate::transport::batch_factor(nb as u64).unwrap_or(f64::INFINITY);
    let traced =
        crate::pipeline::Traced::from_tallies(bench, tallies, crate::pipeline::CacheStatus::Off);
    Ok((
        traced,
        BatchFrames {
            deviations: lights,
            factor,
        },
    ))
}

/// The misfit at one point, its nuisances profiled out.
#[derive(Debug, Clone)]
pub struct Profiled {
    /// Whitened residuals (measured − model) / σ of every used frame value, channel-major within
    /// each frame, sequences in order; then, with a gain prior, its rows ([`super::gains`]).
    pub residuals: Vec<f64>,
    pub chi2: f64,
    /// The linear nuisances in their fitted units (A → V scales, V offsets), [`NUISANCES`] order
    /// before the scales are made relative.
    pub nuisances: [f64; 7],
    /// Residuals (V) and their σ (V) per sequence, frame and channel (NaN where flagged).
    pub residual_v: Vec<Vec<[f64; 3]>>,
    pub sigma_v: Vec<Vec<[f64; 3]>>,
    /// The linear model's columns over all the rows of `residuals`, whitened (column·√weight):
    /// what the profiling projects out ([`super::chi2::expected`]).
    pub basis_w: Vec<Vec<f64>>,
    /// The gain prior's rows at the end of `residuals` (0 without a prior).
    pub prior_rows: usize,
    /// With a gain prior, the common scale of the four channel gains relative to the nominal
    /// electronics (the lamp's absolute power, which the lab does not know).
    pub lamp_scale: Option<f64>,
    /// The records' slow terms' coefficients ([`SlowTerms::split`] reads them).
    pub slow: Vec<f64>,
}

impl Profiled {
    /// The linear parameters fitted: the seven channel nuisances and the records' slow terms.
    pub fn linear_parameters(&self) -> usize {
        self.basis_w.len()
    }

    /// Degrees of freedom with `free` variables: rows (the prior's included) less the linear
    /// parameters and the variables.
    pub fn dof(&self, free: usize) -> usize {
        self.residuals
            .len()
            .saturating_sub(free + self.linear_parameters())
    }
}

/// Weighted least squares of y on the columns `x` (each a basis vector) with weights `w`:
/// the coefficients, through the normal equations (columns scaled to unit weighted norm).
pub(super) fn wls(cols: &[Vec<f64>], y: &[f64], w: &[f64]) -> Result<Vec<f64>> {
    let k = cols.len();
    // Columns scaled to unit weighted norm: the light (A) and the offsets' ones differ by 10¹².
    let norm: Vec<f64> = cols
        .iter()
        .map(|c| {
            let s: f64 = c.iter().zip(w).map(|(v, wi)| wi * v * v).sum();
            if s > 0.0 { s.sqrt() } else { 1.0 }
        })
        .collect();
    let mut a = vec![vec![0.0; k]; k];
    let mut b = vec![0.0; k];
    let mut x = vec![0.0; k];
    for n in 0..y.len() {
        let wn = w[n];
        if wn == 0.0 {
            continue;
        }
        for i in 0..k {
            x[i] = cols[i][n] / norm[i];
        }
        for i in 0..k {
            if x[i] == 0.0 {
                continue;
            }
            b[i] += wn * x[i] * y[n];
            for j in 0..k {
                a[i][j] += wn * x[i] * x[j];
            }
        }
    }
    let scaled = super::linalg::solve(a, b);
    scaled
        .map(|c| c.iter().zip(&norm).map(|(c, s)| c / s).collect())
        .ok_or_else(|| {
            Error::input(
                "the measured frames do not separate the model's light from the offsets (too few \
             distinct frames)",
            )
        })
}

/// What each record adds to its frames besides the light, slowly against a frame and not the
/// same from record to record, fitted as linear nuisances with the channels' offsets.
/// Each record is an acquisition of its own: the ambient light on the diodes drifts between
/// them (an Ornstein–Uhlenbeck process of 10 s against a record of some 50 ms: a constant
/// within a record, another in the next), so each record after the first has an offset shift
/// per channel; and room lights on the mains flicker at twice its frequency, so each record
/// has a sine and a cosine per channel at each of `hum_hz`, in its frames' start times. The
/// calibration frames, from which the noise is measured, last well under one cycle, so their
/// scatter does not see either.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SlowTerms {
    /// The flicker and ripple frequencies (Hz), distinct and positive.
    pub hum_hz: Vec<f64>,
}

impl SlowTerms {
    /// The bench's ambient flicker and lamp ripple frequencies, where their amplitude is not 0.
    pub fn of(drift: &crate::detector::Drift) -> SlowTerms {
        let mut hum_hz = Vec::new();
        for (amplitude, hz) in [
            (drift.ambient_flicker_depth, drift.ambient_flicker_hz),
            (drift.lamp_ripple_amplitude, drift.lamp_ripple_hz),
        ] {
            if amplitude > 0.0 && hz > 0.0 && !hum_hz.contains(&hz) {
                hum_hz.push(hz);
            }
        }
        SlowTerms { hum_hz }
    }

    /// How many slow-term columns `records` records have.
    fn columns(&self, records: usize) -> usize {
        3 * records.saturating_sub(1) + 6 * records * self.hum_hz.len()
    }

    /// Where, among the slow-term columns, record `r`'s offset shift on channel `o` is (None
    /// for the first record, the reference).
    fn shift_at(r: usize, o: usize) -> Option<usize> {
        (r > 0).then(|| 3 * (r - 1) + o)
    }

    /// Where record `r`'s sine on channel `o` at hum frequency `h` is (its cosine follows).
    fn hum_at(&self, records: usize, r: usize, h: usize, o: usize) -> usize {
        3 * records.saturating_sub(1) + 6 * (r * self.hum_hz.len() + h) + 2 * o
    }

    /// The fitted slow terms of `records` records from their coefficients (the columns after
    /// the seven nuisances, [`free_columns`]' order): each record's offset shift per channel
    /// (V; zero for the first) and, per hum frequency, each channel's amplitude √(s² + c²) (V).
    pub fn split(&self, records: usize, coef: &[f64]) -> (Vec<[f64; 3]>, Vec<Vec<[f64; 3]>>) {
        let shift = (0..records)
            .map(|r| [0, 1, 2].map(|o| Self::shift_at(r, o).map_or(0.0, |at| coef[at])))
            .collect();
        let hum = (0..records)
            .map(|r| {
                (0..self.hum_hz.len())
                    .map(|h| {
                        [0, 1, 2].map(|o| {
                            let at = self.hum_at(records, r, h, o);
                            coef[at].hypot(coef[at + 1])
                        })
                    })
                    .collect()
            })
            .collect();
        (shift, hum)
    }
}

/// The used frames flattened: the model's light and its variance per arm, the measured values
/// per channel, each frame's record (its index among the measured sequences) and start time.
pub(super) struct Flat {
    pub u: [Vec<f64>; 2],
    pub var: [Vec<f64>; 2],
    pub y: [Vec<f64>; 3],
    pub record: Vec<usize>,
    pub t: Vec<f64>,
    pub records: usize,
    pub slow: SlowTerms,
}

fn flatten(model: &ModelFrames, measured: &Measured, slow: &SlowTerms) -> Flat {
    let mut u = [Vec::new(), Vec::new()];
    let mut var = [Vec::new(), Vec::new()];
    let mut y = [Vec::new(), Vec::new(), Vec::new()];
    let (mut record, mut t) = (Vec::new(), Vec::new());
    for (s, q) in measured.sequences.iter().enumerate() {
        for (f, v) in q.values.iter().enumerate() {
            if q.flagged[f] {
                continue;
            }
            for a in 0..2 {
                u[a].push(model.light_a[s][f][a]);
                var[a].push(model.var_a2[s][f][a]);
            }
            for o in 0..3 {
                y[o].push(v[o]);
            }
            record.push(s);
            t.push(q.start_s[f]);
        }
    }
    Flat {
        u,
        var,
        y,
        record,
        t,
        records: measured.sequences.len(),
        slow: slow.clone(),
    }
}

impl Flat {
    pub fn frames(&self) -> usize {
        self.y[0].len()
    }

    /// The rows' weights 1 / (σ_c² + Σ_arm c²·var u_arm) from the channel gains
    /// `scales` = [RF on u₊, RF on u₋, MONITOR+, MONITOR−] (V/A), rows frame-major.
    pub fn weights(&self, floor: [f64; 3], scales: [f64; 4]) -> Vec<f64> {
        let n = self.frames();
        let mut w = Vec::with_capacity(3 * n);
        for i in 0..n {
            let mc = [
                scales[0] * scales[0] * self.var[0][i] + scales[1] * scales[1] * self.var[1][i],
                scales[2] * scales[2] * self.var[0][i],
                scales[3] * scales[3] * self.var[1][i],
            ];
            for o in 0..3 {
                w.push(1.0 / (floor[o] + mc[o]));
            }
        }
        w
    }

    /// The measured values, rows frame-major (channels within).
    pub fn rows(&self) -> Vec<f64> {
        (0..self.frames())
            .flat_map(|i| [self.y[0][i], self.y[1][i], self.y[2][i]])
            .collect()
    }
}

/// The free nuisances' columns over the rows (frame-major, channels within): first the seven
/// of [`NUISANCES`] (each channel's scale(s) on the light and its offset), then the records'
/// slow terms ([`SlowTerms`]): per channel, an offset shift for each record after the first,
/// then for each record a sine and a cosine at each hum frequency.
pub(super) fn free_columns(flat: &Flat) -> Vec<Vec<f64>> {
    let n = flat.frames();
    let slow = &flat.slow;
    let mut cols = vec![vec![0.0; 3 * n]; 7 + slow.columns(flat.records)];
    for i in 0..n {
        let (up, um) = (flat.u[0][i], flat.u[1][i]);
        cols[0][3 * i] = up;
        cols[1][3 * i] = -um;
        cols[2][3 * i] = 1.0;
        cols[3][3 * i + 1] = up;
        cols[4][3 * i + 1] = 1.0;
        cols[5][3 * i + 2] = um;
        cols[6][3 * i + 2] = 1.0;
        let r = flat.record[i];
        for o in 0..3 {
            if let Some(at) = SlowTerms::shift_at(r, o) {
                cols[7 + at][3 * i + o] = 1.0;
            }
            for (h, hz) in slow.hum_hz.iter().enumerate() {
                let phase = std::f64::consts::TAU * hz * flat.t[i];
                let at = 7 + slow.hum_at(flat.records, r, h, o);
                cols[at][3 * i + o] = phase.sin();
                cols[at + 1][3 * i + o] = phase.cos();
            }
        }
    }
    cols
}

/// The misfit of the model's frames to the measured ones, the nuisances profiled out (module
/// notes), in two passes: the weights of the second carry the first's fitted scales. With a
/// gain prior ([`super::gains`]) the scales are then fitted again under it.
pub fn profile(
    model: &ModelFrames,
    measured: &Measured,
    prior: Option<&super::gains::GainPrior>,
    slow: &SlowTerms,
) -> Result<Profiled> {
    let flat = flatten(model, measured, slow);
    let n = flat.frames();
    let floor = measured.noise_v.map(|s| (s * s).max(1e-30));
    let scales_of = |c: &[f64]| [c[0], c[1], c[3], c[5]];
    let mut cols = free_columns(&flat);
    let mut y = flat.rows();
    let mut w = flat.weights(floor, [0.0; 4]);
    let mut c = wls(&cols, &y, &w)?;
    w = flat.weights(floor, scales_of(&c));
    c = wls(&cols, &y, &w)?;
    let mut nuisances: [f64; 7] = c[..7].try_into().expect("seven nuisances");
    let mut lamp_scale = None;
    let mut prior_rows = 0;
    if let Some(pr) = prior {
        let fit = super::gains::fit_under_prior(&flat, floor, &c, pr)?;
        (cols, y, w, c) = (fit.cols, fit.y, fit.w, fit.coef);
        nuisances = c[..7].try_into().expect("seven nuisances");
        lamp_scale = Some(fit.lamp_scale);
        prior_rows = fit.prior_rows;
    }
    let mut residuals = Vec::with_capacity(y.len());
    let mut chi2 = 0.0;
    for (r, yr) in y.iter().enumerate() {
        let pred: f64 = cols.iter().zip(&c).map(|(col, ci)| ci * col[r]).sum();
        let z = (yr - pred) * w[r].sqrt();
        residuals.push(z);
        chi2 += z * z;
    }
    let mut residual_v = Vec::new();
    let mut sigma_v = Vec::new();
    let mut i = 0;
    for q in &measured.sequences {
        let (mut rv, mut sv) = (Vec::new(), Vec::new());
        for f in 0..q.values.len() {
            if q.flagged[f] {
                rv.push([f64::NAN; 3]);
                sv.push([f64::NAN; 3]);
                continue;
            }
            let s3 = [0, 1, 2].map(|o| 1.0 / w[3 * i + o].sqrt());
            rv.push([0, 1, 2].map(|o| residuals[3 * i + o] * s3[o]));
            sv.push(s3);
            i += 1;
        }
        residual_v.push(rv);
        sigma_v.push(sv);
    }
    debug_assert_eq!(i, n);
    let basis_w = cols
        .iter()
        .map(|col| col.iter().zip(&w).map(|(c, w)| c * w.sqrt()).collect())
        .collect();
    Ok(Profiled {
        residuals,
        chi2,
        nuisances,
        residual_v,
        sigma_v,
        basis_w,
        prior_rows,
        lamp_scale,
        slow: c[7..].to_vec(),
    })
}

/// The nominal scales (V/A) of [`NUISANCES`]' scale entries from the bench's electronics: the
/// RF and monitor transimpedances times each diode's responsivity scale.
pub fn nominal_scales(bap: &Bap) -> [f64; 4] {
    let s = bap.responsivity_scale;
    let (g_rf, g_p, g_m) = (
        bap.stage(0).gain_v_per_a,
        bap.stage(1).gain_v_per_a,
        bap.stage(2).gain_v_per_a,
    );
    [g_rf * s[0], g_rf * s[1], g_p * s[0], g_m * s[1]]
}
