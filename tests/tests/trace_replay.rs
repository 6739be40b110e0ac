//! Cell traces on the host: every cell of small grids is recorded during a real grid
//! run and replayed through a fresh `cell_core` cell (the code the firmware runs); the digest of
//! outputs and final state must equal the one the grid computed, for both scheduling policies,
//! with and without merging, with integer and fractional rays. Altered traces must fail: any
//! flipped byte, any truncation, a re-encoded changed value, a dropped record. The traces
//! committed for the firmware (`firmware/traces/`) replay to their recorded digests and are
//! exactly what their documented command records today.

use cell_core::beam::frac::{U0, U2};
use cell_core::beam::FracBits;
use cell_core::light::Policy;
use cell_core::trace::{write_event, Parser};
use host_sim::jobs::trace::{record, CellTrace, TraceJob};
use host_sim::machine::capacity::{FA_CAP, LIT_CAP, OB_CAP};
use host_sim::machine::diffuse::{FrustumBlocks, LightConfig};
use host_sim::precompute::LoadConfig;
use rc2_tests::traces::mutate_row_material;

type Replay = fn(&[u8]) -> Result<(u64, cell_core::trace::ReplayStats), cell_core::trace::ReplayError>;

fn replay_fn<F: FracBits>() -> Replay {
    cell_core::trace::replay::<F, { cell_core::cell::DEFAULT_DEXELS }, FA_CAP, OB_CAP, LIT_CAP>
}

fn all_cells<F: FracBits>(scene: &str, n: u32, light: LightConfig) -> Vec<CellTrace> {
    let mesh = host_sim::scene::load(scene).unwrap();
    let load = LoadConfig::thin(n);
    let cells = (0..n).flat_map(|y| (0..n).map(move |x| [x, y])).collect();
    record::<F>(&TraceJob { mesh: &mesh, load, light, lights: Vec::new(), cells, busiest: false }).unwrap()
}

fn check_all<F: FracBits>(scene: &str, n: u32, policy: Policy, merge: bool, fa: usize) {
    check_all_with::<F>(scene, n, LightConfig { fa, policy, merge, record_visits: false, ..Default::default() });
}

fn check_all_with<F: FracBits>(scene: &str, n: u32, light: LightConfig) {
    let (policy, merge) = (light.policy, light.merge);
    let traces = all_cells::<F>(scene, n, light);
    assert_eq!(traces.len(), (n * n) as usize);
    let (mut beams, mut sent) = (0u64, 0u64);
    for t in &traces {
        let (d, st) = replay_fn::<F>()(&t.bytes).unwrap_or_else(|e| panic!("cell ({}, {}): {e:?}", t.x, t.y));
        assert_eq!(d, t.digest, "{scene} n={n} {policy:?} merge={merge} f={}: cell ({}, {})", F::U32, t.x, t.y);
        beams += st.received as u64;
        sent += st.sent as u64;
    }
    // Every beam a cell sent was received by a neighbour: the traces agree with each other.
    assert!(beams >= sent, "{beams} received < {sent} sent");
    assert!(sent > 0, "the light reached no cell");
}

#[test]
fn every_cell_replays_to_the_grid_digest() {
    check_all::<U0>("cornell", 16, Policy::Wavefront, true, 16);
    check_all::<U0>("cornell", 16, Policy::Thesis, false, 2);
    check_all::<U0>("cornell", 16, Policy::Radial, true, 16);
    check_all::<U2>("cornell", 16, Policy::Wavefront, true, 4);
    check_all::<U0>("teapot-floor", 16, Policy::Wavefront, false, 8);
}

/// The sibling wait and the empty-frustum skip run in the cell too: traces (version 3) carry
/// the wait and the summary, and every cell replays to the grid's digest.
#[test]
fn every_cell_replays_with_the_sibling_wait_and_the_frustum_skip() {
    let light = LightConfig { hold: 3, skip_frustum: true, frustum_blocks: FrustumBlocks::B8, ..Default::default() };
    check_all_with::<U0>("teapot-floor", 20, light);
    check_all_with::<U2>("cornell", 16, LightConfig { hold: 8, ..light });
}

fn busiest_trace() -> CellTrace {
    let mesh = host_sim::scene::load("cornell").unwrap();
    let load = LoadConfig::thin(24);
    let light =
        LightConfig { fa: 16, policy: Policy::Wavefront, merge: true, record_visits: false, ..Default::default() };
    let job = TraceJob { mesh: &mesh, load, light, lights: Vec::new(), cells: Vec::new(), busiest: true };
    record::<U0>(&job).unwrap().pop().unwrap()
}

