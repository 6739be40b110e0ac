//! Faulty links: [`FaultInjector`] wraps any link (`cell_core::link::Link`) with a lossy wire.
//! Every send goes through the real wire codec (`cell_core::wire`: frame + CRC-32), and a
//! seeded fault injector in the spirit of smoltcp's `FaultInjector` corrupts, drops or delays
//! frames at given rates; what survives the wire is handed to the wrapped link (for the host
//! grid a [`cell_core::link::PerfectLink`] into the neighbour's FIFO).
//!
//! The link protocol that survives it is stop-and-wait with an alternating sequence bit per
//! link (sender, port):
//!
//! 1. the sender, when its neighbour has credit, sends the head of its output buffer as a data
//!    frame carrying the link's current sequence bit; the message **stays** in the buffer;
//! 2. the receiver decodes the frame; a frame whose CRC fails is discarded (never applied);
//!    a frame whose sequence bit equals the last one it accepted on that link is a duplicate
//!    (its acknowledgement was lost): discarded, but acknowledged again; otherwise the beam
//!    goes into the FIFO and the receiver acknowledges;
//! 3. the sender pops the message and flips the bit only when an intact acknowledgement
//!    arrives; otherwise it sends the same frame again in a later cycle (a retransmission).
//!
//! A delayed data frame stays on the wire for 1 ..= `delay_cycles` extra cycles (drawn per
//! frame) and arrives intact; the link carries nothing else meanwhile (stop-and-wait), and the
//! sender keeps the message until the acknowledgement of the frame's arrival comes back.
//!
//! A beam is therefore applied exactly once, and the no-loss rule holds: nothing leaves an
//! output buffer before the neighbour holds it. The lit voxels do not depend on when a beam
//! arrives (beam merging is exact, see `cell_core::light`), so a faulty run lights exactly what a clean run
//! lights, in more cycles. Fault decisions are a hash of (seed, cycle, link, frame kind), so a
//! run is reproducible whatever the thread count. Each link keeps its own protocol state and
//! counters; a run reports their sum.

use std::str::FromStr;

use cell_core::beam::{FarDistance, FracBits};
use cell_core::light::BeamMsg;
use cell_core::link::{Link, PerfectLink, Sent};
use cell_core::wire::{Frame, Message, HEADER, MAX_FRAME, TRAILER};

use crate::machine::links::{LinkId, BACK};

/// Fault rates, in parts per million, and the seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LinkFaults {
    /// Probability (ppm) that a frame has bits flipped on the way.
    pub corrupt_ppm: u32,
    /// Probability (ppm) that a frame is lost.
    pub drop_ppm: u32,
    /// Probability (ppm) that a data frame is held on the wire.
    pub delay_ppm: u32,
    /// Longest hold of a delayed frame, in cycles (each delay is 1 ..= this, drawn per frame).
    pub delay_cycles: u32,
    /// Seed of the fault decisions.
    pub seed: u64,
}

impl FromStr for LinkFaults {
    type Err = String;

    /// `corrupt=0.01,drop=0.01,delay=0.05,delay-cycles=8,seed=7` (rates in 0 ..= 1, 1 being a
    /// dead link; any part may be left out; the three rates may sum to at most 1).
    fn from_str(s: &str) -> Result<Self, String> {
        let mut f = LinkFaults::NONE;
        for part in s.split(',').filter(|p| !p.trim().is_empty()) {
            let (k, v) = part.split_once('=').ok_or_else(|| format!("'{part}': expected key=value"))?;
            let rate = || -> Result<u32, String> {
                let r: f64 = v.trim().parse().map_err(|_| format!("'{v}' is not a number"))?;
                if !(0.0..=1.0).contains(&r) {
                    return Err(format!("{k}={v}: a fault rate must lie in 0 ..= 1"));
                }
                Ok((r * 1e6).round() as u32)
            };
            match k.trim() {
                "corrupt" => f.corrupt_ppm = rate()?,
                "drop" => f.drop_ppm = rate()?,
                "delay" => f.delay_ppm = rate()?,
                "delay-cycles" => {
                    f.delay_cycles =
                        v.trim().parse().ok().filter(|k| (1..=MAX_DELAY_CYCLES).contains(k)).ok_or_else(|| {
                            format!("delay-cycles={v}: expected an integer in 1 ..= {MAX_DELAY_CYCLES}")
                        })?
                }
                "seed" => f.seed = v.trim().parse().map_err(|_| format!("seed '{v}' is not an integer"))?,
                other => {
                    return Err(format!("unknown link fault '{other}' (corrupt, drop, delay, delay-cycles, seed)"))
                }
            }
        }
        if f.corrupt_ppm as u64 + f.drop_ppm as u64 + f.delay_ppm as u64 > 1_000_000 {
            return Err("corrupt + drop + delay: the fault rates must sum to at most 1".into());
        }
        Ok(f)
    }
}

