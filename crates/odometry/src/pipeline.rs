//! The odometry pipeline: one call per scan.

use nalgebra::{Isometry3, Vector3, Vector6};

use crate::deskew::{azimuth_time, deskew};
use crate::icp::{self, IcpSettings};
use crate::lie;
use crate::threshold::AdaptiveThreshold;
use crate::voxel::{VoxelMap, downsample, downsampled};
use crate::{OdometryError, OdometryParams};

/// How a scan's pose was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FrameOutcome {
    /// The first scan (or the first with points): it defines the world frame.
    First,
    /// ICP registered the scan against the local map.
    Registered {
        /// Whether the updates fell below the tolerance within the iteration limit.
        converged: bool,
    },
    /// The scan could not be registered (too few valid points or correspondences); its pose is
    /// the constant-velocity prediction.
    Predicted,
}

/// What happened to the last scan: counts for logs and tests.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameReport {
    /// Points given.
    pub input_points: usize,
    /// Points dropped for a NaN or infinite coordinate (or point time).
    pub non_finite_points: usize,
    /// Finite points dropped as nearer than `min_range_m` or farther than `max_range_m`.
    pub out_of_range_points: usize,
    /// Points left after downsampling at half a voxel: what the map receives.
    pub frame_points: usize,
    /// Points left after downsampling at 1.5 voxels: what ICP registers.
    pub source_points: usize,
    /// Correspondences in ICP's last iteration.
    pub correspondences: usize,
    /// Gauss–Newton iterations run.
    pub iterations: usize,
    /// The adaptive threshold `σ` used (metres); pairs were accepted up to `3σ`.
    pub sigma_m: f64,
    /// Voxels in the local map after the update.
    pub map_voxels: usize,
    /// How the pose was obtained.
    pub outcome: FrameOutcome,
}

/// Lidar odometry over a sequence of scans. See the crate documentation.
#[derive(Debug, Clone)]
pub struct Odometry {
    params: OdometryParams,
    map: VoxelMap,
    threshold: AdaptiveThreshold,
    poses: Vec<Isometry3<f64>>,
    last_time_s: Option<f64>,
    /// Body-frame twist per second between the last two scans, once there are two.
    velocity: Option<Vector6<f64>>,
    /// The frames (and point times) registered before the velocity was known, to deskew once it
    /// is: at most two.
    /// Each with the index its pose has.
    undeskewed: Vec<(usize, Vec<Vector3<f64>>, Vec<f64>)>,
    last_report: Option<FrameReport>,
}

