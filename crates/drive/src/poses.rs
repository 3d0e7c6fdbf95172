//! Pose files and the time-indexed track they become.
//!
//! A [`PoseTrack`] is a list of rigid transforms `world_from_x` at strictly increasing times,
//! interpolated in between ([`PoseTrack::at`]): scans and pose sources never share a clock tick,
//! so every consumer needs "the pose at time t", not "pose number i".
//!
//! Formats read (and, for the first two, written so that they read back):
//! - **TUM** (`t x y z qx qy qz qw`, `#` comments): [`read_tum`], [`write_tum`];
//! - **KITTI odometry** (12 numbers per line, `world_from_cam0` of frame i as a 3×4 row-major
//!   matrix, no times): [`read_kitti_odometry`], [`write_kitti_odometry`], with the times from a
//!   `times.txt` ([`read_kitti_times`], [`write_kitti_times`]) or from the scans;
//! - **evigrid** (`t x y z roll pitch yaw` in the map's local frame, or `t lat lon alt roll pitch
//!   yaw` after `# frame: wgs84`): [`read_evigrid`], [`write_evigrid`];
//!
//! and [`PoseFormat`] picks one by name or from the first data line's column count.
//! [`Mounting`] places a sensor on the vehicle whose poses a file gives.

use crate::calib::{isometry_from_3x4, rows_3x4};
use crate::error::ReadError;
use crate::oxts::{ProjectionError, check_lat_lon, world_from_geodetic};
use crate::text::{data_lines, file_error, line_error, numbers_on_line, read_text, show};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// How far outside its span (seconds, at either end) [`PoseTrack::at`] still answers, with the
/// end pose: clocks of one drive are rounded differently (KITTI writes nanoseconds, TUM files
/// often microseconds, `times.txt` six digits), and a millisecond moves a car by about 1 cm.
pub const TIME_TOLERANCE_S: f64 = 1e-3;

/// Why a [`PoseTrack`] could not be built or queried.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TrackError {
    /// No poses at all.
    #[error("a pose track needs at least one pose")]
    Empty,
    /// The times and poses have different lengths.
    #[error("{times} times for {poses} poses")]
    LengthMismatch {
        /// Number of times.
        times: usize,
        /// Number of poses.
        poses: usize,
    },
    /// A time or pose is NaN or infinite.
    #[error("pose #{index} (0-based) has a non-finite time or transform")]
    NonFinite {
        /// 0-based index.
        index: usize,
    },
    /// A time does not increase on the previous one.
    #[error("time #{index} (0-based) = {time} s does not increase on the previous {previous} s")]
    NotIncreasing {
        /// 0-based index of the offending time.
        index: usize,
        /// Its value.
        time: f64,
        /// The time before it.
        previous: f64,
    },
    /// A query time lies outside the track's span (beyond the tolerance).
    #[error(
        "time {time:.6} s lies outside the poses' span [{start:.6}, {end:.6}] s \
         (tolerance {tolerance} s at either end)"
    )]
    OutsideSpan {
        /// The query time.
        time: f64,
        /// First pose time.
        start: f64,
        /// Last pose time.
        end: f64,
        /// How far outside the span a query would still have been answered.
        tolerance: f64,
    },
}

/// Rigid transforms `world_from_x` at strictly increasing times (seconds), with interpolation.
///
/// The invariants (non-empty, same lengths, finite, strictly increasing) are checked once by
/// [`PoseTrack::new`], so queries need no checks of their own.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseTrack {
    times: Vec<f64>,
    world_from_x: Vec<Isometry3<f64>>,
}

/// Interpolates between two transforms: translation linearly, rotation along the shortest arc
/// (slerp, written as `a · exp(s · log(a⁻¹ b))` so it never panics, even for opposite
/// rotations, and extrapolates for `s` outside `[0, 1]`).
pub fn interpolate(a: &Isometry3<f64>, b: &Isometry3<f64>, s: f64) -> Isometry3<f64> {
    let ta = a.translation.vector;
    let tb = b.translation.vector;
    let delta = (a.rotation.inverse() * b.rotation).scaled_axis();
    Isometry3::from_parts(
        Translation3::from(ta + (tb - ta) * s),
        a.rotation * UnitQuaternion::from_scaled_axis(delta * s),
    )
}

fn is_finite(iso: &Isometry3<f64>) -> bool {
    iso.translation.vector.iter().all(|v| v.is_finite())
        && iso.rotation.coords.iter().all(|v| v.is_finite())
}

