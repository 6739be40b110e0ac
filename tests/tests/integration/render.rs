//! Shading and the rendered image, each part against what justifies it:
//!
//! * **Arithmetic.** The cell's micromath shading equals the f64 formula within one 8-bit level
//!   on random inputs (f32 rounding can move a value across a rounding boundary).
//! * **Light.** The image is exactly the per-ray oracle's lit state shaded: with every pixel's
//!   lit mask taken from `rc2_tests::oracle` (every ray of the lattice traced on its own, the
//!   plane rule's visible surfaces or the thesis's first voxels) instead of the machine's
//!   diffusion, the image is the same, pixel for pixel and mask for mask; and the render is
//!   deterministic (same bytes twice).
//! * **Coverage.** Against the f64 reference (`host_sim::truth::refrender`, rays through the pixel
//!   centres against the unquantised mesh), a pixel may only be covered in one of the two
//!   images where its centre lies within 1/32 voxel (the lattice's rounding, below) of the
//!   edge of a projected triangle.
//! * **Contact shadows from the neighbours.** The pixels only a neighbouring column's triangles
//!   shadow (the oracle's rational crossing test) are unlit, and the f64 reference shadows
//!   them up to the vertex lattice's rounding.
//!
//! Not asserted: how often the machine's shadows disagree with the f64 reference's. That is a
//! property of the discrete method (rays on a lattice, surfaces as voxels and planes; see
//! docs/LIGHTING.md), measured by `host-sim render --reference` and printed here; a threshold
//! read off today's output would only pin today's numbers. `shadows.rs` checks the part
//! geometry decides: no light through a solid.

use std::collections::BTreeMap;

use cell_core::beam::FracBits;
use cell_core::light::Policy;
use cell_core::lit::LitRule;
use cell_core::shade::{shade, Material as CellMaterial, NormalMode, PointLight, ShadeParams};
use host_sim::config::Preset;
use host_sim::jobs::render::{RenderConfig, RenderInput};
use host_sim::machine::lighting::diffuse::LightConfig;
use host_sim::machine::loading::loaded_scene::LoadedScene;
use host_sim::machine::shading::pixels::{Image, Seen};
use host_sim::precompute::{Contour, LoadConfig, Thickness};
use host_sim::scene::{Material, Mesh};
use host_sim::truth::refrender::{shade_f64, RefLight};
use proptest::prelude::*;
use rc2_tests::oracle::lit::trace_all_plane;
use rc2_tests::oracle::rays::trace_all;

use crate::common;

/// Tolerance of the cell's shading against f64 on the same inputs: one 8-bit level (the cell's
/// math is exact up to f32 rounding, which can move a value across a rounding boundary).
const TOLERANCE_LEVELS: u8 = 1;

fn unit(v: [f32; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / l)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    #[test]
    fn cell_shading_matches_f64(
        n in prop::array::uniform3(-1.0f32..1.0),
        p in prop::array::uniform3(0.0f32..128.0),
        lights in prop::collection::vec((prop::array::uniform3(-20.0f32..150.0), prop::array::uniform3(0.0f32..1.0)), 1..4),
        mask in 0u32..16,
        kd in prop::array::uniform3(0.0f32..1.0),
        ks in prop::array::uniform3(0.0f32..0.6),
        ns in 1.0f32..200.0,
        ka in prop::array::uniform3(0.0f32..0.3),
    ) {
        prop_assume!(n.iter().map(|c| c * c).sum::<f32>() > 1e-3);
        let mut nn = unit(n);
        if nn[2] > 0.0 { nn = nn.map(|c| -c); } // facing the viewer (VIEW = −z)
        let ns = ns.round(); // the cell raises to an integer power
        let m = Material { name: "m".into(), ka, kd, ks, ns, ke: [0.0; 3], ..Material::default() };
        let cm = CellMaterial { ka, kd, ks, ns, ke: [0.0; 3] };
        let pl: Vec<PointLight> = lights.iter().map(|(pos, color)| PointLight { pos: *pos, color: *color }).collect();
        let rl: Vec<RefLight> = lights.iter().map(|(pos, color)| RefLight { pos: pos.map(|c| c as f64), color: color.map(|c| c as f64) }).collect();
        let params = ShadeParams { ambient: [0.2; 3], normal_mode: NormalMode::Facet, eye: cell_core::shade::Eye::Grid };
        let got = shade(p, nn, &cm, &pl, mask, &params);
        let want = shade_f64(p.map(|c| c as f64), nn.map(|c| c as f64), &m, &rl, mask, [0.2; 3]);
        for k in 0..3 {
            prop_assert!(got[k].abs_diff(want[k]) <= TOLERANCE_LEVELS, "channel {}: cell {:?} vs f64 {:?}", k, got, want);
        }
    }
}

