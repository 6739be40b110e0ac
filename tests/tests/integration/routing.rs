//! Destination-addressed routing (§1.3, §4.1.3; `cell_core::route`, `host_sim::machine::rays::network`):
//! random all-to-all and adversarial traffic on grids with 2-message buffers is delivered
//! exactly once, to the right cell, in bounded cycles, and the stall detector never fires —
//! under both routing policies.

use cell_core::route::{RoutePolicy, Routed};
use host_sim::machine::rays::network::Network;

use crate::common;

/// Run `traffic[cell]` (destinations, in injection order; each cell's compute unit injects at
/// most one message per cycle) to completion. Returns the cycles, or an error on a stall.
fn run(n: u32, policy: RoutePolicy, traffic: &[Vec<[u16; 2]>]) -> Result<(u64, Network<u32>), String> {
    let mut net: Network<u32> = Network::new(n, policy);
    let cells = (n * n) as usize;
    let mut next = vec![0usize; cells];
    let mut ids = Vec::new(); // message id → (source, destination)
    let mut base = vec![0u32; cells];
    for (c, t) in traffic.iter().enumerate() {
        base[c] = ids.len() as u32;
        ids.extend(t.iter().map(|d| (c, *d)));
    }
    let mut got = vec![0u32; ids.len()];
    let mut link_used = vec![false; cells * 8];
    let total = ids.len();
    let mut delivered = 0usize;
    let mut cycle = 0u64;
    while delivered < total {
        let mut moved = 0;
        for c in 0..cells {
            if let Some(&d) = traffic[c].get(next[c]) {
                let m = Routed { dest: d, payload: base[c] + next[c] as u32 };
                if net.inject(c, m) {
                    next[c] += 1;
                    moved += 1;
                }
            }
        }
        link_used.iter_mut().for_each(|u| *u = false);
        moved += net.step(&mut link_used, |cell, m| {
            let (_, dest) = ids[m.payload as usize];
            assert_eq!([(cell as u32 % n) as u16, (cell as u32 / n) as u16], dest, "delivered to the wrong cell");
            got[m.payload as usize] += 1;
            delivered += 1;
        });
        cycle += 1;
        if moved == 0 {
            return Err(format!("stall at cycle {cycle}: {} in flight", net.in_flight));
        }
    }
    assert!(got.iter().all(|&g| g == 1), "every message delivered exactly once");
    assert_eq!(net.in_flight, 0);
    Ok((cycle, net))
}

fn lcg(state: &mut u64) -> u64 {
    *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    *state >> 33
}

/// Every cell sends one message to every other cell, in a random order per cell.
fn all_to_all(n: u32, seed: u64) -> Vec<Vec<[u16; 2]>> {
    let mut s = seed;
    (0..n * n)
        .map(|c| {
            let mut d: Vec<[u16; 2]> =
                (0..n * n).filter(|&o| o != c).map(|o| [(o % n) as u16, (o / n) as u16]).collect();
            for i in (1..d.len()).rev() {
                d.swap(i, lcg(&mut s) as usize % (i + 1));
            }
            d
        })
        .collect()
}

#[test]
fn random_all_to_all_is_delivered_exactly_once() {
    for policy in [RoutePolicy::DiagonalFirst, RoutePolicy::Adaptive] {
        for (n, seed) in [(4u32, 1u64), (8, 2), (12, 3)] {
            let traffic = all_to_all(n, seed);
            let (cycles, net) = run(n, policy, &traffic).unwrap_or_else(|e| panic!("{policy:?} n = {n}: {e}"));
            // Each cell must eject n² − 1 messages at one per cycle: the lower bound. The
            // bound asserted leaves room for contention but catches livelock and starvation.
            let lb = (n * n - 1) as u64;
            println!(
                "{policy:?} n = {n}: {cycles} cycles (LB {lb}, ratio {:.2}), {} hops",
                cycles as f64 / lb as f64,
                net.hops
            );
            assert!(cycles <= 4 * lb + 4 * n as u64, "{policy:?} n = {n}: {cycles} cycles, LB {lb}");
            // Minimal routing: hops = Σ Chebyshev distances.
            let cheb: u64 = traffic
                .iter()
                .enumerate()
                .flat_map(|(c, t)| {
                    let (x, y) = ((c as u32 % n) as i64, (c as u32 / n) as i64);
                    t.iter().map(move |d| (d[0] as i64 - x).abs().max((d[1] as i64 - y).abs()) as u64)
                })
                .sum();
            assert_eq!(net.hops, cheb, "every path is minimal");
        }
    }
}

