//! Never lose: a bounded lit store that fills is a counted event that fails
//! the run with a message naming the cell and the capacity to raise.
//!
//! The situation is built on purpose: one column holds every other voxel (z = 2, 4, 6, …), so
//! each lit voxel is its own run, and a source far across the grid lights most of them from
//! the side — more runs than the column's `LIT_CAP`.

use cell_core::dexel::FacetTag;
use cell_core::units::Span;
use host_sim::machine::grid::capacity::LIT_CAP;
use host_sim::machine::grid::Grid;
use host_sim::machine::lighting::diffuse::{diffuse_in, source_at, LightConfig};
use host_sim::machine::lighting::run::check_lit_overflow;

fn striped_column_lighting(stripes: u16) -> (u32, u64, Result<(), String>) {
    let n = 2 * stripes as u32 + 8;
    let mut grid = Grid::<128>::new(n, n);
    let y0 = n / 2;
    let col = &mut grid.cells[(y0 * n) as usize];
    // Each stripe's plane faces the source (+x), on the voxel's near face: g = 2^14·(p_x − ½) − 1
    // (m = 1024 makes the stored offset the exact value, see cell_core::plane).
    let plane = cell_core::plane::FacetPlane { id: 1, nx: 1 << 14, ny: 0, nz: 0, m: 1024 };
    let face = cell_core::plane::ColumnPlane { p: -(1 << 13) - 1, c: 0 };
    for k in 0..stripes {
        let tag = FacetTag { facet: k as u32, plane, ..Default::default() };
        let ins = col.store.insert_on(Span { lo: 2 * k + 2, hi: 2 * k + 2 }, tag, &face);
        assert_eq!(ins.lost, 0, "the column holds every stripe");
    }
    let src = source_at(0, [n as f64 - 1.0, y0 as f64, n as f64 / 2.0], n).unwrap();
    let cfg = LightConfig {
        fa: 16,
        policy: cell_core::light::Policy::Wavefront,
        merge: true,
        record_visits: false,
        ..host_sim::config::plane_rule()
    };
    let lighting = diffuse_in::<128>(&grid, &[src], &cfg, |_, _| {}).unwrap();
    let runs = lighting.cells[(y0 * n) as usize].lit.runs().len() as u32;
    (runs, lighting.lit_overflows(), check_lit_overflow(&lighting).map_err(|e| e.to_string()))
}

#[test]
fn lit_store_overflow_names_the_cell_and_the_capacity() {
    let stripes = LIT_CAP as u16 + 24;
    let (runs, lost, res) = striped_column_lighting(stripes);
    assert_eq!(runs as usize, LIT_CAP, "the column's lit store is full");
    assert!(lost > 0);
    let err = res.unwrap_err();
    let n = 2 * stripes as u32 + 8;
    assert!(err.contains(&format!("first at cell (0, {})", n / 2)), "{err}");
    assert!(err.contains(&format!("more than {LIT_CAP} lit runs")), "{err}");
    assert!(err.contains("raise LIT_CAP"), "{err}");
    assert!(err.contains(&format!("{lost} lit marks lost")), "{err}");
}

#[test]
fn below_capacity_nothing_is_lost() {
    let (runs, lost, res) = striped_column_lighting(12);
    assert!(runs > 4 && (runs as usize) < LIT_CAP, "{runs}");
    assert_eq!(lost, 0);
    res.unwrap();
}
