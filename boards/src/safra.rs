//! The termination exercise (tests/tests/integration/mcu_grid.rs on QEMU boards): an
//! asynchronous diffusing computation over the boards' links, whose end the boards detect
//! themselves with Safra's token ring (`cell_core::termination`, §4.4.4's mechanism without a
//! centre; proof in docs/TERMINATION.md), the host only injecting work and reading the boards'
//! states at the end. [`SafraBoard`] is one board, driven by [`SafraBoard::poll`] with its
//! links and the time.
//!
//! * **Work**: an item `(ttl, id)` ([`KIND_WORK`]). Processing one takes [`Config::work_us`]
//!   of busy time (the item is held from the poll that starts it until a poll at or after its
//!   end); an item with `ttl > 0` then makes [`Config::fan_out`] (f = 1 or 2) children
//!   `(ttl − 1, f·id + k)`, k = 1 … f, each sent to a neighbour picked by its id: a basic
//!   message of the termination algorithm, counted by `Node::sent` when handed to the link and
//!   by `Node::received` when taken off it. An item of `ttl` t thus makes t + 1 items (a chain)
//!   or 2^(t+1) − 1 (a tree) in all, wherever they run: the host knows how many must be
//!   processed.
//! * **Injection**: the host sends its items on the host link before the detection starts
//!   ([`KIND_START`] to ring position 0, sent once every injected item is taken): the host's
//!   items are not basic messages.
//! * **Passive** means: no item queued or being processed, no child waiting for its link.
//! * **Token**: a `KIND_TOKEN` frame on the link to the next ring position
//!   ([`Ring::next`](crate::Ring::next)), on the same link as the work, in order with it.
//! * **Declaration**: ring position 0 sends [`KIND_DONE`] to the host. The run has two phases:
//!   the work's (0) and an empty one (1) whose first round carries the news of the declaration
//!   to every board; a board counts as *late* every item it receives or processes after it
//!   knows, which an early declaration would make likely. The host then asks every board for
//!   its state ([`KIND_QUERY`] → [`KIND_STATE`]).
//!
//! **Invariant**: a board's counter is `sent − received` of work frames between boards; the
//! node is polled passive only when its queue, its item in progress and its outgoing children
//! are empty; so the hypotheses of `cell_core::termination`'s proof hold, and a declaration
//! means every item was processed and none is in flight. A queue overflow (more items than
//! [`QUEUE`]) is counted and reported, never dropped silently.

use cell_core::termination::{Action, Node, Token};
use cell_core::wire::board::{KIND_DONE, KIND_QUERY, KIND_START, KIND_STATE, KIND_TERM_CONFIG, KIND_WORK};
use cell_core::wire::{get_token, Reader, KIND_TOKEN};
use heapless::{Deque, Vec};

use crate::{repairs, send_token, Event, Events, Links, Ring, LINKS};

/// Items a board can hold: more than the host ever injects in all (each board can hold every
/// item of the run, so a board always takes what arrives: no cycle of full queues).
pub const QUEUE: usize = 1024;
/// Children waiting for each link.
pub const OUT: usize = 256;

/// The termination exercise's configuration ([`KIND_TERM_CONFIG`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Config {
    /// The board's place in the grid and the ring.
    pub ring: Ring,
    /// Busy time per item, in the time unit of [`SafraBoard::poll`] (µs on the boards).
    pub work_us: u16,
    /// Children per item (1: a chain, 2: a tree).
    pub fan_out: u32,
}

impl Config {
    /// The configuration, if `kind` and `p` are one: the [`Ring`] head, work time (u16),
    /// fan-out.
    pub fn parse(kind: u8, p: &[u8]) -> Option<Config> {
        if kind != KIND_TERM_CONFIG || p.len() != Ring::BYTES + 3 || !(1..=2).contains(&p[10]) {
            return None;
        }
        Some(Config { ring: Ring::parse(p)?, work_us: u16::from_le_bytes([p[8], p[9]]), fan_out: u32::from(p[10]) })
    }
}

/// A work item: (ttl, id).
pub type Item = (u8, u32);

