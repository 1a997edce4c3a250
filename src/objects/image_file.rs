//! Grayscale objects from image files (PNG, JPEG, OpenEXR or NumPy `.npy`), resampled by exact
//! area averaging.
//!
//! # Values
//!
//! Objects are on the [0, 255] scale of the paper's PSNR (255²/MSE):
//! - 8-bit PNG: the stored code values as they are (0..=255);
//! - 16-bit PNG: code value / 257, which maps 65535 to exactly 255 and keeps 8-bit images
//!   stored in 16 bits (v·257) unchanged;
//! - colour PNG: luminance Y = 0.2125 R + 0.7154 G + 0.0721 B (ITU-R BT.709 primaries, the
//!   weights of scikit-image's `rgb2gray`), applied to the stored, gamma-encoded code values
//!   as `rgb2gray` does, then scaled as above; alpha is ignored (a transparent pixel keeps its
//!   colour), because an object's transmittance is not a compositing question;
//! - JPEG (baseline or progressive, 8-bit): as 8-bit PNG, grey or colour;
//! - EXR: the channel named `Y` if there is one, else the mean of `R`, `G` and `B`, else the
//!   only channel; values are taken as stored (no exposure or transfer curve) and must already
//!   lie in [0, 255]; anything else is an input error rather than a silent clip;
//! - `.npy`: a 2-D array (rows, columns) of any numeric dtype spibench reads (float64, float32,
//!   uint8, int64, bool), values as stored, which must lie in [0, 255] like EXR's: an object
//!   array computed in numpy goes in without an image codec on the way.
//!
//! The format is recognised by the file's signature bytes, not its name.
//!
//! # Resampling
//!
//! [`resize_area`] is exact box resampling: target pixel j of a row spans source columns
//! [j·S/T, (j + 1)·S/T) (S source, T target pixels), and its value is the area-weighted mean
//! of the source pixels it overlaps, with overlaps computed in integers (units of 1/T source
//! pixel), so the weights are exact rationals and the mean of the image is conserved to
//! round-off. Enlarging gives a pixel-replicating (nearest with shared edge pixels) result.

use std::io::Cursor;
use std::path::Path;

use crate::error::{Error, Result};
use crate::raster::Raster;

/// BT.709 luma weights for R, G and B (scikit-image `rgb2gray`).
pub const REC709_LUMA: [f64; 3] = [0.2125, 0.7154, 0.0721];

const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";
const EXR_SIGNATURE: &[u8] = &[0x76, 0x2f, 0x31, 0x01];
const NPY_SIGNATURE: &[u8] = b"\x93NUMPY";
/// JPEG's start-of-image marker followed by the first marker's 0xFF.
const JPEG_SIGNATURE: &[u8] = &[0xFF, 0xD8, 0xFF];

/// Reads an image file as a grayscale raster at its own size, values in [0, 255].
///
/// Errors: [`Error::Io`] (read) if the file cannot be read; [`Error::Input`] naming the file if
/// it is neither PNG nor EXR, cannot be decoded, or holds values the rules above reject.
pub fn load_gray(path: &Path) -> Result<Raster> {
    let bytes = std::fs::read(path).map_err(|e| Error::read(path, e))?;
    decode_gray(&bytes).map_err(|e| e.in_file(path))
}

/// Decodes PNG, OpenEXR or `.npy` bytes (detected from the first bytes) to grey levels in
/// [0, 255].
pub fn decode_gray(bytes: &[u8]) -> Result<Raster> {
    if bytes.starts_with(PNG_SIGNATURE) {
        decode_png(bytes)
    } else if bytes.starts_with(EXR_SIGNATURE) {
        decode_exr(bytes)
    } else if bytes.starts_with(NPY_SIGNATURE) {
        decode_npy(bytes)
    } else if bytes.starts_with(JPEG_SIGNATURE) {
        decode_jpeg(bytes)
    } else {
        Err(Error::input(
            "not a PNG, JPEG, OpenEXR or .npy image (unrecognised file signature)",
        ))
    }
}

/// A 2-D `.npy` array as an image (module documentation).
fn decode_npy(bytes: &[u8]) -> Result<Raster> {
    let a = crate::npy::parse(bytes)
        .map_err(|m| Error::input(format!("not a readable .npy array: {m}")))?;
    let [rows, cols] = a.shape[..] else {
        return Err(Error::input(format!(
            "a .npy object must be a 2-D array (rows, columns), got shape {:?}",
            a.shape
        )));
    };
    if rows == 0 || cols == 0 {
        return Err(Error::input("the .npy object is empty"));
    }
    let data = a.to_f64();
    if let Some(i) = data.iter().position(|v| !(0.0..=255.0).contains(v)) {
        return Err(Error::input(format!(
            "the .npy object has the value {} at row {}, column {}: objects are grey levels in \
             [0, 255] (scale a [0, 1] transmittance by 255)",
            data[i],
            i / cols,
            i % cols
        )));
    }
    Raster::new(cols, rows, data)
}

