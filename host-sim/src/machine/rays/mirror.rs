//! Mirror reflections on the grid: the distributed ray tree (thesis §1.1, §1.3.2, ch. 5).
//!
//! After the light phase every voxel's lit state is known. Each cell whose visible voxel is
//! reflective (`Kr > 0`, and `Kr` ≥ the threshold) emits a [`cell_core::reflect::ReflectRay`] (the view direction
//! mirrored about its normal, [`cell_core::reflect`]) and waits. A ray walks voxel by voxel with
//! the same cycle model as classic shadow rays ([`crate::machine::rays::classic`]): one voxel step per cell and
//! cycle, FIFOs of `fa` rays, one output buffer per link, one message per link and cycle, the
//! no-loss rule (a ray that cannot leave waits, the cell is blocked for the cycle). The cell
//! owning the first occupied voxel the ray meets shades it for the ray's direction; if that
//! voxel is reflective and the tree may grow (level ≤ `--reflections`, weight ≥
//! `--reflect-threshold`: Hall's adaptive depth, §1.2.5.1) it opens a **wait-table entry** and
//! emits its own reflected ray, and answers its parent only when that answer came back (§1.3.2);
//! otherwise it answers at once. Answers (linear RGB, Q12) are routed to the waiting cell on
//! [`crate::machine::rays::network`]; a ray leaving the grid answers black. A root combines
//! `local + Kr · answer` (§5.5.5) and encodes its pixel.
//!
//! Per cycle: 1. compute — each cell takes the head of one of its 4 FIFOs (round robin) and does
//! one voxel of work; then it may move one waiting child ray from its launch queue into the
//! FIFO of the ray's class (when there is room) and hand one answer of its send queue to its
//! router. 2. links — answers first (the routers), then rays (output buffer → neighbour FIFO of
//! the same class with room). 3. each router delivers at most one answer to its cell, which
//! fills the wait-table entry and queues the combined answer for its own parent.
//!
//! **No deadlock, no loss.** Reflected rays go every way, so one FIFO shared by all of them
//! could wait in a cycle (two cells, each full of rays for the other). Each cell therefore has
//! one FIFO and one set of output buffers per **class** (the signs of the ray's x and y
//! steps, [`cell_core::reflect::ReflectRay::class`]): a line never steps against its class, so each cell move of a
//! class-q ray strictly increases φ_q = ±x ± y, and the waits for FIFO room within a class
//! follow increasing φ_q: acyclic, and classes never wait for each other. A hit, an exit or a
//! z step needs no room (the ray's FIFO slot is released or reused); a child ray waits in the
//! launch queue, outside the FIFOs, so a full FIFO never blocks the hit that spawned it. The
//! answer network is deadlock-free by itself ([`cell_core::route`]) and a delivered answer only
//! updates a wait-table entry (never blocks). So every ray ends and every answer arrives; a
//! cycle with work in flight and nothing moving is still reported as an error, never a hang.
//!
//! What one cell holds and does is [`cell_core::reflect_cell::ReflectCell`] (FIFOs, output
//! slots, wait table, launch and send queues, all bounded: the capacities are
//! [`REFLECT_FA_CAP`], [`WAIT_CAP`] and [`SEND_CAP`] of `machine/grid/capacity.rs`); this module
//! schedules the cells, moves their rays over the links and their answers over the routers, and
//! stops with an error naming the cell and the capacity to raise if a store overflowed. The
//! run reports the peaks of the wait tables and send queues (what a firmware must provision).

use std::mem::size_of;

use anyhow::{bail, Result};
use cell_core::beam::frac::U0;
use cell_core::dexel::Dexel;
use cell_core::light::{Port, SourceMask};
use cell_core::ray::{Connectivity, Q};
use cell_core::reflect::{Answer, HitPoint, ReflectNormal, MAX_GRID};
use cell_core::reflect_cell::{Delivered, RayError, ReflectAnswer, ReflectCell, ReflectEnv, Surfaces, Transmit};
use cell_core::route::RoutePolicy;
use cell_core::shade::{Material as CellMaterial, NormalMode, PointLight, ShadeParams};
use cell_core::trace::{Event, ReflectSetup, MAX_MATERIALS};
use cell_core::units::Depth;
use cell_core::wire::RayMsg;

