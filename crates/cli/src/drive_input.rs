//! Scans and the poses that place them, as `evigrid run` and `evigrid odometry` are given them.
//!
//! The rule that matches poses to scans (README, "Pose files"):
//! - scan times come from a KITTI raw drive, from `--times`, or from a `timestamps.txt` beside
//!   the scan folder (KITTI raw's `velodyne_points/{data/, timestamps.txt}`) or inside it (or a
//!   `times.txt`);
//! - with scan times, each scan takes the pose interpolated at its time (linear position, slerp
//!   rotation); a scan outside the poses' span is an error naming it;
//! - without scan times, pose line k goes with scan k (the counts must agree) and the scan's time
//!   is the line's; a format without times (KITTI odometry), or poses from the odometry, take the
//!   scans [`DEFAULT_SCAN_PERIOD_S`] apart from 0.

use std::path::{Path, PathBuf};

use anyhow::Result;
use drive::poses::{
    KittiOdometryContext, Mounting, PoseFormat, PoseTrack, read_pose_track, read_scan_times,
};
use drive::{KittiRawDrive, list_scans, read_scan};
use nalgebra::Isometry3;
use odometry::{Odometry, OdometryParams};

use crate::exit::BadInput;

/// Time between scans that have no timestamps: the 10 Hz of spinning lidars.
pub const DEFAULT_SCAN_PERIOD_S: f64 = 0.1;

/// The scans of a drive, in order, with their times when known.
pub struct ScanSet {
    /// Scan files in frame order.
    pub paths: Vec<PathBuf>,
    /// One time per scan (seconds), when the drive gives them.
    pub times: Option<Vec<f64>>,
    /// Where the times came from, for messages.
    pub times_source: Option<PathBuf>,
    /// The KITTI raw drive, when the scans are one.
    pub kitti: Option<KittiRawDrive>,
    /// The folder given, for messages.
    pub dir: PathBuf,
}

impl ScanSet {
    /// Scan times, or [`DEFAULT_SCAN_PERIOD_S`] apart from 0 when the scans have none.
    pub fn times_or_period(&self) -> Vec<f64> {
        match &self.times {
            Some(times) => times.clone(),
            None => (0..self.paths.len())
                .map(|k| k as f64 * DEFAULT_SCAN_PERIOD_S)
                .collect(),
        }
    }

    /// Keeps the scans at `indices` (increasing), with their times.
    pub fn keep(&mut self, indices: &[usize]) {
        self.paths = indices.iter().map(|&k| self.paths[k].clone()).collect();
        if let Some(times) = &mut self.times {
            *times = indices.iter().map(|&k| times[k]).collect();
        }
    }

    /// Keeps the first `n` scans.
    pub fn truncate(&mut self, n: usize) {
        self.paths.truncate(n);
        if let Some(times) = &mut self.times {
            times.truncate(n);
        }
    }
}

/// Opens a KITTI raw drive (its `*_sync` folder or the date folder holding one).
pub fn open_kitti_raw(dir: &Path) -> Result<ScanSet> {
    let drive = KittiRawDrive::open(dir).map_err(|e| BadInput::new(e.to_string()))?;
    let paths = drive.frames().into_iter().map(|f| f.scan_path).collect();
    Ok(ScanSet {
        paths,
        times: Some(drive.scan_times().to_vec()),
        times_source: Some(drive.drive_dir().join("velodyne_points/timestamps.txt")),
        dir: dir.to_path_buf(),
        kitti: Some(drive),
    })
}

