//! The names of the numbers a bench is judged by: the twelve traced bench metrics
//! ([`BenchMetric`], whose values and standard errors `crate::transport::metrics` computes),
//! and every quantity an evaluated bench records ([`Quantity`]: a bench metric, a common-mode
//! rejection or an image score). They are types inside the crate; their text, the keys of the
//! JSON and CSV outputs and the names a tolerance file or a command line gives, is written and
//! read here alone ([`BenchMetric::key`], `FromStr`, `Display`).

use std::fmt;
use std::ops::{Index, IndexMut};
use std::str::FromStr;

/// One of the traced bench metrics. Each indexes a per-metric array (`[T; 12]`) in the order of
/// [`BenchMetric::ALL`], the order of every output that lists them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BenchMetric {
    KPlus,
    KMinus,
    KPrime,
    Imbalance,
    BPlus,
    BMinus,
    BMinusMinusBPlus,
    PowerPlusW,
    PowerMinusW,
    LeakPlus,
    LeakMinus,
    XTotalW,
}

/// The number of bench metrics.
pub const BENCH_METRICS: usize = 12;

impl BenchMetric {
    /// Every metric in table order.
    pub const ALL: [BenchMetric; BENCH_METRICS] = [
        BenchMetric::KPlus,
        BenchMetric::KMinus,
        BenchMetric::KPrime,
        BenchMetric::Imbalance,
        BenchMetric::BPlus,
        BenchMetric::BMinus,
        BenchMetric::BMinusMinusBPlus,
        BenchMetric::PowerPlusW,
        BenchMetric::PowerMinusW,
        BenchMetric::LeakPlus,
        BenchMetric::LeakMinus,
        BenchMetric::XTotalW,
    ];

    /// The metric's index in a per-metric array.
    #[inline]
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The name in files and on the command line.
    pub const fn key(self) -> &'static str {
        match self {
            BenchMetric::KPlus => "k_plus",
            BenchMetric::KMinus => "k_minus",
            BenchMetric::KPrime => "k_prime",
            BenchMetric::Imbalance => "imbalance",
            BenchMetric::BPlus => "b_plus",
            BenchMetric::BMinus => "b_minus",
            BenchMetric::BMinusMinusBPlus => "b_minus_minus_b_plus",
            BenchMetric::PowerPlusW => "power_plus_w",
            BenchMetric::PowerMinusW => "power_minus_w",
            BenchMetric::LeakPlus => "leak_plus",
            BenchMetric::LeakMinus => "leak_minus",
            BenchMetric::XTotalW => "x_total_w",
        }
    }

    /// The SI unit of the value.
    pub const fn unit(self) -> &'static str {
        match self {
            BenchMetric::KPlus | BenchMetric::KMinus | BenchMetric::KPrime => "A/W",
            BenchMetric::BPlus | BenchMetric::BMinus | BenchMetric::BMinusMinusBPlus => "A",
            BenchMetric::PowerPlusW | BenchMetric::PowerMinusW | BenchMetric::XTotalW => "W",
            BenchMetric::Imbalance | BenchMetric::LeakPlus | BenchMetric::LeakMinus => "1",
        }
    }

    /// What the metric is.
    pub const fn meaning(self) -> &'static str {
        match self {
            BenchMetric::KPlus => "k₊ = Σ_j g₊_j / Σ_j x_j",
            BenchMetric::KMinus => "k₋ = Σ_j g₋_j / Σ_j x_j",
            BenchMetric::KPrime => "k' = k₊ + k₋, the SCB image scale",
            BenchMetric::Imbalance => "(k₊ − k₋)/(k₊ + k₋)",
            BenchMetric::BPlus => {
                "b₊: pattern-independent current of arm + (traced light, ambient, dark)"
            }
            BenchMetric::BMinus => "b₋, as b₊ for arm −",
            BenchMetric::BMinusMinusBPlus => "b₋ − b₊, the offset double-arm detection leaves",
            BenchMetric::PowerPlusW => "power on diode + with every pattern unit in state +",
            BenchMetric::PowerMinusW => "power on diode − with every pattern unit in state −",
            BenchMetric::LeakPlus => {
                "off-arm leak: power on diode − / power on diode + with every unit in state +"
            }
            BenchMetric::LeakMinus => {
                "off-arm leak: power on diode + / power on diode − with every unit in state −"
            }
            BenchMetric::XTotalW => "Σ_j x_j, power on the pattern area",
        }
    }

    /// Whether the metric is an off-arm leak (a ratio of two diodes' powers).
    pub const fn is_leak(self) -> bool {
        matches!(self, BenchMetric::LeakPlus | BenchMetric::LeakMinus)
    }

    /// Every key, in table order, separated by ", " (for messages).
    pub fn keys() -> String {
        BenchMetric::ALL.map(BenchMetric::key).join(", ")
    }
}

impl fmt::Display for BenchMetric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.key())
    }
}

/// A name that is not one of the closed set it was read as; the text is kept for the message
/// of whoever reads it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownName(pub String);

