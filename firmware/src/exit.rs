//! How a test image ends under QEMU (the replay image, the grid's board): its exit status
//! through semihosting, and a panic's message printed before a failing exit — on stderr, so
//! that it never mixes with what the image writes on stdout (the replay's digests, the board's
//! binary defmt log).
//!
//! **Invariant**: the image never returns from [`exit`] or a panic; QEMU ends with the status.

use core::panic::PanicInfo;

use cortex_m_semihosting::{debug, heprintln};

/// End QEMU with success or failure.
pub fn exit(ok: bool) -> ! {
    debug::exit(if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    loop {
        cortex_m::asm::wfi();
    }
}

/// A fault (a bus error; a stack grown over the statics, which leaves garbage pointers) ends
/// QEMU with failure and the faulting address, instead of spinning until the test's timeout.
#[cortex_m_rt::exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    heprintln!("hard fault at pc {:#010x}", ef.pc());
    exit(false)
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    heprintln!("panic: {}", info);
    exit(false)
}
