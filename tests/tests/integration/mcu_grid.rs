//! A grid of microcontrollers on real serial links: 2 × 2 emulated Cortex-M4F boards (four
//! QEMU `mps2-an386` processes running `firmware/src/bin/board`), each UART a TCP character
//! device to a port this test listens on. The test relays the bytes between neighbouring
//! boards' UARTs (E ↔ W, N ↔ S), in the fault runs corrupting and dropping bytes on the
//! wire from a seeded generator, in the slow run delaying one board's bytes, and talks to
//! each board's host link (UART 0) itself, through the same `cell_core::serial::SerialLink`
//! the boards run.
//!
//! * **Link exercise**: each board sends [`COUNT`] data frames on each of its links and checks
//!   the frames it receives against what its neighbour sent, in order; its report must say
//!   every frame arrived exactly once, unaltered, and every one it sent was acknowledged.
//! * **Termination exercise** (`firmware/src/bin/board/safra.rs`): the host injects work items
//!   that spread over the boards as messages on the links; the boards detect the end of the
//!   work themselves with Safra's token ring over the same links, and ring position 0 tells
//!   the host. At the declaration every item must have been processed, none queued or in
//!   flight, and no board may see work after it learned of the declaration (never early);
//!   the declaration must come (never hanging).
//!
//! A board that does not answer within [`GRID_TIMEOUT`] fails the test, with every board's
//! QEMU output; every QEMU child is killed on every exit path.
//!
//! The tiles of cells (loading and lighting a scene) are in `mcu_tiles.rs`; the QEMU processes,
//! relays and host links of both are in `rc2_tests::boards`.
//!
//! Needs `qemu-system-arm` and the `thumbv7em-none-eabihf` target: under CI a missing tool is
//! a failure, elsewhere a skip ([`rc2_tests::qemu::tools_present`]).

use std::path::Path;
use std::time::{Duration, Instant};

use cell_core::wire::board::{KIND_CONFIG, KIND_REPORT, KIND_STATE, KIND_TERM_CONFIG, KIND_WORK};
use rc2_tests::boards::{
    board_config, board_elf, boot, neighbour, ring_config, Booted, Faults, Slow, CLEAN, KIND_QUERY, SIDE,
};
use rc2_tests::qemu;

/// Data frames each board sends on each of its links.
const COUNT: u16 = 120;
/// The whole run (boot, exercise, reports) must end within this.
const GRID_TIMEOUT: Duration = Duration::from_secs(60);

/// One link of a board's report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct LinkReport {
    received: u16,
    mismatches: u16,
    sent: u32,
    acked: u32,
    retransmitted: u32,
    duplicates: u32,
    skipped: u32,
    overruns: u32,
}

fn parse_report(p: &[u8]) -> (u8, [LinkReport; 4]) {
    assert_eq!(p.len(), 1 + 4 * 28, "report length");
    let u16_at = |i: usize| u16::from_le_bytes([p[i], p[i + 1]]);
    let u32_at = |i: usize| u32::from_le_bytes(p[i..i + 4].try_into().unwrap());
    let links = std::array::from_fn(|l| {
        let o = 1 + 28 * l;
        LinkReport {
            received: u16_at(o),
            mismatches: u16_at(o + 2),
            sent: u32_at(o + 4),
            acked: u32_at(o + 8),
            retransmitted: u32_at(o + 12),
            duplicates: u32_at(o + 16),
            skipped: u32_at(o + 20),
            overruns: u32_at(o + 24),
        }
    });
    (p[0], links)
}

/// What a grid run gave: each board's report, bytes relayed, faults injected, wall time.
struct Run {
    reports: Vec<[LinkReport; 4]>,
    bytes: u64,
    injected: u64,
    wall: Duration,
}

/// The link exercise on a grid relaying with `faults`: configure every board, collect every
/// board's report.
fn run_grid(faults: Faults) -> Run {
    let mut g = boot(board_elf(Path::new(env!("CARGO_TARGET_TMPDIR"))), faults, None, GRID_TIMEOUT);
    let boards = SIDE * SIDE;
    for b in 0..boards {
        let mut config = board_config(b);
        config.extend(COUNT.to_le_bytes());
        g.send(b, KIND_CONFIG, &config);
    }
    let mut reports: Vec<Option<[LinkReport; 4]>> = vec![None; boards];
    while reports.iter().any(Option::is_none) {
        g.poll(&|| format!("every board's report (a hang, or a lost frame; so far: {reports:?})"));
        for (b, (_, link)) in g.hosts.iter_mut().enumerate() {
            if let Some(f) = link.received() {
                assert_eq!(f.kind, KIND_REPORT, "board {b} sent an unknown frame");
                let (id, r) = parse_report(f.payload);
                assert_eq!(id as usize, b, "board {b} reported as {id}");
                assert!(reports[b].is_none(), "board {b} reported twice");
                reports[b] = Some(r);
                link.pop();
            }
        }
    }
    // Acknowledge the reports before the boards go.
    g.settle();
    let wall = g.t0.elapsed();
    let (bytes, injected) = g.grid.stop_relays();
    Run { reports: reports.into_iter().map(Option::unwrap).collect(), bytes, injected, wall }
}

