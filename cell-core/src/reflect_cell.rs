//! §1.3.2, §5.5.5 — the reflection cell: one node of the distributed ray tree.
//!
//! After the light phase a cell knows the lit state of its voxels. For the reflection phase it
//! holds, in bounded stores whose capacities are const generics (`size_of::<ReflectCell<FA, W,
//! S>>()` is its RAM for this phase):
//!
//! * four ray **FIFOs** of `FA` rays, one per class of [`ReflectRay::class`] (the signs of the
//!   x and y steps), and one output slot per class and link: within a class every cell move
//!   strictly increases ±x ± y, so waits for FIFO room are acyclic and classes never wait for
//!   each other (the no-deadlock argument of the host's scheduler);
//! * the **wait table** of `W` entries: a voxel that reflects opens an entry (its local
//!   intensity, its Kr and where its own answer goes) and answers its parent only when its
//!   child's answer came back (§1.3.2);
//! * the **launch queue**: child rays waiting for room in their class's FIFO (one per open
//!   entry at most, so it holds `W`), outside the FIFOs, so that a full FIFO never blocks the
//!   hit that spawned a ray;
//! * the **send queue** of `S` answers waiting for the cell's router.
//!
//! Each cycle ([`ReflectCell::step`]) the cell does one voxel of work on the head of one FIFO
//! (round robin over the classes): a hit is shaded for the ray's direction and either reflects
//! (entry + child ray) or answers at once; a ray leaving the grid answers the background; then
//! it may launch one child ray and hand one answer to its router. An answer the router delivers
//! ([`ReflectCell::deliver`]) fills its entry: a root encodes the cell's pixel
//! (`local + Kr · answer`, §5.5.5), another entry queues its combined answer for its parent.
//!
//! **Overflow is counted, never silent.** A hit that would reflect while the wait table is full
//! answers at once instead (counted in [`ReflectCounters::wait_overflows`]: the tree is cut
//! there); an answer that finds the send queue full is lost and counted in
//! [`ReflectCounters::send_overflows`]. Either makes the host stop with an error naming the
//! cell and the capacity to raise. The FIFOs cannot overflow: a ray enters one only after the
//! credit check ([`ReflectCell::can_accept`], [`ReflectEnv::fa`] ≤ `FA`); a push beyond it is
//! refused and counted ([`ReflectCounters::fifo_overflows`]).
//!
//! ```
//! use cell_core::cell::Cell;
//! use cell_core::dexel::FacetTag;
//! use cell_core::plane::ColumnPlane;
//! use cell_core::ray::{Connectivity, Q};
//! use cell_core::reflect::{HitPoint, ReflectNormal};
//! use cell_core::reflect_cell::{ReflectCell, ReflectEnv, Surfaces};
//! use cell_core::shade::{Eye, Material, NormalMode, ShadeParams};
//! use cell_core::units::Span;
//!
//! // A mirror (material 0, Kr = 0.5) at z = 3 in column (1, 1) of a 4 × 4 × 8 grid: its ray goes
//! // back up along −z (the face flip) and leaves the grid.
//! let mut col = Cell::<4>::new(1, 1);
//! let _ = col.store.insert_on(Span { lo: 3, hi: 3 }, FacetTag::default(), &ColumnPlane::default());
//! let mats = [Material::default()];
//! let params = ShadeParams { ambient: [0.1; 3], normal_mode: NormalMode::Facet, eye: Eye::Grid };
//! let surfaces = Surfaces { mats: &mats, kr: &[0.5], lights: &[], params };
//! let env = ReflectEnv {
//!     depth: 1,
//!     threshold: 0.01,
//!     normal: ReflectNormal::Face,
//!     hit: HitPoint::Centre,
//!     skip_own_facet: true,
//!     connectivity: Connectivity::Six,
//!     fa: 2,
//!     span: 2 * Q * 8,
//!     n: 4,
//!     grid_depth: 8,
//! };
//! let mut cell = ReflectCell::<2, 4, 4>::new();
//! assert!(cell.plant_root(&col, &surfaces, &|_| 0, &env).unwrap());
//! let mut sent = None;
//! while sent.is_none() {
//!     cell.step(&col, &surfaces, &|_| 0, &env, |a| {
//!         sent = Some(a);
//!         true
//!     })
//!     .unwrap();
//! }
//! let a = sent.unwrap();
//! assert_eq!((a.dest, a.payload.1), ([1, 1], [0; 3])); // the background, to the root itself
//! cell.deliver(a.payload.0, a.payload.1);
//! assert!(cell.pixel.is_some() && cell.idle());
//! ```

