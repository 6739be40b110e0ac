//! Faulty links: every transfer of the lighting phase's link phase goes through the
//! real link codec (`cell_core::link`: frame + CRC-32), and a seeded fault injector in the
//! spirit of smoltcp's `FaultInjector` corrupts or drops frames at given rates.
//!
//! The link protocol that survives it is stop-and-wait with an alternating sequence bit per
//! (sender, port):
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
//! run is reproducible whatever the thread count.

use std::str::FromStr;

use cell_core::beam::{FarDistance, FracBits};
use cell_core::light::{BeamMsg, BeamTally, Port};
use cell_core::link::{decode, encode, Message, HEADER, MAX_FRAME, TRAILER};

use crate::machine::capacity::HostLightCell;

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

/// What the faulty links did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FaultCounts {
    /// Data frames sent (first sends and retransmissions).
    pub data_frames: u64,
    /// Data frames sent again because no intact acknowledgement came back.
    pub retransmissions: u64,
    /// Data frames corrupted on the way, all refused by the CRC.
    pub data_corrupted: u64,
    /// Data frames lost.
    pub data_dropped: u64,
    /// Data frames held on the wire (they arrive intact, later).
    pub data_delayed: u64,
    /// Cycles links spent holding delayed frames.
    pub delay_cycles: u64,
    /// Acknowledgements corrupted (refused by the CRC) or lost.
    pub acks_lost: u64,
    /// Frames whose CRC failed at the receiving end (never applied).
    pub crc_rejected: u64,
    /// Intact data frames discarded as duplicates (their acknowledgement had been lost).
    pub duplicates: u64,
}

impl FaultCounts {
    /// Sum of two runs.
    pub fn add(&mut self, o: &FaultCounts) {
        self.data_frames += o.data_frames;
        self.retransmissions += o.retransmissions;
        self.data_corrupted += o.data_corrupted;
        self.data_dropped += o.data_dropped;
        self.data_delayed += o.data_delayed;
        self.delay_cycles += o.delay_cycles;
        self.acks_lost += o.acks_lost;
        self.crc_rejected += o.crc_rejected;
        self.duplicates += o.duplicates;
    }
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

/// Link state of the whole grid under fault injection.
pub struct FaultyLinks {
    faults: LinkFaults,
    /// Per cell and outgoing port: the sequence bit of the head frame.
    tx_seq: Vec<[u8; 8]>,
    /// Per cell and outgoing port: the head frame was sent before (a resend is a retransmission).
    tx_tried: Vec<[bool; 8]>,
    /// Per cell and incoming port: the sequence bit last accepted (2: none yet).
    rx_last: Vec<[u8; 8]>,
    /// Per cell and outgoing port: the cycle a delayed frame arrives (0: none on the wire).
    arrives: Vec<[u64; 8]>,
    /// Counters.
    pub counts: FaultCounts,
}

/// Outcome of one link transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transfer {
    /// The beam entered the receiver's FIFO now.
    pub delivered: bool,
    /// The sender got an intact acknowledgement: it pops the message.
    pub acked: bool,
}

impl FaultyLinks {
    /// Links for a grid of `cells` cells.
    pub fn new(faults: LinkFaults, cells: usize) -> Self {
        FaultyLinks {
            faults,
            tx_seq: vec![[0; 8]; cells],
            tx_tried: vec![[false; 8]; cells],
            rx_last: vec![[2; 8]; cells],
            arrives: vec![[0; 8]; cells],
            counts: FaultCounts::default(),
        }
    }

    fn fate(&self, cycle: u64, from: usize, port: Port, ack: bool, len: usize) -> Fate {
        let key = self.faults.seed ^ mix(cycle ^ mix((from as u64) << 4 | (port.index() as u64) << 1 | ack as u64));
        let r = mix(key);
        let p = (r % 1_000_000) as u32;
        if p < self.faults.drop_ppm {
            Fate::Drop
        } else if p < self.faults.drop_ppm + self.faults.corrupt_ppm {
            let bits = (len * 8) as u64;
            let r2 = mix(r);
            Fate::Corrupt([r2 % bits, (r2 >> 32) % bits])
        } else if !ack && p < self.faults.drop_ppm + self.faults.corrupt_ppm + self.faults.delay_ppm {
            Fate::Delay(1 + (mix(r) % self.faults.delay_cycles as u64) as u32)
        } else {
            Fate::Deliver
        }
    }

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

