//! Motion correction within a sweep.
//!
//! A spinning lidar measures its points over the sweep while moving. With the constant-velocity
//! model the sensor's pose at `τ` seconds after the scan time is `pose(0) · exp(τ ξ)`, `ξ` the
//! body-frame twist per second; a point measured then is `exp(τ ξ) · p` in the frame at the scan
//! time.

use nalgebra::{Point3, Vector3, Vector6};

use crate::lie;

/// Per-point times (seconds from the scan time) for a sensor that spins clockwise seen from
/// above, one turn per `period_s`, the sweep starting and ending straight behind it and passing
/// straight ahead at the scan time (Velodyne HDL-64 in KITTI: its `timestamps.txt` is when the
/// sweep faces forward).
pub(crate) fn azimuth_time(point: &Vector3<f64>, period_s: f64) -> f64 {
    // Azimuth decreases as a clockwise sweep goes on: +π at the start, 0 ahead, −π at the end.
    -point.y.atan2(point.x) / std::f64::consts::TAU * period_s
}

/// Moves each point to where it was at the scan time, `twist_per_s` the sensor's body velocity.
pub(crate) fn deskew(points: &mut [Vector3<f64>], times_s: &[f64], twist_per_s: &Vector6<f64>) {
    for (point, &time) in points.iter_mut().zip(times_s) {
        let motion = lie::exp(&(twist_per_s * time));
        *point = (motion * Point3::from(*point)).coords;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn azimuth_times_span_the_sweep() {
        let period = 0.1;
        assert!((azimuth_time(&Vector3::new(10.0, 0.0, 0.0), period)).abs() < 1e-15);
        // Left is a quarter turn before ahead for a clockwise sweep, right a quarter after.
        assert!((azimuth_time(&Vector3::new(0.0, 10.0, 0.0), period) + 0.025).abs() < 1e-15);
        assert!((azimuth_time(&Vector3::new(0.0, -10.0, 0.0), period) - 0.025).abs() < 1e-15);
        let behind_left = azimuth_time(&Vector3::new(-10.0, 1e-9, 0.0), period);
        assert!((behind_left + 0.05).abs() < 1e-9);
    }

    #[test]
    fn a_point_seen_later_by_a_forward_moving_sensor_moves_forward() {
        // Moving at 10 m/s along x: a point measured 0.05 s after the scan time, 5 m ahead in the
        // sensor frame then, is 5.5 m ahead of where the sensor was at the scan time.
        let mut points = [Vector3::new(5.0, 0.0, 0.0)];
        deskew(
            &mut points,
            &[0.05],
            &Vector6::new(10.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        );
        assert!((points[0] - Vector3::new(5.5, 0.0, 0.0)).norm() < 1e-12);
    }
}