use heapless::Deque;

use crate::cell::Cell;
use crate::dexel::Dexel;
use crate::light::{Port, SourceMask};
use crate::ray::{Connectivity, LineError};
use crate::reflect::{
    combine, hit_normal, hit_point, reflected_dir, to_answer, toward_origin, walk_start, Answer, HitPoint, Incident,
    ReflectNormal, ReflectRay, ReflectStep,
};
use crate::route::Routed;
use crate::shade::{encode, facing_mask, shade_linear_toward, shading_normal, Material, PointLight, ShadeParams, VIEW};
use crate::units::Depth;

/// An answer on its way to a waiting voxel: (its parent's wait-table slot, the intensity).
pub type ReflectAnswer = Routed<(u16, Answer)>;

/// The phase's settings, the same for every cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReflectEnv {
    /// Largest tree depth (reflections per path).
    pub depth: u8,
    /// Hall's threshold on the product of the Kr along a path (§1.2.5.1).
    pub threshold: f32,
    /// Normal that mirrors the rays (§5.2).
    pub normal: ReflectNormal,
    /// Where a reflected ray leaves the voxel it reflects from (§5.3).
    pub hit: HitPoint,
    /// Ignore voxels of the facet a ray left (§5.5.2).
    pub skip_own_facet: bool,
    /// Connectivity of the rays' lines.
    pub connectivity: Connectivity,
    /// FIFO limit per class (rays), 1 ..= the cell's `FA`.
    pub fa: usize,
    /// Span of a ray's line (lattice units): long enough to leave the grid from anywhere.
    pub span: i32,
    /// Grid side.
    pub n: u32,
    /// Grid depth.
    pub grid_depth: u32,
}

/// What the cells shade with: materials and their Kr by material id, lights, parameters.
#[derive(Clone, Copy, Debug)]
pub struct Surfaces<'a> {
    /// Materials by id.
    pub mats: &'a [Material],
    /// Kr by material id.
    pub kr: &'a [f32],
    /// The lights.
    pub lights: &'a [PointLight],
    /// Shading parameters (ambient, the normal mode of the visible voxels).
    pub params: ShadeParams,
}

impl Surfaces<'_> {
    fn material(&self, d: &Dexel) -> (Material, f32) {
        let i = d.material as usize;
        (self.mats.get(i).copied().unwrap_or_default(), self.kr.get(i).copied().unwrap_or(0.0))
    }

    /// The visible voxel of column (x, y) (dexel `d`, reached by the sources `reached`) as the
    /// camera sees it: linear local intensity and Kr.
    pub fn visible_local(&self, x: u16, y: u16, d: &Dexel, reached: SourceMask) -> ([f32; 3], f32) {
        let z = d.span.lo;
        let p = [x as f32, y as f32, z as f32];
        let nrm = shading_normal(d, self.params.normal_mode);
        let lit = facing_mask(p, nrm, self.lights, reached);
        let (m, kr) = self.material(d);
        (shade_linear_toward(p, nrm, VIEW, &m, self.lights, lit, &self.params), kr)
    }

    /// Voxel (x, y, z) of dexel `d` hit by `ray`: linear local intensity seen from the ray's
    /// origin, and Kr.
    #[allow(clippy::too_many_arguments)]
    pub fn hit_local(
        &self,
        x: u16,
        y: u16,
        z: Depth,
        d: &Dexel,
        ray: &ReflectRay,
        mode: ReflectNormal,
        reached: SourceMask,
    ) -> ([f32; 3], f32) {
        let p = [x as f32, y as f32, z as f32];
        let v = toward_origin(ray.dir);
        let nrm = hit_normal(d, mode, v, ray.entry, ray.dir);
        let lit = facing_mask(p, nrm, self.lights, reached);
        let (m, kr) = self.material(d);
        (shade_linear_toward(p, nrm, v, &m, self.lights, lit, &self.params), kr)
    }
}

