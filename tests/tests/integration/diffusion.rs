//! Light diffusion by beam subdivision (thesis ch. 4), against the independent
//! per-ray oracle `rc2_tests::oracle::rays` (every ray of the lattice traced on its own):
//! the lit voxels, their source masks and the ray counts must be identical, for any scene,
//! sources, fraction bits f, FIFO size FA, policy, merging and timing rules (`Timing`: the
//! thesis-timing variant and every knob). Also: coverage of the empty scene, conservation,
//! termination on adversarial sources, and the cycle counts we claim.

use cell_core::beam::{Direction, FarDistance, FracBits, Origin, Source, SourceCoord, SourceId};
use cell_core::light::Policy;
use cell_core::lit::LitRule;
use cell_core::occluder::Triangle;
use cell_core::receiver::{crosses_any, target, voxel_ray, POINT_UNITS};
use host_sim::machine::grid::triangles::ColumnTriangles;
use host_sim::machine::grid::Grid;
use host_sim::machine::lighting::diffuse::{diffuse, LightConfig, Lighting};
use host_sim::machine::lighting::timing::{Emission, Timing};
use host_sim::precompute::{LoadConfig, Q};
use proptest::prelude::*;
use rc2_tests::oracle::exact;
use rc2_tests::oracle::lit::{trace_all_plane, trace_all_plane_naive_from};
use rc2_tests::oracle::rays::{dir_axes, RayOutcome};
use rc2_tests::oracle::rays::{trace_all, trace_all_naive_from, RaysFrom};
use std::collections::{BTreeMap, BTreeSet};

type G = Grid<64>;

use crate::common;

fn grid_with(n: u32, tris: &[[[i64; 3]; 3]]) -> G {
    let cfg = LoadConfig::watertight(n);
    let mut g = G::new(n, n);
    g.load_wave(&common::packets_of(tris, &cfg), |_| {});
    let polygons: Vec<Vec<[i64; 3]>> = tris.iter().map(|t| t.to_vec()).collect();
    g.triangles = ColumnTriangles::from_polygons(&polygons, n).expect("triangles in range");
    g
}

/// The exact-occluder oracle's lighting of `g` (`rc2_tests::oracle::exact`, every ray walked
/// on its own against the scene's triangles): the rays' fates, the visible surfaces lit (a
/// column is lit by a source iff its target ray, `cell_core::receiver::target`, reaches its
/// layer) and, as lit voxels, the target voxels of the lit columns.
fn exact_oracle<F: FracBits>(g: &G, src16: &[[i64; 3]], origin: Origin) -> (RayOutcome, BTreeMap<[i64; 2], u64>) {
    let n = g.n as i64;
    let from = match origin {
        Origin::SourceVoxel => RaysFrom::Voxel,
        Origin::Light => RaysFrom::Light,
    };
    // The scene's triangles, from the columns that keep them (voxel-centre sixteenths).
    let tris = scene_triangles(g);
    let scene = exact::Scene::new(n, &tris);
    let far = FarDistance::<F>::new(g.n - 1).expect("far distance");
    let mut out = RayOutcome { lit: BTreeMap::new(), rays_emitted: 0, rays_absorbed: 0, rays_exited: 0 };
    let mut visible = BTreeMap::new();
    for (si, &s) in src16.iter().enumerate() {
        let counts = exact::trace_all_exact(&scene, s, from, F::U32);
        out.rays_absorbed += counts.stopped;
        out.rays_exited += counts.exited;
        out.rays_emitted += counts.stopped + counts.exited;
        let source = sources(&[s])[0].with_origin(origin);
        for c in &g.cells {
            let Some(t) = c.visible.as_ref().and_then(|v| target(c.x as i32, c.y as i32, v, &source, far)) else {
                continue;
            };
            let dir = (0..6).find(|&d| oracle_direction(d) == t.dir).expect("six directions");
            let fate = exact::trace_ray_exact(&scene, s, from, F::U32, dir, t.a, t.b);
            // A triangle kept by the column or one of its 8 neighbours crossing the contact
            // segment shadows the pixel.
            let contact = contact_shadowed(&scene, [c.x as i64, c.y as i64], &t);
            if exact::reaches(fate, t.layer as i64) && !contact {
                *visible.entry([c.x as i64, c.y as i64]).or_insert(0) |= 1u64 << si;
            }
        }
        // The full lit store: each occupied voxel whose own ray (`receiver::voxel_ray`, itself
        // checked against every ray of the face in cell-core) reaches it, traced exactly.
        for c in &g.cells {
            for d in c.store.dexels() {
                for z in d.span.lo..=d.span.hi {
                    let Some(t) = voxel_ray(c.x as i32, c.y as i32, z as i64, &source, far) else { continue };
                    let dir = (0..6).find(|&d| oracle_direction(d) == t.dir).expect("six directions");
                    if exact::reaches(exact::trace_ray_exact(&scene, s, from, F::U32, dir, t.a, t.b), t.layer as i64) {
                        *out.lit.entry([c.x as i64, c.y as i64, z as i64]).or_insert(0) |= 1u64 << si;
                    }
                }
            }
        }
    }
    (out, visible)
}

