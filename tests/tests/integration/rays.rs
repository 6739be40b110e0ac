//! Incremental 3D lines (`cell_core::ray`, thesis §2.3) against the f64 reference walks
//! (`rc2_tests::oracle::lines`), at the edges of their bit budget, and the thesis's topology
//! table (§2.1, Fig. 2.11): can a ray of connectivity 6/18/26 pass through a voxelized surface
//! of each thickness ("passe-muraille")? Run `tunnel_table_for_rays` with `--nocapture` to
//! print the table the README quotes.

use cell_core::ray::{Connectivity, Line, MAX_COORD, MAX_SPAN, Q};
use host_sim::precompute::{polygon_normal, Thickness};
use proptest::prelude::*;
use rc2_tests::oracle::lines::{is_k_connected, voxel, walk18, walk26, walk6};
use rc2_tests::oracle::tunnels::{count_tunnels, plane_side};
use rc2_tests::planes::{random_plane, voxelized, HI, LO};

/// The cell's walk, as i64 voxels.
fn cell_walk(a: [i64; 3], b: [i64; 3], c: Connectivity) -> Vec<[i64; 3]> {
    let mut l = Line::new(a.map(|v| v as i32), b.map(|v| v as i32), c).expect("within budget");
    let expected_len = l.remaining() as usize + 1;
    let mut out = vec![l.voxel().map(i64::from)];
    while let Some(v) = l.step() {
        out.push(v.map(i64::from));
    }
    assert_eq!(out.len(), expected_len, "remaining() counts the steps");
    assert_eq!(l.step(), None, "a finished line stays finished");
    out
}

fn reference(a: [i64; 3], b: [i64; 3], c: Connectivity) -> Vec<[i64; 3]> {
    let q = Q as i64;
    match c {
        Connectivity::Six => walk6(a, b, q),
        Connectivity::Eighteen => walk18(a, b, q),
        Connectivity::TwentySix => walk26(a, b, q),
    }
}