/// The ray a voxel `at` of dexel `d` emits after being reached by the ray `incident` (the
/// primary ray: [`Incident::primary`]), from the point the environment's [`HitPoint`] rule
/// gives, answering to `parent`'s slot; `Ok(None)` when the mirrored direction is degenerate.
pub fn child_ray(
    at: [u16; 3],
    d: &Dexel,
    incident: &Incident,
    env: &ReflectEnv,
    parent: ([u16; 2], u16),
    level: u8,
    weight: f32,
) -> Result<Option<ReflectRay>, LineError> {
    let Some(dir) = reflected_dir(incident.dir, incident.entry, d.normal, env.normal, env.span) else {
        return Ok(None);
    };
    let from = walk_start(hit_point(at, incident, &d.plane, d.span.lo, env.hit), dir, at, env.connectivity);
    ReflectRay::leaving(from, dir, env.connectivity, parent.0, parent.1, d.facet, level, weight).map(Some)
}

/// A ray a cell could not build: the voxel and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RayError {
    /// The reflecting voxel.
    pub at: [u16; 3],
    /// Why.
    pub error: LineError,
}

/// A wait-table entry: a voxel waiting for its reflected ray's answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaitEntry {
    /// Where the combined answer goes (`None`: the root, the cell's pixel).
    pub parent: Option<([u16; 2], u16)>,
    /// Local linear intensity.
    pub local: [f32; 3],
    /// The voxel's Kr.
    pub kr: f32,
}

/// Per-cell counters of the phase.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReflectCounters {
    /// Trees rooted here (0 or 1).
    pub roots: u32,
    /// Rays launched into a FIFO (all levels).
    pub rays: u32,
    /// Voxel steps processed.
    pub ray_steps: u32,
    /// Answers handed to the router.
    pub answers: u32,
    /// Rays that hit a voxel here.
    pub hits: u32,
    /// Rays that left the grid from here.
    pub exits: u32,
    /// Hit voxels that reflected again and waited for their child.
    pub waits: u32,
    /// Deepest ray level launched here.
    pub max_level: u8,
    /// Reflective hit voxels that did not reflect: tree depth reached.
    pub cut_depth: u32,
    /// Reflective hit voxels that did not reflect: weight below the threshold.
    pub cut_threshold: u32,
    /// Cycles with a ray processed in vain (its output slot full).
    pub blocked: u32,
    /// Largest FIFO occupancy (one class).
    pub peak_fifo: u16,
    /// Largest number of open wait-table entries.
    pub peak_wait: u16,
    /// Largest send queue.
    pub peak_send: u16,
    /// Reflections refused for a full wait table (answered at once instead).
    pub wait_overflows: u32,
    /// Answers lost to a full send queue.
    pub send_overflows: u32,
    /// Rays refused by a full FIFO.
    pub fifo_overflows: u32,
    /// Answers delivered for a slot that was not open (a protocol error).
    pub stray_answers: u32,
}

impl ReflectCounters {
    /// Overflows of any store, and stray answers: each one makes the phase's result wrong.
    pub fn faults(&self) -> u32 {
        self.wait_overflows + self.send_overflows + self.fifo_overflows + self.stray_answers
    }
}

