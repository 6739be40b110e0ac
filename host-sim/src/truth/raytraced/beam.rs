//! The beam toward the source (radiosity thesis §3.4.2): a pyramid with its apex at the
//! receiver and the source as its base, after Ghazanfarpour's subdivided beams.
//!
//! 1. **Candidates.** Every triangle is classified against the beam's planes (the planes
//!    through the apex and each edge of the source, and the source's plane) by the outcodes of
//!    its vertices (Sutherland–Hodgman's codes): a triangle with every vertex outside one plane
//!    is out. Where the codes cannot tell (Fig. 3.14's second case: outside, yet straddling
//!    two planes), the triangle is clipped against the planes and is out if nothing is left.
//!    The others are the candidates, sorted by distance from the apex (nearest first).
//! 2. **Recursion.** Each candidate in turn, on the current (sub-)beam: out → dropped; covers
//!    the whole beam (the rays to every corner of its base meet it: the beam is convex, so
//!    every ray does) → the beam is dark; partly in → the beam is cut in four and each part
//!    goes on with the remaining candidates. A beam is cut at most `max_level` times (4: up to
//!    256 sub-beams from a quadrilateral source); at that level a partly covered beam is
//!    judged by the ray to its base's centre.
//! 3. **Form factor.** A beam no candidate darkens adds the exact form factor of its base,
//!    the contour integral (Eq. 2.2, [`point_to_polygon`]).
//!
//! A beam is cut in four like Wallace's elements ([`super::wallace`]): a quadrilateral into
//! its 2 × 2 bilinear cells, a triangle into its four midpoint triangles (`wallace::split`);
//! a source of five or more vertices (a quadrilateral clipped by the receiver's plane), only
//! when it must be cut, into the triangles from its centre to each edge. Without a partial
//! candidate the result is exact (one contour integral over the whole clipped source);
//! the error is confined to the level-`max_level` sub-beams that a shadow's edge crosses.
//!
//! The phases are timed separately ([`BeamStats`]), as Table 3.3 reports them.

use std::time::{Duration, Instant};

use parry3d_f64::math::Vector;

use super::wallace::{centre, split};
use super::{clip, segment_hits, Occluders, Receiver, Source};
use crate::truth::closed_form::point_to_polygon;

/// What a beam computation did, summed over receivers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BeamStats {
    /// Candidates kept by the first phase.
    pub candidates: u64,
    /// Times a beam was cut in four.
    pub subdivisions: u64,
    /// Sub-beams whose form factor was added.
    pub visible_beams: u64,
    /// Time building the candidate lists.
    pub candidates_time: Duration,
    /// Time classifying candidates against (sub-)beams and cutting them.
    pub recursion_time: Duration,
    /// Time in the analytic form factors.
    pub form_factor_time: Duration,
}

/// A triangle against a beam.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Position {
    /// Meets no ray of the beam.
    Out,
    /// Meets every ray of the beam.
    Covers,
    /// Meets some rays, or cannot be told apart from that.
    Partial,
}

/// A beam: the apex and its base (a convex polygon in the source's plane), with its planes.
struct Beam<'a> {
    apex: Vector,
    base: Vec<Vector>,
    /// The side planes (normal, pointing inward; they pass through the apex) and the source's
    /// plane (normal toward the apex, offset).
    sides: Vec<Vector>,
    source: &'a Source,
    tol: f64,
}

