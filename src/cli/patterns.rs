//! `spibench patterns`: pattern sets for a DMD controller, as packed `.npy` and as 1-bit PNG
//! frames at the DMD's native mirror resolution (each unit expanded to its mirrors; by default
//! the DMD of the bench, 1024 × 768 for the built-in one), and `patterns.json`, which says
//! what they are (family, ordering, units, ratio, mirrors per unit, frame order).

use std::io::BufWriter;
use std::path::PathBuf;

use anyhow::Context;

use crate::acquisition::{HadamardOrdering, PatternFamily, patterns_for_ratio};
use crate::error::Error;
use crate::report::output::OutputDir;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FamilyArg {
    Random,
    Hadamard,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OrderingArg {
    Natural,
    Walsh,
    RussianDolls,
    CakeCutting,
}

#[derive(Debug, Clone, clap::Args)]
pub struct PatternsArgs {
    #[arg(long, value_enum)]
    pub family: FamilyArg,
    /// Hadamard ordering.
    #[arg(long, value_enum, default_value = "cake-cutting")]
    pub ordering: OrderingArg,
    /// Seed of random patterns.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Pattern units, e.g. 48x48.
    #[arg(long)]
    pub units: String,
    /// Sampling ratio: round(R·units) base patterns.
    #[arg(long)]
    pub ratio: f64,
    /// Follow every pattern by its complement (the complementary schemes' frame sequence).
    #[arg(long)]
    pub complement: bool,
    /// Mirrors per unit side.
    #[arg(long, default_value_t = 12)]
    pub mirrors_per_unit: usize,
    /// The DMD's mirror array, e.g. 1920x1080 (the pattern is centred; other mirrors off).
    /// Default: the DMD of --scene (1024x768 for the built-in bench's DLP7000 class).
    #[arg(long)]
    pub dmd: Option<String>,
    /// The bench whose DMD sets the default --dmd (default: the built-in paper bench).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    #[arg(long, default_value = "out/patterns")]
    pub out: PathBuf,
}

fn size(s: &str, what: &str) -> Result<(usize, usize), Error> {
    let bad = || Error::field(what, format!("expected WxH, got {s:?}"));
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: usize = w.trim().parse().map_err(|_| bad())?;
    let h: usize = h.trim().parse().map_err(|_| bad())?;
    if w == 0 || h == 0 || w > 65536 || h > 65536 {
        return Err(bad());
    }
    Ok((w, h))
}

/// Rows packed as `numpy.packbits(P, axis=1)` does (most significant bit first).
fn pack(rows: &[Vec<bool>]) -> Vec<u8> {
    let mut out = Vec::new();
    for r in rows {
        for chunk in r.chunks(8) {
            let mut b = 0u8;
            for (k, &v) in chunk.iter().enumerate() {
                if v {
                    b |= 0x80 >> k;
                }
            }
            out.push(b);
        }
    }
    out
}

/// `patterns.json`: what the frames are, for whoever loads them into a DMD controller.
#[derive(serde::Serialize)]
struct PatternsMeta {
    command: &'static str,
    spibench_version: &'static str,
    /// `random` or `hadamard`, with the ordering of a Hadamard set or the seed of a random one.
    family: String,
    ordering: Option<&'static str>,
    seed: Option<u64>,
    units_across: usize,
    units_down: usize,
    /// Unit j = row · units_across + column, row 0 at the top of the frame.
    unit_order: &'static str,
    ratio: f64,
    base_patterns: usize,
    frames: usize,
    /// The frame sequence: base patterns only, or each followed by its complement.
    frame_order: &'static str,
    mirrors_per_unit: usize,
    dmd_columns: usize,
    dmd_rows: usize,
    /// Where the DMD size came from: `--dmd` or the bench file's `dmd.columns × dmd.rows`.
    dmd_from: String,
    /// The first mirror (column, row) of unit 0: the pattern is centred, other mirrors off
    /// (0).
    pattern_origin_mirror: [usize; 2],
    /// 1 = the mirror (or unit) in state +, toward arm +.
    value_meaning: &'static str,
    /// `patterns.npy`: frames × ceil(units/8) uint8, numpy.packbits(P, axis=1) (most
    /// significant bit first); `frame_NNNNN.png`: 1-bit PNG, dmd_columns × dmd_rows.
    files: Vec<String>,
}

/// The DMD size: `--dmd`, or the columns and rows of the bench's DMD.
fn dmd_size(args: &PatternsArgs) -> crate::Result<((usize, usize), String)> {
    if let Some(d) = &args.dmd {
        return Ok((size(d, "--dmd")?, "--dmd".into()));
    }
    let (name, doc) = super::run::load_doc(args.scene.as_deref(), &[])?;
    let Some(d) = &doc.file.dmd else {
        return Err(Error::field(
            "--dmd",
            format!("{name} has no DMD to take the size from: give --dmd WxH"),
        ));
    };
    Ok((
        (d.columns, d.rows),
        format!("dmd.columns × dmd.rows of {name}"),
    ))
}

pub fn run(args: &PatternsArgs) -> anyhow::Result<()> {
    let (w, h) = size(&args.units, "--units")?;
    let ((dw, dh), dmd_from) = dmd_size(args)?;
    let k = args.mirrors_per_unit;
    if k == 0 || w * k > dw || h * k > dh {
        return Err(Error::field(
            "--mirrors-per-unit",
            format!("{w}×{h} units of {k}×{k} mirrors do not fit on a {dw}×{dh} DMD"),
        )
        .into());
    }
    if !(args.ratio > 0.0 && args.ratio <= 1.0) {
        return Err(Error::field("--ratio", "must lie in (0, 1]").into());
    }
    let family = match args.family {
        FamilyArg::Random => PatternFamily::Random { seed: args.seed },
        FamilyArg::Hadamard => PatternFamily::Hadamard {
            ordering: match args.ordering {
                OrderingArg::Natural => HadamardOrdering::Natural,
                OrderingArg::Walsh => HadamardOrdering::Walsh,
                OrderingArg::RussianDolls => HadamardOrdering::RussianDolls,
                OrderingArg::CakeCutting => HadamardOrdering::CakeCutting,
            },
        },
    };
    let m = patterns_for_ratio(args.ratio, w * h);
    let set = family.build(w, h, m)?;
    let bits = set.base_patterns();
    let mut frames: Vec<Vec<bool>> = Vec::new();
    for i in 0..m {
        let p: Vec<bool> = (0..w * h).map(|j| bits.get(i, j)).collect();
        if args.complement {
            let c = p.iter().map(|v| !v).collect();
            frames.push(p);
            frames.push(c);
        } else {
            frames.push(p);
        }
    }
    let out = OutputDir::create(&args.out)?;
    let npy = crate::report::npy::encode_u8(&[frames.len(), (w * h).div_ceil(8)], &pack(&frames));
    std::fs::write(out.path("patterns.npy"), npy).context("writing patterns.npy")?;
    let (x0, y0) = ((dw - w * k) / 2, (dh - h * k) / 2);
    let meta = PatternsMeta {
        command: "patterns",
        spibench_version: env!("CARGO_PKG_VERSION"),
        family: match args.family {
            FamilyArg::Random => "random".into(),
            FamilyArg::Hadamard => "hadamard".into(),
        },
        ordering: match args.family {
            FamilyArg::Random => None,
            FamilyArg::Hadamard => Some(match args.ordering {
                OrderingArg::Natural => "natural",
                OrderingArg::Walsh => "walsh",
                OrderingArg::RussianDolls => "russian-dolls",
                OrderingArg::CakeCutting => "cake-cutting",
            }),
        },
        seed: (args.family == FamilyArg::Random).then_some(args.seed),
        units_across: w,
        units_down: h,
        unit_order: "row-major: unit j = row · units_across + column, row 0 at the top",
        ratio: args.ratio,
        base_patterns: m,
        frames: frames.len(),
        frame_order: if args.complement {
            "base pattern i, then its complement, for i = 0, 1, …"
        } else {
            "base patterns i = 0, 1, …"
        },
        mirrors_per_unit: k,
        dmd_columns: dw,
        dmd_rows: dh,
        dmd_from,
        pattern_origin_mirror: [x0, y0],
        value_meaning: "1 = state + (toward arm +), 0 = state −",
        files: vec![
            "patterns.npy".into(),
            format!(
                "frame_00000.png … frame_{:05}.png",
                frames.len().saturating_sub(1)
            ),
        ],
    };
    let json = serde_json::to_string_pretty(&meta)
        .map_err(|e| Error::Numerical(format!("cannot encode patterns.json: {e}")))?;
    std::fs::write(out.path("patterns.json"), json + "\n").context("writing patterns.json")?;
    for (f, p) in frames.iter().enumerate() {
        // Unit j = row·w + col covers mirrors [x0 + col·k, +k) × [y0 + row·k, +k).
        let rows: Vec<Vec<bool>> = (0..dh)
            .map(|y| {
                (0..dw)
                    .map(|x| {
                        x >= x0
                            && x < x0 + w * k
                            && y >= y0
                            && y < y0 + h * k
                            && p[((y - y0) / k) * w + (x - x0) / k]
                    })
                    .collect()
            })
            .collect();
        let path = out.path(&format!("frame_{f:05}.png"));
        let file = std::fs::File::create(&path).with_context(|| format!("{}", path.display()))?;
        let mut enc = png::Encoder::new(BufWriter::new(file), dw as u32, dh as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::One);
        let mut writer = enc.write_header().context("PNG header")?;
        writer.write_image_data(&pack(&rows)).context("PNG data")?;
        writer.finish().context("PNG end")?;
    }
    let dir = out.commit()?;
    println!(
        "{} frames ({} base patterns, {}) of {w}×{h} units at {dw}×{dh} mirrors → {}",
        frames.len(),
        m,
        family.label(),
        dir.display()
    );
    Ok(())
}
