//! `evigrid odometry`: poses from the scans alone, written as a pose file.
//!
//! ```text
//! evigrid odometry SCANS --out poses.txt [--format tum|kitti] [--json]
//! ```
//!
//! Wiring only: the odometry is crate `odometry`'s, the writers crate `drive`'s. The written
//! poses read back through `evigrid run --poses` (TUM or KITTI odometry).

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use drive::poses::{PoseTrack, write_kitti_odometry, write_kitti_times, write_tum};
use nalgebra::Isometry3;
use odometry::FrameOutcome;
use odometry::metrics::relative_errors;
use serde::Serialize;

use crate::exit::BadInput;
use drive::{Drive, DriveSpec, PoseOrigin};

/// Output formats of `evigrid odometry`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OdometryFormat {
    /// `t x y z qx qy qz qw` per line.
    Tum,
    /// KITTI odometry: 12 numbers per line (3x4 matrix), times in a separate file.
    Kitti,
}

/// Arguments of `evigrid odometry`.
#[derive(Debug, Args)]
pub struct OdometryArgs {
    /// Folder of scans (PCD or KITTI `.bin`, in file-name order) or a KITTI raw drive folder.
    scans: PathBuf,
    /// Pose file to write. An existing file (and, with `--format kitti`, an existing times
    /// file) is replaced only with `--force`; an input never is.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing file at --out and its times file (never an input).
    #[arg(long)]
    force: bool,
    /// Pose file format. `kitti` also writes the times, one per line, to `<out without
    /// extension>.times.txt`.
    #[arg(long, value_enum, default_value = "tum")]
    format: OdometryFormat,
    /// Scan times (KITTI raw `timestamps.txt` or KITTI odometry `times.txt`); by default a
    /// `timestamps.txt` beside or in the scan folder, else scans 0.1 s apart.
    #[arg(long)]
    times: Option<PathBuf>,
    /// KITTI odometry `calib.txt` whose `Tr` turns the Velodyne's poses into camera 0's for
    /// `--format kitti`; without it the file holds the Velodyne's own poses.
    #[arg(long)]
    calib: Option<PathBuf>,
    /// Register only the first N scans.
    #[arg(long, value_name = "N")]
    max_frames: Option<usize>,
    /// Print the summary as JSON on standard output.
    #[arg(long)]
    json: bool,
}

/// Relative errors against a KITTI raw drive's OXTS poses.
#[derive(Debug, Serialize)]
struct AgainstOxts {
    /// Segment lengths, metres.
    lengths_m: Vec<f64>,
    segments: usize,
    translation_pct: Option<f64>,
    rotation_deg_per_m: Option<f64>,
    heading_deg_per_m: Option<f64>,
}

#[derive(Debug, Serialize)]
struct OdometrySummary {
    scans: String,
    out: String,
    format: &'static str,
    times_file: Option<String>,
    /// Where the scan times came from (`null`: none, scans 0.1 s apart).
    scan_times: Option<String>,
    frames: usize,
    registered: usize,
    not_converged: usize,
    predicted: usize,
    seconds: f64,
    ms_per_scan: f64,
    path_length_m: f64,
    against_oxts: Option<AgainstOxts>,
}

/// How the odometry's registrations went, counted as the pass goes, with its bar; and the
/// poses so far, kept for a pass that a signal ends.
struct Counts {
    bar: indicatif::ProgressBar,
    registered: usize,
    not_converged: usize,
    predicted: usize,
    so_far: Vec<Isometry3<f64>>,
}

impl session::Progress for Counts {
    fn odometry_scan(&mut self, odometry: &odometry::Odometry) {
        match odometry.last_report().map(|r| r.outcome) {
            Some(FrameOutcome::Registered { converged: true }) => self.registered += 1,
            Some(FrameOutcome::Registered { converged: false }) => self.not_converged += 1,
            Some(FrameOutcome::Predicted) => self.predicted += 1,
            _ => {}
        }
        // Called once per registered scan (the pass is strict): the last pose is this scan's.
        if let Some(pose) = odometry.poses().last() {
            self.so_far.push(*pose);
        }
        self.bar.inc(1);
    }
}

