//! `trace`'s irradiance maps on the diodes (crate::trace::irradiance): for each diode
//! `irradiance_plus.npy` / `irradiance_minus.npy` (float64, shape (3, bins, bins): the states
//! all +, all −, pattern-independent; W/m²; row 0 at the map's +v, column 0 at −u),
//! `…_stderr.npy` beside them, a figure of each diode's own-state map (`irradiance_plus.svg`,
//! …: mm on the diode's plane, the active area's outline, the centre of the light marked; the
//! diffraction orders show as separate spots), and the summary numbers in
//! `summary.json` (`irradiance`, docs/outputs.md).
//!
//! A named surface's map (`trace --irradiance-at NAME`) is written the same way as
//! `irradiance_at_<stem>.npy` and `…_stderr.npy` (the same layout, the power crossing the
//! surface), a figure of the mean of the states all + and all − (the expected map of a pattern
//! with each unit on or off at even odds, the map being linear in the pattern) and the numbers
//! in `summary.json`'s `irradiance_at`. The stem is the element's name with every character
//! other than an ASCII letter, digit, `-` or `_` replaced by `_` ([`file_stem`]).

use serde::Serialize;

use crate::error::{Error, Result};
use crate::report::output::OutputDir;
use crate::trace::irradiance::{IrradianceMaps, STATES};

/// `summary.json`'s `irradiance`: both diodes.
#[derive(Debug, Clone, Serialize)]
pub struct IrradianceSummary {
    pub bins: usize,
    pub plus: DiodeIrradiance,
    pub minus: DiodeIrradiance,
}

/// Where a map lies, written flat into its diode's or surface's entry.
#[derive(Debug, Clone, Serialize)]
pub struct MapWindow {
    /// The map's half-width (m): the square spans ±half_width_m along u and v.
    pub half_width_m: f64,
    pub bin_m: f64,
    /// The map's centre (m; a diode's active-area centre, a surface's vertex or centre) and
    /// axes in the bench frame (unit vectors).
    pub centre_m: [f64; 3],
    pub u_axis: [f64; 3],
    pub v_axis: [f64; 3],
}

impl MapWindow {
    fn of(w: &crate::trace::irradiance::Window, bins: usize) -> MapWindow {
        MapWindow {
            half_width_m: w.half_width_m,
            bin_m: 2.0 * w.half_width_m / bins as f64,
            centre_m: w.frame.origin.to_array(),
            u_axis: w.frame.u.to_array(),
            v_axis: w.frame.v.to_array(),
        }
    }
}

/// One diode's map window and its numbers per state.
#[derive(Debug, Clone, Serialize)]
pub struct DiodeIrradiance {
    #[serde(flatten)]
    pub window: MapWindow,
    /// The active area's outline: a disk of this radius at the map's centre (m).
    pub active_radius_m: f64,
    pub all_plus: StateIrradiance,
    pub all_minus: StateIrradiance,
    pub pattern_independent: StateIrradiance,
    /// Of the power on this active area with every unit in this arm's state plus that with
    /// every unit in the other arm's state, the share of the latter.
    pub other_arm_share: f64,
}

/// `summary.json`'s `irradiance_at` entry: one named surface's map window and its numbers per
/// state.
#[derive(Debug, Clone, Serialize)]
pub struct SurfaceIrradiance {
    /// The element's name, as given.
    pub name: String,
    /// The files' names: `irradiance_at_<file_stem>.npy`, ….
    pub file_stem: String,
    #[serde(flatten)]
    pub window: MapWindow,
    /// The surface's outline: the radius of the disk that holds it (m).
    pub outline_radius_m: f64,
    pub all_plus: SurfacePower,
    pub all_minus: SurfacePower,
    pub pattern_independent: SurfacePower,
}

/// One state's numbers on one named surface.
#[derive(Debug, Clone, Serialize)]
pub struct SurfacePower {
    /// Power crossing the surface inside the map (W), each crossing booked.
    pub power_w: f64,
    pub power_w_stderr: f64,
    pub centroid_m: [f64; 2],
    pub rms_radius_m: f64,
}

