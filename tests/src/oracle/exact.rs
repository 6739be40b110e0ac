//! Per-ray oracle of exact occluders (thesis §5.5.6, "grazing light"): every ray of the lattice
//! walked on its own, stopped by the first triangle of the scene that it crosses, among the
//! triangles kept by the columns it passes through.
//!
//! Rays, layers, sources and directions are those of [`super::rays`] (thesis §4.1.4, §4.3). This module adds
//! the triangles, the columns that keep them and the segment in which a ray crosses one, restated
//! from their definitions with its own `i128` arithmetic; it never calls `cell-core` (whose
//! `occluder` module is the code under test).
//!
//! # Definition
//!
//! **Coordinates** are in sixteenths of a voxel, voxel `(x, y, z)` centred at `(16x, 16y, 16z)`.
//! The grid has `n × n × n` voxels (`[0, n)³`), `D = n − 1`, `f` fraction bits and
//! `N = D·2^f`. A source is `src: [i64; 3]` (sixteenths).
//!
//! **Rays.** Face `dir` (`0..6`, [`dir_axes`]: principal axis w, sign s, transverse u, v) has the
//! lattice rays `(a, b)`, `a, b ∈ [−N, N]`. A ray leaves from an origin O with a lead
//! ([`origin`], [`lead`]):
//! * [`RaysFrom::Voxel`]: O is `src` with `O_w = 16·(source voxel)_w`, and the lead is 0;
//! * [`RaysFrom::Light`]: O is `src`, and the lead is `s·(src_w − 16·w₀)` ∈ [0, 16), where `w₀` is
//!   the last voxel centre plane at or behind the light along s (`⌊src_w/16⌋` for s = +1,
//!   `⌈src_w/16⌉` for s = −1).
//!
//! With `d = s·N·e_w + a·e_u + b·e_v` the ray's point at distance T (sixteenths, along w) from O
//! is
//!
//! ```text
//!   16·p(T) = O + (T/N)·d
//! ```
//!
//! in sixteenths, and layer j's centre plane lies at `T_j = max(16·j − lead, 0)`
//! ([`Ray::reach`]; `T_0 = 0`: at layer 0 every ray is at O). The ray's voxel at layer k is
//! [`RaysFrom::voxel`] (layer 0: the source voxel); `p(T_k)` lies in it.
//!
//! **Columns.** A triangle `(V₀, V₁, V₂)` (integer sixteenths) is *kept by column (x, y)* iff its
//! projection on the xy plane meets the closed square `|16x − X| ≤ 8`, `|16y − Y| ≤ 8`
//! ([`keeps`]); a triangle standing vertical (projecting to a segment or a point) counts too.
//!
//! **Crossings.** With `n = (V₁ − V₀) × (V₂ − V₀)`, `g(T) = n·(16·p(T) − V₀)` and
//! `σ(T) = [g(T) > 0]`, a triangle *meets ray (a, b) in segment k* (k ≥ 1) iff
//! * σ changes in the segment: `σ(T_{k−1}) ≠ σ(T_k)` (g is affine in T, so σ changes at most
//!   once along the ray: the crossing belongs to exactly one segment — for a decreasing g where
//!   `T_{k−1} < T* ≤ T_k`, for an increasing g where `T_{k−1} ≤ T* < T_k`, with
//!   `T* = −g(0)/g'`), and
//! * the line's crossing point `16·p(T*)` lies in the closed triangle (edges and vertices
//!   included).
//!
//! A ray parallel to the plane (`n·d = 0`), a zero-area triangle (`n = 0`) and a triangle whose
//! plane contains O (`g(0) = 0`) meet nothing. [`Ray::meets`] computes the crossing point as an
//! exact rational and tests it by the signs of its 2D orientations against the three edges in
//! the triangle's projection on the coordinate plane across n's largest component.
//!
//! **The walk** of ray `(dir, a, b)` ([`trace_ray_exact`]): if the source voxel is outside the
//! grid, the ray exits at layer 0 (as in [`super::rays::trace_ray_from`]). Else for
//! `k = 1, 2, …, D`, with `p_k` its voxel at layer k:
//! 1. if `p_k` is outside the grid the ray **exits** at k;
//! 2. else if a triangle kept by the column of `p_{k−1}` or the column of `p_k` meets the ray in
//!    segment k, the ray is **stopped** (absorbed) at k;
//! 3. else it goes on.
//!
//! After layer D every remaining ray exits (at `D + 1`).
//!
//! **Locality.** Only the columns of the ray's voxels at layers k − 1 and k are asked. Where a
//! ray steps diagonally across columns between them (x and y both change) its crossing point
//! can lie in a third column of that 2×2 block, and a triangle reaching neither of the two
//! columns then does not stop it although its line crosses the triangle in segment k. On a
//! closed mesh this lets rare rays through near an edge where two faces meet: 39 of the
//! 6·45² rays from the source voxel escape one of the self-test's boxes (faces at generic
//! positions), none from the light, none for the boxes whose faces lie on column boundaries.
//!
//! The six faces' pyramids share their boundary rays (`|a| = N` or `|b| = N`); every
//! `(dir, a, b)` counts on its own, so a source's rays number [`rays_per_source`]`(D, f)`
//! ([`trace_all_exact`]).
//!
//! # Bit budget
//!
//! Vertex and source coordinates are within `±`[`COORD_MAX`] = 2¹⁹ sixteenths (differences
//! ≤ 2²⁰) and `N ≤` [`MAX_SCALED`] = 2²¹ (asserted). Then `|n| ≤ 2⁴¹` per component,
//! `N·g(0) < 2⁸⁴`, `n·d < 2⁶⁴`, the crossing point's numerators relative to a vertex
//! `N·(n·d)·(O − V) − N·g(0)·d < 2¹⁰⁶` and the edge orientations `< 2¹²⁷`: `i128`, exact.

use std::collections::HashMap;

pub use super::rays::RaysFrom;
use super::rays::{dir_axes, rays_per_source, source_voxel};

/// Largest |coordinate| (sixteenths of a voxel) of a vertex or a source (module doc's bit budget).
pub const COORD_MAX: i64 = 1 << 19;

/// Largest `N = D·2^f` (module doc's bit budget).
pub const MAX_SCALED: i64 = 1 << 21;

/// A triangle: three vertices `(x, y, z)` in sixteenths of a voxel.
pub type Tri = [[i64; 3]; 3];

