//! Files that spibench did not write in this run are untrusted: a dataset manifest whose shard
//! folder or array name leads out of its folder, or a shard folder that is a symbolic link out,
//! is an input error naming the file and the field (exit 2), with nothing written and no file
//! outside the folder opened; a merge checks what it copies, refuses an output that is one of
//! its inputs, and a merge of one folder is a byte-identical copy. Tolerance shard records are
//! checked against their checksum and their names; dataset folders are locked like every
//! output folder.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use serde_json::Value;

use crate::common::{TempDir, assert_input_error, read_json, spibench, stderr, stdout};

/// A tiny dataset spec (10 samples in shards of 3: 4 shards) in `dir`.
pub(crate) fn write_spec(dir: &Path) -> PathBuf {
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    let text = format!(
        "Dataset(\n    bench: {:?},\n    kernel: (rays: 8192, seed: 1, grid_px: (24, 24), field_mm: (7.88, 7.88)),\n    objects: TestImages(names: [\"astronaut\", \"coffee\"], rule: RandomCrop),\n    acquisition: (schemes: [SecondaryComplementaryBalancing, DoubleArm], ratios: [0.05]),\n    seed: 7,\n    samples: 10,\n    shard_samples: 3,\n    write: (patterns: true),\n)\n",
        bench.display().to_string()
    );
    let p = dir.join("spec.ron");
    std::fs::write(&p, text).unwrap();
    p
}

pub(crate) fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "spibench failed: {}", stderr(o));
}

pub(crate) fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Every file below `dir` (links not followed), by relative path, with its bytes.
pub(crate) fn tree(dir: &Path) -> Vec<(String, Vec<u8>)> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<(String, Vec<u8>)>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            let rel = p.strip_prefix(root).unwrap().display().to_string();
            let t = e.file_type().unwrap();
            if t.is_dir() {
                walk(root, &p, out);
            } else if t.is_symlink() {
                out.push((
                    rel,
                    std::fs::read_link(&p).unwrap().display().to_string().into(),
                ));
            } else {
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    let mut v = Vec::new();
    walk(dir, dir, &mut v);
    v.sort();
    v
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let d = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &d);
        } else {
            std::fs::copy(e.path(), d).unwrap();
        }
    }
}

/// Decoys: files that a run following a path out of its folder would read (valid copies of a
/// shard's arrays, so that reading them would let a merge succeed), their access times set far
/// in the past. `opened` tells whether any was read since, where the filesystem records reads.
struct Decoys {
    files: Vec<PathBuf>,
    records_reads: bool,
}

const LONG_AGO: Duration = Duration::from_secs(946_684_800); // 2000-01-01

fn age(p: &Path) {
    let f = std::fs::File::options().write(true).open(p).unwrap();
    f.set_times(std::fs::FileTimes::new().set_accessed(SystemTime::UNIX_EPOCH + LONG_AGO))
        .unwrap();
}

impl Decoys {
    fn new(shard: &Path, outside: &Path) -> Decoys {
        copy_tree(shard, outside);
        let files: Vec<PathBuf> = std::fs::read_dir(outside)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .collect();
        // Does this filesystem record reads (not with `noatime`)? A probe says.
        let probe = outside.with_extension("probe");
        std::fs::write(&probe, b"probe").unwrap();
        age(&probe);
        std::fs::read(&probe).unwrap();
        let records_reads = std::fs::metadata(&probe).unwrap().accessed().unwrap()
            > SystemTime::UNIX_EPOCH + LONG_AGO;
        std::fs::remove_file(&probe).unwrap();
        for f in &files {
            age(f);
        }
        Decoys {
            files,
            records_reads,
        }
    }

    fn assert_unread(&self) {
        if !self.records_reads {
            return;
        }
        for f in &self.files {
            let t = std::fs::metadata(f).unwrap().accessed().unwrap();
            assert_eq!(
                t,
                SystemTime::UNIX_EPOCH + LONG_AGO,
                "{} outside the folder was read",
                f.display()
            );
        }
    }
}

fn edit_manifest(dir: &Path, edit: impl Fn(&mut Value)) {
    let p = dir.join("manifest.json");
    let mut m = read_json(&p);
    edit(&mut m);
    std::fs::write(&p, serde_json::to_string_pretty(&m).unwrap()).unwrap();
}