impl PoseTrack {
    /// A track from times and the poses at those times.
    ///
    /// # Errors
    ///
    /// [`TrackError`]: empty, lengths differ, a non-finite value, or times not strictly
    /// increasing.
    pub fn new(times: Vec<f64>, world_from_x: Vec<Isometry3<f64>>) -> Result<Self, TrackError> {
        if times.len() != world_from_x.len() {
            return Err(TrackError::LengthMismatch {
                times: times.len(),
                poses: world_from_x.len(),
            });
        }
        if times.is_empty() {
            return Err(TrackError::Empty);
        }
        for (index, (t, pose)) in times.iter().zip(&world_from_x).enumerate() {
            if !t.is_finite() || !is_finite(pose) {
                return Err(TrackError::NonFinite { index });
            }
        }
        if let Some(index) = times.windows(2).position(|w| w[1] <= w[0]) {
            return Err(TrackError::NotIncreasing {
                index: index + 1,
                time: times[index + 1],
                previous: times[index],
            });
        }
        Ok(Self {
            times,
            world_from_x,
        })
    }

    /// The times, strictly increasing.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// The poses `world_from_x`, one per time.
    pub fn poses(&self) -> &[Isometry3<f64>] {
        &self.world_from_x
    }

    /// Number of poses (at least one).
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Always false: a track holds at least one pose.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// First and last time.
    pub fn span(&self) -> (f64, f64) {
        let first = self.times.first().copied().unwrap_or(f64::NAN);
        let last = self.times.last().copied().unwrap_or(f64::NAN);
        (first, last)
    }

    /// The times and poses, taken apart.
    pub fn into_parts(self) -> (Vec<f64>, Vec<Isometry3<f64>>) {
        (self.times, self.world_from_x)
    }

    /// The pose at time `t`, interpolated between the two poses around it (see
    /// [`interpolate`]); within [`TIME_TOLERANCE_S`] outside the span, the end pose.
    ///
    /// # Errors
    ///
    /// [`TrackError::OutsideSpan`], naming `t` and the span, when `t` is further outside (or not
    /// finite).
    pub fn at(&self, t: f64) -> Result<Isometry3<f64>, TrackError> {
        self.at_extrapolated(t, 0.0)
    }

    /// As [`PoseTrack::at`], but up to `max_extrapolation_s` outside the span (when larger than
    /// [`TIME_TOLERANCE_S`]) the pose is extrapolated at constant velocity along the first or
    /// last interval. For sources sampled at the same rate but a constant offset from the scans
    /// (KITTI raw: scans 12–22 ms before the OXTS packets), where the first or last scan falls
    /// just outside; a track of one pose answers only within the tolerance.
    ///
    /// # Errors
    ///
    /// [`TrackError::OutsideSpan`] beyond that bound or for a non-finite `t`.
    pub fn at_extrapolated(
        &self,
        t: f64,
        max_extrapolation_s: f64,
    ) -> Result<Isometry3<f64>, TrackError> {
        let (start, end) = self.span();
        let n = self.times.len();
        // One pose has no velocity to extrapolate with.
        let reach = if n > 1 {
            TIME_TOLERANCE_S.max(max_extrapolation_s)
        } else {
            TIME_TOLERANCE_S
        };
        let outside = TrackError::OutsideSpan {
            time: t,
            start,
            end,
            tolerance: reach,
        };
        if !(t.is_finite() && t >= start - reach && t <= end + reach) {
            return Err(outside);
        }
        let pose = |k: usize| self.world_from_x.get(k).copied();
        let segment = |a: usize| -> Option<Isometry3<f64>> {
            let (ta, tb) = (*self.times.get(a)?, *self.times.get(a + 1)?);
            Some(interpolate(&pose(a)?, &pose(a + 1)?, (t - ta) / (tb - ta)))
        };
        let found = if t <= start {
            if start - t <= TIME_TOLERANCE_S {
                pose(0)
            } else {
                segment(0)
            }
        } else if t >= end {
            if t - end <= TIME_TOLERANCE_S {
                pose(n - 1)
            } else {
                segment(n.saturating_sub(2))
            }
        } else {
            // start < t < end, so 1 <= i <= n - 1.
            let i = self.times.partition_point(|&x| x <= t);
            segment(i.saturating_sub(1))
        };
        found.ok_or(outside)
    }

