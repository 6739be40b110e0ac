//! Per-ray oracle of the plane rule (thesis §5.5.6): every ray of the lattice traced on its
//! own against the planes the surface voxels store.
//!
//! Rays, layers, sources and directions are those of [`super::rays`] (thesis §4.1.4, §4.3): ray
//! `(dir, a, b)` of a source given in sixteenths is at layer `k` in the voxel
//! [`super::rays::ray_voxel`] gives. This module adds what a surface voxel and a column store, and
//! the rule that uses them. It restates both from their definitions with its own `i128`
//! arithmetic and never calls `cell-core`.
//!
//! # Planes
//!
//! An occupied voxel belongs to a dexel of its column (x, y); the dexel's first voxel is `lo`
//! and it stores its facet's plane as `(nx, ny, nz, e)` ([`Surface`], `lo` its reference depth).
//! For a point p in voxel units
//!
//! ```text
//!   g(p) = nx·(p_x − x) + ny·(p_y − y) + (nz / 2¹⁶)·(p_z − lo) + e
//! ```
//!
//! is positive on the facet's outward side. A column may also have a *visible surface*
//! ([`Visible`]): the plane of the facet its centre line meets first, with reference depth
//! `z_v`, and the two voxels `z_v`, `z_v + 1` that bracket it.
//!
//! # The ray's points
//!
//! Ray `(dir, a, b)` with principal axis w, sign s and transverse axes (u, v) is the line
//! `p(t) = Se + t·(s·e_w + (a/2^f)/D·e_u + (b/2^f)/D·e_v)` where `Se` is the source with its w
//! coordinate replaced by its voxel's. With L = 16·D·2^f every coordinate of L·p(t) is an
//! integer, so `2¹⁶·L·g(p(t))` is one ([`plane_value`]). σ_t = [g(p(t)) > 0]; at layer k,
//! σ₋ = σ_{max(k−1, 0)}.
//!
//! # The rule
//!
//! A ray walks layers k = 0, 1, … as in [`super::rays`] (it exits past layer D or outside the
//! grid). It is *terminal* or not, and a ±z ray has a *column state*: the dexel (by its first
//! voxel) of the last surface voxel it passed while staying in its column, forgotten when it
//! moves to another column. At layer k, in voxel V of column (x, y):
//!
//! 1. if V is one of the two voxels bracketing the column's visible surface B (its plane as the
//!    column stores it: turned toward the viewer), B faces the source (σᴮ₀) and σᴮ_k or σᴮ₋
//!    holds, the ray lights the visible surface;
//! 2. a terminal ray lights V if V is occupied, V's plane faces the source (σ₀) and σ_k or σ₋
//!    holds; it is absorbed;
//! 3. in an empty V it goes on;
//! 4. in an occupied V: it lights V if σ₀ and (σ_k or σ₋); it is absorbed if σ₋ ≠ σ_k; it is
//!    absorbed if σ₋ = σ_k = 0 and its voxel at layer k − 1 was empty, or was occupied, in
//!    another column, with the ray on the outside of that voxel's plane at k − 1 while V's
//!    plane faces the source (σ₀); it is absorbed if it is a ±z ray whose voxel at layer k + 1 (k < D) is in this column and whose column
//!    state is another dexel than V's; it becomes terminal if σ_k ≠ σ_{k+1}; a ±z ray staying in
//!    the column takes V's dexel as its state.
//!
//! The thesis's rule (§5.5.5) is [`super::rays::trace_all`].
//!
//! **Rays from the light** ([`RaysFrom::Light`], [`trace_all_plane_naive_from`]): the same rule
//! on the rays of [`super::rays::ray_voxel_from_light`], whose point at layer t lies on the t-th
//! voxel centre plane strictly ahead of the light (at the light for t = 0) instead of t voxels
//! from `Se`.

use std::collections::BTreeMap;

pub use super::rays::RaysFrom;
use super::rays::{dir_axes, light_layer, rays_per_source, source_voxel, transverse, Fate, RayOutcome};

/// The plane a surface voxel's dexel stores, or a column's visible surface (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Surface {
    /// The reference depth: the dexel's first voxel (also its identity in the column), or
    /// `z_v` for a visible surface.
    pub lo: i64,
    /// x component of the scaled normal.
    pub nx: i64,
    /// y component of the scaled normal.
    pub ny: i64,
    /// z component, with 16 more fraction bits.
    pub nz: i64,
    /// The plane's value at the centre of voxel (x, y, lo).
    pub e: i64,
    /// A facet of an open surface: its winding says nothing about where light comes from, so
    /// where it faces away from the source its voxels are lit from the source's (inner) side,
    /// and rule 4 does not read that side as "crossed unseen".
    pub two_sided: bool,
}

/// A column's visible surface: its plane (reference depth `z_v`) and the voxels `z_v`,
/// `z_v + 1` that bracket it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Visible {
    /// ⌊z*⌋.
    pub z_v: i64,
    /// The plane, `lo` = `z_v`.
    pub plane: Surface,
}

/// The voxels of a scene with their planes: `None` where empty.
pub type Surfaces<'a> = &'a dyn Fn(i64, i64, i64) -> Option<Surface>;

/// The columns' visible surfaces: `None` where the centre line meets no facet.
pub type Columns<'a> = &'a dyn Fn(i64, i64) -> Option<Visible>;

