//! PNG output: grayscale rasters (8 and 16 bit) and RGB buffers, encoded in memory with the
//! `image` crate and written through a temporary name (`npy::write_atomic`).

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

fn check_range(path: &Path, lo: f64, hi: f64) -> Result<()> {
    if !lo.is_finite() || !hi.is_finite() || hi <= lo {
        return Err(Error::input(format!(
            "the gray range must be finite with hi > lo, got lo = {lo}, hi = {hi}"
        ))
        .in_file(path));
    }
    Ok(())
}

/// The dimensions as PNG needs them (u32, non-zero).
fn dims(path: &Path, width: usize, height: usize) -> Result<(u32, u32)> {
    match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 && (w as u64) * (h as u64) <= (1u64 << 32) => Ok((w, h)),
        _ => Err(
            Error::input(format!("a {width}×{height} image cannot be written as PNG"))
                .in_file(path),
        ),
    }
}

fn check_raster(path: &Path, image: &Raster) -> Result<(u32, u32)> {
    if image.data.len() != image.width * image.height {
        return Err(Error::input(format!(
            "the image holds {} values but claims {}×{}",
            image.data.len(),
            image.width,
            image.height
        ))
        .in_file(path));
    }
    dims(path, image.width, image.height)
}

/// Writes an 8-bit gray PNG: linear map of `[lo, hi]` to `[0, 255]`, clipped, rounded; NaN is 0.
pub fn write_gray8(path: &Path, image: &Raster, lo: f64, hi: f64) -> Result<()> {
    check_range(path, lo, hi)?;
    let (w, h) = check_raster(path, image)?;
    let px: Vec<u8> = image
        .data
        .iter()
        .map(|&v| quantize(v, lo, hi, 255.0) as u8)
        .collect();
    let buf: ImageBuffer<Luma<u8>, Vec<u8>> = ImageBuffer::from_raw(w, h, px)
        .ok_or_else(|| Error::input("image buffer size mismatch").in_file(path))?;
    write_atomic(
        path,
        &encode(path, |out| buf.write_to(out, ImageFormat::Png))?,
    )
}

/// Writes a 16-bit gray PNG: linear map of `[lo, hi]` to `[0, 65535]`, clipped, rounded; NaN is 0.
pub fn write_gray16(path: &Path, image: &Raster, lo: f64, hi: f64) -> Result<()> {
    check_range(path, lo, hi)?;
    let (w, h) = check_raster(path, image)?;
    let px: Vec<u16> = image
        .data
        .iter()
        .map(|&v| quantize(v, lo, hi, 65535.0) as u16)
        .collect();
    let buf: ImageBuffer<Luma<u16>, Vec<u16>> = ImageBuffer::from_raw(w, h, px)
        .ok_or_else(|| Error::input("image buffer size mismatch").in_file(path))?;
    write_atomic(
        path,
        &encode(path, |out| buf.write_to(out, ImageFormat::Png))?,
    )
}

/// Writes an 8-bit RGB PNG from row-major RGB bytes (3 per pixel).
pub fn write_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    dims(path, width as usize, height as usize)?;
    let expected = width as usize * height as usize * 3;
    if rgb.len() != expected {
        return Err(Error::input(format!(
            "an RGB image of {width}×{height} needs {expected} bytes, got {}",
            rgb.len()
        ))
        .in_file(path));
    }
    let buf: ImageBuffer<Rgb<u8>, &[u8]> = ImageBuffer::from_raw(width, height, rgb)
        .ok_or_else(|| Error::input("image buffer size mismatch").in_file(path))?;
    write_atomic(
        path,
        &encode(path, |out| buf.write_to(out, ImageFormat::Png))?,
    )
}

/// Runs an encoder into memory, so that the file itself is written in one atomic step.
fn encode(
    path: &Path,
    f: impl FnOnce(&mut Cursor<Vec<u8>>) -> image::ImageResult<()>,
) -> Result<Vec<u8>> {
    let mut out = Cursor::new(Vec::new());
    f(&mut out).map_err(|e| Error::write(path, std::io::Error::other(e.to_string())))?;
    Ok(out.into_inner())
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