/// What became of one ray under the exact-occluder walk.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ExactFate {
    /// Stopped (absorbed) in the segment of this layer (≥ 1): a triangle kept by the column of
    /// its voxel at this layer or the one before meets it there.
    Stopped(i64),
    /// Exited at this layer: its voxel there is outside the grid (0: the source voxel is), or
    /// it passed layer D (`D + 1`).
    Exited(i64),
}

/// Rays of every face of one source, by fate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct ExactCounts {
    /// Rays stopped by a triangle.
    pub stopped: u128,
    /// Rays that left the grid or passed layer D.
    pub exited: u128,
}

/// Whether ray `fate` reaches layer `layer`: it was stopped at a layer ≥ `layer`, or it exited
/// after it (the receiver's test: a ray stopped at k reaches the voxel of layer k).
pub fn reaches(fate: ExactFate, layer: i64) -> bool {
    match fate {
        ExactFate::Stopped(k) => k >= layer,
        ExactFate::Exited(k) => k > layer,
    }
}

fn sub(p: [i64; 3], q: [i64; 3]) -> [i128; 3] {
    [0, 1, 2].map(|i| p[i] as i128 - q[i] as i128)
}

fn cross(p: [i128; 3], q: [i128; 3]) -> [i128; 3] {
    [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]]
}

fn dot(p: [i128; 3], q: [i128; 3]) -> i128 {
    p[0] * q[0] + p[1] * q[1] + p[2] * q[2]
}

fn in_grid(n: i64, p: [i64; 3]) -> bool {
    p.iter().all(|&c| (0..n).contains(&c))
}

/// `a/b < c/d` for positive denominators.
fn frac_lt((a, b): (i128, i128), (c, d): (i128, i128)) -> bool {
    a * d < c * b
}

/// Whether the closed segment `p..q` meets the closed box `lo ..= hi` (2D, Liang–Barsky with
/// exact rational parameters).
fn segment_meets_box(p: [i64; 2], q: [i64; 2], lo: [i64; 2], hi: [i64; 2]) -> bool {
    // The segment is p + t·(q − p); keep t ∈ [enter, leave] as fractions with positive
    // denominators.
    let (mut enter, mut leave) = ((0i128, 1i128), (1i128, 1i128));
    for c in 0..2 {
        let delta = (q[c] - p[c]) as i128;
        let (l, h, pc) = (lo[c] as i128, hi[c] as i128, p[c] as i128);
        if delta == 0 {
            if pc < l || pc > h {
                return false;
            }
            continue;
        }
        // Entry and exit parameters on this axis.
        let (t_in, t_out) =
            if delta > 0 { ((l - pc, delta), (h - pc, delta)) } else { ((pc - h, -delta), (pc - l, -delta)) };
        if frac_lt(enter, t_in) {
            enter = t_in;
        }
        if frac_lt(t_out, leave) {
            leave = t_out;
        }
    }
    !frac_lt(leave, enter)
}

/// Whether `tri` is kept by column `(x, y)`: its projection on the xy plane meets the closed
/// square `|16x − X| ≤ 8`, `|16y − Y| ≤ 8`.
///
/// Either an edge of the projection meets the square (exact segment clipping; this covers
/// triangles that project to a segment or a point), or no edge does and the square lies wholly
/// inside or wholly outside the projection, which its centre decides.
pub fn keeps(tri: &Tri, x: i64, y: i64) -> bool {
    let p = tri.map(|v| [v[0], v[1]]);
    let (lo, hi) = ([16 * x - 8, 16 * y - 8], [16 * x + 8, 16 * y + 8]);
    if (0..3).any(|i| segment_meets_box(p[i], p[(i + 1) % 3], lo, hi)) {
        return true;
    }
    let orient = |a: [i64; 2], b: [i64; 2], c: [i64; 2]| {
        (b[0] - a[0]) as i128 * (c[1] - a[1]) as i128 - (b[1] - a[1]) as i128 * (c[0] - a[0]) as i128
    };
    let area = orient(p[0], p[1], p[2]).signum();
    let centre = [16 * x, 16 * y];
    area != 0 && (0..3).all(|i| orient(p[i], p[(i + 1) % 3], centre).signum() * area >= 0)
}

fn check_coord(c: i64, what: &str) {
    assert!(c.abs() <= COORD_MAX, "{what} coordinate {c} beyond ±{COORD_MAX} sixteenths");
}

/// The triangles of a scene and, for each column of the grid, those it keeps.
#[derive(Clone, Debug)]
pub struct Scene<'a> {
    /// Voxels per side.
    pub n: i64,
    /// The triangles, each `(V₀, V₁, V₂)` in sixteenths.
    pub triangles: &'a [Tri],
    /// Column `(x, y)` of the grid → indices of the triangles it keeps, ascending.
    columns: HashMap<[i64; 2], Vec<usize>>,
}

impl<'a> Scene<'a> {
    /// The scene of `triangles` in an `n³` grid, with its per-column index (columns of the grid
    /// only: the walk never leaves it).
    ///
    /// # Panics
    /// If `n < 1` or a coordinate is beyond ±[`COORD_MAX`].
    pub fn new(n: i64, triangles: &'a [Tri]) -> Self {
        assert!(n >= 1, "grid side n = {n} must be ≥ 1");
        let mut columns: HashMap<[i64; 2], Vec<usize>> = HashMap::new();
        for (i, t) in triangles.iter().enumerate() {
            t.iter().flatten().for_each(|&c| check_coord(c, "vertex"));
            let lo = |c: usize| t.iter().map(|v| v[c]).min().unwrap_or(0);
            let hi = |c: usize| t.iter().map(|v| v[c]).max().unwrap_or(0);
            // Columns whose square meets the bounding box, clipped to the grid.
            let range = |c: usize| ((lo(c) - 8 + 15).div_euclid(16).max(0), (hi(c) + 8).div_euclid(16).min(n - 1));
            let ((x0, x1), (y0, y1)) = (range(0), range(1));
            for x in x0..=x1 {
                for y in y0..=y1 {
                    if keeps(t, x, y) {
                        columns.entry([x, y]).or_default().push(i);
                    }
                }
            }
        }
        Scene { n, triangles, columns }
    }

    /// The triangles (indices into [`Scene::triangles`], ascending) kept by column `(x, y)`;
    /// empty for a column outside the grid.
    pub fn kept(&self, x: i64, y: i64) -> &[usize] {
        self.columns.get(&[x, y]).map_or(&[], Vec::as_slice)
    }
}

