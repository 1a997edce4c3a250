use super::concise;

#[test]
fn concise_notation() {
    assert_eq!(concise(0.35313, 0.00031), "0.3531(3)");
    assert_eq!(concise(0.35313, 0.00014), "0.35313(14)");
    assert_eq!(concise(17.14, 0.5), "17.1(5)");
    assert_eq!(concise(1.2345e-6, 1.2e-9), "1.2345(12)×10⁻⁶");
    assert_eq!(concise(-0.0123, 0.0009), "−0.0123(9)");
    assert_eq!(concise(0.02, 0.0), "0.02");
    assert_eq!(concise(0.0, 0.0), "0");
    assert_eq!(concise(0.3, f64::NAN), "0.3 (unresolved)");
    assert_eq!(concise(12345.0, 560.0), "12300(600)");
    assert_eq!(concise(0.1, 0.0996), "0.10(10)");
    assert_eq!(super::eng(0.0, "W"), "0 W");
    assert_eq!(super::eng(1.23456e-3, "W"), "1.2346 mW");
    assert_eq!(super::eng(-4.8e-8, "A"), "−48.000 nA");
    assert_eq!(super::eng(999.9996e-6, "W"), "1.0000 mW");
    assert_eq!(super::eng(2.5, "W"), "2.5000 W");
}

use super::*;
use crate::objects::usaf::{PaperRegion, Polarity, UsafChart};

/// An independent decoder for the tests (also the montage's): RFC 4648 §4 read back bit
/// by bit.
pub(crate) fn decode64(s: &str) -> Vec<u8> {
    let alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut bits: Vec<bool> = Vec::new();
    for c in s.trim_end_matches('=').chars() {
        let v = alphabet.find(c).expect("base64 character");
        for k in (0..6).rev() {
            bits.push((v >> k) & 1 == 1);
        }
    }
    bits.chunks_exact(8)
        .map(|b| b.iter().fold(0u8, |acc, &bit| (acc << 1) | u8::from(bit)))
        .collect()
}

/// The payloads of every `src="data:…;base64,…"` in a page, in order, with their media type.
fn data_uris(html: &str) -> Vec<(String, Vec<u8>)> {
    html.split("src=\"")
        .skip(1)
        .map(|s| {
            let uri = &s[..s.find('"').unwrap()];
            let rest = uri.strip_prefix("data:").expect("only data: URIs");
            let (mime, payload) = rest.split_once(";base64,").unwrap();
            (mime.to_string(), decode64(payload))
        })
        .collect()
}

fn gray_png(w: usize, h: usize) -> Vec<u8> {
    let img = Raster::from_fn(w, h, |r, c| ((r * 7 + c * 3) % 11) as f64);
    png_bytes_gray8(&img, 0.0, 10.0).unwrap()
}

const SVG: &str = r##"<?xml version="1.0" encoding="UTF-8"?>
<!-- a plot -->
<svg width="320" height="160" viewBox="0 0 320 160" xmlns="http://www.w3.org/2000/svg">
<rect x="0" y="0" width="320" height="160" fill="#fff" stroke="#888"/>
<polyline fill="none" stroke="#1f77b4" stroke-width="2" points="20,140 80,100 140,110 200,50 260,60 300,20"/>
<text x="24" y="24" font-family="sans-serif" font-size="14">PSNR / dB &lt;vs&gt; sampling ratio</text>
</svg>"##;

#[test]
fn base64_matches_rfc4648_vectors() {
    // RFC 4648 §10 test vectors.
    for (input, want) in [
        ("", ""),
        ("f", "Zg=="),
        ("fo", "Zm8="),
        ("foo", "Zm9v"),
        ("foob", "Zm9vYg=="),
        ("fooba", "Zm9vYmE="),
        ("foobar", "Zm9vYmFy"),
    ] {
        assert_eq!(base64(input.as_bytes()), want, "{input:?}");
    }
    // The last two alphabet entries and high bytes: 0xfb 0xff 0xbf is 111110 111111
    // 111110 111111 = "+/+/"; 0x00 0x10 0x83 is indices 0, 1, 2, 3 = "ABCD".
    assert_eq!(base64(&[0xfb, 0xff, 0xbf]), "+/+/");
    assert_eq!(base64(&[0x00, 0x10, 0x83]), "ABCD");
}

#[test]
fn base64_round_trips_every_byte_and_length() {
    let bytes: Vec<u8> = (0..=255u8).chain((0..=255u8).rev()).collect();
    for n in 0..bytes.len() {
        let enc = base64(&bytes[..n]);
        assert_eq!(enc.len(), n.div_ceil(3) * 4);
        assert_eq!(decode64(&enc), &bytes[..n], "length {n}");
    }
}

