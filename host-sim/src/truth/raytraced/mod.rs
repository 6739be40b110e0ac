//! Form factors by tracing from a point toward the source (radiosity thesis, ch. 3): the
//! form factor from a receiving point (a vertex of the scene, with its surface's normal) to a
//! convex planar source, with its occlusion by the scene's triangles.
//!
//! * [`wallace`] — Wallace's source sampling (§3.1): the source cut into elements of equal
//!   area, one ray per element, each visible element counted by the disc formula
//!   `a cosθ₁ cosθ₂ / (π d² + a)` (§3.1.3); uniform, jittered, or adaptive (§3.1.4, Fig. 3.3).
//! * [`beam`] — the thesis's beam toward the source (§3.4.2): one pyramid from the point to
//!   the source, the candidate occluders found by outcodes against its planes (with a clipping
//!   test where outcodes cannot tell, Fig. 3.14) and sorted by distance, the beam cut in four
//!   while a candidate covers it partly (down to level 4: 256 sub-beams), and each visible
//!   sub-beam's form factor taken analytically (the contour integral, Eq. 2.2).
//!
//! Both test every triangle, with no acceleration structure: the thesis compares them that
//! way (§3.4.2, "Perspectives"), so their time ratio (Table 3.2) is the algorithms' own.
//! Occluders are triangles (the thesis's convex polygons, triangulated): a beam a quadrilateral
//! covers wholly, but no one of its two triangles does, is cut along their shared diagonal.
//!
//! Conventions shared by both: a receiver behind the source's plane, or a source wholly behind
//! the receiver's tangent plane, gets 0; the source is clipped to the receiver's front
//! half-space first ([`Source::front`]). A ray from the receiver to a point of the source is
//! blocked by a triangle it meets strictly inside the segment (parameter in `(ε, 1 − ε)`,
//! [`SEGMENT_TOL`]), the triangle's edges included: the receiver's own facets (met at the
//! start) and the source's neighbours in its plane (met at the end) never block.

pub mod beam;
pub mod wallace;

use anyhow::{bail, Result};
use parry3d_f64::math::Vector;

use crate::scene::patches::area_vector;
pub(crate) use crate::truth::closed_form::clip;

/// A hit closer than this fraction of the segment to either end does not block it.
pub const SEGMENT_TOL: f64 = 1e-9;

/// A receiving point: a vertex of the scene and the unit normal of the surface it is on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Receiver {
    /// The point (world units).
    pub point: Vector,
    /// Its surface's unit normal: the side it receives on.
    pub normal: Vector,
}

/// The source: a convex planar polygon, emitting from the side its winding's normal points to.
#[derive(Clone, Debug, PartialEq)]
pub struct Source {
    /// Its vertices, counter-clockwise seen from the front.
    pub polygon: Vec<Vector>,
    /// Its unit normal.
    pub normal: Vector,
    /// Its area.
    pub area: f64,
}

impl Source {
    /// The source with these vertices.
    ///
    /// Errors: fewer than 3 vertices, a non-finite coordinate, a zero area, a vertex off the
    /// polygon's plane by more than 1e-6 of its size, or a polygon that is not convex.
    pub fn new(polygon: Vec<Vector>) -> Result<Source> {
        if polygon.len() < 3 {
            bail!("source: a polygon needs 3 vertices, got {}", polygon.len());
        }
        if !polygon.iter().all(|p| p.is_finite()) {
            bail!("source: a vertex has a non-finite coordinate: {polygon:?}");
        }
        let av = area_vector(&polygon);
        let area = av.length();
        let size = polygon.iter().map(|p| p.distance(polygon[0])).fold(0.0, f64::max);
        if area.is_nan() || area <= 1e-12 * size * size {
            bail!("source: the polygon has no area: {polygon:?}");
        }
        let normal = av / area;
        let m = polygon.len();
        for (i, p) in polygon.iter().enumerate() {
            if (*p - polygon[0]).dot(normal).abs() > 1e-6 * size {
                bail!("source: vertex {i} is off the polygon's plane");
            }
            let (a, b) = (polygon[(i + 1) % m] - *p, polygon[(i + 2) % m] - polygon[(i + 1) % m]);
            if a.cross(b).dot(normal) < -1e-9 * size * size {
                bail!("source: the polygon is not convex (at vertex {})", (i + 1) % m);
            }
        }
        Ok(Source { polygon, normal, area })
    }

