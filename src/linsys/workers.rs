//! The threads a big system's products run on: a pool kept for the solver's life, since
//! starting threads for every product (a few per conjugate-gradient iteration, each a
//! fraction of a millisecond of work) costs about what they save.

/// The calling thread and a pool of `count - 1` more, or the calling thread alone.
pub(crate) struct Workers {
    pool: Option<rayon::ThreadPool>,
}

impl Workers {
    /// No pool: every part runs on the calling thread.
    pub fn serial() -> Self {
        Self { pool: None }
    }

    /// `threads` in all (serial for one, or when the system refuses threads).
    pub fn new(threads: usize) -> Self {
        let pool = (threads > 1)
            .then(|| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads - 1)
                    .build()
                    .ok()
            })
            .flatten();
        Self { pool }
    }

    /// Threads the parts may run on, the calling one included.
    pub fn count(&self) -> usize {
        self.pool
            .as_ref()
            .map_or(1, |p| p.current_num_threads() + 1)
    }

    /// Runs `work` on each part, the first on the calling thread and the others on the
    /// pool, and returns when all are done (give about [`Workers::count`] parts). Which
    /// thread runs a part never changes what the part computes.
    pub fn run<T: Send>(&self, parts: impl IntoIterator<Item = T>, work: impl Fn(T) + Sync) {
        let mut parts = parts.into_iter();
        match &self.pool {
            None => parts.for_each(work),
            Some(pool) => pool.in_place_scope(|scope| {
                let work = &work;
                let first = parts.next();
                for part in parts {
                    scope.spawn(move |_| work(part));
                }
                if let Some(part) = first {
                    work(part);
                }
            }),
        }
    }
}
