//! Workspace-level integration tests and independent oracles for rc2.
//!
//! The oracles live in [`oracle`] and are re-exported at the crate root
//! (`rc2_tests::brute`, `rc2_tests::tunnels`, `rc2_tests::inside`, `rc2_tests::flood`).
//! They use only `std` and exact integer arithmetic and never call `cell-core` or `host-sim`.
//! [`traces`] holds helpers of the trace tests (those do use host-sim); [`qemu`] those of the
//! tests that run the firmware under QEMU, [`boards`] those of the grid of boards.
#![forbid(unsafe_code)]

pub mod boards;
pub mod oracle;
pub mod planes;
pub mod qemu;

pub use oracle::{brute, flood, inside, tunnels};
pub mod traces;
