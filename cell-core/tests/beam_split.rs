//! §4.3 beam split against independent oracles.
//!
//! * The per-ray oracle `trace_ray_voxel` (i128, direct rounding) is itself checked against a
//!   brute-force "nearest voxel centre, ties up" search written here from the definition of thesis §4.3.
//! * Exhaustive: D ∈ 1..=8, f ∈ {0, 1, 2, 3}, integer and fractional sources, all six
//!   directions, every beam reachable from the initial beams, every ray of every beam.
//! * proptest: D up to `FarDistance::<F>::MAX` for f up to 30, random consistent beams whose
//!   limits sit on or next to the split planes, sampled rays; and arbitrary (inconsistent,
//!   extreme) inputs, which must never panic and still partition.
//! * The thesis's 2D Y_med (§4.3.1.2) and general-source Y2 (§4.3.3) equal U2.

use std::collections::HashSet;

use cell_core::beam::frac::{U0, U1, U12, U16, U2, U20, U24, U3, U30, U4, U8};
use cell_core::beam::{
    split_planes, trace_ray_voxel, Beam, BeamError, Direction, FarDistance, FarOffset, FracBits, Layer, Offset, Origin,
    Ratio, RayRange, Source, SourceCoord, SourceId, SplitOrder, SubBeam, Transverse, SOURCE_FRAC_BITS,
};
use proptest::prelude::*;

const SID: SourceId = SourceId(7);

fn off<F: FracBits>(a: i64) -> FarOffset<F> {
    FarOffset::<F>::from_bits(i32::try_from(a).expect("lattice value fits i32"))
}

/// A source from raw 1/16-voxel coordinates.
fn src(raw: [i32; 3]) -> Source {
    Source::new(SID, raw.map(SourceCoord::from_bits))
}

/// Integer and fractional sources (raw units of 1/16 voxel), with the thesis's rays and with
/// rays from the light.
fn sources() -> Vec<Source> {
    let thesis = [
        src([0, 0, 0]),
        src([48, -32, 80]), // (3, −2, 5)
        src([8, 8, 8]),     // (½, ½, ½): every first plane is a tie
        src([4, -12, 24]),  // (¼, −¾, 1½)
        src([-17, 47, 8]),  // (−1.0625, 2.9375, ½)
        src([1, -1, -7]),   // (1/16, −1/16, −7/16)
    ];
    let light = thesis.map(|s| s.with_origin(Origin::Light));
    thesis.into_iter().chain(light).collect()
}

/// 16 × the distance along `dir` from the rays' origin to the centre plane of layer k, from
/// the definitions: the thesis's rays leave from the source voxel's centre plane (16·k); rays
/// from the light meet, at layer k ≥ 1, the k-th voxel centre plane strictly ahead of the light
/// (found by listing the planes near it), and are at the light at layer 0.
fn spec_reach(s: &Source, dir: Direction, k: i64) -> i64 {
    if s.origin == Origin::SourceVoxel || k == 0 {
        return 16 * k;
    }
    let p = s.pos[dir.principal().index()].to_bits() as i64;
    let sign = dir.sign() as i64;
    let mut ahead: Vec<i64> = (-300..=300).map(|c: i64| sign * (16 * c - p)).filter(|&t| t > 0).collect();
    ahead.sort();
    ahead[k as usize - 1]
}

/// Brute-force rounding (thesis §4.3): the x whose centre is nearest to x_s + u·t/(16·D) (t:
/// [`spec_reach`]; 16·k for the thesis's rays), ties up, i.e. the unique x with
/// −½ ≤ value − x < ½, found by search.
fn spec_voxel(b: i64, a: i64, f: u32, d: i64, t: i64) -> i64 {
    // value = b/16 + a·t/(16·2^f·D) = num/den
    let den = 16 * (1i64 << f) * d;
    let num = b * (1i64 << f) * d + a * t;
    let mut found = None;
    for x in -200..=200 {
        let diff2 = 2 * (num - x * den); // 2·den·(value − x)
        if -den <= diff2 && diff2 < den {
            assert!(found.is_none(), "two nearest centres");
            found = Some(x);
        }
    }
    found.expect("search window")
}

