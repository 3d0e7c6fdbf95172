//! A KITTI raw drive folder, as published: scans, their times, OXTS packets and calibration.
//!
//! Layout ([`LAYOUT`]):
//!
//! ```text
//! 2011_09_26/                               the date folder: one calibration per day
//!   calib_imu_to_velo.txt                   velo_from_imu
//!   2011_09_26_drive_0013_sync/             the drive folder
//!     velodyne_points/data/0000000000.bin   scans, numbered from 0 without gaps
//!     velodyne_points/timestamps.txt        one time per scan
//!     oxts/data/0000000000.txt              one OXTS packet per scan (synced data)
//!     oxts/timestamps.txt                   one time per packet
//! ```
//!
//! Scan times are the Velodyne's `timestamps.txt`: the moment the rotating head faces forward,
//! the middle of the scan (`timestamps_start.txt` and `timestamps_end.txt` bracket it). In the
//! synced data, packet i goes with scan i but is not taken at the same moment: scans come
//! 12–22 ms before their packet. So the Velodyne's pose is the IMU pose *interpolated at the scan
//! time* (through [`PoseTrack`]), composed with the calibrated lever arm: `world_from_velo =
//! world_from_imu(t_scan) · imu_from_velo`. The first scan of a drive precedes the first packet,
//! so up to [`MAX_EXTRAPOLATION_S`] beyond the packets' span the IMU pose is extrapolated at
//! constant velocity (at 12 m/s, 20 ms is 24 cm: far too much to ignore by taking the nearest
//! packet).

use crate::calib::read_velo_from_imu;
use crate::error::ReadError;
use crate::oxts::{
    OxtsPacket, ProjectionError, check_packet_jumps, read_oxts_packet, world_from_imu,
};
use crate::poses::{PoseTrack, TrackError};
use crate::timestamp::read_timestamps;
use nalgebra::Isometry3;
use std::fs;
use std::path::{Path, PathBuf};

/// The KITTI raw layout this reader expects, for error messages.
pub const LAYOUT: &str = "the KITTI raw layout: <date>/calib_imu_to_velo.txt and \
    <date>/<date>_drive_<NNNN>_sync/ holding velodyne_points/{timestamps.txt, data/NNNNNNNNNN.bin} \
    and oxts/{timestamps.txt, data/NNNNNNNNNN.txt}";

/// How far (seconds) before the first or after the last OXTS packet a scan may lie and still get
/// an extrapolated pose: half the 10 Hz period, so that every scan of a synced drive (12–22 ms
/// before its packet) is placed, and nothing further off is.
pub const MAX_EXTRAPOLATION_S: f64 = 0.05;

