//! §3.4 — the per-cell dexel store: a short sorted list of z ranges with shading data.
//!
//! Invariant: the ranges are sorted by `lo`, pairwise disjoint, and each is non-empty. A facet
//! whose span overlaps voxels already stored only claims the voxels that are still free
//! (first come, first kept: facets reach a cell in stream order, so the result does not depend
//! on timing). A new piece that touches a stored dexel of the same surface (same material and
//! same normal code, e.g. the next facet of a flat wall along a vertical column) extends it
//! instead of taking a slot: the merged dexel keeps the first facet's id. The capacity is a const generic, so `size_of::<DexelStore<N>>()` is the real RAM
//! cost. When a range does not fit, the voxels it would have added are counted as lost and the
//! overflow is counted: never silent.
//!
//! Each dexel also stores its facet's plane ([`crate::plane::DexelPlane`], 16 bytes: the
//! plane-aware lit rule of [`crate::lit`] tests rays against it), so "the same surface" also
//! means the same exact plane: two touching pieces merge only when their plane ids are equal,
//! and a merged dexel's plane offset is taken at its (possibly new) first voxel.

use crate::normal::NormalCode;
use crate::plane::{ColumnPlane, DexelPlane, FacetPlane};
use crate::units::{Depth, FacetId, MaterialId, Span};
use heapless::Vec;

/// One dexel: a run of occupied voxels of one facet, with what shading needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Dexel {
    /// The voxels `span.lo ..= span.hi` of this column.
    pub span: Span,
    /// The facet that produced these voxels.
    pub facet: FacetId,
    /// The facet's material.
    pub material: MaterialId,
    /// The facet's normal, quantised.
    pub normal: NormalCode,
    /// The facet's plane (offset at `span.lo`).
    pub plane: DexelPlane,
}

/// Facet attributes stored with each of its dexels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FacetTag {
    /// Facet id (stream position).
    pub facet: FacetId,
    /// Material index.
    pub material: MaterialId,
    /// Quantised facet normal.
    pub normal: NormalCode,
    /// The facet's plane as the packet carries it.
    pub plane: FacetPlane,
}

/// What one insertion did.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Insertion {
    /// Voxels newly claimed by the facet.
    pub added: u32,
    /// Voxels of the span already held by earlier facets.
    pub shared: u32,
    /// Voxels that should have been added but did not fit (capacity exceeded).
    pub lost: u32,
}

/// The sorted, disjoint dexel list of one column, `N` ranges at most.
#[derive(Clone, Debug, Default)]
pub struct DexelStore<const N: usize> {
    dexels: Vec<Dexel, N>,
    overflows: u32,
    lost_voxels: u32,
}

impl<const N: usize> DexelStore<N> {
    /// An empty store.
    pub const fn new() -> Self {
        DexelStore { dexels: Vec::new(), overflows: 0, lost_voxels: 0 }
    }

    /// The stored dexels, sorted by depth.
    pub fn dexels(&self) -> &[Dexel] {
        &self.dexels
    }

    /// Number of insertions that did not fit.
    pub fn overflows(&self) -> u32 {
        self.overflows
    }

    /// Voxels lost to overflow.
    pub fn lost_voxels(&self) -> u32 {
        self.lost_voxels
    }

    /// Number of occupied voxels in the column.
    pub fn voxel_count(&self) -> u32 {
        self.dexels.iter().map(|d| d.span.len()).sum()
    }

    /// Whether voxel `z` is occupied (binary search).
    pub fn occupied(&self, z: Depth) -> Option<&Dexel> {
        let i = self.dexels.partition_point(|d| d.span.hi < z);
        self.dexels.get(i).filter(|d| d.span.lo <= z)
    }

    /// Extend a neighbour of slot `i` (the dexel before it, or the one at it) by `d` when they
    /// touch and belong to the same surface. Returns whether `d` was absorbed.
    fn absorb(&mut self, i: usize, d: Dexel) -> bool {
        let same = |o: &Dexel| o.material == d.material && o.normal == d.normal && o.plane.id == d.plane.id;
        if i > 0 {
            let prev = &mut self.dexels[i - 1];
            if same(prev) && prev.span.hi as u32 + 1 == d.span.lo as u32 {
                prev.span.hi = d.span.hi;
                // The piece may now also touch the next dexel: join them too.
                if let Some(next) = self.dexels.get(i).copied() {
                    if same(&next) && d.span.hi as u32 + 1 == next.span.lo as u32 {
                        self.dexels[i - 1].span.hi = next.span.hi;
                        self.dexels.remove(i);
                    }
                }
                return true;
            }
        }
        if let Some(next) = self.dexels.get_mut(i) {
            if same(next) && d.span.hi as u32 + 1 == next.span.lo as u32 {
                // The dexel now starts at the piece's first voxel: so does its plane offset.
                next.span.lo = d.span.lo;
                next.plane.e = d.plane.e;
                return true;
            }
        }
        false
    }