    /// The track of another frame rigidly attached to `x`: `world_from_y = world_from_x ·
    /// x_from_y` at every time (a sensor mounting, a lever arm).
    pub fn then(&self, x_from_y: &Isometry3<f64>) -> PoseTrack {
        PoseTrack {
            times: self.times.clone(),
            world_from_x: self.world_from_x.iter().map(|p| p * x_from_y).collect(),
        }
    }
}

/// Builds a track from what a reader collected; the reader has checked finiteness and order with
/// line numbers, so the only failure left is an empty file.
fn track_from(
    path: &Path,
    times: Vec<f64>,
    poses: Vec<Isometry3<f64>>,
) -> Result<PoseTrack, ReadError> {
    PoseTrack::new(times, poses).map_err(|e| match e {
        TrackError::Empty => file_error(path, "no poses"),
        other => file_error(path, other.to_string()),
    })
}

/// Largest coordinate of a position in a pose file, metres (10,000 km): beyond the Earth's
/// radius from any local origin, and above any Earth-centred coordinate.
pub const MAX_POSITION_M: f64 = 1e7;

/// Fastest the sensor is taken to move between two poses of a file, m/s (360 km/h).
pub const MAX_POSE_SPEED_MPS: f64 = 100.0;

/// What a pose may jump between two lines beyond [`MAX_POSE_SPEED_MPS`], metres (a
/// re-localisation, a loop closure's correction).
pub const POSE_JUMP_SLACK_M: f64 = 10.0;

/// Largest roll or pitch in a pose file or a mounting, radians: a full turn either way.
pub const MAX_TILT_RAD: f64 = 2.0 * std::f64::consts::PI;

/// Largest yaw in a pose file, radians: 100 turns either way, for a heading written unwrapped.
pub const MAX_YAW_RAD: f64 = 200.0 * std::f64::consts::PI;

/// Largest offset of a sensor from the vehicle's origin in a mounting, metres.
pub const MAX_MOUNTING_OFFSET_M: f64 = 50.0;

/// Checks every coordinate of a position against [`MAX_POSITION_M`].
fn check_position_bound(
    path: &Path,
    line: usize,
    position: &Vector3<f64>,
) -> Result<(), ReadError> {
    match position.iter().find(|v| v.abs() > MAX_POSITION_M) {
        Some(far) => Err(line_error(
            path,
            line,
            format!(
                "position coordinate {} m is beyond ±{MAX_POSITION_M:e} m",
                show(*far)
            ),
        )),
        None => Ok(()),
    }
}

/// Checks a pose's position against [`MAX_POSITION_M`] and its jump from the previous pose
/// (`previous`: its time and position) against [`MAX_POSE_SPEED_MPS`] and
/// [`POSE_JUMP_SLACK_M`]; then makes it the previous pose.
fn check_position(
    path: &Path,
    line: usize,
    time: f64,
    position: Vector3<f64>,
    previous: &mut Option<(f64, Vector3<f64>)>,
) -> Result<(), ReadError> {
    check_position_bound(path, line, &position)?;
    if let Some((t0, p0)) = *previous {
        let jump_m = (position - p0).norm();
        let dt_s = (time - t0).abs();
        let allowed_m = MAX_POSE_SPEED_MPS * dt_s + POSE_JUMP_SLACK_M;
        if jump_m > allowed_m {
            return Err(line_error(
                path,
                line,
                format!(
                    "the position jumps {jump_m:.1} m from the previous pose in {dt_s} s (at \
                     most {allowed_m:.1} m at {MAX_POSE_SPEED_MPS} m/s)"
                ),
            ));
        }
    }
    *previous = Some((time, position));
    Ok(())
}

/// Checks roll and pitch against [`MAX_TILT_RAD`] and yaw against [`MAX_YAW_RAD`].
fn check_angles(roll: f64, pitch: f64, yaw: f64) -> Result<(), String> {
    for (name, angle, max) in [
        ("roll", roll, MAX_TILT_RAD),
        ("pitch", pitch, MAX_TILT_RAD),
        ("yaw", yaw, MAX_YAW_RAD),
    ] {
        if angle.abs() > max {
            return Err(format!(
                "{name} {} rad is beyond ±{max:.2} rad",
                show(angle)
            ));
        }
    }
    Ok(())
}