/// Why a KITTI raw drive could not be opened or placed. Every variant names a file or folder.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum KittiRawError {
    /// A file or folder of the layout is missing.
    #[error("{path}: missing ({what}); expected {LAYOUT}")]
    Missing {
        /// The path that should exist.
        path: PathBuf,
        /// What it should hold.
        what: &'static str,
    },
    /// The folder is neither a drive nor a date folder holding a drive.
    #[error(
        "{dir}: no KITTI raw drive here (no velodyne_points/ and no *_sync/ folder); expected {LAYOUT}"
    )]
    NoDrive {
        /// The folder given.
        dir: PathBuf,
    },
    /// A date folder holds several drives; which one is meant is not ours to guess.
    #[error("{dir}: holds {} drives ({}); give one drive folder", .drives.len(), .drives.join(", "))]
    SeveralDrives {
        /// The folder given.
        dir: PathBuf,
        /// The drive folder names found.
        drives: Vec<String>,
    },
    /// A folder could not be listed.
    #[error("{path}: {source}")]
    Io {
        /// The folder.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A data folder holds a different number of files than its `timestamps.txt` has times.
    #[error("{dir}: {files} files, but {timestamps} has {times} times (one per file expected)")]
    CountMismatch {
        /// The data folder.
        dir: PathBuf,
        /// Files found in it.
        files: usize,
        /// The timestamps file.
        timestamps: PathBuf,
        /// Times in it.
        times: usize,
    },
    /// There are not as many OXTS packets as scans (synced data has one per scan).
    #[error("{drive}: {scans} scans but {packets} OXTS packets (synced data has one per scan)")]
    FrameCount {
        /// The drive folder.
        drive: PathBuf,
        /// Scans.
        scans: usize,
        /// OXTS packets.
        packets: usize,
    },
    /// A data file is not named as the frame sequence requires (a gap or a stray file).
    #[error("{path}: expected {expected} here (frames are numbered from 0 without gaps)")]
    UnexpectedName {
        /// The file found.
        path: PathBuf,
        /// The file name expected in its place.
        expected: String,
    },
    /// A text file of the drive is malformed.
    #[error(transparent)]
    Read(#[from] ReadError),
    /// The projection cannot place an OXTS packet.
    #[error("{path}: {source}")]
    Projection {
        /// The packet file.
        path: PathBuf,
        /// Why.
        source: ProjectionError,
    },
    /// Poses could not form a track (a projection giving non-finite values).
    #[error("{path}: {source}")]
    Track {
        /// The timestamps file of the track.
        path: PathBuf,
        /// Why.
        source: TrackError,
    },
    /// A scan time lies too far outside the OXTS packets' times.
    #[error("scan {scan} (time from {timestamps}): {source}")]
    OutsideOxts {
        /// The scan file.
        scan: PathBuf,
        /// The scan timestamps file.
        timestamps: PathBuf,
        /// The track error, with the time and the span.
        source: TrackError,
    },
}

/// One frame of a drive: a scan and what places it.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiRawFrame {
    /// 0-based frame number (the file name's number).
    pub index: usize,
    /// `velodyne_points/data/NNNNNNNNNN.bin`.
    pub scan_path: PathBuf,
    /// Scan time (mid-scan), seconds since the Unix epoch.
    pub time_s: f64,
    /// The OXTS packet synced with this scan (its geodetic fix, attitude, velocities).
    pub oxts: OxtsPacket,
    /// The packet's own time, seconds since the Unix epoch.
    pub oxts_time_s: f64,
}

/// A KITTI raw drive, read and checked at [`KittiRawDrive::open`]; scans are read later, one at
/// a time, by the caller (`crate::scan::read_scan`).
#[derive(Debug, Clone)]
pub struct KittiRawDrive {
    drive_dir: PathBuf,
    scan_paths: Vec<PathBuf>,
    scan_times: Vec<f64>,
    scan_timestamps: PathBuf,
    oxts_paths: Vec<PathBuf>,
    oxts_times: Vec<f64>,
    oxts: Vec<OxtsPacket>,
    velo_from_imu: Isometry3<f64>,
}

/// The path if it exists, else [`KittiRawError::Missing`].
fn existing(path: PathBuf, what: &'static str) -> Result<PathBuf, KittiRawError> {
    if path.exists() {
        Ok(path)
    } else {
        Err(KittiRawError::Missing { path, what })
    }
}

/// The files of `dir` with extension `ext`, sorted, checked to be `0000000000.ext`,
/// `0000000001.ext`, … and as many as `times` (read from `timestamps`).
fn numbered_files(
    dir: &Path,
    ext: &str,
    times: usize,
    timestamps: &Path,
) -> Result<Vec<PathBuf>, KittiRawError> {
    let io = |source| KittiRawError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut paths = Vec::new();
    for entry in fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if path.extension().and_then(|e| e.to_str()) == Some(ext) {
            paths.push(path);
        }
    }
    paths.sort();
    if paths.len() != times {
        return Err(KittiRawError::CountMismatch {
            dir: dir.to_path_buf(),
            files: paths.len(),
            timestamps: timestamps.to_path_buf(),
            times,
        });
    }
    for (i, path) in paths.iter().enumerate() {
        let expected = format!("{i:010}.{ext}");
        if path.file_name().and_then(|n| n.to_str()) != Some(expected.as_str()) {
            return Err(KittiRawError::UnexpectedName {
                path: path.clone(),
                expected,
            });
        }
    }
    Ok(paths)
}

/// Reads a timestamps file and checks that its times strictly increase (with the line).
fn increasing_times(path: &Path) -> Result<Vec<f64>, KittiRawError> {
    let times = read_timestamps(path)?;
    if let Some(i) = times.windows(2).position(|w| w[1] <= w[0]) {
        return Err(ReadError::NotIncreasing {
            path: path.to_path_buf(),
            line: i + 2,
            time: times[i + 1],
            previous: times[i],
        }
        .into());
    }
    Ok(times)
}

