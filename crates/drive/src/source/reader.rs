//! Reading a drive's scans in order: scan files by path, or a recording's PointCloud2
//! messages as they come (memory does not grow with the recording).

use nalgebra::Isometry3;

use super::{Drive, Kind, Poses, SourceError};
use crate::bag::BagScans;
use crate::scan::read_scan;

/// A GNSS fix that came with a scan (KITTI raw's OXTS packet), as a recording shows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssFix {
    /// Time of the fix, seconds.
    pub time_s: f64,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Altitude, metres.
    pub alt_m: f64,
}

/// One placed scan.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Index of the scan in the drive, from 0.
    pub index: usize,
    /// The scan's name: its file name, `<bag>#NNNNNN` for a recording.
    pub name: String,
    /// Time of the scan, seconds.
    pub time_s: f64,
    /// Points in the sensor frame, metres.
    pub points_in_sensor: Vec<[f32; 3]>,
    /// Intensity per point when the source has it (same length as the points), else empty.
    pub intensity: Vec<f32>,
    /// Where the sensor was: its pose in the local world frame.
    pub world_from_sensor: Isometry3<f64>,
    /// The GNSS fix that came with the scan, if any (KITTI raw).
    pub fix: Option<GnssFix>,
}

/// A scan left out, and why (the message names it).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SkippedScan {
    /// Index of the scan in the drive, from 0.
    pub index: usize,
    /// The scan's name.
    pub name: String,
    /// Why.
    pub error: String,
}

/// One scan read in order, without its pose.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanRead {
    /// Index of the scan in the drive, from 0.
    pub index: usize,
    /// The scan's name.
    pub name: String,
    /// Its time: the drive's, or [`super::DEFAULT_SCAN_PERIOD_S`] apart from 0.
    pub time_s: f64,
    /// The scan.
    pub scan: crate::Scan,
}

/// Where the next scan is read from.
enum Reader {
    Files,
    Bag(Box<BagScans>),
}

impl Reader {
    fn new(drive: &Drive) -> Result<Self, SourceError> {
        Ok(match &drive.kind {
            Kind::Bag(bag) => Self::Bag(Box::new(
                bag.scans().map_err(|e| SourceError::Input(e.to_string()))?,
            )),
            Kind::Files | Kind::KittiRaw(_) => Self::Files,
        })
    }

    /// The next scan, whose path is `path`; the error as the message a skipped scan records.
    fn read(&mut self, path: &std::path::Path) -> Result<crate::Scan, String> {
        match self {
            Self::Files => read_scan(path).map_err(|e| e.to_string()),
            Self::Bag(scans) => match scans.next() {
                Some(scan) => scan.map(|s| s.scan).map_err(|e| e.to_string()),
                None => Err(format!("{}: the recording ended early", path.display())),
            },
        }
    }
}

/// The scans of a drive in order, without poses ([`Drive::scans`]).
pub struct Scans<'a> {
    drive: &'a Drive,
    reader: Reader,
    times: Vec<f64>,
    next: usize,
}

impl<'a> Scans<'a> {
    pub(super) fn new(drive: &'a Drive) -> Result<Self, SourceError> {
        Ok(Self {
            reader: Reader::new(drive)?,
            times: drive.times_or_period(),
            drive,
            next: 0,
        })
    }
}

impl Iterator for Scans<'_> {
    type Item = Result<ScanRead, SkippedScan>;

    fn next(&mut self) -> Option<Self::Item> {
        let index = self.next;
        let path = self.drive.paths.get(index)?;
        let time_s = self.times.get(index).copied().unwrap_or(f64::NAN);
        self.next += 1;
        let name = self.drive.scan_name(index);
        Some(match self.reader.read(path) {
            Ok(scan) => Ok(ScanRead {
                index,
                name,
                time_s,
                scan,
            }),
            Err(error) => Err(SkippedScan { index, name, error }),
        })
    }
}

impl std::fmt::Debug for Scans<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scans")
            .field("next", &self.next)
            .finish_non_exhaustive()
    }
}

/// The placed scans of a drive in order ([`Drive::frames`]).
pub struct Frames<'a> {
    scans: Scans<'a>,
    poses: &'a Poses,
}

impl<'a> Frames<'a> {
    pub(super) fn new(drive: &'a Drive, poses: &'a Poses) -> Result<Self, SourceError> {
        Ok(Self {
            scans: Scans::new(drive)?,
            poses,
        })
    }
}

impl Iterator for Frames<'_> {
    type Item = Result<Frame, SkippedScan>;

    fn next(&mut self) -> Option<Self::Item> {
        let index = self.scans.next;
        let (&world_from_sensor, &time_s) = self
            .poses
            .world_from_sensor
            .get(index)
            .zip(self.poses.times.get(index))?;
        let read = self.scans.next()?;
        Some(read.map(|read| Frame {
            index,
            name: read.name,
            time_s,
            points_in_sensor: read.scan.points_in_sensor,
            intensity: read.scan.intensity,
            world_from_sensor,
            fix: self.scans.drive.gnss_fix(index),
        }))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self
            .poses
            .len()
            .min(self.scans.drive.len())
            .saturating_sub(self.scans.next);
        (left, Some(left))
    }
}

impl ExactSizeIterator for Frames<'_> {}

impl std::fmt::Debug for Frames<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Frames")
            .field("next", &self.scans.next)
            .finish_non_exhaustive()
    }
}
