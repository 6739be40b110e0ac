//! The f64 radiosity reference (`truth::formfactor`, `truth::radiosity`) against independent
//! truths: closed-form form factors, the sum and reciprocity rules of form factors (radiosity
//! thesis §2.1), a direct solve of the same linear system (§1.3.1), the power balance, and the
//! progressive solver's stopping rule (§1.3.2). Every tolerance is derived from the sampling
//! (a bound, or standard errors over independent seeds), not read off an output.
//!
//! The reference's own error on the Cornell box is measured by `host-sim radiosity --reference
//! --reference-self-error`, not here.

use std::f64::consts::PI;

use host_sim::scene::patches::{subdivide, Patch, Patches};
use host_sim::scene::{Face, Material, Mesh};
use host_sim::truth::closed_form::{
    parallel_rectangles, perpendicular_rectangles, point_to_parallel_rectangle, point_to_polygon,
};
use host_sim::truth::formfactor::{Estimator, FormFactors, Sampling};
use host_sim::truth::radiosity::{
    ambient, balance, displayed, jacobi, progressive, rms_relative_error, solve, ShootConfig, Stop,
};
use parry3d_f64::math::Vector;

/// A mesh position.
type V3 = [f64; 3];

/// A quad of the box `lo..hi` on side `side` (0 = low, 1 = high) of `axis`, wound so that its
/// normal points into the box (`inward`) or out of it.
fn box_side(lo: V3, hi: V3, axis: usize, side: usize, inward: bool) -> Vec<V3> {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let corner = |a: f64, b: f64| {
        let mut p = [0.0; 3];
        p[axis] = if side == 0 { lo[axis] } else { hi[axis] };
        p[u] = a;
        p[v] = b;
        p
    };
    // (u, v) counter-clockwise: normal +axis.
    let mut q = vec![corner(lo[u], lo[v]), corner(hi[u], lo[v]), corner(hi[u], hi[v]), corner(lo[u], hi[v])];
    // +axis points inward on the low side.
    if (side == 0) != inward {
        q.reverse();
    }
    q
}

/// A mesh of quads, one material per quad from `mats` (index into `materials`).
fn quads_mesh(quads: Vec<Vec<V3>>, mats: Vec<u16>, materials: Vec<Material>) -> Mesh {
    let mut m = Mesh { name: "test".into(), materials, ..Default::default() };
    for (q, mat) in quads.into_iter().zip(mats) {
        let base = m.positions.len() as u32;
        m.positions.extend(q);
        m.faces.push(Face { verts: (base..base + 4).collect(), material: mat });
    }
    m
}

fn grey(kd: f64) -> Material {
    Material { name: format!("grey{kd}"), kd: [kd as f32; 3], ..Material::default() }
}

/// The closed room `[0,1]³`, walls facing in; with `block`, a closed cube `[0.35,0.65]³`
/// floating inside, facing out.
fn room(block: bool) -> Mesh {
    let mut quads = Vec::new();
    for axis in 0..3 {
        for side in 0..2 {
            quads.push(box_side([0.0; 3], [1.0; 3], axis, side, true));
            if block {
                quads.push(box_side([0.35; 3], [0.65; 3], axis, side, false));
            }
        }
    }
    let n = quads.len();
    quads_mesh(quads, vec![1; n], vec![Material::default(), grey(0.5)])
}

/// Two unit squares: the floor `[0,1]² × {0}` facing +z and either the opposed square at z = 1
/// facing down, or the wall x = 0 facing +x (sharing the edge x = z = 0).
fn two_squares(opposed: bool) -> Mesh {
    let floor = box_side([0.0; 3], [1.0; 3], 2, 0, true);
    let other =
        if opposed { box_side([0.0; 3], [1.0; 3], 2, 1, true) } else { box_side([0.0; 3], [1.0; 3], 0, 0, true) };
    quads_mesh(vec![floor, other], vec![1, 1], vec![Material::default(), grey(0.5)])
}

fn ff(p: &Patches, strata: usize, seed: u64, estimator: Estimator) -> FormFactors {
    FormFactors::new(p, Sampling { strata, seed, estimator }).unwrap()
}

