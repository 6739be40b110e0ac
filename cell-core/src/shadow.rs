//! §4.1.2–4.1.3 — the classic shadow-ray cell: what one cell runs when shadows are found by
//! rays walked toward the source instead of beams diffused from it.
//!
//! For one source, a cell **emits** rays toward it from its column ([`ShadowEnv`]: its visible
//! surface's, and with [`ShadowEnv::all_voxels`] one per occupied voxel, the thesis's count ΣSᵢ
//! of §4.1.6), **walks** the rays that are in its column one voxel per cycle
//! ([`ShadowRay::advance`]), hands a ray that enters a neighbour column to the output slot of
//! that link, and turns a ray that ends into an **answer** ([`ShadowAnswer`]) for its router,
//! addressed to the emitter. The emitter's router hands the answer back to the emitter's cell,
//! which records it ([`ShadowCell::deliver`]).
//!
//! **Lit rules.** Under the thesis's rule a ray leaves each emitting voxel's centre and any
//! occupied voxel of another facet stops it; under the plane rule it leaves the visible surface
//! and stops only where it crosses a voxel's plane ([`crate::ray`]); under exact occluders
//! ([`LitRule::Exact`], cell-core's `exact-occluders` feature) it walks the same line and the
//! triangles of each column it enters, handed to [`ShadowCell::step`], are tested once against
//! the exact segment from the light to ¼ voxel in front of the surface
//! ([`ShadowRay::exact`]): the segment against every triangle of the scene, unless a column's
//! store was full. A surface whose plane turns away from the source emits no ray (counted in
//! [`ShadowCounters::back_facing`]).
//!
//! **Bounded stores, counted overflow.** The ray FIFO holds at most `FA` rays (a const generic:
//! `size_of::<ShadowCell<FA>>()` is the cell's RAM for this phase) and the run-time limit
//! [`ShadowEnv::fa`] ≤ `FA` is the credit a neighbour checks ([`ShadowCell::can_accept`]) before
//! a ray crosses the link. Emitted rays take FIFO room like arriving ones: the cell does not
//! materialise its emission (a wall column would emit a ray per voxel) but generates the next
//! ray from its dexels when its FIFO is below the limit ([`ShadowCell::launch`]); a cell with
//! emission left stays busy. Each output link has one slot. A ray pushed into a full FIFO
//! (a sender ignoring the credit) is handed back and counted in
//! [`ShadowCounters::overflows`]: never silent.
//!
//! **No loss** (§4.4.2): the head ray is processed only if its result can go on now: the output
//! slot of its link is free, or the router takes its answer. Otherwise the ray goes back,
//! unadvanced, to the FIFO's tail and the cell is *blocked* for the cycle.
//!
//! **No deadlock** (thesis §4.1.3 with the argument of [`crate::light`]): every ray ends in the
//! source's voxel and each of its cell steps strictly decreases |x − x_s| + |y − y_s|
//! ([`ShadowRay::new`]), so waits for FIFO room are acyclic; an emission waits only for its own
//! FIFO to drain; answers travel on a network that is deadlock-free by itself
//! ([`crate::route`]).
//!
//! ```
//! use cell_core::cell::Cell;
//! use cell_core::dexel::FacetTag;
//! use cell_core::lit::LitRule;
//! use cell_core::plane::ColumnPlane;
//! use cell_core::ray::{Connectivity, Q};
//! use cell_core::shadow::{ShadowCell, ShadowEnv, ShadowStep};
//! use cell_core::units::Span;
//!
//! // Column (0, 0) holds voxel z = 2; the source is straight above it, at z = 5.
//! let mut col = Cell::<4>::new(0, 0);
//! let _ = col.store.insert_on(Span { lo: 2, hi: 2 }, FacetTag::default(), &ColumnPlane::default());
//! let env = ShadowEnv {
//!     source: [0, 0, 5 * Q],
//!     rule: LitRule::Thesis,
//!     connectivity: Connectivity::Six,
//!     all_voxels: false,
//!     bias: 0,
//!     fa: 4,
//! };
//! let mut cell = ShadowCell::<4>::new();
//! cell.start(&col, &env).unwrap(); // one ray, from the visible voxel
//! assert_eq!(cell.counters.rays, 1);
//! let mut answers = Vec::new();
//! let mut steps = 0;
//! while cell.busy() {
//!     let s = cell.step(&col.store, &[], |a| {
//!         answers.push(a);
//!         true
//!     });
//!     assert_ne!(s, ShadowStep::Blocked);
//!     steps += 1;
//! }
//! // z = 2, 3, 4 walked, then z = 5 is the source's voxel: the end of the line, lit.
//! assert_eq!(steps, 4);
//! assert_eq!(answers.len(), 1);
//! assert_eq!((answers[0].dest, answers[0].payload), ([0, 0], cell_core::shadow::ANSWER_LIT | cell_core::shadow::ANSWER_SURFACE));
//! cell.deliver(answers[0].payload, 1);
//! assert_eq!(cell.mask, 1);
//! ```

