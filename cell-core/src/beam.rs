//! §4.3.1–4.3.4 — light beams and their exact split.
//!
//! **Invariant: every ray lands in exactly one sub-beam.** [`Beam::split`] partitions the rays
//! of a beam into at most 3 × 3 = 9 non-empty sub-beams, and each ray's sub-beam is the voxel
//! that the ray occupies at the next layer by the rounding rule below ([`trace_ray_voxel`] is
//! the per-ray oracle). Hence ray counts are conserved: `beam.ray_count()` equals the sum of
//! its sub-beams' counts.
//!
//! # Geometry (thesis §4.3: rays, beams and the split)
//!
//! * A [`Direction`] is a principal axis w with a sign s. Its transverse axes — the *u-axis*
//!   and *v-axis* — are the other two axes in increasing order: ±z → (x, y), ±y → (x, z),
//!   ±x → (y, z).
//! * A [`Source`] S has a position on a lattice of [`SOURCE_FRAC_BITS`] = g = 4 fraction bits
//!   (1/16 voxel, the loading lattice of [`crate::voxelize`]); an integer source is the thesis's case.
//!   Its voxel is the one whose centre is nearest (round half up, `⌊p + ½⌋` per axis).
//! * [`Layer`] k = 0, 1, 2, … is the voxel slab w = w₀ + s·k, where w₀ is the source voxel's
//!   principal coordinate (layer 0 holds the source voxel).
//! * [`FarDistance`] D ≥ every layer used (the thesis uses D = n − 1), a positive integer.
//! * A **ray** is a far-plane offset (u, v), |u|, |v| ≤ D, on the lattice of step 2^−f: a
//!   [`FarOffset<F>`] = `fixed::FixedI32<F>`, f = `F::U32` fraction bits (f = 0 is the thesis).
//!   At layer k it occupies the voxel whose transverse coordinates are
//!   `⌊x_s + u·k/D + ½⌋` and `⌊y_s + v·k/D + ½⌋` (x_s, y_s: the source's transverse coordinates).
//!   Only the source's *transverse* fraction enters: the principal distance of layer k is k.
//! * A [`Beam`] is a rectangle of rays `[u_min, u_max] × [v_min, v_max]` plus source id,
//!   direction and layer. It does not carry its voxel: the cell that holds it knows its own
//!   transverse position ([`Transverse`]) and passes it to [`Beam::split`]. A *consistent*
//!   beam is one whose rays all occupy that voxel ([`Beam::occupies`]); by monotonicity of the
//!   rounding in u it suffices that its two corners do.
//!
//! # The split (§4.3.1.2, §4.3.3, §4.3.4.2)
//!
//! From layer k to k + 1 a ray's transverse coordinate x changes by −1, 0 or +1 (its slope is
//! at most 1). It moves to x − 1 iff u < U1 and to x + 1 iff u ≥ U2, with
//!
//! ```text
//!   U1 = (x − x_s − ½)·D/(k + 1)        U2 = (x − x_s + ½)·D/(k + 1)
//! ```
//!
//! (same for v with V1, V2): `⌊x_s + u(k+1)/D + ½⌋ ≥ x + 1 ⇔ u ≥ U2` and `≤ x − 1 ⇔ u < U1`.
//! For a source at the origin these are the thesis's Y_med = (y + ½)(n − 1)/(x + 1)
//! (§4.3.1.2), and its Y1, Y2 (§4.3.3) and U1, U2, V1, V2 (§4.3.4.2) with D = n − 1.
//!
//! **Rays from the light** ([`Origin::Light`]). The thesis's rays leave from the source
//! voxel's centre plane along their axis. Rays from the light itself are at
//! `⌊x_s + u·T_k/(16·D) + ½⌋` at layer k, with `T_k = 16·k − lead` ([`Source::reach`]) and
//! layer 1 the first slab whose centre plane lies ahead of the light ([`Source::slab`]; layer
//! 0 is the source voxel, where every ray is still at the light). Then `k + 1` becomes
//! `T_{k+1}/16` below and nothing else changes: `T_{k+1} − T_k ≤ 16`, so a ray still moves by
//! at most one voxel per layer.
//!
//! U1, U2 are rationals. Writing u = a/2^f (a = `to_bits()`), x_s = b/2^g, q = 2·T_{k+1}
//! (= (k + 1)·2^(g+1) for the thesis's rays) and c₁,₂ = 2^(g+1)·(x − x_s) ∓ 2^g, the test
//! u < U1 is decided exactly by
//!
//! ```text
//!   a · q  <  c₁ · D·2^f          (all in i64, no division, no rounding)
//! ```
//!
//! and the lattice ray where a sub-beam starts is the exact ceiling ⌈c·D·2^f / q⌉ —
//! the "fixed-point Y_med": the smallest lattice value ≥ U, one integer division, computed
//! only when a beam actually straddles a plane (most splits do not: two comparisons per axis
//! decide that). [`split_planes`] returns U1, U2, V1, V2 as exact [`Ratio`]s.
//!
//! **Difference from the thesis.** The thesis writes Y_med = [(y + ½)(n − 1)/(x + 1)] (integer
//! part) and splits into (Y_min, Y_med), (Y_med, Y_max) without saying which side owns Y_med.
//! Truncating Y_med misroutes the ray ⌊Y_med⌋ whenever Y_med is not an integer; here the
//! threshold is exact: a ray exactly on U2 goes to x + 1 (round half up) and one exactly on U1
//! stays (tests check both).
//!
//! # Bit budget
//!
//! Every cell comparison is `i64`, proven overflow-free for **any** `FixedI32` limits, any
//! `i32` cell position and any source position, given the two conditions that
//! [`FarDistance::new`] checks:
//!
//! * `D·2^f ≤ 2³¹ − 1` — ±D must be a `FixedI32<F>`;
//! * `D ≤ MAX_FAR = 2^(31−g) − 1 = 2²⁷ − 1` — then `|a·q| ≤ 2³¹·(2²⁷ − 1)·2⁵ < 2⁶³` (q ≤
//!   (k + 1)·2^(g+1) for either origin), and with c clamped to ±2^(g+1)(D + 1) (which changes
//!   no comparison: a plane beyond ±(D + 1)·D·2^(g+1)/q ≥ ±(D + 1) is beyond every ray)
//!   `|c·D·2^f| ≤ 2³²·(2³¹ − 1) < 2⁶³`. Checked by `const` assertions.
//!
//! | f  | largest D ([`FarDistance::MAX`]) |
//! |----|----------------------------------|
//! | 0–4 | 134 217 727 (2²⁷ − 1)           |
//! | 8  | 8 388 607                        |
//! | 12 | 524 287                          |
//! | 16 | 32 767                           |
//! | 20 | 2 047                            |
//! | 24 | 127                              |
//! | 30 | 1                                |
//!
//! f = 31 and 32 admit no D. The per-ray oracle [`trace_ray_voxel`] uses `i128` and different
//! formulas, so that it shares no arithmetic with the split.
//!
//! # Why f is a type parameter
//!
//! The limits are `fixed::FixedI32<F>` with `F` a `typenum` unsigned (`frac::U0`, `frac::U8`,
//! …), so f is part of the beam's type: every representable limit *is* a lattice ray (no
//! run-time lattice check, no f byte to carry or validate in each message), beams of different
//! f cannot be mixed, a limit costs 4 bytes whatever f, and the firmware compiles exactly one f.
//! The host sweeps f by monomorphising once per value, e.g. with [`with_frac_bits!`](crate::with_frac_bits)
//! (`with_frac_bits!(f, F => run::<F>(…))` for f ∈ {0..=8, 10, 12, 16, 20, 24}).
//!
//! # The six initial beams (§4.2.3, §4.3.4.2)
//!
//! [`Beam::initial`] emits, for one direction, the full square [−D, D]² at layer 0 (the source
//! voxel); [`Beam::initial_six`] emits all six in [`Direction::ALL`] order (x and y first, then
//! z, as the thesis found faster, §4.4.3). The six pyramids overlap on their boundaries: a ray
//! with |u| = D or |v| = D lies on an edge of the source cube and belongs to two faces (three at
//! the corners |u| = |v| = D); both beams carry it through the same voxels (rounding commutes
//! with integer shifts). With N = D·2^f, a source emits 6·(2N + 1)² lattice rays
//! ([`FarDistance::rays_per_face`]) for 24N² + 2 distinct directions
//! ([`FarDistance::distinct_directions`]): 12 edges × (2N − 1) rays counted twice and
//! 8 corners counted three times. Conservation is therefore per beam (rays in = rays of the
//! sub-beams), and a source's emitted total is `6·rays_per_face`.
//!
//! # Sub-beam order
//!
//! [`Beam::split`] emits sub-beams in [`SplitOrder::ROW_MAJOR`] order (du = −1, 0, 1 outer,
//! dv = −1, 0, 1 inner). [`Beam::split_with`] takes any [`SplitOrder`] (a validated permutation
//! of the nine offsets), e.g. [`SplitOrder::AXIS_NEIGHBOURS_FIRST`] for a scheduling policy.
//!
//! # Sizes
//!
//! `size_of::<Beam<F>>()` = 24 bytes for every f (four `FixedI32` limits, a `u32` layer, a
//! `u16` source id, a `u8` direction); a [`SubBeam`] is 28; a full [`SubBeams`] is 256 on
//! thumbv7em (264 on a 64-bit host).
//!
//! # Example
//!
//! ```
//! use cell_core::beam::{frac::U2, Beam, Direction, FarDistance, Source, SourceId, Transverse};
//!
//! let source = Source::at_voxel(SourceId(0), [4, 4, 4]).unwrap();
//! let far = FarDistance::<U2>::new(7).unwrap();
//! let beam = Beam::initial(&source, Direction::PosZ, far);
//! let at = Direction::PosZ.transverse_of(source.voxel());
//! assert_eq!(at, Transverse { u: 4, v: 4 });
//! let subs = beam.split(&source, far, at).unwrap();
//! assert_eq!(subs.len(), 9);
//! assert_eq!(subs.iter().map(|s| s.beam.ray_count()).sum::<u64>(), beam.ray_count());
//! ```