    /// Send the head message `m` of cell `from`'s output `port` to cell `to` (which has credit)
    /// in `cycle`, through the codec and the injector.
    #[allow(clippy::too_many_arguments)]
    pub fn transfer<F: FracBits>(
        &mut self,
        cycle: u64,
        from: usize,
        port: Port,
        to: usize,
        m: &BeamMsg<F>,
        far: FarDistance<F>,
        receiver: &mut HostLightCell<F>,
        merge: bool,
        tally: &impl BeamTally,
    ) -> Transfer {
        let p = port.index();
        let (dx, dy) = port.delta();
        // Cannot fail: the opposite of a unit step is a unit step.
        let back = Port::from_delta(-dx, -dy).expect("opposite port").index();
        let seq = self.tx_seq[from][p];
        let mut buf = [0u8; MAX_FRAME];
        // Cannot fail: a beam frame has a fixed size below MAX_FRAME.
        let len = encode(seq, &Message::Beam(*m), &mut buf).expect("beam frame fits");
        let fate = match self.arrives[from][p] {
            0 => {
                self.counts.data_frames += 1;
                if std::mem::replace(&mut self.tx_tried[from][p], true) {
                    self.counts.retransmissions += 1;
                }
                self.fate(cycle, from, port, false, len)
            }
            // The delayed frame is still on the wire.
            t if cycle < t => return Transfer { delivered: false, acked: false },
            // It arrives (intact) now.
            _ => {
                self.arrives[from][p] = 0;
                Fate::Deliver
            }
        };
        match fate {
            Fate::Drop => self.counts.data_dropped += 1,
            Fate::Corrupt(_) => self.counts.data_corrupted += 1,
            Fate::Delay(k) => {
                self.counts.data_delayed += 1;
                self.counts.delay_cycles += k as u64;
                self.arrives[from][p] = cycle + k as u64;
                return Transfer { delivered: false, acked: false };
            }
            Fate::Deliver => {}
        }
        if !Self::carry(&fate, &mut buf[..len]) {
            return Transfer { delivered: false, acked: false };
        }
        // The receiving end.
        let frame = match decode::<F>(&buf[..len], far) {
            Ok((f, _)) => f,
            Err(_) => {
                self.counts.crc_rejected += 1;
                return Transfer { delivered: false, acked: false };
            }
        };
        let Message::Beam(got) = frame.msg else {
            // A corrupted kind byte that still passed the CRC cannot happen with CRC-32 and ≤ 2
            // flipped bits; refuse it all the same.
            self.counts.crc_rejected += 1;
            return Transfer { delivered: false, acked: false };
        };
        let delivered = if self.rx_last[to][back] == frame.seq {
            self.counts.duplicates += 1;
            false
        } else {
            // The sender checked the credit line: the FIFO has room.
            let ok = receiver.accept(got, merge, tally).is_ok();
            if ok {
                self.rx_last[to][back] = frame.seq;
            }
            ok
        };
        // The acknowledgement travels back.
        let mut ack = [0u8; HEADER + 1 + TRAILER];
        // Cannot fail: an ack frame has a fixed size.
        let alen = encode::<F>(frame.seq, &Message::Ack, &mut ack).expect("ack frame fits");
        let afate = self.fate(cycle, to, Port::ALL[back], true, alen);
        let acked = Self::carry(&afate, &mut ack[..alen])
            && matches!(decode::<F>(&ack[..alen], far), Ok((f, _)) if f.msg == Message::Ack && f.seq == seq);
        if !acked {
            self.counts.acks_lost += 1;
            if matches!(afate, Fate::Corrupt(_)) {
                self.counts.crc_rejected += 1;
            }
        } else {
            self.tx_seq[from][p] ^= 1;
            self.tx_tried[from][p] = false;
        }
        Transfer { delivered, acked }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