/// What the rays of every source did under the plane rule.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct PlaneOutcome {
    /// Lit voxels (by their own planes) and the ray counts.
    pub rays: RayOutcome,
    /// Column (x, y) → the sources that lit its visible surface.
    pub visible: BTreeMap<[i64; 2], u64>,
}

/// `2¹⁶·L·g(p(t))` for ray `(dir, a, b)` of `src` against the plane of `s` in column `(x, y)`
/// (L = 16·D·2^f): its sign is the sign of g at the ray's point of parameter t.
#[allow(clippy::too_many_arguments)] // the ray's full coordinates, as the definition states them
pub fn plane_value(
    s: &Surface,
    x: i64,
    y: i64,
    src: [i64; 3],
    dir: usize,
    a: i64,
    b: i64,
    d: i64,
    f: u32,
    t: i64,
) -> i128 {
    plane_value_on(s, x, y, RaysFrom::Voxel, src, dir, a, b, d, f, t)
}

/// [`plane_value`] for rays leaving from `from`: `2¹⁶·L·g` at the ray's point at layer t, the
/// origin O (sixteenths) plus `T/16` times `(s, a/N, b/N)` with T its distance along the axis.
#[allow(clippy::too_many_arguments)] // the ray's full coordinates, as the definition states them
pub fn plane_value_on(
    s: &Surface,
    x: i64,
    y: i64,
    from: RaysFrom,
    src: [i64; 3],
    dir: usize,
    a: i64,
    b: i64,
    d: i64,
    f: u32,
    t: i64,
) -> i128 {
    let (w, sign, ua, va) = dir_axes(dir);
    let l = 16 * ((d as i128) << f);
    let df = (d as i128) << f;
    let reference = [x as i128, y as i128, s.lo as i128];
    let o = ray_origin(from, src, w);
    let tt = ray_distance(from, src, dir, t);
    // L·(p_i(t) − reference_i), exactly: N·O_i + T·(s·N, a, b)_i − L·reference_i.
    let mut lp = [0i128; 3];
    lp[w] = df * o[w] + sign as i128 * df * tt - l * reference[w];
    lp[ua] = df * o[ua] + a as i128 * tt - l * reference[ua];
    lp[va] = df * o[va] + b as i128 * tt - l * reference[va];
    (s.nx as i128 * lp[0] + s.ny as i128 * lp[1]) * 65536 + s.nz as i128 * lp[2] + 65536 * l * s.e as i128
}

/// The rays' origin O in sixteenths for principal axis `w`: the light `src`, moved along `w` to
/// its voxel's centre plane for rays from the source voxel.
fn ray_origin(from: RaysFrom, src: [i64; 3], w: usize) -> [i128; 3] {
    let mut o = src.map(|c| c as i128);
    if from == RaysFrom::Voxel {
        o[w] = 16 * source_voxel(src)[w] as i128;
    }
    o
}

/// The distance T, in sixteenths along the axis, of the point at layer t of the rays of `src`
/// in direction `dir` leaving from `from`: `16·t` from the source voxel's centre plane; from the
/// light, 0 at layer 0 and its k-th centre plane's distance after ([`light_layer`]).
fn ray_distance(from: RaysFrom, src: [i64; 3], dir: usize, t: i64) -> i128 {
    match from {
        RaysFrom::Voxel => 16 * t as i128,
        RaysFrom::Light if t == 0 => 0,
        RaysFrom::Light => light_layer(src, dir, t).1 as i128,
    }
}

/// [`plane_value_on`] along one ray, as a line in the ray's distance T: `base + T·slope` (the
/// same integer, regrouped: every term of `plane_value_on` is constant or linear in T).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PlaneLine {
    base: i128,
    slope: i128,
}

impl PlaneLine {
    /// The value at distance T (sixteenths along the axis, [`Ray::distance`]).
    fn at(&self, tt: i128) -> i128 {
        self.base + tt * self.slope
    }
}

/// What [`PlaneLine`] takes from plane `s` (column (x, y)), the source and the direction, the
/// same for every ray: the walk computes it once per voxel of a class of rays, not per ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PlaneBase {
    base: i128,
    /// The plane's coefficients on the ray's two transverse offsets, and the slope's part along
    /// the axis.
    ca: i128,
    cb: i128,
    axial: i128,
}

impl PlaneBase {
    /// Plane `s` of column (x, y) along the rays of `src` in direction `dir` leaving from `from`.
    #[allow(clippy::too_many_arguments)] // the rays' coordinates, as in `plane_value_on`
    fn new(s: &Surface, x: i64, y: i64, from: RaysFrom, src: [i64; 3], dir: usize, d: i64, f: u32) -> Self {
        let (w, sign, ua, va) = dir_axes(dir);
        let l = 16 * ((d as i128) << f);
        let df = (d as i128) << f;
        let reference = [x as i128, y as i128, s.lo as i128];
        let o = ray_origin(from, src, w);
        let c = [65536 * s.nx as i128, 65536 * s.ny as i128, s.nz as i128];
        let base = (0..3).map(|i| c[i] * (df * o[i] - l * reference[i])).sum::<i128>() + 65536 * l * s.e as i128;
        PlaneBase { base, ca: c[ua], cb: c[va], axial: c[w] * sign as i128 * df }
    }

    /// The line along ray (a, b).
    fn along(&self, a: i64, b: i64) -> PlaneLine {
        PlaneLine { base: self.base, slope: self.axial + self.ca * a as i128 + self.cb * b as i128 }
    }
}

