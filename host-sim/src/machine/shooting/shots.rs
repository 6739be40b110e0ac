//! Progressive radiosity on the grid (radiosity thesis §1.3.2, §3.4, ch. 5): every shot is one
//! beam diffusion from the shooting patch, each beam carrying the energy of its rays
//! ([`cell_core::radiosity`]), collected per patch by the cells and reduced to the supervisor.
//!
//! One shot, in machine phases (docs/RADIOSITY.md):
//! 1. **broadcast** — the supervisor hands the shot (source position, patch normal) to cell
//!    (0, 0), which floods it over the grid: n − 1 cycles (Chebyshev distance), n² − 1 messages;
//! 2. **diffusion** — one diffusion from the patch's centre pushed `offset` voxels along its
//!    normal, initial beams restricted to the front hemisphere ([`front_rays`]), the thesis's
//!    lit rule; every absorbed beam adds its quanta ([`beam_quanta`]) to the [`cell_core::radiosity::Received`] slot of
//!    its voxel's patch ([`cell_core::radiosity::PatchRuns`], loaded once with the patches), every departed beam its
//!    quanta to the rays that left;
//! 3. **reduction** — sorted streams of (patch, quanta) merged westward along the rows, then
//!    northward along column 0, to the supervisor at (0, 0): one message per entry and link, an
//!    end marker per link; cycles from the exact timing of the pipelined merge ([`reduce_cost`]);
//! 4. **supervisor** — converts quanta to RGB power (the shooter's unshot radiosity, each
//!    receiver's reflectance: linear, so it commutes with the sums the cells made), updates the
//!    unshot powers and picks the next shooter: a scan of P patches (the costed global max).
//!
//! **Invariant (tested):** per shot, quanta received (lost ones included) + quanta that left the
//! grid = quanta emitted, exactly ([`ShotLog::balanced`]).

use std::sync::atomic::{AtomicI64, Ordering::Relaxed};
use std::sync::Mutex;

use anyhow::{bail, Result};
use cell_core::beam::{Beam, Direction, FarDistance, FracBits, Layer, Source, SourceCoord, SourceId};
use cell_core::light::RaySink;
use cell_core::lit::LitRule;
use cell_core::radiosity::{beam_quanta, corner_exact, front_rays, PatchId};
use cell_core::units::{Coord, Depth};

use crate::machine::grid::capacity::{CellPatchRuns, CellReceived, DEFAULT_DEXELS};
use crate::machine::grid::{Grid, LightGrid};
use crate::machine::lighting::diffuse::{diffuse_shot, DiffusionCounts, LightConfig};
use crate::machine::loading::loaded_scene::world_to_voxel;
use crate::precompute::Fit;
use crate::scene::patch_display::{by_face, locate};
use crate::scene::patches::Patch;

use super::proxels::{ProxelConfig, ProxelCost, ProxelGrid, ProxelShot};
use super::reduce::reduce_cost;

/// Default push of a shot's source off its patch, in voxels along the normal: beyond the
/// surface's own voxels (a facet's band is at most √3/2 voxel thick on each side), so that no
/// front-hemisphere ray starts inside them.
pub const DEFAULT_OFFSET: f64 = 2.0;

/// Settings of a radiosity run on the grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadiosityConfig {
    /// The diffusion of each shot (thesis's lit rule, no dead-direction skip: [`Self::new`]).
    pub light: LightConfig,
    /// Push of the source off the patch, voxels ([`DEFAULT_OFFSET`]).
    pub offset: f64,
    /// Stop once the unshot power is at most this fraction of the emitted power.
    pub stop_fraction: f64,
    /// Stop after this many shots at most.
    pub max_shots: usize,
    /// Shots in flight at once (≥ 1; 1: the one-shot-at-a-time supervisor), chosen by
    /// `choice` (the radiosity thesis's "several emissions at once", ch. 5).
    pub in_flight: usize,
    /// How the shooters of several shots in flight are chosen.
    pub choice: ShooterChoice,
}

/// How the supervisor chooses the shooters when several shots are in flight (radiosity thesis
/// ch. 5, the parallel versions it reviews). A shot's power is the shooter's unshot radiosity
/// when it is chosen; what the patch receives while its shot is in flight stays unshot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShooterChoice {
    /// A central table of unshot power (Feda's): whenever a shot lands, the patch with the
    /// most unshot power not in flight is shot next; `in_flight` shots are always under way.
    #[default]
    Table,
    /// Rounds (Thomin's): the `in_flight` patches with the most unshot power are shot
    /// together, and the next round is chosen once all of them have landed.
    Rounds,
}

impl ShooterChoice {
    /// Its `--shooter-choice` name.
    pub fn name(self) -> &'static str {
        match self {
            ShooterChoice::Table => "table",
            ShooterChoice::Rounds => "rounds",
        }
    }
}

impl RadiosityConfig {
    /// The lighting defaults made fit for shooting: the thesis's lit rule and rays (a shot's
    /// rays leave from its patch's voxel), the dead-direction skip off (a shot emits its own
    /// beams), the full lit store.
    pub fn new(light: LightConfig, stop_fraction: f64, max_shots: usize) -> Self {
        let light = LightConfig {
            rule: LitRule::Thesis,
            rays: cell_core::beam::Origin::SourceVoxel,
            skip_dead_directions: false,
            lit_visible_only: false,
            skip_hidden: false,
            faults: None,
            ..light
        };
        RadiosityConfig {
            light,
            offset: DEFAULT_OFFSET,
            stop_fraction,
            max_shots,
            in_flight: 1,
            choice: ShooterChoice::Table,
        }
    }
}

