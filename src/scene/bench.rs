//! Bench files: the optical bench in RON, in millimetres and degrees, converted once into a
//! validated SI [`crate::optics::Bench`].
//!
//! **The bench frame.** One right-handed frame for every position and direction. Its origin is
//! the centre of the DMD's mirror array, +z is the array normal (toward the illumination), mirror
//! columns count along +x and rows along −y (row 0 at the top, +y), so per-unit maps read as
//! images of the array seen from the front. A bench without a DMD uses the same frame.
//!
//! **Directions** are written `Vector((x, y, z))` (any length, normalised on reading) or
//! `Polar(theta_deg: θ, phi_deg: φ)` = (sin θ cos φ, sin θ sin φ, cos θ): θ from +z, φ from +x
//! toward +y. The DMD's arms at ±24° in the 45° plane are `Polar(theta_deg: 24.0, phi_deg: -45.0)`
//! (arm +) and `Polar(theta_deg: 24.0, phi_deg: 135.0)` (arm −).
//!
//! **Validation.** Single values are checked while the file is read (a negative length, an empty
//! or unsorted table), so the error carries the line and column; relations between values (a
//! lens whose faces cross, overlapping elements, a pattern area outside the array) are checked
//! after reading and the error is located by looking the field up in the text. A `Bench` that
//! exists is valid.

use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::optics::bench::{
    AIR_MEDIUM, Assembly, Bench, BenchParts, ChartPlate, Coating, DmdSetup, GuideRequest,
    Interaction, LensError, Photodiode, Solid, ambient_responsivity,
};
use crate::optics::chart::ChartMask;
use crate::optics::dmd::{Dmd, MirrorState, PatternArea};
use crate::optics::geometry::{Frame, Geometry, Shape2D, sag};
use crate::optics::glass::{Glass, glass_names, name_key};
use crate::optics::lamp::{
    EmitterShape, FieldOutline, FieldTarget, Lamp, LampSpectrum, band_power_from_filament,
};
use crate::optics::mesh::Mesh;
use crate::optics::spectrum::{self, Spectrum, Table};
use crate::raster::Raster;

// ---------------------------------------------------------------------------------------------
// Checked scalar newtypes: validated while deserialising, so errors carry line and column.

/// A finite number > 0.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Positive(pub f64);

impl From<Positive> for f64 {
    fn from(v: Positive) -> f64 {
        v.0
    }
}

impl TryFrom<f64> for Positive {
    type Error = String;
    fn try_from(v: f64) -> std::result::Result<Self, String> {
        if v.is_finite() && v > 0.0 && v <= MAX_SCALAR {
            Ok(Positive(v))
        } else {
            Err(format!(
                "must be a positive number of at most {MAX_SCALAR:e}, got {v:e}"
            ))
        }
    }
}

/// A finite number ≥ 0.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct NonNegative(pub f64);

impl From<NonNegative> for f64 {
    fn from(v: NonNegative) -> f64 {
        v.0
    }
}

impl TryFrom<f64> for NonNegative {
    type Error = String;
    fn try_from(v: f64) -> std::result::Result<Self, String> {
        if v.is_finite() && (0.0..=MAX_SCALAR).contains(&v) {
            Ok(NonNegative(v))
        } else {
            Err(format!(
                "must be a non-negative number of at most {MAX_SCALAR:e}, got {v:e}"
            ))
        }
    }
}

/// The largest plain positive or non-negative number a bench may hold (gains, bandwidths,
/// noise densities): far above any real one, and far from overflowing in products.
pub const MAX_SCALAR: f64 = 1e15;

/// Declares a validated scalar newtype: finite and within `(lo, hi]`, with the unit in the
/// error message, so that a new field of that kind cannot forget its check.
macro_rules! bounded {
    ($(#[$m:meta])* $name:ident, $lo:expr, $hi:expr, $unit:expr) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
        #[serde(try_from = "f64", into = "f64")]
        pub struct $name(pub f64);

        impl From<$name> for f64 {
            fn from(v: $name) -> f64 {
                v.0
            }
        }

        impl TryFrom<f64> for $name {
            type Error = String;
            fn try_from(v: f64) -> std::result::Result<Self, String> {
                if v.is_finite() && v > $lo && v <= $hi {
                    Ok($name(v))
                } else {
                    Err(format!(
                        "must be a positive number (above {}) of at most {} {}, got {v:e}",
                        $lo, $hi, $unit
                    ))
                }
            }
        }
    };
}

bounded!(
    /// A length (mm) of a part: positive and at most [`MAX_POSITION_MM`] (100 m).
    LengthMm,
    0.0,
    MAX_POSITION_MM,
    "mm"
);

bounded!(
    /// An angle (degrees) that is a size (a cone half-angle, a mirror tilt): in (0, 180].
    AngleDeg,
    0.0,
    180.0,
    "degrees"
);

bounded!(
    /// A radiant power (W): positive and at most 1 MW (a lamp of a bench draws tens of watts).
    PowerW,
    0.0,
    1e6,
    "W"
);

/// A number in (0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct UnitFraction(pub f64);

impl From<UnitFraction> for f64 {
    fn from(v: UnitFraction) -> f64 {
        v.0
    }
}

impl TryFrom<f64> for UnitFraction {
    type Error = String;
    fn try_from(v: f64) -> std::result::Result<Self, String> {
        if v.is_finite() && v > 0.0 && v <= 1.0 {
            Ok(UnitFraction(v))
        } else {
            Err(format!("must be in (0, 1], got {v}"))
        }
    }
}

/// A table of (wavelength_nm, value) pairs with strictly increasing wavelengths.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "Vec<(f64, f64)>", into = "Vec<(f64, f64)>")]
pub struct TableNm(pub Vec<(f64, f64)>);

impl From<TableNm> for Vec<(f64, f64)> {
    fn from(v: TableNm) -> Vec<(f64, f64)> {
        v.0
    }
}

impl TryFrom<Vec<(f64, f64)>> for TableNm {
    type Error = String;
    fn try_from(v: Vec<(f64, f64)>) -> std::result::Result<Self, String> {
        Table::from_nm(&v)?;
        Ok(TableNm(v))
    }
}

// ---------------------------------------------------------------------------------------------
// Shared value types.

/// The largest optical density accepted (transmittance 1e-10: far beyond any filter or chrome).
pub const MAX_OD: f64 = 10.0;

/// The largest distance from the bench origin a position may have (mm): 100 m, far beyond any
/// table, yet small enough that every product of positions stays finite.
pub const MAX_POSITION_MM: f64 = 1e5;

/// A point or vector in the bench frame (mm), each component finite and within
/// ±[`MAX_POSITION_MM`], checked while reading so that the error carries the line.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "(f64, f64, f64)", into = "(f64, f64, f64)")]
pub struct Mm3(pub f64, pub f64, pub f64);

impl From<Mm3> for (f64, f64, f64) {
    fn from(v: Mm3) -> (f64, f64, f64) {
        (v.0, v.1, v.2)
    }
}

impl TryFrom<(f64, f64, f64)> for Mm3 {
    type Error = String;
    fn try_from(v: (f64, f64, f64)) -> std::result::Result<Self, String> {
        for c in [v.0, v.1, v.2] {
            if !(c.is_finite() && c.abs() <= MAX_POSITION_MM) {
                return Err(format!(
                    "components must be finite and within ±{MAX_POSITION_MM} mm, got {c:e}"
                ));
            }
        }
        Ok(Mm3(v.0, v.1, v.2))
    }
}

/// A colour temperature (K) of a thermal source: above 0 and at most 4000 K (tungsten melts at
/// 3695 K; a quartz-halogen filament runs at 2800–3400 K).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Temperature(pub f64);

impl From<Temperature> for f64 {
    fn from(v: Temperature) -> f64 {
        v.0
    }
}

impl TryFrom<f64> for Temperature {
    type Error = String;
    fn try_from(v: f64) -> std::result::Result<Self, String> {
        if v.is_finite() && v > 0.0 && v <= 4000.0 {
            Ok(Temperature(v))
        } else {
            Err(format!(
                "a filament temperature must lie in (0, 4000] K, got {v}"
            ))
        }
    }
}

/// An irradiance (W/m²) of ambient light: at least 0 and at most 2000 W/m² (direct sunlight is
/// about 1000 W/m²; a lit laboratory gives well under 10 W/m²).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Irradiance(pub f64);

impl From<Irradiance> for f64 {
    fn from(v: Irradiance) -> f64 {
        v.0
    }
}

impl TryFrom<f64> for Irradiance {
    type Error = String;
    fn try_from(v: f64) -> std::result::Result<Self, String> {
        if v.is_finite() && (0.0..=2000.0).contains(&v) {
            Ok(Irradiance(v))
        } else {
            Err(format!(
                "an ambient irradiance must lie in [0, 2000] W/m², got {v}"
            ))
        }
    }
}

/// A direction in the bench frame (see the module notes).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum Direction {
    /// Components (x, y, z), any non-zero length.
    Vector(Mm3),
    /// Polar angle `theta_deg` from +z and azimuth `phi_deg` from +x toward +y (degrees).
    Polar { theta_deg: f64, phi_deg: f64 },
}

impl Direction {
    pub fn to_unit(self) -> std::result::Result<DVec3, String> {
        let v = match self {
            Direction::Vector(Mm3(x, y, z)) => DVec3::new(x, y, z),
            Direction::Polar { theta_deg, phi_deg } => {
                let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
                DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
            }
        };
        // Scale by the largest component first, so that no square overflows or underflows.
        let m = v.abs().max_element();
        if !(m.is_finite() && m > 0.0) {
            return Err("a direction must be finite and non-zero".into());
        }
        let v = v / m;
        if v.length() < 1e-12 {
            return Err("a direction must be finite and non-zero".into());
        }
        Ok(v.normalize())
    }
}

/// A wavelength-dependent quantity.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum SpectrumSpec {
    /// The same value at every wavelength.
    Constant(f64),
    /// (wavelength_nm, value) pairs, strictly increasing in wavelength, interpolated linearly and
    /// held constant beyond the ends.
    Table(TableNm),
    /// Bare aluminium reflectance (DMD mirrors; docs/bench-facts.md §2.2, confidence L).
    Aluminium,
    /// Protected-silver mirror reflectance (catalogue fold mirrors; confidence L).
    ProtectedSilver,
    /// Typical Si-PIN responsivity in A/W (docs/bench-facts.md §6; confidence L).
    SiliconPin,
    /// Optical density of Schott NG absorptive glass with the given OD at 546 nm: the nominal
    /// value times the NG spectral shape (flat 450–650 nm, falling to ~0.6× at 1000 nm;
    /// docs/bench-facts.md §4, confidence L).
    NgGlass(f64),
    /// Per-surface reflectance of a visible-AR DMD window (≤ 0.5 % in 420–680 nm, rising in the
    /// NIR; docs/bench-facts.md §2.2, estimate).
    DmdWindowVisibleAr,
}

