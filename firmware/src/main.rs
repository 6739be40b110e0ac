//! One RC² cell on a Cortex-M4F: replays the cell traces embedded at build time (see
//! `build.rs`) through the real `cell_core` cell and prints, for each, the digest of its
//! outputs and final state over semihosting, then exits with semihosting's exit code. Every
//! phase a trace holds is replayed: loading, beam diffusion or the classic shadow rays,
//! shading, and the reflection phase (`cell_core::trace::rays`).
//! `tests/tests/integration/firmware_qemu.rs` records the traces from a host-sim run, builds this, runs it
//! under QEMU (`-machine mps2-an386`) and compares the digests with the host's.
//!
//! The code path is the one a real cell would run, with the trace standing in for the wires:
//!
//! * **receive**: a frame's bytes land in the link's receive buffer and the link interrupt
//!   fires (here PendSV, pended by software); the handler decodes the frame (CRC, bounds) and
//!   puts the beam, or the ray of a ray phase, into the cell's FIFO. What the interrupt shares with the main loop (the
//!   receive buffer, the cell with its FIFO and activity counter) sits in
//!   `critical_section::Mutex`es.
//! * **compute**: the main loop runs `LightCell::step` / `Cell::load_step` (or the ray phase's
//!   cell step, `ShadowCell::step` / `ReflectCell::step`) in a critical section.
//! * **send**: each output port is a `cell_core::link::HalLink` over `embedded-hal` types: the
//!   neighbour's ready line is an `InputPin`, the frame goes out over an `SpiDevice`. Under QEMU
//!   the pin reads what the trace says the neighbour did (it took the message or not) and the
//!   SPI device counts the bytes. A ray a neighbour takes goes out as its frame over the same
//!   SPI device. The cell's answer router is outside the replayed cell: the trace says when it
//!   takes or refuses an answer, and delivers the answers it routed back.
#![no_std]
#![no_main]

mod exit;
mod stack;
mod vectors;
mod wires;

use core::cell::RefCell;

use cell_core::beam::frac::U0;
use cell_core::cell::{DEFAULT_DEXELS, FA_CAP, LIT_CAP, OB_CAP};
use cell_core::light::Port;
use cell_core::trace::{Event, Parser, ReplayError, ReplayStats, Replayer, LINK_FRAME};
use cell_core::wire::DecodeError;
use cortex_m::peripheral::SCB;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::hprintln;
use critical_section::Mutex;
use heapless::Vec;

#[cfg(feature = "defmt")]
use defmt_semihosting as _;

include!(concat!(env!("OUT_DIR"), "/traces.rs"));

/// The cell this firmware is: the host's capacities (64 dexels, FIFO 64, output buffers of 3,
/// 64 lit runs; for the ray phases a shadow-ray FIFO of 64, and 4 × 16 rays, 16 wait entries
/// and 16 queued answers in the reflection cell) and the default ray lattice (f = 0). A trace
/// recorded with others is refused.
type Cell = Replayer<U0, DEFAULT_DEXELS, FA_CAP, OB_CAP, LIT_CAP>;

/// The cell, shared between the main loop and the link interrupt: built once ([`init`]) and
/// started over in place for each trace (each cell built on the stack would take a third of
/// the RAM).
static CELL: Mutex<RefCell<Option<Cell>>> = Mutex::new(RefCell::new(None));
/// A frame that arrived: its link and its bytes.
type RxFrame = (Port, Vec<u8, LINK_FRAME>);
/// The link receive buffer.
static RX: Mutex<RefCell<Option<RxFrame>>> = Mutex::new(RefCell::new(None));
/// What the interrupt made of the last frame.
static RX_RESULT: Mutex<RefCell<Result<(), ReplayError>>> = Mutex::new(RefCell::new(Ok(())));

/// The link receive interrupt: decode the frame and put its beam (or ray) into the FIFO.
#[exception]
fn PendSV() {
    critical_section::with(|cs| {
        let Some((port, frame)) = RX.borrow_ref_mut(cs).take() else { return };
        let r = match CELL.borrow_ref_mut(cs).as_mut() {
            Some(cell) => cell.receive_frame(port, &frame),
            None => Err(ReplayError::BadHeader),
        };
        *RX_RESULT.borrow_ref_mut(cs) = r;
    });
}

/// Bytes arrive on link `port`: fill the receive buffer and raise the interrupt.
fn wire_receive(port: Port, frame: &[u8]) -> Result<(), ReplayError> {
    let mut v = Vec::new();
    v.extend_from_slice(frame).map_err(|_| ReplayError::Decode(DecodeError::BadLength))?;
    critical_section::with(|cs| *RX.borrow_ref_mut(cs) = Some((port, v)));
    SCB::set_pendsv();
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    // The interrupt has run (it preempts as soon as it is pended).
    critical_section::with(|cs| core::mem::replace(&mut *RX_RESULT.borrow_ref_mut(cs), Ok(())))
}

fn with_cell<R>(f: impl FnOnce(&mut Cell) -> Result<R, ReplayError>) -> Result<R, ReplayError> {
    critical_section::with(|cs| match CELL.borrow_ref_mut(cs).as_mut() {
        Some(c) => f(c),
        None => Err(ReplayError::BadHeader),
    })
}

/// Build the cell, first thing at boot: its construction on the stack (a temporary the size of
/// the cell) is over before any replay starts.
#[inline(never)]
fn init() {
    critical_section::with(|cs| *CELL.borrow_ref_mut(cs) = Some(Cell::new()));
}

/// Replay one trace; returns the cell, its stats and the digest.
fn replay(bytes: &[u8]) -> Result<((u16, u16), ReplayStats, u64), ReplayError> {
    with_cell(|c| {
        c.reset();
        Ok(())
    })?;
    let mut links = wires::links();
    let mut parser = Parser::<U0>::new(bytes);
    while let Some(ev) = parser.next_event() {
        match ev? {
            Event::Recv { port, frame } => wire_receive(port, frame)?,
            Event::Grant(port) => {
                wires::grant(&mut links, port);
                with_cell(|c| c.grant(port, &mut links))?;
            }
            Event::Take { class, port } => {
                wires::grant(&mut links, port);
                with_cell(|c| c.take_ray(class, port, |frame| wires::send(&mut links, port, frame)))?;
            }
            ev => with_cell(|c| c.apply(ev))?,
        }
    }
    let (at, stats, digest) = with_cell(|c| Ok(((c.cell.x, c.cell.y), c.stats, c.take_digest())))?;
    #[cfg(feature = "defmt")]
    defmt::info!("cell ({=u16}, {=u16}): {}", at.0, at.1, stats);
    Ok((at, stats, digest?))
}

#[entry]
fn main() -> ! {
    stack::paint();
    init();
    let mut failed = false;
    for (name, bytes) in TRACES {
        match replay(bytes) {
            Ok(((x, y), s, digest)) => hprintln!(
                "trace={} cell=({},{}) rows={} in={} cycles={} sent={} answers={} digest={:016x}",
                name,
                x,
                y,
                s.rows,
                s.received,
                s.steps,
                s.sent,
                s.answers,
                digest
            ),
            Err(e) => {
                failed = true;
                hprintln!("trace={} error={:?}", name, e);
            }
        }
    }
    hprintln!("traces={} sent_bytes={} stack_peak={}", TRACES.len(), wires::bytes_sent(), stack::peak());
    exit::exit(!failed)
}