/// Runs `evigrid odometry`.
pub fn run(args: OdometryArgs) -> Result<()> {
    if args.max_frames == Some(0) {
        return Err(BadInput::new("--max-frames must be at least 1"));
    }
    let times_path = check_outputs(&args)?;
    let interrupt = crate::interrupt::Interrupt::install();
    if let Some(folder) = args.out.parent() {
        crate::interrupt::remove_temporaries_on_exit(folder, None);
    }
    let mut scans = open_scans(&args)?;
    let cam0_from_velo = match &args.calib {
        Some(path) => drive::calib::read_odometry_cam0_from_velo(path)
            .map_err(|e| BadInput::new(e.to_string()))?,
        None => Isometry3::identity(),
    };
    let mut counts = Counts {
        bar: crate::progress::bar(scans.len() as u64, "odometry"),
        registered: 0,
        not_converged: 0,
        predicted: 0,
        so_far: Vec::new(),
    };
    let started = Instant::now();
    // Strict: the pose file has one line per scan, so a scan cannot be left out.
    let poses = session::odometry_pass(
        &mut scans,
        true,
        interrupt.flag(),
        &mut Vec::new(),
        &mut counts,
    );
    counts.bar.finish_and_clear();
    let poses = match poses {
        Err(session::SessionError::Interrupted) => {
            let scan_times = scans.times_or_period();
            return write_interrupted(
                &args,
                &counts.so_far,
                &scan_times,
                &cam0_from_velo,
                times_path.as_deref(),
            );
        }
        poses => poses.map_err(|e| BadInput::new(e.to_string()))?,
    };
    let seconds = started.elapsed().as_secs_f64();
    let track = PoseTrack::new(poses.times.clone(), poses.world_from_sensor.clone())
        .map_err(|e| BadInput::new(format!("{}: scan times: {e}", args.scans.display())))?;

    write_poses(&args, &track, &cam0_from_velo, times_path.as_deref(), None)?;
    let times_file = times_path.as_ref().map(|p| p.display().to_string());

    let against_oxts = against_oxts(&scans, &poses.world_from_sensor)?;

    let frames = poses.times.len();
    let summary = OdometrySummary {
        scans: args.scans.display().to_string(),
        out: args.out.display().to_string(),
        format: match args.format {
            OdometryFormat::Tum => "tum",
            OdometryFormat::Kitti => "kitti",
        },
        times_file,
        scan_times: scans.times_source().map(|p| p.display().to_string()),
        frames,
        registered: counts.registered,
        not_converged: counts.not_converged,
        predicted: counts.predicted,
        seconds,
        ms_per_scan: 1e3 * seconds / frames.max(1) as f64,
        path_length_m: poses
            .world_from_sensor
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum(),
        against_oxts,
    };
    print_summary(args.json, &summary)
}

/// Checks that `--out`, and for the KITTI format its times file beside it, may be written
/// (never an input, a user's file only with `--force`); returns the times file's path.
fn check_outputs(args: &OdometryArgs) -> Result<Option<PathBuf>> {
    let inputs: Vec<&Path> = [Some(&args.scans), args.times.as_ref(), args.calib.as_ref()]
        .into_iter()
        .flatten()
        .map(PathBuf::as_path)
        .collect();
    crate::out_dir::check_out_file(&args.out, &inputs, args.force)?;
    let times_path =
        (args.format == OdometryFormat::Kitti).then(|| args.out.with_extension("times.txt"));
    if let Some(path) = &times_path {
        crate::out_dir::check_side_file(path, &inputs, args.force)?;
    }
    Ok(times_path)
}

/// The folder of scans (`--scans`, `--times`), cut to `--max-frames`.
fn open_scans(args: &OdometryArgs) -> Result<Drive> {
    let mut scans = Drive::open(&DriveSpec::ScanFolder {
        dir: args.scans.clone(),
        times: args.times.clone(),
        poses: None,
    })
    .map_err(|e| BadInput::new(e.to_string()))?;
    if let Some(n) = args.max_frames {
        scans.truncate(n);
    }
    Ok(scans)
}

/// Prints the summary: as JSON (`json`), or as a line for people and, with the drive's OXTS
/// poses, a line of the errors against them.
fn print_summary(json: bool, summary: &OdometrySummary) -> Result<()> {
    if json {
        crate::outln!("{}", serde_json::to_string_pretty(summary)?);
    } else {
        crate::outln!(
            "{} scans registered in {:.1} s ({:.0} ms per scan, scans read included): {} \
             converged, {} not converged, {} predicted; path {:.1} m; poses in {}{}",
            summary.frames,
            summary.seconds,
            summary.ms_per_scan,
            summary.registered,
            summary.not_converged,
            summary.predicted,
            summary.path_length_m,
            summary.out,
            summary
                .times_file
                .as_ref()
                .map_or_else(String::new, |t| format!(", times in {t}"))
        );
        if let Some(e) = &summary.against_oxts {
            crate::outln!(
                "against the drive's OXTS poses, {} segments of 10, 20 and 30 m: translation \
                 {:.2} %, rotation {:.4} °/m, heading {:.4} °/m",
                e.segments,
                e.translation_pct.unwrap_or(f64::NAN),
                e.rotation_deg_per_m.unwrap_or(f64::NAN),
                e.heading_deg_per_m.unwrap_or(f64::NAN)
            );
        }
    }
    Ok(())
}

