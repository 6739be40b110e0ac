//! Tunnel counting oracle ("armoured" surfaces, thesis §3.8).
//!
//! A **k-tunnel** (k ∈ {6, 18, 26}) through a voxelized surface is an unordered pair of
//! k-adjacent voxels `{p, p + δ}` such that
//! * both lie in the inclusive box `[lo, hi]`,
//! * neither is occupied, and
//! * the surface's signed side function changes sign strictly between them:
//!   `side(p) < 0 < side(p + δ)` or `side(p) > 0 > side(p + δ)`.
//!
//! Such a pair is one step of a discrete k-connected line that crosses from one side of the
//! (continuous) surface to the other without meeting an occupied voxel. A surface is
//! k-tunnel-free on the box iff the count is 0.
//!
//! Adjacency: δ ranges over the non-zero vectors of {−1, 0, 1}³ with at most 1 (k = 6), 2
//! (k = 18) or 3 (k = 26) non-zero components; each unordered pair is counted once.
//!
//! Not counted: an unoccupied voxel whose centre lies exactly on the surface (`side == 0`);
//! that is a hole in the band, not a sign change, and shows up in a band check instead.
//!
//! [`plane_side`] gives the side function of a plane: `E = N·(M − P0)` at voxel centres `M`
//! (lattice units, centre of voxel `v` at `q·v + q/2`), exact `i128`.

/// The half-neighbourhood of a connectivity: every δ of the k-neighbourhood that is
/// lexicographically positive (so each unordered pair is visited once).
///
/// # Panics
/// If `connectivity` is not 6, 18 or 26 (a caller bug, not a geometric degeneracy).
pub fn half_neighbourhood(connectivity: u8) -> Vec<[i64; 3]> {
    let max_nonzero = match connectivity {
        6 => 1,
        18 => 2,
        26 => 3,
        k => panic!("connectivity must be 6, 18 or 26, got {k}"),
    };
    let mut out = Vec::new();
    for dx in -1..=1i64 {
        for dy in -1..=1i64 {
            for dz in -1..=1i64 {
                let d = [dx, dy, dz];
                let nz = d.iter().filter(|c| **c != 0).count();
                if nz == 0 || nz > max_nonzero {
                    continue;
                }
                if d > [0, 0, 0] {
                    out.push(d);
                }
            }
        }
    }
    out
}

/// Every k-tunnel pair `(p, p + δ)` in the box (see the module docs), `p` lexicographically
/// smaller, sorted.
pub fn find_tunnels(
    occupied: &dyn Fn([i64; 3]) -> bool,
    side: &dyn Fn([i64; 3]) -> i128,
    lo: [i64; 3],
    hi: [i64; 3],
    connectivity: u8,
) -> Vec<([i64; 3], [i64; 3])> {
    let deltas = half_neighbourhood(connectivity);
    if (0..3).any(|i| lo[i] > hi[i]) {
        return Vec::new();
    }
    let dim = [(hi[0] - lo[0] + 1) as usize, (hi[1] - lo[1] + 1) as usize, (hi[2] - lo[2] + 1) as usize];
    let idx = |p: [i64; 3]| -> usize {
        (p[0] - lo[0]) as usize + dim[0] * ((p[1] - lo[1]) as usize + dim[1] * (p[2] - lo[2]) as usize)
    };
    // Cache: sign of the side function for unoccupied voxels, None for occupied ones.
    let mut cache: Vec<Option<i8>> = vec![None; dim[0] * dim[1] * dim[2]];
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                let p = [x, y, z];
                if !occupied(p) {
                    cache[idx(p)] = Some(side(p).signum() as i8);
                }
            }
        }
    }
    let mut out = Vec::new();
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                let p = [x, y, z];
                let Some(sp) = cache[idx(p)] else { continue };
                if sp == 0 {
                    continue;
                }
                for d in &deltas {
                    let r = [x + d[0], y + d[1], z + d[2]];
                    if (0..3).any(|i| r[i] < lo[i] || r[i] > hi[i]) {
                        continue;
                    }
                    if let Some(sr) = cache[idx(r)] {
                        if sr == -sp {
                            out.push((p, r));
                        }
                    }
                }
            }
        }
    }
    out.sort_unstable();
    out
}

/// The number of k-tunnel pairs in the box (see the module docs).
///
/// # Panics
/// If `connectivity` is not 6, 18 or 26.
pub fn count_tunnels(
    occupied: &dyn Fn([i64; 3]) -> bool,
    side: &dyn Fn([i64; 3]) -> i128,
    lo: [i64; 3],
    hi: [i64; 3],
    connectivity: u8,
) -> usize {
    find_tunnels(occupied, side, lo, hi, connectivity).len()
}