/// Every board received every frame of each neighbour exactly once, unaltered and in order,
/// and had all of its own acknowledged; returns the links' total retransmissions and skipped
/// bytes.
fn check_exactly_once(run: &Run) -> (u32, u32) {
    let (mut retransmitted, mut skipped) = (0, 0);
    for (b, r) in run.reports.iter().enumerate() {
        for (l, link) in r.iter().enumerate() {
            if neighbour(b, l).is_none() {
                assert_eq!(*link, LinkReport::default(), "board {b} link {l} has no neighbour");
                continue;
            }
            assert_eq!(
                (link.received, link.mismatches, link.sent, link.acked),
                (COUNT, 0, COUNT as u32, COUNT as u32),
                "board {b} link {l}: received, mismatched, sent, acknowledged ({link:?})"
            );
            assert_eq!(link.overruns, 0, "board {b} link {l}: the UART lost bytes");
            retransmitted += link.retransmitted;
            skipped += link.skipped;
        }
    }
    (retransmitted, skipped)
}

pub(crate) fn a_2x2_grid_of_boards_exchanges_every_frame_exactly_once() {
    if !qemu::tools_present("a_2x2_grid_of_boards_exchanges_every_frame_exactly_once") {
        return;
    }
    let run = run_grid(CLEAN);
    let (retransmitted, skipped) = check_exactly_once(&run);
    eprintln!(
        "clean wire: {} bytes relayed in {:?}, {retransmitted} retransmissions, {skipped} bytes skipped",
        run.bytes, run.wall
    );
    assert_eq!(run.injected, 0, "a clean wire corrupts nothing");
}

pub(crate) fn corrupted_and_dropped_bytes_between_boards_are_recovered_by_the_link() {
    if !qemu::tools_present("corrupted_and_dropped_bytes_between_boards_are_recovered_by_the_link") {
        return;
    }
    // About one byte in 250 corrupted and one in 250 dropped: some 10 % of the data frames.
    let run = run_grid(Faults { corrupt: 40, drop: 40, seed: 0x5AFE_2025 });
    let (retransmitted, skipped) = check_exactly_once(&run);
    eprintln!(
        "faulty wire: {} bytes relayed in {:?}, {} faults injected, {retransmitted} retransmissions, \
         {skipped} bytes skipped",
        run.bytes, run.wall, run.injected
    );
    assert!(run.injected > 0, "the relays injected no fault");
    assert!(retransmitted > 0 && skipped > 0, "faults were injected, so the links must have repaired some");
}

/// A workload: the host's items (board, ttl), children per item, busy time per item (µs).
#[derive(Clone, Copy, Debug)]
struct Work {
    items: &'static [(usize, u8)],
    fan_out: u8,
    work_us: u16,
}

impl Work {
    /// Items processed in all: an item of ttl t makes t + 1 (one child each) or 2^(t+1) − 1
    /// (two).
    fn total(&self) -> u32 {
        self.items.iter().map(|&(_, t)| if self.fan_out == 1 { u32::from(t) + 1 } else { (2u32 << t) - 1 }).sum()
    }
}

/// Trees: 637 items, 1 ms each, most of the time many messages in flight at once.
const TREES: Work = Work { items: &[(0, 7), (0, 6), (3, 7)], fan_out: 2, work_us: 1000 };
/// A chain of 12 items, 5 ms each, from board 3: one item alive at a time, most of the time
/// every board passive and one message in flight. With board 3's links slowed (the test
/// below), a message on one of them is overtaken by whole token rounds on the others: where a
/// detector without message counters (colours only) declares early. (Checked by hand: with
/// `Node::sent`/`received` replaced by colour-only bookkeeping on the board, the test below
/// fails, late work seen after the declaration.)
const CHAIN: Work = Work { items: &[(3, 11)], fan_out: 1, work_us: 5_000 };

/// A board's state as it answers a query.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct BoardState {
    processed: u32,
    sent: u32,
    received: u32,
    injected: u32,
    queued: u32,
    count: i32,
    forwarded: u32,
    overflows: u32,
    retransmitted: u32,
    skipped: u32,
    late: u32,
}

fn parse_state(p: &[u8]) -> (u8, BoardState) {
    assert_eq!(p.len(), 45, "state length");
    let u = |i: usize| u32::from_le_bytes(p[1 + 4 * i..5 + 4 * i].try_into().unwrap());
    let st = BoardState {
        processed: u(0),
        sent: u(1),
        received: u(2),
        injected: u(3),
        queued: u(4),
        count: u(5) as i32,
        forwarded: u(6),
        overflows: u(7),
        retransmitted: u(8),
        skipped: u(9),
        late: u(10),
    };
    (p[0], st)
}

