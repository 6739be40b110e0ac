//! Wallace's sampling of the source (radiosity thesis §3.1, after Wallace 1989): the source
//! is cut into elements, one ray goes from the receiver to each element, and each element the
//! ray reaches counts as a disc of its area facing the receiver (§3.1.3):
//! `F ≈ Σᵢ δᵢ aᵢ cosθ₁ᵢ cosθ₂ᵢ / (π dᵢ² + aᵢ)` (δᵢ = 1 if ray i reaches the source).
//!
//! The disc formula is exact for a disc seen head-on and biased low for a large element seen
//! close (it stays below `aᵢ/(π dᵢ²)`, which diverges): the error falls as the elements shrink,
//! fastest where the elements stay disc-like (§3.1.4). Adaptive sampling (Fig. 3.3.b) cuts an
//! element in four while its own unoccluded contribution is above a threshold, so a receiver
//! near the source gets many rays and a far one few. Jittering (Fig. 3.3.d) moves each ray to
//! a uniform point of its element: aliasing turns into noise.

use parry3d_f64::math::Vector;
use std::f64::consts::PI;

use super::{Blocker, Receiver, Source};
use crate::rng::Rng;
use crate::scene::patches::{area_vector, split_triangle};

/// How the source is cut into elements.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sampling {
    /// `k × k` elements: a quadrilateral's bilinear `k × k` cells, any other polygon's fan
    /// triangles each cut into `k²` similar triangles; one ray to each element's centre, or,
    /// with `jitter` (a seed), to a uniform point of it.
    Uniform {
        /// Cuts per side (≥ 1).
        k: usize,
        /// Seed of the jittered points; `None`: the centres.
        jitter: Option<u64>,
    },
    /// An element is cut in four while its unoccluded contribution is above `threshold` and it
    /// has been cut fewer than `max_depth` times; one ray to each final element's centre.
    Adaptive {
        /// The largest contribution an element may carry uncut.
        threshold: f64,
        /// The most cuts of one element.
        max_depth: u32,
    },
}

/// A form factor and the rays it took.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate {
    /// The estimated form factor from the receiver to the source.
    pub form_factor: f64,
    /// Rays cast (elements whose unoccluded contribution was not zero).
    pub rays: u64,
}

/// An element of the source: a triangle or a quadrilateral (convex, in the source's plane).
type Element = Vec<Vector>;

/// The form factor from `r` to `s` with the rays blocked as `occ` says, sampled as `sampling` says.
pub fn form_factor(r: &Receiver, s: &Source, occ: &impl Blocker, sampling: &Sampling) -> Estimate {
    let mut est = Estimate::default();
    let Some(front) = s.front(r) else { return est };
    match *sampling {
        Sampling::Uniform { k, jitter } => {
            let mut rng = jitter.map(Rng);
            for e in elements(&front, k.max(1)) {
                let q = match rng.as_mut() {
                    Some(rng) => uniform_point(&e, rng),
                    None => centre(&e),
                };
                add(&mut est, r, s, occ, q, area_vector(&e).length());
            }
        }
        Sampling::Adaptive { threshold, max_depth } => {
            for e in elements(&front, 1) {
                adaptive(&mut est, r, s, occ, e, threshold, max_depth);
            }
        }
    }
    est
}

/// Element `e` cut while its contribution is above `threshold`, its rays cast.
fn adaptive(est: &mut Estimate, r: &Receiver, s: &Source, occ: &impl Blocker, e: Element, threshold: f64, depth: u32) {
    let (q, a) = (centre(&e), area_vector(&e).length());
    if depth > 0 && kernel(r, s, q, a) > threshold {
        for child in split(&e) {
            adaptive(est, r, s, occ, child, threshold, depth - 1);
        }
    } else {
        add(est, r, s, occ, q, a);
    }
}

/// One element: its disc term, if the ray from the receiver reaches `q`.
fn add(est: &mut Estimate, r: &Receiver, s: &Source, occ: &impl Blocker, q: Vector, a: f64) {
    let f = kernel(r, s, q, a);
    if f > 0.0 {
        est.rays += 1;
        if !occ.blocked(r.point, q) {
            est.form_factor += f;
        }
    }
}