    /// The part of the source the receiver can receive from: the polygon clipped to the
    /// receiver's front half-space, or `None` if the receiver is not in front of the source or
    /// nothing of it is in front of the receiver.
    pub fn front(&self, r: &Receiver) -> Option<Vec<Vector>> {
        let span = self.polygon.iter().map(|p| p.distance(r.point)).fold(0.0, f64::max);
        if (r.point - self.polygon[0]).dot(self.normal) <= 1e-10 * span {
            return None;
        }
        let clipped = clip(&self.polygon, |p| (p - r.point).dot(r.normal) - 1e-12 * span);
        (clipped.len() >= 3 && area_vector(&clipped).length() > 0.0).then_some(clipped)
    }
}

/// The scene's triangles that may hide the source, tested one by one.
#[derive(Clone, Debug, Default)]
pub struct Occluders {
    tris: Vec<[Vector; 3]>,
}

impl Occluders {
    /// The occluders `tris` (zero-area and non-finite triangles are dropped: they hide nothing).
    pub fn new(tris: impl IntoIterator<Item = [Vector; 3]>) -> Occluders {
        let ok = |t: &[Vector; 3]| t.iter().all(|p| p.is_finite()) && (t[1] - t[0]).cross(t[2] - t[0]).length() > 0.0;
        Occluders { tris: tris.into_iter().filter(ok).collect() }
    }

    /// The triangles.
    pub fn triangles(&self) -> &[[Vector; 3]] {
        &self.tris
    }
}

/// What tells whether a ray from a receiver to a point of the source is blocked.
pub trait Blocker {
    /// Whether the open segment `from → to` is blocked.
    fn blocked(&self, from: Vector, to: Vector) -> bool;
}

impl Blocker for Occluders {
    /// Some triangle meets the open segment ([`SEGMENT_TOL`]), every triangle tested.
    fn blocked(&self, from: Vector, to: Vector) -> bool {
        self.tris.iter().any(|t| segment_hits(t, from, to))
    }
}

impl Blocker for crate::truth::visibility::Reference {
    /// The reference's exact ray cast through its BVH ([`Reference::visible`], the same end
    /// tolerance): an independent test for the estimates' truth.
    ///
    /// [`Reference::visible`]: crate::truth::visibility::Reference::visible
    fn blocked(&self, from: Vector, to: Vector) -> bool {
        !self.visible(from.to_array(), to.to_array(), &[])
    }
}

/// Whether the segment `from → to` meets triangle `t` (edges included) at a parameter in
/// `(SEGMENT_TOL, 1 − SEGMENT_TOL)` (Möller–Trumbore; a segment in the triangle's plane meets
/// nothing).
pub(crate) fn segment_hits(t: &[Vector; 3], from: Vector, to: Vector) -> bool {
    let d = to - from;
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return false;
    }
    let inv = 1.0 / det;
    let tv = from - t[0];
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let qv = tv.cross(e1);
    let v = d.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let s = e2.dot(qv) * inv;
    s > SEGMENT_TOL && s < 1.0 - SEGMENT_TOL
}

#[cfg(test)]
pub(crate) mod testkit {
    //! Scenes with known form factors: a unit square source above a receiver, an occluding
    //! plate between them whose shadow on the source's plane is a known rectangle.
    use super::*;
    use crate::truth::closed_form::point_to_parallel_rectangle;