/// Side function of the plane through lattice point `p0` with normal `n`: `E = N·(M − P0)` at
/// the centre `M = q·v + q/2` of voxel `v`.
pub fn plane_side(n: [i64; 3], p0: [i64; 3], q: i64) -> impl Fn([i64; 3]) -> i128 {
    let n = n.map(|c| c as i128);
    let p0 = p0.map(|c| c as i128);
    let q = q as i128;
    move |v: [i64; 3]| (0..3).map(|i| n[i] * (q * v[i] as i128 + q / 2 - p0[i])).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oracle::brute::tests::Rng;

    const Q: i64 = 16;

    /// Occupancy of an infinite plane band of full width `w` in normal units:
    /// occupied iff `2|E| ≤ q·w` (w = K naive, |a|+|b|+|c| standard, 2Kσ thesis).
    fn band(n: [i64; 3], p0: [i64; 3], w: i128) -> impl Fn([i64; 3]) -> bool {
        let side = plane_side(n, p0, Q);
        move |v| 2 * side(v).abs() <= Q as i128 * w
    }

    #[test]
    fn neighbourhood_sizes() {
        assert_eq!(half_neighbourhood(6).len(), 3);
        assert_eq!(half_neighbourhood(18).len(), 9);
        assert_eq!(half_neighbourhood(26).len(), 13);
    }

    #[test]
    #[should_panic(expected = "connectivity")]
    fn bad_connectivity_panics() {
        half_neighbourhood(8);
    }

    #[test]
    fn hand_counted_pairs_across_an_empty_plane() {
        // Nothing occupied; the plane x = 1 (lattice 16) separates voxel layer 0 from layer 1.
        let none = |_: [i64; 3]| false;
        let side = plane_side([1, 0, 0], [16, 0, 0], Q);
        assert_eq!(count_tunnels(&none, &side, [0, 0, 0], [1, 0, 0], 6), 1);
        // 2×2×2 box: each of the 4 voxels at x = 0 sees 1 (6), 3 (18), 4 (26) voxels at x = 1.
        assert_eq!(count_tunnels(&none, &side, [0, 0, 0], [1, 1, 1], 6), 4);
        assert_eq!(count_tunnels(&none, &side, [0, 0, 0], [1, 1, 1], 18), 12);
        assert_eq!(count_tunnels(&none, &side, [0, 0, 0], [1, 1, 1], 26), 16);
        // Occupying one of the two voxels kills the pair.
        let one = |p: [i64; 3]| p == [1, 0, 0];
        assert_eq!(count_tunnels(&one, &side, [0, 0, 0], [1, 0, 0], 6), 0);
        // An empty box counts nothing.
        assert_eq!(count_tunnels(&none, &side, [1, 0, 0], [0, 0, 0], 26), 0);
    }

    #[test]
    fn naive_plane_1_0_m2_has_26_tunnels_but_no_6_tunnels() {
        // N = (1, 0, −2), P0 = lattice origin: E/q = x − 2z − ½ (half-integer, generic).
        let n = [1, 0, -2];
        let p0 = [0, 0, 0];
        let side = plane_side(n, p0, Q);
        let (lo, hi) = ([-8; 3], [8; 3]);
        let naive = band(n, p0, 2); // K = 2
        assert_eq!(count_tunnels(&naive, &side, lo, hi, 6), 0);
        let t18 = count_tunnels(&naive, &side, lo, hi, 18);
        let t26 = count_tunnels(&naive, &side, lo, hi, 26);
        assert!(t18 > 0 && t26 >= t18, "18: {t18}, 26: {t26}");
        // A concrete one: E/q(−1, 0, 0) = −1.5 and E/q(0, 0, −1) = +1.5, both outside the
        // band |E/q| ≤ 1, one 18-step δ = (1, 0, −1) apart.
        let pairs = find_tunnels(&naive, &side, lo, hi, 18);
        assert!(pairs.contains(&([-1, 0, 0], [0, 0, -1])));
        let standard = band(n, p0, 3); // |a| + |b| + |c|
        assert_eq!(count_tunnels(&standard, &side, lo, hi, 26), 0);
    }

    #[test]
    fn thesis_sigma_for_normal_321_leaks_26_at_integer_offset() {
        // N = (3, 2, 1), Kσ = 2.5 → thesis full width 5 (in units of q·|E| scale).
        let n = [3, 2, 1];
        let (lo, hi) = ([-6; 3], [6; 3]);
        // Integer offset (P0 at a voxel centre): E/q = 3x + 2y + z.
        let p0 = [8, 8, 8];
        let side = plane_side(n, p0, Q);
        let thesis = band(n, p0, 5);
        let t26 = find_tunnels(&thesis, &side, lo, hi, 26);
        assert!(!t26.is_empty());
        // Every 26-tunnel jumps from level −3 to +3 along δ = ±(1, 1, 1).
        for (a, b) in &t26 {
            assert_eq!([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [1, 1, 1]);
        }
        assert_eq!(count_tunnels(&thesis, &side, lo, hi, 18), 0);
        let standard = band(n, p0, 6);
        assert_eq!(count_tunnels(&standard, &side, lo, hi, 26), 0);
        // Half-integer offset: the thesis band keeps 6 levels and is tunnel-free.
        let p0 = [16, 8, 8];
        let side = plane_side(n, p0, Q);
        assert_eq!(count_tunnels(&band(n, p0, 5), &side, lo, hi, 26), 0);
    }

    #[test]
    fn random_planes_obey_the_textbook_theorems() {
        // Naive planes (width K) have no 6-tunnels; standard planes (width |a|+|b|+|c|) have no
        // 26-tunnels — whatever the normal and offset. Validates the counter itself.
        let mut rng = Rng(0xabad_1dea);
        let (lo, hi) = ([-4; 3], [4; 3]);
        let mut naive_26 = 0;
        for _ in 0..200 {
            let n = [rng.range(-5, 5), rng.range(-5, 5), rng.range(-5, 5)];
            if n == [0, 0, 0] {
                continue;
            }
            let p0 = [rng.range(-20, 20), rng.range(-20, 20), rng.range(-20, 20)];
            let side = plane_side(n, p0, Q);
            let k = n.iter().map(|c| c.abs()).max().unwrap() as i128;
            let sum = n.iter().map(|c| c.abs()).sum::<i64>() as i128;
            assert_eq!(count_tunnels(&band(n, p0, k), &side, lo, hi, 6), 0, "{n:?} {p0:?}");
            assert_eq!(count_tunnels(&band(n, p0, sum), &side, lo, hi, 26), 0, "{n:?} {p0:?}");
            naive_26 += count_tunnels(&band(n, p0, k), &side, lo, hi, 26);
        }
        assert!(naive_26 > 0, "naive planes do have 26-tunnels somewhere");
    }
}
