//! Relative pose errors in the style of the KITTI odometry devkit.
//!
//! For each start frame (every `step`-th) and each segment length `L`, the segment ends at the
//! first frame whose distance travelled along the *reference* since the start is at least `L`.
//! The error of the segment is `(est_first⁻¹ est_last)⁻¹ (ref_first⁻¹ ref_last)`: its
//! translation and its rotation angle, divided by the distance travelled.
//!
//! Two details differ from the devkit on purpose: a segment ends at the first frame at *or*
//! beyond `L` (the devkit: strictly beyond), and errors are divided by the distance actually
//! travelled over the segment rather than by `L`. With frames sampled coarsely the devkit's
//! numbers are biased by the overshoot; these are not (an estimate scaled by 1.01 has exactly
//! 1 % error). On a 10 Hz drive the difference is a few percent of the error.

use nalgebra::Isometry3;

/// Why errors could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MetricsError {
    /// The two trajectories differ in length.
    #[error("estimate has {estimate} poses, reference {reference}")]
    LengthMismatch {
        /// Poses in the estimate.
        estimate: usize,
        /// Poses in the reference.
        reference: usize,
    },
    /// A segment length is not finite and positive.
    #[error("segment length {0} m is not finite and > 0")]
    InvalidSegmentLength(f64),
    /// The start-frame step is zero.
    #[error("start-frame step must be >= 1")]
    ZeroStep,
}

/// The error over one segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentError {
    /// Start frame.
    pub first: usize,
    /// End frame.
    pub last: usize,
    /// The requested segment length (metres).
    pub length_m: f64,
    /// Distance travelled along the reference from `first` to `last` (metres, `>= length_m`).
    pub travelled_m: f64,
    /// Translation error over the distance travelled, in percent.
    pub translation_pct: f64,
    /// Rotation error angle over the distance travelled, in degrees per metre.
    pub rotation_deg_per_m: f64,
    /// The heading part of the rotation error (about the end frame's z axis, up), in degrees per
    /// metre.
    pub heading_deg_per_m: f64,
}

/// All segment errors of a trajectory, with their means.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RelativeErrors {
    /// One entry per (start frame, length) for which the reference goes far enough.
    pub segments: Vec<SegmentError>,
}

impl RelativeErrors {
    fn mean(&self, value: impl Fn(&SegmentError) -> f64) -> Option<f64> {
        if self.segments.is_empty() {
            return None;
        }
        Some(self.segments.iter().map(value).sum::<f64>() / self.segments.len() as f64)
    }

    /// Mean translation error over all segments (percent), as the devkit's summary; `None`
    /// without segments.
    pub fn mean_translation_pct(&self) -> Option<f64> {
        self.mean(|s| s.translation_pct)
    }

    /// Mean rotation error over all segments (degrees per metre).
    pub fn mean_rotation_deg_per_m(&self) -> Option<f64> {
        self.mean(|s| s.rotation_deg_per_m)
    }

    /// Mean heading error over all segments (degrees per metre).
    pub fn mean_heading_deg_per_m(&self) -> Option<f64> {
        self.mean(|s| s.heading_deg_per_m)
    }

    /// The segments of one requested length.
    pub fn of_length(&self, length_m: f64) -> RelativeErrors {
        RelativeErrors {
            segments: self
                .segments
                .iter()
                .filter(|s| s.length_m == length_m)
                .copied()
                .collect(),
        }
    }
}

