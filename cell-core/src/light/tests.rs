extern crate std;
use super::*;
use proptest::prelude::*;

/// The environment of the hand-made cases below: the thesis's rule and policy, FIFO size
/// 4, one source bit, no merging, skip, hold, frustum summary or ray sink; each case
/// changes what it tests with struct update.
fn thesis_env<'a, F: FracBits>(
    source: &'a Source,
    order: &'a SplitOrder,
    far: FarDistance<F>,
    n: u32,
) -> LightEnv<'a, F> {
    LightEnv {
        source,
        far,
        n,
        depth: n,
        policy: Policy::Thesis,
        rule: LitRule::Thesis,
        order,
        fa: 4,
        free_ports: false,
        source_bit: 1,
        merge: false,
        skip: None,
        lit_visible_only: false,
        hold: 0,
        frustum: None,
        rays: None,
        bounds: SubBeamBounds::new(n, n, None, source),
        occluders: None,
    }
}

fn check<const L: usize>(r: &LitRuns<L>) {
    for w in r.runs().windows(2) {
        assert!(w[0].hi < w[1].lo);
        assert!(!(w[0].hi + 1 == w[1].lo && w[0].mask == w[1].mask), "unmerged {:?}", w);
    }
    assert!(r.runs().iter().all(|x| x.lo <= x.hi && x.mask != 0));
}

#[test]
fn lit_runs_split_and_merge() {
    let mut r = LitRuns::<8>::new();
    for z in 10..=20 {
        assert!(r.mark(z, 1));
    }
    assert_eq!(r.runs(), &[LitRun { lo: 10, hi: 20, mask: 1 }]);
    assert!(r.mark(15, 2));
    assert_eq!(r.runs().len(), 3);
    assert_eq!((r.mask_at(14), r.mask_at(15), r.mask_at(16), r.mask_at(9)), (1, 3, 1, 0));
    assert!(r.mark(14, 2) && r.mark(16, 2));
    assert_eq!(
        r.runs(),
        &[LitRun { lo: 10, hi: 13, mask: 1 }, LitRun { lo: 14, hi: 16, mask: 3 }, LitRun { lo: 17, hi: 20, mask: 1 }]
    );
    check(&r);
}

#[test]
fn lit_runs_overflow_is_counted_and_harmless() {
    let mut r = LitRuns::<2>::new();
    assert!(r.mark(1, 1) && r.mark(5, 1));
    assert!(!r.mark(9, 1));
    assert_eq!(r.overflows(), 1);
    assert_eq!(r.mask_at(9), 0);
    assert!(r.mark(2, 1), "merging needs no new run");
}

/// The eight-at-once room check against byte-by-byte comparison, exhaustively for one
/// byte at every position (the other seven empty or full), at OB = 1, 3 and 127.
#[test]
fn room_matches_bytewise_comparison() {
    fn check<const OB: usize>() {
        for pos in 0..8 {
            for other in [0u64, OB as u64] {
                for len in 0..=OB as u64 {
                    for need in 0..=9u64 {
                        let fill = u64::from_le_bytes([other as u8; 8]) & !(0xFF << (8 * pos));
                        let lengths = fill | len << (8 * pos);
                        let needs = need << (8 * pos);
                        let expect = len + need <= OB as u64 && other <= OB as u64;
                        assert_eq!(room::<OB>(lengths, needs), expect, "OB {OB} byte {pos} len {len} need {need}");
                    }
                }
            }
        }
    }
    check::<1>();
    check::<3>();
    check::<127>();
}

