//! Disjoint pieces of the cell array for data-parallel phases (rayon): each piece is a
//! contiguous run of cells with the sorted cell indices that fall in it, so each worker owns its
//! cells exactly and results do not depend on how the work was cut.
//!
//! The phases hand their pieces to rayon through [`par_each`] and [`par_map`], whose pipelines
//! take the work as a `&dyn Fn`: rayon's machinery is compiled once (per item type), not once
//! per instance of the generic scheduler that calls it (14 fraction widths × 4 link stacks; a
//! zipped `par_iter` per phase there was about a quarter of host-sim's LLVM IR). A piece is
//! hundreds of cells, so the indirect call costs nothing measurable.

use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

use rayon::prelude::*;

/// How many items a piece takes: at least `min`, and about eight pieces per thread.
fn piece_len(len: usize, min: usize) -> usize {
    min.max(len.div_ceil(8 * rayon::current_num_threads())).max(1)
}

/// Cut `cells`, the cells from index `origin` on, at the strictly increasing indices `idx`
/// (each `origin` or more) into pieces of about the same number of indices: `(cells of the
/// piece, index of its first cell, the indices in it)`.
pub fn tiles<'a, T>(
    mut cells: &'a mut [T],
    origin: usize,
    idx: &'a [u32],
    min: usize,
) -> Vec<(&'a mut [T], usize, &'a [u32])> {
    let mut out = Vec::new();
    let mut base = origin;
    for chunk in idx.chunks(piece_len(idx.len(), min)) {
        let end = chunk[chunk.len() - 1] as usize + 1;
        let (head, tail) = std::mem::take(&mut cells).split_at_mut(end - base);
        out.push((head, base, chunk));
        cells = tail;
        base = end;
    }
    out
}

/// `work(item)` for each item, in parallel on rayon's pool (one task per item: items are
/// coarse pieces). Results go through what `work` captures (e.g. each item carries its own
/// result slot).
pub fn par_each<T: Send>(items: Vec<T>, work: impl Fn(T) + Sync) {
    let slots: Vec<Mutex<Option<T>>> = items.into_iter().map(|t| Mutex::new(Some(t))).collect();
    par_indices(slots.len(), &|i| {
        // Each index is visited once, so each slot is taken once (the lock is released before
        // the work runs).
        let item = slots[i].lock().unwrap_or_else(PoisonError::into_inner).take();
        if let Some(t) = item {
            work(t);
        }
    });
}

/// `f(i)` for i in `0..len`, in parallel, in index order.
pub fn par_map<T: Send>(len: usize, f: &(dyn Fn(usize) -> T + Sync)) -> Vec<T> {
    (0..len).into_par_iter().map(f).collect()
}

/// The one rayon pipeline behind [`par_each`].
fn par_indices(count: usize, work: &(dyn Fn(usize) + Sync)) {
    (0..count).into_par_iter().for_each(work);
}

/// The threads of rayon's pool kept awake for a whole loop of many short parallel phases (a
/// diffusion runs two or three a machine cycle, each a fraction of a millisecond): between
/// phases the helpers spin, so a phase starts without waking a sleeping worker through the
/// kernel, which cost about a tenth of the CPU time of a two-thread render. Each thread works
/// through its own contiguous lane of a phase's items, then helps with the others' (see `Job`;
/// like [`par_each`], results go through what the work captures), so what a phase computes does
/// not depend on the threads.
///
/// Only the thread that made the team hands out work ([`Team::each`]). Its helpers are threads
/// of their own, not rayon's: the pool's other workers sleep while a team lives.
pub struct Team<'s> {
    state: &'s TeamState,
    /// The caller and its helpers.
    threads: usize,
}

/// What the team's threads share: the phase on offer (null: none), its generation, the helpers
/// inside a phase, and the stop flag.
struct TeamState {
    job: AtomicPtr<Job<'static>>,
    generation: AtomicU64,
    inside: AtomicUsize,
    stop: AtomicBool,
}

/// The most threads a team has lanes for (more share the last lanes' items).
const MAX_LANES: usize = 64;

/// One phase: its work, the item count, its lanes, the items done, and the first panic of an
/// item (re-raised on the caller once the phase is over).
///
/// The items are cut into one contiguous lane per thread of the team (thread t: items
/// `t · count / T ..`), each with the next item it hands out. A thread empties its own lane
/// first, then helps the others, in lane order. Consecutive phases cut alike, and the grid's
/// phases list cells in row-major order, so a thread keeps working on about the same cells
/// cycle after cycle, in its own core's cache, instead of cells going to whichever thread asks
/// first.
struct Job<'w> {
    work: &'w (dyn Fn(usize) + Sync),
    count: usize,
    threads: usize,
    next: [AtomicUsize; MAX_LANES],
    done: AtomicUsize,
    panic: Mutex<Option<Box<dyn std::any::Any + Send>>>,
}

