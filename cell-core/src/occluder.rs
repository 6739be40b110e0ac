//! §5.5.6 — exact occluders: the triangles through a cell's column, and which rays of a beam
//! they stop.
//!
//! **Invariant: a ray is stopped by a triangle in exactly the one segment of its walk where it
//! crosses the triangle's plane inside the (closed) triangle, decided in exact integer
//! arithmetic; the decision is a conjunction of half-planes of the beam's (u, v) lattice, so a
//! beam can be cut by it like by the plane rule's tests ([`crate::lit`]).**
//!
//! # Why
//!
//! The plane rule ([`crate::lit`]) stops a ray where it crosses the plane a voxel stores. Its
//! remaining error is at shadow edges, where three half-voxel biases meet: the receiver (any
//! lattice ray through a pixel's two bracketing voxels lights it), the occluder (a voxel's plane
//! extends past its facet, so rays passing beside an edge are stopped) and the source (the
//! machine's rays leave from the source voxel's centre plane, up to half a voxel from the light).
//! Measured on the per-ray oracle's walk (`tests/examples/lit_bounds.rs`, docs/LIGHTING.md),
//! replacing the rule's stops by the triangles a ray's segment meets is what the occluder side
//! needs, and it is *local*: testing segment [k − 1, k] only against the triangles through the
//! columns of the ray's voxels at layers k − 1 and k gives the same images as testing the whole
//! mesh (to a pixel on teapot-floor and cow-floor at n = 128 and 256 and on bureau1 at 256). So
//! a cell keeps the triangles that pass through its column
//! ([`Triangle::crosses_column`], [`TriangleStore`]) and cuts beams by them (this module).
//!
//! # Geometry
//!
//! Coordinates are in sixteenths of a voxel (the loading lattice of [`crate::voxelize`] and the
//! source lattice of [`crate::beam`]), voxel centres at multiples of 16. The rays of one source
//! and [`Direction`] (w, sign s, transverse u, v) leave from an origin O
//! ([`Source::ray_origin`]): the light's transverse coordinates, and along w either the source
//! voxel's centre (the thesis's rays, [`crate::beam`]'s `⌊x_s + u·k/D + ½⌋`) or the light itself
//! ([`crate::beam::Origin::Light`]). With its lead ([`Source::lead`]: 0, or in [0, 16) from the last centre
//! plane at or behind the light) the point of lattice ray (a, b) (offsets in steps of 2^−f,
//! N = D·2^f) at layer t's centre plane lies `T = 16·t − lead` sixteenths from O along w:
//!
//! ```text
//!   16·p(T) = O + (T/N)·d(a, b),      d = s·N·e_w + a·e_u + b·e_v
//! ```
//!
//! The segment of layer k is `T ∈ [T(k − 1), T(k)]`, clamped at O (`T ≥ 0`): at k = 0 it is the
//! the origin itself (layer 0's rays are all at O).
//!
//! A triangle (V₀, V₁, V₂) with normal n = (V₁ − V₀) × (V₂ − V₀) stops ray (a, b) at layer k iff
//!
//! 1. the ray's line passes through it on the forward side of O: with
//!    `E_ij = ((V_i − O) × (V_j − O))·d` for the edges (0, 1), (1, 2), (2, 0) and
//!    `Δ = det(V₀ − O, V₁ − O, V₂ − O)`, all three `Δ·E_ij ≥ 0` (d = α(V₀ − O) + β(V₁ − O) +
//!    γ(V₂ − O) and `E₁₂ = α·Δ`, `E₂₀ = β·Δ`, `E₀₁ = γ·Δ`: the closed triangle, edges and
//!    vertices included, so two triangles sharing an edge leave no crack between them);
//! 2. it crosses the plane in this segment: σ(T) = [n·(16·p(T) − V₀) > 0] differs at the two
//!    ends. σ changes once along a ray, so each crossing belongs to exactly one segment: where
//!    σ turns false at the first T with g ≤ 0, where it turns true at the first T with g > 0
//!    (a ray touching the plane at a segment's end is stopped in one of the two segments, never
//!    both, never neither).
//!
//! A triangle seen edge-on from O (Δ = 0) or of zero area stops no ray (its forward cone is
//! empty): [`Occluder::new`] returns `None`.
//!
//! Each condition is the sign of an affine function of (a, b) for a fixed layer: five
//! [`Test`]s ([`Occluder::tests`]) — the three edges (`2·sgn(Δ)·E_ij + 1 > 0`, i.e.
//! `sgn(Δ)·E_ij ≥ 0`, read at layer 1 where T > 0) and the plane at layers k − 1 and k — read by the same
//! [`crate::lit::segments`], [`crate::lit::uniform`] and [`crate::lit::run_end`] that cut beams
//! under the plane rule; [`Occluder::stops`] turns their bits into the verdict.
//!
//! # Bit budget
//!
//! All coordinates (vertices, origin) satisfy `|c| ≤ COORD_LIMIT = 2²³` sixteenths (2¹⁹ voxels,
//! eight times [`crate::units::MAX_N`]): differences ≤ 2²⁴, n and the edge cross products
//! ≤ 2·2⁴⁸ = 2⁴⁹ per component. With N ≤ 2³¹ − 1, |a|, |b| ≤ N and T ≤ 16·(D + 1) ≤ 2³¹
//! ([`FarDistance`]'s limits):
//!
//! | quantity | bound |
//! |---|---|
//! | plane `K₀ = N·n·(O − V₀)` | 3·2⁴⁹·2³¹·2²⁴ < 2¹⁰⁶ |
//! | plane slope `n·d` | 3·2⁴⁹·2³¹ < 2⁸² |
//! | plane value `K₀ + T·n·d` | < 2¹⁰⁶ + 2³¹·2⁸² < 2¹¹⁴ |
//! | edge `2·E + 1`, times T | < 2⁸³ · 2³¹ = 2¹¹⁴ |
//!
//! all below 2¹²⁷: `i128`, exact. [`Triangle::crosses_column`] works in `i64` (2D cross products
//! of differences ≤ 2²⁴: < 2⁵⁰). The tests evaluate every term at these limits with overflow
//! checks on.
//!
//! # Sizes
//!
//! A [`Triangle`] is 36 bytes (nine `i32`); a [`TriangleStore<N>`] is 36·N + 8 on the MCU.
//! [`Triangle::crosses_column`] keeps 1.4–2.4 triangles per column on average on teapot-floor
//! and cow-floor at n = 128–512, 5–9 on the fandisk, 4–11 on bureau1, up to 206 in a column
//! along a dense silhouette; a store of 64 loses little on them (BENCHMARKS, "What the cell's
//! own arithmetic gives").
//!
//! # Example
//!
//! ```
//! use cell_core::beam::{frac, Direction, FarDistance, Source, SourceId};
//! use cell_core::occluder::{Occluder, Triangle, TriangleStore};
//!
//! // A light at the centre of voxel (0, 0, 0); a triangle across the +z axis at z = 4.5.
//! let source = Source::at_voxel(SourceId(0), [0, 0, 0]).unwrap();
//! let far = FarDistance::<frac::U0>::new(8).unwrap();
//! let tri = Triangle::new([[-32, -32, 72], [32, -32, 72], [0, 32, 72]]).unwrap();
//! // Column (0, 0) keeps it, column (3, 0) does not.
//! let mut store = TriangleStore::<4>::new();
//! assert!(tri.crosses_column(0, 0) && !tri.crosses_column(3, 0));
//! assert!(store.push(tri));
//! let occ = Occluder::new(&tri, &source, Direction::PosZ, far).unwrap();
//! // The axis ray crosses z = 4.5 between layers 4 and 5: stopped in layer 5's segment only.
//! assert!(occ.meets(0, 0, 5) && !occ.meets(0, 0, 4) && !occ.meets(0, 0, 6));
//! // Ray (8, 0) is at x = 4.5 there, beside the triangle: never stopped.
//! assert!(!(0..=8).any(|k| occ.meets(8, 0, k)));
//! ```

use crate::beam::{Direction, FarDistance, FracBits, Source};
use crate::lit::{Along, Narrow, RayPlane, Segments, Test};
use crate::triangle::{cross64, dot, sub};
pub use crate::triangle::{Triangle, COORD_LIMIT};
use heapless::Vec;

/// One triangle seen along the rays of one source, direction and origin: the five tests and
/// the verdict of the module doc.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Occluder {
    plane: RayPlane,
    edges: [RayPlane; 3],
}

/// The rays of one source and direction as [`Seen`] and [`Occluder`] read them: their origin,
/// the direction's axes and sign, N and the origin's lead.
#[derive(Clone, Copy, Debug)]
struct View {
    o: [i64; 3],
    axes: (usize, usize, usize),
    sign: i128,
    nn: i128,
    lead: i64,
    /// The largest ray parameter a visit reads, 16·(D + 1) ([`RayPlane::narrow`]).
    t_max: i64,
}

impl View {
    /// `source`'s rays in `dir`; `None` if their origin lies outside [`COORD_LIMIT`].
    fn new<F: FracBits>(source: &Source, dir: Direction, far: FarDistance<F>) -> Option<View> {
        let w = dir.principal().index();
        let (u, v) = dir.transverse();
        let (o, lead) = (source.ray_origin(dir), source.lead(dir));
        if o.iter().any(|c| c.abs() > COORD_LIMIT) {
            return None;
        }
        let (sign, nn) = (dir.sign() as i128, far.scaled() as i128);
        let t_max = 16 * (far.get() as i64 + 1);
        Some(View { o, axes: (w, u.index(), v.index()), sign, nn, lead, t_max })
    }
}

/// A triangle's plane seen along the rays of one source and direction, before its edges: what
/// [`ExactVisit`] reads first, since most triangles of a column are decided by the plane alone
/// (no ray crosses it near the beam) and need no edge. It depends on the triangle, the source
/// and the direction only, so a host may compute it once per source ([`SeenTable`],
/// [`SeenEntry`]) instead of once per beam; a cell computes it where it needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Seen {
    plane: RayPlane,
    /// The plane in `i64`, when its values fit for every ray and layer of the far distance.
    narrow: Option<Narrow>,
    /// The edges' orientation (sgn Δ).
    orient: i8,
}