/// The busy-port mask against byte-by-byte testing, exhaustively over which of the eight
/// buffers hold something, with lengths at both ends of a byte (1 and the cap 127) and in
/// between; and `Port::each` against filtering `Port::ALL`.
#[test]
fn busy_mask_matches_bytewise_test() {
    for mask in 0..=255u8 {
        let each: std::vec::Vec<Port> = Port::each(mask).collect();
        let want: std::vec::Vec<Port> = Port::ALL.into_iter().filter(|p| mask >> p.index() & 1 == 1).collect();
        assert_eq!(each, want, "mask {mask:#010b}");
        for len in [1u8, 2, 3, 64, 126, 127] {
            let mut b = OutBuffers::<fixed::types::extra::U0, 127>::new();
            for p in Port::ALL {
                b.len[p.index()] = if mask >> p.index() & 1 == 1 { len.max(1 + p.index() as u8) } else { 0 };
            }
            assert_eq!(b.busy_mask(), mask, "lengths {:?}", b.len);
            assert!(b.busy_ports().eq(want.iter().copied()));
        }
    }
}
proptest! {
    /// The receding test against its definition, axis by axis: empty box, or beyond the box
    /// along the principal axis in the direction of travel, or beyond the box on a
    /// transverse axis and strictly beyond the source voxel on the same side.
    #[test]
    fn receding_matches_its_definition(
        lo in proptest::array::uniform3(0u16..12), hi in proptest::array::uniform3(0u16..12),
        sv in proptest::array::uniform3(-2i32..14), at in proptest::array::uniform3(-3i64..15),
        d in 0usize..6,
    ) {
        let dir = Direction::ALL[d];
        let bx = OccupiedBox { lo, hi };
        let w = dir.principal().index();
        let empty = (0..3).any(|a| lo[a] > hi[a]);
        let ahead = if dir.sign() > 0 { at[w] > hi[w] as i64 } else { at[w] < lo[w] as i64 };
        let side = (0..3).filter(|&a| a != w).any(|a| {
            let (l, h, s) = (lo[a] as i64, hi[a] as i64, sv[a] as i64);
            (at[a] > h && at[a] > s) || (at[a] < l && at[a] < s)
        });
        prop_assert_eq!(bx.receding(dir, sv, at), empty || ahead || side);
    }

    /// The output buffers against eight `VecDeque`s bounded at OB: same accept/refuse, same
    /// order, and the one-word summaries (`any`, `busy_ports`, `len`) agree.
    #[test]
    fn out_buffers_match_bounded_deques(ops in proptest::collection::vec((0usize..8, any::<bool>(), any::<u16>()), 0..200)) {
        let mut b = OutBuffers::<fixed::types::extra::U0, 3>::new();
        let mut want: [std::collections::VecDeque<u16>; 8] = Default::default();
        for (p, push, z) in ops {
            let port = Port::ALL[p];
            if push {
                let r = b.push_back(port, BeamMsg::new(Beam::filler(), z));
                prop_assert_eq!(r.is_ok(), want[p].len() < 3);
                if want[p].len() < 3 {
                    want[p].push_back(z);
                } else {
                    prop_assert_eq!(r.unwrap_err().z, z);
                }
            } else {
                prop_assert_eq!(b.pop_front(port).map(|m| m.z), want[p].pop_front());
            }
            for q in Port::ALL {
                let w = &want[q.index()];
                prop_assert_eq!(b.len(q), w.len());
                prop_assert_eq!(b.is_empty(q), w.is_empty());
                prop_assert_eq!(b.front(q).map(|m| m.z), w.front().copied());
                prop_assert!(b.waiting(q).iter().map(|m| m.z).eq(w.iter().copied()));
            }
            prop_assert_eq!(b.any(), want.iter().any(|w| !w.is_empty()));
            prop_assert!(b.busy_ports().eq(Port::ALL.into_iter().filter(|q| !want[q.index()].is_empty())));
        }
    }

    /// The blocked- and held-step shortcuts are exact: a cell driven by random steps, link
    /// pops and arrivals behaves like a twin that forgets the shortcut before every step
    /// (full re-evaluation of every waiting beam), and like a twin that is not stepped at
    /// all while held ([`LightCell::held_wait`]) and catches up with
    /// [`LightCell::skip_held`] before anything changes it — the host's sleeping cells.
    /// Output buffers of one message, so that cells block often; sibling waits of 0, 2, 3.
    #[test]
    fn blocked_and_held_shortcuts_change_nothing(
        hold in prop_oneof![Just(0u16), Just(2), Just(3)],
        radial in any::<bool>(),
        ops in proptest::collection::vec((0u8..4, 0usize..8, 0usize..24), 1..150),
    ) {
        use crate::beam::{SourceCoord, SourceId};
        use fixed::types::extra::U0;
        type C = LightCell<U0, 4, 1, 8>;
        let n = 16;
        let c = |v: f64| SourceCoord::from_num(v);
        let src = Source::new(SourceId(0), [c(7.5), c(7.25), c(7.0)]);
        let far = FarDistance::<U0>::new(n - 1).unwrap();
        let order = SplitOrder::default();
        let env = LightEnv {
            merge: true,
            policy: if radial { Policy::Radial } else { Policy::Wavefront },
            hold,
            ..thesis_env(&src, &order, far, n)
        };
        let mut store = Cell::<8>::new(0, 0);
        let tag = crate::dexel::FacetTag::default();
        let _ = store.store.insert(crate::units::Span { lo: 12, hi: 13 }, tag);
        let sv = src.voxel();
        // The cell two columns east of the source's and one north, and what can reach it:
        // the initial beams, and the source's +x beam split twice, every layer-2 sub-beam
        // for this column cut in two along u (pieces that wait for each other and merge).
        let (cx, cy) = (sv[0] + 2, sv[1] + 1);
        let mut arrivals: std::vec::Vec<BeamMsg<U0>> =
            Beam::<U0>::initial_six(&src, far).iter().map(|&beam| BeamMsg::new(beam, sv[2] as u16)).collect();
        let px = Direction::PosX;
        for s1 in Beam::<U0>::initial(&src, px, far).split(&src, far, px.transverse_of(sv)).unwrap() {
            let d1 = px.displacement(s1.offset);
            let v1 = [sv[0] + d1[0] as i32, sv[1] + d1[1] as i32, sv[2] + d1[2] as i32];
            for s2 in s1.beam.split(&src, far, px.transverse_of(v1)).unwrap() {
                let d2 = px.displacement(s2.offset);
                let v2 = [v1[0] + d2[0] as i32, v1[1] + d2[1] as i32, v1[2] + d2[2] as i32];
                if (v2[0], v2[1]) != (cx, cy) {
                    continue;
                }
                let (b, u) = (s2.beam, s2.beam.u());
                let mid = crate::beam::FarOffset::<U0>::from_bits((u.lo().to_bits() + u.hi().to_bits()) / 2);
                for (lo, hi) in [(u.lo(), mid), (mid + crate::beam::FarOffset::<U0>::from_bits(1), u.hi())] {
                    if let Some(r) = crate::beam::RayRange::new(lo, hi) {
                        let piece = Beam::new(b.source(), px, b.layer(), r, b.v(), far).unwrap();
                        arrivals.push(BeamMsg::new(piece, v2[2] as u16));
                    }
                }
            }
        }
        let new = || C::new(cx as u16, cy as u16);
        let (mut a, mut b, mut s) = (new(), new(), new());
        let (ta, tb, ts) = (Activity::new(), Activity::new(), Activity::new());
        // The sleeping twin `s`: asleep after a held step, owing the steps it skips.
        let (mut asleep, mut owed) = (false, 0u16);
        let mut popped: std::vec::Vec<BeamMsg<U0>> = std::vec::Vec::new();
        for (op, port, which) in ops {
            // Anything but a step that the wait still covers wakes the twin first.
            let covered = asleep && op == 0 && s.held_wait().is_some_and(|w| owed + 1 < w);
            if asleep && !covered {
                s.skip_held(owed);
                (asleep, owed) = (false, 0);
            }
            match op {
                0 => {
                    b.blocked_on = None;
                    let r = a.step(&store, &env, &ta);
                    prop_assert_eq!(r, b.step(&store, &env, &tb));
                    if covered {
                        prop_assert_eq!(r, Step::Held);
                        owed += 1;
                    } else {
                        prop_assert_eq!(r, s.step(&store, &env, &ts));
                        asleep = r == Step::Held;
                    }
                }
                1 => {
                    let p = Port::ALL[port];
                    let (x, y, z) = (a.out.pop_front(p), b.out.pop_front(p), s.out.pop_front(p));
                    prop_assert_eq!(x, y);
                    prop_assert_eq!(x, z);
                    popped.extend(x);
                }
                _ => {
                    // A new arrival: a piece for this column, or a message a link took earlier.
                    let m = match popped.get(which) {
                        Some(&m) if which % 2 == 0 => m,
                        _ => arrivals[which % arrivals.len()],
                    };
                    if a.can_accept(env.fa) {
                        ta.add(1);
                        tb.add(1);
                        ts.add(1);
                        let r = a.accept(m, true, &ta).is_ok();
                        prop_assert_eq!(r, b.accept(m, true, &tb).is_ok());
                        prop_assert_eq!(r, s.accept(m, true, &ts).is_ok());
                    }
                }
            }
            let mut caught_up = s.clone();
            caught_up.skip_held(owed);
            for t in [&b, &caught_up] {
                prop_assert_eq!(&a.fifo, &t.fifo);
                prop_assert_eq!(a.ticks, t.ticks);
                for p in Port::ALL {
                    prop_assert_eq!(a.out.waiting(p), t.out.waiting(p));
                }
                prop_assert_eq!(a.counters, t.counters);
            }
            prop_assert_eq!(ta.get(), tb.get());
            prop_assert_eq!(ta.get(), ts.get());
        }
    }

    #[test]
    fn lit_runs_match_a_per_voxel_array(marks in proptest::collection::vec((0u16..40, 0u32..4), 0..60)) {
        let mut r = LitRuns::<64>::new();
        let mut want = [0u32; 40];
        for (z, s) in marks {
            prop_assert!(r.mark(z, 1 << s));
            want[z as usize] |= 1 << s;
            check(&r);
        }
        for z in 0..40u16 {
            prop_assert_eq!(r.mask_at(z), want[z as usize]);
        }
    }
}

