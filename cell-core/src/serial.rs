//! §4.4 — a reliable frame link over a byte stream (a UART): the wire codec's frames, each
//! delivered exactly once and in order, whatever bytes the wire corrupts, drops or inserts.
//!
//! A [`SerialLink`] is one end of a point-to-point link between two boards (or a board and
//! the host) whose only physical layer is a byte stream, driven through `embedded-io`'s
//! [`Read`], [`ReadReady`], [`Write`] and [`WriteReady`] (a UART driver, a TCP socket, an
//! in-memory pipe). It carries [`crate::wire`] frames unchanged (`kind u8 | len u16 | seq u8,
//! body | crc32`: every link frame's payload starts with its sequence number) and adds the
//! protocol around them, stop-and-wait automatic repeat request:
//!
//! * **Send**: [`SerialLink::send`] takes one frame (kind and body) while none is outstanding
//!   ([`SerialLink::can_send`]); the link writes it with the next sequence number and writes
//!   it again every `timeout` ticks (the caller's clock, [`SerialLink::poll`]'s `now`) until
//!   the far end's acknowledgement ([`KIND_ACK`], the same sequence number) comes back.
//! * **Receive**: a frame whose sequence number is the expected one is kept in a one-frame
//!   inbox ([`SerialLink::received`]) until the application takes it ([`SerialLink::pop`]);
//!   only then is it acknowledged (the *ready/ack flow control*: a receiver that cannot take a
//!   frame yet leaves it unacknowledged, and the sender keeps it). A copy of the frame just
//!   taken (its acknowledgement was lost) is acknowledged again, never delivered again.
//! * **Resynchronisation**: received bytes collect in a buffer of `N` bytes; the frame at its
//!   start is parsed ([`read_frame`]: length, CRC). A frame whose CRC fails, whose length
//!   cannot fit the buffer or is wrong for an acknowledgement, costs its first byte only: the
//!   hunt goes on from the next byte, so the next intact frame is found wherever it starts
//!   (after a dropped byte, a corrupted length, inserted noise). A partial frame that stays
//!   incomplete for four timeouts ([`STALE_TIMEOUTS`]) loses its first byte the same way (a
//!   corrupted length announcing more bytes than will come must not stall the link; a slow but
//!   real frame lost this way is sent again).
//!
//! **Invariant** (exactly once, in order). If the byte stream between the two ends keeps the
//! order of the bytes it delivers (it may corrupt, drop or insert any of them), CRC-32 catches
//! every corrupted frame, and both ends keep calling [`SerialLink::poll`], then the sequence of
//! frames the application takes at one end ([`SerialLink::received`], then
//! [`SerialLink::pop`]) is a prefix of the sequence [`SerialLink::send`] accepted at the other,
//! and grows to all of it while the stream delivers intact frames now and then. Why: at most one data frame is outstanding, so every data frame
//! that reaches the receiver carries the expected sequence number `e` (the outstanding frame)
//! or `e − 1` (a late copy of the one before: all earlier copies were written before it, and
//! the stream does not reorder); only `e` is delivered, and `e` advances on delivery. Likewise
//! every acknowledgement that reaches the sender is for the outstanding frame or the one
//! before, and only the outstanding one's releases it. Sequence numbers are `u8` and wrap: two
//! live values never collide. Dropping bytes on the receiving side (the hunt, the stale
//! partial frame) is a loss like any on the wire, which the retransmission repairs.
//!
//! What the link does not survive: a restart of one end (both start at sequence number 0 and
//! must stay in step), and a corrupted frame whose CRC still checks (probability 2⁻³² per
//! corrupted frame).
//!
//! ```
//! use cell_core::serial::SerialLink;
//! use cell_core::wire::KIND_BEAM;
//!
//! // An in-memory byte stream (each end reads what the other wrote).
//! #[derive(Default)]
//! struct Pipe { a_to_b: Vec<u8>, b_to_a: Vec<u8> }
//! struct End<'a> { rx: &'a mut Vec<u8>, tx: &'a mut Vec<u8> }
//! impl embedded_io::ErrorType for End<'_> { type Error = core::convert::Infallible; }
//! impl embedded_io::Read for End<'_> {
//!     fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
//!         let n = buf.len().min(self.rx.len());
//!         buf[..n].copy_from_slice(&self.rx[..n]);
//!         self.rx.drain(..n);
//!         Ok(n)
//!     }
//! }
//! impl embedded_io::ReadReady for End<'_> {
//!     fn read_ready(&mut self) -> Result<bool, Self::Error> { Ok(!self.rx.is_empty()) }
//! }
//! impl embedded_io::Write for End<'_> {
//!     fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
//!         self.tx.extend_from_slice(buf);
//!         Ok(buf.len())
//!     }
//!     fn flush(&mut self) -> Result<(), Self::Error> { Ok(()) }
//! }
//! impl embedded_io::WriteReady for End<'_> {
//!     fn write_ready(&mut self) -> Result<bool, Self::Error> { Ok(true) }
//! }
//!
//! let mut pipe = Pipe::default();
//! let (mut a, mut b) = (SerialLink::<64>::new(100), SerialLink::<64>::new(100));
//! a.send(KIND_BEAM, b"hello").unwrap();
//! for now in 0..10 {
//!     a.poll(now, &mut End { rx: &mut pipe.b_to_a, tx: &mut pipe.a_to_b }).unwrap();
//!     if now == 0 {
//!         pipe.a_to_b[4] ^= 0x20; // the first copy is corrupted on the wire
//!     }
//!     b.poll(now, &mut End { rx: &mut pipe.a_to_b, tx: &mut pipe.b_to_a }).unwrap();
//!     if let Some(frame) = b.received() {
//!         assert_eq!((frame.kind, frame.payload), (KIND_BEAM, &b"hello"[..]));
//!         b.pop();
//!     }
//! }
//! // Not yet: the corrupted copy was refused and the retransmission waits for the timeout.
//! assert_eq!(b.stats().delivered, 0);
//! for now in 100..110 {
//!     a.poll(now, &mut End { rx: &mut pipe.b_to_a, tx: &mut pipe.a_to_b }).unwrap();
//!     b.poll(now, &mut End { rx: &mut pipe.a_to_b, tx: &mut pipe.b_to_a }).unwrap();
//!     if b.received().is_some() {
//!         b.pop();
//!     }
//! }
//! assert_eq!((b.stats().delivered, a.stats().retransmitted), (1, 1));
//! assert!(a.can_send()); // acknowledged
//! ```

