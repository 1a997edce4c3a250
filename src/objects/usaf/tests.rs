use super::*;

fn full_chart(polarity: Polarity) -> UsafChart {
    UsafChart::new(MIN_SUPPORTED_GROUP, MAX_SUPPORTED_GROUP, polarity).unwrap()
}

#[test]
fn bar_widths_match_the_paper() {
    // The paper's widths (Experiments section), in µm.
    let paper = [
        (-1, 5, 629.96),
        (-1, 6, 561.23),
        (0, 4, 353.55),
        (0, 5, 314.98),
        (0, 6, 280.62),
    ];
    let chart = UsafChart::thorlabs_r3l3s1n();
    for (g, e, w_um) in paper {
        let bars: Vec<Bar> = chart
            .bars()
            .into_iter()
            .filter(|b| b.group == g && b.element == e)
            .collect();
        assert_eq!(bars.len(), 6);
        assert_eq!(bars.iter().filter(|b| b.horizontal).count(), 3);
        for b in &bars {
            let measured_um = b.width_mm() * 1e3;
            // The paper quotes two decimals, so the rounding error is at most 0.005 µm.
            assert!(
                (measured_um - w_um).abs() <= 0.005 + 1e-9,
                "group {g} element {e}: {measured_um} µm vs {w_um} µm"
            );
            assert!((b.width_mm() - bar_width_mm(g, e)).abs() < 1e-12);
        }
    }
}

#[test]
fn bars_are_five_widths_long_and_oriented() {
    for b in full_chart(Polarity::Negative).bars() {
        let w = bar_width_mm(b.group, b.element);
        let (dx, dy) = (b.x1_mm - b.x0_mm, b.y1_mm - b.y0_mm);
        let (long, short) = if b.horizontal { (dx, dy) } else { (dy, dx) };
        assert!((short - w).abs() <= 1e-12 * w.max(1.0), "{b:?}");
        assert!((long - 5.0 * w).abs() <= 1e-12 * w.max(1.0), "{b:?}");
    }
}

#[test]
fn bars_in_a_triplet_are_one_width_apart() {
    let chart = full_chart(Polarity::Negative);
    let bars = chart.bars();
    for chunk in bars.chunks(3) {
        let w = bar_width_mm(chunk[0].group, chunk[0].element);
        let mut starts: Vec<f64> = chunk
            .iter()
            .map(|b| if b.horizontal { b.y0_mm } else { b.x0_mm })
            .collect();
        starts.sort_by(f64::total_cmp);
        for pair in starts.windows(2) {
            // Period = bar + space = 2w.
            assert!((pair[1] - pair[0] - 2.0 * w).abs() < 1e-12 * w.max(1.0));
        }
    }
}

#[test]
fn no_two_bars_overlap_and_all_fit_on_the_plate() {
    let bars = full_chart(Polarity::Negative).bars();
    assert_eq!(bars.len(), 12 * 6 * 6);
    for (i, a) in bars.iter().enumerate() {
        for b in &bars[i + 1..] {
            let ox = overlap(a.x0_mm, a.x1_mm, b.x0_mm, b.x1_mm);
            let oy = overlap(a.y0_mm, a.y1_mm, b.y0_mm, b.y1_mm);
            assert!(ox * oy == 0.0, "{a:?} overlaps {b:?}");
        }
        let half = 0.5 * PLATE_SIDE_MM;
        assert!(a.x0_mm > -half && a.x1_mm < half && a.y0_mm > -half && a.y1_mm < half);
    }
}

#[test]
fn elements_of_different_groups_do_not_overlap() {
    // Stronger than bar disjointness: whole element boxes are apart, so no element's
    // bars interleave with another's.
    let mut boxes = Vec::new();
    for g in MIN_SUPPORTED_GROUP..=MAX_SUPPORTED_GROUP {
        for e in 1..=6 {
            boxes.push(((g, e), element_box(g, e).unwrap()));
        }
    }
    for (i, (ka, a)) in boxes.iter().enumerate() {
        for (kb, b) in &boxes[i + 1..] {
            let ox = overlap(a.x0_mm(), a.x1_mm(), b.x0_mm(), b.x1_mm());
            let oy = overlap(a.y0_mm(), a.y1_mm(), b.y0_mm(), b.y1_mm());
            assert!(ox * oy == 0.0, "{ka:?} box overlaps {kb:?}");
        }
    }
}

