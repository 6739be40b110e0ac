//! The `host-sim` command line.

mod options;
pub mod phase_args;
pub mod value_args;

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::jobs;
use crate::precompute::LoadConfig;
use crate::scene::camera::{Camera, Projection, ViewChoice};
use value_args::{ContourArg, EngineArg, FrustumBlocksArg, OracleSkipArg, SpreadArg, ThicknessArg, VisibilityArg};

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
    /// Under `mpirun` (a build with the `mpi` feature, docs/MPI.md): how the ranks share the
    /// lighting run of `render` and `light`. `sources`: each rank diffuses its share of the
    /// light sources on its own copy of the grid; `tiles`: the grid is cut into bands of rows,
    /// one per rank, and the messages that cross a band's edge go between the ranks every
    /// cycle; `auto`: sources when there are at least as many as ranks, tiles otherwise.
    /// Images, lit sets and counts are the same either way; one process ignores it.
    #[arg(long, global = true, value_enum, default_value_t = SpreadArg::Auto)]
    pub spread: SpreadArg,
    /// With tiles over K ranks: the K − 1 rows above which the grid is cut into bands,
    /// increasing, comma-separated (e.g. `--tile-rows 300` for 2 ranks at n = 512), instead
    /// of bands of equal height. Every cycle waits for the busiest band: rank 0's last lines
    /// give each band's share of the beams and the cuts that would have balanced them, to
    /// pass here on the next run of the same scene. The result is the same wherever the grid
    /// is cut.
    #[arg(long, global = true, value_name = "ROW,ROW…", value_delimiter = ',')]
    pub tile_rows: Option<Vec<u32>>,
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
    /// with the f64 reference, write a CSV and a Pareto plot (error against machine cycles and
    /// against host seconds).
    Bench(BenchArgs),
    /// RAM of one cell for a scene: static sizes by part, what the scene uses (peak dexels,
    /// FIFO, lit runs, with the cell that needs most), and whether it fits `memory.x`.
    Audit(AuditArgs),
    /// Record, for chosen cells of a run (loading; beam diffusion, or classic shadow rays with
    /// `--lighting classic`; shading; with `--reflections N` the reflection phase), every
    /// message they receive and every cycle, as binary traces (`cell_X_Y.rc2t`) plus the
    /// digest of their outputs and final state (`digests.json`); the firmware replays them.
    Trace(TraceArgs),
    /// Progressive radiosity on the grid (radiosity thesis §1.3.2, §3.4): each shot a beam
    /// diffusion from the patch with the most unshot power; per-patch and per-shot CSV;
    /// `--reference` compares with the f64 solver (ray-cast form factors) on the same patches.
    Radiosity(RadiosityArgs),
    /// The projective form-factor methods of the radiosity thesis (ch. 2: hemicube, Sillion's and
    /// Recker's planes, hemispheres, projection disk): `--tables` computes §2.5's Tables 2.1–2.3
    /// from each method's own surface and prints them beside the published values.
    FormFactors(FormFactorsArgs),
    /// List the built-in scenes.
    Scenes,
    /// Subdivide a mesh (1 → 4 midpoint splits) to about TARGET triangles and write an OBJ.
    Subdivide(SubdivideArgs),
    /// Thesis §5.5.4: a point source's rays reflected by a voxelized flat mirror, each mirrored
    /// and started as a cell does it: the cloud of virtual images around the true one S′ (the
    /// reflected lines' closest approach to it) and the screen cells no reflected ray reaches
    /// (the dark zone); a PNG of both, and with --csv the figures.
    VirtualImages(VirtualImagesArgs),
}

