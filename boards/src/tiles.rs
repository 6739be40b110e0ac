//! The tile exercise (tests/tests/integration/mcu_tiles.rs on QEMU boards): each board holds
//! a tile of cells of an n × n grid and runs the loading wave and one source's lighting on it,
//! asynchronously (no global cycle), with cell-core's own cells — the real counterpart of
//! host-sim's `machine::lighting::boards`, and the firmware's side of §4.4.4 (boards that detect a
//! phase's end themselves). [`TileBoard`] is one board, driven by [`TileBoard::poll`] with its
//! links; the exercise has no notion of time (only the links' retransmissions have, below it).
//!
//! * **Setup** (host → board, UART 0): [`KIND_TILE_CONFIG`] (board id, neighbours, ring
//!   position, tile origin and side, n, depth), then the light setup
//!   ([`KIND_TILE_LIGHT`](cell_core::wire::board::KIND_TILE_LIGHT): a `cell_core::trace` light
//!   record, which [`light_setup`] reads and the driver hands [`TileBoard::new`]), then, to the
//!   board holding pipeline cell 0 (cell (0, 0)), the scene's pipeline packets ([`KIND_PIPE`]
//!   at row 0). Then [`KIND_START`] to ring position 0. The host's frames are not basic
//!   messages: they are all taken (acknowledged) before the detection starts.
//! * **Cells**: a slot per cell of the tile: a `cell_core::cell::Cell` (the dexel store
//!   the loading fills with `Cell::load_step`) and a `cell_core::light::LightCell` (stepped
//!   with the light setup's `LightEnv`, as the production cell does). The firmware has no
//!   lighting or loading code of its own: it only moves packets and beams between cells.
//! * **Loading** (phase 0): the work list holds pipeline packets (at pipeline row y, beside
//!   cell (0, y)) and row packets (at cell (x, y)); each pass moves every item one cell
//!   (`PipelineCell::step`, `Cell::load_step`), in order. An item whose next cell is on another
//!   board goes into that link's outgoing queue ([`KIND_PIPE`], [`KIND_ROW_AT`]): loading only
//!   flows east and north (+x, +y), in order on each link.
//! * **Lighting** (phase 1): arrived beams go into their cell's FIFO when it has room (a beam
//!   for a full FIFO waits; later beams for other cells do not), the source's board hands its
//!   cell the next of the six initial beams it made from the light setup once it entered
//!   phase 1, every cell holding a beam steps, and the head of every output buffer moves: to
//!   the neighbour cell's FIFO inside the tile (when it has room), or into the outgoing queue
//!   of the link towards the neighbour's board ([`KIND_TILE_BEAM`], addressed by cell). A beam
//!   to a diagonal neighbour across a board corner goes first along x, then along y
//!   ([`Config::route`]): the side neighbour forwards it (received, then sent again: both
//!   counted as basic messages).
//! * **Termination**: Safra's token ring (`cell_core::termination`) over the same links, three
//!   phases: loading (0), lighting (1) and an empty phase (2) whose round tells every board
//!   that the lighting was declared. A board is passive when it holds no loading item, no
//!   beam (in a cell, an output buffer, the arrived queue or an outgoing queue) and, in phase
//!   ≥ 1, no initial beam to emit. Ring position 0 tells the host each declaration
//!   ([`KIND_DONE`]).
//! * **Report**: on [`KIND_QUERY`], one [`KIND_TILE_CELL`] frame per cell (its dexels and
//!   lit runs) and one [`KIND_TILE_STATE`].
//!
//! **Invariant**: a board's termination counter is its basic frames sent − received between
//! boards (loading packets and beams), a frame being counted when the link takes it and when
//! the board takes it off the link; a frame is taken off a link only when the board has room
//! for it (the link leaves it unacknowledged otherwise: nothing is dropped); so a declaration
//! means no packet or beam is left anywhere. Work seen after a board learned a phase's
//! declaration is counted as *late* ([`State`]), and every bounded queue's overflow or refusal
//! is counted, never silent.

