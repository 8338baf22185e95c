//! Work spread over the machine's cores with results in input order, so that
//! the outputs do not depend on the number of threads.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

use rayon::prelude::*;

/// Worker threads; 0 means one per core.
static THREADS: AtomicUsize = AtomicUsize::new(0);
static POOL: OnceLock<rayon::ThreadPool> = OnceLock::new();

/// Sets the number of worker threads (0: one per core), for probecal's own
/// parallel loops and OpenCV's. Takes effect if called before the first parallel loop.
pub fn set_threads(n: usize) {
    THREADS.store(n, Ordering::Relaxed);
    let _ = opencv::core::set_num_threads(if n == 0 { -1 } else { n as i32 });
}

/// The number of worker threads in use.
pub fn threads() -> usize {
    match THREADS.load(Ordering::Relaxed) {
        0 => std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        n => n,
    }
}

fn pool() -> &'static rayon::ThreadPool {
    POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads())
            .thread_name(|i| format!("probecal-{i}"))
            .build()
            .unwrap_or_else(|_| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(1)
                    .build()
                    .expect("a one-thread pool")
            })
    })
}

/// Runs `job(i)` for every `i` in `0..n` on the worker threads (rayon); results in
/// index order, so nothing downstream depends on the thread count.
pub fn parallel_map<T: Send>(n: usize, job: impl Fn(usize) -> T + Sync + Send) -> Vec<T> {
    pool().install(|| (0..n).into_par_iter().map(job).collect())
}

#[cfg(test)]
mod tests {
    #[test]
    fn keeps_input_order() {
        let out = super::parallel_map(100, |i| i * 2);
        assert_eq!(out, (0..100).map(|i| i * 2).collect::<Vec<_>>());
    }
}
