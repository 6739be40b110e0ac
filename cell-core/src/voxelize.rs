//! §3.5–3.9 — the loading wave: the pipeline cell and the row cell.
//!
//! A voxel (x, y, z) is kept for a facet iff its centre satisfies the plane band and every
//! contour inequality (§3.6):
//!
//! ```text
//!   −Kσ ≤ a·x + b·y + c·z + d ≤ Kσ          (plane, "collé" theorem §3.5)
//!   a_i·x + b_i·y + c_i·z + d_i ≥ 0           (contour edge i, projected on the base plane
//!                                              most orthogonal to the normal, §3.6)
//! ```
//!
//! With `t = Kσ − (a·x + b·y + d)` and `u = −Kσ − (a·x + b·y + d)` the band reads `u ≤ c·z ≤ t`,
//! so for `c > 0` the dexel is `z_ar = ⌈u/c⌉ ..= z_av = ⌊t/c⌋` (bounds swapped when `c < 0`,
//! an in/out test when `c = 0`). Edges whose `c_i ≠ 0` (facets projected on XOZ or YOZ) bound z
//! further, `c_i = 0` edges are in/out tests (§3.7). Division is exact floor/ceil on integers.
//!
//! # Bit budget (all cell arithmetic is `i64`, exact, overflow-free up to [`MAX_N`])
//!
//! The host quantises vertices to a lattice of `q` steps per voxel (`q ≤ 16`, even), so every
//! vertex coordinate lies in `0 ..= M` with `M = q·n`. The host computes, exactly:
//! plane normal `(A, B, C) = (P1 − P0) × (P2 − P0)`, each `|·| ≤ 2M²`; cell coefficients
//! `a = q·A` … so `|a|, |b|, |c| ≤ 2qM²`; the band half-width `Kσ ≤ 3qM²` for every thickness
//! mode (standard: `(|a|+|b|+|c|)/2`); and at any column whose centre is within one step of the
//! grid, `|a·x + b·y + d| = |A·ΔX + B·ΔY + C·ΔZ| ≤ 6M²(M + q)`. Hence
//!
//! ```text
//!   |t|, |u| ≤ 6M²(M + q) + 3qM²        |g_i| ≤ 2M(M + q) + qM        |a_i|, |c_i| ≤ qM
//! ```
//!
//! For `n = MAX_N = 65 536` and `q = 16`, `M = 2²⁰`: `|t| ≤ 6.92·10¹⁸ < 2⁶³ ≈ 9.22·10¹⁸`
//! (checked at compile time below), and `|a_i| ≤ 2²⁴` fits `i32`. With `i32` instead, the same
//! bound allows `M ≤ 598`, i.e. `n ≤ 37`: too small, hence `i64`. The tests run the wave at
//! `n = MAX_N` on extreme facets with overflow checks on and compare with `i128`.

use crate::cell::Cell;
use crate::facet::{PipelinePacket, RowPacket};
use crate::units::{Coord, Span};

pub use crate::units::MAX_N;

/// Largest lattice resolution (steps per voxel) the bit budget allows.
pub const MAX_LATTICE_Q: i128 = 16;

/// Largest lattice coordinate `M = q·n` the bit budget allows.
pub const MAX_LATTICE_SPAN: i128 = MAX_LATTICE_Q * MAX_N as i128;

/// Worst-case magnitude of `t`/`u` in a cell for lattice span `m` and resolution `q` (see the
/// module doc for the derivation).
pub const fn worst_case_t(m: i128, q: i128) -> i128 {
    6 * m * m * (m + q) + 3 * q * m * m
}

/// Worst-case magnitude of an edge value `g_i`.
pub const fn worst_case_g(m: i128, q: i128) -> i128 {
    2 * m * (m + q) + q * m
}

const _: () = assert!(worst_case_t(MAX_LATTICE_SPAN, MAX_LATTICE_Q) < i64::MAX as i128);
const _: () = assert!(worst_case_g(MAX_LATTICE_SPAN, MAX_LATTICE_Q) < i64::MAX as i128);
const _: () = assert!(MAX_LATTICE_SPAN * MAX_LATTICE_Q <= i32::MAX as i128);

/// ⌊n / d⌋ for any signs (`d ≠ 0`). Wrapping division: `i64::MIN / −1` (outside every bit
/// budget, so only reachable from a forged packet) wraps instead of panicking.
pub const fn floor_div(n: i64, d: i64) -> i64 {
    let q = n.wrapping_div(d);
    if n.wrapping_rem(d) != 0 && ((n < 0) != (d < 0)) {
        q - 1
    } else {
        q
    }
}

/// ⌈n / d⌉ for any signs (`d ≠ 0`).
pub const fn ceil_div(n: i64, d: i64) -> i64 {
    let q = n.wrapping_div(d);
    if n.wrapping_rem(d) != 0 && ((n < 0) == (d < 0)) {
        q + 1
    } else {
        q
    }
}

