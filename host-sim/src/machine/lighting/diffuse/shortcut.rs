//! The host's shortcut to the empty-frustum test's commonest answer (a host speed-up: the
//! cells' answers, so every count, stay the same).
//!
//! Through the Cornell box's camera nearly every beam the skip tests is *not* empty (0.16 %
//! are), and [`cell_core::occupancy::OccupancySummary::frustum_empty`] pays its setup (the
//! source's slab, the layer range, the whole frustum's rectangle) before it finds a block. The
//! test answers "not empty" whenever a lattice ray of the beam lies, at a layer in `[k₀, D]`,
//! in a voxel of an occupied block (its soundness argument, the summary module's doc: that
//! voxel lies in its slab's rectangle, so the block's bit shows; and the summary of the scene
//! whose every voxel of an occupied block is occupied is the same summary, so the proptests'
//! voxel-level soundness covers it). So for the beam's four corner rays the host looks up the
//! last layer at which each lies in an occupied block; when one is ≥ k₀ the answer is "not
//! empty", exactly what the test would have said, and the test is not run. Otherwise the test
//! runs as before.
//!
//! The table ([`Shortcut::new`]) holds, for one source and each of the six directions, that
//! last layer for every lattice ray `(a, b)`, |a|, |b| ≤ N = D·2^f (0: none): at each layer
//! through an occupied block, the rays whose transverse voxels there are in the block form a
//! rectangle of lattice rays, found by inverting the ray's voxel formula
//! (`cell_core::beam::trace_ray_voxel`) exactly. Filling costs one write per (ray, layer in an
//! occupied block); the table, one value per 4 × 4 tile of rays (the least of their last layers: a bound for
//! each), `2·⌈(2N + 1)/4⌉²·6` bytes per source (50 KB at n = 128, 790 KB at 512, f = 0), so that
//! it stays in cache. Past [`MAX_TABLE_BYTES`] there is no table and every beam takes the test.

#[cfg(test)]
use cell_core::beam::{trace_ray_voxel, FarOffset};
use cell_core::beam::{Beam, Direction, FarDistance, FracBits, Layer, Source, SOURCE_FRAC_BITS};
use cell_core::occupancy::FrustumTest;

use super::summary::OccupiedBlocks;

use crate::machine::grid::pieces::par_map;

/// The largest table built (bytes, for one source): above it (large n with fraction bits) the
/// test always runs.
pub const MAX_TABLE_BYTES: usize = 256 << 20;

/// A [`FrustumTest`] that answers "not empty" from the table when it can, and asks `inner`
/// otherwise: the same answers as `inner` (module doc).
pub struct Shortcut<'a, F: FracBits> {
    inner: &'a dyn FrustumTest<F>,
    source: Source,
    far: u32,
    /// N = D·2^f, and the tiles per axis of a direction's table (⌈(2N + 1) / TILE⌉).
    big_n: i64,
    side: usize,
    /// Per direction ([`Direction::index`]), row-major over tiles of TILE × TILE lattice rays
    /// (tile ⌊(a + N) / TILE⌋, ⌊(b + N) / TILE⌋): the least over the tile's rays of the last
    /// layer ≥ 1 at which the ray lies in an occupied block (0: none).
    last: Vec<Vec<u16>>,
}

/// Lattice rays per tile side: the table keeps one value per TILE × TILE rays (the least of
/// their last layers, a bound for each of them), TILE² times smaller than one per ray, so
/// that it stays in cache (Cornell n = 128: 50 KB for the six directions; n = 512: 790 KB).
const TILE: usize = 4;

impl<F: FracBits> std::fmt::Debug for Shortcut<'_, F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Shortcut").field("far", &self.far).field("side", &self.side).finish_non_exhaustive()
    }
}

impl<'a, F: FracBits> Shortcut<'a, F> {
    /// The table for `source` over the summary's occupied `blocks` (the summary behind
    /// `inner`), or `None` when it would exceed [`MAX_TABLE_BYTES`] or the layers do not fit
    /// `u16`.
    pub fn new(
        inner: &'a dyn FrustumTest<F>,
        source: &Source,
        far: FarDistance<F>,
        blocks: &OccupiedBlocks,
    ) -> Option<Self> {
        let big_n = far.get() as i64 * (1i64 << F::U32);
        let side = (2 * big_n + 1) as usize;
        if far.get() > u16::MAX as u32 || side.checked_mul(side)?.checked_mul(12)? > MAX_TABLE_BYTES {
            return None;
        }
        let last = par_map(6, &|d| tiled(&fill(Direction::ALL[d], source, far, big_n, side, blocks), side));
        Some(Shortcut { inner, source: *source, far: far.get(), big_n, side: side.div_ceil(TILE), last })
    }

