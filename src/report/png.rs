//! PNG output: grayscale rasters (8 and 16 bit) and RGB buffers, encoded in memory with the
//! `image` crate ([`encode_gray8`], [`encode_gray16`], [`encode_rgb8`], also used to embed
//! images in HTML reports) and written through a temporary name (`npy::write_atomic`).

use std::io::Cursor;
use std::path::Path;

use image::{ImageBuffer, ImageFormat, Luma, Rgb};

use super::npy::write_atomic;
use crate::error::{Error, Result};
use crate::raster::Raster;

/// Maps `v` linearly from `[lo, hi]` to `[0, max]`, clips, and rounds half away from zero.
/// NaN maps to 0 (the `lo` end), like a pixel with no signal; ±∞ clip to the ends.
fn quantize(v: f64, lo: f64, hi: f64, max: f64) -> f64 {
    if v.is_nan() {
        return 0.0;
    }
    let t = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
    (t * max).round()
}

fn check_range(lo: f64, hi: f64) -> Result<()> {
    if !lo.is_finite() || !hi.is_finite() || hi <= lo {
        return Err(Error::input(format!(
            "the gray range must be finite with hi > lo, got lo = {lo}, hi = {hi}"
        )));
    }
    Ok(())
}

/// The dimensions as PNG needs them (u32, non-zero).
fn dims(width: usize, height: usize) -> Result<(u32, u32)> {
    match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 && (w as u64) * (h as u64) <= (1u64 << 32) => Ok((w, h)),
        _ => Err(Error::input(format!(
            "a {width}×{height} image cannot be encoded as PNG"
        ))),
    }
}

fn check_raster(image: &Raster) -> Result<(u32, u32)> {
    if image.data.len() != image.width * image.height {
        return Err(Error::input(format!(
            "the image holds {} values but claims {}×{}",
            image.data.len(),
            image.width,
            image.height
        )));
    }
    dims(image.width, image.height)
}

/// The stand-in path of an encoding failure in memory (there is no file yet).
const IN_MEMORY: &str = "(PNG in memory)";

/// Encodes an 8-bit gray PNG in memory: linear map of `[lo, hi]` to `[0, 255]`, clipped,
/// rounded; NaN is 0. The bytes are a complete PNG file (for a data: URI or a later write).
pub fn encode_gray8(image: &Raster, lo: f64, hi: f64) -> Result<Vec<u8>> {
    check_range(lo, hi)?;
    let (w, h) = check_raster(image)?;
    let px: Vec<u8> = image
        .data
        .iter()
        .map(|&v| quantize(v, lo, hi, 255.0) as u8)
        .collect();
    let buf: ImageBuffer<Luma<u8>, Vec<u8>> = ImageBuffer::from_raw(w, h, px)
        .ok_or_else(|| Error::input("image buffer size mismatch"))?;
    encode(|out| buf.write_to(out, ImageFormat::Png))
}

/// Encodes a 16-bit gray PNG in memory: linear map of `[lo, hi]` to `[0, 65535]`, clipped,
/// rounded; NaN is 0.
pub fn encode_gray16(image: &Raster, lo: f64, hi: f64) -> Result<Vec<u8>> {
    check_range(lo, hi)?;
    let (w, h) = check_raster(image)?;
    let px: Vec<u16> = image
        .data
        .iter()
        .map(|&v| quantize(v, lo, hi, 65535.0) as u16)
        .collect();
    let buf: ImageBuffer<Luma<u16>, Vec<u16>> = ImageBuffer::from_raw(w, h, px)
        .ok_or_else(|| Error::input("image buffer size mismatch"))?;
    encode(|out| buf.write_to(out, ImageFormat::Png))
}

