//! The grid as asynchronous boards (`host_sim::machine::lighting::boards`): B × B tiles of cells on
//! their own schedules, inter-board messages after random delays, and every phase's end
//! detected by the boards' token ring (`cell_core::termination`, Safra), not by the host.
//!
//! * the dexel stores, lit voxels and pixels equal the synchronous grid's, for several tilings
//!   and seeds (the lit set does not depend on timing);
//! * never early: with one board's links slowed down (its messages still in flight while every
//!   board is passive), no declaration is refuted by the executor's ground truth;
//! * never hanging: each declaration comes within 3N token hops of true quiescence (the bound
//!   proved in `cell_core::termination`);
//! * the mutation: the same ring without message counters declares early under that schedule.

use cell_core::beam::{Origin, Source};
use cell_core::lit::LitRule;
use cell_core::shade::NormalMode;
use host_sim::machine::lighting::boards::{run, AsyncConfig, AsyncRun, SlowBoard};
use host_sim::machine::lighting::diffuse::LightConfig;
use host_sim::machine::lighting::run::run_diffusion;
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights, LoadedScene};
use host_sim::machine::shading::pixels::{point_lights, shade_grid};
use host_sim::precompute::{prepare, LoadConfig, Prepared};
use host_sim::scene::Mesh;

/// The synchronous grid's results beside what the boards need.
struct Case {
    mesh: Mesh,
    loaded: LoadedScene,
    lights: Vec<[f64; 3]>,
    sources: Vec<Source>,
    prepared: Prepared,
    light: LightConfig,
    lit: Vec<([u32; 3], u32)>,
    visible: Vec<u32>,
    rgb: Vec<[u8; 3]>,
}

/// The Cornell box (its blocks cast shadows) at side n under two lights, on the synchronous
/// grid, with the lighting defaults less the skips that need a whole-grid reduction, its rays
/// from `rays`, under lit rule `rule`.
fn case(n: u32, rays: Origin, rule: LitRule) -> Case {
    let mesh = host_sim::scene::load("cornell").unwrap();
    let cfg = LoadConfig::watertight(n);
    let loaded = load_scene(&mesh, &cfg).unwrap();
    let lights = resolve_lights(&mesh, &loaded, &[[0.5, 0.8, 0.45], [0.2, 0.4, 0.3]]).unwrap();
    let light =
        LightConfig { skip_receding: false, skip_dead_directions: false, rays, rule, ..host_sim::config::plane_rule() };
    let sources = lights.iter().enumerate().map(|(i, p)| light.source(i, *p, n).unwrap()).collect();
    let (l, _) = run_diffusion(&mesh, &loaded, &lights, &light, |_, _| {}).unwrap();
    let img = shade_grid(&mesh, &loaded, &point_lights(&lights), &l, NormalMode::Facet);
    let visible = (0..n * n).map(|i| l.visible_mask(i % n, i / n)).collect();
    let lit = l.lit_voxels().collect();
    let prepared = prepare(&mesh, &cfg).unwrap();
    Case { mesh, loaded, lights, sources, prepared, light, lit, visible, rgb: img.rgb }
}

impl Case {
    fn run(&self, cfg: &AsyncConfig) -> AsyncRun {
        run(&self.prepared, self.loaded.grid.n, &self.sources, &self.light, cfg).unwrap()
    }

    /// For each (board side, seed): every phase declared in time, and the boards' results equal
    /// the grid's ([`Case::check_same`]); `what` names the case in messages.
    fn check_boards(&self, runs: &[(u32, u64)], what: &str) {
        for &(tile, seed) in runs {
            let r = self.run(&AsyncConfig { tile, seed, ..Default::default() });
            let what = format!("{what} B = {tile}, seed {seed}");
            check_termination(&r, 1 + self.sources.len(), &what);
            self.check_same(r, &what);
        }
    }

