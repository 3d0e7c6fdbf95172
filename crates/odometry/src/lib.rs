//! Lidar odometry: poses from the scans alone.

#![deny(missing_docs)]