use heapless::Deque;

use crate::cell::Cell;
use crate::dexel::DexelStore;
use crate::light::{Port, SourceMask};
use crate::lit::LitRule;
use crate::occluder::Triangle;
use crate::ray::{lattice_depth, Connectivity, LineError, RayStep, RayWalk, ShadowRay, Q};
use crate::receiver::POINT_UNITS;
use crate::route::Routed;
use crate::units::Depth;

/// Answer payload bit: the ray reached the source.
pub const ANSWER_LIT: u8 = 1;
/// Answer payload bit: the ray left the surface the emitter's pixel shows.
pub const ANSWER_SURFACE: u8 = 2;

/// An answer on its way back to the emitter: payload bits [`ANSWER_LIT`], [`ANSWER_SURFACE`].
pub type ShadowAnswer = Routed<u8>;

/// What the cells need to know about the phase for one source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadowEnv {
    /// The source on the 1/[`Q`] lattice of the rays.
    pub source: [i32; 3],
    /// Which voxels stop a ray (the plane rule walks 6-connected rays only).
    pub rule: LitRule,
    /// Connectivity of the rays.
    pub connectivity: Connectivity,
    /// Every occupied voxel emits, not only the visible surface (the thesis's count, §4.1.6).
    pub all_voxels: bool,
    /// Shadow bias: voxels after the emitter's own a ray does not test
    /// ([`ShadowRay::with_bias`]).
    pub bias: u8,
    /// FIFO limit (rays), 1 ..= the cell's `FA`.
    pub fa: usize,
}

/// A ray the cell could not build (a coordinate or span beyond the ray's bit budget).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmitError {
    /// The emitting voxel's z.
    pub z: i32,
    /// Why.
    pub error: LineError,
}

/// What one call of [`ShadowCell::step`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowStep {
    /// No ray in the FIFO.
    Idle,
    /// The head ray ended; its answer went to the router (`true`: lit).
    Answered(bool),
    /// The head ray went one voxel on (same column, or into an output slot).
    Moved,
    /// The head ray's result could not go on: back to the FIFO's tail, unadvanced.
    Blocked,
}

/// Per-cell counters of one source's run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ShadowCounters {
    /// Rays emitted.
    pub rays: u32,
    /// Emitters whose plane turns away from the source (plane rule): no ray, in shadow.
    pub back_facing: u32,
    /// Voxel steps processed (at most one per cycle).
    pub steps: u32,
    /// Cycles with rays waiting and none processable.
    pub blocked: u32,
    /// "Lit" answers received.
    pub lit: u32,
    /// Rays pushed into a full FIFO (refused, handed back).
    pub overflows: u32,
}

