//! One board of a grid of microcontrollers on real serial links (the grid
//! of boards host-sim's `machine::lighting::boards` simulates): four neighbour links and a host
//! link, each a UART of QEMU's `mps2-an386` ([`uart`], an `embedded-io` driver) carrying
//! `cell_core::wire` frames through a [`SerialLink`] (sequence numbers, acknowledgement,
//! retransmission, resynchronisation after corrupted or dropped bytes).
//!
//! A board runs one of three exercises, chosen by the host's configuration frame. The **tile
//! exercise** ([`tiles`], tests/tests/integration/mcu_tiles.rs) holds a tile of cells that loads and lights
//! a scene with the other boards; the **termination exercise** ([`safra`],
//! tests/tests/integration/mcu_grid.rs) detects the end of a synthetic computation; the **link exercise**
//! (tests/tests/integration/mcu_grid.rs) proves the links:
//!
//! 1. The host sends a configuration on UART 0 ([`KIND_CONFIG`]: this board's id, its
//!    neighbours' ids on links E, N, W, S — UARTs 1 … 4, `0xFF` where there is none — and how
//!    many frames to send on each link).
//! 2. The board sends that many data frames ([`KIND_DATA`], body [`data_body`]`(id, i)`) on
//!    every connected link, and checks every frame it receives: the `i`-th on a link must be
//!    exactly `data_body(neighbour, i)` (a lost, repeated, reordered or altered frame is a
//!    mismatch).
//! 3. When all its frames are acknowledged and all its neighbours' frames received, it sends
//!    its report ([`KIND_REPORT`]) to the host, and goes on serving its links (a neighbour
//!    whose last acknowledgement was lost sends again, and must be answered) until the host
//!    stops it.
//!
//! **Invariant**: a link's `i`-th received frame is compared with the `i`-th frame its
//! neighbour sent; a report says, per link, how many arrived, how many differed, and what
//! the link did to survive its wire (retransmissions, skipped bytes, duplicates).
//!
//! Time is the SysTick counter's ([`Clock`], microseconds of the 25 MHz core clock); the
//! links send an unacknowledged frame again after [`TIMEOUT_US`]. The timeout is not needed
//! to be correct: a short one only costs retransmissions, which the sequence numbers make
//! harmless.
//!
//! **Waiting**: when a pass of its loop leaves nothing to do but wait for bytes, a board sleeps
//! ([`Board::wait`], `wfi`) until a UART interrupt (a byte received, a transmitter free) or
//! SysTick's (every [`TICK_CYCLES`]: the timeouts) wakes it: four boards emulated on one
//! machine leave its cores to each other and to the links' relays.
//!
//! A panic prints its message over semihosting (stderr) and exits QEMU with a failure; with the
//! `defmt` feature the board logs its steps ([`log!`]) on stdout.
#![no_std]
#![no_main]

/// A line of the board's log: with the `defmt` feature, a `defmt::println!` frame (printed
/// whatever `DEFMT_LOG` says) over semihosting (stdout), which the grid tests decode with the
/// image's defmt table and show when a run fails; without it, nothing (its arguments are not
/// evaluated).
macro_rules! log {
    ($($t:tt)*) => {
        #[cfg(feature = "defmt")]
        defmt::println!($($t)*);
    };
}

#[path = "../../cmsdk.rs"]
mod cmsdk;
#[path = "../../exit.rs"]
mod exit;
mod safra;
#[path = "../../stack.rs"]
mod stack;
mod tiles;
mod uart;
#[path = "../../vectors.rs"]
mod vectors;

use boards::{LINKS, NONE};
use cell_core::serial::{SerialLink, SerialStats};
use cell_core::wire::board::{KIND_CONFIG, KIND_DATA, KIND_REPORT};
use cortex_m_rt::entry;
use embedded_io::ReadReady;
use heapless::Vec;

#[cfg(feature = "defmt")]
use defmt_semihosting as _;

use uart::Uart;

/// Bytes per link buffer: the tile exercise's longest frame (`boards::tiles::LINK_BUF`).
pub const LINK_BUF: usize = boards::tiles::LINK_BUF;

