//! The `radiosity` job: progressive radiosity on the grid (radiosity thesis §1.3.2, §3.4;
//! [`crate::machine::shooting::shots`]), per-patch results and per-shot costs as CSV, and with
//! `--reference` the f64 solver on the same patches ([`crate::truth::radiosity`]) for the
//! per-patch RMS error — the machine's and direct light's (the emitters' shots only).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Result};
use cell_core::beam::frac::U0;

use crate::machine::grid::capacity::HostLightCell;
use crate::machine::loading::loaded_scene::{load_scene, LoadedScene};
use crate::machine::shooting::proxels::{ProxelConfig, SurfaceKind, Update};
use crate::machine::shooting::shots::{solve, solve_by_proxels, GridSolution, RadiosityConfig, ShotLog};
use crate::precompute::LoadConfig;
use crate::report::convergence::{plot_residuals, Series};
use crate::report::files::{create, write_json};
use crate::report::progress;
use crate::scene::patches::{subdivide_voxels, Patches};
use crate::truth::formfactor::{Estimator, FormFactors, Sampling};
use crate::truth::radiosity::{ambient, rms_relative_error, ShootConfig, Solution};

/// Most patches a scene may be cut into (a cell names a patch with 16 bits).
pub const MAX_PATCHES: usize = u16::MAX as usize;

/// How a radiosity solution is made: the patches and the stopping rule, shared by the
/// `radiosity` job and `render --radiosity`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadiositySettings {
    /// Largest patch edge, in voxels.
    pub patch_size: f64,
    /// Shot budget.
    pub shots: usize,
    /// Stop when the unshot power is at most this fraction of the emitted power.
    pub residual: f64,
    /// Push of each shot's source off its patch, voxels.
    pub offset: f64,
    /// How the f64 reference estimates its form factors (`--form-factors`; default: the
    /// ray-cast contour estimator).
    pub estimator: Estimator,
    /// How the machine shoots (`--shots-by`).
    pub shots_by: ShotsBy,
    /// With a projection: its resolution (`--resolution`; `None`: the default for the grid,
    /// [`ProxelConfig::default_resolution`]).
    pub resolution: Option<u32>,
    /// With a projection: the update the shots' cycles count (`--update`).
    pub update: Update,
}

/// How the machine computes a shot's form factors (`--shots-by`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShotsBy {
    /// One beam diffusion per shot (radiosity thesis ch. 5, [`crate::machine::shooting::shots`]).
    #[default]
    Beams,
    /// The shooter's hemicube distributed over the cells (§6.2, [`crate::machine::shooting::proxels`]).
    ProxelsHemicube,
    /// The shooter's projection disk distributed over the cells (§6.2).
    ProxelsDisk,
}

impl ShotsBy {
    /// Its `--shots-by` name.
    pub fn name(self) -> &'static str {
        match self {
            ShotsBy::Beams => "beams",
            ShotsBy::ProxelsHemicube => "proxels-hemicube",
            ShotsBy::ProxelsDisk => "proxels-disk",
        }
    }
}

impl Default for RadiositySettings {
    fn default() -> Self {
        RadiositySettings {
            patch_size: 24.0,
            shots: 100_000,
            residual: 0.01,
            offset: crate::machine::shooting::shots::DEFAULT_OFFSET,
            estimator: Estimator::Contour,
            shots_by: ShotsBy::Beams,
            resolution: None,
            update: Update::default(),
        }
    }
}

impl RadiositySettings {
    /// The machine's settings: shots diffused under the plane rule from the source voxel
    /// ([`crate::config::plane_rule`], made fit for shooting).
    pub fn machine(&self) -> RadiosityConfig {
        let mut cfg = RadiosityConfig::new(crate::config::plane_rule(), self.residual, self.shots);
        cfg.offset = self.offset;
        cfg
    }

