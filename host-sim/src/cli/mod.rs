//! The `host-sim` command line.

pub mod phase_args;
pub mod value_args;

use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use crate::machine::diffuse::FrustumBlocks;
use crate::machine::load::{voxelize, VoxelizeStats};
use crate::precompute::{Contour, LoadConfig, Thickness};
use crate::scene;
use value_args::{ContourArg, EngineArg, FrustumBlocksArg, ThicknessArg};

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
    /// Host threads simulating the grid (default: all cores). Results do not depend on it.
    #[arg(long, global = true, value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
}

/// Subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// The main job: load, light and shade a scene on the RC² grid and write a PNG (the built-in
    /// Cornell box by default); `--reference` also ray-casts it in f64 and compares.
    Render(RenderArgs),
    /// Voxelize a scene with the RC² loading wave (§3) and write a .binvox file.
    Voxelize(VoxelizeArgs),
    /// Diffuse light from the scene's sources by beam subdivision (§4) and report what is lit.
    Light(LightArgs),
    /// The thesis's experiment (§4.4.3): empty scene, one source at the centre, T for each N and
    /// FIFO size, as CSV and a PNG plot beside the thesis's published values.
    DiffusionTable(TableArgs),
    /// Lit state of surface voxels against exact f64 visibility, for several n and f: the
    /// run time against error of the lighting phase (CSV).
    LightAccuracy(AccuracyArgs),
    /// Run time against error: render a scene under a sweep of speed/accuracy knobs, compare each
    /// with the f64 reference, write a CSV and a Pareto plot (error against machine cycles).
    Bench(BenchArgs),
    /// RAM of one cell for a scene: static sizes by part, what the scene uses (peak dexels,
    /// FIFO, lit runs, with the cell that needs most), and whether it fits `memory.x`.
    Audit(AuditArgs),
    /// Record, for chosen cells of a load + light run, every message they receive and every
    /// cycle, as binary traces (`cell_X_Y.rc2t`) plus the digest of their outputs and final
    /// state (`digests.json`); the firmware replays them.
    Trace(TraceArgs),
    /// List the built-in scenes.
    Scenes,
    /// Subdivide a mesh (1 → 4 midpoint splits) to about TARGET triangles and write an OBJ.
    Subdivide(SubdivideArgs),
}

/// Options of `voxelize`.
#[derive(Args, Debug)]
pub struct VoxelizeArgs {
    /// Scene and loading options.
    #[command(flatten)]
    pub load: LoadArgs,
    /// wave: the RC² loading wave stepped cycle by cycle; direct: the same integer formulas
    /// evaluated directly on the host (reference, no cycles).
    #[arg(long, value_enum, default_value_t = EngineArg::Wave)]
    pub engine: EngineArg,
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

/// Scheduling policy of the lighting phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PolicyArg {
    /// The thesis's: take the FIFO head; if it cannot go, put it back at the tail (§4.4.1).
    Thesis,
    /// Ours: among beams that can go now, the one at the smallest layer (longest remaining
    /// path) first; no head-of-line blocking.
    Wavefront,
    /// The wavefront's rule with ties at one layer broken by distance to the source's axis,
    /// nearest first: far fewer cycles on large grids (Cornell n = 512: −56 %), a few % more
    /// beams.
    Radial,
}

impl From<PolicyArg> for cell_core::light::Policy {
    fn from(p: PolicyArg) -> Self {
        match p {
            PolicyArg::Thesis => cell_core::light::Policy::Thesis,
            PolicyArg::Wavefront => cell_core::light::Policy::Wavefront,
            PolicyArg::Radial => cell_core::light::Policy::Radial,
        }
    }
}

/// Scene and loading options, the same for every job that loads a scene.
#[derive(Args, Debug, Clone)]
pub struct LoadArgs {
    /// An .obj file, or a built-in scene name (see `host-sim scenes`).
    #[arg(default_value = "cornell")]
    pub scene: String,
    /// Grid side: n × n cells (and pixels), each owning a column of n voxels (4 ..= 65536).
    /// Default: 128; `trace`: 32 (a trace must fit the firmware's flash: keep n small).
    #[arg(long)]
    pub n: Option<u32>,
    /// Plane thickness: naive (σ = ½, stops 6-connected rays), thesis (§3.8's σ), standard
    /// (|a|+|b|+|c|, provably free of 26-tunnels). Default: standard in every job, the
    /// tunnel-free surface: no light passes through a closed mesh.
    #[arg(long, value_enum, default_value_t = ThicknessArg::Standard)]
    pub sigma: ThicknessArg,
    /// Facet contour: projected (the thesis's) or conservative (closes gaps between facets and
    /// holes in thin facets). Default: conservative in every job, the watertight one (the
    /// pixel still shows the exact facet its centre line meets, not the fatter voxels).
    #[arg(long, value_enum, default_value_t = ContourArg::Conservative)]
    pub contour: ContourArg,
}

impl LoadArgs {
    /// The loading configuration, with grid side `default_n` unless `--n` is given.
    pub fn config(&self, default_n: u32) -> LoadConfig {
        LoadConfig { n: self.n.unwrap_or(default_n), thickness: self.sigma.into(), contour: self.contour.into() }
    }
}

/// Default grid side of every job but `trace`.
const DEFAULT_N: u32 = 128;

/// Default grid side of `trace`.
const TRACE_N: u32 = 32;

/// The geometry a summary line names: thickness and contour.
fn geometry(cfg: &LoadConfig) -> String {
    format!("{:?} + {:?} surfaces", cfg.thickness, cfg.contour).to_lowercase()
}

