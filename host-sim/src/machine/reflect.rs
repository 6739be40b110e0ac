//! Mirror reflections on the grid: the distributed ray tree (thesis §1.1, §1.3.2, ch. 5).
//!
//! After the light phase every voxel's lit state is known. Each cell whose visible voxel is
//! reflective (`Kr > 0`, and `Kr` ≥ the threshold) emits a [`ReflectRay`] (the view direction
//! mirrored about its normal, [`cell_core::reflect`]) and waits. A ray walks voxel by voxel with
//! the same cycle model as classic shadow rays ([`crate::machine::classic`]): one voxel step per cell and
//! cycle, FIFOs of `fa` rays, one output buffer per link, one message per link and cycle, the
//! no-loss rule (a ray that cannot leave waits, the cell is blocked for the cycle). The cell
//! owning the first occupied voxel the ray meets shades it for the ray's direction; if that
//! voxel is reflective and the tree may grow (level ≤ `--reflections`, weight ≥
//! `--reflect-threshold`: Hall's adaptive depth, §1.2.5.1) it opens a **wait-table entry** and
//! emits its own reflected ray, and answers its parent only when that answer came back (§1.3.2);
//! otherwise it answers at once. Answers (linear RGB, Q12) are routed to the waiting cell on
//! [`crate::machine::network`]; a ray leaving the grid answers black. A root combines
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
//! steps, [`ReflectRay::class`]): a line never steps against its class, so each cell move of a
//! class-q ray strictly increases φ_q = ±x ± y, and the waits for FIFO room within a class
//! follow increasing φ_q: acyclic, and classes never wait for each other. A hit, an exit or a
//! z step needs no room (the ray's FIFO slot is released or reused); a child ray waits in the
//! launch queue, outside the FIFOs, so a full FIFO never blocks the hit that spawned it. The
//! answer network is deadlock-free by itself ([`cell_core::route`]) and a delivered answer only
//! updates a wait-table entry (never blocks). So every ray ends and every answer arrives; a
//! cycle with work in flight and nothing moving is still reported as an error, never a hang.
//! The wait tables and send queues are unbounded here; the run reports their peaks (what a
//! firmware must provision).

use std::collections::VecDeque;

use anyhow::{bail, Result};
use cell_core::dexel::Dexel;
use cell_core::light::{Port, SourceMask};
use cell_core::ray::{Connectivity, Q};
use cell_core::reflect::{
    combine, hit_normal, reflected_dir, to_answer, toward_origin, Answer, ReflectNormal, ReflectRay, ReflectStep,
    MAX_GRID,
};
use cell_core::route::{RoutePolicy, Routed};
use cell_core::shade::{
    encode, facing_mask, shade_linear_toward, shading_normal, Material as CellMaterial, NormalMode, PointLight,
    ShadeParams, VIEW,
};

