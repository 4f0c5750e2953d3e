//! Parallel helpers shared by the raster passes: a raw pointer that rayon tasks share to write
//! disjoint parts of one buffer ([`SharedMut`]), and column groups of a row-major buffer
//! ([`par_column_groups`]) for column passes without a transpose; and reductions in a fixed
//! order ([`OrderedReduce`], [`ordered_dot`], [`ordered_sum_of`]).

use rayon::prelude::*;

/// Whether rgbn runs work beside the calling thread. Its thread budget is the rayon pool's size
/// (`RAYON_NUM_THREADS`, by default the cores): with more than one thread the pipelines run
/// their stages side by side (decoding beside converting, reading beside computing, compressing
/// beside writing, one output's file beside the next); with one, each stage runs after the
/// other on the calling thread, so that `RAYON_NUM_THREADS=1` is one thread of work, not one
/// plus helpers.
#[must_use]
pub fn pipelined() -> bool {
    rayon::current_num_threads() > 1
}

/// A raw pointer that may be shared between rayon tasks writing disjoint elements of one buffer
/// (column groups in [`par_column_groups`], `convolve::filter_columns` and
/// `smooth::smooth_normals`).
///
/// Every dereference is `unsafe` at its use site, with the disjointness argument there.
pub(crate) struct SharedMut<T>(pub(crate) *mut T);

impl<T> Clone for SharedMut<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for SharedMut<T> {}

impl<T> SharedMut<T> {
    /// The pointer. A method (not field access) so closures capture the whole `Sync` wrapper.
    pub(crate) fn get(self) -> *mut T {
        self.0
    }
}
// SAFETY: used only to write disjoint elements (column groups) from parallel tasks: see
// `par_column_groups`, `convolve::filter_columns` and `smooth::smooth_normals`, whose tasks
// touch disjoint columns. `T: Send` because the elements are written from other threads.
unsafe impl<T: Send> Send for SharedMut<T> {}
unsafe impl<T: Send> Sync for SharedMut<T> {}

/// Columns `c0..c0 + cols` of every row of a row-major buffer, owned by one rayon task.
pub(crate) struct ColumnGroup<'a, T> {
    ptr: SharedMut<T>,
    width: usize,
    height: usize,
    pub(crate) c0: usize,
    pub(crate) cols: usize,
    _data: std::marker::PhantomData<&'a mut [T]>,
}

impl<T> ColumnGroup<'_, T> {
    /// The group's part of row `r` (borrowing the group, so one row slice at a time).
    pub(crate) fn row(&mut self, r: usize) -> &mut [T] {
        assert!(r < self.height);
        // SAFETY: columns c0..c0+cols of row r lie inside the buffer (r < height and
        // c0 + cols ≤ width by construction in `par_column_groups`); no other task touches
        // these columns while the group lives, and `&mut self` allows one slice at a time.
        unsafe {
            std::slice::from_raw_parts_mut(self.ptr.get().add(r * self.width + self.c0), self.cols)
        }
    }
}

