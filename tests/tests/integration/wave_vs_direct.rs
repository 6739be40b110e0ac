//! The cycle-stepped RC² wave produces exactly the dexels of the direct host evaluation of the
//! same integer formulas, cell by cell, on every shipped mesh at n = 64 and 128 (thesis ch. 3).

use crate::common;

use host_sim::machine::grid::Grid;
use host_sim::precompute::{prepare, LoadConfig};
use host_sim::scene;

const CAP: usize = 128;

fn compare(name: &str, cfg: LoadConfig) {
    let mesh = scene::load(name).unwrap();
    let prep = prepare(&mesh, &cfg).unwrap();
    let mut wave = Grid::<CAP>::new(cfg.n, cfg.n);
    let rep = wave.load_wave(&prep.packets, |_| {});
    let mut direct = Grid::<CAP>::new(cfg.n, cfg.n);
    direct.load_direct(&prep.packets, |_| {});
    let mut voxels = 0u64;
    for (w, d) in wave.cells.iter().zip(&direct.cells) {
        assert_eq!(w.store.overflows(), 0, "{name}: capacity too small for the test");
        assert_eq!(w.store.dexels(), d.store.dexels(), "{name} {cfg:?}: cell ({}, {}) differs", w.x, w.y);
        voxels += w.store.voxel_count() as u64;
    }
    assert!(voxels > 0);
    // The wave is systolic: every facet enters one cycle after the previous one and the last
    // one travels at most n pipeline cells and n row cells.
    assert!(rep.cycles <= prep.packets.len() as u64 + 2 * cfg.n as u64, "{name}: {} cycles", rep.cycles);
    assert_eq!(rep.host_messages, prep.packets.len() as u64);
}

#[test]
fn every_shipped_mesh_at_64_and_128() {
    for name in ["cornell", "cow", "fandisk", "suzanne", "teapot", "facet"] {
        for n in [64, 128] {
            compare(name, LoadConfig::watertight(n));
        }
    }
}

#[test]
fn every_mode_on_two_meshes() {
    for name in ["cornell", "teapot"] {
        for thickness in common::THICKNESSES {
            for contour in common::CONTOURS {
                compare(name, LoadConfig { n: 64, thickness, contour });
            }
        }
    }
}