#[test]
fn every_flipped_byte_and_every_truncation_fails() {
    let t = busiest_trace();
    let replay = replay_fn::<U0>();
    assert_eq!(replay(&t.bytes).unwrap().0, t.digest);
    for i in 0..t.bytes.len() {
        let mut b = t.bytes.clone();
        b[i] ^= 1 << (i % 8);
        if let Ok((d, _)) = replay(&b) {
            panic!("flipping byte {i} of {} went through with digest {d:016x}", t.bytes.len());
        }
    }
    for cut in 0..t.bytes.len() {
        assert!(replay(&t.bytes[..cut]).is_err(), "a trace cut at {cut} replayed");
    }
}

#[test]
fn re_encoded_changes_change_the_digest() {
    let t = busiest_trace();
    let replay = replay_fn::<U0>();
    let changed = mutate_row_material::<U0>(&t.bytes).unwrap();
    assert_ne!(replay(&changed).unwrap().0, t.digest, "changed materials");
    // Drop one record of each kind that the cell cannot do without: the replay fails or the
    // digest changes.
    let events: Vec<Vec<u8>> = {
        let mut p = Parser::<U0>::new(&t.bytes);
        let mut v = Vec::new();
        let mut buf = [0u8; 2048];
        while let Some(ev) = p.next_event() {
            let n = write_event(&ev.unwrap(), &mut buf).unwrap();
            v.push(buf[..n].to_vec());
        }
        v
    };
    let mut dropped = 0;
    for skip in 1..events.len() - 1 {
        let kind = events[skip][0];
        let b: Vec<u8> = events.iter().enumerate().filter(|(i, _)| *i != skip).flat_map(|(_, e)| e.clone()).collect();
        if let Ok((d, _)) = replay(&b) {
            assert_ne!(d, t.digest, "dropping record {skip} (kind {kind:#x}) left the digest unchanged");
        }
        dropped += 1;
    }
    assert!(dropped > 10);
}

/// The diffusion report's peak link load (most messages one link carried one way) against the
/// per-cell traces: each `Grant(port)` record is one message leaving that cell on that link.
#[test]
fn peak_link_load_equals_the_busiest_link_in_the_traces() {
    let n = 16;
    let light = LightConfig { fa: 16, policy: Policy::Wavefront, merge: true, ..Default::default() };
    let traces = all_cells::<U0>("cornell", n, light);
    let mut best = (0u64, u32::MAX);
    let mesh = host_sim::scene::load("cornell").unwrap();
    let load = LoadConfig::thin(n);
    let scene = host_sim::machine::loaded::load_scene(&mesh, &load).unwrap();
    let lights = host_sim::machine::loaded::resolve_lights(&mesh, &scene, &[]).unwrap();
    let s = host_sim::machine::diffuse::source_at(0, lights[0], n).unwrap().voxel();
    for t in &traces {
        let mut per_port = [0u64; 8];
        let mut p = Parser::<U0>::new(&t.bytes);
        while let Some(ev) = p.next_event() {
            if let cell_core::trace::Event::Grant(port) = ev.unwrap() {
                per_port[port.index()] += 1;
            }
        }
        let d = t.x.abs_diff(s[0] as u32).max(t.y.abs_diff(s[1] as u32));
        for l in per_port {
            if l > best.0 || (l == best.0 && l > 0 && d < best.1) {
                best = (l, d);
            }
        }
    }
    let cfg = LightConfig { fa: 16, policy: Policy::Wavefront, merge: true, ..Default::default() };
    let (_, stats) = host_sim::machine::lighting::run_diffusion::<U0>(&mesh, &scene, &lights, &cfg, |_, _| {}).unwrap();
    let c = &stats.sources[0].counts;
    assert!(best.0 > 0);
    assert_eq!(c.peak_link_load, best.0, "peak link load");
    // Ties may pick another link at another distance; the load is what must agree.
    eprintln!(
        "peak link load {} at distance {} (traces: nearest such link at {})",
        c.peak_link_load, c.peak_link_distance, best.1
    );
    assert!(c.peak_link_distance >= best.1);
}

/// A light record round-trips: the sibling wait, the lit rule, and the frustum summary rebuilt
/// from its 64 block rows equals the summary the grid built from every dexel (the summary is a
/// function of its occupied blocks), for scenes whose blocks do and do not divide n.
#[test]
fn light_records_carry_the_wait_and_the_summary() {
    use cell_core::beam::{Source, SourceId};
    use cell_core::trace::{Event, Header, LightSetup};
    for (scene, n) in [("teapot-floor", 24), ("cow-floor", 21), ("cornell", 16)] {
        let mesh = host_sim::scene::load(scene).unwrap();
        let load = LoadConfig::thin(n);
        let loaded = host_sim::machine::loaded::load_scene(&mesh, &load).unwrap();
        let summary = host_sim::machine::diffuse::occupancy_summary(&loaded.grid, cell_core::lit::LitRule::Thesis);
        assert!(!summary.is_empty());
        let setup = LightSetup {
            source: Source::at_voxel(SourceId(0), [3, 4, 5]).unwrap(),
            n,
            depth: loaded.grid.depth,
            far: n - 1,
            policy: Policy::Wavefront,
            fa: 16,
            merge: true,
            source_bit: 1,
            skip: None,
            hold: 7,
            frustum: Some(summary),
            rule: if n % 2 == 0 { cell_core::lit::LitRule::Plane } else { cell_core::lit::LitRule::Thesis },
        };
        let header =
            Header { x: 1, y: 2, depth: loaded.grid.depth, frac_bits: 0, dexels: 64, fifo: 64, out: 3, lit: 64 };
        let mut bytes = vec![0u8; 1024];
        let a = write_event::<U0>(&Event::Header(header), &mut bytes).unwrap();
        let b = write_event::<U0>(&Event::Light(setup), &mut bytes[a..]).unwrap();
        let mut p = Parser::<U0>::new(&bytes[..a + b]);
        assert_eq!(p.next_event().unwrap().unwrap(), Event::Header(header));
        assert_eq!(p.next_event().unwrap().unwrap(), Event::Light(setup), "{scene}");
        assert!(p.next_event().is_none());
    }
}

