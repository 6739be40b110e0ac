//! Where the plane rule's shadow error comes from (thesis §5.5.6; docs/LIGHTING.md, "What it
//! does not fix"): the per-ray oracle's walk with one part of the rule replaced at a time by
//! exact geometry, each image shaded as the render shades and compared with the f64 reference.
//!
//! ```text
//! cargo run --release -p rc2-tests --example lit_bounds -- teapot-floor 128 [VARIANT ...]
//! ```
//!
//! Variants (all by default):
//! * `rule` — the plane rule as the machine runs it (the image equals `render --view fitted`);
//! * `empty-crossings` — a plane crossed (rule 4's crossing, the terminal step, "behind after
//!   empty space") stops a ray only where the crossing point lies in an occupied voxel;
//! * `exact-occluders` — a ray is stopped exactly where its segment meets a triangle of the
//!   mesh (f64), wherever the rule would stop it: occluders exactly as thin as the mesh.
//!
//! What no variant changes is the receiving side: a lit pixel is lit by at least one lattice ray through its two bracketing voxels; at f = 0
//! about one or two rays cross a pixel's footprint, and the reference samples its centre.
//!
//! f = 0, standard + conservative surfaces, the scene's own lights, the fitted view. f64
//! arithmetic where the variants need it: an experiment, not a cell.

use cell_core::shade::NormalMode;
use host_sim::jobs::render::{reference_image, RenderConfig};
use host_sim::machine::diffuse::LightConfig;
use host_sim::machine::shade::Seen;
use host_sim::precompute::{Contour, LoadConfig, Thickness};
use host_sim::truth::visibility::Reference;
use rayon::prelude::*;
use rc2_tests::oracle::lit::{plane_value, Surface, Visible};
use rc2_tests::oracle::rays::{dir_axes, ray_voxel, source_voxel};
use std::collections::BTreeMap;

#[path = "../tests/common/mod.rs"]
mod common;

/// Which parts of the rule are replaced by exact geometry.
#[derive(Clone, Copy, Default)]
struct Variant {
    empty_crossings: bool,
    exact_occluders: bool,
}

const VARIANTS: [(&str, Variant); 3] = [
    ("rule", Variant { empty_crossings: false, exact_occluders: false }),
    ("empty-crossings", Variant { empty_crossings: true, exact_occluders: false }),
    ("exact-occluders", Variant { empty_crossings: false, exact_occluders: true }),
];

type Surfaces<'a> = &'a (dyn Fn(i64, i64, i64) -> Option<Surface> + Sync);
type Columns<'a> = &'a (dyn Fn(i64, i64) -> Option<Visible> + Sync);

/// One source seen by the walk: the oracle's lattice (D = n − 1, f = 0).
struct Walk<'a> {
    n: i64,
    d: i64,
    src: [i64; 3],
    sv: [i64; 3],
    surfaces: Surfaces<'a>,
    columns: Columns<'a>,
    mesh: &'a Reference,
    origin: [f64; 3],
    voxel: f64,
}

