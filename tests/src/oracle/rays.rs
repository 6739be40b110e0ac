//! Per-ray lighting oracle (rays, beams and the split: thesis §4.1.4, §4.1.5, §4.3).
//!
//! Beam diffusion must light exactly the voxels that tracing every ray of the lattice one by one
//! lights. This module traces those rays one by one (or, equivalently, one class of identical
//! rays at a time), restating the definition with exact integer arithmetic. It never calls
//! `cell_core::beam`, the code under test.
//!
//! # Definition
//! * The grid is `n × n × n` voxels with indices `0..n`; voxel `(x, y, z)` has its centre at the
//!   integer point `(x, y, z)`.
//! * A source `S` is given in sixteenths of a voxel: `src: [i64; 3]` is `16 · position`
//!   (`16·5 + 8` is 5.5). Its voxel is `⌊p + ½⌋` per axis (round half up), i.e.
//!   `⌊(src + 8) / 16⌋` ([`source_voxel`]).
//! * `d` is the far distance `D ≥ 1` (the thesis uses `D = n − 1`), `f` the fraction bits
//!   (`0 ..= 12` here).
//! * Six directions, numbered `0..6` = `+x, −x, +y, −y, +z, −z` ([`DIR_NAMES`]). Direction `dir`
//!   has principal axis `w = dir / 2`, sign `s = +1` for even `dir`, `−1` for odd; its transverse
//!   axes (u-axis, v-axis) are the other two in increasing order: `(y, z)` for ±x, `(x, z)` for
//!   ±y, `(x, y)` for ±z ([`dir_axes`]).
//! * A ray is `(dir, a, b)` with far-plane offsets `u = a / 2^f`, `v = b / 2^f` and integers
//!   `a, b ∈ [−D·2^f, D·2^f]`. At layer `k = 0, 1, 2, …` it occupies the voxel with principal
//!   coordinate `w_voxel(S) + s·k` and transverse coordinates `⌊S_u + u·k/D + ½⌋`,
//!   `⌊S_v + v·k/D + ½⌋` (round half up; `S_u` is the source's *exact* coordinate, a multiple
//!   of 1/16) — see [`ray_voxel`]. With `L = 16·D·2^f` the transverse coordinate is
//!   `⌊((src_u + 8)·D·2^f + 16·a·k) / L⌋`, computed in `i128`.
//! * Walk: for `k = 0, 1, 2, …` — if the voxel is outside the grid (any coordinate `< 0` or
//!   `≥ n`) or `k > D`, the ray **exits**; else if the voxel is occupied the ray is **absorbed**
//!   and lights that voxel for this source; else go on with `k + 1`. Layer 0 is the source voxel
//!   itself: if it is occupied, every ray is absorbed there.
//! * The six faces' ray sets overlap on edges (`|u| = D` or `|v| = D`); every `(dir, a, b)`
//!   counts separately, so a source emits `6 · (2·D·2^f + 1)²` rays ([`rays_per_source`]).
//!
//! Invariants checked by the tests: emitted = absorbed + exited; lit ⊆ occupied; in an empty grid
//! every voxel is reached when `D = n − 1`, for any source voxel in the grid and any `f`
//! ([`reached_all`]).
//!
//! # Speed
//! [`trace_all`] computes, per source and direction, the transverse coordinate sequence of every
//! `a` (and every `b`) incrementally (quotient/remainder stepping, no division per step), groups
//! offsets whose in-grid sequences are identical, and walks each pair of classes once, weighting
//! it by the product of the class sizes. Rays in one class pair visit the same voxels, so the
//! result is the same as tracing each ray; [`trace_all_naive`] does exactly that (one ray at a
//! time through [`ray_voxel`]) and the tests compare the two.

use std::collections::{BTreeMap, HashMap};

/// Names of the six directions, by index.
pub const DIR_NAMES: [&str; 6] = ["+x", "-x", "+y", "-y", "+z", "-z"];

/// Largest fraction bit count the oracle accepts.
pub const MAX_F: u32 = 12;

/// The result of tracing every ray of every source.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct RayOutcome {
    /// Lit voxel → OR of the masks (`1 << i` for `sources[i]`) of the sources that light it.
    pub lit: BTreeMap<[i64; 3], u64>,
    /// Rays emitted, summed over all sources: `sources.len() · 6 · (2·D·2^f + 1)²`.
    pub rays_emitted: u128,
    /// Rays absorbed by an occupied voxel.
    pub rays_absorbed: u128,
    /// Rays that left the grid or went past layer `D`.
    pub rays_exited: u128,
}

/// What became of one ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fate {
    /// Absorbed at (and lighting) this voxel, at this layer.
    Absorbed { voxel: [i64; 3], k: i64 },
    /// Left the grid, or passed layer `D`, at this layer (the first layer it is not in).
    Exited { k: i64 },
}

