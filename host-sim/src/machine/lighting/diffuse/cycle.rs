//! One source's diffusion cycle by cycle (the parent module's cycle model, thesis §4.4): the
//! phases of [`Run`] (emit, compute, links, pop, next active set) over the grid's cells, in
//! parallel pieces whose results are gathered in a fixed order, so that every count is the
//! same whatever the threads.

use anyhow::{bail, Result};
use cell_core::beam::{Beam, Direction, FarDistance, FracBits, Source};
use cell_core::light::{ActivityDelta, BeamMsg, LightEnv, OccupiedBox, Port, Step};
use cell_core::units::Coord;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicU8, Ordering::Relaxed};

use super::*;
use crate::machine::grid::capacity::HostLightCell;
use crate::machine::grid::pieces::{merge_sorted, par_map, prefetch, prefetch_ends, tiles, with_team, Team};
use crate::machine::grid::Grid;
use crate::machine::links::tap::Tap;
use crate::machine::links::{self, lossless, sure, CellInbox, HostLink, Took, BACK};

use super::offer::{Offer, Taken};
use super::tiles::{Edge, Halo};

/// Active cells per piece of work handed to a thread (below it, splitting costs more than it
/// saves).
const PIECE: usize = 64;

/// How many cells (or offers) ahead of the one being worked on the passes [`prefetch`]: about
/// one memory latency's worth of work (8 measured no better; 1 line or 7 lines of FIFO worse
/// than 4; without prefetching the Cornell n = 192 light phase takes ~20 % longer).
const AHEAD: usize = 4;

/// Prefetch what a pass reads first of a cell: the blocked-step key and output lengths (first
/// line), the FIFO length and the counters, and `fifo_lines` lines of FIFO slots (see the field
/// order of [`LightCell`]): 4 for a step, 1 for a delivery (merge scan), 0 for pops.
fn prefetch_cell<F: FracBits>(c: &HostLightCell<F>, fifo_lines: usize) {
    prefetch(c);
    prefetch(&c.counters);
    let f = c.fifo.as_ptr().cast::<u8>();
    for line in 0..fifo_lines {
        prefetch(f.wrapping_add(64 * line));
    }
}

/// What a piece of the compute phase reports: its beam-count change, whether a beam was
/// processed, (when visits are recorded) the cells and depths processed, (when cells are
/// traced) every cell's step result, and the link offers of its cells; and what a piece of the
/// link phase reports (`delta`, `any`, `taken`, `woke`, `roused`, `took`).
///
/// One per piece lives for the whole diffusion and is cleared, not dropped, each cycle: lists
/// allocated afresh every cycle went back to the kernel when the allocator trimmed its heap,
/// and were faulted in again (~160 k page faults in `light cornell --n 256`).
#[derive(Default)]
struct PieceResult<F: FracBits> {
    delta: i64,
    /// Compute phase: a beam was processed or held; link phase: a beam was delivered or
    /// acknowledged.
    any: bool,
    seen: Vec<(usize, u16)>,
    steps: Vec<(usize, Step)>,
    /// Its cells' offers, one list per port (each in sender order, so in receiver order).
    offers: [Vec<Offer<F>>; 8],
    /// Cells left with nothing to do by their step (empty FIFO, empty output buffers).
    quiet: Vec<u32>,
    /// Held cells with empty output buffers, and their [`LightCell::held_wait`]: nothing
    /// changes for them until that many cycles pass or a beam arrives.
    sleep: Vec<(u32, u16)>,
    /// Cells that the last cycle's deferred pops left with nothing (counted busy last cycle).
    drained: u64,
    /// Link phase: cells that received a beam and were not yet in the active list.
    woke: Vec<u32>,
    /// Link phase: the piece's offers in link order ([`link_order`]).
    order: Vec<(u8, u32)>,
    /// Link phase: beams delivered, and sleeping cells a delivery woke.
    taken: u64,
    roused: usize,
    /// Link phase: the journal of the piece's links (beams taken, in link order; only
    /// recording links write it).
    took: Vec<Took<F>>,
}

impl<F: FracBits> PieceResult<F> {
    /// Empty, keeping the lists' room.
    fn clear(&mut self) {
        self.delta = 0;
        self.any = false;
        self.seen.clear();
        self.steps.clear();
        self.offers.iter_mut().for_each(Vec::clear);
        self.quiet.clear();
        self.sleep.clear();
        self.drained = 0;
        self.woke.clear();
        self.order.clear();
        self.taken = 0;
        self.roused = 0;
        self.took.clear();
    }
}

/// `scratch` grown to at least `len` results, the first `len` cleared.
fn scratch_for<F: FracBits>(scratch: &mut Vec<PieceResult<F>>, len: usize) -> &mut [PieceResult<F>] {
    if scratch.len() < len {
        scratch.resize_with(len, PieceResult::default);
    }
    let s = &mut scratch[..len];
    s.iter_mut().for_each(PieceResult::clear);
    s
}

/// The offers of `lists` (list p: the offers on port p, in increasing receiver order) in link
/// order, as (port, index) into `order`: by receiver, then arbitration key, then sender — the
/// order a sort of all offers by (receiver, key, sender) gives, by an 8-way merge. A receiver
/// has at most one offer per port (from its neighbour on that side), so its offers are the
/// lists' heads with the smallest receiver; most receivers have one.
fn link_order<F: FracBits>(lists: &[&mut [Offer<F>]; 8], order: &mut Vec<(u8, u32)>) {
    order.clear();
    // Receiver of each list's head; `u32::MAX` once a list is done (no cell has that index:
    // the grid is checked to fit memory long before 2^32 cells).
    let next_to = |l: &[Offer<F>], h: usize| l.get(h).map_or(u32::MAX, |o| o.to);
    let mut head = [0usize; 8];
    let mut next: [u32; 8] = std::array::from_fn(|p| next_to(&lists[p][..], 0));
    loop {
        let to = next.iter().fold(u32::MAX, |m, &t| m.min(t));
        if to == u32::MAX {
            return;
        }
        let mut mask = 0u8;
        for (p, &t) in next.iter().enumerate() {
            mask |= u8::from(t == to) << p;
        }
        if mask.is_power_of_two() {
            let p = mask.trailing_zeros() as usize;
            order.push((p as u8, head[p] as u32));
            head[p] += 1;
            next[p] = next_to(&lists[p][..], head[p]);
            continue;
        }
        // Several offers to one receiver: by (key, sender), ordered by insertion (at most 8).
        let mut group = [(0u32, 0u32, 0usize); 8];
        let mut g = 0;
        for p in Port::each(mask).map(Port::index) {
            let o = &lists[p][head[p]];
            let mut at = g;
            while at > 0 && (group[at - 1].0, group[at - 1].1) > (o.key, o.from) {
                group[at] = group[at - 1];
                at -= 1;
            }
            group[at] = (o.key, o.from, p);
            g += 1;
        }
        for &(_, _, p) in &group[..g] {
            order.push((p as u8, head[p] as u32));
            head[p] += 1;
            next[p] = next_to(&lists[p][..], head[p]);
        }
    }
}

