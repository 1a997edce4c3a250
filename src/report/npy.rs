//! NumPy `.npy` (format 1.0/2.0/3.0) reading and writing, little-endian; C-order and
//! Fortran-order arrays are read (the latter reordered to C order), C order is written.
//!
//! Hand-written rather than `npyz`: the format is a text header and raw little-endian data,
//! spibench reads exactly five element types (patterns as uint8/bool, measurements as
//! float64/float32/int64) and writes two, and neither `.npz` archives nor structured dtypes are
//! used by any command; this file does that in ~300 lines with no dependency and with error
//! messages that name the file and the problem.

use std::io::Write;
use std::path::Path;

use crate::error::{Error, Result};

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

fn bad(path: &Path, msg: impl Into<String>) -> Error {
    Error::input(format!("not a readable .npy array: {}", msg.into())).in_file(path)
}

/// The largest `.npy` file spibench reads: 1 GiB (a 4096 × 4096-mirror DMD's full 0/1 pattern
/// set at 100 % sampling is 16 Mi × 16 Mi bits packed, far beyond; measurements and images
/// are megabytes). Larger is a wrong path, such as a device.
pub const MAX_NPY_BYTES: u64 = 1 << 30;

/// Reads a `.npy` file of at most [`MAX_NPY_BYTES`], without reading past the limit (so that
/// `/dev/zero` fails at once).
pub fn read(path: &Path) -> Result<NpyArray> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| Error::read(path, e))?;
    let mut bytes = Vec::new();
    file.take(MAX_NPY_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::read(path, e))?;
    if bytes.len() as u64 > MAX_NPY_BYTES {
        return Err(bad(
            path,
            format!("the file is larger than {} MiB", MAX_NPY_BYTES >> 20),
        ));
    }
    parse(&bytes).map_err(|m| bad(path, m))
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
fn fortran_to_c(shape: &[usize]) -> Vec<usize> {
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

fn header_bytes(descr: &str, shape: &[usize]) -> Vec<u8> {
    let shape_txt = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // Pad so that the data start at a multiple of 64 bytes, ending the header with a newline.
    let total = 10 + h.len() + 1;
    h.push_str(&" ".repeat((64 - total % 64) % 64));
    h.push('\n');
    let mut out = Vec::with_capacity(10 + h.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(h.len() as u16).to_le_bytes());
    out.extend_from_slice(h.as_bytes());
    out
}

/// The bytes of a float64 array.
pub fn encode_f64(shape: &[usize], data: &[f64]) -> Vec<u8> {
    assert_eq!(
        shape.iter().product::<usize>(),
        data.len(),
        "shape and data disagree"
    );
    let mut out = header_bytes("<f8", shape);
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// The bytes of a uint8 array.
pub fn encode_u8(shape: &[usize], data: &[u8]) -> Vec<u8> {
    assert_eq!(
        shape.iter().product::<usize>(),
        data.len(),
        "shape and data disagree"
    );
    let mut out = header_bytes("|u1", shape);
    out.extend_from_slice(data);
    out
}

/// Writes bytes to a file through a temporary name, so that a failed run leaves nothing half written.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension(format!(
        "{}.partial",
        path.extension().and_then(|e| e.to_str()).unwrap_or("")
    ));
    let res = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = res {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::write(path, e));
    }
    Ok(())
}

pub fn write_f64(path: &Path, shape: &[usize], data: &[f64]) -> Result<()> {
    write_atomic(path, &encode_f64(shape, data))
}

pub fn write_u8(path: &Path, shape: &[usize], data: &[u8]) -> Result<()> {
    write_atomic(path, &encode_u8(shape, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// numpy.asfortranarray(np.arange(6, dtype=np.uint8).reshape(2, 3)) stores 0 3 1 4 2 5; it
    /// reads back as the C-order array 0 1 2 3 4 5.
    #[test]
    fn reads_fortran_order() {
        let mut bytes = encode_u8(&[2, 3], &[0, 3, 1, 4, 2, 5]);
        let at = bytes.windows(5).position(|w| w == b"False").unwrap();
        bytes[at..at + 5].copy_from_slice(b"True ");
        let a = parse(&bytes).unwrap();
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, NpyData::U8(vec![0, 1, 2, 3, 4, 5]));
        assert_eq!(fortran_to_c(&[2, 2, 2]), vec![0, 4, 2, 6, 1, 5, 3, 7]);
    }

    #[test]
    fn round_trip_f64_and_u8() {
        let a = vec![1.5, -2.0, 3.25, f64::MAX, 0.0, 1e-300];
        let back = parse(&encode_f64(&[2, 3], &a)).unwrap();
        assert_eq!(back.shape, vec![2, 3]);
        assert_eq!(back.data, NpyData::F64(a));
        let b = vec![0u8, 1, 1, 0, 1];
        let back = parse(&encode_u8(&[5], &b)).unwrap();
        assert_eq!(back.shape, vec![5]);
        assert_eq!(back.data, NpyData::U8(b));
        assert_eq!(encode_u8(&[5], &[0; 5]).len() % 64, 5);
    }

    #[test]
    fn header_is_aligned_to_64_bytes() {
        let bytes = encode_f64(&[128, 128], &vec![0.0; 128 * 128]);
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0);
    }

    #[test]
    fn rejects_garbage_and_truncation() {
        assert!(parse(b"hello world, not numpy").is_err());
        let mut bytes = encode_f64(&[4], &[1.0, 2.0, 3.0, 4.0]);
        bytes.truncate(bytes.len() - 3);
        assert!(parse(&bytes).unwrap_err().contains("truncated"));
    }
}
