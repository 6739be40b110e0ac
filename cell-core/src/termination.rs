//! §4.4.4 — distributed termination detection: Safra's token ring with message counters.
//!
//! The thesis ends a lighting phase when no beam is left anywhere, and says this "cannot be
//! done without a centralised mechanism" (§4.4.4); rc2's host reads an exact activity counter
//! ([`crate::light::Activity`]) over every cell at once. This module is the mechanism a grid
//! of boards runs instead, with nothing central: one [`Node`] per *node* (a board, i.e. a tile
//! of cells), a state machine driven by four events, and one control message, the [`Token`],
//! that travels a ring of the nodes over their neighbour links. It is Safra's algorithm
//! (Dijkstra, EWD998, "Shmuel Safra's version of termination detection", 1987), the
//! Dijkstra–Feijen–van Gasteren ring with message counters.
//!
//! # The algorithm
//!
//! *Basic messages* are the messages of the computation that cross from one node to another
//! (beams, row and pipeline packets on inter-board links; messages between cells of one node
//! are internal to it). A node is *active* while it has work (a cell holding a beam, a packet
//! to process, a beam to emit) and *passive* otherwise; a passive node becomes active only by
//! receiving a basic message, or by starting a phase while it holds the token (below).
//!
//! Each node keeps a counter `c` = basic messages sent − basic messages received
//! ([`Node::sent`], [`Node::received`]) and a colour: receiving a basic message makes it
//! *black*. Ring position 0 is the initiator. The token carries a sum `q` and a colour.
//!
//! * A node other than 0 that holds the token and is passive forwards it to the next ring
//!   position with `q + c`, blackened if the node is black, and turns white ([`Node::poll`]).
//! * Node 0, passive, starts a round by sending a white token with `q = 0` and turns white.
//!   When the token comes back and node 0 is passive, it **declares termination** iff the
//!   token is white, node 0 is white and `q + c₀ = 0`; otherwise it starts a new round.
//!
//! **Phases.** A run is a sequence of phases (loading, then one lighting phase per source);
//! every token carries its phase number. After declaring phase p, node 0 enters phase p + 1
//! and its next round's token carries p + 1; any other node that receives a token of a later
//! phase enters it ([`Arrival::entered`]): this is where the node owning the next source starts
//! emitting. Counters are never reset: at a declaration no basic message is in flight, so
//! `Σ c = 0` and the next phase's counting starts from a true sum.
//!
//! # Invariant and proof sketch
//!
//! Number the ring positions 0 … N − 1; the token travels 0 → 1 → … → N − 1 → 0. While the
//! token of a round is held by (or on its way to) position t, call positions 1 … t − 1
//! *visited*. Let `B` be the number of basic messages in flight (sent, not yet received); by
//! the counter rule `B = Σᵢ cᵢ`. The invariant (EWD998's P0 ∨ P1 ∨ P2 ∨ P3) is
//!
//! * P0: every visited node is passive and `q = Σ_{visited} cᵢ`; or
//! * P1: `Σ_{unvisited} cᵢ + q > 0`; or
//! * P2: some unvisited node is black; or
//! * P3: the token is black.
//!
//! It holds when node 0 starts a round (nothing visited, `q = 0`, token white: P0), and every
//! event keeps it:
//!
//! * the token holder t, passive, forwards: t joins the visited set and `q` grows by `c_t`, so
//!   P0 and P1's sum are unchanged; if t was black, the token turns black (P2 → P3);
//! * a node sends: under P0 the sender is active, hence unvisited, and P0 is untouched; P1's
//!   sum can only grow;
//! * a *visited* node receives (P0 falls): the message was in flight, so `B ≥ 1`, and under P0
//!   `Σ_{unvisited} cᵢ + q = B ≥ 1`: P1 held, and the receipt does not change it (a visited
//!   counter is not in the sum, `q` is not re-read); P2 and P3 are untouched;
//! * an *unvisited* node receives: it turns black (P2);
//! * the token holder starts a phase and becomes active: it is unvisited, nothing changes;
//! * a node turns passive: nothing changes.
//!
//! **Safety (never early).** At a declaration the token is back at 0 (everyone else
//! visited): white token and white node 0 falsify P3 and P2 (0 is the only unvisited node);
//! `q + c₀ = 0` falsifies P1. So P0 holds: every node is passive and `B = Σ cᵢ = q + c₀ = 0`:
//! no message is in flight and no node is active — the computation has terminated, and it
//! cannot restart by itself.
//!
//! **Liveness (never hanging).** Suppose the computation terminates at time T (every node
//! passive, nothing in flight; it stays so). Let r be the round in progress at T. Every node
//! now forwards the token as soon as it holds it, so round r ends. Round r + 1 adds exactly
//! `Σ cᵢ = 0` and whitens every node; no message is received after T, so at the start of
//! round r + 2 every node is white, and round r + 2 is white with sum 0: node 0 declares at its
//! end. Termination is declared **within two whole rounds after the round in progress at
//! quiescence**: at most 3N token hops after T (host-sim's `machine::lighting::boards` checks this
//! bound on every declaration).
//!
//! # Counter widths
//!
//! Counters and the token's sum are `i32` with checked arithmetic. If the machine sends fewer
//! than 2³¹ basic messages in a whole run, no counter and no partial sum can overflow
//! (`|cᵢ| ≤` messages node i sent or received, `|q| ≤` messages sent in total). Beyond that an
//! overflow is not wrapped: it is a [`TerminationError::Overflow`], and the node refuses to
//! declare (a counted error, never a wrong declaration). Phases are `u16`.
//!
//! # Wire
//!
//! The token is a frame of its own ([`crate::wire::TokenFrame`], kind `0x40`): phase u16,
//! sum i32, colour u8 — 15 bytes with the header, sequence number and CRC.
//!
//! ```
//! use cell_core::termination::{Action, Node, Token};
//!
//! // Two nodes, one phase (0). Node 1 sends node 0 one basic message, then goes passive.
//! let (mut n0, mut n1) = (Node::new(0, 0), Node::new(1, 0));
//! n1.sent().unwrap();
//! // Round 1: node 0, passive, starts it; node 1 forwards the token with its counter.
//! let Action::Forward(t) = n0.poll(true).unwrap() else { unreachable!() };
//! n1.token(t);
//! let Action::Forward(t) = n1.poll(true).unwrap() else { unreachable!() };
//! assert_eq!(t, Token { phase: 0, count: 1, black: false }); // one message in flight
//! n0.token(t);
//! // Every node was passive when visited, but the sum is 1: no declaration, round 2.
//! let Action::Forward(t) = n0.poll(true).unwrap() else { unreachable!() };
//! // The message reaches node 0 (it turns black), which works a while.
//! n0.received().unwrap();
//! n1.token(t);
//! let Action::Forward(t) = n1.poll(true).unwrap() else { unreachable!() };
//! n0.token(t);
//! assert_eq!(n0.poll(false).unwrap(), Action::Wait); // busy: it keeps the token
//! // Passive again: sum 1 − 1 = 0, but node 0 is black: round 3, which succeeds.
//! let Action::Forward(t) = n0.poll(true).unwrap() else { unreachable!() };
//! n1.token(t);
//! let Action::Forward(t) = n1.poll(true).unwrap() else { unreachable!() };
//! n0.token(t);
//! assert_eq!(n0.poll(true).unwrap(), Action::Declare(0));
//! assert!(n0.is_done());
//! //! ```