/// The offers of every list, whole, for [`link_order`].
fn whole<F: FracBits>(offers: &mut [Vec<Offer<F>>; 8]) -> [&mut [Offer<F>]; 8] {
    offers.each_mut().map(Vec::as_mut_slice)
}

/// A piece of the link phase: its receiving cells, the index of the first, their offers per
/// port, and their links (by receiving end, [`GridLinks`]).
type LinkPiece<'a, T, F, L> = (&'a mut [T], usize, [&'a mut [Offer<F>]; 8], &'a mut [L]);

/// Cut `cells` (the cells from index `origin` on), their links (8 per cell, by receiving end)
/// and the per-port offer lists (to those cells only) together at the receiver indices `cuts`
/// (increasing), pieces without offers left out. Every offer of a receiver lands in the piece
/// that owns the receiver and its links.
fn by_receiver<'a, T, F: FracBits, L>(
    mut cells: &'a mut [T],
    origin: usize,
    mut links: &'a mut [L],
    offers: &'a mut [Vec<Offer<F>>; 8],
    cuts: &[u32],
) -> Vec<LinkPiece<'a, T, F, L>> {
    let mut rest = whole(offers);
    let mut out = Vec::with_capacity(cuts.len() + 1);
    let (mut base, total) = (origin, origin + cells.len());
    for end in cuts.iter().map(|&c| c as usize).chain([total]) {
        let end = end.clamp(base, total);
        let lists: [&'a mut [Offer<F>]; 8] = std::array::from_fn(|p| {
            let l = std::mem::take(&mut rest[p]);
            let (mine, later) = l.split_at_mut(l.partition_point(|o| (o.to as usize) < end));
            rest[p] = later;
            mine
        });
        let (tile, tail) = std::mem::take(&mut cells).split_at_mut(end - base);
        let (tile_links, links_tail) = std::mem::take(&mut links).split_at_mut((end - base) * 8);
        if lists.iter().any(|l| !l.is_empty()) {
            out.push((tile, base, lists, tile_links));
        }
        cells = tail;
        links = links_tail;
        base = end;
    }
    out
}

/// One message taken on port `p`, as a [`Taken`] increment.
const fn taken_one(p: u8) -> u32 {
    1 << (4 * p)
}

/// The (port, count) pairs of a [`Taken`] value with a nonzero count, in port order.
fn taken_counts(t: u32) -> impl Iterator<Item = (Port, u32)> {
    let mut rest = t;
    std::iter::from_fn(move || {
        (rest != 0).then(|| {
            let p = rest.trailing_zeros() / 4;
            rest &= !(15 << (4 * p));
            (Port::ALL[p as usize], t >> (4 * p) & 15)
        })
    })
}

/// The ports with a nonzero count in a [`Taken`] value.
fn taken_mask(t: u32) -> u8 {
    taken_counts(t).fold(0, |m, (p, _)| m | 1 << p.index())
}

/// Drop the messages of cell `i` whose offers were taken (its `taken` counts, then cleared);
/// whether there were any.
fn pop_taken<F: FracBits>(c: &mut HostLightCell<F>, i: usize, taken: &[Taken]) -> bool {
    let counts = taken[i].load(Relaxed);
    if counts == 0 {
        return false;
    }
    taken[i].store(0, Relaxed);
    for (p, k) in taken_counts(counts) {
        for _ in 0..k {
            c.out.pop_front(p);
        }
    }
    true
}

/// Mark the heads of cell `i` that went on the wire this cycle and were not acknowledged (its
/// `unacked` bits, then cleared), and unmark those acknowledged (its `taken` bits): a head on
/// the wire is not merged into ([`LightCell::head_in_flight`]).
fn mark_in_flight<F: FracBits>(c: &mut HostLightCell<F>, i: usize, taken: &[Taken], unacked: &[AtomicU8]) {
    let u = unacked[i].load(Relaxed);
    if u != 0 {
        unacked[i].store(0, Relaxed);
    }
    c.head_in_flight = (c.head_in_flight & !taken_mask(taken[i].load(Relaxed))) | u;
}

/// Not a sleeper (see [`Sleepers::asleep`]).
const AWAKE: u64 = u64::MAX;

/// One source's diffusion: the cycle loop over the phases of [`Run`].
#[allow(clippy::too_many_arguments)]
pub(super) fn diffuse_one<F: FracBits, const D: usize, L: HostLink<F>>(
    grid: &Grid<D>,
    cells: &mut [HostLightCell<F>],
    links: &mut [L],
    src: (&Source, Option<&[Beam<F>]>),
    si: usize,
    env: &LightEnv<'_, F>,
    cfg: &LightConfig,
    dead: Option<OccupiedBox>,
    rec: Recording<'_>,
    tile: Option<&mut dyn Halo>,
    phases: &mut PhaseSeconds,
    progress: &mut dyn FnMut(u64),
) -> Result<SourceReport> {
    // The seam borrowed for as long as the run's other borrows (`&mut` is invariant).
    let tile = tile.map(|h| h as &mut dyn Halo);
    let mut run = Run::new(grid, cells, links, src, si, env, cfg, dead, rec, tile);
    with_team(|team| {
        let mut lap = Lap::start();
        while run.running() && cfg.stop_at.is_none_or(|t| run.cycle < t) {
            let mut moved = run.emit();
            lap.lap(&mut phases.emit);
            let pieces = run.step(team);
            lap.lap(&mut phases.step);
            moved |= run.gather_steps(pieces);
            lap.lap(&mut phases.gather);
            run.cross_offers()?;
            moved |= run.links(team);
            run.cross_answers()?;
            lap.lap(&mut phases.links);
            run.pop(team);
            lap.lap(&mut phases.pop);
            run.cycle += 1;
            let busy_now = run.next_active();
            run.settle(busy_now, moved)?;
            lap.lap(&mut phases.next);
            if run.cycle % 256 == 0 {
                progress(run.cycle);
            }
        }
        progress(run.cycle);
        run.finish()
    })
}