fn check(a: [i64; 3], b: [i64; 3]) {
    for c in Connectivity::ALL {
        let got = cell_walk(a, b, c);
        let want = reference(a, b, c);
        assert_eq!(got, want, "{c:?} from {a:?} to {b:?}");
        assert!(is_k_connected(&got, c.k()), "{c:?} path not {}-connected", c.k());
    }
    // The 6-connected walk ends in B's voxel.
    let six = cell_walk(a, b, Connectivity::Six);
    assert_eq!(*six.last().unwrap(), b.map(|v| voxel(v, Q as i64)));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    /// Short lines between arbitrary lattice points (many ties and boundary cases).
    #[test]
    fn short_lines_match_the_reference(a in prop::array::uniform3(-80i64..80), b in prop::array::uniform3(-80i64..80)) {
        check(a, b);
    }

    /// Long lines from points on a voxel's faces (where a reflected ray leaves under
    /// `--hit edge`: the entered face, or the lattice point just inside the high face).
    #[test]
    fn lines_from_voxel_faces_match_the_reference(
        v in prop::array::uniform3(0i64..64),
        inside in prop::array::uniform3(-8i64..8),
        face in 0usize..3,
        high in prop::bool::ANY,
        d in prop::array::uniform3(-2000i64..2000),
    ) {
        let q = Q as i64;
        let mut a = [0, 1, 2].map(|k| v[k] * q + inside[k]);
        a[face] = v[face] * q + if high { q / 2 - 1 } else { -q / 2 };
        check(a, [0, 1, 2].map(|k| a[k] + d[k]));
    }

    /// Lines between voxel centres (the shadow-ray case) over a 512 grid.
    #[test]
    fn centre_lines_match_the_reference(a in prop::array::uniform3(0i64..512), b in prop::array::uniform3(0i64..512)) {
        check(a.map(|v| v * Q as i64), b.map(|v| v * Q as i64));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// The largest spans and coordinates the budget admits (overflow checks are on in tests).
    #[test]
    fn lines_at_the_bit_budget(
        s in prop::array::uniform3(prop::bool::ANY),
        f in prop::array::uniform3(0i64..=(MAX_SPAN as i64)),
        big in 0usize..3,
    ) {
        let m = MAX_COORD as i64;
        let mut a = [0i64; 3];
        let mut b = [0i64; 3];
        for i in 0..3 {
            let span = if i == big { MAX_SPAN as i64 } else { f[i] };
            let sign = if s[i] { 1 } else { -1 };
            a[i] = sign * (m - span);
            b[i] = sign * m;
            if i == 1 { std::mem::swap(&mut a[i], &mut b[i]); }
        }
        check(a, b);
    }
}

#[test]
fn out_of_budget_lines_are_rejected() {
    let m = MAX_COORD;
    assert!(Line::new([0, 0, 0], [MAX_SPAN, 0, 0], Connectivity::Six).is_ok());
    assert!(Line::new([0, 0, 0], [MAX_SPAN + 1, 0, 0], Connectivity::Six).is_err());
    assert!(Line::new([-m, 0, 0], [-m, 0, 0], Connectivity::TwentySix).is_ok());
    assert!(Line::new([-m - 1, 0, 0], [-m, 0, 0], Connectivity::TwentySix).is_err());
}

/// Rays between random free voxel centres strictly on opposite sides of the plane; a ray
/// "passes" if none of its voxels is occupied. Returns (rays, passing) per connectivity.
fn rays_through(tri: &[[i64; 3]; 3], th: Thickness, seed: u64, rays: usize) -> ([usize; 3], [usize; 3]) {
    let grid = voxelized(tri, th);
    let occ = |p: [i64; 3]| grid.cell(p[0] as u32, p[1] as u32).store.occupied(p[2] as u16).is_some();
    let nrm = polygon_normal(tri).map(|v| i64::try_from(v).unwrap());
    let side = plane_side(nrm, tri[0], Q as i64);
    let mut state = seed;
    let mut next = move |lo: i64, hi: i64| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        lo + (state % (hi - lo + 1) as u64) as i64
    };
    let mut shot = [0; 3];
    let mut passed = [0; 3];
    let mut k = 0;
    while k < rays {
        let a = [0; 3].map(|_| next(LO[0], HI[0]));
        let b = [0; 3].map(|_| next(LO[0], HI[0]));
        if occ(a) || occ(b) || side(a).signum() * side(b).signum() >= 0 {
            continue;
        }
        k += 1;
        for (ci, c) in Connectivity::ALL.into_iter().enumerate() {
            let path = cell_walk(a.map(|v| v * Q as i64), b.map(|v| v * Q as i64), c);
            shot[ci] += 1;
            if path.iter().all(|&p| !occ(p)) {
                passed[ci] += 1;
                // A ray through the surface crosses it in one step between free voxels: a
                // tunnel of its connectivity, which the independent counter must also see.
                let t = count_tunnels(&occ, &side, LO, HI, c.k());
                assert!(t > 0, "{c:?} ray {a:?} → {b:?} passed a surface with no {}-tunnel", c.k());
            }
        }
    }
    (shot, passed)
}

#[test]
fn tunnel_table_for_rays() {
    let planes: Vec<_> = (0..40).map(random_plane).collect();
    println!("| surface thickness (tunnel-free for) | 6-connected rays through | 18-connected rays through | 26-connected rays through |");
    println!("|---|---|---|---|");
    let mut table = Vec::new();
    for th in [Thickness::Naive, Thickness::Thesis, Thickness::Standard] {
        let mut shot = [0; 3];
        let mut passed = [0; 3];
        for (i, tri) in planes.iter().enumerate() {
            let (s, p) = rays_through(tri, th, 0x5eed + i as u64, 200);
            for k in 0..3 {
                shot[k] += s[k];
                passed[k] += p[k];
            }
        }
        let cell =
            |k: usize| format!("{} / {} ({:.2} %)", passed[k], shot[k], 100.0 * passed[k] as f64 / shot[k] as f64);
        println!("| {th:?} | {} | {} | {} |", cell(0), cell(1), cell(2));
        table.push((th, passed));
    }
    let get = |t: Thickness| table.iter().find(|r| r.0 == t).unwrap().1;
    assert_eq!(get(Thickness::Standard), [0, 0, 0], "standard surfaces stop every ray");
    assert_eq!(get(Thickness::Naive)[0], 0, "naive surfaces stop 6-connected rays");
    assert!(get(Thickness::Naive)[2] > 0, "26-connected rays pass through naive surfaces");
    assert!(get(Thickness::Naive)[1] > 0, "18-connected rays pass through naive surfaces");
}