impl<'a> Beam<'a> {
    fn new(apex: Vector, base: Vec<Vector>, source: &'a Source, tol: f64) -> Beam<'a> {
        let c = centre(&base);
        let m = base.len();
        let sides = (0..m)
            .filter_map(|i| {
                let n = (base[i] - apex).cross(base[(i + 1) % m] - apex);
                let n = if n.dot(c - apex) < 0.0 { -n } else { n };
                let l = n.length();
                (l > 0.0).then(|| n / l)
            })
            .collect();
        Beam { apex, base, sides, source, tol }
    }

    /// Signed distances of `p` to every plane, positive inside.
    fn inside(&self, p: Vector, plane: usize) -> f64 {
        match self.sides.get(plane) {
            Some(n) => n.dot(p - self.apex),
            None => (p - self.base[0]).dot(self.source.normal),
        }
    }

    fn planes(&self) -> usize {
        self.sides.len() + 1
    }

    /// Where triangle `t` stands against the beam (see the module documentation).
    fn position(&self, t: &[Vector; 3]) -> Position {
        if self.outside(t) {
            return Position::Out;
        }
        if self.base.iter().all(|&q| segment_hits(t, self.apex, q)) {
            return Position::Covers;
        }
        Position::Partial
    }

    /// Whether `t` meets no ray: its vertices all outside one plane, or nothing of it left
    /// inside every plane.
    fn outside(&self, t: &[Vector; 3]) -> bool {
        let planes = self.planes();
        let mut straddles = false;
        for k in 0..planes {
            let d = t.map(|p| self.inside(p, k));
            if d.iter().all(|&x| x <= self.tol) {
                return true;
            }
            straddles |= d.iter().any(|&x| x <= self.tol);
        }
        if !straddles {
            return false;
        }
        let mut poly = t.to_vec();
        for k in 0..planes {
            poly = clip(&poly, |p| self.inside(p, k) - self.tol);
            if poly.len() < 3 {
                return true;
            }
        }
        false
    }
}

/// The form factor from `r` to `s` occluded by `occ`, by a beam cut at most `max_level` times;
/// `stats` gathers the counts and phase times.
pub fn form_factor(r: &Receiver, s: &Source, occ: &Occluders, max_level: u32, stats: &mut BeamStats) -> f64 {
    let t0 = Instant::now();
    let Some(front) = s.front(r) else {
        stats.candidates_time += t0.elapsed();
        return 0.0;
    };
    let span = front.iter().map(|p| p.distance(r.point)).fold(0.0, f64::max);
    let tol = 1e-9 * span;
    let beam = Beam::new(r.point, front, s, tol);
    let candidates = candidates(&beam, r, occ);
    stats.candidates += candidates.len() as u64;
    let t1 = Instant::now();
    stats.candidates_time += t1 - t0;
    let mut ff_time = Duration::ZERO;
    let f = visit(beam, r, &candidates, 0, max_level, stats, &mut ff_time);
    stats.form_factor_time += ff_time;
    stats.recursion_time += t1.elapsed().saturating_sub(ff_time);
    f
}

/// The triangles that may hide part of the beam, nearest first.
fn candidates<'o>(beam: &Beam, r: &Receiver, occ: &'o Occluders) -> Vec<&'o [Vector; 3]> {
    let mut c: Vec<(f64, &[Vector; 3])> = occ
        .triangles()
        .iter()
        .filter(|t| {
            // A triangle whose plane holds the apex meets no ray (each leaves its plane at once).
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            (r.point - t[0]).dot(n).abs() > beam.tol * n.length() && !beam.outside(t)
        })
        .map(|t| {
            let d = t.iter().map(|p| p.distance(r.point)).fold(f64::INFINITY, f64::min);
            (d, t)
        })
        .collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    c.into_iter().map(|(_, t)| t).collect()
}

/// The beam's form factor with `candidates` (nearest first), at cut level `level`.
fn visit(
    beam: Beam,
    r: &Receiver,
    candidates: &[&[Vector; 3]],
    level: u32,
    max_level: u32,
    stats: &mut BeamStats,
    ff_time: &mut Duration,
) -> f64 {
    for (i, t) in candidates.iter().enumerate() {
        match beam.position(t) {
            Position::Out => continue,
            Position::Covers => return 0.0,
            Position::Partial if level < max_level => {
                stats.subdivisions += 1;
                let rest = &candidates[i..];
                return split(&beam.base)
                    .into_iter()
                    .map(|part| {
                        visit(
                            Beam::new(beam.apex, part, beam.source, beam.tol),
                            r,
                            rest,
                            level + 1,
                            max_level,
                            stats,
                            ff_time,
                        )
                    })
                    .sum();
            }
            Position::Partial => {
                let c = centre(&beam.base);
                if candidates[i..].iter().any(|t| segment_hits(t, beam.apex, c)) {
                    return 0.0;
                }
                break;
            }
        }
    }
    let t0 = Instant::now();
    stats.visible_beams += 1;
    let f = point_to_polygon(r.point, r.normal, &beam.base, beam.source.normal);
    *ff_time += t0.elapsed();
    f
}

