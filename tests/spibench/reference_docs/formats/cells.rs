//! The cells of a field's row: its allowed range, unit, default and whether it is a bench
//! variable, each read from the field's declared type and attributes.

use std::collections::BTreeSet;

use super::super::source::{Body, Field, Item, Shape, serde_flag, serde_value, split_top};
use super::{Index, PRIMITIVES, generic, is_value, named_types};

impl Index<'_> {
    /// A field's allowed range, from its type.
    pub(super) fn range(&self, ty: &str, from: &str) -> String {
        let ty = ty.trim();
        for g in ["Option", "Vec", "Box"] {
            if let Some(inner) = generic(ty, g) {
                return self.range(inner, from);
            }
        }
        if ty.starts_with('(') {
            let parts: BTreeSet<String> = split_top(&ty[1..ty.len() - 1])
                .iter()
                .map(|p| self.range(p, from))
                .collect();
            return parts.into_iter().collect::<Vec<_>>().join("; ");
        }
        if let Some(b) = ty
            .strip_prefix("Count<")
            .or_else(|| ty.strip_prefix("Whole<"))
        {
            let parts = split_top(b.trim_end_matches('>'));
            if parts.len() == 2 {
                return format!("{} … {}", self.value(&parts[0]), self.value(&parts[1]));
            }
        }
        match ty {
            "u64" | "u32" | "usize" => return "any whole number ≥ 0".into(),
            "String" | "PathBuf" | "bool" => return String::new(),
            _ => {}
        }
        let (n, q) = named_types(ty).into_iter().next().unwrap_or_default();
        let Some(item) = self.resolve(&n, from, &q) else {
            return String::new();
        };
        match &item.body {
            Body::Alias(t) => self.range(t, &item.file),
            Body::Checked(args) => self.checked_range(args),
            Body::Enum(vs) if vs.iter().all(|v| matches!(v.shape, Shape::Unit)) => {
                let names: Vec<String> = vs.iter().map(|v| format!("`{}`", v.name)).collect();
                names.join(", ")
            }
            _ if is_value(item) => format!("see {}", self.link(&item.name, "")),
            _ => String::new(),
        }
    }

    /// A checked scalar's range: `(lo, hi]`, `[lo, hi]` or its condition.
    pub fn checked_range(&self, args: &[String]) -> String {
        let arg = |k: &str| {
            args.iter()
                .find_map(|a| a.strip_prefix(k).map(|v| self.value(v.trim())))
        };
        match (arg("above "), arg("from "), arg("at_most ")) {
            (Some(lo), _, Some(hi)) => format!("({lo}, {hi}]"),
            (_, Some(lo), Some(hi)) => format!("[{lo}, {hi}]"),
            _ => match args.first() {
                Some(cond) => {
                    let c = cond
                        .split_once('|')
                        .and_then(|(_, r)| r.split_once('|'))
                        .map_or(cond.as_str(), |(_, c)| c)
                        .trim();
                    self.condition(c)
                }
                None => String::new(),
            },
        }
    }

    /// A checked scalar's condition in interval notation where it has a common form.
    pub(super) fn condition(&self, c: &str) -> String {
        let parts: Vec<&str> = c.split(" && ").map(str::trim).collect();
        let mut lo: Option<String> = None;
        let mut hi: Option<String> = None;
        let mut rest = Vec::new();
        for p in parts {
            if let Some(x) = p.strip_prefix("v.abs() <= ") {
                let x = self.value(x);
                lo = Some(format!("[−{x}"));
                hi = Some(format!("{x}]"));
            } else if let Some(x) = p.strip_prefix("v.abs() < ") {
                let x = self.value(x);
                lo = Some(format!("(−{x}"));
                hi = Some(format!("{x})"));
            } else if let Some(x) = p.strip_prefix("v > ") {
                lo = Some(format!("({}", self.value(x)));
            } else if let Some(x) = p.strip_prefix("v >= ") {
                lo = Some(format!("[{}", self.value(x)));
            } else if let Some(x) = p.strip_prefix("v < ") {
                hi = Some(format!("{})", self.value(x)));
            } else if let Some(x) = p.strip_prefix("v <= ") {
                hi = Some(format!("{}]", self.value(x)));
            } else if let Some(r) = p
                .strip_prefix('(')
                .and_then(|r| r.strip_suffix(").contains(&v)"))
            {
                if let Some((a, b)) = r.split_once("..=") {
                    lo = Some(format!("[{}", self.value(a)));
                    hi = Some(format!("{}]", self.value(b)));
                } else if let Some((a, b)) = r.split_once("..") {
                    lo = Some(format!("[{}", self.value(a)));
                    hi = Some(format!("{})", self.value(b)));
                }
            } else if p == "v != 0.0" {
                rest.push("not 0".to_string());
            } else if p == "v.is_normal()" {
                rest.push("not subnormal".to_string());
            } else {
                return format!("`{c}`");
            }
        }
        let interval = match (lo, hi) {
            (Some(l), Some(h)) => format!("{l}, {h}"),
            (Some(l), None) => format!("{l}, ∞)"),
            (None, Some(h)) => format!("(−∞, {h}"),
            (None, None) => "finite".to_string(),
        };
        let mut out = vec![interval];
        out.extend(rest);
        out.join(", ")
    }

    /// A bound or constant as written, a constant replaced by its value.
    pub(super) fn value(&self, v: &str) -> String {
        if let Some((a, b)) = v.split_once(" << ")
            && let (Ok(a), Ok(b)) = (a.trim().parse::<u64>(), b.trim().parse::<u32>())
        {
            return (a << b).to_string();
        }
        let v = v.trim().trim_matches(['{', '}']).trim();
        let v = v.split(" as ").next().unwrap_or(v).trim();
        let name = v.rsplit("::").next().unwrap_or(v);
        match self.src.consts.get(name) {
            Some(c) => self.value(c),
            None if v.starts_with(|c: char| c.is_ascii_digit() || c == '-') => v.replace('_', ""),
            None => v.to_string(),
        }
    }

    /// A field's unit: from its name's suffix, else from its checked type.
    pub(super) fn unit(&self, field: &str, ty: &str, from: &str) -> String {
        const SUFFIXES: [(&str, &str); 22] = [
            ("a_per_rthz", "A/√Hz"),
            ("w_per_rthz", "W/√Hz"),
            ("_a_per_w", "A/W"),
            ("volts_per_div", "V/div"),
            ("_mm", "mm"),
            ("_um2", "µm²"),
            ("_um", "µm"),
            ("_nm", "nm"),
            ("_deg", "degrees"),
            ("_hz", "Hz"),
            ("_v", "V"),
            ("_a", "A"),
            ("_w", "W"),
            ("_s", "s"),
            ("_us", "µs"),
            ("_k", "K"),
            ("_px", "pixels"),
            ("_percent", "%"),
            ("_gb", "GB"),
            ("_ohm", "Ω"),
            ("_f", "F"),
            ("_w_m2", "W/m²"),
        ];
        let mut best: Option<(&str, &str)> = None;
        for (s, u) in SUFFIXES {
            let whole = field == s.trim_start_matches('_');
            if (field.ends_with(s) || whole) && best.is_none_or(|(b, _)| s.len() > b.len()) {
                best = Some((s, u));
            }
        }
        if let Some((_, u)) = best {
            return u.to_string();
        }
        let (n, q) = named_types(ty).into_iter().last().unwrap_or_default();
        if let Some(Item {
            body: Body::Checked(args),
            ..
        }) = self.resolve(&n, from, &q)
            && let Some(u) = args.iter().find_map(|a| a.strip_prefix("unit "))
        {
            return u.trim_matches('"').to_string();
        }
        String::new()
    }

    /// A field's default, or "required".
    pub(super) fn default(&self, item: &Item, f: &Field, ty: &str) -> String {
        if let Some(func) = serde_value(&f.attrs, "default") {
            return match self.src.fns.get(&func) {
                Some(body) => self.shown_default(body),
                None => format!("`{func}()`"),
            };
        }
        let container = serde_flag(&item.attrs, "default");
        if !serde_flag(&f.attrs, "default") && !container {
            return if generic(ty, "Option").is_some() {
                "none".into()
            } else {
                "required".into()
            };
        }
        if container
            && let Some(body) = self.src.defaults.get(&item.name)
            && let Some(v) = struct_literal_field(body, &item.name, &f.name)
        {
            return self.shown_default(&v);
        }
        if generic(ty, "Option").is_some() {
            return "none".into();
        }
        if generic(ty, "Vec").is_some() {
            return "`[]`".into();
        }
        if ty == "bool" {
            return "`false`".into();
        }
        if ty == "String" {
            return "`\"\"`".into();
        }
        if PRIMITIVES.contains(&ty) {
            return "`0`".into();
        }
        let (n, q) = named_types(ty).into_iter().next().unwrap_or_default();
        match self.resolve(&n, &item.file, &q) {
            Some(Item {
                body: Body::Enum(vs),
                ..
            }) => match vs.iter().find(|v| v.attrs.contains("#[default]")) {
                Some(v) => format!("`{}`", v.name),
                None => match self.src.defaults.get(&n).and_then(|b| impl_default_expr(b)) {
                    Some(e) => self.shown_default(&e),
                    None => "its default".into(),
                },
            },
            Some(i) if matches!(i.body, Body::Struct(_)) => "its fields' defaults".into(),
            _ => "its default".into(),
        }
    }

    /// A default as a file writes it, or "see meaning" for one computed by a function.
    pub(super) fn shown_default(&self, expr: &str) -> String {
        let v = self.ron(expr);
        if v == "none" {
            v
        } else if v.contains("()") || v.contains("::") {
            "see meaning".into()
        } else {
            format!("`{v}`")
        }
    }

    /// A Rust expression of a default as a file writes it: checked wrappers and paths dropped.
    pub(super) fn ron(&self, expr: &str) -> String {
        let mut s = expr.trim().to_string();
        loop {
            let before = s.clone();
            // `Name::new(v)` and `Name(v)` for checked and count types.
            for (name, items) in &self.src.items {
                let checked = items.iter().any(|i| {
                    matches!(i.body, Body::Checked(_) | Body::Alias(_))
                        || i.name == "Finite"
                        || i.name == "Positive"
                });
                if !checked {
                    continue;
                }
                for open in [format!("{name}::new("), format!("{name}(")] {
                    while let Some(k) = find_word(&s, &open) {
                        let rest = &s[k + open.len()..];
                        let Some(e) = closing(rest) else { break };
                        s = format!("{}{}{}", &s[..k], &rest[..e], &rest[e + 1..]);
                    }
                }
            }
            if s == before {
                break;
            }
        }
        // Paths: `SpectrumSpec::Aluminium` → `Aluminium`; a constant → its value.
        let words: Vec<String> = s
            .split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
            .filter(|w| w.contains("::"))
            .map(str::to_string)
            .collect();
        for w in words {
            let last = w.rsplit("::").next().unwrap_or(&w).to_string();
            let v = self.src.consts.get(&last).cloned().unwrap_or(last);
            s = s.replacen(&w, &v, 1);
        }
        for suffix in [".to_string()", ".into()", ".to_vec()"] {
            s = s.replace(suffix, "");
        }
        if let Some(k) = s.find(".into_iter()") {
            s.truncate(k);
        }
        // Bare constants, and numbers as a file writes them (`2_000_000` → `2000000`).
        let words: Vec<String> = s
            .split(|c: char| !(c.is_alphanumeric() || c == '_' || c == '.'))
            .map(str::to_string)
            .collect();
        for w in words {
            if let Some(v) = self.src.consts.get(&w) {
                s = s.replacen(&w, &self.value(v), 1);
            } else if w.starts_with(|c: char| c.is_ascii_digit()) && w.contains('_') {
                s = s.replacen(&w, &w.replace('_', ""), 1);
            }
        }
        match s.trim() {
            "None" => "none".to_string(),
            t => t.to_string(),
        }
    }

    /// Whether a field of `ty` is a bench variable, and the path components it adds.
    pub(super) fn variable(&self, ty: &str, from: &str, depth: usize) -> String {
        let ty = ty.trim();
        if depth > 8 {
            return "no".into();
        }
        if let Some(inner) = generic(ty, "Option") {
            let v = self.variable(inner, from, depth + 1);
            return if v == "no" {
                v
            } else {
                format!("{v}, when set")
            };
        }
        if let Some(inner) = generic(ty, "Vec") {
            let v = self.variable(inner, from, depth + 1);
            return if v == "no" {
                v
            } else {
                "yes: `.0`, `.1`, … (one per entry)".into()
            };
        }
        if ty.starts_with('(') {
            let n = split_top(&ty[1..ty.len() - 1]).len();
            let comps: Vec<String> = (0..n).map(|i| i.to_string()).collect();
            return format!("yes: `.{}`", comps.join("|"));
        }
        match ty {
            "String" | "PathBuf" | "bool" => return "no".into(),
            t if PRIMITIVES.contains(&t) => return "yes".into(),
            _ => {}
        }
        if ty.starts_with("Count<") || ty.starts_with("Whole<") {
            return "yes".into();
        }
        let (n, q) = named_types(ty).into_iter().next().unwrap_or_default();
        let Some(item) = self.resolve(&n, from, &q) else {
            return "no".into();
        };
        let item = match self.written(item) {
            Some(w) if matches!(w.body, Body::Struct(_) | Body::Enum(_)) => w,
            _ => item,
        };
        match &item.body {
            Body::Alias(t) => self.variable(t, &item.file, depth + 1),
            Body::Checked(_) => "yes".into(),
            Body::TupleStruct(ts) if ts.len() == 3 && item.name == "Mm3" => "yes: `.x|y|z`".into(),
            Body::TupleStruct(ts) if ts.len() == 1 && ts[0].starts_with("f64") => "yes".into(),
            Body::TupleStruct(_) if item.name == "TableNm" => "yes: `.I.0|1` (entry I)".into(),
            Body::Enum(vs) if vs.iter().all(|v| matches!(v.shape, Shape::Unit)) => "no".into(),
            Body::Struct(_) | Body::Enum(_) => "fields below".into(),
            _ => "no".into(),
        }
    }
}

