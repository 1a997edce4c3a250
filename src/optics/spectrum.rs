//! Spectral quantities: tabulated spectra, Planck's law, tungsten emissivity, and the default
//! tables of the bench (silicon responsivity, metal reflectances, absorptive ND glass).
//!
//! Wavelengths are in metres inside spibench; tables are written in nanometres (the unit of every
//! datasheet) and converted once when a [`Spectrum`] is built.

/// A quantity that depends on wavelength: a constant or a table interpolated linearly.
///
/// Outside a table's range the end values are held (no extrapolation): every table used by the
/// bench covers the traced band, and holding the end value is the conservative choice for
/// reflectances and responsivities.
#[derive(Debug, Clone, PartialEq)]
pub enum Spectrum {
    Constant(f64),
    Table(Table),
}

/// A table of (wavelength, value) with strictly increasing wavelengths in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    wavelength_m: Vec<f64>,
    value: Vec<f64>,
}

impl Table {
    /// Builds a table from (wavelength in nm, value) pairs. Fails (with a message for the caller
    /// to attach to a field) if there are no points, a value is not finite, or the wavelengths are
    /// not strictly increasing.
    pub fn from_nm(points: &[(f64, f64)]) -> Result<Table, String> {
        if points.is_empty() {
            return Err("a spectral table needs at least one (wavelength_nm, value) point".into());
        }
        for (i, &(wl, v)) in points.iter().enumerate() {
            if !(wl.is_finite() && wl > 0.0) {
                return Err(format!(
                    "point {i}: wavelength {wl} nm is not a positive number"
                ));
            }
            if !v.is_finite() {
                return Err(format!("point {i}: value {v} is not finite"));
            }
            if i > 0 && wl <= points[i - 1].0 {
                return Err(format!(
                    "wavelengths must be strictly increasing: point {i} ({wl} nm) follows {} nm",
                    points[i - 1].0
                ));
            }
        }
        Ok(Table {
            wavelength_m: points.iter().map(|p| p.0 * 1e-9).collect(),
            value: points.iter().map(|p| p.1).collect(),
        })
    }

    pub fn min_value(&self) -> f64 {
        self.value.iter().copied().fold(f64::INFINITY, f64::min)
    }

    pub fn max_value(&self) -> f64 {
        self.value.iter().copied().fold(f64::NEG_INFINITY, f64::max)
    }

    /// Linear interpolation, holding the end values outside the table.
    #[inline]
    pub fn at(&self, wavelength_m: f64) -> f64 {
        let x = &self.wavelength_m;
        let n = x.len();
        if wavelength_m <= x[0] {
            return self.value[0];
        }
        if wavelength_m >= x[n - 1] {
            return self.value[n - 1];
        }
        // First index with x[i] > wavelength; 1 <= i <= n-1 here.
        let i = x.partition_point(|&v| v <= wavelength_m);
        let (x0, x1) = (x[i - 1], x[i]);
        let (y0, y1) = (self.value[i - 1], self.value[i]);
        y0 + (y1 - y0) * (wavelength_m - x0) / (x1 - x0)
    }

    /// The same table with every value multiplied by `factor`.
    pub fn scaled(&self, factor: f64) -> Table {
        Table {
            wavelength_m: self.wavelength_m.clone(),
            value: self.value.iter().map(|v| v * factor).collect(),
        }
    }
}

impl Spectrum {
    #[inline]
    pub fn at(&self, wavelength_m: f64) -> f64 {
        match self {
            Spectrum::Constant(v) => *v,
            Spectrum::Table(t) => t.at(wavelength_m),
        }
    }

    pub fn min_value(&self) -> f64 {
        match self {
            Spectrum::Constant(v) => *v,
            Spectrum::Table(t) => t.min_value(),
        }
    }

    pub fn max_value(&self) -> f64 {
        match self {
            Spectrum::Constant(v) => *v,
            Spectrum::Table(t) => t.max_value(),
        }
    }

    /// A table spectrum from one of the static tables below (which are sorted by construction).
    pub fn from_static(points: &[(f64, f64)]) -> Spectrum {
        Spectrum::Table(Table::from_nm(points).expect("static tables are sorted and finite"))
    }

    pub fn scaled(&self, factor: f64) -> Spectrum {
        match self {
            Spectrum::Constant(v) => Spectrum::Constant(v * factor),
            Spectrum::Table(t) => Spectrum::Table(t.scaled(factor)),
        }
    }

    /// ∫ value dλ over [a, b] (metres) by composite Simpson's rule on `n` (even) intervals.
    pub fn integrate(&self, a: f64, b: f64, n: usize) -> f64 {
        integrate(|l| self.at(l), a, b, n)
    }
}