#[test]
fn trace_oracle_matches_brute_force_rounding() {
    fn run<F: FracBits>() {
        let f = F::U32;
        for d in 1..=6u32 {
            let far = FarDistance::<F>::new(d).unwrap();
            let n = far.scaled();
            for s in sources() {
                for dir in Direction::ALL {
                    let (ua, va) = dir.transverse();
                    for k in 0..=d {
                        let t = spec_reach(&s, dir, k as i64);
                        assert_eq!(s.reach(dir, Layer(k)), t, "{s:?} {dir:?} layer {k}");
                        for a in -n..=n {
                            let b = (a * 3) % (n + 1); // some v too
                            let got = trace_ray_voxel(&s, dir, off::<F>(a), off::<F>(b), far, Layer(k));
                            let bu = s.pos[ua.index()].to_bits() as i64;
                            let bv = s.pos[va.index()].to_bits() as i64;
                            assert_eq!(got.0, spec_voxel(bu, a, f, d as i64, t));
                            assert_eq!(got.1, spec_voxel(bv, b, f, d as i64, t));
                        }
                    }
                }
            }
        }
    }
    run::<U0>();
    run::<U1>();
    run::<U2>();
    run::<U3>();
}

/// Check one split of a consistent beam exhaustively, ray by ray; return the children with
/// their voxels.
fn check_split_every_ray<F: FracBits>(
    s: &Source,
    far: FarDistance<F>,
    beam: &Beam<F>,
    at: Transverse,
) -> Vec<(Beam<F>, Transverse)> {
    let k = beam.layer();
    let subs = beam.split(s, far, at).unwrap();
    check_structure(beam, &subs);
    let (u, v) = (beam.u(), beam.v());
    for a in u.lo().to_bits()..=u.hi().to_bits() {
        for b in v.lo().to_bits()..=v.hi().to_bits() {
            let (ru, rv) = (FarOffset::<F>::from_bits(a), FarOffset::<F>::from_bits(b));
            let here = trace_ray_voxel(s, beam.direction(), ru, rv, far, k);
            assert_eq!(here, (at.u as i64, at.v as i64), "beam not consistent");
            let owners: Vec<&SubBeam<F>> = subs.iter().filter(|sb| sb.beam.contains(ru, rv)).collect();
            assert_eq!(owners.len(), 1, "ray ({a}, {b}) in {} sub-beams", owners.len());
            let next = trace_ray_voxel(s, beam.direction(), ru, rv, far, Layer(k.0 + 1));
            let to = at.offset(owners[0].offset);
            assert_eq!(next, (to.u as i64, to.v as i64), "ray ({a}, {b}) misrouted");
        }
    }
    subs.iter().map(|sb| (sb.beam, at.offset(sb.offset))).collect()
}

/// Structural partition checks that need no ray enumeration: children inside the parent,
/// pairwise disjoint, non-empty, distinct offsets, counts conserved, fields carried.
fn check_structure<F: FracBits>(beam: &Beam<F>, subs: &[SubBeam<F>]) {
    assert!(!subs.is_empty() && subs.len() <= 9);
    let mut total = 0u128;
    let mut offsets = HashSet::new();
    for sb in subs {
        let c = &sb.beam;
        assert!(offsets.insert(sb.offset), "duplicate offset");
        assert!((-1..=1).contains(&sb.offset.du) && (-1..=1).contains(&sb.offset.dv));
        assert_eq!(c.layer(), Layer(beam.layer().0 + 1));
        assert_eq!(c.source(), beam.source());
        assert_eq!(c.direction(), beam.direction());
        assert!(c.ray_count() >= 1);
        assert!(c.u().lo() <= c.u().hi() && c.v().lo() <= c.v().hi());
        assert!(beam.u().lo() <= c.u().lo() && c.u().hi() <= beam.u().hi());
        assert!(beam.v().lo() <= c.v().lo() && c.v().hi() <= beam.v().hi());
        total += c.ray_count() as u128;
    }
    for (i, p) in subs.iter().enumerate() {
        for q in &subs[i + 1..] {
            let u_overlap = p.beam.u().lo() <= q.beam.u().hi() && q.beam.u().lo() <= p.beam.u().hi();
            let v_overlap = p.beam.v().lo() <= q.beam.v().hi() && q.beam.v().lo() <= p.beam.v().hi();
            assert!(!(u_overlap && v_overlap), "sub-beams overlap");
            // Order along each axis follows the offsets (monotone rounding).
            if p.offset.du < q.offset.du {
                assert!(p.beam.u().hi() < q.beam.u().lo());
            }
            if p.offset.dv < q.offset.dv {
                assert!(p.beam.v().hi() < q.beam.v().lo());
            }
        }
    }
    assert_eq!(total, beam.ray_count() as u128, "rays not conserved");
}

