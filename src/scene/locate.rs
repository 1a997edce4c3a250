//! The field locator of every input file: a scanner of RON text (comments and strings
//! skipped) that finds where a field is written, so that an error found after reading (a value
//! that conflicts with another, a name that is unknown) carries the line and column of that
//! field. Bench, experiment, tolerance and dataset files and the run and electronics sections
//! all locate their errors here.
//!
//! Two ways of naming a field: by structure from the top level ([`Locator`]: nested struct
//! fields, a named entry of a list) or by the full path that [`path_at`] writes
//! (`cases[1].arms.b_minus`, found by [`find_path`]); plus the looser lookups of files whose
//! fields are named alone ([`first_key`], [`key_after`], [`string_literal`]).

use crate::error::Error;

/// Gives `e` the line and column of byte offset `pos` of `text`, when there is one.
pub(crate) fn at(e: Error, text: &str, pos: Option<usize>) -> Error {
    match pos {
        Some(p) => {
            let (line, col) = line_col(text, p);
            e.at_line(line, col)
        }
        None => e,
    }
}

/// Offset of the first `field:` of the text at any depth (for files whose fields are named
/// alone, without their path).
pub(crate) fn first_key(text: &str, field: &str) -> Option<usize> {
    keys(text)
        .into_iter()
        .find(|&(_, k)| k == field)
        .map(|(p, _)| p)
}

/// Offset of the first `field:` after the first `section:`, or of `section:` itself when the
/// field is not written after it; None without the section.
pub(crate) fn key_after(text: &str, section: &str, field: &str) -> Option<usize> {
    let keys = keys(text);
    let (start, _) = *keys.iter().find(|&&(_, k)| k == section)?;
    keys.iter()
        .find(|&&(p, k)| p > start && k == field)
        .map_or(Some(start), |&(p, _)| Some(p))
}

/// Offset of the opening quote of the first string literal whose contents are `value`
/// (outside comments).
pub(crate) fn string_literal(text: &str, value: &str) -> Option<usize> {
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if let Some(next) = skip_trivia(b, i) {
            if b[i] == b'"' && text.get(i + 1..next - 1) == Some(value) {
                return Some(i);
            }
            i = next;
            continue;
        }
        i += 1;
    }
    None
}

/// Finds fields in RON text by structure (comments and strings skipped) to give errors found
/// after deserialisation a line and column.
pub(crate) struct Locator<'a> {
    pub(crate) text: &'a str,
}

impl<'a> Locator<'a> {
    /// Byte range of the contents of the outermost struct.
    pub(crate) fn top(&self) -> Option<(usize, usize)> {
        let b = self.text.as_bytes();
        let mut i = 0;
        while i < b.len() {
            if let Some(next) = skip_trivia(b, i) {
                i = next;
                continue;
            }
            if b[i] == b'#' {
                // #![enable(...)] attribute
                while i < b.len() && b[i] != b']' {
                    i += 1;
                }
                i += 1;
                continue;
            }
            if b[i] == b'(' {
                let end = matching(b, i)?;
                return Some((i + 1, end));
            }
            i += 1;
        }
        None
    }

