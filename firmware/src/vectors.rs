//! The device part of the vector table: the MPS2 board's 32 interrupt lines, all to
//! cortex-m-rt's default handler (the firmware pends only PendSV, a core exception).
//! cortex-m-rt's `device` feature takes the table from here instead of its 240-entry
//! default: 832 bytes less flash (`build.rs` writes the empty `device.x` it includes).

extern "C" {
    fn DefaultHandler();
}

/// Interrupt vectors 0..31.
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
static __INTERRUPTS: [unsafe extern "C" fn(); 32] = [DefaultHandler; 32];
