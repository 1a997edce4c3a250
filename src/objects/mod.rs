//! Objects to image: the modified Shepp–Logan phantom, the 1951 USAF chart, and image files.
//!
//! Every object is a grayscale [`Raster`] on the [0, 255] scale that the paper's PSNR
//! (10·log₁₀(255²/MSE)) assumes, row 0 at the top. Experiment files name an object with
//! [`ObjectSpec`]; for example, in RON:
//!
//! ```text
//! object: Phantom
//! object: Usaf(region: Fig6)                       // negative chart, groups −2..7
//! object: Usaf(polarity: Positive, region: Elements(group: 0, first: 4, last: 6))
//! object: Usaf(region: Window(center_x_mm: 1.3, center_y_mm: -1.4, width_mm: 7.0, height_mm: 7.0))
//! object: File(path: "../scenes/images/astronaut.png")
//! ```

pub mod image_file;
pub mod phantom;
pub mod usaf;

use std::path::{Path, PathBuf};

use crate::checked::{Count, Finite, NonNegative, Positive, Whole, via};
use crate::error::{Error, Result};
use crate::raster::Raster;
use usaf::{PaperRegion, Polarity, Region, UsafChart};

/// The largest object side, in pixels: far above the DMD's 1024 × 768 mirrors, and small enough
/// that a typing error (an extra digit) fails at once instead of exhausting memory.
pub const MAX_OBJECT_SIDE: usize = 8192;

/// An object for an experiment file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ObjectSpec {
    /// The modified Shepp–Logan phantom (MATLAB `phantom(n)` × 255); square sizes only.
    Phantom,
    /// The analytic 1951 USAF chart: the exact clear-area fraction of each pixel × 255.
    Usaf {
        /// Smallest group on the chart (default −2, as on the Thorlabs R3L3S1N).
        #[serde(default = "default_min_group", deserialize_with = "via::<Group, _, _>")]
        min_group: i32,
        /// Largest group on the chart (default 7).
        #[serde(default = "default_max_group", deserialize_with = "via::<Group, _, _>")]
        max_group: i32,
        /// `Negative` (clear bars in chrome, the paper's target; default) or `Positive`.
        #[serde(default = "default_polarity")]
        polarity: Polarity,
        /// The part of the chart that fills the raster.
        region: UsafRegion,
    },
    /// One of the five test scenes shipped with spibench (`scenes/images/`, licences beside
    /// them), embedded in the binary: `astronaut`, `chelsea`, `coffee`, `rocket`,
    /// `hubble_deep_field`. Resampled like a file.
    TestImage(String),
    /// A PNG or OpenEXR image, resampled by exact area averaging (see [`image_file`]).
    File {
        /// Relative paths resolve against the experiment file's folder.
        path: PathBuf,
    },
}

/// A group of the chart layout (−2 to 9, [`usaf::MIN_SUPPORTED_GROUP`] to
/// [`usaf::MAX_SUPPORTED_GROUP`]).
type Group = Whole<{ usaf::MIN_SUPPORTED_GROUP as i64 }, { usaf::MAX_SUPPORTED_GROUP as i64 }>;

/// An element of a group: 1 to 6.
type Element = Count<1, 6>;

fn default_min_group() -> i32 {
    -2
}

fn default_max_group() -> i32 {
    7
}

fn default_polarity() -> Polarity {
    Polarity::Negative
}

