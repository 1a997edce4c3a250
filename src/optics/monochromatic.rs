//! The monochromatic, constant-index substitute of a bench: the problem that Mitsuba 3 can
//! represent, traced by spibench as well so that both renderers solve the same problem
//! (docs/design.md, Validation; docs/mitsuba.md).
//!
//! Mitsuba's `dielectric` takes one number per side (no dispersion, no thin films), its
//! `conductor` one reflectance, its `mask` one opacity, and a monochromatic render one wavelength.
//! So at the stated wavelength λ₀:
//! - every glass becomes the constant index n(λ₀) of its Sellmeier model;
//! - every coating becomes bare Fresnel (Mitsuba's `dielectric` has no layer);
//! - the bulk absorption of absorbing filters is dropped (a `dielectric` does not absorb);
//! - every reflectance (mirrors, DMD aluminium) becomes its value at λ₀;
//! - a chart becomes a thin mask: its substrate takes the index of air (the `mask` BSDF passes
//!   light without refraction), its chrome reflects nothing and transmits T(λ₀) = 10^−OD(λ₀),
//!   and an analytic USAF pattern is rasterised over the plate's lit region (a bitmap is what
//!   Mitsuba's mask reads); Image masks are kept as they are;
//! - the lamp emits the same in-band power, flat over a 1 nm band around λ₀, and the
//!   photodiodes have responsivity 1 A/W, no ambient and no dark current, so every current is the
//!   detected power in watts.
//!
//! Every change that alters the physics is listed in [`Monochromatic::notes`]; a bench that is
//! already monochromatic comes back with no notes.

use super::bench::{Assembly, Bench, Coating, Interaction};
use super::chart::ChartMask;
use super::glass::Glass;
use super::lamp::LampSpectrum;
use super::spectrum::Spectrum;
use crate::raster::Raster;

/// A substituted bench and what the substitution changed.
#[derive(Debug, Clone)]
pub struct Monochromatic {
    pub bench: Bench,
    /// One sentence per change, naming the element.
    pub notes: Vec<String>,
    /// λ₀ (m).
    pub wavelength_m: f64,
}

/// Options of the substitution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonochromaticOptions {
    /// λ₀ (m).
    pub wavelength_m: f64,
    /// Side of the square region of a USAF chart that is rasterised, centred on the chart point
    /// on the lamp axis (m); the rest of the plate is chrome.
    pub usaf_region_m: f64,
    /// Pixels across that region.
    pub usaf_pixels: usize,
}

impl MonochromaticOptions {
    /// λ₀ with a 24 mm × 24 mm USAF window at 2400 px (10 µm pixels: the bars of groups ≤ 5,
    /// ≥ 15.6 µm wide, keep their widths to within a pixel edge).
    pub fn at_nm(wavelength_nm: f64) -> MonochromaticOptions {
        MonochromaticOptions {
            wavelength_m: wavelength_nm * 1e-9,
            usaf_region_m: 24e-3,
            usaf_pixels: 2400,
        }
    }
}

/// Half-width of the traced band around λ₀ (m): 0.5 nm. Every index and spectrum is constant
/// after the substitution, so the width only matters for the lamp's relative spectrum.
const HALF_BAND_M: f64 = 0.5e-9;

