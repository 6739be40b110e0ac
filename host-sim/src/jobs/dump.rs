//! `light --dump-lit F.json`: everything an outside tool needs to check the lighting phase on
//! its own — the scene's triangles in world units, the world ↔ grid mapping, the lights where
//! the cells diffused them, and every occupied voxel with the sources that lit it (0: none).
//!
//! Used by `bench/compare.py` to cast exact shadow rays with Embree from the same voxels toward
//! the same lights. Voxel (x, y, z) (binvox indexing) has its centre at world
//! `origin + (v + ½)·voxel` on each axis, and a light at voxel-unit position p is at world
//! `origin + (p + ½)·voxel` ([`crate::machine::loading::loaded_scene::voxel_to_world`]). Polygons are written as
//! triangle fans over their original vertices.

use std::io::Write;

use anyhow::Result;

use crate::machine::grid::LightGrid;
use crate::machine::lighting::diffuse::Lighting;
use crate::machine::lighting::run::LightStats;
use crate::machine::loading::loaded_scene::voxel_to_world;
use crate::precompute::Fit;
use crate::scene::Mesh;

/// The JSON document `--dump-lit` writes.
#[derive(serde::Serialize)]
pub struct LitDump<'a> {
    /// Scene name.
    pub scene: &'a str,
    /// Grid side (and depth).
    pub n: u32,
    /// World position of the grid's low corner.
    pub origin: [f64; 3],
    /// World size of a voxel.
    pub voxel: f64,
    /// Light positions in voxel units, as the cells used them (1/16-voxel lattice).
    pub lights_voxel: Vec<[f64; 3]>,
    /// The same in world units.
    pub lights_world: Vec<[f64; 3]>,
    /// Vertex positions, world units, flattened `x, y, z, …`.
    pub vertices: Vec<f64>,
    /// Triangles (fans of the mesh's polygons), vertex indices flattened `a, b, c, …`.
    pub triangles: Vec<u32>,
    /// Every occupied voxel, flattened `x, y, z, source_mask, …` in (y, x, z) order.
    pub voxels: Vec<u32>,
    /// Wall time of the diffusion (s).
    pub diffusion_seconds: f64,
    /// Lighting cycles, summed over sources.
    pub cycles: u64,
    /// Beams processed, summed over sources.
    pub beams_processed: u64,
}

/// Build the dump of a finished diffusion.
pub fn lit_dump<'a>(
    mesh: &'a Mesh,
    grid: &LightGrid,
    fit: &Fit,
    lighting: &Lighting,
    stats: &LightStats,
) -> LitDump<'a> {
    let lights_voxel: Vec<[f64; 3]> = lighting.reports.iter().map(|r| r.position).collect();
    let mut triangles = Vec::new();
    for f in &mesh.faces {
        for k in 1..f.verts.len().saturating_sub(1) {
            triangles.extend_from_slice(&[f.verts[0], f.verts[k], f.verts[k + 1]]);
        }
    }
    let mut voxels = Vec::new();
    for c in &grid.cells {
        for d in c.store.dexels() {
            for z in d.span.lo..=d.span.hi {
                let mask = lighting.mask(c.x as u32, c.y as u32, z);
                voxels.extend_from_slice(&[c.x as u32, c.y as u32, z as u32, mask]);
            }
        }
    }
    LitDump {
        scene: &mesh.name,
        n: grid.n,
        origin: fit.origin,
        voxel: fit.voxel,
        lights_world: lights_voxel.iter().map(|p| voxel_to_world(fit, *p)).collect(),
        lights_voxel,
        vertices: mesh.positions.iter().flatten().copied().collect(),
        triangles,
        voxels,
        diffusion_seconds: stats.wall_seconds,
        cycles: stats.totals.cycles,
        beams_processed: stats.totals.beams_processed,
    }
}

/// Write the dump as JSON.
pub fn write_lit_dump(d: &LitDump<'_>, w: impl Write) -> Result<()> {
    serde_json::to_writer(w, d)?;
    Ok(())
}