/// Options of `light`.
#[derive(Args, Debug)]
pub struct LightArgs {
    /// Scene and loading options.
    #[command(flatten)]
    pub load: LoadArgs,
    /// Lighting options.
    #[command(flatten)]
    pub light: LightOpts,
    /// Write statistics as JSON to this file.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Write every lit voxel as CSV `x,y,z,source_mask` (binvox indexing).
    #[arg(long)]
    pub lit_out: Option<PathBuf>,
    /// Write a JSON file for outside checks: the scene's triangles (world units), the grid
    /// mapping, the lights, and every occupied voxel with its source mask (`bench/compare.py`).
    #[arg(long)]
    pub dump_lit: Option<PathBuf>,
    /// Do not draw progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// Lighting options shared by `light` and `render`.
#[derive(Args, Debug, Clone)]
pub struct LightOpts {
    /// A point light at grid-normalised coordinates X,Y,Z in 0..1 (repeatable, up to 32;
    /// replaces the scene's own lights). Sources are diffused one after another.
    #[arg(long = "light", value_parser = parse_triple)]
    pub lights: Vec<[f64; 3]>,
    /// FIFO size FA of every cell (1 ..= 64).
    #[arg(long, default_value_t = 16)]
    pub fa: usize,
    /// Fraction bits f of the far-plane ray offsets (0 = the thesis's integer rays; up to 24,
    /// bounded by D·2^f < 2^31). More bits: more rays, fewer missed voxels, more beams. Default
    /// 0; 1 lights faces the light grazes at a degree or two right too (Cornell n = 512: 0.56 →
    /// 0.09 % of pixels wrong) for 2–4× the cycles.
    #[arg(long, default_value_t = crate::jobs::light::DEFAULT_FRAC_BITS)]
    pub frac_bits: u32,
    /// Which beam a cell processes first. Default: radial (fewest cycles measured on every
    /// scene; `wavefront` was the default before).
    #[arg(long, value_enum, default_value_t = PolicyArg::Radial)]
    pub policy: PolicyArg,
    /// Merge an arriving beam into a waiting beam of the same voxel when their ray rectangles
    /// share a side (exact; fewer beams to process): on, off, or auto (on for wavefront and
    /// radial, off for the thesis policy).
    #[arg(long, value_enum, default_value_t = MergeArg::Auto)]
    pub merge: MergeArg,
    /// Which cells the host visits each cycle: only those holding beams, or every cell (the
    /// reference). Same results, cycles and counters either way.
    #[arg(long, value_enum, default_value_t = SteppingArg::Active)]
    pub stepping: SteppingArg,
    /// Drop sub-beams that can meet no occupied voxel any more (outside the occupied bounding
    /// box and moving away from it); their rays are counted as skipped. Exact: same lit voxels.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub skip_receding: bool,
    /// Do not emit a source's initial beams whose direction leads away from the occupied box.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub skip_dead_directions: bool,
    /// Faulty links: every transfer is framed with a CRC-32, corrupted, dropped or delayed at
    /// these rates (e.g. `corrupt=0.01,drop=0.01,delay=0.05,delay-cycles=8,seed=7`; rates
    /// 0 ..= 1 summing to at most 1; a delayed frame is held 1 ..= delay-cycles cycles, default
    /// 8), and delivered by acknowledgement and retransmission. Same lit voxels and image, more
    /// cycles.
    #[arg(long, value_parser = clap::value_parser!(crate::machine::faults::LinkFaults))]
    pub link_faults: Option<crate::machine::faults::LinkFaults>,
    /// Stop with a stall report (the blocked cells and their queues) after this many cycles in
    /// a row without progress while beams are in flight: a deadlock, or a dead link.
    #[arg(long, default_value_t = crate::machine::diffuse::DEFAULT_STALL_CYCLES)]
    pub stall_cycles: u64,
    /// Cells keep lit marks only for the voxels their pixel reads: the same image, a lit set
    /// (`--lit-out`, stats) restricted to those voxels, and no lit-store overflow in columns lit
    /// in many separate runs (walls seen edge-on, many lights). `render`: on by default (off
    /// with --reflections, which read hidden voxels); `light`: off by default.
    #[arg(long, num_args = 0..=1, default_missing_value = "true", action = clap::ArgAction::Set)]
    pub lit_visible_only: Option<bool>,
    /// Drop a beam when none of its rays can meet an occupied block of the scene's occupancy
    /// summary (--frustum-blocks) at any later layer (their rays are counted as skipped).
    /// Exact: same lit voxels; each cell holds the summary.
    #[arg(long, default_value_t = false, action = clap::ArgAction::Set)]
    pub skip_frustum: bool,
    /// Drop a beam when none of its rays can reach a block holding a voxel a pixel reads: the
    /// empty-frustum test against a summary of those voxels only. Same image and same visible
    /// lit set; hidden voxels are not lit. Needs the visible-only lit store; on by default
    /// wherever that is (`render`).
    #[arg(long, num_args = 0..=1, default_missing_value = "true", action = clap::ArgAction::Set)]
    pub skip_hidden: Option<bool>,
    /// Blocks per axis of the summary --skip-frustum and --skip-hidden test beams against:
    /// finer blocks drop more beams and take more memory per cell (8: 232 B, 16: 1 348 B,
    /// 32: 9 384 B). Same lit voxels and image with any. Default: 32; 8 for `trace` (a cell
    /// trace carries the 8 × 8 × 8 summary).
    #[arg(long, value_enum)]
    pub frustum_blocks: Option<FrustumBlocksArg>,
    /// The sibling wait: a beam that does not yet hold every ray its voxel can receive waits
    /// up to this many cycles (while its FIFO has room) for the pieces from its other parent
    /// voxels to merge into it: fewer beams and messages, same lit voxels. 0: off. Wavefront
    /// policy only; at most 4096.
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=4096))]
    pub hold: u16,
    /// The lit rule: `plane` (default) stops a ray only where it crosses the plane of the facet
    /// owning the voxel it is in, lights only facets facing the source, and lights each pixel's
    /// exact visible surface from that surface's own plane: right at grazing angles (thesis
    /// §5.5.6). `thesis`: a beam entering an occupied voxel lights it and stops (§5.5.5), and the
    /// pixel shows the first occupied voxel of its column (today's figures: add
    /// `--sigma naive --contour projected --frac-bits 0 --policy wavefront`).
    #[arg(long, value_enum, default_value_t = LitRuleArg::Plane)]
    pub lit_rule: LitRuleArg,
    /// Classic shadow rays instead of diffusion.
    #[command(flatten)]
    pub classic: crate::cli::phase_args::ClassicOpts,
}

