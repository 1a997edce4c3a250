//! `spibench dataset`: shards made in separate processes merge into the single-process dataset
//! bit for bit, a killed run resumes to the same samples, merges refuse overlaps and gaps,
//! corrupted shards are found, and bad specs are located input errors.

use std::path::{Path, PathBuf};

use spibench::acquisition::Sequence;
use spibench::dataset::contract::{
    CellArray, MANIFEST, PATTERNS, SampleArray, TOLERANCE_COPY, array_file, is_shard_dir,
    is_shard_staging, scope_array, shard_dir,
};

use crate::common::{TempDir, assert_input_error, read_json, spibench, stderr};

/// A tiny spec (a kernel of 8192 rays, 24×24 objects, 10 samples in shards of 3) in `dir`.
fn write_spec(dir: &Path, edits: &[(&str, &str)]) -> PathBuf {
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let mut text = format!(
        "Dataset(\n    bench: {:?},\n    kernel: (rays: 8192, seed: 1, grid_px: (24, 24), field_mm: (7.88, 7.88)),\n    objects: TestImages(names: [\"astronaut\", \"coffee\"], rule: RandomCrop),\n    acquisition: (schemes: [SecondaryComplementaryBalancing, DoubleArm], ratios: [0.05]),\n    seed: 7,\n    samples: 10,\n    shard_samples: 3,\n)\n",
        bench.display().to_string()
    );
    for (a, b) in edits {
        assert_eq!(text.matches(a).count(), 1, "edit {a}");
        text = text.replace(a, b);
    }
    let p = dir.join("spec.ron");
    std::fs::write(&p, text).unwrap();
    p
}

fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "spibench failed: {}", stderr(o));
}

/// Every shard file of a dataset folder, by relative path.
/// The stderr line on the shards' writing gives four durations (arrays, manifest, waits, the
/// loops' tails past their last samples), each a time of this run: finite, not negative, the
/// tails no longer than the run (the summary line's seconds).
fn writing_figures_are_times_within_the_run(o: &std::process::Output) {
    let seconds = |line: &str| -> Vec<f64> {
        line.split_whitespace()
            .zip(line.split_whitespace().skip(1))
            .filter(|(_, unit)| unit.trim_end_matches([',', ';', ')']) == "s")
            .map(|(v, _)| v.parse::<f64>().unwrap_or(f64::NAN))
            .collect()
    };
    let err = stderr(o);
    let line = err
        .lines()
        .find(|l| l.starts_with("shard writing:"))
        .unwrap_or_else(|| panic!("no shard writing line: {err}"));
    assert!(line.contains("outlasted their last samples by"), "{line}");
    let w = seconds(line);
    assert_eq!(w.len(), 4, "{line}");
    assert!(w.iter().all(|v| v.is_finite() && *v >= 0.0), "{line}");
    let out = String::from_utf8_lossy(&o.stdout);
    let summary = out
        .lines()
        .find(|l| l.contains("outside the sample loops"))
        .unwrap_or_else(|| panic!("no summary line: {out}"));
    let total = *seconds(summary).last().unwrap();
    assert!(total > 0.0 && w[3] <= total, "{line} / {summary}");
}

fn shard_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        if is_shard_dir(&name) {
            for f in std::fs::read_dir(e.path()).unwrap().flatten() {
                v.push((
                    format!("{name}/{}", f.file_name().to_string_lossy()),
                    std::fs::read(f.path()).unwrap(),
                ));
            }
        }
    }
    v.sort();
    v
}

