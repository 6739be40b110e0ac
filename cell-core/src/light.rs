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
use crate::occluder::{ExactTests, ExactVisit, EXACT_SEGMENTS};
use crate::occupancy::FrustumTest;
use crate::units::{Coord, Depth};

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

/// A beam in a message: the beam and the depth of its voxel in the receiving column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BeamMsg<F: FracBits> {
    /// The rays.
    pub beam: Beam<F>,
    /// The z of the beam's voxel (needed for ±x and ±y beams; for ±z beams it is implied by
    /// the layer but carried all the same).
    pub z: Depth,
    /// Cell-local, not sent on links: in a FIFO, the receiving cell's clock when the beam
    /// arrived (for the sibling wait, [`LightEnv::hold`]); 0 elsewhere. It lives in what would
    /// be padding.
    since: u16,
    /// Cell-local, not sent on links: the plane rule's state of a FIFO entry ([`Local`]).
    local: Local,
}

impl<F: FracBits> BeamMsg<F> {
    /// The message carrying `beam`, whose voxel is at depth `z` in the receiving column.
    pub const fn new(beam: Beam<F>, z: Depth) -> Self {
        BeamMsg { beam, z, since: 0, local: Local::NONE }
    }

    /// The plane rule's local state (none for a message on a link).
    pub const fn local(&self) -> Local {
        self.local
    }

    /// Whether it may merge with, or take in, another beam: no local state (a plain or a
    /// terminal beam that is not being peeled).
    pub fn mergeable(&self) -> bool {
        self.local == Local::NONE
    }
}

/// What a FIFO entry carries under the plane rule besides its rays, never sent on a link
/// (8 bytes): the column rule's notch ([`Notch`]: a ±z beam that stayed in its column after a
/// surface voxel), and how far the cell has peeled it (pieces of the current run already sent).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Local {
    state: u16,
    t1: u16,
    t2: u16,
    flags: u8,
    piece: u8,
}

const HAS_NOTCH: u8 = 1;
const FRESH: u8 = 2;
const FRONT: u8 = 4;

impl Local {
    /// No state: a plain beam.
    pub const NONE: Local = Local { state: 0, t1: 0, t2: 0, flags: 0, piece: 0 };

    /// A beam with this notch.
    pub const fn notched(n: Notch) -> Local {
        let flags = HAS_NOTCH | if n.fresh { FRESH } else { 0 } | if n.front { FRONT } else { 0 };
        Local { state: n.state, t1: n.t1, t2: n.t2, flags, piece: 0 }
    }

    /// The notch, if any.
    pub const fn notch(&self) -> Option<Notch> {
        if self.flags & HAS_NOTCH == 0 {
            None
        } else {
            let (fresh, front) = (self.flags & FRESH != 0, self.flags & FRONT != 0);
            Some(Notch { state: self.state, t1: self.t1, t2: self.t2, fresh, front })
        }
    }

    /// Pieces of the current run already sent.
    pub const fn piece(&self) -> u8 {
        self.piece
    }
}

#[cfg(feature = "defmt")]
impl<F: FracBits> defmt::Format for BeamMsg<F> {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "BeamMsg {{ {}, z: {=u16} }}", self.beam, self.z)
    }
}

/// The 8 neighbour links, counter-clockwise from east (y grows to the north).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Port {
    /// (+1, 0)
    E = 0,
    /// (+1, +1)
    NE = 1,
    /// (0, +1)
    N = 2,
    /// (−1, +1)
    NW = 3,
    /// (−1, 0)
    W = 4,
    /// (−1, −1)
    SW = 5,
    /// (0, −1)
    S = 6,
    /// (+1, −1)
    SE = 7,
}

impl Port {
    /// All eight, in index order.
    pub const ALL: [Port; 8] = [Port::E, Port::NE, Port::N, Port::NW, Port::W, Port::SW, Port::S, Port::SE];

    /// The cell step (dx, dy) of this link.
    pub const fn delta(self) -> (i8, i8) {
        match self {
            Port::E => (1, 0),
            Port::NE => (1, 1),
            Port::N => (0, 1),
            Port::NW => (-1, 1),
            Port::W => (-1, 0),
            Port::SW => (-1, -1),
            Port::S => (0, -1),
            Port::SE => (1, -1),
        }
    }

    /// The link for a step (dx, dy); `None` for (0, 0) or a step longer than one cell.
    pub const fn from_delta(dx: i8, dy: i8) -> Option<Port> {
        Some(match (dx, dy) {
            (1, 0) => Port::E,
            (1, 1) => Port::NE,
            (0, 1) => Port::N,
            (-1, 1) => Port::NW,
            (-1, 0) => Port::W,
            (-1, -1) => Port::SW,
            (0, -1) => Port::S,
            (1, -1) => Port::SE,
            _ => return None,
        })
    }

    /// Index 0..8.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The ports whose bit is set in `mask` (bit p: port p), in port order. One
    /// `trailing_zeros` per port present, where filtering [`Port::ALL`] tests all eight.
    pub fn each(mask: u8) -> impl Iterator<Item = Port> {
        let mut m = mask;
        core::iter::from_fn(move || {
            let i = m.trailing_zeros() as usize;
            m &= m.wrapping_sub(1);
            Port::ALL.get(i).copied()
        })
    }
}

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
    /// the pipelines of a ±x or ±y pyramid drain together (Cornell box n = 512: 56 % fewer
    /// cycles than the wavefront, 7 % more beams; BENCHMARKS.md).
    Radial,
}

impl Policy {
    /// Whether the cell picks among all waiting beams by layer (wavefront or radial), rather
    /// than taking its FIFO's head (the thesis's).
    pub const fn by_layer(self) -> bool {
        !matches!(self, Policy::Thesis)
    }
}

/// Lit voxels of one column, as runs of consecutive voxels with the same source mask.
///
/// Invariant: runs sorted, disjoint, non-empty, non-zero masks, and two touching runs never
/// have equal masks (they would be merged). Capacity `L`; a mark that does not fit is counted.
#[derive(Clone, Debug, Default)]
pub struct LitRuns<const L: usize> {
    runs: Vec<LitRun, L>,
    overflows: u32,
}

/// A run of lit voxels `lo ..= hi`, lit by the sources in `mask`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LitRun {
    /// First z.
    pub lo: Depth,
    /// Last z.
    pub hi: Depth,
    /// Sources that lit these voxels.
    pub mask: SourceMask,
}

impl<const L: usize> LitRuns<L> {
    /// No voxel lit.
    pub const fn new() -> Self {
        LitRuns { runs: Vec::new(), overflows: 0 }
    }

    /// The runs, sorted by depth.
    pub fn runs(&self) -> &[LitRun] {
        &self.runs
    }

    /// Marks that did not fit.
    pub fn overflows(&self) -> u32 {
        self.overflows
    }

    /// Sources that lit voxel `z` (0 if none).
    pub fn mask_at(&self, z: Depth) -> SourceMask {
        let i = self.runs.partition_point(|r| r.hi < z);
        match self.runs.get(i) {
            Some(r) if r.lo <= z => r.mask,
            _ => 0,
        }
    }

    /// Record that the sources in `bits` lit voxel `z`. Returns `false` (and counts an
    /// overflow) when the runs would exceed the capacity; the state is then unchanged.
    pub fn mark(&mut self, z: Depth, bits: SourceMask) -> bool {
        let i = self.runs.partition_point(|r| r.hi < z);
        let old = match self.runs.get(i) {
            Some(r) if r.lo <= z => Some(*r),
            _ => None,
        };
        let mask = old.map_or(0, |r| r.mask);
        if mask | bits == mask {
            return true;
        }
        // The pieces replacing `old` (or inserted at i): below z, z itself, above z.
        let mut pieces: Vec<LitRun, 3> = Vec::new();
        if let Some(r) = old {
            if r.lo < z {
                let _ = pieces.push(LitRun { lo: r.lo, hi: z - 1, mask });
            }
        }
        let _ = pieces.push(LitRun { lo: z, hi: z, mask: mask | bits });
        if let Some(r) = old {
            if r.hi > z {
                let _ = pieces.push(LitRun { lo: z + 1, hi: r.hi, mask });
            }
        }
        // Merge the new voxel run with touching neighbours of equal mask.
        let new_mask = mask | bits;
        let prev = if i > 0 { self.runs.get(i - 1).copied() } else { None };
        let next_idx = if old.is_some() { i + 1 } else { i };
        let next = self.runs.get(next_idx).copied();
        let merge_prev = pieces[0].lo == z && prev.is_some_and(|p| p.hi as u32 + 1 == z as u32 && p.mask == new_mask);
        let last = pieces.len() - 1;
        let merge_next =
            pieces[last].hi == z && next.is_some_and(|n| z as u32 + 1 == n.lo as u32 && n.mask == new_mask);
        let removed = old.is_some() as usize + merge_prev as usize + merge_next as usize;
        if self.runs.len() - removed + pieces.len() > L {
            self.overflows += 1;
            return false;
        }
        let mut lo_idx = i;
        if merge_prev {
            lo_idx -= 1;
            let p = prev.unwrap_or(pieces[0]);
            pieces[0].lo = p.lo;
        }
        if merge_next {
            let n = next.unwrap_or(pieces[last]);
            pieces[last].hi = n.hi;
        }
        for _ in 0..removed {
            self.runs.remove(lo_idx);
        }
        for (k, p) in pieces.iter().enumerate() {
            // Cannot fail: capacity checked above.
            let _ = self.runs.insert(lo_idx + k, *p);
        }
        true
    }
}

