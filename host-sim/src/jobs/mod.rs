//! The jobs a user runs, one module each, built on [`crate::machine`] and measured against
//! [`crate::truth`]. The command line ([`crate::cli`]) only parses options and calls these.
//!
//! * [`render`] — the main job: load, light (diffusion or classic), shade, reflect, compare.
//! * [`light`] — the `light` job's defaults and outputs; [`accuracy`] — `light-accuracy`.
//! * [`trace`] — record cell traces for the firmware; [`audit`] — a cell's RAM and flash.
//! * [`bench`] — the speed/accuracy sweep and its Pareto front; [`dump`] — lit-voxel dumps.

pub mod accuracy;
pub mod audit;
pub mod bench;
pub mod dump;
pub mod light;
pub mod render;
pub mod trace;
