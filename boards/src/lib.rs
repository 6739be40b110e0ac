//! What one board of a grid of boards does (the firmware's `board` image,
//! `firmware/src/bin/board`), as sans-IO state machines the host can test: the **tile
//! exercise** ([`tiles::TileBoard`]: a tile of cells that loads and lights a scene with the
//! other boards, the real counterpart of host-sim's `machine::lighting::boards`) and the
//! **termination exercise** ([`safra::SafraBoard`]: a synthetic diffusing computation whose end
//! the boards detect with Safra's token ring, `cell_core::termination`).
//!
//! A board's logic never touches a wire or a clock. It is driven by explicit calls: each
//! `poll` takes the board's [`Links`] (link 0 the host, links 1 … 4 the neighbours E, N, W, S,
//! each a reliable frame link) and, where the logic needs it, the time; it takes frames off
//! the links, works, hands frames to the links, and returns the [`Event`]s a driver may log.
//! The firmware implements [`Links`] with `cell_core::serial::SerialLink`s over UARTs and
//! only moves bytes and sleeps; the host tests implement it with in-memory queues whose
//! delivery order they choose (a late wire, a token that overtakes a beam), or with
//! `SerialLink`s over in-memory byte pipes ([`Links`] is implemented for `[SerialLink<N>; 5]`).
//!
//! **Invariant** (both exercises): a frame is taken off a link ([`Links::pop`]) only when the
//! board has room for what it carries, and a basic frame (work between boards) is counted for
//! the termination detection when a link takes it ([`Links::send`] returned true) and when the
//! board takes it off its link; so a board's Safra counter is its basic frames sent − received,
//! and a declaration means no work is left anywhere (docs/TERMINATION.md).
#![no_std]
#![forbid(unsafe_code)]

pub mod safra;
pub mod tiles;

use cell_core::serial::{SerialLink, SerialStats};
use cell_core::termination::Token;
use cell_core::wire::{put_token, RawFrame, SliceWriter, KIND_TOKEN};

/// Neighbour links (E, N, W, S: links 1 … 4 of [`Links`]).
pub const LINKS: usize = 4;
/// No neighbour on this link (a configuration's neighbour id).
pub const NONE: u8 = 0xFF;

/// Where a board is in the grid and in Safra's ring: the head of every ring exercise's
/// configuration frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ring {
    /// This board's id.
    pub id: u8,
    /// The neighbours' ids on links E, N, W, S ([`NONE`]: none).
    pub neighbours: [u8; LINKS],
    /// This board's ring position (0: the initiator).
    pub position: u8,
    /// The neighbour link (0 … 3: E, N, W, S) towards the next ring position.
    pub next: u8,
}

impl Ring {
    /// Bytes of a configuration's head: id, neighbours E, N, W, S, ring position, ring length,
    /// ring link.
    pub const BYTES: usize = 8;

    /// The head of configuration `p`, if its ring link leads to a neighbour and its position
    /// is inside the ring.
    pub fn parse(p: &[u8]) -> Option<Ring> {
        let &[id, e, n, w, s, position, length, next, ..] = p else { return None };
        let r = Ring { id, neighbours: [e, n, w, s], position, next };
        ((next as usize) < LINKS && r.neighbours[next as usize] != NONE && length > position).then_some(r)
    }

    /// Whether neighbour link `l` (0 … 3) has a neighbour.
    pub fn connected(&self, l: usize) -> bool {
        self.neighbours[l] != NONE
    }
}

/// A board's five frame links: 0 the host, then the neighbours E, N, W, S. Each delivers
/// frames in order, intact, once (a `SerialLink` over a UART, or an in-memory queue).
pub trait Links {
    /// The frame waiting on link `l`, if any (it stays there until [`Links::pop`]).
    fn received(&self, l: usize) -> Option<RawFrame<'_>>;
    /// Take the waiting frame off link `l` (acknowledge it).
    fn pop(&mut self, l: usize);
    /// Whether link `l` would take a frame now.
    fn can_send(&self, l: usize) -> bool;
    /// Hand a frame to link `l`; whether it took it (then it will be delivered).
    fn send(&mut self, l: usize, kind: u8, body: &[u8]) -> bool;
    /// What link `l` did to survive its wire (reported; zeros for a perfect link).
    fn stats(&self, _l: usize) -> SerialStats {
        SerialStats::default()
    }
    /// The board's stack high-water mark in bytes (reported; 0 where unknown).
    fn stack_peak(&self) -> u32 {
        0
    }
}

/// Serial links as a board's links (the firmware's, and a host test's over in-memory bytes:
/// the byte streams are polled by their owner, not here).
impl<const N: usize> Links for [SerialLink<N>; 5] {
    fn received(&self, l: usize) -> Option<RawFrame<'_>> {
        self[l].received()
    }
    fn pop(&mut self, l: usize) {
        self[l].pop();
    }
    fn can_send(&self, l: usize) -> bool {
        self[l].can_send()
    }
    fn send(&mut self, l: usize, kind: u8, body: &[u8]) -> bool {
        self[l].send(kind, body).is_ok()
    }
    fn stats(&self, l: usize) -> SerialStats {
        self[l].stats()
    }
}

/// What a board did in a poll that its driver may want to log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// A token of a later phase arrived: the board entered this phase.
    Entered(u16),
    /// (Ring position 0.) The board declared the end of this phase.
    Declared(u16),
    /// The host asked for the board's report.
    Queried,
}

/// The events of one poll (at most one token arrives and one declaration is made per poll).
pub type Events = heapless::Vec<Event, 4>;

/// Hand termination token `t` to link `l` (the ring's next position); whether it took it.
pub fn send_token(links: &mut impl Links, l: usize, t: &Token) -> bool {
    let mut buf = [0u8; 8];
    let mut w = SliceWriter::new(&mut buf);
    put_token(&mut w, t).is_ok() && links.send(l, KIND_TOKEN, w.written())
}

/// Retransmitted frames and skipped bytes over the neighbour links (the reports' link health).
fn repairs(links: &impl Links) -> (u32, u32) {
    (1..=LINKS).fold((0, 0), |(r, s), l| (r + links.stats(l).retransmitted, s + links.stats(l).skipped))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ring_head_is_read_only_when_its_link_and_position_make_sense() {
        // Board 1 of a 2 × 2 grid: neighbours W (board 0) and N (board 3), ring position 1 of
        // 4, its next ring position on link N (1).
        let ok = [1, NONE, 3, 0, NONE, 1, 4, 1];
        let ring = Ring { id: 1, neighbours: [NONE, 3, 0, NONE], position: 1, next: 1 };
        assert_eq!(Ring::parse(&ok), Some(ring));
        assert_eq!(Ring::parse(&[ok.as_slice(), &[9, 9]].concat()), Some(ring), "a longer configuration");
        assert!(ring.connected(1) && ring.connected(2) && !ring.connected(0) && !ring.connected(3));
        let with = |i: usize, v: u8| {
            let mut p = ok;
            p[i] = v;
            Ring::parse(&p)
        };
        assert_eq!(with(7, 0), None, "the ring link has no neighbour (E)");
        assert_eq!(with(7, 4), None, "no link 4");
        assert_eq!(with(6, 1), None, "position 1 in a ring of 1");
        assert_eq!(Ring::parse(&ok[..7]), None, "too short");
    }
}