#[test]
fn hotspot_and_transpose_traffic() {
    let n = 16u32;
    for policy in [RoutePolicy::DiagonalFirst, RoutePolicy::Adaptive] {
        // Everyone sends 4 messages to one cell near a corner (the source in the shadow-ray
        // phase): the worst case for congestion.
        let hot: Vec<Vec<[u16; 2]>> = (0..n * n).map(|_| vec![[2, 13]; 4]).collect();
        let (cycles, _) = run(n, policy, &hot).unwrap();
        assert!(cycles >= (4 * n * n - 4) as u64, "ejection bound");
        assert!(cycles <= 2 * 4 * (n * n) as u64 + 4 * n as u64, "{policy:?}: {cycles}");
        // Transpose: (x, y) → (y, x), crossing traffic in all four quadrants.
        let tr: Vec<Vec<[u16; 2]>> = (0..n * n).map(|c| vec![[(c / n) as u16, (c % n) as u16]; 8]).collect();
        let (cycles, net) = run(n, policy, &tr).unwrap();
        println!(
            "{policy:?} transpose n = {n}: {cycles} cycles, peak link load {}",
            net.link_load.iter().max().unwrap()
        );
        assert!(cycles <= 8 * 8 * n as u64, "{policy:?}: {cycles}");
    }
}

/// The classic shadow-ray phase on a real scene (§4.1.2): the lit state the cells assemble from
/// routed answers equals a host per-ray oracle (the f64 reference walk of the same line, the
/// same occupancy and own-facet rule), for small FIFOs, every ray connectivity and both routing
/// policies; every ray gets exactly one answer and the stall detector never fires.
#[test]
fn classic_answers_match_a_per_ray_oracle() {
    use cell_core::lit::LitRule;
    use cell_core::ray::{Connectivity, Q};
    use host_sim::machine::rays::classic::{classic, ClassicConfig};
    use host_sim::precompute::LoadConfig;
    use rc2_tests::oracle::lines::{walk18, walk26, walk6};

    let mesh = host_sim::scene::load("cornell").unwrap();
    let n = 32;
    let cfg = LoadConfig::thin(n);
    let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &cfg).unwrap();
    let mut lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
    lights.push([3.0, 20.0, 9.5]); // a second source, low and to the side
    let grid = &loaded.grid;
    for (conn, bias) in Connectivity::ALL.into_iter().map(|c| (c, 0u8)).chain([(Connectivity::Six, 2)]) {
        // Oracle: the lit mask of each visible voxel.
        let mut want = vec![0u32; (n * n) as usize];
        for (i, c) in grid.cells.iter().enumerate() {
            let Some(d) = c.store.dexels().first() else { continue };
            for (s, l) in lights.iter().enumerate() {
                let a = [c.x as i64, c.y as i64, d.span.lo as i64].map(|v| v * Q as i64);
                let b = l.map(|v| (v * Q as f64).round() as i64);
                // 18/26-connected rays aim at the centre of the source's voxel (see ShadowRay::new).
                let b = if conn == Connectivity::Six {
                    b
                } else {
                    b.map(|c| rc2_tests::oracle::lines::voxel(c, Q as i64) * Q as i64)
                };
                let path = match conn {
                    Connectivity::Six => walk6(a, b, Q as i64),
                    Connectivity::Eighteen => walk18(a, b, Q as i64),
                    Connectivity::TwentySix => walk26(a, b, Q as i64),
                };
                // The emitter's voxel and `bias` more are not tested.
                let blocked = path.iter().skip(1 + bias as usize).any(|v| {
                    grid.cell(v[0] as u32, v[1] as u32).store.occupied(v[2] as u16).is_some_and(|o| o.facet != d.facet)
                });
                if !blocked {
                    want[i] |= 1 << s;
                }
            }
        }
        let visible = grid.cells.iter().filter(|c| !c.store.dexels().is_empty()).count() as u64;
        if bias > 0 {
            // The bias must matter here, or this case tests nothing new.
            let plain = classic(
                &loaded,
                &lights,
                &ClassicConfig {
                    fa: 4,
                    connectivity: conn,
                    route: RoutePolicy::Adaptive,
                    all_voxels: false,
                    bias: 0,
                    rule: LitRule::Thesis,
                },
                |_, _| {},
            )
            .unwrap();
            assert_ne!(plain.masks, want, "a bias of {bias} voxels changes some answers");
        }
        for (fa, route) in [(1, RoutePolicy::DiagonalFirst), (2, RoutePolicy::Adaptive), (16, RoutePolicy::Adaptive)] {
            let cl = classic(
                &loaded,
                &lights,
                &ClassicConfig { fa, connectivity: conn, route, all_voxels: false, bias, rule: LitRule::Thesis },
                |_, _| {},
            )
            .unwrap_or_else(|e| panic!("{conn:?} FA {fa} {route:?}: {e}"));
            assert_eq!(cl.masks, want, "{conn:?} bias {bias} FA {fa} {route:?}");
            let t = &cl.totals;
            assert_eq!(t.rays, visible * lights.len() as u64);
            assert_eq!(t.answers, t.rays, "one answer per ray");
            let lit: u64 = want.iter().map(|m| m.count_ones() as u64).sum();
            assert_eq!(t.lit, lit, "each lit answer delivered once");
            assert!(lit > 0 && lit < t.rays, "the scene has both lit and shadowed voxels");
        }
        // Every occupied voxel emitting (the thesis's count): the same image state, more rays.
        let all = ClassicConfig {
            fa: 4,
            connectivity: conn,
            route: RoutePolicy::Adaptive,
            all_voxels: true,
            bias,
            rule: LitRule::Thesis,
        };
        let cl = classic(&loaded, &lights, &all, |_, _| {}).unwrap();
        assert_eq!(cl.masks, want, "{conn:?} all voxels");
        assert_eq!(cl.totals.rays, cl.totals.voxels * lights.len() as u64);
        assert_eq!(cl.totals.answers, cl.totals.rays);
    }
}

