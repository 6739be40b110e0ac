//! Mirror reflections on the grid (thesis §1.3.2, ch. 5): the distributed ray
//! tree against a sequential per-ray oracle, a flat mirror against continuous geometry, and
//! depth 0 against the plain render.

use cell_core::dexel::Dexel;
use cell_core::ray::{Connectivity, Q};
use cell_core::reflect::{
    combine, hit_normal, reflected_dir, to_answer, toward_origin, Answer, HitPoint, ReflectNormal,
};
use cell_core::route::RoutePolicy;
use cell_core::shade::{encode, facing_mask, shade_linear_toward, NormalMode};
use host_sim::jobs::render::{reference_image, render, RenderConfig, RenderInput, RenderLighting, Rendered};
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights, LoadedScene};
use host_sim::machine::rays::mirror::{ray_span, reflect, ReflectConfig, ShadeEnv};
use host_sim::precompute::LoadConfig;
use host_sim::scene::{Mesh, SceneLight};
use rc2_tests::oracle::lines::{walk18, walk26, walk6};

fn render_cfg() -> RenderConfig {
    RenderConfig::diffusion(
        host_sim::machine::lighting::diffuse::LightConfig { fa: 16, ..host_sim::config::plane_rule() },
        NormalMode::Facet,
    )
}

/// The plain render with the reflection phase `cfg` after it.
fn with_reflections(cfg: ReflectConfig) -> RenderConfig {
    RenderConfig { lighting: RenderLighting::Reflections(cfg), ..render_cfg() }
}

/// Render with reflections; the image and the reflection counters.
fn render_reflect(
    input: &RenderInput<'_>,
    cfg: ReflectConfig,
) -> (Rendered, host_sim::machine::rays::mirror::ReflectCounts) {
    let mut r = render(input, &with_reflections(cfg), |_, _| {}).unwrap();
    let counts = r.reflections.take().expect("a render with reflections counts them");
    (r, counts)
}

fn load(mesh: &Mesh, n: u32) -> (LoadedScene, Vec<[f64; 3]>) {
    let cfg = LoadConfig::thin(n);
    let loaded = load_scene(mesh, &cfg).unwrap();
    let lights = resolve_lights(mesh, &loaded, &[]).unwrap();
    (loaded, lights)
}

fn config(depth: u8, conn: Connectivity, fa: usize, route: RoutePolicy) -> ReflectConfig {
    ReflectConfig {
        depth,
        threshold: 0.01,
        normal: ReflectNormal::Facet,
        hit: HitPoint::Centre,
        skip_own_facet: true,
        connectivity: conn,
        fa,
        route,
    }
}

/// The oracle's tally of one tree.
#[derive(Default)]
struct Tally {
    rays: u64,
    hits: u64,
    waits: u64,
    max_level: u8,
}

/// Where a reflected ray leaves voxel `at` (dexel `d`) under `hit` (thesis §5.3), for the
/// incident line `origin + t·incident` (lattice units) that entered it by the faces `entry`:
/// continuous geometry in f64 — the voxel's centre, the point of the last entered face on the
/// line, or the line's point on the dexel's plane — rounded half up to the lattice and kept
/// inside the voxel.
fn oracle_hit(hit: HitPoint, at: [i64; 3], d: &Dexel, origin: [i64; 3], incident: [i32; 3], entry: u8) -> [i64; 3] {
    let q = Q as i64;
    let centre = at.map(|c| c * q);
    let dir = incident.map(i64::from);
    let on_line = |axis: usize, value: i64| -> [f64; 3] {
        // The line's point whose coordinate `axis` is `value`.
        [0, 1, 2].map(|j| {
            if j == axis {
                value as f64
            } else {
                origin[j] as f64 + ((value - origin[axis]) * dir[j]) as f64 / dir[axis] as f64
            }
        })
    };
    let p: Option<[f64; 3]> = match hit {
        HitPoint::Centre => None,
        HitPoint::Edge => {
            let mut best: Option<(f64, usize)> = None;
            for k in (0..3).filter(|&k| entry & (1 << k) != 0 && dir[k] != 0) {
                let face = centre[k] - dir[k].signum() * q / 2;
                let t = (face - origin[k]) as f64 / dir[k] as f64;
                if best.is_none_or(|(b, _)| t > b) {
                    best = Some((t, k));
                }
            }
            best.map(|(_, k)| on_line(k, centre[k] - dir[k].signum() * q / 2))
        }
        HitPoint::Exact => {
            let pl = &d.plane;
            let s = 65536i128;
            let g = s * pl.nx as i128 * (origin[0] - q * at[0]) as i128
                + s * pl.ny as i128 * (origin[1] - q * at[1]) as i128
                + pl.nz as i128 * (origin[2] - q * d.span.lo as i64) as i128
                + q as i128 * s * pl.e as i128;
            let slope = s * pl.nx as i128 * dir[0] as i128
                + s * pl.ny as i128 * dir[1] as i128
                + pl.nz as i128 * dir[2] as i128;
            (slope != 0).then(|| [0, 1, 2].map(|j| origin[j] as f64 - g as f64 * dir[j] as f64 / slope as f64))
        }
    };
    match p {
        None => centre,
        Some(p) => [0, 1, 2].map(|k| ((p[k] + 0.5).floor() as i64).clamp(centre[k] - q / 2, centre[k] + q / 2 - 1)),
    }
}