/// Options of `virtual-images`.
#[derive(Args, Debug)]
pub struct VirtualImagesArgs {
    /// Grid side.
    #[arg(long, default_value_t = 64)]
    pub n: u32,
    /// Where a reflected ray leaves the voxel it hit (thesis §5.3): the entry point on the face
    /// it crossed, the voxel's centre, or the exact intersection with the dexel's facet plane.
    #[arg(long, value_enum, default_value_t = phase_args::HitArg::Centre)]
    pub hit: phase_args::HitArg,
    /// Normal that mirrors the rays: facet (the stored normal, §5.2.1) or face (the face flip,
    /// §5.2.2).
    #[arg(long, value_enum, default_value_t = phase_args::ReflectNormalArg::Facet)]
    pub reflect_normal: phase_args::ReflectNormalArg,
    /// Connectivity of the rays' walks: 6, 18 or 26.
    #[arg(long, default_value_t = 6, value_parser = phase_args::parse_connectivity)]
    pub ray_connectivity: u8,
    /// Tilt of the mirror about y, degrees (0: parallel to the grid's faces, no staircase).
    #[arg(long, default_value_t = 20.0)]
    pub tilt: f64,
    /// Rays from the source per mirror column: K × K points of the column's voxel (1 ..= 8).
    #[arg(long, default_value_t = 4)]
    pub rays_per_voxel: u32,
    /// The picture: the cloud around S′ (left, ±4 voxels, one grid line a voxel) and the screen
    /// (right: grey, rays per cell; red, cells of the mirror's footprint no ray reached).
    #[arg(long, default_value = "virtual-images.png")]
    pub out: PathBuf,
    /// Write the figures as one CSV line (with its header) to this file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

impl From<&VirtualImagesArgs> for jobs::virtual_images::VirtualImagesOptions {
    fn from(a: &VirtualImagesArgs) -> Self {
        jobs::virtual_images::VirtualImagesOptions {
            n: a.n,
            hit: a.hit.into(),
            normal: a.reflect_normal.into(),
            connectivity: phase_args::connectivity(a.ray_connectivity),
            tilt_deg: a.tilt,
            rays_per_voxel: a.rays_per_voxel,
            out: a.out.clone(),
            csv: a.csv.clone(),
        }
    }
}

/// Options of `radiosity`.
#[derive(Args, Debug)]
pub struct RadiosityArgs {
    /// Scene and loading options.
    #[command(flatten)]
    pub load: LoadArgs,
    /// Patches and stopping rule.
    #[command(flatten)]
    pub solve: crate::cli::phase_args::RadiosityOpts,
    /// Also solve with the f64 reference (ray-cast form factors) and compare per patch.
    #[arg(long)]
    pub reference: bool,
    /// With --reference: also solve the reference with 4× the form-factor samples and report
    /// how far its own solution moves (its self-error, to set beside the machine's error).
    #[arg(long, requires = "reference")]
    pub reference_self_error: bool,
    /// With --truth-error: keep the converged truth in this JSON file. If the file holds the
    /// truth of the same patches and stopping rule, it is read instead of solved (a sweep over
    /// --form-factors solves it once); otherwise it is solved and the file (re)written.
    #[arg(long, value_name = "FILE", requires = "truth_error")]
    pub truth_cache: Option<PathBuf>,
    /// Per-patch CSV (default SCENE_patches.csv).
    #[arg(long)]
    pub patches_csv: Option<PathBuf>,
    /// Per-shot CSV: residual, balance, cycles and messages of every shot (default SCENE_shots.csv).
    #[arg(long)]
    pub shots_csv: Option<PathBuf>,
    /// Plot of the residual against shots, PNG (default SCENE_residual.png): the machine's,
    /// and with --reference the f64 reference's beside it.
    #[arg(long)]
    pub residual_plot: Option<PathBuf>,
    /// Write the summary as JSON to this file.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Do not draw progress bars.
    #[arg(long)]
    pub quiet: bool,
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
    /// Output .binvox file (default: SCENE.binvox in the current directory).
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
    /// nearest first: a cell's layer is taken in the order its rays spread, so the pipelines
    /// of a face drain together (its cycles beside the others': BENCHMARKS.md, "How fast is
    /// lighting?").
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

/// Timing rules of the diffusion cycle model (`machine::lighting::timing`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TimingArg {
    /// rc2's: one message per link and cycle, FA counts the beam in process, one initial
    /// beam per cycle.
    Rc2,
    /// The thesis's as docs/DIFFUSION-TIMING.md reads its text and tables.
    Thesis,
}

/// Where the diffusion table's source sits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SourceAtArg {
    /// Voxel (n/2, n/2, n/2) (§4.4.3's time-lapse).
    Centre,
    /// Voxel (0, 0, 0), the case §4.3 derives and §4.4.4 starts from.
    Origin,
}

/// Emission order of the six initial beams.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EmissionArg {
    /// x and y first, then z (§4.4.3's recommendation).
    XyFirst,
    /// z first.
    ZFirst,
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
    /// (|a|+|b|+|c|, provably free of 26-tunnels: no light passes through a closed mesh).
    /// Default: the preset's (standard; naive with --thesis).
    #[arg(long, value_enum)]
    pub sigma: Option<ThicknessArg>,
    /// Facet contour: projected (the thesis's) or conservative (closes gaps between facets and
    /// holes in thin facets; the pixel still shows the exact facet its centre line meets, not
    /// the fatter voxels). Default: the preset's (conservative; projected with --thesis).
    #[arg(long, value_enum)]
    pub contour: Option<ContourArg>,
    /// Camera options.
    #[command(flatten)]
    pub camera: CameraArgs,
}

/// The camera: how the host maps the scene into the grid's screen space (thesis §1.3).
#[derive(Args, Debug, Clone)]
pub struct CameraArgs {
    /// The view: `auto` (the scene's own camera if it has one — the Cornell box's published
    /// eye (278, 273, −800), 39.3° — else fitted; fitted with --reflections), `fitted` (no
    /// camera: the scene's bounding box fitted into the grid, seen along +z), or `scene` (the
    /// scene's camera, an error if it has none). `--eye` gives your own camera instead.
    #[arg(long, value_enum, default_value_t = ViewArg::Auto, conflicts_with = "eye")]
    pub view: ViewArg,
    /// Eye position X,Y,Z (world units): a camera of your own; needs --look-at.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, requires = "look_at")]
    pub eye: Option<[f64; 3]>,
    /// The point the camera looks at, X,Y,Z (world units).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, requires = "eye")]
    pub look_at: Option<[f64; 3]>,
    /// Up direction X,Y,Z.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, default_value = "0,1,0")]
    pub up: [f64; 3],
    /// Perspective field of view in degrees, in (0, 180) (default 40 with --eye).
    #[arg(long, conflicts_with = "ortho", requires = "eye")]
    pub fov: Option<f64>,
    /// Orthographic view of this width (world units) instead of perspective.
    #[arg(long, requires = "eye")]
    pub ortho: Option<f64>,
    /// Near-plane depth (world units from the eye). Default: just before the scene.
    #[arg(long, requires = "eye")]
    pub near: Option<f64>,
    /// Far-plane depth. Default: just behind the scene.
    #[arg(long, requires = "eye")]
    pub far: Option<f64>,
}

