//! A whole lighting run: beam diffusion from every source, its lit-store check and its statistics.

use std::time::Instant;

use anyhow::{bail, Result};
use cell_core::beam::Source;
use cell_core::light::Policy;

use crate::machine::lighting::diffuse::{
    diffuse_share, diffuse_tile, light_cell_bytes, unsupported_frac_bits, DiffusionCounts, Halo, LightConfig, Lighting,
    PhaseSeconds, Share, SourceReport,
};
use crate::machine::loading::loaded_scene::LoadedScene;

use crate::scene::Mesh;

/// Everything `light --stats` reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LightStats {
    /// Scene name.
    pub scene: String,
    /// Grid side.
    pub n: u32,
    /// FIFO limit.
    pub fa: usize,
    /// Fraction bits of the far-plane offsets.
    pub frac_bits: u32,
    /// Scheduling policy.
    pub policy: String,
    /// Beam merging on arrival.
    pub merge: bool,
    /// Facets loaded.
    pub facets: usize,
    /// Loading cycles.
    pub load_cycles: u64,
    /// Counters summed over sources (cycles and lower bounds add up: sources run one after
    /// another).
    #[serde(flatten)]
    pub totals: DiffusionCounts,
    /// totals.cycles / totals.lower_bound.
    pub t_over_lb: f64,
    /// Voxels lit by at least one source.
    pub lit_voxels: u64,
    /// Lit marks lost to a full lit store (non-zero is an error).
    pub lit_overflows: u64,
    /// Under exact occluders, the triangles left out of full columns (`TRIANGLE_CAP`; light
    /// passes where they stand); 0 under the other rules.
    pub triangle_overflows: u64,
    /// `size_of` a beam message.
    pub bytes_beam_message: usize,
    /// `size_of` a cell's lighting state (FIFO, output buffers, lit runs, counters).
    pub bytes_light_cell: usize,
    /// Per-source reports.
    pub sources: Vec<SourceReport>,
    /// Wall time of the diffusion.
    pub wall_seconds: f64,
    /// Where the diffusion's wall time went, by phase of the cycle loop (host time; none for
    /// classic ray casting, which has no such loop).
    pub phase_seconds: Option<PhaseSeconds>,
    /// Peak resident memory (MiB).
    pub peak_rss_mib: Option<f64>,
    /// What the faulty links did (`--link-faults`).
    pub link_faults: Option<crate::machine::links::faults::FaultCounts>,
}

/// Fail, naming the first cell and the capacity to raise, when a lit store overflowed (a lit
/// mark lost is a wrong image, never a silent loss).
pub fn check_lit_overflow(lighting: &Lighting) -> Result<()> {
    let full: Vec<_> = lighting.cells.iter().filter(|c| c.counters.lit_overflows > 0).collect();
    if let Some(c) = full.first() {
        bail!(
            "lit store overflow in {} cell(s), first at cell ({}, {}): more than {} lit runs per column needed, \
             {} lit marks lost; raise LIT_CAP in cell-core/src/cell.rs, or pass --lit-visible-only \
             (keeps only the marks shading needs: same image)",
            full.len(),
            c.x,
            c.y,
            crate::machine::grid::capacity::LIT_CAP,
            lighting.lit_overflows()
        );
    }
    Ok(())
}

/// Warn when a column met more triangles than it keeps (`TRIANGLE_CAP`): the first ones in
/// stream order stop rays, the others let them through (what it costs: BENCHMARKS.md, "What the
/// cell's own arithmetic gives").
pub fn check_triangle_overflow(grid: &crate::machine::grid::LightGrid) {
    let stores = grid.triangles.overflows();
    if stores > 0 {
        eprintln!(
            "warning: {stores} triangle(s) left out of full columns (TRIANGLE_CAP = {} per column, \
             cell-core/src/cell.rs): light passes where they stand",
            crate::machine::grid::capacity::TRIANGLE_CAP
        );
    }
}