/// Runs `f(state, group)` for groups of `group` columns (fewer in the last) of a row-major
/// `width`-wide buffer, groups in parallel, with one `init()` state per rayon job. Columns are
/// gathered / scattered in row segments a cache line wide, so a column transform moves no
/// more memory than a row pass and needs no transpose.
pub(crate) fn par_column_groups<T: Send, S: Send>(
    data: &mut [T],
    width: usize,
    group: usize,
    init: impl Fn() -> S + Sync + Send,
    f: impl Fn(&mut S, &mut ColumnGroup<'_, T>) + Sync + Send,
) {
    if width == 0 || data.is_empty() {
        return;
    }
    let height = data.len() / width;
    assert_eq!(data.len(), width * height);
    let ptr = SharedMut(data.as_mut_ptr());
    (0..width.div_ceil(group))
        .into_par_iter()
        .for_each_init(init, |state, gi| {
            let c0 = gi * group;
            let mut cg = ColumnGroup {
                ptr,
                width,
                height,
                c0,
                cols: group.min(width - c0),
                _data: std::marker::PhantomData,
            };
            f(state, &mut cg);
        });
}

/// Reductions whose result does not depend on how rayon split the work.
///
/// Rayon's `sum` and `reduce` add partial results in the order the work happened to be split
/// and stolen, so a float sum differs in its last bits from one run to the next (an `F` by
/// 1e-17, a conjugate-gradient solve by 1e-7 after its iterations amplify it). These collect
/// each item's result in index order and fold them on the calling thread: the same bits on
/// every run and at every thread count. Items must be coarse (rows, fixed-size chunks): one
/// value per item is kept until the fold.
pub trait OrderedReduce: ParallelIterator + Sized {
    /// `reduce(identity, merge)`, merged left to right in item order.
    fn ordered_reduce(
        self,
        identity: impl FnOnce() -> Self::Item,
        merge: impl FnMut(Self::Item, Self::Item) -> Self::Item,
    ) -> Self::Item {
        let parts: Vec<Self::Item> = self.collect();
        parts.into_iter().fold(identity(), merge)
    }

    /// `sum()`, added left to right in item order.
    fn ordered_sum<S: std::iter::Sum<Self::Item>>(self) -> S {
        let parts: Vec<Self::Item> = self.collect();
        parts.into_iter().sum()
    }
}

impl<I: ParallelIterator> OrderedReduce for I {}

/// Items per chunk of [`ordered_dot`] and [`ordered_sum_of`]: fixed, so the summation order
/// does not depend on the thread count.
const SUM_CHUNK: usize = 1 << 14;

/// `Σ a[i]·b[i]` in parallel, in fixed chunks added in order (see [`OrderedReduce`]).
#[must_use]
pub fn ordered_dot(a: &[f64], b: &[f64]) -> f64 {
    a.par_chunks(SUM_CHUNK)
        .zip(b.par_chunks(SUM_CHUNK))
        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>())
        .ordered_sum()
}

