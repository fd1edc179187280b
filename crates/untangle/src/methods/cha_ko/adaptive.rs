//! The loop's adaptive integrator (ours): projective dynamics while the loop makes progress,
//! Baraff & Witkin for a stretch of steps when it stalls.
//!
//! Projective dynamics ([`Integrator::Projective`], with the loop's CG cap) makes a loop step of
//! the Cha & Ko loop (Fig. 1b) about twice as cheap as Baraff & Witkin, but resolves less: some
//! tangles that Baraff & Witkin untangles stall under it (BENCHMARKS.md, branches loop10 and
//! loop11). The rule here is a deterministic function of the loop's intersecting-pair counts
//! only, so the schedule is the same for any thread count:
//!
//! - Start with projective dynamics.
//! - While projective, a step *stalls* when the cloth intersects and its count of intersecting
//!   triangle pairs is not below the lowest seen so far (the loop's stuck measure). After
//!   `stall_steps` consecutive stalled projective steps the next steps run Baraff & Witkin.
//! - Baraff & Witkin runs `bw_steps` steps (whatever happens meanwhile), then projective
//!   dynamics takes over again with a fresh stall count. `bw_steps = usize::MAX` keeps
//!   Baraff & Witkin for the rest of the run.
//!
//! Every loop step reports the integrator it used and why it changed
//! ([`super::LoopStep::integrator`], [`super::LoopStep::integrator_switch`]).

use crate::sim::Integrator;

/// Settings of the adaptive integrator (see the module text).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdaptiveIntegrator {
    /// Consecutive stalled projective steps (intersecting, no new lowest pair count) after
    /// which Baraff & Witkin takes over.
    pub stall_steps: usize,
    /// Steps Baraff & Witkin then runs before projective dynamics takes over again
    /// (`usize::MAX`: until the end of the run).
    pub bw_steps: usize,
    /// Whether the loop's stuck count restarts at a switch to Baraff & Witkin: the stall may
    /// then last `stuck_steps` more steps from the switch (as after the regionless fallback),
    /// so that Baraff & Witkin gets as many steps to make progress as a run of its own.
    pub restart_stall: bool,
}

impl Default for AdaptiveIntegrator {
    fn default() -> Self {
        AdaptiveIntegrator {
            stall_steps: 8,
            bw_steps: usize::MAX,
            restart_stall: true,
        }
    }
}

/// Why the integrator changed before a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorSwitch {
    /// Projective dynamics stalled for `stall_steps` steps: Baraff & Witkin takes over.
    Stalled,
    /// Baraff & Witkin ran its `bw_steps` steps: projective dynamics takes over again.
    StretchDone,
}

/// The state of the rule: which integrator runs the next step.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IntegratorSchedule {
    params: AdaptiveIntegrator,
    current: Integrator,
    /// Consecutive stalled projective steps.
    stalled: usize,
    /// Baraff & Witkin steps run in the current stretch.
    bw_run: usize,
    /// Lowest intersecting-pair count seen so far.
    best: usize,
    /// The switch made for the next step, if any.
    pending: Option<IntegratorSwitch>,
}

impl IntegratorSchedule {
    /// A schedule starting with projective dynamics.
    pub fn new(params: AdaptiveIntegrator) -> IntegratorSchedule {
        IntegratorSchedule {
            params,
            current: Integrator::Projective,
            stalled: 0,
            bw_run: 0,
            best: usize::MAX,
            pending: None,
        }
    }

    /// The settings.
    pub fn params(&self) -> AdaptiveIntegrator {
        self.params
    }

    /// The integrator of the next step.
    pub fn current(&self) -> Integrator {
        self.current
    }

    /// The switch that made [`IntegratorSchedule::current`] (`None` if the previous step used
    /// the same integrator).
    pub fn pending_switch(&self) -> Option<IntegratorSwitch> {
        self.pending
    }

