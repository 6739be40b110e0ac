//! Criterion benchmarks of the whole grid: loading a small scene with the RC² wave
//! (`Grid::load_wave`, beside the direct host path `Grid::load_direct`) and a whole diffusion
//! of one light over a small Cornell box (`diffuse`), from which the cost of one grid cycle
//! and of one processed beam follow (the bench prints cycles and beams per run).
//!
//! `cargo bench -p host-sim` (results in BENCHMARKS.md). Not part of `cargo test`.

use std::hint::black_box;
use std::time::Duration;

use cell_core::cell::DEFAULT_DEXELS;
use cell_core::light::Policy;
use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion, Throughput};
use host_sim::machine::grid::Grid;
use host_sim::machine::lighting::diffuse::{diffuse, source_at, LightConfig};
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights};
use host_sim::precompute::{prepare, LoadConfig};
use host_sim::scene;

fn bench_load(c: &mut Criterion) {
    let mut g = c.benchmark_group("load");
    g.sample_size(20).measurement_time(Duration::from_secs(4));
    for (name, n) in [("cornell", 64u32), ("teapot", 64), ("teapot", 128)] {
        let mesh = scene::load(name).expect("built-in scene");
        let cfg = LoadConfig::watertight(n);
        let prepared = prepare(&mesh, &cfg).expect("prepares");
        let packets = &prepared.packets;
        g.throughput(Throughput::Elements(packets.len() as u64));
        let id = format!("{name}_n{n}_{}facets", packets.len());
        g.bench_function(BenchmarkId::new("prepare", &id), |b| b.iter(|| prepare(black_box(&mesh), &cfg)));
        g.bench_function(BenchmarkId::new("load_wave", &id), |b| {
            b.iter_batched_ref(
                || Grid::<DEFAULT_DEXELS>::new(n, n),
                |grid| grid.load_wave(black_box(packets), |_| {}),
                BatchSize::LargeInput,
            )
        });
        g.bench_function(BenchmarkId::new("load_direct", &id), |b| {
            b.iter_batched_ref(
                || Grid::<DEFAULT_DEXELS>::new(n, n),
                |grid| grid.load_direct(black_box(packets), |_| {}),
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

fn bench_diffuse(c: &mut Criterion) {
    let mut g = c.benchmark_group("diffuse");
    g.sample_size(10).measurement_time(Duration::from_secs(6));
    let mesh = scene::load("cornell").expect("built-in scene");
    for n in [32u32, 64] {
        // The render defaults: naive + projected surfaces, f = 0, FA = 16, wavefront + merge.
        let cfg = LoadConfig::thin(n);
        let loaded = load_scene(&mesh, &cfg).expect("loads");
        let lights = resolve_lights(&mesh, &loaded, &[]).expect("the Cornell box has its light");
        let sources: Vec<_> = lights.iter().enumerate().map(|(i, p)| source_at(i, *p, n).expect("inside")).collect();
        for (pname, policy) in [("wavefront", Policy::Wavefront), ("thesis", Policy::Thesis)] {
            let lcfg = LightConfig {
                fa: 16,
                policy,
                merge: policy.by_layer(),
                record_visits: false,
                ..host_sim::config::plane_rule()
            };
            let once = diffuse(&loaded.grid, &sources, &lcfg, |_, _| {}).expect("diffuses");
            let r = &once.reports[0].counts;
            eprintln!(
                "diffuse cornell n = {n} {pname}: {} cycles, {} beams processed, {} messages, peak {} active cells",
                r.cycles, r.beams_processed, r.messages, r.peak_active_cells
            );
            g.throughput(Throughput::Elements(r.cycles));
            let id = format!("cornell_n{n}_{}cycles_{}beams", r.cycles, r.beams_processed);
            g.bench_function(BenchmarkId::new(pname, id), |b| {
                b.iter(|| diffuse(black_box(&loaded.grid), &sources, &lcfg, |_, _| {}))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench_load, bench_diffuse);
criterion_main!(benches);