/// The lead of the rays of `src` along face `dir`: 0 from the source voxel, else
/// `s·(src_w − 16·w₀)` ∈ [0, 16) with `w₀` the last voxel centre plane at or behind the light.
pub fn lead(src: [i64; 3], from: RaysFrom, dir: usize) -> i64 {
    let (w, s, _, _) = dir_axes(dir);
    match from {
        RaysFrom::Voxel => 0,
        RaysFrom::Light => {
            let w0 = if s > 0 { src[w].div_euclid(16) } else { -(-src[w]).div_euclid(16) };
            s * (src[w] - 16 * w0)
        }
    }
}

/// The origin O of the rays of `src` along face `dir` (sixteenths): the light, with its w
/// coordinate moved to the source voxel's centre plane for [`RaysFrom::Voxel`].
pub fn origin(src: [i64; 3], from: RaysFrom, dir: usize) -> [i64; 3] {
    let (w, _, _, _) = dir_axes(dir);
    let mut o = src;
    if from == RaysFrom::Voxel {
        o[w] = 16 * source_voxel(src)[w];
    }
    o
}

/// One lattice ray: its origin, direction and lead (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ray {
    /// O, sixteenths.
    o: [i64; 3],
    /// d = s·N·e_w + a·e_u + b·e_v.
    d: [i128; 3],
    /// N = D·2^f.
    scaled: i128,
    lead: i64,
}

impl Ray {
    /// Ray `(dir, a, b)` of `src` from `from`, with far distance `far` = D and `f` fraction bits.
    ///
    /// # Panics
    /// If `dir ≥ 6`, `far < 1`, `N = far·2^f` exceeds [`MAX_SCALED`], `|a|` or `|b|` exceeds N,
    /// or a coordinate of `src` is beyond ±[`COORD_MAX`].
    #[allow(clippy::too_many_arguments)] // the ray's full coordinates, as the definition states them
    pub fn new(src: [i64; 3], from: RaysFrom, far: i64, f: u32, dir: usize, a: i64, b: i64) -> Ray {
        assert!(far >= 1, "far distance D = {far} must be ≥ 1");
        assert!(f < 32 && far.checked_shl(f).is_some_and(|m| m >> f == far && m <= MAX_SCALED), "N = D·2^f too big");
        let big_n = far << f;
        assert!(a.abs() <= big_n && b.abs() <= big_n, "ray ({a}, {b}) outside [−{big_n}, {big_n}]²");
        src.iter().for_each(|&c| check_coord(c, "source"));
        let (w, s, u, v) = dir_axes(dir);
        let mut d = [0i128; 3];
        d[w] = (s * big_n) as i128;
        d[u] = a as i128;
        d[v] = b as i128;
        Ray { o: origin(src, from, dir), d, scaled: big_n as i128, lead: lead(src, from, dir) }
    }

    /// The origin O (sixteenths).
    pub fn origin(&self) -> [i64; 3] {
        self.o
    }

    /// The direction `d = s·N·e_w + a·e_u + b·e_v`.
    pub fn direction(&self) -> [i128; 3] {
        self.d
    }

    /// The lead ∈ [0, 16).
    pub fn lead(&self) -> i64 {
        self.lead
    }

    /// `T_j = max(16·j − lead, 0)`: how far (sixteenths along w) layer j's centre plane lies from
    /// O.
    pub fn reach(&self, j: i64) -> i64 {
        (16 * j - self.lead).max(0)
    }

    /// `N·g(T)`'s two coefficients `(N·g(0), N·g')` for the plane of `tri` (normal `nrm`).
    fn plane(&self, tri: &Tri, nrm: [i128; 3]) -> (i128, i128) {
        (self.scaled * dot(nrm, sub(self.o, tri[0])), dot(nrm, self.d))
    }

    /// The segment (layer k ≥ 1) in which the ray's line crosses the plane of `tri` by the
    /// module doc's convention (`σ(T_{k−1}) ≠ σ(T_k)`), whether or not inside the triangle
    /// (saturated at `i64::MAX`); `None` if it does not cross it ahead of O (parallel,
    /// degenerate, plane through O, or behind O).
    pub fn crossing_layer(&self, tri: &Tri) -> Option<i64> {
        let nrm = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
        let (g0, slope) = self.plane(tri, nrm);
        // T* = −g0/slope must be > 0; σ is constant along the ray otherwise.
        if g0 == 0 || slope == 0 || (g0 > 0) == (slope > 0) {
            return None;
        }
        // In i128: T* may be far beyond any layer. σ(T) is only read near T* (|T − T*| ≤ 32),
        // where |T·slope| ≤ |g0| + 32·|slope|.
        let lead = self.lead as i128;
        let reach = |j: i128| (16 * j - lead).max(0);
        let sigma = |t: i128| g0 + t * slope > 0;
        let s0 = sigma(0);
        // The first k ≥ 1 with σ(T_k) ≠ σ(T_0) = σ(0): start from (T* + lead)/16 and settle it.
        let mut k = (-g0 / slope + lead).div_euclid(16).max(1);
        while k > 1 && sigma(reach(k - 1)) != s0 {
            k -= 1;
        }
        while sigma(reach(k)) == s0 {
            k += 1;
        }
        Some(i64::try_from(k).unwrap_or(i64::MAX))
    }

    /// Whether the ray's line crosses the plane of `tri` inside the closed triangle, ahead of O.
    pub fn hits(&self, tri: &Tri) -> bool {
        let nrm = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
        let (g0, slope) = self.plane(tri, nrm);
        if nrm == [0; 3] || g0 == 0 || slope == 0 || (g0 > 0) == (slope > 0) {
            return false;
        }
        // The crossing point X = O + T*·d/N with T* = −g0/slope: X = Y/den with den = N·slope,
        // Y = den·O − g0·d. Relative to a vertex V: den·(X − V) = den·(O − V) − g0·d.
        let den = self.scaled * slope;
        let rel = |v: [i64; 3]| {
            let ov = sub(self.o, v);
            [0, 1, 2].map(|c| den * ov[c] - g0 * self.d[c])
        };
        // Project on the coordinate plane across n's largest component m, axes (m+1, m+2)
        // cyclically: there the triangle's signed area is n_m ≠ 0 and X is inside iff it is on
        // the inner side (or on) every edge.
        let m = (0..3).max_by_key(|&c| nrm[c].abs()).unwrap_or(0);
        let (i, j) = ((m + 1) % 3, (m + 2) % 3);
        let want = nrm[m].signum() * den.signum();
        (0..3).all(|e| {
            let (p, q) = (tri[e], tri[(e + 1) % 3]);
            let edge = sub(q, p);
            let r = rel(p);
            // orient(P, Q, X)·den = edge × den·(X − P), in the (i, j) plane.
            let o = edge[i] * r[j] - edge[j] * r[i];
            o.signum() * want >= 0
        })
    }