/// Every cell's voxel → patch map, and what did not fit.
pub struct PatchMap {
    /// Per cell, row-major.
    pub cells: Vec<CellPatchRuns>,
    /// Occupied voxels mapped to a patch.
    pub voxels: u64,
    /// Occupied voxels whose face has no patch (a face the subdivision skipped as degenerate).
    pub unmapped: u64,
    /// Runs that did not fit a cell's store (their voxels have no patch).
    pub overflows: u64,
}

/// Map every occupied voxel to the patch of its face that holds (or is nearest to holding) its
/// centre: the host's load of the patch runs (`source_face`: mesh face of each facet id).
pub fn map_patches<const D: usize>(
    grid: &Grid<D>,
    fit: &Fit,
    source_face: &[u32],
    patches: &[Patch],
) -> Result<PatchMap> {
    if patches.len() > PatchId::MAX as usize {
        bail!("radiosity: {} patches, a cell numbers at most {} (raise --patch-size)", patches.len(), PatchId::MAX);
    }
    let faces = source_face.iter().map(|&f| f as usize + 1).max().unwrap_or(0);
    let by_face = by_face(patches, faces);
    let mut map = PatchMap { cells: Vec::with_capacity(grid.cells.len()), voxels: 0, unmapped: 0, overflows: 0 };
    for (idx, cell) in grid.cells.iter().enumerate() {
        let (x, y) = ((idx as u32 % grid.n) as f64, (idx as u32 / grid.n) as f64);
        let mut runs = CellPatchRuns::new();
        for d in cell.store.dexels() {
            let face = source_face.get(d.facet as usize).map(|&f| f as usize);
            let cands = face.and_then(|f| by_face.get(f)).map(Vec::as_slice).unwrap_or(&[]);
            for z in d.span.lo..=d.span.hi {
                let w = crate::machine::loading::loaded_scene::voxel_to_world(fit, [x, y, z as f64]);
                let best = locate(patches, cands, parry3d_f64::math::Vector::new(w[0], w[1], w[2]));
                match best {
                    Some(p) => {
                        map.voxels += 1;
                        if !runs.push(z, p as PatchId) {
                            map.overflows += 1;
                        }
                    }
                    None => map.unmapped += 1,
                }
            }
        }
        map.cells.push(runs);
    }
    Ok(map)
}

/// The cells' side of a shot: what each column received, and the rays that left.
#[derive(Debug)]
struct ShotSink<'a, F: FracBits> {
    normal: [f32; 3],
    far: FarDistance<F>,
    n: u32,
    map: &'a [CellPatchRuns],
    received: Vec<Mutex<CellReceived>>,
    left: AtomicI64,
}

impl<F: FracBits> RaySink<F> for ShotSink<'_, F> {
    fn absorbed(&self, x: Coord, y: Coord, z: Depth, beam: &Beam<F>) {
        let q = beam_quanta(self.normal, beam, self.far);
        let i = y as usize * self.n as usize + x as usize;
        let patch = self.map[i].patch_at(z);
        self.received[i].lock().expect("one cell steps on one thread").add(patch, q);
    }

    fn left(&self, beam: &Beam<F>) {
        self.left.fetch_add(beam_quanta(self.normal, beam, self.far), Relaxed);
    }
}

/// The cost of one shot's phases.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ShotCost {
    /// The diffusion's counters (its cycles and messages).
    #[serde(flatten)]
    pub diffusion: DiffusionCounts,
    /// Broadcast of the shot: cycles, messages.
    pub broadcast_cycles: u64,
    /// Messages of the broadcast.
    pub broadcast_messages: u64,
    /// Reduction to the supervisor: cycles until its end marker arrives.
    pub reduce_cycles: u64,
    /// Messages of the reduction (entries and end markers).
    pub reduce_messages: u64,
    /// Supervisor operations: the global max (one comparison per patch) and the updates (one
    /// per entry it received).
    pub supervisor_ops: u64,
}

impl ShotCost {
    /// Grid cycles of the shot: broadcast + diffusion + reduction.
    pub fn cycles(&self) -> u64 {
        self.broadcast_cycles + self.diffusion.cycles + self.reduce_cycles
    }

    /// Messages on the grid's links: broadcast + diffusion + reduction.
    pub fn messages(&self) -> u64 {
        self.broadcast_messages + self.diffusion.messages + self.reduce_messages
    }
}

/// One shot of the machine.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ShotLog {
    /// The shooting patch.
    pub patch: usize,
    /// Its unshot power before the shot (channels summed).
    pub unshot_power: f64,
    /// Unshot over emitted power after the shot.
    pub residual_after: f64,
    /// Quanta of the initial beams.
    pub emitted: i64,
    /// Quanta the cells received for a patch.
    pub received: i64,
    /// Quanta received for no patch (a full accumulator, an unmapped voxel).
    pub lost: i64,
    /// Quanta of the rays that left the grid.
    pub left: i64,
    /// Quanta of patches' entries below zero (f32 rounding at the horizon), taken as 0.
    pub negative: i64,
    /// Quanta the shooter sent to itself (ignored, as in the reference).
    pub own: i64,
    /// The source was outside the grid: nothing was diffused, the whole shot left.
    pub outside: bool,
    /// Accumulator additions that found no slot or no patch (their quanta are `lost`).
    pub overflows: u64,
    /// Its cost.
    #[serde(flatten)]
    pub cost: ShotCost,
    /// A proxel shot's cost ([`super::proxels`]; `None` for a beam shot).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub proxel: Option<ProxelCost>,
}

