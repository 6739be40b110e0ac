//! Brute-force facet voxelization oracle (thesis ch. 3, §3.5–§3.7).
//!
//! A voxel belongs to a facet iff its **centre** satisfies the plane's thickness band AND every
//! contour inequality. Nothing here is incremental or clever: every voxel of a box is tested
//! directly with exact `i128` arithmetic, so this module can judge any faster voxelizer.
//!
//! # Conventions (fixed)
//! * Lattice resolution `q` (even, 16 by default). Voxel `(x, y, z)` has its centre at the
//!   lattice point `(q·x + q/2, q·y + q/2, q·z + q/2)`; facet vertices are lattice points.
//! * Normal `N = (P1 − P0) × (P2 − P0)`. If that is zero the first pair `(i, j)`, `1 ≤ i < j`
//!   in lexicographic order with `(Pi − P0) × (Pj − P0) ≠ 0` is used (the "first non-collinear
//!   triple"; keeping `P0` loses nothing: if every such product is zero the polygon is
//!   collinear). A polygon with fewer than three vertices, or collinear, has **no voxels**.
//!   `N` is divided by the gcd of its components before use; every test below is homogeneous
//!   of degree 1 in `N`, so this changes no answer and only keeps numbers small.
//! * `E(M) = N·(M − P0)`, `K = max(|Nx|, |Ny|, |Nz|)`. Thickness bands, exact, closed:
//!   - [`Thickness::Naive`]:    `2|E| ≤ q·K` (σ = ½);
//!   - [`Thickness::Standard`]: `2|E| ≤ q·(|Nx| + |Ny| + |Nz|)`;
//!   - [`Thickness::Thesis`]:   some pair `(i, j)`, `i ≠ j`, has: if `N_i = N_j = 0` then
//!     `2|E| ≤ q·K`, else `2·mx·|E| ≤ q·K·(mx + mn)` with `mx`/`mn` the larger/smaller of
//!     `|N_i|, |N_j|` — i.e. `|E| ≤ q·K·σ`, `σ = max_ij ½(1 + min/max)` (thesis §3.8).
//!
//!   Note: the thesis band is **not** always thinner than the standard one: for `N = (10, 2, 1)`
//!   the pair (y, z) gives `Kσ = 7.5 > (10+2+1)/2 = 6.5` (see the unit tests).
//!   Note: the bands are closed, so when `E/q` hits a band edge exactly (e.g. an axis-aligned
//!   facet exactly half-way between two voxel centres) both neighbours belong.
//! * Contour: dominant axis `d = argmax |N_i|`, ties preferring z over y over x; `(u, v)` are
//!   the other two axes in increasing order. For each edge `Pi → Pj` (`j = i + 1 mod count`)
//!   `F(M) = (Uj − Ui)(Mv − Vi) − (Vj − Vi)(Mu − Ui)`; `s` = sign of the polygon's shoelace
//!   area in `(u, v)`.
//!   - [`Contour::Projected`]:    `s·F(M) ≥ 0` for every edge;
//!   - [`Contour::Conservative`]: `s·F(M) + (q/2)(|Uj − Ui| + |Vj − Vi|) ≥ 0` for every edge
//!     (each edge pushed out by the support of the voxel's half-extent square), AND the centre's
//!     projection lies in the polygon's vertex box pushed out by `q/2`:
//!     `min Ui − q/2 ≤ Mu ≤ max Ui + q/2`, same for v. This is conservative rasterisation
//!     (edges ∩ box): the box trims the long spikes that pushed-out edges alone grow at acute
//!     corners.
//!
//!   A polygon whose projected area is zero has no voxels.
//!
//! # Limits
//! Exact for lattice coordinates (vertices and voxel centres) of magnitude up to 2^20
//! (e.g. n = 65 536 at q = 16); beyond that an `i128` product may overflow (the test profile
//! keeps overflow checks on, so it would panic rather than lie). The polygon is assumed planar
//! and convex (thesis ch. 3); for a non-planar polygon the plane through `P0` with the chosen normal
//! is used as is.

/// Plane thickness rule (see the module docs for the exact inequalities).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Thickness {
    /// σ = ½: `2|E| ≤ q·K`; stops 6-connected lines only.
    Naive,
    /// The thesis's experimental σ = max over axis pairs of ½(1 + min/max).
    Thesis,
    /// Standard arithmetic plane: `2|E| ≤ q·(|Nx| + |Ny| + |Nz|)`; no 26-tunnels.
    Standard,
}