    /// Records a step run with [`IntegratorSchedule::current`] that started with
    /// `intersecting_pairs` pairs (0: clean) and decides the integrator of the next step.
    pub fn observe(&mut self, intersecting_pairs: usize) {
        let new_best = intersecting_pairs < self.best;
        self.best = self.best.min(intersecting_pairs);
        self.pending = None;
        match self.current {
            Integrator::Projective => {
                self.stalled = if intersecting_pairs > 0 && !new_best {
                    self.stalled + 1
                } else {
                    0
                };
                if self.stalled >= self.params.stall_steps {
                    self.current = Integrator::BaraffWitkin;
                    self.bw_run = 0;
                    self.pending = Some(IntegratorSwitch::Stalled);
                }
            }
            Integrator::BaraffWitkin => {
                self.bw_run += 1;
                if self.bw_run >= self.params.bw_steps {
                    self.current = Integrator::Projective;
                    self.stalled = 0;
                    self.pending = Some(IntegratorSwitch::StretchDone);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(p: AdaptiveIntegrator, counts: &[usize]) -> Vec<(Integrator, Option<IntegratorSwitch>)> {
        let mut s = IntegratorSchedule::new(p);
        let mut out = vec![(s.current(), s.pending_switch())];
        for &c in counts {
            s.observe(c);
            out.push((s.current(), s.pending_switch()));
        }
        out
    }

    /// An independent statement of the rule: the integrator of step `i + 1` from the
    /// integrators of steps `..= i` and the counts (step `j` stalls when it intersects and its
    /// count is not below every earlier count).
    fn oracle(p: AdaptiveIntegrator, counts: &[usize]) -> Vec<Integrator> {
        use Integrator::{BaraffWitkin as B, Projective as P};
        let stalls = |j: usize| counts[j] > 0 && counts[..j].iter().any(|&c| c <= counts[j]);
        let mut out = vec![P];
        for i in 0..counts.len() {
            let same = out.iter().rev().take_while(|&&x| x == out[i]).count();
            let next = if out[i] == B {
                if same >= p.bw_steps {
                    P
                } else {
                    B
                }
            } else {
                let run = (0..=i)
                    .rev()
                    .take_while(|&j| out[j] == P && stalls(j))
                    .count();
                if run >= p.stall_steps {
                    B
                } else {
                    P
                }
            };
            out.push(next);
        }
        out
    }

    #[test]
    fn it_switches_to_baraff_witkin_after_a_stall_and_back_after_the_stretch() {
        let p = AdaptiveIntegrator {
            stall_steps: 3,
            bw_steps: 2,
            restart_stall: true,
        };
        // 10, 9, 8 are new lows; then 8, 9, 8 stall three steps.
        let s = run(p, &[10, 9, 8, 8, 9, 8, 7, 7, 7, 7, 7, 7]);
        use Integrator::{BaraffWitkin as B, Projective as P};
        let integ: Vec<Integrator> = s.iter().map(|x| x.0).collect();
        assert_eq!(integ, vec![P, P, P, P, P, P, B, B, P, P, P, B, B]);
        assert_eq!(s[6].1, Some(IntegratorSwitch::Stalled));
        assert_eq!(s[8].1, Some(IntegratorSwitch::StretchDone));
        assert_eq!(s[7].1, None);
        assert_eq!(s[11].1, Some(IntegratorSwitch::Stalled));
    }

    #[test]
    fn clean_steps_and_new_lows_never_switch() {
        let p = AdaptiveIntegrator {
            stall_steps: 2,
            bw_steps: usize::MAX,
            restart_stall: true,
        };
        let s = run(p, &[5, 4, 3, 2, 1, 0, 0, 0, 0, 0, 0]);
        assert!(s
            .iter()
            .all(|x| x.0 == Integrator::Projective && x.1.is_none()));
        // Sticky: once switched, Baraff & Witkin to the end.
        let s = run(p, &[5, 5, 5, 0, 0, 0, 0, 0]);
        assert_eq!(
            s[3],
            (Integrator::BaraffWitkin, Some(IntegratorSwitch::Stalled))
        );
        assert!(s[3..].iter().all(|x| x.0 == Integrator::BaraffWitkin));
    }

    #[test]
    fn it_follows_the_rule_on_random_count_sequences() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for _ in 0..300 {
            let p = AdaptiveIntegrator {
                stall_steps: rng.random_range(1..6),
                bw_steps: if rng.random_bool(0.2) {
                    usize::MAX
                } else {
                    rng.random_range(1..6)
                },
                restart_stall: true,
            };
            let n = rng.random_range(0..60);
            let mut c = rng.random_range(0..30usize);
            let counts: Vec<usize> = (0..n)
                .map(|_| {
                    c = (c as i64 + rng.random_range(-3..3)).max(0) as usize;
                    c
                })
                .collect();
            let got: Vec<Integrator> = run(p, &counts).iter().map(|x| x.0).collect();
            assert_eq!(got, oracle(p, &counts), "{p:?} {counts:?}");
        }
    }
}