/// `--view`.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewArg {
    /// The scene's own camera if it has one, else fitted.
    Auto,
    /// No camera: the scene fitted into the grid.
    Fitted,
    /// The scene's own camera.
    Scene,
}

impl CameraArgs {
    /// The view these options choose.
    pub fn choice(&self) -> ViewChoice {
        let (Some(eye), Some(look_at)) = (self.eye, self.look_at) else {
            return match self.view {
                ViewArg::Auto => ViewChoice::Auto,
                ViewArg::Fitted => ViewChoice::Fitted,
                ViewArg::Scene => ViewChoice::Scene,
            };
        };
        let projection = match self.ortho {
            Some(width) => Projection::Ortho { width },
            None => Projection::Perspective { fov_deg: self.fov.unwrap_or(40.0) },
        };
        ViewChoice::Custom(Camera { eye, look_at, up: self.up, projection, near: self.near, far: self.far })
    }
}

impl LoadArgs {
    /// The loading configuration, with grid side `default_n` unless `--n` is given.
    /// The loading of `base` with this command line's changes.
    pub fn config(&self, base: LoadConfig) -> LoadConfig {
        LoadConfig {
            n: self.n.unwrap_or(base.n),
            thickness: self.sigma.map_or(base.thickness, Into::into),
            contour: self.contour.map_or(base.contour, Into::into),
        }
    }
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
    /// Give the --light lights an extent: each is a square lamp W wide (grid-normalised, along
    /// x and z, centred on its point), facing down (−y) like a ceiling lamp, which
    /// --area-light samples. Without it a --light light is a point.
    #[arg(long, value_name = "W")]
    pub light_size: Option<f64>,
    /// Sample every light that has an extent (the Cornell box's ceiling lamp, a --light with
    /// --light-size) by S × S point sources at the centres of the cells of a regular S × S grid
    /// over its area, each with 1/S² of its intensity (the same total light): soft shadows with
    /// penumbrae. The f64 reference samples the same points with the same weights. Lights
    /// without an extent stay points. Every sample is a source of the machine: at most 32 in
    /// all. Default: 1 (a point at the lamp's centre).
    #[arg(long, value_name = "S", value_parser = clap::value_parser!(u32).range(1..))]
    pub area_light: Option<u32>,
    /// The run to start from, every other option changing it (the presets are written out in
    /// docs/CONFIGURATION.md): `render` (what `render` runs by default), `light` (what `light`
    /// runs: render's machine keeping every lit voxel), `trace` (what `trace` records and the
    /// firmware replays: the plane rule from the source voxel, n = 32), `thesis` (the thesis's
    /// machine). Default: the job's own.
    #[arg(long, value_enum, conflicts_with = "thesis")]
    pub preset: Option<PresetArg>,
    /// The thesis's machine: the same as --preset thesis (its lit rule, integer rays from the
    /// source voxel, wavefront policy, free-port timing, naive planes, projected contours, no
    /// rc2 skips).
    #[arg(long)]
    pub thesis: bool,
    /// FIFO size FA of every cell (1 ..= 64). Default: the preset's (16).
    #[arg(long)]
    pub fa: Option<usize>,
    /// Fraction bits f of the far-plane ray offsets (0 = the thesis's integer rays; up to 24,
    /// bounded by D·2^f < 2^31). More bits: more rays, fewer missed voxels at grazing angles,
    /// more beams and cycles. Default: the preset's (1 for `light`, 0 for the others).
    #[arg(long)]
    pub frac_bits: Option<u32>,
    /// Which beam a cell processes first. Default: the preset's (radial; wavefront with
    /// --thesis).
    #[arg(long, value_enum)]
    pub policy: Option<PolicyArg>,
    /// Merge an arriving beam into a waiting beam of the same voxel when their ray rectangles
    /// share a side (exact; fewer beams to process): on, off, or auto (on for wavefront and
    /// radial, off for the thesis policy).
    #[arg(long, value_enum, default_value_t = MergeArg::Auto)]
    pub merge: MergeArg,
    /// Which cells the host visits each cycle: only those holding beams, or every cell (the
    /// reference). Same results, cycles and counters either way.
    #[arg(long, value_enum)]
    pub stepping: Option<SteppingArg>,
    /// Drop sub-beams that can meet no occupied voxel any more (outside the occupied bounding
    /// box and moving away from it); their rays are counted as skipped. Exact: same lit voxels.
    /// Default: the preset's (on; off with --thesis).
    #[arg(long, action = clap::ArgAction::Set)]
    pub skip_receding: Option<bool>,
    /// Do not emit a source's initial beams whose direction leads away from the occupied box.
    /// Default: the preset's (on; off with --thesis).
    #[arg(long, action = clap::ArgAction::Set)]
    pub skip_dead_directions: Option<bool>,
    /// Faulty links: every transfer is framed with a CRC-32, corrupted, dropped or delayed at
    /// these rates (e.g. `corrupt=0.01,drop=0.01,delay=0.05,delay-cycles=8,seed=7`; rates
    /// 0 ..= 1 summing to at most 1; a delayed frame is held 1 ..= delay-cycles cycles, default
    /// 8), and delivered by acknowledgement and retransmission. Same lit voxels and image, more
    /// cycles.
    #[arg(long, value_parser = clap::value_parser!(crate::machine::links::faults::LinkFaults))]
    pub link_faults: Option<crate::machine::links::faults::LinkFaults>,
    /// Stop with a stall report (the blocked cells and their queues) after this many cycles in
    /// a row without progress while beams are in flight: a deadlock, or a dead link.
    /// Default: the preset's (64).
    #[arg(long)]
    pub stall_cycles: Option<u64>,
    /// Cells keep lit marks only for the voxels their pixel reads: the same image, a lit set
    /// (`--lit-out`, stats) restricted to those voxels, and no lit-store overflow in columns lit
    /// in many separate runs (walls seen edge-on, many lights). Default: the preset's (on for
    /// `render`, off with --reflections, which read hidden voxels; off for the others).
    #[arg(long, num_args = 0..=1, default_missing_value = "true", action = clap::ArgAction::Set)]
    pub lit_visible_only: Option<bool>,
    /// Drop a beam when none of its rays can meet an occupied block of the scene's occupancy
    /// summary (--frustum-blocks) at any later layer (their rays are counted as skipped).
    /// Exact: same lit voxels; each cell holds the summary. Default: off.
    #[arg(long, num_args = 0..=1, default_missing_value = "true", action = clap::ArgAction::Set)]
    pub skip_frustum: Option<bool>,
    /// Drop a beam when none of its rays can reach a block holding a voxel a pixel reads: the
    /// empty-frustum test against a summary of those voxels only. Same image and same visible
    /// lit set; hidden voxels are not lit. Needs the visible-only lit store. Default: the
    /// preset's (on for `render` with the visible-only store, off for the others).
    #[arg(long, num_args = 0..=1, default_missing_value = "true", action = clap::ArgAction::Set)]
    pub skip_hidden: Option<bool>,
    /// Blocks per axis of the summary --skip-frustum and --skip-hidden test beams against:
    /// finer blocks drop more beams and take more memory per cell (8: 232 B, 16: 1 348 B,
    /// 32: 9 384 B). Same lit voxels and image with any. Default: the preset's (32; 8 for
    /// `trace`: a cell trace carries the 8 × 8 × 8 summary).
    #[arg(long, value_enum)]
    pub frustum_blocks: Option<FrustumBlocksArg>,
    /// A measurement, not a cell's rule: the host, which knows every pixel's target ray, drops
    /// each beam that carries none to a later layer (`rays`), or whose voxel lies on none before
    /// its target (`voxels`), its rays counted as skipped. The same image; the beams, messages
    /// and cycles left are what the image needs. Needs exact occluders and the visible-only lit
    /// store. Default: off.
    #[arg(long, value_enum)]
    pub oracle_skip: Option<OracleSkipArg>,
    /// The sibling wait: a beam that does not yet hold every ray its voxel can receive waits
    /// up to this many cycles (while its FIFO has room) for the pieces from its other parent
    /// voxels to merge into it: fewer beams and messages, same lit voxels. 0: off. Wavefront
    /// policy only; at most 4096. Default: 0.
    #[arg(long, value_parser = clap::value_parser!(u16).range(0..=4096))]
    pub hold: Option<u16>,
    /// The lit rule. `exact`: exact occluders — each cell keeps the scene's triangles
    /// through its column and a ray is stopped where it meets one; with diffusion each pixel is
    /// lit iff its one target ray (the lattice ray nearest the exact ray to its point) arrives
    /// (thesis §5.5.6); a classic shadow ray is tested against the triangles of each column it
    /// enters. `plane`: a ray is stopped only where it crosses the plane of the facet owning
    /// the voxel it is in, and each pixel is lit from its visible surface's own plane (no
    /// triangle store). `thesis`: a beam entering an occupied voxel lights it and stops
    /// (§5.5.5), and the pixel shows the first occupied voxel of its column. Default: the
    /// preset's (exact; plane for `trace`; thesis with --thesis). What each costs and gets
    /// wrong: BENCHMARKS.md, "How accurate is the image?".
    #[arg(long, value_enum)]
    pub lit_rule: Option<LitRuleArg>,
    /// Where each face's rays leave from along its axis: `light`, the light itself, so that
    /// the rays are true rays from the source wherever it sits in its voxel (needs `--fa` ≥ 4;
    /// not for classic lighting); `voxel`, the source voxel's centre plane, so that layer k is
    /// k whole voxels from it (thesis §4.3; a light on a voxel boundary is half a voxel off
    /// along the axis). Same split arithmetic. Default: the preset's (light; voxel for `trace`,
    /// --thesis and --lighting classic).
    #[arg(long, value_enum)]
    pub rays_from: Option<RaysFromArg>,
    /// How a pixel's visibility of each light is decided under exact occluders (thesis
    /// §5.5.5, "several rays reach one pixel"): `target`, lit iff its one target ray arrives;
    /// `ratio`, the cells count the lattice rays of the target ray's voxel that lie on the
    /// surface's lit side and the share of them that arrive weighs the light (soft shadow
    /// edges: a pixel half covered by a shadow gets about half the light); `majority`, lit iff
    /// more than half of them arrive (the thesis's "> 0.5"). Same beams, cycles and messages;
    /// more fraction bits (--frac-bits) give each voxel more rays to count. With --reference,
    /// the f64 reference then samples each pixel's footprint on its surface (8 × 8 points)
    /// and weighs the light by the share that sees it (or by its majority). Default: target.
    #[arg(long, value_enum)]
    pub visibility: Option<VisibilityArg>,
    /// Classic shadow rays instead of diffusion.
    #[command(flatten)]
    pub classic: crate::cli::phase_args::ClassicOpts,
}

