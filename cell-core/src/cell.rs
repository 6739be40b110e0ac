//! One cell of the grid: its position, its dexel store and its counters.
//!
//! The cell is a deterministic state machine driven by explicit calls (sans-IO): the host
//! simulator and a firmware main loop call the same step functions.

use crate::dexel::DexelStore;
use crate::units::Coord;

/// Dexel capacity a host build uses unless told otherwise.
///
/// This constant and the eight below are the capacities of the cell that host-sim simulates and
/// the firmware runs: they are set here and only here.
pub const DEFAULT_DEXELS: usize = 64;

/// FIFO capacity compiled into a cell (the run-time FIFO limit FA may be smaller).
pub const FA_CAP: usize = 64;

/// Messages an output buffer holds: a ±x/±y beam sends up to 3 sub-beams through one link.
pub const OB_CAP: usize = 3;

/// Lit runs per column: 64 since the office scene `bureau2` at n = 128 needed more than 32 in
/// two columns running along a wall (a lit-store overflow there is an error, never a loss).
pub const LIT_CAP: usize = 64;

/// Ray FIFO capacity of the classic shadow-ray cell ([`crate::shadow::ShadowCell`]): the
/// run-time limit FA of the classic phase may be at most this.
pub const SHADOW_FA_CAP: usize = FA_CAP;

/// Ray FIFO capacity of each of the reflection cell's 4 classes
/// ([`crate::reflect_cell::ReflectCell`]): 16, the default FA, not [`FA_CAP`]. Four classes of
/// 64 rays made a 30 KB cell, and building n² of them cost the host more than the reflection
/// phase itself (+22 % instructions on a whole render at n = 64); at 16 a cell is 11.5 KB.
pub const REFLECT_FA_CAP: usize = 16;

/// Wait-table entries of the reflection cell: trees waiting at one cell at once (the root's
/// included), and slots of the launch queue of child rays waiting for FIFO room.
pub const WAIT_CAP: usize = 16;

/// Wait-table entries of the reflection cells of a scene with transparent materials: there every
/// glass voxel a ray meets has two children, and a glass solid focuses many trees into a few
/// columns (peaks of 20–45 entries measured on `cornell-glass` at n = 64–128, depths 4–8;
/// BENCHMARKS "Refraction"). Scenes without glass keep [`WAIT_CAP`], the firmware's
/// (host-sim's `machine::rays::mirror` picks the cell type).
pub const GLASS_WAIT_CAP: usize = 64;

/// Triangles a column keeps for exact occluders ([`crate::occluder::TriangleStore`]): 64 loses
/// at most 0.32 dB on the meshes measured (BENCHMARKS); a column that needs more counts the
/// triangles it leaves out.
pub const TRIANGLE_CAP: usize = 64;

/// Answers the reflection cell holds for its router.
pub const SEND_CAP: usize = 16;

/// Per-cell counters of the loading phase.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoadCounters {
    /// Facet packets received from the west (or from the pipeline).
    pub packets: u32,
    /// Packets for which the cell computed a span (inside the facet's box).
    pub spans_computed: u32,
    /// Voxels a facet wanted that an earlier facet already held.
    pub voxels_shared: u32,
}

/// One RC² cell with room for `D` dexels.
#[derive(Clone, Debug, Default)]
pub struct Cell<const D: usize> {
    /// Column index.
    pub x: Coord,
    /// Row index.
    pub y: Coord,
    /// The column's voxels.
    pub store: DexelStore<D>,
    /// Loading counters.
    pub counters: LoadCounters,
    /// The facet the column's centre line meets first ([`crate::visible`]): what the pixel shows.
    pub visible: Option<crate::visible::VisibleSurface>,
}

impl<const D: usize> Cell<D> {
    /// An empty cell at (x, y).
    pub const fn new(x: Coord, y: Coord) -> Self {
        Cell {
            x,
            y,
            store: DexelStore::new(),
            counters: LoadCounters { packets: 0, spans_computed: 0, voxels_shared: 0 },
            visible: None,
        }
    }
}