fn exhaustive<F: FracBits>() {
    let mut splits = 0u64;
    for d in 1..=8u32 {
        let far = FarDistance::<F>::new(d).unwrap();
        for s in sources() {
            for (dir, initial) in Direction::ALL.into_iter().zip(Beam::initial_six(&s, far)) {
                assert_eq!(initial.direction(), dir);
                assert_eq!(initial.ray_count(), far.rays_per_face());
                let mut layer = vec![(initial, dir.transverse_of(s.voxel()))];
                for k in 0..=d {
                    let total: u64 = layer.iter().map(|(b, _)| b.ray_count()).sum();
                    assert_eq!(total, far.rays_per_face(), "layer {k} does not cover the face");
                    // The layer's slab: the source voxel's at layer 0, else the one whose centre
                    // plane lies `spec_reach` ahead of the rays' origin; layer 1 is the source
                    // voxel's slab or the next one.
                    let w = dir.principal().index();
                    let o = match s.origin {
                        Origin::SourceVoxel => 16 * s.voxel()[w] as i64,
                        Origin::Light => s.pos[w].to_bits() as i64,
                    };
                    let slab = match k {
                        0 => s.voxel()[w] as i64,
                        _ => (o + dir.sign() as i64 * spec_reach(&s, dir, k as i64)).div_euclid(16),
                    };
                    assert_eq!(s.slab(dir, Layer(k)), slab, "{s:?} {dir:?} layer {k}");
                    let first = dir.sign() as i64 * (s.slab(dir, Layer(1)) - s.voxel()[w] as i64);
                    assert!(first == 0 || first == 1, "{s:?} {dir:?}: layer 1 {first} slabs ahead");
                    for (b, at) in &layer {
                        assert_eq!(b.layer(), Layer(k));
                        assert_eq!(dir.voxel(&s, Layer(k), *at)[w], slab);
                        assert!(b.occupies(&s, far, *at));
                        assert_eq!(b.voxel(&s, far), Some(*at));
                    }
                    if k == d {
                        let (b, at) = layer[0];
                        assert_eq!(b.split(&s, far, at), Err(BeamError::AtFarPlane));
                        break;
                    }
                    let mut next = Vec::new();
                    for (b, at) in &layer {
                        next.extend(check_split_every_ray(&s, far, b, *at));
                        splits += 1;
                    }
                    layer = next;
                }
            }
        }
    }
    assert!(splits > 1000);
}

#[test]
fn exhaustive_f0() {
    exhaustive::<U0>();
}

#[test]
fn exhaustive_f1() {
    exhaustive::<U1>();
}

#[test]
fn exhaustive_f2() {
    exhaustive::<U2>();
}

#[test]
fn exhaustive_f3() {
    exhaustive::<U3>();
}

#[test]
fn initial_beams_overlap_exactly_on_the_cube_edges() {
    fn run<F: FracBits>(d: u32) {
        let far = FarDistance::<F>::new(d).unwrap();
        let n = far.scaled();
        // The thesis's rays: from the light, two faces sample an edge ray on different planes
        // (each face's layers are its own axis's centre planes, ahead of the light by different
        // leads), so their voxels differ.
        for s in sources().into_iter().filter(|s| s.origin == Origin::SourceVoxel) {
            let mut dirs: HashSet<[i64; 3]> = HashSet::new();
            let mut emitted = 0u128;
            // 3D voxels of each distinct direction's ray, per layer: both faces must agree.
            let mut path: std::collections::HashMap<[i64; 3], Vec<[i64; 3]>> = Default::default();
            for dir in Direction::ALL {
                let (ua, va) = dir.transverse();
                for a in -n..=n {
                    for b in -n..=n {
                        let mut vec3 = [0i64; 3];
                        vec3[dir.principal().index()] = dir.sign() as i64 * n;
                        vec3[ua.index()] = a;
                        vec3[va.index()] = b;
                        dirs.insert(vec3);
                        emitted += 1;
                        let voxels: Vec<[i64; 3]> = (0..=d)
                            .map(|k| {
                                let t = trace_ray_voxel(&s, dir, off::<F>(a), off::<F>(b), far, Layer(k));
                                let at = Transverse { u: t.0 as i32, v: t.1 as i32 };
                                dir.voxel(&s, Layer(k), at)
                            })
                            .collect();
                        if let Some(prev) = path.get(&vec3) {
                            assert_eq!(prev, &voxels, "boundary ray traced differently");
                        } else {
                            path.insert(vec3, voxels);
                        }
                    }
                }
            }
            assert_eq!(dirs.len() as u128, far.distinct_directions());
            assert_eq!(emitted, 6 * far.rays_per_face() as u128);
        }
    }
    for d in 1..=5 {
        run::<U0>(d);
        run::<U1>(d);
        run::<U2>(d);
    }
}

