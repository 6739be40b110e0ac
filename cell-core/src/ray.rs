//! §2.3 — incremental discrete 3D lines: a ray that walks voxel to voxel with integer state.
//!
//! A [`Line`] goes from point A to point B, both on the lattice of 1/[`Q`] voxel (the facet and
//! source lattice; voxel `v` has its centre at lattice point `Q·v` and is the set of points p
//! with `⌊(p + Q/2) / Q⌋ = v` on each axis: round half up). Every step is decided by additions
//! and comparisons of the state carried in the ray's message, so a cell holding the ray knows
//! locally whether the next voxel is in its own column (a z step) or which of its 8 neighbours
//! owns it. Three connectivities (thesis §2.1, Fig. 2.11):
//!
//! * [`Connectivity::TwentySix`] — the 3D DDA/Bresenham line: the **major** axis m (largest
//!   |B − A|, lowest index on ties) advances by one voxel per step; every other axis takes the
//!   voxel of the continuous line at the major voxel's centre plane, rounded half up. Per minor
//!   axis the state is (voxel, remainder r ∈ [0, Q·M)) with M = |B_m − A_m|: a step adds
//!   `Q·(B_i − A_i)` to r and carries ±1 — |B_i − A_i| ≤ M, so at most one carry.
//!   It visits one voxel per major coordinate from `round(A_m)` to `round(B_m)`.
//! * [`Connectivity::Eighteen`] — the same walk, but a step that would change all three
//!   coordinates is split in two: first the major axis with the minor axis whose voxel boundary
//!   the continuous line crosses first (lowest index on ties), then the other minor.
//! * [`Connectivity::Six`] — Amanatides–Woo: the voxels the segment A → B passes through, one
//!   face at a time: the axis whose next boundary the segment reaches first (smallest
//!   `distance_i / |B_i − A_i|`, compared by cross-multiplication; lowest index on ties; only
//!   axes not yet at B's voxel) steps. It ends exactly in B's voxel after Σ|round(B_i) − round(A_i)|
//!   steps.
//!
//! **Bit budget.** Construction rejects |B_i − A_i| > [`MAX_SPAN`] = 2²⁰ lattice units (65 536
//! voxels at Q = 16, the largest grid a [`crate::units::Depth`] can address) and coordinates
//! beyond ±[`MAX_COORD`] = 2²⁶. Then, per step: 26/18 remainders stay below Q·M ≤ 2²⁴ and
//! `r + Q·d` below 2²⁵ (i32); the 18 split compares `(Q·M − r)·Q·|d_j|` products below 2⁴⁸ and
//! the 6-connected walk compares `distance_i·|d_j|` with distance_i ≤ 2²⁰ + Q: below 2⁴²: an
//! i64 product (one SMULL on a Cortex-M4). Set-up uses one i64 floor division per minor axis
//! (`(A_i + Q/2)·M + …` below 2⁴⁸). All arithmetic is checked in debug builds (overflow checks)
//! and the limits are tested at their edges.
//!
//! # Shadow rays and the plane principle (§4.1.2, §5.5.6)
//!
//! A [`ShadowRay`] walks from an emitting surface toward a source and is answered "shadow" at
//! the first occupied voxel that stops it. Under the thesis's rule every occupied voxel of
//! another facet stops it, so a ray leaving a surface at a grazing angle is stopped by the
//! staircase of its own surface (shadow *acne*; a bias of k voxels hides it and loses the
//! shadows cast within k voxels). Under the plane rule ([`crate::lit::LitRule::Plane`]) the ray
//! is the exact segment from the emitter's surface point A to the source B, walked 6-connected
//! (the voxels it passes through, with the parameter interval `[t_in, t_out]` of its part in
//! each, [`Line::exit`]), and an occupied voxel stops it **only if the segment crosses that
//! voxel's own plane inside it** ([`crate::plane`]: σ = \[g > 0\] differs at the segment's entry
//! into and exit from the voxel):
//!
//! * crossing from the plane's outward side to its inward side (*entering*) always stops it;
//! * crossing from the inward side to the outward side (*leaving*) stops it unless the segment
//!   is, where it enters that voxel, still within one normal unit of 2¹⁴ (about a voxel) of the
//!   emitter's own plane. There it is the overhang of a neighbouring facet's voxels past an
//!   edge it shares with the emitter's facet (a thick band reaches past its facet's edges):
//!   the ray, leaving the emitter outward, crosses the neighbour's plane beside that facet, not
//!   through it — and a ray outside a closed surface cannot leave it. Farther away a leaving
//!   crossing is an open sheet seen from behind, and stops the ray (sheets are opaque both
//!   ways).
//!
//! Dexels of the emitter's own plane never stop the ray. A surface whose plane does not face
//! the source emits no ray: it is in its own shadow. This is the principle of the plane lit
//! rule of [`crate::lit`] for one exact segment: a facet stops a ray only where the ray
//! crosses it. Without the overhang exception a grazing ray leaving a face near a convex edge
//! is stopped by the neighbouring face's band, and the face shows streaks of false shadow
//! (the Cornell box at n = 128: 4.1 % of pixels wrong instead of 0.3 %).
//!
//! # Shadow rays under exact occluders
//!
//! Under [`crate::lit::LitRule::Exact`] (cell-core's `exact-occluders` feature) the cells keep
//! the triangles through their columns ([`crate::occluder`]) and a shadow ray is tested against
//! them instead of against voxels: it walks the same 6-connected line from the pixel's point
//! A = (x, y, z\*) toward the source B, and in each column it enters, once, the column's
//! triangles are tested against the exact segment from the light to the point ¼ voxel in
//! front of the surface on the ray to the pixel's point — the receiver's contact segment
//! ([`crate::receiver`], "Contact shadows"; [`ExactWalk`]). One crossing and the answer is
//! "shadow". The line and the segment share their projection on the grid's plane (A and the
//! pixel's point differ only in z), so the walk enters every column the segment crosses and
//! each crossing point lies in a column that keeps the triangle: the answer is the segment
//! tested against every triangle of the scene, as long as no column's store is full. The gap
//! keeps the surface's own triangles from shadowing it; the voxels themselves stop nothing.
//! The arithmetic and its bit budget are the contact test's ([`crate::receiver`], "Bit
//! budget"): points and the source within [`crate::occluder::COORD_LIMIT`] sixteenths
//! ([`ShadowRay::exact`] refuses others), exact in `i128`.
//!
//! *Arithmetic.* The ray carries A and D = B − A (lattice units, |A_i| ≤ 2²⁶, |D_i| ≤ 2²⁰),
//! t_in = num/den with 0 ≤ num ≤ den ≤ 2²⁰ + Q, and its own plane's value along the segment.
//! The plane of a dexel of column (x, y) with first voxel `lo` at the point A + t·D, times 2²⁰
//! and den, is `2¹⁶·(nx·X + ny·Y) + nz·Z + 2²⁰·den·e` with X = den·(A_x − 16x) + num·D_x (and
//! Y, Z alike): |X| < 2⁴⁹, every product below 2⁸¹ (`i128`), exact. Its sign is the sign of g
//! there. The own plane's `2²⁰·g` at A (|·| ≤ 2⁵³: A lies on the surface within 1/32 voxel)
//! and its growth to B (|·| < 2⁵⁸) fit `i64`.

use crate::bytes::{ByteSink, DecodeError, EncodeError, PutExt, Reader};
use crate::dexel::DexelStore;
use crate::light::Port;
use crate::occluder::Triangle;
use crate::plane::{DexelPlane, PlaneId, NORMAL_SCALE};
use crate::units::FacetId;

