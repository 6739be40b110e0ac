//! §4.4 — the lighting phase in one cell: FIFO, output ports, back-pressure, lit voxels.
//!
//! A cell owns one input FIFO (the thesis's "FA") fed by its 8 neighbours and by itself, one
//! output buffer per neighbour direction, and the lit state of its column. Each cycle it may
//! process **one** beam (§4.4.1):
//!
//! * the beam's voxel is occupied → the voxel is lit by the beam's source and the beam stops
//!   (its rays are *absorbed*);
//! * otherwise the beam is split ([`crate::beam`]); sub-beams whose voxel leaves the grid are
//!   dropped (their rays *exit*), the others go to the cell itself (±z beams staying in the
//!   column: into its own FIFO) or to the output buffer toward the neighbour that owns them.
//!
//! **No loss** (§4.4.2): a beam is processed only when every destination can take its
//! sub-beams now — room in each output buffer concerned, and room in the cell's own FIFO for
//! self-destined ones (after the processed beam has left it). Otherwise the beam waits and the
//! cell is *blocked* for the cycle. Nothing is ever dropped for lack of space.
//!
//! **No deadlock** (argued here, tested by the host): a ray's transverse coordinates move
//! monotonically away from the source's (rounding ⌊S + u·k/D + ½⌋ is monotone in k with the
//! sign of u), and its principal coordinate strictly does; so every beam that changes cell moves
//! to a cell strictly farther from the source column in `|x − x_s| + |y − y_s|`. The "waits for"
//! relation between cells is therefore acyclic, and a cell's own FIFO always has room for the
//! one self-destined sub-beam of a split (the processed beam frees its slot). Boundary cells
//! never wait. Hence every beam is eventually processed.
//!
//! One split may keep more than one sub-beam: with rays from the light
//! (`beam::Origin::Light`) a ±x or ±y face whose layer 1 is the source voxel's slab sends the
//! source cell's layer-0 beam to up to three voxels of its own column (one per z), and under
//! the plane rule the beam may be peeled, its entry staying. Nothing enters the source column
//! from outside (beams only move away from it), and the emitter hands the source cell an
//! initial beam only when no earlier one waits there ([`LightCell::can_accept_initial`]): its
//! FIFO holds one layer-0 beam at most, its own ±z beams staying in the column (one entry per
//! chain, gone within D layers) and layer-1 beams that leave the column. So with a FIFO of at
//! least [`MIN_FA_FROM_LIGHT`] slots (the entry, kept while peeled, and three) the layer-0
//! beam eventually goes.
//!
//! **Quiescence** (§4.4.4): [`Activity`] counts beams in flight (in FIFOs, output buffers and
//! not yet emitted by a source); it is shared state, guarded by `critical-section` (on an MCU
//! the FIFO producer side runs in a link interrupt). It is exact: it is incremented before a
//! beam becomes visible and decremented when one is consumed, so it reads 0 iff no beam exists.
//!
//! Here: the cell ([`LightCell`]), its step (choose a beam, check that everything fits, commit)
//! and its environment ([`LightEnv`]); `fate` decides what one beam does at its voxel under each
//! lit rule and routes its sub-beams; `msg` holds the messages and ports, `out` the output
//! buffers, `activity` the quiescence counter, `lit_runs` the lit store, `bounds` what the skips
//! know of the scene.

use core::cell::Cell as CoreCell;

use critical_section::Mutex;
use heapless::Vec;

use crate::beam::{
    staying_rays, Beam, Direction, FarDistance, FarOffset, FracBits, Layer, RayRange, Source, SplitOrder, Transverse,
};
use crate::cell::Cell;
use crate::dexel::{Dexel, DexelStore};
use crate::lit::{spans, uniform, Along, Arrival, LitRule, Notch, Out, RayPlane, Rule, Segments, Verdict, Visit};
use crate::occluder::ColumnOccluders;
#[cfg(feature = "exact-occluders")]
use crate::occluder::{ExactTests, ExactVisit, ALL_CANDIDATES, EXACT_SEGMENTS};
use crate::occupancy::FrustumTest;
use crate::units::{Coord, Depth};

mod activity;
mod bounds;
mod fate;
mod lit_runs;
mod msg;
mod out;

pub use activity::{Activity, ActivityDelta, BeamTally};
pub use bounds::{OccupiedBox, SubBeamBounds, VoxelBox};
pub use lit_runs::{LitRun, LitRuns};
pub use msg::{BeamMsg, Local, Port};
use out::room;
pub use out::OutBuffers;

/// The occupancy summary a cell trace carries for the empty-frustum skip ([`LightEnv::frustum`]
/// takes any [`FrustumTest`]): 8 blocks per axis, 232 bytes per cell.
pub type FrustumSummary = crate::occupancy::Occupancy8;

/// Longest sibling wait ([`LightEnv::hold`]): wait ends are compared on the cell's 16-bit clock
/// as signed differences.
pub const MAX_HOLD: u16 = i16::MAX as u16;

