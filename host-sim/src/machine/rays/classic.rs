//! Classic shadow rays on the grid (thesis §4.1.2–4.1.3): the
//! method beam diffusion replaces, simulated with the same cycle model so both can be compared.
//!
//! For each source in turn (like diffusion, the next starts when the grid is quiescent): every
//! column's visible surface emits one [`ShadowRay`] toward the source, walking an incremental
//! line ([`cell_core::ray`]). Under the thesis's rule ([`LitRule::Thesis`]) the visible surface is
//! the first occupied voxel of the column and the ray starts at its centre; under the plane rule
//! ([`LitRule::Plane`]) it is the surface the column's centre line meets
//! ([`cell_core::visible`]), the ray is the exact segment from that point, and a voxel stops it
//! only where the segment crosses the voxel's own plane (the plane principle of
//! [`cell_core::ray`]); a surface whose plane turns away from the source emits no ray (it is in
//! its own shadow, counted as `back_facing`). Under exact occluders ([`LitRule::Exact`], the
//! default of the `light` and `render` jobs) the ray walks the same line and each column it
//! enters tests its own triangles ([`crate::machine::grid::triangles`]) once against the exact
//! segment from the light to ¼ voxel in front of the pixel's point
//! ([`ShadowRay::advance_exact`]): the segment tested against every triangle of the scene, as
//! long as no column's store is full. What one cell holds and does is
//! [`cell_core::shadow::ShadowCell`] (its FIFO of [`SHADOW_FA_CAP`] rays, one output slot per
//! link, its emission, its answers); this module schedules the cells. Cycle model, per cycle:
//! 1. **compute**: every cell with rays takes its FIFO's head and does one voxel of work
//!    ([`ShadowRay::advance`]): an occupied voxel (of another facet) → the answer "shadow";
//!    the end of the line (the source) → "lit"; the next voxel in the same column → the ray
//!    goes back to the FIFO's tail; in a neighbour column → the output buffer of that link.
//!    An answer goes to the cell's router, addressed to the emitter. If the buffer or the router
//!    channel is full the ray is not processed (no loss, §4.4.2), goes to the FIFO's tail, and
//!    the cell is blocked for the cycle (the thesis's policy). Then the cell emits into the
//!    room left below the FIFO limit (with `--emitters all` a column may emit more rays than
//!    FA: they wait in the cell's emitter, which generates them from its dexels).
//! 2. **links**: answers first ([`crate::machine::rays::network`]: routers, virtual channels, credits), then
//!    rays (output buffer → neighbour FIFO when it has room); one message per link, direction
//!    and cycle, whatever its kind.
//! 3. each router hands at most one answer per cycle to its cell, which records it.
//!
//! **Shadow-edge refinement** ([`refine_edges`], `render --lighting refined`) runs the same
//! cycle model after diffusion with only the cells on a diffused shadow's edge emitting
//! ([`cell_core::shadow::on_shadow_edge`], [`ShadowCell::start_if`]).
//!
//! **No deadlock**: every ray ends in the source's voxel and its cell steps go monotonically
//! toward it (18/26 rays aim at the voxel's centre, see [`ShadowRay::new`]), so every ray
//! move strictly decreases |x − x_s| + |y − y_s| and the cells' waits for FIFO space are
//! acyclic (one source at a time); answers travel on a network that is deadlock-free by itself
//! ([`cell_core::route`]) and always drains, so a cell waiting to send an answer waits finitely.
//! A cycle with work in flight and nothing moving is reported as an error, never a hang.

use std::mem::size_of;
use std::time::Instant;

use anyhow::{bail, Result};
use cell_core::light::{Port, SourceMask};
use cell_core::lit::LitRule;
use cell_core::ray::{Connectivity, ShadowRay};
use cell_core::route::RoutePolicy;
use cell_core::shadow::{EmitError, ShadowCell, ShadowEnv, ShadowStep};
use cell_core::trace::ShadowSetup;
use cell_core::wire::RayMsg;

