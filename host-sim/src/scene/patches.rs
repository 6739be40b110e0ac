//! Radiosity patches: a [`Mesh`] cut into small planar convex polygons, each carrying the
//! reflectance and emission of its face (radiosity thesis, §1.3.3: the surfaces are cut into
//! elements on which the radiosity is taken as constant).
//!
//! Invariants of a [`Patches`] built by [`subdivide`]:
//! * every patch is a planar convex polygon of 3 or 4 vertices, every edge at most the requested
//!   size (world units), wound like its face; its [`Patch::normal`] is its face's unit normal
//!   (right-hand rule on the winding, Newell's method) — patches are one-sided;
//! * the patches of a face tile it exactly: their areas sum to the face's area (up to rounding);
//! * the subdivision is deterministic (no randomness, no hashing of positions);
//! * zero-area faces are skipped and counted ([`PatchSummary::degenerate_faces`]), never an error.
//!
//! How a face is cut:
//! * a triangle: regular subdivision into k² similar triangles (every edge cut into k equal parts,
//!   k = ⌈longest edge / size⌉), see [`split_triangle`];
//! * a planar convex quadrilateral: an m × n grid of quadrilaterals (bilinear interpolation of the
//!   corners; m, n = ⌈longer of each pair of opposite edges / size⌉);
//! * any other polygon (more vertices, non-convex, non-planar): triangulated first (ear clipping in
//!   the plane of its Newell normal), then each triangle as above. A planar face stays one
//!   [`Piece`]; a non-planar one becomes one piece per triangle, each with its own normal.
//!
//! [`Piece`]s are the planar parts of the surfaces (a face, or one triangle of a non-planar face):
//! the exact-visibility reference is built on their triangles, one facet id per piece, so that a
//! ray between two patches can ignore the two planes it starts and ends on.

use anyhow::{bail, Result};
use parry3d_f64::math::Vector;

use super::mesh::Mesh;

/// Newell's area vector of a polygon: its direction is the winding normal, its length the area
/// (exact for a planar polygon). Half the sum of the cross products of its fan from the first
/// vertex; zero for fewer than three vertices.
pub fn area_vector(poly: &[Vector]) -> Vector {
    let fan = (1..poly.len().saturating_sub(1)).map(|k| (poly[k] - poly[0]).cross(poly[k + 1] - poly[0]));
    fan.sum::<Vector>() * 0.5
}

/// A face is zero-area when twice its area is at most this fraction of its perimeter squared.
pub const DEGENERATE_RATIO: f64 = 1e-12;

/// A polygon is planar when every vertex lies within this fraction of its diameter from the
/// plane through its first vertex with its Newell normal.
pub const PLANARITY_TOL: f64 = 1e-9;

/// One radiosity patch. Positions and directions are [`Vector`]s (glam's `DVec3`, the vector type
/// of parry3d-f64, which the exact-visibility reference is built on).
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// The polygon (3 or 4 vertices, planar and convex, wound like its face), world coordinates.
    pub polygon: Vec<Vector>,
    /// The polygon as a fan of 1 or 2 triangles from its first vertex.
    pub triangles: Vec<[Vector; 3]>,
    /// Area (world units²).
    pub area: f64,
    /// Unit normal: the face's (its piece's) normal, the side the patch emits and receives on.
    pub normal: Vector,
    /// Area centroid (world coordinates).
    pub centroid: Vector,
    /// Diffuse reflectance ρ per channel: the material's `Kd`.
    pub reflectance: [f64; 3],
    /// Emission per channel: the material's `Ke`, taken as emitted radiosity (radiant
    /// exitance, power per unit area, in the scene's units).
    pub emission: [f64; 3],
    /// Index of the source face in [`Mesh::faces`].
    pub face: usize,
    /// Index of the planar piece it lies on in [`Patches::pieces`] (its visibility facet id).
    pub piece: usize,
}