    /// With a projection, what the cells project on an n × n grid.
    pub fn proxels(&self, n: u32) -> Option<ProxelConfig> {
        let surface = match self.shots_by {
            ShotsBy::Beams => return None,
            ShotsBy::ProxelsHemicube => SurfaceKind::Hemicube,
            ShotsBy::ProxelsDisk => SurfaceKind::Disk,
        };
        let resolution = self.resolution.unwrap_or_else(|| ProxelConfig::default_resolution(n));
        Some(ProxelConfig { surface, resolution, update: self.update })
    }

    /// The patches of `mesh` on a grid of voxel size `voxel` (world units).
    pub fn patches(&self, mesh: &crate::scene::Mesh, voxel: f64) -> Result<Patches> {
        subdivide_voxels(mesh, self.patch_size, voxel, MAX_PATCHES)
    }
}

/// What the `radiosity` job runs and writes.
#[derive(Clone, Debug)]
pub struct RadiosityOptions {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// Grid side and surfaces.
    pub load: LoadConfig,
    /// Patches and stopping rule.
    pub solve: RadiositySettings,
    /// Also solve with the f64 reference and compare.
    pub reference: bool,
    /// With `reference`: also solve it with 4× the samples and report its self-error.
    pub reference_self_error: bool,
    /// With `reference`: also solve a converged truth ([`TRUTH_STRATA`], a tenth of the
    /// residual) and report the reference's and the machine's errors against it.
    pub truth_error: bool,
    /// With `truth_error`: read the truth from this file when it was solved for the same
    /// patches and stopping rule, else solve it and write it there ([`truth_key`]).
    pub truth_cache: Option<PathBuf>,
    /// Per-patch CSV (default `<scene>_patches.csv`).
    pub patches_csv: Option<PathBuf>,
    /// Per-shot CSV (default `<scene>_shots.csv`).
    pub shots_csv: Option<PathBuf>,
    /// Residual against shots, PNG (default `<scene>_residual.png`).
    pub residual_plot: Option<PathBuf>,
    /// Summary as JSON.
    pub stats: Option<PathBuf>,
    /// No progress bar.
    pub quiet: bool,
}

/// The job's summary.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RadiosityStats {
    /// Scene and grid side.
    pub scene: String,
    /// Grid side.
    pub n: u32,
    /// Patches.
    pub patches: usize,
    /// Shots made.
    pub shots: usize,
    /// Why it stopped.
    pub stop: crate::machine::shooting::shots::GridStop,
    /// Unshot over emitted power at the end.
    pub residual: f64,
    /// Grid cycles in all (broadcasts, diffusions, reductions).
    pub cycles: u64,
    /// Messages in all.
    pub messages: u64,
    /// Beams the grid processed in all its shots' diffusions (its samples, beside the
    /// reference's rays or proxels).
    pub beams_processed: u64,
    /// Mean per shot: diffusion cycles, reduction cycles, messages.
    pub diffusion_cycles_per_shot: f64,
    /// Mean reduction cycles per shot.
    pub reduce_cycles_per_shot: f64,
    /// Mean messages per shot.
    pub messages_per_shot: f64,
    /// Bytes a cell adds for radiosity: its patch map, its accumulator and the shot's normal.
    pub bytes_per_cell_added: usize,
    /// Bytes of the lighting cell it extends.
    pub bytes_per_light_cell: usize,
    /// Faces the subdivision skipped as zero-area (they get no patch; their voxels, if any,
    /// count as unmapped).
    pub zero_area_faces: usize,
    /// Voxels with no patch.
    pub unmapped_voxels: u64,
    /// Accumulator additions that found no slot or no patch.
    pub received_overflows: u64,
    /// Wall time of the machine's solution, seconds.
    pub wall_seconds: f64,
    /// With `--reference`: the comparison.
    pub reference: Option<ReferenceStats>,
    /// With `--shots-by proxels-*`: what the cells projected and what it cost.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub proxels: Option<ProxelStats>,
}

