//! Smooth shading on the grid (`cell_core::smooth`): the vertex normals each facet packet
//! carries, and each cell's record of its visible point (its facet's vertex normals and the
//! point's barycentric weights).
//!
//! A cell computes its record from the packet in hand whenever the depth test
//! ([`cell_core::visible::depth_test`]) keeps that packet's facet; the record is a function of
//! that packet at that column and of z\* alone. The host simulator computes it once after
//! loading, for the facet the depth test kept, from the same packet stepped to the same
//! column (`T − B`, `T − A`, … as the wave steps it): the same numbers, with the loading engines
//! untouched. Its cost in a cell is what [`SmoothStats`] reports: the packet's extension
//! ([`cell_core::smooth::VertexNormals`]) and the record ([`cell_core::smooth::SmoothSurface`]).

use anyhow::{bail, Result};
use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::normal::NormalCode;
use cell_core::smooth::{record, Smooth, SmoothSurface, VertexNormals};

use crate::machine::loading::loaded_scene::LoadedScene;
use crate::precompute::LoadConfig;
use crate::scene::normals::CornerNormals;
use crate::scene::{Face, Mesh};

/// What smooth shading costs and did, for `render --stats`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SmoothStats {
    /// "phong" or "gouraud".
    pub mode: String,
    /// Where the vertex normals came from: "file" (every face's `vn`), "averaged", or "mixed".
    pub normals_from: String,
    /// Polygons cut into triangles because their corner normals differ.
    pub polygons_cut: usize,
    /// Bytes the vertex normals add to a facet packet (3 × 16-bit octahedral codes).
    pub bytes_per_packet: usize,
    /// Bytes the record adds to a cell (3 normal codes, 3 weights of 16 bits).
    pub bytes_per_cell: usize,
    /// Bits per vertex normal component (octahedral coordinate).
    pub bits_per_normal_component: u32,
    /// Bits per barycentric weight.
    pub bits_per_weight: u32,
    /// Visible facets that are not triangles (flat polygons: one normal, weight 1).
    pub cells_on_polygons: u64,
}

/// The cells' smooth records (index y·n + x; `None` where the column shows no surface).
pub struct SmoothGrid {
    /// Phong or Gouraud.
    pub mode: Smooth,
    /// Per cell.
    pub records: Vec<Option<SmoothSurface>>,
    /// The statistics.
    pub stats: SmoothStats,
}

/// The packet column (x, y) receives: the pipeline packet stepped down to row y, handed east,
/// stepped east to column x.
pub fn row_at(p: &PipelinePacket, x: u32, y: u32) -> RowPacket {
    let mut p = p.clone();
    for _ in 0..y {
        p.step_down();
    }
    let mut row = p.to_row();
    for _ in 0..x {
        row.step_east();
    }
    row
}

/// The unit vector `n` (world) as the cells' normal codes have it: in view space under a
/// camera, and on the side of `facet` (the packet's facet normal code).
fn vertex_code(mesh: &Mesh, n: [f64; 3], facet: NormalCode) -> NormalCode {
    let n = match &mesh.screen {
        Some(s) => s.view.axes.map(|a| a.x * n[0] + a.y * n[1] + a.z * n[2]),
        None => n,
    };
    let f = facet.decode();
    let side = f[0] as f64 * n[0] + f[1] as f64 * n[1] + f[2] as f64 * n[2];
    let n = if side < 0.0 { n.map(|c| -c) } else { n };
    NormalCode::encode(n.map(|c| c as f32))
}

/// What a smooth render loads: the mode and every face's corner normals, for the mesh cut by
/// [`split_for_smooth`].
#[derive(Clone, Debug)]
pub struct SmoothScene {
    /// Phong or Gouraud.
    pub mode: Smooth,
    /// Per face of the cut mesh, per corner: the unit normal (world).
    pub corners: CornerNormals,
    /// Polygons cut into triangles.
    pub polygons_cut: usize,
    /// Where the normals came from: "file", "averaged" or "mixed".
    pub normals_from: &'static str,
}

impl SmoothScene {
    /// The corner normals of `mesh` ([`crate::scene::normals::corner_normals`]) and the mesh cut
    /// so that the cells interpolate over triangles only.
    pub fn new(mesh: Mesh, mode: Smooth) -> Result<(Mesh, SmoothScene)> {
        let corners = crate::scene::normals::corner_normals(&mesh)?;
        let with_file = mesh.face_normals.iter().filter(|c| !c.is_empty()).count();
        let normals_from = match with_file {
            0 => "averaged",
            k if k == mesh.faces.len() => "file",
            _ => "mixed",
        };
        let (mesh, corners, polygons_cut) = split_for_smooth(&mesh, &corners);
        Ok((mesh, SmoothScene { mode, corners, polygons_cut, normals_from }))
    }
}

