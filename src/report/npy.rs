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
pub use crate::npy::{Header, NpyArray, NpyData, parse};

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
    // The file's size, reserved at once (growing as it reads could take twice as much).
    let size = file
        .metadata()
        .map_or(0, |m| m.len())
        .min(MAX_NPY_BYTES + 1);
    let mut bytes = Vec::with_capacity(size as usize);
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

/// Reads a `.npy` file as [`read`] does, but first reads its header alone and estimates the
/// memory the array takes: the file's bytes, its elements decoded (one copy, in C order
/// whatever the file's order), and `extra` bytes that the caller makes of it (`extra(header)`,
/// with its description). An estimate above the memory limit (`crate::memory`) is refused as
/// bad input about the file, naming the estimate and the array's shape, before anything large
/// is allocated.
pub fn read_bounded(
    path: &Path,
    what: &str,
    extra: impl Fn(&Header) -> (f64, String),
) -> Result<NpyArray> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| Error::read(path, e))?;
    let mut reader = file.take(MAX_NPY_BYTES + 1);
    // The magic, the version and the header's length, then the header.
    let mut bytes = vec![0u8; 12];
    let n = read_up_to(&mut reader, &mut bytes).map_err(|e| Error::read(path, e))?;
    bytes.truncate(n);
    let start = match bytes.get(6) {
        Some(1) if n >= 10 => 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize,
        Some(2 | 3) if n >= 12 => {
            12 + u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize
        }
        // Not a readable header: `parse` says why.
        _ => 0,
    };
    if start as u64 > MAX_NPY_BYTES {
        return Err(bad(path, "the header is longer than the largest file read"));
    }
    if start > bytes.len() {
        let have = bytes.len();
        bytes.resize(start, 0);
        let got = read_up_to(&mut reader, &mut bytes[have..]).map_err(|e| Error::read(path, e))?;
        bytes.truncate(have + got);
    }
    let file_len = reader
        .get_ref()
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len());
    let header = crate::npy::header(&bytes).ok().filter(|h| {
        // A file shorter than its header claims is reported as truncated by `parse`.
        let claimed = h
            .count()
            .zip(h.item_bytes())
            .map(|(c, i)| c as f64 * i as f64);
        claimed.is_some_and(|d| file_len.is_none_or(|l| h.data_start as f64 + d <= l as f64))
    });
    if let Some(h) = header {
        let elements = h.count().unwrap_or(0) as f64;
        let item = h.item_bytes().unwrap_or(8) as f64;
        let data = elements * item;
        let (more, more_what) = extra(&h);
        let order = if h.fortran_order { "Fortran" } else { "C" };
        let dims: Vec<String> = h.shape.iter().map(|d| d.to_string()).collect();
        let settings = format!(
            "a {} array of '{}' in {order} order: the file's {} read, {} decoded{}",
            dims.join(" × "),
            h.descr,
            crate::memory::bytes_text(h.data_start as f64 + data),
            crate::memory::bytes_text(data),
            if more_what.is_empty() {
                String::new()
            } else {
                format!(", {} {more_what}", crate::memory::bytes_text(more))
            }
        );
        crate::memory::check(
            h.data_start as f64 + 2.0 * data + more,
            what,
            &settings,
            "use a smaller array",
        )
        .map_err(|e| e.in_file(path))?;
    }
    // The rest at once, as far as the file has it (growing as it reads could take twice as
    // much as the file).
    let size = reader.get_ref().metadata().map_or(0, |m| m.len());
    bytes.reserve_exact(
        size.min(MAX_NPY_BYTES + 1)
            .saturating_sub(bytes.len() as u64) as usize,
    );
    reader
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

/// Fills `buf` from `r` as far as it has bytes; returns how many it read.
fn read_up_to(r: &mut impl std::io::Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
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
    let mut bytes = header_bytes("<f8", shape);
    bytes.reserve_exact(8 * data.len());
    push_le(&mut bytes, data);
    bytes
}

/// Appends `values` to `bytes` as little-endian float64 (one resize, then a loop the compiler
/// vectorises; pushing 8 bytes at a time checked the capacity per value).
fn push_le(bytes: &mut Vec<u8>, values: &[f64]) {
    let start = bytes.len();
    bytes.resize(start + 8 * values.len(), 0);
    for (c, v) in bytes[start..].chunks_exact_mut(8).zip(values) {
        c.copy_from_slice(&v.to_le_bytes());
    }
}