fn load(scene: &str, n: u32, thickness: Thickness, contour: Contour) -> (Mesh, LoadedScene) {
    let mesh = host_sim::scene::load(scene).unwrap();
    let loaded =
        host_sim::machine::loading::loaded_scene::load_scene(&mesh, &LoadConfig { n, thickness, contour }).unwrap();
    (mesh, loaded)
}

fn render(
    mesh: &Mesh,
    loaded: &LoadedScene,
    lights: &[[f64; 3]],
    light: LightConfig,
    reference: Option<&host_sim::truth::refrender::RefImage>,
) -> host_sim::jobs::render::Rendered {
    let rcfg = RenderConfig::diffusion(light, NormalMode::Facet);
    let input = RenderInput { reference, ..RenderInput::new(mesh, loaded, lights) };
    host_sim::jobs::render::render(&input, &rcfg, |_, _| {}).unwrap()
}

/// Sources in sixteenths of a voxel, as the oracles take them: the lattice positions the
/// machine's sources sit at.
fn sources16(lights: &[[f64; 3]], n: u32) -> Vec<[i64; 3]> {
    lights
        .iter()
        .enumerate()
        .map(|(i, p)| {
            host_sim::machine::lighting::diffuse::source_at(i, *p, n).unwrap().pos.map(|c| c.to_bits() as i64)
        })
        .collect()
}

/// The image `mesh` shows with the lit state of every pixel taken from the per-ray oracle of
/// `rule` (f fraction bits, D = n − 1), shaded as the render shades.
fn oracle_image(mesh: &Mesh, loaded: &LoadedScene, lights: &[[f64; 3]], rule: LitRule, f: u32) -> Image {
    let g = &loaded.grid;
    let n = g.n as i64;
    let src16 = sources16(lights, g.n);
    let cell_lights = host_sim::machine::shading::pixels::point_lights(lights);
    let seen = match rule {
        LitRule::Plane => {
            let o = trace_all_plane(n, &common::surfaces_of(g), &common::columns_of(g), &src16, n - 1, f);
            let visible: BTreeMap<[i64; 2], u64> = o.visible;
            Seen::Surface(Box::new(move |x, y| visible.get(&[x as i64, y as i64]).map_or(0, |&m| m as u32)))
        }
        LitRule::Thesis => {
            let occupied = |x: i64, y: i64, z: i64| g.cell(x as u32, y as u32).store.occupied(z as u16).is_some();
            let lit = trace_all(n, &occupied, &src16, n - 1, f).lit;
            Seen::FirstVoxel(Box::new(move |x, y, z| lit.get(&[x as i64, y as i64, z as i64]).map_or(0, |&m| m as u32)))
        }
        LitRule::Exact => panic!("exact occluders are checked ray by ray in tests/diffusion.rs, not here"),
    };
    host_sim::machine::shading::pixels::shade_grid_with(mesh, loaded, &cell_lights, &seen, NormalMode::Facet)
}

