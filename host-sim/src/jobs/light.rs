//! The `light` job: diffuse light from the scene's sources (or shoot classic shadow rays), write
//! what is lit and summarise the run; and the lighting options `render` and `trace` share.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};

use crate::config::{RunConfig, RunSummary};
use crate::dist::run_diffusion;
use crate::machine::lighting::diffuse::{LightConfig, Lighting};
use crate::machine::lighting::run::LightStats;
use crate::machine::loading::loaded_scene::{load_scene, resolve_sources, LightSampling, LoadedScene};
use crate::machine::rays::classic::{run_classic, ClassicConfig, ClassicLighting};
use crate::precompute::LoadConfig;
use crate::report::files::{create, write_json};
use crate::report::progress;
use crate::scene::{self, Mesh};

/// Lighting options shared by `light`, `render` and `trace`: the run (a preset with the
/// command line's overrides, resolved and validated: [`crate::config`]) and the lighting method.
#[derive(Clone, Debug)]
pub struct LightingOptions {
    /// Point lights at grid-normalised positions in 0..1 (empty: the scene's own).
    pub lights: Vec<[f64; 3]>,
    /// `--light-size`: the `lights` as square lamps this wide (grid-normalised).
    pub light_size: Option<f64>,
    /// What is loaded, f, and the complete diffusion configuration.
    pub run: RunConfig,
    /// Classic shadow rays instead of diffusion (`render`, `light`, `trace`).
    pub classic: Option<ClassicConfig>,
    /// Shadow-edge refinement after diffusion, with these shadow rays (`render`).
    pub refine: Option<ClassicConfig>,
}

impl LightingOptions {
    /// The diffusion configuration.
    pub fn config(&self) -> LightConfig {
        self.run.light
    }

    /// Grid side and surfaces.
    pub fn load(&self) -> &LoadConfig {
        &self.run.load
    }

    /// How the lights become point sources: `--light`, `--light-size`, `--area-light`.
    pub fn sampling(&self) -> LightSampling<'_> {
        LightSampling { cli: &self.lights, cli_size: self.light_size, area: self.run.area_light }
    }
}

/// `light --stats`: what ran, and the lighting run's statistics.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LightJobStats<'a> {
    /// The preset and the resolved settings ([`crate::config::RunSummary`]).
    pub run: RunSummary,
    /// The run's counters.
    #[serde(flatten)]
    pub light: &'a LightStats,
}

/// What the `light` job runs and writes.
#[derive(Clone, Debug)]
pub struct LightOptions {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// The view: fitted, the scene's camera, or a camera of the user's.
    pub view: crate::scene::camera::ViewChoice,
    /// Lights and lighting settings.
    pub light: LightingOptions,
    /// Write the statistics as JSON here.
    pub stats: Option<PathBuf>,
    /// Write every lit voxel as CSV `x,y,z,source_mask` here.
    pub lit_out: Option<PathBuf>,
    /// Write the scene, mapping, lights and occupied voxels as JSON here ([`crate::jobs::dump`]).
    pub dump_lit: Option<PathBuf>,
    /// No progress bars.
    pub quiet: bool,
}

/// Run the `light` job.
pub fn run(o: &LightOptions) -> Result<()> {
    let load = o.light.load();
    let mesh = crate::scene::camera::apply(scene::load(&o.scene)?, &o.view, load.n)?;
    let loaded = load_scene(&mesh, load)?;
    let lights = resolve_sources(&mesh, &loaded, &o.light.sampling())?.positions;
    let lcfg = o.light.config();
    if o.light.refine.is_some() {
        bail!("--lighting refined is a render option (it refines the pixels' lit state): use render");
    }
    let pb = progress::bar(o.quiet, "light");
    if let Some(ccfg) = &o.light.classic {
        let (cl, stats) = run_classic(&mesh, &loaded, &lights, ccfg, progress::light(&pb))?;
        pb.finish_and_clear();
        write_classic_outputs(o, &loaded, &cl, &stats)?;
        print_classic_summary(&o.light.run, lights.len(), &cl, &stats);
        return Ok(());
    }
    let (lighting, stats) = run_diffusion(&mesh, &loaded, &lights, &lcfg, progress::light(&pb))?;
    pb.finish_and_clear();
    write_outputs(o, &mesh, &loaded, &lighting, &stats)?;
    print_summary(&o.light.run, &stats);
    if stats.lit_overflows > 0 {
        bail!(
            "{} lit marks did not fit a cell's lit store ({} runs per column)",
            stats.lit_overflows,
            crate::machine::grid::capacity::LIT_CAP
        );
    }
    Ok(())
}