/// `(principal axis, sign, u-axis, v-axis)` of direction `dir` (0..6 = +x, −x, +y, −y, +z, −z).
///
/// # Panics
/// If `dir >= 6`.
pub fn dir_axes(dir: usize) -> (usize, i64, usize, usize) {
    assert!(dir < 6, "direction {dir} out of 0..6");
    let w = dir / 2;
    let s = [1, -1][dir % 2];
    let (u, v) = match w {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    (w, s, u, v)
}

/// The voxel of a source given in sixteenths: `⌊(src + 8) / 16⌋` per axis (round half up).
pub fn source_voxel(src: [i64; 3]) -> [i64; 3] {
    src.map(|c| (c as i128 + 8).div_euclid(16) as i64)
}

/// Rays one source emits: `6 · (2·D·2^f + 1)²`.
pub fn rays_per_source(d: i64, f: u32) -> u128 {
    let side = 2 * (d as u128) * (1u128 << f) + 1;
    6 * side * side
}

fn check_params(d: i64, f: u32) {
    assert!(d >= 1, "far distance D = {d} must be ≥ 1");
    assert!(f <= MAX_F, "fraction bits f = {f} must be ≤ {MAX_F}");
}

/// Transverse voxel coordinate `⌊src_c/16 + (a/2^f)·k/D + ½⌋`, exactly.
///
/// `src_c` is the source's coordinate on that axis in sixteenths.
pub fn transverse(src_c: i64, a: i64, d: i64, f: u32, k: i64) -> i64 {
    check_params(d, f);
    let scale = (d as i128) << f; // D·2^f
    let num = (src_c as i128 + 8) * scale + 16 * (a as i128) * (k as i128);
    let den = 16 * scale;
    num.div_euclid(den) as i64
}

/// The voxel ray `(dir, a, b)` of source `src` occupies at layer `k` (in or out of the grid;
/// `n` is not used by the formula and is accepted for symmetry with the other functions).
///
/// # Panics
/// If `dir >= 6`, `d < 1` or `f > 12`.
#[allow(clippy::too_many_arguments)] // the ray's full coordinates, as the definition states them
pub fn ray_voxel(n: i64, src: [i64; 3], dir: usize, a: i64, b: i64, d: i64, f: u32, k: i64) -> [i64; 3] {
    let _ = n;
    let (w, s, ua, va) = dir_axes(dir);
    let mut out = [0i64; 3];
    out[w] = source_voxel(src)[w] + s * k;
    out[ua] = transverse(src[ua], a, d, f, k);
    out[va] = transverse(src[va], b, d, f, k);
    out
}

fn in_grid(n: i64, p: [i64; 3]) -> bool {
    p.iter().all(|&c| (0..n).contains(&c))
}

/// Where the rays leave from along their axis: the source voxel's centre plane (the thesis's
/// rays, [`ray_voxel`]) or the light itself ([`ray_voxel_from_light`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RaysFrom {
    /// The source voxel's centre plane: layer k is k voxels from it.
    Voxel,
    /// The light: layer k ≥ 1 lies on the k-th voxel centre plane strictly ahead of it
    /// ([`light_layer`]), layer 0 at the light.
    Light,
}

impl RaysFrom {
    /// The voxel of ray `(dir, a, b)` of `src` at layer `k` ([`ray_voxel`] or
    /// [`ray_voxel_from_light`]).
    #[allow(clippy::too_many_arguments)] // the ray's full coordinates, as the definition states them
    pub fn voxel(self, src: [i64; 3], dir: usize, a: i64, b: i64, d: i64, f: u32, k: i64) -> [i64; 3] {
        match self {
            RaysFrom::Voxel => ray_voxel(0, src, dir, a, b, d, f, k),
            RaysFrom::Light => ray_voxel_from_light(src, dir, a, b, d, f, k),
        }
    }
}

/// Walks one ray by the definition (one [`ray_voxel`] per layer).
#[allow(clippy::too_many_arguments)]
pub fn trace_ray(
    n: i64,
    occupied: &dyn Fn(i64, i64, i64) -> bool,
    src: [i64; 3],
    dir: usize,
    a: i64,
    b: i64,
    d: i64,
    f: u32,
) -> Fate {
    trace_ray_from(RaysFrom::Voxel, n, occupied, src, dir, a, b, d, f)
}

/// [`trace_ray`] for rays leaving from `from`.
#[allow(clippy::too_many_arguments)]
pub fn trace_ray_from(
    from: RaysFrom,
    n: i64,
    occupied: &dyn Fn(i64, i64, i64) -> bool,
    src: [i64; 3],
    dir: usize,
    a: i64,
    b: i64,
    d: i64,
    f: u32,
) -> Fate {
    let mut k = 0;
    loop {
        if k > d {
            return Fate::Exited { k };
        }
        let p = from.voxel(src, dir, a, b, d, f, k);
        if !in_grid(n, p) {
            return Fate::Exited { k };
        }
        if occupied(p[0], p[1], p[2]) {
            return Fate::Absorbed { voxel: p, k };
        }
        k += 1;
    }
}

