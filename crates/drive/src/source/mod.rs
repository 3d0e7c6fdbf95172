//! A drive as one object: where its scans come from, where its poses come from, and the rule
//! that matches the two, whatever the drive's format.
//!
//! A [`DriveSpec`] names a drive as a user gives it: a KITTI raw drive folder, a folder of scans
//! (with a pose file, or none), or a ROS 2 recording. [`Drive::open`] lists its scans and their
//! times; [`Drive::place`] gives every scan its `world_from_sensor` by the matching rule below
//! and says where the poses came from ([`PoseOrigin`]); [`Drive::frames`] then reads the scans
//! in order as [`Frame`]s (name, time, points with intensity, pose).
//!
//! The matching rule (README, "Pose files"):
//! - scan times come from a KITTI raw drive, from a times file, or from a `timestamps.txt`
//!   beside the scan folder (KITTI raw's `velodyne_points/{data/, timestamps.txt}`) or inside
//!   it (or a `times.txt`);
//! - with scan times, each scan takes the pose interpolated at its time (linear position, slerp
//!   rotation); a scan outside the poses' span (beyond the track's 1 ms tolerance) is an error
//!   naming it;
//! - without scan times, pose line k goes with scan k (the counts must agree) and the scan's
//!   time is the line's; a format without times (KITTI odometry) takes the scans
//!   [`DEFAULT_SCAN_PERIOD_S`] apart from 0.
//!
//! Two decisions shape the API:
//! - **WGS84 poses need the caller's projection.** OXTS packets, NavSatFix fixes and
//!   `# frame: wgs84` pose files are placed by a projection `(lat, lon) → (east, north)` in
//!   metres that [`Drive::place`] takes as a function: this crate knows no map. The session
//!   chooses it (the map's, an origin's, or the transverse Mercator at the drive's first fix,
//!   [`Drive::first_fix`]).
//! - **Scans without poses are placed by the caller.** The lidar odometry sits beside this crate
//!   at the bottom layer, so a drive whose [`Drive::pose_origin`] is [`PoseOrigin::Odometry`]
//!   is read with [`Drive::scans`], registered by the caller (the session crate's odometry
//!   pass), and placed with [`Drive::place_with`].

mod matching;
mod reader;

use std::fmt;
use std::path::{Path, PathBuf};

use nalgebra::Isometry3;

use crate::bag::{BagDrive, BagOptions, PoseSource};
use crate::kitti_raw::KittiRawDrive;
use crate::poses::{Mounting, PoseFormat};

pub use reader::{Frame, Frames, GnssFix, ScanRead, Scans, SkippedScan};

/// Time between scans that have no timestamps: the 10 Hz of spinning lidars.
pub const DEFAULT_SCAN_PERIOD_S: f64 = 0.1;

/// A drive as a user names it.
#[derive(Clone, Debug, PartialEq)]
pub enum DriveSpec {
    /// A KITTI raw drive: its `<date>_drive_<NNNN>_sync` folder or the date folder holding one.
    /// Poses from its OXTS packets and `calib_imu_to_velo.txt`, unless `poses` is given.
    KittiRaw {
        /// The folder.
        dir: PathBuf,
        /// A pose file matched to the drive's scan times instead of the OXTS poses.
        poses: Option<PoseFileSpec>,
    },
    /// A folder of scans (PCD or KITTI `.bin`, in file-name order). A folder holding no scan but
    /// a KITTI raw drive is opened as [`DriveSpec::KittiRaw`] (when `times` is not given).
    ScanFolder {
        /// The folder.
        dir: PathBuf,
        /// Scan times (KITTI raw `timestamps.txt`, KITTI odometry `times.txt`); by default a
        /// timestamps file beside or in the folder, if any.
        times: Option<PathBuf>,
        /// The pose file; without one the scans have no poses ([`PoseOrigin::Odometry`]).
        poses: Option<PoseFileSpec>,
    },
    /// A ROS 2 recording (MCAP) of `sensor_msgs/PointCloud2` scans.
    Bag {
        /// The recording.
        path: PathBuf,
        /// The PointCloud2 topic (by default the only one).
        cloud_topic: Option<String>,
        /// Where its poses come from.
        pose_source: PoseSource,
    },
}