    /// The field `name` at depth 0 within `range`: (position of the name, value range).
    pub(crate) fn field(
        &self,
        range: (usize, usize),
        name: &str,
    ) -> Option<(usize, (usize, usize))> {
        let b = self.text.as_bytes();
        let mut i = range.0;
        let mut depth = 0i32;
        while i < range.1 {
            if let Some(next) = skip_trivia(b, i) {
                i = next;
                continue;
            }
            match b[i] {
                b'(' | b'[' | b'{' => depth += 1,
                b')' | b']' | b'}' => depth -= 1,
                c if depth == 0 && (c.is_ascii_alphabetic() || c == b'_') => {
                    let start = i;
                    while i < range.1 && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                        i += 1;
                    }
                    let mut j = i;
                    while j < range.1
                        && (b[j] == b' ' || b[j] == b'\t' || b[j] == b'\n' || b[j] == b'\r')
                    {
                        j += 1;
                    }
                    if &self.text[start..i] == name && j < range.1 && b[j] == b':' {
                        let vstart = j + 1;
                        let vend = value_end(b, vstart, range.1);
                        return Some((start, (vstart, vend)));
                    }
                    continue;
                }
                _ => {}
            }
            i += 1;
        }
        None
    }

    /// The contents of the first parenthesised group in a value range.
    pub(crate) fn inner(&self, range: (usize, usize)) -> Option<(usize, usize)> {
        let b = self.text.as_bytes();
        let mut i = range.0;
        while i < range.1 {
            if let Some(next) = skip_trivia(b, i) {
                i = next;
                continue;
            }
            if b[i] == b'(' {
                let end = matching(b, i)?;
                return Some((i + 1, end));
            }
            i += 1;
        }
        None
    }

    /// The contents of the entry of the top-level list `list` whose `name` is `name`.
    pub(crate) fn named(&self, list: &str, name: &str) -> Option<(usize, usize)> {
        let top = self.top()?;
        let (_, list) = self.field(top, list)?;
        let b = self.text.as_bytes();
        let mut i = list.0;
        while i < list.1 {
            if let Some(next) = skip_trivia(b, i) {
                i = next;
                continue;
            }
            if b[i] == b'(' {
                let end = matching(b, i)?;
                let inner = (i + 1, end);
                if let Some((_, v)) = self.field(inner, "name")
                    && self.text[v.0..v.1].trim().trim_matches('"') == name
                {
                    return Some(inner);
                }
                i = end + 1;
                continue;
            }
            i += 1;
        }
        None
    }

    /// Position of a field along a path of nested struct fields from the top level.
    pub(crate) fn path(&self, path: &[&str]) -> Option<usize> {
        let mut range = self.top()?;
        let mut pos = None;
        for (k, name) in path.iter().enumerate() {
            let (p, v) = self.field(range, name)?;
            pos = Some(p);
            if k + 1 < path.len() {
                range = self.inner(v)?;
            }
        }
        pos
    }

    /// Position of `field` in the entry of the top-level list `list` named `name` (the entry
    /// itself when it lacks the field).
    pub(crate) fn entry_field(&self, list: &str, name: &str, field: &str) -> Option<usize> {
        let range = self.named(list, name)?;
        self.field(range, field).map(|(p, _)| p).or(Some(range.0))
    }

    /// 1-based line and column of a byte offset of the text.
    pub(crate) fn line_col(&self, pos: usize) -> (usize, usize) {
        line_col(self.text, pos)
    }
}

/// Skips a comment or string starting at i, returning the index after it.
pub(crate) fn skip_trivia(b: &[u8], i: usize) -> Option<usize> {
    if b[i] == b'/' && i + 1 < b.len() && b[i + 1] == b'/' {
        let mut j = i;
        while j < b.len() && b[j] != b'\n' {
            j += 1;
        }
        return Some(j);
    }
    if b[i] == b'/' && i + 1 < b.len() && b[i + 1] == b'*' {
        let mut depth = 0;
        let mut j = i;
        while j + 1 < b.len() {
            if b[j] == b'/' && b[j + 1] == b'*' {
                depth += 1;
                j += 2;
            } else if b[j] == b'*' && b[j + 1] == b'/' {
                depth -= 1;
                j += 2;
                if depth == 0 {
                    return Some(j);
                }
            } else {
                j += 1;
            }
        }
        return Some(b.len());
    }
    if b[i] == b'"' {
        let mut j = i + 1;
        while j < b.len() && b[j] != b'"' {
            if b[j] == b'\\' {
                j += 1;
            }
            j += 1;
        }
        return Some(j + 1);
    }
    None
}

fn matching(b: &[u8], open: usize) -> Option<usize> {
    let mut depth = 0i32;
    let mut i = open;
    while i < b.len() {
        if let Some(next) = skip_trivia(b, i) {
            i = next;
            continue;
        }
        match b[i] {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => {
                depth -= 1;
                if depth == 0 {
                    return Some(i);
                }
            }
            _ => {}
        }
        i += 1;
    }
    None
}

fn value_end(b: &[u8], start: usize, end: usize) -> usize {
    let mut depth = 0i32;
    let mut i = start;
    while i < end {
        if let Some(next) = skip_trivia(b, i) {
            i = next;
            continue;
        }
        match b[i] {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => depth -= 1,
            b',' if depth == 0 => return i,
            _ => {}
        }
        i += 1;
    }
    end
}

/// Byte offset of a 1-based line and column.
pub(crate) fn offset_of(text: &str, line: usize, col: usize) -> usize {
    let mut offset = 0;
    for (i, l) in text.split_inclusive('\n').enumerate() {
        if i + 1 == line {
            return offset
                + l.char_indices()
                    .nth(col.saturating_sub(1))
                    .map_or(l.len(), |(b, _)| b);
        }
        offset += l.len();
    }
    text.len()
}

