//! Time to rasterise the whole of `helsinki-centre.osm.pbf` (1.0 × 1.7 km) into map contexts,
//! at 0.5 m (2026 × 3334 cells) and 0.2 m (5064 × 8334 cells), and to fill a 100 m × 100 m
//! window as a vehicle-following grid would, plus index construction.
//!
//! Baseline: the naive method — every polygon tested against every cell centre with
//! `geo::Contains` — is timed on a 20 m window for the ratio (it is too slow for the whole map).
//!
//! Run: `cargo bench -p evigrid-geodata --bench rasterise`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use geo::Contains;
use geodata::testdata::osm_file;
use geodata::{CellWindow, ContextRaster, LoadOptions, MapContext, load_map};

fn rasterise(c: &mut Criterion) {
    let Some(path) = osm_file("helsinki-centre.osm.pbf") else {
        return;
    };
    let loaded = match load_map(&path, &LoadOptions::default()) {
        Ok(loaded) => loaded,
        Err(error) => {
            eprintln!("cannot load {}: {error}", path.display());
            return;
        }
    };
    let mut group = c.benchmark_group("helsinki-centre");
    group.sample_size(10);
    group.bench_function("index construction", |b| {
        b.iter(|| ContextRaster::new(black_box(&loaded.map)))
    });
    let raster = ContextRaster::new(&loaded.map);
    for cell_size_m in [0.5, 0.2] {
        let window = CellWindow::covering(&raster.extent(), cell_size_m);
        let mut out = vec![MapContext::Unknown; window.len()];
        group.bench_function(
            format!(
                "whole map at {cell_size_m} m ({} x {} cells)",
                window.width, window.height
            ),
            |b| b.iter(|| raster.fill(black_box(&window), &mut out)),
        );
    }
    // A 100 m × 100 m window at 0.2 m in the dense centre.
    let window = CellWindow {
        first_col: -250,
        first_row: -250,
        width: 500,
        height: 500,
        cell_size_m: 0.2,
    };
    let mut out = vec![MapContext::Unknown; window.len()];
    group.bench_function("100 m window at 0.2 m (scanline)", |b| {
        b.iter(|| raster.fill(black_box(&window), &mut out))
    });
    // The ratio against the naive baseline on a 20 m × 20 m window (the baseline is too slow for
    // larger ones).
    let small = CellWindow {
        width: 100,
        height: 100,
        ..window
    };
    let mut out = vec![MapContext::Unknown; small.len()];
    group.bench_function("20 m window at 0.2 m (scanline)", |b| {
        b.iter(|| raster.fill(black_box(&small), &mut out))
    });
    group.bench_function(
        "20 m window at 0.2 m (naive baseline: every polygon x every cell)",
        |b| b.iter(|| naive_fill(&loaded.map, &small, &mut out)),
    );
    group.finish();
}

/// The baseline: for each cell centre, test every polygon with `geo::Contains`.
fn naive_fill(map: &geodata::LocalMap, window: &CellWindow, out: &mut [MapContext]) {
    for row in 0..window.height {
        for col in 0..window.width {
            let (x, y) =
                window.cell_centre(window.first_col + col as i64, window.first_row + row as i64);
            let centre = geo::point!(x: x, y: y);
            out[row * window.width + col] = if map.buildings.iter().any(|p| p.contains(&centre)) {
                MapContext::Building
            } else if map.roads.iter().any(|p| p.contains(&centre)) {
                MapContext::Road
            } else {
                MapContext::Other
            };
        }
    }
}

criterion_group!(benches, rasterise);
criterion_main!(benches);