/// A solution shot by projection: the surface, and its phases' costs per shot.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ProxelStats {
    /// `--shots-by`.
    pub shots_by: ShotsBy,
    /// Resolution R.
    pub resolution: u32,
    /// The update the cycles count.
    pub update: Update,
    /// Bytes a cell holds for them (proxel store and patch share).
    pub bytes_per_cell: usize,
    /// Mean per shot: select and shooter broadcast cycles.
    pub select_cycles_per_shot: f64,
    /// Mean per shot: projection cycles (cull, broadcasts, zone tests).
    pub projection_cycles_per_shot: f64,
    /// Mean per shot: triangles broadcast.
    pub triangles_per_shot: f64,
    /// Proxel tests that found their triangle over the zone tests the SIMD cells made (the
    /// thesis's *rendement*, Fig. 6.15.b).
    pub zone_yield: f64,
    /// The same over the proxels inside the rectangles (a MIMD cell's tests).
    pub rect_yield: f64,
    /// Every update strategy: its name, mean cycles and messages per shot.
    pub updates: Vec<UpdateStats>,
}

/// One update strategy over a solution.
#[derive(Clone, Debug, serde::Serialize)]
pub struct UpdateStats {
    /// `--update` name.
    pub update: &'static str,
    /// Mean cycles per shot.
    pub cycles_per_shot: f64,
    /// Mean messages per shot.
    pub messages_per_shot: f64,
}

/// The proxel statistics of a solution shot by projection (`None` for beams).
fn proxel_stats(settings: &RadiositySettings, n: u32, s: &GridSolution) -> Option<ProxelStats> {
    let cfg = settings.proxels(n)?;
    let costs: Vec<&crate::machine::shooting::proxels::ProxelCost> =
        s.shots.iter().filter_map(|x| x.proxel.as_ref()).collect();
    let k = costs.len().max(1) as f64;
    let mean = |f: &dyn Fn(&crate::machine::shooting::proxels::ProxelCost) -> u64| {
        costs.iter().map(|c| f(c)).sum::<u64>() as f64 / k
    };
    let (hits, zones, rects) = (mean(&|c| c.hits), mean(&|c| c.zone_tests), mean(&|c| c.rect_tests));
    Some(ProxelStats {
        shots_by: settings.shots_by,
        resolution: cfg.resolution,
        update: cfg.update,
        bytes_per_cell: crate::machine::shooting::proxels::bytes_per_cell(),
        select_cycles_per_shot: mean(&|c| c.select_cycles),
        projection_cycles_per_shot: mean(&|c| c.projection_cycles),
        triangles_per_shot: mean(&|c| c.triangles),
        zone_yield: hits / zones.max(1.0),
        rect_yield: hits / rects.max(1.0),
        updates: Update::ALL
            .iter()
            .enumerate()
            .map(|(u, up)| UpdateStats {
                update: up.name(),
                cycles_per_shot: mean(&|c| c.updates[u].cycles),
                messages_per_shot: mean(&|c| c.updates[u].messages),
            })
            .collect(),
    })
}

/// The machine against the f64 reference on the same patches and stopping rule.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ReferenceStats {
    /// Area-weighted RMS relative error of the machine's per-patch radiosity.
    pub rms_relative_error: f64,
    /// The same for direct light only (the reference after its emitters' shots).
    pub direct_only_rms_relative_error: f64,
    /// Shots the reference made.
    pub shots: usize,
    /// With `--reference-self-error`: area-weighted RMS relative difference between the
    /// reference (3 × 3 strata per patch pair) and the same solver with 6 × 6 strata, on the
    /// reflected radiosity B − E (a bound on the reference's own error at this patch size).
    pub self_error: Option<f64>,
    /// Wall time of the reference, seconds.
    pub wall_seconds: f64,
    /// How its form factors were estimated (`--form-factors`).
    pub estimator: Estimator,
    /// Visibility rays its form factors cast (the ray-cast estimators).
    pub rays_cast: u64,
    /// Proxels its form factors projected (a projective `--form-factors`: the surface's
    /// proxels at every shooter point of every row computed).
    pub proxels: u64,
    /// With `--truth-error`: the reference's and the machine's errors against a converged
    /// truth.
    pub truth: Option<TruthError>,
}