/// The six initial beams of `src` that the dead-direction skip keeps, their rays counted in
/// `rep` (the skipped ones as skipped); or a radiosity shot's own initial beams (`shot`).
pub(crate) fn initial_beams<F: FracBits>(
    src: &Source,
    far: FarDistance<F>,
    dead: Option<OccupiedBox>,
    shot: Option<&[Beam<F>]>,
    order: [Direction; 6],
    rep: &mut SourceReport,
) -> Vec<Beam<F>> {
    if let Some(beams) = shot {
        rep.counts.rays_emitted += beams.iter().map(|b| b.ray_count() as u128).sum::<u128>();
        return beams.to_vec();
    }
    let sv = src.voxel();
    let mut initial = Vec::new();
    for d in order {
        let b = Beam::initial(src, d, far);
        rep.counts.rays_emitted += b.ray_count() as u128;
        if dead.is_some_and(|bx| bx.receding(d, sv, sv.map(i64::from))) {
            rep.counts.rays_skipped += b.ray_count() as u128;
        } else {
            initial.push(b);
        }
    }
    initial
}

/// The state of one source's diffusion from cycle to cycle, and its phases (the module doc's
/// cycle model). Per-cell flags and counters that the parallel pieces of a phase write, each
/// index from one piece only, are relaxed atomics: plain loads and stores, and the phase's join
/// orders them.
struct Run<'a, 'e, F: FracBits, const D: usize, L> {
    grid: &'a Grid<D>,
    /// The cells this run steps: the whole grid, or a tile's band alone (from cell `origin`).
    cells: &'a mut [HostLightCell<F>],
    /// The index of `cells[0]` in the grid: 0, or the first cell of the tile's band.
    origin: usize,
    /// Their links, by receiving end ([`GridLinks`]).
    links: &'a mut [L],
    env: &'a LightEnv<'e, F>,
    stepping: Stepping,
    visited: Option<&'a mut [bool]>,
    tap: Option<&'a mut Tap>,
    si: usize,
    /// The source's voxel and its cell.
    sv: [i32; 3],
    s_idx: usize,
    /// Beams in flight in the whole grid at the end of the last cycle (the machine's global
    /// activity counter, [`cell_core::light::Activity`]), and this cycle's change so far in this tile.
    in_flight: u64,
    flow: i64,
    /// Cells whose deferred pops left them idle this cycle (see `defer_pops`).
    drained: u64,
    /// The other tiles of a grid cut into tiles ([`Edge`]); `None`: the whole grid is here.
    edge: Option<Edge<'a>>,
    rep: SourceReport,
    /// The initial beams the emitter has not handed over yet.
    pending: std::vec::IntoIter<Beam<F>>,
    next_initial: Option<Beam<F>>,
    /// Every cell (all-cells stepping), or the cells holding beams, in row-major order.
    all: Vec<u32>,
    active: Vec<u32>,
    /// The cell is (or, during a cycle, will be) in the active list.
    in_active: Vec<AtomicBool>,
    /// Messages the receivers took this cycle, per sender, a [`Taken`] count per port (set by
    /// the receivers' pieces, consumed by the senders' pieces); and (links that may not
    /// acknowledge at once) ports whose offer went on the wire unacknowledged.
    taken_ports: Vec<Taken>,
    unacked_ports: Vec<AtomicU8>,
    /// The links acknowledge every delivery at once ([`cell_core::link::Link::LOSSLESS`]).
    lossless: bool,
    /// Deferred pops: a sender drops what was taken at the start of its next step, when the
    /// compute pass has the cell in cache anyway, instead of in a pass of its own over every
    /// sender (a third walk over scattered cells per cycle). Exact: between the link phase and
    /// its next step a sender is touched only by deliveries into its FIFO (and by the emitter,
    /// whose cell's pops are not deferred), which neither read nor change output buffers.
    /// Every sender is in the next active list (its output was busy). The busy count a cycle
    /// reports (`peak_active_cells`) is settled one cycle late: the cells the pops left idle
    /// are subtracted then. The reference modes (all cells, links that acknowledge later) pop
    /// in a pass.
    defer_pops: bool,
    /// Cells counted busy at the end of the last cycle, pending its deferred pops.
    pending_busy: Option<u64>,
    offers: [Vec<Offer<F>>; 8],
    /// Where the compute pieces started (cell indices): the link phase cuts the receivers
    /// there too.
    cuts: Vec<u32>,
    /// Per-piece results, kept from cycle to cycle (see `PieceResult`).
    scratch: Vec<PieceResult<F>>,
    /// Messages delivered per link, by receiving end ([`links::slot`]).
    link_load: Vec<AtomicU32>,
    woken: Vec<u32>,
    merged: Vec<u32>,
    cycle: u64,
    sleepers: Sleepers,
    /// With links that acknowledge later a message can sit in an output buffer, already
    /// delivered, waiting for its acknowledgement after the last beam was consumed: run until
    /// the buffers are empty.
    unacked: bool,
    /// Cycles in a row in which no beam was processed, delivered or acknowledged.
    stalled: u64,
    stall_limit: u64,
    /// [`Timing::burst`], and [`Timing::link_rate`] (messages offered per output buffer).
    burst: bool,
    link_rate: usize,
}

/// Held cells the host does not visit until their sibling wait ends or a beam arrives (exact:
/// [`LightCell::skip_held`] gives them the steps they missed). Not while tracing (a trace
/// records every step), not over links that acknowledge later.
struct Sleepers {
    /// Cells may sleep.
    on: bool,
    /// Per cell: the cycle it fell asleep ([`AWAKE`]: it did not).
    asleep: Vec<AtomicU64>,
    /// Per cycle modulo `hold + 1`: the sleepers whose wait ends then.
    alarms: Vec<Vec<(u32, u64)>>,
    /// Cells asleep.
    count: usize,
}

impl Sleepers {
    /// None asleep among `cells` cells (which may sleep if `on`), sibling wait `hold`.
    fn new(on: bool, cells: usize, hold: u16) -> Self {
        Sleepers {
            on,
            asleep: (0..if on { cells } else { 0 }).map(|_| AtomicU64::new(AWAKE)).collect(),
            alarms: (0..hold as usize + 1).map(|_| Vec::new()).collect(),
            count: 0,
        }
    }
}

