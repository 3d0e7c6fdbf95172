//! KISS-ICP's adaptive correspondence threshold.
//!
//! The constant-velocity prediction is wrong by some amount each scan; how wrong, turned into the
//! largest point displacement it causes within the sensor's range, is the scale of the errors ICP
//! must absorb. The threshold `σ` is the root mean square of those displacements over the drive;
//! ICP pairs points up to `3σ` apart.

use nalgebra::Isometry3;

#[derive(Debug, Clone)]
pub(crate) struct AdaptiveThreshold {
    initial_m: f64,
    min_motion_m: f64,
    max_range_m: f64,
    sum_sq: f64,
    samples: u64,
}

impl AdaptiveThreshold {
    pub(crate) fn new(initial_m: f64, min_motion_m: f64, max_range_m: f64) -> Self {
        Self {
            initial_m,
            min_motion_m,
            max_range_m,
            sum_sq: 0.0,
            samples: 0,
        }
    }

    /// `σ`: the initial value until a deviation above the minimum motion has been seen.
    pub(crate) fn sigma(&self) -> f64 {
        if self.samples == 0 {
            self.initial_m
        } else {
            (self.sum_sq / self.samples as f64).sqrt()
        }
    }

    /// Records `predicted⁻¹ · registered`, the correction ICP applied to the prediction.
    pub(crate) fn observe(&mut self, deviation: &Isometry3<f64>) {
        let error = self.displacement_bound(deviation);
        if error > self.min_motion_m {
            self.sum_sq += error * error;
            self.samples += 1;
        }
    }

    /// The largest displacement the deviation causes on a point within the range: its
    /// translation plus the chord its rotation sweeps at the maximum range.
    fn displacement_bound(&self, deviation: &Isometry3<f64>) -> f64 {
        let angle = deviation.rotation.angle();
        deviation.translation.vector.norm() + 2.0 * self.max_range_m * (angle / 2.0).sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    #[test]
    fn small_deviations_keep_the_initial_threshold() {
        let mut threshold = AdaptiveThreshold::new(2.0, 0.1, 100.0);
        threshold.observe(&Isometry3::translation(0.05, 0.0, 0.0));
        assert_eq!(threshold.sigma(), 2.0);
    }

    #[test]
    fn sigma_is_the_rms_of_displacement_bounds() {
        let mut threshold = AdaptiveThreshold::new(2.0, 0.1, 100.0);
        threshold.observe(&Isometry3::translation(0.3, 0.4, 0.0));
        // 0.002 rad at 100 m: a chord of 2·100·sin(0.001).
        let turn = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, 0.002)),
        );
        threshold.observe(&turn);
        let chord = 200.0 * 0.001_f64.sin();
        let expected = ((0.25 + chord * chord) / 2.0).sqrt();
        assert!((threshold.sigma() - expected).abs() < 1e-12);
    }
}