/// The traces committed in `firmware/traces/` (what the firmware embeds when no
/// `RC2_TRACE_DIR` is given), read from disk: each one replays on the host (the cell code the
/// firmware runs) to the digest `digests.json` lists for it, with the header's cell and the
/// listed size and record count; and recording again with the command that made them
/// (`host-sim trace --n 32 --view fitted --cell 5,7 --cell 16,16 --busiest --out firmware/traces`, parsed and
/// run as the `host-sim` binary does) writes the same files, byte for byte, `digests.json`
/// included. A change to the machine that alters these traces fails here until they are
/// re-recorded.
#[test]
fn committed_firmware_traces_replay_and_re_record_byte_identically() {
    use clap::Parser as _;
    use std::collections::BTreeMap;
    use std::path::Path;

    let files_of = |dir: &Path| -> BTreeMap<String, Vec<u8>> {
        std::fs::read_dir(dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
            .collect()
    };
    let committed_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/traces");
    let committed = files_of(&committed_dir);
    let json: serde_json::Value = serde_json::from_slice(&committed["digests.json"]).expect("digests.json parses");
    let listed = json["traces"].as_array().expect("digests.json: a list under \"traces\"");
    let traces: Vec<&String> = committed.keys().filter(|f| f.ends_with(".rc2t")).collect();
    assert!(!traces.is_empty(), "no committed trace");
    let mut listed_files: Vec<&str> = listed.iter().map(|t| t["file"].as_str().expect("file")).collect();
    listed_files.sort_unstable();
    assert_eq!(listed_files, traces, "digests.json lists exactly the committed traces");

    for t in listed {
        let file = t["file"].as_str().unwrap();
        let bytes = &committed[file];
        let field = |k: &str| t[k].as_u64().unwrap_or_else(|| panic!("{file}: {k}"));
        assert_eq!(bytes.len() as u64, field("bytes"), "{file}: size");
        let want = u64::from_str_radix(t["digest"].as_str().expect("digest"), 16).expect("hex digest");
        let (digest, stats) = replay_fn::<U0>()(bytes).unwrap_or_else(|e| panic!("{file}: {e:?}"));
        assert_eq!(digest, want, "{file}: host replay {digest:016x}, digests.json {want:016x}");
        assert_eq!(stats.records as u64, field("records"), "{file}: records");
        assert!(stats.received > 0 && stats.steps > 0, "{file}: the light reached the cell ({stats:?})");
        match Parser::<U0>::new(bytes).next_event() {
            Some(Ok(cell_core::trace::Event::Header(h))) => {
                assert_eq!((h.x as u64, h.y as u64), (field("x"), field("y")), "{file}: header cell");
                assert_eq!(file, format!("cell_{}_{}.rc2t", h.x, h.y));
            }
            other => panic!("{file}: does not start with a header: {other:?}"),
        }
    }

    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("firmware-traces-rerecorded");
    let _ = std::fs::remove_dir_all(&out);
    let args = [
        "host-sim",
        "trace",
        "--n",
        "32",
        "--view",
        "fitted",
        "--cell",
        "5,7",
        "--cell",
        "16,16",
        "--busiest",
        "--out",
    ];
    let cli = host_sim::cli::Cli::try_parse_from(args.iter().copied().chain([out.to_str().unwrap()]))
        .expect("the documented command line parses");
    host_sim::cli::run(cli).expect("host-sim trace runs");
    let fresh = files_of(&out);
    assert_eq!(fresh.keys().collect::<Vec<_>>(), committed.keys().collect::<Vec<_>>(), "same files");
    for (name, bytes) in &fresh {
        assert!(
            bytes == &committed[name],
            "{name}: re-recorded ({} bytes) differs from the committed file ({} bytes); re-record \
             with `cargo run --release -p host-sim -- trace --n 32 --cell 5,7 --cell 16,16 --busiest \
             --out firmware/traces` if the change is intended",
            bytes.len(),
            committed[name].len()
        );
    }
}
