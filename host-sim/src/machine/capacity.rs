//! The cell capacities host-sim compiles, and the lighting, shadow-ray and reflection cell types
//! built from them (the grid type is [`super::grid::LightGrid`]).
//!
//! The numbers themselves live in one place, [`cell_core::cell`], shared with the firmware: a
//! trace recorded here is replayed there by a cell of exactly the same capacities.

use cell_core::light::LightCell;
use cell_core::reflect_cell::ReflectCell;
use cell_core::shadow::ShadowCell;

pub use cell_core::cell::{DEFAULT_DEXELS, FA_CAP, LIT_CAP, OB_CAP, REFLECT_FA_CAP, SEND_CAP, SHADOW_FA_CAP, WAIT_CAP};

/// The host's lighting cell type.
pub type HostLightCell<F> = LightCell<F, FA_CAP, OB_CAP, LIT_CAP>;

/// The host's classic shadow-ray cell type.
pub type HostShadowCell = ShadowCell<SHADOW_FA_CAP>;

/// The host's reflection cell type.
pub type HostReflectCell = ReflectCell<REFLECT_FA_CAP, WAIT_CAP, SEND_CAP>;
