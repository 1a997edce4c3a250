//! What a trace records: per-batch tallies and their merge in batch order.
//!
//! Per-arm arrays (`[T; 2]`) are indexed by [`Arm`] (+ is 0, − is 1); the tallies T keep arm
//! and mirror state apart ([`BatchTally::t_index`]).

use crate::optics::Arm;
use crate::optics::dmd::{MirrorState, state_index};

/// Index of the ledger "worlds": light before any DMD split (counted in both mirror-state worlds)
/// and the two branches after it.
pub const COMMON: usize = 0;
pub const BRANCH_PLUS: usize = 1;
pub const BRANCH_MINUS: usize = 2;

/// The ledger world of the branch whose pattern mirrors are all in `state` (+ or −).
#[inline]
pub const fn branch(state: MirrorState) -> usize {
    match state {
        MirrorState::Plus => BRANCH_PLUS,
        MirrorState::Minus => BRANCH_MINUS,
        MirrorState::Flat => panic!("a branch has its pattern mirrors in state + or −"),
    }
}

/// The mirror state of the pattern area in ledger world `world`: None for [`COMMON`] (light
/// that has not met the pattern area yet).
#[inline]
pub const fn branch_state(world: usize) -> Option<MirrorState> {
    match world {
        BRANCH_PLUS => Some(MirrorState::Plus),
        BRANCH_MINUS => Some(MirrorState::Minus),
        _ => None,
    }
}

/// Ledger slots after the per-element absorption slots (offsets from `elements.len()`).
pub const SLOT_ESCAPED: usize = 0;
pub const SLOT_PATH_CAP: usize = 1;
pub const SLOT_DETECTED_PLUS: usize = 2;
pub const SLOT_DETECTED_MINUS: usize = 3;
/// The traced emission (sum of initial ray weights); only in the common world.
pub const SLOT_EMITTED: usize = 4;
/// Weight added by following sampled reflections at their path's full weight
/// ([`Sampling::Split`](super::strata::Sampling::Split), `path::cross_interface`): signed, zero
/// in expectation, and zero with the analogue tracer.
pub const SLOT_SAMPLED: usize = 5;
pub const EXTRA_SLOTS: usize = 6;

/// The ledger slot of the power reaching the photodiode of `arm`.
#[inline]
pub const fn slot_detected(arm: Arm) -> usize {
    match arm {
        Arm::Plus => SLOT_DETECTED_PLUS,
        Arm::Minus => SLOT_DETECTED_MINUS,
    }
}

/// The tallies of one batch of rays. Powers in W, currents in A.
#[derive(Debug, Clone)]
pub struct BatchTally {
    pub rays: u64,
    /// Lamp rays whose path reached the pattern area (a diagnostic of sampling efficiency).
    pub arrivals: u64,
    /// Power incident on each unit's mirrors (units, row-major).
    pub x: Vec<f64>,
    /// Photocurrent of the detector of arm d when the path's first pattern unit j is in state s:
    /// index (d·2 + s)·units + j (d, s: 0 = +, 1 = −; [`BatchTally::t_index`]).
    pub t: Vec<f64>,
    /// Photocurrent of detector d from light that never met the pattern area (A).
    pub b: [f64; 2],
    /// Ledger per world ([`COMMON`], [`BRANCH_PLUS`], [`BRANCH_MINUS`]): absorbed power per
    /// element, then the extra slots.
    pub ledger: [Vec<f64>; 3],
}

impl BatchTally {
    pub fn new(units: usize, elements: usize) -> BatchTally {
        let slots = elements + EXTRA_SLOTS;
        BatchTally {
            rays: 0,
            arrivals: 0,
            x: vec![0.0; units],
            t: vec![0.0; 4 * units],
            b: [0.0; 2],
            ledger: [vec![0.0; slots], vec![0.0; slots], vec![0.0; slots]],
        }
    }

    /// The index of T[arm][state][j] in `t`: (d·2 + s)·units + j.
    #[inline]
    pub fn t_index(units: usize, arm: Arm, state: MirrorState, j: usize) -> usize {
        Self::t_block(arm, state) * units + j
    }

    /// The block d·2 + s of T[arm][state] (d, s: 0 = +, 1 = −), of `units` entries in `t`.
    #[inline]
    pub fn t_block(arm: Arm, state: MirrorState) -> usize {
        debug_assert!(state != MirrorState::Flat, "T has states + and − only");
        arm.index() * 2 + state_index(state)
    }

    /// Σ_j (T[d][on][j] − T[d][off][j]) for arm d: the batch's total gain Σ_j g_j of arm d,
    /// where arm + gains when a unit is in state + and arm − when it is in state −.
    pub fn gain_sum(&self, arm: Arm) -> f64 {
        let units = self.x.len();
        let (on, off) = (arm.state(), arm.other().state());
        (0..units)
            .map(|j| {
                self.t[Self::t_index(units, arm, on, j)] - self.t[Self::t_index(units, arm, off, j)]
            })
            .sum()
    }

