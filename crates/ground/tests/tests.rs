//! Integration tests, one binary: hand-computed synthetic scenes, properties, and the shared
//! KITTI scans.

mod common;
mod kitti;
mod properties;
mod synthetic;
