//! Cohen's hemicube (radiosity thesis §2.3.1, Fig. 2.4): five faces of the half cube of
//! half-side 1 above the differential area: the top face z = 1 cut into R × R square proxels,
//! the four side faces into R × R/2 (R even).
//!
//! Delta form factors (§2.3.1): `ΔS / (π (x² + y² + 1)²)` on the top face and
//! `z ΔS / (π (y² + z² + 1)²)` on the side faces at the proxel's centre; here each proxel's
//! exact form factor (the closed form of a small rectangle, [`point_to_parallel_rectangle`],
//! and the contour integral, [`point_to_polygon`]), so that they sum to 1 up to rounding.
//! Stored by symmetry: 1/8 of the top face ([`octant_index`]) and, for the sides, the half of
//! one side face that the symmetry in y leaves (R²/4 values; the thesis counts 1/4 of a side
//! face, R²/8, which a face symmetric only in y does not allow — its byte model is kept in
//! [`ProjectionSurface::memory_bytes`], see docs/FORM-FACTORS.md).
//!
//! Samples: the R² top proxels row by row, then the four side faces (+x, −x, +y, −y), each
//! R × R/2 with the height index fastest.
//!
//! The depth buffer projects each facet on each face and tests only the proxels of its
//! projection's bounding rectangle there (the thesis's hemicube follows the projected contour,
//! the disk scans bounding rectangles, §2.5.3; a rectangle here keeps the two comparable in
//! Fig. 2.16's time): a facet is clipped to the face's side of the plane through the centre
//! parallel to it, and its vertices projected; the proxels kept are the full scan's.

use std::f64::consts::PI;
use std::sync::OnceLock;

use anyhow::Result;
use parry3d_f64::math::Vector;

use super::{check_resolution, octant_index, octant_len, Cone, Planar, ProjectionSurface, Resolution};
use crate::truth::closed_form::{point_to_parallel_rectangle, point_to_polygon};

/// A hemicube at resolution R (even).
#[derive(Debug)]
pub struct Hemicube {
    r: u32,
    /// The stored FFEs, computed on first use.
    tables: OnceLock<Tables>,
}

/// The stored FFEs.
#[derive(Debug)]
struct Tables {
    /// Top-face FFEs on one octant.
    top: Vec<f64>,
    /// Side-face FFEs on the half y ≥ 0 of the +x face: index `j * (R/2) + k` (j from the
    /// middle outwards, k the height).
    side: Vec<f64>,
}

impl Hemicube {
    /// A hemicube at resolution `r` (even, 2..=[`super::MAX_RESOLUTION`]).
    pub fn new(r: u32) -> Result<Hemicube> {
        check_resolution("hemicube", r, true)?;
        Ok(Hemicube { r, tables: OnceLock::new() })
    }

    fn tables(&self) -> &Tables {
        self.tables.get_or_init(|| {
            let (r, w) = (self.r, 2.0 / self.r as f64);
            let mut top = vec![0.0; octant_len(r)];
            for j in 0..r.div_ceil(2) {
                for i in 0..=j {
                    top[octant_index(r, i, j)] = top_cell(w, i, j);
                }
            }
            let h = r / 2;
            let mut side = vec![0.0; (h * h) as usize];
            for j in 0..h {
                for k in 0..h {
                    side[(j * h + k) as usize] = side_cell(w, h + j, k);
                }
            }
            Tables { top, side }
        })
    }

    /// Proxel indices `[lo, hi]` along an axis of `[lo_edge, lo_edge + cells · w]` cut in
    /// `cells` that the interval `[a, b]` touches, or `None` if it misses the axis.
    fn span(a: f64, b: f64, lo_edge: f64, cells: u32, w: f64) -> Option<(u32, u32)> {
        let hi_edge = lo_edge + cells as f64 * w;
        if b < lo_edge || a > hi_edge || a.is_nan() || b.is_nan() {
            return None;
        }
        let idx = |x: f64| ((x - lo_edge) / w).floor().clamp(0.0, cells as f64 - 1.0) as u32;
        Some((idx(a), idx(b)))
    }

    /// One facet's depth-buffer pass on the five faces, over its projection's bounding
    /// rectangle on each.
    fn project(&self, f: u32, cone: &Cone, local: &[[f64; 3]; 3], zbuf: &mut [(f64, u32)]) {
        for rect in self.rects(local) {
            for i in rect.i0..=rect.i1 {
                for j in rect.j0..=rect.j1 {
                    let k = self.sample_at(rect.plane, i, j).expect("a hemicube proxel exists");
                    if let Some(t) = cone.hit(self.direction(k)) {
                        let slot = &mut zbuf[k];
                        if t < slot.0 {
                            *slot = (t, f);
                        }
                    }
                }
            }
        }
    }