#[test]
fn outer_layer_is_centred_on_the_plate() {
    let outer = UsafChart::new(-2, -1, Polarity::Negative).unwrap();
    let b = bbox(&outer.bars());
    let half = 2.0 * field_side();
    for (v, want) in b.iter().zip([-half, -half, half, half]) {
        assert!((v - want).abs() < 1e-12, "{b:?}");
    }
    assert!((half - 23.958).abs() < 5e-4);
}

#[test]
fn layout_follows_the_spiral() {
    // Even group: element 1 at the lower right, 2..6 down the left column; odd group down
    // the right column from the top. Checked on the outer layer's element centres.
    let c = |g, e| element_box(g, e).unwrap();
    assert!(c(-2, 1).center_x_mm > 0.0 && c(-2, 1).center_y_mm < -15.0);
    for e in 2..=6 {
        assert!(c(-2, e).center_x_mm < -10.0);
        if e > 2 {
            assert!(c(-2, e).center_y_mm < c(-2, e - 1).center_y_mm);
        }
    }
    for e in 1..=6 {
        assert!(c(-1, e).center_x_mm > 15.0);
        if e > 1 {
            assert!(c(-1, e).center_y_mm < c(-1, e - 1).center_y_mm);
        }
    }
    // The odd group's element 1 and the even group's element 2 start at the top.
    assert!((c(-1, 1).y1_mm() - c(-2, 2).y1_mm()).abs() < 1e-12);
    // Each inner layer is the same pattern at a quarter of the size.
    for g in 0..=MAX_SUPPORTED_GROUP {
        for e in 1..=6 {
            let (outer, inner) = (c(g - 2, e), c(g, e));
            assert!((outer.width_mm / inner.width_mm - 4.0).abs() < 1e-12);
        }
    }
}

#[test]
fn render_conserves_area() {
    let chart = full_chart(Polarity::Negative);
    let regions = [
        PaperRegion::Fig6.region(),
        PaperRegion::Fig8b.region(),
        PaperRegion::Fig8c.region(),
        Region::new(0.3, -1.7, 31.0, 17.0).unwrap(),
        Region::new(0.0, 0.0, PLATE_SIDE_MM, PLATE_SIDE_MM).unwrap(),
    ];
    for region in regions {
        for (w, h) in [(48, 48), (96, 96), (37, 53), (1, 1)] {
            let raster = chart.render(&region, w, h);
            let pixel_area = region.area_mm2() / (w * h) as f64;
            let rendered = raster.sum() * pixel_area;
            let exact = chart.bar_area_in(&region);
            assert!(exact > 0.0);
            assert!(
                (rendered - exact).abs() <= 1e-9 * exact,
                "{region:?} {w}×{h}: {rendered} vs {exact}"
            );
            assert!(raster.min() >= 0.0 && raster.max() <= 1.0);
        }
    }
}

#[test]
fn a_pixel_inside_a_bar_is_fully_clear() {
    // A pixel strictly inside one bar: the coverage is 1 up to round-off.
    let chart = full_chart(Polarity::Negative);
    let b = chart.bars()[0];
    let region = Region::from_corners(
        b.x0_mm + 0.1 * b.width_mm(),
        b.y0_mm + 0.1 * b.width_mm(),
        b.x0_mm + 0.2 * b.width_mm(),
        b.y0_mm + 0.2 * b.width_mm(),
    );
    let r = chart.render(&region, 1, 1);
    assert!((r.data[0] - 1.0).abs() < 1e-12);
    // Half a pixel over the left edge of the bar: half covered.
    let half = Region::new(
        b.x0_mm,
        b.center_y(),
        0.1 * b.width_mm(),
        0.1 * b.width_mm(),
    )
    .unwrap();
    let r = chart.render(&half, 2, 1);
    assert!(r.data[0].abs() < 1e-12 && (r.data[1] - 1.0).abs() < 1e-12);
    let r = chart.render(&half, 1, 1);
    assert!((r.data[0] - 0.5).abs() < 1e-12);
}

impl Bar {
    fn center_y(&self) -> f64 {
        0.5 * (self.y0_mm + self.y1_mm)
    }
}