/// The lit rule ([`cell_core::lit`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LitRuleArg {
    /// A beam entering an occupied voxel lights it and stops (§5.5.5).
    Thesis,
    /// Stopped only by a plane crossed there; each pixel lit from its visible surface's plane.
    Plane,
}

impl From<LitRuleArg> for cell_core::lit::LitRule {
    fn from(a: LitRuleArg) -> Self {
        match a {
            LitRuleArg::Thesis => cell_core::lit::LitRule::Thesis,
            LitRuleArg::Plane => cell_core::lit::LitRule::Plane,
        }
    }
}

/// How the host steps the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SteppingArg {
    /// Only the cells holding beams (event-driven).
    Active,
    /// Every cell in every cycle (the reference).
    AllCells,
}

impl LightOpts {
    /// The configuration, with the visible-only lit store and the hidden-voxel skip on by
    /// default when `visible_only` (what `render` needs), unless given.
    fn config_for(&self, visible_only: bool) -> Result<crate::machine::diffuse::LightConfig> {
        let lit_visible_only = self.lit_visible_only.unwrap_or(visible_only);
        let skip_hidden = self.skip_hidden.unwrap_or(lit_visible_only && visible_only);
        if skip_hidden && !lit_visible_only {
            anyhow::bail!(
                "--skip-hidden drops the light of hidden voxels: it needs the visible-only lit store \
                 (--lit-visible-only)"
            );
        }
        Ok(crate::machine::diffuse::LightConfig { lit_visible_only, skip_hidden, ..self.config() })
    }

    /// The configuration with the full lit store (the `light` and `trace` jobs' default).
    fn config(&self) -> crate::machine::diffuse::LightConfig {
        crate::machine::diffuse::LightConfig {
            fa: self.fa,
            policy: self.policy.into(),
            merge: self.merge.resolve(self.policy),
            record_visits: false,
            stepping: match self.stepping {
                SteppingArg::Active => crate::machine::diffuse::Stepping::Active,
                SteppingArg::AllCells => crate::machine::diffuse::Stepping::AllCells,
            },
            skip_receding: self.skip_receding,
            skip_dead_directions: self.skip_dead_directions,
            faults: self.link_faults,
            stall_cycles: self.stall_cycles,
            lit_visible_only: self.lit_visible_only.unwrap_or(false),
            hold: self.hold,
            skip_frustum: self.skip_frustum,
            skip_hidden: self.skip_hidden.unwrap_or(false),
            frustum_blocks: self.frustum_blocks.map_or(FrustumBlocks::default(), Into::into),
            rule: self.lit_rule.into(),
        }
    }
}

/// Normal used for shading.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum NormalArg {
    /// The facet's normal stored with each dexel (16-bit octahedral code, §5.2.1).
    Facet,
    /// The voxel face the view ray crossed; no normal stored (§5.2.2).
    Face,
}

/// Options of `render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene and loading options.
    #[command(flatten)]
    pub load: LoadArgs,
    /// Lighting options.
    #[command(flatten)]
    pub light: LightOpts,
    /// Normal used for shading.
    #[arg(long, value_enum, default_value_t = NormalArg::Facet)]
    pub normals: NormalArg,
    /// Reflection options.
    #[command(flatten)]
    pub reflect: crate::cli::phase_args::ReflectOpts,
    /// Output PNG.
    #[arg(long, default_value = "render.png")]
    pub out: PathBuf,
    /// Also ray-cast the scene in f64 (same camera, resolution and shading) and compare: writes
    /// F.reference.png and F.diff.png beside F, and adds the comparison to the stats.
    #[arg(long)]
    pub reference: bool,
    /// Write statistics as JSON to this file.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Do not draw progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// Options of `diffusion-table`.
#[derive(Args, Debug)]
pub struct TableArgs {
    /// Grid sizes N.
    #[arg(long, value_delimiter = ',', default_value = "16,32,64,128")]
    pub n: Vec<u32>,
    /// FIFO sizes FA.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16,32,64")]
    pub fa: Vec<usize>,
    /// Policies to run.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "thesis,wavefront")]
    pub policy: Vec<PolicyArg>,
    /// Beam merging (see `light --help`).
    #[arg(long, value_enum, default_value_t = MergeArg::Auto)]
    pub merge: MergeArg,
    /// Fraction bits f.
    #[arg(long, default_value_t = 0)]
    pub frac_bits: u32,
    /// Output CSV.
    #[arg(long, default_value = "diffusion-table.csv")]
    pub out: PathBuf,
    /// Output PNG plot.
    #[arg(long, default_value = "diffusion-table.png")]
    pub plot: PathBuf,
    /// Do not draw progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// Beam merging switch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MergeArg {
    /// On for the wavefront and radial policies, off for the thesis's.
    Auto,
    /// Always merge.
    On,
    /// Never merge.
    Off,
}