impl KittiRawDrive {
    /// Opens a drive: `path` is the drive's `*_sync` folder (calibration in its parent, the date
    /// folder) or a date folder holding exactly one drive. Reads and checks every text file:
    /// timestamps (strictly increasing), OXTS packets, calibration, and the scan files' names and
    /// count against the timestamps.
    ///
    /// # Errors
    ///
    /// [`KittiRawError`]: a missing file (named, with the expected layout), several or no drives,
    /// counts that disagree, a malformed text file (file and line).
    pub fn open(path: &Path) -> Result<Self, KittiRawError> {
        let given = existing(path.to_path_buf(), "a KITTI raw drive or date folder")?;
        let given = fs::canonicalize(&given).map_err(|source| KittiRawError::Io {
            path: given.clone(),
            source,
        })?;
        let drive_dir = if given.join("velodyne_points").is_dir() || given.join("oxts").is_dir() {
            given
        } else {
            let io = |source| KittiRawError::Io {
                path: given.clone(),
                source,
            };
            let mut drives = Vec::new();
            for entry in fs::read_dir(&given).map_err(io)? {
                let p = entry.map_err(io)?.path();
                let is_drive = p.is_dir()
                    && (p.join("velodyne_points").is_dir()
                        || p.file_name()
                            .and_then(|n| n.to_str())
                            .is_some_and(|n| n.ends_with("_sync")));
                if is_drive {
                    drives.push(p);
                }
            }
            drives.sort();
            match drives.len() {
                0 => return Err(KittiRawError::NoDrive { dir: given }),
                1 => drives.remove(0),
                _ => {
                    let drives = drives
                        .iter()
                        .filter_map(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
                        .collect();
                    return Err(KittiRawError::SeveralDrives { dir: given, drives });
                }
            }
        };
        let date_dir = drive_dir.parent().unwrap_or(&drive_dir).to_path_buf();

        let calib = existing(
            date_dir.join("calib_imu_to_velo.txt"),
            "the IMU-to-Velodyne calibration, in the date folder above the drive",
        )?;
        let velo = existing(
            drive_dir.join("velodyne_points"),
            "the Velodyne scans folder",
        )?;
        let scan_timestamps = existing(velo.join("timestamps.txt"), "the scan times")?;
        let scan_data = existing(velo.join("data"), "the scan files NNNNNNNNNN.bin")?;
        let oxts_dir = existing(drive_dir.join("oxts"), "the OXTS GPS/IMU folder")?;
        let oxts_timestamps = existing(oxts_dir.join("timestamps.txt"), "the OXTS packet times")?;
        let oxts_data = existing(
            oxts_dir.join("data"),
            "the OXTS packet files NNNNNNNNNN.txt",
        )?;

        let velo_from_imu = read_velo_from_imu(&calib)?;
        let scan_times = increasing_times(&scan_timestamps)?;
        let scan_paths = numbered_files(&scan_data, "bin", scan_times.len(), &scan_timestamps)?;
        let oxts_times = increasing_times(&oxts_timestamps)?;
        let oxts_paths = numbered_files(&oxts_data, "txt", oxts_times.len(), &oxts_timestamps)?;
        if oxts_paths.len() != scan_paths.len() {
            return Err(KittiRawError::FrameCount {
                drive: drive_dir,
                scans: scan_paths.len(),
                packets: oxts_paths.len(),
            });
        }
        if scan_paths.is_empty() {
            return Err(KittiRawError::Missing {
                path: scan_data,
                what: "at least one scan",
            });
        }
        let oxts = oxts_paths
            .iter()
            .map(|p| read_oxts_packet(p))
            .collect::<Result<Vec<_>, _>>()?;
        check_packet_jumps(&oxts_paths, &oxts_times, &oxts)?;
        Ok(Self {
            drive_dir,
            scan_paths,
            scan_times,
            scan_timestamps,
            oxts_paths,
            oxts_times,
            oxts,
            velo_from_imu,
        })
    }

    /// The drive folder (canonical path).
    pub fn drive_dir(&self) -> &Path {
        &self.drive_dir
    }

    /// Number of frames (scans), at least one.
    pub fn len(&self) -> usize {
        self.scan_paths.len()
    }

    /// Always false: [`KittiRawDrive::open`] refuses a drive without scans.
    pub fn is_empty(&self) -> bool {
        self.scan_paths.is_empty()
    }

    /// Scan times (mid-scan), seconds since the Unix epoch, strictly increasing.
    pub fn scan_times(&self) -> &[f64] {
        &self.scan_times
    }

    /// OXTS packet times, seconds since the Unix epoch, strictly increasing.
    pub fn oxts_times(&self) -> &[f64] {
        &self.oxts_times
    }

    /// The OXTS packets, one per frame.
    pub fn oxts(&self) -> &[OxtsPacket] {
        &self.oxts
    }

    /// `velo_from_imu`, from `calib_imu_to_velo.txt`.
    pub fn velo_from_imu(&self) -> Isometry3<f64> {
        self.velo_from_imu
    }

    /// `imu_from_velo`: where the Velodyne sits on the IMU (the lever arm).
    pub fn imu_from_velo(&self) -> Isometry3<f64> {
        self.velo_from_imu.inverse()
    }

    /// The frames, in order: scan path, scan time, synced OXTS packet.
    pub fn frames(&self) -> Vec<KittiRawFrame> {
        self.scan_paths
            .iter()
            .zip(&self.scan_times)
            .zip(self.oxts.iter().zip(&self.oxts_times))
            .enumerate()
            .map(
                |(index, ((scan_path, &time_s), (oxts, &oxts_time_s)))| KittiRawFrame {
                    index,
                    scan_path: scan_path.clone(),
                    time_s,
                    oxts: *oxts,
                    oxts_time_s,
                },
            )
            .collect()
    }

    /// The IMU's track at the OXTS packet times, in the projection's frame (see
    /// [`crate::oxts::world_from_imu`]).
    ///
    /// # Errors
    ///
    /// [`KittiRawError::Projection`] naming the packet the projection cannot place.
    pub fn world_from_imu<P>(&self, projection: &P) -> Result<PoseTrack, KittiRawError>
    where
        P: Fn(f64, f64) -> (f64, f64) + ?Sized,
    {
        let mut poses = Vec::with_capacity(self.oxts.len());
        for (packet, path) in self.oxts.iter().zip(&self.oxts_paths) {
            poses.push(world_from_imu(packet, projection).map_err(|source| {
                KittiRawError::Projection {
                    path: path.clone(),
                    source,
                }
            })?);
        }
        // Times were checked at open; what can fail here is a projection's non-finite output.
        PoseTrack::new(self.oxts_times.clone(), poses).map_err(|source| KittiRawError::Track {
            path: self.drive_dir.join("oxts/timestamps.txt"),
            source,
        })
    }

    /// The Velodyne's pose at each scan time: the IMU track interpolated at the scan time
    /// (extrapolated up to [`MAX_EXTRAPOLATION_S`] beyond the packets), composed with
    /// `imu_from_velo`.
    ///
    /// # Errors
    ///
    /// [`KittiRawError::Projection`], or [`KittiRawError::OutsideOxts`] for a scan too far from
    /// every packet.
    pub fn world_from_velodyne<P>(
        &self,
        projection: &P,
    ) -> Result<Vec<Isometry3<f64>>, KittiRawError>
    where
        P: Fn(f64, f64) -> (f64, f64) + ?Sized,
    {
        let imu = self.world_from_imu(projection)?;
        let imu_from_velo = self.imu_from_velo();
        self.scan_times
            .iter()
            .zip(&self.scan_paths)
            .map(|(&t, scan)| {
                imu.at_extrapolated(t, MAX_EXTRAPOLATION_S)
                    .map(|world_from_imu| world_from_imu * imu_from_velo)
                    .map_err(|source| KittiRawError::OutsideOxts {
                        scan: scan.clone(),
                        timestamps: self.scan_timestamps.clone(),
                        source,
                    })
            })
            .collect()
    }

    /// [`KittiRawDrive::world_from_velodyne`] as a track at the scan times.
    ///
    /// # Errors
    ///
    /// As [`KittiRawDrive::world_from_velodyne`].
    pub fn velodyne_track<P>(&self, projection: &P) -> Result<PoseTrack, KittiRawError>
    where
        P: Fn(f64, f64) -> (f64, f64) + ?Sized,
    {
        let poses = self.world_from_velodyne(projection)?;
        PoseTrack::new(self.scan_times.clone(), poses).map_err(|source| KittiRawError::Track {
            path: self.scan_timestamps.clone(),
            source,
        })
    }
}
