//! §5.5.5–5.5.6 — the lit rules: which rays a surface voxel stops, lights or lets pass.
//!
//! **Invariant: the rule is defined ray by ray ([`Visit::verdict`]), and every set of rays the
//! cell treats at once (a beam, a piece of a beam) is uniform under it: the cell only ever
//! applies a verdict to rays whose tests all agree.** The per-ray oracle of the test suite
//! restates the rule with its own arithmetic, and beam diffusion must equal it ray for ray.
//!
//! # The thesis's rule (§5.5.5): [`LitRule::Thesis`]
//!
//! A beam entering an occupied voxel lights it and stops. It is wrong at grazing angles: a
//! surface is a staircase of voxels, and the ray aimed at one step is absorbed by the step before
//! it (§5.5.6, "one of the hardest problems … no truly satisfactory solution").
//!
//! # The plane rule: [`LitRule::Plane`]
//!
//! Each dexel stores its facet's plane ([`crate::plane`]): g(p) > 0 on the outward side. A ray
//! is the line `p(t) = Se + t·(s·e_w + (u/D)·e_u + (v/D)·e_v)` from the source with its principal
//! coordinate snapped to the source voxel's (`Se`); at layer k its point `p(k)` lies in its voxel.
//! Write σ_t = [g(p(t)) > 0] for the plane of a voxel, and σ₋ = σ_{k−1} (σ₀ at layer 0).
//! Because g(p(t)) is affine in t, σ changes at most once along a ray. A facet stops a ray only
//! where the ray crosses its plane *there*: a planar facet cannot shadow itself, and the plane
//! of a facet says nothing about rays that pass beside the facet (beyond its edges, on its far
//! side without crossing it). At layer k in voxel V a ray
//!
//! 1. lights the column's *visible surface* (the facet its centre line meets, [`crate::visible`])
//!    if V is one of the two voxels bracketing it, that facet's plane B — oriented toward the
//!    viewer, whatever the facet's winding — faces the source (g_B(Se) > 0) and σᴮ_k or σᴮ₋
//!    holds;
//! 2. if it is *terminal* (it crossed a plane just before this layer): lights V if V is occupied
//!    and rule 4 would light it; it is absorbed;
//! 3. in an empty V goes on;
//! 4. in an occupied V: lights V if the ray is on the source's side of V's plane at layer k or
//!    k − 1 and that plane faces the source (σ_k or σ₋) or is two-sided (see below; ¬σ_k or
//!    ¬σ₋); is absorbed if σ₋ ≠ σ_k (it crossed the plane between the two layers); is absorbed
//!    if it is behind V's plane at both layers (σ₋ = σ_k = 0) and came from empty space (its
//!    voxel at layer k − 1 was empty, [`crate::beam::Beam::after_empty`]) into a plane that
//!    faces the source or is one-sided, or from the outside of another column's surface (its
//!    voxel at k − 1 was occupied, in another column, and the ray was on the outside of that
//!    voxel's plane, [`crate::beam::Beam::after_outside`]) into a plane facing the source:
//!    either way it crossed a surface between the two layers, in a voxel the 26-connected step
//!    skipped or in a voxel whose plane is another facet's; is absorbed if it
//!    is a ±z ray that stays in its column at layer k + 1 (k < D: at the far plane every ray
//!    leaves) and has passed another dexel of this column while staying in it (the *column
//!    rule*, see below); becomes terminal if σ_k ≠ σ_{k+1} (it will cross before the next
//!    layer: one more step, act there, die); otherwise goes on.
//!
//! The terminal step lights the voxel the crossing point may lie in at the next layer. Planes
//! stop rays from both sides (an open sheet is opaque both ways), but only facets facing the
//! source, or two-sided ones, are lit.
//!
//! **Two-sided planes.** Behind a plane of a solid's surface is its inside: a ray found there,
//! coming from empty space, went through the surface. A surface that bounds no solid (a sheet,
//! a room open to the viewer, the teapot: [`crate::plane::TWO_SIDED`], decided by the host) has
//! no inside; its winding is its author's or the host's majority choice. Where it faces away
//! from the source, "behind" is the source's own side, where a ray is before it reaches the
//! plane: at grazing angles a ray enters the standard surface's band a few voxels before the
//! plane, and stopping it there left most of a sheet wound away from its light dark. So rule 4
//! reads "behind" only for a two-sided plane facing the source, and a two-sided plane facing
//! away is lit from its inner side: an open sheet is lit, and stops light, the same whatever
//! its winding. Its far side is not read as "crossed unseen" either (the one-sided rule for a
//! plane facing away): that is where rays pass a convex edge of an open mesh (the teapot's
//! silhouette).
//!
//! A closed mesh stays closed: a ray crossing its surface crosses a plane in one of the two
//! voxels around the crossing (the standard surface has no 26-tunnel), so it is
//! stopped there — unless that voxel belongs to another facet (a junction), and then it is
//! inside the mesh and is stopped where it leaves it. A step of a layer moves diagonally, so
//! the crossing point may lie in a voxel neither layer visits; the ray then reaches a surface
//! voxel from empty space already behind its plane, and is stopped there (rule 4). Without
//! that, light went through the thin parts of real meshes (the teapot's lid knob at n = 64).
//! A voxel keeps one facet's plane: in the thin parts of a mesh a ray may enter through a
//! voxel owned by a facet it does not cross and go on behind the next voxel's plane; coming
//! from the outside of one plane into the back of another that faces the source, it is
//! stopped (thin parts of the cow at n = 256). Into the back of a plane facing away it goes on: that
//! is a ray passing a convex edge (over a box's top, beyond its far side). What stays open is
//! a voxel holding two surfaces (open parts passing through each other, the teapot's spout in
//! its body): it knows one plane, and a ray crossing only the other one there is not stopped.
//!
//! # Beams under the plane rule
//!
//! For one plane and one layer t, the rays with σ_t form a half-plane of the (u, v) lattice: an
//! exact affine function `V(a, b, t) = K₀ + T·(K_w + c_b·a + c_g·b)` (T = 16·t for the machine's
//! rays, `16·t − lead` from the light: [`crate::beam::Origin`]) of the lattice offsets
//! a, b has the sign of g ([`RayPlane`]). So in each column of a beam's rectangle (fixed a) the
//! rays a test holds for are a prefix or a suffix ([`Test::interval`]), and columns with the same
//! prefixes and suffixes for every test form *runs* (found by binary search: each boundary is
//! monotone in a). A run cut at its boundaries gives rectangles of uniform verdict. A beam whose
//! rectangle is uniform (all four corners agree on every test: each test holds on a half-plane)
//! is processed in one step as before; otherwise the cell *peels* it, one rectangle per step,
//! the rest staying in its FIFO slot ([`crate::light`]).
//!
//! **The column rule.** A ±z beam's rays that stay in the column go back into the cell's own
//! FIFO. For the no-deadlock argument of [`crate::light`] a step may put at most one beam
//! there, so the rays that stay must form one message. After an occupied voxel they are a
//! rectangle minus the rays that crossed its plane (a *notch*: the rays whose σ changed between
//! two layers, [`Notch`]). A second plane would need a second notch, so a ray that stays in its
//! column and meets a voxel of another dexel of that column, having passed one already while
//! staying, is absorbed there. Rays leave a column all the time, and then forget: the rule only
//! concerns rays nearly parallel to z inside one column.
//!
//! # Arithmetic
//!
//! With L = 16·D·2^f every coordinate of L·p(t) is an integer, and `2¹⁶·L·g(p(t))` is one: with
//! the scaled normal (|n| ≤ 2³⁰ after the 2¹⁶ of `nx`, `ny`), |L·(p − ref)| ≤ 2³⁵·2¹⁷ and
//! |16·t·c·a| ≤ 2⁴·2¹⁷·2³⁰·2³¹, every term is below 2⁸³: `i128`, exact, for every f and D the beam
//! budget of [`crate::beam`] admits.