/// The sources at light positions `lights` (voxels) on the rays' 1/16 lattice.
fn lattice(lights: &[[f64; 3]]) -> Vec<[i64; 3]> {
    lights.iter().map(|l| l.map(|v| (v * cell_core::ray::Q as f64).round() as i64)).collect()
}

/// The oracle's lit masks of `grid`'s visible surfaces, in grid-cell order (bit s: source s at
/// lattice point `sources[s]`, as `lit` decides it), and how many surfaces there are.
fn oracle_masks(
    grid: &host_sim::machine::grid::LightGrid,
    sources: &[[i64; 3]],
    lit: impl Fn(&rc2_tests::oracle::shadow::Emitter, [i64; 3]) -> bool,
) -> (Vec<u32>, u64) {
    let mut emitters = 0;
    let masks = grid
        .cells
        .iter()
        .map(|c| {
            let Some(e) = common::emitter_of(grid, c.x as u32, c.y as u32) else { return 0 };
            emitters += 1;
            sources.iter().enumerate().filter(|&(_, &b)| lit(&e, b)).map(|(s, _)| 1u32 << s).sum()
        })
        .collect();
    (masks, emitters)
}

/// Classic shadow rays under the plane principle (`cell_core::ray`, §4.1.2 with §5.5.6): the lit
/// state the cells assemble equals the brute-force segment oracle
/// (`rc2_tests::oracle::shadow`: every occupied voxel of the segment's box clipped on its
/// own), on the Cornell box and the teapot on its floor with thick tunnel-free surfaces, two
/// sources each (one low and grazing), small FIFOs and both routing policies; every occupied
/// voxel emitting gives the same image state.
#[test]
fn classic_plane_answers_match_the_segment_oracle() {
    use cell_core::lit::LitRule;
    use host_sim::machine::rays::classic::classic;
    use host_sim::precompute::LoadConfig;

    for (scene, extra) in [("cornell", [3.0, 20.0, 9.5]), ("teapot-floor", [30.0, 2.0, 4.0])] {
        let mesh = host_sim::scene::load(scene).unwrap();
        let n = 32;
        let cfg = LoadConfig::watertight(n);
        let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &cfg).unwrap();
        let mut lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
        lights.push(extra);
        let occ = common::occupants_of(&loaded.grid);
        let (want, emitters) =
            oracle_masks(&loaded.grid, &lattice(&lights), |e, b| rc2_tests::oracle::shadow::lit(e, b, &occ));
        let all = check_classic(scene, &loaded, &lights, LitRule::Plane, &want, emitters);
        // A source outside the grid is an error, not a ray walking off it.
        let e = classic(&loaded, &[[n as f64 + 0.5, 3.0, 3.0]], &all, |_, _| {}).err().expect("outside source");
        assert!(e.to_string().contains("outside the grid"), "{e}");
    }
}

