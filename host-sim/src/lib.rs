//! # host-sim — the std host of the RC² machine
//!
//! Builds an n × n grid of [`cell_core`] cells, loads scenes into it, and reports.
//!
//! * [`scene`] — OBJ meshes (via `tobj`) and built-in scenes.
//! * [`precompute`] — fit, lattice quantisation and exact facet packets (§3.9 host side).
//! * [`grid`] — the grid and the cycle-stepped loading wave.
//! * [`load`] — the `voxelize` job and its statistics.
//! * [`binvox`] — the `.binvox` voxel file format.
//! * [`meshops`] — mesh utilities (subdivision for benchmarks).
//! * [`trace`] — recording cell traces for the firmware replay (issue 5).
//! * [`cli`] — the command line.
// No unsafe code, except one audited intrinsic call: the cache prefetch hint in `tiles::prefetch`.
#![deny(unsafe_code)]

pub mod audit;
pub mod bench;
pub mod binvox;
pub mod classic;
pub mod cli;
pub mod diffuse;
pub mod dump;
pub mod faults;
pub mod grid;
pub mod lightjob;
pub mod limits;
pub mod load;
pub mod meshops;
pub mod network;
pub mod office;
pub mod plot;
pub mod precompute;
pub mod reference;
pub mod reflect;
pub mod refrender;
pub mod render;
pub mod rng;
pub mod scene;
pub mod tiles;
pub mod trace;
pub mod wave_ref;