use crate::beam::{Direction, FarDistance, FracBits, Source};
use crate::plane::DexelPlane;
use crate::units::Depth;
use crate::visible::VisibleSurface;
use heapless::Vec;

/// Which lit rule the cells apply. No default: a host's run names it (rc2's host: its presets).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LitRule {
    /// §5.5.5: a beam entering an occupied voxel lights it and stops.
    Thesis,
    /// The plane rule (see the module doc): stopped only by a plane crossed there; lights the
    /// column's visible surface from its own plane.
    Plane,
    /// Exact occluders ([`crate::occluder::ExactVisit`]): a ray is stopped where its segment
    /// meets a triangle kept by the columns of its voxels at the segment's two ends; a column's
    /// visible surface is lit iff its one target ray ([`crate::receiver`]) reaches it. Only
    /// with cell-core's `exact-occluders` feature: a cell built without it cannot be asked for
    /// the rule (a trace naming it is refused), never runs another in its place.
    #[cfg(feature = "exact-occluders")]
    Exact,
}

/// The questions the rest of the machine asks of a lit rule, answered here once, so that no
/// phase re-decides them with its own `match`. The rule's ray-by-ray behaviour itself (which
/// rays a voxel stops or lights) is dispatched in one place per algorithm: the beam's fate
/// ([`crate::light`]) and the classic shadow ray's emission ([`crate::shadow`]).
///
/// ```
/// use cell_core::lit::LitRule;
/// // What a trace byte or a message encodes, and back.
/// for &rule in LitRule::ALL {
///     assert_eq!(LitRule::from_code(rule.code()), Some(rule));
/// }
/// assert_eq!(LitRule::Plane.name(), "plane");
/// assert_eq!(LitRule::from_code(3), None);
/// // The thesis's cell shades the first voxel of its column; the others the visible surface.
/// assert!(!LitRule::Thesis.shades_visible_surface());
/// assert!(LitRule::Plane.shades_visible_surface());
/// assert_eq!(LitRule::Plane.receiver_window(), Some((0, 1)));
/// ```
impl LitRule {
    /// Every rule this build of the cell has.
    #[cfg(feature = "exact-occluders")]
    pub const ALL: &'static [LitRule] = &[LitRule::Thesis, LitRule::Plane, LitRule::Exact];
    /// Every rule this build of the cell has.
    #[cfg(not(feature = "exact-occluders"))]
    pub const ALL: &'static [LitRule] = &[LitRule::Thesis, LitRule::Plane];

    /// Whether this is the exact-occluder rule (always `false` without the feature).
    pub const fn is_exact(self) -> bool {
        #[cfg(feature = "exact-occluders")]
        return matches!(self, LitRule::Exact);
        #[cfg(not(feature = "exact-occluders"))]
        {
            let _ = self;
            false
        }
    }

    /// The rule's name, as hosts spell it in options and outputs.
    pub const fn name(self) -> &'static str {
        match self {
            LitRule::Thesis => "thesis",
            LitRule::Plane => "plane",
            #[cfg(feature = "exact-occluders")]
            LitRule::Exact => "exact",
        }
    }

    /// The rule's code in a trace record or an exchanged part (4 bits): 0 thesis, 1 plane,
    /// 2 exact.
    pub const fn code(self) -> u8 {
        match self {
            LitRule::Thesis => 0,
            LitRule::Plane => 1,
            #[cfg(feature = "exact-occluders")]
            LitRule::Exact => 2,
        }
    }

    /// The rule of code `code` ([`LitRule::code`]); `None` for an unknown code or one this
    /// build lacks (a cell without exact occluders refuses code 2, never runs another rule).
    pub const fn from_code(code: u8) -> Option<LitRule> {
        match code {
            0 => Some(LitRule::Thesis),
            1 => Some(LitRule::Plane),
            #[cfg(feature = "exact-occluders")]
            2 => Some(LitRule::Exact),
            _ => None,
        }
    }

    /// Whether the cells need their column's triangles (the triangle store, the target ray,
    /// the neighbours' contact answers) for this rule: exact occluders only.
    pub const fn needs_triangles(self) -> bool {
        self.is_exact()
    }

    /// Whether a column's pixel is its *visible surface* (the facet its centre line meets,
    /// [`crate::visible`]: the plane rule and exact occluders), not the first voxel of its first
    /// dexel (the thesis's cell). It decides what a cell shades, which lit mark its pixel reads,
    /// where a classic shadow ray leaves from, and whether smooth normals or shadow-edge
    /// refinement can apply.
    pub const fn shades_visible_surface(self) -> bool {
        !matches!(self, LitRule::Thesis)
    }

    /// Whether the rule tests rays one by one, so that a beam is cut into pieces of uniform
    /// verdict and a classic ray walks the exact 6-connected segment (the plane rule and exact
    /// occluders); the thesis's rule treats a beam whole.
    pub const fn cuts_rays(self) -> bool {
        !matches!(self, LitRule::Thesis)
    }

    /// The voxels of a column where a ray may light its visible surface, as offsets from the
    /// surface's voxel `z_v` ([`crate::visible::VisibleSurface::z_v`]): the two bracketing it
    /// (`z_v ..= z_v + 1`) under the plane rule, and the one in front of them too under exact
    /// occluders (`z_v − 1 ..= z_v + 1`, where the target ray may arrive: [`crate::receiver`]).
    /// `None` for the thesis's rule, whose pixel is the first voxel.
    pub const fn receiver_window(self) -> Option<(i64, i64)> {
        match self {
            LitRule::Thesis => None,
            LitRule::Plane => Some((0, 1)),
            #[cfg(feature = "exact-occluders")]
            LitRule::Exact => Some((-1, 1)),
        }
    }

    /// Whether voxel `z` of a column receives its pixel's light: the first voxel of its first
    /// dexel (`first`) under the thesis's rule, a voxel of [`LitRule::receiver_window`] around
    /// its visible surface under the others. What a lit store restricted to the pixels keeps.
    pub fn receives(self, first: Option<Depth>, visible: Option<&VisibleSurface>, z: Depth) -> bool {
        match self.receiver_window() {
            None => first == Some(z),
            Some((lo, hi)) => visible.is_some_and(|v| (v.z_v as i64 + lo..=v.z_v as i64 + hi).contains(&(z as i64))),
        }
    }

    /// How many voxels beyond an occupied voxel a beam may still be stopped: 1 under exact
    /// occluders (a segment ending next to an occupied voxel may meet one of its triangles),
    /// 0 under the rules that read the voxel's own dexel. The skips keep every beam that can
    /// come this near an occupied voxel.
    pub const fn occluder_reach(self) -> u16 {
        self.is_exact() as u16
    }
}

/// A visit's tests and the verdict on rays by their bits: what [`crate::light`] cuts and peels
/// beams by, under the plane rule ([`Visit`]) and exact occluders
/// ([`crate::occluder::ExactVisit`]).
pub trait Rule {
    /// Whether a beam is cut by verdicts rather than by tests: neighbouring segments of a line
    /// with the same verdict go on as one piece, and a run takes in the next lines while their
    /// verdicts fall alike ([`verdict_run_end`]). The rays' fates are the same either way; the
    /// pieces are fewer where a test's line crosses rays that it does not change (a triangle's
    /// edge beside its plane's crossing).
    const BY_VERDICT: bool = false;
    /// The tests, in the order the bits read them.
    fn tests(&self) -> &[Test];
    /// The verdict on rays whose test bits are `bits`; `stays`: they stay in the column.
    fn verdict(&self, bits: u64, stays: bool) -> Verdict;
    /// Whether rays with these bits are on the outside of the voxel's plane at this layer
    /// ([`Arrival::after_outside`] for the next voxel).
    fn outside(&self, bits: u64) -> bool;
    /// Cut line `lo ..= hi` (along `along`, the other offset at `fixed`) into segments of
    /// equal bits: [`segments`] of the tests.
    fn line<const C: usize>(&self, along: Along, fixed: i64, lo: i64, hi: i64, out: &mut Segments<C>) {
        segments(self.tests(), along, fixed, lo, hi, out)
    }
    /// The last line of a run of lines cut alike from `start` toward `end`: [`run_end`] of
    /// the tests.
    fn run_end(&self, along: Along, start: i64, end: i64, lo: i64, hi: i64) -> i64 {
        run_end(self.tests(), along, start, end, lo, hi)
    }
}