use cell_core::beam::frac::U0;
use cell_core::beam::{Beam, FarDistance};
use cell_core::cell::{Cell, DEFAULT_DEXELS, FA_CAP, LIT_CAP, OB_CAP};
use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::light::{ActivityDelta, BeamMsg, LightCell, LightEnv, Port};
use cell_core::lit::LitRule;
use cell_core::shade::cell_pixel;
use cell_core::termination::{Action, Node, Token};
use cell_core::trace::{self, kind, LightSetup, ShadeSetup};
use cell_core::voxelize::PipelineCell;
use cell_core::wire::board::{
    KIND_DONE, KIND_PIPE, KIND_QUERY, KIND_ROW_AT, KIND_START, KIND_TILE_BEAM, KIND_TILE_CELL, KIND_TILE_CONFIG,
    KIND_TILE_SHADE, KIND_TILE_STATE,
};
use cell_core::wire::{
    get_beam, get_pipe, get_row, get_token, put_beam, put_pipe, put_row, read_frame, ByteSink, PutExt, Reader,
    SliceWriter, KIND_TOKEN,
};
use heapless::{Deque, Vec};

use crate::{repairs, send_token, Event, Events, Links, Ring, LINKS};

/// Largest tile side: the board's state is sized for [`SIDE`]² cells (board-memory.x).
pub const SIDE: usize = 4;
const CELLS: usize = SIDE * SIDE;
/// Loading items a board holds (its own tile's moving packets).
pub const WORK: usize = 48;
/// Host facets board 0 holds before the start.
const HOST: usize = 32;
/// Frames waiting for each link.
pub const OUT: usize = 32;
/// Beams arrived from other boards, not yet in their cell's FIFO.
pub const ARRIVED: usize = 64;
/// Initial beams (six directions).
const EMIT: usize = 8;
/// Dexels and lit runs reported per cell.
pub const REPORTED: usize = 16;
/// Bytes of the longest frame a board sends: a row packet between boards (3 + 1 + 4 + 73 +
/// 8 × 20 + 4 = 245 B), or a cell's report (3 + 1 + 22 + 2 × 16 × 8 + 4 = 286 B).
pub const LINK_BUF: usize = 320;

type Light = LightCell<U0, FA_CAP, OB_CAP, LIT_CAP>;

/// One cell of the tile.
struct Slot {
    cell: Cell<DEFAULT_DEXELS>,
    light: Light,
}

/// A loading item.
#[derive(Clone)]
enum Load {
    /// A pipeline packet at pipeline row y.
    Pipe(u16, PipelinePacket),
    /// A row packet at cell (x, y).
    Row(u16, u16, RowPacket),
}

/// A frame waiting for a link. Beams are much smaller than loading items, but a queue slot
/// holds either (no heap to box the large one in; the queues are sized in slots).
#[derive(Clone)]
#[allow(clippy::large_enum_variant)]
enum Msg {
    Load(Load),
    /// A beam for cell (x, y).
    Beam(u16, u16, BeamMsg<U0>),
}

/// The configuration ([`KIND_TILE_CONFIG`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Config {
    /// The board's place in the grid and the ring.
    pub ring: Ring,
    /// The tile's first cell.
    pub x0: u16,
    /// The tile's first cell.
    pub y0: u16,
    /// The tile's side in cells (1 … [`SIDE`]).
    pub side: u16,
    /// The grid's side in cells.
    pub n: u16,
    /// Voxels per column.
    pub depth: u16,
}

impl Config {
    /// The configuration, if `kind` and `p` are one this board can hold: the [`Ring`] head, x0
    /// (u16), y0 (u16), side, n (u16), depth (u16).
    pub fn parse(kind: u8, p: &[u8]) -> Option<Config> {
        if kind != KIND_TILE_CONFIG || p.len() != Ring::BYTES + 9 {
            return None;
        }
        let u = |i: usize| u16::from_le_bytes([p[i], p[i + 1]]);
        let c = Config { ring: Ring::parse(p)?, x0: u(8), y0: u(10), side: u16::from(p[12]), n: u(13), depth: u(15) };
        let fits = (1..=SIDE as u16).contains(&c.side) && c.x0 + c.side <= c.n && c.y0 + c.side <= c.n;
        fits.then_some(c)
    }

    /// Cell (x, y)'s index in the tile, if it is in the tile.
    pub fn slot(&self, x: i32, y: i32) -> Option<usize> {
        let (dx, dy) = (x - i32::from(self.x0), y - i32::from(self.y0));
        let s = i32::from(self.side);
        ((0..s).contains(&dx) && (0..s).contains(&dy)).then(|| (dy * s + dx) as usize)
    }

