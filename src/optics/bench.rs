//! The validated optical bench in SI units: the lamp, media, analytic surfaces, meshes, the DMD
//! and the two photodiodes, plus the names that the flux ledger uses.
//!
//! A `Bench` is built by `crate::scene::bench` from a scene file (or directly in code) through
//! the builder functions here, which check the geometry they are given and return a message for
//! the caller to attach to a field. The tracer assumes a `Bench` is consistent.

use glam::DVec3;

use super::chart::ChartMask;
use super::dmd::{Dmd, MirrorState};
use super::geometry::{Frame, Geometry, Shape2D, sag};
use super::glass::Glass;
use super::guide::ChartGuide;
use super::lamp::{Lamp, SpectralSampler};
use super::mesh::Mesh;
use super::spectrum::Spectrum;

pub type MediumId = usize;
pub type ElementId = usize;

/// The medium every bench starts with (id 0): air.
pub const AIR_MEDIUM: MediumId = 0;

/// A homogeneous medium: its index model and optional bulk absorption.
#[derive(Debug, Clone)]
pub struct Medium {
    pub glass: Glass,
    /// Internal optical density per metre of path, OD(λ)/m; the absorbed power is booked to
    /// `element`.
    pub absorption: Option<(Spectrum, ElementId)>,
}

/// The optical treatment of an interface.
#[derive(Debug, Clone, PartialEq)]
pub enum Coating {
    /// Bare Fresnel reflection.
    None,
    /// One homogeneous layer (e.g. quarter-wave MgF2) between the two media.
    SingleLayer { layer: Glass, thickness_m: f64 },
    /// A fixed reflectance R(λ) at any angle, T = 1 − R (a measured or specified coating curve
    /// when its design is unknown; the angle dependence is ignored).
    Reflectance(Spectrum),
}

impl Coating {
    /// Unpolarised power reflectance from index n1 into n2 at incidence cosine `cos_i`.
    #[inline]
    pub fn reflectance(&self, n1: f64, n2: f64, cos_i: f64, wavelength_m: f64) -> f64 {
        use super::fresnel;
        match self {
            Coating::None => fresnel::reflectance(n1, n2, cos_i),
            Coating::SingleLayer { layer, thickness_m } => fresnel::single_layer_reflectance(
                n1,
                layer.index(wavelength_m),
                n2,
                *thickness_m,
                wavelength_m,
                cos_i,
            ),
            Coating::Reflectance(r) => {
                // Total internal reflection still applies.
                let s2 = (n1 / n2).powi(2) * (1.0 - cos_i * cos_i);
                if s2 >= 1.0 {
                    1.0
                } else {
                    r.at(wavelength_m).clamp(0.0, 1.0)
                }
            }
        }
    }

    /// A quarter-wave MgF2 layer for `design_wavelength_m` (thickness λ₀ / (4 n_MgF2(λ₀))).
    pub fn quarter_wave_mgf2(design_wavelength_m: f64) -> Coating {
        let layer = super::glass::MGF2;
        let n = layer.index(design_wavelength_m);
        Coating::SingleLayer {
            layer,
            thickness_m: design_wavelength_m / (4.0 * n),
        }
    }
}

/// What happens to light at a surface.
#[derive(Debug, Clone)]
pub enum Interaction {
    /// A boundary between two media: Fresnel (or coating) reflection and refraction. `front` is
    /// the medium on the normal's side.
    Interface {
        front: MediumId,
        back: MediumId,
        coating: Coating,
    },
    /// A black surface: everything is absorbed.
    Absorber,
    /// A front-surface mirror, reflective on the normal's side, black behind.
    Mirror { reflectance: Spectrum },
    /// The active area of the photodiode of arm `arm`, sensitive on the normal's side; its
    /// housing behind.
    Detector { arm: super::Arm },
    /// The chrome face of chart plate `chart`: clear glass (an interface) where the mask is
    /// clear, chrome elsewhere. `front` is the medium on the normal's side.
    Chart {
        chart: usize,
        front: MediumId,
        back: MediumId,
    },
}