/// The token: the sum of the counters of the nodes visited in this round, its colour and the
/// phase it belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Token {
    /// The phase this round detects the end of.
    pub phase: u16,
    /// Σ (sent − received) over the nodes visited in this round.
    pub count: i32,
    /// A visited node had received a basic message since it last forwarded the token.
    pub black: bool,
}

impl Token {
    /// The token node 0 sends to start a round of `phase`: white, sum 0.
    pub const fn start(phase: u16) -> Token {
        Token { phase, count: 0, black: false }
    }
}

/// What a [`Node`] asks its driver to do when polled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Action {
    /// Nothing now (no token held, or the node is active).
    Wait,
    /// Send this token to the next ring position.
    Forward(Token),
    /// (Node 0 only.) Phase `phase` has terminated: no basic message in flight, every node
    /// passive. The node is now in phase `phase + 1` (or done after its last phase).
    Declare(u16),
}

/// What receiving a token changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Arrival {
    /// The token was of a later phase than the node's: it entered this phase (its driver
    /// starts the phase's local work before the node forwards the token).
    pub entered: Option<u16>,
}

/// Why a node cannot go on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TerminationError {
    /// A counter or the token's sum left `i32` (more than 2³¹ − 1 basic messages in a run):
    /// the node never declares after this.
    Overflow,
}