    /// Insert the voxels of `span` not yet occupied, tagged with `tag`, with plane offsets of
    /// 0 (a store whose lit rule ignores planes, and tests). See [`DexelStore::insert_on`].
    pub fn insert(&mut self, span: Span, tag: FacetTag) -> Insertion {
        self.insert_on(span, tag, &ColumnPlane::default())
    }

    /// Insert the voxels of `span` not yet occupied, tagged with `tag`; `column` is the facet's
    /// exact plane along this column, from which each new dexel's plane offset is taken at its
    /// first voxel ([`FacetPlane::dexel_plane`]).
    pub fn insert_on(&mut self, span: Span, tag: FacetTag, column: &ColumnPlane) -> Insertion {
        self.insert_planes(span, tag, Some(column))
    }

    /// [`DexelStore::insert_on`] for a cell that runs only the thesis's lit rule (§5.5.5),
    /// which never reads a dexel's plane: every new dexel gets the default plane, and the
    /// plane arithmetic stays out of the cell's code (a firmware image with a small flash
    /// budget). Neighbouring pieces of one surface then merge where their planes would have
    /// kept them apart; the occupied voxels are the same.
    pub fn insert_without_planes(&mut self, span: Span, tag: FacetTag) -> Insertion {
        self.insert_planes(span, tag, None)
    }