/// One analytic surface of the bench.
#[derive(Debug, Clone)]
pub struct Surface {
    pub geometry: Geometry,
    pub interaction: Interaction,
    pub element: ElementId,
    /// Light hitting the surface farther than this from its axis is absorbed (a lens face
    /// beyond its clear aperture, covered by the mount).
    pub clear: Option<ClearAperture>,
}

/// A clear aperture around an axis through `point` along `axis`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClearAperture {
    pub point: DVec3,
    pub axis: DVec3,
    pub radius: f64,
}

impl ClearAperture {
    #[inline]
    pub fn blocks(&self, p: DVec3) -> bool {
        let q = p - self.point;
        let along = q.dot(self.axis);
        q.length_squared() - along * along > self.radius * self.radius
    }
}

impl Surface {
    pub fn new(geometry: Geometry, interaction: Interaction, element: ElementId) -> Surface {
        Surface {
            geometry,
            interaction,
            element,
            clear: None,
        }
    }
}

/// What the nearest-hit search found: surface i (with its geometric normal), mesh k, or the
/// DMD's slab.
#[derive(Debug, Clone, Copy)]
pub enum Target {
    Surface(usize, DVec3),
    Mesh(usize),
    Dmd,
}

/// What a leaf of the bench's BVH holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Prim {
    Surface(usize),
    Mesh(usize),
    Dmd,
}

/// A BVH (obvhs `Bvh2`, uncompressed f32 boxes) over every analytic surface, mesh and the DMD
/// slab: the tracer's nearest-hit search. Boxes are padded by 1 µm so that f32 rounding of the
/// ray and the boxes can never drop a candidate; the intersections themselves are exact f64.
/// (obvhs's compressed `CwBvh` was tried first and missed hits on µm-thin boxes, such as a flat
/// face, for rays starting next to them; `Bvh2` has no such quantisation, and a brute-force
/// oracle test guards the search.)
pub struct Accel {
    pub bvh: obvhs::bvh2::Bvh2,
    /// Primitive of BVH slot i (already reordered by `primitive_indices`).
    pub prims: Vec<Prim>,
}

impl std::fmt::Debug for Accel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Accel({} primitives)", self.prims.len())
    }
}

impl Clone for Accel {
    fn clone(&self) -> Self {
        Accel {
            bvh: self.bvh.clone(),
            prims: self.prims.clone(),
        }
    }
}

struct BoxedPrim(obvhs::aabb::Aabb);

impl obvhs::Boundable for BoxedPrim {
    fn aabb(&self) -> obvhs::aabb::Aabb {
        self.0
    }
}

