//! §5.5.6 — the facet plane each dexel stores, for the plane-aware lit rule ([`crate::lit`]).
//!
//! A discrete surface is a staircase of voxels. The thesis's rule (a voxel is lit if one ray
//! reaches it, §5.5.5) lets the step in front of a voxel absorb the ray aimed at it, so surfaces
//! lit at a grazing angle come out dotted (§5.5.6). A cell that knows the plane of the facet that
//! owns each of its dexels can instead let a ray pass a surface voxel while the ray is still on
//! the light's side of that voxel's own plane: a planar facet cannot shadow itself.
//!
//! **Invariant: every dexel carries the plane of the facet that owns it, at a documented
//! precision, and two dexels carry the same plane id iff their facets lie in the same exact
//! plane with the same orientation.**
//!
//! # What the packet carries ([`FacetPlane`])
//!
//! The host knows each facet's exact lattice normal N = (A, B, C) (an `i128` cross product,
//! §3.6). It sends, per facet:
//!
//! * `id`: equal for facets in the same exact oriented plane (the first such facet's id), with
//!   bit 31 ([`TWO_SIDED`]) set for a facet of an open surface;
//! * the normal scaled so that its largest component is 2¹⁴: `nx = round(A·2¹⁴/m)`,
//!   `ny = round(B·2¹⁴/m)` (`i16`, |·| ≤ 2¹⁴), and `nz = round(C·2³⁰/m)` (`i32`, the z
//!   component with 16 more fraction bits, |·| ≤ 2³⁰), with `m = max(|A|, |B|, |C|)`;
//! * `m` itself (`u64`).
//!
//! Coplanar facets get the same `nx`, `ny`, `nz` whatever the length of their integer normal
//! (N = g·P for the primitive normal P, and g cancels in N/m).
//!
//! # What a dexel stores ([`DexelPlane`])
//!
//! The loading cell has, in its row packet, the exact plane value of the facet along its column,
//! `E(z) = a·x + b·y + c·z + d` in the loading units of [`crate::voxelize`]
//! ([`ColumnPlane`]). For each dexel it stores the facet's `id`, `nx`, `ny`, `nz` and
//! `e = round(E(lo)·2¹⁰/m)`: the plane's value at the centre of the dexel's first voxel `lo`,
//! in *normal units* (E is measured in units of q·N with q = 16 lattice steps per voxel, so
//! E·2¹⁴/(16·m) = E·2¹⁰/m is in units of the scaled normal). The plane function of a dexel in
//! column (x, y), for a point p in voxel units, is then
//!
//! ```text
//!   g(p) = nx·(p_x − x) + ny·(p_y − y) + (nz/2¹⁶)·(p_z − lo) + e
//! ```
//!
//! positive on the facet's outward side, and |∇g| ≈ 2¹⁴ per voxel: one normal unit is about
//! 2⁻¹⁴ voxel. The z slope keeps 16 fraction bits so that a long dexel (a plane nearly parallel
//! to z) does not drift: over 65 536 voxels the rounding of `nz` moves g by at most 2⁻¹ unit.
//!
//! # Precision and bit budget
//!
//! * Direction: each scaled component is within ½ of N·2¹⁴/m, an angular error below
//!   2⁻¹⁴·√3 rad (0.006°).
//! * Offset: `e` is within ½ unit (≈ 2⁻¹⁵ voxel) of the exact plane at the dexel's first voxel.
//! * `e`: a dexel's voxels lie in the facet's band, |E| ≤ Kσ ≤ q·(|A| + |B| + |C|)/2 ≤ 24·m
//!   (standard thickness, the thickest), so |e| ≤ 24·2¹⁰ < 2¹⁵ and |E·2¹⁰| ≤ 2⁵⁶ for
//!   m ≤ 2⁴¹ (n ≤ 65 536, [`crate::voxelize`]): `i64` for the product, `i32` for the result.
//! * A forged packet (values outside these bounds) cannot make a cell panic:
//!   [`FacetPlane::dexel_plane`] saturates.
//!
//! Bytes per dexel: 16 ([`DexelPlane`]); per packet: 20 ([`FacetPlane`]).

/// Identifier of an exact oriented plane: facets in the same plane carry the same id.
///
/// Bit 31 is [`TWO_SIDED`]; the rest (below 2³¹) names the plane.
pub type PlaneId = u32;

