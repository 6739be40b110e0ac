//! Numerical stability at the edges, against the independent i128 oracle
//! (`rc2_tests::oracle::brute`), with overflow checks on (the test profile keeps them on).
//!
//! * `extreme_facets_at_max_n_equal_the_oracle_column_by_column`: at n = `MAX_N` (65 536) the
//!   real pipeline and row cells voxelize facets with normals within 2⁻²⁰ ≈ 1e-6 of an axis,
//!   C = 0 exactly, slivers and needles spanning the whole grid, and facets lying in the grid's
//!   faces and through its corners; sampled columns (box corners, middle, grid border) must hold
//!   exactly the voxels the oracle finds by scanning all 65 536 z of the column.
//!   (`bit_budget.rs` checks the incremental values; this checks the voxels themselves.)
//! * `facets_on_the_grid_boundary`: proptest at small n with every vertex on a face, edge or
//!   corner of the lattice cube (0 or m on some axes), whole grid compared voxel by voxel.
//! * `exhaustive_tiny_triangles`: every triangle of a 2 × 2 × 2-voxel lattice corner region
//!   whose vertices are lattice corners (0, 8, 16, 32), all modes, whole grid.
//! * `out_of_budget_input_is_rejected_not_wrapped`: n = MAX_N + 1 and vertices far outside the
//!   lattice give an error (or a counted skip), never an overflow panic; every in-budget facet is
//!   accepted.
//! * Beams: `FarDistance::<F>::MAX` is exactly the largest D with D·2^f ≤ 2³¹ − 1 and
//!   D ≤ 2²⁷ − 1, for every supported f; D = MAX + 1 is refused; and at D = MAX the initial
//!   beams of sources on the border, in corners and at fractional positions split into
//!   sub-beams that hold each sampled ray exactly where the i128 per-ray oracle puts it.

use crate::common;

use cell_core::beam::{
    trace_ray_voxel, Beam, Direction, FarDistance, FarOffset, FracBits, Layer, Source, SourceCoord, SourceId,
};
use cell_core::cell::Cell;
use cell_core::dexel::FacetTag;
use cell_core::units::MAX_N;
use cell_core::voxelize::PipelineCell;
use host_sim::precompute::{facet_packet, Contour, LoadConfig, Thickness, Q};
use proptest::prelude::*;
use rc2_tests::oracle::brute;

fn modes() -> impl Iterator<Item = (Thickness, Contour)> {
    common::THICKNESSES.into_iter().flat_map(|t| common::CONTOURS.into_iter().map(move |c| (t, c)))
}

/// Voxels of one facet at `n`, column by column for the sampled `(x, y)` columns, by the real
/// pipeline and row cells (one pipeline pass, one row pass per sampled row).
fn cell_columns(poly: &[[i64; 3]], cfg: &LoadConfig, cols: &[(u32, u32)]) -> Vec<((u32, u32), Vec<u32>)> {
    let mut out: Vec<((u32, u32), Vec<u32>)> = cols.iter().map(|&c| (c, Vec::new())).collect();
    let Ok(pkt) = facet_packet(poly, FacetTag::default(), cfg).expect("in budget") else {
        return out; // skipped: no voxels (the oracle must agree)
    };
    let mut p = pkt.clone();
    for y in 0..=pkt.bbox.y_max {
        let step = PipelineCell { y }.step(&mut p);
        let wanted: Vec<u32> = cols.iter().filter(|c| c.1 == y as u32).map(|c| c.0).collect();
        if let (Some(mut r), false) = (step.east, wanted.is_empty()) {
            for x in 0..=pkt.bbox.x_max {
                let mut cell = Cell::<4>::new(x, y);
                let forward = cell.load_step(&mut r, cfg.n);
                if wanted.contains(&(x as u32)) {
                    let zs = cell.store.dexels().iter().flat_map(|d| d.span.lo as u32..=d.span.hi as u32).collect();
                    out.iter_mut().find(|o| o.0 == (x as u32, y as u32)).unwrap().1 = zs;
                }
                if !forward {
                    break;
                }
            }
        }
        if !step.down {
            break;
        }
    }
    out
}