/// Checks that `time` on `line` increases on the previous data line's time.
fn check_increasing(
    path: &Path,
    line: usize,
    time: f64,
    previous: &mut Option<f64>,
) -> Result<(), ReadError> {
    if let Some(previous) = *previous
        && time <= previous
    {
        return Err(ReadError::NotIncreasing {
            path: path.to_path_buf(),
            line,
            time,
            previous,
        });
    }
    *previous = Some(time);
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// TUM

/// Largest deviation from 1 accepted for a TUM quaternion's norm before it is normalised: files
/// print 4–9 digits, and a norm far from 1 means the columns are not what we think.
const QUATERNION_NORM_TOLERANCE: f64 = 1e-2;

/// Reads a TUM trajectory: `t x y z qx qy qz qw` per line (seconds, metres, the Hamilton unit
/// quaternion of `world_from_x`), `#` comments and blank lines ignored.
///
/// # Errors
///
/// [`ReadError`] with the line: not 8 numbers, a non-number or non-finite value, a quaternion
/// whose norm is not 1 within 1 %, times not strictly increasing; or an empty file.
pub fn read_tum(path: &Path) -> Result<PoseTrack, ReadError> {
    let text = read_text(path)?;
    let (mut times, mut poses) = (Vec::new(), Vec::new());
    let (mut previous, mut last) = (None, None);
    for (line, data) in data_lines(&text) {
        let [t, x, y, z, qx, qy, qz, qw] =
            numbers_on_line::<8>(path, line, data, "TUM: t x y z qx qy qz qw")?;
        let q = Quaternion::new(qw, qx, qy, qz);
        if (q.norm() - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
            return Err(line_error(
                path,
                line,
                format!(
                    "quaternion (qx qy qz qw) = ({qx} {qy} {qz} {qw}) has norm {:.4}, not 1",
                    q.norm()
                ),
            ));
        }
        check_increasing(path, line, t, &mut previous)?;
        check_position(path, line, t, Vector3::new(x, y, z), &mut last)?;
        times.push(t);
        poses.push(Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::new_normalize(q),
        ));
    }
    track_from(path, times, poses)
}