use core::cmp::Ordering;
use core::fmt::Debug;
use core::hash::Hash;
use core::marker::PhantomData;

use fixed::types::extra::{LeEqU32, U4};
use fixed::FixedI32;
use heapless::Vec;

/// The `typenum` fraction-bit types (`U0`, `U1`, … `U32`) that select f.
pub use fixed::types::extra as frac;

/// Fraction bits f of a far-plane lattice: any `typenum` unsigned ≤ 32 (`frac::U0` …).
/// (The extra bounds, which every `typenum` unsigned meets, let generic code derive traits.)
pub trait FracBits: LeEqU32 + Copy + Debug + Default + Eq + Hash + Send + Sync + 'static {}
impl<T> FracBits for T where T: LeEqU32 + Copy + Debug + Default + Eq + Hash + Send + Sync + 'static {}

/// g: fraction bits of a source position (lattice step 1/16 voxel).
pub const SOURCE_FRAC_BITS: u32 = 4;

/// A source coordinate, in voxel units on the 2^−g lattice.
pub type SourceCoord = FixedI32<U4>;

/// A ray's far-plane offset u or v (voxel units at distance D) on the 2^−f lattice.
pub type FarOffset<F> = FixedI32<F>;

/// Largest far distance the `i64` budget allows for any f: 2^(31−g) − 1.
pub const MAX_FAR: u32 = (1u32 << (31 - SOURCE_FRAC_BITS)) - 1;

const G: u32 = SOURCE_FRAC_BITS;

// Bit budget (see module doc): left side a·m·2^(g+1) with |a| ≤ 2^31, m ≤ MAX_FAR …
const _: () = assert!((1i128 << 31) * (MAX_FAR as i128) * (1i128 << (G + 1)) <= i64::MAX as i128);
// … right side c·D·2^f with |c| ≤ 2^(g+1)·(MAX_FAR + 1) and D·2^f ≤ i32::MAX …
const _: () = assert!((1i128 << (G + 1)) * (MAX_FAR as i128 + 1) * (i32::MAX as i128) <= i64::MAX as i128);
// … and the unclamped c = 2·(x·2^g − b) ± 2^g for any i32 x and b.
const _: () =
    assert!(2 * ((i32::MAX as i128 + 1) * (1i128 << G) + (i32::MAX as i128 + 1)) + (1i128 << G) <= i64::MAX as i128);
// The type of the source coordinates must match g.
const _: () = assert!(SourceCoord::FRAC_NBITS == SOURCE_FRAC_BITS);

// ---------------------------------------------------------------------------------------------
// Names
// ---------------------------------------------------------------------------------------------

/// A coordinate axis of the voxel space.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Axis {
    /// x (columns of the grid).
    X = 0,
    /// y (rows of the grid).
    Y = 1,
    /// z (depth inside a column).
    Z = 2,
}

impl Axis {
    /// 0, 1, 2 for x, y, z.
    pub const fn index(self) -> usize {
        self as usize
    }
}

/// One of the six propagation directions (§4.3.4.2, Fig 4.22).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// +x: transverse (u, v) = (y, z).
    PosX = 0,
    /// −x: transverse (u, v) = (y, z).
    NegX = 1,
    /// +y: transverse (u, v) = (x, z).
    PosY = 2,
    /// −y: transverse (u, v) = (x, z).
    NegY = 3,
    /// +z: transverse (u, v) = (x, y).
    PosZ = 4,
    /// −z: transverse (u, v) = (x, y).
    NegZ = 5,
}

impl Direction {
    /// All six, x and y first, then z (the thesis's faster emission order, §4.4.3).
    pub const ALL: [Direction; 6] =
        [Direction::PosX, Direction::NegX, Direction::PosY, Direction::NegY, Direction::PosZ, Direction::NegZ];

    /// The wire index 0..=5 (the thesis's "D : direction de propagation (0 à 5)").
    pub const fn index(self) -> u8 {
        self as u8
    }

    /// Inverse of [`Direction::index`]; `None` for 6..=255.
    pub const fn from_index(i: u8) -> Option<Direction> {
        match i {
            0 => Some(Direction::PosX),
            1 => Some(Direction::NegX),
            2 => Some(Direction::PosY),
            3 => Some(Direction::NegY),
            4 => Some(Direction::PosZ),
            5 => Some(Direction::NegZ),
            _ => None,
        }
    }

    /// The principal axis w.
    pub const fn principal(self) -> Axis {
        match self {
            Direction::PosX | Direction::NegX => Axis::X,
            Direction::PosY | Direction::NegY => Axis::Y,
            Direction::PosZ | Direction::NegZ => Axis::Z,
        }
    }

    /// The sign s of the direction: +1 or −1.
    pub const fn sign(self) -> i8 {
        match self {
            Direction::PosX | Direction::PosY | Direction::PosZ => 1,
            Direction::NegX | Direction::NegY | Direction::NegZ => -1,
        }
    }

    /// The transverse axes (u-axis, v-axis): the other two axes in increasing order.
    pub const fn transverse(self) -> (Axis, Axis) {
        match self.principal() {
            Axis::X => (Axis::Y, Axis::Z),
            Axis::Y => (Axis::X, Axis::Z),
            Axis::Z => (Axis::X, Axis::Y),
        }
    }

    /// The transverse coordinates of a 3D voxel (e.g. the source voxel, where the initial beam
    /// starts).
    pub const fn transverse_of(self, voxel: [i32; 3]) -> Transverse {
        let (a, b) = self.transverse();
        Transverse { u: voxel[a.index()], v: voxel[b.index()] }
    }

    /// The 3D voxel of (layer, transverse position) for a beam of `source`.
    pub fn voxel(self, source: &Source, layer: Layer, at: Transverse) -> [i64; 3] {
        let (a, b) = self.transverse();
        let w = self.principal().index();
        let mut p = [0i64; 3];
        p[w] = source.slab(self, layer);
        p[a.index()] = at.u as i64;
        p[b.index()] = at.v as i64;
        p
    }

