//! The boards' logic on the host, without QEMU: `boards::tiles::TileBoard` and
//! `boards::safra::SafraBoard` (the state machines the firmware's `board` image drives) on
//! in-memory links whose delivery schedule each test chooses ([`Net`]: one queue of frames
//! per direction of each wire, a wire held back as long as a test likes), or, for the bytes
//! below the frames, on `cell_core::serial::SerialLink`s over in-memory byte pipes.
//!
//! Oracles, never the boards' own figures: host-sim's `machine::lighting::boards` for the cells'
//! dexels, lit voxels and pixels (the same case as the QEMU test, [`super::mcu_tiles`]); the
//! grid's coordinates for where a beam must go; the item counts of a workload from its shape
//! (t + 1 items for a chain of ttl t); and, for termination, the net's ground truth — at every
//! declaration no frame may be in flight on any wire and every board must be passive — which
//! the boards never read. The counterless mutant (`without_counters`: no `Node::sent` /
//! `Node::received`) runs the same schedules and must break that ground truth, so the tests
//! are shown to catch an early declaration.

use std::collections::{BTreeMap, HashMap, VecDeque};

use boards::safra::{item_bytes, SafraBoard};
use boards::tiles::{beam_body, light_setup, TileBoard, SOURCES};
use boards::{Event, Events, Links};
use cell_core::beam::frac::U0;
use cell_core::beam::{Beam, FarDistance, SplitOrder};
use cell_core::light::{BeamMsg, LightEnv};
use cell_core::serial::SerialLink;
use cell_core::trace::LightSetup;
use cell_core::wire::board::{
    KIND_PIPE, KIND_QUERY, KIND_START, KIND_TERM_CONFIG, KIND_TILE_BEAM, KIND_TILE_CELL, KIND_TILE_CONFIG,
    KIND_TILE_STATE, KIND_WORK,
};
use cell_core::wire::{put_pipe, PutExt, RawFrame, SliceWriter};
use rc2_tests::boards::{neighbour, ring_config, RING, SIDE};

use super::mcu_tiles::{board_of, parse_cell, parse_state, the_case, BoardState, Case, CellView, N};

/// A frame: kind and body.
type Frame = (u8, Vec<u8>);

/// One direction of a wire between two boards.
#[derive(Default)]
struct Wire {
    /// Frames handed to the wire, oldest first (the head is the far end's `received`).
    frames: VecDeque<Frame>,
    /// Held back: the far end sees nothing until the test lets go.
    held: bool,
    /// A delay line: the wire takes every frame at once (a `SerialLink` takes one at a time,
    /// until the far end has it).
    buffered: bool,
}

/// The 2 × 2 grid of boards' wires (`rc2_tests::boards::neighbour`: links E, N, W, S) and
/// every board's host link.
struct Net {
    wires: HashMap<(usize, usize), Wire>,
    /// Frames from the host to each board, one delivered at a time.
    host_in: Vec<VecDeque<Frame>>,
    /// Frames each board sent its host.
    host_out: Vec<Vec<Frame>>,
}

impl Net {
    fn new() -> Net {
        let mut wires = HashMap::new();
        for b in 0..SIDE * SIDE {
            for l in 0..4 {
                if let Some(n) = neighbour(b, l) {
                    wires.insert((b, n), Wire::default());
                }
            }
        }
        let boards = SIDE * SIDE;
        Net { wires, host_in: vec![VecDeque::new(); boards], host_out: vec![Vec::new(); boards] }
    }

    fn wire(&mut self, from: usize, to: usize) -> &mut Wire {
        self.wires.get_mut(&(from, to)).expect("a wire between neighbours")
    }

    /// Basic or token frames on any wire (the ground truth the boards never read).
    fn in_flight(&self) -> usize {
        self.wires.values().map(|w| w.frames.len()).sum()
    }

    /// Board `b`'s links.
    fn port(&mut self, b: usize) -> Port<'_> {
        Port { net: self, b }
    }
}