#[test]
fn thesis_2d_y_med_is_u2() {
    // §4.3.1.2: source at the origin, first octant, propagation +x, transverse y (our u-axis
    // for ±x). Y_med = (y + ½)(n − 1)/(x + 1) at cell (x, y), i.e. layer k = x, D = n − 1.
    let s = Source::at_voxel(SID, [0, 0, 0]).unwrap();
    for n in 2..=64u32 {
        let far = FarDistance::<U0>::new(n - 1).unwrap();
        for x in 0..n - 1 {
            for y in 0..=x as i32 {
                let at = Transverse { u: y, v: 0 };
                let p = split_planes(&s, Direction::PosX, far, Layer(x), at).unwrap();
                let y_med = Ratio::new((2 * y as i64 + 1) * (n as i64 - 1), 2 * (x as i64 + 1)).unwrap();
                assert_eq!(p.u2, y_med, "n={n} x={x} y={y}");
                let y1 = Ratio::new((2 * y as i64 - 1) * (n as i64 - 1), 2 * (x as i64 + 1)).unwrap();
                assert_eq!(p.u1, y1);
                assert!(p.u1 < p.u2);
            }
        }
    }
    // §4.3.3: source (X_s, Y_s) anywhere, D = n − 1 − X_s, layer k = x − X_s:
    // Y2 = (y − Y_s + ½)(n − 1 − X_s)/(x − X_s + 1).
    let n = 20i64;
    for (xs, ys) in [(3i64, 5i64), (0, 19), (10, 0), (7, 7)] {
        let s = Source::at_voxel(SID, [xs as i32, ys as i32, 0]).unwrap();
        let far = FarDistance::<U0>::new((n - 1 - xs) as u32).unwrap();
        for x in xs..n - 1 {
            for y in 0..n {
                let at = Transverse { u: y as i32, v: 0 };
                let p = split_planes(&s, Direction::PosX, far, Layer((x - xs) as u32), at).unwrap();
                let y2 = Ratio::new((2 * (y - ys) + 1) * (n - 1 - xs), 2 * (x - xs + 1)).unwrap();
                assert_eq!(p.u2, y2);
            }
        }
    }
}

#[test]
fn thesis_truncated_y_med_would_misroute_exact_threshold_does_not() {
    // n = 8, source at the origin, cell (0, 0): Y_med = ½·7/1 = 3.5, [Y_med] = 3.
    let s = Source::at_voxel(SID, [0, 0, 0]).unwrap();
    let far = FarDistance::<U0>::new(7).unwrap();
    let beam = Beam::initial(&s, Direction::PosX, far);
    let subs = beam.split(&s, far, Transverse { u: 0, v: 0 }).unwrap();
    let owner = |u: i32| subs.iter().find(|sb| sb.beam.contains(off(u as i64), off(0))).unwrap();
    // Ray 3 at layer 1 is at 3/7 < ½: it stays. The truncated threshold would send it up.
    assert_eq!(trace_ray_voxel(&s, Direction::PosX, off::<U0>(3), off(0), far, Layer(1)).0, 0);
    assert_eq!(owner(3).offset.du, 0);
    assert_eq!(owner(4).offset.du, 1);
    let p = split_planes(&s, Direction::PosX, far, Layer(0), Transverse::default()).unwrap();
    assert_eq!(p.u2.lattice_ceil::<U0>(), 4);
}

#[test]
fn rays_exactly_on_a_plane() {
    // D = 4, source at the origin, layer 0 → 1: U2 = ½·4/1 = 2 and U1 = −2 are lattice rays.
    // u = U2 goes up (x_s + 2/4 = ½ rounds up), u = U1 stays (−½ rounds up to 0).
    let s = Source::at_voxel(SID, [0, 0, 0]).unwrap();
    let far = FarDistance::<U0>::new(4).unwrap();
    let beam = Beam::initial(&s, Direction::PosZ, far);
    let subs = beam.split(&s, far, Transverse::default()).unwrap();
    let find = |u: i64, v: i64| subs.iter().find(|sb| sb.beam.contains(off(u), off(v))).unwrap().offset;
    assert_eq!(find(2, 0), Offset { du: 1, dv: 0 });
    assert_eq!(find(1, 0), Offset { du: 0, dv: 0 });
    assert_eq!(find(-2, 0), Offset { du: 0, dv: 0 });
    assert_eq!(find(-3, -3), Offset { du: -1, dv: -1 });
    assert_eq!(find(2, -2), Offset { du: 1, dv: 0 });
    assert_eq!(find(-3, 2), Offset { du: -1, dv: 1 });
    assert_eq!(subs.len(), 9);
}