/// Strata per triangle side of the converged truth (`--truth-error`): 6 × 6 sample points per
/// triangle of each patch, four times the reference's.
pub const TRUTH_STRATA: usize = 6;

/// Errors against a converged truth: the contour estimator ([`Estimator::Contour`]) with
/// [`TRUTH_STRATA`] strata, solved to a tenth of the run's residual. Errors are area-weighted RMS
/// relative differences on the reflected radiosity B − E (the emitted part is exact in every
/// solution).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct TruthError {
    /// Strata of the truth's sample points per triangle side.
    pub strata: usize,
    /// The truth's stopping residual.
    pub residual: f64,
    /// Shots the truth made.
    pub shots: usize,
    /// The reference (with its `--form-factors`) against the truth.
    pub reference_rms_relative_error: f64,
    /// The machine against the truth.
    pub machine_rms_relative_error: f64,
    /// Wall time of the truth, seconds (of reading it, when `cached`).
    pub wall_seconds: f64,
    /// Whether it was read from `--truth-cache` rather than solved.
    pub cached: bool,
}

/// Run the `radiosity` job.
pub fn run(o: &RadiosityOptions) -> Result<()> {
    o.load.validate()?;
    let mesh = crate::scene::load(&o.scene)?;
    let scene = load_scene(&mesh, &o.load)?;
    let p = o.solve.patches(&mesh, scene.fit.voxel)?;
    let t0 = Instant::now();
    let s = solve_with_bar(&scene, &p, &o.solve, o.quiet)?;
    let wall = t0.elapsed().as_secs_f64();
    let truth = o.truth_error.then_some(o.truth_cache.as_deref());
    let compared = o.reference.then(|| compare(&p, &s, &o.solve, o.reference_self_error, truth)).transpose()?;
    let plot = o.residual_plot.clone().unwrap_or_else(|| format!("{}_residual.png", mesh.name).into());
    plot_residual(&plot, &mesh.name, scene.grid.n, &s, compared.as_ref().map(|c| &c.solution), o.solve.residual)?;
    let stats = summarise(&mesh.name, &scene, &p, &s, &o.solve, wall, compared.map(|c| c.stats));
    write_patches(&o.patches_csv.clone().unwrap_or_else(|| format!("{}_patches.csv", mesh.name).into()), &p, &s)?;
    write_shots(&o.shots_csv.clone().unwrap_or_else(|| format!("{}_shots.csv", mesh.name).into()), &s.shots)?;
    if let Some(path) = &o.stats {
        write_json(path, &stats)?;
    }
    print_summary(&stats);
    Ok(())
}

/// The residual against shots: the machine's and, with `--reference`, the f64 reference's on
/// the same patches and stopping rule.
fn plot_residual(
    path: &std::path::Path,
    name: &str,
    n: u32,
    s: &GridSolution,
    reference: Option<&Solution>,
    stop: f64,
) -> Result<()> {
    let points = |r: &mut dyn Iterator<Item = f64>| -> Vec<(f64, f64)> {
        std::iter::once((0.0, 1.0))
            .chain(r.enumerate().map(|(k, v)| ((k + 1) as f64, v)))
            .filter(|p| p.1 > 0.0)
            .collect()
    };
    let mut series = vec![Series {
        label: format!("machine (n = {n})"),
        points: points(&mut s.shots.iter().map(|x| x.residual_after)),
    }];
    if let Some(r) = reference {
        series.push(Series {
            label: "f64 reference".into(),
            points: points(&mut r.shots.iter().map(|x| x.residual_after)),
        });
    }
    plot_residuals(&format!("{name}: progressive radiosity"), "shots", &series, (stop > 0.0).then_some(stop), path)?;
    eprintln!("  wrote {}", path.display());
    Ok(())
}