    /// Each face: the axis it faces (index, sign), its two in-face axes, its first sample.
    fn faces(&self) -> [(usize, f64, usize, usize, usize); 5] {
        let r = self.r;
        let h = r / 2;
        [
            (2, 1.0, 0, 1, 0),
            (0, 1.0, 1, 2, (r * r) as usize),
            (0, -1.0, 1, 2, (r * r + r * h) as usize),
            (1, 1.0, 0, 2, (r * r + 2 * r * h) as usize),
            (1, -1.0, 0, 2, (r * r + 3 * r * h) as usize),
        ]
    }

    fn side_delta(&self, j: u32, k: u32) -> f64 {
        let h = self.r / 2;
        let jf = if j >= h { j - h } else { h - 1 - j };
        self.tables().side[(jf * h + k) as usize]
    }
}

/// Exact FFE of top cell (i, j): the rectangle `[−1 + iw, −1 + (i+1)w] × …` at height 1.
fn top_cell(w: f64, i: u32, j: u32) -> f64 {
    let (x0, y0) = (-1.0 + i as f64 * w, -1.0 + j as f64 * w);
    point_to_parallel_rectangle(x0, x0 + w, y0, y0 + w, 1.0)
}

/// Exact FFE of the +x face's cell (j along y, k along z).
fn side_cell(w: f64, j: u32, k: u32) -> f64 {
    let (y0, z0) = (-1.0 + j as f64 * w, k as f64 * w);
    let p = |y: f64, z: f64| Vector::new(1.0, y, z);
    let poly = [p(y0, z0), p(y0 + w, z0), p(y0 + w, z0 + w), p(y0, z0 + w)];
    point_to_polygon(Vector::ZERO, Vector::Z, &poly, -Vector::X)
}

impl ProjectionSurface for Hemicube {
    fn name(&self) -> &'static str {
        "hemicube"
    }
    fn resolution(&self) -> Resolution {
        Resolution::Single(self.r)
    }
    /// R² on top and 4 × R × R/2 on the sides: 3R² (Table 2.2).
    fn proxels(&self) -> u64 {
        3 * (self.r as u64).pow(2)
    }
    /// The proxels at the centre of the top face (§2.5.2).
    fn largest_delta_ff(&self) -> f64 {
        let c = self.r / 2;
        top_cell(2.0 / self.r as f64, c, c)
    }
    /// §2.5.3: 8 bytes (facet id, distance) per proxel, 4 per stored FFE on 1/8 of the top and
    /// 1/4 of a side face as the thesis counts: `Q_hc = 25 R²`.
    fn memory_bytes(&self) -> u64 {
        let r2 = (self.r as u64).pow(2);
        8 * 3 * r2 + 4 * (r2 / 8 + r2 / 8)
    }
    fn samples(&self) -> usize {
        3 * (self.r as usize).pow(2)
    }
    fn direction(&self, k: usize) -> [f64; 3] {
        let (r, w) = (self.r as usize, 2.0 / self.r as f64);
        let c = |i: usize| -1.0 + (i as f64 + 0.5) * w;
        if k < r * r {
            return [c(k % r), c(k / r), 1.0];
        }
        let k = k - r * r;
        let (face, rest) = (k / (r * r / 2), k % (r * r / 2));
        let (j, z) = (c(rest / (r / 2)), (rest % (r / 2)) as f64 * w + 0.5 * w);
        match face {
            0 => [1.0, j, z],
            1 => [-1.0, j, z],
            2 => [j, 1.0, z],
            _ => [j, -1.0, z],
        }
    }
    /// The depth buffer over each facet's bounding rectangle on each face (module
    /// documentation); the same proxels as the full scan.
    fn form_factors(&self, x: Vector, n: Vector, facets: &[[Vector; 3]]) -> Vec<f64> {
        super::by_facet(self, x, n, facets, |f, cone, local, zbuf| self.project(f, cone, local, zbuf))
    }
    fn delta(&self, k: usize) -> f64 {
        let r = self.r as usize;
        if k < r * r {
            return self.tables().top[octant_index(self.r, (k % r) as u32, (k / r) as u32)];
        }
        let rest = (k - r * r) % (r * r / 2);
        self.side_delta((rest / (r / 2)) as u32, (rest % (r / 2)) as u32)
    }
}

