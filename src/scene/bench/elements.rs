//! The bench's elements, one function per kind: each checks what reading could not (relations
//! between values), converts to SI and adds its surfaces and its solid to the bench.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::optics::bench::{
    AIR_MEDIUM, ChartPlate, Coating, ElementId, Interaction, LensError, Solid,
};
use crate::optics::chart::ChartMask;
use crate::optics::geometry::{Frame, Geometry, Shape2D, sag};
use crate::optics::mesh::Mesh;
use crate::raster::Raster;
use crate::scene::numbers::MAX_OD;

use super::build::{Builder, mm, solid_of};
use super::schema::{
    ApertureSpec, BaffleSpec, CenterOnSpec, ChartPatternSpec, ChartSpec, ElementSpec, FilterSpec,
    LensSpec, MirrorSpec, TubeSpec,
};

impl Builder<'_> {
    /// Adds one element, by kind.
    pub(super) fn element(&mut self, el: &ElementSpec) -> Result<()> {
        let name = el.name().to_string();
        let id = self.parts.element(&name);
        match el {
            ElementSpec::Lens(l) => self.lens(l, id, name),
            ElementSpec::LensSystem(l) => self.lens_system(l, id, name),
            ElementSpec::Filter(f) => self.filter(f, id, name),
            ElementSpec::Aperture(a) => self.aperture(a, id, name),
            ElementSpec::Tube(t) => self.tube(t, id, name),
            ElementSpec::Baffle(b) => self.baffle(b, id, name),
            ElementSpec::Mirror(m) => self.mirror(m, id, name),
            ElementSpec::Chart(c) => self.chart(c, id, name),
        }
    }

    /// A `Lens` element.
    fn lens(&mut self, el: &LensSpec, id: ElementId, name: String) -> Result<()> {
        let LensSpec {
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
        } = el;
        let n = name.as_str();
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
        let frame = self
            .ctx
            .frame(mm(*position_mm), *axis, None, *tilt_deg, &e)?;
        let glass = self.ctx.glass(glass, |m| e("glass", m))?;
        let coating = self.ctx.coating(coating, |m| e("coating", m))?;
        let radius = 0.5e-3 * diameter_mm.0;
        let clear = clear_diameter_mm.map_or(radius, |c| 0.5e-3 * c.0);
        let r1 = front_radius_mm.map(|r| r.0 * 1e-3);
        let r2 = back_radius_mm.map(|r| r.0 * 1e-3);
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
        Ok(())
    }

    /// A `Filter` element.
    fn filter(&mut self, el: &FilterSpec, id: ElementId, name: String) -> Result<()> {
        let FilterSpec {
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
        } = el;
        let n = name.as_str();
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
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
        Ok(())
    }

    /// A `Aperture` element.
    fn aperture(&mut self, el: &ApertureSpec, id: ElementId, name: String) -> Result<()> {
        let ApertureSpec {
            position_mm,
            axis,
            inner_diameter_mm,
            outer_diameter_mm,
            ..
        } = el;
        let n = name.as_str();
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
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
        Ok(())
    }

    /// A `Tube` element.
    fn tube(&mut self, el: &TubeSpec, id: ElementId, name: String) -> Result<()> {
        let TubeSpec {
            position_mm,
            axis,
            diameter_mm,
            length_mm,
            ..
        } = el;
        let n = name.as_str();
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
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
        Ok(())
    }

    /// A `Baffle` element.
    fn baffle(&mut self, el: &BaffleSpec, id: ElementId, name: String) -> Result<()> {
        let BaffleSpec {
            position_mm,
            axis,
            x_axis,
            width_mm,
            height_mm,
            hole_diameter_mm,
            segments,
            ..
        } = el;
        let n = name.as_str();
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
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
            segments.usize(),
        );
        self.parts.meshes.push((mesh, id));
        Ok(())
    }

    /// A `Mirror` element.
    fn mirror(&mut self, el: &MirrorSpec, id: ElementId, name: String) -> Result<()> {
        let MirrorSpec {
            position_mm,
            normal,
            x_axis,
            outline,
            reflectance,
            thickness_mm,
            tilt_deg,
            ..
        } = el;
        let n = name.as_str();
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
        let frame = self
            .ctx
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
        Ok(())
    }

    /// A `Chart` element.
    fn chart(&mut self, el: &ChartSpec, id: ElementId, name: String) -> Result<()> {
        let ChartSpec {
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
        } = el;
        let n = name.as_str();
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
        let at = self
            .ctx
            .frame(mm(*position_mm), *normal, *x_axis, *tilt_deg, &|f, m| {
                e(if f == "axis" { "normal" } else { f }, m)
            })?;
        let glass = self.ctx.glass(glass, |m| e("glass", m))?;
        let mask = chart_mask(pattern, self.ctx.path, &e)?;
        let (cx, cy) = chart_center(center_on.as_ref(), &mask, &e)?;
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
        if !(chrome_od.build().min_value() >= 0.0 && chrome_od.build().max_value() <= MAX_OD) {
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
        Ok(())
    }
}

/// The mask a chart's `pattern` prints (`bench` anchors a relative image path).
fn chart_mask(
    pattern: &ChartPatternSpec,
    bench: &Path,
    e: &dyn Fn(&str, String) -> Error,
) -> Result<ChartMask> {
    Ok(match pattern {
        ChartPatternSpec::Clear => ChartMask::Clear,
        ChartPatternSpec::Usaf {
            min_group,
            max_group,
            positive,
        } => {
            if min_group > max_group {
                return Err(e(
                    "pattern",
                    "USAF groups must satisfy min_group ≤ max_group".into(),
                ));
            }
            // The type bounds the groups to −2 … 9, well within i32.
            ChartMask::Usaf(crate::objects::usaf::UsafChart {
                min_group: min_group.get() as i32,
                max_group: max_group.get() as i32,
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
            let full = resolve(bench, path);
            let raster = load_mask(&full).map_err(|m| e("pattern", m))?;
            ChartMask::Image {
                raster,
                width_m: width_mm.0 * 1e-3,
                height_m: height_mm.0 * 1e-3,
            }
        }
    })
}

/// The chart point (mm from the plate centre) that `center_on` names.
fn chart_center(
    center_on: Option<&CenterOnSpec>,
    mask: &ChartMask,
    e: &dyn Fn(&str, String) -> Error,
) -> Result<(f64, f64)> {
    Ok(match center_on {
        None => (0.0, 0.0),
        Some(CenterOnSpec::Point((x, y))) => (x.0, y.0),
        Some(CenterOnSpec::Elements { group, first, last }) => {
            let ChartMask::Usaf(chart) = mask else {
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
            let group = group.get() as i32;
            for el in first.get() as u8..=last.get() as u8 {
                let r = chart.element_region(group, el).ok_or_else(|| {
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
    })
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