/// The free-ports rule (§4.4.1, "si dir propagation libre"): the source's +z beam sends one
/// sub-beam to each of the 8 neighbours. With one message already waiting toward the east
/// there is room for one more, so the beam goes by default; under `free_ports` the east
/// port is not free and the cell is blocked until that buffer is empty.
#[test]
fn free_ports_wait_for_empty_output_buffers() {
    use crate::beam::{SourceCoord, SourceId};
    use fixed::types::extra::U0;
    let n = 16;
    let src = Source::new(SourceId(0), [SourceCoord::from_num(7); 3]);
    let far = FarDistance::<U0>::new(n - 1).unwrap();
    let order = SplitOrder::default();
    let env = |free_ports| LightEnv { free_ports, ..thesis_env(&src, &order, far, n) };
    let store = Cell::<8>::new(7, 7);
    let up = BeamMsg::new(Beam::<U0>::initial(&src, Direction::PosZ, far), 7);
    let cell = |free_ports| {
        let mut c = LightCell::<U0, 8, 3, 8>::new(7, 7);
        c.accept(up, false, &Activity::new()).unwrap();
        c.out.push_back(Port::E, up).unwrap();
        let first = c.step(&store, &env(free_ports), &Activity::new());
        (first, c)
    };
    let (step, c) = cell(false);
    assert_eq!(step, Step::Processed);
    assert!(Port::ALL.iter().all(|&p| c.out.len(p) == 1 + usize::from(p == Port::E)));
    let (step, mut c) = cell(true);
    assert_eq!(step, Step::Blocked);
    c.out.pop_front(Port::E);
    assert_eq!(c.step(&store, &env(true), &Activity::new()), Step::Processed);
}