/// One state's numbers on one diode.
#[derive(Debug, Clone, Serialize)]
pub struct StateIrradiance {
    pub active_w: f64,
    pub active_w_stderr: f64,
    pub plate_w: f64,
    pub centroid_m: [f64; 2],
    pub rms_radius_m: f64,
    pub spill: f64,
    /// The spill of the pattern light alone (the state less the pattern-independent part;
    /// `IrradianceMaps::signal_spill`) and its standard error; None for the
    /// pattern-independent state itself.
    pub signal_spill: Option<f64>,
    pub signal_spill_stderr: Option<f64>,
}

impl IrradianceSummary {
    pub fn of(maps: &IrradianceMaps) -> IrradianceSummary {
        let diode = |d: usize| {
            let w = &maps.windows[d];
            let st = |s: usize| {
                let x = maps.stats(d, s);
                let signal = (s < 2).then(|| maps.signal_spill(d, s));
                StateIrradiance {
                    active_w: x.active_w,
                    active_w_stderr: x.active_stderr_w,
                    plate_w: x.plate_w,
                    centroid_m: x.centroid_m,
                    rms_radius_m: x.rms_radius_m,
                    spill: x.spill,
                    signal_spill: signal.map(|v| v.0),
                    signal_spill_stderr: signal.map(|v| v.1),
                }
            };
            let (own, other) = (st(d).active_w, st(1 - d).active_w);
            DiodeIrradiance {
                window: MapWindow::of(w, maps.bins),
                active_radius_m: w.radius_m,
                all_plus: st(0),
                all_minus: st(1),
                pattern_independent: st(2),
                other_arm_share: if own + other > 0.0 {
                    other / (own + other)
                } else {
                    0.0
                },
            }
        };
        IrradianceSummary {
            bins: maps.bins,
            plus: diode(0),
            minus: diode(1),
        }
    }
}

/// The stem of a named surface's files: `name` with every character other than an ASCII
/// letter, digit, `-` or `_` replaced by `_`.
pub fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The stems of the named surfaces' files, in order; two names of one stem would write one
/// file over the other, and are refused (the field `irradiance_at`).
pub fn file_stems(names: &[String]) -> Result<Vec<String>> {
    let stems: Vec<String> = names.iter().map(|n| file_stem(n)).collect();
    for (k, stem) in stems.iter().enumerate() {
        if let Some(j) = stems[..k].iter().position(|s| s == stem)
            && names[j] != names[k]
        {
            return Err(Error::field(
                "irradiance_at",
                format!(
                    "`{}` and `{}` would both be written as irradiance_at_{stem}.npy",
                    names[j], names[k]
                ),
            ));
        }
    }
    Ok(stems)
}

/// `summary.json`'s `irradiance_at`: the named surfaces' maps, in the order named.
pub fn surfaces_of(maps: &IrradianceMaps) -> Vec<SurfaceIrradiance> {
    maps.surfaces
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let (d, w) = (2 + k, &s.window);
            let st = |state: usize| {
                let x = maps.stats(d, state);
                SurfacePower {
                    power_w: x.active_w,
                    power_w_stderr: x.active_stderr_w,
                    centroid_m: x.centroid_m,
                    rms_radius_m: x.rms_radius_m,
                }
            };
            SurfaceIrradiance {
                name: s.name.clone(),
                file_stem: file_stem(&s.name),
                window: MapWindow::of(w, maps.bins),
                outline_radius_m: w.radius_m,
                all_plus: st(0),
                all_minus: st(1),
                pattern_independent: st(2),
            }
        })
        .collect()
}

/// Writes map d's irradiance and its standard errors, every state (shape (3, bins, bins)), as
/// `<stem>.npy` and `<stem>_stderr.npy`; returns the irradiance, state-major.
fn write_arrays(
    dir: &OutputDir,
    maps: &IrradianceMaps,
    d: usize,
    stem: &str,
    files: &mut Vec<String>,
) -> Result<Vec<f64>> {
    let bins = maps.bins;
    let (mut e, mut se) = (Vec::new(), Vec::new());
    for s in 0..STATES.len() {
        let (a, b) = maps.irradiance(d, s);
        e.extend(a);
        se.extend(b);
    }
    for (stem, v) in [(stem.to_string(), &e), (format!("{stem}_stderr"), &se)] {
        let name = format!("{stem}.npy");
        let path = dir.path(&name);
        let bytes = crate::report::npy::encode_f64(&[STATES.len(), bins, bins], v);
        std::fs::write(&path, bytes).map_err(|err| Error::write(&path, err))?;
        files.push(name);
    }
    Ok(e)
}