    /// The pattern-independent traced current of arm d: Σ_j T[d][off][j] + B_d.
    pub fn offset_sum(&self, arm: Arm) -> f64 {
        let units = self.x.len();
        let off = arm.other().state();
        (0..units)
            .map(|j| self.t[Self::t_index(units, arm, off, j)])
            .sum::<f64>()
            + self.b[arm]
    }
}

/// Per-batch scalars kept for the standard errors (batch means).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BatchScalars {
    pub rays: u64,
    /// Σ_j x_j (W).
    pub x: f64,
    /// Σ_j g±_j (A).
    pub g: [f64; 2],
    /// Traced part of c± (A).
    pub c: [f64; 2],
    /// Unsplit detector currents B± (A) (the whole signal in a fixed-pattern trace).
    pub b: [f64; 2],
    /// Power reaching photodiode [+, −] (W) with every pattern unit in state + (index 0) and
    /// in state − (index 1): the ledger's detected slots, common part plus branch.
    pub detected_w: [[f64; 2]; 2],
}

/// The merged result of a trace.
#[derive(Debug, Clone, PartialEq)]
pub struct Tallies {
    pub rays: u64,
    /// Lamp rays whose path reached the pattern area.
    pub arrivals: u64,
    pub seed: u64,
    pub units_across: usize,
    pub units_down: usize,
    pub x: Vec<f64>,
    pub t: Vec<f64>,
    pub b: [f64; 2],
    pub ledger: [Vec<f64>; 3],
    /// Power emitted outside the traced cone (W), analytic.
    pub outside_cone_w: f64,
    pub batches: Vec<BatchScalars>,
    /// Per-unit sums over batches of x_b², g_b² (per arm) and g_b·x_b (per arm), for the
    /// standard errors of the maps.
    pub x2: Vec<f64>,
    pub g2: [Vec<f64>; 2],
    pub gx: [Vec<f64>; 2],
}

impl Tallies {
    pub fn new(
        units_across: usize,
        units_down: usize,
        elements: usize,
        seed: u64,
        outside_cone_w: f64,
    ) -> Tallies {
        let units = units_across * units_down;
        let slots = elements + EXTRA_SLOTS;
        Tallies {
            rays: 0,
            arrivals: 0,
            seed,
            units_across,
            units_down,
            x: vec![0.0; units],
            t: vec![0.0; 4 * units],
            b: [0.0; 2],
            ledger: [vec![0.0; slots], vec![0.0; slots], vec![0.0; slots]],
            outside_cone_w,
            batches: Vec::new(),
            x2: vec![0.0; units],
            g2: [vec![0.0; units], vec![0.0; units]],
            gx: [vec![0.0; units], vec![0.0; units]],
        }
    }

    pub fn units(&self) -> usize {
        self.x.len()
    }

    /// Adds one batch. Called in batch order, so the floating-point sums are the same for any
    /// number of threads.
    pub fn absorb(&mut self, b: &BatchTally) {
        let units = self.units();
        self.rays += b.rays;
        self.arrivals += b.arrivals;
        for j in 0..units {
            self.x[j] += b.x[j];
            self.x2[j] += b.x[j] * b.x[j];
            for arm in Arm::ALL {
                let on = b.t[BatchTally::t_index(units, arm, arm.state(), j)];
                let off = b.t[BatchTally::t_index(units, arm, arm.other().state(), j)];
                let g = on - off;
                self.g2[arm][j] += g * g;
                self.gx[arm][j] += g * b.x[j];
            }
        }
        for (a, v) in self.t.iter_mut().zip(&b.t) {
            *a += v;
        }
        for arm in Arm::ALL {
            self.b[arm] += b.b[arm];
        }
        for w in 0..3 {
            for (a, v) in self.ledger[w].iter_mut().zip(&b.ledger[w]) {
                *a += v;
            }
        }
        self.batches.push(BatchScalars {
            rays: b.rays,
            x: b.x.iter().sum(),
            g: Arm::ALL.map(|arm| b.gain_sum(arm)),
            c: Arm::ALL.map(|arm| b.offset_sum(arm)),
            b: b.b,
            detected_w: [MirrorState::Plus, MirrorState::Minus].map(|state| {
                let (world, n_el) = (branch(state), b.ledger[COMMON].len() - EXTRA_SLOTS);
                Arm::ALL.map(|arm| {
                    let slot = n_el + slot_detected(arm);
                    b.ledger[COMMON][slot] + b.ledger[world][slot]
                })
            }),
        });
    }
}