#[test]
fn text_is_escaped_everywhere() {
    let evil = "<script>alert('x')</script> & \"q\" \u{0}";
    let page = Page {
        title: format!("title {evil} </title>"),
        blocks: vec![
            Block::Heading {
                level: 2,
                text: evil.into(),
            },
            Block::Paragraph(evil.into()),
            Block::Table {
                caption: Some(evil.into()),
                header: vec![evil.into(), "n".into()],
                rows: vec![vec![evil.into(), "1.5".into()]],
            },
            Block::Image {
                caption: evil.into(),
                png: gray_png(4, 4),
                alt: "x\" onerror=\"alert(1)".into(),
                width_px: None,
            },
            Block::Svg {
                caption: evil.into(),
                svg: SVG.into(),
            },
            Block::Figures(vec![Block::Paragraph(evil.into())]),
            Block::Preformatted(format!("</pre>{evil}")),
            Block::KeyValues(vec![(evil.into(), evil.into())]),
        ],
    };
    let html = render(&page);
    let lower = html.to_lowercase();
    assert!(!lower.contains("<script"), "{html}");
    assert!(!lower.contains("</script"));
    assert!(!html.contains("\" onerror"));
    assert!(!html.contains('\u{0}'));
    // Title, heading, paragraph, caption, header, cell, figure captions ×2 (+ SVG alt),
    // nested paragraph, pre, key and value.
    let shown = html
        .matches("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;q&quot;")
        .count();
    assert_eq!(shown, 14, "{html}");
    assert_eq!(html.matches("</title>").count(), 1);
    assert_eq!(html.matches("</pre>").count(), 1);
    assert!(html.contains("x&quot; onerror=&quot;alert(1)"));
}

#[test]
fn page_is_self_contained() {
    let page = sample();
    let html = render(&page);
    let lower = html.to_lowercase();
    for banned in [
        "http:",
        "https:",
        "<script",
        "<link",
        "@import",
        "url(",
        "<iframe",
        "<object",
        "<embed",
        "src=\"/",
        "href=\"/",
        "href=\"http",
    ] {
        assert!(!lower.contains(banned), "found {banned}");
    }
    assert!(html.contains(CSP));
    // Every src is a data: URI (data_uris panics otherwise), and every link is in-page.
    assert_eq!(data_uris(&html).len(), 4);
    for link in html.split("href=\"").skip(1) {
        assert!(link.starts_with("#s"), "{link}");
    }
    // Tags balance.
    for tag in ["figure", "table", "div", "pre", "p", "nav", "ol", "tbody"] {
        let open =
            html.matches(&format!("<{tag}>")).count() + html.matches(&format!("<{tag} ")).count();
        let close = html.matches(&format!("</{tag}>")).count();
        assert_eq!(open, close, "<{tag}>");
    }
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(html.trim_end().ends_with("</html>"));
}

#[test]
fn images_are_embedded_with_their_display_size() {
    let small = gray_png(48, 48);
    let mid = gray_png(100, 50);
    let large = gray_png(300, 20);
    let page = Page {
        title: "images".into(),
        blocks: vec![
            Block::Image {
                caption: "48".into(),
                png: small.clone(),
                alt: "a".into(),
                width_px: None,
            },
            Block::Image {
                caption: "100".into(),
                png: mid.clone(),
                alt: "b".into(),
                width_px: None,
            },
            Block::Image {
                caption: "300".into(),
                png: large.clone(),
                alt: "c".into(),
                width_px: None,
            },
            Block::Image {
                caption: "300 shown at 150".into(),
                png: large.clone(),
                alt: "d".into(),
                width_px: Some(150),
            },
            Block::Image {
                caption: "not a png".into(),
                png: b"GIF89a not a png at all".to_vec(),
                alt: "e".into(),
                width_px: None,
            },
        ],
    };
    let html = render(&page);
    let uris = data_uris(&html);
    assert_eq!(uris.len(), 4);
    for ((mime, bytes), want) in uris.iter().zip([&small, &mid, &large, &large]) {
        assert_eq!(mime, "image/png");
        assert_eq!(bytes, want);
    }
    // 48 px: ×6 = 288 ≥ 256, pixelated; 100 px: ×3 = 300; 300 px: natural, smooth;
    // 150 px: shrunk, smooth (pixelated shrinking would drop rows).
    assert!(html.contains("<img class=\"px\" width=\"288\" alt=\"a\""));
    assert!(html.contains("<img class=\"px\" width=\"300\" alt=\"b\""));
    assert!(html.contains("<img width=\"300\" alt=\"c\""));
    assert!(html.contains("<img width=\"150\" alt=\"d\""));
    assert!(html.contains("not a PNG file (23 bytes)"));
    assert!(html.contains("<figcaption>not a png</figcaption>"));
    assert_eq!(png_size(&small), Some((48, 48)));
    assert_eq!(png_size(&mid), Some((100, 50)));
    assert_eq!(png_size(&small[..20]), None);
}

