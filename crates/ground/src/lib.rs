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
//! lies within `max_step_m + max_slope · distance` of *every* earlier ground node (the first
//! being the vehicle's own ground, `sensor_height_m` below the sensor), within
//! `max_slope_unseen` per metre across stretches where no ground was seen, and, when it rises,
//! only if its cell looks like a surface. A kerb is one step and is followed; a car's side,
//! hood or roof is refused. The ground is interpolated linearly in range between nodes, and
//! points are labelled by their height above it ([`PointLabel`]).
//!
//! The global plane ([`GroundMethod::GlobalPlane`], the sensor model's historical model) and a
//! level ground ([`GroundMethod::FixedHeight`]) are kept to compare against.
//!
//! # Why this method: measured on the shared KITTI scans
//!
//! Without labels, per frame (tests/kitti.rs, `examples/ground_eval.rs`): the obstacle share
//! (min/median/max and worst over median), the *flat-patch obstacles* (obstacle points in a
//! 0.5 m square of at least 5 returns spanning under 0.1 m: ground called obstacle, mean /
//! worst frame), the *lifted ground* (ground points more than 0.3 m above the lowest return of
//! their 1 m square: an object's side called ground) and the lane ahead (3–20 m, |y| < 1 m):
//! its returns labelled obstacle lower than 0.25 m above a line fitted to its lowest returns.
//! The zone planes are a Patchwork-style model written for the comparison
//! (`examples/compare_zone_planes.rs`: per-bin PCA plane with uprightness, elevation and
//! flatness tests, no temporal revert). One core, shared machine.
//!
//! | drive 2011_09_26_0013 (40 scans) | obstacle share | flat-patch obstacles | lifted ground | lane false obstacles | ms |
//! | --- | --- | --- | --- | --- | --- |
//! | global plane | 29.7/37.8/54.4 % (1.44×) | 4.89 / 10.77 % | 0.73 / 1.56 % | 0 % | 2.6 |
//! | fixed height | 37.5/42.0/63.4 % (1.51×) | 10.90 / 13.27 % | 0.66 / 1.30 % | 0 % | 1.5 |
//! | zone planes | 26.7/30.9/48.6 % (1.57×) | 2.55 / 3.77 % | 1.15 / 2.63 % | 0.30 % (worst 11.7 %) | 7.7 |
//! | **local height** | 23.1/28.1/47.3 % (1.68×) | **0.10 / 0.19 %** | 0.85 / 1.51 % | 0 % | 3.1 |
//! | local height, no slope limits | 21.5/26.4/41.2 % (1.56×) | 0.08 / 0.19 % | 3.12 / 7.47 % | 0 % | 3.2 |
//!
//! | Karlsruhe street (22 scans) | obstacle share | flat-patch obstacles | lifted ground | lane false obstacles | ms |
//! | --- | --- | --- | --- | --- | --- |
//! | global plane | 46.8/49.2/59.3 % (1.20×) | 0.48 / 1.03 % | 1.18 / 4.68 % | 0 % | 2.3 |
//! | zone planes | 40.1/48.1/54.1 % (1.12×) | 0.62 / 2.21 % | 1.46 / 2.05 % | 2.8 % (worst 29.6 %) | 6.8 |
//! | **local height** | 46.4/49.1/60.1 % (1.22×) | **0.39 / 0.63 %** | 1.12 / 1.89 % | 0 % | 2.8 |
//!
//! On drive 0013 the plane's tilt (up to 3.4°) turns road and pavement rings into obstacles:
//! 4.9 % of all points on flat patches, 98 % of which the local method returns to the ground.
//! Its whole-scan worst frame (1.68× the median) is no ground failure: from frame 28 on, a
//! wall at least 2 m high runs 2.7 m to the right of the car and its ~27,000 returns within
//! 5 m are obstacles; beyond 5 m the share stays within 1.21× its median (1.04× on the
//! street). Without the slope limits the sides and tops of cars become ground (lifted ground
//! ×4). Sectors of 1°, 2° or 4°, seed bands of 5–20 cm and steps of 10–20 cm change these
//! figures by less than 0.2 points; `max_slope_unseen` trades lifted ground (0.73 % at 0.03,
//! 1.12 % at 0.1) against following steep ground behind occlusions.
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
//! # Wiring into the sensor model
//!
//! Rotate the scan into the levelled frame (`world_from_sensor.rotate_xyz`, no translation) as
//! `[f32; 3]`, call [`GroundSegmenter::segment`] once per scan (the segmenter keeps its
//! buffers), then per point: [`PointLabel::Ground`] feeds the sector's farthest ground range,
//! [`PointLabel::Obstacle`] its nearest obstacle range and occupied cell, every other label is
//! ignored. Set `min_range_m`, `max_range_m`, `min_obstacle_height_m` and
//! `max_obstacle_height_m` from the `[sensor]` section; [`Segmentation::ground_z_m`] gives the
//! ground under each point for a tighter ground band if wanted.
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
pub use plane::{GroundPlane, PlaneFitter};
pub use segmenter::GroundSegmenter;
