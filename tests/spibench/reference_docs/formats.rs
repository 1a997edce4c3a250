//! The file-format pages: every type an input file is read into, reached from the file's root
//! type, as a table of its fields (type, unit, default, range, bench variable, meaning) or of
//! its variants, all from the sources' doc comments and declarations ([`super::source`]).

use std::collections::{BTreeMap, BTreeSet, VecDeque};

mod cells;

use super::source::{Body, Field, Item, Shape, Source, serde_flag, serde_value, split_top};

/// One page of the reference: a file format and its root type.
pub struct Format {
    /// The page's file name in docs/reference/.
    pub page: &'static str,
    pub title: &'static str,
    /// The root type and the file that declares it.
    pub root: &'static str,
    pub root_file: &'static str,
    /// The files whose module notes open the page.
    pub notes: &'static [&'static str],
    /// Whether the fields are bench variables (`--set`, `--vary`).
    pub bench: bool,
}

/// The pages, in the order a type is assigned to the first page that reaches it.
pub const FORMATS: [Format; 4] = [
    Format {
        page: "bench.md",
        title: "Bench files",
        root: "BenchFile",
        root_file: "src/scene/bench/schema.rs",
        notes: &["src/scene/bench/mod.rs"],
        bench: true,
    },
    Format {
        page: "experiment.md",
        title: "Experiment files (`spibench simulate`)",
        root: "ExperimentFile",
        root_file: "src/scene/experiment.rs",
        notes: &["src/scene/experiment.rs"],
        bench: false,
    },
    Format {
        page: "tolerance.md",
        title: "Tolerance files (`spibench tolerance`, dataset benches)",
        root: "ToleranceFileSpec",
        root_file: "src/scene/tolerance.rs",
        notes: &["src/scene/tolerance.rs"],
        bench: false,
    },
    Format {
        page: "dataset.md",
        title: "Dataset specs (`spibench dataset`)",
        root: "DatasetFile",
        root_file: "src/scene/dataset.rs",
        notes: &["src/scene/dataset.rs"],
        bench: false,
    },
];

/// The page of the value types (checked numbers, counts, vectors and tables).
pub const VALUES_PAGE: &str = "values.md";

const PRIMITIVES: [&str; 18] = [
    "f32", "f64", "u8", "u16", "u32", "u64", "usize", "i8", "i16", "i32", "i64", "isize", "bool",
    "String", "PathBuf", "Option", "Vec", "Box",
];

/// A type reached from a page, with the file it was named in.
struct Reached<'s> {
    item: &'s Item,
    /// Bench variable prefixes it was reached under (bench page only).
    prefixes: BTreeSet<String>,
}

/// Where each documented type lives: its page and anchor.
pub struct Index<'s> {
    src: &'s Source,
    /// Type name → page file name.
    page_of: BTreeMap<String, &'static str>,
    /// Per page, the types in the order reached.
    order: BTreeMap<&'static str, Vec<String>>,
    reached: BTreeMap<String, Reached<'s>>,
    /// Value types, in the order reached.
    values: Vec<String>,
    /// Problems found: undocumented fields, unresolved types.
    pub problems: Vec<String>,
}

/// The last path segment of each type named in `ty` (`Option<crate::a::B>` → `Option`, `B`),
/// with the path it was written with.
fn named_types(ty: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for c in ty.chars().chain(std::iter::once(' ')) {
        if c.is_alphanumeric() || c == '_' || c == ':' {
            cur.push(c);
        } else {
            if let Some(last) = cur.rsplit("::").next() {
                let constant = last
                    .chars()
                    .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_');
                if !constant && last.chars().next().is_some_and(|c| c.is_ascii_uppercase()) {
                    out.push((last.to_string(), cur.clone()));
                }
            }
            cur.clear();
        }
    }
    out
}

