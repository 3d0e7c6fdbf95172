//! Ground segmentation for 3-D lidar scans on real streets: slopes, crowned roads, kerbs.
//!
//! The sensor model of `evigrid` (SPEC §3) needs every return of a 3-D lidar split into ground
//! returns (free space extends to them) and obstacle returns (their cells are occupied). One
//! plane per scan does not hold on real streets: a slope, a crowned road or a change of grade
//! tilts it and whole rings of road become obstacles. This crate finds the ground *locally*.
//!
//! **Key design decision**: a ground height per polar cell, propagated outward from the sensor
//! under a slope and step limit ([`GroundMethod::LocalHeight`]). Each cell's candidate is the
//! centroid of its lowest points; walking each sector outward, a candidate is accepted when it
//! lies within `max_step_m + max_slope · distance` of *every* earlier accepted node (the first
//! node being the sensor's own ground, `sensor_height_m` below it). A kerb is one step and is
//! followed; a car's side, hood and roof would need several and are refused. The ground is
//! interpolated linearly in range between accepted nodes. Points are then labelled by their
//! height above that ground.
//!
//! The global plane ([`GroundMethod::GlobalPlane`], the sensor model's historical model) and a
//! level ground ([`GroundMethod::FixedHeight`]) are kept to compare against.
//!
//! # Example
//!
//! A level road 1.73 m below the sensor, and the face of a box on it 10 m ahead, sampled every
//! 5 cm from 2.5 cm to 1.475 m above the road:
//!
//! ```
//! use ground::{GroundParams, GroundSegmenter, PointLabel};
//!
//! let mut points = Vec::new();
//! for i in 0..200 {
//!     for j in 0..40 {
//!         // Road from 3 m to 23 m ahead, 4 m wide.
//!         points.push([3.0 + 0.1 * i as f32, -2.0 + 0.1 * j as f32, -1.73]);
//!     }
//! }
//! let box_start = points.len();
//! for k in 0..30 {
//!     points.push([10.0, -0.5 + 0.05 * k as f32, -1.705 + 0.05 * k as f32]);
//! }
//! let mut segmenter = GroundSegmenter::new(GroundParams::default())?;
//! let result = segmenter.segment(&points);
//! let labels = result.labels();
//! assert!(labels[..box_start].iter().all(|&l| l == PointLabel::Ground));
//! // The box's face: ground below 0.3 m (6 points), obstacle above.
//! assert_eq!(labels[box_start + 5], PointLabel::Ground);
//! assert_eq!(labels[box_start + 10], PointLabel::Obstacle);
//! assert!((result.ground_z_m()[0] + 1.73).abs() < 1e-4);
//! assert_eq!(result.stats().obstacle, 30 - 6);
//! # Ok::<(), ground::GroundParamsError>(())
//! ```
//!
//! # References
//!
//! SPEC §3 (`../shared/SPEC.md`); the concentric zones of Patchwork (H. Lim, M. Oh, H. Myung,
//! "Patchwork: Concentric Zone-based Region-wise Ground Segmentation with Ground Likelihood
//! Estimation Using a 3D LiDAR Sensor", RA-L 2021) and Patchwork++ (S. Lee, H. Lim, H. Myung,
//! IROS 2022); slope-limited ground propagation as in line-fit methods (M. Himmelsbach, F. v.
//! Hundelshausen, H.-J. Wuensche, "Fast segmentation of 3D point clouds for ground vehicles",
//! IV 2010).
#![deny(missing_docs)]

mod label;
mod local;
mod params;
mod plane;
mod polar;
mod segmenter;

pub use label::{GroundStats, PointLabel, Segmentation};
pub use params::{
    GroundMethod, GroundParams, GroundParamsError, MAX_CELLS, MAX_RINGS, MAX_SECTORS, RingZone,
};
pub use segmenter::GroundSegmenter;
