//! A small reader of the library's own sources, enough for the reference pages: the items that
//! input files are read into (structs and enums that derive `Deserialize`), their doc comments,
//! serde attributes and fields, the checked scalars declared with `checked!`, type aliases,
//! constants and the bodies of `default_*` functions.
//!
//! It reads rustfmt's layout line by line (an item starts at column 0, its fields or variants
//! at column 4, a struct variant's fields at column 8), which `cargo fmt --check` in CI keeps
//! true. It stops at a file's `#[cfg(test)] mod tests {`, whose types are the tests' own.

use std::collections::BTreeMap;
use std::path::Path;

/// One field of a struct or of a struct variant.
#[derive(Debug, Clone)]
pub struct Field {
    pub name: String,
    /// The type as written (whitespace collapsed).
    pub ty: String,
    pub doc: String,
    /// Its attributes, joined (`#[serde(default)]#[serde(rename = "x")]`).
    pub attrs: String,
}

/// The shape of an enum variant.
#[derive(Debug, Clone)]
pub enum Shape {
    Unit,
    Tuple(Vec<String>),
    Struct(Vec<Field>),
}

#[derive(Debug, Clone)]
pub struct Variant {
    pub name: String,
    pub doc: String,
    pub attrs: String,
    pub shape: Shape,
}

/// What an item is.
#[derive(Debug, Clone)]
pub enum Body {
    Struct(Vec<Field>),
    /// A tuple struct's field types.
    TupleStruct(Vec<String>),
    Enum(Vec<Variant>),
    /// `pub type Name = Target;`
    Alias(String),
    /// A `checked!` scalar: the arguments after its name (`above 0.0`, `at_most 1.0`,
    /// `unit "mm"`, or a condition `|v| …`).
    Checked(Vec<String>),
}

#[derive(Debug, Clone)]
pub struct Item {
    pub name: String,
    /// The file, relative to the crate root.
    pub file: String,
    pub doc: String,
    /// The item's attributes, joined.
    pub attrs: String,
    pub body: Body,
}

impl Item {
    /// Whether a file can hold it: it derives `Deserialize` (or is a checked scalar, an alias,
    /// or `ElementSpec`, whose reader is written by hand).
    pub fn is_input(&self) -> bool {
        match self.body {
            Body::Checked(_) | Body::Alias(_) => true,
            _ => self.attrs.contains("Deserialize") || self.name == "ElementSpec",
        }
    }

    /// The value of a serde attribute `key = "…"` of the item.
    pub fn serde_value(&self, key: &str) -> Option<String> {
        serde_value(&self.attrs, key)
    }
}

