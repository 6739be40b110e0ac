//! The cell capacities host-sim compiles, and the lighting and shadow-ray cell types built from
//! them; the grid type is [`super::LightGrid`], the reflection cells' types `machine::rays::mirror`'s.
//!
//! The numbers themselves live in one place, [`cell_core::cell`], shared with the firmware: a
//! trace recorded here is replayed there by a cell of exactly the same capacities.

use cell_core::light::LightCell;
use cell_core::radiosity::{IndirectPixel, PatchRuns, Received};
use cell_core::shadow::ShadowCell;

pub use cell_core::cell::{
    DEFAULT_DEXELS, FA_CAP, GLASS_WAIT_CAP, LIT_CAP, OB_CAP, REFLECT_FA_CAP, SEND_CAP, SHADOW_FA_CAP, TRIANGLE_CAP,
    WAIT_CAP,
};

/// The host's lighting cell type.
pub type HostLightCell<F> = LightCell<F, FA_CAP, OB_CAP, LIT_CAP>;

/// The host's classic shadow-ray cell type.
pub type HostShadowCell = ShadowCell<SHADOW_FA_CAP>;

/// Patch runs a cell's voxel → patch map holds (radiosity: the patches its column crosses).
pub const PATCH_RUNS_CAP: usize = 32;

/// Patches a cell accumulates quanta for in one shot: as many as its map can name, so a cell
/// whose map fits never overflows its accumulator.
pub const RECEIVED_CAP: usize = PATCH_RUNS_CAP;

/// The host's voxel → patch map of one cell.
pub type CellPatchRuns = PatchRuns<PATCH_RUNS_CAP>;

/// The host's per-shot patch accumulator of one cell.
pub type CellReceived = Received<RECEIVED_CAP>;

/// A cell's indirect light under the flat display: the record of its visible patch.
pub type CellIndirectFlat = IndirectPixel<1>;

/// A cell's indirect light under the smooth display: the records of its patch's corners (a
/// patch has 3 or 4).
pub type CellIndirectSmooth = IndirectPixel<4>;

/// Proxels one cell holds for proxel-parallel shots (radiosity thesis §6.2): 256 × 40 bytes,
/// 10 KiB, within a MasPar PE's 16 KB; enough for a hemicube of R = 2n (12 per cell) and a disk
/// of R = 1024 on 128 × 128 cells (64 per cell).
pub const PROXEL_CAP: usize = 256;

/// Patches one cell owns for proxel-parallel shots (the modulo distribution: ⌈P/n²⌉).
pub const FACET_SHARE_CAP: usize = 64;