fn item(p: &[u8]) -> Option<Item> {
    (p.len() == 5).then(|| (p[0], u32::from_le_bytes([p[1], p[2], p[3], p[4]])))
}

/// A work item's frame body.
pub fn item_bytes((ttl, id): Item) -> [u8; 5] {
    let b = id.to_le_bytes();
    [ttl, b[0], b[1], b[2], b[3]]
}

/// Counters of the exercise (reported in [`KIND_STATE`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct State {
    /// Items processed.
    pub processed: u32,
    /// Work frames sent to neighbours.
    pub sent: u32,
    /// Work frames received from neighbours.
    pub received: u32,
    /// Items the host injected.
    pub injected: u32,
    /// Tokens forwarded.
    pub forwarded: u32,
    /// Items lost to a full queue, and frames that were no item or token.
    pub overflows: u32,
    /// Items received or processed after the board learned of the work's declaration.
    pub late: u32,
}

/// One board of the termination exercise: what `firmware/src/bin/board/safra.rs`'s loop kept
/// in its locals.
pub struct SafraBoard {
    c: Config,
    queue: Deque<Item, QUEUE>,
    out: [Deque<Item, OUT>; LINKS],
    /// The item being processed and when its busy time ends.
    busy: Option<(Item, u64)>,
    node: Node,
    /// The board knows that the work's phase was declared.
    learned: bool,
    token: Option<Token>,
    started: bool,
    st: State,
    connected: Vec<usize, LINKS>,
    state_due: bool,
    done_due: Option<u16>,
    /// Safra's message counters are kept (false: the counterless mutant, for tests only).
    counters: bool,
}

impl SafraBoard {
    /// A board configured by `c`, before the start.
    pub fn new(c: Config) -> SafraBoard {
        SafraBoard {
            c,
            queue: Deque::new(),
            out: core::array::from_fn(|_| Deque::new()),
            busy: None,
            // Two phases: the work's (0), then an empty one (1) whose token tells every board
            // that phase 0 was declared: work a board sees after that is late.
            node: Node::new(u16::from(c.ring.position), 1),
            learned: false,
            token: None,
            started: c.ring.position != 0,
            st: State::default(),
            connected: (0..LINKS).filter(|&l| c.ring.connected(l)).collect(),
            state_due: false,
            done_due: None,
            counters: true,
        }
    }

    /// The *counterless mutant*: a board that never counts its basic messages (nor turns black
    /// on receiving one), so its ring declares as soon as one round finds every board passive,
    /// with work possibly in flight. Only for tests that show the counters are needed.
    #[doc(hidden)]
    pub fn without_counters(mut self) -> SafraBoard {
        self.counters = false;
        self
    }

    /// The exercise's counters.
    pub fn state(&self) -> &State {
        &self.st
    }

    /// The board's termination node.
    pub fn node(&self) -> &Node {
        &self.node
    }

    /// Whether the board has nothing to do but wait for a frame (its driver may sleep).
    pub fn idle(&self) -> bool {
        self.queue.is_empty() && self.busy.is_none()
    }

    /// Whether the board is passive (the termination's sense).
    pub fn passive(&self) -> bool {
        self.idle() && self.out.iter().all(|o| o.is_empty())
    }