#[test]
fn orders_errors_and_names() {
    let s = Source::at_voxel(SID, [2, 3, 4]).unwrap();
    let far = FarDistance::<U2>::new(6).unwrap();
    let beam = Beam::initial(&s, Direction::NegY, far);
    let at = Direction::NegY.transverse_of(s.voxel());
    assert_eq!(at, Transverse { u: 2, v: 4 });
    let a = beam.split(&s, far, at).unwrap();
    let b = beam.split_with(&s, far, at, &SplitOrder::AXIS_NEIGHBOURS_FIRST).unwrap();
    let order_a: Vec<Offset> = a.iter().map(|x| x.offset).collect();
    let order_b: Vec<Offset> = b.iter().map(|x| x.offset).collect();
    assert_eq!(order_a, SplitOrder::ROW_MAJOR.offsets().to_vec());
    assert_eq!(order_b, SplitOrder::AXIS_NEIGHBOURS_FIRST.offsets().to_vec());
    for sb in &b {
        assert!(a.contains(sb));
    }
    // SplitOrder validation.
    let mut o = *SplitOrder::ROW_MAJOR.offsets();
    assert!(SplitOrder::new(o).is_some());
    o[0] = o[1];
    assert!(SplitOrder::new(o).is_none());
    o[0] = Offset { du: 2, dv: 0 };
    assert!(SplitOrder::new(o).is_none());
    assert!(Offset::new(-1, 1).is_some() && Offset::new(0, -2).is_none());
    // Errors.
    let other = Source::new(SourceId(8), s.pos);
    assert_eq!(beam.split(&other, far, at), Err(BeamError::WrongSource));
    let small = FarDistance::<U2>::new(3).unwrap();
    assert_eq!(beam.split(&s, small, at), Err(BeamError::OutsideFarSquare));
    let r = RayRange::new(off::<U2>(-4), off(4)).unwrap();
    assert!(RayRange::new(off::<U2>(4), off(3)).is_none());
    assert_eq!(Beam::new(SID, Direction::PosX, Layer(7), r, r, far), Err(BeamError::LayerBeyondFar));
    let wide = RayRange::new(off::<U2>(-25), off(0)).unwrap();
    assert_eq!(Beam::new(SID, Direction::PosX, Layer(1), wide, r, far), Err(BeamError::OutsideFarSquare));
    let b6 = Beam::new(SID, Direction::PosX, Layer(6), r, r, far).unwrap();
    assert_eq!(b6.split(&s, far, Transverse::default()), Err(BeamError::AtFarPlane));
    // Names.
    for (i, d) in Direction::ALL.into_iter().enumerate() {
        assert_eq!(d.index() as usize, i);
        assert_eq!(Direction::from_index(i as u8), Some(d));
        let (u, v) = d.transverse();
        assert!(u < v && u != d.principal() && v != d.principal());
        let step = d.displacement(Offset { du: 1, dv: -1 });
        assert_eq!(step[d.principal().index()], d.sign());
        assert_eq!((step[u.index()], step[v.index()]), (1, -1));
    }
    assert_eq!(Direction::from_index(6), None);
    assert_eq!(Direction::PosZ.voxel(&s, Layer(3), Transverse { u: 9, v: 8 }), [9, 8, 7]);
    assert_eq!(Direction::NegX.voxel(&s, Layer(3), Transverse { u: 9, v: 8 }), [-1, 9, 8]);
    // Source voxel rounding: half up.
    assert_eq!(src([8, -8, 7]).voxel(), [1, 0, 0]);
    assert_eq!(src([-9, 24, -24]).voxel(), [-1, 2, -1]);
    assert!(Source::at_voxel(SID, [1 << 27, 0, 0]).is_none());
    assert_eq!(SOURCE_FRAC_BITS, 4);
}

