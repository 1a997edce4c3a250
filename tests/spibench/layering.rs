//! The module dependency direction of ARCHITECTURE.md, checked on the source: each module may
//! name only the modules on the floors below its own, and some not even those. Test code
//! (files named `tests.rs` and everything after a `#[cfg(test)]` line) may reach further, to
//! read scenes for instance.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The floors of the module graph, lowest first. A module may use only modules on lower floors:
/// modules on one floor stand side by side and never use each other (the jobs in particular
/// compose `pipeline`, not each other). Every top-level module must be listed.
const FLOORS: &[&[&str]] = &[
    &["error", "rng", "npy", "checked", "lib", "main"],
    &["raster", "detector", "provenance", "memory"],
    &["objects", "reconstruction"],
    &["acquisition", "metrics", "optics"],
    &["scene", "trace"],
    &["transport", "report", "simulation"],
    &["pipeline", "export"],
    // The jobs.
    &["run", "sweep", "align", "tolerance", "dataset"],
    &["cli"],
];

/// For each top-level module, the crate modules it must not use.
const FORBIDDEN: &[(&str, &[&str])] = &[
    ("error", &["*"]),
    ("rng", &["*"]),
    (
        "raster",
        &[
            "optics",
            "trace",
            "transport",
            "scene",
            "pipeline",
            "run",
            "cli",
            "report",
        ],
    ),
    (
        "reconstruction",
        &[
            "optics",
            "objects",
            "trace",
            "transport",
            "detector",
            "acquisition",
            "metrics",
            "scene",
            "pipeline",
            "run",
            "sweep",
            "simulation",
            "export",
            "report",
            "cli",
        ],
    ),
    (
        "optics",
        &[
            "trace",
            "transport",
            "detector",
            "acquisition",
            "reconstruction",
            "metrics",
            "scene",
            "pipeline",
            "run",
            "sweep",
            "simulation",
            "export",
            "report",
            "cli",
        ],
    ),
    (
        "trace",
        &[
            "transport",
            "detector",
            "acquisition",
            "reconstruction",
            "metrics",
            "scene",
            "pipeline",
            "run",
            "sweep",
            "simulation",
            "export",
            "report",
            "cli",
        ],
    ),
    (
        "transport",
        &[
            "detector",
            "acquisition",
            "metrics",
            "scene",
            "pipeline",
            "run",
            "sweep",
            "simulation",
            "export",
            "report",
            "cli",
        ],
    ),
    (
        "detector",
        &[
            "trace",
            "transport",
            "acquisition",
            "reconstruction",
            "metrics",
            "scene",
            "pipeline",
            "run",
            "sweep",
            "simulation",
            "export",
            "report",
            "cli",
        ],
    ),
    (
        "acquisition",
        &[
            "optics",
            "trace",
            "transport",
            "metrics",
            "scene",
            "pipeline",
            "run",
            "sweep",
            "simulation",
            "export",
            "report",
            "cli",
        ],
    ),
    (
        "metrics",
        &[
            "optics",
            "trace",
            "transport",
            "detector",
            "acquisition",
            "scene",
            "pipeline",
            "run",
            "sweep",
            "simulation",
            "export",
            "report",
            "cli",
        ],
    ),
    (
        "scene",
        &[
            "trace",
            "transport",
            "pipeline",
            "run",
            "sweep",
            "simulation",
            "export",
            "report",
            "cli",
        ],
    ),
    (
        "pipeline",
        &["run", "sweep", "simulation", "export", "report", "cli"],
    ),
    ("run", &["sweep", "simulation", "export", "report", "cli"]),
    ("sweep", &["simulation", "export", "report", "cli"]),
    (
        "simulation",
        &[
            "optics",
            "trace",
            "transport",
            "pipeline",
            "run",
            "sweep",
            "report",
            "cli",
        ],
    ),
    ("export", &["pipeline", "run", "sweep", "simulation", "cli"]),
    ("report", &["pipeline", "run", "sweep", "simulation", "cli"]),
    ("npy", &["*"]),
    (
        "objects",
        &[
            "optics",
            "trace",
            "transport",
            "detector",
            "acquisition",
            "reconstruction",
            "scene",
            "pipeline",
            "report",
            "cli",
        ],
    ),
    // The jobs: side by side over the pipeline.
    (
        "run",
        &[
            "sweep",
            "align",
            "tolerance",
            "dataset",
            "simulation",
            "export",
            "report",
        ],
    ),
    (
        "sweep",
        &[
            "run",
            "align",
            "tolerance",
            "dataset",
            "simulation",
            "export",
            "report",
        ],
    ),
    (
        "align",
        &[
            "run",
            "sweep",
            "tolerance",
            "dataset",
            "simulation",
            "export",
            "report",
        ],
    ),
    (
        "tolerance",
        &[
            "run",
            "sweep",
            "align",
            "dataset",
            "simulation",
            "export",
            "report",
        ],
    ),
    (
        "dataset",
        &["run", "sweep", "align", "tolerance", "simulation", "export"],
    ),
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The crate modules named by `crate::NAME` or `use crate::{NAME, …}` in the non-test code.
fn used_modules(text: &str) -> BTreeSet<String> {
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    let code: String = code
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = BTreeSet::new();
    let mut rest = code.as_str();
    while let Some(k) = rest.find("crate::") {
        let after = &rest[k + "crate::".len()..];
        if let Some(group) = after.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            for item in group[..end].split(',') {
                let name: String = item
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    out.insert(name);
                }
            }
        } else {
            let name: String = after
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            out.insert(name);
        }
        rest = after;
    }
    out
}