    /// Whether `tri` meets the ray in segment `k` (module doc): the line crosses its plane in
    /// segment k, inside the closed triangle.
    pub fn meets(&self, tri: &Tri, k: i64) -> bool {
        k >= 1 && self.crossing_layer(tri) == Some(k) && self.hits(tri)
    }
}

/// Whether the segment [x0, x1] crosses the closed triangle `tri` (vertices in sixteenths of a
/// voxel, the segment in `scale`ths of a sixteenth): its ends lie strictly on the positive side
/// of the plane (n·(X − V₀) > 0) and not, in either order, and the crossing point X* — an exact
/// fraction — lies in the closed triangle, tested in the coordinate plane across n's largest
/// component. The contact test of `cell_core::receiver` (`Target::shadowed_by`), by other
/// arithmetic: the cell's sums Plücker signs. Checked `i128` (small scenes only).
///
/// # Panics
/// If an intermediate value leaves `i128` (coordinates beyond about 2²⁰).
pub fn segment_crosses(tri: &Tri, x0: [i64; 3], x1: [i64; 3], scale: i64) -> bool {
    let v = tri.map(|p| p.map(|c| c * scale));
    let nrm = cross(sub(v[1], v[0]), sub(v[2], v[0]));
    let h = |x: [i64; 3]| {
        let r = sub(x, v[0]);
        (0..3).try_fold(0i128, |acc, i| acc.checked_add(nrm[i].checked_mul(r[i])?)).expect("oracle: i128")
    };
    let (h0, h1) = (h(x0), h(x1));
    if (h0 > 0) == (h1 > 0) {
        return false;
    }
    // X* = x0 + t·(x1 − x0), t = h0/(h0 − h1): den·X* = den·x0 + h0·(x1 − x0).
    let den = h0 - h1;
    let xs: [i128; 3] = [0, 1, 2].map(|i| {
        let step = h0.checked_mul((x1[i] - x0[i]) as i128).expect("oracle: i128");
        den.checked_mul(x0[i] as i128).and_then(|a| a.checked_add(step)).expect("oracle: i128")
    });
    let m = (0..3).max_by_key(|&c| nrm[c].abs()).unwrap_or(0);
    let (i, j) = ((m + 1) % 3, (m + 2) % 3);
    // orient(V_a, V_b, X*)·den, in the (i, j) plane; inside iff each has the sign of n_m·den.
    let want = nrm[m].signum() * den.signum();
    (0..3).all(|e| {
        let (pa, pb) = (v[e], v[(e + 1) % 3]);
        let (ex, ey) = ((pb[i] - pa[i]) as i128, (pb[j] - pa[j]) as i128);
        let rx = xs[i] - den * pa[i] as i128;
        let ry = xs[j] - den * pa[j] as i128;
        let o = ex.checked_mul(ry).zip(ey.checked_mul(rx)).map(|(p, q)| p - q).expect("oracle: i128");
        o.signum() * want >= 0
    })
}

/// Walks ray `(dir, a, b)` of `src` (from `from`, `f` fraction bits) through `scene`, with
/// `D = n − 1` (module doc's walk).
///
/// # Panics
/// As [`Ray::new`] (for `n ≥ 2`).
pub fn trace_ray_exact(
    scene: &Scene<'_>,
    src: [i64; 3],
    from: RaysFrom,
    f: u32,
    dir: usize,
    a: i64,
    b: i64,
) -> ExactFate {
    let (n, far) = (scene.n, scene.n - 1);
    let mut prev = source_voxel(src);
    if !in_grid(n, prev) {
        return ExactFate::Exited(0);
    }
    if far < 1 {
        return ExactFate::Exited(1);
    }
    let ray = Ray::new(src, from, far, f, dir, a, b);
    for k in 1..=far {
        let p = from.voxel(src, dir, a, b, far, f, k);
        if !in_grid(n, p) {
            return ExactFate::Exited(k);
        }
        let mut tris = scene.kept(prev[0], prev[1]).iter().chain(scene.kept(p[0], p[1]));
        if tris.any(|&i| ray.meets(&scene.triangles[i], k)) {
            return ExactFate::Stopped(k);
        }
        prev = p;
    }
    ExactFate::Exited(far + 1)
}

/// Every ray of every face of `src` through `scene` ([`trace_ray_exact`]); `stopped + exited`
/// is [`rays_per_source`]`(n − 1, f)`.
pub fn trace_all_exact(scene: &Scene<'_>, src: [i64; 3], from: RaysFrom, f: u32) -> ExactCounts {
    let m = (scene.n - 1) << f;
    let mut out = ExactCounts::default();
    for dir in 0..6 {
        for a in -m..=m {
            for b in -m..=m {
                match trace_ray_exact(scene, src, from, f, dir, a, b) {
                    ExactFate::Stopped(_) => out.stopped += 1,
                    ExactFate::Exited(_) => out.exited += 1,
                }
            }
        }
    }
    debug_assert_eq!(out.stopped + out.exited, rays_per_source(scene.n - 1, f));
    out
}

#[cfg(test)]
mod tests {
    use super::super::rays::{light_layer, trace_ray_from, Fate};
    use super::*;

