//! §4.4 — the link seam: one shape for every neighbour link, whatever carries it.
//!
//! [`Link`] is the one shape of a neighbour link, per output port: [`Link::ready`] (does the
//! neighbour have FIFO credit) and [`Link::send`] (hand it the head beam in a link cycle; the
//! answer, [`Sent`], says whether it was delivered and whether it was acknowledged). The wire
//! codec ([`crate::wire`]: frames, CRC) is separate from it: a link that carries bytes frames
//! its beams with [`Message::emit`]; one that does not (the host's perfect link) never pays for it. The far end is a
//! type parameter: `()` where a wire carries the frame to another chip, an [`Inbox`] (the
//! neighbour's FIFO) where one program runs both ends. Implementations and wrappers:
//!
//! * [`PerfectLink`] delivers into an [`Inbox`] at once: the host grid's default;
//! * [`HalLink`] runs over `embedded-hal` (the neighbour's ready line an [`InputPin`], the frame
//!   on an [`SpiDevice`]): the firmware;
//! * host-sim's `FaultInjector<L>` (`machine/links/faults.rs`) wraps any link with a seeded lossy wire
//!   (corrupt, drop, delay) and stop-and-wait acknowledgement, and host-sim's `Tracer<L>`
//!   (`machine/links/tap.rs`) wraps any link and records every beam the far end took; they compose
//!   (a traced faulty link is a `Tracer<FaultInjector<PerfectLink>>`);
//! * the trace replay's grant link ([`crate::trace`]) is ready on the granted port only.
//!
//! [`drain_outputs`] moves the heads of a light cell's output buffers onto its links.
//!
//! **Invariant** (the no-loss rule at the seam): the caller sends only after `ready` said yes,
//! one message per link and cycle, and keeps the message in its output buffer until a send
//! answers `acked`; it sends the same beam again until then. A link puts a beam into the
//! neighbour's FIFO at most once per message, and by the time it answers `acked` exactly once
//! (a corrupted frame is never applied). A link whose [`Link::LOSSLESS`] is true answers every
//! send to a ready neighbour with [`Sent::TAKEN`].
//!
//! ```
//! use cell_core::beam::{frac::U0, Beam, Direction, FarDistance, Source, SourceId};
//! use cell_core::light::BeamMsg;
//! use cell_core::link::{Inbox, Link, PerfectLink, Sent};
//!
//! /// A neighbour's FIFO of two beams.
//! struct Fifo(heapless::Vec<BeamMsg<U0>, 2>);
//!
//! impl Inbox<U0> for Fifo {
//!     fn has_room(&self) -> bool {
//!         !self.0.is_full()
//!     }
//!     fn put(&mut self, msg: BeamMsg<U0>) -> bool {
//!         self.0.push(msg).is_ok()
//!     }
//! }
//!
//! /// A wrapper: loses every other send (nothing reaches the far end), passes the others on.
//! struct EveryOther<L> {
//!     inner: L,
//!     lose: bool,
//! }
//!
//! impl<Rx: ?Sized, L: Link<U0, Rx>> Link<U0, Rx> for EveryOther<L> {
//!     type Error = L::Error;
//!     const LOSSLESS: bool = false;
//!     fn ready(&mut self, rx: &Rx) -> Result<bool, L::Error> {
//!         self.inner.ready(rx)
//!     }
//!     fn send(&mut self, now: u64, msg: &BeamMsg<U0>, rx: &mut Rx) -> Result<Sent, L::Error> {
//!         self.lose = !self.lose;
//!         if self.lose {
//!             return Ok(Sent::NOTHING);
//!         }
//!         self.inner.send(now, msg, rx)
//!     }
//! }
//!
//! let source = Source::at_voxel(SourceId(0), [1, 1, 1]).unwrap();
//! let far = FarDistance::<U0>::new(7).unwrap();
//! let beam = BeamMsg::new(Beam::initial(&source, Direction::PosX, far), 1);
//!
//! // A perfect link: delivered and acknowledged at once, until the FIFO is full.
//! let mut fifo = Fifo(heapless::Vec::new());
//! let mut link = PerfectLink;
//! assert!(<PerfectLink as Link<U0, Fifo>>::LOSSLESS);
//! for now in 0..2 {
//!     assert_eq!(link.ready(&fifo), Ok(true));
//!     assert_eq!(link.send(now, &beam, &mut fifo), Ok(Sent::TAKEN));
//! }
//! assert_eq!(link.ready(&fifo), Ok(false));
//!
//! // The same link wrapped: the first send is lost (the sender keeps the beam), the resend
//! // goes through. A wrapper is a link like any other: it could be wrapped again.
//! let mut fifo = Fifo(heapless::Vec::new());
//! let mut lossy = EveryOther { inner: PerfectLink, lose: false };
//! assert!(!<EveryOther<PerfectLink> as Link<U0, Fifo>>::LOSSLESS);
//! assert_eq!(lossy.send(0, &beam, &mut fifo), Ok(Sent::NOTHING));
//! assert!(fifo.0.is_empty());
//! assert_eq!(lossy.send(1, &beam, &mut fifo), Ok(Sent::TAKEN));
//! assert_eq!(fifo.0.as_slice(), &[beam]);
//! ```