/// A planar part of the surface: a whole planar face, or one triangle of a non-planar face.
#[derive(Clone, Debug, PartialEq)]
pub struct Piece {
    /// Index of the source face in [`Mesh::faces`].
    pub face: usize,
    /// Unit normal.
    pub normal: Vector,
    /// Triangles covering it exactly (for the visibility reference), world coordinates.
    pub triangles: Vec<[Vector; 3]>,
}

/// What [`subdivide`] did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PatchSummary {
    /// Faces in the mesh.
    pub faces: usize,
    /// Faces skipped as zero-area (fewer than three distinct vertices, collinear, or twice the
    /// area at most [`DEGENERATE_RATIO`] × perimeter²).
    pub degenerate_faces: usize,
    /// Faces triangulated before cutting (more than 4 vertices, non-convex or non-planar).
    pub triangulated_faces: usize,
    /// Of which non-planar (one piece per triangle).
    pub non_planar_faces: usize,
    /// Faces whose ear clipping failed (self-intersecting outline): fanned from their first vertex.
    pub fanned_faces: usize,
    /// Patches made.
    pub patches: usize,
    /// Total patch area.
    pub area: f64,
    /// The largest patch edge allowed (world units).
    pub size: f64,
}

/// The patches of a mesh, its planar pieces, and what was done.
#[derive(Clone, Debug, Default)]
pub struct Patches {
    /// The patches, face by face in mesh order.
    pub patches: Vec<Patch>,
    /// The planar pieces the patches lie on.
    pub pieces: Vec<Piece>,
    /// Counts.
    pub summary: PatchSummary,
}

/// How one planar piece of a face is cut.
enum Cut {
    /// A convex quadrilateral into an m × n grid.
    Grid { quad: [Vector; 4], m: usize, n: usize },
    /// Triangles, each into k² (k per triangle).
    Triangles(Vec<([Vector; 3], usize)>),
}

/// One planar piece of a face before cutting.
struct Plan {
    face: usize,
    normal: Vector,
    cut: Cut,
}

/// Cut `mesh` into patches whose edges are at most `size` world units.
///
/// Errors: `size` not a positive finite number; a face referring to a missing vertex or
/// material; a face vertex with a NaN or infinite coordinate; more than `max_patches` patches
/// (counted before any is made).
pub fn subdivide(mesh: &Mesh, size: f64, max_patches: usize) -> Result<Patches> {
    if !(size.is_finite() && size > 0.0) {
        bail!("patches: the patch size must be a positive finite length, got {size}");
    }
    let mut summary = PatchSummary { faces: mesh.faces.len(), size, ..Default::default() };
    let mut plans = Vec::new();
    for fi in 0..mesh.faces.len() {
        let poly = face_polygon(mesh, fi)?;
        plan_face(fi, poly, size, &mut plans, &mut summary);
    }
    let count = plans.iter().fold(0u128, |acc, p| acc.saturating_add(cut_count(&p.cut)));
    if count > max_patches as u128 {
        bail!(
            "patches: {} at size {size} would make {count} patches, above the cap of {max_patches} \
             (raise the cap or the patch size)",
            mesh.name
        );
    }
    let mut out = Patches { summary, ..Default::default() };
    for plan in plans {
        build_piece(mesh, plan, &mut out);
    }
    out.summary.patches = out.patches.len();
    out.summary.area = out.patches.iter().map(|p| p.area).sum();
    Ok(out)
}

/// [`subdivide`] with the size in voxels of a grid fit: `voxels × voxel_world`, where
/// `voxel_world` is the world size of one voxel (`precompute::Fit::voxel` of the machine's fit).
pub fn subdivide_voxels(mesh: &Mesh, voxels: f64, voxel_world: f64, max_patches: usize) -> Result<Patches> {
    if !(voxels.is_finite() && voxels > 0.0) {
        bail!("patches: the patch size in voxels must be positive and finite, got {voxels}");
    }
    if !(voxel_world.is_finite() && voxel_world > 0.0) {
        bail!("patches: the voxel size must be positive and finite, got {voxel_world}");
    }
    subdivide(mesh, voxels * voxel_world, max_patches)
}

