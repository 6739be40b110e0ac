//! §1.3, §5.5.3 — the surface a cell's pixel shows: a depth test during loading.
//!
//! The thesis's cell shades "the first occupied voxel" of its column. With tunnel-free (thick,
//! conservative) surfaces that voxel is often not on the facet the view ray hits: the bands of
//! neighbouring facets protrude past shared edges (§5.5.3, "voxels shared by two facets") and a
//! silhouette grows by a voxel. So each cell also keeps, while the facets stream past during
//! loading, the facet its column's centre line (x, y, ·) actually meets first: a per-pixel
//! depth test of the exact facets, in the cell's own integer arithmetic.
//!
//! **Invariant: the record holds the facet of the smallest exact depth z\* at which the column's
//! centre line meets a facet (ties: the first in stream order), or nothing if it meets none.**
//!
//! # The exact hit test
//!
//! The row packet at column (x, y) holds the facet's exact plane value along the column,
//! `E(z) = P + c·z` ([`crate::facet::RowPacket::column_plane`]), and its contour edges
//! `g_i + c_i·z ≥ 0` pushed out by `off_i` for the conservative contour. The centre line meets
//! the plane at `z* = −P/c` (none when c = 0: the facet contains the view direction), and the
//! point (x, y, z\*) lies on the facet iff it satisfies every edge without the push:
//! `(g_i − off_i) + c_i·z* ≥ 0`, i.e. `(g_i − off_i)·den + c_i·num ≥ 0` with z\* = num/den,
//! den > 0. (Each edge is a prism along the projection axis; a point of the plane is inside the
//! facet iff its projection is inside the projected polygon.) Depths compare by
//! cross-multiplication. Everything is exact: `|g|·|c| < 2⁸⁶`, `|c_i|·|P| < 2⁸⁸` (`i128`).
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

    /// Whether the surface lies nearer the viewer than `other` (smaller z\*).
    pub fn nearer_than(&self, other: &VisibleSurface) -> bool {
        (self.num as i128) * (other.den as i128) < (other.num as i128) * (self.den as i128)
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
    let inside = p.edges.iter().all(|e| (e.g as i128 - e.off as i128) * d + e.c as i128 * n >= 0);
    inside.then_some((num, den))
}

/// The record for the packet's facet if its centre line meets it (see [`hit`]).
pub fn surface_of(p: &RowPacket, depth: u32) -> Option<VisibleSurface> {
    let (num, den) = hit(p, depth)?;
    let z_v = num.div_euclid(den);
    let e = p.column_plane().value(z_v);
    let plane = p.tag.plane.dexel_plane(e);
    // E grows along c·z: c > 0 means the facet's outward side is +z, away from the viewer.
    let plane = if p.c > 0 { plane.flipped() } else { plane };
    Some(VisibleSurface {
        num,
        den,
        facet: p.tag.facet,
        material: p.tag.material,
        normal: p.tag.normal,
        plane,
        z_v: z_v as i32,
    })
}

/// Keep the nearer of `current` and `candidate` (the current one on a tie: first come, first
/// kept).
pub fn depth_test(current: &mut Option<VisibleSurface>, candidate: Option<VisibleSurface>) {
    if let Some(c) = candidate {
        if current.as_ref().is_none_or(|k| c.nearer_than(k)) {
            *current = Some(c);
        }
    }
}
