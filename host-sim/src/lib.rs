//! # host-sim — the std host of the RC² machine
//!
//! Builds an n × n grid of [`cell_core`] cells, loads scenes into it, runs every phase, and
//! reports. One folder per concern, each layer importing only the layers below it:
//!
//! * [`scene`] — meshes, OBJ/MTL, built-in scenes, offices, binvox, mesh operations.
//! * [`precompute`] — fit, lattice quantisation and exact facet packets (§3.9, host side).
//! * [`machine`] — the grid and its schedulers: loading, diffusion, classic shadow rays,
//!   reflections, shading, link faults, trace tap; the cell capacities in one place.
//! * [`truth`] — the f64 reference: exact visibility, the reference image, comparisons.
//! * [`jobs`] — what a user runs, each job behind a plain options struct: render, light,
//!   light-accuracy, diffusion-table, voxelize, trace, audit, bench, scenes; lit-voxel dumps.
//! * [`report`] — PNG, plots, progress bars, output files.
//! * [`dist`] — past one process: with the `mpi` feature, a render's sources spread over MPI
//!   ranks (docs/MPI.md); without it, one process.
//! * [`cli`] — the command line (the only place that knows clap): it parses the arguments,
//!   converts them into the jobs' options and calls the job.
//!
//! `tests/architecture.rs` checks the layering: no import circles between modules, nothing in
//! `machine/` or `truth/` importing `jobs/`, `report/` or `cli/`, clap only in `cli/`.
// No unsafe code, except one audited intrinsic call: the cache prefetch hint in `tiles::prefetch`.
#![deny(unsafe_code)]

pub mod cli;
pub mod config;
pub mod dist;
pub mod jobs;
pub mod machine;
pub mod precompute;
pub mod report;
pub mod rng;
pub mod scene;
pub mod truth;