/// What an answer the router delivered did ([`ReflectCell::deliver`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delivered {
    /// It completed the cell's own tree: [`ReflectCell::pixel`] is set.
    Root,
    /// It completed an inner node: its combined answer is queued for its parent.
    Forwarded,
    /// Its slot was not open (counted).
    Stray,
}

/// The reflection cell: `FA` rays per class FIFO, `W` wait-table entries, `S` queued answers.
#[derive(Clone, Debug)]
pub struct ReflectCell<const FA: usize, const W: usize, const S: usize> {
    fifo: [Deque<ReflectRay, FA>; 4],
    out: [[Option<ReflectRay>; 8]; 4],
    outs: u8,
    table: [Option<WaitEntry>; W],
    open: u16,
    launch: Deque<ReflectRay, W>,
    send: Deque<ReflectAnswer, S>,
    rr: u8,
    /// The answer the cell's own tree received.
    pub root_answer: Option<Answer>,
    /// The cell's pixel with its reflection (sRGB), once its tree is answered.
    pub pixel: Option<[u8; 3]>,
    /// Counters.
    pub counters: ReflectCounters,
}

impl<const FA: usize, const W: usize, const S: usize> Default for ReflectCell<FA, W, S> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const FA: usize, const W: usize, const S: usize> ReflectCell<FA, W, S> {
    /// An idle cell.
    pub const fn new() -> Self {
        ReflectCell {
            fifo: [const { Deque::new() }; 4],
            out: [[None; 8]; 4],
            outs: 0,
            table: [None; W],
            open: 0,
            launch: Deque::new(),
            send: Deque::new(),
            rr: 0,
            root_answer: None,
            pixel: None,
            counters: ReflectCounters {
                roots: 0,
                rays: 0,
                ray_steps: 0,
                answers: 0,
                hits: 0,
                exits: 0,
                waits: 0,
                max_level: 0,
                cut_depth: 0,
                cut_threshold: 0,
                blocked: 0,
                peak_fifo: 0,
                peak_wait: 0,
                peak_send: 0,
                wait_overflows: 0,
                send_overflows: 0,
                fifo_overflows: 0,
                stray_answers: 0,
            },
        }
    }

    /// Open a wait-table entry; `None` (counted) when the table is full.
    fn open(&mut self, e: WaitEntry) -> Option<u16> {
        let Some(slot) = self.table.iter().position(Option::is_none) else {
            self.counters.wait_overflows += 1;
            return None;
        };
        self.table[slot] = Some(e);
        self.open += 1;
        Some(slot as u16)
    }

    fn close(&mut self, slot: u16) -> Option<WaitEntry> {
        let e = self.table.get_mut(slot as usize)?.take()?;
        self.open -= 1;
        Some(e)
    }

    /// Queue an answer for the router; lost and counted when the queue is full.
    fn queue(&mut self, a: ReflectAnswer) {
        if self.send.push_back(a).is_err() {
            self.counters.send_overflows += 1;
        }
    }

    /// Queue a child ray for launching; one launch entry per open entry, so there is room
    /// while the wait table has it, and an overflow is counted as the table's.
    fn queue_launch(&mut self, r: ReflectRay) {
        if self.launch.push_back(r).is_err() {
            self.counters.wait_overflows += 1;
        }
    }

    /// If the column's visible voxel reflects enough, open the root entry and queue its ray
    /// (or its black answer, for a degenerate direction); `true` if it did. `reached(z)`: the
    /// sources that lit voxel z of the column (the light phase's result).
    pub fn plant_root<const D: usize>(
        &mut self,
        cell: &Cell<D>,
        surfaces: &Surfaces,
        reached: &impl Fn(Depth) -> SourceMask,
        env: &ReflectEnv,
    ) -> Result<bool, RayError> {
        let Some(d) = cell.store.dexels().first() else { return Ok(false) };
        let (x, y) = (cell.x, cell.y);
        let (local, kr) = surfaces.visible_local(x, y, d, reached(d.span.lo));
        if !(kr > 0.0 && kr >= env.threshold) {
            return Ok(false);
        }
        let Some(slot) = self.open(WaitEntry { parent: None, local, kr }) else { return Ok(false) };
        let at = [x, y, d.span.lo];
        match child_ray(at, d, &Incident::primary(x, y), env, ([x, y], slot), 1, kr)
            .map_err(|error| RayError { at, error })?
        {
            Some(r) => self.queue_launch(r),
            None => self.queue(Routed { dest: [x, y], payload: (slot, [0; 3]) }),
        }
        self.counters.roots += 1;
        Ok(true)
    }

