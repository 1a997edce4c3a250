//! What a trace records: per-batch tallies and their merge in batch order.

/// Index of the ledger "worlds": light before any DMD split (counted in both mirror-state worlds)
/// and the two branches after it.
pub const COMMON: usize = 0;
pub const BRANCH_PLUS: usize = 1;
pub const BRANCH_MINUS: usize = 2;

/// Ledger slots after the per-element absorption slots (offsets from `elements.len()`).
pub const SLOT_ESCAPED: usize = 0;
pub const SLOT_PATH_CAP: usize = 1;
pub const SLOT_DETECTED_PLUS: usize = 2;
pub const SLOT_DETECTED_MINUS: usize = 3;
/// The traced emission (sum of initial ray weights); only in the common world.
pub const SLOT_EMITTED: usize = 4;
pub const EXTRA_SLOTS: usize = 5;

/// The tallies of one batch of rays. Powers in W, currents in A.
#[derive(Debug, Clone)]
pub struct BatchTally {
    pub rays: u64,
    /// Lamp rays whose path reached the pattern area (a diagnostic of sampling efficiency).
    pub arrivals: u64,
    /// Power incident on each unit's mirrors (units, row-major).
    pub x: Vec<f64>,
    /// Photocurrent of detector d when the path's first pattern unit j is in state s:
    /// index (d·2 + s)·units + j (d, s: 0 = +, 1 = −).
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

    #[inline]
    pub fn t_index(units: usize, d: usize, s: usize, j: usize) -> usize {
        (d * 2 + s) * units + j
    }

    /// Σ_j (T[d][d'][j] − T[d][other][j]) for arm d: the batch's total gain Σ_j g_j of arm d,
    /// where arm + gains when a unit is in state + and arm − when it is in state −.
    pub fn gain_sum(&self, d: usize) -> f64 {
        let units = self.x.len();
        let (on, off) = (d, 1 - d);
        (0..units)
            .map(|j| {
                self.t[Self::t_index(units, d, on, j)] - self.t[Self::t_index(units, d, off, j)]
            })
            .sum()
    }

    /// The pattern-independent traced current of arm d: Σ_j T[d][off][j] + B_d.
    pub fn offset_sum(&self, d: usize) -> f64 {
        let units = self.x.len();
        let off = 1 - d;
        (0..units)
            .map(|j| self.t[Self::t_index(units, d, off, j)])
            .sum::<f64>()
            + self.b[d]
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
            for d in 0..2 {
                let on = b.t[BatchTally::t_index(units, d, d, j)];
                let off = b.t[BatchTally::t_index(units, d, 1 - d, j)];
                let g = on - off;
                self.g2[d][j] += g * g;
                self.gx[d][j] += g * b.x[j];
            }
        }
        for (a, v) in self.t.iter_mut().zip(&b.t) {
            *a += v;
        }
        for d in 0..2 {
            self.b[d] += b.b[d];
        }
        for w in 0..3 {
            for (a, v) in self.ledger[w].iter_mut().zip(&b.ledger[w]) {
                *a += v;
            }
        }
        self.batches.push(BatchScalars {
            rays: b.rays,
            x: b.x.iter().sum(),
            g: [b.gain_sum(0), b.gain_sum(1)],
            c: [b.offset_sum(0), b.offset_sum(1)],
            b: b.b,
            detected_w: [BRANCH_PLUS, BRANCH_MINUS].map(|branch| {
                let n_el = b.ledger[COMMON].len() - EXTRA_SLOTS;
                [SLOT_DETECTED_PLUS, SLOT_DETECTED_MINUS]
                    .map(|slot| b.ledger[COMMON][n_el + slot] + b.ledger[branch][n_el + slot])
            }),
        });
    }
}
