//! Showing a radiosity solution: where a surface point lies on its patch, the vertices the
//! patches of a planar piece share, and the exposure that puts indirect light in the units of
//! the point lights' direct light. Pure geometry on [`Patch`]es, shared by the machine's display
//! (`crate::machine::shooting::indirect`) and the f64 reference image, so both show a solution the same way.
//!
//! Radiosity thesis §1.3.1 ("Visualisation de la scène"): the solution is a value per patch
//! (its centre); for a continuous picture the value at each patch vertex is the mean of the
//! patches around it, then every point is a double linear interpolation of its patch's vertex
//! values (Gouraud's, §1.1.2). Here:
//!
//! * **vertices** ([`Vertices`]): patch corners with bit-identical coordinates on the same
//!   planar piece are one vertex (the subdivision computes a shared corner by one formula, so
//!   neighbours agree to the bit); corners of different pieces never merge, so a crease (a
//!   wall meeting the floor) keeps its discontinuity. A vertex's value is the area-weighted
//!   mean of its patches' values ([`Vertices::average`]).
//! * **weights** ([`weights`]): barycentric in a triangle, inverse bilinear in a quadrilateral
//!   (Newton's method on the bilinear map, which the grid cells of a convex face are), of the
//!   point projected on the patch's plane and clamped to the patch; they are ≥ 0 and sum to 1.
//! * **location** ([`locate`]): the patch of a face that holds a point, or is nearest to holding
//!   it (a voxel centre can lie just outside every patch of its face).
//! * **exposure** ([`exposure`]): direct light is the point lights' (no distance falloff,
//!   intensity `I` each), radiosity is the emitters' (`Ke`, power per area). Per channel c,
//!   `k_c = Σ_j A_j d_j / Σ_j A_j h_jc` over the non-emitting patches j, with `d_j` the point
//!   lights' unshadowed diffuse factor at j's centre (`Σ_s I max(0, N_j·L̂_s)`) and `h_jc` the
//!   emitters' unoccluded irradiance there (`Σ_i E_ic A_i max(0, N_i·ω) max(0, −N_j·ω)/(π r²)`,
//!   centre to centre): the indirect irradiance times `k` is in the point lights' units, and
//!   white-balanced to their white. Geometry only — no visibility and no solution — so the
//!   machine and the reference share one `k`.

use std::collections::HashMap;

use anyhow::{bail, Result};
use parry3d_f64::math::Vector;

use super::patches::{Patch, Patches};

/// How far inside patch `p` the point `x` lies: its smallest signed distance to an edge, in the
/// patch's plane (negative outside).
pub fn inside(p: &Patch, x: Vector) -> f64 {
    let k = p.polygon.len();
    (0..k)
        .map(|i| {
            let (a, b) = (p.polygon[i], p.polygon[(i + 1) % k]);
            let e = b - a;
            e.cross(x - a).dot(p.normal) / e.length().max(f64::MIN_POSITIVE)
        })
        .fold(f64::INFINITY, f64::min)
}

/// The patches of each face: `by_face(p, faces)[f]` lists the patches of face f (`faces` at
/// least; more when a patch names a higher face).
pub fn by_face(patches: &[Patch], faces: usize) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new(); faces.max(patches.iter().map(|p| p.face + 1).max().unwrap_or(0))];
    for (i, p) in patches.iter().enumerate() {
        out[p.face].push(i);
    }
    out
}

/// The patch among `candidates` that holds `x`, or is nearest to holding it (largest
/// [`inside`]); `None` when there is no candidate.
pub fn locate(patches: &[Patch], candidates: &[usize], x: Vector) -> Option<usize> {
    candidates.iter().copied().max_by(|&a, &b| inside(&patches[a], x).total_cmp(&inside(&patches[b], x)))
}