    /// The 3D step (dx, dy, dz) to the voxel of a sub-beam with this transverse offset: one
    /// layer along s·w, plus (du, dv) on the transverse axes.
    pub const fn displacement(self, offset: Offset) -> [i8; 3] {
        let (a, b) = self.transverse();
        let mut d = [0i8; 3];
        d[self.principal().index()] = self.sign();
        d[a.index()] = offset.du;
        d[b.index()] = offset.dv;
        d
    }
}

/// Identifier of a light source, as numbered by the host.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SourceId(pub u16);

/// A point light source: its id, its position (voxel units, 2^−g lattice) and where its rays
/// leave from ([`Origin`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Source {
    /// The id every beam of this source carries.
    pub id: SourceId,
    /// (x, y, z) in voxel units; voxel (i, j, k) has its centre at the integer point.
    pub pos: [SourceCoord; 3],
    /// Where its rays leave from along each direction's axis.
    pub origin: Origin,
}

impl Source {
    /// A source at an arbitrary lattice position, its rays from the source voxel's centre
    /// plane (the thesis's rays, [`Origin::SourceVoxel`]).
    pub const fn new(id: SourceId, pos: [SourceCoord; 3]) -> Source {
        Source { id, pos, origin: Origin::SourceVoxel }
    }

    /// A source at the centre of voxel `v` (the thesis's case); `None` if a coordinate does not
    /// fit a [`SourceCoord`] (|v| ≥ 2²⁷).
    pub fn at_voxel(id: SourceId, v: [i32; 3]) -> Option<Source> {
        let mut pos = [SourceCoord::ZERO; 3];
        for (p, &c) in pos.iter_mut().zip(v.iter()) {
            *p = SourceCoord::checked_from_num(c)?;
        }
        Some(Source::new(id, pos))
    }

    /// The same source with its rays leaving from `origin`.
    pub const fn with_origin(self, origin: Origin) -> Source {
        Source { origin, ..self }
    }

    /// The source voxel: nearest centre, round half up (⌊p + ½⌋ per axis).
    #[inline]
    pub fn voxel(&self) -> [i32; 3] {
        let half = 1i64 << (G - 1);
        // |raw| ≤ 2^31 so the result is within ±2^27 + 1: it fits i32.
        self.pos.map(|p| ((p.to_bits() as i64 + half) >> G) as i32)
    }

    /// How far (sixteenths of a voxel) the rays' origin lies ahead of the centre plane of the
    /// slab [`Source::slab`] puts behind layer 1 along `dir`: 0 for [`Origin::SourceVoxel`],
    /// `s·(S_w − 16·w₀)` ∈ [0, 16) for [`Origin::Light`].
    #[cfg_attr(not(feature = "rays-from-light"), allow(unused_variables))]
    #[inline]
    pub fn lead(&self, dir: Direction) -> i64 {
        match self.origin {
            Origin::SourceVoxel => 0,
            #[cfg(feature = "rays-from-light")]
            Origin::Light => {
                let p = self.pos[dir.principal().index()].to_bits() as i64;
                (dir.sign() as i64 * p).rem_euclid(16)
            }
        }
    }

    /// `T_k`: 16 × the distance along `dir` from the rays' origin to layer k's centre plane,
    /// `max(16·k − lead, 0)` — the rays' point at layer k is the origin plus `T_k/16` times
    /// their direction `(s, u/D, v/D)`. `16·k` for [`Origin::SourceVoxel`]; 0 at layer 0 for
    /// either origin. Below 2³¹ for every layer ≤ [`MAX_FAR`].
    #[inline]
    pub fn reach(&self, dir: Direction, layer: Layer) -> i64 {
        (16 * layer.0 as i64 - self.lead(dir)).max(0)
    }

    /// The principal coordinate of layer k's voxels along `dir`: the source voxel's at layer
    /// 0 (its rays are all at their origin, which lies in it), and `w₀ + s·k` for k ≥ 1, where
    /// w₀ is the last slab whose centre plane is at or behind the origin: the source voxel's
    /// for [`Origin::SourceVoxel`]; for [`Origin::Light`] the source voxel's or the one behind
    /// it, so that layer 1 is the source voxel's slab or the next one and a ray moves at most
    /// one voxel across from any layer to the next (`T_{k+1} − T_k ≤ 16`).
    #[inline]
    pub fn slab(&self, dir: Direction, layer: Layer) -> i64 {
        let w = dir.principal().index();
        if layer.0 == 0 {
            return self.voxel()[w] as i64;
        }
        let s = dir.sign() as i64;
        let w0 = match self.origin {
            Origin::SourceVoxel => self.voxel()[w] as i64,
            // ⌊S_w/16⌋ for s = +1, ⌈S_w/16⌉ for s = −1.
            #[cfg(feature = "rays-from-light")]
            Origin::Light => s * (s * self.pos[w].to_bits() as i64).div_euclid(16),
        };
        w0 + s * layer.0 as i64
    }

    /// The layer k ≥ 1 whose voxels lie in slab `w` along `dir` (the inverse of
    /// [`Source::slab`] past layer 0; ≤ 0 for slabs at or behind layer 1's).
    pub fn layer_at(&self, dir: Direction, w: i64) -> i64 {
        dir.sign() as i64 * (w - self.slab(dir, Layer(1))) + 1
    }

    /// Where its rays leave from along `dir`, in sixteenths of a voxel (voxel centres at
    /// multiples of 16): the light across the axis, and along it the source voxel's centre
    /// plane ([`Origin::SourceVoxel`]) or the light ([`Origin::Light`]).
    pub fn ray_origin(&self, dir: Direction) -> [i64; 3] {
        let w = dir.principal().index();
        let mut o = self.pos.map(|c| c.to_bits() as i64);
        if self.origin == Origin::SourceVoxel {
            o[w] = 16 * self.voxel()[w] as i64;
        }
        o
    }
}

/// Where the rays of a source leave from along their direction's axis. Across it they leave
/// from the light; along it, from the source voxel's centre plane (§4.3's layers are whole
/// voxels from the source voxel: the thesis's rays, whose voxel at layer k is
/// `⌊x_s + u·k/D + ½⌋`) or from the light itself (`⌊x_s + u·T_k/(16·D) + ½⌋`,
/// [`Source::reach`]). The split, the lit rules and the occluders read a ray's point at layer
/// k at `T_k` sixteenths from its origin along the axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Origin {
    /// The source voxel's centre plane (lead = 0): the thesis's rays.
    #[default]
    SourceVoxel,
    /// The light itself: true rays from the source (feature `rays-from-light`, on by default).
    #[cfg(feature = "rays-from-light")]
    Light,
}

/// Layer k: the slab w = w₀ + s·k at principal distance k from the source voxel (from the slab
/// behind the light for some faces of rays from the light: [`Source::slab`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Layer(pub u32);

/// The far distance D (≥ every layer used), validated against the bit budget for f = `F::U32`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FarDistance<F: FracBits> {
    d: u32,
    _frac: PhantomData<F>,
}

impl<F: FracBits> FarDistance<F> {
    /// The largest D for this f: min(2²⁷ − 1, ⌊(2³¹ − 1)/2^f⌋) (0 when f ≥ 31: none exists).
    pub const MAX: u32 = {
        let by_offset = (i32::MAX as i64) >> F::U32;
        if by_offset < MAX_FAR as i64 {
            by_offset as u32
        } else {
            MAX_FAR
        }
    };

    /// D, if 1 ≤ D ≤ [`FarDistance::MAX`].
    pub const fn new(d: u32) -> Option<Self> {
        if d >= 1 && d <= Self::MAX {
            Some(FarDistance { d, _frac: PhantomData })
        } else {
            None
        }
    }

    /// D as an integer.
    pub const fn get(self) -> u32 {
        self.d
    }

