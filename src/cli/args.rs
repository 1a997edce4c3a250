//! The arguments the bench commands share, declared once: the scene and `--set PATH=VALUE`
//! ([`BenchArgs`], the one entrance for a bench), `--rays N`, `--seed S`, `--out DIR`
//! ([`RunOpts`]) and `--shard I/N`
//! ([`Shard`]), each with one validation, and `--allow-large` ([`WorkArgs`]): the one switch over
//! the limits on a command's total work ([`Work`]).
//!
//! Each command keeps its own defaults and ray range: it sets the defaults on its flags with
//! `mut_arg` (so that `--help` shows them) and checks `--rays` against its own minimum with
//! [`check_rays`].

use std::path::PathBuf;

use clap::Args;

use crate::scene::doc::{BenchDoc, DmdModel};
use crate::scene::run::MAX_RAYS;

/// `--rays`, `--seed` and `--out`: every command that traces a bench has them.
#[derive(Debug, Clone, Default, Args)]
pub struct RunOpts {
    /// Lamp rays per traced bench (the command's range: its minimum to 10¹¹).
    #[arg(long, value_name = "N")]
    pub rays: Option<u64>,
    /// Seed of the random streams (same seed, same output, on any number of threads).
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    /// Output folder (created; files of the same names are replaced).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

impl RunOpts {
    /// The seed (1 unless given; every command's default).
    pub fn seed(&self) -> u64 {
        self.seed.unwrap_or(1)
    }

    /// The output folder, `default` unless given.
    pub fn out_or(&self, default: &str) -> PathBuf {
        self.out.clone().unwrap_or_else(|| PathBuf::from(default))
    }

    /// The one rule for the ray count of a command that traces `doc`: `--rays`, else the
    /// bench file's `run.rays` when the file states one, else the command's `default`; checked
    /// against two batches … [`MAX_RAYS`] ([`check_rays`]).
    pub fn rays(&self, doc: &BenchDoc, default: u64) -> crate::Result<u64> {
        let rays = self.rays.or_else(|| doc.stated_rays()).unwrap_or(default);
        check_rays(rays, MIN_RAYS_WITH_STDERR)
    }
}

/// The `--help` text of `--rays` for a command that traces: `what`, and the one rule
/// ([`RunOpts::rays`]) with the command's `default`.
pub fn rays_help(what: &str, default: u64) -> String {
    format!(
        "{what} (default: the bench file's `run.rays` when it states one, else {default}; \
         at least {MIN_RAYS_WITH_STDERR}, two batches)"
    )
}

/// The one check of `--rays`: between the command's `min` and [`MAX_RAYS`]. A minimum of two
/// batches (`2 · trace::RAYS_PER_BATCH`) is what gives every traced number a standard error.
pub fn check_rays(rays: u64, min: u64) -> crate::Result<u64> {
    if rays < min || rays > MAX_RAYS {
        let why = if min >= 2 * crate::trace::RAYS_PER_BATCH {
            " (two batches, so that every number has a standard error)"
        } else {
            ""
        };
        return Err(crate::Error::field(
            "--rays",
            format!(
                "must lie between {min}{why} and {MAX_RAYS} (about a day on two cores), got {rays}"
            ),
        ));
    }
    Ok(rays)
}

/// The smallest `--rays` of the commands that report standard errors (run, sweep, tolerance,
/// align, trace), and of a bench file's `run.rays`: two batches.
pub const MIN_RAYS_WITH_STDERR: u64 = crate::scene::run::MIN_RAYS;

/// The one entrance for a bench: SCENE (a bench file; without it the paper's bench built into
/// the program) and `--set PATH=VALUE`, read and edited once ([`BenchArgs::load`]). Every
/// command that reads a bench takes these arguments.
#[derive(Debug, Clone, Default, Args)]
pub struct BenchArgs {
    /// Bench file (RON); default: the paper's bench built into the binary.
    pub scene: Option<PathBuf>,
    /// Set a bench variable first, e.g. `--set detectors.minus.decenter_mm.x=0.5`
    /// (repeatable; paths as in `spibench sweep`).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// The DMD's model, over the bench file's `dmd.model`: `diffractive`, the mirror array as a
    /// blazed grating (the shipped bench's), or `geometric`, plane mirrors
    /// (docs/dmd_diffraction.md).
    #[arg(long = "dmd-model", value_name = "MODEL")]
    pub dmd_model: Option<DmdModelArg>,
}

/// The values of `--dmd-model`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DmdModelArg {
    /// Plane mirrors (specular reflection).
    Geometric,
    /// The array as a blazed grating: each ray leaves in one diffraction order.
    Diffractive,
}

