//! §1.3, §4.1.3 — destination-addressed routing: a router per cell, beside the compute unit.
//!
//! A [`Routed`] message carries its destination cell. Routers forward it over the 8 neighbour
//! links along a **minimal** (Chebyshev) path, without the compute unit; the destination's
//! router hands it to its cell (ejection). Flow control is the beams' (§4.4.2): a message moves
//! only into free space (credits), buffers are bounded ([`heapless::Deque`]), and a push into a
//! full buffer hands the message back — nothing is ever dropped.
//!
//! **Next hop.** With (dx, dy) = destination − here, the minimal moves are the diagonal toward
//! the destination (when dx ≠ 0 and dy ≠ 0) and the straight move along the longer axis (when
//! |dx| ≠ |dy|). [`RoutePolicy::DiagonalFirst`] is dimension-ordered: the diagonal while there
//! is one, then straight. [`RoutePolicy::Adaptive`] takes the candidate channel with the most
//! free space (link load), the diagonal on ties.
//!
//! **Virtual channels and deadlock freedom.** A message's **quadrant** is (sign dx, sign dy),
//! zero counted as +; it never changes on a minimal path. Every output channel belongs to one
//! quadrant: a diagonal port serves exactly one; each straight port has two virtual channels,
//! one per quadrant that uses it (E/W split by the sign of dy, N/S by the sign of dx) — 4 + 8 =
//! [`CHANNELS`] buffers. A message of quadrant (sx, sy) in a channel waits only for channels of
//! the same quadrant one cell further, and every move strictly increases φ = sx·x + sy·y.
//! The channel dependency graph is therefore acyclic (each quadrant's is ordered by φ, and
//! quadrants never wait on each other), so with ejection always eventually free the network
//! cannot deadlock (Dally & Seitz), under both policies. The host's stall detector checks it.

use heapless::Deque;

use crate::light::Port;

/// Output buffers of a router: 4 diagonal ports × 1 channel + 4 straight ports × 2.
pub const CHANNELS: usize = 12;

/// A message with its destination cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Routed<P> {
    /// Destination (x, y).
    pub dest: [u16; 2],
    /// What it carries.
    pub payload: P,
}

/// How a router chooses among minimal moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RoutePolicy {
    /// Diagonal first, then straight (dimension-ordered).
    DiagonalFirst,
    /// The minimal move whose channel has the most free space (diagonal on ties).
    Adaptive,
}

/// Where a message goes from a router.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Hop {
    /// It has arrived: hand it to this cell.
    Deliver,
    /// Into output channel `channel` toward `port`.
    Forward {
        /// The link.
        port: Port,
        /// The channel index (0 .. [`CHANNELS`]).
        channel: u8,
    },
}

/// The channel of `port` for a message of quadrant (`neg_x`, `neg_y`).
pub const fn channel_of(port: Port, neg_x: bool, neg_y: bool) -> u8 {
    match port {
        Port::E | Port::W => port as u8 + neg_y as u8,
        Port::N | Port::S => port as u8 + neg_x as u8,
        _ => 8 + port as u8 / 2,
    }
}

/// The port a channel feeds.
pub const fn port_of(channel: u8) -> Port {
    if channel >= 8 {
        Port::ALL[((channel - 8) * 2 + 1) as usize]
    } else {
        Port::ALL[(channel & !1) as usize]
    }
}

/// Per-router counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RouterCounters {
    /// Messages accepted into an output channel (injected here or arriving from a link).
    pub accepted: u64,
    /// Messages handed to this cell.
    pub delivered: u64,
    /// Pushes refused for lack of space (the sender kept the message).
    pub refused: u64,
    /// Largest total occupancy of the output channels.
    pub peak_occupancy: u16,
}

/// A router with `R` messages per output channel and `I` in its ejection queue.
#[derive(Clone, Debug)]
pub struct Router<P, const R: usize, const I: usize> {
    chans: [Deque<Routed<P>, R>; CHANNELS],
    /// Delivered messages waiting for the cell.
    pub inbox: Deque<Routed<P>, I>,
    /// Round-robin bit per straight port (which virtual channel goes first).
    rr: u8,
    /// Counters.
    pub counters: RouterCounters,
}

impl<P: Copy, const R: usize, const I: usize> Default for Router<P, R, I> {
    fn default() -> Self {
        Self::new()
    }
}

impl<P: Copy, const R: usize, const I: usize> Router<P, R, I> {
    /// Empty buffers.
    pub fn new() -> Self {
        Router {
            chans: core::array::from_fn(|_| Deque::new()),
            inbox: Deque::new(),
            rr: 0,
            counters: RouterCounters::default(),
        }
    }

    /// Free space in channel `c`.
    pub fn free(&self, c: u8) -> usize {
        R - self.chans[c as usize].len()
    }

    /// Messages in the output channels.
    pub fn occupancy(&self) -> usize {
        self.chans.iter().map(|q| q.len()).sum()
    }

    /// Nothing buffered (channels and inbox).
    pub fn is_empty(&self) -> bool {
        self.occupancy() == 0 && self.inbox.is_empty()
    }