/// `field: value` of a struct literal `Name { a: 1.0, b: 2.0 }` (or `Self { … }`) in `body`.
fn struct_literal_field(body: &str, name: &str, field: &str) -> Option<String> {
    let open = body
        .find(&format!("{name} {{"))
        .map(|k| k + name.len() + 1)
        .or_else(|| body.find("Self {").map(|k| k + 5))?;
    let inner = &body[open + 1..];
    let mut depth = 1;
    let mut end = inner.len();
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    end = i;
                    break;
                }
            }
            _ => {}
        }
    }
    let inner = &inner[..end];
    split_top(inner).into_iter().find_map(|kv| {
        let (k, v) = kv.split_once(':')?;
        (k.trim() == field).then(|| v.trim().to_string())
    })
}

/// The first `pat` in `s` not preceded by an identifier character.
fn find_word(s: &str, pat: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(k) = s[from..].find(pat) {
        let at = from + k;
        let prev = s[..at].chars().last();
        if !prev.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
            return Some(at);
        }
        from = at + pat.len();
    }
    None
}

/// The index of the `)` that closes an already opened parenthesis.
fn closing(s: &str) -> Option<usize> {
    let mut depth = 1;
    for (i, c) in s.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => {
                depth -= 1;
                if depth == 0 {
                    return Some(i);
                }
            }
            _ => {}
        }
    }
    None
}

/// The expression of `fn default() -> Self { EXPR }` in an `impl Default` body, a struct
/// variant written as a file writes it (`Random { seed: 1 }` → `Random(seed: 1)`).
fn impl_default_expr(body: &str) -> Option<String> {
    let start = body.find("-> Self {")? + "-> Self {".len();
    let inner = body[start..].trim().strip_suffix('}')?.trim();
    Some(match inner.split_once(" { ") {
        Some((head, rest)) if !head.contains(' ') => {
            format!("{head}({})", rest.trim_end_matches('}').trim())
        }
        _ => inner.to_string(),
    })
}