/// The floor of a module (0 the lowest), or None for a module on no floor.
fn floor(module: &str) -> Option<usize> {
    FLOORS.iter().position(|f| f.contains(&module))
}

#[test]
fn modules_depend_only_downward() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let modules: BTreeSet<String> = files
        .iter()
        .filter_map(|f| f.strip_prefix(&src).ok())
        .filter_map(|r| r.components().next())
        .map(|c| {
            c.as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string()
        })
        .collect();
    let mut violations = Vec::new();
    let mut anyhow_outside_cli = Vec::new();
    let mut unplaced = BTreeSet::new();
    for f in &files {
        if f.file_name().is_some_and(|n| n == "tests.rs") {
            continue;
        }
        let rel = f.strip_prefix(&src).unwrap();
        let module = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy()
            .trim_end_matches(".rs")
            .to_string();
        let text = std::fs::read_to_string(f).unwrap();
        if module != "cli" && module != "main" && text.contains("anyhow") {
            anyhow_outside_cli.push(rel.display().to_string());
        }
        let own_floor = floor(&module);
        if own_floor.is_none() {
            unplaced.insert(module.clone());
        }
        let forbidden = FORBIDDEN
            .iter()
            .find(|(m, _)| *m == module)
            .map_or(&[][..], |(_, f)| *f);
        for used in used_modules(&text) {
            if used == module || !modules.contains(&used) {
                continue;
            }
            if let (Some(f), Some(g)) = (own_floor, floor(&used))
                && g >= f
            {
                violations.push(format!(
                    "{} (floor {f}) uses crate::{used} (floor {g})",
                    rel.display()
                ));
            }
            let bad = forbidden.contains(&"*") && !["error"].contains(&used.as_str())
                || forbidden.contains(&used.as_str());
            if bad || used == "cli" {
                violations.push(format!("{} uses crate::{used}", rel.display()));
            }
        }
    }
    assert!(
        violations.is_empty(),
        "module dependencies against the layering of ARCHITECTURE.md:\n{}",
        violations.join("\n")
    );
    assert!(
        unplaced.is_empty(),
        "modules on no floor of FLOORS (give each a floor): {unplaced:?}"
    );
    assert!(
        anyhow_outside_cli.is_empty(),
        "anyhow outside src/cli: {anyhow_outside_cli:?}"
    );
}

#[test]
fn the_scanner_sees_grouped_and_plain_uses() {
    let m = used_modules(
        "use crate::{optics::Bench, trace};\nfn f() { crate::run::run(); }\n// crate::cli\n#[cfg(test)]\nuse crate::scene;",
    );
    let v: Vec<&str> = m.iter().map(|s| s.as_str()).collect();
    assert_eq!(v, ["optics", "run", "trace"]);
}
