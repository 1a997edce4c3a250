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

/// Parses the bytes of a `.npy` file.
pub fn parse(bytes: &[u8]) -> std::result::Result<NpyArray, String> {
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
    let header = std::str::from_utf8(header).map_err(|_| "header is not text")?;
    let descr = dict_value(header, "descr").ok_or("header has no 'descr'")?;
    let descr = descr.trim().trim_matches(|c| c == '\'' || c == '"');
    let fortran = dict_value(header, "fortran_order").ok_or("header has no 'fortran_order'")?;
    let fortran = fortran.trim().starts_with("True");
    let shape_txt = dict_value(header, "shape").ok_or("header has no 'shape'")?;
    let shape_txt = shape_txt.trim();
    let inner = shape_txt
        .strip_prefix('(')
        .and_then(|s| s.find(')').map(|e| &s[..e]))
        .ok_or("malformed shape")?;
    let shape: Vec<usize> = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>()
                .map_err(|_| format!("bad dimension '{s}'"))
        })
        .collect::<std::result::Result<_, _>>()?;
    let count = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or("shape too large")?;
    let body = &bytes[hstart + hlen..];
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
    let data = match descr {
        "<f8" | "f8" | "float64" => NpyData::F64(
            need(8)?
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        "<f4" => NpyData::F32(
            need(4)?
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        "|u1" | "<u1" | "u1" => NpyData::U8(need(1)?.to_vec()),
        "|b1" => NpyData::Bool(need(1)?.to_vec()),
        "<i8" => NpyData::I64(
            need(8)?
                .chunks_exact(8)
                .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        other => {
            return Err(format!(
                "element type '{other}' is not supported (use float64, float32, uint8, bool or int64)"
            ));
        }
    };
    let data = if fortran && shape.len() > 1 {
        let order = fortran_to_c(&shape);
        match data {
            NpyData::F64(v) => NpyData::F64(order.iter().map(|&i| v[i]).collect()),
            NpyData::F32(v) => NpyData::F32(order.iter().map(|&i| v[i]).collect()),
            NpyData::U8(v) => NpyData::U8(order.iter().map(|&i| v[i]).collect()),
            NpyData::Bool(v) => NpyData::Bool(order.iter().map(|&i| v[i]).collect()),
            NpyData::I64(v) => NpyData::I64(order.iter().map(|&i| v[i]).collect()),
        }
    } else {
        data
    };
    Ok(NpyArray { shape, data })
}

/// For each element in C (row-major) order, its position in Fortran (column-major) storage.
pub(crate) fn fortran_to_c(shape: &[usize]) -> Vec<usize> {
    let count: usize = shape.iter().product();
    // Fortran strides: the first index varies fastest.
    let mut strides = vec![1usize; shape.len()];
    for k in 1..shape.len() {
        strides[k] = strides[k - 1] * shape[k - 1];
    }
    let mut idx = vec![0usize; shape.len()];
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        out.push(idx.iter().zip(&strides).map(|(i, s)| i * s).sum());
        // Advance the C-order multi-index: the last index varies fastest.
        for k in (0..shape.len()).rev() {
            idx[k] += 1;
            if idx[k] < shape[k] {
                break;
            }
            idx[k] = 0;
        }
    }
    out
}

/// The text after `'key':` in a Python dict literal, up to the next top-level comma.
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pat1 = format!("'{key}':");
    let start = header.find(&pat1)? + pat1.len();
    let rest = &header[start..];
    let mut depth = 0i32;
    for (i, ch) in rest.char_indices() {
        match ch {
            '(' => depth += 1,
            ')' => depth -= 1,
            ',' | '}' if depth == 0 => return Some(&rest[..i]),
            _ => {}
        }
    }
    Some(rest)
}
