//! The lighting phase on the whole grid (thesis ch. 4): sources diffused one after another by
//! beam subdivision, cycle by cycle.
//!
//! Cycle model (docs/ARCHITECTURE.md; thesis §4.4): in each cycle
//! 1. the source emitter hands the next of the source's six initial beams (x and y first, then
//!    z, §4.4.3) to the source cell if its FIFO has room;
//! 2. **compute**: every cell with a beam runs [`LightCell::step`] — at most one beam each;
//! 3. **links**: every non-empty output buffer moves its front message to the neighbour's FIFO
//!    if that FIFO has room (credit-based flow control; one message per link and direction per
//!    cycle). Senders are served in row-major order, so a FIFO that several neighbours feed in
//!    the same cycle fills deterministically.
//!
//! A message produced in cycle t is processed in cycle t + 1 at the earliest: one hop per cycle.
//! These are rc2's timing rules; [`LightConfig::timing`] ([`Timing`]) changes the open ones
//! (messages per link and cycle, an input register beside the FIFO, free output ports, the
//! emission order and rate) without changing any lit voxel.
//! `T` (cycles) counts cycles until the last beam is consumed, which the global activity
//! counter ([`Activity`]) detects exactly. Only cells holding beams are visited. A cycle in
//! which beams exist but nothing moves is a deadlock: reported as an error, never a hang.

use anyhow::{bail, Result};
use cell_core::beam::{Beam, Direction, FarDistance, FracBits, Origin, Source, SourceId, SplitOrder};
use cell_core::light::RaySink;
use cell_core::light::{
    Activity, ActivityDelta, BeamMsg, FrustumSummary, LightCell, LightCounters, LightEnv, OccupiedBox, Policy, Port,
    SourceMask, Step, SubBeamBounds,
};
use cell_core::lit::LitRule;
use cell_core::occluder::ColumnOccluders;
use cell_core::occupancy::{BlockRow, FrustumTest, Occupancy16, Occupancy32, Occupancy8, OccupancySummary};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicU8, Ordering::Relaxed};

use cell_core::link::PerfectLink;

use crate::machine::capacity::{HostLightCell, FA_CAP};
use crate::machine::faults::{fault_counts, FaultCounts, FaultInjector, FaultTally, LinkFaults, Wire};
use crate::machine::grid::Grid;
use crate::machine::links::{self, lossless, sure, CellInbox, GridLinks, HostLink, Took, BACK};
use crate::machine::occluders::{SourceOccluders, CONTACT_EXCHANGE_CYCLES};
use crate::machine::tap::{Tap, Tracer};
use crate::machine::tiles::{merge_sorted, prefetch, prefetch_ends, tiles};
use crate::machine::timing::Timing;

/// Default of [`LightConfig::stall_cycles`]: a fault-free machine that cannot move for one
/// cycle is deadlocked; under link faults a few cycles of bad luck are normal.
pub const DEFAULT_STALL_CYCLES: u64 = 64;

/// Lighting-phase settings. No default: a run starts from a named preset
/// ([`crate::config::Preset`]: what each job runs) or says what it tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightConfig {
    /// FIFO limit (1 ..= FA_CAP).
    pub fa: usize,
    /// Scheduling policy.
    pub policy: Policy,
    /// Merge arriving beams into waiting beams of the same voxel (exact).
    pub merge: bool,
    /// Record every voxel where a beam was processed (coverage checks; n³ bits).
    pub record_visits: bool,
    /// Which cells the host visits each cycle (same results either way).
    pub stepping: Stepping,
    /// The receding-beam skip ([`OccupiedBox::receding`]): exact, changes cycles and messages,
    /// never lit voxels.
    pub skip_receding: bool,
    /// The dead-direction skip: the source emits no initial beam whose direction leads away
    /// from the occupied box (its rays are counted as skipped).
    pub skip_dead_directions: bool,
    /// Send every link transfer through the codec and a fault injector, with acknowledgement
    /// and retransmission ([`crate::machine::faults`]); `None`: perfect links.
    pub faults: Option<LinkFaults>,
    /// Cycles in a row without progress (no beam processed, delivered or acknowledged) while
    /// beams are in flight before the run stops with a stall report (deadlock, dead link).
    pub stall_cycles: u64,
    /// Store lit marks only for each column's visible voxel (`LightEnv::lit_visible_only`):
    /// same image, a lit set restricted to what the image shows, no lit-store overflow.
    pub lit_visible_only: bool,
    /// The sibling wait in cycles ([`LightEnv::hold`]; 0: off). Exact: changes cycles and
    /// beam counts, never lit voxels.
    pub hold: u16,
    /// The empty-frustum skip ([`LightEnv::frustum`]): exact, changes cycles and messages,
    /// never lit voxels.
    pub skip_frustum: bool,
    /// The hidden-voxel skip (needs `lit_visible_only`): the frustum summary holds only the
    /// visible voxels (each column's first occupied voxel, the one its cell shades), so a beam
    /// none of whose rays can reach a visible voxel's block is dropped, its rays counted as
    /// skipped. Exact for what `lit_visible_only` keeps: same visible lit set, same image.
    /// Hidden voxels are not lit (rays they would absorb may be counted as skipped).
    pub skip_hidden: bool,
    /// Resolution of the summary the empty-frustum and hidden-voxel skips test against.
    pub frustum_blocks: FrustumBlocks,
    /// The lit rule ([`cell_core::lit`]).
    pub rule: LitRule,
    /// Where the sources' rays leave from along each face's axis ([`Origin`]): the source
    /// voxel's centre plane (the thesis's rays) or the light itself. Applied to the
    /// sources the jobs make from light positions ([`LightConfig::source`]).
    pub rays: Origin,
    /// The timing rules the thesis leaves open ([`Timing`]). Exact: changes
    /// cycles, messages and FIFO occupancy, never lit voxels.
    pub timing: Timing,
    /// Stop each source's diffusion after this many cycles, beams still in flight (a snapshot
    /// of the grid: which cells hold beams, which voxels were visited; the thesis's time-lapse,
    /// §4.4.3). A source that ran until then is not checked for conservation. `None`: run
    /// to quiescence.
    pub stop_at: Option<u64>,
}

/// Blocks per axis of the summary the empty-frustum and hidden-voxel skips test beams against
/// ([`cell_core::occupancy`]): finer blocks drop more beams (the test is exact only with
/// one-voxel blocks) for more memory per cell. Same lit voxels and image whichever is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FrustumBlocks {
    /// 8 × 8 × 8 blocks, `u8` rows: 232 bytes per cell (what a cell trace carries).
    B8,
    /// 16 × 16 × 16 blocks, `u16` rows: 1 348 bytes per cell.
    B16,
    /// 32 × 32 × 32 blocks, `u32` rows: 9 384 bytes per cell.
    B32,
}

impl FrustumBlocks {
    /// Bytes each cell holds for the summary.
    pub const fn bytes(self) -> usize {
        match self {
            FrustumBlocks::B8 => Occupancy8::BYTES,
            FrustumBlocks::B16 => Occupancy16::BYTES,
            FrustumBlocks::B32 => Occupancy32::BYTES,
        }
    }
}

/// A summary of the chosen resolution ([`FrustumBlocks`]).
#[derive(Clone, Debug)]
pub enum Summary {
    /// 8 blocks per axis.
    B8(Box<Occupancy8>),
    /// 16 blocks per axis.
    B16(Box<Occupancy16>),
    /// 32 blocks per axis.
    B32(Box<Occupancy32>),
}

impl Summary {
    /// The summary of the voxels where a beam can do something (`active_span`: the occupied
    /// voxels, and under the plane rule the voxels bracketing each visible surface), or
    /// (`visible`) of the voxels the image reads only: each column's first occupied voxel under
    /// the thesis's rule, the two voxels bracketing its visible surface under the plane rule.
    /// What the OR-reduction of every cell's own summary gives.
    pub fn of<const D: usize>(grid: &Grid<D>, blocks: FrustumBlocks, visible: bool, rule: LitRule) -> Self {
        match blocks {
            FrustumBlocks::B8 => Summary::B8(Box::new(summarise(grid, visible, rule))),
            FrustumBlocks::B16 => Summary::B16(Box::new(summarise(grid, visible, rule))),
            FrustumBlocks::B32 => Summary::B32(Box::new(summarise(grid, visible, rule))),
        }
    }

    /// The test a cell runs.
    pub fn test<F: FracBits>(&self) -> &dyn FrustumTest<F> {
        match self {
            Summary::B8(o) => &**o,
            Summary::B16(o) => &**o,
            Summary::B32(o) => &**o,
        }
    }

    /// The 8-block summary a cell trace carries (`None` for finer ones).
    pub fn traceable(&self) -> Option<&FrustumSummary> {
        match self {
            Summary::B8(o) => Some(&**o),
            _ => None,
        }
    }
}

impl LightConfig {
    /// Light `id` at `pos` (voxel units) on an `n` grid ([`source_at`]), its rays leaving from
    /// [`LightConfig::rays`].
    pub fn source(&self, id: usize, pos: [f64; 3], n: u32) -> Result<Source> {
        Ok(source_at(id, pos, n)?.with_origin(self.rays))
    }
}

/// How the host steps the grid. Both simulate every cycle of every cell: a cell without a beam
/// does nothing in a cycle, so visiting it or not changes no state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Stepping {
    /// Visit only the cells holding beams (event-driven; the default).
    #[default]
    Active,
    /// Visit every cell in every cycle (the straightforward reference).
    AllCells,
}

