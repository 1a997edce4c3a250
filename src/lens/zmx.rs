//! The sequential Zemax prescription (`.zmx`) reader: the operands that define a rotationally
//! symmetric lens, the ones that cannot change what a trace sees (ignored and listed), and a
//! located error (file, line, operand) for everything else inside a surface block.

use std::path::Path;

use crate::error::{Error, Location, Result};

/// Operands that change nothing a trace of the element sees: display, notes, coatings (the
/// bench's own coating applies), fields, wavelengths, tolerances, pupil and solve settings.
/// `SQAP` (a square aperture) is deliberately absent: it clips rays.
pub const IGNORED: &[&str] = &[
    "VERS", "NAME", "NOTE", "COAT", "HIDE", "MIRR", "SLAB", "POPS", "FIMP", "COMM", "FLAP", "XDAT",
    "WAVM", "WAVL", "WAVN", "WWGT", "ENPD", "ENVD", "GFAC", "RAIM", "PUSH", "SDMA", "FTYP", "ROPD",
    "PICB", "XFLN", "YFLN", "FWGN", "VDXN", "VDYN", "VCXN", "VCYN", "VANN", "PWAV", "POLS", "GLRS",
    "GSTD", "NSCD", "COFN", "LANG", "PFIL", "BLNK", "TOL", "MNUM", "MOFF", "CONF", "EFFL", "OBSC",
    "TCMM", "FLOA", "AFOC",
];

/// One `SURF` block as written, lengths still in the file's unit.
#[derive(Debug, Clone, Default)]
pub struct RawSurface {
    /// 1-based line of the `SURF` operand.
    pub line: usize,
    /// `EVENASPH` (true) or `STANDARD`.
    pub even_asphere: bool,
    pub curv: Option<(f64, usize)>,
    pub conic: f64,
    /// PARM 1…8 (the r² … r¹⁶ coefficients) and the line of the last non-zero one.
    pub parm: [f64; 8],
    pub parm_line: Option<usize>,
    /// DISZ (∞ for `INFINITY`) and its line.
    pub disz: Option<(f64, usize)>,
    pub glass: Option<GlassLine>,
    pub diam: Option<(f64, usize)>,
    pub mema: Option<(f64, usize)>,
    pub stop: bool,
}

/// A `GLAS` line: the name and the nd, Vd fields (0 there means absent, as vendors write it).
#[derive(Debug, Clone)]
pub struct GlassLine {
    pub name: String,
    pub nd: Option<f64>,
    pub vd: Option<f64>,
    pub line: usize,
}

/// A parsed file: its surfaces, the unit scale to metres, the `GCAT` catalogue names, and the
/// ignored operands (name and how many times).
#[derive(Debug, Clone, Default)]
pub struct RawFile {
    pub name: String,
    pub surfaces: Vec<RawSurface>,
    pub metres_per_unit: f64,
    pub catalogues: Vec<String>,
    pub ignored: Vec<(String, usize)>,
    pub header_unknown: Vec<(String, usize)>,
}

/// A located input error in a prescription file.
pub fn located(path: &Path, line: Option<usize>, operand: &str, message: String) -> Error {
    Error::Input {
        location: Location {
            file: Some(path.to_path_buf()),
            line,
            column: None,
            field: (!operand.is_empty()).then(|| operand.to_string()),
        },
        message,
    }
}

fn number(path: &Path, line: usize, op: &str, tok: Option<&&str>) -> Result<f64> {
    let t = tok.ok_or_else(|| located(path, Some(line), op, format!("`{op}` needs a value")))?;
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(located(
            path,
            Some(line),
            op,
            format!("`{t}` is not a finite number"),
        )),
    }
}

fn count(list: &mut Vec<(String, usize)>, op: &str) {
    match list.iter_mut().find(|(o, _)| o == op) {
        Some((_, n)) => *n += 1,
        None => list.push((op.to_string(), 1)),
    }
}

