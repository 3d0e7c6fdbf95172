//! A scan and a map through the pipeline to a decision, the way an application embeds evigrid.
//!
//! ```text
//! cargo run --release -p evigrid --example scan_and_map -- MAP SCAN [X Y YAW]
//! cargo run --release -p evigrid --example scan_and_map -- \
//!     ../shared/data/osm/bavarian-village.osm ../shared/data/lidar/kitti-city-22/0000000000.pcd
//! ```
//!
//! The sensor is placed at `X Y` (metres east and north of the map's centre, default 0 0) with
//! heading `YAW` (radians from east). The same scan is fed three times, 0.1 s apart, as a parked
//! vehicle would see it; the counts of decided cells are printed.

use std::path::PathBuf;

use evigrid::{IsometryMatrix3, Label, Params, Pipeline, PoseExt};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [map_path, scan_path, rest @ ..] = args.as_slice() else {
        return Err("usage: scan_and_map MAP SCAN [X Y YAW]".into());
    };
    let number = |i: usize| -> Result<f64, Box<dyn std::error::Error>> {
        Ok(rest.get(i).map(|s| s.parse()).transpose()?.unwrap_or(0.0))
    };
    let (x_m, y_m, yaw) = (number(0)?, number(1)?, number(2)?);

    // The map becomes a per-cell context raster in a local metric frame (SPEC §4).
    let loaded = geodata::load_map(
        PathBuf::from(map_path),
        &geodata::LoadOptions { origin: None },
    )?;
    let raster = geodata::ContextRaster::new(&loaded.map);
    // The scan: points in the sensor frame (x forward, y left, z up).
    let scan = drive::read_scan(&PathBuf::from(scan_path))?;

    let mut pipeline = Pipeline::new(Params::default(), Some(raster))?;
    // A roof lidar 1.73 m above the road.
    let world_from_sensor = IsometryMatrix3::from_xyz_rpy(x_m, y_m, 1.73, 0.0, 0.0, yaw);
    for frame in 0..3 {
        let stats = pipeline.process(
            &scan.points_in_sensor,
            &world_from_sensor,
            0.1 * frame as f64,
        )?;
        eprintln!(
            "frame {frame}: sensor model {:.1} ms, step {:.1} ms",
            stats.sensor_ms, stats.step_ms
        );
    }

    for label in Label::ALL {
        let count = pipeline.decisions().iter().filter(|&&d| d == label).count();
        println!("{:>9} {count}", label.name());
    }
    Ok(())
}