impl Thickness {
    /// All three modes, thinnest first (the thesis mode is not always thinner than standard).
    pub const ALL: [Thickness; 3] = [Thickness::Naive, Thickness::Thesis, Thickness::Standard];
}

/// Contour rule (see the module docs for the exact inequalities).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Contour {
    /// Voxel centre inside the closed projected polygon.
    Projected,
    /// Each edge pushed outwards by the voxel's half-extent (Minkowski support of the square).
    Conservative,
}

impl Contour {
    /// Both modes.
    pub const ALL: [Contour; 2] = [Contour::Projected, Contour::Conservative];
}

fn gcd(mut a: i128, mut b: i128) -> i128 {
    a = a.abs();
    b = b.abs();
    while b != 0 {
        let t = a % b;
        a = b;
        b = t;
    }
    a
}

/// Floor of `a / b` for `b > 0`.
pub(crate) fn floor_div(a: i128, b: i128) -> i128 {
    debug_assert!(b > 0);
    a.div_euclid(b)
}

/// Ceiling of `a / b` for `b > 0`.
pub(crate) fn ceil_div(a: i128, b: i128) -> i128 {
    debug_assert!(b > 0);
    -((-a).div_euclid(b))
}

fn sub3(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross3(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn widen(p: [i64; 3]) -> [i128; 3] {
    [p[0] as i128, p[1] as i128, p[2] as i128]
}

/// The facet normal by the module's rule (first non-collinear triple with `P0`), **not**
/// reduced by its gcd. `None` for fewer than three vertices or a collinear polygon.
pub fn plane_normal(poly: &[[i64; 3]]) -> Option<[i128; 3]> {
    if poly.len() < 3 {
        return None;
    }
    let p0 = widen(poly[0]);
    for i in 1..poly.len() {
        let a = sub3(widen(poly[i]), p0);
        for pj in &poly[i + 1..] {
            let n = cross3(a, sub3(widen(*pj), p0));
            if n != [0, 0, 0] {
                return Some(n);
            }
        }
    }
    None
}

/// Dominant axis of a non-zero normal: `argmax |N_i|`, ties preferring z, then y, then x.
/// Returns `(d, u, v)` with `u < v` the two projection axes.
pub fn dominant_axis(n: [i128; 3]) -> (usize, usize, usize) {
    let a = [n[0].abs(), n[1].abs(), n[2].abs()];
    if a[2] >= a[1] && a[2] >= a[0] {
        (2, 0, 1)
    } else if a[1] >= a[0] {
        (1, 0, 2)
    } else {
        (0, 1, 2)
    }
}

/// One contour edge as a half-plane `a·Mu + b·Mv + c ≥ 0` (already multiplied by `s`,
/// conservative slack already added).
#[derive(Clone, Copy, Debug)]
struct HalfPlane {
    a: i128,
    b: i128,
    c: i128,
}

/// A facet prepared for membership tests: plane, band and contour half-planes.
///
/// Built by [`Facet::new`]; `None` there means the facet has no voxels at all (degenerate).
#[derive(Clone, Debug)]
pub struct Facet {
    q: i128,
    n: [i128; 3],
    p0: [i128; 3],
    th: Thickness,
    axes: (usize, usize, usize),
    edges: Vec<HalfPlane>,
}

impl Facet {
    /// Prepares `poly` (lattice vertices, in order) for lattice resolution `q` (even, > 0).
    /// `None` if the polygon is degenerate (fewer than 3 vertices, collinear, or zero area in
    /// its dominant projection), or if `q` is not a positive even number.
    pub fn new(poly: &[[i64; 3]], q: i64, th: Thickness, ct: Contour) -> Option<Facet> {
        if q <= 0 || q % 2 != 0 {
            return None;
        }
        let q = q as i128;
        let raw = plane_normal(poly)?;
        let g = gcd(gcd(raw[0], raw[1]), raw[2]);
        let n = [raw[0] / g, raw[1] / g, raw[2] / g];
        let axes = dominant_axis(n);
        let (_, u, v) = axes;
        let pts: Vec<[i128; 3]> = poly.iter().map(|p| widen(*p)).collect();
        let m = pts.len();
        // Shoelace (twice the signed area) in (u, v).
        let mut area2: i128 = 0;
        for i in 0..m {
            let (pi, pj) = (pts[i], pts[(i + 1) % m]);
            area2 += pi[u] * pj[v] - pj[u] * pi[v];
        }
        let s = area2.signum();
        if s == 0 {
            return None;
        }
        let mut edges = Vec::with_capacity(m);
        for i in 0..m {
            let (pi, pj) = (pts[i], pts[(i + 1) % m]);
            let du = pj[u] - pi[u];
            let dv = pj[v] - pi[v];
            // s·F(M) = s·(du·(Mv − Vi) − dv·(Mu − Ui)) = a·Mu + b·Mv + c.
            let slack = match ct {
                Contour::Projected => 0,
                Contour::Conservative => (q / 2) * (du.abs() + dv.abs()),
            };
            edges.push(HalfPlane { a: -s * dv, b: s * du, c: s * (dv * pi[u] - du * pi[v]) + slack });
        }
        if ct == Contour::Conservative {
            let h = q / 2;
            let (umin, umax) = (pts.iter().map(|p| p[u]).min()?, pts.iter().map(|p| p[u]).max()?);
            let (vmin, vmax) = (pts.iter().map(|p| p[v]).min()?, pts.iter().map(|p| p[v]).max()?);
            edges.push(HalfPlane { a: 1, b: 0, c: h - umin });
            edges.push(HalfPlane { a: -1, b: 0, c: umax + h });
            edges.push(HalfPlane { a: 0, b: 1, c: h - vmin });
            edges.push(HalfPlane { a: 0, b: -1, c: vmax + h });
        }
        Some(Facet { q, n, p0: pts[0], th, axes, edges })
    }

    /// The (gcd-reduced) normal used by every test.
    pub fn normal(&self) -> [i128; 3] {
        self.n
    }

    /// `(d, u, v)`: dominant axis and the two projection axes.
    pub fn axes(&self) -> (usize, usize, usize) {
        self.axes
    }

    /// Lattice coordinates of the centre of voxel `vox`.
    pub fn centre(&self, vox: [i64; 3]) -> [i128; 3] {
        let q = self.q;
        [q * vox[0] as i128 + q / 2, q * vox[1] as i128 + q / 2, q * vox[2] as i128 + q / 2]
    }

    /// `E(M) = N·(M − P0)` at the centre of `vox` (with the gcd-reduced normal).
    pub fn plane_value(&self, vox: [i64; 3]) -> i128 {
        let d = sub3(self.centre(vox), self.p0);
        self.n[0] * d[0] + self.n[1] * d[1] + self.n[2] * d[2]
    }

    /// The band's half-width as an exact rational `(num, den)`, `den > 0`: the centre is in the
    /// band iff `|E|·den ≤ num`.
    pub fn band(&self) -> (i128, i128) {
        band_of(self.n, self.q, self.th)
    }

    /// Whether `|E|` at the centre of `vox` is inside the thickness band.
    pub fn in_band(&self, vox: [i64; 3]) -> bool {
        let e = self.plane_value(vox).abs();
        in_band_value(self.n, self.q, self.th, e)
    }

    /// Whether the centre of `vox` satisfies every contour inequality.
    pub fn in_contour(&self, vox: [i64; 3]) -> bool {
        let c = self.centre(vox);
        let (_, u, v) = self.axes;
        self.edges.iter().all(|h| h.a * c[u] + h.b * c[v] + h.c >= 0)
    }

    /// Whether voxel `vox` belongs to the facet (band AND contour).
    pub fn contains(&self, vox: [i64; 3]) -> bool {
        self.in_band(vox) && self.in_contour(vox)
    }

    /// A voxel box `(lo, hi)` (inclusive) guaranteed to hold every voxel of the facet, or
    /// `None` when the facet provably has no voxel. Computed exactly from the vertices of the
    /// contour region (intersections of the edge lines, pushed out in conservative mode) and the
    /// band's extent along the dominant axis. Note that in conservative mode this region can
    /// reach far beyond the facet's own bounding box near acute vertices.
    pub fn reach_box(&self) -> Option<([i64; 3], [i64; 3])> {
        let (d, u, v) = self.axes;
        let hs: Vec<HalfPlane> = self.edges.iter().copied().filter(|h| h.a != 0 || h.b != 0).collect();
        // Vertices of the region {a·u + b·v + c ≥ 0 for all h}: feasible pairwise intersections.
        let (mut umin, mut umax, mut vmin, mut vmax) = (i128::MAX, i128::MIN, i128::MAX, i128::MIN);
        for i in 0..hs.len() {
            for j in i + 1..hs.len() {
                let (h1, h2) = (hs[i], hs[j]);
                let mut det = h1.a * h2.b - h2.a * h1.b;
                if det == 0 {
                    continue;
                }
                let mut nu = h1.b * h2.c - h2.b * h1.c;
                let mut nv = h2.a * h1.c - h1.a * h2.c;
                if det < 0 {
                    det = -det;
                    nu = -nu;
                    nv = -nv;
                }
                if hs.iter().all(|h| h.a * nu + h.b * nv + h.c * det >= 0) {
                    umin = umin.min(floor_div(nu, det));
                    umax = umax.max(ceil_div(nu, det));
                    vmin = vmin.min(floor_div(nv, det));
                    vmax = vmax.max(ceil_div(nv, det));
                }
            }
        }
        if umin > umax || vmin > vmax {
            return None;
        }
        // Along d: N_d·M_d = N·P0 − N_u·M_u − N_v·M_v + E, |E| ≤ band.
        let n = self.n;
        let np0 = n[0] * self.p0[0] + n[1] * self.p0[1] + n[2] * self.p0[2];
        let mut bmin = i128::MAX;
        let mut bmax = i128::MIN;
        for mu in [umin, umax] {
            for mv in [vmin, vmax] {
                let b = np0 - n[u] * mu - n[v] * mv;
                bmin = bmin.min(b);
                bmax = bmax.max(b);
            }
        }
        let (bn, bd) = self.band();
        let emax = ceil_div(bn, bd);
        let nd = n[d];
        let (dlo, dhi) = if nd > 0 {
            (floor_div(bmin - emax, nd), ceil_div(bmax + emax, nd))
        } else {
            (floor_div(-(bmax + emax), -nd), ceil_div(-(bmin - emax), -nd))
        };
        let q = self.q;
        let to_vox = |lo: i128, hi: i128| -> (i128, i128) { (ceil_div(lo - q / 2, q), floor_div(hi - q / 2, q)) };
        let mut lo = [0i64; 3];
        let mut hi = [0i64; 3];
        for (axis, (l, h)) in [(u, (umin, umax)), (v, (vmin, vmax)), (d, (dlo, dhi))] {
            let (a, b) = to_vox(l, h);
            if a > b {
                return None;
            }
            lo[axis] = clamp64(a);
            hi[axis] = clamp64(b);
        }
        Some((lo, hi))
    }
}

fn clamp64(x: i128) -> i64 {
    x.clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

/// Band half-width `(num, den)` for normal `n`: centre in band iff `|E|·den ≤ num`.
fn band_of(n: [i128; 3], q: i128, th: Thickness) -> (i128, i128) {
    let a = [n[0].abs(), n[1].abs(), n[2].abs()];
    let k = a[0].max(a[1]).max(a[2]);
    match th {
        Thickness::Naive => (q * k, 2),
        Thickness::Standard => (q * (a[0] + a[1] + a[2]), 2),
        Thickness::Thesis => {
            // The largest of the three pair bands (as a rational).
            let mut best = (q * k, 2);
            for (i, j) in [(0, 1), (0, 2), (1, 2)] {
                let (mx, mn) = (a[i].max(a[j]), a[i].min(a[j]));
                let cand = if mx == 0 { (q * k, 2) } else { (q * k * (mx + mn), 2 * mx) };
                if cand.0 * best.1 > best.0 * cand.1 {
                    best = cand;
                }
            }
            best
        }
    }
}

/// The band test exactly as the module docs state it (kept literal on purpose).
fn in_band_value(n: [i128; 3], q: i128, th: Thickness, e_abs: i128) -> bool {
    let a = [n[0].abs(), n[1].abs(), n[2].abs()];
    let k = a[0].max(a[1]).max(a[2]);
    match th {
        Thickness::Naive => 2 * e_abs <= q * k,
        Thickness::Standard => 2 * e_abs <= q * (a[0] + a[1] + a[2]),
        Thickness::Thesis => [(0, 1), (0, 2), (1, 2)].iter().any(|&(i, j)| {
            if a[i] == 0 && a[j] == 0 {
                2 * e_abs <= q * k
            } else {
                let (mx, mn) = (a[i].max(a[j]), a[i].min(a[j]));
                2 * mx * e_abs <= q * k * (mx + mn)
            }
        }),
    }
}

/// Every voxel index in the inclusive box `[lo, hi]` that belongs to the facet `poly`, by
/// brute force over the whole box, sorted lexicographically by `[x, y, z]`.
/// A degenerate facet (see [`Facet::new`]) yields an empty vector.
pub fn facet_voxels(
    poly: &[[i64; 3]],
    q: i64,
    th: Thickness,
    ct: Contour,
    lo: [i64; 3],
    hi: [i64; 3],
) -> Vec<[i64; 3]> {
    let Some(f) = Facet::new(poly, q, th, ct) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                if f.contains([x, y, z]) {
                    out.push([x, y, z]);
                }
            }
        }
    }
    out.sort_unstable();
    out
}