/// Parses decoded `.zmx` text (`path` names it in errors).
pub fn parse(text: &str, path: &Path) -> Result<RawFile> {
    let mut file = RawFile {
        metres_per_unit: 1e-3,
        ..RawFile::default()
    };
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let tok: Vec<&str> = raw.split_whitespace().collect();
        let Some(&op) = tok.first() else { continue };
        let err = |msg: String| located(path, Some(line), op, msg);
        match op {
            "MODE" => {
                if tok.get(1) != Some(&"SEQ") {
                    return Err(err(format!(
                        "only sequential files (`MODE SEQ`) are read; this one is `MODE {}`",
                        tok.get(1).unwrap_or(&"")
                    )));
                }
            }
            "UNIT" => {
                file.metres_per_unit = match tok.get(1).copied() {
                    Some("MM") => 1e-3,
                    Some("CM") => 1e-2,
                    Some("IN") => 0.0254,
                    Some("METR") => 1.0,
                    other => {
                        return Err(err(format!(
                            "lens unit `{}` is not MM, CM, IN or METR",
                            other.unwrap_or("")
                        )));
                    }
                }
            }
            "GCAT" => file.catalogues = tok[1..].iter().map(|s| s.to_string()).collect(),
            "NAME" if file.surfaces.is_empty() => file.name = tok[1..].join(" "),
            "SURF" => file.surfaces.push(RawSurface {
                line,
                ..RawSurface::default()
            }),
            _ if IGNORED.contains(&op) => count(&mut file.ignored, op),
            _ if file.surfaces.is_empty() => count(&mut file.header_unknown, op),
            _ => surface_operand(file.surfaces.last_mut().unwrap(), op, &tok, line, path)?,
        }
    }
    Ok(file)
}

/// One operand inside a `SURF` block.
fn surface_operand(
    s: &mut RawSurface,
    op: &str,
    tok: &[&str],
    line: usize,
    path: &Path,
) -> Result<()> {
    let err = |msg: String| located(path, Some(line), op, msg);
    match op {
        "TYPE" => match tok.get(1).copied() {
            Some("STANDARD") => s.even_asphere = false,
            Some("EVENASPH") => s.even_asphere = true,
            other => {
                return Err(err(format!(
                    "unsupported surface type `{}`: spibench reads STANDARD and EVENASPH \
                     surfaces only",
                    other.unwrap_or("")
                )));
            }
        },
        "CURV" => s.curv = Some((number(path, line, op, tok.get(1))?, line)),
        "CONI" => s.conic = number(path, line, op, tok.get(1))?,
        "PARM" => {
            let i = tok
                .get(1)
                .and_then(|t| t.parse::<usize>().ok())
                .ok_or_else(|| err("`PARM` needs an index and a value".into()))?;
            let v = number(path, line, op, tok.get(2))?;
            if i > 8 {
                return Err(err(format!(
                    "PARM index {i} is beyond 8 (PARM 1…8 are the r² … r¹⁶ coefficients)"
                )));
            }
            if v != 0.0 {
                if i == 0 {
                    return Err(err("PARM 0 is not a coefficient of an even asphere".into()));
                }
                s.parm[i - 1] = v;
                s.parm_line = Some(line);
            }
        }
        "DISZ" => {
            let v = match tok.get(1).copied() {
                Some("INFINITY") => f64::INFINITY,
                _ => number(path, line, op, tok.get(1))?,
            };
            s.disz = Some((v, line));
        }
        "GLAS" => {
            let name = tok
                .get(1)
                .ok_or_else(|| err("`GLAS` needs a glass name".into()))?
                .to_string();
            let field = |k: usize| {
                tok.get(k)
                    .and_then(|t| t.parse::<f64>().ok())
                    .filter(|v| v.is_finite() && *v > 0.0)
            };
            s.glass = Some(GlassLine {
                name,
                nd: field(4),
                vd: field(5),
                line,
            });
        }
        "DIAM" => s.diam = Some((number(path, line, op, tok.get(1))?, line)),
        "MEMA" => s.mema = Some((number(path, line, op, tok.get(1))?, line)),
        "STOP" => s.stop = true,
        _ => {
            return Err(err(format!(
                "operand `{op}` is not read by spibench and may change the lens (tilts, \
                 decentres, apertures, other surface data); the ignored operands are {}",
                IGNORED.join(", ")
            )));
        }
    }
    Ok(())
}
