//! Smooth shading (issue 54 item 4, `cell_core::smooth`) against independent oracles:
//!
//! * the cell's barycentric weights and Phong normal against an f64 barycentric computation on
//!   the same lattice triangle, within the error bound the bit budget gives (16-bit weights,
//!   16-bit octahedral vertex normals: `cell_core::smooth`'s module doc), on facets at the
//!   loading arithmetic's limits (n = MAX_N = 65 536, vertices on the lattice's corners, needles)
//!   and on small ones, at vertices, on edges and inside;
//! * the averaged vertex normals against a brute-force sum over a small mesh;
//! * the `vn` path on a small OBJ file with normals (`tests/fixtures/normals/`).

use cell_core::dexel::FacetTag;
use cell_core::normal::NormalCode;
use cell_core::shade::VIEW;
use cell_core::smooth::{record, VertexNormals, WEIGHT_ONE};
use cell_core::units::MAX_N;
use host_sim::machine::shading::smooth_surface::row_at;
use host_sim::precompute::{facet_packet, LoadConfig, Q};
use host_sim::scene::normals::corner_normals;

type V3 = [f64; 3];

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn unit(v: V3) -> V3 {
    let l = dot(v, v).sqrt();
    v.map(|c| c / l)
}

fn angle(a: V3, b: V3) -> f64 {
    (dot(a, b) / (dot(a, a) * dot(b, b)).sqrt()).clamp(-1.0, 1.0).acos()
}

/// A tiny deterministic generator (xorshift64*), uniform in [0, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The f64 oracle: barycentric coordinates of the column centre (x, y) in the xy projection of
/// the lattice triangle `t` (voxel x's centre is at lattice Q·x + Q/2).
fn barycentric(t: &[[i64; 3]], x: u32, y: u32) -> [f64; 3] {
    let q = [(Q * x as i64 + Q / 2) as f64, (Q * y as i64 + Q / 2) as f64];
    let p: Vec<[f64; 2]> = t.iter().map(|v| [v[0] as f64, v[1] as f64]).collect();
    let area = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let total = area(p[0], p[1], p[2]);
    [area(p[1], p[2], q) / total, area(p[2], p[0], q) / total, area(p[0], p[1], q) / total]
}

/// The error bound of the module doc: weights within ½ of 65 535·λ, renormalised by their sum
/// (within 1.5 of 65 535): |λ̃ − λ| ≤ 1.5/65 533.5 + 0.5/65 535.
const LAMBDA_ERR: f64 = 1.5 / 65_533.5 + 0.5 / 65_535.0;
/// The octahedral code's angular error (cell_core::normal: below 1° over the sphere).
const CODE_DEG: f64 = 1.0;
/// f32 arithmetic in the cell (normalisation by refined inverse square roots, sums).
const F32_SLACK: f64 = 1e-5;

/// Check every column of `cols` whose centre line meets the facet `tri` (lattice units) at
/// grid side `n`, with vertex normals `normals`: the weights against the oracle's barycentric
/// coordinates, the Phong normal against the oracle's interpolation of the exact normals.
/// Returns the number of columns checked.
fn check(n: u32, tri: &[[i64; 3]], normals: [V3; 3], cols: &[(u32, u32)]) -> usize {
    let cfg = LoadConfig::watertight(n);
    let pkt = facet_packet(tri, FacetTag::default(), &cfg).unwrap().expect("non-degenerate");
    let geo = cross(
        sub(tri[1].map(|c| c as f64), tri[0].map(|c| c as f64)),
        sub(tri[2].map(|c| c as f64), tri[0].map(|c| c as f64)),
    );
    let facet = NormalCode::encode(geo.map(|c| c as f32));
    let codes = VertexNormals(normals.map(|v| NormalCode::encode(v.map(|c| c as f32))));
    // The side the eye (VIEW = −z) sees: the oracle turns the exact normals by the exact plane.
    let side = if dot(geo, VIEW.map(f64::from)) < 0.0 { -1.0 } else { 1.0 };
    let mut checked = 0;
    for &(x, y) in cols {
        let row = row_at(&pkt, x, y);
        let Some((num, den)) = cell_core::visible::hit(&row, n) else { continue };
        let l = barycentric(tri, x, y);
        let r = record(&row, codes, num, den);
        for (k, (&w, &lk)) in r.weights.iter().zip(&l).enumerate() {
            let w = w as f64 / WEIGHT_ONE as f64;
            assert!((w - lk).abs() <= 0.5 / 65_535.0 + 1e-12, "({x}, {y}): weight {k} {w} vs λ {lk}");
        }
        let exact: V3 = std::array::from_fn(|i| side * (0..3).map(|k| l[k] * unit(normals[k])[i]).sum::<f64>());
        let cell = r.phong_normal(facet, VIEW).map(f64::from);
        let e = 3.0 * LAMBDA_ERR + 2.0 * (CODE_DEG.to_radians() / 2.0).sin();
        let len = dot(exact, exact).sqrt();
        let bound = (e / len).min(1.0).asin() + F32_SLACK;
        let got = angle(cell, exact);
        assert!(
            got <= bound,
            "({x}, {y}) n = {n}: {:.4}° from the f64 interpolation, bound {:.4}°",
            got.to_degrees(),
            bound.to_degrees()
        );
        checked += 1;
    }
    checked
}