/// Writes the arrays (and, with the `figures` feature, the figures) into `dir`, the diodes'
/// maps then the named surfaces'; returns the files written.
pub fn write(dir: &OutputDir, maps: &IrradianceMaps) -> Result<Vec<String>> {
    let mut files = Vec::new();
    let bins = maps.bins;
    for (d, key) in ["plus", "minus"].into_iter().enumerate() {
        let stem = format!("irradiance_{key}");
        let e = write_arrays(dir, maps, d, &stem, &mut files)?;
        #[cfg(feature = "figures")]
        {
            let c = maps.stats(d, d).centroid_m;
            let figure = Figure {
                d,
                values: &e[d * bins * bins..(d + 1) * bins * bins],
                x_label: format!("u on pd_{key} (mm)"),
                value_label: format!("irradiance, all units {} (W/m²)", ["+", "−"][d]),
                mark: c,
            };
            write_figure(dir, maps, &figure, &stem, &mut files)?;
        }
        #[cfg(not(feature = "figures"))]
        let _ = (e, bins);
    }
    for (k, s) in maps.surfaces.iter().enumerate() {
        let d = 2 + k;
        let stem = format!("irradiance_at_{}", file_stem(&s.name));
        let e = write_arrays(dir, maps, d, &stem, &mut files)?;
        #[cfg(feature = "figures")]
        {
            let n = bins * bins;
            let mean: Vec<f64> = (0..n).map(|i| 0.5 * (e[i] + e[n + i])).collect();
            // The mean map's centre of light: the states' centroids weighted by their power.
            let (p, m) = (maps.stats(d, 0), maps.stats(d, 1));
            let total = p.active_w + m.active_w;
            let mark = if total > 0.0 {
                [0, 1]
                    .map(|a| (p.active_w * p.centroid_m[a] + m.active_w * m.centroid_m[a]) / total)
            } else {
                [0.0; 2]
            };
            let figure = Figure {
                d,
                values: &mean,
                x_label: format!("u on {} (mm)", s.name),
                value_label: "mean irradiance, all ± (W/m²)".into(),
                mark,
            };
            write_figure(dir, maps, &figure, &stem, &mut files)?;
        }
        #[cfg(not(feature = "figures"))]
        let _ = e;
    }
    Ok(files)
}

/// One map's figure: map d's `values` (W/m², row-major, row 0 at +v), its labels and the
/// centre of the light (m, the map's (u, v)).
#[cfg(feature = "figures")]
struct Figure<'a> {
    d: usize,
    values: &'a [f64],
    x_label: String,
    value_label: String,
    mark: [f64; 2],
}

/// Draws a map in mm on its plane as `<stem>.svg`, `.png` and `.pdf`, with the outline of the
/// active area (a diode) or of the surface and the centre of the light marked.
#[cfg(feature = "figures")]
fn write_figure(
    dir: &OutputDir,
    maps: &IrradianceMaps,
    f: &Figure,
    stem: &str,
    files: &mut Vec<String>,
) -> Result<()> {
    use crate::report::heatmap::{Circle, Heatmap, write_heatmap_with};
    let (bins, w) = (maps.bins, maps.window(f.d));
    let centres: Vec<f64> = (0..bins)
        .map(|i| 1e3 * w.bin_centre(bins, 0, i).0)
        .collect();
    // Heatmap cells run x-major with y ascending; the map's rows run from +v down.
    let values = (0..bins * bins)
        .map(|k| f.values[(bins - 1 - k % bins) * bins + k / bins])
        .collect();
    let h = Heatmap {
        x_label: f.x_label.clone(),
        y_label: "v (mm)".into(),
        value_label: f.value_label.clone(),
        xs: centres.clone(),
        ys: centres,
        values,
        mark: Some((1e3 * f.mark[0], 1e3 * f.mark[1])),
    };
    let outline = Circle {
        centre: (0.0, 0.0),
        radius: 1e3 * w.radius_m,
    };
    let (svg, png) = (format!("{stem}.svg"), format!("{stem}.png"));
    write_heatmap_with(&h, &[outline], &dir.path(&svg), &dir.path(&png))?;
    files.extend([svg, png, format!("{stem}.pdf")]);
    Ok(())
}