/// One ray: its parameters and walk state.
struct Ray {
    from: RaysFrom,
    src: [i64; 3],
    dir: usize,
    a: i64,
    b: i64,
    d: i64,
    f: u32,
    terminal: bool,
    column: Option<i64>,
    /// After its last step: it goes on from an occupied voxel, on the outside of its plane at
    /// that layer, to another column.
    outside: bool,
}

/// A plane's sides along a ray around layer k ([`Ray::sigmas`]).
#[derive(Clone, Copy, Debug)]
struct Sigmas {
    s0: bool,
    prev: bool,
    now: bool,
    next: bool,
}

impl Ray {
    fn new(from: RaysFrom, src: [i64; 3], dir: usize, a: i64, b: i64, d: i64, f: u32) -> Self {
        Ray { from, src, dir, a, b, d, f, terminal: false, column: None, outside: false }
    }

    /// The ray's distance T at layer t ([`ray_distance`]).
    fn distance(&self, t: i64) -> i128 {
        ray_distance(self.from, self.src, self.dir, t)
    }

    /// Plane `s` of column (x, y) along this ray's source and direction.
    fn base(&self, s: &Surface, x: i64, y: i64) -> PlaneBase {
        PlaneBase::new(s, x, y, self.from, self.src, self.dir, self.d, self.f)
    }

    /// σ_t of a plane (`plane`: [`Ray::base`]) at layers 0, k − 1 (0 at k = 0), k and k + 1, from
    /// the plane's line along the ray ([`PlaneLine`]: [`plane_value_on`] regrouped).
    fn sigmas(&self, plane: &PlaneBase, k: i64) -> Sigmas {
        let line = plane.along(self.a, self.b);
        let sigma = |t: i64| line.at(self.distance(t)) > 0;
        Sigmas { s0: sigma(0), prev: sigma((k - 1).max(0)), now: sigma(k), next: sigma(k + 1) }
    }

    /// The ray's voxel at layer k.
    fn voxel(&self, k: i64) -> [i64; 3] {
        self.from.voxel(self.src, self.dir, self.a, self.b, self.d, self.f, k)
    }

    /// The rule at layer k in voxel `p` (occupied by `own`, with the column's visible surface
    /// `vis`), `stays`: the ray's voxel at k + 1 is in the same column (±z rays only),
    /// `from_empty`: its voxel at layer k − 1 was empty (false at layer 0), `from_outside`: its
    /// voxel at layer k − 1 was occupied, in another column, and it was on the outside of that
    /// voxel's plane there ([`Ray::outside`] after that step). Sets
    /// `lit` / `lit_visible` when the ray lights V / the visible surface; returns whether it
    /// goes on.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &mut self,
        p: [i64; 3],
        k: i64,
        own: Option<(Surface, PlaneBase)>,
        vis: Option<(Visible, PlaneBase)>,
        stays: bool,
        from_empty: bool,
        from_outside: bool,
        lit: &mut bool,
        lit_visible: &mut bool,
    ) -> bool {
        if let Some((v, plane)) = vis {
            let sv = self.sigmas(&plane, k);
            if (p[2] == v.z_v || p[2] == v.z_v + 1) && sv.s0 && (sv.now || sv.prev) {
                *lit_visible = true;
            }
        }
        // On the source's side (σ_t = σ₀) at layer k or k − 1, of a plane facing the source or
        // of a two-sided one.
        let lights = |g: &Sigmas, s: &Surface| (g.s0 || s.two_sided) && (g.now == g.s0 || g.prev == g.s0);
        if self.terminal {
            if let Some((s, plane)) = own {
                *lit = lights(&self.sigmas(&plane, k), &s);
            }
            return false;
        }
        let z_ray = self.dir >= 4;
        self.outside = false;
        let Some((s, plane)) = own else {
            if z_ray && !stays {
                self.column = None;
            }
            return true;
        };
        let g = self.sigmas(&plane, k);
        *lit = lights(&g, &s);
        let (was, now, next) = (g.prev, g.now, g.next);
        // Behind the plane at both layers, having come from empty space, or from the outside
        // of another column's plane into one facing the source: it crossed a surface unseen.
        // (Behind a two-sided plane facing away is the source's side: the ray has not reached the
        // plane yet.)
        let faces = g.s0;
        if was != now || (((from_empty && (faces || !s.two_sided)) || (from_outside && faces)) && !was && !now) {
            return false;
        }
        if z_ray && stays && self.column.is_some_and(|c| c != s.lo) {
            return false;
        }
        self.terminal = now != next;
        self.column = (z_ray && stays).then_some(s.lo);
        self.outside = now && !stays;
        true
    }
}

fn in_grid(n: i64, p: [i64; 3]) -> bool {
    p.iter().all(|&c| (0..n).contains(&c))
}

/// Whether a ±z ray at layer k has a voxel at layer k + 1 (k < D: past layer D it exits) with
/// the same (x, y) as at layer k.
fn stays_in_column(dir: usize, k: i64, d: i64, now: [i64; 3], next: [i64; 3]) -> bool {
    dir >= 4 && k < d && now[0] == next[0] && now[1] == next[1]
}