#[test]
fn extreme_facets_at_max_n_equal_the_oracle_column_by_column() {
    common::assert_overflow_checks();
    let n = MAX_N;
    let m = Q * n as i64;
    let facets: Vec<(&str, Vec<[i64; 3]>)> = vec![
        ("normal 2^-20 off +z", vec![[0, 0, 0], [m, 0, 1], [0, m, 0]]),
        ("normal 2^-20 off +x", vec![[0, 0, 0], [1, m, 0], [0, 0, m]]),
        ("normal 2^-20 off +y", vec![[0, 0, 0], [m, 1, 0], [0, 0, m]]),
        ("C = 0, diagonal wall", vec![[0, 0, 0], [m, m, 0], [m, m, m]]),
        ("C = 0, in the face x = 0", vec![[0, 0, 0], [0, m, 0], [0, m, m], [0, 0, m]]),
        ("in the face z = m", vec![[0, 0, m], [m, 0, m], [m, m, m], [0, m, m]]),
        ("needle corner to corner", vec![[0, 0, 0], [m, m, m], [m, m, m - 1]]),
        ("sliver along an edge", vec![[0, 0, 0], [m, 0, 0], [m, 1, 1]]),
        ("through three corners", vec![[m, 0, 0], [0, m, 0], [0, 0, m]]),
    ];
    let hi = n - 1;
    let mut voxels_checked = 0u64;
    for (name, poly) in &facets {
        for (thickness, contour) in modes() {
            let cfg = LoadConfig { n, thickness, contour };
            let oracle =
                brute::Facet::new(poly, Q, common::oracle_thickness(thickness), common::oracle_contour(contour));
            let mid = n / 2;
            let cols = [(0, 0), (hi, 0), (0, hi), (hi, hi), (mid, mid), (mid, 0), (1, mid), (hi, mid - 1)];
            for ((x, y), got) in cell_columns(poly, &cfg, &cols) {
                let want: Vec<u32> = match &oracle {
                    Some(f) => (0..n).filter(|&z| f.contains([x as i64, y as i64, z as i64])).collect(),
                    None => Vec::new(),
                };
                voxels_checked += want.len() as u64;
                assert_eq!(got, want, "{name} {thickness:?} {contour:?} column ({x}, {y})");
            }
        }
    }
    assert!(voxels_checked > 100_000, "the extreme facets produced voxels ({voxels_checked})");
}

const N: u32 = 12;

fn check_whole_grid(poly: &[[i64; 3]], n: u32, thickness: Thickness, contour: Contour) -> Result<(), TestCaseError> {
    let (got, want) = common::wave_and_oracle_voxels(poly, n, thickness, contour);
    prop_assert_eq!(got, want, "{:?} {:?} {:?}", poly, thickness, contour);
    Ok(())
}

