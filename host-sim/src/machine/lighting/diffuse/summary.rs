//! What rc2's skips test beams against (docs/LIGHTING.md, the skips): the occupancy summaries
//! of the empty-frustum and hidden-voxel skips ([`cell_core::occupancy`]) and the occupied box
//! of the receding-beam skip — what the OR- (min/max-) reduction of every cell's own gives.

use cell_core::beam::FracBits;
use cell_core::light::{FrustumSummary, OccupiedBox};
use cell_core::lit::LitRule;
use cell_core::occupancy::{BlockRow, FrustumTest, Occupancy16, Occupancy32, Occupancy8, OccupancySummary};

use crate::machine::grid::Grid;

/// Blocks per axis of the summary the empty-frustum and hidden-voxel skips test beams against
/// ([`cell_core::occupancy`]): finer blocks drop more beams (the test is exact only with
/// one-voxel blocks) for more memory per cell. Same lit voxels and image whichever is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FrustumBlocks {
    /// 8 × 8 × 8 blocks, `u8` rows: 232 bytes per cell (what a cell trace carries).
    B8,
    /// 16 × 16 × 16 blocks, `u16` rows: 1 348 bytes per cell.
    B16,
    /// 32 × 32 × 32 blocks, `u32` rows: 9 384 bytes per cell.
    B32,
}

impl FrustumBlocks {
    /// Bytes each cell holds for the summary.
    pub const fn bytes(self) -> usize {
        match self {
            FrustumBlocks::B8 => Occupancy8::BYTES,
            FrustumBlocks::B16 => Occupancy16::BYTES,
            FrustumBlocks::B32 => Occupancy32::BYTES,
        }
    }
}

/// A summary of the chosen resolution ([`FrustumBlocks`]).
#[derive(Clone, Debug)]
pub enum Summary {
    /// 8 blocks per axis.
    B8(Box<Occupancy8>),
    /// 16 blocks per axis.
    B16(Box<Occupancy16>),
    /// 32 blocks per axis.
    B32(Box<Occupancy32>),
}

impl Summary {
    /// The summary of the voxels where a beam can do something (`active_span`: the occupied
    /// voxels, and under the plane rule the voxels bracketing each visible surface), or
    /// (`visible`) of the voxels the image reads only: each column's first occupied voxel under
    /// the thesis's rule, the two voxels bracketing its visible surface under the plane rule.
    /// What the OR-reduction of every cell's own summary gives.
    pub fn of<const D: usize>(grid: &Grid<D>, blocks: FrustumBlocks, visible: bool, rule: LitRule) -> Self {
        match blocks {
            FrustumBlocks::B8 => Summary::B8(Box::new(summarise(grid, visible, rule))),
            FrustumBlocks::B16 => Summary::B16(Box::new(summarise(grid, visible, rule))),
            FrustumBlocks::B32 => Summary::B32(Box::new(summarise(grid, visible, rule))),
        }
    }

    /// The test a cell runs.
    pub fn test<F: FracBits>(&self) -> &dyn FrustumTest<F> {
        match self {
            Summary::B8(o) => &**o,
            Summary::B16(o) => &**o,
            Summary::B32(o) => &**o,
        }
    }

    /// Its occupied blocks.
    pub fn occupied_blocks(&self) -> OccupiedBlocks {
        match self {
            Summary::B8(o) => OccupiedBlocks::of(&**o),
            Summary::B16(o) => OccupiedBlocks::of(&**o),
            Summary::B32(o) => OccupiedBlocks::of(&**o),
        }
    }

    /// The 8-block summary a cell trace carries (`None` for finer ones).
    pub fn traceable(&self) -> Option<&FrustumSummary> {
        match self {
            Summary::B8(o) => Some(&**o),
            _ => None,
        }
    }
}

/// A summary's occupied blocks: block `[bx, by, bz]` holds the voxels `b·side ..
/// min((b + 1)·side, extent)` on each axis.
#[derive(Clone, Debug)]
pub struct OccupiedBlocks {
    /// Voxels per block side, per axis ([`OccupancySummary::side`]).
    pub side: [u32; 3],
    /// The grid's extent (n, n, depth).
    pub extent: [u32; 3],
    /// The occupied blocks.
    pub list: Vec<[usize; 3]>,
}

impl OccupiedBlocks {
    /// The occupied blocks of `s`.
    pub fn of<const B: usize, R: BlockRow>(s: &OccupancySummary<B, R>) -> Self {
        let [bx, by, bz] = s.blocks();
        let list = (0..bx)
            .flat_map(|x| (0..by).flat_map(move |y| (0..bz).map(move |z| [x, y, z])))
            .filter(|&b| s.occupied_block(b))
            .collect();
        OccupiedBlocks { side: s.side(), extent: s.extent(), list }
    }
}

/// The grid's 8-block occupancy summary for the empty-frustum skip (what the OR-reduction of
/// every cell's own summary gives; what a cell trace carries).
pub fn occupancy_summary<const D: usize>(grid: &Grid<D>, rule: LitRule) -> FrustumSummary {
    summarise(grid, false, rule)
}

