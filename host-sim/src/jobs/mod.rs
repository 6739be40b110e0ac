//! The jobs a user runs, one module each, built on [`crate::machine`] and measured against
//! [`crate::truth`]. Each job takes a plain options struct (no clap) and has a `run`; the command
//! line ([`crate::cli`]) only parses arguments, converts them into those options and calls it.
//!
//! * [`render`] — the main job: load, light (diffusion or classic), shade, reflect, compare; its
//!   [`render::render`] is the one entry point of a render on a loaded scene;
//!   [`render_radiosity`] its radiosity phase (`render --radiosity`).
//! * [`light`] — the `light` job and the lighting options `render` and `trace` share;
//!   [`accuracy`] — `light-accuracy`; [`table`] — `diffusion-table`.
//! * [`voxelize`] — load a scene and write a .binvox; [`scenes`] — list, subdivide.
//! * [`trace`] — record cell traces for the firmware; [`audit`] — a cell's RAM and flash.
//! * [`radiosity`] — progressive radiosity on the grid, per-patch and per-shot CSV, the f64
//!   reference's comparison.
//! * [`mod@bench`] — the speed/accuracy sweep and its Pareto front; [`dump`] — lit-voxel dumps.
//! * [`form_factors`] — the radiosity thesis's projective form factors and its Tables 2.1–2.3;
//!   [`ray_traced`] — its ray-traced form factors toward a source, Tables 3.2–3.3.

pub mod accuracy;
pub mod audit;
pub mod bench;
pub mod dump;
pub mod form_factors;
pub mod light;
pub mod radiosity;
pub mod ray_traced;
pub mod render;
pub mod render_radiosity;
pub mod scenes;
pub mod table;
pub mod trace;
pub mod virtual_images;
pub mod voxelize;
