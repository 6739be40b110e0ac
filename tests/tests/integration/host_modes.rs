//! The host's ways of simulating the machine change nothing the machine computes:
//! event-driven (active-cell) stepping against visiting every cell every cycle, one thread
//! against several, for the lighting phase and the loading wave; and the exact skips
//! (receding beams, dead directions) leave lit voxels and images unchanged while their dropped
//! rays are exactly rays that would have left the grid.

use cell_core::light::Policy;
use cell_core::lit::LitRule;
use cell_core::shade::NormalMode;
use host_sim::machine::lighting::diffuse::{FrustumBlocks, LightConfig, SourceReport, Stepping};
use host_sim::machine::lighting::run::run_diffusion;
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights, LoadedScene};
use host_sim::machine::shading::pixels::{point_lights, shade_grid};
use host_sim::precompute::LoadConfig;
use host_sim::report::png::write_png;
use host_sim::scene::Mesh;

/// Everything a run produces that must not depend on the host: per-source reports (cycles and
/// every counter), lit voxels with masks, and the rendered image's PNG bytes.
#[derive(Debug, PartialEq)]
struct Outcome {
    reports: Vec<SourceReport>,
    lit: Vec<([u32; 3], u32)>,
    lit_overflows: u64,
    png: Vec<u8>,
}

fn setup(scene: &str, n: u32) -> (Mesh, LoadedScene, Vec<[f64; 3]>) {
    let mesh = host_sim::scene::load(scene).unwrap();
    let cfg = LoadConfig::thin(n);
    let loaded = load_scene(&mesh, &cfg).unwrap();
    let lights = resolve_lights(&mesh, &loaded, &[]).unwrap();
    (mesh, loaded, lights)
}

fn run(s: &(Mesh, LoadedScene, Vec<[f64; 3]>), cfg: LightConfig, threads: usize) -> Outcome {
    let (mesh, loaded, lights) = s;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let (l, _) = pool.install(|| run_diffusion(mesh, loaded, lights, &cfg, |_, _| {}).unwrap());
    let img = shade_grid(mesh, loaded, &point_lights(lights), &l, NormalMode::Facet);
    let path = std::env::temp_dir().join(format!(
        "rc2-host-modes-{}-{:?}.png",
        std::process::id(),
        std::thread::current().id()
    ));
    write_png(&path, img.n, &img.rgb).unwrap();
    let png = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    Outcome { reports: l.reports.clone(), lit: l.lit_voxels().collect(), lit_overflows: l.lit_overflows(), png }
}

fn scenes() -> Vec<(Mesh, LoadedScene, Vec<[f64; 3]>)> {
    vec![setup("cornell", 40), setup("teapot-floor", 40)]
}

#[test]
fn all_cells_stepping_and_threads_give_identical_results() {
    for s in scenes() {
        for policy in [Policy::Thesis, Policy::Wavefront, Policy::Radial] {
            let cfg = LightConfig { fa: 4, policy, merge: policy.by_layer(), ..host_sim::config::plane_rule() };
            let active = run(&s, cfg, 1);
            assert!(active.reports[0].counts.beams_processed > 1000 && active.lit.len() > 100);
            let all = run(&s, LightConfig { stepping: Stepping::AllCells, ..cfg }, 1);
            assert_eq!(active, all, "{}: {policy:?}, active vs all-cells stepping", s.0.name);
            for threads in [2, 3] {
                let par = run(&s, cfg, threads);
                assert_eq!(active, par, "{}: {policy:?}, 1 vs {threads} threads", s.0.name);
            }
            let par_all = run(&s, LightConfig { stepping: Stepping::AllCells, ..cfg }, 2);
            assert_eq!(active, par_all, "{}: {policy:?}, all-cells stepping on 2 threads", s.0.name);
        }
    }
}