/// Planes 0 (top, R × R, sample `j·R + i`) and 1–4 (+x, −x, +y, −y: R columns along the
/// face's horizontal axis × R/2 rows of height, sample `first + i·R/2 + j`).
impl Planar for Hemicube {
    fn planes(&self) -> Vec<(u32, u32)> {
        let (r, h) = (self.r, self.r / 2);
        vec![(r, r), (r, h), (r, h), (r, h), (r, h)]
    }
    fn sample_at(&self, plane: usize, i: u32, j: u32) -> Option<usize> {
        let (r, h) = (self.r, self.r / 2);
        let first = self.faces().get(plane)?.4;
        if plane == 0 {
            (i < r && j < r).then(|| (j * r + i) as usize)
        } else {
            (i < r && j < h).then(|| first + (i * h + j) as usize)
        }
    }
    fn rects(&self, local: &[[f64; 3]; 3]) -> Vec<super::PlaneRect> {
        self.outlines(local).into_iter().map(|(rect, _)| rect).collect()
    }
}

/// One row of proxels a facet's projection may cover: columns `i0..=i1` of row `j` on `plane`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    /// The face.
    pub plane: usize,
    /// The row.
    pub j: u32,
    /// First column.
    pub i0: u32,
    /// Last column.
    pub i1: u32,
}

impl Hemicube {
    /// Per face the facet's projection reaches: its bounding rectangle and the facet clipped in
    /// front of the face (a convex polygon whose projection is the outline on the face).
    fn outlines(&self, local: &[[f64; 3]; 3]) -> Vec<(super::PlaneRect, Vec<[f64; 3]>)> {
        let (r, w) = (self.r, 2.0 / self.r as f64);
        let h = r / 2;
        let mut out = Vec::new();
        for (face, &(axis, sign, ua, va, _)) in self.faces().iter().enumerate() {
            let depth = |p: &[f64; 3]| sign * p[axis];
            let poly = clip_in_front(local, axis, sign);
            if poly.len() < 3 {
                continue;
            }
            let mut rect = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
            for p in &poly {
                let (u, v) = (p[ua] / depth(p), p[va] / depth(p));
                rect = [rect[0].min(u), rect[1].max(u), rect[2].min(v), rect[3].max(v)];
            }
            let top = face == 0;
            let Some((i0, i1)) = Self::span(rect[0], rect[1], -1.0, r, w) else { continue };
            let (v_lo, v_cells) = if top { (-1.0, r) } else { (0.0, h) };
            let Some((j0, j1)) = Self::span(rect[2], rect[3], v_lo, v_cells, w) else { continue };
            out.push((super::PlaneRect { plane: face, i0, i1, j0, j1 }, poly));
        }
        out
    }

    /// The spans of a facet (radiosity thesis §6.4, Fig. 6.16): per face and proxel row of its
    /// bounding rectangle, the columns whose centres its outline may cover, widened by one
    /// proxel each side (a conservative span; the cells' cone test decides), within the
    /// rectangle. The row's centre line is a plane through the centre (`p_v = v₀ · depth`),
    /// cut with the clipped facet in 3D (well conditioned even where the facet grazes the
    /// face's plane and its projection runs to infinity). Rows the facet misses give none.
    pub fn spans(&self, local: &[[f64; 3]; 3]) -> Vec<Span> {
        let w = 2.0 / self.r as f64;
        let faces = self.faces();
        let mut out = Vec::new();
        for (rect, poly) in self.outlines(local) {
            let (axis, sign, ua, va, _) = faces[rect.plane];
            let v_lo = if rect.plane == 0 { -1.0 } else { 0.0 };
            let col = |u: f64| ((u + 1.0) / w - 0.5).floor();
            for j in rect.j0..=rect.j1 {
                let v0 = v_lo + (j as f64 + 0.5) * w;
                let side = |p: &[f64; 3]| p[va] - v0 * sign * p[axis];
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for k in 0..poly.len() {
                    let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
                    let (sp, sq) = (side(&p), side(&q));
                    let mut cut = |x: [f64; 3]| {
                        let u = x[ua] / (sign * x[axis]);
                        lo = lo.min(u);
                        hi = hi.max(u);
                    };
                    if sp == 0.0 {
                        cut(p);
                    }
                    if (sp < 0.0 && sq > 0.0) || (sp > 0.0 && sq < 0.0) {
                        let t = sp / (sp - sq);
                        cut(std::array::from_fn(|c| p[c] + t * (q[c] - p[c])));
                    }
                }
                if lo > hi || lo.is_nan() || hi.is_nan() {
                    continue;
                }
                let i0 = col(lo).max(rect.i0 as f64).min(rect.i1 as f64) as u32;
                let i1 = (col(hi) + 1.0).max(rect.i0 as f64).min(rect.i1 as f64) as u32;
                out.push(Span { plane: rect.plane, j, i0, i1 });
            }
        }
        out
    }
}