impl MergeArg {
    fn resolve(self, p: PolicyArg) -> bool {
        match self {
            MergeArg::Auto => p != PolicyArg::Thesis,
            MergeArg::On => true,
            MergeArg::Off => false,
        }
    }
}

fn parse_triple(s: &str) -> std::result::Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| format!("'{s}': {e}"))?;
    match v[..] {
        [x, y, z] => Ok([x, y, z]),
        _ => Err(format!("'{s}': expected X,Y,Z")),
    }
}

/// Options of `light-accuracy`.
#[derive(Args, Debug)]
pub struct AccuracyArgs {
    /// An .obj file, or a built-in scene name.
    #[arg(default_value = "cornell")]
    pub scene: String,
    /// Grid sizes.
    #[arg(long, value_delimiter = ',', default_value = "64,128,256")]
    pub n: Vec<u32>,
    /// Fraction bits f to compare.
    #[arg(long, value_delimiter = ',', default_value = "0,2,4,8")]
    pub frac_bits: Vec<u32>,
    /// FIFO size.
    #[arg(long, default_value_t = 16)]
    pub fa: usize,
    /// Scheduling policy.
    #[arg(long, value_enum, default_value_t = PolicyArg::Wavefront)]
    pub policy: PolicyArg,
    /// A light at grid-normalised X,Y,Z (repeatable; default: the scene's own).
    #[arg(long = "light", value_parser = parse_triple)]
    pub lights: Vec<[f64; 3]>,
    /// Output CSV.
    #[arg(long, default_value = "light-accuracy.csv")]
    pub out: PathBuf,
}

/// Options of `bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Scenes (.obj files or built-in names), comma-separated; errors are averaged over them.
    #[arg(value_delimiter = ',', default_value = "cornell,teapot-floor,cow-floor")]
    pub scene: Vec<String>,
    /// Grid sizes.
    #[arg(long, value_delimiter = ',', default_value = "64")]
    pub n: Vec<u32>,
    /// Fraction bits swept.
    #[arg(long, value_delimiter = ',', default_value = "0,1,2")]
    pub frac_bits: Vec<u32>,
    /// Output CSV.
    #[arg(long, default_value = "bench.csv")]
    pub out: PathBuf,
    /// Output Pareto plot (one per n: `<stem>-n<N>.png` when several).
    #[arg(long, default_value = "bench.png")]
    pub plot: PathBuf,
    /// Do not print progress lines.
    #[arg(long)]
    pub quiet: bool,
}

/// Options of `audit`.
#[derive(Args, Debug)]
pub struct AuditArgs {
    /// Scene and loading options.
    #[command(flatten)]
    pub load: LoadArgs,
    /// FIFO size used for the lighting run.
    #[arg(long, default_value_t = 16)]
    pub fa: usize,
    /// Write the audit as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The firmware ELF whose text/data/bss to report (default: the release build under
    /// firmware/, if it exists).
    #[arg(long)]
    pub elf: Option<PathBuf>,
}

/// Options of `trace`.
#[derive(Args, Debug)]
pub struct TraceArgs {
    /// Scene and loading options.
    #[command(flatten)]
    pub load: LoadArgs,
    /// Lighting options (the firmware is built for the default --frac-bits 0).
    #[command(flatten)]
    pub light: LightOpts,
    /// A cell to record, X,Y (repeatable).
    #[arg(long = "cell", value_parser = parse_cell)]
    pub cells: Vec<[u32; 2]>,
    /// Also record the cell that processes the most beams (found by a first run).
    #[arg(long)]
    pub busiest: bool,
    /// Directory for the traces and digests.json.
    #[arg(long, default_value = "out/traces")]
    pub out: PathBuf,
}

fn parse_cell(s: &str) -> Result<[u32; 2], String> {
    let v: Vec<&str> = s.split(',').collect();
    match v.as_slice() {
        [x, y] => Ok([
            x.trim().parse().map_err(|_| format!("'{s}': X is not a cell index"))?,
            y.trim().parse().map_err(|_| format!("'{s}': Y is not a cell index"))?,
        ]),
        _ => Err(format!("'{s}': expected X,Y")),
    }
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
    // The command runs on a thread of the pool, so that the lighting loop's parallel passes
    // (several per machine cycle) fork and join among the pool's own threads: called from a
    // thread outside it, every pass would inject its job and block, a futex wake and sleep
    // per pass.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cli.threads.map_or(0, |t| t as usize))
        .build()
        .context("--threads")?;
    pool.install(|| dispatch(cli.command))
}