/// A named run ([`crate::config::Preset`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PresetArg {
    /// What `render` runs.
    Render,
    /// What `light` runs.
    Light,
    /// What `trace` records and the firmware replays.
    Trace,
    /// The thesis's machine.
    Thesis,
}

impl From<PresetArg> for crate::config::Preset {
    fn from(a: PresetArg) -> Self {
        match a {
            PresetArg::Render => crate::config::Preset::Render,
            PresetArg::Light => crate::config::Preset::Light,
            PresetArg::Trace => crate::config::Preset::Trace,
            PresetArg::Thesis => crate::config::Preset::Thesis,
        }
    }
}

/// Where rays leave from ([`cell_core::beam::Origin`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RaysFromArg {
    /// The source voxel's centre plane (thesis §4.3).
    Voxel,
    /// The light itself.
    Light,
}

impl From<RaysFromArg> for cell_core::beam::Origin {
    fn from(a: RaysFromArg) -> Self {
        match a {
            RaysFromArg::Voxel => cell_core::beam::Origin::SourceVoxel,
            RaysFromArg::Light => cell_core::beam::Origin::Light,
        }
    }
}

/// The lit rule ([`cell_core::lit`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LitRuleArg {
    /// A beam entering an occupied voxel lights it and stops (§5.5.5).
    Thesis,
    /// Stopped only by a plane crossed there; each pixel lit from its visible surface's plane.
    Plane,
    /// Exact occluders: a ray is stopped where it meets a triangle its cells keep; with
    /// diffusion each pixel is lit iff its one target ray (the lattice ray nearest the ray to
    /// its point) arrives.
    Exact,
}

