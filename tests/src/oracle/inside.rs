//! Inside/outside oracle for a closed triangle mesh, by z-column parity (thesis §3.8: leaks).
//!
//! For every column `(x, y)` of an `n × n` grid the oracle collects the exact heights at which
//! the vertical line through the column centre `(q·x + q/2, q·y + q/2)` (lattice units) crosses
//! the mesh, and answers `inside(x, y, z)` by the parity of the crossings strictly below the
//! voxel centre `q·z + q/2`:
//! * `Some(true)` — odd number of crossings below: the centre is strictly inside;
//! * `Some(false)` — even: strictly outside;
//! * `None` — some counted crossing lies exactly at the centre: the centre is on the surface.
//!
//! # Exact definition (what "crosses" means)
//! * A triangle whose xy-projection has zero area (vertical or degenerate) is skipped.
//! * Each other triangle is taken counter-clockwise in xy. The column point `p` is in its
//!   projection iff every edge function `w = (bx − ax)(py − ay) − (by − ay)(px − ax)` is
//!   `> 0`, or `= 0` on an edge that *owns* its points: `dy > 0`, or `dy = 0` and `dx < 0`
//!   (a top-left rule). This is exactly "the point displaced by (−ε, −ε²)·(1, 1) lies in the
//!   open projection" for an infinitesimal ε, so for a watertight mesh a column through a
//!   shared edge or vertex counts each sheet of surface exactly once, and a column lying in a
//!   vertical face behaves as if displaced off it.
//! * The crossing height is the exact rational `z = az − (Nx(px − ax) + Ny(py − ay)) / Nz`,
//!   `N = (b − a) × (c − a)`, kept as `(num, den)`, `den > 0`, never rounded.
//!
//! So the oracle answers for the point displaced by `(−ε, −ε², 0)`, except that it returns
//! `None` when that displaced column meets the surface exactly at the (undisplaced) centre
//! height. A centre lying on a vertical face is therefore classified, not `None`.
//!
//! Columns in `0..n` are precomputed (each triangle rasterises its xy bounding box, O(area)),
//! in compressed form; other columns are computed on demand from all triangles.
//!
//! Exact for lattice coordinates of magnitude up to 2^20.

use crate::oracle::brute::{ceil_div, floor_div};

/// An exact rational `num / den` with `den > 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rat {
    /// Numerator.
    pub num: i128,
    /// Denominator, always positive.
    pub den: i128,
}

impl Rat {
    /// Exact comparison of two rationals.
    pub fn cmp_exact(&self, other: &Rat) -> std::cmp::Ordering {
        (self.num * other.den).cmp(&(other.num * self.den))
    }
    /// Exact comparison with an integer.
    pub fn cmp_int(&self, k: i128) -> std::cmp::Ordering {
        self.num.cmp(&(k * self.den))
    }
}

/// A triangle prepared for column tests: counter-clockwise in xy, with its plane.
#[derive(Clone, Copy, Debug)]
struct Tri {
    a: [i128; 3],
    b: [i128; 3],
    c: [i128; 3],
    /// Normal of the CCW-ordered triangle; `nz > 0`.
    n: [i128; 3],
}

fn owns(dx: i128, dy: i128) -> bool {
    dy > 0 || (dy == 0 && dx < 0)
}

fn edge_ok(a: [i128; 3], b: [i128; 3], px: i128, py: i128) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let w = dx * (py - a[1]) - dy * (px - a[0]);
    w > 0 || (w == 0 && owns(dx, dy))
}

impl Tri {
    fn new(t: &[[i64; 3]; 3]) -> Option<Tri> {
        let w = |p: [i64; 3]| p.map(|c| c as i128);
        let (a, mut b, mut c) = (w(t[0]), w(t[1]), w(t[2]));
        let area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area2 == 0 {
            return None;
        }
        if area2 < 0 {
            std::mem::swap(&mut b, &mut c);
        }
        let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
        let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        debug_assert!(n[2] > 0);
        Some(Tri { a, b, c, n })
    }

