//! Disjoint pieces of the cell array for data-parallel phases (rayon): each piece is a
//! contiguous run of cells with the sorted cell indices that fall in it, so each worker owns its
//! cells exactly and results do not depend on how the work was cut.
//!
//! The phases hand their pieces to rayon through [`par_each`] and [`par_map`], whose pipelines
//! take the work as a `&dyn Fn`: rayon's machinery is compiled once (per item type), not once
//! per instance of the generic scheduler that calls it (14 fraction widths × 4 link stacks; a
//! zipped `par_iter` per phase there was about a quarter of host-sim's LLVM IR). A piece is
//! hundreds of cells, so the indirect call costs nothing measurable.

use std::sync::{Mutex, PoisonError};

use rayon::prelude::*;

/// How many items a piece takes: at least `min`, and about eight pieces per thread.
fn piece_len(len: usize, min: usize) -> usize {
    min.max(len.div_ceil(8 * rayon::current_num_threads())).max(1)
}

/// Cut `cells` at the strictly increasing indices `idx` into pieces of about the same number of
/// indices: `(cells of the piece, index of its first cell, the indices in it)`.
pub fn tiles<'a, T>(mut cells: &'a mut [T], idx: &'a [u32], min: usize) -> Vec<(&'a mut [T], usize, &'a [u32])> {
    let mut out = Vec::new();
    let mut base = 0usize;
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

    #[test]
    fn pieces_cover_every_index_once_with_its_own_cell() {
        let mut cells: Vec<u32> = (0..1000).collect();
        let idx: Vec<u32> = (0..1000).filter(|i| i % 7 == 3 || i % 11 == 0).collect();
        let mut seen = Vec::new();
        for (tile, base, ix) in tiles(&mut cells, &idx, 5) {
            for &i in ix {
                assert_eq!(tile[i as usize - base], i);
                seen.push(i);
            }
        }
        assert_eq!(seen, idx);
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