impl SpectrumSpec {
    fn build(&self) -> Spectrum {
        match self {
            SpectrumSpec::Constant(v) => Spectrum::Constant(*v),
            SpectrumSpec::Table(t) => {
                Spectrum::Table(Table::from_nm(&t.0).expect("validated while reading"))
            }
            SpectrumSpec::Aluminium => Spectrum::from_static(&spectrum::ALUMINIUM_REFLECTANCE),
            SpectrumSpec::ProtectedSilver => {
                Spectrum::from_static(&spectrum::PROTECTED_SILVER_REFLECTANCE)
            }
            SpectrumSpec::SiliconPin => Spectrum::from_static(&spectrum::SILICON_PIN_RESPONSIVITY),
            SpectrumSpec::NgGlass(od) => {
                Spectrum::from_static(&spectrum::NG_GLASS_RELATIVE_OD).scaled(*od)
            }
            SpectrumSpec::DmdWindowVisibleAr => {
                Spectrum::from_static(&spectrum::DMD_WINDOW_VIS_AR_REFLECTANCE)
            }
        }
    }
}

/// The treatment of a glass surface.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum CoatingSpec {
    /// Bare glass: Fresnel reflection (~4 % per surface at normal incidence for N-BK7).
    #[default]
    Uncoated,
    /// A single quarter-wave MgF2 layer for `design_nm` (thickness λ₀/(4 n_MgF2(λ₀))), its
    /// reflectance computed by the thin-film formula at every wavelength and angle.
    MgF2 { design_nm: f64 },
    /// A fixed per-surface reflectance R(λ) at any angle (T = 1 − R), e.g. a vendor AR curve.
    Reflectance(SpectrumSpec),
}

/// A planar outline.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum Outline {
    Round {
        diameter_mm: LengthMm,
    },
    Rect {
        width_mm: LengthMm,
        height_mm: LengthMm,
    },
}

impl Outline {
    fn shape(self) -> Shape2D {
        match self {
            Outline::Round { diameter_mm } => Shape2D::Disk {
                radius: 0.5e-3 * diameter_mm.0,
            },
            Outline::Rect {
                width_mm,
                height_mm,
            } => Shape2D::Rect {
                half_u: 0.5e-3 * width_mm.0,
                half_v: 0.5e-3 * height_mm.0,
            },
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The file.

/// A bench file (see the module notes for the frame and units).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BenchFile {
    /// Traced wavelength band [min, max] in nm. Default (350, 1150): the silicon-sensitive band;
    /// x_j and every power in the ledger are powers within this band.
    #[serde(default = "default_band")]
    pub band_nm: (f64, f64),
    /// Surface interactions after which a path is abandoned and booked as "path cap" (default
    /// 200; a real path here has fewer than 30).
    #[serde(default = "default_max_interactions")]
    pub max_interactions: u32,
    /// Glasses given by their Sellmeier coefficients, usable by name in any element's `glass`
    /// field beside the built-in catalogue (docs/glasses.md).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub glasses: Vec<GlassSpec>,
    /// The light source.
    pub lamp: LampSpec,
    /// Lenses, filters, apertures, mounts, mirrors and charts, in any order.
    #[serde(default)]
    pub elements: Vec<ElementSpec>,
    /// The DMD (at the bench origin). Omit for benches without one (test benches).
    #[serde(default)]
    pub dmd: Option<DmdSpec>,
    /// The two photodiodes of the balanced detector.
    pub detectors: DetectorsSpec,
    /// Detector electronics and oscilloscope for `spibench run` (crate::scene::run); defaults
    /// when absent. Not used by the trace.
    #[serde(default)]
    pub electronics: crate::scene::run::ElectronicsSpec,
    /// Run settings for `spibench run` (crate::scene::run); defaults when absent. Not used by
    /// the trace.
    #[serde(default)]
    pub run: crate::scene::run::RunSpec,
}

/// A glass of the bench file: n²(λ) − 1 = Σᵢ Bᵢλ²/(λ² − Cᵢ), λ in µm (the Sellmeier form of
/// the Schott data sheets; docs/glasses.md).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GlassSpec {
    /// The name `glass` fields use. It may not be a catalogue name or a number.
    pub name: String,
    /// B₁, B₂, B₃ (dimensionless).
    pub sellmeier_b: (NonNegative, NonNegative, NonNegative),
    /// C₁, C₂, C₃ in µm² (the squares of the resonance wavelengths).
    pub sellmeier_c_um2: (NonNegative, NonNegative, NonNegative),
}

/// Wavelengths at which a user glass's index is checked across the traced band.
const GLASS_CHECK_POINTS: usize = 64;

/// The largest index a user glass may have in the band: above germanium's (about 4.0 in the
/// infrared), so only a mistyped coefficient meets it.
const GLASS_MAX_INDEX: f64 = 4.5;

fn default_band() -> (f64, f64) {
    (350.0, 1150.0)
}

fn default_max_interactions() -> u32 {
    200
}

/// The lamp: a flat Lambertian filament and its spectrum and power.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LampSpec {
    /// Centre of the filament (mm).
    pub position_mm: Mm3,
    /// Filament normal = emission axis (toward the collimator).
    pub axis: Direction,
    /// Direction of the filament's width (projected onto its plane); default: the frame's
    /// default in-plane axis.
    #[serde(default)]
    pub x_axis: Option<Direction>,
    /// The emitting outline.
    pub filament: FilamentSpec,
    /// Spectral shape of the emission.
    pub spectrum: LampSpectrumSpec,
    /// Emitted power.
    pub power: LampPowerSpec,
    /// Which directions are traced; the power outside is booked to the lamp housing.
    pub emission: EmissionSpec,
    /// Optional importance sampling toward the part of the collimator that feeds the imaged
    /// field (unbiased for any choice; only the noise changes).
    #[serde(default)]
    pub field_sampling: Option<FieldSamplingSpec>,
}

/// The emitting area of the filament.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum FilamentSpec {
    Rect {
        width_mm: LengthMm,
        height_mm: LengthMm,
    },
    Disk {
        diameter_mm: LengthMm,
    },
}

/// The lamp's spectral shape.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum LampSpectrumSpec {
    /// Planck's law × the Larrabee tungsten emissivity at `temperature_k`.
    Tungsten { temperature_k: Temperature },
    /// Planck's law × a constant emissivity.
    Graybody {
        temperature_k: Temperature,
        emissivity: UnitFraction,
    },
    /// A relative spectral power table (any units).
    Table(TableNm),
}

/// How much power the filament emits.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum LampPowerSpec {
    /// Radiant power emitted in the traced band (W).
    InBand { watts: PowerW },
    /// Electrical power (W) times the in-band radiant efficiency (W radiated in the traced band
    /// per W electrical). A QTH lamp radiates ~85–90 % of its input; at 2800 K a blackbody puts
    /// 32 % of its radiation into 350–1150 nm (tungsten somewhat more, its emissivity falling in
    /// the infrared), so ≈ 0.3 for the default band (estimate, confidence L).
    Electrical {
        watts: PowerW,
        in_band_efficiency: UnitFraction,
    },
    /// From the filament's area and temperature: area·∫ε(λ)·π·B_λ(T) dλ over the band (thermal
    /// spectra only).
    FromFilament,
}

/// The traced emission cone.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum EmissionSpec {
    /// The whole hemisphere.
    Hemisphere,
    /// A cone of the given half-angle (degrees, 0–90) around the filament normal.
    Cone { half_angle_deg: AngleDeg },
    /// The smallest cone (plus 0.1°) that contains the named element as seen from every point of
    /// the filament: usually the collimator.
    Toward { element: String },
}

/// Importance sampling toward a target (disk or rectangle) perpendicular to the lamp axis.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FieldSamplingSpec {
    /// Centre of the target; the target lies in the plane through this point perpendicular to
    /// the lamp axis (mm).
    pub center_mm: Mm3,
    /// The target's outline; a rectangle's width runs along the lamp's `x_axis`.
    pub outline: Outline,
    /// Fraction of rays aimed at the target, in [0, 1).
    pub probability: f64,
    /// Optional: aim a share of those rays at the clear areas of a chart instead of uniformly
    /// over the target. The map from the target to the chart is fitted to design rays traced
    /// through the bench's optics (src/optics/guide.rs); unbiased for any share, it pays when
    /// the field is mostly chrome, as on a negative USAF chart.
    #[serde(default)]
    pub chart_guided: Option<ChartGuidedSpec>,
}

/// Chart-guided aiming within the field target.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ChartGuidedSpec {
    /// Name of the chart element.
    pub chart: String,
    /// Share of the target-aimed rays that aim at the chart's clear areas, in (0, 1].
    pub share: UnitFraction,
    /// The region of the chart whose clear areas are aimed at (width, height, mm), centred
    /// where the optics send light from the filament's centre through the target's centre:
    /// the field imaged onto the DMD's pattern area plus a margin.
    pub region_mm: (Positive, Positive),
}

