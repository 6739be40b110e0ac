//! Link against the top-level `memory.x` (the per-cell budget: 256 KiB flash, 64 KiB RAM, laid
//! out for QEMU's mps2-an386) and cortex-m-rt's `link.x`; embed the cell traces to replay. The
//! `board` binary (a tile of cells of the grid of boards) links against `board-memory.x`
//! instead (512 KiB of RAM): each binary gets its own `memory.x` directory as a linker search
//! path (`cargo:rustc-link-arg-bin`), where `link.x`'s `INCLUDE memory.x` finds it.
//!
//! Traces: every `*.rc2t` file of `$RC2_TRACE_DIR` (the QEMU test records them from a host-sim
//! run and points this variable at them), or of `firmware/traces/`, and of the directories
//! directly under it (a small committed set: the light phase in `traces/`, a classic
//! shadow-ray run in `traces/shadow-rays/`, a reflection run in `traces/reflections/`, exact
//! occluders with rays from the light in `traces/exact/` — embedded only with the features
//! `exact-occluders` and `rays-from-light`; the commands that record them are in
//! docs/FIRMWARE.md). They become
//! `TRACES: &[(&str, &[u8])]` in `$OUT_DIR/traces.rs` via `include_bytes!`, named by their
//! path under the directory.
//!
//! `-Tlink.x` is passed here rather than through `rustflags` in `.cargo/config.toml` so that a
//! `RUSTFLAGS` in the environment (which replaces config rustflags) cannot drop it.

use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap());
    let root = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap());
    let memory_x = root.join("../memory.x");
    let board_memory_x = root.join("board-memory.x");
    // An older build's copy in the shared search path would shadow the per-binary ones.
    let _ = fs::remove_file(out.join("memory.x"));
    for (bins, from, dir) in
        [(&["rc2-firmware", "cell"][..], &memory_x, "cell-memory"), (&["board"][..], &board_memory_x, "board-memory")]
    {
        let d = out.join(dir);
        fs::create_dir_all(&d).expect("create a memory.x directory");
        fs::copy(from, d.join("memory.x")).unwrap_or_else(|e| panic!("copy {}: {e}", from.display()));
        for bin in bins {
            println!("cargo:rustc-link-arg-bin={bin}=-L{}", d.display());
        }
        println!("cargo:rerun-if-changed={}", from.display());
    }
    // cortex-m-rt's `device` feature includes `device.x` (handler aliases of a device crate);
    // the firmware's interrupt vectors (src/vectors.rs) all use the default handler.
    fs::write(out.join("device.x"), "/* no device-specific handlers: see src/vectors.rs */\n").expect("write device.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rustc-link-arg=-Tlink.x");
    if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg=-Tdefmt.x");
    }

    println!("cargo:rerun-if-env-changed=RC2_TRACE_DIR");
    let dir = env::var_os("RC2_TRACE_DIR").map(PathBuf::from).unwrap_or_else(|| root.join("traces"));
    let list = |d: &PathBuf| -> Vec<PathBuf> {
        println!("cargo:rerun-if-changed={}", d.display());
        fs::read_dir(d)
            .unwrap_or_else(|e| panic!("cannot read the trace directory {}: {e}", d.display()))
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect()
    };
    let top = list(&dir);
    // `exact/` holds traces of exact occluders with rays from the light: an image built without
    // those cell-core features would refuse them.
    let exact = env::var_os("CARGO_FEATURE_EXACT_OCCLUDERS").is_some()
        && env::var_os("CARGO_FEATURE_RAYS_FROM_LIGHT").is_some();
    let sets = top.iter().filter(|p| p.is_dir() && (exact || !p.ends_with("exact")));
    let mut files: Vec<PathBuf> = sets.flat_map(list).chain(top.iter().cloned()).collect();
    files.retain(|p| p.is_file() && p.extension().is_some_and(|x| x == "rc2t"));
    files.sort();
    let mut src = String::from(
        "/// The embedded traces: (path under the trace directory, bytes).\npub static TRACES: &[(&str, &[u8])] = &[\n",
    );
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
        let name = f.strip_prefix(&dir).unwrap().to_string_lossy();
        src += &format!("    ({name:?}, include_bytes!({:?})),\n", f.canonicalize().unwrap());
    }
    src += "];\n";
    fs::write(out.join("traces.rs"), src).expect("write traces.rs");
}