/// Reads an image file and resamples it to `width`×`height` by exact area averaging.
pub fn load_image(path: &Path, width: usize, height: usize) -> Result<Raster> {
    check_target(width, height).map_err(|e| e.in_file(path))?;
    let source = load_gray(path)?;
    resize_area(&source, width, height).map_err(|e| e.in_file(path))
}

fn check_target(width: usize, height: usize) -> Result<()> {
    let max = super::MAX_OBJECT_SIDE;
    if width == 0 || height == 0 || width > max || height > max {
        return Err(Error::input(format!(
            "cannot make a {width}×{height} object: each side must be between 1 and {max} pixels"
        )));
    }
    Ok(())
}

fn decode_png(bytes: &[u8]) -> Result<Raster> {
    decode_with(bytes, image::ImageFormat::Png, "PNG")
}

/// JPEG: 8-bit code values as PNG's (luminance of colour images with the same weights, on the
/// stored gamma-encoded values). JPEG is lossy: its 8×8 block artefacts are part of the object.
fn decode_jpeg(bytes: &[u8]) -> Result<Raster> {
    decode_with(bytes, image::ImageFormat::Jpeg, "JPEG")
}

fn decode_with(bytes: &[u8], format: image::ImageFormat, name: &str) -> Result<Raster> {
    use image::DynamicImage as D;
    let img = image::load_from_memory_with_format(bytes, format)
        .map_err(|e| Error::input(format!("cannot decode the {name} image: {e}")))?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let luma =
        |r: f64, g: f64, b: f64| REC709_LUMA[0] * r + REC709_LUMA[1] * g + REC709_LUMA[2] * b;
    let data: Vec<f64> = match &img {
        D::ImageLuma8(b) => b.pixels().map(|p| f64::from(p.0[0])).collect(),
        D::ImageLumaA8(b) => b.pixels().map(|p| f64::from(p.0[0])).collect(),
        D::ImageRgb8(b) => b
            .pixels()
            .map(|p| luma(p.0[0].into(), p.0[1].into(), p.0[2].into()))
            .collect(),
        D::ImageRgba8(b) => b
            .pixels()
            .map(|p| luma(p.0[0].into(), p.0[1].into(), p.0[2].into()))
            .collect(),
        D::ImageLuma16(b) => b.pixels().map(|p| f64::from(p.0[0]) / 257.0).collect(),
        D::ImageLumaA16(b) => b.pixels().map(|p| f64::from(p.0[0]) / 257.0).collect(),
        D::ImageRgb16(b) => b
            .pixels()
            .map(|p| luma(p.0[0].into(), p.0[1].into(), p.0[2].into()) / 257.0)
            .collect(),
        D::ImageRgba16(b) => b
            .pixels()
            .map(|p| luma(p.0[0].into(), p.0[1].into(), p.0[2].into()) / 257.0)
            .collect(),
        // PNG and JPEG decode only to the variants above; anything else goes through f32 RGB
        // in [0, 1].
        other => other
            .to_rgb32f()
            .pixels()
            .map(|p| 255.0 * luma(p.0[0].into(), p.0[1].into(), p.0[2].into()))
            .collect(),
    };
    // Weights sum to 1, so luminance stays in [0, 255] up to one ulp; clamp that away.
    Raster::new(
        w,
        h,
        data.into_iter().map(|v| v.clamp(0.0, 255.0)).collect(),
    )
}