fn dispatch(command: Command) -> Result<()> {
    match command {
        Command::Voxelize(a) => match a.dexel_capacity {
            8 => run_voxelize::<8>(&a),
            16 => run_voxelize::<16>(&a),
            32 => run_voxelize::<32>(&a),
            64 => run_voxelize::<64>(&a),
            _ => run_voxelize::<128>(&a),
        },
        Command::Render(a) => cell_core::with_frac_bits!(a.light.frac_bits, F => run_render::<F>(&a))
            .unwrap_or_else(|| Err(unsupported_f(a.light.frac_bits))),
        Command::Light(a) => cell_core::with_frac_bits!(a.light.frac_bits, F => run_light::<F>(&a))
            .unwrap_or_else(|| Err(unsupported_f(a.light.frac_bits))),
        Command::DiffusionTable(a) => cell_core::with_frac_bits!(a.frac_bits, F => run_table::<F>(&a))
            .unwrap_or_else(|| Err(unsupported_f(a.frac_bits))),
        Command::LightAccuracy(a) => run_accuracy(&a),
        Command::Bench(a) => {
            let meshes = a.scene.iter().map(|s| scene::load(s)).collect::<Result<Vec<_>>>()?;
            crate::jobs::bench::run_bench(&meshes, &a.n, &a.frac_bits, &a.out, &a.plot, a.quiet)
        }
        Command::Audit(a) => {
            let l = &a.load;
            let cfg = l.config(DEFAULT_N);
            cfg.validate()?;
            let mesh = scene::load(&l.scene)?;
            let lcfg = crate::machine::diffuse::LightConfig {
                fa: a.fa,
                policy: cell_core::light::Policy::Wavefront,
                merge: true,
                record_visits: false,
                ..Default::default()
            };
            let default_elf = PathBuf::from(crate::jobs::audit::FIRMWARE_ELF);
            let elf = a.elf.clone().or_else(|| default_elf.exists().then_some(default_elf));
            let audit = crate::jobs::audit::audit(&mesh, &cfg, &lcfg, elf.as_deref())?;
            crate::jobs::audit::print(&audit);
            if let Some(p) = &a.json {
                crate::jobs::audit::write_json(&audit, p)?;
            }
            Ok(())
        }
        Command::Trace(a) => cell_core::with_frac_bits!(a.light.frac_bits, F => run_trace::<F>(&a))
            .unwrap_or_else(|| Err(unsupported_f(a.light.frac_bits))),
        Command::Scenes => {
            for (name, what) in scene::BUILTINS {
                println!("{name:13} {what}");
            }
            Ok(())
        }
        Command::Subdivide(a) => {
            let mesh = scene::load(&a.scene)?;
            let sub = crate::scene::meshops::subdivide_to(&mesh, a.target);
            let f = File::create(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
            crate::scene::meshops::write_obj(&sub, BufWriter::new(f))?;
            eprintln!(
                "{}: {} → {} triangles, written to {}",
                mesh.name,
                mesh.faces.len(),
                sub.faces.len(),
                a.out.display()
            );
            Ok(())
        }
    }
}

fn unsupported_f(f: u32) -> anyhow::Error {
    anyhow::anyhow!("--frac-bits {f} is not supported (0..=8, 10, 12, 16, 20, 24)")
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
        s.load_cycles,
        s.bytes_per_cell_static,
        s.bytes_per_cell_peak,
        s.wall_seconds,
        s.precompute_seconds,
        s.load_seconds
    );
}