#[cfg(unix)]
#[test]
fn tampered_dataset_folders_are_refused_before_anything_is_opened() {
    let t = TempDir::new("untrusted-dataset");
    let spec = write_spec(&t.0);
    let good = t.join("good");
    ok(&spibench(&["dataset", s(&spec), "--out", s(&good)], &[]));
    let outside = t.join("outside/evil");
    let decoys = Decoys::new(&good.join("shard_000001"), &outside);
    let abs_outside = outside.display().to_string();
    // (what is done to the folder, the field the message must name)
    type Tamper = Box<dyn Fn(&Path)>;
    let cases: Vec<(&str, Tamper, &str)> = vec![
        (
            "a shard folder up and out",
            Box::new(|d: &Path| {
                edit_manifest(d, |m| m["shards"][1]["dir"] = "../outside/evil".into())
            }),
            "shards[1].dir",
        ),
        (
            "an absolute shard folder",
            Box::new(move |d: &Path| {
                edit_manifest(d, |m| m["shards"][1]["dir"] = abs_outside.clone().into())
            }),
            "shards[1].dir",
        ),
        (
            "an array name out",
            Box::new(|d: &Path| {
                edit_manifest(d, |m| {
                    m["schema"][0]["name"] = "../../../outside/evil/sample".into()
                })
            }),
            "schema[0].name",
        ),
        (
            "a shard file out",
            Box::new(|d: &Path| {
                edit_manifest(d, |m| {
                    m["shards"][1]["files"][1]["file"] = "../../outside/evil/object.npy".into()
                })
            }),
            "shards[1].files[1].file",
        ),
        (
            "a shard folder that is a link out",
            Box::new(|d: &Path| {
                let shard = d.join("shard_000001");
                std::fs::remove_dir_all(&shard).unwrap();
                std::os::unix::fs::symlink(d.join("../outside/evil"), &shard).unwrap();
            }),
            "shards[1].dir",
        ),
        (
            "an array file that is a link out",
            Box::new(|d: &Path| {
                let f = d.join("shard_000001/object.npy");
                std::fs::remove_file(&f).unwrap();
                std::os::unix::fs::symlink(d.join("../outside/evil/object.npy"), &f).unwrap();
            }),
            "shards[1].files[1].file",
        ),
    ];
    for (k, (what, tamper, field)) in cases.iter().enumerate() {
        let d = t.join(&format!("case{k}"));
        copy_tree(&good, &d);
        tamper(&d);
        let before = tree(&d);
        // Merge, alone and with an untouched folder after it.
        let out = t.join(&format!("merged{k}"));
        let o = spibench(&["dataset", "--merge", s(&d), "--out", s(&out)], &[]);
        assert_input_error(&o, &["manifest.json", &format!("field `{field}`")], &out);
        decoys.assert_unread();
        // Resume: refused before any shard is checked or anything removed or written.
        let o = spibench(&["dataset", s(&spec), "--out", s(&d), "--resume"], &[]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{what}: {err}");
        assert!(err.contains(&format!("field `{field}`")), "{what}: {err}");
        assert!(!err.contains("corrupted"), "{what}: {err}");
        assert_eq!(tree(&d), before, "{what}: the folder changed");
        decoys.assert_unread();
    }
    // What was refused with decoys in place would have merged from them: the same decoys,
    // reached through the folder's own name, are valid shard files.
    let fine = t.join("fine");
    copy_tree(&good, &fine);
    std::fs::remove_dir_all(fine.join("shard_000001")).unwrap();
    copy_tree(&outside, &fine.join("shard_000001"));
    ok(&spibench(
        &["dataset", "--merge", s(&fine), "--out", s(&t.join("m"))],
        &[],
    ));
    // Nothing was left beside the folders: no lock, no staging.
    let names: Vec<String> = std::fs::read_dir(&t.0)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains("spibench")), "{names:?}");
}