/// One bench element.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum ElementSpec {
    /// A singlet lens of real spherical or flat surfaces.
    Lens {
        /// Unique name; the ledger key of the light it absorbs.
        name: String,
        /// Catalogue part number (informational).
        #[serde(default)]
        part: Option<String>,
        /// Vertex of the first surface (mm).
        position_mm: Mm3,
        /// Direction of light travel; the front surface is met first.
        axis: Direction,
        /// Front surface radius (mm): positive when its centre of curvature lies after it along
        /// `axis`; omitted or None = flat.
        #[serde(default)]
        front_radius_mm: Option<f64>,
        /// Back surface radius (mm), same sign rule (a plano-convex lens used curved side first
        /// has front +R and a flat back; used flat side first, a flat front and back −R).
        #[serde(default)]
        back_radius_mm: Option<f64>,
        /// Centre thickness (mm).
        thickness_mm: LengthMm,
        /// Mechanical diameter (mm).
        diameter_mm: LengthMm,
        /// Clear aperture (mm); the ring outside it is covered by the mount (black). Default =
        /// the diameter.
        #[serde(default)]
        clear_diameter_mm: Option<LengthMm>,
        /// Glass: a catalogue name (N-BK7, N-SF11, fused-silica, MgF2) or a constant index such
        /// as "1.5".
        glass: String,
        /// Coating of both surfaces.
        #[serde(default)]
        coating: CoatingSpec,
        /// Alignment error: rotations (degrees) about the lens's local x then y axes, about
        /// `position_mm`.
        #[serde(default)]
        tilt_deg: Option<(f64, f64)>,
    },
    /// A plane-parallel absorptive filter (ND glass).
    Filter {
        /// Unique name.
        name: String,
        /// Catalogue part number (informational).
        #[serde(default)]
        part: Option<String>,
        /// Centre of the first face (mm).
        position_mm: Mm3,
        /// Face normal, in the direction of light travel (the filter extends along it).
        axis: Direction,
        /// Direction of the outline's width for rectangles.
        #[serde(default)]
        x_axis: Option<Direction>,
        /// Outline.
        outline: Outline,
        /// Thickness (mm).
        thickness_mm: LengthMm,
        /// Substrate glass (name or constant index), for refraction and Fresnel reflection.
        glass: String,
        /// Internal optical density through the full thickness at normal incidence (excluding
        /// surface reflections, which are traced); a ray's bulk transmittance is 10^(−OD·L/t)
        /// for path length L.
        od: SpectrumSpec,
        /// Coating of both faces.
        #[serde(default)]
        coating: CoatingSpec,
        /// Alignment tilt (degrees) about local x then y.
        #[serde(default)]
        tilt_deg: Option<(f64, f64)>,
    },
    /// A black annular aperture (iris) in a plane.
    Aperture {
        /// Unique name.
        name: String,
        /// Centre (mm).
        position_mm: Mm3,
        /// Plane normal.
        axis: Direction,
        /// Hole diameter (mm).
        inner_diameter_mm: LengthMm,
        /// Outer diameter of the black annulus (mm).
        outer_diameter_mm: LengthMm,
    },
    /// A black tube (lens tube, lamp housing): the side of a cylinder, analytic (every lamp ray
    /// starts inside the lamp housing, where a faceted mesh is the slowest thing to trace).
    Tube {
        /// Unique name.
        name: String,
        /// Centre of the tube's start (mm).
        position_mm: Mm3,
        /// Tube axis (the tube runs from `position_mm` along it).
        axis: Direction,
        /// Inner diameter (mm).
        diameter_mm: LengthMm,
        /// Length (mm).
        length_mm: LengthMm,
    },
    /// A black plate with a circular hole (baffle, field stop) as a triangle mesh (obvhs).
    Baffle {
        /// Unique name.
        name: String,
        /// Centre of the hole (mm).
        position_mm: Mm3,
        /// Plate normal.
        axis: Direction,
        /// Direction of the plate's width.
        #[serde(default)]
        x_axis: Option<Direction>,
        /// Plate width and height (mm).
        width_mm: LengthMm,
        height_mm: LengthMm,
        /// Hole diameter (mm).
        hole_diameter_mm: LengthMm,
        /// Sides of the hole's polygon (default 64).
        #[serde(default = "default_segments")]
        segments: usize,
    },
    /// A flat front-surface mirror (black behind).
    Mirror {
        /// Unique name.
        name: String,
        /// Catalogue part number (informational).
        #[serde(default)]
        part: Option<String>,
        /// Centre of the reflecting face (mm).
        position_mm: Mm3,
        /// Normal of the reflecting face (pointing out of the mirror).
        normal: Direction,
        /// Direction of the outline's width.
        #[serde(default)]
        x_axis: Option<Direction>,
        /// Outline of the reflecting face.
        outline: Outline,
        /// Reflectance R(λ).
        reflectance: SpectrumSpec,
        /// Substrate thickness behind the face (mm; only used to detect overlaps). Default 6.
        #[serde(default = "default_mirror_thickness")]
        thickness_mm: LengthMm,
        /// Alignment tilt (degrees) about local x then y.
        #[serde(default)]
        tilt_deg: Option<(f64, f64)>,
    },
    /// A chart plate: chrome pattern on a glass substrate.
    Chart {
        /// Unique name.
        name: String,
        /// Catalogue part number (informational).
        #[serde(default)]
        part: Option<String>,
        /// Where the chart point `center_on` lies, on the chrome face (mm).
        position_mm: Mm3,
        /// Normal of the chrome face pointing into the substrate.
        normal: Direction,
        /// Direction of the chart's +x axis (projected onto its plane).
        #[serde(default)]
        x_axis: Option<Direction>,
        /// Plate width and height (mm).
        plate_mm: (Positive, Positive),
        /// Substrate thickness (mm).
        thickness_mm: LengthMm,
        /// Substrate glass.
        glass: String,
        /// What is printed.
        pattern: ChartPatternSpec,
        /// Which chart point sits at `position_mm`. Default: the plate centre.
        #[serde(default)]
        center_on: Option<CenterOnSpec>,
        /// Optical density of the chrome (default 3, docs/bench-facts.md §5.3).
        #[serde(default = "default_chrome_od")]
        chrome_od: SpectrumSpec,
        /// Reflectance of the chrome (default 0.1: low-reflectivity chrome, estimate).
        #[serde(default = "default_chrome_reflectance")]
        chrome_reflectance: SpectrumSpec,
        /// Alignment tilt (degrees) about local x then y.
        #[serde(default)]
        tilt_deg: Option<(f64, f64)>,
    },
}

impl ElementSpec {
    /// The element's unique `name`.
    pub fn name(&self) -> &str {
        match self {
            ElementSpec::Lens { name, .. }
            | ElementSpec::Filter { name, .. }
            | ElementSpec::Aperture { name, .. }
            | ElementSpec::Tube { name, .. }
            | ElementSpec::Baffle { name, .. }
            | ElementSpec::Mirror { name, .. }
            | ElementSpec::Chart { name, .. } => name,
        }
    }
}

fn default_segments() -> usize {
    64
}

fn default_mirror_thickness() -> LengthMm {
    LengthMm(6.0)
}

fn default_chrome_od() -> SpectrumSpec {
    SpectrumSpec::Constant(3.0)
}

fn default_chrome_reflectance() -> SpectrumSpec {
    SpectrumSpec::Constant(0.1)
}

/// What is printed on a chart.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum ChartPatternSpec {
    /// The 1951 USAF chart of groups `min_group..=max_group` (crate::objects::usaf), negative
    /// (clear bars in chrome, as the paper's Thorlabs R3L3S1N) unless `positive` is true.
    Usaf {
        min_group: i32,
        max_group: i32,
        #[serde(default)]
        positive: bool,
    },
    /// A PNG image as a transmittance mask (grey level / max = clear fraction), of the given
    /// physical size, centred on the plate centre; `path` is relative to the bench file.
    Image {
        path: String,
        width_mm: LengthMm,
        height_mm: LengthMm,
    },
    /// No chrome: a plain glass plate.
    Clear,
}

/// A chart point, in chart millimetres from the plate centre.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum CenterOnSpec {
    Point((f64, f64)),
    /// The centre of the bounding box of USAF elements `first..=last` of `group`.
    Elements {
        group: i32,
        first: u8,
        last: u8,
    },
}

/// The DMD (TI DLP7000 class by default values in the paper bench).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DmdSpec {
    /// Mirror columns (along +x).
    pub columns: usize,
    /// Mirror rows (along −y).
    pub rows: usize,
    /// Mirror pitch (µm).
    pub pitch_um: Positive,
    /// Mirror area / cell area (mirror side = pitch·√fill).
    pub fill_factor: UnitFraction,
    /// Landed tilt angle (degrees); state + is +tilt about the hinge axis.
    pub tilt_deg: AngleDeg,
    /// Hinge axis angle from +x toward +y (degrees); 45 = the mirror diagonal.
    #[serde(default = "default_hinge")]
    pub tilt_axis_deg: f64,
    /// Mirror reflectance (default aluminium).
    #[serde(default = "default_dmd_reflectance")]
    pub mirror_reflectance: SpectrumSpec,
    /// The protective window, if any.
    #[serde(default)]
    pub window: Option<WindowSpec>,
    /// The pattern area.
    pub pattern: PatternSpec,
    /// State of every mirror outside the pattern area.
    pub outside_state: StateSpec,
    /// Package outline around the array (mm): light landing on it outside the array is absorbed.
    pub package_mm: (Positive, Positive),
}

fn default_hinge() -> f64 {
    45.0
}

fn default_dmd_reflectance() -> SpectrumSpec {
    SpectrumSpec::Aluminium
}

/// The DMD window: a glass plate parallel to the array.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WindowSpec {
    /// Glass (name or constant index).
    pub glass: String,
    /// Thickness (mm).
    pub thickness_mm: LengthMm,
    /// Gap between the array plane and the window's inner face (mm).
    pub gap_mm: LengthMm,
    /// Clear window size (mm), centred on the array.
    pub size_mm: (Positive, Positive),
    /// Coating of both faces.
    #[serde(default)]
    pub coating: CoatingSpec,
}

/// The block of mirrors that carries the pattern.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PatternSpec {
    /// First mirror (column, row) of the area.
    pub origin: (usize, usize),
    /// Units across (columns) and down (rows).
    pub units_across: usize,
    pub units_down: usize,
    /// Mirrors per unit side (a unit is n × n mirrors).
    pub mirrors_per_unit: usize,
}

/// A mirror state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
pub enum StateSpec {
    /// +tilt (toward arm +).
    Plus,
    /// −tilt (toward arm −).
    Minus,
    /// Flat (unpowered).
    Flat,
}

/// The balanced detector's two photodiodes.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorsSpec {
    /// INPUT+ diode, collecting arm + (mirrors in state +).
    pub plus: PhotodiodeSpec,
    /// INPUT− diode, collecting arm −.
    pub minus: PhotodiodeSpec,
}

/// A photodiode.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PhotodiodeSpec {
    /// Centre of the active area (mm).
    pub position_mm: Mm3,
    /// The direction the active area faces (toward the incoming light).
    pub normal: Direction,
    /// Active-area diameter (mm).
    pub diameter_mm: LengthMm,
    /// Responsivity (A/W) against wavelength; default the typical Si-PIN table.
    #[serde(default = "default_responsivity")]
    pub responsivity: SpectrumSpec,
    /// Ambient (room) irradiance on the diode (W/m²). Converted to current with the diode area
    /// and the mean responsivity over 400–700 nm (room light is visible light).
    #[serde(default = "no_ambient")]
    pub ambient_w_per_m2: Irradiance,
    /// Dark current (A).
    #[serde(default = "zero")]
    pub dark_current_a: NonNegative,
    /// Outer diameter of the black front plate around the diode (mm); omit for none.
    #[serde(default)]
    pub housing_diameter_mm: Option<LengthMm>,
}

fn default_responsivity() -> SpectrumSpec {
    SpectrumSpec::SiliconPin
}

fn zero() -> NonNegative {
    NonNegative(0.0)
}

fn no_ambient() -> Irradiance {
    Irradiance(0.0)
}

// ---------------------------------------------------------------------------------------------
// Locating fields in the text for errors found after reading.

/// Finds fields in RON text by structure (comments and strings skipped) to give errors found
/// after deserialisation a line and column.
struct Locator<'a> {
    text: &'a str,
}

impl<'a> Locator<'a> {
    /// Byte range of the contents of the outermost struct.
    fn top(&self) -> Option<(usize, usize)> {
        let b = self.text.as_bytes();
        let mut i = 0;
        while i < b.len() {
            if let Some(next) = skip_trivia(b, i) {
                i = next;
                continue;
            }
            if b[i] == b'#' {
                // #![enable(...)] attribute
                while i < b.len() && b[i] != b']' {
                    i += 1;
                }
                i += 1;
                continue;
            }
            if b[i] == b'(' {
                let end = matching(b, i)?;
                return Some((i + 1, end));
            }
            i += 1;
        }
        None
    }