    #[inline(always)]
    fn insert_planes(&mut self, span: Span, tag: FacetTag, column: Option<&ColumnPlane>) -> Insertion {
        let mut out = Insertion::default();
        let mut cur = span.lo as u32; // first voxel not yet decided (u32: may pass u16::MAX)
        let hi = span.hi as u32;
        while cur <= hi {
            // First stored dexel ending at or after `cur`.
            let i = self.dexels.partition_point(|d| (d.span.hi as u32) < cur);
            let next = self.dexels.get(i).map(|d| d.span);
            match next {
                Some(s) if s.lo as u32 <= cur => {
                    // `cur` is held by an earlier facet.
                    out.shared += (s.hi as u32).min(hi) + 1 - cur;
                    cur = s.hi as u32 + 1;
                }
                _ => {
                    // Free gap from `cur` to the next stored dexel (or to the span's end).
                    let gap_end = match next {
                        Some(s) if s.lo as u32 <= hi => s.lo as u32,
                        _ => hi + 1,
                    };
                    let piece = Span { lo: cur as Depth, hi: (gap_end - 1) as Depth };
                    let plane =
                        column.map_or(DexelPlane::default(), |c| tag.plane.dexel_plane(c.value(piece.lo as i64)));
                    let d = Dexel { span: piece, facet: tag.facet, material: tag.material, normal: tag.normal, plane };
                    if self.absorb(i, d) || self.dexels.insert(i, d).is_ok() {
                        out.added += piece.len();
                    } else {
                        out.lost += piece.len();
                    }
                    cur = gap_end;
                }
            }
        }
        if out.lost > 0 {
            self.overflows += 1;
            self.lost_voxels += out.lost;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec as StdVec;

    /// A tag of a distinct surface per facet (distinct normals: never merged).
    fn tag(f: u32) -> FacetTag {
        FacetTag { facet: f, normal: NormalCode(f as u16), ..Default::default() }
    }

    fn check_invariant<const N: usize>(s: &DexelStore<N>) {
        for w in s.dexels().windows(2) {
            assert!(w[0].span.hi < w[1].span.lo, "sorted and disjoint: {:?}", w);
        }
        for d in s.dexels() {
            assert!(d.span.lo <= d.span.hi);
        }
    }

    #[test]
    fn overlapping_facet_claims_only_free_voxels() {
        let mut s = DexelStore::<8>::new();
        s.insert(Span { lo: 10, hi: 12 }, tag(1));
        s.insert(Span { lo: 20, hi: 22 }, tag(2));
        let ins = s.insert(Span { lo: 5, hi: 30 }, tag(3));
        assert_eq!(ins, Insertion { added: 26 - 6, shared: 6, lost: 0 });
        let got: StdVec<_> = s.dexels().iter().map(|d| (d.span.lo, d.span.hi, d.facet)).collect();
        assert_eq!(got, [(5, 9, 3), (10, 12, 1), (13, 19, 3), (20, 22, 2), (23, 30, 3)]);
        check_invariant(&s);
    }

    #[test]
    fn touching_pieces_of_one_surface_share_a_slot() {
        let wall = |f: u32| FacetTag { facet: f, material: 3, normal: NormalCode(77), ..Default::default() };
        let mut s = DexelStore::<2>::new();
        s.insert(Span { lo: 0, hi: 4 }, wall(1));
        s.insert(Span { lo: 10, hi: 14 }, wall(2));
        // Fills the gap between both: all three become one dexel, the first facet's id.
        let ins = s.insert(Span { lo: 3, hi: 11 }, wall(3));
        assert_eq!(ins, Insertion { added: 5, shared: 4, lost: 0 });
        let got: StdVec<_> = s.dexels().iter().map(|d| (d.span.lo, d.span.hi, d.facet)).collect();
        assert_eq!(got, [(0, 14, 1)]);
        // Another surface touching it does not merge.
        s.insert(Span { lo: 15, hi: 15 }, tag(9));
        assert_eq!(s.dexels().len(), 2);
    }

    /// Pieces of one plane merge, and the merged dexel's offset is the plane's value at its
    /// first voxel; a touching piece of another plane (same material and normal code) does not
    /// merge.
    #[test]
    fn merging_follows_planes() {
        let plane = |id| FacetPlane { id, nx: 0, ny: 0, nz: 1 << 30, m: 1 };
        // E(z) = 16·(z − 20): a plane z = 20 in loading units (q = 16, m = 1).
        let column = ColumnPlane { p: -16 * 20, c: 16 };
        let tag = |f, id| FacetTag { facet: f, material: 1, normal: NormalCode(5), plane: plane(id) };
        let mut s = DexelStore::<4>::new();
        s.insert_on(Span { lo: 19, hi: 21 }, tag(1, 7), &column);
        assert_eq!(s.dexels()[0].plane.e, -(16 << 10));
        // A piece below, same plane: extends the dexel downward, offset at z = 17.
        s.insert_on(Span { lo: 17, hi: 18 }, tag(2, 7), &column);
        assert_eq!(s.dexels().len(), 1);
        assert_eq!((s.dexels()[0].span.lo, s.dexels()[0].facet), (17, 1));
        assert_eq!(s.dexels()[0].plane.e, -3 * (16 << 10));
        // A piece above, same plane: extends upward, offset unchanged.
        s.insert_on(Span { lo: 22, hi: 22 }, tag(3, 7), &column);
        assert_eq!((s.dexels().len(), s.dexels()[0].span.hi, s.dexels()[0].plane.e), (1, 22, -3 * (16 << 10)));
        // Another plane touching it: a dexel of its own.
        s.insert_on(Span { lo: 23, hi: 24 }, tag(4, 8), &column);
        assert_eq!(s.dexels().len(), 2);
        assert_eq!(s.dexels()[1].plane.id, 8);
        check_invariant(&s);
    }

    #[test]
    fn overflow_is_counted_not_silent() {
        let mut s = DexelStore::<2>::new();
        s.insert(Span { lo: 0, hi: 0 }, tag(1));
        s.insert(Span { lo: 10, hi: 10 }, tag(2));
        let ins = s.insert(Span { lo: 4, hi: 6 }, tag(3));
        assert_eq!(ins.lost, 3);
        assert_eq!((s.overflows(), s.lost_voxels()), (1, 3));
        assert_eq!(s.voxel_count(), 2);
    }

    #[test]
    fn top_of_depth_range() {
        let mut s = DexelStore::<4>::new();
        s.insert(Span { lo: 65530, hi: u16::MAX }, tag(1));
        let ins = s.insert(Span { lo: 65000, hi: u16::MAX }, tag(2));
        assert_eq!(ins, Insertion { added: 530, shared: 6, lost: 0 });
        check_invariant(&s);
    }

    proptest! {
        /// Oracle: a plain per-voxel owner array; first writer keeps the voxel.
        #[test]
        fn store_matches_per_voxel_owner_array(spans in proptest::collection::vec((0u16..64, 0u16..12), 0..24)) {
            let mut s = DexelStore::<64>::new();
            let mut owner = [0u32; 80];
            for (f, (lo, len)) in spans.iter().enumerate() {
                let span = Span { lo: *lo, hi: lo + len };
                let ins = s.insert(span, tag(f as u32 + 1));
                let mut added = 0;
                for z in span.lo..=span.hi {
                    if owner[z as usize] == 0 { owner[z as usize] = f as u32 + 1; added += 1; }
                }
                prop_assert_eq!(ins.added, added);
                prop_assert_eq!(ins.added + ins.shared, span.len());
                check_invariant(&s);
            }
            for z in 0..80u16 {
                prop_assert_eq!(s.occupied(z).map(|d| d.facet).unwrap_or(0), owner[z as usize]);
            }
        }

        /// With merging surfaces (few materials/normals), the voxel set is still the union of
        /// the spans, the store stays sorted and disjoint, and touching same-surface dexels
        /// never remain separate.
        #[test]
        fn merged_store_keeps_the_union(spans in proptest::collection::vec((0u16..64, 0u16..12, 0u16..2), 0..24)) {
            let mut s = DexelStore::<64>::new();
            let mut occ = [false; 80];
            for (f, (lo, len, surf)) in spans.iter().enumerate() {
                let t = FacetTag { facet: f as u32, material: 0, normal: NormalCode(*surf), ..Default::default() };
                let ins = s.insert(Span { lo: *lo, hi: lo + len }, t);
                prop_assert_eq!(ins.added + ins.shared, *len as u32 + 1);
                for z in *lo..=lo + len { occ[z as usize] = true; }
                check_invariant(&s);
                for w in s.dexels().windows(2) {
                    prop_assert!(!(w[0].span.hi + 1 == w[1].span.lo && w[0].normal == w[1].normal));
                }
            }
            for z in 0..80u16 {
                prop_assert_eq!(s.occupied(z).is_some(), occ[z as usize]);
            }
        }

        /// Without planes the store holds the same voxels, each with the same material and
        /// normal, as with them (oracle: the store with planes, itself checked against the
        /// owner array above); the planes are the default, and touching pieces of one surface
        /// that distinct planes kept apart may merge (the merged dexel names its first facet).
        #[test]
        fn without_planes_the_same_voxels(spans in proptest::collection::vec((0u16..64, 0u16..12, 0u16..2, -3i64..3), 0..24)) {
            let (mut with, mut without) = (DexelStore::<64>::new(), DexelStore::<64>::new());
            for (f, (lo, len, surf, p)) in spans.iter().enumerate() {
                let plane = FacetPlane { id: f as u32 % 3, nx: *p as i16, ny: 1, nz: 2 << 16, m: 2 };
                let t = FacetTag { facet: f as u32, material: 0, normal: NormalCode(*surf), plane };
                let span = Span { lo: *lo, hi: lo + len };
                let column = ColumnPlane { p: *p, c: 2 };
                let (a, b) = (with.insert_on(span, t, &column), without.insert_without_planes(span, t));
                prop_assert_eq!((a.added, a.shared, a.lost), (b.added, b.shared, b.lost));
                check_invariant(&without);
            }
            for z in 0..80u16 {
                let key = |d: &Dexel| (d.material, d.normal);
                prop_assert_eq!(with.occupied(z).map(key), without.occupied(z).map(key));
                prop_assert!(without.occupied(z).is_none_or(|d| d.plane == DexelPlane::default()));
            }
        }

        /// With a small capacity nothing is ever lost silently: kept + lost = what the oracle owns.
        #[test]
        fn small_capacity_accounts_for_every_voxel(spans in proptest::collection::vec((0u16..64, 0u16..6), 0..24)) {
            let mut s = DexelStore::<3>::new();
            let mut lost = 0;
            let mut owner = [false; 80];
            for (f, (lo, len)) in spans.iter().enumerate() {
                let ins = s.insert(Span { lo: *lo, hi: lo + len }, tag(f as u32));
                lost += ins.lost;
                for z in *lo..=lo + len { owner[z as usize] = true; }
                check_invariant(&s);
            }
            // Every voxel some facet wanted is either stored or counted lost (possibly counted
            // more than once when several facets wanted it and none fit).
            let wanted = owner.iter().filter(|&&o| o).count() as u32;
            prop_assert!(s.voxel_count() + lost >= wanted);
            prop_assert_eq!(s.lost_voxels(), lost);
            prop_assert_eq!(s.overflows() > 0, lost > 0);
        }
    }
}
