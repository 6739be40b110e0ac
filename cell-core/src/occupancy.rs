//! A coarse occupancy summary of the scene and a sound "this beam's frustum is empty" test.
//!
//! During the lighting phase a cell processes a beam — the rays `[u_lo, u_hi] × [v_lo, v_hi]`
//! of one source and direction at layer k — and splits it ([`crate::beam`]). If no voxel that
//! any of those rays occupies at a layer ≥ k₀ (and inside the grid) is occupied, the rays will
//! all leave the grid without lighting anything, and the beam can be dropped. The receding
//! skip ([`crate::light::OccupiedBox`]) catches the beams that have passed the scene's bounding
//! box; [`OccupancySummary::frustum_empty`] also catches the ones that pass *beside* or
//! *between* objects, at the resolution of a B × B × B block grid.
//!
//! # The summary
//!
//! The grid (n × n columns, `depth` voxels each) is cut into B blocks per axis, B ≤ 32, of side
//! `s = ⌈extent / B⌉` voxels (x, y: extent n; z: extent `depth`); the last block of an axis may
//! be partial, and there may be fewer than B blocks on an axis (`⌈extent / s⌉`). A block is
//! *occupied* if one of its voxels is. Every cell holds the same summary (each cell marks its
//! own column's dexels, [`OccupancySummary::mark_column`]; the summaries are OR-reduced,
//! [`OccupancySummary::union`], and broadcast after loading).
//!
//! The blocks are stored twice, so that for each principal axis w a slab of blocks (one block
//! index j along w) is a set of *rows* along the beam's u-axis, each a bit mask over the
//! v-axis (the transverse axes of [`Direction`](crate::beam::Direction)):
//!
//! | w | transverse (u, v) | row of (slab j, u-block i) |
//! |---|-------------------|----------------------------|
//! | x | (y, z) | `xy[j][i]`: bits over z |
//! | y | (x, z) | `xy[i][j]`: bits over z |
//! | z | (x, y) | `zx[j][i]`: bits over y |
//!
//! plus, per principal axis w: for each slab the two *projections* (which u-blocks, which
//! v-blocks of the slab hold an occupied block), the *shadow* of all blocks along w (B rows
//! over (u, v)), and the mask of non-empty slabs. A row is a [`BlockRow`] (`u8`, `u16` or
//! `u32`: B ≤ its bits), so the summary takes `2·B²·|row| + 9·B·|row| + 3·|row| + 27` bytes,
//! rounded up to 4 (no pointer or `usize`: the same on the host and on thumbv7em):
//!
//! | type | B | s at n = 1024 | bytes ([`OccupancySummary::BYTES`]) |
//! |------|---|---------------|-------------------------------------|
//! | [`Occupancy8`] = `OccupancySummary<8, u8>` | 8 | 128 | 232 |
//! | [`Occupancy16`] = `OccupancySummary<16, u16>` | 16 | 64 | 1 348 |
//! | [`Occupancy32`] = `OccupancySummary<32, u32>` | 32 | 32 | 9 384 |
//! | `OccupancySummary<8>` (u32 rows) | 8 | 128 | 840 |
//!
//! # The frustum test
//!
//! A ray (u, v) is at principal coordinate `w_s + σ·k` at layer k (w_s: the source voxel's
//! principal coordinate, σ the direction's sign; from the light, the slab behind layer 1,
//! [`Source::slab`]) and at transverse voxel `x(u, k) = ⌊x_s + u·T_k/(16·D) + ½⌋` (`T_k = 16·k`
//! for the thesis's rays, [`Source::reach`]; [`trace_ray_voxel`](crate::beam::trace_ray_voxel)). The test
//! walks the slabs along w from the slab of layer `ka` to the slab of layer `kb`, where
//! `[ka, kb]` is `[k₀, D]` cut to the layers whose principal coordinate is inside the grid. For
//! the layers `[K₁, K₂]` of one slab, the rays' u-voxels lie in
//!
//! ```text
//!   [ min(x(u_lo, K₁), x(u_lo, K₂)),  max(x(u_hi, K₁), x(u_hi, K₂)) ]
//! ```
//!
//! because x is monotone (non-decreasing) in u for fixed k and monotone in k (with the sign of
//! u) for fixed u: x(u, k) ≥ x(u_lo, k) ≥ min over the ends of [K₁, K₂], and likewise above.
//! Which end gives the extreme is known from the sign of u_lo (resp. u_hi), so each bound is
//! **one** evaluation. The same holds for v. The bounds are cut to the grid and turned into
//! block ranges; the slab is clear if no row of the rectangle has an occupied bit in it.
//! Before the walk, the same two bounds over all of `[ka, kb]` give the rectangle of the whole
//! remaining frustum, tested at once against the blocks' shadow along w (and each slab's
//! projections against it, before its own bounds are computed).
//! **Soundness**: every voxel any ray occupies at a layer in `[ka, kb]` inside the grid lies in
//! the rectangle of its slab, so an occupied one makes its block's bit show; and layers outside
//! `[ka, kb]` are either below k₀, beyond D (no ray goes there) or outside the grid along w.
//!
//! **Exactness.** On a layer the rays of a beam occupy exactly the product of a u-interval and
//! a v-interval (lattice rays are 2^−f·k/D ≤ 1 voxel apart, so their voxels are contiguous), so
//! with one voxel per block (B ≥ n and B ≥ depth: one layer per slab) the test is *exact*: it
//! answers `true` iff no ray meets an occupied voxel (tested). With larger blocks the only
//! losses are the block granularity and the hull of a slab's layers (the rectangle spans the
//! beam's positions at both ends of the slab).
//!
//! Exact integer arithmetic: with a = u·2^f (`to_bits`), b = x_s·2^g, N = D·2^f,
//!
//! ```text
//!   x(u, k) = ⌊ ((b + 2^(g−1))·N + a·T_k) / (2^g·N) ⌋,   block = ⌊ numerator / (2^g·N·s) ⌋
//! ```
//!
//! (⌊⌊p⌋/s⌋ = ⌊p/s⌋ for integer s > 0), and the numerator is compared with `2^g·N·extent` to cut
//! at the grid's far edge without dividing.
//!
//! # Bit budget
//!
//! All `i64`. With |b + 2^(g−1)| ≤ 2³¹ + 7, |a| ≤ N ≤ 2³¹ − 1 (limits beyond ±D make the test
//! answer `false` at once) and 0 ≤ T_k ≤ 2^g·k ≤ 2^g·D, D ≤ [`MAX_FAR`] = 2²⁷ − 1, the numerator
//! is at most N·(2³¹ + 7 + 2^g·D) ≤ (2³¹ − 1)·(2³² − 9) < 2⁶³; the divisor 2^g·N·s and the edge
//! 2^g·N·extent are < 2⁴·2³¹·2¹⁶ = 2⁵¹ (extents ≤ [`MAX_N`] = 2¹⁶). Layer arithmetic involves
//! |w_s| ≤ 2²⁷ + 1 and extents ≤ 2¹⁶. Checked by `const` assertions.
//!
//! # Cost per call
//!
//! * Setup: the source voxel, the layer range `[ka, kb]` (a few comparisons), two divisions
//!   by s_w for the slab range, the candidate slabs `non-empty slabs & range` (one AND). A
//!   beam at the far plane (k₀ > D), one whose layers are all outside the grid, or one whose
//!   slab range holds no occupied block stops here, with no other division.
//! * The whole remaining frustum: its rectangle over all of `[ka, kb]` (the same corner
//!   argument; four multiply-adds and at most four `i64` divisions — none for a bound outside
//!   the grid), tested against the shadow along w: one AND per occupied u-row of the
//!   rectangle. Beams that pass beside everything stop here.
//! * Each candidate slab, nearest first: two ANDs with its projections against the whole
//!   rectangle (most slabs stop here, with no division); then the slab's own u-bounds (≤ 2
//!   divisions) and AND, v-bounds (≤ 2) and AND, and one AND per occupied row of the slab's
//!   rectangle. Empty slabs are never visited (bit iteration). The walk stops at the first
//!   occupied block (`false`), or as soon as the beam has left the grid sideways for good.
//! * Worst case: 6 + 4·B divisions and B·(B + 3) ANDs; typical beams far from the source are
//!   1–2 blocks wide, so a slab is a few ANDs after its divisions. Measured (ad hoc, x86-64
//!   host, release, n = 1024, f = 0, beams from random split descents, k₀ = layer + 1): 15 ns
//!   per call with one small occupied cube, 30–50 ns with a floor and a pillar or 20 random
//!   cubes (B = 8; B = 32: 15–60 ns), against ≈ 55 ns for one [`Beam::split`].
//!
//! # Example
//!
//! ```
//! use cell_core::beam::{frac::U0, Beam, Direction, FarDistance, Source, SourceId};
//! use cell_core::occupancy::Occupancy8;
//!
//! let mut occ = Occupancy8::new(64, 64);
//! occ.mark_span(40, 10, 50, 60); // one dexel of column (40, 10)
//! let source = Source::at_voxel(SourceId(0), [10, 10, 10]).unwrap();
//! let far = FarDistance::<U0>::new(63).unwrap();
//! // The +z initial beam reaches every voxel above the source: not empty.
//! let up = Beam::initial(&source, Direction::PosZ, far);
//! assert!(!occ.frustum_empty(&up, &source, far, 1));
//! // The −z beam only sees z < 10, where nothing is occupied.
//! let down = Beam::initial(&source, Direction::NegZ, far);
//! assert!(occ.frustum_empty(&down, &source, far, 1));
//! ```