/// Opens a folder of scans (PCD or KITTI `.bin`); a folder holding no scan but a KITTI raw drive
/// is opened as one. `times` overrides the timestamps found beside the scans.
pub fn open_scans(dir: &Path, times: Option<&Path>) -> Result<ScanSet> {
    let paths = list_scans(dir).map_err(|e| BadInput::new(e.to_string()))?;
    if paths.is_empty() {
        let looks_like_kitti = dir.join("velodyne_points").is_dir()
            || std::fs::read_dir(dir).is_ok_and(|entries| {
                entries.flatten().any(|e| {
                    e.path().is_dir() && e.file_name().to_string_lossy().ends_with("_sync")
                })
            });
        if looks_like_kitti && times.is_none() {
            return open_kitti_raw(dir);
        }
        return Err(BadInput::new(format!(
            "{}: no .pcd or .bin scans in this directory",
            dir.display()
        )));
    }
    let found = match times {
        Some(path) => Some(path.to_path_buf()),
        None => beside(dir),
    };
    let times = match &found {
        Some(path) => {
            let times = read_scan_times(path).map_err(|e| BadInput::new(e.to_string()))?;
            if times.len() != paths.len() {
                return Err(BadInput::new(format!(
                    "{}: {} times for {} scans in {} (one time per scan)",
                    path.display(),
                    times.len(),
                    paths.len(),
                    dir.display()
                )));
            }
            Some(times)
        }
        None => None,
    };
    Ok(ScanSet {
        paths,
        times,
        times_source: found,
        kitti: None,
        dir: dir.to_path_buf(),
    })
}

/// A timestamps file where KITTI puts one: `timestamps.txt` beside a `data` folder, or
/// `timestamps.txt` / `times.txt` inside the scan folder.
fn beside(dir: &Path) -> Option<PathBuf> {
    let mut candidates = Vec::new();
    if dir.file_name().is_some_and(|n| n == "data")
        && let Some(parent) = dir.parent()
    {
        candidates.push(parent.join("timestamps.txt"));
    }
    candidates.push(dir.join("timestamps.txt"));
    candidates.push(dir.join("times.txt"));
    candidates.into_iter().find(|p| p.is_file())
}

/// How a pose file is to be read.
pub struct PoseFileOptions<'a> {
    /// The file.
    pub path: &'a Path,
    /// Its format; detected from the column count when `None`.
    pub format: Option<PoseFormat>,
    /// KITTI odometry `calib.txt` (its `Tr`); the identity without one.
    pub calib: Option<&'a Path>,
    /// Vehicle → sensor, when the file gives the vehicle's poses.
    pub mounting: Option<Mounting>,
}

/// One pose per scan: `world_from_sensor` at the scan's time.
pub struct ScanPoses {
    /// One time per scan.
    pub times: Vec<f64>,
    /// One pose per scan.
    pub world_from_sensor: Vec<Isometry3<f64>>,
}

/// Reads a pose file and gives every scan its pose by the module's rule. With scan times, only
/// the first `required` scans must lie in the poses' span: the poses of the others, up to the
/// first outside it, are still given (the ego's path ahead).
pub fn poses_from_file(
    scans: &ScanSet,
    options: &PoseFileOptions<'_>,
    projection: Option<&dyn Fn(f64, f64) -> (f64, f64)>,
    required: usize,
) -> Result<ScanPoses> {
    let path = options.path;
    let bad = |e: &dyn std::fmt::Display| BadInput::new(e.to_string());
    let format = match options.format {
        Some(format) => format,
        None => PoseFormat::detect(path).map_err(|e| bad(&e))?,
    };
    let cam0_from_velo = match options.calib {
        Some(calib) => drive::calib::read_odometry_cam0_from_velo(calib).map_err(|e| bad(&e))?,
        None => Isometry3::identity(),
    };
    let line_times = scans.times_or_period();
    let kitti = KittiOdometryContext {
        times: &line_times,
        cam0_from_velo,
    };
    if format == PoseFormat::KittiOdometry {
        check_count(
            path,
            count_pose_lines(path)?,
            scans,
            "KITTI odometry poses have no times: one line per scan",
        )?;
    }
    let no_projection = projection.is_none();
    let track = read_pose_track(path, Some(format), Some(&kitti), projection).map_err(|e| {
        let message = e.to_string();
        if no_projection && message.contains("need a projection") {
            BadInput::new(format!(
                "{message}: WGS84 poses need --map or --origin (or a KITTI raw --drive)"
            ))
        } else {
            BadInput::new(message)
        }
    })?;
    let track = match &options.mounting {
        Some(mounting) => mounting.apply(&track),
        None => track,
    };
    if scans.times.is_none() {
        // Line order: pose k is scan k's.
        check_count(
            path,
            track.len(),
            scans,
            "without scan timestamps, pose line k goes with scan k",
        )?;
        let (times, poses) = track.into_parts();
        return Ok(ScanPoses {
            times,
            world_from_sensor: poses,
        });
    }
    at_scan_times(scans, &track, path, required)
}

