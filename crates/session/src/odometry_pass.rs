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
    let mut scans = drive.scans()?;
    loop {
        // Polled before a scan is read: a signal does not wait for a slow read.
        if stop.load(Ordering::Relaxed) {
            return Err(SessionError::Interrupted);
        }
        let Some(read) = scans.next() else { break };
        // An unreadable scan is left out (the next registration spans the gap, as the
        // constant-velocity prediction allows) unless `strict`.
        let registered = match read {
            Ok(read) => odometry
                .register(&read.scan.points_in_sensor, read.time_s)
                .map(|pose| (read.index, read.time_s, pose))
                .map_err(|e| (read.name.clone(), format!("{}: {e}", read.name))),
            Err(bad) => Err((bad.name, bad.error)),
        };
        match registered {
            Ok((index, time_s, pose)) => {
                kept.push(index);
                times.push(time_s);
                poses.push(pose);
            }
            Err((_, error)) if recording => {
                return Err(SessionError::Input(format!("{given}: {error}")));
            }
            Err((_, error)) if strict => return Err(SessionError::Input(error)),
            Err((scan, error)) => skipped.push(SkippedScan { scan, error }),
        }
        progress.odometry_scan(&odometry);
    }
    drop(scans);
    drive.keep(&kept);
    Ok(drive.place_with(times, poses))
}
