//! Mesh utilities: midpoint subdivision (to build large benchmark meshes) and OBJ output.

use std::collections::HashMap;
use std::io::Write;

use anyhow::Result;

use crate::scene::{Face, Mesh};

/// Triangulate polygons as fans (for meshes that are then subdivided).
pub fn triangulated(mesh: &Mesh) -> Mesh {
    let mut out = Mesh { faces: Vec::new(), ..mesh.clone() };
    for f in &mesh.faces {
        for k in 1..f.verts.len().saturating_sub(1) {
            out.faces.push(Face { verts: vec![f.verts[0], f.verts[k], f.verts[k + 1]], material: f.material });
        }
    }
    out
}

/// Split triangles 1 → 4 at edge midpoints (watertight: shared edges share their midpoint),
/// level after level until the mesh has at least `target` triangles. In the last level only the
/// largest triangles are split, so the count lands close to the target (that level may leave
/// T-junctions, harmless for benchmarks).
pub fn subdivide_to(mesh: &Mesh, target: usize) -> Mesh {
    let mut m = triangulated(mesh);
    while m.faces.len() < target {
        let need = (target - m.faces.len()).div_ceil(3);
        let mut order: Vec<usize> = (0..m.faces.len()).collect();
        if need < m.faces.len() {
            let area = |f: &Face| {
                let p = |i: usize| m.positions[f.verts[i] as usize];
                let (a, b, c) = (p(0), p(1), p(2));
                let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
                n[0] * n[0] + n[1] * n[1] + n[2] * n[2]
            };
            order.sort_by(|&i, &j| area(&m.faces[j]).total_cmp(&area(&m.faces[i])));
            order.truncate(need);
        }
        let mut split = vec![false; m.faces.len()];
        for &i in &order {
            split[i] = true;
        }
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut positions = m.positions.clone();
        let mut midpoint = |a: u32, b: u32| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (m.positions[a as usize], m.positions[b as usize]);
                positions.push([(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0, (p[2] + q[2]) / 2.0]);
                (positions.len() - 1) as u32
            })
        };
        let mut faces = Vec::with_capacity(m.faces.len() + 3 * order.len());
        for (i, f) in m.faces.iter().enumerate() {
            if !split[i] {
                faces.push(f.clone());
                continue;
            }
            let [a, b, c] = [f.verts[0], f.verts[1], f.verts[2]];
            let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
            for t in [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]] {
                faces.push(Face { verts: t.to_vec(), material: f.material });
            }
        }
        m.positions = positions;
        m.faces = faces;
    }
    m
}

/// Write a mesh as OBJ (positions and faces only).
pub fn write_obj(mesh: &Mesh, mut w: impl Write) -> Result<()> {
    writeln!(w, "# {} — written by rc2 host-sim, {} faces", mesh.name, mesh.faces.len())?;
    for p in &mesh.positions {
        writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
    }
    for f in &mesh.faces {
        write!(w, "f")?;
        for v in &f.verts {
            write!(w, " {}", v + 1)?;
        }
        writeln!(w)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subdivision_reaches_target_and_keeps_closed_meshes_closed() {
        let m = crate::scene::load("cow").unwrap();
        let s = subdivide_to(&m, 4 * m.faces.len());
        assert_eq!(s.faces.len(), 4 * m.faces.len());
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        for f in &s.faces {
            for k in 0..3 {
                let (a, b) = (f.verts[k], f.verts[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(edges.values().all(|&c| c == 2), "every edge shared by exactly two triangles");
        let t = subdivide_to(&m, 70_000);
        assert!(t.faces.len() >= 70_000 && t.faces.len() < 70_003, "{}", t.faces.len());
    }
}
