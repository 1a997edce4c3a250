//! The findings `run` opens its report and its printed summary with: which scheme scores best
//! at each sampling ratio and at equal DMD frames, and by how much against every other scheme
//! (the fair baselines, calibrated and offset-aware double-arm, included).
//!
//! With `--repeats N` every difference is paired: both schemes' scores come from the same
//! repeat (the same noise and drift seed, the same drawn patterns), so the difference of each
//! repeat is one sample and its 95 % interval is the Student-t interval of their mean
//! (N − 1 degrees of freedom, crate::run::repeats::t95). A scheme is called ahead only when that
//! interval excludes 0; otherwise the two are "not distinguished". With one repeat there is no
//! interval and the text says so.
//!
//! At equal frames: the schemes show different numbers of DMD frames at one ratio (a pattern
//! and its complement are two frames). The scores are compared at the frame counts the
//! reference scheme (SCB when it ran) shows, each scheme's score interpolated linearly in
//! log(frames) between its two neighbouring ratios, repeat by repeat (so the differences stay
//! paired); a scheme whose frames do not reach a budget is left out of that comparison.
//!
//! The same standings are written to `summary.json` ([`Record`], under `findings`), so a
//! script reads the result the report states.

use serde::Serialize;

use crate::acquisition::Scheme;
use crate::run::RunOutcome;
use crate::run::repeats::t95;

/// Which score a comparison ranks by.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Score {
    Mssim,
    PsnrDb,
}

impl Score {
    pub fn label(self) -> &'static str {
        match self {
            Score::Mssim => "MSSIM",
            Score::PsnrDb => "PSNR (dB)",
        }
    }

    /// Decimals its values and differences are printed with.
    fn decimals(self) -> usize {
        match self {
            Score::Mssim => 4,
            Score::PsnrDb => 2,
        }
    }

    fn of(self, r: &crate::pipeline::SchemeResult) -> f64 {
        match self {
            Score::Mssim => r.mssim,
            Score::PsnrDb => r.psnr_db,
        }
    }
}

/// Every repeat's scores, indexed [scheme][ratio][repeat].
#[derive(Debug, Clone, PartialEq)]
pub struct Scores {
    pub schemes: Vec<Scheme>,
    pub ratios: Vec<f64>,
    /// DMD frames shown, [scheme][ratio] (the same in every repeat).
    pub frames: Vec<Vec<usize>>,
    pub values: Vec<Vec<Vec<f64>>>,
}

impl Scores {
    /// The scores of repeated outcomes of one scene (repeat 0 first).
    pub fn of(outcomes: &[RunOutcome], score: Score) -> Scores {
        let s = &outcomes[0].settings;
        let n_ratio = s.sampling_ratios.len();
        let at = |k: usize, r: usize| k * n_ratio + r;
        Scores {
            schemes: s.schemes.clone(),
            ratios: s.sampling_ratios.clone(),
            frames: (0..s.schemes.len())
                .map(|k| {
                    (0..n_ratio)
                        .map(|r| outcomes[0].results[at(k, r)].dmd_frames)
                        .collect()
                })
                .collect(),
            values: (0..s.schemes.len())
                .map(|k| {
                    (0..n_ratio)
                        .map(|r| {
                            outcomes
                                .iter()
                                .map(|o| score.of(&o.results[at(k, r)]))
                                .collect()
                        })
                        .collect()
                })
                .collect(),
        }
    }

    fn repeats(&self) -> usize {
        self.values
            .first()
            .and_then(|v| v.first())
            .map_or(0, Vec::len)
    }

    /// Scheme k's per-repeat scores at `frames`, interpolated linearly in log(frames) between
    /// its neighbouring ratios; None outside its range of frames.
    fn at_frames(&self, k: usize, frames: f64) -> Option<Vec<f64>> {
        let f = &self.frames[k];
        let mut order: Vec<usize> = (0..f.len()).collect();
        order.sort_by_key(|&r| f[r]);
        for w in order.windows(2) {
            let (a, b) = (w[0], w[1]);
            let (fa, fb) = (f[a] as f64, f[b] as f64);
            if frames < fa || frames > fb || fa <= 0.0 {
                continue;
            }
            let t = if fb > fa {
                (frames.ln() - fa.ln()) / (fb.ln() - fa.ln())
            } else {
                0.0
            };
            let (va, vb) = (&self.values[k][a], &self.values[k][b]);
            return Some(va.iter().zip(vb).map(|(x, y)| x + t * (y - x)).collect());
        }
        // One ratio only, or a budget equal to a frame count with no neighbour.
        order
            .iter()
            .find(|&&r| f[r] as f64 == frames)
            .map(|&r| self.values[k][r].clone())
    }
}

