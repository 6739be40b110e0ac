//! Messages between cells: a beam with its voxel depth ([`BeamMsg`]), the local state a
//! ±z beam carries in its own column ([`Local`]), and the eight ports ([`Port`], thesis §4.4).

use super::*;

/// A beam in a message: the beam and the depth of its voxel in the receiving column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BeamMsg<F: FracBits> {
    /// The rays.
    pub beam: Beam<F>,
    /// The z of the beam's voxel (needed for ±x and ±y beams; for ±z beams it is implied by
    /// the layer but carried all the same).
    pub z: Depth,
    /// Cell-local, not sent on links: in a FIFO, the receiving cell's clock when the beam
    /// arrived (for the sibling wait, [`LightEnv::hold`]); 0 elsewhere. It lives in what would
    /// be padding.
    pub(super) since: u16,
    /// Cell-local, not sent on links: the plane rule's state of a FIFO entry ([`Local`]).
    pub(super) local: Local,
}

impl<F: FracBits> BeamMsg<F> {
    /// The message carrying `beam`, whose voxel is at depth `z` in the receiving column.
    pub const fn new(beam: Beam<F>, z: Depth) -> Self {
        BeamMsg { beam, z, since: 0, local: Local::NONE }
    }

    /// The plane rule's local state (none for a message on a link).
    pub const fn local(&self) -> Local {
        self.local
    }

    /// Whether it may merge with, or take in, another beam: no local state (a plain or a
    /// terminal beam that is not being peeled).
    pub fn mergeable(&self) -> bool {
        self.local == Local::NONE
    }
}

/// What a FIFO entry carries under the plane rule besides its rays, never sent on a link
/// (8 bytes): the column rule's notch ([`Notch`]: a ±z beam that stayed in its column after a
/// surface voxel), and how far the cell has peeled it (pieces of the current run already sent).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Local {
    pub(super) state: u16,
    pub(super) t1: u16,
    pub(super) t2: u16,
    pub(super) flags: u8,
    pub(super) piece: u8,
}

const HAS_NOTCH: u8 = 1;
const FRESH: u8 = 2;
const FRONT: u8 = 4;

impl Local {
    /// No state: a plain beam.
    pub const NONE: Local = Local { state: 0, t1: 0, t2: 0, flags: 0, piece: 0 };

    /// A beam with this notch.
    pub const fn notched(n: Notch) -> Local {
        let flags = HAS_NOTCH | if n.fresh { FRESH } else { 0 } | if n.front { FRONT } else { 0 };
        Local { state: n.state, t1: n.t1, t2: n.t2, flags, piece: 0 }
    }

    /// The notch, if any.
    pub const fn notch(&self) -> Option<Notch> {
        if self.flags & HAS_NOTCH == 0 {
            None
        } else {
            let (fresh, front) = (self.flags & FRESH != 0, self.flags & FRONT != 0);
            Some(Notch { state: self.state, t1: self.t1, t2: self.t2, fresh, front })
        }
    }

    /// Pieces of the current run already sent.
    pub const fn piece(&self) -> u8 {
        self.piece
    }
}

#[cfg(feature = "defmt")]
impl<F: FracBits> defmt::Format for BeamMsg<F> {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "BeamMsg {{ {}, z: {=u16} }}", self.beam, self.z)
    }
}

/// The 8 neighbour links, counter-clockwise from east (y grows to the north).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Port {
    /// (+1, 0)
    E = 0,
    /// (+1, +1)
    NE = 1,
    /// (0, +1)
    N = 2,
    /// (−1, +1)
    NW = 3,
    /// (−1, 0)
    W = 4,
    /// (−1, −1)
    SW = 5,
    /// (0, −1)
    S = 6,
    /// (+1, −1)
    SE = 7,
}

impl Port {
    /// All eight, in index order.
    pub const ALL: [Port; 8] = [Port::E, Port::NE, Port::N, Port::NW, Port::W, Port::SW, Port::S, Port::SE];

    /// The cell step (dx, dy) of this link.
    pub const fn delta(self) -> (i8, i8) {
        match self {
            Port::E => (1, 0),
            Port::NE => (1, 1),
            Port::N => (0, 1),
            Port::NW => (-1, 1),
            Port::W => (-1, 0),
            Port::SW => (-1, -1),
            Port::S => (0, -1),
            Port::SE => (1, -1),
        }
    }

    /// The link for a step (dx, dy); `None` for (0, 0) or a step longer than one cell.
    pub const fn from_delta(dx: i8, dy: i8) -> Option<Port> {
        Some(match (dx, dy) {
            (1, 0) => Port::E,
            (1, 1) => Port::NE,
            (0, 1) => Port::N,
            (-1, 1) => Port::NW,
            (-1, 0) => Port::W,
            (-1, -1) => Port::SW,
            (0, -1) => Port::S,
            (1, -1) => Port::SE,
            _ => return None,
        })
    }

    /// Index 0..8.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The ports whose bit is set in `mask` (bit p: port p), in port order. One
    /// `trailing_zeros` per port present, where filtering [`Port::ALL`] tests all eight.
    pub fn each(mask: u8) -> impl Iterator<Item = Port> {
        let mut m = mask;
        core::iter::from_fn(move || {
            let i = m.trailing_zeros() as usize;
            m &= m.wrapping_sub(1);
            Port::ALL.get(i).copied()
        })
    }
}
