//! What the skips know of the scene (thesis §4.4.3, the rc2 skips): the occupied box of the
//! receding-beam skip ([`OccupiedBox`]) and the bounds of a sub-beam's voxels ([`SubBeamBounds`],
//! [`VoxelBox`]).

use super::*;

/// The bounding box of the occupied voxels, `lo ..= hi` on each axis (x, y, z); 12 bytes that
/// every cell holds for the *receding-beam skip* (a min/max reduction over the grid after
/// loading, or the host's broadcast). `lo > hi` on an axis means no voxel is occupied.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct OccupiedBox {
    /// Smallest occupied coordinate per axis.
    pub lo: [Depth; 3],
    /// Largest occupied coordinate per axis.
    pub hi: [Depth; 3],
}

impl OccupiedBox {
    /// Whether no ray of a beam of direction `dir`, from a source in voxel `sv`, that is in voxel
    /// `at` can ever meet an occupied voxel again. Exact, by monotonicity: along the principal
    /// axis a ray moves strictly in the direction's sign; on a transverse axis its voxel
    /// coordinate ⌊S + u·k/D + ½⌋ is monotone in k with the sign of u and equals the source
    /// voxel's at k = 0, so a ray in a voxel strictly beyond the source voxel on that axis has
    /// u > 0 (resp. u < 0) and never comes back. So the beam recedes if, on some axis, it is
    /// beyond the box and moving (principal) or bound (transverse) away from it.
    pub fn receding(&self, dir: Direction, sv: [i32; 3], at: [i64; 3]) -> bool {
        !self.alive(dir, sv).contains(at)
    }

    /// The voxels a beam of direction `dir` from a source in voxel `sv` may be in and still
    /// meet an occupied voxel later: [`OccupiedBox::receding`] is "outside this box", so a cell
    /// computes it once per beam and tests each sub-beam with six comparisons. On a transverse
    /// axis a beam recedes beyond max(hi, s) or below min(lo, s); along the principal axis
    /// beyond the box in the direction of travel; an empty box keeps nothing.
    pub fn alive(&self, dir: Direction, sv: [i32; 3]) -> VoxelBox {
        if (0..3).any(|a| self.lo[a] > self.hi[a]) {
            return VoxelBox { lo: [1; 3], hi: [0; 3] };
        }
        let w = dir.principal().index();
        let bound = |a: usize| {
            let (lo, hi, s) = (self.lo[a] as i64, self.hi[a] as i64, sv[a] as i64);
            if a != w {
                (lo.min(s), hi.max(s))
            } else if dir.sign() > 0 {
                (i64::MIN, hi)
            } else {
                (lo, i64::MAX)
            }
        };
        let b = [bound(0), bound(1), bound(2)];
        VoxelBox { lo: b.map(|x| x.0), hi: b.map(|x| x.1) }
    }
}

/// Where a sub-beam may go and still be sent, per direction: the grid, cut by the receding
/// skip's [`OccupiedBox::alive`] box when that skip is on. It depends only on the grid, the
/// skip's box and the source, so a cell computes it once per source ([`SubBeamBounds::new`])
/// rather than once per beam; a sub-beam outside it left the grid or is skipped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SubBeamBounds {
    /// Largest x, y, z of the grid (the smallest are 0).
    grid_hi: [i32; 3],
    /// Per direction (index: [`Direction`] as `usize`): smallest and largest x, y, z kept
    /// (empty: some lo > hi). Within the grid, so they fit `i32`.
    keep: [([i32; 3], [i32; 3]); 6],
}

impl SubBeamBounds {
    /// The bounds of an `n` × `n` grid of `depth` voxels per column, with the receding skip's
    /// box `skip` (`None`: off), for beams from `source`.
    pub fn new(n: u32, depth: u32, skip: Option<OccupiedBox>, source: &Source) -> Self {
        let grid_hi = [n as i64 - 1, n as i64 - 1, depth as i64 - 1];
        let sv = source.voxel();
        let keep = Direction::ALL.map(|dir| {
            let alive = skip.map(|bx| bx.alive(dir, sv));
            let axis = |a: usize| {
                let (lo, hi) = alive.map_or((0, grid_hi[a]), |b| (b.lo[a].max(0), b.hi[a].min(grid_hi[a])));
                // An empty range stays empty: lo > hi after clamping both into [0, grid_hi].
                (lo.clamp(0, grid_hi[a] + 1) as i32, hi.clamp(-1, grid_hi[a]) as i32)
            };
            let [x, y, z] = [axis(0), axis(1), axis(2)];
            ([x.0, y.0, z.0], [x.1, y.1, z.1])
        });
        SubBeamBounds { grid_hi: grid_hi.map(|h| h as i32), keep }
    }

    /// Whether a sub-beam of direction `dir` going to voxel `to` is sent (the common case: one
    /// box test).
    #[inline]
    pub(super) fn keeps(&self, dir: Direction, to: [i64; 3]) -> bool {
        let (lo, hi) = &self.keep[dir as usize];
        (0..3).fold(true, |ok, a| ok & (to[a] >= lo[a] as i64) & (to[a] <= hi[a] as i64))
    }

    /// Whether voxel `to` is in the grid.
    #[inline]
    pub(super) fn in_grid(&self, to: [i64; 3]) -> bool {
        (0..3).fold(true, |ok, a| ok & (to[a] >= 0) & (to[a] <= self.grid_hi[a] as i64))
    }
}

/// A box of voxel coordinates, bounds included (empty if some `lo` > `hi`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VoxelBox {
    /// Smallest coordinate per axis.
    pub lo: [i64; 3],
    /// Largest coordinate per axis.
    pub hi: [i64; 3],
}

impl VoxelBox {
    /// Whether `at` is in the box.
    pub fn contains(&self, at: [i64; 3]) -> bool {
        (at[0] >= self.lo[0])
            & (at[0] <= self.hi[0])
            & (at[1] >= self.lo[1])
            & (at[1] <= self.hi[1])
            & (at[2] >= self.lo[2])
            & (at[2] <= self.hi[2])
    }
}
