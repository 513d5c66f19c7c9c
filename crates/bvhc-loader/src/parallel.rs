//! Scoped worker threads for the loader's data-parallel passes (the refit's): no pool and no dependency, the
//! threads live for one pass (`std::thread::scope`), and a task whose thread the system refuses to start runs
//! on the calling thread instead, so a pass never fails for want of threads and gives the same result on any
//! count.

use std::panic::resume_unwind;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

/// How many threads a pass may use (at least one: the caller's).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Workers {
    count: usize,
}

impl Workers {
    /// `threads` threads, the caller's included (0 counts as 1).
    pub(crate) fn new(threads: usize) -> Workers {
        Workers { count: threads.max(1) }
    }

    /// Runs every task once on up to the pass's threads (the caller's included), each thread taking the
    /// next task not taken until none is left (so tasks of unequal sizes balance: pass the largest first), and
    /// returns their results in task order. A thread the system refuses leaves its share to the others.
    pub(crate) fn run_all<R: Send, F: FnOnce() -> R + Send>(&self, tasks: Vec<F>) -> Vec<R> {
        let threads = self.count.min(tasks.len());
        if threads < 2 {
            return tasks.into_iter().map(|task| task()).collect();
        }
        let slots: Vec<Mutex<(Option<F>, Option<R>)>> =
            tasks.into_iter().map(|task| Mutex::new((Some(task), None))).collect();
        let next = AtomicUsize::new(0);
        let drain = || {
            while let Some(slot) = slots.get(next.fetch_add(1, Ordering::Relaxed)) {
                let task = slot.lock().unwrap_or_else(PoisonError::into_inner).0.take();
                if let Some(task) = task {
                    let result = task();
                    slot.lock().unwrap_or_else(PoisonError::into_inner).1 = Some(result);
                }
            }
        };
        std::thread::scope(|scope| {
            let drain = &drain;
            let handles: Vec<_> =
                (1..threads).filter_map(|_| std::thread::Builder::new().spawn_scoped(scope, drain).ok()).collect();
            drain();
            for handle in handles {
                // A task panics only where its code does; the panic goes on in the caller.
                handle.join().unwrap_or_else(|panic| resume_unwind(panic));
            }
        });
        // Every task ran once: the caller's thread drained the queue to its end.
        slots.into_iter().filter_map(|slot| slot.into_inner().unwrap_or_else(PoisonError::into_inner).1).collect()
    }

    /// [`Workers::run_all`] of tasks given with their sizes, started largest first (so that the threads end
    /// together); the results in the order given.
    pub(crate) fn run_largest_first<R: Send, F: FnOnce() -> R + Send>(&self, tasks: Vec<(usize, F)>) -> Vec<R> {
        let mut order: Vec<usize> = (0..tasks.len()).collect();
        order.sort_by_key(|&k| std::cmp::Reverse(tasks[k].0));
        let mut slots: Vec<Option<F>> = tasks.into_iter().map(|(_, task)| Some(task)).collect();
        let sorted: Vec<F> = order.iter().filter_map(|&k| slots[k].take()).collect();
        let mut results: Vec<Option<R>> = (0..order.len()).map(|_| None).collect();
        for (k, result) in order.into_iter().zip(self.run_all(sorted)) {
            results[k] = Some(result);
        }
        results.into_iter().flatten().collect()
    }

    /// The length of the chunks `len` items are cut into: no more chunks than threads, none shorter than
    /// `min_chunk` items (so a small pass is one chunk), at least 1.
    fn chunk_len(&self, len: usize, min_chunk: usize) -> usize {
        let chunk_count = self.count.min(len / min_chunk.max(1)).max(1);
        len.div_ceil(chunk_count).max(1)
    }

    /// Calls `work(first_index, chunk)` on consecutive chunks of `items` that together cover it once, each chunk
    /// on its own thread, with no more chunks than threads and none shorter than `min_chunk` items (so a small
    /// pass stays on the calling thread). Returns the results in chunk order.
    pub(crate) fn for_chunks<T: Send, R: Send>(
        &self,
        items: &mut [T],
        min_chunk: usize,
        work: impl Fn(usize, &mut [T]) -> R + Sync,
    ) -> Vec<R> {
        let chunk_len = self.chunk_len(items.len(), min_chunk);
        if chunk_len >= items.len() {
            return vec![work(0, items)];
        }
        let work = &work;
        let tasks: Vec<_> =
            items.chunks_mut(chunk_len).enumerate().map(|(k, chunk)| move || work(k * chunk_len, chunk)).collect();
        self.run_all(tasks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_cover_the_items_once_on_any_thread_count() {
        for threads in [0, 1, 2, 3, 8] {
            let mut items: Vec<usize> = vec![0; 1001];
            let starts = Workers::new(threads).for_chunks(&mut items, 100, |first, chunk| {
                for (k, item) in chunk.iter_mut().enumerate() {
                    *item += first + k;
                }
                first
            });
            assert!(items.iter().enumerate().all(|(k, &item)| item == k), "{threads} threads");
            assert_eq!(starts[0], 0);
            assert!(starts.len() <= threads.max(1) && starts.windows(2).all(|w| w[0] < w[1]));
        }
        for threads in [1, 2, 5] {
            let tasks: Vec<_> = (0..9).map(|k| move || k * k).collect();
            assert_eq!(Workers::new(threads).run_all(tasks), (0..9).map(|k| k * k).collect::<Vec<_>>());
            let sized: Vec<_> = (0..9).map(|k| ((k * 7) % 5, move || k + 1)).collect();
            assert_eq!(Workers::new(threads).run_largest_first(sized), (1..10).collect::<Vec<_>>());
        }
    }
}