/// Where a comparison is made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Budget {
    Ratio(f64),
    Frames(f64),
}

impl Budget {
    pub fn label(self) -> String {
        match self {
            Budget::Ratio(r) => pct(r),
            Budget::Frames(f) => format!("{f:.0} frames"),
        }
    }
}

/// The best scheme's score minus another's, over the repeats.
#[derive(Debug, Clone, PartialEq)]
pub struct Margin {
    pub other: Scheme,
    pub mean: f64,
    pub sd: f64,
    /// Student-t 95 % interval of the mean difference; None for one repeat.
    pub ci95: Option<[f64; 2]>,
}

impl Margin {
    /// Whether the 95 % interval excludes 0 (None without an interval).
    pub fn distinguished(&self) -> Option<bool> {
        self.ci95.map(|[lo, hi]| lo > 0.0 || hi < 0.0)
    }
}

/// One comparison: the scheme with the highest mean score, and its margin over every other.
#[derive(Debug, Clone, PartialEq)]
pub struct Standing {
    pub at: Budget,
    pub best: Scheme,
    pub best_mean: f64,
    pub best_sd: f64,
    pub repeats: usize,
    /// Every other scheme compared, closest first.
    pub margins: Vec<Margin>,
}

impl Standing {
    /// The schemes the best is not distinguished from (its interval contains 0).
    pub fn tied_with(&self) -> Vec<Scheme> {
        self.margins
            .iter()
            .filter(|m| m.distinguished() == Some(false))
            .map(|m| m.other)
            .collect()
    }

    /// The comparison in one sentence, honest about ties and single runs.
    pub fn sentence(&self, score: Score) -> String {
        let d = score.decimals();
        let head = format!(
            "At {}, {} has the highest mean {} ({:.d$}{})",
            self.at.label(),
            self.best.label(),
            score.label(),
            self.best_mean,
            if self.repeats > 1 {
                format!(" ± {:.d$} SD", self.best_sd)
            } else {
                String::new()
            },
        );
        let Some(next) = self.margins.first() else {
            return format!("{head}; no other scheme to compare.");
        };
        if self.repeats < 2 {
            return format!(
                "{head}, {:+.d$} above {} (one run: no interval, so not a tested difference; \
                 --repeats N gives paired 95 % intervals).",
                next.mean,
                next.other.label()
            );
        }
        let tied = self.tied_with();
        if tied.is_empty() {
            format!(
                "{head}: ahead of every other scheme, nearest {} by {} (paired 95 % interval \
                 excludes 0).",
                next.other.label(),
                interval(next, d)
            )
        } else {
            // Labels contain commas ("Double-arm, calibrated"): list them with "and".
            let names: Vec<&str> = tied.iter().map(|s| s.label()).collect();
            format!(
                "{head}, but it is not distinguished from {} (the 95 % interval of the paired \
                 difference contains 0; nearest: {} by {}).",
                names.join(" and "),
                next.other.label(),
                interval(next, d)
            )
        }
    }
}

/// "+0.0021 [−0.0010, +0.0052]", or the mean alone without an interval.
pub fn interval(m: &Margin, d: usize) -> String {
    match m.ci95 {
        Some([lo, hi]) => format!("{:+.d$} [{lo:+.d$}, {hi:+.d$}]", m.mean),
        None => format!("{:+.d$}", m.mean),
    }
}

/// Mean and sample standard deviation (0 for one value).
fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, 0.0);
    }
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