/// The output-buffer lengths of a blocked-step key that no length matches: the cell was held
/// with no beam refused for room, so no change of the lengths can unblock it. Buffers hold at
/// most 127 messages, so a real length word is never all ones.
const ANY_LENGTHS: u64 = u64::MAX;

/// The smallest FIFO (the `fa` a host runs with) for sources whose rays leave from the light
/// (see the module doc's no-deadlock argument).
pub const MIN_FA_FROM_LIGHT: usize = 4;

/// One bit per light source (sources are diffused one after another; at most 32).
pub type SourceMask = u32;

/// Most sources a scene may have (bits of [`SourceMask`]).
pub const MAX_SOURCES: usize = 32;

/// Which beam a cell processes when its FIFO holds several (a documented, measured choice).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Policy {
    /// The thesis (§4.4.1): take the FIFO's head; if its sub-beams cannot all be sent, put it
    /// back at the tail ("remettre le faisceau dans FA") and wait for the next cycle.
    Thesis,
    /// Wavefront: among the beams whose sub-beams can all be sent now, take the one at the
    /// smallest layer (the longest remaining path), FIFO order among equals. A beam that cannot
    /// go does not block the ones behind it (no head-of-line blocking).
    Wavefront,
    /// Radial: the wavefront's rule, but among beams at the same layer the one whose voxel is
    /// nearest the source's axis goes first (for ±x and ±y beams, by |z − z_s|; ±z beams of one
    /// layer share their voxel in a cell), FIFO order among equals. Rays spread away from the
    /// axis, so a voxel's pieces come from its own position and the one nearer the axis: taken
    /// inside out, a cell's layer feeds the next cell's in the order that cell takes it, and
    /// the pipelines of a ±x or ±y pyramid drain together (measured against the others:
    /// BENCHMARKS.md, "How fast is lighting?").
    Radial,
}

impl Policy {
    /// Whether the cell picks among all waiting beams by layer (wavefront or radial), rather
    /// than taking its FIFO's head (the thesis's).
    pub const fn by_layer(self) -> bool {
        !matches!(self, Policy::Thesis)
    }
}

/// Per-cell counters of the lighting phase.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LightCounters {
    /// Beams processed (one per cycle at most).
    pub processed: u64,
    /// Cycles with beams waiting but none processable (the thesis's "bloqué").
    pub blocked_cycles: u64,
    /// Largest FIFO occupancy seen.
    pub peak_fifo: u16,
    /// Largest layer of a processed beam.
    pub max_layer: u32,
    /// Rays absorbed in this column.
    pub rays_absorbed: u64,
    /// Rays whose sub-beam left the grid from this cell.
    pub rays_exited: u64,
    /// Rays of sub-beams dropped by the receding-beam skip ([`OccupiedBox::receding`]).
    pub rays_skipped: u64,
    /// Sub-beams sent to neighbours.
    pub sent: u64,
    /// Lit marks lost to a full [`LitRuns`].
    pub lit_overflows: u32,
    /// Beams merged into a waiting beam on arrival.
    pub merged: u64,
    /// Cycles in which every beam that could go waited for its siblings ([`LightEnv::hold`]).
    pub held_cycles: u64,
    /// Exact-occluder visits judged ray by ray ([`crate::occluder::ExactVisit::per_ray`]: more
    /// undecided triangles than one visit tests at once).
    pub per_ray_visits: u32,
}

/// Where the rays of a processed beam end, for a diffusion that carries energy (a radiosity
/// shot, [`crate::radiosity`]): told once per absorbed or departed beam, when the beam is
/// processed (never for a candidate that waits). Under the thesis's rule only, where every such
/// ray set is a whole beam or sub-beam; the plane rule's peeled pieces are not reported.
pub trait RaySink<F: FracBits>: core::fmt::Debug + Sync {
    /// The rays of `beam` stopped in voxel `z` of column (x, y).
    fn absorbed(&self, x: Coord, y: Coord, z: Depth, beam: &Beam<F>);
    /// The rays of `beam` left the grid (exited, or dropped by a skip).
    fn left(&self, beam: &Beam<F>);
}

/// A processed beam's ray sets for a [`RaySink`]: (voxel depth where absorbed, or `None`: left
/// the grid; the rays). At most the beam itself or its nine sub-beams.
type RayEvents<F> = heapless::Vec<(Option<Depth>, Beam<F>), RAY_EVENTS>;

/// Ray ends one processed beam can report: ten, or none without the `ray-sink` feature (a
/// firmware image keeps the step's stack frame as small as before the hook).
const RAY_EVENTS: usize = if cfg!(feature = "ray-sink") { 10 } else { 0 };