/// Which part of the USAF chart an object shows.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum UsafRegion {
    /// The paper's Figs. 6a and 8a: group −1 elements 5–6 ([`PaperRegion::Fig6`]).
    Fig6,
    /// The paper's Fig. 8b: group 0 elements 4–6 ([`PaperRegion::Fig8b`]).
    Fig8b,
    /// The paper's Fig. 8c: groups 1–3 ([`PaperRegion::Fig8c`]).
    Fig8c,
    /// The square around elements `first..=last` of `group`, with `margin_mm` on every side
    /// (default: one bar width of element `first`).
    Elements {
        /// The group.
        #[serde(deserialize_with = "via::<Group, _, _>")]
        group: i32,
        /// Its first element.
        #[serde(deserialize_with = "via::<Element, _, _>")]
        first: u8,
        /// Its last element.
        #[serde(deserialize_with = "via::<Element, _, _>")]
        last: u8,
        /// The margin on every side (mm).
        #[serde(default, deserialize_with = "via::<Option<NonNegative>, _, _>")]
        margin_mm: Option<f64>,
    },
    /// An explicit window in chart millimetres (origin at the plate centre, y up).
    Window {
        /// The window's centre, x (mm).
        #[serde(deserialize_with = "via::<Finite, _, _>")]
        center_x_mm: f64,
        /// The window's centre, y (mm).
        #[serde(deserialize_with = "via::<Finite, _, _>")]
        center_y_mm: f64,
        /// Its width (mm).
        #[serde(deserialize_with = "via::<Positive, _, _>")]
        width_mm: f64,
        /// Its height (mm).
        #[serde(deserialize_with = "via::<Positive, _, _>")]
        height_mm: f64,
    },
}

impl UsafRegion {
    /// The chart window, validated against the chart's group range.
    pub fn resolve(&self, chart: &UsafChart) -> Result<Region> {
        let region = match self {
            UsafRegion::Fig6 => PaperRegion::Fig6.region(),
            UsafRegion::Fig8b => PaperRegion::Fig8b.region(),
            UsafRegion::Fig8c => PaperRegion::Fig8c.region(),
            UsafRegion::Elements {
                group,
                first,
                last,
                margin_mm,
            } => {
                if !(1..=6).contains(first) || !(1..=6).contains(last) || first > last {
                    return Err(Error::field(
                        "last",
                        format!("elements run from 1 to 6 with first ≤ last, got {first}..={last}"),
                    ));
                }
                let boxes: Vec<Region> = (*first..=*last)
                    .map(|e| chart.element_region(*group, e))
                    .collect::<Option<_>>()
                    .ok_or_else(|| {
                        Error::field(
                            "group",
                            format!(
                                "group {group} is not on a chart with groups {} to {}",
                                chart.min_group, chart.max_group
                            ),
                        )
                    })?;
                let margin = margin_mm.unwrap_or_else(|| usaf::bar_width_mm(*group, *first));
                if !(margin.is_finite() && margin >= 0.0) {
                    return Err(Error::field(
                        "margin_mm",
                        format!("the margin must be finite and not negative, got {margin}"),
                    ));
                }
                Region::square_around(&boxes, margin).expect("at least one element")
            }
            UsafRegion::Window {
                center_x_mm,
                center_y_mm,
                width_mm,
                height_mm,
            } => Region::new(*center_x_mm, *center_y_mm, *width_mm, *height_mm)?,
        };
        region.validate()?;
        Ok(region)
    }
}

fn check_size(width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_OBJECT_SIDE || height > MAX_OBJECT_SIDE {
        return Err(Error::input(format!(
            "cannot make a {width}×{height} object: each side must be between 1 and \
             {MAX_OBJECT_SIDE} pixels"
        )));
    }
    Ok(())
}

/// Renders an object to a `width`×`height` raster with values in [0, 255].
///
/// `base_dir` is the folder of the experiment file: relative image paths resolve against it.
/// The shipped test scenes (256×256 8-bit grey, free of copyright restrictions; see
/// `scenes/images/LICENSES.md`).
pub const TEST_IMAGES: &[(&str, &[u8])] = &[
    (
        "astronaut",
        include_bytes!("../../scenes/images/astronaut.png"),
    ),
    ("chelsea", include_bytes!("../../scenes/images/chelsea.png")),
    ("coffee", include_bytes!("../../scenes/images/coffee.png")),
    ("rocket", include_bytes!("../../scenes/images/rocket.png")),
    (
        "hubble_deep_field",
        include_bytes!("../../scenes/images/hubble_deep_field.png"),
    ),
];

