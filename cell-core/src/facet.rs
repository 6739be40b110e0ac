//! §3.9 — the facet packets of the loading wave.
//!
//! The host computes, once per facet, exact integer coefficients (see [`crate::voxelize`]) and
//! injects a [`PipelinePacket`] at the top of the vertical pipeline. Pipeline cell y passes
//! `T − B`, `U − B` and `G_i + B_i` down and hands a [`RowPacket`] (without the `B` terms, which
//! a row never needs) to the first cell of row y; each row cell passes `T − A`, `U − A`,
//! `G_i + A_i` east. At column (x, y) the packet therefore holds
//!
//! * `t = Kσ − (a·x + b·y + d)` and `u = −Kσ − (a·x + b·y + d)`: the plane band
//!   `−Kσ ≤ a·x + b·y + c·z + d ≤ Kσ` becomes `u ≤ c·z ≤ t`;
//! * for each contour edge, `g_i = a_i·x + b_i·y + d_i`: the edge inequality
//!   `a_i·x + b_i·y + c_i·z + d_i ≥ 0` becomes `g_i + c_i·z ≥ 0`.
//!
//! Each packet also carries the facet's bounding box: rows outside it are not fed, a row stops
//! forwarding past `x_max` (skip what a facet does not need), and the cell clips its
//! span to `z_min ..= z_max` (which also trims the spikes that pushed-out edges grow at acute
//! corners in conservative mode).

use crate::dexel::FacetTag;
use crate::units::{Coord, Depth};
use heapless::Vec;

/// Most contour edges a facet may have (convex polygons with more vertices are split by the
/// host).
pub const MAX_EDGES: usize = 8;

/// The voxels a facet can touch: `x_min ..= x_max`, `y_min ..= y_max`, `z_min ..= z_max`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FacetBox {
    /// First column.
    pub x_min: Coord,
    /// Last column.
    pub x_max: Coord,
    /// First row.
    pub y_min: Coord,
    /// Last row.
    pub y_max: Coord,
    /// Lowest depth.
    pub z_min: Depth,
    /// Highest depth.
    pub z_max: Depth,
}

/// One contour edge as a row cell sees it: `g + c·z ≥ 0` at the current column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RowEdge {
    /// x coefficient `a_i`: added to `g` at each step east.
    pub a: i32,
    /// z coefficient `c_i` (0 when the facet projects on XOY: a pure in/out test).
    pub c: i32,
    /// `g_i = a_i·x + b_i·y + d_i` at the current column.
    pub g: i64,
    /// How far the conservative contour pushed the edge out, and whether the facet's own edge
    /// holds its points ([`EdgeOff`]): the exact hit test of [`crate::visible`] uses it.
    pub off: i32,
}

impl RowEdge {
    /// The edge's `off` field read ([`EdgeOff`]).
    pub const fn off(&self) -> EdgeOff {
        EdgeOff(self.off)
    }
}

/// A contour edge's `off` field: the conservative push (`g_i − push` is the facet's own edge; 0
/// for the projected contour), a multiple of 8 (½ voxel times the edge's lattice extent), and in
/// bit 0 whether the facet's own edge **excludes** the points on it.
///
/// Vertices on the 1/16-voxel lattice move by up to 1/32 voxel, so an edge lying a fiftieth of
/// a voxel beside a row of pixel centres in the world can land exactly on it; whether those
/// centres meet the facet is then decided by the unrounded geometry, which only the host
/// knows: it sets the bit where the world's edge lies inside the lattice edge (the centres on
/// it are outside the world's facet). Two facets sharing an edge get opposite answers, so a
/// point on their edge meets exactly one of them (or both, where the world's edge is the
/// lattice's). Voxelization ignores the bit (`g_i` holds the push only).
///
/// ```
/// use cell_core::facet::EdgeOff;
///
/// // A conservative edge pushed out by 24 units whose own points are outside the facet.
/// let off = EdgeOff(24 | EdgeOff::STRICT);
/// assert_eq!((off.push(), off.strict()), (24, true));
/// assert_eq!((EdgeOff(24).push(), EdgeOff(24).strict()), (24, false));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EdgeOff(pub i32);

