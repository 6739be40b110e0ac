//! The tile exercise (tests/tests/integration/mcu_tiles.rs on QEMU boards): each board holds
//! a tile of cells of an n × n grid and runs the loading wave and the lighting of one or more
//! sources, one after another, on it, asynchronously (no global cycle), with cell-core's own
//! cells — the real counterpart of host-sim's `machine::lighting::boards`, and the firmware's side
//! of §4.4.4 (boards that detect a phase's end themselves). [`TileBoard`] is one board, driven
//! by [`TileBoard::poll`] with its links; the exercise has no notion of time (only the links'
//! retransmissions have, below it).
//!
//! * **Setup** (host → board, UART 0): [`KIND_TILE_CONFIG`] (board id, neighbours, ring
//!   position, tile origin and side, n, depth, sources S), then S light setups
//!   ([`KIND_TILE_LIGHT`](cell_core::wire::board::KIND_TILE_LIGHT): `cell_core::trace` light
//!   records, source i with id and bit i, which [`light_setup`] reads and the driver hands
//!   [`TileBoard::new`]), then what the host loads into the cells, as a trace does for a
//!   cell: the shading inputs ([`KIND_TILE_SHADE`]), under exact occluders each column's
//!   triangles ([`KIND_TILE_TRIANGLES`]) and, per source, each contact segment's neighbour
//!   answer ([`KIND_TILE_CONTACT`]); to the board holding pipeline cell 0 (cell (0, 0)), the
//!   scene's pipeline packets ([`KIND_PIPE`] at row 0). Then [`KIND_START`] to ring position
//!   0. The host's frames are not basic messages: they are all taken (acknowledged) before
//!   the detection starts.
//! * **Cells**: a slot per cell of the tile: a `cell_core::cell::Cell` (the dexel store
//!   the loading fills with `Cell::load_step`), a `cell_core::light::LightCell` (stepped
//!   with the light setup's `LightEnv`, as the production cell does) and its column's exact
//!   occluders (its triangles and its target ray, which the cell computes from its visible
//!   surface with `cell_core::receiver::target` when it first steps a beam of a source). The
//!   firmware has no lighting or loading code of its own: it only moves packets and beams
//!   between cells.
//! * **Loading** (phase 0): the work list holds pipeline packets (at pipeline row y, beside
//!   cell (0, y)) and row packets (at cell (x, y)); each pass moves every item one cell
//!   (`PipelineCell::step`, `Cell::load_step`), in order. An item whose next cell is on another
//!   board goes into that link's outgoing queue ([`KIND_PIPE`], [`KIND_ROW_AT`]): loading only
//!   flows east and north (+x, +y), in order on each link.
//! * **Lighting** (phase i + 1 for source i): arrived beams go into their cell's FIFO when it
//!   has room (a beam for a full FIFO waits; later beams for other cells do not), the board
//!   holding source i's cell hands it the next of the six initial beams it made from the light
//!   setup once it entered the phase, every cell holding a beam steps (with the environment of
//!   its beams' source: every beam in the machine is one source's, the next source's leaving
//!   only once the last one's lighting was declared), and the head of every output buffer
//!   moves: to the neighbour cell's FIFO inside the tile (when it has room), or into the
//!   outgoing queue of the link towards the neighbour's board ([`KIND_TILE_BEAM`], addressed
//!   by cell). A beam to a diagonal neighbour across a board corner goes first along x, then
//!   along y ([`Config::route`]): the side neighbour forwards it (received, then sent again:
//!   both counted as basic messages).
//! * **Termination**: Safra's token ring (`cell_core::termination`) over the same links, S + 2
//!   phases: loading (0), one lighting per source (1 … S) and an empty phase (S + 1) whose
//!   round tells every board that the last lighting was declared. A board is passive when it
//!   holds no loading item, no beam (in a cell, an output buffer, the arrived queue or an
//!   outgoing queue) and no initial beam to emit. Ring position 0 tells the host each
//!   declaration ([`KIND_DONE`]).
//! * **Report**: on [`KIND_QUERY`], one [`KIND_TILE_CELL`] frame per cell (its dexels, lit
//!   runs and pixel, `cell_core::shade::cell_pixel`) and one [`KIND_TILE_STATE`].
//!
//! **Invariant**: a board's termination counter is its basic frames sent − received between
//! boards (loading packets and beams), a frame being counted when the link takes it and when
//! the board takes it off the link; a frame is taken off a link only when the board has room
//! for it (the link leaves it unacknowledged otherwise: nothing is dropped); so a declaration
//! means no packet or beam is left anywhere. Work seen after a board learned a phase's
//! declaration is counted as *late* ([`State`]: a loading item in a lighting phase, a beam of
//! source i after phase i + 1), and every bounded queue's overflow or refusal is counted,
//! never silent (a triangle beyond its column's store, a contact answer the cell's target does
//! not ask for or one it lacks among them).