#[test]
fn skips_change_no_lit_voxel_and_no_pixel() {
    let mut skipped_somewhere = false;
    for s in scenes() {
        // One summary resolution per policy: all three are covered at no extra cost.
        for (policy, frustum_blocks) in [
            (Policy::Thesis, FrustumBlocks::B8),
            (Policy::Wavefront, FrustumBlocks::B16),
            (Policy::Radial, FrustumBlocks::B32),
        ] {
            let on = LightConfig {
                fa: 4,
                policy,
                merge: policy.by_layer(),
                skip_frustum: true,
                frustum_blocks,
                ..host_sim::config::plane_rule()
            };
            let off = LightConfig { skip_receding: false, skip_dead_directions: false, skip_frustum: false, ..on };
            let (a, b) = (run(&s, on, 2), run(&s, off, 2));
            assert_eq!(a.lit, b.lit, "{}: lit voxels", s.0.name);
            assert_eq!(a.png, b.png, "{}: image", s.0.name);
            for (x, y) in a.reports.iter().zip(&b.reports) {
                let (x, y) = (&x.counts, &y.counts);
                assert_eq!(y.rays_skipped, 0);
                assert_eq!((x.rays_emitted, x.rays_absorbed), (y.rays_emitted, y.rays_absorbed));
                assert_eq!(x.rays_exited + x.rays_skipped, y.rays_exited, "skipped rays are rays that exit");
                // Fewer beams to move is not a theorem: merges depend on when pieces meet, and
                // a skip shifts the schedule. Under the radial pick it does not hold (Cornell
                // n = 40: 86 499 beams with the skips, 83 360 without, yet fewer messages).
                if policy != Policy::Radial {
                    assert!(
                        x.beams_processed <= y.beams_processed && x.messages <= y.messages,
                        "{}: {policy:?}: {} vs {} beams, {} vs {} messages",
                        s.0.name,
                        x.beams_processed,
                        y.beams_processed,
                        x.messages,
                        y.messages
                    );
                }
                skipped_somewhere |= x.rays_skipped > 0;
            }
            // Each skip alone is exact too.
            let only = LightConfig { skip_receding: false, skip_dead_directions: false, ..on };
            for one in [
                LightConfig { skip_dead_directions: false, skip_frustum: false, ..on },
                LightConfig { skip_receding: false, skip_frustum: false, ..on },
                only,
            ] {
                let c = run(&s, one, 1);
                assert_eq!((&c.lit, &c.png), (&a.lit, &a.png), "{}: {one:?}", s.0.name);
            }
        }
    }
    assert!(skipped_somewhere, "the skips dropped something on an open scene");
}

/// The empty-frustum skip on an open scene: most rays that would leave the grid are dropped
/// early (the default 32 × 32 × 32 summary), the lit set is unchanged, and the machine processes
/// fewer beams.
#[test]
fn frustum_skip_drops_beams_that_light_nothing() {
    let s = setup("teapot-floor", 48);
    let base = LightConfig { skip_receding: false, skip_dead_directions: false, ..host_sim::config::plane_rule() };
    let (off, on) = (run(&s, base, 2), run(&s, LightConfig { skip_frustum: true, ..base }, 2));
    assert_eq!((&on.lit, &on.png), (&off.lit, &off.png));
    let (a, b) = (&on.reports[0].counts, &off.reports[0].counts);
    assert_eq!(a.rays_exited + a.rays_skipped, b.rays_exited, "skipped rays are rays that exit");
    assert!(a.rays_skipped * 10 > b.rays_exited * 9, "{} of {} exiting rays skipped", a.rays_skipped, b.rays_exited);
    assert!(a.beams_processed * 10 < b.beams_processed * 8, "{} vs {} beams", a.beams_processed, b.beams_processed);
}

#[test]
fn loading_wave_all_cells_equals_active_cells() {
    for (scene, n) in [("cornell", 32), ("teapot", 48), ("cow-floor", 40)] {
        let mesh = host_sim::scene::load(scene).unwrap();
        let cfg = LoadConfig::watertight(n);
        let packets = host_sim::precompute::prepare(&mesh, &cfg).unwrap().packets;
        let mut a = host_sim::machine::grid::Grid::<64>::new(n, n);
        let mut b = host_sim::machine::grid::Grid::<64>::new(n, n);
        let ra = a.load_wave(&packets, |_| {});
        let rb = b.load_wave_all_cells(&packets);
        assert_eq!(ra, rb, "{scene}: cycles and message counts");
        assert!(ra.row_steps > 0);
        for (ca, cb) in a.cells.iter().zip(&b.cells) {
            assert_eq!(ca.store.dexels(), cb.store.dexels(), "{scene}: cell ({}, {})", ca.x, ca.y);
        }
    }
}

