//! Shared checks of the projective surfaces (tests only): a closed box, unoccluded parallel and
//! perpendicular squares against the contour integral (radiosity thesis Eq. 2.2), occlusion.
//!
//! The aliasing bound: a facet's sampled form factor differs from the exact one only through
//! proxels cut by its projected contour; each such proxel lies within δ (the largest angular
//! radius of a proxel about its centre direction) of the contour on the unit sphere, and the
//! form-factor density is cos θ / π ≤ 1/π per steradian, so the error is at most the measure of
//! the δ-band around the contour: `(2 δ L + 3 π δ²) / π`, L the contour's length on the sphere
//! (the sum of the angles its edges subtend).

use parry3d_f64::math::Vector;

use super::ProjectionSurface;
use crate::truth::closed_form::point_to_polygon;

/// A surface at resolution R and its largest proxel angular radius δ (radians).
pub type Make = fn(u32) -> (Box<dyn ProjectionSurface>, f64);

/// The surface's delta form factors sum to `total` (up to rounding).
pub fn deltas_sum_to(s: &dyn ProjectionSurface, total: f64) {
    let sum: f64 = (0..s.samples()).map(|k| s.delta(k)).sum();
    assert!((sum - total).abs() < 1e-9, "{}: Σ ΔF = {sum}, expected {total}", s.name());
    assert!((0..s.samples()).all(|k| s.delta(k) > 0.0), "{}: a proxel has ΔF ≤ 0", s.name());
}

fn square(c: [Vector; 4]) -> Vec<[Vector; 3]> {
    vec![[c[0], c[1], c[2]], [c[0], c[2], c[3]]]
}

/// The six faces of the box [−0.4, 0.6] × [−0.7, 0.3] × [0, 1], twelve triangles.
fn closed_box() -> Vec<[Vector; 3]> {
    let (lo, hi) = (Vector::new(-0.4, -0.7, 0.0), Vector::new(0.6, 0.3, 1.0));
    let p = |i: u32| {
        Vector::new(
            [lo.x, hi.x][(i & 1) as usize],
            [lo.y, hi.y][(i >> 1 & 1) as usize],
            [lo.z, hi.z][(i >> 2) as usize],
        )
    };
    let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    quads.iter().flat_map(|q| square(q.map(p))).collect()
}

/// Form factors from the origin (normal +z) to a point on the floor of a closed box sum to the
/// surface's coverage: every proxel sees a wall.
pub fn enclosure(s: &dyn ProjectionSurface, coverage: f64) {
    let ff = s.form_factors(Vector::ZERO, Vector::Z, &closed_box());
    let sum: f64 = ff.iter().sum();
    let tol = 4.0 * s.largest_delta_ff() + 1e-9;
    assert!((sum - coverage).abs() <= tol, "{}: Σ F = {sum}, coverage {coverage}", s.name());
}

/// Contour length on the unit sphere of a polygon seen from the origin.
fn contour_length(poly: &[Vector]) -> f64 {
    (0..poly.len()).map(|i| poly[i].angle_between(poly[(i + 1) % poly.len()])).sum()
}

/// |sampled − exact| for one square and its aliasing bound at the surface's δ.
fn square_error(s: &dyn ProjectionSurface, delta: f64, quad: [Vector; 4], pn: Vector) -> (f64, f64) {
    let exact = point_to_polygon(Vector::ZERO, Vector::Z, &quad, pn);
    let sampled: f64 = s.form_factors(Vector::ZERO, Vector::Z, &square(quad)).iter().sum();
    let l = contour_length(&quad);
    let bound = (2.0 * delta * l + 3.0 * std::f64::consts::PI * delta * delta) / std::f64::consts::PI;
    ((sampled - exact).abs(), bound)
}

/// Offset parallel squares at height 0.6 and perpendicular ones on x = 0.5, z ≥ 0.15 (all
/// unoccluded, within every surface's coverage), at three small shifts so that the aliasing of
/// one position does not decide; each within its bound; errors and bounds summed.
fn squares_error(s: &dyn ProjectionSurface, delta: f64) -> (f64, f64) {
    let v = Vector::new;
    let (mut e, mut b) = (0.0, 0.0);
    for (dx, dy) in [(0.0, 0.0), (0.037, 0.021), (-0.052, 0.043)] {
        let par =
            [v(-0.3, -0.2, 0.6), v(0.5, -0.2, 0.6), v(0.5, 0.4, 0.6), v(-0.3, 0.4, 0.6)].map(|p| p + v(dx, dy, 0.0));
        let perp =
            [v(0.5, -0.3, 0.15), v(0.5, -0.3, 0.7), v(0.5, 0.4, 0.7), v(0.5, 0.4, 0.15)].map(|p| p + v(0.0, dy, dx));
        let (e1, b1) = square_error(s, delta, par, -Vector::Z);
        let (e2, b2) = square_error(s, delta, perp, -Vector::X);
        assert!(e1 <= b1, "{}: parallel square error {e1} > bound {b1}", s.name());
        assert!(e2 <= b2, "{}: perpendicular square error {e2} > bound {b2}", s.name());
        (e, b) = (e + e1 + e2, b + b1 + b2);
    }
    (e, b)
}

/// A triangle wholly behind the parallel square gets 0; the square keeps its share.
pub fn occlusion(s: &dyn ProjectionSurface) {
    let v = Vector::new;
    let mut facets = square([v(-0.3, -0.2, 0.6), v(0.5, -0.2, 0.6), v(0.5, 0.4, 0.6), v(-0.3, 0.4, 0.6)]);
    facets.push([v(-0.1, -0.05, 1.2), v(0.3, -0.05, 1.2), v(0.1, 0.3, 1.2)]);
    let ff = s.form_factors(Vector::ZERO, Vector::Z, &facets);
    assert_eq!(ff[2], 0.0, "{}: hidden facet got {}", s.name(), ff[2]);
    assert!(ff[0] + ff[1] > 0.1, "{}: the square lost its form factor", s.name());
}

/// Every check: enclosure and occlusion at `lo`; squares at `lo` and `hi`, each within its
/// bound, the error and the bound smaller at `hi`.
pub fn all_checks(make: Make, lo: u32, hi: u32, coverage: f64) {
    let (a, da) = make(lo);
    let (b, db) = make(hi);
    enclosure(a.as_ref(), coverage);
    occlusion(a.as_ref());
    let (ea, ba) = squares_error(a.as_ref(), da);
    let (eb, bb) = squares_error(b.as_ref(), db);
    assert!(bb < ba, "{}: bound does not fall with R ({ba} → {bb})", a.name());
    assert!(eb < ea, "{}: error does not fall with R ({ea} at {lo} → {eb} at {hi})", a.name());
}