/// ∫ f over [a, b] by composite Simpson's rule with `n` intervals (rounded up to even).
pub fn integrate(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let n = n.max(2).next_multiple_of(2);
    let h = (b - a) / n as f64;
    let mut s = f(a) + f(b);
    for i in 1..n {
        let x = a + i as f64 * h;
        s += if i % 2 == 1 { 4.0 } else { 2.0 } * f(x);
    }
    s * h / 3.0
}

/// Planck's constant (J s), speed of light (m/s), Boltzmann's constant (J/K): exact SI values.
pub const PLANCK_H: f64 = 6.626_070_15e-34;
pub const LIGHT_C: f64 = 299_792_458.0;
pub const BOLTZMANN_K: f64 = 1.380_649e-23;

/// Blackbody spectral radiance B_λ(T) in W/(m² sr m) (Planck's law).
pub fn planck_radiance(wavelength_m: f64, temperature_k: f64) -> f64 {
    let c1 = 2.0 * PLANCK_H * LIGHT_C * LIGHT_C;
    let c2 = PLANCK_H * LIGHT_C / BOLTZMANN_K;
    c1 / wavelength_m.powi(5) / ((c2 / (wavelength_m * temperature_k)).exp_m1())
}

/// Spectral emissivity of tungsten, Larrabee's empirical fit (JOSA 49:619, 1959; docs/bench-facts.md
/// §3.2): ε = 0.4655 + 0.01558 λ + 0.2675e-4 T − 0.7305e-4 λ T with λ in µm and T in K.
///
/// The fit covers 0.4–0.8 µm and 1600–2800 K. Outside it is extrapolated linearly, which follows
/// the measured fall of ε into the near infrared (≈ 0.34 at 0.8–1 µm near the melting point,
/// docs/bench-facts.md §3.2) across the traced silicon band; the result is clamped to [0.05, 1] so that a
/// far extrapolation can never give a non-physical value.
pub fn tungsten_emissivity(wavelength_m: f64, temperature_k: f64) -> f64 {
    let l = wavelength_m * 1e6;
    let t = temperature_k;
    (0.4655 + 0.01558 * l + 0.2675e-4 * t - 0.7305e-4 * l * t).clamp(0.05, 1.0)
}

/// Typical Si-PIN responsivity (A/W) against wavelength (nm): docs/bench-facts.md §6 (confidence L,
/// a smooth QE model fitted to the FDS100, PDB210A and S1223 anchors).
pub const SILICON_PIN_RESPONSIVITY: [(f64, f64); 18] = [
    (350.0, 0.085),
    (400.0, 0.145),
    (450.0, 0.211),
    (500.0, 0.266),
    (550.0, 0.315),
    (600.0, 0.363),
    (650.0, 0.409),
    (700.0, 0.457),
    (750.0, 0.508),
    (800.0, 0.568),
    (850.0, 0.610),
    (900.0, 0.639),
    (950.0, 0.651),
    (980.0, 0.648),
    (1000.0, 0.613),
    (1050.0, 0.440),
    (1100.0, 0.160),
    (1150.0, 0.028),
];

/// Bare aluminium reflectance at normal incidence against wavelength (nm). Typical values with
/// the interband dip near 830 nm (docs/bench-facts.md §2.2 gives ~88–89 % in the visible and ~86–87 %
/// at 800–900 nm for DMD mirrors; confidence L). Used for DMD mirrors and aluminium folds.
pub const ALUMINIUM_REFLECTANCE: [(f64, f64); 12] = [
    (350.0, 0.920),
    (400.0, 0.920),
    (500.0, 0.916),
    (600.0, 0.908),
    (700.0, 0.896),
    (750.0, 0.884),
    (800.0, 0.868),
    (850.0, 0.866),
    (900.0, 0.880),
    (1000.0, 0.930),
    (1100.0, 0.950),
    (1150.0, 0.955),
];

/// Protected-silver mirror reflectance at 45° (nm → R): the usual catalogue curve of a 2″
/// protected-silver fold mirror, > 97.5 % from 450 nm into the infrared and falling in the
/// near UV (confidence L: read off typical vendor curves, not one part's data).
pub const PROTECTED_SILVER_REFLECTANCE: [(f64, f64); 8] = [
    (350.0, 0.80),
    (400.0, 0.92),
    (450.0, 0.965),
    (500.0, 0.975),
    (600.0, 0.978),
    (800.0, 0.980),
    (1000.0, 0.982),
    (1150.0, 0.983),
];