/// Where node 0 is in its rounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
enum Round {
    /// Node 0 will start a round when passive (other nodes: no token).
    Idle,
    /// Node 0's token is out on the ring.
    Out,
    /// The node holds this token (node 0: its round came back).
    Holding(Token),
    /// Node 0 declared its last phase.
    Done,
}

/// One node's termination state: its ring position, counter, colour, phase and token.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Node {
    position: u16,
    last_phase: u16,
    phase: u16,
    count: i32,
    black: bool,
    round: Round,
    failed: bool,
}

impl Node {
    /// The node at ring position `position` (0: the initiator), in phase 0, for a run whose
    /// phases are `0 ..= last_phase`.
    pub const fn new(position: u16, last_phase: u16) -> Node {
        Node { position, last_phase, phase: 0, count: 0, black: false, round: Round::Idle, failed: false }
    }

    /// The node's ring position.
    pub const fn position(&self) -> u16 {
        self.position
    }

    /// The phase the node is in.
    pub const fn phase(&self) -> u16 {
        self.phase
    }

    /// Sent − received so far (never reset).
    pub const fn count(&self) -> i32 {
        self.count
    }

    /// Whether the node received a basic message since it last forwarded the token.
    pub const fn is_black(&self) -> bool {
        self.black
    }

    /// Whether the node holds the token.
    pub const fn holds_token(&self) -> bool {
        matches!(self.round, Round::Holding(_))
    }

    /// (Node 0.) Whether the last phase was declared.
    pub const fn is_done(&self) -> bool {
        matches!(self.round, Round::Done)
    }

    fn add(&mut self, d: i32) -> Result<(), TerminationError> {
        match self.count.checked_add(d) {
            Some(c) if !self.failed => {
                self.count = c;
                Ok(())
            }
            _ => {
                self.failed = true;
                Err(TerminationError::Overflow)
            }
        }
    }

    /// The node sent one basic message (before it leaves: a message is counted from the
    /// moment it can be in flight).
    pub fn sent(&mut self) -> Result<(), TerminationError> {
        self.add(1)
    }

    /// The node received one basic message: it turns black.
    pub fn received(&mut self) -> Result<(), TerminationError> {
        self.black = true;
        self.add(-1)
    }

    /// A token arrived from the previous ring position. A token of a later phase makes the
    /// node enter that phase (see [`Arrival::entered`]).
    pub fn token(&mut self, t: Token) -> Arrival {
        self.round = Round::Holding(t);
        if t.phase > self.phase {
            self.phase = t.phase;
            return Arrival { entered: Some(t.phase) };
        }
        Arrival { entered: None }
    }