/// Interpolation weights of `x` over the vertices of `p` (in the polygon's order; a triangle's
/// fourth weight is 0): barycentric or inverse bilinear, of `x` projected on the patch's plane,
/// clamped to the patch. Non-negative, summing to 1.
pub fn weights(p: &Patch, x: Vector) -> [f64; 4] {
    let q = &p.polygon;
    // A 2-D frame in the patch's plane.
    let e1 = (q[1] - q[0]).normalize_or_zero();
    let e2 = p.normal.cross(e1);
    let flat = |v: Vector| [(v - q[0]).dot(e1), (v - q[0]).dot(e2)];
    let x2 = flat(x);
    if q.len() == 3 {
        let (b, c) = (flat(q[1]), flat(q[2]));
        let det = b[0] * c[1] - b[1] * c[0];
        let (mut u, mut v) = if det.abs() > 0.0 {
            ((x2[0] * c[1] - x2[1] * c[0]) / det, (b[0] * x2[1] - b[1] * x2[0]) / det)
        } else {
            (1.0 / 3.0, 1.0 / 3.0)
        };
        // Clamp to the triangle: the nearest of its barycentric coordinates' simplex.
        u = u.max(0.0);
        v = v.max(0.0);
        let s = u + v;
        if s > 1.0 {
            (u, v) = (u / s, v / s);
        }
        return [1.0 - u - v, u, v, 0.0];
    }
    let [a, b, c, d] = [flat(q[0]), flat(q[1]), flat(q[2]), flat(q[3])];
    let (s, t) = inverse_bilinear(a, b, c, d, x2);
    [(1.0 - s) * (1.0 - t), s * (1.0 - t), s * t, (1.0 - s) * t]
}

/// (s, t) in [0, 1]² with `(1−t)((1−s)a + s b) + t((1−s)d + s c)` nearest `x`: Newton's method
/// from the centre, clamped at every step.
fn inverse_bilinear(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2], x: [f64; 2]) -> (f64, f64) {
    let at = |s: f64, t: f64, k: usize| (1.0 - t) * ((1.0 - s) * a[k] + s * b[k]) + t * ((1.0 - s) * d[k] + s * c[k]);
    let (mut s, mut t) = (0.5, 0.5);
    for _ in 0..16 {
        let r = [at(s, t, 0) - x[0], at(s, t, 1) - x[1]];
        // ∂/∂s and ∂/∂t of the bilinear map.
        let ds = [0, 1].map(|k| (1.0 - t) * (b[k] - a[k]) + t * (c[k] - d[k]));
        let dt = [0, 1].map(|k| (1.0 - s) * (d[k] - a[k]) + s * (c[k] - b[k]));
        let det = ds[0] * dt[1] - ds[1] * dt[0];
        if det.abs() <= f64::MIN_POSITIVE {
            break;
        }
        let step_s = (r[0] * dt[1] - r[1] * dt[0]) / det;
        let step_t = (ds[0] * r[1] - ds[1] * r[0]) / det;
        s = (s - step_s).clamp(0.0, 1.0);
        t = (t - step_t).clamp(0.0, 1.0);
        if step_s.abs() + step_t.abs() < 1e-13 {
            break;
        }
    }
    (s, t)
}

/// The vertices the patches share (module doc): per patch its vertex ids in polygon order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Vertices {
    /// Vertex ids of each patch's corners (3 or 4).
    pub of_patch: Vec<Vec<u32>>,
    /// Number of vertices.
    pub count: usize,
}

impl Vertices {
    /// Number the corners of `p`'s patches: one id per (piece, exact position), in the order
    /// of first appearance (deterministic).
    pub fn new(p: &Patches) -> Vertices {
        let mut ids: HashMap<(usize, [u64; 3]), u32> = HashMap::new();
        let of_patch = p
            .patches
            .iter()
            .map(|q| {
                q.polygon
                    .iter()
                    .map(|v| {
                        let next = ids.len() as u32;
                        *ids.entry((q.piece, v.to_array().map(f64::to_bits))).or_insert(next)
                    })
                    .collect()
            })
            .collect();
        Vertices { of_patch, count: ids.len() }
    }

    /// Each vertex's value: the area-weighted mean of the values of the patches around it.
    pub fn average(&self, patches: &[Patch], values: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mut sum = vec![[0.0; 3]; self.count];
        let mut area = vec![0.0; self.count];
        for ((ids, p), v) in self.of_patch.iter().zip(patches).zip(values) {
            for &id in ids {
                let id = id as usize;
                area[id] += p.area;
                for c in 0..3 {
                    sum[id][c] += p.area * v[c];
                }
            }
        }
        sum.iter().zip(&area).map(|(s, &a)| if a > 0.0 { s.map(|x| x / a) } else { [0.0; 3] }).collect()
    }

    /// Incidences (patch, vertex): the supervisor's operations for [`Self::average`].
    pub fn incidences(&self) -> usize {
        self.of_patch.iter().map(Vec::len).sum()
    }
}