/// Lattice units per voxel (the 1/16 voxel lattice of facets and sources).
pub const Q: i32 = 16;
/// Largest |B_i − A_i| in lattice units.
pub const MAX_SPAN: i32 = 1 << 20;
/// Largest |coordinate| in lattice units.
pub const MAX_COORD: i32 = 1 << 26;

/// How consecutive voxels of a line touch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Connectivity {
    /// Consecutive voxels share a face (Amanatides–Woo).
    Six,
    /// Consecutive voxels share a face or an edge.
    Eighteen,
    /// Consecutive voxels share a face, an edge or a corner (DDA/Bresenham).
    TwentySix,
}

impl Connectivity {
    /// All three, thinnest walk last.
    pub const ALL: [Connectivity; 3] = [Connectivity::Six, Connectivity::Eighteen, Connectivity::TwentySix];

    /// 6, 18 or 26.
    pub const fn k(self) -> u8 {
        match self {
            Connectivity::Six => 6,
            Connectivity::Eighteen => 18,
            Connectivity::TwentySix => 26,
        }
    }
}

/// Why a line cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineError {
    /// A coordinate beyond ±[`MAX_COORD`].
    CoordinateTooLarge,
    /// |B_i − A_i| beyond [`MAX_SPAN`].
    SpanTooLarge,
}

/// The voxel of a lattice coordinate (round half up).
pub const fn voxel_of(p: i32) -> i32 {
    (p + Q / 2).div_euclid(Q)
}

/// The state of a 26/18 walk (major-axis DDA).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Dda {
    /// Major axis.
    m: u8,
    /// ±1 along the major axis.
    sm: i8,
    /// Q·(B_i − A_i) per minor axis (0 for the major axis).
    inc: [i32; 3],
    /// Remainders in [0, Q·M) (unused for the major axis).
    r: [i32; 3],
    /// Q·M.
    qm: i32,
    /// Major steps left.
    left: u32,
    /// Split corner steps (18-connected).
    split: bool,
    /// The second half of a split corner step, still to be visited.
    pending: Option<[i32; 3]>,
}

/// The state of a 6-connected walk (Amanatides–Woo).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Aw {
    /// |B_i − A_i|.
    d: [i32; 3],
    /// ±1 (0 if d = 0).
    s: [i8; 3],
    /// Lattice distance from A to the next boundary on each axis (≥ 0).
    nb: [i32; 3],
    /// B's voxel.
    target: [i32; 3],
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Walk {
    Dda(Dda),
    Aw(Aw),
}

/// An incremental discrete line (see the module docs). `voxel()` is the current voxel;
/// [`Line::step`] moves to the next one.
///
/// ```
/// use cell_core::ray::{Connectivity, Line, Q};
/// // From the centre of voxel (0, 0, 0) to the centre of voxel (4, 2, 1).
/// let mut l = Line::new([0, 0, 0], [4 * Q, 2 * Q, Q], Connectivity::TwentySix).unwrap();
/// let mut path = vec![l.voxel()];
/// while let Some(v) = l.step() {
///     path.push(v);
/// }
/// assert_eq!(path.len(), 5); // one voxel per x
/// assert_eq!(*path.last().unwrap(), [4, 2, 1]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Line {
    v: [i32; 3],
    walk: Walk,
}

impl Line {
    /// The line from lattice point `a` to lattice point `b`.
    pub fn new(a: [i32; 3], b: [i32; 3], conn: Connectivity) -> Result<Line, LineError> {
        if a.iter().chain(b.iter()).any(|c| c.unsigned_abs() > MAX_COORD as u32) {
            return Err(LineError::CoordinateTooLarge);
        }
        let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        if d.iter().any(|c| c.unsigned_abs() > MAX_SPAN as u32) {
            return Err(LineError::SpanTooLarge);
        }
        Ok(match conn {
            Connectivity::Six => Line::six(a, b, d),
            Connectivity::Eighteen => Line::dda(a, b, d, true),
            Connectivity::TwentySix => Line::dda(a, b, d, false),
        })
    }

    fn dda(a: [i32; 3], b: [i32; 3], d: [i32; 3], split: bool) -> Line {
        let mut m = 0;
        for i in 1..3 {
            if d[i].abs() > d[m].abs() {
                m = i;
            }
        }
        let mm = d[m].abs();
        let sm: i32 = if d[m] < 0 { -1 } else { 1 };
        let c0 = voxel_of(a[m]);
        let c1 = voxel_of(b[m]);
        let mut v = [0; 3];
        v[m] = c0;
        let mut inc = [0; 3];
        let mut r = [0; 3];
        let qm = Q * mm;
        if mm > 0 {
            // Num_i(k) = (A_i + Q/2)·M + d_i·(sm·(c0·Q − A_m) + k·Q); voxel = ⌊Num / (Q·M)⌋.
            let off = sm as i64 * (c0 as i64 * Q as i64 - a[m] as i64);
            for i in 0..3 {
                if i == m {
                    continue;
                }
                let num = (a[i] as i64 + (Q / 2) as i64) * mm as i64 + d[i] as i64 * off;
                let qmi = qm as i64;
                v[i] = num.div_euclid(qmi) as i32;
                r[i] = num.rem_euclid(qmi) as i32;
                inc[i] = Q * d[i];
            }
        } else {
            v = a.map(voxel_of);
        }
        let left = (c1 - c0).unsigned_abs();
        Line { v, walk: Walk::Dda(Dda { m: m as u8, sm: sm as i8, inc, r, qm, left, split, pending: None }) }
    }

    fn six(a: [i32; 3], b: [i32; 3], d: [i32; 3]) -> Line {
        let v = a.map(voxel_of);
        let mut nb = [0; 3];
        let mut s = [0; 3];
        for i in 0..3 {
            s[i] = d[i].signum() as i8;
            // Voxel v spans [v·Q − Q/2, v·Q + Q/2).
            nb[i] = if d[i] > 0 { v[i] * Q + Q / 2 - a[i] } else { a[i] - (v[i] * Q - Q / 2) };
        }
        Line { v, walk: Walk::Aw(Aw { d: d.map(i32::abs), s, nb, target: b.map(voxel_of) }) }
    }

    /// The current voxel.
    pub fn voxel(&self) -> [i32; 3] {
        self.v
    }

    /// A point of the continuous line A → B, from the walk's integer state alone (a ray message
    /// carries no A): `(num, den)` with the point at `num / den` lattice units, `den > 0`.
    /// The 6-connected walk gives A itself (each axis: its next boundary less the distance from
    /// A to it); the 26/18 walk the point where the line crosses the current major voxel's
    /// centre plane, which lies in the current voxel (its minor coordinates are
    /// `(voxel·Q·M + r)/M − Q/2`, the remainder's definition read backwards; a split corner step
    /// reads the voxel its remainders belong to, the pending one). Exact: the hit points of
    /// reflected rays ([`crate::reflect::HitPoint`]) are computed from it.
    ///
    /// Bit budget: |num| ≤ (|v|·Q + Q)·M < 2²²·2²⁰ (|v| ≤ 2²² from [`MAX_COORD`], M ≤
    /// [`MAX_SPAN`]).
    pub fn point(&self) -> ([i64; 3], i64) {
        match &self.walk {
            Walk::Aw(w) => {
                let a = core::array::from_fn(|i| {
                    let s = w.s[i] as i32;
                    // The next boundary: v·Q + Q/2 ahead (s ≥ 0, d = 0 measured from v·Q − Q/2).
                    let boundary = if s < 0 { self.v[i] * Q - Q / 2 } else { self.v[i] * Q + Q / 2 };
                    if s == 0 {
                        (self.v[i] * Q - Q / 2 + w.nb[i]) as i64
                    } else {
                        (boundary - s * w.nb[i]) as i64
                    }
                });
                (a, 1)
            }
            Walk::Dda(w) => {
                let m = w.m as usize;
                let mm = (w.qm / Q) as i64;
                if mm == 0 {
                    return (self.v.map(|c| (c * Q) as i64), 1);
                }
                let base = w.pending.unwrap_or(self.v);
                let num = core::array::from_fn(|i| {
                    if i == m {
                        (base[m] * Q) as i64 * mm
                    } else {
                        base[i] as i64 * w.qm as i64 + w.r[i] as i64 - (Q / 2) as i64 * mm
                    }
                });
                (num, mm)
            }
        }
    }