use crate::machine::grid::capacity::{GLASS_WAIT_CAP, REFLECT_FA_CAP, SEND_CAP, WAIT_CAP};
use crate::machine::grid::{neighbour, LightGrid};
use crate::machine::links::tap::Tap;
use crate::machine::loading::loaded_scene::LoadedScene;
use crate::machine::rays::network::Network;
use crate::scene::Mesh;

/// Reflection-phase settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReflectConfig {
    /// Largest tree depth: reflections per path (0 = off).
    pub depth: u8,
    /// Hall's threshold: a voxel reflects only if the product of the Kr along the path, its
    /// own included, is at least this.
    pub threshold: f32,
    /// Normal that mirrors the rays (§5.2).
    pub normal: ReflectNormal,
    /// Where a reflected ray leaves the voxel it reflects from (§5.3).
    pub hit: HitPoint,
    /// Ignore voxels of the facet a ray left (off: the §5.5.2 self-collision shows).
    pub skip_own_facet: bool,
    /// Connectivity of the rays' lines.
    pub connectivity: Connectivity,
    /// FIFO limit per class and cell (rays), 1 ..= [`REFLECT_FA_CAP`].
    pub fa: usize,
    /// Routing of the answers.
    pub route: RoutePolicy,
}

impl ReflectConfig {
    /// Refuse what the phase cannot run on a grid of side `n`.
    pub fn validate(&self, n: u32) -> Result<()> {
        if n > MAX_GRID {
            bail!("reflections support grids up to n = {MAX_GRID} (got n = {n})");
        }
        if self.fa == 0 || self.fa > REFLECT_FA_CAP {
            bail!(
                "--fa {} is out of range for the reflection phase: its cells hold 1 ..= {REFLECT_FA_CAP} rays per class \
                 (REFLECT_FA_CAP)",
                self.fa
            );
        }
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            bail!("--reflect-threshold {} must be a finite number ≥ 0", self.threshold);
        }
        Ok(())
    }
}

/// Counters of a reflection run.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ReflectCounts {
    /// Where reflected rays left their voxels (`--hit`: centre, edge or exact, §5.3).
    pub hit: &'static str,
    /// Cycles until the last root had its answer.
    pub cycles: u64,
    /// Visible reflective voxels that emitted (tree roots).
    pub roots: u64,
    /// Reflected rays emitted (all levels).
    pub rays: u64,
    /// Voxel steps processed.
    pub ray_steps: u64,
    /// Ray messages over links.
    pub ray_messages: u64,
    /// Answers sent (one per ray).
    pub answers: u64,
    /// Answer messages over links (routed hops).
    pub answer_messages: u64,
    /// Rays that hit a voxel.
    pub hits: u64,
    /// Rays that left the grid (answered black).
    pub exits: u64,
    /// Hit voxels that reflected or refracted again and waited for their children before
    /// answering.
    pub waits: u64,
    /// Refracted (transmitted) rays made, total internal reflections included (§1.1's `I_T`).
    pub refracted: u64,
    /// Of those, rays beyond the critical angle, sent along the mirrored direction.
    pub total_internal: u64,
    /// Rays inside a transparent solid that met another material or left the grid without
    /// crossing its surface (§5.5.2's leak through a discrete surface).
    pub leaks: u64,
    /// Deepest ray level reached (1: rays from visible voxels).
    pub max_level: u8,
    /// Reflective hit voxels that did not reflect: tree depth reached.
    pub cut_depth: u64,
    /// Reflective hit voxels that did not reflect: weight below the threshold.
    pub cut_threshold: u64,
    /// Largest FIFO occupancy (one class).
    pub peak_fifo: u16,
    /// Largest wait table of a cell (entries open at once, root included).
    pub peak_wait: u32,
    /// Largest send queue of a cell (answers waiting for the router).
    pub peak_send: u32,
    /// Sum over cells of cycles with a ray processed in vain (output buffer full).
    pub blocked_cell_cycles: u64,
    /// With a reference: PSNR of the image against the reflective reference (dB).
    pub psnr_db: Option<f64>,
    /// The same image without its reflections (the local shading only) against it.
    pub psnr_without_db: Option<f64>,
    /// PSNR over the pixels where the reference sees a reflective surface.
    pub mirror_psnr_db: Option<f64>,
    /// The same without reflections.
    pub mirror_psnr_without_db: Option<f64>,
    /// Those pixels.
    pub mirror_pixels: u64,
    /// PSNR over the pixels where the reference sees a transparent surface (`Kt > 0`).
    pub glass_psnr_db: Option<f64>,
    /// The same without reflections and refractions.
    pub glass_psnr_without_db: Option<f64>,
    /// Those pixels.
    pub glass_pixels: u64,
}

