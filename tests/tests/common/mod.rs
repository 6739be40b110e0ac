//! Helpers shared by the integration tests: mode mapping between the product and the oracles.
#![allow(dead_code)]

use host_sim::precompute::{Contour, Thickness};
use rc2_tests::oracle::brute;

pub const THICKNESSES: [Thickness; 3] = [Thickness::Naive, Thickness::Thesis, Thickness::Standard];
pub const CONTOURS: [Contour; 2] = [Contour::Projected, Contour::Conservative];

pub fn oracle_thickness(t: Thickness) -> brute::Thickness {
    match t {
        Thickness::Naive => brute::Thickness::Naive,
        Thickness::Thesis => brute::Thickness::Thesis,
        Thickness::Standard => brute::Thickness::Standard,
    }
}

pub fn oracle_contour(c: Contour) -> brute::Contour {
    match c {
        Contour::Projected => brute::Contour::Projected,
        Contour::Conservative => brute::Contour::Conservative,
    }
}

/// Assert that the test runs with overflow checks (the test profile keeps them on).
pub fn assert_overflow_checks() {
    #[allow(clippy::assertions_on_constants)]
    {
        assert!(cfg!(debug_assertions), "run with overflow checks (the test profile keeps them on)");
    }
}

/// One planar convex lattice piece loaded alone by the wave into an n-grid, and the voxels
/// the brute-force oracle finds over the whole grid: `(got, want)`, both sorted.
pub fn wave_and_oracle_voxels(
    piece: &[[i64; 3]],
    n: u32,
    thickness: host_sim::precompute::Thickness,
    contour: host_sim::precompute::Contour,
) -> (Vec<[i64; 3]>, Vec<[i64; 3]>) {
    use host_sim::precompute::{facet_packet, LoadConfig, Q};
    let cfg = LoadConfig { n, thickness, contour };
    let mut grid = host_sim::grid::Grid::<64>::new(n, n);
    if let Ok(pkt) = facet_packet(piece, cell_core::dexel::FacetTag::default(), &cfg).expect("in budget") {
        grid.load_wave(std::slice::from_ref(&pkt), |_| {});
    }
    assert_eq!(grid.summary().overflow_cells, 0);
    let mut got = Vec::new();
    for c in &grid.cells {
        for d in c.store.dexels() {
            for z in d.span.lo..=d.span.hi {
                got.push([c.x as i64, c.y as i64, z as i64]);
            }
        }
    }
    got.sort_unstable();
    let hi = n as i64 - 1;
    let want =
        brute::facet_voxels(piece, Q, oracle_thickness(thickness), oracle_contour(contour), [0, 0, 0], [hi, hi, hi]);
    (got, want)
}