/// `(1/A_S) Σ_{i∈S} A_i Σ_{j∈T} F_ij`: the form factor between two faces from their patches.
fn face_to_face(p: &Patches, f: &[Vec<f64>], s: usize, t: usize) -> f64 {
    let (mut num, mut area) = (0.0, 0.0);
    for (i, pi) in p.patches.iter().enumerate().filter(|(_, q)| q.face == s) {
        area += pi.area;
        num += pi.area * p.patches.iter().enumerate().filter(|(_, q)| q.face == t).map(|(j, _)| f[i][j]).sum::<f64>();
    }
    num / area
}

/// Mean and standard error of the mean.
fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

#[test]
fn the_closed_forms_agree_with_the_literature_and_with_each_other() {
    // Published values (Howell's catalogue, C-11 and C-14).
    assert!((parallel_rectangles(1.0, 1.0, 1.0) - 0.19982).abs() < 5e-6);
    assert!((perpendicular_rectangles(1.0, 1.0, 1.0) - 0.20004).abs() < 5e-6);
    // Reciprocity of C-14: w F(w → h) = h F(h → w).
    let (w, h) = (0.7, 2.3);
    assert!((w * perpendicular_rectangles(1.5, w, h) - h * perpendicular_rectangles(1.5, h, w)).abs() < 1e-12);
    // C-11 as the average of the point form factor B-3 over the square (Gauss–Legendre, 12² nodes
    // of an analytic integrand: error far below 1e-9).
    let (nodes, weights) = gauss_legendre_12();
    let mut avg = 0.0;
    for (a, wa) in nodes.iter().zip(&weights) {
        for (b, wb) in nodes.iter().zip(&weights) {
            let (x, y) = ((a + 1.0) / 2.0, (b + 1.0) / 2.0);
            avg += wa * wb / 4.0 * point_to_parallel_rectangle(-x, 1.0 - x, -y, 1.0 - y, 1.0);
        }
    }
    assert!((avg - parallel_rectangles(1.0, 1.0, 1.0)).abs() < 1e-9, "{avg}");
    // The contour integral (Eq. 2.2) against B-3, the point above, beside and outside the square.
    let square = [[0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 0.0, 1.0]].map(Vector::from); // facing −z
    for x in [[0.5, 0.5, 0.0], [0.1, 0.8, 0.0], [-0.4, 1.7, 0.3], [2.0, -1.0, -3.0]].map(Vector::from) {
        let c = 1.0 - x.z;
        let want = point_to_parallel_rectangle(-x.x, 1.0 - x.x, -x.y, 1.0 - x.y, c);
        let got = point_to_polygon(x, Vector::Z, &square, Vector::NEG_Z);
        assert!((got - want).abs() < 1e-13, "{x:?}: {got} vs {want}");
    }
    // Behind the square, or in its plane: nothing. Half below the horizon: the clipped half.
    assert_eq!(point_to_polygon(Vector::new(0.5, 0.5, 2.0), Vector::NEG_Z, &square, Vector::NEG_Z), 0.0);
    assert_eq!(point_to_polygon(Vector::new(3.0, 0.5, 1.0), Vector::NEG_X, &square, Vector::NEG_Z), 0.0);
    let half = [[0.0, 0.5, 1.0], [0.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 0.5, 1.0]].map(Vector::from); // the part at y > 0.5
    let tilted = point_to_polygon(Vector::new(0.5, 0.5, 0.0), Vector::Y, &square, Vector::NEG_Z);
    let upper_half = point_to_polygon(Vector::new(0.5, 0.5, 0.0), Vector::Y, &half, Vector::NEG_Z);
    assert!(tilted > 0.0 && (tilted - upper_half).abs() < 1e-14, "{tilted} vs {upper_half}");
}

/// 12-point Gauss–Legendre nodes and weights on [−1, 1] (Newton on the Legendre polynomial).
fn gauss_legendre_12() -> (Vec<f64>, Vec<f64>) {
    let n = 12;
    let (mut xs, mut ws) = (Vec::new(), Vec::new());
    for i in 1..=n {
        let mut x = (PI * (i as f64 - 0.25) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            x -= p1 / dp;
        }
        xs.push(x);
        ws.push(2.0 / ((1.0 - x * x) * dp * dp));
    }
    (xs, ws)
}

/// McDiarmid's bounded differences: an estimate that is a function of independent stratum
/// samples, changing by at most `c_k` when sample k moves in its stratum, is within
/// `√(Σ c_k² · ln(2/δ) / 2)` of its mean with probability 1 − δ.
fn mcdiarmid(sum_c2: f64, delta: f64) -> f64 {
    (sum_c2 * (2.0 / delta).ln() / 2.0).sqrt()
}