/// Board `b`'s view of the [`Net`]: its [`Links`].
struct Port<'a> {
    net: &'a mut Net,
    b: usize,
}

impl Port<'_> {
    /// The wire into this board on link `l` (1 … 4), if `l` has a neighbour.
    fn inbound(&self, l: usize) -> Option<&Wire> {
        neighbour(self.b, l - 1).map(|n| &self.net.wires[&(n, self.b)])
    }
}

impl Links for Port<'_> {
    fn received(&self, l: usize) -> Option<RawFrame<'_>> {
        let f = match l {
            0 => self.net.host_in[self.b].front(),
            _ => self.inbound(l).filter(|w| !w.held).and_then(|w| w.frames.front()),
        }?;
        Some(RawFrame { kind: f.0, payload: &f.1 })
    }
    fn pop(&mut self, l: usize) {
        let b = self.b;
        match l {
            0 => self.net.host_in[b].pop_front(),
            _ => {
                let n = neighbour(b, l - 1).expect("a neighbour");
                self.net.wire(n, b).frames.pop_front()
            }
        };
    }
    fn can_send(&self, l: usize) -> bool {
        l == 0
            || neighbour(self.b, l - 1).is_some_and(|n| {
                self.net.wires[&(self.b, n)].buffered || self.net.wires[&(self.b, n)].frames.is_empty()
            })
    }
    fn send(&mut self, l: usize, kind: u8, body: &[u8]) -> bool {
        if !self.can_send(l) {
            return false;
        }
        let b = self.b;
        match l {
            0 => self.net.host_out[b].push((kind, body.to_vec())),
            _ => {
                let n = neighbour(b, l - 1).expect("a neighbour");
                self.net.wire(b, n).frames.push_back((kind, body.to_vec()));
            }
        }
        true
    }
}

/// The ring as the boards are configured: ring position i is board `RING[i]`.
const INITIATOR: usize = RING[0];

// ---------------------------------------------------------------------------------------------
// Safra's termination exercise.

/// Board `b`'s termination configuration: `ring_config`, then work time and fan-out.
fn safra_config(b: usize, work_us: u16, fan_out: u8) -> boards::safra::Config {
    let mut p = ring_config(b);
    p.extend(work_us.to_le_bytes());
    p.push(fan_out);
    boards::safra::Config::parse(KIND_TERM_CONFIG, &p).expect("a termination configuration")
}

/// What a termination run saw: per declaration, (phase, frames in flight, boards active) by
/// the ground truth at that moment; the boards at the end.
struct SafraRun {
    declarations: Vec<(u16, usize, usize)>,
    boards: Vec<SafraBoard>,
}

/// Four termination boards: inject `items` ((board, ttl, id)), start the ring, and poll every
/// board in turn, time advancing by 1 per pass, until phase 1 is declared or `passes` run out;
/// `schedule(pass, net, boards)` runs before each pass (it holds and releases wires).
fn safra_run(
    items: &[(usize, u8, u32)],
    work_us: u16,
    fan_out: u8,
    counters: bool,
    passes: u64,
    mut schedule: impl FnMut(u64, &mut Net, &[SafraBoard]),
) -> SafraRun {
    let mut net = Net::new();
    let mut boards: Vec<SafraBoard> = (0..SIDE * SIDE)
        .map(|b| {
            let s = SafraBoard::new(safra_config(b, work_us, fan_out));
            if counters {
                s
            } else {
                s.without_counters()
            }
        })
        .collect();
    for &(b, ttl, id) in items {
        net.host_in[b].push_back((KIND_WORK, item_bytes((ttl, id)).to_vec()));
    }
    // The host's items are all taken before the start (they are not basic messages).
    for now in 0..items.len() as u64 {
        schedule(now, &mut net, &boards);
        for (b, board) in boards.iter_mut().enumerate() {
            board.poll(&mut net.port(b), now);
        }
    }
    assert!(net.host_in.iter().all(|q| q.is_empty()), "every item injected");
    net.host_in[INITIATOR].push_back((KIND_START, Vec::new()));
    let mut declarations = Vec::new();
    for now in items.len() as u64..passes {
        schedule(now, &mut net, &boards);
        for b in 0..boards.len() {
            let events = boards[b].poll(&mut net.port(b), now);
            for e in events {
                if let Event::Declared(p) = e {
                    let active = boards.iter().filter(|s| !s.passive()).count();
                    declarations.push((p, net.in_flight(), active));
                }
            }
        }
        // Until phase 1 is declared and (for a mutant that declared early) the net drained.
        if declarations.iter().any(|d| d.0 == 1) && net.in_flight() == 0 {
            break;
        }
    }
    SafraRun { declarations, boards }
}

