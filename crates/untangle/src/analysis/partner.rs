//! The second thread kept awake for the length of one analysis.
//!
//! The analysis of a small, dense tangle (the exploded handkerchief: ~1 ms) has several short
//! parallel parts with sequential work between them. An idle rayon worker gives its core back
//! to the system (`thread::yield_now`) and then sleeps, so every parallel part used to pay the
//! wake-up of the second thread, tens of microseconds on a loaded host, which ate most of what
//! splitting the linking and the path making in two saved (BENCHMARKS.md, branch an5 and
//! d0a194f). [`with_partner`] instead hands one *keeper* job to the pool at the start: the
//! worker that takes it runs the analysis' parallel pieces as they appear (rayon's
//! `yield_now`) and spins in between, until the analysis ends or it has found nothing to do for
//! [`MAX_IDLE`]. Which thread runs which piece never changes a result (every parallel part of
//! the analysis combines its pieces in a fixed order), so the output is bit-identical.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The keeper stops after finding no work for this long (a bound on the spinning: long
/// sequential phases of large analyses, or a stalled owner, do not hold a core).
pub const MAX_IDLE: Duration = Duration::from_micros(500);

/// Runs `f` on the current thread while another worker of the pool, if there is one, stands by
/// for the parallel pieces `f` creates. Returns `f`'s result.
pub fn with_partner<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if rayon::current_num_threads() < 2 {
        return f();
    }
    let owner = rayon::current_thread_index();
    let done = AtomicBool::new(false);
    /// Sets the flag when `f` returns or unwinds, so the keeper always stops.
    struct Finish<'a>(&'a AtomicBool);
    impl Drop for Finish<'_> {
        fn drop(&mut self) {
            self.0.store(true, Ordering::Release);
        }
    }
    let (r, ()) = rayon::join(
        || {
            let _finish = Finish(&done);
            f()
        },
        || {
            // The owner takes the keeper back itself when no other worker took it: `f` is
            // over then (or the owner is waiting inside `f`; spinning there would stall it).
            if rayon::current_thread_index() == owner {
                return;
            }
            keep(&done);
        },
    );
    r
}

/// The keeper's loop: run pending pieces of work, spin between them, stop when `done` is set or
/// after [`MAX_IDLE`] without work.
fn keep(done: &AtomicBool) {
    let mut idle_since = Instant::now();
    let mut idle_rounds = 0u32;
    while !done.load(Ordering::Acquire) {
        match rayon::yield_now() {
            Some(rayon::Yield::Executed) => {
                idle_rounds = 0;
            }
            Some(rayon::Yield::Idle) => {
                if idle_rounds == 0 {
                    idle_since = Instant::now();
                }
                idle_rounds += 1;
                if idle_rounds % 64 == 0 && idle_since.elapsed() > MAX_IDLE {
                    return;
                }
                std::hint::spin_loop();
            }
            None => return, // not a worker thread (cannot happen inside `join`)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    #[test]
    fn result_and_parallel_pieces_are_those_of_the_plain_call() {
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let (a, b) = pool.install(|| {
                let f = || {
                    let s: u64 = (0..100_000u64).into_par_iter().map(|i| i * i % 7).sum();
                    let v: Vec<u64> = (0..5_000u64).into_par_iter().map(|i| i ^ 5).collect();
                    (s, v)
                };
                (with_partner(f), f())
            });
            assert_eq!(a, b);
        }
    }

    #[test]
    fn nested_calls_and_panics_end() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        // Nested: the inner call's keeper may be taken by the outer call's keeper.
        let n = pool.install(|| {
            with_partner(|| {
                (0..8)
                    .into_par_iter()
                    .map(|i| with_partner(|| (0..1000u32).into_par_iter().map(|x| x + i).count()))
                    .sum::<usize>()
            })
        });
        assert_eq!(n, 8000);
        // A panic inside still stops the keeper, and is passed on.
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| with_partner(|| -> u32 { panic!("inside") }))
        }));
        assert!(r.is_err());
        // Sequential work longer than the idle bound: the keeper leaves, the result stands.
        let s = pool.install(|| {
            with_partner(|| {
                std::thread::sleep(MAX_IDLE * 3);
                (0..1000u64).into_par_iter().sum::<u64>()
            })
        });
        assert_eq!(s, 499_500);
    }
}
