//! Closed forms of the form factor (radiosity thesis ch. 2): the analytic point-to-polygon form
//! factor by the contour integral (Eq. 2.2) and three cases of Howell's catalogue. Exact, no
//! visibility: the yardsticks the sampled and projective estimators ([`super::formfactor`],
//! [`super::projective`], [`super::raytraced`]) and their tests are measured against.

use parry3d_f64::math::Vector;
use std::f64::consts::PI;

/// Form factor between two directly opposed, equal, parallel `a × b` rectangles at distance `c`
/// (Howell's catalogue C-11). Unit squares at distance 1: 0.19982.
pub fn parallel_rectangles(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (x1, y1) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    let log = ((1.0 + x * x) * (1.0 + y * y) / (1.0 + x * x + y * y)).sqrt().ln();
    2.0 / (PI * x * y) * (log + x * y1 * (x / y1).atan() + y * x1 * (y / x1).atan() - x * x.atan() - y * y.atan())
}

/// Form factor from a `w × l` rectangle to an `h × l` rectangle standing at a right angle on its
/// edge of length `l` (they share that edge; Howell's catalogue C-14). Unit squares: 0.20004.
pub fn perpendicular_rectangles(l: f64, w: f64, h: f64) -> f64 {
    let (w, h) = (w / l, h / l);
    let (w2, h2) = (w * w, h * h);
    let s = (w2 + h2).sqrt();
    let a = (1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2);
    let b = w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2));
    let c = h2 * (1.0 + h2 + w2) / ((1.0 + h2) * (h2 + w2));
    let log = a.ln() + w2 * b.ln() + h2 * c.ln();
    (w * (1.0 / w).atan() + h * (1.0 / h).atan() - s * (1.0 / s).atan() + log / 4.0) / (PI * w)
}

/// Form factor from a differential area to the rectangle `[x0, x1] × [y0, y1]` of the parallel
/// plane at distance `c` facing it, in coordinates where the differential area is at the
/// origin (Howell's catalogue B-3 for a rectangle with a corner above the point, combined by
/// signed corners).
pub fn point_to_parallel_rectangle(x0: f64, x1: f64, y0: f64, y1: f64, c: f64) -> f64 {
    let corner = |x: f64, y: f64| {
        let (a, b) = (x.abs() / c, y.abs() / c);
        let (a1, b1) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
        let f = (a / a1 * (b / a1).atan() + b / b1 * (a / b1).atan()) / (2.0 * PI);
        f * x.signum() * y.signum()
    };
    corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)
}

/// Unoccluded form factor from a differential area at `x` with unit normal `n` to a planar
/// polygon with unit normal `pn`: 0 unless `x` is in front of the polygon's plane; otherwise the
/// polygon is clipped to `x`'s hemisphere and the contour integral of thesis Eq. 2.2 is
/// summed, `1/(2π) Σ_edges γ_g n · (R_g × R_{g+1})/|R_g × R_{g+1}|` (γ_g the angle the edge
/// subtends at `x`).
pub fn point_to_polygon(x: Vector, n: Vector, polygon: &[Vector], pn: Vector) -> f64 {
    let Some(&first) = polygon.first() else {
        return 0.0;
    };
    let span = x.distance(first) + polygon.iter().map(|p| p.distance(first)).fold(0.0, f64::max);
    let height = (x - first).dot(pn);
    if height.is_nan() || height <= 1e-10 * span {
        return 0.0; // behind, or in the plane (cos θ_j = 0 everywhere)
    }
    let clipped = clip_front(polygon, x, n, 1e-12 * span);
    contour(x, n, &clipped)
}

/// The part of `poly` with `(p − x) · n > tol`.
pub(crate) fn clip_front(poly: &[Vector], x: Vector, n: Vector, tol: f64) -> Vec<Vector> {
    clip(poly, |p| (p - x).dot(n) - tol)
}

/// The part of convex `poly` where `side(p) > 0` (Sutherland–Hodgman against one plane).
pub fn clip(poly: &[Vector], side: impl Fn(Vector) -> f64) -> Vec<Vector> {
    let h: Vec<f64> = poly.iter().map(|&p| side(p)).collect();
    if h.iter().all(|&d| d > 0.0) {
        return poly.to_vec();
    }
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let j = (i + 1) % poly.len();
        if h[i] > 0.0 {
            out.push(poly[i]);
        }
        if (h[i] > 0.0) != (h[j] > 0.0) {
            let t = h[i] / (h[i] - h[j]);
            out.push(poly[i] + (poly[j] - poly[i]) * t);
        }
    }
    out
}

/// Eq. 2.2 on a polygon wholly in front of `x`.
fn contour(x: Vector, n: Vector, poly: &[Vector]) -> f64 {
    if poly.len() < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..poly.len() {
        let a = poly[i] - x;
        let b = poly[(i + 1) % poly.len()] - x;
        let c = a.cross(b);
        let cl = c.length();
        if cl > 0.0 {
            let gamma = cl.atan2(a.dot(b));
            sum += gamma * n.dot(c) / cl;
        }
    }
    (sum / (2.0 * PI)).abs()
}