impl DmdModelArg {
    pub fn model(self) -> DmdModel {
        match self {
            DmdModelArg::Geometric => DmdModel::Geometric,
            DmdModelArg::Diffractive => DmdModel::Diffractive,
        }
    }
}

impl BenchArgs {
    /// Reads the bench (or the built-in one), selects `--dmd-model` and applies `--set`, in
    /// order.
    pub fn load(&self) -> crate::Result<BenchDoc> {
        let mut doc = BenchDoc::open(self.scene.as_deref())?;
        if let Some(m) = self.dmd_model {
            doc.set_dmd_model(m.model())?;
        }
        for a in &self.set {
            let (path, value) = super::parse_assignment(a, "--set")?;
            doc.set(&path, value)?;
        }
        // A glass modelled from nd and Vd is never silent (also in check and summary.json).
        for s in doc.glass_substitutions() {
            eprintln!("warning: {s}");
        }
        Ok(doc)
    }
}

/// The most work a command starts without `--allow-large`: traced lamp rays in all (10¹⁰, one
/// trace's own cap [`MAX_RAYS`]; the refusal states its time at the paper bench's rate,
/// `tolerance::work::RAYS_PER_SECOND_TWO_CORES`).
pub const MAX_WORK_RAYS: f64 = 1e10;
/// The most dataset samples one run makes without `--allow-large` (10⁷: about three hours at the
/// 1 000 samples/s of `cargo bench --bench dataset`).
pub const MAX_WORK_SAMPLES: f64 = 1e7;
/// The most bytes one run writes without `--allow-large` (100 GB, a dataset's own default
/// `max_disk_gb`).
pub const MAX_WORK_BYTES: f64 = 1e11;

/// `--allow-large`: the one switch that lifts the limits on a command's total work. Each
/// count of a command has its own cap, but their product (trials × traces × rays, grid points ×
/// rays, samples, bytes) is what takes the time: the commands that multiply counts estimate
/// it with [`Work`] before they start and refuse above the limits unless this flag is given.
#[derive(Debug, Clone, Copy, Default, Args)]
pub struct WorkArgs {
    /// Start even when the estimated work or memory exceeds the limits (10¹⁰ traced rays in all,
    /// 10⁷ dataset samples, 10¹¹ bytes written, 2 GB for one table or array); without it such a
    /// run is refused with its estimate.
    #[arg(long)]
    pub allow_large: bool,
}

/// A command's estimated total work, as the product of the counts that make it (`what`, for
/// the message: "1000000 trials × up to 31 traces × 200000 rays").
#[derive(Debug, Clone, Default)]
pub struct Work {
    pub rays: f64,
    pub samples: f64,
    pub bytes: f64,
    pub what: String,
}

impl WorkArgs {
    /// Refuses `work` above the limits (an input error naming the estimate, the limit and
    /// `--allow-large`), unless `--allow-large` was given.
    pub fn check(&self, work: &Work) -> crate::Result<()> {
        if self.allow_large {
            return Ok(());
        }
        let rays_note = format!(
            " ({} on the paper bench)",
            crate::tolerance::work::rough_time(
                MAX_WORK_RAYS / crate::tolerance::work::RAYS_PER_SECOND_TWO_CORES
            )
        );
        let over = [
            (work.rays, MAX_WORK_RAYS, "traced rays", rays_note.as_str()),
            (work.samples, MAX_WORK_SAMPLES, "samples", ""),
            (work.bytes, MAX_WORK_BYTES, "bytes written", ""),
        ]
        .into_iter()
        // NaN counts as over the limit.
        .find(|(v, max, _, _)| v.partial_cmp(max) != Some(std::cmp::Ordering::Less) && v != max);
        match over {
            None => Ok(()),
            Some((v, max, unit, note)) => Err(crate::Error::field(
                "--allow-large",
                format!(
                    "this run would make about {v:.2e} {unit} ({}), above the limit of {max:.0e} \
                     {unit}{note}: lower the counts, or pass --allow-large to start it anyway",
                    work.what
                ),
            )),
        }
    }
}