impl Odometry {
    /// An odometry with no scans yet.
    ///
    /// # Errors
    /// [`OdometryError::InvalidParameter`] naming the first invalid field.
    pub fn new(params: OdometryParams) -> Result<Self, OdometryError> {
        params.validate()?;
        Ok(Self {
            map: VoxelMap::new(params.voxel_size_m, params.max_points_per_voxel),
            threshold: AdaptiveThreshold::new(
                params.initial_threshold_m,
                params.min_motion_m,
                params.max_range_m,
            ),
            params,
            poses: Vec::new(),
            last_time_s: None,
            velocity: None,
            undeskewed: Vec::new(),
            last_report: None,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &OdometryParams {
        &self.params
    }

    /// `world_from_sensor` of every scan registered so far, in order; the world frame is the
    /// first scan's sensor frame.
    pub fn poses(&self) -> &[Isometry3<f64>] {
        &self.poses
    }

    /// What happened to the last scan registered.
    pub fn last_report(&self) -> Option<&FrameReport> {
        self.last_report.as_ref()
    }

    /// Registers a scan: `points` in the sensor frame (x forward, y left, z up, metres; NaN or
    /// infinite points are dropped and counted) measured at `time_s`. Returns its
    /// `world_from_sensor`. With `azimuth_times` set, the sweep's motion is corrected from
    /// times estimated from each point's azimuth.
    ///
    /// Once the map has begun, a scan with too few usable points gets the constant-velocity
    /// prediction (see [`FrameReport::outcome`]) rather than an error, so poses stay one per
    /// scan.
    ///
    /// # Errors
    /// The time is not finite or not after the previous scan's; or no map has begun and the
    /// scan has fewer than [`MIN_USABLE_POINTS`] usable points ([`OdometryError::TooFewPoints`]:
    /// its pose would be the identity, not a measurement). The state is then unchanged.
    pub fn register(
        &mut self,
        points: &[[f32; 3]],
        time_s: f64,
    ) -> Result<Isometry3<f64>, OdometryError> {
        self.register_scan(points, None, time_s)
    }

    /// As [`Odometry::register`], with each point's time in seconds relative to `time_s`
    /// (negative before it), used for deskewing when `deskew` is set. The pose returned is the
    /// sensor's at `time_s`.
    ///
    /// # Errors
    /// As [`Odometry::register`], and [`OdometryError::PointTimesLength`] when `point_times_s`
    /// is not one per point.
    pub fn register_with_point_times(
        &mut self,
        points: &[[f32; 3]],
        point_times_s: &[f32],
        time_s: f64,
    ) -> Result<Isometry3<f64>, OdometryError> {
        if point_times_s.len() != points.len() {
            return Err(OdometryError::PointTimesLength {
                points: points.len(),
                times: point_times_s.len(),
            });
        }
        self.register_scan(points, Some(point_times_s), time_s)
    }

    fn register_scan(
        &mut self,
        points: &[[f32; 3]],
        point_times_s: Option<&[f32]>,
        time_s: f64,
    ) -> Result<Isometry3<f64>, OdometryError> {
        if !time_s.is_finite() {
            return Err(OdometryError::NonFiniteTime { time_s });
        }
        let elapsed_s = match self.last_time_s {
            Some(previous_s) if time_s <= previous_s => {
                return Err(OdometryError::TimeNotIncreasing { previous_s, time_s });
            }
            Some(previous_s) => time_s - previous_s,
            None => 0.0,
        };
        let params = self.params.clone();
        let mut report = FrameReport {
            input_points: points.len(),
            non_finite_points: 0,
            out_of_range_points: 0,
            frame_points: 0,
            source_points: 0,
            correspondences: 0,
            iterations: 0,
            sigma_m: self.threshold.sigma(),
            map_voxels: 0,
            outcome: FrameOutcome::Predicted,
        };

        // Finite points within range, with their times when given.
        let (min_sq, max_sq) = (
            params.min_range_m * params.min_range_m,
            params.max_range_m * params.max_range_m,
        );
        let mut kept = Vec::with_capacity(points.len());
        let mut kept_times = Vec::new();
        for (index, raw) in points.iter().enumerate() {
            let time = point_times_s.map(|times| times[index]);
            if !raw.iter().all(|c| c.is_finite()) || time.is_some_and(|t| !t.is_finite()) {
                report.non_finite_points += 1;
                continue;
            }
            let point = Vector3::new(f64::from(raw[0]), f64::from(raw[1]), f64::from(raw[2]));
            let range_sq = point.norm_squared();
            if range_sq < min_sq || range_sq > max_sq {
                report.out_of_range_points += 1;
                continue;
            }
            kept.push(point);
            if let Some(time) = time {
                kept_times.push(f64::from(time));
            }
        }

        if kept.len() < MIN_USABLE_POINTS && self.map.is_empty() {
            return Err(OdometryError::TooFewPoints {
                usable: kept.len(),
                input: points.len(),
                min: MIN_USABLE_POINTS,
                min_range_m: params.min_range_m,
                max_range_m: params.max_range_m,
            });
        }
        let frame_indices = downsample(&kept, 0.5 * params.voxel_size_m);
        let mut frame: Vec<Vector3<f64>> = frame_indices.iter().map(|&i| kept[i]).collect();
        report.frame_points = frame.len();
        if params.vertical_angle_offset_deg != 0.0 {
            raise_elevation(&mut frame, params.vertical_angle_offset_deg.to_radians());
        }

        let times: Option<Vec<f64>> = if !params.deskew {
            None
        } else if point_times_s.is_some() {
            Some(frame_indices.iter().map(|&i| kept_times[i]).collect())
        } else if params.azimuth_times {
            Some(
                frame
                    .iter()
                    .map(|p| azimuth_time(p, params.scan_period_s))
                    .collect(),
            )
        } else {
            None
        };
        match (&times, self.velocity) {
            (Some(times), Some(twist)) => deskew(&mut frame, times, &twist),
            // No velocity yet (first two scans): kept as measured, deskewed once it is known.
            (Some(times), None) => {
                self.undeskewed
                    .push((self.poses.len(), frame.clone(), times.clone()));
            }
            (None, _) => {}
        }
        let source = downsampled(&frame, 1.5 * params.voxel_size_m);
        report.source_points = source.len();

        let last_pose = self.poses.last().copied();
        let prediction = match (last_pose, self.velocity) {
            (Some(pose), Some(twist)) => pose * lie::exp(&(twist * elapsed_s)),
            (Some(pose), None) => pose,
            (None, _) => Isometry3::identity(),
        };

        let pose = if last_pose.is_none() || self.map.is_empty() {
            if !frame.is_empty() {
                report.outcome = FrameOutcome::First;
            }
            prediction
        } else {
            let settings = IcpSettings::adaptive(
                self.threshold.sigma(),
                params.max_iterations,
                params.convergence_tolerance,
            );
            let outcome = icp::register(&source, &self.map, &prediction, &settings);
            report.correspondences = outcome.correspondences;
            report.iterations = outcome.iterations;
            if outcome.failed {
                prediction
            } else {
                report.outcome = FrameOutcome::Registered {
                    converged: outcome.converged,
                };
                self.threshold
                    .observe(&(prediction.inverse() * outcome.world_from_sensor));
                outcome.world_from_sensor
            }
        };

        self.map.add(&frame, &pose);
        if let Some(previous) = last_pose {
            let first_velocity = self.velocity.is_none();
            let twist = lie::velocity(&previous, &pose, elapsed_s);
            self.velocity = Some(twist);
            if first_velocity && !self.undeskewed.is_empty() {
                self.rebuild_map_deskewed(&twist, pose);
            }
        }
        self.map
            .remove_far(&pose.translation.vector, params.max_range_m);
        report.map_voxels = self.map.voxel_count();

        self.poses.push(pose);
        self.last_time_s = Some(time_s);
        self.last_report = Some(report);
        Ok(pose)
    }
}

/// Fewest usable points (finite, within range) of the scan that starts the map: as many as ICP
/// needs correspondences, so that the next scan can be registered against it.
pub const MIN_USABLE_POINTS: usize = crate::icp::MIN_CORRESPONDENCES;

impl Odometry {
    /// Replaces the map, built from the first scans as measured, by the same scans deskewed with
    /// the first velocity: otherwise their distortion would stay in the map until driven past.
    /// `pose` is the current scan's, not yet in `poses`.
    fn rebuild_map_deskewed(&mut self, twist: &Vector6<f64>, pose: Isometry3<f64>) {
        self.map = VoxelMap::new(self.params.voxel_size_m, self.params.max_points_per_voxel);
        for (index, mut frame, times) in std::mem::take(&mut self.undeskewed) {
            deskew(&mut frame, &times, twist);
            let frame_pose = self.poses.get(index).copied().unwrap_or(pose);
            self.map.add(&frame, &frame_pose);
        }
    }
}

/// Rotates each point upwards by `angle` in its vertical plane through the sensor.
fn raise_elevation(points: &mut [Vector3<f64>], angle: f64) {
    let (sin, cos) = angle.sin_cos();
    for point in points {
        let horizontal = point.x.hypot(point.y);
        if horizontal == 0.0 {
            continue;
        }
        let raised = horizontal * cos - point.z * sin;
        let scale = raised / horizontal;
        *point = Vector3::new(
            point.x * scale,
            point.y * scale,
            horizontal * sin + point.z * cos,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raising_elevation_keeps_range_and_azimuth() {
        let mut points = [Vector3::new(3.0, 4.0, 0.0), Vector3::new(0.0, 0.0, 2.0)];
        raise_elevation(&mut points, 0.1);
        assert!((points[0].norm() - 5.0).abs() < 1e-12);
        assert!((points[0].z - 5.0 * 0.1_f64.sin()).abs() < 1e-12);
        assert!((points[0].y / points[0].x - 4.0 / 3.0).abs() < 1e-12);
        assert_eq!(points[1], Vector3::new(0.0, 0.0, 2.0));
    }

    #[test]
    fn invalid_params_are_refused() {
        let params = OdometryParams {
            voxel_size_m: -1.0,
            ..OdometryParams::default()
        };
        assert!(matches!(
            Odometry::new(params),
            Err(OdometryError::InvalidParameter {
                name: "voxel_size_m",
                ..
            })
        ));
    }

    #[test]
    fn a_first_scan_of_too_few_points_is_refused_and_nine_are_too_few() {
        let mut odometry = Odometry::new(OdometryParams::default()).expect("defaults are valid");
        let nine: Vec<[f32; 3]> = (0..9).map(|k| [10.0, k as f32, 0.0]).collect();
        let refused = odometry.register(&nine, 0.0);
        assert!(
            matches!(
                refused,
                Err(OdometryError::TooFewPoints {
                    usable: 9,
                    input: 9,
                    min: 10,
                    ..
                })
            ),
            "{refused:?}"
        );
        assert!(odometry.poses().is_empty());
    }

    #[test]
    fn bad_times_are_refused_without_changing_state() {
        let mut odometry = Odometry::new(OdometryParams::default()).expect("defaults are valid");
        // As many points as the first scan needs (`MIN_USABLE_POINTS`).
        let scan: Vec<[f32; 3]> = (0..10).map(|k| [10.0, k as f32, 0.0]).collect();
        assert!(matches!(
            odometry.register(&scan, f64::NAN),
            Err(OdometryError::NonFiniteTime { .. })
        ));
        odometry.register(&scan, 1.0).expect("a valid scan");
        assert!(matches!(
            odometry.register(&scan, 1.0),
            Err(OdometryError::TimeNotIncreasing { .. })
        ));
        assert!(matches!(
            odometry.register_with_point_times(&scan, &[], 2.0),
            Err(OdometryError::PointTimesLength {
                points: 10,
                times: 0
            })
        ));
        assert_eq!(odometry.poses().len(), 1);
    }
}