/// What the machine around a cell looks like during one source's diffusion.
#[derive(Clone, Copy, Debug)]
pub struct LightEnv<'a, F: FracBits> {
    /// The source being diffused.
    pub source: &'a Source,
    /// Far distance D.
    pub far: FarDistance<F>,
    /// Grid side.
    pub n: u32,
    /// Voxels per column.
    pub depth: u32,
    /// Scheduling policy.
    pub policy: Policy,
    /// The lit rule ([`crate::lit`]).
    pub rule: LitRule,
    /// Sub-beam emission order.
    pub order: &'a SplitOrder,
    /// The FIFO limit in use (≤ the compile-time capacity; for FIFO-size sweeps).
    pub fa: usize,
    /// The thesis's "si dir propagation libre" read strictly (§4.4.1): a beam is processed only
    /// when the output buffer of every neighbour it sends to is *empty*, not merely has room.
    /// A timing rule: same lit voxels, other cycles. `false`: room is enough.
    pub free_ports: bool,
    /// Bit of the current source in [`SourceMask`].
    pub source_bit: SourceMask,
    /// Merge arriving beams into waiting beams of the same voxel when exact.
    pub merge: bool,
    /// The receding-beam skip: sub-beams that can meet no occupied voxel are dropped, their
    /// rays counted as skipped (`None`: off).
    pub skip: Option<OccupiedBox>,
    /// Where sub-beams may go: `SubBeamBounds::new(n, depth, skip, source)` with this
    /// environment's fields (checked in debug builds).
    pub bounds: SubBeamBounds,
    /// Keep lit marks only for the column's visible voxel (the first occupied one, the voxel
    /// the cell shades): the rest of the lit set is not stored. The image is the same; the lit
    /// store needs one run, never overflows, and skips the run bookkeeping of hidden voxels.
    pub lit_visible_only: bool,
    /// The empty-frustum skip: a beam none of whose rays can meet an occupied block of this
    /// summary at any later layer ([`FrustumTest::frustum_empty`]) is dropped when processed,
    /// its rays counted as skipped (`None`: off). Each cell holds the summary
    /// ([`FrustumTest::bytes`]: 232 B for [`FrustumSummary`], 8 blocks per axis; 1 348 B for
    /// 16, 9 384 B for 32), an OR-reduction over the grid after loading.
    pub frustum: Option<&'a dyn FrustumTest<F>>,
    /// The sibling wait: an incomplete beam (one that does not yet hold every ray of its voxel,
    /// [`Beam::complete`]) is not processed until it has waited this many of the cell's busy
    /// cycles, so that the pieces its sibling parents send can merge into it first. 0: off;
    /// at most [`MAX_HOLD`] (larger values act as it). Waits are counted on the cell's 16-bit
    /// clock: a beam kept blocked for 65 536 cycles may wait once more, never longer than `hold`.
    pub hold: u16,
    /// Report where the rays of every processed beam end ([`RaySink`]; thesis's rule only).
    /// Compiled only with the `ray-sink` feature (a default one; ignored without it).
    /// `None`: off (the ordinary diffusion).
    pub rays: Option<&'a dyn RaySink<F>>,
    /// The columns' triangles and target rays, for [`LitRule::Exact`] (`None`: no triangle, no
    /// target: nothing is stopped or lit). Read by no other rule.
    pub occluders: Option<&'a dyn ColumnOccluders>,
}

/// What a cell did in one cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Step {
    /// Nothing to do.
    Idle,
    /// Processed one beam.
    Processed,
    /// Had beams, could process none (all destinations busy).
    Blocked,
    /// Had beams that could go, but every one waits for its siblings ([`LightEnv::hold`]).
    Held,
}

/// Where a processed beam's rays go: absorbed in this column, or split into `subs` (plus rays
/// that exited or were skipped). One lives on the stack for a whole step and is filled in
/// place for each candidate ([`LightCell::fate`]): the ~300-byte sub-beam list is never moved.
/// The list is a local of its own that the fate borrows: as a field of a struct built with
/// zeroed scalars, the compiler cleared its whole buffer (a 312-byte `memset` per step,
/// heapless issue #305).
struct Fate<'s, F: FracBits> {
    /// Rays absorbed here.
    absorbed: u64,
    /// The beam lights its voxel (for the lit store).
    lit: bool,
    /// The beam lights the column's visible surface (plane rule).
    visible: bool,
    subs: &'s mut SubList<F>,
    exited: u64,
    skipped: u64,
    /// The entry stays in its FIFO slot as this (a beam being peeled); `None`: it is consumed.
    keep: Option<BeamMsg<F>>,
    /// The sub-beams leave an empty voxel (plane rule): they carry [`Beam::after_empty`].
    after_empty: bool,
    /// The sub-beams leave on the outside of their voxel's plane (plane rule): those going to
    /// another column carry [`Beam::after_outside`].
    after_outside: bool,
    /// Where the rays end, when the environment has a [`RaySink`].
    events: Option<&'s mut RayEvents<F>>,
    /// The exact-occluder visit judged ray by ray ([`LightCounters::per_ray_visits`]).
    #[cfg(feature = "exact-occluders")]
    per_ray: bool,
    /// Candidate rays brought to the column's target voxel ([`crate::visibility`]).
    #[cfg(feature = "lit-ray-ratio")]
    arrived: u64,
}

/// A beam's sub-beams and where each goes (at most nine).
type SubList<F> = heapless::Vec<(Target, BeamMsg<F>), 9>;