    /// A layer at or before the last one (≥ 1) at which lattice ray `(a, b)` of direction
    /// `dir` lies in an occupied block: the least of those of its tile's rays; 0 if none or if
    /// the ray is not on the table.
    pub fn last_layer(&self, dir: Direction, a: i64, b: i64) -> u16 {
        let n = self.big_n;
        if a.abs() > n || b.abs() > n {
            return 0;
        }
        let (ta, tb) = ((a + n) as usize / TILE, (b + n) as usize / TILE);
        self.last[dir.index() as usize][ta * self.side + tb]
    }
}

impl<F: FracBits> FrustumTest<F> for Shortcut<'_, F> {
    fn frustum_empty(&self, beam: &Beam<F>, source: &Source, far: FarDistance<F>, k0: u32) -> bool {
        debug_assert!(source.id == self.source.id && source.pos == self.source.pos && far.get() == self.far);
        // Layer 0 is not on the table (the test's own rules for it apply).
        if k0 >= 1 && beam.source() == source.id {
            let (u, v) = (beam.u(), beam.v());
            let (a, b) = ([u.lo(), u.hi()].map(|x| x.to_bits() as i64), [v.lo(), v.hi()].map(|x| x.to_bits() as i64));
            let dir = beam.direction();
            let corners = [(a[0], b[0]), (a[1], b[1]), (a[0], b[1]), (a[1], b[0])];
            if corners.iter().any(|&(a, b)| self.last_layer(dir, a, b) as u32 >= k0) {
                debug_assert!(!self.inner.frustum_empty(beam, source, far, k0), "shortcut unsound: {beam:?} k0 = {k0}");
                return false;
            }
        }
        self.inner.frustum_empty(beam, source, far, k0)
    }

    fn bytes(&self) -> usize {
        self.inner.bytes()
    }
}

/// One direction's table: for every layer k ∈ [1, D] with a nonzero reach through an occupied
/// block, the rectangle of lattice rays whose voxel there is in the block gets k (the largest
/// wins).
fn fill<F: FracBits>(
    dir: Direction,
    source: &Source,
    far: FarDistance<F>,
    big_n: i64,
    side: usize,
    blocks: &OccupiedBlocks,
) -> Vec<u16> {
    let mut last = vec![0u16; side * side];
    let w = dir.principal().index();
    let (ua, va) = dir.transverse();
    let (ua, va) = (ua.index(), va.index());
    let (f, d) = (F::U32, far.get());
    for b in &blocks.list {
        // The block's voxels on each axis, cut to the grid.
        let range = |axis: usize| {
            let lo = b[axis] as u32 * blocks.side[axis];
            (lo as i64, (lo + blocks.side[axis]).min(blocks.extent[axis]) as i64 - 1)
        };
        let ((w_lo, w_hi), (u_lo, u_hi), (v_lo, v_hi)) = (range(w), range(ua), range(va));
        for wc in w_lo..=w_hi {
            let k = source.layer_at(dir, wc);
            if k < 1 || k > d as i64 {
                continue;
            }
            let t = source.reach(dir, Layer(k as u32));
            let ra = rays_into(source.pos[ua].to_bits(), (u_lo, u_hi), f, d, t, big_n);
            let rb = rays_into(source.pos[va].to_bits(), (v_lo, v_hi), f, d, t, big_n);
            let (Some((a0, a1)), Some((b0, b1))) = (ra, rb) else { continue };
            for a in a0..=a1 {
                let row = (a + big_n) as usize * side;
                for slot in &mut last[row + (b0 + big_n) as usize..=row + (b1 + big_n) as usize] {
                    *slot = (*slot).max(k as u16);
                }
            }
        }
    }
    last
}