#[test]
fn sizes() {
    use core::mem::size_of;
    assert_eq!(size_of::<Beam<U0>>(), 24);
    assert_eq!(size_of::<Beam<U8>>(), 24);
    assert_eq!(size_of::<Beam<U16>>(), 24);
    println!(
        "Beam<U8>: {} B, SubBeam<U8>: {} B, SubBeams<U8>: {} B",
        size_of::<Beam<U8>>(),
        size_of::<SubBeam<U8>>(),
        size_of::<cell_core::beam::SubBeams<U8>>()
    );
}

#[test]
fn host_sweep_dispatch() {
    fn rays_f<F: FracBits>(d: u32) -> u64 {
        let far = FarDistance::<F>::new(d).unwrap();
        let s = Source::at_voxel(SID, [0, 0, 0]).unwrap();
        let b = Beam::initial(&s, Direction::PosZ, far);
        let subs = b.split(&s, far, Transverse::default()).unwrap();
        check_structure(&b, &subs);
        subs.iter().map(|x| x.beam.ray_count()).sum()
    }
    for f in [0u32, 2, 4, 8, 12, 16, 20, 24] {
        let got = cell_core::with_frac_bits!(f, F => rays_f::<F>(5)).unwrap();
        let side = 2 * 5 * (1u64 << f) + 1;
        assert_eq!(got, side * side);
    }
    assert!(cell_core::with_frac_bits!(30u32, F => rays_f::<F>(1)).is_none());
}

// ---------------------------------------------------------------------------------------------
// proptest
// ---------------------------------------------------------------------------------------------

/// Lattice interval [ceil(lo), ceil(hi) − 1] of rays with lo ≤ u < hi, clipped to [−N, N].
fn between<F: FracBits>(lo: Ratio, hi: Ratio, n: i64) -> (i64, i64) {
    let a = lo.lattice_ceil::<F>().max(-(n as i128));
    let b = (hi.lattice_ceil::<F>() - 1).min(n as i128);
    (a as i64, b as i64)
}

#[derive(Debug, Clone)]
struct Case {
    d_pick: u64,
    k_pick: u64,
    src: [i32; 3],
    ray: [i64; 2],
    dir: u8,
    ends: [[u8; 2]; 2],
    picks: [u64; 8],
}

fn case() -> impl Strategy<Value = Case> {
    let coord = prop_oneof![
        -64i32..=64,                  // near the origin, all fractions
        -(1i32 << 20)..=(1i32 << 20), // anywhere on a big grid
        Just(i32::MIN),               // the extreme source positions
        Just(i32::MAX),
    ];
    (
        any::<u64>(),
        any::<u64>(),
        [coord.clone(), coord.clone(), coord],
        [any::<i64>(), any::<i64>()],
        0u8..6,
        [[0u8..8, 0u8..8], [0u8..8, 0u8..8]],
        [any::<u64>(); 8],
    )
        .prop_map(|(d_pick, k_pick, src, ray, dir, ends, picks)| Case {
            d_pick,
            k_pick,
            src,
            ray,
            dir,
            ends,
            picks,
        })
}

/// A D in 1..=MAX, biased to small values, the maximum and powers of two.
fn pick_d(max: u32, p: u64) -> u32 {
    let max = max as u64;
    let d = match p % 4 {
        0 => 1 + (p >> 2) % max.min(16),
        1 => max - (p >> 2) % max.min(3),
        2 => (1u64 << ((p >> 2) % 28)).min(max),
        _ => 1 + (p >> 2) % max,
    };
    d as u32
}