/// The longest frame of the link and termination exercises on a neighbour link (the report's
/// 3 + 1 + 1 + 4 × 28 + 4 = 121 B goes to the host).
const SHORT_FRAME: usize = 128;
/// Microseconds before an unacknowledged frame is sent again.
pub const TIMEOUT_US: u64 = 50_000;
/// The core clock of the MPS2 FPGA images (QEMU's `mps2-an386` too).
const CORE_HZ: u64 = 25_000_000;

/// SysTick's period in core cycles (10 ms): it wakes a waiting board.
const TICK_CYCLES: u32 = 250_000;

/// Microseconds since boot, from SysTick counting down the core clock, [`TICK_CYCLES`] a turn
/// ([`Clock::now`] must be called at least once a turn, which the main loop does: SysTick's
/// interrupt wakes it; a turn missed would only slow the clock down).
struct Clock {
    /// Owned: nothing else reprograms the timer.
    _syst: cortex_m::peripheral::SYST,
    last: u32,
    cycles: u64,
}

impl Clock {
    fn new(mut syst: cortex_m::peripheral::SYST) -> Clock {
        use cortex_m::peripheral::syst::SystClkSource;
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(TICK_CYCLES - 1);
        syst.clear_current();
        syst.enable_interrupt();
        syst.enable_counter();
        Clock { _syst: syst, last: cortex_m::peripheral::SYST::get_current(), cycles: 0 }
    }

    fn now(&mut self) -> u64 {
        let cur = cortex_m::peripheral::SYST::get_current();
        // Counting down from TICK_CYCLES − 1 to 0, then again.
        let elapsed = if cur <= self.last { self.last - cur } else { self.last + TICK_CYCLES - cur };
        self.cycles += u64::from(elapsed);
        self.last = cur;
        self.cycles / (CORE_HZ / 1_000_000)
    }
}

/// The body of data frame `i` from board `from`: `from`, `i` (u16), then 1 … 40 bytes that
/// depend on both. The host test computes the same.
fn data_body(from: u8, i: u16, out: &mut [u8; 43]) -> usize {
    let len = 3 + 1 + (i as usize * 7 + from as usize) % 40;
    out[0] = from;
    out[1..3].copy_from_slice(&i.to_le_bytes());
    for (j, b) in out[3..len].iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(31).wrapping_add(j as u8) ^ from.wrapping_mul(0x5D);
    }
    len
}

/// Per neighbour link: what was sent, received and checked.
#[derive(Clone, Copy, Default)]
struct Tally {
    sent: u16,
    received: u16,
    mismatches: u16,
}

/// A board's wires: its UARTs, the serial link on each, and its clock.
pub struct Board {
    /// UART 0 (host), then the links E, N, W, S.
    pub uarts: [Uart; 5],
    /// The serial link on each UART.
    pub links: [SerialLink<LINK_BUF>; 5],
    clock: Clock,
}

impl Board {
    /// Microseconds since boot.
    pub fn now(&mut self) -> u64 {
        self.clock.now()
    }

    /// Sleep until an interrupt (a UART's, SysTick's) unless a byte is already waiting. Call it
    /// when a pass of the loop leaves nothing to do but wait.
    pub fn wait(&mut self) {
        wait(&mut self.uarts);
    }

    /// Poll link `i` (0: the host).
    pub fn poll(&mut self, i: usize, now: u64) {
        let _ = self.links[i].poll(now, &mut self.uarts[i]);
    }
}

/// [`Board::wait`] on these UARTs.
fn wait(uarts: &mut [Uart; 5]) {
    cortex_m::interrupt::free(|_| {
        // With interrupts masked, an interrupt that comes after the check still ends the `wfi`
        // (it is pending), and its handler runs once they are unmasked.
        if !uarts.iter_mut().any(|u| u.read_ready().unwrap_or(true)) {
            cortex_m::asm::wfi();
        }
    });
}

