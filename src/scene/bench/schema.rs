//! The bench file's schema: the serde types of a bench file, in millimetres and degrees (see
//! the notes of [`crate::scene::bench`] for the frame), their single values checked while
//! reading through the types of [`crate::scene::numbers`].

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::optics::geometry::Shape2D;
use crate::optics::spectrum::{self, Spectrum, Table};
use crate::scene::numbers::{
    AngleDeg, CoordMm, Count, DesignNm, DirectionDeg, Finite, Irradiance, LengthMm, Mm3,
    NonNegative, OpticalDensity, Positive, PowerW, Probability, RadiusMm, TableNm, Temperature,
    TiltDeg, UnitFraction, WavelengthNm, Whole,
};

/// Mirrors along one side of a DMD, or pattern units along one side of its pattern area (the
/// largest DMDs have a few thousand mirrors a side).
pub type MirrorCount = Count<1, 100_000>;

/// A mirror index (column or row) of the pattern area's origin.
pub type MirrorIndex = Count<0, 100_000>;

/// The most surface interactions a path may have before it is abandoned.
pub type Interactions = Count<1, 100_000>;

/// Sides of a baffle hole's polygon.
pub type Segments = Count<8, 4096>;

/// A group of the 1951 USAF chart (−2 … 9 are printed on the charts spibench draws).
pub type UsafGroup = Whole<-2, 9>;

/// An element (1 … 6) of a USAF group.
pub type UsafElement = Count<1, 6>;

/// A direction in the bench frame (see the module notes).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum Direction {
    /// Components (x, y, z), any non-zero length.
    Vector(Mm3),
    /// Polar angle `theta_deg` from +z and azimuth `phi_deg` from +x toward +y (degrees).
    Polar {
        /// Polar angle from +z (degrees).
        theta_deg: DirectionDeg,
        /// Azimuth from +x toward +y (degrees).
        phi_deg: DirectionDeg,
    },
}