/// Items processed in all, from the workload's shape: an item of ttl t makes t + 1 (one child
/// each) or 2^(t+1) − 1 (two).
fn total(items: &[(usize, u8, u32)], fan_out: u8) -> u32 {
    items.iter().map(|&(_, t, _)| if fan_out == 1 { u32::from(t) + 1 } else { (2u32 << t) - 1 }).sum()
}

#[test]
fn safra_declares_once_every_item_is_processed_and_none_in_flight() {
    for (items, fan_out) in [(&[(3, 11, 0)][..], 1), (&[(0, 5, 0), (3, 4, 9), (1, 0, 2)][..], 2)] {
        let r = safra_run(items, 3, fan_out, true, 100_000, |_, _, _| {});
        let processed: u32 = r.boards.iter().map(|b| b.state().processed).sum();
        assert_eq!(processed, total(items, fan_out), "{items:?}");
        assert_eq!(r.declarations.iter().map(|d| d.0).collect::<Vec<_>>(), [0, 1], "{items:?}: each phase once");
        for &(p, in_flight, active) in &r.declarations {
            assert_eq!((in_flight, active), (0, 0), "{items:?}: phase {p} declared with work left");
        }
        let sent: u32 = r.boards.iter().map(|b| b.state().sent).sum();
        let received: u32 = r.boards.iter().map(|b| b.state().received).sum();
        assert_eq!(sent, received);
        assert!(sent > 0, "{items:?}: work crossed boards");
        assert!(r.boards.iter().all(|b| b.state().late == 0), "{items:?}: no late work");
        assert_eq!(r.boards.iter().map(|b| b.node().count()).sum::<i32>(), 0, "{items:?}: the counters' sum");
    }
}

#[test]
fn safra_never_declares_early_under_random_wire_delays() {
    // Every pass, each wire is held or not at random (a seeded xorshift): messages and tokens
    // overtake each other in every way the links allow; trees of work, 3 time units each.
    // (Random delays seldom let a whole round pass a message: the counterless mutant passes
    // this test too, checked by hand; the explicit late-wire schedules below catch it.)
    let items = [(0, 6, 0), (3, 5, 1), (1, 4, 7)];
    for seed in 1..=20u64 {
        let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let r = safra_run(&items, 3, 2, true, 1_000_000, |_, net, _| {
            for w in net.wires.values_mut() {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                w.held = x % 4 != 0;
            }
        });
        let processed: u32 = r.boards.iter().map(|b| b.state().processed).sum();
        assert_eq!(processed, total(&items, 2), "seed {seed}");
        assert_eq!(r.declarations.iter().map(|d| d.0).collect::<Vec<_>>(), [0, 1], "seed {seed}");
        for &(p, in_flight, active) in &r.declarations {
            assert_eq!((in_flight, active), (0, 0), "seed {seed}: phase {p} declared with work left");
        }
        assert!(r.boards.iter().all(|b| b.state().late == 0), "seed {seed}: no late work");
    }
}

