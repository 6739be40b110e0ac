//! The eight neighbour links of the cell as `embedded-hal` devices, with the trace standing in
//! for the wires: a neighbour's ready line (an `InputPin`) and the frame link (an `SpiDevice`).
//! On a board these would be GPIO inputs and an SPI (or UART) peripheral from its HAL.

use core::convert::Infallible;
use core::sync::atomic::{AtomicU32, Ordering};

use cell_core::light::Port;
use cell_core::link::HalLink;
use embedded_hal::digital::{ErrorType as PinErrorType, InputPin};
use embedded_hal::spi::{ErrorType as SpiErrorType, Operation, SpiDevice};

static SENT_BYTES: AtomicU32 = AtomicU32::new(0);

/// A neighbour's ready (credit) line.
pub struct ReadyLine(bool);

impl PinErrorType for ReadyLine {
    type Error = Infallible;
}

impl InputPin for ReadyLine {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.0)
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0)
    }
}

/// The frame link to a neighbour: counts what it sends.
pub struct FrameWire;

impl SpiErrorType for FrameWire {
    type Error = Infallible;
}

impl SpiDevice for FrameWire {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), Infallible> {
        for op in operations {
            if let Operation::Write(b) = op {
                SENT_BYTES.fetch_add(b.len() as u32, Ordering::Relaxed);
            }
        }
        Ok(())
    }
}

/// The cell's eight output links, none ready.
pub fn links() -> [HalLink<ReadyLine, FrameWire>; 8] {
    core::array::from_fn(|_| HalLink { ready: ReadyLine(false), spi: FrameWire })
}

/// The neighbour on `port` raises its ready line (it takes our head message); the others are
/// low for this link cycle.
pub fn grant(links: &mut [HalLink<ReadyLine, FrameWire>; 8], port: Port) {
    for (i, l) in links.iter_mut().enumerate() {
        l.ready.0 = i == port.index();
    }
}

/// A frame goes out on link `port` (a ray a neighbour took).
pub fn send(links: &mut [HalLink<ReadyLine, FrameWire>; 8], port: Port, frame: &[u8]) {
    let _ = links[port.index()].spi.write(frame);
}

/// Frame bytes sent on all links so far.
pub fn bytes_sent() -> u32 {
    SENT_BYTES.load(Ordering::Relaxed)
}