/// Where the walk of a ray leaving lattice point `a` of voxel `at` along `dir` starts: `a` for
/// the 6-connected walk; for the 26/18 walks (whose first voxel is the line's at the first
/// centre plane of their major axis) the line's point on the centre plane of `at`, in f64,
/// rounded half up and kept inside the voxel.
fn oracle_start(a: [i64; 3], dir: [i32; 3], at: [i64; 3], conn: Connectivity) -> [i64; 3] {
    let q = Q as i64;
    if conn == Connectivity::Six {
        return a;
    }
    let d = dir.map(i64::from);
    let mut m = 0;
    for i in 1..3 {
        if d[i].abs() > d[m].abs() {
            m = i;
        }
    }
    let c = at.map(|v| v * q);
    if d[m] == 0 {
        return a;
    }
    [0, 1, 2].map(|i| {
        if i == m {
            c[m]
        } else {
            let v = a[i] as f64 + ((c[m] - a[m]) * d[i]) as f64 / d[m] as f64;
            ((v + 0.5).floor() as i64).clamp(c[i] - q / 2, c[i] + q / 2 - 1)
        }
    })
}

/// Sequential per-ray evaluation of the tree below the voxel `at` (dexel `d`) reached by the
/// ray `origin + t·incident` (entered by `entry`): the reflected line, from the hit point of
/// [`oracle_hit`], walked with the independent f64 walks of `oracle::lines`, the hit found by
/// scanning the columns, then recursion; the same shading and combination formulas as a cell.
/// Returns the answer the voxel's reflected ray brings back.
#[allow(clippy::too_many_arguments)]
fn trace(
    s: &LoadedScene,
    env: &ShadeEnv,
    cfg: &ReflectConfig,
    at: [i64; 3],
    d: &Dexel,
    (origin, incident): ([i64; 3], [i32; 3]),
    entry: u8,
    level: u8,
    weight: f32,
    t: &mut Tally,
) -> Answer {
    t.rays += 1;
    t.max_level = t.max_level.max(level);
    let span = ray_span(s.grid.n, s.grid.depth);
    let Some(dir) = reflected_dir(incident, entry, d.normal, cfg.normal, span) else { return [0; 3] };
    let a = oracle_start(oracle_hit(cfg.hit, at, d, origin, incident, entry), dir, at, cfg.connectivity);
    let b = [0, 1, 2].map(|k| a[k] + dir[k] as i64);
    let path = match cfg.connectivity {
        Connectivity::Six => walk6(a, b, Q as i64),
        Connectivity::Eighteen => walk18(a, b, Q as i64),
        Connectivity::TwentySix => walk26(a, b, Q as i64),
    };
    let (n, depth) = (s.grid.n as i64, s.grid.depth as i64);
    for w in path.windows(2) {
        let (prev, v) = (w[0], w[1]);
        if v[0] < 0 || v[0] >= n || v[1] < 0 || v[1] >= n || v[2] < 0 || v[2] >= depth {
            return [0; 3];
        }
        let cell = s.grid.cell(v[0] as u32, v[1] as u32);
        let Some(h) = cell.store.occupied(v[2] as u16) else { continue };
        if cfg.skip_own_facet && h.facet == d.facet {
            continue;
        }
        t.hits += 1;
        let hit_entry = (0..3).fold(0u8, |m, k| m | ((v[k] != prev[k]) as u8) << k);
        let p = [v[0] as f32, v[1] as f32, v[2] as f32];
        let view = toward_origin(dir);
        let nrm = hit_normal(h, cfg.normal, view, hit_entry, dir);
        let lit = facing_mask(p, nrm, env.lights, (env.mask)(v[0] as u32, v[1] as u32, v[2] as u16));
        let m = env.mats[h.material as usize];
        let kr = env.kr[h.material as usize];
        let local = shade_linear_toward(p, nrm, view, &m, env.lights, lit, &env.params);
        let w2 = weight * kr;
        if kr > 0.0 && level < cfg.depth && w2 >= cfg.threshold {
            t.waits += 1;
            let child = trace(s, env, cfg, v, h, (a, dir), hit_entry, level + 1, w2, t);
            return to_answer(combine(local, kr, child));
        }
        return to_answer(local);
    }
    [0; 3]
}

