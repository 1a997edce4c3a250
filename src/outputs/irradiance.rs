//! `trace`'s irradiance maps on the diodes (crate::trace::irradiance): for each diode
//! `irradiance_plus.npy` / `irradiance_minus.npy` (float64, shape (3, bins, bins): the states
//! all +, all −, pattern-independent; W/m²; row 0 at the map's +v, column 0 at −u),
//! `…_stderr.npy` beside them, a figure of each diode's own-state map (`irradiance_plus.svg`,
//! …: mm on the diode's plane, the active area's outline, the centre of the light marked; the
//! diffraction orders show as separate spots), and the summary numbers in
//! `summary.json` (`irradiance`, docs/outputs.md).

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

/// One diode's map window and its numbers per state.
#[derive(Debug, Clone, Serialize)]
pub struct DiodeIrradiance {
    /// The map's half-width (m): the square spans ±half_width_m along u and v.
    pub half_width_m: f64,
    pub bin_m: f64,
    /// The active area's outline: a disk of this radius at the map's centre (m).
    pub active_radius_m: f64,
    /// The map's axes in the bench frame (unit vectors) and its centre (m).
    pub centre_m: [f64; 3],
    pub u_axis: [f64; 3],
    pub v_axis: [f64; 3],
    pub all_plus: StateIrradiance,
    pub all_minus: StateIrradiance,
    pub pattern_independent: StateIrradiance,
    /// Of the power on this active area with every unit in this arm's state plus that with
    /// every unit in the other arm's state, the share of the latter.
    pub other_arm_share: f64,
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
}

impl IrradianceSummary {
    pub fn of(maps: &IrradianceMaps) -> IrradianceSummary {
        let diode = |d: usize| {
            let w = &maps.windows[d];
            let st = |s: usize| {
                let x = maps.stats(d, s);
                StateIrradiance {
                    active_w: x.active_w,
                    active_w_stderr: x.active_stderr_w,
                    plate_w: x.plate_w,
                    centroid_m: x.centroid_m,
                    rms_radius_m: x.rms_radius_m,
                    spill: x.spill,
                }
            };
            let (own, other) = (st(d).active_w, st(1 - d).active_w);
            DiodeIrradiance {
                half_width_m: w.half_width_m,
                bin_m: 2.0 * w.half_width_m / maps.bins as f64,
                active_radius_m: w.radius_m,
                centre_m: w.frame.origin.to_array(),
                u_axis: w.frame.u.to_array(),
                v_axis: w.frame.v.to_array(),
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

/// Writes the arrays (and, with the `figures` feature, the figures) into `dir`; returns the
/// files written.
pub fn write(dir: &OutputDir, maps: &IrradianceMaps) -> Result<Vec<String>> {
    let mut files = Vec::new();
    let bins = maps.bins;
    for (d, key) in ["plus", "minus"].into_iter().enumerate() {
        let (mut e, mut se) = (Vec::new(), Vec::new());
        for s in 0..STATES.len() {
            let (a, b) = maps.irradiance(d, s);
            e.extend(a);
            se.extend(b);
        }
        for (stem, v) in [
            (format!("irradiance_{key}"), &e),
            (format!("irradiance_{key}_stderr"), &se),
        ] {
            let name = format!("{stem}.npy");
            let path = dir.path(&name);
            let bytes = crate::report::npy::encode_f64(&[STATES.len(), bins, bins], v);
            std::fs::write(&path, bytes).map_err(|err| Error::write(&path, err))?;
            files.push(name);
        }
        #[cfg(feature = "figures")]
        {
            let (svg, png) = (
                format!("irradiance_{key}.svg"),
                format!("irradiance_{key}.png"),
            );
            let own = &e[d * bins * bins..(d + 1) * bins * bins];
            write_figure(maps, d, own, &dir.path(&svg), &dir.path(&png))?;
            files.extend([svg, png, format!("irradiance_{key}.pdf")]);
        }
    }
    Ok(files)
}

/// Draws diode d's own-state map (`own`, W/m², row-major, row 0 at +v) in mm on the diode's
/// plane, with the active area's outline and the centre of the light marked.
#[cfg(feature = "figures")]
fn write_figure(
    maps: &IrradianceMaps,
    d: usize,
    own: &[f64],
    svg: &std::path::Path,
    png: &std::path::Path,
) -> Result<()> {
    use crate::report::heatmap::{Circle, Heatmap, write_heatmap_with};
    let (bins, w) = (maps.bins, &maps.windows[d]);
    let centres: Vec<f64> = (0..bins)
        .map(|i| 1e3 * w.bin_centre(bins, 0, i).0)
        .collect();
    // Heatmap cells run x-major with y ascending; the map's rows run from +v down.
    let values = (0..bins * bins)
        .map(|k| own[(bins - 1 - k % bins) * bins + k / bins])
        .collect();
    let c = maps.stats(d, d).centroid_m;
    let h = Heatmap {
        x_label: format!("u on pd_{} (mm)", ["plus", "minus"][d]),
        y_label: "v (mm)".into(),
        value_label: format!("irradiance, all units {} (W/m²)", ["+", "−"][d]),
        xs: centres.clone(),
        ys: centres,
        values,
        mark: Some((1e3 * c[0], 1e3 * c[1])),
    };
    let outline = Circle {
        centre: (0.0, 0.0),
        radius: 1e3 * w.radius_m,
    };
    write_heatmap_with(&h, &[outline], svg, png)
}