    /// The neighbour link (0 … 3: E, N, W, S) towards the board holding cell (x, y) (not this
    /// one): along x first, then y, so a cell across a board corner is reached through the
    /// side neighbour along x, which forwards it.
    pub fn route(&self, x: i32, y: i32) -> Option<usize> {
        let (x0, y0, s) = (i32::from(self.x0), i32::from(self.y0), i32::from(self.side));
        let l = if x >= x0 + s {
            0
        } else if x < x0 {
            2
        } else if y >= y0 + s {
            1
        } else if y < y0 {
            3
        } else {
            return None;
        };
        self.ring.connected(l).then_some(l)
    }
}

/// Counters of the exercise (reported in [`KIND_TILE_STATE`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct State {
    /// Basic frames the links took.
    pub sent: u32,
    /// Basic frames taken off the links.
    pub received: u32,
    /// Received frames for another board, queued towards it.
    pub forwarded: u32,
    /// Tokens sent on.
    pub tokens: u32,
    /// Work seen after the board learned its phase was declared.
    pub late: u32,
    /// Frames that did not decode or encode, host facets beyond their queue.
    pub overflows: u32,
    /// Items or beams for a cell no link leads to.
    pub misrouted: u32,
    /// Loading steps.
    pub loads: u32,
    /// Lighting steps.
    pub steps: u32,
    /// Most beams arrived and waiting for their FIFO.
    pub peak_arrived: u32,
    /// Most loading items held.
    pub peak_work: u32,
    /// Beams a cell refused (`LightCell::accept`).
    pub refused: u32,
}

/// Encode `m` into `buf`; returns (kind, length).
fn encode(m: &Msg, buf: &mut [u8]) -> Option<(u8, usize)> {
    let mut w = SliceWriter::new(buf);
    let kind = match m {
        Msg::Load(Load::Pipe(y, p)) => {
            w.u16(*y).ok()?;
            put_pipe(&mut w, p).ok()?;
            KIND_PIPE
        }
        Msg::Load(Load::Row(x, y, p)) => {
            w.u16(*x).ok()?;
            w.u16(*y).ok()?;
            put_row(&mut w, p).ok()?;
            KIND_ROW_AT
        }
        Msg::Beam(x, y, m) => {
            w.u16(*x).ok()?;
            w.u16(*y).ok()?;
            put_beam(&mut w, m).ok()?;
            KIND_TILE_BEAM
        }
    };
    Some((kind, w.len()))
}

/// Decode a basic frame from a neighbour.
fn decode(kind: u8, p: &[u8], far: FarDistance<U0>) -> Option<Msg> {
    let mut r = Reader::new(p);
    let m = match kind {
        KIND_PIPE => Msg::Load(Load::Pipe(r.u16().ok()?, get_pipe(&mut r).ok()?)),
        KIND_ROW_AT => {
            let (x, y) = (r.u16().ok()?, r.u16().ok()?);
            Msg::Load(Load::Row(x, y, get_row(&mut r).ok()?))
        }
        KIND_TILE_BEAM => {
            let (x, y) = (r.u16().ok()?, r.u16().ok()?);
            Msg::Beam(x, y, get_beam(&mut r, far).ok()?)
        }
        _ => return None,
    };
    r.finish().ok()?;
    Some(m)
}

/// A [`KIND_TILE_BEAM`] body: beam `m` for cell (x, y) (what a board sends towards that
/// cell's board; for a host test that puts a beam on a wire).
pub fn beam_body(x: u16, y: u16, m: &BeamMsg<U0>, buf: &mut [u8]) -> Option<usize> {
    encode(&Msg::Beam(x, y, *m), buf).map(|(_, n)| n)
}

/// The cell a loading item is at: (x, y) of its cell (a pipeline packet: cell (0, y)).
fn at(l: &Load) -> (i32, i32) {
    match l {
        Load::Pipe(y, _) => (0, i32::from(*y)),
        Load::Row(x, y, _) => (i32::from(*x), i32::from(*y)),
    }
}

/// The light setup of a trace light record (`KIND_TILE_LIGHT`'s body), if the boards can run
/// it: they run without the whole-grid skips (as host-sim's async_tiles does).
pub fn light_setup(bytes: &[u8]) -> Option<LightSetup> {
    let (raw, _) = read_frame(bytes).ok()?;
    if raw.kind != kind::LIGHT {
        return None;
    }
    let mut r = Reader::new(raw.payload);
    let s = trace::get_light_setup(&mut r, trace::read_frustum).ok()?;
    r.finish().ok()?;
    (s.frustum.is_none() && s.skip.is_none() && s.hold == 0).then_some(s)
}