/// Ask every board for its state.
fn query(g: &mut Booted) -> Vec<BoardState> {
    for b in 0..g.hosts.len() {
        g.send(b, KIND_QUERY, &[]);
    }
    let mut states: Vec<Option<BoardState>> = vec![None; g.hosts.len()];
    while states.iter().any(Option::is_none) {
        g.poll(&|| format!("every board's state (so far {states:?})"));
        for (b, (_, link)) in g.hosts.iter_mut().enumerate() {
            if let Some(f) = link.received() {
                assert_eq!(f.kind, KIND_STATE, "board {b} sent an unexpected frame (a second declaration?)");
                let (id, st) = parse_state(f.payload);
                assert_eq!(id as usize, b);
                states[b] = Some(st);
                link.pop();
            }
        }
    }
    states.into_iter().map(Option::unwrap).collect()
}

/// The termination exercise: configure the ring, inject `work`'s items, start the detection, wait
/// for ring position 0's two declarations (the work's phase, then the empty phase whose round
/// tells every board of the first), then read every board's state twice, 300 ms apart.
/// Returns the two readings and the time from start to declaration.
fn run_termination(work: Work, faults: Faults, slow: Option<Slow>) -> ([Vec<BoardState>; 2], Duration, u64) {
    let mut g = boot(board_elf(Path::new(env!("CARGO_TARGET_TMPDIR"))), faults, slow, GRID_TIMEOUT);
    for b in 0..SIDE * SIDE {
        let mut config = ring_config(b);
        config.extend(work.work_us.to_le_bytes());
        config.push(work.fan_out);
        g.send(b, KIND_TERM_CONFIG, &config);
    }
    for (i, &(b, ttl)) in work.items.iter().enumerate() {
        let id = (i as u32) << 24;
        g.send(b, KIND_WORK, &[[ttl].as_slice(), &id.to_le_bytes()].concat());
    }
    // Every injected item taken by its board before the detection starts.
    g.settle();
    // Phase 0 (the work), then phase 1 (empty: its round tells every board of the first).
    let declared = g.declarations(2, &|k| format!("termination of phase {k}"));
    let first = query(&mut g);
    let wait = Instant::now();
    while wait.elapsed() < Duration::from_millis(300) {
        g.poll(&|| "the boards, after the declaration".to_string());
        for (b, (_, link)) in g.hosts.iter().enumerate() {
            assert!(link.received().is_none(), "board {b} sent a frame after the declaration");
        }
    }
    let second = query(&mut g);
    g.settle();
    let (_, injected) = g.grid.stop_relays();
    ([first, second], declared[0], injected)
}

/// At the declaration every item had been processed, none was queued or in flight, and
/// nothing happened after it.
fn check_terminated(work: Work, states: &[Vec<BoardState>; 2]) {
    let expected = work.total();
    let [first, second] = states;
    let sum = |f: fn(&BoardState) -> u32| first.iter().map(f).sum::<u32>();
    assert_eq!(
        sum(|s| s.processed),
        expected,
        "items processed by the declaration (an early declaration leaves work undone): {first:?}"
    );
    assert_eq!(sum(|s| s.injected), work.items.len() as u32);
    assert_eq!(sum(|s| s.sent), sum(|s| s.received), "work frames in flight at the declaration: {first:?}");
    assert_eq!(sum(|s| s.sent), expected - work.items.len() as u32, "every item but the host's crossed a link");
    assert_eq!(first.iter().map(|s| s.count).sum::<i32>(), 0);
    for (b, s) in first.iter().enumerate() {
        assert_eq!((s.queued, s.overflows), (0, 0), "board {b} still had work, or overflowed: {s:?}");
        assert_eq!(s.late, 0, "board {b} saw work after it knew of the declaration: {s:?}");
        assert!(s.forwarded > 0, "board {b} never forwarded the token");
    }
    let processed = |v: &Vec<BoardState>| v.iter().map(|s| (s.processed, s.sent, s.received)).collect::<Vec<_>>();
    assert_eq!(processed(first), processed(second), "work after the declaration");
}

pub(crate) fn the_boards_detect_termination_never_early_with_a_slow_board() {
    if !qemu::tools_present("the_boards_detect_termination_never_early_with_a_slow_board") {
        return;
    }
    // Board 3's links deliver every byte 300 ms late, both ways (a token round over the
    // other links takes less).
    let (states, declared, _) = run_termination(CHAIN, CLEAN, Some(Slow::Board(3, Duration::from_millis(300))));
    eprintln!("slow board 3: declared {declared:?} after the start; states {states:?}");
    check_terminated(CHAIN, &states);
}

pub(crate) fn the_boards_detect_termination_over_faulty_links() {
    if !qemu::tools_present("the_boards_detect_termination_over_faulty_links") {
        return;
    }
    let (states, declared, injected) = run_termination(TREES, Faults { corrupt: 40, drop: 40, seed: 0x7E2A }, None);
    eprintln!("faulty links: {injected} faults, declared {declared:?} after the start; states {states:?}");
    check_terminated(TREES, &states);
    assert!(injected > 0, "the relays injected no fault");
}