/// Occupancy, cached in a flat table when the grid is not huge.
struct Occ<'a> {
    n: i64,
    table: Option<Vec<bool>>,
    f: &'a dyn Fn(i64, i64, i64) -> bool,
}

impl<'a> Occ<'a> {
    const MAX_CACHED: i64 = 1 << 24;

    fn new(n: i64, f: &'a dyn Fn(i64, i64, i64) -> bool) -> Self {
        let table = (n > 0 && n.checked_mul(n).and_then(|m| m.checked_mul(n)).is_some_and(|t| t <= Self::MAX_CACHED))
            .then(|| {
                let mut t = vec![false; (n * n * n) as usize];
                for z in 0..n {
                    for y in 0..n {
                        for x in 0..n {
                            t[(x + n * (y + n * z)) as usize] = f(x, y, z);
                        }
                    }
                }
                t
            });
        Occ { n, table, f }
    }

    /// `p` must be in the grid.
    fn get(&self, p: [i64; 3]) -> bool {
        match &self.table {
            Some(t) => t[(p[0] + self.n * (p[1] + self.n * p[2])) as usize],
            None => (self.f)(p[0], p[1], p[2]),
        }
    }
}

/// Classes of far-plane offsets `a ∈ [−D·2^f, D·2^f]` with identical in-grid transverse
/// sequences: for each class, the coordinates at layers `0, 1, …` up to (not including) the
/// first layer that is out of `0..n` or past `kmax`, and the number of offsets in the class.
fn offset_classes(n: i64, src_c: i64, d: i64, f: u32, kmax: i64) -> Vec<(Vec<i64>, u128)> {
    let scale = (d as i128) << f;
    let den = 16 * scale;
    let num0 = (src_c as i128 + 8) * scale;
    let q0 = num0.div_euclid(den);
    let r0 = num0.rem_euclid(den);
    let m = (d as i128) << f;
    let mut classes: HashMap<Vec<i64>, u128> = HashMap::new();
    let mut seq = Vec::with_capacity((kmax.max(0) + 1) as usize);
    for a in -m..=m {
        let step = 16 * a;
        let (dq, dr) = (step.div_euclid(den), step.rem_euclid(den));
        let (mut q, mut r) = (q0, r0);
        seq.clear();
        let mut k = 0;
        while k <= kmax {
            if q < 0 || q >= n as i128 {
                break;
            }
            seq.push(q as i64);
            q += dq;
            r += dr;
            if r >= den {
                r -= den;
                q += 1;
            }
            k += 1;
        }
        *classes.entry(seq.clone()).or_insert(0) += 1;
    }
    let mut v: Vec<_> = classes.into_iter().collect();
    v.sort();
    v
}

/// Traces every ray of every source (see the module doc for the definition).
///
/// `sources[i]` is in sixteenths of a voxel and gets mask bit `1 << i`.
///
/// # Panics
/// If there are more than 64 sources, `d < 1` or `f > 12`.
pub fn trace_all(n: i64, occupied: &dyn Fn(i64, i64, i64) -> bool, sources: &[[i64; 3]], d: i64, f: u32) -> RayOutcome {
    check_params(d, f);
    assert!(sources.len() <= 64, "at most 64 sources (mask bits), got {}", sources.len());
    let occ = Occ::new(n, occupied);
    let mut out = RayOutcome::default();
    let side = 2 * (d as u128) * (1u128 << f) + 1;
    let per_dir = side * side;
    for (i, &src) in sources.iter().enumerate() {
        let mask = 1u64 << i;
        let sv = source_voxel(src);
        for dir in 0..6 {
            out.rays_emitted += per_dir;
            let (w, s, ua, va) = dir_axes(dir);
            let w0 = sv[w];
            // Last layer whose principal coordinate is in the grid, capped by D.
            let kmax = if !(0..n).contains(&w0) {
                -1
            } else if s > 0 {
                (n - 1 - w0).min(d)
            } else {
                w0.min(d)
            };
            if kmax < 0 {
                out.rays_exited += per_dir;
                continue;
            }
            let us = offset_classes(n, src[ua], d, f, kmax);
            let vs = offset_classes(n, src[va], d, f, kmax);
            for (useq, cu) in &us {
                for (vseq, cv) in &vs {
                    let weight = cu * cv;
                    let len = useq.len().min(vseq.len());
                    let mut absorbed = false;
                    for k in 0..len {
                        let mut p = [0i64; 3];
                        p[w] = w0 + s * k as i64;
                        p[ua] = useq[k];
                        p[va] = vseq[k];
                        if occ.get(p) {
                            *out.lit.entry(p).or_insert(0) |= mask;
                            absorbed = true;
                            break;
                        }
                    }
                    if absorbed {
                        out.rays_absorbed += weight;
                    } else {
                        out.rays_exited += weight;
                    }
                }
            }
        }
    }
    out
}