impl Seen {
    /// The plane of `tri` along the rays of `view`; `None` as for [`Occluder::new`].
    fn new(tri: &Triangle, view: &View) -> Option<Seen> {
        let (w, u, v) = view.axes;
        let n = tri.normal();
        let k0 = view.nn * dot(n, sub(view.o, tri.vertex(0)));
        // Δ = n·(V₀ − O) = −K₀/N: its sign orients the edge tests.
        if k0 == 0 {
            return None;
        }
        let orient = if k0 < 0 { 1 } else { -1 };
        let plane = RayPlane::from_coefficients(k0, n[w] * view.sign * view.nn, n[u], n[v], view.lead);
        let narrow = plane.narrow(view.nn as i64, view.t_max);
        Some(Seen { plane, narrow, orient })
    }

    /// The whole occluder: the plane and the three edges.
    fn occluder(&self, tri: &Triangle, view: &View) -> Occluder {
        Occluder { plane: self.plane, edges: [0, 1, 2].map(|j| self.edge(tri, view, j)) }
    }

    /// Edge j of the occluder ((V₀, V₁), (V₁, V₂), (V₂, V₀) for j = 0, 1, 2).
    #[inline]
    fn edge(&self, tri: &Triangle, view: &View, j: usize) -> RayPlane {
        let (kw, cb, cg) = self.edge_form(tri, view, j);
        RayPlane::from_coefficients(0, kw, cb as i128, cg as i128, view.lead)
    }

    /// Edge j's form `kw + cb·a + cg·b` (its plane has k0 = 0: the test at t = 1 holds iff
    /// T = max(16 − lead, 0) > 0 and the form is positive), with |cb|, |cg| < 2⁵¹.
    #[inline]
    fn edge_form(&self, tri: &Triangle, view: &View, j: usize) -> (i128, i64, i64) {
        let (w, u, v) = view.axes;
        // Differences ≤ 2²⁴ and their cross products ≤ 2⁴⁹ (the module doc's bit budget), times
        // 2·sgn Δ·s ≤ 2⁵¹: `i64`; only the product with N needs `i128`, one widening multiply.
        // Written out, not as array maps: the host's compiler kept nested maps out of line, and
        // building edges was a fifth of a dense scene's time.
        let vs = tri.vertices();
        let rel = |i: usize| {
            let p = vs[i];
            [p[0] as i64 - view.o[0], p[1] as i64 - view.o[1], p[2] as i64 - view.o[2]]
        };
        let m = cross64(rel(j), rel((j + 1) % 3));
        let o = 2 * self.orient as i64;
        ((o * m[w] * view.sign as i64) as i128 * view.nn + 1, o * m[u], o * m[v])
    }

    /// Edge j's test ([`Occluder::tests`], at t = 1) where it is constant on the rectangle
    /// `a × b`: its value there, else `None`. The form is affine in (a, b), so it keeps one
    /// sign on the rectangle iff its least and greatest values there do (4 products, in `i128`:
    /// < 2⁸⁴ by the module doc's budget), and no edge needs building to know it.
    #[inline]
    fn edge_on(&self, tri: &Triangle, view: &View, j: usize, (a, b): ((i64, i64), (i64, i64))) -> Option<bool> {
        if 16 - view.lead <= 0 {
            return Some(false); // T = 0 at t = 1: the value is 0, the test holds nowhere
        }
        let (kw, cb, cg) = self.edge_form(tri, view, j);
        let (p0, p1) = (cb as i128 * a.0 as i128, cb as i128 * a.1 as i128);
        let (q0, q1) = (cg as i128 * b.0 as i128, cg as i128 * b.1 as i128);
        let (lo, hi) = (kw + p0.min(p1) + q0.min(q1), kw + p0.max(p1) + q0.max(q1));
        ((lo > 0) == (hi > 0)).then_some(lo > 0)
    }
}

/// A triangle's [`Seen`] as a host's table keeps it (40 bytes, a quarter of one): the plane's
/// coefficients when they fit `i64` under the far distance (`RayPlane::narrow`, then the
/// visit rebuilds the same `Seen` from them), else a mark that the visit computes it, or that
/// the triangle stops no ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SeenEntry {
    /// `[k0, kw, cb, cg]` (narrow entries).
    k: [i64; 4],
    /// ±1: a narrow entry, the edges' orientation; 0: stops no ray; 2: computed by the visit.
    orient: i8,
}

impl SeenEntry {
    const NONE: SeenEntry = SeenEntry { k: [0; 4], orient: 0 };
    const WIDE: SeenEntry = SeenEntry { k: [0; 4], orient: 2 };

    /// The entry of `tri` along `source`'s rays in `dir` at far distance `far`.
    pub fn of<F: FracBits>(tri: &Triangle, source: &Source, dir: Direction, far: FarDistance<F>) -> SeenEntry {
        Self::from_seen(View::new(source, dir, far).and_then(|view| Seen::new(tri, &view)))
    }

    fn from_seen(seen: Option<Seen>) -> SeenEntry {
        match seen {
            None => SeenEntry::NONE,
            Some(Seen { narrow: Some(n), orient, .. }) => SeenEntry { k: n.coefficients(), orient },
            Some(_) => SeenEntry::WIDE,
        }
    }

    /// The entry's plane in `i64` along the rays of `view`, without the `Seen` around it: `None`
    /// unless the entry is narrow.
    #[inline]
    fn narrow(&self, view: &View) -> Option<Narrow> {
        matches!(self.orient, 1 | -1).then(|| Narrow::of(self.k, view.lead, view.nn as i64))
    }

    /// The `Seen` of `tri` along the rays of `view` (the entry's triangle, source and direction).
    #[inline]
    fn seen(&self, tri: &Triangle, view: &View) -> Option<Seen> {
        match self.orient {
            0 => None,
            2 => Seen::new(tri, view),
            orient => {
                let (plane, narrow) = Narrow::rebuild(self.k, view.lead, view.nn as i64);
                Some(Seen { plane, narrow: Some(narrow), orient })
            }
        }
    }
}

/// One source's rays in each of the six directions, for a host filling a table of
/// [`SeenEntry`]s: [`SeenEntry::of`] with the rays' origin and lead found once per source and
/// direction, not once per triangle.
#[derive(Clone, Copy, Debug)]
pub struct SourceViews([Option<View>; 6]);

impl SourceViews {
    /// The views of `source`'s rays at far distance `far`.
    pub fn new<F: FracBits>(source: &Source, far: FarDistance<F>) -> Self {
        SourceViews(Direction::ALL.map(|d| View::new(source, d, far)))
    }

    /// `tri`'s entry in direction `dir`: [`SeenEntry::of`].
    #[inline]
    pub fn entry(&self, tri: &Triangle, dir: Direction) -> SeenEntry {
        SeenEntry::from_seen(self.0[dir.index() as usize].as_ref().and_then(|view| Seen::new(tri, view)))
    }
}

/// The planes of a column's triangles, computed once per source by a host that holds every
/// column ([`ColumnOccluders::seen`]): triangle i of the column in direction `dir` is
/// [`SeenTable::entry`], `seen[dir.index() · distinct + ids[i]]`. The visit reads the same
/// [`Seen`] it would compute, so the verdicts are the same.
#[derive(Clone, Copy, Debug)]
pub struct SeenTable<'a> {
    /// Per triangle of the column, its distinct triangle's number.
    pub ids: &'a [u32],
    /// Per direction ([`Direction::index`] order), then per distinct triangle, its plane under
    /// the current source and far distance. Direction first: a beam reads one direction, and
    /// the neighbours of a triangle in the mesh, often in the same column, share its cache line
    /// (triangle first, a row of six entries was a cache miss per triangle on dense scenes).
    pub seen: &'a [SeenEntry],
    /// Distinct triangles (the length of one direction's part of `seen`).
    pub distinct: usize,
}

impl SeenTable<'_> {
    /// The entry of the column's triangle i in direction `dir`.
    #[inline]
    pub fn entry(&self, i: usize, dir: Direction) -> &SeenEntry {
        &self.seen[dir.index() as usize * self.distinct + self.ids[i] as usize]
    }
}

/// Bits of [`Occluder::tests`] that must all hold (the three edges).
const EDGE_BITS: u64 = 0b111;

impl Occluder {
    /// The occluder of `tri` for rays of `source` in `dir` from `origin`; `None` if the
    /// triangle stops no ray (zero area, or seen edge-on from the origin) or the origin lies
    /// outside [`COORD_LIMIT`].
    pub fn new<F: FracBits>(tri: &Triangle, source: &Source, dir: Direction, far: FarDistance<F>) -> Option<Occluder> {
        let view = View::new(source, dir, far)?;
        Seen::new(tri, &view).map(|seen| seen.occluder(tri, &view))
    }

    /// The five tests at layer k, in the order [`Occluder::stops`] reads their bits: the three
    /// edges, then the plane's σ at the segment's two ends (layers k − 1 and k; layer −1 reads
    /// as the origin).
    pub fn tests(&self, k: i64) -> [Test; 5] {
        let e = |i: usize| Test { plane: self.edges[i], t: 1 };
        [e(0), e(1), e(2), Test { plane: self.plane, t: k - 1 }, Test { plane: self.plane, t: k }]
    }

    /// Whether rays with test bits `bits` (bit i: test i of [`Occluder::tests`] holds) are
    /// stopped: inside every edge, and σ differs at the segment's ends.
    pub const fn stops(bits: u64) -> bool {
        bits & EDGE_BITS == EDGE_BITS && (bits >> 3 & 1) != (bits >> 4 & 1)
    }

    /// The seven tests of [`ExactVisit`] at layer k: the three edges, then σ at k − 1, k, k + 1
    /// and at `t1` (the notch's start).
    fn exact_tests(&self, k: i64, t1: i64) -> [Test; PER_TRIANGLE] {
        let [e0, e1, e2, prev, now] = self.tests(k);
        let at = |t: i64| Test { plane: self.plane, t };
        [e0, e1, e2, prev, now, at(k + 1), at(t1)]
    }

    /// Whether ray (a, b) is stopped by the triangle in layer k's segment.
    pub fn meets(&self, a: i64, b: i64, k: i64) -> bool {
        let bits = self.tests(k).iter().enumerate().fold(0u64, |m, (i, t)| m | ((t.holds(a, b) as u64) << i));
        Self::stops(bits)
    }
}