impl ShotLog {
    /// Grid cycles of the shot, whichever way it was shot.
    pub fn cycles(&self) -> u64 {
        self.cost.cycles() + self.proxel.as_ref().map_or(0, |p| p.cycles())
    }

    /// Messages of the shot, whichever way it was shot.
    pub fn messages(&self) -> u64 {
        self.cost.messages() + self.proxel.as_ref().map_or(0, |p| p.messages())
    }

    /// Received + lost + left = emitted, exactly.
    pub fn balanced(&self) -> bool {
        self.received + self.lost + self.left == self.emitted
    }
}

/// What one shot delivered: per patch (id, quanta), the emitted quanta, and its log.
pub struct Shot {
    /// (patch, quanta) after the reduction, by patch id.
    pub totals: Vec<(PatchId, i64)>,
    /// Its log.
    pub log: ShotLog,
    /// Its source (voxel units); `None` when the pushed centre was outside the grid.
    pub source: Option<Source>,
}

/// The source of patch `p`'s shot, in voxel units on the 1/16 lattice, and its unit normal;
/// `None` when the pushed centre is outside the grid.
fn shot_source(p: &Patch, fit: &Fit, n: u32, offset: f64) -> (Option<Source>, [f32; 3]) {
    let c = world_to_voxel(fit, [p.centroid.x, p.centroid.y, p.centroid.z]);
    let nv = [p.normal.x, p.normal.y, p.normal.z];
    let pos = [0, 1, 2].map(|k| c[k] + offset * nv[k]);
    let normal = nv.map(|c| c as f32);
    let inside = pos.iter().all(|&c| c.is_finite() && c >= 0.0 && c <= n as f64 - 1.0);
    (inside.then(|| Source::new(SourceId(0), pos.map(SourceCoord::from_num))), normal)
}

/// Shoot patch `i` on the grid (f: `cfg.light.frac_bits`).
pub fn shoot(
    grid: &LightGrid,
    fit: &Fit,
    map: &PatchMap,
    patches: &[Patch],
    i: usize,
    cfg: &RadiosityConfig,
) -> Result<Shot> {
    crate::machine::lighting::diffuse::with_f!(cfg.light.frac_bits, F => shoot_f::<F>(grid, fit, map, patches, i, cfg))
}

/// [`shoot`] under f = `F`.
fn shoot_f<F: FracBits>(
    grid: &LightGrid,
    fit: &Fit,
    map: &PatchMap,
    patches: &[Patch],
    i: usize,
    cfg: &RadiosityConfig,
) -> Result<Shot> {
    let n = grid.n;
    let far = FarDistance::<F>::new(n - 1).ok_or_else(|| {
        anyhow::anyhow!("far distance {} exceeds the beam budget for {} fraction bits", n - 1, F::U32)
    })?;
    if !corner_exact(far.get(), F::U32) {
        bail!(
            "radiosity: corners of D = {} with {} fraction bits are not exact in f32 (2^(f+1)·D ≥ 2^24)",
            n - 1,
            F::U32
        );
    }
    let (source, normal) = shot_source(&patches[i], fit, n, cfg.offset);
    let initial: Vec<Beam<F>> = Direction::ALL
        .iter()
        .filter_map(|&d| front_rays(normal, d, far).map(|(u, v)| (d, u, v)))
        .filter_map(|(d, u, v)| Beam::new(SourceId(0), d, Layer(0), u, v, far).ok())
        .collect();
    let emitted: i64 = initial.iter().map(|b| beam_quanta(normal, b, far)).sum();
    let mut log = ShotLog { patch: i, emitted, ..Default::default() };
    log.cost.broadcast_cycles = n as u64 - 1;
    log.cost.broadcast_messages = (n as u64).pow(2) - 1;
    let Some(source) = source else {
        log.outside = true;
        log.left = emitted;
        return Ok(Shot { totals: Vec::new(), log, source: None });
    };
    let sink = ShotSink {
        normal,
        far,
        n,
        map: &map.cells,
        received: (0..grid.cells.len()).map(|_| Mutex::new(CellReceived::new())).collect(),
        left: AtomicI64::new(0),
    };
    let lighting = diffuse_shot::<F, DEFAULT_DEXELS>(grid, &source, &initial, &cfg.light, &sink, |_, _| {})?;
    log.cost.diffusion = lighting.reports[0].counts.clone();
    log.left = sink.left.load(Relaxed);
    let received: Vec<CellReceived> =
        sink.received.into_iter().map(|m| m.into_inner().expect("not poisoned")).collect();
    log.lost = received.iter().map(|r| r.lost()).sum();
    log.overflows = received.iter().map(|r| r.overflows() as u64).sum();
    let (totals, cycles, messages) = reduce_cost(n, &received);
    log.received = totals.iter().map(|e| e.1).sum();
    log.cost.reduce_cycles = cycles;
    log.cost.reduce_messages = messages;
    if !log.balanced() {
        bail!(
            "radiosity: shot of patch {i} not balanced: received {} + lost {} + left {} ≠ emitted {}",
            log.received,
            log.lost,
            log.left,
            log.emitted
        );
    }
    Ok(Shot { totals, log, source: Some(source) })
}

