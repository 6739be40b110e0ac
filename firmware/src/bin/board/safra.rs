//! The termination exercise: an asynchronous diffusing computation over the boards' serial
//! links, whose end the boards detect themselves with Safra's token ring
//! (`cell_core::termination`, proof in docs/TERMINATION.md), the host only injecting work and
//! reading the boards' states at the end.
//!
//! * **Work**: an item `(ttl, id)` ([`KIND_WORK`]). Processing one takes [`Config::work_us`]
//!   of busy time; an item with `ttl > 0` then makes [`Config::fan_out`] (f = 1 or 2) children
//!   `(ttl − 1, f·id + k)`, k = 1 … f, each sent to a neighbour picked by its id: a basic
//!   message of the termination algorithm, counted by [`Node::sent`] when handed to the link
//!   and by [`Node::received`] when taken off it. An item of `ttl` t thus makes t + 1 items
//!   (a chain: one item alive at a time, a message in flight between two busy spells) or
//!   2^(t+1) − 1 (a tree) in all, wherever they run: the host knows how many must be
//!   processed.
//! * **Injection**: the host sends its items to the boards on their host links before the
//!   detection starts ([`KIND_START`] to ring position 0, sent once every injected item is
//!   acknowledged, i.e. taken by its board): the host's items are not basic messages, and are
//!   all inside boards when the first round begins.
//! * **Passive** means: no item queued or being processed, no child waiting for its link.
//! * **Token**: a [`KIND_TOKEN`] frame on the link to the next ring position
//!   ([`Config::ring_next`]), on the same serial link as the work, in order with it.
//! * **Declaration**: ring position 0 sends [`KIND_DONE`] to the host. The run has two phases:
//!   the work's (0) and an empty one (1). The first round of phase 1 carries the news of the
//!   declaration to every board (`Arrival::entered`); a board counts as *late* every item it
//!   receives or processes after it knows (ring position 0: from its declaration), which an
//!   early declaration would make likely. When phase 1 is declared too, every board knows;
//!   the host then asks every board for its state ([`KIND_QUERY`] → [`KIND_STATE`]).
//!
//! **Invariant**: a board's counter is `sent − received` of work frames between boards; the
//! node is polled passive only when its queue and its outgoing children are empty; so the
//! hypotheses of `cell_core::termination`'s proof hold, and a declaration means every item
//! was processed and none is in flight.
//!
//! A queue overflow (more items than [`QUEUE`]) is counted and reported, never dropped
//! silently; the host sizes its injection below it.

use cell_core::termination::{Action, Node, Token};
use cell_core::wire::board::{KIND_DONE, KIND_QUERY, KIND_START, KIND_STATE, KIND_TERM_CONFIG, KIND_WORK};
use cell_core::wire::{get_token, Reader, KIND_TOKEN};
use heapless::{Deque, Vec};

use crate::{send_token, Board, LINKS, NONE};

/// Items a board can hold: more than the host ever injects in all (each board can hold every
/// item of the run, so a board always takes what arrives: no cycle of full queues).
pub const QUEUE: usize = 1024;
/// Children waiting for each link.
const OUT: usize = 256;

/// The termination exercise's configuration ([`KIND_TERM_CONFIG`]).
#[derive(Clone, Copy)]
pub struct Config {
    id: u8,
    neighbours: [u8; LINKS],
    ring_position: u8,
    ring_next: u8,
    work_us: u16,
    fan_out: u32,
}

impl Config {
    /// The configuration, if `kind` and `p` are one.
    pub fn parse(kind: u8, p: &[u8]) -> Option<Config> {
        if kind != KIND_TERM_CONFIG || p.len() != 11 || p[7] as usize >= LINKS || !(1..=2).contains(&p[10]) {
            return None;
        }
        Some(Config {
            id: p[0],
            neighbours: [p[1], p[2], p[3], p[4]],
            ring_position: p[5],
            ring_next: p[7],
            work_us: u16::from_le_bytes([p[8], p[9]]),
            fan_out: u32::from(p[10]),
        })
        .filter(|c| c.neighbours[c.ring_next as usize] != NONE && p[6] > c.ring_position)
    }
}

type Item = (u8, u32);

fn item(p: &[u8]) -> Option<Item> {
    (p.len() == 5).then(|| (p[0], u32::from_le_bytes([p[1], p[2], p[3], p[4]])))
}

fn item_bytes((ttl, id): Item) -> [u8; 5] {
    let b = id.to_le_bytes();
    [ttl, b[0], b[1], b[2], b[3]]
}

/// Counters of the exercise.
#[derive(Default)]
struct State {
    processed: u32,
    sent: u32,
    received: u32,
    injected: u32,
    forwarded: u32,
    overflows: u32,
    late: u32,
}