    /// The crossing height at column point `(px, py)` if the column crosses this triangle.
    fn crossing(&self, px: i128, py: i128) -> Option<Rat> {
        if !(edge_ok(self.a, self.b, px, py) && edge_ok(self.b, self.c, px, py) && edge_ok(self.c, self.a, px, py)) {
            return None;
        }
        let n = self.n;
        let num = self.a[2] * n[2] - n[0] * (px - self.a[0]) - n[1] * (py - self.a[1]);
        Some(Rat { num, den: n[2] })
    }

    fn xy_bbox(&self) -> (i128, i128, i128, i128) {
        let xs = [self.a[0], self.b[0], self.c[0]];
        let ys = [self.a[1], self.b[1], self.c[1]];
        (*xs.iter().min().unwrap(), *xs.iter().max().unwrap(), *ys.iter().min().unwrap(), *ys.iter().max().unwrap())
    }
}

/// Column-parity inside oracle of a closed triangle mesh (see the module docs).
#[derive(Clone, Debug)]
pub struct InsideOracle {
    q: i128,
    n: i64,
    tris: Vec<Tri>,
    /// Compressed columns: crossings of column `x + n·y` are `z[start[c]..start[c + 1]]`, sorted.
    start: Vec<usize>,
    z: Vec<Rat>,
}

impl InsideOracle {
    /// Builds the oracle for `triangles` (lattice vertices) on an `n × n` column grid with
    /// lattice resolution `q` (positive, even). Degenerate and vertical triangles are skipped.
    pub fn new(triangles: &[[[i64; 3]; 3]], q: i64, n: i64) -> InsideOracle {
        let q = q as i128;
        let n = n.max(0);
        let nn = n as usize;
        let tris: Vec<Tri> = triangles.iter().filter_map(Tri::new).collect();
        let cols = nn * nn;
        let mut hits: Vec<(usize, Rat)> = Vec::new();
        for t in &tris {
            let (x0, x1, y0, y1) = t.xy_bbox();
            // Columns whose centre q·i + q/2 lies in [lo, hi].
            let to_idx =
                |lo: i128, hi: i128| (ceil_div(lo - q / 2, q).max(0), floor_div(hi - q / 2, q).min(n as i128 - 1));
            let (ix0, ix1) = to_idx(x0, x1);
            let (iy0, iy1) = to_idx(y0, y1);
            for iy in iy0..=iy1 {
                let py = q * iy + q / 2;
                for ix in ix0..=ix1 {
                    let px = q * ix + q / 2;
                    if let Some(r) = t.crossing(px, py) {
                        hits.push((ix as usize + nn * iy as usize, r));
                    }
                }
            }
        }
        let mut start = vec![0usize; cols + 1];
        for (c, _) in &hits {
            start[*c + 1] += 1;
        }
        for i in 0..cols {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut z = vec![Rat { num: 0, den: 1 }; hits.len()];
        for (c, r) in hits {
            z[fill[c]] = r;
            fill[c] += 1;
        }
        for c in 0..cols {
            z[start[c]..start[c + 1]].sort_unstable_by(|a, b| a.cmp_exact(b));
        }
        InsideOracle { q, n, tris, start, z }
    }

    /// Grid side `n`.
    pub fn n(&self) -> i64 {
        self.n
    }

    /// Number of triangles kept (non-vertical, non-degenerate).
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// The sorted exact crossing heights (lattice units) of column `(x, y)`.
    pub fn crossings(&self, x: i64, y: i64) -> Vec<Rat> {
        if (0..self.n).contains(&x) && (0..self.n).contains(&y) {
            let c = (x + self.n * y) as usize;
            self.z[self.start[c]..self.start[c + 1]].to_vec()
        } else {
            let (px, py) = (self.q * x as i128 + self.q / 2, self.q * y as i128 + self.q / 2);
            let mut v: Vec<Rat> = self.tris.iter().filter_map(|t| t.crossing(px, py)).collect();
            v.sort_unstable_by(|a, b| a.cmp_exact(b));
            v
        }
    }

    fn parity(zs: &[Rat], zc: i128) -> Option<bool> {
        let mut below = 0usize;
        for r in zs {
            match r.cmp_int(zc) {
                std::cmp::Ordering::Less => below += 1,
                std::cmp::Ordering::Equal => return None,
                std::cmp::Ordering::Greater => break,
            }
        }
        Some(below % 2 == 1)
    }

    /// Whether the centre of voxel `(x, y, z)` is strictly inside (`Some(true)`), strictly
    /// outside (`Some(false)`) or on the surface (`None`); see the module docs.
    pub fn inside(&self, x: i64, y: i64, z: i64) -> Option<bool> {
        let zc = self.q * z as i128 + self.q / 2;
        if (0..self.n).contains(&x) && (0..self.n).contains(&y) {
            let c = (x + self.n * y) as usize;
            Self::parity(&self.z[self.start[c]..self.start[c + 1]], zc)
        } else {
            Self::parity(&self.crossings(x, y), zc)
        }
    }

    /// Columns of the grid with an odd number of crossings. Empty for a watertight closed mesh
    /// (the check that the mesh, and this oracle's tie-break, are consistent).
    pub fn odd_columns(&self) -> Vec<(i64, i64)> {
        let n = self.n;
        let mut out = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let c = (x + n * y) as usize;
                if (self.start[c + 1] - self.start[c]) % 2 == 1 {
                    out.push((x, y));
                }
            }
        }
        out
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::oracle::brute::tests::Rng;