/// The triangles through one column, at most `N`; a triangle that does not fit is counted, never
/// silently dropped.
#[derive(Clone, Debug, Default)]
pub struct TriangleStore<const N: usize> {
    triangles: Vec<Triangle, N>,
    overflows: u32,
}

impl<const N: usize> TriangleStore<N> {
    /// An empty store.
    pub const fn new() -> Self {
        TriangleStore { triangles: Vec::new(), overflows: 0 }
    }

    /// Keep `tri`; false (and counted) when the store is full.
    pub fn push(&mut self, tri: Triangle) -> bool {
        if self.triangles.push(tri).is_ok() {
            true
        } else {
            self.overflows = self.overflows.saturating_add(1);
            false
        }
    }

    /// The triangles kept, in arrival order.
    pub fn triangles(&self) -> &[Triangle] {
        &self.triangles
    }

    /// Triangles that did not fit.
    pub fn overflows(&self) -> u32 {
        self.overflows
    }
}

/// What the cells know under the exact-occluder rule ([`crate::lit::LitRule::Exact`]), column
/// by column: the triangles each keeps ([`Triangle::crosses_column`], loaded with its facets)
/// and its target ray for the source being diffused ([`crate::receiver::target`], computed
/// once per source from the column's visible surface). A firmware cell answers for itself from
/// its [`TriangleStore`]; a host holds all columns at once.
///
/// Not `Debug` itself: a supertrait would put its `fmt` in every vtable, and with it the
/// formatting machinery in a firmware image; `dyn ColumnOccluders` has a short `Debug` of its
/// own (below) for the host's `LightEnv`.
pub trait ColumnOccluders: Sync {
    /// The triangles column (x, y) keeps.
    fn triangles(&self, x: crate::units::Coord, y: crate::units::Coord) -> &[Triangle];
    /// Column (x, y)'s target ray for the current source (`None`: no ray lights its pixel).
    fn target(&self, x: crate::units::Coord, y: crate::units::Coord) -> Option<&crate::receiver::Target>;
    /// The planes of column (x, y)'s triangles under the current source, if precomputed
    /// (`None`: the visit computes each where it needs it, as a cell does).
    fn seen(&self, _x: crate::units::Coord, _y: crate::units::Coord) -> Option<SeenTable<'_>> {
        None
    }
    /// Column (x, y)'s target voxel for the current source, where it counts its candidate rays
    /// (`None`: it does not count them, [`crate::visibility::Visibility::Target`]).
    fn target_voxel(
        &self,
        _x: crate::units::Coord,
        _y: crate::units::Coord,
    ) -> Option<&crate::visibility::TargetVoxel> {
        None
    }
    /// Column (x, y)'s cell took `rays` more candidate rays to its target voxel (one processed
    /// beam's, [`crate::visibility::TargetVoxel::count`]): added to what its target voxel
    /// received for the current source. Called only for a column with a target voxel.
    fn arrived(&self, _x: crate::units::Coord, _y: crate::units::Coord, _rays: u64) {}
    /// Everything column (x, y) holds for the exact visit of a beam at voxel depth `z`, in one
    /// call (a host looks the column up once per beam, not once per item): its target ray only
    /// if that ray's voxel is at `z`. The default gathers the methods above, without near
    /// windows.
    fn column(&self, x: crate::units::Coord, y: crate::units::Coord, z: crate::units::Depth) -> Column<'_> {
        let target = self.target(x, y).filter(|t| t.z == z as i64);
        let voxel = self.target_voxel(x, y).filter(|t| t.z == z as i64);
        Column { triangles: self.triangles(x, y), seen: self.seen(x, y), target, voxel, near: None }
    }
    /// A hint that column (x, y) is visited soon (a host holding every column may start loading
    /// its data); no effect on any result.
    fn prefetch(&self, _x: crate::units::Coord, _y: crate::units::Coord) {}
}

impl core::fmt::Debug for dyn ColumnOccluders + '_ {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("ColumnOccluders")
    }
}

/// One column as the exact visit reads it ([`ColumnOccluders::column`]).
#[derive(Clone, Copy, Debug)]
pub struct Column<'a> {
    /// The triangles it keeps.
    pub triangles: &'a [Triangle],
    /// Their planes under the current source, if precomputed.
    pub seen: Option<SeenTable<'a>>,
    /// Its target ray for the current source, if it ends at the visited depth.
    pub target: Option<&'a crate::receiver::Target>,
    /// Its target voxel, if it counts candidate rays and that voxel is at the visited depth.
    pub voxel: Option<&'a crate::visibility::TargetVoxel>,
    /// Beside each triangle, its [`NearWindows`], if the host computed them (`None`: every
    /// triangle is tested, as a cell does).
    pub near: Option<&'a [NearWindows]>,
}

/// A triangle's depth window in its column ([`near_voxels`]), clamped to the column's depths:
/// `[lo, hi]`, inclusive, empty when lo > hi. 4 bytes beside each triangle a column keeps.
pub type NearWindows = [crate::units::Depth; 2];

impl Column<'_> {
    /// Which triangles a beam at voxel depth `z` may cut, when it is at layer 2 or later and
    /// carries no notch: bit i for triangle i ([`ALL_CANDIDATES`] without windows, or for a
    /// column of more than 64 triangles). A triangle left out is one [`ExactVisit`] would find
    /// uncrossed, so the visit is the same without it.
    pub fn candidates(&self, z: crate::units::Depth) -> u64 {
        let Some(windows) = self.near.filter(|w| w.len() <= 64) else { return ALL_CANDIDATES };
        windows.iter().enumerate().fold(0u64, |m, (i, w)| m | u64::from(w[0] <= z && z <= w[1]) << i)
    }
}

/// The [`NearWindows`] of `tri` in column (x, y) of a grid whose columns hold depths
/// `0 ..= max_depth`.
pub fn near_windows(tri: &Triangle, x: i32, y: i32, max_depth: crate::units::Depth) -> NearWindows {
    let (lo, hi) = near_voxels(tri, x, y);
    let (lo, hi) = (lo.max(0), hi.min(max_depth as i64));
    if lo > hi {
        [1, 0]
    } else {
        [lo as crate::units::Depth, hi as crate::units::Depth]
    }
}

/// Every triangle a column keeps may be cut by a beam ([`ExactVisit::new`]'s `candidates`).
pub const ALL_CANDIDATES: u64 = u64::MAX;

/// The voxel depths z of column (x, y) at which a beam (of any direction) may have rays crossing
/// `tri`'s plane between layers k − 1 and k + 1, for a beam at layer k ≥ 2 carrying no notch:
/// `(lo, hi)`, inclusive (empty when lo > hi). At any other z of the column such a beam's visit
/// finds the triangle uncrossed ([`ExactVisit`]), so a host may leave it out
/// ([`Column::near`]); the window depends on neither the source nor the far distance.
///
/// Why: a beam at voxel V of layer k holds only rays that lie in V at layer k (the split sends
/// each ray to the voxel it occupies, merges join beams of one voxel), so at layer k's centre
/// plane they are within 8 sixteenths of V's centre across the axis. Layers k − 1 and k + 1 are
/// 16 sixteenths before and after it along the axis (k − 1 ≥ 1: T > 0 there, no clamping at the
/// origin), and a ray moves at most 16 sixteenths across per 16 along (|a|, |b| ≤ N). So every
/// point the visit reads (the rays at T_{k−1} and T_{k+1}) lies in the box of half-widths 16
/// along the axis and 24 across it around V's centre `16·V`, so in the cube of half-width 24
/// whatever the direction (one window serves every direction, a little wider along the axis than
/// it need be: 4 bytes per triangle, not 12). If the plane `g = n·(P − V₀)` keeps
/// one strict sign over that box (g > 0 everywhere, or g ≤ 0 everywhere: the sign the visit
/// reads), the visit's corners agree at both layers and it skips the triangle. Over the box g
/// lies within `g(16·V) ± R`, R = Σ |nᵢ|·hᵢ, and `g(16·V) = A + 16·n_z·z` is affine in z: the
/// depths where the sign may change are those with −R < A + 16·n_z·z ≤ R, one interval.
///
/// Exact in `i128`: |n| < 2⁴⁹ per component, coordinates differences < 2²⁵, so every term is
/// below 2⁷⁶.
pub fn near_voxels(tri: &Triangle, x: i32, y: i32) -> (i64, i64) {
    let n = tri.normal();
    let v0 = tri.vertex(0);
    let r: i128 = n.iter().map(|c| c.abs() * 24).sum();
    let a = n[0] * (16 * x as i128 - v0[0] as i128) + n[1] * (16 * y as i128 - v0[1] as i128) - n[2] * v0[2] as i128;
    let b = 16 * n[2];
    let clamp = |z: i128| z.clamp(i64::MIN as i128, i64::MAX as i128) as i64;
    if b == 0 {
        return if -r < a && a <= r { (i64::MIN, i64::MAX) } else { (1, 0) };
    }
    // −R < A + B·z ≤ R, for B > 0 and (negating) for B < 0.
    let (lo, hi) = if b > 0 {
        ((-r - a).div_euclid(b) + 1, (r - a).div_euclid(b))
    } else {
        let b = -b;
        // A − R ≤ B·z < A + R.
        (-((r - a).div_euclid(b)), (a + r - 1).div_euclid(b))
    };
    (clamp(lo), clamp(hi))
}

/// Most triangles one [`ExactVisit`] reads tests for (those it cannot decide on the whole
/// rectangle, seven tests each in a 64-bit word); with more, it judges ray by ray.
pub const MAX_EXACT_TRIANGLES: usize = 9;

/// Tests per undecided triangle: three edges, σ at k − 1, k, k + 1, and at the notch's t₁.
const PER_TRIANGLE: usize = 7;

/// Most tests of one [`ExactVisit`].
pub const MAX_EXACT_TESTS: usize = MAX_EXACT_TRIANGLES * PER_TRIANGLE;

/// The tests an [`ExactVisit`] reads, in a buffer its caller keeps (one per step on the stack, a
/// local of its own: built inside the visit, the compiler cleared and moved all of it).
pub type ExactTests = Vec<Test, MAX_EXACT_TESTS>;

/// Segment capacity for an [`ExactVisit`]'s lines ([`crate::lit::Segments`]).
pub const EXACT_SEGMENTS: usize = 2 * MAX_EXACT_TESTS + 1;