#[test]
fn point_queries_agree_with_the_render() {
    let chart = full_chart(Polarity::Negative);
    let mut checked = 0;
    for region in [
        PaperRegion::Fig6.region(),
        PaperRegion::Fig8c.region(),
        // Around the finest layers (groups 6..9), where the point index is busiest.
        element_box(6, 1)
            .unwrap()
            .union(&element_box(9, 6).unwrap())
            .expanded(0.01),
    ] {
        let (w, h) = (400, 400);
        let raster = chart.render(&region, w, h);
        let dx = region.width_mm / w as f64;
        let dy = region.height_mm / h as f64;
        for r in 0..h {
            for c in 0..w {
                let v = raster.get(r, c);
                let x = region.x0_mm() + (c as f64 + 0.5) * dx;
                let y = region.y1_mm() - (r as f64 + 0.5) * dy;
                if (v - 1.0).abs() < 1e-9 {
                    assert!(chart.is_clear(x, y), "({x}, {y}) should be clear");
                    checked += 1;
                } else if v.abs() < 1e-9 {
                    assert!(!chart.is_clear(x, y), "({x}, {y}) should be chrome");
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 400_000);
}

#[test]
fn point_queries_agree_with_a_linear_scan() {
    // The bucket grid must give exactly the answer of testing every bar, including for
    // partial group ranges. Points: a deterministic low-discrepancy sweep over the field
    // plus every bar's corners (inside and just outside).
    let charts = [
        full_chart(Polarity::Negative),
        UsafChart::new(0, 3, Polarity::Negative).unwrap(),
        UsafChart::new(-1, -1, Polarity::Negative).unwrap(),
        UsafChart::new(5, 9, Polarity::Negative).unwrap(),
    ];
    let all = full_chart(Polarity::Negative).bars();
    let mut points = Vec::new();
    let golden = 0.618_033_988_749_894_9_f64;
    for k in 0..200_000 {
        let u = (k as f64 * golden).fract();
        let v = (k as f64 * 0.754_877_666_246_692_7).fract();
        // Denser near the centre, where the inner layers sit.
        let scale = if k % 2 == 0 { 25.0 } else { 2.0 };
        points.push(((2.0 * u - 1.0) * scale, (2.0 * v - 1.0) * scale));
    }
    for b in &all {
        let eps = 1e-6 * b.width_mm();
        points.push((b.x0_mm, b.y0_mm));
        points.push((b.x1_mm - eps, b.y1_mm - eps));
        points.push((b.x0_mm - eps, b.y0_mm));
        points.push((b.x1_mm, b.y1_mm - eps));
    }
    for chart in &charts {
        let bars = chart.bars();
        for &(x, y) in &points {
            let scan = bars.iter().any(|b| b.contains(x, y));
            assert_eq!(chart.in_bar(x, y), scan, "{chart:?} at ({x}, {y})");
        }
    }
}

#[test]
fn polarity_flips_coverage() {
    let neg = UsafChart::thorlabs_r3l3s1n();
    let pos = UsafChart {
        polarity: Polarity::Positive,
        ..neg.clone()
    };
    let region = PaperRegion::Fig8b.region();
    let (a, b) = (neg.render(&region, 96, 96), pos.render(&region, 96, 96));
    for (n, p) in a.data.iter().zip(&b.data) {
        assert_eq!(*p, 1.0 - n);
    }
    assert!(a.max() == 1.0 || (a.max() - 1.0).abs() < 1e-12);
    for (x, y) in [(20.0, 0.0), (19.0, 2.9), (0.0, 0.0), (-30.0, 30.0)] {
        assert_ne!(neg.is_clear(x, y), pos.is_clear(x, y));
    }
}

#[test]
fn group_range_limits_bars_and_regions() {
    let chart = UsafChart::new(0, 1, Polarity::Negative).unwrap();
    assert!(chart.bars().iter().all(|b| (0..=1).contains(&b.group)));
    assert_eq!(chart.bars().len(), 72);
    assert!(chart.element_region(-1, 5).is_none());
    assert!(chart.element_region(0, 7).is_none());
    assert!(chart.element_region(0, 0).is_none());
    assert!(chart.element_region(1, 6).is_some());
    // A point in a group −1 bar is chrome on a chart without group −1.
    let b = element_bars(-1, 5).unwrap()[0];
    let (x, y) = (0.5 * (b.x0_mm + b.x1_mm), b.center_y());
    assert!(UsafChart::thorlabs_r3l3s1n().is_clear(x, y));
    assert!(!chart.is_clear(x, y));
}

#[test]
fn invalid_ranges_and_regions_are_input_errors() {
    for (lo, hi) in [(-3, 7), (-2, 10), (3, 2)] {
        let e = UsafChart::new(lo, hi, Polarity::Negative).unwrap_err();
        assert!(e.is_user_error(), "{e}");
    }
    for (w, h) in [
        (0.0, 1.0),
        (1.0, -1.0),
        (f64::NAN, 1.0),
        (1.0, f64::INFINITY),
    ] {
        assert!(Region::new(0.0, 0.0, w, h).unwrap_err().is_user_error());
    }
    assert!(Region::new(f64::NAN, 0.0, 1.0, 1.0).is_err());
    // A degenerate region renders as background, without panicking.
    let bad = Region {
        center_x_mm: 0.0,
        center_y_mm: 0.0,
        width_mm: 0.0,
        height_mm: 1.0,
    };
    assert_eq!(UsafChart::thorlabs_r3l3s1n().render(&bad, 4, 4).max(), 0.0);
    assert_eq!(
        UsafChart::thorlabs_r3l3s1n()
            .render(&PaperRegion::Fig6.region(), 0, 3)
            .len(),
        0
    );
}

#[test]
fn paper_regions_hold_their_elements() {
    let chart = UsafChart::thorlabs_r3l3s1n();
    for which in [PaperRegion::Fig6, PaperRegion::Fig8b, PaperRegion::Fig8c] {
        let region = which.region();
        assert!((region.width_mm - region.height_mm).abs() < 1e-12);
        for (g, e) in which.elements() {
            let b = chart.element_region(g, e).unwrap();
            assert!(b.x0_mm() > region.x0_mm() && b.x1_mm() < region.x1_mm());
            assert!(b.y0_mm() > region.y0_mm() && b.y1_mm() < region.y1_mm());
        }
        eprintln!(
            "{which:?}: centre ({:.3}, {:.3}) mm, side {:.3} mm",
            region.center_x_mm, region.center_y_mm, region.width_mm
        );
    }
    // Fig. 6: the paper's "stripes separated by 1.26 mm" is the period of group −1
    // element 5 (2 × 629.96 µm).
    assert!((2.0 * bar_width_mm(-1, 5) - 1.26).abs() < 0.005);
}

#[test]
fn paper_regions_show_only_their_elements() {
    let chart = full_chart(Polarity::Negative);
    for which in [PaperRegion::Fig6, PaperRegion::Fig8b, PaperRegion::Fig8c] {
        let region = which.region();
        let named = which.elements();
        let inner_from = named.iter().map(|&(g, _)| g).max().unwrap() + 1;
        for b in chart.bars() {
            let fraction = b.overlap_area_mm2(&region) / b.area_mm2();
            if named.contains(&(b.group, b.element)) {
                assert_eq!(fraction, 1.0, "{which:?}: {b:?} is cut");
            } else if which == PaperRegion::Fig8c && b.group >= inner_from {
                // Inner layers nested in group 2's field.
                assert_eq!(fraction, 1.0, "{which:?}: {b:?} is cut");
            } else {
                assert_eq!(fraction, 0.0, "{which:?} shows {b:?}");
            }
        }
    }
}

#[test]
fn documented_landmarks_hold() {
    // The coordinates quoted in the module documentation (to 1 µm).
    let union = |list: &[(i32, u8)]| {
        let boxes: Vec<Region> = list
            .iter()
            .map(|&(g, e)| element_box(g, e).unwrap())
            .collect();
        boxes[1..].iter().fold(boxes[0], |u, b| u.union(b))
    };
    let groups_1_to_3: Vec<(i32, u8)> = PaperRegion::Fig8c.elements();
    let mut results = Vec::new();
    for (list, want) in [
        (vec![(-1, 5), (-1, 6)], [16.398, -7.000, 23.958, 0.216]),
        (vec![(0, 4), (0, 5), (0, 6)], [-0.794, -4.462, 3.448, 1.621]),
        (groups_1_to_3, [4.996, -0.223, 11.184, 7.517]),
        (
            (0..=1).flat_map(|g| (1..=6).map(move |e| (g, e))).collect(),
            [-0.794, -4.462, 11.184, 7.517],
        ),
        (
            (2..=3).flat_map(|g| (1..=6).map(move |e| (g, e))).collect(),
            [4.996, 0.412, 7.991, 3.406],
        ),
    ] {
        let u = union(&list);
        let got = [u.x0_mm(), u.y0_mm(), u.x1_mm(), u.y1_mm()];
        results.push((got, want));
    }
    for (which, centre_x, centre_y, side) in [
        (PaperRegion::Fig6, 20.178, -3.392, 8.819),
        (PaperRegion::Fig8b, 1.327, -1.421, 6.790),
        (PaperRegion::Fig8c, 8.893, 3.647, 8.239),
    ] {
        let r = which.region();
        results.push((
            [r.center_x_mm, r.center_y_mm, r.width_mm, r.height_mm],
            [centre_x, centre_y, side, side],
        ));
    }
    for (got, want) in results {
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() < 5e-4, "{got:?} vs {want:?}");
        }
    }
}
