//! Trace throughput of the paper bench with even-asphere arm lenses against the same bench with
//! spherical ones, same run (harness = false, std::time only):
//!
//!     cargo bench --bench lens [-- RAYS]
//!
//! The asphere bench has each arm's LA1050 as an inline `LensSystem` whose curved face is an
//! even asphere (the sphere's R = 51.5 mm, k = 0, and A₄ = 1e−12 mm⁻³, too small to move a ray
//! by more than 1e−5 mm at the rim), so both benches send the same rays along the same paths
//! and the difference is the cost of the Newton intersection alone. The spherical baseline is
//! the bench as shipped; a third, the same lenses as `LensSystem(zmx: "parts/…")` spheres, shows
//! the element itself costs nothing. Runs alternate (sphere, asphere, zmx sphere) three times on
//! one thread; the median time per ray of each and the ratio are printed. The target is
//! a ratio under 1.5.

use std::path::Path;
use std::time::Instant;

use spibench::optics::Bench;
use spibench::pipeline::{TraceRequest, trace_stage};
use spibench::quantities::BenchMetric;
use spibench::scene::bench::{
    ElementSpec, Finite, LengthMm, LensSurfaceSpec, LensSystemSpec, RadiusMm,
};
use spibench::scene::doc::BenchDoc;

fn variant(doc: &BenchDoc, asphere: bool) -> BenchDoc {
    let mut file = doc.file.clone();
    for el in &mut file.elements {
        if let ElementSpec::Lens(l) = el
            && l.name.starts_with("arm_")
        {
            assert!(l.front_radius_mm.is_some() && l.back_radius_mm.is_none());
            let surfaces = vec![
                LensSurfaceSpec {
                    radius_mm: l.front_radius_mm,
                    conic: None,
                    asphere: vec![Finite(1e-12)],
                    semi_diameter_mm: LengthMm(0.5 * l.diameter_mm.0),
                    thickness_mm: Some(l.thickness_mm),
                    glass: Some(l.glass.clone()),
                },
                LensSurfaceSpec {
                    radius_mm: None::<RadiusMm>,
                    conic: None,
                    asphere: Vec::new(),
                    semi_diameter_mm: LengthMm(0.5 * l.diameter_mm.0),
                    thickness_mm: None,
                    glass: None,
                },
            ];
            *el = ElementSpec::LensSystem(LensSystemSpec {
                name: l.name.clone(),
                part: l.part.clone(),
                zmx: (!asphere).then(|| "parts/thorlabs_la1050.zmx".into()),
                surfaces: asphere.then_some(surfaces),
                reversed: false,
                position_mm: l.position_mm,
                axis: l.axis,
                diameter_mm: Some(l.diameter_mm),
                clear_diameter_mm: l.clear_diameter_mm,
                glass_catalogues: Vec::new(),
                allow_glass_substitution: false,
                coating: l.coating.clone(),
                tilt_deg: l.tilt_deg,
            });
        }
    }
    BenchDoc::from_file(file, doc.path())
}

fn timed(bench: &Bench, rays: u64) -> (f64, f64) {
    let start = Instant::now();
    let t = trace_stage(bench, &TraceRequest::new(rays, 7)).expect("trace");
    (
        start.elapsed().as_secs_f64(),
        t.metrics[BenchMetric::KPlus].value,
    )
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let rays: u64 = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .and_then(|a| a.parse().ok())
        .unwrap_or(400_000);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let doc = BenchDoc::read(&path).expect("paper bench");
    let benches = [
        ("spheres (Lens)", doc.build().expect("bench")),
        (
            "even aspheres (LensSystem)",
            variant(&doc, true).build().expect("bench"),
        ),
        (
            "spheres (LensSystem zmx)",
            variant(&doc, false).build().expect("bench"),
        ),
    ];
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut times = vec![Vec::new(); benches.len()];
    let mut k = vec![0.0; benches.len()];
    pool.install(|| {
        for _ in 0..3 {
            for (i, (_, b)) in benches.iter().enumerate() {
                let (s, kp) = timed(b, rays);
                times[i].push(s);
                k[i] = kp;
            }
        }
    });
    let per_ray: Vec<f64> = times.into_iter().map(|t| median(t) / rays as f64).collect();
    for (i, (name, _)) in benches.iter().enumerate() {
        println!(
            "{name:<28} {:>8.3} µs per ray (1 thread, {rays} rays, median of 3), k+ {:.6e}",
            per_ray[i] * 1e6,
            k[i]
        );
    }
    println!(
        "asphere / sphere time per ray: {:.3} (target < 1.5); zmx sphere / sphere: {:.3}",
        per_ray[1] / per_ray[0],
        per_ray[2] / per_ray[0]
    );
}
