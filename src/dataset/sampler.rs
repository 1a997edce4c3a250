//! A dataset's samples: sample s's object drawn from (seed, s), its drawn bench (when the spec
//! draws benches from a tolerance file), its transport through the bench's kernel and its
//! detector record, measured by each scheme; a shard's samples in parallel.

use rayon::prelude::*;

use super::{
    DrawnBenches, OBJECTS, Prepared, bench_kernel, checked_scene, dataset_scene, noise_seed,
};
use crate::error::{Error, Result};
use crate::pipeline::evaluate;
use crate::raster::Raster;
use crate::rng::{self, uniform};
use crate::scene::dataset::{FitRule, ObjectSource};
use crate::scene::run::RunScene;
use crate::trace::kernel::Kernel;
use crate::transport::Transport;

/// One bench of a dataset: its detector, electronics and settings, and its object kernel.
pub struct BenchKernel {
    pub scene: RunScene,
    pub kernel: Kernel,
    /// Deviations of the tolerances (file order) then of the compensators, from the nominal
    /// bench.
    pub deviations: Vec<f64>,
}

/// Invalid drawn benches tolerated in a row before a dataset gives up.
const MAX_REDRAWS: u64 = 64;

/// One sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub object: Vec<f64>,
    /// Per (scheme, ratio) in [`Prepared::measurement_names`] order.
    pub measurements: Vec<Vec<f64>>,
    pub k_a_per_w: [f64; 2],
    pub b_a: [f64; 2],
    /// The drawn bench's deviations (empty for the nominal bench).
    pub deviations: Vec<f64>,
    /// The optional arrays of [`Prepared::optional_arrays`], in that order.
    pub optional: Vec<Vec<f64>>,
}

impl Prepared {
    /// The bench index of sample s (0 for every sample of a nominal dataset).
    pub fn bench_index(&self, s: u64) -> u64 {
        self.drawn.as_ref().map_or(0, |d| s / d.samples_per_bench)
    }

    /// Bench t of the benches `d` (this dataset's): tolerance trial t with the dataset's seed,
    /// or the next valid draw when that one is not a valid bench. Its kernel is traced with the
    /// kernel spec's rays and seed.
    pub fn drawn_bench(&self, d: &DrawnBenches, t: u64) -> Result<BenchKernel> {
        let options = crate::pipeline::evaluate::EvaluateOptions {
            rays: self.spec.file.kernel.rays,
            seed: self.spec.file.seed,
            quality: false,
        };
        let mut last = None;
        for j in 0..MAX_REDRAWS {
            // Redraws use trial indices far beyond any bench index.
            let draw = t + (j << 40);
            let made = crate::pipeline::perturb::trial_doc(&d.doc, &d.set, &options, draw)
                .and_then(|(doc, dev, comp)| {
                    Ok(BenchKernel {
                        scene: dataset_scene(
                            checked_scene(&doc, &self.spec)?,
                            &self.spec,
                            &self.schemes,
                        ),
                        kernel: bench_kernel(&doc, &self.spec)?,
                        deviations: dev.iter().chain(&comp).map(|(_, v)| *v).collect(),
                    })
                });
            match made {
                Ok(b) => return Ok(b),
                Err(e) if e.is_user_error() => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(self.spec.error(
            "benches",
            format!(
                "{MAX_REDRAWS} draws in a row for bench {t} made no valid bench; the last: {}",
                last.map(|e| e.to_string()).unwrap_or_default()
            ),
        ))
    }

    /// Names of the deviations of a drawn bench (tolerances, then compensators).
    pub fn deviation_names(&self) -> Vec<String> {
        self.drawn.as_ref().map_or_else(Vec::new, |d| {
            d.set
                .tolerances
                .iter()
                .map(|t| t.path.clone())
                .chain(
                    d.set
                        .compensators
                        .iter()
                        .map(|c| format!("{} (compensator)", c.path)),
                )
                .collect()
        })
    }

    pub fn units(&self) -> usize {
        self.kernel.units()
    }

    /// The object of sample s.
    pub fn object(&self, s: u64) -> Result<Raster> {
        let (gw, gh) = self.spec.file.kernel.grid_px;
        let mut r = rng::stream(rng::mix64(self.spec.file.seed ^ OBJECTS), s);
        let obj = match &self.spec.objects {
            ObjectSource::Images { images, rule, .. } => {
                let img = &images[(s % images.len() as u64) as usize];
                match rule {
                    FitRule::Resize => crate::objects::image_file::resize_area(img, gw, gh)?,
                    FitRule::RandomCrop => {
                        let c0 = ((uniform(&mut r) * (img.width - gw + 1) as f64) as usize)
                            .min(img.width - gw);
                        let r0 = ((uniform(&mut r) * (img.height - gh + 1) as f64) as usize)
                            .min(img.height - gh);
                        let mut d = Vec::with_capacity(gw * gh);
                        for row in 0..gh {
                            for col in 0..gw {
                                d.push(img.get(r0 + row, c0 + col));
                            }
                        }
                        Raster::new(gw, gh, d)?
                    }
                }
            }
            ObjectSource::Usaf {
                min_field_mm,
                max_field_mm,
            } => {
                let chart = crate::objects::usaf::UsafChart::new(
                    -2,
                    7,
                    crate::objects::usaf::Polarity::Negative,
                )?;
                let f = min_field_mm + uniform(&mut r) * (max_field_mm - min_field_mm);
                let fy = f * gh as f64 / gw as f64;
                let cx = (uniform(&mut r) - 0.5) * f;
                let cy = (uniform(&mut r) - 0.5) * fy;
                let region = crate::objects::usaf::Region::from_corners(
                    cx - 0.5 * f,
                    cy - 0.5 * fy,
                    cx + 0.5 * f,
                    cy + 0.5 * fy,
                );
                chart.render(&region, gw, gh)
            }
            ObjectSource::Phantom => crate::objects::phantom::phantom_sized(gw, gh, false)?,
            ObjectSource::Rectangles { max_count } => {
                let mut d = vec![0.0; gw * gh];
                let n = 1 + ((uniform(&mut r) * *max_count as f64) as usize).min(max_count - 1);
                for _ in 0..n {
                    let (a, b) = (uniform(&mut r) * gw as f64, uniform(&mut r) * gw as f64);
                    let (c, e) = (uniform(&mut r) * gh as f64, uniform(&mut r) * gh as f64);
                    let t = uniform(&mut r);
                    let (x0, x1) = (a.min(b) as usize, (a.max(b) as usize).min(gw - 1));
                    let (y0, y1) = (c.min(e) as usize, (c.max(e) as usize).min(gh - 1));
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            d[y * gw + x] = t;
                        }
                    }
                }
                Raster::new(gw, gh, d)?
            }
        };
        Ok(obj.map(|v| v.clamp(0.0, 1.0)))
    }