#[test]
fn sampled_form_factor_between_opposed_unit_squares_matches_the_closed_form() {
    let exact = parallel_rectangles(1.0, 1.0, 1.0);
    // Kernel between the planes z = 0 and z = 1: f = 1/(π (1+ρ²)²), ρ the horizontal offset;
    // its gradient in either end point is at most 4ρ/(π(1+ρ²)³) ≤ L (at ρ = 1/√5). No pair is
    // nearer than 1, so the near-field cap (ε ≪ π) never acts: both estimators are unbiased.
    let l = 4.0 / (5f64.sqrt() * PI * 1.2f64.powi(3));
    for (size, strata) in [(2.0, 16), (0.5, 8)] {
        let p = subdivide(&two_squares(true), size, 100).unwrap();
        let per_square = p.patches.len() / 2;
        // Stratum diameter: the hypotenuse of a stratum of a patch's half (a right triangle).
        let side = 1.0 / (per_square as f64).sqrt();
        let h = 2f64.sqrt() * side / strata as f64;
        let s = (per_square * 2 * strata * strata) as f64; // samples per square, weight 1/s each
        for est in [Estimator::Contour, Estimator::PointToPoint] {
            let f = ff(&p, strata, 7, est).matrix();
            let got = face_to_face(&p, &f, 0, 1);
            // A shooter sample moves the estimate by ≤ L h / s; a receiver sample (point-to-
            // point only: the contour term is exact in the receiver) by as much.
            let movers = if est == Estimator::Contour { s } else { 2.0 * s };
            let tol = mcdiarmid(movers * (l * h / s).powi(2), 1e-9);
            assert!((got - exact).abs() <= tol, "{est:?} size {size}: {got} vs {exact} (tolerance {tol})");
            assert!(tol < 0.05 * exact, "the bound is tight enough to mean something: {tol}");
            println!(
                "{est:?} size {size}: F = {got:.6} (exact {exact:.6}, error {:.1e}, bound {tol:.1e})",
                got - exact
            );
        }
    }
}

#[test]
fn near_field_perpendicular_unit_squares_sharing_an_edge() {
    let exact = perpendicular_rectangles(1.0, 1.0, 1.0);
    let p = subdivide(&two_squares(false), 2.0, 100).unwrap();
    assert_eq!(p.patches.len(), 2);
    let strata = 8;
    let s = (2 * strata * strata) as f64;
    let seeds = 1..=10u64;
    let run = |est| seeds.clone().map(|seed| ff(&p, strata, seed, est).matrix()[0][1]).collect::<Vec<_>>();
    // Contour: exact for every shooter point (nothing occludes); only the shooter points vary.
    let (m, se) = mean_se(&run(Estimator::Contour));
    assert!((m - exact).abs() <= 5.0 * se + 1e-12, "contour: {m} ± {se} vs {exact}");
    assert!(se < 0.01 * exact, "{se}");
    // Point-to-point: the cap ε = a_k + a_l = 2/s where π r² < ε removes, along the shared edge of
    // length 1 (A_i = 1), 4 ρ₀ / (9 π) with ρ₀ = √(ε/π) (the integral of the capped part of
    // the kernel over a quarter-ball); near the two ends of the edge the ball is cut off, giving
    // back at most ρ₀² in all.
    let rho0 = (2.0 / s / PI).sqrt();
    let bias = 4.0 * rho0 / (9.0 * PI);
    let (m2, se2) = mean_se(&run(Estimator::PointToPoint));
    let lo = exact - bias - 5.0 * se2;
    let hi = exact - bias + rho0 * rho0 + 5.0 * se2;
    assert!(m2 >= lo && m2 <= hi, "point-to-point: {m2} ± {se2}, expected in [{lo}, {hi}] (bias {bias})");
    println!("contour {m:.5}±{se:.1e}, point-to-point {m2:.5}±{se2:.1e}, exact {exact:.5}, predicted bias {bias:.4}");
}

/// The i.i.d. standard error of `(1/A_i) Σ_k w_k g(x_k)` from its own terms: an upper bound of
/// the stratified estimator's (stratification never increases the variance).
fn iid_se(ff: &FormFactors, i: usize, g: impl Fn(Vector) -> f64) -> f64 {
    let x = ff.samples(i);
    let v: Vec<f64> = x.iter().map(|s| g(s.point)).collect();
    mean_se(&v).1
}

