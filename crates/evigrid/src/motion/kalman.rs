//! A track's velocity filter: the velocity block of a constant-velocity Kalman filter, one
//! independent filter per axis.
//!
//! The position of a track is its cluster's centroid, taken as measured rather than filtered:
//! the visible part of an object changes (a façade slides into view as the ego drives along
//! it, a car turns its side) much faster and further than the object moves, and a filter fed
//! those centroids would read the change as speed. The velocity is measured by registration
//! instead (`register`), and filtered here: constant velocity with white acceleration of
//! standard deviation σ_a, so over `dt` the velocity's variance grows by (σ_a·dt)².
//!
//! With `motion.jerk_sigma_mps3` the filter also keeps an acceleration, a random walk driven
//! by a white jerk, and reads each registration as what it is: the mean velocity over the past
//! frames it fits, half its mean span back on average. A braking car's registrations lag its
//! speed by up to half a second; the acceleration they show carries the velocity to the stop.

/// The velocity estimate of one axis: mean and variance, m/s and (m/s)², and, with
/// `motion.jerk_sigma_mps3` (otherwise held at zero), the acceleration, its variance and its
/// covariance with the velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct VelocityFilter {
    pub(crate) mean_mps: f64,
    pub(crate) variance: f64,
    /// Acceleration, m/s².
    pub(crate) accel_mps2: f64,
    /// Variance of the acceleration, (m/s²)².
    pub(crate) accel_variance: f64,
    /// Covariance of the velocity and the acceleration, m²/s³.
    pub(crate) covariance: f64,
}

impl VelocityFilter {
    /// A filter with a prior velocity and its variance, its acceleration zero and known (its
    /// variance grows by the jerk's noise from there, `motion.jerk_sigma_mps3`).
    pub(crate) fn new(mean_mps: f64, variance: f64) -> Self {
        Self {
            mean_mps,
            variance,
            accel_mps2: 0.0,
            accel_variance: 0.0,
            covariance: 0.0,
        }
    }

    /// Prediction over `dt_s`: the velocity moves by the acceleration and its variance grows
    /// by (σ_a·dt)²; the acceleration is a random walk driven by a white jerk of standard
    /// deviation `jerk_sigma_mps3` (Q = σ_j²·[dt³/3, dt²/2; dt²/2, dt]). With σ_j = 0 and no
    /// acceleration known, the constant-velocity filter.
    pub(crate) fn predict(&mut self, dt_s: f64, accel_sigma_mps2: f64, jerk_sigma_mps3: f64) {
        self.mean_mps += self.accel_mps2 * dt_s;
        // P ← F P Fᵀ with F = [1, dt; 0, 1].
        self.variance += 2.0 * dt_s * self.covariance + dt_s * dt_s * self.accel_variance;
        self.covariance += dt_s * self.accel_variance;
        let spread = accel_sigma_mps2 * dt_s;
        self.variance += spread * spread;
        let q = jerk_sigma_mps3 * jerk_sigma_mps3;
        self.variance += q * dt_s.powi(3) / 3.0;
        self.covariance += q * dt_s * dt_s / 2.0;
        self.accel_variance += q * dt_s;
    }