/// The shading inputs of a trace shading record ([`KIND_TILE_SHADE`]'s body).
fn shade_setup(bytes: &[u8]) -> Option<ShadeSetup> {
    let (raw, _) = read_frame(bytes).ok()?;
    if raw.kind != kind::SHADE {
        return None;
    }
    let mut r = Reader::new(raw.payload);
    let s = trace::get_shade_setup(&mut r).ok()?;
    r.finish().ok()?;
    Some(s)
}

/// One board of the tile exercise: what `firmware/src/bin/board/tiles.rs`'s loop kept in its
/// locals. It holds its lighting environment, which borrows the light setup and split order.
pub struct TileBoard<'s> {
    c: Config,
    env: LightEnv<'s, U0>,
    slots: Vec<Slot, CELLS>,
    tally: ActivityDelta,
    work: Deque<Load, WORK>,
    host: Deque<PipelinePacket, HOST>,
    out: [Deque<Msg, OUT>; LINKS],
    arrived: Deque<(usize, BeamMsg<U0>), ARRIVED>,
    /// The source's initial beams, before the lighting phase.
    pending: Deque<BeamMsg<U0>, EMIT>,
    /// The source's initial beams, released: handed to its cell one by one.
    emit: Deque<BeamMsg<U0>, EMIT>,
    source_slot: Option<usize>,
    node: Node,
    token: Option<Token>,
    started: bool,
    st: State,
    done_due: Deque<u16, 4>,
    report_next: Option<usize>,
    shade: Option<ShadeSetup>,
    /// Safra's message counters are kept (false: the counterless mutant, for tests only).
    counters: bool,
}

impl<'s> TileBoard<'s> {
    /// A board configured by `c` lighting with `env` (the light setup's, `LightSetup::env`:
    /// the setup checked by [`light_setup`] and against `c`'s n and depth by the caller),
    /// before the start.
    ///
    /// The board is large (its cells and queues: about 150 KB on the Cortex-M4F), so `new` is
    /// one struct expression, built in the caller's place, and the cells are made in place by
    /// the first [`TileBoard::poll`]: a board built in a local of `new` and then returned cost
    /// the firmware's stack a second copy (198 KB more at the peak).
    pub fn new(c: Config, env: LightEnv<'s, U0>) -> TileBoard<'s> {
        let sv = env.source.voxel();
        TileBoard {
            c,
            env,
            slots: Vec::new(),
            tally: ActivityDelta::new(),
            work: Deque::new(),
            host: Deque::new(),
            out: [const { Deque::new() }; LINKS],
            arrived: Deque::new(),
            pending: Deque::new(),
            emit: Deque::new(),
            source_slot: c.slot(sv[0], sv[1]),
            // Loading (0), lighting (1), and the empty phase (2) that tells every board of the
            // lighting's declaration.
            node: Node::new(u16::from(c.ring.position), 2),
            token: None,
            started: c.ring.position != 0,
            st: State::default(),
            done_due: Deque::new(),
            report_next: None,
            shade: None,
            counters: true,
        }
    }

    /// The tile's cells, and the source cell's six initial beams (§4.3: it makes them itself,
    /// from the light setup every board got; they go out once the board enters the lighting
    /// phase). Once, at the first poll.
    fn make_cells(&mut self) {
        let c = self.c;
        let side = i32::from(c.side);
        for i in 0..side * side {
            let (x, y) = (c.x0 + (i % side) as u16, c.y0 + (i / side) as u16);
            let _ = self.slots.push(Slot { cell: Cell::new(x, y), light: LightCell::new(x, y) });
        }
        if self.source_slot.is_some() {
            let sv = self.env.source.voxel();
            for b in Beam::initial_six(self.env.source, self.env.far) {
                let _ = self.pending.push_back(BeamMsg::new(b, sv[2] as u16));
            }
        }
    }

    /// The *counterless mutant*: a board that never counts its basic frames (nor turns black
    /// on receiving one), so its ring declares a phase as soon as one round finds every board
    /// passive, with a beam possibly in flight. Only for tests that show the counters are
    /// needed.
    #[doc(hidden)]
    pub fn without_counters(mut self) -> TileBoard<'s> {
        self.counters = false;
        self
    }

    /// The board's configuration.
    pub fn config(&self) -> &Config {
        &self.c
    }