/// Why the machine stopped shooting.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum GridStop {
    /// The residual reached the stop fraction.
    Converged,
    /// The shot budget was spent first.
    ShotBudget,
}

/// The machine's progressive solution.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GridSolution {
    /// Radiosity per patch (RGB).
    pub radiosity: Vec<[f64; 3]>,
    /// Unshot radiosity per patch (RGB).
    pub unshot: Vec<[f64; 3]>,
    /// Indirect irradiance per patch (RGB): what the shots of reflected power brought it, the
    /// emitters' first shots of their own emission left out (the direct light).
    pub indirect: Vec<[f64; 3]>,
    /// Every shot.
    pub shots: Vec<ShotLog>,
    /// Why it stopped.
    pub stop: GridStop,
    /// Emitted power (channels summed).
    pub emitted_power: f64,
    /// Unshot over emitted power at the end.
    pub residual: f64,
    /// Runs that did not fit the cells' patch maps, voxels with no patch.
    pub map_overflows: u64,
    /// Occupied voxels whose face has no patch.
    pub unmapped_voxels: u64,
    /// Accumulator additions that found no slot or no patch, over all shots.
    pub received_overflows: u64,
}

/// Power of an RGB radiosity on an area, channels summed.
fn power(v: [f64; 3], area: f64) -> f64 {
    (v[0] + v[1] + v[2]) * area
}

/// The supervisor's global max: the patch with the largest unshot power (lowest index among
/// equals).
fn select(patches: &[Patch], unshot: &[[f64; 3]]) -> usize {
    let mut best = (0, f64::NEG_INFINITY);
    for (i, (p, u)) in patches.iter().zip(unshot).enumerate() {
        let w = power(*u, p.area);
        if w > best.1 {
            best = (i, w);
        }
    }
    best.0
}

/// Check the patches before shooting: positive finite areas, some emission. Returns the
/// emitted power.
fn check_patches(patches: &[Patch]) -> Result<f64> {
    if let Some((i, p)) = patches.iter().enumerate().find(|(_, p)| !(p.area.is_finite() && p.area > 0.0)) {
        bail!("radiosity: patch {i} (face {}) has zero or invalid area {}", p.face, p.area);
    }
    let emitted: f64 = patches.iter().map(|p| power(p.emission, p.area)).sum();
    if emitted.is_nan() || emitted <= 0.0 {
        bail!(
            "radiosity: nothing emits: no patch has a material with Ke > 0 ({} patches); the machine's radiosity needs an emitting surface",
            patches.len()
        );
    }
    Ok(emitted)
}

/// One shot read as form factors (the grid's `F_ij`, radiosity thesis §1.3.2): the quanta each
/// patch received from patch `i`'s shot over the quanta it emitted (its own and negative
/// entries as 0), and the shot's source (voxel units: its rays leave from the source voxel's
/// centre plane along each face's axis, from its position across). Fails when the source lies
/// outside the grid.
pub fn shot_form_factors(
    grid: &LightGrid,
    fit: &Fit,
    source_face: &[u32],
    patches: &[Patch],
    i: usize,
    cfg: &RadiosityConfig,
) -> Result<(Vec<f64>, Source)> {
    let map = map_patches(grid, fit, source_face, patches)?;
    let shot = shoot(grid, fit, &map, patches, i, cfg)?;
    let Some(source) = shot.source else {
        bail!("radiosity: the shot of patch {i} starts outside the grid");
    };
    let emitted = shot.log.emitted.max(1) as f64;
    let mut ff = vec![0.0; patches.len()];
    for &(j, q) in shot.totals.iter().filter(|&&(j, q)| j as usize != i && q > 0) {
        ff[j as usize] += q as f64 / emitted;
    }
    Ok((ff, source))
}

/// Bytes a cell adds for radiosity: its patch runs, its accumulator and its patch's radiosity.
pub const fn bytes_per_cell_added() -> usize {
    std::mem::size_of::<CellPatchRuns>() + std::mem::size_of::<CellReceived>() + std::mem::size_of::<[f32; 3]>()
}

/// Progressive refinement on the grid: shoot the patch with the most unshot power until the
/// residual is at most `cfg.stop_fraction` or `cfg.max_shots` shots are made.
/// `progress(shots, residual)` after each shot.
pub fn solve(
    grid: &LightGrid,
    fit: &Fit,
    source_face: &[u32],
    patches: &[Patch],
    cfg: &RadiosityConfig,
    mut progress: impl FnMut(usize, f64),
) -> Result<GridSolution> {
    solve_farmed(grid, fit, source_face, patches, cfg, None, &mut progress)
}

