//! The output schema of docs/outputs.md, checked. That document is the one place where every
//! key of every command's JSON output is written down with its type and unit; its tables are
//! also machine-readable, and this module validates the files the CLI tests write against them
//! (`check_file`, called from each command's end-to-end test), so that a key added without
//! documentation, a key that changes type, or a documented key that disappears fails a test.
//!
//! The format. A structure is a heading `### \`Name\`` followed by a table whose header is
//! `| key | type | unit | meaning |`. A key is a field name; `a.b` documents field `b` of the
//! object `a` (whose own row has type `object`); a key ending in `?` may be absent. A type is
//! `string`, `number`, `integer`, `boolean`, `null`, `object` (an object whose fields are the
//! dotted keys below it), `any`, another structure's name, `T[]` (an array of T), `map<T>` (an
//! object whose keys are data, each value a T) or `T?` (T or null). A row whose key is `..`
//! includes every row of the structure named in its type.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

use serde_json::Value;

/// One documented key.
#[derive(Debug, Clone)]
struct Entry {
    key: String,
    ty: String,
    optional: bool,
}

type Schemas = BTreeMap<String, Vec<Entry>>;

/// Parses the structures of a document in the format of the module documentation.
fn parse(doc: &str) -> Result<Schemas, String> {
    let mut out: Schemas = BTreeMap::new();
    let mut current: Option<String> = None;
    let mut in_table = false;
    for (n, line) in doc.lines().enumerate() {
        let t = line.trim();
        if let Some(rest) = t.strip_prefix("### `") {
            let name = rest.split('`').next().unwrap_or("").to_string();
            if out.contains_key(&name) {
                return Err(format!("line {}: structure `{name}` defined twice", n + 1));
            }
            out.insert(name.clone(), Vec::new());
            current = Some(name);
            in_table = false;
            continue;
        }
        if t.starts_with('#') {
            current = None;
            in_table = false;
            continue;
        }
        let Some(name) = &current else { continue };
        if t.starts_with("| key | type | unit | meaning |") {
            in_table = true;
            continue;
        }
        if !in_table || !t.starts_with('|') || t.starts_with("|---") {
            if !t.starts_with('|') {
                in_table = false;
            }
            continue;
        }
        let cells: Vec<&str> = t.trim_matches('|').split('|').map(str::trim).collect();
        if cells.len() < 4 {
            return Err(format!("line {}: a schema row needs 4 cells", n + 1));
        }
        let key = cells[0].trim_matches('`');
        let ty = cells[1].trim_matches('`').to_string();
        let (key, optional) = match key.strip_suffix('?') {
            Some(k) => (k.to_string(), true),
            None => (key.to_string(), false),
        };
        out.get_mut(name).unwrap().push(Entry { key, ty, optional });
    }
    Ok(out)
}

/// The structures of docs/outputs.md, parsed once.
fn schemas() -> &'static Schemas {
    static CELL: OnceLock<Schemas> = OnceLock::new();
    CELL.get_or_init(|| {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/outputs.md");
        let text = std::fs::read_to_string(&p).expect("docs/outputs.md");
        parse(&text).unwrap_or_else(|e| panic!("docs/outputs.md: {e}"))
    })
}

/// The rows of a structure with its `..` inclusions expanded.
fn rows(s: &Schemas, name: &str, depth: usize) -> Result<Vec<Entry>, String> {
    let own = s
        .get(name)
        .ok_or_else(|| format!("no structure `{name}` in docs/outputs.md"))?;
    if depth > 8 {
        return Err(format!("`{name}`: inclusions nest too deep"));
    }
    let mut out = Vec::new();
    for e in own {
        if e.key == ".." {
            out.extend(rows(s, &e.ty, depth + 1)?);
        } else {
            out.push(e.clone());
        }
    }
    Ok(out)
}

fn is_type(v: &Value, ty: &str) -> bool {
    match ty {
        "string" => v.is_string(),
        "number" => v.is_number(),
        "integer" => v.is_i64() || v.is_u64(),
        "boolean" => v.is_boolean(),
        "null" => v.is_null(),
        "any" => true,
        _ => false,
    }
}

/// Validates `v` against the type expression `ty`, adding problems (with their JSON paths).
fn check(s: &Schemas, v: &Value, ty: &str, path: &str, out: &mut Vec<String>) {
    let ty = ty.trim();
    if let Some(inner) = ty.strip_suffix('?') {
        if !v.is_null() {
            check(s, v, inner, path, out);
        }
        return;
    }
    if let Some(inner) = ty.strip_suffix("[]") {
        match v.as_array() {
            Some(a) => {
                for (i, w) in a.iter().enumerate() {
                    check(s, w, inner, &format!("{path}[{i}]"), out);
                }
            }
            None => out.push(format!("{path}: expected an array ({ty}), found {v}")),
        }
        return;
    }
    if let Some(inner) = ty.strip_prefix("map<").and_then(|t| t.strip_suffix('>')) {
        match v.as_object() {
            Some(m) => {
                for (k, w) in m {
                    check(s, w, inner, &format!("{path}.{k}"), out);
                }
            }
            None => out.push(format!("{path}: expected an object ({ty}), found {v}")),
        }
        return;
    }
    if matches!(
        ty,
        "string" | "number" | "integer" | "boolean" | "null" | "any"
    ) {
        if !is_type(v, ty) {
            out.push(format!("{path}: expected {ty}, found {v}"));
        }
        return;
    }
    match rows(s, ty, 0) {
        Ok(entries) => check_object(s, v, &entries, "", ty, path, out),
        Err(e) => out.push(format!("{path}: {e}")),
    }
}

