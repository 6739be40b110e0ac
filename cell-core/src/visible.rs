//! §1.3, §5.5.3 — the surface a cell's pixel shows: a depth test during loading.
//!
//! The thesis's cell shades "the first occupied voxel" of its column. With tunnel-free (thick,
//! conservative) surfaces that voxel is often not on the facet the view ray hits: the bands of
//! neighbouring facets protrude past shared edges (§5.5.3, "voxels shared by two facets") and a
//! silhouette grows by a voxel. So each cell also keeps, while the facets stream past during
//! loading, the facet its column's centre line (x, y, ·) actually meets first: a per-pixel
//! depth test of the exact facets, in the cell's own integer arithmetic.
//!
//! **Invariant: the record holds a facet the column's centre line meets, at an exact depth z\*
//! at most [`DEPTH_TIE`]⁻¹ = 1/8 voxel beyond the smallest depth at which it meets one, or
//! nothing if it meets none. A later facet replaces the record when it is nearer — by more than
//! 1/8 voxel if both have the same normal code — so the first in stream order wins ties, and
//! the record is the exact nearest whenever no two facets of one normal lie within 1/8 voxel of
//! each other on the line.**
//!
//! # The exact hit test
//!
//! The row packet at column (x, y) holds the facet's exact plane value along the column,
//! `E(z) = P + c·z` ([`crate::facet::RowPacket::column_plane`]), and its contour edges
//! `g_i + c_i·z ≥ 0` pushed out by `off_i` (the push of [`crate::facet::EdgeOff`]) for the
//! conservative contour. The centre line meets
//! the plane at `z* = −P/c` (none when c = 0: the facet contains the view direction), and the
//! point (x, y, z\*) lies on the facet iff it satisfies every edge without the push:
//! `(g_i − off_i) + c_i·z* ≥ 0`, i.e. `(g_i − off_i)·den + c_i·num ≥ 0` with z\* = num/den,
//! den > 0 — or `> 0` for an edge the host marked strict, where the world's edge lies inside
//! the lattice's ([`crate::facet::EdgeOff`]: a point exactly on a rounded edge follows the
//! unrounded mesh). (Each edge is a prism along the projection axis; a point of the plane is inside the
//! facet iff its projection is inside the projected polygon.) Depths compare by
//! cross-multiplication. Everything is exact: `|g|·|c| < 2⁸⁶`, `|c_i|·|P| < 2⁸⁸` (`i128`).
//!
//! # Coplanar facets: the depth tie
//!
//! Two facets in one plane of the world — a lamp set into its ceiling, a decal — are quantised
//! separately: each vertex moves up to 1/32 voxel per axis (the 1/16-voxel lattice), so their
//! planes, equal in the world, come out a fraction of a voxel apart along the view, either
//! way and from column to column (through the Cornell box's camera at n = 512 the ceiling came
//! out nearer over the whole of its lamp). An exact comparison then shows
//! whichever the rounding put nearer: the ceiling over its lamp. Surfaces with the same normal
//! code (the world normal's, so equal for coplanar facets) are therefore a tie within
//! 1/[`DEPTH_TIE`] voxel, and the first in stream order is kept — as the f64 reference keeps the
//! lowest facet id among hits within its rounding. Facets of different normals, which meet
//! only along edges, compare exactly: a silhouette keeps its nearer facet.
//!
//! Bits: `|num| = |P| < 2⁶³` and `den = |c| ≤ 2qM² ≤ 2⁴⁵` ([`crate::voxelize`]'s budget), so
//! the cross products are below 2¹⁰⁸, their difference times [`DEPTH_TIE`] below 2¹¹², and
//! `den·den` below 2⁹⁰: exact in `i128`.
//!
//! # What the record keeps
//!
//! z\* as the exact fraction `num/den` (16 bytes, loading only), the facet's id, material and
//! normal code (what shading needs), and its plane ([`DexelPlane`]) with the offset at the
//! centre of voxel `z_v = ⌊z*⌋`: the lighting phase tests the rays that visit voxels `z_v` and
//! `z_v + 1` of the column — the two whose centres bracket z\*, so that at least half a voxel of
//! depth lies on each side of the surface — against that plane ([`crate::lit`]). 40 bytes.
//!
//! The plane is kept **oriented toward the viewer** (g > 0 on the −z side, where the view ray
//! comes from), whatever the facet's winding: a pixel shows the side of the surface the viewer
//! sees, and that side is lit by the sources in front of it — as the exact reference and the
//! shading (both two-sided) take it. A mesh wound inside out, or an open sheet seen from its
//! back, is then lit right. The plane keeps its facet's id (the id names the geometric plane).

