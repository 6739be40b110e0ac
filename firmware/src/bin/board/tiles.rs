//! The tile exercise: each board holds a tile of cells of an n × n grid and runs the loading
//! wave and one source's lighting on it, asynchronously (no global cycle), with cell-core's own
//! cells — the real counterpart of host-sim's `machine::async_tiles`.
//!
//! * **Setup** (host → board, UART 0): [`KIND_TILE_CONFIG`] (board id, neighbours, ring
//!   position, tile origin and side, n, depth), then the light setup ([`KIND_TILE_LIGHT`]: a
//!   `cell_core::trace` light record), then, to the board holding pipeline cell 0 (cell
//!   (0, 0)), the scene's pipeline packets ([`KIND_PIPE`] at row 0). Then
//!   `safra::KIND_START` to ring position 0. The host's frames are not basic messages: they are
//!   all taken (acknowledged) before the detection starts.
//! * **Cells**: a [`Slot`] per cell of the tile: a `cell_core::cell::Cell` (the dexel store
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
//!   phase 1, every cell holding a beam steps, and
//!   the head of every output buffer moves: to the neighbour cell's FIFO inside the tile (when
//!   it has room), or into the outgoing queue of the link towards the neighbour's board
//!   ([`KIND_TILE_BEAM`], addressed by cell). A beam to a diagonal neighbour across a board
//!   corner goes first along x, then along y: the side neighbour forwards it (received, then
//!   sent again: both counted as basic messages).
//! * **Termination**: Safra's token ring (`cell_core::termination`) over the same links, three
//!   phases: loading (0), lighting (1) and an empty phase (2) whose round tells every board
//!   that the lighting was declared. A board is passive when it holds no loading item, no
//!   beam (in a cell, an output buffer, the arrived queue or an outgoing queue) and, in phase
//!   ≥ 1, no initial beam to emit. Ring position 0 tells the host each declaration
//!   (`safra::KIND_DONE`).
//! * **Report**: on `safra::KIND_QUERY`, one [`KIND_TILE_CELL`] frame per cell (its dexels and
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
use cell_core::beam::{Beam, FarDistance, SplitOrder};
use cell_core::cell::{Cell, DEFAULT_DEXELS, FA_CAP, LIT_CAP, OB_CAP};
use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::light::{ActivityDelta, BeamMsg, LightCell, Port};
use cell_core::lit::LitRule;
use cell_core::shade::cell_pixel;
use cell_core::termination::{Action, Node, Token};
use cell_core::trace::{self, kind, LightSetup, ShadeSetup};
use cell_core::voxelize::PipelineCell;
use cell_core::wire::board::{
    KIND_DONE, KIND_PIPE, KIND_QUERY, KIND_ROW_AT, KIND_START, KIND_TILE_BEAM, KIND_TILE_CELL, KIND_TILE_CONFIG,
    KIND_TILE_LIGHT, KIND_TILE_SHADE, KIND_TILE_STATE,
};
use cell_core::wire::{
    get_beam, get_pipe, get_row, get_token, put_beam, put_pipe, put_row, read_frame, ByteSink, PutExt, Reader,
    SliceWriter, KIND_TOKEN,
};
use heapless::{Deque, Vec};

use cell_core::serial::SerialLink;

use crate::{send_token, stack, Board, LINKS, LINK_BUF, NONE, TIMEOUT_US};

/// Largest tile side: the board's state is sized for [`SIDE`]² cells (board-memory.x).
pub const SIDE: usize = 4;
const CELLS: usize = SIDE * SIDE;
/// Loading items a board holds (its own tile's moving packets).
const WORK: usize = 48;
/// Host facets board 0 holds before the start.
const HOST: usize = 32;
/// Frames waiting for each link.
const OUT: usize = 32;
/// Beams arrived from other boards, not yet in their cell's FIFO.
const ARRIVED: usize = 64;
/// Initial beams (six directions).
const EMIT: usize = 8;
/// Dexels and lit runs reported per cell.
pub const REPORTED: usize = 16;

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
#[derive(Clone, Copy)]
pub struct Config {
    id: u8,
    neighbours: [u8; LINKS],
    ring_position: u8,
    ring_next: u8,
    x0: u16,
    y0: u16,
    side: u16,
    n: u16,
    depth: u16,
}