/// Unit normals within `cone` radians of `axis`, at random.
fn normals_near(rng: &mut Rng, axis: V3, cone: f64) -> [V3; 3] {
    let a = unit(axis);
    let t = unit(cross(a, if a[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] }));
    let b = cross(a, t);
    std::array::from_fn(|_| {
        let (th, ph) = (cone * rng.next().sqrt(), std::f64::consts::TAU * rng.next());
        std::array::from_fn(|i| th.cos() * a[i] + th.sin() * (ph.cos() * t[i] + ph.sin() * b[i]))
    })
}

/// Columns at the vertices, along the edges and inside the projected triangle.
fn columns(tri: &[[i64; 3]], n: u32, rng: &mut Rng, inside: usize) -> Vec<(u32, u32)> {
    let col = |p: [f64; 2]| -> (u32, u32) {
        let c = |v: f64| ((v - (Q / 2) as f64) / Q as f64).round().clamp(0.0, n as f64 - 1.0) as u32;
        (c(p[0]), c(p[1]))
    };
    let v: Vec<[f64; 2]> = tri.iter().map(|p| [p[0] as f64, p[1] as f64]).collect();
    let mut out = Vec::new();
    for i in 0..3 {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        for t in [0.0, 0.001, 0.5, 0.999] {
            out.push(col([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]));
        }
    }
    for _ in 0..inside {
        let (mut s, mut t) = (rng.next(), rng.next());
        if s + t > 1.0 {
            (s, t) = (1.0 - s, 1.0 - t);
        }
        out.push(col(std::array::from_fn(|i| v[0][i] + s * (v[1][i] - v[0][i]) + t * (v[2][i] - v[0][i]))));
    }
    out
}

/// At the loading arithmetic's limits: n = MAX_N, vertices on the lattice's corners and faces,
/// needles across the whole grid (the largest edge coefficients and values the bit budget
/// allows, `cell_core::voxelize`); the weights are exact to ½ of their last bit and the normal
/// within the bound.
#[test]
fn interpolated_normals_match_f64_barycentrics_at_the_bit_budget() {
    let n = MAX_N;
    let facets = crate::common::budget_facets(n);
    let mut rng = Rng(0x5eed_0054);
    let mut checked = 0;
    for tri in &facets {
        let geo = cross(
            sub(tri[1].map(|c| c as f64), tri[0].map(|c| c as f64)),
            sub(tri[2].map(|c| c as f64), tri[0].map(|c| c as f64)),
        );
        for cone in [0.3, 1.0] {
            let normals = normals_near(&mut rng, geo, cone);
            checked += check(n, tri, normals, &columns(tri, n, &mut rng, 12));
        }
    }
    assert!(checked > 60, "only {checked} columns met their facets");
}