    /// One cycle of the cell (see the module doc): one voxel of work, one launch, one answer
    /// offered to the router through `send` (which says whether the router took it). Returns
    /// the moves made (0 ..= 3).
    pub fn step<const D: usize>(
        &mut self,
        cell: &Cell<D>,
        surfaces: &Surfaces,
        reached: &impl Fn(Depth) -> SourceMask,
        env: &ReflectEnv,
        send: impl FnOnce(ReflectAnswer) -> bool,
    ) -> Result<u32, RayError> {
        let mut moved = self.work(cell, surfaces, reached, env)? as u32;
        moved += self.launch(env.fa) as u32;
        if let Some(&m) = self.send.front() {
            if send(m) {
                let _ = self.send.pop_front();
                self.counters.answers += 1;
                moved += 1;
            }
        }
        let k = &mut self.counters;
        k.peak_wait = k.peak_wait.max(self.open);
        k.peak_send = k.peak_send.max(self.send.len() as u16);
        Ok(moved)
    }

    /// One voxel of work on the head ray of the next non-empty FIFO; `true` if it moved.
    fn work<const D: usize>(
        &mut self,
        cell: &Cell<D>,
        surfaces: &Surfaces,
        reached: &impl Fn(Depth) -> SourceMask,
        env: &ReflectEnv,
    ) -> Result<bool, RayError> {
        let Some(c) = (0..4).map(|o| (self.rr as usize + o) % 4).find(|&c| !self.fifo[c].is_empty()) else {
            return Ok(false);
        };
        self.rr = ((c + 1) % 4) as u8;
        let Some(head) = self.fifo[c].pop_front() else { return Ok(false) };
        let mut ray = head;
        match ray.advance(&cell.store, env.n, env.grid_depth, env.skip_own_facet) {
            ReflectStep::Hit(d, z) => {
                self.counters.hits += 1;
                self.hit(cell, surfaces, reached(z), env, &ray, &d, z)?;
            }
            ReflectStep::Exit => {
                self.counters.exits += 1;
                self.queue(Routed { dest: ray.parent, payload: (ray.slot, [0; 3]) });
            }
            // The slot `head` left is free.
            ReflectStep::Stay => {
                let _ = self.fifo[c].push_back(ray);
            }
            ReflectStep::Forward(p) if self.out[c][p.index()].is_none() => {
                self.out[c][p.index()] = Some(ray);
                self.outs += 1;
            }
            ReflectStep::Forward(_) => {
                let _ = self.fifo[c].push_back(head);
                self.counters.blocked += 1;
                return Ok(false);
            }
        }
        self.counters.ray_steps += 1;
        Ok(true)
    }