/// Counters of a diffusion run (docs/LIGHTING.md, "light-accuracy"): one source's, or the sum over sources.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct DiffusionCounts {
    /// Cycles until the last beam was consumed (the thesis's T).
    pub cycles: u64,
    /// max(`lb_distance`, `lb_cell_load`).
    pub lower_bound: u64,
    /// Largest layer reached + 1: a beam at layer k was processed k + 1 times in sequence.
    pub lb_distance: u64,
    /// Largest number of beams one cell had to process (one per cycle).
    pub lb_cell_load: u64,
    /// Beams processed in the whole grid.
    pub beams_processed: u64,
    /// Beams merged into a waiting beam on arrival.
    pub beams_merged: u64,
    /// Messages that crossed a link.
    pub messages: u64,
    /// Rays of the six initial beams.
    pub rays_emitted: u128,
    /// Rays that stopped in an occupied voxel.
    pub rays_absorbed: u128,
    /// Rays that left the grid.
    pub rays_exited: u128,
    /// Rays dropped by the skips (they would have left the grid without meeting a voxel).
    pub rays_skipped: u128,
    /// Largest FIFO occupancy of any cell.
    pub peak_fifo: u16,
    /// Sum over cells of cycles with beams waiting and none processable.
    pub blocked_cell_cycles: u64,
    /// Sum over cells of cycles in which every beam that could go waited for its siblings
    /// (`--hold`).
    pub held_cell_cycles: u64,
    /// Most cells active in one cycle.
    pub peak_active_cells: u64,
    /// Most messages one link carried in one direction (the thesis expects the links near the
    /// source to be the busiest, §4.1.3).
    pub peak_link_load: u64,
    /// Chebyshev distance (cells) from that link's sending cell to the source's column.
    pub peak_link_distance: u32,
    /// Beam steps judged ray by ray under exact occluders (more undecided triangles than
    /// `cell_core::occluder::MAX_EXACT_TRIANGLES`): same verdicts, more arithmetic.
    pub per_ray_visits: u64,
}

impl DiffusionCounts {
    /// Accumulate another run: sums for totals, maxima for peaks (sources run one after
    /// another, so cycles and lower bounds add up).
    pub fn add(&mut self, o: &DiffusionCounts) {
        self.cycles += o.cycles;
        self.lower_bound += o.lower_bound;
        self.lb_distance = self.lb_distance.max(o.lb_distance);
        self.lb_cell_load = self.lb_cell_load.max(o.lb_cell_load);
        self.beams_processed += o.beams_processed;
        self.beams_merged += o.beams_merged;
        self.messages += o.messages;
        self.rays_emitted += o.rays_emitted;
        self.rays_absorbed += o.rays_absorbed;
        self.rays_exited += o.rays_exited;
        self.rays_skipped += o.rays_skipped;
        self.peak_fifo = self.peak_fifo.max(o.peak_fifo);
        self.blocked_cell_cycles += o.blocked_cell_cycles;
        self.held_cell_cycles += o.held_cell_cycles;
        self.per_ray_visits += o.per_ray_visits;
        self.peak_active_cells = self.peak_active_cells.max(o.peak_active_cells);
        if o.peak_link_load > self.peak_link_load {
            self.peak_link_load = o.peak_link_load;
            self.peak_link_distance = o.peak_link_distance;
        }
    }

    /// cycles / lower_bound.
    pub fn t_over_lb(&self) -> f64 {
        self.cycles as f64 / self.lower_bound.max(1) as f64
    }
}

/// One source's diffusion.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SourceReport {
    /// Source index (bit in the mask).
    pub source: usize,
    /// Its position in voxel units.
    pub position: [f64; 3],
    /// The cell that processed the most beams (`lb_cell_load` of them).
    pub busiest_cell: [u32; 2],
    /// Its counters.
    #[serde(flatten)]
    pub counts: DiffusionCounts,
}

/// The lighting state of the whole grid after diffusion.
pub struct Lighting<F: FracBits> {
    /// Grid side.
    pub n: u32,
    /// Cells, row-major.
    pub cells: Vec<HostLightCell<F>>,
    /// One report per source, in diffusion order.
    pub reports: Vec<SourceReport>,
    /// Voxels where a beam was processed, index `(y·n + x)·depth + z` (with `record_visits`).
    pub visited: Option<Vec<bool>>,
    /// What the faulty links did (with `faults`).
    pub link_faults: Option<FaultCounts>,
    /// The lit rule the cells applied.
    pub rule: LitRule,
}

impl<F: FracBits> Lighting<F> {
    /// Sources that lit voxel (x, y, z).
    pub fn mask(&self, x: u32, y: u32, z: u16) -> SourceMask {
        self.cells[(y * self.n + x) as usize].lit.mask_at(z)
    }

    /// Sources that lit the visible surface of column (x, y) (the plane rule).
    pub fn visible_mask(&self, x: u32, y: u32) -> SourceMask {
        self.cells[(y * self.n + x) as usize].visible_lit
    }

    /// Every lit voxel with its mask, in (y, x, z) order.
    pub fn lit_voxels(&self) -> impl Iterator<Item = ([u32; 3], SourceMask)> + '_ {
        self.cells.iter().flat_map(|c| {
            c.lit
                .runs()
                .iter()
                .flat_map(move |r| (r.lo..=r.hi).map(move |z| ([c.x as u32, c.y as u32, z as u32], r.mask)))
        })
    }

    /// Lit marks lost to full lit stores.
    pub fn lit_overflows(&self) -> u64 {
        self.cells.iter().map(|c| c.counters.lit_overflows as u64).sum()
    }
}

/// Diffuse every source over the loaded grid. Source positions are in voxel units (already
/// validated to lie inside the grid). `progress(source, cycle)` is called now and then.
pub fn diffuse<F: FracBits, const D: usize>(
    grid: &Grid<D>,
    sources: &[Source],
    cfg: &LightConfig,
    progress: impl FnMut(usize, u64),
) -> Result<Lighting<F>> {
    diffuse_tapped(grid, sources, cfg, None, progress)
}

/// [`diffuse`], recording what the cells watched by `tap` receive and send.
///
/// The links are chosen here, once per run: perfect links, or each behind a fault injector
/// (`cfg.faults`), each traced when `tap` records. Every source then runs the same scheduler,
/// generic over the links ([`crate::machine::links`]).
pub fn diffuse_tapped<F: FracBits, const D: usize>(
    grid: &Grid<D>,
    sources: &[Source],
    cfg: &LightConfig,
    tap: Option<&mut Tap>,
    progress: impl FnMut(usize, u64),
) -> Result<Lighting<F>> {
    let far = check_light_run::<F>(grid.n, sources, cfg)?;
    let n = grid.n;
    let cells = idle_cells(n);
    let occupied = occupied_box(grid, cfg.rule);
    let frustum = frustum_summary(grid, cfg, tap.is_some())?;
    check_recording(cfg, tap.is_some())?;
    cfg.timing.check(cfg.fa, cfg.faults.is_none() && tap.is_none())?;
    let run = AllSources { grid, sources, cfg, far, occupied, frustum: frustum.as_ref(), shot: None };
    let wire = cfg.faults.map(|faults| Wire { faults, far: far.get() });
    match (&wire, tap) {
        (None, None) => run.diffuse(cells, GridLinks::new(n, |_| PerfectLink), None, progress),
        (Some(w), None) => {
            run.diffuse(cells, GridLinks::new(n, |id| FaultInjector::new(PerfectLink, w, id)), None, progress)
        }
        (None, Some(t)) => run.diffuse(cells, GridLinks::new(n, |id| Tracer::new(PerfectLink, id)), Some(t), progress),
        (Some(w), Some(t)) => {
            let links = GridLinks::new(n, |id| Tracer::new(FaultInjector::new(PerfectLink, w, id), id));
            run.diffuse(cells, links, Some(t), progress)
        }
    }
}

/// n × n idle lighting cells, row-major.
fn idle_cells<F: FracBits>(n: u32) -> Vec<HostLightCell<F>> {
    let mut cells: Vec<HostLightCell<F>> = Vec::with_capacity((n * n) as usize);
    for y in 0..n {
        for x in 0..n {
            cells.push(LightCell::new(x as u16, y as u16));
        }
    }
    cells
}

/// One radiosity shot (radiosity thesis §3.4; `machine::radiosity` drives it): the diffusion of
/// one source whose initial beams are `initial` (the shooting patch's front hemisphere) instead
/// of the six full faces, every processed beam's absorbed and departed rays reported to `rays`.
/// The thesis's lit rule only (its absorbed ray sets are whole beams), perfect links.
pub fn diffuse_shot<F: FracBits, const D: usize>(
    grid: &Grid<D>,
    source: &Source,
    initial: &[Beam<F>],
    cfg: &LightConfig,
    rays: &dyn RaySink<F>,
    progress: impl FnMut(usize, u64),
) -> Result<Lighting<F>> {
    if cfg.rule != LitRule::Thesis
        || cfg.rays != Origin::SourceVoxel
        || cfg.faults.is_some()
        || cfg.skip_dead_directions
    {
        bail!(
            "a radiosity shot runs under the thesis's lit rule and rays, on perfect links, without the dead-direction skip"
        );
    }
    let sources = std::slice::from_ref(source);
    let far = check_light_run::<F>(grid.n, sources, cfg)?;
    let occupied = occupied_box(grid, cfg.rule);
    let frustum = frustum_summary(grid, cfg, false)?;
    let shot = Some(Shot { initial, rays });
    let run = AllSources { grid, sources, cfg, far, occupied, frustum: frustum.as_ref(), shot };
    run.diffuse(idle_cells(grid.n), GridLinks::new(grid.n, |_| PerfectLink), None, progress)
}

/// What a radiosity shot changes in a diffusion ([`diffuse_shot`]).
#[derive(Clone, Copy)]
struct Shot<'a, F: FracBits> {
    initial: &'a [Beam<F>],
    rays: &'a dyn RaySink<F>,
}