/// What the triangles of one column do to one beam at one layer under the exact-occluder rule
/// ([`crate::lit::LitRule::Exact`]).
///
/// At layer k in column C, a ray of the beam
/// * is *absent* if the beam carries a notch from t₁ (rays of a ±z beam that stayed in C) and
///   a triangle of C meets it between t₁ and k − 1 (it was absorbed at an earlier layer of C);
/// * is *absorbed* if the beam is terminal, or a triangle of C meets it in segment k (the
///   receiver's half: [k − 1, k] against its own triangles);
/// * goes on otherwise; if it leaves C and a triangle of C meets it in segment k + 1 it goes
///   on *terminal* (the sender's half: the next column does not know C's triangles), and a
///   terminal ray is absorbed at the next voxel. A ray staying in C goes on plain: C tests
///   segment k + 1 itself at the next layer.
///
/// So a ray is stopped at the first layer k whose segment meets a triangle kept by the column
/// of its voxel at k − 1 or at k. Triangles whose tests are constant on the beam's rectangle
/// are decided once; the others' tests cut the beam like the plane rule's
/// ([`crate::lit::Rule`]). With more than [`MAX_EXACT_TRIANGLES`] undecided, the visit judges
/// each ray against every triangle and cuts lines where the verdict changes (*per-ray*: slower,
/// the same verdicts).
#[derive(Debug)]
pub struct ExactVisit<'a, 't, F: FracBits> {
    /// The undecided triangles' tests, in a buffer the caller owns ([`ExactTests`]): a visit
    /// is built for every beam, and a 6 KB buffer inside it was cleared and copied each time.
    tests: &'t mut ExactTests,
    /// Decided on the whole rectangle: some triangle removes every ray (absent), absorbs every
    /// ray, makes every leaving ray terminal.
    absent: bool,
    absorbed: bool,
    terminal: bool,
    /// The beam arrived terminal.
    arrival_terminal: bool,
    /// The notch's start t₁ (the tests include σ at t₁).
    notch: Option<i64>,
    /// Too many undecided triangles: each ray is judged on its own.
    per_ray: bool,
    /// With `per_ray`: the triangles each ray is judged against — bit i for the undecided
    /// triangles [`ExactVisit::sort_triangles`] met before it gave up, then every candidate
    /// from the one it stopped at (`judged_from`) on. The others meet no ray of the rectangle
    /// or are decided on all of it (their verdict is in the flags): judging them again for
    /// every ray changed nothing and was most of a visit's time on dense columns.
    judged: u64,
    judged_from: usize,
    triangles: &'a [Triangle],
    /// Bit i: triangle i may cut the beam ([`ALL_CANDIDATES`]: any may; the others the caller
    /// knows the visit would find uncrossed, [`near_voxels`]).
    candidates: u64,
    /// The triangles' planes, when the host precomputed them.
    seen: Option<SeenTable<'a>>,
    source: &'a Source,
    dir: Direction,
    far: FarDistance<F>,
    k: i64,
}

/// A per-ray verdict's code in the test bits: its `Out` for rays leaving the column (bits
/// 0–1) and staying in it (bits 2–3).
fn out_code(o: crate::lit::Out) -> u64 {
    use crate::lit::Out;
    match o {
        Out::Absent => 0,
        Out::Absorbed => 1,
        Out::Continue => 2,
        Out::Terminal => 3,
    }
}

fn code_out(c: u64) -> crate::lit::Out {
    use crate::lit::Out;
    match c & 3 {
        0 => Out::Absent,
        1 => Out::Absorbed,
        2 => Out::Continue,
        _ => Out::Terminal,
    }
}