/// Beams in flight in the whole machine: the global activity detector (§4.4.4).
pub struct Activity {
    count: Mutex<CoreCell<u64>>,
}

impl Default for Activity {
    fn default() -> Self {
        Self::new()
    }
}

impl Activity {
    /// Nothing in flight.
    pub const fn new() -> Self {
        Activity { count: Mutex::new(CoreCell::new(0)) }
    }

    /// `n` beams appeared (before they become visible to any cell).
    pub fn add(&self, n: u64) {
        critical_section::with(|cs| {
            let c = self.count.borrow(cs);
            c.set(c.get() + n);
        });
    }

    /// One beam was consumed.
    pub fn consume(&self) {
        critical_section::with(|cs| {
            let c = self.count.borrow(cs);
            c.set(c.get().saturating_sub(1));
        });
    }

    /// Beams in flight.
    pub fn get(&self) -> u64 {
        critical_section::with(|cs| self.count.borrow(cs).get())
    }

    /// No beam anywhere: the diffusion of the current source is over.
    pub fn is_quiescent(&self) -> bool {
        self.get() == 0
    }
}

/// Counts beams appearing and being consumed: the machine-wide [`Activity`], or an
/// [`ActivityDelta`] that a host simulating many cells at once keeps per worker and adds to the
/// [`Activity`] at the end of a phase ([`Activity::apply`]).
pub trait BeamTally {
    /// `n` beams appeared.
    fn add(&self, n: u64);
    /// One beam was consumed.
    fn consume(&self);
}

impl BeamTally for Activity {
    fn add(&self, n: u64) {
        Activity::add(self, n);
    }
    fn consume(&self) {
        Activity::consume(self);
    }
}

/// A local, unsynchronised change of the beam count (not `Sync`: one per worker). Sound
/// because quiescence is only read between phases, after every delta has been applied.
#[derive(Debug, Default)]
pub struct ActivityDelta(CoreCell<i64>);

impl ActivityDelta {
    /// No change yet.
    pub const fn new() -> Self {
        ActivityDelta(CoreCell::new(0))
    }

    /// Net change so far (appeared − consumed).
    pub fn get(&self) -> i64 {
        self.0.get()
    }
}

impl BeamTally for ActivityDelta {
    fn add(&self, n: u64) {
        self.0.set(self.0.get() + n as i64);
    }
    fn consume(&self) {
        self.0.set(self.0.get() - 1);
    }
}

impl Activity {
    /// Add a worker's net change (one critical section per phase instead of one per beam).
    pub fn apply(&self, delta: i64) {
        critical_section::with(|cs| {
            let c = self.count.borrow(cs);
            c.set(c.get().saturating_add_signed(delta));
        });
    }
}

/// The bounding box of the occupied voxels, `lo ..= hi` on each axis (x, y, z); 12 bytes that
/// every cell holds for the *receding-beam skip* (a min/max reduction over the grid after
/// loading, or the host's broadcast). `lo > hi` on an axis means no voxel is occupied.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct OccupiedBox {
    /// Smallest occupied coordinate per axis.
    pub lo: [Depth; 3],
    /// Largest occupied coordinate per axis.
    pub hi: [Depth; 3],
}

impl OccupiedBox {
    /// Whether no ray of a beam of direction `dir`, from a source in voxel `sv`, that is in voxel
    /// `at` can ever meet an occupied voxel again. Exact, by monotonicity: along the principal
    /// axis a ray moves strictly in the direction's sign; on a transverse axis its voxel
    /// coordinate ⌊S + u·k/D + ½⌋ is monotone in k with the sign of u and equals the source
    /// voxel's at k = 0, so a ray in a voxel strictly beyond the source voxel on that axis has
    /// u > 0 (resp. u < 0) and never comes back. So the beam recedes if, on some axis, it is
    /// beyond the box and moving (principal) or bound (transverse) away from it.
    pub fn receding(&self, dir: Direction, sv: [i32; 3], at: [i64; 3]) -> bool {
        !self.alive(dir, sv).contains(at)
    }

    /// The voxels a beam of direction `dir` from a source in voxel `sv` may be in and still
    /// meet an occupied voxel later: [`OccupiedBox::receding`] is "outside this box", so a cell
    /// computes it once per beam and tests each sub-beam with six comparisons. On a transverse
    /// axis a beam recedes beyond max(hi, s) or below min(lo, s); along the principal axis
    /// beyond the box in the direction of travel; an empty box keeps nothing.
    pub fn alive(&self, dir: Direction, sv: [i32; 3]) -> VoxelBox {
        if (0..3).any(|a| self.lo[a] > self.hi[a]) {
            return VoxelBox { lo: [1; 3], hi: [0; 3] };
        }
        let w = dir.principal().index();
        let bound = |a: usize| {
            let (lo, hi, s) = (self.lo[a] as i64, self.hi[a] as i64, sv[a] as i64);
            if a != w {
                (lo.min(s), hi.max(s))
            } else if dir.sign() > 0 {
                (i64::MIN, hi)
            } else {
                (lo, i64::MAX)
            }
        };
        let b = [bound(0), bound(1), bound(2)];
        VoxelBox { lo: b.map(|x| x.0), hi: b.map(|x| x.1) }
    }
}

/// Where a sub-beam may go and still be sent, per direction: the grid, cut by the receding
/// skip's [`OccupiedBox::alive`] box when that skip is on. It depends only on the grid, the
/// skip's box and the source, so a cell computes it once per source ([`SubBeamBounds::new`])
/// rather than once per beam; a sub-beam outside it left the grid or is skipped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SubBeamBounds {
    /// Largest x, y, z of the grid (the smallest are 0).
    grid_hi: [i32; 3],
    /// Per direction (index: [`Direction`] as `usize`): smallest and largest x, y, z kept
    /// (empty: some lo > hi). Within the grid, so they fit `i32`.
    keep: [([i32; 3], [i32; 3]); 6],
}

impl SubBeamBounds {
    /// The bounds of an `n` × `n` grid of `depth` voxels per column, with the receding skip's
    /// box `skip` (`None`: off), for beams from `source`.
    pub fn new(n: u32, depth: u32, skip: Option<OccupiedBox>, source: &Source) -> Self {
        let grid_hi = [n as i64 - 1, n as i64 - 1, depth as i64 - 1];
        let sv = source.voxel();
        let keep = Direction::ALL.map(|dir| {
            let alive = skip.map(|bx| bx.alive(dir, sv));
            let axis = |a: usize| {
                let (lo, hi) = alive.map_or((0, grid_hi[a]), |b| (b.lo[a].max(0), b.hi[a].min(grid_hi[a])));
                // An empty range stays empty: lo > hi after clamping both into [0, grid_hi].
                (lo.clamp(0, grid_hi[a] + 1) as i32, hi.clamp(-1, grid_hi[a]) as i32)
            };
            let [x, y, z] = [axis(0), axis(1), axis(2)];
            ([x.0, y.0, z.0], [x.1, y.1, z.1])
        });
        SubBeamBounds { grid_hi: grid_hi.map(|h| h as i32), keep }
    }

    /// Whether a sub-beam of direction `dir` going to voxel `to` is sent (the common case: one
    /// box test).
    #[inline]
    fn keeps(&self, dir: Direction, to: [i64; 3]) -> bool {
        let (lo, hi) = &self.keep[dir as usize];
        (0..3).fold(true, |ok, a| ok & (to[a] >= lo[a] as i64) & (to[a] <= hi[a] as i64))
    }

