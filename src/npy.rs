//! Parsing NumPy `.npy` bytes (format 1.0/2.0/3.0, little-endian; C-order and Fortran-order
//! arrays, the latter reordered to C order). Pure and file-free, so that every layer can read
//! arrays: `objects` (object images as `.npy`), `scene` and `report` (which adds reading files
//! under a size cap and writing; `report::npy`).

/// The element data of an array read from a file.
#[derive(Debug, Clone, PartialEq)]
pub enum NpyData {
    F64(Vec<f64>),
    F32(Vec<f32>),
    U8(Vec<u8>),
    I64(Vec<i64>),
    Bool(Vec<u8>),
}

#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    pub shape: Vec<usize>,
    pub data: NpyData,
}

impl NpyArray {
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The elements as f64 (exact for every supported type except huge i64 values).
    pub fn to_f64(&self) -> Vec<f64> {
        match &self.data {
            NpyData::F64(v) => v.clone(),
            NpyData::F32(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::U8(v) | NpyData::Bool(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::I64(v) => v.iter().map(|&x| x as f64).collect(),
        }
    }

    /// The element type as NumPy spells it.
    pub fn dtype(&self) -> &'static str {
        match self.data {
            NpyData::F64(_) => "<f8",
            NpyData::F32(_) => "<f4",
            NpyData::U8(_) => "|u1",
            NpyData::I64(_) => "<i8",
            NpyData::Bool(_) => "|b1",
        }
    }
}

/// The header of a `.npy` file: the element type, the order and the shape, and where the data
/// start.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    pub descr: String,
    pub fortran_order: bool,
    pub shape: Vec<usize>,
    /// The byte offset of the data.
    pub data_start: usize,
}

impl Header {
    /// The number of elements (None when the product overflows).
    pub fn count(&self) -> Option<usize> {
        self.shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d))
    }

    /// The bytes of one element of a supported type (None for any other).
    pub fn item_bytes(&self) -> Option<usize> {
        match self.descr.as_str() {
            "<f8" | "f8" | "float64" | "<i8" => Some(8),
            "<f4" => Some(4),
            "|u1" | "<u1" | "u1" | "|b1" => Some(1),
            _ => None,
        }
    }
}

/// Reads the header of `.npy` bytes (at least its first 10 or 12 bytes and the header text;
/// the data need not be there).
pub fn header(bytes: &[u8]) -> std::result::Result<Header, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("missing the \\x93NUMPY magic".into());
    }
    let major = bytes[6];
    let (hlen, hstart) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err("truncated header".into());
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => return Err(format!("unsupported format version {v}")),
    };
    let header = bytes.get(hstart..hstart + hlen).ok_or("truncated header")?;
    // Format 3.0 allows UTF-8; 1.0 and 2.0 are latin-1, of which the keys and values here are
    // the ASCII part.
    let text = std::str::from_utf8(header).map_err(|_| "header is not text")?;
    let (descr, fortran_order, shape) = literal::dictionary(text)?;
    Ok(Header {
        descr,
        fortran_order,
        shape,
        data_start: hstart + hlen,
    })
}

/// Parses the bytes of a `.npy` file.
pub fn parse(bytes: &[u8]) -> std::result::Result<NpyArray, String> {
    let h = header(bytes)?;
    let count = h.count().ok_or("shape too large")?;
    let body = &bytes[h.data_start..];
    let need = |size: usize| -> std::result::Result<&[u8], String> {
        let n = count.checked_mul(size).ok_or("shape too large")?;
        body.get(..n).ok_or_else(|| {
            format!(
                "data truncated: {} bytes for {} elements",
                body.len(),
                count
            )
        })
    };
    let (shape, fortran) = (h.shape.as_slice(), h.fortran_order);
    let data = match h.descr.as_str() {
        "<f8" | "f8" | "float64" => {
            let raw = need(8)?;
            NpyData::F64(in_c_order(shape, fortran, |i| {
                f64::from_le_bytes(raw[8 * i..8 * i + 8].try_into().unwrap())
            }))
        }
        "<f4" => {
            let raw = need(4)?;
            NpyData::F32(in_c_order(shape, fortran, |i| {
                f32::from_le_bytes(raw[4 * i..4 * i + 4].try_into().unwrap())
            }))
        }
        "|u1" | "<u1" | "u1" => {
            let raw = need(1)?;
            NpyData::U8(in_c_order(shape, fortran, |i| raw[i]))
        }
        "|b1" => {
            let raw = need(1)?;
            NpyData::Bool(in_c_order(shape, fortran, |i| raw[i]))
        }
        "<i8" => {
            let raw = need(8)?;
            NpyData::I64(in_c_order(shape, fortran, |i| {
                i64::from_le_bytes(raw[8 * i..8 * i + 8].try_into().unwrap())
            }))
        }
        other => {
            return Err(format!(
                "element type '{other}' is not supported (use float64, float32, uint8, bool or int64)"
            ));
        }
    };
    Ok(NpyArray {
        shape: h.shape,
        data,
    })
}