/// The value of `key = "…"` in a run of attributes.
pub fn serde_value(attrs: &str, key: &str) -> Option<String> {
    let mut rest = attrs;
    while let Some(k) = rest.find(key) {
        let before = rest[..k].chars().last();
        let after = rest[k + key.len()..].trim_start();
        rest = &rest[k + key.len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        if let Some(v) = after.strip_prefix('=') {
            let v = v.trim_start().strip_prefix('"')?;
            return Some(v[..v.find('"')?].to_string());
        }
    }
    None
}

/// Whether a run of attributes holds the bare serde word `word` (`default`, `skip`).
pub fn serde_flag(attrs: &str, word: &str) -> bool {
    attrs
        .split("#[")
        .filter_map(|a| a.strip_prefix("serde("))
        .any(|a| {
            let inner = a.trim_end().trim_end_matches(']').trim_end_matches(')');
            split_top(inner).iter().any(|w| w == word)
        })
}

/// Everything read from the sources.
#[derive(Debug, Default)]
pub struct Source {
    /// Items by name; a name declared in several files keeps each.
    pub items: BTreeMap<String, Vec<Item>>,
    /// Constants by name: their value as written.
    pub consts: BTreeMap<String, String>,
    /// Function bodies by name (one-expression bodies of `fn default_…` and similar).
    pub fns: BTreeMap<String, String>,
    /// Bodies of `impl Default for Name` (`Name { field: value, … }`), by type name.
    pub defaults: BTreeMap<String, String>,
    /// Module doc comments (`//!`) by file.
    pub module_docs: BTreeMap<String, String>,
}

impl Source {
    /// Reads every `.rs` file below `src/` of `root`, except unit-test files.
    pub fn read(root: &Path) -> Source {
        let mut files = Vec::new();
        let mut dirs = vec![root.join("src")];
        while let Some(d) = dirs.pop() {
            for e in std::fs::read_dir(&d).unwrap().flatten() {
                let p = e.path();
                if p.is_dir() {
                    dirs.push(p);
                } else if p.extension().is_some_and(|x| x == "rs")
                    && p.file_name().is_some_and(|n| n != "tests.rs")
                {
                    files.push(p);
                }
            }
        }
        files.sort();
        let mut src = Source::default();
        for f in files {
            let rel = f
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            let text = std::fs::read_to_string(&f).unwrap();
            src.read_file(&rel, &text);
        }
        src
    }

    /// The item `name` as seen from `file`: the one in that file, else in the same folder,
    /// else one whose file matches the path the type was written with, else the only one.
    pub fn item(&self, name: &str, from_file: &str, qualified: &str) -> Option<&Item> {
        let all = self.items.get(name)?;
        let inputs: Vec<&Item> = all.iter().filter(|i| i.is_input()).collect();
        let pool = if inputs.is_empty() {
            all.iter().collect()
        } else {
            inputs
        };
        if pool.len() == 1 {
            return Some(pool[0]);
        }
        let dir = |f: &str| {
            f.rsplit_once('/')
                .map_or(String::new(), |(d, _)| d.to_string())
        };
        if let Some(i) = pool.iter().find(|i| i.file == from_file) {
            return Some(i);
        }
        let module = qualified
            .trim_start_matches("crate::")
            .rsplit_once("::")
            .map(|(m, _)| m.replace("::", "/"));
        if let Some(m) = module
            && let Some(i) = pool.iter().find(|i| i.file.contains(&m))
        {
            return Some(i);
        }
        if let Some(i) = pool.iter().find(|i| dir(&i.file) == dir(from_file)) {
            return Some(i);
        }
        pool.first().copied()
    }

    fn read_file(&mut self, file: &str, text: &str) {
        let lines: Vec<&str> = text.lines().collect();
        let module_doc: Vec<&str> = lines
            .iter()
            .take_while(|l| l.starts_with("//!"))
            .map(|l| l.trim_start_matches("//!").strip_prefix(' ').unwrap_or(""))
            .collect();
        self.module_docs
            .insert(file.to_string(), module_doc.join("\n"));
        let mut doc: Vec<String> = Vec::new();
        let mut attrs = String::new();
        let mut i = 0;
        while i < lines.len() {
            let line = lines[i];
            if line == "#[cfg(test)]" && lines.get(i + 1).is_some_and(|l| l.ends_with('{')) {
                break;
            }
            if let Some(d) = line.strip_prefix("///") {
                doc.push(d.strip_prefix(' ').unwrap_or(d).to_string());
                i += 1;
                continue;
            }
            if line.starts_with("#[") {
                let (a, next) = attribute(&lines, i);
                attrs.push_str(&a);
                i = next;
                continue;
            }
            // A plain comment between an item's attributes keeps them.
            if line.starts_with("//") && !line.starts_with("//!") {
                i += 1;
                continue;
            }
            let head = strip_visibility(line);
            let take = |doc: &mut Vec<String>, attrs: &mut String| {
                (std::mem::take(doc).join("\n"), std::mem::take(attrs))
            };
            if let Some(rest) = head.strip_prefix("struct ") {
                let (d, a) = take(&mut doc, &mut attrs);
                let name = ident(rest);
                let (body, next) = if rest.trim_end().ends_with('{') {
                    let (fields, next) = fields(&lines, i + 1, 4);
                    (Body::Struct(fields), next)
                } else if rest.contains('(') {
                    let (inner, next) = until_balanced(&lines, i, '(', ')');
                    (Body::TupleStruct(split_top(&inner)), next)
                } else {
                    (Body::Struct(Vec::new()), i + 1)
                };
                self.push(file, name, d, a, body);
                i = next;
            } else if let Some(rest) = head.strip_prefix("enum ") {
                let (d, a) = take(&mut doc, &mut attrs);
                let name = ident(rest);
                let (variants, next) = variants(&lines, i + 1);
                self.push(file, name, d, a, Body::Enum(variants));
                i = next;
            } else if let Some(rest) = head.strip_prefix("type ") {
                let (d, a) = take(&mut doc, &mut attrs);
                let (text, next) = until_semicolon(&lines, i);
                let target = text.split_once('=').map_or("", |(_, t)| t).trim();
                let target = target.trim_end_matches(';').trim().to_string();
                self.push(file, ident(rest), d, a, Body::Alias(target));
                i = next;
            } else if line.starts_with("checked!(") {
                doc.clear();
                attrs.clear();
                i = self.checked(file, &lines, i + 1);
            } else if let Some(rest) = head.strip_prefix("const ") {
                doc.clear();
                attrs.clear();
                let (text, next) = until_semicolon(&lines, i);
                let name = ident(rest);
                if let Some((_, v)) = text.split_once('=') {
                    let v = v.trim().trim_end_matches(';').trim().to_string();
                    self.consts.insert(name, v);
                }
                let _ = rest;
                i = next;
            } else if let Some(rest) = head.strip_prefix("fn ") {
                doc.clear();
                attrs.clear();
                let name = ident(rest);
                let mut j = i + 1;
                let mut body = Vec::new();
                while j < lines.len() && lines[j] != "}" {
                    body.push(lines[j].trim());
                    j += 1;
                }
                if line.trim_end().ends_with('{') && body.len() <= 3 {
                    self.fns.insert(name, body.join(" "));
                }
                i = j + 1;
            } else if let Some(rest) = line.strip_prefix("impl Default for ") {
                doc.clear();
                attrs.clear();
                let name = ident(rest);
                let mut j = i + 1;
                let mut body = Vec::new();
                while j < lines.len() && lines[j] != "}" {
                    body.push(lines[j].trim());
                    j += 1;
                }
                self.defaults.insert(name, body.join(" "));
                i = j + 1;
            } else {
                if !line.trim().is_empty() {
                    doc.clear();
                    attrs.clear();
                }
                i += 1;
            }
        }
    }

    fn push(&mut self, file: &str, name: String, doc: String, attrs: String, body: Body) {
        self.items.entry(name.clone()).or_default().push(Item {
            name,
            file: file.to_string(),
            doc,
            attrs,
            body,
        });
    }

    /// A `checked!(…)` invocation from its first argument line; returns the line after it.
    fn checked(&mut self, file: &str, lines: &[&str], mut i: usize) -> usize {
        let mut doc = Vec::new();
        let mut args: Vec<String> = Vec::new();
        let mut name = None;
        while i < lines.len() && !lines[i].starts_with(')') {
            let t = lines[i].trim();
            if let Some(d) = t.strip_prefix("///") {
                doc.push(d.strip_prefix(' ').unwrap_or(d).to_string());
            } else if name.is_none() {
                name = Some(t.trim_end_matches(',').to_string());
            } else if lines[i].starts_with("    ") && !lines[i].starts_with("     ") {
                args.push(t.trim_end_matches(',').to_string());
            } else if let Some(last) = args.last_mut() {
                last.push(' ');
                last.push_str(t);
            }
            i += 1;
        }
        if let Some(n) = name {
            self.push(file, n, doc.join("\n"), String::new(), Body::Checked(args));
        }
        i + 1
    }
}

fn strip_visibility(line: &str) -> &str {
    for p in ["pub(crate) ", "pub(super) ", "pub "] {
        if let Some(r) = line.strip_prefix(p) {
            return r;
        }
    }
    line
}

/// The identifier at the start of `s`.
fn ident(s: &str) -> String {
    s.trim_start()
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect()
}

/// An attribute from line `i` (possibly over several lines); returns it and the next line.
fn attribute(lines: &[&str], i: usize) -> (String, usize) {
    let (text, next) = until_balanced(lines, i, '[', ']');
    (format!("#[{text}]"), next)
}

/// The text inside the first `open` … matching `close` from line `i` (joined with spaces), and
/// the line after the one that closes it.
fn until_balanced(lines: &[&str], i: usize, open: char, close: char) -> (String, usize) {
    let mut depth = 0;
    let mut out = String::new();
    let mut started = false;
    let mut j = i;
    while j < lines.len() {
        let mut in_str = false;
        for c in lines[j].trim().chars() {
            if c == '"' {
                in_str = !in_str;
            }
            if !in_str && c == open {
                depth += 1;
                if !started {
                    started = true;
                    continue;
                }
            }
            if !in_str && c == close && started {
                depth -= 1;
                if depth == 0 {
                    return (out.trim().to_string(), j + 1);
                }
            }
            if started {
                out.push(c);
            }
        }
        if started {
            out.push(' ');
        }
        j += 1;
    }
    (out, j)
}

fn until_semicolon(lines: &[&str], i: usize) -> (String, usize) {
    let mut out = String::new();
    let mut j = i;
    while j < lines.len() {
        out.push_str(lines[j].trim());
        out.push(' ');
        if lines[j].trim_end().ends_with(';') {
            return (out, j + 1);
        }
        j += 1;
    }
    (out, j)
}

/// Splits at commas outside brackets.
pub fn split_top(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut cur = String::new();
    for c in s.chars() {
        match c {
            '<' | '(' | '[' | '{' => depth += 1,
            '>' | ')' | ']' | '}' => depth -= 1,
            ',' if depth == 0 => {
                out.push(cur.trim().to_string());
                cur.clear();
                continue;
            }
            _ => {}
        }
        cur.push(c);
    }
    if !cur.trim().is_empty() {
        out.push(cur.trim().to_string());
    }
    out.into_iter()
        .map(|t| t.trim_start_matches("pub ").to_string())
        .collect()
}

/// Collapses runs of whitespace (a type written over several lines).
fn collapse(s: &str) -> String {
    let s = s.split_whitespace().collect::<Vec<_>>().join(" ");
    s.replace("< ", "<")
        .replace(" >", ">")
        .replace("( ", "(")
        .replace(" )", ")")
}

/// The fields of a struct body starting at line `i`, at indent `indent`, up to the closing
/// brace one level out; returns them and the line after that brace.
fn fields(lines: &[&str], mut i: usize, indent: usize) -> (Vec<Field>, usize) {
    let pad = " ".repeat(indent);
    let mut out = Vec::new();
    let mut doc = Vec::new();
    let mut attrs = String::new();
    while i < lines.len() {
        let line = lines[i];
        let t = line.trim();
        if !line.starts_with(&pad) && t.starts_with('}') {
            return (out, i + 1);
        }
        if let Some(d) = t.strip_prefix("///") {
            doc.push(d.strip_prefix(' ').unwrap_or(d).to_string());
            i += 1;
        } else if t.starts_with("#[") {
            let (a, next) = attribute(lines, i);
            attrs.push_str(&a);
            i = next;
        } else if t.starts_with("//") || t.is_empty() {
            i += 1;
        } else {
            // `name: Type,`, the type possibly over several lines.
            let mut text = String::new();
            let mut j = i;
            loop {
                text.push_str(lines[j].trim());
                text.push(' ');
                let open = text.matches(['<', '(', '[']).count();
                let close = text.matches(['>', ')', ']']).count() - text.matches("->").count();
                if (text.trim_end().ends_with(',') && open == close) || j + 1 >= lines.len() {
                    break;
                }
                if lines[j + 1].trim().starts_with('}') && !lines[j + 1].starts_with(&pad) {
                    break;
                }
                j += 1;
            }
            let text = strip_visibility(text.trim());
            if let Some((n, ty)) = text.split_once(':') {
                out.push(Field {
                    name: n.trim().to_string(),
                    ty: collapse(ty.trim().trim_end_matches(',')),
                    doc: std::mem::take(&mut doc).join("\n"),
                    attrs: std::mem::take(&mut attrs),
                });
            }
            i = j + 1;
        }
    }
    (out, i)
}

/// The variants of an enum body from line `i`; returns them and the line after its brace.
fn variants(lines: &[&str], mut i: usize) -> (Vec<Variant>, usize) {
    let mut out = Vec::new();
    let mut doc = Vec::new();
    let mut attrs = String::new();
    while i < lines.len() {
        let line = lines[i];
        let t = line.trim();
        if line.starts_with('}') {
            return (out, i + 1);
        }
        if let Some(d) = t.strip_prefix("///") {
            doc.push(d.strip_prefix(' ').unwrap_or(d).to_string());
            i += 1;
            continue;
        }
        if t.starts_with("#[") {
            let (a, next) = attribute(lines, i);
            attrs.push_str(&a);
            i = next;
            continue;
        }
        if t.starts_with("//") || t.is_empty() {
            i += 1;
            continue;
        }
        let name = ident(t);
        let rest = t[name.len()..].trim();
        let (shape, next) = if rest.starts_with('{') && rest.ends_with("},") {
            // `Name { field: Type },` on one line.
            let inner = rest.trim_start_matches('{').trim_end_matches("},");
            let fields = split_top(inner)
                .into_iter()
                .filter_map(|f| {
                    let (n, ty) = f.split_once(':')?;
                    Some(Field {
                        name: n.trim().to_string(),
                        ty: collapse(ty),
                        doc: String::new(),
                        attrs: String::new(),
                    })
                })
                .collect();
            (Shape::Struct(fields), i + 1)
        } else if rest.starts_with('{') {
            let (f, next) = fields(lines, i + 1, 8);
            (Shape::Struct(f), next)
        } else if rest.starts_with('(') {
            let (inner, next) = until_balanced(lines, i, '(', ')');
            let mut next = next;
            // A tuple variant closed on its own line `),`.
            if lines.get(next).is_some_and(|l| l.trim() == ",") {
                next += 1;
            }
            (Shape::Tuple(split_top(&collapse(&inner))), next)
        } else {
            (Shape::Unit, i + 1)
        };
        out.push(Variant {
            name,
            doc: std::mem::take(&mut doc).join("\n"),
            attrs: std::mem::take(&mut attrs),
            shape,
        });
        i = next;
    }
    (out, i)
}