/// Writes a track in TUM format, one `t x y z qx qy qz qw` line per pose, every number in its
/// shortest form that reads back to the same `f64`.
///
/// # Errors
///
/// The writer's I/O error.
pub fn write_tum<W: Write>(out: &mut W, track: &PoseTrack) -> std::io::Result<()> {
    writeln!(out, "# t x y z qx qy qz qw")?;
    for (t, pose) in track.times().iter().zip(track.poses()) {
        let p = pose.translation.vector;
        let q = pose.rotation.coords; // (i, j, k, w)
        writeln!(
            out,
            "{t} {} {} {} {} {} {} {}",
            p.x, p.y, p.z, q.x, q.y, q.z, q.w
        )?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// KITTI odometry

/// Reads a KITTI odometry `times.txt`: one time (seconds) per line, strictly increasing.
///
/// # Errors
///
/// [`ReadError`] with the line: not one number, not increasing; or an empty file.
pub fn read_kitti_times(path: &Path) -> Result<Vec<f64>, ReadError> {
    let text = read_text(path)?;
    let mut times = Vec::new();
    let mut previous = None;
    for (line, data) in data_lines(&text) {
        let [t] = numbers_on_line::<1>(path, line, data, "one time in seconds")?;
        if t < 0.0 {
            return Err(line_error(
                path,
                line,
                format!("time {t} s is negative; scan times count from the drive's start"),
            ));
        }
        check_increasing(path, line, t, &mut previous)?;
        times.push(t);
    }
    if times.is_empty() {
        return Err(file_error(path, "no times"));
    }
    Ok(times)
}

/// Reads scan times in either of KITTI's two forms, told apart by the first non-blank line: KITTI
/// raw `timestamps.txt` (`2011-09-26 13:02:25.964389445`, seconds since the Unix epoch) or KITTI
/// odometry `times.txt` (one number of seconds per line). Times must strictly increase.
///
/// # Errors
///
/// [`ReadError`] with the line: a malformed time or one that does not increase; or no times.
pub fn read_scan_times(path: &Path) -> Result<Vec<f64>, ReadError> {
    let text = read_text(path)?;
    let dated = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty())
        .is_some_and(|l| l.contains(':') && l.contains('-') && l.contains(' '));
    if !dated {
        return read_kitti_times(path);
    }
    let times = crate::timestamp::read_timestamps(path)?;
    if times.is_empty() {
        return Err(file_error(path, "no times"));
    }
    if let Some(first) = times.iter().position(|&t| t < 0.0) {
        return Err(line_error(
            path,
            first + 1,
            "a time before 1970 (the Unix epoch); scan times are never negative",
        ));
    }
    if let Some(i) = times.windows(2).position(|w| w[1] <= w[0]) {
        return Err(ReadError::NotIncreasing {
            path: path.to_path_buf(),
            line: i + 2,
            time: times[i + 1],
            previous: times[i],
        });
    }
    Ok(times)
}

/// Writes times one per line (KITTI odometry `times.txt`), in shortest round-trip form.
///
/// # Errors
///
/// The writer's I/O error.
pub fn write_kitti_times<W: Write>(out: &mut W, times: &[f64]) -> std::io::Result<()> {
    for t in times {
        writeln!(out, "{t:e}")?;
    }
    Ok(())
}

/// Reads the `world_from_cam0` matrices of a KITTI odometry pose file, one per data line, as
/// written (the world is camera 0 of frame 0: x right, y down, z forward).
///
/// # Errors
///
/// [`ReadError`] with the line: not 12 numbers, a non-number, or a rotation block that is not a
/// rotation (see [`crate::calib::ROTATION_TOLERANCE`]).
pub fn read_kitti_odometry_cam0(path: &Path) -> Result<Vec<Isometry3<f64>>, ReadError> {
    let text = read_text(path)?;
    let mut poses = Vec::new();
    for (line, data) in data_lines(&text) {
        let v = numbers_on_line::<12>(
            path,
            line,
            data,
            "KITTI odometry: a 3x4 row-major world_from_cam0 matrix",
        )?;
        let pose = isometry_from_3x4(&v).map_err(|m| line_error(path, line, m))?;
        check_position_bound(path, line, &pose.translation.vector)?;
        poses.push(pose);
    }
    Ok(poses)
}

/// Reads a KITTI odometry pose file as a track of the **Velodyne** in a z-up world.
///
/// The file's line i is `P_i = world_cam0_from_cam0_i`, where the world is camera 0 of frame 0
/// (x right, y down, z forward: not a map frame). With `Tr = cam0_from_velo` from the sequence's
/// `calib.txt` ([`crate::calib::read_odometry_cam0_from_velo`]), take as world the Velodyne frame
/// of frame 0, which sits to camera 0 of frame 0 exactly as every Velodyne sits to its camera:
/// `world_cam0_from_world_velo = Tr`. Then
///
/// `world_velo_from_velo_i = world_velo_from_world_cam0 · world_cam0_from_cam0_i ·
/// cam0_i_from_velo_i = Tr⁻¹ · P_i · Tr`,
///
/// a frame with x forward, y left, z up (as level as the car was at frame 0). The file has no
/// times: `times` gives one per line (from `times.txt`, [`read_kitti_times`], or from the scans).
///
/// # Errors
///
/// [`ReadError`]: a malformed line (with its number), a count that differs from `times.len()`,
/// or `times` not strictly increasing.
pub fn read_kitti_odometry(
    path: &Path,
    times: &[f64],
    cam0_from_velo: &Isometry3<f64>,
) -> Result<PoseTrack, ReadError> {
    let cam0 = read_kitti_odometry_cam0(path)?;
    if cam0.len() != times.len() {
        return Err(file_error(
            path,
            format!(
                "{} poses for {} times (KITTI odometry pose files have one line per frame and no \
                 times; the times come from times.txt or the scans)",
                cam0.len(),
                times.len()
            ),
        ));
    }
    let velo_from_cam0 = cam0_from_velo.inverse();
    let poses = cam0
        .iter()
        .map(|p| velo_from_cam0 * p * cam0_from_velo)
        .collect();
    PoseTrack::new(times.to_vec(), poses)
        .map_err(|e| file_error(path, format!("the times given for these poses: {e}")))
}

/// Writes a Velodyne track in KITTI odometry format, the inverse of [`read_kitti_odometry`]:
/// line i is `P_i = Tr · world_velo_from_velo_i · Tr⁻¹`, 12 numbers in shortest round-trip
/// form. The times are not written (see [`write_kitti_times`]).
///
/// # Errors
///
/// The writer's I/O error.
pub fn write_kitti_odometry<W: Write>(
    out: &mut W,
    track: &PoseTrack,
    cam0_from_velo: &Isometry3<f64>,
) -> std::io::Result<()> {
    let velo_from_cam0 = cam0_from_velo.inverse();
    for pose in track.poses() {
        let p = cam0_from_velo * pose * velo_from_cam0;
        let words: Vec<String> = rows_3x4(&p).iter().map(|v| format!("{v:e}")).collect();
        writeln!(out, "{}", words.join(" "))?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// evigrid's own format

/// One line of an evigrid pose file in the WGS84 frame, unprojected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeodeticPose {
    /// 1-based line in the file (for errors found later, when projecting).
    pub line: usize,
    /// Time, seconds.
    pub time_s: f64,
    /// Latitude, degrees, in [-90, 90].
    pub lat_deg: f64,
    /// Longitude, degrees, in [-180, 180].
    pub lon_deg: f64,
    /// Altitude, metres (becomes z).
    pub alt_m: f64,
    /// Roll, radians.
    pub roll: f64,
    /// Pitch, radians.
    pub pitch: f64,
    /// Yaw, radians, from true east, counter-clockwise.
    pub yaw: f64,
}

/// What an evigrid pose file holds: poses in the map's local frame, or geodetic ones for the
/// caller to project (the file does not know the map).
#[derive(Debug, Clone, PartialEq)]
pub enum EvigridPoses {
    /// `t x y z roll pitch yaw` in the local frame (the default, or after `# frame: local`).
    Local(PoseTrack),
    /// `t lat lon alt roll pitch yaw` (after `# frame: wgs84`), times strictly increasing.
    Wgs84 {
        /// The file, for errors found when projecting.
        path: PathBuf,
        /// The lines, in order.
        poses: Vec<GeodeticPose>,
    },
}

impl EvigridPoses {
    /// The poses as a track in the projection's frame: local poses as they are, geodetic ones
    /// through [`crate::oxts::world_from_geodetic`] (heading turned by the grid convergence, as
    /// for OXTS).
    ///
    /// # Errors
    ///
    /// [`ReadError::Line`] naming the line whose position the projection cannot place.
    pub fn into_track<P>(self, projection: &P) -> Result<PoseTrack, ReadError>
    where
        P: Fn(f64, f64) -> (f64, f64) + ?Sized,
    {
        match self {
            EvigridPoses::Local(track) => Ok(track),
            EvigridPoses::Wgs84 { path, poses } => {
                let mut world = Vec::with_capacity(poses.len());
                for g in &poses {
                    let pose = world_from_geodetic(
                        [g.lat_deg, g.lon_deg, g.alt_m],
                        [g.roll, g.pitch, g.yaw],
                        projection,
                    )
                    .map_err(|e: ProjectionError| line_error(&path, g.line, e.to_string()))?;
                    world.push(pose);
                }
                track_from(&path, poses.iter().map(|g| g.time_s).collect(), world)
            }
        }
    }
}

/// Reads an evigrid pose file: `t x y z roll pitch yaw` per line (seconds, metres, radians,
/// `R = Rz(yaw) · Ry(pitch) · Rx(roll)`), or `t lat lon alt roll pitch yaw` after a
/// `# frame: wgs84` line. A `# frame:` line must come before the first pose (a file in two
/// frames is a mistake); other `#` lines and blank lines are ignored.
///
/// # Errors
///
/// [`ReadError`] with the line: not 7 numbers, a non-number or non-finite value, latitude or
/// longitude out of range, an unknown frame or a frame line after data, times not strictly
/// increasing; or no poses.
pub fn read_evigrid(path: &Path) -> Result<EvigridPoses, ReadError> {
    let text = read_text(path)?;
    let mut wgs84 = false;
    let mut seen_data = false;
    let (mut previous, mut last) = (None, None);
    let (mut times, mut local, mut geodetic) = (Vec::new(), Vec::new(), Vec::new());
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let data = raw.trim();
        if data.is_empty() {
            continue;
        }
        if let Some(comment) = data.strip_prefix('#') {
            if let Some(frame) = comment.trim().strip_prefix("frame:") {
                if seen_data {
                    return Err(line_error(
                        path,
                        line,
                        "a `# frame:` line after poses; it must come first",
                    ));
                }
                wgs84 = match frame.trim() {
                    "wgs84" => true,
                    "local" => false,
                    other => {
                        return Err(line_error(
                            path,
                            line,
                            format!("unknown frame `{other}` (wgs84 or local)"),
                        ));
                    }
                };
            }
            continue;
        }
        seen_data = true;
        let what = if wgs84 {
            "evigrid wgs84: t lat lon alt roll pitch yaw"
        } else {
            "evigrid: t x y z roll pitch yaw"
        };
        let [t, a, b, z, roll, pitch, yaw] = numbers_on_line::<7>(path, line, data, what)?;
        check_increasing(path, line, t, &mut previous)?;
        check_angles(roll, pitch, yaw).map_err(|m| line_error(path, line, m))?;
        if wgs84 {
            check_lat_lon(a, b).map_err(|m| {
                line_error(
                    path,
                    line,
                    format!("{m} (columns after `# frame: wgs84`: t lat lon alt roll pitch yaw)"),
                )
            })?;
            if !(crate::oxts::MIN_ALTITUDE_M..=crate::oxts::MAX_ALTITUDE_M).contains(&z) {
                return Err(line_error(
                    path,
                    line,
                    format!(
                        "altitude {} m outside [{}, {}] m",
                        show(z),
                        crate::oxts::MIN_ALTITUDE_M,
                        crate::oxts::MAX_ALTITUDE_M
                    ),
                ));
            }
            geodetic.push(GeodeticPose {
                line,
                time_s: t,
                lat_deg: a,
                lon_deg: b,
                alt_m: z,
                roll,
                pitch,
                yaw,
            });
        } else {
            check_position(path, line, t, Vector3::new(a, b, z), &mut last)?;
            times.push(t);
            local.push(Isometry3::from_parts(
                Translation3::new(a, b, z),
                UnitQuaternion::from_euler_angles(roll, pitch, yaw),
            ));
        }
    }
    if wgs84 {
        if geodetic.is_empty() {
            return Err(file_error(path, "no poses"));
        }
        Ok(EvigridPoses::Wgs84 {
            path: path.to_path_buf(),
            poses: geodetic,
        })
    } else {
        track_from(path, times, local).map(EvigridPoses::Local)
    }
}

/// Writes a track in evigrid's local format (`t x y z roll pitch yaw`, `# frame: local` first),
/// the angles being those of `R = Rz(yaw) · Ry(pitch) · Rx(roll)`.
///
/// # Errors
///
/// The writer's I/O error.
pub fn write_evigrid<W: Write>(out: &mut W, track: &PoseTrack) -> std::io::Result<()> {
    writeln!(out, "# frame: local")?;
    for (t, pose) in track.times().iter().zip(track.poses()) {
        let p = pose.translation.vector;
        let (roll, pitch, yaw) = pose.rotation.euler_angles();
        writeln!(out, "{t} {} {} {} {roll} {pitch} {yaw}", p.x, p.y, p.z)?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Format choice

/// The pose file formats this crate reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PoseFormat {
    /// evigrid's 7 columns (local or WGS84), [`read_evigrid`].
    Evigrid,
    /// TUM's 8 columns, [`read_tum`].
    Tum,
    /// KITTI odometry's 12 columns, [`read_kitti_odometry`].
    KittiOdometry,
}

/// A pose format name that is not one of ours.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown pose format `{0}` (evigrid, tum or kitti)")]
pub struct UnknownPoseFormat(pub String);

impl FromStr for PoseFormat {
    type Err = UnknownPoseFormat;

    /// `evigrid`, `tum`, `kitti` (or `kitti-odometry`), any case.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "evigrid" => Ok(PoseFormat::Evigrid),
            "tum" => Ok(PoseFormat::Tum),
            "kitti" | "kitti-odometry" | "kitti_odometry" => Ok(PoseFormat::KittiOdometry),
            _ => Err(UnknownPoseFormat(s.chars().take(64).collect())),
        }
    }
}

