//! OpenEXR output of f32 maps with any number of named channels (for example the per-mirror
//! transport maps `k_plus` and `k_minus`), losslessly compressed (ZIP, `SMALL_LOSSLESS`), and
//! the matching reader. Samples are row-major (`index = y · width + x`); EXR requires channels
//! sorted by name, so files hold them in that order whatever order the caller gives
//! (docs/rust-notes.md §5).

use std::io::Cursor;
use std::path::Path;

use ::exr::prelude::*;

use super::npy::write_atomic;
use crate::error::{Error, Result};

/// Channels as read: `(name, row-major samples)` in file order.
pub type NamedChannels = Vec<(String, Vec<f32>)>;

fn bad(path: &Path, msg: impl Into<String>) -> Error {
    Error::input(msg.into()).in_file(path)
}

/// Writes one EXR layer named "spibench" of `width × height` pixels with the given f32 channels.
/// Every channel must hold exactly `width · height` samples; names must be distinct, non-empty
/// printable ASCII. Values (including NaN and ±∞) are stored bit-exactly.
pub fn write_channels(
    path: &Path,
    width: usize,
    height: usize,
    channels: &[(&str, &[f32])],
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(bad(
            path,
            format!("a {width}×{height} EXR image has no pixels"),
        ));
    }
    let pixels = width
        .checked_mul(height)
        .filter(|&n| n <= i32::MAX as usize)
        .ok_or_else(|| bad(path, format!("a {width}×{height} EXR image is too large")))?;
    if channels.is_empty() {
        return Err(bad(path, "an EXR image needs at least one channel"));
    }
    let mut list = SmallVec::<[AnyChannel<FlatSamples>; 4]>::new();
    for (i, (name, samples)) in channels.iter().enumerate() {
        if name.is_empty() || !name.chars().all(|c| c.is_ascii_graphic() || c == ' ') {
            return Err(bad(
                path,
                format!("EXR channel name {name:?} must be non-empty printable ASCII"),
            ));
        }
        if channels[..i].iter().any(|(other, _)| other == name) {
            return Err(bad(path, format!("EXR channel {name:?} is given twice")));
        }
        if samples.len() != pixels {
            return Err(bad(
                path,
                format!(
                    "EXR channel {name:?} holds {} samples, but {width}×{height} needs {pixels}",
                    samples.len()
                ),
            ));
        }
        let text = Text::new_or_none(name).ok_or_else(|| {
            bad(
                path,
                format!("EXR channel name {name:?} is not representable"),
            )
        })?;
        list.push(AnyChannel::new(text, FlatSamples::F32(samples.to_vec())));
    }
    let layer = Layer::new(
        (width, height),
        LayerAttributes::named("spibench"),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut out)
        .map_err(|e| Error::write(path, std::io::Error::other(e.to_string())))?;
    write_atomic(path, &out.into_inner())
}

/// Reads the first layer of an EXR file at its largest resolution: `(width, height, channels)`
/// with channels in file order (sorted by name) and samples row-major. f16 samples widen to f32
/// exactly; u32 samples convert to the nearest f32 (exact up to 2²⁴).
pub fn read_channels(path: &Path) -> Result<(usize, usize, NamedChannels)> {
    let bytes = std::fs::read(path).map_err(|e| Error::read(path, e))?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| bad(path, format!("not a readable OpenEXR file: {e}")))?;
    let layer = image
        .layer_data
        .into_iter()
        .next()
        .ok_or_else(|| bad(path, "the OpenEXR file has no layer"))?;
    let (width, height) = (layer.size.x(), layer.size.y());
    let channels = layer
        .channel_data
        .list
        .into_iter()
        .map(|ch| {
            let samples = match ch.sample_data {
                FlatSamples::F32(v) => v,
                FlatSamples::F16(v) => v.into_iter().map(f32::from).collect(),
                FlatSamples::U32(v) => v.into_iter().map(|x| x as f32).collect(),
            };
            (ch.name.to_string(), samples)
        })
        .collect();
    Ok((width, height, channels))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory for one test (tests run in parallel), removed by the test at its end.
    fn scratch(test: &str) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("spibench-exr-test-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn two_channels_round_trip_bit_exact_and_sorted() {
        let dir = scratch("two_channels_round_trip_bit_exact_and_sorted");
        let (w, h) = (7usize, 3usize);
        // Values that a lossy or f16 path would change: tiny, huge, negative zero, NaN, ∞.
        let zed: Vec<f32> = (0..w * h)
            .map(|i| match i {
                0 => f32::NAN,
                1 => -0.0,
                2 => f32::INFINITY,
                3 => f32::MIN_POSITIVE,
                _ => (i as f32 * 0.1234567).sin() * 1e6,
            })
            .collect();
        let alpha: Vec<f32> = (0..w * h).map(|i| 1.0 / (i as f32 + 3.0)).collect();
        let path = dir.join("two.exr");
        // Given out of order: the file must hold them sorted.
        write_channels(&path, w, h, &[("zed", &zed), ("alpha", &alpha)]).unwrap();
        let (rw, rh, chans) = read_channels(&path).unwrap();
        assert_eq!((rw, rh), (w, h));
        assert_eq!(chans.len(), 2);
        assert_eq!(chans[0].0, "alpha");
        assert_eq!(chans[1].0, "zed");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&chans[0].1), bits(&alpha));
        assert_eq!(bits(&chans[1].1), bits(&zed));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_channels_are_input_errors() {
        let dir = scratch("bad_channels_are_input_errors");
        let path = dir.join("bad.exr");
        let a = [0.0f32; 6];
        let short = [0.0f32; 5];
        for (w, h, chans) in [
            (3, 2, vec![("a", &short[..])]),
            (3, 2, vec![("a", &a[..]), ("a", &a[..])]),
            (3, 2, vec![("", &a[..])]),
            (3, 2, vec![("k₊", &a[..])]),
            (0, 2, vec![("a", &a[..])]),
            (3, 2, vec![]),
        ] {
            let e = write_channels(&path, w, h, &chans).unwrap_err();
            assert!(e.is_user_error());
            assert!(e.to_string().contains("bad.exr"), "{e}");
        }
        assert!(!path.exists());
        let garbage = dir.join("garbage.exr");
        std::fs::write(&garbage, b"not an exr file at all").unwrap();
        let e = read_channels(&garbage).unwrap_err();
        assert!(e.to_string().contains("garbage.exr"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
