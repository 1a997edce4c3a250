//! The parts of the bench outside the element list: the DMD (and its window), the two
//! photodiodes and the lamp.

use glam::DVec3;

use crate::error::{Error, Result};
use crate::optics::Arm;
use crate::optics::bench::{
    DmdSetup, ElementId, Interaction, Photodiode, Solid, ambient_responsivity,
};
use crate::optics::dmd::{Dmd, MirrorState, PatternArea};
use crate::optics::geometry::{Frame, Geometry, Shape2D};
use crate::optics::lamp::{
    EmitterShape, FieldOutline, FieldTarget, Lamp, LampSpectrum, band_power_from_filament,
};
use crate::optics::spectrum::{Spectrum, Table};

use super::build::{Builder, mm, solid_outline};
use super::schema::{
    DmdModelSpec, DmdSpec, EmissionSpec, FilamentSpec, LampPowerSpec, LampSpec, LampSpectrumSpec,
    Outline, PhotodiodeSpec, StateSpec, WindowSpec,
};

impl Builder<'_> {
    /// The DMD, its window and package, checked; with the diffractive model, the tail tables'
    /// bin (m), for `Builder::build` to build them once the whole bench is checked.
    pub(super) fn dmd(&mut self, d: &DmdSpec, band: (f64, f64)) -> Result<(DmdSetup, Option<f64>)> {
        let e = |f: &str, m: String| self.ctx.err_path(&["dmd", f], m);
        if d.tilt_deg.0 >= 45.0 {
            return Err(e("tilt_deg", "the tilt must be below 45°".into()));
        }
        let p = d.pattern;
        let (columns, rows) = (d.columns.usize(), d.rows.usize());
        let (col0, row0) = (p.origin.0.usize(), p.origin.1.usize());
        let (across, down, per_unit) = (
            p.units_across.usize(),
            p.units_down.usize(),
            p.mirrors_per_unit.usize(),
        );
        // Each count is at most 10⁵ (its type), so these products cannot wrap.
        let (end_c, end_r) = (col0 + across * per_unit, row0 + down * per_unit);
        if end_c > columns || end_r > rows {
            return Err(self.ctx.err_path(
                &["dmd", "pattern"],
                format!(
                    "the pattern area (mirrors {}..{} × {}..{}) does not fit the {}×{} array",
                    col0, end_c, row0, end_r, columns, rows
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
            columns,
            rows,
            d.pitch_um.0 * 1e-6,
            d.fill_factor.0,
            d.tilt_deg.0.to_radians(),
            d.tilt_axis_deg.0.to_radians(),
            PatternArea {
                col0,
                row0,
                units_across: across,
                units_down: down,
                mirrors_per_unit: per_unit,
            },
            state,
            refl,
        );
        // The diffractive model's tables are built last (`Builder::build`), once every input
        // is checked: here only their bin and their memory.
        let tail_bin = match d.model {
            DmdModelSpec::Geometric => None,
            DmdModelSpec::Diffractive { tail_bin_nm } => {
                let width_nm = (band.1 - band.0) * 1e9;
                let field = ["dmd", "model", "tail_bin_nm"];
                if !(0.5..=width_nm).contains(&tail_bin_nm.0) {
                    return Err(self.ctx.err_path(
                        &field,
                        format!(
                            "the tail table's wavelength bin must be 0.5 nm to the band's \
                             {width_nm:.0} nm, got {}",
                            tail_bin_nm.0
                        ),
                    ));
                }
                let size = dmd.diffraction_size(band, tail_bin_nm.0 * 1e-9);
                // The tables shrink as the bin widens: the bin that brings them under the limit.
                let wider = tail_bin_nm.0 * size.bytes / crate::memory::MAX_MEMORY_BYTES;
                crate::memory::check(
                    size.bytes,
                    "the diffractive DMD's tail tables",
                    &size.settings(),
                    &format!(
                        "widen `tail_bin_nm` to at least {:.1} nm or narrow `band_nm`",
                        (wider * 10.0).ceil() / 10.0
                    ),
                )
                .map_err(|e| self.ctx.err_path(&field, e.message()))?;
                Some(tail_bin_nm.0 * 1e-9)
            }
        };
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
        let top = match &d.window {
            Some(w) => self.dmd_window(w, &dmd, (px, py), package)?,
            None => 2.0 * dmd.slab_half_height(),
        };
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
        Ok((
            DmdSetup {
                dmd,
                mirrors_element,
                gaps_element,
                package_element: package,
            },
            tail_bin,
        ))
    }

    pub(super) fn photodiode(&mut self, s: &PhotodiodeSpec, arm: Arm) -> Result<Photodiode> {
        let key = match arm {
            Arm::Plus => "plus",
            Arm::Minus => "minus",
        };
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
            Interaction::Detector { arm },
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

    pub(super) fn lamp(&mut self, s: &LampSpec, band: (f64, f64)) -> Result<Lamp> {
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
            EmissionSpec::Toward { element } => self.toward(element, &frame, shape, &e)?,
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
            probability: f.probability.0,
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

    /// The DMD's window and the package top around it; returns the height of the window's
    /// outer face above the array.
    fn dmd_window(
        &mut self,
        w: &WindowSpec,
        dmd: &Dmd,
        (px, py): (f64, f64),
        package: ElementId,
    ) -> Result<f64> {
        let (hx, hy) = dmd.half_size();
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
        let top = gap + t;
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
        Ok(top)
    }

    /// sin² of the half-angle of the smallest cone (plus 0.1°) around the lamp axis that holds
    /// the solid of `element` as seen from every point of the filament.
    fn toward(
        &self,
        element: &str,
        frame: &Frame,
        shape: EmitterShape,
        e: &dyn Fn(&str, String) -> Error,
    ) -> Result<f64> {
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
                    .map(|(a, b)| frame.origin + a * half_u * frame.u + b * half_v * frame.v)
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
        Ok(a.sin().powi(2))
    }
}
