//! The state of a resolution loop with the fewest intersecting triangle pairs seen so far
//! (ours). [`super::combined`] starts Cha & Ko from its pre-pass's; `untangle fix` writes it,
//! not the last state, when a run ends with tanglements left.
//!
//! A run that gets stuck can end far worse than it began: on ARCSim's dress4 sagged 25 steps,
//! Cha & Ko's pulls of a 231-vertex BLI region took the garment from 259 to 290 pairs, with a
//! peak of 978, and crumpled it (BENCHMARKS.md, session 31). Handing that back would lose the
//! user's garment. So the loop offers each state before its step, with that step's
//! intersecting-pair count; the fewest-pair state (the first, on ties) is kept, and `fix`
//! writes it instead of the last state whenever it has fewer pairs. The input itself is a
//! candidate, so `fix` never writes a state with more pairs than it read. `--output-last`
//! writes the last state. Not used with an animated body: an earlier state fits an earlier
//! body frame.

use crate::geom::Vec3;

/// A candidate state.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Steps run before it (0 = the input).
    pub after_steps: usize,
    /// Intersecting triangle pairs the loop counted in it.
    pub pairs: usize,
    /// Cloth positions.
    pub positions: Vec<Vec3>,
}

/// Keeps the state with the fewest intersecting pairs offered so far.
#[derive(Clone, Debug, Default)]
pub struct Fewest {
    enabled: bool,
    best: Option<State>,
}

impl Fewest {
    /// A tracker; a disabled one keeps nothing and copies no positions.
    pub fn new(enabled: bool) -> Self {
        Fewest {
            enabled,
            best: None,
        }
    }

    /// Positions worth offering after the step about to run: a copy of `positions` when
    /// enabled, `None` (no copy) otherwise.
    pub fn before_step(&self, positions: &[Vec3]) -> Option<Vec<Vec3>> {
        self.enabled.then(|| positions.to_vec())
    }

    /// Offers the state `positions` (from [`Fewest::before_step`]) taken after `after_steps`
    /// steps, with the pair count the next step found in it; kept if it has strictly fewer
    /// pairs than the best so far. Whether it was kept (`false` for `None`).
    pub fn offer(
        &mut self,
        after_steps: usize,
        pairs: usize,
        positions: Option<Vec<Vec3>>,
    ) -> bool {
        let Some(positions) = positions else {
            return false;
        };
        let kept = self.best.as_ref().is_none_or(|b| pairs < b.pairs);
        if kept {
            self.best = Some(State {
                after_steps,
                pairs,
                positions,
            });
        }
        kept
    }

    /// The kept state, if any.
    pub fn best(&self) -> Option<&State> {
        self.best.as_ref()
    }

    /// Takes the kept state out, leaving none.
    pub fn take(&mut self) -> Option<State> {
        self.best.take()
    }

    /// The kept state, if it has fewer pairs than `last_pairs` (the last state's count).
    pub fn better_than(&self, last_pairs: usize) -> Option<&State> {
        self.best.as_ref().filter(|b| b.pairs < last_pairs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: f64) -> Vec<Vec3> {
        vec![Vec3::new(x, 0.0, 0.0)]
    }

    /// Against a brute-force oracle: the first minimum of random pair sequences.
    #[test]
    fn keeps_the_first_state_with_the_fewest_pairs() {
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as usize % 20
        };
        for _ in 0..200 {
            let n = 1 + next();
            let pairs: Vec<usize> = (0..n).map(|_| next()).collect();
            let mut f = Fewest::new(true);
            for (k, &p) in pairs.iter().enumerate() {
                let pos = f.before_step(&at(k as f64));
                f.offer(k, p, pos);
            }
            let min = *pairs.iter().min().unwrap();
            let first = pairs.iter().position(|&p| p == min).unwrap();
            let last = next();
            match f.better_than(last) {
                Some(s) => {
                    assert!(min < last);
                    assert_eq!((s.after_steps, s.pairs), (first, min));
                    assert_eq!(s.positions, at(first as f64));
                }
                None => assert!(min >= last),
            }
        }
    }

    #[test]
    fn a_disabled_tracker_keeps_nothing() {
        let mut f = Fewest::new(false);
        let pos = f.before_step(&at(1.0));
        assert!(pos.is_none());
        f.offer(0, 0, pos);
        assert!(f.better_than(100).is_none());
    }
}