impl fmt::Display for UnknownName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}` is not a known name", self.0)
    }
}

impl std::error::Error for UnknownName {}

impl FromStr for BenchMetric {
    type Err = UnknownName;

    /// A metric's [`BenchMetric::key`].
    fn from_str(s: &str) -> Result<BenchMetric, UnknownName> {
        BenchMetric::ALL
            .into_iter()
            .find(|m| m.key() == s)
            .ok_or_else(|| UnknownName(s.to_string()))
    }
}

/// Per-metric arrays are indexed by metric: `values[BenchMetric::Imbalance]`.
impl<T> Index<BenchMetric> for [T] {
    type Output = T;
    #[inline]
    fn index(&self, m: BenchMetric) -> &T {
        &self[m.index()]
    }
}

impl<T> IndexMut<BenchMetric> for [T] {
    #[inline]
    fn index_mut(&mut self, m: BenchMetric) -> &mut T {
        &mut self[m.index()]
    }
}

/// An image score recorded per scheme and sampling ratio when an evaluation runs the whole
/// pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ImageScore {
    Mssim,
    PsnrDb,
    /// The finest resolved USAF element (lp/mm).
    FinestLpPerMm,
}

impl ImageScore {
    /// In the order an evaluation records them.
    pub const ALL: [ImageScore; 3] = [
        ImageScore::Mssim,
        ImageScore::PsnrDb,
        ImageScore::FinestLpPerMm,
    ];

    /// The suffix of the recorded name after `SCHEME_PERCENT_`.
    pub const fn suffix(self) -> &'static str {
        match self {
            ImageScore::Mssim => "mssim",
            ImageScore::PsnrDb => "psnr_db",
            ImageScore::FinestLpPerMm => "finest_lp_per_mm",
        }
    }

    /// The score whose name `name` ends with (`_mssim`, `_psnr_db`, `_finest_lp_per_mm`), and
    /// the rest of the name before that `_`.
    pub fn split(name: &str) -> Option<(&str, ImageScore)> {
        ImageScore::ALL.into_iter().find_map(|s| {
            name.strip_suffix(s.suffix())
                .and_then(|rest| rest.strip_suffix('_'))
                .map(|rest| (rest, s))
        })
    }
}

/// A quantity recorded for every evaluated bench, as the limits of a tolerance file and of
/// `sweep`, the tolerance report and the metric rows name it.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Quantity {
    Metric(BenchMetric),
    /// The bench's common-mode rejection with the arms' k± in it (`cmrr_db`).
    Cmrr,
    /// The detector's common-mode rejection from its electronics alone
    /// (`cmrr_electronics_db`).
    CmrrElectronics,
    /// An image score; `key` is the `SCHEME_PERCENT` part of its name (which scheme and ratio
    /// a run scores is known only to that run).
    Score {
        key: String,
        score: ImageScore,
    },
}

impl Quantity {
    /// The common-mode rejections every evaluation records beside the traced metrics.
    pub const CMRRS: [Quantity; 2] = [Quantity::Cmrr, Quantity::CmrrElectronics];

    /// Whether this is a traced bench metric or a CMRR (recorded for every bench), not an image
    /// score (recorded only with the whole pipeline).
    pub fn is_traced(&self) -> bool {
        !matches!(self, Quantity::Score { .. })
    }

    /// The bench metric, if it is one.
    pub fn metric(&self) -> Option<BenchMetric> {
        match self {
            Quantity::Metric(m) => Some(*m),
            _ => None,
        }
    }
}

impl From<BenchMetric> for Quantity {
    fn from(m: BenchMetric) -> Quantity {
        Quantity::Metric(m)
    }
}

impl fmt::Display for Quantity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Quantity::Metric(m) => f.write_str(m.key()),
            Quantity::Cmrr => f.write_str("cmrr_db"),
            Quantity::CmrrElectronics => f.write_str("cmrr_electronics_db"),
            Quantity::Score { key, score } => write!(f, "{key}_{}", score.suffix()),
        }
    }
}

impl FromStr for Quantity {
    type Err = UnknownName;

    /// A bench metric's key, `cmrr_db`, `cmrr_electronics_db`, or any name ending in `_mssim`,
    /// `_psnr_db` or `_finest_lp_per_mm` (an image score of some scheme and ratio).
    fn from_str(s: &str) -> Result<Quantity, UnknownName> {
        if let Ok(m) = s.parse::<BenchMetric>() {
            return Ok(Quantity::Metric(m));
        }
        if let Some(q) = Quantity::CMRRS.into_iter().find(|q| q.to_string() == s) {
            return Ok(q);
        }
        match ImageScore::split(s) {
            Some((key, score)) => Ok(Quantity::Score {
                key: key.to_string(),
                score,
            }),
            None => Err(UnknownName(s.to_string())),
        }
    }
}

impl serde::Serialize for Quantity {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_read_back_as_they_are_written() {
        for (i, m) in BenchMetric::ALL.into_iter().enumerate() {
            assert_eq!(m.index(), i);
            assert_eq!(m.key().parse::<BenchMetric>(), Ok(m));
            assert_eq!(m.to_string().parse::<Quantity>(), Ok(Quantity::Metric(m)));
        }
        let arr: [usize; BENCH_METRICS] = std::array::from_fn(|i| i);
        assert_eq!(arr[BenchMetric::XTotalW], 11);
        assert!("k_plus_stderr".parse::<BenchMetric>().is_err());
        for q in Quantity::CMRRS {
            assert_eq!(q.to_string().parse::<Quantity>(), Ok(q.clone()));
        }
        let s: Quantity = "secondary_complementary_balancing_40_mssim"
            .parse()
            .unwrap();
        assert_eq!(
            s,
            Quantity::Score {
                key: "secondary_complementary_balancing_40".into(),
                score: ImageScore::Mssim
            }
        );
        assert_eq!(s.to_string(), "secondary_complementary_balancing_40_mssim");
        assert!("scb_40_finest_lp_per_mm".parse::<Quantity>().is_ok());
        assert!("arrivals".parse::<Quantity>().is_err());
        assert!("imbalanse".parse::<Quantity>().is_err());
        assert!("cmrr_db_stderr".parse::<Quantity>().is_err());
    }
}