impl PoseFormat {
    /// The format with this many columns per data line: 7, 8 or 12.
    pub fn from_columns(columns: usize) -> Option<Self> {
        match columns {
            7 => Some(PoseFormat::Evigrid),
            8 => Some(PoseFormat::Tum),
            12 => Some(PoseFormat::KittiOdometry),
            _ => None,
        }
    }

    /// Detects a file's format from its first data line (not blank, not `#`): 7 columns →
    /// evigrid, 8 → TUM, 12 → KITTI odometry.
    ///
    /// # Errors
    ///
    /// [`ReadError::Columns`] (listing the three formats) for another count;
    /// [`ReadError::File`] for a file without data lines.
    pub fn detect(path: &Path) -> Result<Self, ReadError> {
        let text = read_text(path)?;
        let Some((line, data)) = data_lines(&text).next() else {
            return Err(file_error(path, "no pose lines to tell the format from"));
        };
        let found = data.split_whitespace().count();
        let hint = if data.contains(',') {
            " (separated by commas? columns are separated by spaces or tabs:              `tr ',' ' ' < FILE.csv`)"
        } else {
            ""
        };
        PoseFormat::from_columns(found).ok_or_else(|| ReadError::Columns {
            path: path.to_path_buf(),
            line,
            found,
            hint: hint.to_owned(),
        })
    }
}