impl<'w> Job<'w> {
    fn new(work: &'w (dyn Fn(usize) + Sync), count: usize, threads: usize) -> Self {
        let threads = threads.clamp(1, MAX_LANES);
        Job {
            work,
            count,
            threads,
            next: std::array::from_fn(|l| AtomicUsize::new(Self::lane_start(count, threads, l))),
            done: AtomicUsize::new(0),
            panic: Mutex::new(None),
        }
    }

    /// The first item of lane `l` (lane `threads` ends the last one).
    fn lane_start(count: usize, threads: usize, l: usize) -> usize {
        count * l.min(threads) / threads
    }

    /// Thread `me`: take and run items, from its own lane and then the others', until none is
    /// left. An item that panics still counts as done (the caller must not return while others
    /// run), its panic kept for the caller.
    fn run(&self, me: usize) {
        let t = self.threads;
        for l in (0..t).map(|k| (me + k) % t) {
            let end = Self::lane_start(self.count, t, l + 1);
            loop {
                let i = self.next[l].fetch_add(1, Ordering::Relaxed);
                if i >= end {
                    break;
                }
                if let Err(p) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| (self.work)(i))) {
                    self.panic.lock().unwrap_or_else(PoisonError::into_inner).get_or_insert(p);
                }
                self.done.fetch_add(1, Ordering::Release);
            }
        }
    }
}

/// Run `f` with a [`Team`] as large as the current rayon pool (`--threads`): the caller and
/// threads of its own for the rest (scoped: started here, joined before returning; a pool of
/// one has no helpers, the team's phases run on the caller).
pub fn with_team<R>(f: impl FnOnce(&Team<'_>) -> R) -> R {
    let state = TeamState {
        job: AtomicPtr::new(std::ptr::null_mut()),
        generation: AtomicU64::new(0),
        inside: AtomicUsize::new(0),
        stop: AtomicBool::new(false),
    };
    let helpers = rayon::current_num_threads().saturating_sub(1);
    if helpers == 0 {
        return f(&Team { state: &state, threads: 1 });
    }
    std::thread::scope(|s| {
        for me in 1..=helpers {
            let state = &state;
            s.spawn(move || state.help(me));
        }
        // Stops the helpers however `f` ends (a panic in it unwinds through here).
        struct Stop<'a>(&'a AtomicBool);
        impl Drop for Stop<'_> {
            fn drop(&mut self) {
                self.0.store(true, Ordering::Release);
            }
        }
        let _stop = Stop(&state.stop);
        f(&Team { state: &state, threads: helpers + 1 })
    })
}

/// One round of waiting for another thread, the `round`-th in a row: a spin (a phase is a
/// fraction of a millisecond), then, past a few thousand rounds, the core handed back to the
/// scheduler each round (more threads than cores: a test harness running diffusions side by
/// side, another process), and past a few hundred thousand a short sleep (a long serial stretch
/// of the caller).
fn wait(round: u32) {
    if round < 4096 {
        std::hint::spin_loop();
    } else if round < 1 << 18 {
        std::thread::yield_now();
    } else {
        std::thread::sleep(std::time::Duration::from_micros(50));
    }
}

impl TeamState {
    /// A helper: wait for phases (spinning, then yielding its core now and then) and work on
    /// them until the team stops.
    fn help(&self, me: usize) {
        let mut seen = 0u64;
        let mut idle = 0u32;
        while !self.stop.load(Ordering::Acquire) {
            let g = self.generation.load(Ordering::Acquire);
            if g == seen {
                idle = idle.saturating_add(1);
                wait(idle);
                continue;
            }
            idle = 0;
            // Announce before reading the job: the caller does not end a phase while a helper
            // that may have read it is inside. Both this pair and the caller's retirement
            // (null the job, then read `inside`) are sequentially consistent: with release and
            // acquire alone each side may miss the other's write (a store buffer on x86-64
            // holds the caller's null while its load of `inside` reads 0), and a helper would
            // run a retired job.
            self.inside.fetch_add(1, Ordering::SeqCst);
            let job = self.job.load(Ordering::SeqCst);
            if !job.is_null() {
                // SAFETY: a non-null `job` points to the `Job` of a phase `Team::each` has
                // published and not yet retired: it retires it (nulls the pointer, then waits
                // for `inside` to drop to zero) before the `Job` and the work it borrows go out
                // of scope, and this helper counted itself in `inside` before loading it.
                #[allow(unsafe_code)]
                unsafe {
                    (*job).run(me)
                };
            }
            seen = g;
            self.inside.fetch_sub(1, Ordering::AcqRel);
        }
    }
}

