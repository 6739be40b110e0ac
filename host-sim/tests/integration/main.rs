//! host-sim's integration tests, one test binary: each file below is a module (run one with
//! `cargo test -p host-sim --test integration <module>::`). One binary links and
//! monomorphizes the simulator once instead of once per file.

mod architecture;
mod bad_inputs;
mod cli;
mod dump;
mod radiosity_grid;
mod radiosity_reference;
mod radiosity_render;