impl Rule for Visit {
    fn tests(&self) -> &[Test] {
        &self.tests
    }

    fn verdict(&self, bits: u64, stays: bool) -> Verdict {
        Visit::verdict(self, bits, stays)
    }

    fn outside(&self, bits: u64) -> bool {
        Visit::outside(self, bits)
    }
}

/// The spans of a line's segments ([`spans`]) with neighbours of the same verdict and
/// [`Rule::outside`] joined: `(start, stop, verdict, outside)`.
pub fn verdict_spans<'a, R: Rule, const C: usize>(
    rule: &'a R,
    seg: &'a Segments<C>,
    hi: i64,
    stays: bool,
) -> impl Iterator<Item = (i64, i64, Verdict, bool)> + 'a {
    let mut it =
        spans(seg, hi).map(move |(a, b, bits)| (a, b, rule.verdict(bits, stays), rule.outside(bits))).peekable();
    core::iter::from_fn(move || {
        let (start, mut stop, v, o) = it.next()?;
        while let Some(&(_, s, v2, o2)) = it.peek() {
            if (v2, o2) != (v, o) {
                break;
            }
            stop = s;
            it.next();
        }
        Some((start, stop, v, o))
    })
}

/// The last line, moving from `start` toward `end`, of a run of lines whose verdict spans
/// ([`verdict_spans`], rays leaving the column) equal those of line `start` across `lo ..= hi`:
/// [`Rule::run_end`]'s run, then line by line while the verdicts fall alike. `seg` holds line
/// `start`'s segments; `next` is scratch.
pub fn verdict_run_end<R: Rule, const C: usize>(
    rule: &R,
    along: Along,
    (start, end): (i64, i64),
    (lo, hi): (i64, i64),
    seg: &Segments<C>,
    next: &mut Segments<C>,
) -> i64 {
    let step = if end >= start { 1 } else { -1 };
    let mut last = rule.run_end(along, start, end, lo, hi);
    while last != end {
        let line = last + step;
        rule.line(along, line, lo, hi, next);
        if !verdict_spans(rule, seg, hi, false).eq(verdict_spans(rule, next, hi, false)) {
            break;
        }
        last = rule.run_end(along, line, end, lo, hi);
    }
    last
}

/// A dexel's plane seen along the rays of one source and direction: `V(a, b, t)` has the sign of
/// g at the point of parameter t of lattice ray (a, b) (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RayPlane {
    k0: i128,
    kw: i128,
    cb: i128,
    cg: i128,
    /// How far (sixteenths of a voxel) the rays' origin lies behind layer 0's centre plane
    /// along the direction: the point of parameter t is at distance `T = max(16·t − lead, 0)`
    /// sixteenths from the origin. 0 for rays from the source voxel's centre plane (the
    /// machine's), `s·(S_w − 16·V_w)` for rays from the light itself ([`crate::occluder`]).
    lead: i64,
    /// A facet of an open surface ([`crate::plane::TWO_SIDED`]): rule 4 reads "behind" only
    /// when the plane faces the source (see the module doc). Only a voxel's own plane reads it,
    /// not the visible surface's.
    two_sided: bool,
}

impl RayPlane {
    /// The plane of a dexel of column (x, y) whose first voxel is `lo` (`reference` = (x, y, lo)),
    /// along the rays of `source` in `dir` (from its [`crate::beam::Origin`]).
    pub fn new<F: FracBits>(
        plane: &DexelPlane,
        reference: [i64; 3],
        source: &Source,
        dir: Direction,
        far: FarDistance<F>,
    ) -> Self {
        let df = far.scaled() as i128;
        let l = 16 * df;
        let c = [(plane.nx as i128) << 16, (plane.ny as i128) << 16, plane.nz as i128];
        let w = dir.principal().index();
        let (ua, va) = dir.transverse();
        let (u, v) = (ua.index(), va.index());
        let (o, lead) = (source.ray_origin(dir), source.lead(dir));
        // L·(O − reference) per axis, O in sixteenths.
        let rel = |i: usize| df * o[i] as i128 - l * reference[i] as i128;
        let k0 = c[w] * rel(w) + c[u] * rel(u) + c[v] * rel(v) + (1i128 << 16) * l * plane.e as i128;
        RayPlane { k0, kw: c[w] * df * dir.sign() as i128, cb: c[u], cg: c[v], lead, two_sided: plane.two_sided() }
    }

    /// A plane given by its coefficients: `value(a, b, t) = k0 + T·(kw + cb·a + cg·b)` with
    /// `T = max(16·t − lead, 0)` (see [`RayPlane::value`]). The caller keeps every term within
    /// `i128` ([`crate::occluder`] documents its budget).
    pub(crate) const fn from_coefficients(k0: i128, kw: i128, cb: i128, cg: i128, lead: i64) -> Self {
        RayPlane { k0, kw, cb, cg, lead, two_sided: false }
    }

    /// 16 × the distance along the direction from the rays' origin to the point of parameter
    /// t, clamped at the origin: `max(16·t − lead, 0)`.
    fn t16(&self, t: i64) -> i128 {
        (16 * t as i128 - self.lead as i128).max(0)
    }

    /// `2¹⁶·L·g` at ray (a, b)'s point of parameter t (for a dexel's plane: `k0 + 16·t·(kw +
    /// cb·a + cg·b)`).
    pub fn value(&self, a: i64, b: i64, t: i64) -> i128 {
        self.k0 + self.t16(t) * self.form(a, b)
    }

    /// The part of [`RayPlane::value`] that depends on the ray only: `value = k0 + T·form`.
    pub(crate) fn form(&self, a: i64, b: i64) -> i128 {
        self.kw + self.cb * a as i128 + self.cg * b as i128
    }

    /// Whether the value is positive at parameter t for a ray whose [`RayPlane::form`] is
    /// `form` (several layers of one ray for the price of one form).
    pub(crate) fn positive_with(&self, form: i128, t: i64) -> bool {
        self.k0 + self.t16(t) * form > 0
    }

    /// Whether the plane faces the source: g > 0 at the rays' origin (T = 0, the same point for
    /// every ray: Se for the machine's rays, the light for [`crate::beam::Origin::Light`]).
    pub fn faces_source(&self) -> bool {
        self.k0 > 0
    }

    /// The plane in `i64` for rays with |a|, |b| ≤ `n` and parameters with `T ≤ t_max`, if every
    /// value it can take there, `|k0| + t_max·(|kw| + (|cb| + |cg|)·n)`, is below 2⁶³: then no
    /// partial sum of [`Narrow::form`] or [`Narrow::positive_with`] overflows and their signs are
    /// this plane's (the same tests at a third of the multiplications). `None` otherwise (a
    /// large grid or far distance): the caller evaluates in `i128`.
    ///
    /// Decided on bit lengths (one test per beam and undecided edge: no 128-bit product): with
    /// `|kw| < 2^bw`, `max(|cb|, |cg|) < 2^bc`, `t_max < 2^bt` and `n < 2^bn`, the terms
    /// `t_max·|kw| < 2^(bw+bt)` and `t_max·(|cb| + |cg|)·n < 2^(bc+1+bn+bt)` each at most 2⁶⁰
    /// and `|k0| < 2⁶¹` keep the sum below 2⁶². A refused plane's bound is at least 2⁵⁷.
    pub(crate) fn narrow(&self, n: i64, t_max: i64) -> Option<Narrow> {
        let bits = |x: u128| 128 - x.leading_zeros();
        let bt = bits(t_max.unsigned_abs() as u128);
        let along = bits(self.kw.unsigned_abs()) + bt;
        let across = bits(self.cb.unsigned_abs() | self.cg.unsigned_abs()) + 1 + bits(n.unsigned_abs() as u128) + bt;
        (bits(self.k0.unsigned_abs()) <= 61 && along <= 60 && across <= 60).then_some(Narrow {
            k0: self.k0 as i64,
            kw: self.kw as i64,
            cb: self.cb as i64,
            cg: self.cg as i64,
            lead: self.lead,
            n,
        })
    }
}