use crate::machine::lighting::diffuse::{DiffusionCounts, SourceReport};

use crate::machine::grid::capacity::{HostShadowCell, SHADOW_FA_CAP};
use crate::machine::grid::{neighbour, LightGrid};
use crate::machine::lighting::run::LightStats;
use crate::machine::links::tap::Tap;
use crate::machine::loading::loaded_scene::LoadedScene;
use crate::machine::rays::network::Network;
use crate::scene::Mesh;

/// Classic-phase settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClassicConfig {
    /// FIFO limit of each cell (rays), 1 ..= [`SHADOW_FA_CAP`].
    pub fa: usize,
    /// Connectivity of the shadow rays.
    pub connectivity: Connectivity,
    /// Routing of the answers.
    pub route: RoutePolicy,
    /// Every occupied voxel emits (not only the visible ones): the thesis's count ΣS_i, for
    /// the occupancy comparison (§4.1.6). Only visible voxels' answers change the image.
    pub all_voxels: bool,
    /// Shadow bias: voxels after the emitter's own a ray does not test
    /// ([`ShadowRay::with_bias`]; 0 = the thesis's rule, only the emitter's facet is ignored).
    pub bias: u8,
    /// Which voxels stop a ray: the thesis's (every occupied voxel of another facet) or the
    /// plane principle (only where the ray crosses the voxel's plane; 6-connected rays only).
    pub rule: LitRule,
}

/// Counters of a classic run (one source's, or summed).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ClassicCounts {
    /// Cycles until the last answer was recorded.
    pub cycles: u64,
    /// Shadow rays emitted (one per emitting voxel).
    pub rays: u64,
    /// Voxel steps processed (one per cycle per cell at most).
    pub ray_steps: u64,
    /// Ray messages that crossed a link.
    pub ray_messages: u64,
    /// Answers (one per ray).
    pub answers: u64,
    /// Answer messages that crossed a link (routed hops).
    pub answer_messages: u64,
    /// Occupied voxels of the scene (for occupancy = voxels / n³).
    pub voxels: u64,
    /// Rays answered "lit".
    pub lit: u64,
    /// Emitters whose plane turns away from the source (plane rule): no ray, in shadow.
    pub back_facing: u64,
    /// Largest number of voxel steps one cell processed.
    pub busiest_cell_steps: u64,
    /// That cell, (x, y) (the first in row-major order on ties).
    pub busiest_cell: [u32; 2],
    /// Chebyshev distance (cells) from the busiest cell to the source's column.
    pub busiest_cell_distance: u32,
    /// Most messages (rays + answers) one link carried in one direction.
    pub peak_link_load: u64,
    /// Chebyshev distance from that link's sending cell to the source's column.
    pub peak_link_distance: u32,
    /// Largest FIFO occupancy.
    pub peak_fifo: u16,
    /// Sum over cells of cycles with rays waiting and none processable.
    pub blocked_cell_cycles: u64,
}

impl ClassicCounts {
    /// Accumulate another source's run (sums; peaks by maximum).
    pub fn add(&mut self, o: &ClassicCounts) {
        self.cycles += o.cycles;
        self.rays += o.rays;
        self.voxels = o.voxels;
        self.ray_steps += o.ray_steps;
        self.ray_messages += o.ray_messages;
        self.answers += o.answers;
        self.answer_messages += o.answer_messages;
        self.lit += o.lit;
        self.back_facing += o.back_facing;
        if o.busiest_cell_steps > self.busiest_cell_steps {
            self.busiest_cell_steps = o.busiest_cell_steps;
            self.busiest_cell = o.busiest_cell;
            self.busiest_cell_distance = o.busiest_cell_distance;
        }
        if o.peak_link_load > self.peak_link_load {
            self.peak_link_load = o.peak_link_load;
            self.peak_link_distance = o.peak_link_distance;
        }
        self.peak_fifo = self.peak_fifo.max(o.peak_fifo);
        self.blocked_cell_cycles += o.blocked_cell_cycles;
    }