#[test]
fn closed_box_form_factors_sum_to_one_and_are_reciprocal() {
    let p = subdivide(&room(false), 0.5, 100).unwrap();
    assert_eq!(p.patches.len(), 24);
    let a: Vec<f64> = p.patches.iter().map(|q| q.area).collect();
    // Contour: exact per shooter point, and the clipped receivers tile the hemisphere.
    let c = ff(&p, 4, 3, Estimator::Contour);
    let f = c.matrix();
    for (i, row) in f.iter().enumerate() {
        let sum: f64 = row.iter().sum();
        assert!((sum - 1.0).abs() < 1e-9, "patch {i}: Σ F = {sum}");
    }
    // Reciprocity: each side is a stratified mean over its own shooter points; 5 i.i.d. standard
    // errors of both sides (an upper bound) cover the difference.
    let (pi, pj) = (&p.patches, &p.patches);
    for i in 0..24 {
        for j in 0..24 {
            let se_ij = iid_se(&c, i, |x| point_to_polygon(x, pi[i].normal, &pj[j].polygon, pj[j].normal));
            let se_ji = iid_se(&c, j, |x| point_to_polygon(x, pj[j].normal, &pi[i].polygon, pi[i].normal));
            let tol = 5.0 * ((a[i] * se_ij).powi(2) + (a[j] * se_ji).powi(2)).sqrt() + 1e-12;
            let d = a[i] * f[i][j] - a[j] * f[j][i];
            assert!(d.abs() <= tol, "A F reciprocity {i}–{j}: {} vs {} (tol {tol})", a[i] * f[i][j], a[j] * f[j][i]);
        }
    }
    // Point-to-point: reciprocal by construction (same pairs, same rays, symmetric kernel).
    let f2 = ff(&p, 4, 3, Estimator::PointToPoint).matrix();
    for i in 0..24 {
        for j in 0..24 {
            let (x, y) = (a[i] * f2[i][j], a[j] * f2[j][i]);
            assert!((x - y).abs() <= 1e-12 * x.max(y), "{i}–{j}: {x} vs {y}");
        }
    }
}

#[test]
fn closed_box_with_an_occluder_sums_to_one() {
    // The room and a floating closed cube: every ray from a surface ends on a surface, so Σ_j F_ij
    // = 1; occlusion now decides which. Tolerance: 5 standard errors over 8 seeds of each sum,
    // plus 1e-9 (the unoccluded part is exact).
    let p = subdivide(&room(true), 0.5, 200).unwrap();
    let n = p.patches.len();
    assert_eq!(n, 24 + 6);
    for est in [Estimator::Contour, Estimator::PointToPoint] {
        let sums: Vec<Vec<f64>> =
            (1..=8).map(|seed| ff(&p, 4, seed, est).matrix().iter().map(|r| r.iter().sum()).collect()).collect();
        let mut worst = 0.0f64;
        for i in 0..n {
            let (m, se) = mean_se(&sums.iter().map(|s| s[i]).collect::<Vec<_>>());
            // Point-to-point: the cap's known deficit along right-angle edges (room patches at
            // the room's edges; see the near-field test), less at the room's corners.
            let expect = if est == Estimator::PointToPoint { 1.0 - edge_deficit(&p.patches[i], 4) } else { 1.0 };
            let corner = if est == Estimator::PointToPoint { corner_allowance(&p.patches[i], 4) } else { 0.0 };
            let ok = m >= expect - 5.0 * se - 1e-9 && m <= expect + corner + 5.0 * se + 1e-9;
            assert!(ok, "{est:?} patch {i}: Σ F = {m} ± {se}, expected {expect} (+ up to {corner})");
            worst = worst.max((m - expect).abs() / se.max(1e-300));
        }
        println!("{est:?}: worst |Σ F − expected| = {worst:.2} standard errors");
    }
}

/// ρ₀ of the point-to-point cap for a patch with `strata` strata per triangle (two triangles).
fn rho0(q: &Patch, strata: usize) -> f64 {
    let w = q.area / (2 * strata * strata) as f64;
    (2.0 * w / PI).sqrt()
}

