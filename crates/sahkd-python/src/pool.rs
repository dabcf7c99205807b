//! Worker pools for builds and queries, safe across `fork`.
//!
//! rayon's global pool cannot be used in a process forked after the pool started: its threads
//! do not exist in the child, and the first parallel call there waits forever. Python's
//! `multiprocessing` forks by default on Linux before 3.14, so every pool here remembers the
//! process that made it and a forked child makes its own. Pools are shared by thread count, so
//! many trees with the same `threads` option do not start many pools.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use rayon::{ThreadPool, ThreadPoolBuilder};

/// Pools by requested thread count (`0` = rayon's default: `RAYON_NUM_THREADS` or every core),
/// and the process they belong to.
static POOLS: Mutex<Option<ProcessPools>> = Mutex::new(None);

/// The process id and its pools by thread count.
type ProcessPools = (u32, HashMap<usize, Arc<ThreadPool>>);

/// The pool with `threads` workers (`None`: the default size) for this process.
pub fn pool(threads: Option<usize>) -> Result<Arc<ThreadPool>, String> {
    // `threads=` was checked against the rule; a tree saved on a larger machine may carry
    // more, and runs here on this machine's cap (the answers do not depend on it).
    let key = threads.map_or(0, |n| n.min(sahkd::threads::max_threads()));
    let pid = std::process::id();
    let mut guard = POOLS.lock().unwrap_or_else(|e| e.into_inner());
    if guard.as_ref().is_some_and(|(owner, _)| *owner != pid) {
        // Inherited from the parent across fork: its threads are gone, and dropping it would
        // try to signal them, so it is leaked on purpose.
        std::mem::forget(guard.take());
    }
    let (_, pools) = guard.get_or_insert_with(|| (pid, HashMap::new()));
    if let Some(p) = pools.get(&key) {
        return Ok(p.clone());
    }
    let p = Arc::new(
        ThreadPoolBuilder::new()
            .num_threads(key)
            .thread_name(|i| format!("sahkd-{i}"))
            .build()
            .map_err(|e| format!("cannot start {key} worker threads: {e}"))?,
    );
    pools.insert(key, p.clone());
    Ok(p)
}