/// The standing among `entries` (scheme, per-repeat scores, all of one length); None for none.
pub fn standing(at: Budget, entries: &[(Scheme, Vec<f64>)]) -> Option<Standing> {
    let means: Vec<f64> = entries.iter().map(|(_, v)| mean_sd(v).0).collect();
    let best = (0..entries.len())
        .filter(|&i| means[i].is_finite())
        .max_by(|&a, &b| means[a].total_cmp(&means[b]))?;
    let (best_mean, best_sd) = mean_sd(&entries[best].1);
    let n = entries[best].1.len();
    let mut margins: Vec<Margin> = entries
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != best)
        .map(|(_, (other, v))| {
            let d: Vec<f64> = entries[best].1.iter().zip(v).map(|(a, b)| a - b).collect();
            let (mean, sd) = mean_sd(&d);
            let ci95 = (n > 1).then(|| {
                let h = t95(n - 1) * sd / (n as f64).sqrt();
                [mean - h, mean + h]
            });
            Margin {
                other: *other,
                mean,
                sd,
                ci95,
            }
        })
        .collect();
    margins.sort_by(|a, b| a.mean.total_cmp(&b.mean));
    Some(Standing {
        at,
        best: entries[best].0,
        best_mean,
        best_sd,
        repeats: n,
        margins,
    })
}

/// The standings at every ratio.
pub fn at_ratios(s: &Scores) -> Vec<Standing> {
    (0..s.ratios.len())
        .filter_map(|r| {
            let entries: Vec<(Scheme, Vec<f64>)> = s
                .schemes
                .iter()
                .enumerate()
                .map(|(k, &scheme)| (scheme, s.values[k][r].clone()))
                .collect();
            standing(Budget::Ratio(s.ratios[r]), &entries)
        })
        .collect()
}

/// The scheme whose frame counts set the equal-frame budgets: SCB when it ran, else the
/// scheme showing the most frames (so the others reach its budgets at a higher ratio).
fn reference(s: &Scores) -> Option<usize> {
    s.schemes
        .iter()
        .position(|&k| k == Scheme::SecondaryComplementaryBalancing)
        .or_else(|| (0..s.schemes.len()).max_by_key(|&k| s.frames[k].iter().max().copied()))
}

/// The standings at the reference scheme's frame counts, among the schemes whose frames reach
/// each budget (at least two). Empty when every scheme shows the same frames at each ratio
/// (then equal frames are the ratios themselves).
pub fn at_equal_frames(s: &Scores) -> Vec<Standing> {
    let Some(rk) = reference(s) else {
        return Vec::new();
    };
    let all_equal = (0..s.ratios.len()).all(|r| s.frames.iter().all(|f| f[r] == s.frames[rk][r]));
    if all_equal {
        return Vec::new();
    }
    let mut budgets: Vec<usize> = s.frames[rk].clone();
    budgets.sort_unstable();
    budgets.dedup();
    budgets
        .into_iter()
        .filter_map(|b| {
            let entries: Vec<(Scheme, Vec<f64>)> = (0..s.schemes.len())
                .filter_map(|k| Some((s.schemes[k], s.at_frames(k, b as f64)?)))
                .collect();
            if entries.len() < 2 {
                return None;
            }
            standing(Budget::Frames(b as f64), &entries)
        })
        .collect()
}

/// Everything the findings say, for both scores.
#[derive(Debug, Clone, PartialEq)]
pub struct Findings {
    pub repeats: usize,
    pub schemes: Vec<Scheme>,
    /// (score, standings at each ratio, standings at equal frames).
    pub by_score: Vec<(Score, Vec<Standing>, Vec<Standing>)>,
}

impl Findings {
    pub fn of(outcomes: &[RunOutcome]) -> Findings {
        let by_score = [Score::Mssim, Score::PsnrDb]
            .into_iter()
            .map(|score| {
                let s = Scores::of(outcomes, score);
                (score, at_ratios(&s), at_equal_frames(&s))
            })
            .collect();
        let first = Scores::of(outcomes, Score::Mssim);
        Findings {
            repeats: first.repeats(),
            schemes: first.schemes,
            by_score,
        }
    }

