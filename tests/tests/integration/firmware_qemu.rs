//! The cell on a microcontroller: traces recorded from host-sim runs for several cells — the
//! busiest included — are embedded in the `firmware/` crate, which drives a real `cell_core`
//! cell through them on an emulated Cortex-M4F (QEMU `mps2-an386`): frames arrive through the
//! link interrupt, go out through `embedded-hal` links. Every phase is there: loading and one
//! light of the Cornell box (and an open scene with the sibling wait and the frustum skip), the
//! same light under exact occluders with rays from the light ([`exact_traces`]), the classic
//! shadow-ray phase and the reflection phase ([`ray_traces`]). The firmware prints the
//! digest of each cell's outputs and final state; this test checks each equals the digest the
//! host computed from its own grid run. Altered traces ride along and must fail: flipped bytes
//! (a CRC refuses them: a trace record's, or a ray frame's own on the link receive path) and
//! re-encoded changed values (valid frames, different digest).
//!
//! The production images are built, audited and booted too: the default cell (every phase and
//! option `host-sim render` uses by default, held to 66 KiB of flash: the 32 KiB aimed at is
//! not reached) and the thesis's cell (held to 16 KiB); see [`CellImage`].
//!
//! When `qemu-system-arm` or the `thumbv7em-none-eabihf` target is missing: under CI (the
//! environment variable `CI` set, as `.ci/run` and CI services set it) the test **fails**, since
//! `.ci/run` installs both and a silent skip would hide a broken install; elsewhere it is skipped
//! with the reason on stderr.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cell_core::beam::frac::U0;
use cell_core::beam::Origin;
use cell_core::lit::LitRule;
use cell_core::ray::Connectivity;
use cell_core::reflect::{HitPoint, ReflectNormal};
use cell_core::route::RoutePolicy;
use host_sim::jobs::trace::{record, CellTrace, TraceJob};
use host_sim::machine::lighting::diffuse::{FrustumBlocks, LightConfig};
use host_sim::machine::rays::classic::ClassicConfig;
use host_sim::machine::rays::mirror::ReflectConfig;
use host_sim::precompute::LoadConfig;
use rc2_tests::qemu::{self, QEMU};
use rc2_tests::traces::{
    brighten_reflect_answers, cornell_job_cells, corrupt_first_ray_frame, drop_triangles, flip_shadow_answers,
    mutate_row_material, trace_job,
};

const QEMU_TIMEOUT: Duration = Duration::from_secs(60);

/// Build the firmware in release mode, with the traces of `traces`, into a target directory of
/// this test's own.
/// Build the firmware in release mode, with the traces of `traces` and the cargo arguments
/// `args`, into target directory `target` of this test's own (one per test: they run at once).
fn build_firmware(target: &str, traces: &Path, args: &[&str]) -> PathBuf {
    let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(target);
    qemu::build_firmware(&target_dir, Some(traces), args).join("rc2-firmware")
}

/// The replay image with cell-core's exact occluders and rays from the light (default features
/// of the firmware, for the default cell, whose 31 KB of code would not leave the other traces
/// room in the 256 KiB of flash): it replays the traces of [`exact_traces`] on their own.
const EXACT_FEATURES: [&str; 4] = ["--bin", "rc2-firmware", "--features", "exact-occluders,rays-from-light"];

/// The firmware's cell images: the default cell (`cargo build --release --bin cell`: every
/// phase and option `host-sim render` uses by default) and the thesis's cell (`cargo build
/// --profile thesis --bin cell --no-default-features`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CellImage {
    Default,
    Thesis,
}

impl CellImage {
    /// Build it into target directory `target` of this test's own; its ELF.
    fn build(self, target: &str) -> PathBuf {
        let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(target);
        let dir = match self {
            CellImage::Default => qemu::build_firmware(&target_dir, None, &["--bin", "cell"]),
            CellImage::Thesis => {
                qemu::build_firmware_profile(&target_dir, None, "thesis", &["--bin", "cell", "--no-default-features"])
            }
        };
        dir.join("cell")
    }