    /// Messages over links, both kinds.
    pub fn messages(&self) -> u64 {
        self.ray_messages + self.answer_messages
    }
}

/// Lit state of the visible voxels after the classic phase.
pub struct ClassicLighting {
    /// Grid side.
    pub n: u32,
    /// Sources that lit the visible voxel of each column (index y·n + x).
    pub masks: Vec<SourceMask>,
    /// One report per source.
    pub per_source: Vec<ClassicCounts>,
    /// Sum over sources.
    pub totals: ClassicCounts,
}

impl ClassicLighting {
    /// Sources that lit the surface column (x, y) shows: only visible surfaces are ever tested.
    pub fn mask(&self, x: u32, y: u32) -> SourceMask {
        self.masks[(y * self.n + x) as usize]
    }
}

/// The source position on the 1/16 lattice of the rays.
fn lattice(p: [f64; 3]) -> [i32; 3] {
    p.map(|c| (c * cell_core::ray::Q as f64).round() as i32)
}

/// Run the classic phase for every source (positions in voxel units).
pub fn classic(
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &ClassicConfig,
    mut progress: impl FnMut(usize, u64),
) -> Result<ClassicLighting> {
    classic_tapped(scene, lights, cfg, None, &mut progress)
}

/// [`classic`], recording what the cells watched by `tap` receive and send (each source's
/// setup, cycles, rays, answers, and its end with the cell's state).
pub fn classic_tapped(
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &ClassicConfig,
    mut tap: Option<&mut Tap>,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<ClassicLighting> {
    let n = scene.grid.n;
    check_run(n, lights, cfg)?;
    let mut masks = vec![0; (n * n) as usize];
    let mut per_source = Vec::new();
    let mut totals = ClassicCounts::default();
    for (si, &l) in lights.iter().enumerate() {
        let c = classic_one(scene, l, si, cfg, None, &mut masks, tap.as_deref_mut(), &mut |c| progress(si, c))?;
        totals.add(&c);
        per_source.push(c);
    }
    Ok(ClassicLighting { n, masks, per_source, totals })
}

/// Refuse a classic run the cells cannot do: too many sources, a source outside the grid, a
/// FIFO limit outside `1 ..= SHADOW_FA_CAP`, or rays other than 6-connected under the plane
/// rule or exact occluders.
fn check_run(n: u32, lights: &[[f64; 3]], cfg: &ClassicConfig) -> Result<()> {
    if lights.len() > cell_core::light::MAX_SOURCES {
        bail!("{} light sources: at most {} are supported", lights.len(), cell_core::light::MAX_SOURCES);
    }
    if cfg.fa == 0 || cfg.fa > SHADOW_FA_CAP {
        bail!("--fa {} is out of range: 1 ..= {SHADOW_FA_CAP}", cfg.fa);
    }
    for (i, &l) in lights.iter().enumerate() {
        crate::machine::lighting::diffuse::source_at(i, l, n)?;
    }
    if cfg.rule.cuts_rays() && cfg.connectivity != Connectivity::Six {
        bail!(
            "the plane rule and exact occluders walk the exact segment (6-connected): use \
             --ray-connectivity 6, or --lit-rule thesis for {}-connected rays",
            cfg.connectivity.k()
        );
    }
    Ok(())
}

/// One source's classic run: the cycle loop over the phases of [`ClassicRun`]; `emit`: the
/// cells that emit (`None`: all).
#[allow(clippy::too_many_arguments)]
fn classic_one(
    scene: &LoadedScene,
    light: [f64; 3],
    si: usize,
    cfg: &ClassicConfig,
    emit: Option<&[bool]>,
    masks: &mut [SourceMask],
    tap: Option<&mut Tap>,
    progress: &mut dyn FnMut(u64),
) -> Result<ClassicCounts> {
    let mut run = ClassicRun::new(scene, light, si, cfg, emit, tap)?;
    while run.rays_in_flight > 0 || run.net.in_flight > 0 || run.emitters > 0 {
        let mut moved = run.compute()?;
        moved += run.answers();
        moved += run.ray_links();
        run.cycle += 1;
        run.next_active();
        if moved == 0 {
            return Err(run.deadlock());
        }
        if run.cycle % 256 == 0 {
            progress(run.cycle);
        }
    }
    progress(run.cycle);
    if let Some(t) = run.tap.as_deref_mut() {
        t.each(|i, r| r.shadow_end(&run.cells[i]));
    }
    run.check_overflow()?;
    for (m, c) in masks.iter_mut().zip(&run.cells) {
        *m |= c.mask;
    }
    Ok(run.finish())
}

/// The state of one source's classic run from cycle to cycle, and its phases (the module
/// doc's cycle model). The cells ([`ShadowCell`]) do the per-cell work; the run moves their
/// rays over the links and their answers over the routers.
struct ClassicRun<'a> {
    grid: &'a LightGrid,
    env: ShadowEnv,
    si: usize,
    n: usize,
    /// The source's column.
    src_col: [i64; 2],
    cells: Vec<HostShadowCell>,
    /// Ray messages per link (`cell·8 + port`, the sender's side).
    ray_link: Vec<u32>,
    /// The answer network ([`cell_core::shadow::ShadowAnswer`] payloads).
    net: Network<u8>,
    k: ClassicCounts,
    /// This source's bit in the masks.
    bit: SourceMask,
    rays_in_flight: u64,
    /// Cells with emission left.
    emitters: u64,
    /// The cells with rays, in row-major order, and their flags.
    active: Vec<u32>,
    in_active: Vec<bool>,
    link_used: Vec<bool>,
    woken: Vec<u32>,
    cycle: u64,
    /// The trace recorder, if the run is recorded.
    tap: Option<&'a mut Tap>,
}

