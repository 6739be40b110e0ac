//! The loading phase (thesis §3.5–3.9): the host injects the scene's facet packets into the
//! vertical pipeline, each cell computes its own dexels from the packets that cross it, and the
//! loaded grid is mapped back to the world.
//!
//! * [`wave`] — the loading wave, cycle by cycle ([`crate::machine::grid::Grid::load_wave`]),
//!   and the direct host path that evaluates the same integer formulas; [`wave_ref`] the wave
//!   stepped over every cell, its check.
//! * [`engines`] — a whole voxelization with either engine (the `voxelize` job's machine): the
//!   precompute, the load, each column's triangles, the occupancy summary.
//! * [`loaded_scene`] — a scene loaded into the grid, the world ↔ grid mapping, where its
//!   lights are.
//!
//! Invariant: the wave is systolic — every cell has one upstream neighbour, a packet makes one
//! hop per cycle, nothing contends — and every engine leaves the same dexels in every cell
//! (`tests/tests/integration/wave_vs_direct.rs`, and [`wave_ref`] for the wave's counts).
//! Loading stands on the grid and the links' trace tap only; it knows nothing of light.

pub mod engines;
pub mod loaded_scene;
pub mod wave;
pub mod wave_ref;
