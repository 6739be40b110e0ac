//! The cell capacities host-sim compiles, and the lighting cell type built from them (the grid
//! type is [`super::grid::LightGrid`]).
//!
//! The numbers themselves live in one place, [`cell_core::cell`], shared with the firmware: a
//! trace recorded here is replayed there by a cell of exactly the same capacities.

use cell_core::light::LightCell;

pub use cell_core::cell::{DEFAULT_DEXELS, FA_CAP, LIT_CAP, OB_CAP};

/// The host's lighting cell type.
pub type HostLightCell<F> = LightCell<F, FA_CAP, OB_CAP, LIT_CAP>;