/// Data lines of a file (for the count a KITTI odometry file must have).
fn count_pose_lines(path: &Path) -> Result<usize> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| BadInput::new(format!("{}: {e}", path.display())))?;
    Ok(text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .count())
}

fn check_count(path: &Path, poses: usize, scans: &ScanSet, why: &str) -> Result<()> {
    if poses == scans.paths.len() {
        return Ok(());
    }
    Err(BadInput::new(format!(
        "{}: {poses} poses for {} scans in {} ({why})",
        path.display(),
        scans.paths.len(),
        scans.dir.display()
    )))
}

/// Every scan's pose interpolated at its time; the first of the `required` first scans outside
/// the span is an error naming it, later scans end the list there.
fn at_scan_times(
    scans: &ScanSet,
    track: &PoseTrack,
    source: &Path,
    required: usize,
) -> Result<ScanPoses> {
    let mut times = scans.times.clone().unwrap_or_default();
    let mut poses = Vec::with_capacity(times.len());
    for (k, (scan, &t)) in scans.paths.iter().zip(&times).enumerate() {
        if k >= required && track.at(t).is_err() {
            break;
        }
        let pose = track.at(t).map_err(|e| {
            BadInput::new(format!(
                "scan {} (time from {}): {e} of {}",
                scan.display(),
                scans
                    .times_source
                    .as_deref()
                    .unwrap_or(Path::new("?"))
                    .display(),
                source.display()
            ))
        })?;
        poses.push(pose);
    }
    times.truncate(poses.len());
    Ok(ScanPoses {
        times,
        world_from_sensor: poses,
    })
}

/// The Velodyne's poses from a KITTI raw drive's OXTS packets and calibration.
pub fn poses_from_oxts(
    drive: &KittiRawDrive,
    projection: &dyn Fn(f64, f64) -> (f64, f64),
) -> Result<ScanPoses> {
    let poses = drive
        .world_from_velodyne(projection)
        .map_err(|e| BadInput::new(e.to_string()))?;
    Ok(ScanPoses {
        times: drive.scan_times().to_vec(),
        world_from_sensor: poses,
    })
}

/// Poses from the scans alone: the lidar odometry over every scan, in the first scan's frame.
/// `tick` is called after each scan, with the odometry (its last report says how the scan went).
/// Unreadable scans are skipped into `skipped` and left out of `scans` (an error if `strict`);
/// `stop_requested` is polled before each scan (a signal ends the pass with
/// [`Interrupted`](crate::interrupt::Interrupted)).
pub fn poses_from_odometry(
    scans: &mut ScanSet,
    params: OdometryParams,
    strict: bool,
    skipped: &mut Vec<(PathBuf, String)>,
    stop_requested: &dyn Fn() -> bool,
    mut tick: impl FnMut(&Odometry),
) -> Result<ScanPoses> {
    let times = scans.times_or_period();
    let mut odometry = Odometry::new(params).map_err(|e| BadInput::new(e.to_string()))?;
    let mut poses = Vec::with_capacity(times.len());
    let mut kept = Vec::with_capacity(times.len());
    for (k, (path, &t)) in scans.paths.iter().zip(&times).enumerate() {
        if stop_requested() {
            return Err(crate::interrupt::Interrupted.into());
        }
        // An unreadable scan is left out (the next registration spans the gap, as the
        // constant-velocity prediction allows) unless `strict`.
        let pose = read_scan(path).map_err(|e| e.to_string()).and_then(|scan| {
            odometry
                .register(&scan.points_in_sensor, t)
                .map_err(|e| format!("{}: {e}", path.display()))
        });
        match pose {
            Ok(pose) => {
                poses.push(pose);
                kept.push(k);
            }
            Err(error) if strict => return Err(BadInput::new(error)),
            Err(error) => skipped.push((path.clone(), error)),
        }
        tick(&odometry);
    }
    scans.keep(&kept);
    Ok(ScanPoses {
        times: kept.iter().map(|&k| times[k]).collect(),
        world_from_sensor: poses,
    })
}