impl Accel {
    pub fn new(surfaces: &[Surface], meshes: &[(Mesh, ElementId)], dmd: Option<&Dmd>) -> Accel {
        use glam::Vec3A;
        let pad = 1e-6;
        let to_box = |lo: DVec3, hi: DVec3| {
            let lo = lo - DVec3::splat(pad);
            let hi = hi + DVec3::splat(pad);
            obvhs::aabb::Aabb::new(
                Vec3A::new(lo.x as f32, lo.y as f32, lo.z as f32),
                Vec3A::new(hi.x as f32, hi.y as f32, hi.z as f32),
            )
        };
        let mut prims = Vec::new();
        let mut boxes = Vec::new();
        for (i, s) in surfaces.iter().enumerate() {
            let (lo, hi) = s.geometry.aabb();
            prims.push(Prim::Surface(i));
            boxes.push(BoxedPrim(to_box(lo, hi)));
        }
        for (k, (m, _)) in meshes.iter().enumerate() {
            let (lo, hi) = m.aabb();
            prims.push(Prim::Mesh(k));
            boxes.push(BoxedPrim(to_box(lo, hi)));
        }
        if let Some(d) = dmd {
            let (hx, hy) = d.half_size();
            let h = d.slab_half_height();
            prims.push(Prim::Dmd);
            boxes.push(BoxedPrim(to_box(
                DVec3::new(-hx, -hy, -h),
                DVec3::new(hx, hy, h),
            )));
        }
        let bvh = obvhs::bvh2::builder::build_bvh2(
            &boxes,
            obvhs::BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        let prims = bvh
            .primitive_indices
            .iter()
            .map(|&i| prims[i as usize])
            .collect();
        Accel { bvh, prims }
    }
}

/// A chart plate's chrome: its mask, the frame of the chrome face (origin at the plate centre,
/// w into the substrate), and the chrome's optical density and reflectance.
#[derive(Debug, Clone)]
pub struct ChartPlate {
    pub mask: ChartMask,
    pub frame: Frame,
    pub chrome_od: Spectrum,
    pub chrome_reflectance: Spectrum,
}

/// One photodiode of the balanced detector.
#[derive(Debug, Clone)]
pub struct Photodiode {
    /// Centre of the active area; w = the direction the diode faces (toward incoming light).
    pub frame: Frame,
    pub radius: f64,
    /// Responsivity ℜ(λ) in A/W (external quantum efficiency, so light reflected by the diode
    /// surface is already counted as lost; that reflected light is not traced further).
    pub responsivity: Spectrum,
    /// Ambient irradiance on the diode (W/m²) and the current it makes (A).
    pub ambient_w_per_m2: f64,
    pub ambient_current_a: f64,
    pub dark_current_a: f64,
}

impl Photodiode {
    pub fn area(&self) -> f64 {
        std::f64::consts::PI * self.radius * self.radius
    }
}

/// The wavelength range used to turn ambient irradiance into current: room light is visible
/// light, so the ambient current uses the mean responsivity over 400–700 nm (flat weighting;
/// for the default Si table this is 0.311 A/W).
pub const AMBIENT_BAND_M: (f64, f64) = (400e-9, 700e-9);

/// Mean responsivity over [`AMBIENT_BAND_M`] (A/W).
pub fn ambient_responsivity(responsivity: &Spectrum) -> f64 {
    let (a, b) = AMBIENT_BAND_M;
    responsivity.integrate(a, b, 600) / (b - a)
}

/// The DMD with the ledger elements of its parts.
#[derive(Debug, Clone)]
pub struct DmdSetup {
    pub dmd: Dmd,
    /// Light absorbed by the aluminium (1 − R).
    pub mirrors_element: ElementId,
    /// Light that falls between mirrors.
    pub gaps_element: ElementId,
    /// The package around and behind the array (light from behind ends there).
    pub package_element: ElementId,
}

/// The validated bench.
///
/// A `Bench` is built once, by [`Bench::assemble`], and never changed: its fields are private
/// and read through methods. Everything derived from its parts — the nearest-hit search
/// structure (BVH), the spectral sampler and the lamp's chart guide — is made by the
/// constructor from those parts, so a bench whose part moved (a new bench, built from an edited
/// [`crate::scene::doc::BenchDoc`]) can never keep a stale one.
#[derive(Debug, Clone)]
pub struct Bench {
    band: (f64, f64),
    lamp: Lamp,
    sampler: SpectralSampler,
    media: Vec<Medium>,
    surfaces: Vec<Surface>,
    accel: Accel,
    meshes: Vec<(Mesh, ElementId)>,
    dmd: Option<DmdSetup>,
    detectors: [Photodiode; 2],
    charts: Vec<ChartPlate>,
    elements: Vec<String>,
    lamp_housing: ElementId,
    max_interactions: u32,
    /// Internal optical densities of the absorbing filters (for the spectral sampler).
    filter_ods: Vec<Spectrum>,
    guide: Option<GuideRequest>,
}

/// The chart guide a bench asks for (crate::optics::guide): which chart, what share of the
/// field-target rays, and the region of the chart (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuideRequest {
    pub chart: usize,
    pub share: f64,
    pub region_m: (f64, f64),
}

