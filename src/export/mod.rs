//! Export of a bench as a Mitsuba 3 scene (mitsuba==3.9.1), built in memory: `scene.xml`, one
//! binary PLY per optical surface (plus one for every black absorber and one for the DMD), a
//! float bitmap (PFM) per chart mask, and `manifest.json` with what an external forward tracer
//! needs (lamp frame, emission cone, power, the photodiodes). Pure: no file IO; the CLI writes
//! the files (src/cli/export.rs).
//!
//! The exporter writes exactly the surfaces spibench traces: it walks [`Bench::surfaces`],
//! [`Bench::meshes`] and the DMD and maps each interaction onto one Mitsuba BSDF:
//!
//! | spibench | Mitsuba |
//! |---|---|
//! | interface between media n₁ (normal side) and n₂ | `dielectric`, `ext_ior` n₁, `int_ior` n₂ (none when n₁ = n₂) |
//! | black surface, lens rim, mount, housing, DMD gaps | `diffuse` of reflectance 0 |
//! | mirror (front surface) and DMD facets | `conductor`, `material: none`, `specular_reflectance` R |
//! | chart mask | `mask` with opacity 1 − T from a bitmap (nearest, raw), black behind |
//! | photodiode | `disk` with a black BSDF and an `irradiancemeter` |
//! | lamp filament | `rectangle`/`disk` with an `area` emitter of radiance Φ/(π·A), black BSDF |
//!
//! One difference is left: spibench's filament is transparent to light coming back to it, the
//! exported one absorbs it (Mitsuba's `path` integrator finds no emission on an emitter with a
//! `null` BSDF). Light that returns onto the 2 mm filament and would then still reach a
//! photodiode is far below the validation's resolution.
//!
//! Only a monochromatic, constant-index bench can be exported (Mitsuba has no dispersion, no
//! thin films, no absorbing dielectric, no refracting mask): pass a bench through
//! [`crate::optics::monochromatic::monochromatic`] first; [`export_mitsuba`] refuses anything
//! else with a message that names the element.
//!
//! Geometry (docs/mitsuba.md): scene units are millimetres (Mitsuba offsets every spawned ray by
//! about (1 + max|p|)·8.9e-5 scene units, 0.09 µm near the DMD at the origin); spherical caps are
//! meshes of [`CAP_RINGS`] rings × [`SEGMENTS`] segments with exact vertex normals (chord sag
//! error below 0.5 µm for the benches here), circles are polygons of [`SEGMENTS`] sides whose
//! radius is scaled to keep the circle's area; the DMD is one mesh of two triangles per facet,
//! each facet in its pattern state, over a black substrate below the tilted mirrors.

pub mod pattern;

use std::fmt::Write as _;

use glam::DVec3;
use serde_json::json;

use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::optics::bench::{Coating, DmdSetup, Interaction, Surface, state_of_bit};
use crate::optics::chart::ChartMask;
use crate::optics::dmd::MirrorState;
use crate::optics::geometry::{Frame, Geometry, Shape2D, sag};
use crate::optics::glass::Glass;
use crate::optics::lamp::{EmitterShape, LampSpectrum};
use crate::optics::spectrum::Spectrum;

pub use pattern::DmdPattern;

/// Sides of every circle polygon and azimuthal segments of every cap.
pub const SEGMENTS: usize = 256;
/// Radial rings of a spherical cap.
pub const CAP_RINGS: usize = 48;

/// Metres to scene millimetres.
const MM: f64 = 1e3;

/// An exported scene: files (relative path, bytes) and notes for the user.
#[derive(Debug, Clone)]
pub struct MitsubaScene {
    pub files: Vec<(String, Vec<u8>)>,
    /// What the export could not represent exactly, one sentence each.
    pub notes: Vec<String>,
}

/// Export options.
#[derive(Debug, Clone)]
pub struct ExportOptions {
    /// State of every pattern unit (true = +), row-major; must have `bench.units()` entries.
    pub pattern: Vec<bool>,
    /// A label for the pattern (written to the manifest).
    pub pattern_label: String,
    /// The monochromatic wavelength of the substitute (m), for the manifest; None if the bench
    /// was exported as it is.
    pub wavelength_m: Option<f64>,
    /// Samples per pixel of the two irradiancemeters (for Mitsuba's own `path` integrator).
    pub sensor_samples: u32,
    /// Keep the lamp's thermal spectrum and the diodes' responsivity tables (written to the
    /// manifest for a spectral render: Mitsuba's `blackbody` emitter and a `specfilm` with the
    /// responsivity as its response). Glasses must still have constant indices.
    pub spectral: bool,
}

/// A triangle soup in scene millimetres, optionally with vertex normals.
#[derive(Debug, Default, Clone)]
struct Soup {
    v: Vec<[f32; 3]>,
    n: Vec<[f32; 3]>,
    f: Vec<[u32; 3]>,
}

