//! The balanced amplified photodetector (Thorlabs PDB210A/M class, docs/bench-facts.md §1.1).
//!
//! Two silicon diodes feed three outputs (Thorlabs PDB2xx manual, docs/bench-facts.md §1.1, H):
//!
//! ```text
//! RF OUTPUT:  V_rf = G_rf·(I₊ − I₋) + V₀,rf     clipped at ±swing_rf
//! MONITOR+:   V₊   = G₊·I₊ + V₀,₊               clipped at ±swing₊
//! MONITOR−:   V₋   = G₋·I₋ + V₀,₋               clipped at ±swing₋
//! ```
//!
//! with I_d = s_d·(light_d + ambient_d) + dark_d the total current of diode d: the traced light
//! (already weighted by the diode's spectral responsivity table), the ambient current, both
//! scaled by the device's flat responsivity mismatch s_d, and the dark current. Each output is a
//! one-pole low-pass of bandwidth B (−3 dB) whose noise is the shot noise of the diodes it sees,
//! S = 2qI (A²/Hz, one-sided; Schottky), plus its amplifier's input current noise i_n² (A²/Hz),
//! integrated over the one-pole noise bandwidth π·B/2. All values are SI.

use serde::Serialize;

/// The elementary charge (C), exact in the 2019 SI.
pub const ELEMENTARY_CHARGE_C: f64 = 1.602_176_634e-19;

/// Index of the RF output in every `[_; 3]` of this module.
pub const RF: usize = 0;
/// Index of MONITOR+.
pub const MONITOR_PLUS: usize = 1;
/// Index of MONITOR−.
pub const MONITOR_MINUS: usize = 2;

/// Output names in index order.
pub const OUTPUT_NAMES: [&str; 3] = ["rf", "monitor_plus", "monitor_minus"];

/// The load on the outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Load {
    HighImpedance,
    FiftyOhm,
}

/// One output stage at the chosen load.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OutputStage {
    /// Transimpedance (V/A).
    pub gain_v_per_a: f64,
    /// The output is clipped to [−swing, +swing] (V).
    pub swing_v: f64,
    /// Output with no current (V).
    pub offset_v: f64,
    /// −3 dB bandwidth of the single pole (Hz).
    pub bandwidth_hz: f64,
    /// Amplifier input current noise density (A/√Hz).
    pub input_noise_a_per_rthz: f64,
}

impl OutputStage {
    /// The noise-free, unclipped output for an input current (V).
    pub fn ideal_v(&self, current_a: f64) -> f64 {
        self.gain_v_per_a * current_a + self.offset_v
    }

    /// Clips to the output swing.
    pub fn clip(&self, v: f64) -> f64 {
        v.clamp(-self.swing_v, self.swing_v)
    }

    /// Equivalent noise bandwidth of the single pole, π·B/2 (Hz).
    pub fn noise_bandwidth_hz(&self) -> f64 {
        std::f64::consts::FRAC_PI_2 * self.bandwidth_hz
    }

    /// The pole's decay per sample interval dt: a = exp(−2π·B·dt).
    pub fn pole_factor(&self, dt_s: f64) -> f64 {
        (-std::f64::consts::TAU * self.bandwidth_hz * dt_s).exp()
    }
}

/// The balanced detector.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bap {
    pub load: Load,
    pub rf: OutputStage,
    /// [MONITOR+, MONITOR−].
    pub monitors: [OutputStage; 2],
    /// Flat photocurrent scale of diode [+, −] on top of its responsivity table.
    pub responsivity_scale: [f64; 2],
    /// Whether the diodes' shot noise is simulated.
    pub shot_noise: bool,
}

impl Bap {
    /// The output stage with index [`RF`], [`MONITOR_PLUS`] or [`MONITOR_MINUS`].
    pub fn stage(&self, output: usize) -> &OutputStage {
        match output {
            RF => &self.rf,
            MONITOR_PLUS => &self.monitors[0],
            _ => &self.monitors[1],
        }
    }

    /// Total current of each diode (A): s_d·(light_d + ambient_d) + dark_d.
    pub fn diode_currents(
        &self,
        light_a: [f64; 2],
        ambient_a: [f64; 2],
        dark_a: [f64; 2],
    ) -> [f64; 2] {
        [0, 1].map(|d| self.responsivity_scale[d] * (light_a[d] + ambient_a[d]) + dark_a[d])
    }

    /// The current each output amplifies: [I₊ − I₋, I₊, I₋] (A).
    pub fn output_currents(i: [f64; 2]) -> [f64; 3] {
        [i[0] - i[1], i[0], i[1]]
    }

    /// The noise-free, unclipped outputs for diode currents `i` (V).
    pub fn ideal_outputs_v(&self, i: [f64; 2]) -> [f64; 3] {
        let c = Self::output_currents(i);
        [0, 1, 2].map(|o| self.stage(o).ideal_v(c[o]))
    }

    /// The noise-free outputs after clipping (V).
    pub fn outputs_v(&self, i: [f64; 2]) -> [f64; 3] {
        let v = self.ideal_outputs_v(i);
        [0, 1, 2].map(|o| self.stage(o).clip(v[o]))
    }

    /// Common-mode rejection of the RF output from the diodes' flat mismatch alone,
    /// 20·log₁₀(s̄ / |s₊ − s₋|) dB (∞ for identical diodes): the response to one input divided
    /// by the response to equal inputs on both (Thorlabs' definition, docs/bench-facts.md §1.2).
    pub fn cmrr_db(&self) -> f64 {
        let [a, b] = self.responsivity_scale;
        20.0 * (0.5 * (a + b) / (a - b).abs()).log10()
    }

