//! What the link phase passes between a sender and its receiver's link (the parent module's
//! cycle model): the sender's offer, and the count of what the receiver took. Shared by the
//! cycle loop (`cycle`) and the tiles' edges (`tiles`), which carry both across a tile edge.

use cell_core::beam::FracBits;
use cell_core::light::BeamMsg;
use std::sync::atomic::AtomicU32;

/// A message offered on a link in the link phase: receiver, arbitration key, sender, port, and a
/// copy of the message at the front of the sender's output buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Offer<F: FracBits> {
    pub(super) to: u32,
    pub(super) key: u32,
    pub(super) from: u32,
    pub(super) port: u8,
    pub(super) msg: BeamMsg<F>,
}

/// Messages a sender's links delivered in one cycle: a 4-bit count per port (port p in bits
/// 4p ..= 4p + 3; a link carries at most [`Timing::link_rate`](crate::machine::lighting::timing::Timing::link_rate) ≤ `OB_CAP` < 16 per cycle).
pub(super) type Taken = AtomicU32;