/// Encodes an 8-bit RGB PNG in memory from row-major RGB bytes (3 per pixel).
pub fn encode_rgb8(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>> {
    dims(width as usize, height as usize)?;
    let expected = width as usize * height as usize * 3;
    if rgb.len() != expected {
        return Err(Error::input(format!(
            "an RGB image of {width}×{height} needs {expected} bytes, got {}",
            rgb.len()
        )));
    }
    let buf: ImageBuffer<Rgb<u8>, &[u8]> = ImageBuffer::from_raw(width, height, rgb)
        .ok_or_else(|| Error::input("image buffer size mismatch"))?;
    encode(|out| buf.write_to(out, ImageFormat::Png))
}

/// [`encode_rgb8`] with the resolution the image is drawn at stated in a `pHYs` chunk (pixels
/// per metre, PNG 1.2 §11.3.5.3), so that word processors and LaTeX place a figure at its
/// print size instead of at 72 or 96 dpi.
pub fn encode_rgb8_at_dpi(width: u32, height: u32, rgb: &[u8], dpi: f64) -> Result<Vec<u8>> {
    Ok(with_phys(encode_rgb8(width, height, rgb)?, dpi))
}

/// Metres per inch (exact, by definition of the inch).
const M_PER_IN: f64 = 0.0254;

/// `png` with a `pHYs` chunk of `dpi` (the same on both axes, unit: the metre) right after its
/// `IHDR` chunk, where the specification requires it (before `IDAT`); an existing `pHYs` is
/// kept as it is. Bytes that are not a PNG are returned unchanged.
pub fn with_phys(png: Vec<u8>, dpi: f64) -> Vec<u8> {
    // Signature (8 bytes), then IHDR: length (4), type (4), 13 data bytes, CRC (4).
    const IHDR_END: usize = 8 + 4 + 4 + 13 + 4;
    if png.len() < IHDR_END || &png[12..16] != b"IHDR" || phys_dpi(&png).is_some() {
        return png;
    }
    let ppm = (dpi / M_PER_IN).round() as u32;
    let mut chunk = Vec::with_capacity(21);
    chunk.extend(9u32.to_be_bytes());
    chunk.extend(b"pHYs");
    chunk.extend(ppm.to_be_bytes());
    chunk.extend(ppm.to_be_bytes());
    chunk.push(1);
    let crc = crc32(&chunk[4..]);
    chunk.extend(crc.to_be_bytes());
    let mut out = Vec::with_capacity(png.len() + chunk.len());
    out.extend_from_slice(&png[..IHDR_END]);
    out.extend(chunk);
    out.extend_from_slice(&png[IHDR_END..]);
    out
}

/// The resolution a PNG's `pHYs` chunk states, in dots per inch (x axis), when it states one
/// in metres.
pub fn phys_dpi(png: &[u8]) -> Option<f64> {
    let mut at = 8;
    while at + 12 <= png.len() {
        let len = u32::from_be_bytes(png[at..at + 4].try_into().ok()?) as usize;
        let kind = &png[at + 4..at + 8];
        if kind == b"pHYs" && len == 9 && at + 8 + 9 <= png.len() {
            let d = &png[at + 8..at + 17];
            let x = u32::from_be_bytes(d[..4].try_into().ok()?);
            return (d[8] == 1).then(|| f64::from(x) * M_PER_IN);
        }
        if kind == b"IDAT" {
            return None;
        }
        at += 12 + len;
    }
    None
}

/// CRC-32 (ISO 3309, the polynomial PNG uses), bit by bit: a chunk of 13 bytes needs no table.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// Writes an 8-bit gray PNG: linear map of `[lo, hi]` to `[0, 255]`, clipped, rounded; NaN is 0.
pub fn write_gray8(path: &Path, image: &Raster, lo: f64, hi: f64) -> Result<()> {
    let bytes = encode_gray8(image, lo, hi).map_err(|e| at_path(e, path))?;
    write_atomic(path, &bytes)
}

/// Writes a 16-bit gray PNG: linear map of `[lo, hi]` to `[0, 65535]`, clipped, rounded; NaN is 0.
pub fn write_gray16(path: &Path, image: &Raster, lo: f64, hi: f64) -> Result<()> {
    let bytes = encode_gray16(image, lo, hi).map_err(|e| at_path(e, path))?;
    write_atomic(path, &bytes)
}

/// Writes an 8-bit RGB PNG from row-major RGB bytes (3 per pixel).
pub fn write_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    let bytes = encode_rgb8(width, height, rgb).map_err(|e| at_path(e, path))?;
    write_atomic(path, &bytes)
}