/// The type a field is read as: the checked type of `deserialize_with = "via::<T, _, _>"`, else
/// its declared type.
pub fn read_type(f: &Field) -> String {
    if let Some(v) = serde_value(&f.attrs, "deserialize_with")
        && let Some(inner) = v.strip_prefix("via::<")
        && let Some(first) = split_top(inner.trim_end_matches('>')).first()
    {
        return first.clone();
    }
    f.ty.clone()
}

/// A doc comment as one Markdown paragraph for a table cell.
pub fn cell(doc: &str) -> String {
    let s = unlink(&doc.split_whitespace().collect::<Vec<_>>().join(" "));
    s.replace('|', "\\|")
}

/// Rustdoc links (``[`x`]``) as plain code spans.
pub fn unlink(s: &str) -> String {
    let mut out = String::new();
    let mut rest = s;
    while let Some(k) = rest.find("[`") {
        out.push_str(&rest[..k]);
        let after = &rest[k + 1..];
        match after.find("`]") {
            Some(e) if !after[e + 2..].starts_with('(') => {
                out.push_str(&after[..e + 1]);
                rest = &after[e + 2..];
            }
            _ => {
                out.push('[');
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

fn anchor(name: &str) -> String {
    name.to_lowercase()
}

impl<'s> Index<'s> {
    /// Walks every page's root and assigns each type it reaches to the first page.
    pub fn build(src: &'s Source) -> Index<'s> {
        let mut ix = Index {
            src,
            page_of: BTreeMap::new(),
            order: BTreeMap::new(),
            reached: BTreeMap::new(),
            values: Vec::new(),
            problems: Vec::new(),
        };
        for fmt in &FORMATS {
            ix.walk(fmt);
        }
        ix
    }

    fn resolve(&self, name: &str, from: &str, qualified: &str) -> Option<&'s Item> {
        if PRIMITIVES.contains(&name) {
            return None;
        }
        self.src.item(name, from, qualified)
    }

    /// The written form of a type: a container's `try_from`/`from` type when it names an item.
    fn written(&self, item: &'s Item) -> Option<&'s Item> {
        let via = item
            .serde_value("try_from")
            .or_else(|| item.serde_value("from"))?;
        let (name, q) = named_types(&via).into_iter().next()?;
        self.resolve(&name, &item.file, &q)
    }

    fn walk(&mut self, fmt: &Format) {
        let Some(root) = self.src.item(fmt.root, fmt.root_file, "") else {
            self.problems
                .push(format!("{}: no type {}", fmt.page, fmt.root));
            return;
        };
        let mut queue: VecDeque<(&'s Item, String)> = VecDeque::new();
        queue.push_back((root, String::new()));
        while let Some((item, prefix)) = queue.pop_front() {
            if let Some(w) = self.written(item)
                && matches!(w.body, Body::Struct(_) | Body::Enum(_))
            {
                queue.push_front((w, prefix));
                continue;
            }
            if is_value(item) {
                if !self.values.contains(&item.name) {
                    self.values.push(item.name.clone());
                    self.page_of.insert(item.name.clone(), VALUES_PAGE);
                }
                if let Body::Alias(t) = &item.body {
                    for (n, q) in named_types(t) {
                        if let Some(i) = self.resolve(&n, &item.file, &q) {
                            queue.push_back((i, String::new()));
                        }
                    }
                }
                continue;
            }
            let first = !self.page_of.contains_key(&item.name);
            if first {
                self.page_of.insert(item.name.clone(), fmt.page);
                self.order
                    .entry(fmt.page)
                    .or_default()
                    .push(item.name.clone());
                self.reached.insert(
                    item.name.clone(),
                    Reached {
                        item,
                        prefixes: BTreeSet::new(),
                    },
                );
            }
            if fmt.bench && !prefix.is_empty() {
                let r = self.reached.get_mut(&item.name).unwrap();
                if !r.prefixes.insert(prefix.clone()) && !first {
                    continue;
                }
            } else if !first {
                continue;
            }
            for (field, ty) in children(item) {
                let child_prefix = self.child_prefix(fmt, item, &prefix, &field);
                for (n, q) in named_types(&ty) {
                    if PRIMITIVES.contains(&n.as_str()) {
                        continue;
                    }
                    match self.resolve(&n, &item.file, &q) {
                        Some(i) if i.is_input() || matches!(i.body, Body::Struct(_)) => {
                            queue.push_back((i, child_prefix.clone()));
                        }
                        Some(_) => {}
                        None => self.problems.push(format!(
                            "{}: `{}.{field}` names type `{n}`, declared nowhere in src/",
                            item.file, item.name
                        )),
                    }
                }
            }
        }
    }

    /// The bench variable prefix of a field's type, reached from `item` under `prefix`.
    fn child_prefix(&self, fmt: &Format, item: &Item, prefix: &str, field: &str) -> String {
        if !fmt.bench {
            return String::new();
        }
        if item.name == fmt.root {
            let sections = self.src.consts.get("SECTIONS").cloned().unwrap_or_default();
            return if field == "elements" {
                "NAME".into()
            } else if sections.contains(&format!("\"{field}\"")) {
                field.to_string()
            } else {
                String::new()
            };
        }
        if prefix.is_empty() {
            return String::new();
        }
        if item.name == "ElementSpec" {
            return prefix.to_string();
        }
        if field.chars().next().is_some_and(|c| c.is_ascii_uppercase()) {
            // A variant: passed through.
            return prefix.to_string();
        }
        format!("{prefix}.{field}")
    }

    /// The page a type is documented on, as a Markdown link from `page`.
    pub fn link(&self, name: &str, page: &str) -> String {
        match self.page_of.get(name) {
            Some(p) if *p == page => format!("[`{name}`](#{})", anchor(name)),
            Some(p) => format!("[`{name}`]({p}#{})", anchor(name)),
            None => format!("`{name}`"),
        }
    }

    /// A type as a reader writes it, with links.
    fn show_type(&self, ty: &str, page: &str, from: &str) -> String {
        let ty = ty.trim();
        if let Some(inner) = generic(ty, "Option") {
            return format!("{} (optional)", self.show_type(inner, page, from));
        }
        if let Some(inner) = generic(ty, "Vec") {
            return format!("[{}, …]", self.show_type(inner, page, from));
        }
        if let Some(inner) = generic(ty, "Box") {
            return self.show_type(inner, page, from);
        }
        if ty.starts_with('(') {
            let parts = split_top(&ty[1..ty.len() - 1]);
            let shown: Vec<String> = parts
                .iter()
                .map(|p| self.show_type(p, page, from))
                .collect();
            return format!("({})", shown.join(", "));
        }
        match ty {
            "String" | "PathBuf" => return "text".into(),
            "bool" => return "`true` or `false`".into(),
            t if PRIMITIVES.contains(&t) => return "number".into(),
            _ => {}
        }
        if ty.starts_with("Count<") || ty.starts_with("Whole<") {
            return "whole number".into();
        }
        let (n, q) = named_types(ty).into_iter().next().unwrap_or_default();
        match self.resolve(&n, from, &q) {
            Some(i) => match self.written(i) {
                Some(w) if self.page_of.contains_key(&w.name) => self.link(&w.name, page),
                _ => self.link(&i.name, page),
            },
            None => format!("`{ty}`"),
        }
    }

    /// The Markdown of one format page.
    pub fn page(&self, fmt: &Format) -> String {
        let mut out = String::new();
        out.push_str(&format!("# {}\n\n", fmt.title));
        out.push_str(GENERATED);
        for n in fmt.notes {
            if let Some(doc) = self.src.module_docs.get(*n) {
                out.push_str(&notes(doc));
                out.push('\n');
            }
        }
        if fmt.bench {
            out.push_str("## Bench variables (`--set`, `--vary`, tolerances)\n\n");
            out.push_str(
                "The column *variable* of the tables below says whether a field is a bench \
                 variable, a path that `--set PATH=VALUE`, `sweep --vary`, `align --free` and \
                 tolerance files accept; each type's heading names the paths it is reached \
                 under. The rules (from `src/scene/variables/mod.rs`):\n\n",
            );
            if let Some(doc) = self.src.module_docs.get("src/scene/variables/mod.rs") {
                out.push_str(&notes(doc));
                out.push('\n');
            }
        }
        out.push_str("## Types\n\n");
        for name in self.order.get(fmt.page).into_iter().flatten() {
            let r = &self.reached[name];
            out.push_str(&self.section(fmt, r));
        }
        out
    }

    fn section(&self, fmt: &Format, r: &Reached) -> String {
        let item = r.item;
        let mut out = format!("### `{}`\n\n", item.name);
        let mut head = Vec::new();
        if let Some(w) = item.serde_value("rename") {
            head.push(format!("Written `{w}(…)`."));
        }
        if item.name == "ElementSpec" {
            head.push(
                "Written as a struct variant `Kind(name: …, …)` holding its kind's fields.".into(),
            );
        }
        if fmt.bench && !r.prefixes.is_empty() {
            let ps: Vec<String> = r.prefixes.iter().map(|p| format!("`{p}.FIELD`")).collect();
            if ps.len() <= 4 {
                head.push(format!("Bench variables: {}.", ps.join(", ")));
            } else {
                head.push(
                    "Bench variables: the path of the field that holds it, then `.FIELD`.".into(),
                );
            }
        }
        let doc = unlink(&item.doc);
        if !doc.trim().is_empty() {
            out.push_str(doc.trim());
            out.push_str("\n\n");
        }
        if !head.is_empty() {
            out.push_str(&head.join(" "));
            out.push_str("\n\n");
        }
        match &item.body {
            Body::Struct(fields) => out.push_str(&self.fields_table(fmt, item, fields)),
            Body::Enum(vs) => {
                out.push_str("| variant | written | meaning |\n|---|---|---|\n");
                for v in vs {
                    let written = match &v.shape {
                        Shape::Unit => format!("`{}`", v.name),
                        Shape::Tuple(ts) => {
                            let shown: Vec<String> = ts
                                .iter()
                                .map(|t| self.show_type(t, fmt.page, &item.file))
                                .collect();
                            format!("`{}(`{}`)`", v.name, shown.join(", "))
                        }
                        Shape::Struct(fs) => {
                            let names: Vec<String> =
                                fs.iter().map(|f| format!("{}: …", f.name)).collect();
                            format!("`{}({})`", v.name, names.join(", "))
                        }
                    };
                    let mut meaning = cell(&v.doc);
                    if let (true, Shape::Tuple(ts)) = (meaning.is_empty(), &v.shape) {
                        let (n, q) = named_types(&ts[0]).into_iter().next().unwrap_or_default();
                        if let Some(i) = self.resolve(&n, &item.file, &q) {
                            meaning = first_sentence(&i.doc);
                        }
                    }
                    if let Some(a) = serde_value(&v.attrs, "alias") {
                        meaning.push_str(&format!(" (also `{a}`)"));
                    }
                    if v.attrs.contains("#[default]") {
                        meaning.push_str(" Default.");
                    }
                    out.push_str(&format!(
                        "| `{}` | {written} | {} |\n",
                        v.name,
                        meaning.trim()
                    ));
                }
                out.push('\n');
                for v in vs {
                    if let Shape::Struct(fs) = &v.shape {
                        out.push_str(&format!("Fields of `{}`:\n\n", v.name));
                        out.push_str(&self.fields_table(fmt, item, fs));
                    }
                }
            }
            Body::TupleStruct(ts) => {
                let shown: Vec<String> = ts
                    .iter()
                    .map(|t| self.show_type(t, fmt.page, &item.file))
                    .collect();
                out.push_str(&format!("Written as {}.\n\n", shown.join(", ")));
            }
            _ => {}
        }
        out
    }

    fn fields_table(&self, fmt: &Format, item: &Item, fields: &[Field]) -> String {
        let mut out = String::new();
        if fmt.bench {
            out.push_str(
                "| field | type | unit | default | range | variable | meaning |\n\
                 |---|---|---|---|---|---|---|\n",
            );
        } else {
            out.push_str(
                "| field | type | unit | default | range | meaning |\n|---|---|---|---|---|---|\n",
            );
        }
        for f in fields {
            if serde_flag(&f.attrs, "skip") || serde_flag(&f.attrs, "skip_deserializing") {
                continue;
            }
            let ty = read_type(f);
            let name = serde_value(&f.attrs, "rename").unwrap_or_else(|| f.name.clone());
            let cells = [
                format!("`{name}`"),
                self.show_type(&ty, fmt.page, &item.file),
                self.unit(&name, &ty, &item.file),
                self.default(item, f, &ty),
                self.range(&ty, &item.file),
            ];
            let mut row = format!("| {} ", cells.join(" | "));
            if fmt.bench {
                let top = item.name == fmt.root;
                let tops = self
                    .src
                    .consts
                    .get("TOP_FIELDS")
                    .cloned()
                    .unwrap_or_default();
                let sections = self.src.consts.get("SECTIONS").cloned().unwrap_or_default();
                let quoted = format!("\"{name}\"");
                let v = if !top {
                    self.variable(&ty, &item.file, 0)
                } else if tops.contains(&quoted) {
                    let v = self.variable(&ty, &item.file, 0);
                    format!("`{name}`{}", v.strip_prefix("yes").unwrap_or(""))
                } else if sections.contains(&quoted) {
                    format!("`{name}.FIELD`")
                } else if name == "elements" {
                    "`NAME.FIELD`".into()
                } else {
                    "no".into()
                };
                row.push_str(&format!("| {v} "));
            }
            row.push_str(&format!("| {} |\n", cell(&f.doc)));
            out.push_str(&row);
        }
        out.push('\n');
        out
    }

    /// The page of value types.
    pub fn values_page(&self) -> String {
        let mut out = String::from("# Value types\n\n");
        out.push_str(GENERATED);
        out.push_str(
            "The numbers of every input file are read through these types: a value outside its \
             range is refused while the file is read, and the error names the file, line, \
             column and field.\n\n| type | range | unit | meaning |\n|---|---|---|---|\n",
        );
        let mut names = self.values.clone();
        names.sort();
        for name in names {
            let items = &self.src.items[&name];
            let item = items.iter().find(|i| is_value(i)).unwrap_or(&items[0]);
            let (range, unit) = match &item.body {
                Body::Checked(args) => (
                    self.checked_range(args),
                    args.iter()
                        .find_map(|a| a.strip_prefix("unit "))
                        .map(|u| u.trim_matches('"').to_string())
                        .unwrap_or_default(),
                ),
                Body::Alias(t) => (self.range(t, &item.file), String::new()),
                _ => (String::new(), String::new()),
            };
            out.push_str(&format!(
                "| <a id=\"{}\"></a>`{name}` | {range} | {unit} | {} |\n",
                anchor(&name),
                cell(&item.doc)
            ));
        }
        out
    }

    /// Fields and variants without a doc comment, and types never resolved.
    pub fn undocumented(&self) -> Vec<String> {
        let mut out = self.problems.clone();
        for r in self.reached.values() {
            let item = r.item;
            if item.doc.trim().is_empty() {
                out.push(format!("{}: type `{}`", item.file, item.name));
            }
            let fields: Vec<(&str, &Field)> = match &item.body {
                Body::Struct(fs) => fs.iter().map(|f| ("", f)).collect(),
                Body::Enum(vs) => {
                    let mut v = Vec::new();
                    for var in vs {
                        if var.doc.trim().is_empty() && item.name != "ElementSpec" {
                            out.push(format!(
                                "{}: variant `{}::{}`",
                                item.file, item.name, var.name
                            ));
                        }
                        if let Shape::Struct(fs) = &var.shape {
                            v.extend(fs.iter().map(|f| (var.name.as_str(), f)));
                        }
                    }
                    v
                }
                _ => Vec::new(),
            };
            for (var, f) in fields {
                if f.doc.trim().is_empty() && !serde_flag(&f.attrs, "skip") {
                    let var = if var.is_empty() {
                        String::new()
                    } else {
                        format!("::{var}")
                    };
                    out.push(format!(
                        "{}: field `{}{var}.{}`",
                        item.file, item.name, f.name
                    ));
                }
            }
        }
        for name in &self.values {
            let items = &self.src.items[name];
            if items.iter().all(|i| i.doc.trim().is_empty()) {
                out.push(format!("{}: value type `{name}`", items[0].file));
            }
        }
        out.sort();
        out
    }
}

/// The line every generated page carries under its title.
pub const GENERATED: &str = "*Generated from the doc comments and declarations of `src/` by \
     `tests/spibench/reference_docs.rs`; do not edit: change the source and regenerate \
     (CONTRIBUTING.md, \"The reference pages\").*\n\n";

/// A value type: a checked scalar, a count alias or a checked tuple (its whole written form is
/// a number or numbers).
fn is_value(item: &Item) -> bool {
    match &item.body {
        Body::Checked(_) => true,
        Body::Alias(t) => t.starts_with("Count<") || t.starts_with("Whole<"),
        Body::TupleStruct(_) => {
            item.serde_value("try_from")
                .is_some_and(|t| t.starts_with('(') || t.starts_with("Vec") || t == "f64")
                || matches!(item.name.as_str(), "Count" | "Whole")
        }
        _ => false,
    }
}

/// The fields of an item (and of its struct variants, and its tuple variants' types), as
/// (name, type read) pairs.
fn children(item: &Item) -> Vec<(String, String)> {
    match &item.body {
        Body::Struct(fs) => fs.iter().map(|f| (f.name.clone(), read_type(f))).collect(),
        Body::TupleStruct(ts) => ts.iter().map(|t| ("0".to_string(), t.clone())).collect(),
        Body::Alias(t) => vec![(String::new(), t.clone())],
        Body::Enum(vs) => {
            let mut out = Vec::new();
            for v in vs {
                match &v.shape {
                    Shape::Unit => {}
                    Shape::Tuple(ts) => out.extend(ts.iter().map(|t| (v.name.clone(), t.clone()))),
                    Shape::Struct(fs) => {
                        out.extend(fs.iter().map(|f| (v.name.clone(), read_type(f))));
                    }
                }
            }
            out
        }
        Body::Checked(_) => Vec::new(),
    }
}

/// The inner type of `Name<inner>`.
fn generic<'a>(ty: &'a str, name: &str) -> Option<&'a str> {
    let (head, rest) = ty.trim().split_once('<')?;
    if head.rsplit("::").next() != Some(name) {
        return None;
    }
    rest.strip_suffix('>')
}

fn first_sentence(doc: &str) -> String {
    let d = cell(doc);
    match d.find(". ") {
        Some(k) => d[..=k].to_string(),
        None => d,
    }
}

/// The module notes as Markdown: rustdoc links unlinked, the list of the module's own files
/// dropped (it is for readers of the code).
fn notes(doc: &str) -> String {
    let mut out = String::new();
    for para in doc.split("\n\n") {
        if para.starts_with("The module's files") || para.trim().is_empty() {
            continue;
        }
        out.push_str(&unlink(para));
        out.push_str("\n\n");
    }
    out
}