fn run_voxelize<const D: usize>(a: &VoxelizeArgs) -> Result<()> {
    let l = &a.load;
    let cfg = l.config(DEFAULT_N);
    cfg.validate()?;
    let mesh = scene::load(&l.scene)?;
    let pb = progress_bar(a.quiet, "load");
    let v = voxelize::<D>(&mesh, &cfg, a.engine.into(), |pos, len| {
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

fn run_light<F: cell_core::beam::FracBits>(a: &LightArgs) -> Result<()> {
    use crate::jobs::light::write_lit_csv;
    use crate::machine::lighting::run_diffusion;
    use crate::machine::loaded::{load_scene, resolve_lights};
    let l = &a.load;
    let cfg = l.config(DEFAULT_N);
    cfg.validate()?;
    let mesh = scene::load(&l.scene)?;
    let loaded = load_scene(&mesh, &cfg)?;
    let lights = resolve_lights(&mesh, &loaded, &a.light.lights)?;
    let lcfg = a.light.config_for(false)?;
    let pb = progress_bar(a.quiet, "light");
    if a.light.classic.lighting == crate::cli::phase_args::LightingArg::Classic {
        return run_light_classic::<F>(a, &cfg, &mesh, &loaded, &lights, pb);
    }
    let (lighting, stats) = run_diffusion::<F>(&mesh, &loaded, &lights, &lcfg, light_progress(&pb))?;
    pb.finish_and_clear();
    if let Some(p) = &a.stats {
        write_json(p, &stats)?;
    }
    if let Some(p) = &a.lit_out {
        let f = File::create(p).with_context(|| format!("cannot create {}", p.display()))?;
        write_lit_csv(&lighting, BufWriter::new(f))?;
    }
    if let Some(p) = &a.dump_lit {
        let f = File::create(p).with_context(|| format!("cannot create {}", p.display()))?;
        let d = crate::jobs::dump::lit_dump(&mesh, &loaded.grid, &loaded.fit, &lighting, &stats);
        crate::jobs::dump::write_lit_dump(&d, BufWriter::new(f))?;
    }
    eprintln!(
        "{}: n = {}, {} facets ({}), {} light(s), FA = {}, f = {}, policy {}, merge {}",
        stats.scene,
        stats.n,
        stats.facets,
        geometry(&cfg),
        stats.sources.len(),
        stats.fa,
        stats.frac_bits,
        stats.policy,
        stats.merge
    );
    print_link_faults(&stats);
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
    eprintln!(
        "  lit voxels {}  rays emitted {} = absorbed {} + exited {}  wall {:.3} s",
        stats.lit_voxels,
        stats.totals.rays_emitted,
        stats.totals.rays_absorbed,
        stats.totals.rays_exited,
        stats.wall_seconds
    );
    if stats.lit_overflows > 0 {
        anyhow::bail!(
            "{} lit marks did not fit a cell's lit store ({} runs per column)",
            stats.lit_overflows,
            crate::machine::capacity::LIT_CAP
        );
    }
    Ok(())
}

fn run_table<F: cell_core::beam::FracBits>(a: &TableArgs) -> Result<()> {
    use crate::machine::lighting::run_diffusion;
    use crate::machine::loaded::{load_scene, resolve_lights};
    use std::io::Write;
    let mut rows = Vec::new();
    let mut csv = BufWriter::new(File::create(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?);
    writeln!(csv, "n,fa,policy,frac_bits,cycles,lower_bound,t_over_lb,lb_distance,lb_cell_load,beams_processed,messages,peak_fifo,blocked_cell_cycles,wall_seconds")?;
    let mesh = scene::load("empty")?;
    let pb = progress_bar(a.quiet, "table");
    pb.set_length((a.n.len() * a.fa.len() * a.policy.len()) as u64);
    for &n in &a.n {
        let cfg = LoadConfig { n, thickness: Thickness::Standard, contour: Contour::Conservative };
        let loaded = load_scene(&mesh, &cfg)?;
        // The thesis's source at the centre: voxel (n/2, n/2, n/2).
        let c = (n / 2) as f64;
        let lights = resolve_lights(&mesh, &loaded, &[])?.iter().map(|_| [c, c, c]).collect::<Vec<_>>();
        for &policy in &a.policy {
            for &fa in &a.fa {
                let lcfg = crate::machine::diffuse::LightConfig {
                    fa,
                    policy: policy.into(),
                    merge: a.merge.resolve(policy),
                    record_visits: false,
                    // The thesis's experiment measures diffusion through an empty scene, which
                    // the skips would drop entirely.
                    skip_receding: false,
                    skip_dead_directions: false,
                    ..Default::default()
                };
                let (_, s) = run_diffusion::<F>(&mesh, &loaded, &lights, &lcfg, |_, _| {})?;
                let r = &s.sources[0];
                writeln!(
                    csv,
                    "{n},{fa},{},{},{},{},{:.4},{},{},{},{},{},{},{:.4}",
                    s.policy,
                    s.frac_bits,
                    r.counts.cycles,
                    r.counts.lower_bound,
                    s.t_over_lb,
                    r.counts.lb_distance,
                    r.counts.lb_cell_load,
                    r.counts.beams_processed,
                    r.counts.messages,
                    r.counts.peak_fifo,
                    r.counts.blocked_cell_cycles,
                    s.wall_seconds
                )?;
                rows.push(crate::report::plot::DiffusionRow {
                    n,
                    fa: fa as u32,
                    policy: s.policy.clone(),
                    cycles: r.counts.cycles,
                    lower_bound: r.counts.lower_bound,
                });
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    csv.flush()?;
    crate::report::plot::plot_diffusion(&rows, &a.plot)?;
    eprintln!("| N | FA | policy | T | LB | T/LB |");
    eprintln!("|---|---|---|---|---|---|");
    for r in &rows {
        eprintln!(
            "| {} | {} | {} | {} | {} | {:.2} |",
            r.n,
            r.fa,
            r.policy,
            r.cycles,
            r.lower_bound,
            r.cycles as f64 / r.lower_bound.max(1) as f64
        );
    }
    eprintln!("wrote {} and {}", a.out.display(), a.plot.display());
    Ok(())
}

fn run_accuracy(a: &AccuracyArgs) -> Result<()> {
    use crate::jobs::accuracy::accuracy;
    use crate::machine::lighting::run_diffusion;
    use crate::machine::loaded::{load_scene, resolve_lights};
    use std::io::Write;
    let mesh = scene::load(&a.scene)?;
    let mut csv = BufWriter::new(File::create(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?);
    writeln!(csv, "scene,n,frac_bits,surface_voxels,lit_discrete,lit_continuous,false_lit,false_dark,disagreement_pct,cycles,lower_bound,beams_processed,wall_seconds")?;
    eprintln!("| n | f | surface voxels | false lit | false dark | disagreement % | cycles | beams | wall s |");
    eprintln!("|---|---|---|---|---|---|---|---|---|");
    for &n in &a.n {
        let cfg = LoadConfig { n, thickness: Thickness::Standard, contour: Contour::Conservative };
        let loaded = load_scene(&mesh, &cfg)?;
        let lights = resolve_lights(&mesh, &loaded, &a.lights)?;
        for &f in &a.frac_bits {
            let lcfg = crate::machine::diffuse::LightConfig {
                fa: a.fa,
                policy: a.policy.into(),
                merge: MergeArg::Auto.resolve(a.policy),
                record_visits: false,
                ..Default::default()
            };
            let row = cell_core::with_frac_bits!(f, F => {
                run_diffusion::<F>(&mesh, &loaded, &lights, &lcfg, |_, _| {})
                    .and_then(|(l, s)| Ok((accuracy(&mesh, &loaded, &lights, &l)?, s)))
            })
            .unwrap_or_else(|| Err(anyhow::anyhow!("--frac-bits {f} is not supported")))?;
            let (acc, s) = row;
            writeln!(
                csv,
                "{},{n},{f},{},{},{},{},{},{:.4},{},{},{},{:.4}",
                mesh.name,
                acc.surface_voxels,
                acc.lit_discrete,
                acc.lit_continuous,
                acc.false_lit,
                acc.false_dark,
                acc.disagreement_pct,
                s.totals.cycles,
                s.totals.lower_bound,
                s.totals.beams_processed,
                s.wall_seconds
            )?;
            eprintln!(
                "| {n} | {f} | {} | {} | {} | {:.2} | {} | {} | {:.2} |",
                acc.surface_voxels,
                acc.false_lit,
                acc.false_dark,
                acc.disagreement_pct,
                s.totals.cycles,
                s.totals.beams_processed,
                s.wall_seconds
            );
        }
    }
    csv.flush()?;
    eprintln!("wrote {}", a.out.display());
    Ok(())
}

fn print_link_faults(s: &crate::machine::lighting::LightStats) {
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

fn run_trace<F: cell_core::beam::FracBits>(a: &TraceArgs) -> Result<()> {
    let load = a.load.config(TRACE_N);
    load.validate()?;
    let mesh = scene::load(&a.load.scene)?;
    let job = crate::jobs::trace::TraceJob {
        mesh: &mesh,
        load,
        light: crate::machine::diffuse::LightConfig {
            frustum_blocks: a.light.frustum_blocks.map_or(FrustumBlocks::B8, Into::into),
            ..a.light.config()
        },
        lights: a.light.lights.clone(),
        cells: a.cells.clone(),
        busiest: a.busiest,
    };
    let traces = crate::jobs::trace::record::<F>(&job)?;
    crate::jobs::trace::write_traces(&a.out, &traces)?;
    for t in &traces {
        // The host's own build of cell-core replays it: the same digest, or the trace is wrong.
        let (d, st) = crate::jobs::trace::replay::<F>(&t.bytes)?;
        let ok = if d == t.digest { "replay ok" } else { "REPLAY MISMATCH" };
        println!(
            "cell ({:>3}, {:>3}): {:>6} bytes, {:>5} records ({} rows, {} beams in, {} cycles, {} sent), digest {:016x}, {ok}",
            t.x, t.y, t.bytes.len(), t.records, st.rows, st.received, st.steps, st.sent, t.digest
        );
        if d != t.digest {
            anyhow::bail!("replaying the trace of cell ({}, {}) gave digest {d:016x}", t.x, t.y);
        }
    }
    println!("traces written to {}", a.out.display());
    Ok(())
}

/// Progress of the lighting phase: source and cycle.
fn light_progress(pb: &ProgressBar) -> impl FnMut(usize, u64) + '_ {
    |s, c| {
        pb.set_message(format!("light {}", s + 1));
        pb.set_length(c.max(1));
        pb.set_position(c);
    }
}

fn run_light_classic<F: cell_core::beam::FracBits>(
    a: &LightArgs,
    cfg: &LoadConfig,
    mesh: &scene::Mesh,
    loaded: &crate::machine::loaded::LoadedScene,
    lights: &[[f64; 3]],
    pb: ProgressBar,
) -> Result<()> {
    use std::io::Write;
    let ccfg = a.light.classic.config(a.light.fa, a.light.lit_rule.into());
    let (cl, stats) = crate::machine::classic::run_classic::<F>(mesh, loaded, lights, &ccfg, light_progress(&pb))?;
    pb.finish_and_clear();
    let stats_out = a.stats.as_ref().map(|p| write_json(p, &stats));
    stats_out.transpose()?;
    if let Some(p) = &a.lit_out {
        let mut w = BufWriter::new(File::create(p).with_context(|| format!("cannot create {}", p.display()))?);
        writeln!(w, "x,y,z,source_mask")?;
        for (i, c) in loaded.grid.cells.iter().enumerate() {
            if let (Some(d), m) = (c.store.dexels().first(), cl.masks[i]) {
                if m != 0 {
                    writeln!(w, "{},{},{},{m}", c.x, c.y, d.span.lo)?;
                }
            }
        }
    }
    eprintln!(
        "{}: n = {}, {} facets ({}), {} light(s), FA = {}, {}: T = {} cycles, {} lit visible voxels, wall {:.3} s",
        stats.scene,
        stats.n,
        stats.facets,
        geometry(cfg),
        lights.len(),
        stats.fa,
        stats.policy,
        stats.totals.cycles,
        stats.lit_voxels,
        stats.wall_seconds
    );
    eprintln!("  {}", crate::machine::classic::summary(&cl.totals));
    Ok(())
}

/// `F.EXT` beside the image `F.png`: its extension replaced, dots in the stem kept
/// (`shot-0.5.png` gives `shot-0.5.diff.png`).
fn beside(out: &std::path::Path, ext: &str) -> std::path::PathBuf {
    let stem = out.file_stem().unwrap_or_default().to_string_lossy();
    out.with_file_name(format!("{stem}.{ext}"))
}

fn run_render<F: cell_core::beam::FracBits>(a: &RenderArgs) -> Result<()> {
    use crate::jobs::render::{reference_image, render, RenderConfig};
    use crate::machine::loaded::{load_scene, resolve_lights};
    use crate::report::png::write_png;
    let cfg = a.load.config(DEFAULT_N);
    cfg.validate()?;
    a.reflect.validate(a.light.classic.lighting, cfg.n, a.light.fa)?;
    let reflecting = a.reflect.reflections > 0;
    if reflecting && a.light.lit_visible_only == Some(true) {
        anyhow::bail!(
            "--reflections reads the lit state of the voxels reflected rays hit, hidden ones included: \
             run without --lit-visible-only (and --skip-hidden)"
        );
    }
    // The image needs only what its pixels read; reflected rays read hidden voxels too.
    let light = a.light.config_for(!reflecting)?;
    let mesh = scene::load(&a.load.scene)?;
    let t0 = std::time::Instant::now();
    let pb = progress_bar(a.quiet, "load");
    pb.set_length(1);
    let loaded = load_scene(&mesh, &cfg)?;
    pb.finish_and_clear();
    let load_seconds = t0.elapsed().as_secs_f64();
    let lights = resolve_lights(&mesh, &loaded, &a.light.lights)?;
    let rcfg = RenderConfig {
        light,
        normals: match a.normals {
            NormalArg::Facet => cell_core::shade::NormalMode::Facet,
            NormalArg::Face => cell_core::shade::NormalMode::Face,
        },
    };
    let t1 = std::time::Instant::now();
    let reference = if a.reference {
        if mesh.faces.is_empty() {
            anyhow::bail!("--reference needs a scene with geometry ('{}' has none)", mesh.name);
        }
        if a.reflect.reflections > 0 {
            let (d, t) = (a.reflect.reflections, a.reflect.reflect_threshold);
            Some(crate::jobs::render::reflect_reference_image(&mesh, &loaded, &lights, d, t)?)
        } else {
            Some(reference_image(&mesh, &loaded, &lights)?)
        }
    } else {
        None
    };
    let reference_seconds = t1.elapsed().as_secs_f64();
    let pb = progress_bar(a.quiet, "light 1");
    let progress = light_progress(&pb);
    let mut reflections = None;
    let (r, classic) = if a.reflect.reflections > 0 {
        let refl = a.reflect.config(a.light.fa, &a.light.classic.config(a.light.fa, a.light.lit_rule.into()));
        let times = [load_seconds, reference_seconds];
        let (r, c) = crate::jobs::render::render_reflect::<F>(
            &mesh,
            &loaded,
            &lights,
            &rcfg,
            &refl,
            reference.as_ref(),
            times,
            progress,
        )?;
        reflections = Some(c);
        (r, None)
    } else if a.light.classic.lighting == crate::cli::phase_args::LightingArg::Classic {
        let ccfg = a.light.classic.config(a.light.fa, a.light.lit_rule.into());
        let (r, c) = crate::jobs::render::render_classic::<F>(
            &mesh,
            &loaded,
            &lights,
            &rcfg,
            &ccfg,
            reference.as_ref(),
            load_seconds,
            reference_seconds,
            progress,
        )?;
        (r, Some(c))
    } else {
        (
            render::<F>(&mesh, &loaded, &lights, &rcfg, reference.as_ref(), load_seconds, reference_seconds, progress)?,
            None,
        )
    };
    pb.finish_and_clear();
    write_png(&a.out, r.image.n, &r.image.rgb)?;
    let mut written = vec![a.out.display().to_string()];
    if let Some(reference) = &reference {
        let (rp, dp) = (beside(&a.out, "reference.png"), beside(&a.out, "diff.png"));
        write_png(&rp, reference.n, &reference.rgb)?;
        let diff = crate::truth::compare::difference_image(&r.image.rgb, &r.image.covered, reference);
        write_png(&dp, reference.n, &diff)?;
        written.push(rp.display().to_string());
        written.push(dp.display().to_string());
    }
    match (&a.stats, &reflections) {
        (Some(p), Some(c)) => write_json(p, &crate::jobs::render::with_counts(&r.stats, c)?)?,
        (Some(p), None) => write_json(p, &r.stats)?,
        _ => {}
    }
    let s = &r.stats;
    let t = &s.light.totals;
    eprintln!(
        "{}: n = {}, {} facets ({}), {} light(s), f = {}, FA = {}, {} policy{}, {} normals",
        s.light.scene,
        s.light.n,
        s.light.facets,
        geometry(&cfg),
        s.light.sources.len(),
        s.light.frac_bits,
        s.light.fa,
        s.light.policy,
        if s.light.merge { " + merge" } else { "" },
        s.normals
    );
    eprintln!(
        "  cycles: load {}  light {} (T/LB {:.2}, {} beams)  shade {}",
        s.light.load_cycles, t.cycles, s.light.t_over_lb, t.beams_processed, s.shade_cycles
    );
    print_link_faults(&s.light);
    eprintln!(
        "  pixels: {} covered, {} lit   bytes/cell {} (dexels {} + light {})   shading vs f64: max {} mean {:.3} levels",
        s.covered_pixels, s.lit_pixels, s.bytes_per_cell, s.bytes_per_cell_load, s.light.bytes_light_cell,
        s.shading_max_err_levels, s.shading_mean_err_levels
    );
    if let Some(c) = &classic {
        eprintln!("  {}", crate::machine::classic::summary(c));
    }
    if let Some(c) = &reflections {
        eprintln!("  {}", crate::machine::reflect::summary(c));
    }
    if let Some(c) = &s.reference {
        eprintln!(
            "  reference: shadow disagreement {:.2} %, coverage disagreement {:.2} %, PSNR {:.2} dB",
            c.shadow_disagreement_pct, c.coverage_disagreement_pct, c.psnr_db
        );
    }
    eprintln!(
        "  wall {:.2} s (load {:.2}, light {:.2}, shade {:.2}, reference {:.2})   wrote {}",
        s.wall_seconds,
        s.load_seconds,
        s.light_seconds,
        s.shade_seconds,
        s.reference_seconds,
        written.join(", ")
    );
    Ok(())
}