use crate::machine::capacity::FA_CAP;
use crate::machine::grid::LightGrid;
use crate::machine::loaded::LoadedScene;
use crate::machine::network::Network;
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
    /// Ignore voxels of the facet a ray left (off: the §5.5.2 self-collision shows).
    pub skip_own_facet: bool,
    /// Connectivity of the rays' lines.
    pub connectivity: Connectivity,
    /// FIFO limit per class and cell (rays), 1 ..= [`FA_CAP`].
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
        if self.fa == 0 || self.fa > FA_CAP {
            bail!("--fa {} is out of range: 1 ..= {FA_CAP}", self.fa);
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
    /// Hit voxels that reflected again and waited for their child before answering.
    pub waits: u64,
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

/// A wait-table entry: a voxel waiting for its reflected ray's answer.
#[derive(Clone, Copy, Debug)]
struct Node {
    /// Where the combined answer goes (`None`: the root, the cell's pixel).
    parent: Option<([u16; 2], u16)>,
    /// Local linear intensity.
    local: [f32; 3],
    kr: f32,
}

/// Answer payload: the wait-table slot and the intensity.
type Msg = (u16, Answer);

#[derive(Default)]
struct CellState {
    fifo: [VecDeque<ReflectRay>; 4],
    out: [[Option<ReflectRay>; 8]; 4],
    outs: u32,
    table: Vec<Option<Node>>,
    free: Vec<u16>,
    open: u32,
    launch: VecDeque<ReflectRay>,
    send: VecDeque<Routed<Msg>>,
    rr: usize,
}

impl CellState {
    fn open(&mut self, node: Node) -> u16 {
        self.open += 1;
        match self.free.pop() {
            Some(s) => {
                self.table[s as usize] = Some(node);
                s
            }
            None => {
                self.table.push(Some(node));
                (self.table.len() - 1) as u16
            }
        }
    }

    fn idle(&self) -> bool {
        self.outs == 0 && self.launch.is_empty() && self.send.is_empty() && self.fifo.iter().all(VecDeque::is_empty)
    }
}

/// What the cells need to shade and reflect: materials, lights, lit state.
pub struct ShadeEnv<'a> {
    /// Cell materials by id.
    pub mats: Vec<CellMaterial>,
    /// Kr by material id.
    pub kr: Vec<f32>,
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
            mats: mesh.materials.iter().map(crate::machine::shade::cell_material).collect(),
            kr: mesh.materials.iter().map(|m| m.kr).collect(),
            lights,
            params: ShadeParams {
                ambient: [crate::machine::shade::AMBIENT; 3],
                normal_mode: normals,
                eye: cell_core::shade::Eye::Grid,
            },
            mask,
        }
    }

    fn material(&self, d: &Dexel) -> (CellMaterial, f32) {
        let i = d.material as usize;
        (self.mats.get(i).copied().unwrap_or_default(), self.kr.get(i).copied().unwrap_or(0.0))
    }

    /// The visible voxel of column (x, y) as the camera sees it: linear local intensity and Kr.
    pub fn visible_local(&self, x: u16, y: u16, d: &Dexel) -> ([f32; 3], f32) {
        let z = d.span.lo;
        let p = [x as f32, y as f32, z as f32];
        let nrm = shading_normal(d, self.params.normal_mode);
        let lit = facing_mask(p, nrm, self.lights, (self.mask)(x as u32, y as u32, z));
        let (m, kr) = self.material(d);
        (shade_linear_toward(p, nrm, VIEW, &m, self.lights, lit, &self.params), kr)
    }

    /// A voxel hit by `ray`: linear local intensity seen from the ray's origin, and Kr.
    pub fn hit_local(
        &self,
        x: u16,
        y: u16,
        z: u16,
        d: &Dexel,
        ray: &ReflectRay,
        mode: ReflectNormal,
    ) -> ([f32; 3], f32) {
        let p = [x as f32, y as f32, z as f32];
        let v = toward_origin(ray.dir);
        let nrm = hit_normal(d, mode, v, ray.entry, ray.dir);
        let lit = facing_mask(p, nrm, self.lights, (self.mask)(x as u32, y as u32, z));
        let (m, kr) = self.material(d);
        (shade_linear_toward(p, nrm, v, &m, self.lights, lit, &self.params), kr)
    }
}

/// Span (lattice units) of a reflected ray's line: long enough to leave the grid from anywhere.
pub fn ray_span(n: u32, depth: u32) -> i32 {
    2 * Q * n.max(depth) as i32
}