    /// The field `name` at depth 0 within `range`: (position of the name, value range).
    fn field(&self, range: (usize, usize), name: &str) -> Option<(usize, (usize, usize))> {
        let b = self.text.as_bytes();
        let mut i = range.0;
        let mut depth = 0i32;
        while i < range.1 {
            if let Some(next) = skip_trivia(b, i) {
                i = next;
                continue;
            }
            match b[i] {
                b'(' | b'[' | b'{' => depth += 1,
                b')' | b']' | b'}' => depth -= 1,
                c if depth == 0 && (c.is_ascii_alphabetic() || c == b'_') => {
                    let start = i;
                    while i < range.1 && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                        i += 1;
                    }
                    let mut j = i;
                    while j < range.1
                        && (b[j] == b' ' || b[j] == b'\t' || b[j] == b'\n' || b[j] == b'\r')
                    {
                        j += 1;
                    }
                    if &self.text[start..i] == name && j < range.1 && b[j] == b':' {
                        let vstart = j + 1;
                        let vend = value_end(b, vstart, range.1);
                        return Some((start, (vstart, vend)));
                    }
                    continue;
                }
                _ => {}
            }
            i += 1;
        }
        None
    }

    /// The contents of the first parenthesised group in a value range.
    fn inner(&self, range: (usize, usize)) -> Option<(usize, usize)> {
        let b = self.text.as_bytes();
        let mut i = range.0;
        while i < range.1 {
            if let Some(next) = skip_trivia(b, i) {
                i = next;
                continue;
            }
            if b[i] == b'(' {
                let end = matching(b, i)?;
                return Some((i + 1, end));
            }
            i += 1;
        }
        None
    }

    /// The contents of the entry of the top-level list `list` whose `name` is `name`.
    fn named(&self, list: &str, name: &str) -> Option<(usize, usize)> {
        let top = self.top()?;
        let (_, list) = self.field(top, list)?;
        let b = self.text.as_bytes();
        let mut i = list.0;
        while i < list.1 {
            if let Some(next) = skip_trivia(b, i) {
                i = next;
                continue;
            }
            if b[i] == b'(' {
                let end = matching(b, i)?;
                let inner = (i + 1, end);
                if let Some((_, v)) = self.field(inner, "name")
                    && self.text[v.0..v.1].trim().trim_matches('"') == name
                {
                    return Some(inner);
                }
                i = end + 1;
                continue;
            }
            i += 1;
        }
        None
    }

    /// Position of a field along a path of nested struct fields from the top level.
    fn path(&self, path: &[&str]) -> Option<usize> {
        let mut range = self.top()?;
        let mut pos = None;
        for (k, name) in path.iter().enumerate() {
            let (p, v) = self.field(range, name)?;
            pos = Some(p);
            if k + 1 < path.len() {
                range = self.inner(v)?;
            }
        }
        pos
    }

    /// Position of `field` in the entry of the top-level list `list` named `name` (the entry
    /// itself when it lacks the field).
    fn entry_field(&self, list: &str, name: &str, field: &str) -> Option<usize> {
        let range = self.named(list, name)?;
        self.field(range, field).map(|(p, _)| p).or(Some(range.0))
    }

    fn line_col(&self, pos: usize) -> (usize, usize) {
        let before = &self.text[..pos.min(self.text.len())];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        (line, col)
    }
}

/// Skips a comment or string starting at i, returning the index after it.
pub(super) fn skip_trivia(b: &[u8], i: usize) -> Option<usize> {
    if b[i] == b'/' && i + 1 < b.len() && b[i + 1] == b'/' {
        let mut j = i;
        while j < b.len() && b[j] != b'\n' {
            j += 1;
        }
        return Some(j);
    }
    if b[i] == b'/' && i + 1 < b.len() && b[i + 1] == b'*' {
        let mut depth = 0;
        let mut j = i;
        while j + 1 < b.len() {
            if b[j] == b'/' && b[j + 1] == b'*' {
                depth += 1;
                j += 2;
            } else if b[j] == b'*' && b[j + 1] == b'/' {
                depth -= 1;
                j += 2;
                if depth == 0 {
                    return Some(j);
                }
            } else {
                j += 1;
            }
        }
        return Some(b.len());
    }
    if b[i] == b'"' {
        let mut j = i + 1;
        while j < b.len() && b[j] != b'"' {
            if b[j] == b'\\' {
                j += 1;
            }
            j += 1;
        }
        return Some(j + 1);
    }
    None
}

fn matching(b: &[u8], open: usize) -> Option<usize> {
    let mut depth = 0i32;
    let mut i = open;
    while i < b.len() {
        if let Some(next) = skip_trivia(b, i) {
            i = next;
            continue;
        }
        match b[i] {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => {
                depth -= 1;
                if depth == 0 {
                    return Some(i);
                }
            }
            _ => {}
        }
        i += 1;
    }
    None
}

fn value_end(b: &[u8], start: usize, end: usize) -> usize {
    let mut depth = 0i32;
    let mut i = start;
    while i < end {
        if let Some(next) = skip_trivia(b, i) {
            i = next;
            continue;
        }
        match b[i] {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => depth -= 1,
            b',' if depth == 0 => return i,
            _ => {}
        }
        i += 1;
    }
    end
}

// ---------------------------------------------------------------------------------------------
// Conversion.

/// Reads and validates a bench file.
pub fn read_bench(path: &Path) -> Result<Bench> {
    let text = crate::scene::read_text(path)?;
    parse_bench(&text, path)
}

/// Parses and validates bench text; `path` names the file in errors and anchors relative image
/// paths.
pub fn parse_bench(text: &str, path: &Path) -> Result<Bench> {
    let file: BenchFile = crate::scene::parse_ron(text, path)?;
    build_bench(&file, Some(text), path)
}

/// Converts a parsed bench file into a validated bench. `text` is the file's source when there
/// is one: errors then carry the line and column of the field they name; a bench made in code
/// has none, and its errors name the field alone. `path` names the file in errors and anchors
/// relative image paths.
pub fn build_bench(file: &BenchFile, text: Option<&str>, path: &Path) -> Result<Bench> {
    Builder {
        ctx: Ctx {
            loc: text.map(|text| Locator { text }),
            path,
            glasses: Vec::new(),
        },
        parts: BenchParts::new(),
        solids: Vec::new(),
        throughput: Vec::new(),
    }
    .build(file)
}

/// The text (when the bench has one) and path, for locating errors, and the bench's own
/// glasses (checked first: see `Builder::user_glasses`).
struct Ctx<'a> {
    loc: Option<Locator<'a>>,
    path: &'a Path,
    glasses: Vec<(String, Glass)>,
}

struct Builder<'a> {
    ctx: Ctx<'a>,
    parts: BenchParts,
    /// (element name, solid) for overlap checks and the emission cone.
    solids: Vec<(String, Solid)>,
    /// Internal optical densities of the absorbing filters (for wavelength sampling).
    throughput: Vec<Spectrum>,
}

const RESERVED: [&str; 8] = [
    "lamp_housing",
    "dmd_mirrors",
    "dmd_gaps",
    "dmd_package",
    "dmd_window",
    "pd_plus",
    "pd_minus",
    "pd_housing",
];

fn mm(p: Mm3) -> DVec3 {
    DVec3::new(p.0, p.1, p.2) * 1e-3
}

impl Ctx<'_> {
    /// An error at a top-level path of fields.
    fn err_path(&self, path: &[&str], msg: impl Into<String>) -> Error {
        let mut e = Error::field(path.join("."), msg).in_file(self.path);
        if let Some(loc) = &self.loc
            && let Some(p) = loc.path(path)
        {
            let (l, c) = loc.line_col(p);
            e = e.at_line(l, c);
        }
        e
    }

    /// An error at a field of a named element.
    fn err_el(&self, element: &str, field: &str, msg: impl Into<String>) -> Error {
        self.err_entry(
            format!("elements[{element}]"),
            "elements",
            element,
            field,
            msg,
        )
    }

    /// An error at `field` of the entry named `name` of the top-level list `list`, reported
    /// under the path `label.field`.
    fn err_entry(
        &self,
        label: String,
        list: &str,
        name: &str,
        field: &str,
        msg: impl Into<String>,
    ) -> Error {
        let mut e = Error::field(format!("{label}.{field}"), msg).in_file(self.path);
        if let Some(loc) = &self.loc
            && let Some(p) = loc.entry_field(list, name, field)
        {
            let (l, c) = loc.line_col(p);
            e = e.at_line(l, c);
        }
        e
    }

    fn glass(&self, name: &str, err: impl Fn(String) -> Error) -> Result<Glass> {
        if let Some(g) = Glass::by_name(name) {
            return Ok(g);
        }
        let key = name_key(name);
        if let Some((_, g)) = self.glasses.iter().find(|(n, _)| name_key(n) == key) {
            return Ok(g.clone());
        }
        match name.trim().parse::<f64>() {
            Ok(n) if n.is_finite() && n >= 1.0 => Ok(Glass::Constant(n)),
            _ => {
                let own = if self.glasses.is_empty() {
                    String::new()
                } else {
                    let names: Vec<&str> = self.glasses.iter().map(|(n, _)| n.as_str()).collect();
                    format!(", this bench's glasses ({})", names.join(", "))
                };
                Err(err(format!(
                    "unknown glass `{name}`: use one of {}{own} or a constant index such as \"1.5\"",
                    glass_names()
                )))
            }
        }
    }

    /// An error at a field of the bench's glass number `index` (named `name`).
    fn err_glass(&self, index: usize, name: &str, field: &str, msg: impl Into<String>) -> Error {
        self.err_entry(format!("glasses[{index}]"), "glasses", name, field, msg)
    }

    fn coating(&self, c: &CoatingSpec, err: impl Fn(String) -> Error) -> Result<Coating> {
        Ok(match c {
            CoatingSpec::Uncoated => Coating::None,
            CoatingSpec::MgF2 { design_nm } => {
                if !(design_nm.is_finite() && *design_nm > 100.0 && *design_nm < 5000.0) {
                    return Err(err(format!(
                        "the AR design wavelength must be in (100, 5000) nm, got {design_nm}"
                    )));
                }
                Coating::quarter_wave_mgf2(design_nm * 1e-9)
            }
            CoatingSpec::Reflectance(s) => {
                let s = s.build();
                if !(s.min_value() >= 0.0 && s.max_value() <= 1.0) {
                    return Err(err("a reflectance must lie in [0, 1]".into()));
                }
                Coating::Reflectance(s)
            }
        })
    }

    fn fraction_spectrum(
        &self,
        s: &SpectrumSpec,
        err: impl Fn(String) -> Error,
    ) -> Result<Spectrum> {
        let s = s.build();
        if !(s.min_value() >= 0.0 && s.max_value() <= 1.0) {
            return Err(err("values must lie in [0, 1]".into()));
        }
        Ok(s)
    }

    fn frame(
        &self,
        origin: DVec3,
        w: Direction,
        x_axis: Option<Direction>,
        tilt: Option<(f64, f64)>,
        err: &dyn Fn(&str, String) -> Error,
    ) -> Result<Frame> {
        let w = w.to_unit().map_err(|m| err("axis", m))?;
        let u = match x_axis {
            Some(d) => Some(d.to_unit().map_err(|m| err("x_axis", m))?),
            None => None,
        };
        let mut f = Frame::new(origin, w, u);
        if let Some((a, b)) = tilt {
            if !(a.is_finite() && b.is_finite() && a.abs() < 90.0 && b.abs() < 90.0) {
                return Err(err("tilt_deg", "tilts must be finite and below 90°".into()));
            }
            f = f.tilted(a.to_radians(), b.to_radians());
        }
        Ok(f)
    }
}