#[cfg(test)]
mod tests {
    use super::super::testkit::*;
    use super::super::wallace::{self, Sampling};
    use super::*;

    fn unit_source() -> Source {
        Source::new(rect_down(-0.5, 0.5, -0.5, 0.5, 1.0)).unwrap()
    }

    fn beam(r: &Receiver, s: &Source, occ: &Occluders, level: u32) -> (f64, BeamStats) {
        let mut st = BeamStats::default();
        (form_factor(r, s, occ, level, &mut st), st)
    }

    #[test]
    fn an_unoccluded_source_is_exact_with_one_beam() {
        let (f, st) = beam(&up(), &unit_source(), &Occluders::default(), 4);
        assert!((f - exact(-0.5, 0.5, -0.5, 0.5, 1.0)).abs() < 1e-12);
        assert_eq!((st.subdivisions, st.visible_beams), (0, 1));
        // Occluders out of the beam: beside it, behind the receiver, beyond the source.
        let occ = Occluders::new(
            [plate(2.0, 3.0, -1.0, 1.0, 0.5), plate(-9.0, 9.0, -9.0, 9.0, -0.5), plate(-9.0, 9.0, -9.0, 9.0, 1.5)]
                .concat(),
        );
        let (g, st) = beam(&up(), &unit_source(), &occ, 4);
        assert_eq!((g, st.candidates, st.subdivisions), (f, 0, 0));
    }

    #[test]
    fn a_shadow_on_the_cut_lines_is_exact_and_a_covering_plate_is_dark() {
        // The plate's shadow on the source is its x < 0 half: one cut, then exact.
        let occ = Occluders::new(plate(-2.0, 0.0, -2.0, 2.0, 0.5));
        let (f, st) = beam(&up(), &unit_source(), &occ, 4);
        assert!((f - exact(0.0, 0.5, -0.5, 0.5, 1.0)).abs() < 1e-12, "{f}");
        assert_eq!((st.subdivisions, st.visible_beams), (1, 2));
        let big = [Vector::new(-9.0, -9.0, 0.5), Vector::new(9.0, -9.0, 0.5), Vector::new(0.0, 9.0, 0.5)];
        let (g, st) = beam(&up(), &unit_source(), &Occluders::new([big]), 4);
        assert_eq!((g, st.subdivisions), (0.0, 0));
        // A plate of two triangles covers the beam with neither: the beams its diagonal
        // crosses are cut to the last level, where their centre rays meet one of the two.
        let all = Occluders::new(plate(-2.0, 2.0, -2.0, 2.0, 0.5));
        let (g, st) = beam(&up(), &unit_source(), &all, 4);
        assert_eq!(g, 0.0);
        assert!(st.subdivisions > 0);
    }

    #[test]
    fn an_oblique_shadow_edge_converges_with_the_level_within_the_cut_band() {
        // A plate whose shadow's edge crosses the source off every cut line, at an angle.
        let t = [Vector::new(-3.0, -3.0, 0.5), Vector::new(0.13, -3.0, 0.5), Vector::new(-0.07, 3.0, 0.5)];
        let occ = Occluders::new([t]);
        // Truth: the lit part of the source, a polygon (the source minus the shadow's
        // half-plane), by the contour integral.
        let s = unit_source();
        let shadow = t.map(|p| p * 2.0); // projected from the origin onto z = 1
        let lit = clip(&s.polygon, |p| {
            let (a, b) = (shadow[1], shadow[2]);
            -(b - a).cross(p - a).z // right of the edge a → b: outside the shadow
        });
        let truth = point_to_polygon(Vector::ZERO, Vector::Z, &lit, s.normal);
        let mut last = f64::NAN;
        for level in 0..=6 {
            let (f, st) = beam(&up(), &s, &occ, level);
            let err = (f - truth).abs();
            // The error is at most the form factor of the sub-beams the edge crosses: at most
            // 2 · 2^level + 1 squares of side 2^−level, each at least 1 away: at most its area / π.
            let cell = 0.5f64.powi(level as i32);
            let bound = (2.0 / cell + 1.0) * cell * cell / std::f64::consts::PI;
            assert!(err <= bound, "level {level}: error {err}, bound {bound}");
            if level == 2 {
                last = err;
            }
            assert!(st.subdivisions <= (1 << (2 * level)), "level {level}: {} cuts", st.subdivisions);
            if level == 6 {
                assert!(err < last, "level 6: {err}, level 2: {last}");
                assert!(err < 2e-3 * truth, "level 6: {err} of {truth}");
            }
        }
    }