/// Every surface a mirror (Kr 0.6; the light stays an emitter): deep trees everywhere.
fn hall_of_mirrors() -> Mesh {
    let mut mesh = host_sim::scene::load("cornell-mirror").unwrap();
    mesh.name = "hall-of-mirrors".into();
    for m in &mut mesh.materials {
        if m.ke.iter().all(|&k| k == 0.0) {
            m.kr = m.kr.max(0.6);
        }
    }
    mesh
}

/// The grid's trees (FIFOs of 1, 2 and 16 rays per class, every connectivity, both routings;
/// rays from the voxel's centre, and from the entry point and the exact hit with FIFOs of 16)
/// give every root exactly the answer of the sequential per-ray oracle, so the same pixels;
/// every ray is answered once, and no run stalls.
#[test]
fn grid_trees_match_a_per_ray_oracle() {
    for (mesh, n, depth) in [(host_sim::scene::load("cornell-mirror").unwrap(), 32, 3), (hall_of_mirrors(), 20, 4)] {
        let (s, lights) = load(&mesh, n);
        let (lighting, _) =
            host_sim::machine::lighting::run::run_diffusion(&mesh, &s, &lights, &render_cfg().light, |_, _| {})
                .unwrap();
        let mask = |x, y, z| lighting.mask(x, y, z);
        let pl = host_sim::machine::shading::pixels::point_lights(&lights);
        let env = ShadeEnv::new(&mesh, &pl, NormalMode::Facet, &mask);
        for (hit, conn) in HitPoint::ALL.into_iter().flat_map(|h| Connectivity::ALL.map(|c| (h, c))) {
            let cfg0 = ReflectConfig { hit, ..config(depth, conn, 1, RoutePolicy::DiagonalFirst) };
            // Oracle.
            let mut want: Vec<Option<Answer>> = vec![None; (n * n) as usize];
            let mut want_rgb: Vec<Option<[u8; 3]>> = vec![None; (n * n) as usize];
            let mut t = Tally::default();
            for (i, c) in s.grid.cells.iter().enumerate() {
                let Some(d) = c.store.dexels().first() else { continue };
                let (local, kr) = env.visible_local(c.x, c.y, d);
                if kr > 0.0 && kr >= cfg0.threshold {
                    let at = [c.x as i64, c.y as i64, d.span.lo as i64];
                    let primary = [c.x as i64 * Q as i64, c.y as i64 * Q as i64, 0];
                    let a = trace(&s, &env, &cfg0, at, d, (primary, [0, 0, 1]), 0b100, 1, kr, &mut t);
                    want[i] = Some(a);
                    want_rgb[i] = Some(combine(local, kr, a).map(encode));
                }
            }
            let roots = want.iter().filter(|a| a.is_some()).count() as u64;
            assert!(roots > 20 && t.hits > 0, "{}: the scene has mirrors and their rays hit", mesh.name);
            let fifos = [(1, RoutePolicy::DiagonalFirst), (2, RoutePolicy::Adaptive), (16, RoutePolicy::Adaptive)];
            for &(fa, route) in &fifos[if hit == HitPoint::Centre { 0 } else { 2 }..] {
                let cfg = ReflectConfig { hit, ..config(depth, conn, fa, route) };
                let what = format!("{} n {n} {conn:?} FA {fa} {route:?} hit {hit:?}", mesh.name);
                let r = reflect(&s, &env, &cfg).unwrap_or_else(|e| panic!("{what}: {e}"));
                assert_eq!(r.root_answers, want, "{what}");
                assert_eq!(r.rgb, want_rgb, "{what}");
                let k = &r.counts;
                assert_eq!((k.roots, k.rays, k.hits, k.waits), (roots, t.rays, t.hits, t.waits), "{what}");
                assert_eq!(k.answers, k.rays, "{what}: one answer per ray");
                assert_eq!(k.hits + k.exits, k.rays, "{what}: every ray ends once");
                assert_eq!(k.max_level, t.max_level, "{what}");
                assert!(k.peak_fifo as usize <= fa, "{what}: FIFO limit kept");
                if mesh.name != "cornell-mirror" {
                    assert!(t.max_level == depth && k.cut_depth > 0, "{what}: deep trees, cut at the depth");
                }
            }
        }
    }
}

