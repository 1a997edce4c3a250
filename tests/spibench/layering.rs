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
    &[
        "error",
        "rng",
        "npy",
        "checked",
        "quantities",
        "lib",
        "main",
    ],
    &["raster", "detector", "provenance", "memory"],
    &["objects", "reconstruction"],
    &["acquisition", "metrics", "optics"],
    // Lens prescriptions from files (.zmx, .agf), which benches and `spibench lens` read.
    &["lens"],
    &["scene", "trace"],
    &["transport", "report", "simulation"],
    &["pipeline", "export"],
    // The jobs.
    &[
        "run",
        "sweep",
        "align",
        "tolerance",
        "dataset",
        "intake",
        "fit",
    ],
    // What each command writes, from what its job returned.
    &["outputs"],
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
        "lens",
        &[
            "trace",
            "transport",
            "detector",
            "acquisition",
            "reconstruction",
            "metrics",
            "scene",
            "pipeline",
            "report",
            "cli",
        ],
    ),
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
    // Reads the records and patterns it takes in through `report::npy`, as `dataset` does.
    (
        "intake",
        &[
            "run",
            "sweep",
            "align",
            "tolerance",
            "dataset",
            "simulation",
            "export",
        ],
    ),
    // Reads an intake folder as files (its summary and frames), not through the intake job.
    (
        "fit",
        &[
            "run",
            "sweep",
            "align",
            "tolerance",
            "dataset",
            "intake",
            "simulation",
            "export",
            "report",
        ],
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

/// The calls whose string arguments are error messages (or a flag's name for one).
const ERROR_CALLS: &[&str] = &[
    "field",
    "input",
    "Numerical",
    "with_note",
    "at_field",
    "within",
    "bad",
    "bad_field",
    "refuse_overlap",
    "Err",
];

/// Each string literal of `code` (comments skipped; raw and byte strings included) with the
/// calls it is an argument of, innermost last: `Error::field("x", format!("…"))` gives
/// `"…"` with `["field", "format"]`.
fn literals_in_calls(code: &str) -> Vec<(String, Vec<String>)> {
    let b = code.as_bytes();
    let mut out = Vec::new();
    // The open brackets: a call's name for `(` (empty when none), "{" or "[" otherwise.
    let mut stack: Vec<String> = Vec::new();
    let calls = |stack: &[String]| -> Vec<String> {
        stack
            .iter()
            .filter(|s| *s != "{" && *s != "[" && !s.is_empty())
            .cloned()
            .collect()
    };
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if code[i..].starts_with("//") {
            i = code[i..].find('\n').map_or(b.len(), |k| i + k);
            continue;
        }
        if code[i..].starts_with("/*") {
            i = code[i..].find("*/").map_or(b.len(), |k| i + k + 2);
            continue;
        }
        let ident_before = i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
        // Raw strings: r"…", r#"…"#, br"…".
        let raw_at = if c == b'r' && !ident_before {
            Some(i + 1)
        } else if c == b'b' && !ident_before && b.get(i + 1) == Some(&b'r') {
            Some(i + 2)
        } else {
            None
        };
        if let Some(mut j) = raw_at {
            let hashes = b[j..].iter().take_while(|&&h| h == b'#').count();
            j += hashes;
            if b.get(j) == Some(&b'"') {
                let close = format!("\"{}", "#".repeat(hashes));
                let end = code[j + 1..].find(&close).map_or(b.len(), |k| j + 1 + k);
                out.push((code[j + 1..end].to_string(), calls(&stack)));
                i = end + close.len();
                continue;
            }
        }
        match c {
            b'"' => {
                let mut j = i + 1;
                while j < b.len() && b[j] != b'"' {
                    j += if b[j] == b'\\' { 2 } else { 1 };
                }
                out.push((code[i + 1..j.min(b.len())].to_string(), calls(&stack)));
                i = j + 1;
                continue;
            }
            // A char literal ('x', '\n', '"'), not a lifetime ('a).
            b'\'' => {
                if b.get(i + 1) == Some(&b'\\') {
                    i = code[i + 2..].find('\'').map_or(b.len(), |k| i + 2 + k + 1);
                    continue;
                }
                if code[i + 1..].chars().nth(1) == Some('\'') {
                    i += 1 + code[i + 1..].chars().next().map_or(1, char::len_utf8) + 1;
                    continue;
                }
            }
            b'(' => {
                let head = code[..i].trim_end().trim_end_matches('!');
                let name: String = head
                    .chars()
                    .rev()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect::<Vec<_>>()
                    .into_iter()
                    .rev()
                    .collect();
                stack.push(name);
            }
            b'{' => stack.push("{".into()),
            b'[' => stack.push("[".into()),
            b')' | b'}' | b']' => {
                stack.pop();
            }
            _ => {}
        }
        i += 1;
    }
    out
}

