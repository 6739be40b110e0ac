//! The links between cells (thesis §4.4: one message per link, direction and cycle, credits, no
//! loss): the level every stepping phase sends through, below them all.
//!
//! * this module — the grid's links behind `cell_core::link::Link` (the link seam).
//! * [`faults`] — the fault-injecting link wrapper (a lossy wire and stop-and-wait).
//! * [`tap`] — recording cell traces: the tracing link wrapper and the per-cell recorders the
//!   phases feed, for the firmware to replay.
//!
//! Invariant: a link hands its far end every message once and in order, whatever wraps it (a
//! fault is retransmitted, never applied twice); the step acts on the link's answer alone.
//! The links stand on the grid level only; the phases hand them their events, never the
//! reverse.
//!
//! The grid's links: one [`Link`] (`cell_core::link`'s seam) per directed neighbour link, and
//! the receiving end the host hands them, a cell's FIFO as an [`Inbox`].
//!
//! The lighting phase's link step ([`crate::machine::lighting::diffuse`]) offers each sender's head
//! message to its link and acts on the answer ([`cell_core::link::Sent`]) alone: the same step drives the
//! perfect links ([`cell_core::link::PerfectLink`], the default), the fault injector
//! ([`crate::machine::links::faults::FaultInjector`]) and the tracer ([`crate::machine::links::tap::Tracer`]),
//! each wrapping any link. The link set is chosen once per run; the step is generic over it
//! (static dispatch, nothing allocated per message).

pub mod faults;
pub mod tap;

use std::convert::Infallible;

use cell_core::beam::FracBits;
use cell_core::light::{ActivityDelta, BeamMsg, Port};
use cell_core::link::{Inbox, Link};

use crate::machine::grid::capacity::HostLightCell;

/// Port index of the receiving end of a link that leaves through port `p`: `BACK[p]`.
pub const BACK: [usize; 8] = {
    let mut b = [0; 8];
    let mut p = 0;
    while p < 8 {
        let (dx, dy) = Port::ALL[p].delta();
        b[p] = match Port::from_delta(-dx, -dy) {
            Some(q) => q.index(),
            None => panic!("the opposite of a unit step is a unit step"),
        };
        p += 1;
    }
    b
};

/// A directed link of the grid: cell `from` sends through its port `port` to cell `to`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkId {
    /// Sending cell (row-major index; `u32::MAX` for a link from outside the grid, never used).
    pub from: u32,
    /// Its output port.
    pub port: Port,
    /// Receiving cell.
    pub to: u32,
}

/// A beam a link's far end took (its sender pops it): what a trace records.
#[derive(Clone, Copy, Debug)]
pub struct Took<F: FracBits> {
    /// The link.
    pub link: LinkId,
    /// The beam.
    pub msg: BeamMsg<F>,
}

/// Where a link wrapper that records ([`crate::machine::links::tap::Tracer`]) writes.
pub trait Journal<F: FracBits> {
    /// A link's far end took a beam.
    fn took(&mut self, t: Took<F>);
}

/// The receiving end of a host link: cell `cell`'s FIFO (limit `fa`, merging arrivals with
/// `merge`), the beam count change of the piece of the link step that owns the cell, and the
/// piece's journal (written only by recording links).
pub struct CellInbox<'a, F: FracBits> {
    /// The receiving cell.
    pub cell: &'a mut HostLightCell<F>,
    /// Its FIFO limit.
    pub fa: usize,
    /// Merge arriving beams into waiting ones.
    pub merge: bool,
    /// The piece's beam count change.
    pub tally: &'a ActivityDelta,
    /// The piece's journal, in link order.
    pub journal: &'a mut Vec<Took<F>>,
}

impl<F: FracBits> Inbox<F> for CellInbox<'_, F> {
    #[inline(always)]
    fn has_room(&self) -> bool {
        self.cell.can_accept(self.fa)
    }

    #[inline(always)]
    fn put(&mut self, msg: BeamMsg<F>) -> bool {
        self.cell.accept(msg, self.merge, self.tally).is_ok()
    }
}

