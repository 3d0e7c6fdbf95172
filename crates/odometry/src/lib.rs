//! Lidar odometry: poses from the scans alone.
//!
//! An own implementation in the spirit of KISS-ICP (Vizzo et al., "KISS-ICP: In Defense of
//! Point-to-Point ICP", RA-L 2023): each scan is range-filtered and voxel-downsampled, registered
//! by point-to-point ICP (Gauss–Newton on SE(3), Geman–McClure kernel) against a voxel-hash local
//! map, starting from a constant-velocity prediction; the correspondence threshold adapts to how
//! far the registrations deviate from that prediction.
//!
//! [`PoseRefiner`] does the same registration with a reported pose (GNSS/INS) as the prior:
//! it corrects that pose instead of replacing it.
//!
//! ```no_run
//! use odometry::{Odometry, OdometryParams};
//! # fn scans() -> Vec<(Vec<[f32; 3]>, f64)> { Vec::new() }
//! let mut odometry = Odometry::new(OdometryParams::default())?;
//! for (points, time_s) in scans() {
//!     let world_from_sensor = odometry.register(&points, time_s)?;
//!     println!("{}", world_from_sensor.translation);
//! }
//! # Ok::<(), odometry::OdometryError>(())
//! ```
//!
//! # Timing
//! [`Odometry::register`] does all the work of a scan, so timing it is timing the odometry; the
//! bench `register` in this crate and the example `kitti_raw` do that on the shared KITTI drive.
//! Set `RAYON_NUM_THREADS=1` for one core. The search and the normal equations are reduced in
//! fixed chunks, so poses are bit-identical whatever the number of threads.

#![deny(missing_docs)]

mod deskew;
mod error;
mod icp;
mod lie;
pub mod metrics;
mod params;
mod pipeline;
mod refine;
mod threshold;
mod voxel;

pub use error::OdometryError;
pub use params::OdometryParams;
pub use pipeline::{FrameOutcome, FrameReport, MIN_USABLE_POINTS, Odometry};
pub use refine::{
    KeptReason, PLANAR_SPREAD_M, PREDICTION_LEVER_M, PoseRefiner, PriorSigma, RefineBlend,
    RefineOutcome, RefineParams, RefineStart, Refinement, SIGMA_SAMPLES, SIGMA_WINDOW,
};