/// `Σ f(i)` over `0..n` (with the count of terms that were `Some`) in parallel, in fixed
/// chunks added in order (see [`OrderedReduce`]).
pub fn ordered_sum_of(n: usize, f: impl Fn(usize) -> Option<f64> + Sync) -> (f64, usize) {
    (0..n.div_ceil(SUM_CHUNK))
        .into_par_iter()
        .map(|c| {
            let (mut s, mut k) = (0.0f64, 0usize);
            for v in (c * SUM_CHUNK..((c + 1) * SUM_CHUNK).min(n)).filter_map(&f) {
                s += v;
                k += 1;
            }
            (s, k)
        })
        .ordered_reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Items handled one at a time, in the order given, by tasks on the rayon pool: a stage of a
/// pipeline (a PNG's rows filtered and compressed into one stream) that runs on the pool's
/// threads instead of a thread of its own, so that the process runs no more threads of work
/// than the pool has. A task runs while items wait and ends when none do; [`push`] queues a
/// new one. The caller must not be a worker of the pool ([`push`] and [`finish`] wait).
///
/// [`push`]: Sequenced::push
/// [`finish`]: Sequenced::finish
pub struct Sequenced<'r, 's, T, S, F> {
    inner: std::sync::Arc<SeqInner<T, S, F>>,
    scope: &'r rayon::Scope<'s>,
}

struct SeqInner<T, S, F> {
    q: parking_lot::Mutex<SeqQueue<T>>,
    cv: parking_lot::Condvar,
    state: parking_lot::Mutex<Option<S>>,
    work: F,
    cap: usize,
}

struct SeqQueue<T> {
    items: std::collections::VecDeque<T>,
    running: bool,
    /// The first error of `work` (or a panic's): the items after it are dropped.
    failed: Option<crate::error::RgbnError>,
}

impl<'r, 's, T, S, F> Sequenced<'r, 's, T, S, F>
where
    T: Send + 's,
    S: Send + 's,
    F: Fn(&mut S, T) -> Result<(), crate::error::RgbnError> + Send + Sync + 's,
{
    /// A stage running `work` on `state` for each item, with at most `cap` items waiting.
    pub fn new(scope: &'r rayon::Scope<'s>, state: S, cap: usize, work: F) -> Self {
        Self {
            inner: std::sync::Arc::new(SeqInner {
                q: parking_lot::Mutex::new(SeqQueue {
                    items: std::collections::VecDeque::new(),
                    running: false,
                    failed: None,
                }),
                cv: parking_lot::Condvar::new(),
                state: parking_lot::Mutex::new(Some(state)),
                work,
                cap: cap.max(1),
            }),
            scope,
        }
    }

    /// Queues `item` (waiting while `cap` items wait). `Err(())`: an earlier item failed (the
    /// error comes from [`finish`](Self::finish)); `item` is dropped.
    pub fn push(&self, item: T) -> Result<(), ()> {
        let inner = &self.inner;
        let mut q = inner.lock_q();
        while q.failed.is_none() && q.items.len() >= inner.cap {
            inner.cv.wait(&mut q);
        }
        if q.failed.is_some() {
            return Err(());
        }
        q.items.push_back(item);
        if !q.running {
            q.running = true;
            let task = std::sync::Arc::clone(inner);
            self.scope.spawn(move |_| task.run());
        }
        Ok(())
    }

    /// Waits for every item queued, and hands back the state (or the first error).
    pub fn finish(self) -> Result<S, crate::error::RgbnError> {
        let inner = &self.inner;
        let mut q = inner.lock_q();
        while q.running {
            inner.cv.wait(&mut q);
        }
        if let Some(e) = q.failed.take() {
            return Err(e);
        }
        drop(q);
        // The last task has ended (it lets the state go just after saying so).
        let state = inner.state.lock().take();
        Ok(state.expect("the state is taken once"))
    }
}

impl<T, S, F> SeqInner<T, S, F>
where
    F: Fn(&mut S, T) -> Result<(), crate::error::RgbnError>,
{
    fn lock_q(&self) -> parking_lot::MutexGuard<'_, SeqQueue<T>> {
        self.q.lock()
    }

    /// The task: the waiting items, in order, until none waits.
    fn run(&self) {
        // Ends the task however it ends: a panic stops the stage with an error (and the scope
        // re-raises the panic).
        struct Ended<'a, T, S, F>(&'a SeqInner<T, S, F>, bool);
        impl<T, S, F> Drop for Ended<'_, T, S, F> {
            fn drop(&mut self) {
                if self.1 {
                    return;
                }
                let mut q = self.0.q.lock();
                q.running = false;
                q.failed.get_or_insert(crate::error::RgbnError::Decode {
                    detail: "a writing task panicked".into(),
                    path: std::path::PathBuf::new(),
                });
                q.items.clear();
                self.0.cv.notify_all();
            }
        }
        let mut ended = Ended(self, false);
        let mut guard = self.state.lock();
        let state = guard.as_mut().expect("the state is there until finished");
        loop {
            let item = {
                let mut q = self.lock_q();
                match q.items.pop_front() {
                    Some(item) => {
                        self.cv.notify_all();
                        item
                    }
                    None => {
                        q.running = false;
                        self.cv.notify_all();
                        ended.1 = true;
                        return;
                    }
                }
            };
            if let Err(e) = (self.work)(state, item) {
                let mut q = self.lock_q();
                q.failed = Some(e);
                q.items.clear();
                q.running = false;
                self.cv.notify_all();
                ended.1 = true;
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::sample::noise_field;

    /// Runs `f` in a pool of `threads` threads.
    fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
            .install(f)
    }

    #[test]
    fn ordered_sums_are_the_same_bits_at_every_thread_count() {
        // Values of very different magnitudes, so that the order of addition shows in the bits.
        let a: Vec<f64> = (0..300_001)
            .map(|i| ((i as f64) * 0.618_033_988_7).fract() * 10f64.powi(i % 17 - 8))
            .collect();
        let b: Vec<f64> = a.iter().rev().map(|v| v.sqrt() - 0.3).collect();
        let sequential: f64 = a
            .chunks(SUM_CHUNK)
            .zip(b.chunks(SUM_CHUNK))
            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>())
            .sum();
        let (s1, n1) = (0..a.len())
            .filter(|i| i % 3 != 0)
            .fold((0.0, 0), |(s, n), i| (s + a[i], n + 1));
        for threads in [1, 2, 3, 8] {
            let dot = in_pool(threads, || ordered_dot(&a, &b));
            assert_eq!(dot.to_bits(), sequential.to_bits(), "{threads} threads");
            // Chunks of SUM_CHUNK, each summed in order: the same additions as one pass
            // only where a chunk boundary falls; so compare with the chunked sequential sum.
            let (s, n) = in_pool(threads, || {
                ordered_sum_of(a.len(), |i| (i % 3 != 0).then_some(a[i]))
            });
            assert_eq!(n, n1);
            assert!((s - s1).abs() <= 1e-12 * s1.abs(), "{s} vs {s1}");
            let again = in_pool(9 - threads, || {
                ordered_sum_of(a.len(), |i| (i % 3 != 0).then_some(a[i]))
            });
            assert_eq!(
                s.to_bits(),
                again.0.to_bits(),
                "{threads} vs {} threads",
                9 - threads
            );
        }
    }

    #[test]
    fn curl_statistics_are_the_same_bits_at_every_thread_count() {
        let g = noise_field(301, 257, 7);
        let one = in_pool(1, || g.curl_stats(None));
        for threads in [2, 3, 8] {
            let many = in_pool(threads, || g.curl_stats(None));
            assert_eq!(
                one.relative.to_bits(),
                many.relative.to_bits(),
                "{threads} threads"
            );
            assert_eq!(
                one.rms_curl.to_bits(),
                many.rms_curl.to_bits(),
                "{threads} threads"
            );
        }
    }

    /// A [`Sequenced`] stage in a pool of `threads`, fed from outside the pool: every item
    /// handled once, in order, on the pool's threads; the state comes back.
    #[test]
    fn sequenced_items_are_handled_once_in_order_on_the_pool() {
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let (seen, on_pool) = pool.in_place_scope(|scope| {
                let stage = Sequenced::new(
                    scope,
                    (Vec::new(), true),
                    1,
                    |s: &mut (Vec<usize>, bool), x: usize| {
                        s.0.push(x);
                        s.1 &= rayon::current_thread_index().is_some();
                        Ok(())
                    },
                );
                for i in 0..500 {
                    stage.push(i).expect("no item fails");
                }
                stage.finish().expect("no item fails")
            });
            assert_eq!(seen, (0..500).collect::<Vec<_>>(), "{threads} threads");
            assert!(on_pool, "every item handled by a worker of the pool");
        }
    }

    /// The first failing item ends the stage: later items are refused (not handled) and
    /// `finish` gives that error.
    #[test]
    fn a_failing_item_stops_the_stage_with_its_error() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a thread pool");
        let handled = parking_lot::Mutex::new(Vec::new());
        let (refused, err) = pool.in_place_scope(|scope| {
            let stage = Sequenced::new(scope, (), 2, |(): &mut (), x: usize| {
                if x == 7 {
                    return Err(crate::error::RgbnError::InvalidImage(format!("item {x}")));
                }
                handled.lock().push(x);
                Ok(())
            });
            let refused = (0..100).filter(|&i| stage.push(i).is_err()).count();
            let err = match stage.finish() {
                Err(e) => e.to_string(),
                Ok(()) => panic!("item 7 failed, yet the stage finished"),
            };
            (refused, err)
        });
        assert_eq!(*handled.lock(), (0..7).collect::<Vec<_>>());
        assert!(err.contains("item 7"), "{err}");
        // Items 0..7 handled, 7 failed; of the rest, at most the `cap` queued behind it were
        // accepted before the failure was known.
        assert!(refused >= 100 - 8 - 2, "{refused} refused");
    }
}
