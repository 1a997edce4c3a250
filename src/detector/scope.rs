//! The oscilloscope (Tektronix MSO64 class, docs/bench-facts.md §8): per channel a vertical range of
//! 10 divisions centred on an offset, input noise, and an ADC of `bits` over the range.
//!
//! Input noise at full bandwidth is max(floor, fraction·V/div) (rms); in High Res mode the
//! record is a boxcar-decimated stream whose noise bandwidth is 0.44 × the sample rate (docs/bench-facts.md
//! §8, Tektronix FAQ), so the noise shrinks by √(0.44·fs / analog bandwidth). A sample outside
//! the 10 divisions is over range: the ADC returns its end code and the sample is flagged.

use serde::Serialize;

/// How a channel's vertical range is set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ChannelRange {
    /// From the noise-free signal ([`auto_range`]).
    Auto,
    /// As given.
    Fixed { volts_per_div: f64, offset_v: f64 },
}

/// Input noise model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ScopeNoise {
    pub floor_v_rms: f64,
    pub fraction_of_div: f64,
    pub analog_bandwidth_hz: f64,
    pub high_res: bool,
}

/// The oscilloscope.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Scope {
    pub sample_rate_hz: f64,
    pub bits: u32,
    pub noise: ScopeNoise,
    /// [RF, MONITOR+, MONITOR−].
    pub channels: [ChannelRange; 3],
}

/// A channel with its range resolved.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Channel {
    pub volts_per_div: f64,
    pub offset_v: f64,
    /// Rms input noise added to every sample (V).
    pub noise_v_rms: f64,
    /// ADC step (V); 0 records the value unquantised.
    pub lsb_v: f64,
    /// ADC bits (0 when unquantised).
    pub bits: u32,
}

/// Divisions on the screen.
pub const DIVISIONS: f64 = 10.0;
/// Divisions the automatic range fills with the noise-free signal, leaving room for noise.
pub const AUTO_FILL_DIVISIONS: f64 = 8.0;
/// The smallest and largest volts/division of the instrument (1 mV/div at 50 Ω to 10 V/div at
/// 1 MΩ, docs/bench-facts.md §8, M/L).
pub const VOLTS_PER_DIV_RANGE: (f64, f64) = (1e-3, 10.0);

/// The smallest 1-2-5 volts/division (within [`VOLTS_PER_DIV_RANGE`]) that holds [lo, hi] in
/// [`AUTO_FILL_DIVISIONS`] divisions, and the offset that centres it.
pub fn auto_range(lo: f64, hi: f64) -> (f64, f64) {
    let span = (hi - lo).max(0.0);
    let need = span / AUTO_FILL_DIVISIONS;
    let mut vdiv = VOLTS_PER_DIV_RANGE.1;
    'search: for decade in -3..=1 {
        for m in [1.0, 2.0, 5.0] {
            let v = m * 10f64.powi(decade);
            if v >= VOLTS_PER_DIV_RANGE.0 && v <= VOLTS_PER_DIV_RANGE.1 && v >= need {
                vdiv = v;
                break 'search;
            }
        }
    }
    (vdiv, 0.5 * (lo + hi))
}

impl ScopeNoise {
    /// Rms noise of one recorded sample at `volts_per_div` and sample rate `fs` (V).
    pub fn v_rms(&self, volts_per_div: f64, fs: f64) -> f64 {
        let full = self.floor_v_rms.max(self.fraction_of_div * volts_per_div);
        if self.high_res {
            full * (0.44 * fs / self.analog_bandwidth_hz).min(1.0).sqrt()
        } else {
            full
        }
    }
}