impl<F: FracBits> Journal<F> for CellInbox<'_, F> {
    fn took(&mut self, t: Took<F>) {
        self.journal.push(t);
    }
}

/// A link the host grid can drive: any [`Link`] into a [`CellInbox`] that cannot fail and can
/// move between the threads of the link step.
pub trait HostLink<F: FracBits>: for<'a> Link<F, CellInbox<'a, F>, Error = Infallible> + Send {}

impl<F: FracBits, L> HostLink<F> for L where L: for<'a> Link<F, CellInbox<'a, F>, Error = Infallible> + Send {}

/// [`Link::LOSSLESS`] of a host link.
pub fn lossless<F: FracBits + 'static, L: HostLink<F>>() -> bool {
    <L as Link<F, CellInbox<'static, F>>>::LOSSLESS
}

/// The value of a link answer that cannot be an error.
#[inline(always)]
pub fn sure<T>(r: Result<T, Infallible>) -> T {
    match r {
        Ok(v) => v,
        Err(e) => match e {},
    }
}

/// The links of an n × n grid, stored by receiving end: slot `to · 8 + BACK[port]` holds the
/// link into cell `to` (so that a piece of receivers owns its links). Border slots, whose
/// sender would lie outside the grid, hold a link that is never used.
pub struct GridLinks<L> {
    links: Vec<L>,
}

impl<L> GridLinks<L> {
    /// The links of an n × n grid, `make` building each.
    pub fn new(n: u32, make: impl FnMut(LinkId) -> L) -> Self {
        Self::into_cells(n, 0..n * n, make)
    }

    /// The links into cells `cells` (row-major indices) of an n × n grid, `make` building each:
    /// what a tile of the grid holds. Link `slot(to, port) − 8 · cells.start` leads into `to`.
    pub fn into_cells(n: u32, cells: std::ops::Range<u32>, mut make: impl FnMut(LinkId) -> L) -> Self {
        let mut links = Vec::with_capacity(cells.len() * 8);
        for to in cells {
            let (x, y) = ((to % n) as i64, (to / n) as i64);
            for back in Port::ALL {
                let (dx, dy) = back.delta();
                let (fx, fy) = (x + dx as i64, y + dy as i64);
                let inside = (0..n as i64).contains(&fx) && (0..n as i64).contains(&fy);
                let from = if inside { (fy * n as i64 + fx) as u32 } else { u32::MAX };
                links.push(make(LinkId { from, port: Port::ALL[BACK[back.index()]], to }));
            }
        }
        GridLinks { links }
    }

    /// Every link, by receiving end.
    pub fn slots(&mut self) -> &mut [L] {
        &mut self.links
    }

    /// Every link, by receiving end.
    pub fn all(&self) -> &[L] {
        &self.links
    }
}

/// Slot of the link from cell `from` through port `port` into cell `to` (see [`GridLinks`]).
#[inline(always)]
pub fn slot(to: u32, port: u8) -> usize {
    to as usize * 8 + BACK[port as usize]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_hold_the_link_into_their_cell() {
        let n = 5;
        let mut g = GridLinks::new(n, |id| id);
        for (s, id) in g.slots().iter().enumerate() {
            assert_eq!(id.to as usize, s / 8);
            if id.from != u32::MAX {
                let (dx, dy) = id.port.delta();
                let to = id.from as i64 + dy as i64 * n as i64 + dx as i64;
                assert_eq!(to, id.to as i64);
                assert_eq!(slot(id.to, id.port.index() as u8), s);
            }
        }
        // Directed links: 2 · 2 · n(n − 1) along the axes, 4 · (n − 1)² along the diagonals.
        assert_eq!(g.slots().iter().filter(|id| id.from != u32::MAX).count(), 2 * 2 * 5 * 4 + 4 * 4 * 4);
        // A band's links are the whole grid's into its cells, in the same order.
        let band = GridLinks::into_cells(n, 10..20, |id| id);
        assert_eq!(band.all(), &g.all()[80..160]);
    }
}
