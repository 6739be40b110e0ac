//! Integer types named for what they mean, and the one place they convert.
//!
//! A cell never sees floating point during loading: positions are voxel indices, depths are
//! voxel indices along z, and the geometry arrives as exact integer coefficients (see
//! [`crate::voxelize`] for their bit budget).

/// Index of a column (a cell) along x or y: `0 ..= MAX_N - 1`.
pub type Coord = u16;

/// Index of a voxel along z inside a column: `0 ..= depth - 1`.
pub type Depth = u16;

/// Identifier of a facet, as numbered by the host (its position in the facet stream).
pub type FacetId = u32;

/// Material index, as numbered by the host (index into the scene's material table).
pub type MaterialId = u16;

/// Largest grid side (and depth) a cell supports: coordinates and depths are `u16`, and the
/// loading arithmetic is proven overflow-free up to this size (see [`crate::voxelize`]).
pub const MAX_N: u32 = 1 << 16;

/// Half-open-free inclusive range of depths `lo ..= hi` inside one column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Span {
    /// First (smallest) z of the range: the thesis's `Z_ar`.
    pub lo: Depth,
    /// Last (largest) z of the range: the thesis's `Z_av`.
    pub hi: Depth,
}

impl Span {
    /// Number of voxels in the span.
    pub const fn len(&self) -> u32 {
        self.hi as u32 - self.lo as u32 + 1
    }

    /// A span is never empty (`lo <= hi` is an invariant of every constructor).
    pub const fn is_empty(&self) -> bool {
        false
    }

    /// Whether `z` lies in the span.
    pub const fn contains(&self, z: Depth) -> bool {
        self.lo <= z && z <= self.hi
    }

    /// Clip an exact integer range `lo ..= hi` to `0 ..= depth - 1`; `None` when empty.
    pub fn clipped(lo: i64, hi: i64, depth: u32) -> Option<Span> {
        let lo = lo.max(0);
        let hi = hi.min(depth as i64 - 1);
        if lo > hi {
            return None;
        }
        // Both are now in 0 ..= depth - 1 <= u16::MAX.
        Some(Span { lo: lo as Depth, hi: hi as Depth })
    }
}