/// The parts of a bench, from which [`Bench::assemble`] derives the rest.
#[derive(Debug, Clone)]
pub struct Assembly {
    /// Traced wavelength band (m).
    pub band: (f64, f64),
    /// The lamp (its `guide` is ignored: the guide is fitted from `guide`).
    pub lamp: Lamp,
    pub parts: BenchParts,
    pub dmd: Option<DmdSetup>,
    /// [arm +, arm −].
    pub detectors: [Photodiode; 2],
    /// The element charged with the lamp's emission outside the traced cone.
    pub lamp_housing: ElementId,
    /// Interactions after which a path is abandoned (booked as "path cap").
    pub max_interactions: u32,
    /// Internal optical densities of the absorbing filters, for wavelength sampling.
    pub filter_ods: Vec<Spectrum>,
    pub guide: Option<GuideRequest>,
}

impl Bench {
    /// The one constructor: derives the BVH, the spectral sampler (lamp spectrum × mean diode
    /// responsivity × filter transmittance) and the chart guide from the parts. Fails only when
    /// the guide cannot be fitted (the message says why).
    pub fn assemble(a: Assembly) -> std::result::Result<Bench, String> {
        let Assembly {
            band,
            mut lamp,
            parts,
            dmd,
            detectors,
            lamp_housing,
            max_interactions,
            filter_ods,
            guide,
        } = a;
        lamp.guide = None;
        let resp =
            |l: f64| 0.5 * (detectors[0].responsivity.at(l) + detectors[1].responsivity.at(l));
        let throughput = |l: f64| {
            filter_ods
                .iter()
                .map(|od| 10f64.powf(-od.at(l)))
                .product::<f64>()
        };
        let sampler = SpectralSampler::new(&lamp.spectrum, band, resp, throughput);
        let accel = Accel::new(&parts.surfaces, &parts.meshes, dmd.as_ref().map(|d| &d.dmd));
        let mut bench = Bench {
            band,
            lamp,
            sampler,
            media: parts.media,
            surfaces: parts.surfaces,
            accel,
            meshes: parts.meshes,
            dmd,
            detectors,
            charts: parts.charts,
            elements: parts.elements,
            lamp_housing,
            max_interactions,
            filter_ods,
            guide,
        };
        if let Some(g) = guide {
            // The guide is fitted to design rays traced through this very bench.
            let fitted = ChartGuide::fit(&bench, g.chart, g.share, g.region_m)?;
            bench.lamp.guide = Some(fitted);
        }
        Ok(bench)
    }

    /// The parts this bench was assembled from, to assemble a variant (the guide is refitted).
    pub fn into_assembly(self) -> Assembly {
        Assembly {
            band: self.band,
            lamp: self.lamp,
            parts: BenchParts {
                media: self.media,
                surfaces: self.surfaces,
                meshes: self.meshes,
                charts: self.charts,
                elements: self.elements,
            },
            dmd: self.dmd,
            detectors: self.detectors,
            lamp_housing: self.lamp_housing,
            max_interactions: self.max_interactions,
            filter_ods: self.filter_ods,
            guide: self.guide,
        }
    }

    /// Traced wavelength band (m).
    pub fn band(&self) -> (f64, f64) {
        self.band
    }

    pub fn lamp(&self) -> &Lamp {
        &self.lamp
    }

    pub fn sampler(&self) -> &SpectralSampler {
        &self.sampler
    }

    pub fn media(&self) -> &[Medium] {
        &self.media
    }

    pub fn surfaces(&self) -> &[Surface] {
        &self.surfaces
    }

    pub fn meshes(&self) -> &[(Mesh, ElementId)] {
        &self.meshes
    }

    pub fn dmd(&self) -> Option<&DmdSetup> {
        self.dmd.as_ref()
    }