    /// D as a far offset (the largest ray offset).
    pub const fn offset(self) -> FarOffset<F> {
        FarOffset::<F>::from_bits(self.scaled() as i32)
    }

    /// N = D·2^f: the largest ray offset in lattice steps (≤ `i32::MAX` by construction).
    pub const fn scaled(self) -> i64 {
        (self.d as i64) << F::U32
    }

    /// Lattice rays in one face's initial beam: (2N + 1)² (fits `u64`: 2N + 1 < 2³²).
    pub const fn rays_per_face(self) -> u64 {
        let side = 2 * self.scaled() as u64 + 1;
        side * side
    }

    /// Distinct ray directions over the six faces: 24N² + 2 (see the module doc).
    pub const fn distinct_directions(self) -> u128 {
        let n = self.scaled() as u128;
        24 * n * n + 2
    }
}

/// A voxel's transverse coordinates: its index along the direction's u-axis and v-axis (for a
/// ±z beam, the cell's (x, y)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Transverse {
    /// Voxel index along the u-axis.
    pub u: i32,
    /// Voxel index along the v-axis.
    pub v: i32,
}

impl Transverse {
    /// The neighbour at `offset` (wrapping at the `i32` ends, which no grid reaches).
    pub const fn offset(self, offset: Offset) -> Transverse {
        Transverse { u: self.u.wrapping_add(offset.du as i32), v: self.v.wrapping_add(offset.dv as i32) }
    }
}

/// A sub-beam's transverse move (du, dv) ∈ {−1, 0, 1}².
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Offset {
    /// Move along the u-axis.
    pub du: i8,
    /// Move along the v-axis.
    pub dv: i8,
}

impl Offset {
    /// (du, dv) if both are in {−1, 0, 1}.
    pub const fn new(du: i8, dv: i8) -> Option<Offset> {
        if du >= -1 && du <= 1 && dv >= -1 && dv <= 1 {
            Some(Offset { du, dv })
        } else {
            None
        }
    }

    const fn slot(self) -> Option<(usize, usize)> {
        match Offset::new(self.du, self.dv) {
            Some(o) => Some(((o.du + 1) as usize, (o.dv + 1) as usize)),
            None => None,
        }
    }
}

const fn off(du: i8, dv: i8) -> Offset {
    Offset { du, dv }
}

/// The order in which [`Beam::split_with`] emits sub-beams: a permutation of the nine offsets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SplitOrder {
    offsets: [Offset; 9],
    /// The order is [`SplitOrder::ROW_MAJOR`] (the split has a faster path for it).
    row_major: bool,
}

impl SplitOrder {
    /// du = −1, 0, 1 (outer) × dv = −1, 0, 1 (inner). The default.
    pub const ROW_MAJOR: SplitOrder = SplitOrder::known([
        off(-1, -1),
        off(-1, 0),
        off(-1, 1),
        off(0, -1),
        off(0, 0),
        off(0, 1),
        off(1, -1),
        off(1, 0),
        off(1, 1),
    ]);

    /// The four axis neighbours, then the four diagonals, then (0, 0) (for a ±z beam: the
    /// x/y neighbour cells first, the beam that stays in this column last).
    pub const AXIS_NEIGHBOURS_FIRST: SplitOrder = SplitOrder::known([
        off(-1, 0),
        off(1, 0),
        off(0, -1),
        off(0, 1),
        off(-1, -1),
        off(-1, 1),
        off(1, -1),
        off(1, 1),
        off(0, 0),
    ]);

    /// An order, if `order` holds each of the nine offsets exactly once.
    pub const fn new(order: [Offset; 9]) -> Option<SplitOrder> {
        let mut seen = [[false; 3]; 3];
        let mut i = 0;
        while i < 9 {
            match order[i].slot() {
                Some((a, b)) => {
                    if seen[a][b] {
                        return None;
                    }
                    seen[a][b] = true;
                }
                None => return None,
            }
            i += 1;
        }
        Some(SplitOrder::known(order))
    }

    /// The nine offsets in emission order.
    pub const fn offsets(&self) -> &[Offset; 9] {
        &self.offsets
    }

    /// The order `offsets` (a permutation of the nine offsets).
    const fn known(offsets: [Offset; 9]) -> SplitOrder {
        let mut row_major = true;
        let mut i = 0;
        while i < 9 {
            row_major &= offsets[i].du as i32 == (i / 3) as i32 - 1 && offsets[i].dv as i32 == (i % 3) as i32 - 1;
            i += 1;
        }
        SplitOrder { offsets, row_major }
    }
}

impl Default for SplitOrder {
    fn default() -> Self {
        SplitOrder::ROW_MAJOR
    }
}

/// Why a beam could not be built or split.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BeamError {
    /// A range with `lo > hi`.
    EmptyRange,
    /// A limit outside [−D, D].
    OutsideFarSquare,
    /// A layer beyond D.
    LayerBeyondFar,
    /// Split asked at layer k ≥ D: layer k + 1 would exceed the far distance.
    AtFarPlane,
    /// The beam belongs to another source than the one given.
    WrongSource,
}

// ---------------------------------------------------------------------------------------------
// Beams
// ---------------------------------------------------------------------------------------------

/// A non-empty closed interval of lattice rays `lo ..= hi` along one transverse axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RayRange<F: FracBits> {
    lo: FarOffset<F>,
    hi: FarOffset<F>,
}

impl<F: FracBits> RayRange<F> {
    /// `lo ..= hi`, if `lo ≤ hi`.
    pub fn new(lo: FarOffset<F>, hi: FarOffset<F>) -> Option<Self> {
        (lo <= hi).then_some(RayRange { lo, hi })
    }

    /// `lo ..= hi` for a piece of a beam's own range (`lo ≤ hi` and both within it: the caller's
    /// invariant, not checked).
    pub(crate) const fn within_beam(lo: FarOffset<F>, hi: FarOffset<F>) -> Self {
        RayRange { lo, hi }
    }

    /// `[−D, D]`: every ray of a face.
    pub const fn full(far: FarDistance<F>) -> Self {
        let n = far.scaled() as i32;
        RayRange { lo: FarOffset::<F>::from_bits(-n), hi: FarOffset::<F>::from_bits(n) }
    }

    /// Smallest ray (the thesis's U_min).
    pub const fn lo(self) -> FarOffset<F> {
        self.lo
    }

    /// Largest ray (the thesis's U_max).
    pub const fn hi(self) -> FarOffset<F> {
        self.hi
    }

    /// Number of lattice rays, ≥ 1 (≤ 2³², fits `u64`).
    pub const fn len(self) -> u64 {
        (self.hi.to_bits() as i64 - self.lo.to_bits() as i64 + 1) as u64
    }

    /// Never empty (an invariant of every constructor).
    pub const fn is_empty(self) -> bool {
        false
    }

    /// Whether the ray `x` lies in the range.
    pub fn contains(self, x: FarOffset<F>) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// The union of two touching ranges (`self.hi + 1 == other.lo` or the reverse), if they
    /// touch.
    pub fn joined(self, other: RayRange<F>) -> Option<RayRange<F>> {
        let (a, b) = if self.lo <= other.lo { (self, other) } else { (other, self) };
        (a.hi.to_bits() as i64 + 1 == b.lo.to_bits() as i64).then_some(RayRange { lo: a.lo, hi: b.hi })
    }

    fn within(self, far: FarDistance<F>) -> bool {
        let n = far.scaled();
        -n <= self.lo.to_bits() as i64 && self.hi.to_bits() as i64 <= n
    }
}

/// A 3D beam (§4.3.4.1): the rays `u × v` of one source and direction at one layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Beam<F: FracBits> {
    u: RayRange<F>,
    v: RayRange<F>,
    layer: Layer,
    source: SourceId,
    dir: Direction,
    /// Flags of the plane rule ([`crate::lit`]; both clear under the thesis's rule):
    /// [`Beam::is_terminal`], [`Beam::after_empty`], [`Beam::after_outside`].
    flags: u8,
}