/// Every voxel of the facet, anywhere in space: [`facet_voxels`] over [`Facet::reach_box`].
pub fn facet_voxels_all(poly: &[[i64; 3]], q: i64, th: Thickness, ct: Contour) -> Vec<[i64; 3]> {
    match Facet::new(poly, q, th, ct).and_then(|f| f.reach_box()) {
        Some((lo, hi)) => facet_voxels(poly, q, th, ct, lo, hi),
        None => Vec::new(),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::collections::{BTreeMap, BTreeSet};

    const Q: i64 = 16;

    /// Tiny deterministic PRNG (xorshift64*), so the tests need no dependency.
    pub(crate) struct Rng(pub u64);
    impl Rng {
        pub(crate) fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }
        /// Uniform in `lo..=hi`.
        pub(crate) fn range(&mut self, lo: i64, hi: i64) -> i64 {
            lo + (self.next() % ((hi - lo + 1) as u64)) as i64
        }
    }

    fn add(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
        [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
    }
    fn scale(a: [i64; 3], k: i64) -> [i64; 3] {
        [a[0] * k, a[1] * k, a[2] * k]
    }

    /// A big triangle in the plane through `p0` spanned by `v1`, `v2` (lattice vectors), with
    /// centroid `p0`: `p0 − s(v1+v2)`, `p0 + s(2v1 − v2)`, `p0 + s(2v2 − v1)`.
    fn big_triangle(p0: [i64; 3], v1: [i64; 3], v2: [i64; 3], s: i64) -> Vec<[i64; 3]> {
        vec![
            add(p0, scale(add(v1, v2), -s)),
            add(p0, scale(add(scale(v1, 2), scale(v2, -1)), s)),
            add(p0, scale(add(scale(v2, 2), scale(v1, -1)), s)),
        ]
    }

    fn cube(lo: i64, hi: i64) -> ([i64; 3], [i64; 3]) {
        ([lo; 3], [hi; 3])
    }

    #[test]
    fn axis_aligned_square_gives_one_layer() {
        // Square [16, 80]² at lattice z = 91 (voxel 5 has centre 88: |88 − 91| = 3 ≤ 8).
        let sq = [[16, 16, 91], [80, 16, 91], [80, 80, 91], [16, 80, 91]];
        let (lo, hi) = cube(-2, 9);
        for th in Thickness::ALL {
            let proj = facet_voxels(&sq, Q, th, Contour::Projected, lo, hi);
            // Centres 24, 40, 56, 72 lie in [16, 80]: x, y ∈ 1..=4, z = 5 only.
            let want: Vec<[i64; 3]> = (1..=4).flat_map(|x| (1..=4).map(move |y| [x, y, 5])).collect();
            assert_eq!(proj, want, "{th:?}");
            // Conservative: edges pushed out by q/2 → centres in [8, 88]: x, y ∈ 0..=5.
            let cons = facet_voxels(&sq, Q, th, Contour::Conservative, lo, hi);
            let want: Vec<[i64; 3]> = (0..=5).flat_map(|x| (0..=5).map(move |y| [x, y, 5])).collect();
            assert_eq!(cons, want, "{th:?}");
        }
        // Exactly half-way between centres 88 and 104: the closed band keeps both layers.
        let mid = [[16, 16, 96], [80, 16, 96], [80, 80, 96], [16, 80, 96]];
        let v = facet_voxels(&mid, Q, Thickness::Naive, Contour::Projected, lo, hi);
        assert_eq!(v.len(), 32);
        assert!(v.iter().all(|p| p[2] == 5 || p[2] == 6));
    }

    #[test]
    fn plane_at_45_degrees() {
        // Plane x = z through lattice (8, 8, 8) = centre of voxel 0: E = ±16(x − z).
        let p0 = [8, 8, 8];
        let tri = big_triangle(p0, [1, 0, 1], [0, 1, 0], 16 * 40);
        let f = Facet::new(&tri, Q, Thickness::Naive, Contour::Projected).unwrap();
        assert_eq!(f.axes(), (2, 0, 1), "tie |Nx| = |Nz| prefers z");
        let (lo, hi) = cube(-5, 5);
        let per_column = |th| {
            let mut cols: BTreeMap<(i64, i64), Vec<i64>> = BTreeMap::new();
            for p in facet_voxels(&tri, Q, th, Contour::Projected, lo, hi) {
                cols.entry((p[0], p[1])).or_default().push(p[2]);
            }
            assert_eq!(cols.len(), 121, "every column of the box is hit");
            cols
        };
        // Naive: |x − z| ≤ ½ → z = x exactly.
        for ((x, _), zs) in per_column(Thickness::Naive) {
            assert_eq!(zs, vec![x]);
        }
        // Standard (|E| ≤ 16) and thesis (σ = 1 for the pair (x, z)): |x − z| ≤ 1.
        for th in [Thickness::Standard, Thickness::Thesis] {
            for ((x, _), zs) in per_column(th) {
                let want: Vec<i64> = (x - 1..=x + 1).filter(|z| (-5..=5).contains(z)).collect();
                assert_eq!(zs, want, "{th:?}");
            }
        }
    }

    /// Distinct values of `E/q` (as `2E/q`, to stay integral) over a facet's voxels in a box.
    fn levels(tri: &[[i64; 3]], th: Thickness, n: [i64; 3], p0: [i64; 3]) -> BTreeSet<i64> {
        let (lo, hi) = cube(-6, 6);
        facet_voxels(tri, Q, th, Contour::Projected, lo, hi)
            .into_iter()
            .map(|p| {
                let m = [Q * p[0] + Q / 2, Q * p[1] + Q / 2, Q * p[2] + Q / 2];
                let e = n[0] * (m[0] - p0[0]) + n[1] * (m[1] - p0[1]) + n[2] * (m[2] - p0[2]);
                assert_eq!((2 * e) % Q, 0);
                2 * e / Q
            })
            .collect()
    }

    #[test]
    fn thesis_sigma_for_normal_321_keeps_five_integer_levels() {
        // N = (3, 2, 1): σ = max(5/6, 2/3, 3/4) = 5/6, Kσ = 2.5; standard half-width 3;
        // naive 1.5. Spanning vectors (1, 0, −3) × (0, 1, −2) = (3, 2, 1).
        let n = [3, 2, 1];
        let (v1, v2) = ([1, 0, -3], [0, 1, -2]);
        // Integer offset: P0 at a voxel centre, so E/q = 3x + 2y + z ∈ ℤ.
        let p0 = [8, 8, 8];
        let tri = big_triangle(p0, v1, v2, 16 * 60);
        let lv = |th| levels(&tri, th, n, p0);
        // (values are 2E/q)
        assert_eq!(lv(Thickness::Naive), [-2, 0, 2].into());
        assert_eq!(lv(Thickness::Thesis), [-4, -2, 0, 2, 4].into(), "5 levels");
        // The closed symmetric standard band keeps 7 (the half-open one of the literature, 6).
        assert_eq!(lv(Thickness::Standard), [-6, -4, -2, 0, 2, 4, 6].into());
        // Half-integer offset: P0 = centre + (8, 0, 0) lattice → E/q ∈ ℤ + ½.
        let p0 = [16, 8, 8];
        let tri = big_triangle(p0, v1, v2, 16 * 60);
        let lv = |th| levels(&tri, th, n, p0);
        assert_eq!(lv(Thickness::Naive), [-3, -1, 1, 3].into());
        assert_eq!(lv(Thickness::Thesis), [-5, -3, -1, 1, 3, 5].into(), "6 levels");
        assert_eq!(lv(Thickness::Standard), [-5, -3, -1, 1, 3, 5].into());
    }

    #[test]
    fn thesis_band_can_exceed_standard_band() {
        // N = (10, 2, 1): pair (y, z) gives σ = 3/4, Kσ = 7.5 > (10 + 2 + 1)/2 = 6.5.
        let f = |th| {
            let tri = [[0, 0, 0], [1, -5, 0], [0, 1, -2]];
            let f = Facet::new(&tri, Q, th, Contour::Projected).unwrap();
            assert_eq!(f.normal(), [10, 2, 1]);
            f.band()
        };
        assert_eq!(f(Thickness::Thesis), (16 * 10 * 3, 4)); // 7.5·q
        assert_eq!(f(Thickness::Standard), (16 * 13, 2)); // 6.5·q
        assert_eq!(f(Thickness::Naive), (16 * 10, 2)); // 5·q
    }

    #[test]
    fn degenerate_facets_have_no_voxels() {
        let (lo, hi) = cube(-3, 3);
        let cases: [&[[i64; 3]]; 5] = [
            &[],
            &[[0, 0, 0], [16, 0, 0]],
            &[[0, 0, 0], [16, 16, 16], [32, 32, 32]],         // collinear
            &[[5, 5, 5], [5, 5, 5], [5, 5, 5]],               // a point
            &[[0, 0, 0], [16, 0, 0], [32, 0, 0], [48, 0, 0]], // collinear quad
        ];
        for poly in cases {
            for th in Thickness::ALL {
                for ct in Contour::ALL {
                    assert!(facet_voxels(poly, Q, th, ct, lo, hi).is_empty());
                    assert!(facet_voxels_all(poly, Q, th, ct).is_empty());
                }
            }
        }
        // Odd or non-positive q is rejected, not a panic.
        let tri = [[0, 0, 0], [32, 0, 0], [0, 32, 0]];
        assert!(facet_voxels(&tri, 15, Thickness::Naive, Contour::Projected, lo, hi).is_empty());
        assert!(facet_voxels(&tri, 0, Thickness::Naive, Contour::Projected, lo, hi).is_empty());
    }

    #[test]
    fn repeated_first_vertices_use_the_next_triple() {
        let tri = [[3, 5, 7], [70, 9, 20], [10, 60, 40]];
        let dup = [[3, 5, 7], [3, 5, 7], [70, 9, 20], [10, 60, 40]];
        let (lo, hi) = cube(-2, 6);
        for th in Thickness::ALL {
            for ct in Contour::ALL {
                let a = facet_voxels(&tri, Q, th, ct, lo, hi);
                assert!(!a.is_empty());
                assert_eq!(a, facet_voxels(&dup, Q, th, ct, lo, hi));
            }
        }
    }

    fn random_triangle(rng: &mut Rng, span: i64) -> [[i64; 3]; 3] {
        let mut p = || [rng.range(0, span), rng.range(0, span), rng.range(0, span)];
        [p(), p(), p()]
    }

    #[test]
    fn vertex_order_does_not_matter() {
        let mut rng = Rng(0x1234_5678_9abc_def1);
        for _ in 0..60 {
            let t = random_triangle(&mut rng, 8 * Q);
            let (lo, hi) = cube(-3, 10);
            for th in Thickness::ALL {
                for ct in Contour::ALL {
                    let a = facet_voxels(&t, Q, th, ct, lo, hi);
                    assert_eq!(a, facet_voxels(&[t[2], t[1], t[0]], Q, th, ct, lo, hi));
                    assert_eq!(a, facet_voxels(&[t[1], t[2], t[0]], Q, th, ct, lo, hi));
                }
            }
        }
    }

    #[test]
    fn quad_equals_union_of_its_two_triangles_projected() {
        // A planar convex quad: parallelogram p, p+a, p+a+b, p+b.
        let mut rng = Rng(0xfeed_beef_0bad_cafe);
        for _ in 0..40 {
            let p = [rng.range(0, 40), rng.range(0, 40), rng.range(0, 40)];
            let a = [rng.range(-40, 60), rng.range(-40, 60), rng.range(-40, 60)];
            let b = [rng.range(-40, 60), rng.range(-40, 60), rng.range(-40, 60)];
            let quad = [p, add(p, a), add(add(p, a), b), add(p, b)];
            let (lo, hi) = cube(-8, 12);
            for th in Thickness::ALL {
                let qv = facet_voxels(&quad, Q, th, Contour::Projected, lo, hi);
                let mut u: BTreeSet<[i64; 3]> =
                    facet_voxels(&[quad[0], quad[1], quad[2]], Q, th, Contour::Projected, lo, hi).into_iter().collect();
                u.extend(facet_voxels(&[quad[0], quad[2], quad[3]], Q, th, Contour::Projected, lo, hi));
                assert_eq!(qv, u.into_iter().collect::<Vec<_>>());
            }
        }
    }

    #[test]
    fn modes_are_nested() {
        // naive ⊆ thesis, naive ⊆ standard; projected ⊆ conservative.
        let mut rng = Rng(42);
        for _ in 0..60 {
            let t = random_triangle(&mut rng, 6 * Q);
            let (lo, hi) = cube(-4, 10);
            let set = |th, ct| -> BTreeSet<[i64; 3]> { facet_voxels(&t, Q, th, ct, lo, hi).into_iter().collect() };
            for ct in Contour::ALL {
                let naive = set(Thickness::Naive, ct);
                assert!(naive.is_subset(&set(Thickness::Thesis, ct)));
                assert!(naive.is_subset(&set(Thickness::Standard, ct)));
            }
            for th in Thickness::ALL {
                assert!(set(th, Contour::Projected).is_subset(&set(th, Contour::Conservative)));
            }
        }
    }

    #[test]
    fn reach_box_holds_every_voxel() {
        let mut rng = Rng(7);
        for i in 0..150 {
            // Mix of general triangles and thin slivers.
            let mut t = random_triangle(&mut rng, 7 * Q);
            if i % 3 == 0 {
                t[2] = [t[0][0] + rng.range(-2, 2), t[0][1] + rng.range(-2, 2), t[0][2]];
                t[2] = add(t[2], [(t[1][0] - t[0][0]) / 2, (t[1][1] - t[0][1]) / 2, 3]);
            }
            for th in Thickness::ALL {
                for ct in Contour::ALL {
                    let Some(f) = Facet::new(&t, Q, th, ct) else { continue };
                    let (lo, hi) = match f.reach_box() {
                        Some(b) => b,
                        None => {
                            let all = facet_voxels(&t, Q, th, ct, [-12; 3], [20; 3]);
                            assert!(all.is_empty());
                            continue;
                        }
                    };
                    let inner = facet_voxels(&t, Q, th, ct, lo, hi);
                    let outer = facet_voxels(
                        &t,
                        Q,
                        th,
                        ct,
                        [lo[0] - 3, lo[1] - 3, lo[2] - 3],
                        [hi[0] + 3, hi[1] + 3, hi[2] + 3],
                    );
                    assert_eq!(inner, outer, "{t:?} {th:?} {ct:?}");
                }
            }
        }
    }

    #[test]
    fn conservative_box_trims_the_spike_at_acute_vertices() {
        // A sliver in z = 8: (0,0), (640,16), (640,0). Its bbox spans x ∈ [0, 640] lattice,
        // i.e. voxel centres x ∈ 0..=39 (+ half a voxel of slack: still ≥ 0). The pushed-out
        // edges alone meet far to the left of x = 0; the box keeps the region within half a voxel of it (the square of voxel −1 touches the vertex at 0), and
        // still covers every column along the sliver.
        let t = [[0, 0, 8], [640, 16, 8], [640, 0, 8]];
        let v = facet_voxels_all(&t, Q, Thickness::Naive, Contour::Conservative);
        let xs: BTreeSet<i64> = v.iter().map(|p| p[0]).collect();
        assert_eq!(xs, (-1..=40).collect::<BTreeSet<i64>>(), "conservative region: {xs:?}");
        // Projected contour: the sliver is thinner than a voxel, some columns along it are empty.
        let p = facet_voxels_all(&t, Q, Thickness::Naive, Contour::Projected);
        let xs: BTreeSet<i64> = p.iter().map(|p| p[0]).collect();
        assert!(xs.len() < 40, "projected contour leaves holes in a thin sliver: {xs:?}");
    }
}
