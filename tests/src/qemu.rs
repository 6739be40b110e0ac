//! Helpers of the tests that run the firmware under QEMU (`firmware_qemu.rs`, `mcu_grid.rs`):
//! whether the tools are there, and building the firmware crate for its target.
//!
//! **Invariant**: under CI (the environment variable `CI` set) a missing tool is a test
//! failure, never a skip ([`tools_present`]); elsewhere the skip is printed on stderr.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The firmware's target.
pub const TARGET: &str = "thumbv7em-none-eabihf";
/// The emulator.
pub const QEMU: &str = "qemu-system-arm";

/// The `firmware/` crate.
pub fn firmware_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware")
}

/// Why the QEMU tests cannot run here, if they cannot.
pub fn missing_tool() -> Option<String> {
    match Command::new(QEMU).arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status() {
        Ok(s) if s.success() => {}
        _ => return Some(format!("`{QEMU}` is not on PATH (apt-get install -y qemu-system-arm)")),
    }
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let sysroot = Command::new(&rustc).args(["--print", "sysroot"]).output().ok().filter(|o| o.status.success());
    let Some(sysroot) = sysroot else {
        return Some(format!("`{rustc} --print sysroot` failed"));
    };
    let lib = Path::new(String::from_utf8_lossy(&sysroot.stdout).trim()).join("lib/rustlib").join(TARGET).join("lib");
    if !lib.is_dir() {
        return Some(format!("the {TARGET} target is not installed (rustup target add {TARGET})"));
    }
    None
}

/// Whether this is a CI run: `CI` is set to anything but empty, `0` or `false` (`.ci/run`
/// exports `CI=1`; GitHub Actions, GitLab and most services set `CI=true`).
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !matches!(v.trim().to_ascii_lowercase().as_str(), "" | "0" | "false"))
}

/// Whether test `test` can run here; when it cannot, why (on stderr), or a failure under CI.
pub fn tools_present(test: &str) -> bool {
    let Some(why) = missing_tool() else { return true };
    assert!(
        !in_ci(),
        "CI is set, and the firmware cannot run under QEMU: {why}. `.ci/run` installs \
         qemu-system-arm and the {TARGET} target; a CI run must not skip this test"
    );
    // Straight to stderr, not through `eprintln!`, which the test harness captures and
    // hides for a passing test: a skip must show in every run.
    let _ = writeln!(std::io::stderr(), "SKIPPED {test}: {why} (not a CI run; with CI=1 this is a failure)");
    false
}

/// Build the firmware in release mode into `target_dir` (`cargo build --release` with
/// `args` added, e.g. `--bin board`; `RC2_TRACE_DIR` set to `traces` if given, for the replay
/// image). Returns the directory of the built images.
pub fn build_firmware(target_dir: &Path, traces: Option<&Path>, args: &[&str]) -> PathBuf {
    build_firmware_profile(target_dir, traces, "release", args)
}

/// [`build_firmware`] with cargo profile `profile` (`release`, or `thesis`: the thesis's cell,
/// `firmware/Cargo.toml`). Returns the directory of the built images (`TARGET/profile`).
pub fn build_firmware_profile(target_dir: &Path, traces: Option<&Path>, profile: &str, args: &[&str]) -> PathBuf {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    // Run from firmware/ so that its .cargo/config.toml applies; no RUSTFLAGS from outside
    // (host flags must not reach the thumbv7em build).
    let mut cmd = Command::new(cargo);
    cmd.current_dir(firmware_dir())
        .args(["build", "--profile", profile, "--target", TARGET])
        .args(args)
        .env("CARGO_TARGET_DIR", target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET");
    match traces {
        Some(t) => cmd.env("RC2_TRACE_DIR", t),
        None => cmd.env_remove("RC2_TRACE_DIR"),
    };
    let out = cmd.output().expect("run cargo build for the firmware");
    assert!(out.status.success(), "firmware build failed:\n{}", String::from_utf8_lossy(&out.stderr));
    target_dir.join(TARGET).join(profile)
}