/// `--shard I/N`: part I (0-based) of N of a run's work, for running the parts as separate
/// processes and merging them. The two commands split the work differently, and say so in
/// their help: `tolerance` takes the trials i ≡ I (mod N) ([`Shard::strided`]: every part
/// meets early and late trials alike), `dataset` the contiguous block of shards from
/// ⌊I·T/N⌋ to ⌊(I+1)·T/N⌋ ([`Shard::block`]: each part writes neighbouring folders).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl Shard {
    /// The whole run: part 0 of 1.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Parses `I/N` with 0 ≤ I < N.
    pub fn parse(text: &str) -> crate::Result<Shard> {
        let bad = || {
            crate::Error::field(
                "--shard",
                format!("`{text}`: expected I/N with 0 ≤ I < N, e.g. 0/4"),
            )
        };
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count): (u64, u64) = (
            i.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// Parses an optional `--shard`.
    pub fn parse_opt(text: Option<&str>) -> crate::Result<Option<Shard>> {
        text.map(Shard::parse).transpose()
    }

    /// (I, N), as the library and the shard records hold it.
    pub fn pair(self) -> (u64, u64) {
        (self.index, self.count)
    }

    /// The items i ≡ I (mod N) of `0..total` (`tolerance`'s trials).
    pub fn strided(self, total: u64) -> impl Iterator<Item = u64> {
        crate::tolerance::shard_indices(total, self.pair())
    }

    /// The contiguous block of `0..total` that is part I of N, as [start, end)
    /// (`dataset`'s shards).
    pub fn block(self, total: u64) -> (u64, u64) {
        crate::dataset::shard_range(total, Some(self.pair()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_once_and_split_two_ways() {
        let s = Shard::parse(" 1 / 3").unwrap();
        assert_eq!(s, Shard { index: 1, count: 3 });
        assert_eq!(s.strided(8).collect::<Vec<_>>(), [1, 4, 7]);
        assert_eq!(s.block(9), (3, 6));
        for bad in ["3/3", "0/0", "1", "a/2", "-1/2"] {
            let e = Shard::parse(bad).unwrap_err();
            assert!(
                e.is_user_error() && e.to_string().contains("--shard"),
                "{e}"
            );
        }
        // The parts of either split cover the run once.
        let mut all: Vec<u64> = (0..3)
            .flat_map(|i| Shard { index: i, count: 3 }.strided(10))
            .collect();
        all.sort_unstable();
        assert_eq!(all, (0..10).collect::<Vec<_>>());
        let ends: Vec<(u64, u64)> = (0..3)
            .map(|i| Shard { index: i, count: 3 }.block(10))
            .collect();
        assert_eq!(ends, [(0, 3), (3, 6), (6, 10)]);
    }

    #[test]
    fn work_above_a_limit_is_refused_with_its_estimate() {
        let small = Work {
            rays: 1e9,
            what: "10 points × 1e8 rays".into(),
            ..Work::default()
        };
        assert!(WorkArgs::default().check(&small).is_ok());
        let big = Work {
            rays: 2e14,
            what: "100 × 100 points × 1e10 rays".into(),
            ..Work::default()
        };
        let e = WorkArgs::default().check(&big).unwrap_err();
        let m = e.to_string();
        assert!(e.is_user_error(), "{m}");
        for f in [
            "2.00e14 traced rays",
            "100 × 100 points",
            "--allow-large",
            "1e10",
        ] {
            assert!(m.contains(f), "{m} lacks {f}");
        }
        let nan = Work {
            bytes: f64::NAN,
            ..Work::default()
        };
        assert!(WorkArgs::default().check(&nan).is_err());
        let allowed = WorkArgs { allow_large: true };
        assert!(allowed.check(&big).is_ok());
    }

    #[test]
    fn one_rays_check() {
        let min = MIN_RAYS_WITH_STDERR;
        assert_eq!(min, 2 * crate::trace::RAYS_PER_BATCH, "two batches");
        assert_eq!(check_rays(min, min).unwrap(), min);
        let e = check_rays(min - 1, min).unwrap_err();
        assert!(e.is_user_error() && e.to_string().contains("--rays"), "{e}");
        assert!(check_rays(MAX_RAYS + 1, 1).is_err());
        assert!(check_rays(0, 1).is_err());
    }
}
