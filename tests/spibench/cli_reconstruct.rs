use spibench::acquisition::patterns;
use spibench::reconstruction::{LinearOperator, PackedOperator, PatternForm};
use spibench::report::npy;

use crate::common::*;

/// A 32×32 test object and its ±1 measurements with 40 % random patterns.
fn problem(
    dir: &TempDir,
    packbits: bool,
) -> (
    Vec<f64>,
    std::path::PathBuf,
    std::path::PathBuf,
    std::path::PathBuf,
) {
    let (w, h, m) = (32usize, 32usize, 410usize);
    let x: Vec<f64> = (0..w * h)
        .map(|i| {
            let (r, c) = (i / w, i % w);
            if (8..24).contains(&r) && (10..20).contains(&c) {
                200.0
            } else if r > 26 {
                80.0
            } else {
                20.0
            }
        })
        .collect();
    let p = patterns::random(m, w * h, 99);
    let op = PackedOperator::new(p.clone(), PatternForm::PlusMinusOne);
    let mut y = vec![0.0; m];
    op.apply(&x, &mut y);
    let pp = dir.join("P.npy");
    if packbits {
        let bpr = (w * h).div_ceil(8);
        let mut bytes = vec![0u8; m * bpr];
        for r in 0..m {
            for c in 0..w * h {
                if p.get(r, c) {
                    bytes[r * bpr + c / 8] |= 0x80 >> (c % 8);
                }
            }
        }
        npy::write_u8(&pp, &[m, bpr], &bytes).unwrap();
    } else {
        let bytes: Vec<u8> = (0..m).flat_map(|r| p.row_bytes01(r)).collect();
        npy::write_u8(&pp, &[m, w * h], &bytes).unwrap();
    }
    let yp = dir.join("y.npy");
    npy::write_f64(&yp, &[m], &y).unwrap();
    let xp = dir.join("x.npy");
    npy::write_f64(&xp, &[h, w], &x).unwrap();
    (y, pp, yp, xp)
}

