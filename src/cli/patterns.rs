//! `spibench patterns`: pattern sets for a DMD controller, as packed `.npy` and as 1-bit PNG
//! frames at the DMD's native mirror resolution (each unit expanded to its mirrors; by default
//! the DMD of the bench, 1024 × 768 for the built-in one), and `patterns.json`, which says
//! what they are (family, ordering, units, ratio, mirrors per unit, frame order). The bench
//! comes in as every command's does (SCENE, else the built-in bench; `--set`), through
//! `BenchArgs::load`.

use std::io::{BufWriter, Write};
use std::path::PathBuf;

use anyhow::Context;

use crate::acquisition::{HadamardOrdering, PatternFamily, patterns_for_ratio};
use crate::error::Error;
use crate::report::output::OutputDir;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FamilyArg {
    /// Random 0/1 patterns from `--seed`.
    Random,
    /// Sylvester Hadamard patterns (2^m × 2^m units) in `--ordering`.
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
#[command(mut_arg("set", |a| a.help("Set a bench variable first (repeatable)")))]
pub struct PatternsArgs {
    /// The bench whose DMD sets the default --dmd (default: the built-in paper bench).
    #[command(flatten)]
    pub bench: crate::cli::args::BenchArgs,
    /// The pattern family.
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
    /// Default: the DMD of SCENE (1024x768 for the built-in bench's DLP7000 class).
    #[arg(long, conflicts_with_all = ["scene", "set", "scene_flag"])]
    pub dmd: Option<String>,
    /// SCENE given as a flag, as earlier versions took it.
    #[arg(
        long = "scene",
        id = "scene_flag",
        value_name = "SCENE",
        hide = true,
        conflicts_with = "scene"
    )]
    pub scene_flag: Option<PathBuf>,
    /// Output folder (created; files of the same names are replaced).
    #[arg(long, default_value = "out/patterns", value_name = "DIR")]
    pub out: PathBuf,
    #[command(flatten)]
    pub work: crate::cli::args::WorkArgs,
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

/// One packed row, MSB first, as `numpy.packbits` writes it: bit j of `len` from `bit(j)`.
fn pack_row(len: usize, bit: impl Fn(usize) -> bool, out: &mut Vec<u8>) {
    for start in (0..len).step_by(8) {
        let mut b = 0u8;
        for k in 0..8.min(len - start) {
            if bit(start + k) {
                b |= 0x80 >> k;
            }
        }
        out.push(b);
    }
}

/// The sizes of a pattern set on a DMD, checked before anything is allocated: units of
/// `k` × `k` mirrors (the products checked, so that a huge `--mirrors-per-unit` cannot wrap)
/// that fit the DMD, at most the pattern module's `MAX_UNITS` units.
fn check_sizes(w: usize, h: usize, k: usize, dw: usize, dh: usize) -> Result<(), Error> {
    let fits = |units: usize, mirrors: usize| units.checked_mul(k).is_some_and(|m| m <= mirrors);
    if k == 0 || !fits(w, dw) || !fits(h, dh) {
        return Err(Error::field(
            "--mirrors-per-unit",
            format!("{w}×{h} units of {k}×{k} mirrors do not fit on a {dw}×{dh} DMD"),
        ));
    }
    let max = crate::acquisition::patterns::MAX_UNITS;
    if w.checked_mul(h).is_none_or(|n| n > max) {
        return Err(Error::field(
            "--units",
            format!("{w}×{h} units is more than the {max} units a pattern set may have"),
        ));
    }
    Ok(())
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
    let mut bench = args.bench.clone();
    if let Some(scene) = &args.scene_flag {
        bench.scene = Some(scene.clone());
    }
    let doc = bench.load()?;
    let name = doc.name();
    let Some(d) = &doc.file.dmd else {
        return Err(Error::field(
            "--dmd",
            format!("{name} has no DMD to take the size from: give --dmd WxH"),
        ));
    };
    Ok((
        (d.columns.get() as usize, d.rows.get() as usize),
        format!("dmd.columns × dmd.rows of {name}"),
    ))
}

pub fn run(args: &PatternsArgs) -> anyhow::Result<()> {
    let (w, h) = size(&args.units, "--units")?;
    let ((dw, dh), dmd_from) = dmd_size(args)?;
    let k = args.mirrors_per_unit;
    check_sizes(w, h, k, dw, dh)?;
    if !(args.ratio > 0.0 && args.ratio <= 1.0) {
        return Err(
            Error::field("--ratio", format!("must lie in (0, 1], got {}", args.ratio)).into(),
        );
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
    let units = w * h;
    let m = patterns_for_ratio(args.ratio, units);
    let frames = if args.complement { 2 * m } else { m };
    // The bytes written: the packed array, and every frame at one bit per mirror (before the
    // PNG's compression), estimated before the patterns are built.
    let row_bytes = units.div_ceil(8);
    args.work.check(&crate::cli::args::Work {
        bytes: frames as f64 * (row_bytes as f64 + dw.div_ceil(8) as f64 * dh as f64),
        what: format!("{frames} frames of {dw}×{dh} mirrors, and their packed array"),
        ..Default::default()
    })?;
    let set = family.build(w, h, m).map_err(|e| match e {
        Error::Input { .. } => Error::field("--units", e.message()),
        other => other,
    })?;
    let bits = set.base_patterns();
    // Frame f shows base pattern f (or f/2, complemented when f is odd, with --complement).
    let frame_bit = |f: usize, j: usize| {
        if args.complement {
            bits.get(f / 2, j) != (f % 2 == 1)
        } else {
            bits.get(f, j)
        }
    };
    let out = OutputDir::create(&args.out)?;
    let mut packed = Vec::with_capacity(frames * row_bytes);
    for f in 0..frames {
        pack_row(units, |j| frame_bit(f, j), &mut packed);
    }
    let npy = crate::report::npy::encode_u8(&[frames, row_bytes], &packed);
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
        frames,
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
                frames.saturating_sub(1)
            ),
        ],
    };
    let json = serde_json::to_string_pretty(&meta)
        .map_err(|e| Error::Numerical(format!("cannot encode patterns.json: {e}")))?;
    std::fs::write(out.path("patterns.json"), json + "\n").context("writing patterns.json")?;
    let mut row = Vec::with_capacity(dw.div_ceil(8));
    for f in 0..frames {
        let path = out.path(&format!("frame_{f:05}.png"));
        let file = std::fs::File::create(&path).with_context(|| format!("{}", path.display()))?;
        let mut enc = png::Encoder::new(BufWriter::new(file), dw as u32, dh as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::One);
        let mut writer = enc.write_header().context("PNG header")?;
        // Row by row, so that a frame of any size needs one row of memory. Unit j = row·w + col
        // covers mirrors [x0 + col·k, +k) × [y0 + row·k, +k).
        let mut stream = writer.stream_writer().context("PNG data")?;
        for y in 0..dh {
            row.clear();
            let inside_y = y >= y0 && y < y0 + h * k;
            pack_row(
                dw,
                |x| {
                    inside_y
                        && x >= x0
                        && x < x0 + w * k
                        && frame_bit(f, ((y - y0) / k) * w + (x - x0) / k)
                },
                &mut row,
            );
            stream.write_all(&row).context("PNG data")?;
        }
        stream.finish().context("PNG end")?;
    }
    let dir = out.commit()?;
    println!(
        "{frames} frames ({m} base patterns, {}) of {w}×{h} units at {dw}×{dh} mirrors → {}",
        family.label(),
        dir.display()
    );
    Ok(())
}