/// The dexel `[z_ar, z_av]` of the facet in the current column, clipped to the facet's box and
/// to `0 ..= depth − 1`;
/// `None` when the column holds no voxel of the facet (§3.7 with exact integer division).
pub fn row_span(p: &RowPacket, depth: u32) -> Option<Span> {
    let mut lo: i64 = p.bbox.z_min as i64;
    let mut hi: i64 = (depth as i64 - 1).min(p.bbox.z_max as i64);
    if p.c == 0 {
        // The plane contains the z direction: the whole column or nothing.
        if p.t < 0 || p.u > 0 {
            return None;
        }
    } else if p.c > 0 {
        hi = hi.min(floor_div(p.t, p.c));
        lo = lo.max(ceil_div(p.u, p.c));
    } else {
        lo = lo.max(ceil_div(p.t, p.c));
        hi = hi.min(floor_div(p.u, p.c));
    }
    for e in &p.edges {
        if lo > hi {
            return None;
        }
        let c = e.c as i64;
        if c == 0 {
            if e.g < 0 {
                return None;
            }
        } else if c > 0 {
            lo = lo.max(ceil_div(-e.g, c));
        } else {
            hi = hi.min(floor_div(-e.g, c));
        }
    }
    Span::clipped(lo, hi, depth)
}

/// A cell of the vertical pipeline along the left edge of the grid (§1.3.2, §3.9).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PipelineCell {
    /// The row this pipeline cell feeds.
    pub y: Coord,
}

/// What a pipeline cell does with one packet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PipelineStep {
    /// Packet for the first cell of the row, when the row is inside the facet's box.
    pub east: Option<RowPacket>,
    /// Whether the (already stepped) packet goes on down the pipeline.
    pub down: bool,
}

impl PipelineCell {
    /// Process one packet: feed the row if it is in the box, step the packet down
    /// (`T − B`, `U − B`, `G_i + B_i`) if rows below still need it. The caller sends
    /// `pkt` down when `down` is true.
    pub fn step(&self, pkt: &mut PipelinePacket) -> PipelineStep {
        let b = pkt.bbox;
        let east = (b.y_min <= self.y && self.y <= b.y_max).then(|| pkt.to_row());
        let down = self.y < b.y_max;
        if down {
            pkt.step_down();
        }
        PipelineStep { east, down }
    }
}

impl<const D: usize> Cell<D> {
    /// Row-cell loading step (§3.9): compute this column's dexel when the column is inside the
    /// facet's box, store it, and step the packet east (`T − A`, `U − A`, `G_i + A_i`) when
    /// cells further east still need it. Returns whether the caller must send `pkt` east.
    pub fn load_step(&mut self, pkt: &mut RowPacket, depth: u32) -> bool {
        self.load_step_planes::<true>(pkt, depth)
    }

    /// [`Cell::load_step`] for a cell that runs only the thesis's lit rule (§5.5.5): its
    /// dexels get no plane ([`DexelStore::insert_without_planes`]) and it keeps no visible
    /// surface (the plane rule's pixel); the occupied voxels are the same. A firmware image
    /// with a small flash budget leaves the plane arithmetic out this way.
    ///
    /// [`DexelStore::insert_without_planes`]: crate::dexel::DexelStore::insert_without_planes
    pub fn load_step_without_planes(&mut self, pkt: &mut RowPacket, depth: u32) -> bool {
        self.load_step_planes::<false>(pkt, depth)
    }

    #[inline(always)]
    fn load_step_planes<const PLANES: bool>(&mut self, pkt: &mut RowPacket, depth: u32) -> bool {
        self.counters.packets += 1;
        if self.x >= pkt.bbox.x_min {
            self.counters.spans_computed += 1;
            if let Some(span) = row_span(pkt, depth) {
                let ins = if PLANES {
                    self.store.insert_on(span, pkt.tag, &pkt.column_plane())
                } else {
                    self.store.insert_without_planes(span, pkt.tag)
                };
                self.counters.voxels_shared += ins.shared;
            }
            if PLANES {
                crate::visible::depth_test(&mut self.visible, crate::visible::surface_of(pkt, depth));
            }
        }
        let forward = self.x < pkt.bbox.x_max;
        if forward {
            pkt.step_east();
        }
        forward
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_and_ceil_division_all_signs() {
        for n in -20i64..=20 {
            for d in [-7i64, -3, -2, -1, 1, 2, 3, 7] {
                let exact = n as f64 / d as f64;
                assert_eq!(floor_div(n, d), exact.floor() as i64, "{n}/{d}");
                assert_eq!(ceil_div(n, d), exact.ceil() as i64, "{n}/{d}");
            }
        }
    }
}
