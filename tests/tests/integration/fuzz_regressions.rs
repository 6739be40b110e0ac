//! Replays every input kept in `fuzz/regressions/<target>/` (crashes and slow inputs the
//! fuzzers found, plus seeds) through the fuzz targets' bodies, which this test includes from
//! `fuzz/src/lib.rs`: each must now run to completion without a panic.

#[allow(dead_code)]
#[path = "../../../fuzz/src/lib.rs"]
mod fuzz_bodies;

fn replay(target: &str, body: fn(&[u8])) -> usize {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/regressions").join(target);
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let p = e.unwrap().path();
        body(&std::fs::read(&p).unwrap());
        n += 1;
    }
    n
}

#[test]
fn obj_load_regressions() {
    assert!(replay("obj_load", fuzz_bodies::obj_load) > 0);
}

#[test]
fn link_decode_regressions() {
    assert!(replay("link_decode", fuzz_bodies::link_decode) > 0);
}
