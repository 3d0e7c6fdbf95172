//! Measures the ground methods on the shared KITTI scans, without labels: per frame the ground
//! and obstacle shares, the obstacle share against the drive's median, and the ego-corridor
//! false-obstacle share; optionally writes top views coloured by label.
//!
//! Run: `EVIGRID_SHARED=/work/shared cargo run --release -p evigrid-ground --example ground_eval
//! [-- --dump /tmp/ground] [--set name=value ...] [--frames]`.
//!
//! `--set` changes one [`GroundParams`] field (`sectors`, `max_slope`, `max_step_m`,
//! `max_slope_unseen`, `seed_band_m`, `min_obstacle_height_m`, `sensor_height_tolerance_m`, `outer_ring_width_m`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use ground::{GroundMethod, GroundParams, GroundSegmenter, PointLabel};

#[path = "../tests/common/mod.rs"]
mod common;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut dump: Option<PathBuf> = None;
    let mut per_frame = false;
    let mut params = GroundParams::default();
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        match arg.as_str() {
            "--dump" => dump = it.next().map(PathBuf::from),
            "--frames" => per_frame = true,
            "--set" => {
                let kv = it.next().ok_or("--set needs name=value")?;
                let (k, v) = kv.split_once('=').ok_or("--set needs name=value")?;
                let v: f64 = v.parse()?;
                match k {
                    "sectors" => params.sectors = v as usize,
                    "max_slope" => params.max_slope = v,
                    "max_step_m" => params.max_step_m = v,
                    "max_slope_unseen" => params.max_slope_unseen = v,
                    "seed_band_m" => params.seed_band_m = v,
                    "min_obstacle_height_m" => params.min_obstacle_height_m = v,
                    "sensor_height_tolerance_m" => params.sensor_height_tolerance_m = v,
                    // The width of the outermost zone's rings.
                    "outer_ring_width_m" => {
                        if let Some(zone) = params.ring_zones.last_mut() {
                            zone.ring_width_m = v;
                        }
                    }
                    _ => return Err(format!("unknown parameter {k}").into()),
                }
            }
            _ => return Err(format!("unknown argument {arg}").into()),
        }
    }
    for (name, paths) in [
        ("kitti-raw-0013", common::raw_0013_scans()),
        ("kitti-city-22", common::city_22_scans()),
    ] {
        let Some(paths) = paths else {
            eprintln!("{name}: shared data absent");
            continue;
        };
        let scans: Vec<Vec<[f32; 3]>> = paths
            .iter()
            .map(|p| common::read_points(p))
            .collect::<Result<_, _>>()?;
        for method in [
            GroundMethod::GlobalPlane,
            GroundMethod::FixedHeight,
            GroundMethod::LocalHeight,
        ] {
            let mut segmenter = GroundSegmenter::new(GroundParams {
                method,
                ..params.clone()
            })?;
            let mut frames = Vec::new();
            for (k, points) in scans.iter().enumerate() {
                let result = segmenter.segment(points);
                let measure = common::measure(points, result);
                if let Some(dir) = &dump {
                    std::fs::create_dir_all(dir)?;
                    let file = dir.join(format!("{name}-{method:?}-{k:02}.ppm"));
                    write_top_view(&file, points, result.labels())?;
                }
                frames.push(measure);
            }
            let summary = common::Summary::of(&frames);
            println!("{name} {method:?}: {summary}");
            if per_frame {
                let mut line = String::new();
                for f in &frames {
                    write!(
                        line,
                        " {:.1}/{:.1}/{:.1}/{:.2}/{:.2}/{:.2}",
                        100.0 * f.obstacle_share,
                        100.0 * f.far_obstacle_share,
                        100.0 * f.ground_share,
                        100.0 * f.corridor_false_obstacle_share,
                        100.0 * f.flat_obstacle_share,
                        100.0 * f.lifted_ground_share
                    )?;
                }
                println!(
                    "  obstacle%/beyond-5m-obstacle%/ground%/corridor-false%/flat-obstacle%/lifted-ground%:{line}"
                );
            }
        }
    }
    Ok(())
}

/// A 0.1 m/pixel top view, ±40 m around the sensor, x up: ground green, obstacle red,
/// overhanging blue, below ground yellow, invalid grey.
fn write_top_view(path: &Path, points: &[[f32; 3]], labels: &[PointLabel]) -> std::io::Result<()> {
    const SIZE: usize = 800;
    let mut image = vec![0u8; SIZE * SIZE * 3];
    // Obstacles last, so that they show over the ground beneath them.
    for pass in 0..2 {
        for (p, &label) in points.iter().zip(labels) {
            if (label == PointLabel::Obstacle) != (pass == 1) {
                continue;
            }
            let col = (SIZE as f32 / 2.0 - p[1] * 10.0) as isize;
            let row = (SIZE as f32 / 2.0 - p[0] * 10.0) as isize;
            if !(0..SIZE as isize).contains(&col) || !(0..SIZE as isize).contains(&row) {
                continue;
            }
            let rgb = match label {
                PointLabel::Ground => [40, 200, 40],
                PointLabel::Obstacle => [255, 40, 40],
                PointLabel::Overhanging => [60, 100, 255],
                PointLabel::BelowGround => [255, 255, 0],
                PointLabel::Invalid => [120, 120, 120],
            };
            let at = (row as usize * SIZE + col as usize) * 3;
            image[at..at + 3].copy_from_slice(&rgb);
        }
    }
    let mut bytes = format!("P6\n{SIZE} {SIZE}\n255\n").into_bytes();
    bytes.extend_from_slice(&image);
    std::fs::write(path, bytes)
}
