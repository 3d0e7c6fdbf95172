//! One real HDL-64E scan segmented by the local method against the global-plane baseline (the
//! sensor model's historical ground model), on one thread and on all threads.
//!
//! Run: `EVIGRID_SHARED=../shared cargo bench -p evigrid-ground --bench segment`. Skips (with a
//! note) when the shared scans are absent.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ground::{GroundMethod, GroundParams, GroundSegmenter};
use std::hint::black_box;

#[path = "../tests/common/mod.rs"]
mod common;

fn scans() -> Vec<(&'static str, Vec<[f32; 3]>)> {
    let mut out = Vec::new();
    // Frame 30 of raw 0013: the wall alongside, a slope; frame 0 of the city street.
    let picks = [
        (
            "raw0013_f30",
            common::raw_0013_scans().and_then(|p| p.get(30).cloned()),
        ),
        (
            "city22_f0",
            common::city_22_scans().and_then(|p| p.first().cloned()),
        ),
    ];
    for (name, path) in picks {
        if let Some(points) = path.and_then(|p| common::read_points(&p).ok()) {
            out.push((name, points));
        }
    }
    out
}

fn bench_segment(c: &mut Criterion) {
    let scans = scans();
    if scans.is_empty() {
        eprintln!("note: shared scans absent; nothing to bench (set EVIGRID_SHARED)");
        return;
    }
    let mut group = c.benchmark_group("segment");
    group.sample_size(30);
    let all = rayon::current_num_threads();
    for (name, points) in &scans {
        group.throughput(Throughput::Elements(points.len() as u64));
        for method in [GroundMethod::LocalHeight, GroundMethod::GlobalPlane] {
            for threads in [1, all] {
                let Ok(pool) = rayon::ThreadPoolBuilder::new().num_threads(threads).build() else {
                    continue;
                };
                let Ok(mut segmenter) = GroundSegmenter::new(GroundParams {
                    method,
                    ..GroundParams::default()
                }) else {
                    continue;
                };
                let id = BenchmarkId::new(format!("{method:?}/{threads}_threads"), name);
                group.bench_function(id, |b| {
                    b.iter(|| {
                        pool.install(|| segmenter.segment(black_box(points)).stats().obstacle)
                    })
                });
                if threads == all {
                    break;
                }
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_segment);
criterion_main!(benches);
