//! The bench builder: checks a parsed bench file against itself (names, glasses, overlaps)
//! and converts it into a validated SI [`Bench`]. Errors found here are located in the text by
//! [`crate::scene::locate`]. The elements are built in `elements.rs`, the DMD, the photodiodes
//! and the lamp in `devices.rs`.

use std::path::Path;

use glam::DVec3;

use crate::error::{Error, Result};
use crate::optics::Arm;
use crate::optics::bench::{
    Assembly, Bench, BenchParts, Coating, GuideRequest, Interaction, Solid,
};
use crate::optics::geometry::{Frame, Shape2D};
use crate::optics::glass::{Glass, glass_names, name_key};
use crate::optics::spectrum::Spectrum;
use crate::scene::locate::Locator;
use crate::scene::numbers::{Mm3, TiltDeg};

use super::schema::{BenchFile, CoatingSpec, Direction, SpectrumSpec};

/// Wavelengths at which a user glass's index is checked across the traced band.
const GLASS_CHECK_POINTS: usize = 64;

/// The largest index a user glass may have in the band: above germanium's (about 4.0 in the
/// infrared), so only a mistyped coefficient meets it.
const GLASS_MAX_INDEX: f64 = 4.5;

/// The text (when the bench has one) and path, for locating errors, and the bench's own
/// glasses (checked first: see `Builder::user_glasses`).
pub(super) struct Ctx<'a> {
    pub(super) loc: Option<Locator<'a>>,
    pub(super) path: &'a Path,
    pub(super) glasses: Vec<(String, Glass)>,
}

pub(super) struct Builder<'a> {
    pub(super) ctx: Ctx<'a>,
    pub(super) parts: BenchParts,
    /// (element name, solid) for overlap checks and the emission cone.
    pub(super) solids: Vec<(String, Solid)>,
    /// Internal optical densities of the absorbing filters (for wavelength sampling).
    pub(super) throughput: Vec<Spectrum>,
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

pub(super) fn mm(p: Mm3) -> DVec3 {
    DVec3::new(p.0, p.1, p.2) * 1e-3
}

impl Ctx<'_> {
    /// An error at a top-level path of fields.
    pub(super) fn err_path(&self, path: &[&str], msg: impl Into<String>) -> Error {
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
    pub(super) fn err_el(&self, element: &str, field: &str, msg: impl Into<String>) -> Error {
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
    pub(super) fn err_entry(
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

    pub(super) fn glass(&self, name: &str, err: impl Fn(String) -> Error) -> Result<Glass> {
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
    pub(super) fn err_glass(
        &self,
        index: usize,
        name: &str,
        field: &str,
        msg: impl Into<String>,
    ) -> Error {
        self.err_entry(format!("glasses[{index}]"), "glasses", name, field, msg)
    }

    pub(super) fn coating(
        &self,
        c: &CoatingSpec,
        err: impl Fn(String) -> Error,
    ) -> Result<Coating> {
        Ok(match c {
            CoatingSpec::Uncoated => Coating::None,
            CoatingSpec::MgF2 { design_nm } => Coating::quarter_wave_mgf2(design_nm.0 * 1e-9),
            CoatingSpec::Reflectance(s) => {
                let s = s.build();
                if !(s.min_value() >= 0.0 && s.max_value() <= 1.0) {
                    return Err(err("a reflectance must lie in [0, 1]".into()));
                }
                Coating::Reflectance(s)
            }
        })
    }

    pub(super) fn fraction_spectrum(
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

    pub(super) fn frame(
        &self,
        origin: DVec3,
        w: Direction,
        x_axis: Option<Direction>,
        tilt: Option<(TiltDeg, TiltDeg)>,
        err: &dyn Fn(&str, String) -> Error,
    ) -> Result<Frame> {
        let w = w.to_unit().map_err(|m| err("axis", m))?;
        let u = match x_axis {
            Some(d) => Some(d.to_unit().map_err(|m| err("x_axis", m))?),
            None => None,
        };
        let mut f = Frame::new(origin, w, u);
        if let Some((a, b)) = tilt {
            f = f.tilted(a.0.to_radians(), b.0.to_radians());
        }
        Ok(f)
    }
}

impl Builder<'_> {
    /// The bench's own glasses, checked: a name that is neither a catalogue glass, nor a number,
    /// nor used twice; coefficients whose index is finite, at least 1 and below
    /// `GLASS_MAX_INDEX` across the traced band, with no resonance (λ² = Cᵢ) inside it.
    pub(super) fn user_glasses(
        &self,
        file: &BenchFile,
        band_m: (f64, f64),
    ) -> Result<Vec<(String, Glass)>> {
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

    pub(super) fn build(mut self, file: &BenchFile) -> Result<Bench> {
        // Band.
        let (lo, hi) = (file.band_nm.0.0, file.band_nm.1.0);
        if hi <= lo {
            return Err(self.ctx.err_path(
                &["band_nm"],
                format!("the band must satisfy min < max, got ({lo}, {hi}) nm"),
            ));
        }
        let band = (lo * 1e-9, hi * 1e-9);
        self.ctx.glasses = self.user_glasses(file, band)?;
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
        let (dmd, tail_bin) = match &file.dmd {
            Some(d) => {
                let (setup, bin) = self.dmd(d, band)?;
                (Some(setup), bin)
            }
            None => (None, None),
        };
        let detectors = [
            self.photodiode(&file.detectors.plus, Arm::Plus)?,
            self.photodiode(&file.detectors.minus, Arm::Minus)?,
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
        // The diffractive DMD's tail tables (seconds and up to the memory limit at fine
        // bins) only now that every input is checked.
        let dmd = dmd.map(|mut s| {
            if let Some(bin) = tail_bin {
                s.dmd = s.dmd.with_diffraction(band, bin);
            }
            s
        });
        Bench::assemble(Assembly {
            band,
            lamp,
            parts: self.parts,
            dmd,
            detectors,
            lamp_housing,
            max_interactions: file.max_interactions.get() as u32,
            filter_ods: self.throughput,
            guide,
        })
        .map_err(|m| self.ctx.err_path(&path, m))
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
pub(super) fn solid_of(frame: &Frame, shape: Shape2D, thickness: f64) -> Solid {
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
pub(super) fn solid_outline(s: &Solid) -> Vec<DVec3> {
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