use embedded_io::{Read, ReadReady, Write, WriteReady};
use heapless::Vec;

use crate::wire::{read_frame, write_frame, DecodeError, EncodeError, RawFrame, HEADER, KIND_ACK, TRAILER};

/// Counters of one end of a [`SerialLink`] (what the link did to survive its wire).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SerialStats {
    /// Data frames accepted by [`SerialLink::send`].
    pub sent: u32,
    /// Copies of data frames written again after a timeout.
    pub retransmitted: u32,
    /// Data frames acknowledged by the far end.
    pub acked: u32,
    /// Data frames delivered into the inbox (each once).
    pub delivered: u32,
    /// Copies of a delivered frame received again (acknowledged again, not delivered).
    pub duplicates: u32,
    /// Intact data frames refused because the inbox was full (left unacknowledged).
    pub refused: u32,
    /// Bytes skipped while hunting for a frame (bad CRC, impossible length, stale partial
    /// frame).
    pub skipped: u32,
    /// Intact frames that fit no state (an acknowledgement of nothing outstanding, a data
    /// frame with a sequence number neither expected nor just delivered).
    pub stray: u32,
}

/// Why [`SerialLink::send`] refused a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SendError {
    /// A frame is still outstanding (not acknowledged yet): wait for [`SerialLink::can_send`].
    Busy,
    /// The kind is [`KIND_ACK`], which the link reserves for itself.
    ReservedKind,
    /// The frame would not fit the link's `N`-byte buffers.
    TooLong,
}

impl From<EncodeError> for SendError {
    fn from(_: EncodeError) -> Self {
        SendError::TooLong
    }
}

/// The outstanding data frame's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Out {
    /// None: [`SerialLink::send`] may take one.
    Idle,
    /// Encoded in `out`, waiting for the transmitter (first copy or a retransmission).
    Due,
    /// A copy is being written.
    Writing,
    /// The last copy was written at this tick; waiting for its acknowledgement.
    Waiting(u64),
}

