//! Lens prescriptions from files: the Zemax `.zmx` reader ([`zmx`]), glass catalogues
//! ([`agf`]), their text encodings ([`text`]), and the glass resolution that turns a file into
//! an [`optics::lens::Prescription`](crate::optics::lens::Prescription) in SI units, with every
//! substitution and every ignored operand reported. [`report`] is the `spibench lens` job.

pub mod agf;
pub mod report;
pub mod text;
pub mod zmx;

#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::optics::glass::Glass;
use crate::optics::lens::{Defect, LensSurface, Medium, Prescription, Shape};
use zmx::{RawFile, RawSurface, located};

/// How glass names resolve: catalogue files, then the built-in catalogue; and whether a glass
/// none has may be modelled from its `GLAS` line's nd and Vd.
#[derive(Debug, Clone, Default)]
pub struct GlassOptions {
    pub catalogues: Vec<agf::Catalogue>,
    pub allow_substitution: bool,
}

/// A glass modelled from nd and Vd because no catalogue has it.
#[derive(Debug, Clone, PartialEq)]
pub struct Substitution {
    pub glass: String,
    pub nd: f64,
    pub vd: f64,
    pub file: PathBuf,
    pub line: usize,
}

impl std::fmt::Display for Substitution {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}, line {}: glass {} is in no catalogue; modelled from the file's nd = {}, Vd = {}",
            self.file.display(),
            self.line,
            self.glass,
            self.nd,
            self.vd
        )
    }
}

/// A prescription read from a file, with what the reader did to it.
#[derive(Debug, Clone)]
pub struct LoadedLens {
    pub path: PathBuf,
    pub prescription: Prescription,
    pub substitutions: Vec<Substitution>,
    /// Operands ignored (they change nothing a trace sees), with their counts.
    pub ignored: Vec<(String, usize)>,
}

/// Curvatures above this (1/m; a radius below 10 µm) are no lens surface.
const ABSURD_CURVATURE: f64 = 1e5;

/// Reads a `.zmx` file.
pub fn read_zmx(path: &Path, glasses: &GlassOptions) -> Result<LoadedLens> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        action: "read the lens prescription",
        path: path.to_path_buf(),
        source,
    })?;
    from_bytes(&bytes, path, glasses)
}

/// Reads `.zmx` bytes (`path` names them in errors).
pub fn from_bytes(bytes: &[u8], path: &Path, glasses: &GlassOptions) -> Result<LoadedLens> {
    let text = text::decode(bytes).map_err(|m| located(path, None, "", m))?;
    let raw = zmx::parse(&text, path)?;
    build(&raw, path, glasses)
}

/// The element: the surfaces from the first with a glass after it to the one where the last
/// glass ends; the object surface before and the image surface after are dropped.
fn build(raw: &RawFile, path: &Path, glasses: &GlassOptions) -> Result<LoadedLens> {
    let is_glass = |s: &RawSurface| {
        s.glass
            .as_ref()
            .is_some_and(|g| !g.name.eq_ignore_ascii_case("AIR"))
    };
    let glass_idx: Vec<usize> = (0..raw.surfaces.len())
        .filter(|&i| is_glass(&raw.surfaces[i]))
        .collect();
    let (Some(&first), Some(&last)) = (glass_idx.first(), glass_idx.last()) else {
        return Err(located(
            path,
            None,
            "GLAS",
            "no surface has a glass after it".into(),
        ));
    };
    if last + 1 >= raw.surfaces.len() {
        return Err(located(
            path,
            Some(raw.surfaces[last].line),
            "SURF",
            "the last glass has no surface after it to end on".into(),
        ));
    }
    let scale = raw.metres_per_unit;
    // Every surface from the first lens surface to the one before the image needs its DISZ.
    let n_total = raw.surfaces.len();
    let mut disz = Vec::new();
    for s in &raw.surfaces[first..n_total.saturating_sub(1).max(last + 1)] {
        match s.disz {
            None => {
                return Err(located(
                    path,
                    Some(s.line),
                    "DISZ",
                    "surface has no DISZ (the thickness to the next surface)".into(),
                ));
            }
            Some((v, line)) if !v.is_finite() => {
                return Err(located(
                    path,
                    Some(line),
                    "DISZ",
                    "an infinite thickness inside the lens".into(),
                ));
            }
            Some((v, _)) => disz.push(v * scale),
        }
    }
    let element = &raw.surfaces[first..=last + 1];
    let mut substitutions = Vec::new();
    let mut surfaces = Vec::new();
    for (k, s) in element.iter().enumerate() {
        let shape = shape(s, scale, path)?;
        let sd = match (s.diam, s.mema) {
            (Some((d, _)), _) if d > 0.0 => d * scale,
            (_, Some((m, _))) if m > 0.0 => m * scale,
            _ => {
                return Err(located(
                    path,
                    Some(s.line),
                    "DIAM",
                    "surface has no semi-diameter (DIAM or MEMA)".into(),
                ));
            }
        };
        let medium = if k + 1 == element.len() || !is_glass(s) {
            Medium::air()
        } else {
            medium(s, raw, path, glasses, &mut substitutions)?
        };
        surfaces.push(LensSurface {
            shape,
            semi_diameter_m: sd,
            thickness_m: if k + 1 == element.len() { 0.0 } else { disz[k] },
            medium_after: medium,
        });
    }
    let image_distance_m = (n_total > last + 2).then(|| disz[element.len() - 1..].iter().sum());
    let prescription = Prescription {
        name: raw.name.clone(),
        surfaces,
        image_distance_m,
    };
    if let Some(defect) = prescription.defect() {
        return Err(defect_error(defect, element, path, scale));
    }
    let mut ignored = raw.ignored.clone();
    ignored.extend(raw.header_unknown.iter().cloned());
    Ok(LoadedLens {
        path: path.to_path_buf(),
        prescription,
        substitutions,
        ignored,
    })
}

