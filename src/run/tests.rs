//! Tests of the traced experiment: the balanced-output identities of docs/design.md on the paper's
//! bench (noise off, exact to rounding), the paper's main claim on the default bench, saturation
//! reporting and determinism across thread counts.

use std::path::Path;

use super::*;
use crate::acquisition::Scheme;
use crate::detector::{
    ChannelRange, DriftPath, FrameTiming, Illumination, Record, ideal_frames, record,
};
use crate::scene::run::{RunScene, parse_run_scene};
use crate::trace::{TraceOptions, trace};
use crate::transport::Transport;

fn paper_text() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/paper_bench.ron"
    ))
    .unwrap()
}

/// The paper bench text with extra top-level sections and text replacements.
fn scene(extra: &str, edits: &[(&str, &str)]) -> RunScene {
    let mut t = paper_text();
    for (a, b) in edits {
        assert_eq!(t.matches(a).count(), 1, "edit {a}");
        t = t.replace(a, b);
    }
    let end = t.rfind(')').unwrap();
    let t = format!("{}{}\n)\n", &t[..end], extra);
    parse_run_scene(&t, Path::new("test_bench.ron")).unwrap()
}

/// The same 576 × 576 mirrors as 16 × 16 units of 36 × 36: a quick bench for pipeline tests.
const SMALL: (&str, &str) = (
    "pattern: (origin: (224, 96), units_across: 48, units_down: 48, mirrors_per_unit: 12),",
    "pattern: (origin: (224, 96), units_across: 16, units_down: 16, mirrors_per_unit: 36),",
);

fn transport_of(s: &RunScene, rays: u64) -> Transport {
    let t = trace(&s.bench, &TraceOptions::new(rays, 11)).unwrap();
    Transport::from_tallies(&s.bench, &t)
}

/// Records a sequence noise-free: flat drift, ideal channels, no draws.
fn record_ideal(s: &RunScene, t: &Transport, light: &[[f64; 2]]) -> Record {
    let il = Illumination {
        light_a: light,
        ambient_a: t.ambient_a,
        dark_a: t.dark_a,
    };
    let ideal = ideal_frames(&s.detector, &il);
    let channels = [0, 1, 2].map(|o| {
        let (lo, hi) = ideal
            .iter()
            .map(|v| v[o])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        s.scope.channel(o, lo, hi, true)
    });
    let timing = FrameTiming {
        frame_s: 1.0 / s.settings.dmd_rate_hz,
        settling_s: s.settings.settling_time_s,
        sample_rate_hz: s.scope.sample_rate_hz,
    };
    record(
        &s.detector,
        &channels,
        timing,
        &il,
        &DriftPath::flat(light.len(), timing.frame_s),
        1,
        false,
        0,
    )
}

/// docs/design.md: B₁ − B₂ = V(P) − V(1 − P) = G·Σ_j (2P_j − 1)(g₊_j + g₋_j), here through the whole
/// time-domain recording with every noise source off. With a responsivity mismatch s₋ on the
/// minus diode the same holds with s₋·g₋_j.
#[test]
fn scb_difference_is_the_balanced_sum_when_noise_is_off() {
    for s_minus in [1.0, 0.97] {
        let s = scene(
            &format!(
                "electronics: (detector: (responsivity_scale_minus: {s_minus:?})), run: (noise: false),"
            ),
            &[],
        );
        let t = transport_of(&s, 100_000);
        let n = t.units();
        let m = 40;
        let pats = crate::acquisition::patterns::random(m, n, 77);
        let light = t.frame_currents(&pats, m, true);
        let rec = record_ideal(&s, &t, &light);
        let y = Scheme::SecondaryComplementaryBalancing.measurements(&rec.frames, m);
        let g = s.detector.rf.gain_v_per_a;
        let scale = g * (t.g_a[0].iter().sum::<f64>() + t.g_a[1].iter().sum::<f64>());
        for (i, yi) in y.iter().enumerate() {
            // Summed naively, unit by unit.
            let mut want = 0.0;
            for j in 0..n {
                let a = if pats.get(i, j) { 1.0 } else { -1.0 };
                want += a * (t.g_a[0][j] + s_minus * t.g_a[1][j]);
            }
            want *= g;
            // Rounding only: a few ulps of the largest term (the full-scale sum).
            assert!(
                (yi - want).abs() <= 1e-12 * scale,
                "s- = {s_minus}, pattern {i}: {yi} vs {want}"
            );
        }
        assert!(rec.clipped.iter().all(|&c| c == 0));
    }
}