    /// What the differences are, in one sentence.
    pub fn basis(&self) -> String {
        if self.repeats > 1 {
            format!(
                "Scores are means over {} repeats; each difference is paired (both schemes \
                 from the same repeat: the same noise and drift seed and patterns), with its \
                 Student-t 95 % interval (t = {:.3}, {} degrees of freedom). Two schemes are \
                 called not distinguished when that interval contains 0.",
                self.repeats,
                t95(self.repeats - 1),
                self.repeats - 1
            )
        } else {
            "One run (one noise draw): the differences below have no interval and are not \
             tested; run with --repeats N (N ≥ 2) for paired 95 % intervals."
                .to_string()
        }
    }

    /// A table of standings: one row per budget, the best scheme and its mean, then for every
    /// scheme the best's margin over it (the best's own cell names it).
    pub fn table(&self, score: Score, standings: &[Standing]) -> (Vec<String>, Vec<Vec<String>>) {
        let d = score.decimals();
        let mut header = vec!["at".to_string(), "best".into(), score.label().into()];
        header.extend(self.schemes.iter().map(|s| format!("best − {}", s.label())));
        let rows = standings
            .iter()
            .map(|st| {
                let mut row = vec![
                    st.at.label(),
                    st.best.label().to_string(),
                    if st.repeats > 1 {
                        format!("{:.d$} ± {:.d$}", st.best_mean, st.best_sd)
                    } else {
                        format!("{:.d$}", st.best_mean)
                    },
                ];
                for k in &self.schemes {
                    row.push(if *k == st.best {
                        "best".into()
                    } else {
                        match st.margins.iter().find(|m| m.other == *k) {
                            Some(m) => {
                                let tag = match m.distinguished() {
                                    Some(false) => " (not distinguished)",
                                    _ => "",
                                };
                                format!("{}{tag}", interval(m, d))
                            }
                            None => "–".into(),
                        }
                    });
                }
                row
            })
            .collect();
        (header, rows)
    }

    /// The printed findings, under 100 columns: one line per ratio (best scheme, its nearest
    /// rival and whether the two are distinguished), then the same at equal frames.
    pub fn printed(&self) -> Vec<String> {
        let mut lines = vec![format!(
            "findings (MSSIM; {}):",
            if self.repeats > 1 {
                format!(
                    "means of {} repeats, paired differences with 95 % intervals",
                    self.repeats
                )
            } else {
                "one run, differences not tested: --repeats N for intervals".into()
            }
        )];
        lines.push(
            "  (where; best scheme, its mean | nearest other scheme: best − it [95 % interval])"
                .to_string(),
        );
        let Some((score, ratios, frames)) = self.by_score.first() else {
            return lines;
        };
        let d = score.decimals();
        for (title, list) in [("at each ratio", ratios), ("at equal DMD frames", frames)] {
            if list.is_empty() {
                continue;
            }
            lines.push(format!("  {title}:"));
            for st in list {
                let mut line = format!(
                    "  {:>11} {:<15} {:.d$}",
                    st.at.label(),
                    short(st.best),
                    st.best_mean
                );
                if let Some(m) = st.margins.first() {
                    let verdict = m.verdict().replace('_', " ");
                    line += &format!(" | {:<15} {} {verdict}", short(m.other), interval(m, d));
                }
                lines.push(line);
            }
        }
        lines.push("  (every scheme's margin, and PSNR: report.html, \"Findings\")".to_string());
        lines
    }
}

/// The findings as `summary.json` holds them (beside the paper's comparisons under
/// `findings`): for each score, the standings at each ratio and at equal DMD frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Record {
    /// Repeats the scores are over (1: one run, whose differences are not tested).
    pub repeats: usize,
    /// How the differences were made and tested, in one sentence.
    pub basis: String,
    pub mssim: ScoreRecord,
    pub psnr_db: ScoreRecord,
}

/// One score's standings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoreRecord {
    pub at_ratios: Vec<StandingRecord>,
    pub at_equal_frames: Vec<StandingRecord>,
}