/// The render's image equals the image of the per-ray oracle's lit state, pixel for pixel; the
/// machine lit something, and not everything.
fn check_against_oracle<F: FracBits>(
    scene: &str,
    n: u32,
    surfaces: (Thickness, Contour),
    lights: &[[f64; 3]],
    light: LightConfig,
) {
    let (mesh, loaded) = load(scene, n, surfaces.0, surfaces.1);
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, lights).unwrap();
    let got = render(&mesh, &loaded, &lights, LightConfig { frac_bits: F::U32, ..light }, None).image;
    let want = oracle_image(&mesh, &loaded, &lights, light.rule, F::U32);
    let what = format!("{scene} n = {n} f = {} {light:?}", F::U32);
    assert_eq!(got.covered, want.covered, "{what}: covered pixels");
    for i in 0..got.rgb.len() {
        let (x, y) = (i as u32 % n, i as u32 / n);
        assert_eq!(got.lit[i], want.lit[i], "{what}: lit mask of pixel ({x}, {y})");
        assert_eq!(got.rgb[i], want.rgb[i], "{what}: colour of pixel ({x}, {y})");
    }
    assert!(got.shading_max_err_levels <= TOLERANCE_LEVELS, "{what}: {}", got.shading_max_err_levels);
    let lit = got.lit.iter().filter(|&&m| m != 0).count();
    let covered = got.covered.iter().filter(|&&c| c).count();
    assert!(lit > 0 && lit < covered, "{what}: {lit} lit of {covered} covered pixels");
}

/// The `render` preset's machine (standard + conservative surfaces, f = 0, radial + merge, the
/// visible-only lit store with the hidden-voxel skip) under the plane rule from the source
/// voxel, and the other modes the README documents, against the per-ray oracles of those
/// rules. The preset's own rule, exact occluders, is checked ray by ray in
/// `tests/diffusion.rs` and on bureau1 below.
#[test]
fn image_is_the_per_ray_oracles_lit_state_shaded() {
    use cell_core::beam::frac::{U0, U1};
    let tunnel_free = (Thickness::Standard, Contour::Conservative);
    let thesis_surfaces = (Thickness::Naive, Contour::Projected);
    let render_defaults =
        LightConfig { rule: LitRule::Plane, rays: cell_core::beam::Origin::SourceVoxel, ..Preset::Render.light() };
    check_against_oracle::<U0>("cornell", 32, tunnel_free, &[], render_defaults);
    // The full lit store, the wavefront policy, f = 1 (the accuracy knob), two lights.
    let full = LightConfig { policy: Policy::Wavefront, ..host_sim::config::plane_rule() };
    check_against_oracle::<U1>("cornell", 24, tunnel_free, &[], full);
    let two = [[0.3, 0.9, 0.25], [0.75, 0.7, 0.5]];
    check_against_oracle::<U0>("cow-floor", 32, tunnel_free, &two, render_defaults);
    // The thesis's lit rule on the thesis's surfaces (the first occupied voxel is shown).
    let thesis = LightConfig {
        rule: LitRule::Thesis,
        policy: Policy::Thesis,
        merge: false,
        fa: 4,
        ..host_sim::config::plane_rule()
    };
    check_against_oracle::<U0>("cornell", 24, thesis_surfaces, &[], thesis);
    check_against_oracle::<U0>("teapot-floor", 24, thesis_surfaces, &two, thesis);
}

