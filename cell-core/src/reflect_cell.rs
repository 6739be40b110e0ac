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
//! * the **wait table** of `W` entries: a voxel that reflects or refracts opens an entry (its
//!   local intensity, its Kr and Kt·Tf, and where its own answer goes) and answers its parent
//!   only when its children's answers came back (§1.3.2: two children per node, the reflected
//!   and the refracted ray);
//! * the **launch queue** of `W` child rays waiting for room in their class's FIFO, outside
//!   the FIFOs, so that a full FIFO never blocks the hit that spawned a ray (without glass one
//!   child per open entry, so it cannot fill; a glass voxel's two children can: a child that
//!   finds it full is not made, its branch cut and counted as a wait-table overflow);
//! * the **send queue** of `S` answers waiting for the cell's router.
//!
//! Each cycle ([`ReflectCell::step`]) the cell does one voxel of work on the head of one FIFO
//! (round robin over the classes): a hit is shaded for the ray's direction and either reflects
//! (entry + child ray) or answers at once; a ray leaving the grid answers the background; then
//! it may launch one child ray and hand one answer to its router. An answer the router delivers
//! ([`ReflectCell::deliver`]) fills its branch of the entry; with every branch answered a root
//! encodes the cell's pixel (`local + Kr·I_R + Kt·Tf·I_T`, §1.1, §5.5.5), another entry queues
//! its combined answer for its parent.
//!
//! **Refraction** (§1.1, §1.2.5): a hit voxel whose material transmits ([`Transmit`], `Kt > 0`)
//! makes a second child, along Snell's direction computed with the stored normal
//! ([`transmitted_dir`], exact integers but the root, [`crate::refract`]) — entering the medium
//! where the ray meets the outer side of the facet (its winding), leaving on the inner side —
//! or, beyond the critical angle, along the mirrored direction (total internal reflection,
//! counted). Its answer comes back to the same entry under the slot's [`REFRACTED`] bit. Hall's
//! threshold and the depth limit apply to each branch with its own weight (`Kr` or `Kt`).
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
//! let surfaces = Surfaces { mats: &mats, kr: &[0.5], transmit: &[], lights: &[], params };
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
    hit_normal, hit_point, normal_int, reflected_dir, scaled, to_answer, toward_origin, walk_start, Answer, HitPoint,
    Incident, ReflectNormal, ReflectRay, ReflectStep, ANSWER_ONE,
};
use crate::refract::{refract, IorCode, Refraction, IOR_ONE};
use crate::route::Routed;
use crate::shade::{encode, facing_mask, shade_linear_toward, shading_normal, Material, PointLight, ShadeParams, VIEW};
use crate::units::{Depth, MaterialId};

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
    /// How each material transmits, by material id (a material past the end is opaque; empty:
    /// no refraction anywhere).
    pub transmit: &'a [Transmit],
    /// The lights.
    pub lights: &'a [PointLight],
    /// Shading parameters (ambient, the normal mode of the visible voxels).
    pub params: ShadeParams,
}

/// How a material transmits light (§1.1's refracted term `Kt·I_T`): its transparency, the filter
/// its colour passes through, and its index of refraction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transmit {
    /// Kt in 0..1 (0: opaque).
    pub kt: f32,
    /// Tf, the transmission filter per channel.
    pub tf: [f32; 3],
    /// The index of refraction (the medium on the inner side of the surface, air outside).
    pub ni: IorCode,
}

impl Transmit {
    /// No transmitted light.
    pub const OPAQUE: Transmit = Transmit { kt: 0.0, tf: [1.0; 3], ni: IOR_ONE };
}

impl Surfaces<'_> {
    fn material(&self, d: &Dexel) -> (Material, f32) {
        let i = d.material as usize;
        (self.mats.get(i).copied().unwrap_or_default(), self.kr.get(i).copied().unwrap_or(0.0))
    }

    /// How dexel `d`'s material transmits.
    pub fn transmit(&self, d: &Dexel) -> Transmit {
        self.transmit.get(d.material as usize).copied().unwrap_or(Transmit::OPAQUE)
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
    ray_along(at, d, incident, env, parent, level, weight, dir).map(Some)
}