/// Runs an encoder into memory, so that a file is written in one atomic step afterwards.
fn encode(f: impl FnOnce(&mut Cursor<Vec<u8>>) -> image::ImageResult<()>) -> Result<Vec<u8>> {
    let mut out = Cursor::new(Vec::new());
    f(&mut out)
        .map_err(|e| Error::write(Path::new(IN_MEMORY), std::io::Error::other(e.to_string())))?;
    Ok(out.into_inner())
}

/// Puts the file an encoder was meant for into its error: input errors name the file, and an
/// encoding failure is reported as a failure to write that file (as before the in-memory
/// encoders existed).
fn at_path(e: Error, path: &Path) -> Error {
    match e {
        Error::Io { action, source, .. } => Error::Io {
            action,
            path: path.to_path_buf(),
            source,
        },
        other => other.in_file(path),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory for one test (tests run in parallel), removed by the test at its end.
    fn scratch(test: &str) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("spibench-png-test-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn gray8_round_trip_maps_clips_and_rounds() {
        let dir = scratch("gray8_round_trip_maps_clips_and_rounds");
        // lo = 10, hi = 20: 10 → 0, 20 → 255, 15 → 127.5 → 128, 12 → 51, below/above clip,
        // NaN → 0, 10.98 → 24.99 → 25, 11.0 → 25.5 → 26 (half away from zero).
        let values = vec![10.0, 20.0, 15.0, 12.0, -5.0, 99.0, f64::NAN, 10.98, 11.0];
        let img = Raster::new(3, 3, values).unwrap();
        let path = dir.join("g8.png");
        write_gray8(&path, &img, 10.0, 20.0).unwrap();
        let back = image::open(&path).unwrap();
        let back = back.as_luma8().expect("8-bit gray PNG");
        assert_eq!(back.dimensions(), (3, 3));
        assert_eq!(back.as_raw(), &vec![0, 255, 128, 51, 0, 255, 0, 25, 26]);
        // Row-major order: pixel (x = 2, y = 0) is value index 2.
        assert_eq!(back.get_pixel(2, 0).0[0], 128);
        assert_eq!(back.get_pixel(0, 1).0[0], 51);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn gray16_round_trip_is_exact() {
        let dir = scratch("gray16_round_trip_is_exact");
        // lo = -1, hi = 1 on a non-square image: -1 → 0, 1 → 65535, 0 → 32767.5 → 32768,
        // 0.5 → 49151.25 → 49151, -0.25 → 24575.625 → 24576, out of range clips.
        let values = vec![-1.0, 1.0, 0.0, 0.5, -0.25, 7.0, -7.0, f64::INFINITY];
        let img = Raster::new(4, 2, values).unwrap();
        let path = dir.join("g16.png");
        write_gray16(&path, &img, -1.0, 1.0).unwrap();
        let back = image::open(&path).unwrap();
        let back = back.as_luma16().expect("16-bit gray PNG");
        assert_eq!(back.dimensions(), (4, 2));
        assert_eq!(
            back.as_raw(),
            &vec![0, 65535, 32768, 49151, 24576, 65535, 0, 65535]
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The pHYs chunk states 288 dpi (11 339 pixels per metre), sits before the image data,
    /// carries a valid CRC (the decoder checks it) and leaves the pixels as they were.
    #[test]
    fn phys_states_the_drawing_resolution() {
        assert_eq!(crc32(b"IEND"), 0xAE42_6082);
        let rgb: Vec<u8> = (0..4 * 3 * 3).map(|i| (i * 7) as u8).collect();
        let plain = encode_rgb8(4, 3, &rgb).unwrap();
        assert_eq!(phys_dpi(&plain), None);
        let bytes = encode_rgb8_at_dpi(4, 3, &rgb, 288.0).unwrap();
        let dpi = phys_dpi(&bytes).unwrap();
        assert!((dpi - 288.0).abs() < 0.05, "{dpi}");
        assert_eq!(
            u32::from_be_bytes(bytes[41..45].try_into().unwrap()),
            11_339
        );
        assert_eq!(with_phys(bytes.clone(), 96.0), bytes);
        let back = image::load_from_memory(&bytes).unwrap();
        assert_eq!(back.as_rgb8().unwrap().as_raw(), &rgb);
        assert_eq!(with_phys(b"not a png".to_vec(), 288.0), b"not a png");
    }

    #[test]
    fn rgb8_round_trip() {
        let dir = scratch("rgb8_round_trip");
        let rgb: Vec<u8> = (0..2 * 3 * 3).map(|i| (i * 13) as u8).collect();
        let path = dir.join("rgb.png");
        write_rgb8(&path, 2, 3, &rgb).unwrap();
        let back = image::open(&path).unwrap();
        let back = back.as_rgb8().expect("RGB PNG");
        assert_eq!(back.dimensions(), (2, 3));
        assert_eq!(back.as_raw(), &rgb);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn in_memory_encoders_give_the_file_bytes() {
        let dir = scratch("in_memory_encoders_give_the_file_bytes");
        let img = Raster::new(3, 2, vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]).unwrap();
        let path = dir.join("m.png");
        write_gray8(&path, &img, 0.0, 1.0).unwrap();
        let bytes = encode_gray8(&img, 0.0, 1.0).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), bytes);
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let back = image::load_from_memory(&bytes).unwrap();
        assert_eq!(
            back.as_luma8().unwrap().as_raw(),
            &vec![0, 51, 102, 153, 204, 255]
        );
        write_gray16(&path, &img, 0.0, 1.0).unwrap();
        assert_eq!(
            std::fs::read(&path).unwrap(),
            encode_gray16(&img, 0.0, 1.0).unwrap()
        );
        let rgb = [10u8, 20, 30, 40, 50, 60];
        write_rgb8(&path, 2, 1, &rgb).unwrap();
        assert_eq!(
            std::fs::read(&path).unwrap(),
            encode_rgb8(2, 1, &rgb).unwrap()
        );
        // Without a file, bad input is still an input error, with no file named.
        let e = encode_gray8(&img, 2.0, 1.0).unwrap_err();
        assert!(e.is_user_error());
        assert!(e.to_string().starts_with("the gray range"), "{e}");
        assert!(encode_rgb8(0, 1, &[]).unwrap_err().is_user_error());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_input_is_an_error_naming_the_file() {
        let dir = scratch("bad_input_is_an_error_naming_the_file");
        let img = Raster::zeros(2, 2);
        let path = dir.join("bad.png");
        let e = write_gray8(&path, &img, 1.0, 1.0).unwrap_err();
        assert!(e.is_user_error());
        assert!(e.to_string().contains("bad.png"), "{e}");
        let e = write_rgb8(&path, 2, 2, &[0; 5]).unwrap_err();
        assert!(e.to_string().contains("bad.png"), "{e}");
        let broken = Raster {
            width: 3,
            height: 3,
            data: vec![0.0; 4],
        };
        assert!(write_gray16(&path, &broken, 0.0, 1.0).is_err());
        assert!(!path.exists());
        // A directory that does not exist is a write error naming the path.
        let e = write_gray8(&dir.join("missing-dir/x.png"), &img, 0.0, 1.0).unwrap_err();
        assert!(e.to_string().contains("missing-dir"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