use cell_core::beam::frac::U0;
use cell_core::beam::{Beam, FarDistance};
use cell_core::cell::{Cell, DEFAULT_DEXELS, FA_CAP, LIT_CAP, OB_CAP, TRIANGLE_CAP};
use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::light::{ActivityDelta, BeamMsg, LightCell, LightEnv, Port};
use cell_core::lit::LitRule;
use cell_core::occluder::{ColumnOccluders, Triangle, TriangleStore};
use cell_core::receiver::Target;
use cell_core::shade::cell_pixel;
use cell_core::termination::{Action, Node, Token};
use cell_core::trace::{self, kind, LightSetup, ShadeSetup};
use cell_core::voxelize::PipelineCell;
use cell_core::wire::board::{
    KIND_DONE, KIND_PIPE, KIND_QUERY, KIND_ROW_AT, KIND_START, KIND_TILE_BEAM, KIND_TILE_CELL, KIND_TILE_CONFIG,
    KIND_TILE_CONTACT, KIND_TILE_SHADE, KIND_TILE_STATE, KIND_TILE_TRIANGLES,
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
/// Light sources a board lights with, one after another (each its own lighting phase).
pub const SOURCES: usize = 4;
/// Triangles one [`KIND_TILE_TRIANGLES`] frame carries at most (4 + 8 × 36 = 292 B of body).
pub const TRIANGLES_PER_FRAME: usize = 8;
/// Bytes of one cell of a tile on the board: its dexel store, its lighting cell and its
/// column's occluders (the board's state is [`SIDE`]² of them and its queues).
pub const CELL_BYTES: usize = core::mem::size_of::<Slot>();
/// Dexels and lit runs reported per cell.
pub const REPORTED: usize = 16;
/// Bytes of the longest frame on a board's links: a row packet between boards (3 + 1 + 4 + 73 +
/// 8 × 20 + 4 = 245 B), a cell's report (3 + 1 + 26 + 2 × 16 × 8 + 4 = 290 B), a column's
/// triangles (3 + 1 + 4 + 8 × 36 + 4 = 300 B), or the host's shading record, a trace record
/// of L lights and M materials (3 + 1 + 7 + 15 + 24 L + 52 M + 4 B: 490 B with 4 lights and 7
/// materials: the Cornell box's record with two lights did not fit the former 320 B).
pub const LINK_BUF: usize = 512;

type Light = LightCell<U0, FA_CAP, OB_CAP, LIT_CAP>;

/// One cell of the tile.
struct Slot {
    cell: Cell<DEFAULT_DEXELS>,
    light: Light,
    column: Column,
}

/// A column's exact occluders (`LitRule::Exact`), as a cell of the default image holds them:
/// the triangles the host loads into it with the facets ([`KIND_TILE_TRIANGLES`]), and the
/// target ray it computes itself from its visible surface (`cell_core::receiver::target`) for
/// the source whose beams it steps, with its neighbours' answer to its contact query
/// ([`KIND_TILE_CONTACT`], from the host as a trace's `NeighbourContact` record).
#[derive(Debug)]
struct Column {
    triangles: TriangleStore<TRIANGLE_CAP>,
    target: Option<Target>,
    /// The source (index in the run) `target` is for; `None`: not computed yet.
    target_of: Option<u8>,
    /// Per source (bit i): the host gave the contact answer, and what it was.
    answered: u32,
    shadowed: u32,
}

impl Column {
    const fn new() -> Column {
        Column { triangles: TriangleStore::new(), target: None, target_of: None, answered: 0, shadowed: 0 }
    }

    /// The target ray of cell `cell` for source `i` of `env`, once per source (when the cell
    /// first steps one of its beams: every column's loading is over by then). Returns false when
    /// the host's contact answer and the target disagree (an answer missing or one too many).
    fn aim(&mut self, cell: &Cell<DEFAULT_DEXELS>, i: u8, env: &LightEnv<'_, U0>) -> bool {
        if self.target_of == Some(i) {
            return true;
        }
        self.target_of = Some(i);
        let (x, y) = (i32::from(cell.x), i32::from(cell.y));
        let t = cell.visible.as_ref().and_then(|v| cell_core::receiver::target::<U0>(x, y, v, env.source, env.far));
        let (answered, shadowed) = (self.answered >> i & 1 != 0, self.shadowed >> i & 1 != 0);
        let contact = t.is_some_and(|t| t.contact.is_some());
        self.target = t.map(|t| if contact { t.with_neighbour_answers(shadowed) } else { t });
        answered == contact
    }
}

impl ColumnOccluders for Column {
    fn triangles(&self, _x: u16, _y: u16) -> &[Triangle] {
        self.triangles.triangles()
    }

    fn target(&self, _x: u16, _y: u16) -> Option<&Target> {
        self.target.as_ref()
    }
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
    /// Light sources, lit one after another (1 … [`SOURCES`]): as many light setups follow.
    pub sources: u8,
}

impl Config {
    /// The configuration, if `kind` and `p` are one this board can hold: the [`Ring`] head, x0
    /// (u16), y0 (u16), side, n (u16), depth (u16), sources (u8).
    pub fn parse(kind: u8, p: &[u8]) -> Option<Config> {
        if kind != KIND_TILE_CONFIG || p.len() != Ring::BYTES + 10 {
            return None;
        }
        let u = |i: usize| u16::from_le_bytes([p[i], p[i + 1]]);
        let (x0, y0, side, n, depth, sources) = (u(8), u(10), u16::from(p[12]), u(13), u(15), p[17]);
        let c = Config { ring: Ring::parse(p)?, x0, y0, side, n, depth, sources };
        let fits = (1..=SIDE as u16).contains(&c.side) && c.x0 + c.side <= c.n && c.y0 + c.side <= c.n;
        (fits && (1..=SOURCES as u8).contains(&sources)).then_some(c)
    }

    /// The phase lighting source `i` (0: loading; the lighting phases 1 … `sources`; then the
    /// empty phase that tells every board the last lighting was declared).
    pub fn lighting_phase(&self, i: u8) -> u16 {
        u16::from(i) + 1
    }

    /// The last phase: the empty one after the last source's lighting.
    pub fn last_phase(&self) -> u16 {
        u16::from(self.sources) + 1
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
/// it: with the receding-beam and dead-direction skips of its occupied box (the whole-grid
/// reduction after loading, which the host makes as `host-sim trace` does), without the
/// frustum summary or a sibling wait.
pub fn light_setup(bytes: &[u8]) -> Option<LightSetup> {
    let (raw, _) = read_frame(bytes).ok()?;
    if raw.kind != kind::LIGHT {
        return None;
    }
    let mut r = Reader::new(raw.payload);
    let s = trace::get_light_setup(&mut r, trace::read_frustum).ok()?;
    r.finish().ok()?;
    (s.frustum.is_none() && s.hold == 0).then_some(s)
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
    /// Per source of the run, its lighting environment (at least one).
    envs: Vec<LightEnv<'s, U0>, SOURCES>,
    slots: Vec<Slot, CELLS>,
    tally: ActivityDelta,
    work: Deque<Load, WORK>,
    host: Deque<PipelinePacket, HOST>,
    out: [Deque<Msg, OUT>; LINKS],
    arrived: Deque<(usize, BeamMsg<U0>), ARRIVED>,
    /// The initial beams of the source whose lighting phase the board entered, if its cell is
    /// on this board: handed to its cell one by one.
    emit: Deque<BeamMsg<U0>, EMIT>,
    /// The tile's slot of the source cell the initial beams in `emit` are for.
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
    /// A board configured by `c` lighting with `envs`, one environment per source in order (the
    /// light setups', `LightSetup::env`: each checked by [`light_setup`] and against `c`'s n and
    /// depth by the caller; their source bits and ids are the sources' indices), before the
    /// start. With other than `c.sources` of them the board is misconfigured: it counts an
    /// overflow, and without any it does nothing at all.
    ///
    /// The board is large (its cells and queues: about 190 KB on the Cortex-M4F), so `new` is
    /// one struct expression, built in the caller's place, and the cells are made in place by
    /// the first [`TileBoard::poll`]: a board built in a local of `new` and then returned cost
    /// the firmware's stack a second copy (198 KB more at the peak).
    pub fn new(c: Config, envs: Vec<LightEnv<'s, U0>, SOURCES>) -> TileBoard<'s> {
        let misconfigured = u32::from(envs.len() != usize::from(c.sources));
        TileBoard {
            c,
            envs,
            slots: Vec::new(),
            tally: ActivityDelta::new(),
            work: Deque::new(),
            host: Deque::new(),
            out: [const { Deque::new() }; LINKS],
            arrived: Deque::new(),
            emit: Deque::new(),
            source_slot: None,
            // Loading (0), one lighting phase per source, and the empty phase that tells every
            // board of the last lighting's declaration.
            node: Node::new(u16::from(c.ring.position), c.last_phase()),
            token: None,
            started: c.ring.position != 0,
            st: State { overflows: misconfigured, ..State::default() },
            done_due: Deque::new(),
            report_next: None,
            shade: None,
            counters: true,
        }
    }

    /// The tile's cells. Once, at the first poll.
    fn make_cells(&mut self) {
        let c = self.c;
        let side = i32::from(c.side);
        for i in 0..side * side {
            let (x, y) = (c.x0 + (i % side) as u16, c.y0 + (i / side) as u16);
            let _ = self.slots.push(Slot { cell: Cell::new(x, y), light: LightCell::new(x, y), column: Column::new() });
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

    /// How many of the sources' cells are on this board.
    pub fn holds_sources(&self) -> usize {
        self.envs.iter().filter(|e| self.c.slot(e.source.voxel()[0], e.source.voxel()[1]).is_some()).count()
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

    /// Entering the lighting phase of source i releases its initial beams (§4.3: its cell
    /// makes them itself, from the light setup every board got), if its cell is on this board;
    /// with the setup's occupied box, not those of the directions in which no occupied voxel
    /// lies (the dead-direction skip, as host-sim's `initial_beams`).
    fn entered(&mut self, p: u16) {
        let Some(env) = p.checked_sub(1).and_then(|i| self.envs.get(usize::from(i))) else { return };
        let sv = env.source.voxel();
        self.source_slot = self.c.slot(sv[0], sv[1]);
        if self.source_slot.is_some() {
            let dead = |b: &Beam<U0>| env.skip.is_some_and(|bx| bx.receding(b.direction(), sv, sv.map(i64::from)));
            for b in Beam::initial_six(env.source, env.far).into_iter().filter(|b| !dead(b)) {
                let _ = self.emit.push_back(BeamMsg::new(b, sv[2] as u16));
            }
        }
    }

    /// One pass: take the neighbours' frames (tokens, loading packets, beams) and the host's,
    /// move every loading item one cell, step the lighting, send, act on the token, answer the
    /// host.
    pub fn poll(&mut self, links: &mut impl Links) -> Events {
        if self.envs.is_empty() {
            return Events::new();
        }
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
                    cell_report(&self.slots[i], self.envs[0].rule, self.shade.as_ref(), &mut buf)
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
            let Some(m) = decode(f.kind, f.payload, self.envs[0].far) else {
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
                    // A beam of a source whose lighting the board learned was declared.
                    let i = b.beam.source().0;
                    if usize::from(i) >= self.envs.len() {
                        st.overflows += 1;
                        links.pop(l + 1);
                        continue;
                    }
                    st.late += u32::from(self.node.phase() > c.lighting_phase(i as u8));
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
                KIND_TILE_TRIANGLES if !self.triangles(f.payload) => self.st.overflows += 1,
                KIND_TILE_CONTACT => match (r.u16(), r.u16(), r.u8(), r.u8(), r.finish()) {
                    (Ok(x), Ok(y), Ok(i), Ok(a @ 0..=1), Ok(())) if usize::from(i) < self.envs.len() => {
                        match self.c.slot(i32::from(x), i32::from(y)) {
                            Some(s) => {
                                let col = &mut self.slots[s].column;
                                col.answered |= 1 << i;
                                col.shadowed |= u32::from(a) << i;
                            }
                            None => self.st.overflows += 1,
                        }
                    }
                    _ => self.st.overflows += 1,
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

    /// A [`KIND_TILE_TRIANGLES`] body into its column's store; whether it was one and every
    /// triangle fitted.
    fn triangles(&mut self, p: &[u8]) -> bool {
        let mut r = Reader::new(p);
        let (Ok(x), Ok(y)) = (r.u16(), r.u16()) else { return false };
        let Some(s) = self.c.slot(i32::from(x), i32::from(y)) else { return false };
        let column = &mut self.slots[s].column.triangles;
        let mut ok = true;
        let mut k = 0;
        while r.remaining() > 0 && k < TRIANGLES_PER_FRAME {
            let mut v = [[0i32; 3]; 3];
            for c in v.as_flattened_mut() {
                let Ok(x) = r.i32() else { return false };
                *c = x;
            }
            ok &= Triangle::new(v).is_some_and(|t| column.push(t));
            k += 1;
        }
        ok && k > 0 && r.finish().is_ok()
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
        let (c, fa, merge) = (self.c, self.envs[0].fa, self.envs[0].merge);
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
        let phase = self.node.phase();
        for s in self.slots.iter_mut() {
            // Every beam in the machine is one source's (the next source's beams leave once the
            // last one's lighting was declared): the cell steps with that source's environment.
            let Some(i) = s.light.fifo.first().map(|m| m.beam.source().0 as u8) else { continue };
            let Some(&env) = self.envs.get(usize::from(i)) else {
                st.overflows += 1;
                s.light.fifo.clear();
                continue;
            };
            st.steps += 1;
            st.late += u32::from(phase > c.lighting_phase(i));
            let Slot { cell, light, column } = s;
            let env = if env.rule.is_exact() {
                st.overflows += u32::from(!column.aim(cell, i, &env));
                LightEnv { occluders: Some(&*column as &dyn ColumnOccluders), ..env }
            } else {
                env
            };
            light.step(cell, &env, tally);
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