/// The far distance of an n × n grid, once the run's sources, FIFO limit and memory are
/// checked.
pub(crate) fn check_light_run<F: FracBits>(n: u32, sources: &[Source], cfg: &LightConfig) -> Result<FarDistance<F>> {
    if sources.len() > cell_core::light::MAX_SOURCES {
        bail!("{} light sources: at most {} are supported", sources.len(), cell_core::light::MAX_SOURCES);
    }
    if cfg.fa == 0 || cfg.fa > FA_CAP {
        bail!("--fa {} is out of range: 1 ..= {FA_CAP} (the FIFO capacity compiled into a cell)", cfg.fa);
    }
    if let Some((i, s)) = sources.iter().enumerate().find(|(_, s)| {
        let v = s.voxel();
        v[0] < 0 || v[1] < 0 || v[0] >= n as i32 || v[1] >= n as i32 || !(0..=u16::MAX as i32).contains(&v[2])
    }) {
        bail!("light {} is in voxel {:?}, outside the {n} × {n} grid of cells", i + 1, s.voxel());
    }
    let min_fa = cell_core::light::MIN_FA_FROM_LIGHT;
    if cfg.fa < min_fa && sources.iter().any(|s| s.origin == cell_core::beam::Origin::Light) {
        bail!(
            "--fa {} is too small for rays from the light (the default): the source cell's first split may keep four FIFO slots (at least {min_fa}); for a smaller FIFO, --rays-from voxel",
            cfg.fa
        );
    }
    let far = FarDistance::<F>::new(n - 1).ok_or_else(|| {
        anyhow::anyhow!(
            "far distance D = {} exceeds the beam bit budget for {} fraction bits (max D = {})",
            n - 1,
            F::U32,
            FarDistance::<F>::MAX
        )
    })?;
    crate::machine::limits::check_grid_memory("grid of lighting cells", n, std::mem::size_of::<HostLightCell<F>>())?;
    Ok(far)
}

/// The summary the empty-frustum and hidden-voxel skips test against, if either is on.
fn frustum_summary<const D: usize>(grid: &Grid<D>, cfg: &LightConfig, tapped: bool) -> Result<Option<Summary>> {
    if cfg.skip_hidden && !cfg.lit_visible_only {
        bail!("the hidden-voxel skip drops the light of hidden voxels: use it with --lit-visible-only");
    }
    let frustum =
        (cfg.skip_hidden || cfg.skip_frustum).then(|| Summary::of(grid, cfg.frustum_blocks, cfg.skip_hidden, cfg.rule));
    if tapped && frustum.as_ref().is_some_and(|s| s.traceable().is_none()) {
        bail!("a cell trace carries the 8 × 8 × 8 frustum summary: record with --frustum-blocks 8");
    }
    Ok(frustum)
}

/// Refuse link delays the stall detector would take for stalls, and traces of a partial lit
/// store.
fn check_recording(cfg: &LightConfig, tapped: bool) -> Result<()> {
    if let Some(f) = cfg.faults.filter(|f| f.delay_ppm > 0 && f.delay_cycles as u64 >= cfg.stall_cycles.max(1)) {
        bail!(
            "--link-faults delay-cycles={} must be below --stall-cycles {}: a frame held on the wire is not progress",
            f.delay_cycles,
            cfg.stall_cycles
        );
    }
    if cfg.lit_visible_only && tapped {
        bail!("a cell trace records the whole lit store: record without --lit-visible-only");
    }
    Ok(())
}

/// What every source's diffusion of a run shares.
pub(crate) struct AllSources<'a, F: FracBits, const D: usize> {
    grid: &'a Grid<D>,
    sources: &'a [Source],
    cfg: &'a LightConfig,
    far: FarDistance<F>,
    occupied: OccupiedBox,
    frustum: Option<&'a Summary>,
    shot: Option<Shot<'a, F>>,
}

impl<'a, F: FracBits, const D: usize> AllSources<'a, F, D> {
    /// The sources of a run on `grid` whose cells are told no frustum summary (the
    /// asynchronous boards, [`crate::machine::async_tiles`]: every cell's environment comes
    /// from [`AllSources::env`] as here).
    pub(crate) fn plain(grid: &'a Grid<D>, sources: &'a [Source], cfg: &'a LightConfig, far: FarDistance<F>) -> Self {
        let occupied = occupied_box(grid, cfg.rule);
        AllSources { grid, sources, cfg, far, occupied, frustum: None, shot: None }
    }

    /// Diffuse the sources one after another over `cells`, through `links`.
    fn diffuse<L: HostLink<F> + FaultTally>(
        &self,
        mut cells: Vec<HostLightCell<F>>,
        mut links: GridLinks<L>,
        mut tap: Option<&mut Tap>,
        mut progress: impl FnMut(usize, u64),
    ) -> Result<Lighting<F>> {
        let (grid, cfg) = (self.grid, self.cfg);
        let order = SplitOrder::default();
        let traced = self.frustum.and_then(Summary::traceable);
        let mut reports = Vec::new();
        let mut visited = cfg.record_visits.then(|| vec![false; (grid.n * grid.n * grid.depth) as usize]);
        for (si, src) in self.sources.iter().enumerate() {
            let occluders = (cfg.rule == LitRule::Exact).then(|| SourceOccluders::new(self.grid, src, self.far));
            let env = self.env(src, si, &order, occluders.as_ref().map(|o| o as &dyn ColumnOccluders));
            let before: Vec<LightCounters> = cells.iter().map(|c| c.counters).collect();
            for c in cells.iter_mut() {
                c.counters.max_layer = 0;
                c.counters.peak_fifo = 0;
            }
            if let Some(t) = tap.as_deref_mut() {
                t.light(&env, traced);
            }
            let dead = cfg.skip_dead_directions.then_some(self.occupied);
            let rec = Recording { visited: visited.as_deref_mut(), tap: tap.as_deref_mut() };
            let (links, cells) = (links.slots(), &mut cells[..]);
            let initial = self.shot.map(|s| s.initial);
            let mut rep =
                diffuse_one(grid, cells, links, (src, initial), si, &env, cfg, dead, rec, |c| progress(si, c))?;
            rep.position = src.pos.map(|p| p.to_num::<f64>());
            add_cell_counts(&mut rep, cells, &before);
            if let Some(o) = &occluders {
                // The contact exchange ran before the beams left.
                rep.counts.cycles += CONTACT_EXCHANGE_CYCLES;
                rep.counts.messages += o.exchange_messages();
            }
            if cfg.stop_at.is_none_or(|t| rep.counts.cycles < t) {
                check_conservation(si, &rep.counts)?;
            }
            reports.push(rep);
        }
        let link_faults = fault_counts(links.all());
        Ok(Lighting { n: grid.n, cells, reports, visited, link_faults, rule: cfg.rule })
    }

    /// The lighting environment of source `si`.
    pub(crate) fn env<'e>(
        &'e self,
        src: &'e Source,
        si: usize,
        order: &'e SplitOrder,
        occluders: Option<&'e dyn ColumnOccluders>,
    ) -> LightEnv<'e, F> {
        let (cfg, grid, occupied) = (self.cfg, self.grid, self.occupied);
        LightEnv {
            source: src,
            far: self.far,
            n: grid.n,
            depth: grid.depth,
            policy: cfg.policy,
            rule: cfg.rule,
            order,
            fa: cfg.timing.fifo_limit(cfg.fa),
            free_ports: cfg.timing.free_ports,
            source_bit: 1 << si,
            merge: cfg.merge,
            skip: cfg.skip_receding.then_some(occupied),
            bounds: SubBeamBounds::new(grid.n, grid.depth, cfg.skip_receding.then_some(occupied), src),
            lit_visible_only: cfg.lit_visible_only,
            hold: cfg.hold,
            frustum: self.frustum.map(Summary::test),
            rays: self.shot.map(|s| s.rays),
            occluders,
        }
    }
}

/// Add what the cells counted during one source's diffusion (since `before`) to its report.
fn add_cell_counts<F: FracBits>(rep: &mut SourceReport, cells: &[HostLightCell<F>], before: &[LightCounters]) {
    for (c, b) in cells.iter().zip(before) {
        let k = &c.counters;
        let processed = k.processed - b.processed;
        rep.counts.beams_processed += processed;
        rep.counts.beams_merged += k.merged - b.merged;
        if processed > rep.counts.lb_cell_load {
            rep.counts.lb_cell_load = processed;
            rep.busiest_cell = [c.x as u32, c.y as u32];
        }
        rep.counts.rays_absorbed += (k.rays_absorbed - b.rays_absorbed) as u128;
        rep.counts.rays_exited += (k.rays_exited - b.rays_exited) as u128;
        rep.counts.rays_skipped += (k.rays_skipped - b.rays_skipped) as u128;
        rep.counts.blocked_cell_cycles += k.blocked_cycles - b.blocked_cycles;
        rep.counts.held_cell_cycles += k.held_cycles - b.held_cycles;
        rep.counts.per_ray_visits += (k.per_ray_visits - b.per_ray_visits) as u64;
        rep.counts.peak_fifo = rep.counts.peak_fifo.max(k.peak_fifo);
        if processed > 0 {
            rep.counts.lb_distance = rep.counts.lb_distance.max(k.max_layer as u64 + 1);
        }
    }
    rep.counts.lower_bound = rep.counts.lb_distance.max(rep.counts.lb_cell_load);
}

/// Every ray emitted was absorbed, left the grid or was skipped.
fn check_conservation(si: usize, c: &DiffusionCounts) -> Result<()> {
    if c.rays_emitted != c.rays_absorbed + c.rays_exited + c.rays_skipped {
        bail!(
            "ray conservation violated for source {si}: emitted {} ≠ absorbed {} + exited {} + skipped {} \
             ({} steps judged ray by ray)",
            c.rays_emitted,
            c.rays_absorbed,
            c.rays_exited,
            c.rays_skipped,
            c.per_ray_visits
        );
    }
    Ok(())
}

/// What a run records besides its results: visited voxels, cell traces.
struct Recording<'a> {
    visited: Option<&'a mut [bool]>,
    tap: Option<&'a mut Tap>,
}

/// Active cells per piece of work handed to a thread (below it, splitting costs more than it
/// saves).
const PIECE: usize = 64;

/// How many cells (or offers) ahead of the one being worked on the passes [`prefetch`]: about
/// one memory latency's worth of work (8 measured no better; 1 line or 7 lines of FIFO worse
/// than 4; without prefetching the Cornell n = 192 light phase takes ~20 % longer).
const AHEAD: usize = 4;

/// Prefetch what a pass reads first of a cell: the blocked-step key and output lengths (first
/// line), the FIFO length and the counters, and `fifo_lines` lines of FIFO slots (see the field
/// order of [`LightCell`]): 4 for a step, 1 for a delivery (merge scan), 0 for pops.
fn prefetch_cell<F: FracBits>(c: &HostLightCell<F>, fifo_lines: usize) {
    prefetch(c);
    prefetch(&c.counters);
    let f = c.fifo.as_ptr().cast::<u8>();
    for line in 0..fifo_lines {
        prefetch(f.wrapping_add(64 * line));
    }
}

