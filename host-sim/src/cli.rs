//! The `host-sim` command line.

use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use crate::load::{voxelize, Engine, VoxelizeStats};
use crate::precompute::{Contour, LoadConfig, Thickness};
use crate::scene;

/// RC² cellular ray-tracing machine — host simulator.
///
/// Instantiates an n × n grid of RC² cells (the `cell-core` crate: exactly what one cell runs)
/// and drives whole scenes through it.
#[derive(Parser, Debug)]
#[command(name = "host-sim", version, about, long_about = None)]
pub struct Cli {
    /// What to run.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Voxelize a scene with the RC² loading wave (§3) and write a .binvox file.
    Voxelize(VoxelizeArgs),
    /// List the built-in scenes.
    Scenes,
    /// Subdivide a mesh (1 → 4 midpoint splits) to about TARGET triangles and write an OBJ.
    Subdivide(SubdivideArgs),
}

/// Options of `voxelize`.
#[derive(Args, Debug)]
pub struct VoxelizeArgs {
    /// An .obj file, or a built-in scene name (see `host-sim scenes`).
    #[arg(default_value = "cornell")]
    pub scene: String,
    /// Grid side: n × n cells, each owning a column of n voxels (4 ..= 65536).
    #[arg(long, default_value_t = 128)]
    pub n: u32,
    /// Plane thickness: naive (σ = ½, stops 6-connected rays), thesis (§3.8's σ), standard
    /// (|a|+|b|+|c|, provably free of 26-tunnels).
    #[arg(long, value_enum, default_value_t = Thickness::Standard)]
    pub sigma: Thickness,
    /// Facet contour: projected (the thesis's) or conservative (closes gaps between facets and
    /// holes in thin facets).
    #[arg(long, value_enum, default_value_t = Contour::Conservative)]
    pub contour: Contour,
    /// wave: the RC² loading wave stepped cycle by cycle; direct: the same integer formulas
    /// evaluated directly on the host (reference, no cycles).
    #[arg(long, value_enum, default_value_t = Engine::Wave)]
    pub engine: Engine,
    /// Dexels a cell can hold (a compile-time capacity; one of 8, 16, 32, 64, 128).
    #[arg(long, default_value_t = cell_core::cell::DEFAULT_DEXELS, value_parser = parse_capacity)]
    pub dexel_capacity: usize,
    /// Output .binvox file (default: <scene>.binvox in the current directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write statistics as JSON to this file (schema in the README).
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Do not draw progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// Options of `subdivide`.
#[derive(Args, Debug)]
pub struct SubdivideArgs {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// Triangle count to reach.
    #[arg(long, default_value_t = 70_000)]
    pub target: usize,
    /// Output .obj file.
    #[arg(long)]
    pub out: PathBuf,
}

/// Run a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Voxelize(a) => match a.dexel_capacity {
            8 => run_voxelize::<8>(&a),
            16 => run_voxelize::<16>(&a),
            32 => run_voxelize::<32>(&a),
            64 => run_voxelize::<64>(&a),
            _ => run_voxelize::<128>(&a),
        },
        Command::Scenes => {
            for (name, what) in scene::BUILTINS {
                println!("{name:10} {what}");
            }
            Ok(())
        }
        Command::Subdivide(a) => {
            let mesh = scene::load(&a.scene)?;
            let sub = crate::meshops::subdivide_to(&mesh, a.target);
            let f = File::create(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
            crate::meshops::write_obj(&sub, BufWriter::new(f))?;
            eprintln!("{}: {} → {} triangles, written to {}", mesh.name, mesh.faces.len(), sub.faces.len(), a.out.display());
            Ok(())
        }
    }
}

fn parse_capacity(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(v @ (8 | 16 | 32 | 64 | 128)) => Ok(v),
        _ => Err(format!("'{s}' is not a compiled dexel capacity (8, 16, 32, 64 or 128)")),
    }
}

fn progress_bar(quiet: bool, what: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(1);
    pb.set_style(
        ProgressStyle::with_template("{msg:>8} [{bar:40}] {pos}/{len} ({elapsed})")
            .expect("static template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

fn write_json(path: &PathBuf, value: &impl serde::Serialize) -> Result<()> {
    let f = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    serde_json::to_writer_pretty(BufWriter::new(f), value)?;
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
        s.load_cycles, s.bytes_per_cell_static, s.bytes_per_cell_peak, s.wall_seconds, s.precompute_seconds, s.load_seconds
    );
}

fn run_voxelize<const D: usize>(a: &VoxelizeArgs) -> Result<()> {
    let cfg = LoadConfig { n: a.n, thickness: a.sigma, contour: a.contour };
    cfg.validate()?;
    let mesh = scene::load(&a.scene)?;
    let pb = progress_bar(a.quiet, "load");
    let v = voxelize::<D>(&mesh, &cfg, a.engine, |pos, len| {
        pb.set_length(len.max(pos));
        pb.set_position(pos);
    })?;
    pb.finish_and_clear();
    if let Some(p) = &a.stats {
        write_json(p, &v.stats)?;
    }
    print_summary(&v.stats);
    v.check_overflow()?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from(format!("{}.binvox", mesh.name)));
    let vox = v.grid.to_voxels(v.stats.translate, v.stats.scale);
    let f = File::create(&out).with_context(|| format!("cannot create {}", out.display()))?;
    vox.write(BufWriter::new(f))?;
    eprintln!("  wrote {}", out.display());
    Ok(())
}
