//! The cell on a microcontroller (issue 5, first step): the `firmware/` crate runs a real
//! `cell_core` cell on an emulated Cortex-M4F (QEMU `mps2-an386`), replays the packet table of
//! `firmware/src/scenario.rs` through `Cell::load_step`, and prints a digest of every output and
//! of the final dexel store. This test builds the firmware, boots it under QEMU, and checks that
//! the digest is bit-identical to the one the same `scenario.rs` computes here on the host.
//!
//! Skipped, with the reason on stderr, when `qemu-system-arm` or the `thumbv7em-none-eabihf`
//! target is missing; `.ci/run` installs both.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[allow(dead_code)]
mod scenario {
    include!("../../firmware/src/scenario.rs");
}

const TARGET: &str = "thumbv7em-none-eabihf";
const QEMU: &str = "qemu-system-arm";
const QEMU_TIMEOUT: Duration = Duration::from_secs(30);

fn firmware_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware")
}

/// The log line the firmware prints before the digest.
fn summary_line(o: &scenario::Outcome) -> String {
    format!(
        "cell=({},{}) packets={} spans={} forwarded={} undecodable={} dexels={} voxels={} shared={} overflows={} lost={}",
        scenario::X,
        scenario::Y,
        o.packets,
        o.spans,
        o.forwarded,
        o.undecodable,
        o.dexels,
        o.voxels,
        o.shared,
        o.overflows,
        o.lost
    )
}

/// Why the QEMU test cannot run here, if it cannot.
fn missing_tool() -> Option<String> {
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

/// Build the firmware in release mode into a target directory of this test's own.
fn build_firmware() -> PathBuf {
    let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("firmware");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    // Run from firmware/ so that its .cargo/config.toml applies; no RUSTFLAGS from outside
    // (host flags must not reach the thumbv7em build).
    let out = Command::new(cargo)
        .current_dir(firmware_dir())
        .args(["build", "--release", "--target", TARGET])
        .env("CARGO_TARGET_DIR", &target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .output()
        .expect("run cargo build for the firmware");
    assert!(out.status.success(), "firmware build failed:\n{}", String::from_utf8_lossy(&out.stderr));
    target_dir.join(TARGET).join("release/rc2-firmware")
}

/// Boot `elf` in QEMU's mps2-an386 (Cortex-M4F), killed after [`QEMU_TIMEOUT`]; returns
/// (exit code, stdout).
fn run_qemu(elf: &Path) -> (Option<i32>, String) {
    let mut child = Command::new(QEMU)
        .args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-nographic"])
        .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start qemu-system-arm");
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().expect("wait for qemu") {
            break st;
        }
        if start.elapsed() > QEMU_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("QEMU did not exit within {QEMU_TIMEOUT:?}; output so far:\n{}", reader.join().unwrap());
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    (status.code(), reader.join().unwrap())
}

#[test]
fn firmware_digest_under_qemu_equals_host_digest() {
    if let Some(why) = missing_tool() {
        eprintln!("SKIPPED firmware_digest_under_qemu_equals_host_digest: {why}");
        return;
    }
    let t0 = Instant::now();
    let elf = build_firmware();
    let t_build = t0.elapsed();
    let (code, out) = run_qemu(&elf);
    eprintln!("firmware build {t_build:?}, QEMU run {:?}; QEMU said:\n{out}", t0.elapsed() - t_build);
    assert_eq!(code, Some(0), "firmware did not exit with semihosting EXIT_SUCCESS:\n{out}");

    let host = scenario::run(&scenario::TABLE);
    let digest = out.lines().find_map(|l| l.trim().strip_prefix("digest=")).expect("no `digest=` line in QEMU output");
    let digest = u64::from_str_radix(digest, 16).expect("digest is hex");
    let summary = out.lines().find(|l| l.starts_with("cell=")).expect("no `cell=` line in QEMU output");
    assert_eq!(summary.trim(), summary_line(&host), "counts differ between the Cortex-M4F and the host");
    assert_eq!(digest, host.digest, "digest differs: firmware {digest:016x}, host {:016x}", host.digest);
}

/// The digest is a real comparison: one changed byte in any field of a packet record changes it.
#[test]
fn one_changed_packet_byte_changes_the_digest() {
    let base = scenario::run(&scenario::TABLE);
    // Offsets in record 0 (the floor at z = 3): facet id, material, normal, plane d, Kσ; in
    // record 1: its z edge's d_i; in record 3 (the wall clipped to its box): bbox z_min. (The
    // digest covers what the cell outputs, so the byte must matter to the cell: the floor's
    // z_min 0 → 1 would not.)
    let rec = scenario::RECORD;
    for (at, what) in [
        (0, "facet id"),
        (4, "material"),
        (6, "normal"),
        (20 + 12, "plane d"),
        (20 + 16, "Kσ"),
        (rec + 41 + 12, "edge d_i"),
        (3 * rec + 16, "bbox z_min"),
    ] {
        let mut t = scenario::TABLE.to_vec();
        t[at] ^= 0x01;
        let o = scenario::run(&t);
        assert_ne!(o.digest, base.digest, "flipping the {what} byte (offset {at}) left the digest unchanged");
    }
    // A truncated record is an undecodable value, not a panic, and changes the digest too.
    let cut = &scenario::TABLE[..scenario::TABLE.len() - 1];
    let o = scenario::run(cut);
    assert_eq!(o.undecodable, 1);
    assert_ne!(o.digest, base.digest);
}

/// The scenario exercises what its comments say: the hand-made facets give the expected dexels,
/// and the whole table overflows the 64-dexel store (counted, not silent).
#[test]
fn scenario_covers_the_load_step_paths() {
    let hand = &scenario::TABLE[..scenario::HAND.len() * scenario::RECORD];
    let mut cell: cell_core::cell::Cell<{ scenario::CAP }> = cell_core::cell::Cell::new(scenario::X, scenario::Y);
    let mut forwarded = Vec::new();
    for r in hand.chunks(scenario::RECORD) {
        let mut pkt = scenario::decode(r, scenario::X, scenario::Y).unwrap();
        forwarded.push(cell.load_step(&mut pkt, scenario::DEPTH));
    }
    let got: Vec<(u16, u16, u32)> = cell.store.dexels().iter().map(|d| (d.span.lo, d.span.hi, d.facet)).collect();
    assert_eq!(got, [(3, 3, 0), (15, 18, 1), (38, 39, 3), (40, 40, 2), (41, 42, 3), (61, 61, 6), (66, 70, 8)]);
    assert_eq!(forwarded, [true, true, true, true, true, true, false, true, true]);
    assert_eq!(cell.counters.spans_computed, 8, "facet 5's box starts east of the cell");
    assert_eq!(cell.counters.voxels_shared, 2, "voxel 40 (facet 3) and 16 (facet 4)");

    let all = scenario::run(&scenario::TABLE);
    assert_eq!(all.undecodable, 0);
    assert_eq!(all.dexels as usize, scenario::CAP);
    assert!(all.overflows > 0 && all.lost > 0, "{all:?}");
}