/// [`Beam::is_terminal`].
const TERMINAL: u8 = 1;
/// [`Beam::after_empty`].
const AFTER_EMPTY: u8 = 2;
/// [`Beam::after_outside`].
const AFTER_OUTSIDE: u8 = 4;

#[cfg(feature = "defmt")]
impl<F: FracBits> defmt::Format for Beam<F> {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(
            f,
            "Beam {{ source: {=u16}, dir: {}, layer: {=u32}, u: [{=i32}, {=i32}], v: [{=i32}, {=i32}] (2^-{=u32}) }}",
            self.source.0,
            self.dir,
            self.layer.0,
            self.u.lo.to_bits(),
            self.u.hi.to_bits(),
            self.v.lo.to_bits(),
            self.v.hi.to_bits(),
            F::U32
        )
    }
}

/// One output of a split: the sub-beam (at layer k + 1) and its transverse move.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SubBeam<F: FracBits> {
    /// Where it goes: the voxel at `at.offset(offset)` in layer k + 1.
    pub offset: Offset,
    /// Its rays, at layer k + 1.
    pub beam: Beam<F>,
}

/// The sub-beams of one split: at most nine, none empty.
pub type SubBeams<F> = Vec<SubBeam<F>, 9>;

impl<F: FracBits> Beam<F> {
    /// The initial beam of `source` toward `dir`: all rays [−D, D]² at layer 0.
    pub fn initial(source: &Source, dir: Direction, far: FarDistance<F>) -> Self {
        let full = RayRange::full(far);
        Beam { u: full, v: full, layer: Layer(0), source: source.id, dir, flags: 0 }
    }

    /// The six initial beams of `source`, in [`Direction::ALL`] order (see the module doc for
    /// how they overlap on the cube's edges).
    pub fn initial_six(source: &Source, far: FarDistance<F>) -> [Self; 6] {
        Direction::ALL.map(|d| Beam::initial(source, d, far))
    }

    /// A beam from its parts (e.g. decoded from a message), if its ranges lie in [−D, D] and
    /// its layer is ≤ D. Whether it is consistent with a voxel is [`Beam::occupies`].
    pub fn new(
        source: SourceId,
        dir: Direction,
        layer: Layer,
        u: RayRange<F>,
        v: RayRange<F>,
        far: FarDistance<F>,
    ) -> Result<Self, BeamError> {
        if !u.within(far) || !v.within(far) {
            return Err(BeamError::OutsideFarSquare);
        }
        if layer.0 > far.get() {
            return Err(BeamError::LayerBeyondFar);
        }
        Ok(Beam { u, v, layer, source, dir, flags: 0 })
    }

    /// Rays along the u-axis: [u_min, u_max].
    pub const fn u(&self) -> RayRange<F> {
        self.u
    }

    /// Rays along the v-axis: [v_min, v_max].
    pub const fn v(&self) -> RayRange<F> {
        self.v
    }

    /// The layer the beam is at.
    pub const fn layer(&self) -> Layer {
        self.layer
    }

    /// Its source.
    pub const fn source(&self) -> SourceId {
        self.source
    }

    /// Its direction.
    pub const fn direction(&self) -> Direction {
        self.dir
    }

    /// Whether its rays are terminal: they act at this layer's voxel and die ([`crate::lit`]).
    pub const fn is_terminal(&self) -> bool {
        self.flags & TERMINAL != 0
    }

    /// The same rays, terminal or not.
    pub const fn with_terminal(self, terminal: bool) -> Self {
        Beam { flags: (self.flags & !TERMINAL) | if terminal { TERMINAL } else { 0 }, ..self }
    }

    /// Whether its rays were in an empty voxel at the previous layer ([`crate::lit`]: a ray
    /// that comes from empty space into the back of a surface voxel's plane crossed a surface
    /// between the two layers).
    pub const fn after_empty(&self) -> bool {
        self.flags & AFTER_EMPTY != 0
    }

    /// The same rays, with or without [`Beam::after_empty`].
    pub const fn with_after_empty(self, after_empty: bool) -> Self {
        Beam { flags: (self.flags & !AFTER_EMPTY) | if after_empty { AFTER_EMPTY } else { 0 }, ..self }
    }

    /// Whether its rays were, at the previous layer, in an occupied voxel of another column and
    /// on the outside of its plane ([`crate::lit`]: a ray that comes from there into the back
    /// of a plane facing the source crossed a surface between the two layers).
    pub const fn after_outside(&self) -> bool {
        self.flags & AFTER_OUTSIDE != 0
    }

    /// The same rays, with or without [`Beam::after_outside`].
    pub const fn with_after_outside(self, after_outside: bool) -> Self {
        Beam { flags: (self.flags & !AFTER_OUTSIDE) | if after_outside { AFTER_OUTSIDE } else { 0 }, ..self }
    }

    /// The same beam with other ray ranges (within the far square when `self` is).
    pub(crate) const fn with_rays(self, u: RayRange<F>, v: RayRange<F>) -> Self {
        Beam { u, v, ..self }
    }

    /// Number of lattice rays in the beam, ≥ 1 (≤ (2³² − 1)², fits `u64`).
    pub const fn ray_count(&self) -> u64 {
        self.u.len() * self.v.len()
    }

    /// A filler for unused slots of fixed-size buffers (never read as a beam).
    pub(crate) const fn filler() -> Self {
        Beam {
            u: RayRange { lo: FarOffset::<F>::ZERO, hi: FarOffset::<F>::ZERO },
            v: RayRange { lo: FarOffset::<F>::ZERO, hi: FarOffset::<F>::ZERO },
            layer: Layer(0),
            source: SourceId(0),
            dir: Direction::PosX,
            flags: 0,
        }
    }

    /// The union of two beams of the same source, direction and layer whose ray rectangles
    /// share a whole side (equal u range and touching v ranges, or the reverse); `None`
    /// otherwise. When both beams are in the same voxel the merge is exact: a ray's voxel at
    /// every later layer depends only on (u, v) and the layer, not on the beam it came in.
    pub fn merged(&self, other: &Beam<F>) -> Option<Beam<F>> {
        if self.source != other.source
            || self.dir != other.dir
            || self.layer != other.layer
            || self.flags != other.flags
        {
            return None;
        }
        let (u, v) = if self.u == other.u {
            (self.u, self.v.joined(other.v)?)
        } else if self.v == other.v {
            (self.u.joined(other.u)?, self.v)
        } else {
            return None;
        };
        Some(Beam { u, v, ..*self })
    }

    /// Whether the ray (u, v) is in the beam.
    pub fn contains(&self, u: FarOffset<F>, v: FarOffset<F>) -> bool {
        self.u.contains(u) && self.v.contains(v)
    }

    /// Whether every ray of the beam occupies voxel `at` at the beam's layer (by monotonicity,
    /// checked on the two corners with [`trace_ray_voxel`]).
    pub fn occupies(&self, source: &Source, far: FarDistance<F>, at: Transverse) -> bool {
        let k = self.layer;
        let want = (at.u as i64, at.v as i64);
        trace_ray_voxel(source, self.dir, self.u.lo, self.v.lo, far, k) == want
            && trace_ray_voxel(source, self.dir, self.u.hi, self.v.hi, far, k) == want
    }

    /// Whether the beam holds every ray of the far square that occupies voxel `at` at its
    /// layer — no other beam of this source and direction can ever bring rays to that voxel,
    /// so there is nothing left to merge with. For a consistent beam (see
    /// [`Beam::occupies`]); four multiplications, no division. Layer 0 holds the whole square.
    pub fn complete(&self, source: &Source, far: FarDistance<F>, at: Transverse) -> bool {
        let m = self.layer.0 as i64;
        if m == 0 {
            return self.u == RayRange::full(far) && self.v == RayRange::full(far);
        }
        let (ua, va) = self.dir.transverse();
        let q = 2 * source.reach(self.dir, self.layer);
        AxisPlanes::new(source.pos[ua.index()], at.u, far, q).spans(self.u, far)
            && AxisPlanes::new(source.pos[va.index()], at.v, far, q).spans(self.v, far)
    }

