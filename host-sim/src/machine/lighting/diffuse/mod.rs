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
//! counter ([`cell_core::light::Activity`]) detects exactly. Only cells holding beams are visited. A cycle in
//! which beams exist but nothing moves is a deadlock: reported as an error, never a hang.
//!
//! Here: a run's settings ([`LightConfig`]), its results ([`Lighting`], [`SourceReport`]) and
//! the entry points; `cycle` runs one source's cycles, `summary` builds what the skips test
//! beams against.

use anyhow::{bail, Result};
use cell_core::beam::{Beam, FarDistance, FracBits, Origin, Source, SourceId, SplitOrder};
use cell_core::light::RaySink;
use cell_core::light::{
    BeamMsg, LightCell, LightCounters, LightEnv, LitRuns, OccupiedBox, Policy, SourceMask, SubBeamBounds,
};
use cell_core::lit::LitRule;
use cell_core::occluder::ColumnOccluders;
use cell_core::units::Coord;
use cell_core::visibility::Visibility;

use cell_core::link::PerfectLink;

use crate::machine::grid::capacity::{HostLightCell, FA_CAP, LIT_CAP};
use crate::machine::grid::{Grid, LightGrid};
use crate::machine::lighting::occluders::{SourceOccluders, CONTACT_EXCHANGE_CYCLES};
use crate::machine::lighting::timing::Timing;
use crate::machine::links::faults::{fault_counts, FaultCounts, FaultInjector, FaultTally, LinkFaults, Wire};
use crate::machine::links::tap::{Tap, Tracer};
use crate::machine::links::{GridLinks, HostLink};

mod cycle;
mod offer;
mod oracle;
mod share;
mod shortcut;
mod summary;
mod tiles;

use cycle::diffuse_one;
pub(crate) use cycle::initial_beams;
pub use oracle::OracleSkip;
pub use share::{counts_from_bytes, counts_to_bytes, decode_part, encode_part, merge_parts, Share};
use shortcut::Shortcut;
pub use summary::{occupancy_summary, occupied_box, FrustumBlocks, Summary};
pub use tiles::{diffuse_in_tiles, diffuse_tile, merge_tiles, Halo, ThreadHalo, Tile, Traffic};

/// Default of [`LightConfig::stall_cycles`]: a fault-free machine that cannot move for one
/// cycle is deadlocked; under link faults a few cycles of bad luck are normal.
pub const DEFAULT_STALL_CYCLES: u64 = 64;

/// Lighting-phase settings. No default: a run starts from a named preset
/// ([`crate::config::Preset`]: what each job runs) or says what it tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightConfig {
    /// Fraction bits f of the far-plane ray offsets (§4.3.4: rays on a lattice 2^−f of a
    /// voxel at the far plane). The cells are compiled once per supported f
    /// ([`cell_core::with_frac_bits`]); the run picks that build here, and nothing outside the
    /// lighting run is generic over it.
    pub frac_bits: u32,
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
    /// and retransmission ([`crate::machine::links::faults`]); `None`: perfect links.
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
    /// The oracle skip ([`OracleSkip`], needs exact occluders and `lit_visible_only`): the host
    /// drops every beam that carries no pixel's target ray to a later layer — not a cell's rule
    /// (a cell would need every target ray through its column), a measure of the work no pixel
    /// needs. Same image; fewer beams, messages and cycles.
    pub oracle_skip: OracleSkip,
    /// Stop each source's diffusion after this many cycles, beams still in flight (a snapshot
    /// of the grid: which cells hold beams, which voxels were visited; the thesis's time-lapse,
    /// §4.4.3). A source that ran until then is not checked for conservation. `None`: run
    /// to quiescence.
    pub stop_at: Option<u64>,
    /// How a pixel's visibility of a light is decided ([`Visibility`], exact occluders only):
    /// its target ray (the default), or the share of its target voxel's rays that arrive,
    /// counted by the cells (same beams, cycles and messages; other pixels).
    pub visibility: Visibility,
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