/// Writes the pose file (and the KITTI times file), each whole or not at all; `incomplete`,
/// if given, is a comment on the first line of a TUM file saying why it ends early.
///
/// # Errors
/// A write error naming the file (exit 1: the folder was checked writable before the work).
fn write_poses(
    args: &OdometryArgs,
    track: &PoseTrack,
    cam0_from_velo: &Isometry3<f64>,
    times_path: Option<&Path>,
    incomplete: Option<&str>,
) -> Result<()> {
    write_file(&args.out, |out| match args.format {
        OdometryFormat::Tum => {
            if let Some(why) = incomplete {
                writeln!(out, "# incomplete: {why}")?;
            }
            write_tum(out, track)
        }
        OdometryFormat::Kitti => write_kitti_odometry(out, track, cam0_from_velo),
    })?;
    if let Some(path) = times_path {
        write_file(path, |out| write_kitti_times(out, track.times()))?;
    }
    Ok(())
}

/// Writes the poses registered before a signal stopped the pass (`so_far`, one per scan from
/// the first, at `scan_times`), marked incomplete; returns the error to end the command with
/// (interrupted, saying what was written).
fn write_interrupted(
    args: &OdometryArgs,
    so_far: &[Isometry3<f64>],
    scan_times: &[f64],
    cam0_from_velo: &Isometry3<f64>,
    times_path: Option<&Path>,
) -> Result<()> {
    let interrupted = anyhow::Error::new(crate::interrupt::Interrupted);
    let of = scan_times.len();
    let registered = so_far.len().min(of);
    if registered == 0 {
        return Err(interrupted.context("no scan registered, no pose file written"));
    }
    let why = format!("{interrupted} after {registered} of {of} scans");
    let track = PoseTrack::new(
        scan_times[..registered].to_vec(),
        so_far[..registered].to_vec(),
    )
    .map_err(|e| BadInput::new(format!("{}: scan times: {e}", args.scans.display())))?;
    write_poses(args, &track, cam0_from_velo, times_path, Some(&why))?;
    Err(interrupted.context(format!(
        "poses of {registered} of {of} scans written to {} (incomplete)",
        args.out.display()
    )))
}

/// Writes a file whole through `write` (a temporary beside it, renamed); an error names the file.
fn write_file(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<&mut fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    // The error names the file.
    Ok(output::write_atomic(path, |file| {
        let mut out = std::io::BufWriter::new(file);
        write(&mut out).and_then(|()| out.flush())
    })?)
}

/// The odometry's relative errors against a KITTI raw drive's OXTS poses (in the frame of the
/// transverse Mercator at its first fix); `None` for other drives.
fn against_oxts(scans: &Drive, poses: &[Isometry3<f64>]) -> Result<Option<AgainstOxts>> {
    if !matches!(scans.pose_origin(), PoseOrigin::Oxts { .. }) {
        return Ok(None);
    }
    let Some((lat, lon)) = scans.first_fix() else {
        return Ok(None);
    };
    let projection =
        geodata::TransverseMercator::new(lat, lon).map_err(|e| BadInput::new(e.to_string()))?;
    let project = |lat: f64, lon: f64| projection.forward(lat, lon);
    let reference = scans
        .place(Some(&project), usize::MAX)
        .map_err(|e| BadInput::new(e.to_string()))?;
    let n = poses.len().min(reference.world_from_sensor.len());
    let lengths_m = vec![10.0, 20.0, 30.0];
    let errors = relative_errors(poses, &reference.world_from_sensor[..n], &lengths_m, 1)
        .context("relative errors against OXTS")?;
    Ok(Some(AgainstOxts {
        lengths_m,
        segments: errors.segments.len(),
        translation_pct: errors.mean_translation_pct(),
        rotation_deg_per_m: errors.mean_rotation_deg_per_m(),
        heading_deg_per_m: errors.mean_heading_deg_per_m(),
    }))
}