/// Keeping lit marks for visible voxels only (`--lit-visible-only`) is a skip of work no one
/// sees: the image bytes and cycles are those of the full lit store. Under the thesis's and the
/// plane rule the lit set is exactly the full one restricted to the voxels the image reads —
/// each column's first occupied voxel, the two voxels bracketing its visible surface. Under
/// exact occluders the two stores answer different questions (the pixels' target rays; every
/// occupied voxel's own ray, `receiver::voxel_ray`): the visible-only store holds one mark per
/// lit pixel and light, at its target voxel (some in front of the surface), and the full one
/// marks occupied voxels only.
#[test]
fn visible_only_lit_store_gives_the_same_image() {
    let mut in_front_lit = 0;
    for (scene, n) in [("cornell", 64), ("teapot-floor", 24), ("bureau1", 32)] {
        let s = setup(scene, n);
        for rule in [LitRule::Thesis, LitRule::Plane, LitRule::Exact] {
            let full = run(&s, LightConfig { rule, ..host_sim::config::plane_rule() }, 2);
            let vis = run(&s, LightConfig { lit_visible_only: true, rule, ..host_sim::config::plane_rule() }, 2);
            assert_eq!(vis.png, full.png, "{scene} {rule:?}: image");
            let cycles = |o: &Outcome| o.reports.iter().map(|r| r.counts.cycles).collect::<Vec<_>>();
            assert_eq!(cycles(&vis), cycles(&full), "{scene} {rule:?}: the machine does the same work");
            let grid = &s.1.grid;
            let visible = |p: &[u32; 3]| {
                let c = grid.cell(p[0], p[1]);
                match rule {
                    LitRule::Thesis => c.store.dexels().first().is_some_and(|d| d.span.lo as u32 == p[2]),
                    LitRule::Plane => c.visible.is_some_and(|v| v.brackets(p[2] as i64)),
                    LitRule::Exact => c.visible.is_some_and(|v| v.receives(p[2] as i64)),
                }
            };
            match rule {
                LitRule::Exact => {
                    let occupied = |p: &[u32; 3]| grid.cell(p[0], p[1]).store.occupied(p[2] as u16).is_some();
                    assert!(full.lit.iter().all(|(p, _)| occupied(p)), "{scene}: the full store marks occupied voxels");
                    assert!(vis.lit.iter().all(|(p, _)| visible(p)), "{scene}: target voxels only");
                    // One mark per lit pixel and light: a column's marks are its pixel's mask.
                    let mut per_column = std::collections::BTreeMap::new();
                    for (p, m) in &vis.lit {
                        let e = per_column.entry([p[0], p[1]]).or_insert(0u64);
                        assert_eq!(*e & *m as u64, 0, "{scene}: a light marks one target voxel per column");
                        *e |= *m as u64;
                    }
                    assert!(
                        !per_column.is_empty() && full.lit.len() > vis.lit.len(),
                        "{scene}: both stores hold marks"
                    );
                    let in_front =
                        |p: &[u32; 3]| grid.cell(p[0], p[1]).visible.is_some_and(|v| v.z_v as i64 - 1 == p[2] as i64);
                    in_front_lit += vis.lit.iter().filter(|(p, _)| in_front(p)).count();
                }
                _ => {
                    let want: Vec<_> = full.lit.iter().filter(|(p, _)| visible(p)).cloned().collect();
                    assert_eq!(vis.lit, want, "{scene} {rule:?}: lit set restricted to visible voxels");
                    assert!(
                        want.len() < full.lit.len(),
                        "{scene}: hidden lit voxels exist, so the test compares something"
                    );
                }
            }
        }
    }
    assert!(in_front_lit > 0, "some target ray arrives in front of its surface, so the test keeps those marks");
}

/// The sibling wait (`--hold`) is exact: the same lit voxels and image for every wait, fewer
/// beams processed (pieces of one voxel merge), and its host shortcut — held cells with nothing
/// to send are not visited until their wait ends or a beam arrives — gives the counters of the
/// all-cells reference, on 1 or 2 threads.
#[test]
fn sibling_wait_is_exact_and_merges() {
    for (scene, n) in [("cornell", 40), ("teapot-floor", 40), ("cow-floor", 32)] {
        let s = setup(scene, n);
        let off = run(&s, host_sim::config::plane_rule(), 2);
        for hold in [2, 3, 8] {
            let cfg = LightConfig { hold, ..host_sim::config::plane_rule() };
            let on = run(&s, cfg, 1);
            assert_eq!((&on.lit, &on.png), (&off.lit, &off.png), "{scene}: hold {hold}: lit voxels and image");
            let (a, b) = (&on.reports[0].counts, &off.reports[0].counts);
            assert_eq!(
                (a.rays_absorbed, a.rays_exited, a.rays_skipped),
                (b.rays_absorbed, b.rays_exited, b.rays_skipped)
            );
            assert!(a.held_cell_cycles > 0, "{scene}: hold {hold}: some cell waited");
            assert!(
                a.beams_processed < b.beams_processed,
                "{scene}: hold {hold}: {} ≥ {} beams",
                a.beams_processed,
                b.beams_processed
            );
            let all = run(&s, LightConfig { stepping: Stepping::AllCells, ..cfg }, 2);
            assert_eq!(on, all, "{scene}: hold {hold}: active (sleeping held cells) vs all-cells stepping");
            assert_eq!(on, run(&s, cfg, 2), "{scene}: hold {hold}: 1 vs 2 threads");
        }
    }
}

