//! The machine: an n × n grid of `cell_core` cells and the host code that steps them, cycle by
//! cycle, through every phase. Nothing here knows about jobs, reports or the command line.
//!
//! * [`capacity`] — the cell capacities (from `cell_core::cell`, shared with the firmware) and
//!   the cell and grid types built from them.
//! * [`grid`], [`load`], [`wave_ref`] — the loading wave (§3.9), its engines and its check.
//! * [`loaded`] — a scene loaded into the grid, the world ↔ grid mapping, light placement.
//! * [`diffuse`] — the beam-diffusion scheduler (§4.3–4.4), [`tiles`] its memory layout,
//!   [`timing`] the timing rules the thesis leaves open, [`sequential`] the ray-by-ray
//!   emission mode it weighs against beams (§4.2.4).
//! * [`lighting`] — a whole lighting run and its statistics.
//! * [`classic`] — classic shadow rays (§4.1.2) on the same cycle model; [`network`] routes
//!   their answers.
//! * [`reflect`] — the reflection phase (§5.2).
//! * [`shade`] — the cells' shading of their pixels; [`smooth`] — their smooth-shading records.
//! * [`links`] — the grid's links behind `cell_core::link::Link` (the link seam); [`faults`] —
//!   the fault-injecting link wrapper; [`tap`] — recording cell traces (and the tracing link
//!   wrapper); [`record`] — a whole traced run, the traces and their digests.
//! * [`radiosity`] — progressive radiosity on the grid: one beam diffusion per shot carrying
//!   its rays' energy, per-patch accumulators, the costed reduction and the supervisor;
//!   [`indirect`] shows its solution: each cell's indirect light, broadcast and costed.
//! * [`triangles`] — the triangles each column keeps for exact occluders; [`occluders`] — those
//!   triangles and each column's target ray for one source.
//! * [`limits`] — host memory checks before allocating a grid.
//! * [`async_tiles`] — the grid as asynchronous boards (tiles of cells, random link delays, no
//!   global cycle) whose phases end by distributed termination detection
//!   (`cell_core::termination`), checked against the host's ground truth.

pub mod async_tiles;
pub mod capacity;
pub mod classic;
pub mod diffuse;
pub mod faults;
pub mod grid;
pub mod indirect;
pub mod lighting;
pub mod limits;
pub mod links;
pub mod load;
pub mod loaded;
pub mod network;
pub mod occluders;
pub mod radiosity;
pub mod record;
pub mod reflect;
pub mod sequential;
pub mod shade;
pub mod smooth;
pub mod tap;
pub mod tiles;
pub mod timing;
pub mod triangles;
pub mod wave_ref;