/// The ray a voxel at (x, y, z) of dexel `d` emits after being reached by a ray of direction
/// `incident` entering by the faces `entry` (the primary ray: (0, 0, 1), face −z).
#[allow(clippy::too_many_arguments)]
pub fn child_ray(
    at: [u16; 3],
    d: &Dexel,
    incident: [i32; 3],
    entry: u8,
    cfg: &ReflectConfig,
    span: i32,
    parent: ([u16; 2], u16),
    level: u8,
    weight: f32,
) -> Result<Option<ReflectRay>> {
    let Some(dir) = reflected_dir(incident, entry, d.normal, cfg.normal, span) else { return Ok(None) };
    let r = ReflectRay::new(at, dir, cfg.connectivity, parent.0, parent.1, d.facet, level, weight)
        .map_err(|e| anyhow::anyhow!("reflected ray from {at:?}: {e:?}"))?;
    Ok(Some(r))
}

/// Run the reflection phase over a lit grid: the cycle loop over the phases of `ReflectRun`.
pub fn reflect(scene: &LoadedScene, env: &ShadeEnv, cfg: &ReflectConfig) -> Result<Reflected> {
    let mut run = ReflectRun::new(scene, env, cfg)?;
    while run.roots_left > 0 {
        let mut moved = run.compute()?;
        moved += run.answers();
        moved += run.ray_links();
        run.cycle += 1;
        run.next_active();
        if moved == 0 && run.roots_left > 0 {
            return Err(run.deadlock());
        }
    }
    run.out.counts.cycles = run.cycle;
    run.out.counts.answer_messages = run.net.hops;
    Ok(run.out)
}

/// The state of the reflection phase from cycle to cycle, and its phases (the module doc's
/// per-cycle steps).
struct ReflectRun<'a> {
    grid: &'a LightGrid,
    env: &'a ShadeEnv<'a>,
    cfg: &'a ReflectConfig,
    /// Span of a ray's line ([`ray_span`]).
    span: i32,
    cells: Vec<CellState>,
    out: Reflected,
    /// Trees whose root has no answer yet.
    roots_left: u64,
    net: Network<Msg>,
    link_used: Vec<bool>,
    /// The cells with work, in row-major order, and their flags.
    active: Vec<usize>,
    in_active: Vec<bool>,
    woken: Vec<usize>,
    cycle: u64,
}

