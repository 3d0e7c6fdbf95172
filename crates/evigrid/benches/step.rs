//! One full fusion step (SPEC §5) on 200 × 200 and 1000 × 1000 windows, single thread and all
//! threads, against two baselines:
//! - `copy`: a STREAM-like copy of the bytes a step must read and write (~145 bytes per cell each
//!   way), the memory floor;
//! - `naive_aos`: the same step written the obvious way, an array of cell structs and dense
//!   32 × 32 combinations (200 × 200 only: it is slow).
//!
//! Run: `cargo bench -p evigrid --bench step`.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use evigrid::{
    GisGrid, N_SETS, OMEGA, Params, PerceptionGrid, SensorGrid, class, prior_beta, prior_focal_set,
    step,
};
use geodata::MapContext;
use std::hint::black_box;

/// A scene with a realistic mix: a third of the cells seen free, a sixth occupied, the rest
/// unobserved; contexts in stripes.
fn scene(width: usize, height: usize) -> (PerceptionGrid, SensorGrid, GisGrid) {
    let pg = PerceptionGrid::new(width, height);
    let mut sg = SensorGrid::new(width, height);
    let mut gg = GisGrid::new(width, height);
    for idx in 0..width * height {
        match idx % 6 {
            0 | 1 => sg.m_free_mut()[idx] = 0.7,
            2 => sg.m_occupied_mut()[idx] = 0.8,
            _ => {}
        }
        gg.context[idx] = match (idx / 7) % 4 {
            0 => MapContext::Unknown,
            1 => MapContext::Other,
            2 => MapContext::Road,
            _ => MapContext::Building,
        };
    }
    (pg, sg, gg)
}

fn pools() -> Vec<(String, rayon::ThreadPool)> {
    let all = rayon::current_num_threads();
    [1, all]
        .into_iter()
        .filter_map(|n| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .ok()?;
            Some((format!("{n}_threads"), pool))
        })
        .collect()
}

fn bench_step(c: &mut Criterion) {
    let params = Params::default();
    let mut group = c.benchmark_group("step");
    group.sample_size(20);
    for (width, height) in [(200, 200), (1000, 1000)] {
        let cells = (width * height) as u64;
        group.throughput(Throughput::Elements(cells));
        let (mut pg, sg, gg) = scene(width, height);
        // Warm the grid up so that the masses are no longer trivially vacuous.
        for _ in 0..5 {
            step(&mut pg, &sg, &gg, &params, 0.1);
        }
        for (name, pool) in pools() {
            group.bench_function(
                BenchmarkId::new(format!("kernel/{name}"), format!("{width}x{height}")),
                |b| b.iter(|| pool.install(|| step(black_box(&mut pg), &sg, &gg, &params, 0.1))),
            );
        }
        // The memory floor: read and write the same number of bytes once.
        let source = vec![0.5_f32; 36 * width * height];
        let mut target = vec![0.0_f32; 36 * width * height];
        group.bench_function(
            BenchmarkId::new("copy/1_threads", format!("{width}x{height}")),
            |b| b.iter(|| target.copy_from_slice(black_box(&source))),
        );
        if width <= 200 {
            let mut naive = vec![NaiveCell::default(); width * height];
            group.bench_function(
                BenchmarkId::new("naive_aos/1_threads", format!("{width}x{height}")),
                |b| b.iter(|| naive_step(black_box(&mut naive), &sg, &gg, &params, 0.1)),
            );
        }
    }
    group.finish();
}

/// The baseline: one struct per cell, dense mass arrays, 32 × 32 combination loops.
#[derive(Clone, Copy)]
struct NaiveCell {
    m: [f32; N_SETS],
    zeta: f32,
    fo: f32,
    of: f32,
}

impl Default for NaiveCell {
    fn default() -> Self {
        let mut m = [0.0; N_SETS];
        m[OMEGA] = 1.0;
        NaiveCell {
            m,
            zeta: 0.0,
            fo: 0.0,
            of: 0.0,
        }
    }
}

fn conjunctive(a: &[f32; N_SETS], b: &[f32; N_SETS]) -> [f32; N_SETS] {
    let mut c = [0.0; N_SETS];
    for x in 0..N_SETS {
        for y in 0..N_SETS {
            c[x & y] += a[x] * b[y];
        }
    }
    c
}

fn naive_step(cells: &mut [NaiveCell], sg: &SensorGrid, gg: &GisGrid, p: &Params, dt: f64) {
    let rates = p.fusion.discount_per_second.as_array();
    let alpha: Vec<f32> = (0..N_SETS)
        .map(|set| {
            let members = if set == 0 { OMEGA } else { set };
            let r = (0..5)
                .filter(|k| members & (1 << k) != 0)
                .map(|k| rates[k])
                .fold(0.0, f64::max);
            (1.0 - (1.0 - r).powf(dt)) as f32
        })
        .collect();
    for (idx, cell) in cells.iter_mut().enumerate() {
        let mut r_sg = [0.0; N_SETS];
        r_sg[class::F] = sg.m_free()[idx];
        r_sg[class::O] = sg.m_occupied()[idx];
        r_sg[OMEGA] = 1.0 - sg.m_free()[idx] - sg.m_occupied()[idx];
        let context = gg.context[idx];
        let (g, beta) = (prior_focal_set(context), prior_beta(context, &p.map) as f32);
        let mut gm = [0.0; N_SETS];
        gm[g] += beta;
        gm[OMEGA] += 1.0 - beta;
        let mut sgp = conjunctive(&r_sg, &gm);
        let k = sgp[0];
        sgp[0] = 0.0;
        for v in &mut sgp {
            *v /= 1.0 - k;
        }
        let mut m = cell.m;
        for set in 0..OMEGA {
            let moved = alpha[set] * m[set];
            m[set] -= moved;
            m[OMEGA] += moved;
        }
        let occ = |x: &[f32; N_SETS]| {
            (1..N_SETS)
                .filter(|s| s & class::F == 0)
                .map(|s| x[s])
                .sum::<f32>()
        };
        let fo = m[class::F] * occ(&sgp);
        let of = occ(&m) * sgp[class::F];
        let mut c = conjunctive(&m, &sgp);
        c[class::M] += fo;
        c[OMEGA] += of + (c[0] - fo - of);
        c[0] = 0.0;
        let a = &p.accumulator;
        let conflict = fo + of;
        if occ(&c) >= a.gamma_occupied as f32 && conflict <= a.gamma_conflict as f32 {
            cell.zeta = (cell.zeta + a.delta_inc as f32).min(1.0);
        } else if conflict > a.gamma_conflict as f32 {
            cell.zeta = (cell.zeta - a.delta_dec as f32).max(0.0);
        }
        for set in 0..N_SETS {
            if set & class::M != 0 {
                let moved = cell.zeta * c[set];
                c[set] -= moved;
                c[set ^ class::M] += moved;
            }
        }
        c[OMEGA] += c[0];
        c[0] = 0.0;
        cell.m = c;
        cell.fo = fo;
        cell.of = of;
    }
}

criterion_group!(benches, bench_step);
criterion_main!(benches);