/// Whether a pixel lies on the edge of a diffused shadow: it shows a surface, lit (`own`) or
/// not by the source, and a neighbour that shows one (each of the 8 links brings the
/// neighbour's bit, `None` where it shows nothing or there is no neighbour) has the other bit.
///
/// Shadow-edge refinement (rc2's, after diffusion; not the thesis's): the pixels on an edge are
/// where the diffused answer may be off — its target ray passes up to half a voxel from the
/// exact ray to the pixel — and they alone send a classic shadow ray, whose answer replaces
/// the diffused one. One exchange of a bit per link and source finds them.
///
/// ```
/// use cell_core::shadow::on_shadow_edge;
///
/// let dark = [Some(false); 8];
/// assert!(!on_shadow_edge(Some(false), dark)); // inside a shadow
/// let mut edge = dark;
/// edge[3] = Some(true);
/// assert!(on_shadow_edge(Some(false), edge)); // one lit neighbour
/// assert!(!on_shadow_edge(None, edge)); // no surface, no ray
/// assert!(!on_shadow_edge(Some(true), [None; 8])); // a pixel alone
/// ```
pub fn on_shadow_edge(own: Option<bool>, around: [Option<bool>; 8]) -> bool {
    own.is_some_and(|o| around.iter().flatten().any(|&b| b != o))
}

/// Where the next emission comes from: the visible surface (plane rule), then the voxels of the
/// dexels in order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Emitter {
    /// The plane rule's visible-surface ray is still to emit.
    surface: bool,
    /// The next voxel to emit from: (dexel index, z).
    next: Option<(u16, Depth)>,
}

/// The classic shadow-ray cell of one column, with room for `FA` rays (see the module doc).
#[derive(Clone, Debug)]
pub struct ShadowCell<const FA: usize> {
    fifo: Deque<ShadowRay, FA>,
    out: [Option<ShadowRay>; 8],
    outs: u8,
    emitter: Emitter,
    /// Sources whose "lit" answer reached the visible surface.
    pub mask: SourceMask,
    /// Counters.
    pub counters: ShadowCounters,
}

impl<const FA: usize> Default for ShadowCell<FA> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const FA: usize> ShadowCell<FA> {
    /// An idle cell.
    pub const fn new() -> Self {
        ShadowCell {
            fifo: Deque::new(),
            out: [None; 8],
            outs: 0,
            emitter: Emitter { surface: false, next: None },
            mask: 0,
            counters: ShadowCounters { rays: 0, back_facing: 0, steps: 0, blocked: 0, lit: 0, overflows: 0 },
        }
    }

    /// Start a source: point the emitter at the column's surfaces and launch what fits.
    pub fn start<const D: usize>(&mut self, cell: &Cell<D>, env: &ShadowEnv) -> Result<(), EmitError> {
        let first = cell.store.dexels().first().map(|d| (0, d.span.lo));
        self.emitter = if env.rule.shades_visible_surface() {
            Emitter { surface: cell.visible.is_some(), next: first.filter(|_| env.all_voxels) }
        } else {
            Emitter { surface: false, next: first }
        };
        self.launch(cell, env).map(|_| ())
    }

    /// [`ShadowCell::start`] if `emit`, else nothing to emit: the cell only walks the rays that
    /// reach it and records answers. Shadow-edge refinement starts the pixels
    /// [`on_shadow_edge`] names this way.
    pub fn start_if<const D: usize>(&mut self, cell: &Cell<D>, env: &ShadowEnv, emit: bool) -> Result<(), EmitError> {
        if emit {
            self.start(cell, env)
        } else {
            self.emitter = Emitter::default();
            Ok(())
        }
    }

    /// Emit rays while the FIFO is below the limit and emission is left; returns how many.
    pub fn launch<const D: usize>(&mut self, cell: &Cell<D>, env: &ShadowEnv) -> Result<u32, EmitError> {
        let mut launched = 0;
        while self.fifo.len() < env.fa.min(FA) && self.emitting() {
            match self.next_ray(cell, env)? {
                Some(ray) => {
                    // Room checked above.
                    let _ = self.fifo.push_back(ray.with_bias(env.bias));
                    self.counters.rays += 1;
                    launched += 1;
                }
                None => self.counters.back_facing += 1,
            }
        }
        Ok(launched)
    }

