//! Why odometry refused a parameter set or a scan.

/// Errors of [`crate::Odometry`]. A refused scan leaves the odometry's state unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum OdometryError {
    /// A parameter is out of its valid range.
    #[error("parameter `{name}` = {value}: {expected}")]
    InvalidParameter {
        /// The field of [`crate::OdometryParams`].
        name: &'static str,
        /// Its value, as given.
        value: String,
        /// What it must be.
        expected: &'static str,
    },
    /// The scan's time is NaN or infinite.
    #[error("scan time {time_s} s is not finite")]
    NonFiniteTime {
        /// The time given.
        time_s: f64,
    },
    /// The scan's time is not after the previous scan's.
    #[error("scan time {time_s} s is not after the previous scan's {previous_s} s")]
    TimeNotIncreasing {
        /// The previous scan's time.
        previous_s: f64,
        /// The time given.
        time_s: f64,
    },
    /// The scan that would start the map has too few usable points (finite, within the range
    /// limits) to register anything against: with no map yet, its pose would only be the
    /// identity, not a measurement.
    #[error(
        "{usable} usable points (finite, within {min_range_m}-{max_range_m} m) of {input}; the \
         first scan needs at least {min}"
    )]
    TooFewPoints {
        /// Finite points within the range limits.
        usable: usize,
        /// Points given.
        input: usize,
        /// The least accepted, [`crate::MIN_USABLE_POINTS`].
        min: usize,
        /// The odometry's `min_range_m`.
        min_range_m: f64,
        /// The odometry's `max_range_m`.
        max_range_m: f64,
    },
    /// Per-point times were given, but not one per point.
    #[error("{times} point times for {points} points")]
    PointTimesLength {
        /// Number of points.
        points: usize,
        /// Number of times.
        times: usize,
    },
}