/// Run the termination exercise for ever (the host stops the board).
pub fn run(mut board: Board, c: Config) -> ! {
    let mut queue: Deque<Item, QUEUE> = Deque::new();
    let mut out: [Deque<Item, OUT>; LINKS] = core::array::from_fn(|_| Deque::new());
    // Two phases: the work's (0), then an empty one (1) whose token tells every board that
    // phase 0 was declared: work a board sees after that is late (an early declaration).
    let mut node = Node::new(u16::from(c.ring_position), 1);
    let mut learned = false;
    let mut token: Option<Token> = None;
    let mut started = c.ring_position != 0;
    let mut st = State::default();
    let connected: Vec<usize, LINKS> = (0..LINKS).filter(|&l| c.neighbours[l] != NONE).collect();
    let mut state_due = false;
    let mut done_due: Option<u16> = None;
    loop {
        let now = board.now();
        // Receive: work and tokens from the neighbours.
        for l in 0..LINKS {
            if c.neighbours[l] == NONE {
                continue;
            }
            board.poll(l + 1, now);
            let link = &mut board.links[l + 1];
            let Some(f) = link.received() else { continue };
            match (f.kind, item(f.payload)) {
                (KIND_WORK, Some(it)) => {
                    if queue.push_back(it).is_err() {
                        st.overflows += 1;
                    }
                    let _ = node.received();
                    st.received += 1;
                    st.late += u32::from(learned);
                }
                (KIND_TOKEN, _) => {
                    if let Ok(t) = get_token(&mut Reader::new(f.payload)) {
                        learned |= node.token(t).entered.is_some();
                    }
                }
                _ => st.overflows += 1,
            }
            link.pop();
        }
        // The host: injected work, start, queries.
        board.poll(0, now);
        if let Some(f) = board.links[0].received() {
            match (f.kind, item(f.payload)) {
                (KIND_WORK, Some(it)) => {
                    if queue.push_back(it).is_err() {
                        st.overflows += 1;
                    }
                    st.injected += 1;
                }
                (KIND_START, _) => started = true,
                (KIND_QUERY, _) => state_due = true,
                _ => {}
            }
            board.links[0].pop();
        }
        // Work: one item per loop, its children to their links.
        if out.iter().all(|o| o.len() + 2 <= OUT) {
            if let Some((ttl, id)) = queue.pop_front() {
                let until = board.now() + u64::from(c.work_us);
                while board.now() < until {}
                st.processed += 1;
                st.late += u32::from(learned);
                if ttl > 0 {
                    for k in 1..=c.fan_out {
                        let child = id.wrapping_mul(c.fan_out).wrapping_add(k);
                        let l = connected[(child as usize) % connected.len()];
                        let _ = out[l].push_back((ttl - 1, child));
                    }
                }
            }
        }
        // Send: the token first (rounds go on while work flows), then children (counted as
        // sent when handed to the link).
        for (l, (link, out)) in board.links[1..].iter_mut().zip(&mut out).enumerate() {
            if !link.can_send() {
                continue;
            }
            if let (true, Some(t)) = (l == c.ring_next as usize, token) {
                if send_token(link, &t) {
                    token = None;
                    st.forwarded += 1;
                }
            } else if let Some(&it) = out.front() {
                if link.send(KIND_WORK, &item_bytes(it)).is_ok() {
                    let _ = node.sent();
                    st.sent += 1;
                    out.pop_front();
                }
            }
        }
        // Termination: the node acts on the token only when passive.
        let passive = queue.is_empty() && out.iter().all(|o| o.is_empty());
        if started && token.is_none() {
            match node.poll(passive) {
                Ok(Action::Forward(t)) => token = Some(t),
                Ok(Action::Declare(p)) => {
                    learned = true;
                    done_due = Some(p);
                }
                _ => {}
            }
        }
        // Answers to the host.
        if board.links[0].can_send() {
            if let Some(p) = done_due {
                if board.links[0].send(KIND_DONE, &p.to_le_bytes()).is_ok() {
                    done_due = None;
                }
            } else if state_due {
                let mut r: Vec<u8, 45> = Vec::new();
                let _ = r.push(c.id);
                let queued = (queue.len() + out.iter().map(|o| o.len()).sum::<usize>()) as u32;
                let (mut retransmitted, mut skipped) = (0, 0);
                for l in &board.links[1..] {
                    retransmitted += l.stats().retransmitted;
                    skipped += l.stats().skipped;
                }
                for v in [st.processed, st.sent, st.received, st.injected, queued] {
                    let _ = r.extend_from_slice(&v.to_le_bytes());
                }
                let _ = r.extend_from_slice(&node.count().to_le_bytes());
                for v in [st.forwarded, st.overflows, retransmitted, skipped, st.late] {
                    let _ = r.extend_from_slice(&v.to_le_bytes());
                }
                if board.links[0].send(KIND_STATE, &r).is_ok() {
                    state_due = false;
                }
            }
        }
        if queue.is_empty() {
            board.wait();
        }
    }
}
