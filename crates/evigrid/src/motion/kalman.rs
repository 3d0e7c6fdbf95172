//! A track's velocity filter: the velocity block of a constant-velocity Kalman filter, one
//! independent filter per axis.
//!
//! The position of a track is its cluster's centroid, taken as measured rather than filtered:
//! the visible part of an object changes (a façade slides into view as the ego drives along
//! it, a car turns its side) much faster and further than the object moves, and a filter fed
//! those centroids would read the change as speed. The velocity is measured by registration
//! instead (`register`), and filtered here: constant velocity with white acceleration of
//! standard deviation σ_a, so over `dt` the velocity's variance grows by (σ_a·dt)².

/// The velocity estimate of one axis: mean and variance, m/s and (m/s)².
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct VelocityFilter {
    pub(crate) mean_mps: f64,
    pub(crate) variance: f64,
}

impl VelocityFilter {
    /// A filter with a prior velocity and its variance.
    pub(crate) fn new(mean_mps: f64, variance: f64) -> Self {
        Self { mean_mps, variance }
    }

    /// Prediction over `dt_s`: the velocity is kept, its variance grows by (σ_a·dt)².
    pub(crate) fn predict(&mut self, dt_s: f64, accel_sigma_mps2: f64) {
        let spread = accel_sigma_mps2 * dt_s;
        self.variance += spread * spread;
    }

    /// Update with a measured velocity of variance `measurement_variance`.
    pub(crate) fn update(&mut self, measured_mps: f64, measurement_variance: f64) {
        let gain = self.variance / (self.variance + measurement_variance);
        self.mean_mps += gain * (measured_mps - self.mean_mps);
        self.variance *= 1.0 - gain;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn predict_and_update_by_hand() {
        let mut f = VelocityFilter::new(0.0, 1.0);
        // σ_a = 3 m/s², dt = 0.1 s: variance 1 + 0.3² = 1.09.
        f.predict(0.1, 3.0);
        assert!((f.variance - 1.09).abs() < 1e-12);
        // Measured 2 m/s with variance 0.25: gain 1.09 / 1.34.
        f.update(2.0, 0.25);
        let gain = 1.09 / 1.34;
        assert!((f.mean_mps - 2.0 * gain).abs() < 1e-12);
        assert!((f.mean_mps - 1.626_865_671_641_791).abs() < 1e-12);
        assert!((f.variance - 1.09 * 0.25 / 1.34).abs() < 1e-12);
    }

    #[test]
    fn repeated_measurements_converge_and_shrink_the_variance() {
        let mut f = VelocityFilter::new(0.0, 100.0);
        for _ in 0..20 {
            f.predict(0.1, 3.0);
            f.update(8.0, 1.0);
        }
        assert!((f.mean_mps - 8.0).abs() < 1e-3);
        assert!(f.variance < 0.5);
    }
}