impl EdgeOff {
    /// Bit 0 of `off`: the facet's own edge excludes its points.
    pub const STRICT: i32 = 1;

    /// The conservative push.
    pub const fn push(self) -> i32 {
        self.0 & !Self::STRICT
    }

    /// Whether the points on the facet's own edge are outside the facet.
    pub const fn strict(self) -> bool {
        self.0 & Self::STRICT != 0
    }
}

/// One contour edge as a pipeline cell sees it (it also needs `b_i` to step down).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PipeEdge {
    /// x coefficient `a_i`.
    pub a: i32,
    /// y coefficient `b_i`: added to `g` at each step down the pipeline.
    pub b: i32,
    /// z coefficient `c_i`.
    pub c: i32,
    /// `g_i` at column (0, y).
    pub g: i64,
    /// The conservative push and the edge's own-point rule ([`EdgeOff`]).
    pub off: i32,
}

/// What travels along a row: the thesis's `A, C, T, U, A_i, C_i, T_i` plus the tag and box.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct RowPacket {
    /// Facet id, material and normal, stored with every dexel.
    pub tag: FacetTag,
    /// Voxels the facet can touch.
    pub bbox: FacetBox,
    /// Plane x coefficient `a`.
    pub a: i64,
    /// Plane z coefficient `c`.
    pub c: i64,
    /// `Kσ − P(x, y)` at the current column.
    pub t: i64,
    /// `−Kσ − P(x, y)` at the current column.
    pub u: i64,
    /// Contour edges.
    pub edges: Vec<RowEdge, MAX_EDGES>,
}

/// What travels down the vertical pipeline: a row packet plus the `B` terms.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct PipelinePacket {
    /// Facet id, material and normal.
    pub tag: FacetTag,
    /// Voxels the facet can touch.
    pub bbox: FacetBox,
    /// Plane x coefficient `a`.
    pub a: i64,
    /// Plane y coefficient `b`.
    pub b: i64,
    /// Plane z coefficient `c`.
    pub c: i64,
    /// `Kσ − P(0, y)` at the current pipeline cell.
    pub t: i64,
    /// `−Kσ − P(0, y)` at the current pipeline cell.
    pub u: i64,
    /// Contour edges.
    pub edges: Vec<PipeEdge, MAX_EDGES>,
}

impl PipelinePacket {
    /// The packet pipeline cell y hands to the first cell of its row (column 0).
    pub fn to_row(&self) -> RowPacket {
        RowPacket {
            tag: self.tag,
            bbox: self.bbox,
            a: self.a,
            c: self.c,
            t: self.t,
            u: self.u,
            edges: self.edges.iter().map(|e| RowEdge { a: e.a, c: e.c, g: e.g, off: e.off }).collect(),
        }
    }

    /// Advance from row y to row y + 1: `T − B`, `U − B`, `G_i + B_i` (§3.9).
    pub fn step_down(&mut self) {
        self.t -= self.b;
        self.u -= self.b;
        for e in self.edges.iter_mut() {
            e.g += e.b as i64;
        }
    }
}

impl RowPacket {
    /// The facet's exact plane value along the current column, `E(z) = P(x, y) + c·z`, from
    /// `t = Kσ − P` and `u = −Kσ − P`: `P = −u − (t − u)/2` (t − u = 2Kσ, so no sum of two large
    /// terms is formed). Wrapping: exact within the bit budget, no panic on a forged packet.
    pub fn column_plane(&self) -> crate::plane::ColumnPlane {
        let half_band = self.t.wrapping_sub(self.u) / 2;
        crate::plane::ColumnPlane { p: self.u.wrapping_add(half_band).wrapping_neg(), c: self.c }
    }

    /// Advance from column x to column x + 1: `T − A`, `U − A`, `G_i + A_i` (§3.9).
    pub fn step_east(&mut self) {
        self.t -= self.a;
        self.u -= self.a;
        for e in self.edges.iter_mut() {
            e.g += e.a as i64;
        }
    }
}
