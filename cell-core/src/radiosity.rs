//! Radiosity thesis §1.3.2, §3.4 — a shooting patch's energy on the grid: what a beam of rays
//! carries, and what a cell collects for the patches of its column.
//!
//! **Invariant: energy is conserved exactly, in integers.** The energy of a beam is a function
//! of its ray rectangle alone ([`beam_quanta`]), additive over any exact split or merge of
//! rectangles: the quanta of a beam equal the sum of its sub-beams' quanta, bit for bit. So per
//! shot, quanta absorbed + quanta that left the grid = quanta emitted, with no rounding slack.
//!
//! # The form factor of a beam (radiosity thesis §3.4, beam tracing)
//!
//! A shot is one beam diffusion ([`crate::light`]) from a source S pushed off the shooting
//! patch's centre along its unit normal N. A lattice ray (u, v) of direction ±w stands for the
//! far-plane square of side h = 2^−f around it, clipped to the cube face [−D, D]²: the six faces
//! tile the directions around S exactly (a ray on a cube edge belongs to two faces, each keeping
//! its half of the square). The fraction of the patch's power that leaves into a set R of
//! directions is its point form factor, the cosine-weighted solid angle
//!
//! ```text
//!   F(R) = (1/π) ∫_R max(0, N·ω) dω
//! ```
//!
//! and for a polygon P seen from S (vertices R_i relative to S) on the front side of N, Lambert's
//! contour integral gives it in closed form (Cohen & Wallace, radiosity thesis ch. 2):
//!
//! ```text
//!   F(P) = (1/2π) | Σ_i θ_i · N·(R_i × R_{i+1}) / |R_i × R_{i+1}| |,  θ_i = ∠(R_i, R_{i+1})
//! ```
//!
//! A beam's rectangle is cut by the patch's tangent plane N·R = 0 first (the front hemisphere).
//! Rather than evaluate F per rectangle, the cell evaluates the **corner function**
//! `C(a, b) = F([−D, a] × [−D, b])` and takes `E = C(a₁,b₁) − C(a₀,b₁) − C(a₁,b₀) + C(a₀,b₀)`
//! with (a₀, a₁) = (u_min − h/2, u_max + h/2) clamped to [−D, D] (same for b). Each C is rounded
//! once to an integer number of quanta, a deterministic function of the integer corner; two
//! rectangles that share a side share its two corners, so the roundings telescope and the split
//! conserves quanta exactly. Rounding only limits the accuracy of a form factor, never the
//! balance.
//!
//! # What the host precomputes, what the cell computes
//!
//! The host precomputes, per shot: the source position (1/16 voxel, the ordinary [`crate::beam::Source`]),
//! the patch normal (three `f32`), and the six initial beams clipped to the lattice rays whose
//! squares reach the front hemisphere ([`front_rays`]; the others carry 0 quanta anyway). The
//! cell computes the quanta of every beam it absorbs or drops out of the grid: four corners,
//! each a clip of a 4-gon by a plane and at most 5 `atan2f`/`sqrtf` (`libm`, the Cortex-M4F's
//! single precision).
//!
//! # Bit budget
//!
//! * One quantum is 2^−30 of the power shot ([`FORM_FACTOR_ONE`]): a corner value is in
//!   [0, 2^30] (F ≤ 1), a beam's quanta in (−2^32, 2^32) — `i64` throughout, with room for any
//!   sum over a shot (at most 2^31 in magnitude per beam, fewer than 2^31 beams).
//! * Corners are on the 2^−(f+1) lattice: |2^(f+1)·a| ≤ 2^(f+1)·D ≤ 2³² (an `i64`); they are
//!   exact in `f32` while 2^(f+1)·D < 2^24 ([`corner_exact`]; the grids here have D ≤ 511 and
//!   f ≤ 8).
//! * `f32` limits accuracy, not the balance: a corner value is an `f32` below 2^30 quanta, so it
//!   carries a rounding of up to one ulp, 2^6 quanta (6·10^−8 of the shot), plus libm's
//!   `atan2f`/`sqrtf` (within 1 ulp each); a beam's quanta are good to about 4·2^6 quanta. A
//!   beam of rays behind the patch, or at its horizon, can come out a few quanta off zero, even
//!   negative: it is counted as is, and the balance stays exact.
//!
//! # The cell's stores
//!
//! [`PatchRuns`] maps the cell's occupied voxels to patch ids (runs along z, loaded by the
//! host with the patches), [`Received`] accumulates the quanta each patch of the column
//! received during the shot. Both are bounded; overflow is a counted event — quanta that find
//! no slot go to [`Received::lost`], so the balance still closes. After the shots,
//! [`IndirectPixel`] holds what the cell's pixel shows of the solution.
//!
//! ```
//! use cell_core::beam::{frac::U0, Beam, Direction, FarDistance, Source, SourceId};
//! use cell_core::radiosity::{beam_quanta, FORM_FACTOR_ONE};
//!
//! // A patch facing +z: the +z face and the upper halves of the four side faces share its whole
//! // power, the −z face gets nothing.
//! let far = FarDistance::<U0>::new(15).unwrap();
//! let s = Source::at_voxel(SourceId(0), [8, 8, 8]).unwrap();
//! let n = [0.0, 0.0, 1.0];
//! let q: i64 = Direction::ALL.iter().map(|&d| beam_quanta(n, &Beam::initial(&s, d, far), far)).sum();
//! assert!((q - FORM_FACTOR_ONE).abs() <= 6 * 4 * 64, "the six faces hold the whole hemisphere (to f32 ulps)");
//! assert_eq!(beam_quanta(n, &Beam::initial(&s, Direction::NegZ, far), far), 0);
//! ```

