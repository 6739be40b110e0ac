//! The projection disk (radiosity thesis §2.4.2, Fig. 2.12–2.15): the hemisphere's base disk
//! cut into R × R equal square proxels on its bounding square `[−1, 1]²`, only those whose
//! centre is inside the disk used; by Nusselt's analogue every used proxel carries the same
//! FFE (here `1 / N_in`, N_in the used proxels, so they sum to 1 exactly; `(2/R)² / π` up to
//! the rim's O(R^-1.5)).
//!
//! Facets in the (u, v, ρ) frame (Goldfeather): `x = ρu, y = ρv, z = ρ√(1 − u² − v²)`. An
//! edge's plane through the centre `Ax + By + Cz = 0` projects on the disk as the half-ellipse
//! (MPE) `E(u, v) = Au + Bv + C√(1 − u² − v²) = 0` (Eq. 2.5); a proxel is inside a facet's
//! projection iff all its edges' `E` have the same sign, and its relative depth is
//! `λ = A″u + B″v + C″√(1 − u² − v²)` (§2.4.2). The square root is precomputed per proxel and
//! stored on 1/8 of the disk ([`octant_index`]); the facet's proxels are looked for only in the
//! rectangle bounding its arcs (Fig. 2.14–2.15: an arc's extremum in v is an end point's or
//! the ellipse's `V_max = √((A² + C²)/(A² + B² + C²))` when that point lies on the arc).

use anyhow::Result;
use parry3d_f64::math::Vector;

use super::{check_resolution, octant_index, octant_len, Cone, ProjectionSurface, Resolution};

/// The projection disk at resolution R (of its bounding square).
#[derive(Clone, Debug)]
pub struct Disk {
    r: u32,
    /// √(1 − u² − v²) on one octant; negative outside the disk.
    root: Vec<f64>,
    /// Used proxels.
    used: u64,
}

impl Disk {
    /// The disk at resolution `r`.
    pub fn new(r: u32) -> Result<Disk> {
        check_resolution("disk", r, false)?;
        let mut root = vec![-1.0; octant_len(r)];
        for j in 0..r.div_ceil(2) {
            for i in 0..=j {
                let (u, v) = (centre(r, i), centre(r, j));
                let s = 1.0 - u * u - v * v;
                root[octant_index(r, i, j)] = if s > 0.0 { s.sqrt() } else { -1.0 };
            }
        }
        let mut d = Disk { r, root, used: 0 };
        d.used =
            (0..r).flat_map(|j| (0..r).map(move |i| (i, j))).filter(|&(i, j)| d.sqrt_at(i, j) > 0.0).count() as u64;
        Ok(d)
    }

    /// The stored √(1 − u² − v²) of proxel (i, j), negative outside the disk.
    pub fn sqrt_at(&self, i: u32, j: u32) -> f64 {
        self.root[octant_index(self.r, i, j)]
    }

    /// Used proxels (centre inside the disk).
    pub fn used(&self) -> u64 {
        self.used
    }

    /// Proxel columns (or rows) `[lo, hi]` that the interval `[a, b]` of u (or v) touches.
    fn span(&self, a: f64, b: f64) -> (u32, u32) {
        let r = self.r as f64;
        let idx = |x: f64| (((x + 1.0) / 2.0 * r).floor()).clamp(0.0, r - 1.0) as u32;
        (idx(a), idx(b))
    }

    /// The z-buffer pass of one facet over its bounding rectangle (§2.4.2's algorithm).
    fn project(&self, f: usize, cone: &Cone, rect: [f64; 4], zbuf: &mut [(f64, u32)]) {
        let (i0, i1) = self.span(rect[0], rect[1]);
        let (j0, j1) = self.span(rect[2], rect[3]);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let s = self.sqrt_at(i, j);
                if s <= 0.0 {
                    continue;
                }
                if let Some(t) = cone.hit([centre(self.r, i), centre(self.r, j), s]) {
                    let slot = &mut zbuf[(j * self.r + i) as usize];
                    if t < slot.0 {
                        *slot = (t, f as u32);
                    }
                }
            }
        }
    }
}