/// Split a triangle into k² similar triangles: each edge cut into k equal parts (k ≥ 1), rows
/// from the first vertex; every edge of a piece is 1/k of the parallel edge of the triangle, the
/// pieces have equal areas and the winding of the triangle. k = 0 gives nothing.
pub fn split_triangle(tri: [Vector; 3], k: usize) -> Vec<[Vector; 3]> {
    let kf = k as f64;
    let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
    let p = |i: usize, j: usize| tri[0] + (e1 * (i as f64 / kf) + e2 * (j as f64 / kf));
    let mut out = Vec::with_capacity(k * k);
    for i in 0..k {
        for j in 0..k - i {
            out.push([p(i, j), p(i + 1, j), p(i, j + 1)]);
            if j + 1 < k - i {
                out.push([p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
            }
        }
    }
    out
}

/// The face's vertices (consecutive repeats removed), checked.
fn face_polygon(mesh: &Mesh, fi: usize) -> Result<Vec<Vector>> {
    let f = &mesh.faces[fi];
    if f.material as usize >= mesh.materials.len() {
        bail!("patches: face {fi} uses material {} but the mesh has {}", f.material, mesh.materials.len());
    }
    let mut poly: Vec<Vector> = Vec::with_capacity(f.verts.len());
    for &v in &f.verts {
        let Some(&p) = mesh.positions.get(v as usize) else {
            bail!("patches: face {fi} refers to vertex {v} but the mesh has {}", mesh.positions.len());
        };
        if !p.iter().all(|c| c.is_finite()) {
            bail!("patches: face {fi} uses vertex {v} with a non-finite coordinate {p:?}");
        }
        let p = Vector::from(p);
        if poly.last() != Some(&p) {
            poly.push(p);
        }
    }
    while poly.len() > 1 && poly.first() == poly.last() {
        poly.pop();
    }
    Ok(poly)
}

/// Classify one face and push its planar pieces' plans (or count it as degenerate).
fn plan_face(fi: usize, poly: Vec<Vector>, size: f64, plans: &mut Vec<Plan>, summary: &mut PatchSummary) {
    let av = area_vector(&poly);
    let perimeter: f64 = (0..poly.len()).map(|i| poly[(i + 1) % poly.len()].distance(poly[i])).sum();
    let twice_area = 2.0 * av.length();
    if poly.len() < 3 || twice_area.is_nan() || twice_area <= DEGENERATE_RATIO * perimeter * perimeter {
        summary.degenerate_faces += 1;
        return;
    }
    let normal = av.normalize();
    let planar = is_planar(&poly, normal);
    if poly.len() == 3 {
        let tri = [poly[0], poly[1], poly[2]];
        plans.push(Plan { face: fi, normal, cut: Cut::Triangles(vec![(tri, divisions(&tri, size))]) });
        return;
    }
    if poly.len() == 4 && planar && is_convex(&poly, normal) {
        let quad = [poly[0], poly[1], poly[2], poly[3]];
        let m = edge_divisions(quad[1].distance(quad[0]).max(quad[2].distance(quad[3])), size);
        let n = edge_divisions(quad[3].distance(quad[0]).max(quad[2].distance(quad[1])), size);
        plans.push(Plan { face: fi, normal, cut: Cut::Grid { quad, m, n } });
        return;
    }
    summary.triangulated_faces += 1;
    let tris = match ear_clip(&poly, normal) {
        Some(t) => t,
        None => {
            summary.fanned_faces += 1;
            (1..poly.len() - 1).map(|k| [poly[0], poly[k], poly[k + 1]]).collect()
        }
    };
    let nonzero = |t: &[Vector; 3]| area_vector(t).length() > 0.0;
    if planar {
        let cut = tris.iter().filter(|t| nonzero(t)).map(|t| (*t, divisions(t, size))).collect();
        plans.push(Plan { face: fi, normal, cut: Cut::Triangles(cut) });
    } else {
        summary.non_planar_faces += 1;
        for t in tris.into_iter().filter(nonzero) {
            let normal = area_vector(&t).normalize();
            plans.push(Plan { face: fi, normal, cut: Cut::Triangles(vec![(t, divisions(&t, size))]) });
        }
    }
}

/// ⌈length / size⌉, at least 1 (saturating: the patch cap refuses absurd counts).
fn edge_divisions(length: f64, size: f64) -> usize {
    let k = (length / size).ceil();
    if k >= usize::MAX as f64 {
        usize::MAX
    } else {
        (k as usize).max(1)
    }
}

/// Divisions per edge of a triangle: by its longest edge.
fn divisions(t: &[Vector; 3], size: f64) -> usize {
    let longest = (0..3).map(|i| t[(i + 1) % 3].distance(t[i])).fold(0.0, f64::max);
    edge_divisions(longest, size)
}

/// Patches a plan makes (as u128: no overflow for any k).
fn cut_count(cut: &Cut) -> u128 {
    match cut {
        Cut::Grid { m, n, .. } => *m as u128 * *n as u128,
        Cut::Triangles(ts) => ts.iter().fold(0u128, |s, (_, k)| s.saturating_add(*k as u128 * *k as u128)),
    }
}

fn is_planar(poly: &[Vector], normal: Vector) -> bool {
    let diameter = poly.iter().flat_map(|a| poly.iter().map(move |b| a.distance(*b))).fold(0.0, f64::max);
    poly.iter().all(|p| (*p - poly[0]).dot(normal).abs() <= PLANARITY_TOL * diameter)
}

/// Strictly convex, turning the way of `normal` at every vertex.
fn is_convex(poly: &[Vector], normal: Vector) -> bool {
    let n = poly.len();
    (0..n).all(|i| {
        let (a, b, c) = (poly[i], poly[(i + 1) % n], poly[(i + 2) % n]);
        (b - a).cross(c - b).dot(normal) > 0.0
    })
}

/// Ear clipping in the plane of `normal` (the polygon wound counter-clockwise about it);
/// `None` when no ear is found (a self-intersecting outline).
fn ear_clip(poly: &[Vector], normal: Vector) -> Option<Vec<[Vector; 3]>> {
    let area2 = |a: Vector, b: Vector, c: Vector| (b - a).cross(c - a).dot(normal);
    let mut idx: Vec<usize> = (0..poly.len()).collect();
    let mut out = Vec::with_capacity(poly.len() - 2);
    while idx.len() > 3 {
        let n = idx.len();
        let ear = (0..n).find(|&i| {
            let (a, b, c) = (poly[idx[(i + n - 1) % n]], poly[idx[i]], poly[idx[(i + 1) % n]]);
            area2(a, b, c) > 0.0
                && idx.iter().all(|&j| {
                    let p = poly[j];
                    p == a
                        || p == b
                        || p == c
                        || !(area2(a, b, p) >= 0.0 && area2(b, c, p) >= 0.0 && area2(c, a, p) >= 0.0)
                })
        })?;
        out.push([poly[idx[(ear + n - 1) % n]], poly[idx[ear]], poly[idx[(ear + 1) % n]]]);
        idx.remove(ear);
    }
    out.push([poly[idx[0]], poly[idx[1]], poly[idx[2]]]);
    Some(out)
}

/// Make the patches of one planar piece and record the piece.
fn build_piece(mesh: &Mesh, plan: Plan, out: &mut Patches) {
    let mat = &mesh.materials[mesh.faces[plan.face].material as usize];
    let reflectance = mat.kd.map(f64::from);
    let emission = mat.ke.map(f64::from);
    let piece = out.pieces.len();
    let make = |polygon: Vec<Vector>| patch(polygon, plan.normal, reflectance, emission, plan.face, piece);
    let triangles = match &plan.cut {
        Cut::Grid { quad, m, n } => {
            out.patches.extend(grid_cells(quad, *m, *n).into_iter().map(make));
            vec![[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]]
        }
        Cut::Triangles(ts) => {
            for (t, k) in ts {
                out.patches.extend(split_triangle(*t, *k).into_iter().map(|s| make(s.to_vec())));
            }
            ts.iter().map(|(t, _)| *t).collect()
        }
    };
    out.pieces.push(Piece { face: plan.face, normal: plan.normal, triangles });
}

/// The m × n cells of a convex planar quadrilateral (bilinear in its corners).
fn grid_cells(q: &[Vector; 4], m: usize, n: usize) -> Vec<Vec<Vector>> {
    let at = |a: usize, b: usize| {
        let (s, t) = (a as f64 / m as f64, b as f64 / n as f64);
        q[0].lerp(q[1], s).lerp(q[3].lerp(q[2], s), t)
    };
    let mut cells = Vec::with_capacity(m * n);
    for b in 0..n {
        for a in 0..m {
            cells.push(vec![at(a, b), at(a + 1, b), at(a + 1, b + 1), at(a, b + 1)]);
        }
    }
    cells
}

fn patch(
    polygon: Vec<Vector>,
    normal: Vector,
    reflectance: [f64; 3],
    emission: [f64; 3],
    face: usize,
    piece: usize,
) -> Patch {
    let triangles: Vec<[Vector; 3]> =
        (1..polygon.len() - 1).map(|k| [polygon[0], polygon[k], polygon[k + 1]]).collect();
    let mut area = 0.0;
    let mut moment = Vector::ZERO;
    for t in &triangles {
        let a = area_vector(t).dot(normal);
        area += a;
        moment += (t[0] + t[1] + t[2]) * (a / 3.0);
    }
    let centroid = if area > 0.0 { moment / area } else { polygon[0] };
    Patch { polygon, triangles, area, normal, centroid, reflectance, emission, face, piece }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Face, Material};

    fn mesh(positions: Vec<[f64; 3]>, faces: Vec<Vec<u32>>) -> Mesh {
        let faces = faces.into_iter().map(|verts| Face { verts, material: 1 }).collect();
        let lamp = Material { name: "lamp".into(), kd: [0.5, 0.25, 0.125], ke: [3.0, 2.0, 1.0], ..Material::default() };
        Mesh { name: "t".into(), positions, faces, materials: vec![Material::default(), lamp], ..Default::default() }
    }

    /// Independent area of a planar polygon: half the norm of the sum of its edges' cross
    /// products about the origin (the shoelace formula in 3-D).
    fn shoelace(poly: &[Vector]) -> (f64, Vector) {
        let s: Vector = (0..poly.len()).map(|i| poly[i].cross(poly[(i + 1) % poly.len()])).sum();
        (s.length() / 2.0, s.normalize())
    }

    /// The face's vertices as vectors.
    fn face_vertices(m: &Mesh, fi: usize) -> Vec<Vector> {
        m.faces[fi].verts.iter().map(|&v| Vector::from(m.positions[v as usize])).collect()
    }

    /// A mesh of every kind of face: triangle, rectangle, skewed convex quad, non-convex hexagon
    /// (an L), a pentagon, a non-planar quad.
    fn assorted() -> Mesh {
        #[rustfmt::skip]
        let positions = vec![
            [0.0, 0.0, 0.0], [3.0, 0.2, 0.0], [1.0, 2.5, 0.7], // triangle 0..3
            [5.0, 0.0, 0.0], [9.0, 0.0, 0.0], [9.0, 0.0, 3.0], [5.0, 0.0, 3.0], // rectangle 3..7
            [0.0, 4.0, 0.0], [4.0, 4.5, 0.0], [3.5, 7.0, 0.0], [0.5, 6.0, 0.0], // skewed quad 7..11
            [0.0, 0.0, 5.0], [4.0, 0.0, 5.0], [4.0, 1.0, 5.0], [1.0, 1.0, 5.0], [1.0, 3.0, 5.0], [0.0, 3.0, 5.0], // L 11..17
            [6.0, 6.0, 1.0], [8.0, 6.0, 1.5], [8.5, 7.5, 1.925], [7.0, 8.5, 1.75], [5.5, 7.5, 1.175], // planar pentagon 17..22
            [10.0, 0.0, 0.0], [12.0, 0.0, 0.0], [12.0, 2.0, 0.3], [10.0, 2.0, 0.0], // non-planar 22..26
        ];
        let faces = vec![
            vec![0, 1, 2],
            vec![3, 4, 5, 6],
            vec![7, 8, 9, 10],
            vec![11, 12, 13, 14, 15, 16],
            vec![17, 18, 19, 20, 21],
            vec![22, 23, 24, 25],
        ];
        mesh(positions, faces)
    }

    #[test]
    fn areas_sum_to_the_faces_and_every_edge_is_at_most_the_size() {
        let m = assorted();
        for size in [0.3, 0.77, 1.0, 2.5, 100.0] {
            let p = subdivide(&m, size, 1_000_000).unwrap();
            for fi in 0..m.faces.len() {
                let poly = face_vertices(&m, fi);
                let got: f64 = p.patches.iter().filter(|q| q.face == fi).map(|q| q.area).sum();
                let want = if fi == 5 {
                    // non-planar: the two triangles of the diagonal the ear clipping takes (1–3)
                    shoelace(&[poly[3], poly[0], poly[1]]).0 + shoelace(&[poly[1], poly[2], poly[3]]).0
                } else {
                    shoelace(&poly).0
                };
                assert!((got - want).abs() <= 1e-9 * want, "size {size} face {fi}: {got} vs {want}");
            }
            for q in &p.patches {
                assert!(q.polygon.len() == 3 || q.polygon.len() == 4);
                for k in 0..q.polygon.len() {
                    let e = q.polygon[(k + 1) % q.polygon.len()].distance(q.polygon[k]);
                    assert!(e <= size * (1.0 + 1e-12), "size {size}: edge {e} of a patch of face {}", q.face);
                }
                assert!((q.area - shoelace(&q.polygon).0).abs() <= 1e-9 * q.area);
            }
            assert_eq!(p.summary.patches, p.patches.len());
            assert_eq!((p.summary.triangulated_faces, p.summary.non_planar_faces, p.summary.fanned_faces), (3, 1, 0));
        }
    }

    #[test]
    fn normals_are_the_face_normals_and_patches_are_convex_and_in_the_face_plane() {
        let m = assorted();
        let p = subdivide(&m, 0.6, 1_000_000).unwrap();
        for q in &p.patches {
            let poly = face_vertices(&m, q.face);
            let own = shoelace(&q.polygon).1;
            assert!(own.dot(q.normal) > 1.0 - 1e-12, "patch of face {} wound against its normal", q.face);
            assert!(is_convex(&q.polygon, q.normal));
            assert_eq!(q.normal, p.pieces[q.piece].normal);
            if q.face != 5 {
                let n = shoelace(&poly).1;
                assert!(q.normal.distance(n) < 1e-12, "face {}: {:?} vs {:?}", q.face, q.normal, n);
                for v in &q.polygon {
                    assert!((*v - poly[0]).dot(n).abs() < 1e-12 * 10.0);
                }
            }
            assert_eq!(q.emission, [3.0, 2.0, 1.0]);
            assert_eq!(q.reflectance, [0.5, 0.25, 0.125]);
            let c = q.polygon.iter().sum::<Vector>() / q.polygon.len() as f64;
            assert!(c.distance(q.centroid) < 0.6, "centroid inside the patch's neighbourhood");
        }
        // The L's patches lie inside the L (not in its notch [1,4]×[1,3]).
        for q in p.patches.iter().filter(|q| q.face == 3) {
            assert!(!(q.centroid.x > 1.0 && q.centroid.y > 1.0), "{:?}", q.centroid);
        }
    }

    #[test]
    fn zero_area_faces_are_skipped_and_counted() {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 2.0, 2.0],
            [3.0, 3.0, 3.0],
            [4.0, 4.0, 4.0], // collinear
        ];
        let m = mesh(positions, vec![vec![0, 1, 2], vec![3, 4, 5], vec![0, 0, 1], vec![2, 2, 2, 2], vec![0, 1, 1, 0]]);
        let p = subdivide(&m, 0.5, 1000).unwrap();
        assert_eq!(p.summary.degenerate_faces, 4);
        assert_eq!(p.summary.faces, 5);
        assert!(p.patches.iter().all(|q| q.face == 0));
        assert!((p.summary.area - 0.5).abs() < 1e-15);
        assert_eq!(p.patches.len(), 9, "hypotenuse √2 at size 0.5: k = 3");
    }

    #[test]
    fn bad_input_is_a_clear_error() {
        let m = assorted();
        for size in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(subdivide(&m, size, 1000).is_err(), "size {size}");
        }
        let e = subdivide(&m, 0.01, 5000).unwrap_err().to_string();
        assert!(e.contains("cap of 5000"), "{e}");
        assert!(subdivide(&m, 1e-300, usize::MAX).is_err(), "an absurd count is refused, not allocated");
        let mut nan = assorted();
        nan.positions[4][1] = f64::NAN;
        let e = subdivide(&nan, 1.0, 1000).unwrap_err().to_string();
        assert!(e.contains("face 1") && e.contains("non-finite"), "{e}");
        let mut bad = assorted();
        bad.faces[2].verts[1] = 999;
        assert!(subdivide(&bad, 1.0, 1000).unwrap_err().to_string().contains("vertex 999"));
        let mut bad = assorted();
        bad.faces[0].material = 7;
        assert!(subdivide(&bad, 1.0, 1000).unwrap_err().to_string().contains("material 7"));
        assert!(subdivide_voxels(&m, 0.0, 1.0, 1000).is_err());
        assert!(subdivide_voxels(&m, 2.0, f64::NAN, 1000).is_err());
        let a = subdivide_voxels(&m, 2.0, 0.25, 100_000).unwrap();
        assert_eq!(a.patches, subdivide(&m, 0.5, 100_000).unwrap().patches);
    }

    #[test]
    fn subdivision_is_deterministic_and_conforms_to_the_size() {
        let m = crate::scene::load("cornell").unwrap();
        let a = subdivide(&m, 100.0, 10_000).unwrap();
        let b = subdivide(&m, 100.0, 10_000).unwrap();
        assert_eq!(a.patches, b.patches);
        assert!((300..400).contains(&a.patches.len()), "{}", a.patches.len());
        // The light (face 1, material "light") becomes emitting patches facing down.
        let light: Vec<&Patch> = a.patches.iter().filter(|p| p.face == 1).collect();
        assert!(!light.is_empty() && light.iter().all(|p| p.emission == [17.0, 12.0, 4.0] && p.normal.y < -0.999));
    }

    #[test]
    fn split_triangle_makes_similar_equal_pieces() {
        let t = [Vector::new(0.0, 0.0, 0.0), Vector::new(3.0, 0.5, 0.0), Vector::new(1.0, 2.0, 1.0)];
        let twice_area = |t: &[Vector; 3]| (t[1] - t[0]).cross(t[2] - t[0]);
        let area = |t: &[Vector; 3]| twice_area(t).length() / 2.0;
        for k in 1..7 {
            let s = split_triangle(t, k);
            assert_eq!(s.len(), k * k);
            let total: f64 = s.iter().map(area).sum();
            assert!((total - area(&t)).abs() < 1e-12);
            for p in &s {
                assert!((area(p) - area(&t) / (k * k) as f64).abs() < 1e-12);
                assert!(twice_area(p).dot(twice_area(&t)) > 0.0, "winding kept");
            }
        }
        assert!(split_triangle(t, 0).is_empty());
    }
}