/// Depth 0 is the plain render byte for byte; with reflections only reflective pixels change,
/// and on `cornell-mirror` the image gets closer to the reflective reference on the mirror.
#[test]
fn depth_zero_is_the_plain_render_and_reflections_only_touch_mirrors() {
    let mesh = host_sim::scene::load("cornell-mirror").unwrap();
    let (s, lights) = load(&mesh, 64);
    let input = RenderInput::new(&mesh, &s, &lights);
    let plain = render(&input, &render_cfg(), |_, _| {}).unwrap();
    let (r0, k0) = render_reflect(&input, config(0, Connectivity::Six, 4, RoutePolicy::Adaptive));
    assert_eq!(r0.image.rgb, plain.image.rgb);
    assert_eq!(k0.rays, 0);
    let cfg = config(2, Connectivity::Six, 4, RoutePolicy::Adaptive);
    let reference = reference_image(&mesh, &s, &lights, &with_reflections(cfg)).unwrap();
    let (r2, k2) = render_reflect(&input.compared_with(&reference), cfg);
    let mirror_mat = mesh.materials.iter().position(|m| m.kr > 0.0).unwrap() as u16;
    let mut changed = 0;
    for (i, c) in s.grid.cells.iter().enumerate() {
        let on_mirror = c.store.dexels().first().is_some_and(|d| d.material == mirror_mat);
        if !on_mirror {
            assert_eq!(r2.image.rgb[i], plain.image.rgb[i], "pixel {i} is not a mirror");
        } else if r2.image.rgb[i] != plain.image.rgb[i] {
            changed += 1;
        }
    }
    assert!(changed > 20, "the mirror shows reflections ({changed} pixels changed)");
    let (with, without) = (k2.mirror_psnr_db.unwrap(), k2.mirror_psnr_without_db.unwrap());
    assert!(
        with > without + 2.0,
        "mirror pixels vs the reflective reference: {with:.2} dB with, {without:.2} dB without"
    );
}

