//! A polled driver for the CMSDK APB UART (the UARTs of the MPS2 FPGA images, QEMU
//! `mps2-an386`), behind `embedded-io`'s [`Read`], [`ReadReady`], [`Write`] and [`WriteReady`]:
//! the byte stream a [`cell_core::serial::SerialLink`] runs over.
//!
//! The an386 has five UARTs, at [`UART_BASE`] (QEMU's `hw/arm/mps2.c` connects `-serial` i to
//! UART i). Registers (ARM CMSDK APB UART, DDI 0479, and QEMU's `hw/char/cmsdk-apb-uart.c`):
//! `DATA` (0x00), `STATE` (0x04: bit 0 transmitter full, bit 1 receiver full, bits 2 and 3 the
//! transmit and receive overruns, write 1 to clear), `CTRL` (0x08: bit 0 transmit enable, bit
//! 1 receive enable, bits 2 and 3 their interrupts), `INTSTATUS`/`INTCLEAR` (0x0C, write 1 to
//! clear), `BAUDDIV` (0x10, at least 16). Each direction holds one byte.
//!
//! The driver polls; the interrupts (a byte received, the transmitter free again) only wake a
//! core that waits for them ([`clear_interrupts`] is the handler's whole work).
//!
//! **Invariant**: a read takes a byte only while the receiver is full, a write puts one only
//! while the transmitter is not full, so neither overruns; [`Uart::overruns`] counts any
//! overrun the hardware reports anyway (a byte lost in the UART, which the link above repairs
//! like any loss on the wire).
//!
//! Registers are read and written with volatile accesses ([`crate::cmsdk`], the register map
//! the production cell's driver shares).

use core::convert::Infallible;

use embedded_io::{ErrorType, Read, ReadReady, Write, WriteReady};

use crate::cmsdk::{
    read, write, BAUDDIV, CTRL, CTRL_ENABLE_WITH_INTERRUPTS, DATA, INTCLEAR, STATE, STATE_OVERRUNS, STATE_RX_FULL,
    STATE_TX_FULL,
};

/// The an386's UARTs: 0 (the host link on a board of the grid), then 1 … 4.
pub const UART_BASE: [usize; 5] = [0x4000_4000, 0x4000_5000, 0x4000_6000, 0x4000_7000, 0x4000_9000];

/// One CMSDK APB UART.
pub struct Uart {
    base: usize,
    overruns: u32,
}

impl Uart {
    /// Enable UART `i` (`UART_BASE[i]`), transmitter and receiver, and their interrupts.
    pub fn new(i: usize) -> Uart {
        let base = UART_BASE[i];
        write(base + BAUDDIV, 16);
        write(base + CTRL, CTRL_ENABLE_WITH_INTERRUPTS);
        Uart { base, overruns: 0 }
    }

    /// Overruns the UART reported (bytes it lost).
    pub fn overruns(&self) -> u32 {
        self.overruns
    }

    fn state(&mut self) -> u32 {
        let s = read(self.base + STATE);
        if s & STATE_OVERRUNS != 0 {
            self.overruns += (s & STATE_OVERRUNS).count_ones();
            write(self.base + STATE, s & STATE_OVERRUNS);
        }
        s
    }
}

/// Acknowledge every UART's interrupts (the interrupt handler: the bytes themselves are
/// polled).
pub fn clear_interrupts() {
    for base in UART_BASE {
        write(base + INTCLEAR, 0b1111);
    }
}

impl ErrorType for Uart {
    type Error = Infallible;
}

impl ReadReady for Uart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.state() & STATE_RX_FULL != 0)
    }
}

impl Read for Uart {
    /// Waits for the first byte, then takes the bytes the receiver has, up to `buf.len()`.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        if buf.is_empty() {
            return Ok(0);
        }
        while self.state() & STATE_RX_FULL == 0 {}
        let mut n = 0;
        while n < buf.len() && self.state() & STATE_RX_FULL != 0 {
            buf[n] = read(self.base + DATA) as u8;
            n += 1;
        }
        Ok(n)
    }
}

impl WriteReady for Uart {
    fn write_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.state() & STATE_TX_FULL == 0)
    }
}

impl Write for Uart {
    /// Waits for room for the first byte, then writes while the transmitter takes bytes.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        if buf.is_empty() {
            return Ok(0);
        }
        while self.state() & STATE_TX_FULL != 0 {}
        let mut n = 0;
        while n < buf.len() && self.state() & STATE_TX_FULL == 0 {
            write(self.base + DATA, buf[n] as u32);
            n += 1;
        }
        Ok(n)
    }

    /// Waits until the transmitter has taken the last byte.
    fn flush(&mut self) -> Result<(), Infallible> {
        while self.state() & STATE_TX_FULL != 0 {}
        Ok(())
    }
}