/// Whether a patch emits.
pub fn emits(p: &Patch) -> bool {
    p.emission.iter().any(|&e| e > 0.0)
}

/// The per-channel exposure of indirect irradiance (module doc): point lights at `lights`
/// (world units) of intensity `intensity` each.
///
/// Errors: no point light, no emitting patch, or emitters that light no non-emitting patch.
pub fn exposure(patches: &[Patch], lights: &[[f64; 3]], intensity: f64) -> Result<[f64; 3]> {
    if lights.is_empty() {
        bail!("radiosity display: no point light to expose indirect light against");
    }
    let emitters: Vec<&Patch> = patches.iter().filter(|p| emits(p)).collect();
    if emitters.is_empty() {
        bail!("radiosity display: no emitting patch (a material with Ke > 0)");
    }
    let (mut direct, mut emitted) = (0.0, [0.0; 3]);
    for j in patches.iter().filter(|p| !emits(p)) {
        let d: f64 = lights
            .iter()
            .map(|l| intensity * j.normal.dot((Vector::from(*l) - j.centroid).normalize_or_zero()).max(0.0))
            .sum();
        direct += j.area * d;
        for i in &emitters {
            let r = j.centroid - i.centroid;
            let r2 = r.length_squared();
            if r2 <= 0.0 {
                continue;
            }
            let w = r / r2.sqrt();
            let g = i.area * i.normal.dot(w).max(0.0) * (-j.normal.dot(w)).max(0.0) / (std::f64::consts::PI * r2);
            for (e, ie) in emitted.iter_mut().zip(i.emission) {
                *e += j.area * g * ie;
            }
        }
    }
    if emitted.iter().all(|&h| h <= 0.0) || !emitted.iter().all(|h| h.is_finite()) {
        bail!("radiosity display: the emitters face no other patch: no indirect light to show");
    }
    Ok(emitted.map(|h| if h > 0.0 { direct / h } else { 0.0 }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::patches::subdivide;
    use crate::scene::{Face, Material, Mesh};

    /// A skewed convex quad and a triangle, cut into patches.
    fn shapes() -> Patches {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [4.0, 0.5, 0.0],
            [4.5, 3.0, 0.0],
            [-0.5, 2.5, 0.0],
            [6.0, 0.0, 1.0],
            [9.0, 0.0, 1.0],
            [7.0, 2.0, 1.0],
        ];
        let faces = vec![Face { verts: vec![0, 1, 2, 3], material: 0 }, Face { verts: vec![4, 5, 6], material: 0 }];
        let m = Mesh { name: "s".into(), positions, faces, materials: vec![Material::default()], ..Default::default() };
        subdivide(&m, 1.0, 1000).unwrap()
    }

    #[test]
    fn weights_reproduce_the_point_and_sum_to_one() {
        let p = shapes();
        for q in &p.patches {
            for (s, t) in [(0.2, 0.7), (0.5, 0.5), (0.9, 0.05), (0.0, 1.0)] {
                // A point inside: bilinear in a quad, (s, t) scaled into the simplex in a triangle.
                let x = if q.polygon.len() == 4 {
                    q.polygon[0].lerp(q.polygon[1], s).lerp(q.polygon[3].lerp(q.polygon[2], s), t)
                } else {
                    let (u, v) = (s * (1.0 - t), t * (1.0 - s));
                    q.polygon[0] + (q.polygon[1] - q.polygon[0]) * u + (q.polygon[2] - q.polygon[0]) * v
                };
                let w = weights(q, x);
                assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12 && w.iter().all(|&a| a >= 0.0), "{w:?}");
                let back: Vector = q.polygon.iter().zip(w).map(|(v, a)| *v * a).sum();
                assert!(back.distance(x) < 1e-9, "{back:?} vs {x:?}");
            }
            // A point off the patch is clamped onto it: weights stay a convex combination.
            let far = q.centroid + (q.polygon[0] - q.centroid) * 3.0 + q.normal * 2.0;
            let w = weights(q, far);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12 && w.iter().all(|&a| a >= 0.0), "{w:?}");
            assert!(w[0] > 0.99, "beyond corner 0: {w:?}");
        }
    }

    #[test]
    fn neighbours_share_vertices_within_a_piece_only_and_averages_are_area_weighted() {
        let p = shapes();
        let v = Vertices::new(&p);
        // The quad face is cut into an m × n grid ((m+1)(n+1) vertices), the triangle into k²
        // triangles ((k+1)(k+2)/2 vertices); the two faces share none.
        let quads = p.patches.iter().filter(|q| q.face == 0).count();
        let tris = p.patches.iter().filter(|q| q.face == 1).count();
        let k = (tris as f64).sqrt().round() as usize;
        assert_eq!(k * k, tris);
        let quad_vertices = v.count - (k + 1) * (k + 2) / 2;
        let ids = |f: usize| -> std::collections::BTreeSet<u32> {
            p.patches.iter().zip(&v.of_patch).filter(|(q, _)| q.face == f).flat_map(|(_, i)| i.clone()).collect()
        };
        assert!(ids(0).is_disjoint(&ids(1)));
        assert_eq!(ids(0).len(), quad_vertices);
        assert!(quad_vertices < 4 * quads, "grid corners are shared");
        // Constant values average to themselves; a patch's value reaches only its own corners.
        let ones = vec![[1.0, 2.0, 3.0]; p.patches.len()];
        assert!(v.average(&p.patches, &ones).iter().all(|a| (a[0] - 1.0).abs() < 1e-12 && (a[2] - 3.0).abs() < 1e-12));
        let mut one_hot = vec![[0.0; 3]; p.patches.len()];
        one_hot[0] = [1.0; 3];
        let avg = v.average(&p.patches, &one_hot);
        for (id, a) in avg.iter().enumerate() {
            let touching: Vec<usize> = (0..p.patches.len()).filter(|&j| v.of_patch[j].contains(&(id as u32))).collect();
            let want = if touching.contains(&0) {
                p.patches[0].area / touching.iter().map(|&j| p.patches[j].area).sum::<f64>()
            } else {
                0.0
            };
            assert!((a[0] - want).abs() < 1e-12, "vertex {id}: {} vs {want}", a[0]);
        }
    }

    #[test]
    fn locate_finds_the_patch_holding_a_point() {
        let p = shapes();
        let faces = by_face(&p.patches, 2);
        for (i, q) in p.patches.iter().enumerate() {
            assert_eq!(locate(&p.patches, &faces[q.face], q.centroid), Some(i));
        }
        assert_eq!(locate(&p.patches, &[], Vector::ZERO), None);
    }

    /// A floor facing up under a square lamp facing down: the exposure matches the closed form
    /// of the lamp's irradiance at the floor's centre against a point light straight above.
    #[test]
    fn exposure_puts_the_emitters_irradiance_in_point_light_units() {
        let (h, s) = (10.0, 0.01);
        let positions = vec![
            [-s, -s, 0.0],
            [s, -s, 0.0],
            [s, s, 0.0],
            [-s, s, 0.0],
            [-0.5, -0.5, h],
            [-0.5, 0.5, h],
            [0.5, 0.5, h],
            [0.5, -0.5, h],
        ];
        let white = Material { name: "w".into(), kd: [0.5; 3], ..Material::default() };
        let lamp = Material { name: "l".into(), ke: [2.0, 4.0, 8.0], ..Material::default() };
        let faces = vec![Face { verts: vec![0, 1, 2, 3], material: 0 }, Face { verts: vec![4, 5, 6, 7], material: 1 }];
        let m = Mesh { name: "f".into(), positions, faces, materials: vec![white, lamp], ..Default::default() };
        let p = subdivide(&m, 10.0, 10).unwrap();
        assert_eq!(p.patches.len(), 2);
        // Centre to centre: h_c = E_c · A · 1 · 1 / (π h²), d = I.
        let k = exposure(&p.patches, &[[0.0, 0.0, 5.0]], 0.5).unwrap();
        for (c, e) in [2.0, 4.0, 8.0].iter().enumerate() {
            let want = 0.5 / (e * 1.0 / (std::f64::consts::PI * h * h));
            assert!((k[c] - want).abs() < 1e-9 * want, "channel {c}: {} vs {want}", k[c]);
        }
        assert!(exposure(&p.patches, &[], 1.0).is_err());
        let dark: Vec<Patch> = p.patches.iter().filter(|q| !emits(q)).cloned().collect();
        assert!(exposure(&dark, &[[0.0; 3]], 1.0).unwrap_err().to_string().contains("no emitting patch"));
    }
}