/// A flat 45° mirror under an emissive patch: the patch appears in the mirror exactly where
/// continuous geometry puts its mirror image (the reflected ray of a mirror point goes straight
/// up, +y, at the same x and z), and nowhere else.
#[test]
fn flat_mirror_shows_the_object_at_the_mirrored_position() {
    // Mirror: the plane z = y − 0.2 for y in [0.5, 0.9], x in [0.1, 0.9]; normal (0, 1, −1)/√2
    // toward the eye, so the view ray (0, 0, 1) reflects to (0, 1, 0). Patch: y = 0.95, facing
    // down, x in [0.4, 0.6], z in [0.5, 0.9]. A frame point at (0, 0, 0) and (1, 1, 1) fixes the
    // fit (the tiny far-corner triangles are outside the mirror's view).
    let obj = "mtllib mirror45.mtl\n\
v 0.1 0.5 0.3\nv 0.9 0.5 0.3\nv 0.9 0.9 0.7\nv 0.1 0.9 0.7\n\
v 0.4 0.95 0.5\nv 0.6 0.95 0.5\nv 0.6 0.95 0.9\nv 0.4 0.95 0.9\n\
v 0 0 0\nv 0.02 0 0\nv 0 0.02 0\nv 1 1 1\nv 0.98 1 1\nv 1 0.98 1\n\
usemtl mirror\nf 1 2 3 4\nusemtl patch\nf 5 6 7 8\nusemtl mirror\nf 9 10 11\nf 12 13 14\n";
    let mtl = "newmtl mirror\nKa 0 0 0\nKd 0.05 0.05 0.05\nKs 0 0 0\nKr 0.9\nnewmtl patch\nKe 1 1 1\n";
    let mut mesh = host_sim::scene::load_obj_bytes("mirror45", obj.as_bytes(), Some(mtl.as_bytes())).unwrap();
    mesh.lights = vec![SceneLight::grid([0.5, 0.2, 0.05])];
    let n = 40;
    let (s, lights) = load(&mesh, n);
    let cfg = config(1, Connectivity::Six, 2, RoutePolicy::Adaptive);
    let (r, k) = render_reflect(&RenderInput::new(&mesh, &s, &lights), cfg);
    assert!(k.roots > 100, "{} roots; materials {:?}", k.roots, mesh.materials);
    let mirror_mat = mesh.materials.iter().position(|m| m.name == "mirror").unwrap() as u16;
    let (mut shown, mut dark, mut checked) = (0, 0, 0);
    for c in s.grid.cells.iter() {
        let Some(d) = c.store.dexels().first() else { continue };
        // The mirror point (voxel centre) in world units.
        let w = s.fit.to_world([c.x as i64, c.y as i64, d.span.lo as i64].map(|v| v * Q as i64));
        if d.material != mirror_mat || !(0.5..=0.9).contains(&w[1]) {
            continue;
        }
        let margin = 1.5 * s.fit.voxel;
        let inside = |v: f64, lo: f64, hi: f64| v > lo + margin && v < hi - margin;
        let outside = |v: f64, lo: f64, hi: f64| v < lo - margin || v > hi + margin;
        let px = r.image.rgb[(c.y as u32 * n + c.x as u32) as usize];
        if inside(w[0], 0.4, 0.6) && inside(w[2], 0.5, 0.9) {
            checked += 1;
            assert!(px.iter().all(|&v| v > 200), "({}, {}) at {w:?} must show the patch: {px:?}", c.x, c.y);
            shown += 1;
        } else if outside(w[0], 0.4, 0.6) || outside(w[2], 0.5, 0.9) {
            checked += 1;
            assert!(px.iter().all(|&v| v < 120), "({}, {}) at {w:?} must not show the patch: {px:?}", c.x, c.y);
            dark += 1;
        }
    }
    assert!(shown > 10 && dark > 50 && checked > 100, "shown {shown}, dark {dark}, checked {checked}");
}

/// f64 Snell (the oracle: the reference's own, continuous geometry): unit incident `i`, unit
/// normal `n` (either side), η = n₁/n₂; `None` beyond the critical angle.
fn snell(i: [f64; 3], n: [f64; 3], eta: f64) -> Option<[f64; 3]> {
    host_sim::truth::refrender::refracted(i.into(), n.into(), eta).map(|t| [t.x, t.y, t.z])
}