/// Per-cell flags, `len` of them or none.
fn flags<T: Default>(on: bool, len: usize) -> Vec<T> {
    (0..if on { len } else { 0 }).map(|_| T::default()).collect()
}

impl<'a, 'e, F: FracBits, const D: usize, L: HostLink<F>> Run<'a, 'e, F, D, L> {
    #[allow(clippy::too_many_arguments)]
    fn new(
        grid: &'a Grid<D>,
        cells: &'a mut [HostLightCell<F>],
        links: &'a mut [L],
        (src, shot): (&Source, Option<&[Beam<F>]>),
        si: usize,
        env: &'a LightEnv<'e, F>,
        cfg: &LightConfig,
        dead: Option<OccupiedBox>,
        rec: Recording<'a>,
        tile: Option<&'a mut dyn Halo>,
    ) -> Self {
        let (n, stepping) = (grid.n as usize, cfg.stepping);
        // Per-cell flags are the whole grid's: indexed by cell, as offers and answers are.
        let len = n * n;
        let sv = src.voxel();
        let s_idx = sv[1] as usize * n + sv[0] as usize;
        let mut rep = SourceReport { source: si, ..Default::default() };
        let mut initial = initial_beams(src, env.far, dead, shot, cfg.timing.emission.order(), &mut rep);
        // Every tile counts the initial beams in flight; the source cell's tile emits them.
        let in_flight = initial.len() as u64;
        let edge = tile.map(|h| Edge::new(h, grid.n));
        let emitter = edge.as_ref().is_none_or(|e| e.owns(s_idx as u32));
        if !emitter {
            initial.clear();
            rep.counts.rays_emitted = 0;
            rep.counts.rays_skipped = 0;
        }
        let mut pending = initial.into_iter();
        let next_initial = pending.next();
        let active_stepping = stepping == Stepping::Active;
        let in_active: Vec<AtomicBool> = flags(active_stepping, len);
        if active_stepping && emitter {
            in_active[s_idx].store(true, Relaxed);
        }
        let mine = edge.as_ref().map_or(0..len as u32, Edge::cells);
        assert!(
            cells.len() == mine.len() && links.len() == 8 * cells.len(),
            "a run's cells and links are its tile's ({} cells, {} links for cells {mine:?})",
            cells.len(),
            links.len()
        );
        let origin = mine.start as usize;
        let lossless = lossless::<F, L>();
        let may_sleep = active_stepping && rec.tap.is_none() && lossless && env.hold > 0;
        Run {
            grid,
            cells,
            origin,
            links,
            env,
            stepping,
            visited: rec.visited,
            tap: rec.tap,
            si,
            sv,
            s_idx,
            in_flight,
            flow: 0,
            drained: 0,
            edge,
            rep,
            pending,
            next_initial,
            all: if active_stepping { Vec::new() } else { mine.collect() },
            active: if emitter { vec![s_idx as u32] } else { Vec::new() },
            in_active,
            taken_ports: flags(true, len),
            unacked_ports: flags(!lossless, len),
            lossless,
            defer_pops: active_stepping && lossless,
            pending_busy: None,
            offers: Default::default(),
            cuts: Vec::new(),
            scratch: Vec::new(),
            link_load: flags(true, len * 8),
            woken: Vec::new(),
            merged: Vec::new(),
            cycle: 0,
            sleepers: Sleepers::new(may_sleep, len, env.hold),
            unacked: false,
            stalled: 0,
            stall_limit: cfg.stall_cycles.max(1),
            burst: cfg.timing.burst,
            link_rate: cfg.timing.link_rate as usize,
        }
    }

    /// Beams are in flight (or messages wait for their acknowledgement).
    fn running(&self) -> bool {
        self.in_flight > 0 || self.unacked
    }

    /// 1. The source emitter hands the next initial beam to the source cell if its FIFO has
    ///    room (under [`Timing::burst`], every one it has room for); whether it did.
    fn emit(&mut self) -> bool {
        let mut moved = false;
        while self.emit_one() {
            moved = true;
            if !self.burst {
                break;
            }
        }
        moved
    }

    /// Hand the next initial beam to the source cell if its FIFO has room; whether it did.
    fn emit_one(&mut self) -> bool {
        let Some(b) = self.next_initial else { return false };
        let s_idx = self.s_idx;
        let s = s_idx - self.origin;
        if !self.cells[s].can_accept_initial(self.env.fa, self.env.source) {
            return false;
        }
        let msg = BeamMsg::new(b, self.sv[2] as u16);
        if let Some(r) = self.tap.as_deref_mut().and_then(|t| t.get(s_idx)) {
            r.inject(&msg);
        }
        let delta = ActivityDelta::new();
        let taken = self.cells[s].accept(msg, self.env.merge, &delta).is_ok();
        self.flow += delta.get();
        if taken {
            self.next_initial = self.pending.next();
        }
        taken
    }

    /// 2. Compute: every visited cell steps on its own state and its own dexels, in parallel
    ///    over pieces of the (row-major) visit list; each piece counts beams in a local delta.
    ///    A cell's output buffers change only in its own step, so the piece also gathers its
    ///    cells' link offers (the message at the front of each busy output buffer) while the
    ///    cell is in cache: the same offers, in the same order, as a pass after all steps.
    ///    The number of pieces, whose results [`Run::gather_steps`] takes next.
    fn step(&mut self, team: &Team<'_>) -> usize {
        let k = StepCtx {
            grid: self.grid,
            env: self.env,
            taken_ports: &self.taken_ports,
            defer_pops: self.defer_pops,
            tapping: self.tap.is_some(),
            record: self.visited.is_some(),
            may_sleep: self.sleepers.on,
            s_idx: self.s_idx,
            emitting: self.next_initial.is_some(),
            n: self.grid.n as usize,
            wave: self.env.policy.by_layer(),
            link_rate: self.link_rate,
            reads_dexels: !self.env.rule.needs_triangles() || !self.env.lit_visible_only,
        };
        let visit = if self.stepping == Stepping::AllCells { &self.all } else { &self.active };
        let pieces = tiles(self.cells, self.origin, visit, PIECE);
        self.cuts.clear();
        self.cuts.extend(pieces.iter().skip(1).map(|&(_, base, _)| base as u32));
        let count = pieces.len();
        let done = scratch_for(&mut self.scratch, count);
        team.each(pieces.into_iter().zip(done.iter_mut()).collect(), |((tile, base, idx), r)| {
            k.step_piece(tile, base, idx, r);
        });
        count
    }