/// The machine's solution, shot as `settings` says, with a progress bar showing the residual.
pub fn solve_with_bar(
    scene: &LoadedScene,
    p: &Patches,
    settings: &RadiositySettings,
    quiet: bool,
) -> Result<GridSolution> {
    if settings.shots_by == ShotsBy::Beams && settings.resolution.is_some() {
        bail!("radiosity: --resolution is the projection's (--shots-by proxels-hemicube or proxels-disk); beam shots have none");
    }
    let cfg = settings.machine();
    let pb = progress::bar(quiet, "shots");
    pb.set_length(cfg.max_shots.min(100_000) as u64);
    let mut bar = |k: usize, r: f64| {
        pb.set_position(k as u64);
        pb.set_message(format!("residual {r:.4}"));
    };
    let s = match settings.proxels(scene.grid.n) {
        None => solve(&scene.grid, &scene.fit, &scene.source_face, &p.patches, &cfg, bar),
        Some(proxels) => solve_by_proxels(scene.grid.n, &p.patches, &cfg, proxels, &mut bar),
    };
    pb.finish_and_clear();
    s
}

/// Form factors of the f64 reference with `strata` × `strata` samples per patch triangle.
fn form_factors(p: &Patches, strata: usize, estimator: Estimator) -> Result<FormFactors> {
    FormFactors::new(p, Sampling { strata, seed: 1, estimator })
}

/// The f64 reference's solution on the same patches with the same stopping rule (3 × 3 strata),
/// its form factors, and its wall time in seconds.
pub fn reference_solve(p: &Patches, s: &RadiositySettings) -> Result<(FormFactors, Solution, f64)> {
    let t0 = Instant::now();
    let ff = form_factors(p, 3, s.estimator)?;
    let r = shoot(p, &ff, s)?;
    Ok((ff, r, t0.elapsed().as_secs_f64()))
}

/// The reference's progressive solution with `ff` under the stopping rule of `s`.
fn shoot(p: &Patches, ff: &FormFactors, s: &RadiositySettings) -> Result<Solution> {
    crate::truth::radiosity::solve(&p.patches, ff, &ShootConfig { stop_fraction: s.residual, max_shots: s.shots })
}

/// What [`compare`] makes: the statistics, the reference's form factors and solution, and with
/// a truth its form factors and solution.
pub struct Compared {
    /// The comparison.
    pub stats: ReferenceStats,
    /// The reference's form factors.
    pub ff: FormFactors,
    /// The reference's solution.
    pub solution: Solution,
    /// The converged truth's form factors and solution (with `truth`).
    pub truth: Option<(FormFactors, Solution)>,
}

/// The f64 reference on the same patches with the same stopping rule, and direct light only.
/// `self_error`: also solve it with 6 × 6 strata ([`ReferenceStats::self_error`]); `truth`:
/// also against a converged truth ([`TruthError`]), kept in the file it names if any.
pub fn compare(
    p: &Patches,
    s: &GridSolution,
    settings: &RadiositySettings,
    self_error: bool,
    truth: Option<Option<&Path>>,
) -> Result<Compared> {
    let (ff, r, wall_seconds) = reference_solve(p, settings)?;
    let (rays_cast, proxels) = (ff.rays_cast(), ff.proxels_sampled());
    let emitters = p.patches.iter().filter(|q| q.emission.iter().any(|&e| e > 0.0)).count();
    let direct =
        crate::truth::radiosity::solve(&p.patches, &ff, &ShootConfig { stop_fraction: 0.0, max_shots: emitters })?;
    let areas: Vec<f64> = p.patches.iter().map(|q| q.area).collect();
    let self_error = self_error
        .then(|| -> Result<f64> {
            let fine = shoot(p, &form_factors(p, 6, settings.estimator)?, settings)?;
            let reflected = |b: &[[f64; 3]]| crate::truth::radiosity::reflected(&p.patches, b);
            rms_relative_error(&reflected(&fine.radiosity), &reflected(&r.radiosity), &areas)
        })
        .transpose()?;
    let truth = truth.map(|cache| truth_error(p, s, settings, &r, cache)).transpose()?;
    let (truth, truth_solution) = truth.map_or((None, None), |(e, ff, t)| (Some(e), Some((ff, t))));
    let stats = ReferenceStats {
        rms_relative_error: rms_relative_error(&r.radiosity, &s.radiosity, &areas)?,
        direct_only_rms_relative_error: rms_relative_error(&r.radiosity, &direct.radiosity, &areas)?,
        shots: r.shots.len(),
        wall_seconds,
        estimator: settings.estimator,
        rays_cast,
        proxels,
        self_error,
        truth,
    };
    Ok(Compared { stats, ff, solution: r, truth: truth_solution })
}

