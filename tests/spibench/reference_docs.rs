//! The reference pages of docs/reference/, generated from the code and checked against it.
//!
//! The file formats (bench, experiment, tolerance and dataset files, and the value types their
//! numbers are read through) come from the doc comments and declarations of `src/`, read as
//! text ([`source`], [`formats`]); the commands page from the clap definitions that parse the
//! command line (`spibench::cli::command()`, [`commands`]). A page that differs from what the
//! generator writes now fails `reference_pages_match_the_code`, and a field, variant or type of
//! an input file without a doc comment fails `input_files_are_documented`, so the reference
//! cannot drift from the code nor leave a field out. A new field, element kind, command or flag
//! needs only its doc comment and a regenerate:
//!
//! ```text
//! SPIBENCH_BLESS=1 cargo test --test spibench reference
//! ```

mod commands;
mod formats;
mod source;

use std::path::{Path, PathBuf};

use formats::{FORMATS, GENERATED, Index, VALUES_PAGE};
use source::Source;

/// The command that rewrites the pages.
const REGENERATE: &str = "SPIBENCH_BLESS=1 cargo test --test spibench reference";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every page the generator writes: (file name in docs/reference/, text).
fn pages() -> (Vec<(String, String)>, Vec<String>) {
    let src = Source::read(&root());
    let ix = Index::build(&src);
    let mut out = vec![("README.md".to_string(), index_page())];
    for f in &FORMATS {
        out.push((f.page.to_string(), ix.page(f)));
    }
    out.push((VALUES_PAGE.to_string(), ix.values_page()));
    out.push((
        "commands.md".to_string(),
        commands::page(&spibench::cli::command()),
    ));
    let mut undocumented = ix.undocumented();
    undocumented.extend(commands::undocumented(&spibench::cli::command()));
    (out, undocumented)
}

fn index_page() -> String {
    let mut out = String::from("# Reference\n\n");
    out.push_str(GENERATED);
    out.push_str(
        "The reference of what spibench reads and writes, generated from the code so that it \
         cannot drift from it. The [user guide](../guide/README.md) shows how to use them.\n\n\
         - [Commands](commands.md): every command, argument, default and help text.\n",
    );
    for f in &FORMATS {
        out.push_str(&format!(
            "- [{}]({}): every field with its type, unit, default and range{}.\n",
            f.title,
            f.page,
            if f.bench {
                ", and whether it is a bench variable for `--set` and `--vary`"
            } else {
                ""
            }
        ));
    }
    out.push_str(&format!(
        "- [Value types]({VALUES_PAGE}): the checked numbers the files' fields are read \
         through, with their ranges.\n\
         - [Outputs](../outputs.md): every file each command writes and every key of its JSON \
         (checked against the commands' real outputs by `tests/spibench/outputs_schema.rs`).\n\
         - The Python API: the `spibench` package's docstrings, rendered by pdoc with \
         `python/docs.sh` to `target/python-docs/` (a build output, which CI's Python stage \
         builds; CONTRIBUTING.md, \"The reference pages\").\n"
    ));
    out
}

/// The first line where two texts differ, for the failure message.
fn first_difference(a: &str, b: &str) -> String {
    for (n, (x, y)) in a.lines().zip(b.lines()).enumerate() {
        if x != y {
            return format!("line {}:\n    on disk:   {x}\n    generated: {y}", n + 1);
        }
    }
    format!(
        "the texts differ in length ({} and {} lines)",
        a.lines().count(),
        b.lines().count()
    )
}

#[test]
fn reference_pages_match_the_code() {
    let dir = root().join("docs/reference");
    let (pages, _) = pages();
    let bless = std::env::var_os("SPIBENCH_BLESS").is_some_and(|v| v == "1");
    let mut stale = Vec::new();
    for (name, text) in &pages {
        let path = dir.join(name);
        let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
        if on_disk == *text {
            continue;
        }
        if bless {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&path, text).unwrap();
        } else {
            stale.push(format!(
                "docs/reference/{name}: {}",
                first_difference(&on_disk, text)
            ));
        }
    }
    // A generated page the generator no longer writes (a renamed format).
    for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let generated = std::fs::read_to_string(e.path())
            .is_ok_and(|t| t.contains("do not edit: change the source and regenerate"));
        if generated && !pages.iter().any(|(n, _)| *n == name) {
            if bless {
                std::fs::remove_file(e.path()).unwrap();
            } else {
                stale.push(format!("docs/reference/{name}: no longer generated"));
            }
        }
    }
    assert!(
        stale.is_empty(),
        "the reference pages differ from the code; regenerate them with\n    {REGENERATE}\n\
         and commit the result:\n{}",
        stale.join("\n")
    );
}

#[test]
fn reference_input_files_are_documented() {
    let (_, undocumented) = pages();
    assert!(
        undocumented.is_empty(),
        "every type, field and variant of an input file needs a doc comment, and every command \
         and argument a help text (they are the reference: docs/reference/, {REGENERATE}); \
         missing:\n{}",
        undocumented.join("\n")
    );
}

/// The reader finds the types it should: a broken reader would write empty pages that match.
#[test]
fn reference_reader_finds_the_schema() {
    let (pages, _) = pages();
    let bench = &pages.iter().find(|(n, _)| n == "bench.md").unwrap().1;
    for kind in [
        "LensSpec",
        "MirrorSpec",
        "DmdSpec",
        "PhotodiodeSpec",
        "LampSpec",
    ] {
        assert!(
            bench.contains(&format!("### `{kind}`")),
            "bench.md lacks {kind}"
        );
    }
    assert!(bench.contains("| `position_mm` | [`Mm3`](values.md#mm3) | mm | required |"));
    let commands = &pages.iter().find(|(n, _)| n == "commands.md").unwrap().1;
    assert!(commands.contains("## `spibench run`") && commands.contains("`--set <PATH=VALUE>`"));
    assert!(Path::new(&root().join("docs/outputs.md")).exists());
}