#[test]
fn an_item_keeps_its_board_active_for_its_work_time() {
    // One board of the ring, alone on its links: an item of ttl 0 injected at time 0 with a
    // work time of 100 is processed by the first poll at or after time 100, not before.
    let mut net = Net::new();
    let mut b = SafraBoard::new(safra_config(1, 100, 1));
    net.host_in[1].push_back((KIND_WORK, item_bytes((0, 7)).to_vec()));
    for now in [0, 1, 50, 99] {
        b.poll(&mut net.port(1), now);
        assert!(!b.passive() && !b.idle() && b.state().processed == 0, "busy at {now}");
    }
    b.poll(&mut net.port(1), 100);
    assert_eq!((b.state().processed, b.state().injected), (1, 1));
    assert!(b.passive() && b.idle());
}

/// The late-wire schedule: a chain of two items from board 2, whose child (id 2: link E, see
/// `SafraBoard`'s child routing) goes to board 3 on wire 2 → 3, which runs against the ring
/// (0 → 1 → 3 → 2 → 0): while that wire holds it, the token goes round every other link,
/// and finds every board passive.
fn late_wire(counters: bool) -> SafraRun {
    let mut released = false;
    safra_run(&[(2, 1, 1)], 0, 1, counters, 5_000, move |pass, net, boards| {
        let w = net.wire(2, 3);
        w.buffered = true;
        // Held from the start; let go after 2000 passes, long after every board went passive.
        w.held = !released;
        if !released && pass >= 2_000 && boards.iter().all(|b| b.passive()) {
            assert_eq!(w.frames.len(), 1, "the child is on the wire");
            released = true;
        }
    })
}

#[test]
fn safra_waits_for_work_a_late_wire_holds_while_the_token_overtakes_it() {
    let r = late_wire(true);
    assert_eq!(r.declarations.iter().map(|d| d.0).collect::<Vec<_>>(), [0, 1]);
    for &(p, in_flight, active) in &r.declarations {
        assert_eq!((in_flight, active), (0, 0), "phase {p} declared early");
    }
    assert_eq!(r.boards.iter().map(|b| b.state().processed).collect::<Vec<_>>(), [0, 0, 1, 1]);
    assert!(r.boards.iter().all(|b| b.state().late == 0));
    // The token went round many times meanwhile (it did overtake the item).
    assert!(r.boards[1].state().forwarded > 10, "{:?}", r.boards[1].state());
}

#[test]
fn the_counterless_mutant_declares_while_the_late_wire_holds_work() {
    let r = late_wire(false);
    let (p, in_flight, _) = r.declarations[0];
    assert_eq!(p, 0);
    assert_eq!(in_flight, 1, "the mutant declared the work's end with the item still on wire 2 → 3");
    // The item arrives after the news: board 3 sees it late.
    assert!(r.boards[3].state().late > 0, "{:?}", r.boards[3].state());
}

// ---------------------------------------------------------------------------------------------
// A partial frame and a restarted end, below the frames: serial links over in-memory bytes.

/// One direction of bytes.
#[derive(Default)]
struct Bytes(VecDeque<u8>);

/// One end of a byte pipe: reads `rx`, writes `tx`.
struct End<'a> {
    rx: &'a mut Bytes,
    tx: &'a mut Bytes,
}

impl embedded_io::ErrorType for End<'_> {
    type Error = core::convert::Infallible;
}
impl embedded_io::Read for End<'_> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let n = buf.len().min(self.rx.0.len());
        for b in &mut buf[..n] {
            *b = self.rx.0.pop_front().unwrap_or(0);
        }
        Ok(n)
    }
}
impl embedded_io::ReadReady for End<'_> {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(!self.rx.0.is_empty())
    }
}
impl embedded_io::Write for End<'_> {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.tx.0.extend(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}
impl embedded_io::WriteReady for End<'_> {
    fn write_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(true)
    }
}