    /// The compute pieces' results, in piece order: offers, idle and sleeping cells, beam
    /// counts, trace steps, visits. Whether a beam was processed (or held).
    fn gather_steps(&mut self, count: usize) -> bool {
        self.offers.iter_mut().for_each(Vec::clear);
        let done = &self.scratch[..count];
        self.drained = done.iter().map(|r| r.drained).sum();
        let (cycle, ring, depth) = (self.cycle, self.sleepers.alarms.len(), self.grid.depth as usize);
        let mut moved = false;
        for PieceResult { delta, any, seen, steps, offers: o, quiet, sleep, .. } in done.iter() {
            for (all, mine) in self.offers.iter_mut().zip(o) {
                all.extend_from_slice(mine);
            }
            if self.stepping == Stepping::Active {
                // Marked idle now; a quiet cell that receives below is marked busy again.
                for &q in quiet {
                    self.in_active[q as usize].store(false, Relaxed);
                }
                // Sleepers too, until their wait ends (or a beam arrives, below).
                for &(q, w) in sleep {
                    self.in_active[q as usize].store(false, Relaxed);
                    self.sleepers.asleep[q as usize].store(cycle, Relaxed);
                    self.sleepers.alarms[(cycle + w as u64) as usize % ring].push((q, cycle));
                    self.sleepers.count += 1;
                }
            }
            self.flow += *delta;
            moved |= *any;
            if let Some(t) = self.tap.as_deref_mut() {
                for &(i, step) in steps {
                    if let Some(r) = t.get(i) {
                        r.step(step);
                    }
                }
            }
            if let Some(v) = self.visited.as_deref_mut() {
                for &(i, z) in seen {
                    v[i * depth + z as usize] = true;
                }
            }
        }
        moved
    }

    /// 3. Links. Under the wavefront policy the oldest messages (smallest layer) claim FIFO
    ///    credits first; under the thesis's, senders in row-major order. A (sender, port)
    ///    feeds one receiver, and receivers interact only through their own FIFO (and their
    ///    own links), so each receiver pulls its offers in (key, sender) order — the same
    ///    outcome as one global pass in (key, row-major sender) order — in parallel. Each
    ///    port's offers are in receiver order already (a port's receiver is its sender plus a
    ///    constant): the lists are merged ([`link_order`]), not sorted. Every offer goes
    ///    through its link ([`HostLink`]); whether a beam was delivered or acknowledged.
    fn links(&mut self, team: &Team<'_>) -> bool {
        let k = PullCtx {
            env: self.env,
            cycle: self.cycle,
            stepping: self.stepping,
            may_sleep: self.sleepers.on,
            lossless: self.lossless,
            taken_ports: &self.taken_ports,
            unacked_ports: &self.unacked_ports,
            in_active: &self.in_active,
            asleep: &self.sleepers.asleep,
            link_load: &self.link_load,
        };
        let groups = by_receiver(self.cells, self.origin, self.links, &mut self.offers, &self.cuts);
        let count = groups.len();
        let pulled = scratch_for(&mut self.scratch, count);
        team.each(groups.into_iter().zip(pulled.iter_mut()).collect(), |(piece, r)| k.pull_piece(piece, r));
        let mut moved = false;
        for r in &self.scratch[..count] {
            self.sleepers.count -= r.roused;
            self.flow += r.delta;
            self.rep.counts.messages += r.taken;
            moved |= r.any;
            self.woken.extend_from_slice(&r.woke);
            if let Some(t) = self.tap.as_deref_mut() {
                r.took.iter().for_each(|e| t.took(e));
            }
        }
        moved
    }

    /// Senders drop what was taken (and, over links that acknowledge later, mark what is on the
    /// wire): deferred to their next step (see `defer_pops`) but for the emitting cell, whose
    /// room the emitter checks first; otherwise in parallel over the visited cells (every
    /// sender is one). A cell's last pop leaves its flag right (receptions came before the
    /// pops).
    fn pop(&mut self, team: &Team<'_>) {
        let (taken, unacked, in_active) = (&self.taken_ports, &self.unacked_ports, &self.in_active);
        if self.defer_pops {
            // The emitting cell: this tile's (a tile that does not hold it emits nothing).
            if let Some(c) = self.s_idx.checked_sub(self.origin).and_then(|s| self.cells.get_mut(s)) {
                if pop_taken(c, self.s_idx, taken) {
                    in_active[self.s_idx].store(c.busy(), Relaxed);
                }
            }
            return;
        }
        let (lossless, stepping) = (self.lossless, self.stepping);
        let visit = if stepping == Stepping::AllCells { &self.all } else { &self.active };
        team.each(tiles(self.cells, self.origin, visit, PIECE), |(tile, base, idx)| {
            for (k, &i) in idx.iter().enumerate() {
                if let Some(&j) = idx.get(k + AHEAD) {
                    prefetch_cell(&tile[j as usize - base], 0);
                }
                let i = i as usize;
                let c = &mut tile[i - base];
                if !lossless {
                    mark_in_flight(c, i, taken, unacked);
                }
                if pop_taken(c, i, taken) && stepping == Stepping::Active {
                    in_active[i].store(c.busy(), Relaxed);
                }
            }
        });
    }

    /// The cells busy at the start of the next cycle (`cycle` is its number), and (active
    /// stepping) the next cycle's active list.
    fn next_active(&mut self) -> u64 {
        match self.stepping {
            Stepping::Active => self.next_active_list(),
            Stepping::AllCells => {
                let chunks: Vec<&[HostLightCell<F>]> = self.cells.chunks(64 * PIECE).collect();
                let per_chunk = par_map(chunks.len(), &|k| chunks[k].iter().filter(|c| c.busy()).count() as u64);
                let busy: u64 = per_chunk.iter().sum();
                // Initial beams are left only where the tile holds the source cell.
                busy + u64::from(self.next_initial.is_some() && !self.cells[self.s_idx - self.origin].busy())
            }
        }
    }

