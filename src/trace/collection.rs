//! Spectral collection: the share of the light the DMD's pattern mirrors reflect that reaches
//! each arm's photodiode, per wavelength bin (docs/dmd_diffraction.md, "What trace reports").
//!
//! One ordinary trace in branch mode (the streams and batches of `trace::trace`, so the result
//! is bit-identical on any number of threads) with a recorder that bins, by the lamp ray's
//! wavelength, the power incident on the pattern mirrors (x, the mean over the two branches)
//! and the power each diode detects from each branch. The share of diode d from state s in a bin
//! is detected[d][s] / (x·R(λ)), R the mirrors' reflectance at the bin centre: with geometric
//! mirrors it is the arms' geometric collection; with the diffractive model it also carries
//! the orders that miss the diode.

use crate::error::{Error, Result};
use crate::optics::dmd::MirrorState;
use crate::optics::{Arm, Bench};

use super::RAYS_PER_BATCH;
use super::path::{self, Detection, PatternMode, Recorder};
use super::tally::{BatchTally, branch_state};

/// Per wavelength bin of the traced band: power on the pattern mirrors and detected power.
#[derive(Debug, Clone, PartialEq)]
pub struct Collection {
    /// The traced band (m) and its bins (equal widths).
    pub band_m: (f64, f64),
    pub bins: usize,
    /// Power incident on the pattern mirrors per bin (W).
    pub incident_w: Vec<f64>,
    /// Power the pattern mirrors reflect per bin (W): incident × R(bin centre).
    pub reflected_w: Vec<f64>,
    /// Detected power per bin, [diode arm][mirror state of the branch: +, −] (W).
    pub detected_w: Vec<[[f64; 2]; 2]>,
}

impl Collection {
    /// The centre of bin `b` (m).
    pub fn wavelength_m(&self, b: usize) -> f64 {
        let w = (self.band_m.1 - self.band_m.0) / self.bins as f64;
        self.band_m.0 + (b as f64 + 0.5) * w
    }

    /// The share of the reflected power of the mirrors in the state of `state` that reaches the
    /// diode of `diode`, over the whole band.
    pub fn share(&self, diode: Arm, state: Arm) -> f64 {
        let det: f64 = self
            .detected_w
            .iter()
            .map(|d| d[diode.index()][state.index()])
            .sum();
        let refl: f64 = self.reflected_w.iter().sum();
        if refl > 0.0 { det / refl } else { 0.0 }
    }

    /// The same in bin `b` (NaN where no light reached the pattern).
    pub fn share_in(&self, b: usize, diode: Arm, state: Arm) -> f64 {
        let refl = self.reflected_w[b];
        if refl > 0.0 {
            self.detected_w[b][diode.index()][state.index()] / refl
        } else {
            f64::NAN
        }
    }
}

/// One batch's recorder.
struct Binned {
    band: (f64, f64),
    bins: usize,
    bin: usize,
    incident: Vec<f64>,
    detected: Vec<[[f64; 2]; 2]>,
}

impl Recorder for Binned {
    #[inline(always)]
    fn segment(&mut self, _: glam::DVec3, _: glam::DVec3, _: f64) {}
    #[inline(always)]
    fn ray_done(&mut self, _: &BatchTally) {}
    fn wavelength(&mut self, wl: f64) {
        let f = (wl - self.band.0) / (self.band.1 - self.band.0);
        self.bin = ((f * self.bins as f64).floor().max(0.0) as usize).min(self.bins - 1);
    }
    fn incident(&mut self, _unit: usize, _pixel: u32, w: f64) {
        self.incident[self.bin] += w;
    }
    fn detected(&mut self, hit: Detection) {
        let s = match branch_state(hit.world) {
            Some(MirrorState::Plus) => 0,
            Some(MirrorState::Minus) => 1,
            _ => return,
        };
        self.detected[self.bin][hit.detector.index()][s] += hit.power_w;
    }
}

/// Wavelength bins of [`diffraction_pair`] (20 nm over the default band).
pub const PAIR_BINS: usize = 40;

/// The collection of the bench's reflected light with geometric mirrors and with its
/// diffractive model (what `spibench trace` reports on a diffractive bench), each from a
/// quarter of `rays` (at least 50 000): the shares are ratios of powers on the same rays, well
/// resolved by fewer rays. Returns the rays of each trace and the collections (geometric,
/// diffractive), binned into [`PAIR_BINS`] wavelength bins.
pub fn diffraction_pair(bench: &Bench, rays: u64, seed: u64) -> Result<(u64, [Collection; 2])> {
    let n = (rays / 4).max(50_000);
    let geometric = collection(&bench.with_geometric_dmd(), n, seed, PAIR_BINS)?;
    let diffractive = collection(bench, n, seed, PAIR_BINS)?;
    Ok((n, [geometric, diffractive]))
}

/// Traces `rays` lamp rays of `bench` (seed `seed`) and bins the collection into `bins`
/// wavelength bins of the traced band.
pub fn collection(bench: &Bench, rays: u64, seed: u64, bins: usize) -> Result<Collection> {
    if rays == 0 || bins == 0 {
        return Err(Error::field(
            "rays",
            "the collection needs at least one ray and one bin",
        ));
    }
    let Some(dmd) = bench.dmd() else {
        return Err(Error::field(
            "dmd",
            "the collection needs a bench with a DMD",
        ));
    };
    let band = bench.band();
    let n_batches = rays.div_ceil(RAYS_PER_BATCH);
    let inv = 1.0 / rays as f64;
    let mut incident = vec![0.0; bins];
    let mut detected = vec![[[0.0; 2]; 2]; bins];
    super::batches_in_order(
        n_batches,
        |b| {
            let n = RAYS_PER_BATCH.min(rays - b * RAYS_PER_BATCH);
            let mut rec = Binned {
                band,
                bins,
                bin: 0,
                incident: vec![0.0; bins],
                detected: vec![[[0.0; 2]; 2]; bins],
            };
            path::run_batch_recorded(bench, PatternMode::Branch, seed, b, n, inv, &mut rec);
            rec
        },
        |_, rec| {
            for (sum, v) in incident.iter_mut().zip(&rec.incident) {
                *sum += v;
            }
            for (sum, v) in detected.iter_mut().zip(&rec.detected) {
                for (row, vrow) in sum.iter_mut().zip(v) {
                    for (x, y) in row.iter_mut().zip(vrow) {
                        *x += y;
                    }
                }
            }
        },
        |_| {},
    );
    let mut c = Collection {
        band_m: band,
        bins,
        incident_w: incident,
        reflected_w: vec![0.0; bins],
        detected_w: detected,
    };
    for b in 0..bins {
        let r = dmd.dmd.reflectance.at(c.wavelength_m(b)).clamp(0.0, 1.0);
        c.reflected_w[b] = c.incident_w[b] * r;
    }
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit-identical on one and two threads, and with geometric mirrors nearly all of each arm's
    /// reflected light reaches its own diode on the paper bench (the arms are designed so), and
    /// little reaches the other.
    #[test]
    fn collection_is_deterministic_and_geometric_arms_collect() {
        // The shipped bench is diffractive: its geometric twin.
        let bench = crate::trace::testing::paper_bench_with_mask().with_geometric_dmd();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| collection(&bench, 20_000, 5, 16).unwrap())
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a, b);
        for arm in Arm::ALL {
            let own = a.share(arm, arm);
            assert!(own > 0.7 && own <= 1.0, "{arm:?}: {own}");
            assert!(a.share(arm.other(), arm) < 0.05);
        }
    }
}