impl ReflectCounts {
    /// Messages over links, both kinds.
    pub fn messages(&self) -> u64 {
        self.ray_messages + self.answer_messages
    }
}

/// The result of the reflection phase.
pub struct Reflected {
    /// Pixels of the reflective visible voxels that emitted (index y·n + x), others `None`.
    pub rgb: Vec<Option<[u8; 3]>>,
    /// The answer each root received.
    pub root_answers: Vec<Option<Answer>>,
    /// Counters.
    pub counts: ReflectCounts,
}

/// Answer payload: the wait-table slot and the intensity.
type Msg = (u16, Answer);

/// What the cells need to shade and reflect: materials, lights, lit state.
pub struct ShadeEnv<'a> {
    /// Cell materials by id.
    pub mats: Vec<CellMaterial>,
    /// Kr by material id.
    pub kr: Vec<f32>,
    /// How each material transmits (Kt, Tf, Ni), by material id.
    pub transmit: Vec<Transmit>,
    /// Lights.
    pub lights: &'a [PointLight],
    /// Shading parameters (ambient, the normal mode of the visible voxels).
    pub params: ShadeParams,
    /// Sources that reached voxel (x, y, z) (the light phase's result).
    pub mask: &'a dyn Fn(u32, u32, u16) -> SourceMask,
}

impl<'a> ShadeEnv<'a> {
    /// The environment of a mesh's materials.
    pub fn new(
        mesh: &Mesh,
        lights: &'a [PointLight],
        normals: NormalMode,
        mask: &'a dyn Fn(u32, u32, u16) -> SourceMask,
    ) -> Self {
        ShadeEnv {
            mats: mesh.materials.iter().map(crate::machine::shading::pixels::cell_material).collect(),
            kr: mesh.materials.iter().map(|m| m.kr).collect(),
            transmit: mesh.materials.iter().map(transmit).collect(),
            lights,
            params: ShadeParams {
                ambient: [crate::machine::shading::pixels::AMBIENT; 3],
                normal_mode: normals,
                eye: cell_core::shade::Eye::Grid,
            },
            mask,
        }
    }

    /// The cells' view of the materials and lights.
    pub fn surfaces(&self) -> Surfaces<'_> {
        Surfaces { mats: &self.mats, kr: &self.kr, transmit: &self.transmit, lights: self.lights, params: self.params }
    }

    /// Whether some material transmits (the trees branch in two at its voxels).
    pub fn refracts(&self) -> bool {
        self.transmit.iter().any(|t| t.kt > 0.0)
    }

    /// The visible voxel of column (x, y) as the camera sees it: linear local intensity and Kr.
    pub fn visible_local(&self, x: u16, y: u16, d: &Dexel) -> ([f32; 3], f32) {
        self.surfaces().visible_local(x, y, d, (self.mask)(x as u32, y as u32, d.span.lo))
    }
}

/// How a mesh material transmits, as the cells hold it (an index outside the refraction's bit
/// budget, which the MTL reader refuses, reads as 1).
pub fn transmit(m: &crate::scene::mesh::Material) -> Transmit {
    let ni = cell_core::refract::ior_code(m.ni).unwrap_or(cell_core::refract::IOR_ONE);
    Transmit { kt: m.kt, tf: m.tf, ni }
}

/// Span (lattice units) of a reflected ray's line: long enough to leave the grid from anywhere.
pub fn ray_span(n: u32, depth: u32) -> i32 {
    2 * Q * n.max(depth) as i32
}