/// The scene's triangles, from the columns that keep them (voxel-centre sixteenths).
fn scene_triangles(g: &G) -> Vec<[[i64; 3]; 3]> {
    let tris: BTreeSet<[[i64; 3]; 3]> = (0..g.n)
        .flat_map(|y| (0..g.n).map(move |x| (x, y)))
        .flat_map(|(x, y)| g.triangles.column(x, y).iter().map(|t| t.vertices().map(|v| v.map(i64::from))))
        .collect();
    tris.into_iter().collect()
}

/// Whether a triangle kept by column `[x, y]` or one of its 8 neighbours crosses target `t`'s
/// contact segment (the oracle's rational crossing test): the pixel is in a contact shadow.
fn contact_shadowed(scene: &exact::Scene<'_>, [x, y]: [i64; 2], t: &cell_core::receiver::Target) -> bool {
    let n = scene.n;
    let kept: Vec<usize> = (y - 1..=y + 1)
        .flat_map(|v| (x - 1..=x + 1).map(move |u| (u, v)))
        .filter(|&(u, v)| (0..n).contains(&u) && (0..n).contains(&v))
        .flat_map(|(u, v)| scene.kept(u, v).iter().copied())
        .collect();
    t.contact.is_some_and(|[x0, x1]| {
        kept.iter().any(|&i| exact::segment_crosses(&scene.triangles[i], x0, x1, POINT_UNITS / 16))
    })
}

/// A random exact-occluder case of the proptests: triangles on the loading lattice (`raw_tris`
/// in 0..=20, scaled to 0.8·n voxels), sources anywhere (`raw_src` in 0..=1000 of the grid),
/// rays from the light (with the FIFO it needs) or the source voxel.
fn exact_case(
    n: u32,
    raw_tris: &[[[i64; 3]; 3]],
    raw_src: &[[i64; 3]],
    light_origin: bool,
    cfg: LightConfig,
) -> (G, Vec<[i64; 3]>, LightConfig) {
    let tris: Vec<[[i64; 3]; 3]> = raw_tris.iter().map(|t| t.map(|p| p.map(|c| c * 8 * n as i64 / 10))).collect();
    let src16: Vec<[i64; 3]> = raw_src.iter().map(|p| p.map(|c| c * 16 * (n as i64 - 1) / 1000)).collect();
    let (rays, fa) = match light_origin {
        true => (Origin::Light, cfg.fa.max(cell_core::light::MIN_FA_FROM_LIGHT)),
        false => (Origin::SourceVoxel, cfg.fa),
    };
    (grid_with(n, &tris), src16, LightConfig { rays, fa, ..cfg })
}

/// The cell's direction of the oracle's face `dir`.
fn oracle_direction(dir: usize) -> Direction {
    let (w, sign, _, _) = dir_axes(dir);
    Direction::ALL.into_iter().find(|d| d.principal().index() == w && d.sign() as i64 == sign).expect("six faces")
}

fn sources(src16: &[[i64; 3]]) -> Vec<Source> {
    src16
        .iter()
        .enumerate()
        .map(|(i, p)| Source::new(SourceId(i as u16), p.map(|c| SourceCoord::from_bits(c as i32))))
        .collect()
}

fn light<F: FracBits>(g: &G, src16: &[[i64; 3]], cfg: LightConfig) -> Lighting {
    let sources: Vec<Source> = sources(src16).into_iter().map(|s| s.with_origin(cfg.rays)).collect();
    let cfg = LightConfig { frac_bits: F::U32, ..cfg };
    diffuse(g, &sources, &cfg, |_, _| {}).expect("diffusion terminates without loss")
}

/// The columns whose visible surface the diffusion lit, with their source masks.
fn visible_lit(l: &Lighting) -> BTreeMap<[i64; 2], u64> {
    l.cells.iter().filter(|c| c.visible_lit != 0).map(|c| ([c.x as i64, c.y as i64], c.visible_lit as u64)).collect()
}