/// One end of a reliable frame link over a byte stream; `N` bytes per buffer (at least the
/// longest frame the link carries). See the module doc for the protocol and its invariant.
pub struct SerialLink<const N: usize> {
    /// Received bytes not framed yet.
    rx: Vec<u8, N>,
    /// Tick at which the last byte arrived (for the stale partial frame).
    rx_at: u64,
    /// The delivered frame the application has not taken: the whole frame as received.
    inbox: Vec<u8, N>,
    /// The outstanding data frame, encoded.
    out: Vec<u8, N>,
    out_state: Out,
    /// Sequence number of the outstanding (or next) data frame.
    out_seq: u8,
    /// Sequence number the next delivered frame must carry.
    expect: u8,
    /// An acknowledgement of `expect − 1` must be written.
    ack_due: bool,
    /// Bytes being written (a whole frame: acknowledgements never cut into a data frame).
    tx: Vec<u8, N>,
    tx_pos: usize,
    tx_is_data: bool,
    timeout: u64,
    /// The longest frame either end sends on this link ([`SerialLink::with_max_frame`]; `N`
    /// by default): a header announcing more is not a frame.
    max_frame: usize,
    stats: SerialStats,
}

/// A partial frame incomplete for this many timeouts loses its first byte (the hunt goes on
/// from the next).
pub const STALE_TIMEOUTS: u64 = 4;

/// The length of an acknowledgement frame.
const ACK_FRAME: usize = HEADER + 1 + TRAILER;

impl<const N: usize> SerialLink<N> {
    /// A link end at sequence number 0 that writes an unacknowledged frame again every
    /// `timeout` ticks of [`SerialLink::poll`]'s clock (and gives up on a partial frame that
    /// stays incomplete [`STALE_TIMEOUTS`] times as long).
    pub const fn new(timeout: u64) -> Self {
        SerialLink {
            rx: Vec::new(),
            rx_at: 0,
            inbox: Vec::new(),
            out: Vec::new(),
            out_state: Out::Idle,
            out_seq: 0,
            expect: 0,
            ack_due: false,
            tx: Vec::new(),
            tx_pos: 0,
            tx_is_data: false,
            timeout,
            max_frame: N,
            stats: SerialStats {
                sent: 0,
                retransmitted: 0,
                acked: 0,
                delivered: 0,
                duplicates: 0,
                refused: 0,
                skipped: 0,
                stray: 0,
            },
        }
    }

    /// This link with frames of at most `max` bytes (header, sequence number, body and CRC;
    /// capped at `N`), both ways: [`SerialLink::send`] refuses a longer one
    /// ([`SendError::TooLong`]), and the receiver's hunt treats a header announcing a longer one
    /// as noise at once. Both ends of a link must agree. A link whose buffer must hold long
    /// frames for one use but carries only short ones in another resynchronises faster with the
    /// short limit: a corrupted length it would otherwise wait for (receiving retransmissions
    /// into the bogus frame until it is complete, or stale) costs it only one skipped byte.
    pub const fn with_max_frame(mut self, max: usize) -> Self {
        self.max_frame = if max < N { max } else { N };
        self
    }

    /// What the link did so far.
    pub fn stats(&self) -> SerialStats {
        self.stats
    }

    /// Whether [`SerialLink::send`] would take a frame now (none is outstanding).
    pub fn can_send(&self) -> bool {
        self.out_state == Out::Idle
    }

    /// Whether everything sent was acknowledged and nothing is left to write (an
    /// acknowledgement included): the link is quiet on this end.
    pub fn idle(&self) -> bool {
        self.can_send() && !self.ack_due && self.tx_pos >= self.tx.len()
    }