    /// The voxel of the beam's (u_min, v_min) ray at the beam's layer — the beam's voxel when it
    /// is consistent. `None` if it does not fit `i32` (rays beyond the far square only).
    pub fn voxel(&self, source: &Source, far: FarDistance<F>) -> Option<Transverse> {
        let (a, b) = trace_ray_voxel(source, self.dir, self.u.lo, self.v.lo, far, self.layer);
        Some(Transverse { u: i32::try_from(a).ok()?, v: i32::try_from(b).ok()? })
    }

    /// Split the beam held by the cell at transverse position `at` into its sub-beams at layer
    /// k + 1, in [`SplitOrder::ROW_MAJOR`] order. See [`Beam::split_with`].
    pub fn split(&self, source: &Source, far: FarDistance<F>, at: Transverse) -> Result<SubBeams<F>, BeamError> {
        self.split_with(source, far, at, &SplitOrder::ROW_MAJOR)
    }

    /// Split the beam held at `at` (§4.3.4.2): every ray goes to the one sub-beam whose voxel
    /// `at.offset(offset)` it occupies at layer k + 1; empty sub-beams are not emitted; the
    /// sub-beams come in `order`.
    ///
    /// If the beam is not consistent with `at` (see [`Beam::occupies`]) the result is still a
    /// partition of its rays by the planes of `at`, but not the rays' true voxels.
    ///
    /// Errors: [`BeamError::WrongSource`] if `source.id` is not the beam's,
    /// [`BeamError::AtFarPlane`] if k ≥ D, [`BeamError::OutsideFarSquare`] if a limit is
    /// outside [−D, D] (a beam made for a larger D).
    pub fn split_with(
        &self,
        source: &Source,
        far: FarDistance<F>,
        at: Transverse,
        order: &SplitOrder,
    ) -> Result<SubBeams<F>, BeamError> {
        let mut out = SubBeams::new();
        // At most nine distinct offsets (a SplitOrder is a permutation): never full.
        self.split_each(source, far, at, order, |sb| {
            let _ = out.push(sb);
        })?;
        Ok(out)
    }

    /// [`Beam::split_with`] handing each sub-beam to `emit`, in `order`, instead of collecting
    /// them: the cell's step files sub-beams straight into its own list, with no intermediate
    /// array to fill and copy. Same sub-beams, same order, same errors (checked before any
    /// sub-beam is emitted).
    pub fn split_each(
        &self,
        source: &Source,
        far: FarDistance<F>,
        at: Transverse,
        order: &SplitOrder,
        mut emit: impl FnMut(SubBeam<F>),
    ) -> Result<(), BeamError> {
        let split = self.split_axes(source, far, at)?;
        split.each(order, |offset, i, j| emit(SubBeam { offset, beam: split.sub_beam(self, i, j) }));
        Ok(())
    }

    /// The split of the beam held at `at` (see [`Beam::split_with`]), axis by axis: which rays
    /// of each transverse axis go to each of the three voxels at layer k + 1. The sub-beams are
    /// the non-empty products of the two axes' pieces ([`Split::each`], [`Split::sub_beam`]).
    /// Same errors as [`Beam::split_with`].
    #[inline]
    pub fn split_axes(&self, source: &Source, far: FarDistance<F>, at: Transverse) -> Result<Split, BeamError> {
        if self.source != source.id {
            return Err(BeamError::WrongSource);
        }
        if self.layer.0 >= far.get() {
            return Err(BeamError::AtFarPlane);
        }
        if !self.u.within(far) || !self.v.within(far) {
            return Err(BeamError::OutsideFarSquare);
        }
        let (ua, va) = self.dir.transverse();
        // k + 1 ≤ D ≤ MAX_FAR, so 0 < T_{k+1} ≤ 16·(k + 1) < 2³¹.
        let next = Layer(self.layer.0 + 1);
        let q = 2 * source.reach(self.dir, next);
        Ok(Split {
            u: split_axis(self.u, source.pos[ua.index()], at.u, far, q),
            v: split_axis(self.v, source.pos[va.index()], at.v, far, q),
        })
    }
}

/// The rays of one transverse axis of a beam that go to voxel x − 1, x, x + 1 at the next layer
/// (index 0, 1, 2): `lo[i] ..= hi[i]` in lattice steps (`to_bits`), for the pieces of `mask`
/// (bit i); the others are empty.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisSplit {
    lo: [i32; 3],
    hi: [i32; 3],
    mask: u8,
}

impl AxisSplit {
    /// The non-empty pieces (bit i: voxel x − 1 + i).
    pub const fn mask(&self) -> u8 {
        self.mask
    }

    /// Piece i's rays (meaningful when bit i of [`AxisSplit::mask`] is set).
    pub fn range<F: FracBits>(&self, i: usize) -> RayRange<F> {
        RayRange { lo: FarOffset::<F>::from_bits(self.lo[i]), hi: FarOffset::<F>::from_bits(self.hi[i]) }
    }
}

/// A beam's split into sub-beams, axis by axis ([`Beam::split_axes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Split {
    /// The u-axis pieces.
    pub u: AxisSplit,
    /// The v-axis pieces.
    pub v: AxisSplit,
}

impl Split {
    /// `f(offset, i, j)` for each non-empty sub-beam (u piece i, v piece j, offset (i − 1,
    /// j − 1)), in `order`.
    #[inline]
    pub fn each(&self, order: &SplitOrder, mut f: impl FnMut(Offset, usize, usize)) {
        let (mu, mv) = (self.u.mask, self.v.mask);
        if order.row_major {
            // The default order, du outer and dv inner: a missing u piece skips its whole row.
            for i in 0..3 {
                if mu >> i & 1 == 0 {
                    continue;
                }
                for j in 0..3 {
                    if mv >> j & 1 == 1 {
                        f(Offset { du: i as i8 - 1, dv: j as i8 - 1 }, i, j);
                    }
                }
            }
            return;
        }
        for &offset in order.offsets() {
            // A `SplitOrder` holds valid offsets only (checked when it was made).
            let (i, j) = ((offset.du + 1) as usize, (offset.dv + 1) as usize);
            if mu >> i & 1 == 1 && mv >> j & 1 == 1 {
                f(offset, i, j);
            }
        }
    }

    /// Sub-beam (i, j) of `beam` (the beam split): its rays at layer k + 1.
    #[inline]
    pub fn sub_beam<F: FracBits>(&self, beam: &Beam<F>, i: usize, j: usize) -> Beam<F> {
        Beam { u: self.u.range(i), v: self.v.range(j), layer: Layer(beam.layer.0 + 1), ..*beam }
    }
}

/// The two planes of voxel x at a layer m on one transverse axis, scaled so that a lattice ray
/// a (`to_bits`) compares with one multiplication: u < U1 ⇔ a·q < n1, u ≥ U2 ⇔ a·q ≥ n2, with
/// q = 2·T_m ([`Source::reach`]; 32·m for the thesis's rays). See the module doc for the
/// budget: every product is < 2⁶³ in magnitude.
#[derive(Clone, Copy)]
struct AxisPlanes {
    q: i64,
    n1: i64,
    n2: i64,
}

impl AxisPlanes {
    fn new<F: FracBits>(src: SourceCoord, x: i32, far: FarDistance<F>, q: i64) -> Self {
        // 0 < q = 2·T_m ≤ m·2^(g+1) < 2^32. Planes beyond ±(D+1)·16·D/T_m (beyond every ray:
        // T_m ≤ 16·m ≤ 16·D).
        let limit = (far.get() as i64 + 1) << (G + 1);
        let r = 2 * (((x as i64) << G) - src.to_bits() as i64); // 2^(g+1)·(x − x_s), |r| < 2^37
        let c1 = (r - (1 << G)).clamp(-limit, limit);
        let c2 = (r + (1 << G)).clamp(-limit, limit);
        let n = far.scaled(); // D·2^f ≤ i32::MAX
        AxisPlanes { q, n1: c1 * n, n2: c2 * n }
    }