/// A [`RayPlane`] whose values fit `i64` for rays with |a|, |b| ≤ `n` ([`RayPlane::narrow`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Narrow {
    k0: i64,
    kw: i64,
    cb: i64,
    cg: i64,
    lead: i64,
    n: i64,
}

impl Narrow {
    /// Its coefficients `[k0, kw, cb, cg]`.
    pub(crate) const fn coefficients(&self) -> [i64; 4] {
        [self.k0, self.kw, self.cb, self.cg]
    }

    /// The plane `narrow(n, ·)` gave these coefficients for (lead `lead`), and the form itself.
    pub(crate) const fn rebuild(k: [i64; 4], lead: i64, n: i64) -> (RayPlane, Narrow) {
        let plane = RayPlane::from_coefficients(k[0] as i128, k[1] as i128, k[2] as i128, k[3] as i128, lead);
        (plane, Self::of(k, lead, n))
    }

    /// The form alone of [`Narrow::rebuild`] (no `i128` plane: for a reader that may need
    /// only its signs).
    pub(crate) const fn of(k: [i64; 4], lead: i64, n: i64) -> Narrow {
        Narrow { k0: k[0], kw: k[1], cb: k[2], cg: k[3], lead, n }
    }

    /// Whether ray (a, b) is one this form is exact for (|a|, |b| ≤ n).
    #[inline]
    pub(crate) fn covers(&self, a: i64, b: i64) -> bool {
        a.abs() <= self.n && b.abs() <= self.n
    }

    /// [`RayPlane::form`] for a ray it [`Narrow::covers`].
    #[inline]
    pub(crate) fn form(&self, a: i64, b: i64) -> i64 {
        self.kw + self.cb * a + self.cg * b
    }

    /// [`RayPlane::positive_with`] (T within the `t_max` it was narrowed for).
    #[inline]
    pub(crate) fn positive_with(&self, form: i64, t: i64) -> bool {
        self.k0 + (16 * t - self.lead).max(0) * form > 0
    }
}

/// One test of the rule: σ_t of a plane ("the ray's point of parameter t is on the outward
/// side").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Test {
    /// The plane.
    pub plane: RayPlane,
    /// The ray parameter (a layer ≥ 0; −1 reads as the rays' origin, T = 0).
    pub t: i64,
}

/// Which lattice axis is held fixed when a test is read along the other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Along {
    /// Columns: a (the u offset) fixed, b varies.
    V,
    /// Rows: b (the v offset) fixed, a varies.
    U,
}

/// ⌊n/d⌋ for d > 0.
///
/// On a 32-bit ARM core (the firmware) through [`floor_div_bitwise`]: LLVM expands an `i128`
/// division inline there, 1.1 KB of flash; elsewhere `div_euclid`. Both are exact, the same
/// quotient for every `n` and `d > 0` (the unit test `floor_div_bitwise_is_div_euclid`).
#[inline]
pub(crate) fn floor_div(n: i128, d: i128) -> i128 {
    if cfg!(target_arch = "arm") {
        floor_div_bitwise(n, d)
    } else {
        n.div_euclid(d)
    }
}

/// ⌊n/d⌋ for d > 0, one quotient bit per step (restoring division of |n| by d, then the floor
/// for a negative `n`): small code; speed does not matter (a few per lit test).
#[inline(never)]
pub(crate) fn floor_div_bitwise(n: i128, d: i128) -> i128 {
    debug_assert!(d > 0);
    let (a, d) = (n.unsigned_abs(), d as u128);
    let (mut q, mut r) = (0u128, 0u128);
    for i in (0..128).rev() {
        r = r << 1 | (a >> i & 1);
        if r >= d {
            r -= d;
            q |= 1 << i;
        }
    }
    // n < 0: n = -(q·d + r), so ⌊n/d⌋ = -q when r = 0, else -q - 1.
    if n < 0 {
        -(q as i128) - (r != 0) as i128
    } else {
        q as i128
    }
}

impl Test {
    /// Whether the test holds for ray (a, b).
    pub fn holds(&self, a: i64, b: i64) -> bool {
        self.plane.value(a, b, self.t) > 0
    }

    /// The offsets of `lo ..= hi` along `along` for which the test holds, with the other offset
    /// fixed at `fixed`: an interval touching one end (σ is monotone along a line of rays), as
    /// `(first, last)`, empty when first > last.
    pub fn interval(&self, along: Along, fixed: i64, lo: i64, hi: i64) -> (i64, i64) {
        let p = &self.plane;
        let tt = p.t16(self.t);
        let (fixed_c, free_c) = match along {
            Along::V => (p.cb, p.cg),
            Along::U => (p.cg, p.cb),
        };
        let a = p.k0 + tt * (p.kw + fixed_c * fixed as i128);
        let b = tt * free_c;
        if b == 0 {
            return if a > 0 { (lo, hi) } else { (hi.saturating_add(1), hi) };
        }
        // a + b·x > 0.
        let (lo128, hi128) = (lo as i128, hi as i128);
        let (first, last) = if b > 0 { (floor_div(-a, b) + 1, hi128) } else { (lo128, -floor_div(-a, -b) - 1) };
        let (first, last) = (first.max(lo128), last.min(hi128));
        if first > last {
            (hi.saturating_add(1), hi)
        } else {
            (first as i64, last as i64)
        }
    }
}

/// At most this many tests in one visit (three for the voxel's plane, three for a notch, two
/// for the visible surface).
pub const MAX_TESTS: usize = 8;

/// Segments of a line of rays: `(first offset, test bits)`, each up to the next one's first
/// offset − 1 (the last up to the line's end). At most one cut per test end: `C` ≥ twice the
/// tests plus one (the plane rule's [`MAX_TESTS`] by default, [`crate::occluder::MAX_EXACT_TESTS`]
/// for exact occluders).
pub type Segments<const C: usize = { 2 * MAX_TESTS + 1 }> = Vec<(i64, u64), C>;

/// Split `lo ..= hi` (along `along`, the other offset at `fixed`) into segments on which every
/// test in `tests` has one value (bit i: test i holds).
pub fn segments<const C: usize>(tests: &[Test], along: Along, fixed: i64, lo: i64, hi: i64, out: &mut Segments<C>) {
    debug_assert!(C > 2 * tests.len() && tests.len() <= 64);
    out.clear();
    let mut cuts: Vec<i64, C> = Vec::new();
    let mut spans: Vec<(i64, i64), C> = Vec::new();
    let _ = cuts.push(lo);
    for t in tests {
        let (f, l) = t.interval(along, fixed, lo, hi);
        let _ = spans.push((f, l));
        if f <= l {
            for c in [f, l.saturating_add(1)] {
                if c > lo && c <= hi && !cuts.contains(&c) {
                    let at = cuts.iter().position(|&x| x > c).unwrap_or(cuts.len());
                    // Cannot fail: at most 2 cuts per test plus `lo`.
                    let _ = cuts.insert(at, c);
                }
            }
        }
    }
    for &c in &cuts {
        let bits = spans.iter().enumerate().fold(0u64, |m, (i, &(f, l))| m | (((f <= c && c <= l) as u64) << i));
        let _ = out.push((c, bits));
    }
}

