//! Progressive radiosity on the grid (`machine::shooting::shots`) against independent truths: exact
//! energy balance per shot (integers), a closed box that loses nothing, the reduction's cost
//! against a hand count, the supervisor's loop against the f64 reference solver fed the
//! machine's own form factors, the machine's form factors against the f64 ray-cast reference,
//! and bad input.

use cell_core::radiosity::Received;
use host_sim::machine::grid::capacity::CellReceived;
use host_sim::machine::loading::loaded_scene::{load_scene, LoadedScene};
use host_sim::machine::shooting::reduce::reduce_cost;
use host_sim::machine::shooting::shots::{map_patches, shoot, solve, PatchMap, RadiosityConfig};
use host_sim::precompute::LoadConfig;
use host_sim::scene::patches::{subdivide, subdivide_voxels, Patches};
use host_sim::scene::{Face, Material, Mesh};
use host_sim::truth::closed_form::point_to_polygon;
use host_sim::truth::radiosity::{progressive, ShootConfig};

type V3 = [f64; 3];

/// A quad of the box `lo..hi` on side `side` of `axis`, normal into the box.
fn box_side(lo: V3, hi: V3, axis: usize, side: usize) -> Vec<V3> {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let corner = |a: f64, b: f64| {
        let mut p = [0.0; 3];
        p[axis] = if side == 0 { lo[axis] } else { hi[axis] };
        p[u] = a;
        p[v] = b;
        p
    };
    let mut q = vec![corner(lo[u], lo[v]), corner(hi[u], lo[v]), corner(hi[u], hi[v]), corner(lo[u], hi[v])];
    if side == 1 {
        q.reverse();
    }
    q
}

/// The closed room [0,1]³, walls facing in, grey 0.5; the ceiling (z = 1) emits `ke`.
fn room(ke: f32) -> Mesh {
    let grey = Material { name: "grey".into(), kd: [0.5; 3], ..Material::default() };
    let lamp = Material { name: "lamp".into(), kd: [0.5; 3], ke: [ke; 3], ..Material::default() };
    let mut m = Mesh { name: "room".into(), materials: vec![grey, lamp], ..Default::default() };
    for axis in 0..3 {
        for side in 0..2 {
            let base = m.positions.len() as u32;
            m.positions.extend(box_side([0.0; 3], [1.0; 3], axis, side));
            let material = u16::from(axis == 2 && side == 1);
            m.faces.push(Face { verts: (base..base + 4).collect(), material });
        }
    }
    m
}

fn cfg(shots: usize) -> RadiosityConfig {
    RadiosityConfig::new(host_sim::config::plane_rule(), 0.0, shots)
}

fn loaded(mesh: &Mesh, n: u32) -> LoadedScene {
    load_scene(mesh, &LoadConfig::watertight(n)).unwrap()
}

fn patches_of(mesh: &Mesh, scene: &LoadedScene, voxels: f64) -> Patches {
    subdivide_voxels(mesh, voxels, scene.fit.voxel, 10_000).unwrap()
}

#[test]
fn a_closed_box_receives_every_quantum_of_every_shot() {
    let mesh = room(1.0);
    let scene = loaded(&mesh, 20);
    let p = patches_of(&mesh, &scene, 6.0);
    let s = solve(&scene.grid, &scene.fit, &scene.source_face, &p.patches, &cfg(6), |_, _| {}).unwrap();
    assert_eq!(s.shots.len(), 6);
    for shot in &s.shots {
        assert!(shot.balanced(), "{shot:?}");
        assert_eq!(
            (shot.left, shot.lost, shot.overflows),
            (0, 0, 0),
            "closed box: nothing leaves, nothing lost: {shot:?}"
        );
        assert_eq!(shot.received, shot.emitted);
        // The six faces hold the hemisphere: 2^30 quanta to f32 ulps (cell_core::radiosity).
        assert!((shot.emitted - (1 << 30)).abs() <= 6 * 4 * 64, "{shot:?}");
    }
    // Residual never increases (ρ ≤ 1, Σ F ≤ 1).
    assert!(s.shots.windows(2).all(|w| w[1].residual_after <= w[0].residual_after + 1e-12));
}