    /// Voxels still to visit after the current one.
    pub fn remaining(&self) -> u32 {
        match &self.walk {
            Walk::Dda(w) => {
                let corners = if w.split { self.corner_steps_left() } else { 0 };
                w.left + corners + w.pending.is_some() as u32
            }
            Walk::Aw(w) => (0..3).map(|i| (w.target[i] - self.v[i]).unsigned_abs()).sum(),
        }
    }

    /// Corner steps still ahead (each is split in two by the 18-connected walk): a replay of
    /// the 26-connected walk, O(remaining) — for reports, not for the cell's hot path.
    fn corner_steps_left(&self) -> u32 {
        let mut probe = *self;
        if let Walk::Dda(p) = &mut probe.walk {
            p.split = false;
            p.pending = None;
        }
        let mut corners = 0;
        let mut prev = probe.v;
        while let Some(nv) = probe.step() {
            let changed = (0..3).filter(|&i| nv[i] != prev[i]).count();
            corners += (changed == 3) as u32;
            prev = nv;
        }
        corners
    }

    /// The parameter t = num / den (den > 0) at which the segment leaves the current voxel,
    /// t = 1 in B's voxel (the segment ends there): the smallest `nb_i / |D_i|` over the axes
    /// not yet at B's voxel. Only the 6-connected walk follows the segment exactly: `None` for
    /// the others.
    pub fn exit(&self) -> Option<(i32, i32)> {
        let Walk::Aw(w) = &self.walk else { return None };
        let mut best = (1, 1);
        for i in 0..3 {
            if self.v[i] != w.target[i] && (w.nb[i] as i64) * (best.1 as i64) < (best.0 as i64) * (w.d[i] as i64) {
                best = (w.nb[i], w.d[i]);
            }
        }
        Some(best)
    }

    /// Move to the next voxel; `None` (and no change) at the end of the line.
    pub fn step(&mut self) -> Option<[i32; 3]> {
        match &mut self.walk {
            Walk::Dda(w) => {
                if let Some(p) = w.pending.take() {
                    self.v = p;
                    return Some(p);
                }
                if w.left == 0 {
                    return None;
                }
                w.left -= 1;
                let m = w.m as usize;
                let mut next = self.v;
                next[m] += w.sm as i32;
                // Boundary-crossing "time" of each minor axis within this step, as a fraction
                // num / den (only for axes that carry).
                let mut cross: [Option<(i64, i64)>; 3] = [None; 3];
                for i in 0..3 {
                    if i == m || w.inc[i] == 0 {
                        continue;
                    }
                    let old = w.r[i];
                    let r = old + w.inc[i];
                    if r >= w.qm {
                        w.r[i] = r - w.qm;
                        next[i] += 1;
                        cross[i] = Some(((w.qm - old) as i64, w.inc[i] as i64));
                    } else if r < 0 {
                        w.r[i] = r + w.qm;
                        next[i] -= 1;
                        cross[i] = Some((old as i64, -(w.inc[i] as i64)));
                    } else {
                        w.r[i] = r;
                    }
                }
                let carried: [usize; 2] = {
                    let mut it = (0..3).filter(|&i| cross[i].is_some());
                    [it.next().unwrap_or(3), it.next().unwrap_or(3)]
                };
                if w.split && carried[1] < 3 {
                    let (i, j) = (carried[0], carried[1]);
                    let (ni, di) = cross[i].unwrap_or((0, 1));
                    let (nj, dj) = cross[j].unwrap_or((0, 1));
                    // i first iff ni/di ≤ nj/dj (lowest index on ties).
                    let first = if ni * dj <= nj * di { i } else { j };
                    let mut mid = self.v;
                    mid[m] = next[m];
                    mid[first] = next[first];
                    w.pending = Some(next);
                    self.v = mid;
                    return Some(mid);
                }
                self.v = next;
                Some(next)
            }
            Walk::Aw(w) => {
                let mut best: Option<usize> = None;
                for i in 0..3 {
                    if self.v[i] == w.target[i] {
                        continue;
                    }
                    best = match best {
                        None => Some(i),
                        // i beats b iff nb_i / d_i < nb_b / d_b.
                        Some(b) if (w.nb[i] as i64) * (w.d[b] as i64) < (w.nb[b] as i64) * (w.d[i] as i64) => Some(i),
                        keep => keep,
                    };
                }
                let i = best?;
                self.v[i] += w.s[i] as i32;
                w.nb[i] += Q;
                Some(self.v)
            }
        }
    }
}

/// Largest |voxel coordinate| a decoded line may hold: the voxels of lattice points within
/// ±[`MAX_COORD`].
const MAX_VOXEL: i32 = MAX_COORD / Q + 1;
/// Most steps along one axis a decoded line may have left: a span of [`MAX_SPAN`].
const MAX_STEPS: i32 = MAX_SPAN / Q + 1;

/// Bytes of [`Line::put`] at most: a 26/18 walk with a pending voxel.
pub const LINE_BYTES: usize = 58;

impl Line {
    /// Write the walk's state, what a ray message carries (all integers little-endian):
    ///
    /// * a tag u8: 0 the 6-connected walk, 1 the 26-connected, 2 the 18-connected; the current
    ///   voxel 3×i32;
    /// * 6-connected: |B − A| 3×i32, the step signs u8 (2 bits per axis, two's complement),
    ///   the lattice distances to the next boundaries 3×i32, B's voxel 3×i32 (50 bytes);
    /// * 26/18: u8 with the major axis (bits 0–1), a negative major step (bit 2) and a pending
    ///   split step (bit 3); the increments 3×i32, the remainders 3×i32, Q·M i32, the major
    ///   steps left u32, and the pending voxel 3×i32 when bit 3 is set (46 or 58 bytes).
    ///
    /// ```
    /// use cell_core::ray::{Connectivity, Line, Q, LINE_BYTES};
    /// use cell_core::wire::{Reader, SliceWriter};
    ///
    /// let mut line = Line::new([0, 0, 0], [3 * Q, 2 * Q, Q], Connectivity::Eighteen).unwrap();
    /// line.step(); // mid-walk: a corner step split in two, its second half pending
    /// let mut buf = [0u8; LINE_BYTES];
    /// let mut w = SliceWriter::new(&mut buf);
    /// line.put(&mut w).unwrap();
    /// let len = w.len();
    /// let mut copy = Line::get(&mut Reader::new(&buf[..len])).unwrap();
    /// assert_eq!(copy, line);
    /// assert_eq!((copy.step(), copy.remaining()), (line.clone().step(), line.remaining() - 1));
    /// ```
    pub fn put<S: ByteSink + ?Sized>(&self, w: &mut S) -> Result<(), EncodeError> {
        let tag = match &self.walk {
            Walk::Aw(_) => 0,
            Walk::Dda(d) => 1 + d.split as u8,
        };
        w.u8(tag)?;
        for c in self.v {
            w.i32(c)?;
        }
        match &self.walk {
            Walk::Aw(a) => {
                a.d.iter().try_for_each(|&c| w.i32(c))?;
                w.u8((0..3).fold(0, |m, i| m | ((a.s[i] as u8) & 3) << (2 * i)))?;
                a.nb.iter().chain(&a.target).try_for_each(|&c| w.i32(c))
            }
            Walk::Dda(d) => {
                w.u8(d.m | ((d.sm < 0) as u8) << 2 | (d.pending.is_some() as u8) << 3)?;
                d.inc.iter().chain(&d.r).try_for_each(|&c| w.i32(c))?;
                w.i32(d.qm)?;
                w.u32(d.left)?;
                d.pending.iter().flatten().try_for_each(|&c| w.i32(c))
            }
        }
    }