/// The error of a ray a cell could not emit.
fn emit_error(
    c: &cell_core::cell::Cell<{ crate::machine::grid::capacity::DEFAULT_DEXELS }>,
    e: EmitError,
) -> anyhow::Error {
    anyhow::anyhow!("shadow ray from ({}, {}, {}): {:?}", c.x, c.y, e.z, e.error)
}

impl<'a> ClassicRun<'a> {
    /// Every cell started on the source: its first rays in its FIFO.
    fn new(
        scene: &'a LoadedScene,
        light: [f64; 3],
        si: usize,
        cfg: &'a ClassicConfig,
        emit: Option<&[bool]>,
        mut tap: Option<&'a mut Tap>,
    ) -> Result<Self> {
        let grid = &scene.grid;
        let n = grid.n as usize;
        crate::machine::grid::limits::check_grid_memory(
            "grid of shadow-ray cells",
            grid.n,
            size_of::<HostShadowCell>(),
        )?;
        let env = ShadowEnv {
            source: lattice(light),
            rule: cfg.rule,
            connectivity: cfg.connectivity,
            all_voxels: cfg.all_voxels,
            bias: cfg.bias,
            fa: cfg.fa,
        };
        if let Some(t) = tap.as_deref_mut() {
            t.shadow_setup(ShadowSetup { env, source_bit: 1 << si, fifo: SHADOW_FA_CAP as u16 }, &grid.triangles);
        }
        let mut cells: Vec<HostShadowCell> = (0..n * n).map(|_| ShadowCell::new()).collect();
        let (mut active, mut emitters) = (Vec::new(), 0);
        for (i, c) in grid.cells.iter().enumerate() {
            cells[i].start_if(c, &env, emit.is_none_or(|e| e[i])).map_err(|e| emit_error(c, e))?;
            emitters += cells[i].emitting() as u64;
            if cells[i].busy() {
                active.push(i as u32);
            }
        }
        let voxels = grid.cells.iter().map(|c| c.store.voxel_count() as u64).sum();
        let k = ClassicCounts { voxels, ..Default::default() };
        let rays_in_flight = cells.iter().map(|c| c.counters.rays as u64).sum();
        let mut in_active = vec![false; n * n];
        for &i in &active {
            in_active[i as usize] = true;
        }
        Ok(ClassicRun {
            grid,
            env,
            si,
            n,
            src_col: [(light[0] + 0.5).floor() as i64, (light[1] + 0.5).floor() as i64],
            cells,
            ray_link: vec![0u32; n * n * 8],
            net: Network::new(grid.n, cfg.route),
            rays_in_flight,
            emitters,
            k,
            bit: 1 << si,
            active,
            in_active,
            link_used: vec![false; n * n * 8],
            woken: Vec::new(),
            cycle: 0,
            tap,
        })
    }