/// `scene` loaded on an n³ grid with thick surfaces and triangle stores that never fill (the
/// cells' code, larger stores: a full store lets light through, which the oracle does not
/// model), and its lattice triangles (sixteenths, voxel centres at multiples of 16): the fan of
/// each prepared polygon, as the stores cut it.
fn exact_scene(scene: &str, n: u32) -> (host_sim::machine::loading::loaded_scene::LoadedScene, Vec<[[i64; 3]; 3]>) {
    let mesh = host_sim::scene::load(scene).unwrap();
    let cfg = host_sim::precompute::LoadConfig::watertight(n);
    let mut loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &cfg).unwrap();
    let prepared = host_sim::precompute::prepare(&mesh, &cfg).unwrap();
    loaded.grid.triangles =
        host_sim::machine::grid::triangles::ColumnTriangles::from_polygons_keeping(&prepared.polygons, n, usize::MAX)
            .unwrap();
    let mut tris = Vec::new();
    for poly in &prepared.polygons {
        let v: Vec<[i64; 3]> = poly.iter().map(|p| p.map(|c| c - 8)).collect();
        tris.extend((1..v.len().saturating_sub(1)).map(|k| [v[0], v[k], v[k + 1]]));
    }
    (loaded, tris)
}

/// Classic shadow rays under exact occluders: the lit state the cells assemble (each column
/// testing its own triangles against the exact segment as the ray passes) equals the segment
/// tested against every triangle of the scene (`rc2_tests::oracle::shadow::lit_exact`), on the
/// Cornell box and the teapot on its floor with two sources each (one low and grazing), small
/// FIFOs and both routing policies, no column's store full; every occupied voxel emitting gives
/// the same image state.
#[test]
fn classic_exact_answers_match_every_triangle() {
    use cell_core::lit::LitRule;

    for (scene, extra) in [("cornell", [3.0, 20.0, 9.5]), ("teapot-floor", [30.0, 2.0, 4.0])] {
        let mesh = host_sim::scene::load(scene).unwrap();
        let n = 32;
        let (loaded, tris) = exact_scene(scene, n);
        let mut lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
        lights.push(extra);
        let (grid, sources) = (&loaded.grid, lattice(&lights));
        let (want, emitters) = oracle_masks(grid, &sources, |e, b| rc2_tests::oracle::shadow::lit_exact(e, b, &tris));
        let occ = common::occupants_of(grid);
        let (plane, _) = oracle_masks(grid, &sources, |e, b| rc2_tests::oracle::shadow::lit(e, b, &occ));
        assert_ne!(want, plane, "{scene}: exact occluders and the plane rule differ somewhere");
        check_classic(scene, &loaded, &lights, LitRule::Exact, &want, emitters);
    }
}

