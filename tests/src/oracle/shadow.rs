//! Per-segment oracle of classic shadow rays under the plane principle (thesis §4.1.2 with the
//! plane rule of §5.5.6): brute force over the voxels of the segment's bounding box.
//!
//! Restated from the definitions with its own `i128` arithmetic; never calls `cell-core` (which
//! walks the segment incrementally, 6-connected, and knows each voxel's part of it from its
//! walk state). Here every occupied voxel of the box is clipped against the segment on its own.
//!
//! # Definitions
//!
//! Lattice units are 1/16 voxel; voxel v on an axis is the half-open interval
//! `[16v − 8, 16v + 8)`. A column (x, y) whose centre line meets its visible surface at depth
//! z\* = num/den emits the segment from `A = (16x, 16y, round(16·z*))` (half up) to the source
//! B (a lattice point). The surface's plane (viewer-facing, reference depth z_v) must face the
//! source, g(B) > 0, or there is no ray and the surface is in shadow.
//!
//! For each voxel V, the segment's part in V is `[t₀, t₁] = [0, 1] ∩ {t : A + t·(B − A) ∈ V}`.
//! V *meets* the segment when t₀ < t₁. An occupied V whose dexel's plane id differs from the
//! emitter's stops the segment when its plane g (see [`super::lit`]) changes sign across
//! `[t₀, t₁]` (σ = \[g > 0\] differs at t₀ and t₁):
//!
//! * from σ = 1 to σ = 0 (entering the plane's inward side): always;
//! * from σ = 0 to σ = 1 (leaving it): unless the segment is, at t₀, within one normal unit
//!   of 2¹⁴ of the emitter's own plane (`g_own(A + t₀·D) < 2¹⁴`): there it is the overhang of a
//!   neighbouring facet's voxels past a shared edge, and a ray outside a closed surface cannot
//!   leave it.
//!
//! The surface is lit iff no voxel stops its segment.
//!
//! # Under exact occluders ([`lit_exact`])
//!
//! The same facing test; then the segment from the source S to the point X₁ of the exact ray
//! to the pixel's point P = (x, y, round(4096·z\*)/4096) where the surface's plane g falls to
//! ¼ voxel (one quarter of its normal unit 2¹⁴), in units of 1/4096 voxel: X₁ = S + σ·(P − S)
//! with σ = (g(S) − ¼)/(g(S) − g(P)), each coordinate rounded half up — no segment (lit) when
//! g(S) ≤ ¼ or g(S) ≤ g(P). The surface is lit iff no triangle of the scene crosses [S, X₁]
//! ([`super::exact::segment_crosses`]): no voxel, no walk, no column.

use super::exact::{segment_crosses, Tri};
use super::lit::Surface;

/// An occupied voxel: the id of its dexel's plane and the plane ([`Surface`], `lo` the dexel's
/// first voxel).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Occupant {
    /// Plane id (equal for coplanar facets of one orientation).
    pub id: u32,
    /// The plane.
    pub plane: Surface,
}

/// The emitting surface of a column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Emitter {
    /// The column.
    pub x: i64,
    /// The column.
    pub y: i64,
    /// z\* = num / den, den > 0.
    pub num: i64,
    /// z\* = num / den, den > 0.
    pub den: i64,
    /// Its plane's id.
    pub id: u32,
    /// Its plane (viewer-facing), `lo` = z_v.
    pub plane: Surface,
}

/// `2²⁰·q·g(P/16)` for the point P = A + (p/q)·D (lattice units), with `g` the plane of `s` in
/// column (x, y): the sign of g at that point.
fn g_at(s: &Surface, x: i64, y: i64, a: [i64; 3], d: [i64; 3], p: i128, q: i128) -> i128 {
    let r = [16 * x, 16 * y, 16 * s.lo];
    // q·16·(P/16 − r/16) per axis, exactly: q·(A − r) + p·D.
    let o: Vec<i128> = (0..3).map(|i| q * (a[i] - r[i]) as i128 + p * d[i] as i128).collect();
    65536 * (s.nx as i128 * o[0] + s.ny as i128 * o[1]) + s.nz as i128 * o[2] + 1_048_576 * q * s.e as i128
}

/// A rational t = p/q, q > 0.
type T = (i128, i128);

fn less(a: T, b: T) -> bool {
    a.0 * b.1 < b.0 * a.1
}

/// The segment's part `[t₀, t₁]` in voxel v, if it meets v (t₀ < t₁).
fn part(a: [i64; 3], d: [i64; 3], v: [i64; 3]) -> Option<(T, T)> {
    let (mut t0, mut t1): (T, T) = ((0, 1), (1, 1));
    for i in 0..3 {
        let (lo, hi) = (16 * v[i] - 8, 16 * v[i] + 8);
        if d[i] == 0 {
            if !(lo..hi).contains(&a[i]) {
                return None;
            }
            continue;
        }
        // A_i + t·D_i in [lo, hi]: t between (lo − A_i)/D_i and (hi − A_i)/D_i.
        let mut e: [T; 2] = [((lo - a[i]) as i128, d[i] as i128), ((hi - a[i]) as i128, d[i] as i128)];
        for t in e.iter_mut() {
            if t.1 < 0 {
                *t = (-t.0, -t.1);
            }
        }
        let (enter, leave) = if less(e[0], e[1]) { (e[0], e[1]) } else { (e[1], e[0]) };
        if less(t0, enter) {
            t0 = enter;
        }
        if less(leave, t1) {
            t1 = leave;
        }
    }
    less(t0, t1).then_some((t0, t1))
}