    /// One pass: receive from the neighbours and the host, work (time `now`), send, act on the
    /// token, answer the host.
    pub fn poll(&mut self, links: &mut impl Links, now: u64) -> Events {
        let mut events = Events::new();
        let c = self.c;
        // Receive: work and tokens from the neighbours.
        for l in 0..LINKS {
            if !c.ring.connected(l) {
                continue;
            }
            let Some(f) = links.received(l + 1) else { continue };
            match (f.kind, item(f.payload)) {
                (KIND_WORK, Some(it)) => {
                    if self.queue.push_back(it).is_err() {
                        self.st.overflows += 1;
                    }
                    if self.counters {
                        let _ = self.node.received();
                    }
                    self.st.received += 1;
                    self.st.late += u32::from(self.learned);
                }
                (KIND_TOKEN, _) => {
                    if let Ok(t) = get_token(&mut Reader::new(f.payload)) {
                        if let Some(p) = self.node.token(t).entered {
                            self.learned = true;
                            let _ = events.push(Event::Entered(p));
                        }
                    }
                }
                _ => self.st.overflows += 1,
            }
            links.pop(l + 1);
        }
        // The host: injected work, start, queries.
        if let Some(f) = links.received(0) {
            match (f.kind, item(f.payload)) {
                (KIND_WORK, Some(it)) => {
                    if self.queue.push_back(it).is_err() {
                        self.st.overflows += 1;
                    }
                    self.st.injected += 1;
                }
                (KIND_START, _) => self.started = true,
                (KIND_QUERY, _) => {
                    self.state_due = true;
                    let _ = events.push(Event::Queried);
                }
                _ => {}
            }
            links.pop(0);
        }
        // Work: one item at a time, started when every link has room for its children.
        if self.busy.is_none() && self.out.iter().all(|o| o.len() + 2 <= OUT) {
            self.busy = self.queue.pop_front().map(|it| (it, now + u64::from(c.work_us)));
        }
        if let Some(((ttl, id), until)) = self.busy {
            if now >= until {
                self.busy = None;
                self.st.processed += 1;
                self.st.late += u32::from(self.learned);
                if ttl > 0 {
                    for k in 1..=c.fan_out {
                        let child = id.wrapping_mul(c.fan_out).wrapping_add(k);
                        let l = self.connected[(child as usize) % self.connected.len()];
                        let _ = self.out[l].push_back((ttl - 1, child));
                    }
                }
            }
        }
        // Send: the token first (rounds go on while work flows), then children (counted as
        // sent when the link takes them).
        for (l, out) in self.out.iter_mut().enumerate() {
            if !c.ring.connected(l) || !links.can_send(l + 1) {
                continue;
            }
            if let (true, Some(t)) = (l == c.ring.next as usize, self.token) {
                if send_token(links, l + 1, &t) {
                    self.token = None;
                    self.st.forwarded += 1;
                }
            } else if let Some(&it) = out.front() {
                if links.send(l + 1, KIND_WORK, &item_bytes(it)) {
                    if self.counters {
                        let _ = self.node.sent();
                    }
                    self.st.sent += 1;
                    out.pop_front();
                }
            }
        }
        // Termination: the node acts on the token only when passive.
        if self.started && self.token.is_none() {
            match self.node.poll(self.passive()) {
                Ok(Action::Forward(t)) => self.token = Some(t),
                Ok(Action::Declare(p)) => {
                    self.learned = true;
                    self.done_due = Some(p);
                    let _ = events.push(Event::Declared(p));
                }
                _ => {}
            }
        }
        // Answers to the host.
        if links.can_send(0) {
            if let Some(p) = self.done_due {
                if links.send(0, KIND_DONE, &p.to_le_bytes()) {
                    self.done_due = None;
                }
            } else if self.state_due {
                let r = self.report(links);
                if links.send(0, KIND_STATE, &r) {
                    self.state_due = false;
                }
            }
        }
        events
    }

    /// The [`KIND_STATE`] body: id, processed, sent, received, injected, queued, counter,
    /// tokens forwarded, overflows, retransmitted, skipped, late.
    fn report(&self, links: &impl Links) -> Vec<u8, 45> {
        let mut r: Vec<u8, 45> = Vec::new();
        let _ = r.push(self.c.ring.id);
        let queued = (self.queue.len() + self.out.iter().map(|o| o.len()).sum::<usize>()) as u32;
        let (retransmitted, skipped) = repairs(links);
        let st = &self.st;
        for v in [st.processed, st.sent, st.received, st.injected, queued] {
            let _ = r.extend_from_slice(&v.to_le_bytes());
        }
        let _ = r.extend_from_slice(&self.node.count().to_le_bytes());
        for v in [st.forwarded, st.overflows, retransmitted, skipped, st.late] {
            let _ = r.extend_from_slice(&v.to_le_bytes());
        }
        r
    }
}