/// A command-line flag (`--name`) in `text`.
fn names_a_flag(text: &str) -> bool {
    text.as_bytes()
        .windows(3)
        .any(|w| w[0] == b'-' && w[1] == b'-' && w[2].is_ascii_lowercase())
}

/// No error message of the library (everything outside `src/cli/`, test code aside) names a
/// command-line flag: the library names its own fields (`vary`, `free`, `merge`; an option in
/// a message in backquotes, `` `resume` ``), and the command line shows them as its flags
/// (`cli::flags`). A Python caller never passed `--vary`.
#[test]
fn library_errors_name_no_flags() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut found = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(&src).unwrap();
        if rel.starts_with("cli") || f.file_name().is_some_and(|n| n == "tests.rs") {
            continue;
        }
        let text = std::fs::read_to_string(f).unwrap();
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        for (literal, calls) in literals_in_calls(code) {
            if names_a_flag(&literal) && calls.iter().any(|c| ERROR_CALLS.contains(&c.as_str())) {
                found.push(format!("{}: {literal:?} in {calls:?}", rel.display()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "library error messages that name a command-line flag (name the library's field \
         instead, and map it in src/cli/flags.rs):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_flag_scanner_finds_messages_in_error_calls() {
    let code = r##"
        fn f(t: &str) -> Result<()> {
            let bad = |why: &str| Error::field("--vary", format!("`{t}`: {why}"));
            let c = '"'; let l: &'static str = "x";
            // Error::input("--commented")
            if t.is_empty() { return Err(Error::input(format!("give it with --resume"))); }
            let s = r#"raw "--quoted" text"#;
            describe("the budget (--max-evaluations) ran out");
            Err(e.with_note(r"--note"))
        }
    "##;
    let flagged: Vec<String> = literals_in_calls(code)
        .into_iter()
        .filter(|(l, c)| names_a_flag(l) && c.iter().any(|c| ERROR_CALLS.contains(&c.as_str())))
        .map(|(l, _)| l)
        .collect();
    assert_eq!(flagged, ["--vary", "give it with --resume", "--note"]);
}

/// The API boundary: the library paths the two edges, the command line (`src/cli/`) and the
/// Python binding crate (`python/src/`), may name. ARCHITECTURE.md ("The API boundary") lists
/// the same paths. An entry admits itself and everything below it (`scene::doc` admits
/// `scene::doc::BenchDoc`); a path the edges name that no entry admits fails
/// [`the_edges_use_only_the_api`]. What is not here (the tracer's walk and tallies, the optics'
/// parts, the random streams, the figure writers, the object models) the edges reach only
/// through a job, the evaluate step or an output module.
const API: &[&str] = &[
    // Errors, notes and the checked numbers the edges read from flags.
    "Error",
    "Result",
    "note",
    "error",
    "checked",
    "memory",
    // The input files: the one bench entrance, the other files, bench variables.
    "scene::doc",
    "scene::experiment",
    "scene::dataset",
    "scene::tolerance",
    "scene::run",
    "scene::variables",
    "scene::parse_ron",
    "scene::read_text",
    "scene::budget_costs",
    "scene::bench::element_prescription",
    // The jobs and what each command writes.
    "run",
    "sweep",
    "align",
    "tolerance",
    "dataset",
    "simulation",
    "export",
    "lens",
    "intake",
    "fit",
    "outputs",
    // The stages every job composes, and the evaluate step.
    "pipeline",
    // The engine's entry points that `trace`, `layout`, `check` and the binding's kernels use.
    "trace::RAYS_PER_BATCH",
    "trace::BatchTally",
    "trace::kernel",
    "trace::collection",
    "trace::fan",
    "trace::paraxial",
    "trace::irradiance",
    "trace::TraceOptions",
    "transport::Transport",
    "transport::Estimate",
    "optics::Arm",
    "optics::dmd::MirrorState",
    "optics::monochromatic",
    "acquisition",
    "detector::RecordModel",
    // `reconstruct`: a measured set solved and scored without the optics.
    "reconstruction",
    "metrics",
    "raster",
    "quantities",
    "provenance",
    // Output folders and arrays.
    "report::output",
    "report::npy",
];

/// Every path named from `root` (`crate` or `spibench`) in the non-test code of `text`:
/// `use crate::scene::{doc::BenchDoc, tolerance::{self, ToleranceSet}};` gives
/// `scene::doc::BenchDoc`, `scene::tolerance` and `scene::tolerance::ToleranceSet`; a path in
/// an expression (`crate::trace::fan::dmd_axes(…)`) is read the same way.
fn named_paths(text: &str, root: &str) -> Vec<String> {
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    let code: String = code
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    let head = format!("{root}::");
    let b = code.as_bytes();
    let mut out = Vec::new();
    let mut at = 0;
    while let Some(k) = code[at..].find(&head) {
        let start = at + k;
        at = start + head.len();
        let before = start.checked_sub(1).map(|i| b[i]);
        if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_' || c == b':') {
            continue;
        }
        use_tree(&code[at..], "", &mut out);
    }
    out
}

/// Reads one use tree at the start of `s` below `prefix` into `out`; returns the bytes read.
fn use_tree(s: &str, prefix: &str, out: &mut Vec<String>) -> usize {
    let skip_ws = |i: usize| i + s[i..].len() - s[i..].trim_start().len();
    let mut i = skip_ws(0);
    if s[i..].starts_with('{') {
        i += 1;
        loop {
            i = skip_ws(i);
            if i >= s.len() || s[i..].starts_with('}') {
                return i + 1;
            }
            i += use_tree(&s[i..], prefix, out);
            i = skip_ws(i);
            if s[i..].starts_with(',') {
                i += 1;
            }
        }
    }
    let name: String = s[i..]
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == '*')
        .collect();
    i += name.len();
    if name.is_empty() {
        if !prefix.is_empty() {
            out.push(prefix.to_string());
        }
        return i;
    }
    let path = match (prefix.is_empty(), name.as_str()) {
        (_, "self") | (false, "*") => prefix.to_string(),
        (true, _) => name.clone(),
        (false, _) => format!("{prefix}::{name}"),
    };
    if s[i..].starts_with("::") {
        return i + 2 + use_tree(&s[i + 2..], &path, out);
    }
    // `Name as Alias`: the alias is the edge's own name.
    let rest = s[i..].trim_start();
    if let Some(alias) = rest.strip_prefix("as ") {
        i = s.len() - alias.trim_start().len();
        i += alias
            .trim_start()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .map(char::len_utf8)
            .sum::<usize>();
    }
    out.push(path);
    i
}

/// Whether an entry of [`API`] admits `path`.
fn in_api(path: &str) -> bool {
    API.iter().any(|e| {
        path == *e
            || path
                .strip_prefix(e)
                .is_some_and(|rest| rest.starts_with("::"))
    })
}

/// The paths outside [`API`] that the edge files under `dir` name from `root`, as
/// "file: path" (the command line's own modules, `crate::cli::…`, aside).
fn outside_api(dir: &Path, root: &str) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(dir, &mut files);
    files.sort();
    let mut found = Vec::new();
    for f in &files {
        if f.file_name().is_some_and(|n| n == "tests.rs") {
            continue;
        }
        let text = std::fs::read_to_string(f).unwrap();
        for p in named_paths(&text, root) {
            if !(root == "crate" && (p == "cli" || p.starts_with("cli::"))) && !in_api(&p) {
                found.push(format!("{}: {root}::{p}", f.display()));
            }
        }
    }
    found
}