/// Among waiting beams of one layer, the wavefront takes the oldest and radial the one
/// nearest the source's axis (|z − z_s|), whatever their arrival order; both take a smaller
/// layer first. Checked on every pair of the +x beam's layer-2 sub-beams in one column.
#[test]
fn radial_takes_the_beam_nearest_the_axis() {
    use crate::beam::{SourceCoord, SourceId};
    use fixed::types::extra::U0;
    let n = 16;
    let c = |v: f64| SourceCoord::from_num(v);
    let src = Source::new(SourceId(0), [c(7.0), c(7.0), c(7.25)]);
    let far = FarDistance::<U0>::new(n - 1).unwrap();
    let order = SplitOrder::default();
    let env = |policy| LightEnv { policy, fa: 8, ..thesis_env(&src, &order, far, n) };
    let store = Cell::<8>::new(0, 0);
    let sv = src.voxel();
    let px = Direction::PosX;
    // Every sub-beam of layers 1 and 2 that lands in column (x_s + 2, y_s), by voxel z.
    let mut layer2: std::vec::Vec<BeamMsg<U0>> = std::vec::Vec::new();
    let mut layer1: std::vec::Vec<BeamMsg<U0>> = std::vec::Vec::new();
    for s1 in Beam::<U0>::initial(&src, px, far).split(&src, far, px.transverse_of(sv)).unwrap() {
        let d1 = px.displacement(s1.offset);
        let v1 = [sv[0] + d1[0] as i32, sv[1] + d1[1] as i32, sv[2] + d1[2] as i32];
        if (v1[0], v1[1]) == (sv[0] + 1, sv[1]) {
            layer1.push(BeamMsg::new(s1.beam, v1[2] as u16));
        }
        for s2 in s1.beam.split(&src, far, px.transverse_of(v1)).unwrap() {
            let d2 = px.displacement(s2.offset);
            let v2 = [v1[0] + d2[0] as i32, v1[1] + d2[1] as i32, v1[2] + d2[2] as i32];
            if (v2[0], v2[1]) == (sv[0] + 2, sv[1]) {
                layer2.push(BeamMsg::new(s2.beam, v2[2] as u16));
            }
        }
    }
    let axis = |m: &BeamMsg<U0>| (m.z as f64 - 7.25).abs();
    assert!(layer2.iter().any(|m| axis(m) != axis(&layer2[0])), "pieces at several distances");
    let first = |policy, msgs: &[BeamMsg<U0>]| {
        let mut cell = LightCell::<U0, 8, 3, 8>::new(sv[0] as u16 + 2, sv[1] as u16);
        for &m in msgs {
            cell.accept(m, false, &Activity::new()).unwrap();
        }
        assert_eq!(cell.step(&store, &env(policy), &Activity::new()), Step::Processed);
        cell.last_z
    };
    let mut pairs = 0;
    for a in &layer2 {
        for b in &layer2 {
            if axis(a) == axis(b) {
                continue;
            }
            pairs += 1;
            let near = if axis(a) < axis(b) { a.z } else { b.z };
            assert_eq!(first(Policy::Wavefront, &[*a, *b]), a.z, "oldest first");
            assert_eq!(first(Policy::Radial, &[*a, *b]), near, "nearest the axis first");
            // A smaller layer goes first under both, however far from the axis.
            for l1 in &layer1 {
                assert_eq!(first(Policy::Radial, &[*a, *b, *l1]), l1.z);
            }
        }
    }
    assert!(pairs >= 2, "{pairs} pairs");
}

#[test]
fn activity_counts_exactly() {
    let a = Activity::new();
    assert!(a.is_quiescent());
    a.add(6);
    for _ in 0..5 {
        a.consume();
    }
    assert!(!a.is_quiescent());
    a.consume();
    assert!(a.is_quiescent());
}

#[test]
fn ports_round_trip() {
    for p in Port::ALL {
        let (dx, dy) = p.delta();
        assert_eq!(Port::from_delta(dx, dy), Some(p));
    }
    assert_eq!(Port::from_delta(0, 0), None);
    // Exhaustively: a port exactly for the eight unit steps.
    for dx in i8::MIN..=i8::MAX {
        for dy in i8::MIN..=i8::MAX {
            let want = Port::ALL.into_iter().find(|p| p.delta() == (dx, dy));
            assert_eq!(Port::from_delta(dx, dy), want, "({dx}, {dy})");
        }
    }
}