impl From<LitRuleArg> for cell_core::lit::LitRule {
    fn from(a: LitRuleArg) -> Self {
        match a {
            LitRuleArg::Thesis => cell_core::lit::LitRule::Thesis,
            LitRuleArg::Plane => cell_core::lit::LitRule::Plane,
            LitRuleArg::Exact => cell_core::lit::LitRule::Exact,
        }
    }
}

/// Where `light-accuracy` measures a surface voxel's visibility ([`crate::jobs::accuracy::Measure`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MeasureArg {
    /// The voxel's centre, its own face ignored.
    Centre,
    /// Where the segment from the light enters the voxel.
    Entry,
    /// One voxel before the centre along the segment's major axis.
    Reach,
}

impl From<MeasureArg> for crate::jobs::accuracy::Measure {
    fn from(a: MeasureArg) -> Self {
        use crate::jobs::accuracy::Measure;
        match a {
            MeasureArg::Centre => Measure::Centre,
            MeasureArg::Entry => Measure::Entry,
            MeasureArg::Reach => Measure::Reach,
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

impl From<SteppingArg> for crate::machine::lighting::diffuse::Stepping {
    fn from(a: SteppingArg) -> Self {
        match a {
            SteppingArg::Active => crate::machine::lighting::diffuse::Stepping::Active,
            SteppingArg::AllCells => crate::machine::lighting::diffuse::Stepping::AllCells,
        }
    }
}

/// Normal used for shading.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum NormalArg {
    /// The facet's normal stored with each dexel (16-bit octahedral code, §5.2.1): flat facets.
    Facet,
    /// The voxel face the view ray crossed; no normal stored (§5.2.2).
    Face,
    /// Smooth: the facet packets carry the vertex normals (the OBJ's `vn`, else averaged over the
    /// faces around each vertex), each cell shades with each of them at its visible point and
    /// interpolates the colours (+6 bytes per packet, +12 per cell; needs the plane or exact lit
    /// rule, no reflections or radiosity).
    Gouraud,
    /// Smooth: as gouraud, but the cell interpolates the normal at its visible point and shades
    /// once with it (docs/LIGHTING.md, "Smooth shading").
    Phong,
}

impl From<NormalArg> for cell_core::shade::NormalMode {
    fn from(a: NormalArg) -> Self {
        match a {
            NormalArg::Facet | NormalArg::Gouraud | NormalArg::Phong => cell_core::shade::NormalMode::Facet,
            NormalArg::Face => cell_core::shade::NormalMode::Face,
        }
    }
}

impl NormalArg {
    /// The smooth mode asked for, if any.
    pub fn smooth(self) -> Option<cell_core::smooth::Smooth> {
        match self {
            NormalArg::Facet | NormalArg::Face => None,
            NormalArg::Gouraud => Some(cell_core::smooth::Smooth::Gouraud),
            NormalArg::Phong => Some(cell_core::smooth::Smooth::Phong),
        }
    }
}

/// How a sample takes its lights (`render --sample-lights`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SampleLightsArg {
    /// The lit states of the four cells around the sample, weighed bilinearly.
    Bilinear,
    /// The lit state of the nearest cell that shows the sample's facet.
    Nearest,
}

impl From<SampleLightsArg> for cell_core::subpixel::SampleLights {
    fn from(a: SampleLightsArg) -> Self {
        match a {
            SampleLightsArg::Bilinear => cell_core::subpixel::SampleLights::Bilinear,
            SampleLightsArg::Nearest => cell_core::subpixel::SampleLights::Nearest,
        }
    }
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
    /// Normals the cells shade with: flat facets (the default), voxel faces, or smooth (vertex
    /// normals interpolated over each triangle: gouraud or phong).
    #[arg(long, value_enum, default_value_t = NormalArg::Facet)]
    pub normals: NormalArg,
    /// Samples per pixel side (1 to 4): each cell also finds the surface at S × S points of its
    /// pixel's square during loading, lights each from itself or from the neighbour that shows
    /// the same facet, and shows the mean of their colours (anti-aliased silhouettes and
    /// creases; lighting unchanged; needs the plane or exact lit rule, facet or face normals, no
    /// reflections or radiosity). With --reference the reference averages
    /// the same S × S points (docs/LIGHTING.md, "Samples per pixel").
    #[arg(long, default_value_t = 1)]
    pub samples: u32,
    /// With --samples: how a sample takes its lights from the cells around it. bilinear: the
    /// lit states of the four cells whose centres surround it, weighed by its position among
    /// them (over those that show its facet or its plane), so that shadow edges fall off across
    /// a pixel; nearest: those of the nearest cell that shows its facet.
    #[arg(long, value_enum, default_value_t = SampleLightsArg::Bilinear)]
    pub sample_lights: SampleLightsArg,
    /// Reflection options.
    #[command(flatten)]
    pub reflect: crate::cli::phase_args::ReflectOpts,
    /// Add indirect light: progressive radiosity on the grid (as the `radiosity` job, whose
    /// --patch-size, --shots, --residual and --offset it takes), each cell shading its direct
    /// light plus the indirect light of its visible point; also writes F.direct.png (direct
    /// light only). With --reference, the reference shades with the f64 solver's radiosity.
    #[arg(long)]
    pub radiosity: bool,
    /// Radiosity options (with --radiosity).
    #[command(flatten)]
    pub radiosity_opts: crate::cli::phase_args::RadiosityOpts,
    /// How a cell shows radiosity (with --radiosity): flat (its patch's value) or smooth (vertex
    /// values interpolated over the patch) [default: smooth].
    #[arg(long, value_enum)]
    pub radiosity_display: Option<crate::cli::phase_args::DisplayArg>,
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
    /// Timing rules of the cycle model to run (docs/DIFFUSION-TIMING.md).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "rc2")]
    pub timing: Vec<TimingArg>,
    /// Override the timings' link rate: messages per link, direction and cycle (1 ..= 3).
    #[arg(long)]
    pub link_rate: Option<u8>,
    /// Override the timings' input register: whether FA counts only the waiting beams.
    #[arg(long)]
    pub register: Option<bool>,
    /// Override the timings' free-ports rule: a beam goes only when every output buffer it
    /// sends to is empty.
    #[arg(long)]
    pub free_ports: Option<bool>,
    /// Run every (N, FA) point the thesis published (§4.4.3's tables) instead of --n × --fa.
    #[arg(long)]
    pub published: bool,
    /// Where the source sits: the grid's centre voxel (n/2, n/2, n/2) or its origin corner.
    #[arg(long, value_enum, default_value_t = SourceAtArg::Centre)]
    pub source: SourceAtArg,
    /// Override the timings' emission order of the six initial beams.
    #[arg(long, value_enum)]
    pub emission: Option<EmissionArg>,
    /// Override the timings' burst: the source hands over every initial beam its FIFO has
    /// room for in one cycle.
    #[arg(long)]
    pub burst: Option<bool>,
    /// Also write the thesis's time-lapse of the 16³ experiment (§4.4.3) as slices, one PNG
    /// per FA of `--timelapse-fa`, named after this path (`F.fa1.png`, …); only that run.
    #[arg(long)]
    pub timelapse: Option<PathBuf>,
    /// FIFO sizes of the time-lapse.
    #[arg(long, value_delimiter = ',', default_value = "1,16")]
    pub timelapse_fa: Vec<usize>,
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
    /// On or off as given; `None` for auto.
    pub(crate) fn choice(self) -> Option<bool> {
        match self {
            MergeArg::Auto => None,
            MergeArg::On => Some(true),
            MergeArg::Off => Some(false),
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
    /// The lit rule measured: `exact` (what `light` runs: rays from the light, each occupied
    /// voxel lit iff the lattice ray nearest the exact ray to its centre arrives), `plane` or
    /// `thesis` (rays from the source voxel).
    #[arg(long, value_enum, default_value_t = LitRuleArg::Exact)]
    pub lit_rule: LitRuleArg,
    /// A light at grid-normalised X,Y,Z (repeatable; default: the scene's own).
    #[arg(long = "light", value_parser = parse_triple)]
    pub lights: Vec<[f64; 3]>,
    /// Which point of a surface voxel the f64 visibility is taken at, on the exact segment
    /// from the light to its centre: `centre` (its own face ignored), `entry` (where the
    /// segment enters the voxel), `reach` (one voxel before the centre along the segment's
    /// major axis: how far the machine's voxel ray must come unstopped under exact occluders).
    #[arg(long, value_enum, default_value_t = MeasureArg::Centre)]
    pub measure: MeasureArg,
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
    /// The camera each scene is seen through (the same at every n).
    #[command(flatten)]
    pub camera: CameraArgs,
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
    /// A point light at grid-normalised coordinates X,Y,Z in 0..1 (repeatable; replaces the
    /// scene's own lights): the peaks are those of the cells lit from these.
    #[arg(long = "light", value_parser = parse_triple)]
    pub lights: Vec<[f64; 3]>,
    /// Write the audit as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the firmware images' flash tables (per module) as CSV to this file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// A firmware ELF whose sections and flash per module to report; repeat for several
    /// (default: the release builds under firmware/ that exist, the production image `cell`
    /// and the trace-replaying `rc2-firmware`).
    #[arg(long)]
    pub elf: Vec<PathBuf>,
}

/// Options of `trace`.
#[derive(Args, Debug)]
pub struct TraceArgs {
    /// Scene and loading options.
    #[command(flatten)]
    pub load: LoadArgs,
    /// Lighting options (the firmware is built for the default --frac-bits 0). With
    /// `--lighting classic` the trace records the classic shadow-ray phase of each source
    /// instead of beam diffusion.
    #[command(flatten)]
    pub light: LightOpts,
    /// The reflection phase, recorded after shading (`--reflections N`, N > 0; needs
    /// `--lighting diffusion` and the fitted view, the default with it).
    #[command(flatten)]
    pub reflect: crate::cli::phase_args::ReflectOpts,
    /// A cell to record, X,Y (repeatable).
    #[arg(long = "cell", value_parser = parse_cell)]
    pub cells: Vec<[u32; 2]>,
    /// Also record the cell that processes the most beams (with `--lighting classic`: the most
    /// shadow-ray voxel steps), found by a first run. Near a source that cell receives most
    /// rays: its trace can be large.
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
/// Options of `form-factors`.
#[derive(Args, Debug)]
pub struct FormFactorsArgs {
    /// Compute §2.5's Tables 2.1 (equivalent resolutions), 2.2 (proxels used) and 2.3 (memory,
    /// Mo) from each method's surface and print them, `computed (published)`, `*` where a cell
    /// is more than one unit of its last digit away (docs/FORM-FACTORS.md says why).
    #[arg(long)]
    pub tables: bool,
    /// Also write the tables as CSV: columns table (2.1|2.2|2.3), reference (the row's reference
    /// form factor, or hemicube resolution), method, computed, published.
    #[arg(long, value_name = "F.csv")]
    pub csv: Option<PathBuf>,
    /// Draw §2.5.4's comparison (the thesis's Fig. 2.18): the form factor of two of four equal
    /// squares off the axis, at two distances, by every method at the resolution equivalent to
    /// a hemicube of every even R from 16 to 96, as its relative error to the exact value (PNG).
    #[arg(long, value_name = "F.png")]
    pub figure: Option<PathBuf>,
    /// Also write the figure's points as CSV: columns distance, facet, method, hemicube_r,
    /// resolution, computed, exact, relative_error.
    #[arg(long, value_name = "F.csv", requires = "figure")]
    pub figure_csv: Option<PathBuf>,
    /// Compare ch. 3's form factors toward a source on these scenes (comma-separated names or
    /// .obj files; Tables 3.2 and 3.3): from every vertex of the scene (its patches' corners)
    /// to the patch emitting the most power, by Wallace's rays (1, 4 × 4 and 5 × 5 per vertex,
    /// §3.1) and by the subdivided beam (§3.4), each timed on one thread over every triangle
    /// (no acceleration structure, as the thesis timed them), the beam's time split into its
    /// phases, each estimate's error measured against 32 × 32 jittered rays per vertex.
    #[arg(long, value_name = "SCENE", value_delimiter = ',')]
    pub ray_traced: Vec<String>,
    /// With --ray-traced: the largest patch edge, as a fraction of the scene's largest extent.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.0625, requires = "ray_traced")]
    pub ray_traced_patch: f64,
    /// With --ray-traced: how many times a beam may be cut in four (the thesis's 4: up to 256
    /// sub-beams from a quadrilateral source); at most 8.
    #[arg(long, value_name = "L", default_value_t = 4, requires = "ray_traced")]
    pub ray_traced_level: u32,
    /// With --ray-traced: write one line per scene and method as CSV: columns scene,
    /// receivers, occluders, source_area, source_vertices, method, seconds, ratio_to_ray1,
    /// work_per_receiver (rays, or beam cuts), candidates_per_receiver, candidates_share,
    /// recursion_share, form_factor_share, relative_error.
    #[arg(long, value_name = "F.csv", requires = "ray_traced")]
    pub ray_traced_csv: Option<PathBuf>,
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
    crate::dist::set_spread(cli.spread.into(), cli.tile_rows.clone());
    pool.install(|| dispatch(cli.command))
}

/// Each command's job, with its arguments converted into the job's options ([`options`]).
///
/// Under MPI (docs/MPI.md) the ranks other than 0 take part in `render` and `light` only (their
/// diffusion's sources are spread over the ranks), quietly; under classic shadow rays, and in
/// every other command, rank 0 works alone.
fn dispatch(command: Command) -> Result<()> {
    let helper = crate::dist::helper();
    if helper && !matches!(command, Command::Render(_) | Command::Light(_) | Command::Radiosity(_)) {
        return Ok(());
    }
    match command {
        Command::Voxelize(a) => jobs::voxelize::run(&(&a).into()),
        Command::Render(a) => {
            let o: jobs::render::RenderOptions = (&a).try_into()?;
            if helper && o.light.classic.is_some() {
                return Ok(());
            }
            if helper {
                // A helper rank only diffuses its share of the sources: no reference image, no
                // radiosity (neither changes the grid or the diffusion; rank 0 does both).
                let o = jobs::render::RenderOptions { quiet: true, reference: false, radiosity: None, ..o };
                return jobs::render::run(&o);
            }
            jobs::render::run(&o)
        }
        Command::Light(a) => {
            let o: jobs::light::LightOptions = (&a).try_into()?;
            if helper && o.light.classic.is_some() {
                return Ok(());
            }
            jobs::light::run(&jobs::light::LightOptions { quiet: o.quiet || helper, ..o })
        }
        Command::DiffusionTable(a) => jobs::table::run(&(&a).into()),
        Command::LightAccuracy(a) => jobs::accuracy::run(&(&a).into()),
        Command::Bench(a) => jobs::bench::run(&(&a).into()),
        Command::Audit(a) => jobs::audit::run(&(&a).into()),
        Command::Trace(a) => jobs::trace::run(&(&a).try_into()?),
        Command::Radiosity(a) => {
            let o: jobs::radiosity::RadiosityOptions = (&a).into();
            if helper {
                // A helper rank computes its share of the shots in flight (beam shots, more
                // than one under way), quietly; rank 0 alone runs the rest, and the reference.
                if o.solve.in_flight <= 1 || o.solve.shots_by != jobs::radiosity::ShotsBy::Beams {
                    return Ok(());
                }
                return jobs::radiosity::run(&jobs::radiosity::RadiosityOptions { quiet: true, reference: false, ..o });
            }
            jobs::radiosity::run(&o)
        }
        Command::Scenes => {
            jobs::scenes::list();
            Ok(())
        }
        Command::Subdivide(a) => jobs::scenes::subdivide(&(&a).into()),
        Command::FormFactors(a) => jobs::form_factors::run(&(&a).into()),
        Command::VirtualImages(a) => {
            let r = jobs::virtual_images::run(&(&a).into())?;
            println!(
                "virtual images (n = {}, hit {:?}, {:?} normals, {}-connected): {} rays, {} reflected; closest approach to S' mean {:.3}, rms {:.3}, max {:.3} voxels ({:.1} % within one voxel); screen: {} footprint cells, {:.2} % dark ({:.2} % with the same rays reflected exactly); wrote {}",
                a.n, a.hit, a.reflect_normal, a.ray_connectivity, r.rays, r.reflected, r.spread_mean, r.spread_rms,
                r.spread_max, 100.0 * r.within_one_voxel, r.footprint_cells, r.dark_pct, r.dark_continuous_pct, a.out.display()
            );
            Ok(())
        }
    }
}

pub(crate) fn parse_form_factors(s: &str) -> std::result::Result<crate::truth::formfactor::Estimator, String> {
    use crate::truth::formfactor::Estimator;
    if s == "beams" {
        return Ok(Estimator::Contour);
    }
    crate::truth::projective::SurfaceSpec::parse(s).map(Estimator::Projective).map_err(|e| format!("{e:#}; or beams"))
}

fn parse_capacity(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(v @ (8 | 16 | 32 | 64 | 128)) => Ok(v),
        _ => Err(format!("'{s}' is not a compiled dexel capacity (8, 16, 32, 64 or 128)")),
    }
}
