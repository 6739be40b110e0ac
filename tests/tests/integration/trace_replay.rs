//! Cell traces on the host: every cell of small grids is recorded during a real grid
//! run and replayed through a fresh `cell_core` cell (the code the firmware runs); the digest of
//! outputs and final state must equal the one the grid computed, for both scheduling policies,
//! with and without merging, with integer and fractional rays, under exact occluders with rays
//! from the light (the column's triangles in the trace, the target ray computed by the cell),
//! and for the ray phases: the
//! classic shadow rays (both lit rules, 6-, 18- and 26-connected rays, routers that refuse
//! answers) and the reflections. Altered traces must fail: any flipped byte, any truncation, a
//! re-encoded changed value, a dropped record. The traces committed for the firmware
//! (`firmware/traces/` and its `shadow-rays/`, `reflections/` and `exact/`) replay to their recorded
//! digests and are exactly what their documented commands record today.

use std::collections::BTreeMap;
use std::path::Path;

use cell_core::beam::frac::{U0, U2};
use cell_core::beam::{FracBits, Origin};
use cell_core::light::Policy;
use cell_core::lit::LitRule;
use cell_core::ray::Connectivity;
use cell_core::reflect::{HitPoint, ReflectNormal};
use cell_core::route::RoutePolicy;
use cell_core::trace::{write_event, Event, Parser};
use host_sim::jobs::trace::{record, CellTrace, TraceJob};
use host_sim::machine::grid::capacity::{FA_CAP, LIT_CAP, OB_CAP};
use host_sim::machine::lighting::diffuse::{FrustumBlocks, LightConfig};
use host_sim::machine::rays::classic::ClassicConfig;
use host_sim::machine::rays::mirror::ReflectConfig;
use host_sim::precompute::LoadConfig;
use rc2_tests::traces::{brighten_reflect_answers, flip_shadow_answers, mutate_row_material, trace_job};

type Replay = fn(&[u8]) -> Result<(u64, cell_core::trace::ReplayStats), cell_core::trace::ReplayError>;

fn replay_fn<F: FracBits>() -> Replay {
    cell_core::trace::replay::<F, { cell_core::cell::DEFAULT_DEXELS }, FA_CAP, OB_CAP, LIT_CAP>
}

fn all_cells<F: FracBits>(scene: &str, n: u32, light: LightConfig) -> Vec<CellTrace> {
    let mesh = host_sim::scene::load(scene).unwrap();
    let load = LoadConfig::thin(n);
    let cells = (0..n).flat_map(|y| (0..n).map(move |x| [x, y])).collect();
    record(&trace_job(&mesh, load, LightConfig { frac_bits: F::U32, ..light }, cells)).unwrap()
}

fn check_all<F: FracBits>(scene: &str, n: u32, policy: Policy, merge: bool, fa: usize) {
    check_all_with::<F>(
        scene,
        n,
        LightConfig { fa, policy, merge, record_visits: false, ..host_sim::config::plane_rule() },
    );
}

fn check_all_with<F: FracBits>(scene: &str, n: u32, light: LightConfig) {
    let (policy, merge) = (light.policy, light.merge);
    let traces = all_cells::<F>(scene, n, light);
    assert_eq!(traces.len(), (n * n) as usize);
    check_traces::<F>(&traces, &format!("{scene} n={n} {policy:?} merge={merge} f={}", F::U32));
}

