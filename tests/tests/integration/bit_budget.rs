//! Bit budget (thesis §3.5–§3.7, the incremental arithmetic): the loading arithmetic is `i64` and overflow-free up to
//! `MAX_N = 65 536` cells per side with a 1/16-voxel lattice. This test runs the real pipeline
//! and row cells of cell-core at that size — the whole pipeline, then whole rows at the top,
//! middle and bottom — on extreme facets (vertices on the lattice's corners and faces), with
//! overflow checks on, and compares every incremental value and every span with an `i128`
//! evaluation of the same formulas.

use cell_core::cell::Cell;
use cell_core::dexel::FacetTag;
use cell_core::units::MAX_N;
use cell_core::voxelize::{row_span, PipelineCell};
use host_sim::precompute::{facet_packet, Contour, LoadConfig, Thickness, Q};

fn floor_div(n: i128, d: i128) -> i128 {
    n.div_euclid(d) - if d < 0 && n.rem_euclid(d) != 0 { 1 } else { 0 }
}

#[test]
fn extreme_facets_at_max_n() {
    #[allow(clippy::assertions_on_constants)]
    {
        assert!(cfg!(debug_assertions), "run with overflow checks (the test profile keeps them on)");
    }
    let n = MAX_N;
    let m = Q * n as i64;
    let facets: Vec<Vec<[i64; 3]>> = vec![
        vec![[0, 0, 0], [m, 0, m], [0, m, m]],
        vec![[m, m, 0], [0, m, m], [m, 0, m]],
        vec![[0, 0, m], [m, m, 0], [m, 0, 0]],
        vec![[0, 0, 0], [m, m, m], [m, 0, 1]], // needle across the whole grid
        vec![[0, 0, 0], [m, 1, 0], [0, m, m]],
        vec![[0, m, 0], [m, 0, m], [m, m, 1]],
    ];
    let mut spans_seen = 0u64;
    for poly in &facets {
        for thickness in [Thickness::Naive, Thickness::Thesis, Thickness::Standard] {
            for contour in [Contour::Projected, Contour::Conservative] {
                let cfg = LoadConfig { n, thickness, contour };
                let pkt = facet_packet(poly, FacetTag::default(), &cfg).unwrap().expect("non-degenerate");
                let (t0, u0) = (pkt.t as i128, pkt.u as i128);
                let (a, b, c) = (pkt.a as i128, pkt.b as i128, pkt.c as i128);
                let mut p = pkt.clone();
                let rows = [pkt.bbox.y_min, (pkt.bbox.y_min / 2 + pkt.bbox.y_max / 2), pkt.bbox.y_max];
                for y in 0..=pkt.bbox.y_max {
                    // The pipeline cell's incoming value equals the direct i128 evaluation.
                    assert_eq!(p.t as i128, t0 - b * y as i128);
                    for (e, e0) in p.edges.iter().zip(&pkt.edges) {
                        assert_eq!(e.g as i128, e0.g as i128 + e0.b as i128 * y as i128);
                    }
                    let step = PipelineCell { y }.step(&mut p);
                    if !rows.contains(&y) {
                        continue;
                    }
                    let mut r = step.east.expect("row inside the box");
                    let mut cell = Cell::<4>::new(0, y);
                    for x in 0..=pkt.bbox.x_max {
                        let plane = a * x as i128 + b * y as i128;
                        assert_eq!((r.t as i128, r.u as i128), (t0 - plane, u0 - plane));
                        // i128 span of the band alone, then the cell's span must lie inside it.
                        if c != 0 && x >= pkt.bbox.x_min {
                            let (t, u) = (t0 - plane, u0 - plane);
                            let (lo, hi) = if c > 0 {
                                (-floor_div(-u, c), floor_div(t, c))
                            } else {
                                (-floor_div(-t, c), floor_div(u, c))
                            };
                            if let Some(s) = row_span(&r, n) {
                                assert!(lo <= s.lo as i128 && s.hi as i128 <= hi);
                                spans_seen += 1;
                            }
                        }
                        cell.x = x;
                        if !cell.load_step(&mut r, n) {
                            break;
                        }
                    }
                }
            }
        }
    }
    assert!(spans_seen > 1000, "the extreme facets produced voxels ({spans_seen} spans)");
}