    const Q: i64 = 16;

    /// The 12 triangles of the box `[lo, hi]` (lattice), outward-oriented; `flip` alternates
    /// the face diagonals.
    pub(crate) fn box_mesh(lo: [i64; 3], hi: [i64; 3], flip: bool) -> Vec<[[i64; 3]; 3]> {
        let v = |i: usize| -> [i64; 3] {
            [
                if i & 1 != 0 { hi[0] } else { lo[0] },
                if i & 2 != 0 { hi[1] } else { lo[1] },
                if i & 4 != 0 { hi[2] } else { lo[2] },
            ]
        };
        // Faces as CCW (seen from outside) quads of corner indices.
        let quads = [
            [0, 2, 3, 1], // z = lo
            [4, 5, 7, 6], // z = hi
            [0, 1, 5, 4], // y = lo
            [2, 6, 7, 3], // y = hi
            [0, 4, 6, 2], // x = lo
            [1, 3, 7, 5], // x = hi
        ];
        let mut out = Vec::new();
        for q in quads {
            if flip {
                out.push([v(q[0]), v(q[1]), v(q[2])]);
                out.push([v(q[0]), v(q[2]), v(q[3])]);
            } else {
                out.push([v(q[1]), v(q[2]), v(q[3])]);
                out.push([v(q[1]), v(q[3]), v(q[0])]);
            }
        }
        out
    }

    /// Analytic classification of a point against a convex polyhedron given by its triangles
    /// (outward or not: the orientation is fixed with the centroid). `Some(b)` when the point
    /// is strictly inside/outside, `None` when it is on the boundary.
    fn convex_classify(tris: &[[[i64; 3]; 3]], p: [i128; 3]) -> Option<bool> {
        let w = |p: [i64; 3]| p.map(|c| c as i128);
        let mut centroid3 = [0i128; 3]; // 3·#tris × centroid
        for t in tris {
            for v in t {
                for i in 0..3 {
                    centroid3[i] += v[i] as i128;
                }
            }
        }
        let m = 3 * tris.len() as i128;
        let mut on = false;
        for t in tris {
            let (a, b, c) = (w(t[0]), w(t[1]), w(t[2]));
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            if n == [0, 0, 0] {
                continue;
            }
            let f = |p: [i128; 3], s: i128| -> i128 { (0..3).map(|i| n[i] * (p[i] - s * a[i])).sum() };
            let fc = f(centroid3, m); // scaled by m
            let fp = f(p, 1);
            let fp = if fc > 0 { -fp } else { fp }; // now < 0 means the centroid's side
            if fp > 0 {
                return Some(false);
            }
            if fp == 0 {
                on = true;
            }
        }
        if on {
            None
        } else {
            Some(true)
        }
    }