/// The segments of [`segments`] as `(start, stop, bits)`, inclusive, the last ending at `hi`
/// (the `hi` that split them).
pub fn spans<const C: usize>(seg: &Segments<C>, hi: i64) -> impl Iterator<Item = (i64, i64, u64)> + '_ {
    seg.iter().enumerate().map(move |(i, &(start, bits))| (start, seg.get(i + 1).map_or(hi, |s| s.0 - 1), bits))
}

/// Whether every test in `tests` has the same value on the whole rectangle `[a0, a1] × [b0, b1]`
/// (a test holds on a half-plane: it is constant on a rectangle iff it agrees on the corners).
pub fn uniform(tests: &[Test], a: (i64, i64), b: (i64, i64)) -> Option<u64> {
    let mut bits = 0u64;
    for (i, t) in tests.iter().enumerate() {
        let c = [t.holds(a.0, b.0), t.holds(a.0, b.1), t.holds(a.1, b.0), t.holds(a.1, b.1)];
        if c.iter().any(|&x| x != c[0]) {
            return None;
        }
        bits |= (c[0] as u64) << i;
    }
    Some(bits)
}

/// The last line (offset along the run direction, moving from `start` toward `end`) whose test
/// intervals across `lo ..= hi` equal those of line `start`: a run of lines with the same
/// segments. Each interval's ends are monotone in the line, so each test's equal lines form an
/// interval: binary search per test.
pub fn run_end(tests: &[Test], along: Along, start: i64, end: i64, lo: i64, hi: i64) -> i64 {
    let mut reach = end;
    for t in tests {
        let want = t.interval(along, start, lo, hi);
        let same = |line: i64| t.interval(along, line, lo, hi) == want;
        // Invariant: `good` is equal, `bad` (if moved) is not; search between them.
        let (mut good, mut bad) = (start, reach);
        if same(bad) {
            continue;
        }
        while (bad - good).abs() > 1 {
            let mid = good + (bad - good) / 2;
            if same(mid) {
                good = mid;
            } else {
                bad = mid;
            }
        }
        reach = good;
    }
    reach
}

/// Rays excluded from a beam that stays in its column (see the column rule in the module doc):
/// those whose σ for the plane of the column's dexel at `state` changed between layers `t1` and
/// `t2` (and with `front`, those with σ = 0 at both). With `fresh`, those whose σ changes between `t2` and `t2 + 1` are terminal at layer
/// `t2 + 1`, the beam's layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Notch {
    /// A voxel of the dexel whose plane cut the beam (the rays' column state).
    pub state: u16,
    /// First layer of the excluded crossing.
    pub t1: u16,
    /// Last layer of the excluded crossing.
    pub t2: u16,
    /// The rays crossing between t2 and t2 + 1 are terminal at this layer.
    pub fresh: bool,
    /// The rays behind the plane at both t1 and t2 are excluded too (rule 4 absorbed them for
    /// the way they arrived, [`Visit::absorbs_behind`]).
    pub front: bool,
}

/// What happens to a set of rays with the same test bits at one visit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Out {
    /// Not in the beam (a notch excludes them).
    Absent,
    /// Stopped here.
    Absorbed,
    /// Go on to the next layer.
    Continue,
    /// Go on one more layer as terminal rays.
    Terminal,
}

impl Out {
    /// The rays are in the beam (no notch cut them out).
    pub fn present(self) -> bool {
        self != Out::Absent
    }

    /// The rays leave the voxel for the next layer (terminal or not).
    pub fn goes_on(self) -> bool {
        matches!(self, Out::Continue | Out::Terminal)
    }
}

/// The verdict on rays with the same test bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Verdict {
    /// Where they go.
    pub out: Out,
    /// They light the voxel (its own plane).
    pub lit: bool,
    /// They light the column's visible surface.
    pub visible: bool,
}

/// How a beam's rays arrive at a voxel: the plane rule's flags it carries
/// ([`crate::beam::Beam`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Arrival {
    /// The rays are terminal: they act at this voxel and die.
    pub terminal: bool,
    /// The rays were in an empty voxel at the previous layer.
    pub after_empty: bool,
    /// The rays were in an occupied voxel of another column at the previous layer, on the
    /// outside of its plane.
    pub after_outside: bool,
}

impl Arrival {
    /// A plain beam: none of the flags.
    pub const NONE: Arrival = Arrival { terminal: false, after_empty: false, after_outside: false };

    /// The flags `beam` carries.
    pub const fn of<F: FracBits>(beam: &crate::beam::Beam<F>) -> Self {
        Arrival { terminal: beam.is_terminal(), after_empty: beam.after_empty(), after_outside: beam.after_outside() }
    }
}

/// Everything the plane rule needs about one beam at one voxel, and the tests it reads.
#[derive(Clone, Debug)]
pub struct Visit {
    /// The tests, in the order [`Visit::verdict`] reads their bits.
    pub tests: Vec<Test, MAX_TESTS>,
    /// Index of the voxel's own σ₋, σ_k, σ_{k+1} (when occupied), whether its plane faces the
    /// source, and whether it is two-sided.
    own: Option<(usize, bool, bool)>,
    /// Index of the notch's σ_{t1}, σ_{t2} (and σ_{t2+1} when fresh), and its `fresh`, `front`.
    notch: Option<(usize, bool, bool)>,
    /// Index of the visible surface's σ₋, σ_k (when the voxel brackets it and it faces the source).
    visible: Option<usize>,
    /// How the beam arrived.
    arrival: Arrival,
    /// Staying rays meet another dexel than their state's: the column rule absorbs them.
    other_dexel: bool,
}

impl Visit {
    /// A visit at layer `k` of a beam that arrived as `arrival`, in a voxel whose dexel's
    /// plane is `own` (None: empty), with `notch` (plane and notch) and the visible surface's
    /// plane when the voxel brackets it; `other_dexel`: the beam has a column state and the
    /// voxel is occupied by another dexel.
    pub fn new(
        k: i64,
        arrival: Arrival,
        own: Option<RayPlane>,
        notch: Option<(RayPlane, Notch)>,
        visible: Option<RayPlane>,
        other_dexel: bool,
    ) -> Self {
        let mut tests = Vec::new();
        let prev = (k - 1).max(0);
        let own = own.map(|p| {
            let i = tests.len();
            for t in [prev, k, k + 1] {
                let _ = tests.push(Test { plane: p, t });
            }
            (i, p.faces_source(), p.two_sided)
        });
        let notch = notch.map(|(p, n)| {
            let i = tests.len();
            for t in [n.t1 as i64, n.t2 as i64, n.t2 as i64 + 1] {
                let _ = tests.push(Test { plane: p, t });
            }
            (i, n.fresh, n.front)
        });
        let visible = visible.filter(RayPlane::faces_source).map(|p| {
            let i = tests.len();
            for t in [prev, k] {
                let _ = tests.push(Test { plane: p, t });
            }
            i
        });
        Visit { tests, own, notch, visible, arrival, other_dexel }
    }

    /// Whether the visit needs no test at all: an empty voxel that does not bracket the visible
    /// surface, for a plain beam (the fast path of the thesis's machine).
    pub fn is_plain(&self) -> bool {
        self.tests.is_empty() && !self.arrival.terminal
    }

    /// Whether the rays behind the voxel's plane at both layers (σ₋ = σ_k = 0) are absorbed
    /// for the way they arrived (rule 4): after an empty voxel into a plane facing the source
    /// or one-sided, or after the outside of another column's plane into a plane facing the
    /// source.
    pub fn absorbs_behind(&self) -> bool {
        let Some((_, faces, two_sided)) = self.own else { return false };
        (self.arrival.after_empty && (faces || !two_sided)) || (self.arrival.after_outside && faces)
    }

