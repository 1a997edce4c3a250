//! Tests of the layout drawing and its irradiance insets.

use super::*;
#[cfg(feature = "figures")]
use crate::trace::fan::ray_fan;

/// The insets' trace refuses a ray count outside two batches … the trace's limit, naming
/// its field. On the paper bench two seeds' spills and centroids agree within 5 combined
/// standard errors (each error from its own trace; an error too small by a factor of ~2
/// would fail this for the 6 numbers), and the errors are positive.
#[test]
fn inset_numbers_agree_between_seeds_within_their_errors() {
    let bench = crate::trace::testing::paper_bench_with_mask();
    for n in [0, 2047, crate::scene::run::MAX_RAYS + 1] {
        let e = Insets::trace(&bench, n, 1).unwrap_err().to_string();
        assert!(e.contains("irradiance_rays"), "{e}");
    }
    let [a, b] = [1, 2].map(|seed| Insets::trace(&bench, 20_480, seed).unwrap());
    for d in 0..2 {
        let (x, y) = (a.stats(d), b.stats(d));
        let pairs = [
            (x.spill, y.spill),
            (x.centroid_m[0], y.centroid_m[0]),
            (x.centroid_m[1], y.centroid_m[1]),
        ];
        for (p, q) in pairs {
            assert!(p.stderr > 0.0 && q.stderr > 0.0, "diode {d}: {x:?}");
            let bound = 5.0 * p.stderr.hypot(q.stderr);
            assert!(
                (p.value - q.value).abs() < bound,
                "diode {d}: {x:?} vs {y:?}"
            );
        }
    }
}

#[test]
fn nice_lengths() {
    assert_eq!(nice_below(73.0), 50.0);
    assert_eq!(nice_below(19.9), 10.0);
    assert_eq!(nice_below(0.25), 0.2);
}

/// The arm-plane view's axes are orthonormal, and the outgoing chief rays of the paper
/// bench lie in its plane: both have no component along e1 × e2.
#[test]
fn arm_plane_contains_both_arms_and_the_incoming_axis() {
    let bench = crate::trace::testing::paper_bench_with_mask();
    let axes = dmd_axes(&bench, DESIGN_WAVELENGTH_M).unwrap();
    let v = &views(&axes)[2];
    assert!(v.e1.dot(v.e2).abs() < 1e-12);
    let n = v.e1.cross(v.e2);
    for d in [axes.outgoing[0], axes.outgoing[1], axes.incoming] {
        assert!(d.dot(n).abs() < 1e-9, "{d:?}");
    }
    // The + arm is to the right: its chief ray has a positive horizontal component.
    assert!(axes.outgoing[0].dot(v.e1) > 0.3);
}

/// The SVG has three views, a path for every ray in each, and renders to a PNG of its size.
#[test]
#[cfg(feature = "figures")]
fn svg_and_png_of_the_test_bench() {
    let bench = crate::trace::testing::bench_with("tests/symmetric_arms.ron", &[]);
    let fan = ray_fan(&bench, 60, 1).unwrap();
    let svg = layout_svg(&bench, &fan, "symmetric <arms> & co").unwrap();
    assert_eq!(svg.matches(r#"class="view""#).count(), 3);
    assert_eq!(svg.matches(r#"class="ray "#).count(), 3 * fan.rays.len());
    assert!(svg.contains("&lt;arms&gt; &amp; co"));
    let png = svg_to_png(&svg).unwrap();
    let img = image::load_from_memory(&png).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let vb: Vec<f64> = doc
        .root_element()
        .attribute("viewBox")
        .unwrap()
        .split(' ')
        .map(|t| t.parse().unwrap())
        .collect();
    // The page's width (7.2 in) at 288 dpi: 2 px per unit.
    assert_eq!(vb[2], 1037.0);
    assert_eq!(f64::from(img.width()), 2.0 * vb[2]);
    // One scale for all views: every scale bar is as long per millimetre.
    let per_mm: Vec<f64> = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("scale-bar"))
        .map(|n| {
            let mm: f64 = n.attribute("data-mm").unwrap().parse().unwrap();
            let d = n.attribute("d").unwrap();
            let xs: Vec<f64> = d
                .split(['M', 'L'])
                .filter_map(|t| t.split_whitespace().next()?.parse().ok())
                .collect();
            (xs[1] - xs[0]) / mm
        })
        .collect();
    assert_eq!(per_mm.len(), 3);
    assert!(
        per_mm.iter().all(|k| (k - per_mm[0]).abs() < 1e-3),
        "{per_mm:?}"
    );
    // Every element is labelled by name once, in the arm plane.
    let names: Vec<String> = crate::optics::outline::element_outlines(&bench)
        .into_iter()
        .map(|o| o.name)
        .collect();
    let labels: Vec<&str> = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("element-label"))
        .filter_map(|n| n.text())
        .collect();
    for name in &names {
        assert_eq!(labels.iter().filter(|l| *l == name).count(), 1, "{name}");
    }
    // The top view is drawn at least MIN_VIEW_HEIGHT high.
    let clip_h = |key: &str| -> f64 {
        doc.descendants()
            .find(|n| n.attribute("id") == Some(&format!("clip-{key}")))
            .and_then(|n| n.first_element_child())
            .and_then(|r| r.attribute("height"))
            .unwrap()
            .parse()
            .unwrap()
    };
    assert!(clip_h("top") >= MIN_VIEW_HEIGHT - 1e-9);
    let rgb = img.to_rgb8();
    // Not blank: some pixels carry ray colours.
    assert!(
        rgb.pixels().any(|p| p.0[2] > 150 && p.0[0] < 100),
        "no blue ray drawn"
    );
}