    /// Whether emission is left.
    pub fn emitting(&self) -> bool {
        self.emitter.surface || self.emitter.next.is_some()
    }

    /// The next emission (`None`: a surface facing away from the source), advancing the emitter.
    fn next_ray<const D: usize>(&mut self, cell: &Cell<D>, env: &ShadowEnv) -> Result<Option<ShadowRay>, EmitError> {
        let err = |z: i32| move |error| EmitError { z, error };
        if core::mem::take(&mut self.emitter.surface) {
            let v = cell.visible.as_ref().expect("the plane rule emits from a visible surface");
            let ray = if env.rule.is_exact() {
                // The pixel's point, as the receiver takes it.
                let p = crate::receiver::pixel_point(cell.x as i32, cell.y as i32, v)
                    .ok_or(err(v.z_v)(LineError::CoordinateTooLarge))?;
                ShadowRay::exact(p, &v.plane, v.z_v, env.source, v.facet)
            } else {
                let a = [cell.x as i32 * Q, cell.y as i32 * Q, lattice_depth(v.num, v.den)];
                ShadowRay::on_plane(a, &v.plane, v.z_v, env.source, v.facet)
            };
            return Ok(ray.map_err(err(v.z_v))?.map(ShadowRay::for_surface));
        }
        let (i, z) = self.emitter.next.expect("emission left");
        let dexels = cell.store.dexels();
        let d = &dexels[i as usize];
        self.emitter.next = match env.all_voxels {
            false => None,
            true if z < d.span.hi => Some((i, z + 1)),
            true => dexels.get(i as usize + 1).map(|n| (i + 1, n.span.lo)),
        };
        match env.rule {
            LitRule::Thesis => {
                let ray = ShadowRay::new([cell.x, cell.y, z], env.source, env.connectivity, d.facet)
                    .map_err(err(z as i32))?;
                Ok(Some(if i == 0 && z == d.span.lo { ray.for_surface() } else { ray }))
            }
            _ if env.rule.is_exact() => {
                let p = [cell.x as i64, cell.y as i64, z as i64].map(|v| v * POINT_UNITS);
                ShadowRay::exact(p, &d.plane, d.span.lo as i32, env.source, d.facet).map_err(err(z as i32))
            }
            _ => {
                let centre = [cell.x as i32, cell.y as i32, z as i32].map(|v| v * Q);
                ShadowRay::on_plane(centre, &d.plane, d.span.lo as i32, env.source, d.facet).map_err(err(z as i32))
            }
        }
    }

    /// Whether a neighbour may send a ray now (the credit of the link), FIFO limit `fa`.
    pub fn can_accept(&self, fa: usize) -> bool {
        self.fifo.len() < fa.min(FA)
    }

    /// A ray arriving from a link; handed back (and counted) when the FIFO is full.
    // The ray itself comes back: no allocation to box it in, and nothing may be lost.
    #[allow(clippy::result_large_err)]
    pub fn accept(&mut self, ray: ShadowRay) -> Result<(), ShadowRay> {
        self.fifo.push_back(ray).inspect_err(|_| self.counters.overflows += 1)
    }