    /// Whether rays with test bits `bits` are on the outside of the voxel's plane at this
    /// layer (σ_k; false in an empty voxel): what [`Arrival::after_outside`] records for the
    /// next voxel.
    pub fn outside(&self, bits: u64) -> bool {
        self.own.is_some_and(|(i, _, _)| bits >> (i + 1) & 1 == 1)
    }

    /// The verdict on rays whose test bits are `bits`; `stays`: they stay in the column (a ±z
    /// beam's rays whose voxel at the next layer is in this column).
    pub fn verdict(&self, bits: u64, stays: bool) -> Verdict {
        let bit = |i: usize| bits >> i & 1 == 1;
        let mut v = Verdict { out: Out::Continue, lit: false, visible: false };
        let mut terminal = self.arrival.terminal;
        if let Some((i, fresh, front)) = self.notch {
            if bit(i) != bit(i + 1) || (front && !bit(i) && !bit(i + 1)) {
                v.out = Out::Absent;
                return v;
            }
            terminal |= fresh && bit(i + 1) != bit(i + 2);
        }
        if let Some(i) = self.visible {
            v.visible = bit(i) || bit(i + 1);
        }
        let own = self.own.map(|(i, front, two_sided)| (bit(i), bit(i + 1), bit(i + 2), front, two_sided));
        if let Some((prev, now, _, front, two_sided)) = own {
            // On the source's side at layer k − 1 or k: the outer side of a plane facing the
            // source, or the inner side of a two-sided one facing away.
            v.lit = if front { prev || now } else { two_sided && !(prev && now) };
        }
        if terminal {
            v.out = Out::Absorbed;
            return v;
        }
        let Some((prev, now, next, _, _)) = own else {
            return v;
        };
        v.out = if prev != now || (stays && self.other_dexel) || (self.absorbs_behind() && !prev && !now) {
            Out::Absorbed
        } else if now != next {
            Out::Terminal
        } else {
            Out::Continue
        };
        v
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    /// Which voxels receive a column's light, against the definitions each rule's cell reads
    /// elsewhere: the thesis's first voxel, the plane rule's two bracketing voxels
    /// ([`VisibleSurface::brackets`]), exact occluders' three ([`VisibleSurface::receives`]).
    #[test]
    fn each_rule_receives_where_its_cell_reads_the_pixel() {
        use crate::normal::NormalCode;
        let plane = DexelPlane { id: 0, nx: 0, ny: 0, nz: -(16384 << 16), e: 8192 };
        for z_v in -1..8 {
            let v = VisibleSurface {
                num: 2 * z_v as i64 + 1,
                den: 2,
                facet: 0,
                material: 0,
                normal: NormalCode::default(),
                plane,
                z_v,
            };
            for first in [None, Some(0), Some(3)] {
                for z in 0..10u16 {
                    assert_eq!(LitRule::Thesis.receives(first, Some(&v), z), first == Some(z));
                    assert_eq!(LitRule::Plane.receives(first, Some(&v), z), v.brackets(z as i64));
                    assert!(!LitRule::Plane.receives(first, None, z));
                    #[cfg(feature = "exact-occluders")]
                    assert_eq!(LitRule::Exact.receives(first, Some(&v), z), v.receives(z as i64));
                }
            }
        }
        for &r in LitRule::ALL {
            assert_eq!(r.receiver_window().is_some(), r.shades_visible_surface(), "{r:?}");
            assert_eq!(r.needs_triangles(), r.is_exact());
            assert_eq!(r.occluder_reach() > 0, r.needs_triangles());
        }
    }

    /// The firmware's division (`floor_div` on ARM) is `div_euclid`, exactly: at the ends of
    /// the range and on random values.
    #[test]
    fn floor_div_bitwise_is_div_euclid() {
        let mut x = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let edges = [0i128, 1, -1, 2, -2, 7, -7, i64::MAX as i128, i64::MIN as i128, i128::MAX, i128::MIN + 1];
        let mut cases = std::vec::Vec::new();
        for n in edges {
            for d in [1i128, 2, 3, 7, 16, i64::MAX as i128, i128::MAX] {
                cases.push((n, d));
            }
        }
        for _ in 0..20_000 {
            let n = ((next() as i128) << 64 | next() as i128) >> (next() % 100);
            let d = (((next() as i128) << 64 | next() as i128) >> (next() % 127 + 1)).abs().max(1);
            cases.push((n, d));
        }
        for (n, d) in cases {
            assert_eq!(floor_div_bitwise(n, d), n.div_euclid(d), "{n} / {d}");
        }
    }
    use crate::beam::{frac, Layer, Origin, SourceCoord, SourceId};

    fn lcg(s: &mut u64) -> u64 {
        *s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *s >> 33
    }

    /// A uniform integer in `-m ..= m`.
    fn rnd(s: &mut u64, m: u64) -> i64 {
        (lcg(s) % (2 * m + 1)) as i64 - m as i64
    }

    /// The `i64` plane ([`RayPlane::narrow`]) against the `i128` one: wherever it is offered,
    /// the same sign for every ray of the square and every parameter up to `t_max`, including
    /// coefficients at the edge of what fits (each term drawn near 2⁶³ / its multiplier) and
    /// the square's corners; and it is refused when the bound is 2⁶³ or more.
    #[test]
    fn narrow_planes_give_the_i128_signs_and_refuse_what_could_overflow() {
        let mut seed = 7u64;
        let (mut offered, mut refused) = (0, 0);
        for case in 0..20_000 {
            let n = 1 + (lcg(&mut seed) % (1 << 20)) as i64;
            let t_max = 16 * (1 + (lcg(&mut seed) % 4096) as i64);
            // Magnitudes from tiny to past the bound: scale each term by a random power of 2.
            // A term of magnitude up to min(2^bits, room) (random bits), times 1 to 3 for two
            // cases in three (past the room: refused), with a random sign.
            let mut term = |room: i128| {
                let bits = (lcg(&mut seed) % 63) as u32;
                let m = (1i128 << bits).min(room.max(1));
                let wide = ((lcg(&mut seed) << 31) | lcg(&mut seed)) as i128;
                let sign = if lcg(&mut seed) % 2 == 0 { 1 } else { -1 };
                let times = if case % 3 == 0 { 1 } else { (lcg(&mut seed) % 3) as i128 + 1 };
                sign * times * (if lcg(&mut seed) % 4 == 0 { m } else { wide % (m + 1) })
            };
            let lim = 1i128 << 63;
            let k0 = term(lim);
            let kw = term(lim / t_max as i128);
            let cb = term(lim / (t_max as i128 * n as i128));
            let cg = term(lim / (t_max as i128 * n as i128));
            let lead = (lcg(&mut seed) % 16) as i64;
            let p = RayPlane::from_coefficients(k0, kw, cb, cg, lead);
            let bound = k0.unsigned_abs()
                + t_max as u128 * (kw.unsigned_abs() + (cb.unsigned_abs() + cg.unsigned_abs()) * n as u128);
            let Some(q) = p.narrow(n, t_max) else {
                assert!(bound >= 1 << 56, "refused a plane whose bound {bound} is far below 2^63");
                refused += 1;
                continue;
            };
            assert!(bound < 1 << 63);
            offered += 1;
            for _ in 0..8 {
                let pick = |s: &mut u64| match lcg(s) % 3 {
                    0 => n,
                    1 => -n,
                    _ => rnd(s, n as u64),
                };
                let (a, b) = (pick(&mut seed), pick(&mut seed));
                let t = match lcg(&mut seed) % 3 {
                    0 => (t_max + lead) / 16,
                    1 => -1,
                    _ => (lcg(&mut seed) % (t_max as u64 / 16 + 1)) as i64,
                };
                assert!(q.covers(a, b));
                assert_eq!(
                    q.positive_with(q.form(a, b), t),
                    p.positive_with(p.form(a, b), t),
                    "{p:?} at ({a}, {b}, {t})"
                );
            }
        }
        assert!(offered > 1000 && refused > 1000, "offered {offered}, refused {refused}");
    }

    /// A random dexel plane near voxel (6, 6, 6), seen along `dir`.
    fn random_plane(s: &mut u64, src: &Source, dir: Direction, far: FarDistance<frac::U2>) -> RayPlane {
        let plane = DexelPlane {
            id: 0,
            nx: rnd(s, 16384) as i16,
            ny: rnd(s, 16384) as i16,
            nz: (rnd(s, 16384) << 16) as i32,
            e: rnd(s, 30000) as i32,
        };
        let reference = [rnd(s, 8) + 6, rnd(s, 8) + 6, rnd(s, 8) + 6];
        RayPlane::new(&plane, reference, src, dir, far)
    }

    /// `value` against the definition, in f64 where it is exact enough: g at the ray's point.
    #[test]
    fn ray_plane_value_is_scaled_g() {
        let src = Source::new(SourceId(0), [5.25, 7.5, 3.0625].map(SourceCoord::from_num));
        let far = FarDistance::<frac::U1>::new(15).unwrap();
        let plane = DexelPlane { id: 0, nx: 1200, ny: -16384, nz: 300 << 16, e: -777 };
        let reference = [6i64, 9, 4];
        for dir in Direction::ALL {
            let rp = RayPlane::new(&plane, reference, &src, dir, far);
            for (a, b, t) in [(0i64, 0i64, 0i64), (7, -3, 2), (-30, 30, 9), (13, 1, 15)] {
                let w = dir.principal().index();
                let (ua, va) = dir.transverse();
                let mut p = [0f64; 3];
                p[w] = src.voxel()[w] as f64 + dir.sign() as f64 * t as f64;
                p[ua.index()] = src.pos[ua.index()].to_num::<f64>() + (a as f64 / 2.0) * t as f64 / 15.0;
                p[va.index()] = src.pos[va.index()].to_num::<f64>() + (b as f64 / 2.0) * t as f64 / 15.0;
                let g = 1200.0 * (p[0] - 6.0) - 16384.0 * (p[1] - 9.0) + 300.0 * (p[2] - 4.0) - 777.0;
                let want = g * 65536.0 * 16.0 * 30.0;
                let got = rp.value(a, b, t) as f64;
                assert!((got - want).abs() <= want.abs() * 1e-12 + 1e-3, "{dir:?} {a} {b} {t}: {got} vs {want}");
            }
        }
    }

    /// Rays from the light: the point of layer t lies on the centre plane of layer t's slab
    /// ([`Source::slab`]), `T_t/16` voxels from the light along the axis.
    #[test]
    fn ray_plane_from_the_light_is_scaled_g() {
        let far = FarDistance::<frac::U1>::new(15).unwrap();
        let plane = DexelPlane { id: 0, nx: 1200, ny: -16384, nz: 300 << 16, e: -777 };
        // Leads of every sign, and ±8 (a light on a voxel boundary).
        let sources = [[5.25, 7.4375, 3.0625], [5.5, 6.5, 2.5625], [4.9375, 7.5, 3.4375]];
        for dir in Direction::ALL {
            for pos in sources {
                let src = Source::new(SourceId(0), pos.map(SourceCoord::from_num)).with_origin(Origin::Light);
                let rp = RayPlane::new(&plane, [6, 9, 4], &src, dir, far);
                let w = dir.principal().index();
                let (ua, va) = dir.transverse();
                let light = src.pos.map(|c| c.to_num::<f64>());
                for (a, b, t) in [(7i64, -3i64, 2i64), (-30, 30, 9), (13, 1, 15), (0, 0, 1)] {
                    let mut p = [0f64; 3];
                    p[w] = src.slab(dir, Layer(t as u32)) as f64;
                    let dist = dir.sign() as f64 * (p[w] - light[w]);
                    p[ua.index()] = light[ua.index()] + (a as f64 / 2.0) * dist / 15.0;
                    p[va.index()] = light[va.index()] + (b as f64 / 2.0) * dist / 15.0;
                    let g = 1200.0 * (p[0] - 6.0) - 16384.0 * (p[1] - 9.0) + 300.0 * (p[2] - 4.0) - 777.0;
                    let want = g * 65536.0 * 16.0 * 30.0;
                    let got = rp.value(a, b, t) as f64;
                    assert!(
                        (got - want).abs() <= want.abs() * 1e-12 + 1e-3,
                        "{dir:?} {pos:?} {a} {b} {t}: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// Intervals and segments against testing every ray, on random planes.
    #[test]
    fn intervals_and_segments_match_every_ray() {
        let mut s = 7u64;
        let src = Source::new(SourceId(0), [4.5, 6.0, 2.25].map(SourceCoord::from_num));
        let far = FarDistance::<frac::U2>::new(12).unwrap();
        for _ in 0..300 {
            let r = rnd;
            let dir = Direction::ALL[(lcg(&mut s) % 6) as usize];
            let rp = random_plane(&mut s, &src, dir, far);
            let tests: std::vec::Vec<Test> = (0..3).map(|_| Test { plane: rp, t: (lcg(&mut s) % 13) as i64 }).collect();
            let (lo, hi) = (r(&mut s, 48), r(&mut s, 48));
            let (lo, hi) = (lo.min(hi), lo.max(hi));
            let fixed = r(&mut s, 48);
            for along in [Along::V, Along::U] {
                let at = |x: i64| match along {
                    Along::V => (fixed, x),
                    Along::U => (x, fixed),
                };
                for t in &tests {
                    let (f, l) = t.interval(along, fixed, lo, hi);
                    for x in lo..=hi {
                        let (a, b) = at(x);
                        assert_eq!(f <= x && x <= l, t.holds(a, b), "{t:?} {along:?} {x}");
                    }
                }
                let mut seg: Segments = Segments::new();
                segments(&tests, along, fixed, lo, hi, &mut seg);
                assert_eq!(seg[0].0, lo);
                for (start, end, bits) in spans(&seg, hi) {
                    assert!(start <= end);
                    for x in start..=end {
                        let (a, b) = at(x);
                        let want = tests.iter().enumerate().fold(0u64, |m, (j, t)| m | ((t.holds(a, b) as u64) << j));
                        assert_eq!(bits, want);
                    }
                }
            }
            // Runs: every line from start to run_end has the same segments, the next does not.
            let (a0, a1) = (r(&mut s, 40), r(&mut s, 40));
            let (a0, a1) = (a0.min(a1), a0.max(a1));
            for (start, end) in [(a0, a1), (a1, a0)] {
                let e = run_end(&tests, Along::V, start, end, lo, hi);
                let seg_of = |x: i64| {
                    let mut g: Segments = Segments::new();
                    segments(&tests, Along::V, x, lo, hi, &mut g);
                    g
                };
                let first = seg_of(start);
                let step = if end >= start { 1 } else { -1 };
                let mut x = start;
                loop {
                    assert_eq!(seg_of(x), first, "line {x} in the run {start}..={e}");
                    if x == e {
                        break;
                    }
                    x += step;
                }
                if e != end {
                    assert_ne!(seg_of(e + step), first);
                }
            }
        }
    }

    /// A rule of three tests whose verdict depends on two of them (the third cuts lines but
    /// never changes a verdict, as a triangle's edge does beside its plane's crossing).
    struct Toy(std::vec::Vec<Test>);

    impl Rule for Toy {
        const BY_VERDICT: bool = true;
        fn tests(&self) -> &[Test] {
            &self.0
        }
        fn verdict(&self, bits: u64, _stays: bool) -> Verdict {
            let out = if bits & 0b11 == 0b11 { Out::Absorbed } else { Out::Continue };
            Verdict { out, lit: false, visible: false }
        }
        fn outside(&self, _bits: u64) -> bool {
            false
        }
    }

    /// Verdict spans join exactly the neighbours of equal verdict, and a verdict run holds the
    /// lines whose rays, one by one, have the start line's verdicts (the next line's differ).
    #[test]
    fn verdict_spans_and_runs_match_every_ray() {
        let mut s = 11u64;
        let src = Source::new(SourceId(0), [4.5, 6.0, 2.25].map(SourceCoord::from_num));
        let far = FarDistance::<frac::U2>::new(12).unwrap();
        let r = rnd;
        let mut joined = 0;
        for _ in 0..300 {
            let dir = Direction::ALL[(lcg(&mut s) % 6) as usize];
            let tests: std::vec::Vec<Test> = (0..3)
                .map(|_| Test { plane: random_plane(&mut s, &src, dir, far), t: (lcg(&mut s) % 13) as i64 })
                .collect();
            let toy = Toy(tests);
            let (lo, hi) = (r(&mut s, 48), r(&mut s, 48));
            let (lo, hi) = (lo.min(hi), lo.max(hi));
            let per_ray = |line: i64| -> std::vec::Vec<Out> {
                (lo..=hi)
                    .map(|x| {
                        let bits =
                            toy.0.iter().enumerate().fold(0u64, |m, (j, t)| m | ((t.holds(line, x) as u64) << j));
                        toy.verdict(bits, false).out
                    })
                    .collect()
            };
            let mut seg: Segments = Segments::new();
            let mut next: Segments = Segments::new();
            let line = r(&mut s, 40);
            toy.line(Along::V, line, lo, hi, &mut seg);
            let want = per_ray(line);
            let mut prev: Option<Out> = None;
            let mut x = lo;
            for (start, stop, v, _) in verdict_spans(&toy, &seg, hi, false) {
                assert_eq!(start, x);
                assert_ne!(prev, Some(v.out), "neighbours of equal verdict are joined");
                assert!(want[(start - lo) as usize..=(stop - lo) as usize].iter().all(|&o| o == v.out));
                prev = Some(v.out);
                x = stop + 1;
            }
            assert_eq!(x, hi + 1);
            let end = line + r(&mut s, 40);
            let e = verdict_run_end(&toy, Along::V, (line, end), (lo, hi), &seg, &mut next);
            let step = if end >= line { 1 } else { -1 };
            let mut y = line;
            loop {
                assert_eq!(per_ray(y), want, "line {y} in the run {line}..={e}");
                if y == e {
                    break;
                }
                y += step;
            }
            if e != end {
                assert_ne!(per_ray(e + step), want, "the run stops where the verdicts change");
            }
            joined += (e - run_end(&toy.0, Along::V, line, end, lo, hi)).abs();
        }
        // The test exercises what verdicts add: runs longer than the tests' own.
        assert!(joined > 0);
    }

    #[test]
    fn verdicts_by_hand() {
        let p = RayPlane { k0: 1, kw: 0, cb: 0, cg: 0, lead: 0, two_sided: false };
        // Own plane only: bits (σ₋, σ_k, σ_{k+1}).
        let v = Visit::new(3, Arrival::NONE, Some(p), None, None, false);
        let out = |bits, stays| v.verdict(bits, stays).out;
        assert_eq!(out(0b111, false), Out::Continue);
        assert_eq!(out(0b000, false), Out::Continue);
        assert_eq!(out(0b011, false), Out::Terminal); // σ₋ = σ_k = 1, σ_{k+1} = 0
        assert_eq!(out(0b001, false), Out::Absorbed); // crossed between k − 1 and k
        assert!(v.verdict(0b001, false).lit && v.verdict(0b110, false).lit && !v.verdict(0b000, false).lit);
        // From an empty voxel into the back of the plane (crossed in a voxel the layers skipped):
        // absorbed; from a surface voxel, or in front of the plane, not.
        let e = Visit::new(3, Arrival { after_empty: true, ..Arrival::NONE }, Some(p), None, None, false);
        assert_eq!(e.verdict(0b000, false).out, Out::Absorbed);
        assert_eq!(e.verdict(0b111, false).out, Out::Continue);
        assert_eq!(e.verdict(0b011, false).out, Out::Terminal);
        // From the outside of another column's plane into the back of one facing the source:
        // absorbed; into the back of a plane facing away (beyond a convex edge), not.
        let o = Arrival { after_outside: true, ..Arrival::NONE };
        assert_eq!(Visit::new(3, o, Some(p), None, None, false).verdict(0b000, false).out, Out::Absorbed);
        assert_eq!(Visit::new(3, o, Some(p), None, None, false).verdict(0b111, false).out, Out::Continue);
        let away = RayPlane { k0: -1, ..p };
        assert_eq!(Visit::new(3, o, Some(away), None, None, false).verdict(0b000, false).out, Out::Continue);
        // A one-sided plane facing away: behind it after an empty voxel is inside a closed
        // surface (absorbed, unlit). Two-sided, it is the source's side: the rays go on and
        // light the voxel; in front of it they go on unlit.
        assert_eq!(Visit::new(3, e.arrival, Some(away), None, None, false).verdict(0b000, false).out, Out::Absorbed);
        let open = Visit::new(3, e.arrival, Some(RayPlane { two_sided: true, ..away }), None, None, false);
        assert_eq!(open.verdict(0b000, false), Verdict { out: Out::Continue, lit: true, visible: false });
        assert_eq!(open.verdict(0b100, false), Verdict { out: Out::Terminal, lit: true, visible: false });
        assert_eq!(open.verdict(0b111, false), Verdict { out: Out::Continue, lit: false, visible: false });
        assert!(!open.absorbs_behind());
        // Two-sided and facing the source: the one-sided rule.
        let front = Visit::new(3, e.arrival, Some(RayPlane { two_sided: true, ..p }), None, None, false);
        assert_eq!(front.verdict(0b000, false).out, Out::Absorbed);
        // The column rule: staying rays meeting another dexel are absorbed.
        let w = Visit::new(3, Arrival::NONE, Some(p), None, None, true);
        assert_eq!(w.verdict(0b111, true).out, Out::Absorbed);
        assert_eq!(w.verdict(0b111, false).out, Out::Continue);
        // A terminal beam acts and dies; an empty voxel lets everything go on.
        let t = Visit::new(3, Arrival { terminal: true, ..Arrival::NONE }, Some(p), None, None, false);
        assert_eq!(t.verdict(0b111, false), Verdict { out: Out::Absorbed, lit: true, visible: false });
        assert_eq!(Visit::new(3, Arrival::NONE, None, None, None, false).verdict(0, false).out, Out::Continue);
        assert!(Visit::new(3, Arrival::NONE, None, None, None, false).is_plain());
        // A notch: bits 3.. are σ_{t1}, σ_{t2}, σ_{t2+1}.
        let n = Notch { state: 4, t1: 1, t2: 2, fresh: true, front: false };
        let v = Visit::new(3, Arrival::NONE, None, Some((p, n)), None, false);
        assert_eq!(v.verdict(0b010, false).out, Out::Absent);
        assert_eq!(v.verdict(0b011, false).out, Out::Absorbed); // terminal: crossed between 2 and 3
        assert_eq!(v.verdict(0b111, false).out, Out::Continue);
        assert_eq!(v.verdict(0b000, false).out, Out::Continue);
        let v = Visit::new(3, Arrival::NONE, None, Some((p, Notch { front: true, ..n })), None, false);
        assert_eq!(v.verdict(0b000, false).out, Out::Absent);
        assert_eq!(v.verdict(0b111, false).out, Out::Continue);
        // The visible surface's bits come after.
        let back = RayPlane { k0: -1, ..p };
        assert_eq!(
            Visit::new(3, Arrival::NONE, None, None, Some(back), false).tests.len(),
            0,
            "a back face is never lit"
        );
        let v = Visit::new(3, Arrival::NONE, None, None, Some(p), false);
        assert!(v.verdict(0b10, false).visible && !v.verdict(0b00, false).visible);
        let _ = Layer(0);
    }
}