impl DriveSpec {
    /// Every file or folder the spec names (the scans' folder or recording, the pose, calibration
    /// and times files): what an output must never replace.
    pub fn input_paths(&self) -> Vec<&Path> {
        let (main, times, poses) = match self {
            Self::KittiRaw { dir, poses } => (dir, None, poses.as_ref()),
            Self::ScanFolder { dir, times, poses } => (dir, times.as_ref(), poses.as_ref()),
            Self::Bag { path, .. } => (path, None, None),
        };
        let pose_files = poses
            .into_iter()
            .flat_map(|p| [Some(&p.path), p.calib.as_ref()]);
        [Some(main), times]
            .into_iter()
            .chain(pose_files)
            .flatten()
            .map(PathBuf::as_path)
            .collect()
    }
}

/// A pose file and how to read it.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseFileSpec {
    /// The file.
    pub path: PathBuf,
    /// Its format; detected from the column count when `None`.
    pub format: Option<PoseFormat>,
    /// KITTI odometry `calib.txt` (its `Tr`); the identity without one.
    pub calib: Option<PathBuf>,
    /// Vehicle → sensor, when the file gives the vehicle's poses.
    pub mounting: Option<Mounting>,
}

/// How scans met their poses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoseMatching {
    /// Interpolated at the scan times.
    Time,
    /// Pose line k for scan k.
    LineOrder,
    /// Registered by the lidar odometry (one pose per scan by construction).
    Odometry,
}

impl PoseMatching {
    /// The name the summary gives it: `time`, `line order`, `odometry`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Time => "time",
            Self::LineOrder => "line order",
            Self::Odometry => "odometry",
        }
    }
}

/// Where a drive's poses come from.
#[derive(Clone, Debug, PartialEq)]
pub enum PoseOrigin {
    /// A pose file.
    File {
        /// The file.
        path: PathBuf,
        /// By time, or by line order when the scans have no times.
        matching: PoseMatching,
    },
    /// A KITTI raw drive's OXTS packets, with the Velodyne's lever arm.
    Oxts {
        /// The drive's `*_sync` folder.
        drive_dir: PathBuf,
    },
    /// A recording's tf, Odometry or NavSatFix messages.
    Bag {
        /// Which ones (`tf map`, `odometry /odom`, …).
        source: String,
        /// The recording.
        path: PathBuf,
    },
    /// None given: the lidar odometry places the scans, in the first scan's frame.
    Odometry,
}

impl PoseOrigin {
    /// How scans meet these poses.
    pub fn matching(&self) -> PoseMatching {
        match self {
            Self::File { matching, .. } => *matching,
            Self::Oxts { .. } | Self::Bag { .. } => PoseMatching::Time,
            Self::Odometry => PoseMatching::Odometry,
        }
    }
}

impl fmt::Display for PoseOrigin {
    /// As the summary names it: the file, `OXTS of <drive>`, `<source> of <bag>`,
    /// `lidar odometry`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::File { path, .. } => write!(f, "{}", path.display()),
            Self::Oxts { drive_dir } => write!(f, "OXTS of {}", drive_dir.display()),
            Self::Bag { source, path } => write!(f, "{source} of {}", path.display()),
            Self::Odometry => f.write_str("lidar odometry"),
        }
    }
}

/// Why a drive cannot be opened or placed. Every message names the input and the problem.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SourceError {
    /// The drive, a scan time or a pose cannot be used (the message names the file).
    #[error("{0}")]
    Input(String),
    /// WGS84 poses and no projection to place them: `what` names them.
    #[error("{what}: WGS84 poses need a projection")]
    NeedsProjection {
        /// The poses (file or recording) and their kind.
        what: String,
    },
    /// [`Drive::place`] on a drive without poses: they come from [`Drive::place_with`].
    #[error("{0}: the scans have no poses (run the lidar odometry and place them with it)")]
    NoPoses(String),
}