/// The bit of a [`PlaneId`] that marks a facet of a surface that bounds no solid (a sheet, a
/// room open to the viewer; the host decides, `meshops::open_faces`). Its winding was chosen
/// by its author or by the host's majority rule, not by an inside, so it says nothing about
/// which side light comes from: the plane lit rule reads such a plane's sides relative to each
/// source ([`crate::lit`], "two-sided planes") instead of reading its winding as the outward
/// side. Facets of solids keep their outward winding. It costs no byte: facet ids stay below
/// 2³¹.
pub const TWO_SIDED: PlaneId = 1 << 31;

/// Largest |nx|, |ny|: the scaled normal's largest component.
pub const NORMAL_SCALE: i32 = 1 << 14;

/// Fraction bits of the z slope `nz` beyond those of `nx`, `ny`.
pub const NZ_FRAC_BITS: u32 = 16;

/// Largest |nz| (the z component with [`NZ_FRAC_BITS`] more fraction bits).
pub const NZ_MAX: i32 = 1 << 30;

/// Largest scale divisor `m` a packet may carry (the largest normal component of a facet
/// within the loading bit budget of [`crate::voxelize`]: 2·M² with M = 2²⁰).
pub const M_MAX: u64 = 1 << 41;

/// A facet's plane as the host sends it with every packet (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FacetPlane {
    /// Equal for facets in the same exact oriented plane.
    pub id: PlaneId,
    /// x component of the normal scaled to a largest component of 2¹⁴.
    pub nx: i16,
    /// y component, same scale.
    pub ny: i16,
    /// z component, same scale, with 16 more fraction bits.
    pub nz: i32,
    /// The largest |component| of the exact lattice normal (the scale divisor), ≥ 1.
    pub m: u64,
}

/// The plane a dexel stores (see the module doc): 16 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DexelPlane {
    /// Equal for dexels of facets in the same exact oriented plane.
    pub id: PlaneId,
    /// x component of the scaled normal.
    pub nx: i16,
    /// y component of the scaled normal.
    pub ny: i16,
    /// z component of the scaled normal, 16 more fraction bits.
    pub nz: i32,
    /// The plane's value at the centre of the dexel's first voxel, in normal units.
    pub e: i32,
}

impl DexelPlane {
    /// Whether the plane is a facet of an open surface ([`TWO_SIDED`]).
    pub const fn two_sided(&self) -> bool {
        self.id & TWO_SIDED != 0
    }

    /// The same plane with the other orientation (g → −g), the same id. Exact: every field
    /// is within ±2³⁰ (or a saturated `e`, negated within `i32`).
    pub const fn flipped(&self) -> DexelPlane {
        DexelPlane { id: self.id, nx: -self.nx, ny: -self.ny, nz: -self.nz, e: self.e.saturating_neg() }
    }
}

/// The exact plane value of a facet along one column, `E(z) = p + c·z`, in the loading units of
/// [`crate::voxelize`] (what the row packet holds at that column).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct ColumnPlane {
    /// E at z = 0 (`a·x + b·y + d`).
    pub p: i64,
    /// The z coefficient `c`.
    pub c: i64,
}

impl ColumnPlane {
    /// E(z). Wrapping arithmetic: exact whenever E(z) itself fits `i64` (always at the voxels
    /// of a dexel, whose values lie in the band), whatever the intermediate terms.
    pub const fn value(&self, z: i64) -> i64 {
        self.p.wrapping_add(self.c.wrapping_mul(z))
    }
}

impl FacetPlane {
    /// Whether the fields are within the bounds of the module doc (a packet decoder refuses
    /// others).
    pub const fn in_budget(&self) -> bool {
        self.m >= 1
            && self.m <= M_MAX
            && (self.nx as i32).abs() <= NORMAL_SCALE
            && (self.ny as i32).abs() <= NORMAL_SCALE
            && self.nz.unsigned_abs() <= NZ_MAX as u32
    }

    /// The plane a dexel stores when its first voxel has exact plane value `e_exact`:
    /// `e = round(e_exact·2¹⁰/m)` (half away from zero), saturated to `i32` (only a forged packet
    /// gets there).
    pub fn dexel_plane(&self, e_exact: i64) -> DexelPlane {
        let m = self.m.max(1) as i128;
        let num = (e_exact as i128) << 10;
        let q = (2 * num.abs() + m) / (2 * m);
        let e = if num < 0 { -q } else { q };
        DexelPlane {
            id: self.id,
            nx: self.nx,
            ny: self.ny,
            nz: self.nz,
            e: e.clamp(i32::MIN as i128, i32::MAX as i128) as i32,
        }
    }
}