use embedded_hal::digital::InputPin;
use embedded_hal::spi::SpiDevice;

use crate::beam::FracBits;
use crate::light::{BeamMsg, LightCell, Port};
use crate::wire::{EncodeError, Message, BEAM_PAYLOAD, HEADER, TRAILER};

/// What became of one [`Link::send`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sent {
    /// The beam entered the neighbour's FIFO in this call.
    pub delivered: bool,
    /// The neighbour holds the beam (its acknowledgement came back intact, or the link cannot
    /// lose it): the sender pops it. Until then the sender keeps it and sends it again later.
    pub acked: bool,
}

impl Sent {
    /// Delivered and acknowledged: what a lossless link answers to every send.
    pub const TAKEN: Sent = Sent { delivered: true, acked: true };
    /// Nothing reached the neighbour, nothing came back.
    pub const NOTHING: Sent = Sent { delivered: false, acked: false };
}

/// The receiving end of a link whose two ends one program runs (the host grid, a test): the
/// neighbour's input FIFO.
pub trait Inbox<F: FracBits> {
    /// Whether the FIFO has room for one more beam (the credit a ready line reports).
    fn has_room(&self) -> bool;
    /// Put a beam into the FIFO; `false` if it had no room.
    fn put(&mut self, msg: BeamMsg<F>) -> bool;
}

/// One directed neighbour link, as the output port of the sending cell sees it: is the
/// neighbour ready, and send it a beam. See the module doc ("The link seam") for the invariant
/// every implementation keeps.
///
/// `Rx` is the far end as the caller holds it: `()` where a wire carries the frame to another
/// chip ([`HalLink`]), an [`Inbox`] where one program runs both ends ([`PerfectLink`]).
/// Wrappers ([`Link`]s around a `Link`) pass it on untouched, so they compose with any link.
pub trait Link<F: FracBits, Rx: ?Sized = ()> {
    /// The link's error (a pin or bus error; [`core::convert::Infallible`] for simulated links).
    type Error;
    /// Every [`Link::send`] to a ready neighbour returns [`Sent::TAKEN`] (no loss, no delay,
    /// no acknowledgement round trip). A scheduler may rely on it: for such links a message
    /// sent is a message taken.
    const LOSSLESS: bool;
    /// Whether the neighbour can take one more message now (its FIFO has credit).
    fn ready(&mut self, rx: &Rx) -> Result<bool, Self::Error>;
    /// Send `msg`, the head of the port's output buffer, in link cycle `now` (a cycle count;
    /// links that do not model time ignore it). Called only after [`Link::ready`] said yes.
    fn send(&mut self, now: u64, msg: &BeamMsg<F>, rx: &mut Rx) -> Result<Sent, Self::Error>;
}