/// The command line and the Python binding name only the library paths of [`API`], and
/// ARCHITECTURE.md lists the same paths.
#[test]
fn the_edges_use_only_the_api() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut found = outside_api(&root.join("src/cli"), "crate");
    found.extend(outside_api(&root.join("python/src"), "spibench"));
    assert!(
        found.is_empty(),
        "the command line or the Python binding names a library path outside the API boundary \
         (reach it through a job, the evaluate step or an output module, or widen API here and \
         in ARCHITECTURE.md):\n{}",
        found.join("\n")
    );
    let doc = std::fs::read_to_string(root.join("ARCHITECTURE.md")).unwrap();
    let section = doc
        .split("## The API boundary")
        .nth(1)
        .expect("ARCHITECTURE.md has a section \"## The API boundary\"");
    let section = section.split("\n## ").next().unwrap();
    // The list: its items and their continuation lines, after the prose.
    let listed: BTreeSet<&str> = section
        .lines()
        .skip_while(|l| !l.starts_with("- "))
        .flat_map(|l| l.split('`').skip(1).step_by(2))
        .collect();
    let api: BTreeSet<&str> = API.iter().copied().collect();
    assert_eq!(
        listed, api,
        "ARCHITECTURE.md's API boundary (backquoted paths in its list) and API differ"
    );
}