    /// `ray` hit voxel z (dexel `d`, reached by the sources `reached`): the voxel shades itself
    /// for the ray and either reflects (opens an entry, queues its child ray) or answers at once.
    #[allow(clippy::too_many_arguments)]
    fn hit<const D: usize>(
        &mut self,
        cell: &Cell<D>,
        surfaces: &Surfaces,
        reached: SourceMask,
        env: &ReflectEnv,
        ray: &ReflectRay,
        d: &Dexel,
        z: Depth,
    ) -> Result<(), RayError> {
        let (local, kr) = surfaces.hit_local(cell.x, cell.y, z, d, ray, env.normal, reached);
        let w = ray.weight * kr;
        let parent = (ray.parent, ray.slot);
        let reflects = kr > 0.0 && ray.level < env.depth && w >= env.threshold;
        if kr > 0.0 && !reflects {
            if ray.level >= env.depth {
                self.counters.cut_depth += 1;
            } else {
                self.counters.cut_threshold += 1;
            }
        }
        let child = match reflects.then(|| self.open(WaitEntry { parent: Some(parent), local, kr })).flatten() {
            Some(slot) => {
                let at = [cell.x, cell.y, z];
                let from = ([cell.x, cell.y], slot);
                let r = child_ray(at, d, &Incident::of(ray), env, from, ray.level + 1, w)
                    .map_err(|error| RayError { at, error })?;
                if r.is_none() {
                    self.close(slot);
                }
                r
            }
            None => None,
        };
        match child {
            Some(r) => {
                self.counters.waits += 1;
                self.queue_launch(r);
            }
            None => self.queue(Routed { dest: parent.0, payload: (parent.1, to_answer(local)) }),
        }
        Ok(())
    }

    /// Move the first waiting child ray into its class's FIFO if it holds fewer than `fa`;
    /// `true` if it did.
    fn launch(&mut self, fa: usize) -> bool {
        let Some(c) = self.launch.front().map(ReflectRay::class) else { return false };
        if self.fifo[c].len() >= fa.min(FA) {
            return false;
        }
        let Some(r) = self.launch.pop_front() else { return false };
        self.counters.max_level = self.counters.max_level.max(r.level);
        self.counters.rays += 1;
        let _ = self.fifo[c].push_back(r);
        self.counters.peak_fifo = self.counters.peak_fifo.max(self.fifo[c].len() as u16);
        true
    }

    /// An answer for wait-table slot `slot` delivered by the router: fills the entry.
    pub fn deliver(&mut self, slot: u16, answer: Answer) -> Delivered {
        let Some(e) = self.close(slot) else {
            self.counters.stray_answers += 1;
            return Delivered::Stray;
        };
        match e.parent {
            None => {
                self.root_answer = Some(answer);
                self.pixel = Some(combine(e.local, e.kr, answer).map(encode));
                Delivered::Root
            }
            Some((dest, pslot)) => {
                self.queue(Routed { dest, payload: (pslot, to_answer(combine(e.local, e.kr, answer))) });
                Delivered::Forwarded
            }
        }
    }

    /// Whether a neighbour may send a ray of class `class` now (the link's credit).
    pub fn can_accept(&self, class: usize, fa: usize) -> bool {
        self.fifo[class].len() < fa.min(FA)
    }

    /// A ray of class `class` arriving from a link; handed back (and counted) when its FIFO is
    /// full.
    pub fn accept(&mut self, class: usize, ray: ReflectRay) -> Result<(), ReflectRay> {
        self.fifo[class].push_back(ray).inspect_err(|_| self.counters.fifo_overflows += 1)?;
        self.counters.peak_fifo = self.counters.peak_fifo.max(self.fifo[class].len() as u16);
        Ok(())
    }

    /// The ray waiting in the output slot of class `class` toward `p`.
    pub fn out(&self, class: usize, p: Port) -> Option<&ReflectRay> {
        self.out[class][p.index()].as_ref()
    }

    /// Take the ray of the output slot of class `class` toward `p` (the link carried it).
    pub fn take_out(&mut self, class: usize, p: Port) -> Option<ReflectRay> {
        let r = self.out[class][p.index()].take();
        self.outs -= r.is_some() as u8;
        r
    }

    /// Rays waiting in output slots.
    pub fn outs(&self) -> u32 {
        self.outs as u32
    }

    /// Rays in each class's FIFO.
    pub fn fifo_lens(&self) -> [usize; 4] {
        [0, 1, 2, 3].map(|c| self.fifo[c].len())
    }

    /// Child rays waiting for FIFO room.
    pub fn launching(&self) -> usize {
        self.launch.len()
    }

    /// Answers waiting for the router.
    pub fn sending(&self) -> usize {
        self.send.len()
    }