/// Opens a ROS 2 recording as a drive.
pub fn open_bag(
    path: &Path,
    cloud_topic: Option<String>,
    pose_source: Option<&str>,
) -> Result<drive::bag::BagDrive> {
    let pose_source = match pose_source {
        Some(text) => text
            .parse()
            .map_err(|e: String| BadInput::new(format!("--pose-source: {e}")))?,
        None => drive::bag::PoseSource::Auto,
    };
    let options = drive::bag::BagOptions {
        cloud_topic,
        pose_source,
    };
    drive::bag::BagDrive::open(path, &options).map_err(|e| BadInput::new(e.to_string()))
}

/// The scans of a recording as a [`ScanSet`]: one name per PointCloud2 message (`<bag>#k`, for
/// messages and the summary) and the header stamps as times; the points are read by the run
/// from the recording itself, in order.
pub fn bag_scan_set(bag: &drive::bag::BagDrive) -> ScanSet {
    let times = bag.scan_times().to_vec();
    let stem = bag
        .path()
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let paths = (0..times.len())
        .map(|k| PathBuf::from(format!("{stem}#{k:06}")))
        .collect();
    ScanSet {
        paths,
        times: Some(times),
        times_source: Some(bag.path().to_path_buf()),
        kitti: None,
        dir: bag.path().to_path_buf(),
    }
}

/// Reads a run's scans in frame order: scan files by path, or a recording's PointCloud2
/// messages as they come (memory does not grow with the recording).
pub enum ScanReader {
    /// PCD / KITTI `.bin` files.
    Files,
    /// The messages of a recording; the paths are only names.
    Bag(Box<drive::bag::BagScans>),
}

impl ScanReader {
    /// A reader of files, or of `bag`'s scans from its first.
    pub fn new(bag: Option<&drive::bag::BagDrive>) -> Result<Self> {
        Ok(match bag {
            Some(bag) => Self::Bag(Box::new(
                bag.scans().map_err(|e| BadInput::new(e.to_string()))?,
            )),
            None => Self::Files,
        })
    }

    /// The next scan, named `path`; the error as the message a skipped scan records.
    pub fn read(&mut self, path: &Path) -> std::result::Result<drive::Scan, String> {
        match self {
            Self::Files => read_scan(path).map_err(|e| e.to_string()),
            Self::Bag(scans) => match scans.next() {
                Some(scan) => scan.map(|s| s.scan).map_err(|e| e.to_string()),
                None => Err(format!("{}: the recording ended early", path.display())),
            },
        }
    }
}