impl<'a, 't, F: FracBits> ExactVisit<'a, 't, F> {
    /// The visit at layer `k` of a beam with lattice rectangle `a × b` (inclusive), terminal or
    /// not, with the notch start `notch` (for a ±z beam that stayed in its column), in a column
    /// keeping `triangles` (with their planes `seen`, if precomputed) of which those of
    /// `candidates` may cut it (bit i: triangle i; [`ALL_CANDIDATES`] for every one, a cell's
    /// choice; the rest must be triangles the visit would find uncrossed, [`near_voxels`]); its
    /// tests go to `tests` (whatever it held is dropped).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn new(
        tests: &'t mut ExactTests,
        triangles: &'a [Triangle],
        seen: Option<SeenTable<'a>>,
        candidates: u64,
        source: &'a Source,
        dir: Direction,
        far: FarDistance<F>,
        k: i64,
        (a, b): ((i64, i64), (i64, i64)),
        arrival_terminal: bool,
        notch: Option<i64>,
    ) -> Self {
        tests.clear();
        let mut v = ExactVisit {
            tests,
            absent: false,
            absorbed: false,
            terminal: false,
            arrival_terminal,
            notch,
            per_ray: false,
            judged: 0,
            judged_from: 0,
            triangles,
            candidates,
            seen,
            source,
            dir,
            far,
            k,
        };
        v.sort_triangles((a, b));
        v
    }

    /// The same visit taken again, in place, on rectangle `a × b` of the same beam's rays
    /// (what is left of it after a run was peeled off), terminal or not: no second visit on
    /// the stack (each holds up to [`MAX_EXACT_TESTS`] tests, 5.5 KB on the MCU).
    pub fn rejudge(&mut self, rect: ((i64, i64), (i64, i64)), arrival_terminal: bool) {
        (self.absent, self.absorbed, self.terminal, self.per_ray) = (false, false, false, false);
        (self.judged, self.judged_from) = (0, 0);
        self.arrival_terminal = arrival_terminal;
        self.tests.clear();
        self.sort_triangles(rect);
    }

    /// Sort the column's triangles for rectangle `a × b`: those decided on the whole rectangle
    /// set the flags, the others leave their tests (or, past [`MAX_EXACT_TRIANGLES`], make the
    /// visit judge ray by ray).
    #[inline(never)]
    fn sort_triangles(&mut self, (a, b): ((i64, i64), (i64, i64))) {
        let (source, dir, far, k, notch) = (self.source, self.dir, self.far, self.k, self.notch);
        let v = self;
        // Triangle i ≥ 64 is always a candidate (it has no bit).
        let (candidates, len) = (v.candidates, v.triangles.len());
        let candidate = |i: usize| i >= 64 || candidates >> i & 1 == 1;
        let low = if len >= 64 { u64::MAX } else { (1 << len) - 1 };
        if len <= 64 && candidates & low == 0 {
            return; // every triangle would be found uncrossed
        }
        let Some(view) = View::new(source, dir, far) else { return };
        let corners = [(a.0, b.0), (a.0, b.1), (a.1, b.0), (a.1, b.1)];
        // Some(value) when a test's values at the corners agree: it is constant on the rectangle.
        let constant = |c: [bool; 4]| c.iter().all(|&x| x == c[0]).then_some(c[0]);
        // Planes whose values fit `i64` for every ray of the far square are read in `i64`
        // ([`RayPlane::narrow`]: the same signs).
        let in_square = |n: &Narrow| corners.iter().all(|&(a, b)| n.covers(a, b));
        let t1 = notch.unwrap_or(k - 1);
        // No ray crosses the plane between t₁ and k + 1: σ is monotone along each ray, so its
        // sign at the earliest and the latest of those layers, at the rectangle's corners,
        // decides it.
        let (t_first, t_last) = (t1.min(k - 1), t1.max(k + 1));
        let uncrossed = |first: [bool; 4], last: [bool; 4]| first == last && constant(first).is_some();
        // Table entries are narrowed for |a|, |b| ≤ N ([`SeenEntry::narrow`]).
        let nn = view.nn as i64;
        let narrow_square = corners.iter().all(|&(a, b)| a.abs() <= nn && b.abs() <= nn);
        for (i, tri) in v.triangles.iter().enumerate() {
            if !candidate(i) {
                continue;
            }
            // The plane first: most triangles are crossed by no ray near this layer, and their
            // edges are never built. A table's narrow plane is read from its coefficients
            // (the same `i64` form and signs as below), before any `Seen` is built.
            if let Some(t) = v.seen.filter(|_| narrow_square) {
                let entry = t.entry(i, v.dir);
                match entry.narrow(&view) {
                    Some(n) => {
                        // σ_t = k0 + T_t·form with T_t ≥ 0 is non-decreasing in the form, and the
                        // form is linear over the rectangle: the corners' signs all agree at both
                        // layers iff those of the least and the greatest corner form do.
                        let forms = corners.map(|(a, b)| n.form(a, b));
                        let (lo, hi) = (forms.iter().min(), forms.iter().max());
                        let (lo, hi) = (lo.copied().unwrap_or(0), hi.copied().unwrap_or(0));
                        let s = n.positive_with(lo, t_first);
                        if s == n.positive_with(hi, t_first)
                            && s == n.positive_with(lo, t_last)
                            && s == n.positive_with(hi, t_last)
                        {
                            continue;
                        }
                    }
                    None if entry.orient == 0 => continue,
                    None => {}
                }
            }
            let Some(seen) = v.seen_of(i, tri, &view) else { continue };
            let narrow = seen.narrow.filter(in_square);
            let (forms, forms64) = match narrow {
                Some(n) => ([0; 4], corners.map(|(a, b)| n.form(a, b))),
                None => (corners.map(|(a, b)| seen.plane.form(a, b)), [0; 4]),
            };
            let sigma_at = |t: i64| match narrow {
                Some(n) => forms64.map(|f| n.positive_with(f, t)),
                None => forms.map(|f| seen.plane.positive_with(f, t)),
            };
            if uncrossed(sigma_at(t_first), sigma_at(t_last)) {
                continue;
            }
            // The edges one by one, from their forms alone: at the first one outside which
            // every ray of the rectangle lies the triangle meets no ray; the edges' planes are
            // built only for a triangle left undecided.
            let mut fixed = [None; PER_TRIANGLE];
            if (0..3).any(|j| {
                fixed[j] = seen.edge_on(tri, &view, j, (a, b));
                fixed[j] == Some(false)
            }) {
                continue;
            }
            for (f, t) in fixed[3..].iter_mut().zip([k - 1, k, k + 1, t1]) {
                *f = constant(sigma_at(t));
            }
            if fixed.iter().all(Option::is_some) {
                let bits = fixed.iter().enumerate().fold(0u64, |m, (i, x)| m | ((*x == Some(true)) as u64) << i);
                let (absent, absorbed, terminal) = Self::triangle(bits, notch.is_some());
                v.absent |= absent;
                v.absorbed |= absorbed;
                v.terminal |= terminal;
                continue;
            }
            if v.tests.len() + PER_TRIANGLE > MAX_EXACT_TESTS {
                v.per_ray = true;
                v.judged_from = i;
                v.tests.clear();
                break;
            }
            if i < 64 {
                v.judged |= 1 << i;
            }
            for t in seen.occluder(tri, &view).exact_tests(k, t1) {
                let _ = v.tests.push(t);
            }
        }
    }

    /// One triangle's verdict on rays with its seven test bits: (absent, absorbed, terminal).
    fn triangle(bits: u64, notched: bool) -> (bool, bool, bool) {
        let inside = bits & 0b111 == 0b111;
        let s = |i: u32| bits >> i & 1 == 1;
        (inside && notched && s(6) != s(3), inside && s(3) != s(4), inside && s(4) != s(5))
    }

    /// Whether the visit judges ray by ray (more than [`MAX_EXACT_TRIANGLES`] undecided
    /// triangles): counted by the cell ([`crate::light::LightCounters::per_ray_visits`]).
    pub const fn per_ray(&self) -> bool {
        self.per_ray
    }

    /// Whether no test is needed and nothing happens: every ray of the beam goes on plain.
    pub fn is_plain(&self) -> bool {
        self.is_uniform() && !(self.absent || self.absorbed || self.terminal || self.arrival_terminal)
    }

    /// Whether every ray has the same verdict (no test to read).
    pub fn is_uniform(&self) -> bool {
        self.tests.is_empty() && !self.per_ray
    }

    /// The verdict on rays from the flags and the triangles' bits.
    fn out(&self, (mut absent, mut absorbed, mut terminal): (bool, bool, bool), stays: bool) -> crate::lit::Out {
        use crate::lit::Out;
        absent |= self.absent;
        absorbed |= self.absorbed;
        terminal |= self.terminal;
        if absent {
            Out::Absent
        } else if self.arrival_terminal || absorbed {
            Out::Absorbed
        } else if terminal && !stays {
            Out::Terminal
        } else {
            Out::Continue
        }
    }

    /// Triangle i of the column (`tri`) seen along the rays of `view`: rebuilt from the host's
    /// table entry, or computed.
    #[inline(always)]
    fn seen_of(&self, i: usize, tri: &Triangle, view: &View) -> Option<Seen> {
        match self.seen {
            Some(t) => {
                let s = t.entry(i, self.dir).seen(tri, view);
                debug_assert_eq!(s, Seen::new(tri, view), "a precomputed plane differs from the triangle's");
                s
            }
            None => Seen::new(tri, view),
        }
    }

    /// Whether the per-ray path judges rays against triangle i of the column (see `judged`).
    fn judges(&self, i: usize) -> bool {
        i >= 64 || if i < self.judged_from { self.judged >> i & 1 == 1 } else { self.candidates >> i & 1 == 1 }
    }

    /// Ray (a, b) judged against every triangle of the column.
    fn judge(&self, a: i64, b: i64) -> (bool, bool, bool) {
        let mut acc = (false, false, false);
        let Some(view) = View::new(self.source, self.dir, self.far) else { return acc };
        for (i, tri) in self.triangles.iter().enumerate() {
            if !self.judges(i) {
                continue;
            }
            let Some(occ) = self.seen_of(i, tri, &view).map(|s| s.occluder(tri, &view)) else { continue };
            let bits = occ
                .exact_tests(self.k, self.notch.unwrap_or(self.k - 1))
                .iter()
                .enumerate()
                .fold(0u64, |m, (i, t)| m | (t.holds(a, b) as u64) << i);
            let (x, y, z) = Self::triangle(bits, self.notch.is_some());
            acc = (acc.0 | x, acc.1 | y, acc.2 | z);
        }
        acc
    }

    /// The bits [`crate::lit::Rule::verdict`] reads for ray (a, b): its tests', or per ray its
    /// verdicts' codes.
    pub fn bits(&self, a: i64, b: i64) -> u64 {
        if self.per_ray {
            return self.codes(self.judge(a, b));
        }
        self.tests.iter().enumerate().fold(0u64, |m, (i, t)| m | (t.holds(a, b) as u64) << i)
    }

    /// A per-ray judgement as the codes of its verdicts (leaving the column, staying in it).
    fn codes(&self, j: (bool, bool, bool)) -> u64 {
        out_code(self.out(j, false)) | out_code(self.out(j, true)) << 2
    }

    /// The per-ray path's line: the rays `lo ..= hi` along `along` (the other offset at
    /// `fixed`) judged 64 at a time, each judged triangle's occluder built once per 64 rays and
    /// each of its tests read as the interval of the line where it holds
    /// ([`Test::interval`], the same signs as [`Test::holds`]), so a ray's verdict is the one
    /// [`ExactVisit::judge`] gives it. Segments as [`crate::lit::Rule::line`]'s.
    fn line_per_ray<const C: usize>(&self, along: Along, fixed: i64, lo: i64, hi: i64, out: &mut Segments<C>) {
        out.clear();
        let view = View::new(self.source, self.dir, self.far);
        let (k, t1, notched) = (self.k, self.notch.unwrap_or(self.k - 1), self.notch.is_some());
        let mut x0 = lo;
        while x0 <= hi {
            let x1 = hi.min(x0.saturating_add(63));
            // Bit x − x0: ray x is absent, absorbed, made terminal by some judged triangle.
            let (mut absent, mut absorbed, mut terminal) = (0u64, 0u64, 0u64);
            for (i, tri) in self.triangles.iter().enumerate() {
                let Some(view) = view.as_ref().filter(|_| self.judges(i)) else { continue };
                let Some(occ) = self.seen_of(i, tri, view).map(|s| s.occluder(tri, view)) else { continue };
                let mask = |t: Test| {
                    let (first, last) = t.interval(along, fixed, x0, x1);
                    if first > last {
                        return 0;
                    }
                    let width = (last - first + 1) as u32;
                    (if width >= 64 { u64::MAX } else { (1u64 << width) - 1 }) << (first - x0) as u32
                };
                let [e0, e1, e2, prev, now, next, start] = occ.exact_tests(k, t1);
                let inside = mask(e0) & mask(e1) & mask(e2);
                if inside == 0 {
                    continue;
                }
                let (prev, now, next) = (mask(prev), mask(now), mask(next));
                if notched {
                    absent |= inside & (mask(start) ^ prev);
                }
                absorbed |= inside & (prev ^ now);
                terminal |= inside & (now ^ next);
            }
            for x in x0..=x1 {
                let bit = |m: u64| m >> (x - x0) as u32 & 1 == 1;
                let bits = self.codes((bit(absent), bit(absorbed), bit(terminal)));
                if out.last().is_none_or(|l| l.1 != bits) && out.push((x, bits)).is_err() {
                    // More verdict changes on one line than segments: the rest of the line
                    // takes the last verdict (never met; the host's conservation check would
                    // fail).
                    return;
                }
            }
            if x1 == hi {
                break;
            }
            x0 = x1 + 1;
        }
    }
}

impl<F: FracBits> crate::lit::Rule for ExactVisit<'_, '_, F> {
    const BY_VERDICT: bool = true;

    fn tests(&self) -> &[Test] {
        self.tests
    }

    fn verdict(&self, bits: u64, stays: bool) -> crate::lit::Verdict {
        let out = if self.per_ray {
            code_out(bits >> (2 * stays as u32))
        } else {
            let mut acc = (false, false, false);
            for i in 0..self.tests.len() / PER_TRIANGLE {
                let (x, y, z) = Self::triangle(bits >> (i * PER_TRIANGLE), self.notch.is_some());
                acc = (acc.0 | x, acc.1 | y, acc.2 | z);
            }
            self.out(acc, stays)
        };
        crate::lit::Verdict { out, lit: false, visible: false }
    }

    fn outside(&self, _bits: u64) -> bool {
        false
    }

    fn line<const C: usize>(
        &self,
        along: crate::lit::Along,
        fixed: i64,
        lo: i64,
        hi: i64,
        out: &mut crate::lit::Segments<C>,
    ) {
        if !self.per_ray {
            return crate::lit::segments(self.tests, along, fixed, lo, hi, out);
        }
        self.line_per_ray(along, fixed, lo, hi, out)
    }