/// Write `x,y,z,source_mask` for every lit voxel.
pub fn write_lit_csv(l: &Lighting, mut w: impl Write) -> Result<()> {
    writeln!(w, "x,y,z,source_mask")?;
    for ([x, y, z], m) in l.lit_voxels() {
        writeln!(w, "{x},{y},{z},{m}")?;
    }
    Ok(())
}

/// The statistics, the lit voxels and the lit dump, as asked.
fn write_outputs(
    o: &LightOptions,
    mesh: &Mesh,
    loaded: &LoadedScene,
    lighting: &Lighting,
    stats: &LightStats,
) -> Result<()> {
    if let Some(p) = &o.stats {
        write_json(p, &LightJobStats { run: o.light.run.summary(), light: stats })?;
    }
    if let Some(p) = &o.lit_out {
        write_lit_csv(lighting, create(p)?)?;
    }
    if let Some(p) = &o.dump_lit {
        let d = crate::jobs::dump::lit_dump(mesh, &loaded.grid, &loaded.fit, lighting, stats);
        crate::jobs::dump::write_lit_dump(&d, create(p)?)?;
    }
    Ok(())
}

/// The first summary line of a classic-ray run: the preset, the rule and the geometry (the
/// diffusion settings do not apply).
pub fn classic_description(run: &RunConfig, fa: usize) -> String {
    let s = run.summary();
    format!(
        "preset {}: classic shadow rays, {} rule, n = {}, {} + {} surfaces, FA = {fa}",
        s.preset, s.lit_rule, s.n, s.thickness, s.contour
    )
}

/// The link counters of a run over faulty links (nothing without link faults).
pub fn print_link_faults(s: &LightStats) {
    if let Some(f) = &s.link_faults {
        eprintln!(
            "  links: {} data frames ({} retransmissions): {} corrupted + {} dropped data frames, {} acks lost, {} refused by CRC, {} duplicates discarded; {} frames delayed ({} link-cycles held)",
            f.data_frames,
            f.retransmissions,
            f.data_corrupted,
            f.data_dropped,
            f.acks_lost,
            f.crc_rejected,
            f.duplicates,
            f.data_delayed,
            f.delay_cycles
        );
    }
}

fn print_summary(run: &RunConfig, stats: &LightStats) {
    eprintln!("{}", run.describe());
    eprintln!("{}: {} facets, {} light(s)", stats.scene, stats.facets, stats.sources.len());
    print_link_faults(stats);
    for s in &stats.sources {
        eprintln!(
            "  light {} at {:?}: T = {} cycles, LB = {} (T/LB {:.2}), {} beams, {} messages, peak FIFO {}, peak link load {} at distance {}",
            s.source + 1,
            s.position,
            s.counts.cycles,
            s.counts.lower_bound,
            s.counts.cycles as f64 / s.counts.lower_bound.max(1) as f64,
            s.counts.beams_processed,
            s.counts.messages,
            s.counts.peak_fifo,
            s.counts.peak_link_load,
            s.counts.peak_link_distance
        );
    }
    let t = &stats.totals;
    eprintln!(
        "  lit voxels {}  rays emitted {} = absorbed {} + exited {} + skipped {}  wall {:.3} s",
        stats.lit_voxels, t.rays_emitted, t.rays_absorbed, t.rays_exited, t.rays_skipped, stats.wall_seconds
    );
}

/// `light --lighting classic`: the statistics and the lit visible voxels, as asked.
fn write_classic_outputs(
    o: &LightOptions,
    loaded: &LoadedScene,
    cl: &ClassicLighting,
    stats: &LightStats,
) -> Result<()> {
    if let Some(p) = &o.stats {
        write_json(p, &LightJobStats { run: o.light.run.summary(), light: stats })?;
    }
    if let Some(p) = &o.lit_out {
        let mut w = create(p)?;
        writeln!(w, "x,y,z,source_mask")?;
        for (i, c) in loaded.grid.cells.iter().enumerate() {
            if let (Some(d), m) = (c.store.dexels().first(), cl.masks[i]) {
                if m != 0 {
                    writeln!(w, "{},{},{},{m}", c.x, c.y, d.span.lo)?;
                }
            }
        }
    }
    Ok(())
}

fn print_classic_summary(run: &RunConfig, lights: usize, cl: &ClassicLighting, stats: &LightStats) {
    eprintln!("{}", classic_description(run, stats.fa));
    eprintln!(
        "{}: {} facets, {} light(s), FA = {}, {}: T = {} cycles, {} lit visible voxels, wall {:.3} s",
        stats.scene,
        stats.facets,
        lights,
        stats.fa,
        stats.policy,
        stats.totals.cycles,
        stats.lit_voxels,
        stats.wall_seconds
    );
    eprintln!("  {}", crate::machine::rays::classic::summary(&cl.totals));
}