    /// Sample s: its object, transport, recorded frames and measurements (for a dataset over
    /// drawn benches its bench is traced first: [`Prepared::sample_on`] reuses one).
    pub fn sample(&self, s: u64) -> Result<Sample> {
        match &self.drawn {
            Some(d) => self.sample_on(s, Some(&self.drawn_bench(d, self.bench_index(s))?)),
            None => self.sample_on(s, None),
        }
    }

    /// Sample s measured through `bench` (which must be bench [`Prepared::bench_index`]`(s)`),
    /// or through the nominal bench.
    pub fn sample_on(&self, s: u64, bench: Option<&BenchKernel>) -> Result<Sample> {
        let (scene, kernel) = match bench {
            Some(b) => (&b.scene, &b.kernel),
            None => (&self.scene, &self.kernel),
        };
        let object = self.object(s)?.data;
        // Values only: a sample's arrays hold no standard errors (Transport::from_kernel_values).
        let transport = Transport::from_kernel_values(&scene.bench, kernel, &object, false)?;
        let seed = noise_seed(self.spec.file.seed, s);
        let rec = evaluate::acquire(scene, &transport, &self.patterns, seed, &|_, _, _| {})?;
        let mut measurements = Vec::new();
        for (_, scheme, m) in self.measurement_names() {
            let r = rec.record(scheme.sequence()).ok_or_else(|| {
                Error::input(format!("no record for the {} sequence", scheme.label()))
            })?;
            measurements.push(scheme.measurements(&r.frames, m));
        }
        let mut optional = Vec::new();
        let w = &self.spec.file.write;
        if w.reconstructions {
            let x = Raster::new(
                transport.units_across,
                transport.units_down,
                transport.x_w.clone(),
            )?;
            let truth = evaluate::truth_view(&x).ok_or_else(|| {
                Error::input(format!(
                    "sample {s}: no light of the object reached the DMD's pattern area"
                ))
            })?;
            let cells = evaluate::solve_scored(
                &scene.settings,
                &rec,
                &self.schemes,
                &self.ratios,
                &truth,
                None,
                &|_, _, _| {},
            )?;
            optional.push(x.data);
            let scores: Vec<Vec<f64>> = cells.iter().map(|c| vec![c.psnr_db, c.mssim]).collect();
            optional.extend(cells.into_iter().map(|c| c.solution.data));
            optional.extend(scores);
        }
        if w.scope_frames > 0 {
            for (q, len) in self.scope_sequences() {
                let r = rec.record(q).ok_or_else(|| {
                    Error::Numerical(format!("no record for the {} sequence", q.key()))
                })?;
                let v = &r.trace.v;
                if v.iter().any(|c| c.len() != len) {
                    return Err(Error::Numerical(format!(
                        "the {} sequence's oscilloscope record holds {} samples, not {len}",
                        q.key(),
                        v[0].len()
                    )));
                }
                optional.push(v.concat());
            }
        }
        Ok(Sample {
            object,
            measurements,
            k_a_per_w: [transport.k[0].value, transport.k[1].value],
            b_a: [transport.b[0].value, transport.b[1].value],
            deviations: bench.map_or_else(Vec::new, |b| b.deviations.clone()),
            optional,
        })
    }