#[test]
fn the_reduction_costs_what_a_hand_count_says() {
    let n = 7u32;
    let empty: Vec<CellReceived> = (0..n * n).map(|_| Received::new()).collect();
    // Every cell sends one end marker; the supervisor's comes after 2(n − 1) + 1 links.
    let (t, cycles, messages) = reduce_cost(n, &empty);
    assert!(t.is_empty());
    assert_eq!(messages, (n * n) as u64);
    assert_eq!(cycles, 2 * (n as u64 - 1) + 1);
    // One entry in the far corner: it travels 2(n − 1) + 1 links, its end marker one cycle behind.
    let mut one = empty.clone();
    one[(n * n - 1) as usize].add(Some(5), 42);
    let (t, cycles, messages) = reduce_cost(n, &one);
    assert_eq!(t, vec![(5, 42)]);
    assert_eq!(messages, (n * n) as u64 + 2 * (n as u64 - 1) + 1);
    assert_eq!(cycles, 2 * (n as u64 - 1) + 2);
    // Every cell holds the same patch: merged at every hop, the totals add up.
    let mut all = empty.clone();
    for r in all.iter_mut() {
        r.add(Some(3), 2);
    }
    let (t, _, messages) = reduce_cost(n, &all);
    assert_eq!(t, vec![(3, 2 * (n * n) as i64)]);
    assert_eq!(messages, 2 * (n * n) as u64);
}

#[test]
fn bad_input_is_a_clear_error() {
    // No emitter.
    let mesh = room(0.0);
    let scene = loaded(&mesh, 16);
    let p = patches_of(&mesh, &scene, 6.0);
    let e = solve(&scene.grid, &scene.fit, &scene.source_face, &p.patches, &cfg(3), |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("nothing emits"), "{e}");
    // Zero-area patch.
    let mesh = room(1.0);
    let mut p = patches_of(&mesh, &scene, 6.0);
    p.patches[2].area = 0.0;
    let e = solve(&scene.grid, &scene.fit, &scene.source_face, &p.patches, &cfg(3), |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("zero or invalid area"), "{e}");
    // Patches too small for the cells' patch maps (a column crosses more than 32 patches).
    let scene = loaded(&mesh, 48);
    let p = patches_of(&mesh, &scene, 1.5);
    let e = solve(&scene.grid, &scene.fit, &scene.source_face, &p.patches, &cfg(3), |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("raise --patch-size"), "{e}");
}

/// The machine's form factor row of shooter `i`: its quanta over the quanta emitted, its own
/// entry and negative (rounding) entries dropped, as the supervisor takes them.
fn machine_row(scene: &LoadedScene, map: &PatchMap, p: &Patches, i: usize, c: &RadiosityConfig) -> Vec<f64> {
    let shot = shoot(&scene.grid, &scene.fit, map, &p.patches, i, c).unwrap();
    let mut row = vec![0.0; p.patches.len()];
    for (j, q) in shot.totals {
        if j as usize != i && q > 0 {
            row[j as usize] = q as f64 / shot.log.emitted as f64;
        }
    }
    row
}

#[test]
fn the_supervisor_shoots_like_the_reference_solver_given_the_same_form_factors() {
    let mesh = room(1.0);
    let scene = loaded(&mesh, 16);
    let p = patches_of(&mesh, &scene, 8.0);
    let c = cfg(5);
    let s = solve(&scene.grid, &scene.fit, &scene.source_face, &p.patches, &c, |_, _| {}).unwrap();
    let map = map_patches(&scene.grid, &scene.fit, &scene.source_face, &p.patches).unwrap();
    let shoot_cfg = ShootConfig { stop_fraction: 0.0, max_shots: 5 };
    let r = progressive(&p.patches, &shoot_cfg, |i| Ok(machine_row(&scene, &map, &p, i, &c))).unwrap();
    let order: Vec<usize> = s.shots.iter().map(|x| x.patch).collect();
    assert_eq!(order, r.shots.iter().map(|x| x.patch).collect::<Vec<_>>());
    for (a, b) in s.radiosity.iter().zip(&r.radiosity) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() <= 1e-12 * b[k].abs().max(1.0), "{a:?} vs {b:?}");
        }
    }
    assert!((s.residual - r.residual).abs() < 1e-12);
}