    /// Sleepers whose wait ends next cycle, and sleepers a beam reached, wake up: they are owed
    /// the held steps they were not given (cycles c0 + 1 ..= cycle). Next cycle's active set:
    /// busy cells, in row-major order. `in_active` now says which cells are busy without
    /// reading them: a cell is idle after the link phase if its step left it quiet and it
    /// received nothing, or its last pop drained it; every receiver holds a beam. (A quiet
    /// receiver can be in both lists: the merge keeps one.) Returns the busy count.
    fn next_active_list(&mut self) -> u64 {
        let (cycle, ring) = (self.cycle, self.sleepers.alarms.len());
        let due = std::mem::take(&mut self.sleepers.alarms[(cycle as usize) % ring]);
        for (q, c0) in due {
            if self.sleepers.asleep[q as usize].load(Relaxed) == c0 {
                self.cells[q as usize - self.origin].skip_held((cycle - 1 - c0) as u16);
                self.sleepers.asleep[q as usize].store(AWAKE, Relaxed);
                self.sleepers.count -= 1;
                let was = self.in_active[q as usize].swap(true, Relaxed);
                debug_assert!(!was);
                self.woken.push(q);
            }
        }
        let in_active = &self.in_active;
        self.active.retain(|&i| in_active[i as usize].load(Relaxed));
        debug_assert!(self.woken.iter().all(|&j| self.cells[j as usize - self.origin].busy()));
        self.woken.sort_unstable();
        merge_sorted(&mut self.active, &self.woken, &mut self.merged);
        self.woken.clear();
        debug_assert!(self
            .active
            .iter()
            .all(|&i| self.cells[i as usize - self.origin].busy() || self.taken_ports[i as usize].load(Relaxed) != 0));
        if self.next_initial.is_some() && !self.in_active[self.s_idx].swap(true, Relaxed) {
            self.active.push(self.s_idx as u32);
            self.active.sort_unstable();
        }
        self.active.len() as u64 + self.sleepers.count as u64
    }

    /// The end of a cycle: the busy count (settled next cycle under deferred pops), whether
    /// acknowledgements are awaited, and the stall detector.
    /// Over a grid cut into tiles, every tile settles the machine-wide figures: the beams in
    /// flight, the busy and drained cells, progress and sleepers are sums over the tiles.
    fn settle(&mut self, busy_now: u64, moved: bool) -> Result<()> {
        let mut t = [self.flow, busy_now as i64, self.drained as i64, i64::from(moved), self.sleepers.count as i64];
        if let Some(e) = self.edge.as_mut() {
            e.sum(&mut t)?;
        }
        let [flow, busy_now, drained, moved, sleeping] = t;
        let (busy_now, drained) = (busy_now as u64, drained as u64);
        self.in_flight = self.in_flight.saturating_add_signed(flow);
        self.flow = 0;
        self.drained = 0;
        let peak = &mut self.rep.counts.peak_active_cells;
        // The busy count of the last cycle, less the cells its deferred pops left idle.
        if let Some(b) = self.pending_busy.take() {
            *peak = (*peak).max(b - drained);
        }
        if self.defer_pops {
            self.pending_busy = Some(busy_now);
        } else {
            *peak = (*peak).max(busy_now);
        }
        self.unacked = !self.lossless && busy_now > 0;
        // A sleeping cell's wait ends by itself: not a stall.
        self.stalled = if moved != 0 || sleeping > 0 { 0 } else { self.stalled + 1 };
        if self.stalled >= self.stall_limit {
            let blocked: Vec<String> = self
                .cells
                .iter()
                .filter(|c| c.busy())
                .take(8)
                .map(|c| format!("({}, {}) fifo {} out {:?}", c.x, c.y, c.fifo.len(), Port::ALL.map(|p| c.out.len(p))))
                .collect();
            bail!(
                "stall at cycle {} of source {}: no progress for {} cycle(s) with {} beams in flight \
                 (deadlock or dead link; --stall-cycles {}); blocked cells (fifo, output buffers): {}",
                self.cycle,
                self.si,
                self.stalled,
                self.in_flight,
                self.stall_limit,
                blocked.join("; ")
            );
        }
        Ok(())
    }

    /// The last cycle's deferred pops and busy count; the cycle count and the busiest link
    /// (over a grid cut into tiles, the whole grid's: every tile ends in the same cycle).
    fn finish(mut self) -> Result<SourceReport> {
        if self.defer_pops {
            let mut drained = 0;
            for &i in &self.active {
                let c = &mut self.cells[i as usize - self.origin];
                if pop_taken(c, i as usize, &self.taken_ports) && !c.busy() {
                    drained += 1;
                }
            }
            let mut t = [drained];
            if let Some(e) = self.edge.as_mut() {
                e.sum(&mut t)?;
            }
            if let Some(b) = self.pending_busy {
                self.rep.counts.peak_active_cells = self.rep.counts.peak_active_cells.max(b - t[0] as u64);
            }
        }
        debug_assert!(
            self.running()
                || self.cells.iter().all(|c| !c.busy()) && self.taken_ports.iter().all(|t| t.load(Relaxed) == 0)
        );
        self.rep.counts.cycles = self.cycle;
        let n = self.grid.n as usize;
        let mut busiest = busiest_link(n, &self.link_load);
        if let Some(e) = self.edge.as_mut() {
            busiest = e.busiest(busiest)?;
        }
        if let Some((i, load)) = busiest {
            let (x, y) = ((i / 8) % n, (i / 8) / n);
            self.rep.counts.peak_link_load = load as u64;
            self.rep.counts.peak_link_distance =
                (x.abs_diff(self.sv[0] as usize)).max(y.abs_diff(self.sv[1] as usize)) as u32;
        }
        Ok(self.rep)
    }

    /// Over a grid cut into tiles, after the compute phase: the offers to receivers in the
    /// tiles above and below go there, and theirs to this tile's receivers come in.
    fn cross_offers(&mut self) -> Result<()> {
        match self.edge.as_mut() {
            Some(e) => e.offers(&mut self.offers, self.env.far),
            None => Ok(()),
        }
    }

    /// Over a grid cut into tiles, after the link phase: what this tile's receivers took of
    /// the other tiles' senders (and, over links that acknowledge later, left unacknowledged)
    /// goes back to them, and theirs comes in, before any sender pops.
    fn cross_answers(&mut self) -> Result<()> {
        match self.edge.as_mut() {
            Some(e) => e.answers(&self.taken_ports, &self.unacked_ports, self.lossless),
            None => Ok(()),
        }
    }
}