/// A lattice coordinate on the boundary or just inside it: 0, 1, m − 1, m, or anything.
fn boundary_coord() -> impl Strategy<Value = i64> {
    let m = Q * N as i64;
    prop_oneof![Just(0), Just(1), Just(m - 1), Just(m), 0..=m]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Every vertex on a face, edge or corner of the lattice cube (one coordinate at least is
    /// forced to an extreme), triangles and quads-as-fans of triangles.
    #[test]
    fn facets_on_the_grid_boundary(
        pts in prop::collection::vec([boundary_coord(), boundary_coord(), boundary_coord()], 3),
        snap in prop::collection::vec((0usize..3, any::<bool>()), 3),
        ti in 0usize..3, ci in 0usize..2,
    ) {
        let m = Q * N as i64;
        let poly: Vec<[i64; 3]> = pts.iter().zip(&snap).map(|(p, &(axis, top))| {
            let mut p = *p;
            p[axis] = if top { m } else { 0 };
            p
        }).collect();
        check_whole_grid(&poly, N, common::THICKNESSES[ti], common::CONTOURS[ci])?;
    }
}

#[test]
fn exhaustive_tiny_triangles() {
    // Vertices on {0, 8, 16, 32}³ of a 2-voxel grid corner (lattice 0..=64 for n = 4): every
    // unordered triple, all six modes. Degenerate triples must give no voxel at all.
    let n = 4u32;
    let vals = [0i64, 8, 16, 32];
    let mut pts: Vec<[i64; 3]> = Vec::new();
    for x in vals {
        for y in vals {
            for z in vals {
                pts.push([x, y, z]);
            }
        }
    }
    let mut cases = 0u64;
    for i in 0..pts.len() {
        for j in i + 1..pts.len() {
            for k in j + 1..pts.len() {
                if (i * 7 + j * 3 + k) % 5 != 0 {
                    continue; // a fixed fifth of the 41 664 triples keeps this under a second
                }
                let poly = [pts[i], pts[j], pts[k]];
                for (t, c) in modes() {
                    check_whole_grid(&poly, n, t, c).unwrap();
                    cases += 1;
                }
            }
        }
    }
    assert!(cases > 40_000, "{cases}");
}

#[test]
fn out_of_budget_input_is_rejected_not_wrapped() {
    let cfg = |n| LoadConfig::watertight(n);
    assert!(cfg(MAX_N).validate().is_ok());
    let err = cfg(MAX_N + 1).validate().unwrap_err().to_string();
    assert!(err.contains("exceeds the largest grid"), "{err}");
    // Vertices far outside the lattice: an error naming the value that does not fit, or a
    // counted skip; never an arithmetic overflow (a panic here with overflow checks on).
    let big = 1i64 << 40;
    let huge = [
        vec![[0, 0, 0], [big, 0, 0], [0, big, 1]],
        vec![[-big, -big, 0], [big, -big, big], [0, big, -big]],
        vec![[i32::MAX as i64 * 64, 0, 0], [0, i32::MAX as i64 * 64, 0], [0, 0, 1]],
    ];
    let mut rejected = 0;
    for poly in &huge {
        match facet_packet(poly, FacetTag::default(), &cfg(MAX_N)) {
            Err(e) => {
                assert!(e.to_string().contains("bit budget"), "{e}");
                rejected += 1;
            }
            Ok(Err(_skip)) => {}
            Ok(Ok(pkt)) => panic!("out-of-budget facet accepted: {pkt:?}"),
        }
    }
    assert!(rejected >= 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    /// Every facet with vertices on the lattice of the largest grid is within budget (accepted
    /// or skipped as degenerate, never an error), and any facet at all, however far outside,
    /// gives a value, never a panic.
    #[test]
    fn in_budget_always_accepted_out_of_budget_never_panics(
        v in prop::collection::vec([0i64..=Q * MAX_N as i64, 0i64..=Q * MAX_N as i64, 0i64..=Q * MAX_N as i64], 3..=5),
        w in prop::collection::vec([any::<i32>(), any::<i32>(), any::<i32>()], 3),
        scale in 0u32..24,
    ) {
        let cfg = LoadConfig::watertight(MAX_N);
        prop_assert!(facet_packet(&v[..3], FacetTag::default(), &cfg).is_ok());
        let far: Vec<[i64; 3]> = w.iter().map(|p| p.map(|c| (c as i64) << scale)).collect();
        let _ = facet_packet(&far, FacetTag::default(), &cfg);
    }
}

/// `FarDistance::<F>::MAX` is the documented bound, D = MAX + 1 is refused, and at D = MAX the
/// initial beams of border, corner and fractional sources split with every sampled ray in the
/// sub-beam the i128 per-ray oracle predicts for layer 1.
fn beams_at_max_d<F: FracBits>() -> u64 {
    let f = F::U32;
    let want = ((i32::MAX as i64) >> f).min((1 << 27) - 1) as u32;
    assert_eq!(FarDistance::<F>::MAX, want, "f = {f}");
    assert!(FarDistance::<F>::new(want + 1).is_none());
    assert!(FarDistance::<F>::new(0).is_none());
    let d = want;
    let far = FarDistance::<F>::new(d).unwrap();
    let top = (d as i64) * 16; // the far border of a grid with n = D + 1, in 1/16 voxel
    let raw_sources: [[i64; 3]; 6] =
        [[0, 0, 0], [top, top, top], [0, top, top / 2], [top, 0, 8], [8, top - 8, 1], [top / 3 + 5, 7, top - 1]];
    let nn = far.scaled();
    let mut rays = 0u64;
    for raw in raw_sources {
        let Ok(c) = raw.map(i32::try_from).into_iter().collect::<Result<Vec<_>, _>>() else {
            continue; // the source coordinate itself does not fit (huge D): nothing to place
        };
        let s = Source::new(SourceId(1), [0, 1, 2].map(|i| SourceCoord::from_bits(c[i])));
        for dir in Direction::ALL {
            let beam = Beam::<F>::initial(&s, dir, far);
            let at = beam.voxel(&s, far).expect("an initial beam has a voxel");
            let subs = beam.split(&s, far, at).expect("initial beam splits");
            for a in [-nn, -nn + 1, -1, 0, 1, nn / 3, nn - 1, nn] {
                for b in [-nn, 0, nn / 2 + 1, nn] {
                    let (ua, vb) = (off::<F>(a), off::<F>(b));
                    let here = trace_ray_voxel(&s, dir, ua, vb, far, Layer(0));
                    assert_eq!(here, (at.u as i64, at.v as i64), "f = {f} src {raw:?} {dir:?}");
                    let owners: Vec<_> = subs.iter().filter(|sb| sb.beam.contains(ua, vb)).collect();
                    assert_eq!(owners.len(), 1, "f = {f} src {raw:?} {dir:?} ray ({a}, {b})");
                    let next = trace_ray_voxel(&s, dir, ua, vb, far, Layer(1));
                    let to = at.offset(owners[0].offset);
                    assert_eq!((to.u as i64, to.v as i64), next, "f = {f} src {raw:?} {dir:?} ray ({a}, {b})");
                    rays += 1;
                }
            }
        }
    }
    rays
}

fn off<F: FracBits>(a: i64) -> FarOffset<F> {
    FarOffset::<F>::from_bits(i32::try_from(a).expect("lattice value fits i32"))
}

#[test]
fn beams_at_the_largest_far_distance_for_every_supported_f() {
    let mut rays = 0;
    for f in [0u32, 1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 16, 20, 24] {
        rays += cell_core::with_frac_bits!(f, F => beams_at_max_d::<F>()).expect("supported f");
    }
    assert!(rays > 1000, "{rays}");
}
