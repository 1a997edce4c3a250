//! Refractive indices: Sellmeier glasses by name, or a constant index.

/// A transparent medium's refractive index model.
#[derive(Debug, Clone, PartialEq)]
pub enum Glass {
    /// n²(λ) − 1 = Σᵢ Bᵢ λ² / (λ² − Cᵢ) with λ in µm and Cᵢ in µm².
    Sellmeier { b: [f64; 3], c_um2: [f64; 3] },
    /// A wavelength-independent index (air, or dispersion-free validation cases for Mitsuba).
    Constant(f64),
}

/// Air at the bench. The index of air (1.00027) is taken as 1: it changes every interface of the
/// bench by the same tiny amount and no result here depends on it at that level.
pub const AIR: Glass = Glass::Constant(1.0);

/// Schott N-BK7 (Schott optical glass catalogue; docs/bench-facts.md §7.1).
pub const N_BK7: Glass = Glass::Sellmeier {
    b: [1.039_612_12, 0.231_792_344, 1.010_469_45],
    c_um2: [0.006_000_698_67, 0.020_017_914_4, 103.560_653],
};

/// Schott N-SF11 (Schott optical glass catalogue).
pub const N_SF11: Glass = Glass::Sellmeier {
    b: [1.737_596_95, 0.313_747_346, 1.898_781_01],
    c_um2: [0.013_188_707, 0.062_306_814_2, 155.236_29],
};

/// Fused silica, I. H. Malitson, JOSA 55:1205 (1965): B = 0.6961663, 0.4079426, 0.8974794 and
/// resonance wavelengths 0.0684043, 0.1162414, 9.896161 µm (Cᵢ are their squares).
pub const FUSED_SILICA: Glass = Glass::Sellmeier {
    b: [0.696_166_3, 0.407_942_6, 0.897_479_4],
    c_um2: [
        0.068_404_3 * 0.068_404_3,
        0.116_241_4 * 0.116_241_4,
        9.896_161 * 9.896_161,
    ],
};

/// Magnesium fluoride, ordinary ray, M. J. Dodge, Appl. Opt. 23:1980 (1984): B = 0.48755108,
/// 0.39875031, 2.3120353; resonances 0.04338408, 0.09461442, 23.793604 µm. Used for
/// quarter-wave AR coatings (thin evaporated films are close to the ordinary index).
pub const MGF2: Glass = Glass::Sellmeier {
    b: [0.487_551_08, 0.398_750_31, 2.312_035_3],
    c_um2: [
        0.043_384_08 * 0.043_384_08,
        0.094_614_42 * 0.094_614_42,
        23.793_604 * 23.793_604,
    ],
};

/// The names accepted in scene files, for error messages.
pub const GLASS_NAMES: &str = "N-BK7, N-SF11, fused-silica, MgF2";

impl Glass {
    /// A catalogue glass by name (case-insensitive; `_` and spaces count as `-`).
    pub fn by_name(name: &str) -> Option<Glass> {
        let key: String = name
            .trim()
            .to_ascii_lowercase()
            .chars()
            .map(|c| if c == '_' || c == ' ' { '-' } else { c })
            .collect();
        match key.as_str() {
            "n-bk7" | "bk7" => Some(N_BK7),
            "n-sf11" | "sf11" => Some(N_SF11),
            "fused-silica" | "silica" | "f-silica" | "uvfs" => Some(FUSED_SILICA),
            "mgf2" => Some(MGF2),
            _ => None,
        }
    }

    /// Refractive index at a vacuum wavelength in metres.
    #[inline]
    pub fn index(&self, wavelength_m: f64) -> f64 {
        match self {
            Glass::Constant(n) => *n,
            Glass::Sellmeier { b, c_um2 } => {
                let l2 = (wavelength_m * 1e6).powi(2);
                let mut n2 = 1.0;
                for i in 0..3 {
                    n2 += b[i] * l2 / (l2 - c_um2[i]);
                }
                n2.sqrt()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalogue_check_values() {
        // docs/bench-facts.md §7.1 N-BK7 check values, quoted to 3 decimals (1.5308 appears as 1.530, so
        // some are truncated rather than rounded): allow one unit of the last decimal.
        for (nm, n) in [
            (400.0, 1.530),
            (500.0, 1.521),
            (600.0, 1.516),
            (800.0, 1.511),
            (1000.0, 1.508),
        ] {
            assert!((N_BK7.index(nm * 1e-9) - n).abs() < 1e-3, "{nm} nm");
        }
        // Catalogue n_d at 587.56 nm: N-BK7 1.51680, N-SF11 1.78472, fused silica 1.45846;
        // MgF2 ordinary 1.3777 at 589 nm. Given to 5 decimals, so 2e-5 covers rounding.
        let d = 587.56e-9;
        assert!((N_BK7.index(d) - 1.51680).abs() < 2e-5);
        assert!((N_SF11.index(d) - 1.78472).abs() < 2e-5);
        assert!((FUSED_SILICA.index(d) - 1.45846).abs() < 2e-5);
        assert!((MGF2.index(589.0e-9) - 1.3777).abs() < 2e-4);
        assert_eq!(Glass::by_name("n_bk7"), Some(N_BK7));
        assert_eq!(Glass::by_name("Fused Silica"), Some(FUSED_SILICA));
        assert_eq!(Glass::by_name("unobtainium"), None);
    }
}