/// The per-ray table `last` (`side` × `side`) reduced to TILE × TILE tiles, each the least of
/// its rays' values (a partial tile at the edge: of the rays it has).
fn tiled(last: &[u16], side: usize) -> Vec<u16> {
    let tiles = side.div_ceil(TILE);
    let mut out = vec![u16::MAX; tiles * tiles];
    for (a, row) in last.chunks_exact(side).enumerate() {
        let t_row = &mut out[a / TILE * tiles..][..tiles];
        for (b, &k) in row.iter().enumerate() {
            let t = &mut t_row[b / TILE];
            *t = (*t).min(k);
        }
    }
    out
}

/// The lattice rays `a` ∈ [−N, N] (2^−f units) whose transverse voxel at reach `t` is in
/// `x_lo ..= x_hi`, on an axis where the source is at `b` (2^−g units): `x(a) = ⌊(b·2^(f+1)·D +
/// 2·a·t + 2^(f+g)·D) / (2^(f+g+1)·D)⌋` (`trace_ray_voxel`'s formula, non-decreasing in `a`)
/// solved for `a`; `None` if no ray (or `t = 0`, where every ray is at the origin: not tabled).
fn rays_into(b: i32, (x_lo, x_hi): (i64, i64), f: u32, d: u32, t: i64, big_n: i64) -> Option<(i64, i64)> {
    if t <= 0 {
        return None;
    }
    let (d, pf, g) = (d as i128, 1i128 << f, SOURCE_FRAC_BITS);
    let den = (pf << (g + 1)) * d;
    let c = b as i128 * (pf << 1) * d + (pf << g) * d;
    let two_t = 2 * t as i128;
    // x_lo·den ≤ c + 2t·a ≤ x_hi·den + den − 1.
    let lo = -((c - x_lo as i128 * den).div_euclid(two_t));
    let hi = (x_hi as i128 * den + den - 1 - c).div_euclid(two_t);
    let (lo, hi) = (lo.max(-big_n as i128) as i64, hi.min(big_n as i128) as i64);
    (lo <= hi).then_some((lo, hi))
}