    /// Open wait-table entries.
    pub fn waiting(&self) -> u16 {
        self.open
    }

    /// The open wait-table entries with their slots, in slot order.
    pub fn wait_table(&self) -> impl Iterator<Item = (u16, &WaitEntry)> {
        self.table.iter().enumerate().filter_map(|(i, e)| e.as_ref().map(|e| (i as u16, e)))
    }

    /// Nothing to do until an answer arrives.
    pub fn idle(&self) -> bool {
        self.outs == 0 && self.launch.is_empty() && self.send.is_empty() && self.fifo.iter().all(Deque::is_empty)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dexel::FacetTag;
    use crate::plane::ColumnPlane;
    use crate::ray::Q;
    use crate::shade::NormalMode;
    use crate::units::Span;

    const SPAN: i32 = 2 * Q * 8;

    fn mirror_column() -> Cell<4> {
        let mut c = Cell::<4>::new(1, 1);
        let _ = c.store.insert_on(Span { lo: 3, hi: 3 }, FacetTag::default(), &ColumnPlane::default());
        c
    }

    fn env(depth: u8, fa: usize) -> ReflectEnv {
        ReflectEnv {
            depth,
            threshold: 0.01,
            normal: ReflectNormal::Face,
            hit: HitPoint::Centre,
            skip_own_facet: true,
            connectivity: Connectivity::Six,
            fa,
            span: SPAN,
            n: 4,
            grid_depth: 8,
        }
    }

    /// A level-1 ray coming down column (1, 1) from z = 6 toward the mirror at z = 3.
    fn falling(slot: u16) -> ReflectRay {
        ReflectRay::leaving([Q, Q, 6 * Q], [0, 0, -SPAN], Connectivity::Six, [0, 0], slot, 7, 1, 1.0).unwrap()
    }

    fn surfaces(mats: &[Material]) -> Surfaces<'_> {
        let params = ShadeParams { ambient: [0.25; 3], normal_mode: NormalMode::Facet, eye: crate::shade::Eye::Grid };
        Surfaces { mats, kr: &[0.5], lights: &[], params }
    }

    /// Step until nothing is left to walk; the router refuses every answer.
    fn run_refusing<const FA: usize, const W: usize, const S: usize>(
        cell: &mut ReflectCell<FA, W, S>,
        col: &Cell<4>,
        env: &ReflectEnv,
    ) {
        let mats = [Material::default()];
        for _ in 0..16 {
            cell.step(col, &surfaces(&mats), &|_| 0, env, |_| false).unwrap();
        }
    }

    #[test]
    fn wait_table_overflow_at_capacity_plus_one_is_counted() {
        let col = mirror_column();
        let mut cell = ReflectCell::<4, 1, 4>::new();
        cell.accept(0, falling(0)).unwrap();
        run_refusing(&mut cell, &col, &env(2, 4));
        assert_eq!((cell.counters.hits, cell.counters.waits, cell.waiting()), (1, 1, 1), "exactly the capacity");
        assert_eq!(cell.counters.wait_overflows, 0);
        assert_eq!(cell.counters.faults(), 0);
        cell.accept(0, falling(1)).unwrap();
        run_refusing(&mut cell, &col, &env(2, 4));
        assert_eq!(cell.counters.hits, 2);
        assert_eq!(cell.counters.wait_overflows, 1, "capacity + 1: counted");
        assert_eq!(cell.waiting(), 1);
        // The first child left the grid (its black answer is queued); the refused voxel answered
        // at once: the tree is cut there, nothing is lost.
        assert_eq!((cell.counters.exits, cell.sending()), (1, 2));
        assert_eq!(cell.counters.faults(), 1);
    }