    /// The exercise's counters.
    pub fn state(&self) -> &State {
        &self.st
    }

    /// The board's termination node.
    pub fn node(&self) -> &Node {
        &self.node
    }

    /// Whether the source's cell is on this board.
    pub fn holds_source(&self) -> bool {
        self.source_slot.is_some()
    }

    /// Whether the board holds no loading item, no beam (in a cell, an output buffer, the
    /// arrived queue or an outgoing queue) and no released initial beam: the termination's
    /// passive.
    pub fn passive(&self) -> bool {
        self.host.is_empty()
            && self.work.is_empty()
            && self.arrived.is_empty()
            && self.emit.is_empty()
            && self.out.iter().all(|o| o.is_empty())
            && self.slots.iter().all(|s| !s.light.busy())
    }

    /// Whether the board has nothing to do but wait for a frame (its driver may sleep).
    pub fn idle(&self) -> bool {
        self.passive() && self.done_due.is_empty() && self.report_next.is_none()
    }

    /// Entering phase `p` = 1 (lighting) releases the initial beams.
    fn entered(&mut self, p: u16) {
        if p == 1 {
            while let Some(b) = self.pending.pop_front() {
                let _ = self.emit.push_back(b);
            }
        }
    }

    /// One pass: take the neighbours' frames (tokens, loading packets, beams) and the host's,
    /// move every loading item one cell, step the lighting, send, act on the token, answer the
    /// host.
    pub fn poll(&mut self, links: &mut impl Links) -> Events {
        if self.slots.is_empty() {
            self.make_cells();
        }
        let mut events = Events::new();
        let mut buf = [0u8; LINK_BUF];
        self.receive(links, &mut events);
        self.host(links, &mut events);
        self.load();
        self.light();
        self.send(links, &mut buf);

        // Step 6, termination: the node acts on the token only when the board is passive.
        if self.started && self.token.is_none() {
            match self.node.poll(self.passive()) {
                Ok(Action::Forward(t)) => self.token = Some(t),
                Ok(Action::Declare(p)) => {
                    let _ = events.push(Event::Declared(p));
                    let _ = self.done_due.push_back(p);
                    self.entered(self.node.phase());
                }
                _ => {}
            }
        }

        // Step 7, answers to the host: declarations, then the report.
        if links.can_send(0) {
            if let Some(p) = self.done_due.pop_front() {
                let _ = links.send(0, KIND_DONE, &p.to_le_bytes());
            } else if let Some(i) = self.report_next {
                let n = if i < self.slots.len() {
                    cell_report(&self.slots[i], self.env.rule, self.shade.as_ref(), &mut buf)
                } else {
                    self.state_report(links, &mut buf)
                };
                let kind = if i < self.slots.len() { KIND_TILE_CELL } else { KIND_TILE_STATE };
                if links.send(0, kind, &buf[..n]) {
                    self.report_next = (i < self.slots.len()).then_some(i + 1);
                }
            }
        }
        events
    }

    /// Step 1, neighbours: tokens and basic frames, each taken only when there is room.
    fn receive(&mut self, links: &mut impl Links, events: &mut Events) {
        let c = self.c;
        for l in 0..LINKS {
            if !c.ring.connected(l) {
                continue;
            }
            let Some(f) = links.received(l + 1) else { continue };
            if f.kind == KIND_TOKEN {
                if let Ok(t) = get_token(&mut Reader::new(f.payload)) {
                    if let Some(p) = self.node.token(t).entered {
                        let _ = events.push(Event::Entered(p));
                        self.entered(p);
                    }
                }
                links.pop(l + 1);
                continue;
            }
            let Some(m) = decode(f.kind, f.payload, self.env.far) else {
                self.st.overflows += 1;
                links.pop(l + 1);
                continue;
            };
            let (x, y) = match &m {
                Msg::Load(ld) => at(ld),
                Msg::Beam(x, y, _) => (i32::from(*x), i32::from(*y)),
            };
            let st = &mut self.st;
            let took = match (c.slot(x, y), m) {
                (Some(_), Msg::Load(ld)) => {
                    st.late += u32::from(self.node.phase() >= 1);
                    self.work.push_back(ld).is_ok()
                }
                (Some(s), Msg::Beam(_, _, b)) => {
                    st.late += u32::from(self.node.phase() >= 2);
                    let ok = self.arrived.push_back((s, b)).is_ok();
                    st.peak_arrived = st.peak_arrived.max(self.arrived.len() as u32);
                    ok
                }
                (None, m) => match c.route(x, y) {
                    Some(to) => {
                        let ok = self.out[to].push_back(m).is_ok();
                        st.forwarded += u32::from(ok);
                        ok
                    }
                    None => {
                        st.misrouted += 1;
                        true
                    }
                },
            };
            if took {
                if self.counters {
                    let _ = self.node.received();
                }
                st.received += 1;
                links.pop(l + 1);
            }
        }
    }