impl Walk<'_> {
    fn value(&self, s: &Surface, p: [i64; 3], dir: usize, a: i64, b: i64, t: i64) -> i128 {
        plane_value(s, p[0], p[1], self.src, dir, a, b, self.d, 0, t)
    }

    /// The ray's point of parameter t, in voxel-centre coordinates.
    fn point(&self, dir: usize, a: i64, b: i64, t: f64) -> [f64; 3] {
        let (w, sg, ua, va) = dir_axes(dir);
        let mut p = [0.0; 3];
        p[w] = self.sv[w] as f64 + sg as f64 * t;
        p[ua] = self.src[ua] as f64 / 16.0 + a as f64 * t / self.d as f64;
        p[va] = self.src[va] as f64 / 16.0 + b as f64 * t / self.d as f64;
        p
    }

    /// Whether the ray's segment between parameters t0 and t1 meets a triangle.
    fn meets_mesh(&self, dir: usize, a: i64, b: i64, t0: f64, t1: f64) -> bool {
        let world = |p: [f64; 3]| [0, 1, 2].map(|i| self.origin[i] + (p[i] + 0.5) * self.voxel);
        !self.mesh.visible(world(self.point(dir, a, b, t0)), world(self.point(dir, a, b, t1)), &[])
    }

    /// Where the ray crosses the plane of `s` (voxel p) between layers t0 and t1: in voxel
    /// coordinates, if it does.
    fn crossing(&self, s: &Surface, p: [i64; 3], (dir, a, b): (usize, i64, i64), t0: i64, t1: i64) -> Option<[f64; 3]> {
        let (v0, v1) = (self.value(s, p, dir, a, b, t0) as f64, self.value(s, p, dir, a, b, t1) as f64);
        (v0 != v1 && (v0 > 0.0) != (v1 > 0.0))
            .then(|| self.point(dir, a, b, t0 as f64 + (t1 - t0) as f64 * v0 / (v0 - v1)))
    }

    /// Whether the ray crossed the plane of `s` between layers t0 and t1 in an occupied voxel
    /// (or did not cross it there at all: then nothing is known, and it counts as occupied).
    fn crossed_in_occupied(&self, s: &Surface, p: [i64; 3], ray: (usize, i64, i64), t0: i64, t1: i64) -> bool {
        let Some(q) = self.crossing(s, p, ray, t0, t1) else { return true };
        let v = q.map(|c| c.round() as i64);
        v.iter().all(|&c| (0..self.n).contains(&c)) && (self.surfaces)(v[0], v[1], v[2]).is_some()
    }

    /// One ray by the plane rule (`rc2_tests::oracle::lit`'s walk, restated) with `var`'s
    /// replacements; pushes the columns whose visible surface it lights.
    fn ray(&self, dir: usize, a: i64, b: i64, var: Variant, out: &mut Vec<[i64; 2]>) {
        let (n, d, z_ray) = (self.n, self.d, dir >= 4);
        let mut terminal: Option<(Surface, [i64; 3], i64)> = None;
        let (mut column, mut outside, mut from_empty) = (None, false, false);
        for k in 0..=d {
            let p = ray_voxel(n, self.src, dir, a, b, d, 0, k);
            if p.iter().any(|&c| !(0..n).contains(&c)) {
                return;
            }
            let next = ray_voxel(n, self.src, dir, a, b, d, 0, k + 1);
            let stays = z_ray && k < d && p[0] == next[0] && p[1] == next[1];
            let own = (self.surfaces)(p[0], p[1], p[2]);
            let prev = (k - 1).max(0);
            let sigma = |s: &Surface, t: i64| self.value(s, p, dir, a, b, t) > 0;
            // Rule 1: the visible surface.
            if let Some(v) = (self.columns)(p[0], p[1]) {
                if (p[2] == v.z_v || p[2] == v.z_v + 1)
                    && sigma(&v.plane, 0)
                    && (sigma(&v.plane, k) || sigma(&v.plane, prev))
                {
                    out.push([p[0], p[1]]);
                }
            }
            let from_outside = std::mem::take(&mut outside);
            // Rule 2: a terminal ray dies.
            if let Some((s, q, tk)) = terminal.take() {
                let dies = if var.exact_occluders {
                    self.meets_mesh(dir, a, b, tk as f64, k as f64)
                } else {
                    !var.empty_crossings || own.is_some() || self.crossed_in_occupied(&s, q, (dir, a, b), tk, k)
                };
                if dies {
                    return;
                }
            }
            // Rule 3: empty space.
            let Some(s) = own else {
                if z_ray && !stays {
                    column = None;
                }
                from_empty = true;
                continue;
            };
            // Rule 4.
            let (was, now, then, faces) = (sigma(&s, prev), sigma(&s, k), sigma(&s, k + 1), sigma(&s, 0));
            let stop = |t0: i64| {
                if var.exact_occluders {
                    self.meets_mesh(dir, a, b, t0 as f64, k as f64)
                } else {
                    !var.empty_crossings || self.crossed_in_occupied(&s, p, (dir, a, b), t0, k)
                }
            };
            if was != now && stop(prev) {
                return;
            }
            let behind = ((from_empty && (faces || !s.two_sided)) || (from_outside && faces)) && !was && !now;
            if behind && stop(0) {
                return;
            }
            if z_ray && stays && column.is_some_and(|c| c != s.lo) {
                return;
            }
            if now != then {
                terminal = Some((s, p, k));
            }
            column = (z_ray && stays).then_some(s.lo);
            outside = now && !stays;
            from_empty = false;
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(scene), Some(n)) = (args.first(), args.get(1).and_then(|s| s.parse::<u32>().ok())) else {
        eprintln!("usage: lit_bounds SCENE N [VARIANT ...]  (variants: rule empty-crossings exact-occluders)");
        std::process::exit(2);
    };
    let chosen: Vec<_> =
        VARIANTS.iter().filter(|(name, _)| args.len() < 3 || args[2..].iter().any(|a| a == name)).collect();
    let mesh = host_sim::scene::load(scene).unwrap_or_else(|e| {
        eprintln!("{scene}: {e:#}");
        std::process::exit(1)
    });
    let cfg = LoadConfig { n, thickness: Thickness::Standard, contour: Contour::Conservative };
    let loaded = host_sim::machine::loaded::load_scene(&mesh, &cfg).expect("load");
    let lights = host_sim::machine::loaded::resolve_lights(&mesh, &loaded, &[]).expect("lights");
    let reference =
        reference_image(&mesh, &loaded, &lights, &RenderConfig::diffusion(LightConfig::default(), NormalMode::Facet))
            .expect("reference");
    let (triangles, facets) = host_sim::truth::refrender::mesh_triangles(&mesh).expect("triangles");
    let exact = Reference::new(triangles, facets).expect("reference mesh");
    let (surfaces, columns) = (common::surfaces_of(&loaded.grid), common::columns_of(&loaded.grid));
    let cell_lights = host_sim::machine::shade::point_lights(&lights);
    println!(
        "{scene} n = {n}: variant, shadow disagreement, PSNR, pixels darker / brighter than the reference (light 1)"
    );
    for (name, var) in chosen {
        let mut lit: BTreeMap<[i64; 2], u32> = BTreeMap::new();
        for (i, light) in lights.iter().enumerate() {
            let src =
                host_sim::machine::diffuse::source_at(i, *light, n).expect("source").pos.map(|c| c.to_bits() as i64);
            let walk = Walk {
                n: n as i64,
                d: n as i64 - 1,
                src,
                sv: source_voxel(src),
                surfaces: &surfaces,
                columns: &columns,
                mesh: &exact,
                origin: loaded.fit.origin,
                voxel: loaded.fit.voxel,
            };
            let m = walk.d;
            let cols: Vec<[i64; 2]> = (0..6usize)
                .into_par_iter()
                .flat_map_iter(|dir| (-m..=m).map(move |a| (dir, a)))
                .flat_map_iter(|(dir, a)| {
                    let mut out = Vec::new();
                    for b in -m..=m {
                        walk.ray(dir, a, b, *var, &mut out);
                    }
                    out
                })
                .collect();
            for c in cols {
                *lit.entry(c).or_insert(0) |= 1 << i;
            }
        }
        let seen = Seen::Surface(Box::new(move |x, y| lit.get(&[x as i64, y as i64]).copied().unwrap_or(0)));
        let img = host_sim::machine::shade::shade_grid_with(&mesh, &loaded, &cell_lights, &seen, NormalMode::Facet);
        let c = host_sim::truth::compare::compare(&img.rgb, &img.covered, &img.lit, &reference);
        let (mut darker, mut brighter) = (0, 0);
        for i in (0..img.lit.len()).filter(|&i| img.covered[i] && reference.covered[i]) {
            match (img.lit[i] & 1).cmp(&(reference.lit[i] & 1)) {
                std::cmp::Ordering::Less => darker += 1,
                std::cmp::Ordering::Greater => brighter += 1,
                std::cmp::Ordering::Equal => {}
            }
        }
        println!("{name:>16}  {:5.2} %  {:5.2} dB  {darker} / {brighter}", c.shadow_disagreement_pct, c.psnr_db);
    }
}