    /// Read a walk written by [`Line::put`]. The state is checked to be one a line within the
    /// bit budget can reach (voxels within ±2²² + 1, spans within [`MAX_SPAN`], remainders in
    /// range, steps toward the end voxel), so that walking it cannot overflow or panic; a value
    /// outside is [`DecodeError::BadValue`].
    pub fn get(r: &mut Reader<'_>) -> Result<Line, DecodeError> {
        let tag = r.u8()?;
        let v = [r.i32()?, r.i32()?, r.i32()?];
        if v.iter().any(|c| c.unsigned_abs() > MAX_VOXEL as u32) {
            return Err(DecodeError::BadValue("line voxel"));
        }
        let walk = match tag {
            0 => Walk::Aw(Aw::get(r, v)?),
            1 | 2 => Walk::Dda(Dda::get(r, v, tag == 2)?),
            _ => return Err(DecodeError::BadValue("line walk")),
        };
        Ok(Line { v, walk })
    }
}

impl Aw {
    /// The 6-connected walk's state after the current voxel `v` ([`Line::get`]).
    fn get(r: &mut Reader<'_>, v: [i32; 3]) -> Result<Aw, DecodeError> {
        let d = [r.i32()?, r.i32()?, r.i32()?];
        let signs = r.u8()?;
        let s = [0, 1, 2].map(|i| ((signs >> (2 * i)) << 6) as i8 >> 6);
        let nb = [r.i32()?, r.i32()?, r.i32()?];
        let target = [r.i32()?, r.i32()?, r.i32()?];
        for i in 0..3 {
            // A step sign (±1) on exactly the axes that move.
            if !(0..=MAX_SPAN).contains(&d[i]) || s[i] < -1 || (s[i] == 0) != (d[i] == 0) || signs >> 6 != 0 {
                return Err(DecodeError::BadValue("line span"));
            }
            // The end voxel lies ahead along the step's sign (or is reached).
            let ahead = target[i].abs_diff(v[i]);
            let toward = (target[i] > v[i]) as i8 - (target[i] < v[i]) as i8;
            if !(0..=MAX_SPAN + 2 * Q).contains(&nb[i]) || ahead > MAX_STEPS as u32 || (toward != 0 && toward != s[i]) {
                return Err(DecodeError::BadValue("line boundary"));
            }
        }
        Ok(Aw { d, s, nb, target })
    }
}

impl Dda {
    /// The 26- (or, `split`, 18-) connected walk's state after the current voxel `v`
    /// ([`Line::get`]).
    fn get(r: &mut Reader<'_>, v: [i32; 3], split: bool) -> Result<Dda, DecodeError> {
        let b = r.u8()?;
        let (m, sm, pending) = (b & 3, if b & 4 != 0 { -1 } else { 1 }, b & 8 != 0);
        let inc = [r.i32()?, r.i32()?, r.i32()?];
        let rem = [r.i32()?, r.i32()?, r.i32()?];
        let (qm, left) = (r.i32()?, r.u32()?);
        let pending = if pending { Some([r.i32()?, r.i32()?, r.i32()?]) } else { None };
        if m > 2 || b >> 4 != 0 || !(0..=Q * MAX_SPAN).contains(&qm) || left > MAX_STEPS as u32 {
            return Err(DecodeError::BadValue("line axis"));
        }
        let minor_ok = |i: usize| {
            let (inc, rem) = (inc[i], rem[i]);
            if i == m as usize || qm == 0 {
                inc == 0 && rem == 0
            } else {
                inc.unsigned_abs() <= qm as u32 && (0..qm).contains(&rem)
            }
        };
        if !(0..3).all(minor_ok) || (qm == 0 && left != 0) {
            return Err(DecodeError::BadValue("line remainder"));
        }
        if pending.is_some_and(|p| p.iter().zip(&v).any(|(a, b)| a.abs_diff(*b) > 1)) {
            return Err(DecodeError::BadValue("line pending voxel"));
        }
        Ok(Dda { m, sm, inc, r: rem, qm, left, split, pending })
    }
}

/// The 2D cell step (dx, dy) between two consecutive voxels of a line, or `None` when the
/// next voxel is in the same column (a z step, handled inside the cell).
pub fn cell_step(from: [i32; 3], to: [i32; 3]) -> Option<(i8, i8)> {
    let (dx, dy) = ((to[0] - from[0]) as i8, (to[1] - from[1]) as i8);
    if dx == 0 && dy == 0 {
        None
    } else {
        Some((dx, dy))
    }
}

/// A shadow ray in flight (§4.1.2): its line toward the source, the cell waiting for the
/// answer, and the facet of the emitting voxel (a planar facet cannot shadow its own points:
/// hits on it are ignored, which removes the discrete "self-shadowing" of thick surfaces).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ShadowRay {
    /// The walk, its current voxel in the column of the cell holding the ray.
    pub line: Line,
    /// The cell that emitted the ray and waits for the answer.
    pub emitter: [u16; 2],
    /// The facet of the emitting voxel.
    pub facet: FacetId,
    /// The emitting voxel's z (its answer tells which voxel of the column it is about).
    pub emitter_z: i32,
    /// Whether the current voxel is still the emitter's own (not tested).
    pub fresh: bool,
    /// Voxels after the emitter's own still to pass untested: the shadow bias
    /// ([`ShadowRay::with_bias`]).
    pub grace: u8,
    /// Whether the answer is about the surface the emitter's pixel shows.
    pub surface: bool,
    /// What the rule the ray runs carries (see the module doc).
    pub walk: RayWalk,
}

/// The state a [`ShadowRay`] carries for its lit rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RayWalk {
    /// The thesis's rule: occupied voxels of other facets stop the ray.
    Thesis,
    /// The plane principle.
    Plane(PlaneWalk),
    /// Exact occluders.
    Exact(ExactWalk),
}

/// What a shadow ray under exact occluders carries (see the module doc, "Shadow rays under
/// exact occluders"): the segment its columns' triangles are tested against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ExactWalk {
    /// The segment's near end: ¼ voxel in front of the emitter's surface on the exact ray to
    /// its point, in 1/[`crate::receiver::POINT_UNITS`] voxel; `None` when the source itself
    /// is not that far in front (nothing to test: the ray walks to the source untested).
    pub near: Option<[i64; 3]>,
    /// The segment's far end, the source (lattice units).
    pub source: [i32; 3],
    /// Whether the current column's triangles are still to test.
    pub untested: bool,
}