use core::f32::consts::PI;

use heapless::Vec;

use crate::beam::{Beam, Direction, FarDistance, FracBits, RayRange};
use crate::units::Depth;

/// Quanta of a form factor of 1: the whole power of a shot.
pub const FORM_FACTOR_ONE: i64 = 1 << 30;

/// A radiosity patch id (the host numbers the scene's patches; at most 65 535).
pub type PatchId = u16;

/// Whether corners of a grid of far distance `d` with `f` fraction bits are exact in `f32`.
pub const fn corner_exact(d: u32, f: u32) -> bool {
    (d as u64) << (f + 1) < 1 << 24
}

/// A 3-vector of `f32`.
type V = [f32; 3];

fn cross(a: V, b: V) -> V {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn dot(a: V, b: V) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The point on the far plane of `dir` at (a, b) (voxel units), relative to the source.
fn far_point(dir: Direction, d: f32, a: f32, b: f32) -> V {
    let (ua, va) = dir.transverse();
    let mut p = [0.0; 3];
    p[dir.principal().index()] = dir.sign() as f32 * d;
    p[ua.index()] = a;
    p[va.index()] = b;
    p
}

/// The point form factor (from a differential area of unit normal `n` at the origin) of the
/// convex polygon `poly` cut to the front half-space n·R ≥ 0: Lambert's contour integral.
pub fn polygon_form_factor(n: V, poly: &[V]) -> f32 {
    // Sutherland–Hodgman against n·R ≥ 0: a convex k-gon gives at most k + 1 vertices.
    let mut clipped: Vec<V, 8> = Vec::new();
    for (i, &p) in poly.iter().enumerate() {
        let q = poly[(i + 1) % poly.len()];
        let (dp, dq) = (dot(n, p), dot(n, q));
        if dp >= 0.0 {
            let _ = clipped.push(p);
        }
        if (dp >= 0.0) != (dq >= 0.0) {
            let t = dp / (dp - dq);
            let _ = clipped.push([0, 1, 2].map(|k| p[k] + t * (q[k] - p[k])));
        }
    }
    let mut sum = 0.0f32;
    for (i, &p) in clipped.iter().enumerate() {
        let q = clipped[(i + 1) % clipped.len()];
        let c = cross(p, q);
        let len = libm::sqrtf(dot(c, c));
        if len > 0.0 {
            sum += libm::atan2f(len, dot(p, q)) * dot(n, c) / len;
        }
    }
    libm::fabsf(sum) / (2.0 * PI)
}

/// The corner function in quanta: `C(a, b) = F([−D, a] × [−D, b])` on the far plane of `dir`,
/// with the corner (a, b) = (a2, b2) / 2^(f+1) clamped to the face. 0 when the rectangle is
/// empty (a or b at −D).
pub fn corner_quanta(n: V, dir: Direction, d: u32, f: u32, a2: i64, b2: i64) -> i64 {
    let lim = (d as i64) << (f + 1);
    let (a2, b2) = (a2.clamp(-lim, lim), b2.clamp(-lim, lim));
    if a2 == -lim || b2 == -lim {
        return 0;
    }
    let scale = 1.0 / (1u64 << (f + 1)) as f32;
    let (df, a, b) = (d as f32, a2 as f32 * scale, b2 as f32 * scale);
    let poly = [
        far_point(dir, df, -df, -df),
        far_point(dir, df, a, -df),
        far_point(dir, df, a, b),
        far_point(dir, df, -df, b),
    ];
    let ff = polygon_form_factor(n, &poly);
    libm::roundf(ff * FORM_FACTOR_ONE as f32) as i64
}

/// The quanta a beam's rays carry from an emitter of unit normal `n`: the inclusion–exclusion
/// of [`corner_quanta`] at its rectangle's corners (module doc). Exactly additive over splits.
pub fn beam_quanta<F: FracBits>(n: V, beam: &Beam<F>, far: FarDistance<F>) -> i64 {
    let (u, v) = (beam.u(), beam.v());
    let (a0, a1) = (2 * u.lo().to_bits() as i64 - 1, 2 * u.hi().to_bits() as i64 + 1);
    let (b0, b1) = (2 * v.lo().to_bits() as i64 - 1, 2 * v.hi().to_bits() as i64 + 1);
    let c = |a, b| corner_quanta(n, beam.direction(), far.get(), F::U32, a, b);
    c(a1, b1) - c(a0, b1) - c(a1, b0) + c(a0, b0)
}

/// The lattice rays of face `dir` whose squares reach the front half-space of `n` (a
/// conservative bounding rectangle; rays outside it carry no quanta), or `None` when the face
/// lies wholly behind the patch.
pub fn front_rays<F: FracBits>(n: V, dir: Direction, far: FarDistance<F>) -> Option<(RayRange<F>, RayRange<F>)> {
    let d = far.get() as f32;
    let corners = [(-d, -d), (d, -d), (d, d), (-d, d)];
    let (ua, va) = dir.transverse();
    let (nu, nv) = (n[ua.index()], n[va.index()]);
    let nw = n[dir.principal().index()] * dir.sign() as f32 * d;
    // Clip the face square to nw + nu·a + nv·b ≥ 0 and bound what is left.
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    let mut any = false;
    for i in 0..4 {
        let (p, q) = (corners[i], corners[(i + 1) % 4]);
        let (dp, dq) = (nw + nu * p.0 + nv * p.1, nw + nu * q.0 + nv * q.1);
        let mut take = |x: (f32, f32)| {
            any = true;
            lo = [lo[0].min(x.0), lo[1].min(x.1)];
            hi = [hi[0].max(x.0), hi[1].max(x.1)];
        };
        if dp > 0.0 {
            take(p);
        }
        if (dp > 0.0) != (dq > 0.0) && dp != dq {
            let t = dp / (dp - dq);
            take((p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1)));
        }
    }
    if !any || lo[0] >= hi[0] || lo[1] >= hi[1] {
        return None;
    }
    // Lattice rays whose squares [r − h/2, r + h/2] meet [lo, hi], one step of margin for f32.
    let step = (1u64 << F::U32) as f32;
    let max = far.get() as i64 * (1i64 << F::U32);
    let range = |l: f32, h: f32| {
        let (a, b) = ((libm::floorf(l * step) as i64 - 1).max(-max), (libm::ceilf(h * step) as i64 + 1).min(max));
        RayRange::new(fixed::FixedI32::from_bits(a as i32), fixed::FixedI32::from_bits(b as i32))
    };
    Some((range(lo[0], hi[0])?, range(lo[1], hi[1])?))
}