/// What a piece of the compute phase reports: its beam-count change, whether a beam was
/// processed, (when visits are recorded) the cells and depths processed, (when cells are
/// traced) every cell's step result, and the link offers of its cells; and what a piece of the
/// link phase reports (`delta`, `any`, `taken`, `woke`, `roused`, `took`).
///
/// One per piece lives for the whole diffusion and is cleared, not dropped, each cycle: lists
/// allocated afresh every cycle went back to the kernel when the allocator trimmed its heap,
/// and were faulted in again (~160 k page faults in `light cornell --n 256`).
#[derive(Default)]
struct PieceResult<F: FracBits> {
    delta: i64,
    /// Compute phase: a beam was processed or held; link phase: a beam was delivered or
    /// acknowledged.
    any: bool,
    seen: Vec<(usize, u16)>,
    steps: Vec<(usize, Step)>,
    /// Its cells' offers, one list per port (each in sender order, so in receiver order).
    offers: [Vec<Offer<F>>; 8],
    /// Cells left with nothing to do by their step (empty FIFO, empty output buffers).
    quiet: Vec<u32>,
    /// Held cells with empty output buffers, and their [`LightCell::held_wait`]: nothing
    /// changes for them until that many cycles pass or a beam arrives.
    sleep: Vec<(u32, u16)>,
    /// Cells that the last cycle's deferred pops left with nothing (counted busy last cycle).
    drained: u64,
    /// Link phase: cells that received a beam and were not yet in the active list.
    woke: Vec<u32>,
    /// Link phase: the piece's offers in link order ([`link_order`]).
    order: Vec<(u8, u32)>,
    /// Link phase: beams delivered, and sleeping cells a delivery woke.
    taken: u64,
    roused: usize,
    /// Link phase: the journal of the piece's links (beams taken, in link order; only
    /// recording links write it).
    took: Vec<Took<F>>,
}

impl<F: FracBits> PieceResult<F> {
    /// Empty, keeping the lists' room.
    fn clear(&mut self) {
        self.delta = 0;
        self.any = false;
        self.seen.clear();
        self.steps.clear();
        self.offers.iter_mut().for_each(Vec::clear);
        self.quiet.clear();
        self.sleep.clear();
        self.drained = 0;
        self.woke.clear();
        self.order.clear();
        self.taken = 0;
        self.roused = 0;
        self.took.clear();
    }
}

/// `scratch` grown to at least `len` results, the first `len` cleared.
fn scratch_for<F: FracBits>(scratch: &mut Vec<PieceResult<F>>, len: usize) -> &mut [PieceResult<F>] {
    if scratch.len() < len {
        scratch.resize_with(len, PieceResult::default);
    }
    let s = &mut scratch[..len];
    s.iter_mut().for_each(PieceResult::clear);
    s
}

/// A message offered on a link in the link phase: receiver, arbitration key, sender, port, and a
/// copy of the message at the front of the sender's output buffer.
#[derive(Clone, Copy)]
struct Offer<F: FracBits> {
    to: u32,
    key: u32,
    from: u32,
    port: u8,
    msg: BeamMsg<F>,
}

/// The offers of `lists` (list p: the offers on port p, in increasing receiver order) in link
/// order, as (port, index) into `order`: by receiver, then arbitration key, then sender — the
/// order a sort of all offers by (receiver, key, sender) gives, by an 8-way merge. A receiver
/// has at most one offer per port (from its neighbour on that side), so its offers are the
/// lists' heads with the smallest receiver; most receivers have one.
fn link_order<F: FracBits>(lists: &[&mut [Offer<F>]; 8], order: &mut Vec<(u8, u32)>) {
    order.clear();
    // Receiver of each list's head; `u32::MAX` once a list is done (no cell has that index:
    // the grid is checked to fit memory long before 2^32 cells).
    let next_to = |l: &[Offer<F>], h: usize| l.get(h).map_or(u32::MAX, |o| o.to);
    let mut head = [0usize; 8];
    let mut next: [u32; 8] = std::array::from_fn(|p| next_to(&lists[p][..], 0));
    loop {
        let to = next.iter().fold(u32::MAX, |m, &t| m.min(t));
        if to == u32::MAX {
            return;
        }
        let mut mask = 0u8;
        for (p, &t) in next.iter().enumerate() {
            mask |= u8::from(t == to) << p;
        }
        if mask.is_power_of_two() {
            let p = mask.trailing_zeros() as usize;
            order.push((p as u8, head[p] as u32));
            head[p] += 1;
            next[p] = next_to(&lists[p][..], head[p]);
            continue;
        }
        // Several offers to one receiver: by (key, sender), ordered by insertion (at most 8).
        let mut group = [(0u32, 0u32, 0usize); 8];
        let mut g = 0;
        for p in Port::each(mask).map(Port::index) {
            let o = &lists[p][head[p]];
            let mut at = g;
            while at > 0 && (group[at - 1].0, group[at - 1].1) > (o.key, o.from) {
                group[at] = group[at - 1];
                at -= 1;
            }
            group[at] = (o.key, o.from, p);
            g += 1;
        }
        for &(_, _, p) in &group[..g] {
            order.push((p as u8, head[p] as u32));
            head[p] += 1;
            next[p] = next_to(&lists[p][..], head[p]);
        }
    }
}

/// The offers of every list, whole, for [`link_order`].
fn whole<F: FracBits>(offers: &mut [Vec<Offer<F>>; 8]) -> [&mut [Offer<F>]; 8] {
    offers.each_mut().map(Vec::as_mut_slice)
}

/// A piece of the link phase: its receiving cells, the index of the first, their offers per
/// port, and their links (by receiving end, [`GridLinks`]).
type LinkPiece<'a, T, F, L> = (&'a mut [T], usize, [&'a mut [Offer<F>]; 8], &'a mut [L]);

/// Cut `cells`, their links (8 per cell, by receiving end) and the per-port offer lists
/// together at the receiver indices `cuts` (increasing), pieces without offers left out. Every
/// offer of a receiver lands in the piece that owns the receiver and its links.
fn by_receiver<'a, T, F: FracBits, L>(
    mut cells: &'a mut [T],
    mut links: &'a mut [L],
    offers: &'a mut [Vec<Offer<F>>; 8],
    cuts: &[u32],
) -> Vec<LinkPiece<'a, T, F, L>> {
    let mut rest = whole(offers);
    let mut out = Vec::with_capacity(cuts.len() + 1);
    let (mut base, total) = (0usize, cells.len());
    for end in cuts.iter().map(|&c| c as usize).chain([total]) {
        let end = end.clamp(base, total);
        let lists: [&'a mut [Offer<F>]; 8] = std::array::from_fn(|p| {
            let l = std::mem::take(&mut rest[p]);
            let (mine, later) = l.split_at_mut(l.partition_point(|o| (o.to as usize) < end));
            rest[p] = later;
            mine
        });
        let (tile, tail) = std::mem::take(&mut cells).split_at_mut(end - base);
        let (tile_links, links_tail) = std::mem::take(&mut links).split_at_mut((end - base) * 8);
        if lists.iter().any(|l| !l.is_empty()) {
            out.push((tile, base, lists, tile_links));
        }
        cells = tail;
        links = links_tail;
        base = end;
    }
    out
}

/// Messages a sender's links delivered in one cycle: a 4-bit count per port (port p in bits
/// 4p ..= 4p + 3; a link carries at most [`Timing::link_rate`] ≤ `OB_CAP` < 16 per cycle).
type Taken = AtomicU32;

/// One message taken on port `p`, as a [`Taken`] increment.
const fn taken_one(p: u8) -> u32 {
    1 << (4 * p)
}

/// The (port, count) pairs of a [`Taken`] value with a nonzero count, in port order.
fn taken_counts(t: u32) -> impl Iterator<Item = (Port, u32)> {
    let mut rest = t;
    std::iter::from_fn(move || {
        (rest != 0).then(|| {
            let p = rest.trailing_zeros() / 4;
            rest &= !(15 << (4 * p));
            (Port::ALL[p as usize], t >> (4 * p) & 15)
        })
    })
}

/// The ports with a nonzero count in a [`Taken`] value.
fn taken_mask(t: u32) -> u8 {
    taken_counts(t).fold(0, |m, (p, _)| m | 1 << p.index())
}

/// Drop the messages of cell `i` whose offers were taken (its `taken` counts, then cleared);
/// whether there were any.
fn pop_taken<F: FracBits>(c: &mut HostLightCell<F>, i: usize, taken: &[Taken]) -> bool {
    let counts = taken[i].load(Relaxed);
    if counts == 0 {
        return false;
    }
    taken[i].store(0, Relaxed);
    for (p, k) in taken_counts(counts) {
        for _ in 0..k {
            c.out.pop_front(p);
        }
    }
    true
}

/// Mark the heads of cell `i` that went on the wire this cycle and were not acknowledged (its
/// `unacked` bits, then cleared), and unmark those acknowledged (its `taken` bits): a head on
/// the wire is not merged into ([`LightCell::head_in_flight`]).
fn mark_in_flight<F: FracBits>(c: &mut HostLightCell<F>, i: usize, taken: &[Taken], unacked: &[AtomicU8]) {
    let u = unacked[i].load(Relaxed);
    if u != 0 {
        unacked[i].store(0, Relaxed);
    }
    c.head_in_flight = (c.head_in_flight & !taken_mask(taken[i].load(Relaxed))) | u;
}

/// Not a sleeper (see [`Sleepers::asleep`]).
const AWAKE: u64 = u64::MAX;