/// docs/design.md: double-arm dual-pixel measures (k'/2)·Âx plus the offset
/// (k₊ − k₋)/2·Σx + b₊ − b₋ (in monitor volts: times the monitor gain). With the transport's
/// per-unit gains the exact form is G_m·[½Σ_j(2P_j − 1)(g₊_j + g₋_j) + ½Σ_j(g₊_j − g₋_j) + c₊ − c₋],
/// and ½Σ(g₊ − g₋) = (k₊ − k₋)/2·Σx by the definition k± = Σg± / Σx.
#[test]
fn double_arm_carries_the_derived_offset() {
    // Plane mirrors: the offset's sign below is the geometric bench's (with the diffractive
    // DMD b₋ falls and the imbalance grows, and the offset changes sign); the identity holds
    // for either model.
    let s = scene(
        "electronics: (detector: (responsivity_scale_minus: 1.0)), run: (noise: false),",
        &[(
            "model: Diffractive(tail_bin_nm: 10.0),",
            "model: Geometric,",
        )],
    );
    let t = transport_of(&s, 100_000);
    let n = t.units();
    let m = 40;
    let pats = crate::acquisition::patterns::random(m, n, 78);
    let light = t.frame_currents(&pats, m, false);
    let rec = record_ideal(&s, &t, &light);
    let y = Scheme::DoubleArm.measurements(&rec.frames, m);
    let gm = s.detector.monitors[0].gain_v_per_a;
    assert_eq!(gm, s.detector.monitors[1].gain_v_per_a);
    let sum_x: f64 = t.x_w.iter().sum();
    let offset = gm * ((t.k[0].value - t.k[1].value) / 2.0 * sum_x + t.b[0].value - t.b[1].value);
    let scale = gm * (t.g_a[0].iter().sum::<f64>() + t.g_a[1].iter().sum::<f64>() + t.c_a[1]);
    let mut residual_offsets = Vec::new();
    for (i, yi) in y.iter().enumerate() {
        let mut signal = 0.0;
        for j in 0..n {
            let a = if pats.get(i, j) { 1.0 } else { -1.0 };
            signal += a * (t.g_a[0][j] + t.g_a[1][j]);
        }
        let rest = yi - gm * signal / 2.0;
        assert!(
            (rest - offset).abs() <= 1e-11 * scale,
            "pattern {i}: offset {rest} vs {offset}"
        );
        residual_offsets.push(rest);
    }
    // The offset is not small on this bench: b₋ (mirrors parked toward arm −) dominates it, and
    // it is of the order of the signal's spread.
    assert!(offset < 0.0);
    let spread = y.iter().map(|v| (v - offset).abs()).fold(0.0, f64::max);
    assert!(
        offset.abs() > 0.3 * spread,
        "offset {offset}, signal spread {spread}"
    );
}

/// The paper's main experimental claim on the default bench (fewer rays than the default run;
/// the claim does not hinge on the Monte Carlo noise of the transport).
#[test]
fn scb_beats_double_arm_at_every_ratio_on_the_paper_bench() {
    let mut s = scene("", &[]);
    s.settings.rays = 400_000;
    s.settings.schemes = Scheme::paper().to_vec();
    let o = run(&s, &TraceRequest::new(s.settings.rays, 1), &|_, _, _| {}).unwrap();
    assert_eq!(o.results.len(), 32);
    for (r, &ratio) in s.settings.sampling_ratios.iter().enumerate() {
        let scb = o
            .result(Scheme::SecondaryComplementaryBalancing, r)
            .unwrap();
        let dbl = o.result(Scheme::DoubleArm, r).unwrap();
        assert!(
            scb.mssim > dbl.mssim,
            "ratio {ratio}: SCB {} vs double-arm {}",
            scb.mssim,
            dbl.mssim
        );
        assert!(!scb.saturated && !dbl.saturated);
        assert_eq!(scb.dmd_frames, 2 * scb.measurements);
        assert_eq!(dbl.dmd_frames, dbl.measurements);
    }
    assert!(o.saturation.is_empty());
    // Frames and acquisition time at 100 %: 2 × 2304 frames at 22 727 Hz.
    let full = o
        .result(Scheme::SecondaryComplementaryBalancing, 7)
        .unwrap();
    assert_eq!(full.measurements, 2304);
    assert!((full.acquisition_time_s - 4608.0 / 22_727.0).abs() < 1e-12);
    // Resolution read-out: x registers against the chart, and the field (group −1, elements
    // 5 and 6: bars of 0.315 and 0.281 mm, about 1.9 and 1.7 units of 0.164 mm) is resolved
    // down to element 6 in x and, at 100 %, in the SCB reconstruction.
    let c = o
        .resolution
        .as_ref()
        .expect("the paper bench's chart registers");
    assert!(
        c.registration_correlation > 0.95,
        "{}",
        c.registration_correlation
    );
    let e6 = |r: Option<crate::run::Resolved>| r.map(|e| (e.group, e.element));
    assert_eq!(e6(c.ideal_finest_resolved), Some((-1, 6)));
    assert_eq!(e6(full.finest_resolved), Some((-1, 6)));
}

