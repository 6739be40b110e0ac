//! Link against the top-level `memory.x` (the per-cell budget: 256 KiB flash, 64 KiB RAM, laid
//! out for QEMU's mps2-an386) and cortex-m-rt's `link.x`.
//!
//! `-Tlink.x` is passed here rather than through `rustflags` in `.cargo/config.toml` so that a
//! `RUSTFLAGS` in the environment (which replaces config rustflags) cannot drop it.

use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap());
    let memory_x = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap()).join("../memory.x");
    fs::copy(&memory_x, out.join("memory.x")).expect("copy ../memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rustc-link-arg=-Tlink.x");
}