/// Beam diffusion == per-ray tracing under the configured lit rule: lit voxels, masks, the
/// visible surfaces' masks (plane rule), and every ray count.
fn check_against_rays<F: FracBits>(g: &G, src16: &[[i64; 3]], cfg: LightConfig) -> Result<(), TestCaseError> {
    let n = g.n as i64;
    let l = light::<F>(g, src16, cfg);
    let occupied = |x: i64, y: i64, z: i64| g.cell(x as u32, y as u32).store.occupied(z as u16).is_some();
    let want = match (cfg.rule, cfg.rays) {
        (LitRule::Thesis, Origin::SourceVoxel) => trace_all(n, &occupied, src16, n - 1, F::U32),
        (LitRule::Thesis, Origin::Light) => trace_all_naive_from(RaysFrom::Light, n, &occupied, src16, n - 1, F::U32),
        (LitRule::Plane, origin) => {
            let (surfaces, columns) = (common::surfaces_of(g), common::columns_of(g));
            let o = match origin {
                Origin::SourceVoxel => trace_all_plane(n, &surfaces, &columns, src16, n - 1, F::U32),
                Origin::Light => {
                    trace_all_plane_naive_from(RaysFrom::Light, n, &surfaces, &columns, src16, n - 1, F::U32)
                }
            };
            prop_assert_eq!(&visible_lit(&l), &o.visible, "visible surfaces lit differ (f = {}, {:?})", F::U32, cfg);
            o.rays
        }
        (LitRule::Exact, origin) => {
            let (rays, visible) = exact_oracle::<F>(g, src16, origin);
            prop_assert_eq!(&visible_lit(&l), &visible, "visible surfaces lit differ (f = {}, {:?})", F::U32, cfg);
            rays
        }
    };
    let got: BTreeMap<[i64; 3], u64> = l.lit_voxels().map(|(v, m)| (v.map(|c| c as i64), m as u64)).collect();
    prop_assert_eq!(&got, &want.lit, "lit sets differ (f = {}, {:?})", F::U32, cfg);
    let emitted: u128 = l.reports.iter().map(|r| r.counts.rays_emitted).sum();
    let absorbed: u128 = l.reports.iter().map(|r| r.counts.rays_absorbed).sum();
    // Rays the skips dropped are rays that would have exited without meeting a voxel.
    let exited: u128 = l.reports.iter().map(|r| r.counts.rays_exited + r.counts.rays_skipped).sum();
    prop_assert_eq!((emitted, absorbed, exited), (want.rays_emitted, want.rays_absorbed, want.rays_exited));
    for r in &l.reports {
        let c = &r.counts;
        prop_assert_eq!(c.rays_emitted, c.rays_absorbed + c.rays_exited + c.rays_skipped, "conservation");
        prop_assert!(r.counts.cycles >= r.counts.lower_bound, "T ≥ LB");
    }
    Ok(())
}

/// Every combination of the timing knobs (link rate 1–3, register, free ports, emission
/// order, burst): 48 rule sets.
fn all_timings() -> Vec<Timing> {
    let mut all = Vec::new();
    for link_rate in 1..=3 {
        for bits in 0..16u8 {
            let emission = if bits & 4 != 0 { Emission::ZFirst } else { Emission::XyFirst };
            let (register, free_ports, burst) = (bits & 1 != 0, bits & 2 != 0, bits & 8 != 0);
            all.push(Timing { link_rate, register, free_ports, emission, burst });
        }
    }
    all
}

fn config() -> impl Strategy<Value = LightConfig> {
    config_of(vec![LitRule::Thesis, LitRule::Plane])
}