impl Builder<'_> {
    /// The bench's own glasses, checked: a name that is neither a catalogue glass, nor a number,
    /// nor used twice; coefficients whose index is finite, at least 1 and below
    /// `GLASS_MAX_INDEX` across the traced band, with no resonance (λ² = Cᵢ) inside it.
    fn user_glasses(&self, file: &BenchFile, band_m: (f64, f64)) -> Result<Vec<(String, Glass)>> {
        let mut out: Vec<(String, Glass)> = Vec::new();
        for (i, g) in file.glasses.iter().enumerate() {
            let name = g.name.trim();
            let err = |field: &str, msg: String| self.ctx.err_glass(i, &g.name, field, msg);
            if name.is_empty() {
                return Err(err("name", "a glass needs a name".into()));
            }
            if let Some(c) = Glass::catalogue_entry(name) {
                return Err(err(
                    "name",
                    format!(
                        "`{name}` is the catalogue glass {}: give your glass another name (a \
                         bench's glass may not replace a catalogue one)",
                        c.name
                    ),
                ));
            }
            if name.parse::<f64>().is_ok() {
                return Err(err(
                    "name",
                    format!("`{name}` reads as a constant index: give the glass a name"),
                ));
            }
            if out.iter().any(|(n, _)| name_key(n) == name_key(name)) {
                return Err(err(
                    "name",
                    format!("the bench defines the glass `{name}` twice"),
                ));
            }
            let b = [g.sellmeier_b.0.0, g.sellmeier_b.1.0, g.sellmeier_b.2.0];
            let c = [
                g.sellmeier_c_um2.0.0,
                g.sellmeier_c_um2.1.0,
                g.sellmeier_c_um2.2.0,
            ];
            let (lo_um2, hi_um2) = ((band_m.0 * 1e6).powi(2), (band_m.1 * 1e6).powi(2));
            if let Some(k) = c.iter().position(|&ck| ck >= lo_um2 && ck <= hi_um2) {
                return Err(err(
                    "sellmeier_c_um2",
                    format!(
                        "C{} = {} µm² puts a resonance at {:.1} nm, inside the traced band \
                         ({:.0}–{:.0} nm): the index is infinite there",
                        k + 1,
                        c[k],
                        c[k].sqrt() * 1e3,
                        band_m.0 * 1e9,
                        band_m.1 * 1e9
                    ),
                ));
            }
            let glass = Glass::Sellmeier { b, c_um2: c };
            for k in 0..=GLASS_CHECK_POINTS {
                let l = band_m.0 + (band_m.1 - band_m.0) * k as f64 / GLASS_CHECK_POINTS as f64;
                let n = glass.index(l);
                if !(n.is_finite() && (1.0..=GLASS_MAX_INDEX).contains(&n)) {
                    return Err(err(
                        "sellmeier_b",
                        format!(
                            "these coefficients give n = {n} at {:.1} nm, inside the traced band: \
                             a glass needs 1 ≤ n ≤ {GLASS_MAX_INDEX} there (are the C in µm²?)",
                            l * 1e9
                        ),
                    ));
                }
            }
            out.push((name.to_string(), glass));
        }
        Ok(out)
    }

    fn build(mut self, file: &BenchFile) -> Result<Bench> {
        // Band.
        let (lo, hi) = file.band_nm;
        if !(lo.is_finite() && hi.is_finite() && lo > 100.0 && hi > lo && hi < 20_000.0) {
            return Err(self.ctx.err_path(
                &["band_nm"],
                format!("the band must satisfy 100 < min < max < 20000 nm, got ({lo}, {hi})"),
            ));
        }
        let band = (lo * 1e-9, hi * 1e-9);
        self.ctx.glasses = self.user_glasses(file, band)?;
        if file.max_interactions == 0 {
            return Err(self
                .ctx
                .err_path(&["max_interactions"], "must be at least 1"));
        }
        let lamp_housing = self.parts.element("lamp_housing");

        // Element names.
        let mut names: Vec<&str> = Vec::new();
        for el in &file.elements {
            let name = el.name();
            if name.trim().is_empty() {
                return Err(self
                    .ctx
                    .err_path(&["elements"], "every element needs a non-empty name"));
            }
            if RESERVED.contains(&name) || name.starts_with("pd_") || name.starts_with("dmd_") {
                return Err(self.ctx.err_el(
                    name,
                    "name",
                    format!("the name `{name}` is reserved for the bench's own ledger entries"),
                ));
            }
            if names.contains(&name) {
                return Err(self.ctx.err_el(
                    name,
                    "name",
                    format!("the name `{name}` is used twice"),
                ));
            }
            names.push(name);
        }
        for el in &file.elements {
            self.element(el)?;
        }
        let dmd = match &file.dmd {
            Some(d) => Some(self.dmd(d)?),
            None => None,
        };
        let detectors = [
            self.photodiode(&file.detectors.plus, 0)?,
            self.photodiode(&file.detectors.minus, 1)?,
        ];
        self.check_overlaps()?;
        let lamp = self.lamp(&file.lamp, band)?;
        let path = ["lamp", "field_sampling", "chart_guided"];
        let guide = match file
            .lamp
            .field_sampling
            .as_ref()
            .and_then(|f| f.chart_guided.as_ref())
        {
            None => None,
            Some(g) => {
                let id = self.parts.elements.iter().position(|e| *e == g.chart);
                let chart = id
                    .and_then(|id| {
                        self.parts
                            .surfaces
                            .iter()
                            .find_map(|s| match s.interaction {
                                Interaction::Chart { chart, .. } if s.element == id => Some(chart),
                                _ => None,
                            })
                    })
                    .ok_or_else(|| {
                        self.ctx
                            .err_path(&path, format!("no chart named `{}`", g.chart))
                    })?;
                Some(GuideRequest {
                    chart,
                    share: g.share.0,
                    region_m: (g.region_mm.0.0 * 1e-3, g.region_mm.1.0 * 1e-3),
                })
            }
        };
        Bench::assemble(Assembly {
            band,
            lamp,
            parts: self.parts,
            dmd,
            detectors,
            lamp_housing,
            max_interactions: file.max_interactions,
            filter_ods: self.throughput,
            guide,
        })
        .map_err(|m| self.ctx.err_path(&path, m))
    }

    fn element(&mut self, el: &ElementSpec) -> Result<()> {
        let name = el.name().to_string();
        let n = name.as_str();
        let id = self.parts.element(n);
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
        match el {
            ElementSpec::Lens {
                position_mm,
                axis,
                front_radius_mm,
                back_radius_mm,
                thickness_mm,
                diameter_mm,
                clear_diameter_mm,
                glass,
                coating,
                tilt_deg,
                ..
            } => {
                let frame = self
                    .ctx
                    .frame(mm(*position_mm), *axis, None, *tilt_deg, &e)?;
                let glass = self.ctx.glass(glass, |m| e("glass", m))?;
                let coating = self.ctx.coating(coating, |m| e("coating", m))?;
                let radius = 0.5e-3 * diameter_mm.0;
                let clear = clear_diameter_mm.map_or(radius, |c| 0.5e-3 * c.0);
                let r1 = front_radius_mm.map(|r| r * 1e-3);
                let r2 = back_radius_mm.map(|r| r * 1e-3);
                let t = thickness_mm.0 * 1e-3;
                self.parts
                    .lens(id, &frame, r1, r2, t, radius, clear, glass, coating)
                    .map_err(|le| match le {
                        LensError::Radius(0, m) => e("front_radius_mm", m),
                        LensError::Radius(_, m) => e("back_radius_mm", m),
                        LensError::Thickness(m) => e("thickness_mm", m),
                        LensError::Diameter(m) => {
                            if clear_diameter_mm.is_some() {
                                e("clear_diameter_mm", m)
                            } else {
                                e("diameter_mm", m)
                            }
                        }
                    })?;
                let z1 = r1.map_or(0.0, |r| sag(r, radius)).min(0.0);
                let z2 = (t + r2.map_or(0.0, |r| sag(r, radius))).max(t);
                let solid = Solid::Cylinder {
                    frame: Frame {
                        origin: frame.origin + z1 * frame.w,
                        ..frame
                    },
                    radius,
                    length: z2 - z1,
                };
                self.solids.push((name, solid));
            }
            ElementSpec::Filter {
                position_mm,
                axis,
                x_axis,
                outline,
                thickness_mm,
                glass,
                od,
                coating,
                tilt_deg,
                ..
            } => {
                let frame = self
                    .ctx
                    .frame(mm(*position_mm), *axis, *x_axis, *tilt_deg, &e)?;
                let glass = self.ctx.glass(glass, |m| e("glass", m))?;
                let coating = self.ctx.coating(coating, |m| e("coating", m))?;
                let od = od.build();
                if !(od.min_value() >= 0.0 && od.max_value() <= MAX_OD) {
                    return Err(e(
                        "od",
                        format!("an optical density must lie in [0, {MAX_OD}]"),
                    ));
                }
                let t = thickness_mm.0 * 1e-3;
                let per_m = od.scaled(1.0 / t);
                self.throughput.push(od);
                let m = self.parts.medium(glass, Some((per_m, id)));
                let shape = outline.shape();
                self.parts.slab(id, &frame, shape, t, m, coating);
                self.solids.push((name, solid_of(&frame, shape, t)));
            }
            ElementSpec::Aperture {
                position_mm,
                axis,
                inner_diameter_mm,
                outer_diameter_mm,
                ..
            } => {
                if outer_diameter_mm.0 <= inner_diameter_mm.0 {
                    return Err(e(
                        "outer_diameter_mm",
                        "the outer diameter must exceed the hole".into(),
                    ));
                }
                let frame = self.ctx.frame(mm(*position_mm), *axis, None, None, &e)?;
                self.parts.surface(
                    Geometry::Plane {
                        frame,
                        shape: Shape2D::Annulus {
                            inner: 0.5e-3 * inner_diameter_mm.0,
                            outer: 0.5e-3 * outer_diameter_mm.0,
                        },
                    },
                    Interaction::Absorber,
                    id,
                );
            }
            ElementSpec::Tube {
                position_mm,
                axis,
                diameter_mm,
                length_mm,
                ..
            } => {
                let frame = self.ctx.frame(mm(*position_mm), *axis, None, None, &e)?;
                self.parts.surface(
                    Geometry::Cylinder {
                        base: frame.origin,
                        axis: frame.w,
                        radius: 0.5e-3 * diameter_mm.0,
                        length: 1e-3 * length_mm.0,
                    },
                    Interaction::Absorber,
                    id,
                );
            }
            ElementSpec::Baffle {
                position_mm,
                axis,
                x_axis,
                width_mm,
                height_mm,
                hole_diameter_mm,
                segments,
                ..
            } => {
                if !(8..=4096).contains(segments) {
                    return Err(e("segments", "use 8 to 4096 segments".into()));
                }
                if hole_diameter_mm.0 >= width_mm.0.min(height_mm.0) {
                    return Err(e(
                        "hole_diameter_mm",
                        "the hole must be smaller than the plate".into(),
                    ));
                }
                let frame = self.ctx.frame(mm(*position_mm), *axis, *x_axis, None, &e)?;
                let mesh = Mesh::plate_with_hole(
                    &frame,
                    0.5e-3 * width_mm.0,
                    0.5e-3 * height_mm.0,
                    0.5e-3 * hole_diameter_mm.0,
                    *segments,
                );
                self.parts.meshes.push((mesh, id));
            }
            ElementSpec::Mirror {
                position_mm,
                normal,
                x_axis,
                outline,
                reflectance,
                thickness_mm,
                tilt_deg,
                ..
            } => {
                let frame =
                    self.ctx
                        .frame(mm(*position_mm), *normal, *x_axis, *tilt_deg, &|f, m| {
                            e(if f == "axis" { "normal" } else { f }, m)
                        })?;
                let r = self
                    .ctx
                    .fraction_spectrum(reflectance, |m| e("reflectance", m))?;
                let shape = outline.shape();
                self.parts.surface(
                    Geometry::Plane { frame, shape },
                    Interaction::Mirror { reflectance: r },
                    id,
                );
                let t = thickness_mm.0 * 1e-3;
                let back = Frame {
                    origin: frame.origin - t * frame.w,
                    ..frame
                };
                self.solids.push((name, solid_of(&back, shape, t)));
            }
            ElementSpec::Chart {
                position_mm,
                normal,
                x_axis,
                plate_mm,
                thickness_mm,
                glass,
                pattern,
                center_on,
                chrome_od,
                chrome_reflectance,
                tilt_deg,
                ..
            } => {
                let at =
                    self.ctx
                        .frame(mm(*position_mm), *normal, *x_axis, *tilt_deg, &|f, m| {
                            e(if f == "axis" { "normal" } else { f }, m)
                        })?;
                let glass = self.ctx.glass(glass, |m| e("glass", m))?;
                let mask = match pattern {
                    ChartPatternSpec::Clear => ChartMask::Clear,
                    ChartPatternSpec::Usaf {
                        min_group,
                        max_group,
                        positive,
                    } => {
                        if min_group > max_group || *min_group < -2 || *max_group > 9 {
                            return Err(e(
                                "pattern",
                                "USAF groups must satisfy −2 ≤ min_group ≤ max_group ≤ 9".into(),
                            ));
                        }
                        ChartMask::Usaf(crate::objects::usaf::UsafChart {
                            min_group: *min_group,
                            max_group: *max_group,
                            polarity: if *positive {
                                crate::objects::usaf::Polarity::Positive
                            } else {
                                crate::objects::usaf::Polarity::Negative
                            },
                        })
                    }
                    ChartPatternSpec::Image {
                        path,
                        width_mm,
                        height_mm,
                    } => {
                        let full = resolve(self.ctx.path, path);
                        let raster = load_mask(&full).map_err(|m| e("pattern", m))?;
                        ChartMask::Image {
                            raster,
                            width_m: width_mm.0 * 1e-3,
                            height_m: height_mm.0 * 1e-3,
                        }
                    }
                };
                let (cx, cy) = match center_on {
                    None => (0.0, 0.0),
                    Some(CenterOnSpec::Point(p)) => *p,
                    Some(CenterOnSpec::Elements { group, first, last }) => {
                        let ChartMask::Usaf(chart) = &mask else {
                            return Err(e(
                                "center_on",
                                "Elements(..) needs a Usaf chart pattern".into(),
                            ));
                        };
                        if first > last {
                            return Err(e("center_on", "first must not exceed last".into()));
                        }
                        let (mut x0, mut y0, mut x1, mut y1) = (
                            f64::INFINITY,
                            f64::INFINITY,
                            f64::NEG_INFINITY,
                            f64::NEG_INFINITY,
                        );
                        for el in *first..=*last {
                            let r = chart.element_region(*group, el).ok_or_else(|| {
                                e(
                                    "center_on",
                                    format!("the chart has no group {group} element {el}"),
                                )
                            })?;
                            x0 = x0.min(r.center_x_mm - 0.5 * r.width_mm);
                            x1 = x1.max(r.center_x_mm + 0.5 * r.width_mm);
                            y0 = y0.min(r.center_y_mm - 0.5 * r.height_mm);
                            y1 = y1.max(r.center_y_mm + 0.5 * r.height_mm);
                        }
                        (0.5 * (x0 + x1), 0.5 * (y0 + y1))
                    }
                };
                let (pw, ph) = (plate_mm.0.0 * 1e-3, plate_mm.1.0 * 1e-3);
                if (cx * 1e-3).abs() > 0.5 * pw || (cy * 1e-3).abs() > 0.5 * ph {
                    return Err(e("center_on", "the point lies outside the plate".into()));
                }
                // The chrome face's frame: origin at the plate centre.
                let face = Frame {
                    origin: at.origin - cx * 1e-3 * at.u - cy * 1e-3 * at.v,
                    ..at
                };
                let chart_index = self.parts.charts.len();
                self.parts.charts.push(ChartPlate {
                    mask,
                    frame: face,
                    chrome_od: chrome_od.build(),
                    chrome_reflectance: self
                        .ctx
                        .fraction_spectrum(chrome_reflectance, |m| e("chrome_reflectance", m))?,
                });
                if !(chrome_od.build().min_value() >= 0.0
                    && chrome_od.build().max_value() <= MAX_OD)
                {
                    return Err(e(
                        "chrome_od",
                        format!("an optical density must lie in [0, {MAX_OD}]"),
                    ));
                }
                let t = thickness_mm.0 * 1e-3;
                let m = self.parts.medium(glass, None);
                let shape = Shape2D::Rect {
                    half_u: 0.5 * pw,
                    half_v: 0.5 * ph,
                };
                // The chrome face looks back (normal −w: air in front), then the back face.
                let first = Frame {
                    origin: face.origin,
                    u: face.u,
                    v: -face.v,
                    w: -face.w,
                };
                self.parts.surface(
                    Geometry::Plane {
                        frame: first,
                        shape,
                    },
                    Interaction::Chart {
                        chart: chart_index,
                        front: AIR_MEDIUM,
                        back: m,
                    },
                    id,
                );
                let second = Frame {
                    origin: face.origin + t * face.w,
                    ..first
                };
                self.parts.surface(
                    Geometry::Plane {
                        frame: second,
                        shape,
                    },
                    Interaction::Interface {
                        front: m,
                        back: AIR_MEDIUM,
                        coating: Coating::None,
                    },
                    id,
                );
                self.parts.slab_edges(id, &face, shape, t);
                self.solids.push((name, solid_of(&face, shape, t)));
            }
        }
        Ok(())
    }

    fn dmd(&mut self, d: &DmdSpec) -> Result<DmdSetup> {
        let e = |f: &str, m: String| self.ctx.err_path(&["dmd", f], m);
        if d.columns == 0 || d.rows == 0 || d.columns > 100_000 || d.rows > 100_000 {
            return Err(e(
                "columns",
                "the array needs 1 to 100000 columns and rows".into(),
            ));
        }
        if d.tilt_deg.0 >= 45.0 {
            return Err(e("tilt_deg", "the tilt must be below 45°".into()));
        }
        if !(d.tilt_axis_deg.is_finite() && d.tilt_axis_deg.abs() <= 360.0) {
            return Err(e(
                "tilt_axis_deg",
                format!(
                    "the hinge angle must be finite and within ±360°, got {}",
                    d.tilt_axis_deg
                ),
            ));
        }
        let p = d.pattern;
        if p.mirrors_per_unit == 0 || p.units_across == 0 || p.units_down == 0 {
            return Err(self.ctx.err_path(
                &["dmd", "pattern"],
                "units_across, units_down and mirrors_per_unit must be at least 1",
            ));
        }
        // Checked arithmetic: a huge count must be refused, never wrap around.
        let end = |origin: usize, units: usize| {
            units
                .checked_mul(p.mirrors_per_unit)
                .and_then(|m| m.checked_add(origin))
        };
        let (Some(end_c), Some(end_r)) = (
            end(p.origin.0, p.units_across),
            end(p.origin.1, p.units_down),
        ) else {
            return Err(self.ctx.err_path(
                &["dmd", "pattern"],
                format!(
                    "the pattern area is larger than any DMD (at most {} × {} mirrors here)",
                    d.columns, d.rows
                ),
            ));
        };
        if end_c > d.columns || end_r > d.rows {
            return Err(self.ctx.err_path(
                &["dmd", "pattern"],
                format!(
                    "the pattern area (mirrors {}..{} × {}..{}) does not fit the {}×{} array",
                    p.origin.0, end_c, p.origin.1, end_r, d.columns, d.rows
                ),
            ));
        }
        let refl = self
            .ctx
            .fraction_spectrum(&d.mirror_reflectance, |m| e("mirror_reflectance", m))?;
        let state = match d.outside_state {
            StateSpec::Plus => MirrorState::Plus,
            StateSpec::Minus => MirrorState::Minus,
            StateSpec::Flat => MirrorState::Flat,
        };
        let dmd = Dmd::new(
            d.columns,
            d.rows,
            d.pitch_um.0 * 1e-6,
            d.fill_factor.0,
            d.tilt_deg.0.to_radians(),
            d.tilt_axis_deg.to_radians(),
            PatternArea {
                col0: p.origin.0,
                row0: p.origin.1,
                units_across: p.units_across,
                units_down: p.units_down,
                mirrors_per_unit: p.mirrors_per_unit,
            },
            state,
            refl,
        );
        let (hx, hy) = dmd.half_size();
        let (px, py) = (0.5e-3 * d.package_mm.0.0, 0.5e-3 * d.package_mm.1.0);
        if px <= hx || py <= hy {
            return Err(e(
                "package_mm",
                format!(
                    "the package must be larger than the {:.3} × {:.3} mm array",
                    2e3 * hx,
                    2e3 * hy
                ),
            ));
        }
        let mirrors_element = self.parts.element("dmd_mirrors");
        let gaps_element = self.parts.element("dmd_gaps");
        let package = self.parts.element("dmd_package");
        let base = Frame::new(DVec3::ZERO, DVec3::Z, Some(DVec3::X));
        self.parts.surface(
            Geometry::Plane {
                frame: base,
                shape: Shape2D::RectWithRectHole {
                    half_u: px,
                    half_v: py,
                    hole_u: hx,
                    hole_v: hy,
                },
            },
            Interaction::Absorber,
            package,
        );
        let mut top = 2.0 * dmd.slab_half_height();
        if let Some(w) = &d.window {
            let ew = |f: &str, m: String| self.ctx.err_path(&["dmd", "window", f], m);
            let glass = self.ctx.glass(&w.glass, |m| ew("glass", m))?;
            let coating = self.ctx.coating(&w.coating, |m| ew("coating", m))?;
            let gap = w.gap_mm.0 * 1e-3;
            let t = w.thickness_mm.0 * 1e-3;
            let (wx, wy) = (0.5e-3 * w.size_mm.0.0, 0.5e-3 * w.size_mm.1.0);
            if gap <= 2.0 * dmd.slab_half_height() {
                return Err(ew(
                    "gap_mm",
                    "the window must clear the tilted mirrors".into(),
                ));
            }
            if wx < hx || wy < hy {
                return Err(ew("size_mm", "the window must cover the array".into()));
            }
            if wx >= px || wy >= py {
                return Err(ew(
                    "size_mm",
                    "the window must fit inside the package".into(),
                ));
            }
            let window = self.parts.element("dmd_window");
            let m = self.parts.medium(glass, None);
            let wf = Frame::new(DVec3::new(0.0, 0.0, gap), DVec3::Z, Some(DVec3::X));
            self.parts.slab(
                window,
                &wf,
                Shape2D::Rect {
                    half_u: wx,
                    half_v: wy,
                },
                t,
                m,
                coating,
            );
            top = gap + t;
            // The package top around the window.
            self.parts.surface(
                Geometry::Plane {
                    frame: Frame::new(DVec3::new(0.0, 0.0, top), DVec3::Z, Some(DVec3::X)),
                    shape: Shape2D::RectWithRectHole {
                        half_u: px,
                        half_v: py,
                        hole_u: wx,
                        hole_v: wy,
                    },
                },
                Interaction::Absorber,
                package,
            );
        }
        self.solids.push((
            "dmd".into(),
            Solid::Box {
                frame: Frame::new(
                    DVec3::new(0.0, 0.0, 0.5 * top - 1e-3),
                    DVec3::Z,
                    Some(DVec3::X),
                ),
                half: DVec3::new(px, py, 0.5 * top + 1e-3),
            },
        ));
        Ok(DmdSetup {
            dmd,
            mirrors_element,
            gaps_element,
        })
    }

    fn photodiode(&mut self, s: &PhotodiodeSpec, index: usize) -> Result<Photodiode> {
        let key = if index == 0 { "plus" } else { "minus" };
        let e = |f: &str, m: String| self.ctx.err_path(&["detectors", key, f], m);
        let normal = s.normal.to_unit().map_err(|m| e("normal", m))?;
        let frame = Frame::new(mm(s.position_mm), normal, None);
        let radius = 0.5e-3 * s.diameter_mm.0;
        let responsivity = s.responsivity.build();
        if !(responsivity.min_value() >= 0.0 && responsivity.max_value() <= 2.0) {
            return Err(e(
                "responsivity",
                "a responsivity must lie in [0, 2] A/W (silicon peaks near 0.65 A/W)".into(),
            ));
        }
        let name = format!("pd_{key}");
        let id = self.parts.element(&name);
        self.parts.surface(
            Geometry::Plane {
                frame,
                shape: Shape2D::Disk { radius },
            },
            Interaction::Detector { index },
            id,
        );
        if let Some(h) = s.housing_diameter_mm {
            let outer = 0.5e-3 * h.0;
            if outer <= radius {
                return Err(e(
                    "housing_diameter_mm",
                    "the housing must be larger than the active area".into(),
                ));
            }
            let hid = self.parts.element(&format!("pd_{key}_housing"));
            self.parts.surface(
                Geometry::Plane {
                    frame,
                    shape: Shape2D::Annulus {
                        inner: radius,
                        outer,
                    },
                },
                Interaction::Absorber,
                hid,
            );
        }
        let back = Frame {
            origin: frame.origin - 1e-3 * frame.w,
            ..frame
        };
        self.solids.push((
            name,
            Solid::Cylinder {
                frame: back,
                radius,
                length: 1e-3,
            },
        ));
        let area = std::f64::consts::PI * radius * radius;
        let ambient = s.ambient_w_per_m2.0;
        Ok(Photodiode {
            frame,
            radius,
            ambient_current_a: ambient * area * ambient_responsivity(&responsivity),
            responsivity,
            ambient_w_per_m2: ambient,
            dark_current_a: s.dark_current_a.0,
        })
    }

    fn lamp(&mut self, s: &LampSpec, band: (f64, f64)) -> Result<Lamp> {
        let e = |f: &str, m: String| self.ctx.err_path(&["lamp", f], m);
        let w = s.axis.to_unit().map_err(|m| e("axis", m))?;
        let u = match s.x_axis {
            Some(d) => Some(d.to_unit().map_err(|m| e("x_axis", m))?),
            None => None,
        };
        let frame = Frame::new(mm(s.position_mm), w, u);
        let shape = match s.filament {
            FilamentSpec::Rect {
                width_mm,
                height_mm,
            } => EmitterShape::Rect {
                half_u: 0.5e-3 * width_mm.0,
                half_v: 0.5e-3 * height_mm.0,
            },
            FilamentSpec::Disk { diameter_mm } => EmitterShape::Disk {
                radius: 0.5e-3 * diameter_mm.0,
            },
        };
        let spectrum = match &s.spectrum {
            LampSpectrumSpec::Tungsten { temperature_k } => LampSpectrum::Tungsten {
                temperature_k: temperature_k.0,
            },
            LampSpectrumSpec::Graybody {
                temperature_k,
                emissivity,
            } => LampSpectrum::Graybody {
                temperature_k: temperature_k.0,
                emissivity: emissivity.0,
            },
            LampSpectrumSpec::Table(t) => {
                let t = Table::from_nm(&t.0).expect("validated while reading");
                if !(t.min_value() >= 0.0 && t.max_value().is_finite()) {
                    return Err(e(
                        "spectrum",
                        "spectral power must be finite and not negative".into(),
                    ));
                }
                LampSpectrum::Table(Spectrum::Table(t))
            }
        };
        if spectrum.integral(band) <= 0.0 {
            return Err(e(
                "spectrum",
                "the lamp emits nothing in the traced band".into(),
            ));
        }
        let band_power_w = match s.power {
            LampPowerSpec::InBand { watts } => watts.0,
            LampPowerSpec::Electrical {
                watts,
                in_band_efficiency,
            } => watts.0 * in_band_efficiency.0,
            LampPowerSpec::FromFilament => {
                if matches!(spectrum, LampSpectrum::Table(_)) {
                    return Err(e(
                        "power",
                        "FromFilament needs a thermal spectrum (Tungsten or Graybody)".into(),
                    ));
                }
                band_power_from_filament(shape.area(), &spectrum, band)
            }
        };
        let sin2_max = match &s.emission {
            EmissionSpec::Hemisphere => 1.0,
            EmissionSpec::Cone { half_angle_deg } => {
                if half_angle_deg.0 > 90.0 {
                    return Err(e("emission", "the half-angle must be at most 90°".into()));
                }
                half_angle_deg.0.to_radians().sin().powi(2)
            }
            EmissionSpec::Toward { element } => {
                let Some((_, solid)) = self.solids.iter().find(|(n, _)| n == element) else {
                    return Err(e(
                        "emission",
                        format!("no lens, filter, mirror or chart named `{element}`"),
                    ));
                };
                let corners: Vec<DVec3> = match shape {
                    EmitterShape::Rect { half_u, half_v } => {
                        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                            .iter()
                            .map(|(a, b)| {
                                frame.origin + a * half_u * frame.u + b * half_v * frame.v
                            })
                            .collect()
                    }
                    EmitterShape::Disk { radius } => (0..64)
                        .map(|k| {
                            let a = std::f64::consts::TAU * k as f64 / 64.0;
                            frame.origin + radius * (a.cos() * frame.u + a.sin() * frame.v)
                        })
                        .collect(),
                };
                let mut max_angle = 0.0f64;
                for q in solid_outline(solid) {
                    for &p in &corners {
                        let v = q - p;
                        let c = v.dot(frame.w) / v.length();
                        if c <= 0.0 {
                            return Err(e(
                                "emission",
                                format!("`{element}` is not in front of the filament"),
                            ));
                        }
                        max_angle = max_angle.max(c.clamp(-1.0, 1.0).acos());
                    }
                }
                let a = (max_angle + 0.1f64.to_radians()).min(std::f64::consts::FRAC_PI_2);
                a.sin().powi(2)
            }
        };
        let field = s.field_sampling.as_ref().map(|f| FieldTarget {
            center: mm(f.center_mm),
            outline: match f.outline {
                Outline::Round { diameter_mm } => FieldOutline::Disk {
                    radius: 0.5e-3 * diameter_mm.0,
                },
                Outline::Rect {
                    width_mm,
                    height_mm,
                } => FieldOutline::Rect {
                    half_u: 0.5e-3 * width_mm.0,
                    half_v: 0.5e-3 * height_mm.0,
                },
            },
            probability: f.probability,
        });
        let lamp = Lamp {
            frame,
            shape,
            spectrum,
            band_power_w,
            sin2_max,
            field,
            guide: None,
        };
        lamp.check_field().map_err(|m| e("field_sampling", m))?;
        Ok(lamp)
    }

    fn check_overlaps(&self) -> Result<()> {
        // Blame the element listed later (the DMD and the photodiodes come after all elements),
        // at its position field.
        let locate = |name: &str, msg: String| match name {
            "pd_plus" => self
                .ctx
                .err_path(&["detectors", "plus", "position_mm"], msg),
            "pd_minus" => self
                .ctx
                .err_path(&["detectors", "minus", "position_mm"], msg),
            "dmd" => self.ctx.err_path(&["dmd"], msg),
            other => self.ctx.err_el(other, "position_mm", msg),
        };
        for i in 0..self.solids.len() {
            for j in i + 1..self.solids.len() {
                let (a, sa) = &self.solids[i];
                let (b, sb) = &self.solids[j];
                if sa.overlaps(sb) {
                    let msg = format!("`{b}` overlaps `{a}`: two solid parts cannot share space");
                    return Err(if b == "dmd" {
                        locate(a, msg)
                    } else {
                        locate(b, msg)
                    });
                }
            }
        }
        Ok(())
    }
}