/// Builds the monochromatic substitute of `bench` (see the module notes). Fails with a message
/// only for an impossible wavelength.
pub fn monochromatic(bench: &Bench, opts: &MonochromaticOptions) -> Result<Monochromatic, String> {
    let wl = opts.wavelength_m;
    if !(wl.is_finite() && wl > 100e-9 && wl < 20e-6) {
        return Err(format!(
            "the substitute wavelength must lie in (100, 20000) nm, got {} nm",
            wl * 1e9
        ));
    }
    if !(opts.usaf_pixels >= 2 && opts.usaf_pixels <= 20_000 && opts.usaf_region_m > 0.0) {
        return Err("the USAF raster needs 2 to 20000 pixels over a positive region".into());
    }
    let mut b = bench.clone().into_assembly();
    let mut notes = Vec::new();
    let nm = wl * 1e9;
    let element_of_medium = |m: usize| -> String {
        bench
            .surfaces()
            .iter()
            .find(|s| match &s.interaction {
                Interaction::Interface { front, back, .. } => *front == m || *back == m,
                Interaction::Chart { front, back, .. } => *front == m || *back == m,
                _ => false,
            })
            .map_or_else(
                || format!("medium {m}"),
                |s| bench.elements()[s.element].clone(),
            )
    };
    // Glasses and bulk absorption.
    for (i, m) in b.parts.media.iter_mut().enumerate() {
        if let Glass::Sellmeier { .. } | Glass::Schott { .. } = m.glass {
            let n = m.glass.index(wl);
            notes.push(format!(
                "`{}`: dispersive glass replaced by the constant index n = {n:.6} (its value at \
                 {nm} nm)",
                element_of_medium(i)
            ));
            m.glass = Glass::Constant(n);
        }
        if let Some((_, el)) = &m.absorption {
            notes.push(format!(
                "`{}`: bulk absorption dropped (Mitsuba's dielectric does not absorb)",
                bench.elements()[*el]
            ));
            m.absorption = None;
        }
    }
    substitute_charts(bench, &mut b, opts, &mut notes);
    // Coatings and reflectances.
    for s in b.parts.surfaces.iter_mut() {
        let name = &bench.elements()[s.element];
        match &mut s.interaction {
            Interaction::Interface { coating, .. } if *coating != Coating::None => {
                notes.push(format!(
                    "`{name}`: coating replaced by bare Fresnel (Mitsuba's dielectric has no \
                     thin film)"
                ));
                *coating = Coating::None;
            }
            Interaction::Mirror { reflectance }
                if !matches!(reflectance, Spectrum::Constant(_)) =>
            {
                let r = reflectance.at(wl);
                notes.push(format!(
                    "`{name}`: reflectance fixed at R = {r:.5} ({nm} nm)"
                ));
                *reflectance = Spectrum::Constant(r);
            }
            _ => {}
        }
    }
    if let Some(d) = &mut b.dmd
        && !matches!(d.dmd.reflectance, Spectrum::Constant(_))
    {
        let r = d.dmd.reflectance.at(wl);
        notes.push(format!(
            "DMD mirrors: reflectance fixed at R = {r:.5} ({nm} nm)"
        ));
        d.dmd.reflectance = Spectrum::Constant(r);
    }
    // Detectors: 1 A/W, no ambient, no dark current.
    for (k, det) in b.detectors.iter_mut().enumerate() {
        let name = if k == 0 { "pd_plus" } else { "pd_minus" };
        if det.responsivity != Spectrum::Constant(1.0) {
            notes.push(format!(
                "`{name}`: responsivity replaced by 1 A/W (currents are detected powers in W)"
            ));
            det.responsivity = Spectrum::Constant(1.0);
        }
        if det.ambient_current_a != 0.0 || det.dark_current_a != 0.0 {
            notes.push(format!("`{name}`: ambient and dark currents dropped"));
            det.ambient_current_a = 0.0;
            det.ambient_w_per_m2 = 0.0;
            det.dark_current_a = 0.0;
        }
    }
    // The lamp: same in-band power, flat over 1 nm around λ₀.
    let flat = LampSpectrum::Table(Spectrum::Constant(1.0));
    let band = (wl - HALF_BAND_M, wl + HALF_BAND_M);
    let flat_already = match &bench.lamp().spectrum {
        LampSpectrum::Table(s) => s.min_value() == s.max_value(),
        _ => false,
    };
    if !flat_already
        || (bench.band().0 - band.0).abs() > 1e-12
        || (bench.band().1 - band.1).abs() > 1e-12
    {
        notes.push(format!(
            "lamp: the same in-band power ({:.6e} W) emitted at {nm} nm",
            bench.lamp().band_power_w
        ));
    }
    // One note per change (a lens's two faces make the same change twice).
    let mut seen = std::collections::HashSet::new();
    notes.retain(|n| seen.insert(n.clone()));
    b.lamp.spectrum = flat.clone();
    b.band = band;
    // Bulk absorption is dropped: nothing filters the spectrum any more.
    b.filter_ods = Vec::new();
    let b = Bench::assemble(b)?;
    Ok(Monochromatic {
        bench: b,
        notes,
        wavelength_m: wl,
    })
}

