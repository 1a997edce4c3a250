//! Memory bounded before it is taken: the diffractive DMD's tail tables and a `.npy` pattern
//! file are estimated from their settings and refused above the memory limit with the estimate
//! and the settings (exit 2, `--allow-large` to proceed), every input is checked before the
//! tables are built, and a Fortran-order array is read without an index table. Each command runs
//! under an address-space cap (`ulimit -v`) below what the old code allocated, where an
//! allocation beyond it aborts the process (exit 134).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Instant;

use crate::common::{TempDir, stderr};

/// Runs spibench with its address space capped at `mib` MiB, one worker thread.
fn capped(mib: u64, args: &[&str]) -> (Output, f64) {
    let t = Instant::now();
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {} && exec \"$0\" \"$@\"", mib << 10))
        // One malloc arena: the address space the threads reserve does not vary from run to run.
        .env("MALLOC_ARENA_MAX", "1")
        .arg(env!("CARGO_BIN_EXE_spibench"))
        .arg("--threads")
        .arg("1")
        .args(args)
        .output()
        .expect("sh runs");
    (o, t.elapsed().as_secs_f64())
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

fn refused(o: &Output, fragments: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for f in fragments {
        assert!(err.contains(f), "stderr lacks {f:?}: {err}");
    }
}

/// The paper bench with a 60 µm pitch (a 256 × 192 array), a 300–3000 nm band, the three
/// mirror states (the outside mirrors flat) and the diffractive model at `bin_nm`; `edit`
/// applied last.
fn diffractive(dir: &TempDir, bin_nm: f64, edit: (&str, &str)) -> PathBuf {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron"),
    )
    .unwrap();
    let mut text = text;
    for (a, b) in [
        ("band_nm: (350.0, 1150.0)", "band_nm: (300.0, 3000.0)"),
        (
            "columns: 1024,\n        rows: 768,\n        pitch_um: 13.68,",
            "columns: 256,\n        rows: 192,\n        pitch_um: 60.0,",
        ),
        (
            "pattern: (origin: (224, 96), units_across: 48, units_down: 48, mirrors_per_unit: 12)",
            "pattern: (origin: (32, 0), units_across: 48, units_down: 48, mirrors_per_unit: 4)",
        ),
        ("outside_state: Minus,", "outside_state: Flat,"),
        (
            "model: Diffractive(tail_bin_nm: 10.0),",
            &format!("model: Diffractive(tail_bin_nm: {bin_nm:?}),"),
        ),
        edit,
    ] {
        if a.is_empty() {
            continue;
        }
        assert_eq!(text.matches(a).count(), 1, "edit {a:?}");
        text = text.replace(a, b);
    }
    let p = dir.join(&format!("fine_{bin_nm}.ron"));
    std::fs::write(&p, text).unwrap();
    p
}

#[cfg(target_os = "linux")]
#[test]
fn fine_diffractive_tables_are_refused_with_their_estimate_before_anything_is_built() {
    let t = TempDir::new("memory-diffractive");
    // 0.5 nm bins: 3.07 GB of tables, above the 2 GB limit. The old code built them until
    // the cap stopped it (exit 134).
    let fine = diffractive(&t, 0.5, ("", ""));
    let (o, secs) = capped(1024, &["check", fine.to_str().unwrap()]);
    refused(
        &o,
        &[
            "field `dmd.model.tail_bin_nm`",
            "tail tables would take about 3.07 GB of memory",
            "5400 wavelength bins of 0.5 nm over 300–3000 nm × 3 mirror states",
            "above the limit of 2.00 GB",
            "at least 0.8 nm",
            "--allow-large",
        ],
    );
    assert!(secs < 30.0, "refused after {secs:.1} s");
    // 2 nm bins (0.77 GB of tables, under the limit) with a window that cannot be: the window
    // is reported before any table is built, under a cap the tables would not fit.
    let window = diffractive(&t, 2.0, ("size_mm: (16.0, 12.6)", "size_mm: (1.0, 1.0)"));
    let (o, _) = capped(512, &["check", window.to_str().unwrap()]);
    refused(&o, &["field `dmd.window.size_mm`", "cover the array"]);
    // With --allow-large the fine tables are built (and the cap stops them: the refusal was
    // the limit's, not the cap's).
    let (o, _) = capped(1024, &["check", fine.to_str().unwrap(), "--allow-large"]);
    assert_ne!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// A `.npy` header with `shape` and the data `bytes` (version 1.0), in Fortran order or not.
fn npy(path: &Path, descr: &str, fortran: bool, shape: &[usize], data: Option<&[u8]>) {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let order = if fortran { "True" } else { "False" };
    let mut h = format!(
        "{{'descr': '{descr}', 'fortran_order': {order}, 'shape': ({},), }}",
        dims.join(", ")
    );
    let total = 10 + h.len() + 1;
    h.push_str(&" ".repeat((64 - total % 64) % 64));
    h.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(h.len() as u16).to_le_bytes());
    bytes.extend_from_slice(h.as_bytes());
    let header = bytes.len() as u64;
    match data {
        Some(d) => {
            bytes.extend_from_slice(d);
            std::fs::write(path, bytes).unwrap();
        }
        None => {
            // A sparse file: the data are holes, nothing is written.
            std::fs::write(path, bytes).unwrap();
            let f = std::fs::File::options().write(true).open(path).unwrap();
            f.set_len(header + shape.iter().product::<usize>() as u64)
                .unwrap();
        }
    }
}

#[cfg(target_os = "linux")]
#[test]
fn pattern_files_are_estimated_before_they_are_read() {
    let t = TempDir::new("memory-npy");
    let y = t.join("y.npy");
    npy(&y, "<f8", false, &[3], Some(&[0u8; 24]));
    let out = t.join("out");
    let reconstruct = |p: &Path| -> Vec<String> {
        [
            "reconstruct",
            "--patterns",
            p.to_str().unwrap(),
            "--measurements",
            y.to_str().unwrap(),
            "--size",
            "32x32",
            "--out",
            out.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec()
    };
    // 1 GB of 0/1 patterns in Fortran order (a sparse file): 2.1 GB to read and decode, over
    // the limit: refused from the header alone, under a cap far below the file.
    let big = t.join("big.npy");
    npy(&big, "|u1", true, &[976_000, 1024], None);
    let a = reconstruct(&big);
    let (o, secs) = capped(512, &strs(&a));
    refused(
        &o,
        &[
            "big.npy",
            "the pattern array would take about 2.",
            "a 976000 × 1024 array of '|u1' in Fortran order",
            "--allow-large",
        ],
    );
    assert!(secs < 30.0, "refused after {secs:.1} s");
    assert!(!out.exists());
    // 48 MB in Fortran order is read with the array's own copy alone (about 100 MB with the
    // file's bytes and the bit rows): the old index table (8 bytes per element, 393 MB) did not
    // fit the cap and aborted. The next check is the measurements' count.
    let mid = t.join("mid.npy");
    let (m, n) = (48_000usize, 1024usize);
    let bits: Vec<u8> = (0..m * n).map(|i| ((i * 7) % 3 == 0) as u8).collect();
    npy(&mid, "|u1", true, &[m, n], Some(&bits));
    let a = reconstruct(&mid);
    let (o, _) = capped(450, &strs(&a));
    refused(&o, &["3 measurements for 48000 patterns"]);
}
