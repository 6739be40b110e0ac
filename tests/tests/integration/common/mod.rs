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
    let mut grid = host_sim::machine::grid::Grid::<64>::new(n, n);
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

/// A dexel plane as the plane-rule oracle reads it, referred to depth `lo` (`two_sided`: a
/// dexel's plane says it; a visible surface, turned toward the viewer, is read as it is).
fn surface(lo: i64, p: &cell_core::plane::DexelPlane, two_sided: bool) -> rc2_tests::oracle::lit::Surface {
    rc2_tests::oracle::lit::Surface { lo, nx: p.nx as i64, ny: p.ny as i64, nz: p.nz as i64, e: p.e as i64, two_sided }
}

/// The plane rule's oracle view of a loaded grid: each occupied voxel's dexel plane.
pub fn surfaces_of<const D: usize>(
    g: &host_sim::machine::grid::Grid<D>,
) -> impl Fn(i64, i64, i64) -> Option<rc2_tests::oracle::lit::Surface> + '_ {
    move |x, y, z| {
        g.cell(x as u32, y as u32)
            .store
            .occupied(z as u16)
            .map(|d| surface(d.span.lo as i64, &d.plane, d.plane.two_sided()))
    }
}

/// The plane rule's oracle view of a loaded grid: each column's visible surface.
pub fn columns_of<const D: usize>(
    g: &host_sim::machine::grid::Grid<D>,
) -> impl Fn(i64, i64) -> Option<rc2_tests::oracle::lit::Visible> + '_ {
    move |x, y| {
        g.cell(x as u32, y as u32).visible.map(|v| rc2_tests::oracle::lit::Visible {
            z_v: v.z_v as i64,
            plane: surface(v.z_v as i64, &v.plane, false),
        })
    }
}

/// The classic shadow-ray oracle's view of a loaded grid: each occupied voxel's plane id and
/// plane.
pub fn occupants_of<const D: usize>(
    g: &host_sim::machine::grid::Grid<D>,
) -> impl Fn(i64, i64, i64) -> Option<rc2_tests::oracle::shadow::Occupant> + '_ {
    let planes = surfaces_of(g);
    move |x, y, z| {
        if [x, y].iter().any(|&c| c < 0 || c >= g.n as i64) || !(0..=u16::MAX as i64).contains(&z) {
            return None;
        }
        let id = g.cell(x as u32, y as u32).store.occupied(z as u16)?.plane.id;
        planes(x, y, z).map(|plane| rc2_tests::oracle::shadow::Occupant { id, plane })
    }
}

/// The emitting surface of column (x, y) for the classic shadow-ray oracle.
pub fn emitter_of<const D: usize>(
    g: &host_sim::machine::grid::Grid<D>,
    x: u32,
    y: u32,
) -> Option<rc2_tests::oracle::shadow::Emitter> {
    let v = g.cell(x, y).visible?;
    let plane = columns_of(g)(x as i64, y as i64)?.plane;
    Some(rc2_tests::oracle::shadow::Emitter { x: x as i64, y: y as i64, num: v.num, den: v.den, id: v.plane.id, plane })
}

/// The packets of lattice triangles with their planes (ids shared by coplanar ones) and
/// distinct materials, skipping degenerate ones. Every second triangle is two-sided (a facet of
/// an open surface, [`cell_core::plane::TWO_SIDED`]) so that random scenes exercise both kinds.
pub fn packets_of(
    tris: &[[[i64; 3]; 3]],
    cfg: &host_sim::precompute::LoadConfig,
) -> Vec<cell_core::facet::PipelinePacket> {
    let mut ids = host_sim::precompute::PlaneIds::default();
    tris.iter()
        .enumerate()
        .filter_map(|(i, t)| {
            let plane = host_sim::precompute::facet_plane(t, i as u32, i % 2 == 1, &mut ids);
            let tag = cell_core::dexel::FacetTag { facet: i as u32, material: i as u16, plane, ..Default::default() };
            host_sim::precompute::facet_packet(t, tag, cfg).expect("in budget").ok()
        })
        .collect()
}

/// Facets at the loading arithmetic's limits on an n-grid (lattice span `m = Q·n − 1`): vertices
/// on the lattice's corners, planes across the whole grid, a needle one lattice step wide (the
/// largest coefficients and edge values of `cell_core::voxelize`'s bit budget).
pub fn budget_facets(n: u32) -> [[[i64; 3]; 3]; 4] {
    let m = host_sim::precompute::Q * n as i64 - 1;
    [
        [[0, 0, 0], [m, 0, m], [0, m, m]],
        [[m, m, 0], [0, m, m], [m, 0, m]],
        [[0, 0, m], [m, m, 0], [m, 0, 0]],
        [[0, 0, 0], [m, 1, 0], [0, m, m]],
    ]
}