    /// 0, 1, 2: ray a occupies voxel x − 1, x, x + 1 at the planes' layer.
    fn class(self, a: i64) -> usize {
        let aq = a * self.q;
        if aq < self.n1 {
            0
        } else if aq >= self.n2 {
            2
        } else {
            1
        }
    }

    /// Whether `range` (rays of voxel x) reaches both ends of the voxel's rays within [−N, N]:
    /// the ray below its first is in x − 1 (or beyond the far square), the ray above its last in
    /// x + 1.
    fn spans<F: FracBits>(self, range: RayRange<F>, far: FarDistance<F>) -> bool {
        let n = far.scaled();
        let (lo, hi) = (range.lo.to_bits() as i64, range.hi.to_bits() as i64);
        (lo == -n || self.class(lo - 1) == 0) && (hi == n || self.class(hi + 1) == 2)
    }
}

/// The lattice rays (`to_bits` units, `lo ..= hi`, empty when lo > hi) of one transverse axis
/// that stay in voxel coordinate `x` from layer k to layer k + 1 (the split's middle class),
/// for the cell at `x` and source coordinate `src`: `⌈n1/q⌉ ..= ⌈n2/q⌉ − 1`. `reach` is
/// `T_{k+1}` ([`Source::reach`] of layer k + 1: 16·(k + 1) for the thesis's rays), > 0.
pub fn staying_rays<F: FracBits>(src: SourceCoord, x: i32, far: FarDistance<F>, reach: i64) -> (i64, i64) {
    let AxisPlanes { q, n1, n2 } = AxisPlanes::new(src, x, far, 2 * reach);
    (ceil_div(n1, q), ceil_div(n2, q) - 1)
}

/// ⌈n / q⌉ for q > 0 and |n| < 2⁶³.
const fn ceil_div(n: i64, q: i64) -> i64 {
    -((-n).div_euclid(q))
}