/// Small and thin facets at n = 64 in every orientation, every column of their box.
#[test]
fn interpolated_normals_match_f64_barycentrics_on_small_facets() {
    let mut rng = Rng(54);
    let n = 64;
    let mut checked = 0;
    for _ in 0..60 {
        let tri: [[i64; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| (rng.next() * 16.0 * 64.0) as i64));
        let geo = cross(
            sub(tri[1].map(|c| c as f64), tri[0].map(|c| c as f64)),
            sub(tri[2].map(|c| c as f64), tri[0].map(|c| c as f64)),
        );
        // Not seen edge-on (the centre line would not meet it): |n_z| ≥ 0.1.
        if dot(geo, geo) == 0.0 || geo[2].abs() < 0.1 * dot(geo, geo).sqrt() {
            continue;
        }
        // Every column of the facet's box.
        let range = |k: usize| {
            let lo = tri.iter().map(|p| p[k]).min().unwrap() / Q;
            let hi = (tri.iter().map(|p| p[k]).max().unwrap() / Q).min(n as i64 - 1);
            lo as u32..=hi as u32
        };
        let cols: Vec<(u32, u32)> = range(1).flat_map(|y| range(0).map(move |x| (x, y))).collect();
        checked += check(n, &tri, normals_near(&mut rng, geo, 1.0), &cols);
    }
    assert!(checked > 1000, "only {checked} columns met their facets");
}

/// A square pyramid on an open square base (apex shared by four faces, base corners by three),
/// a quad with a fold and a lone triangle: the averaged normal of every corner against a brute
/// force over every face (its area vector as a sum of fan cross products, not Newell's formula),
/// turned to its own face's side.
#[test]
fn averaged_vertex_normals_match_brute_force() {
    let obj = "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\nv 1 1 1.5\nv 5 0 0\nv 6 0 0.5\nv 6 1 0\nv 5 1 0.2\n\
               v 8 0 0\nv 9 0 0\nv 8 1 3\n\
               f 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\nf 1 4 3 2\nf 6 7 8 9\nf 10 11 12\n";
    let mesh = host_sim::scene::load_obj_bytes("pyramid", obj.as_bytes(), None).unwrap();
    assert!(mesh.face_normals.iter().all(|c| c.is_empty()), "no vn in the file");
    let got = corner_normals(&mesh).unwrap();
    let p = |v: u32| mesh.positions[v as usize];
    let area_vector = |f: &host_sim::scene::Face| {
        let mut s = [0.0; 3];
        for k in 1..f.verts.len() - 1 {
            let c = cross(sub(p(f.verts[k]), p(f.verts[0])), sub(p(f.verts[k + 1]), p(f.verts[0])));
            for i in 0..3 {
                s[i] += c[i];
            }
        }
        s
    };
    let mut corners = 0;
    for (fi, f) in mesh.faces.iter().enumerate() {
        for (k, &v) in f.verts.iter().enumerate() {
            let mut sum = [0.0; 3];
            for g in mesh.faces.iter().filter(|g| g.verts.contains(&v)) {
                let a = area_vector(g);
                for i in 0..3 {
                    sum[i] += a[i];
                }
            }
            let mut want = unit(sum);
            if dot(want, area_vector(f)) < 0.0 {
                want = want.map(|c| -c);
            }
            let have = got[fi][k];
            assert!(angle(have, want) < 1e-12, "face {fi} corner {k}: {have:?} vs {want:?}");
            corners += 1;
        }
    }
    assert_eq!(corners, 4 * 3 + 4 + 4 + 3);
}

/// The `vn` path: a small OBJ file whose corners carry their own normals (`f v//vn`), bent
/// away from the faces' normal: each corner gets its file normal, normalised, whatever the
/// loader did to the winding.
#[test]
fn the_file_normals_of_a_small_obj_are_read_per_corner() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/normals/bent-square.obj");
    let mesh = host_sim::scene::load(path).unwrap();
    let text = std::fs::read_to_string(path).unwrap();
    let triples = |prefix: &str| -> Vec<V3> {
        text.lines()
            .filter_map(|l| l.strip_prefix(prefix))
            .map(|l| {
                let c: Vec<f64> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
                [c[0], c[1], c[2]]
            })
            .collect()
    };
    let (v, vn) = (triples("v "), triples("vn "));
    assert_eq!((mesh.faces.len(), vn.len()), (2, 4));
    let got = corner_normals(&mesh).unwrap();
    for (f, c) in mesh.faces.iter().zip(&got) {
        for (&i, &n) in f.verts.iter().zip(c) {
            // In this file every corner at vertex k (1-based) uses normal k; the loader numbers
            // vertices its own way: find the file's by position.
            let k = v.iter().position(|p| *p == mesh.positions[i as usize]).unwrap();
            let want = unit(vn[k]);
            assert!(angle(n, want) < 1e-12, "file vertex {}: {n:?} vs {want:?}", k + 1);
        }
    }
    // And it differs from what averaging would give (the flat square's normal).
    assert!(got.iter().flatten().all(|n| n[2].abs() < 0.99));
}