    /// The sequences the schemes read, each with the length of its oscilloscope record of the
    /// first `scope_frames` frames (samples n whose frame ⌊(n + 10⁻⁶)/P⌋ is below that, P the
    /// samples per frame, as [`crate::detector::record`] assigns them).
    pub fn scope_sequences(&self) -> Vec<(crate::acquisition::Sequence, usize)> {
        let st = &self.scene.settings;
        let timing = crate::detector::FrameTiming {
            frame_s: 1.0 / st.dmd_rate_hz,
            settling_s: st.settling_time_s,
            sample_rate_hz: self.scene.scope.sample_rate_hz,
        };
        let m = self.patterns.set().measurements();
        crate::acquisition::Sequence::all()
            .into_iter()
            .filter(|q| self.schemes.iter().any(|k| k.sequence() == *q))
            .map(|q| {
                let frames = q.frames(m);
                let f = self.spec.file.write.scope_frames.min(frames);
                let len = crate::detector::frame_start_sample(timing, frames, f);
                (q, len as usize)
            })
            .collect()
    }

    pub fn shards_total(&self) -> u64 {
        self.spec
            .file
            .samples
            .div_ceil(self.spec.file.shard_samples)
    }

    /// The samples of shard b, computed in parallel (the drawn benches they see traced first,
    /// each once, in index order; a kernel trace is itself parallel).
    pub fn shard_samples(&self, b: u64) -> Result<Vec<Sample>> {
        self.shard_samples_timed(b).map(|(v, _)| v)
    }

    /// [`Prepared::shard_samples`], with the seconds by which the parallel loop outlasted its
    /// last sample. A thread of the pool that waits for its part of the loop runs any pending
    /// work of the pool meanwhile, a shard's file writing included, and the loop ends only
    /// when that thread is back: this measures what such work holds the loop up (the tail
    /// between its end and the end of its last sample).
    pub fn shard_samples_timed(&self, b: u64) -> Result<(Vec<Sample>, f64)> {
        let f = &self.spec.file;
        let first = b * f.shard_samples;
        let end = (first + f.shard_samples).min(f.samples);
        let t0 = self.bench_index(first);
        let benches: Vec<BenchKernel> = match &self.drawn {
            Some(d) => (t0..=self.bench_index(end - 1))
                .map(|t| self.drawn_bench(d, t))
                .collect::<Result<_>>()?,
            None => Vec::new(),
        };
        let start = std::time::Instant::now();
        // The latest end of a sample, in nanoseconds since `start` (one atomic store a sample).
        let last_end = std::sync::atomic::AtomicU64::new(0);
        let samples: Vec<Result<Sample>> = (first..end)
            .into_par_iter()
            .map(|s| {
                let bench = benches.get((self.bench_index(s) - t0) as usize);
                let v = self.sample_on(s, bench);
                let ns = u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
                last_end.fetch_max(ns, std::sync::atomic::Ordering::Relaxed);
                v
            })
            .collect();
        let samples = crate::error::in_order(samples)?;
        let last = std::time::Duration::from_nanos(last_end.into_inner());
        Ok((samples, start.elapsed().saturating_sub(last).as_secs_f64()))
    }
}