/// The disc formula: an element of area `a` at `q`, facing the receiver at `cos θ₂`.
pub fn kernel(r: &Receiver, s: &Source, q: Vector, a: f64) -> f64 {
    let v = q - r.point;
    let d2 = v.dot(v);
    let d = d2.sqrt();
    let (c1, c2) = (r.normal.dot(v) / d, -s.normal.dot(v) / d);
    if !(c1 > 0.0 && c2 > 0.0) {
        return 0.0;
    }
    a * c1 * c2 / (PI * d2 + a)
}

/// The polygon cut into `k × k` elements (see [`Sampling::Uniform`]).
fn elements(poly: &[Vector], k: usize) -> Vec<Element> {
    if poly.len() == 4 {
        let kf = k as f64;
        let at = |i: usize, j: usize| bilinear(poly, i as f64 / kf, j as f64 / kf);
        let cells = (0..k).flat_map(|i| (0..k).map(move |j| (i, j)));
        return cells.map(|(i, j)| vec![at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]).collect();
    }
    (1..poly.len() - 1).flat_map(|i| split_triangle([poly[0], poly[i], poly[i + 1]], k)).map(|t| t.to_vec()).collect()
}

/// The point `(u, v)` of quadrilateral `q` (`(0, 0)` is `q[0]`, `(1, 0)` `q[1]`, `(1, 1)` `q[2]`).
fn bilinear(q: &[Vector], u: f64, v: f64) -> Vector {
    let (a, b) = (q[0] + (q[1] - q[0]) * u, q[3] + (q[2] - q[3]) * u);
    a + (b - a) * v
}

/// A convex element cut once: a quadrilateral into its 2 × 2 bilinear cells, a triangle into
/// its four midpoint triangles, a polygon of more sides (a source clipped by the receiver's
/// plane) into the fan of triangles around its centre.
pub(crate) fn split(e: &[Vector]) -> Vec<Element> {
    match e.len() {
        3 => split_triangle([e[0], e[1], e[2]], 2).into_iter().map(|t| t.to_vec()).collect(),
        4 => elements(e, 2),
        m => {
            let c = centre(e);
            (0..m).map(|i| vec![c, e[i], e[(i + 1) % m]]).collect()
        }
    }
}

/// An element's centre: its vertices' mean (the centroid of a triangle or a parallelogram).
pub(crate) fn centre(e: &[Vector]) -> Vector {
    e.iter().fold(Vector::ZERO, |s, &p| s + p) / e.len() as f64
}

/// A uniform point of a triangle, or of a quadrilateral by its bilinear map (uniform on a
/// parallelogram).
fn uniform_point(e: &[Vector], rng: &mut Rng) -> Vector {
    let (u, v) = (rng.f(), rng.f());
    if e.len() == 4 {
        return bilinear(e, u, v);
    }
    let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
    e[0] + (e[1] - e[0]) * u + (e[2] - e[0]) * v
}

#[cfg(test)]
mod tests {
    use super::super::testkit::*;
    use super::super::Occluders;
    use super::*;

    fn unit_source() -> Source {
        Source::new(rect_down(-0.5, 0.5, -0.5, 0.5, 1.0)).unwrap()
    }

    fn uniform(k: usize) -> Sampling {
        Sampling::Uniform { k, jitter: None }
    }

    #[test]
    fn unoccluded_estimates_converge_to_the_closed_form() {
        let exact = exact(-0.5, 0.5, -0.5, 0.5, 1.0);
        let errs: Vec<f64> = [1, 2, 4, 8, 16]
            .iter()
            .map(|&k| {
                (form_factor(&up(), &unit_source(), &Occluders::default(), &uniform(k)).form_factor - exact).abs()
            })
            .collect();
        // From 2 × 2 on the error falls as 1/k² (one element's disc is lucky on a square).
        assert!(errs[1..].windows(2).all(|w| w[1] < w[0] / 3.0), "{errs:?}");
        assert!(errs[4] < 1e-3 * exact, "k = 16: {} against {exact}", errs[4]);
        // One disc for a unit square seen head-on at distance 1: 1/(π + 1) = 0.2415, the exact
        // value 0.2395 (the disc overestimates a square's corners).
        let one = form_factor(&up(), &unit_source(), &Occluders::default(), &uniform(1));
        assert_eq!(one.rays, 1);
        assert!((one.form_factor - 1.0 / (PI + 1.0)).abs() < 1e-12);
    }