/// Validates the object `v` at the dotted prefix `prefix` of a structure's rows.
fn check_object(
    s: &Schemas,
    v: &Value,
    entries: &[Entry],
    prefix: &str,
    name: &str,
    path: &str,
    out: &mut Vec<String>,
) {
    let Some(obj) = v.as_object() else {
        out.push(format!("{path}: expected an object (`{name}`), found {v}"));
        return;
    };
    let full = |k: &str| {
        if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        }
    };
    for (k, w) in obj {
        let key = full(k);
        match entries.iter().find(|e| e.key == key) {
            Some(e) if e.ty == "object" => {
                check_object(s, w, entries, &key, name, &format!("{path}.{k}"), out)
            }
            Some(e) => check(s, w, &e.ty, &format!("{path}.{k}"), out),
            None => out.push(format!(
                "{path}.{k}: not documented in `{name}` (docs/outputs.md)"
            )),
        }
    }
    for e in entries {
        let parent = e.key.rsplit_once('.').map_or("", |(p, _)| p);
        let field = e.key.rsplit_once('.').map_or(e.key.as_str(), |(_, f)| f);
        if parent == prefix && !e.optional && !obj.contains_key(field) {
            out.push(format!(
                "{path}.{field}: documented in `{name}` but missing"
            ));
        }
    }
}

/// The problems of `v` against the structure `name` (empty when it conforms).
fn problems(v: &Value, name: &str) -> Vec<String> {
    let mut out = Vec::new();
    check(schemas(), v, name, "$", &mut out);
    out
}

/// Checks a JSON file written by a command against its structure in docs/outputs.md.
pub fn check_file(path: &Path, name: &str) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let v: Value = serde_json::from_str(&text).unwrap();
    let p = problems(&v, name);
    assert!(
        p.is_empty(),
        "{} does not match `{name}` of docs/outputs.md:\n{}",
        path.display(),
        p.join("\n")
    );
}

/// The checker itself: a conforming value passes; an undocumented key, a wrong type, a missing
/// key and a bad array element each fail, with the path named.
#[test]
fn the_checker_finds_undocumented_missing_and_mistyped_keys() {
    let doc = "### `Inner`\n\n| key | type | unit | meaning |\n|---|---|---|---|\n| x_m | number | m | a length |\n\n\
               ### `Outer`\n\n| key | type | unit | meaning |\n|---|---|---|---|\n| .. | Inner | – | included |\n\
               | n | integer | – | a count |\n| block | object | – | nested |\n| block.ok | boolean | – | a flag |\n\
               | list | Inner[] | – | items |\n| table | map<number?> | – | by name |\n| note? | string | – | optional |\n";
    let s = parse(doc).unwrap();
    let run = |v: Value| {
        let mut out = Vec::new();
        check(&s, &v, "Outer", "$", &mut out);
        out
    };
    let good = serde_json::json!({"x_m": 1.5, "n": 3, "block": {"ok": true},
        "list": [{"x_m": 0.0}], "table": {"a": 1.0, "b": null}});
    assert!(run(good.clone()).is_empty(), "{:?}", run(good.clone()));
    let mut extra = good.clone();
    extra["surprise"] = Value::from(1);
    assert!(run(extra)[0].contains("$.surprise: not documented"));
    let mut wrong = good.clone();
    wrong["n"] = Value::from(2.5);
    assert!(run(wrong)[0].contains("$.n: expected integer"));
    let mut missing = good.clone();
    missing["block"] = serde_json::json!({});
    assert!(run(missing)[0].contains("$.block.ok: documented in `Outer` but missing"));
    let mut bad_item = good;
    bad_item["list"] = serde_json::json!([{"x_m": "far"}]);
    assert!(run(bad_item)[0].contains("$.list[0].x_m: expected number"));
    // Every structure the document names in a type exists.
    let all = schemas();
    for (name, entries) in all {
        for e in entries {
            let base =
                e.ty.trim_end_matches('?')
                    .trim_end_matches("[]")
                    .trim_start_matches("map<")
                    .trim_end_matches('>')
                    .trim_end_matches('?')
                    .trim_end_matches("[]");
            let known = matches!(
                base,
                "string" | "number" | "integer" | "boolean" | "null" | "any" | "object"
            ) || all.contains_key(base);
            assert!(known, "`{name}`.{}: unknown type `{}`", e.key, e.ty);
        }
    }
}

/// The outputs no other end-to-end test writes: `run --repeats 2` (its summary, timings and
/// repeats on a small run section) and `export-mitsuba`.
#[test]
fn repeats_and_export_match_the_schema() {
    use crate::common::{TempDir, spibench, stderr};
    let dir = TempDir::new("schema");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("scenes/paper_bench.ron")).unwrap();
    let end = text.trim_end().rfind(')').unwrap();
    let bench = dir.join("small_run.ron");
    std::fs::write(
        &bench,
        format!(
            "{},\n    run: (sampling_ratios: [0.2], rays: 100000, schemes: \
             [SecondaryComplementaryBalancing, DoubleArmOffset]),\n)\n",
            text[..end].trim_end().trim_end_matches(',')
        ),
    )
    .unwrap();
    let out = dir.join("run");
    let o = spibench(
        &[
            "run",
            bench.to_str().unwrap(),
            "--repeats",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    check_file(&out.join("summary.json"), "RunSummary");
    check_file(&out.join("timings.json"), "RunTimings");
    check_file(&out.join("repeats.json"), "Repeats");
    let out = dir.join("export");
    let o = spibench(
        &[
            "export-mitsuba",
            root.join("scenes/tests/symmetric_arms.ron")
                .to_str()
                .unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    check_file(&out.join("summary.json"), "ExportSummary");
    check_file(&out.join("manifest.json"), "MitsubaManifest");
}