/// 1-based line and column of a byte offset.
pub(crate) fn line_col(text: &str, pos: usize) -> (usize, usize) {
    let mut pos = pos.min(text.len());
    while !text.is_char_boundary(pos) {
        pos -= 1;
    }
    let before = &text[..pos];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Offset of the last `key:` (as a whole word, outside comments and strings) before `pos`.
pub(crate) fn last_key_before(text: &str, key: &str, pos: usize) -> Option<usize> {
    keys(text)
        .into_iter()
        .filter(|&(p, k)| k == key && p < pos)
        .map(|(p, _)| p)
        .next_back()
}

/// Every `identifier:` of the text outside comments and strings: (offset, identifier).
pub(crate) fn keys(text: &str) -> Vec<(usize, &str)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if let Some(next) = skip_trivia(b, i) {
            i = next;
            continue;
        }
        if b[i].is_ascii_alphabetic() || b[i] == b'_' {
            let start = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            let mut j = i;
            while j < b.len() && b[j].is_ascii_whitespace() {
                j += 1;
            }
            if j < b.len() && b[j] == b':' && b.get(j + 1) != Some(&b':') {
                out.push((start, &text[start..i]));
            }
            continue;
        }
        i += 1;
    }
    out
}

/// The full path (`cases[1].arms.b_minus`) of the field whose value holds byte offset `pos`:
/// struct fields joined by `.`, list items by their index. None outside every field.
pub fn path_at(text: &str, pos: usize) -> Option<String> {
    enum Frame {
        Struct(Option<String>),
        List(usize),
    }
    let b = text.as_bytes();
    let end = pos.min(b.len());
    let mut stack: Vec<Frame> = Vec::new();
    let mut i = 0;
    while i < end {
        if let Some(next) = skip_trivia(b, i) {
            i = next;
            continue;
        }
        match b[i] {
            b'(' | b'{' => stack.push(Frame::Struct(None)),
            b'[' => stack.push(Frame::List(0)),
            b')' | b']' | b'}' => {
                stack.pop();
            }
            b',' => match stack.last_mut() {
                Some(Frame::List(n)) => *n += 1,
                Some(Frame::Struct(f)) => *f = None,
                None => {}
            },
            c if c.is_ascii_alphabetic() || c == b'_' => {
                let start = i;
                while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                    i += 1;
                }
                let mut j = i;
                while j < b.len() && b[j].is_ascii_whitespace() {
                    j += 1;
                }
                if j < b.len()
                    && b[j] == b':'
                    && b.get(j + 1) != Some(&b':')
                    && let Some(Frame::Struct(f)) = stack.last_mut()
                {
                    *f = Some(text[start..i].to_string());
                }
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    let mut path = String::new();
    for f in &stack {
        match f {
            Frame::Struct(Some(name)) => {
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(name);
            }
            Frame::Struct(None) => {}
            Frame::List(n) => path.push_str(&format!("[{n}]")),
        }
    }
    (!path.is_empty()).then_some(path)
}

/// Offset of the field at a full path (`cases[1].label`, as [`path_at`] writes it): the
/// first `key:` whose path is that one. None when the field is not written in the text.
pub fn find_path(text: &str, path: &str) -> Option<usize> {
    let last = path.rsplit('.').next().unwrap_or(path);
    let last = last.split('[').next().unwrap_or(last);
    keys(text)
        .into_iter()
        .filter(|&(_, k)| k == last)
        .map(|(p, k)| (p, p + k.len() + 1))
        .find(|&(_, after)| {
            path_at(text, after + 1).is_some_and(|found| {
                found == path || found.strip_prefix(path).is_some_and(|r| r.starts_with('['))
            })
        })
        .map(|(p, _)| p)
}

/// The name of the field whose value contains the position (1-based line and column): the last
/// `identifier:` at or before it. Used to name the field of a value that failed validation.
pub fn field_before(text: &str, line: usize, col: usize) -> Option<String> {
    let mut offset = 0;
    for (i, l) in text.split_inclusive('\n').enumerate() {
        if i + 1 == line {
            offset += l
                .char_indices()
                .nth(col.saturating_sub(1))
                .map_or(l.len(), |(b, _)| b);
            break;
        }
        offset += l.len();
    }
    let before = &text[..offset.min(text.len())];
    let bytes = before.as_bytes();
    let mut i = bytes.len();
    while i > 0 {
        i -= 1;
        if bytes[i] == b':'
            && !(i + 1 < bytes.len() && bytes[i + 1] == b':')
            && !(i > 0 && bytes[i - 1] == b':')
        {
            let mut j = i;
            while j > 0 && bytes[j - 1] == b' ' {
                j -= 1;
            }
            let end = j;
            while j > 0 && (bytes[j - 1].is_ascii_alphanumeric() || bytes[j - 1] == b'_') {
                j -= 1;
            }
            if j < end {
                return Some(before[j..end].to_string());
            }
        }
    }
    None
}
