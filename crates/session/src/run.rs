//! A whole drive: place its scans ([`place`]), run the session over them with the caller's
//! sinks ([`run_placed`]), or both at once ([`run_drive`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use drive::{Drive, PoseOrigin, Poses};
use output::sink::FrameSink;

use crate::progress::Progress;
use crate::session::{DriveLabels, Session, SessionConfig};
use crate::summary::{SkippedScan, Summary};
use crate::{SessionError, odometry_pass};

/// A drive whose scans have their poses, ready to run.
#[derive(Debug)]
pub struct Placement {
    /// The drive (the scans the odometry could not read left out).
    pub drive: Drive,
    /// One pose per scan to process (at most `max_frames`).
    pub poses: Poses,
    /// The ego's path: every pose known, those after `max_frames` too, metres.
    pub path: Vec<[f64; 2]>,
    /// Scans the odometry pass left out.
    pub skipped: Vec<SkippedScan>,
    /// Seconds of the odometry pass (0 when poses were given).
    pub odometry_seconds: f64,
    /// The odometry pass stopped early (interrupted, or a bad scan with `strict`): no frame
    /// runs, and the summary says why.
    pub stopped: Option<SessionError>,
    /// The origin of the local frame when neither the map nor the configuration gives one:
    /// a KITTI raw drive's first fix.
    pub first_fix: Option<(f64, f64)>,
    /// When placing began: the summary's `total_seconds` counts from here.
    pub started: Instant,
}

/// The local frame's projection: the map's, else the configuration's origin, else `first_fix`.
fn projection(
    config: &SessionConfig,
    first_fix: Option<(f64, f64)>,
) -> Result<Option<geodata::TransverseMercator>, SessionError> {
    match (&config.map, config.origin.or(first_fix)) {
        (Some(map), _) => Ok(Some(map.loaded.projection)),
        (None, Some((lat, lon))) => geodata::TransverseMercator::new(lat, lon)
            .map(Some)
            .map_err(|e| SessionError::Input(format!("origin of the local frame: {e}"))),
        (None, None) => Ok(None),
    }
}

/// How far a pose may lie outside the map's extent: the sensor sees about this far, so a pose
/// farther out sees nothing of the map (a wrong map, origin or pose frame).
const MAP_MARGIN_M: f64 = 100.0;

/// The first pose farther than [`MAP_MARGIN_M`] outside the map's extent, as an error.
fn check_poses_on_map(poses: &Poses, extent: &geo::Rect<f64>) -> Result<(), String> {
    let (min, max) = (extent.min(), extent.max());
    for (k, pose) in poses.world_from_sensor.iter().enumerate() {
        let (x, y) = (pose.translation.x, pose.translation.y);
        let dx = (min.x - x).max(x - max.x).max(0.0);
        let dy = (min.y - y).max(y - max.y).max(0.0);
        let distance_m = dx.hypot(dy);
        if distance_m > MAP_MARGIN_M || !distance_m.is_finite() {
            return Err(format!(
                "pose {} (scan {}) lies {distance_m:.0} m outside the extent",
                k + 1,
                k + 1
            ));
        }
    }
    Ok(())
}