impl Direction {
    pub fn to_unit(self) -> std::result::Result<DVec3, String> {
        let v = match self {
            Direction::Vector(Mm3(x, y, z)) => DVec3::new(x, y, z),
            Direction::Polar { theta_deg, phi_deg } => {
                let (t, p) = (theta_deg.0.to_radians(), phi_deg.0.to_radians());
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
    Constant(Finite),
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
    NgGlass(OpticalDensity),
    /// Per-surface reflectance of a visible-AR DMD window (≤ 0.5 % in 420–680 nm, rising in the
    /// NIR; docs/bench-facts.md §2.2, estimate).
    DmdWindowVisibleAr,
}

impl SpectrumSpec {
    pub(crate) fn build(&self) -> Spectrum {
        match self {
            SpectrumSpec::Constant(v) => Spectrum::Constant(v.0),
            SpectrumSpec::Table(t) => {
                Spectrum::Table(Table::from_nm(&t.0).expect("validated while reading"))
            }
            SpectrumSpec::Aluminium => Spectrum::from_static(&spectrum::ALUMINIUM_REFLECTANCE),
            SpectrumSpec::ProtectedSilver => {
                Spectrum::from_static(&spectrum::PROTECTED_SILVER_REFLECTANCE)
            }
            SpectrumSpec::SiliconPin => Spectrum::from_static(&spectrum::SILICON_PIN_RESPONSIVITY),
            SpectrumSpec::NgGlass(od) => {
                Spectrum::from_static(&spectrum::NG_GLASS_RELATIVE_OD).scaled(od.0)
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
    MgF2 {
        /// The design wavelength λ₀ (nm).
        design_nm: DesignNm,
    },
    /// A fixed per-surface reflectance R(λ) at any angle (T = 1 − R), e.g. a vendor AR curve.
    Reflectance(SpectrumSpec),
}

/// A planar outline.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum Outline {
    /// A disk.
    Round {
        /// Its diameter (mm).
        diameter_mm: LengthMm,
    },
    /// A rectangle, its width along the part's `x_axis`.
    Rect {
        /// Width (mm).
        width_mm: LengthMm,
        /// Height (mm).
        height_mm: LengthMm,
    },
}

impl Outline {
    pub(crate) fn shape(self) -> Shape2D {
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

/// A bench file (see the module notes for the frame and units).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BenchFile {
    /// Traced wavelength band [min, max] in nm. Default (350, 1150): the silicon-sensitive band;
    /// x_j and every power in the ledger are powers within this band.
    #[serde(default = "default_band")]
    pub band_nm: (WavelengthNm, WavelengthNm),
    /// Surface interactions after which a path is abandoned and booked as "path cap" (default
    /// 200; a real path here has fewer than 30).
    #[serde(default = "default_max_interactions")]
    pub max_interactions: Interactions,
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

fn default_band() -> (WavelengthNm, WavelengthNm) {
    (WavelengthNm(350.0), WavelengthNm(1150.0))
}

fn default_max_interactions() -> Interactions {
    Interactions::new(200)
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
    /// A flat rectangle (a coiled filament seen face on), its width along the lamp's `x_axis`.
    Rect {
        /// Width (mm).
        width_mm: LengthMm,
        /// Height (mm).
        height_mm: LengthMm,
    },
    /// A flat disk.
    Disk {
        /// Diameter (mm).
        diameter_mm: LengthMm,
    },
}

/// The lamp's spectral shape.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum LampSpectrumSpec {
    /// Planck's law × the Larrabee tungsten emissivity at `temperature_k`.
    Tungsten {
        /// Filament temperature (K).
        temperature_k: Temperature,
    },
    /// Planck's law × a constant emissivity.
    Graybody {
        /// Temperature (K).
        temperature_k: Temperature,
        /// The constant emissivity.
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
    InBand {
        /// Radiant power in the band (W).
        watts: PowerW,
    },
    /// Electrical power (W) times the in-band radiant efficiency (W radiated in the traced band
    /// per W electrical). A QTH lamp radiates ~85–90 % of its input; at 2800 K a blackbody puts
    /// 32 % of its radiation into 350–1150 nm (tungsten somewhat more, its emissivity falling in
    /// the infrared), so ≈ 0.3 for the default band (estimate, confidence L).
    Electrical {
        /// Electrical power (W).
        watts: PowerW,
        /// W radiated in the traced band per W electrical.
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
    Cone {
        /// Half-angle around the filament normal (degrees, up to 90).
        half_angle_deg: AngleDeg,
    },
    /// The smallest cone (plus 0.1°) that contains the named element as seen from every point of
    /// the filament: usually the collimator.
    Toward {
        /// The element's name.
        element: String,
    },
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
    pub probability: Probability,
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

/// One bench element. A file writes each as a struct variant, `Lens(name: …, …)`
/// (`element_serde`), and each variant holds the struct of its fields.
#[derive(Debug, Clone, PartialEq)]
pub enum ElementSpec {
    Lens(LensSpec),
    LensSystem(LensSystemSpec),
    Filter(FilterSpec),
    Aperture(ApertureSpec),
    Tube(TubeSpec),
    Baffle(BaffleSpec),
    Mirror(MirrorSpec),
    Chart(ChartSpec),
}

/// A singlet lens of real spherical or flat surfaces.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, expecting = "struct variant ElementSpec::Lens")]
pub struct LensSpec {
    /// Unique name; the ledger key of the light it absorbs.
    pub name: String,
    /// Catalogue part number (informational).
    #[serde(default)]
    pub part: Option<String>,
    /// Vertex of the first surface (mm).
    pub position_mm: Mm3,
    /// Direction of light travel; the front surface is met first.
    pub axis: Direction,
    /// Front surface radius (mm): positive when its centre of curvature lies after it along
    /// `axis`; omitted or None = flat.
    #[serde(default)]
    pub front_radius_mm: Option<RadiusMm>,
    /// Back surface radius (mm), same sign rule (a plano-convex lens used curved side first
    /// has front +R and a flat back; used flat side first, a flat front and back −R).
    #[serde(default)]
    pub back_radius_mm: Option<RadiusMm>,
    /// Centre thickness (mm).
    pub thickness_mm: LengthMm,
    /// Mechanical diameter (mm).
    pub diameter_mm: LengthMm,
    /// Clear aperture (mm); the ring outside it is covered by the mount (black). Default =
    /// the diameter.
    #[serde(default)]
    pub clear_diameter_mm: Option<LengthMm>,
    /// Glass: a catalogue name (N-BK7, N-SF11, fused-silica, MgF2) or a constant index such
    /// as "1.5".
    pub glass: String,
    /// Coating of both surfaces.
    #[serde(default)]
    pub coating: CoatingSpec,
    /// Alignment error: rotations (degrees) about the lens's local x then y axes, about
    /// `position_mm`.
    #[serde(default)]
    pub tilt_deg: Option<(TiltDeg, TiltDeg)>,
}

/// A multi-surface lens (a doublet, an asphere, …): the surfaces of a Zemax prescription
/// (`zmx`, a path relative to the bench file) or written inline (`surfaces`), front to back.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(
    deny_unknown_fields,
    expecting = "struct variant ElementSpec::LensSystem"
)]
pub struct LensSystemSpec {
    /// Unique name; the ledger key of the light it absorbs.
    pub name: String,
    /// Catalogue part number (informational).
    #[serde(default)]
    pub part: Option<String>,
    /// A sequential Zemax prescription (.zmx), relative to the bench file.
    #[serde(default)]
    pub zmx: Option<String>,
    /// The surfaces written inline, front to back (instead of `zmx`).
    #[serde(default)]
    pub surfaces: Option<Vec<LensSurfaceSpec>>,
    /// Use the element turned round: light meets its last surface first.
    #[serde(default)]
    pub reversed: bool,
    /// Vertex of the first surface the light meets (mm).
    pub position_mm: Mm3,
    /// Direction of light travel.
    pub axis: Direction,
    /// Mechanical diameter of the edge (mm); default: the largest surface's diameter.
    #[serde(default)]
    pub diameter_mm: Option<LengthMm>,
    /// Clear aperture of the mount (mm); light beyond it is absorbed. Default: each surface's.
    #[serde(default)]
    pub clear_diameter_mm: Option<LengthMm>,
    /// Zemax glass catalogues (.agf, relative to the bench file) to resolve the prescription's
    /// glasses through before the built-in catalogue.
    #[serde(default)]
    pub glass_catalogues: Vec<String>,
    /// Model a glass that no catalogue has from the prescription's own nd and Vd (every such
    /// substitution is reported on stderr, by `check` and in `summary.json`); default: refuse.
    #[serde(default)]
    pub allow_glass_substitution: bool,
    /// Coating of every surface.
    #[serde(default)]
    pub coating: CoatingSpec,
    /// Alignment error: rotations (degrees) about the local x then y axes, about
    /// `position_mm`.
    #[serde(default)]
    pub tilt_deg: Option<(TiltDeg, TiltDeg)>,
}

/// One surface of an inline `LensSystem`, in the sag convention of docs/guide/08-lens-prescriptions.md.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LensSurfaceSpec {
    /// Radius of curvature (mm), positive with its centre after the surface; omitted = flat.
    #[serde(default)]
    pub radius_mm: Option<RadiusMm>,
    /// Conic constant k (0 a sphere, −1 a paraboloid).
    #[serde(default)]
    pub conic: Option<Finite>,
    /// Even-asphere coefficients A4, A6, … A16 (mm^(1−2i)), as many as needed.
    #[serde(default)]
    pub asphere: Vec<Finite>,
    /// Clear semi-diameter (mm).
    pub semi_diameter_mm: LengthMm,
    /// Axial distance to the next surface's vertex (mm); omitted on the last surface.
    #[serde(default)]
    pub thickness_mm: Option<LengthMm>,
    /// The glass after the surface (a catalogue name or a constant index); omitted = air.
    #[serde(default)]
    pub glass: Option<String>,
}

/// A plane-parallel absorptive filter (ND glass).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, expecting = "struct variant ElementSpec::Filter")]
pub struct FilterSpec {
    /// Unique name.
    pub name: String,
    /// Catalogue part number (informational).
    #[serde(default)]
    pub part: Option<String>,
    /// Centre of the first face (mm).
    pub position_mm: Mm3,
    /// Face normal, in the direction of light travel (the filter extends along it).
    pub axis: Direction,
    /// Direction of the outline's width for rectangles.
    #[serde(default)]
    pub x_axis: Option<Direction>,
    /// Outline.
    pub outline: Outline,
    /// Thickness (mm).
    pub thickness_mm: LengthMm,
    /// Substrate glass (name or constant index), for refraction and Fresnel reflection.
    pub glass: String,
    /// Internal optical density through the full thickness at normal incidence (excluding
    /// surface reflections, which are traced); a ray's bulk transmittance is 10^(−OD·L/t)
    /// for path length L.
    pub od: SpectrumSpec,
    /// Coating of both faces.
    #[serde(default)]
    pub coating: CoatingSpec,
    /// Alignment tilt (degrees) about local x then y.
    #[serde(default)]
    pub tilt_deg: Option<(TiltDeg, TiltDeg)>,
}

/// A black annular aperture (iris) in a plane.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(
    deny_unknown_fields,
    expecting = "struct variant ElementSpec::Aperture"
)]
pub struct ApertureSpec {
    /// Unique name.
    pub name: String,
    /// Centre (mm).
    pub position_mm: Mm3,
    /// Plane normal.
    pub axis: Direction,
    /// Hole diameter (mm).
    pub inner_diameter_mm: LengthMm,
    /// Outer diameter of the black annulus (mm).
    pub outer_diameter_mm: LengthMm,
}

/// A black tube (lens tube, lamp housing): the side of a cylinder, analytic (every lamp ray
/// starts inside the lamp housing, where a faceted mesh is the slowest thing to trace).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, expecting = "struct variant ElementSpec::Tube")]
pub struct TubeSpec {
    /// Unique name.
    pub name: String,
    /// Centre of the tube's start (mm).
    pub position_mm: Mm3,
    /// Tube axis (the tube runs from `position_mm` along it).
    pub axis: Direction,
    /// Inner diameter (mm).
    pub diameter_mm: LengthMm,
    /// Length (mm).
    pub length_mm: LengthMm,
}

/// A black plate with a circular hole (baffle, field stop) as a triangle mesh (obvhs).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, expecting = "struct variant ElementSpec::Baffle")]
pub struct BaffleSpec {
    /// Unique name.
    pub name: String,
    /// Centre of the hole (mm).
    pub position_mm: Mm3,
    /// Plate normal.
    pub axis: Direction,
    /// Direction of the plate's width.
    #[serde(default)]
    pub x_axis: Option<Direction>,
    /// Plate width (mm), along `x_axis`.
    pub width_mm: LengthMm,
    /// Plate height (mm).
    pub height_mm: LengthMm,
    /// Hole diameter (mm).
    pub hole_diameter_mm: LengthMm,
    /// Sides of the hole's polygon (default 64).
    #[serde(default = "default_segments")]
    pub segments: Segments,
}

/// A flat front-surface mirror (black behind).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, expecting = "struct variant ElementSpec::Mirror")]
pub struct MirrorSpec {
    /// Unique name.
    pub name: String,
    /// Catalogue part number (informational).
    #[serde(default)]
    pub part: Option<String>,
    /// Centre of the reflecting face (mm).
    pub position_mm: Mm3,
    /// Normal of the reflecting face (pointing out of the mirror).
    pub normal: Direction,
    /// Direction of the outline's width.
    #[serde(default)]
    pub x_axis: Option<Direction>,
    /// Outline of the reflecting face.
    pub outline: Outline,
    /// Reflectance R(λ).
    pub reflectance: SpectrumSpec,
    /// Substrate thickness behind the face (mm; only used to detect overlaps). Default 6.
    #[serde(default = "default_mirror_thickness")]
    pub thickness_mm: LengthMm,
    /// Alignment tilt (degrees) about local x then y.
    #[serde(default)]
    pub tilt_deg: Option<(TiltDeg, TiltDeg)>,
}

/// A chart plate: chrome pattern on a glass substrate.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, expecting = "struct variant ElementSpec::Chart")]
pub struct ChartSpec {
    /// Unique name.
    pub name: String,
    /// Catalogue part number (informational).
    #[serde(default)]
    pub part: Option<String>,
    /// Where the chart point `center_on` lies, on the chrome face (mm).
    pub position_mm: Mm3,
    /// Normal of the chrome face pointing into the substrate.
    pub normal: Direction,
    /// Direction of the chart's +x axis (projected onto its plane).
    #[serde(default)]
    pub x_axis: Option<Direction>,
    /// Plate width and height (mm).
    pub plate_mm: (Positive, Positive),
    /// Substrate thickness (mm).
    pub thickness_mm: LengthMm,
    /// Substrate glass.
    pub glass: String,
    /// What is printed.
    pub pattern: ChartPatternSpec,
    /// Which chart point sits at `position_mm`. Default: the plate centre.
    #[serde(default)]
    pub center_on: Option<CenterOnSpec>,
    /// Optical density of the chrome (default 3, docs/bench-facts.md §5.3).
    #[serde(default = "default_chrome_od")]
    pub chrome_od: SpectrumSpec,
    /// Reflectance of the chrome (default 0.1: low-reflectivity chrome, estimate).
    #[serde(default = "default_chrome_reflectance")]
    pub chrome_reflectance: SpectrumSpec,
    /// Alignment tilt (degrees) about local x then y.
    #[serde(default)]
    pub tilt_deg: Option<(TiltDeg, TiltDeg)>,
}

impl ElementSpec {
    /// The element's unique `name`.
    pub fn name(&self) -> &str {
        match self {
            ElementSpec::Lens(LensSpec { name, .. })
            | ElementSpec::LensSystem(LensSystemSpec { name, .. })
            | ElementSpec::Filter(FilterSpec { name, .. })
            | ElementSpec::Aperture(ApertureSpec { name, .. })
            | ElementSpec::Tube(TubeSpec { name, .. })
            | ElementSpec::Baffle(BaffleSpec { name, .. })
            | ElementSpec::Mirror(MirrorSpec { name, .. })
            | ElementSpec::Chart(ChartSpec { name, .. }) => name,
        }
    }
}

fn default_segments() -> Segments {
    Segments::new(64)
}

fn default_mirror_thickness() -> LengthMm {
    LengthMm(6.0)
}

fn default_chrome_od() -> SpectrumSpec {
    SpectrumSpec::Constant(Finite(3.0))
}

fn default_chrome_reflectance() -> SpectrumSpec {
    SpectrumSpec::Constant(Finite(0.1))
}

/// What is printed on a chart.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum ChartPatternSpec {
    /// The 1951 USAF chart of groups `min_group..=max_group` (crate::objects::usaf), negative
    /// (clear bars in chrome, as the paper's Thorlabs R3L3S1N) unless `positive` is true.
    Usaf {
        /// Smallest group printed.
        min_group: UsafGroup,
        /// Largest group printed.
        max_group: UsafGroup,
        /// Chrome bars on clear glass instead of clear bars in chrome.
        #[serde(default)]
        positive: bool,
    },
    /// A PNG image as a transmittance mask (grey level / max = clear fraction), of the given
    /// physical size, centred on the plate centre; `path` is relative to the bench file.
    Image {
        /// The PNG, relative to the bench file.
        path: String,
        /// Its physical width on the plate (mm).
        width_mm: LengthMm,
        /// Its physical height on the plate (mm).
        height_mm: LengthMm,
    },
    /// No chrome: a plain glass plate.
    Clear,
}

/// A chart point, in chart millimetres from the plate centre.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum CenterOnSpec {
    /// A point (x, y) of the chart, in chart millimetres from the plate centre.
    Point((CoordMm, CoordMm)),
    /// The centre of the bounding box of USAF elements `first..=last` of `group`.
    Elements {
        /// The USAF group.
        group: UsafGroup,
        /// Its first element.
        first: UsafElement,
        /// Its last element.
        last: UsafElement,
    },
}

/// The DMD (TI DLP7000 class by default values in the paper bench).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DmdSpec {
    /// Mirror columns (along +x).
    pub columns: MirrorCount,
    /// Mirror rows (along −y).
    pub rows: MirrorCount,
    /// Mirror pitch (µm).
    pub pitch_um: Positive,
    /// Mirror area / cell area (mirror side = pitch·√fill).
    pub fill_factor: UnitFraction,
    /// Landed tilt angle (degrees); state + is +tilt about the hinge axis.
    pub tilt_deg: AngleDeg,
    /// Hinge axis angle from +x toward +y (degrees); 45 = the mirror diagonal.
    #[serde(default = "default_hinge")]
    pub tilt_axis_deg: DirectionDeg,
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
    /// How the mirrors reflect: `Geometric`, plane mirrors, or `Diffractive(...)`, the array as
    /// a blazed grating (docs/dmd_diffraction.md). A bench without the field is geometric, as it
    /// always was; the shipped paper bench states `Diffractive(...)`, the DMD as built.
    #[serde(default, skip_serializing_if = "DmdModelSpec::is_geometric")]
    pub model: DmdModelSpec,
}

/// How the DMD's mirrors reflect (docs/dmd_diffraction.md).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum DmdModelSpec {
    /// Each mirror reflects specularly (geometric optics).
    #[default]
    Geometric,
    /// The array is a two-dimensional grating: each ray that meets a mirror leaves in one
    /// diffraction order drawn with the order's efficiency. `tail_bin_nm`: the wavelength bin of
    /// the tables of the orders far from the blaze peak (default 10 nm); the orders near the
    /// peak are computed exactly for every ray.
    Diffractive {
        /// Wavelength bin (nm) of the tables of the orders far from the blaze peak.
        #[serde(default = "default_tail_bin")]
        tail_bin_nm: Positive,
    },
}

impl DmdModelSpec {
    pub fn is_geometric(&self) -> bool {
        matches!(self, DmdModelSpec::Geometric)
    }

    /// `Diffractive()`: the diffractive model with its default tail bin.
    pub fn diffractive() -> DmdModelSpec {
        DmdModelSpec::Diffractive {
            tail_bin_nm: default_tail_bin(),
        }
    }
}

fn default_tail_bin() -> Positive {
    Positive(10.0)
}

fn default_hinge() -> DirectionDeg {
    DirectionDeg(45.0)
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
    pub origin: (MirrorIndex, MirrorIndex),
    /// Units across (columns).
    pub units_across: MirrorCount,
    /// Units down (rows).
    pub units_down: MirrorCount,
    /// Mirrors per unit side (a unit is n × n mirrors).
    pub mirrors_per_unit: MirrorCount,
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