#[test]
fn shards_in_separate_processes_merge_bit_identically() {
    let t = TempDir::new("dataset-shards");
    let spec = write_spec(&t.0, &[]);
    let s = spec.to_str().unwrap();
    let one = t.join("one");
    let o = spibench(&["dataset", s, "--out", one.to_str().unwrap()], &[]);
    ok(&o);
    writing_figures_are_times_within_the_run(&o);
    let jobs: Vec<PathBuf> = (0..3).map(|i| t.join(&format!("job{i}"))).collect();
    let children: Vec<_> = jobs
        .iter()
        .enumerate()
        .map(|(i, d)| {
            std::process::Command::new(env!("CARGO_BIN_EXE_spibench"))
                .args(["dataset", s, "--out", d.to_str().unwrap(), "--shard"])
                .arg(format!("{i}/3"))
                .output()
        })
        .collect();
    for c in children {
        ok(&c.unwrap());
    }
    let merged = t.join("merged");
    let mut args = vec!["dataset", "--out", merged.to_str().unwrap(), "--merge"];
    args.extend(jobs.iter().map(|j| j.to_str().unwrap()));
    ok(&spibench(&args, &[]));
    let a = shard_files(&one);
    assert_eq!(a.len(), 4 * 6, "4 shards of 6 arrays");
    assert_eq!(a, shard_files(&merged));
    // The manifest's schema matches the arrays: names, dtype, shapes (read with spibench's reader).
    crate::outputs_schema::check_file(&merged.join(MANIFEST), "DatasetManifest");
    crate::outputs_schema::check_file(&one.join(MANIFEST), "DatasetManifest");
    let m = read_json(&merged.join(MANIFEST));
    for shard in m["shards"].as_array().unwrap() {
        let n = shard["samples"].as_u64().unwrap() as usize;
        for a in m["schema"].as_array().unwrap() {
            let p = merged
                .join(shard["dir"].as_str().unwrap())
                .join(array_file(a["name"].as_str().unwrap()));
            let arr = spibench::report::npy::read(&p).unwrap();
            let mut shape = vec![n];
            shape.extend(
                a["sample_shape"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_u64().unwrap() as usize),
            );
            assert_eq!(arr.shape, shape, "{}", p.display());
            assert_eq!(arr.dtype(), a["dtype"].as_str().unwrap());
        }
    }
    // Overlap: job 0 twice.
    let bad = t.join("bad");
    let o = spibench(
        &[
            "dataset",
            "--out",
            bad.to_str().unwrap(),
            "--merge",
            jobs[0].to_str().unwrap(),
            jobs[0].to_str().unwrap(),
            jobs[1].to_str().unwrap(),
            jobs[2].to_str().unwrap(),
        ],
        &[],
    );
    assert_input_error(&o, &["shard 0", "in both"], &bad);
    // Gap: job 1 missing.
    let o = spibench(
        &[
            "dataset",
            "--out",
            bad.to_str().unwrap(),
            "--merge",
            jobs[0].to_str().unwrap(),
            jobs[2].to_str().unwrap(),
        ],
        &[],
    );
    assert_input_error(&o, &["missing"], &bad);
    // A flipped byte in a shard: merge and resume both find it.
    let object = array_file(SampleArray::Object.name());
    let victim = jobs[2].join(shard_dir(3)).join(&object);
    let mut bytes = std::fs::read(&victim).unwrap();
    let k = bytes.len() - 5;
    bytes[k] ^= 0x10;
    std::fs::write(&victim, bytes).unwrap();
    let mut args = vec!["dataset", "--out", bad.to_str().unwrap(), "--merge"];
    args.extend(jobs.iter().map(|j| j.to_str().unwrap()));
    assert_input_error(&spibench(&args, &[]), &["corrupted", &object], &bad);
    let o = spibench(
        &[
            "dataset",
            s,
            "--out",
            jobs[2].to_str().unwrap(),
            "--shard",
            "2/3",
            "--resume",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("corrupted"), "{}", stderr(&o));
}

#[cfg(unix)]
#[test]
fn killed_run_resumes_to_the_same_samples() {
    let t = TempDir::new("dataset-resume");
    let spec = write_spec(&t.0, &[("samples: 10", "samples: 30")]);
    let s = spec.to_str().unwrap();
    let one = t.join("one");
    ok(&spibench(
        &["dataset", s, "--out", one.to_str().unwrap()],
        &[],
    ));
    let killed = t.join("killed");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_spibench"))
        .args(["dataset", s, "--out", killed.to_str().unwrap()])
        .stderr(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Wait until at least one shard is committed (or the run ends), then SIGKILL.
    let manifest = killed.join(MANIFEST);
    for _ in 0..6000 {
        if let Ok(text) = std::fs::read_to_string(&manifest)
            && text.contains(&format!("{:?}", shard_dir(0)))
        {
            break;
        }
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let _ = child.kill();
    let _ = child.wait();
    ok(&spibench(
        &["dataset", s, "--out", killed.to_str().unwrap(), "--resume"],
        &[],
    ));
    assert_eq!(shard_files(&one), shard_files(&killed));
    let names: Vec<String> = std::fs::read_dir(&killed)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .collect();
    assert!(names.iter().all(|n| !n.contains("partial")), "{names:?}");
}

/// SIGTERM while the folder is set up (its first files and manifest) or while shards are being
/// written (up to three at once, each in its own staging folder) leaves no temporary file or
/// staging folder and no lock file, exits with 143, and `--resume` makes the bytes of an
/// uninterrupted run (from the committed shards, or afresh when no manifest was written). A run
/// that ends before the signal arrives must leave the same.
#[cfg(unix)]
#[test]
fn sigterm_while_setting_up_or_writing_shards_leaves_a_resumable_folder() {
    let t = TempDir::new("dataset-sigterm");
    let spec = write_spec(
        &t.0,
        &[
            ("samples: 10", "samples: 160"),
            ("shard_samples: 3", "shard_samples: 4"),
        ],
    );
    let s = spec.to_str().unwrap();
    let one = t.join("one");
    ok(&spibench(
        &["dataset", s, "--out", one.to_str().unwrap()],
        &[],
    ));
    let names = |d: &Path| -> Vec<String> {
        std::fs::read_dir(d)
            .map(|r| {
                r.flatten()
                    .map(|e| e.file_name().to_string_lossy().to_string())
                    .collect()
            })
            .unwrap_or_default()
    };
    let setup = |n: &str| n.ends_with(".partial") && !is_shard_staging(n);
    let shard = |n: &str| is_shard_staging(n);
    for (when, staged) in [
        ("setup", &setup as &dyn Fn(&str) -> bool),
        ("shards", &shard),
    ] {
        let out = t.join(when);
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_spibench"))
            .args(["dataset", s, "--out", out.to_str().unwrap()])
            .stderr(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .spawn()
            .unwrap();
        // Signal once such a piece is staged (or the run has ended).
        let start = std::time::Instant::now();
        while start.elapsed() < std::time::Duration::from_secs(60)
            && !names(&out).iter().any(|n| staged(n))
            && child.try_wait().unwrap().is_none()
        {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        let killed = std::process::Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        let status = child.wait().unwrap();
        if killed.success() && !status.success() {
            assert_eq!(status.code(), Some(143), "{when}");
        }
        let left = names(&out);
        assert!(
            left.iter().all(|n| !n.contains("partial")),
            "{when}: {left:?}"
        );
        assert!(
            names(&t.0).iter().all(|n| !n.contains("spibench-lock")),
            "{when}: {:?}",
            names(&t.0)
        );
        ok(&spibench(
            &["dataset", s, "--out", out.to_str().unwrap(), "--resume"],
            &[],
        ));
        assert_eq!(shard_files(&one), shard_files(&out), "{when}");
    }
}

#[test]
fn bad_specs_are_located_input_errors() {
    let t = TempDir::new("dataset-bad");
    let out = t.join("out");
    let o = out.to_str().unwrap();
    let empty = t.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let junk = t.join("junk");
    std::fs::create_dir_all(&junk).unwrap();
    std::fs::write(junk.join("broken.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let small = t.join("small");
    std::fs::create_dir_all(&small).unwrap();
    let tiny = spibench::raster::Raster::new(8, 8, vec![0.5; 64]).unwrap();
    spibench::report::png::write_gray8(&small.join("tiny.png"), &tiny, 0.0, 1.0).unwrap();
    let tol = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/tolerances/paper_bench.ron")
        .display()
        .to_string();
    let bad_tol = t.join("bad_tolerances.ron");
    std::fs::write(
        &bad_tol,
        "(tolerances: [(path: \"no_such_lens.despace_mm\", range: PlusMinus(0.1))])",
    )
    .unwrap();
    let bad_tol = bad_tol.display().to_string();
    let folder = |p: &Path| {
        format!(
            "objects: Folder(path: {:?}, rule: RandomCrop),",
            p.display().to_string()
        )
    };
    let cases: Vec<(String, Vec<&str>)> = vec![
        (folder(&empty), vec!["no PNG", "objects"]),
        (folder(&junk), vec!["unreadable image", "broken.png"]),
        (folder(&small), vec!["smaller than", "tiny.png"]),
        ("samples: 0,".into(), vec!["samples", "from 1 to", "line 7"]),
        (
            "samples: 9000000, max_disk_gb: 1.0,".into(),
            vec!["GB", "max_disk_gb"],
        ),
        (
            "acquisition: (schemes: [DoubleArm], ratios: [0.05], \
             patterns: Hadamard(ordering: CakeCutting)),"
                .into(),
            vec!["patterns", "line 5"],
        ),
        (
            "seed: 7,\n    electronics: (oscilloscope: (bits: 40)),".into(),
            vec!["bits", "from 1 to 24", "line 7"],
        ),
        (
            "seed: 7, benches: Tolerance(file: \"nowhere.ron\", samples_per_bench: 2),".into(),
            vec![
                "tolerance file",
                "nowhere.ron",
                "does not exist",
                "field `file`",
                "line 6",
            ],
        ),
        (
            format!("seed: 7, benches: Tolerance(file: {tol:?}, samples_per_bench: 0),"),
            vec!["samples_per_bench`", "from 1 to", "line 6"],
        ),
        (
            format!("seed: 7, benches: Tolerance(file: {bad_tol:?}, samples_per_bench: 2),"),
            vec!["bad_tolerances.ron", "no_such_lens", "line 1"],
        ),
        (
            "kernel: (rays: 8192, seed: 1, grid_px: (24, 24), field_mm: (7.88, 7.88), \
             chart: \"nope\"),"
                .into(),
            vec![
                "no chart named \"nope\"",
                "its charts",
                "field `chart`",
                "line 3",
            ],
        ),
    ];
    for (k, (replacement, fragments)) in cases.iter().enumerate() {
        let from = if replacement.starts_with("objects") {
            "objects: TestImages(names: [\"astronaut\", \"coffee\"], rule: RandomCrop),"
        } else if replacement.starts_with("seed") {
            "seed: 7,"
        } else if replacement.starts_with("kernel") {
            "kernel: (rays: 8192, seed: 1, grid_px: (24, 24), field_mm: (7.88, 7.88)),"
        } else if replacement.starts_with("acquisition") {
            "acquisition: (schemes: [SecondaryComplementaryBalancing, DoubleArm], ratios: [0.05]),"
        } else {
            "samples: 10,"
        };
        let dir = t.join(&format!("case{k}"));
        std::fs::create_dir_all(&dir).unwrap();
        let spec = write_spec(&dir, &[(from, replacement.as_str())]);
        let r = spibench(&["dataset", spec.to_str().unwrap(), "--out", o], &[]);
        assert_input_error(&r, fragments, &out);
        // The file at fault is named: the spec, or the tolerance file it points to.
        let file = if fragments.contains(&"bad_tolerances.ron") {
            "bad_tolerances.ron"
        } else {
            "spec.ron"
        };
        assert!(stderr(&r).contains(file), "{}", stderr(&r));
    }
}

/// `spibench patterns`: packed rows as numpy.packbits gives them, and 1-bit PNG frames at the
/// DMD's mirror resolution with each unit expanded to its mirrors (pattern centred).
#[test]
fn patterns_exports_packed_rows_and_mirror_frames() {
    let t = TempDir::new("patterns");
    let out = t.join("p");
    ok(&spibench(
        &[
            "patterns",
            "--family",
            "hadamard",
            "--ordering",
            "natural",
            "--units",
            "4x4",
            "--ratio",
            "0.5",
            "--complement",
            "--mirrors-per-unit",
            "2",
            "--dmd",
            "12x10",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    ));
    let p = spibench::report::npy::read(&out.join("patterns.npy")).unwrap();
    assert_eq!(p.shape, vec![16, 2]);
    let bytes = match p.data {
        spibench::report::npy::NpyData::U8(b) => b,
        other => panic!("{other:?}"),
    };
    // Natural Hadamard row 0 is all ones; its complement all zeros.
    assert_eq!(&bytes[..4], &[0xFF, 0xFF, 0x00, 0x00]);
    let frame = |k: usize| {
        image::open(out.join(format!("frame_{k:05}.png")))
            .unwrap()
            .to_luma8()
    };
    let (f0, f1) = (frame(0), frame(1));
    assert_eq!(f0.dimensions(), (12, 10));
    // The 8 x 8 mirrors of the pattern sit at (2..10, 1..9): on in frame 0, off in frame 1.
    assert_eq!(f0.get_pixel(2, 1).0[0], 255);
    assert_eq!(f0.get_pixel(9, 8).0[0], 255);
    assert_eq!(f0.get_pixel(1, 1).0[0], 0);
    assert_eq!(f0.get_pixel(2, 9).0[0], 0);
    assert_eq!(f1.get_pixel(5, 5).0[0], 0);
    // 16 frames, patterns.npy and patterns.json.
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 18);
    let meta = read_json(&out.join("patterns.json"));
    assert_eq!(meta["family"], "hadamard");
    assert_eq!(meta["ordering"], "natural");
    assert_eq!(meta["frames"], 16);
    assert_eq!(meta["mirrors_per_unit"], 2);
    assert_eq!(meta["pattern_origin_mirror"], serde_json::json!([2, 1]));
    assert!(meta["frame_order"].as_str().unwrap().contains("complement"));
}

/// Without --dmd the frames are the size of the bench's DMD (the built-in bench: 1024 × 768,
/// the DLP7000 class), and patterns.json says where the size came from.
#[test]
fn patterns_default_to_the_benchs_dmd() {
    let t = TempDir::new("patterns-dmd");
    let out = t.join("p");
    ok(&spibench(
        &[
            "patterns",
            "--family",
            "random",
            "--units",
            "4x4",
            "--ratio",
            "0.25",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    ));
    let f = image::open(out.join("frame_00000.png")).unwrap().to_luma8();
    assert_eq!(f.dimensions(), (1024, 768));
    let meta = read_json(&out.join("patterns.json"));
    assert_eq!(
        (meta["dmd_columns"].clone(), meta["dmd_rows"].clone()),
        (1024.into(), 768.into())
    );
    assert!(
        meta["dmd_from"].as_str().unwrap().contains("dmd.columns"),
        "{meta}"
    );
    assert_eq!(meta["seed"], 1);
}

/// The bench comes in as every bench command takes it: a positional SCENE (here a copy of the
/// paper bench with a 1280-column DMD), with `--set` edits, or through the older `--scene`,
/// which gives the same frames.
#[test]
fn patterns_take_the_bench_as_the_other_commands_do() {
    let t = TempDir::new("patterns-scene");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("scenes/paper_bench.ron")).unwrap();
    assert!(text.contains("columns: 1024,"));
    let bench = t.join("wide.ron");
    std::fs::write(&bench, text.replace("columns: 1024,", "columns: 1280,")).unwrap();
    let b = bench.to_str().unwrap();
    let base = [
        "patterns", "--family", "random", "--units", "4x4", "--ratio", "0.25",
    ];
    for (tag, how) in [
        ("positional", vec![b, "--set", "dmd.tilt_deg=12"]),
        ("flag", vec!["--scene", b]),
    ] {
        let out = t.join(tag);
        let mut args: Vec<&str> = base.to_vec();
        args.extend(how);
        args.extend(["--out", out.to_str().unwrap()]);
        ok(&spibench(&args, &[]));
        let f = image::open(out.join("frame_00000.png")).unwrap().to_luma8();
        assert_eq!(f.dimensions(), (1280, 768), "{tag}");
        let meta = read_json(&out.join("patterns.json"));
        assert!(
            meta["dmd_from"].as_str().unwrap().contains("wide"),
            "{tag}: {meta}"
        );
    }
    // An edit the bench cannot take is refused naming it.
    let out = t.join("bad");
    let mut args: Vec<&str> = base.to_vec();
    args.extend([
        "--set",
        "no_such_element.despace_mm=1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_input_error(&spibench(&args, &[]), &["no_such_element"], &out);
}

/// One array of a dataset folder, every shard's rows in sample order.
fn dataset_array(dir: &Path, name: &str) -> (Vec<usize>, Vec<f64>) {
    let m = read_json(&dir.join(MANIFEST));
    let mut shards: Vec<&serde_json::Value> = m["shards"].as_array().unwrap().iter().collect();
    shards.sort_by_key(|s| s["index"].as_u64().unwrap());
    let mut shape = Vec::new();
    let mut data = Vec::new();
    for s in shards {
        let a = spibench::report::npy::read(
            &dir.join(s["dir"].as_str().unwrap()).join(array_file(name)),
        )
        .unwrap();
        shape = a.shape[1..].to_vec();
        data.extend(a.to_f64());
    }
    (shape, data)
}

/// Benches drawn from a tolerance file: samples s with the same ⌊s/4⌋ see the same drawn bench
/// (its index and deviations are arrays of the dataset, its k± its own), shards made apart merge
/// bit for bit, and zero tolerances give the nominal dataset's samples exactly.
#[test]
fn drawn_benches_serve_samples_per_bench_samples() {
    let t = TempDir::new("dataset-drawn");
    let drawn_from = |tol: &Path| {
        [(
            "seed: 7,",
            format!(
                "seed: 7,\n    benches: Tolerance(file: {:?}, samples_per_bench: 4),",
                tol.display().to_string()
            ),
        )]
    };
    // Zero tolerances: every drawn bench is the nominal one.
    let zero = t.join("zero.ron");
    std::fs::write(
        &zero,
        "(tolerances: [(path: \"dmd.tilt_deg\", range: PlusMinus(0.0)), \
         (path: \"detectors.minus.decenter_mm.x\", range: Between(0.0, 0.0), \
         distribution: Normal(sigmas: 2.0))])",
    )
    .unwrap();
    let shipped = drawn_from(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tolerances/paper_bench.ron"),
    );
    let outs = made_datasets(&t.0, &[&shipped, &[], &drawn_from(&zero)]);
    let (one, nout, zout) = (&outs[0], &outs[1], &outs[2]);
    let spec = one.parent().unwrap().join("spec.ron");
    let s = spec.to_str().unwrap();
    crate::outputs_schema::check_file(&one.join(MANIFEST), "DatasetManifest");
    let m = read_json(&one.join(MANIFEST));
    assert_eq!(m["provenance"]["tolerance_file"], TOLERANCE_COPY);
    assert!(one.join(TOLERANCE_COPY).is_file());
    let (_, bench) = dataset_array(one, "bench");
    assert_eq!(bench, [0., 0., 0., 0., 1., 1., 1., 1., 2., 2.]);
    let (shape, dev) = dataset_array(one, "deviations");
    let n_tol = shape[0];
    assert_eq!(n_tol, 27, "the shipped file's 27 tolerances");
    for s in 0..10 {
        let same = s / 4 * 4;
        assert_eq!(
            dev[s * n_tol..(s + 1) * n_tol],
            dev[same * n_tol..(same + 1) * n_tol]
        );
    }
    assert!(dev[..n_tol] != dev[4 * n_tol..5 * n_tol]);
    assert!(dev[..n_tol].iter().all(|v| v.is_finite()) && dev[..n_tol].iter().any(|v| *v != 0.0));
    // The same objects (keyed by the seed and s) through the nominal bench: every sample's k±
    // differ, since every drawn bench differs from the nominal one.
    assert_eq!(dataset_array(one, "object"), dataset_array(nout, "object"));
    let (_, k) = dataset_array(one, "k");
    let (_, k_nominal) = dataset_array(nout, "k");
    for s in 0..10 {
        for d in 0..2 {
            assert!(k[2 * s + d] != k_nominal[2 * s + d], "sample {s}: {k:?}");
        }
    }
    // Two jobs and a merge: the same files, byte for byte (bench 1 spans the shard boundary at
    // sample 6, so both jobs trace it).
    let jobs: Vec<PathBuf> = (0..2).map(|i| t.join(&format!("job{i}"))).collect();
    for (i, j) in jobs.iter().enumerate() {
        let shard = format!("{i}/2");
        ok(&spibench(
            &[
                "dataset",
                s,
                "--out",
                j.to_str().unwrap(),
                "--shard",
                &shard,
            ],
            &[],
        ));
    }
    let merged = t.join("merged");
    let mut args = vec!["dataset", "--out", merged.to_str().unwrap(), "--merge"];
    args.extend(jobs.iter().map(|j| j.to_str().unwrap()));
    ok(&spibench(&args, &[]));
    assert_eq!(shard_files(one), shard_files(&merged));
    assert!(merged.join(TOLERANCE_COPY).is_file());

    let m = read_json(&nout.join(MANIFEST));
    for a in m["schema"].as_array().unwrap() {
        let name = a["name"].as_str().unwrap();
        assert_eq!(
            dataset_array(zout, name),
            dataset_array(nout, name),
            "array {name}"
        );
    }
    assert!(
        dataset_array(zout, "deviations")
            .1
            .iter()
            .all(|v| *v == 0.0)
    );
}

/// The optional arrays: the oscilloscope's record of the first frames, the reconstructions with
/// the DMD image they are scored against, and scores that `metrics::score` gives again.
#[test]
fn optional_arrays_hold_scope_records_and_scored_reconstructions() {
    let t = TempDir::new("dataset-optional");
    let edits = [
        ("samples: 10,", "samples: 3,".to_string()),
        (
            "shard_samples: 3,",
            "shard_samples: 3,\n    write: (scope_frames: 2, reconstructions: true),".into(),
        ),
    ];
    let out = made_datasets(&t.0, &[&edits]).remove(0);
    crate::outputs_schema::check_file(&out.join(MANIFEST), "DatasetManifest");
    // SCB reads the complementary sequence, double-arm the base one: 2 frames of 440.009
    // samples (1/22 727 Hz at 10 MS/s) each, so 881 samples begin in them.
    for q in [Sequence::Base, Sequence::Complementary] {
        let q = scope_array(q);
        let (shape, v) = dataset_array(&out, &q);
        assert_eq!(shape, [3, 881], "{q}");
        assert_eq!(v.len(), 3 * 3 * 881);
        assert!(v.iter().all(|x| x.is_finite()));
        // A noisy record: not constant within a channel.
        assert!(v[..881].iter().any(|x| *x != v[0]), "{q}");
    }
    let (shape, image) = dataset_array(&out, "dmd_image");
    assert_eq!(shape, [48, 48]);
    for scheme in ["secondary_complementary_balancing", "double_arm"] {
        let (shape, recon) = dataset_array(&out, &CellArray::Reconstruction.name(scheme, 0.05));
        assert_eq!(shape, [48, 48]);
        let (_, scores) = dataset_array(&out, &CellArray::Score.name(scheme, 0.05));
        for s in 0..3 {
            let x = spibench::raster::Raster::new(48, 48, image[s * 2304..(s + 1) * 2304].to_vec())
                .unwrap();
            let max = x.max();
            let truth = x.map(|v| 255.0 * v / max);
            let r = spibench::raster::Raster::new(48, 48, recon[s * 2304..(s + 1) * 2304].to_vec())
                .unwrap();
            let sc = spibench::metrics::score(&truth, &r).unwrap();
            assert_eq!(
                [sc.psnr_db, sc.mssim],
                scores[2 * s..2 * s + 2],
                "{scheme} sample {s}"
            );
            assert!(sc.mssim > 0.0 && sc.mssim <= 1.0);
        }
    }
    // Too many scope frames: a located input error.
    let bad = write_spec(
        &t.0,
        &[(
            "shard_samples: 3,",
            "shard_samples: 3,\n    write: (scope_frames: 1000),",
        )],
    );
    let o = t.join("bad");
    assert_input_error(
        &spibench(
            &[
                "dataset",
                bad.to_str().unwrap(),
                "--out",
                o.to_str().unwrap(),
            ],
            &[],
        ),
        &["scope_frames", "from 0 to 100", "line 9"],
        &o,
    );
}

/// Datasets made from the tiny spec with each set of edits, in folders of their own below
/// `dir`: their output folders.
fn made_datasets(dir: &Path, edits: &[&[(&str, String)]]) -> Vec<PathBuf> {
    let mut outs = Vec::new();
    for (k, e) in edits.iter().enumerate() {
        let d = dir.join(format!("s{k}"));
        std::fs::create_dir_all(&d).unwrap();
        let pairs: Vec<(&str, &str)> = e.iter().map(|(a, b)| (*a, b.as_str())).collect();
        let spec = write_spec(&d, &pairs);
        let out = d.join("out");
        ok(&spibench(
            &[
                "dataset",
                spec.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        ));
        outs.push(out);
    }
    outs
}

/// The spec's pattern family replaces the bench's: another random seed gives other patterns and
/// other measurements of the same objects, and the manifest names the family.
#[test]
fn the_spec_names_the_pattern_family() {
    let t = TempDir::new("dataset-patterns");
    let acq =
        "acquisition: (schemes: [SecondaryComplementaryBalancing, DoubleArm], ratios: [0.05]),";
    let plain = [
        (acq, acq.to_string()),
        (
            "samples: 10,",
            "samples: 2,\n    write: (patterns: true),".into(),
        ),
    ];
    let mut other = plain.clone();
    other[0].1 = acq.replace("]),", "], patterns: Random(seed: 5)),");
    let outs = made_datasets(&t.0, &[&plain, &other]);
    let label = |o: &Path| read_json(&o.join(MANIFEST))["pattern_family"].clone();
    assert_ne!(label(&outs[0]), label(&outs[1]));
    assert!(
        label(&outs[1]).to_string().contains('5'),
        "{}",
        label(&outs[1])
    );
    assert_eq!(
        dataset_array(&outs[0], "object"),
        dataset_array(&outs[1], "object")
    );
    let m = &CellArray::Measurements.name("double_arm", 0.05);
    assert_ne!(dataset_array(&outs[0], m), dataset_array(&outs[1], m));
    assert_ne!(
        std::fs::read(outs[0].join(PATTERNS)).unwrap(),
        std::fs::read(outs[1].join(PATTERNS)).unwrap()
    );
}

/// The spec's electronics replace the bench's: into 50 Ω the detector's gains halve
/// (docs/bench-facts.md §1.1), so the same objects give other measurements.
#[test]
fn the_spec_names_the_electronics() {
    let t = TempDir::new("dataset-electronics");
    let plain = [("samples: 10,", "samples: 2,".to_string())];
    let fifty = [(
        "samples: 10,",
        "samples: 2,\n    electronics: (detector: (load: FiftyOhm)),".to_string(),
    )];
    let outs = made_datasets(&t.0, &[&plain, &fifty]);
    assert_eq!(
        dataset_array(&outs[0], "object"),
        dataset_array(&outs[1], "object")
    );
    let m = &CellArray::Measurements.name("double_arm", 0.05);
    let (_, high_z) = dataset_array(&outs[0], m);
    let (_, fifty) = dataset_array(&outs[1], m);
    let mean = |v: &[f64]| v.iter().map(|x| x.abs()).sum::<f64>() / v.len() as f64;
    let ratio = mean(&fifty) / mean(&high_z);
    assert!(
        (ratio - 0.5).abs() < 0.05,
        "50 Ω / high-Z measurement ratio {ratio}"
    );
}

/// On one thread each shard is written and committed before the next one's samples (before,
/// on one thread no shard committed until the last sample loop had ended, so an interrupt lost
/// the whole run): SIGTERM once two shards are committed and the last is not yet made, and
/// `--resume` continues from the committed ones to the bytes of an uninterrupted run.
#[cfg(unix)]
#[test]
fn one_thread_commits_shards_as_they_finish() {
    let t = TempDir::new("dataset-one-thread");
    // Eight shards of one sample each, with reconstructions: some 0.1 s of work per shard.
    let spec = write_spec(
        &t.0,
        &[
            ("samples: 10", "samples: 8"),
            ("shard_samples: 3", "shard_samples: 1"),
            ("seed: 7,", "seed: 7,\n    write: (reconstructions: true),"),
        ],
    );
    let s = spec.to_str().unwrap();
    let one = t.join("one");
    let (o1, k1) = (one.to_str().unwrap(), t.join("killed"));
    ok(&spibench(
        &["--threads", "1", "dataset", s, "--out", o1],
        &[],
    ));
    let killed = k1.to_str().unwrap();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_spibench"))
        .args(["--threads", "1", "dataset", s, "--out", killed])
        .stderr(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let committed = |d: &Path| -> usize {
        std::fs::read_to_string(d.join("manifest.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|m| m["shards"].as_array().map(|a| a.len()))
            .unwrap_or(0)
    };
    let last_made =
        |d: &Path| d.join("shard_000007").exists() || d.join(".shard_000007.partial").exists();
    let start = std::time::Instant::now();
    loop {
        if committed(&k1) >= 2 && !last_made(&k1) {
            break;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before two shards were committed with the last one still to make"
        );
        assert!(
            start.elapsed().as_secs() < 300,
            "no shard committed in 300 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let term = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(term.success());
    assert_eq!(child.wait().unwrap().code(), Some(143));
    let kept = committed(&k1);
    assert!((2..8).contains(&kept), "{kept} shards kept");
    let o = spibench(
        &["--threads", "1", "dataset", s, "--out", killed, "--resume"],
        &[],
    );
    ok(&o);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(&format!(
            "{} shards written ({kept} already there)",
            8 - kept
        )),
        "{out}"
    );
    assert_eq!(shard_files(&one), shard_files(&k1));
    let (m1, mk) = (
        read_json(&one.join("manifest.json")),
        read_json(&k1.join("manifest.json")),
    );
    assert_eq!(m1["shards"], mk["shards"]);
}