    /// Its flash budget (`host-sim audit`'s `budget_of`): 16 KiB for the thesis's cell; for
    /// the default cell 66 KiB, what it reached (66 836 B) plus a small margin, **not** the
    /// 32 KiB aimed at (docs/FIRMWARE.md, "Flash budget", says where the bytes go).
    fn budget(self) -> u64 {
        match self {
            CellImage::Default => host_sim::jobs::audit::DEFAULT_CELL_FLASH_BUDGET,
            CellImage::Thesis => host_sim::jobs::audit::FLASH_BUDGET,
        }
    }

    /// The modules whose code must be in it: the cell's parts; for the default cell also
    /// shading, the plane rule, exact occluders, the radial policy's choice (in `light`) and
    /// the empty-frustum skip.
    fn modules(self) -> &'static [&'static str] {
        const THESIS: [&str; 5] =
            ["cell_core::beam", "cell_core::light", "cell_core::dexel", "cell_core::voxelize", "cell_core::link"];
        const DEFAULT: [&str; 10] = [
            "cell_core::beam",
            "cell_core::light",
            "cell_core::dexel",
            "cell_core::voxelize",
            "cell_core::link",
            "cell_core::shade",
            "cell_core::lit",
            "cell_core::occluder",
            "cell_core::receiver",
            "cell_core::occupancy",
        ];
        match self {
            CellImage::Default => &DEFAULT,
            CellImage::Thesis => &THESIS,
        }
    }
}

/// A cell image: its code and read-only data, and its whole flash (vector table included),
/// within its budget ([`CellImage::budget`]), every byte of it in the per-module table of
/// `host-sim audit`, and the cell's parts in it.
fn check_production_image(elf: &Path, image: CellImage) {
    use host_sim::jobs::audit::{budget_of, flash_table};
    let budget = image.budget();
    assert_eq!(budget_of(elf), budget, "audit holds {} to its budget", elf.display());
    let t = flash_table(elf).expect("read the production image's ELF");
    let rows: Vec<String> = t.modules.iter().map(|m| format!("{} {} + {} B", m.module, m.code, m.data)).collect();
    let table = rows.join("\n");
    assert_eq!(t.modules.iter().map(|m| m.code + m.data).sum::<u64>(), t.flash, "every byte in one row:\n{table}");
    eprintln!(
        "{image:?} cell: flash {} B (text {} + rodata {} + vector table {}) of {budget}",
        t.flash, t.text, t.rodata, t.vector_table
    );
    assert!(
        t.text + t.rodata <= budget && t.flash <= budget,
        "the {image:?} cell image takes {} B of flash (text {} + rodata {} + vector table {}), over its \
         {budget} B budget; by module:\n{table}",
        t.flash,
        t.text,
        t.rodata,
        t.vector_table
    );
    assert!(t.by_debug_info, "the release profile keeps debug info in the ELF (not in flash)");
    for m in image.modules() {
        assert!(
            t.modules.iter().any(|r| r.module == *m && r.code > 0),
            "no code of {m} in the {image:?} cell:\n{table}"
        );
    }
}

