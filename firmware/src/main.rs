//! One RC² cell on a Cortex-M4F: the real `cell_core::cell::Cell` at (5, 7) loads the facet
//! packets of [`scenario::TABLE`] through `load_step`, then the firmware prints a digest of
//! every output and of the final dexel store over semihosting and exits with semihosting's exit
//! code. `tests/tests/firmware_qemu.rs` runs it under QEMU and recomputes the digest on the
//! host with the same `scenario.rs`.
#![no_std]
#![no_main]

mod scenario;

use core::panic::PanicInfo;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};

#[entry]
fn main() -> ! {
    let o = scenario::run(&scenario::TABLE);
    hprintln!(
        "cell=({},{}) packets={} spans={} forwarded={} undecodable={} dexels={} voxels={} shared={} overflows={} lost={}",
        scenario::X,
        scenario::Y,
        o.packets,
        o.spans,
        o.forwarded,
        o.undecodable,
        o.dexels,
        o.voxels,
        o.shared,
        o.overflows,
        o.lost
    );
    hprintln!("digest={:016x}", o.digest);
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
