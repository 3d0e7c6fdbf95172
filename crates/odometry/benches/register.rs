//! Time per scan of the odometry on the shared KITTI raw scans (40 HDL-64 scans at ~10 m/s).
//!
//! `RAYON_NUM_THREADS=1 cargo bench -p evigrid-odometry --bench register` for one core. Skipped
//! when the shared data is absent.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use odometry::{Odometry, OdometryParams};

const SCANS: &str =
    "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync/velodyne_points/data";

fn register_sequence(c: &mut Criterion) {
    let Some(dir) = geodata::testdata::shared_file(SCANS) else {
        return;
    };
    let Ok(paths) = drive::list_scans(&dir) else {
        eprintln!("note: cannot list {}; skipping", dir.display());
        return;
    };
    let scans: Vec<Vec<[f32; 3]>> = paths
        .iter()
        .filter_map(|path| drive::read_scan(path).ok())
        .map(|scan| scan.points_in_sensor)
        .collect();
    let mut group = c.benchmark_group("odometry");
    group.sample_size(10);
    // Per element: the time of one scan within the sequence.
    group.throughput(Throughput::Elements(scans.len() as u64));
    group.bench_function("kitti_raw_0013_40_scans", |b| {
        b.iter(|| {
            let mut odometry =
                Odometry::new(OdometryParams::default()).expect("default params are valid");
            for (index, points) in scans.iter().enumerate() {
                let pose = odometry.register(black_box(points), index as f64 * 0.1);
                black_box(pose.expect("increasing times"));
            }
        });
    });
    group.finish();
}

criterion_group!(benches, register_sequence);
criterion_main!(benches);