/// Diffuse and summarise (under `cfg.frac_bits`: the one choice of a build of the cells is made
/// inside the diffusion).
pub fn run_diffusion(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &LightConfig,
    mut progress: impl FnMut(usize, u64),
) -> Result<(Lighting, LightStats)> {
    run_diffusion_with(mesh, scene, lights, cfg, &mut progress)
}

/// [`run_diffusion`] compiled once, whatever the caller's progress closure.
fn run_diffusion_with(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &LightConfig,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<(Lighting, LightStats)> {
    let t0 = Instant::now();
    let lighting = diffuse_part(scene, lights, cfg, Share::ALL, progress)?;
    let wall = t0.elapsed().as_secs_f64();
    summarise(mesh, scene, cfg, lighting, wall)
}

/// One share of a lighting run's sources diffused ([`Share`]): a part for
/// [`crate::machine::lighting::diffuse::merge_parts`], whose result [`summarise`] checks and
/// counts as [`run_diffusion`] does.
pub fn diffuse_part(
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &LightConfig,
    share: Share,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<Lighting> {
    let sources = sources_of(scene, lights, cfg)?;
    diffuse_share(&scene.grid, &sources, cfg, share, progress)
}

/// One tile's part of a lighting run of every source over a grid cut into tiles
/// ([`crate::machine::lighting::diffuse::diffuse_tile`], through `halo`): a part for
/// [`crate::machine::lighting::diffuse::merge_tiles`].
pub fn diffuse_tile_part(
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &LightConfig,
    halo: &mut dyn Halo,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<Lighting> {
    let sources = sources_of(scene, lights, cfg)?;
    diffuse_tile(&scene.grid, &sources, cfg, halo, progress)
}

/// The run's sources, once its f is checked.
fn sources_of(scene: &LoadedScene, lights: &[[f64; 3]], cfg: &LightConfig) -> Result<Vec<Source>> {
    light_cell_bytes(cfg.frac_bits).ok_or_else(|| unsupported_frac_bits(cfg.frac_bits))?;
    let n = scene.grid.n;
    lights.iter().enumerate().map(|(i, p)| cfg.source(i, *p, n)).collect()
}

/// The checks and statistics of a lighting run of every source (`wall`: its wall time): the
/// lit-store overflow is an error, the triangle overflow a warning.
pub fn summarise(
    mesh: &Mesh,
    scene: &LoadedScene,
    cfg: &LightConfig,
    lighting: Lighting,
    wall: f64,
) -> Result<(Lighting, LightStats)> {
    let (bytes_beam_message, bytes_light_cell) =
        light_cell_bytes(cfg.frac_bits).ok_or_else(|| unsupported_frac_bits(cfg.frac_bits))?;
    let n = scene.grid.n;
    check_lit_overflow(&lighting)?;
    if cfg.rule.needs_triangles() {
        check_triangle_overflow(&scene.grid);
    }
    let r = &lighting.reports;
    let mut totals = DiffusionCounts::default();
    for s in r {
        totals.add(&s.counts);
    }
    let stats = LightStats {
        scene: mesh.name.clone(),
        n,
        fa: cfg.fa,
        frac_bits: cfg.frac_bits,
        policy: policy_name(cfg.policy).into(),
        merge: cfg.merge,
        facets: scene.facets,
        load_cycles: scene.load_cycles,
        t_over_lb: totals.t_over_lb(),
        totals,
        lit_voxels: lighting.lit_voxels().count() as u64,
        lit_overflows: lighting.lit_overflows(),
        triangle_overflows: if cfg.rule.needs_triangles() { scene.grid.triangles.overflows() } else { 0 },
        bytes_beam_message,
        bytes_light_cell,
        sources: r.clone(),
        wall_seconds: wall,
        phase_seconds: Some(lighting.phases),
        peak_rss_mib: crate::machine::grid::limits::peak_rss_mib(),
        link_faults: lighting.link_faults,
    };
    Ok((lighting, stats))
}

/// The CLI name of a policy.
pub fn policy_name(p: Policy) -> &'static str {
    match p {
        Policy::Thesis => "thesis",
        Policy::Wavefront => "wavefront",
        Policy::Radial => "radial",
    }
}
