//! The production image of one RC² cell: the cell driven by its links only — no trace data,
//! no replay harness, no formatting, no logging. Two images come from this source
//! (docs/FIRMWARE.md, "Flash budget"): the **default cell**, the crate's plain
//! `cargo build --release` (its default features: every phase and option `host-sim render`
//! uses by default; 66 836 B of flash, held to 66 KiB), and the **thesis's cell**,
//! `cargo build --profile thesis --bin cell --no-default-features` (the thesis's lit rule and
//! policy, held to the 16 KiB a cell of the thesis's machine could afford). `host-sim audit`
//! reads their ELFs and says what each part of the cell costs in flash.
//!
//! **Links** ([`board`]): one serial link to the host and one per neighbour port, each carrying
//! `cell_core::link` frames (kind, length, payload, CRC-32); a ready line per port each way.
//!
//! * **Host link**: the host's records, in the trace record format of `cell_core::trace`
//!   (the same bytes a trace holds): `Header` (which cell this is, and the capacities the host
//!   expects: a mismatch is refused), `Light` (a source's diffusion starts), under exact
//!   occluders the column's `Triangle`s and its neighbours' `NeighbourContact` answer (the
//!   cell computes its target ray itself, `cell_core::trace::TraceColumn`), `Shade` (shade the
//!   pixel and report), and beam frames (`KIND_BEAM`: the source emitter's initial beams).
//!   The cell answers a `Shade` with a report frame ([`KIND_REPORT`]), which ends its counters
//!   with the deepest its stack has gone (the free RAM is painted at boot, `stack.rs`).
//! * **Port links**: row packets (loading, §3.9: from the west, forwarded east while cells
//!   further east need them) and beams (lighting, §4.4) from the eight neighbours.
//! * **Ready lines**: while the FIFO has room, the cell raises its line to one neighbour at a
//!   time (round robin), and lowers it when a frame from that neighbour starts: one credit, one
//!   beam. It sends the head of an output buffer only while that neighbour's line is high.
//!
//! **Main loop**: receive (poll every link, assemble frames, decode: CRC, bounds, the bit
//! budget), compute (one `LightCell::step`), send (`cell_core::link::drain_outputs` over
//! `HalLink`s), credit. Nothing is ever dropped silently: frames that do not decode, beams
//! that find the FIFO full, dexel-store and lit-store overflows are counted and reported.
//!
//! **Panics** halt the core without formatting their message (the message and its formatting
//! machinery would cost several KiB of flash); every decoder returns errors as values, so a
//! panic is a bug in the cell.
#![no_std]
#![no_main]

mod board;
#[path = "../../cmsdk.rs"]
mod cmsdk;
mod features;
mod mem;
#[path = "../../stack.rs"]
mod stack;
#[path = "../../vectors.rs"]
mod vectors;

use core::panic::PanicInfo;

use cell_core::beam::frac::U0;
use cell_core::beam::{FarDistance, SplitOrder};
use cell_core::cell::{Cell, DEFAULT_DEXELS, FA_CAP, LIT_CAP, OB_CAP};
use cell_core::facet::RowPacket;
use cell_core::light::{ActivityDelta, LightCell, Port};
use cell_core::link::{drain_outputs, HalLink};
use cell_core::trace::{self, kind, LightSetup, ReplayError, Replayer, MAX_LIGHTS, MAX_MATERIALS};
use cell_core::wire::{
    self, read_frame, write_frame, ByteSink, DecodeError, Frame, Message, PutExt, Reader, HEADER, KIND_BEAM, KIND_ROW,
    MAX_FRAME, TRAILER,
};
use cortex_m_rt::entry;
use embedded_hal::digital::OutputPin;
use heapless::Vec;

use board::{FrameWire, ReadyIn, ReadyOut, Uart};

/// The report frame's kind: the cell's pixel, counters and lit runs, sent to the host.
pub const KIND_REPORT: u8 = 0x50;
/// Longest host record: a `Shade` record with the most lights and materials.
const HOST_FRAME: usize = HEADER + 12 + 2 + MAX_LIGHTS * 24 + 1 + MAX_MATERIALS * 52 + TRAILER;
/// Longest report: the cell (4 bytes), its pixel (10), five counters and the stack peak (24),
/// the run count (1) and 8 bytes per lit run.
const REPORT_FRAME: usize = HEADER + 4 + 10 + 24 + 1 + LIT_CAP * 8 + TRAILER;