use crate::facet::RowPacket;
use crate::normal::NormalCode;
use crate::plane::DexelPlane;
use crate::units::{FacetId, MaterialId};

/// Surfaces of one normal code within `1/DEPTH_TIE` voxel of each other are a tie in the depth
/// test: the first is kept (see the module doc, "Coplanar facets").
pub const DEPTH_TIE: i64 = 8;

/// The surface a column's centre line meets first (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VisibleSurface {
    /// Numerator of z\* (z\* = num / den).
    pub num: i64,
    /// Denominator of z\*, > 0.
    pub den: i64,
    /// The facet met.
    pub facet: FacetId,
    /// Its material.
    pub material: MaterialId,
    /// Its normal code (for shading).
    pub normal: NormalCode,
    /// Its plane, oriented toward the viewer (see the module doc), with the offset at the centre
    /// of voxel [`VisibleSurface::z_v`].
    pub plane: DexelPlane,
    /// ⌊z\*⌋: the nearer of the two voxels that bracket the surface (−1 when z\* < 0).
    pub z_v: i32,
}

impl VisibleSurface {
    /// z\* as a float, for shading.
    pub fn depth(&self) -> f32 {
        self.num as f32 / self.den as f32
    }

    /// Whether voxel `z` is one of the two that bracket the surface (z_v or z_v + 1).
    pub fn brackets(&self, z: i64) -> bool {
        z == self.z_v as i64 || z == self.z_v as i64 + 1
    }

    /// Whether voxel `z` may hold the column's target ray under exact occluders
    /// ([`crate::receiver`]): the two bracketing voxels or the one in front of them
    /// (z_v − 1 ..= z_v + 1).
    pub fn receives(&self, z: i64) -> bool {
        (self.z_v as i64 - 1..=self.z_v as i64 + 1).contains(&z)
    }

    /// Whether the surface lies nearer the viewer than `other` (smaller z\*).
    pub fn nearer_than(&self, other: &VisibleSurface) -> bool {
        (self.num as i128) * (other.den as i128) < (other.num as i128) * (self.den as i128)
    }

    /// Whether the surface lies nearer the viewer than `other` by more than the depth tie,
    /// `1/DEPTH_TIE` voxel: `T·(z_o − z_s) > 1` ⇔ `T·(num_o·den_s − num_s·den_o) > den_s·den_o`.
    pub fn clearly_nearer_than(&self, other: &VisibleSurface) -> bool {
        let gap = (other.num as i128) * (self.den as i128) - (self.num as i128) * (other.den as i128);
        DEPTH_TIE as i128 * gap > (self.den as i128) * (other.den as i128)
    }
}

/// The exact depth z\* = num/den (den > 0) where the centre line of the packet's current column
/// meets its facet, if it does and z\* lies in `[−½, depth − ½)` (a voxel of the column holds
/// it). See the module doc.
pub fn hit(p: &RowPacket, depth: u32) -> Option<(i64, i64)> {
    if p.c == 0 {
        return None;
    }
    let col = p.column_plane();
    let (num, den) = if p.c > 0 { (col.p.checked_neg()?, p.c) } else { (col.p, p.c.checked_neg()?) };
    let (n, d) = (num as i128, den as i128);
    if 2 * n < -d || 2 * n >= (2 * depth as i128 - 1) * d {
        return None;
    }
    let inside = p.edges.iter().all(|e| {
        let v = (e.g as i128 - e.off().push() as i128) * d + e.c as i128 * n;
        if e.off().strict() {
            v > 0
        } else {
            v >= 0
        }
    });
    inside.then_some((num, den))
}

/// The record for the packet's facet if its centre line meets it (see [`hit`]).
pub fn surface_of(p: &RowPacket, depth: u32) -> Option<VisibleSurface> {
    let (num, den) = hit(p, depth)?;
    Some(record_at(p, num, den))
}

/// The record of the packet's facet at depth z\* = num/den (den > 0) of its current column: its
/// plane oriented toward the viewer, with the offset at the centre of voxel `z_v = ⌊z*⌋`.
pub fn record_at(p: &RowPacket, num: i64, den: i64) -> VisibleSurface {
    let z_v = num.div_euclid(den);
    let e = p.column_plane().value(z_v);
    let plane = p.tag.plane.dexel_plane(e);
    // E grows along c·z: c > 0 means the facet's outward side is +z, away from the viewer.
    let plane = if p.c > 0 { plane.flipped() } else { plane };
    VisibleSurface {
        num,
        den,
        facet: p.tag.facet,
        material: p.tag.material,
        normal: p.tag.normal,
        plane,
        z_v: z_v as i32,
    }
}