#[test]
fn a_partial_frame_from_a_restarted_host_end_is_dropped_and_the_next_taken_once() {
    const TIMEOUT: u64 = 10;
    const BUF: usize = 320;
    // Board 1 of the ring (links E none, N board 3, W board 0), its host link over bytes.
    let mut board = SafraBoard::new(safra_config(1, 0, 1));
    let mut links: [SerialLink<BUF>; 5] = core::array::from_fn(|_| SerialLink::new(TIMEOUT));
    let (mut to_board, mut to_host) = (Bytes::default(), Bytes::default());
    // The host's end sends an item, but only the first half of its bytes reaches the wire
    // before that end restarts (a new link, its sequence numbers from the start again).
    let mut host: SerialLink<BUF> = SerialLink::new(TIMEOUT);
    assert!(host.send(KIND_WORK, &item_bytes((0, 5))).is_ok());
    let _ = host.poll(0, &mut End { rx: &mut to_host, tx: &mut to_board });
    let whole = to_board.0.len();
    to_board.0.truncate(whole / 2);
    let mut now = 0;
    let pass = |now: u64, board: &mut SafraBoard, links: &mut [SerialLink<BUF>; 5], tb: &mut Bytes, th: &mut Bytes| {
        let _ = links[0].poll(now, &mut End { rx: tb, tx: th });
        board.poll(links, now)
    };
    for _ in 0..5 {
        pass(now, &mut board, &mut links, &mut to_board, &mut to_host);
        now += 1;
    }
    assert_eq!(board.state().injected, 0, "half a frame is no frame");
    // The restarted end sends the item again, whole.
    let mut host: SerialLink<BUF> = SerialLink::new(TIMEOUT);
    assert!(host.send(KIND_WORK, &item_bytes((0, 5))).is_ok());
    for _ in 0..20 * TIMEOUT {
        let _ = host.poll(now, &mut End { rx: &mut to_host, tx: &mut to_board });
        pass(now, &mut board, &mut links, &mut to_board, &mut to_host);
        now += 1;
    }
    assert!(host.can_send(), "the host's item was acknowledged");
    assert_eq!((board.state().injected, board.state().processed), (1, 1), "taken once, processed once");
    assert!(links[0].stats().skipped > 0, "the partial frame's bytes were skipped");
    assert_eq!(board.state().overflows, 0);
}

// ---------------------------------------------------------------------------------------------
// The tile exercise.

/// Board `b`'s tile configuration, as the QEMU test sends it.
fn tile_config(b: usize, depth: u32) -> boards::tiles::Config {
    let sources = the_case().sources();
    boards::tiles::Config::parse(KIND_TILE_CONFIG, &super::mcu_tiles::tile_config(b, depth, sources))
        .expect("a tile configuration")
}

#[test]
fn a_beam_is_routed_along_x_then_y_to_the_board_of_its_cell() {
    // For every board and every cell of the grid, following `route` link by link from the
    // board reaches the cell's board, first along x then along y, in as many hops as their
    // board coordinates differ (a diagonal neighbour: two, through the side neighbour along x).
    let depth = 8;
    let configs: Vec<_> = (0..SIDE * SIDE).map(|b| tile_config(b, depth)).collect();
    for b in 0..SIDE * SIDE {
        for (x, y) in (0..N as i32).flat_map(|x| (0..N as i32).map(move |y| (x, y))) {
            let target = board_of(x as u32, y as u32);
            let (mut at, mut path) = (b, Vec::new());
            while configs[at].slot(x, y).is_none() {
                let l = configs[at].route(x, y).expect("a link towards the cell");
                path.push(l);
                at = neighbour(at, l).expect("the link has a neighbour");
                assert!(path.len() <= 2, "board {b} to cell ({x}, {y}): {path:?}");
            }
            assert_eq!(at, target, "board {b} to cell ({x}, {y})");
            let (bx, by, tx, ty) = (b % SIDE, b / SIDE, target % SIDE, target / SIDE);
            let mut expected = Vec::new();
            if tx != bx {
                expected.push(if tx > bx { 0 } else { 2 });
            }
            if ty != by {
                expected.push(if ty > by { 1 } else { 3 });
            }
            assert_eq!(path, expected, "board {b} to cell ({x}, {y})");
        }
    }
}