    /// Chebyshev distance (cells) from cell `i` to the source's column.
    fn cheb(&self, i: usize) -> u32 {
        let n = self.n;
        ((i % n) as i64 - self.src_col[0]).abs().max(((i / n) as i64 - self.src_col[1]).abs()) as u32
    }

    /// 1. Compute: every active cell does one voxel of work on its FIFO's head
    ///    ([`ShadowCell::step`]: an answer goes to its router if it has room, a ray to its free
    ///    output slot; otherwise the cell is blocked), then emits into the room left
    ///    ([`ShadowCell::launch`]). Returns the steps and emissions done.
    fn compute(&mut self) -> Result<u64> {
        let mut moved = 0;
        let (cells, net) = (&mut self.cells, &mut self.net);
        for a in 0..self.active.len() {
            let i = self.active[a] as usize;
            let c = &mut cells[i];
            let col = &self.grid.cells[i];
            let mut offered = None;
            let step = c.step(&col.store, self.grid.triangles.column(col.x as u32, col.y as u32), |m| {
                let took = net.can_inject(i, m.dest) && net.inject(i, m);
                offered = Some((m, took));
                took
            });
            match step {
                ShadowStep::Answered(_) => {
                    self.rays_in_flight -= 1;
                    self.k.answers += 1;
                    moved += 1;
                }
                ShadowStep::Moved => moved += 1,
                ShadowStep::Idle | ShadowStep::Blocked => {}
            }
            let mut launched = 0;
            if c.emitting() {
                launched = c.launch(col, &self.env).map_err(|e| emit_error(col, e))?;
                self.rays_in_flight += launched as u64;
                moved += launched as u64;
                self.emitters -= !c.emitting() as u64;
            }
            if let Some(r) = self.tap.as_deref_mut().and_then(|t| t.get(i)) {
                r.shadow_cycle(step, launched, offered);
            }
        }
        Ok(moved)
    }

    /// 2a. Links, answers first: the routers move them; an answer delivered to its emitter is
    ///     recorded by it ([`ShadowCell::deliver`]). Returns the messages moved.
    fn answers(&mut self) -> u64 {
        self.link_used.iter_mut().for_each(|u| *u = false);
        let (cells, bit, tap) = (&mut self.cells, self.bit, &mut self.tap);
        self.net.step(&mut self.link_used, |cell, m| {
            if let Some(r) = tap.as_deref_mut().and_then(|t| t.get(cell)) {
                r.shadow_answer(m.payload);
            }
            cells[cell].deliver(m.payload, bit)
        })
    }

    /// 2b. Links, then rays: each output slot's ray moves to the neighbour's FIFO if it has
    ///     room and the link carried no answer this cycle. Returns the rays moved.
    fn ray_links(&mut self) -> u64 {
        let (n, mut moved) = (self.n, 0);
        for a in 0..self.active.len() {
            let i = self.active[a] as usize;
            if !self.cells[i].has_out() {
                continue;
            }
            for p in Port::ALL {
                let link = i * 8 + p.index();
                if self.link_used[link] || self.cells[i].out(p).is_none() {
                    continue;
                }
                let j = neighbour(n as u32, i, p).expect("a ray leaves only toward a cell of the grid");
                if !self.cells[j].can_accept(self.env.fa) {
                    continue;
                }
                let ray = self.cells[i].take_out(p).expect("a ray in the slot");
                if let Some(t) = self.tap.as_deref_mut() {
                    t.ray_moved(i, p, 0, &RayMsg::Shadow(ray), j);
                }
                // Room checked: a refusal would be counted in the cell and reported after the run.
                let _ = self.cells[j].accept(ray);
                self.k.peak_fifo = self.k.peak_fifo.max(self.cells[j].fifo_len() as u16);
                self.link_used[link] = true;
                self.ray_link[link] += 1;
                self.k.ray_messages += 1;
                moved += 1;
                if !self.in_active[j] {
                    self.in_active[j] = true;
                    self.woken.push(j as u32);
                }
            }
        }
        moved
    }