/// One source's diffusion: the cycle loop over the phases of [`Run`].
#[allow(clippy::too_many_arguments)]
fn diffuse_one<F: FracBits, const D: usize, L: HostLink<F>>(
    grid: &Grid<D>,
    cells: &mut [HostLightCell<F>],
    links: &mut [L],
    src: (&Source, Option<&[Beam<F>]>),
    si: usize,
    env: &LightEnv<'_, F>,
    cfg: &LightConfig,
    dead: Option<OccupiedBox>,
    rec: Recording<'_>,
    mut progress: impl FnMut(u64),
) -> Result<SourceReport> {
    let mut run = Run::new(grid, cells, links, src, si, env, cfg, dead, rec);
    while run.running() && cfg.stop_at.is_none_or(|t| run.cycle < t) {
        let mut moved = run.emit();
        moved |= run.compute();
        moved |= run.links();
        run.pop();
        run.cycle += 1;
        let busy_now = run.next_active();
        run.settle(busy_now, moved)?;
        if run.cycle % 256 == 0 {
            progress(run.cycle);
        }
    }
    progress(run.cycle);
    Ok(run.finish())
}

/// The six initial beams of `src` that the dead-direction skip keeps, their rays counted in
/// `rep` (the skipped ones as skipped); or a radiosity shot's own initial beams (`shot`).
pub(crate) fn initial_beams<F: FracBits>(
    src: &Source,
    far: FarDistance<F>,
    dead: Option<OccupiedBox>,
    shot: Option<&[Beam<F>]>,
    order: [Direction; 6],
    rep: &mut SourceReport,
) -> Vec<Beam<F>> {
    if let Some(beams) = shot {
        rep.counts.rays_emitted += beams.iter().map(|b| b.ray_count() as u128).sum::<u128>();
        return beams.to_vec();
    }
    let sv = src.voxel();
    let mut initial = Vec::new();
    for d in order {
        let b = Beam::initial(src, d, far);
        rep.counts.rays_emitted += b.ray_count() as u128;
        if dead.is_some_and(|bx| bx.receding(d, sv, sv.map(i64::from))) {
            rep.counts.rays_skipped += b.ray_count() as u128;
        } else {
            initial.push(b);
        }
    }
    initial
}

/// The state of one source's diffusion from cycle to cycle, and its phases (the module doc's
/// cycle model). Per-cell flags and counters that the parallel pieces of a phase write, each
/// index from one piece only, are relaxed atomics: plain loads and stores, and the phase's join
/// orders them.
struct Run<'a, 'e, F: FracBits, const D: usize, L> {
    grid: &'a Grid<D>,
    cells: &'a mut [HostLightCell<F>],
    /// The grid's links, by receiving end ([`GridLinks`]).
    links: &'a mut [L],
    env: &'a LightEnv<'e, F>,
    stepping: Stepping,
    visited: Option<&'a mut [bool]>,
    tap: Option<&'a mut Tap>,
    si: usize,
    /// The source's voxel and its cell.
    sv: [i32; 3],
    s_idx: usize,
    activity: Activity,
    rep: SourceReport,
    /// The initial beams the emitter has not handed over yet.
    pending: std::vec::IntoIter<Beam<F>>,
    next_initial: Option<Beam<F>>,
    /// Every cell (all-cells stepping), or the cells holding beams, in row-major order.
    all: Vec<u32>,
    active: Vec<u32>,
    /// The cell is (or, during a cycle, will be) in the active list.
    in_active: Vec<AtomicBool>,
    /// Messages the receivers took this cycle, per sender, a [`Taken`] count per port (set by
    /// the receivers' pieces, consumed by the senders' pieces); and (links that may not
    /// acknowledge at once) ports whose offer went on the wire unacknowledged.
    taken_ports: Vec<Taken>,
    unacked_ports: Vec<AtomicU8>,
    /// The links acknowledge every delivery at once ([`cell_core::link::Link::LOSSLESS`]).
    lossless: bool,
    /// Deferred pops: a sender drops what was taken at the start of its next step, when the
    /// compute pass has the cell in cache anyway, instead of in a pass of its own over every
    /// sender (a third walk over scattered cells per cycle). Exact: between the link phase and
    /// its next step a sender is touched only by deliveries into its FIFO (and by the emitter,
    /// whose cell's pops are not deferred), which neither read nor change output buffers.
    /// Every sender is in the next active list (its output was busy). The busy count a cycle
    /// reports (`peak_active_cells`) is settled one cycle late: the cells the pops left idle
    /// are subtracted then. The reference modes (all cells, links that acknowledge later) pop
    /// in a pass.
    defer_pops: bool,
    /// Cells counted busy at the end of the last cycle, pending its deferred pops.
    pending_busy: Option<u64>,
    offers: [Vec<Offer<F>>; 8],
    /// Where the compute pieces started (cell indices): the link phase cuts the receivers
    /// there too.
    cuts: Vec<u32>,
    /// Per-piece results, kept from cycle to cycle (see `PieceResult`).
    scratch: Vec<PieceResult<F>>,
    /// Messages delivered per link, by receiving end ([`links::slot`]).
    link_load: Vec<AtomicU32>,
    woken: Vec<u32>,
    merged: Vec<u32>,
    cycle: u64,
    sleepers: Sleepers,
    /// With links that acknowledge later a message can sit in an output buffer, already
    /// delivered, waiting for its acknowledgement after the last beam was consumed: run until
    /// the buffers are empty.
    unacked: bool,
    /// Cycles in a row in which no beam was processed, delivered or acknowledged.
    stalled: u64,
    stall_limit: u64,
    /// [`Timing::burst`], and [`Timing::link_rate`] (messages offered per output buffer).
    burst: bool,
    link_rate: usize,
}

/// Held cells the host does not visit until their sibling wait ends or a beam arrives (exact:
/// [`LightCell::skip_held`] gives them the steps they missed). Not while tracing (a trace
/// records every step), not over links that acknowledge later.
struct Sleepers {
    /// Cells may sleep.
    on: bool,
    /// Per cell: the cycle it fell asleep ([`AWAKE`]: it did not).
    asleep: Vec<AtomicU64>,
    /// Per cycle modulo `hold + 1`: the sleepers whose wait ends then.
    alarms: Vec<Vec<(u32, u64)>>,
    /// Cells asleep.
    count: usize,
}

impl Sleepers {
    /// None asleep among `cells` cells (which may sleep if `on`), sibling wait `hold`.
    fn new(on: bool, cells: usize, hold: u16) -> Self {
        Sleepers {
            on,
            asleep: (0..if on { cells } else { 0 }).map(|_| AtomicU64::new(AWAKE)).collect(),
            alarms: (0..hold as usize + 1).map(|_| Vec::new()).collect(),
            count: 0,
        }
    }
}

/// Per-cell flags, `len` of them or none.
fn flags<T: Default>(on: bool, len: usize) -> Vec<T> {
    (0..if on { len } else { 0 }).map(|_| T::default()).collect()
}

impl<'a, 'e, F: FracBits, const D: usize, L: HostLink<F>> Run<'a, 'e, F, D, L> {
    #[allow(clippy::too_many_arguments)]
    fn new(
        grid: &'a Grid<D>,
        cells: &'a mut [HostLightCell<F>],
        links: &'a mut [L],
        (src, shot): (&Source, Option<&[Beam<F>]>),
        si: usize,
        env: &'a LightEnv<'e, F>,
        cfg: &LightConfig,
        dead: Option<OccupiedBox>,
        rec: Recording<'a>,
    ) -> Self {
        let (n, len, stepping) = (grid.n as usize, cells.len(), cfg.stepping);
        let sv = src.voxel();
        let s_idx = sv[1] as usize * n + sv[0] as usize;
        let mut rep = SourceReport { source: si, ..Default::default() };
        let initial = initial_beams(src, env.far, dead, shot, cfg.timing.emission.order(), &mut rep);
        let activity = Activity::new();
        activity.add(initial.len() as u64);
        let mut pending = initial.into_iter();
        let next_initial = pending.next();
        let active_stepping = stepping == Stepping::Active;
        let in_active: Vec<AtomicBool> = flags(active_stepping, len);
        if active_stepping {
            in_active[s_idx].store(true, Relaxed);
        }
        let lossless = lossless::<F, L>();
        let may_sleep = active_stepping && rec.tap.is_none() && lossless && env.hold > 0;
        Run {
            grid,
            cells,
            links,
            env,
            stepping,
            visited: rec.visited,
            tap: rec.tap,
            si,
            sv,
            s_idx,
            activity,
            rep,
            pending,
            next_initial,
            all: if active_stepping { Vec::new() } else { (0..len as u32).collect() },
            active: vec![s_idx as u32],
            in_active,
            taken_ports: flags(true, len),
            unacked_ports: flags(!lossless, len),
            lossless,
            defer_pops: active_stepping && lossless,
            pending_busy: None,
            offers: Default::default(),
            cuts: Vec::new(),
            scratch: Vec::new(),
            link_load: flags(true, len * 8),
            woken: Vec::new(),
            merged: Vec::new(),
            cycle: 0,
            sleepers: Sleepers::new(may_sleep, len, env.hold),
            unacked: false,
            stalled: 0,
            stall_limit: cfg.stall_cycles.max(1),
            burst: cfg.timing.burst,
            link_rate: cfg.timing.link_rate as usize,
        }
    }

    /// Beams are in flight (or messages wait for their acknowledgement).
    fn running(&self) -> bool {
        !self.activity.is_quiescent() || self.unacked
    }

    /// 1. The source emitter hands the next initial beam to the source cell if its FIFO has
    ///    room (under [`Timing::burst`], every one it has room for); whether it did.
    fn emit(&mut self) -> bool {
        let mut moved = false;
        while self.emit_one() {
            moved = true;
            if !self.burst {
                break;
            }
        }
        moved
    }

    /// Hand the next initial beam to the source cell if its FIFO has room; whether it did.
    fn emit_one(&mut self) -> bool {
        let Some(b) = self.next_initial else { return false };
        let s_idx = self.s_idx;
        if !self.cells[s_idx].can_accept_initial(self.env.fa, self.env.source) {
            return false;
        }
        let msg = BeamMsg::new(b, self.sv[2] as u16);
        if let Some(r) = self.tap.as_deref_mut().and_then(|t| t.get(s_idx)) {
            r.inject(&msg);
        }
        if self.cells[s_idx].accept(msg, self.env.merge, &self.activity).is_ok() {
            self.next_initial = self.pending.next();
            return true;
        }
        false
    }