/// Record a ray set's end in `events` (if recording): absorbed at depth `z`, or left (`None`).
/// Compiled out without the `ray-sink` feature (a firmware image: no radiosity, no code).
#[inline(always)]
fn record<F: FracBits>(events: &mut Option<&mut RayEvents<F>>, z: Option<Depth>, beam: &Beam<F>) {
    if !cfg!(feature = "ray-sink") {
        return;
    }
    if let Some(e) = events.as_deref_mut() {
        // At most ten per processed beam: never full.
        let _ = e.push((z, *beam));
    }
}

impl<'s, F: FracBits> Fate<'s, F> {
    fn new(subs: &'s mut SubList<F>, events: Option<&'s mut RayEvents<F>>) -> Self {
        Fate {
            events,
            absorbed: 0,
            lit: false,
            visible: false,
            subs,
            exited: 0,
            skipped: 0,
            keep: None,
            after_empty: false,
            after_outside: false,
            #[cfg(feature = "exact-occluders")]
            per_ray: false,
            #[cfg(feature = "lit-ray-ratio")]
            arrived: 0,
        }
    }

    fn reset(&mut self) {
        self.subs.clear();
        if let Some(e) = self.events.as_deref_mut() {
            e.clear();
        }
        self.absorbed = 0;
        self.lit = false;
        self.visible = false;
        self.exited = 0;
        self.skipped = 0;
        self.keep = None;
        self.after_empty = false;
        self.after_outside = false;
        #[cfg(feature = "exact-occluders")]
        {
            self.per_ray = false;
            #[cfg(feature = "lit-ray-ratio")]
            {
                self.arrived = 0;
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Target {
    SelfFifo,
    Out(Port),
}

/// What becomes of one sub-beam of a split ([`LightCell::route`]).
#[derive(Clone, Copy)]
enum Sub {
    /// Sent, terminal or not, with this local state.
    Send(bool, Local),
    /// Absorbed here (staying rays the column rule stops).
    Absorb,
}

/// What becomes of each sub-beam of a split, by its offset: the one that stays in the column
/// (offset (0, 0) of a ±z beam below the far plane) takes `stay` when given, every other one
/// `other`.
#[derive(Clone, Copy)]
struct Decide {
    other: Sub,
    stay: Option<Sub>,
}

impl Decide {
    /// Every sub-beam sent plain.
    const PLAIN: Decide = Decide { other: Sub::Send(false, Local::NONE), stay: None };

    /// Every sub-beam as `s`.
    const fn all(s: Sub) -> Decide {
        Decide { other: s, stay: None }
    }

    /// The fate of the sub-beam with offset `o`.
    #[inline]
    fn at(&self, o: crate::beam::Offset) -> Sub {
        match self.stay {
            Some(s) if o == STAY => s,
            _ => self.other,
        }
    }
}

/// The sub-beam offset of the rays that stay in the column (a ±z beam's only).
const STAY: crate::beam::Offset = crate::beam::Offset { du: 0, dv: 0 };

/// A ray range in lattice steps (`to_bits`), `(lo, hi)`.
fn lattice<F: FracBits>(r: RayRange<F>) -> (i64, i64) {
    (r.lo().to_bits() as i64, r.hi().to_bits() as i64)
}

/// The ray range `lo ..= hi` (lattice steps within the far square: a piece of a beam's range).
fn range<F: FracBits>((lo, hi): (i64, i64)) -> RayRange<F> {
    RayRange::within_beam(FarOffset::<F>::from_bits(lo as i32), FarOffset::<F>::from_bits(hi as i32))
}

/// The lighting state of one cell: FIFO capacity `FA`, `OB` messages per output buffer,
/// `L` lit runs.
///
/// Field order is fixed (`repr(C)`) for locality: what every step reads first (the blocked-step
/// key, the output-buffer lengths) shares the first cache line; the FIFO's length (stored after
/// its slots) sits next to the counters every processed beam updates. On the host, where the
/// grid is a large array of these, a step touches a handful of cache lines instead of one per
/// field group scattered over 3 KB.
#[derive(Clone, Debug)]
#[repr(C)]
pub struct LightCell<F: FracBits, const FA: usize, const OB: usize, const L: usize> {
    /// After a wavefront step found nothing processable: the output-buffer lengths and FIFO
    /// generation it saw. Between two steps the output buffers can only shrink (links pop) and
    /// the FIFO only change through `accept`, and a beam's fate depends on nothing else, so
    /// while both are unchanged the cell is still blocked and skips re-splitting every waiting
    /// beam (exact: same result, same counters). Cleared when a beam is processed. When every
    /// waiting beam was held (none was refused for room), the lengths are [`ANY_LENGTHS`]:
    /// output buffers that shrink cannot end a sibling wait, only its clock or an arrival can.
    blocked_on: Option<(u64, u32)>,
    /// Bumped by every change of the FIFO ([`LightCell::accept`], processing).
    fifo_generation: u32,
    /// With `blocked_on`: the `ticks` at which the first waiting beam's sibling wait ends
    /// (`None`: no beam was waiting, the cell was blocked). Until then the cell stays held.
    held_until: Option<u16>,
    /// The cell's clock for the sibling wait: steps taken with a non-empty FIFO (wrapping; a
    /// FIFO entry's `since` is this clock when it arrived).
    ticks: u16,
    /// Column index.
    pub x: Coord,
    /// Row index.
    pub y: Coord,
    /// Depth of the voxel of the last beam processed (for tracing and coverage checks).
    pub last_z: Depth,
    /// Bit p: the head of output buffer p is on the wire (sent, not yet acknowledged); it is
    /// not merged into. Only links with acknowledgement set it.
    pub head_in_flight: u8,
    /// One output buffer per neighbour link (lengths first).
    pub out: OutBuffers<F, OB>,
    /// The input FIFO ("FA"). Fill it only through [`LightCell::accept`] (which the blocked-step
    /// shortcut relies on).
    pub fifo: Vec<BeamMsg<F>, FA>,
    /// Counters.
    pub counters: LightCounters,
    /// Lit voxels of the column.
    pub lit: LitRuns<L>,
    /// The sources that light the column's visible surface (the plane rule's image; under the
    /// thesis's rule the image reads the lit store).
    pub visible_lit: SourceMask,
}

impl<F: FracBits, const FA: usize, const OB: usize, const L: usize> LightCell<F, FA, OB, L> {
    const FA_FITS_THE_TRIED_MASK: () = assert!(FA <= 64, "the wavefront policy tracks tried FIFO slots in a u64");

    /// An idle cell at (x, y).
    pub fn new(x: Coord, y: Coord) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::FA_FITS_THE_TRIED_MASK;
        LightCell {
            x,
            y,
            fifo: Vec::new(),
            out: OutBuffers::new(),
            lit: LitRuns::new(),
            counters: LightCounters::default(),
            last_z: 0,
            head_in_flight: 0,
            fifo_generation: 0,
            blocked_on: None,
            ticks: 0,
            held_until: None,
            visible_lit: 0,
        }
    }

    /// Whether the cell holds any beam (FIFO or output buffers).
    pub fn busy(&self) -> bool {
        !self.fifo.is_empty() || self.out.any()
    }

    /// Whether the FIFO can take one more beam under limit `fa` (the credit a link checks).
    pub fn can_accept(&self, fa: usize) -> bool {
        self.fifo.len() < fa.min(FA)
    }

    /// Whether the source emitter may hand this cell (the source's) its next initial beam of
    /// `source` under limit `fa`: room, and for rays from the light no earlier initial beam
    /// still waiting (its split may keep three beams in the column: the module doc's
    /// no-deadlock argument).
    pub fn can_accept_initial(&self, fa: usize, source: &Source) -> bool {
        self.can_accept(fa)
            && (source.origin == crate::beam::Origin::SourceVoxel
                || !self.fifo.iter().any(|m| m.beam.layer().0 == 0 && m.beam.source() == source.id))
    }

    /// Deliver a beam into the FIFO (a link, or the source emitter). The caller checked
    /// [`LightCell::can_accept`]; a full FIFO returns the beam back. With `merge`, a beam that
    /// shares a whole side with a waiting beam of the same voxel joins it instead of taking a
    /// slot (exact, see [`Beam::merged`]; one beam fewer in flight).
    pub fn accept(&mut self, msg: BeamMsg<F>, merge: bool, activity: &impl BeamTally) -> Result<(), BeamMsg<F>> {
        self.fifo_generation = self.fifo_generation.wrapping_add(1);
        if merge && msg.mergeable() {
            let mut m = msg;
            let mut joined = false;
            // The joined beam keeps the oldest arrival among its pieces: a ray waits at most
            // `hold` cycles in a cell for siblings, however many pieces join.
            let mut stamp = self.ticks;
            // Keep joining while the grown rectangle meets another waiting beam.
            while let Some((i, b)) = self.fifo.iter().enumerate().find_map(|(i, e)| {
                (e.z == m.z && e.mergeable()).then(|| e.beam.merged(&m.beam)).flatten().map(|b| (i, b))
            }) {
                let old = self.fifo.remove(i).since;
                if self.ticks.wrapping_sub(old) > self.ticks.wrapping_sub(stamp) {
                    stamp = old;
                }
                if joined {
                    // Two waiting beams became one.
                    activity.consume();
                }
                m = BeamMsg::new(b, m.z);
                joined = true;
                self.counters.merged += 1;
            }
            if joined {
                activity.consume();
                // Cannot fail: a slot was freed by the removal.
                let _ = self.fifo.push(BeamMsg { since: stamp, ..m });
                return Ok(());
            }
        }
        self.fifo.push(BeamMsg { since: self.ticks, ..msg }).map_err(|_| msg)?;
        self.counters.peak_fifo = self.counters.peak_fifo.max(self.fifo.len() as u16);
        Ok(())
    }

    /// Whether nothing that could unblock the cell changed since its last step found nothing
    /// processable (see `blocked_on`).
    fn still_blocked(&self) -> bool {
        self.blocked_on.is_some_and(|(lengths, generation)| {
            generation == self.fifo_generation && (lengths == ANY_LENGTHS || lengths == self.out.lengths())
        })
    }

    /// While the cell is held (its last step returned [`Step::Held`] and nothing that could end
    /// the wait changed since, see `blocked_on`): the number of steps until a waiting beam's sibling
    /// wait ends. Every step before that returns [`Step::Held`] and changes nothing but the
    /// clock and `held_cycles`, so a host may skip them ([`LightCell::skip_held`]).
    pub fn held_wait(&self) -> Option<u16> {
        match (self.still_blocked(), self.held_until) {
            (true, Some(t)) => Some(t.wrapping_sub(self.ticks)).filter(|&w| (w as i16) > 0),
            _ => None,
        }
    }

    /// Account for `k` steps that a held cell was not given (`k` < [`LightCell::held_wait`]):
    /// exactly what `k` steps would have done — each one a [`Step::Held`].
    pub fn skip_held(&mut self, k: u16) {
        debug_assert!(k == 0 || self.held_wait().is_some_and(|w| k < w));
        self.ticks = self.ticks.wrapping_add(k);
        self.counters.held_cycles += k as u64;
    }

    /// Whether the beam of `m` holds all the rays its voxel can receive ([`Beam::complete`]).
    /// A beam with local state, or a terminal one, never waits for siblings: nothing merges with
    /// it.
    fn complete(&self, m: &BeamMsg<F>, env: &LightEnv<'_, F>) -> bool {
        if !m.mergeable() || m.beam.is_terminal() {
            return true;
        }
        let pos = [self.x as i32, self.y as i32, m.z as i32];
        let (ua, va) = m.beam.direction().transverse();
        m.beam.complete(env.source, env.far, Transverse { u: pos[ua.index()], v: pos[va.index()] })
    }

    /// Whether every sub-beam of `fate` fits now (the no-loss rule), given that the processed
    /// beam leaves the FIFO first (a beam being peeled stays, and sends nothing to its own
    /// FIFO).
    /// The eight output buffers are checked at once on their length word ([`room`]; byte p of
    /// `need` counts the sub-beams for port p).
    /// Under [`LightEnv::free_ports`] every port it sends to must be empty as well.
    fn fits(&self, fate: &Fate<'_, F>, env: &LightEnv<'_, F>) -> bool {
        let (mut need, mut own) = (0u64, 0usize);
        for (t, _) in fate.subs.iter() {
            match t {
                Target::Out(p) => need += 1 << (8 * p.index()),
                Target::SelfFifo => own += 1,
            }
        }
        let stays = fate.keep.is_some() as usize;
        let lengths = self.out.lengths();
        let free = !env.free_ports || (0..8).all(|p| (need >> (8 * p)) & 0xFF == 0 || (lengths >> (8 * p)) & 0xFF == 0);
        free && room::<OB>(lengths, need) && self.fifo.len() - 1 + stays + own <= env.fa.min(FA)
    }

    /// One compute cycle (§4.4.1): pick a beam by `env.policy`, process it if the no-loss rule
    /// allows, else wait. `activity` counts beams in flight machine-wide.
    ///
    /// Phases: `unchanged_wait` (nothing changed since the last refusal), `choose` (the first
    /// beam whose sub-beams fit), `wait` (none fits) or `commit` (take it, count it, mark what
    /// it lit, send its sub-beams).
    pub fn step<const D: usize>(&mut self, cell: &Cell<D>, env: &LightEnv<'_, F>, activity: &impl BeamTally) -> Step {
        if self.fifo.is_empty() {
            return Step::Idle;
        }
        self.ticks = self.ticks.wrapping_add(1);
        let wave = env.policy.by_layer();
        if wave {
            if let Some(step) = self.unchanged_wait() {
                return step;
            }
        }
        let mut subs = SubList::new();
        let mut events = RayEvents::new();
        let mut fate = Fate::new(&mut subs, env.rays.is_some().then_some(&mut events));
        let choice = self.choose(cell, env, &mut fate);
        let Some(i) = choice.chosen else {
            return self.wait(wave, &choice);
        };
        #[cfg(debug_assertions)]
        self.check_conservation(i, &fate, cell, env);
        self.commit(i, fate, cell, env, activity)
    }

    /// A wave policy's shortcut: when nothing changed since the last step found nothing
    /// processable and no waiting beam's sibling wait has ended, the step is the same refusal.
    #[inline(always)]
    fn unchanged_wait(&mut self) -> Option<Step> {
        if !self.still_blocked() {
            return None;
        }
        match self.held_until {
            None => {
                self.counters.blocked_cycles += 1;
                Some(Step::Blocked)
            }
            Some(t) if (t.wrapping_sub(self.ticks) as i16) > 0 => {
                self.counters.held_cycles += 1;
                Some(Step::Held)
            }
            Some(_) => None,
        }
    }

    /// The FIFO slot to process this step (its fate in `fate`), by `env.policy`.
    #[inline(always)]
    fn choose<const D: usize>(&mut self, cell: &Cell<D>, env: &LightEnv<'_, F>, fate: &mut Fate<'_, F>) -> Choice {
        match env.policy {
            Policy::Thesis => {
                self.fate(&self.fifo[0], cell, env, fate);
                if self.fits(fate, env) {
                    Choice { chosen: Some(0), ..Choice::NONE }
                } else {
                    // Put it back at the tail.
                    let head = self.fifo.remove(0);
                    let _ = self.fifo.push(head);
                    Choice::NONE
                }
            }
            Policy::Wavefront | Policy::Radial => self.choose_by_key(cell, env, fate),
        }
    }

    /// The wave policies: candidates by (layer, position), or (layer, distance to the axis,
    /// position) for radial; the first that fits goes. Keys are layer << 27 | distance << 6 |
    /// position (FA ≤ 64, asserted; layer < 2^31; the distance |z·16 − z_s·16|, z_s in 1/16
    /// voxel, is < 2^21 for a source inside the grid and clamped there for one outside): the
    /// smallest is found by one scan, and the rest are listed and sorted only if it cannot go.
    #[inline(always)]
    fn choose_by_key<const D: usize>(&self, cell: &Cell<D>, env: &LightEnv<'_, F>, fate: &mut Fate<'_, F>) -> Choice {
        let hold = env.hold.min(MAX_HOLD);
        // `wait`: cycles until the first waiting beam's sibling wait ends (`hold`: none is
        // waiting); `refused`: a beam was refused for lack of room (then the output lengths
        // matter).
        let mut choice = Choice { wait: hold, ..Choice::NONE };
        let radial = env.policy == Policy::Radial;
        let zs = env.source.pos[2].to_bits() as i64;
        let key = |i: usize| {
            let m = &self.fifo[i];
            let d = if radial { (((m.z as i64) << 4) - zs).unsigned_abs().min((1 << 21) - 1) } else { 0 };
            (m.beam.layer().0 as u64) << 27 | d << 6 | i as u64
        };
        let first = (0..self.fifo.len()).map(key).min().unwrap_or(0);
        // Built when the first candidate cannot go (rare without a sibling wait).
        let mut rest: Option<Vec<u64, FA>> = None;
        // A full FIFO takes no sibling: nothing is worth waiting for.
        let may_hold = hold > 0 && self.fifo.len() < env.fa.min(FA);
        for c in 0..self.fifo.len() {
            let i = if c == 0 {
                (first & 63) as usize
            } else {
                let rest = rest.get_or_insert_with(|| {
                    let mut r: Vec<u64, FA> = Vec::new();
                    // Insertion sort: a few keys, and no general sort in a firmware.
                    for k in (0..self.fifo.len()).map(key).filter(|&k| k != first) {
                        let at = r.iter().position(|&x| x > k).unwrap_or(r.len());
                        // Cannot fail: FA keys at most.
                        let _ = r.insert(at, k);
                    }
                    r
                });
                (rest[c - 1] & 63) as usize
            };
            let age = self.ticks.wrapping_sub(self.fifo[i].since);
            if may_hold && age < hold && !self.complete(&self.fifo[i], env) {
                choice.held = true;
                choice.wait = choice.wait.min(hold - age);
                continue;
            }
            self.fate(&self.fifo[i], cell, env, fate);
            if self.fits(fate, env) {
                choice.chosen = Some(i);
                break;
            }
            choice.refused = true;
        }
        choice
    }

    /// No beam can go this step: remember what would change that (wave policies) and report
    /// a held or a blocked cycle.
    fn wait(&mut self, wave: bool, choice: &Choice) -> Step {
        if wave {
            let lengths = if choice.refused { self.out.lengths() } else { ANY_LENGTHS };
            self.blocked_on = Some((lengths, self.fifo_generation));
            self.held_until = choice.held.then(|| self.ticks.wrapping_add(choice.wait));
        }
        if choice.held {
            // Waiting by choice, for a bounded time.
            self.counters.held_cycles += 1;
            return Step::Held;
        }
        self.counters.blocked_cycles += 1;
        Step::Blocked
    }

    /// Conservation per step, for steps that start and end at a run boundary (mid-run the
    /// entry still holds the rectangle of pieces already sent).
    #[cfg(debug_assertions)]
    fn check_conservation<const D: usize>(&self, i: usize, fate: &Fate<'_, F>, cell: &Cell<D>, env: &LightEnv<'_, F>) {
        if env.rule.cuts_rays() && self.fifo[i].local.piece == 0 && fate.keep.is_none_or(|k| k.local.piece == 0) {
            let before = self.present_rays(&self.fifo[i], cell, env);
            let subs: u64 = fate.subs.iter().map(|(_, s)| self.present_rays(s, cell, env)).sum();
            let kept = fate.keep.as_ref().map_or(0, |k| self.present_rays(k, cell, env));
            debug_assert_eq!(
                before,
                fate.absorbed + fate.exited + fate.skipped + subs + kept,
                "rays of {:?} at ({}, {}, {}): absorbed {} exited {} skipped {} subs {} kept {} ({:?}, {:?})",
                self.fifo[i],
                self.x,
                self.y,
                self.fifo[i].z,
                fate.absorbed,
                fate.exited,
                fate.skipped,
                subs,
                kept,
                fate.subs,
                fate.keep
            );
        }
    }

    /// Process FIFO slot `i` whose fate is `fate`: take it (or keep the rest of a peeled beam
    /// in its slot), count it, mark what it lit and send its sub-beams.
    #[inline(always)]
    fn commit<const D: usize>(
        &mut self,
        i: usize,
        fate: Fate<'_, F>,
        cell: &Cell<D>,
        env: &LightEnv<'_, F>,
        activity: &impl BeamTally,
    ) -> Step {
        self.blocked_on = None;
        self.fifo_generation = self.fifo_generation.wrapping_add(1);
        let m = match fate.keep {
            // Being peeled: the rest of the beam keeps its slot (and its arrival time).
            Some(rest) => core::mem::replace(&mut self.fifo[i], rest),
            None => self.fifo.remove(i),
        };
        self.last_z = m.z;
        self.counters.processed += 1;
        self.counters.max_layer = self.counters.max_layer.max(m.beam.layer().0);
        self.counters.rays_absorbed += fate.absorbed;
        self.counters.rays_exited += fate.exited;
        self.counters.rays_skipped += fate.skipped;
        #[cfg(feature = "exact-occluders")]
        {
            self.counters.per_ray_visits += fate.per_ray as u32;
            #[cfg(feature = "lit-ray-ratio")]
            if fate.arrived > 0 {
                if let Some(o) = env.occluders {
                    o.arrived(self.x, self.y, fate.arrived);
                }
            }
        }
        if fate.lit {
            self.mark_lit(m.z, cell, env);
        }
        if fate.visible {
            self.visible_lit |= env.source_bit;
        }
        if let (Some(sink), Some(events)) = (env.rays, fate.events.as_deref()) {
            for (z, b) in events.iter() {
                match z {
                    Some(z) => sink.absorbed(self.x, self.y, *z, b),
                    None => sink.left(b),
                }
            }
        }
        activity.add(fate.subs.len() as u64);
        for &(t, sub) in fate.subs.iter() {
            self.send(t, sub, env, activity);
        }
        if fate.keep.is_some() {
            return Step::Processed;
        }
        activity.consume();
        Step::Processed
    }

    /// Mark voxel `z` lit by this source, where the lit store keeps it.
    #[inline(always)]
    fn mark_lit<const D: usize>(&mut self, z: Depth, cell: &Cell<D>, env: &LightEnv<'_, F>) {
        // The image reads its pixel's mark; the full lit store is for the lit set, the
        // visible-only one keeps the voxels that receive the pixel's light.
        let shown = !env.lit_visible_only
            || env.rule.receives(cell.store.dexels().first().map(|d| d.span.lo), cell.visible.as_ref(), z);
        if shown && !self.lit.mark(z, env.source_bit) {
            self.counters.lit_overflows += 1;
        }
    }

    /// Put a sub-beam where it goes: this cell's FIFO, or an output buffer (joining a waiting
    /// message for the same neighbour voxel when merging). `fits` checked every destination.
    #[inline(always)]
    fn send(&mut self, t: Target, sub: BeamMsg<F>, env: &LightEnv<'_, F>, activity: &impl BeamTally) {
        match t {
            Target::SelfFifo => {
                let _ = self.accept(sub, env.merge, activity);
            }
            Target::Out(p) => {
                // A head already on the wire (sent, not yet acknowledged) must not
                // change: a retransmission has to carry the same beam.
                let skip_head = (self.head_in_flight >> p.index() & 1) as usize;
                // Same neighbour voxel, side by side: join the waiting message.
                let joined = env.merge
                    && self.out.waiting_mut(p).iter_mut().skip(skip_head).any(|w| {
                        let j = (w.z == sub.z).then(|| w.beam.merged(&sub.beam)).flatten();
                        if let Some(b) = j {
                            w.beam = b;
                        }
                        j.is_some()
                    });
                if joined {
                    activity.consume();
                    self.counters.merged += 1;
                } else {
                    let _ = self.out.push_back(p, sub);
                    self.counters.sent += 1;
                }
            }
        }
    }
}

/// What [`LightCell::choose`] found: the slot to process, or why none goes.
#[derive(Clone, Copy, Debug)]
struct Choice {
    /// The FIFO slot whose beam goes this step.
    chosen: Option<usize>,
    /// A beam was held back to wait for its siblings.
    held: bool,
    /// Cycles until the first held beam's sibling wait ends.
    wait: u16,
    /// A beam was refused for lack of room.
    refused: bool,
}

impl Choice {
    const NONE: Choice = Choice { chosen: None, held: false, wait: 0, refused: false };
}

#[cfg(test)]
mod tests;