/// Run the reflection phase over a lit grid: the cycle loop over the phases of `ReflectRun`.
pub fn reflect(scene: &LoadedScene, env: &ShadeEnv, cfg: &ReflectConfig) -> Result<Reflected> {
    reflect_tapped(scene, env, cfg, None)
}

/// [`reflect`], recording what the cells watched by `tap` receive and send (the phase's
/// setup, cycles, rays, answers, and its end with the cell's state).
pub fn reflect_tapped(
    scene: &LoadedScene,
    env: &ShadeEnv,
    cfg: &ReflectConfig,
    tap: Option<&mut Tap>,
) -> Result<Reflected> {
    // A refracting tree branches at every glass voxel: its cells need the larger wait table.
    match env.refracts() {
        true => run_cells::<GLASS_WAIT_CAP>(scene, env, cfg, tap),
        false => run_cells::<WAIT_CAP>(scene, env, cfg, tap),
    }
}

/// [`reflect_tapped`] with cells of `W` wait-table entries.
fn run_cells<const W: usize>(
    scene: &LoadedScene,
    env: &ShadeEnv,
    cfg: &ReflectConfig,
    tap: Option<&mut Tap>,
) -> Result<Reflected> {
    let mut run = ReflectRun::<W>::new(scene, env, cfg, tap)?;
    while run.roots_left > 0 {
        let mut moved = run.compute()?;
        moved += run.answers();
        moved += run.ray_links();
        run.cycle += 1;
        run.next_active();
        if moved == 0 && run.roots_left > 0 {
            run.check_faults()?;
            return Err(run.deadlock());
        }
    }
    if let Some(t) = run.tap.as_deref_mut() {
        t.each(|i, r| r.reflect_end(&run.cells[i]));
    }
    run.check_faults()?;
    Ok(run.finish())
}

/// The error of a ray a cell could not build.
fn ray_error(e: RayError) -> anyhow::Error {
    anyhow::anyhow!("reflected ray from {:?}: {:?}", e.at, e.error)
}

/// The state of the reflection phase from cycle to cycle, and its phases (the module doc's
/// per-cycle steps). The cells ([`ReflectCell`]) do the per-cell work; the run moves their rays
/// over the links and their answers over the routers.
struct ReflectRun<'a, const W: usize> {
    grid: &'a LightGrid,
    env: &'a ShadeEnv<'a>,
    renv: ReflectEnv,
    cells: Vec<ReflectCell<REFLECT_FA_CAP, W, SEND_CAP>>,
    /// Trees whose root has no answer yet.
    roots_left: u64,
    ray_messages: u64,
    net: Network<Msg>,
    link_used: Vec<bool>,
    /// The cells with work, in row-major order, and their flags.
    active: Vec<usize>,
    in_active: Vec<bool>,
    woken: Vec<usize>,
    cycle: u64,
    /// The trace recorder, if the run is recorded.
    tap: Option<&'a mut Tap>,
}