/// Keep the nearer of `current` and `candidate`.
///
/// ```
/// use cell_core::normal::NormalCode;
/// use cell_core::plane::DexelPlane;
/// use cell_core::visible::{depth_test, VisibleSurface};
///
/// // A surface at depth num/den, facet `facet`, facing `normal`.
/// let at = |num: i64, den: i64, facet: u32, normal: [f32; 3]| VisibleSurface {
///     num, den, facet, material: 0, normal: NormalCode::encode(normal),
///     plane: DexelPlane::default(), z_v: num.div_euclid(den) as i32,
/// };
/// let down = [0.0, -1.0, 0.0];
/// let mut record = None;
/// depth_test(&mut record, Some(at(160, 16, 1, down))); // a lamp at z* = 10
/// depth_test(&mut record, Some(at(159, 16, 2, down))); // its ceiling, 1/16 voxel nearer: a tie
/// assert_eq!(record.unwrap().facet, 1);
/// depth_test(&mut record, Some(at(157, 16, 3, down))); // 3/16 voxel nearer: replaces it
/// assert_eq!(record.unwrap().facet, 3);
/// depth_test(&mut record, Some(at(156, 16, 4, [0.0, 0.0, -1.0]))); // another normal: exact
/// assert_eq!(record.unwrap().facet, 4);
/// ```
///
/// The candidate replaces the record when it is
/// nearer, and by more than 1/[`DEPTH_TIE`] voxel when both have the same normal code (the
/// current one on a tie: first come, first kept).
pub fn depth_test(current: &mut Option<VisibleSurface>, candidate: Option<VisibleSurface>) {
    if let Some(c) = candidate {
        let nearer =
            |k: &VisibleSurface| if c.normal == k.normal { c.clearly_nearer_than(k) } else { c.nearer_than(k) };
        if current.as_ref().is_none_or(nearer) {
            *current = Some(c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(num: i64, den: i64, normal: [f32; 3]) -> VisibleSurface {
        VisibleSurface {
            num,
            den,
            facet: 0,
            material: 0,
            normal: NormalCode::encode(normal),
            plane: DexelPlane::default(),
            z_v: num.div_euclid(den) as i32,
        }
    }

    /// The tie at the bit budget's limits (`|num| < 2⁶³`, `den ≤ 2⁴⁵`, module doc): a gap of
    /// exactly 1/8 voxel is a tie, one lattice unit more is not, at the largest and smallest
    /// depths and with denominators that differ, where a wrong product would overflow `i128`
    /// or lose the unit.
    #[test]
    fn the_tie_is_exact_at_the_bit_budget() {
        const D: i64 = 1 << 45;
        let up = [0.0, 1.0, 0.0];
        for base in [i64::MAX - 4 * D, i64::MIN + 4 * D, 0, -D / 3] {
            let far = at(base, D, up);
            let eighth = D / DEPTH_TIE;
            assert!(!at(base - eighth, D, up).clearly_nearer_than(&far), "base {base}: a gap of exactly 1/8");
            assert!(at(base - eighth - 1, D, up).clearly_nearer_than(&far), "base {base}: 1/8 + 2⁻⁴⁵");
            assert!(!far.clearly_nearer_than(&at(base - eighth - 1, D, up)), "base {base}: farther");
            // The same depths over half the denominator (num halved): unchanged answers.
            if base % 2 == 0 {
                let half = at(base / 2, D / 2, up);
                assert!(!at(base - eighth, D, up).clearly_nearer_than(&half));
                assert!(at(base - eighth - 2, D, up).clearly_nearer_than(&half));
            }
        }
    }

    /// Ties only between surfaces of one normal code; otherwise the exact nearest, and the
    /// first of exactly equal depths.
    #[test]
    fn depth_test_ties_only_coplanar_surfaces() {
        let (up, side) = ([0.0, 1.0, 0.0], [1.0, 0.0, 0.0]);
        let keep = |a: VisibleSurface, b: VisibleSurface| {
            let mut r = None;
            depth_test(&mut r, Some(a));
            depth_test(&mut r, Some(b));
            r.unwrap()
        };
        let first = VisibleSurface { facet: 1, ..at(80, 8, up) };
        assert_eq!(keep(first, VisibleSurface { facet: 2, ..at(79 * 2 + 1, 16, up) }).facet, 1);
        assert_eq!(keep(first, VisibleSurface { facet: 2, ..at(79 * 2 - 1, 16, up) }).facet, 2);
        assert_eq!(keep(first, VisibleSurface { facet: 2, ..at(80 * 16 - 1, 128, side) }).facet, 2);
        assert_eq!(keep(first, VisibleSurface { facet: 2, ..at(80, 8, side) }).facet, 1);
        assert_eq!(keep(first, VisibleSurface { facet: 2, ..at(81, 8, up) }).facet, 1);
    }
}