    /// 2. Compute: every visited cell steps on its own state and its own dexels, in parallel
    ///    over pieces of the (row-major) visit list; each piece counts beams in a local delta.
    ///    A cell's output buffers change only in its own step, so the piece also gathers its
    ///    cells' link offers (the message at the front of each busy output buffer) while the
    ///    cell is in cache: the same offers, in the same order, as a pass after all steps.
    ///    Whether a beam was processed (or held).
    fn compute(&mut self) -> bool {
        let k = StepCtx {
            grid: self.grid,
            env: self.env,
            taken_ports: &self.taken_ports,
            defer_pops: self.defer_pops,
            tapping: self.tap.is_some(),
            record: self.visited.is_some(),
            may_sleep: self.sleepers.on,
            s_idx: self.s_idx,
            emitting: self.next_initial.is_some(),
            n: self.grid.n as usize,
            wave: self.env.policy.by_layer(),
            link_rate: self.link_rate,
        };
        let visit = if self.stepping == Stepping::AllCells { &self.all } else { &self.active };
        let pieces = tiles(self.cells, visit, PIECE);
        self.cuts.clear();
        self.cuts.extend(pieces.iter().skip(1).map(|&(_, base, _)| base as u32));
        let count = pieces.len();
        let done = scratch_for(&mut self.scratch, count);
        pieces.into_par_iter().zip(done.par_iter_mut()).for_each(|((tile, base, idx), r)| {
            k.step_piece(tile, base, idx, r);
        });
        self.gather_steps(count)
    }

    /// The compute pieces' results, in piece order: offers, idle and sleeping cells, beam
    /// counts, trace steps, visits. Whether a beam was processed (or held).
    fn gather_steps(&mut self, count: usize) -> bool {
        self.offers.iter_mut().for_each(Vec::clear);
        let done = &self.scratch[..count];
        let drained: u64 = done.iter().map(|r| r.drained).sum();
        if let Some(b) = self.pending_busy.take() {
            self.rep.counts.peak_active_cells = self.rep.counts.peak_active_cells.max(b - drained);
        }
        let (cycle, ring, depth) = (self.cycle, self.sleepers.alarms.len(), self.grid.depth as usize);
        let mut moved = false;
        for PieceResult { delta, any, seen, steps, offers: o, quiet, sleep, .. } in done.iter() {
            for (all, mine) in self.offers.iter_mut().zip(o) {
                all.extend_from_slice(mine);
            }
            if self.stepping == Stepping::Active {
                // Marked idle now; a quiet cell that receives below is marked busy again.
                for &q in quiet {
                    self.in_active[q as usize].store(false, Relaxed);
                }
                // Sleepers too, until their wait ends (or a beam arrives, below).
                for &(q, w) in sleep {
                    self.in_active[q as usize].store(false, Relaxed);
                    self.sleepers.asleep[q as usize].store(cycle, Relaxed);
                    self.sleepers.alarms[(cycle + w as u64) as usize % ring].push((q, cycle));
                    self.sleepers.count += 1;
                }
            }
            self.activity.apply(*delta);
            moved |= *any;
            if let Some(t) = self.tap.as_deref_mut() {
                for &(i, step) in steps {
                    if let Some(r) = t.get(i) {
                        r.step(step);
                    }
                }
            }
            if let Some(v) = self.visited.as_deref_mut() {
                for &(i, z) in seen {
                    v[i * depth + z as usize] = true;
                }
            }
        }
        moved
    }

    /// 3. Links. Under the wavefront policy the oldest messages (smallest layer) claim FIFO
    ///    credits first; under the thesis's, senders in row-major order. A (sender, port)
    ///    feeds one receiver, and receivers interact only through their own FIFO (and their
    ///    own links), so each receiver pulls its offers in (key, sender) order — the same
    ///    outcome as one global pass in (key, row-major sender) order — in parallel. Each
    ///    port's offers are in receiver order already (a port's receiver is its sender plus a
    ///    constant): the lists are merged ([`link_order`]), not sorted. Every offer goes
    ///    through its link ([`HostLink`]); whether a beam was delivered or acknowledged.
    fn links(&mut self) -> bool {
        let k = PullCtx {
            env: self.env,
            cycle: self.cycle,
            stepping: self.stepping,
            may_sleep: self.sleepers.on,
            lossless: self.lossless,
            taken_ports: &self.taken_ports,
            unacked_ports: &self.unacked_ports,
            in_active: &self.in_active,
            asleep: &self.sleepers.asleep,
            link_load: &self.link_load,
        };
        let groups = by_receiver(self.cells, self.links, &mut self.offers, &self.cuts);
        let count = groups.len();
        let pulled = scratch_for(&mut self.scratch, count);
        groups.into_par_iter().zip(pulled.par_iter_mut()).for_each(|(piece, r)| k.pull_piece(piece, r));
        let mut moved = false;
        for r in &self.scratch[..count] {
            self.sleepers.count -= r.roused;
            self.activity.apply(r.delta);
            self.rep.counts.messages += r.taken;
            moved |= r.any;
            self.woken.extend_from_slice(&r.woke);
            if let Some(t) = self.tap.as_deref_mut() {
                r.took.iter().for_each(|e| t.took(e));
            }
        }
        moved
    }

    /// Senders drop what was taken (and, over links that acknowledge later, mark what is on the
    /// wire): deferred to their next step (see `defer_pops`) but for the emitting cell, whose
    /// room the emitter checks first; otherwise in parallel over the visited cells (every
    /// sender is one). A cell's last pop leaves its flag right (receptions came before the
    /// pops).
    fn pop(&mut self) {
        let (taken, unacked, in_active) = (&self.taken_ports, &self.unacked_ports, &self.in_active);
        if self.defer_pops {
            let c = &mut self.cells[self.s_idx];
            if pop_taken(c, self.s_idx, taken) {
                in_active[self.s_idx].store(c.busy(), Relaxed);
            }
            return;
        }
        let (lossless, stepping) = (self.lossless, self.stepping);
        let visit = if stepping == Stepping::AllCells { &self.all } else { &self.active };
        tiles(self.cells, visit, PIECE).into_par_iter().for_each(|(tile, base, idx)| {
            for (k, &i) in idx.iter().enumerate() {
                if let Some(&j) = idx.get(k + AHEAD) {
                    prefetch_cell(&tile[j as usize - base], 0);
                }
                let i = i as usize;
                let c = &mut tile[i - base];
                if !lossless {
                    mark_in_flight(c, i, taken, unacked);
                }
                if pop_taken(c, i, taken) && stepping == Stepping::Active {
                    in_active[i].store(c.busy(), Relaxed);
                }
            }
        });
    }

    /// The cells busy at the start of the next cycle (`cycle` is its number), and (active
    /// stepping) the next cycle's active list.
    fn next_active(&mut self) -> u64 {
        match self.stepping {
            Stepping::Active => self.next_active_list(),
            Stepping::AllCells => {
                let busy = self.cells.par_iter().filter(|c| c.busy()).count() as u64;
                busy + u64::from(self.next_initial.is_some() && !self.cells[self.s_idx].busy())
            }
        }
    }

    /// Sleepers whose wait ends next cycle, and sleepers a beam reached, wake up: they are owed
    /// the held steps they were not given (cycles c0 + 1 ..= cycle). Next cycle's active set:
    /// busy cells, in row-major order. `in_active` now says which cells are busy without
    /// reading them: a cell is idle after the link phase if its step left it quiet and it
    /// received nothing, or its last pop drained it; every receiver holds a beam. (A quiet
    /// receiver can be in both lists: the merge keeps one.) Returns the busy count.
    fn next_active_list(&mut self) -> u64 {
        let (cycle, ring) = (self.cycle, self.sleepers.alarms.len());
        let due = std::mem::take(&mut self.sleepers.alarms[(cycle as usize) % ring]);
        for (q, c0) in due {
            if self.sleepers.asleep[q as usize].load(Relaxed) == c0 {
                self.cells[q as usize].skip_held((cycle - 1 - c0) as u16);
                self.sleepers.asleep[q as usize].store(AWAKE, Relaxed);
                self.sleepers.count -= 1;
                let was = self.in_active[q as usize].swap(true, Relaxed);
                debug_assert!(!was);
                self.woken.push(q);
            }
        }
        let in_active = &self.in_active;
        self.active.retain(|&i| in_active[i as usize].load(Relaxed));
        debug_assert!(self.woken.iter().all(|&j| self.cells[j as usize].busy()));
        self.woken.sort_unstable();
        merge_sorted(&mut self.active, &self.woken, &mut self.merged);
        self.woken.clear();
        debug_assert!(self
            .active
            .iter()
            .all(|&i| self.cells[i as usize].busy() || self.taken_ports[i as usize].load(Relaxed) != 0));
        if self.next_initial.is_some() && !self.in_active[self.s_idx].swap(true, Relaxed) {
            self.active.push(self.s_idx as u32);
            self.active.sort_unstable();
        }
        self.active.len() as u64 + self.sleepers.count as u64
    }

    /// The end of a cycle: the busy count (settled next cycle under deferred pops), whether
    /// acknowledgements are awaited, and the stall detector.
    fn settle(&mut self, busy_now: u64, moved: bool) -> Result<()> {
        if self.defer_pops {
            self.pending_busy = Some(busy_now);
        } else {
            self.rep.counts.peak_active_cells = self.rep.counts.peak_active_cells.max(busy_now);
        }
        self.unacked = !self.lossless && busy_now > 0;
        // A sleeping cell's wait ends by itself: not a stall.
        self.stalled = if moved || self.sleepers.count > 0 { 0 } else { self.stalled + 1 };
        if self.stalled >= self.stall_limit {
            let blocked: Vec<String> = self
                .cells
                .iter()
                .filter(|c| c.busy())
                .take(8)
                .map(|c| format!("({}, {}) fifo {} out {:?}", c.x, c.y, c.fifo.len(), Port::ALL.map(|p| c.out.len(p))))
                .collect();
            bail!(
                "stall at cycle {} of source {}: no progress for {} cycle(s) with {} beams in flight \
                 (deadlock or dead link; --stall-cycles {}); blocked cells (fifo, output buffers): {}",
                self.cycle,
                self.si,
                self.stalled,
                self.activity.get(),
                self.stall_limit,
                blocked.join("; ")
            );
        }
        Ok(())
    }

