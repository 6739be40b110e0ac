//! Test fixtures (not oracles): large random planes through a measuring box, voxelized by the
//! real wave. Shared by `tests/topology.rs` (tunnels) and `tests/rays.rs` (rays through them).

use cell_core::dexel::FacetTag;
use host_sim::machine::grid::Grid;
use host_sim::precompute::{facet_packet, Contour, LoadConfig, Thickness};

/// Grid side of the fixture.
pub const N: u32 = 48;
/// The measuring box (voxels, inclusive), well inside every plane's triangle.
pub const LO: [i64; 3] = [16, 16, 16];
/// Upper corner of the measuring box.
pub const HI: [i64; 3] = [31, 31, 31];

/// A random plane through the measuring box: a triangle (lattice units) far larger than the
/// box, dominant axis `d`, heights chosen so that `d` stays dominant. Deterministic in `seed`.
pub fn random_plane(seed: u64) -> [[i64; 3]; 3] {
    // splitmix64: a tiny deterministic generator, so the table is reproducible.
    let mut state = seed;
    let mut next = move |m: u64| {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        (z ^ (z >> 31)) % m
    };
    let d = next(3) as usize;
    let (u, v) = ((d + 1) % 3, (d + 2) % 3);
    // Through a point near the box centre (lattice 384), slopes below 1 so d stays dominant.
    let c = 384 + next(17) as i64 - 8;
    let (s1, s2) = (next(1801) as i64 - 900, next(1801) as i64 - 900); // slopes in 1/1000
    let uv = [(-400, -400), (1600, -400), (-400, 1600)];
    let mut tri = [[0i64; 3]; 3];
    for (k, &(pu, pv)) in uv.iter().enumerate() {
        tri[k][u] = pu;
        tri[k][v] = pv;
        tri[k][d] = c + (s1 * (pu - 384) + s2 * (pv - 384)) / 1000;
    }
    tri
}

/// The triangle voxelized by the loading wave on an N × N × N grid.
pub fn voxelized(tri: &[[i64; 3]; 3], thickness: Thickness) -> Grid<4> {
    let cfg = LoadConfig { n: N, thickness, contour: Contour::Projected };
    let pkt = facet_packet(tri, FacetTag::default(), &cfg).unwrap().expect("non-degenerate");
    let mut grid = Grid::<4>::new(N, N);
    grid.load_wave(std::slice::from_ref(&pkt), |_| {});
    grid
}