/// The cell's capacities: those of host-sim's cell (`cell_core::cell`), so that the host's
/// `Header` record matches.
type Light = LightCell<U0, FA_CAP, OB_CAP, LIT_CAP>;
type Links = [HalLink<ReadyIn, FrameWire>; 8];

/// The bytes of one frame as they arrive on a link.
struct Rx<const N: usize> {
    buf: Vec<u8, N>,
}

impl<const N: usize> Rx<N> {
    const fn new() -> Self {
        Rx { buf: Vec::new() }
    }

    /// Take one byte: the frame's length once it is complete, an error for a frame longer than
    /// this link carries (the bytes so far are dropped).
    fn push(&mut self, b: u8) -> Option<Result<usize, DecodeError>> {
        if self.buf.push(b).is_err() {
            self.buf.clear();
            return Some(Err(DecodeError::BadLength));
        }
        let [_, lo, hi, ..] = self.buf[..] else { return None };
        let total = HEADER + u16::from_le_bytes([lo, hi]) as usize + TRAILER;
        if total > N {
            self.buf.clear();
            return Some(Err(DecodeError::BadLength));
        }
        (self.buf.len() == total).then_some(Ok(total))
    }
}

/// The cell: loading state, lighting state and what it counts.
struct Node {
    cell: Cell<DEFAULT_DEXELS>,
    light: Light,
    /// Beams that appeared here minus beams consumed here: this cell's share of the
    /// machine's activity count (§4.4.4).
    activity: ActivityDelta,
    setup: Option<LightSetup>,
    /// Under exact occluders: the column's triangles, target ray and contact answer for the
    /// current source (host records, as a trace hands them to the replayer).
    #[cfg(feature = "exact-occluders")]
    column: trace::TraceColumn,
    depth: u32,
    /// Frames that did not decode (CRC, length, values), or that came out of order.
    bad_frames: u32,
    /// Beams that arrived with the FIFO full (a neighbour sent without credit).
    refused: u32,
}

impl Node {
    fn new() -> Self {
        Node {
            cell: Cell::new(0, 0),
            light: LightCell::new(0, 0),
            activity: ActivityDelta::new(),
            setup: None,
            #[cfg(feature = "exact-occluders")]
            column: trace::TraceColumn::new(),
            depth: 0,
            bad_frames: 0,
            refused: 0,
        }
    }

    fn far(&self) -> Result<FarDistance<U0>, ReplayError> {
        let s = self.setup.as_ref().ok_or(ReplayError::NoLightSetup)?;
        FarDistance::new(s.far).ok_or(ReplayError::BadFar)
    }

    /// A beam for the FIFO (from a neighbour or the source emitter).
    fn accept(&mut self, bytes: &[u8]) -> Result<(), ReplayError> {
        let (raw, _) = read_frame(bytes)?;
        let Message::Beam(m) = Frame::parse_payload(raw, self.far()?)?.msg else {
            return Err(DecodeError::UnknownKind(raw.kind).into());
        };
        let s = self.setup.as_ref().ok_or(ReplayError::NoLightSetup)?;
        if !self.light.can_accept(s.fa as usize) || self.light.accept(m, s.merge, &self.activity).is_err() {
            self.refused += 1;
        }
        Ok(())
    }

    /// A row packet from the west (§3.9): store this column's span; the packet to forward
    /// east, if cells further east need it.
    fn row(&mut self, payload: &[u8]) -> Result<Option<RowPacket>, ReplayError> {
        let mut r = Reader::new(payload);
        r.u8()?; // sequence number
        let mut pkt = wire::get_row(&mut r)?;
        r.finish()?;
        Ok(features::load_step(&mut self.cell, &mut pkt, self.depth).then_some(pkt))
    }

    /// A frame from a neighbour: a row packet (returned when it goes on east) or a beam.
    fn port_frame(&mut self, bytes: &[u8]) -> Result<Option<RowPacket>, ReplayError> {
        let (raw, _) = read_frame(bytes)?;
        match raw.kind {
            KIND_ROW => self.row(raw.payload),
            _ => self.accept(bytes).map(|()| None),
        }
    }