/// The poses of a recording (tf, odometry or NavSatFix) at its scans' times. `projection`
/// places NavSatFix fixes; only the first `required` scans must lie in the poses' span.
pub fn poses_from_bag(
    bag: &drive::bag::BagDrive,
    projection: Option<&dyn Fn(f64, f64) -> (f64, f64)>,
    required: usize,
) -> Result<ScanPoses> {
    let bad = |e: String| BadInput::new(format!("{}: {e}", bag.path().display()));
    let unplaced = |_: f64, _: f64| (f64::NAN, f64::NAN);
    let track = match (bag.poses(), projection) {
        (drive::bag::BagPoses::Wgs84(_), None) => {
            return Err(bad(format!(
                "poses from NavSatFix ({}) need --map or --origin",
                bag.pose_source()
            )));
        }
        (poses, Some(projection)) => poses.track(projection),
        (poses, None) => poses.track(&unplaced),
    }
    .map_err(|e| bad(e.to_string()))?
    .ok_or_else(|| bad("the recording has no poses".into()))?;
    let times: Vec<f64> = bag.scan_times().iter().copied().take(required).collect();
    let world_from_sensor = times
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            track
                .at(t)
                .map_err(|e| bad(format!("scan {k} (time {t:.6} s): {e}")))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(ScanPoses {
        times,
        world_from_sensor,
    })
}

/// Poses of a recording's first `count` scans from the lidar odometry (a first pass over the
/// recording). A message that cannot be read ends the pass: the poses would lose their
/// correspondence with the messages.
pub fn poses_from_bag_odometry(
    bag: &drive::bag::BagDrive,
    params: OdometryParams,
    count: usize,
    stop_requested: &dyn Fn() -> bool,
    mut tick: impl FnMut(&Odometry),
) -> Result<ScanPoses> {
    let bad = |e: String| BadInput::new(format!("{}: {e}", bag.path().display()));
    let mut odometry = Odometry::new(params).map_err(|e| BadInput::new(e.to_string()))?;
    let (mut times, mut poses) = (Vec::new(), Vec::new());
    for scan in bag.scans().map_err(|e| bad(e.to_string()))?.take(count) {
        if stop_requested() {
            return Err(crate::interrupt::Interrupted.into());
        }
        let scan = scan.map_err(|e| bad(e.to_string()))?;
        let pose = odometry
            .register(&scan.scan.points_in_sensor, scan.time_s)
            .map_err(|e| bad(format!("scan {}: {e}", scan.index)))?;
        times.push(scan.time_s);
        poses.push(pose);
        tick(&odometry);
    }
    Ok(ScanPoses {
        times,
        world_from_sensor: poses,
    })
}

/// The pose as the pipeline takes it.
pub fn to_pipeline(pose: &Isometry3<f64>) -> evigrid::Isometry3 {
    let r = pose.rotation.to_rotation_matrix();
    let m = r.matrix();
    let t = pose.translation.vector;
    evigrid::Isometry3 {
        rotation: [
            [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
        ],
        translation: [t.x, t.y, t.z],
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn the_pipeline_pose_is_the_same_transform() {
        let pose = Isometry3::from_parts(
            nalgebra::Translation3::new(1.0, 2.0, 3.0),
            nalgebra::UnitQuaternion::from_euler_angles(0.1, -0.2, 1.3),
        );
        let ours = to_pipeline(&pose);
        let expected = evigrid::Isometry3::from_xyz_rpy(1.0, 2.0, 3.0, 0.1, -0.2, 1.3);
        for (a, b) in ours
            .rotation
            .iter()
            .flatten()
            .zip(expected.rotation.iter().flatten())
        {
            assert!((a - b).abs() < 1e-12);
        }
        let p = pose.transform_point(&nalgebra::Point3::new(4.0, -5.0, 6.0));
        let q = ours.transform_point([4.0, -5.0, 6.0]);
        assert!(
            (p.x - q[0]).abs() < 1e-12 && (p.y - q[1]).abs() < 1e-12 && (p.z - q[2]).abs() < 1e-12
        );
    }

    #[test]
    fn scans_without_times_are_a_period_apart() {
        let scans = ScanSet {
            paths: vec![
                PathBuf::from("a.bin"),
                PathBuf::from("b.bin"),
                PathBuf::from("c.bin"),
            ],
            times: None,
            times_source: None,
            kitti: None,
            dir: PathBuf::from("scans"),
        };
        assert_eq!(scans.times_or_period(), vec![0.0, 0.1, 0.2]);
    }
}