/// A room patch's edges lying on the room's edges (where a perpendicular wall starts): both
/// ends have two coordinates on the room's faces (0 or 1). The block's edges have none.
fn room_edges(q: &Patch) -> Vec<(Vector, Vector)> {
    let on_edge = |v: &Vector| v.to_array().iter().filter(|c| **c == 0.0 || **c == 1.0).count() >= 2;
    let n = q.polygon.len();
    (0..n).map(|k| (q.polygon[k], q.polygon[(k + 1) % n])).filter(|(a, b)| on_edge(a) && on_edge(b)).collect()
}

/// The point-to-point estimator's expected deficit of `Σ_j F_ij` along the room's edges.
fn edge_deficit(q: &Patch, strata: usize) -> f64 {
    let length: f64 = room_edges(q).iter().map(|(a, b)| a.distance(*b)).sum();
    length * 4.0 * rho0(q, strata) / (9.0 * PI) / q.area
}

/// What [`edge_deficit`] over-counts at the room's corners: there the perpendicular wall ends, so
/// within ρ₀ of a corner the capped region is cut off. The deficit per unit edge length is
/// 4ρ₀/(9π); the cut affects at most ρ₀ of edge at each end lying on a room corner.
fn corner_allowance(q: &Patch, strata: usize) -> f64 {
    let corner = |v: &Vector| v.to_array().iter().all(|c| *c == 0.0 || *c == 1.0);
    let ends: usize = room_edges(q).iter().map(|(a, b)| corner(a) as usize + corner(b) as usize).sum();
    let r = rho0(q, strata);
    ends as f64 * 4.0 * r * r / (9.0 * PI) / q.area
}

/// The room with colours, one emitting patch on the ceiling.
fn lit_room() -> (Patches, FormFactors) {
    let mut p = subdivide(&room(false), 0.5, 100).unwrap();
    let kd = [[0.7, 0.2, 0.1], [0.1, 0.6, 0.2], [0.5, 0.5, 0.5], [0.8, 0.8, 0.7], [0.3, 0.3, 0.9], [0.6, 0.4, 0.2]];
    for q in &mut p.patches {
        q.reflectance = kd[q.face];
    }
    let ceiling = p.patches.iter().position(|q| q.normal.z < -0.5).unwrap();
    p.patches[ceiling].emission = [10.0, 8.0, 6.0];
    let f = ff(&p, 3, 5, Estimator::Contour);
    (p, f)
}

#[test]
fn energy_is_conserved_and_shooting_matches_the_direct_solve() {
    let (p, f) = lit_room();
    let cfg = ShootConfig { stop_fraction: 1e-12, max_shots: 100_000 };
    let sol = solve(&p.patches, &f, &cfg).unwrap();
    assert_eq!(sol.stop, Stop::Converged);
    let b = balance(&p.patches, &sol);
    // Bookkeeping identity, and no leak in a closed room (Σ_j F_ij = 1 to 1e-9 per row).
    assert!((b.emitted - b.absorbed - b.unshot - b.leaked).abs() <= 1e-12 * b.emitted, "{b:?}");
    assert!(b.leaked.abs() <= 1e-9 * b.emitted, "{b:?}");
    assert!((b.absorbed - b.emitted).abs() <= (1e-12 + 1e-9) * b.emitted, "{b:?}");
    // The same linear system, solved directly with the same F.
    let m = f.matrix();
    let direct = jacobi(&p.patches, &m, 1e-14, 10_000).unwrap();
    let areas: Vec<f64> = p.patches.iter().map(|q| q.area).collect();
    let e = rms_relative_error(&direct, &sol.radiosity, &areas).unwrap();
    assert!(e < 1e-6, "RMS relative difference {e}");
    for (d, s) in direct.iter().zip(&sol.radiosity) {
        for c in 0..3 {
            assert!((d[c] - s[c]).abs() <= 1e-6 * d[c], "{d:?} vs {s:?}");
        }
    }
    println!("{} shots, RMS relative difference to Jacobi {e:.1e}, balance {b:?}", sol.shots.len());
}