/// [`config`] drawing its lit rule from `rules`.
fn config_of(rules: Vec<LitRule>) -> impl Strategy<Value = LightConfig> {
    (
        prop::sample::select(vec![1usize, 2, 3, 5, 16, 64]),
        prop::sample::select(vec![Policy::Thesis, Policy::Wavefront, Policy::Radial]),
        any::<bool>(),
        any::<bool>(),
        prop::sample::select(rules),
        prop::sample::select(all_timings()),
    )
        .prop_map(|(fa, policy, merge, skip, rule, timing)| LightConfig {
            // An input register takes one FIFO slot of the compiled capacity.
            fa: fa.min(64 - timing.register as usize),
            timing,
            policy,
            merge,
            record_visits: false,
            skip_receding: skip,
            skip_dead_directions: skip,
            rule,
            ..host_sim::config::plane_rule()
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn random_scenes_match_per_ray_tracing(
        n in 5u32..=11,
        raw_tris in prop::collection::vec(prop::array::uniform3(prop::array::uniform3(0i64..=1000)), 0..4),
        raw_src in prop::collection::vec([0i64..=1000, 0..=1000, 0..=1000], 1..4),
        f in prop::sample::select(vec![0u32, 2, 4, 8]),
        cfg in config(),
    ) {
        let m = Q * n as i64;
        let tris: Vec<[[i64; 3]; 3]> = raw_tris.iter().map(|t| t.map(|p| p.map(|c| c * m / 1000))).collect();
        let src16: Vec<[i64; 3]> = raw_src.iter().map(|p| p.map(|c| c * 16 * (n as i64 - 1) / 1000)).collect();
        let g = grid_with(n, &tris);
        cell_core::with_frac_bits!(f, F => check_against_rays::<F>(&g, &src16, cfg)).unwrap()?;
    }

    /// Exact occluders (`LitRule::Exact`): a ray stops where its segment meets a triangle the
    /// columns of its two voxels keep, a pixel is lit iff its target ray gets there — against
    /// the oracle that walks each ray against the triangles (`oracle::exact`), for both ray
    /// origins, every policy, FIFO size, merging, skip and timing. Facets on the loading
    /// lattice, so rays through edges and vertices are common.
    #[test]
    fn exact_occluders_match_per_ray_tracing(
        n in 5u32..=11,
        raw_tris in prop::collection::vec(prop::array::uniform3(prop::array::uniform3(0i64..=20)), 0..6),
        raw_src in prop::collection::vec([0i64..=1000, 0..=1000, 0..=1000], 1..3),
        light_origin in any::<bool>(),
        f in prop::sample::select(vec![0u32, 1, 2]),
        cfg in config_of(vec![LitRule::Exact]),
    ) {
        let (g, src16, cfg) = exact_case(n, &raw_tris, &raw_src, light_origin, cfg);
        cell_core::with_frac_bits!(f, F => check_against_rays::<F>(&g, &src16, cfg)).unwrap()?;
    }

    /// Rays from the light (`Origin::Light`: each face's layers on the voxel centre planes
    /// ahead of the light, the first split possibly inside the source voxel's slab) under both
    /// lit rules, against the per-ray oracles that walk each ray from that definition; sources
    /// anywhere on the 1/16 lattice, on voxel boundaries included.
    #[test]
    fn rays_from_the_light_match_per_ray_tracing(
        n in 5u32..=11,
        raw_tris in prop::collection::vec(prop::array::uniform3(prop::array::uniform3(0i64..=1000)), 0..4),
        raw_src in prop::collection::vec([0i64..=1000, 0..=1000, 0..=1000], 1..3),
        boundary in any::<bool>(),
        f in prop::sample::select(vec![0u32, 1, 2]),
        cfg in config_of(vec![LitRule::Thesis, LitRule::Plane, LitRule::Exact]),
    ) {
        let m = Q * n as i64;
        let tris: Vec<[[i64; 3]; 3]> = raw_tris.iter().map(|t| t.map(|p| p.map(|c| c * m / 1000))).collect();
        let src16: Vec<[i64; 3]> = raw_src
            .iter()
            .map(|p| p.map(|c| {
                // Inside the grid: a boundary source rounds up, so not on the last one.
                let c = c * 16 * (n as i64 - 1) / 1000;
                let b = c - c.rem_euclid(16) + 8;
                match (boundary, b > 16 * (n as i64 - 1)) {
                    (false, _) => c,
                    (true, false) => b,
                    (true, true) => b - 16,
                }
            }))
            .collect();
        let g = grid_with(n, &tris);
        // The source cell's first split may keep four slots (`MIN_FA_FROM_LIGHT`).
        let fa = cfg.fa.max(cell_core::light::MIN_FA_FROM_LIGHT);
        let cfg = LightConfig { rays: Origin::Light, fa, ..cfg };
        cell_core::with_frac_bits!(f, F => check_against_rays::<F>(&g, &src16, cfg)).unwrap()?;
    }
}

/// Sources on faces, edges and corners of the grid, and inside an object; beams that leave at
/// once; a closed box around the source. Each must terminate, conserve rays and match the oracle.
#[test]
fn adversarial_sources() {
    let n = 10u32;
    let m = Q * n as i64;
    let top = 16 * (n as i64 - 1);
    // A closed cube of 12 triangles around the centre, and a floor.
    let (a, b) = (3 * Q, 7 * Q);
    let c = |x, y, z| [x, y, z];
    let cube = [
        [c(a, a, a), c(b, a, a), c(b, b, a)],
        [c(a, a, a), c(b, b, a), c(a, b, a)],
        [c(a, a, b), c(b, b, b), c(b, a, b)],
        [c(a, a, b), c(a, b, b), c(b, b, b)],
        [c(a, a, a), c(a, b, a), c(a, b, b)],
        [c(a, a, a), c(a, b, b), c(a, a, b)],
        [c(b, a, a), c(b, b, b), c(b, b, a)],
        [c(b, a, a), c(b, a, b), c(b, b, b)],
        [c(a, a, a), c(b, a, b), c(b, a, a)],
        [c(a, a, a), c(a, a, b), c(b, a, b)],
        [c(a, b, a), c(b, b, a), c(b, b, b)],
        [c(a, b, a), c(b, b, b), c(a, b, b)],
    ];
    let floor = [[c(0, 0, 8), c(m, 0, 8), c(m, m, 8)], [c(0, 0, 8), c(m, m, 8), c(0, m, 8)]];
    let scenes: Vec<(&str, Vec<[[i64; 3]; 3]>)> =
        vec![("empty", vec![]), ("cube", cube.to_vec()), ("floor", floor.to_vec())];
    let positions = [
        [0, 0, 0],
        [top, top, top],
        [0, top, 0],
        [top, 0, top / 2],
        [top / 2, 0, 0], // corners, edges, faces
        [80, 80, 80],    // inside the cube's surface or interior
        [88, 88, 88],
        [top / 2 + 8, top / 2 + 3, 5], // fractional
    ];
    for (name, tris) in &scenes {
        let g = grid_with(n, tris);
        for p in positions {
            for policy in [Policy::Thesis, Policy::Wavefront, Policy::Radial] {
                for rule in [LitRule::Thesis, LitRule::Plane, LitRule::Exact] {
                    let merge = policy.by_layer();
                    let cfg = LightConfig {
                        fa: 2,
                        policy,
                        merge,
                        record_visits: false,
                        rule,
                        ..host_sim::config::plane_rule()
                    };
                    check_against_rays::<cell_core::beam::frac::U2>(&g, &[p], cfg)
                        .unwrap_or_else(|e| panic!("{name} {p:?} {rule:?}: {e}"));
                }
            }
        }
    }
}

/// The timing rules change when beams move, never what they carry: under every one of the 48
/// rule sets, each policy and both lit rules, a scene with a floor and a box lights exactly
/// the oracle's voxels (so the same set under every timing), and FIFO peaks respect FA plus
/// the register.
#[test]
fn every_timing_lights_the_oracles_voxels() {
    let n = 9u32;
    let m = Q * n as i64;
    let tris = [
        [[0, 0, 8], [m, 0, 8], [m, m, 8]],
        [[0, 0, 8], [m, m, 8], [0, m, 8]],
        [[2 * Q, 2 * Q, 4 * Q], [6 * Q, 3 * Q, 5 * Q], [3 * Q, 6 * Q, 4 * Q]],
    ];
    let g = grid_with(n, &tris);
    let src = [[100, 60, 120]];
    for timing in all_timings() {
        for policy in [Policy::Thesis, Policy::Wavefront, Policy::Radial] {
            for rule in [LitRule::Thesis, LitRule::Plane, LitRule::Exact] {
                let cfg = LightConfig {
                    fa: 2,
                    policy,
                    merge: policy.by_layer(),
                    rule,
                    timing,
                    ..host_sim::config::plane_rule()
                };
                check_against_rays::<cell_core::beam::frac::U0>(&g, &src, cfg)
                    .unwrap_or_else(|e| panic!("{timing:?} {policy:?} {rule:?}: {e}"));
                let peak = light::<cell_core::beam::frac::U0>(&g, &src, cfg).reports[0].counts.peak_fifo;
                assert!(peak as usize <= timing.fifo_limit(2), "{timing:?}: FIFO peak {peak}");
            }
        }
    }
}

/// Multi-source: each voxel's mask is the union over sources, and equals lighting each source
/// alone.
#[test]
fn multi_source_masks_are_unions() {
    let n = 12u32;
    let m = Q * n as i64;
    let tris = [
        [[0, m / 3, 0], [m, m / 3, m], [m, m / 3, 0]],
        [[0, m / 3, 0], [0, m / 3, m], [m, m / 3, m]],
        [[m / 4, m / 2, m / 4], [m / 2, m / 2, m / 2], [m / 4, m / 2, m / 2]],
    ];
    let g = grid_with(n, &tris);
    let srcs = [[16, 170, 16], [160, 150, 100], [90, 40, 90]];
    let cfg = LightConfig {
        fa: 8,
        policy: Policy::Wavefront,
        merge: true,
        record_visits: false,
        ..host_sim::config::plane_rule()
    };
    let all = light::<cell_core::beam::frac::U0>(&g, &srcs, cfg);
    let mut union: BTreeMap<[u32; 3], u32> = BTreeMap::new();
    for (i, s) in srcs.iter().enumerate() {
        for (v, mask) in light::<cell_core::beam::frac::U0>(&g, &[*s], cfg).lit_voxels() {
            assert_eq!(mask, 1);
            *union.entry(v).or_default() |= 1 << i;
        }
    }
    let got: BTreeMap<[u32; 3], u32> = all.lit_voxels().collect();
    assert!(got.values().any(|&m| m.count_ones() > 1), "some voxel is lit by two sources");
    assert_eq!(got, union);
}

/// Coverage (§4.1.4): in the empty scene a beam is processed in every voxel, for any source
/// position (integer or fractional) and every f.
#[test]
fn empty_scene_every_voxel_is_reached() {
    let n = 9u32;
    let top = 16 * (n as i64 - 1);
    let positions = [[0, 0, 0], [top, 5, 77], [64, 64, 64], [67, 23, 111], [top, top, top]];
    for f in [0u32, 1, 2, 3, 4, 6, 8, 12, 16] {
        for p in positions {
            let g = grid_with(n, &[]);
            let cfg = LightConfig {
                fa: 4,
                policy: Policy::Wavefront,
                merge: f % 2 == 0,
                record_visits: true,
                skip_receding: false,
                skip_dead_directions: false,
                ..host_sim::config::plane_rule()
            };
            let l = cell_core::with_frac_bits!(f, F => {
                let l = light::<F>(&g, &[p], cfg);
                (l.visited.clone().unwrap(), l.reports[0].counts.rays_emitted, l.reports[0].counts.rays_exited)
            })
            .unwrap();
            let missed = l.0.iter().filter(|v| !**v).count();
            assert_eq!(missed, 0, "f = {f}, source {p:?}: {missed} voxels never reached");
            assert_eq!(l.1, l.2, "empty scene: every ray exits");
        }
    }
}

/// The thesis's experiment: with the thesis policy and FA = 1, T grows like N² (×4 when N
/// doubles, within slack); our wavefront policy with merging reaches T/LB ≤ 1.5 at N = 64 with
/// FA = 16, and lights exactly the same voxels as the thesis policy on the Cornell box.
#[test]
fn thesis_shape_and_our_policy() {
    let t = |n: u32, fa: usize, policy: Policy, merge: bool| {
        let g = grid_with(n, &[]);
        let c = 16 * (n as i64 / 2);
        let l = light::<cell_core::beam::frac::U0>(
            &g,
            &[[c, c, c]],
            // Skips off: the thesis's experiment diffuses through the empty scene.
            LightConfig {
                fa,
                policy,
                merge,
                skip_receding: false,
                skip_dead_directions: false,
                ..host_sim::config::plane_rule()
            },
        );
        (l.reports[0].counts.cycles, l.reports[0].counts.lower_bound)
    };
    let (t16, _) = t(16, 1, Policy::Thesis, false);
    let (t32, _) = t(32, 1, Policy::Thesis, false);
    let ratio = t32 as f64 / t16 as f64;
    assert!(ratio > 3.0, "FA = 1: T(32)/T(16) = {ratio:.2}, expected about 4 (N²)");
    let (t64, lb64) = t(64, 16, Policy::Wavefront, true);
    assert!(t64 as f64 <= 1.5 * lb64 as f64, "wavefront+merge N=64 FA=16: T = {t64}, LB = {lb64}");
    let (t64_thesis, _) = t(64, 16, Policy::Thesis, false);
    assert!(t64 * 3 < t64_thesis, "ours {t64} vs thesis policy {t64_thesis}");

    let mesh = host_sim::scene::load("cornell").unwrap();
    let cfg = LoadConfig::watertight(32);
    let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &cfg).unwrap();
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
    let lit = |policy, merge| {
        let lcfg =
            LightConfig { fa: 4, policy, merge, record_visits: false, frac_bits: 2, ..host_sim::config::plane_rule() };
        let (l, _) =
            host_sim::machine::lighting::run::run_diffusion(&mesh, &loaded, &lights, &lcfg, |_, _| {}).unwrap();
        l.lit_voxels().collect::<Vec<_>>()
    };
    let a = lit(Policy::Thesis, false);
    assert!(a.len() > 1000);
    assert_eq!(a, lit(Policy::Wavefront, true));
}

/// Each column keeps, in stream order, the first `TRIANGLE_CAP` of the triangles whose
/// projection meets its square by the oracle's own test (`exact::keeps`), and the triangles a
/// full column leaves out are counted, one per (triangle, column): random triangles plus a stack
/// of 80 over one column, more than it keeps.
#[test]
fn column_stores_keep_what_the_oracle_says() {
    use host_sim::machine::grid::capacity::TRIANGLE_CAP;
    let n = 12u32;
    let mut s = 0x5eed_u64;
    let mut next = |m: i64| {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 33) as i64 % m
    };
    // Loading-lattice sixteenths (voxel x spans 16x ..= 16x + 16).
    let mut polys: Vec<Vec<[i64; 3]>> =
        (0..40).map(|_| (0..3).map(|_| [next(192), next(192), next(192)]).collect()).collect();
    polys
        .extend((0..80).map(|i| vec![[80 + i % 7, 80, 8 + 2 * i], [100, 84 + i % 5, 8 + 2 * i], [88, 100, 9 + 2 * i]]));
    let stores = ColumnTriangles::from_polygons(&polys, n).expect("in range");
    // The oracle's coordinates: voxel centres at multiples of 16.
    let tris: Vec<exact::Tri> = polys.iter().map(|p| [p[0], p[1], p[2]].map(|v| v.map(|c| c - 8))).collect();
    let mut left_out = 0u64;
    let mut full = 0;
    for y in 0..n {
        for x in 0..n {
            let want: Vec<exact::Tri> = tris.iter().filter(|t| exact::keeps(t, x as i64, y as i64)).copied().collect();
            let got: Vec<exact::Tri> =
                stores.column(x, y).iter().map(|t| t.vertices().map(|v| v.map(i64::from))).collect();
            let kept = want.len().min(TRIANGLE_CAP);
            assert_eq!(got, want[..kept], "column ({x}, {y})");
            left_out += (want.len() - kept) as u64;
            full += (want.len() > TRIANGLE_CAP) as usize;
        }
    }
    assert!(full > 0, "the stack overfills a column");
    assert_eq!(stores.overflows(), left_out);
}