/// The elements of an array of `shape` in C (row-major) order, `get(i)` reading the element at
/// storage position i: position i itself in C order, or, in Fortran (column-major) order, the
/// position of the same multi-index there. One pass and one allocation, the array's own: no
/// index table (which took 8 bytes per element, eight times a uint8 pattern array).
fn in_c_order<T>(shape: &[usize], fortran: bool, get: impl Fn(usize) -> T) -> Vec<T> {
    let count: usize = shape.iter().product();
    let mut out = Vec::with_capacity(count);
    if !fortran || shape.len() < 2 || count == 0 {
        let mut i = 0;
        while i < count {
            out.push(get(i));
            i += 1;
        }
        return out;
    }
    // Fortran strides: the first index varies fastest.
    let mut strides = vec![1usize; shape.len()];
    for k in 1..shape.len() {
        strides[k] = strides[k - 1] * shape[k - 1];
    }
    let last = shape.len() - 1;
    let mut idx = vec![0usize; shape.len()];
    let mut pos = 0usize;
    for _ in 0..count {
        out.push(get(pos));
        // Advance the C-order multi-index (the last index fastest) and its Fortran position.
        let mut k = last;
        loop {
            idx[k] += 1;
            pos += strides[k];
            if idx[k] < shape[k] || k == 0 {
                break;
            }
            pos -= strides[k] * shape[k];
            idx[k] = 0;
            k -= 1;
        }
    }
    out
}

/// The header's text: a Python literal dictionary, as the format defines it ("a Python literal
/// expression of a dictionary", read by NumPy with `ast.literal_eval`), with exactly the keys
/// `descr` (a string), `fortran_order` (`True` or `False`) and `shape` (a tuple of whole
/// numbers). Strings in single or double quotes, any spaces, trailing commas; anything else,
/// such as `true` or `'yes'` for the order, is refused by name rather than guessed.
mod literal {
    type Parsed<T> = std::result::Result<T, String>;