#[test]
fn the_path_reader_sees_nested_groups_aliases_and_expressions() {
    let code = "use crate::scene::{doc::BenchDoc, tolerance::{self, ToleranceSet}};\n\
                use spibench::trace::kernel::Kernel as LibKernel;\n\
                fn f() { crate::trace::fan::dmd_axes(&b); let x = crate::Error::input(\"x\"); }\n\
                // crate::rng::stream\n\
                use my_crate::x;\n\
                #[cfg(test)]\nuse crate::objects;";
    assert_eq!(
        named_paths(code, "crate"),
        [
            "scene::doc::BenchDoc",
            "scene::tolerance",
            "scene::tolerance::ToleranceSet",
            "trace::fan::dmd_axes",
            "Error::input"
        ]
    );
    assert_eq!(named_paths(code, "spibench"), ["trace::kernel::Kernel"]);
    assert!(in_api("scene::doc::BenchDoc") && in_api("Error::input"));
    assert!(!in_api("scene::docs") && !in_api("trace::path") && !in_api("rng::stream"));
}

/// ARCHITECTURE.md's floor table ("## Module graph": `| N | `a`, `b` |`, the highest floor
/// first) is [`FLOORS`], floor by floor in order (`lib` and `main`, the crate's roots, aside;
/// the numbers are labels).
#[test]
fn floors_match_architecture() {
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("ARCHITECTURE.md"))
            .unwrap();
    let graph = doc
        .split("## Module graph")
        .nth(1)
        .expect("ARCHITECTURE.md has a section \"## Module graph\"");
    let graph = graph.split("\n## ").next().unwrap();
    let mut table: Vec<BTreeSet<String>> = Vec::new();
    for line in graph.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if let [_, n, modules, _] = cells[..]
            && n.starts_with(|c: char| c.is_ascii_digit())
        {
            let names = modules.split('`').skip(1).step_by(2).map(String::from);
            table.push(names.collect());
        }
    }
    table.reverse();
    let expected: Vec<BTreeSet<String>> = FLOORS
        .iter()
        .map(|f| {
            let names = f.iter().filter(|m| !["lib", "main"].contains(m));
            names.map(|m| m.to_string()).collect()
        })
        .collect();
    assert_eq!(
        table, expected,
        "ARCHITECTURE.md's floor table (highest first) and FLOORS in tests/spibench/layering.rs \
         (lowest first) differ"
    );
}