    /// Step 2, the host: facets, shading inputs, start, query.
    fn host(&mut self, links: &mut impl Links, events: &mut Events) {
        if let Some(f) = links.received(0) {
            let mut r = Reader::new(f.payload);
            match f.kind {
                KIND_PIPE => match (r.u16(), get_pipe(&mut r)) {
                    (Ok(0), Ok(p)) if self.c.slot(0, 0).is_some() => {
                        if self.host.push_back(p).is_err() {
                            self.st.overflows += 1;
                        }
                    }
                    _ => self.st.overflows += 1,
                },
                KIND_TILE_SHADE => match shade_setup(f.payload) {
                    Some(sh) => self.shade = Some(sh),
                    None => self.st.overflows += 1,
                },
                KIND_START => self.started = true,
                KIND_QUERY => {
                    let _ = events.push(Event::Queried);
                    self.report_next = Some(0)
                }
                _ => {}
            }
            links.pop(0);
        }
        if self.work.len() < WORK {
            if let Some(p) = self.host.pop_front() {
                let _ = self.work.push_back(Load::Pipe(0, p));
            }
        }
    }

    /// Step 3, loading: every item one cell on, in order; stop while there is no room for what an
    /// item may make (two items, or one outgoing frame).
    fn load(&mut self) {
        let c = self.c;
        let st = &mut self.st;
        for _ in 0..self.work.len() {
            if self.work.len() + 2 > WORK || self.out.iter().any(|o| o.is_full()) {
                break;
            }
            let Some(item) = self.work.pop_front() else { break };
            st.loads += 1;
            st.late += u32::from(self.node.phase() >= 1);
            let next = match item {
                Load::Pipe(y, mut p) => {
                    let step = PipelineCell { y }.step(&mut p);
                    if let Some(rp) = step.east {
                        let _ = self.work.push_back(Load::Row(0, y, rp));
                    }
                    (step.down && y + 1 < c.n).then_some(Load::Pipe(y + 1, p))
                }
                Load::Row(x, y, mut rp) => {
                    let Some(s) = c.slot(i32::from(x), i32::from(y)) else {
                        st.misrouted += 1;
                        continue;
                    };
                    let forward = self.slots[s].cell.load_step(&mut rp, u32::from(c.depth));
                    (forward && x + 1 < c.n).then_some(Load::Row(x + 1, y, rp))
                }
            };
            if let Some(m) = next {
                let (x, y) = at(&m);
                if c.slot(x, y).is_some() {
                    let _ = self.work.push_back(m);
                } else if let Some(to) = c.route(x, y) {
                    let _ = self.out[to].push_back(Msg::Load(m));
                } else {
                    st.misrouted += 1;
                }
            }
            st.peak_work = st.peak_work.max(self.work.len() as u32);
        }
    }

    /// Step 4, lighting: arrived beams into FIFOs with room, the next initial beam, a step of every
    /// cell holding a beam, the output buffers' heads to their neighbour cells (inside the
    /// tile, when it has room) or their links' queues.
    fn light(&mut self) {
        let (c, fa, merge) = (self.c, self.env.fa, self.env.merge);
        let (st, tally) = (&mut self.st, &self.tally);
        for _ in 0..self.arrived.len() {
            let Some((s, b)) = self.arrived.pop_front() else { break };
            let light = &mut self.slots[s].light;
            if light.can_accept(fa) {
                st.refused += u32::from(light.accept(b, merge, tally).is_err());
            } else {
                let _ = self.arrived.push_back((s, b));
            }
        }
        if let (Some(s), Some(&b)) = (self.source_slot, self.emit.front()) {
            let light = &mut self.slots[s].light;
            if light.can_accept(fa) {
                st.refused += u32::from(light.accept(b, merge, tally).is_err());
                self.emit.pop_front();
            }
        }
        for s in self.slots.iter_mut() {
            if !s.light.fifo.is_empty() {
                st.steps += 1;
                st.late += u32::from(self.node.phase() >= 2);
                s.light.step(&s.cell, &self.env, tally);
            }
        }
        for i in 0..self.slots.len() {
            let (x, y) = (i32::from(self.slots[i].cell.x), i32::from(self.slots[i].cell.y));
            for p in Port::ALL {
                let Some(&b) = self.slots[i].light.out.front(p) else { continue };
                let (dx, dy) = p.delta();
                let (tx, ty) = (x + i32::from(dx), y + i32::from(dy));
                let taken = match c.slot(tx, ty) {
                    Some(j) => {
                        let light = &mut self.slots[j].light;
                        let ok = light.can_accept(fa);
                        if ok {
                            st.refused += u32::from(light.accept(b, merge, tally).is_err());
                        }
                        ok
                    }
                    None => match c.route(tx, ty) {
                        Some(to) => self.out[to].push_back(Msg::Beam(tx as u16, ty as u16, b)).is_ok(),
                        None => {
                            st.misrouted += 1;
                            true
                        }
                    },
                };
                if taken {
                    self.slots[i].light.out.pop_front(p);
                }
            }
        }
    }