#[test]
fn render_is_deterministic() {
    let (mesh, loaded) = load("cornell", 32, Thickness::Standard, Contour::Conservative);
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
    let cfg = LightConfig { lit_visible_only: true, skip_hidden: true, ..host_sim::config::plane_rule() };
    let a = render(&mesh, &loaded, &lights, cfg, None).image;
    let b = render(&mesh, &loaded, &lights, cfg, None).image;
    assert_eq!(a.rgb, b.rgb, "same input, same pixels");
    let dir = std::env::temp_dir().join(format!("rc2-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (p, q) = (dir.join("a.png"), dir.join("b.png"));
    host_sim::report::png::write_png(&p, a.n, &a.rgb).unwrap();
    host_sim::report::png::write_png(&q, b.n, &b.rgb).unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(&q).unwrap(), "same bytes");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Whether segment `a`–`b` meets the square of half-side `r` around `c` (Liang–Barsky clip).
fn segment_meets_square(a: [f64; 2], b: [f64; 2], c: [f64; 2], r: f64) -> bool {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..2 {
        let d = b[k] - a[k];
        let (lo, hi) = (c[k] - r - a[k], c[k] + r - a[k]);
        if d == 0.0 {
            if lo > 0.0 || hi < 0.0 {
                return false;
            }
        } else {
            let (u, v) = if d > 0.0 { (lo / d, hi / d) } else { (hi / d, lo / d) };
            t0 = t0.max(u);
            t1 = t1.min(v);
        }
    }
    t0 <= t1
}

/// Coverage against the f64 reference, with the margin the lattice gives.
///
/// The machine sees the mesh with its vertices rounded to the 1/16-voxel lattice
/// (`Fit::to_lattice`), so each coordinate of each vertex moves by at most 1/32 voxel, and so
/// does each point of each edge (an edge's points are convex combinations of its ends). Under
/// the render defaults a pixel is covered in the machine's image iff its centre line meets a
/// quantised facet (`cell_core::visible`: exact, and standard + conservative surfaces leave no
/// facet without voxels), and in the reference's iff it meets an unquantised triangle. If the
/// pixel centre c lies in the projection of one of a triangle T and its quantised T′ but not of
/// the other, then moving the vertices linearly from one to the other, c crosses an edge of an
/// intermediate triangle, whose points each lie within 1/32 voxel (per axis) of T's edge:
/// c is within 1/32 voxel of the projected boundary of T. Every disagreeing pixel must be so
/// (plus 10⁻⁹ for f64 rounding).
#[test]
fn coverage_differs_from_the_f64_reference_only_at_projected_edges() {
    const MARGIN: f64 = 1.0 / 32.0 + 1e-9;
    for (scene, n) in [("cow", 64u32), ("teapot", 48), ("suzanne", 48)] {
        let (mesh, loaded) = load(scene, n, Thickness::Standard, Contour::Conservative);
        let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
        let cfg = LightConfig { lit_visible_only: true, skip_hidden: true, ..host_sim::config::plane_rule() };
        let rcfg = RenderConfig::diffusion(cfg, NormalMode::Facet);
        let reference = host_sim::jobs::render::reference_image(&mesh, &loaded, &lights, &rcfg).unwrap();
        let r = render(&mesh, &loaded, &lights, cfg, Some(&reference));
        // Triangles projected on the image plane, in voxel units from the grid's low corner
        // (pixel (x, y) has its centre at (x + ½, y + ½)).
        let (tris, _) = host_sim::truth::refrender::mesh_triangles(&mesh).unwrap();
        let fit = loaded.fit;
        let to_grid = |p: [f64; 3]| [(p[0] - fit.origin[0]) / fit.voxel, (p[1] - fit.origin[1]) / fit.voxel];
        let projected: Vec<[[f64; 2]; 3]> = tris.iter().map(|t| t.map(to_grid)).collect();
        let (mut machine_only, mut reference_only) = (0, 0);
        for y in 0..n {
            for x in 0..n {
                let i = (y * n + x) as usize;
                let (m, f) = (r.image.covered[i], reference.covered[i]);
                if m == f {
                    continue;
                }
                if m {
                    machine_only += 1;
                } else {
                    reference_only += 1;
                }
                let c = [x as f64 + 0.5, y as f64 + 0.5];
                let near_edge =
                    projected.iter().any(|t| (0..3).any(|k| segment_meets_square(t[k], t[(k + 1) % 3], c, MARGIN)));
                assert!(
                    near_edge,
                    "{scene} n = {n}: pixel ({x}, {y}) covered by {} only, its centre is farther than 1/32 voxel \
                     from every projected edge",
                    if m { "the machine" } else { "the reference" }
                );
            }
        }
        let covered = reference.covered.iter().filter(|&&c| c).count();
        // A silhouette to test: covered and uncovered pixels, many of each.
        assert!(
            covered > (n * n / 8) as usize && covered < (n * n * 7 / 8) as usize,
            "{scene}: the reference covers {covered} of {} pixels",
            n * n
        );
        // For information (`--nocapture`): how the discrete light compares with f64.
        eprintln!(
            "{scene} n = {n}: coverage differs on {machine_only} + {reference_only} of {covered} pixels (all at \
             projected edges); against the f64 reference {:?}",
            r.stats.reference
        );
    }
}

#[test]
fn segment_square_test() {
    let (a, b) = ([0.0, 0.0], [4.0, 2.0]);
    assert!(segment_meets_square(a, b, [2.0, 1.0], 0.01)); // on the segment
    assert!(segment_meets_square(a, b, [2.0, 1.5], 0.5)); // the square's corner touches it
    assert!(!segment_meets_square(a, b, [2.0, 1.6], 0.05));
    assert!(!segment_meets_square(a, b, [5.0, 2.5], 0.4)); // beyond the end
    assert!(segment_meets_square(a, b, [4.3, 2.0], 0.3)); // the end inside
    assert!(segment_meets_square([1.0, 0.0], [1.0, 3.0], [1.2, 2.0], 0.25)); // vertical
    assert!(!segment_meets_square([1.0, 0.0], [1.0, 3.0], [1.3, 2.0], 0.25));
}

/// A front quad over a back wall, its top edge `dy` voxel from the centre line of pixel row 20
/// (n = 34: the wall's unit square spans 32 voxels, the row's centre line at y = 19.5/32).
fn ledge(dy: f64) -> Mesh {
    let top = (19.5 + dy) / 32.0;
    let obj = format!(
        "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nv 0.2 0.2 0.5\nv 0.8 0.2 0.5\nv 0.8 {top} 0.5\nv 0.2 {top} 0.5\n\
         f 1 2 3 4\nf 5 6 7 8\n"
    );
    host_sim::scene::mesh::load_obj_bytes("ledge", obj.as_bytes(), None).unwrap()
}

/// An edge a fiftieth of a voxel beside a row of pixel centres lands on it when its vertices
/// are rounded to the 1/16-voxel lattice; the row then shows what the unrounded mesh shows
/// there (the f64 reference's facet, pixel for pixel): the front quad with its edge just above
/// the row, the wall with it just below, and the front quad with it exactly on the lattice
/// (its points are its own). Before the host marked such edges ([`cell_core::facet::EdgeOff`])
/// the row showed the front quad either way.
#[test]
fn a_row_of_pixel_centres_the_rounding_puts_on_an_edge_shows_the_mesh_side() {
    let n = 34;
    for dy in [0.02, -0.02, 0.0, 0.03, -0.03] {
        let mesh = ledge(dy);
        let (loaded, lights) = {
            let cfg = LoadConfig { n, thickness: Thickness::Standard, contour: Contour::Conservative };
            let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &cfg).unwrap();
            let lights =
                host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[[0.5, 0.5, 0.0]]).unwrap();
            (loaded, lights)
        };
        let fit = loaded.fit;
        assert_eq!(fit.to_lattice([0.5, (19.5 + dy) / 32.0, 0.5])[1], 16 * 20 + 8, "dy {dy}: the edge lands on row 20");
        let rcfg = RenderConfig::diffusion(host_sim::config::plane_rule(), NormalMode::Facet);
        let reference = host_sim::jobs::render::reference_image(&mesh, &loaded, &lights, &rcfg).unwrap();
        let mut front = 0;
        for x in 10..=22 {
            let i = (20 * n + x) as usize;
            let vis = loaded.grid.cell(x, 20).visible.expect("the wall is behind every pixel");
            let shown = loaded.source_face[vis.facet as usize];
            assert!(reference.covered[i]);
            assert_eq!(shown, reference.facet[i], "dy {dy}: pixel ({x}, 20) shows face {shown}");
            front += (shown == 1) as u32;
        }
        assert_eq!(front > 0, dy >= 0.0, "dy {dy}: {front} pixels of row 20 show the front quad");
    }
}