/// Walks one ray by the rule, one [`super::rays::ray_voxel`] per layer; the voxels it lit and the columns
/// whose visible surface it lit.
#[allow(clippy::too_many_arguments)]
pub fn trace_ray_plane(
    n: i64,
    surfaces: Surfaces<'_>,
    columns: Columns<'_>,
    src: [i64; 3],
    dir: usize,
    a: i64,
    b: i64,
    d: i64,
    f: u32,
    lit: &mut Vec<[i64; 3]>,
    lit_visible: &mut Vec<[i64; 2]>,
) -> Fate {
    walk_ray(Ray::new(RaysFrom::Voxel, src, dir, a, b, d, f), n, surfaces, columns, lit, lit_visible)
}

/// [`trace_ray_plane`] for any [`RaysFrom`].
fn walk_ray(
    mut ray: Ray,
    n: i64,
    surfaces: Surfaces<'_>,
    columns: Columns<'_>,
    lit: &mut Vec<[i64; 3]>,
    lit_visible: &mut Vec<[i64; 2]>,
) -> Fate {
    let (dir, d) = (ray.dir, ray.d);
    let mut k = 0;
    let mut from_empty = false;
    loop {
        if k > d {
            return Fate::Exited { k };
        }
        let p = ray.voxel(k);
        if !in_grid(n, p) {
            return Fate::Exited { k };
        }
        let next = ray.voxel(k + 1);
        let (mut l, mut lv) = (false, false);
        let own = surfaces(p[0], p[1], p[2]);
        let from_outside = ray.outside;
        let vis = columns(p[0], p[1]);
        let goes = ray.step(
            p,
            k,
            own.map(|s| (s, ray.base(&s, p[0], p[1]))),
            vis.map(|v| (v, ray.base(&v.plane, p[0], p[1]))),
            stays_in_column(dir, k, d, p, next),
            from_empty,
            from_outside,
            &mut l,
            &mut lv,
        );
        from_empty = own.is_none();
        if l {
            lit.push(p);
        }
        if lv {
            lit_visible.push([p[0], p[1]]);
        }
        if !goes {
            return Fate::Absorbed { voxel: p, k };
        }
        k += 1;
    }
}

/// Every ray of every source traced one by one with [`trace_ray_plane`]. Slow: a reference
/// for [`trace_all_plane`], for small `D·2^f`.
pub fn trace_all_plane_naive(
    n: i64,
    surfaces: Surfaces<'_>,
    columns: Columns<'_>,
    sources: &[[i64; 3]],
    d: i64,
    f: u32,
) -> PlaneOutcome {
    trace_all_plane_naive_from(RaysFrom::Voxel, n, surfaces, columns, sources, d, f)
}

/// [`trace_all_plane_naive`] for rays leaving from `from` (the only oracle of the plane rule
/// for rays from the light, [`RaysFrom::Light`]): every ray walked on its own. For small
/// `D·2^f`.
pub fn trace_all_plane_naive_from(
    from: RaysFrom,
    n: i64,
    surfaces: Surfaces<'_>,
    columns: Columns<'_>,
    sources: &[[i64; 3]],
    d: i64,
    f: u32,
) -> PlaneOutcome {
    assert!(sources.len() <= 64, "at most 64 sources (mask bits)");
    let m = d << f;
    let mut out = PlaneOutcome::default();
    let (mut lit, mut vis) = (Vec::new(), Vec::new());
    for (i, &src) in sources.iter().enumerate() {
        for dir in 0..6 {
            for a in -m..=m {
                for b in -m..=m {
                    out.rays.rays_emitted += 1;
                    lit.clear();
                    vis.clear();
                    let ray = Ray::new(from, src, dir, a, b, d, f);
                    match walk_ray(ray, n, surfaces, columns, &mut lit, &mut vis) {
                        Fate::Absorbed { .. } => out.rays.rays_absorbed += 1,
                        Fate::Exited { .. } => out.rays.rays_exited += 1,
                    }
                    for p in &lit {
                        *out.rays.lit.entry(*p).or_insert(0) |= 1 << i;
                    }
                    for c in &vis {
                        *out.visible.entry(*c).or_insert(0) |= 1 << i;
                    }
                }
            }
        }
    }
    out
}

/// Offsets `a ∈ [−D·2^f, D·2^f]` grouped by their transverse coordinate sequence at layers
/// `0 ..= kmax + 1` (one past the last the walk may use, so that a ray's next voxel is known):
/// each class is an interval of a (the coordinate is monotone in a at every layer).
fn class_ranges(src_c: i64, d: i64, f: u32, kmax: i64) -> Vec<(Vec<i64>, i64, i64)> {
    let m = d << f;
    let mut out: Vec<(Vec<i64>, i64, i64)> = Vec::new();
    for a in -m..=m {
        let seq: Vec<i64> = (0..=kmax + 1).map(|k| transverse(src_c, a, d, f, k)).collect();
        match out.last_mut() {
            Some(c) if c.0 == seq => c.2 = a,
            _ => out.push((seq, a, a)),
        }
    }
    out
}

