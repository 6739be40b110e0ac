//! The ARM CMSDK APB UART's registers (DDI 0479; QEMU's `hw/char/cmsdk-apb-uart.c`), the
//! UARTs of the MPS2 FPGA images (QEMU `mps2-an386`), and the volatile accesses every driver
//! of a memory-mapped peripheral here goes through. Shared by the production cell
//! (`src/bin/cell/board.rs`) and the grid's board (`src/bin/board/uart.rs`); each uses the part
//! of the map it needs.
#![allow(dead_code)]

use core::ptr::{read_volatile, write_volatile};

/// Data: the byte received, or the byte to send.
pub const DATA: usize = 0x00;
/// State: bit 0 transmitter full, bit 1 receiver full, bits 2 and 3 the transmit and receive
/// overruns (write 1 to clear).
pub const STATE: usize = 0x04;
/// Control: bit 0 transmit enable, bit 1 receive enable, bits 2 and 3 their interrupts.
pub const CTRL: usize = 0x08;
/// Interrupt status / clear (write 1 to clear).
pub const INTCLEAR: usize = 0x0C;
/// Baud divider (at least 16).
pub const BAUDDIV: usize = 0x10;
pub const STATE_TX_FULL: u32 = 1 << 0;
pub const STATE_RX_FULL: u32 = 1 << 1;
pub const STATE_OVERRUNS: u32 = 0b1100;
/// Transmitter and receiver enabled.
pub const CTRL_TX_RX_ENABLE: u32 = 0b0011;
/// Transmitter, receiver and both their interrupts enabled.
pub const CTRL_ENABLE_WITH_INTERRUPTS: u32 = 0b1111;

/// Read the 32-bit register at `addr`.
pub fn read(addr: usize) -> u32 {
    // SAFETY: callers pass fixed, aligned peripheral register addresses of the MPS2 images.
    unsafe { read_volatile(addr as *const u32) }
}

/// Write the 32-bit register at `addr`.
pub fn write(addr: usize, v: u32) {
    // SAFETY: as in `read`.
    unsafe { write_volatile(addr as *mut u32, v) }
}