/// The receiver's contact test (`cell_core::receiver::crosses_any`, behind
/// `Target::shadowed_by` and the neighbours' answers; Plücker signs) is the oracle's exact
/// crossing point in the closed triangle (`exact::segment_crosses`), on
/// random segments and triangles and on segments ending exactly on a vertex, an edge's middle
/// or a point inside the triangle.
#[test]
fn contact_test_matches_the_rational_crossing() {
    let mut s = 0xc0ffee_u64;
    let mut next = |lo: i64, hi: i64| {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        lo + (s >> 33) as i64 % (hi - lo + 1)
    };
    let scale = POINT_UNITS / 16;
    let (mut crossed, mut missed) = ([0u32; 4], [0u32; 4]);
    for i in 0..40_000 {
        let tri: exact::Tri = [0; 3].map(|_| [0; 3].map(|_| next(-48, 48)));
        let x0 = [0; 3].map(|_| next(-48 * scale, 48 * scale));
        let kind = i % 4;
        let x1 = match kind {
            0 => [0; 3].map(|_| next(-48 * scale, 48 * scale)),
            1 => tri[0].map(|c| c * scale),
            2 => [0, 1, 2].map(|c| (tri[1][c] + tri[2][c]) * scale / 2),
            // A point inside the triangle, in its plane (barycentric ¼, ¼, ½).
            _ => [0, 1, 2].map(|c| (tri[0][c] + tri[1][c] + 2 * tri[2][c]) * scale / 4),
        };
        let want = exact::segment_crosses(&tri, x0, x1, scale);
        let cell_tri = Triangle::new(tri.map(|v| v.map(|c| c as i32))).expect("small");
        assert_eq!(crosses_any(&[cell_tri], [x0, x1]), want, "{tri:?} from {x0:?} to {x1:?}");
        if want {
            crossed[kind] += 1
        } else {
            missed[kind] += 1
        }
    }
    assert!(crossed.iter().chain(&missed).all(|&c| c > 100), "every kind both ways: {crossed:?} / {missed:?}");
}

