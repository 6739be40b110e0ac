//! A scene triangle as the cells keep it, and the exact integer geometry on its vertices.
//!
//! Invariant: every coordinate is within [`COORD_LIMIT`] sixteenths of a voxel (checked by
//! [`Triangle::new`]), so differences stay below 2²⁴ and the cross products of the occluders
//! ([`crate::occluder`]) and of the receivers' contact tests ([`crate::receiver`]) are exact in
//! `i64`/`i128` (the bit budget of [`crate::occluder`]'s module doc). Exact occluders, thesis
//! §5.5.6.

/// Largest |coordinate| (sixteenths of a voxel) of a vertex or a ray origin (module doc's bit
/// budget).
pub const COORD_LIMIT: i64 = 1 << 23;

/// A triangle of the scene, vertices in sixteenths of a voxel (voxel centres at multiples of 16).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Triangle {
    /// The vertices, each (x, y, z), within [`COORD_LIMIT`] (checked by [`Triangle::new`]: the
    /// bit budget rests on it).
    v: [[i32; 3]; 3],
}

pub(crate) fn sub(p: [i64; 3], q: [i64; 3]) -> [i128; 3] {
    [(p[0] - q[0]) as i128, (p[1] - q[1]) as i128, (p[2] - q[2]) as i128]
}

pub(crate) fn cross(p: [i128; 3], q: [i128; 3]) -> [i128; 3] {
    [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]]
}

/// [`cross`] of vectors whose components are at most 2²⁴ in magnitude (differences of
/// coordinates within [`COORD_LIMIT`]): each product is below 2⁴⁸, each component below 2⁴⁹,
/// exact in `i64`.
pub(crate) fn cross64(p: [i64; 3], q: [i64; 3]) -> [i64; 3] {
    [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]]
}

pub(crate) fn dot(p: [i128; 3], q: [i128; 3]) -> i128 {
    p[0] * q[0] + p[1] * q[1] + p[2] * q[2]
}

impl Triangle {
    /// A triangle, if every coordinate is within [`COORD_LIMIT`].
    pub fn new(v: [[i32; 3]; 3]) -> Option<Triangle> {
        v.iter().flatten().all(|&c| (c as i64).abs() <= COORD_LIMIT).then_some(Triangle { v })
    }

    /// The vertices, each (x, y, z).
    pub const fn vertices(&self) -> [[i32; 3]; 3] {
        self.v
    }

    pub(crate) fn vertex(&self, i: usize) -> [i64; 3] {
        self.v[i].map(i64::from)
    }

    /// n = (V₁ − V₀) × (V₂ − V₀), exact: differences ≤ 2²⁴, so each product is below 2⁴⁸ and
    /// each component below 2⁴⁹, in `i64` (the module doc's bit budget).
    pub fn normal(&self) -> [i128; 3] {
        // Written out: the host's compiler kept nested array maps out of line here.
        let d = |i: usize| {
            let (p, q) = (self.v[i], self.v[0]);
            [p[0] as i64 - q[0] as i64, p[1] as i64 - q[1] as i64, p[2] as i64 - q[2] as i64]
        };
        let m = cross64(d(1), d(2));
        [m[0] as i128, m[1] as i128, m[2] as i128]
    }

    /// Whether the triangle's projection on z meets the closed square of column (x, y)
    /// (`|16x − X| ≤ 8`, `|16y − Y| ≤ 8`): the column holds a point of the triangle. Exact
    /// (separating axes: the square's two, and the triangle's edge normals, or the normal of
    /// the segment it projects to when it stands vertical).
    pub fn crosses_column(&self, x: i32, y: i32) -> bool {
        let p = self.v.map(|c| [c[0] as i64, c[1] as i64]);
        let (cx, cy) = (16 * x as i64, 16 * y as i64);
        let lo = |i: usize| p[0][i].min(p[1][i]).min(p[2][i]);
        let hi = |i: usize| p[0][i].max(p[1][i]).max(p[2][i]);
        if hi(0) < cx - 8 || lo(0) > cx + 8 || hi(1) < cy - 8 || lo(1) > cy + 8 {
            return false;
        }
        let corners = [[cx - 8, cy - 8], [cx + 8, cy - 8], [cx + 8, cy + 8], [cx - 8, cy + 8]];
        let side = |i: usize, j: usize, q: [i64; 2]| {
            (p[j][0] - p[i][0]) * (q[1] - p[i][1]) - (p[j][1] - p[i][1]) * (q[0] - p[i][0])
        };
        let area = side(0, 1, p[2]);
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            let s: [i64; 4] = corners.map(|c| side(i, j, c));
            let separated = match area.signum() {
                0 => s.iter().all(|&v| v > 0) || s.iter().all(|&v| v < 0),
                o => s.iter().all(|&v| v.signum() == -o),
            };
            if separated {
                return false;
            }
        }
        true
    }
}
