//! Drives as they are published: lidar scans and the poses that place them in the world.
//!
//! This crate reads; it computes nothing about grids or belief functions. A scan is a list of
//! points in the sensor frame ([`scan`]); what places it in the world comes from pose files or
//! from a published drive's own layout.

#![deny(missing_docs)]

pub mod scan;

pub use scan::{Scan, ScanError, list_scans, read_scan};
