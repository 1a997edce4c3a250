//! The settle-window rule: which samples of an oscilloscope record make a frame's value, and
//! the value itself. Both the simulated record ([`super::record`]) and the intake of a measured
//! record (crate::intake) cut frames through this module, so the two cannot drift apart.
//!
//! Frame f of a regular sequence starts at sample position f·P (P = T·fs samples per frame,
//! not necessarily whole); sample n belongs to frame ⌊(n + ε)/P⌋ and is *settled* when it lies
//! at least S = t_settle·fs samples after its frame's start, (n − start) + ε ≥ S. A frame's
//! value is the mean of its settled samples, summed in time order. ε ([`BOUNDARY_EPS`]) keeps
//! a sample that falls exactly on a boundary where exact arithmetic puts it.

use super::record::FrameTiming;

/// Tolerance, in samples, of the frame and settling boundaries: a sample that falls exactly on
/// a boundary (440 samples per 44 µs frame) is not moved by the rounding of t/T.
pub const BOUNDARY_EPS: f64 = 1e-6;

/// The settle-window rule of one sampling: samples per frame and settling samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettleRule {
    /// P = frame time × sample rate.
    pub per_frame: f64,
    /// S = settling time × sample rate.
    pub settle: f64,
}

impl SettleRule {
    /// The rule of a sequence's timing.
    pub fn of(timing: FrameTiming) -> SettleRule {
        SettleRule {
            per_frame: timing.frame_s * timing.sample_rate_hz,
            settle: timing.settling_s * timing.sample_rate_hz,
        }
    }

    /// The frame of sample `n` (counted from the start of frame 0) on the regular grid, at most
    /// `n_frames − 1` (the last frame keeps any trailing sample).
    #[inline(always)]
    pub fn frame_of(&self, n: u64, n_frames: usize) -> usize {
        (((n as f64 + BOUNDARY_EPS) / self.per_frame) as usize).min(n_frames.saturating_sub(1))
    }

    /// Where frame `f` of the regular grid starts (samples from the start of frame 0).
    #[inline(always)]
    pub fn grid_start(&self, f: usize) -> f64 {
        f as f64 * self.per_frame
    }

    /// Whether sample `n` is settled in a frame that starts at sample position `start`.
    #[inline(always)]
    pub fn settled(&self, n: u64, start: f64) -> bool {
        let in_frame = n as f64 - start;
        in_frame + BOUNDARY_EPS >= self.settle
    }

    /// The first sample of a frame that starts at sample position `start`.
    pub fn first_sample(start: f64) -> u64 {
        (start - BOUNDARY_EPS).ceil().max(0.0) as u64
    }
}

/// Running sums of each frame's settled samples over `K` channels: a frame's value is
/// [`FrameMeans::means`]'s sum in time order divided by the count (one sample at least).
#[derive(Debug, Clone)]
pub struct FrameMeans<const K: usize> {
    sums: Vec<[f64; K]>,
    counts: Vec<usize>,
}

impl<const K: usize> FrameMeans<K> {
    /// Sums for `n_frames` frames, all empty.
    pub fn new(n_frames: usize) -> FrameMeans<K> {
        FrameMeans {
            sums: vec![[0.0; K]; n_frames],
            counts: vec![0; n_frames],
        }
    }

    /// Adds channel `o`'s settled sample `v` to frame `f`.
    #[inline(always)]
    pub fn add(&mut self, f: usize, o: usize, v: f64) {
        self.sums[f][o] += v;
    }

    /// Counts one settled sample (all channels) of frame `f`.
    #[inline(always)]
    pub fn count(&mut self, f: usize) {
        self.counts[f] += 1;
    }

    /// Settled samples of each frame.
    pub fn counts(&self) -> &[usize] {
        &self.counts
    }

    /// Each frame's mean of its settled samples (an empty frame reads 0), and the counts.
    pub fn means(self) -> (Vec<[f64; K]>, Vec<usize>) {
        let mut sums = self.sums;
        for (fr, &c) in sums.iter_mut().zip(&self.counts) {
            let k = c.max(1) as f64;
            for v in fr.iter_mut() {
                *v /= k;
            }
        }
        (sums, self.counts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_sample_agrees_with_the_grid_membership() {
        // The first sample of each grid frame is the first n that frame_of assigns to it, for
        // whole and fractional samples per frame.
        for (frame_s, fs) in [
            (44e-6, 10e6),
            (1.0 / 22_727.0, 10e6),
            (1.0 / 9_523.0, 2.5e6),
        ] {
            let rule = SettleRule::of(FrameTiming {
                frame_s,
                settling_s: 13e-6,
                sample_rate_hz: fs,
            });
            let n_frames = 3000;
            let mut f_prev = 0;
            let end = (n_frames as f64 * rule.per_frame) as u64;
            for n in 0..end {
                let f = rule.frame_of(n, n_frames);
                if f != f_prev {
                    assert_eq!(f, f_prev + 1);
                    assert_eq!(SettleRule::first_sample(rule.grid_start(f)), n, "{f}");
                    f_prev = f;
                }
            }
        }
    }

    #[test]
    fn means_divide_in_order_and_empty_frames_read_zero() {
        let mut m = FrameMeans::<2>::new(2);
        for v in [0.1, 0.2, 0.3] {
            m.add(0, 0, v);
            m.add(0, 1, -v);
            m.count(0);
        }
        let (means, counts) = m.means();
        assert_eq!(counts, vec![3, 0]);
        assert_eq!(means[0][0], (0.1 + 0.2 + 0.3) / 3.0);
        assert_eq!(means[1], [0.0, 0.0]);
    }
}