    #[test]
    fn send_queue_overflow_at_capacity_plus_one_is_counted() {
        let col = mirror_column();
        let mut cell = ReflectCell::<4, 4, 2>::new();
        for slot in 0..2 {
            cell.accept(0, falling(slot)).unwrap();
        }
        run_refusing(&mut cell, &col, &env(1, 4)); // depth 1: the hits answer at once
        assert_eq!((cell.counters.cut_depth, cell.sending()), (2, 2), "exactly the capacity");
        assert_eq!(cell.counters.send_overflows, 0);
        cell.accept(0, falling(2)).unwrap();
        run_refusing(&mut cell, &col, &env(1, 4));
        assert_eq!((cell.sending(), cell.counters.send_overflows), (2, 1), "capacity + 1: lost and counted");
        // The router takes them now: the queue drains, one per cycle.
        let mats = [Material::default()];
        let mut taken = 0;
        for _ in 0..2 {
            cell.step(&col, &surfaces(&mats), &|_| 0, &env(1, 4), |a| {
                taken += (a.dest == [0, 0]) as u32;
                true
            })
            .unwrap();
        }
        assert_eq!((taken, cell.counters.answers), (2, 2));
        assert!(cell.idle());
    }

    #[test]
    fn fifo_refuses_beyond_capacity_and_stray_answers_are_counted() {
        let mut cell = ReflectCell::<2, 2, 2>::new();
        assert!(cell.can_accept(0, 2));
        cell.accept(0, falling(0)).unwrap();
        cell.accept(0, falling(1)).unwrap();
        assert!(!cell.can_accept(0, 2) && !cell.can_accept(0, 64) && cell.can_accept(1, 2));
        assert_eq!(cell.accept(0, falling(2)), Err(falling(2)));
        assert_eq!((cell.counters.fifo_overflows, cell.counters.peak_fifo), (1, 2));
        assert_eq!(cell.deliver(1, [0; 3]), Delivered::Stray);
        assert_eq!(cell.counters.stray_answers, 1);
        assert_eq!(cell.counters.faults(), 2);
    }

    #[test]
    fn inner_node_combines_and_forwards() {
        let col = mirror_column();
        let mut cell = ReflectCell::<4, 2, 4>::new();
        cell.accept(0, falling(5)).unwrap();
        let mats = [Material::default()];
        for _ in 0..4 {
            // z = 6 → 5 → 4 → 3, then the hit: an entry and a child ray.
            cell.step(&col, &surfaces(&mats), &|_| 0, &env(2, 4), |_| false).unwrap();
        }
        assert_eq!((cell.counters.hits, cell.counters.rays, cell.waiting()), (1, 1, 1));
        // The child's answer, as the router would deliver it.
        assert_eq!(cell.deliver(0, [4096; 3]), Delivered::Forwarded);
        assert_eq!(cell.waiting(), 0);
        assert_eq!(cell.sending(), 1);
        // local (ambient 0.25 × ka 0) + 0.5 × 1.0 = 0.5 → Q12 2048, to the parent's slot 5.
        let mut got = None;
        cell.step(&col, &surfaces(&mats), &|_| 0, &env(2, 4), |a| {
            got = Some(a);
            true
        })
        .unwrap();
        assert_eq!(got.map(|a| (a.dest, a.payload)), Some(([0, 0], (5, [2048; 3]))));
    }

    #[test]
    fn ram_is_the_capacities_times_the_ray() {
        use core::mem::size_of;
        type Host = ReflectCell<{ crate::cell::REFLECT_FA_CAP }, { crate::cell::WAIT_CAP }, { crate::cell::SEND_CAP }>;
        let (fa, w, s) = (crate::cell::REFLECT_FA_CAP, crate::cell::WAIT_CAP, crate::cell::SEND_CAP);
        let stores = 4 * fa * size_of::<ReflectRay>()
            + 32 * size_of::<Option<ReflectRay>>()
            + w * (size_of::<Option<WaitEntry>>() + size_of::<ReflectRay>())
            + s * size_of::<ReflectAnswer>();
        let bookkeeping = size_of::<Host>() - stores;
        assert!(bookkeeping < 256, "{bookkeeping} bytes besides the stores");
    }
}