    /// The same bench with its DMD reflecting geometrically (a copy of itself when it already
    /// does): the reference of the diffractive model's comparison.
    pub fn with_geometric_dmd(&self) -> Bench {
        let mut b = self.clone();
        if let Some(s) = &mut b.dmd {
            s.dmd = s.dmd.geometric();
        }
        b
    }

    /// [arm +, arm −].
    pub fn detectors(&self) -> &[Photodiode; 2] {
        &self.detectors
    }

    pub fn charts(&self) -> &[ChartPlate] {
        &self.charts
    }

    /// Ledger names, indexed by element id.
    pub fn elements(&self) -> &[String] {
        &self.elements
    }

    /// The element charged with the lamp's emission outside the traced cone.
    pub fn lamp_housing(&self) -> ElementId {
        self.lamp_housing
    }

    /// Interactions after which a path is abandoned (booked as "path cap").
    pub fn max_interactions(&self) -> u32 {
        self.max_interactions
    }
}

impl Bench {
    pub fn units(&self) -> usize {
        self.dmd.as_ref().map_or(0, |d| d.dmd.pattern.units())
    }

    pub fn units_shape(&self) -> (usize, usize) {
        self.dmd.as_ref().map_or((0, 0), |d| {
            (d.dmd.pattern.units_across, d.dmd.pattern.units_down)
        })
    }

    /// The nearest primitive hit by the ray (o, unit d) beyond t = 0: its distance and what it is.
    #[inline]
    pub fn nearest(&self, o: DVec3, d: DVec3) -> (f64, Option<Target>) {
        let bench = self;
        let mut best = f64::INFINITY;
        let mut target = None;
        let accel = &bench.accel;
        let mut hit = obvhs::ray::RayHit::none();
        let ray = crate::optics::mesh::bvh_ray(o, d, f64::INFINITY);
        accel.bvh.ray_traverse(ray, &mut hit, |_, slot| {
            match accel.prims[slot] {
                Prim::Surface(i) => {
                    if let Some(h) = bench.surfaces[i].geometry.intersect(o, d, 0.0, best) {
                        best = h.t;
                        target = Some(Target::Surface(i, h.normal));
                    }
                }
                Prim::Mesh(k) => {
                    if let Some(t) = bench.meshes[k].0.intersect(o, d, 0.0, best)
                        && t < best
                    {
                        best = t;
                        target = Some(Target::Mesh(k));
                    }
                }
                Prim::Dmd => {
                    if let Some(dmd) = &bench.dmd
                        && let Some(t) = dmd.dmd.slab_entry(o, d, 0.0)
                        && t < best
                    {
                        best = t;
                        target = Some(Target::Dmd);
                    }
                }
            }
            // Tell the traversal an f32 distance no smaller than the exact best, so that no box
            // that could hold a closer hit is pruned by rounding.
            if best.is_finite() {
                (best * (1.0 + 1e-6) + 1e-6) as f32
            } else {
                f32::INFINITY
            }
        });
        (best, target)
    }
}

/// Assembles a bench: hands out element and medium ids and collects surfaces.
#[derive(Debug, Clone, Default)]
pub struct BenchParts {
    pub media: Vec<Medium>,
    pub surfaces: Vec<Surface>,
    pub meshes: Vec<(Mesh, ElementId)>,
    pub charts: Vec<ChartPlate>,
    pub elements: Vec<String>,
}

impl BenchParts {
    pub fn new() -> BenchParts {
        BenchParts {
            media: vec![Medium {
                glass: super::glass::AIR,
                absorption: None,
            }],
            ..Default::default()
        }
    }

    /// A ledger element; names are unique (the same name returns the same id).
    pub fn element(&mut self, name: &str) -> ElementId {
        if let Some(i) = self.elements.iter().position(|e| e == name) {
            return i;
        }
        self.elements.push(name.to_string());
        self.elements.len() - 1
    }

    pub fn medium(&mut self, glass: Glass, absorption: Option<(Spectrum, ElementId)>) -> MediumId {
        self.media.push(Medium { glass, absorption });
        self.media.len() - 1
    }