#[test]
fn svg_is_checked_then_embedded() {
    assert_eq!(checked_svg(SVG).as_deref(), Some(SVG));
    // A missing namespace is added to the root element only.
    let bare = "<svg width=\"10\" height=\"10\"><rect width=\"5\" height=\"5\"/></svg>";
    let fixed = checked_svg(bare).unwrap();
    assert_eq!(
        fixed,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"10\" height=\"10\"><rect width=\"5\" height=\"5\"/></svg>"
    );
    let with_doctype = "\u{FEFF}  <!DOCTYPE svg PUBLIC \"-//W3C//DTD SVG 1.1//EN\" \"x.dtd\">\n<svg xmlns=\"http://www.w3.org/2000/svg\"/>";
    assert!(checked_svg(with_doctype).is_some());
    for bad in [
        "",
        "not svg",
        "<html><svg></svg></html>",
        "<svgfoo/>",
        "<script>alert(1)</script><svg/>",
        "<!DOCTYPE svg [<!ENTITY x \"y\">]><svg/>",
        "<!-- unterminated <svg/>",
        "<?xml version=\"1.0\"<svg/>",
        "<svg",
        "<éééééé svg",
        "<!DOCéééé <svg/>",
    ] {
        assert!(checked_svg(bad).is_none(), "{bad:?}");
    }
    let page = Page {
        title: "svg".into(),
        blocks: vec![
            Block::Svg {
                caption: "plot".into(),
                svg: SVG.into(),
            },
            Block::Svg {
                caption: "bad".into(),
                svg: "<p>hello</p></figure></body>".into(),
            },
        ],
    };
    let html = render(&page);
    let uris = data_uris(&html);
    assert_eq!(uris.len(), 1);
    assert_eq!(uris[0].0, "image/svg+xml");
    assert_eq!(uris[0].1, SVG.as_bytes());
    assert!(html.contains("not an SVG document"));
    assert!(!html.contains("<p>hello"));
    assert_eq!(html.matches("</body>").count(), 1);
}

#[test]
fn headings_tables_and_text_are_structured() {
    let page = Page {
        title: "t".into(),
        blocks: vec![
            Block::Heading {
                level: 0,
                text: "zero".into(),
            },
            Block::Heading {
                level: 9,
                text: "nine".into(),
            },
            Block::Heading {
                level: 2,
                text: "A".into(),
            },
            Block::Figures(vec![Block::Heading {
                level: 2,
                text: "B".into(),
            }]),
            Block::Heading {
                level: 2,
                text: "C".into(),
            },
            Block::Table {
                caption: None,
                header: vec![],
                rows: vec![vec![
                    "3.14".into(),
                    "\u{2212}2".into(),
                    " 12 %".into(),
                    "1e-3".into(),
                    "abc".into(),
                    "1.2.3".into(),
                    "-".into(),
                    "inf".into(),
                ]],
            },
            Block::Preformatted("\nfirst line blank\n  indented".into()),
        ],
    };
    let html = render(&page);
    assert!(html.contains("<h1 id=\"s1\">zero</h1>"));
    assert!(html.contains("<h6 id=\"s2\">nine</h6>"));
    assert!(html.contains("<h2 id=\"s4\">B</h2>"));
    assert!(html.contains("<li><a href=\"#s3\">A</a></li>\n<li><a href=\"#s4\">B</a></li>\n<li><a href=\"#s5\">C</a></li>"));
    assert!(!html.contains("<thead>"));
    assert!(!html.contains("<caption>"));
    assert_eq!(html.matches("<td class=\"num\">").count(), 4, "{html}");
    assert!(html.contains("<td>abc</td><td>1.2.3</td><td>-</td><td>inf</td>"));
    assert!(html.contains("<pre>\n\nfirst line blank\n  indented</pre>"));
    // Fewer than three level-2 headings: no contents.
    let short = Page {
        title: "t".into(),
        blocks: vec![Block::Heading {
            level: 2,
            text: "only".into(),
        }],
    };
    assert!(!render(&short).contains("<nav"));
}

