//! Drives as they are published: lidar scans and the poses that place them in the world.
//!
//! This crate reads; it computes nothing about grids or belief functions. A scan is a list of
//! points in the sensor frame ([`scan`]); what places it in the world comes from pose files
//! ([`poses`]) or from a published drive's own layout ([`kitti_raw`], built on [`timestamp`],
//! [`calib`] and [`oxts`]), or from a ROS 2 recording ([`bag`]). [`source`] makes any of them one [`Drive`]: scans
//! matched to poses, read as frames.
//!
//! Conventions, everywhere in this crate:
//! - rigid transforms are [`nalgebra::Isometry3<f64>`] named by what they map:
//!   `world_from_sensor` takes a point in sensor coordinates to world coordinates, so transforms
//!   chain like fractions (`world_from_imu * imu_from_velo = world_from_velo`);
//! - time is `f64` seconds (Unix time for KITTI raw, whatever the file uses otherwise);
//! - world frames are local, metric, x east, y north, z up, unless a type says otherwise;
//! - every reader error names the file and, for text formats, the 1-based line, because the
//!   person who has to fix the file needs exactly that.

#![deny(missing_docs)]

pub mod bag;
pub mod calib;
pub mod error;
pub mod kitti_raw;
pub mod oxts;
pub mod poses;
pub mod scan;
pub mod source;
mod text;
pub mod timestamp;

pub use bag::{BagDrive, BagError, BagOptions, BagPoses, PoseSource};
pub use error::ReadError;
pub use kitti_raw::{KittiRawDrive, KittiRawError, KittiRawFrame};
pub use poses::{PoseFormat, PoseTrack, TrackError};
pub use scan::{Scan, ScanError, list_scans, read_scan};
pub use source::{Drive, DriveSpec, Frame, PoseOrigin, Poses, SourceError};
pub use text::read_text_limited;