/// The host's time by phase of the cycle loop (`--stats` light.phase_seconds) is laps of one
/// clock inside the diffusion's own wall interval: each phase non-negative, the steps (where
/// every beam is processed) some of it, and all of them together no more than the wall time.
#[test]
fn phase_seconds_are_laps_inside_the_light_wall() {
    let mesh = host_sim::scene::load("cornell").unwrap();
    let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &LoadConfig::watertight(24)).unwrap();
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
    let cfg = host_sim::config::Preset::Light.light();
    let (_, stats) = host_sim::machine::lighting::run::run_diffusion(&mesh, &loaded, &lights, &cfg, |_, _| {}).unwrap();
    let phases = stats.phase_seconds.expect("a beam diffusion reports its phases");
    for (name, s) in phases.named() {
        assert!(s >= 0.0, "{name}: {s}");
    }
    assert!(phases.step > 0.0 && stats.totals.beams_processed > 0);
    assert!(phases.total() <= stats.wall_seconds, "{} s of phases in {} s", phases.total(), stats.wall_seconds);
}

/// The lit-ray ratio's oracle (`cell_core::visibility`): for every column with a target ray and
/// every source, the candidates R — every lattice ray of the target's face, enumerated, whose
/// voxel at the target's layer is the target voxel (`RaysFrom::voxel`) and that lies on the
/// visible plane's outer side at that layer or the one before (`oracle::lit::plane_value_on`)
/// — and r, those of them the exact walk (`oracle::exact`) brings to that layer; the weight
/// `⌊255·r/R + ½⌋` (`majority`: 255 iff 2r > R), 0 in a contact shadow. Keyed by (column,
/// source).
fn ratio_oracle<F: FracBits>(
    g: &G,
    src16: &[[i64; 3]],
    origin: Origin,
    majority: bool,
) -> BTreeMap<([i64; 2], usize), (u64, u64, u8)> {
    let n = g.n as i64;
    let from = match origin {
        Origin::SourceVoxel => RaysFrom::Voxel,
        Origin::Light => RaysFrom::Light,
    };
    let tris = scene_triangles(g);
    let scene = exact::Scene::new(n, &tris);
    let far = FarDistance::<F>::new(g.n - 1).expect("far distance");
    let (d, m) = (n - 1, (n - 1) << F::U32);
    let columns = common::columns_of(g);
    let mut out = BTreeMap::new();
    for (si, &s) in src16.iter().enumerate() {
        let source = sources(&[s])[0].with_origin(origin);
        for c in &g.cells {
            let (x, y) = (c.x as i64, c.y as i64);
            let Some(t) = c.visible.as_ref().and_then(|v| target(c.x as i32, c.y as i32, v, &source, far)) else {
                continue;
            };
            let vis = columns(x, y).expect("a target needs a visible surface");
            let dir = (0..6).find(|&d| oracle_direction(d) == t.dir).expect("six directions");
            let k = t.layer as i64;
            let (mut total, mut arrived) = (0u64, 0u64);
            for a in -m..=m {
                for b in -m..=m {
                    if from.voxel(s, dir, a, b, d, F::U32, k) != [x, y, t.z] {
                        continue;
                    }
                    let side = |layer| {
                        rc2_tests::oracle::lit::plane_value_on(&vis.plane, x, y, from, s, dir, a, b, d, F::U32, layer)
                            > 0
                    };
                    if side(k) || side(k - 1) {
                        total += 1;
                        arrived += exact::reaches(exact::trace_ray_exact(&scene, s, from, F::U32, dir, a, b), k) as u64;
                    }
                }
            }
            let contact = contact_shadowed(&scene, [x, y], &t);
            let weight = match (contact || total == 0, majority) {
                (true, _) => 0,
                (false, true) => 255 * (2 * arrived > total) as u8,
                (false, false) => ((510 * arrived + total) / (2 * total)) as u8,
            };
            out.insert(([x, y], si), (arrived, total, weight));
        }
    }
    out
}