/// Bytes a [`F64FileWriter`] gathers before it hashes and writes them: small enough to stay in
/// a core's cache between the encoding, the hash and the copy into the file.
const FILE_CHUNK_BYTES: usize = 256 << 10;

/// A float64 array written to its file as its values come, in chunks, and hashed (SHA-256 of
/// the file's bytes, header included) on the way. A dataset shard's largest array (its
/// objects, ~18 MB at 250 samples of 96 × 96) used to be encoded whole, then hashed, then
/// copied into the file, three passes over memory that no cache holds; each chunk here is
/// encoded, hashed and written while it is in the cache. The file and the digest are the same
/// bytes as [`encode_f64`]'s and `sha256_hex` of them.
pub struct F64FileWriter {
    path: std::path::PathBuf,
    file: std::fs::File,
    hash: sha2::Sha256,
    chunk: Vec<u8>,
    left: usize,
}

impl F64FileWriter {
    /// Creates (or truncates) `path` for an array of `shape`.
    pub fn create(path: &Path, shape: &[usize]) -> Result<F64FileWriter> {
        let file = std::fs::File::create(path).map_err(|e| Error::write(path, e))?;
        let mut chunk = Vec::with_capacity(FILE_CHUNK_BYTES + 4096);
        chunk.extend_from_slice(&header_bytes("<f8", shape));
        Ok(F64FileWriter {
            path: path.to_path_buf(),
            file,
            hash: sha2::Sha256::default(),
            chunk,
            left: shape.iter().product(),
        })
    }

