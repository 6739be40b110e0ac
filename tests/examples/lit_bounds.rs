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
//!   mesh (f64), wherever the rule would stop it: occluders exactly as thin as the mesh;
//! * `exact-source` — the lattice rays leave from the light itself: the machine's ray at layer
//!   k of a face is `S + (u, v)·k/D` with S the light across the face's axis (sixteenths) but
//!   its voxel's centre along it (§4.3's layers are whole voxels from the source voxel), up to
//!   half a voxel from the light; here the ray's distance along the axis is counted from the
//!   light, `k − δ`, so every ray is a true ray from the light.
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
    exact_source: bool,
}

const VARIANTS: [(&str, Variant); 4] = [
    ("rule", Variant { empty_crossings: false, exact_occluders: false, exact_source: false }),
    ("empty-crossings", Variant { empty_crossings: true, exact_occluders: false, exact_source: false }),
    ("exact-occluders", Variant { empty_crossings: false, exact_occluders: true, exact_source: false }),
    ("exact-source", Variant { empty_crossings: false, exact_occluders: false, exact_source: true }),
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
    /// Rays from the light itself (the `exact-source` variant).
    exact_source: bool,
}

impl Walk<'_> {
    /// 16 × the distance along the face's axis from the ray's origin to layer t: 16·t for the
    /// machine's rays, 16·t − sign·(S_w − 16·V_w) from the light itself.
    fn t16(&self, dir: usize, t: i64) -> i128 {
        let (w, sign, _, _) = dir_axes(dir);
        let lead = if self.exact_source { self.src[w] - 16 * self.sv[w] } else { 0 };
        16 * t as i128 - (sign * lead) as i128
    }

    /// The voxel of ray (dir, a, b) at layer k: the oracle's [`ray_voxel`], or the same
    /// rounding (`⌊x + ½⌋`, exact) of the true ray from the light.
    fn voxel(&self, dir: usize, a: i64, b: i64, k: i64) -> [i64; 3] {
        if !self.exact_source {
            return ray_voxel(self.n, self.src, dir, a, b, self.d, 0, k);
        }
        let (w, sign, ua, va) = dir_axes(dir);
        let scale = self.d as i128;
        let across = |c: i64, o: i64| ((c as i128 + 8) * scale + o as i128 * self.t16(dir, k)).div_euclid(16 * scale);
        let mut p = [0; 3];
        p[w] = self.sv[w] + sign * k;
        p[ua] = across(self.src[ua], a) as i64;
        p[va] = across(self.src[va], b) as i64;
        p
    }

    /// `plane_value` of the oracle, or the same scaled plane value at the true ray's point.
    fn value(&self, s: &Surface, p: [i64; 3], dir: usize, a: i64, b: i64, t: i64) -> i128 {
        if !self.exact_source {
            return plane_value(s, p[0], p[1], self.src, dir, a, b, self.d, 0, t);
        }
        let (w, sign, ua, va) = dir_axes(dir);
        let (df, tt) = (self.d as i128, self.t16(dir, t));
        let reference = [p[0] as i128, p[1] as i128, s.lo as i128];
        let mut lp = [0i128; 3];
        lp[w] = 16 * df * (self.sv[w] as i128 + sign as i128 * t as i128 - reference[w]);
        lp[ua] = df * self.src[ua] as i128 + a as i128 * tt - 16 * df * reference[ua];
        lp[va] = df * self.src[va] as i128 + b as i128 * tt - 16 * df * reference[va];
        Self::scaled(s, lp, 16 * df)
    }

    /// `2¹⁶·L·g` from `L·(point − reference)`, as the oracle's `plane_value` combines it.
    fn scaled(s: &Surface, lp: [i128; 3], l: i128) -> i128 {
        (s.nx as i128 * lp[0] + s.ny as i128 * lp[1]) * 65536 + s.nz as i128 * lp[2] + 65536 * l * s.e as i128
    }

    /// Whether the source is on the front side of `s` (voxel p): the layer-0 point of the
    /// machine's rays, or the light itself.
    fn source_in_front(&self, s: &Surface, p: [i64; 3], dir: usize) -> bool {
        if !self.exact_source {
            return self.value(s, p, dir, 0, 0, 0) > 0;
        }
        let l = 16 * self.d as i128;
        let reference = [p[0] as i128, p[1] as i128, s.lo as i128];
        Self::scaled(s, [0, 1, 2].map(|i| self.d as i128 * self.src[i] as i128 - l * reference[i]), l) > 0
    }

    /// The ray's point of parameter t, in voxel-centre coordinates.
    fn point(&self, dir: usize, a: i64, b: i64, t: f64) -> [f64; 3] {
        let (w, sg, ua, va) = dir_axes(dir);
        let dist = t + self.t16(dir, 0) as f64 / 16.0;
        let mut p = [0.0; 3];
        p[w] = self.sv[w] as f64 + sg as f64 * t;
        p[ua] = self.src[ua] as f64 / 16.0 + a as f64 * dist / self.d as f64;
        p[va] = self.src[va] as f64 / 16.0 + b as f64 * dist / self.d as f64;
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
            let p = self.voxel(dir, a, b, k);
            if p.iter().any(|&c| !(0..n).contains(&c)) {
                return;
            }
            let next = self.voxel(dir, a, b, k + 1);
            let stays = z_ray && k < d && p[0] == next[0] && p[1] == next[1];
            let own = (self.surfaces)(p[0], p[1], p[2]);
            let prev = (k - 1).max(0);
            let sigma = |s: &Surface, t: i64| self.value(s, p, dir, a, b, t) > 0;
            // Rule 1: the visible surface.
            if let Some(v) = (self.columns)(p[0], p[1]) {
                if (p[2] == v.z_v || p[2] == v.z_v + 1)
                    && self.source_in_front(&v.plane, p, dir)
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
            let (was, now, then, faces) =
                (sigma(&s, prev), sigma(&s, k), sigma(&s, k + 1), self.source_in_front(&s, p, dir));
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
    for (i, light) in lights.iter().enumerate() {
        let src = host_sim::machine::diffuse::source_at(i, *light, n).expect("source").pos.map(|c| c.to_bits() as i64);
        let lead = [0, 1, 2].map(|w| (src[w] - 16 * source_voxel(src)[w]) as f64 / 16.0);
        println!("light {}: voxel {:?}, the light {lead:+?} voxel from its centre", i + 1, source_voxel(src));
    }
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
                exact_source: var.exact_source,
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