use core::fmt::Debug;
use core::hash::Hash;

use crate::beam::{Beam, FarDistance, FracBits, Layer, Source, MAX_FAR, SOURCE_FRAC_BITS};
use crate::dexel::Dexel;
use crate::units::MAX_N;

const G: u32 = SOURCE_FRAC_BITS;

// Bit budget (see module doc): |b + 2^(g−1)|·N + 2^g·N·D < 2^63 for every N < 2^31, D ≤ MAX_FAR …
const _: () = assert!(
    (i32::MAX as i128) * (i32::MAX as i128 + 1 + (1i128 << (G - 1)) + ((1i128 << G) * MAX_FAR as i128))
        <= i64::MAX as i128
);
// … and the divisor 2^g·N·s and the edge 2^g·N·extent for extents ≤ MAX_N.
const _: () = assert!((1i128 << G) * (i32::MAX as i128) * (MAX_N as i128) < (1i128 << 51));

mod sealed {
    pub trait Sealed {}
    impl Sealed for u8 {}
    impl Sealed for u16 {}
    impl Sealed for u32 {}
}

/// The word of one row of blocks (a bit mask over one transverse axis): `u8`, `u16` or `u32`.
/// B must be at most its bits; the smallest word that fits B gives the smallest summary.
pub trait BlockRow: sealed::Sealed + Copy + Debug + Default + Eq + Hash + Send + Sync + 'static {
    /// Bits in the word.
    const BITS: usize;
    /// The empty row.
    const ZERO: Self;
    /// The low `BITS` bits of `m`.
    fn from_u32(m: u32) -> Self;
    /// The row as a `u32` mask.
    fn to_u32(self) -> u32;
}

macro_rules! block_row {
    ($($t:ty),*) => {$(
        impl BlockRow for $t {
            const BITS: usize = <$t>::BITS as usize;
            const ZERO: Self = 0;
            #[inline]
            fn from_u32(m: u32) -> Self {
                m as $t
            }
            #[inline]
            fn to_u32(self) -> u32 {
                self as u32
            }
        }
    )*};
}
block_row!(u8, u16, u32);

/// 8 blocks per axis in `u8` rows (232 bytes).
pub type Occupancy8 = OccupancySummary<8, u8>;
/// 16 blocks per axis in `u16` rows (1 348 bytes).
pub type Occupancy16 = OccupancySummary<16, u16>;
/// 32 blocks per axis in `u32` rows (9 384 bytes).
pub type Occupancy32 = OccupancySummary<32, u32>;

/// Bits `lo ..= hi` of a `u32` (0 ≤ lo ≤ hi ≤ 31).
#[inline]
const fn range_mask(lo: u32, hi: u32) -> u32 {
    (u32::MAX >> (31 - hi)) & (u32::MAX << lo)
}

/// Which blocks of a grid of B³ blocks (B per axis, block side s = ⌈extent / B⌉) hold an
/// occupied voxel, laid out for [`OccupancySummary::frustum_empty`] (see the module doc).
/// Fixed size, `Copy`, no heap: [`OccupancySummary::BYTES`] bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct OccupancySummary<const B: usize, R: BlockRow = u32> {
    /// `xy[bx][by]`: bit bz — the rows of principal axes x and y.
    xy: [[R; B]; B],
    /// `zx[bz][bx]`: bit by — the rows of principal axis z.
    zx: [[R; B]; B],
    /// `proj_u[w][j]`: bit i if u-block i of slab j (principal axis w) holds an occupied block.
    proj_u: [[R; B]; 3],
    /// `proj_v[w][j]`: bit i if v-block i of slab j holds an occupied block.
    proj_v: [[R; B]; 3],
    /// `slabs[w]`: bit j if slab j along axis w holds an occupied block.
    slabs: [R; 3],
    /// `shadow[w][i]`: the blocks' projection along w — bit l if some slab has an occupied
    /// block at (u-block i, v-block l).
    shadow: [[R; B]; 3],
    /// Grid extent per axis: (n, n, depth).
    extent: [u32; 3],
    /// Block side per axis, ⌈extent / B⌉.
    side: [u32; 3],
    /// Index of the last block per axis, (extent − 1) / side < B.
    last: [u8; 3],
}

impl<const B: usize, R: BlockRow> OccupancySummary<B, R> {
    /// Its size in bytes (for the per-cell memory report).
    pub const BYTES: usize = core::mem::size_of::<Self>();

    const VALID_B: () = assert!(B >= 1 && B <= R::BITS, "need 1 <= B <= bits of the row type");