impl Team<'_> {
    /// `work(item)` for each item, on the team's threads; returns when every item is done
    /// (like [`par_each`]).
    pub fn each<T: Send>(&self, items: Vec<T>, work: impl Fn(T) + Sync) {
        let count = items.len();
        if count == 0 {
            return;
        }
        let slots: Vec<Mutex<Option<T>>> = items.into_iter().map(|t| Mutex::new(Some(t))).collect();
        let run = |i: usize| {
            // Each index is handed out once, so each slot is taken once.
            let item = slots[i].lock().unwrap_or_else(PoisonError::into_inner).take();
            if let Some(t) = item {
                work(t);
            }
        };
        if count == 1 {
            return run(0);
        }
        let job = Job::new(&run, count, self.threads);
        let st = self.state;
        // The helpers see the job only between here and its retirement below.
        st.job.store((&job as *const Job<'_>).cast_mut().cast(), Ordering::Release);
        st.generation.fetch_add(1, Ordering::AcqRel);
        job.run(0);
        let mut spins = 0u32;
        while job.done.load(Ordering::Acquire) < count {
            spins = spins.saturating_add(1);
            wait(spins);
        }
        // Retire: no helper reads the job once it is null, and those that read it are counted.
        // Sequentially consistent, against the helpers' announce-then-load (see `help`).
        st.job.store(std::ptr::null_mut(), Ordering::SeqCst);
        while st.inside.load(Ordering::SeqCst) != 0 {
            spins = spins.saturating_add(1);
            wait(spins);
        }
        if let Some(p) = job.panic.into_inner().unwrap_or_else(PoisonError::into_inner) {
            std::panic::resume_unwind(p);
        }
    }
}

/// Ask the CPU to start loading the cache line at `p` (a hint: no effect on results, never a
/// fault, a no-op off x86-64). The grid's passes walk scattered cells of a large array and are
/// bound by memory latency; they announce the cells a few steps ahead.
#[inline(always)]
#[allow(unsafe_code)]
pub fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: the intrinsic needs SSE, part of the x86-64 baseline; PREFETCHT0 reads nothing
    // architecturally visible and never faults, whatever the address.
    unsafe {
        core::arch::x86_64::_mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(p.cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// [`prefetch`] the first and the last cache line of `x` (a heapless vector keeps its length
/// after its slots: both ends are what a lookup reads first).
#[inline(always)]
pub fn prefetch_ends<T>(x: &T) {
    let p = (x as *const T).cast::<u8>();
    prefetch(p);
    prefetch(p.wrapping_add(std::mem::size_of::<T>().saturating_sub(1)));
}

/// `into` := the sorted union of the sorted lists `a` and `b` (an index in both appears once),
/// then swapped into `a`: linear, where sorting the appended lists each cycle was not.
pub fn merge_sorted(a: &mut Vec<u32>, b: &[u32], into: &mut Vec<u32>) {
    into.clear();
    into.reserve(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        let (x, y) = (a[i], b[j]);
        into.push(x.min(y));
        i += usize::from(x <= y);
        j += usize::from(y <= x);
    }
    into.extend_from_slice(&a[i..]);
    into.extend_from_slice(&b[j..]);
    std::mem::swap(a, into);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn par_each_visits_every_item_once_and_par_map_keeps_order() {
        let mut out = vec![0u32; 1000];
        let items: Vec<(usize, &mut u32)> = out.iter_mut().enumerate().collect();
        par_each(items, |(i, r)| *r += i as u32 * 3 + 1);
        assert!(out.iter().enumerate().all(|(i, &v)| v == i as u32 * 3 + 1));
        assert_eq!(par_map(1000, &|i| i * i), (0..1000).map(|i| i * i).collect::<Vec<_>>());
        par_each(Vec::<u8>::new(), |_| unreachable!("no items"));
    }

    /// A team of 1 to 4 threads runs every item of every phase once, phase after phase (many
    /// short phases, as a diffusion's cycles), and a panicking item reaches the caller after
    /// the phase, with the team still usable.
    #[test]
    fn a_team_runs_every_item_once_and_passes_panics_on() {
        for threads in 1..=4 {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                with_team(|team| {
                    let mut out = vec![0u32; 300];
                    for phase in 0..200u32 {
                        let len = (phase as usize * 7) % 300;
                        let items: Vec<(usize, &mut u32)> = out[..len].iter_mut().enumerate().collect();
                        team.each(items, |(i, r)| *r += i as u32 + phase);
                    }
                    let want: Vec<u32> = (0..300usize)
                        .map(|i| (0..200u32).filter(|&p| i < (p as usize * 7) % 300).map(|p| i as u32 + p).sum())
                        .collect();
                    assert_eq!(out, want, "{threads} threads");
                    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        team.each((0..64).collect(), |i: u32| assert!(i != 41, "item 41"));
                    }));
                    assert!(caught.is_err(), "the panic reaches the caller");
                    let count = AtomicUsize::new(0);
                    team.each((0..64).collect(), |_: u32| {
                        count.fetch_add(1, Ordering::Relaxed);
                    });
                    assert_eq!(count.into_inner(), 64);
                });
            });
        }
    }

    /// Many phases of two items, each phase's work borrowing fresh heap memory freed as soon as
    /// the phase returns, with more threads than items: a helper that ran a retired phase (the
    /// caller's retirement and a helper's announce missing each other) would count into freed
    /// memory, so that a phase's items are not each counted once.
    #[test]
    fn retired_phases_are_never_run() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
        pool.install(|| {
            with_team(|team| {
                for phase in 0..20_000u32 {
                    let counts: Vec<AtomicUsize> = (0..2).map(|_| AtomicUsize::new(0)).collect();
                    team.each(vec![0usize, 1], |i| {
                        counts[i].fetch_add(1, Ordering::Relaxed);
                    });
                    let got: Vec<usize> = counts.iter().map(|c| c.load(Ordering::Relaxed)).collect();
                    assert_eq!(got, [1, 1], "phase {phase}");
                }
            });
        });
    }

    /// A job's lanes cut its items into contiguous runs, one per thread, of sizes differing by
    /// at most one, covering every item once (any count, any team size, beyond the lane limit).
    #[test]
    fn lanes_cut_the_items_into_one_run_per_thread() {
        let work = |_: usize| {};
        for threads in [1usize, 2, 3, 7, MAX_LANES, MAX_LANES + 5] {
            for count in [0usize, 1, 2, 5, 63, 64, 65, 1000] {
                let job = Job::new(&work, count, threads);
                let t = threads.min(MAX_LANES);
                assert_eq!(job.threads, t);
                let bounds: Vec<usize> = (0..=t).map(|l| Job::lane_start(count, t, l)).collect();
                assert_eq!((bounds[0], bounds[t]), (0, count));
                let sizes: Vec<usize> = bounds.windows(2).map(|w| w[1] - w[0]).collect();
                assert!(sizes.iter().max().unwrap() - sizes.iter().min().unwrap() <= 1, "{count} over {t}: {sizes:?}");
                (0..t).for_each(|l| assert_eq!(job.next[l].load(Ordering::Relaxed), bounds[l]));
            }
        }
    }

    #[test]
    fn pieces_cover_every_index_once_with_its_own_cell() {
        let mut cells: Vec<u32> = (0..1000).collect();
        let idx: Vec<u32> = (0..1000).filter(|i| i % 7 == 3 || i % 11 == 0).collect();
        // The whole array, and the cells from 300 on (a band held alone).
        for origin in [0usize, 300] {
            let want: Vec<u32> = idx.iter().copied().filter(|&i| i as usize >= origin).collect();
            let mut seen = Vec::new();
            for (tile, base, ix) in tiles(&mut cells[origin..], origin, &want, 5) {
                for &i in ix {
                    assert_eq!(tile[i as usize - base], i);
                    seen.push(i);
                }
            }
            assert_eq!(seen, want);
        }
    }

    proptest::proptest! {
        #[test]
        fn merge_is_the_sorted_union(a in proptest::collection::btree_set(0u32..300, 0..80),
                                     b in proptest::collection::btree_set(0u32..300, 0..80)) {
            let (mut x, y) = (a.iter().copied().collect::<Vec<_>>(), b.iter().copied().collect::<Vec<_>>());
            let mut scratch = vec![7, 7, 7];
            merge_sorted(&mut x, &y, &mut scratch);
            proptest::prop_assert_eq!(x, a.union(&b).copied().collect::<Vec<_>>());
        }
    }
}