/// The fair baselines on the paper bench (48 × 48 units). Noise-free at 100 % sampling,
/// traditional CS solved through the zero-mean system comes within 1 dB of single-arm
/// complementary, which shows the same frames' complements (the plain 0/1 solve does not:
/// its DC singular value stalls TVAL3). With the default electronics noise at 40 %, the
/// two-point calibration lifts double-arm by at least 10 dB.
#[test]
fn fair_baselines_on_the_paper_bench() {
    let mut s = scene("", &[]);
    s.settings.rays = 300_000;
    s.settings.noise = false;
    s.settings.sampling_ratios = vec![1.0];
    s.settings.schemes = vec![
        Scheme::SingleArmComplementary,
        Scheme::Traditional,
        Scheme::TraditionalZeroMean,
    ];
    let o = run(&s, &TraceRequest::new(s.settings.rays, 2), &|_, _, _| {}).unwrap();
    let psnr = |k| o.result(k, 0).unwrap().psnr_db;
    let (single, plain, zero_mean) = (
        psnr(Scheme::SingleArmComplementary),
        psnr(Scheme::Traditional),
        psnr(Scheme::TraditionalZeroMean),
    );
    eprintln!(
        "100 %, noise-free: single-arm {single:.2} dB, traditional plain {plain:.2} dB, zero-mean {zero_mean:.2} dB"
    );
    assert!(
        zero_mean > single - 1.0,
        "zero-mean {zero_mean} vs single-arm {single}"
    );
    assert!(zero_mean > plain, "zero-mean {zero_mean} vs plain {plain}");
    let zm = o.result(Scheme::TraditionalZeroMean, 0).unwrap();
    assert_eq!(zm.dmd_frames, 2304);

    let mut s = scene("", &[]);
    s.settings.rays = 300_000;
    s.settings.sampling_ratios = vec![0.4];
    s.settings.schemes = vec![
        Scheme::DoubleArm,
        Scheme::DoubleArmCalibrated,
        Scheme::DoubleArmOffset,
        Scheme::SecondaryComplementaryBalancing,
    ];
    let o = run(&s, &TraceRequest::new(s.settings.rays, 2), &|_, _, _| {}).unwrap();
    let (plain, calibrated, offset, scb) = (
        o.result(Scheme::DoubleArm, 0).unwrap(),
        o.result(Scheme::DoubleArmCalibrated, 0).unwrap(),
        o.result(Scheme::DoubleArmOffset, 0).unwrap(),
        o.result(Scheme::SecondaryComplementaryBalancing, 0)
            .unwrap(),
    );
    eprintln!(
        "40 %, default noise: double-arm {:.2} dB / {:.4}, calibrated {:.2} dB / {:.4}, \
         offset-aware {:.2} dB / {:.4} ({} iterations, {:?}), SCB {:.2} dB / {:.4}",
        plain.psnr_db,
        plain.mssim,
        calibrated.psnr_db,
        calibrated.mssim,
        offset.psnr_db,
        offset.mssim,
        offset.iterations,
        offset.stop,
        scb.psnr_db,
        scb.mssim
    );
    assert!(
        calibrated.psnr_db > plain.psnr_db + 10.0,
        "calibrated {} dB vs plain {} dB",
        calibrated.psnr_db,
        plain.psnr_db
    );
    // The calibration frames are counted: 16 more frames than patterns.
    assert_eq!(calibrated.dmd_frames, calibrated.measurements + 16);
    assert_eq!(calibrated.detector_samples, 2 * calibrated.dmd_frames);
}

/// A 1 kW lamp (about 1000× the default light) drives the RF output past its swing: the run
/// says so instead of returning silent garbage.
#[test]
fn saturation_is_reported() {
    let s = scene(
        "run: (sampling_ratios: [0.5], rays: 30000),",
        &[
            SMALL,
            ("power: FromFilament,", "power: InBand(watts: 1000.0),"),
        ],
    );
    let o = run(&s, &TraceRequest::new(s.settings.rays, 3), &|_, _, _| {}).unwrap();
    let rf: Vec<_> = o
        .saturation
        .iter()
        .filter(|x| x.output == "rf" && x.kind == "detector_swing")
        .collect();
    assert!(!rf.is_empty(), "{:?}", o.saturation);
    assert!(rf[0].peak_abs_ideal_v > rf[0].limit_v);
    let scb = o
        .result(Scheme::SecondaryComplementaryBalancing, 0)
        .unwrap();
    assert!(scb.saturated);
    // The same bench at the default lamp power is clean.
    let s = scene("run: (sampling_ratios: [0.5], rays: 30000),", &[SMALL]);
    let o = run(&s, &TraceRequest::new(s.settings.rays, 3), &|_, _, _| {}).unwrap();
    assert!(o.saturation.is_empty(), "{:?}", o.saturation);
    assert!(o.results.iter().all(|r| !r.saturated));
}