/// Centre of proxel i along an axis of `[−1, 1]` cut in r.
fn centre(r: u32, i: u32) -> f64 {
    -1.0 + (i as f64 + 0.5) * 2.0 / r as f64
}

/// The (u, v) rectangle bounding a facet's projection on the disk (Fig. 2.15): each edge's arc
/// bounded by its end points and, where they lie on the arc, the ellipse's extrema. Vertices
/// below the base plane are clipped first (the disk sees the upper half only).
pub fn bounding_rect(local: &[[f64; 3]; 3]) -> Option<[f64; 4]> {
    let poly = clip_above(local);
    if poly.len() < 3 {
        return None;
    }
    let unit = |p: [f64; 3]| {
        let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        [p[0] / n, p[1] / n, p[2] / n]
    };
    let mut rect = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
    for k in 0..poly.len() {
        let (a, b) = (unit(poly[k]), unit(poly[(k + 1) % poly.len()]));
        for axis in 0..2 {
            let (lo, hi) = arc_extent(a, b, axis);
            rect[2 * axis] = rect[2 * axis].min(lo);
            rect[2 * axis + 1] = rect[2 * axis + 1].max(hi);
        }
    }
    Some(rect)
}

/// The extent along `axis` (0: u, 1: v) of the great-circle arc from unit `a` to unit `b`: its
/// end points, and the great circle's extremum `±√(1 − n_axis²)` (the thesis's `U_max`,
/// `V_max` of the ellipse, n the unit normal of the edge's plane) when it lies on the arc.
fn arc_extent(a: [f64; 3], b: [f64; 3], axis: usize) -> (f64, f64) {
    let (mut lo, mut hi) = (a[axis].min(b[axis]), a[axis].max(b[axis]));
    let n = Vector::from(a).cross(Vector::from(b));
    if n.length() < 1e-15 {
        return (lo, hi);
    }
    let n = n.normalize();
    let mut e = [0.0; 3];
    e[axis] = 1.0;
    // The circle's point of extreme coordinate: the axis projected on the circle's plane.
    let p = Vector::from(e) - n * n[axis];
    if p.length() < 1e-15 {
        return (lo, hi);
    }
    for q in [p.normalize(), -p.normalize()] {
        let on_arc = Vector::from(a).cross(q).dot(n) >= 0.0 && q.cross(Vector::from(b)).dot(n) >= 0.0;
        if on_arc {
            lo = lo.min(q[axis]);
            hi = hi.max(q[axis]);
        }
    }
    (lo, hi)
}

/// The polygon clipped to z ≥ 0.
fn clip_above(v: &[[f64; 3]; 3]) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(4);
    for k in 0..3 {
        let (p, q) = (v[k], v[(k + 1) % 3]);
        if p[2] >= 0.0 {
            out.push(p);
        }
        if (p[2] >= 0.0) != (q[2] >= 0.0) {
            let t = p[2] / (p[2] - q[2]);
            out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]), 0.0]);
        }
    }
    out
}

/// One plane, the bounding square R × R (sample `j·R + i`), its proxels outside the disk absent.
impl super::Planar for Disk {
    fn planes(&self) -> Vec<(u32, u32)> {
        vec![(self.r, self.r)]
    }
    fn sample_at(&self, plane: usize, i: u32, j: u32) -> Option<usize> {
        (plane == 0 && i < self.r && j < self.r && self.sqrt_at(i, j) > 0.0).then(|| (j * self.r + i) as usize)
    }
    fn rects(&self, local: &[[f64; 3]; 3]) -> Vec<super::PlaneRect> {
        bounding_rect(local)
            .map(|rect| {
                let ((i0, i1), (j0, j1)) = (self.span(rect[0], rect[1]), self.span(rect[2], rect[3]));
                super::PlaneRect { plane: 0, i0, i1, j0, j1 }
            })
            .into_iter()
            .collect()
    }
}