/// Shadow-edge refinement (`host_sim::machine::rays::classic::refine_edges`, after diffusion): a
/// pixel whose 8-neighbourhood holds a pixel lit otherwise by a source (computed here from
/// the masks) takes the exact segment's answer for it (`oracle::shadow::lit_exact`, every
/// triangle of the scene); every other pixel keeps its diffused bit. On the Cornell box and
/// the teapot on its floor (n = 32, two sources each, one grazing), after diffusion under the
/// plane rule and under exact occluders, FIFOs of 1 and 16 and both routings; the counters
/// count the edges and the bits changed, and some bits do change.
#[test]
fn refined_shadow_edges_take_the_exact_answer_and_the_rest_keeps_the_diffused_one() {
    use cell_core::lit::LitRule;
    use host_sim::machine::lighting::diffuse::LightConfig;
    use host_sim::machine::rays::classic::{refine_edges, ClassicConfig};

    let mut changed = 0;
    for (scene, extra) in [("cornell", [3.0, 20.0, 9.5]), ("teapot-floor", [30.0, 2.0, 4.0])] {
        let mesh = host_sim::scene::load(scene).unwrap();
        let n = 32usize;
        let (loaded, tris) = exact_scene(scene, n as u32);
        let mut lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
        lights.push(extra);
        let (want, _) =
            oracle_masks(&loaded.grid, &lattice(&lights), |e, b| rc2_tests::oracle::shadow::lit_exact(e, b, &tris));
        for rule in [LitRule::Plane, LitRule::Exact] {
            let lcfg = LightConfig { rule, ..host_sim::config::plane_rule() };
            let (lighting, _) =
                host_sim::machine::lighting::run::run_diffusion(&mesh, &loaded, &lights, &lcfg, |_, _| {}).unwrap();
            let diffused: Vec<u32> =
                (0..n * n).map(|i| lighting.visible_mask((i % n) as u32, (i / n) as u32)).collect();
            let shows = |i: usize| loaded.grid.cells[i].visible.is_some();
            for (fa, route) in [(1, RoutePolicy::DiagonalFirst), (16, RoutePolicy::Adaptive)] {
                let cfg = ClassicConfig {
                    fa,
                    connectivity: cell_core::ray::Connectivity::Six,
                    route,
                    all_voxels: false,
                    bias: 0,
                    rule: LitRule::Exact,
                };
                let mut masks = diffused.clone();
                let k = refine_edges(&loaded, &lights, &mut masks, &cfg, |_, _| {}).unwrap();
                let (mut edges, mut diff) = (0, 0);
                for i in (0..n * n).filter(|&i| shows(i)) {
                    let (x, y) = ((i % n) as i64, (i / n) as i64);
                    for s in 0..lights.len() {
                        let bit = |m: u32| m >> s & 1;
                        let edge = (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy))).any(|(u, v)| {
                            let j = v * n as i64 + u;
                            (0..n as i64).contains(&u)
                                && (0..n as i64).contains(&v)
                                && shows(j as usize)
                                && bit(diffused[j as usize]) != bit(diffused[i])
                        });
                        let expect = if edge { bit(want[i]) } else { bit(diffused[i]) };
                        assert_eq!(
                            bit(masks[i]),
                            expect,
                            "{scene} {rule:?} FA {fa}: pixel ({x}, {y}), source {s}, edge {edge}"
                        );
                        edges += edge as u64;
                        diff += (bit(masks[i]) != bit(diffused[i])) as u64;
                    }
                }
                assert!(edges > 0, "{scene} {rule:?}: shadow edges to refine");
                assert_eq!((k.edge_pixels, k.changed), (edges, diff), "{scene} {rule:?} FA {fa}: counters");
                assert_eq!(k.classic.rays + k.classic.back_facing, edges, "one ray per edge pixel");
                changed += diff;
            }
        }
    }
    assert!(changed > 0, "the refinement changed some diffused bits");
}