/// One pose per scan, from the first: `world_from_sensor` at each scan's time.
#[derive(Clone, Debug, PartialEq)]
pub struct Poses {
    /// One time per placed scan, seconds.
    pub times: Vec<f64>,
    /// One pose per placed scan.
    pub world_from_sensor: Vec<Isometry3<f64>>,
    /// Where they came from.
    pub origin: PoseOrigin,
}

impl Poses {
    /// Number of placed scans.
    pub fn len(&self) -> usize {
        self.world_from_sensor.len()
    }

    /// True when no scan is placed.
    pub fn is_empty(&self) -> bool {
        self.world_from_sensor.is_empty()
    }

    /// The horizontal positions (east, north), metres: the ego's path.
    pub fn positions(&self) -> Vec<[f64; 2]> {
        self.world_from_sensor
            .iter()
            .map(|p| [p.translation.x, p.translation.y])
            .collect()
    }
}

/// Where a drive's scans are read from.
#[derive(Debug)]
enum Kind {
    /// PCD / KITTI `.bin` files.
    Files,
    /// A KITTI raw drive's Velodyne files.
    KittiRaw(Box<KittiRawDrive>),
    /// A recording's PointCloud2 messages.
    Bag(Box<BagDrive>),
}

/// An opened drive: its scans in order, their times when known, and where its poses come from.
#[derive(Debug)]
pub struct Drive {
    kind: Kind,
    /// Scan files in frame order (for a recording, `<bag>#NNNNNN` names).
    paths: Vec<PathBuf>,
    /// One time per scan (seconds), when the drive gives them.
    times: Option<Vec<f64>>,
    /// Where the times came from, for messages.
    times_source: Option<PathBuf>,
    /// The path given, for messages and the summary.
    given: PathBuf,
    /// The pose file, when one is given.
    pose_file: Option<PoseFileSpec>,
}

impl Drive {
    /// Opens the drive `spec` names: lists its scans and reads their times (the scans and the
    /// poses are read later).
    ///
    /// # Errors
    ///
    /// [`SourceError::Input`] naming the folder or file: no scans, an unreadable drive or times
    /// file, times and scans that do not pair up.
    pub fn open(spec: &DriveSpec) -> Result<Self, SourceError> {
        let bad = |e: &dyn fmt::Display| SourceError::Input(e.to_string());
        match spec {
            DriveSpec::KittiRaw { dir, poses } => {
                let mut drive = open_kitti_raw(dir)?;
                drive.pose_file.clone_from(poses);
                Ok(drive)
            }
            DriveSpec::ScanFolder { dir, times, poses } => {
                let mut drive = open_scan_folder(dir, times.as_deref())?;
                drive.pose_file.clone_from(poses);
                Ok(drive)
            }
            DriveSpec::Bag {
                path,
                cloud_topic,
                pose_source,
            } => {
                let options = BagOptions {
                    cloud_topic: cloud_topic.clone(),
                    pose_source: pose_source.clone(),
                };
                let bag = BagDrive::open(path, &options).map_err(|e| bad(&e))?;
                Ok(bag_drive(bag, path))
            }
        }
    }

    /// Number of scans.
    pub fn len(&self) -> usize {
        self.paths.len()
    }

    /// True when the drive has no scan.
    pub fn is_empty(&self) -> bool {
        self.paths.is_empty()
    }

    /// The path the drive was given as, for messages and the summary.
    pub fn given_path(&self) -> &Path {
        &self.given
    }