    /// One voxel of work on the FIFO's head (see the module doc). `send` offers an answer to the
    /// cell's router and says whether it took it.
    ///
    /// `triangles` are the column's own (exact occluders; empty otherwise): a ray under exact
    /// occluders is tested against them in its first voxel of the column
    /// ([`ShadowRay::advance_exact`]).
    pub fn step<const D: usize>(
        &mut self,
        store: &DexelStore<D>,
        triangles: &[Triangle],
        send: impl FnOnce(ShadowAnswer) -> bool,
    ) -> ShadowStep {
        let Some(head) = self.fifo.pop_front() else { return ShadowStep::Idle };
        let mut ray = head;
        let step = match ray.walk {
            RayWalk::Exact(_) => ray.advance_exact(triangles),
            _ => ray.advance(store),
        };
        let done = match step {
            RayStep::Shadow | RayStep::Lit => {
                let lit = step == RayStep::Lit;
                let payload = if lit { ANSWER_LIT } else { 0 } | if ray.surface { ANSWER_SURFACE } else { 0 };
                send(Routed { dest: ray.emitter, payload }).then_some(ShadowStep::Answered(lit))
            }
            RayStep::Stay => {
                // The slot `head` left is free.
                let _ = self.fifo.push_back(ray);
                Some(ShadowStep::Moved)
            }
            RayStep::Forward(p) => self.out[p.index()].is_none().then(|| {
                self.out[p.index()] = Some(ray);
                self.outs += 1;
                ShadowStep::Moved
            }),
        };
        match done {
            Some(s) => {
                self.counters.steps += 1;
                s
            }
            None => {
                let _ = self.fifo.push_back(head);
                self.counters.blocked += 1;
                ShadowStep::Blocked
            }
        }
    }

    /// An answer the router delivered to this (emitting) cell, for the source of bit `bit`.
    pub fn deliver(&mut self, payload: u8, bit: SourceMask) {
        if payload & ANSWER_LIT != 0 {
            self.counters.lit += 1;
            if payload & ANSWER_SURFACE != 0 {
                self.mask |= bit;
            }
        }
    }

    /// The ray waiting in the output slot toward `p`.
    pub fn out(&self, p: Port) -> Option<&ShadowRay> {
        self.out[p.index()].as_ref()
    }

    /// Take the ray of the output slot toward `p` (the link carried it).
    pub fn take_out(&mut self, p: Port) -> Option<ShadowRay> {
        let r = self.out[p.index()].take();
        self.outs -= r.is_some() as u8;
        r
    }

    /// Rays in the FIFO.
    pub fn fifo_len(&self) -> usize {
        self.fifo.len()
    }

    /// The FIFO's rays, head first.
    pub fn fifo(&self) -> impl Iterator<Item = &ShadowRay> {
        self.fifo.iter()
    }

    /// Whether any output slot holds a ray.
    pub fn has_out(&self) -> bool {
        self.outs > 0
    }

