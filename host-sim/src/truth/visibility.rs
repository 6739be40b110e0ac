//! Continuous ground truth: exact `f64` visibility against the world-space triangles.
//!
//! The discrete machine answers visibility from dexels on a lattice; this module answers the
//! same questions in continuous `f64` space so the discrete lighting's error can be measured.
//!
//! * The triangles are kept as given (world units), each tagged with a facet id.
//! * A parry3d-f64 [`Bvh`] over the triangles' bounding boxes does the culling only. Every
//!   leaf box is loosened by [`Reference::margin`] (10⁻⁶ of the scene's scale), so the box tests'
//!   own rounding can never hide a triangle: every answer comes from the exact per-triangle test.
//! * The per-triangle test is the watertight ray–triangle test of Woop, Benthin and Wald
//!   (JCGT 2013) in plain `f64`, without epsilons: a ray crossing a shared edge of two
//!   triangles hits at least one of them (no leaks through a closed mesh), edges and vertices
//!   count as inside, and a ray parallel to a triangle's plane (coplanar grazing included)
//!   does not hit it.
//!
//! Conventions:
//! * [`Reference::visible`] tests the open segment `from → to`: a hit at parameter `t`
//!   (`p = from + t·(to − from)`) blocks iff `1e-9 < t < 1 − 1e-9` ([`SEGMENT_END_TOL`]), so a
//!   surface point on a triangle does not shadow itself at either end, with no offset of the
//!   start point.
//! * [`Reference::first_hit`] accepts hits with `0 < t < max_t` (`t` in units of `dir`, which
//!   need not be normalised).
//! * Facets listed in `ignore` are transparent to both queries (all hits along the ray are
//!   visited, not only the first).
//! * Non-finite query input (NaN or ±∞ coordinates) is not an error: `visible` answers `false`
//!   and `first_hit` answers `None`. A zero-length segment is visible; a zero direction hits
//!   nothing.

use anyhow::{bail, Result};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};
use parry3d_f64::query::Ray;

/// Hits within this parameter distance of either end of a [`Reference::visible`] segment
/// (relative: the segment runs over `t ∈ [0, 1]`) do not block.
pub const SEGMENT_END_TOL: f64 = 1e-9;

/// Hits of [`Reference::first_hit`] within this relative depth of the first are ties, broken by
/// the lowest facet id: coplanar triangles differ by rounding only (about 10⁻¹⁶ relative).
pub const TIE_REL: f64 = 1e-9;

/// A triangle is skipped as zero-area when `|e1 × e2| ≤ DEGENERATE_SIN · |e1| · |e2|`, i.e.
/// when the sine of its angle at the first vertex is at most 10⁻¹² (an exact zero included).
pub const DEGENERATE_SIN: f64 = 1e-12;

// Vector arithmetic is parry3d-f64's `Vector` (glam's `DVec3`): its `dot` sums x, y, z in
// that order and its `cross` is the textbook formula, so every result is the one the former
// hand-written `[f64; 3]` helpers gave, bit for bit.

/// One kept (non-degenerate) triangle.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v: [Vector; 3],
    /// Unit geometric normal, `(v1 − v0) × (v2 − v0)` normalised.
    normal: Vector,
    facet: u32,
}

/// A ray prepared for the watertight test (shear constants and axis permutation).
#[derive(Clone, Copy, Debug)]
struct ShearRay {
    o: Vector,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f64,
    sy: f64,
    sz: f64,
}

impl ShearRay {
    /// `None` for a zero direction (no hit possible).
    fn new(o: Vector, d: Vector) -> Option<ShearRay> {
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let d = d.to_array();
        if d[kz] == 0.0 {
            return None;
        }
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the triangle winding: a negative major axis flips the handedness.
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Some(ShearRay { o, kx, ky, kz, sx: d[kx] / d[kz], sy: d[ky] / d[kz], sz: 1.0 / d[kz] })
    }

    /// Watertight ray–triangle test: the ray parameter of the hit, or `None`.
    /// Edges and vertices count as inside; a ray parallel to the plane misses.
    #[inline]
    fn hit(&self, tri: &Tri) -> Option<f64> {
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        // Arrays: the permuted axes index them directly.
        let a = (tri.v[0] - self.o).to_array();
        let b = (tri.v[1] - self.o).to_array();
        let c = (tri.v[2] - self.o).to_array();
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let t = (u * (self.sz * a[kz]) + v * (self.sz * b[kz]) + w * (self.sz * c[kz])) / det;
        t.is_finite().then_some(t)
    }
}

/// World-space triangles with a BVH (parry3d-f64 [`Bvh`]), each tagged with a facet id.
#[derive(Clone)]
pub struct Reference {
    tris: Vec<Tri>,
    bvh: Bvh,
    margin: f64,
    skipped: usize,
}

impl std::fmt::Debug for Reference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reference")
            .field("triangles", &self.tris.len())
            .field("skipped", &self.skipped)
            .field("margin", &self.margin)
            .finish()
    }
}