    pub fn surface(&mut self, geometry: Geometry, interaction: Interaction, element: ElementId) {
        self.surfaces
            .push(Surface::new(geometry, interaction, element));
    }

    /// A lens of `glass` whose first vertex is at `frame.origin`, light travelling along
    /// `frame.w`; radii are signed (positive: centre of curvature after the surface), `None` is
    /// flat. `radius` is the mechanical semi-diameter and `clear` the clear semi-aperture (the
    /// ring beyond it is covered by the mount: black). Errors name the offending quantity.
    #[allow(clippy::too_many_arguments)]
    pub fn lens(
        &mut self,
        element: ElementId,
        frame: &Frame,
        front_radius: Option<f64>,
        back_radius: Option<f64>,
        thickness: f64,
        radius: f64,
        clear: f64,
        glass: Glass,
        coating: Coating,
    ) -> Result<(), LensError> {
        check_lens(front_radius, back_radius, thickness, radius, clear)?;
        let m = self.medium(glass, None);
        let w = frame.w;
        let o = frame.origin;
        let back_vertex = o + thickness * w;
        for (vertex, r, before, after) in [
            (o, front_radius, AIR_MEDIUM, m),
            (back_vertex, back_radius, m, AIR_MEDIUM),
        ] {
            let interaction = Interaction::Interface {
                front: before,
                back: after,
                coating: coating.clone(),
            };
            let geometry = match r {
                Some(r) => Geometry::SphereCap {
                    vertex,
                    axis: w,
                    radius: r,
                    aperture: radius,
                    inner: 0.0,
                },
                None => Geometry::Plane {
                    frame: Frame {
                        origin: vertex,
                        u: frame.u,
                        v: -frame.v,
                        w: -w,
                    },
                    shape: Shape2D::Disk { radius },
                },
            };
            let mut surface = Surface::new(geometry, interaction, element);
            if clear < radius {
                // The ring outside the clear aperture is under the retaining ring: black.
                surface.clear = Some(ClearAperture {
                    point: vertex,
                    axis: w,
                    radius: clear,
                });
            }
            self.surfaces.push(surface);
        }
        // The ground (blackened) edge between the two faces.
        let z1 = front_radius.map_or(0.0, |r| sag(r, radius));
        let z2 = thickness + back_radius.map_or(0.0, |r| sag(r, radius));
        self.surface(
            Geometry::Cylinder {
                base: o + z1 * w,
                axis: w,
                radius,
                length: z2 - z1,
            },
            Interaction::Absorber,
            element,
        );
        Ok(())
    }

    /// A plane-parallel plate of `medium` from `frame.origin` to `frame.origin + thickness·w`
    /// with outline `shape` (Disk or Rect), faces of the given coating and black edges.
    pub fn slab(
        &mut self,
        element: ElementId,
        frame: &Frame,
        shape: Shape2D,
        thickness: f64,
        medium: MediumId,
        coating: Coating,
    ) {
        let w = frame.w;
        let first = Frame {
            origin: frame.origin,
            u: frame.u,
            v: -frame.v,
            w: -w,
        };
        let second = Frame {
            origin: frame.origin + thickness * w,
            ..first
        };
        for (f, before, after) in [(first, AIR_MEDIUM, medium), (second, medium, AIR_MEDIUM)] {
            self.surface(
                Geometry::Plane { frame: f, shape },
                Interaction::Interface {
                    front: before,
                    back: after,
                    coating: coating.clone(),
                },
                element,
            );
        }
        self.slab_edges(element, frame, shape, thickness);
    }