/// One quad, the plane y = z/2 (seen from z = −∞ it is tilted in screen space), wound `front`
/// toward the viewer or away from it.
fn tilted_sheet(front: bool) -> Mesh {
    let face = if front { "f 1 4 3 2" } else { "f 1 2 3 4" };
    let obj = format!("v -4 -2 -4\nv 4 -2 -4\nv 4 2 4\nv -4 2 4\n{face}\n");
    host_sim::scene::mesh::load_obj_bytes("tilted-sheet", obj.as_bytes(), None).unwrap()
}

/// A single planar sheet cannot shadow itself: the f64 reference lights every pixel of it
/// whose surface faces the light, and so must the machine — whichever way the sheet is wound,
/// with the same image both ways (an open sheet is two-sided; lit from the side its winding
/// turns away from the light, its rays used to be absorbed by rule 4 as soon as they entered
/// the thick band, before reaching the plane: 61.9 % of the pixels dark at n = 96,
/// docs/LIGHTING.md). The lights graze the sheet at 7° to 25°, above and below the light's
/// principal planes, and the beam diffusion equals the per-ray oracle here.
#[test]
fn a_tilted_sheet_is_lit_wherever_the_reference_sees_the_light() {
    let n = 48;
    let cfg = LightConfig { lit_visible_only: true, skip_hidden: true, ..host_sim::config::plane_rule() };
    let rcfg = RenderConfig::diffusion(cfg, NormalMode::Facet);
    let mut images = Vec::new();
    for front in [false, true] {
        let mesh = tilted_sheet(front);
        let loaded = host_sim::machine::loading::loaded_scene::load_scene(
            &mesh,
            &LoadConfig { n, thickness: Thickness::Standard, contour: Contour::Conservative },
        )
        .unwrap();
        for light in [[0.5, 0.5, 0.2], [0.5, 0.7, 0.2], [0.3, 0.35, 0.05]] {
            let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[light]).unwrap();
            let reference = host_sim::jobs::render::reference_image(&mesh, &loaded, &lights, &rcfg).unwrap();
            let got = render(&mesh, &loaded, &lights, cfg, Some(&reference)).image;
            let want = oracle_image(&mesh, &loaded, &lights, LitRule::Plane, 0);
            assert_eq!(got.lit, want.lit, "front {front}, light {light:?}: the machine equals the per-ray oracle");
            let both: Vec<usize> = (0..got.covered.len()).filter(|&i| got.covered[i] && reference.covered[i]).collect();
            assert!(both.len() > (n * n / 4) as usize, "the sheet covers a good part of the image");
            assert!(both.iter().all(|&i| reference.lit[i] == 1), "the reference lights the whole sheet");
            let dark: Vec<(u32, u32)> =
                both.iter().filter(|&&i| got.lit[i] == 0).map(|&i| (i as u32 % n, i as u32 / n)).collect();
            assert!(dark.is_empty(), "front {front}, light {light:?}: {} pixels dark: {dark:?}", dark.len());
            images.push(got.lit);
        }
    }
    let (away, toward) = images.split_at(images.len() / 2);
    assert_eq!(away, toward, "the same lit pixels whichever way the sheet is wound");
}

