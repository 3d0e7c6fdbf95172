//! Odometry parameters, their defaults (KISS-ICP's) and their validation.

use crate::OdometryError;

/// Parameters of [`crate::Odometry`]. Plain numbers and flags, so they serialise as they are
/// (feature `serde`).
///
/// [`OdometryParams::default`] is KISS-ICP's configuration for a 100 m lidar;
/// [`OdometryParams::for_max_range`] scales the voxel size with the range as KISS-ICP does.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct OdometryParams {
    /// Points farther than this from the sensor are dropped, and map points farther than this
    /// from the current position are forgotten (metres, default 100).
    pub max_range_m: f64,
    /// Points closer than this to the sensor are dropped: the vehicle itself (metres, default 3).
    pub min_range_m: f64,
    /// Edge of a local-map voxel (metres, default `max_range_m / 100`). A scan is downsampled at
    /// half of it for the map and at 1.5 times it for registration.
    pub voxel_size_m: f64,
    /// At most this many points are kept per map voxel (default 20).
    pub max_points_per_voxel: usize,
    /// Correspondence threshold before any motion has been observed (metres, default 2).
    pub initial_threshold_m: f64,
    /// Deviations from the predicted motion smaller than this do not feed the adaptive threshold,
    /// so standing still does not shrink it to nothing (metres, default 0.1).
    pub min_motion_m: f64,
    /// Gauss–Newton iterations per scan at most (default 500).
    pub max_iterations: usize,
    /// ICP stops when an update's norm (metres and radians, as one 6-vector) is below this
    /// (default 1e-4).
    pub convergence_tolerance: f64,
    /// Correct the motion during a sweep when per-point times are known (given, or estimated
    /// with `azimuth_times`) (default true).
    pub deskew: bool,
    /// When no per-point times are given, estimate them from each point's azimuth, for a sensor
    /// that spins clockwise seen from above (Velodyne), one turn per `scan_period_s`, starting
    /// and ending behind it, centred on the scan time as KITTI's scans are (default false).
    pub azimuth_times: bool,
    /// Duration of one sweep for `azimuth_times` (seconds, default 0.1).
    pub scan_period_s: f64,
    /// Raise every point's elevation by this angle (degrees, default 0): a correction of the
    /// sensor's intrinsic calibration. KITTI's HDL-64 scans need about 0.205°: without it they
    /// are slightly bowl-shaped and the odometry overestimates distance by about 1 %.
    pub vertical_angle_offset_deg: f64,
}

impl Default for OdometryParams {
    fn default() -> Self {
        Self::for_max_range(100.0)
    }
}

impl OdometryParams {
    /// The defaults for a lidar of the given range, with KISS-ICP's voxel size of a hundredth of
    /// it.
    pub fn for_max_range(max_range_m: f64) -> Self {
        Self {
            max_range_m,
            min_range_m: 3.0,
            voxel_size_m: max_range_m / 100.0,
            max_points_per_voxel: 20,
            initial_threshold_m: 2.0,
            min_motion_m: 0.1,
            max_iterations: 500,
            convergence_tolerance: 1e-4,
            deskew: true,
            azimuth_times: false,
            scan_period_s: 0.1,
            vertical_angle_offset_deg: 0.0,
        }
    }

    /// Checks every field; the error names the first one that is out of range.
    pub fn validate(&self) -> Result<(), OdometryError> {
        check_registration(&Registration {
            max_range_m: self.max_range_m,
            min_range_m: self.min_range_m,
            voxel_name: "voxel_size_m",
            voxel_size_m: self.voxel_size_m,
            max_points_per_voxel: self.max_points_per_voxel,
            initial_threshold_m: self.initial_threshold_m,
            max_iterations: self.max_iterations,
            convergence_tolerance: self.convergence_tolerance,
        })?;
        if !(self.min_motion_m.is_finite() && self.min_motion_m >= 0.0) {
            return Err(invalid(
                "min_motion_m",
                self.min_motion_m,
                "must be finite and >= 0",
            ));
        }
        positive("scan_period_s", self.scan_period_s)?;
        if !(self.vertical_angle_offset_deg.is_finite()
            && self.vertical_angle_offset_deg.abs() <= 5.0)
        {
            return Err(invalid(
                "vertical_angle_offset_deg",
                self.vertical_angle_offset_deg,
                "must be finite and within ±5°",
            ));
        }
        Ok(())
    }
}