impl<'a> ReflectRun<'a> {
    /// The roots' rays ready to launch (or their black answers ready to send).
    fn new(scene: &'a LoadedScene, env: &'a ShadeEnv<'a>, cfg: &'a ReflectConfig) -> Result<Self> {
        let grid = &scene.grid;
        let (n, depth) = (grid.n, grid.depth);
        cfg.validate(n.max(depth))?;
        let nn = n as usize;
        let out = Reflected { rgb: vec![None; nn * nn], root_answers: vec![None; nn * nn], counts: Default::default() };
        let mut run = ReflectRun {
            grid,
            env,
            cfg,
            span: ray_span(n, depth),
            cells: (0..nn * nn).map(|_| CellState::default()).collect(),
            out,
            roots_left: 0,
            net: Network::new(n, cfg.route),
            link_used: vec![false; nn * nn * 8],
            active: Vec::new(),
            in_active: vec![false; nn * nn],
            woken: Vec::new(),
            cycle: 0,
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
        let (env, cfg) = (self.env, self.cfg);
        for (i, c) in self.grid.cells.iter().enumerate() {
            let Some(d) = c.store.dexels().first() else { continue };
            let (local, kr) = env.visible_local(c.x, c.y, d);
            if !(kr > 0.0 && kr >= cfg.threshold) {
                continue;
            }
            let (x, y) = (c.x, c.y);
            let slot = self.cells[i].open(Node { parent: None, local, kr });
            match child_ray([x, y, d.span.lo], d, [0, 0, 1], 0b100, cfg, self.span, ([x, y], slot), 1, kr)? {
                Some(r) => self.cells[i].launch.push_back(r),
                None => self.cells[i].send.push_back(Routed { dest: [x, y], payload: (slot, [0; 3]) }),
            }
            self.out.counts.roots += 1;
            self.roots_left += 1;
        }
        Ok(())
    }

    /// 1. Compute, launch, send: every active cell does one voxel of work on the head of one
    ///    of its FIFOs (round robin), may move one child ray from its launch queue into its
    ///    class's FIFO, and may hand one answer to its router. Returns the moves made.
    fn compute(&mut self) -> Result<u64> {
        let mut moved = 0;
        for a in 0..self.active.len() {
            let i = self.active[a];
            moved += self.work(i)?;
            moved += self.launch(i);
            let (k, st) = (&mut self.out.counts, &mut self.cells[i]);
            if let Some(m) = st.send.front() {
                if self.net.can_inject(i, m.dest) && self.net.inject(i, *m) {
                    st.send.pop_front();
                    k.answers += 1;
                    moved += 1;
                }
            }
            k.peak_wait = k.peak_wait.max(st.open);
            k.peak_send = k.peak_send.max(st.send.len() as u32);
        }
        Ok(moved)
    }

    /// Cell `i` advances the head ray of its next non-empty FIFO by one voxel; 1 if it moved.
    fn work(&mut self, i: usize) -> Result<u64> {
        let cell = &self.grid.cells[i];
        let (n, depth) = (self.grid.n, self.grid.depth);
        let st = &mut self.cells[i];
        let Some(c) = (0..4).map(|o| (st.rr + o) % 4).find(|&c| !st.fifo[c].is_empty()) else { return Ok(0) };
        st.rr = (c + 1) % 4;
        let head = st.fifo[c].pop_front().expect("non-empty FIFO");
        let mut ray = head;
        let k = &mut self.out.counts;
        match ray.advance(&cell.store, n, depth, self.cfg.skip_own_facet) {
            ReflectStep::Hit(d, z) => {
                k.hits += 1;
                self.hit(i, &ray, &d, z)?;
            }
            ReflectStep::Exit => {
                k.exits += 1;
                st.send.push_back(Routed { dest: ray.parent, payload: (ray.slot, [0; 3]) });
            }
            ReflectStep::Stay => st.fifo[c].push_back(ray),
            ReflectStep::Forward(p) if st.out[c][p.index()].is_none() => {
                st.out[c][p.index()] = Some(ray);
                st.outs += 1;
            }
            ReflectStep::Forward(_) => {
                st.fifo[c].push_back(head);
                k.blocked_cell_cycles += 1;
                return Ok(0);
            }
        }
        self.out.counts.ray_steps += 1;
        Ok(1)
    }

    /// `ray` hit voxel z of cell `i` (dexel `d`): the voxel shades itself for the ray and either
    /// reflects (opens a wait-table entry and queues its child ray) or answers at once.
    fn hit(&mut self, i: usize, ray: &ReflectRay, d: &Dexel, z: u16) -> Result<()> {
        let (cell, cfg, k) = (&self.grid.cells[i], self.cfg, &mut self.out.counts);
        let st = &mut self.cells[i];
        let (local, kr) = self.env.hit_local(cell.x, cell.y, z, d, ray, cfg.normal);
        let w = ray.weight * kr;
        let parent = (ray.parent, ray.slot);
        let reflects = kr > 0.0 && ray.level < cfg.depth && w >= cfg.threshold;
        if kr > 0.0 && !reflects {
            if ray.level >= cfg.depth {
                k.cut_depth += 1;
            } else {
                k.cut_threshold += 1;
            }
        }
        let child = if reflects {
            let slot = st.open(Node { parent: Some(parent), local, kr });
            let (at, from) = ([cell.x, cell.y, z], ([cell.x, cell.y], slot));
            let r = child_ray(at, d, ray.dir, ray.entry, cfg, self.span, from, ray.level + 1, w)?;
            if r.is_none() {
                st.table[slot as usize] = None;
                st.free.push(slot);
                st.open -= 1;
            }
            r
        } else {
            None
        };
        match child {
            Some(r) => {
                k.waits += 1;
                st.launch.push_back(r);
            }
            None => st.send.push_back(Routed { dest: parent.0, payload: (parent.1, to_answer(local)) }),
        }
        Ok(())
    }

    /// Cell `i` moves its first waiting child ray into its class's FIFO if there is room; 1 if
    /// it did.
    fn launch(&mut self, i: usize) -> u64 {
        let (k, st) = (&mut self.out.counts, &mut self.cells[i]);
        let Some(r) = st.launch.front() else { return 0 };
        let c = r.class();
        if st.fifo[c].len() >= self.cfg.fa {
            return 0;
        }
        let r = st.launch.pop_front().expect("non-empty launch queue");
        k.max_level = k.max_level.max(r.level);
        k.rays += 1;
        st.fifo[c].push_back(r);
        k.peak_fifo = k.peak_fifo.max(st.fifo[c].len() as u16);
        1
    }

    /// 2a. Links, answers first: the routers move them; 3. each delivered answer fills its
    ///     wait-table entry: a root encodes its pixel, another entry queues its combined answer
    ///     for its parent. Returns the messages moved.
    fn answers(&mut self) -> u64 {
        self.link_used.iter_mut().for_each(|u| *u = false);
        let mut delivered: Vec<(usize, Msg)> = Vec::new();
        let moved = self.net.step(&mut self.link_used, |cell, m| delivered.push((cell, m.payload)));
        for (i, (slot, answer)) in delivered {
            let st = &mut self.cells[i];
            let node = st.table[slot as usize].take().expect("an answer for an open wait-table entry");
            st.free.push(slot);
            st.open -= 1;
            match node.parent {
                None => {
                    self.out.root_answers[i] = Some(answer);
                    self.out.rgb[i] = Some(combine(node.local, node.kr, answer).map(encode));
                    self.roots_left -= 1;
                }
                Some((dest, pslot)) => {
                    st.send
                        .push_back(Routed { dest, payload: (pslot, to_answer(combine(node.local, node.kr, answer))) });
                    if !self.in_active[i] {
                        self.in_active[i] = true;
                        self.woken.push(i);
                    }
                }
            }
        }
        moved
    }

    /// 2b. Links, then rays: each output buffer's ray moves to the neighbour's FIFO of the
    ///     same class if it has room and the link carried nothing else this cycle. Returns the
    ///     rays moved.
    fn ray_links(&mut self) -> u64 {
        let (nn, fa, mut moved) = (self.grid.n as usize, self.cfg.fa, 0);
        for a in 0..self.active.len() {
            let i = self.active[a];
            if self.cells[i].outs == 0 {
                continue;
            }
            for c in 0..4 {
                for p in Port::ALL {
                    let link = i * 8 + p.index();
                    if self.link_used[link] {
                        continue;
                    }
                    let Some(ray) = self.cells[i].out[c][p.index()] else { continue };
                    let (dx, dy) = p.delta();
                    let j = (i as i64 + dy as i64 * nn as i64 + dx as i64) as usize;
                    if self.cells[j].fifo[c].len() >= fa {
                        continue;
                    }
                    self.cells[i].out[c][p.index()] = None;
                    self.cells[i].outs -= 1;
                    self.cells[j].fifo[c].push_back(ray);
                    let k = &mut self.out.counts;
                    k.peak_fifo = k.peak_fifo.max(self.cells[j].fifo[c].len() as u16);
                    self.link_used[link] = true;
                    k.ray_messages += 1;
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
                    s.fifo.iter().map(VecDeque::len).collect::<Vec<_>>(),
                    s.outs,
                    s.launch.len(),
                    s.send.len()
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
}

/// One line of reflection counters for the job summaries.
pub fn summary(c: &ReflectCounts) -> String {
    format!(
        "reflections: {} cycles, {} trees, {} rays (deepest level {}), {} hits, {} exits, {} waits, {} voxel steps, {} ray + {} answer messages; cut by depth {}, by threshold {}; peak FIFO {}, wait table {}, send queue {}",
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