impl Config {
    /// The configuration, if `kind` and `p` are one this board can hold.
    pub fn parse(kind: u8, p: &[u8]) -> Option<Config> {
        if kind != KIND_TILE_CONFIG || p.len() != 17 || p[7] as usize >= LINKS {
            return None;
        }
        let u = |i: usize| u16::from_le_bytes([p[i], p[i + 1]]);
        let c = Config {
            id: p[0],
            neighbours: [p[1], p[2], p[3], p[4]],
            ring_position: p[5],
            ring_next: p[7],
            x0: u(8),
            y0: u(10),
            side: u16::from(p[12]),
            n: u(13),
            depth: u(15),
        };
        let fits = (1..=SIDE as u16).contains(&c.side) && c.x0 + c.side <= c.n && c.y0 + c.side <= c.n;
        (fits && c.neighbours[c.ring_next as usize] != NONE && p[6] > c.ring_position).then_some(c)
    }

    /// Cell (x, y)'s index in the tile, if it is in the tile.
    fn slot(&self, x: i32, y: i32) -> Option<usize> {
        let (dx, dy) = (x - i32::from(self.x0), y - i32::from(self.y0));
        let s = i32::from(self.side);
        ((0..s).contains(&dx) && (0..s).contains(&dy)).then(|| (dy * s + dx) as usize)
    }

    /// The link towards the board holding cell (x, y) (not this one): along x first, then y.
    fn route(&self, x: i32, y: i32) -> Option<usize> {
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
        (self.neighbours[l] != NONE).then_some(l)
    }
}