    /// Send one frame of `kind` whose payload is `seq` (the link's) then `body`. Refused while
    /// a frame is outstanding.
    pub fn send(&mut self, kind: u8, body: &[u8]) -> Result<(), SendError> {
        if kind == KIND_ACK {
            return Err(SendError::ReservedKind);
        }
        if !self.can_send() {
            return Err(SendError::Busy);
        }
        let mut buf = [0u8; N];
        let seq = self.out_seq;
        let len = write_frame(&mut buf, kind, |w| {
            use crate::wire::ByteSink;
            w.put(&[seq])?;
            w.put(body)
        })?;
        if len > self.max_frame {
            return Err(SendError::TooLong);
        }
        self.out.clear();
        // Cannot fail: `len` ≤ N.
        let _ = self.out.extend_from_slice(&buf[..len]);
        self.out_state = Out::Due;
        self.stats.sent += 1;
        Ok(())
    }

    /// The delivered frame waiting to be taken, if any: its kind and its body (the payload
    /// after the sequence number).
    pub fn received(&self) -> Option<RawFrame<'_>> {
        let (raw, _) = read_frame(&self.inbox).ok()?;
        Some(RawFrame { kind: raw.kind, payload: raw.payload.get(1..)? })
    }

    /// Take the delivered frame (drop it from the inbox) and acknowledge it. Returns whether
    /// there was one.
    pub fn pop(&mut self) -> bool {
        if self.inbox.is_empty() {
            return false;
        }
        self.inbox.clear();
        self.ack_due = true;
        true
    }

    /// One step of the link at tick `now` (any monotonic count: loop iterations, timer
    /// ticks): read what the stream has, deliver and acknowledge, write what is due while the
    /// stream takes bytes. Never blocks (reads and writes only when the stream says it is
    /// ready).
    pub fn poll<S>(&mut self, now: u64, io: &mut S) -> Result<(), S::Error>
    where
        S: Read + ReadReady + Write + WriteReady,
    {
        // Receive.
        while !self.rx.is_full() && io.read_ready()? {
            let mut chunk = [0u8; 16];
            let room = (N - self.rx.len()).min(chunk.len());
            let n = io.read(&mut chunk[..room])?;
            if n == 0 {
                break;
            }
            let _ = self.rx.extend_from_slice(&chunk[..n]);
            self.rx_at = now;
        }
        self.hunt();
        if !self.rx.is_empty() && now.saturating_sub(self.rx_at) >= self.timeout.saturating_mul(STALE_TIMEOUTS) {
            // A partial frame that will not complete (its length was corrupted, or its end
            // dropped): skip its first byte and hunt again from the next.
            self.skip(1);
            self.rx_at = now;
            self.hunt();
        }

        // Transmit: a whole frame at a time; an acknowledgement before the data frame.
        if self.tx_pos >= self.tx.len() {
            if self.tx_is_data {
                self.tx_is_data = false;
                if self.out_state == Out::Writing {
                    self.out_state = Out::Waiting(now);
                }
            }
            if let Out::Waiting(at) = self.out_state {
                if now.saturating_sub(at) >= self.timeout {
                    self.out_state = Out::Due;
                    self.stats.retransmitted += 1;
                }
            }
            self.tx.clear();
            self.tx_pos = 0;
            if self.ack_due {
                self.ack_due = false;
                let seq = self.expect.wrapping_sub(1);
                let mut buf = [0u8; ACK_FRAME];
                if let Ok(len) = write_frame(&mut buf, KIND_ACK, |w| crate::wire::ByteSink::put(w, &[seq])) {
                    let _ = self.tx.extend_from_slice(&buf[..len]);
                }
            } else if self.out_state == Out::Due {
                let _ = self.tx.extend_from_slice(&self.out);
                self.out_state = Out::Writing;
                self.tx_is_data = true;
            }
        }
        while self.tx_pos < self.tx.len() && io.write_ready()? {
            let n = io.write(&self.tx[self.tx_pos..])?;
            if n == 0 {
                break;
            }
            self.tx_pos += n;
        }
        if self.tx_is_data && self.tx_pos >= self.tx.len() && self.out_state == Out::Writing {
            self.out_state = Out::Waiting(now);
        }
        Ok(())
    }

    /// Drop `n` bytes from the front of the receive buffer, counted as skipped.
    fn skip(&mut self, n: usize) {
        let n = n.min(self.rx.len());
        self.stats.skipped += n as u32;
        self.consume(n);
    }

    fn consume(&mut self, n: usize) {
        let n = n.min(self.rx.len());
        self.rx.copy_within(n.., 0);
        self.rx.truncate(self.rx.len() - n);
    }

    /// Frame what the receive buffer holds: handle every intact frame at its start, skip a
    /// byte at a time past what cannot be one, stop at an incomplete frame.
    fn hunt(&mut self) {
        while self.rx.len() >= HEADER {
            let len = u16::from_le_bytes([self.rx[1], self.rx[2]]) as usize;
            let impossible =
                len == 0 || HEADER + len + TRAILER > self.max_frame || (self.rx[0] == KIND_ACK && len != 1);
            if impossible {
                self.skip(1);
                continue;
            }
            match read_frame(&self.rx) {
                Ok((raw, used)) => {
                    let (kind, seq) = (raw.kind, raw.payload[0]);
                    self.handle(kind, seq, used);
                    self.consume(used);
                }
                Err(DecodeError::Truncated) => break,
                Err(_) => self.skip(1),
            }
        }
    }

    /// An intact frame of `kind` with sequence number `seq`, the first `used` bytes of the
    /// receive buffer.
    fn handle(&mut self, kind: u8, seq: u8, used: usize) {
        if kind == KIND_ACK {
            let outstanding = matches!(self.out_state, Out::Writing | Out::Waiting(_) | Out::Due);
            if outstanding && seq == self.out_seq {
                self.out_state = Out::Idle;
                self.out.clear();
                self.out_seq = self.out_seq.wrapping_add(1);
                self.stats.acked += 1;
                if self.tx_is_data {
                    // A retransmitted copy is still being written: let it finish, but it no
                    // longer belongs to anything outstanding.
                    self.tx_is_data = false;
                }
            } else {
                self.stats.stray += 1;
            }
        } else if seq == self.expect {
            if self.inbox.is_empty() {
                let _ = self.inbox.extend_from_slice(&self.rx[..used]);
                self.expect = self.expect.wrapping_add(1);
                self.stats.delivered += 1;
            } else {
                self.stats.refused += 1;
            }
        } else if seq == self.expect.wrapping_sub(1) {
            self.stats.duplicates += 1;
            // Its acknowledgement was lost: acknowledge again, unless the application has not
            // taken it yet (then `pop` will).
            if self.inbox.is_empty() {
                self.ack_due = true;
            }
        } else {
            self.stats.stray += 1;
        }
    }
}

