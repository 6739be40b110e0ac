//! The bodies of the fuzz targets, shared with the regression replay
//! (`tests/tests/integration/fuzz_regressions.rs` includes this file).

use cell_core::beam::{frac::U0, frac::U8, FarDistance, FracBits};
use cell_core::cell::Cell;
use cell_core::wire::{Frame, Message, RawFrame, MAX_FRAME};
use host_sim::precompute::{prepare, LoadConfig};

/// OBJ (and MTL after the first NUL) → mesh → packets → wave at n = 16.
pub fn obj_load(data: &[u8]) {
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], Some(&data[i + 1..])),
        None => (data, None),
    };
    let Ok(mesh) = host_sim::scene::load_obj_bytes("fuzz", obj, mtl) else {
        return;
    };
    let cfg = LoadConfig::watertight(16);
    let Ok(prepared) = prepare(&mesh, &cfg) else {
        return;
    };
    let mut grid = host_sim::machine::grid::Grid::<8>::new(16, 16);
    grid.load_wave(&prepared.packets, |_| {});
    let _ = grid.summary();
}

fn decode_as<F: FracBits>(data: &[u8], d: u32) {
    let far = FarDistance::<F>::new(d).expect("valid D");
    let mut frames = vec![];
    if let Ok((frame, used)) = Frame::<F>::parse(data, far) {
        assert!(used <= data.len());
        frames.push(frame);
    }
    if let Some((&kind, payload)) = data.split_first() {
        if let Ok(frame) = Frame::<F>::parse_payload(RawFrame { kind, payload }, far) {
            frames.push(frame);
        }
    }
    for f in frames {
        let mut buf = [0u8; MAX_FRAME];
        let len = f.emit(&mut buf).expect("a decoded message re-encodes");
        let (again, used) = Frame::<F>::parse(&buf[..len], far).expect("its encoding decodes");
        assert_eq!((again, used), (f.clone(), len));
        match f.msg {
            Message::Row(mut p) => {
                for x in 0..64u16 {
                    let mut cell = Cell::<4>::new(x, 3);
                    if !cell.load_step(&mut p, 16) {
                        break;
                    }
                }
            }
            Message::Beam(m) => {
                let src = cell_core::beam::Source::new(
                    cell_core::beam::SourceId(0),
                    [cell_core::beam::SourceCoord::from_bits(8); 3],
                );
                if let Some(at) = m.beam.voxel(&src, far) {
                    let _ = m.beam.split(&src, far, at);
                }
            }
            Message::Ack => {}
        }
    }
}

/// Decode arbitrary bytes as frames for f = 0 and f = 8.
pub fn link_decode(data: &[u8]) {
    decode_as::<U0>(data, 15);
    decode_as::<U8>(data, 255);
}