/// Host wall time of each phase of the diffusion loop (seconds, summed over sources): where the
/// simulator's time goes. Not simulated — it differs from run to run and with the threads, so
/// it is kept out of [`SourceReport`] and compared by no test. `step` and `links` run in
/// parallel over the grid's pieces; the others are serial (one thread works, the rest wait).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PhaseSeconds {
    /// Per source, before its first cycle: occluder tables, environment, counter snapshot.
    pub setup: f64,
    /// Initial beams handed to the source cell.
    pub emit: f64,
    /// Every active cell's step (parallel).
    pub step: f64,
    /// The steps' results gathered in order: offers, idle cells, beam counts (serial).
    pub gather: f64,
    /// Offers cut by receiver (serial) and pulled through the links (parallel), tallied.
    pub links: f64,
    /// Senders drop what was taken.
    pub pop: f64,
    /// The next cycle's active list, sleepers, the stall check (serial).
    pub next: f64,
    /// Per source, after its last cycle: per-cell counters summed, conservation checked.
    pub tally: f64,
}

impl PhaseSeconds {
    /// Every phase's seconds, with its name, in loop order.
    pub fn named(&self) -> [(&'static str, f64); 8] {
        let p = self;
        [
            ("setup", p.setup),
            ("emit", p.emit),
            ("step", p.step),
            ("gather", p.gather),
            ("links", p.links),
            ("pop", p.pop),
            ("next", p.next),
            ("tally", p.tally),
        ]
    }

    /// The sum over phases.
    pub fn total(&self) -> f64 {
        self.named().iter().map(|(_, s)| s).sum()
    }
}

/// A stopwatch that adds the time since its last lap to a phase.
struct Lap(std::time::Instant);

impl Lap {
    fn start() -> Self {
        Lap(std::time::Instant::now())
    }

    /// Add the time since the last lap to `phase`; start the next lap.
    fn lap(&mut self, phase: &mut f64) {
        let now = std::time::Instant::now();
        *phase += (now - self.0).as_secs_f64();
        self.0 = now;
    }
}

/// The error for an f no cell build exists for.
pub fn unsupported_frac_bits(f: u32) -> anyhow::Error {
    anyhow::anyhow!("--frac-bits {f} is not supported (0..=8, 10, 12, 16, 20, 24)")
}

/// `$body` with `$F` the fraction-bit type of `f`, or the error naming the supported values
/// (the one place the host picks a build of the cells for a run-time f).
macro_rules! with_f {
    ($f:expr, $F:ident => $body:expr) => {{
        let f: u32 = $f;
        cell_core::with_frac_bits!(f, $F => $body)
            .unwrap_or_else(|| Err($crate::machine::lighting::diffuse::unsupported_frac_bits(f)))
    }};
}
pub(crate) use with_f;

/// Bytes of a beam message and of a host lighting cell under f (`None`: unsupported f).
pub fn light_cell_bytes(f: u32) -> Option<(usize, usize)> {
    cell_core::with_frac_bits!(f, F => (std::mem::size_of::<BeamMsg<F>>(), std::mem::size_of::<HostLightCell<F>>()))
}

/// What one cell's lighting left once the run ended: its lit store, the sources lighting its
/// visible surface, its counters (the FIFOs and output buffers of the run are gone; only how
/// many beams its FIFO still held is kept, for snapshots taken with `stop_at`).
#[derive(Clone, Debug)]
pub struct LitColumn {
    /// Column index.
    pub x: Coord,
    /// Row index.
    pub y: Coord,
    /// Lit voxels of the column.
    pub lit: LitRuns<LIT_CAP>,
    /// The sources that light the column's visible surface (the plane and exact rules' image).
    pub visible_lit: SourceMask,
    /// The cell's counters.
    pub counters: LightCounters,
    /// Beams waiting in the FIFO when the run stopped (0 after a run to quiescence).
    pub queued: usize,
}

impl LitColumn {
    /// What `c` leaves.
    pub(crate) fn of<F: FracBits>(c: &HostLightCell<F>) -> Self {
        LitColumn {
            x: c.x,
            y: c.y,
            lit: c.lit.clone(),
            visible_lit: c.visible_lit,
            counters: c.counters,
            queued: c.fifo.len(),
        }
    }
}

/// The lit columns `cells` leave.
pub(crate) fn lit_columns<F: FracBits>(cells: &[HostLightCell<F>]) -> Vec<LitColumn> {
    cells.iter().map(LitColumn::of).collect()
}

/// The lighting state of the whole grid after diffusion.
pub struct Lighting {
    /// Grid side.
    pub n: u32,
    /// What each cell's lighting left, row-major.
    pub cells: Vec<LitColumn>,
    /// One report per source, in diffusion order.
    pub reports: Vec<SourceReport>,
    /// Voxels where a beam was processed, index `(y·n + x)·depth + z` (with `record_visits`).
    pub visited: Option<Vec<bool>>,
    /// What the faulty links did (with `faults`).
    pub link_faults: Option<FaultCounts>,
    /// The lit rule the cells applied.
    pub rule: LitRule,
    /// Host time per phase of the loop (not simulated).
    pub phases: PhaseSeconds,
    /// Per source (diffusion order), per column (row-major), the weight of the light for its
    /// pixel (0 ..= 255, [`Visibility::weight`]) when the cells counted their target voxels'
    /// rays; `None` under [`Visibility::Target`].
    pub weights: Option<Vec<Vec<u8>>>,
}

impl Lighting {
    /// Sources that lit voxel (x, y, z).
    pub fn mask(&self, x: u32, y: u32, z: u16) -> SourceMask {
        self.cells[(y * self.n + x) as usize].lit.mask_at(z)
    }