/// The case's light setups, one per source (what the firmware's glue reads off the host link);
/// `visible_only`: under `render`'s visible-only lit store.
fn light_setups(c: &Case, visible_only: bool) -> Vec<LightSetup> {
    c.records(visible_only).iter().map(|r| light_setup(r).expect("the case's light setup")).collect()
}

/// Every source's lighting environment, for a board.
fn envs<'s>(setups: &'s [LightSetup], order: &'s SplitOrder) -> heapless::Vec<LightEnv<'s, U0>, SOURCES> {
    setups.iter().map(|s| s.env(order).expect("an environment")).collect()
}

/// The phases a tile run declares: loading, one lighting per source, the news.
fn phases(c: &Case) -> Vec<u16> {
    (0..c.sources() as u16 + 2).collect()
}

/// A beam of the case's source for cell `at` (any beam: the board only moves it).
fn some_beam(setup: &LightSetup) -> BeamMsg<U0> {
    let far = FarDistance::<U0>::new(setup.far).expect("a far distance");
    BeamMsg::new(Beam::initial_six(&setup.source, far)[0], 3)
}

#[test]
fn a_beam_for_a_diagonal_board_is_forwarded_by_the_side_neighbour() {
    let c = the_case();
    let setups = light_setups(c, false);
    let setup = &setups[0];
    let order = SplitOrder::default();
    // Board 1 holds cells x 4 … 7, y 0 … 3; board 0 sends it (on its link W) a beam for cell
    // (4, 4), board 3's, diagonal to board 0's corner cell (3, 3).
    let mut net = Net::new();
    let mut b1 = TileBoard::new(tile_config(1, c.depth), envs(&setups, &order));
    let mut body = [0u8; 64];
    let n = beam_body(4, 4, &some_beam(setup), &mut body).expect("a beam frame");
    net.wire(0, 1).frames.push_back((KIND_TILE_BEAM, body[..n].to_vec()));
    b1.poll(&mut net.port(1));
    b1.poll(&mut net.port(1));
    // Taken off the wire from board 0, sent unchanged on the wire to board 3 (link N).
    assert!(net.wire(0, 1).frames.is_empty());
    assert_eq!(net.wire(1, 3).frames, [(KIND_TILE_BEAM, body[..n].to_vec())]);
    assert!(net.wire(1, 0).frames.is_empty());
    let st = b1.state();
    assert_eq!((st.received, st.sent, st.forwarded, st.steps, st.misrouted), (1, 1, 1, 0, 0));
    assert_eq!(b1.node().count(), 0, "received once and sent once: the counter is even");
    assert!(b1.passive(), "a forwarded beam leaves nothing behind");
}

/// What a tile run saw: per declaration (phase, frames in flight, boards active by the ground
/// truth); every cell's report; every board's state report.
struct TileRun {
    declarations: Vec<(u16, usize, usize)>,
    cells: BTreeMap<(u16, u16), CellView>,
    states: Vec<(u8, BoardState)>,
    /// Cells whose report has a non-zero overflow or busy counter.
    busy: Vec<((u16, u16), [u32; 4])>,
    events: Vec<Vec<Event>>,
}