    #[test]
    fn an_occluder_straddling_two_planes_outside_the_beam_is_dropped() {
        // Fig. 3.14's second case: a thin triangle crossing the extensions of two side planes
        // past the beam's corner, outside the beam.
        let t = [Vector::new(0.9, 0.2, 0.5), Vector::new(0.2, 0.9, 0.5), Vector::new(3.0, 3.0, 0.5)];
        let occ = Occluders::new([t]);
        let (f, st) = beam(&up(), &unit_source(), &occ, 4);
        assert_eq!((st.candidates, st.subdivisions), (0, 0));
        assert!((f - exact(-0.5, 0.5, -0.5, 0.5, 1.0)).abs() < 1e-12);
    }

    #[test]
    fn beams_and_many_rays_agree_on_a_cluttered_scene() {
        // Random plates between a receiver and a tilted source: the level-6 beam against
        // Wallace's 64 × 64 jittered rays, averaged over seeds.
        let mut rng = crate::rng::Rng(7);
        let mut tris = Vec::new();
        for _ in 0..12 {
            let (x, y, z) = (rng.range(-0.8, 0.8), rng.range(-0.8, 0.8), rng.range(0.2, 0.8));
            let w = rng.range(0.05, 0.3);
            tris.push([Vector::new(x, y, z), Vector::new(x + w, y, z + 0.05), Vector::new(x, y + w, z - 0.05)]);
        }
        let occ = Occluders::new(tris);
        let s = Source::new(vec![
            Vector::new(-0.5, -0.5, 1.0),
            Vector::new(-0.5, 0.5, 1.2),
            Vector::new(0.5, 0.5, 1.2),
            Vector::new(0.5, -0.5, 1.0),
        ])
        .unwrap();
        let r = Receiver { point: Vector::new(0.1, -0.05, 0.0), normal: Vector::new(0.0, 0.3, 1.0).normalize() };
        let (f, st) = beam(&r, &s, &occ, 6);
        assert!(st.candidates > 0 && st.subdivisions > 0);
        let seeds = 8;
        let rays: f64 = (0..seeds)
            .map(|seed| {
                wallace::form_factor(&r, &s, &occ, &Sampling::Uniform { k: 64, jitter: Some(seed) }).form_factor
            })
            .sum::<f64>()
            / seeds as f64;
        assert!((f - rays).abs() < 0.01 * rays, "beam {f}, rays {rays}");
    }

    #[test]
    fn a_source_clipped_to_a_pentagon_is_one_beam_until_something_covers_part_of_it() {
        // The receiver's plane cuts the (−0.5, −0.5) corner off the unit source: a pentagon.
        let r = Receiver { point: Vector::ZERO, normal: Vector::new(1.5, 1.5, 1.0).normalize() };
        let s = unit_source();
        assert_eq!(s.front(&r).unwrap().len(), 5);
        let rays = |occ: &Occluders| {
            let seeds = 8;
            (0..seeds)
                .map(|seed| {
                    wallace::form_factor(&r, &s, occ, &Sampling::Uniform { k: 64, jitter: Some(seed) }).form_factor
                })
                .sum::<f64>()
                / seeds as f64
        };
        let (f, st) = beam(&r, &s, &Occluders::default(), 4);
        assert_eq!((st.subdivisions, st.visible_beams), (0, 1));
        let free = rays(&Occluders::default());
        assert!((f - free).abs() < 1e-3 * free, "beam {f}, rays {free}");
        // A plate over part of it: the pentagon is cut into its fan of five, then as any beam.
        let occ = Occluders::new(plate(0.0, 2.0, -2.0, 0.1, 0.5));
        let (g, st) = beam(&r, &s, &occ, 6);
        assert!(st.subdivisions > 0 && g < f);
        let shadowed = rays(&occ);
        assert!((g - shadowed).abs() < 0.01 * shadowed, "beam {g}, rays {shadowed}");
    }
}
