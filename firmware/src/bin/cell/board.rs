//! The cell's wires on the board: polled drivers for the CMSDK APB UART (one per link) and the
//! CMSDK AHB GPIO (the ready lines), the peripherals of the MPS2 FPGA images (QEMU
//! `mps2-an386`), behind `embedded-hal` traits.
//!
//! * Link `i` (host, then ports E … SE in [`Port::ALL`] order) is the UART at [`LINK_UART`]`[i]`.
//!   The an386 has five UARTs (0x4000_4000 … 0x4000_7000 and 0x4000_9000): the host and the
//!   four axis links; the diagonal links sit in the board's unused APB space (QEMU reads it as
//!   zero: silent links). A board with nine serial ports gives each its own.
//! * The neighbour on port `p` raises its ready line (FIFO credit for us) on input `p` of GPIO0;
//!   this cell drives its own ready line to that neighbour on output `p` of GPIO1.
//!
//! Registers are read and written with volatile accesses: the compiler can assume nothing
//! about what a link delivers, so the image keeps all of the cell's code.

use core::convert::Infallible;

use cell_core::light::Port;
use embedded_hal::digital::{ErrorType as PinErrorType, InputPin, OutputPin};
use embedded_hal::spi::{self, Operation, SpiDevice};

use crate::cmsdk::{read, write, BAUDDIV, CTRL, CTRL_TX_RX_ENABLE, DATA, STATE, STATE_RX_FULL, STATE_TX_FULL};

/// UART base addresses: the host link, then one per port in [`Port::ALL`] order.
pub const LINK_UART: [usize; 9] = [
    0x4000_4000, // host
    0x4000_5000, // E
    0x4000_A000, // NE
    0x4000_6000, // N
    0x4000_B000, // NW
    0x4000_7000, // W
    0x4000_C000, // SW
    0x4000_9000, // S
    0x4000_D000, // SE
];
/// GPIO0: the neighbours' ready lines (inputs).
const GPIO_READY_IN: usize = 0x4001_0000;
/// GPIO1: this cell's ready lines to its neighbours (outputs).
const GPIO_READY_OUT: usize = 0x4001_1000;

// CMSDK AHB GPIO registers.
const GPIO_DATA: usize = 0x00;
const GPIO_DATAOUT: usize = 0x04;
const GPIO_OUTENSET: usize = 0x10;

/// One UART: a byte stream carrying link frames.
#[derive(Clone, Copy)]
pub struct Uart(usize);

impl Uart {
    /// Enable the UART of link `i` (`LINK_UART[i]`).
    pub fn link(i: usize) -> Uart {
        let u = Uart(LINK_UART[i]);
        write(u.0 + BAUDDIV, 16);
        write(u.0 + CTRL, CTRL_TX_RX_ENABLE);
        u
    }

    /// The byte waiting in the receiver, if any.
    pub fn read_byte(self) -> Option<u8> {
        (read(self.0 + STATE) & STATE_RX_FULL != 0).then(|| read(self.0 + DATA) as u8)
    }

    /// Send `bytes`, waiting for room in the transmitter.
    pub fn write_all(self, bytes: &[u8]) {
        for &b in bytes {
            while read(self.0 + STATE) & STATE_TX_FULL != 0 {}
            write(self.0 + DATA, b as u32);
        }
    }
}

/// The frame link to a neighbour as the `SpiDevice` that [`cell_core::link::HalLink`] takes:
/// its writes go out of the link's UART (embedded-hal 1 has no serial trait).
pub struct FrameWire(pub Uart);

/// The only transfer a frame link does is a write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadUnsupported;

impl spi::Error for ReadUnsupported {
    fn kind(&self) -> spi::ErrorKind {
        spi::ErrorKind::Other
    }
}

impl spi::ErrorType for FrameWire {
    type Error = ReadUnsupported;
}

impl SpiDevice for FrameWire {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), ReadUnsupported> {
        for op in operations {
            match op {
                Operation::Write(b) => self.0.write_all(b),
                Operation::DelayNs(_) => {}
                _ => return Err(ReadUnsupported),
            }
        }
        Ok(())
    }
}

/// The ready line the neighbour on a port drives: high when it has FIFO credit for us.
pub struct ReadyIn(u32);

impl ReadyIn {
    /// The neighbour's line on port `p`.
    pub fn port(p: Port) -> ReadyIn {
        ReadyIn(1 << p.index())
    }
}

impl PinErrorType for ReadyIn {
    type Error = Infallible;
}

impl InputPin for ReadyIn {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(read(GPIO_READY_IN + GPIO_DATA) & self.0 != 0)
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        self.is_high().map(|h| !h)
    }
}

/// This cell's ready line to the neighbour on a port.
pub struct ReadyOut(u32);

impl ReadyOut {
    /// The line to the neighbour on port `p` (made an output).
    pub fn port(p: Port) -> ReadyOut {
        let bit = 1 << p.index();
        write(GPIO_READY_OUT + GPIO_OUTENSET, bit);
        ReadyOut(bit)
    }
}

impl PinErrorType for ReadyOut {
    type Error = Infallible;
}

impl OutputPin for ReadyOut {
    fn set_high(&mut self) -> Result<(), Infallible> {
        let a = GPIO_READY_OUT + GPIO_DATAOUT;
        write(a, read(a) | self.0);
        Ok(())
    }
    fn set_low(&mut self) -> Result<(), Infallible> {
        let a = GPIO_READY_OUT + GPIO_DATAOUT;
        write(a, read(a) & !self.0);
        Ok(())
    }
}