    /// Scan `k`'s name: its file name (`<bag>#NNNNNN` for a recording).
    pub fn scan_name(&self, k: usize) -> String {
        self.paths
            .get(k)
            .and_then(|p| p.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    }

    /// The scans' times, when the drive gives them.
    pub fn times(&self) -> Option<&[f64]> {
        self.times.as_deref()
    }

    /// The file the scan times were read from, when they were.
    pub fn times_source(&self) -> Option<&Path> {
        self.times_source.as_deref()
    }

    /// Scan times, or [`DEFAULT_SCAN_PERIOD_S`] apart from 0 when the scans have none.
    pub fn times_or_period(&self) -> Vec<f64> {
        match &self.times {
            Some(times) => times.clone(),
            None => (0..self.paths.len())
                .map(|k| k as f64 * DEFAULT_SCAN_PERIOD_S)
                .collect(),
        }
    }

    /// The first GNSS fix `(lat, lon)` in degrees, for a KITTI raw drive: the origin of the
    /// local frame when no map or origin gives one.
    pub fn first_fix(&self) -> Option<(f64, f64)> {
        match &self.kind {
            Kind::KittiRaw(drive) => drive.oxts().first().map(|p| (p.lat_deg, p.lon_deg)),
            _ => None,
        }
    }

    /// The GNSS fix of scan `k` (KITTI raw's OXTS packet), for recordings.
    pub fn gnss_fix(&self, k: usize) -> Option<GnssFix> {
        let Kind::KittiRaw(drive) = &self.kind else {
            return None;
        };
        let (packet, &time_s) = drive.oxts().get(k).zip(drive.oxts_times().get(k))?;
        Some(GnssFix {
            time_s,
            lat_deg: packet.lat_deg,
            lon_deg: packet.lon_deg,
            alt_m: packet.alt_m,
        })
    }

    /// True when the scans are a recording's messages, read as a stream: a message that cannot
    /// be read there breaks the pairing of later messages with poses.
    pub fn is_recording(&self) -> bool {
        matches!(self.kind, Kind::Bag(_))
    }

    /// Where [`Drive::place`] takes the poses from; [`PoseOrigin::Odometry`] when the drive
    /// has none.
    pub fn pose_origin(&self) -> PoseOrigin {
        if let Some(file) = &self.pose_file {
            return PoseOrigin::File {
                path: file.path.clone(),
                matching: if self.times.is_some() {
                    PoseMatching::Time
                } else {
                    PoseMatching::LineOrder
                },
            };
        }
        match &self.kind {
            Kind::KittiRaw(drive) => PoseOrigin::Oxts {
                drive_dir: drive.drive_dir().to_path_buf(),
            },
            Kind::Bag(bag) if !matches!(bag.poses(), crate::bag::BagPoses::None) => {
                PoseOrigin::Bag {
                    source: bag.pose_source().to_owned(),
                    path: bag.path().to_path_buf(),
                }
            }
            Kind::Files | Kind::Bag(_) => PoseOrigin::Odometry,
        }
    }

    /// Gives the scans their poses by the module's rule. `projection` maps WGS84 `(lat, lon)`
    /// in degrees to the local frame's `(east, north)` in metres. With scan times only the
    /// first `required` scans must lie in the poses' span: the poses of later scans, up to the
    /// first outside it, are still given (the ego's path ahead).
    ///
    /// # Errors
    ///
    /// [`SourceError::NoPoses`] when the drive has none ([`PoseOrigin::Odometry`]),
    /// [`SourceError::NeedsProjection`] for WGS84 poses without `projection`,
    /// [`SourceError::Input`] for an unreadable pose file, counts that disagree or a scan
    /// outside the poses' span (naming the scan and the file).
    pub fn place(
        &self,
        projection: Option<&dyn Fn(f64, f64) -> (f64, f64)>,
        required: usize,
    ) -> Result<Poses, SourceError> {
        let origin = self.pose_origin();
        let (times, world_from_sensor) = match (&self.pose_file, &self.kind) {
            (Some(file), _) => matching::from_file(self, file, projection, required)?,
            (None, Kind::KittiRaw(drive)) => matching::from_oxts(drive, projection)?,
            (None, Kind::Bag(bag)) if origin != PoseOrigin::Odometry => {
                matching::from_bag(bag, projection, required)?
            }
            (None, _) => {
                return Err(SourceError::NoPoses(self.given.display().to_string()));
            }
        };
        Ok(Poses {
            times,
            world_from_sensor,
            origin,
        })
    }

    /// Places the scans with poses the caller computed (the lidar odometry), one per scan from
    /// the first, at `times`.
    pub fn place_with(&self, times: Vec<f64>, world_from_sensor: Vec<Isometry3<f64>>) -> Poses {
        Poses {
            times,
            world_from_sensor,
            origin: PoseOrigin::Odometry,
        }
    }

    /// Keeps the scans at `indices` (increasing), with their times: after a pass that left
    /// unreadable scans out.
    pub fn keep(&mut self, indices: &[usize]) {
        self.paths = indices
            .iter()
            .filter_map(|&k| self.paths.get(k).cloned())
            .collect();
        if let Some(times) = &mut self.times {
            *times = indices
                .iter()
                .filter_map(|&k| times.get(k).copied())
                .collect();
        }
    }

    /// Keeps the first `n` scans.
    pub fn truncate(&mut self, n: usize) {
        self.paths.truncate(n);
        if let Some(times) = &mut self.times {
            times.truncate(n);
        }
    }

    /// The scans in order, without poses (for a pass that computes them).
    ///
    /// # Errors
    ///
    /// [`SourceError::Input`] when a recording cannot be read from its start.
    pub fn scans(&self) -> Result<Scans<'_>, SourceError> {
        Scans::new(self)
    }