/// One run of a column's voxel → patch map: voxels `lo ..= hi` belong to `patch`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PatchRun {
    /// First voxel.
    pub lo: Depth,
    /// Last voxel.
    pub hi: Depth,
    /// Their patch.
    pub patch: PatchId,
}

/// The patches of a column's occupied voxels, as sorted disjoint runs (at most `R`), loaded by
/// the host with the patches. Invariant: runs sorted by `lo`, disjoint; a run that does not fit
/// is counted in [`PatchRuns::overflows`] and its voxels have no patch.
#[derive(Clone, Debug, Default)]
pub struct PatchRuns<const R: usize> {
    runs: Vec<PatchRun, R>,
    overflows: u32,
}

impl<const R: usize> PatchRuns<R> {
    /// No runs.
    pub const fn new() -> Self {
        PatchRuns { runs: Vec::new(), overflows: 0 }
    }

    /// Append voxel `z` of `patch` (voxels come in increasing z): extends the last run when it
    /// is the same patch and adjacent. Returns `false` (counted) when a new run does not fit,
    /// or `z` is not above the last run (ignored, counted).
    pub fn push(&mut self, z: Depth, patch: PatchId) -> bool {
        if let Some(last) = self.runs.last_mut() {
            if z <= last.hi {
                self.overflows += 1;
                return false;
            }
            if last.patch == patch && last.hi + 1 == z {
                last.hi = z;
                return true;
            }
        }
        if self.runs.push(PatchRun { lo: z, hi: z, patch }).is_err() {
            self.overflows += 1;
            return false;
        }
        true
    }