    /// Next cycle's active list: the busy cells and those a ray reached, in row-major order.
    fn next_active(&mut self) {
        let (cells, in_active) = (&self.cells, &mut self.in_active);
        self.active.retain(|&i| {
            let busy = cells[i as usize].busy();
            in_active[i as usize] = busy;
            busy
        });
        for &j in &self.woken {
            self.in_active[j as usize] = true;
            self.active.push(j);
        }
        self.woken.clear();
        self.active.sort_unstable();
    }

    /// A cell's FIFO refused a ray: [`overflow_report`].
    fn check_overflow(&self) -> Result<()> {
        overflow_report(&self.cells, self.n)
    }

    /// The error of a cycle with work in flight and nothing moving.
    fn deadlock(&self) -> anyhow::Error {
        let n = self.n;
        let net = &self.net;
        let mut busy: Vec<String> = net.busy_cells().take(4).map(|(c, o)| format!("router {c}: {o}")).collect();
        busy.extend(self.active.iter().take(8).map(|&i| {
            let c = &self.cells[i as usize];
            let outs: Vec<String> =
                Port::ALL.iter().filter_map(|&p| c.out(p).map(|r| format!("{p:?}→{:?}", r.line.voxel()))).collect();
            let heads: Vec<[i32; 3]> = c.fifo().map(|r| r.line.voxel()).collect();
            format!("cell ({}, {}) fifo {heads:?} out [{}]", i as usize % n, i as usize / n, outs.join(", "))
        }));
        anyhow::anyhow!(
            "deadlock in the classic phase at cycle {} of source {}: {} rays and {} answers in flight, nothing can move ({})",
            self.cycle,
            self.si,
            self.rays_in_flight,
            net.in_flight,
            busy.join("; ")
        )
    }

    /// The counters: cycles, the cells' sums, the busiest cell and link.
    fn finish(mut self) -> ClassicCounts {
        let n = self.n;
        self.k.cycles = self.cycle;
        for c in &self.cells {
            let k = &c.counters;
            self.k.rays += k.rays as u64;
            self.k.back_facing += k.back_facing as u64;
            self.k.ray_steps += k.steps as u64;
            self.k.lit += k.lit as u64;
            self.k.blocked_cell_cycles += k.blocked as u64;
        }
        let steps = |i: usize| self.cells[i].counters.steps as u64;
        if let Some((i, s)) = (0..n * n).map(|i| (i, steps(i))).max_by_key(|&(i, s)| (s, std::cmp::Reverse(i))) {
            self.k.busiest_cell_steps = s;
            self.k.busiest_cell = [(i % n) as u32, (i / n) as u32];
            self.k.busiest_cell_distance = self.cheb(i);
        }
        self.k.answer_messages = self.net.hops;
        if let Some((l, load)) = (0..n * n * 8)
            .map(|l| (l, self.ray_link[l] as u64 + self.net.link_load[l] as u64))
            .max_by_key(|&(l, v)| (v, std::cmp::Reverse(l)))
        {
            self.k.peak_link_load = load;
            self.k.peak_link_distance = self.cheb(l / 8);
        }
        self.k
    }
}