/// The converged truth ([`TruthError`]), its form factors and solution, and the errors of the
/// reference `r` and the machine `s` against it; read from `cache` if it holds this truth,
/// else solved (and written there).
fn truth_error(
    p: &Patches,
    s: &GridSolution,
    settings: &RadiositySettings,
    r: &Solution,
    cache: Option<&Path>,
) -> Result<(TruthError, FormFactors, Solution)> {
    let t0 = Instant::now();
    let converged =
        RadiositySettings { residual: settings.residual / 10.0, estimator: Estimator::Contour, ..*settings };
    let ff = form_factors(p, TRUTH_STRATA, Estimator::Contour)?;
    let key = truth_key(p, &converged);
    let cached = cache.map(|c| read_truth(c, &key)).transpose()?.flatten();
    let (truth, cached) = match cached {
        Some(t) => (t, true),
        None => {
            let t = shoot(p, &ff, &converged)?;
            if let Some(c) = cache {
                write_json(c, &CachedTruth { key, solution: t.clone() })?;
            }
            (t, false)
        }
    };
    let wall_seconds = t0.elapsed().as_secs_f64();
    let areas: Vec<f64> = p.patches.iter().map(|q| q.area).collect();
    let reflected = |b: &[[f64; 3]]| crate::truth::radiosity::reflected(&p.patches, b);
    let t = reflected(&truth.radiosity);
    let e = TruthError {
        strata: TRUTH_STRATA,
        residual: converged.residual,
        shots: truth.shots.len(),
        reference_rms_relative_error: rms_relative_error(&t, &reflected(&r.radiosity), &areas)?,
        machine_rms_relative_error: rms_relative_error(&t, &reflected(&s.radiosity), &areas)?,
        wall_seconds,
        cached,
    };
    Ok((e, ff, truth))
}

/// A truth kept on disk (`--truth-cache`): what it was solved for, and the solution.
#[derive(serde::Serialize, serde::Deserialize)]
struct CachedTruth {
    key: String,
    solution: Solution,
}

/// What a truth depends on, hashed (FNV-1a over the bits): every patch's polygon, area,
/// centroid, normal, reflectance and emission, the stopping rule, the strata and the estimator.
pub fn truth_key(p: &Patches, converged: &RadiositySettings) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |x: f64| {
        for b in x.to_bits().to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for x in [p.patches.len() as f64, converged.residual, converged.shots as f64, TRUTH_STRATA as f64] {
        eat(x);
    }
    for q in &p.patches {
        for v in q.polygon.iter().chain([&q.centroid, &q.normal]) {
            [v.x, v.y, v.z].into_iter().for_each(&mut eat);
        }
        eat(q.area);
        q.reflectance.iter().chain(&q.emission).for_each(|&c| eat(c));
    }
    format!("contour-{TRUTH_STRATA}x{TRUTH_STRATA}-{h:016x}")
}

/// The truth in `path` if it holds one for `key`; `None` if there is no such file or it was
/// solved for something else (it is then solved again and overwritten).
fn read_truth(path: &Path, key: &str) -> Result<Option<Solution>> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => bail!("--truth-cache {}: {e}", path.display()),
    };
    let c: CachedTruth = serde_json::from_str(&text).map_err(|e| {
        anyhow!(
            "--truth-cache {}: not a truth written by host-sim ({e}); remove it or name another file",
            path.display()
        )
    })?;
    if c.key != key {
        eprintln!(
            "  --truth-cache {}: solved for other patches or another stopping rule; solving again",
            path.display()
        );
        return Ok(None);
    }
    Ok(Some(c.solution))
}