    fn lcg(seed: &mut u64) -> u64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *seed >> 33
    }

    /// Uniform in `[−m, m]`.
    fn r(seed: &mut u64, m: i64) -> i64 {
        (lcg(seed) % (2 * m as u64 + 1)) as i64 - m
    }

    const FROMS: [RaysFrom; 2] = [RaysFrom::Voxel, RaysFrom::Light];

    /// The 12 triangles of the box `lo ..= hi` (sixteenths), two per face.
    fn box_triangles(lo: [i64; 3], hi: [i64; 3]) -> Vec<Tri> {
        // Corner i: bit c of i picks hi on axis c.
        let c = |i: usize| [0, 1, 2].map(|a| if i >> a & 1 == 0 { lo[a] } else { hi[a] });
        // Faces as corner quads (bit masks), split along a diagonal.
        let faces = [[0, 2, 6, 4], [1, 5, 7, 3], [0, 4, 5, 1], [2, 3, 7, 6], [0, 1, 3, 2], [4, 6, 7, 5]];
        faces.iter().flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]]).collect()
    }

    /// The ray's T of its exit from the box `lo ..= hi` (it starts inside), in f64.
    fn box_exit_f64(ray: &Ray, lo: [i64; 3], hi: [i64; 3]) -> f64 {
        let (o, d, nn) = (ray.origin(), ray.direction(), ray.scaled as f64);
        (0..3)
            .filter(|&c| d[c] != 0)
            .map(|c| {
                let face = if d[c] > 0 { hi[c] } else { lo[c] };
                (face - o[c]) as f64 * nn / d[c] as f64
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Whether x is within `eps` of an integer.
    fn near_integer(x: f64, eps: f64) -> bool {
        (x - x.round()).abs() < eps
    }

    /// The layer whose segment holds T (T > 0, not on a boundary): `⌈(T + lead)/16⌉`.
    fn layer_of(t: f64, lead: i64) -> i64 {
        ((t + lead as f64) / 16.0).ceil() as i64
    }

    #[test]
    fn empty_scene_every_ray_exits_where_the_thesis_walk_does() {
        for (n, f) in [(2, 0), (5, 1), (8, 0), (7, 2)] {
            let scene = Scene::new(n, &[]);
            for src in [[8 * (n - 1); 3], [0, 16 * (n - 1), 5], [16 * n / 3 + 7, 16 * n / 2 - 8, 16 * n / 4 + 1]] {
                for from in FROMS {
                    let c = trace_all_exact(&scene, src, from, f);
                    assert_eq!(c, ExactCounts { stopped: 0, exited: rays_per_source(n - 1, f) }, "n={n} {src:?}");
                    let m = (n - 1) << f;
                    for dir in 0..6 {
                        for a in -m..=m {
                            for b in -m..=m {
                                let got = trace_ray_exact(&scene, src, from, f, dir, a, b);
                                let want = match trace_ray_from(from, n, &|_, _, _| false, src, dir, a, b, n - 1, f) {
                                    Fate::Exited { k } => k,
                                    Fate::Absorbed { .. } => unreachable!(),
                                };
                                assert_eq!(got, ExactFate::Exited(want), "n={n} {src:?} {from:?} {dir} ({a}, {b})");
                            }
                        }
                    }
                }
            }
        }
        // A source outside the grid: every ray exits at layer 0.
        let scene = Scene::new(4, &[]);
        assert_eq!(trace_ray_exact(&scene, [-16, 16, 16], RaysFrom::Light, 0, 0, 0, 0), ExactFate::Exited(0));
        assert_eq!(trace_all_exact(&scene, [-16, 16, 16], RaysFrom::Voxel, 1).exited, rays_per_source(3, 1));
    }

    /// The lead and origin as the rays of [`super::super::rays`] read them: layer k's plane lies
    /// `T_k` from O (the light's [`light_layer`]), and `p(T_k)` lies in the ray's voxel at k.
    #[test]
    fn rays_points_lie_in_their_voxels() {
        let (far, f) = (7, 1);
        let m = far << f;
        for src in [[48, 32, 80], [56, 40, 88], [52, 27, 71], [40, 41, 73], [-3, 100, 17]] {
            for from in FROMS {
                for dir in 0..6 {
                    let (w, s, _, _) = dir_axes(dir);
                    let ld = lead(src, from, dir);
                    assert!((0..16).contains(&ld));
                    if from == RaysFrom::Light {
                        assert_eq!(ld, (s * src[w]).rem_euclid(16), "{src:?} {dir}");
                    }
                    for a in (-m..=m).step_by(3) {
                        for b in (-m..=m).step_by(5) {
                            let ray = Ray::new(src, from, far, f, dir, a, b);
                            for k in 1..=far {
                                let t = ray.reach(k);
                                if from == RaysFrom::Light {
                                    assert_eq!(t, light_layer(src, dir, k).1);
                                }
                                let (o, d) = (ray.origin(), ray.direction());
                                let nn = (far << f) as i128;
                                // ⌊(16·p + 8)/16⌋ with 16·p = O + T·d/N, exactly.
                                let voxel =
                                    [0, 1, 2].map(|c| ((o[c] as i128 + 8) * nn + t as i128 * d[c]).div_euclid(16 * nn));
                                let want = from.voxel(src, dir, a, b, far, f, k).map(|c| c as i128);
                                assert_eq!(voxel, want, "{src:?} {from:?} {dir} ({a}, {b}) layer {k}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// The convention at a segment's end, and the closed triangle, by hand.
    #[test]
    fn meets_by_hand() {
        // Light at the centre of voxel 0; a triangle across +z at z = 4.5 (72 sixteenths).
        let tri = [[-32, -32, 72], [32, -32, 72], [0, 32, 72]];
        let (far, f) = (8, 0);
        for from in FROMS {
            let ray = Ray::new([0; 3], from, far, f, 4, 0, 0);
            assert!(ray.meets(&tri, 5) && !ray.meets(&tri, 4) && !ray.meets(&tri, 6));
            // Ray (8, 0) is at x = 4.5 there, beside the triangle.
            let beside = Ray::new([0; 3], from, far, f, 4, 8, 0);
            assert!(!(0..=9).any(|k| beside.meets(&tri, k)));
            // Ray (1, 0) passes x = 9/16 there, inside.
            assert!(Ray::new([0; 3], from, far, f, 4, 1, 0).meets(&tri, 5));
        }
        // A plane through layer 4's centre plane (z = 64): the crossing is at T = T_4 exactly.
        // g increasing (n_z > 0 along +z): T_3 ≤ T* < T_4 fails, T_4 ≤ T* < T_5 holds: layer 5.
        let up = [[-32, -32, 64], [32, -32, 64], [0, 32, 64]];
        let down = [up[0], up[2], up[1]];
        let ray = Ray::new([0; 3], RaysFrom::Voxel, far, f, 4, 0, 0);
        assert_eq!((ray.crossing_layer(&up), ray.crossing_layer(&down)), (Some(5), Some(4)));
        assert!(ray.meets(&up, 5) && ray.meets(&down, 4));
        // Along −z the same triangles are crossed the other way round.
        let back = [[-32, -32, -64], [32, -32, -64], [0, 32, -64]];
        let ray = Ray::new([0; 3], RaysFrom::Voxel, far, f, 5, 0, 0);
        assert_eq!(ray.crossing_layer(&back), Some(4));
        // Through a vertex and along an edge: the closed triangle. With D = 9 (N = 9) ray (a, b)
        // crosses z = 72 at T* = 72, at 16·p = (8a, 8b): ray (4, −4) through the vertex
        // (32, −32), ray (2, −4) on the edge y = −32, ray (2, −5) beside it.
        let ray = Ray::new([0; 3], RaysFrom::Voxel, 9, 0, 4, 4, -4);
        assert!(ray.hits(&tri) && ray.meets(&tri, 5), "through the vertex (32, −32, 72)");
        let ray = Ray::new([0; 3], RaysFrom::Voxel, 9, 0, 4, 2, -4);
        assert!(ray.meets(&tri, 5), "on the edge y = −32");
        let ray = Ray::new([0; 3], RaysFrom::Voxel, 9, 0, 4, 2, -5);
        assert!(!ray.hits(&tri), "just beside the edge");
        // Degenerate cases meet nothing: zero area, plane through O, parallel ray.
        let flat = [[0, 0, 72], [16, 16, 72], [32, 32, 72]];
        let through_o = [[0, -32, -32], [0, 32, -32], [0, 0, 64]];
        let ray = Ray::new([0; 3], RaysFrom::Voxel, far, f, 4, 0, 0);
        assert!(!ray.hits(&flat) && ray.crossing_layer(&flat).is_none());
        assert!(!ray.hits(&through_o) && ray.crossing_layer(&through_o).is_none());
        let parallel = [[-32, -32, 72], [32, -32, 72], [0, 32, 72]];
        assert!(Ray::new([0; 3], RaysFrom::Voxel, far, f, 0, 0, 0).crossing_layer(&parallel).is_none());
        // Behind O.
        assert!(!Ray::new([0; 3], RaysFrom::Voxel, far, f, 5, 0, 0).hits(&tri));
        // The light 5/16 ahead of voxel 0's centre along +z: lead 5, T_k = 16k − 5.
        let ray = Ray::new([0, 0, 5], RaysFrom::Light, far, f, 4, 0, 0);
        assert_eq!((ray.lead(), ray.reach(0), ray.reach(1), ray.reach(5)), (5, 0, 11, 75));
        // z = 72 is T* = 67: T_4 = 59 < 67 < T_5 = 75.
        assert!(ray.meets(&tri, 5));
        let ray = Ray::new([0, 0, 5], RaysFrom::Light, far, f, 5, 0, 0);
        assert_eq!(ray.lead(), 11); // −z: the last plane at or behind is z = 16.
    }

    /// Every term at the bit budget's limits, with overflow checks on (the test profile).
    #[test]
    fn arithmetic_at_the_limits() {
        let l = COORD_MAX;
        let (far, f) = (1 << 9, 12); // N = 2²¹
        let tris: [Tri; 4] = [
            [[l, l, l], [-l, l, -l], [l, -l, -l]],
            [[-l, -l, -l], [l, -l, l], [-l, l, l]],
            [[l, -l, l], [-l, -l, -l], [l, l, -l]],
            // Nearly parallel to +x rays: the crossing lies far beyond any layer.
            [[-l, -l, -l], [l, l, -l + 1], [-l, l, -l]],
        ];
        let nn = far << f;
        let mut hits = 0;
        for tri in tris {
            for src in [[-(l - 8); 3], [l - 8, -(l - 8), 0], [0, 0, l]] {
                for from in FROMS {
                    for dir in 0..6 {
                        for (a, b) in [(nn, nn), (-nn, nn), (nn, -nn), (-nn, -nn), (0, 0), (1, -nn)] {
                            let ray = Ray::new(src, from, far, f, dir, a, b);
                            hits += ray.hits(&tri) as u32;
                            let _ = ray.crossing_layer(&tri);
                            let _ = ray.meets(&tri, far);
                        }
                    }
                }
            }
        }
        assert!(hits > 0);
    }

    /// `reaches` by hand.
    #[test]
    fn reaches_by_hand() {
        assert!(reaches(ExactFate::Stopped(3), 3) && !reaches(ExactFate::Stopped(3), 4));
        assert!(reaches(ExactFate::Exited(3), 2) && !reaches(ExactFate::Exited(3), 3));
    }

    /// A closed box around the source: each ray stops where its line leaves the box (f64, away
    /// from segment boundaries), except the rare ray that escapes through a box edge (see the
    /// module doc's note on locality): none escapes three of the four boxes.
    #[test]
    fn closed_box_stops_rays_where_they_leave_it() {
        let n = 12;
        // (source, box lo, box hi, f, rays that escape from the source voxel, from the light).
        type Case = ([i64; 3], [i64; 3], [i64; 3], u32, u128, u128);
        let cases: [Case; 4] = [
            // Source (5.19, 5.69, 5.56) → voxel (5, 6, 6); faces at generic positions.
            ([16 * 5 + 3, 16 * 6 - 5, 16 * 5 + 9], [37, 30, 45], [147, 150, 139], 1, 39, 0),
            // A centred source, faces on column boundaries and a centre plane.
            ([96, 96, 96], [40, 24, 56], [152, 136, 128], 0, 0, 0),
            ([90, 70, 100], [33, 51, 61], [129, 117, 143], 2, 0, 0),
            ([90, 70, 100], [40, 40, 56], [136, 136, 152], 2, 0, 0),
        ];
        let (mut checked, mut total, mut escaped) = (0u64, 0u64, 0u64);
        for (src, lo, hi, f, esc_voxel, esc_light) in cases {
            let tris = box_triangles(lo, hi);
            let scene = Scene::new(n, &tris);
            for from in FROMS {
                let c = trace_all_exact(&scene, src, from, f);
                assert_eq!(c.stopped + c.exited, rays_per_source(n - 1, f));
                let want_esc = if from == RaysFrom::Voxel { esc_voxel } else { esc_light };
                assert_eq!(c.exited, want_esc, "{src:?} {from:?}: rays escaped the box");
                let m = (n - 1) << f;
                for dir in 0..6 {
                    for a in -m..=m {
                        for b in -m..=m {
                            let fate = trace_ray_exact(&scene, src, from, f, dir, a, b);
                            let ray = Ray::new(src, from, n - 1, f, dir, a, b);
                            let t = box_exit_f64(&ray, lo, hi);
                            total += 1;
                            if near_integer((t + ray.lead() as f64) / 16.0, 1e-6) {
                                continue;
                            }
                            checked += 1;
                            let k = layer_of(t, ray.lead());
                            if !matches!(fate, ExactFate::Exited(_)) || !tris.iter().any(|t| ray.meets(t, k)) {
                                assert_eq!(fate, ExactFate::Stopped(k), "{src:?} {from:?} {dir} ({a}, {b}): T* = {t}");
                                continue;
                            }
                            // An escape: the whole mesh would stop it at k, but its voxels at
                            // k − 1 and k step diagonally across columns, and it leaves the box
                            // within a voxel of an edge (two faces' planes).
                            escaped += 1;
                            let (p0, p1) =
                                (from.voxel(src, dir, a, b, n - 1, f, k - 1), from.voxel(src, dir, a, b, n - 1, f, k));
                            assert!(p0[0] != p1[0] && p0[1] != p1[1], "{from:?} {dir} ({a}, {b}): {p0:?} → {p1:?}");
                            let (o, d) = (ray.origin(), ray.direction());
                            let x = [0, 1, 2].map(|c| o[c] as f64 + t * d[c] as f64 / ray.scaled as f64);
                            let near = (0..3)
                                .filter(|&c| (x[c] - lo[c] as f64).abs().min((x[c] - hi[c] as f64).abs()) <= 16.0);
                            assert!(near.count() >= 2, "{from:?} {dir} ({a}, {b}) leaves the box at {x:?}");
                        }
                    }
                }
            }
        }
        assert!(checked * 10 > total * 8, "most rays checked ({checked} of {total})");
        assert!(escaped > 0 && escaped * 1000 < total, "{escaped} escapes");
    }

    /// f64 line–triangle intersection (Möller–Trumbore): `(T, barycentrics)` or `None` when
    /// the line is (nearly) parallel.
    fn intersect_f64(ray: &Ray, tri: &Tri) -> Option<(f64, [f64; 3])> {
        let f = |p: [i64; 3]| p.map(|c| c as f64);
        let (v0, v1, v2) = (f(tri[0]), f(tri[1]), f(tri[2]));
        let o = f(ray.origin());
        let dir = ray.direction().map(|c| c as f64 / ray.scaled as f64);
        let s3 = |p: [f64; 3], q: [f64; 3]| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
        let cr = |p: [f64; 3], q: [f64; 3]| {
            [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]]
        };
        let dt = |p: [f64; 3], q: [f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        let (e1, e2) = (s3(v1, v0), s3(v2, v0));
        let h = cr(dir, e2);
        let det = dt(e1, h);
        if det.abs() < 1e-9 * (dt(e1, e1) * dt(e2, e2)).sqrt() {
            return None;
        }
        let sv = s3(o, v0);
        let beta = dt(sv, h) / det;
        let q = cr(sv, e1);
        let gamma = dt(dir, q) / det;
        let t = dt(e2, q) / det;
        Some((t, [1.0 - beta - gamma, beta, gamma]))
    }

    /// A big triangle in front of the source: segment membership equals the f64 intersection
    /// on random rays away from edges and segment boundaries.
    #[test]
    fn big_triangle_matches_f64_intersection() {
        let mut seed = 7u64;
        let (mut checked, mut total, mut hit) = (0u64, 0u64, 0u64);
        for _ in 0..200 {
            let f = (lcg(&mut seed) % 3) as u32;
            let far = 4 + (lcg(&mut seed) % 10) as i64;
            let m = far << f;
            let src = [0; 3].map(|_| r(&mut seed, 200));
            let dir = (lcg(&mut seed) % 6) as usize;
            let (w, s, u, v) = dir_axes(dir);
            // Vertices around the axis, 1 to `far` voxels ahead.
            let dist = 16 + r(&mut seed, 8 * far).abs() * 2;
            let tri: Tri = [0; 3].map(|_| {
                let mut p = src;
                p[w] += s * (dist + r(&mut seed, 40));
                p[u] += r(&mut seed, 16 * far);
                p[v] += r(&mut seed, 16 * far);
                p
            });
            for _ in 0..60 {
                let from = FROMS[(lcg(&mut seed) % 2) as usize];
                let (a, b) = (r(&mut seed, m), r(&mut seed, m));
                let ray = Ray::new(src, from, far, f, dir, a, b);
                total += 1;
                let got: Vec<i64> = (0..=far + 3).filter(|&k| ray.meets(&tri, k)).collect();
                let Some((t, bary)) = intersect_f64(&ray, &tri) else { continue };
                let x = (t + ray.lead() as f64) / 16.0;
                if bary.iter().any(|&c| c.abs() < 1e-6) || t.abs() < 1e-6 || (t > 0.0 && near_integer(x, 1e-6)) {
                    continue;
                }
                checked += 1;
                let inside = bary.iter().all(|&c| c > 0.0) && t > 0.0;
                let want: Vec<i64> =
                    if inside && layer_of(t, ray.lead()) <= far + 3 { vec![layer_of(t, ray.lead())] } else { vec![] };
                hit += !want.is_empty() as u64;
                assert_eq!(got, want, "{tri:?} src {src:?} {from:?} {dir} ({a}, {b}) T* = {t} bary {bary:?}");
            }
        }
        assert!(checked * 10 > total * 9, "most rays checked ({checked} of {total})");
        assert!(hit * 10 > checked, "many rays hit ({hit} of {checked})");
    }

    /// Each triangle meets a ray in at most one segment, even on a coarse lattice where rays
    /// through edges, vertices and segment ends are common; a quad split in two triangles leaves
    /// no crack; fates do not depend on the triangles' order.
    #[test]
    fn one_segment_per_triangle_no_crack_deterministic() {
        let mut seed = 99u64;
        let mut met = 0;
        for _ in 0..150 {
            let src = [0; 3].map(|_| 96 + r(&mut seed, 40));
            let tri: Tri = [0; 3].map(|_| [0; 3].map(|_| 96 + 4 * r(&mut seed, 24)));
            let (far, f) = (6, (lcg(&mut seed) % 2) as u32);
            let m = far << f;
            for from in FROMS {
                for dir in 0..6 {
                    for a in -m..=m {
                        for b in -m..=m {
                            let ray = Ray::new(src, from, far, f, dir, a, b);
                            let ks: Vec<i64> = (0..=far + 8).filter(|&k| ray.meets(&tri, k)).collect();
                            assert!(ks.len() <= 1, "{tri:?} {src:?} {from:?} {dir} ({a}, {b}): {ks:?}");
                            // The crossing's segment, σ read at every layer's end.
                            let nrm = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
                            let (o, d) = (ray.origin(), ray.direction());
                            let g = |t: i64| {
                                let q = [0, 1, 2].map(|c| ray.scaled * (o[c] - tri[0][c]) as i128 + t as i128 * d[c]);
                                dot(nrm, q)
                            };
                            let naive = (1..=far + 8).find(|&k| (g(ray.reach(k - 1)) > 0) != (g(ray.reach(k)) > 0));
                            let got = ray.crossing_layer(&tri).filter(|&k| k <= far + 8);
                            assert_eq!(got, naive.filter(|_| g(0) != 0), "{tri:?} {src:?} {from:?} {dir} ({a}, {b})");
                            met += ks.len();
                        }
                    }
                }
            }
        }
        assert!(met > 1000, "rays were met ({met})");
        // A square at z = 4.25 voxels split along its diagonal: rays on the diagonal and on
        // the outer edges are met, by one triangle or both, in one segment.
        let quad = [[-32, -32, 68], [32, -32, 68], [32, 32, 68], [-32, 32, 68]];
        let halves = [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]];
        let (far, f) = (8, 2);
        let m = far << f;
        let mut on_diagonal = 0;
        for a in -m..=m {
            for b in -m..=m {
                let ray = Ray::new([0; 3], RaysFrom::Voxel, far, f, 4, a, b);
                // 16·p at T* = 68: (68·a/32, 68·b/32); inside iff |a|, |b| ≤ 32·32/68.
                let inside = 68 * a.abs() <= 32 * 32 && 68 * b.abs() <= 32 * 32;
                let ks: Vec<i64> = (0..=far).filter(|&k| halves.iter().any(|h| ray.meets(h, k))).collect();
                assert_eq!(ks, if inside { vec![5] } else { vec![] }, "({a}, {b})");
                on_diagonal += (inside && a == b) as u32;
            }
        }
        assert!(on_diagonal > 10);
        // Determinism and order independence on a random scene.
        let n = 8;
        let tris: Vec<Tri> = (0..30).map(|_| [0; 3].map(|_| [0; 3].map(|_| 64 + r(&mut seed, 56)))).collect();
        let rev: Vec<Tri> = tris.iter().rev().copied().collect();
        let (s1, s2) = (Scene::new(n, &tris), Scene::new(n, &rev));
        let src = [60, 70, 65];
        let m = (n - 1) << 1;
        let mut stopped = 0;
        for from in FROMS {
            for dir in 0..6 {
                for a in -m..=m {
                    for b in -m..=m {
                        let x = trace_ray_exact(&s1, src, from, 1, dir, a, b);
                        assert_eq!(x, trace_ray_exact(&s1, src, from, 1, dir, a, b));
                        assert_eq!(x, trace_ray_exact(&s2, src, from, 1, dir, a, b));
                        stopped += matches!(x, ExactFate::Stopped(_)) as u32;
                    }
                }
            }
            assert_eq!(trace_all_exact(&s1, src, from, 1), trace_all_exact(&s2, src, from, 1));
        }
        assert!(stopped > 1000, "the random scene stops rays ({stopped})");
    }

    /// `kept` against dense sampling of each triangle: every sampled point's column keeps it,
    /// and a column keeps it only if a sample lies near its square.
    #[test]
    fn kept_matches_sampling() {
        let mut seed = 5u64;
        let n = 16;
        let (mut kept_total, mut far_checked) = (0, 0);
        for i in 0..300 {
            let mm = if i % 2 == 0 { 8 } else { 1 };
            let mut t: Tri =
                [0; 3].map(|_| [128 + r(&mut seed, 60 / mm) * mm, 128 + r(&mut seed, 60 / mm) * mm, r(&mut seed, 99)]);
            match i % 6 {
                // Standing vertical: projects to a segment.
                4 => t[2] = [(t[0][0] + t[1][0]) / 2, (t[0][1] + t[1][1]) / 2, t[2][2]],
                // Projects to a point.
                5 => {
                    t[1] = [t[0][0], t[0][1], t[1][2]];
                    t[2] = [t[0][0], t[0][1], t[2][2]];
                }
                _ => {}
            }
            let tris = [t];
            let scene = Scene::new(n, &tris);
            const S: i64 = 64;
            let mut samples = Vec::new();
            for p in 0..=S {
                for q in 0..=S - p {
                    let r3 = S - p - q;
                    // 64 × the point, xy.
                    samples.push([0, 1].map(|c| p * t[0][c] + q * t[1][c] + r3 * t[2][c]));
                }
            }
            for s in &samples {
                let col = s.map(|c| (c + 8 * S).div_euclid(16 * S));
                assert!(keeps(&t, col[0], col[1]), "{t:?} sample {s:?}/64 column {col:?}");
                if in_grid(n, [col[0], col[1], 0]) {
                    assert!(scene.kept(col[0], col[1]).contains(&0));
                }
            }
            // Slack: every point of the triangle lies within (longest edge)/64 of a sample.
            let longest = (0..3)
                .map(|e| (0..2).map(|c| (t[e][c] - t[(e + 1) % 3][c]).abs()).max().unwrap_or(0))
                .max()
                .unwrap_or(0);
            let slack = S * (longest / S + 1);
            for x in 0..n {
                for y in 0..n {
                    let k = scene.kept(x, y).contains(&0);
                    assert_eq!(k, keeps(&t, x, y));
                    kept_total += k as u32;
                    // Chebyshev distance (×64) from the column centre to the nearest sample.
                    let dist = samples.iter().map(|s| (s[0] - 16 * S * x).abs().max((s[1] - 16 * S * y).abs())).min();
                    let dist = dist.unwrap_or(i64::MAX);
                    if dist <= 8 * S {
                        assert!(k, "{t:?}: column ({x}, {y}) holds a sample");
                    }
                    if dist > 8 * S + slack {
                        assert!(!k, "{t:?}: column ({x}, {y}) is far from the triangle");
                        far_checked += 1;
                    }
                }
            }
        }
        assert!(kept_total > 2000 && far_checked > 20000, "{kept_total} kept, {far_checked} far");
        // Touching cases by hand: a vertex on a square's corner, an edge along its border.
        let corner = [[8, 8, 0], [40, 8, 0], [40, 40, 0]];
        assert!(keeps(&corner, 0, 0) && keeps(&corner, 1, 1) && !keeps(&corner, -1, 0));
        let below = [[-40, -9, 0], [40, -9, 0], [0, -40, 0]];
        assert!(!keeps(&below, 0, 0) && keeps(&below, 0, -1));
        let touching = [[-40, -8, 0], [40, -8, 0], [0, -40, 0]];
        assert!(keeps(&touching, 0, 0));
        // The square inside a big triangle, no edge near it.
        let big = [[-400, -400, 0], [400, -400, 0], [0, 400, 5]];
        assert!(keeps(&big, 0, 0));
        // A vertical triangle whose segment passes a corner diagonally.
        let vertical = [[16, 0, 0], [0, 16, 0], [8, 8, 50]];
        assert!(keeps(&vertical, 0, 0) && keeps(&vertical, 1, 1));
        let vertical = [[17, 0, 0], [0, 17, 0], [0, 17, 50]];
        assert!(!keeps(&vertical, 0, 0) && keeps(&vertical, 1, 0));
        let point = [[8, -8, 0], [8, -8, 9], [8, -8, 3]];
        assert!(keeps(&point, 0, 0) && keeps(&point, 1, -1) && !keeps(&point, 0, 1));
    }
}