    /// The patch of voxel `z`, if mapped.
    pub fn patch_at(&self, z: Depth) -> Option<PatchId> {
        let i = self.runs.partition_point(|r| r.hi < z);
        self.runs.get(i).filter(|r| r.lo <= z).map(|r| r.patch)
    }

    /// The runs.
    pub fn runs(&self) -> &[PatchRun] {
        &self.runs
    }

    /// Runs (or voxels) that did not fit.
    pub const fn overflows(&self) -> u32 {
        self.overflows
    }
}

/// What one cell's column received during a shot: quanta per patch (at most `A` patches), sorted
/// by patch id (the order of the reduction's streams). Quanta for a patch that finds no slot,
/// or for a voxel with no patch, go to [`Received::lost`] and are counted: the balance of the
/// shot still closes.
#[derive(Clone, Debug, Default)]
pub struct Received<const A: usize> {
    entries: Vec<(PatchId, i64), A>,
    lost: i64,
    overflows: u32,
}

impl<const A: usize> Received<A> {
    /// Nothing received.
    pub const fn new() -> Self {
        Received { entries: Vec::new(), lost: 0, overflows: 0 }
    }

    /// Add `q` quanta to `patch` (`None`: a voxel with no patch, counted as lost).
    ///
    /// ```
    /// use cell_core::radiosity::Received;
    /// let mut r = Received::<2>::new();
    /// assert!(r.add(Some(7), 5) && r.add(Some(3), 1) && r.add(Some(7), 2));
    /// assert_eq!(r.entries(), &[(3, 1), (7, 7)]);
    /// assert!(!r.add(Some(9), 4), "full: counted, not silent");
    /// assert_eq!((r.lost(), r.overflows(), r.total()), (4, 1, 12));
    /// ```
    pub fn add(&mut self, patch: Option<PatchId>, q: i64) -> bool {
        let Some(p) = patch else {
            self.lost += q;
            self.overflows += 1;
            return false;
        };
        let i = self.entries.partition_point(|e| e.0 < p);
        if let Some(e) = self.entries.get_mut(i).filter(|e| e.0 == p) {
            e.1 += q;
            return true;
        }
        if self.entries.insert(i, (p, q)).is_err() {
            self.lost += q;
            self.overflows += 1;
            return false;
        }
        true
    }

    /// The (patch, quanta) entries, by increasing patch id.
    pub fn entries(&self) -> &[(PatchId, i64)] {
        &self.entries
    }

    /// Quanta that found no slot or no patch.
    pub const fn lost(&self) -> i64 {
        self.lost
    }

    /// Additions that found no slot or no patch.
    pub const fn overflows(&self) -> u32 {
        self.overflows
    }

    /// All quanta received, lost ones included.
    pub fn total(&self) -> i64 {
        self.entries.iter().map(|e| e.1).sum::<i64>() + self.lost
    }

    /// Empty it for the next shot (after the reduction has read it).
    pub fn clear(&mut self) {
        self.entries.clear();
        self.lost = 0;
    }
}

