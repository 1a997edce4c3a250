//! Where a trace spends its work: the path segments (each one nearest-hit query of the BVH and
//! one interaction) before a ray reaches the DMD's pattern area and after it splits into its
//! two mirror-state branches. A bench change that moves only parts after the DMD could re-trace
//! only the light leaving the DMD (a stored ray bundle per unit and state); that pays in
//! proportion to the share of the work done after the DMD, which this measures.

use super::path::{Recorder, run_batch_recorded};
use super::{BatchTally, PatternMode, RAYS_PER_BATCH};
use crate::optics::Bench;
use glam::DVec3;

/// Segment counts of a trace.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SegmentSplit {
    /// Lamp rays traced.
    pub rays: u64,
    /// Rays that reached the pattern area (and split).
    pub arrived: u64,
    /// Segments of arriving rays up to their arrival on the pattern area.
    pub before_dmd: u64,
    /// Segments of arriving rays after it, both branches.
    pub after_dmd: u64,
    /// Segments of rays that never reached the pattern area (light stopped before the DMD,
    /// and light on the mirrors outside the pattern, which does not split).
    pub never_arrived: u64,
}

impl SegmentSplit {
    /// The share of all segments traced after the DMD.
    pub fn after_share(&self) -> f64 {
        self.after_dmd as f64 / (self.before_dmd + self.after_dmd + self.never_arrived) as f64
    }
}

#[derive(Default)]
struct Counter {
    split: SegmentSplit,
    ray: u64,
    arrived: bool,
}

impl Recorder for Counter {
    fn segment(&mut self, _: DVec3, _: DVec3, _: f64) {
        self.ray += 1;
    }
    fn ray_done(&mut self, _: &BatchTally) {
        let s = &mut self.split;
        s.rays += 1;
        if self.arrived {
            s.arrived += 1;
            s.after_dmd += self.ray;
        } else {
            s.never_arrived += self.ray;
        }
        self.ray = 0;
        self.arrived = false;
    }
    fn incident(&mut self, _unit: usize, _pixel: u32, _w: f64) {
        // The first booking of x_j is the arrival: the segments so far came before the DMD.
        if !self.arrived {
            self.arrived = true;
            self.split.before_dmd += self.ray;
            self.ray = 0;
        }
    }
}

/// Counts the segments of `rays` lamp rays of the ordinary trace (both mirror states at every
/// arrival), in one thread, batch by batch as `trace` draws them.
pub fn segment_split(bench: &Bench, rays: u64, seed: u64) -> SegmentSplit {
    let mut c = Counter::default();
    let batches = rays.div_ceil(RAYS_PER_BATCH);
    for b in 0..batches {
        let n = RAYS_PER_BATCH.min(rays - b * RAYS_PER_BATCH);
        run_batch_recorded(
            bench,
            PatternMode::Branch,
            seed,
            b,
            n,
            1.0 / rays as f64,
            &mut c,
        );
    }
    c.split
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every segment is counted once; every arriving ray has at least one segment in each
    /// branch after the DMD, and at least the lamp → … → DMD segments before it.
    #[test]
    fn segments_split_at_the_dmd() {
        let doc = crate::scene::doc::BenchDoc::read(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron"),
        )
        .unwrap();
        let bench = doc.build().unwrap();
        let s = segment_split(&bench, 3000, 1);
        assert_eq!(s.rays, 3000);
        assert!(s.arrived > 0 && s.arrived < s.rays, "{s:?}");
        assert!(s.after_dmd >= 2 * s.arrived, "{s:?}");
        assert!(s.before_dmd >= 2 * s.arrived, "{s:?}");
        let share = s.after_share();
        assert!(share > 0.0 && share < 1.0);
        // The same split for the same seed; batches are drawn as the trace draws them.
        assert_eq!(s, segment_split(&bench, 3000, 1));
    }
}