/// Longest delay a frame may be given, in cycles.
pub const MAX_DELAY_CYCLES: u32 = 1 << 16;

impl LinkFaults {
    /// Perfect links (seed 1, delays up to 8 cycles once a rate is set).
    pub const NONE: LinkFaults = LinkFaults { corrupt_ppm: 0, drop_ppm: 0, delay_ppm: 0, delay_cycles: 8, seed: 1 };
}

/// What the faulty links did (`T = u32`: what one link did, see [`FaultInjector`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FaultCounts<T = u64> {
    /// Data frames sent (first sends and retransmissions).
    pub data_frames: T,
    /// Data frames sent again because no intact acknowledgement came back.
    pub retransmissions: T,
    /// Data frames corrupted on the way, all refused by the CRC.
    pub data_corrupted: T,
    /// Data frames lost.
    pub data_dropped: T,
    /// Data frames held on the wire (they arrive intact, later).
    pub data_delayed: T,
    /// Cycles links spent holding delayed frames.
    pub delay_cycles: T,
    /// Acknowledgements corrupted (refused by the CRC) or lost.
    pub acks_lost: T,
    /// Frames whose CRC failed at the receiving end (never applied).
    pub crc_rejected: T,
    /// Intact data frames discarded as duplicates (their acknowledgement had been lost).
    pub duplicates: T,
}

impl FaultCounts {
    /// Sum of two runs (or links).
    pub fn add<T: Copy + Into<u64>>(&mut self, o: &FaultCounts<T>) {
        self.data_frames += o.data_frames.into();
        self.retransmissions += o.retransmissions.into();
        self.data_corrupted += o.data_corrupted.into();
        self.data_dropped += o.data_dropped.into();
        self.data_delayed += o.data_delayed.into();
        self.delay_cycles += o.delay_cycles.into();
        self.acks_lost += o.acks_lost.into();
        self.crc_rejected += o.crc_rejected.into();
        self.duplicates += o.duplicates.into();
    }
}

/// What every faulty link of a grid shares: the fault rates and seed, and the grid's far
/// distance (to decode beams; checked when the grid was set up).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wire {
    /// Fault rates and seed.
    pub faults: LinkFaults,
    /// The far distance D.
    pub far: u32,
}

/// What happens to one frame.
enum Fate {
    Deliver,
    Drop,
    /// Hold the frame on the wire this many extra cycles.
    Delay(u32),
    /// Flip these bits (indices into the frame's bits).
    Corrupt([u64; 2]),
}

fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// What happens to a frame sent by cell `from` through port `port` in `cycle` (`ack`: an
/// acknowledgement; `len`: the frame's bytes).
fn fate(faults: &LinkFaults, cycle: u64, from: u32, port: usize, ack: bool, len: usize) -> Fate {
    let key = faults.seed ^ mix(cycle ^ mix((from as u64) << 4 | (port as u64) << 1 | ack as u64));
    let r = mix(key);
    let p = (r % 1_000_000) as u32;
    if p < faults.drop_ppm {
        Fate::Drop
    } else if p < faults.drop_ppm + faults.corrupt_ppm {
        let bits = (len * 8) as u64;
        let r2 = mix(r);
        Fate::Corrupt([r2 % bits, (r2 >> 32) % bits])
    } else if !ack && p < faults.drop_ppm + faults.corrupt_ppm + faults.delay_ppm {
        Fate::Delay(1 + (mix(r) % faults.delay_cycles as u64) as u32)
    } else {
        Fate::Deliver
    }
}