fn random_consistent_split<F: FracBits>(c: &Case) -> Result<(), TestCaseError> {
    let dmax = FarDistance::<F>::MAX;
    let d = pick_d(dmax, c.d_pick);
    let far = FarDistance::<F>::new(d).unwrap();
    let n = far.scaled();
    let k = match c.k_pick % 3 {
        0 => d - 1,
        1 => (c.k_pick >> 2) as u32 % d.min(4),
        _ => (c.k_pick >> 2) as u32 % d,
    };
    let s = src(c.src);
    let dir = Direction::from_index(c.dir).unwrap();
    let ray = [c.ray[0].rem_euclid(2 * n + 1) - n, c.ray[1].rem_euclid(2 * n + 1) - n];
    let t = trace_ray_voxel(&s, dir, off::<F>(ray[0]), off::<F>(ray[1]), far, Layer(k));
    let (Ok(tu), Ok(tv)) = (i32::try_from(t.0), i32::try_from(t.1)) else {
        return Ok(()); // a source at ±2^27 with a far ray: the voxel is off any i32 grid
    };
    let at = Transverse { u: tu, v: tv };

    // The rays occupying `at` at layer k, from the planes of layer k − 1 (all for k = 0).
    let occupied: [(i64, i64); 2] = if k == 0 {
        [(-n, n), (-n, n)]
    } else {
        let p = split_planes(&s, dir, far, Layer(k - 1), at).unwrap();
        [between::<F>(p.u1, p.u2, n), between::<F>(p.v1, p.v2, n)]
    };
    // This independent interval must hold the ray and be exactly the occupied set (ends in,
    // neighbours out).
    for ax in 0..2 {
        let (lo, hi) = occupied[ax];
        prop_assert!(lo <= ray[ax] && ray[ax] <= hi);
        let voxel = |a: i64| {
            let mut r = [off::<F>(ray[0]), off::<F>(ray[1])];
            r[ax] = off::<F>(a);
            let t = trace_ray_voxel(&s, dir, r[0], r[1], far, Layer(k));
            [t.0, t.1][ax]
        };
        let want = [at.u as i64, at.v as i64][ax];
        prop_assert_eq!(voxel(lo), want);
        prop_assert_eq!(voxel(hi), want);
        if lo > -n {
            prop_assert_ne!(voxel(lo - 1), want);
        }
        if hi < n {
            prop_assert_ne!(voxel(hi + 1), want);
        }
    }

    // The planes of this split, and their lattice ceilings.
    let p = split_planes(&s, dir, far, Layer(k), at).unwrap();
    // (Clamped to just beyond the square: planes further out cut no ray.)
    let ceil = |r: Ratio| r.lattice_ceil::<F>().clamp(-(n as i128) - 2, n as i128 + 2) as i64;
    let planes = [[ceil(p.u1), ceil(p.u2)], [ceil(p.v1), ceil(p.v2)]];
    // Beam limits: on a plane, next to one, at the occupied ends, or random.
    let mut ranges = [(0i64, 0i64); 2];
    for ax in 0..2 {
        let (olo, ohi) = occupied[ax];
        let [t1, t2] = planes[ax];
        let choose = |sel: u8, pick: u64, a: i64, b: i64| -> i64 {
            let r = a + (pick % ((b - a) as u64 + 1)) as i64;
            let v = match sel {
                0 => t1,
                1 => t1 - 1,
                2 => t2,
                3 => t2 - 1,
                4 => a,
                5 => b,
                _ => r,
            };
            v.clamp(a, b)
        };
        let lo = choose(c.ends[ax][0], c.picks[2 * ax], olo, ray[ax]);
        let hi = choose(c.ends[ax][1], c.picks[2 * ax + 1], ray[ax], ohi);
        ranges[ax] = (lo, hi);
    }
    let ru = RayRange::new(off::<F>(ranges[0].0), off(ranges[0].1)).unwrap();
    let rv = RayRange::new(off::<F>(ranges[1].0), off(ranges[1].1)).unwrap();
    let beam = Beam::new(SID, dir, Layer(k), ru, rv, far).unwrap();
    prop_assert!(beam.occupies(&s, far, at));

    let subs = beam.split(&s, far, at).unwrap();
    check_structure(&beam, &subs);

    // Sampled rays: the ends, both sides of both planes, the seed ray, two random ones.
    let samples = |ax: usize| -> Vec<i64> {
        let (lo, hi) = ranges[ax];
        let [t1, t2] = planes[ax];
        let span = (hi - lo) as u64 + 1;
        let mut v = vec![lo, hi, t1 - 1, t1, t2 - 1, t2, ray[ax]];
        v.push(lo + (c.picks[4 + 2 * ax] % span) as i64);
        v.push(lo + (c.picks[5 + 2 * ax] % span) as i64);
        v.retain(|&a| lo <= a && a <= hi);
        v.sort_unstable();
        v.dedup();
        v
    };
    for &a in &samples(0) {
        for &b in &samples(1) {
            let (ru, rv) = (off::<F>(a), off::<F>(b));
            let owners: Vec<_> = subs.iter().filter(|sb| sb.beam.contains(ru, rv)).collect();
            prop_assert_eq!(owners.len(), 1);
            let next = trace_ray_voxel(&s, dir, ru, rv, far, Layer(k + 1));
            let to = at.offset(owners[0].offset);
            prop_assert_eq!(next, (to.u as i64, to.v as i64), "ray ({}, {}) misrouted", a, b);
        }
    }
    // A ray exactly on a plane: on U2 goes +1, on U1 stays (when the plane is a lattice ray).
    for ax in 0..2 {
        let (lo, hi) = ranges[ax];
        let (p1, p2) = if ax == 0 { (p.u1, p.u2) } else { (p.v1, p.v2) };
        for (plane, t, want) in [(p1, planes[ax][0], 0i8), (p2, planes[ax][1], 1)] {
            let on_lattice = (t as i128) * (plane.den() as i128) == (plane.num() as i128) << F::U32;
            if on_lattice && lo <= t && t <= hi {
                let mut r = [ranges[0].0, ranges[1].0];
                r[ax] = t;
                let sb = subs.iter().find(|sb| sb.beam.contains(off(r[0]), off(r[1]))).unwrap();
                let got = if ax == 0 { sb.offset.du } else { sb.offset.dv };
                prop_assert_eq!(got, want);
            }
        }
    }
    Ok(())
}