#[test]
fn png_bytes_gray8_encodes_the_raster() {
    let img = Raster::new(3, 2, vec![0.0, 0.5, 1.0, f64::NAN, -3.0, 7.0]).unwrap();
    let bytes = png_bytes_gray8(&img, 0.0, 1.0).unwrap();
    let back = image::load_from_memory(&bytes).unwrap();
    let back = back.as_luma8().expect("8-bit gray");
    assert_eq!(back.dimensions(), (3, 2));
    assert_eq!(back.as_raw(), &vec![0, 128, 255, 0, 0, 255]);
    assert!(png_bytes_gray8(&img, 1.0, 0.0).unwrap_err().is_user_error());
    assert!(png_bytes_gray8(&img, 0.0, f64::NAN).is_err());
    let b = Block::gray_image("g", &img, 0.0, 1.0).unwrap();
    assert!(matches!(b, Block::Image { ref png, .. } if *png == bytes));
}

/// A page with every block type, like a run report: the chart at 48×48 and 96×96 beside
/// each other, a plot, tables, parameters and a log.
fn sample() -> Page {
    let chart = UsafChart::new(-2, 7, Polarity::Negative).unwrap();
    let region = PaperRegion::Fig8b.region();
    let img48 = chart.render(&region, 48, 48);
    let img96 = chart.render(&region, 96, 96);
    let rows: Vec<Vec<String>> = [
        ("single-arm", 0.25, 24.31, 0.712),
        ("complementary", 0.25, 27.9, 0.801),
        ("balanced (SCB)", 0.25, 31.07, 0.874),
    ]
    .iter()
    .map(|(s, r, p, m)| {
        vec![
            s.to_string(),
            format!("{r}"),
            format!("{p:.2}"),
            format!("{m:.3}"),
        ]
    })
    .collect();
    Page {
        title: "spibench run — sample report <Fig. 8b>".into(),
        blocks: vec![
            Block::Paragraph(
                "A sample page with every block type, used to check the layout in a browser. \
                     Text such as <b>this</b> is shown literally."
                    .into(),
            ),
            Block::Heading {
                level: 2,
                text: "Parameters".into(),
            },
            Block::KeyValues(vec![
                ("scene".into(), "scenes/paper_bench.ron".into()),
                ("sampling ratio".into(), "0.25".into()),
                ("seed".into(), "1234".into()),
                (
                    "detector".into(),
                    "Thorlabs PDB450A (free-space balanced)".into(),
                ),
            ]),
            Block::Heading {
                level: 2,
                text: "Reconstructions".into(),
            },
            Block::Figures(vec![
                Block::gray_image("48×48, group 0 elements 4–6", &img48, 0.0, 1.0).unwrap(),
                Block::gray_image("96×96, same region", &img96, 0.0, 1.0).unwrap(),
                Block::Image {
                    caption: "96×96 at natural size".into(),
                    png: png_bytes_gray8(&img96, 0.0, 1.0).unwrap(),
                    alt: "natural".into(),
                    width_px: Some(96),
                },
            ]),
            Block::Table {
                caption: Some("Scores (PSNR in dB)".into()),
                header: vec![
                    "scheme".into(),
                    "ratio".into(),
                    "PSNR".into(),
                    "MSSIM".into(),
                ],
                rows,
            },
            Block::Heading {
                level: 2,
                text: "Plot".into(),
            },
            Block::Figures(vec![
                Block::Svg {
                    caption: "PSNR against sampling ratio (SVG)".into(),
                    svg: SVG.into(),
                },
                Block::Svg {
                    caption: "a broken SVG is a visible placeholder".into(),
                    svg: "<html>".into(),
                },
            ]),
            Block::Heading {
                level: 3,
                text: "Log".into(),
            },
            Block::Preformatted(
                "trace: 1.0e7 rays in 3.2 s\nreconstruct: TVAL3, 412 iterations\n\
                     a very long line that should wrap rather than widen the page: \
                     0123456789 0123456789 0123456789 0123456789 0123456789 0123456789 \
                     0123456789 0123456789 0123456789"
                    .into(),
            ),
        ],
    }
}

/// The sample page; with SPIBENCH_HTML_SAMPLE=path it is also written there to be looked
/// at in a browser (see the module docs).
#[test]
fn sample_page() {
    let page = sample();
    let html = render(&page);
    assert_eq!(html.matches("<figure>").count(), 5);
    assert_eq!(html.matches("class=\"px\"").count(), 2);
    assert!(html.contains("&lt;b&gt;this&lt;/b&gt;"));
    if let Some(path) = std::env::var_os("SPIBENCH_HTML_SAMPLE") {
        write_page(Path::new(&path), &page).unwrap();
    }
}
