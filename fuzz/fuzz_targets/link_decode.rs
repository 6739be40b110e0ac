//! The inter-cell frame decoder on arbitrary bytes: framed (CRC-checked) and, to get past the
//! CRC, raw payloads of every kind. A decoded message must re-encode to the same frame and be
//! safe for a cell to act on (a row packet steps through row cells, a beam splits).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    rc2_fuzz::link_decode(data);
});