    /// A frame from the host: a record, or an initial beam. Returns whether to report.
    fn host_frame(&mut self, bytes: &[u8], host: Uart) -> Result<(), ReplayError> {
        if bytes.first() == Some(&KIND_BEAM) {
            return self.accept(bytes);
        }
        let (raw, _) = read_frame(bytes)?;
        let mut r = Reader::new(raw.payload);
        match raw.kind {
            kind::HEADER => {
                let h = trace::get_header(&mut r)?;
                if h != Replayer::<U0, DEFAULT_DEXELS, FA_CAP, OB_CAP, LIT_CAP>::header(h.x, h.y, h.depth) {
                    return Err(ReplayError::CapacityMismatch);
                }
                self.cell = Cell::new(h.x, h.y);
                self.light = LightCell::new(h.x, h.y);
                self.depth = h.depth;
            }
            kind::LIGHT => {
                let s = features::check(trace::get_light_setup(&mut r, features::read_frustum)?)?;
                FarDistance::<U0>::new(s.far).ok_or(ReplayError::BadFar)?;
                self.light.counters.max_layer = 0;
                self.light.counters.peak_fifo = 0;
                #[cfg(feature = "exact-occluders")]
                self.column.start::<U0, DEFAULT_DEXELS>(&self.cell, &s)?;
                self.setup = Some(s);
            }
            // Under exact occluders, after the light record: the column's triangles, then its
            // neighbours' contact answer if its target has a contact segment.
            #[cfg(feature = "exact-occluders")]
            kind::TRIANGLE => {
                if !self.setup.is_some_and(|s| s.rule.needs_triangles()) {
                    return Err(DecodeError::BadValue("a triangle outside exact occluders").into());
                }
                self.column.push(trace::get_triangle(&mut r)?)?;
            }
            #[cfg(feature = "exact-occluders")]
            kind::NEIGHBOUR_CONTACT => self.column.answer(trace::get_neighbour_contact(&mut r)?)?,
            kind::SHADE => {
                #[cfg(feature = "shading")]
                let pixel = self.shade(trace::get_shade_setup(&mut r)?);
                #[cfg(not(feature = "shading"))]
                let pixel = None;
                self.report(pixel, host);
            }
            _ => return Err(ReplayError::BadHeader),
        }
        r.finish()?;
        Ok(())
    }

    /// The pixel (§5.2), under the lit rule of the last light setup.
    #[cfg(feature = "shading")]
    fn shade(&self, s: trace::ShadeSetup) -> Option<cell_core::shade::Pixel> {
        use cell_core::{lit::LitRule, shade::cell_pixel, units::Depth};
        let rule = features::rule(self.setup.map_or(LitRule::Thesis, |l| l.rule));
        let lit = &self.light.lit;
        let reached = |z: Depth| lit.mask_at(z);
        cell_pixel(rule, &self.cell, reached, self.light.visible_lit, &s.materials, &s.lights, &s.params)
    }

    /// Whether the light cell may step: a source is set up and, under exact occluders, its
    /// target ray is final (the neighbours' contact answer is in).
    fn lighting(&self) -> Option<LightSetup> {
        #[cfg(feature = "exact-occluders")]
        if self.column.awaiting() {
            return None;
        }
        self.setup.map(features::fixed_options)
    }

    /// The report to the host: cell, pixel (flag, rgb, light mask, depth), counters
    /// (dexel overflows, lost voxels, lit-run overflows, refused beams, bad frames), the
    /// deepest the stack has gone so far (bytes, [`stack::peak`]), lit runs.
    fn report(&self, pixel: Option<cell_core::shade::Pixel>, host: Uart) {
        let mut buf = [0u8; REPORT_FRAME];
        let (store, lit) = (&self.cell.store, &self.light.lit);
        let n = write_frame(&mut buf, KIND_REPORT, |w| {
            w.u16(self.cell.x)?;
            w.u16(self.cell.y)?;
            let p = pixel.unwrap_or(cell_core::shade::Pixel { rgb: [0; 3], lit: 0, z: 0 });
            w.u8(pixel.is_some() as u8)?;
            w.put(&p.rgb)?;
            w.u32(p.lit)?;
            w.u16(p.z)?;
            for c in [store.overflows(), store.lost_voxels(), lit.overflows(), self.refused, self.bad_frames] {
                w.u32(c)?;
            }
            w.u32(stack::peak() as u32)?;
            w.u8(lit.runs().len() as u8)?;
            for r in lit.runs() {
                w.u16(r.lo)?;
                w.u16(r.hi)?;
                w.u32(r.mask)?;
            }
            Ok(())
        });
        // The buffer holds the longest report: the write cannot fail.
        if let Ok(n) = n {
            host.write_all(&buf[..n]);
        }
    }
}