/// [`solve`], the shots in flight computed by `farm` (`None`: here, each when it lands).
pub fn solve_farmed(
    grid: &LightGrid,
    fit: &Fit,
    source_face: &[u32],
    patches: &[Patch],
    cfg: &RadiosityConfig,
    farm: Option<&mut dyn ShotFarm>,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<GridSolution> {
    check_settings(patches, cfg)?;
    let map = map_patches(grid, fit, source_face, patches)?;
    if map.overflows > 0 {
        bail!(
            "radiosity: {} voxel runs of patches do not fit the cells' patch maps ({} runs per column \
             compiled): raise --patch-size",
            map.overflows,
            crate::machine::grid::capacity::PATCH_RUNS_CAP
        );
    }
    let mut s = progressive(patches, cfg, &mut |i| shoot(grid, fit, &map, patches, i, cfg), farm, progress)?;
    s.map_overflows = map.overflows;
    s.unmapped_voxels = map.unmapped;
    Ok(s)
}

/// Progressive refinement with shots by projection ([`super::proxels`]) on an n × n grid: the
/// same supervisor arithmetic and stopping rule as [`solve`], each shot's form factors from the
/// cells' depth buffer of the shooter's surface.
pub fn solve_by_proxels(
    n: u32,
    patches: &[Patch],
    cfg: &RadiosityConfig,
    proxels: ProxelConfig,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<GridSolution> {
    check_settings(patches, cfg)?;
    let mut grid = ProxelGrid::new(n, patches, proxels)?;
    progressive(patches, cfg, &mut |i| grid.shoot(patches, i).map(|shot| proxel_shot(i, shot)), None, progress)
}

/// A proxel shot of patch `i` as the supervisor logs it: what its front-facing patches
/// received, what triangles seen from behind hid (`lost`), what saw nothing (`left`).
fn proxel_shot(i: usize, shot: ProxelShot) -> Shot {
    let ProxelShot { totals, emitted, received, hidden, left, cost } = shot;
    let log = ShotLog { patch: i, emitted, received, lost: hidden, left, proxel: Some(cost), ..Default::default() };
    Shot { totals, log, source: None }
}

/// Check the patches and the stopping rule.
fn check_settings(patches: &[Patch], cfg: &RadiosityConfig) -> Result<()> {
    check_patches(patches)?;
    if !(cfg.stop_fraction >= 0.0 && cfg.stop_fraction < 1.0) {
        bail!("radiosity: the residual must be in [0, 1), got {}", cfg.stop_fraction);
    }
    if !(cfg.offset.is_finite() && cfg.offset >= 0.0) {
        bail!("radiosity: the source offset must be a finite number of voxels ≥ 0, got {}", cfg.offset);
    }
    if cfg.in_flight == 0 {
        bail!("radiosity: --in-flight 0: at least one shot must be in flight");
    }
    Ok(())
}

/// The supervisor's loop: shoot the patch with the most unshot power (`shoot(i)`) until the
/// residual or the shot budget of `cfg` is reached.
fn progressive(
    patches: &[Patch],
    cfg: &RadiosityConfig,
    shoot: &mut dyn FnMut(usize) -> Result<Shot>,
    farm: Option<&mut dyn ShotFarm>,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<GridSolution> {
    let emitted_power = check_patches(patches)?;
    let mut s = GridSolution {
        radiosity: patches.iter().map(|p| p.emission).collect(),
        unshot: patches.iter().map(|p| p.emission).collect(),
        indirect: vec![[0.0; 3]; patches.len()],
        shots: Vec::new(),
        stop: GridStop::ShotBudget,
        emitted_power,
        residual: 1.0,
        map_overflows: 0,
        unmapped_voxels: 0,
        received_overflows: 0,
    };
    if cfg.in_flight > 1 {
        return in_flight(patches, cfg, s, shoot, farm, progress);
    }
    while s.residual > cfg.stop_fraction {
        if s.shots.len() >= cfg.max_shots {
            return Ok(s);
        }
        let i = select(patches, &s.unshot);
        let shot = shoot(i)?;
        let u = s.unshot[i];
        apply(patches, &mut s, i, shot, u);
        progress(s.shots.len(), s.residual);
    }
    s.stop = GridStop::Converged;
    Ok(s)
}

/// The `k` patches with the most unshot power, not in `busy`, that have some (largest first,
/// the lowest index among equals: [`select`]'s order).
fn select_top(patches: &[Patch], unshot: &[[f64; 3]], busy: &[usize], k: usize) -> Vec<usize> {
    let mut by_power: Vec<(usize, f64)> = patches
        .iter()
        .zip(unshot)
        .enumerate()
        .map(|(i, (p, u))| (i, power(*u, p.area)))
        .filter(|&(i, w)| w > 0.0 && !busy.contains(&i))
        .collect();
    by_power.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    by_power.into_iter().take(k).map(|(i, _)| i).collect()
}

/// The supervisor with `cfg.in_flight` shots under way ([`ShooterChoice`]): each shot carries
/// the unshot radiosity its shooter had when chosen, and lands (is applied) in the order the
/// shots started. A shot's form factors do not depend on the powers, so the shots are computed
/// when they land. Once the residual is reached the shots under way still land; no new one
/// starts. The budget counts shots started. With a `farm`, the shots under way that are not
/// computed yet are computed together (spread over processes) when the first of them lands.
fn in_flight(
    patches: &[Patch],
    cfg: &RadiosityConfig,
    mut s: GridSolution,
    shoot: &mut dyn FnMut(usize) -> Result<Shot>,
    mut farm: Option<&mut dyn ShotFarm>,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<GridSolution> {
    let k = cfg.in_flight;
    // (shooter, its unshot radiosity when chosen, its shot once computed), in start order.
    let mut under_way: std::collections::VecDeque<(usize, [f64; 3], Option<Shot>)> = Default::default();
    let mut started = 0;
    loop {
        let open = s.residual > cfg.stop_fraction && started < cfg.max_shots;
        let start = match cfg.choice {
            ShooterChoice::Table => open && under_way.len() < k,
            ShooterChoice::Rounds => open && under_way.is_empty(),
        };
        if start {
            let busy: Vec<usize> = under_way.iter().map(|w| w.0).collect();
            let room = match cfg.choice {
                ShooterChoice::Table => k - under_way.len(),
                ShooterChoice::Rounds => k,
            };
            let picks = select_top(patches, &s.unshot, &busy, room.min(cfg.max_shots - started));
            started += picks.len();
            under_way.extend(picks.into_iter().map(|i| (i, s.unshot[i], None)));
        }
        if let Some(f) = farm.as_deref_mut().filter(|_| under_way.front().is_some_and(|w| w.2.is_none())) {
            let pending: Vec<usize> = under_way.iter().filter(|w| w.2.is_none()).map(|w| w.0).collect();
            let mut shots = f.shoot_all(&pending, shoot)?.into_iter();
            for w in under_way.iter_mut().filter(|w| w.2.is_none()) {
                w.2 = Some(shots.next().ok_or_else(|| anyhow::anyhow!("radiosity: a farm returned too few shots"))?);
            }
        }
        let Some((i, u, ready)) = under_way.pop_front() else { break };
        let shot = match ready {
            Some(shot) => shot,
            None => shoot(i)?,
        };
        apply(patches, &mut s, i, shot, u);
        progress(s.shots.len(), s.residual);
    }
    if s.residual <= cfg.stop_fraction {
        s.stop = GridStop::Converged;
    }
    Ok(s)
}

/// Where the shots in flight are computed when a run spreads them (the radiosity thesis's
/// "several emissions at once" on several processors, ch. 5): the MPI ranks' farm in
/// `crate::dist`, or [`Here`]. A shot depends on its shooter alone (not on the powers), so when
/// and where it is computed changes nothing.
pub trait ShotFarm {
    /// The shots of the shooters `picks`, in their order; `shoot` computes one in this process.
    fn shoot_all(&mut self, picks: &[usize], shoot: &mut dyn FnMut(usize) -> Result<Shot>) -> Result<Vec<Shot>>;
}

/// Every shot in this process, one after another (what a farm of one is).
pub struct Here;

impl ShotFarm for Here {
    fn shoot_all(&mut self, picks: &[usize], shoot: &mut dyn FnMut(usize) -> Result<Shot>) -> Result<Vec<Shot>> {
        picks.iter().map(|&i| shoot(i)).collect()
    }
}

/// A beam shot as bytes for another process ([`shot_from_bytes`]): its reduced totals and its
/// log (its source, which the supervisor does not read, is not carried). Proxel shots are not
/// carried.
pub fn shot_to_bytes(shot: &Shot) -> Result<Vec<u8>> {
    let l = &shot.log;
    if l.proxel.is_some() {
        bail!("radiosity: a proxel shot is not carried between processes");
    }
    let mut b = Vec::new();
    b.extend((shot.totals.len() as u64).to_le_bytes());
    for &(j, q) in &shot.totals {
        b.extend(j.to_le_bytes());
        b.extend(q.to_le_bytes());
    }
    b.extend((l.patch as u64).to_le_bytes());
    b.extend(l.unshot_power.to_bits().to_le_bytes());
    b.extend(l.residual_after.to_bits().to_le_bytes());
    for v in [l.emitted, l.received, l.lost, l.left, l.negative, l.own] {
        b.extend(v.to_le_bytes());
    }
    b.push(u8::from(l.outside));
    let c = &l.cost;
    for v in
        [l.overflows, c.broadcast_cycles, c.broadcast_messages, c.reduce_cycles, c.reduce_messages, c.supervisor_ops]
    {
        b.extend(v.to_le_bytes());
    }
    b.extend(crate::machine::lighting::diffuse::counts_to_bytes(&c.diffusion));
    Ok(b)
}

/// A reader of a carried shot's bytes.
struct ShotReader<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> ShotReader<'a> {
    fn take(&mut self, k: usize) -> Result<&'a [u8]> {
        let s = self.b.get(self.at..self.at + k);
        let s = s.ok_or_else(|| anyhow::anyhow!("radiosity: a carried shot is truncated at byte {}", self.at))?;
        self.at += k;
        Ok(s)
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into()?))
    }
}