/// The ray leaving voxel `at` of dexel `d` along `dir`, from the point the environment's
/// [`HitPoint`] rule gives for the ray `incident`.
#[allow(clippy::too_many_arguments)]
fn ray_along(
    at: [u16; 3],
    d: &Dexel,
    incident: &Incident,
    env: &ReflectEnv,
    parent: ([u16; 2], u16),
    level: u8,
    weight: f32,
    dir: [i32; 3],
) -> Result<ReflectRay, LineError> {
    let from = walk_start(hit_point(at, incident, &d.plane, d.span.lo, env.hit), dir, at, env.connectivity);
    ReflectRay::leaving(from, dir, env.connectivity, parent.0, parent.1, d.facet, level, weight)
}

/// The direction of the transmitted branch of a ray of direction `incident` (entered by the
/// faces `entry`) at a surface of normal code `normal` oriented by the facet's winding (outward
/// for a closed mesh) into or out of a medium of index `ni`: Snell's ([`refract`]) with the
/// stored normal — entering where the ray meets the outer side (`I·N < 0`: from air, index 1,
/// into `ni`), leaving on the inner side — or, beyond the critical angle, the reflected
/// direction (total internal reflection, `true`), scaled to a largest component of `span`;
/// `None` if degenerate.
pub fn transmitted_dir(
    incident: [i32; 3],
    entry: u8,
    normal: crate::normal::NormalCode,
    mode: ReflectNormal,
    ni: IorCode,
    span: i32,
) -> Option<([i32; 3], bool)> {
    let nv = normal_int(normal);
    if incident == [0; 3] || nv == [0; 3] {
        return None;
    }
    let (from, to) = if enters(incident, normal) { (IOR_ONE, ni) } else { (ni, IOR_ONE) };
    match refract(incident, nv, from, to) {
        Refraction::Through(t) => scaled(t, span).map(|t| (t, false)),
        Refraction::TotalInternal => reflected_dir(incident, entry, normal, mode, span).map(|r| (r, true)),
    }
}

/// The transmitted child of voxel `at` of dexel `d` (material transmitting as `t`) reached by
/// `incident`, answering to `parent`'s refracted slot: the ray and whether it was totally
/// internally reflected; `Ok(None)` when its direction is degenerate.
#[allow(clippy::too_many_arguments)]
pub fn transmitted_ray(
    at: [u16; 3],
    d: &Dexel,
    incident: &Incident,
    env: &ReflectEnv,
    parent: ([u16; 2], u16),
    level: u8,
    weight: f32,
    t: Transmit,
) -> Result<Option<(ReflectRay, bool)>, LineError> {
    let Some((dir, tir)) = transmitted_dir(incident.dir, incident.entry, d.normal, env.normal, t.ni, env.span) else {
        return Ok(None);
    };
    let slot = (parent.0, parent.1 | REFRACTED);
    ray_along(at, d, incident, env, slot, level, weight, dir).map(|mut r| {
        // Through the surface: into the solid from its outer side, out of it from the inner.
        if !tir {
            r.inside = enters(incident.dir, d.normal).then_some(d.material);
        }
        Some((r, tir))
    })
}

/// Whether a ray of direction `incident` meets a surface of normal code `normal` (its facet's
/// winding) on its outer side (`I·N < 0`): it enters the solid there.
fn enters(incident: [i32; 3], normal: crate::normal::NormalCode) -> bool {
    let nv = normal_int(normal);
    (0..3).map(|k| incident[k] as i64 * nv[k] as i64).sum::<i64>() < 0
}

/// The bit of an answer's slot that names the refracted child (clear: the reflected one).
pub const REFRACTED: u16 = 1 << 15;

/// The refracted child's weight per channel, Kt·Tf, when the voxel refracts (else 0).
fn transmitted(refracts: bool, t: Transmit) -> [f32; 3] {
    match refracts {
        true => t.tf.map(|f| t.kt * f),
        false => [0.0; 3],
    }
}

/// A ray a cell could not build: the voxel and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RayError {
    /// The reflecting voxel.
    pub at: [u16; 3],
    /// Why.
    pub error: LineError,
}

