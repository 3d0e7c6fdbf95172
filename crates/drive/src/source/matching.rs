//! The rule that gives every scan its pose (the module documentation of [`super`]): a pose
//! file by time or line order, a KITTI raw drive's OXTS packets, a recording's poses.

use std::path::Path;

use nalgebra::Isometry3;

use super::{Drive, PoseFileSpec, SourceError};
use crate::bag::{BagDrive, BagPoses};
use crate::kitti_raw::KittiRawDrive;
use crate::poses::{KittiOdometryContext, PoseFormat, PoseTrack, read_pose_track};

/// Times and poses of the placed scans.
type Placed = (Vec<f64>, Vec<Isometry3<f64>>);

/// A projection of WGS84 `(lat, lon)` degrees to local `(east, north)` metres.
type Projection<'a> = &'a dyn Fn(f64, f64) -> (f64, f64);

fn input(e: &dyn std::fmt::Display) -> SourceError {
    SourceError::Input(e.to_string())
}

/// Reads a pose file and gives every scan its pose; with scan times only the first `required`
/// scans must lie in the poses' span.
pub(super) fn from_file(
    drive: &Drive,
    file: &PoseFileSpec,
    projection: Option<Projection<'_>>,
    required: usize,
) -> Result<Placed, SourceError> {
    let path = file.path.as_path();
    let format = match file.format {
        Some(format) => format,
        None => PoseFormat::detect(path).map_err(|e| input(&e))?,
    };
    let cam0_from_velo = match &file.calib {
        Some(calib) => crate::calib::read_odometry_cam0_from_velo(calib).map_err(|e| input(&e))?,
        None => Isometry3::identity(),
    };
    let line_times = drive.times_or_period();
    let kitti = KittiOdometryContext {
        times: &line_times,
        cam0_from_velo,
    };
    if format == PoseFormat::KittiOdometry {
        check_count(
            path,
            count_pose_lines(path)?,
            drive,
            "KITTI odometry poses have no times: one line per scan",
        )?;
    }
    let no_projection = projection.is_none();
    let track = read_pose_track(path, Some(format), Some(&kitti), projection).map_err(|e| {
        let message = e.to_string();
        if no_projection && message.contains("need a projection") {
            SourceError::NeedsProjection { what: message }
        } else {
            SourceError::Input(message)
        }
    })?;
    let track = match &file.mounting {
        Some(mounting) => mounting.apply(&track),
        None => track,
    };
    if drive.times.is_none() {
        // Line order: pose k is scan k's.
        check_count(
            path,
            track.len(),
            drive,
            "without scan timestamps, pose line k goes with scan k",
        )?;
        return Ok(track.into_parts());
    }
    at_scan_times(drive, &track, path, required)
}

/// Data lines of a file (for the count a KITTI odometry file must have).
fn count_pose_lines(path: &Path) -> Result<usize, SourceError> {
    let text = crate::text::read_text(path).map_err(|e| input(&e))?;
    Ok(text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .count())
}

fn check_count(path: &Path, poses: usize, drive: &Drive, why: &str) -> Result<(), SourceError> {
    if poses == drive.paths.len() {
        return Ok(());
    }
    Err(SourceError::Input(format!(
        "{}: {poses} poses for {} scans in {} ({why})",
        path.display(),
        drive.paths.len(),
        drive.given.display()
    )))
}

/// Every scan's pose interpolated at its time; the first of the `required` first scans outside
/// the span is an error naming it, later scans end the list there.
fn at_scan_times(
    drive: &Drive,
    track: &PoseTrack,
    source: &Path,
    required: usize,
) -> Result<Placed, SourceError> {
    let mut times = drive.times.clone().unwrap_or_default();
    let mut poses = Vec::with_capacity(times.len());
    for (k, (scan, &t)) in drive.paths.iter().zip(&times).enumerate() {
        if k >= required && track.at(t).is_err() {
            break;
        }
        let pose = track.at(t).map_err(|e| {
            SourceError::Input(format!(
                "scan {} (time from {}): {e} of {}",
                scan.display(),
                drive
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
    Ok((times, poses))
}

/// The Velodyne's poses from a KITTI raw drive's OXTS packets and calibration.
pub(super) fn from_oxts(
    drive: &KittiRawDrive,
    projection: Option<Projection<'_>>,
) -> Result<Placed, SourceError> {
    let Some(projection) = projection else {
        return Err(SourceError::NeedsProjection {
            what: format!("OXTS of {}", drive.drive_dir().display()),
        });
    };
    let poses = drive
        .world_from_velodyne(projection)
        .map_err(|e| input(&e))?;
    Ok((drive.scan_times().to_vec(), poses))
}

/// The poses of a recording (tf, odometry or NavSatFix) at its scans' times; only the first
/// `required` scans are placed.
pub(super) fn from_bag(
    bag: &BagDrive,
    projection: Option<Projection<'_>>,
    required: usize,
) -> Result<Placed, SourceError> {
    let bad = |e: String| SourceError::Input(format!("{}: {e}", bag.path().display()));
    let unplaced = |_: f64, _: f64| (f64::NAN, f64::NAN);
    let track = match (bag.poses(), projection) {
        (BagPoses::Wgs84(_), None) => {
            return Err(SourceError::NeedsProjection {
                what: format!(
                    "{}: poses from NavSatFix ({})",
                    bag.path().display(),
                    bag.pose_source()
                ),
            });
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
        .collect::<Result<Vec<_>, _>>()?;
    Ok((times, world_from_sensor))
}