impl<'a, const W: usize> ReflectRun<'a, W> {
    /// The roots' rays ready to launch (or their black answers ready to send).
    fn new(
        scene: &'a LoadedScene,
        env: &'a ShadeEnv<'a>,
        cfg: &'a ReflectConfig,
        mut tap: Option<&'a mut Tap>,
    ) -> Result<Self> {
        let grid = &scene.grid;
        let (n, depth) = (grid.n, grid.depth);
        cfg.validate(n.max(depth))?;
        crate::machine::grid::limits::check_grid_memory(
            "grid of reflection cells",
            n,
            size_of::<ReflectCell<REFLECT_FA_CAP, W, SEND_CAP>>(),
        )?;
        let nn = n as usize;
        let renv = ReflectEnv {
            depth: cfg.depth,
            threshold: cfg.threshold,
            normal: cfg.normal,
            hit: cfg.hit,
            skip_own_facet: cfg.skip_own_facet,
            connectivity: cfg.connectivity,
            fa: cfg.fa,
            span: ray_span(n, depth),
            n,
            grid_depth: depth,
        };
        if let Some(t) = tap.as_deref_mut() {
            if env.refracts() {
                bail!(
                    "a traced reflection phase carries no transparent materials (the trace's setup has no Kt, Tf, Ni)"
                );
            }
            let Ok(kr) = heapless::Vec::from_slice(&env.kr) else {
                bail!("{} materials: a trace carries at most {MAX_MATERIALS}", env.kr.len());
            };
            let caps = [REFLECT_FA_CAP, W, SEND_CAP].map(|c| c as u16);
            t.all::<U0>(&Event::Reflect(ReflectSetup { env: renv, kr, caps }));
        }
        let mut run = ReflectRun {
            grid,
            env,
            renv,
            cells: (0..nn * nn).map(|_| ReflectCell::new()).collect(),
            roots_left: 0,
            ray_messages: 0,
            net: Network::new(n, cfg.route),
            link_used: vec![false; nn * nn * 8],
            active: Vec::new(),
            in_active: vec![false; nn * nn],
            woken: Vec::new(),
            cycle: 0,
            tap,
        };
        if cfg.depth > 0 {
            run.plant_roots()?;
        }
        run.active = (0..nn * nn).filter(|&i| !run.cells[i].idle()).collect();
        let (active, in_active) = (&run.active, &mut run.in_active);
        active.iter().for_each(|&i| in_active[i] = true);
        Ok(run)
    }

    /// Each cell whose visible voxel reflects enough opens its root entry and queues its ray.
    fn plant_roots(&mut self) -> Result<()> {
        let surfaces = self.env.surfaces();
        for (i, c) in self.grid.cells.iter().enumerate() {
            let reached = |z: Depth| (self.env.mask)(c.x as u32, c.y as u32, z);
            if self.cells[i].plant_root(c, &surfaces, &reached, &self.renv).map_err(ray_error)? {
                self.roots_left += 1;
            }
        }
        Ok(())
    }

    /// 1. Compute, launch, send: every active cell does one voxel of work on the head of one
    ///    of its FIFOs (round robin), may move one child ray from its launch queue into its
    ///    class's FIFO, and may hand one answer to its router ([`ReflectCell::step`]). Returns
    ///    the moves made.
    fn compute(&mut self) -> Result<u64> {
        let mut moved = 0;
        let surfaces = self.env.surfaces();
        let (cells, net) = (&mut self.cells, &mut self.net);
        for &i in &self.active {
            let c = &self.grid.cells[i];
            let reached = |z: Depth| (self.env.mask)(c.x as u32, c.y as u32, z);
            let mut offered = None;
            let send = |m: ReflectAnswer| {
                let took = net.can_inject(i, m.dest) && net.inject(i, m);
                offered = Some((m, took));
                took
            };
            let m = cells[i].step(c, &surfaces, &reached, &self.renv, send).map_err(ray_error)?;
            if let Some(r) = self.tap.as_deref_mut().and_then(|t| t.get(i)) {
                r.reflect_cycle(m, offered);
            }
            moved += m as u64;
        }
        Ok(moved)
    }

    /// 2a. Links, answers first: the routers move them; 3. each delivered answer fills its
    ///     wait-table entry ([`ReflectCell::deliver`]): a root encodes its pixel, another entry
    ///     queues its combined answer for its parent. Returns the messages moved.
    fn answers(&mut self) -> u64 {
        self.link_used.iter_mut().for_each(|u| *u = false);
        let (cells, roots_left) = (&mut self.cells, &mut self.roots_left);
        let (in_active, woken, tap) = (&mut self.in_active, &mut self.woken, &mut self.tap);
        self.net.step(&mut self.link_used, |i, m| {
            if let Some(r) = tap.as_deref_mut().and_then(|t| t.get(i)) {
                r.reflect_answer(m.payload.0, m.payload.1);
            }
            match cells[i].deliver(m.payload.0, m.payload.1) {
                Delivered::Root => *roots_left -= 1,
                Delivered::Forwarded if !in_active[i] => {
                    in_active[i] = true;
                    woken.push(i);
                }
                Delivered::Forwarded | Delivered::Waiting | Delivered::Stray => {}
            }
        })
    }