    fn run_end(&self, along: crate::lit::Along, start: i64, end: i64, lo: i64, hi: i64) -> i64 {
        if self.per_ray {
            return start; // one line at a time
        }
        crate::lit::run_end(self.tests, along, start, end, lo, hi)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::beam::{frac, Origin, SourceCoord, SourceId};
    use crate::lit::{segments, spans, uniform, Along, Segments};
    use crate::triangle::cross;
    use core::cmp::Ordering;
    use std::vec::Vec as StdVec;

    fn lcg(s: &mut u64) -> u64 {
        *s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *s >> 33
    }

    fn r(s: &mut u64, m: i64) -> i64 {
        (lcg(s) % (2 * m as u64 + 1)) as i64 - m
    }

    fn source16(p: [i64; 3]) -> Source {
        Source::new(SourceId(0), p.map(|c| SourceCoord::from_bits(c as i32)))
    }

    /// The oracle: where the ray's *line* meets the polygon's plane (an exact rational point),
    /// whether that point lies in the segment of layer k (each crossing in one segment, by the
    /// module doc's convention) and inside the closed convex polygon `poly` (edge by edge, in
    /// its plane). Shares no formula with [`Occluder`]: no signed volume from the origin.
    fn oracle(poly: &[[i64; 3]], o: [i64; 3], dir: Direction, nn: i64, lead: i64, (a, b): (i64, i64), k: i64) -> bool {
        let w = dir.principal().index();
        let (u, v) = dir.transverse();
        let mut d = [0i128; 3];
        d[w] = dir.sign() as i128 * nn as i128;
        d[u.index()] = a as i128;
        d[v.index()] = b as i128;
        let n = cross(sub(poly[1], poly[0]), sub(poly[2], poly[0]));
        let den = dot(n, d);
        let num0 = nn as i128 * dot(n, sub(o, poly[0]));
        if den == 0 || num0 == 0 {
            return false;
        }
        // T* = −num0 / den; compare it with t.
        let cmp = |t: i64| (-num0 - t as i128 * den).signum().cmp(&0).then(Ordering::Equal);
        let cmp = |t: i64| if den > 0 { cmp(t) } else { cmp(t).reverse() };
        let (t_lo, t_hi) = ((16 * (k - 1) - lead).max(0), (16 * k - lead).max(0));
        let in_segment = if den > 0 {
            cmp(t_lo) != Ordering::Less && cmp(t_hi) == Ordering::Less
        } else {
            cmp(t_lo) == Ordering::Greater && cmp(t_hi) != Ordering::Greater
        };
        if !in_segment {
            return false;
        }
        // The crossing point, scaled: X = Y / (den·N) sixteenths.
        let scale = den * nn as i128;
        let y = [0, 1, 2].map(|i| scale * o[i] as i128 - num0 * d[i]);
        (0..poly.len()).all(|i| {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            let rel = [0, 1, 2].map(|c| y[c] - scale * p[c] as i128);
            dot(cross(sub(q, p), rel), n) * scale.signum() >= 0
        })
    }

    fn random_config<F: FracBits>(s: &mut u64) -> (Triangle, Source, Direction, FarDistance<F>, Origin) {
        // Vertices on a coarse lattice (multiples of 4 sixteenths) near the source, so that rays
        // through edges and vertices are common.
        let v = [0; 3].map(|_| [r(s, 24) * 4 + 96, r(s, 24) * 4 + 96, r(s, 24) * 4 + 96].map(|c| c as i32));
        let src = source16([r(s, 40) + 96, r(s, 40) + 96, r(s, 40) + 96]);
        let dir = Direction::ALL[(lcg(s) % 6) as usize];
        let far = FarDistance::<F>::new(4 + (lcg(s) % 6) as u32).unwrap();
        let origin = if lcg(s) % 2 == 0 { Origin::SourceVoxel } else { Origin::Light };
        (Triangle::new(v).unwrap(), src.with_origin(origin), dir, far, origin)
    }

    /// A configuration of [`random_config`] with up to `more − 1` further triangles.
    fn random_triangles<F: FracBits>(s: &mut u64, more: u64) -> (StdVec<Triangle>, Source, Direction, FarDistance<F>) {
        let (first, src, dir, far, _) = random_config::<F>(s);
        let mut tris = std::vec![first];
        for _ in 0..lcg(s) % more {
            tris.push(random_config::<F>(s).0);
        }
        (tris, src, dir, far)
    }

    /// A rectangle of lattice rays, `(a0, a1) × (b0, b1)`.
    type Rect = ((i64, i64), (i64, i64));

    /// A random visit of a beam under `far`: its layer k ≥ 1, a notch start (one in three) and a
    /// rectangle of lattice rays within the far square.
    fn random_visit<F: FracBits>(s: &mut u64, far: FarDistance<F>) -> (i64, Option<i64>, Rect) {
        let nn = far.scaled();
        let k = 1 + (lcg(s) % far.get() as u64) as i64;
        let notch = (lcg(s) % 3 == 0).then(|| (lcg(s) % k as u64) as i64);
        let (a0, a1, b0, b1) = (r(s, nn), r(s, nn), r(s, nn), r(s, nn));
        (k, notch, ((a0.min(a1), a0.max(a1)), (b0.min(b1), b0.max(b1))))
    }

    /// The origin and lead, restated from the module doc and [`Source::lead`]: from the light,
    /// the lead is measured from the last centre plane at or behind it (in [0, 16)).
    fn origin_and_lead(src: &Source, dir: Direction, origin: Origin) -> ([i64; 3], i64) {
        let w = dir.principal().index();
        let mut o = src.pos.map(|c| c.to_bits() as i64);
        let vw = 16 * ((o[w] + 8) >> 4);
        if origin == Origin::SourceVoxel {
            o[w] = vw;
        }
        let lead = dir.sign() as i64 * (o[w] - vw);
        (o, if lead < 0 { lead + 16 } else { lead })
    }

    fn meets_like_the_oracle<F: FracBits>(seed: u64) {
        let mut s = seed;
        let (mut stops, mut checked) = (0, 0);
        for _ in 0..60 {
            let (tri, src, dir, far, origin) = random_config::<F>(&mut s);
            let Some(occ) = Occluder::new(&tri, &src, dir, far) else { continue };
            let (o, lead) = origin_and_lead(&src, dir, origin);
            let poly = [0, 1, 2].map(|i| tri.vertex(i));
            let nn = far.scaled();
            for a in -nn..=nn {
                for b in -nn..=nn {
                    let mut per_ray = 0;
                    for k in 0..=far.get() as i64 {
                        let want = oracle(&poly, o, dir, nn, lead, (a, b), k);
                        assert_eq!(
                            occ.meets(a, b, k),
                            want,
                            "{tri:?} {src:?} {dir:?} {origin:?} ray ({a}, {b}) layer {k}"
                        );
                        per_ray += want as u32;
                        checked += 1;
                    }
                    assert!(per_ray <= 1, "a ray crosses a triangle once");
                    stops += per_ray;
                }
            }
        }
        assert!(stops > 500, "the configurations stop rays ({stops} of {checked})");
    }

    #[test]
    fn meets_equals_the_crossing_point_oracle() {
        meets_like_the_oracle::<frac::U0>(1);
        meets_like_the_oracle::<frac::U1>(2);
        meets_like_the_oracle::<frac::U2>(3);
    }

    /// A visit reading a host's table of planes ([`SeenTable`]) is the visit computing them:
    /// the same tests, flags, per-ray bits and verdicts (the table's narrow planes are read
    /// before any `Seen` is built, `sort_triangles`).
    fn table_is_transparent<F: FracBits>(seed: u64) {
        use crate::lit::Rule;
        let mut s = seed;
        let (mut decided, mut undecided) = (0, 0);
        for _ in 0..400 {
            let (tris, src, dir, far) = random_triangles::<F>(&mut s, 5);
            let table: StdVec<SeenEntry> =
                Direction::ALL.iter().flat_map(|&d| tris.iter().map(move |t| SeenEntry::of(t, &src, d, far))).collect();
            let views = SourceViews::new(&src, far);
            for (i, t) in tris.iter().enumerate() {
                let row = Direction::ALL.map(|d| table[d.index() as usize * tris.len() + i]);
                assert_eq!(Direction::ALL.map(|d| views.entry(t, d)), row, "one source's views give each entry");
            }
            let ids: StdVec<u32> = (0..tris.len() as u32).collect();
            let (k, notch, rect) = random_visit(&mut s, far);
            let terminal = lcg(&mut s) % 4 == 0;
            let (mut t1, mut t2) = (ExactTests::new(), ExactTests::new());
            let seen = Some(SeenTable { ids: &ids, seen: &table, distinct: tris.len() });
            let with = ExactVisit::new(&mut t1, &tris, seen, ALL_CANDIDATES, &src, dir, far, k, rect, terminal, notch);
            let without =
                ExactVisit::new(&mut t2, &tris, None, ALL_CANDIDATES, &src, dir, far, k, rect, terminal, notch);
            let case = std::format!("{tris:?} {src:?} {dir:?} k {k} notch {notch:?} rect {rect:?}");
            assert_eq!(with.tests(), without.tests(), "{case}");
            assert_eq!(
                (with.is_plain(), with.is_uniform(), with.per_ray()),
                (without.is_plain(), without.is_uniform(), without.per_ray()),
                "{case}"
            );
            for a in rect.0 .0..=rect.0 .1 {
                for b in rect.1 .0..=rect.1 .1 {
                    let (x, y) = (with.bits(a, b), without.bits(a, b));
                    assert_eq!(x, y, "{case} ray ({a}, {b})");
                    assert_eq!(with.verdict(x, false), without.verdict(y, false), "{case} ray ({a}, {b})");
                    assert_eq!(with.verdict(x, true), without.verdict(y, true), "{case} ray ({a}, {b})");
                }
            }
            if with.tests().is_empty() {
                decided += 1
            } else {
                undecided += 1
            }
        }
        assert!(decided > 40 && undecided > 40, "both kinds of visit met ({decided} decided, {undecided} not)");
    }

    /// Every ray's verdict in a visit is the module doc's, read from [`Occluder::meets`] ray by
    /// ray (checked against the crossing-point oracle above): absent if a triangle meets it in a
    /// segment after the notch's start and before layer k, absorbed if the beam arrived
    /// terminal or a triangle meets it in segment k, terminal (leaving the column) if one meets
    /// it in segment k + 1. Whatever the visit decided on the whole rectangle, cut by tests or
    /// judged ray by ray.
    fn visit_is_the_ray_by_ray_verdict<F: FracBits>(seed: u64) {
        use crate::lit::{Out, Rule};
        let mut s = seed;
        let (mut uniform, mut cut, mut per_ray, mut stopped) = (0, 0, 0, 0);
        for i in 0..300 {
            // Every third configuration dense enough for the per-ray path.
            let (tris, src, dir, far) = random_triangles::<F>(&mut s, if i % 3 == 0 { 48 } else { 12 });
            let occs: StdVec<Occluder> = tris.iter().filter_map(|t| Occluder::new(t, &src, dir, far)).collect();
            let (k, notch, rect) = random_visit(&mut s, far);
            let terminal = lcg(&mut s) % 6 == 0;
            let mut tests = ExactTests::new();
            let v = ExactVisit::new(&mut tests, &tris, None, ALL_CANDIDATES, &src, dir, far, k, rect, terminal, notch);
            match (v.per_ray(), v.is_uniform()) {
                (true, _) => per_ray += 1,
                (false, true) => uniform += 1,
                (false, false) => cut += 1,
            }
            for a in rect.0 .0..=rect.0 .1 {
                for b in rect.1 .0..=rect.1 .1 {
                    let meets = |layer: i64| occs.iter().any(|o| o.meets(a, b, layer));
                    let absent = notch.is_some_and(|t1| (t1 + 1..k).any(meets));
                    let absorbed = terminal || meets(k);
                    let leaves_terminal = meets(k + 1);
                    for stays in [false, true] {
                        let want = if absent {
                            Out::Absent
                        } else if absorbed {
                            Out::Absorbed
                        } else if leaves_terminal && !stays {
                            Out::Terminal
                        } else {
                            Out::Continue
                        };
                        stopped += (want != Out::Continue) as u32;
                        let got = v.verdict(v.bits(a, b), stays).out;
                        assert_eq!(
                            got, want,
                            "{tris:?} {src:?} {dir:?} k {k} notch {notch:?} ray ({a}, {b}) stays {stays}"
                        );
                    }
                }
            }
        }
        assert!(
            uniform > 20 && cut > 20 && per_ray > 5 && stopped > 1000,
            "{uniform} uniform, {cut} cut, {per_ray} per-ray visits, {stopped} stopped"
        );
    }

    #[test]
    fn visits_give_each_ray_the_verdict_of_its_crossings() {
        visit_is_the_ray_by_ray_verdict::<frac::U0>(31);
        visit_is_the_ray_by_ray_verdict::<frac::U1>(32);
    }

    /// The per-ray path's lines (64 rays at a time, each test read as an interval of the line)
    /// give every ray the verdict codes of judging it alone ([`ExactVisit::bits`]: each test
    /// read at the ray), along both axes, on lines longer than 64 rays.
    fn per_ray_lines_judge_each_ray_alone<F: FracBits>(seed: u64) {
        use crate::lit::Rule;
        let mut s = seed;
        let (mut visits, mut long, mut changes) = (0, 0, 0);
        for _ in 0..300 {
            let (tris, src, dir, far) = random_triangles::<F>(&mut s, 40);
            let nn = far.scaled();
            let k = 1 + (lcg(&mut s) % far.get() as u64) as i64;
            let notch = (lcg(&mut s) % 3 == 0).then(|| (lcg(&mut s) % k as u64) as i64);
            let (lo, hi) = (-nn + r(&mut s, 2).abs(), nn - r(&mut s, 2).abs());
            let mut tests = ExactTests::new();
            let rect = ((lo, hi), (lo, hi));
            let terminal = lcg(&mut s) % 8 == 0;
            let v = ExactVisit::new(&mut tests, &tris, None, ALL_CANDIDATES, &src, dir, far, k, rect, terminal, notch);
            if !v.per_ray() {
                continue;
            }
            visits += 1;
            long += (hi - lo + 1 > 64) as u32;
            let mut seg: Segments<EXACT_SEGMENTS> = Segments::new();
            for along in [Along::V, Along::U] {
                for fixed in (lo..=hi).step_by(11) {
                    v.line(along, fixed, lo, hi, &mut seg);
                    assert_eq!(seg.first().map(|s| s.0), Some(lo));
                    changes += seg.len() - 1;
                    for (start, stop, bits) in spans(&seg, hi) {
                        for x in start..=stop {
                            let (a, b) = if along == Along::V { (fixed, x) } else { (x, fixed) };
                            assert_eq!(bits, v.bits(a, b), "{tris:?} {src:?} {dir:?} k {k} ray ({a}, {b})");
                        }
                    }
                }
            }
        }
        assert!(
            visits > 30 && long > 10 && changes > 1000,
            "{visits} per-ray visits, {long} with long lines, {changes} changes"
        );
    }

    #[test]
    fn per_ray_lines_are_rays_judged_alone() {
        per_ray_lines_judge_each_ray_alone::<frac::U2>(21);
        per_ray_lines_judge_each_ray_alone::<frac::U3>(22);
    }

    /// The window oracle: the plane's values at the eight corners of the cube of half-width 24
    /// around the voxel centre (16x, 16y, 16z) — the extremes of an affine function over a box
    /// — straddle 0 (some > 0 and some ≤ 0) exactly at the depths of [`near_voxels`].
    #[test]
    fn near_voxels_are_the_depths_whose_box_the_plane_cuts() {
        let mut s = 21u64;
        let (mut inside, mut outside) = (0, 0);
        for case in 0..3000 {
            let m = if case % 3 == 0 { 16 } else { 1 };
            let v = [0; 3]
                .map(|_| [r(&mut s, 160 / m) * m, r(&mut s, 160 / m) * m, r(&mut s, 400 / m) * m].map(|c| c as i32));
            let tri = Triangle::new(v).unwrap();
            let (x, y) = (r(&mut s, 6) as i32, r(&mut s, 6) as i32);
            let (lo, hi) = near_voxels(&tri, x, y);
            let n = tri.normal();
            let v0 = tri.vertex(0);
            for z in -40..=40i64 {
                let c = [16 * x as i64, 16 * y as i64, 16 * z];
                let h = [24; 3];
                let values = (0..8).map(|bits| {
                    let p = [0, 1, 2].map(|i| c[i] + if bits >> i & 1 == 1 { h[i] } else { -h[i] });
                    dot(n, sub(p, v0))
                });
                let (mut pos, mut non_pos) = (false, false);
                for g in values {
                    pos |= g > 0;
                    non_pos |= g <= 0;
                }
                let cut = pos && non_pos;
                assert_eq!(lo <= z && z <= hi, cut, "{v:?} column ({x}, {y}) z {z}: window {lo}..={hi}");
                if cut {
                    inside += 1
                } else {
                    outside += 1
                }
            }
        }
        assert!(inside > 10_000 && outside > 10_000, "both kinds of depth tested ({inside} in, {outside} out)");
    }

    /// A visit told which triangles may cut the beam ([`Column::candidates`] from the
    /// triangles' [`near_windows`]) is the visit that tests them all, for beams as the machine
    /// makes them: at layer k ≥ 2, no notch, rays of one voxel (a sub-rectangle of the rays
    /// that occupy it, found ray by ray with [`crate::beam::trace_ray_voxel`]).
    fn near_windows_are_transparent<F: FracBits>(seed: u64) {
        use crate::beam::{trace_ray_voxel, FarOffset, Layer};
        use crate::lit::Rule;
        let mut s = seed;
        let (mut skipped, mut kept) = (0, 0);
        for _ in 0..400 {
            let (tris, src, dir, far) = random_triangles::<F>(&mut s, 6);
            let nn = far.scaled();
            let k = 2 + (lcg(&mut s) % (far.get() as u64 - 1)) as i64;
            // A voxel of layer k that some ray reaches, and the rays that occupy it.
            let (a, b) = (r(&mut s, nn), r(&mut s, nn));
            let at = |a: i64, b: i64| {
                let off = |x: i64| FarOffset::<F>::from_bits(x as i32);
                trace_ray_voxel(&src, dir, off(a), off(b), far, Layer(k as u32))
            };
            let (tu, tv) = at(a, b);
            let us: StdVec<i64> = (-nn..=nn).filter(|&a| at(a, 0).0 == tu).collect();
            let vs: StdVec<i64> = (-nn..=nn).filter(|&b| at(0, b).1 == tv).collect();
            let pick = |s: &mut u64, l: &[i64]| {
                let (i, j) = ((lcg(s) % l.len() as u64) as usize, (lcg(s) % l.len() as u64) as usize);
                (l[i.min(j)], l[i.max(j)])
            };
            let rect = (pick(&mut s, &us), pick(&mut s, &vs));
            // The voxel in grid coordinates: its slab along the axis, (tu, tv) across.
            let (w, (ua, va)) = (dir.principal().index(), dir.transverse());
            let mut voxel = [0i64; 3];
            voxel[w] = src.slab(dir, Layer(k as u32));
            voxel[ua.index()] = tu;
            voxel[va.index()] = tv;
            if voxel[2] < 0 {
                continue; // depths are unsigned
            }
            let near: StdVec<NearWindows> =
                tris.iter().map(|t| near_windows(t, voxel[0] as i32, voxel[1] as i32, u16::MAX)).collect();
            let column = Column { triangles: &tris, seen: None, target: None, voxel: None, near: Some(&near) };
            let candidates = column.candidates(voxel[2] as u16);
            let terminal = lcg(&mut s) % 4 == 0;
            let (mut t1, mut t2) = (ExactTests::new(), ExactTests::new());
            let with = ExactVisit::new(&mut t1, &tris, None, candidates, &src, dir, far, k, rect, terminal, None);
            let all = ExactVisit::new(&mut t2, &tris, None, ALL_CANDIDATES, &src, dir, far, k, rect, terminal, None);
            let case = std::format!("{tris:?} {src:?} {dir:?} k {k} rect {rect:?} candidates {candidates:b}");
            assert_eq!(with.tests(), all.tests(), "{case}");
            assert_eq!(
                (with.is_plain(), with.is_uniform(), with.per_ray(), with.absent, with.absorbed, with.terminal),
                (all.is_plain(), all.is_uniform(), all.per_ray(), all.absent, all.absorbed, all.terminal),
                "{case}"
            );
            for a in rect.0 .0..=rect.0 .1 {
                for b in rect.1 .0..=rect.1 .1 {
                    assert_eq!(
                        with.verdict(with.bits(a, b), false),
                        all.verdict(all.bits(a, b), false),
                        "{case} ({a}, {b})"
                    );
                }
            }
            skipped += (0..tris.len()).filter(|&i| candidates >> i & 1 == 0).count();
            kept += (candidates & ((1 << tris.len()) - 1)).count_ones() as usize;
        }
        assert!(skipped > 100 && kept > 100, "triangles both left out ({skipped}) and kept ({kept})");
    }

    #[test]
    fn near_windows_change_no_visit() {
        near_windows_are_transparent::<frac::U0>(31);
        near_windows_are_transparent::<frac::U1>(32);
        near_windows_are_transparent::<frac::U2>(33);
    }

    #[test]
    fn a_table_of_planes_changes_no_visit() {
        table_is_transparent::<frac::U0>(11);
        table_is_transparent::<frac::U1>(12);
        table_is_transparent::<frac::U2>(13);
    }

    /// Cut every column of a beam's rectangle into segments of equal test bits: the verdict of
    /// each segment is every ray's.
    #[test]
    fn beam_segments_are_uniform() {
        let mut s = 11u64;
        let (mut cut, mut whole) = (0, 0);
        for _ in 0..200 {
            let (tri, src, dir, far, _) = random_config::<frac::U1>(&mut s);
            let Some(occ) = Occluder::new(&tri, &src, dir, far) else { continue };
            let nn = far.scaled();
            let k = (lcg(&mut s) % (far.get() as u64 + 1)) as i64;
            let tests = occ.tests(k);
            let (a0, a1) = (r(&mut s, nn), r(&mut s, nn));
            let (b0, b1) = (r(&mut s, nn), r(&mut s, nn));
            let (a0, a1, b0, b1) = (a0.min(a1), a0.max(a1), b0.min(b1), b0.max(b1));
            let mut seg: Segments = Segments::new();
            for a in a0..=a1 {
                segments(&tests, Along::V, a, b0, b1, &mut seg);
                cut += seg.len() - 1;
                for (start, end, bits) in spans(&seg, b1) {
                    for b in start..=end {
                        assert_eq!(Occluder::stops(bits), occ.meets(a, b, k), "ray ({a}, {b}) layer {k}");
                    }
                }
            }
            if let Some(bits) = uniform(&tests, (a0, a1), (b0, b1)) {
                whole += 1;
                for (a, b) in (a0..=a1).flat_map(|a| (b0..=b1).map(move |b| (a, b))) {
                    assert_eq!(Occluder::stops(bits), occ.meets(a, b, k));
                }
            }
        }
        assert!(cut > 100 && whole > 10, "beams cut ({cut} cuts) and whole ({whole})");
    }

    /// A planar quad cut along its diagonal into two triangles stops exactly the rays that the
    /// quad stops: none passes through the shared edge, none is stopped beside the quad. The
    /// rays of the first configuration hit the diagonal and the outer edges exactly.
    #[test]
    fn a_split_quad_has_no_crack() {
        let mut s = 5u64;
        let mut on_diagonal = 0;
        for case in 0..40 {
            let (quad, src) = if case == 0 {
                // Source at a voxel centre, quad ±2 voxels around the +z axis at layer 4.
                ([[-32, -32, 64], [32, -32, 64], [32, 32, 64], [-32, 32, 64]], source16([0, 0, 0]))
            } else {
                // A random parallelogram, tilted.
                let p0 = [r(&mut s, 6) * 8, r(&mut s, 6) * 8, 64 + r(&mut s, 4) * 8];
                let e1 = [8 + r(&mut s, 4) * 8, r(&mut s, 3) * 8, r(&mut s, 3) * 8];
                let e2 = [r(&mut s, 3) * 8, 8 + r(&mut s, 4) * 8, r(&mut s, 3) * 8];
                let q = |i: usize| [p0[i], p0[i] + e1[i], p0[i] + e1[i] + e2[i], p0[i] + e2[i]];
                let (x, y, z) = (q(0), q(1), q(2));
                ([0, 1, 2, 3].map(|j| [x[j], y[j], z[j]]), source16([r(&mut s, 8), r(&mut s, 8), r(&mut s, 8)]))
            };
            let far = FarDistance::<frac::U0>::new(8).unwrap();
            let t = |i: [usize; 3]| Triangle::new(i.map(|j| quad[j].map(|c| c as i32))).unwrap();
            let halves = [t([0, 1, 2]), t([0, 2, 3])];
            for dir in Direction::ALL {
                for origin in [Origin::SourceVoxel, Origin::Light] {
                    let occ: StdVec<Occluder> =
                        halves.iter().filter_map(|h| Occluder::new(h, &src.with_origin(origin), dir, far)).collect();
                    let (o, lead) = origin_and_lead(&src, dir, origin);
                    for a in -8..=8 {
                        for b in -8..=8 {
                            for k in 0..=8 {
                                let want = oracle(&quad, o, dir, 8, lead, (a, b), k);
                                let got = occ.iter().any(|h| h.meets(a, b, k));
                                assert_eq!(got, want, "case {case} {dir:?} {origin:?} ray ({a}, {b}) layer {k}");
                                on_diagonal += (case == 0 && want && a == b) as u32;
                            }
                        }
                    }
                }
            }
        }
        assert!(on_diagonal > 0, "rays through the shared edge were tested");
    }

    /// Every term at the bit budget's limits, with overflow checks on (the test profile): no
    /// panic. (Points in a box of side 2l give cross products up to (2l)² = 2⁴⁸ per component,
    /// half the budget's 2⁴⁹.)
    #[test]
    fn arithmetic_at_the_limits() {
        let l = COORD_LIMIT as i32;
        let far = FarDistance::<frac::U4>::new(FarDistance::<frac::U4>::MAX).unwrap();
        let nn = far.scaled();
        let big_t = far.get() as i64;
        let tris = [
            [[l, l, l], [-l, l, -l], [l, -l, -l]],
            [[-l, -l, -l], [l, -l, l], [-l, l, l]],
            [[l, -l, l], [-l, -l, -l], [l, l, -l]],
        ];
        for v in tris {
            let tri = Triangle::new(v).unwrap();
            for src in [source16([-(COORD_LIMIT - 8); 3]), source16([COORD_LIMIT - 8, -(COORD_LIMIT - 8), 0])] {
                for dir in Direction::ALL {
                    for origin in [Origin::SourceVoxel, Origin::Light] {
                        let Some(occ) = Occluder::new(&tri, &src.with_origin(origin), dir, far) else { continue };
                        for (a, b) in [(nn, nn), (-nn, nn), (nn, -nn), (-nn, -nn), (0, 0)] {
                            for k in [0, 1, big_t / 2, big_t] {
                                let _ = occ.meets(a, b, k);
                                for t in occ.tests(k) {
                                    let _ = t.interval(Along::V, a, -nn, nn);
                                    let _ = t.interval(Along::U, b, -nn, nn);
                                }
                            }
                        }
                    }
                }
            }
        }
        // The column test at the limits: columns at the triangle's corners and anywhere an i32
        // reaches.
        for v in tris {
            let tri = Triangle::new(v).unwrap();
            for (x, y) in [(l / 16, l / 16), (-l / 16, l / 16), (0, 0), (i32::MAX, i32::MIN), (i32::MIN, 0)] {
                let _ = tri.crosses_column(x, y);
            }
            assert!(tri.crosses_column(l / 16, l / 16) || tri.crosses_column(-l / 16, l / 16));
            assert!(!tri.crosses_column(i32::MAX, i32::MIN));
        }
        assert!(Triangle::new([[l + 1, 0, 0], [0; 3], [0; 3]]).is_none());
        let far_src = source16([COORD_LIMIT + 16, 0, 0]);
        let tri = Triangle::new(tris[0]).unwrap();
        assert!(Occluder::new(&tri, &far_src.with_origin(Origin::Light), Direction::PosY, far).is_none());
    }

    /// The oracle for [`Triangle::crosses_column`]: the closed projected triangle and square
    /// overlap iff a vertex of one lies in the other or two of their edges meet.
    fn overlaps(p: [[i64; 2]; 3], c: [i64; 2]) -> bool {
        let sq = [[c[0] - 8, c[1] - 8], [c[0] + 8, c[1] - 8], [c[0] + 8, c[1] + 8], [c[0] - 8, c[1] + 8]];
        let orient = |a: [i64; 2], b: [i64; 2], q: [i64; 2]| {
            ((b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])).signum()
        };
        let on = |a: [i64; 2], b: [i64; 2], q: [i64; 2]| {
            orient(a, b, q) == 0
                && (a[0].min(b[0])..=a[0].max(b[0])).contains(&q[0])
                && (a[1].min(b[1])..=a[1].max(b[1])).contains(&q[1])
        };
        let meet = |a: [i64; 2], b: [i64; 2], p: [i64; 2], q: [i64; 2]| {
            let (d1, d2, d3, d4) = (orient(a, b, p), orient(a, b, q), orient(p, q, a), orient(p, q, b));
            (d1 * d2 < 0 && d3 * d4 < 0) || on(a, b, p) || on(a, b, q) || on(p, q, a) || on(p, q, b)
        };
        let in_square = |q: [i64; 2]| (q[0] - c[0]).abs() <= 8 && (q[1] - c[1]).abs() <= 8;
        let in_triangle = |q: [i64; 2]| {
            let s = [orient(p[0], p[1], q), orient(p[1], p[2], q), orient(p[2], p[0], q)];
            orient(p[0], p[1], p[2]) != 0 && (s.iter().all(|&x| x >= 0) || s.iter().all(|&x| x <= 0))
        };
        p.iter().any(|&q| in_square(q))
            || sq.iter().any(|&q| in_triangle(q))
            || (0..3).any(|i| (0..4).any(|j| meet(p[i], p[(i + 1) % 3], sq[j], sq[(j + 1) % 4])))
    }