    fn centre(v: [i64; 3]) -> [i128; 3] {
        v.map(|c| (Q * c + Q / 2) as i128)
    }

    /// The oracle must agree with the analytic answer wherever the latter is strict, and may
    /// answer `None` only on the boundary.
    fn check_against(oracle: &InsideOracle, analytic: &dyn Fn([i128; 3]) -> Option<bool>, n: i64) {
        let mut strict = 0;
        for x in -1..=n {
            for y in -1..=n {
                for z in -1..=n {
                    let a = analytic(centre([x, y, z]));
                    let o = oracle.inside(x, y, z);
                    if let Some(a) = a {
                        strict += 1;
                        assert_eq!(o, Some(a), "voxel {:?}", [x, y, z]);
                    }
                }
            }
        }
        assert!(strict > 0);
    }

    #[test]
    fn cube_matches_the_displaced_point_definition_exactly() {
        // Cube with corners at voxel centres 1 and 6: columns run through its edges, vertices
        // and face diagonals; centres lie on its faces.
        let (a, b) = ((Q + Q / 2) as i128, (6 * Q + Q / 2) as i128);
        let n = 8;
        for flip in [false, true] {
            for reverse in [false, true] {
                let mut mesh = box_mesh([a as i64; 3], [b as i64; 3], flip);
                if reverse {
                    for t in &mut mesh {
                        t.swap(1, 2);
                    }
                }
                let o = InsideOracle::new(&mesh, Q, n);
                assert_eq!(o.triangle_count(), 4, "vertical faces are skipped");
                assert!(o.odd_columns().is_empty());
                for x in -1..=n {
                    for y in -1..=n {
                        for z in -1..=n {
                            let [px, py, pz] = centre([x, y, z]);
                            // Displaced column (px − ε, py − ε²) is inside the open square iff:
                            let in_xy = a < px && px <= b && a < py && py <= b;
                            let want = if !in_xy {
                                Some(false)
                            } else if pz == a || pz == b {
                                None
                            } else {
                                Some(a < pz && pz < b)
                            };
                            assert_eq!(o.inside(x, y, z), want, "{:?}", [x, y, z]);
                        }
                    }
                }
                // Every column strictly inside the square (incl. the diagonal and the corners of
                // the triangle pairs) has exactly one crossing per horizontal face.
                for x in 2..=6 {
                    for y in 2..=6 {
                        assert_eq!(o.crossings(x, y).len(), 2, "column {x},{y}");
                    }
                }
            }
        }
    }

    #[test]
    fn cube_off_lattice_matches_analytic() {
        let mesh = box_mesh([21, 30, 7], [90, 77, 101], true);
        let o = InsideOracle::new(&mesh, Q, 8);
        assert!(o.odd_columns().is_empty());
        check_against(&o, &|p| convex_classify(&mesh, p), 8);
    }

    /// The 8 faces of the octahedron |x − c| + |y − c| + |z − c| ≤ r (lattice).
    fn octahedron(c: [i64; 3], r: i64) -> Vec<[[i64; 3]; 3]> {
        let mut out = Vec::new();
        for sx in [-1, 1] {
            for sy in [-1, 1] {
                for sz in [-1, 1] {
                    out.push([[c[0] + sx * r, c[1], c[2]], [c[0], c[1] + sy * r, c[2]], [c[0], c[1], c[2] + sz * r]]);
                }
            }
        }
        out
    }