    /// The last cycle's deferred pops and busy count; the cycle count and the busiest link.
    fn finish(mut self) -> SourceReport {
        if self.defer_pops {
            let mut drained = 0;
            for &i in &self.active {
                let c = &mut self.cells[i as usize];
                if pop_taken(c, i as usize, &self.taken_ports) && !c.busy() {
                    drained += 1;
                }
            }
            if let Some(b) = self.pending_busy {
                self.rep.counts.peak_active_cells = self.rep.counts.peak_active_cells.max(b - drained);
            }
        }
        debug_assert!(
            self.running()
                || self.cells.iter().all(|c| !c.busy()) && self.taken_ports.iter().all(|t| t.load(Relaxed) == 0)
        );
        self.rep.counts.cycles = self.cycle;
        let n = self.grid.n as usize;
        if let Some((i, load)) = busiest_link(n, &self.link_load) {
            let (x, y) = ((i / 8) % n, (i / 8) / n);
            self.rep.counts.peak_link_load = load as u64;
            self.rep.counts.peak_link_distance =
                (x.abs_diff(self.sv[0] as usize)).max(y.abs_diff(self.sv[1] as usize)) as u32;
        }
        self.rep
    }
}

/// The busiest link, as (sender · 8 + port, messages): the first in that order among the
/// busiest. `load` is by receiving end ([`links::slot`]); a port leading out of the grid
/// carried nothing.
fn busiest_link(n: usize, load: &[AtomicU32]) -> Option<(usize, u32)> {
    (0..n * n * 8)
        .map(|i| {
            let (x, y) = ((i / 8 % n) as i64, (i / 8 / n) as i64);
            let (dx, dy) = Port::ALL[i % 8].delta();
            let (tx, ty) = (x + dx as i64, y + dy as i64);
            let inside = (0..n as i64).contains(&tx) && (0..n as i64).contains(&ty);
            let to = (ty * n as i64 + tx) as u32;
            (i, if inside { load[links::slot(to, (i % 8) as u8)].load(Relaxed) } else { 0 })
        })
        .max_by_key(|&(i, l)| (l, std::cmp::Reverse(i)))
}

/// What every piece of the compute phase reads.
struct StepCtx<'a, 'e, F: FracBits, const D: usize> {
    grid: &'a Grid<D>,
    env: &'a LightEnv<'e, F>,
    taken_ports: &'a [Taken],
    defer_pops: bool,
    tapping: bool,
    record: bool,
    may_sleep: bool,
    s_idx: usize,
    emitting: bool,
    n: usize,
    wave: bool,
    /// Messages offered per output buffer ([`Timing::link_rate`]).
    link_rate: usize,
}

impl<F: FracBits, const D: usize> StepCtx<'_, '_, F, D> {
    /// Step the visited cells `idx` of one piece (`tile`, from cell `base`).
    fn step_piece(&self, tile: &mut [HostLightCell<F>], base: usize, idx: &[u32], r: &mut PieceResult<F>) {
        let delta = ActivityDelta::new();
        for (k, &i) in idx.iter().enumerate() {
            if let Some(&j) = idx.get(k + AHEAD) {
                self.prefetch(&tile[j as usize - base], j as usize);
            }
            let c = &mut tile[i as usize - base];
            if self.defer_pops && pop_taken(c, i as usize, self.taken_ports) && !c.busy() {
                r.drained += 1;
            }
            let step = c.step(&self.grid.cells[i as usize], self.env, &delta);
            self.note(c, i, step, r);
            for p in c.out.busy_ports() {
                let (dx, dy) = p.delta();
                let to = (i as i64 + dy as i64 * self.n as i64 + dx as i64) as u32;
                for m in c.out.waiting(p).iter().take(self.link_rate) {
                    let key = if self.wave { m.beam.layer().0 } else { 0 };
                    r.offers[p.index()].push(Offer { to, key, from: i, port: p.index() as u8, msg: *m });
                }
            }
        }
        r.delta = delta.get();
    }

    /// Prefetch what stepping cell `j` (`cj`) reads first.
    fn prefetch(&self, cj: &HostLightCell<F>, j: usize) {
        prefetch_cell(cj, 4);
        prefetch_ends(&self.grid.cells[j].store);
        if self.defer_pops {
            // The buffers its pending pops will shift.
            let t = taken_mask(self.taken_ports[j].load(Relaxed));
            for p in Port::each(t) {
                prefetch(cj.out.slots(p));
            }
        }
    }

    /// Note cell `i`'s step: for the trace, the stall detector, the visits, and whether it is
    /// idle or asleep now.
    fn note(&self, c: &HostLightCell<F>, i: u32, step: Step, r: &mut PieceResult<F>) {
        if self.tapping {
            r.steps.push((i as usize, step));
        }
        // A sibling wait ends by itself within `hold` cycles: not a stall.
        r.any |= step == Step::Held;
        if step == Step::Processed {
            r.any = true;
            if self.record {
                r.seen.push((i as usize, c.last_z));
            }
        }
        if !c.busy() {
            r.quiet.push(i);
        } else if self.may_sleep && step == Step::Held && !c.out.any() && (i as usize != self.s_idx || !self.emitting) {
            if let Some(w) = c.held_wait() {
                r.sleep.push((i, w));
            }
        }
    }
}

/// What every piece of the link phase reads.
struct PullCtx<'a, 'e, F: FracBits> {
    env: &'a LightEnv<'e, F>,
    cycle: u64,
    stepping: Stepping,
    may_sleep: bool,
    lossless: bool,
    taken_ports: &'a [Taken],
    unacked_ports: &'a [AtomicU8],
    in_active: &'a [AtomicBool],
    asleep: &'a [AtomicU64],
    link_load: &'a [AtomicU32],
}

impl<F: FracBits> PullCtx<'_, '_, F> {
    /// Offer every message of one piece of receivers to its link, in link order.
    fn pull_piece<L: HostLink<F>>(&self, piece: LinkPiece<'_, HostLightCell<F>, F, L>, r: &mut PieceResult<F>) {
        let (tile, base, lists, links) = piece;
        let delta = ActivityDelta::new();
        let PieceResult { taken, woke, roused, order, took, any, .. } = r;
        link_order(&lists, order);
        for k in 0..order.len() {
            if let Some(&(p, j)) = order.get(k + AHEAD) {
                let a = &lists[p as usize][j as usize];
                prefetch_cell(&tile[a.to as usize - base], 1);
                prefetch(&self.taken_ports[a.from as usize]);
            }
            let (p, j) = order[k];
            let o = &lists[p as usize][j as usize];
            let at = o.to as usize - base;
            let link = &mut links[at * 8 + BACK[o.port as usize]];
            let mut rx = CellInbox {
                cell: &mut tile[at],
                fa: self.env.fa,
                merge: self.env.merge,
                tally: &delta,
                journal: &mut *took,
            };
            if !sure(link.ready(&rx)) {
                continue;
            }
            if self.may_sleep {
                *roused += self.rouse(rx.cell, o.to);
            }
            let sent = sure(link.send(self.cycle, &o.msg, &mut rx));
            *any |= sent.delivered || sent.acked;
            let bit = 1u8 << o.port;
            if sent.acked {
                self.taken_ports[o.from as usize].fetch_add(taken_one(o.port), Relaxed);
            } else if !self.lossless {
                self.unacked_ports[o.from as usize].fetch_or(bit, Relaxed);
            }
            if sent.delivered {
                *taken += 1;
                let l = &self.link_load[links::slot(o.to, o.port)];
                l.store(l.load(Relaxed) + 1, Relaxed);
                // Receivers are this piece's alone: a plain load and store.
                if self.stepping == Stepping::Active && !self.in_active[o.to as usize].load(Relaxed) {
                    self.in_active[o.to as usize].store(true, Relaxed);
                    woke.push(o.to);
                }
            }
        }
        r.delta = delta.get();
    }

    /// A sleeper a beam reaches first takes the held steps it missed (cycles c0 + 1 ..= cycle):
    /// the arrival is stamped with its true clock. 1 if `c` (cell `to`) was asleep.
    fn rouse(&self, c: &mut HostLightCell<F>, to: u32) -> usize {
        let c0 = self.asleep[to as usize].load(Relaxed);
        if c0 == AWAKE {
            return 0;
        }
        c.skip_held((self.cycle - c0) as u16);
        self.asleep[to as usize].store(AWAKE, Relaxed);
        1
    }
}

/// The grid's 8-block occupancy summary for the empty-frustum skip (what the OR-reduction of
/// every cell's own summary gives; what a cell trace carries).
pub fn occupancy_summary<const D: usize>(grid: &Grid<D>, rule: LitRule) -> FrustumSummary {
    summarise(grid, false, rule)
}

/// The summary of the grid's occupied voxels, or (`visible_only`) of each column's first
/// occupied voxel (the one its cell shades) for the hidden-voxel skip.
fn summarise<const B: usize, R: BlockRow, const D: usize>(
    grid: &Grid<D>,
    visible_only: bool,
    rule: LitRule,
) -> OccupancySummary<B, R> {
    let mut s = OccupancySummary::new(grid.n, grid.depth);
    for c in &grid.cells {
        let (x, y) = (c.x as u32, c.y as u32);
        match (visible_only, rule) {
            (false, LitRule::Exact) => {
                // A ray meets a triangle within one voxel of its voxels at the segment's ends,
                // and every point of a triangle lies in an occupied voxel: a beam can do
                // something only near an occupied voxel, or at its target.
                if let Some((lo, hi)) = active_span(c, grid.depth, rule) {
                    for (nx, ny) in neighbourhood(x, y, grid.n) {
                        s.mark_span(nx, ny, lo as u32, hi as u32);
                    }
                }
            }
            (false, _) => {
                s.mark_column(x, y, c.store.dexels());
                // Under the plane rule a ray may light the pixel in an empty voxel bracketing
                // the visible surface: a beam that can reach one is not empty.
                if let (LitRule::Plane, Some((lo, hi))) = (rule, active_span(c, grid.depth, rule)) {
                    s.mark_span(x, y, lo as u32, hi as u32);
                }
            }
            (true, LitRule::Thesis) => {
                if let Some(d) = c.store.dexels().first() {
                    s.mark_span(x, y, d.span.lo as u32, d.span.lo as u32);
                }
            }
            (true, LitRule::Plane | LitRule::Exact) => {
                if let Some((lo, hi)) = c.visible.map(|v| receiver_span(&v, grid.depth, rule)) {
                    s.mark_span(x, y, lo as u32, hi as u32);
                }
            }
        }
    }
    s
}

