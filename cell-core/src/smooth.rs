//! §1.3.2 — smooth shading: the vertex normals of a facet interpolated over it (Phong), or the
//! colours shaded with them (Gouraud), at the point the column's centre line meets the facet.
//!
//! # What travels and what a cell keeps
//!
//! * **The packet's extension** ([`VertexNormals`], 6 bytes): the unit normal of each of a
//!   triangle's three vertices as a 16-bit octahedral [`NormalCode`] (8 bits per octahedral
//!   coordinate, the dexel's own code: angular error below 1°, [`crate::normal`]). Vertex k is
//!   the start of contour edge k (the host writes the edges in vertex order).
//! * **The cell's record** ([`SmoothSurface`], 12 bytes): the three codes and the barycentric
//!   weights of the visible point, 16 bits each.
//!
//! # The weights, exactly from the packet
//!
//! The packet's contour edge i (from vertex i to vertex i + 1, [`crate::facet`]) holds, at the
//! current column, `F_i(z) = (g_i − push_i) + c_i·z`: the projected cross product
//! `(V_{i+1} − V_i) × (M − V_i)`, i.e. twice the projected area of the triangle (V_i, V_{i+1}, M)
//! at the point M = (x, y, z) of the facet's plane, all three to the same scale. So the
//! barycentric coordinate of vertex i + 2 (the one opposite edge i) is `F_i / (F_0 + F_1 + F_2)`
//! — a projection along an axis keeps barycentric coordinates of points of the plane. At the
//! visible point z\* = num/den ([`crate::visible`]) the cell evaluates `F_i·den =
//! (g_i − push_i)·den + c_i·num` exactly in `i128` (below 2⁸⁹: [`crate::visible`]'s budget), clamps
//! the negative ones to 0 (a point a rounded edge leaves just outside) and rounds each weight to
//! 16 bits: `W_k = round(65535·F/ΣF)` (`65535·2·F < 2¹⁰⁷`, exact).
//!
//! **Error bound** (tested at its limits in `tests/tests/integration/smooth.rs`): each weight is
//! within ½ of 65535·λ_k, their sum within 1.5 of 65535, and the cell uses `λ̃_k = W_k / ΣW`, so
//! `|λ̃_k − λ_k| ≤ 1.5/65533.5 + 0.5/65535 < 3.1·10⁻⁵`; each decoded unit normal is within the
//! octahedral code's angle δ < 1° of the exact one. The interpolated sum `Σ λ̃_k ñ_k` is then
//! within `e = 3·3.1·10⁻⁵ + 2·sin(δ/2)` (≈ 0.0175) of the exact `Σ λ_k n_k`, and the normalised
//! normal within `asin(e / |Σ λ_k n_k|)` of the exact one (1.0° for vertex normals that agree,
//! 2.0° where they spread so that `|Σ λ_k n_k|` = ½).
//!
//! # Shading
//!
//! The vertex normals are turned to the side of the facet the eye sees (all three flipped when
//! the facet's own normal code faces away from the eye). **Phong**: `N = normalise(Σ λ̃_k n_k)`
//! (the facet normal where that sum vanishes), shaded once ([`crate::shade`]'s formula). **Gouraud**
//! in rc2 is the same interpolation of colours instead of normals: `c = Σ λ̃_k shade(p, n_k)`,
//! each shaded at the visible point p (a cell knows its own point, not the vertices', and which
//! lights reach p, not the vertices: per-pixel shadows), so highlights inside a facet are averaged
//! rather than evaluated. In both the lights a pixel lists as lighting it are those that reached
//! it ([`crate::lit`]) and that the interpolated normal faces.

use crate::facet::RowPacket;
use crate::light::SourceMask;
use crate::normal::NormalCode;
use crate::shade::{
    dot, encode, facing_mask, normalise, shade_linear_toward, surface_point, Material, Pixel, PointLight, ShadeParams,
};
use crate::visible::VisibleSurface;

/// The smooth shading modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Smooth {
    /// Interpolate the normal, then shade (Phong 1975).
    Phong,
    /// Shade with each vertex normal, then interpolate the colour (Gouraud 1971).
    Gouraud,
}