/// A plate of outline `shape` from `frame.origin` along `frame.w` over `thickness`.
fn solid_of(frame: &Frame, shape: Shape2D, thickness: f64) -> Solid {
    match shape {
        Shape2D::Disk { radius } => Solid::Cylinder {
            frame: *frame,
            radius,
            length: thickness,
        },
        other => {
            let r = other.bounding_radius();
            let (hu, hv) = match other {
                Shape2D::Rect { half_u, half_v } => (half_u, half_v),
                _ => (r, r),
            };
            Solid::Box {
                frame: Frame {
                    origin: frame.origin + 0.5 * thickness * frame.w,
                    ..*frame
                },
                half: DVec3::new(hu, hv, 0.5 * thickness),
            }
        }
    }
}

/// Points on the outline of a solid's faces (for the emission cone).
fn solid_outline(s: &Solid) -> Vec<DVec3> {
    let mut v = Vec::new();
    match *s {
        Solid::Cylinder {
            frame,
            radius,
            length,
        } => {
            for z in [0.0, length] {
                for k in 0..256 {
                    let a = std::f64::consts::TAU * k as f64 / 256.0;
                    v.push(frame.to_world(DVec3::new(radius * a.cos(), radius * a.sin(), z)));
                }
            }
        }
        Solid::Box { frame, half } => {
            for sx in [-1.0, 1.0] {
                for sy in [-1.0, 1.0] {
                    for sz in [-1.0, 1.0] {
                        v.push(frame.to_world(DVec3::new(sx * half.x, sy * half.y, sz * half.z)));
                    }
                }
            }
        }
    }
    v
}