/// The distance between segments [p0, p1] and [q0, q1] (f64; the closest points by clamped
/// parameters, then each end against the other segment).
fn segment_distance(p0: [f64; 3], p1: [f64; 3], q0: [f64; 3], q1: [f64; 3]) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let at = |a: [f64; 3], d: [f64; 3], t: f64| [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]];
    let point_seg = |x: [f64; 3], a: [f64; 3], b: [f64; 3]| {
        let d = sub(b, a);
        let t = if dot(d, d) > 0.0 { (dot(sub(x, a), d) / dot(d, d)).clamp(0.0, 1.0) } else { 0.0 };
        let e = sub(x, at(a, d, t));
        dot(e, e).sqrt()
    };
    let (d1, d2, r) = (sub(p1, p0), sub(q1, q0), sub(p0, q0));
    let (a, e, b, c, f) = (dot(d1, d1), dot(d2, d2), dot(d1, d2), dot(d1, r), dot(d2, r));
    let den = a * e - b * b;
    let mut best = [point_seg(p0, q0, q1), point_seg(p1, q0, q1), point_seg(q0, p0, p1), point_seg(q1, p0, p1)]
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    if den > 1e-12 {
        let (s, t) = (((b * f - c * e) / den).clamp(0.0, 1.0), ((a * f - b * c) / den).clamp(0.0, 1.0));
        let g = sub(at(p0, d1, s), at(q0, d2, t));
        best = best.min(dot(g, g).sqrt());
    }
    best
}