/// The machine's row against the exact point form factor (the closed form of the contour
/// integral, `truth::closed_form::point_to_polygon`) from the pushed source: in the empty room
/// every patch sees every other, so the only errors are the grid's. A patch's voxels are
/// assigned by their centres, so receivers gain or lose at most a strip one voxel wide along
/// each edge: |ΔF_j| ≤ F_j · perimeter_j · 1 voxel / area_j (rays and quanta are far finer).
#[test]
fn the_machine_form_factors_approach_the_exact_point_form_factors() {
    let mesh = room(1.0);
    let scene = loaded(&mesh, 48);
    let p = subdivide(&mesh, 0.5, 1000).unwrap();
    let map = map_patches(&scene.grid, &scene.fit, &scene.source_face, &p.patches).unwrap();
    let c = cfg(1);
    let voxel = scene.fit.voxel;
    for i in [0usize, 5, 20] {
        let m = machine_row(&scene, &map, &p, i, &c);
        let pi = &p.patches[i];
        let x = pi.centroid + pi.normal * (c.offset * voxel);
        let mut sum = 0.0;
        for (j, pj) in p.patches.iter().enumerate().filter(|&(j, _)| j != i) {
            let f = point_to_polygon(x, pi.normal, &pj.polygon, pj.normal);
            let perimeter: f64 =
                (0..pj.polygon.len()).map(|k| pj.polygon[k].distance(pj.polygon[(k + 1) % pj.polygon.len()])).sum();
            let bound = f * perimeter * voxel / pj.area + 1e-6;
            assert!((m[j] - f).abs() <= bound, "F[{i}][{j}]: machine {} vs exact {f} (bound {bound})", m[j]);
            sum += m[j];
        }
        // A closed room: every quantum lands on a patch (the shooter's own wall gets none).
        assert!((sum - 1.0).abs() < 1e-6, "Σ F[{i}] = {sum}");
    }
}

/// The `radiosity` job through the binary, run to a residual: it says it converged, its
/// per-shot CSV shows the residual falling to the stopping fraction (never rising: Σ_j F_ij ≤ 1
/// and ρ < 1 on every patch of the Cornell box), and it draws that curve as a PNG beside the
/// f64 reference's.
#[test]
fn the_radiosity_job_converges_and_plots_its_residual() {
    let dir = std::env::temp_dir().join(format!("rc2-radiosity-job-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let (stats, shots, plot) = (file("s.json"), file("shots.csv"), file("residual.png"));
    let args = [
        "--threads",
        "1",
        "radiosity",
        "cornell",
        "--n",
        "24",
        "--patch-size",
        "8",
        "--residual",
        "0.3",
        "--reference",
        "--quiet",
        "--stats",
        &stats,
        "--shots-csv",
        &shots,
        "--residual-plot",
        &plot,
        "--patches-csv",
        &file("p.csv"),
    ];
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_host-sim")).args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(json["stop"], "Converged", "{json}");
    let csv = std::fs::read_to_string(&shots).unwrap();
    let mut lines = csv.lines();
    let column = lines.next().unwrap().split(',').position(|h| h == "residual_after").unwrap();
    let residuals: Vec<f64> = lines.map(|l| l.split(',').nth(column).unwrap().parse().unwrap()).collect();
    assert_eq!(residuals.len() as u64, json["shots"].as_u64().unwrap());
    assert!(residuals.windows(2).all(|w| w[1] <= w[0] + 1e-12), "{residuals:?}");
    let (last, before) = (residuals[residuals.len() - 1], residuals[residuals.len() - 2]);
    assert!(last <= 0.3 && before > 0.3, "stopped at the first shot below 0.3: {before} then {last}");
    let png = std::fs::read(&plot).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert!(err.contains(&format!("wrote {plot}")), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