/// Counters of the exercise.
#[derive(Default)]
struct State {
    sent: u32,
    received: u32,
    forwarded: u32,
    tokens: u32,
    late: u32,
    overflows: u32,
    misrouted: u32,
    loads: u32,
    steps: u32,
    peak_arrived: u32,
    peak_work: u32,
    refused: u32,
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

/// Phase bookkeeping: entering phase `p` = 1 (lighting) releases the initial beams.
fn entered(p: u16, emit: &mut Deque<BeamMsg<U0>, EMIT>, pending: &mut Deque<BeamMsg<U0>, EMIT>) {
    if p == 1 {
        while let Some(b) = pending.pop_front() {
            let _ = emit.push_back(b);
        }
    }
}

/// The cell a loading item is at: (x, y) of its cell (a pipeline packet: cell (0, y)).
fn at(l: &Load) -> (i32, i32) {
    match l {
        Load::Pipe(y, _) => (0, i32::from(*y)),
        Load::Row(x, y, _) => (i32::from(*x), i32::from(*y)),
    }
}

/// Wait for the light setup on the host link (the host sends it right after the
/// configuration), then run the exercise.
pub fn run(mut board: Board, c: Config) -> ! {
    // The neighbour links carry row and pipeline packets: lift the short exercises' frame
    // limit. They have carried nothing yet (nothing goes between boards before the start).
    for l in &mut board.links[1..] {
        *l = SerialLink::new(TIMEOUT_US);
    }
    let setup = loop {
        let now = board.now();
        board.poll(0, now);
        let Some(f) = board.links[0].received() else {
            board.wait();
            continue;
        };
        let s = (f.kind == KIND_TILE_LIGHT).then(|| light_setup(f.payload)).flatten();
        board.links[0].pop();
        if let Some(s) = s.filter(|s| s.n == u32::from(c.n) && s.depth == u32::from(c.depth)) {
            break s;
        }
    };
    tile(board, c, setup)
}

/// The light setup of a trace light record.
fn light_setup(bytes: &[u8]) -> Option<LightSetup> {
    let (raw, _) = read_frame(bytes).ok()?;
    if raw.kind != kind::LIGHT {
        return None;
    }
    let mut r = Reader::new(raw.payload);
    let s = trace::get_light_setup(&mut r, trace::read_frustum).ok()?;
    r.finish().ok()?;
    // The boards run without the whole-grid skips (as host-sim's async_tiles does).
    (s.frustum.is_none() && s.skip.is_none() && s.hold == 0).then_some(s)
}

/// The exercise proper.
fn tile(mut board: Board, c: Config, setup: LightSetup) -> ! {
    let order = SplitOrder::default();
    let Ok(env) = setup.env::<U0>(&order) else { panic!("light setup beyond the bit budget") };
    let far = env.far;
    let fa = env.fa;
    let side = i32::from(c.side);
    let mut slots: Vec<Slot, CELLS> = Vec::new();
    for i in 0..side * side {
        let (x, y) = (c.x0 + (i % side) as u16, c.y0 + (i / side) as u16);
        let _ = slots.push(Slot { cell: Cell::new(x, y), light: LightCell::new(x, y) });
    }
    let tally = ActivityDelta::new();
    let mut work: Deque<Load, WORK> = Deque::new();
    let mut host: Deque<PipelinePacket, HOST> = Deque::new();
    let mut out: [Deque<Msg, OUT>; LINKS] = core::array::from_fn(|_| Deque::new());
    let mut arrived: Deque<(usize, BeamMsg<U0>), ARRIVED> = Deque::new();
    let mut pending: Deque<BeamMsg<U0>, EMIT> = Deque::new();
    let mut emit: Deque<BeamMsg<U0>, EMIT> = Deque::new();
    let sv = setup.source.voxel();
    let source_slot = c.slot(sv[0], sv[1]);
    // The source's cell makes its six initial beams itself (§4.3), from the light setup every
    // board got; they go out once the board enters the lighting phase.
    if source_slot.is_some() {
        for b in Beam::initial_six(&setup.source, far) {
            let _ = pending.push_back(BeamMsg::new(b, sv[2] as u16));
        }
    }
    // Loading (0), lighting (1), and the empty phase (2) that tells every board of the
    // lighting's declaration.
    let mut node = Node::new(u16::from(c.ring_position), 2);
    let mut token: Option<Token> = None;
    let mut started = c.ring_position != 0;
    let mut st = State::default();
    let mut done_due: Deque<u16, 4> = Deque::new();
    let mut report_next: Option<usize> = None;
    let mut shade: Option<ShadeSetup> = None;
    let mut buf = [0u8; LINK_BUF];
    log!(
        "board {=u8}: tile of {=u16} x {=u16} cells at ({=u16}, {=u16}), ring position {=u8}, source here: {=bool}",
        c.id,
        c.side,
        c.side,
        c.x0,
        c.y0,
        c.ring_position,
        source_slot.is_some()
    );
    loop {
        let now = board.now();
        // 1. Neighbours: tokens and basic frames, each taken only when there is room.
        for l in 0..LINKS {
            if c.neighbours[l] == NONE {
                continue;
            }
            board.poll(l + 1, now);
            let Some(f) = board.links[l + 1].received() else { continue };
            if f.kind == KIND_TOKEN {
                if let Ok(t) = get_token(&mut Reader::new(f.payload)) {
                    if let Some(p) = node.token(t).entered {
                        log!(
                            "board {=u8}: entered phase {=u16} ({=u32} frames sent, {=u32} received)",
                            c.id,
                            p,
                            st.sent,
                            st.received
                        );
                        entered(p, &mut emit, &mut pending);
                    }
                }
                board.links[l + 1].pop();
                continue;
            }
            let Some(m) = decode(f.kind, f.payload, far) else {
                st.overflows += 1;
                board.links[l + 1].pop();
                continue;
            };
            let (x, y) = match &m {
                Msg::Load(ld) => at(ld),
                Msg::Beam(x, y, _) => (i32::from(*x), i32::from(*y)),
            };
            let took = match (c.slot(x, y), m) {
                (Some(_), Msg::Load(ld)) => {
                    st.late += u32::from(node.phase() >= 1);
                    work.push_back(ld).is_ok()
                }
                (Some(s), Msg::Beam(_, _, b)) => {
                    st.late += u32::from(node.phase() >= 2);
                    let ok = arrived.push_back((s, b)).is_ok();
                    st.peak_arrived = st.peak_arrived.max(arrived.len() as u32);
                    ok
                }
                (None, m) => match c.route(x, y) {
                    Some(to) => {
                        let ok = out[to].push_back(m).is_ok();
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
                let _ = node.received();
                st.received += 1;
                board.links[l + 1].pop();
            }
        }

        // 2. The host: facets, initial beams, start, query.
        board.poll(0, now);
        if let Some(f) = board.links[0].received() {
            let mut r = Reader::new(f.payload);
            match f.kind {
                KIND_PIPE => match (r.u16(), get_pipe(&mut r)) {
                    (Ok(0), Ok(p)) if c.slot(0, 0).is_some() => {
                        if host.push_back(p).is_err() {
                            st.overflows += 1;
                        }
                    }
                    _ => st.overflows += 1,
                },
                KIND_TILE_SHADE => match shade_setup(f.payload) {
                    Some(sh) => shade = Some(sh),
                    None => st.overflows += 1,
                },
                KIND_START => started = true,
                KIND_QUERY => {
                    log!(
                        "board {=u8}: report ({=u32} late, {=u32} overflows, {=u32} beams forwarded)",
                        c.id,
                        st.late,
                        st.overflows,
                        st.forwarded
                    );
                    report_next = Some(0)
                }
                _ => {}
            }
            board.links[0].pop();
        }
        if work.len() < WORK {
            if let Some(p) = host.pop_front() {
                let _ = work.push_back(Load::Pipe(0, p));
            }
        }

        // 3. Loading: every item one cell on, in order; stop while there is no room for what
        // an item may make (two items, or one outgoing frame).
        for _ in 0..work.len() {
            if work.len() + 2 > WORK || out.iter().any(|o| o.is_full()) {
                break;
            }
            let Some(item) = work.pop_front() else { break };
            st.loads += 1;
            st.late += u32::from(node.phase() >= 1);
            let next = match item {
                Load::Pipe(y, mut p) => {
                    let step = PipelineCell { y }.step(&mut p);
                    if let Some(rp) = step.east {
                        let _ = work.push_back(Load::Row(0, y, rp));
                    }
                    (step.down && y + 1 < c.n).then_some(Load::Pipe(y + 1, p))
                }
                Load::Row(x, y, mut rp) => {
                    let Some(s) = c.slot(i32::from(x), i32::from(y)) else {
                        st.misrouted += 1;
                        continue;
                    };
                    let forward = slots[s].cell.load_step(&mut rp, u32::from(c.depth));
                    (forward && x + 1 < c.n).then_some(Load::Row(x + 1, y, rp))
                }
            };
            if let Some(m) = next {
                let (x, y) = at(&m);
                if c.slot(x, y).is_some() {
                    let _ = work.push_back(m);
                } else if let Some(to) = c.route(x, y) {
                    let _ = out[to].push_back(Msg::Load(m));
                } else {
                    st.misrouted += 1;
                }
            }
            st.peak_work = st.peak_work.max(work.len() as u32);
        }

        // 4. Lighting: arrived beams into FIFOs with room, the next initial beam, a step of
        // every cell holding a beam, the output buffers' heads over their links.
        for _ in 0..arrived.len() {
            let Some((s, b)) = arrived.pop_front() else { break };
            let light = &mut slots[s].light;
            if light.can_accept(fa) {
                st.refused += u32::from(light.accept(b, setup.merge, &tally).is_err());
            } else {
                let _ = arrived.push_back((s, b));
            }
        }
        if let (Some(s), Some(&b)) = (source_slot, emit.front()) {
            let light = &mut slots[s].light;
            if light.can_accept(fa) {
                st.refused += u32::from(light.accept(b, setup.merge, &tally).is_err());
                emit.pop_front();
            }
        }
        for s in slots.iter_mut() {
            if !s.light.fifo.is_empty() {
                st.steps += 1;
                st.late += u32::from(node.phase() >= 2);
                s.light.step(&s.cell, &env, &tally);
            }
        }
        for i in 0..slots.len() {
            let (x, y) = (i32::from(slots[i].cell.x), i32::from(slots[i].cell.y));
            for p in Port::ALL {
                let Some(&b) = slots[i].light.out.front(p) else { continue };
                let (dx, dy) = p.delta();
                let (tx, ty) = (x + i32::from(dx), y + i32::from(dy));
                let taken = match c.slot(tx, ty) {
                    Some(j) => {
                        let light = &mut slots[j].light;
                        let ok = light.can_accept(fa);
                        if ok {
                            st.refused += u32::from(light.accept(b, setup.merge, &tally).is_err());
                        }
                        ok
                    }
                    None => match c.route(tx, ty) {
                        Some(to) => out[to].push_back(Msg::Beam(tx as u16, ty as u16, b)).is_ok(),
                        None => {
                            st.misrouted += 1;
                            true
                        }
                    },
                };
                if taken {
                    slots[i].light.out.pop_front(p);
                }
            }
        }

        // 5. Send: the token first, then the queued frames (counted when the link takes them).
        for (l, (link, out)) in board.links[1..].iter_mut().zip(&mut out).enumerate() {
            if c.neighbours[l] == NONE || !link.can_send() {
                continue;
            }
            if let (true, Some(t)) = (l == c.ring_next as usize, token) {
                if send_token(link, &t) {
                    token = None;
                    st.tokens += 1;
                }
            } else if let Some(m) = out.front() {
                match encode(m, &mut buf) {
                    Some((k, n)) if link.send(k, &buf[..n]).is_ok() => {
                        let _ = node.sent();
                        st.sent += 1;
                    }
                    Some(_) => continue,
                    None => st.overflows += 1,
                }
                out.pop_front();
            }
        }

        // 6. Termination: the node acts on the token only when the board is passive.
        let passive = host.is_empty()
            && work.is_empty()
            && arrived.is_empty()
            && emit.is_empty()
            && out.iter().all(|o| o.is_empty())
            && slots.iter().all(|s| !s.light.busy());
        if started && token.is_none() {
            match node.poll(passive) {
                Ok(Action::Forward(t)) => token = Some(t),
                Ok(Action::Declare(p)) => {
                    log!("board {=u8}: declared the end of phase {=u16}", c.id, p);
                    let _ = done_due.push_back(p);
                    entered(node.phase(), &mut emit, &mut pending);
                }
                _ => {}
            }
        }

        // 7. Answers to the host: declarations, then the report.
        if board.links[0].can_send() {
            if let Some(p) = done_due.pop_front() {
                let _ = board.links[0].send(KIND_DONE, &p.to_le_bytes());
            } else if let Some(i) = report_next {
                let n = if i < slots.len() {
                    cell_report(&slots[i], setup.rule, shade.as_ref(), &mut buf)
                } else {
                    state_report(&c, &st, &node, &board, &mut buf)
                };
                let kind = if i < slots.len() { KIND_TILE_CELL } else { KIND_TILE_STATE };
                if board.links[0].send(kind, &buf[..n]).is_ok() {
                    report_next = (i < slots.len()).then_some(i + 1);
                }
            }
        }
        if passive && done_due.is_empty() && report_next.is_none() {
            board.wait();
        }
    }
}

/// The shading inputs of a trace shading record.
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

/// A [`KIND_TILE_STATE`] body into `buf`; returns its length.
fn state_report(c: &Config, st: &State, node: &Node, board: &Board, buf: &mut [u8]) -> usize {
    let (mut retransmitted, mut skipped) = (0, 0);
    for l in &board.links[1..] {
        retransmitted += l.stats().retransmitted;
        skipped += l.stats().skipped;
    }
    let mut w = SliceWriter::new(buf);
    let _ = w.u8(c.id);
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
        stack::peak() as u32,
    ] {
        let _ = w.u32(v);
    }
    let _ = w.i32(node.count());
    w.len()
}