    /// Update with a measured velocity of variance `measurement_variance` that is the mean
    /// velocity over a span reaching `lag_s` into the past on average: under a constant
    /// acceleration a, it reads v − a·lag_s (H = [1, −lag_s]).
    pub(crate) fn update_lagged(
        &mut self,
        measured_mps: f64,
        measurement_variance: f64,
        lag_s: f64,
    ) {
        let h = -lag_s;
        // P Hᵀ, and the innovation's variance.
        let pv = self.variance + h * self.covariance;
        let pa = self.covariance + h * self.accel_variance;
        let innovation_variance = pv + h * pa + measurement_variance;
        if innovation_variance <= 0.0 {
            return;
        }
        let innovation = measured_mps - (self.mean_mps + h * self.accel_mps2);
        self.mean_mps += pv / innovation_variance * innovation;
        self.accel_mps2 += pa / innovation_variance * innovation;
        self.variance -= pv * pv / innovation_variance;
        self.covariance -= pv * pa / innovation_variance;
        self.accel_variance -= pa * pa / innovation_variance;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn predict_and_update_by_hand() {
        let mut f = VelocityFilter::new(0.0, 1.0);
        // σ_a = 3 m/s², dt = 0.1 s: variance 1 + 0.3² = 1.09.
        f.predict(0.1, 3.0, 0.0);
        assert!((f.variance - 1.09).abs() < 1e-12);
        // Measured 2 m/s with variance 0.25: gain 1.09 / 1.34.
        f.update_lagged(2.0, 0.25, 0.3);
        let gain = 1.09 / 1.34;
        assert!((f.mean_mps - 2.0 * gain).abs() < 1e-12);
        assert!((f.mean_mps - 1.626_865_671_641_791).abs() < 1e-12);
        assert!((f.variance - 1.09 * 0.25 / 1.34).abs() < 1e-12);
    }

    #[test]
    fn without_an_acceleration_the_lag_changes_nothing() {
        // `predict_and_update_by_hand` above used a lag of 0.3 s: no acceleration is known
        // (variance 0, no covariance), so the update is the constant-velocity one.
        let mut lagged = VelocityFilter::new(1.0, 0.5);
        let mut now = lagged;
        lagged.update_lagged(3.0, 0.5, 0.4);
        now.update_lagged(3.0, 0.5, 0.0);
        assert_eq!(lagged, now);
        assert!((now.mean_mps - 2.0).abs() < 1e-12);
        assert!((now.variance - 0.25).abs() < 1e-12);
        assert_eq!(now.accel_mps2, 0.0);
    }

    #[test]
    fn predict_with_an_acceleration_by_hand() {
        let mut f = VelocityFilter {
            mean_mps: 2.0,
            variance: 0.5,
            accel_mps2: -3.0,
            accel_variance: 1.0,
            covariance: 0.1,
        };
        // dt = 0.1 s, σ_a = 3 m/s², σ_j = 1 m/s³: v = 2 − 0.3 = 1.7; P_vv = 0.5 + 2·0.1·0.1 +
        // 0.01·1 + 0.3² + 1·0.001/3 = 0.620333…; P_va = 0.1 + 0.1·1 + 1·0.01/2 = 0.205;
        // P_aa = 1 + 1·0.1 = 1.1.
        f.predict(0.1, 3.0, 1.0);
        assert!((f.mean_mps - 1.7).abs() < 1e-12);
        assert!((f.accel_mps2 + 3.0).abs() < 1e-12);
        assert!((f.variance - (0.62 + 0.001 / 3.0)).abs() < 1e-12);
        assert!((f.covariance - 0.205).abs() < 1e-12);
        assert!((f.accel_variance - 1.1).abs() < 1e-12);
    }

    #[test]
    fn a_lagged_measurement_below_the_velocity_shows_an_acceleration_by_hand() {
        let mut f = VelocityFilter {
            mean_mps: 2.0,
            variance: 1.0,
            accel_mps2: 0.0,
            accel_variance: 0.25,
            covariance: 0.0,
        };
        // Measured 1 m/s (variance 0.5) over a span 0.2 s back on average: H = [1, −0.2],
        // P·Hᵀ = (1, −0.05), S = 1 + 0.01 + 0.5 = 1.51, innovation 1 − 2 = −1.
        f.update_lagged(1.0, 0.5, 0.2);
        assert!((f.mean_mps - (2.0 - 1.0 / 1.51)).abs() < 1e-12);
        // The velocity was lower 0.2 s ago: it has been rising.
        assert!((f.accel_mps2 - 0.05 / 1.51).abs() < 1e-12);
        assert!((f.variance - (1.0 - 1.0 / 1.51)).abs() < 1e-12);
        assert!((f.covariance - 0.05 / 1.51).abs() < 1e-12);
        assert!((f.accel_variance - (0.25 - 0.0025 / 1.51)).abs() < 1e-12);
    }

    #[test]
    fn repeated_measurements_converge_and_shrink_the_variance() {
        let mut f = VelocityFilter::new(0.0, 100.0);
        for _ in 0..20 {
            f.predict(0.1, 3.0, 0.0);
            f.update_lagged(8.0, 1.0, 0.0);
        }
        assert!((f.mean_mps - 8.0).abs() < 1e-3);
        assert!(f.variance < 0.5);
    }
}
