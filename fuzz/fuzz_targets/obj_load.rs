//! OBJ/MTL bytes → scene → precompute → loading wave at n = 16. Any input must give a value
//! (a mesh or an error), never a panic (overflow checks are on), a hang or unbounded memory.
//! Bytes after the first NUL are the MTL file every `mtllib` resolves to.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    rc2_fuzz::obj_load(data);
});