fn decode_exr(bytes: &[u8]) -> Result<Raster> {
    use exr::prelude::{AnyChannel, FlatSamples, ReadChannels, ReadLayers, read};
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| Error::input(format!("cannot decode the OpenEXR image: {e}")))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let channels = &layer.channel_data.list;
    let find = |name: &str| channels.iter().find(|c| c.name == *name);
    let samples = |c: &AnyChannel<FlatSamples>| -> Result<Vec<f64>> {
        let v: Vec<f64> = c.sample_data.values_as_f32().map(f64::from).collect();
        if v.len() != w * h {
            return Err(Error::input(format!(
                "the OpenEXR channel `{}` is subsampled ({} values for {w}×{h} pixels)",
                c.name,
                v.len()
            )));
        }
        Ok(v)
    };
    let data = if let Some(y) = find("Y") {
        samples(y)?
    } else if let (Some(r), Some(g), Some(b)) = (find("R"), find("G"), find("B")) {
        let (r, g, b) = (samples(r)?, samples(g)?, samples(b)?);
        (0..w * h).map(|i| (r[i] + g[i] + b[i]) / 3.0).collect()
    } else if channels.len() == 1 {
        samples(&channels[0])?
    } else {
        let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
        return Err(Error::input(format!(
            "the OpenEXR image has no `Y` channel, no `R`, `G`, `B` channels and more than one \
             channel ({}), so its gray level is ambiguous",
            names.join(", ")
        )));
    };
    if let Some(bad) = data.iter().find(|v| !(0.0..=255.0).contains(*v)) {
        return Err(Error::input(format!(
            "OpenEXR values are used as stored and must lie in [0, 255], found {bad}"
        )));
    }
    Raster::new(w, h, data)
}

/// For each of `target` output pixels along an axis of `source` input pixels: the input pixel
/// indices it overlaps and the exact weights (overlap / output pixel length, summing to 1).
fn axis_weights(source: usize, target: usize) -> Vec<Vec<(usize, f64)>> {
    // Output pixel j covers [j·S, (j + 1)·S) and input pixel k covers [k·T, (k + 1)·T), both
    // in units of 1/T input pixel, so every overlap is an exact integer.
    let (s, t) = (source as u64, target as u64);
    (0..t)
        .map(|j| {
            let (lo, hi) = (j * s, (j + 1) * s);
            let (k0, k1) = (lo / t, hi.div_ceil(t));
            (k0..k1)
                .filter_map(|k| {
                    let ov = hi.min((k + 1) * t).saturating_sub(lo.max(k * t));
                    (ov > 0).then(|| (k as usize, ov as f64 / s as f64))
                })
                .collect()
        })
        .collect()
}