    /// Step 5, send: the token first, then the queued frames (counted when the link takes them).
    fn send(&mut self, links: &mut impl Links, buf: &mut [u8]) {
        for (l, out) in self.out.iter_mut().enumerate() {
            if !self.c.ring.connected(l) || !links.can_send(l + 1) {
                continue;
            }
            if let (true, Some(t)) = (l == self.c.ring.next as usize, self.token) {
                if send_token(links, l + 1, &t) {
                    self.token = None;
                    self.st.tokens += 1;
                }
            } else if let Some(m) = out.front() {
                match encode(m, buf) {
                    Some((k, n)) if links.send(l + 1, k, &buf[..n]) => {
                        if self.counters {
                            let _ = self.node.sent();
                        }
                        self.st.sent += 1;
                    }
                    Some(_) => continue,
                    None => self.st.overflows += 1,
                }
                out.pop_front();
            }
        }
    }

    /// A [`KIND_TILE_STATE`] body into `buf`; returns its length.
    fn state_report(&self, links: &impl Links, buf: &mut [u8]) -> usize {
        let (st, c) = (&self.st, &self.c);
        let (retransmitted, skipped) = repairs(links);
        let mut w = SliceWriter::new(buf);
        let _ = w.u8(c.ring.id);
        for v in [
            st.sent,
            st.received,
            st.forwarded,
            st.tokens,
            st.late,
            st.overflows + st.refused,
            st.misrouted,
            st.loads,
            st.steps,
            st.peak_arrived,
            st.peak_work,
            retransmitted,
            skipped,
            links.stack_peak(),
        ] {
            let _ = w.u32(v);
        }
        let _ = w.i32(self.node.count());
        w.len()
    }
}

/// A [`KIND_TILE_CELL`] body into `buf`; returns its length.
fn cell_report(s: &Slot, rule: LitRule, shade: Option<&ShadeSetup>, buf: &mut [u8]) -> usize {
    let (store, lit) = (&s.cell.store, &s.light.lit);
    let pixel = shade.and_then(|sh| {
        let reached = |z| lit.mask_at(z);
        cell_pixel(rule, &s.cell, reached, s.light.visible_lit, &sh.materials, &sh.lights, &sh.params)
    });
    let mut w = SliceWriter::new(buf);
    let dexels = &store.dexels()[..store.dexels().len().min(REPORTED)];
    let runs = &lit.runs()[..lit.runs().len().min(REPORTED)];
    let _ = (|| {
        w.u16(s.cell.x)?;
        w.u16(s.cell.y)?;
        w.u8(store.dexels().len() as u8)?;
        w.u8(lit.runs().len() as u8)?;
        for v in [store.overflows(), store.lost_voxels(), lit.overflows(), u32::from(s.light.busy())] {
            w.u32(v)?;
        }
        w.u8(u8::from(pixel.is_some()))?;
        w.put(&pixel.map_or([0; 3], |p| p.rgb))?;
        for d in dexels {
            w.u16(d.span.lo)?;
            w.u16(d.span.hi)?;
            w.u32(d.facet)?;
        }
        for r in runs {
            w.u16(r.lo)?;
            w.u16(r.hi)?;
            w.u32(r.mask)?;
        }
        Ok::<(), cell_core::wire::EncodeError>(())
    })();
    w.len()
}