/// Arbitrary, possibly inconsistent inputs at the extremes of every type: never panics
/// (overflow checks are on in tests) and always partitions.
fn arbitrary_split<F: FracBits>(c: &Case, at: [i32; 2], order: &[usize]) -> Result<(), TestCaseError> {
    let d = pick_d(FarDistance::<F>::MAX, c.d_pick);
    let far = FarDistance::<F>::new(d).unwrap();
    let n = far.scaled();
    let k = (c.k_pick % d as u64) as u32;
    let a = |x: u64| (x % (2 * n as u64 + 1)) as i64 - n;
    let (u0, u1) = (a(c.picks[0]), a(c.picks[1]));
    let (v0, v1) = (a(c.picks[2]), a(c.picks[3]));
    let ru = RayRange::new(off::<F>(u0.min(u1)), off(u0.max(u1))).unwrap();
    let rv = RayRange::new(off::<F>(v0.min(v1)), off(v0.max(v1))).unwrap();
    let dir = Direction::from_index(c.dir).unwrap();
    let beam = Beam::new(SID, dir, Layer(k), ru, rv, far).unwrap();
    let all = *SplitOrder::ROW_MAJOR.offsets();
    let order = SplitOrder::new(core::array::from_fn(|i| all[order[i]])).unwrap();
    let s = src(c.src);
    let subs = beam.split_with(&s, far, Transverse { u: at[0], v: at[1] }, &order).unwrap();
    check_structure(&beam, &subs);
    // The default order has a path of its own: the same sub-beams as the general one (any
    // other permutation), in row-major order of their offsets.
    let rm = beam.split(&s, far, Transverse { u: at[0], v: at[1] }).unwrap();
    prop_assert!(rm.windows(2).all(|w| (w[0].offset.du, w[0].offset.dv) < (w[1].offset.du, w[1].offset.dv)));
    prop_assert_eq!(rm.len(), subs.len());
    for sb in subs.iter() {
        prop_assert!(rm.contains(sb));
    }
    let _ = beam.voxel(&s, far);
    let _ = beam.occupies(&s, far, Transverse { u: at[0], v: at[1] });
    let _ = split_planes(&s, dir, far, Layer(k), Transverse { u: at[0], v: at[1] });
    Ok(())
}

macro_rules! prop_for_frac {
    ($($name:ident, $arb:ident: $F:ty;)*) => {
        proptest! {
            #![proptest_config(ProptestConfig::default())]
            $(
                #[test]
                fn $name(c in case()) {
                    random_consistent_split::<$F>(&c)?;
                }

                #[test]
                fn $arb(
                    c in case(),
                    at in [prop_oneof![any::<i32>(), -100i32..100], prop_oneof![any::<i32>(), -100i32..100]],
                    order in Just((0usize..9).collect::<Vec<_>>()).prop_shuffle(),
                ) {
                    arbitrary_split::<$F>(&c, at, &order)?;
                }
            )*
        }
    };
}

prop_for_frac! {
    consistent_f0, arbitrary_f0: U0;
    consistent_f1, arbitrary_f1: U1;
    consistent_f2, arbitrary_f2: U2;
    consistent_f3, arbitrary_f3: U3;
    consistent_f4, arbitrary_f4: U4;
    consistent_f8, arbitrary_f8: U8;
    consistent_f12, arbitrary_f12: U12;
    consistent_f16, arbitrary_f16: U16;
    consistent_f20, arbitrary_f20: U20;
    consistent_f24, arbitrary_f24: U24;
    consistent_f30, arbitrary_f30: U30;
}