    #[test]
    fn octahedron_columns_through_vertices_and_edges() {
        // Centre at the centre of voxel (4, 4, 4), radius 3 voxels: the column (4, 4) runs
        // through the top and bottom vertices (4 triangles each), and the columns x = 4 or
        // y = 4 run along projected edges.
        let c = [4 * Q + Q / 2; 3];
        let r = 3 * Q;
        let mesh = octahedron(c, r);
        let o = InsideOracle::new(&mesh, Q, 9);
        assert!(o.odd_columns().is_empty());
        let analytic = |p: [i128; 3]| -> Option<bool> {
            let d: i128 = (0..3).map(|i| (p[i] - c[i] as i128).abs()).sum();
            match d.cmp(&(r as i128)) {
                std::cmp::Ordering::Less => Some(true),
                std::cmp::Ordering::Equal => None,
                std::cmp::Ordering::Greater => Some(false),
            }
        };
        check_against(&o, &analytic, 9);
        // The vertex column: exactly two crossings, at the two apexes.
        let zs = o.crossings(4, 4);
        assert_eq!(zs.len(), 2);
        assert_eq!(zs[0].cmp_int((c[2] - r) as i128), std::cmp::Ordering::Equal);
        assert_eq!(zs[1].cmp_int((c[2] + r) as i128), std::cmp::Ordering::Equal);
        assert_eq!(o.inside(4, 4, 1), None);
        assert_eq!(o.inside(4, 4, 2), Some(true));
        assert_eq!(o.inside(4, 4, 7), None);
        assert_eq!(o.inside(4, 4, 8), Some(false));
    }

    #[test]
    fn random_tetrahedra_match_analytic() {
        let mut rng = Rng(0x7e7a_7e7a);
        for _ in 0..40 {
            // Vertices on the half-voxel sublattice: many columns through edges and vertices.
            let mut p = || [rng.range(0, 14) * (Q / 2), rng.range(0, 14) * (Q / 2), rng.range(0, 14) * (Q / 2)];
            let v = [p(), p(), p(), p()];
            // Skip flat tetrahedra (the analytic classifier needs a solid).
            let d = |i: usize| [0, 1, 2].map(|k| (v[i][k] - v[0][k]) as i128);
            let (a, b, c) = (d(1), d(2), d(3));
            let vol = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
            if vol == 0 {
                continue;
            }
            let mesh = vec![[v[0], v[1], v[2]], [v[0], v[3], v[1]], [v[1], v[3], v[2]], [v[2], v[3], v[0]]];
            let o = InsideOracle::new(&mesh, Q, 7);
            assert!(o.odd_columns().is_empty(), "{v:?}");
            check_against(&o, &|p| convex_classify(&mesh, p), 7);
        }
    }

    #[test]
    fn dented_pyramid_non_convex() {
        // Square base [16, 144]² at z = 8; apex (80, 80, 136); the base is pushed in to a
        // dent apex (80, 80, 72). Inside = inside the big pyramid and outside the dent pyramid.
        let base = [[16, 16, 8], [144, 16, 8], [144, 144, 8], [16, 144, 8]];
        let top = [80, 80, 136];
        let dent = [80, 80, 72];
        let mut mesh = Vec::new();
        let mut big = Vec::new();
        let mut small = Vec::new();
        for i in 0..4 {
            let (p, q) = (base[i], base[(i + 1) % 4]);
            mesh.push([p, q, top]);
            mesh.push([q, p, dent]);
            big.push([p, q, top]);
            small.push([q, p, dent]);
        }
        big.push([base[0], base[2], base[1]]);
        big.push([base[0], base[3], base[2]]);
        small.push([base[0], base[2], base[1]]);
        small.push([base[0], base[3], base[2]]);
        let o = InsideOracle::new(&mesh, Q, 10);
        assert!(o.odd_columns().is_empty());
        let analytic = |p: [i128; 3]| -> Option<bool> {
            match (convex_classify(&big, p)?, convex_classify(&small, p)) {
                (false, _) => Some(false),
                (true, Some(s)) => Some(!s),
                (true, None) => None,
            }
        };
        check_against(&o, &analytic, 10);
        // The apex column (4, 4) — centre (72, 72) — is inside only between dent and top.
        assert_eq!(o.inside(4, 4, 3), Some(false));
        assert_eq!(o.inside(4, 4, 5), Some(true));
    }