/// Under `--visibility ratio|majority` the cells' weights equal the oracle's, ray count for ray
/// count; the beams, cycles and lit sets are those of the default (target) visibility.
fn check_ratio<F: FracBits>(g: &G, src16: &[[i64; 3]], cfg: LightConfig) -> Result<u32, TestCaseError> {
    use cell_core::visibility::Visibility;
    let base = light::<F>(g, src16, LightConfig { visibility: Visibility::Target, ..cfg });
    let l = light::<F>(g, src16, cfg);
    let counts = |l: &Lighting| l.reports.iter().map(|r| r.counts.clone()).collect::<Vec<_>>();
    prop_assert_eq!(counts(&base), counts(&l), "counting rays changed the machine");
    prop_assert_eq!(visible_lit(&base), visible_lit(&l));
    let want = ratio_oracle::<F>(g, src16, cfg.rays, cfg.visibility == Visibility::Majority);
    let weights = l.weights.as_ref().expect("the cells counted");
    prop_assert_eq!(weights.len(), src16.len());
    let mut fractional = 0;
    for y in 0..g.n {
        for x in 0..g.n {
            for (si, per_source) in weights.iter().enumerate() {
                let got = per_source[(y * g.n + x) as usize];
                let w = want.get(&([x as i64, y as i64], si)).map_or(0, |o| o.2);
                prop_assert_eq!(
                    got,
                    w,
                    "column ({}, {}) source {}: oracle {:?}",
                    x,
                    y,
                    si,
                    want.get(&([x as i64, y as i64], si))
                );
                fractional += (got != 0 && got != 255) as u32;
            }
        }
    }
    Ok(fractional)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// The lit-ray ratio against the oracle that enumerates every ray of each target voxel and
    /// walks it alone (`ratio_oracle`), for both ray origins, f = 0–2, every policy, FIFO
    /// size, merging, skip and timing: the count is the rays', not the beams'.
    #[test]
    fn lit_ray_ratio_matches_per_ray_counts(
        n in 5u32..=9,
        raw_tris in prop::collection::vec(prop::array::uniform3(prop::array::uniform3(0i64..=20)), 1..6),
        raw_src in prop::collection::vec([0i64..=1000, 0..=1000, 0..=1000], 1..3),
        light_origin in any::<bool>(),
        majority in any::<bool>(),
        f in prop::sample::select(vec![0u32, 1, 2]),
        cfg in config_of(vec![LitRule::Exact]),
    ) {
        use cell_core::visibility::Visibility;
        let visibility = if majority { Visibility::Majority } else { Visibility::Ratio };
        let (g, src16, cfg) = exact_case(n, &raw_tris, &raw_src, light_origin, LightConfig { visibility, ..cfg });
        cell_core::with_frac_bits!(f, F => check_ratio::<F>(&g, &src16, cfg)).unwrap()?;
    }
}