#[test]
fn the_residual_never_grows_and_shooting_stops_where_asked() {
    let (p, f) = lit_room();
    let sol = solve(&p.patches, &f, &ShootConfig { stop_fraction: 0.01, max_shots: 10_000 }).unwrap();
    assert_eq!(sol.stop, Stop::Converged);
    let r: Vec<f64> = sol.shots.iter().map(|s| s.residual_after).collect();
    for w in r.windows(2) {
        assert!(w[1] <= w[0] * (1.0 + 1e-12), "residual grew: {} → {}", w[0], w[1]);
    }
    // Stopped at the first shot that brought it to 1 %, not later.
    assert!(*r.last().unwrap() <= 0.01 && (r.len() < 2 || r[r.len() - 2] > 0.01), "{r:?}");
    assert_eq!(sol.residual, *r.last().unwrap());
    assert_eq!(sol.shots[0].patch, p.patches.iter().position(|q| q.emission[0] > 0.0).unwrap(), "the emitter first");
    // Each shot's power is the largest unshot power then: replay the shots and check.
    let budget = solve(&p.patches, &f, &ShootConfig { stop_fraction: 1e-9, max_shots: 7 }).unwrap();
    assert_eq!((budget.stop, budget.shots.len()), (Stop::ShotBudget, 7));
    assert!(budget.residual > 1e-9);
    assert_eq!(&budget.shots[..], &sol.shots[..7], "the same shots, deterministic");
    // A zero budget shoots nothing: B = E.
    let none = solve(&p.patches, &f, &ShootConfig { stop_fraction: 0.5, max_shots: 0 }).unwrap();
    assert!(none.shots.is_empty() && none.residual == 1.0 && none.stop == Stop::ShotBudget);
}

#[test]
fn the_ambient_term_is_exact_for_a_uniform_closed_room_and_fades() {
    // A well-mixed closed enclosure: equal areas, F_ij = 1/(n−1) (rows sum to 1, reciprocal),
    // uniform ρ = 0.5 and E = 1: the solution is E/(1−ρ) = 2 on every patch, which is what the
    // ambient display gives before any shot: B + ρ · U/(1−ρ) = 1 + 0.5 · 1/0.5.
    let mut p = subdivide(&room(false), 0.5, 100).unwrap();
    for q in &mut p.patches {
        q.emission = [1.0; 3];
    }
    let n = p.patches.len();
    let mixed = |i: usize| -> Vec<f64> { (0..n).map(|j| if i == j { 0.0 } else { 1.0 / (n - 1) as f64 }).collect() };
    let none = progressive(&p.patches, &ShootConfig { stop_fraction: 0.0, max_shots: 0 }, |i| Ok(mixed(i))).unwrap();
    let shown = displayed(&p.patches, &none);
    let exact = jacobi(&p.patches, &(0..n).map(mixed).collect::<Vec<_>>(), 1e-14, 10_000).unwrap();
    for (s, e) in shown.iter().zip(&exact) {
        for c in 0..3 {
            assert!((s[c] - 2.0).abs() < 1e-12 && (e[c] - 2.0).abs() < 1e-12, "{s:?} {e:?}");
        }
    }
    // In the lit room the ambient term shrinks with the unshot power and the display approaches
    // the solution faster than the raw radiosity does.
    let (p, f) = lit_room();
    let last = solve(&p.patches, &f, &ShootConfig { stop_fraction: 1e-10, max_shots: 100_000 }).unwrap();
    let areas: Vec<f64> = p.patches.iter().map(|q| q.area).collect();
    let mut prev = f64::INFINITY;
    for shots in [1, 5, 20, 60] {
        let s = solve(&p.patches, &f, &ShootConfig { stop_fraction: 0.0, max_shots: shots }).unwrap();
        let a = ambient(&p.patches, &s.unshot);
        let total: f64 = a.iter().sum();
        assert!(total < prev, "{shots} shots: ambient {a:?}");
        prev = total;
        let raw = rms_relative_error(&last.radiosity, &s.radiosity, &areas).unwrap();
        let amb = rms_relative_error(&last.radiosity, &displayed(&p.patches, &s), &areas).unwrap();
        assert!(amb < raw, "{shots} shots: with ambient {amb}, raw {raw}");
    }
}

