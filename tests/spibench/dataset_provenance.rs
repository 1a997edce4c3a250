//! `spibench dataset`: the object images are part of a dataset's provenance. The manifest lists
//! every image read with the SHA-256 of its bytes (`provenance.objects`); a merge of jobs that
//! read different images, and a resume over images that changed, are located input errors that
//! name the object; a merged manifest equals the single-process one but for the command and the
//! merged folders (what examples/slurm/check.sh compares).

use std::path::{Path, PathBuf};

use serde_json::Value;
use spibench::dataset::contract::MANIFEST;
use spibench::dataset::sha256_hex;

use crate::common::{TempDir, assert_input_error, read_json, spibench, stderr};

/// A 32 × 32 grey-level image as `.npy` bytes, its levels drawn from `seed`.
fn image(seed: u64) -> Vec<u8> {
    let data: Vec<f64> = (0..32 * 32u64)
        .map(|i| ((i * 37 + seed * 101) % 256) as f64)
        .collect();
    spibench::report::npy::encode_f64(&[32, 32], &data)
}

/// A tiny spec (8192 rays, 24 × 24 objects, 8 samples in shards of 2) over the image folder
/// `imgs` beside it, which gets the images `a.npy` and `b.npy`.
fn setup(dir: &Path) -> PathBuf {
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let imgs = dir.join("imgs");
    std::fs::create_dir_all(&imgs).unwrap();
    std::fs::write(imgs.join("a.npy"), image(1)).unwrap();
    std::fs::write(imgs.join("b.npy"), image(2)).unwrap();
    let text = format!(
        "Dataset(\n    bench: {:?},\n    kernel: (rays: 8192, seed: 1, grid_px: (24, 24), field_mm: (7.88, 7.88)),\n    objects: Folder(path: \"imgs\", rule: RandomCrop),\n    acquisition: (schemes: [DoubleArm], ratios: [0.05]),\n    seed: 5,\n    samples: 8,\n    shard_samples: 2,\n)\n",
        bench.display().to_string()
    );
    let p = dir.join("spec.ron");
    std::fs::write(&p, text).unwrap();
    p
}

fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "spibench failed: {}", stderr(o));
}

fn make(spec: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "dataset",
        spec.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    spibench(&args, &[])
}

fn merge(out: &Path, inputs: &[&Path]) -> std::process::Output {
    let mut args = vec!["dataset", "--out", out.to_str().unwrap(), "--merge"];
    args.extend(inputs.iter().map(|p| p.to_str().unwrap()));
    spibench(&args, &[])
}

/// A manifest less what a merge changes by design: the command and the folders merged.
fn comparable(dir: &Path) -> Value {
    let mut m = read_json(&dir.join(MANIFEST));
    let p = m["provenance"].as_object_mut().unwrap();
    p.remove("command");
    p.remove("merged_from");
    m
}

#[test]
fn the_manifest_lists_every_object_image_and_a_merge_keeps_them() {
    let t = TempDir::new("dataset-objects");
    let spec = setup(&t.0);
    let one = t.join("one");
    ok(&make(&spec, &one, &[]));
    let m = read_json(&one.join(MANIFEST));
    let objects = m["provenance"]["objects"].as_array().unwrap();
    let listed: Vec<(&str, &str)> = objects
        .iter()
        .map(|o| (o["name"].as_str().unwrap(), o["sha256"].as_str().unwrap()))
        .collect();
    let (a, b) = (sha256_hex(&image(1)), sha256_hex(&image(2)));
    assert_eq!(listed, [("a.npy", a.as_str()), ("b.npy", b.as_str())]);
    crate::outputs_schema::check_file(&one.join(MANIFEST), "DatasetManifest");
    // Shipped test images are listed too, by name, with the hash of the shipped bytes.
    let text = std::fs::read_to_string(&spec).unwrap().replace(
        "Folder(path: \"imgs\", rule: RandomCrop)",
        "TestImages(names: [\"coffee\"], rule: RandomCrop)",
    );
    let shipped = t.join("shipped.ron");
    std::fs::write(&shipped, text).unwrap();
    let s = t.join("shipped");
    ok(&make(&shipped, &s, &["--shard", "0/4"]));
    let m = read_json(&s.join(MANIFEST));
    let o = &m["provenance"]["objects"][0];
    assert_eq!(o["name"], "coffee");
    assert_eq!(
        o["sha256"].as_str().unwrap(),
        sha256_hex(spibench::objects::test_image("coffee").unwrap())
    );
    // Four jobs merged: the manifest of the single run, but for the command and merged_from.
    let jobs: Vec<PathBuf> = (0..4).map(|i| t.join(&format!("job{i}"))).collect();
    for (i, j) in jobs.iter().enumerate() {
        ok(&make(&spec, j, &["--shard", &format!("{i}/4")]));
    }
    let merged = t.join("merged");
    let inputs: Vec<&Path> = jobs.iter().map(PathBuf::as_path).collect();
    ok(&merge(&merged, &inputs));
    assert_eq!(comparable(&one), comparable(&merged));
}

#[test]
fn a_merge_of_jobs_over_other_images_is_refused_naming_the_object() {
    let t = TempDir::new("dataset-objects-merge");
    let spec = setup(&t.0);
    let (job0, job1) = (t.join("job0"), t.join("job1"));
    ok(&make(&spec, &job0, &["--shard", "0/2"]));
    // The image b.npy changes between the two jobs: same spec, same names, other pixels.
    std::fs::write(t.join("imgs/b.npy"), image(3)).unwrap();
    ok(&make(&spec, &job1, &["--shard", "1/2"]));
    let out = t.join("merged");
    let o = merge(&out, &[&job0, &job1]);
    let field = format!(
        "{}, field `provenance.objects[1]`",
        job1.join(MANIFEST).display()
    );
    assert_input_error(&o, &[&field, "b.npy", "other object images"], &out);
    // An image added to the folder between the jobs.
    std::fs::write(t.join("imgs/b.npy"), image(2)).unwrap();
    std::fs::write(t.join("imgs/c.npy"), image(4)).unwrap();
    let job1c = t.join("job1c");
    ok(&make(&spec, &job1c, &["--shard", "1/2"]));
    let o = merge(&out, &[&job0, &job1c]);
    assert_input_error(&o, &["provenance.objects[2]", "c.npy"], &out);
    // With the first job's images back, the merge goes through.
    std::fs::remove_file(t.join("imgs/c.npy")).unwrap();
    let job1a = t.join("job1a");
    ok(&make(&spec, &job1a, &["--shard", "1/2"]));
    ok(&merge(&out, &[&job0, &job1a]));
}

#[test]
fn a_resume_over_changed_images_is_refused_naming_the_object() {
    let t = TempDir::new("dataset-objects-resume");
    let spec = setup(&t.0);
    let job = t.join("job");
    ok(&make(&spec, &job, &["--shard", "0/2"]));
    let before = std::fs::read(job.join(MANIFEST)).unwrap();
    std::fs::write(t.join("imgs/a.npy"), image(5)).unwrap();
    let o = make(&spec, &job, &["--shard", "0/2", "--resume"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for f in ["provenance.objects[0]", "a.npy", "other object images"] {
        assert!(err.contains(f), "stderr lacks {f:?}: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    // The folder is left as it was.
    assert_eq!(before, std::fs::read(job.join(MANIFEST)).unwrap());
    std::fs::write(t.join("imgs/a.npy"), image(1)).unwrap();
    ok(&make(&spec, &job, &["--shard", "0/2", "--resume"]));
}