/// A floor partly in the shadow of a slab's slanted straight edge, lit from above the slab at
/// f = 2: the shadow edge's pixels get weights strictly between 0 and 255 (the ratio is not the target ray's
/// all-or-nothing), each equal to the oracle's.
#[test]
fn a_shadow_edge_gets_fractional_weights() {
    use cell_core::visibility::Visibility;
    let n = 9u32;
    let m = Q * n as i64;
    let at = |x: i64, y: i64, z: i64| [x * m / 90, y * m / 90, z * m / 90];
    // The floor at z ≈ 7.5 voxels, a slab over half of it at z ≈ 4.3 whose edge runs along y
    // at a slant, so that it cuts the columns' target voxels at many offsets.
    let tris = [
        [at(2, 2, 75), at(88, 2, 75), at(88, 88, 75)],
        [at(2, 2, 75), at(88, 88, 75), at(2, 88, 75)],
        [at(0, 0, 43), at(36, 0, 43), at(44, 90, 43)],
        [at(0, 0, 43), at(44, 90, 43), at(0, 90, 43)],
    ];
    let g = grid_with(n, &tris);
    // The light over the slab: the edge's shadow falls on the visible floor beyond it.
    let src16 = [[16 + 3, 16 * 4 + 3, 8]];
    let cfg = LightConfig { visibility: Visibility::Ratio, rule: LitRule::Exact, ..host_sim::config::plane_rule() };
    let fractional = check_ratio::<cell_core::beam::frac::U2>(&g, &src16, cfg).unwrap();
    assert!(fractional >= 3, "only {fractional} fractional weights along the shadow edge");
}