/// The summary of a machine solution.
pub fn summarise(
    name: &str,
    scene: &LoadedScene,
    p: &Patches,
    s: &GridSolution,
    settings: &RadiositySettings,
    wall_seconds: f64,
    reference: Option<ReferenceStats>,
) -> RadiosityStats {
    let k = s.shots.len().max(1) as f64;
    let sum = |f: &dyn Fn(&ShotLog) -> u64| s.shots.iter().map(f).sum::<u64>();
    RadiosityStats {
        scene: name.to_string(),
        n: scene.grid.n,
        patches: p.patches.len(),
        shots: s.shots.len(),
        stop: s.stop,
        residual: s.residual,
        cycles: sum(&|x| x.cycles()),
        messages: sum(&|x| x.messages()),
        beams_processed: sum(&|x| x.cost.diffusion.beams_processed),
        diffusion_cycles_per_shot: sum(&|x| x.cost.diffusion.cycles) as f64 / k,
        reduce_cycles_per_shot: sum(&|x| x.cost.reduce_cycles) as f64 / k,
        messages_per_shot: sum(&|x| x.messages()) as f64 / k,
        bytes_per_cell_added: crate::machine::shooting::shots::bytes_per_cell_added(),
        bytes_per_light_cell: std::mem::size_of::<HostLightCell<U0>>(),
        zero_area_faces: p.summary.degenerate_faces,
        unmapped_voxels: s.unmapped_voxels,
        received_overflows: s.received_overflows,
        wall_seconds,
        reference,
        proxels: proxel_stats(settings, scene.grid.n, s),
    }
}

/// One row per patch: geometry, material, the machine's radiosity, and what is displayed with
/// the ambient term of §1.3.2.
fn write_patches(path: &std::path::Path, p: &Patches, s: &GridSolution) -> Result<()> {
    let mut w = create(path)?;
    writeln!(w, "patch,face,area,cx,cy,cz,nx,ny,nz,rho_r,rho_g,rho_b,e_r,e_g,e_b,b_r,b_g,b_b,shown_r,shown_g,shown_b,unshot_r,unshot_g,unshot_b")?;
    let a = ambient(&p.patches, &s.unshot);
    for (i, q) in p.patches.iter().enumerate() {
        let (b, u) = (s.radiosity[i], s.unshot[i]);
        let shown = [0, 1, 2].map(|c| b[c] + q.reflectance[c] * a[c]);
        let mut row = vec![i as f64, q.face as f64, q.area, q.centroid.x, q.centroid.y, q.centroid.z];
        row.extend([q.normal.x, q.normal.y, q.normal.z]);
        row.extend(q.reflectance.iter().chain(&q.emission).chain(&b).chain(&shown).chain(&u));
        writeln!(w, "{}", row.iter().map(|v| format!("{v}")).collect::<Vec<_>>().join(","))?;
    }
    eprintln!("  wrote {}", path.display());
    Ok(())
}