/// Whether the surface of `e` is lit by the source at lattice point `b`, with the scene's
/// occupied voxels given by `occ` (see the module doc).
pub fn lit(e: &Emitter, b: [i64; 3], occ: &dyn Fn(i64, i64, i64) -> Option<Occupant>) -> bool {
    let az = (32 * e.num as i128 + e.den as i128).div_euclid(2 * e.den as i128) as i64;
    let a = [16 * e.x, 16 * e.y, az];
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    if g_at(&e.plane, e.x, e.y, b, [0; 3], 0, 1) <= 0 {
        return false;
    }
    let vox = |p: i64| (p + 8).div_euclid(16);
    let (lo, hi): (Vec<i64>, Vec<i64>) = (0..3).map(|i| (vox(a[i].min(b[i])), vox(a[i].max(b[i])))).unzip();
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                let Some(o) = occ(x, y, z) else { continue };
                if o.id == e.id {
                    continue;
                }
                let Some((t0, t1)) = part(a, d, [x, y, z]) else { continue };
                let s0 = g_at(&o.plane, x, y, a, d, t0.0, t0.1) > 0;
                let s1 = g_at(&o.plane, x, y, a, d, t1.0, t1.1) > 0;
                let stops = match (s0, s1) {
                    (true, false) => true,
                    (false, true) => g_at(&e.plane, e.x, e.y, a, d, t0.0, t0.1) >= 16384 * 1_048_576 * t0.1,
                    _ => false,
                };
                if stops {
                    return false;
                }
            }
        }
    }
    true
}

/// Whether the surface of `e` is lit by the source at lattice point `b` under exact occluders,
/// `triangles` the scene's (sixteenths; see the module doc).
pub fn lit_exact(e: &Emitter, b: [i64; 3], triangles: &[Tri]) -> bool {
    if g_at(&e.plane, e.x, e.y, b, [0; 3], 0, 1) <= 0 {
        return false;
    }
    // g in units of 2⁻¹⁴·2⁻¹⁶·2⁻¹² (a normal unit, nz's extra bits, 1/4096 voxel) at point q.
    let pl = &e.plane;
    let g = |q: [i64; 3]| {
        let d = [q[0] - 4096 * e.x, q[1] - 4096 * e.y, q[2] - 4096 * pl.lo].map(|c| c as i128);
        65536 * (pl.nx as i128 * d[0] + pl.ny as i128 * d[1]) + pl.nz as i128 * d[2] + 65536 * 4096 * pl.e as i128
    };
    let quarter = 4096i128 * 65536 * 4096;
    let pz = (2 * 4096 * e.num as i128 + e.den as i128).div_euclid(2 * e.den as i128) as i64;
    let (s, p) = (b.map(|c| 256 * c), [4096 * e.x, 4096 * e.y, pz]);
    let (gs, gp) = (g(s), g(p));
    if gs <= quarter || gs <= gp {
        return true;
    }
    let (num, den) = (gs - quarter, gs - gp);
    let x1 = [0, 1, 2].map(|i| {
        let t = num * (p[i] - s[i]) as i128;
        s[i] + (2 * t + den).div_euclid(2 * den) as i64
    });
    !triangles.iter().any(|t| segment_crosses(t, s, x1, 256))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plane y = y0 facing +y as a surface of column (·, y) with reference voxel `lo`.
    fn wall_y(y0_vox: f64, y: i64, lo: i64) -> Surface {
        Surface { lo, nx: 0, ny: 16384, nz: 0, e: (16384.0 * (y as f64 - y0_vox)).round() as i64, two_sided: false }
    }

    #[test]
    fn parts_of_an_axis_segment() {
        // From the centre of voxel 0 to the centre of voxel 3 along x: voxels 0..=3 meet it.
        let (a, d) = ([0, 0, 0], [48, 0, 0]);
        assert_eq!(part(a, d, [0, 0, 0]), Some(((0, 1), (8, 48))));
        assert_eq!(part(a, d, [3, 0, 0]), Some(((40, 48), (1, 1))));
        assert_eq!(part(a, d, [4, 0, 0]), None);
        assert_eq!(part(a, d, [1, 1, 0]), None);
    }

    #[test]
    fn an_occluding_slab_stops_and_a_leaving_overhang_does_not() {
        // Emitter: the floor z* = 2 in column (0, 0), plane facing −z (the viewer), source
        // straight "above" at z = −10 voxels.
        let floor = Surface { lo: 2, nx: 0, ny: 0, nz: -(1 << 30), e: 0, two_sided: false };
        let e = Emitter { x: 0, y: 0, num: 2, den: 1, id: 1, plane: floor };
        let b = [0, 0, -160];
        assert!(lit(&e, b, &|_, _, _| None));
        // A slab at z = −5 facing the emitter (+z): the segment enters it: stops.
        let slab = |nz: i64, lo: i64, e: i64| {
            move |_: i64, _: i64, z: i64| {
                (z == lo).then_some(Occupant { id: 2, plane: Surface { lo, nx: 0, ny: 0, nz, e, two_sided: false } })
            }
        };
        assert!(!lit(&e, b, &slab(1 << 30, -5, 0)));
        // Facing the source (−z), its plane a quarter voxel past the centre: the segment leaves
        // its inward side there, far from the floor: an open sheet seen from behind: stops.
        assert!(!lit(&e, b, &slab(-(1 << 30), -5, -(1 << 12))));
        // The same within one voxel of the floor (the overhang of a neighbour): no stop.
        assert!(lit(&e, b, &slab(-(1 << 30), 2, -(1 << 12))));
        // A source behind the floor's plane: no ray, shadow.
        assert!(!lit(&e, [0, 0, 160], &|_, _, _| None));
        // A plane the segment never crosses inside its voxel does not stop it.
        let beside = |_: i64, y: i64, z: i64| (z == -3).then_some(Occupant { id: 3, plane: wall_y(5.0, y, -3) });
        assert!(lit(&e, b, &beside));
    }
}