/// The shape of one surface, lengths scaled to metres (PARM i, the r^(2i) coefficient, has the
/// unit length^(1−2i)).
fn shape(s: &RawSurface, scale: f64, path: &Path) -> Result<Shape> {
    let (curv, curv_line) = s.curv.unwrap_or((0.0, s.line));
    let c = curv / scale;
    if c.abs() > ABSURD_CURVATURE {
        return Err(located(
            path,
            Some(curv_line),
            "CURV",
            format!(
                "curvature {curv} gives a radius of {:e} m, below any lens surface",
                1.0 / c.abs()
            ),
        ));
    }
    let k = s.conic;
    if !s.even_asphere {
        if let Some(line) = s.parm_line {
            return Err(located(
                path,
                Some(line),
                "PARM",
                "PARM coefficients on a STANDARD surface (an EVENASPH surface has them)".into(),
            ));
        }
        return Ok(match (c, k) {
            (0.0, _) => Shape::Flat,
            (c, 0.0) => Shape::Sphere { c },
            (c, k) => Shape::Conic { c, k },
        });
    }
    let a: [f64; 8] = std::array::from_fn(|i| s.parm[i] * scale.powi(-(2 * i as i32 + 1)));
    Ok(if a.iter().all(|&x| x == 0.0) {
        match (c, k) {
            (0.0, _) => Shape::Flat,
            (c, 0.0) => Shape::Sphere { c },
            (c, k) => Shape::Conic { c, k },
        }
    } else {
        Shape::EvenAsphere { c, k, a }
    })
}

/// The medium after a glass surface: the file's `GCAT` catalogues in order, the other
/// catalogue files, the built-in catalogue; else nd/Vd when substitution is allowed.
fn medium(
    s: &RawSurface,
    raw: &RawFile,
    path: &Path,
    opts: &GlassOptions,
    substitutions: &mut Vec<Substitution>,
) -> Result<Medium> {
    let g = s.glass.as_ref().expect("a glass surface");
    let rank = |c: &agf::Catalogue| {
        raw.catalogues
            .iter()
            .position(|n| n.eq_ignore_ascii_case(&c.name))
            .unwrap_or(usize::MAX)
    };
    let mut order: Vec<&agf::Catalogue> = opts.catalogues.iter().collect();
    order.sort_by_key(|c| rank(c));
    for c in order {
        if let Some(m) = c.medium(&g.name) {
            return m;
        }
    }
    if let Some(e) = Glass::catalogue_entry(&g.name) {
        return Ok(Medium {
            name: e.name.to_string(),
            glass: e.glass.clone(),
            range_nm: Some(e.range_nm),
            source: "built-in catalogue (docs/glasses.md)".into(),
        });
    }
    let err = |m: String| located(path, Some(g.line), "GLAS", m);
    match (g.nd, g.vd) {
        (Some(nd), Some(vd)) if opts.allow_substitution => {
            substitutions.push(Substitution {
                glass: g.name.clone(),
                nd,
                vd,
                file: path.to_path_buf(),
                line: g.line,
            });
            Ok(Medium {
                name: g.name.clone(),
                glass: Glass::from_nd_vd(nd, vd),
                range_nm: None,
                source: format!("substituted from the file's nd = {nd}, Vd = {vd}"),
            })
        }
        (Some(nd), Some(vd)) => Err(err(format!(
            "unknown glass {}: in no catalogue ({}). The file gives nd = {nd}, Vd = {vd}; a \
             model from them is used only when substitution is allowed",
            g.name,
            catalogue_list(opts)
        ))),
        _ => Err(err(format!(
            "unknown glass {}: in no catalogue ({}), and the file gives no nd/Vd to model it",
            g.name,
            catalogue_list(opts)
        ))),
    }
}

fn catalogue_list(opts: &GlassOptions) -> String {
    let mut names: Vec<String> = opts
        .catalogues
        .iter()
        .map(|c| c.path.display().to_string())
        .collect();
    names.push("the built-in catalogue".into());
    names.join(", ")
}

fn defect_error(defect: Defect, element: &[RawSurface], path: &Path, scale: f64) -> Error {
    let mm = |m: f64| m / scale;
    match defect {
        Defect::ApertureBeyondSag { surface, r_max_m } => {
            let s = &element[surface];
            let (op, line) = match (s.diam, s.mema) {
                (Some((d, l)), _) if d > 0.0 => ("DIAM", l),
                (_, Some((_, l))) => ("MEMA", l),
                _ => ("SURF", s.line),
            };
            located(
                path,
                Some(line),
                op,
                format!(
                    "the semi-diameter is larger than the surface allows: its sag is defined \
                     out to r = {:.6} (file units) only",
                    mm(r_max_m)
                ),
            )
        }
        Defect::Crossing { surface, gap_m } => {
            let s = &element[surface];
            let line = s.disz.map_or(s.line, |(_, l)| l);
            located(
                path,
                Some(line),
                "DISZ",
                format!(
                    "this surface and the next cross inside their common aperture (the \
                     thickness leaves an axial gap of {:.6} file units at worst)",
                    mm(gap_m)
                ),
            )
        }
        Defect::BadDimension { surface } => located(
            path,
            Some(element[surface].line),
            "SURF",
            "a negative or non-finite thickness or semi-diameter".into(),
        ),
    }
}
