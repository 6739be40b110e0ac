//! The lighting phase on the whole grid (thesis ch. 4): sources diffused one after another by
//! beam subdivision, cycle by cycle.
//!
//! Cycle model (SPEC §1): in each cycle
//! 1. the source emitter hands the next of the source's six initial beams (x and y first, then
//!    z, §4.4.3) to the source cell if its FIFO has room;
//! 2. **compute**: every cell with a beam runs [`LightCell::step`] — at most one beam each;
//! 3. **links**: every non-empty output buffer moves its front message to the neighbour's FIFO
//!    if that FIFO has room (credit-based flow control; one message per link and direction per
//!    cycle). Senders are served in row-major order, so a FIFO that several neighbours feed in
//!    the same cycle fills deterministically.
//!
//! A message produced in cycle t is processed in cycle t + 1 at the earliest: one hop per cycle.
//! `T` (cycles) counts cycles until the last beam is consumed, which the global activity
//! counter ([`Activity`]) detects exactly. Only cells holding beams are visited. A cycle in
//! which beams exist but nothing moves is a deadlock: reported as an error, never a hang.

use anyhow::{bail, Result};
use cell_core::beam::{Beam, Direction, FarDistance, FracBits, Source, SourceId, SplitOrder};
use cell_core::light::{Activity, BeamMsg, LightCell, LightCounters, LightEnv, Policy, Port, SourceMask, Step};

use crate::grid::Grid;
use crate::trace::Tap;

/// FIFO capacity compiled into the host's cells (the run-time `--fa` may be smaller).
pub const FA_CAP: usize = 64;
/// Messages an output buffer holds: a ±x/±y beam sends up to 3 sub-beams through one link.
pub const OB_CAP: usize = 3;
/// Lit runs per column.
pub const LIT_CAP: usize = 32;

/// The host's lighting cell type.
pub type HostLightCell<F> = LightCell<F, FA_CAP, OB_CAP, LIT_CAP>;

/// Lighting-phase settings.
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
}

/// Counters of a diffusion run (SPEC §7): one source's, or the sum over sources.
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
    /// Largest FIFO occupancy of any cell.
    pub peak_fifo: u16,
    /// Sum over cells of cycles with beams waiting and none processable.
    pub blocked_cell_cycles: u64,
    /// Most cells active in one cycle.
    pub peak_active_cells: u64,
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
        self.peak_fifo = self.peak_fifo.max(o.peak_fifo);
        self.blocked_cell_cycles += o.blocked_cell_cycles;
        self.peak_active_cells = self.peak_active_cells.max(o.peak_active_cells);
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
}