    /// Sources that lit the visible surface of column (x, y) (the plane rule).
    pub fn visible_mask(&self, x: u32, y: u32) -> SourceMask {
        self.cells[(y * self.n + x) as usize].visible_lit
    }

    /// The weight of each source for the pixel of column (x, y) (0 ..= 255), when the cells
    /// counted rays ([`Lighting::weights`]).
    pub fn pixel_weights(&self, x: u32, y: u32) -> Option<Vec<u8>> {
        let i = (y * self.n + x) as usize;
        self.weights.as_ref().map(|w| w.iter().map(|s| s.get(i).copied().unwrap_or(0)).collect())
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

/// What a run records besides its results: visited voxels, cell traces.
struct Recording<'a> {
    visited: Option<&'a mut [bool]>,
    tap: Option<&'a mut Tap>,
}

/// Diffuse every source over the loaded grid. Source positions are in voxel units (already
/// validated to lie inside the grid). `progress(source, cycle)` is called now and then.
///
/// Not generic: the scheduler is built once per f and link stack here, in this crate, and a
/// caller (a test crate, a bench) compiles none of it again.
pub fn diffuse(
    grid: &LightGrid,
    sources: &[Source],
    cfg: &LightConfig,
    mut progress: impl FnMut(usize, u64),
) -> Result<Lighting> {
    diffuse_tapped(grid, sources, cfg, None, &mut progress)
}

/// [`diffuse`] on a grid of another dexel capacity `D` (each capacity compiles the scheduler
/// once more, in the caller's crate).
pub fn diffuse_in<const D: usize>(
    grid: &Grid<D>,
    sources: &[Source],
    cfg: &LightConfig,
    mut progress: impl FnMut(usize, u64),
) -> Result<Lighting> {
    diffuse_at(grid, sources, cfg, Share::ALL, None, &mut progress)
}

/// [`diffuse`] of one share of the sources only ([`Share`]): the others are skipped, each
/// source keeping its index (its bit in the masks, its report's `source`). The parts of every
/// share of a run, put together by [`merge_parts`], are the whole run's [`Lighting`] (sources
/// share nothing but the lit stores and the counters, which add up: see [`Share::spreads`] for
/// the settings under which they share more).
pub fn diffuse_share(
    grid: &LightGrid,
    sources: &[Source],
    cfg: &LightConfig,
    share: Share,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<Lighting> {
    diffuse_at(grid, sources, cfg, share, None, progress)
}

/// [`diffuse`], recording what the cells watched by `tap` receive and send.
pub fn diffuse_tapped(
    grid: &LightGrid,
    sources: &[Source],
    cfg: &LightConfig,
    tap: Option<&mut Tap>,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<Lighting> {
    diffuse_at(grid, sources, cfg, Share::ALL, tap, progress)
}

/// The cells' build for `cfg.frac_bits`, picked once for a grid of capacity `D`.
fn diffuse_at<const D: usize>(
    grid: &Grid<D>,
    sources: &[Source],
    cfg: &LightConfig,
    share: Share,
    tap: Option<&mut Tap>,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<Lighting> {
    with_f!(cfg.frac_bits, F => diffuse_cells::<F, D>(grid, sources, cfg, share, tap, None, progress).map(|(l, _)| l))
}

/// [`diffuse_tapped`] under f = `F`, also returning the cells themselves (what a cell trace's
/// digest reads).
///
/// The links are chosen here, once per run: perfect links, or each behind a fault injector
/// (`cfg.faults`), each traced when `tap` records. Every source then runs the same scheduler,
/// generic over the links ([`crate::machine::links`]). `progress` is behind `dyn`: the
/// scheduler is compiled once per f and link stack, not once more per caller's closure.
pub(crate) fn diffuse_cells<F: FracBits, const D: usize>(
    grid: &Grid<D>,
    sources: &[Source],
    cfg: &LightConfig,
    share: Share,
    tap: Option<&mut Tap>,
    tile: Option<&mut dyn Halo>,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<(Lighting, Vec<HostLightCell<F>>)> {
    if cfg.frac_bits != F::U32 {
        bail!("a run configured for f = {} was started with the cells of f = {}", cfg.frac_bits, F::U32);
    }
    let n = grid.n;
    // A tile holds its band's cells and links only.
    let band = tile.as_ref().map_or(0..n * n, |h| h.tile().cells(n));
    let far = check_light_run::<F>(n, band.len() as u64, sources, cfg)?;
    let cells = idle_cells(n, band.clone());
    let occupied = occupied_box(grid, cfg.rule);
    let frustum = frustum_summary(grid, cfg, tap.is_some())?;
    check_recording(cfg)?;
    cfg.timing.check(cfg.fa, cfg.faults.is_none() && tap.is_none())?;
    if share != Share::ALL && !Share::spreads(cfg, tap.is_some()) {
        bail!("this lighting run's sources share more than the lit stores (link faults, a snapshot, visited voxels or a cell trace): it cannot be split");
    }
    let run = AllSources { grid, sources, cfg, far, occupied, frustum: frustum.as_ref(), shot: None, share };
    let wire = cfg.faults.map(|faults| Wire { faults, far: far.get() });
    match (&wire, tap) {
        (None, None) => run.diffuse(cells, GridLinks::into_cells(n, band, |_| PerfectLink), None, tile, progress),
        (Some(w), None) => {
            let links = GridLinks::into_cells(n, band, |id| FaultInjector::new(PerfectLink, w, id));
            run.diffuse(cells, links, None, tile, progress)
        }
        (None, Some(t)) => {
            let links = GridLinks::into_cells(n, band, |id| Tracer::new(PerfectLink, id));
            run.diffuse(cells, links, Some(t), tile, progress)
        }
        (Some(w), Some(t)) => {
            let links = GridLinks::into_cells(n, band, |id| Tracer::new(FaultInjector::new(PerfectLink, w, id), id));
            run.diffuse(cells, links, Some(t), tile, progress)
        }
    }
}

/// The idle lighting cells `cells` (row-major indices) of an n × n grid.
fn idle_cells<F: FracBits>(n: u32, cells: std::ops::Range<u32>) -> Vec<HostLightCell<F>> {
    let mut out: Vec<HostLightCell<F>> = Vec::with_capacity(cells.len());
    out.extend(cells.map(|i| LightCell::new((i % n) as u16, (i / n) as u16)));
    out
}

/// One radiosity shot (radiosity thesis §3.4; `machine::shooting::shots` drives it): the diffusion of
/// one source whose initial beams are `initial` (the shooting patch's front hemisphere) instead
/// of the six full faces, every processed beam's absorbed and departed rays reported to `rays`.
/// The thesis's lit rule only (its absorbed ray sets are whole beams), perfect links.
pub(crate) fn diffuse_shot<F: FracBits, const D: usize>(
    grid: &Grid<D>,
    source: &Source,
    initial: &[Beam<F>],
    cfg: &LightConfig,
    rays: &dyn RaySink<F>,
    mut progress: impl FnMut(usize, u64),
) -> Result<Lighting> {
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
    let far = check_light_run::<F>(grid.n, grid.n as u64 * grid.n as u64, sources, cfg)?;
    let occupied = occupied_box(grid, cfg.rule);
    let frustum = frustum_summary(grid, cfg, false)?;
    let shot = Some(Shot { initial, rays });
    let run = AllSources { grid, sources, cfg, far, occupied, frustum: frustum.as_ref(), shot, share: Share::ALL };
    let (n, cells) = (grid.n, idle_cells(grid.n, 0..grid.n * grid.n));
    run.diffuse(cells, GridLinks::new(n, |_| PerfectLink), None, None, &mut progress).map(|(l, _)| l)
}

/// What a radiosity shot changes in a diffusion ([`diffuse_shot`]).
#[derive(Clone, Copy)]
struct Shot<'a, F: FracBits> {
    initial: &'a [Beam<F>],
    rays: &'a dyn RaySink<F>,
}

/// The far distance of an n × n grid, once the run's sources, FIFO limit and memory (for
/// `cells` lighting cells: the grid's, or a tile's band) are checked.
pub(crate) fn check_light_run<F: FracBits>(
    n: u32,
    cells: u64,
    sources: &[Source],
    cfg: &LightConfig,
) -> Result<FarDistance<F>> {
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
    crate::machine::grid::limits::check_cells_memory(
        "grid of lighting cells",
        n,
        cells,
        std::mem::size_of::<HostLightCell<F>>(),
    )?;
    Ok(far)
}

/// The summary the empty-frustum and hidden-voxel skips test against, if either is on.
fn frustum_summary<const D: usize>(grid: &Grid<D>, cfg: &LightConfig, tapped: bool) -> Result<Option<Summary>> {
    if cfg.skip_hidden && !cfg.lit_visible_only {
        bail!("the hidden-voxel skip drops the light of hidden voxels: use it with --lit-visible-only");
    }
    if cfg.oracle_skip != OracleSkip::Off && (!cfg.rule.needs_triangles() || !cfg.lit_visible_only) {
        bail!("--oracle-skip reads the pixels' target rays: it needs exact occluders and --lit-visible-only");
    }
    let frustum =
        (cfg.skip_hidden || cfg.skip_frustum).then(|| Summary::of(grid, cfg.frustum_blocks, cfg.skip_hidden, cfg.rule));
    if tapped && frustum.as_ref().is_some_and(|s| s.traceable().is_none()) {
        bail!("a cell trace carries the 8 × 8 × 8 frustum summary: record with --frustum-blocks 8");
    }
    Ok(frustum)
}

/// Refuse link delays the stall detector would take for stalls. (A trace's light record
/// carries the lit store, visible-only or full: both are traced.)
fn check_recording(cfg: &LightConfig) -> Result<()> {
    if let Some(f) = cfg.faults.filter(|f| f.delay_ppm > 0 && f.delay_cycles as u64 >= cfg.stall_cycles.max(1)) {
        bail!(
            "--link-faults delay-cycles={} must be below --stall-cycles {}: a frame held on the wire is not progress",
            f.delay_cycles,
            cfg.stall_cycles
        );
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
    /// The sources this run diffuses (the others are skipped).
    share: Share,
}

impl<'a, F: FracBits, const D: usize> AllSources<'a, F, D> {
    /// The sources of a run on `grid` whose cells are told no frustum summary (the
    /// asynchronous boards, [`crate::machine::lighting::boards`]: every cell's environment comes
    /// from [`AllSources::env`] as here).
    pub(crate) fn plain(grid: &'a Grid<D>, sources: &'a [Source], cfg: &'a LightConfig, far: FarDistance<F>) -> Self {
        let occupied = occupied_box(grid, cfg.rule);
        AllSources { grid, sources, cfg, far, occupied, frustum: None, shot: None, share: Share::ALL }
    }

    /// Diffuse the sources one after another over `cells`, through `links`.
    fn diffuse<L: HostLink<F> + FaultTally>(
        &self,
        mut cells: Vec<HostLightCell<F>>,
        mut links: GridLinks<L>,
        mut tap: Option<&mut Tap>,
        mut tile: Option<&mut dyn Halo>,
        progress: &mut dyn FnMut(usize, u64),
    ) -> Result<(Lighting, Vec<HostLightCell<F>>)> {
        let (grid, cfg) = (self.grid, self.cfg);
        // The columns of `cells`: the whole grid's, or a tile's band.
        let origin = cells.first().map_or(0, |c| c.y as usize * grid.n as usize + c.x as usize);
        let columns = origin..origin + cells.len();
        let order = SplitOrder::default();
        let traced = self.frustum.and_then(Summary::traceable);
        let mut reports = Vec::new();
        let mut visited = cfg.record_visits.then(|| vec![false; (grid.n * grid.n * grid.depth) as usize]);
        let mut phases = PhaseSeconds::default();
        // The summary's occupied blocks, the same for every source: what each source's
        // frustum shortcut is filled from (not for a radiosity shot's few rays).
        let blocks = self.frustum.filter(|_| self.shot.is_none()).map(|s| (s, s.occupied_blocks()));
        let mut weights =
            (cfg.visibility.counts_rays() && cfg.rule.needs_triangles()).then(|| vec![Vec::new(); self.sources.len()]);
        for (si, src) in self.sources.iter().enumerate().filter(|(si, _)| self.share.takes(*si)) {
            let mut lap = Lap::start();
            let occluders = cfg.rule.needs_triangles().then(|| {
                let o = SourceOccluders::new(self.grid, src, self.far);
                match cfg.visibility.counts_rays() {
                    true => o.counting_rays(self.grid, src, self.far),
                    false => o,
                }
            });
            let mut env = self.env(src, si, &order, occluders.as_ref().map(|o| o as &dyn ColumnOccluders));
            // The host's table of the frustum test's commonest answer (same answers, faster).
            let shortcut = blocks.as_ref().and_then(|(s, b)| Shortcut::new(s.test(), src, self.far, b));
            if let Some(s) = &shortcut {
                env.frustum = Some(s);
            }
            // The oracle skip, around whichever frustum test the cells run.
            let needed = occluders
                .as_ref()
                .and_then(|o| oracle::Needed::new(cfg.oracle_skip, env.frustum, o, src, self.far, grid));
            if let Some(t) = &needed {
                env.frustum = Some(t);
            }
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
            lap.lap(&mut phases.setup);
            let edge = tile.as_deref_mut().map(|h| h as &mut dyn Halo);
            let mut rep =
                diffuse_one(grid, cells, links, (src, initial), si, &env, cfg, dead, rec, edge, &mut phases, {
                    &mut |c| progress(si, c)
                })?;
            lap = Lap::start();
            rep.position = src.pos.map(|p| p.to_num::<f64>());
            add_cell_counts(&mut rep, cells, &before);
            if let Some(h) = tile.as_deref_mut() {
                // Each tile counted its own cells and links: the whole grid's report.
                rep = tiles::whole_report(h, rep)?;
            }
            if let Some(w) = weights.as_mut() {
                w[si] = pixel_weights(cfg.visibility, columns.clone(), occluders.as_ref());
            }
            if let Some(o) = &occluders {
                // The contact exchange ran before the beams left.
                rep.counts.cycles += CONTACT_EXCHANGE_CYCLES;
                rep.counts.messages += o.exchange_messages();
            }
            if cfg.stop_at.is_none_or(|t| rep.counts.cycles < t) {
                check_conservation(si, &rep.counts)?;
            }
            reports.push(rep);
            lap.lap(&mut phases.tally);
        }
        let link_faults = fault_counts(links.all());
        let lit = lit_columns(&cells);
        Ok((Lighting { n: grid.n, cells: lit, reports, visited, link_faults, rule: cfg.rule, phases, weights }, cells))
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

/// The weight of each column of `columns` (row-major indices) for the source just diffused:
/// what its cell makes of the candidate rays its target voxel received under `visibility`; 0
/// without a target.
fn pixel_weights(
    visibility: Visibility,
    columns: std::ops::Range<usize>,
    occluders: Option<&SourceOccluders<'_>>,
) -> Vec<u8> {
    let (voxels, arrived) = occluders.map_or((&[][..], Vec::new()), |o| (o.target_voxels(), o.arrived_rays()));
    columns
        .map(|i| {
            voxels
                .get(i)
                .and_then(Option::as_ref)
                .map_or(0, |tv| visibility.weight(arrived[i], tv.total, tv.contact_shadow))
        })
        .collect()
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

    /// A source whose voxel lies outside the grid, or rays from the light with a FIFO too small
    /// for the source cell's first split, are refused before any cell is touched.
    #[test]
    fn light_runs_refuse_bad_sources() {
        let cfg = crate::config::plane_rule();
        let at = |p: [f64; 3]| Source::new(SourceId(0), p.map(SourceCoord::from_num));
        assert!(check_light_run::<U0>(8, 64, &[at([7.0, 7.0, 7.0])], &cfg).is_ok());
        for outside in [[7.5, 0.0, 0.0], [0.0, -0.5625, 0.0], [0.0, 0.0, -1.0]] {
            let err = check_light_run::<U0>(8, 64, &[at(outside)], &cfg).unwrap_err().to_string();
            assert!(err.contains("outside the 8 × 8 grid"), "{outside:?}: {err}");
        }
        let light = at([3.5, 3.0, 3.0]).with_origin(cell_core::beam::Origin::Light);
        let small = LightConfig { fa: cell_core::light::MIN_FA_FROM_LIGHT - 1, ..cfg };
        assert!(check_light_run::<U0>(8, 64, &[light], &small).unwrap_err().to_string().contains("too small"));
        let enough = LightConfig { fa: cell_core::light::MIN_FA_FROM_LIGHT, ..cfg };
        assert!(check_light_run::<U0>(8, 64, &[light], &enough).is_ok());
    }
}
