//! The workspace's integration tests, one test binary: each file below is a module (run one
//! with `cargo test -p rc2-tests --test integration <module>::`). One binary links and
//! monomorphizes the simulator once instead of once per file, and its harness spreads every
//! test over the cores.
//!
//! `common` holds the helpers several modules share; `rc2_tests` (the crate's `src/`) the
//! oracles and the QEMU and board harnesses.

mod common;

mod area_lights;
mod async_boards;
mod bit_budget;
mod board_grids;
mod board_logic;
mod brute_force;
mod camera;
mod closed_meshes;
mod diffusion;
mod extremes;
mod faulty_links;
mod firmware_qemu;
mod fuzz_regressions;
mod host_modes;
mod lit_set;
mod mcu_grid;
mod mcu_tiles;
mod never_lose;
mod rays;
mod reflections;
mod render;
mod routing;
mod samples;
mod shadows;
mod smooth;
mod topology;
mod trace_replay;
mod wave_vs_direct;
