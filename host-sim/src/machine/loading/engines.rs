//! The `voxelize` job's machine: precompute, load the grid (wave or direct), summarise.

use std::time::Instant;

use anyhow::{bail, Result};
use cell_core::cell::Cell;
use cell_core::dexel::Dexel;
use cell_core::facet::{PipelinePacket, RowPacket};

use crate::machine::grid::limits::peak_rss_mib;
use crate::machine::grid::Grid;
use crate::machine::loading::wave::LoadReport;
use crate::precompute::{prepare, Contour, LoadConfig, Prepared, Thickness};
use crate::scene::binvox::Voxels;
use crate::scene::Mesh;

/// How the grid is loaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Engine {
    /// The RC² wave, cycle by cycle (the machine).
    Wave,
    /// The direct host evaluation of the same integer formulas (reference and baseline).
    Direct,
}

/// Occupancy summary of a loaded grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct GridSummary {
    /// Occupied voxels.
    pub voxels: u64,
    /// Columns holding at least one dexel.
    pub occupied_columns: u64,
    /// Dexels in the whole grid.
    pub dexels_total: u64,
    /// Largest dexel count of a cell.
    pub dexels_max_per_cell: u32,
    /// The cell holding that many dexels.
    pub dexels_max_cell: [u32; 2],
    /// Mean dexels per cell (all n² cells).
    pub dexels_mean_per_cell: f64,
    /// Mean dexels per occupied column.
    pub dexels_mean_per_occupied_cell: f64,
    /// Cells whose dexel store overflowed.
    pub overflow_cells: u64,
    /// Voxels lost to overflow.
    pub voxels_lost: u64,
    /// First overflowing cell (row-major order), if any.
    pub first_overflow_cell: Option<[u32; 2]>,
}

impl<const D: usize> Grid<D> {
    /// Summarise occupancy and overflow.
    pub fn summary(&self) -> GridSummary {
        let mut s = GridSummary::default();
        for c in &self.cells {
            let k = c.store.dexels().len() as u32;
            s.voxels += c.store.voxel_count() as u64;
            s.dexels_total += k as u64;
            s.occupied_columns += (k > 0) as u64;
            if k > s.dexels_max_per_cell {
                s.dexels_max_per_cell = k;
                s.dexels_max_cell = [c.x as u32, c.y as u32];
            }
            if c.store.overflows() > 0 {
                s.overflow_cells += 1;
                s.voxels_lost += c.store.lost_voxels() as u64;
                s.first_overflow_cell.get_or_insert([c.x as u32, c.y as u32]);
            }
        }
        let cells = self.cells.len().max(1) as f64;
        s.dexels_mean_per_cell = s.dexels_total as f64 / cells;
        s.dexels_mean_per_occupied_cell = s.dexels_total as f64 / s.occupied_columns.max(1) as f64;
        s
    }

    /// Dense occupancy in binvox order.
    pub fn to_voxels(&self, translate: [f64; 3], scale: f64) -> Voxels {
        let mut v = Voxels::new(self.n, translate, scale);
        for c in &self.cells {
            for d in c.store.dexels() {
                for z in d.span.lo..=d.span.hi {
                    v.set(c.x as u32, c.y as u32, z as u32);
                }
            }
        }
        v
    }
}

/// Everything `voxelize --stats` reports (schema documented in the README).
#[derive(Clone, Debug, serde::Serialize)]
pub struct VoxelizeStats {
    /// Scene name.
    pub scene: String,
    /// Grid side.
    pub n: u32,
    /// Voxels per column.
    pub depth: u32,
    /// Thickness mode.
    pub thickness: Thickness,
    /// Contour mode.
    pub contour: Contour,
    /// Loading engine.
    pub engine: Engine,
    /// Faces in the input mesh.
    pub faces: usize,
    /// Facet packets loaded.
    pub facets: usize,
    /// Facets skipped (degenerate after quantisation, or outside the grid).
    pub facets_skipped: usize,
    /// Polygons split into triangles.
    pub polygons_split: usize,
    /// Occupancy summary (voxels, dexels, overflow).
    #[serde(flatten)]
    pub grid: GridSummary,
    /// Cycles of the loading wave (0 for the direct engine).
    pub load_cycles: u64,
    /// Message and step counters of the wave.
    pub wave: Option<LoadReport>,
    /// Dexel capacity of a cell (compile-time constant chosen with --dexel-capacity).
    pub dexel_capacity: usize,
    /// `size_of` one dexel.
    pub bytes_per_dexel: usize,
    /// `size_of` a row packet (a cell's inbound link register).
    pub bytes_row_packet: usize,
    /// `size_of` a pipeline packet.
    pub bytes_pipeline_packet: usize,
    /// `size_of::<Cell<CAP>>()` + one inbound row packet register.
    pub bytes_per_cell_static: usize,
    /// The same for the busiest cell with its store sized to what it used.
    pub bytes_per_cell_peak: usize,
    /// Lattice steps per voxel.
    pub lattice_q: i64,
    /// World size of a voxel.
    pub voxel_size: f64,
    /// binvox translate (world position of the grid's low corner).
    pub translate: [f64; 3],
    /// binvox scale (world side of the grid).
    pub scale: f64,
    /// Host precompute wall time.
    pub precompute_seconds: f64,
    /// Loading wall time.
    pub load_seconds: f64,
    /// Whole job wall time (without writing files).
    pub wall_seconds: f64,
    /// Peak resident memory of the process so far (Linux `VmHWM`), in MiB.
    pub peak_rss_mib: Option<f64>,
}