/// A glass slab (Ni 1.5, Kt 0.9) tilted 45° about y in front of a backdrop whose left half
/// (x < 0.5) glows red and right half green: through the slab every pixel shows the half that
/// continuous geometry puts there — the view ray refracted into the slab by Snell's law, out of
/// it again parallel to itself but shifted sideways (by t·sin(θ − θ_r)/cos θ_r, 4 voxels here),
/// traced in f64 to the backdrop — and with the slab made opaque none does.
#[test]
fn a_tilted_glass_slab_shifts_what_is_behind_it_as_snell_says() {
    let (c, s2) = ([0.5, 0.5, 0.45], std::f64::consts::FRAC_1_SQRT_2);
    // The slab's frame: `a` along its faces (tilted), `b` up, `t` through it (toward +z, −x).
    let (a, b, t) = ([s2, 0.0, s2], [0.0, 1.0, 0.0], [-s2, 0.0, s2]);
    let (ha, hb, ht) = (0.3, 0.3, 0.075);
    let corner = |sa: f64, sb: f64, st: f64| -> [f64; 3] {
        [0, 1, 2].map(|k| c[k] + sa * ha * a[k] + sb * hb * b[k] + st * ht * t[k])
    };
    let mut obj = String::from("mtllib slab.mtl\n");
    let mut v = 0;
    let mut quad = |obj: &mut String, q: [[f64; 3]; 4], mat: &str| {
        // Outward winding: flip the quad if its normal points toward the slab's centre.
        let (e1, e2) = ([0, 1, 2].map(|k| q[1][k] - q[0][k]), [0, 1, 2].map(|k| q[2][k] - q[0][k]));
        let nrm = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
        let out: f64 = (0..3).map(|k| nrm[k] * (q[0][k] - c[k])).sum();
        let q = if out < 0.0 { [q[3], q[2], q[1], q[0]] } else { q };
        obj.push_str(&format!("usemtl {mat}\n"));
        for p in q {
            obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
        }
        obj.push_str(&format!("f {} {} {} {}\n", v + 1, v + 2, v + 3, v + 4));
        v += 4;
    };
    for axis in 0..3 {
        for side in [-1.0, 1.0] {
            let p = |u: f64, w: f64| match axis {
                0 => corner(side, u, w),
                1 => corner(u, side, w),
                _ => corner(u, w, side),
            };
            quad(&mut obj, [p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)], "glass");
        }
    }
    // The backdrop at z = 0.9, split at x = 0.5; frame points fix the fit to the unit cube.
    let z = 0.9;
    quad(&mut obj, [[0.02, 0.02, z], [0.5, 0.02, z], [0.5, 0.98, z], [0.02, 0.98, z]], "red");
    quad(&mut obj, [[0.5, 0.02, z], [0.98, 0.02, z], [0.98, 0.98, z], [0.5, 0.98, z]], "green");
    obj.push_str("usemtl red\nv 0 0 0\nv 0.02 0 0\nv 0 0.02 0\nv 1 1 1\nv 0.98 1 1\nv 1 0.98 1\n");
    obj.push_str(&format!("f {} {} {}\nf {} {} {}\n", v + 1, v + 2, v + 3, v + 4, v + 5, v + 6));
    let mtl = |kt: f64| {
        format!(
            "newmtl glass\nKa 0 0 0\nKd 0.02 0.02 0.02\nKs 0 0 0\nd {}\nNi 1.5\nTf 1 1 1\n\
             newmtl red\nKa 0 0 0\nKd 0 0 0\nKe 1 0 0\nnewmtl green\nKa 0 0 0\nKd 0 0 0\nKe 0 1 0\n",
            1.0 - kt
        )
    };
    let n = 64;
    let cfg = config(3, Connectivity::Six, 4, RoutePolicy::Adaptive);
    let run = |kt: f64| {
        let mut mesh = host_sim::scene::load_obj_bytes("slab", obj.as_bytes(), Some(mtl(kt).as_bytes())).unwrap();
        mesh.lights = vec![SceneLight::grid([0.5, 0.5, 0.02])];
        let (s, lights) = load(&mesh, n);
        let (r, k) = render_reflect(&RenderInput::new(&mesh, &s, &lights), cfg);
        (mesh, s, r, k)
    };
    let (mesh, s, r, k) = run(0.9);
    // (Rays near the slab's top and bottom meet those faces' voxels at grazing angles from
    // inside: total internal reflections there, not in the pixels checked below.)
    assert!(k.refracted > 2 * k.roots && k.roots > 500, "{k:?}");
    let (_, _, opaque, k0) = run(0.0);
    assert_eq!(k0.refracted, 0);
    let glass = mesh.materials.iter().position(|m| m.name == "glass").unwrap() as u16;
    let (front, back) = ([-t[0], 0.0, -t[2]], t);
    // Where the view ray through world point (x, y) meets the plane of normal `nrm` through `p`.
    let meet = |o: [f64; 3], d: [f64; 3], nrm: [f64; 3], p: [f64; 3]| {
        let num: f64 = (0..3).map(|k| nrm[k] * (p[k] - o[k])).sum();
        let den: f64 = (0..3).map(|k| nrm[k] * d[k]).sum();
        let u = num / den;
        [0, 1, 2].map(|k| o[k] + u * d[k])
    };
    let margin = 2.0 * s.fit.voxel;
    let (mut red, mut green, mut shifted) = (0, 0, 0);
    for cell in s.grid.cells.iter() {
        let Some(d) = cell.store.dexels().first() else { continue };
        if d.material != glass {
            continue;
        }
        let w = s.fit.to_world([cell.x as i64, cell.y as i64, d.span.lo as i64].map(|v| v * Q as i64));
        // The continuous path: into the front face, through the slab, out of the back face.
        let o = [w[0], w[1], -1.0];
        let p1 = meet(o, [0.0, 0.0, 1.0], front, corner(0.0, 0.0, -1.0));
        let d1 = snell([0.0, 0.0, 1.0], front, 1.0 / 1.5).unwrap();
        let p2 = meet(p1, d1, back, corner(0.0, 0.0, 1.0));
        let d2 = snell(d1, back, 1.5).unwrap();
        let p3 = meet(p2, d2, [0.0, 0.0, 1.0], [0.0, 0.0, z]);
        // Only rays well inside both faces' extents and away from the seam and the borders.
        let along = |p: [f64; 3]| (0..3).map(|k| (p[k] - c[k]) * a[k]).sum::<f64>();
        let inside = |p: [f64; 3]| along(p).abs() < ha - margin && (p[1] - c[1]).abs() < hb - margin;
        if !(inside(p1) && inside(p2)) || (p3[0] - 0.5).abs() < margin {
            continue;
        }
        let px = r.image.rgb[(cell.y as u32 * n + cell.x as u32) as usize];
        let dark = opaque.image.rgb[(cell.y as u32 * n + cell.x as u32) as usize];
        let at = (cell.x, cell.y, w, p3);
        if p3[0] < 0.5 {
            assert!(px[0] > 150 && px[1] < 60, "{at:?} must show red through the glass: {px:?}");
            red += 1;
        } else {
            assert!(px[1] > 150 && px[0] < 60, "{at:?} must show green through the glass: {px:?}");
            green += 1;
        }
        // Where the shift moves the seam, the straight line of sight would see the other half.
        shifted += ((w[0] < 0.5) != (p3[0] < 0.5)) as u32;
        assert!(dark[0] < 60 && dark[1] < 60, "{at:?}: the opaque slab shows nothing behind it: {dark:?}");
    }
    assert!(red > 100 && green > 100 && shifted > 40, "red {red}, green {green}, shifted {shifted}");
}