/// Whether a frame of this fate reaches the far end (corrupted ones do, with bits flipped).
fn carry(fate: &Fate, frame: &mut [u8]) -> bool {
    match fate {
        Fate::Deliver | Fate::Delay(_) => true,
        Fate::Drop => false,
        Fate::Corrupt(bits) => {
            frame[(bits[0] / 8) as usize] ^= 1 << (bits[0] % 8);
            if bits[1] != bits[0] {
                frame[(bits[1] / 8) as usize] ^= 1 << (bits[1] % 8);
            }
            true
        }
    }
}

/// A link behind a faulty wire: a send is framed, may be corrupted, dropped or delayed on the
/// way, is decoded at the far end (a frame failing its CRC is never applied), handed to the
/// wrapped link `L` unless it is a duplicate, and acknowledged over the same faulty wire. The
/// protocol state of the link (both ends) and its counters live here: one cache line with a
/// perfect inner link (the grid holds one per directed link). The counters are `u32`: in a
/// cycle a link sends at most one data frame and one acknowledgement and holds at most one
/// frame, so none exceeds twice the run's cycle count (runs end long before 2³¹ cycles; the
/// run's report sums them in `u64`).
#[repr(align(64))]
pub struct FaultInjector<'w, L> {
    inner: L,
    wire: &'w Wire,
    /// The cycle a delayed frame arrives (0: none on the wire).
    arrives: u64,
    /// Sending cell and port, receiving cell (the fault decisions hash them).
    from: u32,
    to: u32,
    port: u8,
    /// The sequence bit of the head frame.
    tx_seq: u8,
    /// The head frame was sent before (a resend is a retransmission).
    tx_tried: bool,
    /// The far end: the sequence bit last accepted (2: none yet).
    rx_last: u8,
    /// Counters.
    pub counts: FaultCounts<u32>,
}

impl<'w, L> FaultInjector<'w, L> {
    /// Link `id` behind `wire`.
    pub fn new(inner: L, wire: &'w Wire, id: LinkId) -> Self {
        FaultInjector {
            inner,
            wire,
            from: id.from,
            to: id.to,
            port: id.port.index() as u8,
            tx_seq: 0,
            tx_tried: false,
            rx_last: 2,
            arrives: 0,
            counts: FaultCounts::default(),
        }
    }

    /// The data frame's fate in `cycle` (first send, retransmission or arrival of a delayed
    /// frame), counted; `None` while a delayed frame is still on the wire.
    fn data_fate(&mut self, cycle: u64, len: usize) -> Option<Fate> {
        let fate = match self.arrives {
            0 => {
                self.counts.data_frames += 1;
                if std::mem::replace(&mut self.tx_tried, true) {
                    self.counts.retransmissions += 1;
                }
                fate(&self.wire.faults, cycle, self.from, self.port as usize, false, len)
            }
            // The delayed frame is still on the wire.
            t if cycle < t => return None,
            // It arrives (intact) now.
            _ => {
                self.arrives = 0;
                Fate::Deliver
            }
        };
        match fate {
            Fate::Drop => self.counts.data_dropped += 1,
            Fate::Corrupt(_) => self.counts.data_corrupted += 1,
            Fate::Delay(k) => {
                self.counts.data_delayed += 1;
                self.counts.delay_cycles += k;
                self.arrives = cycle + k as u64;
                return None;
            }
            Fate::Deliver => {}
        }
        Some(fate)
    }

    /// The far end acknowledges `seq` in `cycle`; whether the acknowledgement of the sender's
    /// `expect` came back intact (the sender then pops and flips its bit).
    fn acknowledge<F: FracBits>(&mut self, cycle: u64, seq: u8, expect: u8, far: FarDistance<F>) -> bool {
        let mut ack = [0u8; HEADER + 1 + TRAILER];
        // Cannot fail: an ack frame has a fixed size.
        let alen = Message::<F>::Ack.emit(seq, &mut ack).expect("ack frame fits");
        let afate = fate(&self.wire.faults, cycle, self.to, BACK[self.port as usize], true, alen);
        let acked = carry(&afate, &mut ack[..alen])
            && matches!(Frame::<F>::parse(&ack[..alen], far), Ok((f, _)) if f.msg == Message::Ack && f.seq == expect);
        if !acked {
            self.counts.acks_lost += 1;
            if matches!(afate, Fate::Corrupt(_)) {
                self.counts.crc_rejected += 1;
            }
        } else {
            self.tx_seq ^= 1;
            self.tx_tried = false;
        }
        acked
    }
}

