//! The threads a big system's products run on: a pool kept for the solver's life, since
//! starting threads for every product (a few per conjugate-gradient iteration, each a
//! fraction of a millisecond of work) costs about what they save.

/// A pool of `count` threads, or none for one.
pub(crate) struct Workers {
    pool: Option<rayon::ThreadPool>,
}

impl Workers {
    /// No pool: every part runs on the calling thread.
    pub fn serial() -> Self {
        Self { pool: None }
    }

    /// A pool of `threads` (serial for one, or when the system refuses threads).
    pub fn new(threads: usize) -> Self {
        let pool = (threads > 1)
            .then(|| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .ok()
            })
            .flatten();
        Self { pool }
    }

    /// Threads the parts may run on.
    pub fn count(&self) -> usize {
        self.pool.as_ref().map_or(1, |p| p.current_num_threads())
    }

    /// Runs `work` on each part, side by side when there is a pool, and returns when all
    /// are done. Which thread runs a part never changes what the part computes.
    pub fn run<T: Send>(&self, parts: impl IntoIterator<Item = T>, work: impl Fn(T) + Sync) {
        match &self.pool {
            None => parts.into_iter().for_each(work),
            Some(pool) => pool.in_place_scope(|scope| {
                let work = &work;
                for part in parts {
                    scope.spawn(move |_| work(part));
                }
            }),
        }
    }

    /// Runs `fill(first, chunk)` on contiguous chunks of `out`, one per thread (`first`:
    /// the chunk's offset in `out`).
    pub fn fill(&self, out: &mut [f64], fill: impl Fn(usize, &mut [f64]) + Sync) {
        let len = out.len().div_ceil(self.count()).max(1);
        self.run(out.chunks_mut(len).enumerate(), |(k, chunk)| {
            fill(k * len, chunk)
        });
    }
}