/// The QEMU test's run on in-memory links: configure every board, hand board 0 the facets,
/// start the ring, poll every board in turn until three declarations (or `passes` run out),
/// then query every board. `schedule(pass, net, boards)` runs before each pass; `visible_only`:
/// the light records ask for `render`'s visible-only lit store.
fn tile_run(
    counters: bool,
    visible_only: bool,
    passes: usize,
    mut schedule: impl FnMut(usize, &mut Net, &[TileBoard]),
) -> TileRun {
    let c = the_case();
    let setups = light_setups(c, visible_only);
    let order = SplitOrder::default();
    let mut net = Net::new();
    let mut boards: Vec<TileBoard> = (0..SIDE * SIDE)
        .map(|b| {
            let t = TileBoard::new(tile_config(b, c.depth), envs(&setups, &order));
            if counters {
                t
            } else {
                t.without_counters()
            }
        })
        .collect();
    for b in 0..SIDE * SIDE {
        net.host_in[b].extend(c.host_frames(b).iter().cloned());
    }
    for p in &c.packets {
        let mut buf = [0u8; 512];
        let mut w = SliceWriter::new(&mut buf);
        w.u16(0).unwrap();
        put_pipe(&mut w, p).unwrap();
        net.host_in[board_of(0, 0)].push_back((KIND_PIPE, w.written().to_vec()));
    }
    let mut events: Vec<Vec<Event>> = vec![Vec::new(); SIDE * SIDE];
    let mut poll_all = |net: &mut Net, boards: &mut [TileBoard], declarations: &mut Vec<(u16, usize, usize)>| {
        for b in 0..boards.len() {
            let ev: Events = boards[b].poll(&mut net.port(b));
            for e in ev {
                if let Event::Declared(p) = e {
                    let active = boards.iter().filter(|s| !s.passive()).count();
                    declarations.push((p, net.in_flight(), active));
                }
                events[b].push(e);
            }
        }
    };
    let mut declarations = Vec::new();
    // The host's frames are all taken before the start (they are not basic messages).
    while net.host_in.iter().any(|q| !q.is_empty()) {
        poll_all(&mut net, &mut boards, &mut declarations);
    }
    net.host_in[INITIATOR].push_back((KIND_START, Vec::new()));
    for pass in 0..passes {
        schedule(pass, &mut net, &boards);
        poll_all(&mut net, &mut boards, &mut declarations);
        if declarations.len() == c.sources() + 2 {
            break;
        }
    }
    // Whatever is left (a mutant's late beams) delivered and worked off, then the reports.
    for w in net.wires.values_mut() {
        w.held = false;
    }
    for _ in 0..passes {
        if net.in_flight() == 0 && boards.iter().all(|b| b.passive()) {
            break;
        }
        poll_all(&mut net, &mut boards, &mut declarations);
    }
    for q in &mut net.host_in {
        q.push_back((KIND_QUERY, Vec::new()));
    }
    for _ in 0..200 {
        poll_all(&mut net, &mut boards, &mut declarations);
    }
    let (mut cells, mut states, mut busy) = (BTreeMap::new(), Vec::new(), Vec::new());
    for out in &net.host_out {
        for (kind, body) in out {
            match *kind {
                KIND_TILE_CELL => {
                    let (xy, view, counters) = parse_cell(body);
                    if counters != [0; 4] {
                        busy.push((xy, counters));
                    }
                    cells.insert(xy, view);
                }
                KIND_TILE_STATE => states.push(parse_state(body)),
                _ => {}
            }
        }
    }
    TileRun { declarations, cells, states, busy, events }
}

#[test]
fn in_memory_boards_load_and_light_the_cells_as_host_sim_does() {
    let c = the_case();
    let r = tile_run(true, false, 200_000, |_, _, _| {});
    assert_eq!(r.declarations.iter().map(|d| d.0).collect::<Vec<_>>(), phases(c));
    for &(p, in_flight, active) in &r.declarations {
        assert_eq!((in_flight, active), (0, 0), "phase {p} declared with work left");
    }
    assert_eq!(r.cells, c.cells, "every cell's dexels, lit voxels and pixel are host-sim's");
    let sum = |f: fn(&BoardState) -> u32| r.states.iter().map(|(_, s)| f(s)).sum::<u32>();
    assert_eq!(sum(|s| s.sent), sum(|s| s.received));
    assert!(sum(|s| s.forwarded) > 0, "a beam crossed a board corner");
    for (b, s) in &r.states {
        assert_eq!((s.late, s.overflows, s.misrouted), (0, 0, 0), "board {b}: late, overflows, misrouted");
    }
    assert_eq!(r.states.iter().map(|(_, s)| s.count).sum::<i32>(), 0, "the counters' sum");
    assert!(r.busy.is_empty(), "cells still busy or overflowed: {:?}", r.busy);
    // Every board heard of phases 1 and 2 (ring position 0 by declaring them).
    for (b, ev) in r.events.iter().enumerate() {
        let want: Vec<Event> = match b == INITIATOR {
            true => phases(c).into_iter().map(Event::Declared).chain([Event::Queried]).collect(),
            false => phases(c).into_iter().skip(1).map(Event::Entered).chain([Event::Queried]).collect(),
        };
        assert_eq!(ev, &want, "board {b}");
    }
}