/// The same result as [`trace_all_plane_naive`], fast: rays whose voxel sequences agree on both
/// transverse axes share a path, walked once to find where something can happen (surface
/// voxels, the voxels bracketing a visible surface); each ray of the class applies the rule
/// there only (and at the layer after one that made it terminal). The tests compare the two.
pub fn trace_all_plane(
    n: i64,
    surfaces: Surfaces<'_>,
    columns: Columns<'_>,
    sources: &[[i64; 3]],
    d: i64,
    f: u32,
) -> PlaneOutcome {
    assert!(sources.len() <= 64, "at most 64 sources (mask bits)");
    let mut out = PlaneOutcome::default();
    for (i, &src) in sources.iter().enumerate() {
        let mask = 1u64 << i;
        let sv = source_voxel(src);
        out.rays.rays_emitted += rays_per_source(d, f);
        for dir in 0..6 {
            let (w, s, ua, va) = dir_axes(dir);
            let side = 2 * ((d as u128) << f) + 1;
            let kmax = if !(0..n).contains(&sv[w]) {
                -1
            } else if s > 0 {
                (n - 1 - sv[w]).min(d)
            } else {
                sv[w].min(d)
            };
            if kmax < 0 {
                out.rays.rays_exited += side * side;
                continue;
            }
            let us = class_ranges(src[ua], d, f, kmax);
            let vs = class_ranges(src[va], d, f, kmax);
            for (useq, alo, ahi) in &us {
                for (vseq, blo, bhi) in &vs {
                    let voxel = |k: usize| {
                        let mut p = [0i64; 3];
                        p[w] = sv[w] + s * k as i64;
                        p[ua] = useq[k];
                        p[va] = vseq[k];
                        p
                    };
                    // The shared path: layers 0 ..= last, inside the grid.
                    let mut last: i64 = -1;
                    while last < kmax && in_grid(n, voxel((last + 1) as usize)) {
                        last += 1;
                    }
                    let len = (last + 1) as usize;
                    // Each plane met with its part of the line that is the same for every ray.
                    let based =
                        |s: Surface, p: [i64; 3]| (s, PlaneBase::new(&s, p[0], p[1], RaysFrom::Voxel, src, dir, d, f));
                    let own: Vec<Option<(Surface, PlaneBase)>> =
                        (0..len).map(&voxel).map(|p| surfaces(p[0], p[1], p[2]).map(|s| based(s, p))).collect();
                    let vis: Vec<Option<(Visible, PlaneBase)>> = (0..len)
                        .map(|k| {
                            let p = voxel(k);
                            let v = columns(p[0], p[1]).filter(|v| p[2] == v.z_v || p[2] == v.z_v + 1)?;
                            Some((v, based(v.plane, p).1))
                        })
                        .collect();
                    let stays: Vec<bool> =
                        (0..len).map(|k| stays_in_column(dir, k as i64, d, voxel(k), voxel(k + 1))).collect();
                    let visits: Vec<usize> = (0..len).filter(|&k| own[k].is_some() || vis[k].is_some()).collect();
                    let weight = ((ahi - alo + 1) as u128) * ((bhi - blo + 1) as u128);
                    if !visits.iter().any(|&k| own[k].is_some()) {
                        // Nothing absorbs on this path; only the visible surfaces can be lit.
                        out.rays.rays_exited += weight;
                        if visits.is_empty() {
                            continue;
                        }
                    }
                    // The planes the rays read, with the layers (t₀ = 0, k − 1, k, k + 1) at which
                    // a step at visit k reads them: every σ the walk can evaluate.
                    let reads: Vec<(PlaneBase, i64)> = visits
                        .iter()
                        .flat_map(|&k| {
                            let planes = [own[k].map(|o| o.1), vis[k].map(|v| v.1)].into_iter().flatten();
                            let k = k as i64;
                            planes.flat_map(move |p| [0, (k - 1).max(0), k, k + 1].map(|t| (p, t)))
                        })
                        .collect();
                    let mut cuts = Vec::new();
                    for b in *blo..=*bhi {
                        // Rays of this row between two cuts read every σ alike, so they take the
                        // same steps: one walks for all of them.
                        row_cuts(&reads, *alo, *ahi, b, &mut cuts);
                        for (i, &a) in cuts.iter().enumerate() {
                            let rays = (cuts.get(i + 1).map_or(*ahi + 1, |&c| c) - a) as u128;
                            let mut ray = Ray::new(RaysFrom::Voxel, src, dir, a, b, d, f);
                            let mut absorbed = false;
                            let mut at = 0usize; // next index into `visits`
                            let mut k = visits[0];
                            let mut since = 0usize; // layer of the ray's previous visit
                            loop {
                                // The column state is forgotten when the ray left its column
                                // between its previous visit and this one.
                                if (since..k).any(|j| !stays[j]) {
                                    ray.column = None;
                                }
                                let p = voxel(k);
                                let (mut l, mut lv) = (false, false);
                                let from_empty = k > 0 && own[k - 1].is_none();
                                // The outside flag of the ray's step at k − 1, if it made one
                                // there (an occupied voxel is always visited).
                                let from_outside = k > 0 && own[k - 1].is_some() && ray.outside;
                                let goes = ray.step(
                                    p,
                                    k as i64,
                                    own[k],
                                    vis[k],
                                    stays[k],
                                    from_empty,
                                    from_outside,
                                    &mut l,
                                    &mut lv,
                                );
                                if l {
                                    *out.rays.lit.entry(p).or_insert(0) |= mask;
                                }
                                if lv {
                                    *out.visible.entry([p[0], p[1]]).or_insert(0) |= mask;
                                }
                                if !goes {
                                    absorbed = true;
                                    break;
                                }
                                // The step already applied the move to layer k + 1; the moves
                                // after it, through empty voxels, are checked at the next visit.
                                since = k + 1;
                                let next = if ray.terminal {
                                    Some(k + 1)
                                } else {
                                    while at < visits.len() && visits[at] <= k {
                                        at += 1;
                                    }
                                    visits.get(at).copied()
                                };
                                match next {
                                    Some(nk) if nk < len => k = nk,
                                    _ => break,
                                }
                            }
                            if visits.iter().any(|&v| own[v].is_some()) {
                                if absorbed {
                                    out.rays.rays_absorbed += rays;
                                } else {
                                    out.rays.rays_exited += rays;
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    out
}

/// Where σ changes along row b of a class (rays a ∈ `alo ..= ahi` from the source voxel): the
/// sorted first offsets of the runs of a on which every `(plane, t)` of `reads` keeps its sign,
/// into `cuts` (`alo` first). σ is affine in a at fixed b and t ([`PlaneBase::along`]), so each
/// read changes sign at most once on the row.
fn row_cuts(reads: &[(PlaneBase, i64)], alo: i64, ahi: i64, b: i64, cuts: &mut Vec<i64>) {
    cuts.clear();
    cuts.push(alo);
    for (plane, t) in reads {
        let tt = 16 * *t as i128; // the distance T of rays from the source voxel
                                  // value(a) = c0 + c1·a.
        let c0 = plane.base + tt * (plane.axial + plane.cb * b as i128);
        let c1 = tt * plane.ca;
        // The first a on the other side: value > 0 ⇔ a > −c0/c1 (c1 > 0) or a < c0/(−c1) (c1 < 0).
        let start = match c1.signum() {
            1 => (-c0).div_euclid(c1) + 1,
            -1 => -(-c0).div_euclid(-c1),
            _ => continue,
        };
        if start > alo as i128 && start <= ahi as i128 {
            cuts.push(start as i64);
        }
    }
    cuts.sort_unstable();
    cuts.dedup();
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> u64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *seed >> 33
    }

    /// The plane z = zp (normal +z or −z) as stored by a dexel starting at `lo`.
    fn z_plane(zp: f64, up: bool, lo: i64) -> Surface {
        let sgn = if up { 1 } else { -1 };
        // g = sgn·2^14·(p_z − zp) = (nz/2^16)(p_z − lo) + e.
        Surface {
            lo,
            nx: 0,
            ny: 0,
            nz: sgn << 30,
            e: (sgn as f64 * 16384.0 * (lo as f64 - zp)).round() as i64,
            two_sided: false,
        }
    }

    fn none_visible(_: i64, _: i64) -> Option<Visible> {
        None
    }

    /// The walk's regrouped form is the definition's integer, for both ray origins, at random
    /// planes, rays and layers (normals and offsets at the stores' full widths).
    #[test]
    fn plane_line_is_the_plane_value() {
        let mut seed = 7u64;
        let mut r = |lo: i64, hi: i64| lo + (lcg(&mut seed) as i64).rem_euclid(hi - lo + 1);
        for _ in 0..20_000 {
            let (d, f) = (r(1, 300), r(0, 8) as u32);
            let m = d << f;
            let s = Surface {
                lo: r(0, 300),
                nx: r(-(1 << 15), 1 << 15),
                ny: r(-(1 << 15), 1 << 15),
                nz: r(-(1 << 31), 1 << 31),
                e: r(-(1 << 31), 1 << 31),
                two_sided: false,
            };
            let src = [r(0, 16 * 300), r(0, 16 * 300), r(0, 16 * 300)];
            let (x, y, dir, a, b, t) = (r(0, 300), r(0, 300), r(0, 5) as usize, r(-m, m), r(-m, m), r(0, d + 1));
            for from in [RaysFrom::Voxel, RaysFrom::Light] {
                let ray = Ray::new(from, src, dir, a, b, d, f);
                let line = PlaneBase::new(&s, x, y, from, src, dir, d, f).along(a, b);
                assert_eq!(line.at(ray.distance(t)), plane_value_on(&s, x, y, from, src, dir, a, b, d, f, t));
            }
        }
    }

    #[test]
    fn plane_value_signs_by_hand() {
        // A floor z = 4.25 facing +z; source at (5, 5, 8) (sixteenths 80, 80, 128).
        let s = z_plane(4.25, true, 4);
        let src = [80, 80, 128];
        // At t = 0 the point is the source (z = 8): above the plane, which faces it.
        assert!(plane_value(&s, 5, 5, src, 0, 0, 0, 15, 0, 0) > 0);
        // A −z ray (dir 5) reaches z = 4.25 at t = 3.75: above at 3, below at 4.
        assert!(plane_value(&s, 5, 5, src, 5, 0, 0, 15, 0, 3) > 0);
        assert!(plane_value(&s, 5, 5, src, 5, 0, 0, 15, 0, 4) < 0);
        // Facing down instead: the source is on its inner side.
        assert!(plane_value(&z_plane(4.25, false, 4), 5, 5, src, 5, 0, 0, 15, 0, 0) < 0);
    }

    /// A −z ray into a thick floor (dexel 3 ..= 5, plane z = 4.25): at layer 4 (z = 5) it is
    /// above the plane and will cross it before layer 5, so it lights z = 5 and becomes
    /// terminal; at layer 5 (z = 4) it lights z = 4 (it was above the plane at layer 4) and dies.
    #[test]
    fn terminal_step_lights_the_voxel_after_the_crossing() {
        let n = 12;
        let src = [80, 80, 16 * 9]; // (5, 5, 9)
        let floor = |x: i64, y: i64, z: i64| ((x, y) == (5, 5) && (3..=5).contains(&z)).then(|| z_plane(4.25, true, 3));
        let (mut lit, mut vis) = (Vec::new(), Vec::new());
        let fate = trace_ray_plane(n, &floor, &none_visible, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        assert_eq!(lit, vec![[5, 5, 5], [5, 5, 4]]);
        assert_eq!(fate, Fate::Absorbed { voxel: [5, 5, 4], k: 5 });
        assert!(vis.is_empty());
    }

    /// A ray passing a plane it does not cross there goes on: the plane of a facet says nothing
    /// about rays that pass beside the facet. Unless it comes from empty space into the back of
    /// it: then it crossed a surface in a voxel its steps skipped (rule 4).
    #[test]
    fn a_plane_not_crossed_there_does_not_stop_the_ray() {
        let n = 12;
        let src = [80, 80, 16 * 9];
        // The voxels z = 3 ..= 5 of column (5, 5) hold a plane z = 7.5 facing −z, away from the
        // source: the −z ray crossed it at t = 1.5, in empty voxels, and is on its outer side
        // all along those voxels. It goes on, lighting nothing (the facet faces away).
        let away = |x: i64, y: i64, z: i64| ((x, y) == (5, 5) && (3..=5).contains(&z)).then(|| z_plane(7.5, false, 3));
        let (mut lit, mut vis) = (Vec::new(), Vec::new());
        let fate = trace_ray_plane(n, &away, &none_visible, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        assert_eq!(fate, Fate::Exited { k: 10 });
        assert!(lit.is_empty(), "a plane facing away is not lit");
        // The same plane facing +z: the ray arrives from an empty voxel behind it at both
        // layers and is absorbed there, unlit.
        let sheet = |x: i64, y: i64, z: i64| ((x, y) == (5, 5) && (3..=5).contains(&z)).then(|| z_plane(7.5, true, 3));
        let fate = trace_ray_plane(n, &sheet, &none_visible, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        assert_eq!(fate, Fate::Absorbed { voxel: [5, 5, 5], k: 4 });
        assert!(lit.is_empty(), "behind a plane facing the source: not lit");
        // The plane facing away, on an open surface (two-sided): the ray is on its outer side,
        // beyond the source's; it goes on as for the one-sided plane, lighting nothing.
        let open = |x: i64, y: i64, z: i64| away(x, y, z).map(|s| Surface { two_sided: true, ..s });
        let fate = trace_ray_plane(n, &open, &none_visible, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        assert_eq!(fate, Fate::Exited { k: 10 });
        assert!(lit.is_empty());
    }

    /// An open sheet wound away from the source: a one-sided plane facing away stops the ray as
    /// soon as it enters the plane's voxels from the source's side (rule 4, "behind" it: inside
    /// a closed surface); two-sided, the ray goes on to the plane, lights the voxels on the
    /// source's side, and is stopped where it crosses: as for the sheet wound toward it.
    #[test]
    fn an_open_sheet_is_lit_from_the_source_side_whatever_its_winding() {
        let n = 12;
        let src = [80, 80, 16 * 9];
        let sheet = |two_sided: bool| {
            move |x: i64, y: i64, z: i64| {
                ((x, y) == (5, 5) && (4..=6).contains(&z)).then(|| Surface { two_sided, ..z_plane(4.75, false, 4) })
            }
        };
        let (mut lit, mut vis) = (Vec::new(), Vec::new());
        let fate = trace_ray_plane(n, &sheet(false), &none_visible, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        assert_eq!(fate, Fate::Absorbed { voxel: [5, 5, 6], k: 3 }, "one-sided: stopped on entry");
        assert!(lit.is_empty());
        let fate = trace_ray_plane(n, &sheet(true), &none_visible, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        // z = 6, 5 are above z = 4.75, the source's side (lit); the ray crosses between layers 4
        // and 5 (z = 5 → 4): terminal at z = 5, it lights z = 4 (it was above at layer 4) and
        // dies there.
        assert_eq!(lit, vec![[5, 5, 6], [5, 5, 5], [5, 5, 4]]);
        assert_eq!(fate, Fate::Absorbed { voxel: [5, 5, 4], k: 5 });
        let up = |x: i64, y: i64, z: i64| sheet(false)(x, y, z).map(|s| Surface { nz: -s.nz, e: -s.e, ..s });
        lit.clear();
        let fate_up = trace_ray_plane(n, &up, &none_visible, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        assert_eq!(fate_up, fate, "the same as the sheet wound toward the source");
        assert_eq!(lit, vec![[5, 5, 6], [5, 5, 5], [5, 5, 4]]);
    }

    /// The visible surface is lit by rays in the two voxels that bracket it, on its own plane.
    #[test]
    fn visible_surface_lit_from_its_own_plane() {
        let n = 12;
        let src = [80, 80, 16 * 9];
        let empty = |_: i64, _: i64, _: i64| None;
        // Visible plane z = 4.25 facing +z in column (5, 5): z_v = 4, bracket 4 and 5.
        let col = |x: i64, y: i64| ((x, y) == (5, 5)).then(|| Visible { z_v: 4, plane: z_plane(4.25, true, 4) });
        let (mut lit, mut vis) = (Vec::new(), Vec::new());
        trace_ray_plane(n, &empty, &col, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        // At z = 5 (layer 4) the ray is above: lit; at z = 4 (layer 5) it was above at 4: lit.
        assert_eq!(vis, vec![[5, 5], [5, 5]]);
        // Facing away from the source: never lit.
        let back = |x: i64, y: i64| ((x, y) == (5, 5)).then(|| Visible { z_v: 4, plane: z_plane(4.25, false, 4) });
        vis.clear();
        trace_ray_plane(n, &empty, &back, src, 5, 0, 0, 11, 0, &mut lit, &mut vis);
        assert!(vis.is_empty());
    }

    #[test]
    fn fast_path_matches_naive() {
        let mut seed = 99u64;
        for case in 0..60 {
            let n = 3 + (lcg(&mut seed) % 6) as i64;
            let d = (n - 1).max(1);
            let f = (lcg(&mut seed) % 4) as u32;
            let r = |seed: &mut u64, m: u64| (lcg(seed) % (2 * m + 1)) as i64 - m as i64;
            // Random dexels of random planes in random columns, and random visible surfaces.
            let mut cols: Vec<Vec<(i64, i64, Surface)>> = vec![Vec::new(); (n * n) as usize];
            let mut vis: Vec<Option<Visible>> = vec![None; (n * n) as usize];
            for (i, col) in cols.iter_mut().enumerate() {
                let mut z = 0;
                while z < n {
                    if lcg(&mut seed) % 3 == 0 {
                        let hi = (z + (lcg(&mut seed) % 3) as i64).min(n - 1);
                        let s = Surface {
                            lo: z,
                            nx: r(&mut seed, 16384),
                            ny: r(&mut seed, 16384),
                            nz: r(&mut seed, 16384) << 16,
                            e: r(&mut seed, 20000),
                            two_sided: lcg(&mut seed) % 2 == 0,
                        };
                        col.push((z, hi, s));
                        z = hi + 2;
                    } else {
                        z += 1;
                    }
                }
                if lcg(&mut seed) % 2 == 0 {
                    let z_v = r(&mut seed, n as u64).abs().min(n - 1);
                    let plane = Surface {
                        lo: z_v,
                        nx: r(&mut seed, 16384),
                        ny: r(&mut seed, 16384),
                        nz: r(&mut seed, 16384) << 16,
                        e: r(&mut seed, 20000),
                        two_sided: false,
                    };
                    vis[i] = Some(Visible { z_v, plane });
                }
            }
            let surf =
                |x: i64, y: i64, z: i64| cols[(y * n + x) as usize].iter().find(|c| c.0 <= z && z <= c.1).map(|c| c.2);
            let columns = |x: i64, y: i64| vis[(y * n + x) as usize];
            let sources: Vec<[i64; 3]> =
                (0..1 + case % 2).map(|_| [0; 3].map(|_| (lcg(&mut seed) % (16 * n as u64)) as i64)).collect();
            let fast = trace_all_plane(n, &surf, &columns, &sources, d, f);
            let naive = trace_all_plane_naive(n, &surf, &columns, &sources, d, f);
            assert_eq!(fast, naive, "case {case}: n={n} f={f} sources={sources:?}");
            assert_eq!(fast.rays.rays_emitted, fast.rays.rays_absorbed + fast.rays.rays_exited);
        }
    }

    /// A wall whose planes lie on its near face (x = 5.5, facing the source, a hair outside the
    /// voxels): every ray point in a wall voxel is behind it and every earlier point in front
    /// (ray points have denominators 16·D·2^f = 256 here), so the plane rule gives exactly the
    /// thesis's: the first occupied voxel is lit and absorbs.
    #[test]
    fn planes_on_the_near_face_give_the_thesis_rule() {
        let n = 9;
        let wall = |x: i64, _: i64, _: i64| x == 6;
        // g(p) = −2^14·(p_x − 6) − 2^13 − 1: zero at x = 5.5 − 2^−14.
        let surf = |x: i64, y: i64, z: i64| {
            wall(x, y, z).then_some(Surface { lo: z, nx: -16384, ny: 0, nz: 0, e: -8193, two_sided: false })
        };
        let src = [16 * 2, 16 * 4, 16 * 4];
        let got = trace_all_plane(n, &surf, &none_visible, &[src], n - 1, 1);
        let want = super::super::rays::trace_all(n, &|x, y, z| wall(x, y, z), &[src], n - 1, 1);
        assert_eq!(got.rays, want);
    }

    /// Rays from a light at a voxel centre are the thesis's rays: the same plane values at
    /// every layer.
    #[test]
    fn rays_from_a_centred_light_are_the_thesis_rays() {
        let s = Surface { lo: 3, nx: 1200, ny: -16384, nz: 300 << 16, e: -777, two_sided: false };
        let src = [80, 48, 32];
        for dir in 0..6 {
            for (a, b) in [(0, 0), (7, -3), (-20, 20), (13, 1)] {
                for t in 0..=10 {
                    let light = plane_value_on(&s, 6, 2, RaysFrom::Light, src, dir, a, b, 10, 1, t);
                    assert_eq!(light, plane_value(&s, 6, 2, src, dir, a, b, 10, 1, t), "{dir} ({a}, {b}) layer {t}");
                }
            }
        }
    }
}
