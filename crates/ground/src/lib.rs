//! Ground segmentation for 3-D lidar scans.

#![deny(missing_docs)]