/// `render`'s own cell on the boards: light records asking for the visible-only lit store give
/// every cell host-sim's lit marks under that store (only each pixel's target voxel), which are
/// not the full store's, and the same pixels.
#[test]
fn in_memory_boards_keep_render_s_visible_only_lit_store() {
    let c = the_case();
    let r = tile_run(true, true, 200_000, |_, _, _| {});
    assert_eq!(r.declarations.iter().map(|d| d.0).collect::<Vec<_>>(), phases(c));
    assert!(r.busy.is_empty(), "cells still busy or overflowed: {:?}", r.busy);
    assert_eq!(&r.cells, c.expected(true), "every cell's dexels, visible-only lit marks and pixel are host-sim's");
    assert_ne!(&r.cells, c.expected(false), "the visible-only store is not the full one");
}

/// The QEMU late-wire run's schedule, made explicit: the source's board (2) sends board 3 its
/// beams on wire 2 → 3, against the ring, and that wire (a delay line here: it takes every
/// frame) holds them from the lighting phase on until every board has been passive for 2000
/// passes; the token's way round 2 → 0 → 1 → 3 never uses it.
fn tile_late_wire(counters: bool) -> (TileRun, bool) {
    assert_eq!(the_case().source_board(), 2, "the light is on board 2");
    let mut quiet = 0;
    let released = std::cell::Cell::new(false);
    let r = tile_run(counters, false, 200_000, |_, net, boards| {
        let w = net.wire(2, 3);
        w.buffered = true;
        let lighting = boards[2].node().phase() >= 1;
        w.held = lighting && !released.get();
        quiet = if boards.iter().all(|b| b.passive()) { quiet + 1 } else { 0 };
        if lighting && !w.frames.is_empty() && quiet >= 2_000 {
            released.set(true);
        }
    });
    (r, released.get())
}

#[test]
fn the_ring_waits_for_beams_a_late_wire_holds_and_the_counterless_mutant_does_not() {
    let c = the_case();
    let (r, released) = tile_late_wire(true);
    assert!(released, "beams were held on wire 2 → 3 while every board was passive");
    assert_eq!(r.declarations.iter().map(|d| d.0).collect::<Vec<_>>(), phases(c));
    for &(p, in_flight, active) in &r.declarations {
        assert_eq!((in_flight, active), (0, 0), "phase {p} declared with work left");
    }
    assert_eq!(r.cells, c.cells, "the lit set does not depend on the schedule");
    assert!(r.states.iter().all(|(_, s)| s.late == 0), "no late work");
    assert!(r.busy.is_empty(), "cells still busy or overflowed: {:?}", r.busy);

    let (m, _) = tile_late_wire(false);
    let early: Vec<_> = m.declarations.iter().filter(|d| d.1 > 0 || d.2 > 0).collect();
    assert!(
        early.iter().any(|d| d.0 == 1),
        "the mutant declared the lighting with beams held on wire 2 → 3: {:?}",
        m.declarations
    );
    let late: u32 = m.states.iter().map(|(_, s)| s.late).sum();
    assert!(late > 0, "the held beams arrived after the declaration: late work");
}