    /// Black edges of a plate of outline `shape` and `thickness` along frame.w.
    pub fn slab_edges(
        &mut self,
        element: ElementId,
        frame: &Frame,
        shape: Shape2D,
        thickness: f64,
    ) {
        match shape {
            Shape2D::Disk { radius } => self.surface(
                Geometry::Cylinder {
                    base: frame.origin,
                    axis: frame.w,
                    radius,
                    length: thickness,
                },
                Interaction::Absorber,
                element,
            ),
            Shape2D::Rect { half_u, half_v } => {
                let mid = frame.origin + 0.5 * thickness * frame.w;
                for (n, half_n, t, half_t) in [
                    (frame.u, half_u, frame.v, half_v),
                    (-frame.u, half_u, frame.v, half_v),
                    (frame.v, half_v, frame.u, half_u),
                    (-frame.v, half_v, frame.u, half_u),
                ] {
                    let f = Frame {
                        origin: mid + half_n * n,
                        u: t,
                        v: n.cross(t),
                        w: n,
                    };
                    self.surface(
                        Geometry::Plane {
                            frame: f,
                            shape: Shape2D::Rect {
                                half_u: half_t,
                                half_v: 0.5 * thickness,
                            },
                        },
                        Interaction::Absorber,
                        element,
                    );
                }
            }
            _ => {}
        }
    }
}

/// Why a lens cannot exist.
#[derive(Debug, Clone, PartialEq)]
pub enum LensError {
    /// A radius of curvature smaller than the lens's semi-diameter (the sphere cannot reach the
    /// rim): (which surface: 0 front, 1 back, message).
    Radius(usize, String),
    /// Centre or edge thickness not positive.
    Thickness(String),
    /// Diameter or clear aperture not positive or inconsistent.
    Diameter(String),
}

/// Checks a lens's numbers: |R| must exceed the semi-diameter, and both the centre and the edge
/// thickness must be positive (edge = t + sag₂(r) − sag₁(r)).
pub fn check_lens(
    front_radius: Option<f64>,
    back_radius: Option<f64>,
    thickness: f64,
    radius: f64,
    clear: f64,
) -> Result<(), LensError> {
    if !(radius > 0.0 && radius.is_finite()) {
        return Err(LensError::Diameter(format!(
            "the diameter must be positive, got {} mm",
            2e3 * radius
        )));
    }
    if !(clear > 0.0 && clear <= radius) {
        return Err(LensError::Diameter(format!(
            "the clear diameter ({} mm) must be positive and at most the diameter ({} mm)",
            2e3 * clear,
            2e3 * radius
        )));
    }
    for (i, r) in [front_radius, back_radius].into_iter().enumerate() {
        if let Some(r) = r
            && (!(r.is_finite() && r != 0.0) || r.abs() <= radius)
        {
            return Err(LensError::Radius(
                i,
                format!(
                    "a radius of curvature of {} mm cannot span a {} mm diameter \
                     (|R| must exceed the semi-diameter {} mm)",
                    1e3 * r,
                    2e3 * radius,
                    1e3 * radius
                ),
            ));
        }
    }
    if !(thickness > 0.0 && thickness.is_finite()) {
        return Err(LensError::Thickness(format!(
            "the centre thickness must be positive, got {} mm",
            1e3 * thickness
        )));
    }
    let z1 = front_radius.map_or(0.0, |r| sag(r, radius));
    let z2 = thickness + back_radius.map_or(0.0, |r| sag(r, radius));
    if z2 - z1 <= 0.0 {
        return Err(LensError::Thickness(format!(
            "the faces cross before the rim: with these radii a {} mm diameter needs a centre \
             thickness above {:.3} mm (edge thickness would be {:.3} mm)",
            2e3 * radius,
            1e3 * (thickness - (z2 - z1)),
            1e3 * (z2 - z1)
        )));
    }
    Ok(())
}