#[test]
fn segment_distance_by_hand() {
    let d = segment_distance([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, -1.0], [1.0, 1.0, 1.0]);
    assert!((d - 1.0).abs() < 1e-12, "crossing lines a unit apart: {d}");
    let d = segment_distance([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [3.0, 0.0, 0.0], [4.0, 0.0, 0.0]);
    assert!((d - 2.0).abs() < 1e-12, "collinear, two apart: {d}");
}

/// The neighbours' contact answers (`cell_core::receiver`, "The neighbours' triangles") darken
/// pixels the mesh shadows, up to the vertex lattice. On bureau1, whose bookcase, shelves and
/// drawers cast shadows from within a voxel or two, the pixels whose contact segment a
/// triangle of a neighbouring column crosses and none of their own column's does — found here
/// with the oracle's rational crossing test (`oracle::exact::segment_crosses`, not the cell's
/// Plücker signs) — exist and are unlit in the machine's image; and each is in shadow in the
/// f64 reference unless the segment passes within the lattice's rounding of an edge of the
/// triangle that crossed it (its vertices moved up to 1/32 voxel per axis: √3/32).
#[test]
fn the_neighbours_contact_answers_darken_pixels_the_mesh_shadows() {
    use cell_core::beam::{frac::U0, FarDistance};
    use cell_core::light::Port;
    use cell_core::occluder::Triangle;
    use cell_core::receiver::{target, POINT_UNITS};
    use rc2_tests::oracle::exact::segment_crosses;
    let n = 128;
    let (mesh, loaded) = load("bureau1", n, Thickness::Standard, Contour::Conservative);
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
    // What a flagless `host-sim render` runs.
    let cfg = Preset::Render.light();
    let rcfg = RenderConfig::diffusion(cfg, NormalMode::Facet);
    let reference = host_sim::jobs::render::reference_image(&mesh, &loaded, &lights, &rcfg).unwrap();
    let got = render(&mesh, &loaded, &lights, cfg, Some(&reference)).image;
    let source = cfg.source(0, lights[0], n).unwrap();
    let far = FarDistance::<U0>::new(n - 1).unwrap();
    // The triangles of column (x, y) the segment crosses.
    let crossing = |x: i64, y: i64, seg: [[i64; 3]; 2]| -> Vec<Triangle> {
        if !((0..n as i64).contains(&x) && (0..n as i64).contains(&y)) {
            return Vec::new();
        }
        let tris = loaded.grid.triangles.column(x as u32, y as u32).iter();
        tris.filter(|t| segment_crosses(&t.vertices().map(|v| v.map(i64::from)), seg[0], seg[1], POINT_UNITS / 16))
            .copied()
            .collect()
    };
    let voxels = |p: [i64; 3]| p.map(|c| c as f64 / POINT_UNITS as f64);
    let (mut darkened, mut by_rounding) = (0, 0);
    for c in &loaded.grid.cells {
        let (x, y) = (c.x as i64, c.y as i64);
        let Some(seg) = c.visible.and_then(|v| target(x as i32, y as i32, &v, &source, far)).and_then(|t| t.contact)
        else {
            continue;
        };
        let around: Vec<Triangle> = Port::ALL
            .iter()
            .map(|p| p.delta())
            .flat_map(|(dx, dy)| crossing(x + dx as i64, y + dy as i64, seg))
            .collect();
        if around.is_empty() || !crossing(x, y, seg).is_empty() {
            continue;
        }
        darkened += 1;
        let i = (c.y as u32 * n + c.x as u32) as usize;
        assert_eq!(got.lit[i] & 1, 0, "pixel ({x}, {y}): the machine lights it");
        if reference.lit[i] & 1 != 0 {
            // Vertices in sixteenths of a voxel from the voxel centres' lattice.
            let near_edge = around.iter().any(|t| {
                let v = t.vertices().map(|p| p.map(|c| c as f64 / 16.0));
                (0..3).any(|e| {
                    segment_distance(voxels(seg[0]), voxels(seg[1]), v[e], v[(e + 1) % 3]) <= 3f64.sqrt() / 32.0
                })
            });
            assert!(near_edge, "pixel ({x}, {y}): the reference lights it, and no crossed edge lies within rounding");
            by_rounding += 1;
        }
    }
    println!("bureau1 n = {n}: {darkened} pixels in a contact shadow only a neighbour's triangles cast, {by_rounding} lit by the reference within the lattice's rounding");
    assert!(darkened > 0, "bureau1 has shadows cast from one column over");
}