/// Same result as [`trace_all`], tracing each ray separately with [`trace_ray`]; slow, a
/// reference for the fast path. Use only for small `D·2^f`.
pub fn trace_all_naive(
    n: i64,
    occupied: &dyn Fn(i64, i64, i64) -> bool,
    sources: &[[i64; 3]],
    d: i64,
    f: u32,
) -> RayOutcome {
    trace_all_naive_from(RaysFrom::Voxel, n, occupied, sources, d, f)
}

/// [`trace_all_naive`] for rays leaving from `from` ([`trace_ray_from`]).
pub fn trace_all_naive_from(
    from: RaysFrom,
    n: i64,
    occupied: &dyn Fn(i64, i64, i64) -> bool,
    sources: &[[i64; 3]],
    d: i64,
    f: u32,
) -> RayOutcome {
    check_params(d, f);
    assert!(sources.len() <= 64, "at most 64 sources (mask bits), got {}", sources.len());
    let m = d << f;
    let mut out = RayOutcome::default();
    for (i, &src) in sources.iter().enumerate() {
        for dir in 0..6 {
            for a in -m..=m {
                for b in -m..=m {
                    out.rays_emitted += 1;
                    match trace_ray_from(from, n, occupied, src, dir, a, b, d, f) {
                        Fate::Absorbed { voxel, .. } => {
                            out.rays_absorbed += 1;
                            *out.lit.entry(voxel).or_insert(0) |= 1 << i;
                        }
                        Fate::Exited { .. } => out.rays_exited += 1,
                    }
                }
            }
        }
    }
    out
}

/// For rays from the light, layer `k ≥ 1` of direction `dir`: the principal coordinate c of
/// the k-th voxel centre plane strictly ahead of the light `src` (sixteenths), and its distance
/// `T = s·(16·c − src_w)` > 0 from the light in sixteenths.
pub fn light_layer(src: [i64; 3], dir: usize, k: i64) -> (i64, i64) {
    let (w, s, _, _) = dir_axes(dir);
    // The first centre plane strictly ahead of the light, then k − 1 more.
    let mut c = src[w].div_euclid(16) - s;
    while s * (16 * c - src[w]) <= 0 {
        c += s;
    }
    c += s * (k - 1);
    (c, s * (16 * c - src[w]))
}

/// The voxel of ray `(dir, a, b)` of `src` at layer `k` for **rays from the light itself**
/// (`cell_core::beam::Origin::Light`), from the definition: at layer 0 every ray is at the
/// light, in the source voxel; at layer k ≥ 1 it meets the k-th voxel centre plane strictly
/// ahead of the light along `dir` (principal coordinate c with `s·(16·c − src_w) > 0`), at
/// distance `T = s·(16·c − src_w)` sixteenths from the light along the axis, and its transverse
/// coordinates round `src_u/16 + (a/2^f)·T/(16·D)` half up.
#[allow(clippy::too_many_arguments)] // the ray's full coordinates, as the definition states them
pub fn ray_voxel_from_light(src: [i64; 3], dir: usize, a: i64, b: i64, d: i64, f: u32, k: i64) -> [i64; 3] {
    check_params(d, f);
    let (w, _, ua, va) = dir_axes(dir);
    if k == 0 {
        return source_voxel(src);
    }
    let (c, t) = light_layer(src, dir, k);
    let t = t as i128;
    let scale = (d as i128) << f;
    let across = |src_c: i64, a: i64| ((src_c as i128 + 8) * scale + t * a as i128).div_euclid(16 * scale) as i64;
    let mut out = [0i64; 3];
    out[w] = c;
    out[ua] = across(src[ua], a);
    out[va] = across(src[va], b);
    out
}

/// Voxels of an empty `n³` grid that no ray of `src` occupies at any layer (the coverage oracle:
/// diffusion must reach every voxel of an empty scene); sorted.
pub fn unreached(n: i64, src: [i64; 3], d: i64, f: u32) -> Vec<[i64; 3]> {
    check_params(d, f);
    if n <= 0 {
        return Vec::new();
    }
    let nu = n as usize;
    let mut seen = vec![false; nu * nu * nu];
    let sv = source_voxel(src);
    for dir in 0..6 {
        let (w, s, ua, va) = dir_axes(dir);
        let w0 = sv[w];
        let kmax = if !(0..n).contains(&w0) {
            -1
        } else if s > 0 {
            (n - 1 - w0).min(d)
        } else {
            w0.min(d)
        };
        if kmax < 0 {
            continue;
        }
        let us = offset_classes(n, src[ua], d, f, kmax);
        let vs = offset_classes(n, src[va], d, f, kmax);
        for (useq, _) in &us {
            for (vseq, _) in &vs {
                for k in 0..useq.len().min(vseq.len()) {
                    let mut p = [0i64; 3];
                    p[w] = w0 + s * k as i64;
                    p[ua] = useq[k];
                    p[va] = vseq[k];
                    seen[(p[0] + n * (p[1] + n * p[2])) as usize] = true;
                }
            }
        }
    }
    let mut out = Vec::new();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                if !seen[(x + n * (y + n * z)) as usize] {
                    out.push([x, y, z]);
                }
            }
        }
    }
    out.sort();
    out
}