/// The summary of the grid's occupied voxels, or (`visible_only`) of each column's first
/// occupied voxel (the one its cell shades) for the hidden-voxel skip.
fn summarise<const B: usize, R: BlockRow, const D: usize>(
    grid: &Grid<D>,
    visible_only: bool,
    rule: LitRule,
) -> OccupancySummary<B, R> {
    let mut s = OccupancySummary::new(grid.n, grid.depth);
    for c in &grid.cells {
        let (x, y) = (c.x as u32, c.y as u32);
        if visible_only {
            if let Some((lo, hi)) = pixel_span(c, grid.depth, rule) {
                s.mark_span(x, y, lo as u32, hi as u32);
            }
        } else if rule.occluder_reach() > 0 {
            // A ray meets a triangle within one voxel of its voxels at the segment's ends,
            // and every point of a triangle lies in an occupied voxel: a beam can do
            // something only near an occupied voxel, or at its target.
            if let Some((lo, hi)) = active_span(c, grid.depth, rule) {
                for (nx, ny) in neighbourhood(x, y, grid.n) {
                    s.mark_span(nx, ny, lo as u32, hi as u32);
                }
            }
        } else {
            s.mark_column(x, y, c.store.dexels());
            // Under the plane rule a ray may light the pixel in an empty voxel bracketing
            // the visible surface: a beam that can reach one is not empty.
            if let Some((lo, hi)) = active_span(c, grid.depth, rule).filter(|_| rule.shades_visible_surface()) {
                s.mark_span(x, y, lo as u32, hi as u32);
            }
        }
    }
    s
}

/// The voxels of column `c` that receive its pixel's light ([`LitRule::receives`]), clipped
/// to the grid: its first voxel under the thesis's rule, the receiver window around its
/// visible surface under the others.
fn pixel_span<const D: usize>(c: &cell_core::cell::Cell<D>, depth: u32, rule: LitRule) -> Option<(u16, u16)> {
    match rule.receiver_window() {
        None => c.store.dexels().first().map(|d| (d.span.lo, d.span.lo)),
        Some(_) => c.visible.map(|v| receiver_span(&v, depth, rule)),
    }
}

/// The voxels of a column where a ray may light its visible surface ([`LitRule::receiver_window`]),
/// clipped to the grid.
fn receiver_span(v: &cell_core::visible::VisibleSurface, depth: u32, rule: LitRule) -> (u16, u16) {
    let top = depth as i64 - 1;
    let (front, back) = rule.receiver_window().unwrap_or((0, 0));
    let (lo, hi) = ((v.z_v as i64 + front).clamp(0, top), (v.z_v as i64 + back).clamp(0, top));
    (lo as u16, hi as u16)
}

/// The depths of column `c` where a beam can do something besides passing: its occupied
/// voxels (grown by the rule's [`LitRule::occluder_reach`]), and where the pixel is the visible
/// surface the voxels that receive its light (a ray may light the pixel in an empty voxel),
/// clipped to the grid. The skips keep every beam that can reach one.
fn active_span<const D: usize>(c: &cell_core::cell::Cell<D>, depth: u32, rule: LitRule) -> Option<(u16, u16)> {
    let ds = c.store.dexels();
    let occupied = ds.first().zip(ds.last()).map(|(f, l)| (f.span.lo, l.span.hi));
    let top = depth as i64 - 1;
    let reach = rule.occluder_reach();
    let occupied = occupied.map(|(lo, hi)| (lo.saturating_sub(reach), (hi as i64 + reach as i64).min(top) as u16));
    let bracket = c.visible.filter(|_| rule.shades_visible_surface()).map(|v| receiver_span(&v, depth, rule));
    match (occupied, bracket) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, b) => a.or(b),
    }
}

/// The bounding box of the grid's occupied voxels, and under the plane rule of the voxels that
/// bracket its visible surfaces (`active_span`); `lo > hi` when there are none.
pub fn occupied_box<const D: usize>(grid: &Grid<D>, rule: LitRule) -> OccupiedBox {
    let mut b = OccupiedBox { lo: [u16::MAX; 3], hi: [0; 3] };
    for c in &grid.cells {
        if let Some((lo, hi)) = active_span(c, grid.depth, rule) {
            // Exact occluders: one column more each way ([`active_span`]).
            let g = rule.occluder_reach();
            let last = grid.n.saturating_sub(1) as u16;
            b.lo = [b.lo[0].min(c.x.saturating_sub(g)), b.lo[1].min(c.y.saturating_sub(g)), b.lo[2].min(lo)];
            b.hi = [b.hi[0].max((c.x + g).min(last)), b.hi[1].max((c.y + g).min(last)), b.hi[2].max(hi)];
        }
    }
    b
}

/// Column (x, y) and its (up to) eight neighbours inside an n × n grid.
fn neighbourhood(x: u32, y: u32, n: u32) -> impl Iterator<Item = (u32, u32)> {
    let (x0, x1, y0, y1) = (x.saturating_sub(1), (x + 1).min(n - 1), y.saturating_sub(1), (y + 1).min(n - 1));
    (y0..=y1).flat_map(move |ny| (x0..=x1).map(move |nx| (nx, ny)))
}
