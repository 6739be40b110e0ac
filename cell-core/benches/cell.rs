//! Criterion benchmarks of what one cell does per step: the loading wave's row cell
//! (`row_span`, `Cell::load_step`, `DexelStore::insert`), the beam split at several layers and
//! fraction bits, the tests of the sibling wait and the empty-frustum skip, the lighting FIFO
//! (`LightCell::accept` with and without merging, `step`), the exact occluders' and the
//! receiver's tests beside the plane rule's, and the shading of one pixel.
//!
//! `cargo bench -p cell-core` (results in BENCHMARKS.md). Not part of `cargo test`: benches are
//! built only with `--benches`/`--all-targets`, and then run once per case as a smoke test.
//!
//! The inputs are built here by hand (a cell never sees a mesh): a plane facet over a 64 × 64
//! triangle, in the exact integer form of `cell_core::facet` (see the packet doc there), and
//! beams obtained by following real splits from a source, so every beam is consistent with
//! the cell that holds it.

use std::hint::black_box;

use cell_core::beam::{frac, Beam, Direction, FarDistance, FracBits, Layer, RayRange, Source, SourceId, SplitOrder};
use cell_core::cell::{Cell, DEFAULT_DEXELS};
use cell_core::dexel::{DexelStore, FacetTag};
use cell_core::facet::{FacetBox, RowEdge, RowPacket};
use cell_core::light::{Activity, BeamMsg, LightCell, LightEnv, Policy, SubBeamBounds};
use cell_core::lit::{segments, uniform, Along, RayPlane, Segments, Test};
use cell_core::normal::NormalCode;
use cell_core::occluder::{Occluder, Triangle};
use cell_core::occupancy::Occupancy8;
use cell_core::plane::DexelPlane;
use cell_core::receiver::target;
use cell_core::shade::{shade, shading_normal, Material, NormalMode, PointLight, ShadeParams};
use cell_core::units::Span;
use cell_core::visible::VisibleSurface;
use cell_core::voxelize::row_span;
use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion, Throughput};

/// Columns in the benchmark row (and grid side for the lighting benches).
const ROW: u16 = 64;

/// The row packet at column 0 of row `y` for the plane `a·x + b·y + c·z + d = 0` with band
/// half-width `k` (standard thickness: (|a|+|b|+|c|)/2, here with even coefficients), cut by
/// the triangle x ≥ 0, y ≥ 0, x + y ≤ 63 (three XOY edges, pure in/out tests).
fn row_packet(a: i64, b: i64, c: i64, d: i64, y: i64) -> RowPacket {
    let k = (a.abs() + b.abs() + c.abs()) / 2;
    let p = b * y + d; // P(0, y)
    let mut edges = heapless::Vec::new();
    for e in [
        RowEdge { a: 1, c: 0, g: 0, off: 0 },
        RowEdge { a: 0, c: 0, g: y, off: 0 },
        RowEdge { a: -1, c: 0, g: 63 - y, off: 0 },
    ] {
        edges.push(e).expect("3 ≤ MAX_EDGES");
    }
    RowPacket {
        tag: FacetTag {
            facet: 7,
            material: 1,
            normal: NormalCode::encode([a as f32, b as f32, c as f32]),
            ..Default::default()
        },
        bbox: FacetBox { x_min: 0, x_max: ROW - 1, y_min: 0, y_max: ROW - 1, z_min: 0, z_max: ROW - 1 },
        a,
        c,
        t: k - p,
        u: -k - p,
        edges,
    }
}