/// The perfect link: ready when the neighbour's FIFO has room, and a send puts the beam into
/// it, acknowledged at once. The host grid's default link.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PerfectLink;

impl<F: FracBits, I: Inbox<F> + ?Sized> Link<F, I> for PerfectLink {
    type Error = core::convert::Infallible;
    const LOSSLESS: bool = true;

    #[inline(always)]
    fn ready(&mut self, rx: &I) -> Result<bool, Self::Error> {
        Ok(rx.has_room())
    }

    #[inline(always)]
    fn send(&mut self, _now: u64, msg: &BeamMsg<F>, rx: &mut I) -> Result<Sent, Self::Error> {
        let ok = rx.put(*msg);
        Ok(Sent { delivered: ok, acked: ok })
    }
}

/// A [`Link`] over `embedded-hal`: the neighbour's ready line and an SPI frame link. A send
/// writes the beam's frame ([`Message::emit`], sequence number 0) and counts as taken: the wire and
/// the neighbour's receive interrupt are trusted not to lose it.
pub struct HalLink<P, S> {
    /// High when the neighbour has FIFO credit.
    pub ready: P,
    /// The frame link.
    pub spi: S,
}

/// Error of a [`HalLink`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HalLinkError<P, S> {
    /// Reading the ready line failed.
    Pin(P),
    /// The frame transfer failed.
    Spi(S),
    /// The frame could not be encoded (cannot happen for a beam: its frame is fixed-size).
    Encode(EncodeError),
}

impl<F: FracBits, P: InputPin, S: SpiDevice> Link<F> for HalLink<P, S> {
    type Error = HalLinkError<P::Error, S::Error>;
    const LOSSLESS: bool = true;

    fn ready(&mut self, _: &()) -> Result<bool, Self::Error> {
        self.ready.is_high().map_err(HalLinkError::Pin)
    }

    fn send(&mut self, _now: u64, msg: &BeamMsg<F>, _: &mut ()) -> Result<Sent, Self::Error> {
        let mut buf = [0u8; HEADER + BEAM_PAYLOAD + TRAILER];
        let len = Message::Beam(*msg).emit(0, &mut buf).map_err(HalLinkError::Encode)?;
        self.spi.write(&buf[..len]).map_err(HalLinkError::Spi)?;
        Ok(Sent::TAKEN)
    }
}

/// Error of [`drain_outputs`]: a link failed (the message stays in its output buffer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DrainError<E>(pub Port, pub E);

/// One link cycle (`now`) of a light cell's output side: for every port whose buffer is not
/// empty and whose neighbour is ready, send the head message over its link; pop it when the
/// link acknowledges it (`sent(port, beam)` sees each one), otherwise mark it in flight (a
/// head on the wire is not merged into, [`LightCell::head_in_flight`]). Returns how many were
/// popped.
pub fn drain_outputs<F: FracBits, const FA: usize, const OB: usize, const L: usize, K: Link<F>>(
    cell: &mut LightCell<F, FA, OB, L>,
    links: &mut [K; 8],
    now: u64,
    mut sent: impl FnMut(Port, &BeamMsg<F>),
) -> Result<u32, DrainError<K::Error>> {
    let mut count = 0;
    for p in Port::ALL {
        let Some(&m) = cell.out.front(p) else { continue };
        let link = &mut links[p.index()];
        if !link.ready(&()).map_err(|e| DrainError(p, e))? {
            continue;
        }
        let bit = 1u8 << p.index();
        if !link.send(now, &m, &mut ()).map_err(|e| DrainError(p, e))?.acked {
            cell.head_in_flight |= bit;
            continue;
        }
        cell.head_in_flight &= !bit;
        sent(p, &m);
        cell.out.pop_front(p);
        count += 1;
    }
    Ok(count)
}
