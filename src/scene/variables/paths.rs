//! Field paths over a bench file written as a JSON value: walking a path to its leaf, the
//! numeric leaves a bench holds, and the error for a path that names nothing.

use serde_json::Value;

use super::{SECTIONS, TOP_FIELDS, list};
use crate::error::{Error, Result};
use crate::scene::bench::BenchFile;

/// Numeric leaves under `v`, named from `base` (variant wrappers passed through, `name` and
/// strings skipped).
pub(super) fn leaves(v: &Value, base: &str, out: &mut Vec<String>) {
    match v {
        Value::Number(_) => out.push(base.to_string()),
        Value::Array(a) => {
            let names: &[&str] = if a.len() == 3 { &["x", "y", "z"] } else { &[] };
            for (i, x) in a.iter().enumerate() {
                let c = names
                    .get(i)
                    .map_or_else(|| i.to_string(), |s| s.to_string());
                leaves(x, &format!("{base}.{c}"), out);
            }
        }
        Value::Object(m) => {
            if let Some(inner) = variant_inner(v) {
                leaves(inner, base, out);
                return;
            }
            for (k, x) in m {
                leaves(x, &format!("{base}.{k}"), out);
            }
        }
        _ => {}
    }
}

pub(super) fn to_value(file: &BenchFile) -> Result<Value> {
    serde_json::to_value(file)
        .map_err(|e| Error::Numerical(format!("a bench could not be represented: {e}")))
}

pub(super) fn clean_serde(e: &serde_json::Error) -> String {
    let s = e.to_string();
    // serde_json appends "at line 0 column 0" for values: meaningless here.
    match s.find(" at line ") {
        Some(k) => s[..k].to_string(),
        None => s,
    }
}

/// An externally tagged enum variant `{"Name": inner}`: its inner value.
pub(super) fn variant_inner(v: &Value) -> Option<&Value> {
    match v {
        Value::Object(m) if m.len() == 1 => {
            let (k, inner) = m.iter().next()?;
            k.chars()
                .next()
                .is_some_and(|c| c.is_ascii_uppercase())
                .then_some(inner)
        }
        _ => None,
    }
}

pub(super) fn variant_inner_mut(v: &mut Value) -> Option<&mut Value> {
    let is_variant = variant_inner(v).is_some();
    match v {
        Value::Object(m) if is_variant => m.values_mut().next(),
        _ => None,
    }
}

/// An element's name and its fields.
pub(super) fn element_parts(el: &Value) -> Option<(String, &Value)> {
    let inner = variant_inner(el)?;
    let name = inner.get("name")?.as_str()?.to_string();
    Some((name, inner))
}

/// Splits a path into the part it addresses (a section, `detectors.plus|minus` or an element
/// name) and the rest.
pub(super) fn split_target(path: &str) -> (String, Vec<&str>) {
    let segs: Vec<&str> = path.split('.').collect();
    if segs.len() >= 2 && segs[0] == "detectors" {
        return (format!("detectors.{}", segs[1]), segs[2..].to_vec());
    }
    (segs[0].to_string(), segs[1..].to_vec())
}

pub(super) fn walk_ref<'v>(root: &'v Value, path: &str) -> std::result::Result<&'v Value, String> {
    let (target, rest) = split_target(path);
    let mut cur = find_target(root, &target)?;
    for seg in rest {
        if let Some(inner) = variant_inner(cur) {
            cur = inner;
        }
        cur = step(cur, seg)?;
    }
    if let Some(inner) = variant_inner(cur) {
        cur = inner;
    }
    Ok(cur)
}

pub(super) fn walk_mut<'v>(
    root: &'v mut Value,
    path: &str,
) -> std::result::Result<&'v mut Value, String> {
    // Resolve with the immutable walk first (good messages), then follow the same steps.
    walk_ref(root, path)?;
    let (target, rest) = split_target(path);
    let mut cur = find_target_mut(root, &target).ok_or("unknown part")?;
    for seg in rest {
        if variant_inner(cur).is_some() {
            cur = variant_inner_mut(cur).ok_or("unreachable")?;
        }
        let idx = index_of(cur, seg)?;
        cur = match (cur, idx) {
            (Value::Object(m), Key::Field) => m.get_mut(seg).ok_or("unknown field")?,
            (Value::Array(a), Key::Index(i)) => a.get_mut(i).ok_or("no such component")?,
            _ => return Err("unreachable".into()),
        };
    }
    if variant_inner(cur).is_some() {
        cur = variant_inner_mut(cur).ok_or("unreachable")?;
    }
    Ok(cur)
}