    #[test]
    fn degenerate_triangles_are_skipped() {
        let mesh = vec![
            [[0, 0, 0], [16, 16, 16], [32, 32, 32]], // collinear
            [[5, 5, 5], [5, 5, 5], [5, 5, 5]],       // a point
            [[0, 0, 0], [64, 0, 0], [0, 0, 64]],     // vertical
        ];
        let o = InsideOracle::new(&mesh, Q, 4);
        assert_eq!(o.triangle_count(), 0);
        assert_eq!(o.inside(1, 1, 1), Some(false));
        let empty = InsideOracle::new(&[], Q, 0);
        assert_eq!(empty.inside(0, 0, 0), Some(false));
    }

    /// A closed sphere-like mesh: a cube subdivided m×m per face, pushed onto a sphere of
    /// radius `r` (lattice) around `c`, vertices rounded to the lattice (shared, so watertight).
    pub(crate) fn sphere_mesh(c: [i64; 3], r: f64, m: usize) -> Vec<[[i64; 3]; 3]> {
        use std::collections::HashMap;
        let mut ids: HashMap<[i64; 3], [i64; 3]> = HashMap::new();
        let mut vert = |g: [i64; 3]| -> [i64; 3] {
            *ids.entry(g).or_insert_with(|| {
                let h = m as f64 / 2.0;
                let d = [g[0] as f64 - h, g[1] as f64 - h, g[2] as f64 - h];
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                [0, 1, 2].map(|i| c[i] + (d[i] / l * r).round() as i64)
            })
        };
        let m = m as i64;
        let mut out = Vec::new();
        // Each face: fixed axis `a` at 0 or m, the other two (b, c) run over the grid.
        for a in 0..3 {
            for side in [0, m] {
                let (b, cc) = ((a + 1) % 3, (a + 2) % 3);
                for i in 0..m {
                    for j in 0..m {
                        let g = |di: i64, dj: i64| {
                            let mut p = [0i64; 3];
                            p[a] = side;
                            p[b] = i + di;
                            p[cc] = j + dj;
                            p
                        };
                        let (p00, p10, p11, p01) = (g(0, 0), g(1, 0), g(1, 1), g(0, 1));
                        let (v00, v10, v11, v01) = (vert(p00), vert(p10), vert(p11), vert(p01));
                        if side == m {
                            out.push([v00, v10, v11]);
                            out.push([v00, v11, v01]);
                        } else {
                            out.push([v00, v11, v10]);
                            out.push([v00, v01, v11]);
                        }
                    }
                }
            }
        }
        out
    }

    #[test]
    fn sphere_n256_13k_triangles_is_fast_and_consistent() {
        let n = 256;
        let c = [128 * Q + Q / 2; 3];
        let r = 100.0 * Q as f64;
        let mesh = sphere_mesh(c, r, 33);
        assert_eq!(mesh.len(), 6 * 33 * 33 * 2); // 13 068
        let t0 = std::time::Instant::now();
        let o = InsideOracle::new(&mesh, Q, n);
        let build = t0.elapsed();
        assert!(o.odd_columns().is_empty(), "watertight mesh ⇒ even columns");
        // Away from the surface (±2 voxels) the answer is the sphere's.
        let margin = 2.0 * Q as f64;
        let mut checked = 0u64;
        for z in (0..n).step_by(7) {
            for y in 0..n {
                for x in 0..n {
                    let p = centre([x, y, z]);
                    let d = ((0..3).map(|i| ((p[i] - c[i] as i128) as f64).powi(2)).sum::<f64>()).sqrt();
                    if d < r - margin {
                        assert_eq!(o.inside(x, y, z), Some(true));
                        checked += 1;
                    } else if d > r + margin {
                        assert_eq!(o.inside(x, y, z), Some(false));
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 1_000_000);
        eprintln!("InsideOracle n=256, {} triangles: built in {build:?}", mesh.len());
        assert!(build.as_secs_f64() < 5.0);
    }
}