    /// The summary of an n × n × `depth` grid with nothing occupied.
    ///
    /// # Panics
    ///
    /// Unless 1 ≤ n, depth ≤ [`MAX_N`] (the bit budget).
    pub const fn new(n: u32, depth: u32) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::VALID_B;
        assert!(n >= 1 && n <= MAX_N && depth >= 1 && depth <= MAX_N, "grid extent out of 1..=MAX_N");
        let b = B as u32;
        let extent = [n, n, depth];
        let side = [n.div_ceil(b), n.div_ceil(b), depth.div_ceil(b)];
        // (extent − 1) / ⌈extent / B⌉ ≤ B − 1 ≤ 31.
        let last = [((n - 1) / side[0]) as u8, ((n - 1) / side[1]) as u8, ((depth - 1) / side[2]) as u8];
        OccupancySummary {
            xy: [[R::ZERO; B]; B],
            zx: [[R::ZERO; B]; B],
            proj_u: [[R::ZERO; B]; 3],
            proj_v: [[R::ZERO; B]; 3],
            slabs: [R::ZERO; 3],
            shadow: [[R::ZERO; B]; 3],
            extent,
            side,
            last,
        }
    }

    /// The grid extent (x, y, z): (n, n, depth).
    pub const fn extent(&self) -> [u32; 3] {
        self.extent
    }

    /// The block side per axis, ⌈extent / B⌉ voxels.
    pub const fn side(&self) -> [u32; 3] {
        self.side
    }

    /// Blocks per axis actually used: ⌈extent / side⌉ ≤ B.
    pub const fn blocks(&self) -> [usize; 3] {
        [self.last[0] as usize + 1, self.last[1] as usize + 1, self.last[2] as usize + 1]
    }

    /// Mark the voxels `z_lo ..= z_hi` of column (x, y) occupied (a dexel). The span is cut to
    /// the grid; a column outside the grid or an empty span marks nothing.
    pub fn mark_span(&mut self, x: u32, y: u32, z_lo: u32, z_hi: u32) {
        let [n, _, depth] = self.extent;
        if x >= n || y >= n || z_lo > z_hi || z_lo >= depth {
            return;
        }
        let z_hi = z_hi.min(depth - 1);
        let (bx, by) = ((x / self.side[0]) as usize, (y / self.side[1]) as usize);
        let (bz_lo, bz_hi) = (z_lo / self.side[2], z_hi / self.side[2]);
        let zm = range_mask(bz_lo, bz_hi);
        let (xb, yb) = (1u32 << bx, 1u32 << by);
        let or = |r: &mut R, m: u32| *r = R::from_u32(r.to_u32() | m);
        or(&mut self.xy[bx][by], zm);
        // Principal x: slab bx, rows over y, bits over z.
        or(&mut self.proj_u[0][bx], yb);
        or(&mut self.proj_v[0][bx], zm);
        // Principal y: slab by, rows over x, bits over z.
        or(&mut self.proj_u[1][by], xb);
        or(&mut self.proj_v[1][by], zm);
        or(&mut self.slabs[0], xb);
        or(&mut self.slabs[1], yb);
        or(&mut self.slabs[2], zm);
        or(&mut self.shadow[0][by], zm);
        or(&mut self.shadow[1][bx], zm);
        or(&mut self.shadow[2][bx], yb);
        // Principal z: slab bz, rows over x, bits over y.
        for bz in bz_lo as usize..=bz_hi as usize {
            or(&mut self.zx[bz][bx], yb);
            or(&mut self.proj_u[2][bz], xb);
            or(&mut self.proj_v[2][bz], yb);
        }
    }

    /// Mark every dexel of column (x, y).
    pub fn mark_column(&mut self, x: u32, y: u32, dexels: &[Dexel]) {
        for d in dexels {
            self.mark_span(x, y, d.span.lo as u32, d.span.hi as u32);
        }
    }

    /// Add the occupied blocks of `other` (the OR-reduction of the cells' summaries). Returns
    /// `false`, changing nothing, if the two are for different grids.
    pub fn union(&mut self, other: &Self) -> bool {
        if self.extent != other.extent {
            return false;
        }
        let or = |a: &mut R, b: R| *a = R::from_u32(a.to_u32() | b.to_u32());
        for (a, b) in self.xy.iter_mut().flatten().zip(other.xy.iter().flatten()) {
            or(a, *b);
        }
        for (a, b) in self.zx.iter_mut().flatten().zip(other.zx.iter().flatten()) {
            or(a, *b);
        }
        for (a, b) in self.proj_u.iter_mut().flatten().zip(other.proj_u.iter().flatten()) {
            or(a, *b);
        }
        for (a, b) in self.proj_v.iter_mut().flatten().zip(other.proj_v.iter().flatten()) {
            or(a, *b);
        }
        for (a, b) in self.shadow.iter_mut().flatten().zip(other.shadow.iter().flatten()) {
            or(a, *b);
        }
        for (a, b) in self.slabs.iter_mut().zip(other.slabs.iter()) {
            or(a, *b);
        }
        true
    }

    /// Whether no voxel is occupied.
    pub fn is_empty(&self) -> bool {
        self.slabs[0].to_u32() == 0
    }

    /// Whether block `b` = (bx, by, bz) holds an occupied voxel (`false` outside the blocks).
    pub fn occupied_block(&self, b: [usize; 3]) -> bool {
        let [bx, by, bz] = b;
        bx < B && by < B && bz < B && (self.xy[bx][by].to_u32() >> bz) & 1 != 0
    }

    /// The row of (slab j, u-block i) for principal axis w: a mask over the v-blocks.
    #[inline]
    fn row(&self, w: usize, j: usize, i: usize) -> u32 {
        match w {
            0 => self.xy[j][i],
            1 => self.xy[i][j],
            _ => self.zx[j][i],
        }
        .to_u32()
    }

    /// Whether no ray of `beam` occupies an occupied voxel inside the grid at any layer
    /// k₀ ≤ k ≤ D: then the beam's rays all leave the grid unlit and it can be dropped.
    ///
    /// **Sound**: never `true` if some ray does (see the module doc for the argument); exact
    /// when blocks are single voxels; otherwise as exact as the blocks and the per-slab hull
    /// allow. `false` (the safe answer) for a beam of another source than `source` or with
    /// limits outside ±D, and from k₀ = 0 on a face whose layer 1 is the source voxel's slab
    /// (rays from the light: the cells ask from the layer after a beam's, ≥ 1). k₀ > D: `true`.
    /// Cost: see the module doc.
    pub fn frustum_empty<F: FracBits>(&self, beam: &Beam<F>, source: &Source, far: FarDistance<F>, k0: u32) -> bool {
        let dir = beam.direction();
        let w = dir.principal().index();
        let slabs = self.slabs[w].to_u32();
        if slabs == 0 {
            return true;
        }
        if beam.source() != source.id {
            return false;
        }
        let n = far.scaled();
        let (u, v) = (beam.u(), beam.v());
        let lims = [u.lo(), u.hi(), v.lo(), v.hi()].map(|l| l.to_bits() as i64);
        if lims.iter().any(|&a| a < -n || a > n) {
            return false;
        }
        // Layers whose principal coordinate w_s + σ·k is inside the grid, cut to [k0, D]. From
        // the light, w_s is the slab behind layer 1 ([`Source::slab`]); when that is not the
        // source voxel (which holds layer 0), a walk from layer 0 is not offered: `false`.
        let ws = source.slab(dir, Layer(1)) - dir.sign() as i64;
        if k0 == 0 && ws != source.voxel()[w] as i64 {
            return false;
        }
        // `Source::reach` with the lead read once (layers here are 0 ..= D).
        let lead = source.lead(dir);
        let reach = |k: i64| (16 * k - lead).max(0);
        debug_assert_eq!(reach(k0 as i64), source.reach(dir, Layer(k0)));
        let ew = self.extent[w] as i64;
        let plus = dir.sign() > 0;
        let (k_in, k_out) = if plus { (-ws, ew - 1 - ws) } else { (ws - (ew - 1), ws) };
        let ka = k_in.max(k0 as i64);
        let kb = k_out.min(far.get() as i64);
        if ka > kb {
            return true;
        }
        let sw = self.side[w] as i64;
        let at = |k: i64| if plus { ws + k } else { ws - k };
        // Both coordinates are in 0 ..= ew − 1, so both slabs are in 0 ..= last.
        let (ja, jb) = ((at(ka) / sw) as u32, (at(kb) / sw) as u32);
        let mut cand = slabs & range_mask(ja.min(jb), ja.max(jb));
        if cand == 0 {
            return true;
        }
        let (ua, va) = dir.transverse();
        let (ua, va) = (ua.index(), va.index());
        let su =
            Side::new(source.pos[ua].to_bits(), lims[0], lims[1], n, self.side[ua], self.extent[ua], self.last[ua]);
        let sv =
            Side::new(source.pos[va].to_bits(), lims[2], lims[3], n, self.side[va], self.extent[va], self.last[va]);
        // The whole remaining frustum against the blocks' shadow along w: most beams that miss
        // everything stop here, after four divisions.
        let (ta, tb) = (reach(ka), reach(kb));
        let (Cover::Blocks(all_u), Cover::Blocks(all_v)) = (su.cover(ta, tb), sv.cover(ta, tb)) else {
            return true;
        };
        let mut rows = all_u & self.slabs[ua].to_u32();
        loop {
            if rows == 0 {
                return true;
            }
            let i = rows.trailing_zeros() as usize;
            rows &= rows - 1;
            if self.shadow[w][i].to_u32() & all_v != 0 {
                break;
            }
        }
        // Slabs from the far end back (descending j for σ = +1, ascending for σ = −1): the
        // answer is whether any slab holds a block the rays meet, whatever the order, and the
        // frustum is widest far away, where a block is met soonest (Cornell through its camera
        // at n = 64: a quarter fewer instructions in this test than from the near end). The
        // walk ends early when the rays are outside the grid in a slab and every nearer one.
        while cand != 0 {
            let j = if plus { 31 - cand.leading_zeros() } else { cand.trailing_zeros() };
            cand &= !(1u32 << j);
            let j = j as usize;
            // Within the whole frustum's rectangle? (No division.)
            if self.proj_u[w][j].to_u32() & all_u == 0 || self.proj_v[w][j].to_u32() & all_v == 0 {
                continue;
            }
            let (w_lo, w_hi) = (j as i64 * sw, (j as i64 + 1) * sw - 1);
            let (k1, k2) = if plus { (w_lo - ws, w_hi - ws) } else { (ws - w_hi, ws - w_lo) };
            let (t1, t2) = (reach(k1.max(ka)), reach(k2.min(kb)));
            let rows = match su.cover(t1, t2) {
                Cover::Blocks(m) => m & self.proj_u[w][j].to_u32(),
                Cover::Miss => continue,
                Cover::Gone => return true,
            };
            if rows == 0 {
                continue;
            }
            let cols = match sv.cover(t1, t2) {
                Cover::Blocks(m) => m,
                Cover::Miss => continue,
                Cover::Gone => return true,
            };
            if cols & self.proj_v[w][j].to_u32() == 0 {
                continue;
            }
            let mut rows = rows;
            while rows != 0 {
                let i = rows.trailing_zeros() as usize;
                rows &= rows - 1;
                if self.row(w, j, i) & cols != 0 {
                    return false;
                }
            }
        }
        true
    }
}