    /// 2b. Links, then rays: each output slot's ray moves to the neighbour's FIFO of the same
    ///     class if it has room and the link carried nothing else this cycle. Returns the rays
    ///     moved.
    fn ray_links(&mut self) -> u64 {
        let (n, fa, mut moved) = (self.grid.n, self.renv.fa, 0);
        for a in 0..self.active.len() {
            let i = self.active[a];
            if self.cells[i].outs() == 0 {
                continue;
            }
            for c in 0..4 {
                for p in Port::ALL {
                    let link = i * 8 + p.index();
                    if self.link_used[link] || self.cells[i].out(c, p).is_none() {
                        continue;
                    }
                    let j = neighbour(n, i, p).expect("a ray leaves only toward a cell of the grid");
                    if !self.cells[j].can_accept(c, fa) {
                        continue;
                    }
                    let ray = self.cells[i].take_out(c, p).expect("a ray in the slot");
                    if let Some(t) = self.tap.as_deref_mut() {
                        t.ray_moved(i, p, c as u8, &RayMsg::Reflect(ray), j);
                    }
                    // Room checked: a refusal would be counted in the cell and reported.
                    let _ = self.cells[j].accept(c, ray);
                    self.link_used[link] = true;
                    self.ray_messages += 1;
                    moved += 1;
                    if !self.in_active[j] {
                        self.in_active[j] = true;
                        self.woken.push(j);
                    }
                }
            }
        }
        moved
    }

    /// Next cycle's active list: the busy cells and those a message reached, in row-major order.
    fn next_active(&mut self) {
        let (cells, in_active) = (&self.cells, &mut self.in_active);
        self.active.retain(|&i| {
            let busy = !cells[i].idle();
            in_active[i] = busy;
            busy
        });
        for &j in &self.woken {
            self.in_active[j] = true;
            self.active.push(j);
        }
        self.woken.clear();
        self.active.sort_unstable();
    }

    /// A cell whose store overflowed (or that received a stray answer): [`fault_report`].
    fn check_faults(&self) -> Result<()> {
        fault_report(&self.cells, self.grid.n as usize)
    }

    /// The error of a cycle with trees unanswered and nothing moving.
    fn deadlock(&self) -> anyhow::Error {
        let nn = self.grid.n as usize;
        let busy: Vec<String> = self
            .active
            .iter()
            .take(6)
            .map(|&i| {
                let s = &self.cells[i];
                format!(
                    "cell ({}, {}): FIFOs {:?}, {} out, {} to launch, {} to send",
                    i % nn,
                    i / nn,
                    s.fifo_lens(),
                    s.outs(),
                    s.launching(),
                    s.sending()
                )
            })
            .collect();
        anyhow::anyhow!(
            "deadlock in the reflection phase at cycle {}: {} trees unanswered, {} answers in flight, nothing can move ({})",
            self.cycle,
            self.roots_left,
            self.net.in_flight,
            busy.join("; ")
        )
    }

    /// The result: the roots' pixels and answers, the cells' counters summed (peaks by maximum).
    fn finish(self) -> Reflected {
        let mut k = ReflectCounts {
            hit: self.renv.hit.name(),
            cycles: self.cycle,
            ray_messages: self.ray_messages,
            answer_messages: self.net.hops,
            ..Default::default()
        };
        for c in &self.cells {
            let m = &c.counters;
            k.roots += m.roots as u64;
            k.rays += m.rays as u64;
            k.ray_steps += m.ray_steps as u64;
            k.answers += m.answers as u64;
            k.hits += m.hits as u64;
            k.exits += m.exits as u64;
            k.waits += m.waits as u64;
            k.refracted += m.refracted as u64;
            k.total_internal += m.total_internal as u64;
            k.leaks += m.leaks as u64;
            k.cut_depth += m.cut_depth as u64;
            k.cut_threshold += m.cut_threshold as u64;
            k.blocked_cell_cycles += m.blocked as u64;
            k.max_level = k.max_level.max(m.max_level);
            k.peak_fifo = k.peak_fifo.max(m.peak_fifo);
            k.peak_wait = k.peak_wait.max(m.peak_wait as u32);
            k.peak_send = k.peak_send.max(m.peak_send as u32);
        }
        let rgb = self.cells.iter().map(|c| c.pixel).collect();
        let root_answers = self.cells.iter().map(|c| c.root_answer).collect();
        Reflected { rgb, root_answers, counts: k }
    }
}

