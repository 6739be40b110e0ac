//! The lit state of a column (thesis §4.4, §5.5.5): runs of consecutive lit voxels with the
//! same source mask ([`LitRuns`]); a mark that does not fit is counted, never lost silently.

use super::*;

/// Lit voxels of one column, as runs of consecutive voxels with the same source mask.
///
/// Invariant: runs sorted, disjoint, non-empty, non-zero masks, and two touching runs never
/// have equal masks (they would be merged). Capacity `L`; a mark that does not fit is counted.
#[derive(Clone, Debug, Default)]
pub struct LitRuns<const L: usize> {
    runs: Vec<LitRun, L>,
    overflows: u32,
}

/// A run of lit voxels `lo ..= hi`, lit by the sources in `mask`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LitRun {
    /// First z.
    pub lo: Depth,
    /// Last z.
    pub hi: Depth,
    /// Sources that lit these voxels.
    pub mask: SourceMask,
}

impl<const L: usize> LitRuns<L> {
    /// No voxel lit.
    pub const fn new() -> Self {
        LitRuns { runs: Vec::new(), overflows: 0 }
    }

    /// The runs, sorted by depth.
    pub fn runs(&self) -> &[LitRun] {
        &self.runs
    }

    /// Marks that did not fit.
    pub fn overflows(&self) -> u32 {
        self.overflows
    }

    /// Sources that lit voxel `z` (0 if none).
    pub fn mask_at(&self, z: Depth) -> SourceMask {
        let i = self.runs.partition_point(|r| r.hi < z);
        match self.runs.get(i) {
            Some(r) if r.lo <= z => r.mask,
            _ => 0,
        }
    }

    /// Record that the sources in `bits` lit voxel `z`. Returns `false` (and counts an
    /// overflow) when the runs would exceed the capacity; the state is then unchanged.
    pub fn mark(&mut self, z: Depth, bits: SourceMask) -> bool {
        let i = self.runs.partition_point(|r| r.hi < z);
        let old = match self.runs.get(i) {
            Some(r) if r.lo <= z => Some(*r),
            _ => None,
        };
        let mask = old.map_or(0, |r| r.mask);
        if mask | bits == mask {
            return true;
        }
        // The pieces replacing `old` (or inserted at i): below z, z itself, above z.
        let mut pieces: Vec<LitRun, 3> = Vec::new();
        if let Some(r) = old {
            if r.lo < z {
                let _ = pieces.push(LitRun { lo: r.lo, hi: z - 1, mask });
            }
        }
        let _ = pieces.push(LitRun { lo: z, hi: z, mask: mask | bits });
        if let Some(r) = old {
            if r.hi > z {
                let _ = pieces.push(LitRun { lo: z + 1, hi: r.hi, mask });
            }
        }
        // Merge the new voxel run with touching neighbours of equal mask.
        let new_mask = mask | bits;
        let prev = if i > 0 { self.runs.get(i - 1).copied() } else { None };
        let next_idx = if old.is_some() { i + 1 } else { i };
        let next = self.runs.get(next_idx).copied();
        let merge_prev = pieces[0].lo == z && prev.is_some_and(|p| p.hi as u32 + 1 == z as u32 && p.mask == new_mask);
        let last = pieces.len() - 1;
        let merge_next =
            pieces[last].hi == z && next.is_some_and(|n| z as u32 + 1 == n.lo as u32 && n.mask == new_mask);
        let removed = old.is_some() as usize + merge_prev as usize + merge_next as usize;
        if self.runs.len() - removed + pieces.len() > L {
            self.overflows += 1;
            return false;
        }
        let mut lo_idx = i;
        if merge_prev {
            lo_idx -= 1;
            let p = prev.unwrap_or(pieces[0]);
            pieces[0].lo = p.lo;
        }
        if merge_next {
            let n = next.unwrap_or(pieces[last]);
            pieces[last].hi = n.hi;
        }
        for _ in 0..removed {
            self.runs.remove(lo_idx);
        }
        for (k, p) in pieces.iter().enumerate() {
            // Cannot fail: capacity checked above.
            let _ = self.runs.insert(lo_idx + k, *p);
        }
        true
    }
}