/// `cornell-glass` (a glass block and a glass sphere): without refraction only mirrors changed
/// the image; with it every glass pixel carries what its refracted ray brings back, and the
/// glass gets ≥ 2 dB closer to the f64 reference refracting the same way (as the mirror does in
/// the reflection test above); pixels of opaque, non-reflective surfaces do not change.
#[test]
fn glass_pixels_get_closer_to_the_refracting_reference() {
    let mesh = host_sim::scene::load("cornell-glass").unwrap();
    let (s, lights) = load(&mesh, 64);
    let input = RenderInput::new(&mesh, &s, &lights);
    let plain = render(&input, &render_cfg(), |_, _| {}).unwrap();
    let cfg = config(4, Connectivity::Six, 4, RoutePolicy::Adaptive);
    let reference = reference_image(&mesh, &s, &lights, &with_reflections(cfg)).unwrap();
    let (r, k) = render_reflect(&input.compared_with(&reference), cfg);
    assert!(k.refracted > k.roots && k.glass_pixels > 300, "{k:?}");
    for (i, c) in s.grid.cells.iter().enumerate() {
        let Some(d) = c.store.dexels().first() else { continue };
        let m = &mesh.materials[d.material as usize];
        if m.kr == 0.0 && m.kt == 0.0 {
            assert_eq!(r.image.rgb[i], plain.image.rgb[i], "pixel {i} sees neither glass nor a mirror");
        }
    }
    let (with, without) = (k.glass_psnr_db.unwrap(), k.glass_psnr_without_db.unwrap());
    assert!(
        with > without + 2.0,
        "glass pixels vs the refracting reference: {with:.2} dB with, {without:.2} dB without"
    );
    assert!(k.psnr_db.unwrap() > k.psnr_without_db.unwrap(), "{k:?}");
}