/// The paraxial focal length and back focal length of a thick lens in air (index n, signed radii
/// with None = flat, centre thickness t), from the lensmaker's equation:
/// 1/f = (n − 1)[1/R1 − 1/R2 + (n − 1) t/(n R1 R2)], BFL = f·(1 − (n − 1) t/(n R1)).
pub fn thick_lens(n: f64, r1: Option<f64>, r2: Option<f64>, t: f64) -> (f64, f64) {
    let c1 = r1.map_or(0.0, |r| 1.0 / r);
    let c2 = r2.map_or(0.0, |r| 1.0 / r);
    let power = (n - 1.0) * (c1 - c2 + (n - 1.0) * t * c1 * c2 / n);
    let f = 1.0 / power;
    (f, f * (1.0 - (n - 1.0) * t * c1 / n))
}

/// A convex solid used to detect overlapping elements: a cylinder or a box.
#[derive(Debug, Clone, Copy)]
pub enum Solid {
    /// Axis from `frame.origin` along `frame.w` over [0, length], radius `radius`.
    Cylinder {
        frame: Frame,
        radius: f64,
        length: f64,
    },
    /// Centred on frame.origin with half extents along u, v, w.
    Box { frame: Frame, half: DVec3 },
}

impl Solid {
    /// Strictly inside, with a margin (m) that forgives touching faces.
    fn contains(&self, p: DVec3, margin: f64) -> bool {
        match *self {
            Solid::Cylinder {
                frame,
                radius,
                length,
            } => {
                let l = frame.to_local(p);
                l.z > margin && l.z < length - margin && l.x.hypot(l.y) < radius - margin
            }
            Solid::Box { frame, half } => {
                let l = frame.to_local(p);
                l.x.abs() < half.x - margin
                    && l.y.abs() < half.y - margin
                    && l.z.abs() < half.z - margin
            }
        }
    }

    /// Points on the surface and inside of the solid (a deterministic lattice).
    fn samples(&self) -> Vec<DVec3> {
        let mut v = Vec::new();
        match *self {
            Solid::Cylinder {
                frame,
                radius,
                length,
            } => {
                for k in 0..=8 {
                    let z = length * k as f64 / 8.0;
                    v.push(frame.to_world(DVec3::new(0.0, 0.0, z)));
                    for ring in 1..=4 {
                        let r = radius * ring as f64 / 4.0;
                        for a in 0..48 {
                            let phi = std::f64::consts::TAU * a as f64 / 48.0;
                            v.push(frame.to_world(DVec3::new(r * phi.cos(), r * phi.sin(), z)));
                        }
                    }
                }
            }
            Solid::Box { frame, half } => {
                let n = 10;
                for i in 0..=n {
                    for j in 0..=n {
                        for k in 0..=n {
                            let f = |q: usize| 2.0 * q as f64 / n as f64 - 1.0;
                            v.push(frame.to_world(DVec3::new(
                                f(i) * half.x,
                                f(j) * half.y,
                                f(k) * half.z,
                            )));
                        }
                    }
                }
            }
        }
        v
    }

    fn bounding_sphere(&self) -> (DVec3, f64) {
        match *self {
            Solid::Cylinder {
                frame,
                radius,
                length,
            } => (
                frame.origin + 0.5 * length * frame.w,
                radius.hypot(0.5 * length),
            ),
            Solid::Box { frame, half } => (frame.origin, half.length()),
        }
    }

    /// True if the two solids share volume (beyond a 1 µm margin): a point lattice of each is
    /// tested against the other. Sound for the bench's plates, lenses and boxes, whose overlaps
    /// when they happen are large compared with the lattice spacing.
    pub fn overlaps(&self, other: &Solid) -> bool {
        let (c1, r1) = self.bounding_sphere();
        let (c2, r2) = other.bounding_sphere();
        if (c1 - c2).length() >= r1 + r2 {
            return false;
        }
        let margin = 1e-6;
        self.samples().iter().any(|&p| other.contains(p, margin))
            || other.samples().iter().any(|&p| self.contains(p, margin))
    }
}

/// The mirror state used by traces that set the pattern area explicitly.
pub fn state_of_bit(bit: bool) -> MirrorState {
    MirrorState::from_bit(bit)
}

#[cfg(test)]
mod tests;