    /// The optical power difference that drives the RF output to its swing at responsivity
    /// `responsivity_a_per_w`, ignoring the offset: the balanced-mode saturation power (W).
    pub fn rf_saturation_power_w(&self, responsivity_a_per_w: f64) -> f64 {
        self.rf.swing_v / (self.rf.gain_v_per_a * responsivity_a_per_w)
    }

    /// One-sided current noise density of each output's input (A²/Hz) for diode currents `i`:
    /// shot noise 2q·I of the diodes it sees (when enabled) plus the amplifier's i_n².
    pub fn input_noise_psd(&self, i: [f64; 2]) -> [f64; 3] {
        let shot = if self.shot_noise {
            [0, 1].map(|d| 2.0 * ELEMENTARY_CHARGE_C * i[d].max(0.0))
        } else {
            [0.0; 2]
        };
        let amp = |o: usize| self.stage(o).input_noise_a_per_rthz.powi(2);
        [
            shot[0] + shot[1] + amp(RF),
            shot[0] + amp(MONITOR_PLUS),
            shot[1] + amp(MONITOR_MINUS),
        ]
    }

    /// Rms output noise of each output for steady diode currents `i` (V): G·√(S·πB/2).
    pub fn output_noise_v_rms(&self, i: [f64; 2]) -> [f64; 3] {
        let s = self.input_noise_psd(i);
        [0, 1, 2].map(|o| {
            let st = self.stage(o);
            st.gain_v_per_a * (s[o] * st.noise_bandwidth_hz()).sqrt()
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub fn stage(gain: f64, swing: f64, offset: f64) -> OutputStage {
        OutputStage {
            gain_v_per_a: gain,
            swing_v: swing,
            offset_v: offset,
            bandwidth_hz: 1e6,
            input_noise_a_per_rthz: 2.3e-12,
        }
    }

    pub fn bap() -> Bap {
        Bap {
            load: Load::HighImpedance,
            rf: stage(350e3, 10.0, 2e-3),
            monitors: [stage(17.5e3, 10.0, 1e-3), stage(17.5e3, 10.0, 1e-3)],
            responsivity_scale: [1.0, 0.97],
            shot_noise: true,
        }
    }

    #[test]
    fn outputs_follow_the_manual_law() {
        let b = bap();
        let i = b.diode_currents([1e-6, 0.8e-6], [1e-11, 2e-11], [1.5e-9, 1.8e-9]);
        assert!((i[0] - (1e-6 + 1e-11 + 1.5e-9)).abs() < 1e-20);
        assert!((i[1] - (0.97 * (0.8e-6 + 2e-11) + 1.8e-9)).abs() < 1e-20);
        let v = b.ideal_outputs_v(i);
        assert!((v[RF] - (350e3 * (i[0] - i[1]) + 2e-3)).abs() < 1e-15);
        assert!((v[MONITOR_PLUS] - (17.5e3 * i[0] + 1e-3)).abs() < 1e-15);
        assert!((v[MONITOR_MINUS] - (17.5e3 * i[1] + 1e-3)).abs() < 1e-15);
        // Clipping at the swing, both signs.
        let big = b.outputs_v([1e-3, 0.0]);
        assert_eq!(big[RF], 10.0);
        let neg = b.outputs_v([0.0, 1e-3]);
        assert_eq!(neg[RF], -10.0);
    }

    #[test]
    fn cmrr_and_saturation_power() {
        let b = bap();
        // 0.985 / 0.03 = 32.83 → 30.33 dB.
        assert!((b.cmrr_db() - 20.0 * (0.985f64 / 0.03).log10()).abs() < 1e-12);
        // 10 V / (350 kV/A · 0.62 A/W) = 46.1 µW (docs/bench-facts.md §1.1's estimate).
        assert!((b.rf_saturation_power_w(0.62) - 46.08e-6).abs() < 0.01e-6);
        let mut same = b.clone();
        same.responsivity_scale = [1.0, 1.0];
        assert!(same.cmrr_db().is_infinite());
    }

    #[test]
    fn noise_matches_the_bench_facts_estimate() {
        // Dark inputs: the RF output noise is G·i_n·√(πB/2) = 350e3 · 2.3e-12 · √(1.571e6)
        // = 1.009 mV rms, the "~1 mV rms" of docs/bench-facts.md §1.1.
        let mut b = bap();
        b.shot_noise = false;
        let n = b.output_noise_v_rms([0.0, 0.0]);
        assert!(
            (n[RF] - 350e3 * 2.3e-12 * (std::f64::consts::FRAC_PI_2 * 1e6).sqrt()).abs() < 1e-12
        );
        assert!((n[RF] - 1.009e-3).abs() < 1e-5);
        // Shot noise of 1 µA: 2qI = 3.2e-25 A²/Hz adds to both RF and MONITOR+.
        b.shot_noise = true;
        let s = b.input_noise_psd([1e-6, 0.0]);
        let shot = 2.0 * ELEMENTARY_CHARGE_C * 1e-6;
        assert!((s[RF] - (shot + 2.3e-12f64.powi(2))).abs() < 1e-36);
        assert!((s[MONITOR_PLUS] - (shot + 2.3e-12f64.powi(2))).abs() < 1e-36);
        assert!((s[MONITOR_MINUS] - 2.3e-12f64.powi(2)).abs() < 1e-36);
    }
}