/// What a cell keeps to show indirect light (radiosity thesis §1.3.1, "Visualisation de la
/// scène"): the broadcast records it listens for — its visible patch's value (flat display), or
/// its patch's vertex values (smooth: Gouraud's double linear interpolation, §1.1.2) — each with
/// the weight of its pixel's visible point (loaded by the host with the patch runs), and their
/// weighted sum, the irradiance the cell shades with in place of the empirical ambient source of
/// §1.1.1. At most `K` keys; one that does not fit is refused (`listen` returns `false`).
///
/// **Bit budget.** A key is 16 bits (at most 65 536 records: patches or vertices, checked by the
/// host before loading). A weight is an `f32` in [0, 1] and a cell's weights sum to 1; a record
/// is three non-negative `f32` (the supervisor's exposed irradiance, the shading's own unit, as
/// the point lights' intensities). The sum is at most `K` products and `K` additions per
/// channel, each rounded once: a relative error of at most about `2K` ulp (4.8·10⁻⁷ for
/// `K` = 4), three orders below the half level (1/510) of the 8-bit pixel it shades. Memory:
/// `2K + 4K + 1 + 12` bytes, aligned: 20 for `K` = 1 (flat display), 40 for `K` = 4 (smooth).
///
/// ```
/// use cell_core::radiosity::IndirectPixel;
/// let mut px = IndirectPixel::<4>::new();
/// assert!(px.listen(7, 0.25) && px.listen(9, 0.75));
/// px.hear(3, [8.0; 3]); // not its record
/// px.hear(7, [1.0, 2.0, 4.0]);
/// px.hear(9, [1.0, 2.0, 0.0]);
/// assert_eq!(px.rgb(), [1.0, 2.0, 1.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndirectPixel<const K: usize> {
    keys: [u16; K],
    weights: [f32; K],
    len: u8,
    rgb: [f32; 3],
}

impl<const K: usize> Default for IndirectPixel<K> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const K: usize> IndirectPixel<K> {
    /// Listening for nothing; the sum is zero.
    pub const fn new() -> Self {
        IndirectPixel { keys: [0; K], weights: [0.0; K], len: 0, rgb: [0.0; 3] }
    }

    /// Listen for record `key`, weighted `weight`. `false` when `K` keys are already taken.
    pub fn listen(&mut self, key: u16, weight: f32) -> bool {
        let i = self.len as usize;
        if i >= K || i >= u8::MAX as usize {
            return false;
        }
        self.keys[i] = key;
        self.weights[i] = weight;
        self.len += 1;
        true
    }

    /// A broadcast record passes: add its value, weighted, for every slot listening for it.
    pub fn hear(&mut self, key: u16, value: [f32; 3]) {
        for (k, w) in self.keys[..self.len as usize].iter().zip(&self.weights) {
            if *k == key {
                for (c, v) in self.rgb.iter_mut().zip(value) {
                    *c += w * v;
                }
            }
        }
    }

    /// The keys listened for.
    pub fn keys(&self) -> &[u16] {
        &self.keys[..self.len as usize]
    }

    /// The weighted sum of the records heard.
    pub const fn rgb(&self) -> [f32; 3] {
        self.rgb
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::beam::{frac, Source, SourceId, Transverse};
    use proptest::prelude::*;

    fn unit(v: [f64; 3]) -> V {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| (c / l) as f32)
    }

    /// The point form factor of the axis-aligned rectangle [x0,x1]×[y0,y1] at height c, seen
    /// from a point below it facing it (Howell B-3 by superposition), in f64.
    fn parallel_rect(x0: f64, x1: f64, y0: f64, y1: f64, c: f64) -> f64 {
        let g = |x: f64, y: f64| {
            let (a, b) = (x / c, y / c);
            (1.0 / (2.0 * std::f64::consts::PI))
                * (a / (1.0 + a * a).sqrt() * (b / (1.0 + a * a).sqrt()).atan()
                    + b / (1.0 + b * b).sqrt() * (a / (1.0 + b * b).sqrt()).atan())
        };
        let s = |x: f64, y: f64| x.signum() * y.signum() * g(x.abs(), y.abs());
        s(x1, y1) - s(x0, y1) - s(x1, y0) + s(x0, y0)
    }

    #[test]
    fn the_corner_function_matches_the_closed_form() {
        let n = [0.0, 0.0, 1.0];
        for &(a, b) in &[(0.0f64, 0.0f64), (3.5, -2.5), (15.0, 15.0), (-14.5, 7.0)] {
            let q = corner_quanta(n, Direction::PosZ, 15, 0, (a * 2.0) as i64, (b * 2.0) as i64);
            let want = parallel_rect(-15.0, a, -15.0, b, 15.0);
            assert!((q as f64 / FORM_FACTOR_ONE as f64 - want).abs() < 2e-6, "({a}, {b}): {q} vs {want}");
        }
    }