/// One standing: where, the best scheme, and its margin over every other scheme compared.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StandingRecord {
    /// The sampling ratio (null at equal frames).
    pub ratio: Option<f64>,
    /// The DMD frame budget (null at a ratio).
    pub frames: Option<u64>,
    pub best: Scheme,
    /// Its mean score and sample SD over the repeats (SD 0 for one run).
    pub best_mean: f64,
    pub best_sd: f64,
    /// Closest first.
    pub margins: Vec<MarginRecord>,
}

/// The best scheme's score minus `scheme`'s, over the repeats.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarginRecord {
    pub scheme: Scheme,
    pub mean: f64,
    pub sd: f64,
    /// Paired Student-t 95 % interval of the mean; null for one run.
    pub ci95: Option<[f64; 2]>,
    /// `ahead` (interval excludes 0), `not_distinguished` (contains 0) or `untested` (one run).
    pub verdict: &'static str,
}

impl Margin {
    /// The verdict word of [`MarginRecord::verdict`].
    pub fn verdict(&self) -> &'static str {
        match self.distinguished() {
            Some(true) => "ahead",
            Some(false) => "not_distinguished",
            None => "untested",
        }
    }
}

impl Standing {
    fn record(&self) -> StandingRecord {
        let (ratio, frames) = match self.at {
            Budget::Ratio(r) => (Some(r), None),
            Budget::Frames(f) => (None, Some(f.round() as u64)),
        };
        StandingRecord {
            ratio,
            frames,
            best: self.best,
            best_mean: self.best_mean,
            best_sd: self.best_sd,
            margins: self
                .margins
                .iter()
                .map(|m| MarginRecord {
                    scheme: m.other,
                    mean: m.mean,
                    sd: m.sd,
                    ci95: m.ci95,
                    verdict: m.verdict(),
                })
                .collect(),
        }
    }
}

impl Findings {
    /// The findings as written to summary.json.
    pub fn record(&self) -> Record {
        let of = |score: Score| {
            let (ratios, frames) = self
                .by_score
                .iter()
                .find(|(s, _, _)| *s == score)
                .map(|(_, r, f)| (r.as_slice(), f.as_slice()))
                .unwrap_or((&[], &[]));
            ScoreRecord {
                at_ratios: ratios.iter().map(Standing::record).collect(),
                at_equal_frames: frames.iter().map(Standing::record).collect(),
            }
        };
        Record {
            repeats: self.repeats,
            basis: self.basis(),
            mssim: of(Score::Mssim),
            psnr_db: of(Score::PsnrDb),
        }
    }
}

/// A ratio as a percentage: "40 %", "12.5 %".
pub fn pct(r: f64) -> String {
    let p = r * 100.0;
    if (p - p.round()).abs() < 1e-9 {
        format!("{p:.0} %")
    } else {
        format!("{p:.1} %")
    }
}

