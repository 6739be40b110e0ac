//! Byte-at-a-time memory routines for the production image. compiler-builtins' word-optimised
//! `memcpy`/`memmove`/`memset` and their `__aeabi_*` entry points take about 2.9 KiB of flash;
//! a cell copies beams of 36 bytes and FIFO slots, where a byte loop costs little time. The
//! symbols here are strong and compiler-builtins' are weak, so the linker takes these.
//!
//! Volatile accesses keep the optimiser from recognising the loops as copies and calling the
//! routine being defined.

use core::ptr::{read_volatile, write_volatile};

unsafe fn copy_forward(dest: *mut u8, src: *const u8, n: usize) {
    for i in 0..n {
        // SAFETY: the caller's contract: `n` bytes readable at `src`, writable at `dest`.
        unsafe { write_volatile(dest.add(i), read_volatile(src.add(i))) }
    }
}

unsafe fn copy_backward(dest: *mut u8, src: *const u8, n: usize) {
    for i in (0..n).rev() {
        // SAFETY: as in `copy_forward`.
        unsafe { write_volatile(dest.add(i), read_volatile(src.add(i))) }
    }
}

unsafe fn fill(dest: *mut u8, c: u8, n: usize) {
    for i in 0..n {
        // SAFETY: the caller's contract: `n` bytes writable at `dest`.
        unsafe { write_volatile(dest.add(i), c) }
    }
}

/// C `memcpy`.
#[no_mangle]
unsafe extern "C" fn memcpy(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    unsafe { copy_forward(dest, src, n) };
    dest
}

/// Overlapping copies go the safe way round. The `__aeabi_memmove*` entry points call this, not
/// `memmove`: LLVM takes a call to a function named `memmove` for the C library's, turns it into
/// its `llvm.memmove` intrinsic and lowers that, on ARM, to a call to `__aeabi_memmove` — from
/// inside `__aeabi_memmove`, an endless recursion that ran the stack out of RAM at the cell's
/// first FIFO removal (`heapless::Vec::remove`) and hard-faulted the core.
unsafe fn move_bytes(dest: *mut u8, src: *const u8, n: usize) {
    if (dest as usize) <= (src as usize) {
        unsafe { copy_forward(dest, src, n) };
    } else {
        unsafe { copy_backward(dest, src, n) };
    }
}

/// C `memmove`.
#[no_mangle]
unsafe extern "C" fn memmove(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    unsafe { move_bytes(dest, src, n) };
    dest
}

/// C `memset`.
#[no_mangle]
unsafe extern "C" fn memset(dest: *mut u8, c: i32, n: usize) -> *mut u8 {
    unsafe { fill(dest, c as u8, n) };
    dest
}

/// ARM EABI copy entry points (the `4`/`8` variants only promise alignment).
#[no_mangle]
unsafe extern "C" fn __aeabi_memcpy(dest: *mut u8, src: *const u8, n: usize) {
    unsafe { copy_forward(dest, src, n) }
}
/// See [`__aeabi_memcpy`].
#[no_mangle]
unsafe extern "C" fn __aeabi_memcpy4(dest: *mut u8, src: *const u8, n: usize) {
    unsafe { copy_forward(dest, src, n) }
}
/// See [`__aeabi_memcpy`].
#[no_mangle]
unsafe extern "C" fn __aeabi_memcpy8(dest: *mut u8, src: *const u8, n: usize) {
    unsafe { copy_forward(dest, src, n) }
}
/// ARM EABI move entry points (through [`move_bytes`], never `memmove`: see there).
#[no_mangle]
unsafe extern "C" fn __aeabi_memmove(dest: *mut u8, src: *const u8, n: usize) {
    unsafe { move_bytes(dest, src, n) }
}
/// See [`__aeabi_memmove`].
#[no_mangle]
unsafe extern "C" fn __aeabi_memmove4(dest: *mut u8, src: *const u8, n: usize) {
    unsafe { move_bytes(dest, src, n) }
}
/// See [`__aeabi_memmove`].
#[no_mangle]
unsafe extern "C" fn __aeabi_memmove8(dest: *mut u8, src: *const u8, n: usize) {
    unsafe { move_bytes(dest, src, n) }
}
/// ARM EABI fill entry points: note the argument order (length before value).
#[no_mangle]
unsafe extern "C" fn __aeabi_memset(dest: *mut u8, n: usize, c: i32) {
    unsafe { fill(dest, c as u8, n) }
}
/// See [`__aeabi_memset`].
#[no_mangle]
unsafe extern "C" fn __aeabi_memset4(dest: *mut u8, n: usize, c: i32) {
    unsafe { fill(dest, c as u8, n) }
}
/// See [`__aeabi_memset`].
#[no_mangle]
unsafe extern "C" fn __aeabi_memset8(dest: *mut u8, n: usize, c: i32) {
    unsafe { fill(dest, c as u8, n) }
}
/// ARM EABI clear entry points.
#[no_mangle]
unsafe extern "C" fn __aeabi_memclr(dest: *mut u8, n: usize) {
    unsafe { fill(dest, 0, n) }
}
/// See [`__aeabi_memclr`].
#[no_mangle]
unsafe extern "C" fn __aeabi_memclr4(dest: *mut u8, n: usize) {
    unsafe { fill(dest, 0, n) }
}
/// See [`__aeabi_memclr`].
#[no_mangle]
unsafe extern "C" fn __aeabi_memclr8(dest: *mut u8, n: usize) {
    unsafe { fill(dest, 0, n) }
}

// Signed 64-bit division. compiler-builtins' `__divmoddi4` goes through a fast specialised
// unsigned division of about 1 KiB; a cell divides 64-bit values only while it loads (the
// exact floor/ceil divisions of `cell_core::voxelize`) and splits beams, a few times per
// packet. `__aeabi_ldivmod` (compiler-builtins' assembly entry point, kept) calls this one.
/// `n / d` and `n % d` for `d != 0`, one quotient bit per step (restoring division).
fn udivmod(n: u64, d: u64) -> (u64, u64) {
    let (mut q, mut r) = (0u64, 0u64);
    for i in (0..64).rev() {
        r = r << 1 | (n >> i & 1);
        if r >= d {
            r -= d;
            q |= 1 << i;
        }
    }
    (q, r)
}

/// Signed division truncating toward zero, the remainder with the dividend's sign (C and
/// Rust semantics; the caller has excluded `d == 0` and `i64::MIN / -1`).
fn divmod(a: i64, b: i64) -> (i64, i64) {
    let (q, r) = udivmod(a.unsigned_abs(), b.unsigned_abs());
    let q = if (a < 0) != (b < 0) { (q as i64).wrapping_neg() } else { q as i64 };
    let r = if a < 0 { (r as i64).wrapping_neg() } else { r as i64 };
    (q, r)
}

/// `a / b`, and `a % b` into `rem` (the C runtime's `__divmoddi4`).
#[no_mangle]
extern "C" fn __divmoddi4(a: i64, b: i64, rem: &mut i64) -> i64 {
    let (q, r) = divmod(a, b);
    *rem = r;
    q
}

/// `a / b`, and `a % b` into `rem` if given (the C runtime's `__udivmoddi4`, which
/// `__aeabi_uldivmod` calls): the empty-frustum skip's unsigned 64-bit divisions
/// (`cell_core::occupancy`), a few per beam it tests. compiler-builtins' own is 864 B more.
#[no_mangle]
extern "C" fn __udivmoddi4(a: u64, b: u64, rem: Option<&mut u64>) -> u64 {
    let (q, r) = udivmod(a, b);
    if let Some(rem) = rem {
        *rem = r;
    }
    q
}
