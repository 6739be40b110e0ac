//! The `voxelize` job: load a scene with the RC² loading wave (§3) or the direct host
//! evaluation, summarise the grid and write it as a .binvox file.

use std::path::PathBuf;

use anyhow::{bail, Result};

use crate::machine::loading::engines::{voxelize, Engine, VoxelizeStats};
use crate::precompute::LoadConfig;
use crate::report::files::{create, write_json};
use crate::report::progress;

/// What the `voxelize` job loads and writes.
#[derive(Clone, Debug)]
pub struct VoxelizeOptions {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// The view: fitted, the scene's camera, or a camera of the user's.
    pub view: crate::scene::camera::ViewChoice,
    /// Grid side and surfaces.
    pub load: LoadConfig,
    /// The loading wave or the direct evaluation.
    pub engine: Engine,
    /// Dexels a cell holds: a compile-time capacity, one of 8, 16, 32, 64, 128.
    pub dexel_capacity: usize,
    /// Output .binvox file (default: `<scene>.binvox` in the current directory).
    pub out: Option<PathBuf>,
    /// Write the statistics as JSON here.
    pub stats: Option<PathBuf>,
    /// No progress bar.
    pub quiet: bool,
}

/// Run the `voxelize` job with the cell type of the chosen dexel capacity.
pub fn run(o: &VoxelizeOptions) -> Result<()> {
    match o.dexel_capacity {
        8 => run_with::<8>(o),
        16 => run_with::<16>(o),
        32 => run_with::<32>(o),
        64 => run_with::<64>(o),
        128 => run_with::<128>(o),
        d => bail!("'{d}' is not a compiled dexel capacity (8, 16, 32, 64 or 128)"),
    }
}

fn run_with<const D: usize>(o: &VoxelizeOptions) -> Result<()> {
    o.load.validate()?;
    let mesh = crate::scene::camera::apply(crate::scene::load(&o.scene)?, &o.view, o.load.n)?;
    let pb = progress::bar(o.quiet, "load");
    let v = voxelize::<D>(&mesh, &o.load, o.engine, |pos, len| {
        pb.set_length(len.max(pos));
        pb.set_position(pos);
    })?;
    pb.finish_and_clear();
    if let Some(p) = &o.stats {
        write_json(p, &v.stats)?;
    }
    print_summary(&v.stats);
    v.check_overflow()?;
    let out = o.out.clone().unwrap_or_else(|| PathBuf::from(format!("{}.binvox", mesh.name)));
    let vox = v.grid.to_voxels(v.stats.translate, v.stats.scale);
    vox.write(create(&out)?)?;
    eprintln!("  wrote {}", out.display());
    Ok(())
}

fn print_summary(s: &VoxelizeStats) {
    let g = &s.grid;
    eprintln!(
        "{}: n = {}, {} facets ({} skipped, {} polygons split), {:?}/{:?}, engine {:?}",
        s.scene, s.n, s.facets, s.facets_skipped, s.polygons_split, s.thickness, s.contour, s.engine
    );
    eprintln!(
        "  voxels {}  dexels/cell max {} (cell {:?}) mean {:.3} (occupied {:.2})",
        g.voxels, g.dexels_max_per_cell, g.dexels_max_cell, g.dexels_mean_per_cell, g.dexels_mean_per_occupied_cell
    );
    eprintln!(
        "  load cycles {}  bytes/cell static {} peak {}  wall {:.3} s (precompute {:.3} s, load {:.3} s)",
        s.load_cycles,
        s.bytes_per_cell_static,
        s.bytes_per_cell_peak,
        s.wall_seconds,
        s.precompute_seconds,
        s.load_seconds
    );
}
