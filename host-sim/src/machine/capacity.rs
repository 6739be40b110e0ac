//! The cell capacities host-sim compiles, and the lighting cell type built from them (the grid
//! type is [`super::grid::LightGrid`]).
//!
//! The numbers themselves live in one place, [`cell_core::cell`], shared with the firmware: a
//! trace recorded here is replayed there by a cell of exactly the same capacities.

use cell_core::light::LightCell;
use cell_core::radiosity::{PatchRuns, Received};

pub use cell_core::cell::{DEFAULT_DEXELS, FA_CAP, LIT_CAP, OB_CAP};

/// The host's lighting cell type.
pub type HostLightCell<F> = LightCell<F, FA_CAP, OB_CAP, LIT_CAP>;

/// Patch runs a cell's voxel → patch map holds (radiosity: the patches its column crosses).
pub const PATCH_RUNS_CAP: usize = 32;

/// Patches a cell accumulates quanta for in one shot: as many as its map can name, so a cell
/// whose map fits never overflows its accumulator.
pub const RECEIVED_CAP: usize = PATCH_RUNS_CAP;

/// The host's voxel → patch map of one cell.
pub type CellPatchRuns = PatchRuns<PATCH_RUNS_CAP>;

/// The host's per-shot patch accumulator of one cell.
pub type CellReceived = Received<RECEIVED_CAP>;
