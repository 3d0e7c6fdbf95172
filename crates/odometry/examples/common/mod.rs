//! What the KITTI raw examples share: a drive's scans and its OXTS Velodyne poses.

use drive::kitti_raw::KittiRawDrive;
use drive::oxts::KittiMercator;
use nalgebra::Isometry3;

/// A KITTI raw drive read for the examples.
pub struct KittiDrive {
    /// The Velodyne's pose per scan from OXTS, in a frame centred on the first fix.
    pub reference: Vec<Isometry3<f64>>,
    /// Each scan's points (sensor frame) and time, read beforehand so that timings leave out
    /// the disk.
    pub scans: Vec<(Vec<[f32; 3]>, f64)>,
}

/// Opens the `*_sync` folder `dir` and reads its scans and OXTS poses.
pub fn read_drive(dir: &str) -> Result<KittiDrive, Box<dyn std::error::Error>> {
    let drive = KittiRawDrive::open(std::path::Path::new(dir))?;
    let frames = drive.frames();
    let first = frames.first().ok_or("no frames")?;
    let projection = KittiMercator::centered(first.oxts.lat_deg, first.oxts.lon_deg);
    let reference =
        drive.world_from_velodyne(&|lat: f64, lon: f64| projection.project(lat, lon))?;
    let scans = frames
        .iter()
        .map(|f| drive::read_scan(&f.scan_path).map(|s| (s.points_in_sensor, f.time_s)))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(KittiDrive { reference, scans })
}