/// The shot [`shot_to_bytes`] wrote (its source `None`), and the bytes after it.
pub fn shot_from_bytes(b: &[u8]) -> Result<(Shot, &[u8])> {
    let mut r = ShotReader { b, at: 0 };
    let count = r.u64()? as usize;
    if count > b.len() / 10 {
        bail!("radiosity: a carried shot announces {count} totals");
    }
    let mut totals = Vec::with_capacity(count);
    for _ in 0..count {
        let j = PatchId::from_le_bytes(r.take(2)?.try_into()?);
        totals.push((j, r.u64()? as i64));
    }
    let patch = r.u64()? as usize;
    let (unshot_power, residual_after) = (f64::from_bits(r.u64()?), f64::from_bits(r.u64()?));
    let [emitted, received, lost, left, negative, own] =
        [r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?].map(|v| v as i64);
    let outside = match r.take(1)?[0] {
        0 => false,
        1 => true,
        k => bail!("radiosity: a carried shot's outside flag is {k}"),
    };
    let [overflows, broadcast_cycles, broadcast_messages, reduce_cycles, reduce_messages, supervisor_ops] =
        [r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?];
    let (diffusion, rest) = crate::machine::lighting::diffuse::counts_from_bytes(&b[r.at..])?;
    let cost =
        ShotCost { diffusion, broadcast_cycles, broadcast_messages, reduce_cycles, reduce_messages, supervisor_ops };
    let log = ShotLog {
        patch,
        unshot_power,
        residual_after,
        emitted,
        received,
        lost,
        left,
        negative,
        own,
        outside,
        overflows,
        cost,
        proxel: None,
    };
    Ok((Shot { totals, log, source: None }, rest))
}