/// The host's side of a smoke run of the production image: the records that make cell (3, 5)
/// of a 16 × 16 × 32 grid, a light setup (the thesis's rule and policy), the same setup with
/// a flipped byte and an initial beam of the source in this cell; apart, a shading record;
/// and, for the default cell, an exact-occluder source (the default lit rule): its light
/// record, one triangle more than the column holds (`TRIANGLE_CAP`, crossing the column
/// above the source) and the source's initial beam.
fn production_image_input() -> (Vec<u8>, Vec<u8>, Vec<u8>) {
    use cell_core::beam::{Beam, Direction, FarDistance, Source, SourceId};
    use cell_core::light::{BeamMsg, Policy};
    use cell_core::lit::LitRule;
    use cell_core::shade::{NormalMode, ShadeParams};
    use cell_core::trace::{write_event, Event, LightSetup, Replayer, ShadeSetup};
    use cell_core::wire::Message;
    let source = Source::at_voxel(SourceId(0), [3, 5, 10]).unwrap();
    let (policy, rule) = (Policy::Thesis, LitRule::Thesis);
    let setup = LightSetup {
        source,
        n: 16,
        depth: 32,
        far: 31,
        policy,
        fa: 16,
        merge: true,
        source_bit: 1,
        skip: None,
        hold: 0,
        frustum: None,
        rule,
        lit_visible_only: false,
    };
    let shade = ShadeSetup {
        params: ShadeParams { ambient: [0.1; 3], normal_mode: NormalMode::Facet, eye: cell_core::shade::Eye::Grid },
        lights: Default::default(),
        materials: Default::default(),
    };
    let header = Replayer::<U0, 64, 64, 3, 64>::header(3, 5, 32);
    let mut input = Vec::new();
    let frame = |ev: Event<'_, U0>| {
        let mut buf = [0u8; 2048];
        let n = write_event(&ev, &mut buf).unwrap();
        buf[..n].to_vec()
    };
    input.extend(frame(Event::Header(header)));
    let light = frame(Event::Light(setup));
    let mut flipped = light.clone();
    flipped[10] ^= 0x04;
    input.extend(flipped);
    input.extend(&light);
    let beam = Beam::<U0>::initial(&source, Direction::ALL[0], FarDistance::new(31).unwrap());
    let mut buf = [0u8; 64];
    let n = Message::Beam(BeamMsg::new(beam, 10)).emit(0, &mut buf).unwrap();
    input.extend(&buf[..n]);
    let mut exact = frame(Event::Light(LightSetup { rule: LitRule::Exact, ..setup }));
    // Sheets at z = 12 voxels over the whole grid (vertices in sixteenths of a voxel), each a
    // sixteenth of a voxel above the last.
    for k in 0..=cell_core::cell::TRIANGLE_CAP as i32 {
        let z = 12 * 16 + k;
        let t = cell_core::triangle::Triangle::new([[0, 0, z], [512, 0, z], [0, 512, z]]).unwrap();
        exact.extend(frame(Event::Triangle(t)));
    }
    exact.extend(&buf[..n]);
    (input, frame(Event::Shade(shade)), exact)
}

