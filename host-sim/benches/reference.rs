//! Criterion benchmarks of the f64 ground truth (`host_sim::truth::visibility`,
//! `host_sim::truth::refrender`): building the BVH, visibility and first-hit queries between
//! random points of a scene's box, and the whole reference image of the Cornell box (what
//! `render --reference` adds). They replace the former `#[ignore]`d timing tests of
//! `truth::visibility` and `truth::refrender`.
//!
//! `cargo bench -p host-sim --bench reference` (results in BENCHMARKS.md). Not part of
//! `cargo test`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use host_sim::truth::refrender::{mesh_triangles, render_reference, RefLight};
use host_sim::truth::visibility::Reference;

/// Query pairs per measured iteration.
const QUERIES: usize = 10_000;

/// `count` pairs of points drawn uniformly in the box `[lo, hi]` (reproducible: seed `seed`).
fn points(lo: [f64; 3], hi: [f64; 3], count: usize, seed: u64) -> Vec<([f64; 3], [f64; 3])> {
    let mut rng = host_sim::rng::Rng(seed);
    let mut p = move || [0, 1, 2].map(|k| rng.range(lo[k], hi[k]));
    (0..count).map(|_| (p(), p())).collect()
}

fn bench_queries(c: &mut Criterion) {
    let mut g = c.benchmark_group("reference");
    g.sample_size(20).measurement_time(Duration::from_secs(4));
    for name in ["cornell", "fandisk"] {
        let mesh = host_sim::scene::load(name).expect("built-in scene");
        let (tris, facets) = mesh_triangles(&mesh).expect("valid mesh");
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in tris.iter().flatten() {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let id = format!("{name}_{}tris", tris.len());
        g.throughput(Throughput::Elements(tris.len() as u64));
        g.bench_function(BenchmarkId::new("build", &id), |b| {
            b.iter(|| Reference::new(black_box(tris.clone()), facets.clone()))
        });
        let r = Reference::new(tris.clone(), facets.clone()).expect("builds");
        let pts = points(lo, hi, QUERIES, 9);
        g.throughput(Throughput::Elements(QUERIES as u64));
        g.bench_function(BenchmarkId::new("visible", &id), |b| {
            b.iter(|| pts.iter().filter(|(a, e)| r.visible(*a, *e, &[])).count())
        });
        g.bench_function(BenchmarkId::new("first_hit", &id), |b| {
            b.iter(|| {
                pts.iter()
                    .filter(|(a, e)| r.first_hit(*a, [0, 1, 2].map(|k| e[k] - a[k]), f64::INFINITY, &[]).is_some())
                    .count()
            })
        });
    }
    g.finish();
}

fn bench_image(c: &mut Criterion) {
    let mut g = c.benchmark_group("reference_image");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    let mesh = host_sim::scene::load("cornell").expect("built-in scene");
    for n in [128u32, 512] {
        let fit = host_sim::precompute::fit(&mesh, n).expect("fits");
        // The Cornell light (centre of the light quad, two voxels below the ceiling), voxel units.
        let wpos = [278.0, 548.8, 279.5];
        let mut pos = [0, 1, 2].map(|i| (wpos[i] - fit.origin[i]) / fit.voxel - 0.5);
        pos[1] -= 2.0;
        let light = RefLight { pos, color: [1.0; 3] };
        g.throughput(Throughput::Elements(u64::from(n) * u64::from(n)));
        g.bench_function(BenchmarkId::new("cornell", n), |b| {
            b.iter(|| render_reference(&mesh, &fit, n, &[light], [0.1; 3]))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_queries, bench_image);
criterion_main!(benches);