/// The supervisor's update after patch i's shot of unshot radiosity `u`: receiver j gets
/// `ΔH_j = U_i F_ij A_i / A_j` with `F_ij` = its quanta over the quanta emitted, adds `ρ_j ΔH_j`
/// to its radiosity and its unshot radiosity; `U_i` loses `u` (all of it, 0, when `u` is its
/// current unshot radiosity; with shots in flight, what it received since it was chosen stays).
/// Until its first shot the unshot radiosity of i holds its emission `E_i` (it only grows from
/// `E_i`); what `U_i − E_i` brings j on that shot, and all of `U_i` on later ones, is indirect
/// irradiance.
fn apply(patches: &[Patch], s: &mut GridSolution, i: usize, shot: Shot, u: [f64; 3]) {
    let Shot { totals, mut log, .. } = shot;
    let first = s.shots.iter().all(|x| x.patch != i);
    let reflected: [f64; 3] =
        std::array::from_fn(|c| if first { (u[c] - patches[i].emission[c]).max(0.0) } else { u[c] });
    log.unshot_power = power(u, patches[i].area);
    let emitted = log.emitted.max(1) as f64;
    for &(j, q) in &totals {
        let j = j as usize;
        if j == i {
            log.own += q;
            continue;
        }
        if q < 0 {
            log.negative += -q;
            continue;
        }
        let t = q as f64 / emitted * patches[i].area / patches[j].area;
        for (c, (uc, rho)) in u.iter().zip(patches[j].reflectance).enumerate() {
            let dh = uc * t * rho;
            s.radiosity[j][c] += dh;
            s.unshot[j][c] += dh;
            s.indirect[j][c] += reflected[c] * t;
        }
    }
    for (c, uc) in u.iter().enumerate() {
        s.unshot[i][c] -= uc;
    }
    let unshot: f64 = patches.iter().zip(&s.unshot).map(|(p, u)| power(*u, p.area)).sum();
    s.residual = unshot / s.emitted_power;
    log.residual_after = s.residual;
    // A proxel shot's cells select and update their own patches (its cost has them).
    log.cost.supervisor_ops = if log.proxel.is_some() { 0 } else { patches.len() as u64 + totals.len() as u64 };
    s.received_overflows += log.overflows;
    s.shots.push(log);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::patches::Patch;
    use parry3d_f64::math::Vector;

    /// Four patches, patch 0 the emitter, and the share of a shot's quanta each other patch
    /// receives (rows sum below 1: some leaves).
    const AREAS: [f64; 4] = [1.0, 2.0, 1.5, 3.0];
    const RHO: [f64; 4] = [0.5, 0.8, 0.6, 0.7];
    const F: [[f64; 4]; 4] =
        [[0.0, 0.3, 0.2, 0.4], [0.15, 0.0, 0.25, 0.3], [0.1, 0.3, 0.0, 0.4], [0.12, 0.2, 0.2, 0.0]];
    const QUANTA: i64 = 1_000_000_000;

    fn patches() -> Vec<Patch> {
        (0..4)
            .map(|i| Patch {
                polygon: Vec::new(),
                triangles: Vec::new(),
                area: AREAS[i],
                normal: Vector::new(0.0, 0.0, 1.0),
                centroid: Vector::new(i as f64, 0.0, 0.0),
                reflectance: [RHO[i]; 3],
                emission: if i == 0 { [1.0, 0.5, 0.25] } else { [0.0; 3] },
                face: i,
                piece: i,
            })
            .collect()
    }

    fn shot(i: usize) -> Result<Shot> {
        let totals = (0..4).filter(|&j| j != i).map(|j| (j as PatchId, (F[i][j] * QUANTA as f64) as i64)).collect();
        Ok(Shot { totals, log: ShotLog { patch: i, emitted: QUANTA, ..Default::default() }, source: None })
    }

    /// The solution the shots converge to, by Jacobi iteration of
    /// `B_j = E_j + ρ_j Σ_i B_i F_ij A_i / A_j` (the quanta rounded as the shots round them).
    fn fixed_point() -> Vec<[f64; 3]> {
        let p = patches();
        let f = |i: usize, j: usize| (F[i][j] * QUANTA as f64) as i64 as f64 / QUANTA as f64;
        let mut b: Vec<[f64; 3]> = p.iter().map(|q| q.emission).collect();
        for _ in 0..2000 {
            b = (0..4)
                .map(|j| {
                    std::array::from_fn(|c| {
                        let gathered: f64 =
                            (0..4).filter(|&i| i != j).map(|i| b[i][c] * f(i, j) * AREAS[i] / AREAS[j]).sum();
                        p[j].emission[c] + RHO[j] * gathered
                    })
                })
                .collect();
        }
        b
    }

    /// One shot at a time, Feda's table and Thomin's rounds with 3 shots under way converge to
    /// the same radiosity (the linear system's, by an independent iteration), and the residual
    /// never grows; a round shoots distinct patches.
    #[test]
    fn shots_in_flight_converge_to_the_same_radiosity() {
        let want = fixed_point();
        let p = patches();
        for (k, choice) in [(1, ShooterChoice::Table), (3, ShooterChoice::Table), (3, ShooterChoice::Rounds)] {
            let cfg = RadiosityConfig {
                in_flight: k,
                choice,
                ..RadiosityConfig::new(crate::config::plane_rule(), 1e-12, 10_000)
            };
            let mut residuals = Vec::new();
            let s = progressive(&p, &cfg, &mut shot, None, &mut |_, r| residuals.push(r)).unwrap();
            assert_eq!(s.stop, GridStop::Converged, "{k} {choice:?}");
            assert!(residuals.windows(2).all(|w| w[1] <= w[0]), "{k} {choice:?}: the residual grew");
            for (j, (got, w)) in s.radiosity.iter().zip(&want).enumerate() {
                for c in 0..3 {
                    assert!(
                        (got[c] - w[c]).abs() <= 1e-9 * w[c].max(1e-3),
                        "{k} {choice:?} patch {j}: {got:?} vs {w:?}"
                    );
                }
            }
            if choice == ShooterChoice::Rounds {
                // The first round is the emitter alone (no other patch has power yet); the second,
                // the three patches it lit, each once.
                let order: Vec<usize> = s.shots.iter().map(|x| x.patch).collect();
                let mut second = order[1..4].to_vec();
                second.sort();
                assert_eq!((order[0], second), (0, vec![1, 2, 3]), "{order:?}");
            }
        }
    }

    /// With 3 under way from a table, the first shots are the emitter (alone with power), then
    /// the three patches it lit, largest unshot power first, before the emitter shoots again.
    #[test]
    fn the_table_keeps_the_largest_shooters_under_way() {
        let p = patches();
        let cfg = RadiosityConfig { in_flight: 3, ..RadiosityConfig::new(crate::config::plane_rule(), 0.0, 4) };
        let s = progressive(&p, &cfg, &mut shot, None, &mut |_, _| {}).unwrap();
        let order: Vec<usize> = s.shots.iter().map(|x| x.patch).collect();
        // After the emitter's shot patch j holds ρ_j F_0j A_0 / A_j, power ρ_j F_0j A_0.
        let mut lit: Vec<usize> = vec![1, 2, 3];
        lit.sort_by(|&a, &b| (RHO[b] * F[0][b]).total_cmp(&(RHO[a] * F[0][a])));
        assert_eq!(order, [vec![0], lit].concat());
        assert_eq!(s.stop, GridStop::ShotBudget);
    }

    /// A farm that computes the shots it is handed here, each carried through its bytes, and
    /// records how many it was handed at once.
    struct Carried(Vec<usize>);

    impl ShotFarm for Carried {
        fn shoot_all(&mut self, picks: &[usize], shoot: &mut dyn FnMut(usize) -> Result<Shot>) -> Result<Vec<Shot>> {
            self.0.push(picks.len());
            let shots = Here.shoot_all(picks, shoot)?;
            shots
                .iter()
                .map(|s| {
                    let bytes = shot_to_bytes(s)?;
                    let (back, rest) = shot_from_bytes(&bytes)?;
                    assert!(rest.is_empty());
                    Ok(back)
                })
                .collect()
        }
    }

    /// Shots computed ahead, together, by a farm (and carried as bytes) give the supervisor
    /// exactly what it gets shooting each when it lands: the same radiosity, bit for bit, and
    /// the same shot logs; the farm is handed the shots under way several at a time.
    #[test]
    fn a_farm_changes_no_shot() {
        let p = patches();
        for choice in [ShooterChoice::Table, ShooterChoice::Rounds] {
            let cfg = RadiosityConfig {
                in_flight: 3,
                choice,
                ..RadiosityConfig::new(crate::config::plane_rule(), 1e-6, 500)
            };
            let alone = progressive(&p, &cfg, &mut shot, None, &mut |_, _| {}).unwrap();
            let mut farm = Carried(Vec::new());
            let farmed = progressive(&p, &cfg, &mut shot, Some(&mut farm), &mut |_, _| {}).unwrap();
            assert_eq!(farmed.radiosity, alone.radiosity, "{choice:?}");
            assert_eq!(farmed.unshot, alone.unshot, "{choice:?}");
            assert_eq!(farmed.shots, alone.shots, "{choice:?}");
            assert!(farm.0.contains(&3), "{choice:?}: batches {:?}", farm.0);
            assert_eq!(farm.0.iter().sum::<usize>(), alone.shots.len(), "{choice:?}: every shot computed once");
        }
        // Bytes that are not a shot are refused.
        let bytes = shot_to_bytes(&shot(1).unwrap()).unwrap();
        for cut in [0, 7, bytes.len() / 2, bytes.len() - 1] {
            assert!(shot_from_bytes(&bytes[..cut]).is_err(), "cut at {cut}");
        }
    }
}
