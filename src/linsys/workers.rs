//! The threads a big system's products run on: a pool kept for the solver's life, since
//! starting threads for every product (a few per conjugate-gradient iteration, each a
//! fraction of a millisecond of work) costs about what they save. Work reaches the pool
//! through `join`, whose jobs live on the stack: a product allocates nothing.

/// A pool of `count` threads, or the calling thread alone.
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

    /// Runs `work` on each part, side by side on the pool when there is one, and returns
    /// when all are done (give about [`Workers::count`] parts). Which thread runs a part
    /// never changes what the part computes.
    pub fn run<I>(&self, parts: I, work: impl Fn(I::Item) + Sync)
    where
        I: IntoIterator,
        I::IntoIter: Send,
        I::Item: Send,
    {
        let parts = parts.into_iter();
        match &self.pool {
            None => parts.for_each(work),
            Some(pool) => pool.install(|| join_all(parts, &work)),
        }
    }
}

/// The first part here, the rest beside it (recursively).
fn join_all<I>(mut parts: I, work: &(impl Fn(I::Item) + Sync))
where
    I: Iterator + Send,
    I::Item: Send,
{
    if let Some(first) = parts.next() {
        rayon::join(|| work(first), || join_all(parts, work));
    }
}
