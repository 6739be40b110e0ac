//! How a test image ends under QEMU (the replay image, the grid's board): its exit status
//! through semihosting, and a panic's message printed before a failing exit.
//!
//! **Invariant**: the image never returns from [`exit`] or a panic; QEMU ends with the status.

use core::panic::PanicInfo;

use cortex_m_semihosting::{debug, hprintln};

/// End QEMU with success or failure.
pub fn exit(ok: bool) -> ! {
    debug::exit(if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    exit(false)
}
