//! The motion stage of the `evigrid` fusion variant against the SPEC §5 step it follows, on
//! the real 1000 × 1000 case of `evigrid bench`: a KITTI scan (`kitti-raw-0013`, frame 0,
//! 120k points, 360°) driven 1 m east per frame at 10 Hz through a 1000 × 1000 window of
//! 0.5 m cells. Everything in the scene is static, so every cluster is registered against
//! eight past frames: the stage's full work.
//!
//! Timed per frame (the front end runs untimed before each): `update/kurdej2013`, the paper's
//! fusion (step and decision); `update/evigrid`, the same plus the motion stage. The ratio
//! motion / step is printed from the stages' own clocks over the frames run.
//!
//! Run: `EVIGRID_SHARED=/work/shared cargo bench -p evigrid --bench motion`.

use criterion::{Criterion, criterion_group, criterion_main};
use evigrid::IsometryMatrix3;
use evigrid::Params;
use evigrid::PoseExt;
use evigrid::{FrontEnd, Fusion, Method, Prior};
use std::path::PathBuf;
use std::time::{Duration, Instant};

const SCAN: &str = "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync/velodyne_points/data/0000000000.bin";
/// KITTI's velodyne height above the road, m.
const SENSOR_HEIGHT_M: f64 = 1.73;

fn bench_motion(c: &mut Criterion) {
    let shared =
        PathBuf::from(std::env::var("EVIGRID_SHARED").unwrap_or_else(|_| "../shared".into()));
    let Ok(scan) = drive::read_scan(&shared.join(SCAN)) else {
        eprintln!(
            "{} not found: set EVIGRID_SHARED; motion bench skipped",
            SCAN
        );
        return;
    };
    let mut params = Params::default();
    (params.window.width_cells, params.window.height_cells) = (1000, 1000);
    let mut group = c.benchmark_group("motion");
    group.sample_size(20);
    for method in [Method::Kurdej2013, Method::Evigrid] {
        let (Ok(mut front_end), Ok(mut fusion)) = (
            FrontEnd::new(&params, None),
            Fusion::with_method(params.clone(), Prior::Map, method),
        ) else {
            return;
        };
        let mut frame = 0u32;
        let (mut step_ms, mut motion_ms, mut frames) = (0.0, 0.0, 0u32);
        let name = match method {
            Method::Kurdej2013 => "update/kurdej2013",
            Method::Evigrid => "update/evigrid",
        };
        group.bench_function(name, |b| {
            b.iter_custom(|iterations| {
                let mut spent = Duration::ZERO;
                for _ in 0..iterations {
                    let x_m = f64::from(frame);
                    let pose =
                        IsometryMatrix3::from_xyz_rpy(x_m, 0.0, SENSOR_HEIGHT_M, 0.0, 0.0, 0.0);
                    let time_s = 0.1 * f64::from(frame);
                    frame += 1;
                    if front_end
                        .process(&scan.points_in_sensor, &pose, time_s)
                        .is_err()
                    {
                        continue;
                    }
                    let start = Instant::now();
                    if let Ok(stats) = fusion.update(&front_end) {
                        spent += start.elapsed();
                        // The first eight frames fill the history; count the rest.
                        if frame > 8 {
                            step_ms += stats.step_ms;
                            motion_ms += stats.motion.map_or(0.0, |m| m.ms);
                            frames += 1;
                        }
                    }
                }
                spent
            });
        });
        if method == Method::Evigrid && frames > 0 {
            let n = f64::from(frames);
            eprintln!(
                "motion/step over {frames} frames: motion {:.2} ms, step {:.2} ms a frame, ratio {:.2}",
                motion_ms / n,
                step_ms / n,
                motion_ms / step_ms
            );
        }
    }
    group.finish();
}

criterion_group!(benches, bench_motion);
criterion_main!(benches);