    #[test]
    fn a_plate_hiding_half_the_source_leaves_the_other_half() {
        // The plate at z = 0.5 over x < 0 hides exactly the source's x < 0 half from the origin.
        let occ = Occluders::new(plate(-2.0, 0.0, -2.0, 2.0, 0.5));
        let half = exact(0.0, 0.5, -0.5, 0.5, 1.0);
        let f = form_factor(&up(), &unit_source(), &occ, &uniform(32)).form_factor;
        assert!((f - half).abs() < 2e-3 * half, "{f} against {half}");
        let all = Occluders::new(plate(-2.0, 2.0, -2.0, 2.0, 0.5));
        assert_eq!(form_factor(&up(), &unit_source(), &all, &uniform(8)).form_factor, 0.0);
        let behind = Occluders::new(plate(-2.0, 2.0, -2.0, 2.0, 1.5));
        let free = form_factor(&up(), &unit_source(), &Occluders::default(), &uniform(8)).form_factor;
        assert_eq!(form_factor(&up(), &unit_source(), &behind, &uniform(8)).form_factor, free);
    }

    #[test]
    fn jittered_points_average_to_the_closed_form() {
        let occ = Occluders::new(plate(-2.0, 0.1, -2.0, 2.0, 0.5));
        let truth = exact(0.2, 0.5, -0.5, 0.5, 1.0);
        let runs = 64;
        let mean = (0..runs)
            .map(|seed| {
                form_factor(&up(), &unit_source(), &occ, &Sampling::Uniform { k: 8, jitter: Some(seed) }).form_factor
            })
            .sum::<f64>()
            / runs as f64;
        // The centres alias on the shadow's edge at x = 0.2 (between cells' centres); jittered,
        // the cells it cuts count by the fraction of their area in the light, on average.
        assert!((mean - truth).abs() < 0.02 * truth, "{mean} against {truth}");
    }

    #[test]
    fn adaptive_sampling_spends_its_rays_near_the_source() {
        let s = unit_source();
        let adaptive = Sampling::Adaptive { threshold: 0.002, max_depth: 6 };
        let near = Receiver { point: Vector::new(0.0, 0.0, 0.8), normal: Vector::Z };
        let far = Receiver { point: Vector::new(0.0, 0.0, -4.0), normal: Vector::Z };
        let (en, ef) = (
            form_factor(&near, &s, &Occluders::default(), &adaptive),
            form_factor(&far, &s, &Occluders::default(), &adaptive),
        );
        assert!(en.rays > 4 * ef.rays, "near {} rays, far {}", en.rays, ef.rays);
        for (r, e, c) in [(near, en, 0.2), (far, ef, 5.0)] {
            let exact = exact(-0.5, 0.5, -0.5, 0.5, c);
            assert!((e.form_factor - exact).abs() < 0.01 * exact, "{:?}: {} against {exact}", r.point, e.form_factor);
        }
        let coarse = Sampling::Adaptive { threshold: 0.02, max_depth: 6 };
        let exact = exact(-0.5, 0.5, -0.5, 0.5, 0.2);
        let ec = form_factor(&near, &s, &Occluders::default(), &coarse);
        assert!(ec.rays < en.rays && (ec.form_factor - exact).abs() > (en.form_factor - exact).abs());
    }

    #[test]
    fn a_receiver_behind_the_source_or_facing_away_gets_nothing() {
        let s = unit_source();
        let behind = Receiver { point: Vector::new(0.0, 0.0, 2.0), normal: -Vector::Z };
        let away = Receiver { point: Vector::ZERO, normal: -Vector::Z };
        for r in [behind, away] {
            assert_eq!(form_factor(&r, &s, &Occluders::default(), &uniform(4)), Estimate::default());
        }
    }
}
