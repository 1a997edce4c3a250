use glam::DVec3;

use super::shape::refract;
use super::*;
use crate::optics::glass::N_BK7;

fn glass(n: f64) -> Medium {
    Medium {
        name: format!("n{n}"),
        glass: Glass::Constant(n),
        range_nm: None,
        source: "test".into(),
    }
}

fn surface(shape: Shape, sd: f64, t: f64, medium: Medium) -> LensSurface {
    LensSurface {
        shape,
        semi_diameter_m: sd,
        thickness_m: t,
        medium_after: medium,
    }
}

fn singlet(c1: f64, c2: f64, t: f64, n: f64) -> Prescription {
    Prescription {
        name: "singlet".into(),
        surfaces: vec![
            surface(Shape::Sphere { c: c1 }, 0.01, t, glass(n)),
            surface(Shape::Sphere { c: c2 }, 0.01, 0.0, Medium::air()),
        ],
        image_distance_m: None,
    }
}

/// The thick-lens formula 1/f = (n − 1)[c₁ − c₂ + (n − 1) t c₁ c₂ / n], BFL = f (1 − (n − 1) t c₁ / n)
/// and FFL = f (1 + (n − 1) t c₂ / n) (Hecht, Optics, §6.2), and its thin-lens limit.
#[test]
fn thick_and_thin_lens_closed_forms() {
    let (c1, c2, n) = (1.0 / 0.05, -1.0 / 0.08, 1.5);
    for t in [6e-3, 1e-4, 1e-8] {
        let p = singlet(c1, c2, t, n).paraxial(850e-9).unwrap();
        let f = 1.0 / ((n - 1.0) * (c1 - c2 + (n - 1.0) * t * c1 * c2 / n));
        let bfl = f * (1.0 - (n - 1.0) * t * c1 / n);
        let ffl = f * (1.0 + (n - 1.0) * t * c2 / n);
        let efl = p.efl_m.unwrap();
        assert!((efl - f).abs() < 1e-14 * f, "t {t}: {efl} vs {f}");
        assert!((p.bfl_m.unwrap() - bfl).abs() < 1e-14 * f);
        assert!((p.ffl_m.unwrap() - ffl).abs() < 1e-14 * f);
        if t < 1e-6 {
            let thin = 1.0 / ((n - 1.0) * (c1 - c2));
            assert!((efl - thin).abs() < 1e-6 * thin);
        }
    }
    // A flat window is afocal.
    let w = singlet(0.0, 0.0, 5e-3, 1.5).paraxial(850e-9).unwrap();
    assert_eq!(w.efl_m, None);
}

/// A paraboloid reflects every ray parallel to its axis through its focus at R/2: a check of
/// the exact intersection and the analytic normal, with no refraction in it.
#[test]
fn paraboloid_sends_parallel_rays_through_its_focus() {
    let r = 0.04;
    let shape = Shape::Conic {
        c: 1.0 / r,
        k: -1.0,
    };
    for h in [1e-5, 1e-3, 0.01, 0.03, 0.1] {
        let o = DVec3::new(0.0, h, -0.01);
        let t = shape.intersect(o, DVec3::Z, 0.2, 0.0).unwrap();
        let p = o + t * DVec3::Z;
        assert!((p.z - h * h / (2.0 * r)).abs() < 1e-15);
        let n = shape.normal(p).unwrap();
        let d = DVec3::Z - 2.0 * DVec3::Z.dot(n) * n;
        // The reflected ray meets the axis at z = R/2.
        let z_axis = p.z - p.y * d.z / d.y;
        assert!((z_axis - r / 2.0).abs() < 1e-15, "h {h}: {z_axis}");
    }
}