/// A short name for the terminal.
pub fn short(s: Scheme) -> &'static str {
    use crate::acquisition::Scheme::*;
    match s {
        Traditional => "traditional",
        SingleArmComplementary => "single-arm",
        DoubleArm => "double-arm",
        SecondaryComplementaryBalancing => "SCB",
        TraditionalZeroMean => "trad. zero-mean",
        DoubleArmCalibrated => "cal. double-arm",
        DoubleArmOffset => "offset dbl-arm",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acquisition::Scheme::*;

    fn scores(frames: Vec<Vec<usize>>, values: Vec<Vec<Vec<f64>>>) -> Scores {
        Scores {
            schemes: vec![
                SecondaryComplementaryBalancing,
                DoubleArmCalibrated,
                Traditional,
            ],
            ratios: vec![0.25, 0.5],
            frames,
            values,
        }
    }

    /// A lead whose paired interval contains 0 is reported as not distinguished, and one that
    /// excludes 0 as ahead; the interval is the paired Student-t one.
    #[test]
    fn a_lead_within_the_noise_is_not_called_a_win() {
        // SCB leads calibrated double-arm by 0.001 on average, with per-repeat differences
        // +0.011, −0.009, +0.001: interval ±0.025, contains 0. Traditional trails by ~0.1.
        let s = scores(
            vec![vec![10, 20], vec![10, 20], vec![5, 10]],
            vec![
                vec![vec![0.911, 0.891, 0.901], vec![0.95, 0.95, 0.95]],
                vec![vec![0.900, 0.900, 0.900], vec![0.96, 0.96, 0.96]],
                vec![vec![0.80, 0.81, 0.79], vec![0.90, 0.90, 0.90]],
            ],
        );
        let st = at_ratios(&s);
        assert_eq!(st[0].best, SecondaryComplementaryBalancing);
        let m = &st[0].margins[0];
        assert_eq!(m.other, DoubleArmCalibrated);
        assert!((m.mean - 0.001).abs() < 1e-12);
        let [lo, hi] = m.ci95.unwrap();
        let h = 4.303 * 0.01 / 3f64.sqrt();
        assert!((hi - lo - 2.0 * h).abs() < 1e-9, "{lo} {hi}");
        assert_eq!(m.distinguished(), Some(false));
        assert_eq!(st[0].margins[1].distinguished(), Some(true));
        let text = st[0].sentence(Score::Mssim);
        assert!(
            text.contains("not distinguished from Double-arm, calibrated"),
            "{text}"
        );
        // At 50 %, calibrated double-arm leads by a constant 0.01: zero spread, ahead.
        assert_eq!(st[1].best, DoubleArmCalibrated);
        assert_eq!(st[1].margins[0].distinguished(), Some(true));
        assert!(
            st[1]
                .sentence(Score::Mssim)
                .contains("ahead of every other")
        );
    }

    /// One repeat: no interval, and the sentence says the difference is untested.
    #[test]
    fn one_run_has_no_interval() {
        let s = scores(
            vec![vec![10, 20], vec![10, 20], vec![5, 10]],
            vec![
                vec![vec![0.9], vec![0.95]],
                vec![vec![0.8], vec![0.90]],
                vec![vec![0.7], vec![0.85]],
            ],
        );
        let st = at_ratios(&s);
        assert_eq!(st[0].margins[0].ci95, None);
        assert!(
            st[0]
                .sentence(Score::Mssim)
                .contains("not a tested difference")
        );
    }

    /// At equal frames each scheme is read at the reference's frame counts, interpolated in
    /// log(frames), repeat by repeat; schemes that do not reach a budget are left out.
    #[test]
    fn equal_frames_interpolate_in_log_frames() {
        let s = scores(
            vec![vec![10, 20], vec![10, 20], vec![5, 10]],
            vec![
                vec![vec![0.5, 0.6], vec![0.7, 0.8]],
                vec![vec![0.4, 0.4], vec![0.6, 0.6]],
                vec![vec![0.6, 0.6], vec![0.9, 0.9]],
            ],
        );
        let st = at_equal_frames(&s);
        // Budgets 10 and 20 (SCB's frames); traditional reaches only 10 (at its 50 %).
        assert_eq!(st.len(), 2);
        assert_eq!(st[0].at, Budget::Frames(10.0));
        assert_eq!(st[0].best, Traditional);
        assert_eq!(st[0].margins.len(), 2);
        assert_eq!(st[1].margins.len(), 1);
        // Interpolation halfway in log frames.
        let v = s.at_frames(2, 50f64.sqrt()).unwrap();
        assert!((v[0] - 0.75).abs() < 1e-12, "{v:?}");
        assert_eq!(s.at_frames(2, 20.0), None);
    }

    /// Every printed line fits 100 columns.
    #[test]
    fn printed_findings_fit_100_columns() {
        let s = scores(
            vec![vec![10, 20], vec![10, 20], vec![5, 10]],
            vec![
                vec![vec![0.5, 0.6], vec![0.7, 0.8]],
                vec![vec![0.4, 0.4], vec![0.6, 0.6]],
                vec![vec![0.6, 0.6], vec![0.9, 0.9]],
            ],
        );
        let f = Findings {
            repeats: 2,
            schemes: s.schemes.clone(),
            by_score: vec![(Score::Mssim, at_ratios(&s), at_equal_frames(&s))],
        };
        let lines = f.printed();
        assert!(lines.len() >= 6);
        for l in &lines {
            assert!(
                l.chars().count() <= 100,
                "{} columns: {l}",
                l.chars().count()
            );
        }
    }
}