/// A nearly horizontal facet (1-voxel dexels) and a steep one (long dexels), both through the
/// middle of the box at row y = 10.
fn packets() -> [(&'static str, RowPacket); 2] {
    [("shallow", row_packet(2, 4, 8, -8 * 32, 10)), ("steep", row_packet(16, 2, 2, -16 * 32, 10))]
}

fn bench_voxelize(c: &mut Criterion) {
    let mut g = c.benchmark_group("voxelize");
    g.throughput(Throughput::Elements(ROW as u64));
    for (name, pkt) in packets() {
        // The pure span computation, stepping east along the row as the wave does.
        g.bench_with_input(BenchmarkId::new("row_span_x64", name), &pkt, |b, pkt| {
            b.iter_batched(
                || pkt.clone(),
                |mut p| {
                    let mut voxels = 0u32;
                    for _ in 0..ROW {
                        voxels += row_span(&p, ROW as u32).map_or(0, |s| s.len());
                        p.step_east();
                    }
                    voxels
                },
                BatchSize::SmallInput,
            )
        });
        // The row cell's whole step (span, store insert, counters, forward) over 64 fresh cells.
        g.bench_with_input(BenchmarkId::new("load_step_x64", name), &pkt, |b, pkt| {
            b.iter_batched_ref(
                || (pkt.clone(), (0..ROW).map(|x| Cell::<DEFAULT_DEXELS>::new(x, 10)).collect::<Vec<_>>()),
                |(p, cells)| {
                    for cell in cells.iter_mut() {
                        if !cell.load_step(p, ROW as u32) {
                            break;
                        }
                    }
                },
                BatchSize::SmallInput,
            )
        });
    }
    g.finish();

    // 32 disjoint spans, 3 voxels each, inserted in a scrambled order into an empty store
    // (binary search + shift), then the same spans again (every voxel already held: shared).
    let spans: Vec<(Span, FacetTag)> = (0..32u16)
        .map(|i| {
            let j = (i * 13) % 32; // a permutation of 0..32
            let tag = FacetTag { facet: j as u32, material: j % 2, normal: NormalCode(j), ..Default::default() };
            (Span { lo: 4 * j, hi: 4 * j + 2 }, tag)
        })
        .collect();
    let mut g = c.benchmark_group("dexel_insert");
    g.throughput(Throughput::Elements(spans.len() as u64));
    g.bench_function("into_empty_x32", |b| {
        b.iter_batched_ref(
            DexelStore::<DEFAULT_DEXELS>::new,
            |s| {
                for &(span, tag) in &spans {
                    black_box(s.insert(span, tag));
                }
            },
            BatchSize::SmallInput,
        )
    });
    let mut full = DexelStore::<DEFAULT_DEXELS>::new();
    for &(span, tag) in &spans {
        full.insert(span, tag);
    }
    g.bench_function("all_shared_x32", |b| {
        b.iter_batched_ref(
            || full.clone(),
            |s| {
                for &(span, tag) in &spans {
                    black_box(s.insert(span, tag));
                }
            },
            BatchSize::SmallInput,
        )
    });
    g.finish();
}

/// The beam at `layer` toward `dir` that a cell really receives: follow the split from the
/// source, each time into the sub-beam with the most rays (so it keeps straddling planes).
/// Returns the beam and its voxel.
fn beam_at<F: FracBits>(src: &Source, far: FarDistance<F>, dir: Direction, layer: u32) -> (Beam<F>, [i64; 3]) {
    let mut beam = Beam::initial(src, dir, far);
    let mut at = dir.transverse_of(src.voxel());
    for _ in 0..layer {
        let subs = beam.split(src, far, at).expect("below the far plane");
        let best = subs.iter().max_by_key(|s| s.beam.ray_count()).expect("never empty");
        at = at.offset(best.offset);
        beam = best.beam;
    }
    (beam, dir.voxel(src, Layer(layer), at))
}

fn split_group<F: FracBits>(c: &mut Criterion) {
    let n = 256u32;
    let src = Source::at_voxel(SourceId(0), [100, 128, 140]).expect("fits");
    let far = FarDistance::<F>::new(n - 1).expect("within the bit budget");
    let mut g = c.benchmark_group(format!("beam_split_f{}", F::U32));
    for layer in [0u32, 16, 128, 250] {
        let (beam, voxel) = beam_at(&src, far, Direction::PosX, layer);
        let at = Direction::PosX.transverse_of(voxel.map(|v| v as i32));
        let parts = beam.split(&src, far, at).expect("below the far plane").len();
        g.bench_function(BenchmarkId::new("split", format!("layer{layer}_{parts}subs")), |b| {
            b.iter(|| black_box(&beam).split(&src, far, black_box(at)))
        });
        g.bench_function(BenchmarkId::new("split_with_axis_first", format!("layer{layer}_{parts}subs")), |b| {
            b.iter(|| black_box(&beam).split_with(&src, far, black_box(at), &SplitOrder::AXIS_NEIGHBOURS_FIRST))
        });
    }
    g.finish();
}

fn bench_split(c: &mut Criterion) {
    split_group::<frac::U0>(c);
    split_group::<frac::U4>(c);
    split_group::<frac::U8>(c);
}

/// The two tests the new skips run per beam: `Beam::complete` (the sibling wait, every held
/// candidate) and `OccupancySummary::frustum_empty` (the empty-frustum skip, every processed
/// beam) on an open scene (a floor and a cube) at n = 256, for beams heading into it and away.
fn bench_skips(c: &mut Criterion) {
    let n = 256u32;
    let src = Source::at_voxel(SourceId(0), [100, 128, 140]).expect("fits");
    let far = FarDistance::<frac::U0>::new(n - 1).expect("within the bit budget");
    let mut open = Occupancy8::new(n, n);
    for x in 0..n {
        for y in 0..n {
            open.mark_span(x, y, 0, 3);
        }
    }
    for x in 150..190 {
        for y in 100..140 {
            open.mark_span(x, y, 100, 140);
        }
    }
    let mut g = c.benchmark_group("skips");
    for (dir, layer) in [(Direction::PosX, 16u32), (Direction::PosX, 128), (Direction::NegZ, 16), (Direction::PosZ, 16)]
    {
        let (beam, voxel) = beam_at(&src, far, dir, layer);
        let at = dir.transverse_of(voxel.map(|v| v as i32));
        let empty = open.frustum_empty(&beam, &src, far, layer + 1);
        let id = format!("{dir:?}_layer{layer}_{}", if empty { "empty" } else { "meets" });
        g.bench_function(BenchmarkId::new("frustum_empty_8", &id), |b| {
            b.iter(|| black_box(&open).frustum_empty(black_box(&beam), &src, far, layer + 1))
        });
        g.bench_function(BenchmarkId::new("complete", &id), |b| {
            b.iter(|| black_box(&beam).complete(&src, far, black_box(at)))
        });
    }
    g.finish();
}

type BenchCell = LightCell<frac::U0, 64, 3, 32>;

/// A lighting cell at the voxel of a real layer-`layer` beam, its FIFO holding that beam
/// (first) and `extra` other real beams of the same cell column at other depths.
fn loaded_cell(src: &Source, far: FarDistance<frac::U0>, layer: u32, extra: u32) -> (BenchCell, BeamMsg<frac::U0>) {
    let (beam, v) = beam_at(src, far, Direction::PosX, layer);
    let msg = BeamMsg::new(beam, v[2] as u16);
    let mut cell = BenchCell::new(v[0] as u16, v[1] as u16);
    let activity = Activity::new();
    activity.add(1 + extra as u64);
    cell.accept(msg, false, &activity).expect("room");
    for k in 0..extra {
        // Other beams waiting in the same cell: same beam, other depths (no merge possible).
        let other = BeamMsg::new(beam, (v[2] as u16 + 1 + k as u16) % ROW);
        cell.accept(other, false, &activity).expect("room");
    }
    (cell, msg)
}

fn bench_fifo(c: &mut Criterion) {
    let src = Source::at_voxel(SourceId(0), [8, 32, 32]).expect("fits");
    let far = FarDistance::<frac::U0>::new(ROW as u32 - 1).expect("fits");
    let activity = Activity::new();
    activity.add(1 << 40); // consumes in the benches never reach 0
    let (cell15, msg) = loaded_cell(&src, far, 20, 14);
    // An arriving beam that shares a whole side with the waiting `msg`: the halves of a beam
    // split along u, the lower half waiting, the upper arriving.
    let whole = msg.beam;
    let mid = whole.u().lo().to_bits() + (whole.u().hi().to_bits() - whole.u().lo().to_bits()) / 2;
    let half = |lo: i32, hi: i32| {
        let u = RayRange::new(cell_core::beam::FarOffset::from_bits(lo), cell_core::beam::FarOffset::from_bits(hi))
            .expect("lo ≤ hi");
        BeamMsg::new(Beam::new(whole.source(), whole.direction(), whole.layer(), u, whole.v(), far).expect("ok"), msg.z)
    };
    assert!(whole.u().len() >= 2, "the benchmark beam must be splittable");
    let (lower, upper) = (half(whole.u().lo().to_bits(), mid), half(mid + 1, whole.u().hi().to_bits()));
    let mut cell_lower = cell15.clone();
    cell_lower.fifo[0] = lower;
    let stranger = BeamMsg::new(msg.beam, (msg.z + 40) % ROW); // matches nothing waiting

    let mut g = c.benchmark_group("fifo_accept");
    g.bench_function("no_merge_into_15", |b| {
        b.iter_batched_ref(
            || cell15.clone(),
            |c| c.accept(black_box(stranger), false, &activity),
            BatchSize::SmallInput,
        )
    });
    g.bench_function("merge_scan_miss_15", |b| {
        b.iter_batched_ref(|| cell15.clone(), |c| c.accept(black_box(stranger), true, &activity), BatchSize::SmallInput)
    });
    g.bench_function("merge_hit_15", |b| {
        b.iter_batched_ref(
            || cell_lower.clone(),
            |c| {
                c.accept(black_box(upper), true, &activity).expect("merges");
                debug_assert_eq!(c.fifo.len(), 15);
            },
            BatchSize::SmallInput,
        )
    });
    g.finish();

    let order = SplitOrder::default();
    let env = |policy| LightEnv {
        source: &src,
        far,
        n: ROW as u32,
        depth: ROW as u32,
        policy,
        rule: cell_core::lit::LitRule::Thesis,
        order: &order,
        fa: 16,
        free_ports: false,
        source_bit: 1,
        merge: true,
        skip: None,
        bounds: SubBeamBounds::new(ROW as u32, ROW as u32, None, &src),
        lit_visible_only: false,
        hold: 0,
        frustum: None,
        rays: None,
        occluders: None,
    };
    let empty = cell_core::cell::Cell::<DEFAULT_DEXELS>::new(0, 0);
    let mut wall = cell_core::cell::Cell::<DEFAULT_DEXELS>::new(0, 0);
    wall.store.insert(Span { lo: 0, hi: ROW - 1 }, FacetTag::default());
    let mut g = c.benchmark_group("light_step");
    for (name, policy) in [("wavefront", Policy::Wavefront), ("thesis", Policy::Thesis)] {
        let env = env(policy);
        for extra in [0u32, 14] {
            let cell = loaded_cell(&src, far, 20, extra).0;
            g.bench_function(BenchmarkId::new(format!("split_{name}"), format!("fifo{}", extra + 1)), |b| {
                b.iter_batched_ref(
                    || cell.clone(),
                    |c| c.step(black_box(&empty), &env, &activity),
                    BatchSize::SmallInput,
                )
            });
        }
        let cell = loaded_cell(&src, far, 20, 0).0;
        g.bench_function(BenchmarkId::new(format!("absorb_{name}"), "fifo1"), |b| {
            b.iter_batched_ref(|| cell.clone(), |c| c.step(black_box(&wall), &env, &activity), BatchSize::SmallInput)
        });
    }
    g.finish();
}

fn bench_shade(c: &mut Criterion) {
    let params = ShadeParams { ambient: [0.2; 3], normal_mode: NormalMode::Facet, eye: cell_core::shade::Eye::Grid };
    let plastic = Material { ka: [0.1; 3], kd: [0.6, 0.3, 0.2], ks: [0.3; 3], ns: 40.0, ke: [0.0; 3] };
    let matte = Material { ks: [0.0; 3], ..plastic };
    let lights: Vec<PointLight> =
        (0..4).map(|i| PointLight { pos: [20.0 + 30.0 * i as f32, 120.0, -40.0], color: [0.5; 3] }).collect();
    let dexel = cell_core::dexel::Dexel {
        span: Span { lo: 40, hi: 41 },
        facet: 3,
        material: 0,
        normal: NormalCode::encode([0.3, 0.5, -0.8]),
        plane: Default::default(),
    };
    let p = [64.0, 70.0, 40.0];
    let mut g = c.benchmark_group("shade_pixel");
    g.bench_function("normal_decode", |b| b.iter(|| shading_normal(black_box(&dexel), NormalMode::Facet)));
    for (name, m) in [("matte", &matte), ("specular", &plastic)] {
        for k in [1usize, 4] {
            g.bench_function(BenchmarkId::new(name, format!("{k}lights")), |b| {
                b.iter(|| {
                    let n = shading_normal(black_box(&dexel), NormalMode::Facet);
                    shade(black_box(p), n, m, &lights[..k], (1 << k) - 1, &params)
                })
            });
        }
    }
    g.finish();
}

/// The exact occluders' work beside the plane rule's, on the beam a cell really receives (+x,
/// layer 16, n = 256): building a triangle's tests (once per light and direction), deciding a
/// whole beam by them (`uniform`), cutting one column of it (`segments`); the plane rule's
/// three tests of a dexel's plane, built at each visit; the column test a loading cell runs per
/// triangle, and the receiver's target, once per light.
fn bench_occluders(c: &mut Criterion) {
    let n = 256u32;
    let src = Source::at_voxel(SourceId(0), [100, 128, 140]).expect("fits");
    let far = FarDistance::<frac::U0>::new(n - 1).expect("within the bit budget");
    let dir = Direction::PosX;
    let k = 16i64;
    let (beam, voxel) = beam_at(&src, far, dir, k as u32);
    let c16 = voxel.map(|v| 16 * v as i32);
    // A triangle across the beam's voxel, and the same three voxels aside.
    let triangle = |off: i32| {
        Triangle::new([
            [c16[0] + 4, c16[1] - 40 + off, c16[2] - 40],
            [c16[0] - 4, c16[1] + 40 + off, c16[2] - 8],
            [c16[0], c16[1] - 8 + off, c16[2] + 40],
        ])
        .expect("within the limits")
    };
    let bits = |r: RayRange<frac::U0>| (r.lo().to_bits() as i64, r.hi().to_bits() as i64);
    let (u, v) = (bits(beam.u()), bits(beam.v()));
    let mut g = c.benchmark_group("occluders");
    for (name, tri) in [("across", triangle(0)), ("aside", triangle(48))] {
        let occ = Occluder::new(&tri, &src, dir, far).expect("seen from the source");
        let whole = uniform(&occ.tests(k), u, v).is_some();
        let id = format!("{name}_{}", if whole { "whole" } else { "cut" });
        g.bench_function(BenchmarkId::new("occluder_new", &id), |b| {
            b.iter(|| Occluder::new(black_box(&tri), &src, dir, far))
        });
        g.bench_function(BenchmarkId::new("uniform_5_tests", &id), |b| {
            b.iter(|| uniform(&black_box(&occ).tests(k), u, v))
        });
        g.bench_function(BenchmarkId::new("segments_one_column", &id), |b| {
            let mut seg: Segments = Segments::new();
            b.iter(|| {
                segments(&black_box(&occ).tests(k), Along::V, u.0, v.0, v.1, &mut seg);
                seg.len()
            })
        });
    }
    let plane = DexelPlane { id: 0, nx: 16384, ny: 1200, nz: -(300 << 16), e: 0 };
    g.bench_function("plane_rule_new_and_uniform_3_tests", |b| {
        b.iter(|| {
            let rp = RayPlane::new(black_box(&plane), voxel, &src, dir, far);
            uniform(&[k - 1, k, k + 1].map(|t| Test { plane: rp, t }), u, v)
        })
    });
    let tri = triangle(0);
    g.bench_function("crosses_column", |b| b.iter(|| black_box(&tri).crosses_column(voxel[0] as i32, voxel[1] as i32)));
    // A surface facing the source 60.5 voxels above it (z* = 200.5), seen from column (110, 130).
    let floor = VisibleSurface {
        num: 401,
        den: 2,
        facet: 0,
        material: 0,
        normal: NormalCode::default(),
        plane: DexelPlane { id: 0, nx: 0, ny: 0, nz: -(16384 << 16), e: 8192 },
        z_v: 200,
    };
    assert!(target(110, 130, &floor, &src, far).is_some());
    g.bench_function("receiver_target", |b| b.iter(|| target(110, 130, black_box(&floor), &src, far)));
    g.finish();
}

criterion_group!(benches, bench_voxelize, bench_split, bench_skips, bench_fifo, bench_occluders, bench_shade);
criterion_main!(benches);