/// A wait-table entry: a voxel waiting for the answers of its reflected and refracted rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaitEntry {
    /// Where the combined answer goes (`None`: the root, the cell's pixel).
    pub parent: Option<([u16; 2], u16)>,
    /// Local linear intensity.
    pub local: [f32; 3],
    /// The reflected child's weight: the voxel's Kr (0 without a reflected child).
    pub kr: f32,
    /// The refracted child's weight per channel: Kt·Tf (0 without a refracted child).
    pub kt: [f32; 3],
    /// The children whose answers are awaited (bit 0: reflected, bit 1: refracted).
    pub pending: u8,
    /// What the children that answered add to `local`.
    pub acc: [f32; 3],
}

impl WaitEntry {
    /// An entry for a voxel of local intensity `local` whose children weigh `kr` and `kt`, none
    /// of them launched yet.
    pub const fn new(parent: Option<([u16; 2], u16)>, local: [f32; 3], kr: f32, kt: [f32; 3]) -> Self {
        WaitEntry { parent, local, kr, kt, pending: 0, acc: [0.0; 3] }
    }

    /// `local` plus what the children brought (§1.1: `I_local + Kr·I_R + Kt·Tf·I_T`).
    pub fn combined(&self) -> [f32; 3] {
        [0, 1, 2].map(|k| self.local[k] + self.acc[k])
    }
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
    /// Hit voxels that reflected or refracted again and waited for their children.
    pub waits: u32,
    /// Refracted (transmitted) child rays made, total internal reflections included.
    pub refracted: u32,
    /// Of those, rays beyond the critical angle, sent along the mirrored direction.
    pub total_internal: u32,
    /// Rays inside a transparent solid that met a voxel of another material, or left the grid,
    /// without crossing its surface (§5.5.2: a discrete line through a discrete surface).
    pub leaks: u32,
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
    /// It filled one branch of an entry that still waits for its other child.
    Waiting,
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
                refracted: 0,
                total_internal: 0,
                leaks: 0,
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

    /// Queue a child ray for launching; `false` (counted as a wait-table overflow: the branch is
    /// cut) when the launch queue is full.
    fn queue_child(&mut self, r: ReflectRay) -> bool {
        let room = self.launch.push_back(r).is_ok();
        self.counters.wait_overflows += !room as u32;
        room
    }