/// The vertex normals of every packet of `prepared` (packet order; `mesh` prepared): each
/// piece vertex takes the normal of its face's corner at the same lattice point.
pub fn packet_normals(
    mesh: &Mesh,
    corners: &CornerNormals,
    prepared: &crate::precompute::Prepared,
) -> Result<Vec<VertexNormals>> {
    let fit = prepared.fit.expect("fitted");
    let mut out = Vec::with_capacity(prepared.packets.len());
    for ((pkt, piece), &face) in prepared.packets.iter().zip(&prepared.polygons).zip(&prepared.source_face) {
        let f = &mesh.faces[face as usize];
        let lat: Vec<[i64; 3]> =
            f.verts.iter().map(|&v| fit.to_lattice_f64(mesh.positions[v as usize]).map(|c| c.round() as i64)).collect();
        let mut codes = [pkt.tag.normal; 3];
        for (k, code) in codes.iter_mut().enumerate() {
            let Some(p) = piece.get(k) else { break };
            // The corner at this lattice point (the nearest, for a piece cut from a folded polygon).
            let d2 = |l: &[i64; 3]| (0..3).map(|i| (l[i] - p[i]).pow(2)).sum::<i64>();
            let Some(c) = (0..lat.len()).min_by_key(|&i| d2(&lat[i])) else {
                bail!("{}: face {} has no vertices", mesh.name, face + 1);
            };
            *code = vertex_code(mesh, corners[face as usize][c], pkt.tag.normal);
        }
        out.push(VertexNormals(codes));
    }
    Ok(out)
}

/// The cells' records of `scene`, loaded with `load` from `mesh` (the cut mesh of `smooth`).
pub fn smooth_grid(mesh: &Mesh, smooth: &SmoothScene, scene: &LoadedScene, load: &LoadConfig) -> Result<SmoothGrid> {
    let prepared = crate::precompute::prepare(mesh, load)?;
    let normals = packet_normals(mesh, &smooth.corners, &prepared)?;
    let packets = prepared.packets;
    let mut cells_on_polygons = 0;
    let records = scene
        .grid
        .cells
        .iter()
        .map(|c| {
            let s = c.visible.as_ref()?;
            let pkt = &packets[s.facet as usize];
            cells_on_polygons += (pkt.edges.len() != 3) as u64;
            let row = row_at(pkt, c.x as u32, c.y as u32);
            Some(record(&row, normals[s.facet as usize], s.num, s.den))
        })
        .collect();
    Ok(SmoothGrid {
        mode: smooth.mode,
        records,
        stats: SmoothStats {
            mode: match smooth.mode {
                Smooth::Phong => "phong".into(),
                Smooth::Gouraud => "gouraud".into(),
            },
            normals_from: smooth.normals_from.into(),
            polygons_cut: smooth.polygons_cut,
            bytes_per_packet: std::mem::size_of::<VertexNormals>(),
            bytes_per_cell: std::mem::size_of::<SmoothSurface>(),
            bits_per_normal_component: cell_core::smooth::BITS_PER_NORMAL / 2,
            bits_per_weight: cell_core::smooth::BITS_PER_WEIGHT,
            cells_on_polygons,
        },
    })
}

/// The mesh with every polygon whose corner normals are not all equal cut into triangles (ear
/// clipping of its own polygon, [`crate::precompute::triangulate_f64`]; a polygon it cannot cut
/// stays whole), the corner normals that go with it, and how many polygons were cut. Faces keep
/// their order; the triangles of a cut face follow each other where it was.
pub fn split_for_smooth(mesh: &Mesh, corners: &CornerNormals) -> (Mesh, CornerNormals, usize) {
    let (mut faces, mut normals, mut cut) = (Vec::new(), Vec::new(), 0);
    for (f, c) in mesh.faces.iter().zip(corners) {
        let flat = c.iter().all(|n| n == &c[0]);
        let pts: Vec<[f64; 3]> = f.verts.iter().map(|&v| mesh.positions[v as usize]).collect();
        match (f.verts.len() > 3 && !flat).then(|| crate::precompute::triangulate_f64(&pts)) {
            Some(Ok(tris)) => {
                cut += 1;
                for t in tris {
                    faces.push(Face { verts: t.map(|k| f.verts[k]).to_vec(), material: f.material });
                    normals.push(t.map(|k| c[k]).to_vec());
                }
            }
            _ => {
                faces.push(f.clone());
                normals.push(c.clone());
            }
        }
    }
    (Mesh { faces, face_normals: Vec::new(), ..mesh.clone() }, normals, cut)
}