/// The hidden-voxel skip drops the beams that can reach no visible voxel: the visible lit set
/// and the image are those of the same run without it (itself the full lit set restricted to
/// visible voxels, `lit_visible_only` above), under both by-layer policies; the rays it drops
/// are rays the run without it absorbed in hidden voxels or let out, and it drops some on the
/// Cornell box (whose walls are seen edge-on: almost all of them is hidden).
#[test]
fn hidden_skip_keeps_the_visible_lit_set_and_the_image() {
    for s in scenes() {
        for policy in [Policy::Wavefront, Policy::Radial] {
            let visible =
                LightConfig { fa: 4, policy, merge: true, lit_visible_only: true, ..host_sim::config::plane_rule() };
            let a = run(&s, visible, 2);
            assert!(!a.lit.is_empty());
            // Beams processed on the Cornell box per summary resolution.
            let mut beams = Vec::new();
            for frustum_blocks in [FrustumBlocks::B8, FrustumBlocks::B16, FrustumBlocks::B32] {
                let hidden = LightConfig { skip_hidden: true, frustum_blocks, ..visible };
                let b = run(&s, hidden, 2);
                assert_eq!(a.lit, b.lit, "{}: {policy:?}, {frustum_blocks:?}: visible lit voxels", s.0.name);
                assert_eq!(a.png, b.png, "{}: {policy:?}, {frustum_blocks:?}: image", s.0.name);
                beams.push(b.reports[0].counts.beams_processed);
                for (x, y) in a.reports.iter().zip(&b.reports) {
                    let (x, y) = (&x.counts, &y.counts);
                    assert_eq!(x.rays_emitted, y.rays_emitted);
                    assert_eq!(y.rays_emitted, y.rays_absorbed + y.rays_exited + y.rays_skipped, "conservation");
                    assert!(y.rays_absorbed <= x.rays_absorbed && y.rays_exited <= x.rays_exited + x.rays_skipped);
                    if s.0.name == "cornell" {
                        assert!(
                            y.rays_skipped > x.rays_skipped && y.beams_processed < x.beams_processed,
                            "{policy:?}: {x:?} / {y:?}"
                        );
                    }
                }
            }
            // Finer blocks see past more of the hidden walls (at n = 40, 32 blocks are 2-voxel
            // blocks, 8 are 5-voxel ones).
            if s.0.name == "cornell" {
                assert!(beams[2] < beams[0], "{policy:?}: beams with 8, 16, 32 blocks: {beams:?}");
            }
        }
    }
    // Without `lit_visible_only` the skip would lose hidden voxels' light: refused.
    let s = setup("cornell", 16);
    let cfg = LightConfig { skip_hidden: true, ..host_sim::config::plane_rule() };
    let Err(err) = run_diffusion(&s.0, &s.1, &s.2, &cfg, |_, _| {}) else {
        panic!("the hidden-voxel skip ran without --lit-visible-only");
    };
    let err = err.to_string();
    assert!(err.contains("--lit-visible-only"), "{err}");
}

/// The oracle skip (a measurement: the host drops every beam that carries no pixel's target
/// ray, or whose voxel is on none) leaves the render's visible lit set and image as they are,
/// on 1 or 2 threads, and its dropped rays are counted (conservation); the per-ray oracle drops
/// at least what the per-voxel one does, and both drop beams on every scene. Without exact
/// occluders and the visible-only store it is refused.
#[test]
fn the_oracle_skip_keeps_the_image() {
    use host_sim::machine::lighting::diffuse::OracleSkip;
    for (scene, n) in [("cornell", 48), ("teapot-floor", 40), ("bureau1", 48)] {
        let s = setup(scene, n);
        let render = host_sim::config::Preset::Render.light();
        let off = run(&s, render, 2);
        let mut beams = Vec::new();
        for skip in [OracleSkip::Voxels, OracleSkip::Rays] {
            let on = run(&s, LightConfig { oracle_skip: skip, ..render }, 1);
            assert_eq!((&on.lit, &on.png), (&off.lit, &off.png), "{scene}: {skip:?}: visible lit set and image");
            assert_eq!(
                on,
                run(&s, LightConfig { oracle_skip: skip, ..render }, 2),
                "{scene}: {skip:?}: 1 vs 2 threads"
            );
            let (a, b) = (&on.reports[0].counts, &off.reports[0].counts);
            assert_eq!(a.rays_emitted, a.rays_absorbed + a.rays_exited + a.rays_skipped, "{scene}: conservation");
            assert!(a.rays_skipped > b.rays_skipped, "{scene}: {skip:?} drops rays");
            beams.push(a.beams_processed);
        }
        let all = off.reports[0].counts.beams_processed;
        assert!(beams[1] <= beams[0] && beams[0] < all, "{scene}: beams rays ≤ voxels < off: {beams:?} / {all}");
    }
    let s = setup("cornell", 16);
    let cfg = LightConfig { oracle_skip: OracleSkip::Rays, ..host_sim::config::Preset::Light.light() };
    let Err(err) = run_diffusion(&s.0, &s.1, &s.2, &cfg, |_, _| {}) else {
        panic!("the oracle skip ran with the full lit store");
    };
    assert!(err.to_string().contains("--oracle-skip"), "{err}");
}