    /// The boards' dexel stores, lit voxels, visible-surface masks and pixels equal the grid's.
    fn check_same(&self, r: AsyncRun, what: &str) {
        let n = self.loaded.grid.n;
        for (a, b) in r.grid.cells.iter().zip(&self.loaded.grid.cells) {
            assert_eq!(a.store.dexels(), b.store.dexels(), "{what}: dexels of ({}, {})", a.x, a.y);
            assert_eq!(a.visible, b.visible, "{what}: visible surface of ({}, {})", a.x, a.y);
        }
        assert_eq!(r.lighting.lit_voxels().collect::<Vec<_>>(), self.lit, "{what}: lit voxels");
        let visible: Vec<u32> = (0..n * n).map(|i| r.lighting.visible_mask(i % n, i / n)).collect();
        assert_eq!(visible, self.visible, "{what}: lit visible surfaces");
        let loaded = LoadedScene {
            grid: r.grid,
            fit: self.loaded.fit,
            facets: self.loaded.facets,
            load_cycles: 0,
            source_face: self.loaded.source_face.clone(),
            eye: self.loaded.eye,
        };
        let img = shade_grid(&self.mesh, &loaded, &point_lights(&self.lights), &r.lighting, NormalMode::Facet);
        assert_eq!(img.rgb, self.rgb, "{what}: pixels");
    }
}

/// No early declaration, every phase declared, each within 3N token hops of quiescence.
fn check_termination(r: &AsyncRun, phases: usize, what: &str) {
    assert_eq!(r.early, None, "{what}: declared early");
    let s = &r.stats;
    assert_eq!(s.phases.iter().map(|p| p.phase as usize).collect::<Vec<_>>(), (0..phases).collect::<Vec<_>>());
    for p in &s.phases {
        assert!(p.hops_after_quiescence <= 3 * s.boards as u64, "{what}: {p:?} (N = {})", s.boards);
        assert!(p.declared_at >= p.quiet_at, "{what}: {p:?}");
    }
    eprintln!("{what}: {s:?}");
}

#[test]
fn boards_load_and_light_what_the_grid_does() {
    let c = case(32, Origin::SourceVoxel, LitRule::Plane);
    assert!(c.lit.len() > 100 && c.rgb.iter().any(|p| p[0] > 0), "a lit scene");
    c.check_boards(&[(16, 1), (16, 2), (8, 3), (8, 4)], "");
}

/// The same with rays from the light (the source cell's first splits keep beams in its column;
/// the boards' emitter waits as the grid's does).
#[test]
fn boards_light_rays_from_the_light_as_the_grid_does() {
    let c = case(32, Origin::Light, LitRule::Plane);
    assert!(c.sources.iter().all(|s| s.origin == Origin::Light));
    assert_ne!(c.lit, case(32, Origin::SourceVoxel, LitRule::Plane).lit, "these lights are off their voxels' centres");
    c.check_boards(&[(16, 5), (8, 6)], "rays from the light");
}

/// The same under exact occluders: the boards' columns keep the triangles the grid's do, and
/// each source's target rays are the grid's.
#[test]
fn boards_light_exact_occluders_as_the_grid_does() {
    let c = case(32, Origin::Light, LitRule::Exact);
    assert_ne!(c.lit, case(32, Origin::Light, LitRule::Plane).lit, "exact occluders change what is lit");
    c.check_boards(&[(16, 7), (8, 8)], "exact occluders");
}

/// Board 1's every message spends 300 to 308 ticks on its wire.
fn slow_schedule(seed: u64) -> AsyncConfig {
    let slow = Some(SlowBoard { board: 1, extra_delay: 300 });
    AsyncConfig { tile: 8, seed, slow, max_delay: 8, max_pause: 3, ..Default::default() }
}

#[test]
fn a_slow_board_never_makes_the_ring_declare_early() {
    let c = case(16, Origin::SourceVoxel, LitRule::Plane);
    for seed in [5, 6] {
        let r = c.run(&slow_schedule(seed));
        let what = format!("slow board 1, seed {seed}");
        // The schedule is adversarial: every board was passive while messages were in flight.
        assert!(r.stats.passive_in_flight > 0, "{what}: the schedule never left messages in flight alone");
        check_termination(&r, 1 + c.sources.len(), &what);
        c.check_same(r, &what);
    }
}

#[test]
fn a_ring_without_counters_declares_early() {
    // The mutation check: the same ring and schedule, the nodes told of no basic message (no
    // counters, no colours): it declares when it finds every board passive, while the slow
    // board's messages are still on the wires. The executor's ground truth catches it.
    let c = case(16, Origin::SourceVoxel, LitRule::Plane);
    let r = c.run(&AsyncConfig { counting: false, ..slow_schedule(5) });
    let early = r.early.expect("the ring without counters declared early");
    assert!(early.in_flight > 0, "{early:?}");
    eprintln!("without counters: {early:?}");
}
