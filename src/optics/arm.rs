//! The two detection arms of the bench, + and −: the photodiode that collects the light of the
//! mirrors in state + and the one that collects the light of the mirrors in state −
//! (docs/bench-facts.md §2.3). Arm + is index 0 and arm − index 1 in every per-arm array
//! (`[T; 2]`) of the crate: the bench's detectors, the tallies, the transport maps and scalars.
//!
//! An arm is not a mirror state ([`MirrorState`]): a unit in state s sends its light to arm s
//! ([`Arm::state`]), and the other arm sees the unit as part of its offset. The two meet only in
//! the gains, g±_j = T[±][±][j] − T[±][∓][j].

use std::ops::{Index, IndexMut};

use super::dmd::MirrorState;

/// One of the two detection arms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Arm {
    Plus,
    Minus,
}

impl Arm {
    /// Both arms in index order: [+, −].
    pub const ALL: [Arm; 2] = [Arm::Plus, Arm::Minus];

    /// The arm's index in a per-arm array: + is 0, − is 1.
    #[inline]
    pub const fn index(self) -> usize {
        match self {
            Arm::Plus => 0,
            Arm::Minus => 1,
        }
    }

    /// The arm of index `i` (0: +, 1: −). Panics on any other index.
    #[inline]
    pub const fn from_index(i: usize) -> Arm {
        match i {
            0 => Arm::Plus,
            1 => Arm::Minus,
            _ => panic!("an arm index is 0 (+) or 1 (−)"),
        }
    }

    /// The other arm.
    #[inline]
    pub const fn other(self) -> Arm {
        match self {
            Arm::Plus => Arm::Minus,
            Arm::Minus => Arm::Plus,
        }
    }

    /// "+" or "−" (U+2212), as the reports write the arms.
    pub const fn label(self) -> &'static str {
        match self {
            Arm::Plus => "+",
            Arm::Minus => "−",
        }
    }

    /// The mirror state that sends light into this arm (the arm's "on" state); the other arm's
    /// state is its "off" state.
    #[inline]
    pub const fn state(self) -> MirrorState {
        match self {
            Arm::Plus => MirrorState::Plus,
            Arm::Minus => MirrorState::Minus,
        }
    }
}

/// Per-arm arrays (`[T; 2]`, and slices) are indexed by arm: `k[Arm::Minus]`.
impl<T> Index<Arm> for [T] {
    type Output = T;
    #[inline]
    fn index(&self, arm: Arm) -> &T {
        &self[arm.index()]
    }
}

impl<T> IndexMut<Arm> for [T] {
    #[inline]
    fn index_mut(&mut self, arm: Arm) -> &mut T {
        &mut self[arm.index()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arms_index_their_arrays_in_the_crate_convention() {
        let a = [10, 20];
        assert_eq!((a[Arm::Plus], a[Arm::Minus]), (10, 20));
        for (i, arm) in Arm::ALL.into_iter().enumerate() {
            assert_eq!(arm.index(), i);
            assert_eq!(Arm::from_index(i), arm);
            assert_eq!(arm.other().other(), arm);
            assert_ne!(arm.other(), arm);
            assert_eq!(arm.state().arm(), Some(arm));
        }
        assert_eq!(MirrorState::Flat.arm(), None);
        assert_eq!(Arm::Minus.label(), "\u{2212}");
    }
}