/// The error naming the first cell (of a grid of side `n`) whose FIFO refused a ray (its count
/// of overflows) and the capacity to raise; `Ok` if none did.
fn overflow_report<const FA: usize>(cells: &[ShadowCell<FA>], n: usize) -> Result<()> {
    let over = cells.iter().filter(|c| c.counters.overflows > 0).count();
    if let Some(i) = cells.iter().position(|c| c.counters.overflows > 0) {
        bail!(
            "shadow-ray FIFO overflow in {over} cell(s), first at cell ({}, {}): more than {FA} rays; raise \
             SHADOW_FA_CAP in cell_core::cell (host-sim/src/machine/grid/capacity.rs re-exports it)",
            i % n,
            i / n
        );
    }
    Ok(())
}

/// What shadow-edge refinement did, summed over sources.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct RefineCounts {
    /// Cycles: one exchange of lit bits per source, then its shadow rays' run.
    pub cycles: u64,
    /// (pixel, source) pairs on a diffused shadow's edge: the rays sent.
    pub edge_pixels: u64,
    /// Of those, the pairs whose lit bit the ray's answer changed.
    pub changed: u64,
    /// Lit-bit messages of the exchanges (one per link from a cell that shows a surface).
    pub exchange_messages: u64,
    /// The shadow rays' run.
    pub classic: ClassicCounts,
}

/// Shadow-edge refinement after diffusion ([`cell_core::shadow::on_shadow_edge`]): for each
/// source, every cell that shows a surface sends its lit bit to its 8 neighbours (one cycle);
/// the cells on an edge send one classic shadow ray each ([`classic`]'s cycle model, `cfg`'s
/// rule), and its answer replaces their bit in `masks` (index y·n + x, the diffused visible
/// masks).
pub fn refine_edges(
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    masks: &mut [SourceMask],
    cfg: &ClassicConfig,
    mut progress: impl FnMut(usize, u64),
) -> Result<RefineCounts> {
    refine_edges_with(scene, lights, masks, cfg, &mut progress)
}