impl Reference {
    /// Build from world-space triangles and one facet id per triangle.
    ///
    /// Errors: the two lengths differ, a coordinate is NaN or infinite, there are more than
    /// `u32::MAX` triangles, or no triangle is left after skipping the zero-area ones (see
    /// [`DEGENERATE_SIN`]; an empty input included). Zero-area triangles are skipped and
    /// counted ([`Reference::skipped`]); every kept triangle keeps its own facet id.
    pub fn new(triangles: Vec<[[f64; 3]; 3]>, facet_of_triangle: Vec<u32>) -> Result<Reference> {
        if triangles.len() != facet_of_triangle.len() {
            bail!("reference: {} triangles but {} facet ids", triangles.len(), facet_of_triangle.len());
        }
        if triangles.len() > u32::MAX as usize {
            bail!("reference: too many triangles ({})", triangles.len());
        }
        let mut tris = Vec::with_capacity(triangles.len());
        let mut skipped = 0;
        let mut scale: f64 = 0.0;
        for (i, (v, &facet)) in triangles.iter().zip(&facet_of_triangle).enumerate() {
            let p = v.map(Vector::from);
            if !p.iter().all(|p| p.is_finite()) {
                bail!("reference: triangle {i} (facet {facet}) has a non-finite coordinate: {v:?}");
            }
            let e1 = p[1] - p[0];
            let e2 = p[2] - p[0];
            let n = e1.cross(e2);
            let n2 = n.dot(n);
            let lim = DEGENERATE_SIN * DEGENERATE_SIN * e1.dot(e1) * e2.dot(e2);
            if !(n2.is_finite() && n2 > lim) {
                skipped += 1;
                continue;
            }
            let inv = 1.0 / n2.sqrt();
            for p in v {
                for x in p {
                    scale = scale.max(x.abs());
                }
            }
            tris.push(Tri { v: p, normal: n * inv, facet });
        }
        if tris.is_empty() {
            bail!("reference: no triangle with a non-zero area ({} given, {} zero-area)", triangles.len(), skipped);
        }
        // Loosen every leaf box so that the box tests' rounding can never cull a real hit.
        let margin = 1e-6 * scale.max(f64::MIN_POSITIVE);
        let aabbs: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                let lo = t.v[0].min(t.v[1]).min(t.v[2]);
                let hi = t.v[0].max(t.v[1]).max(t.v[2]);
                Aabb::new(lo - Vector::splat(margin), hi + Vector::splat(margin))
            })
            .collect();
        let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &aabbs);
        Ok(Reference { tris, bvh, margin, skipped })
    }

    /// Number of triangles kept (zero-area ones excluded).
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Number of zero-area triangles skipped by [`Reference::new`].
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// How much every leaf box of the BVH is loosened (world units).
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// Whether the open segment from `from` to `to` is free of every triangle except those whose
    /// facet id is in `ignore` (exact `f64` ray–triangle tests, no epsilon offsets of the start
    /// point; hits at parameter `t ∈ (0, 1)` count, except within [`SEGMENT_END_TOL`] of either
    /// end). Non-finite input answers `false`; a zero-length segment is visible.
    pub fn visible(&self, from: [f64; 3], to: [f64; 3], ignore: &[u32]) -> bool {
        let (lo, hi) = (SEGMENT_END_TOL, 1.0 - SEGMENT_END_TOL);
        self.segment_clear(from, to, 1.0, |facet| ignore.contains(&facet), |_, t| t > lo && t < hi)
    }

    /// Whether point `from` on facet `from_facet` and point `to` on facet `to_facet` see each
    /// other: the open segment is free of every other facet (as [`Reference::visible`] with
    /// both ignored), and neither point is covered by a facet that wins it — one of a lower id
    /// hit within [`SEGMENT_END_TOL`] of that end. Overlapping coplanar facets (the Cornell
    /// box's light quad in its ceiling) go to the lowest id, as in [`Reference::first_hit`]:
    /// the part of the ceiling under the light neither sees nor is seen, as no ray of the
    /// renderer sees it. Non-finite input answers `false`; a zero-length segment is visible.
    pub fn surfaces_see(&self, from: [f64; 3], from_facet: u32, to: [f64; 3], to_facet: u32) -> bool {
        let tol = SEGMENT_END_TOL;
        let skip = |facet| facet == from_facet || facet == to_facet;
        let blocks = |facet, t: f64| {
            let inside = t > tol && t < 1.0 - tol;
            let covers_from = t.abs() <= tol && facet < from_facet;
            let covers_to = (t - 1.0).abs() <= tol && facet < to_facet;
            inside || covers_from || covers_to
        };
        self.segment_clear(from, to, 1.0 + tol, skip, blocks)
    }

    /// No triangle of a facet not `skip`ped is hit at a parameter `t ≤ reach` of the segment
    /// `from → to` that `blocks(facet, t)`. Non-finite input answers `false`; a zero-length
    /// segment is clear.
    fn segment_clear(
        &self,
        from: [f64; 3],
        to: [f64; 3],
        reach: f64,
        skip: impl Fn(u32) -> bool,
        blocks: impl Fn(u32, f64) -> bool,
    ) -> bool {
        let (from, to) = (Vector::from(from), Vector::from(to));
        if !from.is_finite() || !to.is_finite() {
            return false;
        }
        let d = to - from;
        if !d.is_finite() {
            return false;
        }
        let Some(sr) = ShearRay::new(from, d) else {
            return true; // from == to: the open segment is empty
        };
        let ray = Ray::new(from, d);
        for leaf in self.bvh.leaves(|node| node.cast_ray(&ray, reach) <= reach) {
            let tri = &self.tris[leaf as usize];
            if skip(tri.facet) {
                continue;
            }
            if sr.hit(tri).is_some_and(|t| blocks(tri.facet, t)) {
                return false;
            }
        }
        true
    }

    /// First hit along the ray `origin + t·dir` with `0 < t < max_t`, ignoring the facets in
    /// `ignore`: `(t, facet id, unit normal facing the ray origin)`. `t` is in units of `dir`
    /// (which need not be normalised). Non-finite input, a zero `dir` or `max_t ≤ 0` give `None`.
    ///
    /// Coplanar facets that overlap (the Cornell box's light quad in its ceiling) are hit at the
    /// same depth up to rounding: among the hits within [`TIE_REL`] of the first, the lowest
    /// facet id wins — the first in the scene's order, as the machine's depth test keeps the
    /// first of equal depths (`cell_core::visible`). Without it the rounding picked either
    /// facet pixel by pixel.
    pub fn first_hit(
        &self,
        origin: [f64; 3],
        dir: [f64; 3],
        max_t: f64,
        ignore: &[u32],
    ) -> Option<(f64, u32, [f64; 3])> {
        let (origin, dir) = (Vector::from(origin), Vector::from(dir));
        if !origin.is_finite() || !dir.is_finite() || max_t.is_nan() || max_t <= 0.0 {
            return None;
        }
        let sr = ShearRay::new(origin, dir)?;
        let ray = Ray::new(origin, dir);
        // Best-first traversal: nodes whose entry parameter is not below the best hit so far
        // are pruned; a leaf's value is accepted only when strictly below the best so far.
        let (leaf, t) = self.bvh.cast_ray(&ray, max_t, |leaf, best| {
            let tri = &self.tris[leaf as usize];
            if ignore.contains(&tri.facet) {
                return None;
            }
            let t = sr.hit(tri)?;
            (t > 0.0 && t < best).then_some(t)
        })?;
        let tie = t * (1.0 + TIE_REL);
        let tri = self
            .bvh
            .leaves(|node| node.cast_ray(&ray, tie) <= tie)
            .map(|l| &self.tris[l as usize])
            .filter(|c| !ignore.contains(&c.facet) && sr.hit(c).is_some_and(|tc| tc > 0.0 && tc <= tie))
            .min_by_key(|c| c.facet)
            .unwrap_or(&self.tris[leaf as usize]);
        let n = tri.normal;
        let n = if n.dot(dir) > 0.0 { -n } else { n };
        Some((t, tri.facet, n.to_array()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::rng::Rng;

    // The oracle's own arithmetic, independent of the code under test.
    type V3 = [f64; 3];

    fn sub(a: V3, b: V3) -> V3 {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }

    fn cross(a: V3, b: V3) -> V3 {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    }

    fn dot(a: V3, b: V3) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    fn point(rng: &mut Rng, lo: f64, hi: f64) -> V3 {
        [rng.range(lo, hi), rng.range(lo, hi), rng.range(lo, hi)]
    }

    /// Independent oracle: Möller–Trumbore over every triangle, no BVH.
    /// Returns (t, u, v, det/(|e1||e2||d|)) for a hit with inclusive barycentrics.
    fn mt(o: V3, d: V3, tri: &[V3; 3]) -> Option<(f64, f64, f64, f64)> {
        let e1 = sub(tri[1], tri[0]);
        let e2 = sub(tri[2], tri[0]);
        let p = cross(d, e2);
        let det = dot(e1, p);
        if det == 0.0 {
            return None;
        }
        let inv = 1.0 / det;
        let s = sub(o, tri[0]);
        let u = dot(s, p) * inv;
        let q = cross(s, e1);
        let v = dot(d, q) * inv;
        if u < 0.0 || v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = dot(e2, q) * inv;
        let scale = (dot(e1, e1) * dot(e2, e2) * dot(d, d)).sqrt();
        Some((t, u, v, det.abs() / scale))
    }

    /// Whether the oracle's answer for this triangle is too close to a decision boundary
    /// (an edge of the triangle, an end of the accepted `t` range, a grazing ray crossing the
    /// plane) for two different exact-`f64` tests to be required to agree on it.
    fn near_boundary(o: V3, d: V3, tri: &[V3; 3], lo: f64, hi: f64) -> bool {
        const EPS: f64 = 1e-7; // barycentric / angular band
        const EPS_T: f64 = 1e-12; // band around the ends of the t range
        let e1 = sub(tri[1], tri[0]);
        let e2 = sub(tri[2], tri[0]);
        let p = cross(d, e2);
        let det = dot(e1, p);
        let scale = (dot(e1, e1) * dot(e2, e2) * dot(d, d)).sqrt();
        if det.abs() <= EPS * scale {
            // Nearly parallel: ambiguous only if the ray reaches (or nearly reaches) the plane
            // within the accepted range.
            let n = cross(e1, e2);
            let nl = dot(n, n).sqrt();
            let size = dot(e1, e1).sqrt().max(dot(e2, e2).sqrt());
            let dist = |t: f64| dot(sub([o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]], tri[0]), n) / nl;
            let (s0, s1) = (dist(lo), dist(hi));
            return s0 * s1 <= 0.0 || s0.abs().min(s1.abs()) <= EPS * size;
        }
        let inv = 1.0 / det;
        let s = sub(o, tri[0]);
        let u = dot(s, p) * inv;
        let q = cross(s, e1);
        let v = dot(d, q) * inv;
        let t = dot(e2, q) * inv;
        let inside_loose = u >= -EPS && v >= -EPS && u + v <= 1.0 + EPS;
        let inside_tight = u >= EPS && v >= EPS && u + v <= 1.0 - EPS;
        let in_range = t >= lo - EPS_T && t <= hi + EPS_T;
        let t_near = (t - lo).abs() <= EPS_T || (t - hi).abs() <= EPS_T;
        (inside_loose && !inside_tight && in_range) || (inside_loose && t_near)
    }

    fn brute_visible(tris: &[[V3; 3]], facets: &[u32], from: V3, to: V3, ignore: &[u32]) -> bool {
        let d = sub(to, from);
        !tris.iter().zip(facets).any(|(tri, f)| {
            !ignore.contains(f)
                && mt(from, d, tri).is_some_and(|(t, ..)| t > SEGMENT_END_TOL && t < 1.0 - SEGMENT_END_TOL)
        })
    }

    fn brute_first(tris: &[[V3; 3]], facets: &[u32], o: V3, d: V3, max_t: f64, ignore: &[u32]) -> Option<(f64, usize)> {
        let mut best: Option<(f64, usize)> = None;
        for (i, (tri, f)) in tris.iter().zip(facets).enumerate() {
            if ignore.contains(f) {
                continue;
            }
            if let Some((t, ..)) = mt(o, d, tri) {
                let better = match best {
                    None => true,
                    Some((bt, _)) => t < bt,
                };
                if t > 0.0 && t < max_t && better {
                    best = Some((t, i));
                }
            }
        }
        best
    }

    fn ambiguous(tris: &[[V3; 3]], facets: &[u32], o: V3, d: V3, lo: f64, hi: f64, ignore: &[u32]) -> bool {
        tris.iter().zip(facets).any(|(tri, f)| !ignore.contains(f) && near_boundary(o, d, tri, lo, hi))
    }

    fn unit_normal(tri: &[V3; 3]) -> V3 {
        let n = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
        let l = dot(n, n).sqrt();
        n.map(|x| x / l)
    }

    /// Compare `visible` and `first_hit` with the brute force on `n` random queries.
    /// Returns (blocked count, hit count, ambiguous `visible` cases skipped, ambiguous
    /// `first_hit` cases skipped).
    fn compare(
        tris: &[[V3; 3]],
        facets: &[u32],
        n: usize,
        rng: &mut Rng,
        mut gen: impl FnMut(&mut Rng) -> (V3, V3),
    ) -> (usize, usize, usize, usize) {
        let r = Reference::new(tris.to_vec(), facets.to_vec()).unwrap();
        assert_eq!(r.triangle_count(), tris.len());
        let max_facet = facets.iter().copied().max().unwrap() as u64;
        let (mut blocked, mut hits, mut skip_vis, mut skip_first) = (0, 0, 0, 0);
        for q in 0..n {
            let (a, b) = gen(rng);
            let ignore: Vec<u32> = match q % 3 {
                0 => vec![],
                1 => vec![rng.below(max_facet + 1) as u32],
                _ => (0..3).map(|_| rng.below(max_facet + 1) as u32).collect(),
            };
            let d = sub(b, a);
            // visible
            if ambiguous(tris, facets, a, d, SEGMENT_END_TOL, 1.0 - SEGMENT_END_TOL, &ignore) {
                skip_vis += 1;
            } else {
                let want = brute_visible(tris, facets, a, b, &ignore);
                assert_eq!(r.visible(a, b, &ignore), want, "visible({a:?}, {b:?}, {ignore:?})");
                assert_eq!(r.visible(b, a, &ignore), want, "visible reversed ({b:?}, {a:?}, {ignore:?})");
                blocked += usize::from(!want);
            }
            // first_hit along the same ray, past the segment end (max_t = 3)
            let max_t = 3.0;
            if ambiguous(tris, facets, a, d, 0.0, max_t, &ignore) {
                skip_first += 1;
                continue;
            }
            let want = brute_first(tris, facets, a, d, max_t, &ignore);
            let got = r.first_hit(a, d, max_t, &ignore);
            match (want, got) {
                (None, None) => {}
                (Some((wt, wi)), Some((gt, gf, gn))) => {
                    hits += 1;
                    assert!((wt - gt).abs() <= 1e-9 * wt.max(1.0), "t: brute {wt} vs {gt} for {a:?} + t·{d:?}");
                    // Two triangles at (nearly) the same t: either facet is right.
                    let same_t: Vec<u32> = tris
                        .iter()
                        .zip(facets)
                        .filter(|(tri, f)| {
                            !ignore.contains(f) && mt(a, d, tri).is_some_and(|(t, ..)| (t - wt).abs() <= 1e-9)
                        })
                        .map(|(_, f)| *f)
                        .collect();
                    assert!(same_t.contains(&gf), "facet {gf} not among {same_t:?} (brute {})", facets[wi]);
                    if same_t.len() == 1 {
                        let mut n = unit_normal(&tris[wi]);
                        if dot(n, d) > 0.0 {
                            n = n.map(|x| -x);
                        }
                        for k in 0..3 {
                            assert!((n[k] - gn[k]).abs() < 1e-12, "normal {gn:?} vs {n:?}");
                        }
                    }
                    assert!(dot(gn, d) <= 0.0, "normal must face the ray origin");
                    assert!((dot(gn, gn) - 1.0).abs() < 1e-12);
                }
                (w, g) => panic!("first_hit({a:?}, {d:?}, {max_t}, {ignore:?}): brute {w:?}, got {g:?}"),
            }
        }
        eprintln!("{n} queries: {blocked} blocked, {hits} first hits, {skip_vis} + {skip_first} ambiguous skipped");
        (blocked, hits, skip_vis, skip_first)
    }

    fn random_soup(rng: &mut Rng, n: usize, size: f64) -> (Vec<[V3; 3]>, Vec<u32>) {
        let mut tris = Vec::new();
        let mut facets = Vec::new();
        for i in 0..n {
            let c = point(rng, 0.0, 1.0);
            let mut t = [[0.0; 3]; 3];
            for p in &mut t {
                *p = [c[0] + rng.range(-size, size), c[1] + rng.range(-size, size), c[2] + rng.range(-size, size)];
            }
            tris.push(t);
            facets.push((i / 2) as u32); // two triangles per facet
        }
        (tris, facets)
    }

    /// Axis-aligned box [lo, hi]³ as 12 triangles, facet = face index 0..6 (+ `base`),
    /// outward winding.
    fn boxed(lo: V3, hi: V3, base: u32) -> (Vec<[V3; 3]>, Vec<u32>) {
        let c = |i: usize| {
            [
                if i & 1 != 0 { hi[0] } else { lo[0] },
                if i & 2 != 0 { hi[1] } else { lo[1] },
                if i & 4 != 0 { hi[2] } else { lo[2] },
            ]
        };
        // quads (outward, counter-clockwise seen from outside)
        let quads = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
        let mut tris = Vec::new();
        let mut facets = Vec::new();
        for (f, q) in quads.iter().enumerate() {
            tris.push([c(q[0]), c(q[1]), c(q[2])]);
            tris.push([c(q[0]), c(q[2]), c(q[3])]);
            facets.extend([base + f as u32; 2]);
        }
        (tris, facets)
    }

    #[test]
    fn oracle_self_check() {
        // The brute force itself: a known hit, a known miss, and a parallel ray.
        let tri = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
        let (t, u, v, _) = mt([0.2, 0.2, 0.0], [0.0, 0.0, 2.0], &tri).unwrap();
        assert_eq!((t, u, v), (0.5, 0.2, 0.2));
        assert!(mt([0.8, 0.8, 0.0], [0.0, 0.0, 1.0], &tri).is_none());
        assert!(mt([0.2, 0.2, 0.0], [1.0, 0.0, 0.0], &tri).is_none());
    }

    #[test]
    fn random_soup_matches_brute_force() {
        let mut rng = Rng(1);
        let (tris, facets) = random_soup(&mut rng, 300, 0.15);
        let (blocked, hits, skip_vis, skip_first) =
            compare(&tris, &facets, 4000, &mut rng, |r| (point(r, -0.2, 1.2), point(r, -0.2, 1.2)));
        // The comparison must actually exercise both outcomes.
        assert!(blocked > 1000 && blocked < 3500, "blocked {blocked}");
        assert!(hits > 1000, "hits {hits}");
        assert!(skip_vis + skip_first < 40, "skipped {skip_vis} + {skip_first}");
    }

    #[test]
    fn closed_box_with_obstacles_matches_brute_force() {
        // A closed room (facets 0..6) with two boxes inside (facets 10..16, 20..26).
        let (mut tris, mut facets) = boxed([0.0; 3], [1.0; 3], 0);
        for (lo, hi, base) in [([0.2, 0.0, 0.2], [0.45, 0.6, 0.45], 10), ([0.55, 0.0, 0.5], [0.8, 0.3, 0.75], 20)] {
            let (t, f) = boxed(lo, hi, base);
            tris.extend(t);
            facets.extend(f);
        }
        let mut rng = Rng(2);
        // Endpoints anywhere in and around the room (some outside), and points on the walls.
        let (blocked, hits, skip_vis, skip_first) = compare(&tris, &facets, 6000, &mut rng, |r| {
            let mut p = point(r, -0.3, 1.3);
            let mut q = point(r, 0.01, 0.99);
            if r.below(3) == 0 {
                // put q exactly on a wall: the wall must not shadow its own point
                let k = r.below(3) as usize;
                q[k] = if r.below(2) == 0 { 0.0 } else { 1.0 };
            }
            if r.below(2) == 0 {
                std::mem::swap(&mut p, &mut q);
            }
            (p, q)
        });
        assert!(blocked > 1500, "blocked {blocked}");
        assert!(hits > 3000, "hits {hits}");
        assert!(skip_vis < 20, "skipped {skip_vis}");
        // first_hit from a point on a wall meets that wall at t ≈ 0: ambiguous by design (the
        // caller ignores its own facet); about 1/6 of the queries start on a wall.
        assert!(skip_first < 1200, "skipped {skip_first}");
    }

    #[test]
    fn closed_box_is_watertight() {
        // Every ray from inside a closed box hits it, also when aimed exactly at edges,
        // the face diagonals (shared by two triangles) and the corners.
        let (tris, facets) = boxed([-1.0, -2.0, 0.5], [3.0, 1.0, 2.5], 0);
        let r = Reference::new(tris, facets).unwrap();
        let lo = [-1.0, -2.0, 0.5];
        let hi = [3.0, 1.0, 2.5];
        let mut rng = Rng(3);
        let mut n = 0;
        for _ in 0..2000 {
            let o = [rng.range(lo[0], hi[0]), rng.range(lo[1], hi[1]), rng.range(lo[2], hi[2])];
            // target on an edge, a face diagonal, or a corner
            let s = rng.f();
            let mut p = [0.0; 3];
            for k in 0..3 {
                p[k] = if rng.below(2) == 0 { lo[k] } else { hi[k] };
            }
            match rng.below(3) {
                0 => {
                    let k = rng.below(3) as usize; // along an edge
                    p[k] = lo[k] + s * (hi[k] - lo[k]);
                }
                1 => {
                    // along a face diagonal: two coordinates move together
                    let k = rng.below(3) as usize;
                    let j = (k + 1) % 3;
                    p[k] = lo[k] + s * (hi[k] - lo[k]);
                    p[j] = lo[j] + s * (hi[j] - lo[j]);
                }
                _ => {}
            }
            let d = sub(p, o);
            let (t, f, nrm) = r.first_hit(o, d, 10.0, &[]).unwrap_or_else(|| panic!("leak: {o:?} → {p:?}"));
            assert!((t - 1.0).abs() < 1e-9, "t = {t} for {o:?} → {p:?} (facet {f})");
            assert!(dot(nrm, d) < 0.0);
            // and past the target, with the hit face ignored, still something (another face
            // through the same edge, or the ray leaves the box there)
            assert!(!r.visible(o, [o[0] + 2.0 * d[0], o[1] + 2.0 * d[1], o[2] + 2.0 * d[2]], &[]));
            n += 1;
        }
        assert_eq!(n, 2000);
    }

    #[test]
    fn axis_aligned_grid_matches_brute_force() {
        // Flat (zero-thickness) boxes in the BVH and axis-parallel rays (zero direction
        // components): the culling must not lose these.
        let mut tris = Vec::new();
        let mut facets = Vec::new();
        for z in 0..8 {
            for x in 0..8 {
                for y in 0..8 {
                    if (x + y + z) % 3 == 0 {
                        continue;
                    }
                    let (x, y, zf) = (x as f64, y as f64, z as f64);
                    tris.push([[x, y, zf], [x + 1.0, y, zf], [x, y + 1.0, zf]]);
                    facets.push(tris.len() as u32 - 1);
                }
            }
        }
        let mut rng = Rng(4);
        let (blocked, hits, skip_vis, skip_first) = compare(&tris, &facets, 3000, &mut rng, |r| {
            let a = point(r, -0.5, 8.5);
            let mut b = a;
            let k = r.below(3) as usize;
            b[k] = r.range(-0.5, 8.5);
            (a, b)
        });
        assert!(blocked > 300, "blocked {blocked}");
        assert!(hits > 300, "hits {hits}");
        assert!(skip_vis + skip_first < 20, "skipped {skip_vis} + {skip_first}");
    }

    #[test]
    fn larger_mesh_matches_brute_force() {
        let mut rng = Rng(5);
        let (tris, facets) = random_soup(&mut rng, 3000, 0.04);
        let (blocked, hits, _, _) =
            compare(&tris, &facets, 1500, &mut rng, |r| (point(r, 0.0, 1.0), point(r, 0.0, 1.0)));
        assert!(blocked > 300 && hits > 300, "blocked {blocked} hits {hits}");
    }

    #[test]
    fn far_away_origin() {
        // A query origin far from the scene (1e5 × its size) still finds hits.
        let (tris, facets) = boxed([0.0; 3], [1.0; 3], 0);
        let r = Reference::new(tris, facets).unwrap();
        let o = [0.37, 0.61, -1.0e5];
        let (t, f, n) = r.first_hit(o, [0.0, 0.0, 1.0], f64::INFINITY, &[]).unwrap();
        assert_eq!((t, f, n), (1.0e5, 4, [0.0, 0.0, -1.0]));
        assert!(!r.visible(o, [0.4, 0.6, 0.5], &[]));
        assert!(r.visible(o, [0.4, 0.6, 0.5], &[4]));
        assert!(!r.visible(o, [0.4, 0.6, 2.0], &[4]));
        assert!(r.visible(o, [0.4, 0.6, 2.0], &[4, 5]));
    }

    #[test]
    fn ignore_really_ignores() {
        let tri = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
        let other = [[5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]];
        let r = Reference::new(vec![other, tri], vec![3, 7]).unwrap();
        let (a, b) = ([0.2, 0.2, 0.0], [0.2, 0.2, 2.0]);
        assert!(!brute_visible(&[other, tri], &[3, 7], a, b, &[]));
        assert!(!r.visible(a, b, &[]));
        assert!(!r.visible(b, a, &[]));
        assert!(!r.visible(a, b, &[3]));
        assert!(r.visible(a, b, &[7]));
        assert!(r.visible(a, b, &[3, 7]));
        // first_hit: the triangle at t = 0.5, normal facing the origin; nothing once ignored.
        assert_eq!(r.first_hit(a, [0.0, 0.0, 2.0], 10.0, &[]), Some((0.5, 7, [0.0, 0.0, -1.0])));
        assert_eq!(r.first_hit(b, [0.0, 0.0, -1.0], 10.0, &[]), Some((1.0, 7, [0.0, 0.0, 1.0])));
        assert_eq!(r.first_hit(a, [0.0, 0.0, 2.0], 10.0, &[7]), None);
        // max_t is exclusive
        assert_eq!(r.first_hit(a, [0.0, 0.0, 2.0], 0.5, &[]), None);
        // Two stacked facets: ignoring the near one finds the far one.
        let far = [[0.0, 0.0, 1.5], [1.0, 0.0, 1.5], [0.0, 1.0, 1.5]];
        let r = Reference::new(vec![tri, far], vec![7, 8]).unwrap();
        assert_eq!(r.first_hit(a, [0.0, 0.0, 1.0], 10.0, &[7]).map(|h| (h.0, h.1)), Some((1.5, 8)));
        assert!(!r.visible(a, b, &[7]));
        assert!(!r.visible(a, b, &[8]));
        assert!(r.visible(a, b, &[8, 7]));
    }

    #[test]
    fn segment_end_points_on_surfaces() {
        // Points lying exactly on a triangle (the usual lighting query: surface point → light)
        // are not shadowed by that triangle, at either end; a point just past it is.
        let tri = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
        let r = Reference::new(vec![tri], vec![0]).unwrap();
        let on = [0.25, 0.25, 1.0];
        assert!(r.visible(on, [0.3, 0.1, 3.0], &[]));
        assert!(r.visible([0.3, 0.1, -3.0], on, &[]));
        assert!(!r.visible([0.25, 0.25, 1.0 + 1e-6], [0.25, 0.25, 0.0], &[]));
        // a zero-length segment is visible; coplanar grazing does not block
        assert!(r.visible(on, on, &[]));
        assert!(r.visible([-1.0, 0.25, 1.0], [2.0, 0.25, 1.0], &[]));
        // an edge counts as the triangle
        assert!(!r.visible([0.5, 0.5, 0.0], [0.5, 0.5, 2.0], &[]));
        assert!(r.visible([0.5 + 1e-9, 0.5, 0.0], [0.5 + 1e-9, 0.5, 2.0], &[]));
    }

    #[test]
    fn degenerate_and_nan_input_are_errors() {
        let good = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let point = [[1.0, 2.0, 3.0]; 3];
        let line = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]];
        let line2 = [[0.0, 0.0, 0.0], [0.1, 0.2, 0.3], [0.2, 0.4, 0.6]];
        let nan = [[0.0, f64::NAN, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let inf = [[0.0, 0.0, 0.0], [f64::INFINITY, 0.0, 0.0], [0.0, 1.0, 0.0]];
        // all degenerate / empty / NaN / ∞ / mismatched lengths: errors
        assert!(Reference::new(vec![point, line, line2], vec![0, 1, 2]).is_err());
        assert!(Reference::new(vec![], vec![]).is_err());
        assert!(Reference::new(vec![good, nan], vec![0, 1]).is_err());
        assert!(Reference::new(vec![inf, good], vec![0, 1]).is_err());
        assert!(Reference::new(vec![good], vec![0, 1]).is_err());
        let e = Reference::new(vec![good, nan], vec![0, 1]).unwrap_err().to_string();
        assert!(e.contains("triangle 1"), "{e}");
        // degenerate triangles among good ones are skipped; facet ids stay with their triangles
        let far = [[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]];
        let r = Reference::new(vec![point, good, line, far, line2], vec![10, 11, 12, 13, 14]).unwrap();
        assert_eq!((r.triangle_count(), r.skipped()), (2, 3));
        let hit = r.first_hit([0.2, 0.2, -1.0], [0.0, 0.0, 1.0], 10.0, &[]).unwrap();
        assert_eq!((hit.0, hit.1), (1.0, 11));
        let hit = r.first_hit([0.2, 0.2, -1.0], [0.0, 0.0, 1.0], 10.0, &[11]).unwrap();
        assert_eq!((hit.0, hit.1), (3.0, 13));
        // NaN / ∞ queries do not panic
        assert!(!r.visible([f64::NAN, 0.0, 0.0], [0.0; 3], &[]));
        assert!(!r.visible([0.0; 3], [0.0, f64::INFINITY, 0.0], &[]));
        assert!(!r.visible([-1e308, 0.0, 0.0], [1e308, 0.0, 0.0], &[])); // overflowing direction
        assert_eq!(r.first_hit([0.2, 0.2, -1.0], [0.0, 0.0, f64::NAN], 10.0, &[]), None);
        assert_eq!(r.first_hit([0.2, 0.2, -1.0], [0.0, 0.0, 1.0], f64::NAN, &[]), None);
        assert_eq!(r.first_hit([0.2, 0.2, -1.0], [0.0; 3], 10.0, &[]), None);
        assert_eq!(r.first_hit([0.2, 0.2, -1.0], [0.0, 0.0, 1.0], -1.0, &[]), None);
    }

    /// Points of two overlapping coplanar quads (the light in its ceiling) and a point below:
    /// a point of the larger quad under the smaller one is covered when the smaller has the
    /// lower id and sees nothing, either way round; elsewhere both see the point below; a
    /// blocker between them blocks as [`Reference::visible`] does.
    #[test]
    fn covered_points_of_a_coplanar_overlap_neither_see_nor_are_seen() {
        let on = |x: f64, y: f64| [x, y, 0.3 * x + 0.7 * y + 5.0];
        let quad = |lo: f64, hi: f64| {
            let (a, b, c, d) = (on(lo, lo), on(hi, lo), on(hi, hi), on(lo, hi));
            [[a, b, c], [a, c, d]]
        };
        let below = [4.0, 5.0, -20.0];
        let mut rng = Rng(11);
        for (small_id, big_id) in [(3u32, 7u32), (7, 3)] {
            let r =
                Reference::new([quad(3.0, 6.0), quad(0.0, 10.0)].concat(), vec![small_id, small_id, big_id, big_id])
                    .unwrap();
            for _ in 0..2000 {
                let (x, y) = (10.0 * rng.f(), 10.0 * rng.f());
                let p = on(x, y);
                let under = (3.0..=6.0).contains(&x) && (3.0..=6.0).contains(&y);
                let want = !(under && small_id < big_id);
                assert_eq!(r.surfaces_see(p, big_id, below, 99), want, "({x}, {y}) from, small id {small_id}");
                assert_eq!(r.surfaces_see(below, 99, p, big_id), want, "({x}, {y}) to, small id {small_id}");
                // A point of the small quad is covered by the big one when that has the lower id.
                if under {
                    assert_eq!(r.surfaces_see(p, small_id, below, 99), small_id < big_id, "({x}, {y}) small");
                }
            }
        }
        let wall = [[[0.0, 0.0, -10.0], [20.0, 0.0, -10.0], [0.0, 20.0, -10.0]]];
        let r = Reference::new(wall.to_vec(), vec![1]).unwrap();
        assert!(!r.surfaces_see([1.0, 1.0, -20.0], 5, [1.0, 1.0, 0.0], 6), "a blocker in between");
        assert!(r.surfaces_see([1.0, 1.0, -20.0], 5, [1.0, 1.0, -10.0], 1), "the target's own facet");
        assert!(!r.surfaces_see([f64::NAN, 0.0, 0.0], 5, [1.0, 1.0, 0.0], 6));
    }

    /// Two overlapping coplanar quads in a tilted plane (the Cornell light in its ceiling): where
    /// both are hit, the lower facet id wins, whichever order they are given in; where only one
    /// is, that one.
    #[test]
    fn coplanar_overlap_is_won_by_the_lower_facet_id() {
        // The plane z = 0.3·x + 0.7·y + 5, seen along +z from below.
        let on = |x: f64, y: f64| [x, y, 0.3 * x + 0.7 * y + 5.0];
        let quad = |lo: f64, hi: f64| {
            let (a, b, c, d) = (on(lo, lo), on(hi, lo), on(hi, hi), on(lo, hi));
            [[a, b, c], [a, c, d]]
        };
        let (big, small) = (quad(0.0, 10.0), quad(3.0, 6.0));
        let mut rng = Rng(9);
        for order in [false, true] {
            let (tris, facets) = if order {
                ([big, small].concat(), vec![7, 7, 3, 3])
            } else {
                ([small, big].concat(), vec![3, 3, 7, 7])
            };
            let r = Reference::new(tris, facets).unwrap();
            for _ in 0..2000 {
                let (x, y) = (10.0 * rng.f(), 10.0 * rng.f());
                let inside = (3.0..=6.0).contains(&x) && (3.0..=6.0).contains(&y);
                let (t, facet, _) = r.first_hit([x, y, -20.0], [0.0, 0.0, 1.0], 100.0, &[]).unwrap();
                assert!((t - (on(x, y)[2] + 20.0)).abs() < 1e-9, "({x}, {y}): depth {t}");
                assert_eq!(facet, if inside { 3 } else { 7 }, "({x}, {y}), order {order}");
            }
        }
    }
}