/// The settings the odometry and the pose refiner share: the scan's range, the local map and
/// the registration.
pub(crate) struct Registration {
    pub(crate) max_range_m: f64,
    pub(crate) min_range_m: f64,
    /// The voxel edge's parameter name, for the error.
    pub(crate) voxel_name: &'static str,
    pub(crate) voxel_size_m: f64,
    pub(crate) max_points_per_voxel: usize,
    pub(crate) initial_threshold_m: f64,
    pub(crate) max_iterations: usize,
    pub(crate) convergence_tolerance: f64,
}

/// Checks the shared settings; the error names the first field out of range.
pub(crate) fn check_registration(r: &Registration) -> Result<(), OdometryError> {
    positive("max_range_m", r.max_range_m)?;
    if !(r.min_range_m.is_finite() && r.min_range_m >= 0.0 && r.min_range_m < r.max_range_m) {
        return Err(invalid(
            "min_range_m",
            r.min_range_m,
            "must be finite, >= 0 and < max_range_m",
        ));
    }
    positive(r.voxel_name, r.voxel_size_m)?;
    // Voxel indices are i32: a voxel so small that the map's extent overflows them is a typo.
    if r.max_range_m / r.voxel_size_m > 1.0e6 {
        return Err(invalid(
            r.voxel_name,
            r.voxel_size_m,
            "must be at least max_range_m / 1e6",
        ));
    }
    if r.max_points_per_voxel == 0 {
        return Err(invalid("max_points_per_voxel", 0, "must be >= 1"));
    }
    positive("initial_threshold_m", r.initial_threshold_m)?;
    if r.max_iterations == 0 {
        return Err(invalid("max_iterations", 0, "must be >= 1"));
    }
    positive("convergence_tolerance", r.convergence_tolerance)
}

/// Ok if `value` is finite and > 0.
pub(crate) fn positive(name: &'static str, value: f64) -> Result<(), OdometryError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(invalid(name, value, "must be finite and > 0"))
    }
}

/// The error naming parameter `name`, its `value` and what was `expected`.
pub(crate) fn invalid(
    name: &'static str,
    value: impl ToString,
    expected: &'static str,
) -> OdometryError {
    OdometryError::InvalidParameter {
        name,
        value: value.to_string(),
        expected,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_scale_with_range() {
        assert_eq!(OdometryParams::default().validate(), Ok(()));
        let short = OdometryParams::for_max_range(50.0);
        assert_eq!(short.voxel_size_m, 0.5);
        assert_eq!(short.validate(), Ok(()));
    }

    #[test]
    fn errors_name_the_parameter() {
        type Spoil = fn(&mut OdometryParams);
        let cases: [(&str, Spoil); 9] = [
            ("max_range_m", |p| p.max_range_m = f64::NAN),
            ("min_range_m", |p| p.min_range_m = 200.0),
            ("min_range_m", |p| p.min_range_m = -1.0),
            ("voxel_size_m", |p| p.voxel_size_m = 0.0),
            ("voxel_size_m", |p| p.voxel_size_m = 1e-9),
            ("max_points_per_voxel", |p| p.max_points_per_voxel = 0),
            ("max_iterations", |p| p.max_iterations = 0),
            ("scan_period_s", |p| p.scan_period_s = -0.1),
            ("vertical_angle_offset_deg", |p| {
                p.vertical_angle_offset_deg = 90.0
            }),
        ];
        for (expected, spoil) in cases {
            let mut params = OdometryParams::default();
            spoil(&mut params);
            match params.validate() {
                Err(OdometryError::InvalidParameter { name, .. }) => assert_eq!(name, expected),
                other => panic!("{expected}: {other:?}"),
            }
        }
    }
}