/// The even asphere's Newton intersection lands on the sag to rounding for rays of every
/// slope, and rays outside the aperture or the sag's domain are misses, never NaN.
#[test]
fn asphere_intersections_lie_on_the_sag_and_misses_are_clean() {
    let shape = Shape::EvenAsphere {
        c: 1.0 / 0.02,
        k: -0.8,
        a: [
            0.0,
            1e-5 * 1e9,
            -2e-7 * 1e15,
            3e-9 * 1e21,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
    };
    let sd = 8e-3;
    let mut hits = 0;
    for i in 0..200 {
        let y = -0.012 + 0.024 * i as f64 / 199.0;
        for slope in [-0.3, -0.05, 0.0, 0.1, 0.4] {
            let o = DVec3::new(0.3 * y, y, -0.01);
            let d = DVec3::new(0.0, slope, 1.0).normalize();
            match shape.intersect(o, d, sd, 0.0) {
                Some(t) => {
                    let p = o + t * d;
                    let s = p.x * p.x + p.y * p.y;
                    assert!(s <= sd * sd);
                    assert!((p.z - shape.sag(s).unwrap()).abs() < 1e-15);
                    assert!(shape.normal(p).unwrap().is_finite());
                    hits += 1;
                }
                None => {
                    // A miss is a ray whose aperture crossing lies outside the semi-diameter.
                    let p = o + (-o.z / d.z) * d;
                    assert!(
                        p.x * p.x + p.y * p.y > 0.5 * sd * sd,
                        "y {y}, slope {slope}"
                    );
                }
            }
        }
    }
    assert!(hits > 300);
    // Beyond a sphere's domain the sag is undefined, not NaN.
    let sphere = Shape::Sphere { c: 100.0 };
    assert_eq!(sphere.sag(0.011 * 0.011), None);
    assert!(sphere.sag(0.0099 * 0.0099).unwrap().is_finite());
    // A sphere's far branch is never returned: a ray from inside the sphere heading −z.
    let o = DVec3::new(0.0, 0.001, 0.005);
    assert_eq!(sphere.intersect(o, DVec3::Z, 0.0099, 0.0), None);
}

#[test]
fn refraction_obeys_snell_and_total_internal_reflection_is_a_miss() {
    let n = DVec3::Z;
    let d = DVec3::new(0.0, 0.5_f64.sin(), 0.5_f64.cos());
    let out = refract(d, n, 1.0, 1.5).unwrap();
    assert!((out.y - 0.5_f64.sin() / 1.5).abs() < 1e-15);
    assert!((out.length() - 1.0).abs() < 1e-15);
    let steep = DVec3::new(0.0, 1.2_f64.sin(), 1.2_f64.cos());
    assert_eq!(refract(steep, n, 1.5, 1.0), None);
    // A parallel ray too high on a strongly curved back face is internally reflected.
    let p = singlet(0.0, -1.0 / 0.0101, 5e-3, 1.9);
    let n = p.indices(850e-9).unwrap();
    assert!(p.parallel_ray(0.009, 0.01, &n).is_none());
    assert!(p.parallel_ray(0.001, 0.01, &n).is_some());
}

#[test]
fn defects_are_found_and_ranges_enforced() {
    // R = ±20 mm, t = 1 mm, semi-Ø 10 mm: the faces cross.
    let p = singlet(50.0, -50.0, 1e-3, 1.5);
    let mut q = p.clone();
    for s in &mut q.surfaces {
        s.semi_diameter_m = 0.01;
    }
    assert!(matches!(
        q.defect(),
        Some(Defect::Crossing { surface: 0, .. })
    ));
    let mut q = p.clone();
    q.surfaces[0].semi_diameter_m = 0.03;
    assert!(matches!(
        q.defect(),
        Some(Defect::ApertureBeyondSag { surface: 0, .. })
    ));
    assert_eq!(singlet(20.0, -20.0, 6e-3, 1.5).defect(), None);
    let narrow = Medium {
        name: "NARROW".into(),
        glass: N_BK7,
        range_nm: Some((400.0, 700.0)),
        source: "test".into(),
    };
    assert!(narrow.index(600e-9).is_ok());
    let e = narrow.index(850e-9).unwrap_err().to_string();
    assert!(e.contains("NARROW") && e.contains("850"), "{e}");
}

/// In the bench's geometry an asphere surface answers as the shape does, with its normal
/// against the light (−axis at the vertex, as a spherical cap's).
#[test]
fn bench_asphere_geometry_agrees_with_the_shape() {
    use crate::optics::geometry::{Frame, Geometry};
    let shape = Shape::EvenAsphere {
        c: 85.836_909_871_244_64,
        k: -1.1,
        a: [0.0, 3.69e4, -12.85, 0.0, 0.0, 0.0, 0.0, 0.0],
    };
    let axis = DVec3::new(0.3, -0.2, 1.0).normalize();
    let frame = Frame::new(DVec3::new(0.01, 0.02, 0.5), axis, None);
    let g = Geometry::Asphere {
        frame,
        shape,
        aperture: 9e-3,
    };
    let (lo, hi) = g.aabb();
    for h in [0.0, 2e-3, 6e-3, 8.9e-3] {
        let o = frame.to_world(DVec3::new(0.0, h, -0.02));
        let hit = g.intersect(o, axis, 0.0, 1.0).unwrap();
        let t = shape
            .intersect(DVec3::new(0.0, h, -0.02), DVec3::Z, 9e-3, 0.0)
            .unwrap();
        assert!((hit.t - t).abs() < 1e-15);
        let p = o + hit.t * axis;
        assert!(p.cmpge(lo).all() && p.cmple(hi).all());
        if h == 0.0 {
            assert!((hit.normal + axis).length() < 1e-12);
        }
        assert!(hit.normal.dot(axis) < 0.0);
    }
    // Outside the aperture: a miss.
    let o = frame.to_world(DVec3::new(0.0, 9.5e-3, -0.02));
    assert!(g.intersect(o, axis, 0.0, 1.0).is_none());
}