impl ExactWalk {
    /// Whether one of `triangles` crosses the segment.
    pub fn blocked_by(&self, triangles: &[Triangle]) -> bool {
        let s = self.source.map(|c| c as i64 * (crate::receiver::POINT_UNITS / Q as i64));
        self.near.is_some_and(|x1| triangles.iter().any(|t| crate::receiver::crosses_segment(t, s, x1)))
    }
}

/// What a shadow ray under the plane principle carries (see the module doc): 56 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PlaneWalk {
    /// The segment's start A (lattice units).
    pub a: [i32; 3],
    /// D = B − A (lattice units).
    pub d: [i32; 3],
    /// The emitter's plane: its dexels never stop the ray.
    pub own: PlaneId,
    /// Where the segment entered the current voxel: t = num / den (0 in the emitter's voxel).
    pub t_in: (i32, i32),
    /// The emitter's own plane along the segment: `2²⁰·g_own` at t = 0 and its growth to t = 1.
    pub own_g: (i64, i64),
}

/// How a segment crosses a plane inside a voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Crossing {
    /// From the plane's outward side to its inward side.
    Entering,
    /// From the inward side to the outward side.
    Leaving,
}

impl PlaneWalk {
    /// `2²⁰·den·g` at the point A + (num/den)·D for the plane of a dexel of `column` whose
    /// first voxel is `lo`: it has the sign of g there (see the module doc's arithmetic).
    pub fn value(&self, plane: &DexelPlane, column: [i32; 2], lo: i32, t: (i32, i32)) -> i128 {
        plane_value(plane, [column[0], column[1], lo], self.a, self.d, t)
    }

    /// How the segment crosses `plane` between `t_in` and `t_out` (σ differs), if it does.
    pub fn crossing(&self, plane: &DexelPlane, column: [i32; 2], lo: i32, t_out: (i32, i32)) -> Option<Crossing> {
        match (self.value(plane, column, lo, self.t_in) > 0, self.value(plane, column, lo, t_out) > 0) {
            (true, false) => Some(Crossing::Entering),
            (false, true) => Some(Crossing::Leaving),
            _ => None,
        }
    }

    /// Whether the segment is within `NEAR` of its own plane at `t_in` (g_own < 2¹⁴).
    pub fn near_own(&self) -> bool {
        let (num, den) = self.t_in;
        let g = (den as i128) * (self.own_g.0 as i128) + (num as i128) * (self.own_g.1 as i128);
        g < ((den as i128) * (NORMAL_SCALE as i128)) << 20
    }
}

/// `2²⁰·den·g` of `plane` (reference voxel `r`: its column and first voxel) at the lattice
/// point A + (num/den)·D.
fn plane_value(plane: &DexelPlane, r: [i32; 3], a: [i32; 3], d: [i32; 3], (num, den): (i32, i32)) -> i128 {
    let off = |i: usize| den as i128 * (a[i] as i128 - (Q * r[i]) as i128) + num as i128 * d[i] as i128;
    ((plane.nx as i128 * off(0) + plane.ny as i128 * off(1)) << 16)
        + plane.nz as i128 * off(2)
        + ((den as i128 * plane.e as i128) << 20)
}

/// The lattice z nearest the exact depth z\* = num/den (den > 0) of a surface: round(Q·z\*),
/// half up, saturated to ±[`MAX_COORD`] (beyond which no line is built).
pub fn lattice_depth(num: i64, den: i64) -> i32 {
    let q = (2 * Q as i128 * num as i128 + den as i128).div_euclid(2 * den as i128);
    q.clamp(-(MAX_COORD as i128) - 1, MAX_COORD as i128 + 1) as i32
}

/// What the cell holding a [`ShadowRay`] does with it this cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RayStep {
    /// The current voxel is occupied: route "shadow" back to the emitter.
    Shadow,
    /// The line reached its end (the source) unobstructed: route "lit" back to the emitter.
    Lit,
    /// The next voxel is in this column: keep the ray (next cycle tests it).
    Stay,
    /// The next voxel is in the neighbour column through this port.
    Forward(Port),
}

impl ShadowRay {
    /// A ray from the centre of voxel `from` toward lattice point `to` (the source).
    ///
    /// The 6-connected walk aims at `to` itself and ends in its voxel. The 18/26-connected
    /// walks aim at the **centre of `to`'s voxel**: aimed at `to` itself, their last voxel may
    /// round past the source's voxel, so that rays from opposite sides cross over — and two
    /// rays waiting for each other's cell deadlock the grid (found by the routing test with
    /// FIFOs of 1). Aimed at the centre, every ray ends in the source's voxel and each of its
    /// cell steps strictly decreases |x − x_s| + |y − y_s|.
    pub fn new(from: [u16; 3], to: [i32; 3], conn: Connectivity, facet: FacetId) -> Result<Self, LineError> {
        let a = [from[0] as i32 * Q, from[1] as i32 * Q, from[2] as i32 * Q];
        let to = if conn == Connectivity::Six { to } else { to.map(|c| voxel_of(c) * Q) };
        Ok(ShadowRay {
            line: Line::new(a, to, conn)?,
            emitter: [from[0], from[1]],
            facet,
            emitter_z: from[2] as i32,
            fresh: true,
            grace: 0,
            surface: false,
            walk: RayWalk::Thesis,
        })
    }

    /// A ray under the plane principle (see the module doc) from lattice point `a` of a surface
    /// of plane `own` — the plane of a dexel (or visible surface) of column (a's column) with
    /// first voxel `lo` — toward lattice point `to`, walked 6-connected. `Ok(None)` when the
    /// plane does not face the source (g(B) ≤ 0): the surface is in its own shadow, no ray.
    pub fn on_plane(
        a: [i32; 3],
        own: &DexelPlane,
        lo: i32,
        to: [i32; 3],
        facet: FacetId,
    ) -> Result<Option<Self>, LineError> {
        let line = Line::new(a, to, Connectivity::Six)?;
        let [x, y, z] = line.voxel();
        let g_b = plane_value(own, [x, y, lo], to, [0; 3], (0, 1));
        if g_b <= 0 {
            return Ok(None);
        }
        let g_a = plane_value(own, [x, y, lo], a, [0; 3], (0, 1));
        let d = [to[0] - a[0], to[1] - a[1], to[2] - a[2]];
        Ok(Some(ShadowRay {
            line,
            emitter: [x as u16, y as u16],
            facet,
            emitter_z: z,
            fresh: true,
            grace: 0,
            surface: false,
            walk: RayWalk::Plane(PlaneWalk {
                a,
                d,
                own: own.id,
                t_in: (0, 1),
                own_g: (g_a as i64, (g_b - g_a) as i64),
            }),
        }))
    }

    /// A ray under exact occluders (see the module doc) from the point `p` = (x, y, z\*) of a
    /// surface of plane `own` (in 1/[`crate::receiver::POINT_UNITS`] voxel; x and y whole
    /// voxels, the column's centre line; `lo` the plane's reference voxel in the column)
    /// toward lattice point `to`, walked 6-connected from `p`'s lattice rounding. `Ok(None)`
    /// when the plane does not face the source: the surface is in its own shadow, no ray.
    pub fn exact(
        p: [i64; 3],
        own: &DexelPlane,
        lo: i32,
        to: [i32; 3],
        facet: FacetId,
    ) -> Result<Option<Self>, LineError> {
        let units = crate::receiver::POINT_UNITS;
        let limit = crate::occluder::COORD_LIMIT * (units / Q as i64);
        if p.iter().any(|c| c.abs() > limit) || to.iter().any(|c| c.abs() as i64 > crate::occluder::COORD_LIMIT) {
            return Err(LineError::CoordinateTooLarge);
        }
        let q = units / Q as i64;
        let (x, y) = ((p[0] / units) as i32, (p[1] / units) as i32);
        let a = [x * Q, y * Q, (2 * p[2] + q).div_euclid(2 * q) as i32];
        let line = Line::new(a, to, Connectivity::Six)?;
        if plane_value(own, [x, y, lo], to, [0; 3], (0, 1)) <= 0 {
            return Ok(None);
        }
        let light = to.map(|c| c as i64 * q);
        let near = crate::receiver::contact_point(own, (x, y), lo, light, p);
        Ok(Some(ShadowRay {
            line,
            emitter: [x as u16, y as u16],
            facet,
            emitter_z: line.voxel()[2],
            fresh: true,
            grace: 0,
            surface: false,
            walk: RayWalk::Exact(ExactWalk { near, source: to, untested: true }),
        }))
    }