/// The busiest link, as (sender · 8 + port, messages): the first in that order among the
/// busiest. `load` is by receiving end ([`links::slot`]); a port leading out of the grid
/// carried nothing.
fn busiest_link(n: usize, load: &[AtomicU32]) -> Option<(usize, u32)> {
    (0..n * n * 8)
        .map(|i| {
            let (x, y) = ((i / 8 % n) as i64, (i / 8 / n) as i64);
            let (dx, dy) = Port::ALL[i % 8].delta();
            let (tx, ty) = (x + dx as i64, y + dy as i64);
            let inside = (0..n as i64).contains(&tx) && (0..n as i64).contains(&ty);
            let to = (ty * n as i64 + tx) as u32;
            (i, if inside { load[links::slot(to, (i % 8) as u8)].load(Relaxed) } else { 0 })
        })
        .max_by_key(|&(i, l)| (l, std::cmp::Reverse(i)))
}

/// What every piece of the compute phase reads.
struct StepCtx<'a, 'e, F: FracBits, const D: usize> {
    grid: &'a Grid<D>,
    env: &'a LightEnv<'e, F>,
    taken_ports: &'a [Taken],
    defer_pops: bool,
    tapping: bool,
    record: bool,
    may_sleep: bool,
    s_idx: usize,
    emitting: bool,
    n: usize,
    wave: bool,
    /// Messages offered per output buffer ([`Timing::link_rate`]).
    link_rate: usize,
    /// A step may read the column's dexels (every rule but exact occluders with the
    /// visible-only lit store).
    reads_dexels: bool,
}

impl<F: FracBits, const D: usize> StepCtx<'_, '_, F, D> {
    /// Step the visited cells `idx` of one piece (`tile`, from cell `base`).
    fn step_piece(&self, tile: &mut [HostLightCell<F>], base: usize, idx: &[u32], r: &mut PieceResult<F>) {
        let delta = ActivityDelta::new();
        for (k, &i) in idx.iter().enumerate() {
            if let Some(&j) = idx.get(k + AHEAD) {
                self.prefetch(&tile[j as usize - base], j as usize);
            }
            let c = &mut tile[i as usize - base];
            if self.defer_pops && pop_taken(c, i as usize, self.taken_ports) && !c.busy() {
                r.drained += 1;
            }
            let step = c.step(&self.grid.cells[i as usize], self.env, &delta);
            self.note(c, i, step, r);
            for p in c.out.busy_ports() {
                let (dx, dy) = p.delta();
                let to = (i as i64 + dy as i64 * self.n as i64 + dx as i64) as u32;
                for m in c.out.waiting(p).iter().take(self.link_rate) {
                    let key = if self.wave { m.beam.layer().0 } else { 0 };
                    r.offers[p.index()].push(Offer { to, key, from: i, port: p.index() as u8, msg: *m });
                }
            }
        }
        r.delta = delta.get();
    }

    /// Prefetch what stepping cell `j` (`cj`) reads first.
    fn prefetch(&self, cj: &HostLightCell<F>, j: usize) {
        prefetch_cell(cj, 4);
        // Exact occluders with the visible-only lit store read the column's triangles and
        // target ray, not its dexels.
        if self.reads_dexels {
            prefetch_ends(&self.grid.cells[j].store);
        }
        if let Some(o) = self.env.occluders {
            // The column from its index, not from the cell's `x`, `y`: reading those would wait
            // for the very line `prefetch_cell` just asked for.
            o.prefetch((j % self.n) as Coord, (j / self.n) as Coord);
        }
        if self.defer_pops {
            // The buffers its pending pops will shift.
            let t = taken_mask(self.taken_ports[j].load(Relaxed));
            for p in Port::each(t) {
                prefetch(cj.out.slots(p));
            }
        }
    }

    /// Note cell `i`'s step: for the trace, the stall detector, the visits, and whether it is
    /// idle or asleep now.
    fn note(&self, c: &HostLightCell<F>, i: u32, step: Step, r: &mut PieceResult<F>) {
        if self.tapping {
            r.steps.push((i as usize, step));
        }
        // A sibling wait ends by itself within `hold` cycles: not a stall.
        r.any |= step == Step::Held;
        if step == Step::Processed {
            r.any = true;
            if self.record {
                r.seen.push((i as usize, c.last_z));
            }
        }
        if !c.busy() {
            r.quiet.push(i);
        } else if self.may_sleep && step == Step::Held && !c.out.any() && (i as usize != self.s_idx || !self.emitting) {
            if let Some(w) = c.held_wait() {
                r.sleep.push((i, w));
            }
        }
    }
}

/// What every piece of the link phase reads.
struct PullCtx<'a, 'e, F: FracBits> {
    env: &'a LightEnv<'e, F>,
    cycle: u64,
    stepping: Stepping,
    may_sleep: bool,
    lossless: bool,
    taken_ports: &'a [Taken],
    unacked_ports: &'a [AtomicU8],
    in_active: &'a [AtomicBool],
    asleep: &'a [AtomicU64],
    link_load: &'a [AtomicU32],
}

impl<F: FracBits> PullCtx<'_, '_, F> {
    /// Offer every message of one piece of receivers to its link, in link order.
    fn pull_piece<L: HostLink<F>>(&self, piece: LinkPiece<'_, HostLightCell<F>, F, L>, r: &mut PieceResult<F>) {
        let (tile, base, lists, links) = piece;
        let delta = ActivityDelta::new();
        let PieceResult { taken, woke, roused, order, took, any, .. } = r;
        link_order(&lists, order);
        for k in 0..order.len() {
            if let Some(&(p, j)) = order.get(k + AHEAD) {
                let a = &lists[p as usize][j as usize];
                prefetch_cell(&tile[a.to as usize - base], 1);
                prefetch(&self.taken_ports[a.from as usize]);
            }
            let (p, j) = order[k];
            let o = &lists[p as usize][j as usize];
            let at = o.to as usize - base;
            let link = &mut links[at * 8 + BACK[o.port as usize]];
            let mut rx = CellInbox {
                cell: &mut tile[at],
                fa: self.env.fa,
                merge: self.env.merge,
                tally: &delta,
                journal: &mut *took,
            };
            if !sure(link.ready(&rx)) {
                continue;
            }
            if self.may_sleep {
                *roused += self.rouse(rx.cell, o.to);
            }
            let sent = sure(link.send(self.cycle, &o.msg, &mut rx));
            *any |= sent.delivered || sent.acked;
            let bit = 1u8 << o.port;
            if sent.acked {
                self.taken_ports[o.from as usize].fetch_add(taken_one(o.port), Relaxed);
            } else if !self.lossless {
                self.unacked_ports[o.from as usize].fetch_or(bit, Relaxed);
            }
            if sent.delivered {
                *taken += 1;
                let l = &self.link_load[links::slot(o.to, o.port)];
                l.store(l.load(Relaxed) + 1, Relaxed);
                // Receivers are this piece's alone: a plain load and store.
                if self.stepping == Stepping::Active && !self.in_active[o.to as usize].load(Relaxed) {
                    self.in_active[o.to as usize].store(true, Relaxed);
                    woke.push(o.to);
                }
            }
        }
        r.delta = delta.get();
    }