/// What reading a KITTI odometry pose file needs besides the file.
#[derive(Debug, Clone, Copy)]
pub struct KittiOdometryContext<'a> {
    /// One time per pose line (from `times.txt` or the scans).
    pub times: &'a [f64],
    /// `Tr` of the sequence's `calib.txt`.
    pub cam0_from_velo: Isometry3<f64>,
}

/// Reads any pose file into a track, the format given or [detected](PoseFormat::detect).
/// `kitti` is needed for KITTI odometry files, `projection` for evigrid files in WGS84.
///
/// # Errors
///
/// [`ReadError`] from the format's reader, or [`ReadError::File`] when what the format needs
/// (`kitti`, `projection`) was not given.
pub fn read_pose_track(
    path: &Path,
    format: Option<PoseFormat>,
    kitti: Option<&KittiOdometryContext<'_>>,
    projection: Option<&dyn Fn(f64, f64) -> (f64, f64)>,
) -> Result<PoseTrack, ReadError> {
    let format = match format {
        Some(format) => format,
        None => PoseFormat::detect(path)?,
    };
    match format {
        PoseFormat::Tum => read_tum(path),
        PoseFormat::KittiOdometry => {
            let Some(kitti) = kitti else {
                return Err(file_error(
                    path,
                    "KITTI odometry poses need the scan times (or times.txt) and the \
                     sequence's calib.txt",
                ));
            };
            read_kitti_odometry(path, kitti.times, &kitti.cam0_from_velo)
        }
        PoseFormat::Evigrid => match read_evigrid(path)? {
            EvigridPoses::Local(track) => Ok(track),
            wgs84 @ EvigridPoses::Wgs84 { .. } => match projection {
                Some(projection) => wgs84.into_track(projection),
                None => Err(file_error(
                    path,
                    "poses in WGS84 (`# frame: wgs84`) need a projection (a map)",
                )),
            },
        },
    }
}

