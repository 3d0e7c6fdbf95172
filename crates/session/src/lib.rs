//! A drive's run as a library object: the one thing the command line, the Python package and a
//! batch runner call.
//!
//! A [`Session`] is built from the parameters, the method and the map ([`SessionConfig`]). It
//! runs the pipeline frame by frame ([`Session::step`], for Python), keeps the running totals
//! and the ego-path check, and gives the [`Summary`] (`summary.json`). [`run_drive`] runs a
//! whole [`drive::Drive`]: it places the scans (the drive's own poses, or the lidar odometry's
//! for scans without poses), steps every frame, hands each to the caller's sinks
//! ([`output::sink::FrameSink`]: the recording, pictures, `frames.jsonl`, the final figures and
//! grids), and stops between frames when the caller's flag is raised.
//!
//! The key design decision: the session owns the frame loop and nothing else. Where scans and
//! poses come from is `drive::source`'s, what is written is the sinks', the method is
//! `evigrid`'s; so a new input, a new output or a new caller is an addition, not an edit here.
//! WGS84 poses are placed in the map's projection, else the configured origin's, else at a
//! KITTI raw drive's first fix ([`place`]).
//!
//! Over the shared KITTI raw drive (runs when the shared data is found: `EVIGRID_SHARED`, by
//! default `../shared` beside the workspace):
//!
//! ```
//! use std::sync::atomic::AtomicBool;
//! use drive::{Drive, DriveSpec};
//! use session::{SessionConfig, run_drive};
//!
//! let kitti = "data/lidar/kitti-raw-0013/2011_09_26";
//! let Some(dir) = geodata::testdata::shared_file(kitti) else { return Ok(()) };
//! let drive = Drive::open(&DriveSpec::KittiRaw { dir, poses: None })?;
//! let config = SessionConfig {
//!     max_frames: Some(3),
//!     ..SessionConfig::default()
//! };
//! // No sinks: nothing is written; the summary is returned.
//! let summary = run_drive(drive, config, &mut [], &AtomicBool::new(false))?;
//! assert!(summary.complete);
//! assert_eq!(summary.frames, 3);
//! assert_eq!(summary.pose_matching, "time");
//! assert!(summary.poses.starts_with("OXTS of"));
//! assert!(summary.points > 100_000);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

mod error;
mod odometry_pass;
mod progress;
mod run;
mod session;
mod summary;

/// Why a session could not start, or stopped.
pub use error::SessionError;
/// Poses from the scans alone, for drives without poses.
pub use odometry_pass::odometry_pass;
/// What a caller hears as a drive runs.
pub use progress::Progress;
/// A whole drive: placing it, running it, both.
pub use run::{Placement, RunOutcome, place, run_drive, run_placed};
/// The session, step by step.
pub use session::{DriveLabels, Map, Session, SessionConfig, StepResult, method_name};
/// What a session reports.
pub use summary::{
    EgoPathTotals, FRAMES_FILE, FrameRecord, RefinementTotals, SkippedScan, Summary,
};

#[cfg(test)]
mod tests;