    struct Reader<'a> {
        text: &'a str,
        at: usize,
    }

    impl Reader<'_> {
        fn skip_space(&mut self) {
            let rest = &self.text[self.at..];
            self.at += rest.len() - rest.trim_start().len();
        }

        fn peek(&self) -> Option<char> {
            self.text[self.at..].chars().next()
        }

        fn eat(&mut self, c: char) -> bool {
            self.skip_space();
            if self.peek() == Some(c) {
                self.at += c.len_utf8();
                true
            } else {
                false
            }
        }

        fn expect(&mut self, c: char, context: &str) -> Parsed<()> {
            if self.eat(c) {
                Ok(())
            } else {
                Err(format!(
                    "the header's dictionary needs `{c}` {context}, found {}",
                    self.found()
                ))
            }
        }

        /// The token at the reading position, for messages: a name or number, a quoted
        /// string, or else the next few characters.
        fn found(&self) -> String {
            let rest = self.text[self.at..].trim_end();
            let token: String = match rest.chars().next() {
                None => return "the end of the header".into(),
                Some(c) if c.is_ascii_alphanumeric() || c == '_' || c == '-' => rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '-')
                    .collect(),
                Some(q @ ('\'' | '"')) => match rest[1..].find(q) {
                    Some(end) => rest[..end + 2].to_string(),
                    None => rest.to_string(),
                },
                Some(_) => rest.chars().take(16).collect(),
            };
            format!("`{token}`")
        }

        /// A string literal in single or double quotes, without escapes.
        fn string(&mut self, what: &str) -> Parsed<String> {
            self.skip_space();
            let quote = match self.peek() {
                Some(q @ ('\'' | '"')) => q,
                _ => {
                    return Err(format!(
                        "{what} must be a quoted string, found {}",
                        self.found()
                    ));
                }
            };
            let body = &self.text[self.at + 1..];
            let end = body
                .find(quote)
                .ok_or_else(|| format!("{what}: the string is not closed"))?;
            let s = &body[..end];
            if s.contains('\\') {
                return Err(format!(
                    "{what}: escapes in strings are not supported, got {s:?}"
                ));
            }
            self.at += end + 2;
            Ok(s.to_string())
        }

        /// A name such as `True`: the letters, digits and underscores at the reading position.
        fn word(&mut self) -> &str {
            self.skip_space();
            let rest = &self.text[self.at..];
            let n = rest
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            self.at += n;
            &rest[..n]
        }

        fn boolean(&mut self) -> Parsed<bool> {
            self.skip_space();
            let at = self.at;
            match self.word() {
                "True" => Ok(true),
                "False" => Ok(false),
                _ => {
                    self.at = at;
                    Err(format!(
                        "`fortran_order` must be True or False (Python literals), found {}",
                        self.found()
                    ))
                }
            }
        }

        fn shape(&mut self) -> Parsed<Vec<usize>> {
            let bad = |r: &Reader| {
                format!(
                    "`shape` must be a tuple of whole numbers such as (3,) or (2, 3), found {}",
                    r.found()
                )
            };
            if !self.eat('(') {
                return Err(bad(self));
            }
            let mut dims = Vec::new();
            let mut comma = false;
            loop {
                if self.eat(')') {
                    break;
                }
                if !dims.is_empty() && !comma {
                    return Err(bad(self));
                }
                self.skip_space();
                let at = self.at;
                let digits = self.word();
                if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                    self.at = at;
                    return Err(bad(self));
                }
                let d = digits
                    .parse::<usize>()
                    .map_err(|_| format!("`shape`: the dimension {digits} is too large"))?;
                dims.push(d);
                comma = self.eat(',');
            }
            // `(3)` is the number 3 in Python, not a tuple.
            if dims.len() == 1 && !comma {
                return Err(
                    "`shape` (n) is a number, not a tuple: a 1-D shape is written (n,)".to_string(),
                );
            }
            Ok(dims)
        }
    }

    /// (descr, fortran_order, shape) of the header text.
    pub(super) fn dictionary(text: &str) -> Parsed<(String, bool, Vec<usize>)> {
        let mut r = Reader { text, at: 0 };
        r.expect('{', "at its start")?;
        let (mut descr, mut fortran, mut shape) = (None, None, None);
        loop {
            if r.eat('}') {
                break;
            }
            let key = r.string("a key of the header's dictionary")?;
            r.expect(':', &format!("after the key '{key}'"))?;
            let twice = |k: &str| format!("the header names `{k}` twice");
            match key.as_str() {
                "descr" => {
                    r.skip_space();
                    if r.peek() == Some('[') {
                        return Err(
                            "structured element types (a list as `descr`) are not supported".into(),
                        );
                    }
                    let v = r.string("`descr`")?;
                    if descr.replace(v).is_some() {
                        return Err(twice("descr"));
                    }
                }
                "fortran_order" => {
                    let v = r.boolean()?;
                    if fortran.replace(v).is_some() {
                        return Err(twice("fortran_order"));
                    }
                }
                "shape" => {
                    let v = r.shape()?;
                    if shape.replace(v).is_some() {
                        return Err(twice("shape"));
                    }
                }
                other => {
                    return Err(format!(
                        "the header has a key '{other}'; a .npy header holds exactly 'descr', \
                         'fortran_order' and 'shape'"
                    ));
                }
            }
            if !r.eat(',') {
                r.expect('}', "after a value (or `,` before the next key)")?;
                break;
            }
        }
        r.skip_space();
        if r.at < text.len() {
            return Err(format!(
                "the header holds {} after its dictionary",
                r.found()
            ));
        }
        let missing = |k: &str| format!("header has no '{k}'");
        Ok((
            descr.ok_or_else(|| missing("descr"))?,
            fortran.ok_or_else(|| missing("fortran_order"))?,
            shape.ok_or_else(|| missing("shape"))?,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A version 1.0 file with header text `dict` and the data `body`.
    fn file(dict: &str, body: &[u8]) -> Vec<u8> {
        let mut h = dict.to_string();
        let total = 10 + h.len() + 1;
        h.push_str(&" ".repeat((64 - total % 64) % 64));
        h.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend_from_slice(&(h.len() as u16).to_le_bytes());
        out.extend_from_slice(h.as_bytes());
        out.extend_from_slice(body);
        out
    }

    /// numpy.asfortranarray(np.arange(6, dtype=np.uint8).reshape(2, 3)) stores 0 3 1 4 2 5.
    const FORTRAN_2X3: [u8; 6] = [0, 3, 1, 4, 2, 5];

    #[test]
    fn headers_are_read_as_python_literals() {
        let c_order = [
            "{'descr': '|u1', 'fortran_order': False, 'shape': (2, 3), }",
            // Double quotes (valid Python; refused before).
            "{\"descr\": \"|u1\", \"fortran_order\": False, \"shape\": (2, 3)}",
            // Spaces anywhere, no trailing comma in the tuple, keys in another order.
            "{ 'shape' : ( 2 , 3 ) ,'fortran_order':False,'descr':'|u1' , }",
        ];
        for dict in c_order {
            let a =
                parse(&file(dict, &[0, 1, 2, 3, 4, 5])).unwrap_or_else(|e| panic!("{dict}: {e}"));
            assert_eq!(a.shape, [2, 3], "{dict}");
            assert_eq!(a.data, NpyData::U8(vec![0, 1, 2, 3, 4, 5]), "{dict}");
        }
        for dict in [
            "{'descr': '|u1', 'fortran_order': True, 'shape': (2, 3), }",
            "{\"descr\": \"|u1\", \"fortran_order\": True, \"shape\": (2, 3,)}",
        ] {
            let a = parse(&file(dict, &FORTRAN_2X3)).unwrap();
            assert_eq!(a.data, NpyData::U8(vec![0, 1, 2, 3, 4, 5]), "{dict}");
        }
        // A 1-D shape, a 0-D one, float64 in Fortran order.
        let a = parse(&file(
            "{'descr': '<f8', 'fortran_order': True, 'shape': (2,)}",
            &[0; 16],
        ));
        assert_eq!(a.unwrap().shape, [2]);
        let a = parse(&file(
            "{'descr': '<f8', 'fortran_order': False, 'shape': ()}",
            &[0; 8],
        ));
        assert_eq!(a.unwrap().shape, Vec::<usize>::new());
        let f: Vec<u8> = [0.0f64, 3.0, 1.0, 4.0, 2.0, 5.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let a = parse(&file(
            "{'descr': '<f8', 'fortran_order': True, 'shape': (2, 3)}",
            &f,
        ));
        assert_eq!(a.unwrap().to_f64(), [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
    }

    /// What is not a Python literal dictionary with the three keys is refused, naming what is
    /// wrong: never read as C order by a guess.
    #[test]
    fn anything_else_is_refused_by_name() {
        let body = FORTRAN_2X3;
        for (dict, words) in [
            (
                "{'descr': '|u1', 'fortran_order': true, 'shape': (2, 3)}",
                "`true`",
            ),
            (
                "{'descr': '|u1', 'fortran_order': 'yes', 'shape': (2, 3)}",
                "'yes'",
            ),
            (
                "{'descr': '|u1', 'fortran_order': 1, 'shape': (2, 3)}",
                "True or False",
            ),
            (
                "{'descr': '|u1', 'fortran_order': Truely, 'shape': (2, 3)}",
                "Truely",
            ),
            ("{'descr': '|u1', 'shape': (2, 3)}", "no 'fortran_order'"),
            ("{'descr': '|u1', 'fortran_order': False}", "no 'shape'"),
            (
                "{'descr': '|u1', 'fortran_order': False, 'shape': (6)}",
                "(n,)",
            ),
            (
                "{'descr': '|u1', 'fortran_order': False, 'shape': [2, 3]}",
                "tuple",
            ),
            (
                "{'descr': '|u1', 'fortran_order': False, 'shape': (2, -3)}",
                "tuple",
            ),
            (
                "{'descr': '|u1', 'fortran_order': False, 'shape': (2 3)}",
                "tuple",
            ),
            (
                "{'descr': '|u1', 'fortran_order': False, 'shape': (2, 3), 'x': 1}",
                "'x'",
            ),
            (
                "{'descr': '|u1', 'fortran_order': False, 'fortran_order': True, 'shape': (6,)}",
                "twice",
            ),
            (
                "{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (6,)}",
                "structured",
            ),
            (
                "{descr: '|u1', 'fortran_order': False, 'shape': (6,)}",
                "key",
            ),
            (
                "{'descr': '|u1', 'fortran_order': False, 'shape': (6,)} x",
                "after",
            ),
            (
                "{'descr': '|u1' 'fortran_order': False, 'shape': (6,)}",
                "`,`",
            ),
            ("{'descr': '|u1, 'fortran_order': False}", "key"),
        ] {
            let e = parse(&file(dict, &body)).unwrap_err();
            assert!(e.contains(words), "{dict}: {e}");
        }
        let e = parse(&file(
            "{'descr': '>f8', 'fortran_order': False, 'shape': (1,)}",
            &[0; 8],
        ));
        assert!(e.unwrap_err().contains(">f8"));
    }
}