    #[test]
    fn a_tilted_patch_sends_all_its_power_into_the_six_faces() {
        let far = FarDistance::<frac::U2>::new(31).unwrap();
        let s = Source::at_voxel(SourceId(0), [40, 40, 40]).unwrap();
        for n in [[1.0, 2.0, 3.0], [-0.3, 0.1, -0.9], [0.0, 1.0, 0.0], [1.0, -1.0, 0.0]] {
            let n = unit(n);
            let (mut all, mut front) = (0i64, 0i64);
            for d in Direction::ALL {
                all += beam_quanta(n, &Beam::initial(&s, d, far), far);
                if let Some((u, v)) = front_rays(n, d, far) {
                    let b = Beam::new(SourceId(0), d, crate::beam::Layer(0), u, v, far).unwrap();
                    front += beam_quanta(n, &b, far);
                }
            }
            // A corner value is an f32 below 2^30: one ulp is at most 2^6 quanta, so a beam's
            // quanta are good to 4 · 2^6, six faces to 6 · 4 · 2^6 (module doc, bit budget).
            let ulps = 6 * 4 * 64;
            assert!((all - FORM_FACTOR_ONE).abs() <= ulps, "{n:?}: {all}");
            assert!((front - all).abs() <= ulps, "{n:?}: the rays left out carry only rounding: {front} vs {all}");
        }
    }

    proptest! {
        /// Every split conserves quanta exactly (the corners telescope), whatever the normal.
        #[test]
        fn splits_conserve_quanta(nx in -1.0f64..1.0, ny in -1.0f64..1.0, nz in -1.0f64..1.0, d in 0usize..6,
                                  steps in proptest::collection::vec(0usize..9, 1..6)) {
            prop_assume!(nx * nx + ny * ny + nz * nz > 0.01);
            let n = unit([nx, ny, nz]);
            let far = FarDistance::<frac::U1>::new(12).unwrap();
            let s = Source::at_voxel(SourceId(0), [20, 20, 20]).unwrap();
            let dir = Direction::ALL[d];
            let mut beam = Beam::initial(&s, dir, far);
            let mut at = dir.transverse_of(s.voxel());
            for pick in steps {
                let subs = match beam.split(&s, far, at) { Ok(x) => x, Err(_) => break };
                let sum: i64 = subs.iter().map(|sb| beam_quanta(n, &sb.beam, far)).sum();
                prop_assert_eq!(sum, beam_quanta(n, &beam, far));
                let sb = subs[pick % subs.len()];
                beam = sb.beam;
                at = Transverse { u: at.u + sb.offset.du as i32, v: at.v + sb.offset.dv as i32 };
            }
        }
    }

    #[test]
    fn patch_runs_map_voxels_and_count_overflow() {
        let mut r = PatchRuns::<2>::new();
        assert!(r.push(3, 1) && r.push(4, 1) && r.push(6, 2));
        assert!(!r.push(7, 3), "a third run does not fit");
        assert!(!r.push(5, 3), "not increasing");
        assert_eq!(
            (r.patch_at(3), r.patch_at(4), r.patch_at(5), r.patch_at(6), r.patch_at(7)),
            (Some(1), Some(1), None, Some(2), None)
        );
        assert_eq!(r.overflows(), 2);
    }

    /// The documented memory and error bound of `IndirectPixel`: a full pixel refuses a fifth
    /// key, and its sum stays within 2K ulp (relative) of the f64 sum for any convex weights.
    #[test]
    fn indirect_pixels_hold_what_their_budget_says() {
        assert_eq!(core::mem::size_of::<IndirectPixel<1>>(), 20);
        assert_eq!(core::mem::size_of::<IndirectPixel<4>>(), 40);
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        for _ in 0..1000 {
            let raw = [next(), next(), next(), next()];
            let total: f32 = raw.iter().sum::<f32>().max(f32::MIN_POSITIVE);
            let mut px = IndirectPixel::<4>::new();
            let values: [[f32; 3]; 4] = core::array::from_fn(|_| [next() * 8.0, next(), next() * 1e-3]);
            for (k, w) in raw.iter().enumerate() {
                assert!(px.listen(k as u16, w / total));
            }
            assert!(!px.listen(9, 0.0), "a fifth key does not fit");
            for (k, v) in values.iter().enumerate() {
                px.hear(k as u16, *v);
            }
            for c in 0..3 {
                let exact: f64 = raw.iter().zip(&values).map(|(w, v)| f64::from(w / total) * f64::from(v[c])).sum();
                let got = f64::from(px.rgb()[c]);
                assert!(
                    (got - exact).abs() <= 8.0 * f64::from(f32::EPSILON) * exact.max(f64::MIN_POSITIVE),
                    "{got} vs {exact}"
                );
            }
        }
    }
}