/// The voxels of a column where a ray may light its pixel, clipped to the grid: the two
/// bracketing its visible surface under the plane rule, and the one in front of them too under
/// exact occluders (where the target ray may arrive, `cell_core::receiver`).
fn receiver_span(v: &cell_core::visible::VisibleSurface, depth: u32, rule: LitRule) -> (u16, u16) {
    let top = depth as i64 - 1;
    let front = (rule == LitRule::Exact) as i64;
    let (lo, hi) = ((v.z_v as i64 - front).clamp(0, top), (v.z_v as i64 + 1).clamp(0, top));
    (lo as u16, hi as u16)
}

/// The depths of column `c` where a beam can do something besides passing: its occupied
/// voxels, and under the plane rule the two voxels bracketing its visible surface (where a ray
/// may light the pixel in an empty voxel), clipped to the grid. The skips keep every beam that
/// can reach one.
fn active_span<const D: usize>(c: &cell_core::cell::Cell<D>, depth: u32, rule: LitRule) -> Option<(u16, u16)> {
    let ds = c.store.dexels();
    let occupied = ds.first().zip(ds.last()).map(|(f, l)| (f.span.lo, l.span.hi));
    let top = depth as i64 - 1;
    // Under exact occluders a segment ending in a voxel next to an occupied one may meet a
    // triangle: the occupied span grows by one voxel each way.
    let occupied = match rule {
        LitRule::Exact => occupied.map(|(lo, hi)| (lo.saturating_sub(1), (hi as i64 + 1).min(top) as u16)),
        _ => occupied,
    };
    let bracket = match rule {
        LitRule::Thesis => None,
        LitRule::Plane | LitRule::Exact => c.visible.map(|v| receiver_span(&v, depth, rule)),
    };
    match (occupied, bracket) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, b) => a.or(b),
    }
}

/// The bounding box of the grid's occupied voxels, and under the plane rule of the voxels that
/// bracket its visible surfaces (`active_span`); `lo > hi` when there are none.
pub fn occupied_box<const D: usize>(grid: &Grid<D>, rule: LitRule) -> OccupiedBox {
    let mut b = OccupiedBox { lo: [u16::MAX; 3], hi: [0; 3] };
    for c in &grid.cells {
        if let Some((lo, hi)) = active_span(c, grid.depth, rule) {
            // Exact occluders: one column more each way ([`active_span`]).
            let g = (rule == LitRule::Exact) as u16;
            let last = grid.n.saturating_sub(1) as u16;
            b.lo = [b.lo[0].min(c.x.saturating_sub(g)), b.lo[1].min(c.y.saturating_sub(g)), b.lo[2].min(lo)];
            b.hi = [b.hi[0].max((c.x + g).min(last)), b.hi[1].max((c.y + g).min(last)), b.hi[2].max(hi)];
        }
    }
    b
}

/// Column (x, y) and its (up to) eight neighbours inside an n × n grid.
fn neighbourhood(x: u32, y: u32, n: u32) -> impl Iterator<Item = (u32, u32)> {
    let (x0, x1, y0, y1) = (x.saturating_sub(1), (x + 1).min(n - 1), y.saturating_sub(1), (y + 1).min(n - 1));
    (y0..=y1).flat_map(move |ny| (x0..=x1).map(move |nx| (nx, ny)))
}

/// A source at a position in voxel units (1/16-voxel lattice), checked to lie in the grid.
pub fn source_at(id: usize, pos: [f64; 3], n: u32) -> Result<Source> {
    let lim = n as f64 - 1.0;
    if pos.iter().any(|p| !p.is_finite() || *p < 0.0 || *p > lim) {
        bail!("light {} at voxel position {:?} is outside the grid (0 ..= {lim} on each axis)", id + 1, pos);
    }
    let q = pos.map(|p| cell_core::beam::SourceCoord::from_num((p * 16.0).round() / 16.0));
    Ok(Source::new(SourceId(id as u16), q))
}

#[cfg(test)]
mod tests {
    use super::*;
    use cell_core::beam::frac::U0;
    use cell_core::beam::SourceCoord;
    use proptest::prelude::*;

    /// Offers as the compute pass makes them: senders in increasing order, each with the ports
    /// of `mask` (receivers outside an `n` × `n` grid left out), one list per port.
    fn offers(n: u32, senders: &[(u32, u8, u32)]) -> [Vec<Offer<U0>>; 8] {
        let src = Source::new(SourceId(0), [SourceCoord::from_num(0.0); 3]);
        let far = FarDistance::<U0>::new(n).unwrap();
        let msg = BeamMsg::new(Beam::initial(&src, Direction::PosX, far), 0);
        let mut lists: [Vec<Offer<U0>>; 8] = Default::default();
        for &(from, mask, key) in senders {
            let (x, y) = ((from % n) as i64, (from / n) as i64);
            for p in Port::each(mask) {
                let (dx, dy) = p.delta();
                let (tx, ty) = (x + dx as i64, y + dy as i64);
                if (0..n as i64).contains(&tx) && (0..n as i64).contains(&ty) {
                    let to = (ty * n as i64 + tx) as u32;
                    // Keys from a few values, so that ties between senders are common.
                    let key = key.wrapping_mul(p.index() as u32 + 3) % 4;
                    lists[p.index()].push(Offer { to, key, from, port: p.index() as u8, msg });
                }
            }
        }
        lists
    }

    /// A source whose voxel lies outside the grid, or rays from the light with a FIFO too small
    /// for the source cell's first split, are refused before any cell is touched.
    #[test]
    fn light_runs_refuse_bad_sources() {
        let cfg = crate::config::plane_rule();
        let at = |p: [f64; 3]| Source::new(SourceId(0), p.map(SourceCoord::from_num));
        assert!(check_light_run::<U0>(8, &[at([7.0, 7.0, 7.0])], &cfg).is_ok());
        for outside in [[7.5, 0.0, 0.0], [0.0, -0.5625, 0.0], [0.0, 0.0, -1.0]] {
            let err = check_light_run::<U0>(8, &[at(outside)], &cfg).unwrap_err().to_string();
            assert!(err.contains("outside the 8 × 8 grid"), "{outside:?}: {err}");
        }
        let light = at([3.5, 3.0, 3.0]).with_origin(cell_core::beam::Origin::Light);
        let small = LightConfig { fa: cell_core::light::MIN_FA_FROM_LIGHT - 1, ..cfg };
        assert!(check_light_run::<U0>(8, &[light], &small).unwrap_err().to_string().contains("too small"));
        let enough = LightConfig { fa: cell_core::light::MIN_FA_FROM_LIGHT, ..cfg };
        assert!(check_light_run::<U0>(8, &[light], &enough).is_ok());
    }

    proptest! {
        /// A [`Taken`] value holds up to 15 messages per port: adding `taken_one` per message
        /// and reading back gives each port's count, and the mask of the ports that had any.
        #[test]
        fn taken_counts_add_up(counts in proptest::array::uniform8(0u32..=3)) {
            let t = Taken::new(0);
            for (p, &k) in counts.iter().enumerate() {
                for _ in 0..k {
                    t.fetch_add(taken_one(p as u8), Relaxed);
                }
            }
            let got: Vec<(usize, u32)> = taken_counts(t.load(Relaxed)).map(|(p, k)| (p.index(), k)).collect();
            let want: Vec<(usize, u32)> = counts.iter().copied().enumerate().filter(|&(_, k)| k > 0).collect();
            prop_assert_eq!(got, want);
            let mask = counts.iter().enumerate().fold(0u8, |m, (p, &k)| m | (u8::from(k > 0) << p));
            prop_assert_eq!(taken_mask(t.load(Relaxed)), mask);
        }

        /// The merge gives exactly the order of a sort of all offers by (receiver, key,
        /// sender), and the receiver cut hands every offer, once, to the piece owning its
        /// receiver.
        #[test]
        fn link_order_is_the_sorted_order(
            n in 1u32..12,
            picks in proptest::collection::btree_map(0u32..144, (any::<u8>(), any::<u32>()), 0..60),
            cut_picks in proptest::collection::btree_set(0u32..160, 0..6),
        ) {
            let senders: Vec<(u32, u8, u32)> =
                picks.into_iter().filter(|&(c, _)| c < n * n).map(|(c, (m, k))| (c, m, k)).collect();
            let mut lists = offers(n, &senders);
            let mut expect: Vec<(u32, u32, u32, u8)> =
                lists.iter().flatten().map(|o| (o.to, o.key, o.from, o.port)).collect();
            expect.sort_unstable();
            let mut order = Vec::new();
            let whole_lists = whole(&mut lists);
            link_order(&whole_lists, &mut order);
            let got: Vec<(u32, u32, u32, u8)> = order
                .iter()
                .map(|&(p, j)| {
                    let o = &whole_lists[p as usize][j as usize];
                    (o.to, o.key, o.from, o.port)
                })
                .collect();
            prop_assert_eq!(&got, &expect);

            let mut cells: Vec<u32> = (0..n * n).collect();
            let mut links: Vec<u32> = (0..n * n * 8).collect();
            let cuts: Vec<u32> = cut_picks.into_iter().collect();
            let mut seen = Vec::new();
            for (tile, base, piece, tile_links) in by_receiver(&mut cells, &mut links, &mut lists, &cuts) {
                prop_assert_eq!(tile_links.len(), tile.len() * 8);
                prop_assert_eq!(tile_links.first().copied(), tile.first().map(|&c| c * 8));
                for o in piece.iter().flat_map(|l| l.iter()) {
                    prop_assert_eq!(tile[o.to as usize - base], o.to);
                    seen.push((o.to, o.key, o.from, o.port));
                }
            }
            seen.sort_unstable();
            prop_assert_eq!(seen, expect);
        }
    }
}