/// Result of a voxelization.
pub struct Voxelized<const D: usize> {
    /// The loaded grid.
    pub grid: Grid<D>,
    /// The precompute's output.
    pub prepared: Prepared,
    /// Statistics.
    pub stats: VoxelizeStats,
}

impl<const D: usize> Voxelized<D> {
    /// Fail with a clear message when a dexel store overflowed.
    pub fn check_overflow(&self) -> Result<()> {
        let g = &self.stats.grid;
        if let Some([x, y]) = g.first_overflow_cell {
            bail!(
                "dexel store overflow in {} cell(s), first at cell ({x}, {y}): more than {D} dexels needed, \
                 {} voxels lost; rerun with a larger --dexel-capacity",
                g.overflow_cells,
                g.voxels_lost
            );
        }
        Ok(())
    }
}

/// Voxelize a mesh into an n-grid of cells with `D` dexels each.
pub fn voxelize<const D: usize>(
    mesh: &Mesh,
    cfg: &LoadConfig,
    engine: Engine,
    progress: impl FnMut(u64, u64),
) -> Result<Voxelized<D>> {
    voxelize_tapped(mesh, cfg, engine, None, progress)
}

/// [`voxelize`], recording the cells watched by `tap` (wave engine only).
pub fn voxelize_tapped<const D: usize>(
    mesh: &Mesh,
    cfg: &LoadConfig,
    engine: Engine,
    tap: Option<&mut crate::machine::links::tap::Tap>,
    mut progress: impl FnMut(u64, u64),
) -> Result<Voxelized<D>> {
    let t0 = Instant::now();
    cfg.validate()?;
    crate::machine::grid::limits::check_grid_memory("grid of loading cells", cfg.n, std::mem::size_of::<Cell<D>>())?;
    let prepared = prepare(mesh, cfg)?;
    let t1 = Instant::now();
    let mut grid = Grid::<D>::new(cfg.n, cfg.n);
    let packets: &[PipelinePacket] = &prepared.packets;
    let wave = match engine {
        Engine::Wave => {
            let est = packets.len() as u64 + 2 * cfg.n as u64;
            Some(grid.load_wave_tapped(packets, tap, |c| progress(c, est)))
        }
        Engine::Direct => {
            grid.load_direct(packets, |i| progress(i, packets.len() as u64));
            None
        }
    };
    let t2 = Instant::now();
    grid.triangles = crate::machine::grid::triangles::ColumnTriangles::from_polygons(&prepared.polygons, cfg.n)?;
    let summary = grid.summary();
    let fit = prepared.fit.expect("prepare always fits");
    let cell = std::mem::size_of::<Cell<D>>() + std::mem::size_of::<RowPacket>();
    let stats = VoxelizeStats {
        scene: mesh.name.clone(),
        n: cfg.n,
        depth: cfg.n,
        thickness: cfg.thickness,
        contour: cfg.contour,
        engine,
        faces: prepared.faces_in,
        facets: packets.len(),
        facets_skipped: prepared.skipped_degenerate + prepared.skipped_outside + prepared.skipped_duplicate,
        polygons_split: prepared.polygons_split,
        grid: summary,
        load_cycles: wave.map_or(0, |w| w.cycles),
        wave,
        dexel_capacity: D,
        bytes_per_dexel: std::mem::size_of::<Dexel>(),
        bytes_row_packet: std::mem::size_of::<RowPacket>(),
        bytes_pipeline_packet: std::mem::size_of::<PipelinePacket>(),
        bytes_per_cell_static: cell,
        bytes_per_cell_peak: cell - (D - summary.dexels_max_per_cell as usize) * std::mem::size_of::<Dexel>(),
        lattice_q: crate::precompute::Q,
        voxel_size: fit.voxel,
        translate: fit.origin,
        scale: fit.voxel * cfg.n as f64,
        precompute_seconds: (t1 - t0).as_secs_f64(),
        load_seconds: (t2 - t1).as_secs_f64(),
        wall_seconds: (t2 - t0).as_secs_f64(),
        peak_rss_mib: peak_rss_mib(),
    };
    Ok(Voxelized { grid, prepared, stats })
}