    /// Called by the driver whenever it likes (each loop, after local work), with whether the
    /// node is passive now: forward the token, start a round, or declare. Nothing happens
    /// while the node is active.
    pub fn poll(&mut self, passive: bool) -> Result<Action, TerminationError> {
        if self.failed {
            return Err(TerminationError::Overflow);
        }
        if !passive {
            return Ok(Action::Wait);
        }
        match (self.position, self.round) {
            (_, Round::Done | Round::Out) => Ok(Action::Wait),
            (0, Round::Idle) => Ok(self.start_round()),
            (0, Round::Holding(t)) => {
                let sum = t.count.checked_add(self.count).ok_or(TerminationError::Overflow);
                if sum.is_err() {
                    self.failed = true;
                }
                if !t.black && !self.black && sum? == 0 && t.phase == self.phase {
                    let p = self.phase;
                    if p >= self.last_phase {
                        self.round = Round::Done;
                    } else {
                        self.phase += 1;
                        self.round = Round::Idle;
                    }
                    return Ok(Action::Declare(p));
                }
                Ok(self.start_round())
            }
            (_, Round::Idle) => Ok(Action::Wait),
            (_, Round::Holding(t)) => {
                let Some(count) = t.count.checked_add(self.count) else {
                    self.failed = true;
                    return Err(TerminationError::Overflow);
                };
                self.round = Round::Idle;
                let black = t.black || self.black;
                self.black = false;
                Ok(Action::Forward(Token { phase: t.phase, count, black }))
            }
        }
    }