/// The scaled normal of an exact integer normal (the host's side of the module doc):
/// `(nx, ny, nz, m)`, or `None` for a zero normal or one beyond ±2⁹⁰ (the rounding below
/// shifts remainders by 31 bits in `i128`).
pub fn scale_normal(n: [i128; 3]) -> Option<(i16, i16, i32, u64)> {
    let m = n.iter().map(|v| v.unsigned_abs()).max()?;
    if m == 0 || m > 1u128 << 90 {
        return None;
    }
    let m = m as i128;
    // round(v·2^k/m), half away from zero; |v| ≤ m so the results are within ±2^k.
    let round = |v: i128, k: u32| -> i128 {
        // Divide first (|v| ≤ m, so q is 0 or 1), then round the remainder: r·2^(k+1) < 2^121.
        let (q, r) = (v.abs() / m, v.abs() % m);
        let scaled = (q << k) + (((r << (k + 1)) / m + 1) >> 1);
        if v < 0 {
            -scaled
        } else {
            scaled
        }
    };
    let nx = round(n[0], 14) as i16;
    let ny = round(n[1], 14) as i16;
    let nz = round(n[2], 14 + NZ_FRAC_BITS) as i32;
    // `m` itself must fit the packet's u64 (any normal of a facet within the grid does).
    let m = u64::try_from(m).ok()?;
    Some((nx, ny, nz, m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_normals_of_axis_planes_are_exact() {
        assert_eq!(scale_normal([0, 0, 7]), Some((0, 0, 1 << 30, 7)));
        assert_eq!(scale_normal([-3, 0, 0]), Some((-(1 << 14), 0, 0, 3)));
        assert_eq!(scale_normal([0, 5, 0]), Some((0, 1 << 14, 0, 5)));
        assert_eq!(scale_normal([0, 0, 0]), None);
    }

    #[test]
    fn coplanar_normals_scale_alike() {
        // N = g·P for several g: the same scaled normal.
        let p = [3i128, -7, 11];
        let want = scale_normal(p).unwrap();
        for g in [2i128, 5, 1 << 20, 123_456_789] {
            let (nx, ny, nz, m) = scale_normal(p.map(|v| v * g)).unwrap();
            assert_eq!((nx, ny, nz), (want.0, want.1, want.2), "g = {g}");
            assert_eq!(m as i128, 11 * g);
        }
    }

    #[test]
    fn rounding_matches_f64_within_half_a_unit() {
        let mut s = 0x2545F4914F6CDD1Du64;
        for _ in 0..2000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let v = |k: u64| (((s >> k) & 0xFFFF_FFFF) as i64 - (1 << 31)) as i128;
            let n = [v(0), v(11), v(23)];
            let (nx, ny, nz, m) = scale_normal(n).unwrap();
            let m = m as f64;
            assert!((nx as f64 - n[0] as f64 * 16384.0 / m).abs() <= 0.5 + 1e-9);
            assert!((ny as f64 - n[1] as f64 * 16384.0 / m).abs() <= 0.5 + 1e-9);
            assert!((nz as f64 - n[2] as f64 * 1073741824.0 / m).abs() <= 0.5 + 1e-6);
        }
    }

    #[test]
    fn dexel_offset_rounds_and_saturates() {
        let f = FacetPlane { id: 1, nx: 0, ny: 0, nz: 1 << 30, m: 3 };
        // E·2^10/3: 1 → 341.33 → 341; 2 → 682.67 → 683; −2 → −683.
        assert_eq!(f.dexel_plane(1).e, 341);
        assert_eq!(f.dexel_plane(2).e, 683);
        assert_eq!(f.dexel_plane(-2).e, -683);
        assert_eq!(f.dexel_plane(i64::MAX).e, i32::MAX);
        assert_eq!(f.dexel_plane(i64::MIN).e, i32::MIN);
        let zero_m = FacetPlane { m: 0, ..f };
        assert!(!zero_m.in_budget());
        assert_eq!(zero_m.dexel_plane(5).e, 5 << 10);
    }
}