/// The empty-frustum test as the lighting cell asks it ([`crate::light::LightEnv::frustum`]):
/// object-safe for one fraction type, so that a host can choose the summary's resolution at
/// run time ([`Occupancy8`], [`Occupancy16`], [`Occupancy32`]: finer blocks drop more beams
/// and cost more memory per cell) while the cell's code stays one function.
///
/// Not `Debug` itself: a supertrait would put the summary's `Debug::fmt` in every vtable, and
/// with it `core::fmt` in a firmware image that never formats (2 KB of flash); `dyn
/// FrustumTest` has its own short `Debug` (its size), for [`crate::light::LightEnv`]'s.
pub trait FrustumTest<F: FracBits>: Sync {
    /// [`OccupancySummary::frustum_empty`].
    fn frustum_empty(&self, beam: &Beam<F>, source: &Source, far: FarDistance<F>, k0: u32) -> bool;
    /// The summary's size in bytes (what each cell holds).
    fn bytes(&self) -> usize;
}

impl<F: FracBits> Debug for dyn FrustumTest<F> + '_ {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("FrustumTest").field("bytes", &self.bytes()).finish()
    }
}

impl<const B: usize, R: BlockRow, F: FracBits> FrustumTest<F> for OccupancySummary<B, R> {
    fn frustum_empty(&self, beam: &Beam<F>, source: &Source, far: FarDistance<F>, k0: u32) -> bool {
        OccupancySummary::frustum_empty(self, beam, source, far, k0)
    }

    fn bytes(&self) -> usize {
        Self::BYTES
    }
}

/// Where a beam's rays are on one transverse axis over the layers of a slab.
enum Cover {
    /// Inside the grid, within these blocks (a mask).
    Blocks(u32),
    /// Outside the grid in this slab.
    Miss,
    /// Outside the grid in this slab and in every nearer one (the bound comes no closer to the
    /// grid toward the source): with the farther slabs already walked, nothing is left.
    Gone,
}

/// One transverse axis of a frustum: its two extreme rays, in the scaled integers of the module
/// doc (numerator `c0 + step·T`, block divisor `m`, grid edge `top`).
struct Side {
    c0: i64,
    step_lo: i64,
    step_hi: i64,
    m: i64,
    top: i64,
    last: i64,
}

impl Side {
    /// `b`: source coordinate (2^−g lattice), `a_lo`, `a_hi`: the extreme rays (2^−f lattice,
    /// |a| ≤ N), `n`: N = D·2^f; `side`, `extent`, `last`: the axis's blocks.
    fn new(b: i32, a_lo: i64, a_hi: i64, n: i64, side: u32, extent: u32, last: u8) -> Self {
        let unit = n << G; // 2^g·N < 2^35
        Side {
            c0: (b as i64 + (1 << (G - 1))) * n,
            step_lo: a_lo,
            step_hi: a_hi,
            m: unit * side as i64,
            top: unit * extent as i64,
            last: last as i64,
        }
    }