    /// A sleeper a beam reaches first takes the held steps it missed (cycles c0 + 1 ..= cycle):
    /// the arrival is stamped with its true clock. 1 if `c` (cell `to`) was asleep.
    fn rouse(&self, c: &mut HostLightCell<F>, to: u32) -> usize {
        let c0 = self.asleep[to as usize].load(Relaxed);
        if c0 == AWAKE {
            return 0;
        }
        c.skip_held((self.cycle - c0) as u16);
        self.asleep[to as usize].store(AWAKE, Relaxed);
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cell_core::beam::frac::U0;
    use cell_core::beam::SourceCoord;
    use proptest::prelude::*;

    /// Offers as the compute pass makes them: senders in increasing order, each with the ports
    /// of `mask` (receivers outside an `n` × `n` grid left out), one list per port.
    fn offers(n: u32, senders: &[(u32, u8, u32)]) -> [Vec<Offer<U0>>; 8] {
        let src = Source::new(SourceId(0), [SourceCoord::from_num(0.0); 3]);
        let far = FarDistance::<U0>::new(n).unwrap();
        let msg = BeamMsg::new(Beam::initial(&src, Direction::PosX, far), 0);
        let mut lists: [Vec<Offer<U0>>; 8] = Default::default();
        for &(from, mask, key) in senders {
            let (x, y) = ((from % n) as i64, (from / n) as i64);
            for p in Port::each(mask) {
                let (dx, dy) = p.delta();
                let (tx, ty) = (x + dx as i64, y + dy as i64);
                if (0..n as i64).contains(&tx) && (0..n as i64).contains(&ty) {
                    let to = (ty * n as i64 + tx) as u32;
                    // Keys from a few values, so that ties between senders are common.
                    let key = key.wrapping_mul(p.index() as u32 + 3) % 4;
                    lists[p.index()].push(Offer { to, key, from, port: p.index() as u8, msg });
                }
            }
        }
        lists
    }

    proptest! {
        /// A [`Taken`] value holds up to 15 messages per port: adding `taken_one` per message
        /// and reading back gives each port's count, and the mask of the ports that had any.
        #[test]
        fn taken_counts_add_up(counts in proptest::array::uniform8(0u32..=3)) {
            let t = Taken::new(0);
            for (p, &k) in counts.iter().enumerate() {
                for _ in 0..k {
                    t.fetch_add(taken_one(p as u8), Relaxed);
                }
            }
            let got: Vec<(usize, u32)> = taken_counts(t.load(Relaxed)).map(|(p, k)| (p.index(), k)).collect();
            let want: Vec<(usize, u32)> = counts.iter().copied().enumerate().filter(|&(_, k)| k > 0).collect();
            prop_assert_eq!(got, want);
            let mask = counts.iter().enumerate().fold(0u8, |m, (p, &k)| m | (u8::from(k > 0) << p));
            prop_assert_eq!(taken_mask(t.load(Relaxed)), mask);
        }

        /// The merge gives exactly the order of a sort of all offers by (receiver, key,
        /// sender), and the receiver cut hands every offer, once, to the piece owning its
        /// receiver.
        #[test]
        fn link_order_is_the_sorted_order(
            n in 1u32..12,
            picks in proptest::collection::btree_map(0u32..144, (any::<u8>(), any::<u32>()), 0..60),
            cut_picks in proptest::collection::btree_set(0u32..160, 0..6),
        ) {
            let senders: Vec<(u32, u8, u32)> =
                picks.into_iter().filter(|&(c, _)| c < n * n).map(|(c, (m, k))| (c, m, k)).collect();
            let mut lists = offers(n, &senders);
            let mut expect: Vec<(u32, u32, u32, u8)> =
                lists.iter().flatten().map(|o| (o.to, o.key, o.from, o.port)).collect();
            expect.sort_unstable();
            let mut order = Vec::new();
            let whole_lists = whole(&mut lists);
            link_order(&whole_lists, &mut order);
            let got: Vec<(u32, u32, u32, u8)> = order
                .iter()
                .map(|&(p, j)| {
                    let o = &whole_lists[p as usize][j as usize];
                    (o.to, o.key, o.from, o.port)
                })
                .collect();
            prop_assert_eq!(&got, &expect);

            // The whole grid, and the band of rows n/2.. held alone (its receivers' offers only).
            for origin in [0, n / 2 * n] {
                let mut cells: Vec<u32> = (origin..n * n).collect();
                let mut links: Vec<u32> = (origin * 8..n * n * 8).collect();
                let mut band = lists.clone();
                band.iter_mut().for_each(|l| l.retain(|o| o.to >= origin));
                let cuts: Vec<u32> = cut_picks.iter().copied().filter(|&c| c > origin).collect();
                let mut seen = Vec::new();
                for (tile, base, piece, tile_links) in by_receiver(&mut cells, origin as usize, &mut links, &mut band, &cuts) {
                    prop_assert_eq!(tile_links.len(), tile.len() * 8);
                    prop_assert_eq!(tile_links.first().copied(), tile.first().map(|&c| c * 8));
                    for o in piece.iter().flat_map(|l| l.iter()) {
                        prop_assert_eq!(tile[o.to as usize - base], o.to);
                        seen.push((o.to, o.key, o.from, o.port));
                    }
                }
                seen.sort_unstable();
                let want: Vec<_> = expect.iter().copied().filter(|e| e.0 >= origin).collect();
                prop_assert_eq!(seen, want);
            }
        }
    }
}
