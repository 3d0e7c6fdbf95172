//! Odometry on a KITTI raw drive, against its OXTS poses: time per scan (scans read
//! beforehand, not timed) and relative errors over 10, 20 and 30 m.
//!
//! ```text
//! RAYON_NUM_THREADS=1 cargo run --release -p evigrid-odometry --example kitti_raw -- \
//!     <shared>/data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync \
//!     [--azimuth-times] [--vertical-offset DEG] [--min-range M]
//! ```

mod common;

use std::time::Instant;

use odometry::metrics::relative_errors;
use odometry::{Odometry, OdometryParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = args
        .next()
        .ok_or("usage: kitti_raw <drive_sync dir> [--azimuth-times] [--vertical-offset DEG] [--min-range M]")?;
    let mut params = OdometryParams::default();
    while let Some(flag) = args.next() {
        match flag.as_str() {
            "--azimuth-times" => params.azimuth_times = true,
            "--vertical-offset" => {
                params.vertical_angle_offset_deg =
                    args.next().ok_or("--vertical-offset DEG")?.parse()?
            }
            "--min-range" => params.min_range_m = args.next().ok_or("--min-range M")?.parse()?,
            other => return Err(format!("unknown flag {other}").into()),
        }
    }
    let common::KittiDrive {
        reference, scans, ..
    } = common::read_drive(&dir)?;
    let mut odometry = Odometry::new(params)?;
    let start = Instant::now();
    for (points, time_s) in &scans {
        odometry.register(points, *time_s)?;
    }
    let elapsed = start.elapsed();
    println!(
        "{} scans, {:.1} ms per scan",
        scans.len(),
        elapsed.as_secs_f64() * 1e3 / scans.len() as f64
    );
    let path_length = |poses: &[nalgebra::Isometry3<f64>]| -> f64 {
        poses
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum()
    };
    let (estimate, truth) = (odometry.poses(), &reference[..]);
    let end = |poses: &[nalgebra::Isometry3<f64>]| {
        poses
            .first()
            .map(|f| f.inverse())
            .zip(poses.last())
            .map(|(f, l)| f * l)
    };
    println!(
        "path: estimate {:.2} m, OXTS {:.2} m; end in first frame: estimate {:?}, OXTS {:?}",
        path_length(estimate),
        path_length(truth),
        end(estimate).map(|e| e.translation.vector.as_slice().to_vec()),
        end(truth).map(|e| e.translation.vector.as_slice().to_vec()),
    );
    let errors = relative_errors(odometry.poses(), &reference, &[10.0, 20.0, 30.0], 1)?;
    for length in [10.0, 20.0, 30.0] {
        let of = errors.of_length(length);
        println!(
            "{length:>4} m: {:>3} segments, translation {:.2} %, rotation {:.4} deg/m, heading {:.4} deg/m",
            of.segments.len(),
            of.mean_translation_pct().unwrap_or(f64::NAN),
            of.mean_rotation_deg_per_m().unwrap_or(f64::NAN),
            of.mean_heading_deg_per_m().unwrap_or(f64::NAN),
        );
    }
    println!(
        "all: translation {:.2} %, rotation {:.4} deg/m, heading {:.4} deg/m",
        errors.mean_translation_pct().unwrap_or(f64::NAN),
        errors.mean_rotation_deg_per_m().unwrap_or(f64::NAN),
        errors.mean_heading_deg_per_m().unwrap_or(f64::NAN),
    );
    Ok(())
}