/// Runs the classic phase of `loaded` under `rule` with FIFOs of 1, 2 and 16 and both
/// routings, then with every occupied voxel emitting: each gives `want` (the oracle's masks,
/// both lit and shadowed surfaces among them), one ray per surface facing a source, one answer
/// per ray and each lit answer delivered once; 26-connected rays are refused. Returns the
/// every-voxel configuration.
fn check_classic(
    scene: &str,
    loaded: &host_sim::machine::loading::loaded_scene::LoadedScene,
    lights: &[[f64; 3]],
    rule: cell_core::lit::LitRule,
    want: &[u32],
    emitters: u64,
) -> host_sim::machine::rays::classic::ClassicConfig {
    use cell_core::ray::Connectivity;
    use host_sim::machine::rays::classic::{classic, ClassicConfig};
    let lit: u64 = want.iter().map(|m| m.count_ones() as u64).sum();
    assert!(lit > 0 && lit < emitters * lights.len() as u64, "{scene}: both lit and shadowed surfaces");
    let base = ClassicConfig {
        fa: 1,
        connectivity: Connectivity::Six,
        route: RoutePolicy::Adaptive,
        all_voxels: false,
        bias: 0,
        rule,
    };
    for (fa, route) in [(1, RoutePolicy::DiagonalFirst), (2, RoutePolicy::Adaptive), (16, RoutePolicy::Adaptive)] {
        let c = ClassicConfig { fa, route, ..base };
        let cl = classic(loaded, lights, &c, |_, _| {}).unwrap_or_else(|e| panic!("{scene} FA {fa} {route:?}: {e}"));
        assert_eq!(cl.masks, want, "{scene} {rule:?} FA {fa} {route:?}");
        let t = &cl.totals;
        assert_eq!(t.rays + t.back_facing, emitters * lights.len() as u64, "one ray per surface facing a source");
        assert_eq!(t.answers, t.rays, "one answer per ray");
        assert_eq!(t.lit, lit, "each lit answer delivered once");
    }
    let all = ClassicConfig { fa: 4, all_voxels: true, ..base };
    let cl = classic(loaded, lights, &all, |_, _| {}).unwrap();
    assert_eq!(cl.masks, want, "{scene} {rule:?}: all voxels");
    assert_eq!(cl.totals.rays + cl.totals.back_facing, (emitters + cl.totals.voxels) * lights.len() as u64);
    // Both rules walk the exact segment: other connectivities are refused.
    let c26 = ClassicConfig { connectivity: Connectivity::TwentySix, ..all };
    let e = classic(loaded, lights, &c26, |_, _| {}).err().expect("26-connected rays are refused");
    assert!(e.to_string().contains("--ray-connectivity 6"), "{e}");
    all
}

/// The same against random sources (anywhere in the grid, on and off the lattice's voxel
/// boundaries) and FIFO sizes, on small grids.
mod random_sources {
    use super::common;
    use cell_core::lit::LitRule;
    use cell_core::ray::{Connectivity, Q};
    use cell_core::route::RoutePolicy;
    use host_sim::machine::rays::classic::{classic, ClassicConfig};
    use host_sim::precompute::LoadConfig;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
        #[test]
        fn classic_plane_matches_the_oracle(
            scene in prop::sample::select(vec!["cornell", "teapot-floor", "cow-floor"]),
            lights16 in prop::collection::vec(prop::array::uniform3(0i64..=240), 1..=2),
            fa in 1usize..=3,
        ) {
            let mesh = host_sim::scene::load(scene).unwrap();
            let n = 16;
            let cfg = LoadConfig::watertight(n);
            let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &cfg).unwrap();
            let lights: Vec<[f64; 3]> = lights16.iter().map(|l| l.map(|c| c as f64 / Q as f64)).collect();
            let occ = common::occupants_of(&loaded.grid);
            let c = ClassicConfig { fa, connectivity: Connectivity::Six, route: RoutePolicy::Adaptive, all_voxels: false, bias: 0, rule: LitRule::Plane };
            let cl = classic(&loaded, &lights, &c, |_, _| {}).unwrap();
            let (want, _) = super::oracle_masks(&loaded.grid, &lights16, |e, b| rc2_tests::oracle::shadow::lit(e, b, &occ));
            for (i, cell) in loaded.grid.cells.iter().enumerate() {
                prop_assert_eq!(cl.masks[i], want[i], "{} cell ({}, {})", scene, cell.x, cell.y);
            }
        }

        #[test]
        fn classic_exact_matches_the_oracle(
            scene in prop::sample::select(vec!["cornell", "teapot-floor", "cow-floor"]),
            lights16 in prop::collection::vec(prop::array::uniform3(0i64..=240), 1..=2),
            fa in 1usize..=3,
        ) {
            let (loaded, tris) = super::exact_scene(scene, 16);
            let lights: Vec<[f64; 3]> = lights16.iter().map(|l| l.map(|c| c as f64 / Q as f64)).collect();
            let c = ClassicConfig { fa, connectivity: Connectivity::Six, route: RoutePolicy::Adaptive, all_voxels: false, bias: 0, rule: LitRule::Exact };
            let cl = classic(&loaded, &lights, &c, |_, _| {}).unwrap();
            let (want, _) = super::oracle_masks(&loaded.grid, &lights16, |e, b| rc2_tests::oracle::shadow::lit_exact(e, b, &tris));
            for (i, cell) in loaded.grid.cells.iter().enumerate() {
                prop_assert_eq!(cl.masks[i], want[i], "{} cell ({}, {})", scene, cell.x, cell.y);
            }
        }
    }
}