#[test]
fn bad_input_is_a_clear_error() {
    let mut p = subdivide(&room(false), 0.5, 100).unwrap();
    let f = ff(&p, 2, 1, Estimator::Contour);
    let cfg = ShootConfig::default();
    let e = solve(&p.patches, &f, &cfg).unwrap_err().to_string();
    assert!(e.contains("no emitter"), "{e}");
    p.patches[3].emission = [1.0, 0.0, 0.0];
    p.patches[5].reflectance = [1.2, 0.5, 0.5];
    let e = solve(&p.patches, &f, &cfg).unwrap_err().to_string();
    assert!(e.contains("patch 5") && e.contains("reflectance"), "{e}");
    p.patches[5].reflectance = [0.5; 3];
    let e = progressive(&p.patches, &cfg, |_| Ok(vec![0.0; 3])).unwrap_err().to_string();
    assert!(e.contains("3 entries"), "{e}");
    let e = progressive(&p.patches, &cfg, |_| Ok(vec![f64::NAN; 24])).unwrap_err().to_string();
    assert!(e.contains("not a finite"), "{e}");
    for bad in [1.0, -0.1, f64::NAN] {
        assert!(solve(&p.patches, &f, &ShootConfig { stop_fraction: bad, max_shots: 10 }).is_err());
    }
    assert!(FormFactors::new(&p, Sampling { strata: 0, ..Sampling::default() }).is_err());
    assert!(FormFactors::new(&Patches::default(), Sampling::default()).is_err());
    assert!(f.row(24).is_err());
    assert!(rms_relative_error(&[[0.0; 3]], &[[1.0; 3]], &[1.0]).is_err());
    assert!(rms_relative_error(&[[1.0; 3]], &[[1.0; 3]], &[1.0, 2.0]).is_err());
    assert!(jacobi(&p.patches, &[vec![0.0; 24]], 1e-9, 10).is_err());
    // Zero-area faces of a scene are skipped and counted by the subdivision, never patches.
    let mut m = room(false);
    m.positions.extend([[0.2, 0.2, 0.2], [0.4, 0.4, 0.4], [0.6, 0.6, 0.6]]);
    m.faces.push(Face { verts: vec![24, 25, 26], material: 1 });
    let q = subdivide(&m, 0.5, 100).unwrap();
    assert_eq!((q.summary.degenerate_faces, q.patches.len()), (1, 24));
}

/// A lamp in its ceiling (the Cornell box's light): a square coplanar with the closed room's
/// ceiling, overlapping it, cut on the same 0.25 grid. The facet listed first wins the overlap
/// (as in the reference renderer): the ceiling patches under the lamp — or, listed the other
/// way, the lamp's patches — exchange nothing (their rows and columns are exactly 0), and every
/// other patch still sees a closed room once: Σ_j F_ij = 1 (the contour estimator is exact when
/// each receiver is wholly seen or wholly hidden, as here). Counting both the lamp and the
/// ceiling behind it would give 1 + F(lamp) for the floor's patches.
#[test]
fn a_lamp_in_its_ceiling_hides_the_ceiling_behind_it() {
    let lamp = box_side([0.25, 0.25, 0.0], [0.75, 0.75, 1.0], 2, 1, true);
    let room_quads = || (0..3).flat_map(|axis| (0..2).map(move |side| box_side([0.0; 3], [1.0; 3], axis, side, true)));
    for lamp_first in [true, false] {
        let quads: Vec<Vec<V3>> = if lamp_first {
            std::iter::once(lamp.clone()).chain(room_quads()).collect()
        } else {
            room_quads().chain([lamp.clone()]).collect()
        };
        let lamp_face = if lamp_first { 0 } else { 6 };
        let mesh = quads_mesh(quads, vec![1; 7], vec![Material::default(), grey(0.5)]);
        let p = subdivide(&mesh, 0.25, 200).unwrap();
        assert_eq!(p.patches.len(), 6 * 16 + 4);
        let inside = |q: &Patch| (0..2).all(|k| q.centroid[k] > 0.25 && q.centroid[k] < 0.75);
        let on_ceiling = |q: &Patch| q.centroid.z > 1.0 - 1e-12;
        // The patches that lose the overlap: the ceiling's under the lamp, or the lamp's.
        let hidden = |q: &Patch| on_ceiling(q) && inside(q) && ((q.face == lamp_face) != lamp_first);
        assert_eq!(p.patches.iter().filter(|q| hidden(q)).count(), 4);
        let f = ff(&p, 3, 5, Estimator::Contour).matrix();
        for (i, qi) in p.patches.iter().enumerate() {
            let sum: f64 = f[i].iter().sum();
            if hidden(qi) {
                assert!(f[i].iter().all(|&x| x == 0.0), "lamp first {lamp_first}: hidden patch {i} sees {sum}");
                assert!(f.iter().all(|r| r[i] == 0.0), "lamp first {lamp_first}: hidden patch {i} is seen");
            } else {
                assert!((sum - 1.0).abs() < 1e-9, "lamp first {lamp_first}: patch {i}: Σ F = {sum}");
            }
        }
    }
}