impl<F: FracBits, Rx: ?Sized, L: Link<F, Rx>> Link<F, Rx> for FaultInjector<'_, L> {
    type Error = L::Error;
    const LOSSLESS: bool = false;

    fn ready(&mut self, rx: &Rx) -> Result<bool, L::Error> {
        self.inner.ready(rx)
    }

    /// Send the head message `m` in `cycle` through the codec and the injector.
    fn send(&mut self, cycle: u64, m: &BeamMsg<F>, rx: &mut Rx) -> Result<Sent, L::Error> {
        let far = FarDistance::<F>::new(self.wire.far).expect("the grid's far distance was checked");
        let seq = self.tx_seq;
        let mut buf = [0u8; MAX_FRAME];
        // Cannot fail: a beam frame has a fixed size below MAX_FRAME.
        let len = Message::Beam(*m).emit(seq, &mut buf).expect("beam frame fits");
        let Some(fate) = self.data_fate(cycle, len) else { return Ok(Sent::NOTHING) };
        if !carry(&fate, &mut buf[..len]) {
            return Ok(Sent::NOTHING);
        }
        // The receiving end.
        let frame = match Frame::<F>::parse(&buf[..len], far) {
            Ok((f, _)) => f,
            Err(_) => {
                self.counts.crc_rejected += 1;
                return Ok(Sent::NOTHING);
            }
        };
        let Message::Beam(got) = frame.msg else {
            // A corrupted kind byte that still passed the CRC cannot happen with CRC-32 and ≤ 2
            // flipped bits; refuse it all the same.
            self.counts.crc_rejected += 1;
            return Ok(Sent::NOTHING);
        };
        let delivered = if self.rx_last == frame.seq {
            self.counts.duplicates += 1;
            false
        } else {
            // The sender checked the credit line: the FIFO has room.
            let ok = self.inner.send(cycle, &got, rx)?.delivered;
            if ok {
                self.rx_last = frame.seq;
            }
            ok
        };
        // The acknowledgement travels back.
        let acked = self.acknowledge(cycle, frame.seq, seq, far);
        Ok(Sent { delivered, acked })
    }
}

/// What a link reports of the faults it met.
pub trait FaultTally {
    /// This link's counts added to `into` (left alone by a link that meets no faults).
    fn add_counts(&self, into: &mut Option<FaultCounts>);
}

/// What `links` met, summed (`None` for links that meet no faults).
pub fn fault_counts<L: FaultTally>(links: &[L]) -> Option<FaultCounts> {
    let mut sum = None;
    links.iter().for_each(|l| l.add_counts(&mut sum));
    sum
}

impl FaultTally for PerfectLink {
    fn add_counts(&self, _: &mut Option<FaultCounts>) {}
}

impl<L> FaultTally for FaultInjector<'_, L> {
    fn add_counts(&self, into: &mut Option<FaultCounts>) {
        into.get_or_insert_with(FaultCounts::default).add(&self.counts);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_faulty_perfect_link_is_one_cache_line() {
        assert_eq!(std::mem::size_of::<FaultInjector<'_, PerfectLink>>(), 64);
    }

    #[test]
    fn parses_fault_specs() {
        let f: LinkFaults = "corrupt=0.01,drop=0.02,seed=9".parse().unwrap();
        assert_eq!(f, LinkFaults { corrupt_ppm: 10_000, drop_ppm: 20_000, seed: 9, ..LinkFaults::NONE });
        let d: LinkFaults = "delay=0.5,delay-cycles=3".parse().unwrap();
        assert_eq!((d.delay_ppm, d.delay_cycles), (500_000, 3));
        assert!("delay-cycles=0".parse::<LinkFaults>().is_err());
        assert!("delay=0.6,drop=0.6".parse::<LinkFaults>().is_err(), "rates sum above 1");
        assert!("corrupt=2".parse::<LinkFaults>().is_err());
        assert!("drop=1".parse::<LinkFaults>().is_ok(), "a dead link is a valid test case");
        assert!("bogus=0.1".parse::<LinkFaults>().is_err());
        assert!("drop".parse::<LinkFaults>().is_err());
    }
}