/// One row per shot: the shooter, the residual after it, the balance and the costs.
fn write_shots(path: &std::path::Path, shots: &[ShotLog]) -> Result<()> {
    let mut w = create(path)?;
    let proxels = shots.iter().any(|x| x.proxel.is_some());
    let mut extra = String::new();
    if proxels {
        extra.push_str(",select_cycles,projection_cycles,projection_messages,triangles,zone_tests,rect_tests,hits");
        for u in Update::ALL {
            let name = u.name().replace('-', "_");
            extra.push_str(&format!(",update_{name}_cycles,update_{name}_messages"));
        }
    }
    writeln!(
        w,
        "shot,patch,unshot_power,residual_after,emitted,received,lost,left,negative,own,\
         diffusion_cycles,diffusion_messages,broadcast_cycles,broadcast_messages,reduce_cycles,reduce_messages,\
         supervisor_ops,cycles,messages{extra}"
    )?;
    for (k, x) in shots.iter().enumerate() {
        let c = &x.cost;
        write!(
            w,
            "{k},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            x.patch,
            x.unshot_power,
            x.residual_after,
            x.emitted,
            x.received,
            x.lost,
            x.left,
            x.negative,
            x.own,
            c.diffusion.cycles,
            c.diffusion.messages,
            c.broadcast_cycles,
            c.broadcast_messages,
            c.reduce_cycles,
            c.reduce_messages,
            c.supervisor_ops,
            x.cycles(),
            x.messages()
        )?;
        if let Some(p) = &x.proxel {
            write!(
                w,
                ",{},{},{},{},{},{},{}",
                p.select_cycles,
                p.projection_cycles,
                p.projection_messages,
                p.triangles,
                p.zone_tests,
                p.rect_tests,
                p.hits
            )?;
            for u in &p.updates {
                write!(w, ",{},{}", u.cycles, u.messages)?;
            }
        }
        writeln!(w)?;
    }
    eprintln!("  wrote {}", path.display());
    Ok(())
}

/// Print the summary of a solution (and its comparison).
pub fn print_summary(s: &RadiosityStats) {
    eprintln!(
        "{}: n = {}, {} patches, {} shots ({:?}), residual {:.4}, {:.1} s",
        s.scene, s.n, s.patches, s.shots, s.stop, s.residual, s.wall_seconds
    );
    eprintln!(
        "  cycles {} (per shot: diffusion {:.0}, reduction {:.0}), messages {} ({:.0} per shot)",
        s.cycles, s.diffusion_cycles_per_shot, s.reduce_cycles_per_shot, s.messages, s.messages_per_shot
    );
    eprintln!(
        "  bytes per cell added {} (lighting cell {}), zero-area faces skipped {}, unmapped voxels {}, accumulator overflows {}",
        s.bytes_per_cell_added, s.bytes_per_light_cell, s.zero_area_faces, s.unmapped_voxels, s.received_overflows
    );
    if let Some(x) = &s.proxels {
        eprintln!(
            "  shots by {} (R = {}, {} bytes per cell): per shot select {:.0} + projection {:.0} cycles ({:.0} triangles broadcast, yield {:.4} of zone tests, {:.4} of rectangle tests)",
            x.shots_by.name(),
            x.resolution,
            x.bytes_per_cell,
            x.select_cycles_per_shot,
            x.projection_cycles_per_shot,
            x.triangles_per_shot,
            x.zone_yield,
            x.rect_yield
        );
        let ups: Vec<String> = x
            .updates
            .iter()
            .map(|u| {
                format!(
                    "{}{} {:.0}",
                    u.update,
                    if u.update == x.update.name() { " (counted)" } else { "" },
                    u.cycles_per_shot
                )
            })
            .collect();
        eprintln!("  update cycles per shot: {}", ups.join(", "));
    }
    if let Some(r) = &s.reference {
        eprintln!(
            "  reference ({} shots, {:.1} s, form factors {}): per-patch RMS relative error {:.4} (direct light only {:.4})",
            r.shots, r.wall_seconds, r.estimator, r.rms_relative_error, r.direct_only_rms_relative_error
        );
        if let Some(e) = r.self_error {
            eprintln!("  reference self-error (3×3 against 6×6 strata, reflected B − E): RMS relative {e:.4}");
        }
        if let Some(t) = &r.truth {
            eprintln!(
                "  against the converged truth (contour, {0}×{0} strata, residual {1}, {2} shots, {3:.1} s{6}; reflected B − E): reference {4:.4}, machine {5:.4}",
                t.strata,
                t.residual,
                t.shots,
                t.wall_seconds,
                t.reference_rms_relative_error,
                t.machine_rms_relative_error,
                if t.cached { ", read from --truth-cache" } else { "" }
            );
        }
    }
}