impl Soup {
    fn vertex(&mut self, p: DVec3, normal: Option<DVec3>) -> u32 {
        let q = p * MM;
        self.v.push([q.x as f32, q.y as f32, q.z as f32]);
        if let Some(n) = normal {
            let n = n.normalize();
            self.n.push([n.x as f32, n.y as f32, n.z as f32]);
        }
        (self.v.len() - 1) as u32
    }

    fn tri(&mut self, a: u32, b: u32, c: u32) {
        self.f.push([a, b, c]);
    }

    /// A planar quadrilateral (corners in order around it) as two triangles, without normals.
    fn quad(&mut self, corners: [DVec3; 4]) {
        let [a, b, c, d] = corners.map(|p| self.vertex(p, None));
        self.tri(a, b, c);
        self.tri(a, c, d);
    }

    fn append(&mut self, other: &Soup) {
        let base = self.v.len() as u32;
        self.v.extend_from_slice(&other.v);
        self.f.extend(
            other
                .f
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    fn is_empty(&self) -> bool {
        self.f.is_empty()
    }

    /// Binary little-endian PLY (normals only if every vertex has one).
    fn ply(&self) -> Vec<u8> {
        let normals = !self.n.is_empty() && self.n.len() == self.v.len();
        let mut h = String::from("ply\nformat binary_little_endian 1.0\n");
        let _ = writeln!(h, "element vertex {}", self.v.len());
        h.push_str("property float x\nproperty float y\nproperty float z\n");
        if normals {
            h.push_str("property float nx\nproperty float ny\nproperty float nz\n");
        }
        let _ = writeln!(h, "element face {}", self.f.len());
        h.push_str("property list uchar int vertex_indices\nend_header\n");
        let mut out = h.into_bytes();
        for (i, v) in self.v.iter().enumerate() {
            for c in v {
                out.extend_from_slice(&c.to_le_bytes());
            }
            if normals {
                for c in &self.n[i] {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
        }
        for t in &self.f {
            out.push(3);
            for &i in t {
                out.extend_from_slice(&(i as i32).to_le_bytes());
            }
        }
        out
    }
}

/// The radius of a regular polygon of `n` sides with the area of the circle of radius `r`.
fn area_preserving(r: f64, n: usize) -> f64 {
    let a = std::f64::consts::TAU / n as f64;
    r * (a / a.sin()).sqrt()
}

/// A planar outline triangulated counter-clockwise in (u, v), so the normal is `frame.w`.
fn plane_soup(frame: &Frame, shape: Shape2D) -> Soup {
    let mut s = Soup::default();
    let at = |x: f64, y: f64| frame.origin + x * frame.u + y * frame.v;
    let n = SEGMENTS;
    let ring = |r: f64, k: usize| {
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        (r * a.cos(), r * a.sin())
    };
    match shape {
        Shape2D::Disk { radius } => {
            let r = area_preserving(radius, n);
            let c = s.vertex(at(0.0, 0.0), None);
            let first = s.v.len() as u32;
            for k in 0..n {
                let (x, y) = ring(r, k);
                s.vertex(at(x, y), None);
            }
            for k in 0..n as u32 {
                s.tri(c, first + k, first + (k + 1) % n as u32);
            }
        }
        Shape2D::Annulus { inner, outer } => {
            let (ri, ro) = (area_preserving(inner, n), area_preserving(outer, n));
            strip(
                &mut s,
                n,
                |k| at(ring(ri, k).0, ring(ri, k).1),
                |k| at(ring(ro, k).0, ring(ro, k).1),
            );
        }
        Shape2D::Rect { half_u, half_v } => {
            s.quad([
                at(-half_u, -half_v),
                at(half_u, -half_v),
                at(half_u, half_v),
                at(-half_u, half_v),
            ]);
        }
        Shape2D::RectWithRectHole {
            half_u,
            half_v,
            hole_u,
            hole_v,
        } => {
            let outer = [
                (-half_u, -half_v),
                (half_u, -half_v),
                (half_u, half_v),
                (-half_u, half_v),
            ];
            let inner = [
                (-hole_u, -hole_v),
                (hole_u, -hole_v),
                (hole_u, hole_v),
                (-hole_u, hole_v),
            ];
            strip(
                &mut s,
                4,
                |k| at(inner[k].0, inner[k].1),
                |k| at(outer[k].0, outer[k].1),
            );
        }
        Shape2D::RectWithHole {
            half_u,
            half_v,
            hole,
        } => {
            // Wedges from the hole polygon out to the rectangle, with the rectangle's corners
            // inserted in the wedges that contain them.
            let r = area_preserving(hole, n);
            let to_rect = |k: usize| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                let (c, si) = (a.cos(), a.sin());
                let t = (half_u / c.abs().max(1e-300)).min(half_v / si.abs().max(1e-300));
                (t * c, t * si)
            };
            let corners = [
                (half_u, half_v),
                (-half_u, half_v),
                (-half_u, -half_v),
                (half_u, -half_v),
            ];
            for k in 0..n {
                let a0 = std::f64::consts::TAU * k as f64 / n as f64;
                let a1 = std::f64::consts::TAU * (k + 1) as f64 / n as f64;
                let (i0, i1) = (ring(r, k), ring(r, k + 1));
                let (o0, o1) = (to_rect(k), to_rect(k + 1));
                let ia = s.vertex(at(i0.0, i0.1), None);
                let ib = s.vertex(at(i1.0, i1.1), None);
                let oa = s.vertex(at(o0.0, o0.1), None);
                let ob = s.vertex(at(o1.0, o1.1), None);
                let corner = corners.iter().find(|c| {
                    let a = c.1.atan2(c.0).rem_euclid(std::f64::consts::TAU);
                    a > a0 && a < a1
                });
                match corner {
                    Some(c) => {
                        let cv = s.vertex(at(c.0, c.1), None);
                        s.tri(ia, oa, cv);
                        s.tri(ia, cv, ob);
                    }
                    None => s.tri(ia, oa, ob),
                }
                s.tri(ia, ob, ib);
            }
        }
    }
    s
}

/// Quads between an inner and an outer closed chain of `n` points (counter-clockwise).
fn strip(s: &mut Soup, n: usize, inner: impl Fn(usize) -> DVec3, outer: impl Fn(usize) -> DVec3) {
    let first = s.v.len() as u32;
    for k in 0..n {
        s.vertex(inner(k), None);
        s.vertex(outer(k), None);
    }
    for k in 0..n as u32 {
        let (i0, o0) = (first + 2 * k, first + 2 * k + 1);
        let k1 = (k + 1) % n as u32;
        let (i1, o1) = (first + 2 * k1, first + 2 * k1 + 1);
        s.tri(i0, o0, o1);
        s.tri(i0, o1, i1);
    }
}

/// A spherical cap between `rho0` and `rho1` from the axis, with exact vertex normals
/// (p − centre)/R and the winding that agrees with them.
fn cap_soup(vertex: DVec3, axis: DVec3, radius: f64, rho0: f64, rho1: f64) -> Soup {
    let mut s = Soup::default();
    // e1 × e2 = −axis: counter-clockwise in (e1, e2) faces −axis, the normal at the vertex.
    let f = Frame::new(vertex, -axis, None);
    let (e1, e2) = (f.u, f.v);
    let centre = vertex + radius * axis;
    let n = SEGMENTS;
    let scale = area_preserving(1.0, n);
    let point = |rho: f64, k: usize| {
        let rho = (rho * scale).min(radius.abs() * (1.0 - 1e-12));
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        vertex + sag(radius, rho) * axis + rho * (a.cos() * e1 + a.sin() * e2)
    };
    let normal = |p: DVec3| (p - centre) / radius;
    let rings = ((CAP_RINGS as f64 * (rho1 - rho0) / rho1).ceil() as usize).max(2);
    let mut prev: Option<u32> = None;
    let mut start = 0;
    if rho0 <= 0.0 {
        let c = s.vertex(vertex, Some(normal(vertex)));
        prev = Some(c);
        start = 1;
    }
    let mut prev_ring: Option<u32> = None;
    for i in start..=rings {
        let rho = rho0 + (rho1 - rho0) * i as f64 / rings as f64;
        let first = s.v.len() as u32;
        for k in 0..n {
            let p = point(rho, k);
            s.vertex(p, Some(normal(p)));
        }
        let nn = n as u32;
        match (prev_ring, prev) {
            (Some(pr), _) => {
                for k in 0..nn {
                    let k1 = (k + 1) % nn;
                    s.tri(pr + k, first + k, first + k1);
                    s.tri(pr + k, first + k1, pr + k1);
                }
            }
            (None, Some(c)) => {
                for k in 0..nn {
                    s.tri(c, first + k, first + (k + 1) % nn);
                }
            }
            (None, None) => {}
        }
        prev_ring = Some(first);
    }
    s
}

/// The side of a cylinder (black: its winding does not matter).
fn cylinder_soup(base: DVec3, axis: DVec3, radius: f64, length: f64) -> Soup {
    let f = Frame::new(base, axis, None);
    let r = area_preserving(radius, SEGMENTS);
    let ring = |k: usize, h: f64| {
        let a = std::f64::consts::TAU * k as f64 / SEGMENTS as f64;
        base + h * axis + r * (a.cos() * f.u + a.sin() * f.v)
    };
    let mut s = Soup::default();
    strip(&mut s, SEGMENTS, |k| ring(k, 0.0), |k| ring(k, length));
    s
}

fn geometry_soup(g: &Geometry, rho_range: Option<(f64, f64)>) -> Soup {
    match g {
        Geometry::Plane { frame, shape } => plane_soup(frame, *shape),
        Geometry::SphereCap {
            vertex,
            axis,
            radius,
            aperture,
            inner,
        } => {
            let (a, b) = rho_range.unwrap_or((*inner, *aperture));
            cap_soup(*vertex, *axis, *radius, a, b)
        }
        Geometry::Cylinder {
            base,
            axis,
            radius,
            length,
        } => cylinder_soup(*base, *axis, *radius, *length),
    }
}

fn fmt(v: f64) -> String {
    format!("{v:.9e}")
}

fn matrix(cols: [DVec3; 3], origin: DVec3) -> String {
    let o = origin * MM;
    let rows = [
        [cols[0].x, cols[1].x, cols[2].x, o.x],
        [cols[0].y, cols[1].y, cols[2].y, o.y],
        [cols[0].z, cols[1].z, cols[2].z, o.z],
        [0.0, 0.0, 0.0, 1.0],
    ];
    rows.iter()
        .flat_map(|r| r.iter().map(|&x| fmt(x)))
        .collect::<Vec<_>>()
        .join(" ")
}

const BLACK: &str = r#"<bsdf type="diffuse"><float name="reflectance" value="0"/></bsdf>"#;

/// A refusal: the bench has something Mitsuba cannot represent.
fn unrepresentable(what: String) -> Error {
    Error::input(format!(
        "{what}; Mitsuba 3 cannot represent it: export the monochromatic substitute \
         (`wavelength_nm`)"
    ))
}

fn constant_index(bench: &Bench, m: usize, el: &str) -> Result<f64> {
    let medium = &bench.media()[m];
    if medium.absorption.is_some() {
        return Err(unrepresentable(format!("`{el}` absorbs in its bulk")));
    }
    match medium.glass {
        Glass::Constant(n) => Ok(n),
        Glass::Sellmeier { .. } => Err(unrepresentable(format!("`{el}` has a dispersive glass"))),
    }
}

fn constant(s: &Spectrum, what: String) -> Result<f64> {
    match s {
        Spectrum::Constant(v) => Ok(*v),
        Spectrum::Table(_) => Err(unrepresentable(format!("{what} varies with wavelength"))),
    }
}

/// Exports a monochromatic, constant-index bench (see the module notes).
pub fn export_mitsuba(bench: &Bench, opts: &ExportOptions) -> Result<MitsubaScene> {
    if bench.dmd().is_some() && opts.pattern.len() != bench.units() {
        return Err(Error::field(
            "pattern",
            format!(
                "a pattern of {} units for a DMD pattern area of {} units",
                opts.pattern.len(),
                bench.units()
            ),
        ));
    }
    let notes: Vec<String> = Vec::new();
    let depth = bench.max_interactions() + 1;
    let mut w = SceneWriter::new(depth);
    for s in bench.surfaces() {
        w.surface(bench, opts, s)?;
    }
    w.meshes(bench);
    if let Some(setup) = &bench.dmd() {
        w.dmd(setup, opts)?;
    }
    if !w.black.is_empty() {
        let black = std::mem::take(&mut w.black);
        w.add_mesh("absorbers", &black, BLACK);
    }
    let lamp_json = w.lamp(bench, opts)?;
    let manifest = json!({
        "generator": format!("spibench {} export-mitsuba", env!("CARGO_PKG_VERSION")),
        "mitsuba_version": "3.9.1",
        "units": "millimetres; powers in W",
        "wavelength_nm": opts.wavelength_m.map(|w| w * 1e9),
        "pattern": opts.pattern_label,
        "pattern_units": opts.pattern.len(),
        "max_depth": depth,
        "lamp": lamp_json,
        "band_nm": [bench.band().0 * 1e9, bench.band().1 * 1e9],
        "detectors": w.detectors_json,
    });
    let mut files = w.files;
    files.push(("scene.xml".into(), w.xml.into_bytes()));
    files.push((
        "manifest.json".into(),
        serde_json::to_string_pretty(&manifest)
            .map_err(|e| Error::Numerical(e.to_string()))?
            .into_bytes(),
    ));
    Ok(MitsubaScene { files, notes })
}

/// The scene as it is written: `scene.xml`, the files beside it, the black surfaces gathered
/// into one mesh (written last), and the detectors for the manifest.
struct SceneWriter {
    xml: String,
    files: Vec<(String, Vec<u8>)>,
    black: Soup,
    shape_index: usize,
    detectors_json: Vec<serde_json::Value>,
    charts_done: Vec<usize>,
}

/// A `dielectric` BSDF between indices `n1` (normal side) and `n2`.
fn dielectric(n1: f64, n2: f64) -> String {
    format!(
        "<bsdf type=\"dielectric\"><float name=\"ext_ior\" value=\"{}\"/>\
         <float name=\"int_ior\" value=\"{}\"/></bsdf>",
        fmt(n1),
        fmt(n2)
    )
}

/// A front-surface mirror BSDF of reflectance `r`.
fn conductor(r: f64) -> String {
    format!(
        "<bsdf type=\"conductor\"><string name=\"material\" value=\"none\"/>\
         <float name=\"specular_reflectance\" value=\"{}\"/></bsdf>",
        fmt(r)
    )
}

/// A surface with a clear aperture, as its clear part and the ring outside it (None without
/// a clear aperture, or for a geometry that has no ring).
fn clear_split(s: &Surface) -> Option<(Soup, Soup)> {
    let c = s.clear?;
    match &s.geometry {
        Geometry::SphereCap {
            vertex,
            axis,
            radius,
            aperture,
            inner,
        } => Some((
            cap_soup(*vertex, *axis, *radius, *inner, c.radius.max(*inner)),
            cap_soup(*vertex, *axis, *radius, c.radius.max(*inner), *aperture),
        )),
        Geometry::Plane {
            frame,
            shape: Shape2D::Disk { radius },
        } => Some((
            plane_soup(frame, Shape2D::Disk { radius: c.radius }),
            plane_soup(
                frame,
                Shape2D::Annulus {
                    inner: c.radius,
                    outer: *radius,
                },
            ),
        )),
        _ => None,
    }
}

impl SceneWriter {
    /// Starts `scene.xml` with the integrator (path depth `depth`).
    fn new(depth: u32) -> Self {
        let mut xml = String::new();
        let _ = writeln!(
            xml,
            "<?xml version=\"1.0\"?>\n<!-- spibench export: millimetres; powers in W. -->\n\
             <scene version=\"3.0.0\">\n  <integrator type=\"path\">\n    \
             <integer name=\"max_depth\" value=\"{depth}\"/>\n    \
             <integer name=\"rr_depth\" value=\"{depth}\"/>\n  </integrator>"
        );
        SceneWriter {
            xml,
            files: Vec::new(),
            black: Soup::default(),
            shape_index: 0,
            detectors_json: Vec::new(),
            charts_done: Vec::new(),
        }
    }

    /// Writes `soup` as the next PLY shape with the BSDF `bsdf`.
    fn add_mesh(&mut self, id: &str, soup: &Soup, bsdf: &str) {
        let shape_index = self.shape_index;
        let file = format!("meshes/{shape_index:03}_{id}.ply");
        let _ = writeln!(
            self.xml,
            "  <shape type=\"ply\" id=\"s{shape_index:03}_{id}\">\n    \
             <string name=\"filename\" value=\"{file}\"/>\n    {bsdf}\n  </shape>"
        );
        self.files.push((file, soup.ply()));
        self.shape_index += 1;
    }

    /// One traced surface, by its interaction.
    fn surface(&mut self, bench: &Bench, opts: &ExportOptions, s: &Surface) -> Result<()> {
        let el = bench.elements()[s.element].replace(|c: char| !c.is_ascii_alphanumeric(), "_");
        match &s.interaction {
            Interaction::Absorber => self.black.append(&geometry_soup(&s.geometry, None)),
            Interaction::Interface {
                front,
                back,
                coating,
            } => {
                if *coating != Coating::None {
                    return Err(unrepresentable(format!(
                        "`{el}` has a thin-film or fixed-R coating"
                    )));
                }
                let n1 = constant_index(bench, *front, &el)?;
                let n2 = constant_index(bench, *back, &el)?;
                let (clear, ring) = match clear_split(s) {
                    Some((a, b)) => (a, Some(b)),
                    None => (geometry_soup(&s.geometry, None), None),
                };
                if let Some(ring) = ring {
                    self.black.append(&ring);
                }
                if n1 != n2 {
                    self.add_mesh(&el, &clear, &dielectric(n1, n2));
                }
            }
            Interaction::Mirror { reflectance } => {
                let r = constant(reflectance, format!("the reflectance of `{el}`"))?;
                let (face, ring) = match clear_split(s) {
                    Some((a, b)) => (a, Some(b)),
                    None => (geometry_soup(&s.geometry, None), None),
                };
                if let Some(ring) = ring {
                    self.black.append(&ring);
                }
                self.add_mesh(&el, &face, &conductor(r));
            }
            Interaction::Detector { arm } => self.detector(bench, opts, arm.index(), &el)?,
            Interaction::Chart { chart, front, back } => {
                self.chart(bench, s, *chart, (*front, *back), &el)?
            }
        }
        Ok(())
    }

    /// A photodiode: a black disk with an irradiancemeter, and its manifest entry.
    fn detector(
        &mut self,
        bench: &Bench,
        opts: &ExportOptions,
        index: usize,
        el: &str,
    ) -> Result<()> {
        let det = &bench.detectors()[index];
        if !opts.spectral {
            constant(&det.responsivity, format!("the responsivity of `{el}`"))?;
        }
        let (b0, b1) = (bench.band().0 * 1e9, bench.band().1 * 1e9);
        let table: Vec<[f64; 2]> = if opts.spectral {
            let n = (b1 - b0).round().max(1.0) as usize;
            (0..=n)
                .map(|k| {
                    let nm = b0 + (b1 - b0) * k as f64 / n as f64;
                    [nm, det.responsivity.at(nm * 1e-9)]
                })
                .collect()
        } else {
            Vec::new()
        };
        let f = det.frame;
        let r = det.radius * MM;
        let id = if index == 0 { "pd_plus" } else { "pd_minus" };
        let _ = writeln!(
            self.xml,
            "  <shape type=\"disk\" id=\"{id}\">\n    <transform name=\"to_world\">\
             <matrix value=\"{}\"/></transform>\n    {BLACK}\n    \
             <sensor type=\"irradiancemeter\">\n      \
             <sampler type=\"independent\"><integer name=\"sample_count\" value=\"{}\"/>\
             <integer name=\"seed\" value=\"{}\"/></sampler>\n      \
             <film type=\"hdrfilm\"><integer name=\"width\" value=\"1\"/>\
             <integer name=\"height\" value=\"1\"/><rfilter type=\"box\"/></film>\n    \
             </sensor>\n  </shape>",
            matrix([f.u * r, f.v * r, f.w], f.origin),
            opts.sensor_samples,
            index + 1
        );
        self.detectors_json.push(json!({
            "id": id,
            "index": index,
            "center_mm": [f.origin.x * MM, f.origin.y * MM, f.origin.z * MM],
            "normal": [f.w.x, f.w.y, f.w.z],
            "radius_mm": r,
            "area_mm2": std::f64::consts::PI * r * r,
            "responsivity_a_per_w": det.responsivity.at(bench.band().0),
            "responsivity_table_nm_a_per_w": table,
        }));
        Ok(())
    }

    /// The chrome face of a chart plate: a plain dielectric when nothing is printed, else the
    /// image as a mask and the chrome around it.
    fn chart(
        &mut self,
        bench: &Bench,
        s: &Surface,
        chart: usize,
        (front, back): (usize, usize),
        el: &str,
    ) -> Result<()> {
        let n1 = constant_index(bench, front, el)?;
        let n2 = constant_index(bench, back, el)?;
        let plate = &bench.charts()[chart];
        let Geometry::Plane {
            frame: face,
            shape: Shape2D::Rect { half_u, half_v },
        } = s.geometry
        else {
            return Err(Error::input(format!(
                "`{el}`: a chart face must be a rectangle"
            )));
        };
        if matches!(plate.mask, ChartMask::Clear) {
            if n1 != n2 {
                self.add_mesh(el, &geometry_soup(&s.geometry, None), &dielectric(n1, n2));
            }
            return Ok(());
        }
        if n1 != n2 {
            return Err(unrepresentable(format!(
                "`{el}`: a printed chart on a refracting substrate"
            )));
        }
        let rc = constant(
            &plate.chrome_reflectance,
            format!("the chrome reflectance of `{el}`"),
        )?;
        if rc != 0.0 {
            return Err(unrepresentable(format!("`{el}`: chrome that reflects")));
        }
        let tc = 10f64.powf(-constant(
            &plate.chrome_od,
            format!("the chrome OD of `{el}`"),
        )?);
        let ChartMask::Image {
            raster,
            width_m,
            height_m,
        } = &plate.mask
        else {
            return Err(unrepresentable(format!("`{el}`: an analytic USAF pattern")));
        };
        // The image in the chart face plane: its centre and half sizes in the face's
        // (u, v) coordinates (the face frame is the plate frame with v and w reversed).
        let pf = plate.frame;
        let c = face.to_local(pf.origin);
        let (hw, hh) = (0.5 * width_m, 0.5 * height_m);
        if c.x.abs() + hw > half_u * (1.0 + 1e-9) || c.y.abs() + hh > half_v * (1.0 + 1e-9) {
            return Err(Error::input(format!(
                "`{el}`: the chart image extends beyond the plate"
            )));
        }
        self.chart_image(chart, raster, tc, &pf, (hw, hh), el);
        // The plate outside the image: four strips of constant opacity 1 − T.
        let bounds = (c.x - hw, c.x + hw, c.y - hh, c.y + hh);
        let rest = chrome_strips(&face, (half_u, half_v), bounds);
        if !rest.is_empty() {
            let bsdf = format!(
                "<bsdf type=\"mask\"><float name=\"opacity\" value=\"{}\"/>{BLACK}</bsdf>",
                fmt(1.0 - tc)
            );
            self.add_mesh(&format!("{el}_chrome"), &rest, &bsdf);
        }
        Ok(())
    }

    /// A chart's image as a `mask` rectangle of opacity 1 − (c + (1 − c)·T) read from a PFM
    /// bitmap (`tc`: the chrome's transmittance T; half sizes `(hw, hh)` in metres).
    fn chart_image(
        &mut self,
        chart: usize,
        raster: &crate::raster::Raster,
        tc: f64,
        pf: &Frame,
        (hw, hh): (f64, f64),
        el: &str,
    ) {
        // Opacity 1 − (c + (1 − c)·T). Mitsuba flips a PFM on loading (PFM stores the bottom
        // scanline first) and maps its bitmap row 0 to local −y, so the file's first scanline
        // lands at local +y: spibench's raster row 0 (the top, +v) is written first. Checked in
        // validation/mitsuba (the chart case disagrees by 35 % with the rows reversed).
        let (w, h) = (raster.width, raster.height);
        let mut pfm = format!("Pf\n{w} {h}\n-1.0\n").into_bytes();
        for r in 0..h {
            for col in 0..w {
                let clear = raster.get(r, col).clamp(0.0, 1.0);
                let opacity = 1.0 - (clear + (1.0 - clear) * tc);
                pfm.extend_from_slice(&(opacity as f32).to_le_bytes());
            }
        }
        let k = self.charts_done.len();
        self.charts_done.push(chart);
        let bitmap = format!("charts/chart{k}.pfm");
        self.files.push((bitmap.clone(), pfm));
        let axis_w = pf.u.cross(pf.v);
        let _ = writeln!(
            self.xml,
            "  <shape type=\"rectangle\" id=\"{el}_mask\">\n    <transform name=\"to_world\">\
             <matrix value=\"{}\"/></transform>\n    <bsdf type=\"mask\">\n      \
             <texture name=\"opacity\" type=\"bitmap\"><string name=\"filename\" value=\"{bitmap}\"/>\
             <boolean name=\"raw\" value=\"true\"/><string name=\"filter_type\" value=\"nearest\"/>\
             <string name=\"wrap_mode\" value=\"clamp\"/></texture>\n      {BLACK}\n    </bsdf>\n  </shape>",
            matrix([pf.u * (hw * MM), pf.v * (hh * MM), axis_w], pf.origin)
        );
    }

    /// The triangle meshes (baffles), black.
    fn meshes(&mut self, bench: &Bench) {
        for (m, _) in bench.meshes() {
            let mut soup = Soup::default();
            for t in m.triangles() {
                let p = |v: glam::Vec3A| DVec3::new(v.x as f64, v.y as f64, v.z as f64);
                let a = soup.vertex(p(t.v0), None);
                let b = soup.vertex(p(t.v1), None);
                let c = soup.vertex(p(t.v2), None);
                soup.tri(a, b, c);
            }
            self.black.append(&soup);
        }
    }

    /// The DMD: one mesh of every facet in its pattern state, over a black substrate.
    fn dmd(&mut self, setup: &DmdSetup, opts: &ExportOptions) -> Result<()> {
        let d = &setup.dmd;
        let r = constant(&d.reflectance, "the DMD mirror reflectance".into())?;
        let mut soup = Soup::default();
        let half = 0.5 * d.side;
        let rots = [
            d.rotation(MirrorState::Plus),
            d.rotation(MirrorState::Minus),
            d.rotation(MirrorState::Flat),
        ];
        for row in 0..d.rows {
            for col in 0..d.columns {
                let state = match d.pattern.unit_of(col, row) {
                    Some(j) => state_of_bit(opts.pattern[j]),
                    None => d.outside,
                };
                let rot = rots[crate::optics::dmd::state_index(state)];
                let c0 = d.mirror_center(col, row);
                let corner = |x: f64, y: f64| c0 + rot * DVec3::new(x, y, 0.0);
                soup.quad([
                    corner(-half, -half),
                    corner(half, -half),
                    corner(half, half),
                    corner(-half, half),
                ]);
            }
        }
        self.add_mesh("dmd_mirrors", &soup, &conductor(r));
        // The substrate below the tilted mirrors: light that falls between them is absorbed,
        // as in spibench (DmdHit::Gap).
        let (hx, hy) = d.half_size();
        let z = -2.0 * d.slab_half_height();
        self.black.append(&plane_soup(
            &Frame::new(DVec3::new(0.0, 0.0, z), DVec3::Z, Some(DVec3::X)),
            Shape2D::Rect {
                half_u: hx,
                half_v: hy,
            },
        ));
        Ok(())
    }

    /// The lamp's filament as an area emitter (closing `scene.xml`); returns its manifest
    /// entry.
    fn lamp(&mut self, bench: &Bench, opts: &ExportOptions) -> Result<serde_json::Value> {
        let lamp = &bench.lamp();
        let f = lamp.frame;
        let area_mm2 = lamp.shape.area() * MM * MM;
        let radiance = lamp.band_power_w / (std::f64::consts::PI * area_mm2);
        let (shape_xml, shape_json) = match lamp.shape {
            EmitterShape::Rect { half_u, half_v } => (
                format!(
                    "<shape type=\"rectangle\" id=\"lamp\">\n    <transform name=\"to_world\">\
                     <matrix value=\"{}\"/></transform>",
                    matrix([f.u * (half_u * MM), f.v * (half_v * MM), f.w], f.origin)
                ),
                json!({"type": "rect", "half_u_mm": half_u * MM, "half_v_mm": half_v * MM}),
            ),
            EmitterShape::Disk { radius } => (
                format!(
                    "<shape type=\"disk\" id=\"lamp\">\n    <transform name=\"to_world\">\
                     <matrix value=\"{}\"/></transform>",
                    matrix([f.u * (radius * MM), f.v * (radius * MM), f.w], f.origin)
                ),
                json!({"type": "disk", "radius_mm": radius * MM}),
            ),
        };
        let _ = writeln!(
            self.xml,
            "  {shape_xml}\n    {BLACK}\n    <emitter type=\"area\">\
             <float name=\"radiance\" value=\"{}\"/></emitter>\n  </shape>\n</scene>",
            fmt(radiance)
        );
        let spectrum_json = match (&lamp.spectrum, opts.spectral) {
            (_, false) => json!({"kind": "monochromatic"}),
            (
                LampSpectrum::Graybody {
                    temperature_k,
                    emissivity,
                },
                true,
            ) => {
                json!({"kind": "graybody", "temperature_k": temperature_k, "emissivity": emissivity})
            }
            (_, true) => {
                return Err(unrepresentable(
                    "the lamp spectrum is not a graybody (Mitsuba's blackbody times a constant)"
                        .into(),
                ));
            }
        };
        Ok(json!({
            "origin_mm": [f.origin.x * MM, f.origin.y * MM, f.origin.z * MM],
            "u": [f.u.x, f.u.y, f.u.z],
            "v": [f.v.x, f.v.y, f.v.z],
            "w": [f.w.x, f.w.y, f.w.z],
            "shape": shape_json,
            "power_w": lamp.band_power_w,
            "radiance_w_per_mm2_sr": radiance,
            "sin2_max": lamp.sin2_max,
            "spectrum": spectrum_json,
        }))
    }
}

/// The chrome of a chart face outside its image: up to four rectangles (below, above, left and
/// right of the image) of the plate `(half_u, half_v)`, the image spanning `(x0, x1, y0, y1)`
/// in face coordinates.
fn chrome_strips(face: &Frame, (half_u, half_v): (f64, f64), bounds: (f64, f64, f64, f64)) -> Soup {
    let (x0, x1, y0, y1) = bounds;
    let mut rest = Soup::default();
    let at = |x: f64, y: f64| face.origin + x * face.u + y * face.v;
    for (a, b, cc, d) in [
        (
            (-half_u, -half_v),
            (half_u, -half_v),
            (half_u, y0),
            (-half_u, y0),
        ),
        (
            (-half_u, y1),
            (half_u, y1),
            (half_u, half_v),
            (-half_u, half_v),
        ),
        ((-half_u, y0), (x0, y0), (x0, y1), (-half_u, y1)),
        ((x1, y0), (half_u, y0), (half_u, y1), (x1, y1)),
    ] {
        if (b.0 - a.0) <= 0.0 || (cc.1 - b.1) <= 0.0 {
            continue;
        }
        let i = rest.vertex(at(a.0, a.1), None);
        let j = rest.vertex(at(b.0, b.1), None);
        let l = rest.vertex(at(cc.0, cc.1), None);
        let m = rest.vertex(at(d.0, d.1), None);
        rest.tri(i, j, l);
        rest.tri(i, l, m);
    }
    rest
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Signed area of a triangle soup projected on the xy plane (positive counter-clockwise).
    fn signed_area_z(s: &Soup) -> f64 {
        let p = |i: u32| {
            let v = s.v[i as usize];
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        s.f.iter()
            .map(|t| 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).z)
            .sum()
    }

    #[test]
    fn polygons_keep_the_circle_area() {
        let f = Frame::new(DVec3::ZERO, DVec3::Z, None);
        let s = plane_soup(&f, Shape2D::Disk { radius: 1.0 });
        let area = signed_area_z(&s);
        // Counter-clockwise (normal +z) and the area of the unit circle in mm² (1 m = 1000 mm),
        // to f32 rounding of the vertices.
        let exact = std::f64::consts::PI * 1e6;
        assert!((area - exact).abs() < 1e-5 * exact, "{area}");
    }

    #[test]
    fn rect_with_hole_covers_the_rect_minus_the_hole() {
        let f = Frame::new(DVec3::ZERO, DVec3::Z, None);
        let s = plane_soup(
            &f,
            Shape2D::RectWithHole {
                half_u: 0.04,
                half_v: 0.03,
                hole: 0.01,
            },
        );
        let area = signed_area_z(&s);
        let exact = (0.08 * 0.06 - std::f64::consts::PI * 1e-4) * 1e6;
        assert!((area - exact).abs() < 1e-5 * exact, "{area} vs {exact}");
    }

    #[test]
    fn cap_normals_agree_with_the_winding() {
        for r in [0.05, -0.05] {
            let s = cap_soup(DVec3::new(0.0, 0.0, 0.1), DVec3::Z, r, 0.0, 0.02);
            for t in &s.f {
                let p = |i: u32| {
                    let v = s.v[i as usize];
                    DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
                };
                let geo = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
                let n = s.n[t[0] as usize];
                let n = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
                assert!(geo.dot(n) > 0.0);
            }
        }
    }
}