/// Boot the production image with its host link (UART0) on QEMU's stdio and the port links
/// unconnected, send [`production_image_input`], and read its report: the cell the header
/// named, no pixel (shading is a feature the image leaves out), one bad frame (the flipped
/// one), nothing lost, no lit voxel (the column is empty). Then send the shading record again
/// and read a second report, the same but for one more bad frame (see below): the cell may
/// answer the first before its light cell has stepped with the beam, but not the second. Taking
/// the beam off the FIFO (a `memmove`) is what hard-faulted the image while its
/// `__aeabi_memmove` called itself (`firmware/src/bin/cell/mem.rs`), and a single report could
/// come before it.
///
/// The default cell then gets the exact-occluder source, a shading record, and a shading
/// record again: the triangle past the column's capacity is one more bad frame (refused, not
/// dropped), and the beam is judged against the column's triangles — the exact visit, whose
/// frames come on top of the beam's fate: the stack went deeper than in the thesis-rule run.
///
/// Every report ends its counters with the deepest the stack has gone (the image paints its
/// free RAM at boot, `firmware/src/stack.rs`). It is at least the nine frame buffers the cell
/// keeps on its stack, and with the image's statics (none: `.data` and `.bss` are empty) it
/// fits the RAM of `memory.x`. The peaks are printed: docs/FIRMWARE.md's RAM figures.
fn run_production_image(elf: &Path, image: CellImage) {
    let mut child = Command::new(QEMU)
        .args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-display", "none", "-monitor", "none"])
        .args(["-serial", "stdio", "-kernel"])
        .arg(elf)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start qemu-system-arm");
    // The host link stays open until the reports are read: on end of input QEMU's stdio backend
    // may close the serial port, and a guest slowed down by a loaded machine would answer into
    // a closed port.
    let mut host_link = child.stdin.take().unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || loop {
        // A report: header (kind, length), payload, CRC.
        let mut head = [0u8; 3];
        if stdout.read_exact(&mut head).is_err() {
            return;
        }
        let mut rest = vec![0u8; u16::from_le_bytes([head[1], head[2]]) as usize + 4];
        if stdout.read_exact(&mut rest).is_err() || tx.send([head.to_vec(), rest].concat()).is_err() {
            return;
        }
    });
    let (records, shade, exact) = production_image_input();
    let deadline = Instant::now() + QEMU_TIMEOUT;
    let mut reports = Vec::new();
    let mut inputs = vec![[records, shade.clone()].concat(), shade.clone()];
    if image == CellImage::Default {
        inputs.extend([[exact, shade.clone()].concat(), shade]);
    }
    let want = inputs.len();
    for input in inputs {
        host_link.write_all(&input).unwrap();
        host_link.flush().unwrap();
        match rx.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
            Ok(r) => reports.push(r),
            Err(_) => break,
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    drop(host_link);
    assert_eq!(
        reports.len(),
        want,
        "the production image sent {} of its {want} reports before QEMU stopped",
        reports.len()
    );
    // Without the shading feature (the thesis's cell) the second report counts one more bad
    // frame: the image does not decode a `Shade` record's payload, so after answering it counts
    // the record as bad. The default cell shades: the record is good; its exact-occluder
    // source's triangle past the column's capacity is one more.
    let bad: &[u32] = match image {
        CellImage::Default => &[1, 1, 2, 2],
        CellImage::Thesis => &[1, 2],
    };
    let mut peaks = Vec::new();
    for (report, &bad) in reports.iter().zip(bad) {
        let (raw, used) = cell_core::wire::read_frame(report).expect("the report's frame and CRC");
        assert_eq!((raw.kind, used), (0x50, report.len()));
        let p = raw.payload;
        let u16_at = |i: usize| u16::from_le_bytes([p[i], p[i + 1]]);
        let u32_at = |i: usize| u32::from_le_bytes(p[i..i + 4].try_into().unwrap());
        assert_eq!((u16_at(0), u16_at(2)), (3, 5), "the cell the header named");
        assert_eq!(p[4], 0, "no pixel: no shading feature (thesis), or an empty column (default)");
        let counters: Vec<u32> = (0..5).map(|k| u32_at(14 + 4 * k)).collect();
        assert_eq!(
            counters,
            [0, 0, 0, 0, bad],
            "dexel overflows, lost voxels, lit overflows, refused beams, bad frames"
        );
        peaks.push(u32_at(34) as usize);
        assert_eq!((p[38], p.len()), (0, 39), "no lit run in an empty column");
    }
    println!("{image:?} cell: stack peaks {peaks:?} B, report by report");
    let buffers = 9 * cell_core::wire::MAX_FRAME;
    let ram = host_sim::jobs::audit::ram_budget(host_sim::jobs::audit::MEMORY_X).expect("memory.x's RAM length");
    for (i, &peak) in peaks.iter().enumerate() {
        assert!(peak >= buffers, "report {i}: a stack peak of {peak} B, under the {buffers} B of frame buffers");
        assert!(peak <= ram, "report {i}: a stack peak of {peak} B, over memory.x's {ram} B of RAM");
        assert!(i == 0 || peak >= peaks[i - 1], "the peak never falls: {peaks:?}");
    }
    if image == CellImage::Default {
        assert!(peaks[3] > peaks[1], "the exact visit adds frames to the beam's fate: {peaks:?}");
    }
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

/// What the firmware printed for each trace: the digest, or the error.
fn parse_output(out: &str) -> HashMap<String, Result<u64, String>> {
    let mut m = HashMap::new();
    for l in out.lines() {
        let Some(rest) = l.trim().strip_prefix("trace=") else { continue };
        let name = rest.split_whitespace().next().unwrap_or("").to_string();
        if let Some(e) = rest.split("error=").nth(1) {
            m.insert(name, Err(e.to_string()));
        } else if let Some(d) = rest.split("digest=").nth(1) {
            m.insert(name, Ok(u64::from_str_radix(d.trim(), 16).expect("digest is hex")));
        }
    }
    m
}

/// The light-phase traces the firmware replays, written to `dir`: a Cornell-box run at n = 64
/// (loading + one light) for its corner, centre, source and busiest cells, two altered copies
/// of the corner cell's (`z_flipped`: a flipped byte; `z_changed`: a re-encoded changed
/// material), and an open scene's busiest and centre cells with the sibling wait and the
/// frustum skip (`w_…`). Returns the unaltered traces by the name the firmware prints, and
/// the corner cell's digest.
fn light_traces(dir: &Path) -> (Vec<(String, CellTrace)>, u64) {
    let (mesh, load, light, cells) = cornell_job_cells(64);
    let job = TraceJob { busiest: true, ..trace_job(&mesh, load, light, cells) };
    let traces = record(&job).expect("record traces");
    assert!(traces.len() >= 4, "corner, centre, source and busiest cells");
    host_sim::jobs::trace::write_traces(dir, &traces).unwrap();
    // Two altered copies of the corner cell's trace (the first one recorded; small, so that the
    // firmware's flash holds them too).
    let corner = traces.first().unwrap();
    let mut flipped = corner.bytes.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 0x10;
    std::fs::write(dir.join("z_flipped.rc2t"), &flipped).unwrap();
    let changed = mutate_row_material::<U0>(&corner.bytes).expect("the corner cell received a row packet");
    std::fs::write(dir.join("z_changed.rc2t"), &changed).unwrap();
    // The sibling wait and the empty-frustum skip on the MCU: an open scene's busiest cell and
    // its source cell, recorded with both on. Thin surfaces: with conservative contours every
    // one of the teapot's ~6 000 sub-voxel facets sends row packets through these cells, and
    // the traces would not fit the firmware's 256 KiB of flash.
    let teapot = host_sim::scene::load("teapot-floor").unwrap();
    let tlight = LightConfig { hold: 4, skip_frustum: true, frustum_blocks: FrustumBlocks::B8, ..light };
    let tjob = TraceJob { busiest: true, ..trace_job(&teapot, LoadConfig::thin(32), tlight, vec![[16, 16]]) };
    let waits = record(&tjob).expect("record traces with the wait and the frustum skip");
    for t in &waits {
        std::fs::write(dir.join(format!("w_cell_{}_{}.rc2t", t.x, t.y)), &t.bytes).unwrap();
    }
    let corner_digest = corner.digest;
    let named = traces.into_iter().map(|t| (format!("cell_{}_{}.rc2t", t.x, t.y), t));
    let named = named.chain(waits.into_iter().map(|t| (format!("w_cell_{}_{}.rc2t", t.x, t.y), t)));
    (named.collect(), corner_digest)
}

/// Exact occluders with rays from the light (`x_…`): the Cornell box at n = 32, its corner,
/// centre, source and busiest cells; the cells take their triangles from the trace and compute
/// their target rays themselves. `z_no_triangles.rc2t` is the busiest cell's trace without its
/// triangle records: a valid trace that must not reach the busiest cell's digest. Returns the
/// traces by name and the busiest cell's digest.
fn exact_traces(dir: &Path) -> (Vec<(String, CellTrace)>, u64) {
    let (mesh, load, light, cells) = cornell_job_cells(32);
    let light = LightConfig { rule: LitRule::Exact, rays: Origin::Light, ..light };
    let job = TraceJob { busiest: true, ..trace_job(&mesh, load, light, cells) };
    let traces = record(&job).expect("record traces under exact occluders");
    let busiest = traces.last().expect("the busiest cell");
    let without = drop_triangles::<U0>(&busiest.bytes).expect("the busiest cell keeps triangles");
    std::fs::write(dir.join("z_no_triangles.rc2t"), without).unwrap();
    let digest = busiest.digest;
    let named = traces.into_iter().map(|t| (format!("x_cell_{}_{}.rc2t", t.x, t.y), t));
    (named.inspect(|(name, t)| std::fs::write(dir.join(name), &t.bytes).unwrap()).collect(), digest)
}

/// The ray phases on the MCU, recorded at n = 32 (small traces, a few KB each): the Cornell box
/// lit by classic shadow rays under the plane rule (6-connected walks, the plane segment's
/// 64-bit arithmetic) and under the thesis's rule with 26-connected rays from every occupied
/// voxel and dimension-ordered answers; the Cornell box with a mirror, reflections to depth 4
/// (`f32` shading, the wait table, answers forwarded), with 6-connected rays and with
/// 26-connected ones through FIFOs of 2. Each set goes to a directory under `dir` (the firmware
/// build embeds those too, named `set/cell_X_Y.rc2t`). Altered copies in `dir`: `z_ray_flipped`
/// (a byte of a ray frame flipped in the trace: the record's CRC), `z_ray_wire` (the same byte
/// flipped on the wire, the record re-encoded: the ray frame's own CRC, on the link receive
/// path), `z_answer_changed` and `z_reflect_changed` (an answer the router delivers, re-encoded
/// changed: a valid trace, another digest). Returns the unaltered traces by name and the
/// digests of the two whose answers were changed.
fn ray_traces(dir: &Path) -> (Vec<(String, CellTrace)>, [u64; 2]) {
    let named = record_ray_sets(dir);
    let (shadow, mirror) = (&named[0].1, &named[3].1);
    altered_ray_traces(dir, shadow, mirror);
    let digests = [shadow.digest, mirror.digest];
    (named, digests)
}

/// The unaltered ray-phase traces of [`ray_traces`], written under `dir`, by name: the first
/// two are the plane rule's shadow rays, the fourth a reflection cell.
fn record_ray_sets(dir: &Path) -> Vec<(String, CellTrace)> {
    let (six, adaptive) = (Connectivity::Six, RoutePolicy::Adaptive);
    let plane =
        ClassicConfig { fa: 16, connectivity: six, route: adaptive, all_voxels: false, bias: 0, rule: LitRule::Plane };
    let thesis = ClassicConfig {
        connectivity: Connectivity::TwentySix,
        all_voxels: true,
        rule: LitRule::Thesis,
        route: RoutePolicy::DiagonalFirst,
        ..plane
    };
    let normal = ReflectNormal::Facet;
    let mirror = ReflectConfig {
        depth: 4,
        threshold: 0.01,
        normal,
        hit: HitPoint::Centre,
        skip_own_facet: true,
        connectivity: six,
        fa: 16,
        route: adaptive,
    };
    let mirror26 = ReflectConfig { connectivity: Connectivity::TwentySix, fa: 2, ..mirror };
    let sets = [
        ("shadow-plane", "cornell", Some(plane), None, vec![[22, 14], [10, 18]]),
        ("shadow-thesis-26", "cornell", Some(thesis), None, vec![[6, 22]]),
        ("reflect", "cornell-mirror", None, Some(mirror), vec![[20, 11], [20, 17]]),
        ("reflect-26", "cornell-mirror", None, Some(mirror26), vec![[20, 17]]),
    ];
    let mut named = Vec::new();
    for (set, scene, classic, reflections, cells) in sets {
        let mesh = host_sim::scene::load(scene).unwrap();
        let (load, light) = (LoadConfig::watertight(32), host_sim::config::plane_rule());
        let job = TraceJob { classic, reflections, ..trace_job(&mesh, load, light, cells) };
        let traces = record(&job).unwrap_or_else(|e| panic!("record the {set} traces: {e}"));
        host_sim::jobs::trace::write_traces(&dir.join(set), &traces).unwrap();
        named.extend(traces.into_iter().map(|t| (format!("{set}/cell_{}_{}.rc2t", t.x, t.y), t)));
    }
    named
}

/// The altered copies of [`ray_traces`], from a shadow-ray trace and a reflection trace.
fn altered_ray_traces(dir: &Path, shadow: &CellTrace, mirror: &CellTrace) {
    let flipped = corrupt_first_ray_frame::<U0>(&shadow.bytes).expect("a ray came in on a link");
    let mut records = cell_core::trace::Parser::<U0>::new(&flipped);
    assert!(std::iter::from_fn(|| records.next_event()).all(|r| r.is_ok()), "only the ray frame's CRC is wrong");
    let at = (0..flipped.len()).find(|&i| flipped[i] != shadow.bytes[i]).unwrap();
    let mut raw = shadow.bytes.clone();
    raw[at] ^= flipped[at] ^ shadow.bytes[at];
    std::fs::write(dir.join("z_ray_flipped.rc2t"), raw).unwrap();
    std::fs::write(dir.join("z_ray_wire.rc2t"), flipped).unwrap();
    let unlit = flip_shadow_answers::<U0>(&shadow.bytes);
    std::fs::write(dir.join("z_answer_changed.rc2t"), unlit.expect("an answer came back")).unwrap();
    let brighter = brighten_reflect_answers::<U0>(&mirror.bytes);
    std::fs::write(dir.join("z_reflect_changed.rc2t"), brighter.expect("a reflection answer came back")).unwrap();
}

/// The firmware's digest of each named trace equals the host grid's.
fn check_digests(got: &HashMap<String, Result<u64, String>>, traces: &[(String, CellTrace)], out: &str) {
    for (name, t) in traces {
        match got.get(name) {
            Some(Ok(d)) => assert_eq!(
                *d, t.digest,
                "{name} (cell ({}, {})): the Cortex-M4F gives {d:016x}, the host grid {:016x}",
                t.x, t.y, t.digest
            ),
            other => panic!("{name} (cell ({}, {})): no digest from the firmware: {other:?}\n{out}", t.x, t.y),
        }
    }
}

/// The altered traces: each flipped byte refused by a CRC, each re-encoded change replayed to
/// another digest than the original's.
fn check_altered(got: &HashMap<String, Result<u64, String>>, changed: &[(&str, u64)]) {
    for name in ["z_flipped.rc2t", "z_ray_flipped.rc2t", "z_ray_wire.rc2t"] {
        assert!(
            matches!(got.get(name), Some(Err(e)) if e.contains("BadCrc")),
            "{name}: a flipped byte must be refused by the CRC: {:?}",
            got.get(name)
        );
    }
    for &(name, original) in changed {
        match got.get(name) {
            Some(Ok(d)) => assert_ne!(*d, original, "{name}: a changed value must change the digest"),
            Some(Err(e)) => panic!("{name}: the re-encoded trace is valid and must replay: {e}"),
            None => panic!("no result for {name}"),
        }
    }
}

#[test]
fn firmware_replays_cornell_traces_bit_identical_to_the_host() {
    if !qemu::tools_present("firmware_replays_cornell_traces_bit_identical_to_the_host") {
        return;
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("qemu-traces");
    let _ = std::fs::remove_dir_all(&dir);
    let (light, corner) = light_traces(&dir);
    let (rays, [shadow, mirror]) = ray_traces(&dir);

    let t0 = Instant::now();
    // The replay image as before: without the default cell's features (cell-core's exact
    // occluders would leave these traces no room in the 256 KiB of flash).
    let elf = build_firmware("firmware", &dir, &["--bin", "rc2-firmware", "--no-default-features"]);
    for image in [CellImage::Default, CellImage::Thesis] {
        let cell = image.build("firmware");
        check_production_image(&cell, image);
        run_production_image(&cell, image);
    }
    let t_build = t0.elapsed();
    let (code, out) = run_qemu(&elf);
    eprintln!("firmware build {t_build:?}, QEMU run {:?}; QEMU said:\n{out}", t0.elapsed() - t_build);
    let got = parse_output(&out);
    check_digests(&got, &light, &out);
    check_digests(&got, &rays, &out);
    let changed = [("z_changed.rc2t", corner), ("z_answer_changed.rc2t", shadow), ("z_reflect_changed.rc2t", mirror)];
    check_altered(&got, &changed);
    // The flipped traces make the firmware report failure through its exit code.
    assert_eq!(code, Some(1), "the firmware must exit with EXIT_FAILURE when a trace fails:\n{out}");
}

/// Exact occluders with rays from the light on the Cortex-M4F: the replay image built with
/// those features replays the Cornell box's cells (their triangles from the trace, their
/// target rays computed in the cell) to the host grid's digests; the busiest cell's trace
/// without its triangles fails (the cell sends other beams than the trace's neighbours take)
/// or replays to another digest.
#[test]
fn firmware_replays_exact_occluder_traces_bit_identical_to_the_host() {
    if !qemu::tools_present("firmware_replays_exact_occluder_traces_bit_identical_to_the_host") {
        return;
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("qemu-exact-traces");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (traces, busiest) = exact_traces(&dir);
    let elf = build_firmware("firmware-exact", &dir, &EXACT_FEATURES);
    let (code, out) = run_qemu(&elf);
    let got = parse_output(&out);
    check_digests(&got, &traces, &out);
    let failed = match got.get("z_no_triangles.rc2t") {
        Some(Ok(d)) => {
            assert_ne!(*d, busiest, "the triangles must matter:\n{out}");
            false
        }
        Some(Err(_)) => true,
        None => panic!("no result for z_no_triangles.rc2t:\n{out}"),
    };
    let want = if failed { 1 } else { 0 };
    assert_eq!(code, Some(want), "the exact-occluder traces replay, the one without triangles aside:\n{out}");
}