impl<const N: usize> Default for SerialLink<N> {
    /// A link end with a timeout of 1 000 ticks.
    fn default() -> Self {
        Self::new(1000)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::collections::VecDeque;
    use std::vec::Vec as StdVec;

    use proptest::prelude::*;

    use super::*;
    use crate::wire::{KIND_BEAM, KIND_ROW, KIND_TOKEN};

    /// One direction of a byte stream with at most `cap` bytes in flight, that corrupts
    /// (flips bits of), drops and inserts bytes with the given rates (per 10 000 bytes),
    /// from a seeded generator. It never reorders.
    struct Wire {
        bytes: VecDeque<u8>,
        cap: usize,
        rng: u64,
        corrupt: u64,
        drop: u64,
        insert: u64,
        faults: u32,
    }

    impl Wire {
        fn new(seed: u64, cap: usize, corrupt: u64, drop: u64, insert: u64) -> Self {
            Wire { bytes: VecDeque::new(), cap, rng: seed | 1, corrupt, drop, insert, faults: 0 }
        }

        fn next(&mut self) -> u64 {
            // xorshift64*
            self.rng ^= self.rng >> 12;
            self.rng ^= self.rng << 25;
            self.rng ^= self.rng >> 27;
            self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11
        }

        fn push(&mut self, b: u8) {
            let r = self.next() % 10_000;
            if r < self.drop {
                self.faults += 1;
            } else if r < self.drop + self.corrupt {
                self.faults += 1;
                let flip = (self.next() % 255 + 1) as u8;
                self.bytes.push_back(b ^ flip);
            } else if r < self.drop + self.corrupt + self.insert {
                self.faults += 1;
                let noise = self.next() as u8;
                self.bytes.push_back(noise);
                self.bytes.push_back(b);
            } else {
                self.bytes.push_back(b);
            }
        }
    }

    struct End<'a> {
        rx: &'a mut Wire,
        tx: &'a mut Wire,
    }