impl Scope {
    /// Resolves channel `o` for a noise-free signal spanning [lo, hi]; `ideal` leaves out the
    /// input noise and the quantisation (the noise-free limit of a run).
    pub fn channel(&self, o: usize, lo: f64, hi: f64, ideal: bool) -> Channel {
        let (volts_per_div, offset_v) = match self.channels[o] {
            ChannelRange::Auto => auto_range(lo, hi),
            ChannelRange::Fixed {
                volts_per_div,
                offset_v,
            } => (volts_per_div, offset_v),
        };
        if ideal {
            return Channel {
                volts_per_div,
                offset_v,
                noise_v_rms: 0.0,
                lsb_v: 0.0,
                bits: 0,
            };
        }
        Channel {
            volts_per_div,
            offset_v,
            noise_v_rms: self.noise.v_rms(volts_per_div, self.sample_rate_hz),
            lsb_v: DIVISIONS * volts_per_div / 2f64.powi(self.bits as i32),
            bits: self.bits,
        }
    }
}

impl Channel {
    /// The voltage window [low, high] of the screen.
    pub fn window(&self) -> (f64, f64) {
        let half = 0.5 * DIVISIONS * self.volts_per_div;
        (self.offset_v - half, self.offset_v + half)
    }

    /// The recorded value of an input `v` (noise already added) and whether it was over range.
    /// Codes run from −2^(bits−1) to 2^(bits−1) − 1 around the offset.
    pub fn digitise(&self, v: f64) -> (f64, bool) {
        let (lo, hi) = self.window();
        let over = !(lo..=hi).contains(&v);
        if self.lsb_v == 0.0 {
            return (v.clamp(lo, hi), over);
        }
        let half = 2f64.powi(self.bits as i32 - 1);
        let code = ((v - self.offset_v) / self.lsb_v).round();
        let clamped = code.clamp(-half, half - 1.0);
        (
            self.offset_v + clamped * self.lsb_v,
            over || clamped != code,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scope() -> Scope {
        Scope {
            sample_rate_hz: 10e6,
            bits: 16,
            noise: ScopeNoise {
                floor_v_rms: 50e-6,
                fraction_of_div: 0.006,
                analog_bandwidth_hz: 4e9,
                high_res: true,
            },
            channels: [ChannelRange::Auto; 3],
        }
    }

    #[test]
    fn auto_range_picks_the_smallest_125_step() {
        // A 30 mV span needs 3.75 mV/div → 5 mV/div, centred.
        let (v, o) = auto_range(-0.04, -0.01);
        assert_eq!(v, 5e-3);
        assert!((o + 0.025).abs() < 1e-15);
        // 0.5 V span → 62.5 mV/div → 0.1 V/div.
        assert_eq!(auto_range(0.0, 0.5).0, 0.1);
        // A flat signal gets the most sensitive setting.
        assert_eq!(auto_range(0.3, 0.3).0, 1e-3);
        // A huge span saturates at 10 V/div.
        assert_eq!(auto_range(-1e3, 1e3).0, 10.0);
    }

    #[test]
    fn quantisation_and_over_range() {
        let s = scope();
        let c = s.channel(0, -0.04, -0.01, false);
        // 10 div × 5 mV / 2^16 = 0.763 µV.
        assert!((c.lsb_v - 0.05 / 65536.0).abs() < 1e-18);
        let (v, over) = c.digitise(-0.02);
        assert!(!over);
        assert!((v + 0.02).abs() <= 0.5 * c.lsb_v + 1e-18);
        // Beyond the top of the screen: the end code, flagged.
        let (v, over) = c.digitise(1.0);
        assert!(over);
        let (_, hi) = c.window();
        assert!(v <= hi && v > hi - 2.0 * c.lsb_v);
        // High Res noise: max(50 µV, 0.006·5 mV) · √(0.44·10e6 / 4e9) = 50 µV · 0.0332.
        let want = 50e-6 * (0.44f64 * 10e6 / 4e9).sqrt();
        assert!((c.noise_v_rms - want).abs() < 1e-15);
        // The ideal channel neither quantises nor adds noise.
        let ideal = s.channel(0, -0.04, -0.01, true);
        assert_eq!(ideal.digitise(-0.0123456789).0, -0.0123456789);
        assert_eq!(ideal.noise_v_rms, 0.0);
    }
}