/// Every trace replays to its digest, and the traces agree with each other.
fn check_traces<F: FracBits>(traces: &[CellTrace], what: &str) {
    let (mut beams, mut sent) = (0u64, 0u64);
    for t in traces {
        let (d, st) = replay_fn::<F>()(&t.bytes).unwrap_or_else(|e| panic!("{what}: cell ({}, {}): {e:?}", t.x, t.y));
        assert_eq!(d, t.digest, "{what}: cell ({}, {})", t.x, t.y);
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
    let light = LightConfig {
        hold: 3,
        skip_frustum: true,
        frustum_blocks: FrustumBlocks::B8,
        ..host_sim::config::plane_rule()
    };
    check_all_with::<U0>("teapot-floor", 20, light);
    check_all_with::<U2>("cornell", 16, LightConfig { hold: 8, ..light });
}

/// Exact occluders with rays from the light: every cell replays to the grid's digest, its
/// triangles from the trace, its target ray computed by the cell itself (the watertight
/// surfaces: open and closed meshes, two fraction counts).
#[test]
fn every_cell_replays_under_exact_occluders_with_rays_from_the_light() {
    let exact = LightConfig {
        rule: LitRule::Exact,
        rays: Origin::Light,
        record_visits: false,
        ..host_sim::config::plane_rule()
    };
    for (scene, n) in [("cornell", 16), ("teapot-floor", 16)] {
        let mesh = host_sim::scene::load(scene).unwrap();
        let cells = (0..n).flat_map(|y| (0..n).map(move |x| [x, y])).collect();
        let traces = record(&trace_job(&mesh, LoadConfig::watertight(n), exact, cells)).unwrap();
        let triangles: usize = traces.iter().map(|t| triangle_records(&t.bytes)).sum();
        assert!(triangles > 0, "{scene}: the cells keep triangles");
        check_traces::<U0>(&traces, &format!("{scene} n={n} exact"));
    }
    let cornell = host_sim::scene::load("cornell").unwrap();
    let cells = (0..16).flat_map(|y| (0..16).map(move |x| [x, y])).collect();
    let traces =
        record(&trace_job(&cornell, LoadConfig::watertight(16), LightConfig { frac_bits: 2, ..exact }, cells)).unwrap();
    check_traces::<U2>(&traces, "cornell n=16 exact f=2");
}

/// `render`'s visible-only lit store runs in the cell too: the light record carries it (bit 7
/// of its lit-rule byte), and every cell replays to the grid's digest under it, which differs
/// from the full store's wherever a hidden voxel is lit.
#[test]
fn every_cell_replays_under_render_s_visible_only_lit_store() {
    let exact = LightConfig {
        rule: LitRule::Exact,
        rays: Origin::Light,
        record_visits: false,
        ..host_sim::config::plane_rule()
    };
    let cornell = host_sim::scene::load("cornell").unwrap();
    let cells = || (0..16).flat_map(|y| (0..16).map(move |x| [x, y])).collect();
    let visible = LightConfig { lit_visible_only: true, ..exact };
    let traces = record(&trace_job(&cornell, LoadConfig::watertight(16), visible, cells())).unwrap();
    check_traces::<U0>(&traces, "cornell n=16 exact, visible-only lit store");
    let full = record(&trace_job(&cornell, LoadConfig::watertight(16), exact, cells())).unwrap();
    let differ = traces.iter().zip(&full).filter(|(v, f)| v.digest != f.digest).count();
    assert!(differ > 0, "the visible-only store changed no cell's digest: the test could not tell the stores apart");
    let carried = |t: &CellTrace| {
        Parser::<U0>::new(&t.bytes)
            .filter_map(|e| match e {
                Ok(Event::Light(s)) => Some(s.lit_visible_only),
                _ => None,
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(
        (carried(&traces[0]), carried(&full[0])),
        (vec![true], vec![false]),
        "the light records say which store"
    );
}

fn triangle_records(bytes: &[u8]) -> usize {
    Parser::<U0>::new(bytes).filter(|e| matches!(e, Ok(Event::Triangle(_)))).count()
}

fn busiest_trace_with(light: LightConfig) -> CellTrace {
    let mesh = host_sim::scene::load("cornell").unwrap();
    let load = LoadConfig::thin(24);
    let job = TraceJob { busiest: true, ..trace_job(&mesh, load, light, Vec::new()) };
    record(&job).unwrap().pop().unwrap()
}

fn busiest_trace() -> CellTrace {
    busiest_trace_with(LightConfig {
        fa: 16,
        policy: Policy::Wavefront,
        merge: true,
        record_visits: false,
        ..host_sim::config::plane_rule()
    })
}

/// Every flipped byte, every truncation of `t` fails to replay; every record dropped (but the
/// header and the end) fails or changes the digest — triangle records together: a triangle
/// that no ray of this cell meets changes nothing; returns how many records were dropped.
fn altered_traces_fail(t: &CellTrace) -> usize {
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
    for skip in 1..events.len() - 1 {
        let kind = events[skip][0];
        if kind == cell_core::trace::kind::TRIANGLE {
            continue;
        }
        let b: Vec<u8> = events.iter().enumerate().filter(|(i, _)| *i != skip).flat_map(|(_, e)| e.clone()).collect();
        if let Ok((d, _)) = replay(&b) {
            assert_ne!(d, t.digest, "dropping record {skip} (kind {kind:#x}) left the digest unchanged");
        }
    }
    if let Some(b) = rc2_tests::traces::drop_triangles::<U0>(&t.bytes) {
        if let Ok((d, _)) = replay(&b) {
            assert_ne!(d, t.digest, "dropping the triangle records left the digest unchanged");
        }
    }
    events.len() - 2
}

#[test]
fn every_flipped_byte_every_truncation_and_every_dropped_record_fails() {
    assert!(altered_traces_fail(&busiest_trace()) > 10);
    // Under exact occluders too: a dropped triangle record changes what the cell does.
    let exact =
        busiest_trace_with(LightConfig { rule: LitRule::Exact, rays: Origin::Light, ..host_sim::config::plane_rule() });
    assert!(triangle_records(&exact.bytes) > 0, "the busiest cell keeps triangles");
    assert!(altered_traces_fail(&exact) > 10);
}

#[test]
fn re_encoded_changes_change_the_digest() {
    let t = busiest_trace();
    let replay = replay_fn::<U0>();
    let changed = mutate_row_material::<U0>(&t.bytes).unwrap();
    assert_ne!(replay(&changed).unwrap().0, t.digest, "changed materials");
}

/// Counts of the ray-phase records of a trace: (rays received, rays taken by a neighbour,
/// answers delivered, refused cycles, phase ends).
fn ray_records(bytes: &[u8]) -> [u64; 5] {
    let mut k = [0u64; 5];
    let mut p = Parser::<U0>::new(bytes);
    while let Some(ev) = p.next_event() {
        match ev.unwrap() {
            Event::Recv { frame, .. } if frame[0] != cell_core::wire::KIND_BEAM => k[0] += 1,
            Event::Take { .. } => k[1] += 1,
            Event::ShadowAnswer(_) | Event::ReflectAnswer { .. } => k[2] += 1,
            Event::Refused => k[3] += 1,
            Event::PhaseEnd => k[4] += 1,
            _ => {}
        }
    }
    k
}

/// Record every cell of `scene` at side `n` with the classic phase `classic` or the
/// reflections `reflections`, replay each to the grid's digest; returns the ray-record totals
/// over all cells ([`ray_records`]).
fn check_ray_phase(
    scene: &str,
    n: u32,
    lights: Vec<[f64; 3]>,
    classic: Option<ClassicConfig>,
    reflections: Option<ReflectConfig>,
) -> [u64; 5] {
    let mesh = host_sim::scene::load(scene).unwrap();
    let load = LoadConfig::thin(n);
    let cells = (0..n).flat_map(|y| (0..n).map(move |x| [x, y])).collect();
    let light = LightConfig { fa: 16, policy: Policy::Wavefront, merge: true, ..host_sim::config::plane_rule() };
    let job = TraceJob { lights, classic, reflections, ..trace_job(&mesh, load, light, cells) };
    let traces = record(&job).unwrap();
    let mut total = [0u64; 5];
    for t in &traces {
        let (d, _) = replay_fn::<U0>()(&t.bytes).unwrap_or_else(|e| panic!("{scene} cell ({}, {}): {e:?}", t.x, t.y));
        assert_eq!(d, t.digest, "{scene} n={n} {classic:?} {reflections:?}: cell ({}, {})", t.x, t.y);
        for (a, b) in total.iter_mut().zip(ray_records(&t.bytes)) {
            *a += b;
        }
    }
    // Every ray a neighbour took was received: the traces agree with each other.
    assert_eq!(total[0], total[1], "{scene}: rays received against rays taken");
    assert!(total[2] > 0, "{scene}: no answer came back: {total:?}");
    total
}

fn classic(rule: LitRule, connectivity: Connectivity, all_voxels: bool, fa: usize) -> ClassicConfig {
    ClassicConfig { fa, connectivity, route: RoutePolicy::Adaptive, all_voxels, bias: 0, rule }
}

/// The classic shadow-ray phase in the cell: every cell of a 16 × 16 Cornell box replays to
/// the grid's digest under the plane rule (exact segments, 6-connected), under the thesis's
/// rule with 26- and 18-connected rays from every occupied voxel, with small FIFOs and
/// dimension-ordered routing that make routers refuse answers, with two sources, and under
/// exact occluders (the column's triangles recorded after each source's setup).
#[test]
fn every_cell_replays_the_classic_shadow_ray_phase() {
    let plane =
        check_ray_phase("cornell", 16, Vec::new(), Some(classic(LitRule::Plane, Connectivity::Six, false, 16)), None);
    assert_eq!(plane[4], 256, "one phase end per cell and source");
    assert!(plane[0] > 0, "rays crossed links");
    let mut refused = 0;
    for c in [Connectivity::TwentySix, Connectivity::Eighteen] {
        let cfg = ClassicConfig { route: RoutePolicy::DiagonalFirst, ..classic(LitRule::Thesis, c, true, 2) };
        refused += check_ray_phase("cornell", 16, Vec::new(), Some(cfg), None)[3];
    }
    assert!(refused > 0, "no router refused an answer: the Refused record went untested");
    let two = vec![[0.3, 0.8, 0.4], [0.7, 0.3, 0.6]];
    let k =
        check_ray_phase("cornell", 16, two.clone(), Some(classic(LitRule::Plane, Connectivity::Six, false, 4)), None);
    assert_eq!(k[4], 2 * 256, "one phase end per cell and source");
    // Exact occluders: each cell's triangles follow its setup record; every voxel emitting.
    let cfg =
        ClassicConfig { route: RoutePolicy::DiagonalFirst, ..classic(LitRule::Exact, Connectivity::Six, true, 2) };
    let k = check_ray_phase("cornell", 16, two, Some(cfg), None);
    assert_eq!(k[4], 2 * 256, "one phase end per cell and source");
}

fn reflections(depth: u8, normal: ReflectNormal) -> ReflectConfig {
    ReflectConfig {
        depth,
        threshold: 0.01,
        normal,
        hit: HitPoint::Centre,
        skip_own_facet: true,
        connectivity: Connectivity::Six,
        fa: 16,
        route: RoutePolicy::Adaptive,
    }
}

/// The reflection phase in the cell: every cell of a 16 × 16 Cornell box with a mirror replays
/// to the grid's digest, with facet normals to depth 4 (trees with inner nodes: answers
/// forwarded from the wait table), with 26-connected rays, FIFOs of 2 and Hall's threshold
/// cutting trees, and with the face flip (which sends every primary reflection straight back
/// up its own column: no ray crosses a link).
#[test]
fn every_cell_replays_the_reflection_phase() {
    let k = check_ray_phase("cornell-mirror", 16, Vec::new(), None, Some(reflections(4, ReflectNormal::Facet)));
    assert_eq!(k[4], 256, "one phase end per cell");
    assert!(k[0] > 0 && k[2] > k[4] / 8, "rays crossed links and trees answered: {k:?}");
    let cfg = ReflectConfig {
        fa: 2,
        threshold: 0.5,
        connectivity: Connectivity::TwentySix,
        ..reflections(4, ReflectNormal::Facet)
    };
    assert!(check_ray_phase("cornell-mirror", 16, Vec::new(), None, Some(cfg))[0] > 0, "rays crossed links");
    check_ray_phase("cornell-mirror", 16, Vec::new(), None, Some(reflections(2, ReflectNormal::Face)));
    // The rays leaving from the face they entered by and from the facet plane (§5.3.1, §5.3.3).
    for hit in [HitPoint::Edge, HitPoint::Exact] {
        let k = check_ray_phase(
            "cornell-mirror",
            16,
            Vec::new(),
            None,
            Some(ReflectConfig { hit, ..reflections(4, ReflectNormal::Facet) }),
        );
        assert!(k[0] > 0, "{hit:?}: rays crossed links");
    }
}

/// A cell of each ray phase, recorded alone: every flipped byte, every truncation and every
/// dropped record of its trace fails, and a re-encoded changed answer changes its digest.
#[test]
fn altered_ray_phase_traces_fail() {
    let record_one = |scene: &str, cell: [u32; 2], classic, reflections| {
        let mesh = host_sim::scene::load(scene).unwrap();
        let light = host_sim::config::plane_rule();
        let job = TraceJob { classic, reflections, ..trace_job(&mesh, LoadConfig::thin(16), light, vec![cell]) };
        record(&job).unwrap().pop().unwrap()
    };
    let shadow = record_one("cornell", [8, 8], Some(classic(LitRule::Plane, Connectivity::Six, false, 16)), None);
    let mirror = record_one("cornell-mirror", [10, 7], None, Some(reflections(4, ReflectNormal::Facet)));
    for t in [&shadow, &mirror] {
        let [rays, taken, answers, ..] = ray_records(&t.bytes);
        assert!(rays > 0 && taken > 0 && answers > 0, "cell ({}, {}): {:?}", t.x, t.y, ray_records(&t.bytes));
        assert!(altered_traces_fail(t) > 10);
    }
    let replay = replay_fn::<U0>();
    let unlit = flip_shadow_answers::<U0>(&shadow.bytes);
    assert_ne!(replay(&unlit.unwrap()).unwrap().0, shadow.digest, "an answer turned from lit to shadow or back");
    let brighter = brighten_reflect_answers::<U0>(&mirror.bytes);
    assert_ne!(replay(&brighter.unwrap()).unwrap().0, mirror.digest, "a reflection answer changed");
}

/// The diffusion report's peak link load (most messages one link carried one way) against the
/// per-cell traces: each `Grant(port)` record is one message leaving that cell on that link.
#[test]
fn peak_link_load_equals_the_busiest_link_in_the_traces() {
    let n = 16;
    let light = LightConfig { fa: 16, policy: Policy::Wavefront, merge: true, ..host_sim::config::plane_rule() };
    let traces = all_cells::<U0>("cornell", n, light);
    let mut best = (0u64, u32::MAX);
    let mesh = host_sim::scene::load("cornell").unwrap();
    let load = LoadConfig::thin(n);
    let scene = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &load).unwrap();
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &scene, &[]).unwrap();
    let s = host_sim::machine::lighting::diffuse::source_at(0, lights[0], n).unwrap().voxel();
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
    let cfg = LightConfig { fa: 16, policy: Policy::Wavefront, merge: true, ..host_sim::config::plane_rule() };
    let (_, stats) = host_sim::machine::lighting::run::run_diffusion(&mesh, &scene, &lights, &cfg, |_, _| {}).unwrap();
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

/// A light record round-trips: the sibling wait, the lit rule, the lit store, and the frustum summary rebuilt
/// from its 64 block rows equals the summary the grid built from every dexel (the summary is a
/// function of its occupied blocks), for scenes whose blocks do and do not divide n.
#[test]
fn light_records_carry_the_wait_and_the_summary() {
    use cell_core::beam::{Source, SourceId};
    use cell_core::trace::{Event, Header, LightSetup};
    for (scene, n) in [("teapot-floor", 24), ("cow-floor", 21), ("cornell", 16)] {
        let mesh = host_sim::scene::load(scene).unwrap();
        let load = LoadConfig::thin(n);
        let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &load).unwrap();
        let summary =
            host_sim::machine::lighting::diffuse::occupancy_summary(&loaded.grid, cell_core::lit::LitRule::Thesis);
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
            lit_visible_only: n == 21,
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

/// The committed trace sets: (directory under `firmware/traces/`, the `host-sim trace`
/// arguments that record them, the `--out` directory left out). docs/FIRMWARE.md gives the same
/// commands.
const COMMITTED: [(&str, &[&str]); 4] = [
    ("", &["--n", "32", "--view", "fitted", "--cell", "5,7", "--cell", "16,16", "--busiest"]),
    (
        "exact",
        &[
            "cornell",
            "--n",
            "32",
            "--view",
            "fitted",
            "--lit-rule",
            "exact",
            "--rays-from",
            "light",
            "--cell",
            "5,7",
            "--cell",
            "16,16",
            "--busiest",
        ],
    ),
    (
        "shadow-rays",
        &["cornell", "--n", "32", "--view", "fitted", "--lighting", "classic", "--cell", "16,16", "--cell", "20,10"],
    ),
    (
        "reflections",
        &[
            "cornell-mirror",
            "--n",
            "32",
            "--view",
            "fitted",
            "--reflections",
            "4",
            "--cell",
            "20,14",
            "--cell",
            "16,16",
        ],
    ),
];

/// The traces committed in `firmware/traces/` and the directories under it (what the firmware
/// embeds when no `RC2_TRACE_DIR` is given), read from disk: each one replays on the host (the
/// cell code the firmware runs) to the digest its `digests.json` lists for it, with the
/// header's cell and the listed size and record count; and recording again with the command
/// that made them ([`COMMITTED`], parsed and run as the `host-sim` binary does) writes the same
/// files, byte for byte, `digests.json` included. A change to the machine that alters these
/// traces fails here until they are re-recorded.
#[test]
fn committed_firmware_traces_replay_and_re_record_byte_identically() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/traces");
    let subdirs: Vec<String> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    let mut listed_sets: Vec<&str> = COMMITTED.iter().map(|(d, _)| *d).filter(|d| !d.is_empty()).collect();
    let mut on_disk: Vec<&str> = subdirs.iter().map(String::as_str).collect();
    listed_sets.sort_unstable();
    on_disk.sort_unstable();
    assert_eq!(listed_sets, on_disk, "every trace directory has its command here");
    for (sub, args) in COMMITTED {
        let committed = files_of(&root.join(sub));
        check_committed_set(sub, &committed);
        re_record(sub, args, &committed);
    }
}

/// The files of `dir` (not its directories), by name.
fn files_of(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect()
}

/// The committed set `traces/{sub}`: `digests.json` lists exactly its traces, and each one
/// replays on the host to its listed digest, size and record count, with the header's cell
/// (and, in a ray-phase set, rays in, rays out and answers).
fn check_committed_set(sub: &str, committed: &BTreeMap<String, Vec<u8>>) {
    let json: serde_json::Value = serde_json::from_slice(&committed["digests.json"]).expect("digests.json parses");
    let listed = json["traces"].as_array().expect("digests.json: a list under \"traces\"");
    let traces: Vec<&String> = committed.keys().filter(|f| f.ends_with(".rc2t")).collect();
    assert!(!traces.is_empty(), "no committed trace in traces/{sub}");
    let mut listed_files: Vec<&str> = listed.iter().map(|t| t["file"].as_str().expect("file")).collect();
    listed_files.sort_unstable();
    assert_eq!(listed_files, traces, "traces/{sub}: digests.json lists exactly the committed traces");
    for t in listed {
        let file = t["file"].as_str().unwrap();
        let bytes = &committed[file];
        let field = |k: &str| t[k].as_u64().unwrap_or_else(|| panic!("{sub}/{file}: {k}"));
        assert_eq!(bytes.len() as u64, field("bytes"), "{sub}/{file}: size");
        let want = u64::from_str_radix(t["digest"].as_str().expect("digest"), 16).expect("hex digest");
        let (digest, stats) = replay_fn::<U0>()(bytes).unwrap_or_else(|e| panic!("{sub}/{file}: {e:?}"));
        assert_eq!(digest, want, "{sub}/{file}: host replay {digest:016x}, digests.json {want:016x}");
        assert_eq!(stats.records as u64, field("records"), "{sub}/{file}: records");
        assert!(stats.received > 0 && stats.steps > 0, "{sub}/{file}: nothing reached the cell ({stats:?})");
        if sub == "exact" {
            assert!(triangle_records(bytes) > 0, "{sub}/{file}: no triangle records");
        } else if !sub.is_empty() {
            let [rays, taken, answers, ..] = ray_records(bytes);
            assert!(rays > 0 && taken > 0 && answers > 0, "{sub}/{file}: the ray phase left no trace");
        }
        match Parser::<U0>::new(bytes).next_event() {
            Some(Ok(cell_core::trace::Event::Header(h))) => {
                assert_eq!((h.x as u64, h.y as u64), (field("x"), field("y")), "{sub}/{file}: header cell");
                assert_eq!(file, format!("cell_{}_{}.rc2t", h.x, h.y));
            }
            other => panic!("{sub}/{file}: does not start with a header: {other:?}"),
        }
    }
}

/// Record `traces/{sub}` again with its command (`host-sim trace` and `args`, parsed and run as
/// the `host-sim` binary does): the same files, byte for byte.
fn re_record(sub: &str, args: &[&str], committed: &BTreeMap<String, Vec<u8>>) {
    use clap::Parser as _;
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("firmware-traces-rerecorded").join(sub);
    let _ = std::fs::remove_dir_all(&out);
    let argv = ["host-sim", "trace"].into_iter().chain(args.iter().copied()).chain(["--out", out.to_str().unwrap()]);
    let cli = host_sim::cli::Cli::try_parse_from(argv).expect("the documented command line parses");
    host_sim::cli::run(cli).expect("host-sim trace runs");
    let fresh = files_of(&out);
    assert_eq!(fresh.keys().collect::<Vec<_>>(), committed.keys().collect::<Vec<_>>(), "traces/{sub}: same files");
    for (name, bytes) in &fresh {
        assert!(
            bytes == &committed[name],
            "traces/{sub}/{name}: re-recorded ({} bytes) differs from the committed file ({} bytes); re-record \
             with `cargo run --release -p host-sim -- trace {} --out firmware/traces/{sub}` if the change is \
             intended",
            bytes.len(),
            committed[name].len(),
            args.join(" ")
        );
    }
}