#[test]
fn a_merge_copies_what_it_checked_and_never_its_inputs() {
    let t = TempDir::new("untrusted-merge");
    let spec = write_spec(&t.0);
    let one = t.join("one");
    ok(&spibench(&["dataset", s(&spec), "--out", s(&one)], &[]));
    // A merge of one folder is a complete, byte-identical copy.
    let copy = t.join("copy");
    ok(&spibench(
        &["dataset", "--merge", s(&one), "--out", s(&copy)],
        &[],
    ));
    let strip = |v: Vec<(String, Vec<u8>)>| -> Vec<(String, Vec<u8>)> {
        v.into_iter()
            .filter(|(n, _)| n != "manifest.json")
            .collect()
    };
    let a = strip(tree(&one));
    assert_eq!(
        a.len(),
        4 * 6 + 3,
        "4 shards of 6 arrays, spec, bench, patterns"
    );
    assert_eq!(a, strip(tree(&copy)));
    crate::outputs_schema::check_file(&copy.join("manifest.json"), "DatasetManifest");
    let (m1, mc) = (
        read_json(&one.join("manifest.json")),
        read_json(&copy.join("manifest.json")),
    );
    assert_eq!(m1["shards"], mc["shards"]);
    assert_eq!(m1["schema"], mc["schema"]);
    // The merged manifest keeps the command that made each input.
    let from = &mc["provenance"]["merged_from"];
    assert_eq!(from.as_array().unwrap().len(), 1, "{from}");
    assert_eq!(from[0]["command"], m1["provenance"]["command"]);
    assert_eq!(from[0]["folder"], s(&one));
    // An edited copy of an input (the spec, the patterns) is found.
    let edited = t.join("edited");
    copy_tree(&one, &edited);
    std::fs::write(edited.join("spec.ron"), "Dataset()").unwrap();
    let out = t.join("out");
    assert_input_error(
        &spibench(&["dataset", "--merge", s(&edited), "--out", s(&out)], &[]),
        &["spec.ron", "SHA-256"],
        &out,
    );
    // An output that is one of the inputs, however it is spelt, is refused and left as it was.
    let before = tree(&one);
    for o in [
        one.clone(),
        one.join("."),
        t.join("copy/../one"),
        t.0.clone(),
        one.join("inner"),
    ] {
        let r = spibench(
            &["dataset", "--merge", s(&copy), s(&one), "--out", s(&o)],
            &[],
        );
        assert_eq!(r.status.code(), Some(2), "{}", stderr(&r));
        assert!(stderr(&r).contains("--out"), "{}", stderr(&r));
        assert_eq!(tree(&one), before);
    }
    // A spec with --merge is refused, not ignored.
    let r = spibench(
        &["dataset", s(&spec), "--merge", s(&one), "--out", s(&out)],
        &[],
    );
    assert_input_error(&r, &["SPEC", "--merge"], &out);
}

#[test]
fn a_dataset_folder_is_locked_and_quiet_means_quiet() {
    let t = TempDir::new("untrusted-lock");
    let spec = write_spec(&t.0);
    let d = t.join("d");
    let o = spibench(&["--quiet", "dataset", s(&spec), "--out", s(&d)], &[]);
    ok(&o);
    assert_eq!(stderr(&o), "", "--quiet prints nothing on stderr");
    assert!(stdout(&o).contains("4 shards written"), "{}", stdout(&o));
    // Another run holds the folder's lock: a resume stops at once and touches nothing.
    let before = tree(&d);
    let lock_path = t.join(".d.spibench-lock");
    let lock = std::fs::File::create(&lock_path).unwrap();
    lock.try_lock().unwrap();
    for args in [
        vec!["dataset", s(&spec), "--out", s(&d), "--resume"],
        vec!["dataset", s(&spec), "--out", s(&d)],
    ] {
        let r = spibench(&args, &[]);
        assert_eq!(r.status.code(), Some(2), "{}", stderr(&r));
        assert!(
            stderr(&r).contains("another spibench run"),
            "{}",
            stderr(&r)
        );
        assert!(
            !stderr(&r).contains("kernel"),
            "locked before the kernel is traced"
        );
        assert_eq!(tree(&d), before);
    }
    drop(lock);
    std::fs::remove_file(&lock_path).unwrap();
    ok(&spibench(
        &["dataset", s(&spec), "--out", s(&d), "--resume"],
        &[],
    ));
    assert_eq!(tree(&d).len(), before.len());
}

pub(crate) fn tolerance(args: &[&str], out: &Path) -> std::process::Output {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let bench = scenes.join("tests/symmetric_arms.ron");
    let tol = scenes.join("tolerances/symmetric_arms.ron");
    let mut a = vec![
        "tolerance",
        s(&bench),
        "--tolerances",
        s(&tol),
        "--rays",
        "8192",
        "--seed",
        "3",
    ];
    a.extend_from_slice(args);
    a.extend(["--out", s(out)]);
    spibench(&a, &[])
}