    fn start_round(&mut self) -> Action {
        self.black = false;
        self.round = Round::Out;
        Action::Forward(Token::start(self.phase))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// A ring of `n` nodes and a set of basic messages in flight, driven by hand: the ground
    /// truth (`in_flight`, `active`) is kept beside the nodes, which never read it.
    struct Ring {
        nodes: Vec<Node>,
        active: Vec<bool>,
        /// (to) of each message in flight.
        in_flight: Vec<usize>,
        /// The token in flight: (to, token).
        token: Option<(usize, Token)>,
        declared: Vec<u16>,
        hops: u32,
    }

    impl Ring {
        fn new(n: usize, last: u16) -> Self {
            Ring {
                nodes: (0..n).map(|i| Node::new(i as u16, last)).collect(),
                active: std::vec![false; n],
                in_flight: Vec::new(),
                token: None,
                declared: Vec::new(),
                hops: 0,
            }
        }

        fn send(&mut self, from: usize, to: usize) {
            assert!(self.active[from], "a passive node sends nothing");
            self.nodes[from].sent().unwrap();
            self.in_flight.push(to);
        }

        /// Deliver the k-th message in flight.
        fn deliver(&mut self, k: usize) {
            let to = self.in_flight.remove(k);
            self.nodes[to].received().unwrap();
            self.active[to] = true;
        }

        fn move_token(&mut self) {
            if let Some((to, t)) = self.token.take() {
                self.nodes[to].token(t);
                self.hops += 1;
            }
        }

        /// Poll every node once; check safety at every declaration.
        fn poll_all(&mut self) {
            for i in 0..self.nodes.len() {
                match self.nodes[i].poll(!self.active[i]).unwrap() {
                    Action::Wait => {}
                    Action::Forward(t) => {
                        assert!(self.token.is_none(), "one token");
                        self.token = Some(((i + 1) % self.nodes.len(), t));
                    }
                    Action::Declare(p) => {
                        assert!(self.in_flight.is_empty() && self.active.iter().all(|a| !a), "declared early");
                        self.declared.push(p);
                    }
                }
            }
        }
    }

    #[test]
    fn quiet_ring_declares_after_one_round() {
        for n in 1..6 {
            let mut r = Ring::new(n, 0);
            for _ in 0..2 * n + 2 {
                r.poll_all();
                r.move_token();
            }
            assert_eq!(r.declared, [0], "ring of {n}");
            assert_eq!(r.hops as usize, n, "one round");
            assert!(r.nodes[0].is_done());
        }
    }

    #[test]
    fn message_in_flight_behind_the_token_is_caught() {
        // Node 2 sends to node 1 after the token passed node 1 and goes passive at once: every
        // node is passive when visited, but a message is in flight.
        let mut r = Ring::new(3, 0);
        r.active[2] = true;
        r.poll_all(); // node 0 starts a round
        r.move_token(); // at 1
        r.poll_all(); // 1 forwards
        r.send(2, 1);
        r.active[2] = false;
        r.move_token(); // at 2
        r.poll_all(); // 2 forwards with count 1
        r.move_token(); // back at 0
        r.poll_all(); // not declared: q + c0 = 1
        assert!(r.declared.is_empty());
        // Deliver the message late; node 1 works, then stops.
        for _ in 0..10 {
            r.move_token();
            r.poll_all();
        }
        assert!(r.declared.is_empty(), "the message is still in flight");
        r.deliver(0);
        r.active[1] = false;
        for _ in 0..10 {
            r.move_token();
            r.poll_all();
        }
        assert_eq!(r.declared, [0]);
    }

    #[test]
    fn random_runs_are_never_early_and_never_hang() {
        // Seeded random computations of three phases on rings of 1 ..= 6 nodes: active nodes
        // send and stop at random, messages are delivered in random order after random delays,
        // the token moves at random. Phase p starts at node p % N (node 0 when it declares the
        // previous phase, another node when the phase's token reaches it). Declarations are
        // checked against the ground truth (`poll_all`), and each comes within 3N token hops
        // of the quiescence it reports.
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        let mut rnd = move |k: u64| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s % k
        };
        for trial in 0..300 {
            let n = 1 + trial % 6;
            let mut r = Ring::new(n, 2);
            let mut started = [false; 3];
            let mut budget = 0u32; // messages the current phase may still send
            let mut quiet_since: Option<u32> = None; // token hops when the system went quiet
            while !r.nodes[0].is_done() {
                let p = r.nodes[0].phase() as usize;
                let s = p % n;
                if !started[p] && r.nodes[s].phase() as usize == p && (s == 0 || r.nodes[s].holds_token()) {
                    started[p] = true;
                    r.active[s] = true;
                    budget = 40;
                }
                let declared = r.declared.len();
                match rnd(4) {
                    0 => {
                        let actives: Vec<usize> = (0..n).filter(|&i| r.active[i]).collect();
                        if !actives.is_empty() {
                            let i = actives[rnd(actives.len() as u64) as usize];
                            if budget > 0 && rnd(3) > 0 {
                                budget -= 1;
                                r.send(i, rnd(n as u64) as usize);
                            } else {
                                r.active[i] = false;
                            }
                        }
                    }
                    1 if !r.in_flight.is_empty() => r.deliver(rnd(r.in_flight.len() as u64) as usize),
                    2 => r.move_token(),
                    _ => r.poll_all(),
                }
                if r.declared.len() > declared {
                    let q = quiet_since.expect("declared while quiet");
                    assert!(r.hops - q <= 3 * n as u32, "trial {trial}: {} hops after quiescence", r.hops - q);
                    quiet_since = Some(r.hops);
                }
                let quiet = r.in_flight.is_empty() && r.active.iter().all(|a| !a);
                if !quiet {
                    quiet_since = None;
                } else if quiet_since.is_none() {
                    quiet_since = Some(r.hops);
                }
                assert!(r.hops < 100_000, "trial {trial}: hangs");
            }
            assert_eq!(r.declared, [0, 1, 2], "trial {trial}: every phase declared, in order");
        }
    }

    #[test]
    fn overflow_is_an_error_not_a_wrap() {
        let mut a = Node::new(1, 0);
        a.count = i32::MAX;
        assert_eq!(a.sent(), Err(TerminationError::Overflow));
        a.token(Token::start(0));
        assert_eq!(a.poll(true), Err(TerminationError::Overflow));
        let mut z = Node::new(0, 0);
        z.count = -1;
        z.token(Token { phase: 0, count: i32::MIN, black: false });
        assert_eq!(z.poll(true), Err(TerminationError::Overflow));
        assert_eq!(z.poll(true), Err(TerminationError::Overflow), "sticky");
    }

    #[test]
    fn phases_follow_the_token() {
        let mut r = Ring::new(3, 1);
        for _ in 0..4 {
            r.poll_all();
            r.move_token();
        }
        assert_eq!(r.declared, [0]);
        assert_eq!(r.nodes[0].phase(), 1);
        assert_eq!(r.nodes[2].phase(), 0, "node 2 has not seen the phase-1 token yet");
        r.poll_all(); // node 0 starts phase 1's round
        r.move_token();
        assert_eq!(r.nodes[1].phase(), 1);
    }
}
