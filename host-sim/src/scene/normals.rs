//! Vertex normals for smooth shading (§1.3.2): the OBJ file's own (`vn`, `f v//vn`), or
//! averaged over the faces around each vertex.
//!
//! **Invariant: every face gets one unit normal per corner, in world space, on the side of the
//! face its winding says** (a corner normal pointing away from its face's normal is turned
//! over: a vertex normal describes the surface the face belongs to, and the loader
//! ([`crate::scene::meshops::orient`]) may have rewound the face). A face whose corners the file
//! gives normals for uses them; any other face uses the **area-weighted average** of the
//! normals of the faces that share each vertex (Newell's normal of a polygon has twice its area
//! as length, so the plain sum weighs by area). A vertex whose faces cancel takes its face's
//! normal.
//!
//! Bad input is an error naming the face, never a panic: a corner normal index out of range, a
//! face with normals for some corners only, a `vn` that is not a direction (NaN, infinite, zero).
//!
//! The cells interpolate over triangles only ([`cell_core::smooth`]):
//! `machine::shading::smooth_surface::split_for_smooth` cuts the polygons whose corner normals differ into
//! triangles (the machine and the reference then load the same triangles).

use anyhow::{bail, Result};

use super::mesh::{Face, Mesh};

/// Per face, per corner (the face's vertex order): a unit normal in world space.
pub type CornerNormals = Vec<Vec<[f64; 3]>>;

/// Newell's normal of a polygon: twice its area as length, along its winding's normal.
pub fn newell(p: &[[f64; 3]]) -> [f64; 3] {
    let mut n = [0.0f64; 3];
    for (i, a) in p.iter().enumerate() {
        let b = p[(i + 1) % p.len()];
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    n
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `v` over its length; `None` for a zero or non-finite vector.
pub fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let l = dot(v, v).sqrt();
    (l > 0.0 && l.is_finite()).then(|| v.map(|c| c / l))
}

/// The world positions of a mesh (under a camera, those the screen positions came from).
pub fn world_positions(mesh: &Mesh) -> &[[f64; 3]] {
    mesh.screen.as_ref().map_or(&mesh.positions[..], |s| &s.world[..])
}

/// The corner normals of every face (see the module doc).
pub fn corner_normals(mesh: &Mesh) -> Result<CornerNormals> {
    let world = world_positions(mesh);
    let points = |f: &Face| -> Result<Vec<[f64; 3]>> {
        f.verts
            .iter()
            .map(|&v| world.get(v as usize).copied())
            .collect::<Option<_>>()
            .ok_or_else(|| anyhow::anyhow!("{}: a face refers to a vertex the mesh does not have", mesh.name))
    };
    let mut face_n = Vec::with_capacity(mesh.faces.len());
    let mut sum = vec![[0.0f64; 3]; world.len()];
    for f in &mesh.faces {
        let n = newell(&points(f)?);
        let mut verts = f.verts.clone();
        verts.sort_unstable();
        verts.dedup();
        for v in verts {
            let s = &mut sum[v as usize];
            for k in 0..3 {
                s[k] += n[k];
            }
        }
        face_n.push(n);
    }
    let mut out = Vec::with_capacity(mesh.faces.len());
    for (fi, f) in mesh.faces.iter().enumerate() {
        let fnrm = unit(face_n[fi]).unwrap_or([0.0, 0.0, 1.0]);
        let file = mesh.face_normals.get(fi).filter(|c| !c.is_empty());
        if let Some(c) = file {
            if c.len() != f.verts.len() {
                bail!(
                    "{}: face {} gives normals for {} of its {} corners (give one per corner or none)",
                    mesh.name,
                    fi + 1,
                    c.len(),
                    f.verts.len()
                );
            }
        }
        let mut corners = Vec::with_capacity(f.verts.len());
        for (k, &v) in f.verts.iter().enumerate() {
            let n = match file {
                Some(c) => {
                    let i = c[k] as usize;
                    let Some(&vn) = mesh.normals.get(i) else {
                        bail!(
                            "{}: face {} refers to normal {} but the file has {} (vn)",
                            mesh.name,
                            fi + 1,
                            i + 1,
                            mesh.normals.len()
                        );
                    };
                    unit(vn).ok_or_else(|| {
                        anyhow::anyhow!(
                            "{}: normal {} (vn {} {} {}) of face {} is not a direction (NaN, infinite or zero length)",
                            mesh.name,
                            i + 1,
                            vn[0],
                            vn[1],
                            vn[2],
                            fi + 1
                        )
                    })?
                }
                None => unit(sum[v as usize]).unwrap_or(fnrm),
            };
            corners.push(if dot(n, fnrm) < 0.0 { n.map(|c| -c) } else { n });
        }
        out.push(corners);
    }
    Ok(out)
}