/// The vertex normals a facet packet carries (see the module doc): vertex k starts edge k.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VertexNormals(pub [NormalCode; 3]);

/// Bits of one vertex normal in the packet: 8 per octahedral coordinate.
pub const BITS_PER_NORMAL: u32 = 16;
/// Bits of one barycentric weight in the cell's record.
pub const BITS_PER_WEIGHT: u32 = 16;
/// A weight of 1.
pub const WEIGHT_ONE: u16 = u16::MAX;

/// What a cell keeps for its visible point (see the module doc), 12 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SmoothSurface {
    /// The facet's vertex normals.
    pub normals: [NormalCode; 3],
    /// The visible point's barycentric weights, `WEIGHT_ONE` = 1 (their sum is within 2 of it).
    pub weights: [u16; 3],
}

/// The barycentric weights of the point z = num/den (den > 0) of the packet's current column,
/// 16 bits each (see the module doc). `None` unless the packet is a triangle (three edges) and
/// the point is not outside all of them.
///
/// ```
/// use cell_core::facet::{FacetBox, RowEdge, RowPacket};
/// use cell_core::smooth::weights;
///
/// // A triangle whose edges, at this column, have F_0 = 16, F_1 = 16, F_2 = 32 (no z term):
/// // vertex 0 (opposite edge 1) weighs 16/64, vertex 1 (opposite edge 2) 32/64, vertex 2 16/64.
/// let mut p = RowPacket {
///     tag: Default::default(),
///     bbox: FacetBox { x_min: 0, x_max: 8, y_min: 0, y_max: 8, z_min: 0, z_max: 0 },
///     a: 0, c: 1, t: 0, u: 0, edges: Default::default(),
/// };
/// for g in [16, 16, 32] {
///     p.edges.push(RowEdge { a: 0, c: 0, g, off: 0 }).unwrap();
/// }
/// assert_eq!(weights(&p, 0, 1), Some([16384, 32768, 16384]));
/// ```
pub fn weights(p: &RowPacket, num: i64, den: i64) -> Option<[u16; 3]> {
    if p.edges.len() != 3 || den <= 0 {
        return None;
    }
    let f: [i128; 3] = core::array::from_fn(|i| {
        let e = &p.edges[i];
        let v = (e.g as i128 - e.off().push() as i128) * den as i128 + e.c as i128 * num as i128;
        v.max(0)
    });
    let sum = f[0] + f[1] + f[2];
    if sum <= 0 {
        return None;
    }
    // Vertex k is opposite edge k + 1.
    let one = WEIGHT_ONE as i128;
    Some(core::array::from_fn(|k| ((2 * one * f[(k + 1) % 3] + sum) / (2 * sum)) as u16))
}

/// The record of the packet's facet at the point z = num/den of its current column: its vertex
/// normals and the point's weights; a facet that is not a triangle (the host sends polygons only
/// when their vertex normals are equal) keeps its first vertex normal with weight 1.
pub fn record(p: &RowPacket, normals: VertexNormals, num: i64, den: i64) -> SmoothSurface {
    let weights = weights(p, num, den).unwrap_or([WEIGHT_ONE, 0, 0]);
    SmoothSurface { normals: normals.0, weights }
}

impl SmoothSurface {
    /// The weights as fractions summing to 1, `λ̃_k = W_k / ΣW`.
    pub fn lambdas(&self) -> [f32; 3] {
        let sum = self.weights.iter().map(|&w| w as u32).sum::<u32>().max(1) as f32;
        self.weights.map(|w| w as f32 / sum)
    }

    /// The unit vertex normals turned to the side of the facet (normal code `facet`) that `v`
    /// (the unit direction to the eye) sees.
    pub fn unit_normals(&self, facet: NormalCode, v: [f32; 3]) -> [[f32; 3]; 3] {
        let s = if dot(facet.decode(), v) < 0.0 { -1.0 } else { 1.0 };
        self.normals.map(|c| normalise(c.decode()).map(|x| s * x))
    }