/// Send a row packet east, once the east neighbour has room.
fn forward_east(links: &mut Links, pkt: RowPacket) {
    let mut buf = [0u8; MAX_FRAME];
    let Ok(n) = Message::<U0>::Row(pkt).emit(0, &mut buf) else { return };
    let east = &mut links[Port::E.index()];
    while !embedded_hal::digital::InputPin::is_high(&mut east.ready).unwrap_or(true) {}
    east.spi.0.write_all(&buf[..n]);
}

/// The receive side: the host link and the eight port links, polled.
struct Receiver {
    host: Uart,
    host_rx: Rx<HOST_FRAME>,
    rx: [Rx<MAX_FRAME>; 8],
    /// This cell's ready lines, and which are high (bit `p`: one credit granted to port `p`).
    credit: [ReadyOut; 8],
    raised: u8,
}

impl Receiver {
    /// Every byte waiting on the host link.
    fn host(&mut self, node: &mut Node) {
        while let Some(b) = self.host.read_byte() {
            if let Some(frame) = self.host_rx.push(b) {
                let r =
                    frame.map_err(ReplayError::from).and_then(|n| node.host_frame(&self.host_rx.buf[..n], self.host));
                node.bad_frames += r.is_err() as u32;
                self.host_rx.buf.clear();
            }
        }
    }

    /// One byte from each port link that has one. A frame that starts uses up the credit of
    /// its port; a complete one is decoded and handled.
    fn ports(&mut self, node: &mut Node, links: &mut Links) {
        for (i, rx) in self.rx.iter_mut().enumerate() {
            let Some(b) = links[i].spi.0.read_byte() else { continue };
            if self.raised & 1 << i != 0 {
                let _ = self.credit[i].set_low();
                self.raised &= !(1 << i);
            }
            let Some(frame) = rx.push(b) else { continue };
            match frame.map_err(ReplayError::from).and_then(|n| node.port_frame(&rx.buf[..n])) {
                Ok(Some(pkt)) => forward_east(links, pkt),
                Ok(None) => {}
                Err(_) => node.bad_frames += 1,
            }
            rx.buf.clear();
        }
    }

    /// Raise ready lines while the FIFO has a free slot for every granted credit and every
    /// frame on its way (one frame at a time while loading, before any light setup).
    fn grant(&mut self, node: &Node) {
        let limit = node.setup.map_or(1, |s| (s.fa as usize).min(FA_CAP));
        let in_progress = self.rx.iter().filter(|r| !r.buf.is_empty()).count();
        let mut reserved = node.light.fifo.len() + in_progress + self.raised.count_ones() as usize;
        for i in 0..8 {
            if reserved < limit && self.raised & 1 << i == 0 && self.rx[i].buf.is_empty() {
                let _ = self.credit[i].set_high();
                self.raised |= 1 << i;
                reserved += 1;
            }
        }
    }
}

#[entry]
fn main() -> ! {
    // Before anything lives on the stack below this frame: every report says how deep it went.
    stack::paint();
    let mut links: Links =
        core::array::from_fn(|i| HalLink { ready: ReadyIn::port(Port::ALL[i]), spi: FrameWire(Uart::link(i + 1)) });
    let mut recv = Receiver {
        host: Uart::link(0),
        host_rx: Rx::new(),
        rx: core::array::from_fn(|_| Rx::new()),
        credit: core::array::from_fn(|i| ReadyOut::port(Port::ALL[i])),
        raised: 0,
    };
    let mut node = Node::new();
    let order = SplitOrder::default();
    let mut now = 0u64;
    loop {
        recv.host(&mut node);
        recv.ports(&mut node, &mut links);
        if let Some(setup) = node.lighting() {
            #[allow(unused_mut)]
            if let Ok(mut env) = features::env(&setup, &order) {
                #[cfg(feature = "exact-occluders")]
                if setup.rule.needs_triangles() {
                    env.occluders = Some(&node.column);
                }
                node.light.step(&node.cell, &env, &node.activity);
            }
        }
        // A link error leaves the beam in its output buffer, to go at a later cycle.
        let _ = drain_outputs(&mut node.light, &mut links, now, |_, _| {});
        now += 1;
        recv.grant(&node);
    }
}

/// Halt, without formatting the message: see the module docs.
#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    // An undefined instruction: the core faults and stays in cortex-m-rt's fault handler.
    cortex_m::asm::udf()
}