/// Relative errors of `estimate` against `reference` (both `world_from_sensor`, frame for frame)
/// over segments of `lengths_m`, starting at every `step`-th frame.
///
/// # Errors
/// The trajectories differ in length, a length is not finite and positive, or `step` is 0.
pub fn relative_errors(
    estimate: &[Isometry3<f64>],
    reference: &[Isometry3<f64>],
    lengths_m: &[f64],
    step: usize,
) -> Result<RelativeErrors, MetricsError> {
    if estimate.len() != reference.len() {
        return Err(MetricsError::LengthMismatch {
            estimate: estimate.len(),
            reference: reference.len(),
        });
    }
    if let Some(&bad) = lengths_m.iter().find(|l| !(l.is_finite() && **l > 0.0)) {
        return Err(MetricsError::InvalidSegmentLength(bad));
    }
    if step == 0 {
        return Err(MetricsError::ZeroStep);
    }
    // Distance travelled along the reference up to each frame.
    let mut travelled = Vec::with_capacity(reference.len());
    let mut total = 0.0;
    for (i, pose) in reference.iter().enumerate() {
        if i > 0 {
            total += (pose.translation.vector - reference[i - 1].translation.vector).norm();
        }
        travelled.push(total);
    }
    let mut errors = RelativeErrors::default();
    for first in (0..reference.len()).step_by(step) {
        for &length_m in lengths_m {
            let target = travelled[first] + length_m;
            // `travelled` is non-decreasing: the end frame is the first one reaching the target.
            let last = first + travelled[first..].partition_point(|&d| d < target);
            if last >= reference.len() {
                continue;
            }
            let distance = travelled[last] - travelled[first];
            let reference_delta = reference[first].inverse() * reference[last];
            let estimate_delta = estimate[first].inverse() * estimate[last];
            let error = estimate_delta.inverse() * reference_delta;
            let rotation = error.rotation.to_rotation_matrix();
            let heading = rotation[(1, 0)].atan2(rotation[(0, 0)]);
            errors.segments.push(SegmentError {
                first,
                last,
                length_m,
                travelled_m: distance,
                translation_pct: 100.0 * error.translation.vector.norm() / distance,
                rotation_deg_per_m: error.rotation.angle().to_degrees() / distance,
                heading_deg_per_m: heading.abs().to_degrees() / distance,
            });
        }
    }
    Ok(errors)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// A reference driving along x at 1 m per frame, turning left by `yaw_per_frame`.
    fn arc(frames: usize, yaw_per_frame: f64) -> Vec<Isometry3<f64>> {
        let mut pose = Isometry3::identity();
        let step = Isometry3::from_parts(
            Translation3::new(1.0, 0.0, 0.0),
            UnitQuaternion::from_scaled_axis(Vector3::z() * yaw_per_frame),
        );
        (0..frames)
            .map(|_| {
                let current = pose;
                pose *= step;
                current
            })
            .collect()
    }

    #[test]
    fn identical_trajectories_have_no_error() {
        let reference = arc(50, 0.02);
        let errors =
            relative_errors(&reference, &reference, &[10.0, 20.0, 30.0], 1).expect("valid input");
        // Starts 0..=39 reach 10 m, 0..=29 reach 20 m, 0..=19 reach 30 m.
        assert_eq!(errors.segments.len(), 40 + 30 + 20);
        assert!(errors.mean_translation_pct().is_some_and(|e| e < 1e-12));
        assert!(errors.mean_rotation_deg_per_m().is_some_and(|e| e < 1e-12));
        let ten = errors.of_length(10.0);
        assert!(ten.segments.iter().all(|s| s.last == s.first + 10));
    }

    #[test]
    fn a_scaled_estimate_has_the_scale_error() {
        let reference = arc(50, 0.0);
        let estimate: Vec<Isometry3<f64>> = reference
            .iter()
            .map(|p| {
                Isometry3::from_parts(Translation3::from(p.translation.vector * 1.01), p.rotation)
            })
            .collect();
        let errors =
            relative_errors(&estimate, &reference, &[10.0, 20.0, 30.0], 1).expect("valid input");
        for segment in &errors.segments {
            assert!((segment.translation_pct - 1.0).abs() < 1e-9, "{segment:?}");
            assert!(segment.rotation_deg_per_m < 1e-12);
        }
    }

    #[test]
    fn a_constant_yaw_drift_gives_its_rate_per_metre() {
        // Straight reference; the estimate yaws by 0.001 rad more per metre, in place.
        let reference = arc(40, 0.0);
        let drift = 0.001;
        let estimate: Vec<Isometry3<f64>> = reference
            .iter()
            .enumerate()
            .map(|(i, p)| {
                Isometry3::from_parts(
                    p.translation,
                    UnitQuaternion::from_scaled_axis(Vector3::z() * drift * i as f64),
                )
            })
            .collect();
        let errors = relative_errors(&estimate, &reference, &[10.0, 20.0], 2).expect("valid");
        let expected = drift.to_degrees();
        for segment in &errors.segments {
            assert!((segment.rotation_deg_per_m - expected).abs() < 1e-12);
            assert!((segment.heading_deg_per_m - expected).abs() < 1e-12);
            // The positions are right but the estimate's delta is expressed in a start frame
            // yawed by first·drift: its translation is off by the chord of that angle.
            let start_angle = drift * segment.first as f64;
            let chord = 2.0 * segment.travelled_m * (start_angle / 2.0).sin();
            assert!(
                (segment.translation_pct - 100.0 * chord / segment.travelled_m).abs() < 1e-9,
                "{segment:?}"
            );
        }
        assert_eq!(errors.segments[1].first, 0);
        assert_eq!(errors.segments[2].first, 2);
    }

    #[test]
    fn bad_input_is_refused() {
        let reference = arc(5, 0.0);
        assert!(matches!(
            relative_errors(&reference[..4], &reference, &[1.0], 1),
            Err(MetricsError::LengthMismatch { .. })
        ));
        assert_eq!(
            relative_errors(&reference, &reference, &[0.0], 1),
            Err(MetricsError::InvalidSegmentLength(0.0))
        );
        assert_eq!(
            relative_errors(&reference, &reference, &[1.0], 0),
            Err(MetricsError::ZeroStep)
        );
        let none = relative_errors(&reference, &reference, &[100.0], 1).expect("valid");
        assert_eq!(none.mean_translation_pct(), None);
    }
}