    /// Mark the ray as the one whose answer shades the emitter's pixel.
    pub fn for_surface(mut self) -> Self {
        self.surface = true;
        self
    }

    /// Leave the first `k` voxels after the emitter's own untested (a shadow bias of `k`
    /// voxels, the discrete form of the offset ray tracers add against shadow acne): a ray
    /// leaving a facet then ignores the adjacent facets of the same object it grazes, at the
    /// price of shadows cast within `k` voxels of the emitter.
    pub fn with_bias(mut self, k: u8) -> Self {
        self.grace = k;
        self
    }

    /// One voxel of work in the cell owning the current voxel: test it against the column's
    /// dexels, then take one step of the line. Under the thesis's rule the emitter's voxel is
    /// not tested and a voxel of another facet stops the ray; under the plane principle every
    /// voxel is tested and stops the ray iff the segment crosses its plane there (see the
    /// module doc). Pure in the store; the ray advances (the caller keeps a copy if it cannot
    /// send the result yet).
    pub fn advance<const D: usize>(&mut self, store: &DexelStore<D>) -> RayStep {
        let here = self.line.voxel();
        let test = if self.fresh && matches!(self.walk, RayWalk::Thesis) {
            false
        } else if self.grace > 0 && !self.fresh {
            self.grace -= 1;
            false
        } else {
            true
        };
        // The segment's exit from this voxel (the plane principle walks 6-connected: known).
        let t_out = self.line.exit().unwrap_or((1, 1));
        if test {
            if let Some(d) = u16::try_from(here[2]).ok().and_then(|z| store.occupied(z)) {
                let stops = match &self.walk {
                    RayWalk::Thesis => d.facet != self.facet,
                    RayWalk::Exact(_) => false,
                    RayWalk::Plane(w) => {
                        d.plane.id != w.own
                            && match w.crossing(&d.plane, [here[0], here[1]], d.span.lo as i32, t_out) {
                                None => false,
                                Some(Crossing::Entering) => true,
                                Some(Crossing::Leaving) => !w.near_own(),
                            }
                    }
                };
                if stops {
                    return RayStep::Shadow;
                }
            }
        }
        self.fresh = false;
        if let RayWalk::Plane(w) = &mut self.walk {
            w.t_in = t_out;
        }
        self.step_line()
    }

    /// One voxel of work under exact occluders (see the module doc): in the first voxel of each
    /// column, test the segment against `triangles`, the column's; then take one step of the
    /// line. Pure in the triangles; the ray advances.
    pub fn advance_exact(&mut self, triangles: &[Triangle]) -> RayStep {
        if let RayWalk::Exact(w) = &mut self.walk {
            if core::mem::take(&mut w.untested) && w.blocked_by(triangles) {
                return RayStep::Shadow;
            }
        }
        self.fresh = false;
        let step = self.step_line();
        if let (RayStep::Forward(_), RayWalk::Exact(w)) = (step, &mut self.walk) {
            w.untested = true;
        }
        step
    }

