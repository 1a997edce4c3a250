//! A [`Prescription`] as bench surfaces: one interface per surface (spheres and flats as the
//! bench's own `SphereCap` and `Plane`, so a spherical prescription traces exactly as a `Lens`
//! does; conics and even aspheres as `Geometry::Asphere`), the coating on every interface, and
//! the ground edge and any step between apertures black.

use super::{Prescription, Shape};
use crate::optics::bench::{
    AIR_MEDIUM, BenchParts, ClearAperture, Coating, ElementId, Interaction, MediumId, Surface,
};
use crate::optics::geometry::{Frame, Geometry, Shape2D};

/// Adds the prescription's surfaces with the first vertex at `frame.origin` and light
/// travelling along `frame.w`. `radius` is the mechanical semi-diameter of the element's edge
/// (at least every surface's clear semi-diameter). The prescription must be free of defects
/// ([`Prescription::defect`]). `clear`, when smaller than a surface's semi-diameter, is the
/// clear aperture of the mount: light beyond it is absorbed.
pub fn add_lens_system(
    parts: &mut BenchParts,
    element: ElementId,
    frame: &Frame,
    p: &Prescription,
    coating: &Coating,
    radius: f64,
    clear: Option<f64>,
) {
    let w = frame.w;
    let vz = p.vertex_z();
    // One medium per glass, in order.
    let mut before: MediumId = AIR_MEDIUM;
    for (k, s) in p.surfaces.iter().enumerate() {
        let after = if k + 1 == p.surfaces.len() || s.medium_after.is_air() {
            AIR_MEDIUM
        } else {
            parts.medium(s.medium_after.glass.clone(), None)
        };
        let vertex = frame.origin + vz[k] * w;
        let sd = s.semi_diameter_m;
        let geometry = match s.shape {
            Shape::Flat => Geometry::Plane {
                frame: Frame {
                    origin: vertex,
                    u: frame.u,
                    v: -frame.v,
                    w: -w,
                },
                shape: Shape2D::Disk { radius: sd },
            },
            Shape::Sphere { c } => Geometry::SphereCap {
                vertex,
                axis: w,
                radius: 1.0 / c,
                aperture: sd,
                inner: 0.0,
            },
            shape => Geometry::Asphere {
                frame: Frame {
                    origin: vertex,
                    ..*frame
                },
                shape,
                aperture: sd,
            },
        };
        let interaction = Interaction::Interface {
            front: before,
            back: after,
            coating: coating.clone(),
        };
        let mut surface = Surface::new(geometry, interaction, element);
        if let Some(c) = clear.filter(|&c| c < sd) {
            surface.clear = Some(ClearAperture {
                point: vertex,
                axis: w,
                radius: c,
            });
        }
        parts.surfaces.push(surface);
        // A step out to the edge where this surface is smaller than the element: black.
        if sd < radius {
            let z = vz[k] + s.shape.sag(sd * sd).unwrap_or(0.0);
            parts.surface(
                Geometry::Plane {
                    frame: Frame {
                        origin: frame.origin + z * w,
                        u: frame.u,
                        v: -frame.v,
                        w: -w,
                    },
                    shape: Shape2D::Annulus {
                        inner: sd,
                        outer: radius,
                    },
                },
                Interaction::Absorber,
                element,
            );
        }
        before = after;
    }
    // The ground edge between the first and the last surface's rims.
    let rim = |k: usize| {
        let s = &p.surfaces[k];
        vz[k] + s.shape.sag(s.semi_diameter_m.powi(2)).unwrap_or(0.0)
    };
    let (z1, z2) = (rim(0), rim(p.surfaces.len() - 1));
    parts.surface(
        Geometry::Cylinder {
            base: frame.origin + z1 * w,
            axis: w,
            radius,
            length: z2 - z1,
        },
        Interaction::Absorber,
        element,
    );
}