    impl embedded_io::ErrorType for End<'_> {
        type Error = core::convert::Infallible;
    }

    impl Read for End<'_> {
        fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
            let mut n = 0;
            while n < buf.len() {
                let Some(b) = self.rx.bytes.pop_front() else { break };
                buf[n] = b;
                n += 1;
            }
            Ok(n)
        }
    }

    impl ReadReady for End<'_> {
        fn read_ready(&mut self) -> Result<bool, Self::Error> {
            Ok(!self.rx.bytes.is_empty())
        }
    }

    impl Write for End<'_> {
        fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
            let n = buf.len().min(self.tx.cap.saturating_sub(self.tx.bytes.len())).max(1);
            for &b in &buf[..n] {
                self.tx.push(b);
            }
            Ok(n)
        }
        fn flush(&mut self) -> Result<(), Self::Error> {
            Ok(())
        }
    }

    impl WriteReady for End<'_> {
        fn write_ready(&mut self) -> Result<bool, Self::Error> {
            Ok(self.tx.bytes.len() < self.tx.cap)
        }
    }

    /// Frame `i` of a direction: a kind and a body whose length and bytes depend on `i`.
    fn frame(dir: u8, i: usize) -> (u8, StdVec<u8>) {
        let kind = [KIND_BEAM, KIND_ROW, KIND_TOKEN][i % 3];
        let len = 1 + (i * 7 + dir as usize) % 40;
        let body = (0..len).map(|j| (i as u8).wrapping_mul(31).wrapping_add(j as u8) ^ dir).collect();
        (kind, body)
    }

    const TIMEOUT: u64 = 40;

    /// The frames one end received, in order: kind and body.
    type Received = StdVec<(u8, StdVec<u8>)>;

    /// Both ends send `count` frames to each other over two faulty wires; the receivers take
    /// frames only on some ticks (back-pressure). Returns what each end received, in order,
    /// the two ends' counters and the faults the wires injected.
    fn exchange(
        seed: u64,
        count: usize,
        (corrupt, drop, insert): (u64, u64, u64),
        cap: usize,
    ) -> ([Received; 2], [SerialStats; 2], u32) {
        let mut wires = [
            Wire::new(seed, cap, corrupt, drop, insert),
            Wire::new(seed.rotate_left(17) ^ 0x9E37, cap, corrupt, drop, insert),
        ];
        let mut ends = [SerialLink::<64>::new(TIMEOUT), SerialLink::<64>::new(TIMEOUT)];
        let mut next = [0usize; 2];
        let mut got: [Received; 2] = [StdVec::new(), StdVec::new()];
        let limit = (count as u64 + 10) * (TIMEOUT + 20) * 20;
        let mut now = 0;
        while got[0].len() < count || got[1].len() < count || !ends[0].idle() || !ends[1].idle() {
            assert!(now < limit, "no progress after {now} ticks: received {} and {}", got[0].len(), got[1].len());
            for e in 0..2 {
                if next[e] < count && ends[e].can_send() {
                    let (kind, body) = frame(e as u8, next[e]);
                    ends[e].send(kind, &body).unwrap();
                    next[e] += 1;
                }
                let (w0, w1) = wires.split_at_mut(1);
                let (rx, tx) = if e == 0 { (&mut w1[0], &mut w0[0]) } else { (&mut w0[0], &mut w1[0]) };
                ends[e].poll(now, &mut End { rx, tx }).unwrap();
                // End e takes a frame on two ticks of three.
                if (now + e as u64) % 3 != 0 {
                    if let Some(f) = ends[e].received() {
                        got[e].push((f.kind, f.payload.to_vec()));
                        assert!(ends[e].pop());
                    }
                }
            }
            now += 1;
        }
        (got, [ends[0].stats(), ends[1].stats()], wires[0].faults + wires[1].faults)
    }

    fn expected(dir: u8, count: usize) -> Received {
        (0..count).map(|i| frame(dir, i)).collect()
    }

    #[test]
    fn a_clean_wire_delivers_everything_once_without_retransmission() {
        let (got, stats, faults) = exchange(1, 300, (0, 0, 0), 1000);
        assert_eq!(faults, 0);
        assert_eq!(got[0], expected(1, 300));
        assert_eq!(got[1], expected(0, 300));
        for s in stats {
            assert_eq!((s.sent, s.acked, s.delivered), (300, 300, 300));
            assert_eq!((s.retransmitted, s.skipped, s.duplicates, s.stray), (0, 0, 0, 0));
        }
    }

    #[test]
    fn a_very_noisy_narrow_wire_still_delivers_everything_once_in_order() {
        // 2 % of the bytes corrupted, 2 % dropped, 1 % noise inserted; 5 bytes in flight.
        let (got, stats, faults) = exchange(7, 300, (200, 200, 100), 5);
        assert!(faults > 500, "{faults}");
        assert_eq!(got[0], expected(1, 300));
        assert_eq!(got[1], expected(0, 300));
        for s in stats {
            assert_eq!((s.sent, s.acked, s.delivered), (300, 300, 300));
            assert!(s.retransmitted > 0 && s.skipped > 0, "{s:?}");
        }
    }

    #[test]
    fn refusals_are_values() {
        let mut l = SerialLink::<16>::new(10);
        assert_eq!(l.send(KIND_ACK, &[]), Err(SendError::ReservedKind));
        assert_eq!(l.send(KIND_BEAM, &[0; 9]), Err(SendError::TooLong));
        assert_eq!(l.send(KIND_BEAM, &[0; 8]), Ok(()));
        assert_eq!(l.send(KIND_BEAM, &[0; 1]), Err(SendError::Busy));
        assert!(!l.pop());
        assert!(l.received().is_none());
    }

    #[test]
    fn a_shorter_frame_limit_refuses_long_frames_and_skips_their_headers_at_once() {
        // Sending: 8 bytes of frame around the body.
        let mut l = SerialLink::<64>::new(5).with_max_frame(32);
        assert_eq!(l.send(KIND_BEAM, &[0; 25]), Err(SendError::TooLong));
        assert_eq!(l.send(KIND_BEAM, &[0; 24]), Ok(()));
        // Receiving: a header announcing a 40-byte frame (it fits 64) is noise under the limit
        // of 32, the start of a frame without it.
        for (limit, skipped) in [(32, 1), (64, 0)] {
            let (mut rx, mut tx) = (Wire::new(1, 100, 0, 0, 0), Wire::new(2, 100, 0, 0, 0));
            rx.bytes.extend([KIND_BEAM, 33, 0]);
            let mut l = SerialLink::<64>::new(5).with_max_frame(limit);
            l.poll(0, &mut End { rx: &mut rx, tx: &mut tx }).unwrap();
            assert_eq!(l.stats().skipped, skipped, "limit {limit}");
        }
    }

    #[test]
    fn garbage_alone_is_skipped_never_delivered() {
        let mut rx = Wire::new(3, 10_000, 0, 0, 0);
        let mut tx = Wire::new(4, 10_000, 0, 0, 0);
        let mut g = Wire::new(5, 0, 0, 0, 0);
        rx.bytes.extend((0..5000).map(|_| g.next() as u8));
        let mut l = SerialLink::<64>::new(5);
        for now in 0..20_000 {
            l.poll(now, &mut End { rx: &mut rx, tx: &mut tx }).unwrap();
            assert!(l.received().is_none());
        }
        assert!(rx.bytes.is_empty() && tx.bytes.is_empty());
        assert_eq!(l.stats().delivered, 0);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// Every frame delivered exactly once, in order, in both directions, whatever bytes
        /// the wires corrupt, drop or insert.
        #[test]
        fn every_frame_exactly_once_in_order(
            seed in any::<u64>(),
            corrupt in 0u64..100,
            drop in 0u64..100,
            insert in 0u64..50,
            cap in 1usize..200,
            count in 1usize..120,
        ) {
            let (got, stats, _) = exchange(seed, count, (corrupt, drop, insert), cap);
            prop_assert_eq!(&got[0], &expected(1, count));
            prop_assert_eq!(&got[1], &expected(0, count));
            for s in stats {
                prop_assert_eq!((s.sent, s.acked, s.delivered), (count as u32, count as u32, count as u32));
            }
        }
    }
}