impl ProjectionSurface for Disk {
    fn name(&self) -> &'static str {
        "disk"
    }
    fn resolution(&self) -> Resolution {
        Resolution::Single(self.r)
    }
    /// R², the bounding square, as Table 2.2 counts (about 21 % of them outside the disk).
    fn proxels(&self) -> u64 {
        (self.r as u64).pow(2)
    }
    fn largest_delta_ff(&self) -> f64 {
        1.0 / self.used as f64
    }
    /// §2.5.3: 8 bytes per used proxel and the root on 1/8 of them, 4 bytes each:
    /// `Q_d = 17/2 R² π/4` with N_in for `R² π/4`.
    fn memory_bytes(&self) -> u64 {
        8 * self.used + self.used / 2
    }
    fn samples(&self) -> usize {
        (self.r as usize).pow(2)
    }
    fn direction(&self, k: usize) -> [f64; 3] {
        let r = self.r as usize;
        let (i, j) = ((k % r) as u32, (k / r) as u32);
        [centre(self.r, i), centre(self.r, j), self.sqrt_at(i, j).max(0.0)]
    }
    fn delta(&self, k: usize) -> f64 {
        let r = self.r as usize;
        if self.sqrt_at((k % r) as u32, (k / r) as u32) > 0.0 {
            1.0 / self.used as f64
        } else {
            0.0
        }
    }
    /// §2.4.2's algorithm: per facet, its MPEs and bounding rectangle, then the proxels of the
    /// rectangle through the depth buffer.
    fn form_factors(&self, x: Vector, n: Vector, facets: &[[Vector; 3]]) -> Vec<f64> {
        super::by_facet(self, x, n, facets, |f, cone, local, zbuf| {
            if let Some(rect) = bounding_rect(local) {
                self.project(f as usize, cone, rect, zbuf);
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::projective::{depth_buffer, local_cones, testkit};

    #[test]
    fn deltas_sum_to_one_and_a_fifth_is_unused() {
        let d = Disk::new(100).unwrap();
        let s: f64 = (0..d.samples()).map(|k| d.delta(k)).sum();
        assert!((s - 1.0).abs() < 1e-9);
        let unused = 1.0 - d.used() as f64 / d.proxels() as f64;
        assert!((unused - (1.0 - std::f64::consts::FRAC_PI_4)).abs() < 0.01, "{unused}");
    }

    #[test]
    fn bounding_rectangles_agree_with_the_full_scan() {
        let d = Disk::new(64).unwrap();
        let v = Vector::new;
        let facets = vec![
            [v(-0.5, 0.2, 0.3), v(0.8, -0.3, 0.2), v(0.1, 0.9, 0.05)],
            [v(2.0, 0.0, -0.5), v(0.0, 2.0, 1.0), v(-2.0, -1.0, 0.4)],
        ];
        let fast = d.form_factors(Vector::ZERO, Vector::Z, &facets);
        let ids = depth_buffer(&d, &local_cones(Vector::ZERO, Vector::Z, &facets));
        let mut slow = vec![0.0; 2];
        d.gather(&ids, &mut slow);
        assert_eq!(fast, slow);
    }

    #[test]
    fn enclosure_parallel_perpendicular_occlusion() {
        // δ: a proxel is 2/R wide in (u, v); at radius ρ the direction turns by at most
        // dρ/√(1 − ρ²) per unit of ρ. The used proxel nearest the rim has its centre at
        // ρ_c < 1 and reaches ρ_c + √2/R: bounded by the angle from asin(ρ_c − √2/R) to
        // asin(min(1, ρ_c + √2/R)), ρ_c ≤ 1.
        let make: testkit::Make = |r| {
            let d = Disk::new(r).unwrap();
            let h = std::f64::consts::SQRT_2 / r as f64;
            let delta = std::f64::consts::FRAC_PI_2 - (1.0 - 2.0 * h).max(0.0).asin();
            (Box::new(d), delta)
        };
        testkit::all_checks(make, 32, 128, 1.0);
    }

    #[test]
    fn zero_resolution_is_refused() {
        assert!(Disk::new(0).is_err());
    }
}