    /// The Phong normal: the interpolated vertex normals, normalised; the facet's normal turned
    /// toward `v` where they cancel.
    pub fn phong_normal(&self, facet: NormalCode, v: [f32; 3]) -> [f32; 3] {
        let (n, l) = (self.unit_normals(facet, v), self.lambdas());
        let sum: [f32; 3] = core::array::from_fn(|i| l[0] * n[0][i] + l[1] * n[1][i] + l[2] * n[2][i]);
        let n = normalise(sum);
        if n == [0.0; 3] {
            crate::shade::shading_normal_toward(facet, crate::shade::NormalMode::Facet, v)
        } else {
            n
        }
    }
}

/// The pixel of column (x, y) under the plane rule with smooth normals: as
/// [`crate::shade::surface_pixel`], shaded as `mode` says (see the module doc) from the cell's
/// record `smooth` of its visible surface.
#[allow(clippy::too_many_arguments)]
pub fn smooth_pixel(
    x: crate::units::Coord,
    y: crate::units::Coord,
    surface: &VisibleSurface,
    smooth: &SmoothSurface,
    mode: Smooth,
    reached: SourceMask,
    materials: &[Material],
    lights: &[PointLight],
    params: &ShadeParams,
) -> Pixel {
    let (p, v, m) = surface_point(x, y, surface, materials, params);
    let nrm = smooth.phong_normal(surface.normal, v);
    let lit = facing_mask(p, nrm, lights, reached);
    let c = match mode {
        Smooth::Phong => shade_linear_toward(p, nrm, v, &m, lights, lit, params),
        Smooth::Gouraud => {
            let (n, l) = (smooth.unit_normals(surface.normal, v), smooth.lambdas());
            let mut c = [0.0f32; 3];
            for k in 0..3 {
                let ck = shade_linear_toward(p, n[k], v, &m, lights, lit, params);
                for (ci, cki) in c.iter_mut().zip(ck) {
                    *ci += l[k] * cki;
                }
            }
            c
        }
    };
    Pixel { rgb: c.map(encode), lit, z: surface.z_v.clamp(0, u16::MAX as i32) as u16 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::facet::{FacetBox, RowEdge};

    fn packet(edges: &[(i32, i32, i64, i32)]) -> RowPacket {
        let mut p = RowPacket {
            tag: Default::default(),
            bbox: FacetBox { x_min: 0, x_max: 0, y_min: 0, y_max: 0, z_min: 0, z_max: 0 },
            a: 0,
            c: 1,
            t: 0,
            u: 0,
            edges: Default::default(),
        };
        for &(a, c, g, off) in edges {
            p.edges.push(RowEdge { a, c, g, off }).unwrap();
        }
        p
    }

    /// The pushed-out edges of conservative mode are taken back, a point outside one edge
    /// gets weight 0 there, and a packet that is not a triangle gets none.
    #[test]
    fn push_clamp_and_polygons() {
        // F = g − push: 10, 30, 60 → vertex 0 gets F_1 = 30/100, 1 gets F_2 = 60/100, 2 gets F_0.
        let p = packet(&[(0, 0, 10 + 8, 8), (0, 0, 30 + 16, 16 | 1), (0, 0, 60, 0)]);
        assert_eq!(weights(&p, 0, 1), Some([19661, 39321, 6554]));
        let outside = packet(&[(0, 0, -5, 0), (0, 0, 50, 0), (0, 0, 50, 0)]);
        assert_eq!(weights(&outside, 0, 1), Some([32768, 32768, 0]));
        let quad = packet(&[(0, 0, 1, 0); 4]);
        assert_eq!(weights(&quad, 0, 1), None);
        let n = VertexNormals([NormalCode::encode([1.0, 0.0, 0.0]); 3]);
        assert_eq!(record(&quad, n, 0, 1).weights, [WEIGHT_ONE, 0, 0]);
    }

    /// The depth enters through c_i·num/den: F_i·den = (g − push)·den + c_i·num.
    #[test]
    fn depth_enters_exactly() {
        // F_0 = 2z, F_1 = 4 − z... at z = 4/3 (num 4, den 3): 8/3, 8/3, 8/3 → equal thirds.
        let p = packet(&[(0, 2, 0, 0), (0, -1, 4, 0), (0, -1, 4, 0)]);
        assert_eq!(weights(&p, 4, 3), Some([21845, 21845, 21845]));
    }
}