    /// The axis-aligned rectangle `[x0, x1] × [y0, y1]` at height `z`, facing down (−z).
    pub fn rect_down(x0: f64, x1: f64, y0: f64, y1: f64, z: f64) -> Vec<Vector> {
        vec![Vector::new(x0, y0, z), Vector::new(x0, y1, z), Vector::new(x1, y1, z), Vector::new(x1, y0, z)]
    }

    /// Two triangles of the rectangle `[x0, x1] × [y0, y1]` at height `z`.
    pub fn plate(x0: f64, x1: f64, y0: f64, y1: f64, z: f64) -> [[Vector; 3]; 2] {
        let p = |x, y| Vector::new(x, y, z);
        [[p(x0, y0), p(x1, y0), p(x1, y1)], [p(x0, y0), p(x1, y1), p(x0, y1)]]
    }

    /// The receiver at the origin facing +z.
    pub fn up() -> Receiver {
        Receiver { point: Vector::ZERO, normal: Vector::Z }
    }

    /// The exact form factor from the origin (facing +z) to the rectangle at height `c`.
    pub fn exact(x0: f64, x1: f64, y0: f64, y1: f64, c: f64) -> f64 {
        point_to_parallel_rectangle(x0, x1, y0, y1, c)
    }
}

#[cfg(test)]
mod tests {
    use super::testkit::*;
    use super::*;

    #[test]
    fn a_source_must_be_a_convex_planar_polygon() {
        assert!(Source::new(rect_down(0.0, 1.0, 0.0, 1.0, 1.0)).is_ok());
        assert!(Source::new(vec![Vector::ZERO, Vector::X]).is_err());
        assert!(Source::new(vec![Vector::ZERO, Vector::X, Vector::X * 2.0]).is_err());
        let mut off = rect_down(0.0, 1.0, 0.0, 1.0, 1.0);
        off[2].z += 0.1;
        assert!(Source::new(off).is_err());
        let dart =
            vec![Vector::ZERO, Vector::new(2.0, 0.0, 0.0), Vector::new(1.0, 0.2, 0.0), Vector::new(1.0, 2.0, 0.0)];
        assert!(Source::new(dart).is_err());
        assert!(Source::new(vec![Vector::ZERO, Vector::X, Vector::new(0.0, f64::NAN, 0.0)]).is_err());
    }

    #[test]
    fn front_clips_to_the_receivers_half_space_and_refuses_the_back() {
        let s = Source::new(rect_down(-1.0, 1.0, -1.0, 1.0, 1.0)).unwrap();
        assert_eq!(s.front(&up()).unwrap().len(), 4);
        let below = Receiver { point: Vector::new(0.0, 0.0, 2.0), normal: -Vector::Z };
        assert!(s.front(&below).is_none(), "behind the source");
        let side = Receiver { point: Vector::ZERO, normal: Vector::X };
        let half = s.front(&side).unwrap();
        assert!((area_vector(&half).length() - 2.0).abs() < 1e-9, "half of the 2 × 2 source is in front");
    }

    #[test]
    fn a_segment_is_blocked_inside_and_not_at_its_ends() {
        let [t, _] = plate(-1.0, 1.0, -1.0, 1.0, 0.5);
        assert!(segment_hits(&t, Vector::ZERO, Vector::new(0.2, -0.1, 1.0)));
        assert!(!segment_hits(&t, Vector::ZERO, Vector::new(0.2, -0.1, 0.5)), "ends on it");
        assert!(!segment_hits(&t, Vector::new(0.2, -0.1, 0.5), Vector::new(0.0, 0.0, 1.0)), "starts on it");
        assert!(!segment_hits(&t, Vector::ZERO, Vector::new(0.0, 0.0, 0.4)), "stops short");
        assert!(!segment_hits(&t, Vector::new(0.0, 0.0, 0.5), Vector::new(0.3, 0.0, 0.5)), "in its plane");
        assert!(segment_hits(&t, Vector::ZERO, Vector::new(2.0, -2.0, 1.0)), "through its corner");
    }
}