/// The PNG bytes of a shipped test scene.
pub fn test_image(name: &str) -> Result<&'static [u8]> {
    TEST_IMAGES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, b)| *b)
        .ok_or_else(|| {
            let names: Vec<&str> = TEST_IMAGES.iter().map(|(n, _)| *n).collect();
            Error::field(
                "TestImage",
                format!(
                    "no test image {name:?}; the shipped ones are {}",
                    names.join(", ")
                ),
            )
        })
}

pub fn render_object(
    spec: &ObjectSpec,
    width: usize,
    height: usize,
    base_dir: &Path,
) -> Result<Raster> {
    check_size(width, height)?;
    match spec {
        ObjectSpec::Phantom => phantom::phantom_sized(width, height, true),
        ObjectSpec::Usaf {
            min_group,
            max_group,
            polarity,
            region,
        } => {
            let chart = UsafChart::new(*min_group, *max_group, *polarity)?;
            let region = region.resolve(&chart).map_err(|e| e.at_field("region"))?;
            Ok(chart.render(&region, width, height).map(|v| 255.0 * v))
        }
        ObjectSpec::TestImage(name) => {
            let bytes = test_image(name)?;
            let source = image_file::decode_gray(bytes)
                .map_err(|e| e.at_field(format!("TestImage({name})")))?;
            image_file::resize_area(&source, width, height)
        }
        ObjectSpec::File { path } => {
            let full = if path.is_absolute() {
                path.clone()
            } else {
                base_dir.join(path)
            };
            image_file::load_image(&full, width, height)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_ron;

    fn parse(text: &str) -> Result<ObjectSpec> {
        parse_ron(text, Path::new("experiment.ron"))
    }

    #[test]
    fn specs_parse_from_ron_with_defaults() {
        assert_eq!(parse("Phantom").unwrap(), ObjectSpec::Phantom);
        assert_eq!(
            parse("Usaf(region: Fig6)").unwrap(),
            ObjectSpec::Usaf {
                min_group: -2,
                max_group: 7,
                polarity: Polarity::Negative,
                region: UsafRegion::Fig6
            }
        );
        assert_eq!(
            parse("Usaf(polarity: Positive, min_group: 0, region: Elements(group: 0, first: 4, last: 6))")
                .unwrap(),
            ObjectSpec::Usaf {
                min_group: 0,
                max_group: 7,
                polarity: Polarity::Positive,
                region: UsafRegion::Elements { group: 0, first: 4, last: 6, margin_mm: None }
            }
        );
        assert_eq!(
            parse("File(path: \"a/b.png\")").unwrap(),
            ObjectSpec::File {
                path: "a/b.png".into()
            }
        );
    }

    #[test]
    fn unknown_fields_are_rejected_with_their_name() {
        for (text, field) in [
            ("Usaf(region: Fig6, colour: 3)", "colour"),
            ("File(path: \"x.png\", scale: 2)", "scale"),
            (
                "Usaf(region: Window(center_x_mm: 0, center_y_mm: 0, width_mm: 1, height_mm: 1, depth_mm: 1))",
                "depth_mm",
            ),
        ] {
            let e = parse(text).unwrap_err();
            let Error::Input { location, .. } = &e else {
                panic!("{e}")
            };
            // The field's full path ends with the field's name (`region.depth_mm`).
            let named = location
                .field
                .as_deref()
                .is_some_and(|f| f == field || f.ends_with(&format!(".{field}")));
            assert!(named, "{e}");
        }
        assert!(parse("Sphere").is_err());
    }

    #[test]
    fn renders_every_kind_in_range() {
        let base = Path::new(env!("CARGO_MANIFEST_DIR"));
        let specs = [
            ObjectSpec::Phantom,
            parse("Usaf(region: Fig6)").unwrap(),
            parse("Usaf(region: Fig8c, max_group: 9)").unwrap(),
            parse("File(path: \"scenes/images/coffee.png\")").unwrap(),
        ];
        for spec in &specs {
            let r = render_object(spec, 48, 48, base).unwrap();
            assert_eq!((r.width, r.height), (48, 48));
            assert!(r.min() >= 0.0 && r.max() <= 255.0, "{spec:?}");
            assert!(r.max() > 100.0, "{spec:?} is too dark");
        }
        // The USAF object is the chart's clear fraction × 255.
        let chart = UsafChart::thorlabs_r3l3s1n();
        let want = chart.render(&PaperRegion::Fig6.region(), 48, 48);
        let got = render_object(&specs[1], 48, 48, base).unwrap();
        for (g, w) in got.data.iter().zip(&want.data) {
            assert_eq!(*g, 255.0 * w);
        }
        // Absolute paths ignore the base folder.
        let abs = ObjectSpec::File {
            path: base.join("scenes/images/rocket.png"),
        };
        assert!(render_object(&abs, 32, 32, Path::new("/nonexistent")).is_ok());
    }

    #[test]
    fn elements_region_is_the_square_around_them() {
        let chart = UsafChart::thorlabs_r3l3s1n();
        let r = UsafRegion::Elements {
            group: 0,
            first: 4,
            last: 6,
            margin_mm: None,
        }
        .resolve(&chart)
        .unwrap();
        assert_eq!(r, PaperRegion::Fig8b.region());
    }

    #[test]
    fn bad_specs_are_input_errors() {
        let base = Path::new(env!("CARGO_MANIFEST_DIR"));
        let cases = [
            (parse("Phantom").unwrap(), 64, 32),
            (parse("Phantom").unwrap(), 0, 0),
            (parse("Usaf(region: Fig6)").unwrap(), MAX_OBJECT_SIDE + 1, 4),
            (
                parse("Usaf(region: Fig6, min_group: 3, max_group: 1)").unwrap(),
                8,
                8,
            ),
            (
                parse("Usaf(region: Elements(group: 0, first: 5, last: 4))").unwrap(),
                8,
                8,
            ),
            (
                parse("Usaf(region: Elements(group: 8, first: 1, last: 2))").unwrap(),
                8,
                8,
            ),
            (
                parse("File(path: \"scenes/images/nothing.png\")").unwrap(),
                8,
                8,
            ),
            (parse("File(path: \"Cargo.toml\")").unwrap(), 8, 8),
        ];
        for (spec, w, h) in &cases {
            let e = render_object(spec, *w, *h, base).unwrap_err();
            assert!(e.is_user_error(), "{spec:?}: {e}");
        }
        let e = render_object(&cases[5].0, 8, 8, base).unwrap_err();
        assert!(e.to_string().contains("group"), "{e}");
        // A number out of its own range is refused while reading, naming its field.
        for (text, field) in [
            ("Usaf(region: Fig6, min_group: -3)", "min_group"),
            (
                "Usaf(region: Elements(group: 12, first: 1, last: 2))",
                "group",
            ),
            (
                "Usaf(region: Elements(group: 0, first: 0, last: 2))",
                "first",
            ),
            (
                "Usaf(region: Elements(group: 0, first: 1, last: 2, margin_mm: -1))",
                "margin_mm",
            ),
            (
                "Usaf(region: Window(center_x_mm: 0, center_y_mm: 0, width_mm: 0, height_mm: 1))",
                "width_mm",
            ),
            (
                "Usaf(region: Window(center_x_mm: NaN, center_y_mm: 0, width_mm: 1, height_mm: 1))",
                "center_x_mm",
            ),
        ] {
            let e = parse(text).unwrap_err();
            assert!(e.is_user_error(), "{text}: {e}");
            assert!(e.to_string().contains(&format!("{field}`")), "{text}: {e}");
        }
    }
}