#[entry]
fn main() -> ! {
    // The stack's high-water mark, which the tile exercise reports (the board's state lives on
    // its stack).
    stack::paint();
    let peripherals = cortex_m::Peripherals::take().unwrap_or_else(|| panic!("peripherals taken twice"));
    // Every interrupt line of the board to the default handler: the UARTs' are the ones
    // enabled at their source.
    // SAFETY: the handler below only acknowledges UART interrupts; no critical section of this
    // program relies on interrupts being masked.
    unsafe { (*cortex_m::peripheral::NVIC::PTR).iser[0].write(u32::MAX) };
    let mut board = Board {
        uarts: core::array::from_fn(Uart::new),
        // The host link carries the tile exercise's long frames from the start; the neighbour
        // links carry the link and termination exercises' short ones unless the tile exercise
        // lifts their limit (a short limit resynchronises faster after a corrupted length).
        links: core::array::from_fn(|i| {
            let link = SerialLink::new(TIMEOUT_US);
            if i == 0 {
                link
            } else {
                link.with_max_frame(SHORT_FRAME)
            }
        }),
        clock: Clock::new(peripherals.SYST),
    };

    // 1. The configuration. Neighbour links are not polled yet: their bytes wait in the UARTs
    // (QEMU holds them back while a receiver is full), nothing is lost.
    loop {
        let now = board.now();
        board.poll(0, now);
        let Some(f) = board.links[0].received() else {
            board.wait();
            continue;
        };
        let p = f.payload;
        if f.kind == KIND_CONFIG && p.len() == 7 {
            let (id, neighbours, count) = (p[0], [p[1], p[2], p[3], p[4]], u16::from_le_bytes([p[5], p[6]]));
            log!("board {=u8}: link exercise, {=u16} frames per link", id, count);
            board.links[0].pop();
            link_exercise(board, id, neighbours, count);
        }
        if let Some(config) = safra::Config::parse(f.kind, p) {
            log!("termination exercise: configured");
            board.links[0].pop();
            safra::run(board, config);
        }
        if let Some(config) = tiles::Config::parse(f.kind, p) {
            log!("tile exercise: configured");
            board.links[0].pop();
            tiles::run(board, config);
        }
        board.links[0].pop();
    }
}

/// The link exercise (the module doc's steps 2 and 3).
fn link_exercise(mut board: Board, id: u8, neighbours: [u8; LINKS], count: u16) -> ! {
    let (links, uarts) = (&mut board.links, &mut board.uarts);
    let clock = &mut board.clock;
    let mut tally = [Tally::default(); LINKS];
    let mut reported = false;
    let mut buf = [0u8; 43];
    let mut expect = [0u8; 43];
    loop {
        let now = clock.now();
        for l in 0..LINKS {
            if neighbours[l] == NONE {
                continue;
            }
            let (link, t) = (&mut links[l + 1], &mut tally[l]);
            if t.sent < count && link.can_send() {
                let len = data_body(id, t.sent, &mut buf);
                if link.send(KIND_DATA, &buf[..len]).is_ok() {
                    t.sent += 1;
                }
            }
            let _ = link.poll(now, &mut uarts[l + 1]);
            if let Some(f) = link.received() {
                let len = data_body(neighbours[l], t.received, &mut expect);
                if f.kind != KIND_DATA || f.payload != &expect[..len] {
                    t.mismatches = t.mismatches.saturating_add(1);
                }
                t.received = t.received.saturating_add(1);
                link.pop();
            }
        }
        let _ = links[0].poll(now, &mut uarts[0]);
        if links[0].received().is_some() {
            links[0].pop(); // nothing else comes from the host in the exercise
        }

        // 3. The report, once.
        let done = (0..LINKS).all(|l| {
            neighbours[l] == NONE || (tally[l].sent == count && links[l + 1].can_send() && tally[l].received >= count)
        });
        if done && !reported && links[0].can_send() {
            let mut report: Vec<u8, 113> = Vec::new();
            let _ = report.push(id);
            for l in 0..LINKS {
                let s: SerialStats = links[l + 1].stats();
                let _ = report.extend_from_slice(&tally[l].received.to_le_bytes());
                let _ = report.extend_from_slice(&tally[l].mismatches.to_le_bytes());
                for v in [s.sent, s.acked, s.retransmitted, s.duplicates, s.skipped, uarts[l + 1].overruns()] {
                    let _ = report.extend_from_slice(&v.to_le_bytes());
                }
            }
            reported = links[0].send(KIND_REPORT, &report).is_ok();
        }
        wait(uarts);
    }
}

/// Every device interrupt (and SysTick's): acknowledge the UARTs'; waking the core was the
/// point.
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(_irqn: i16) {
    uart::clear_interrupts();
}

/// SysTick: waking the core is the point.
#[cortex_m_rt::exception]
fn SysTick() {}