    /// The line's next voxel: the end (lit), this column, or a neighbour's.
    fn step_line(&mut self) -> RayStep {
        let here = self.line.voxel();
        let Some(next) = self.line.step() else { return RayStep::Lit };
        match cell_step(here, next).and_then(|(dx, dy)| Port::from_delta(dx, dy)) {
            Some(p) => RayStep::Forward(p),
            None => RayStep::Stay,
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    fn path(a: [i32; 3], b: [i32; 3], c: Connectivity) -> heapless::Vec<[i32; 3], 256> {
        let mut l = Line::new(a, b, c).unwrap();
        let mut out = heapless::Vec::new();
        out.push(l.voxel()).unwrap();
        let r0 = l.remaining();
        while let Some(v) = l.step() {
            out.push(v).unwrap();
        }
        assert_eq!(out.len() as u32, r0 + 1);
        out
    }

    #[test]
    fn axis_lines() {
        for c in Connectivity::ALL {
            let p = path([0, 0, 0], [0, 0, 5 * Q], c);
            assert_eq!(p.len(), 6);
            assert_eq!(p[5], [0, 0, 5]);
        }
    }

    #[test]
    fn diagonal_lengths() {
        let b = [3 * Q, 3 * Q, 3 * Q];
        assert_eq!(path([0; 3], b, Connectivity::TwentySix).len(), 4);
        assert_eq!(path([0; 3], b, Connectivity::Eighteen).len(), 7);
        assert_eq!(path([0; 3], b, Connectivity::Six).len(), 10);
    }

    #[test]
    fn exits_follow_the_segment() {
        // From the centre of voxel 0 to the centre of voxel 3 along x: exits at 8/48, 24/48, …
        let mut l = Line::new([0; 3], [3 * Q, 0, 0], Connectivity::Six).unwrap();
        let mut exits = heapless::Vec::<(i32, i32), 8>::new();
        loop {
            exits.push(l.exit().unwrap()).unwrap();
            if l.step().is_none() {
                break;
            }
        }
        assert_eq!(exits, [(8, 48), (24, 48), (40, 48), (1, 1)]);
        assert_eq!(Line::new([0; 3], [3 * Q, 0, 0], Connectivity::TwentySix).unwrap().exit(), None);
    }

    fn z_plane(id: u32, nz: i32, e: i32) -> DexelPlane {
        DexelPlane { id, nx: 0, ny: 0, nz, e }
    }

    #[test]
    fn plane_rays_stop_only_where_they_cross() {
        use crate::dexel::{DexelStore, FacetTag};
        use crate::plane::{ColumnPlane, FacetPlane, NZ_MAX};
        use crate::units::Span;
        // The emitter: a floor at z* = 9 facing −z (the viewer), the source 8 voxels above.
        let floor = z_plane(1, -NZ_MAX, 0);
        let source = [0, 0, Q];
        let run = |store: &DexelStore<4>| {
            let mut r = ShadowRay::on_plane([0, 0, 9 * Q], &floor, 9, source, 0).unwrap().unwrap();
            loop {
                match r.advance(store) {
                    RayStep::Stay => continue,
                    other => return other,
                }
            }
        };
        // A source behind the floor: no ray.
        assert_eq!(ShadowRay::on_plane([0, 0, 9 * Q], &floor, 9, [0, 0, 12 * Q], 0), Ok(None));
        assert_eq!(run(&DexelStore::<4>::new()), RayStep::Lit);
        // A one-voxel dexel at z of plane id `id`, z slope `nz` and value `e` at its centre
        // (m = 2¹⁰: the stored offset is the column value itself).
        let slab = |z: u16, id: u32, nz: i32, e: i64| {
            let mut store = DexelStore::<4>::new();
            let plane = FacetPlane { id, nx: 0, ny: 0, nz, m: 1 << 10 };
            let tag = FacetTag { facet: 2, plane, ..FacetTag::default() };
            store.insert_on(Span { lo: z, hi: z }, tag, &ColumnPlane { p: e, c: 0 });
            assert_eq!(store.occupied(z).unwrap().plane.e as i64, e);
            store
        };
        // The plane z = 4.25 facing +z (g = 2¹⁴·(z − 4.25)) in voxel 4: entered there: shadow.
        assert_eq!(run(&slab(4, 2, NZ_MAX, -(1 << 12))), RayStep::Shadow);
        // The plane z = 5.5 in voxel 4: not crossed inside it: lit.
        assert_eq!(run(&slab(4, 2, NZ_MAX, -(3 << 13))), RayStep::Lit);
        // A dexel of the emitter's own plane id never stops the ray.
        assert_eq!(run(&slab(4, 1, NZ_MAX, -(1 << 12))), RayStep::Lit);
        // Leaving a plane's inward side: within a voxel of the floor it is a neighbour's
        // overhang (no stop); farther it is a sheet seen from behind (shadow).
        assert_eq!(run(&slab(9, 2, -NZ_MAX, -(1 << 12))), RayStep::Lit);
        assert_eq!(run(&slab(4, 2, -NZ_MAX, -(1 << 12))), RayStep::Shadow);
    }

    #[test]
    fn exact_rays_stop_where_a_triangle_crosses_their_segment() {
        use crate::plane::NZ_MAX;
        // The emitter: a floor at z* = 9 facing −z (the viewer); the source 8 voxels up and 8
        // along x, so that the ray crosses columns x = 0 ..= 8.
        let floor = z_plane(1, -NZ_MAX, 0);
        let source = [8 * Q, 0, Q];
        let p = [0, 0, 9 * crate::receiver::POINT_UNITS];
        // A horizontal triangle at height z (sixteenths) around the point where the ray
        // (x = 9 − z) passes that height: x within ¾ voxel of it at y = 0.
        let sheet = |z: i32| {
            let x = 144 - z;
            Triangle::new([[x - 24, -40, z], [x + 24, -40, z], [x, 40, z]]).unwrap()
        };
        let ground = [
            Triangle::new([[-64, -64, 144], [200, -64, 144], [-64, 64, 144]]).unwrap(),
            Triangle::new([[200, -64, 144], [200, 64, 144], [-64, 64, 144]]).unwrap(),
        ];
        // Walk the ray, each column handing it the triangles through its square.
        let run = |to: [i32; 3], scene: &[Triangle]| {
            let mut r = ShadowRay::exact(p, &floor, 9, to, 0).unwrap().expect("faces the source");
            let mut tests = 0;
            loop {
                let [x, y, _] = r.line.voxel();
                let here: heapless::Vec<Triangle, 8> =
                    scene.iter().copied().filter(|t| t.crosses_column(x, y)).collect();
                tests += matches!(r.walk, RayWalk::Exact(ExactWalk { untested: true, .. })) as u32;
                match r.advance_exact(&here) {
                    RayStep::Stay | RayStep::Forward(_) => continue,
                    other => return (other, tests),
                }
            }
        };
        // Nothing but the floor itself (its own triangles, within the gap): lit, one test per
        // column crossed.
        assert_eq!(run(source, &ground), (RayStep::Lit, 9));
        // A shelf half way up: shadow, found in the first column that keeps it (x = 3).
        assert_eq!(run(source, &[ground[0], ground[1], sheet(80)]), (RayStep::Shadow, 4));
        // A sheet ½ voxel over the floor shadows it; ⅛ voxel over it lies within the gap.
        assert_eq!(run(source, &[sheet(136)]).0, RayStep::Shadow);
        assert_eq!(run(source, &[sheet(142)]).0, RayStep::Lit);
        // A sheet the ray passes beside, and one beyond the source: lit.
        assert_eq!(run([-8 * Q, 0, Q], &[sheet(80)]).0, RayStep::Lit);
        assert_eq!(run(source, &[sheet(-16)]).0, RayStep::Lit);
        // A source behind the floor: no ray. One within the gap: a ray with nothing to test.
        assert_eq!(ShadowRay::exact(p, &floor, 9, [8 * Q, 0, 12 * Q], 0), Ok(None));
        let near = ShadowRay::exact(p, &floor, 9, [8 * Q, 0, 9 * Q - 2], 0).unwrap().unwrap();
        assert!(matches!(near.walk, RayWalk::Exact(ExactWalk { near: None, .. })));
        let wall = Triangle::new([[64, -40, 100], [64, 40, 100], [64, 0, 200]]).unwrap();
        assert_eq!(run(source, &[wall]).0, RayStep::Lit, "the ray passes the wall at z = 5, it starts at 6.25");
        assert_eq!(run([8 * Q, 0, 9 * Q - 2], &[wall]).0, RayStep::Lit, "untested");
        // Coordinates beyond the occluders' budget are refused, not wrapped.
        let far = crate::occluder::COORD_LIMIT as i32 + 1;
        assert_eq!(ShadowRay::exact(p, &floor, 9, [far, 0, Q], 0), Err(LineError::CoordinateTooLarge));
    }

    #[test]
    fn message_sizes() {
        assert_eq!(core::mem::size_of::<PlaneWalk>(), 56);
        // The line's walk state (72), the plane state (64 with its tag), emitter and flags.
        assert_eq!(core::mem::size_of::<ShadowRay>(), 144);
    }

    #[test]
    fn plane_values_at_the_bit_budget() {
        // Extreme coordinates, span, normal and offset: no overflow (checked in debug builds),
        // and the sign is right at both ends of the segment.
        let p = DexelPlane {
            id: 0,
            nx: NORMAL_SCALE as i16,
            ny: -(NORMAL_SCALE as i16),
            nz: crate::plane::NZ_MAX,
            e: i32::MAX,
        };
        let a = [MAX_COORD, -MAX_COORD, MAX_COORD];
        let d = [-MAX_SPAN, MAX_SPAN, -MAX_SPAN];
        let r = [-(MAX_COORD / Q), MAX_COORD / Q, -(MAX_COORD / Q)];
        for t in [(0, 1), (MAX_SPAN + Q, MAX_SPAN + Q), (1, MAX_SPAN + Q)] {
            assert!(plane_value(&p, r, a, d, t) > 0);
            let flipped = plane_value(&p.flipped(), r, a, d, t);
            assert!(flipped < 0);
        }
    }

    /// Writes `l` and reads it back.
    fn round_trip(l: &Line) -> Result<Line, DecodeError> {
        let mut buf = [0u8; LINE_BYTES];
        let mut w = crate::bytes::SliceWriter::new(&mut buf);
        l.put(&mut w).unwrap();
        let n = w.len();
        let mut r = Reader::new(&buf[..n]);
        let back = Line::get(&mut r)?;
        r.finish()?;
        Ok(back)
    }

    #[test]
    fn line_state_round_trips_at_every_step() {
        let ends = [
            ([0, 0, 0], [5 * Q + 3, -7 * Q, 2 * Q + 9]),
            ([3, -8, 40], [-50 * Q, 33 * Q + 5, -2]),
            ([0; 3], [3 * Q, 3 * Q, 3 * Q]),
            ([0; 3], [0; 3]),
            ([MAX_COORD, -MAX_COORD, 0], [MAX_COORD - MAX_SPAN, -MAX_COORD + MAX_SPAN, MAX_SPAN / 3]),
        ];
        for c in Connectivity::ALL {
            for (a, b) in ends {
                let mut l = Line::new(a, b, c).unwrap();
                for _ in 0..200 {
                    assert_eq!(round_trip(&l), Ok(l), "{c:?} {a:?} → {b:?} at {:?}", l.voxel());
                    if l.step().is_none() {
                        break;
                    }
                }
            }
        }
    }

    #[test]
    fn decoded_lines_outside_the_budget_are_refused() {
        let l = Line::new([0; 3], [3 * Q, -2 * Q, Q], Connectivity::Six).unwrap();
        let aw = |edit: &dyn Fn(&mut [i32; 3], &mut Aw)| {
            let mut f = l;
            if let Walk::Aw(w) = &mut f.walk {
                edit(&mut f.v, w);
            }
            round_trip(&f)
        };
        assert!(aw(&|v, _| v[0] = MAX_VOXEL + 1).is_err(), "a voxel beyond the budget");
        assert!(aw(&|_, w| w.s[1] = 0).is_err(), "no step on an axis that moves");
        assert!(aw(&|_, w| w.target[0] = -1).is_err(), "the end behind the step");
        assert!(aw(&|_, w| w.nb[2] = -1).is_err(), "a negative boundary distance");
        let d = Line::new([0; 3], [3 * Q, -2 * Q, Q], Connectivity::TwentySix).unwrap();
        let dda = |edit: &dyn Fn(&mut Dda)| {
            let mut f = d;
            if let Walk::Dda(w) = &mut f.walk {
                edit(w);
            }
            round_trip(&f)
        };
        assert!(dda(&|w| w.m = 3).is_err(), "a major axis beyond z");
        assert!(dda(&|w| w.r[1] = w.qm).is_err(), "a remainder out of [0, Q·M)");
        assert!(dda(&|w| w.inc[1] = w.qm + 1).is_err(), "two carries in a step");
        assert!(dda(&|w| w.inc[0] = 1).is_err(), "an increment on the major axis");
        assert!(dda(&|w| w.left = MAX_STEPS as u32 + 1).is_err(), "a walk beyond the span");
        assert!(dda(&|w| w.pending = Some([5, 5, 5])).is_err(), "a pending voxel not next to the current one");
        assert_eq!(Line::get(&mut Reader::new(&[3, 0, 0, 0, 0])), Err(DecodeError::Truncated));
        let mut walk3 = [0u8; 64];
        walk3[0] = 3;
        assert_eq!(Line::get(&mut Reader::new(&walk3)), Err(DecodeError::BadValue("line walk")));
    }

    proptest::proptest! {
        /// Any bytes: decoding never panics.
        #[test]
        fn any_bytes_decode_without_panic(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..64)) {
            let _ = Line::get(&mut Reader::new(&bytes));
        }

        /// Any state the decoder's checks admit, reachable by a real line or not (remainders,
        /// boundary distances, steps left and directions drawn at random within the checks):
        /// it round-trips and walks to its end without overflow or panic (debug builds check
        /// every operation), its exit parameter in range.
        #[test]
        fn any_admitted_state_walks_without_panic(
            kind in 0u8..3,
            v in proptest::array::uniform3(-MAX_VOXEL..=MAX_VOXEL),
            small in proptest::array::uniform3(0i32..40),
            signs in proptest::array::uniform3(proptest::prelude::any::<bool>()),
            m in 0u8..3,
            qm in 0i32..200,
            fractions in proptest::array::uniform3(0.0f64..1.0),
            pending in proptest::prelude::any::<bool>(),
        ) {
            let sign = |k: usize| if signs[k] { 1 } else { -1 };
            let walk = if kind == 0 {
                let d = small.map(|c| c * 1000);
                let s = [0, 1, 2].map(|k| if d[k] == 0 { 0 } else { sign(k) as i8 });
                let target = [0, 1, 2].map(|k| v[k] + s[k] as i32 * (small[k] % 7));
                let nb = small.map(|c| c * 97 % (MAX_SPAN + 2 * Q));
                Walk::Aw(Aw { d, s, nb, target })
            } else {
                let mut inc = [0; 3];
                let mut r = [0; 3];
                for k in (0..3).filter(|&k| k != m as usize && qm > 0) {
                    inc[k] = sign(k) * (fractions[k] * qm as f64) as i32;
                    r[k] = ((fractions[(k + 1) % 3] * qm as f64) as i32).min(qm - 1);
                }
                let left = if qm == 0 { 0 } else { small[0] as u32 };
                let pending = pending.then(|| [v[0] + 1, v[1], v[2] - 1]);
                Walk::Dda(Dda { m, sm: sign(m as usize) as i8, inc, r, qm, left, split: kind == 2, pending })
            };
            let mut l = Line { v, walk };
            proptest::prop_assert_eq!(round_trip(&l), Ok(l));
            let mut steps = 0u32;
            while l.step().is_some() {
                if let Some((num, den)) = l.exit() {
                    proptest::prop_assert!(den > 0 && num >= 0);
                }
                steps += 1;
                proptest::prop_assert!(steps <= 3 * MAX_STEPS as u32 + 3);
            }
        }

        /// Lines built from any end points within the budget round-trip at every step.
        #[test]
        fn built_lines_round_trip(a in proptest::array::uniform3(-4000i32..4000), b in proptest::array::uniform3(-4000i32..4000), k in 0usize..3) {
            let mut l = Line::new(a, b, Connectivity::ALL[k]).unwrap();
            loop {
                proptest::prop_assert_eq!(round_trip(&l), Ok(l));
                if l.step().is_none() {
                    break;
                }
            }
        }
    }

    #[test]
    fn limits() {
        assert_eq!(Line::new([0; 3], [MAX_SPAN + 1, 0, 0], Connectivity::Six), Err(LineError::SpanTooLarge));
        assert_eq!(
            Line::new([MAX_COORD + 1, 0, 0], [MAX_COORD, 0, 0], Connectivity::Six),
            Err(LineError::CoordinateTooLarge)
        );
    }

    proptest::proptest! {
        /// `Line::point` is on the continuous segment A → B at every step of every walk (the
        /// cross product of point − A with B − A is zero, exactly), and for the 26/18 walks in
        /// the current voxel.
        #[test]
        fn the_line_point_is_on_the_segment_at_every_step(
            a in proptest::array::uniform3(-2000i32..2000),
            d in proptest::array::uniform3(-900i32..900),
            k in 0usize..3,
        ) {
            let b = [a[0] + d[0], a[1] + d[1], a[2] + d[2]];
            let conn = Connectivity::ALL[k];
            let mut l = Line::new(a, b, conn).unwrap();
            loop {
                let (num, den) = l.point();
                proptest::prop_assert!(den > 0);
                let u = [0, 1, 2].map(|i| num[i] - a[i] as i64 * den);
                let dd = d.map(i64::from);
                let cross = [u[1] * dd[2] - u[2] * dd[1], u[2] * dd[0] - u[0] * dd[2], u[0] * dd[1] - u[1] * dd[0]];
                proptest::prop_assert_eq!(cross, [0, 0, 0], "{:?} {:?} at {:?}: {:?}/{}", a, b, l.voxel(), num, den);
                if conn != Connectivity::Six && d != [0, 0, 0] {
                    // Round half up, as voxel_of: ⌊(p + Q/2)/Q⌋ = v.
                    let v = num.map(|c| (2 * c + Q as i64 * den).div_euclid(2 * Q as i64 * den));
                    let split = matches!(&l.walk, Walk::Dda(w) if w.pending.is_some());
                    if !split {
                        proptest::prop_assert_eq!(v, l.voxel().map(i64::from));
                    }
                }
                if l.step().is_none() {
                    break;
                }
            }
        }
    }
}