#[test]
fn reconstruct_bytes_and_packbits() {
    for packbits in [false, true] {
        let dir = TempDir::new(if packbits {
            "rec-packbits"
        } else {
            "rec-bytes"
        });
        let (_, pp, yp, xp) = problem(&dir, packbits);
        let out = dir.join("out");
        let o = spibench(
            &[
                "reconstruct",
                "--patterns",
                pp.to_str().unwrap(),
                "--measurements",
                yp.to_str().unwrap(),
                "--size",
                "32x32",
                "--form",
                "pm1",
                "--truth",
                xp.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        for f in [
            "reconstruction.npy",
            "reconstruction.png",
            "reconstruction16.png",
            "reconstruction.exr",
            "summary.json",
        ] {
            assert!(out.join(f).is_file(), "missing {f}");
        }
        crate::outputs_schema::check_file(&out.join("summary.json"), "ReconstructSummary");
        let s = read_json(&out.join("summary.json"));
        // Provenance: the version, the command line and every input file hashed.
        let p = &s["provenance"];
        assert_eq!(p["spibench_version"], env!("CARGO_PKG_VERSION"));
        assert!(p["command"][1] == "reconstruct", "{p}");
        let inputs = p["inputs"].as_array().unwrap();
        assert!(inputs.len() >= 2, "{p}");
        assert!(
            inputs
                .iter()
                .all(|i| i["sha256"].as_str().unwrap().len() == 64)
        );
        assert_eq!(
            s["patterns_encoding"],
            if packbits { "packbits" } else { "uint8_01" }
        );
        // A piecewise-constant object at 40 % noiseless sampling is recovered almost exactly.
        assert!(s["psnr_db"].as_f64().unwrap() > 40.0, "{s}");
        assert!(s["mssim"].as_f64().unwrap() > 0.98, "{s}");
        for key in [
            "iterations",
            "forward_applications",
            "adjoint_applications",
            "relative_residual",
            "time_s",
        ] {
            assert!(!s[key].is_null(), "summary lacks {key}");
        }
        let img = npy::read(&out.join("reconstruction.npy")).unwrap();
        assert_eq!(img.shape, vec![32, 32]);
    }
}

#[test]
fn reconstruct_rejects_bad_input() {
    let dir = TempDir::new("rec-bad");
    let (y, pp, yp, _) = problem(&dir, false);
    let out = dir.join("out");
    let run = |args: &[&str]| {
        let mut a = vec!["reconstruct"];
        a.extend_from_slice(args);
        a.extend_from_slice(&["--out", out.to_str().unwrap()]);
        spibench(&a, &[])
    };
    // Size mismatch between patterns and image.
    let o = run(&[
        "--patterns",
        pp.to_str().unwrap(),
        "--measurements",
        yp.to_str().unwrap(),
        "--size",
        "16x16",
    ]);
    assert_input_error(&o, &["P.npy", "columns"], &out);
    // Fewer measurements than patterns.
    let short = dir.join("short.npy");
    npy::write_f64(&short, &[y.len() - 1], &y[1..]).unwrap();
    let o = run(&[
        "--patterns",
        pp.to_str().unwrap(),
        "--measurements",
        short.to_str().unwrap(),
        "--size",
        "32x32",
    ]);
    assert_input_error(
        &o,
        &["short.npy", "409 measurements for 410 patterns"],
        &out,
    );
    // NaN in the measurements.
    let mut ynan = y.clone();
    ynan[7] = f64::NAN;
    let nan = dir.join("nan.npy");
    npy::write_f64(&nan, &[ynan.len()], &ynan).unwrap();
    let o = run(&[
        "--patterns",
        pp.to_str().unwrap(),
        "--measurements",
        nan.to_str().unwrap(),
        "--size",
        "32x32",
    ]);
    assert_input_error(&o, &["nan.npy", "element 7", "not finite"], &out);
    // Missing file.
    let o = run(&[
        "--patterns",
        dir.join("absent.npy").to_str().unwrap(),
        "--measurements",
        yp.to_str().unwrap(),
        "--size",
        "32x32",
    ]);
    assert_input_error(&o, &["absent.npy"], &out);
    // Not a .npy file.
    let junk = dir.join("junk.npy");
    std::fs::write(&junk, b"not numpy at all").unwrap();
    let o = run(&[
        "--patterns",
        junk.to_str().unwrap(),
        "--measurements",
        yp.to_str().unwrap(),
        "--size",
        "32x32",
    ]);
    assert_input_error(&o, &["junk.npy", ".npy"], &out);
    // Absurd size (clap's usage error, also exit status 2).
    let o = run(&[
        "--patterns",
        pp.to_str().unwrap(),
        "--measurements",
        yp.to_str().unwrap(),
        "--size",
        "100000x100000",
    ]);
    assert_input_error(&o, &["size"], &out);
}

/// `--form 01` with both handlings of the 0/1 system, on 0/1 measurements of the same object
/// at 100 % sampling (noise-free): the zero-mean system recovers the object (the square system
/// is consistent, so a solved one is exact: above 60 dB), the plain one is kept, reported as
/// such, and (on the iteration cap of 300) stays far behind; `converged` agrees with `stop`
/// in both summaries.
#[test]
fn reconstruct_zero_one_handlings() {
    let dir = TempDir::new("rec-01");
    let (w, h) = (16usize, 16usize);
    let n = w * h;
    let x: Vec<f64> = (0..n)
        .map(|i| {
            if (4..12).contains(&(i / w)) && (3..9).contains(&(i % w)) {
                200.0
            } else {
                30.0
            }
        })
        .collect();
    let p = patterns::random(n, n, 17);
    let op = PackedOperator::new(p.clone(), PatternForm::ZeroOne);
    let mut y = vec![0.0; n];
    op.apply(&x, &mut y);
    let pp = dir.join("P.npy");
    let bytes: Vec<u8> = (0..n).flat_map(|r| p.row_bytes01(r)).collect();
    npy::write_u8(&pp, &[n, n], &bytes).unwrap();
    let yp = dir.join("y.npy");
    npy::write_f64(&yp, &[n], &y).unwrap();
    let xp = dir.join("x.npy");
    npy::write_f64(&xp, &[h, w], &x).unwrap();
    let mut psnr = Vec::new();
    for handling in ["zero-mean", "plain"] {
        let out = dir.join(handling);
        let o = spibench(
            &[
                "reconstruct",
                "--patterns",
                pp.to_str().unwrap(),
                "--measurements",
                yp.to_str().unwrap(),
                "--size",
                "16x16",
                "--form",
                "01",
                "--zero-one",
                handling,
                "--truth",
                xp.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let s = read_json(&out.join("summary.json"));
        assert_eq!(s["zero_one_handling"], handling, "{s}");
        assert_eq!(
            s["converged"].as_bool().unwrap(),
            s["stop"] == "Tolerance",
            "{s}"
        );
        psnr.push(s["psnr_db"].as_f64().unwrap());
    }
    assert!(psnr[0] > 60.0, "zero-mean {:.2} dB", psnr[0]);
    assert!(
        psnr[1] < psnr[0] - 3.0,
        "plain {:.2} dB vs zero-mean {:.2} dB",
        psnr[1],
        psnr[0]
    );
}

/// A truth is scored on its own range: the same object on [0, 1] and on its 8-bit scale gets
/// the same PSNR and MSSIM (before, the [0, 1] truth was scored with peak 255: about 48 dB
/// more), the summary and the output say which range was used, `--data-range` overrides it,
/// and a truth far narrower than the declared range draws a warning.
#[test]
fn reconstruct_scores_on_the_truths_range() {
    let dir = TempDir::new("rec-range");
    let (_, pp, yp, xp) = problem(&dir, false);
    let x = npy::read(&xp).unwrap().to_f64();
    let unit = dir.join("x01.npy");
    npy::write_f64(
        &unit,
        &[32, 32],
        &x.iter().map(|v| v / 255.0).collect::<Vec<_>>(),
    )
    .unwrap();
    let run = |truth: &std::path::Path, name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut a = vec![
            "reconstruct",
            "--patterns",
            pp.to_str().unwrap(),
            "--measurements",
            yp.to_str().unwrap(),
            "--size",
            "32x32",
            "--maxit",
            "40",
            "--truth",
            truth.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        let o = spibench(&a, &[]);
        assert!(o.status.success(), "{}", stderr(&o));
        (read_json(&out.join("summary.json")), o)
    };
    let (a, oa) = run(&xp, "a", &[]);
    let (b, _) = run(&unit, "b", &[]);
    let (pa, pb) = (
        a["psnr_db"].as_f64().unwrap(),
        b["psnr_db"].as_f64().unwrap(),
    );
    assert!((pa - pb).abs() < 1e-6, "{pa} dB vs {pb} dB");
    let (ma, mb) = (a["mssim"].as_f64().unwrap(), b["mssim"].as_f64().unwrap());
    assert!((ma - mb).abs() < 1e-6, "{ma} vs {mb}");
    assert_eq!(b["data_range_from"], "truth");
    assert!((b["data_range"]["hi"].as_f64().unwrap() - 200.0 / 255.0).abs() < 1e-12);
    assert!(stdout(&oa).contains("data range [20, 200] from the truth's own min and max"));
    // The old scale, now asked for explicitly: peak 255 on a truth spanning 180.
    let (c, oc) = run(&xp, "c", &["--data-range", "0:255"]);
    let pc = c["psnr_db"].as_f64().unwrap();
    // 20·log₁₀(255/180) = 3.03 dB from the peak, less what the wider clip lets through.
    let gain = 20.0 * (255.0f64 / 180.0).log10();
    assert!(pc - pa > 1.0 && pc - pa < gain + 1e-6, "{pc} vs {pa}");
    assert_eq!(c["data_range_from"], "--data-range");
    // A [0, 1] truth against a declared 0:255 range is flagged.
    let (_, od) = run(&unit, "d", &["--data-range", "255"]);
    assert!(
        stderr(&od).contains("under a quarter of the data range"),
        "{}",
        stderr(&od)
    );
    assert!(
        !stderr(&oc).contains("warning: the truth spans ["),
        "{}",
        stderr(&oc)
    );
}

/// A truth whose shape is not the image's is an input error even when it holds W·H values.
#[test]
fn reconstruct_rejects_a_truth_of_another_shape() {
    let dir = TempDir::new("rec-shape");
    let (_, pp, yp, xp) = problem(&dir, false);
    let x = npy::read(&xp).unwrap().to_f64();
    let out = dir.join("out");
    for (name, shape) in [("stack.npy", vec![4, 16, 16]), ("wide.npy", vec![16, 64])] {
        let t = dir.join(name);
        npy::write_f64(&t, &shape, &x).unwrap();
        let o = spibench(
            &[
                "reconstruct",
                "--patterns",
                pp.to_str().unwrap(),
                "--measurements",
                yp.to_str().unwrap(),
                "--size",
                "32x32",
                "--truth",
                t.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert_input_error(&o, &[name, "shape", "[32, 32]"], &out);
    }
}
