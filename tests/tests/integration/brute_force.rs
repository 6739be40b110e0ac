//! Brute force: on random facets, the dexels the cells compute are exactly the voxels whose
//! centre satisfies the plane and contour inequalities, checked voxel by voxel over the whole
//! grid by an independent i128 oracle (`rc2_tests::oracle::brute`) that shares no code with the
//! product. This also checks the facet's column box (no voxel is ever cut off by it).

use crate::common;

use host_sim::precompute::{planar_pieces, Contour, Thickness, Q};
use proptest::prelude::*;

const N: u32 = 20;

fn check(poly: Vec<[i64; 3]>, thickness: Thickness, contour: Contour) -> Result<(), TestCaseError> {
    // A polygon the precompute refuses (self-overlapping) has nothing to compare: rejected, so
    // that proptest counts it (and gives up if rejections crowd out real cases).
    let pieces = planar_pieces(poly);
    prop_assume!(pieces.is_ok(), "refused by planar_pieces: {:?}", pieces);
    let (pieces, _) = pieces.unwrap();
    for piece in pieces {
        let (got, want) = common::wave_and_oracle_voxels(&piece, N, thickness, contour);
        prop_assert_eq!(got, want, "piece {:?} {:?} {:?}", piece, thickness, contour);
    }
    Ok(())
}

fn lattice_point() -> impl Strategy<Value = [i64; 3]> {
    let m = Q * N as i64;
    [0..=m, 0..=m, 0..=m]
}

fn modes() -> impl Strategy<Value = (Thickness, Contour)> {
    (prop::sample::select(common::THICKNESSES.to_vec()), prop::sample::select(common::CONTOURS.to_vec()))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn random_triangles(a in lattice_point(), b in lattice_point(), c in lattice_point(), (t, ct) in modes()) {
        check(vec![a, b, c], t, ct)?;
    }

    /// Thin and needle triangles: two vertices close together.
    #[test]
    fn slivers(a in lattice_point(), b in lattice_point(), d in [-3i64..=3, -3..=3, -3..=3], (t, ct) in modes()) {
        let c = [0, 1, 2].map(|i| (a[i] + d[i]).clamp(0, Q * N as i64));
        check(vec![a, b, c], t, ct)?;
    }

    /// Nearly axis-aligned facets (one small slope) and exactly axis-aligned ones (C = 0 too).
    #[test]
    fn near_axis_planes(a in lattice_point(), b in lattice_point(), dz in -2i64..=2, axis in 0usize..3, (t, ct) in modes()) {
        let mut c = b;
        c[(axis + 1) % 3] = a[(axis + 1) % 3];
        let mut poly = vec![a, b, c];
        for p in poly.iter_mut() {
            p[axis] = (a[axis] + dz * (p[0] % 3)).clamp(0, Q * N as i64);
        }
        check(poly, t, ct)?;
    }

    /// Planar convex quads (parallelograms), kept whole by the precompute.
    #[test]
    fn parallelograms(a in lattice_point(), u in [-96i64..=96, -96..=96, -96..=96], v in [-96i64..=96, -96..=96, -96..=96], (t, ct) in modes()) {
        let m = Q * N as i64;
        let b = [0, 1, 2].map(|i| a[i] + u[i]);
        let d = [0, 1, 2].map(|i| a[i] + v[i]);
        let c = [0, 1, 2].map(|i| a[i] + u[i] + v[i]);
        prop_assume!([b, c, d].iter().all(|p| p.iter().all(|&x| (0..=m).contains(&x))));
        check(vec![a, b, c, d], t, ct)?;
    }
}
