//! Reference walks of discrete 3D lines in f64 (thesis §2.3), for `cell_core::ray`.
//!
//! Restated from the definitions, never calling the code under test. Points are on the lattice
//! of 1/`q` voxel (`q` = 16 in the project); voxel `v` is the set of points with
//! `⌊p/q + ½⌋ = v` (round half up).
//!
//! * 26-connected: the major axis m (largest |B − A|, lowest index on ties) visits every voxel
//!   coordinate from `round(A_m)` to `round(B_m)`; the other coordinates are those of the
//!   continuous line at the voxel centre's plane, rounded half up.
//! * 18-connected: the 26 walk where a step changing all three coordinates is split: first the
//!   minor axis whose voxel boundary the segment crosses at the smaller parameter t (lowest
//!   index on ties).
//! * 6-connected: Amanatides–Woo: among the axes not yet at B's voxel, step the one whose next
//!   voxel boundary the segment reaches first (smallest t, lowest index on ties).
//!
//! Exactness: every quantity is a ratio of integers below 2⁵³, computed with one correctly
//! rounded division, so ties are exact and distinct rationals (at least 2⁻⁴⁴ apart for spans
//! up to 2²⁰ lattice units, values ≤ 2¹²) keep their order: the f64 walk is the exact walk.

/// The voxel of a lattice coordinate.
pub fn voxel(p: i64, q: i64) -> i64 {
    (p as f64 / q as f64 + 0.5).floor() as i64
}

fn major(d: [i64; 3]) -> usize {
    let mut m = 0;
    for i in 1..3 {
        if d[i].abs() > d[m].abs() {
            m = i;
        }
    }
    m
}

/// The 26-connected walk from `a` to `b` (lattice points).
pub fn walk26(a: [i64; 3], b: [i64; 3], q: i64) -> Vec<[i64; 3]> {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let m = major(d);
    let (c0, c1) = (voxel(a[m], q), voxel(b[m], q));
    if d[m] == 0 {
        return vec![a.map(|c| voxel(c, q))];
    }
    let s = if c1 >= c0 { 1 } else { -1 };
    let mut out = Vec::new();
    let mut c = c0;
    loop {
        let mut v = [0; 3];
        v[m] = c;
        for i in 0..3 {
            if i != m {
                // p_i = A_i + d_i·(c·q − A_m)/d_m, as one division.
                let num = (a[i] * d[m] + d[i] * (c * q - a[m])) as f64;
                v[i] = (num / (d[m] * q) as f64 + 0.5).floor() as i64;
            }
        }
        out.push(v);
        if c == c1 {
            break;
        }
        c += s;
    }
    out
}

/// Parameter t ∈ [0, 1] (as a float) at which the segment a → b leaves voxel coordinate `v`
/// on axis `i` toward the next voxel in its direction.
fn leave_t(a: [i64; 3], d: [i64; 3], i: usize, v: i64, q: i64) -> f64 {
    // Boundary (v ± ½)·q, in half-lattice units to stay integral.
    let boundary2 = if d[i] > 0 { 2 * v * q + q } else { 2 * v * q - q };
    (boundary2 - 2 * a[i]) as f64 / (2 * d[i]) as f64
}

/// The 18-connected walk (see the module docs).
pub fn walk18(a: [i64; 3], b: [i64; 3], q: i64) -> Vec<[i64; 3]> {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let w = walk26(a, b, q);
    let mut out = vec![w[0]];
    for pair in w.windows(2) {
        let (p, n) = (pair[0], pair[1]);
        let changed: Vec<usize> = (0..3).filter(|&i| p[i] != n[i]).collect();
        if changed.len() == 3 {
            let m = major(d);
            let minors: Vec<usize> = (0..3).filter(|&i| i != m).collect();
            let (i, j) = (minors[0], minors[1]);
            let first = if leave_t(a, d, i, p[i], q) <= leave_t(a, d, j, p[j], q) { i } else { j };
            let mut mid = p;
            mid[m] = n[m];
            mid[first] = n[first];
            out.push(mid);
        }
        out.push(n);
    }
    out
}

/// The 6-connected walk (Amanatides–Woo, see the module docs).
pub fn walk6(a: [i64; 3], b: [i64; 3], q: i64) -> Vec<[i64; 3]> {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let target = b.map(|c| voxel(c, q));
    let mut v = a.map(|c| voxel(c, q));
    let mut out = vec![v];
    loop {
        let mut best: Option<(f64, usize)> = None;
        for i in 0..3 {
            if v[i] == target[i] {
                continue;
            }
            let t = leave_t(a, d, i, v[i], q);
            if best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, i));
            }
        }
        let Some((_, i)) = best else { break };
        v[i] += d[i].signum();
        out.push(v);
    }
    out
}

/// Whether consecutive voxels of `path` are k-adjacent (k = 6, 18, 26) and distinct.
pub fn is_k_connected(path: &[[i64; 3]], k: u8) -> bool {
    let max_nonzero = match k {
        6 => 1,
        18 => 2,
        _ => 3,
    };
    path.windows(2).all(|w| {
        let d: Vec<i64> = (0..3).map(|i| w[1][i] - w[0][i]).collect();
        let nz = d.iter().filter(|c| **c != 0).count();
        d.iter().all(|c| c.abs() <= 1) && nz >= 1 && nz <= max_nonzero
    })
}
