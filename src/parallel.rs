//! Work spread over the machine's cores with results in input order, so that
//! the outputs do not depend on the number of threads.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Worker threads; 0 means one per core.
static THREADS: AtomicUsize = AtomicUsize::new(0);

/// Sets the number of worker threads (0: one per core), for probecal's own
/// parallel loops and OpenCV's.
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

/// Runs `job(i)` for every `i` in `0..n` on the worker threads; results in index order.
pub fn parallel_map<T: Send>(n: usize, job: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let threads = threads().min(n.max(1));
    let next = AtomicUsize::new(0);
    let mut results: Vec<(usize, T)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut out = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= n {
                            break;
                        }
                        out.push((i, job(i)));
                    }
                    out
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| match h.join() {
                Ok(v) => v,
                Err(panic) => std::panic::resume_unwind(panic),
            })
            .collect()
    });
    results.sort_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, t)| t).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn keeps_input_order() {
        let out = super::parallel_map(100, |i| i * 2);
        assert_eq!(out, (0..100).map(|i| i * 2).collect::<Vec<_>>());
    }
}