    #[test]
    fn crosses_column_matches_the_overlap_oracle() {
        let mut s = 3u64;
        let (mut hit, mut miss) = (0, 0);
        for i in 0..4000 {
            // Coarse lattices make touching cases (a vertex or edge on the square's border) common;
            // every fourth triangle stands vertical (projects to a segment or a point).
            let m = if i % 2 == 0 { 8 } else { 1 };
            let mut v = [0; 3].map(|_| [r(&mut s, 48 / m) * m, r(&mut s, 48 / m) * m, r(&mut s, 30)].map(|c| c as i32));
            if i % 4 == 3 {
                v[2] = [(v[0][0] + v[1][0]) / 2, (v[0][1] + v[1][1]) / 2, v[2][2]];
                if i % 8 == 7 {
                    v[1] = [v[0][0], v[0][1], v[1][2]];
                    v[2] = [v[0][0], v[0][1], v[2][2]];
                }
            }
            let tri = Triangle::new(v).unwrap();
            for (x, y) in [(0, 0), (1, 0), (0, -1), (2, 2), (-1, 1)] {
                let want = overlaps(v.map(|q| [q[0] as i64, q[1] as i64]), [16 * x as i64, 16 * y as i64]);
                assert_eq!(tri.crosses_column(x, y), want, "{v:?} column ({x}, {y})");
                if want {
                    hit += 1
                } else {
                    miss += 1
                }
            }
        }
        assert!(hit > 1000 && miss > 1000, "both outcomes tested ({hit} / {miss})");
    }

    #[test]
    fn store_overflow_is_counted() {
        let t = Triangle::new([[0, 0, 0], [16, 0, 0], [0, 16, 0]]).unwrap();
        let mut store = TriangleStore::<2>::new();
        assert!(store.push(t) && store.push(t));
        assert!(!store.push(t));
        assert_eq!((store.triangles().len(), store.overflows()), (2, 1));
    }
}