/// [`refine_edges`] compiled once, whatever the caller's progress closure.
fn refine_edges_with(
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    masks: &mut [SourceMask],
    cfg: &ClassicConfig,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<RefineCounts> {
    let n = scene.grid.n as usize;
    if !cfg.rule.shades_visible_surface() {
        bail!("shadow-edge refinement needs visible surfaces: use --lit-rule exact or plane");
    }
    check_run(scene.grid.n, lights, cfg)?;
    let mut k = RefineCounts::default();
    for (si, &l) in lights.iter().enumerate() {
        let bit: SourceMask = 1 << si;
        let shows = |i: usize| scene.grid.cells[i].visible.is_some();
        let own = |i: usize| shows(i).then_some(masks[i] & bit != 0);
        let edge: Vec<bool> = (0..n * n)
            .map(|i| {
                let around = Port::ALL.map(|p| neighbour(n as u32, i, p).and_then(own));
                cell_core::shadow::on_shadow_edge(own(i), around)
            })
            .collect();
        k.exchange_messages += (0..n * n).filter(|&i| shows(i)).count() as u64 * 8;
        k.edge_pixels += edge.iter().filter(|&&e| e).count() as u64;
        let mut answers = vec![0; n * n];
        let c = classic_one(scene, l, si, cfg, Some(&edge), &mut answers, None, &mut |c| progress(si, c))?;
        for i in (0..n * n).filter(|&i| edge[i]) {
            k.changed += ((masks[i] ^ answers[i]) & bit != 0) as u64;
            masks[i] = (masks[i] & !bit) | (answers[i] & bit);
        }
        k.cycles += 1 + c.cycles;
        k.classic.add(&c);
    }
    Ok(k)
}

/// The classic phase as the `light`/`render` jobs report it: the lit state and a [`LightStats`]
/// whose diffusion counters hold the classic equivalents (cycles; `beams_processed` = voxel
/// steps; `messages` = ray + answer link messages; `lb_cell_load` = busiest cell's steps).
pub fn run_classic(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &ClassicConfig,
    mut progress: impl FnMut(usize, u64),
) -> Result<(ClassicLighting, LightStats)> {
    run_classic_with(mesh, scene, lights, cfg, &mut progress)
}

/// [`run_classic`] compiled once, whatever the caller's progress closure.
fn run_classic_with(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &ClassicConfig,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<(ClassicLighting, LightStats)> {
    let t0 = Instant::now();
    let cl = classic_tapped(scene, lights, cfg, None, progress)?;
    let exact = cfg.rule.needs_triangles();
    if exact {
        crate::machine::lighting::run::check_triangle_overflow(&scene.grid);
    }
    let wall = t0.elapsed().as_secs_f64();
    let as_diffusion = |c: &ClassicCounts| DiffusionCounts {
        cycles: c.cycles,
        lower_bound: c.busiest_cell_steps,
        lb_cell_load: c.busiest_cell_steps,
        beams_processed: c.ray_steps,
        messages: c.messages(),
        peak_fifo: c.peak_fifo,
        blocked_cell_cycles: c.blocked_cell_cycles,
        peak_link_load: c.peak_link_load,
        peak_link_distance: c.peak_link_distance,
        ..Default::default()
    };
    let totals = as_diffusion(&cl.totals);
    let sources = cl
        .per_source
        .iter()
        .enumerate()
        .map(|(s, c)| SourceReport {
            source: s,
            position: lights[s],
            busiest_cell: c.busiest_cell,
            counts: as_diffusion(c),
        })
        .collect();
    let stats = LightStats {
        scene: mesh.name.clone(),
        n: scene.grid.n,
        fa: cfg.fa,
        frac_bits: 0,
        policy: format!("classic-{}", cfg.connectivity.k()),
        merge: false,
        facets: scene.facets,
        load_cycles: scene.load_cycles,
        t_over_lb: totals.t_over_lb(),
        totals,
        lit_voxels: cl.masks.iter().filter(|&&m| m != 0).count() as u64,
        lit_overflows: 0,
        triangle_overflows: if exact { scene.grid.triangles.overflows() } else { 0 },
        bytes_beam_message: std::mem::size_of::<ShadowRay>(),
        bytes_light_cell: size_of::<HostShadowCell>() + size_of::<crate::machine::rays::network::HostRouter<u8>>(),
        sources,
        wall_seconds: wall,
        phase_seconds: None,
        peak_rss_mib: crate::machine::grid::limits::peak_rss_mib(),
        link_faults: None,
    };
    Ok((cl, stats))
}

/// One line of classic counters for the job summaries.
pub fn summary(c: &ClassicCounts) -> String {
    format!(
        "classic: {} rays ({} surfaces facing away), {} voxel steps, {} ray + {} answer messages, {} lit; busiest cell {} steps at distance {}; peak link load {} at distance {}; peak FIFO {}",
        c.rays,
        c.back_facing,
        c.ray_steps,
        c.ray_messages,
        c.answer_messages,
        c.lit,
        c.busiest_cell_steps,
        c.busiest_cell_distance,
        c.peak_link_load,
        c.peak_link_distance,
        c.peak_fifo
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use cell_core::ray::Q;

    #[test]
    fn a_full_fifo_is_reported_naming_the_cell_and_the_capacity() {
        let mut cells = [ShadowCell::<2>::new(), ShadowCell::new(), ShadowCell::new(), ShadowCell::new()];
        let ray = ShadowRay::new([1, 0, 0], [5 * Q, 0, 0], Connectivity::Six, 0).unwrap();
        for _ in 0..2 {
            cells[1].accept(ray).unwrap();
        }
        assert!(overflow_report(&cells, 2).is_ok(), "exactly the capacity is no overflow");
        assert!(cells[1].accept(ray).is_err());
        let e = overflow_report(&cells, 2).unwrap_err().to_string();
        assert!(e.contains("cell (1, 0)") && e.contains("more than 2 rays") && e.contains("SHADOW_FA_CAP"), "{e}");
    }
}