/// Gives the drive's scans their poses: by the drive's own rule ([`Drive::place`], WGS84
/// poses in the map's frame, else the origin's, else the drive's first fix), or, for a drive
/// without poses, by the lidar odometry over its scans.
///
/// # Errors
///
/// [`SessionError::Source`] for poses that cannot be matched, [`SessionError::Input`] for the
/// odometry's poses with a map, or poses off the map.
pub fn place(
    mut drive: Drive,
    config: &SessionConfig,
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<Placement, SessionError> {
    let started = Instant::now();
    let first_fix = drive.first_fix();
    let projection = projection(config, first_fix)?;
    let project = |lat: f64, lon: f64| match &projection {
        Some(p) => p.forward(lat, lon),
        None => (f64::NAN, f64::NAN),
    };
    let project_dyn: &dyn Fn(f64, f64) -> (f64, f64) = &project;
    let (mut skipped, mut odometry_seconds, mut stopped) = (Vec::new(), 0.0, None);
    let mut poses = if drive.pose_origin() == PoseOrigin::Odometry {
        if let Some(map) = &config.map {
            return Err(SessionError::Input(format!(
                "{}: poses from the lidar odometry are in the first scan's frame, not the \
                 map's; give a pose file",
                map.name
            )));
        }
        if let Some(n) = config.max_frames {
            drive.truncate(n);
        }
        progress.odometry_started(drive.len());
        let t0 = Instant::now();
        let registered =
            odometry_pass::odometry_pass(&mut drive, config.strict, stop, &mut skipped, progress);
        progress.odometry_finished();
        odometry_seconds = t0.elapsed().as_secs_f64();
        registered.unwrap_or_else(|error| {
            stopped = Some(error);
            drive.place_with(Vec::new(), Vec::new())
        })
    } else {
        drive.place(
            projection.is_some().then_some(project_dyn),
            config.max_frames.unwrap_or(usize::MAX),
        )?
    };
    // The ego's path: every pose is known before the run, those after `max_frames` too.
    let path = poses.positions();
    if let Some(n) = config.max_frames {
        drive.truncate(n);
        poses.times.truncate(n);
        poses.world_from_sensor.truncate(n);
    }
    if let Some(map) = &config.map {
        check_poses_on_map(&poses, &map.loaded.map.extent).map_err(|e| {
            SessionError::Input(format!(
                "{}: {e} of the map {} (a map of another place, or poses in metres from another \
                 point: give that point as --origin LAT,LON)",
                poses.origin, map.name
            ))
        })?;
    }
    Ok(Placement {
        drive,
        poses,
        path,
        skipped,
        odometry_seconds,
        stopped,
        first_fix,
        started,
    })
}

/// What [`run_placed`] did: the summary, and the error that ended it early (`None` when
/// `summary.complete`).
#[derive(Debug)]
pub struct RunOutcome {
    /// The summary (marked incomplete after an early stop).
    pub summary: Summary,
    /// Why the session stopped early.
    pub error: Option<SessionError>,
}

/// Runs the session over a placed drive: every frame through the pipeline, the ego-path check
/// and the `sinks`, until the last, a raised `stop`, a sink's error, or (with `strict`) a bad
/// scan. The sinks are finished in every case, so what was done stays readable.
///
/// # Errors
///
/// Only before the first frame: [`SessionError::Input`] from [`Session::new`], or a recording
/// that cannot be read. Errors after are in [`RunOutcome::error`].
pub fn run_placed(
    placement: Placement,
    mut config: SessionConfig,
    sinks: &mut [&mut dyn FrameSink],
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<RunOutcome, SessionError> {
    let Placement {
        drive,
        poses,
        path,
        skipped,
        odometry_seconds,
        stopped,
        first_fix,
        started,
    } = placement;
    config.adapt_to_poses(&poses.origin);
    if config.map.is_none() && config.origin.is_none() {
        config.origin = first_fix;
    }
    let strict = config.strict;
    let mut session = Session::new(config)?;
    // The configuration is already adapted to the poses: this only names the drive.
    session.begin_drive(
        DriveLabels::new(&drive, &poses.origin, odometry_seconds),
        &poses.origin,
    )?;
    session.set_path(path);
    session.started_at(started);
    for scan in skipped {
        session.skipped_before(scan);
    }
    let mut cause = None;
    if let Some(error) = stopped {
        session.stop(format!("odometry pass: {error}"));
        cause = Some(error);
    }
    let frames = drive.frames(&poses)?;
    progress.frames_started(frames.len());
    if cause.is_none() {
        cause = run_frames(&mut session, frames, strict, sinks, stop, progress);
    }
    progress.frames_finished();
    if session.frames() == 0
        && cause.is_none()
        && let Some(first) = session.skipped().first()
    {
        let error = format!(
            "no scan could be used ({} skipped; the first: {})",
            session.skipped().len(),
            first.error
        );
        session.stop(error.clone());
        cause = Some(SessionError::Input(error));
    }
    // The sinks are finished even after an early stop (the final pictures and grids are the
    // last processed frame's); a failure here is kept, and the summary is still made.
    for sink in sinks.iter_mut() {
        if let Err(error) = sink.finish(&session.final_view())
            && cause.is_none()
        {
            session.stop(format!("finishing the outputs: {error}"));
            cause = Some(error.into());
        }
    }
    Ok(RunOutcome {
        summary: session.summary(),
        error: cause,
    })
}

/// The frame loop; the error that ended it early, if any.
fn run_frames(
    session: &mut Session,
    mut frames: drive::source::Frames<'_>,
    strict: bool,
    sinks: &mut [&mut dyn FrameSink],
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Option<SessionError> {
    loop {
        let t0 = Instant::now();
        // The next frame is asked for before the stop flag, so that a flag raised while the
        // last frame was processed leaves a complete drive, not an interrupted one.
        let next = frames.next()?;
        if stop.load(Ordering::Relaxed) {
            session.stop(SessionError::Interrupted.to_string());
            return Some(SessionError::Interrupted);
        }
        let frame = match next {
            Ok(frame) => frame,
            // A scan that cannot be read is the input's fault: skipped, or with `strict` the
            // end of the session.
            Err(bad) => {
                if strict {
                    session.stop(bad.error.clone());
                    return Some(SessionError::Input(bad.error));
                }
                tracing::debug!("skipped: {}", bad.error);
                let index = bad.index;
                session.skip(SkippedScan {
                    scan: bad.name,
                    error: bad.error,
                });
                progress.frame(index, None);
                continue;
            }
        };
        let read_ms = t0.elapsed().as_secs_f64() * 1e3;
        match session.step_into(&frame, read_ms, sinks) {
            Ok(record) => progress.frame(frame.index, Some(&record)),
            Err(error @ SessionError::Input(_)) if !strict => {
                tracing::debug!("skipped: {error}");
                progress.frame(frame.index, None);
            }
            Err(error) => {
                let why = match &error {
                    SessionError::Output(e) => format!("frame {}: {e}", frame.index),
                    other => other.to_string(),
                };
                session.stop(why);
                return Some(error);
            }
        }
    }
}

/// Runs a whole drive: places its scans ([`place`]) and runs the session over them with
/// `sinks` ([`run_placed`]); `stop` is polled between frames.
///
/// # Errors
///
/// [`SessionError::Stopped`] with the summary (marked incomplete) and the cause when the
/// session ended early; any error of [`place`] or [`run_placed`] before the first frame.
pub fn run_drive(
    drive: Drive,
    config: SessionConfig,
    sinks: &mut [&mut dyn FrameSink],
    stop: &AtomicBool,
) -> Result<Summary, SessionError> {
    let placement = place(drive, &config, stop, &mut ())?;
    let outcome = run_placed(placement, config, sinks, stop, &mut ())?;
    match outcome.error {
        None => Ok(outcome.summary),
        Some(cause) => Err(SessionError::Stopped {
            summary: Box::new(outcome.summary),
            cause: Box::new(cause),
        }),
    }
}