    /// The placed scans in order as frames: scan `k` with `poses`' pose `k`, as many as both
    /// have. A scan that cannot be read is yielded as a [`SkippedScan`] naming it.
    ///
    /// # Errors
    ///
    /// [`SourceError::Input`] when a recording cannot be read from its start.
    pub fn frames<'a>(&'a self, poses: &'a Poses) -> Result<Frames<'a>, SourceError> {
        Frames::new(self, poses)
    }
}

/// Opens a KITTI raw drive (its `*_sync` folder or the date folder holding one).
fn open_kitti_raw(dir: &Path) -> Result<Drive, SourceError> {
    let drive = KittiRawDrive::open(dir).map_err(|e| SourceError::Input(e.to_string()))?;
    let paths = drive.frames().into_iter().map(|f| f.scan_path).collect();
    Ok(Drive {
        paths,
        times: Some(drive.scan_times().to_vec()),
        times_source: Some(drive.drive_dir().join("velodyne_points/timestamps.txt")),
        given: dir.to_path_buf(),
        kind: Kind::KittiRaw(Box::new(drive)),
        pose_file: None,
    })
}

/// Opens a folder of scans; a folder holding no scan but a KITTI raw drive is opened as one.
/// `times` overrides the timestamps found beside the scans.
fn open_scan_folder(dir: &Path, times: Option<&Path>) -> Result<Drive, SourceError> {
    let bad = |e: &dyn fmt::Display| SourceError::Input(e.to_string());
    let paths = crate::scan::list_scans(dir).map_err(|e| bad(&e))?;
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
        return Err(SourceError::Input(format!(
            "{}: no .pcd or .bin scans in this directory",
            dir.display()
        )));
    }
    let found = match times {
        Some(path) => Some(path.to_path_buf()),
        None => times_beside(dir),
    };
    let times = match &found {
        Some(path) => {
            let times = crate::poses::read_scan_times(path).map_err(|e| bad(&e))?;
            if times.len() != paths.len() {
                return Err(SourceError::Input(format!(
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
    Ok(Drive {
        kind: Kind::Files,
        paths,
        times,
        times_source: found,
        given: dir.to_path_buf(),
        pose_file: None,
    })
}

/// A timestamps file where KITTI puts one: `timestamps.txt` beside a `data` folder, or
/// `timestamps.txt` / `times.txt` inside the scan folder.
fn times_beside(dir: &Path) -> Option<PathBuf> {
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

/// A recording as a drive: one name per PointCloud2 message (`<bag>#k`) and the header stamps
/// as times; the points are read from the recording itself, in order.
fn bag_drive(bag: BagDrive, given: &Path) -> Drive {
    let times = bag.scan_times().to_vec();
    let stem = bag
        .path()
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let paths = (0..times.len())
        .map(|k| PathBuf::from(format!("{stem}#{k:06}")))
        .collect();
    Drive {
        paths,
        times: Some(times),
        times_source: Some(bag.path().to_path_buf()),
        given: given.to_path_buf(),
        kind: Kind::Bag(Box::new(bag)),
        pose_file: None,
    }
}

#[cfg(test)]
mod tests;