pub(super) enum Key {
    Field,
    Index(usize),
}

pub(super) fn index_of(cur: &Value, seg: &str) -> std::result::Result<Key, String> {
    match cur {
        Value::Object(m) => {
            if m.contains_key(seg) {
                Ok(Key::Field)
            } else {
                Err(format!("has no field `{seg}`"))
            }
        }
        Value::Array(a) => {
            let i = match seg {
                "x" => 0,
                "y" => 1,
                "z" => 2,
                s => s
                    .parse::<usize>()
                    .map_err(|_| format!("`{seg}` is not a component (x, y, z or an index)"))?,
            };
            if i < a.len() {
                Ok(Key::Index(i))
            } else {
                Err(format!(
                    "component `{seg}` is out of range: the value has {} components",
                    a.len()
                ))
            }
        }
        Value::Null => Err(format!(
            "reaches a field that is not set in this bench before `{seg}`: write it in the \
             bench file first"
        )),
        _ => Err(format!("reaches a plain value before `{seg}`")),
    }
}

pub(super) fn step<'v>(cur: &'v Value, seg: &str) -> std::result::Result<&'v Value, String> {
    match (cur, index_of(cur, seg)?) {
        (Value::Object(m), Key::Field) => m.get(seg).ok_or_else(|| "unknown field".into()),
        (Value::Array(a), Key::Index(i)) => a.get(i).ok_or_else(|| "no such component".into()),
        _ => Err("unreachable".into()),
    }
}

pub(super) fn find_target<'v>(
    root: &'v Value,
    target: &str,
) -> std::result::Result<&'v Value, String> {
    if let Some(rest) = target.strip_prefix("detectors.") {
        return root
            .get("detectors")
            .and_then(|d| d.get(rest))
            .ok_or_else(|| format!("`{target}`: the detectors are `plus` and `minus`"));
    }
    if SECTIONS.contains(&target) || TOP_FIELDS.contains(&target) {
        return match root.get(target) {
            Some(Value::Null) | None => Err(format!("this bench has no `{target}` section")),
            Some(v) => Ok(v),
        };
    }
    if let Some(Value::Array(els)) = root.get("elements") {
        for el in els {
            if let Some((name, inner)) = element_parts(el)
                && name == target
            {
                return Ok(inner);
            }
        }
    }
    Err(format!("no element or section named `{target}`"))
}

pub(super) fn find_target_mut<'v>(root: &'v mut Value, target: &str) -> Option<&'v mut Value> {
    if let Some(rest) = target.strip_prefix("detectors.") {
        return root.get_mut("detectors")?.get_mut(rest);
    }
    if SECTIONS.contains(&target) || TOP_FIELDS.contains(&target) {
        return root.get_mut(target);
    }
    let Some(Value::Array(els)) = root.get_mut("elements") else {
        return None;
    };
    els.iter_mut()
        .filter_map(variant_inner_mut)
        .find(|inner| inner.get("name").and_then(Value::as_str) == Some(target))
}

/// An input error for a bad path: the reason and the valid paths nearest to it.
pub(super) fn bad_path(file: &BenchFile, path: &str, why: String) -> Error {
    let all = list(file);
    let (target, _) = split_target(path);
    let mut near: Vec<&String> = all
        .iter()
        .filter(|p| p.starts_with(&format!("{target}.")) || p.as_str() == target)
        .collect();
    let hint = if near.is_empty() {
        let mut parts: Vec<String> = SECTIONS
            .iter()
            .filter(|s| **s != "detectors")
            .map(|s| s.to_string())
            .collect();
        parts.extend(["detectors.plus".to_string(), "detectors.minus".to_string()]);
        if let Ok(Value::Array(els)) = to_value(file).map(|v| v["elements"].clone()) {
            parts.extend(els.iter().filter_map(|e| element_parts(e).map(|p| p.0)));
        }
        format!("the parts of this bench are {}", parts.join(", "))
    } else {
        near.sort_by_key(|p| distance(p, path));
        near.truncate(12);
        format!(
            "valid paths near it: {}",
            near.iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    Error::field(path, format!("bench variable `{path}` {why}; {hint}"))
}

/// Levenshtein distance, for ordering suggestions.
pub(super) fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != *cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}