/// The rays of `range` that go to x − 1, x, x + 1 (indices 0, 1, 2) at layer k + 1 (q = 2·T_{k+1}),
/// for the cell at transverse coordinate `x` and source coordinate `src`. See the module doc
/// for the budget: every product below is < 2⁶³ in magnitude. A quotient is taken only for a
/// plane the range straddles.
#[inline]
fn split_axis<F: FracBits>(range: RayRange<F>, src: SourceCoord, x: i32, far: FarDistance<F>, q: i64) -> AxisSplit {
    let planes = AxisPlanes::new(src, x, far, q);
    let AxisPlanes { q, n1, n2 } = planes;
    let (lo, hi) = (range.lo.to_bits(), range.hi.to_bits());
    let (cl, ch) = (planes.class(lo as i64), planes.class(hi as i64));
    let mut out = AxisSplit { lo: [0; 3], hi: [0; 3], mask: 0 };
    if cl == ch {
        (out.lo[cl], out.hi[cl], out.mask) = (lo, hi, 1 << cl);
        return out;
    }
    // The beam straddles a plane: the first lattice rays at or above U1 (when the range
    // starts below it) and U2 (when it ends at or above it), both within lo + 1 ..= hi (so in
    // i32). The ray below U1 is in x − 1, the one at U2 in x + 1: those pieces are not empty.
    let t1 = if cl == 0 { ceil_div(n1, q) as i32 } else { lo };
    let t2 = if ch == 2 { ceil_div(n2, q) as i32 } else { hi + 1 };
    if cl == 0 {
        (out.lo[0], out.hi[0], out.mask) = (lo, t1 - 1, 1);
    }
    let (a, b) = (t1.max(lo), (t2 - 1).min(hi));
    if a <= b {
        (out.lo[1], out.hi[1], out.mask) = (a, b, out.mask | 2);
    }
    if ch == 2 {
        (out.lo[2], out.hi[2], out.mask) = (t2, hi, out.mask | 4);
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Oracles and exact planes
// ---------------------------------------------------------------------------------------------

/// The transverse voxel `(⌊x_s + u·T_k/(16·D) + ½⌋, ⌊y_s + v·T_k/(16·D) + ½⌋)` of ray (u, v)
/// at layer k (`T_k` = [`Source::reach`]: `(⌊x_s + u·k/D + ½⌋, …)` for the thesis's rays),
/// computed directly in `i128` (independently of the split). Exact for every input with
/// |u|, |v| ≤ D; saturates at the `i64` ends otherwise (rays that do not exist).
pub fn trace_ray_voxel<F: FracBits>(
    source: &Source,
    dir: Direction,
    u: FarOffset<F>,
    v: FarOffset<F>,
    far: FarDistance<F>,
    k: Layer,
) -> (i64, i64) {
    let (ua, va) = dir.transverse();
    let f = F::U32;
    let d = far.get();
    let t = source.reach(dir, k);
    (
        trace_axis(source.pos[ua.index()].to_bits(), u.to_bits(), f, d, t),
        trace_axis(source.pos[va.index()].to_bits(), v.to_bits(), f, d, t),
    )
}

/// ⌊b/2^g + (a/2^f)·t/(2^g·D) + ½⌋ over the common denominator 2^(f+g+1)·D (all < 2¹⁰⁰).
fn trace_axis(b: i32, a: i32, f: u32, d: u32, t: i64) -> i64 {
    let d = d as i128;
    let pf = 1i128 << f;
    let den = (pf << (G + 1)) * d;
    let num = (b as i128) * (pf << 1) * d + 2 * (a as i128) * (t as i128) + (pf << G) * d;
    num.div_euclid(den).clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

/// An exact rational `num / den`, `den > 0`, compared by cross-multiplication.
#[derive(Clone, Copy, Debug)]
pub struct Ratio {
    num: i64,
    den: i64,
}

impl Ratio {
    /// `num / den`, if `den > 0`.
    pub const fn new(num: i64, den: i64) -> Option<Ratio> {
        if den > 0 {
            Some(Ratio { num, den })
        } else {
            None
        }
    }

    /// The numerator.
    pub const fn num(self) -> i64 {
        self.num
    }

    /// The (positive) denominator.
    pub const fn den(self) -> i64 {
        self.den
    }

    /// The smallest lattice ray ≥ this value, in lattice steps (`to_bits` units) of 2^−f:
    /// the exact "fixed-point Y_med".
    pub fn lattice_ceil<F: FracBits>(self) -> i128 {
        let n = (self.num as i128) << F::U32;
        -((-n).div_euclid(self.den as i128))
    }
}

impl PartialEq for Ratio {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Ratio {}

impl PartialOrd for Ratio {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Ratio {
    fn cmp(&self, other: &Self) -> Ordering {
        // |num·den| < 2^126: no overflow.
        (self.num as i128 * other.den as i128).cmp(&(other.num as i128 * self.den as i128))
    }
}

/// The four split planes of a cell (in far-plane units): a ray goes to u − 1 iff u < `u1`,
/// to u + 1 iff u ≥ `u2`; the same for v.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SplitPlanes {
    /// U1 = (x − x_s − ½)·D/(k + 1) (`16·D/T_{k+1}` for rays from the light).
    pub u1: Ratio,
    /// U2 = (x − x_s + ½)·D/(k + 1) (the thesis's Y_med).
    pub u2: Ratio,
    /// V1 = (y − y_s − ½)·D/(k + 1).
    pub v1: Ratio,
    /// V2 = (y − y_s + ½)·D/(k + 1).
    pub v2: Ratio,
}

/// The exact planes U1, U2, V1, V2 for splitting a beam of `source` toward `dir` held at `at`,
/// layer `layer`, into layer + 1. `None` if a numerator does not fit `i64` (only for `at`
/// implausibly far from the source: |x − x_s|·D ≳ 2⁵⁸).
pub fn split_planes<F: FracBits>(
    source: &Source,
    dir: Direction,
    far: FarDistance<F>,
    layer: Layer,
    at: Transverse,
) -> Option<SplitPlanes> {
    let (ua, va) = dir.transverse();
    let den = 2 * source.reach(dir, Layer(layer.0 + 1));
    let d = far.get() as i64;
    let plane = |src: SourceCoord, x: i32, sign: i64| -> Option<Ratio> {
        let c = 2 * (((x as i64) << G) - src.to_bits() as i64) + sign * (1 << G);
        Ratio::new(c.checked_mul(d)?, den)
    };
    Some(SplitPlanes {
        u1: plane(source.pos[ua.index()], at.u, -1)?,
        u2: plane(source.pos[ua.index()], at.u, 1)?,
        v1: plane(source.pos[va.index()], at.v, -1)?,
        v2: plane(source.pos[va.index()], at.v, 1)?,
    })
}

/// Run `$body` with the type alias `$F` bound to the `typenum` type for the run-time fraction
/// bits `$f`: `Some(body)` for f ∈ {0, 1, …, 8, 10, 12, 16, 20, 24}, `None` otherwise. Each
/// listed f monomorphises `$body` once.
///
/// ```
/// use cell_core::beam::{FarDistance, FracBits};
/// fn max_far<F: FracBits>() -> u32 { FarDistance::<F>::MAX }
/// assert_eq!(cell_core::with_frac_bits!(16u32, F => max_far::<F>()), Some(32_767));
/// assert_eq!(cell_core::with_frac_bits!(9u32, F => max_far::<F>()), None);
/// ```
#[macro_export]
macro_rules! with_frac_bits {
    ($f:expr, $F:ident => $body:expr) => {{
        match $f {
            0 => {
                type $F = $crate::beam::frac::U0;
                Some($body)
            }
            1 => {
                type $F = $crate::beam::frac::U1;
                Some($body)
            }
            2 => {
                type $F = $crate::beam::frac::U2;
                Some($body)
            }
            3 => {
                type $F = $crate::beam::frac::U3;
                Some($body)
            }
            4 => {
                type $F = $crate::beam::frac::U4;
                Some($body)
            }
            5 => {
                type $F = $crate::beam::frac::U5;
                Some($body)
            }
            6 => {
                type $F = $crate::beam::frac::U6;
                Some($body)
            }
            7 => {
                type $F = $crate::beam::frac::U7;
                Some($body)
            }
            8 => {
                type $F = $crate::beam::frac::U8;
                Some($body)
            }
            10 => {
                type $F = $crate::beam::frac::U10;
                Some($body)
            }
            12 => {
                type $F = $crate::beam::frac::U12;
                Some($body)
            }
            16 => {
                type $F = $crate::beam::frac::U16;
                Some($body)
            }
            20 => {
                type $F = $crate::beam::frac::U20;
                Some($body)
            }
            24 => {
                type $F = $crate::beam::frac::U24;
                Some($body)
            }
            _ => None,
        }
    }};
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use fixed::types::extra::{U0, U8};

    #[test]
    fn budget_table() {
        assert_eq!(FarDistance::<U0>::MAX, MAX_FAR);
        assert_eq!(FarDistance::<frac::U4>::MAX, MAX_FAR);
        assert_eq!(FarDistance::<frac::U5>::MAX, 67_108_863);
        assert_eq!(FarDistance::<U8>::MAX, 8_388_607);
        assert_eq!(FarDistance::<frac::U12>::MAX, 524_287);
        assert_eq!(FarDistance::<frac::U16>::MAX, 32_767);
        assert_eq!(FarDistance::<frac::U20>::MAX, 2_047);
        assert_eq!(FarDistance::<frac::U24>::MAX, 127);
        assert_eq!(FarDistance::<frac::U30>::MAX, 1);
        assert_eq!(FarDistance::<frac::U31>::MAX, 0);
        assert_eq!(FarDistance::<frac::U32>::MAX, 0);
        assert!(FarDistance::<frac::U31>::new(1).is_none());
        assert!(FarDistance::<U8>::new(0).is_none());
        assert!(FarDistance::<U8>::new(8_388_608).is_none());
        assert_eq!(FarDistance::<U8>::new(8_388_607).unwrap().offset().to_bits(), i32::MAX - 255);
    }

    #[test]
    fn ceil_div_matches_definition() {
        for n in -50i64..=50 {
            for q in 1i64..=7 {
                let c = ceil_div(n, q);
                assert!(c * q >= n && (c - 1) * q < n, "{n}/{q}");
            }
        }
    }

    #[test]
    fn split_axis_single_class_is_identity() {
        let far = FarDistance::<U0>::new(8).unwrap();
        let r = RayRange::<U0>::new(FarOffset::from_num(0), FarOffset::from_num(0)).unwrap();
        let out = split_axis(r, SourceCoord::ZERO, 0, far, 32);
        assert_eq!((out.mask(), out.range::<U0>(1)), (0b010, r));
    }

    /// `complete` against the per-ray oracle, exhaustively on small cases: for every voxel of
    /// every layer, the rays of the far square that occupy it (found ray by ray with
    /// [`trace_ray_voxel`]) form a rectangle R; the beam R is complete, and R less one lattice
    /// row or column on any side is not.
    fn complete_matches_rays<F: FracBits>(d: u32, pos: [f64; 3], dir: Direction) {
        let far = FarDistance::<F>::new(d).unwrap();
        let src = Source::new(SourceId(0), pos.map(SourceCoord::from_num));
        let n = far.scaled() as i32;
        let ray = |a: i32| FarOffset::<F>::from_bits(a);
        let range = |lo: i32, hi: i32| RayRange::<F>::new(ray(lo), ray(hi)).unwrap();
        let mut checked = 0;
        for k in 0..=d {
            // Per axis, the rays of each voxel coordinate (an interval, by monotonicity).
            let per_axis = |ax: usize, other: i32| -> std::vec::Vec<(i64, i32, i32)> {
                let mut out: std::vec::Vec<(i64, i32, i32)> = std::vec::Vec::new();
                for a in -n..=n {
                    let (u, v) = if ax == 0 { (a, other) } else { (other, a) };
                    let (x, y) = trace_ray_voxel(&src, dir, ray(u), ray(v), far, Layer(k));
                    let c = if ax == 0 { x } else { y };
                    match out.last_mut() {
                        Some(l) if l.0 == c => l.2 = a,
                        _ => out.push((c, a, a)),
                    }
                }
                out
            };
            for &(xu, ulo, uhi) in &per_axis(0, 0) {
                for &(xv, vlo, vhi) in &per_axis(1, 0) {
                    let at = Transverse { u: xu as i32, v: xv as i32 };
                    let beam =
                        Beam { u: range(ulo, uhi), v: range(vlo, vhi), layer: Layer(k), source: src.id, dir, flags: 0 };
                    assert!(beam.occupies(&src, far, at));
                    assert!(beam.complete(&src, far, at), "k {k} at {at:?}: {beam:?}");
                    let shrunk = [
                        (ulo + 1, uhi, vlo, vhi),
                        (ulo, uhi - 1, vlo, vhi),
                        (ulo, uhi, vlo + 1, vhi),
                        (ulo, uhi, vlo, vhi - 1),
                    ];
                    for (a, b, c, e) in shrunk {
                        if a <= b && c <= e {
                            let part = Beam { u: range(a, b), v: range(c, e), ..beam };
                            assert!(!part.complete(&src, far, at), "k {k} at {at:?}: {part:?} is a part");
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 0);
    }

    #[test]
    fn complete_matches_the_per_ray_oracle() {
        for dir in [Direction::PosZ, Direction::NegX, Direction::PosY] {
            for pos in [[4.0, 4.0, 4.0], [3.5, 4.25, 5.0625], [0.0, 7.9375, 2.5]] {
                for d in [1, 3, 7] {
                    complete_matches_rays::<U0>(d, pos, dir);
                    complete_matches_rays::<frac::U2>(d, pos, dir);
                }
                complete_matches_rays::<frac::U1>(12, pos, dir);
            }
        }
    }

    #[test]
    fn sizes() {
        assert_eq!(core::mem::size_of::<Beam<U8>>(), 24);
        assert_eq!(core::mem::size_of::<Beam<U0>>(), 24);
    }
}
