//! Zemax glass catalogues (`.agf`): `NM` starts a glass (name, formula number, glass code, nd,
//! Vd, …), `CD` gives its dispersion coefficients and `LD` its wavelength range in µm. The
//! Schott (formula 1) and Sellmeier 1 (formula 2, coefficients K₁ L₁ K₂ L₂ K₃ L₃ interleaved)
//! formulas are read; a glass with another formula is reported when a prescription uses it.

use std::path::{Path, PathBuf};

use super::zmx::located;
use crate::error::{Error, Result};
use crate::optics::glass::Glass;
use crate::optics::lens::Medium;

/// One glass of a catalogue file, as written.
#[derive(Debug, Clone)]
pub struct AgfGlass {
    pub name: String,
    pub formula: u32,
    pub nd: f64,
    pub vd: f64,
    pub cd: Vec<f64>,
    /// λmin, λmax (µm), from the `LD` line.
    pub range_um: Option<(f64, f64)>,
    /// 1-based line of the `NM` record.
    pub line: usize,
}

/// A catalogue file: its name (the file stem, as `GCAT` names catalogues) and glasses.
#[derive(Debug, Clone)]
pub struct Catalogue {
    pub name: String,
    pub path: PathBuf,
    pub glasses: Vec<AgfGlass>,
}

impl Catalogue {
    /// Reads a catalogue file (any encoding [`super::text::decode`] reads).
    pub fn read(path: &Path) -> Result<Catalogue> {
        let bytes = std::fs::read(path).map_err(|source| Error::Io {
            action: "read the glass catalogue",
            path: path.to_path_buf(),
            source,
        })?;
        let text = super::text::decode(&bytes).map_err(|m| located(path, None, "", m))?;
        Catalogue::parse(&text, path)
    }

    pub fn parse(text: &str, path: &Path) -> Result<Catalogue> {
        let mut glasses: Vec<AgfGlass> = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            let tok: Vec<&str> = raw.split_whitespace().collect();
            let Some(&op) = tok.first() else { continue };
            let num = |k: usize| -> Result<f64> {
                tok.get(k)
                    .and_then(|t| t.parse::<f64>().ok())
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        located(path, Some(line), op, format!("field {k} is not a number"))
                    })
            };
            match op {
                "NM" => {
                    let name = tok
                        .get(1)
                        .ok_or_else(|| located(path, Some(line), op, "no glass name".into()))?;
                    glasses.push(AgfGlass {
                        name: name.to_string(),
                        formula: num(2)? as u32,
                        nd: num(4)?,
                        vd: num(5).unwrap_or(0.0),
                        cd: Vec::new(),
                        range_um: None,
                        line,
                    });
                }
                "CD" | "LD" => {
                    let g = glasses.last_mut().ok_or_else(|| {
                        located(path, Some(line), op, "record before any `NM` glass".into())
                    })?;
                    if op == "CD" {
                        g.cd = (1..tok.len()).map(num).collect::<Result<_>>()?;
                    } else {
                        g.range_um = Some((num(1)?, num(2)?));
                    }
                }
                _ => {}
            }
        }
        Ok(Catalogue {
            name: path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            path: path.to_path_buf(),
            glasses,
        })
    }

    /// The medium of a glass of this catalogue (names matched case-insensitively), an error if
    /// its formula is not one spibench evaluates, `None` if the catalogue lacks it.
    pub fn medium(&self, name: &str) -> Option<Result<Medium>> {
        let g = self
            .glasses
            .iter()
            .find(|g| g.name.eq_ignore_ascii_case(name))?;
        let coefficient = |k: usize| g.cd.get(k).copied().unwrap_or(0.0);
        let glass = match g.formula {
            1 => Glass::Schott {
                a: std::array::from_fn(coefficient),
            },
            2 => Glass::Sellmeier {
                b: [coefficient(0), coefficient(2), coefficient(4)],
                c_um2: [coefficient(1), coefficient(3), coefficient(5)],
            },
            f => {
                return Some(Err(located(
                    &self.path,
                    Some(g.line),
                    "NM",
                    format!(
                        "glass {} uses dispersion formula {f}; spibench evaluates formulas 1 \
                         (Schott) and 2 (Sellmeier 1)",
                        g.name
                    ),
                )));
            }
        };
        Some(Ok(Medium {
            name: g.name.clone(),
            glass,
            range_nm: g.range_um.map(|(lo, hi)| (lo * 1e3, hi * 1e3)),
            source: format!("{}, line {}", self.path.display(), g.line),
        }))
    }
}