    /// Launch the children of the entry in `slot` for a voxel `at` of dexel `d` reached by
    /// `incident` — the reflected one if `w` (its weight) is `Some`, the refracted one if `t`
    /// is — and note which were made in the entry; the children made (bit 0: reflected, bit 1:
    /// refracted), none when every direction was degenerate (the entry is then still open).
    /// `inside`: the solid the incident ray travels in, where a reflected child stays.
    #[allow(clippy::too_many_arguments)]
    fn spawn(
        &mut self,
        slot: u16,
        at: [u16; 3],
        d: &Dexel,
        (incident, inside): (&Incident, Option<MaterialId>),
        env: &ReflectEnv,
        level: u8,
        w: Option<f32>,
        t: Option<(f32, Transmit)>,
    ) -> Result<u8, RayError> {
        let parent = ([at[0], at[1]], slot);
        let err = |error| RayError { at, error };
        let mut made = 0;
        if let Some(w) = w {
            if let Some(mut r) = child_ray(at, d, incident, env, parent, level, w).map_err(err)? {
                r.inside = inside;
                made |= self.queue_child(r) as u8;
            }
        }
        if let Some((wt, t)) = t {
            if let Some((mut r, tir)) = transmitted_ray(at, d, incident, env, parent, level, wt, t).map_err(err)? {
                if tir {
                    r.inside = inside;
                }
                self.counters.refracted += 1;
                self.counters.total_internal += tir as u32;
                made |= (self.queue_child(r) as u8) << 1;
            }
        }
        if let Some(Some(e)) = self.table.get_mut(slot as usize) {
            e.pending = made;
        }
        Ok(made)
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
        let t = surfaces.transmit(d);
        let reflects = kr > 0.0 && kr >= env.threshold;
        let refracts = t.kt > 0.0 && t.kt >= env.threshold;
        if !(reflects || refracts) {
            return Ok(false);
        }
        let entry = WaitEntry::new(None, local, if reflects { kr } else { 0.0 }, transmitted(refracts, t));
        let Some(slot) = self.open(entry) else { return Ok(false) };
        let at = [x, y, d.span.lo];
        let (w, wt) = (reflects.then_some(kr), refracts.then_some((t.kt, t)));
        if self.spawn(slot, at, d, (&Incident::primary(x, y), None), env, 1, w, wt)? == 0 {
            // No direction: the root answers itself black.
            if let Some(Some(e)) = self.table.get_mut(slot as usize) {
                e.pending = 1;
            }
            self.queue(Routed { dest: [x, y], payload: (slot, [0; 3]) });
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
                self.counters.leaks += ray.inside.is_some_and(|m| m != d.material) as u32;
                self.hit(cell, surfaces, reached(z), env, &ray, &d, z)?;
            }
            ReflectStep::Exit => {
                self.counters.exits += 1;
                self.counters.leaks += ray.inside.is_some() as u32;
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
        let t = surfaces.transmit(d);
        let (w, wt) = (ray.weight * kr, ray.weight * t.kt);
        let parent = (ray.parent, ray.slot);
        let reflects = self.grows(kr, w, ray.level, env);
        let refracts = self.grows(t.kt, wt, ray.level, env);
        let entry = WaitEntry::new(Some(parent), local, if reflects { kr } else { 0.0 }, transmitted(refracts, t));
        let waits = match (reflects || refracts).then(|| self.open(entry)).flatten() {
            Some(slot) => {
                let at = [cell.x, cell.y, z];
                let (w, wt) = (reflects.then_some(w), refracts.then_some((wt, t)));
                let made = self.spawn(slot, at, d, (&Incident::of(ray), ray.inside), env, ray.level + 1, w, wt)?;
                if made == 0 {
                    self.close(slot);
                }
                made != 0
            }
            None => false,
        };
        match waits {
            true => self.counters.waits += 1,
            false => self.queue(Routed { dest: parent.0, payload: (parent.1, to_answer(local)) }),
        }
        Ok(())
    }

    /// Whether a hit voxel's branch of coefficient `k` (Kr or Kt) and weight `w` (the path's
    /// product, this `k` included) grows the tree from a ray of level `level`; a cut is counted.
    fn grows(&mut self, k: f32, w: f32, level: u8, env: &ReflectEnv) -> bool {
        let grows = k > 0.0 && level < env.depth && w >= env.threshold;
        if k > 0.0 && !grows {
            if level >= env.depth {
                self.counters.cut_depth += 1;
            } else {
                self.counters.cut_threshold += 1;
            }
        }
        grows
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

    /// An answer for wait-table slot `slot` delivered by the router (its [`REFRACTED`] bit
    /// names the branch): adds the branch's share to the entry; once every child has answered
    /// the entry closes with `local + Kr·I_R + Kt·Tf·I_T` — the root's pixel, or an answer
    /// queued for its parent.
    pub fn deliver(&mut self, slot: u16, answer: Answer) -> Delivered {
        let (i, bit) = (slot & !REFRACTED, if slot & REFRACTED != 0 { 2 } else { 1 });
        let Some(e) = self.table.get_mut(i as usize).and_then(Option::as_mut).filter(|e| e.pending & bit != 0) else {
            self.counters.stray_answers += 1;
            return Delivered::Stray;
        };
        let w = if bit == 1 { [e.kr; 3] } else { e.kt };
        for k in 0..3 {
            e.acc[k] += w[k] * (answer[k] as f32 / ANSWER_ONE);
        }
        e.pending &= !bit;
        if bit == 1 && e.parent.is_none() {
            self.root_answer = Some(answer);
        }
        if e.pending != 0 {
            return Delivered::Waiting;
        }
        let Some(e) = self.close(i) else { return Delivered::Stray };
        match e.parent {
            None => {
                self.pixel = Some(e.combined().map(encode));
                Delivered::Root
            }
            Some((dest, pslot)) => {
                self.queue(Routed { dest, payload: (pslot, to_answer(e.combined())) });
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
        glass_surfaces(mats, &[0.5], &[])
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

    /// A glass column: a voxel at z = 3 of material 0 with normal `normal` (the facet's winding).
    fn glass_column(normal: [f32; 3]) -> Cell<4> {
        let mut c = Cell::<4>::new(1, 1);
        let tag = FacetTag { normal: crate::normal::NormalCode::encode(normal), ..FacetTag::default() };
        let _ = c.store.insert_on(Span { lo: 3, hi: 3 }, tag, &ColumnPlane::default());
        c
    }

    const GLASS: Transmit = Transmit { kt: 0.5, tf: [0.5, 1.0, 1.5], ni: 384 };

    fn glass_surfaces<'a>(mats: &'a [Material], kr: &'a [f32], transmit: &'a [Transmit]) -> Surfaces<'a> {
        let params = ShadeParams { ambient: [0.25; 3], normal_mode: NormalMode::Facet, eye: crate::shade::Eye::Grid };
        Surfaces { mats, kr, transmit, lights: &[], params }
    }

    /// Step `cell` (column `col`) `k` times, the router refusing every answer.
    fn steps(cell: &mut ReflectCell<4, 2, 4>, col: &Cell<4>, s: &Surfaces, env: &ReflectEnv, k: usize) {
        for _ in 0..k {
            cell.step(col, s, &|_| 0, env, |_| false).unwrap();
        }
    }

    /// f64 Snell, the oracle: unit `i`, `n`, η = n₁/n₂; `None` beyond the critical angle.
    fn snell(i: [f64; 3], n: [f64; 3], eta: f64) -> Option<[f64; 3]> {
        let d = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let n = if d(n, i) > 0.0 { n.map(|c| -c) } else { n };
        let c1 = -d(n, i);
        let k = 1.0 - eta * eta * (1.0 - c1 * c1);
        (k >= 0.0).then(|| [0, 1, 2].map(|j| eta * i[j] + (eta * c1 - k.sqrt()) * n[j]))
    }

    fn unit(v: [f64; 3]) -> [f64; 3] {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| c / l)
    }

    #[test]
    fn a_glass_voxel_refracts_straight_through_at_normal_incidence() {
        let col = glass_column([0.0, 0.0, 1.0]);
        let mats = [Material::default()];
        let s = glass_surfaces(&mats, &[0.0], &[GLASS]);
        let mut cell = ReflectCell::<4, 2, 4>::new();
        cell.accept(0, falling(5)).unwrap();
        steps(&mut cell, &col, &s, &env(2, 4), 4); // z = 6 → 3, then the hit
        let k = cell.counters;
        assert_eq!((k.hits, k.waits, k.refracted, k.total_internal, cell.waiting()), (1, 1, 1, 0, 1));
        let child = cell.fifo.iter().flatten().chain(cell.launch.iter()).next().copied().expect("a refracted child");
        assert_eq!(child.dir, [0, 0, -SPAN], "normal incidence: Snell's direction is the incident one");
        assert_eq!((child.slot, child.level, child.weight), (REFRACTED, 2, 0.5));
        // The child goes on down and leaves the grid: its black answer to the refracted slot.
        let mut got = None;
        for _ in 0..8 {
            cell.step(&col, &s, &|_| 0, &env(2, 4), |a| {
                got.get_or_insert(a);
                false
            })
            .unwrap();
        }
        assert_eq!(got.map(|a| (a.dest, a.payload)), Some(([1, 1], (REFRACTED, [0; 3]))));
        assert_eq!(cell.deliver(0, [4096; 3]), Delivered::Stray, "no reflected child was made");
        assert_eq!(cell.deliver(REFRACTED, [0; 3]), Delivered::Forwarded);
        assert_eq!(cell.waiting(), 0);
    }

    #[test]
    fn both_children_answer_before_the_entry_combines() {
        let col = glass_column([0.0, 0.0, 1.0]);
        let mats = [Material::default()];
        let s = glass_surfaces(&mats, &[0.5], &[GLASS]);
        let mut cell = ReflectCell::<4, 2, 4>::new();
        cell.accept(0, falling(5)).unwrap();
        steps(&mut cell, &col, &s, &env(2, 4), 4);
        assert_eq!((cell.counters.waits, cell.counters.refracted, cell.launching() + cell.fifo_lens()[0]), (1, 1, 2));
        assert_eq!(cell.deliver(REFRACTED, [4096; 3]), Delivered::Waiting, "the reflected child is still out");
        assert_eq!(cell.deliver(REFRACTED, [4096; 3]), Delivered::Stray, "one answer per branch");
        assert_eq!(cell.deliver(0, [4096; 3]), Delivered::Forwarded);
        // local 0 (ambient × ka 0) + Kr 0.5 × 1 + Kt·Tf (0.25, 0.5, 0.75) × 1, in Q12.
        let mut got = None;
        for _ in 0..16 {
            cell.step(&col, &s, &|_| 0, &env(2, 4), |a| {
                if a.dest == [0, 0] {
                    got = Some(a.payload);
                }
                a.dest == [0, 0]
            })
            .unwrap();
        }
        assert_eq!(got, Some((5, [3072, 4096, 5120])));
    }

    #[test]
    fn beyond_the_critical_angle_the_transmitted_share_is_mirrored() {
        // A ray rising through glass (n = 1.5) to its top face (outward normal +z): leaving at
        // sin θ = 2/√5 > 1/1.5, so no ray gets out; the child goes back down, mirrored.
        let (s_, n) = (SPAN / 2, crate::normal::NormalCode::encode([0.0, 0.0, 1.0]));
        // (The stored normal is +z within its code's quantisation: the mirror image within a
        // few lattice units.)
        let (r, tir) = transmitted_dir([2 * s_, 0, s_], 0, n, ReflectNormal::Facet, 384, SPAN).unwrap();
        assert!(tir && r[0] == SPAN && r[1].abs() <= 2 && (r[2] + SPAN / 2).abs() <= 4, "{r:?}");
        // A steeper one (sin θ = 1/√5 < 1/1.5) gets out, bent away from the normal.
        let (t, tir) = transmitted_dir([s_, 0, 2 * s_], 0, n, ReflectNormal::Facet, 384, SPAN).unwrap();
        assert!(!tir && t[0] > 0 && t[2] > 0 && t[0] * 2 > t[2], "{t:?}");
        // From the outer side there is never total internal reflection.
        assert!(matches!(transmitted_dir([2 * s_, 0, -s_], 0, n, ReflectNormal::Facet, 384, SPAN), Some((_, false))));
    }

    #[test]
    fn transmitted_directions_are_snells_law_in_f64() {
        // Directions and normals on a grid of integer vectors, glass (1.5) and a dense one (2.4).
        let mut checked = 0;
        for ni in [384u16, 614] {
            for (ix, iy, iz) in (-3..=3).flat_map(|x| (-3..=3).flat_map(move |y| (-3..=3).map(move |z| (x, y, z)))) {
                let i = [ix * 1000, iy * 1000, iz * 1000 + 7];
                for nv in [[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [-0.48, 0.6, 0.64], [0.0, -1.0, 0.0]] {
                    let code = crate::normal::NormalCode::encode(nv);
                    let n = normal_int(code).map(f64::from);
                    let (iu, nu) = (unit(i.map(f64::from)), unit(n));
                    let a: f64 = (0..3).map(|k| iu[k] * nu[k]).sum();
                    let eta = if a < 0.0 { 256.0 / ni as f64 } else { ni as f64 / 256.0 };
                    let got = transmitted_dir(i, 0, code, ReflectNormal::Facet, ni, SPAN).unwrap();
                    match snell(iu, nu, eta) {
                        Some(t) => {
                            assert!(!got.1, "{i:?} {n:?}: Snell has a transmitted ray");
                            let g = unit(got.0.map(f64::from));
                            let err = (0..3).map(|k| (g[k] - t[k]).abs()).fold(0.0, f64::max);
                            // The direction's own rounding to `span` steps (1/SPAN) dominates.
                            assert!(err < 4.0 / SPAN as f64, "{i:?} {n:?}: {g:?} vs {t:?}");
                        }
                        None => {
                            assert!(got.1, "{i:?} {n:?}: beyond the critical angle");
                            let r = [0, 1, 2].map(|k| iu[k] - 2.0 * a * nu[k]);
                            let g = unit(got.0.map(f64::from));
                            assert!((0..3).all(|k| (g[k] - r[k]).abs() < 4.0 / SPAN as f64), "{g:?} vs mirror {r:?}");
                        }
                    }
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 2 * 343 * 4);
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
        // Queue indices, flags, the pixel and the counters (21 of them).
        assert!(bookkeeping < 320, "{bookkeeping} bytes besides the stores");
    }
}