    /// Whether the cell has anything to do: rays to walk or send, emission left.
    pub fn busy(&self) -> bool {
        !self.fifo.is_empty() || self.outs > 0 || self.emitting()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dexel::FacetTag;
    use crate::plane::ColumnPlane;
    use crate::units::Span;

    fn column(spans: &[(u16, u16)]) -> Cell<8> {
        let mut c = Cell::<8>::new(1, 1);
        for (k, &(lo, hi)) in spans.iter().enumerate() {
            let tag = FacetTag { facet: k as u32, ..Default::default() };
            let _ = c.store.insert_on(Span { lo, hi }, tag, &ColumnPlane::default());
        }
        c
    }

    fn env(all_voxels: bool, fa: usize) -> ShadowEnv {
        ShadowEnv {
            source: [6 * Q, Q, 9 * Q],
            rule: LitRule::Thesis,
            connectivity: Connectivity::Six,
            all_voxels,
            bias: 0,
            fa,
        }
    }

    #[test]
    fn emission_waits_for_fifo_room_and_covers_every_voxel() {
        let col = column(&[(2, 4), (7, 8)]);
        let mut cell = ShadowCell::<3>::new();
        cell.start(&col, &env(true, 2)).unwrap();
        assert_eq!((cell.fifo_len(), cell.counters.rays), (2, 2), "the FIFO limit bounds the emission");
        assert!(cell.emitting());
        let zs: heapless::Vec<i32, 8> = cell.fifo().map(|r| r.emitter_z).collect();
        assert_eq!(zs, [2, 3]);
        assert!(cell.fifo().next().unwrap().surface && !cell.fifo().nth(1).unwrap().surface);
        let mut emitted = zs;
        while cell.emitting() {
            let _ = cell.fifo.pop_front();
            let before = cell.fifo_len();
            assert_eq!(cell.launch(&col, &env(true, 2)).unwrap(), 1);
            emitted.push(cell.fifo().nth(before).unwrap().emitter_z).unwrap();
        }
        assert_eq!(emitted, [2, 3, 4, 7, 8], "one ray per occupied voxel, in column order");
        assert_eq!(cell.counters.rays, 5);
    }

    #[test]
    fn fifo_overflow_at_capacity_plus_one_is_counted() {
        let col = column(&[(0, 7)]);
        let mut cell = ShadowCell::<4>::new();
        cell.start(&col, &env(true, 4)).unwrap();
        assert_eq!(cell.fifo_len(), 4, "exactly the capacity");
        assert!(!cell.can_accept(4) && !cell.can_accept(64));
        assert_eq!(cell.counters.overflows, 0);
        let extra = *cell.fifo().next().unwrap();
        assert_eq!(cell.accept(extra), Err(extra), "capacity + 1 is handed back");
        assert_eq!(cell.counters.overflows, 1);
        assert_eq!(cell.fifo_len(), 4);
    }

    #[test]
    fn blocked_answer_goes_back_unadvanced() {
        let col = column(&[(2, 2)]);
        let e = ShadowEnv { source: [Q, Q, 3 * Q], ..env(false, 4) };
        let mut cell = ShadowCell::<4>::new();
        cell.start(&col, &e).unwrap();
        assert_eq!(cell.step(&col.store, &[], |_| true), ShadowStep::Moved); // z = 2 → 3
        let head = *cell.fifo().next().unwrap();
        assert_eq!(cell.step(&col.store, &[], |_| false), ShadowStep::Blocked, "the router refuses");
        assert_eq!((cell.counters.blocked, *cell.fifo().next().unwrap()), (1, head));
        assert_eq!(
            cell.step(&col.store, &[], |a| a.payload == ANSWER_LIT | ANSWER_SURFACE),
            ShadowStep::Answered(true)
        );
        assert!(!cell.busy());
        assert_eq!(cell.counters.steps, 2);
    }

    #[test]
    fn forward_uses_one_slot_per_link() {
        let col = column(&[(0, 0)]);
        // Source far along +x at the same height: both rays leave east.
        let e = ShadowEnv { source: [9 * Q, Q, 0], all_voxels: false, ..env(false, 4) };
        let mut cell = ShadowCell::<4>::new();
        cell.start(&col, &e).unwrap();
        let ray = *cell.fifo().next().unwrap();
        cell.accept(ray).unwrap();
        assert_eq!(cell.step(&col.store, &[], |_| true), ShadowStep::Moved);
        assert!(cell.out(Port::E).is_some() && cell.has_out());
        assert_eq!(cell.step(&col.store, &[], |_| true), ShadowStep::Blocked, "the east slot is taken");
        assert!(cell.take_out(Port::E).is_some());
        assert!(!cell.has_out());
        assert_eq!(cell.step(&col.store, &[], |_| true), ShadowStep::Moved);
    }

    #[test]
    fn ram_is_the_fifo_and_the_slots() {
        use core::mem::size_of;
        let fa = crate::cell::SHADOW_FA_CAP;
        let stores = fa * size_of::<ShadowRay>() + 8 * size_of::<Option<ShadowRay>>();
        let bookkeeping = size_of::<ShadowCell<{ crate::cell::SHADOW_FA_CAP }>>() - stores;
        // FIFO indices, slot count, emitter cursor, mask, counters.
        assert!(bookkeeping <= size_of::<ShadowCounters>() + 40, "{bookkeeping} bytes besides the stores");
    }
}