    /// Whether voxel `to` is in the grid.
    #[inline]
    fn in_grid(&self, to: [i64; 3]) -> bool {
        (0..3).fold(true, |ok, a| ok & (to[a] >= 0) & (to[a] <= self.grid_hi[a] as i64))
    }
}

/// A box of voxel coordinates, bounds included (empty if some `lo` > `hi`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VoxelBox {
    /// Smallest coordinate per axis.
    pub lo: [i64; 3],
    /// Largest coordinate per axis.
    pub hi: [i64; 3],
}

impl VoxelBox {
    /// Whether `at` is in the box.
    pub fn contains(&self, at: [i64; 3]) -> bool {
        (at[0] >= self.lo[0])
            & (at[0] <= self.hi[0])
            & (at[1] >= self.lo[1])
            & (at[1] <= self.hi[1])
            & (at[2] >= self.lo[2])
            & (at[2] <= self.hi[2])
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

/// Counts a sub-beam's rays: `(rays, of which terminal at the next layer)`, given the
/// sub-beam and whether it is sent terminal.
type RayCount<'a, F> = dyn FnMut(&Beam<F>, bool) -> (u64, u64) + 'a;

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

/// The cell's eight output buffers, `OB` messages each, FIFO order. The eight lengths sit
/// together in one word ahead of the messages, so "is anything waiting", "which links have a
/// message" and the no-loss room check read 8 bytes instead of a header per buffer (the host's
/// cell step was bound by those loads). Buffers are tiny (`OB` = 3): popping shifts the rest.
#[derive(Clone, Debug)]
#[repr(C)]
pub struct OutBuffers<F: FracBits, const OB: usize> {
    len: [u8; 8],
    msgs: [[BeamMsg<F>; OB]; 8],
}

impl<F: FracBits, const OB: usize> Default for OutBuffers<F, OB> {
    fn default() -> Self {
        Self::new()
    }
}

impl<F: FracBits, const OB: usize> OutBuffers<F, OB> {
    const OB_FITS_A_BYTE: () =
        assert!(OB <= 127, "output buffer lengths are bytes, checked eight at a time with a bias of 127 − OB");

    /// Eight empty buffers.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::OB_FITS_A_BYTE;
        OutBuffers { len: [0; 8], msgs: [[BeamMsg::new(Beam::filler(), 0); OB]; 8] }
    }

    /// Messages waiting toward `p`.
    pub fn len(&self, p: Port) -> usize {
        self.len[p.index()] as usize
    }

    /// Whether nothing waits toward `p`.
    pub fn is_empty(&self, p: Port) -> bool {
        self.len[p.index()] == 0
    }

    /// Whether any buffer holds a message.
    pub fn any(&self) -> bool {
        self.lengths() != 0
    }

    /// The eight lengths as one word (byte p: port p).
    pub fn lengths(&self) -> u64 {
        u64::from_le_bytes(self.len)
    }

    /// The links with a message waiting, as a mask (bit p: port p). Each length is at most
    /// 127, so adding 127 to every byte sets its high bit exactly when it is non-zero, with no
    /// carry into the next byte.
    pub fn busy_mask(&self) -> u8 {
        const HIGH: u64 = 0x8080_8080_8080_8080;
        let nonzero = (self.lengths() + (HIGH - 0x0101_0101_0101_0101)) & HIGH;
        // Gather the eight high bits into one byte (bit 7 of byte p lands on bit 56 + p).
        (((nonzero >> 7).wrapping_mul(0x0102_0408_1020_4080)) >> 56) as u8
    }

    /// The links with a message waiting, in port order.
    pub fn busy_ports(&self) -> impl Iterator<Item = Port> {
        Port::each(self.busy_mask())
    }

    /// The oldest message toward `p`.
    pub fn front(&self, p: Port) -> Option<&BeamMsg<F>> {
        self.waiting(p).first()
    }

    /// The messages toward `p`, oldest first.
    pub fn waiting(&self, p: Port) -> &[BeamMsg<F>] {
        &self.msgs[p.index()][..self.len[p.index()] as usize]
    }

    /// Where the slots of buffer `p` start (reads nothing: for a host that prefetches).
    pub fn slots(&self, p: Port) -> *const BeamMsg<F> {
        self.msgs[p.index()].as_ptr()
    }

    /// The messages toward `p`, oldest first, to update in place (merging).
    pub fn waiting_mut(&mut self, p: Port) -> &mut [BeamMsg<F>] {
        &mut self.msgs[p.index()][..self.len[p.index()] as usize]
    }

    /// Queue `m` toward `p`; a full buffer gives it back.
    pub fn push_back(&mut self, p: Port, m: BeamMsg<F>) -> Result<(), BeamMsg<F>> {
        let (q, n) = (&mut self.msgs[p.index()], &mut self.len[p.index()]);
        let Some(slot) = q.get_mut(*n as usize) else { return Err(m) };
        *slot = m;
        *n += 1;
        Ok(())
    }

    /// Take the oldest message toward `p`.
    pub fn pop_front(&mut self, p: Port) -> Option<BeamMsg<F>> {
        let (q, n) = (&mut self.msgs[p.index()], &mut self.len[p.index()]);
        let len = *n as usize;
        if len == 0 {
            return None;
        }
        let m = q[0];
        // Every slot moves up, waiting or not (`OB` is tiny): a fixed-size copy the compiler
        // unrolls, where a copy of `len − 1` slots was a call to `memmove`. Slots past the
        // length are never read.
        for s in 1..OB {
            q[s - 1] = q[s];
        }
        *n -= 1;
        Some(m)
    }
}

/// Whether every byte of `lengths` (each ≤ `OB` ≤ 127) plus the same byte of `need` (each ≤ 9)
/// is at most `OB`: the bytes of `lengths + need + (127 − OB)` are at most 136 (no carry) and
/// reach 128 exactly when the sum exceeds `OB`.
const fn room<const OB: usize>(lengths: u64, need: u64) -> bool {
    const HIGH: u64 = 0x8080_8080_8080_8080;
    let bias = u64::from_le_bytes([(127 - OB) as u8; 8]);
    (lengths + need + bias) & HIGH == 0
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

    /// Decide a beam's fate into `f` without changing the cell.
    fn fate<const D: usize>(&self, m: &BeamMsg<F>, cell: &Cell<D>, env: &LightEnv<'_, F>, f: &mut Fate<'_, F>) {
        f.reset();
        match env.rule {
            LitRule::Thesis => self.thesis_fate(m, &cell.store, env, f),
            LitRule::Plane => self.plane_fate(m, cell, env, f),
            #[cfg(feature = "exact-occluders")]
            LitRule::Exact => self.exact_fate(m, &cell.store, env, f),
        }
    }

    /// The thesis's rule (§5.5.5): an occupied voxel absorbs the beam and is lit by it.
    fn thesis_fate<const D: usize>(
        &self,
        m: &BeamMsg<F>,
        store: &DexelStore<D>,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        if store.occupied(m.z).is_some() {
            f.absorbed = m.beam.ray_count();
            f.lit = true;
            record(&mut f.events, Some(m.z), &m.beam);
            return;
        }
        if self.frustum_skips(m, env, f) {
            return;
        }
        self.route(&m.beam, m.z, env, f, |_| Sub::Send(false, Local::NONE));
    }

    /// The empty-frustum skip ([`LightEnv::frustum`]): drops the beam (its rays skipped) when
    /// none of its rays can meet an occupied block at a later layer. For a beam with nothing to
    /// do at its own voxel.
    fn frustum_skips(&self, m: &BeamMsg<F>, env: &LightEnv<'_, F>, f: &mut Fate<'_, F>) -> bool {
        let b = &m.beam;
        let skip = env.frustum.is_some_and(|o| o.frustum_empty(b, env.source, env.far, b.layer().0 + 1));
        if skip {
            f.skipped = b.ray_count();
            record(&mut f.events, None, b);
        }
        skip
    }

    /// The transverse position of voxel `z` of this column for direction `dir`.
    fn at(&self, dir: Direction, z: Depth) -> ([i64; 3], Transverse) {
        let pos = [self.x as i64, self.y as i64, z as i64];
        let (ua, va) = dir.transverse();
        (pos, Transverse { u: pos[ua.index()] as i32, v: pos[va.index()] as i32 })
    }

    /// Split `beam` (held at voxel `z` of this column) and file its sub-beams into `f`: `decide`
    /// says, by transverse offset, whether a sub-beam is sent (terminal or not, with what local
    /// state) or absorbed here. Sub-beams leaving the grid count as exited, those the receding
    /// skip drops as skipped; `rays` counts a sub-beam's rays (its rectangle's, unless a notch
    /// removes some).
    fn route(
        &self,
        beam: &Beam<F>,
        z: Depth,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
        mut decide: impl FnMut(crate::beam::Offset) -> Sub,
    ) {
        let mut rays = |b: &Beam<F>, terminal: bool| (b.ray_count(), if terminal { b.ray_count() } else { 0 });
        self.route_counted(beam, z, env, f, &mut decide, &mut rays);
    }

    /// [`LightCell::route`] with the rays of each sub-beam counted by `rays(sub-beam, terminal)`:
    /// `(rays, of which terminal at the next layer)`.
    fn route_counted(
        &self,
        beam: &Beam<F>,
        z: Depth,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
        decide: &mut dyn FnMut(crate::beam::Offset) -> Sub,
        rays: &mut RayCount<'_, F>,
    ) {
        let dir = beam.direction();
        let (pos, at) = self.at(dir, z);
        let Fate { subs, exited, skipped, absorbed, after_empty, after_outside, events, .. } = f;
        let (after_empty, after_outside) = (*after_empty, *after_outside);
        debug_assert_eq!(env.bounds, SubBeamBounds::new(env.n, env.depth, env.skip, env.source));
        let bounds = &env.bounds;
        // The principal step to the next layer: one voxel, but none from layer 0 (the source
        // voxel) when layer 1 is the source voxel's slab (rays from the light, [`Source::slab`]).
        let w = dir.principal().index();
        let step_w = match beam.layer().0 {
            0 if cfg!(feature = "rays-from-light") => {
                (env.source.slab(dir, Layer(1)) - env.source.slab(dir, Layer(0))) as i8
            }
            _ => dir.sign(),
        };
        let split = beam.split_each(env.source, env.far, at, env.order, |sb| {
            let (terminal, local) = match decide(sb.offset) {
                Sub::Send(t, l) => (t, l),
                Sub::Absorb => {
                    *absorbed += rays(&sb.beam, false).0;
                    record(events, Some(z), &sb.beam);
                    return;
                }
            };
            let mut d = dir.displacement(sb.offset);
            d[w] = step_w;
            let to = [pos[0] + d[0] as i64, pos[1] + d[1] as i64, pos[2] + d[2] as i64];
            if bounds.keeps(dir, to) {
                let target = match Port::from_delta(d[0], d[1]) {
                    Some(p) => Target::Out(p),
                    None => Target::SelfFifo,
                };
                // A ray staying in its column meets the same dexel's plane, or another dexel
                // (the column rule), or an empty voxel next: it carries no outside flag.
                let outside = after_outside && target != Target::SelfFifo;
                let beam = sb.beam.with_terminal(terminal).with_after_empty(after_empty).with_after_outside(outside);
                let msg = BeamMsg { local, ..BeamMsg::new(beam, to[2] as Depth) };
                // At most nine sub-beams: never full.
                let _ = subs.push((target, msg));
            } else if !bounds.in_grid(to) {
                *exited += rays(&sb.beam, terminal).0;
                record(events, None, &sb.beam);
            } else {
                // Dropped by the receding skip; a terminal ray dies at its next voxel anyway
                // (lighting nothing: it is beyond every occupied voxel): absorbed.
                let (all, dying) = rays(&sb.beam, terminal);
                *absorbed += dying;
                *skipped += all - dying;
                record(events, None, &sb.beam);
            }
        });
        // At the far plane (k = D) or for a beam that is not this source's: the next layer is
        // outside every grid the far distance was chosen for; the rays leave.
        if split.is_err() {
            *exited += rays(beam, false).0;
            record(events, None, beam);
        }
    }

    /// The plane rule ([`crate::lit`]) at this beam's voxel.
    fn plane_fate<const D: usize>(&self, m: &BeamMsg<F>, cell: &Cell<D>, env: &LightEnv<'_, F>, f: &mut Fate<'_, F>) {
        let b = &m.beam;
        let dir = b.direction();
        let k = b.layer().0 as i64;
        let (x, y) = (self.x as i64, self.y as i64);
        let plane = |d: &Dexel| RayPlane::new(&d.plane, [x, y, d.span.lo as i64], env.source, dir, env.far);
        let own = cell.store.occupied(m.z);
        let notch = m.local.notch();
        let state = notch.and_then(|n| cell.store.occupied(n.state).map(|d| (plane(d), n)));
        let other = matches!((notch, own), (Some(n), Some(d)) if !d.span.contains(n.state));
        let visible = cell
            .visible
            .filter(|v| v.brackets(m.z as i64))
            .map(|v| RayPlane::new(&v.plane, [x, y, v.z_v as i64], env.source, dir, env.far));
        let mut visit = Visit::new(k, Arrival::of(b), own.map(plane), state, visible, other);
        f.after_empty = own.is_none();
        f.after_outside = false;
        if visit.is_plain() {
            // Nothing happens at this voxel: the thesis's path (a notched beam is not plain).
            if m.local == Local::NONE && self.frustum_skips(m, env, f) {
                return;
            }
            self.route(b, m.z, env, f, |_| Sub::Send(false, Local::NONE));
            return;
        }
        let stay = self.staying(b, env);
        let (u, v) = (lattice(b.u()), lattice(b.v()));
        if let Some(bits) = uniform(&visit.tests, u, v) {
            let out = visit.verdict(bits, false);
            let stays = visit.verdict(bits, true);
            f.after_outside = visit.outside(bits);
            f.lit = out.lit;
            f.visible = out.visible;
            match out.out {
                Out::Absent => {}
                Out::Absorbed => f.absorbed = b.ray_count(),
                Out::Continue | Out::Terminal => {
                    let send = out.out == Out::Terminal;
                    let stay_sub = match stays.out {
                        Out::Continue => Sub::Send(false, self.carried(m, own.map(|d| d.span), k, &visit)),
                        Out::Terminal => Sub::Send(true, Local::NONE),
                        _ => Sub::Absorb,
                    };
                    let z = m.z;
                    self.route(b, z, env, f, |o| {
                        if o == STAY && stay.is_some() {
                            stay_sub
                        } else {
                            Sub::Send(send, Local::NONE)
                        }
                    });
                }
            }
            return;
        }
        let carry = self.carried(m, own.map(|d| d.span), k, &visit);
        self.peel::<_, { 2 * crate::lit::MAX_TESTS + 1 }>(m, &mut visit, &|_, _| {}, stay, carry, env, f);
    }

    /// The exact-occluder rule ([`crate::occluder::ExactVisit`]) at this beam's voxel.
    #[cfg(feature = "exact-occluders")]
    fn exact_fate<const D: usize>(
        &self,
        m: &BeamMsg<F>,
        store: &DexelStore<D>,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        let b = &m.beam;
        let dir = b.direction();
        let k = b.layer().0 as i64;
        let (u, v) = (lattice(b.u()), lattice(b.v()));
        let triangles = env.occluders.map_or(&[][..], |o| o.triangles(self.x, self.y));
        let seen = env.occluders.and_then(|o| o.seen(self.x, self.y));
        let notch = m.local.notch().map(|n| n.t1 as i64);
        let mut tests = ExactTests::new();
        let mut visit =
            ExactVisit::new(&mut tests, triangles, seen, env.source, dir, env.far, k, (u, v), b.is_terminal(), notch);
        f.per_ray = visit.per_ray();
        // The receiver: the column's target ray, if this beam brings it here (absent rays were
        // absorbed earlier; a terminal or absorbed one still arrived).
        let target = env.occluders.and_then(|o| o.target(self.x, self.y));
        if let Some(t) = target.filter(|t| t.z == m.z as i64 && t.in_beam(b)) {
            // It arrived, and no triangle of this column or its neighbours shadows the pixel
            // from close by.
            let lit = visit.verdict(visit.bits(t.a, t.b), false).out.present() && !t.in_contact_shadow(triangles);
            f.visible = lit;
            f.lit = lit;
        }
        // The full lit store keeps every occupied voxel whose own ray arrives
        // ([`crate::receiver::voxel_ray`]); the visible-only store, the pixel's target voxel.
        if !env.lit_visible_only {
            f.lit = store.occupied(m.z).is_some()
                && crate::receiver::voxel_ray(self.x as i32, self.y as i32, m.z as i64, env.source, env.far)
                    .is_some_and(|t| t.in_beam(b) && visit.verdict(visit.bits(t.a, t.b), false).out.present());
        }
        if visit.is_plain() {
            if m.local == Local::NONE && !f.visible && self.frustum_skips(m, env, f) {
                return;
            }
            self.route(b, m.z, env, f, |_| Sub::Send(false, Local::NONE));
            return;
        }
        let stay = self.staying(b, env);
        // Staying rays carry the notch of this column's triangles since they entered it, unless
        // every ray of the rectangle had the same verdict (then none is missing).
        let carry = match (visit.is_uniform(), notch) {
            (true, _) => Local::NONE,
            (false, t1) => Local::notched(Notch {
                state: 0,
                t1: t1.unwrap_or((k - 1).max(0)) as u16,
                t2: k as u16,
                fresh: false,
                front: false,
            }),
        };
        if visit.is_uniform() {
            let out = visit.verdict(0, false);
            let stays = visit.verdict(0, true);
            match out.out {
                Out::Absent => {}
                Out::Absorbed => f.absorbed = b.ray_count(),
                Out::Continue | Out::Terminal => {
                    let send = out.out == Out::Terminal;
                    let stay_sub = Sub::Send(stays.out == Out::Terminal, carry);
                    self.route(b, m.z, env, f, |o| {
                        if o == STAY && stay.is_some() {
                            stay_sub
                        } else {
                            Sub::Send(send, Local::NONE)
                        }
                    });
                }
            }
            return;
        }
        let revisit =
            |b: &Beam<F>, v: &mut ExactVisit<'_, '_, F>| v.rejudge((lattice(b.u()), lattice(b.v())), b.is_terminal());
        self.peel::<_, EXACT_SEGMENTS>(m, &mut visit, &revisit, stay, carry, env, f);
    }

    /// The local state a ±z beam's staying rays carry to the next layer of this column (see
    /// the column rule of [`crate::lit`]): after a surface voxel (`own`: its dexel's span; the
    /// staying rays were not absorbed by the column rule), a fresh notch of that dexel's plane
    /// (extending the beam's own when it is the same dexel); after an empty voxel, the beam's
    /// notch without its terminal rays, which died there.
    fn carried(&self, m: &BeamMsg<F>, own: Option<crate::units::Span>, k: i64, visit: &Visit) -> Local {
        let notch = m.local.notch();
        match own {
            Some(span) => {
                // A new notch excludes, besides the rays that crossed, those the visit absorbed
                // for arriving behind the plane (rule 4).
                let (t1, front) = match notch {
                    Some(n) if span.contains(n.state) => (n.t1, n.front),
                    _ => ((k - 1).max(0) as u16, visit.absorbs_behind()),
                };
                Local::notched(Notch { state: m.z, t1, t2: k as u16, fresh: true, front })
            }
            None => match notch {
                Some(n) => Local::notched(Notch { t2: n.t2 + n.fresh as u16, fresh: false, ..n }),
                None => Local::NONE,
            },
        }
    }

    /// The rays an entry holds: its rectangle's, less those its notch excludes (counted run by
    /// run, [`crate::lit`]). For the per-step conservation check of debug builds.
    #[cfg(debug_assertions)]
    fn present_rays<const D: usize>(&self, m: &BeamMsg<F>, cell: &Cell<D>, env: &LightEnv<'_, F>) -> u64 {
        let b = &m.beam;
        let Some(n) = m.local.notch() else {
            return b.ray_count();
        };
        let (u, v) = (lattice(b.u()), lattice(b.v()));
        let (dir, k) = (b.direction(), b.layer().0 as i64);
        #[cfg(feature = "exact-occluders")]
        if env.rule == LitRule::Exact {
            let triangles = env.occluders.map_or(&[][..], |o| o.triangles(self.x, self.y));
            let seen = env.occluders.and_then(|o| o.seen(self.x, self.y));
            let mut tests = ExactTests::new();
            let visit = ExactVisit::new(
                &mut tests,
                triangles,
                seen,
                env.source,
                dir,
                env.far,
                k,
                (u, v),
                false,
                Some(n.t1 as i64),
            );
            return Self::count_present::<_, EXACT_SEGMENTS>(&visit, u, v);
        }
        let Some(d) = cell.store.occupied(n.state) else {
            return b.ray_count();
        };
        let (x, y) = (self.x as i64, self.y as i64);
        let plane = RayPlane::new(&d.plane, [x, y, d.span.lo as i64], env.source, dir, env.far);
        let visit = Visit::new(k, Arrival::NONE, None, Some((plane, Notch { fresh: false, ..n })), None, false);
        Self::count_present::<_, { 2 * crate::lit::MAX_TESTS + 1 }>(&visit, u, v)
    }

    /// The rays of rectangle `u × v` that `visit` finds present (not cut out by a notch).
    #[cfg(debug_assertions)]
    fn count_present<R: Rule, const C: usize>(visit: &R, u: (i64, i64), v: (i64, i64)) -> u64 {
        let mut seg = Segments::<C>::new();
        let (mut line, mut present) = (u.0, 0u64);
        while line <= u.1 {
            let end = visit.run_end(Along::V, line, u.1, v.0, v.1);
            visit.line(Along::V, line, v.0, v.1, &mut seg);
            for (start, stop, bits) in spans(&seg, v.1) {
                if visit.verdict(bits, false).out.present() {
                    present += (end - line + 1) as u64 * (stop - start + 1) as u64;
                }
            }
            line = end + 1;
        }
        present
    }

    /// For a ±z beam, the lattice rays of each axis that stay in this column at the next layer
    /// (`None` for the other directions, whose sub-beams all change column, and at the far plane
    /// k = D, past which every ray leaves).
    fn staying(&self, b: &Beam<F>, env: &LightEnv<'_, F>) -> Option<((i64, i64), (i64, i64))> {
        let dir = b.direction();
        if dir.principal() != crate::beam::Axis::Z || b.layer().0 >= env.far.get() {
            return None;
        }
        let (ua, va) = dir.transverse();
        let reach = env.source.reach(dir, Layer(b.layer().0 + 1));
        let su = staying_rays(env.source.pos[ua.index()], self.x as i32, env.far, reach);
        let sv = staying_rays(env.source.pos[va.index()], self.y as i32, env.far, reach);
        Some((su, sv))
    }

    /// Peel a beam whose rectangle is not uniform under the plane rule: one rectangle of uniform
    /// verdict per step, the rest staying in the FIFO slot (see [`crate::lit`]). The rays that
    /// change column go first, run by run, from the outside in (for a ±z beam: the columns
    /// before and after the staying rays, then the rows below and above them), so that what is
    /// left is always a rectangle; the staying rays go last, as one beam, and the entry is
    /// consumed.
    #[allow(clippy::too_many_arguments)]
    fn peel<R: Rule, const C: usize>(
        &self,
        m: &BeamMsg<F>,
        visit: &mut R,
        revisit: &dyn Fn(&Beam<F>, &mut R),
        stay: Option<((i64, i64), (i64, i64))>,
        carry: Local,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        let mut beam = m.beam;
        let mut piece = m.local.piece;
        let mut seg = Segments::<C>::new();
        loop {
            let (a0, a1) = lattice(beam.u());
            let (b0, b1) = lattice(beam.v());
            // The region of this step: lines `from` toward `to` along `along` (upward: from the
            // low end), across `cross`.
            let region = match stay {
                Some(((su0, su1), (sv0, sv1))) => {
                    if a0 < su0 {
                        Some((Along::V, true, a0, a1.min(su0 - 1), (b0, b1)))
                    } else if a1 > su1 {
                        Some((Along::V, false, a1, a0.max(su1 + 1), (b0, b1)))
                    } else if b0 < sv0 {
                        Some((Along::U, true, b0, b1.min(sv0 - 1), (a0, a1)))
                    } else if b1 > sv1 {
                        Some((Along::U, false, b1, b0.max(sv1 + 1), (a0, a1)))
                    } else {
                        None
                    }
                }
                None => Some((Along::V, true, a0, a1, (b0, b1))),
            };
            let Some((along, upward, from, to, cross)) = region else {
                // Only staying rays are left: one beam to this column's next voxel.
                self.peel_staying::<R, C>(m, beam, visit, carry, env, f);
                return;
            };
            visit.line(along, from, cross.0, cross.1, &mut seg);
            let end = if R::BY_VERDICT {
                let mut next = Segments::<C>::new();
                crate::lit::verdict_run_end(&*visit, along, (from, to), cross, &seg, &mut next)
            } else {
                visit.run_end(along, from, to, cross.0, cross.1)
            };
            let lines = (from.min(end), from.max(end));

            let width = (lines.1 - lines.0 + 1) as u64;
            let (mut present, mut sent, mut count) = (0u64, 0u64, 0u8);
            let mut emit = None;
            let mut pieces = |(start, stop, v, outside): (i64, i64, Verdict, bool)| {
                f.lit |= v.lit;
                f.visible |= v.visible;
                let rays = width * (stop - start + 1) as u64;
                if v.out.present() {
                    present += rays;
                }
                if v.out.goes_on() {
                    if count == piece {
                        emit = Some((start, stop, v.out == Out::Terminal, outside));
                    }
                    count += 1;
                    sent += rays;
                }
            };
            if R::BY_VERDICT {
                crate::lit::verdict_spans(&*visit, &seg, cross.1, false).for_each(&mut pieces);
            } else {
                spans(&seg, cross.1)
                    .for_each(|(a, b, bits)| pieces((a, b, visit.verdict(bits, false), visit.outside(bits))));
            }
            if let Some((start, stop, terminal, outside)) = emit {
                let (u, v) = match along {
                    Along::V => (lines, (start, stop)),
                    Along::U => ((start, stop), lines),
                };
                let rect = beam.with_rays(range::<F>(u), range::<F>(v));
                f.after_outside = outside;
                self.route(&rect, m.z, env, f, |_| Sub::Send(terminal, Local::NONE));
                piece += 1;
                if piece < count {
                    f.keep = Some(BeamMsg { beam, local: Local { piece, ..m.local }, ..*m });
                    return;
                }
            }
            // The run is done: its rays not sent were absorbed; the beam shrinks past it.
            f.absorbed += present - sent;
            piece = 0;
            let (u, v) = (lattice(beam.u()), lattice(beam.v()));
            let shrunk = match (along, upward) {
                (Along::V, true) => ((lines.1 + 1, u.1), v),
                (Along::V, false) => ((u.0, lines.0 - 1), v),
                (Along::U, true) => (u, (lines.1 + 1, v.1)),
                (Along::U, false) => (u, (v.0, lines.0 - 1)),
            };
            if shrunk.0 .0 > shrunk.0 .1 || shrunk.1 .0 > shrunk.1 .1 {
                // Nothing left: the entry is consumed.
                return;
            }
            beam = beam.with_rays(range::<F>(shrunk.0), range::<F>(shrunk.1));
            // A visit that depends on the rectangle is taken again on what is left: the same
            // visit the next step will take on it, so a run's pieces are cut alike in every step.
            revisit(&beam, visit);
            if emit.is_some() {
                f.keep = Some(BeamMsg { beam, local: Local { piece: 0, ..m.local }, ..*m });
                return;
            }
        }
    }

    /// The last step of a peeled ±z beam: `beam` holds only rays that stay in the column. Those
    /// that go on become one beam for the next voxel of the column ([`LightCell::carried`]); the
    /// entry is consumed.
    fn peel_staying<R: Rule, const C: usize>(
        &self,
        m: &BeamMsg<F>,
        beam: Beam<F>,
        visit: &R,
        carry: Local,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        let (u, v) = (lattice(beam.u()), lattice(beam.v()));
        let (mut present, mut going, mut dying) = (0u64, 0u64, 0u64);
        let mut seg = Segments::<C>::new();
        let mut line = u.0;
        while line <= u.1 {
            let end = visit.run_end(Along::V, line, u.1, v.0, v.1);
            let width = (end - line + 1) as u64;
            visit.line(Along::V, line, v.0, v.1, &mut seg);
            for (start, stop, bits) in spans(&seg, v.1) {
                let verdict = visit.verdict(bits, true);
                f.lit |= verdict.lit;
                f.visible |= verdict.visible;
                let rays = width * (stop - start + 1) as u64;
                if verdict.out.present() {
                    present += rays;
                }
                if verdict.out.goes_on() {
                    going += rays;
                }
                if verdict.out == Out::Terminal {
                    dying += rays;
                }
            }
            line = end + 1;
        }
        f.absorbed += present - going;
        if going > 0 {
            let mut decide = |_| Sub::Send(false, carry);
            self.route_counted(&beam, m.z, env, f, &mut decide, &mut |_, _| (going, dying));
        }
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
        if env.rule != LitRule::Thesis && self.fifo[i].local.piece == 0 && fate.keep.is_none_or(|k| k.local.piece == 0)
        {
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
        let shown = match env.rule {
            LitRule::Thesis => !env.lit_visible_only || cell.store.dexels().first().is_some_and(|d| d.span.lo == z),
            // The image reads the visible surface's mark; the lit store is for the lit set,
            // restricted to the two voxels bracketing the visible surface (and under exact
            // occluders the one in front of them, where the target ray may arrive).
            LitRule::Plane => !env.lit_visible_only || cell.visible.is_some_and(|v| v.brackets(z as i64)),
            #[cfg(feature = "exact-occluders")]
            LitRule::Exact => !env.lit_visible_only || cell.visible.is_some_and(|v| v.receives(z as i64)),
        };
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
mod tests {
    extern crate std;
    use super::*;
    use proptest::prelude::*;

    /// The environment of the hand-made cases below: the thesis's rule and policy, FIFO size
    /// 4, one source bit, no merging, skip, hold, frustum summary or ray sink; each case
    /// changes what it tests with struct update.
    fn thesis_env<'a, F: FracBits>(
        source: &'a Source,
        order: &'a SplitOrder,
        far: FarDistance<F>,
        n: u32,
    ) -> LightEnv<'a, F> {
        LightEnv {
            source,
            far,
            n,
            depth: n,
            policy: Policy::Thesis,
            rule: LitRule::Thesis,
            order,
            fa: 4,
            free_ports: false,
            source_bit: 1,
            merge: false,
            skip: None,
            lit_visible_only: false,
            hold: 0,
            frustum: None,
            rays: None,
            bounds: SubBeamBounds::new(n, n, None, source),
            occluders: None,
        }
    }

    fn check<const L: usize>(r: &LitRuns<L>) {
        for w in r.runs().windows(2) {
            assert!(w[0].hi < w[1].lo);
            assert!(!(w[0].hi + 1 == w[1].lo && w[0].mask == w[1].mask), "unmerged {:?}", w);
        }
        assert!(r.runs().iter().all(|x| x.lo <= x.hi && x.mask != 0));
    }

    #[test]
    fn lit_runs_split_and_merge() {
        let mut r = LitRuns::<8>::new();
        for z in 10..=20 {
            assert!(r.mark(z, 1));
        }
        assert_eq!(r.runs(), &[LitRun { lo: 10, hi: 20, mask: 1 }]);
        assert!(r.mark(15, 2));
        assert_eq!(r.runs().len(), 3);
        assert_eq!((r.mask_at(14), r.mask_at(15), r.mask_at(16), r.mask_at(9)), (1, 3, 1, 0));
        assert!(r.mark(14, 2) && r.mark(16, 2));
        assert_eq!(
            r.runs(),
            &[
                LitRun { lo: 10, hi: 13, mask: 1 },
                LitRun { lo: 14, hi: 16, mask: 3 },
                LitRun { lo: 17, hi: 20, mask: 1 }
            ]
        );
        check(&r);
    }

    #[test]
    fn lit_runs_overflow_is_counted_and_harmless() {
        let mut r = LitRuns::<2>::new();
        assert!(r.mark(1, 1) && r.mark(5, 1));
        assert!(!r.mark(9, 1));
        assert_eq!(r.overflows(), 1);
        assert_eq!(r.mask_at(9), 0);
        assert!(r.mark(2, 1), "merging needs no new run");
    }

    /// The eight-at-once room check against byte-by-byte comparison, exhaustively for one
    /// byte at every position (the other seven empty or full), at OB = 1, 3 and 127.
    #[test]
    fn room_matches_bytewise_comparison() {
        fn check<const OB: usize>() {
            for pos in 0..8 {
                for other in [0u64, OB as u64] {
                    for len in 0..=OB as u64 {
                        for need in 0..=9u64 {
                            let fill = u64::from_le_bytes([other as u8; 8]) & !(0xFF << (8 * pos));
                            let lengths = fill | len << (8 * pos);
                            let needs = need << (8 * pos);
                            let expect = len + need <= OB as u64 && other <= OB as u64;
                            assert_eq!(room::<OB>(lengths, needs), expect, "OB {OB} byte {pos} len {len} need {need}");
                        }
                    }
                }
            }
        }
        check::<1>();
        check::<3>();
        check::<127>();
    }

    /// The busy-port mask against byte-by-byte testing, exhaustively over which of the eight
    /// buffers hold something, with lengths at both ends of a byte (1 and the cap 127) and in
    /// between; and `Port::each` against filtering `Port::ALL`.
    #[test]
    fn busy_mask_matches_bytewise_test() {
        for mask in 0..=255u8 {
            let each: std::vec::Vec<Port> = Port::each(mask).collect();
            let want: std::vec::Vec<Port> = Port::ALL.into_iter().filter(|p| mask >> p.index() & 1 == 1).collect();
            assert_eq!(each, want, "mask {mask:#010b}");
            for len in [1u8, 2, 3, 64, 126, 127] {
                let mut b = OutBuffers::<fixed::types::extra::U0, 127>::new();
                for p in Port::ALL {
                    b.len[p.index()] = if mask >> p.index() & 1 == 1 { len.max(1 + p.index() as u8) } else { 0 };
                }
                assert_eq!(b.busy_mask(), mask, "lengths {:?}", b.len);
                assert!(b.busy_ports().eq(want.iter().copied()));
            }
        }
    }
    proptest! {
        /// The receding test against its definition, axis by axis: empty box, or beyond the box
        /// along the principal axis in the direction of travel, or beyond the box on a
        /// transverse axis and strictly beyond the source voxel on the same side.
        #[test]
        fn receding_matches_its_definition(
            lo in proptest::array::uniform3(0u16..12), hi in proptest::array::uniform3(0u16..12),
            sv in proptest::array::uniform3(-2i32..14), at in proptest::array::uniform3(-3i64..15),
            d in 0usize..6,
        ) {
            let dir = Direction::ALL[d];
            let bx = OccupiedBox { lo, hi };
            let w = dir.principal().index();
            let empty = (0..3).any(|a| lo[a] > hi[a]);
            let ahead = if dir.sign() > 0 { at[w] > hi[w] as i64 } else { at[w] < lo[w] as i64 };
            let side = (0..3).filter(|&a| a != w).any(|a| {
                let (l, h, s) = (lo[a] as i64, hi[a] as i64, sv[a] as i64);
                (at[a] > h && at[a] > s) || (at[a] < l && at[a] < s)
            });
            prop_assert_eq!(bx.receding(dir, sv, at), empty || ahead || side);
        }

        /// The output buffers against eight `VecDeque`s bounded at OB: same accept/refuse, same
        /// order, and the one-word summaries (`any`, `busy_ports`, `len`) agree.
        #[test]
        fn out_buffers_match_bounded_deques(ops in proptest::collection::vec((0usize..8, any::<bool>(), any::<u16>()), 0..200)) {
            let mut b = OutBuffers::<fixed::types::extra::U0, 3>::new();
            let mut want: [std::collections::VecDeque<u16>; 8] = Default::default();
            for (p, push, z) in ops {
                let port = Port::ALL[p];
                if push {
                    let r = b.push_back(port, BeamMsg::new(Beam::filler(), z));
                    prop_assert_eq!(r.is_ok(), want[p].len() < 3);
                    if want[p].len() < 3 {
                        want[p].push_back(z);
                    } else {
                        prop_assert_eq!(r.unwrap_err().z, z);
                    }
                } else {
                    prop_assert_eq!(b.pop_front(port).map(|m| m.z), want[p].pop_front());
                }
                for q in Port::ALL {
                    let w = &want[q.index()];
                    prop_assert_eq!(b.len(q), w.len());
                    prop_assert_eq!(b.is_empty(q), w.is_empty());
                    prop_assert_eq!(b.front(q).map(|m| m.z), w.front().copied());
                    prop_assert!(b.waiting(q).iter().map(|m| m.z).eq(w.iter().copied()));
                }
                prop_assert_eq!(b.any(), want.iter().any(|w| !w.is_empty()));
                prop_assert!(b.busy_ports().eq(Port::ALL.into_iter().filter(|q| !want[q.index()].is_empty())));
            }
        }

        /// The blocked- and held-step shortcuts are exact: a cell driven by random steps, link
        /// pops and arrivals behaves like a twin that forgets the shortcut before every step
        /// (full re-evaluation of every waiting beam), and like a twin that is not stepped at
        /// all while held ([`LightCell::held_wait`]) and catches up with
        /// [`LightCell::skip_held`] before anything changes it — the host's sleeping cells.
        /// Output buffers of one message, so that cells block often; sibling waits of 0, 2, 3.
        #[test]
        fn blocked_and_held_shortcuts_change_nothing(
            hold in prop_oneof![Just(0u16), Just(2), Just(3)],
            radial in any::<bool>(),
            ops in proptest::collection::vec((0u8..4, 0usize..8, 0usize..24), 1..150),
        ) {
            use crate::beam::{SourceCoord, SourceId};
            use fixed::types::extra::U0;
            type C = LightCell<U0, 4, 1, 8>;
            let n = 16;
            let c = |v: f64| SourceCoord::from_num(v);
            let src = Source::new(SourceId(0), [c(7.5), c(7.25), c(7.0)]);
            let far = FarDistance::<U0>::new(n - 1).unwrap();
            let order = SplitOrder::default();
            let env = LightEnv {
                merge: true,
                policy: if radial { Policy::Radial } else { Policy::Wavefront },
                hold,
                ..thesis_env(&src, &order, far, n)
            };
            let mut store = Cell::<8>::new(0, 0);
            let tag = crate::dexel::FacetTag::default();
            let _ = store.store.insert(crate::units::Span { lo: 12, hi: 13 }, tag);
            let sv = src.voxel();
            // The cell two columns east of the source's and one north, and what can reach it:
            // the initial beams, and the source's +x beam split twice, every layer-2 sub-beam
            // for this column cut in two along u (pieces that wait for each other and merge).
            let (cx, cy) = (sv[0] + 2, sv[1] + 1);
            let mut arrivals: std::vec::Vec<BeamMsg<U0>> =
                Beam::<U0>::initial_six(&src, far).iter().map(|&beam| BeamMsg::new(beam, sv[2] as u16)).collect();
            let px = Direction::PosX;
            for s1 in Beam::<U0>::initial(&src, px, far).split(&src, far, px.transverse_of(sv)).unwrap() {
                let d1 = px.displacement(s1.offset);
                let v1 = [sv[0] + d1[0] as i32, sv[1] + d1[1] as i32, sv[2] + d1[2] as i32];
                for s2 in s1.beam.split(&src, far, px.transverse_of(v1)).unwrap() {
                    let d2 = px.displacement(s2.offset);
                    let v2 = [v1[0] + d2[0] as i32, v1[1] + d2[1] as i32, v1[2] + d2[2] as i32];
                    if (v2[0], v2[1]) != (cx, cy) {
                        continue;
                    }
                    let (b, u) = (s2.beam, s2.beam.u());
                    let mid = crate::beam::FarOffset::<U0>::from_bits((u.lo().to_bits() + u.hi().to_bits()) / 2);
                    for (lo, hi) in [(u.lo(), mid), (mid + crate::beam::FarOffset::<U0>::from_bits(1), u.hi())] {
                        if let Some(r) = crate::beam::RayRange::new(lo, hi) {
                            let piece = Beam::new(b.source(), px, b.layer(), r, b.v(), far).unwrap();
                            arrivals.push(BeamMsg::new(piece, v2[2] as u16));
                        }
                    }
                }
            }
            let new = || C::new(cx as u16, cy as u16);
            let (mut a, mut b, mut s) = (new(), new(), new());
            let (ta, tb, ts) = (Activity::new(), Activity::new(), Activity::new());
            // The sleeping twin `s`: asleep after a held step, owing the steps it skips.
            let (mut asleep, mut owed) = (false, 0u16);
            let mut popped: std::vec::Vec<BeamMsg<U0>> = std::vec::Vec::new();
            for (op, port, which) in ops {
                // Anything but a step that the wait still covers wakes the twin first.
                let covered = asleep && op == 0 && s.held_wait().is_some_and(|w| owed + 1 < w);
                if asleep && !covered {
                    s.skip_held(owed);
                    (asleep, owed) = (false, 0);
                }
                match op {
                    0 => {
                        b.blocked_on = None;
                        let r = a.step(&store, &env, &ta);
                        prop_assert_eq!(r, b.step(&store, &env, &tb));
                        if covered {
                            prop_assert_eq!(r, Step::Held);
                            owed += 1;
                        } else {
                            prop_assert_eq!(r, s.step(&store, &env, &ts));
                            asleep = r == Step::Held;
                        }
                    }
                    1 => {
                        let p = Port::ALL[port];
                        let (x, y, z) = (a.out.pop_front(p), b.out.pop_front(p), s.out.pop_front(p));
                        prop_assert_eq!(x, y);
                        prop_assert_eq!(x, z);
                        popped.extend(x);
                    }
                    _ => {
                        // A new arrival: a piece for this column, or a message a link took earlier.
                        let m = match popped.get(which) {
                            Some(&m) if which % 2 == 0 => m,
                            _ => arrivals[which % arrivals.len()],
                        };
                        if a.can_accept(env.fa) {
                            ta.add(1);
                            tb.add(1);
                            ts.add(1);
                            let r = a.accept(m, true, &ta).is_ok();
                            prop_assert_eq!(r, b.accept(m, true, &tb).is_ok());
                            prop_assert_eq!(r, s.accept(m, true, &ts).is_ok());
                        }
                    }
                }
                let mut caught_up = s.clone();
                caught_up.skip_held(owed);
                for t in [&b, &caught_up] {
                    prop_assert_eq!(&a.fifo, &t.fifo);
                    prop_assert_eq!(a.ticks, t.ticks);
                    for p in Port::ALL {
                        prop_assert_eq!(a.out.waiting(p), t.out.waiting(p));
                    }
                    prop_assert_eq!(a.counters, t.counters);
                }
                prop_assert_eq!(ta.get(), tb.get());
                prop_assert_eq!(ta.get(), ts.get());
            }
        }

        #[test]
        fn lit_runs_match_a_per_voxel_array(marks in proptest::collection::vec((0u16..40, 0u32..4), 0..60)) {
            let mut r = LitRuns::<64>::new();
            let mut want = [0u32; 40];
            for (z, s) in marks {
                prop_assert!(r.mark(z, 1 << s));
                want[z as usize] |= 1 << s;
                check(&r);
            }
            for z in 0..40u16 {
                prop_assert_eq!(r.mask_at(z), want[z as usize]);
            }
        }
    }

    /// The free-ports rule (§4.4.1, "si dir propagation libre"): the source's +z beam sends one
    /// sub-beam to each of the 8 neighbours. With one message already waiting toward the east
    /// there is room for one more, so the beam goes by default; under `free_ports` the east
    /// port is not free and the cell is blocked until that buffer is empty.
    #[test]
    fn free_ports_wait_for_empty_output_buffers() {
        use crate::beam::{SourceCoord, SourceId};
        use fixed::types::extra::U0;
        let n = 16;
        let src = Source::new(SourceId(0), [SourceCoord::from_num(7); 3]);
        let far = FarDistance::<U0>::new(n - 1).unwrap();
        let order = SplitOrder::default();
        let env = |free_ports| LightEnv { free_ports, ..thesis_env(&src, &order, far, n) };
        let store = Cell::<8>::new(7, 7);
        let up = BeamMsg::new(Beam::<U0>::initial(&src, Direction::PosZ, far), 7);
        let cell = |free_ports| {
            let mut c = LightCell::<U0, 8, 3, 8>::new(7, 7);
            c.accept(up, false, &Activity::new()).unwrap();
            c.out.push_back(Port::E, up).unwrap();
            let first = c.step(&store, &env(free_ports), &Activity::new());
            (first, c)
        };
        let (step, c) = cell(false);
        assert_eq!(step, Step::Processed);
        assert!(Port::ALL.iter().all(|&p| c.out.len(p) == 1 + usize::from(p == Port::E)));
        let (step, mut c) = cell(true);
        assert_eq!(step, Step::Blocked);
        c.out.pop_front(Port::E);
        assert_eq!(c.step(&store, &env(true), &Activity::new()), Step::Processed);
    }

    /// Among waiting beams of one layer, the wavefront takes the oldest and radial the one
    /// nearest the source's axis (|z − z_s|), whatever their arrival order; both take a smaller
    /// layer first. Checked on every pair of the +x beam's layer-2 sub-beams in one column.
    #[test]
    fn radial_takes_the_beam_nearest_the_axis() {
        use crate::beam::{SourceCoord, SourceId};
        use fixed::types::extra::U0;
        let n = 16;
        let c = |v: f64| SourceCoord::from_num(v);
        let src = Source::new(SourceId(0), [c(7.0), c(7.0), c(7.25)]);
        let far = FarDistance::<U0>::new(n - 1).unwrap();
        let order = SplitOrder::default();
        let env = |policy| LightEnv { policy, fa: 8, ..thesis_env(&src, &order, far, n) };
        let store = Cell::<8>::new(0, 0);
        let sv = src.voxel();
        let px = Direction::PosX;
        // Every sub-beam of layers 1 and 2 that lands in column (x_s + 2, y_s), by voxel z.
        let mut layer2: std::vec::Vec<BeamMsg<U0>> = std::vec::Vec::new();
        let mut layer1: std::vec::Vec<BeamMsg<U0>> = std::vec::Vec::new();
        for s1 in Beam::<U0>::initial(&src, px, far).split(&src, far, px.transverse_of(sv)).unwrap() {
            let d1 = px.displacement(s1.offset);
            let v1 = [sv[0] + d1[0] as i32, sv[1] + d1[1] as i32, sv[2] + d1[2] as i32];
            if (v1[0], v1[1]) == (sv[0] + 1, sv[1]) {
                layer1.push(BeamMsg::new(s1.beam, v1[2] as u16));
            }
            for s2 in s1.beam.split(&src, far, px.transverse_of(v1)).unwrap() {
                let d2 = px.displacement(s2.offset);
                let v2 = [v1[0] + d2[0] as i32, v1[1] + d2[1] as i32, v1[2] + d2[2] as i32];
                if (v2[0], v2[1]) == (sv[0] + 2, sv[1]) {
                    layer2.push(BeamMsg::new(s2.beam, v2[2] as u16));
                }
            }
        }
        let axis = |m: &BeamMsg<U0>| (m.z as f64 - 7.25).abs();
        assert!(layer2.iter().any(|m| axis(m) != axis(&layer2[0])), "pieces at several distances");
        let first = |policy, msgs: &[BeamMsg<U0>]| {
            let mut cell = LightCell::<U0, 8, 3, 8>::new(sv[0] as u16 + 2, sv[1] as u16);
            for &m in msgs {
                cell.accept(m, false, &Activity::new()).unwrap();
            }
            assert_eq!(cell.step(&store, &env(policy), &Activity::new()), Step::Processed);
            cell.last_z
        };
        let mut pairs = 0;
        for a in &layer2 {
            for b in &layer2 {
                if axis(a) == axis(b) {
                    continue;
                }
                pairs += 1;
                let near = if axis(a) < axis(b) { a.z } else { b.z };
                assert_eq!(first(Policy::Wavefront, &[*a, *b]), a.z, "oldest first");
                assert_eq!(first(Policy::Radial, &[*a, *b]), near, "nearest the axis first");
                // A smaller layer goes first under both, however far from the axis.
                for l1 in &layer1 {
                    assert_eq!(first(Policy::Radial, &[*a, *b, *l1]), l1.z);
                }
            }
        }
        assert!(pairs >= 2, "{pairs} pairs");
    }

    #[test]
    fn activity_counts_exactly() {
        let a = Activity::new();
        assert!(a.is_quiescent());
        a.add(6);
        for _ in 0..5 {
            a.consume();
        }
        assert!(!a.is_quiescent());
        a.consume();
        assert!(a.is_quiescent());
    }

    #[test]
    fn ports_round_trip() {
        for p in Port::ALL {
            let (dx, dy) = p.delta();
            assert_eq!(Port::from_delta(dx, dy), Some(p));
        }
        assert_eq!(Port::from_delta(0, 0), None);
        // Exhaustively: a port exactly for the eight unit steps.
        for dx in i8::MIN..=i8::MAX {
            for dy in i8::MIN..=i8::MAX {
                let want = Port::ALL.into_iter().find(|p| p.delta() == (dx, dy));
                assert_eq!(Port::from_delta(dx, dy), want, "({dx}, {dy})");
            }
        }
    }
}