/// Shape of the optical density of Schott NG absorptive glass relative to its value at 546 nm
/// (nm → OD/OD₅₄₆). Flat from 450 to 650 nm and falling in the near infrared (~0.85 at 750,
/// ~0.7 at 850, ~0.6 at 1000 nm), docs/bench-facts.md §4 (confidence L, read from the general shape of
/// NG4/NG9 curves); the UV end rises as NG glasses absorb more there, the far end continues the
/// infrared fall gently.
pub const NG_GLASS_RELATIVE_OD: [(f64, f64); 11] = [
    (350.0, 1.30),
    (400.0, 1.08),
    (450.0, 1.00),
    (546.0, 1.00),
    (650.0, 1.00),
    (750.0, 0.85),
    (850.0, 0.70),
    (950.0, 0.63),
    (1000.0, 0.60),
    (1100.0, 0.56),
    (1150.0, 0.55),
];

/// Estimated per-surface reflectance of a DMD window with a visible broadband AR coating
/// (nm → R at normal incidence): ≤ 0.5 % across 420–680 nm as specified, rising outside the
/// design band as single- and few-layer visible AR designs do (docs/bench-facts.md §2.2: "not specified in
/// the NIR, where reflectance rises"; the NIR values are estimates, confidence L).
pub const DMD_WINDOW_VIS_AR_REFLECTANCE: [(f64, f64); 10] = [
    (350.0, 0.030),
    (400.0, 0.008),
    (420.0, 0.005),
    (550.0, 0.003),
    (680.0, 0.005),
    (750.0, 0.010),
    (850.0, 0.020),
    (950.0, 0.032),
    (1050.0, 0.042),
    (1150.0, 0.050),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_interpolates_and_holds_ends() {
        let t = Table::from_nm(&[(400.0, 1.0), (500.0, 3.0)]).unwrap();
        assert_eq!(t.at(300e-9), 1.0);
        assert_eq!(t.at(600e-9), 3.0);
        assert!((t.at(450e-9) - 2.0).abs() < 1e-12);
        assert!(Table::from_nm(&[(500.0, 1.0), (400.0, 1.0)]).is_err());
        assert!(Table::from_nm(&[(500.0, 1.0), (500.0, 1.0)]).is_err());
        assert!(Table::from_nm(&[]).is_err());
    }

    #[test]
    fn planck_matches_bench_facts_ratios() {
        // docs/bench-facts.md §3.3: B(500 nm)/B(1000 nm) = 0.185 at 2796 K and 0.262 at 3000 K,
        // B(1100)/B(1000) = 0.995 at 2796 K. Three significant figures are quoted.
        let r = |l: f64, t: f64| planck_radiance(l * 1e-9, t) / planck_radiance(1000e-9, t);
        assert!((r(500.0, 2796.0) - 0.185).abs() < 0.0006);
        assert!((r(500.0, 3000.0) - 0.262).abs() < 0.0006);
        assert!((r(1100.0, 2796.0) - 0.995).abs() < 0.0006);
        // Stefan–Boltzmann: π ∫ B dλ = σ T⁴ (σ = 5.670374e-8 W m⁻² K⁻⁴); integrate far enough.
        let t = 3000.0;
        let total =
            std::f64::consts::PI * integrate(|l| planck_radiance(l, t), 50e-9, 200e-6, 400_000);
        let sigma_t4 = 5.670_374_419e-8 * t.powi(4);
        assert!(
            (total / sigma_t4 - 1.0).abs() < 1e-4,
            "{}",
            total / sigma_t4
        );
    }

    #[test]
    fn larrabee_fit_matches_tabulated_values() {
        // docs/bench-facts.md §3.2 computed values at 2800 K: 0.465 (0.4 µm), 0.427 (0.6), 0.389 (0.8).
        assert!((tungsten_emissivity(400e-9, 2800.0) - 0.465).abs() < 6e-4);
        assert!((tungsten_emissivity(600e-9, 2800.0) - 0.427).abs() < 6e-4);
        assert!((tungsten_emissivity(800e-9, 2800.0) - 0.389).abs() < 6e-4);
    }

    #[test]
    fn responsivity_anchors() {
        let r = Spectrum::from_static(&SILICON_PIN_RESPONSIVITY);
        // ≈ 0.565 A/W at 795 nm (PDB210A anchor 0.57), peak 0.65 near 950–980 nm.
        assert!((r.at(795e-9) - 0.563).abs() < 0.005);
        assert!((r.max_value() - 0.651).abs() < 1e-12);
    }
}