impl<F: FracBits> Lighting<F> {
    /// Sources that lit voxel (x, y, z).
    pub fn mask(&self, x: u32, y: u32, z: u16) -> SourceMask {
        self.cells[(y * self.n + x) as usize].lit.mask_at(z)
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
pub fn diffuse_tapped<F: FracBits, const D: usize>(
    grid: &Grid<D>,
    sources: &[Source],
    cfg: &LightConfig,
    mut tap: Option<&mut Tap>,
    mut progress: impl FnMut(usize, u64),
) -> Result<Lighting<F>> {
    let n = grid.n;
    if sources.len() > cell_core::light::MAX_SOURCES {
        bail!("{} light sources: at most {} are supported", sources.len(), cell_core::light::MAX_SOURCES);
    }
    if cfg.fa == 0 || cfg.fa > FA_CAP {
        bail!("--fa {} is out of range: 1 ..= {FA_CAP} (the FIFO capacity compiled into a cell)", cfg.fa);
    }
    let far = FarDistance::<F>::new(n - 1).ok_or_else(|| {
        anyhow::anyhow!(
            "far distance D = {} exceeds the beam bit budget for {} fraction bits (max D = {})",
            n - 1,
            F::U32,
            FarDistance::<F>::MAX
        )
    })?;
    crate::limits::check_grid_memory("grid of lighting cells", n, std::mem::size_of::<HostLightCell<F>>())?;
    let mut cells: Vec<HostLightCell<F>> = Vec::with_capacity((n * n) as usize);
    for y in 0..n {
        for x in 0..n {
            cells.push(LightCell::new(x as u16, y as u16));
        }
    }
    let order = SplitOrder::default();
    let mut reports = Vec::new();
    let mut visited = cfg.record_visits.then(|| vec![false; (n * n * grid.depth) as usize]);
    for (si, src) in sources.iter().enumerate() {
        let env = LightEnv {
            source: src,
            far,
            n,
            depth: grid.depth,
            policy: cfg.policy,
            order: &order,
            fa: cfg.fa,
            source_bit: 1 << si,
            merge: cfg.merge,
        };
        let before: Vec<LightCounters> = cells.iter().map(|c| c.counters).collect();
        for c in cells.iter_mut() {
            c.counters.max_layer = 0;
            c.counters.peak_fifo = 0;
        }
        if let Some(t) = tap.as_deref_mut() {
            t.light(&env);
        }
        let r = diffuse_one(
            grid,
            &mut cells,
            src,
            si,
            &env,
            Recording { visited: visited.as_deref_mut(), tap: tap.as_deref_mut() },
            |c| progress(si, c),
        )?;
        let mut rep = r;
        rep.position = src.pos.map(|p| p.to_num::<f64>());
        for (c, b) in cells.iter().zip(&before) {
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
            rep.counts.blocked_cell_cycles += k.blocked_cycles - b.blocked_cycles;
            rep.counts.peak_fifo = rep.counts.peak_fifo.max(k.peak_fifo);
            if processed > 0 {
                rep.counts.lb_distance = rep.counts.lb_distance.max(k.max_layer as u64 + 1);
            }
        }
        rep.counts.lower_bound = rep.counts.lb_distance.max(rep.counts.lb_cell_load);
        if rep.counts.rays_emitted != rep.counts.rays_absorbed + rep.counts.rays_exited {
            bail!(
                "ray conservation violated for source {si}: emitted {} ≠ absorbed {} + exited {}",
                rep.counts.rays_emitted,
                rep.counts.rays_absorbed,
                rep.counts.rays_exited
            );
        }
        reports.push(rep);
    }
    Ok(Lighting { n, cells, reports, visited })
}

/// What a run records besides its results: visited voxels, cell traces.
struct Recording<'a> {
    visited: Option<&'a mut [bool]>,
    tap: Option<&'a mut Tap>,
}

fn diffuse_one<F: FracBits, const D: usize>(
    grid: &Grid<D>,
    cells: &mut [HostLightCell<F>],
    src: &Source,
    si: usize,
    env: &LightEnv<'_, F>,
    rec: Recording<'_>,
    mut progress: impl FnMut(u64),
) -> Result<SourceReport> {
    let Recording { mut visited, mut tap } = rec;
    let n = grid.n as usize;
    let sv = src.voxel();
    let s_idx = sv[1] as usize * n + sv[0] as usize;
    let activity = Activity::new();
    let initial: Vec<Beam<F>> = Direction::ALL.iter().map(|&d| Beam::initial(src, d, env.far)).collect();
    let mut rep = SourceReport { source: si, ..Default::default() };
    rep.counts.rays_emitted = initial.iter().map(|b| b.ray_count() as u128).sum();
    activity.add(initial.len() as u64);
    let mut pending = initial.into_iter();
    let mut next_initial = pending.next();
    let mut active: Vec<u32> = vec![s_idx as u32];
    let mut in_active = vec![false; cells.len()];
    in_active[s_idx] = true;
    let mut woken: Vec<u32> = Vec::new();
    let mut transfers: Vec<(u32, u32, u8)> = Vec::new();
    let mut cycle: u64 = 0;
    while !activity.is_quiescent() {
        let mut moved = false;
        // 1. Source emitter.
        if let Some(b) = next_initial {
            if cells[s_idx].can_accept(env.fa) {
                let msg = BeamMsg { beam: b, z: sv[2] as u16 };
                if let Some(r) = tap.as_deref_mut().and_then(|t| t.get(s_idx)) {
                    r.inject(&msg);
                }
                if cells[s_idx].accept(msg, env.merge, &activity).is_ok() {
                    next_initial = pending.next();
                    moved = true;
                }
            }
        }
        // 2. Compute.
        for &i in &active {
            let i = i as usize;
            let step = cells[i].step(&grid.cells[i].store, env, &activity);
            if let Some(r) = tap.as_deref_mut().and_then(|t| t.get(i)) {
                r.step(step);
            }
            if step == Step::Processed {
                moved = true;
                if let Some(v) = visited.as_deref_mut() {
                    v[i * grid.depth as usize + cells[i].last_z as usize] = true;
                }
            }
        }
        // 3. Links. Under the wavefront policy the oldest messages (smallest layer) claim FIFO
        //    credits first; under the thesis's, senders in row-major order.
        transfers.clear();
        for &i in &active {
            for p in Port::ALL {
                if let Some(m) = cells[i as usize].out[p.index()].front() {
                    let key = if env.policy == Policy::Wavefront { m.beam.layer().0 } else { 0 };
                    transfers.push((key, i, p.index() as u8));
                }
            }
        }
        if env.policy == Policy::Wavefront {
            transfers.sort_by_key(|t| t.0); // stable: row-major among equals
        }
        for &(_, i, p) in &transfers {
            let i = i as usize;
            let (dx, dy) = Port::ALL[p as usize].delta();
            let j = (i as i64 + dy as i64 * n as i64 + dx as i64) as usize;
            if !cells[j].can_accept(env.fa) {
                continue;
            }
            if let Some(m) = cells[i].out[p as usize].pop_front() {
                if let Some(t) = tap.as_deref_mut() {
                    t.transfer(i, j, Port::ALL[p as usize], &m);
                }
                let _ = cells[j].accept(m, env.merge, &activity);
                rep.counts.messages += 1;
                moved = true;
                if !in_active[j] {
                    in_active[j] = true;
                    woken.push(j as u32);
                }
            }
        }
        cycle += 1;
        // Next cycle's active set: busy cells, in row-major order.
        active.retain(|&i| {
            let busy = cells[i as usize].busy();
            in_active[i as usize] = busy;
            busy
        });
        for &j in &woken {
            if cells[j as usize].busy() {
                in_active[j as usize] = true;
                active.push(j);
            } else {
                in_active[j as usize] = false;
            }
        }
        woken.clear();
        active.sort_unstable();
        if next_initial.is_some() && !in_active[s_idx] {
            in_active[s_idx] = true;
            active.push(s_idx as u32);
            active.sort_unstable();
        }
        rep.counts.peak_active_cells = rep.counts.peak_active_cells.max(active.len() as u64);
        if !moved {
            let blocked: Vec<String> = active
                .iter()
                .take(8)
                .map(|&i| {
                    let c = &cells[i as usize];
                    format!(
                        "({}, {}) fifo {} out {:?}",
                        c.x,
                        c.y,
                        c.fifo.len(),
                        c.out.iter().map(|q| q.len()).collect::<Vec<_>>()
                    )
                })
                .collect();
            bail!(
                "deadlock at cycle {cycle} of source {si}: {} beams in flight, nothing can move; blocked cells: {}",
                activity.get(),
                blocked.join("; ")
            );
        }
        if cycle % 256 == 0 {
            progress(cycle);
        }
    }
    progress(cycle);
    rep.counts.cycles = cycle;
    Ok(rep)
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
