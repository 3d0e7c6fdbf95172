//! Poses from the scans alone: the lidar odometry over a drive that has none, before the
//! session's frames (the odometry crate sits beside `drive` at the bottom layer, so the pass
//! lives here and hands the poses back to the drive with [`drive::Drive::place_with`]).

use std::sync::atomic::{AtomicBool, Ordering};

use drive::{Drive, Poses};
use odometry::{Odometry, OdometryParams};

use crate::SessionError;
use crate::progress::Progress;
use crate::summary::SkippedScan;

/// Registers every scan of `drive` in order, in the first scan's frame. An unreadable scan of
/// a folder is left out of the drive (into `skipped`; an error if `strict`); in a recording it
/// ends the pass (later messages would lose their pairing with poses). `stop` is polled before
/// each scan.
///
/// # Errors
///
/// [`SessionError::Interrupted`] when `stop` is raised; [`SessionError::Input`] for a scan that
/// cannot be read or registered (`strict`, or in a recording).
pub fn odometry_pass(
    drive: &mut Drive,
    strict: bool,
    stop: &AtomicBool,
    skipped: &mut Vec<SkippedScan>,
    progress: &mut dyn Progress,
) -> Result<Poses, SessionError> {
    let mut odometry =
        Odometry::new(OdometryParams::default()).map_err(|e| SessionError::Input(e.to_string()))?;
    let recording = drive.is_recording();
    let given = drive.given_path().display().to_string();
    let (mut times, mut poses, mut kept) = (Vec::new(), Vec::new(), Vec::new());
    for read in drive.scans()? {
        if stop.load(Ordering::Relaxed) {
            return Err(SessionError::Interrupted);
        }
        // An unreadable scan is left out (the next registration spans the gap, as the
        // constant-velocity prediction allows) unless `strict`.
        let registered = read.map_err(|s| s.error).and_then(|read| {
            odometry
                .register(&read.scan.points_in_sensor, read.time_s)
                .map(|pose| (read.index, read.time_s, pose))
                .map_err(|e| format!("{}: {e}", read.name))
        });
        match registered {
            Ok((index, time_s, pose)) => {
                kept.push(index);
                times.push(time_s);
                poses.push(pose);
            }
            Err(error) if recording => {
                return Err(SessionError::Input(format!("{given}: {error}")));
            }
            Err(error) if strict => return Err(SessionError::Input(error)),
            Err(error) => {
                let index = kept.len() + skipped.len();
                skipped.push(SkippedScan {
                    scan: drive.scan_name(index),
                    error,
                });
            }
        }
        progress.odometry_scan(&odometry);
    }
    drive.keep(&kept);
    Ok(drive.place_with(times, poses))
}