/// Same seed, same outcome on one and two threads (everything but the timings), and a different
/// seed changes the noise.
#[test]
fn identical_for_one_and_two_threads() {
    let s = scene(
        "run: (sampling_ratios: [0.3, 1.0], rays: 30000, additive_noise: (distribution: Gaussian, std: 1e-4)),",
        &[SMALL],
    );
    let go = |threads: usize, seed: u64| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(&s, &TraceRequest::new(s.settings.rays, seed), &|_, _, _| {}).unwrap())
    };
    let (a, b) = (go(1, 5), go(2, 5));
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.transport.x_w), bits(&b.transport.x_w));
    assert_eq!(a.results.len(), b.results.len());
    for (x, y) in a.results.iter().zip(&b.results) {
        assert_eq!(x.psnr_db.to_bits(), y.psnr_db.to_bits());
        assert_eq!(x.mssim.to_bits(), y.mssim.to_bits());
        assert_eq!(x.iterations, y.iterations);
        assert_eq!(bits(&x.reconstruction.data), bits(&y.reconstruction.data));
    }
    for ((_, x), (_, y)) in a.traces.iter().zip(&b.traces) {
        for o in 0..3 {
            assert_eq!(bits(&x.v[o]), bits(&y.v[o]));
        }
    }
    let c = go(2, 6);
    assert_ne!(
        bits(&a.traces[0].1.v[0]),
        bits(&c.traces[0].1.v[0]),
        "another seed, other noise"
    );
    // Auto ranges come from the noise-free signal.
    assert!(matches!(s.scope.channels[0], ChannelRange::Auto));
}

/// `--repeats 3`: bit-identical statistics on one and two threads; the scores spread where
/// there is noise (the default electronics) and not where there is none.
#[test]
fn repeats_are_deterministic_and_spread_with_noise() {
    use crate::run::repeats::run_repeats;
    let s = scene(
        "run: (sampling_ratios: [0.5], rays: 30000, schemes: [SingleArmComplementary, SecondaryComplementaryBalancing, DoubleArmCalibrated]),",
        &[SMALL],
    );
    let go = |threads: usize, scene: &RunScene| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                run_repeats(
                    scene,
                    &TraceRequest::new(scene.settings.rays, 4),
                    3,
                    &|_, _, _| {},
                )
                .unwrap()
            })
    };
    let ((oa, a), (_, b)) = (go(1, &s), go(2, &s));
    assert_eq!(oa.len(), 3);
    let key = |r: &crate::run::repeats::Repeats| {
        r.stats
            .iter()
            .flat_map(|x| [x.psnr_db_mean, x.psnr_db_sd, x.mssim_mean, x.mssim_sd])
            .chain(r.paired.iter().flat_map(|p| [p.mean, p.sd]))
            .map(f64::to_bits)
            .collect::<Vec<_>>()
    };
    assert_eq!(key(&a), key(&b));
    assert_eq!(
        a.paired.len(),
        4,
        "SCB − single-arm and SCB − calibrated, two metrics"
    );
    assert!(
        a.stats
            .iter()
            .all(|x| x.psnr_db_sd > 0.0 && x.mssim_sd > 0.0),
        "{:?}",
        a.stats
    );
    // Repeat 0 is the plain run with the same seed.
    let plain = run(&s, &TraceRequest::new(s.settings.rays, 4), &|_, _, _| {}).unwrap();
    assert_eq!(
        plain.results[0].psnr_db.to_bits(),
        oa[0].results[0].psnr_db.to_bits()
    );
    // Noise off and Hadamard patterns: every repeat is the same acquisition.
    let mut quiet = s.clone();
    quiet.settings.noise = false;
    quiet.settings.patterns = crate::acquisition::PatternFamily::Hadamard {
        ordering: crate::acquisition::HadamardOrdering::Natural,
    };
    let (_, q) = go(2, &quiet);
    assert!(
        q.stats
            .iter()
            .all(|x| x.psnr_db_sd < 1e-9 && x.mssim_sd < 1e-12),
        "{:?}",
        q.stats
    );
}