/// Whether every voxel of an empty `n³` grid is occupied by at least one ray of `src` at some
/// layer `k ≤ D`.
pub fn reached_all(n: i64, src: [i64; 3], d: i64, f: u32) -> bool {
    unreached(n, src, d, f).is_empty()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sixteenths of a voxel.
    fn p16(x: i64) -> i64 {
        16 * x
    }

    fn check_conservation(o: &RayOutcome) {
        assert_eq!(o.rays_emitted, o.rays_absorbed + o.rays_exited, "{o:?}");
    }

    fn lcg(seed: &mut u64) -> u64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *seed >> 33
    }

    #[test]
    fn source_voxel_rounds_half_up() {
        assert_eq!(source_voxel([88, 87, 89]), [6, 5, 6]); // 5.5 → 6, 5.4375 → 5, 5.5625 → 6
        assert_eq!(source_voxel([-8, -9, 7]), [0, -1, 0]); // −0.5 → 0, −0.5625 → −1, 0.4375 → 0
        assert_eq!(source_voxel([-24, 0, 16 * 15 + 8]), [-1, 0, 16]); // −1.5 → −1, 0, 15.5 → 16
    }

    #[test]
    fn transverse_rounding_by_hand() {
        // Integer source 5, D = 15, u = ±1.
        assert_eq!(transverse(p16(5), 1, 15, 0, 7), 5); // 5 + 7/15 = 5.47 → 5
        assert_eq!(transverse(p16(5), 1, 15, 0, 8), 6); // 5 + 8/15 = 5.53 → 6
        assert_eq!(transverse(p16(5), -1, 15, 0, 7), 5); // 4.53 → 5
        assert_eq!(transverse(p16(5), -1, 15, 0, 8), 4); // 4.47 → 4
                                                         // Exact halves round up, also for negative u: D = 2, k = 1.
        assert_eq!(transverse(p16(5), 1, 2, 0, 1), 6); // 5.5 → 6
        assert_eq!(transverse(p16(5), -1, 2, 0, 1), 5); // 4.5 → 5 (not 4)
        assert_eq!(transverse(p16(0), -1, 2, 0, 1), 0); // −0.5 → 0
        assert_eq!(transverse(p16(0), -3, 2, 0, 1), -1); // −1.5 → −1
        assert_eq!(transverse(p16(0), -3, 2, 0, 2), -3); // −3 → −3
                                                         // Fractional source 5.25, D = 4.
        assert_eq!(transverse(84, 1, 4, 0, 1), 6); // 5.5 → 6
        assert_eq!(transverse(84, -3, 4, 0, 1), 5); // 4.5 → 5
        assert_eq!(transverse(84, -3, 4, 0, 2), 4); // 3.75 → 4
        assert_eq!(transverse(84, -3, 4, 0, 0), 5); // 5.25 → 5
                                                    // Fractional u: f = 2, a = −3 (u = −0.75), D = 3, k = 2: 5 − 0.5 = 4.5 → 5.
        assert_eq!(transverse(p16(5), -3, 3, 2, 2), 5);
        assert_eq!(transverse(p16(5), -3, 3, 2, 3), 4); // 4.25 → 4
        assert_eq!(transverse(p16(5), 3, 3, 2, 2), 6); // 5.5 → 6
                                                       // Source at 5.5 exactly: layer 0 is its (rounded-up) voxel; −1/16 of u doesn't move it.
        assert_eq!(transverse(88, 0, 15, 4, 0), 6);
        assert_eq!(transverse(88, -1, 15, 4, 1), 5); // 5.5 − 1/240 → 5
        assert_eq!(transverse(88, 1, 15, 4, 1), 6);
    }

    #[test]
    fn ray_voxel_directions() {
        let src = [p16(5), p16(6), 16 * 7 + 8]; // (5, 6, 7.5) → voxel (5, 6, 8)
        let (d, f) = (2, 0);
        // +x: w = x, u = y, v = z.
        assert_eq!(ray_voxel(16, src, 0, 1, -1, d, f, 1), [6, 7, 7]); // y 6.5→7, z 7.0→7
                                                                      // −x.
        assert_eq!(ray_voxel(16, src, 1, 1, -1, d, f, 2), [3, 7, 7]); // y 7, z 6.5→7
                                                                      // +y: u = x, v = z.
        assert_eq!(ray_voxel(16, src, 2, -1, 1, d, f, 1), [5, 7, 8]); // x 4.5→5, z 8.0→8
                                                                      // −y.
        assert_eq!(ray_voxel(16, src, 3, -2, 2, d, f, 2), [3, 4, 10]); // x 3, z 9.5→10
                                                                       // +z: u = x, v = y; principal from the rounded source voxel 8.
        assert_eq!(ray_voxel(16, src, 4, 2, -2, d, f, 1), [6, 5, 9]); // x 6, y 5
                                                                      // −z.
        assert_eq!(ray_voxel(16, src, 5, 0, 1, d, f, 2), [5, 7, 6]);
        for dir in 0..6 {
            assert_eq!(ray_voxel(16, src, dir, 2, -2, d, f, 0), [5, 6, 8]);
        }
    }

    #[test]
    fn incremental_classes_match_direct_formula() {
        for &(n, src_c, d, f) in
            &[(16, 120, 15, 4), (16, 7, 15, 2), (9, 16 * 4 + 3, 8, 3), (5, -5, 7, 1), (4, 80, 3, 0)]
        {
            let kmax = d.min(n);
            let classes = offset_classes(n, src_c, d, f, kmax);
            let total: u128 = classes.iter().map(|c| c.1).sum();
            assert_eq!(total, 2 * ((d as u128) << f) + 1);
            // Every offset's direct sequence (truncated at the first out-of-grid layer) is a class.
            let m = d << f;
            for a in -m..=m {
                let mut seq = Vec::new();
                for k in 0..=kmax {
                    let c = transverse(src_c, a, d, f, k);
                    if !(0..n).contains(&c) {
                        break;
                    }
                    seq.push(c);
                }
                assert!(classes.iter().any(|c| c.0 == seq), "a = {a}: {seq:?}");
            }
        }
    }

    #[test]
    fn empty_grid_every_ray_exits() {
        for &(n, d, f) in &[(8, 7, 0), (8, 7, 2), (5, 4, 3), (16, 15, 4)] {
            let src = [8 * n - 8, 8 * n, 8 * n + 3];
            let o = trace_all(n, &|_, _, _| false, &[src], d, f);
            let want = 6 * (2 * (d as u128) * (1 << f) + 1).pow(2);
            assert_eq!(o.rays_absorbed, 0);
            assert!(o.lit.is_empty());
            assert_eq!(o.rays_emitted, want);
            assert_eq!(o.rays_exited, want);
            assert_eq!(rays_per_source(d, f), want);
        }
        // f = 0, D = 1: 6 · 3² = 54.
        assert_eq!(trace_all(3, &|_, _, _| false, &[[16; 3]], 1, 0).rays_exited, 54);
    }

    #[test]
    fn empty_grid_is_covered() {
        for n in [1, 2, 3, 5, 8, 16] {
            let d = (n - 1).max(1);
            for f in [0, 1, 3] {
                // Centre (7.5 for n = 16 → voxel 8), corner, fractional, near-corner sources.
                for src in [
                    [8 * (n - 1); 3],
                    [0; 3],
                    [16 * (n - 1); 3],
                    [8 * n - 5, 3, 16 * n - 9],
                    [16 * (n / 3) + 7, 16 * (n / 2) - 8, 16 * (n / 4) + 1],
                ] {
                    assert!(in_grid(n, source_voxel(src)), "test source {src:?} outside {n}³");
                    let miss = unreached(n, src, d, f);
                    assert!(
                        miss.is_empty(),
                        "n={n} f={f} src={src:?}: {} unreached, e.g. {:?}",
                        miss.len(),
                        &miss[..miss.len().min(5)]
                    );
                }
            }
        }
        assert!(reached_all(16, [120; 3], 15, 4));
    }

    #[test]
    fn coverage_oracle_can_fail() {
        // D = 2 from a corner of a 5³ grid: voxels at Chebyshev distance 3 and 4 are beyond D.
        let miss = unreached(5, [0; 3], 2, 1);
        assert!(!miss.is_empty());
        assert!(miss.contains(&[4, 4, 4]) && miss.contains(&[3, 0, 0]));
        assert!(!miss.contains(&[2, 2, 2]));
        assert!(!reached_all(5, [0; 3], 2, 1));
        // A source outside the grid reaches nothing.
        assert_eq!(unreached(3, [-16, 16, 16], 2, 0).len(), 27);
    }

    #[test]
    fn neighbour_of_source_is_lit() {
        let n = 16;
        let src = [p16(8); 3];
        for nb in [[9, 8, 8], [7, 8, 8], [8, 9, 8], [8, 8, 7], [9, 9, 8], [7, 9, 9]] {
            let o = trace_all(n, &|x, y, z| [x, y, z] == nb, &[src], 15, 2);
            assert_eq!(o.lit.len(), 1, "{nb:?}");
            assert_eq!(o.lit.get(&nb), Some(&1));
            assert!(o.rays_absorbed > 0);
            check_conservation(&o);
        }
    }

    #[test]
    fn wall_blocks_everything_behind_it() {
        let n = 16;
        let src = [120, 120, 120]; // 7.5 → voxel 8
        for f in [0, 2] {
            let wall = |_: i64, _: i64, z: i64| z == 10;
            let o = trace_all(n, &wall, &[src], 15, f);
            check_conservation(&o);
            assert!(o.lit.keys().all(|p| p[2] == 10), "lit behind or before the wall");
            assert!(o.lit.contains_key(&[8, 8, 10]));
            // Put an occupied voxel behind the wall: it stays dark.
            let wall2 = |x: i64, y: i64, z: i64| z == 10 || [x, y, z] == [8, 8, 12];
            let o2 = trace_all(n, &wall2, &[src], 15, f);
            assert!(!o2.lit.contains_key(&[8, 8, 12]));
            assert_eq!(o.lit, o2.lit);
            // Without the wall it is lit.
            let o3 = trace_all(n, &|x, y, z| [x, y, z] == [8, 8, 12], &[src], 15, f);
            assert_eq!(o3.lit.keys().copied().collect::<Vec<_>>(), vec![[8, 8, 12]]);
        }
    }

    #[test]
    fn hollow_box_lights_only_its_inner_faces() {
        let n = 12;
        let shell = |x: i64, y: i64, z: i64| {
            let inb = |c: i64| (2..=9).contains(&c);
            let edge = |c: i64| c == 2 || c == 9;
            inb(x) && inb(y) && inb(z) && (edge(x) || edge(y) || edge(z))
        };
        let o = trace_all(n, &shell, &[[p16(5), 90, p16(6)]], 11, 1);
        check_conservation(&o);
        assert_eq!(o.rays_exited, 0, "a ray escaped a closed box");
        assert!(o.lit.keys().all(|&[x, y, z]| shell(x, y, z)));
        // Every face-centre voxel of the box is lit.
        for p in [[2, 5, 5], [9, 5, 5], [5, 2, 5], [5, 9, 5], [5, 5, 2], [5, 5, 9]] {
            assert!(o.lit.contains_key(&p), "{p:?}");
        }
    }

    #[test]
    fn source_inside_occupied_voxel() {
        let src = [16 * 4 + 5, 16 * 4 - 7, p16(4)]; // (4.3125, 3.5625, 4) → voxel (4, 4, 4)
        let solid = |_: i64, _: i64, _: i64| true;
        let o = trace_all(8, &solid, &[src], 7, 1);
        assert_eq!(o.lit.keys().copied().collect::<Vec<_>>(), vec![[4, 4, 4]]);
        assert_eq!(o.rays_absorbed, o.rays_emitted);
        assert_eq!(o.rays_exited, 0);
        let only = |x: i64, y: i64, z: i64| [x, y, z] == [4, 4, 4];
        let o2 = trace_all(8, &only, &[src], 7, 1);
        assert_eq!(o, o2);
    }

    #[test]
    fn fast_path_matches_naive_and_conserves() {
        let mut seed = 12345u64;
        for case in 0..40 {
            let n = 2 + (lcg(&mut seed) % 7) as i64;
            let d = if case % 3 == 0 { n - 1 } else { 1 + (lcg(&mut seed) % 8) as i64 }.max(1);
            let f = (lcg(&mut seed) % 3) as u32;
            let density = lcg(&mut seed) % 40;
            let occ: Vec<bool> = (0..n * n * n).map(|_| lcg(&mut seed) % 100 < density).collect();
            let occupied = |x: i64, y: i64, z: i64| occ[(x + n * (y + n * z)) as usize];
            let nsrc = 1 + (lcg(&mut seed) % 3) as usize;
            let sources: Vec<[i64; 3]> =
                (0..nsrc).map(|_| [0; 3].map(|_| (lcg(&mut seed) % (16 * n as u64 + 8)) as i64 - 8)).collect();
            let fast = trace_all(n, &occupied, &sources, d, f);
            let naive = trace_all_naive(n, &occupied, &sources, d, f);
            assert_eq!(fast, naive, "case {case}: n={n} d={d} f={f} sources={sources:?}");
            check_conservation(&fast);
            assert_eq!(fast.rays_emitted, nsrc as u128 * rays_per_source(d, f));
            assert!(fast.lit.keys().all(|&[x, y, z]| occupied(x, y, z)));
            // Masks: each source alone lights exactly the voxels carrying its bit.
            for (i, &s) in sources.iter().enumerate() {
                let one = trace_all(n, &occupied, &[s], d, f);
                let with_bit: Vec<_> = fast.lit.iter().filter(|(_, &m)| m & (1 << i) != 0).map(|(p, _)| *p).collect();
                assert_eq!(one.lit.keys().copied().collect::<Vec<_>>(), with_bit);
            }
        }
    }

    #[test]
    fn fast_path_matches_naive_n16_f2() {
        let n = 16;
        let occ = |x: i64, y: i64, z: i64| (x * 7 + y * 3 + z * 5) % 13 == 0 || z == 1;
        let sources = [[120, 121, 119], [16 * 3 + 8, 16 * 12 - 8, 16 * 9 + 3]];
        let fast = trace_all(n, &occ, &sources, 15, 2);
        let naive = trace_all_naive(n, &occ, &sources, 15, 2);
        assert_eq!(fast, naive);
        assert!(fast.lit.values().any(|&m| m == 3));
    }

    #[test]
    fn rays_stop_after_layer_d() {
        // D = 3 in an 8³ grid from voxel (1, 1, 1): layer 3 (x = 4) is lit, layer 4 (x = 5) is not.
        let src = [p16(1); 3];
        let at = |q: [i64; 3]| move |x: i64, y: i64, z: i64| [x, y, z] == q;
        assert!(trace_all(8, &at([4, 1, 1]), &[src], 3, 1).lit.contains_key(&[4, 1, 1]));
        let o = trace_all(8, &at([5, 1, 1]), &[src], 3, 1);
        assert!(o.lit.is_empty());
        assert_eq!(o.rays_exited, o.rays_emitted);
        assert_eq!(trace_ray(8, &at([5, 1, 1]), src, 0, 0, 0, 3, 1), Fate::Exited { k: 4 });
        assert_eq!(trace_ray(8, &at([4, 1, 1]), src, 0, 0, 0, 3, 1), Fate::Absorbed { voxel: [4, 1, 1], k: 3 });
        // Leaving the grid: from voxel 6 along +x the ray is out at layer 2 (x = 8).
        assert_eq!(trace_ray(8, &|_, _, _| false, [p16(6); 3], 0, 0, 0, 7, 0), Fate::Exited { k: 2 });
    }

    #[test]
    fn source_outside_grid_emits_and_everything_exits() {
        let o = trace_all(4, &|_, _, _| true, &[[-16, 16, 16]], 3, 0);
        assert_eq!(o.rays_exited, o.rays_emitted);
        assert!(o.lit.is_empty());
    }

    #[test]
    fn timing_n16_f4() {
        let n = 16;
        let occ = |x: i64, y: i64, z: i64| (x * 7 + y * 3 + z * 5) % 11 == 0;
        let t = std::time::Instant::now();
        let o = trace_all(n, &occ, &[[120, 120, 120]], 15, 4);
        let el = t.elapsed();
        check_conservation(&o);
        assert_eq!(o.rays_emitted, 6 * 481 * 481);
        eprintln!("trace_all n=16 D=15 f=4: {:?} ({} lit)", el, o.lit.len());
        assert!(el.as_secs_f64() < 2.0, "too slow: {el:?}");
    }

    /// Rays from a light at a voxel centre are the thesis's rays; from anywhere, a ray moves
    /// at most one voxel per layer on every axis (the split's premise), and layer 1 is the
    /// source voxel's slab or the next.
    #[test]
    fn rays_from_the_light() {
        let (d, f) = (7, 1);
        let m = d << f;
        for src in [[48, 32, 80], [56, 40, 88], [52, 27, 71], [40, 41, 73]] {
            let centred = src.iter().all(|c| c % 16 == 0);
            for dir in 0..6 {
                for a in -m..=m {
                    for b in (-m..=m).step_by(3) {
                        let path: Vec<[i64; 3]> =
                            (0..=d).map(|k| ray_voxel_from_light(src, dir, a, b, d, f, k)).collect();
                        if centred {
                            let thesis: Vec<[i64; 3]> =
                                (0..=d).map(|k| ray_voxel(0, src, dir, a, b, d, f, k)).collect();
                            assert_eq!(path, thesis, "{src:?} {dir} ({a}, {b})");
                        }
                        for k in 0..d as usize {
                            let step: Vec<i64> = (0..3).map(|i| (path[k + 1][i] - path[k][i]).abs()).collect();
                            assert!(step.iter().all(|&c| c <= 1), "{src:?} {dir} ({a}, {b}) layer {k}: {path:?}");
                        }
                        let (w, s, _, _) = dir_axes(dir);
                        let first = s * (path[1][w] - source_voxel(src)[w]);
                        assert!(first == 0 || first == 1, "{src:?} {dir}: layer 1 at {first}");
                    }
                }
            }
        }
    }
}