pub(crate) fn merge_tolerance(inputs: &[&Path], out: &Path) -> std::process::Output {
    let mut a = vec!["tolerance", "--merge"];
    a.extend(inputs.iter().map(|p| s(p)));
    a.extend(["--out", s(out)]);
    spibench(&a, &[])
}

#[cfg(unix)]
#[test]
fn tolerance_shard_records_are_checked() {
    let t = TempDir::new("untrusted-tolerance");
    let shards: Vec<PathBuf> = (0..2).map(|i| t.join(&format!("s{i}"))).collect();
    for (i, d) in shards.iter().enumerate() {
        let shard = format!("{i}/2");
        ok(&tolerance(&["--trials", "3", "--shard", &shard], d));
    }
    let sum = std::fs::read_to_string(shards[1].join("trials.ron.sha256")).unwrap();
    assert!(
        sum.ends_with("  trials.ron\n") && sum.len() == 64 + 13,
        "{sum:?}"
    );
    let out = t.join("out");
    // An edited value: the checksum finds it.
    let edited = t.join("edited");
    copy_tree(&shards[1], &edited);
    let rec = edited.join("trials.ron");
    let text = std::fs::read_to_string(&rec).unwrap();
    let at = text.find("index: 1").expect("trial 1");
    std::fs::write(&rec, format!("{}index: 3{}", &text[..at], &text[at + 8..])).unwrap();
    assert_input_error(
        &merge_tolerance(&[&shards[0], &edited], &out),
        &["trials.ron", "SHA-256", "trials.ron.sha256"],
        &out,
    );
    // A name that would become a file name, with the checksum made to match: its field named.
    let text = std::fs::read_to_string(shards[1].join("trials.ron")).unwrap();
    let records = text.find("records:").expect("records");
    let (head, tail) = text.split_at(records);
    let evil = format!(
        "{head}{}",
        tail.replacen("\"imbalance\"", "\"../../evil_mssim\"", 1)
    );
    assert_ne!(evil, text);
    std::fs::write(&rec, &evil).unwrap();
    let hex = spibench::provenance::sha256_hex(evil.as_bytes());
    std::fs::write(
        edited.join("trials.ron.sha256"),
        format!("{hex}  trials.ron\n"),
    )
    .unwrap();
    assert_input_error(
        &merge_tolerance(&[&shards[0], &edited], &out),
        &["trials.ron", "field `records[0].values[", "evil"],
        &out,
    );
    // A record that is a link out of its folder.
    let linked = t.join("linked");
    std::fs::create_dir_all(&linked).unwrap();
    std::fs::copy(
        shards[1].join("trials.ron.sha256"),
        linked.join("trials.ron.sha256"),
    )
    .unwrap();
    std::os::unix::fs::symlink(shards[1].join("trials.ron"), linked.join("trials.ron")).unwrap();
    assert_input_error(
        &merge_tolerance(&[&shards[0], &linked], &out),
        &["symbolic link", "field `trials.ron`"],
        &out,
    );
    // The output is an input: refused, the input left as it was.
    let before = tree(&shards[0]);
    let o = merge_tolerance(&[&shards[0], &shards[1]], &shards[0]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--out"), "{}", stderr(&o));
    assert_eq!(tree(&shards[0]), before);
    ok(&merge_tolerance(&[&shards[1], &shards[0]], &out));
    let merged = std::fs::read(out.join("trials.ron")).unwrap();
    assert_eq!(
        std::fs::read_to_string(out.join("trials.ron.sha256")).unwrap(),
        format!(
            "{}  trials.ron\n",
            spibench::provenance::sha256_hex(&merged)
        )
    );
    // `--trials 0`: shard 1 alone has no sensitivity table and is refused; both shards merge
    // with it.
    let z: Vec<PathBuf> = (0..2).map(|i| t.join(&format!("z{i}"))).collect();
    for (i, d) in z.iter().enumerate() {
        let shard = format!("{i}/2");
        ok(&tolerance(&["--trials", "0", "--shard", &shard], d));
    }
    let zout = t.join("zout");
    assert_input_error(
        &merge_tolerance(&[&z[1]], &zout),
        &["--merge", "shard 0/2", "sensitivity table"],
        &zout,
    );
    ok(&merge_tolerance(&[&z[1], &z[0]], &zout));
    let summary = read_json(&zout.join("summary.json"));
    assert!(!summary["sensitivity"].as_array().unwrap().is_empty());
    assert!(zout.join("sensitivity.csv").is_file());
}