    /// The blocks the rays occupy over the layers from `k1` to `k2` (0 ≤ k1 ≤ k2 ≤ D), given by
    /// their reaches `T_k1 ≤ T_k2` ([`Source::reach`]), cut to the grid.
    #[inline]
    fn cover(&self, t1: i64, t2: i64) -> Cover {
        // The lowest voxel: ray a_lo at k1 if it rises (a_lo ≥ 0), else at k2; the highest:
        // ray a_hi at k2 if it rises, else at k1 (monotone in T, so in k, with the sign of a).
        let lo_up = self.step_lo >= 0;
        let hi_up = self.step_hi >= 0;
        let num_lo = self.c0 + self.step_lo * if lo_up { t1 } else { t2 };
        let num_hi = self.c0 + self.step_hi * if hi_up { t2 } else { t1 };
        if num_lo >= self.top {
            // Every voxel ≥ extent; in nearer slabs too if the low bound never increases with
            // T (nearer slabs have smaller reaches).
            return if self.step_lo <= 0 { Cover::Gone } else { Cover::Miss };
        }
        if num_hi < 0 {
            // Every voxel < 0; in nearer slabs too if the high bound never decreases with T.
            return if self.step_hi >= 0 { Cover::Gone } else { Cover::Miss };
        }
        // Here num_lo < top and 0 ≤ num_hi; num_lo ≤ num_hi's extreme, so lo ≤ hi below.
        // Both quotients are of non-negative numerators by m > 0: unsigned divisions.
        let lo = if num_lo < 0 { 0 } else { (num_lo as u64 / self.m as u64) as i64 };
        let hi = if num_hi >= self.top { self.last } else { (num_hi as u64 / self.m as u64) as i64 };
        Cover::Blocks(range_mask(lo as u32, hi as u32))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::beam::{
        frac, trace_ray_voxel, Direction, FarOffset, Layer, Origin, RayRange, SourceCoord, SourceId, Transverse,
    };
    use proptest::prelude::*;
    use std::vec::Vec;

    /// A brute-force voxel grid.
    struct Scene {
        n: u32,
        depth: u32,
        occ: Vec<bool>,
        spans: Vec<(u32, u32, u32, u32)>,
    }

    impl Scene {
        fn new(n: u32, depth: u32) -> Self {
            Scene { n, depth, occ: std::vec![false; (n * n * depth) as usize], spans: Vec::new() }
        }

        fn mark(&mut self, x: u32, y: u32, z_lo: u32, z_hi: u32) {
            for z in z_lo..=z_hi.min(self.depth - 1) {
                self.occ[((x * self.n + y) * self.depth + z) as usize] = true;
            }
            self.spans.push((x, y, z_lo, z_hi));
        }

        fn inside(&self, p: [i64; 3]) -> bool {
            let e = [self.n as i64, self.n as i64, self.depth as i64];
            (0..3).all(|a| 0 <= p[a] && p[a] < e[a])
        }

        fn occupied(&self, p: [i64; 3]) -> bool {
            self.inside(p) && self.occ[((p[0] * self.n as i64 + p[1]) * self.depth as i64 + p[2]) as usize]
        }

        fn summary<const B: usize, R: BlockRow>(&self) -> OccupancySummary<B, R> {
            let mut s = OccupancySummary::<B, R>::new(self.n, self.depth);
            for &(x, y, lo, hi) in &self.spans {
                s.mark_span(x, y, lo, hi);
            }
            s
        }
    }

    /// Every voxel (inside the grid) that a lattice ray of `beam` occupies at a layer
    /// k0 ..= D, from `trace_ray_voxel` and `Direction::voxel`: whether `hit` says yes for one.
    fn oracle<F: FracBits>(
        beam: &Beam<F>,
        source: &Source,
        far: FarDistance<F>,
        k0: u32,
        mut hit: impl FnMut([i64; 3]) -> bool,
    ) -> bool {
        let dir = beam.direction();
        let (u, v) = (beam.u(), beam.v());
        for a in u.lo().to_bits()..=u.hi().to_bits() {
            for b in v.lo().to_bits()..=v.hi().to_bits() {
                for k in k0..=far.get() {
                    let (tu, tv) = trace_ray_voxel(
                        source,
                        dir,
                        FarOffset::<F>::from_bits(a),
                        FarOffset::<F>::from_bits(b),
                        far,
                        Layer(k),
                    );
                    let p = dir.voxel(source, Layer(k), Transverse { u: tu as i32, v: tv as i32 });
                    if hit(p) {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// A random case, from raw numbers (shared by the proptests and the seeded statistics).
    #[derive(Clone, Debug)]
    struct Case {
        n: u32,
        depth: u32,
        spans: Vec<(u32, u32, u32, u32)>,
        src: [u32; 3],
        src_out: bool,
        dir: u8,
        far_delta: i32,
        rect: [u32; 4],
        wide: bool,
        k0: u32,
    }

    struct Built<F: FracBits> {
        scene: Scene,
        source: Source,
        far: FarDistance<F>,
        beam: Beam<F>,
        k0: u32,
    }

    impl Case {
        fn build<F: FracBits>(&self) -> Built<F> {
            let (n, depth) = (self.n, self.depth);
            let mut scene = Scene::new(n, depth);
            for &(x, y, z, len) in &self.spans {
                scene.mark(x % n, y % n, z % depth, z % depth + len);
            }
            // Source voxels in the grid (0 ..= extent − 1), or from −2 to extent + 1 on the
            // 1/16 lattice when `src_out`.
            let e = [n, n, depth];
            let (pad, shift) = if self.src_out { (4, 40) } else { (0, 8) };
            let pos: [SourceCoord; 3] =
                core::array::from_fn(|a| SourceCoord::from_bits((self.src[a] % ((e[a] + pad) * 16)) as i32 - shift));
            // The thesis's rays, or rays from the light (a spare bit of the position's draw).
            let origin = if self.src[1] >> 31 == 1 { Origin::Light } else { Origin::SourceVoxel };
            let source = Source::new(SourceId(3), pos).with_origin(origin);
            let d = (n.max(depth) as i32 - 1 + self.far_delta).max(1) as u32;
            let far = FarDistance::<F>::new(d).unwrap();
            let nn = far.scaled() as u32;
            let range = |lo_raw: u32, w_raw: u32| {
                let lo = lo_raw % (2 * nn + 1);
                let width = if self.wide { w_raw % (2 * nn + 1) } else { w_raw % (nn / 2 + 4) };
                let hi = (lo + width).min(2 * nn);
                RayRange::new(
                    FarOffset::<F>::from_bits(lo as i32 - nn as i32),
                    FarOffset::<F>::from_bits(hi as i32 - nn as i32),
                )
                .unwrap()
            };
            let dir = Direction::from_index(self.dir % 6).unwrap();
            let k0 = if self.k0 & 1 == 0 { (self.k0 >> 1) % 4 } else { (self.k0 >> 1) % (d + 3) };
            let (u, v) = (range(self.rect[0], self.rect[1]), range(self.rect[2], self.rect[3]));
            let beam = Beam::new(source.id, dir, Layer(k0.min(d)), u, v, far).unwrap();
            Built { scene, source, far, beam, k0 }
        }
    }

    fn case_strategy() -> impl Strategy<Value = Case> {
        (
            (4u32..=20, any::<bool>(), 4u32..=20),
            proptest::collection::vec((0u32..64, 0u32..64, 0u32..64, 0u32..20), 0..64),
            (any::<[u32; 3]>(), proptest::bool::weighted(0.1), 0u8..6, -3i32..=8),
            (any::<[u32; 4]>(), proptest::bool::weighted(0.15), any::<u32>()),
        )
            .prop_map(|((n, same, d), spans, (src, src_out, dir, far_delta), (rect, wide, k0))| Case {
                n,
                depth: if same { n } else { d },
                spans,
                src,
                src_out,
                dir,
                far_delta,
                rect,
                wide,
                k0,
            })
    }

    /// The oracle's verdict, and every summary's: sound for all, exact for one-voxel blocks.
    fn check<F: FracBits>(case: &Case, descent: Option<&[u8]>) {
        let Built { scene, source, far, mut beam, mut k0 } = case.build::<F>();
        if let Some(choices) = descent {
            // A beam the lighting phase makes: split from the initial beam, one random sub-beam
            // per layer; its frustum from the next layer (or from its own).
            beam = Beam::initial(&source, beam.direction(), far);
            let mut at = beam.direction().transverse_of(source.voxel());
            for &c in choices {
                let Ok(subs) = beam.split(&source, far, at) else { break };
                // Only sub-beams still in the grid (the cell drops the others).
                let dir = beam.direction();
                let inside: Vec<_> = subs
                    .iter()
                    .filter(|sb| scene.inside(dir.voxel(&source, sb.beam.layer(), at.offset(sb.offset))))
                    .collect();
                let Some(&&sb) = inside.get(c as usize % inside.len().max(1)) else { break };
                at = at.offset(sb.offset);
                beam = sb.beam;
            }
            k0 = beam.layer().0 + u32::from(k0 % 2 == 0);
        }
        let hit = oracle(&beam, &source, far, k0, |p| scene.occupied(p));
        let mut answers = Vec::new();
        macro_rules! each {
            ($(($b:literal, $r:ty)),*) => {$(
                let e = scene.summary::<$b, $r>().frustum_empty(&beam, &source, far, k0);
                answers.push(($b, e));
            )*};
        }
        each!((1, u8), (2, u8), (3, u32), (4, u8), (5, u8), (7, u16), (8, u8), (8, u32), (16, u16), (32, u32));
        // From layer 0 of a face whose layer 1 is the source voxel's slab (rays from the
        // light), the test answers `false` (documented): exactness holds from layer 1.
        let dir = beam.direction();
        let w = dir.principal().index();
        let shifted_zero = k0 == 0 && source.slab(dir, Layer(1)) == source.voxel()[w] as i64;
        for &(b, empty) in &answers {
            assert!(!(hit && empty), "B = {b}: said empty but a ray meets an occupied voxel: {case:?}");
            if b >= case.n.max(case.depth) && !shifted_zero {
                assert_eq!(empty, !hit, "B = {b} (one voxel per block) must be exact: {case:?}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2048, ..ProptestConfig::default() })]

        /// Soundness against the per-ray, per-layer oracle for f = 0 and f = 2, every B; exact
        /// equality when blocks are voxels.
        #[test]
        fn frustum_empty_is_sound_and_exact_for_voxel_blocks(case in case_strategy(), f2 in any::<bool>()) {
            if f2 { check::<frac::U2>(&case, None) } else { check::<frac::U0>(&case, None) }
        }

        /// The same for the beams the lighting phase actually makes: sub-beams of a random
        /// descent of splits from an initial beam, their frustum from the next layer.
        #[test]
        fn frustum_empty_is_sound_for_split_beams(
            case in case_strategy(),
            f2 in any::<bool>(),
            choices in proptest::collection::vec(any::<u8>(), 0..24),
        ) {
            if f2 { check::<frac::U2>(&case, Some(&choices)) } else { check::<frac::U0>(&case, Some(&choices)) }
        }

        /// The summary's blocks are exactly those holding an occupied voxel, and the union of
        /// two summaries is the summary of the union.
        #[test]
        fn blocks_match_voxels(case in case_strategy(), other in case_strategy()) {
            let Built { scene, .. } = case.build::<frac::U0>();
            let s = scene.summary::<5, u8>();
            let side = s.side();
            let [bx, by, bz] = s.blocks();
            for i in 0..bx {
                for j in 0..by {
                    for k in 0..bz {
                        let any = (0..side[0]).any(|x| (0..side[1]).any(|y| (0..side[2]).any(|z| {
                            scene.occupied([(i as u32 * side[0] + x) as i64, (j as u32 * side[1] + y) as i64, (k as u32 * side[2] + z) as i64])
                        })));
                        prop_assert_eq!(s.occupied_block([i, j, k]), any);
                    }
                }
            }
            prop_assert_eq!(s.is_empty(), !scene.occ.iter().any(|&o| o));
            let mut o = Scene::new(case.n, case.depth);
            for &(x, y, z, len) in &other.spans {
                o.mark(x % case.n, y % case.n, z % case.depth, z % case.depth + len);
            }
            let mut u = s;
            prop_assert!(u.union(&o.summary::<5, u8>()));
            let mut both = Scene::new(case.n, case.depth);
            both.spans = scene.spans.iter().chain(o.spans.iter()).copied().collect();
            prop_assert_eq!(u, both.summary::<5, u8>());
        }
    }

    /// A tiny deterministic generator for the statistics below (xorshift64*).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u32 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 32) as u32
        }
        fn case(&mut self) -> Case {
            let n = 4 + self.next() % 17;
            let spans = (0..1 + self.next() % 40)
                .map(|_| (self.next() % 64, self.next() % 64, self.next() % 64, self.next() % 16))
                .collect();
            Case {
                n,
                depth: n,
                spans,
                src: [self.next(), self.next(), self.next()],
                src_out: false,
                dir: (self.next() % 6) as u8,
                far_delta: 0,
                rect: [self.next(), self.next(), self.next(), self.next()],
                wide: self.next() % 4 == 0,
                k0: self.next() % 8,
            }
        }
    }

    /// How often the test says "not empty" when nothing is hit: against the voxel oracle (block
    /// granularity + slab hull) and against a block oracle (blocks met by some ray: the hull
    /// alone). The hull may only add, never remove (the block oracle's hits are all `false`).
    #[test]
    fn pessimism_is_bounded() {
        fn run<const B: usize, R: BlockRow>(rng: &mut Rng) -> (u32, u32, u32, u32) {
            let (mut clear, mut said_full, mut block_clear, mut hull_extra) = (0, 0, 0, 0);
            for _ in 0..300 {
                let case = rng.case();
                let Built { scene, source, far, beam, k0 } = case.build::<frac::U0>();
                let (dir, w) = (beam.direction(), beam.direction().principal().index());
                if k0 == 0 && source.slab(dir, Layer(1)) == source.voxel()[w] as i64 {
                    // Answered `false` by design (see `frustum_empty`); soundness is checked above.
                    continue;
                }
                let s = scene.summary::<B, R>();
                let side = s.side();
                let empty = s.frustum_empty(&beam, &source, far, k0);
                let hit = oracle(&beam, &source, far, k0, |p| scene.occupied(p));
                let block_hit = oracle(&beam, &source, far, k0, |p| {
                    scene.inside(p) && s.occupied_block(core::array::from_fn(|a| (p[a] / side[a] as i64) as usize))
                });
                assert!(!(block_hit && empty), "{case:?}");
                if !hit {
                    clear += 1;
                    said_full += u32::from(!empty);
                }
                if !block_hit {
                    block_clear += 1;
                    hull_extra += u32::from(!empty);
                }
            }
            (clear, said_full, block_clear, hull_extra)
        }
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for (b, (clear, said_full, block_clear, hull_extra)) in
            [(4, run::<4, u8>(&mut rng)), (8, run::<8, u8>(&mut rng)), (32, run::<32, u32>(&mut rng))]
        {
            std::println!(
                "B = {b:2}: {clear} clear frusta, {said_full} called non-empty; \
                 {block_clear} block-clear, {hull_extra} of them called non-empty (hull)"
            );
            if b == 32 {
                assert_eq!(said_full, 0, "one voxel per block: exact");
                assert_eq!(hull_extra, 0);
            }
            // The slab hull costs little beyond the block granularity.
            assert!(hull_extra * 5 <= block_clear, "B = {b}: hull too loose: {hull_extra} / {block_clear}");
        }
    }

    fn src(p: [f64; 3]) -> Source {
        Source::new(SourceId(0), p.map(SourceCoord::from_num))
    }

    /// Every B on one beam: sound, and exact for voxel blocks.
    fn agree<F: FracBits>(scene: &Scene, beam: &Beam<F>, source: &Source, far: FarDistance<F>, k0: u32) -> bool {
        let hit = oracle(beam, source, far, k0, |p| scene.occupied(p));
        let answers = [
            scene.summary::<1, u8>().frustum_empty(beam, source, far, k0),
            scene.summary::<4, u8>().frustum_empty(beam, source, far, k0),
            scene.summary::<8, u8>().frustum_empty(beam, source, far, k0),
            scene.summary::<32, u32>().frustum_empty(beam, source, far, k0),
        ];
        assert!(answers.iter().all(|&e| !(hit && e)), "unsound: {answers:?}");
        if scene.n <= 32 && scene.depth <= 32 {
            assert_eq!(answers[3], !hit);
        }
        hit
    }

    #[test]
    fn empty_summary_is_always_empty_and_full_never() {
        let far = FarDistance::<frac::U2>::new(12).unwrap();
        let mut full = Occupancy8::new(13, 9);
        for x in 0..13 {
            for y in 0..13 {
                full.mark_span(x, y, 0, 8);
            }
        }
        let empty = Occupancy8::new(13, 9);
        assert!(empty.is_empty() && !full.is_empty());
        let source = src([6.0, 2.5, 4.0]);
        for dir in Direction::ALL {
            let beam = Beam::initial(&source, dir, far);
            for k0 in 0..=14 {
                assert!(empty.frustum_empty(&beam, &source, far, k0));
                // The source is inside the grid and every layer up to the edge is too.
                let inside = match dir {
                    Direction::PosX => 6 + k0 < 13,
                    Direction::NegX => k0 <= 6,
                    Direction::PosY => 3 + k0 < 13,
                    Direction::NegY => k0 <= 3,
                    Direction::PosZ => 4 + k0 < 9,
                    Direction::NegZ => k0 <= 4,
                } && k0 <= 12;
                assert_eq!(full.frustum_empty(&beam, &source, far, k0), !inside, "{dir:?} k0 = {k0}");
            }
        }
    }

    #[test]
    fn far_plane_wrong_source_and_outside_limits() {
        let mut scene = Scene::new(8, 8);
        for x in 0..8 {
            for y in 0..8 {
                scene.mark(x, y, 0, 7);
            }
        }
        let s = scene.summary::<4, u8>();
        let source = Source::at_voxel(SourceId(1), [4, 4, 4]).unwrap();
        let far = FarDistance::<frac::U0>::new(7).unwrap();
        let beam = Beam::initial(&source, Direction::PosZ, far);
        // k0 > D: no layer left.
        assert!(s.frustum_empty(&beam, &source, far, 8));
        assert!(!agree(&scene, &beam, &source, far, 8));
        assert!(!s.frustum_empty(&beam, &source, far, 3));
        // Another source's beam, or a beam made for a larger D: the safe answer.
        let other = Source::at_voxel(SourceId(2), [4, 4, 4]).unwrap();
        let mut one = Occupancy8::new(8, 8);
        one.mark_span(0, 0, 0, 0);
        assert!(!one.frustum_empty(&beam, &other, far, 0));
        let big = FarDistance::<frac::U0>::new(9).unwrap();
        let wide = Beam::initial(&source, Direction::NegZ, big);
        assert!(!one.frustum_empty(&wide, &source, far, 0));
        // With its own D it is fine: the ray u = v = −9 meets (0, 0, 0) at layer 4.
        assert!(!one.frustum_empty(&wide, &source, big, 0));
        let mut corner = Scene::new(8, 8);
        corner.mark(0, 0, 0, 0);
        assert!(agree(&corner, &wide, &source, big, 0));
    }

    #[test]
    fn sources_on_block_boundaries() {
        // n = 16, B = 4: blocks of 4. Sources exactly on block edges (x = 4j), on the half-voxel
        // just below an edge (rounds up into the next block) and just above it.
        let mut scene = Scene::new(16, 16);
        scene.mark(3, 3, 3, 4);
        scene.mark(12, 8, 11, 12);
        scene.mark(7, 12, 0, 15);
        let far = FarDistance::<frac::U2>::new(15).unwrap();
        let mut hits = 0;
        for c in [3.5, 3.9375, 4.0, 7.5, 8.0, 8.0625, 11.5, 12.0] {
            for (i, p) in [[c, 8.0, 8.0], [8.0, c, 4.0], [4.0, 8.0, c], [c, c, c]].into_iter().enumerate() {
                let source = src(p);
                for dir in Direction::ALL {
                    let n = far.scaled() as i32;
                    for (lo, hi) in [(-n, n), (-n, -n / 2), (0, 0), (n / 3, n), (-3, 5)] {
                        let r = RayRange::new(FarOffset::from_bits(lo), FarOffset::from_bits(hi)).unwrap();
                        let beam = Beam::new(source.id, dir, Layer(0), r, r, far).unwrap();
                        for k0 in [0, 1, 4 + i as u32, 9] {
                            hits += u32::from(agree(&scene, &beam, &source, far, k0));
                        }
                    }
                }
            }
        }
        assert!(hits > 100, "the cases should meet something: {hits}");
    }

    #[test]
    fn blocks_not_dividing_the_grid() {
        // n = 13, B = 4: side 4, blocks 0..=3, the last one is the single voxel 12.
        let s = Occupancy8::new(13, 13);
        assert_eq!((s.side(), s.blocks()), ([2, 2, 2], [7, 7, 7]));
        let t = OccupancySummary::<4, u8>::new(13, 5);
        assert_eq!((t.side(), t.blocks()), ([4, 4, 2], [4, 4, 3]));
        let mut scene = Scene::new(13, 13);
        scene.mark(12, 12, 12, 12);
        scene.mark(0, 6, 2, 3);
        let far = FarDistance::<frac::U0>::new(12).unwrap();
        let mut hits = 0;
        for p in [[6, 6, 6], [12, 12, 0], [11, 11, 11], [0, 0, 12], [8, 12, 12]] {
            let source = Source::at_voxel(SourceId(0), p).unwrap();
            for dir in Direction::ALL {
                for (lo, hi) in [(-12, 12), (0, 12), (5, 7), (-12, -10), (12, 12)] {
                    let r = RayRange::new(FarOffset::from_num(lo), FarOffset::from_num(hi)).unwrap();
                    let beam = Beam::new(source.id, dir, Layer(0), r, r, far).unwrap();
                    for k0 in [0, 1, 3, 6, 12] {
                        hits += u32::from(agree(&scene, &beam, &source, far, k0));
                    }
                }
            }
        }
        assert!(hits > 20, "{hits}");
        // A beam that leaves the grid at x = 13 right beside the partial last block: the cut
        // at the grid edge is exact (no voxel ≥ 13 counts).
        let mut edge = Scene::new(13, 13);
        edge.mark(12, 0, 0, 12);
        let source = Source::at_voxel(SourceId(0), [12, 6, 6]).unwrap();
        let r = RayRange::new(FarOffset::from_num(6), FarOffset::from_num(12)).unwrap();
        let all = RayRange::full(far);
        let beam = Beam::new(source.id, Direction::PosY, Layer(0), r, all, far).unwrap();
        // Rays u ≥ 6 reach x ≥ 13 at some layer; the ones with small u stay at x = 12 early.
        assert!(!agree(&edge, &beam, &source, far, 0));
    }

    #[test]
    fn one_voxel_in_a_1024_grid() {
        let n = 1024;
        let far = FarDistance::<frac::U0>::new(n - 1).unwrap();
        let mut scene = Scene::new(n, n);
        scene.mark(600, 512, 900, 900);
        let source = Source::at_voxel(SourceId(0), [512, 512, 0]).unwrap();
        let rect = |u: (i32, i32), v: (i32, i32), k: u32| {
            let r = |(a, b): (i32, i32)| RayRange::new(FarOffset::from_num(a), FarOffset::from_num(b)).unwrap();
            Beam::new(source.id, Direction::PosZ, Layer(k), r(u), r(v), far).unwrap()
        };
        // The ray toward (600, 512, 900): u = 88·1023/900 ≈ 100.03.
        let toward = rect((95, 105), (-2, 2), 0);
        let away = rect((-105, -95), (-2, 2), 0);
        let above = rect((95, 105), (40, 44), 0);
        let s32 = scene.summary::<32, u32>();
        let s8 = scene.summary::<8, u8>();
        let oracle_hit = |b: &Beam<frac::U0>, k0| oracle(b, &source, far, k0, |p| scene.occupied(p));
        for (beam, k0, hit, empty32) in [
            (toward, 0, true, false),
            (toward, 850, true, false),
            (away, 0, false, true),
            (above, 0, false, true),
            // k0 = 901 is past the voxel but still in its block (z 896..=927): not known empty.
            (toward, 901, false, false),
            // k0 = 928: the next slab of blocks: empty.
            (toward, 928, false, true),
        ] {
            assert_eq!(oracle_hit(&beam, k0), hit, "{beam:?} k0 = {k0}");
            assert_eq!(s32.frustum_empty(&beam, &source, far, k0), empty32, "{beam:?} k0 = {k0}");
            assert!(!(hit && s8.frustum_empty(&beam, &source, far, k0)));
        }
        // B = 8: blocks of 128; the voxel's block (x 512..=639, y 512..=639, z 896..=1023) is
        // in `away`'s slab range but not in its rectangle; `above` (v ≈ 40..44 → y ≤ 555 at
        // z = 1023) is in it.
        assert!(s8.frustum_empty(&away, &source, far, 0));
        assert!(!s8.frustum_empty(&above, &source, far, 0));
    }

    #[test]
    fn one_block_and_thirty_two() {
        // B = 1: one block, the whole grid: non-empty iff the beam has a layer in the grid.
        let mut scene = Scene::new(6, 6);
        scene.mark(0, 0, 0, 0);
        let s = scene.summary::<1, u8>();
        assert_eq!((s.side(), s.blocks()), ([6, 6, 6], [1, 1, 1]));
        let far = FarDistance::<frac::U0>::new(5).unwrap();
        let source = Source::at_voxel(SourceId(0), [5, 5, 5]).unwrap();
        for dir in Direction::ALL {
            let beam = Beam::initial(&source, dir, far);
            let empty = s.frustum_empty(&beam, &source, far, 1);
            assert_eq!(empty, dir.sign() > 0, "{dir:?}");
            agree(&scene, &beam, &source, far, 1);
        }
        // B = 32 on a 32-voxel grid: single voxels, exact (checked by `agree`).
        let mut scene = Scene::new(32, 32);
        scene.mark(31, 0, 31, 31);
        scene.mark(16, 16, 0, 3);
        let far = FarDistance::<frac::U0>::new(31).unwrap();
        assert_eq!(scene.summary::<32, u32>().side(), [1, 1, 1]);
        let source = Source::at_voxel(SourceId(0), [16, 16, 16]).unwrap();
        let mut hits = 0;
        for dir in Direction::ALL {
            for (lo, hi) in [(-31, 31), (15, 15), (14, 16), (-16, -14), (0, 0)] {
                let r = RayRange::new(FarOffset::from_num(lo), FarOffset::from_num(hi)).unwrap();
                let beam = Beam::new(source.id, dir, Layer(0), r, r, far).unwrap();
                for k0 in [0, 5, 15, 16, 31] {
                    hits += u32::from(agree(&scene, &beam, &source, far, k0));
                }
            }
        }
        assert!(hits > 5, "{hits}");
    }

    #[test]
    fn mark_column_marks_each_dexel() {
        use crate::dexel::Dexel;
        use crate::normal::NormalCode;
        use crate::units::Span;
        let d = |lo, hi| Dexel {
            span: Span { lo, hi },
            facet: 0,
            material: 0,
            normal: NormalCode(0),
            plane: Default::default(),
        };
        let mut s = OccupancySummary::<4, u8>::new(16, 32);
        s.mark_column(5, 9, &[d(0, 2), d(20, 31)]);
        let mut t = OccupancySummary::<4, u8>::new(16, 32);
        t.mark_span(5, 9, 0, 2);
        t.mark_span(5, 9, 20, 31);
        assert_eq!(s, t);
        let occupied: Vec<[usize; 3]> = (0..4)
            .flat_map(|x| (0..4).flat_map(move |y| (0..4).map(move |z| [x, y, z])))
            .filter(|&b| s.occupied_block(b))
            .collect();
        assert_eq!(occupied, [[1, 2, 0], [1, 2, 2], [1, 2, 3]]);
        // Outside the grid: nothing; a span past the depth: cut.
        s.mark_span(16, 0, 0, 0);
        s.mark_span(0, 0, 32, 40);
        assert_eq!(s, t);
        assert!(!s.union(&OccupancySummary::<4, u8>::new(16, 31)));
    }

    #[test]
    fn sizes() {
        assert_eq!(Occupancy8::BYTES, core::mem::size_of::<Occupancy8>());
        assert_eq!(Occupancy16::BYTES, core::mem::size_of::<Occupancy16>());
        assert_eq!(Occupancy32::BYTES, core::mem::size_of::<Occupancy32>());
        assert_eq!(OccupancySummary::<8>::BYTES, core::mem::size_of::<OccupancySummary<8>>());
        std::println!(
            "Occupancy8 {} B, Occupancy16 {} B, Occupancy32 {} B, OccupancySummary<8> {} B",
            Occupancy8::BYTES,
            Occupancy16::BYTES,
            Occupancy32::BYTES,
            OccupancySummary::<8>::BYTES
        );
        assert_eq!(Occupancy8::BYTES, 232);
    }
}
