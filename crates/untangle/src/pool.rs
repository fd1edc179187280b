//! Running a whole computation inside rayon's thread pool.
//!
//! A parallel loop started from a thread outside the pool hands its work to the pool and puts
//! the calling thread to sleep until the loop is done; a computation with dozens of short
//! parallel loops (a simulator step, a projection pass, an analysis) pays that sleep and wake-up
//! once per loop. Started from inside the pool, the loops run on the calling worker directly.
//! The operations and their order are the same either way, so results are bit-identical; only
//! the hand-overs go (branch sim15, BENCHMARKS.md: Baraff & Witkin's step -35 % wall).

/// Runs `f` on one of rayon's worker threads (on the current thread if it is one already) and
/// returns its result.
pub fn in_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

#[cfg(test)]
mod tests {
    use super::in_pool;
    use rayon::prelude::*;

    #[test]
    fn runs_on_a_worker_and_returns_the_same_result() {
        assert!(rayon::current_thread_index().is_none(), "the test thread");
        let (inside, sum) = in_pool(|| {
            let s: u64 = (0..10_000u64).into_par_iter().map(|i| i * i).sum();
            (rayon::current_thread_index().is_some(), s)
        });
        assert!(inside);
        assert_eq!(sum, (0..10_000u64).map(|i| i * i).sum::<u64>());
        // Nested: already on a worker, it runs in place.
        let nested = in_pool(|| {
            let outer = rayon::current_thread_index();
            in_pool(|| rayon::current_thread_index() == outer)
        });
        assert!(nested);
    }
}