    /// Appends values in C order.
    pub fn extend(&mut self, values: &[f64]) -> Result<()> {
        assert!(values.len() <= self.left, "shape and data disagree");
        self.left -= values.len();
        push_le(&mut self.chunk, values);
        if self.chunk.len() >= FILE_CHUNK_BYTES {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<()> {
        use sha2::Digest;
        self.hash.update(&self.chunk);
        self.file
            .write_all(&self.chunk)
            .map_err(|e| Error::write(&self.path, e))?;
        self.chunk.clear();
        Ok(())
    }

    /// Writes what is left; every value of the shape must have been given. Returns the file's
    /// SHA-256 as lower-case hex.
    pub fn finish(mut self) -> Result<String> {
        use sha2::Digest;
        assert_eq!(self.left, 0, "shape and data disagree");
        self.flush()?;
        Ok(crate::provenance::hex(&self.hash.finalize()))
    }
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

/// The temporary name [`write_atomic`] writes `path` under before renaming it: `NAME.EXT.partial`.
pub fn atomic_temp(path: &Path) -> std::path::PathBuf {
    path.with_extension(format!(
        "{}.partial",
        path.extension().and_then(|e| e.to_str()).unwrap_or("")
    ))
}

/// Writes bytes to a file through a temporary name, so that a failed run leaves nothing half written.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, bytes, |tmp| std::fs::File::create(tmp))
}

/// [`write_atomic`], the temporary file ([`atomic_temp`]) made by `create`.
pub fn write_atomic_with(
    path: &Path,
    bytes: &[u8],
    create: impl FnOnce(&Path) -> std::io::Result<std::fs::File>,
) -> Result<()> {
    let tmp = atomic_temp(path);
    let res = (|| {
        let mut f = create(&tmp)?;
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
        // 3-D: the element at C index (a, b, c) is the one stored at a + 2b + 4c.
        let mut bytes = encode_u8(&[2, 2, 2], &[0, 1, 2, 3, 4, 5, 6, 7]);
        let at = bytes.windows(5).position(|w| w == b"False").unwrap();
        bytes[at..at + 5].copy_from_slice(b"True ");
        let a = parse(&bytes).unwrap();
        assert_eq!(a.data, NpyData::U8(vec![0, 4, 2, 6, 1, 5, 3, 7]));
    }

    /// `read_bounded` refuses from the header alone an array whose reading would exceed the
    /// memory limit (a sparse 1.2 GB-claiming file is never read), reads a small one as `read`
    /// does, and leaves a file shorter than its header claims to `parse`'s "truncated".
    #[test]
    fn bounded_reads_estimate_from_the_header() {
        let dir = std::env::temp_dir().join(format!("spibench-npy-bounded-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let small = dir.join("small.npy");
        write_u8(&small, &[2, 3], &[0, 1, 0, 1, 1, 0]).unwrap();
        let none = |_: &Header| (0.0, String::new());
        assert_eq!(
            read_bounded(&small, "x", none).unwrap(),
            read(&small).unwrap()
        );
        // 1e9 elements of float64 claimed, 64 bytes there: truncated, not a memory estimate.
        let mut short = header_bytes("<f8", &[1000, 1_000_000]);
        short.extend_from_slice(&[0; 64]);
        let trunc = dir.join("trunc.npy");
        std::fs::write(&trunc, &short).unwrap();
        let e = read_bounded(&trunc, "x", none).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
        // A sparse file of 1 GB of bytes: file, decoded copy and 0.5 GB of the caller's.
        let big = dir.join("big.npy");
        let h = header_bytes("|u1", &[1000, 1_000_000]);
        std::fs::write(&big, &h).unwrap();
        let f = std::fs::File::options().write(true).open(&big).unwrap();
        f.set_len(h.len() as u64 + 1_000_000_000).unwrap();
        let rows = |h: &Header| (0.5 * h.count().unwrap() as f64, "of rows".to_string());
        let e = read_bounded(&big, "the big array", rows).unwrap_err();
        let m = e.to_string();
        assert!(e.is_user_error() && m.contains("big.npy"), "{m}");
        assert!(
            m.contains("the big array would take about 2.50 GB")
                && m.contains("a 1000 × 1000000 array of '|u1' in C order")
                && m.contains("500.00 MB of rows"),
            "{m}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
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

    /// The file writer gives the bytes of `encode_f64` and their SHA-256, whatever the rows'
    /// lengths, over several chunks (an odd row length makes rows straddle the chunks).
    #[test]
    fn file_writer_equals_the_encoded_array_and_its_hash() {
        let dir = std::env::temp_dir().join(format!("spibench-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (rows, cols) in [(3, 5), (70, 1001), (1, 0)] {
            let data: Vec<f64> = (0..rows * cols).map(|i| (i as f64).sqrt() - 7.0).collect();
            let p = dir.join(format!("a{rows}x{cols}.npy"));
            let mut w = F64FileWriter::create(&p, &[rows, cols]).unwrap();
            for r in data.chunks(cols.max(1)) {
                w.extend(r).unwrap();
            }
            let sha = w.finish().unwrap();
            let want = encode_f64(&[rows, cols], &data);
            assert!(want.len() > 2 * FILE_CHUNK_BYTES || rows * cols < 100);
            assert_eq!(std::fs::read(&p).unwrap(), want, "{rows}×{cols}");
            assert_eq!(sha, crate::provenance::sha256_hex(&want), "{rows}×{cols}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
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

    /// A 2-D `.npy` array is an object image (values as stored, [0, 255]); other shapes and
    /// values outside the range are input errors.
    #[test]
    fn npy_objects_decode_as_images() {
        use crate::objects::image_file::decode_gray;
        let data: Vec<f64> = (0..6).map(|i| i as f64 * 40.0).collect();
        let img = decode_gray(&encode_f64(&[2, 3], &data)).unwrap();
        assert_eq!((img.width, img.height), (3, 2));
        assert_eq!(img.data, data);
        let u8s = decode_gray(&encode_u8(&[1, 2], &[0, 255])).unwrap();
        assert_eq!(u8s.data, vec![0.0, 255.0]);
        for (bytes, words) in [
            (encode_f64(&[6], &data), "2-D"),
            (encode_f64(&[1, 2, 3], &data), "2-D"),
            (
                encode_f64(&[2, 3], &[0.0, 1.0, 2.0, 3.0, 256.0, 5.0]),
                "row 1, column 1",
            ),
            (encode_f64(&[1, 1], &[f64::NAN]), "[0, 255]"),
        ] {
            let e = decode_gray(&bytes).unwrap_err();
            assert!(e.is_user_error() && e.to_string().contains(words), "{e}");
        }
    }
}