/// The part of triangle `v` in front of a face: where `sign · v[axis] > 0` (one
/// Sutherland–Hodgman pass). A crossing point lies on the plane, where projecting divides by
/// zero: it is moved `1e-12` of the triangle's size in front, so that its projection is far out
/// in the direction the edge's projection runs to (or, when it projects to 0, where the rest of
/// the edge's projection already is).
fn clip_in_front(v: &[[f64; 3]; 3], axis: usize, sign: f64) -> Vec<[f64; 3]> {
    let scale = v.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs())).max(f64::MIN_POSITIVE);
    let mut out = Vec::with_capacity(4);
    for k in 0..3 {
        let (p, q) = (v[k], v[(k + 1) % 3]);
        let (dp, dq) = (sign * p[axis], sign * q[axis]);
        if dp > 0.0 {
            out.push(p);
        }
        if (dp > 0.0) != (dq > 0.0) {
            let t = dp / (dp - dq);
            let mut x: [f64; 3] = std::array::from_fn(|i| p[i] + t * (q[i] - p[i]));
            x[axis] = sign * 1e-12 * scale;
            out.push(x);
        }
    }
    out
}

/// The thesis's top-face FFE formula at a proxel centre (§2.3.1), for the tests.
pub fn thesis_top_delta(x: f64, y: f64, area: f64) -> f64 {
    area / (PI * (x * x + y * y + 1.0).powi(2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::projective::{local_cones, testkit};

    #[test]
    fn deltas_sum_to_one_and_match_the_thesis_formula() {
        let h = Hemicube::new(40).unwrap();
        testkit::deltas_sum_to(&h, 1.0);
        // Centre proxel against §2.3.1's formula at its centre: O(w²) apart.
        let w = 0.05;
        let f = thesis_top_delta(w / 2.0, w / 2.0, w * w);
        assert!((h.largest_delta_ff() - f).abs() < f * w * w, "{} {f}", h.largest_delta_ff());
    }

    #[test]
    fn enclosure_parallel_perpendicular_occlusion() {
        testkit::all_checks(
            |r| (Box::new(Hemicube::new(r).unwrap()), std::f64::consts::SQRT_2 / r as f64),
            24,
            96,
            1.0,
        );
    }

    #[test]
    fn bounding_rectangles_agree_with_the_full_scan() {
        use crate::truth::projective::depth_buffer;
        let h = Hemicube::new(32).unwrap();
        let v = Vector::new;
        let mut rng = crate::rng::Rng(11);
        let mut facets = vec![
            [v(-0.5, 0.2, 0.3), v(0.8, -0.3, 0.2), v(0.1, 0.9, 0.05)],
            [v(2.0, 0.0, -0.5), v(0.0, 2.0, 1.0), v(-2.0, -1.0, 0.4)],
            [v(-3.0, -3.0, 0.0), v(3.0, -3.0, 0.0), v(0.0, 3.0, 2.0)],
        ];
        for _ in 0..60 {
            let p = |rng: &mut crate::rng::Rng| v(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), rng.range(-0.5, 2.0));
            facets.push([p(&mut rng), p(&mut rng), p(&mut rng)]);
        }
        for normal in [Vector::Z, v(0.3, -0.2, 1.0).normalize()] {
            let fast = h.form_factors(Vector::ZERO, normal, &facets);
            let ids = depth_buffer(&h, &local_cones(Vector::ZERO, normal, &facets));
            let mut slow = vec![0.0; facets.len()];
            h.gather(&ids, &mut slow);
            assert_eq!(fast, slow);
        }
    }

    #[test]
    fn odd_or_zero_resolution_is_refused() {
        assert!(Hemicube::new(0).is_err());
        assert!(Hemicube::new(7).is_err());
        assert!(Hemicube::new(1_000_000).is_err());
    }
}
