//! How deep the stack went: at boot the free RAM between the end of the statics
//! (`_stack_end`, cortex-m-rt's linker script) and the stack pointer is painted with a pattern;
//! after the replays the lowest word that no longer holds it marks the deepest the stack
//! reached. The replay image keeps its cell in a static (about 19 KB), so its stack has what
//! is left of the 64 KiB of `memory.x`; this says how much of that it used. The production
//! images (`src/bin/cell`) keep everything on the stack and report the peak with every
//! report frame.

use core::ptr::{addr_of, read_volatile, write_volatile};

/// The paint.
const PAINT: u32 = 0x5a5a_a5a5;
/// Words below the stack pointer left unpainted at boot (the painting code's own frame).
const MARGIN: usize = 64;

extern "C" {
    static _stack_end: u32;
    static _stack_start: u32;
}

fn bounds() -> (usize, usize) {
    (addr_of!(_stack_end) as usize, addr_of!(_stack_start) as usize)
}

/// Paint the free stack below the current stack pointer.
pub fn paint() {
    let (lo, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize - 4 * MARGIN;
    for a in (lo..sp).step_by(4) {
        // SAFETY: free RAM between the statics and the live stack, word-aligned.
        unsafe { write_volatile(a as *mut u32, PAINT) };
    }
}

/// Bytes of stack used at the deepest so far (from the top of RAM).
pub fn peak() -> usize {
    let (lo, hi) = bounds();
    // SAFETY: reads of RAM between the statics and the top of the stack, word-aligned.
    let used = (lo..hi).step_by(4).find(|&a| unsafe { read_volatile(a as *const u32) } != PAINT).unwrap_or(hi);
    hi - used
}