fn resolve(scene: &Path, rel: &str) -> PathBuf {
    let p = Path::new(rel);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        scene.parent().unwrap_or(Path::new(".")).join(p)
    }
}

/// Loads a PNG as a [0, 1] transmittance raster (grey level / maximum level).
fn load_mask(path: &Path) -> std::result::Result<Raster, String> {
    let img =
        image::open(path).map_err(|e| format!("cannot read image {}: {e}", path.display()))?;
    let g = img.to_luma16();
    let (w, h) = (g.width() as usize, g.height() as usize);
    let data = g.pixels().map(|p| p.0[0] as f64 / 65535.0).collect();
    Raster::new(w, h, data).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The symmetric test bench with `glasses` added before its lamp and its + arm's lens made
    /// of the glass `lens_glass`.
    fn with_glasses(glasses: &str, lens_glass: &str) -> (String, PathBuf) {
        let (text, path) = base();
        let text = text
            .replacen(
                "(\n    lamp: (",
                &format!("(\n    glasses: [{glasses}],\n    lamp: ("),
                1,
            )
            .replacen("glass: \"N-BK7\"", &format!("glass: \"{lens_glass}\""), 1);
        (text, path)
    }

    const MY_BK7: &str = "(name: \"MY-BK7\", sellmeier_b: (1.03961212, 0.231792344, 1.01046945), \
         sellmeier_c_um2: (0.00600069867, 0.0200179144, 103.560653))";

    /// A bench's own glass with N-BK7's coefficients builds the same media as the catalogue's
    /// N-BK7, traces bit-identically, and survives the canonical RON writer.
    #[test]
    fn user_glass_equals_the_catalogue_glass_it_copies() {
        let (text, path) = with_glasses(MY_BK7, "my_bk7");
        let own = parse_bench(&text, &path).unwrap();
        let (plain, _) = base();
        let cat = parse_bench(&plain, &path).unwrap();
        let glasses =
            |b: &Bench| -> Vec<Glass> { b.media().iter().map(|m| m.glass.clone()).collect() };
        assert_eq!(glasses(&own), glasses(&cat));
        let opts = crate::trace::TraceOptions::new(20_480, 3);
        let (a, b) = (
            crate::trace::trace(&own, &opts).unwrap(),
            crate::trace::trace(&cat, &opts).unwrap(),
        );
        let (ta, tb) = (
            crate::transport::Transport::from_tallies(&own, &a),
            crate::transport::Transport::from_tallies(&cat, &b),
        );
        assert_eq!(ta.k[0].value.to_bits(), tb.k[0].value.to_bits());
        assert_eq!(ta.k[1].value.to_bits(), tb.k[1].value.to_bits());
        // Round trip: written as canonical RON and read back, the glass is still there.
        let doc = crate::scene::doc::BenchDoc::parse(&text, &path).unwrap();
        let ron = doc.to_ron().unwrap();
        assert!(ron.contains("MY-BK7"), "{ron}");
        let back = parse_bench(&ron, &path).unwrap();
        assert_eq!(glasses(&back), glasses(&own));
        // A bench without glasses writes no `glasses` field.
        let plain_doc = crate::scene::doc::BenchDoc::parse(&plain, &path).unwrap();
        assert!(!plain_doc.to_ron().unwrap().contains("glasses"));
    }

    /// Bad glasses are located input errors naming the field and line.
    #[test]
    fn bad_user_glasses_are_located() {
        let check = |glasses: &str, lens: &str, marker: &str, field: &str, words: &str| {
            let (text, path) = with_glasses(glasses, lens);
            let (msg, line) = fails_at(&text, &path, marker);
            assert!(msg.contains(&format!("line {line}")), "{msg} (line {line})");
            assert!(msg.contains("symmetric_arms.ron"), "{msg}");
            assert!(msg.contains(field), "{msg}");
            assert!(msg.contains(words), "{msg}");
        };
        // A catalogue name may not be redefined.
        check(
            &MY_BK7.replace("MY-BK7", "n_sf5"),
            "N-BK7",
            "name: \"n_sf5\"",
            "glasses[0].name",
            "catalogue glass N-SF5",
        );
        // A resonance inside the traced band (C = 0.36 µm²: 600 nm).
        check(
            &MY_BK7.replace("0.0200179144", "0.36"),
            "MY-BK7",
            "name: \"MY-BK7\"",
            "glasses[0].sellmeier_c_um2",
            "600.0 nm",
        );
        // Coefficients that give n < 1 somewhere in the band (C in nm² by mistake).
        check(
            "(name: \"WRONG\", sellmeier_b: (1.0, 0.2, 1.0), sellmeier_c_um2: (6000.0, 20000.0, 1.0e8))",
            "WRONG",
            "name: \"WRONG\"",
            "glasses[0].sellmeier_b",
            "µm²",
        );
        // Twice the same name.
        check(
            &format!("{MY_BK7}, {}", MY_BK7.replace("MY-BK7", "my bk7")),
            "MY-BK7",
            "name: \"my bk7\"",
            "glasses[1].name",
            "twice",
        );
        // A negative coefficient is refused by its type.
        let (text, path) = with_glasses(&MY_BK7.replace("1.03961212", "-1.0"), "MY-BK7");
        let msg = parse_bench(&text, &path).unwrap_err().to_string();
        assert!(
            msg.contains("non-negative") && msg.contains("glasses") && msg.contains("line "),
            "{msg}"
        );
        // An unknown glass names the catalogue and the bench's own glasses.
        let (text, path) = with_glasses(MY_BK7, "MY-BK8");
        let msg = parse_bench(&text, &path).unwrap_err().to_string();
        assert!(
            msg.contains("N-LAK22") && msg.contains("this bench's glasses (MY-BK7)"),
            "{msg}"
        );
    }

    fn base() -> (String, PathBuf) {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron");
        (std::fs::read_to_string(&p).unwrap(), p)
    }

    /// Applies one edit and parses; returns the error text and the 1-based line where `marker`
    /// (a string of the edited text) sits.
    fn fails(from: &str, to: &str, marker: &str) -> (String, usize) {
        let (text, path) = base();
        assert_eq!(text.matches(from).count(), 1, "edit {from}");
        fails_at(&text.replacen(from, to, 1), &path, marker)
    }

    /// Parses `text`, which must fail as a user error; returns the error text and the 1-based
    /// line where `marker` sits.
    fn fails_at(text: &str, path: &Path, marker: &str) -> (String, usize) {
        let line = text[..text.find(marker).expect("marker")]
            .matches('\n')
            .count()
            + 1;
        let err = parse_bench(text, path).expect_err("must fail");
        assert!(err.is_user_error());
        (err.to_string(), line)
    }

    fn expect(from: &str, to: &str, marker: &str, field: &str, words: &str) {
        let (msg, line) = fails(from, to, marker);
        assert!(
            msg.contains(&format!("line {line}")),
            "{msg} (expected line {line})"
        );
        assert!(
            msg.contains("field `")
                && (msg.contains(&format!("{field}`")) || msg.contains(&format!("{field}["))),
            "{msg}"
        );
        assert!(msg.contains(words), "{msg}");
        assert!(msg.contains("symmetric_arms.ron"), "{msg}");
    }

    /// Numbers that would reach the tracer as NaN, infinity, an overflow or a wrapped size are
    /// refused where they are written, naming the field and the line.
    #[test]
    fn non_finite_huge_and_wrapping_numbers_are_refused_where_written() {
        expect(
            "position_mm: (0.0, 0.0, 100.0),",
            "position_mm: (0.0, NaN, 100.0),",
            "position_mm: (0.0, NaN",
            "position_mm",
            "finite",
        );
        expect(
            "position_mm: (39.0011, -39.0011, 123.8823),",
            "position_mm: (39.0011, -39.0011, 1e308),",
            "1e308",
            "position_mm",
            "within",
        );
        expect(
            "position_mm: (-17.2564, 17.2564, 54.8127),",
            "position_mm: (-17.2564, inf, 54.8127),",
            "inf, 54",
            "position_mm",
            "finite",
        );
        expect(
            "axis: Vector((0.0, 0.0, -1.0)),",
            "axis: Vector((0.0, 0.0, -1e300)),",
            "-1e300",
            "axis",
            "within",
        );
        expect(
            "temperature_k: 2800.0",
            "temperature_k: 1e9",
            "1e9",
            "temperature_k",
            "4000",
        );
        let (msg, _) = fails(
            "units_across: 4, units_down: 4, mirrors_per_unit: 8",
            "units_across: 4, units_down: 4, mirrors_per_unit: 4611686018427387904",
            "mirrors_per_unit: 46",
        );
        assert!(
            msg.contains("pattern") && msg.contains("larger than any DMD"),
            "{msg}"
        );
    }

    #[test]
    fn the_test_benches_and_the_paper_bench_parse() {
        let (text, path) = base();
        let b = parse_bench(&text, &path).unwrap();
        assert_eq!(b.units(), 16);
        assert_eq!(b.elements()[b.lamp_housing()], "lamp_housing");
        // The paper bench parses as far as its chart (the USAF geometry is another module's).
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
        let file: BenchFile = crate::scene::read_ron(&p).unwrap();
        assert_eq!(file.elements.len(), 13);
        let d = file.dmd.as_ref().unwrap();
        assert_eq!(d.pattern.units_across * d.pattern.mirrors_per_unit, 576);
    }

    #[test]
    fn directions() {
        let v = Direction::Polar {
            theta_deg: 24.0,
            phi_deg: -45.0,
        }
        .to_unit()
        .unwrap();
        assert!((v - DVec3::new(0.287_606, -0.287_606, 0.913_545)).length() < 1e-6);
        assert!(Direction::Vector(Mm3(0.0, 0.0, 0.0)).to_unit().is_err());
        // Huge but finite components normalise without overflow.
        let u = Direction::Vector(Mm3(1e300, 1e300, 0.0)).to_unit().unwrap();
        assert!((u.length() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn single_value_errors_carry_line_and_field() {
        expect(
            "power: InBand(watts: 1.0),",
            "power: InBand(watts: -1.0),",
            "watts: -1.0",
            "watts",
            "positive",
        );
        expect(
            "            diameter_mm: 5.0,\n        ),\n        minus",
            "            diameter_mm: 0.0,\n        ),\n        minus",
            "diameter_mm: 0.0",
            "diameter_mm",
            "positive",
        );
        expect(
            "spectrum: Tungsten(temperature_k: 2800.0),",
            "spectrum: Table([(500.0, 1.0), (400.0, 2.0)]),",
            "Table([(500.0",
            "spectrum",
            "strictly increasing",
        );
        expect(
            "        pitch_um: 100.0,",
            "        pitch_um: 100.0,\n        pich_um: 3.0,",
            "pich_um",
            "pich_um",
            "pich_um",
        );
    }

    #[test]
    fn geometry_errors_carry_line_and_field() {
        // A lens too thin for its radius and diameter: the faces would cross before the rim.
        expect(
            "            thickness_mm: 5.34,\n            diameter_mm: 25.4,\n            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
            "            thickness_mm: 2.0,\n            diameter_mm: 25.4,\n            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
            "thickness_mm: 2.0",
            "thickness_mm",
            "faces cross",
        );
        // A radius that cannot span the diameter.
        expect(
            "            front_radius_mm: 25.75,\n            thickness_mm: 5.34,\n            diameter_mm: 25.4,\n            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
            "            front_radius_mm: 10.0,\n            thickness_mm: 5.34,\n            diameter_mm: 25.4,\n            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
            "front_radius_mm: 10.0",
            "front_radius_mm",
            "cannot span",
        );
        // Overlapping elements: move the − lens onto the + lens.
        expect(
            "position_mm: (-17.2564, 17.2564, 54.8127),",
            "position_mm: (17.2564, -17.2564, 56.0),",
            "position_mm: (17.2564, -17.2564, 56.0)",
            "position_mm",
            "overlaps",
        );
        // A pattern area larger than the array.
        expect(
            "units_across: 4,",
            "units_across: 5,",
            "pattern: (origin",
            "pattern",
            "does not fit",
        );
        // An unknown glass.
        expect(
            "            glass: \"N-BK7\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
            "            glass: \"N-BK8\",\n        ),\n        Lens(\n            name: \"arm_minus_lens\",",
            "glass: \"N-BK8\"",
            "glass",
            "unknown glass",
        );
        // Emission toward an element that does not exist.
        expect(
            "emission: Cone(half_angle_deg: 3.0),",
            "emission: Toward(element: \"nothing\"),",
            "emission: Toward",
            "emission",
            "nothing",
        );
        // A field target outside the emission cone.
        expect(
            "center_mm: (0.0, 0.0, 0.0),",
            "center_mm: (30.0, 0.0, 0.0),",
            "field_sampling: (",
            "field_sampling",
            "outside the emission cone",
        );
    }

    #[test]
    fn unsorted_nd_table_is_rejected_at_its_line() {
        // An ND filter added to the test bench with an unsorted OD table.
        let filter = "        Filter(\n            name: \"nd\",\n            position_mm: (0.0, 0.0, 80.0),\n            axis: Vector((0.0, 0.0, -1.0)),\n            outline: Round(diameter_mm: 10.0),\n            thickness_mm: 2.0,\n            glass: \"N-BK7\",\n            od: Table([(400.0, 1.0), (900.0, 0.6), (700.0, 0.8)]),\n        ),\n    ],\n    dmd:";
        expect(
            "    ],\n    dmd:",
            filter,
            "od: Table",
            "od",
            "strictly increasing",
        );
    }
}