    /// The next hop of a message for `dest` at the router of cell `here`.
    pub fn route(&self, here: [u16; 2], dest: [u16; 2], policy: RoutePolicy) -> Hop {
        let dx = dest[0] as i32 - here[0] as i32;
        let dy = dest[1] as i32 - here[1] as i32;
        if dx == 0 && dy == 0 {
            return Hop::Deliver;
        }
        let (neg_x, neg_y) = (dx < 0, dy < 0);
        let (sx, sy) = (dx.signum() as i8, dy.signum() as i8);
        let diag = (dx != 0 && dy != 0).then(|| Port::from_delta(sx, sy));
        let straight = (dx.abs() != dy.abs()).then(|| {
            if dx.abs() > dy.abs() {
                Port::from_delta(sx, 0)
            } else {
                Port::from_delta(0, sy)
            }
        });
        let fwd = |p: Port| Hop::Forward { port: p, channel: channel_of(p, neg_x, neg_y) };
        match (diag.flatten(), straight.flatten()) {
            (Some(d), Some(s)) => {
                let (hd, hs) = (fwd(d), fwd(s));
                match (policy, hd, hs) {
                    (RoutePolicy::Adaptive, Hop::Forward { channel: cd, .. }, Hop::Forward { channel: cs, .. })
                        if self.free(cs) > self.free(cd) =>
                    {
                        hs
                    }
                    _ => hd,
                }
            }
            (Some(d), None) => fwd(d),
            (None, Some(s)) => fwd(s),
            // Unreachable for dx, dy not both 0; deliver rather than panic.
            (None, None) => Hop::Deliver,
        }
    }

    /// Whether `hop` has room now.
    pub fn can_take(&self, hop: Hop) -> bool {
        match hop {
            Hop::Deliver => !self.inbox.is_full(),
            Hop::Forward { channel, .. } => self.free(channel) > 0,
        }
    }

    /// Put a message where `hop` says; a full buffer hands it back (counted as refused).
    pub fn push(&mut self, hop: Hop, m: Routed<P>) -> Result<(), Routed<P>> {
        let r = match hop {
            Hop::Deliver => self.inbox.push_back(m).map(|()| self.counters.delivered += 1),
            Hop::Forward { channel, .. } => self.chans[channel as usize].push_back(m).map(|()| {
                self.counters.accepted += 1;
                self.counters.peak_occupancy = self.counters.peak_occupancy.max(self.occupancy() as u16);
            }),
        };
        if r.is_err() {
            self.counters.refused += 1;
        }
        r
    }

    /// The channels feeding the link of `port`, in the order the link tries them this cycle
    /// (the two virtual channels of a straight port take turns; a diagonal port has one,
    /// listed twice). The link tries the second when the first is empty **or** its front
    /// message cannot move: virtual channels must bypass each other, or a blocked message of
    /// one quadrant would hold up another quadrant's and reintroduce a cyclic wait.
    pub fn candidates(&self, port: Port) -> [u8; 2] {
        let p = port as u8;
        if p % 2 == 1 {
            [8 + p / 2, 8 + p / 2]
        } else if self.rr >> (p / 2) & 1 == 0 {
            [p, p + 1]
        } else {
            [p + 1, p]
        }
    }

    /// The front message of channel `c`.
    pub fn peek(&self, c: u8) -> Option<&Routed<P>> {
        self.chans[c as usize].front()
    }

    /// Take the front message of channel `c` (after the next router accepted it); flips the
    /// port's round-robin bit.
    pub fn pop(&mut self, c: u8) -> Option<Routed<P>> {
        let m = self.chans[c as usize].pop_front()?;
        if c < 8 {
            self.rr ^= 1 << (c / 2);
        }
        Some(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channels_are_a_bijection_on_used_pairs() {
        let mut seen = [false; CHANNELS];
        for p in Port::ALL {
            for (nx, ny) in [(false, false), (true, false), (false, true), (true, true)] {
                let (dx, dy) = p.delta();
                // Only the quadrants that can use the port.
                if (dx < 0) != nx && dx != 0 || (dy < 0) != ny && dy != 0 {
                    continue;
                }
                let c = channel_of(p, nx, ny);
                assert_eq!(port_of(c), p);
                seen[c as usize] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn minimal_hops() {
        let r: Router<u8, 2, 2> = Router::new();
        for &(dest, want) in &[
            ([5u16, 5u16], None),
            ([8, 5], Some(Port::E)),
            ([8, 8], Some(Port::NE)),
            ([9, 7], Some(Port::NE)),
            ([2, 0], Some(Port::SW)),
            ([5, 1], Some(Port::S)),
        ] {
            let h = r.route([5, 5], dest, RoutePolicy::DiagonalFirst);
            match (h, want) {
                (Hop::Deliver, None) => {}
                (Hop::Forward { port, .. }, Some(p)) => assert_eq!(port, p),
                _ => panic!("{dest:?}: {h:?}"),
            }
        }
    }
}