/// The charts of the substitute: substrate index 1 (a thin mask), chrome R = 0 and T(λ₀), an
/// analytic USAF chart rasterised around the lamp axis; a note per change.
fn substitute_charts(
    bench: &Bench,
    b: &mut Assembly,
    opts: &MonochromaticOptions,
    notes: &mut Vec<String>,
) {
    let wl = opts.wavelength_m;
    let mut chart_media = Vec::new();
    for s in bench.surfaces() {
        if let Interaction::Chart { front, back, .. } = s.interaction {
            chart_media.push((front, back, s.element));
        }
    }
    for &(front, back, el) in &chart_media {
        for m in [front, back] {
            if m != super::bench::AIR_MEDIUM && b.parts.media[m].glass != Glass::Constant(1.0) {
                notes.push(format!(
                    "`{}`: chart substrate replaced by index 1 (a thin mask without refraction)",
                    bench.elements()[el]
                ));
                b.parts.media[m].glass = Glass::Constant(1.0);
            }
        }
    }
    for (k, plate) in b.parts.charts.iter_mut().enumerate() {
        let name = chart_name(bench, k);
        let rc = plate.chrome_reflectance.at(wl);
        if rc != 0.0 || !matches!(plate.chrome_reflectance, Spectrum::Constant(_)) {
            if rc != 0.0 {
                notes.push(format!(
                    "`{name}`: chrome reflectance {rc:.4} replaced by 0 (Mitsuba's mask BSDF \
                     passes or absorbs)"
                ));
            }
            plate.chrome_reflectance = Spectrum::Constant(0.0);
        }
        plate.chrome_od = Spectrum::Constant(plate.chrome_od.at(wl));
        if let ChartMask::Usaf(chart) = &plate.mask {
            let n = opts.usaf_pixels;
            let side = opts.usaf_region_m;
            // The window is centred on the point of the chart face nearest the lamp axis.
            let lamp = &bench.lamp().frame;
            let f = plate.frame;
            let den = lamp.w.dot(f.w);
            let centre = if den.abs() > 1e-12 {
                let t = (f.origin - lamp.origin).dot(f.w) / den;
                f.to_local(lamp.origin + t * lamp.w)
            } else {
                glam::DVec3::ZERO
            };
            let (cx, cy) = (centre.x, centre.y);
            let px = side / n as f64;
            let raster = Raster::from_fn(n, n, |row, col| {
                let x = cx - 0.5 * side + (col as f64 + 0.5) * px;
                let y = cy + 0.5 * side - (row as f64 + 0.5) * px;
                if chart.is_clear(x * 1e3, y * 1e3) {
                    1.0
                } else {
                    0.0
                }
            });
            notes.push(format!(
                "`{name}`: analytic USAF chart rasterised to {n} × {n} px over {:.1} mm × {:.1} \
                 mm around the lamp axis (pixel-centre sampling); chrome elsewhere",
                side * 1e3,
                side * 1e3
            ));
            // An Image mask is centred on the plate centre: move the frame so that the window
            // centre sits at the raster centre.
            plate.frame.origin = f.origin + cx * f.u + cy * f.v;
            plate.mask = ChartMask::Image {
                raster,
                width_m: side,
                height_m: side,
            };
        }
    }
}

fn chart_name(bench: &Bench, chart: usize) -> String {
    bench
        .surfaces()
        .iter()
        .find(|s| matches!(s.interaction, Interaction::Chart { chart: c, .. } if c == chart))
        .map_or_else(
            || format!("chart {chart}"),
            |s| bench.elements()[s.element].clone(),
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_bench_substitute_is_constant_and_listed() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
        let bench = crate::scene::bench::read_bench(&path).unwrap();
        let m = monochromatic(&bench, &MonochromaticOptions::at_nm(850.0)).unwrap();
        assert!(
            m.bench
                .media()
                .iter()
                .all(|x| matches!(x.glass, Glass::Constant(_)) && x.absorption.is_none())
        );
        // N-BK7 at 850 nm (docs/bench-facts.md §3.4: 1.50984).
        assert!(m.bench.media().iter().any(|x| match x.glass {
            Glass::Constant(n) => (n - 1.50984).abs() < 1e-5,
            _ => false,
        }));
        assert!(
            m.bench
                .charts()
                .iter()
                .all(|c| matches!(c.mask, ChartMask::Image { .. }))
        );
        assert!(m.notes.iter().any(|n| n.contains("collimator")));
        assert_eq!(m.bench.lamp().band_power_w, bench.lamp().band_power_w);
        // A second substitution changes nothing more.
        let again = monochromatic(&m.bench, &MonochromaticOptions::at_nm(850.0)).unwrap();
        assert!(again.notes.is_empty(), "{:?}", again.notes);
        assert!(monochromatic(&bench, &MonochromaticOptions::at_nm(-1.0)).is_err());
    }
}