/// `rays_into` checked against [`trace_ray_voxel`] (tests).
#[cfg(test)]
fn voxel_of<F: FracBits>(source: &Source, dir: Direction, far: FarDistance<F>, a: i64, b: i64, k: u32) -> (i64, i64) {
    trace_ray_voxel(
        source,
        dir,
        FarOffset::<F>::from_bits(a as i32),
        FarOffset::<F>::from_bits(b as i32),
        far,
        Layer(k),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use cell_core::beam::frac::{U0, U2};
    use cell_core::beam::{Origin, RayRange, SourceCoord, SourceId};
    use cell_core::occupancy::Occupancy8;

    fn source(p: [f64; 3], light: bool) -> Source {
        let s = Source::new(SourceId(0), p.map(SourceCoord::from_num));
        if light {
            s.with_origin(Origin::Light)
        } else {
            s
        }
    }

    /// The rays `rays_into` gives are exactly those whose voxel is in `x ..= x + 2` (every ray of the
    /// lattice checked with the direct formula), for sources on and off voxel centres, both
    /// origins, f = 0 and 2, every layer.
    #[test]
    fn rays_into_inverts_the_ray_voxel_formula() {
        fn check<F: FracBits>(src: &Source) {
            let far = FarDistance::<F>::new(11).unwrap();
            let big_n = 11i64 << F::U32;
            for dir in Direction::ALL {
                let (ua, _) = dir.transverse();
                for k in 1..=11u32 {
                    let t = src.reach(dir, Layer(k));
                    for x in -3..16i64 {
                        let got = rays_into(src.pos[ua.index()].to_bits(), (x, x + 2), F::U32, 11, t, big_n);
                        let want: Vec<i64> = (-big_n..=big_n)
                            .filter(|&a| (x..=x + 2).contains(&voxel_of(src, dir, far, a, 0, k).0))
                            .collect();
                        let got: Vec<i64> = got.map(|(lo, hi)| (lo..=hi).collect()).unwrap_or_default();
                        assert_eq!(got, want, "{dir:?} k = {k} x = {x}");
                    }
                }
            }
        }
        for (p, light) in [([5.0, 5.0, 5.0], false), ([4.3125, 6.5, 2.75], true), ([0.0, 11.0, 3.5625], true)] {
            check::<U0>(&source(p, light));
            check::<U2>(&source(p, light));
        }
    }

    /// Against the per-ray oracle: the filled layer of every lattice ray is the last layer ≥ 1
    /// (with a nonzero reach) at which its voxel lies in an occupied block, a tile keeps the
    /// least of its rays'; and over rectangles
    /// of rays from every layer, the shortcut answers exactly as the summary's test.
    #[test]
    fn the_table_is_each_rays_last_occupied_block_and_answers_as_the_test() {
        let n = 12u32;
        let marked = |[x, y, z]: [u32; 3]| (x + 2 * y + 3 * z) % 23 == 0;
        let mut summary = Occupancy8::new(n, n);
        for (x, y, z) in (0..n).flat_map(|x| (0..n).flat_map(move |y| (0..n).map(move |z| (x, y, z)))) {
            if marked([x, y, z]) {
                summary.mark_span(x, y, z, z);
            }
        }
        let blocks = OccupiedBlocks::of(&summary);
        assert!(!blocks.list.is_empty() && blocks.list.len() < 8 * 8 * 8, "a sparse scene: {}", blocks.list.len());
        let in_block = |p: [i64; 3]| {
            p.iter().all(|&c| (0..n as i64).contains(&c)) && summary.occupied_block(p.map(|c| c as usize / 2))
        };
        let big_n = (n - 1) as i64;
        let r =
            |lo: i64, hi: i64| RayRange::new(FarOffset::from_bits(lo as i32), FarOffset::from_bits(hi as i32)).unwrap();
        let mut seed = 0x2545_f491_u64;
        let mut next = |m: i64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % m as u64) as i64
        };
        let mut answered = [0usize; 2];
        for src in [source([5.0, 6.0, 4.0], false), source([3.4375, 8.25, 6.5], true)] {
            let far = FarDistance::<U0>::new(n - 1).unwrap();
            let table = Shortcut::new(&summary as &dyn FrustumTest<U0>, &src, far, &blocks).unwrap();
            let side = (2 * big_n + 1) as usize;
            for dir in Direction::ALL {
                let full = fill(dir, &src, far, big_n, side, &blocks);
                for a in -big_n..=big_n {
                    for b in -big_n..=big_n {
                        let want = (1..n)
                            .filter(|&k| src.reach(dir, Layer(k)) > 0)
                            .filter(|&k| {
                                let (u, v) = voxel_of(&src, dir, far, a, b, k);
                                in_block(dir.voxel(
                                    &src,
                                    Layer(k),
                                    cell_core::beam::Transverse { u: u as i32, v: v as i32 },
                                ))
                            })
                            .max()
                            .unwrap_or(0);
                        assert_eq!(
                            full[(a + big_n) as usize * side + (b + big_n) as usize] as u32,
                            want,
                            "{dir:?} ({a}, {b})"
                        );
                        // The tile's value: the least of its rays'.
                        let (ta, tb) = ((a + big_n) / TILE as i64, (b + big_n) / TILE as i64);
                        let tile = |x: i64, t: i64| (x + big_n) / TILE as i64 == t;
                        let least = (-big_n..=big_n)
                            .filter(|&x| tile(x, ta))
                            .flat_map(|x| (-big_n..=big_n).filter(move |&y| tile(y, tb)).map(move |y| (x, y)))
                            .map(|(x, y)| full[(x + big_n) as usize * side + (y + big_n) as usize])
                            .min();
                        assert_eq!(Some(table.last_layer(dir, a, b)), least, "{dir:?} tile of ({a}, {b})");
                    }
                }
                for _ in 0..300 {
                    let (a0, b0) = (next(2 * big_n + 1) - big_n, next(2 * big_n + 1) - big_n);
                    let (a1, b1) = ((a0 + next(4)).min(big_n), (b0 + next(4)).min(big_n));
                    for k0 in 1..n {
                        let beam = Beam::<U0>::new(src.id, dir, Layer(k0 - 1), r(a0, a1), r(b0, b1), far).unwrap();
                        let empty = summary.frustum_empty(&beam, &src, far, k0);
                        assert_eq!(table.frustum_empty(&beam, &src, far, k0), empty, "{beam:?} k0 = {k0}");
                        answered[empty as usize] += 1;
                    }
                }
            }
        }
        // Both answers occur (the comparison is not vacuous).
        assert!(answered.iter().all(|&c| c > 100), "{answered:?}");
    }
}