/// Resamples to `width`×`height` by exact area averaging (see the module documentation).
pub fn resize_area(src: &Raster, width: usize, height: usize) -> Result<Raster> {
    check_target(width, height)?;
    if src.width == 0 || src.height == 0 || src.data.len() != src.width * src.height {
        return Err(Error::input(format!(
            "cannot resample a {}×{} image holding {} values",
            src.width,
            src.height,
            src.data.len()
        )));
    }
    if (src.width, src.height) == (width, height) {
        return Ok(src.clone());
    }
    let wx = axis_weights(src.width, width);
    let wy = axis_weights(src.height, height);
    // Rows first: every source row resampled to `width` columns.
    let mut rows = vec![0.0; src.height * width];
    for r in 0..src.height {
        let line = &src.data[r * src.width..(r + 1) * src.width];
        for (c, weights) in wx.iter().enumerate() {
            rows[r * width + c] = weights.iter().map(|&(k, w)| w * line[k]).sum();
        }
    }
    let mut out = Raster::zeros(width, height);
    for (r, weights) in wy.iter().enumerate() {
        for c in 0..width {
            out.data[r * width + c] = weights.iter().map(|&(k, w)| w * rows[k * width + c]).sum();
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// A fresh directory for one test's files (removed at the end of the test).
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(tag: &str) -> Self {
            let dir = std::env::temp_dir()
                .join(format!("spibench-image-file-{tag}-{}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            TempDir(dir)
        }

        fn path(&self, name: &str) -> PathBuf {
            self.0.join(name)
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn mean(r: &Raster) -> f64 {
        r.sum() / r.len() as f64
    }

    #[test]
    fn resize_weights_are_exact() {
        // 3 → 2: each output pixel covers 1.5 inputs.
        let src = Raster::new(3, 1, vec![3.0, 6.0, 9.0]).unwrap();
        let out = resize_area(&src, 2, 1).unwrap();
        assert!((out.data[0] - (3.0 + 0.5 * 6.0) / 1.5).abs() < 1e-12);
        assert!((out.data[1] - (0.5 * 6.0 + 9.0) / 1.5).abs() < 1e-12);
        // 4×4 → 2×2 is the 2×2 block mean.
        let src = Raster::from_fn(4, 4, |r, c| (r * 4 + c) as f64);
        let out = resize_area(&src, 2, 2).unwrap();
        assert_eq!(out.data, vec![2.5, 4.5, 10.5, 12.5]);
        // 2×1 → 4×1 replicates.
        let src = Raster::new(2, 1, vec![1.0, 5.0]).unwrap();
        assert_eq!(
            resize_area(&src, 4, 1).unwrap().data,
            vec![1.0, 1.0, 5.0, 5.0]
        );
    }

    #[test]
    fn resize_conserves_the_mean() {
        let src = Raster::from_fn(37, 23, |r, c| ((r * 31 + c * 17) % 97) as f64 * 2.5);
        for (w, h) in [(5, 7), (48, 48), (96, 11), (1, 1), (37, 23), (74, 46)] {
            let out = resize_area(&src, w, h).unwrap();
            // Sums of at most a few thousand terms of size ≤ 240: round-off ≤ 1e-12 relative.
            assert!(
                (mean(&out) - mean(&src)).abs() <= 1e-12 * mean(&src),
                "{w}×{h}"
            );
            assert!(out.min() >= src.min() - 1e-12 && out.max() <= src.max() + 1e-12);
        }
    }

    #[test]
    fn loads_8_and_16_bit_gray_and_rgb_png() {
        let dir = TempDir::new("png");
        let g8 = image::GrayImage::from_fn(3, 2, |x, y| image::Luma([(x * 100 + y * 7) as u8]));
        g8.save(dir.path("g8.png")).unwrap();
        let r = load_gray(&dir.path("g8.png")).unwrap();
        assert_eq!((r.width, r.height), (3, 2));
        assert_eq!(r.data, vec![0.0, 100.0, 200.0, 7.0, 107.0, 207.0]);

        let g16: image::ImageBuffer<image::Luma<u16>, Vec<u16>> =
            image::ImageBuffer::from_fn(2, 2, |x, y| {
                image::Luma([[0, 257, 65535, 1000][(y * 2 + x) as usize]])
            });
        g16.save(dir.path("g16.png")).unwrap();
        let r = load_gray(&dir.path("g16.png")).unwrap();
        assert_eq!(r.data, vec![0.0, 1.0, 255.0, 1000.0 / 257.0]);

        let rgb = image::RgbImage::from_fn(2, 1, |x, _| {
            if x == 0 {
                image::Rgb([255, 0, 0])
            } else {
                image::Rgb([10, 20, 30])
            }
        });
        rgb.save(dir.path("rgb.png")).unwrap();
        let r = load_gray(&dir.path("rgb.png")).unwrap();
        assert!((r.data[0] - 0.2125 * 255.0).abs() < 1e-12);
        assert!((r.data[1] - (0.2125 * 10.0 + 0.7154 * 20.0 + 0.0721 * 30.0)).abs() < 1e-12);

        let rgba = image::RgbaImage::from_fn(1, 1, |_, _| image::Rgba([255, 255, 255, 0]));
        rgba.save(dir.path("rgba.png")).unwrap();
        let r = load_gray(&dir.path("rgba.png")).unwrap();
        assert_eq!(r.data, vec![255.0]);

        // Resampled on load.
        let r = load_image(&dir.path("g8.png"), 1, 1).unwrap();
        assert!((r.data[0] - (0.0 + 100.0 + 200.0 + 7.0 + 107.0 + 207.0) / 6.0).abs() < 1e-12);
    }

    fn write_exr(path: &Path, w: usize, h: usize, channels: Vec<(&str, Vec<f32>)>) {
        use exr::prelude::{
            AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes,
            WritableImage,
        };
        let list: Vec<AnyChannel<FlatSamples>> = channels
            .into_iter()
            .map(|(name, v)| AnyChannel::new(name, FlatSamples::F32(v)))
            .collect();
        let layer = Layer::new(
            (w, h),
            LayerAttributes::named("object"),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(list.into()),
        );
        Image::from_layer(layer).write().to_file(path).unwrap();
    }

    #[test]
    fn loads_exr_channels_by_rule() {
        let dir = TempDir::new("exr");
        let p = dir.path("y.exr");
        write_exr(
            &p,
            2,
            1,
            vec![("R", vec![9.0, 9.0]), ("Y", vec![12.5, 200.0])],
        );
        assert_eq!(load_gray(&p).unwrap().data, vec![12.5, 200.0]);

        let p = dir.path("rgb.exr");
        write_exr(
            &p,
            2,
            1,
            vec![
                ("R", vec![3.0, 0.0]),
                ("G", vec![6.0, 0.0]),
                ("B", vec![9.0, 255.0]),
                ("A", vec![1.0, 1.0]),
            ],
        );
        assert_eq!(load_gray(&p).unwrap().data, vec![6.0, 85.0]);

        let p = dir.path("one.exr");
        write_exr(&p, 1, 2, vec![("transmittance", vec![0.25, 100.0])]);
        let r = load_gray(&p).unwrap();
        assert_eq!(
            (r.width, r.height, r.data.clone()),
            (1, 2, vec![0.25, 100.0])
        );

        let p = dir.path("two.exr");
        write_exr(&p, 1, 1, vec![("a", vec![1.0]), ("b", vec![2.0])]);
        let e = load_gray(&p).unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("two.exr"),
            "{e}"
        );

        let p = dir.path("range.exr");
        write_exr(&p, 1, 1, vec![("Y", vec![300.0])]);
        let e = load_gray(&p).unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("[0, 255]"),
            "{e}"
        );
    }

    #[test]
    fn astronaut_at_128_is_the_2x2_block_mean() {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/images/astronaut.png"
        ));
        let r = load_image(path, 128, 128).unwrap();
        assert_eq!((r.width, r.height), (128, 128));
        // Independent decode: 8-bit gray, so the object is the plain 2×2 mean of code values.
        let img = image::open(path).unwrap().to_luma8();
        assert_eq!(img.dimensions(), (256, 256));
        for row in 0..128u32 {
            for col in 0..128u32 {
                let s: f64 = [(0, 0), (0, 1), (1, 0), (1, 1)]
                    .iter()
                    .map(|&(dr, dc)| f64::from(img.get_pixel(2 * col + dc, 2 * row + dr).0[0]))
                    .sum();
                assert_eq!(r.get(row as usize, col as usize), s / 4.0);
            }
        }
        assert!(r.min() >= 0.0 && r.max() <= 255.0 && r.max() > 200.0);
    }

    #[test]
    fn errors_name_the_file() {
        let dir = TempDir::new("errors");
        let missing = dir.path("missing.png");
        let e = load_image(&missing, 8, 8).unwrap_err();
        assert!(
            matches!(e, Error::Io { action: "read", .. }) && e.is_user_error(),
            "{e}"
        );

        let junk = dir.path("junk.png");
        std::fs::write(&junk, b"this is not an image").unwrap();
        let e = load_image(&junk, 8, 8).unwrap_err();
        assert!(
            matches!(e, Error::Input { .. }) && e.to_string().contains("junk.png"),
            "{e}"
        );

        let truncated = dir.path("truncated.png");
        let g = image::GrayImage::from_pixel(16, 16, image::Luma([9]));
        g.save(&truncated).unwrap();
        let bytes = std::fs::read(&truncated).unwrap();
        std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
        let e = load_image(&truncated, 8, 8).unwrap_err();
        assert!(
            matches!(e, Error::Input { .. }) && e.to_string().contains("truncated.png"),
            "{e}"
        );

        let good = dir.path("good.png");
        g.save(&good).unwrap();
        for (w, h) in [(0, 8), (8, 0), (super::super::MAX_OBJECT_SIDE + 1, 8)] {
            let e = load_image(&good, w, h).unwrap_err();
            assert!(
                matches!(e, Error::Input { .. }) && e.to_string().contains("good.png"),
                "{e}"
            );
        }
    }

    /// JPEG objects decode like 8-bit PNG: a uniform grey field comes back at its level (JPEG
    /// codes a flat block exactly up to rounding), a colour one as its BT.709 luminance, and
    /// the size is kept; the signature, not the name, selects the decoder.
    #[test]
    fn loads_gray_and_colour_jpeg() {
        use image::ImageEncoder;
        let encode = |color: image::ExtendedColorType, data: &[u8]| {
            let mut out = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 95)
                .write_image(data, 16, 8, color)
                .unwrap();
            out
        };
        let gray = decode_gray(&encode(image::ExtendedColorType::L8, &[120u8; 128])).unwrap();
        assert_eq!((gray.width, gray.height), (16, 8));
        assert!(
            gray.data.iter().all(|&v| (v - 120.0).abs() <= 1.0),
            "{:?}",
            gray.data
        );
        let rgb: Vec<u8> = (0..128).flat_map(|_| [200u8, 100, 50]).collect();
        let colour = decode_gray(&encode(image::ExtendedColorType::Rgb8, &rgb)).unwrap();
        let y = REC709_LUMA[0] * 200.0 + REC709_LUMA[1] * 100.0 + REC709_LUMA[2] * 50.0;
        // Chroma subsampling and the YCbCr round trip move a flat colour by a few levels.
        assert!(
            colour.data.iter().all(|&v| (v - y).abs() <= 3.0),
            "{y}: {:?}",
            colour.data
        );
        let e = decode_gray(&[0xFF, 0xD8, 0xFF, 0x00]).unwrap_err();
        assert!(e.is_user_error() && e.to_string().contains("JPEG"), "{e}");
    }
}