/// The error naming the first cell (of a grid of side `n`) whose store overflowed or that
/// received a stray answer, and the capacity to raise; `Ok` if none did.
fn fault_report<const FA: usize, const W: usize, const S: usize>(
    cells: &[ReflectCell<FA, W, S>],
    n: usize,
) -> Result<()> {
    let faulty = cells.iter().filter(|c| c.counters.faults() > 0).count();
    let Some(i) = cells.iter().position(|c| c.counters.faults() > 0) else { return Ok(()) };
    let k = &cells[i].counters;
    let what = if k.wait_overflows > 0 {
        let cap = if W == WAIT_CAP { "WAIT_CAP" } else { "GLASS_WAIT_CAP" };
        format!("wait table full (more than {W} trees waiting at once); raise {cap}")
    } else if k.send_overflows > 0 {
        format!("send queue full (more than {S} answers for the router); raise SEND_CAP")
    } else if k.fifo_overflows > 0 {
        format!("ray FIFO full (more than {FA} rays); raise REFLECT_FA_CAP")
    } else {
        return Err(anyhow::anyhow!(
            "reflection cell ({}, {}) received an answer for a wait-table slot that was not open",
            i % n,
            i / n
        ));
    };
    bail!(
        "reflection cell overflow in {faulty} cell(s), first at cell ({}, {}): {what} in cell_core::cell \
         (host-sim/src/machine/grid/capacity.rs re-exports it)",
        i % n,
        i / n
    )
}

/// One line of reflection counters for the job summaries.
pub fn summary(c: &ReflectCounts) -> String {
    format!(
        "reflections (hit {}): {} cycles, {} trees, {} rays (deepest level {}), {} hits, {} exits, {} waits, {} voxel steps, {} ray + {} answer messages; cut by depth {}, by threshold {}; peak FIFO {}, wait table {}, send queue {}",
        c.hit,
        c.cycles,
        c.roots,
        c.rays,
        c.max_level,
        c.hits,
        c.exits,
        c.waits,
        c.ray_steps,
        c.ray_messages,
        c.answer_messages,
        c.cut_depth,
        c.cut_threshold,
        c.peak_fifo,
        c.peak_wait,
        c.peak_send
    ) + &match (c.psnr_db, c.psnr_without_db, c.mirror_psnr_db, c.mirror_psnr_without_db) {
        (Some(a), Some(b), Some(m), Some(mb)) => format!(
            "\n  vs the reflective reference: PSNR {a:.2} dB (without reflections {b:.2} dB); on the {} mirror pixels {m:.2} dB (without {mb:.2} dB)",
            c.mirror_pixels
        ),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cell_core::reflect::ReflectRay;

    #[test]
    fn a_full_fifo_is_reported_naming_the_cell_and_the_capacity() {
        let mut cells = [ReflectCell::<2, 2, 2>::new(), ReflectCell::new(), ReflectCell::new(), ReflectCell::new()];
        let ray = ReflectRay::leaving([Q, Q, 6 * Q], [0, 0, -Q], Connectivity::Six, [0, 0], 0, 7, 1, 1.0).unwrap();
        for _ in 0..2 {
            cells[3].accept(0, ray).unwrap();
        }
        assert!(fault_report(&cells, 2).is_ok(), "exactly the capacity is no fault");
        assert!(cells[3].accept(0, ray).is_err());
        let e = fault_report(&cells, 2).unwrap_err().to_string();
        assert!(e.contains("cell (1, 1)") && e.contains("more than 2 rays") && e.contains("REFLECT_FA_CAP"), "{e}");
        cells[3] = ReflectCell::new();
        cells[2].deliver(0, [0; 3]);
        let e = fault_report(&cells, 2).unwrap_err().to_string();
        assert!(e.contains("cell (0, 1)") && e.contains("not open"), "{e}");
    }
}
