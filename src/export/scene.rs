//! The scene writer: `scene.xml` with one shape and BSDF per traced surface, the files beside it
//! (PLY meshes, PFM chart masks), the DMD's facets, the lamp and the detectors for the manifest.

use std::fmt::Write as _;

use glam::DVec3;
use serde_json::json;

use super::mesh::{Soup, cap_soup, chrome_strips, geometry_soup, plane_soup};
use super::{ExportOptions, MM, unrepresentable};
use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::optics::bench::{Coating, DmdSetup, Interaction, Surface, state_of_bit};
use crate::optics::chart::ChartMask;
use crate::optics::dmd::MirrorState;
use crate::optics::geometry::{Frame, Geometry, Shape2D};
use crate::optics::glass::Glass;
use crate::optics::lamp::{EmitterShape, LampSpectrum};
use crate::optics::spectrum::Spectrum;

pub(super) fn fmt(v: f64) -> String {
    format!("{v:.9e}")
}

pub(super) fn matrix(cols: [DVec3; 3], origin: DVec3) -> String {
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

pub(super) const BLACK: &str =
    r#"<bsdf type="diffuse"><float name="reflectance" value="0"/></bsdf>"#;

pub(super) fn constant_index(bench: &Bench, m: usize, el: &str) -> Result<f64> {
    let medium = &bench.media()[m];
    if medium.absorption.is_some() {
        return Err(unrepresentable(format!("`{el}` absorbs in its bulk")));
    }
    match medium.glass {
        Glass::Constant(n) => Ok(n),
        Glass::Sellmeier { .. } | Glass::Schott { .. } => {
            Err(unrepresentable(format!("`{el}` has a dispersive glass")))
        }
    }
}

pub(super) fn constant(s: &Spectrum, what: String) -> Result<f64> {
    match s {
        Spectrum::Constant(v) => Ok(*v),
        Spectrum::Table(_) => Err(unrepresentable(format!("{what} varies with wavelength"))),
    }
}

/// The scene as it is written: `scene.xml`, the files beside it, the black surfaces gathered
/// into one mesh (written last), and the detectors for the manifest.
pub(super) struct SceneWriter {
    pub(super) xml: String,
    pub(super) files: Vec<(String, Vec<u8>)>,
    pub(super) black: Soup,
    shape_index: usize,
    pub(super) detectors_json: Vec<serde_json::Value>,
    charts_done: Vec<usize>,
}

/// A `dielectric` BSDF between indices `n1` (normal side) and `n2`.
pub(super) fn dielectric(n1: f64, n2: f64) -> String {
    format!(
        "<bsdf type=\"dielectric\"><float name=\"ext_ior\" value=\"{}\"/>\
         <float name=\"int_ior\" value=\"{}\"/></bsdf>",
        fmt(n1),
        fmt(n2)
    )
}

/// A front-surface mirror BSDF of reflectance `r`.
pub(super) fn conductor(r: f64) -> String {
    format!(
        "<bsdf type=\"conductor\"><string name=\"material\" value=\"none\"/>\
         <float name=\"specular_reflectance\" value=\"{}\"/></bsdf>",
        fmt(r)
    )
}

/// A surface with a clear aperture, as its clear part and the ring outside it (None without
/// a clear aperture, or for a geometry that has no ring).
pub(super) fn clear_split(s: &Surface) -> Option<(Soup, Soup)> {
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
    pub(super) fn new(depth: u32) -> Self {
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
    pub(super) fn add_mesh(&mut self, id: &str, soup: &Soup, bsdf: &str) {
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
    pub(super) fn surface(
        &mut self,
        bench: &Bench,
        opts: &ExportOptions,
        s: &Surface,
    ) -> Result<()> {
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
    pub(super) fn meshes(&mut self, bench: &Bench) {
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
    pub(super) fn dmd(&mut self, setup: &DmdSetup, opts: &ExportOptions) -> Result<()> {
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
    pub(super) fn lamp(
        &mut self,
        bench: &Bench,
        opts: &ExportOptions,
    ) -> Result<serde_json::Value> {
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