// ---------------------------------------------------------------------------------------------
// Mounting

/// Where a sensor sits on the vehicle whose poses a file gives: `vehicle_from_sensor`.
///
/// Parsed from `x,y,z,roll,pitch,yaw` (metres, radians, `R = Rz(yaw) · Ry(pitch) · Rx(roll)`,
/// vehicle frame x forward, y left, z up), as a command line gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mounting {
    /// The sensor's pose in the vehicle frame.
    pub vehicle_from_sensor: Isometry3<f64>,
}

/// Why a mounting string could not be parsed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("mounting `{input}`: {message} (expected x,y,z,roll,pitch,yaw in metres and radians)")]
pub struct MountingError {
    /// The offending text (cut to 64 characters).
    pub input: String,
    /// What is wrong.
    pub message: String,
}

impl FromStr for Mounting {
    type Err = MountingError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let fail = |message: String| MountingError {
            input: s.chars().take(64).collect(),
            message,
        };
        let mut v = [0.0; 6];
        let mut count = 0usize;
        for word in s.split(',') {
            if count < 6 {
                v[count] = crate::text::number(word.trim()).map_err(fail)?;
            }
            count += 1;
        }
        if count != 6 {
            return Err(fail(format!("{count} values, expected 6")));
        }
        let offset_m = Vector3::new(v[0], v[1], v[2]).norm();
        if offset_m > MAX_MOUNTING_OFFSET_M {
            return Err(fail(format!(
                "the sensor is {} m from the vehicle's origin, beyond \
                 {MAX_MOUNTING_OFFSET_M} m",
                show(offset_m)
            )));
        }
        check_angles(v[3], v[4], v[5]).map_err(fail)?;
        Ok(Mounting {
            vehicle_from_sensor: Isometry3::from_parts(
                Translation3::from(Vector3::new(v[0], v[1], v[2])),
                UnitQuaternion::from_euler_angles(v[3], v[4], v[5]),
            ),
        })
    }
}

impl Mounting {
    /// `world_from_sensor = world_from_vehicle · vehicle_from_sensor`.
    pub fn world_from_sensor(&self, world_from_vehicle: &Isometry3<f64>) -> Isometry3<f64> {
        world_from_vehicle * self.vehicle_from_sensor
    }

    /// The sensor's track from the vehicle's.
    pub fn apply(&self, world_from_vehicle: &PoseTrack) -> PoseTrack {
        world_from_vehicle.then(&self.vehicle_from_sensor)
    }
}

#[cfg(test)]
mod tests;
