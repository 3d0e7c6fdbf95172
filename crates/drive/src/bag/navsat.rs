//! Poses from `sensor_msgs/msg/NavSatFix`: a WGS84 position and nothing else.
//!
//! A fix carries no attitude, so the heading is the *course over ground*: the direction from the
//! fix before to the fix after (in the caller's projection, so no grid convergence is needed),
//! once they lie at least [`MIN_COURSE_BASELINE_M`] apart; while the receiver stands still the
//! last course is held, and fixes before the first movement take the first course. Roll and
//! pitch are zero. The course equals the heading only when the vehicle does not slip sideways: a
//! car's differs by a few degrees in turns, which moves a lidar point at 30 m by about a metre.
//! Prefer tf or odometry when the recording has them. Fixes with status `STATUS_NO_FIX` or a
//! non-finite position are skipped.

use super::error::BagError;
use crate::poses::PoseTrack;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2};
use std::path::PathBuf;

/// Smallest distance (metres) between the fixes around a fix for their direction to count as a
/// course: GNSS noise of a few centimetres would make the course of a standing car random.
pub const MIN_COURSE_BASELINE_M: f64 = 0.5;

/// One usable fix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeodeticFix {
    /// Header stamp, seconds.
    pub time_s: f64,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Altitude, metres (becomes z).
    pub alt_m: f64,
}

/// Fixes of one topic, strictly increasing in time, with the rigid transform from the fix's frame
/// to the cloud's frame (from `/tf_static`, or the identity when they are the same frame).
#[derive(Debug, Clone, PartialEq)]
pub struct GeodeticTrack {
    pub(crate) path: PathBuf,
    pub(crate) topic: String,
    /// The fixes.
    pub fixes: Vec<GeodeticFix>,
    /// `fix_frame_from_sensor`.
    pub fix_from_sensor: Isometry3<f64>,
}

impl GeodeticTrack {
    /// `world_from_sensor` in the projection's frame (see the module documentation for the
    /// heading).
    ///
    /// # Errors
    ///
    /// [`BagError::Poses`] when the projection cannot place a fix or the receiver never moves
    /// [`MIN_COURSE_BASELINE_M`].
    pub fn into_track<P>(&self, projection: &P) -> Result<PoseTrack, BagError>
    where
        P: Fn(f64, f64) -> (f64, f64) + ?Sized,
    {
        let fail = |message: String| BagError::Poses {
            path: self.path.clone(),
            message: format!("{}: {message}", self.topic),
        };
        let mut xy = Vec::with_capacity(self.fixes.len());
        for f in &self.fixes {
            let (e, n) = projection(f.lat_deg, f.lon_deg);
            if !(e.is_finite() && n.is_finite()) {
                return Err(fail(format!(
                    "the projection cannot place lat {}, lon {}",
                    f.lat_deg, f.lon_deg
                )));
            }
            xy.push(Vector2::new(e, n));
        }
        let last = xy.len().saturating_sub(1);
        let mut course: Vec<Option<f64>> = (0..xy.len())
            .map(|i| {
                let d = xy[(i + 1).min(last)] - xy[i.saturating_sub(1)];
                (d.norm() >= MIN_COURSE_BASELINE_M).then(|| d.y.atan2(d.x))
            })
            .collect();
        let Some(first) = course.iter().flatten().next().copied() else {
            return Err(fail(format!(
                "no heading: the receiver never moved {MIN_COURSE_BASELINE_M} m between fixes \
                 (a NavSatFix has no attitude; use tf or odometry)"
            )));
        };
        let mut held = first;
        for c in &mut course {
            held = c.unwrap_or(held);
            *c = Some(held);
        }
        let poses = self
            .fixes
            .iter()
            .zip(&xy)
            .zip(&course)
            .map(|((f, p), c)| {
                Isometry3::from_parts(
                    Translation3::new(p.x, p.y, f.alt_m),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, c.unwrap_or(first)),
                ) * self.fix_from_sensor
            })
            .collect();
        PoseTrack::new(self.fixes.iter().map(|f| f.time_s).collect(), poses)
            .map_err(|e| fail(e.to_string()))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn course_from_neighbours_held_while_standing() {
        // Degrees as metres: a toy projection. Stand, go north 1 m per fix, stand.
        let fixes = [0.0, 0.0, 1.0, 2.0, 2.0, 2.0]
            .iter()
            .enumerate()
            .map(|(i, &n)| GeodeticFix {
                time_s: i as f64,
                lat_deg: n,
                lon_deg: 0.0,
                alt_m: 5.0,
            })
            .collect();
        let track = GeodeticTrack {
            path: "b.mcap".into(),
            topic: "/fix".into(),
            fixes,
            fix_from_sensor: Isometry3::translation(1.0, 0.0, 0.0),
        };
        let t = track.into_track(&|lat, lon| (lon, lat)).unwrap();
        for pose in t.poses() {
            // Heading north: the sensor 1 m ahead is 1 m further north.
            let yaw = pose.rotation.euler_angles().2;
            assert!((yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12, "{yaw}");
            assert_eq!(pose.translation.vector.z, 5.0);
        }
        assert!((t.poses()[3].translation.vector.y - 3.0).abs() < 1e-12);
        let standing = GeodeticTrack {
            fixes: track.fixes[..2].to_vec(),
            ..track
        };
        let err = standing.into_track(&|lat, lon| (lon, lat)).unwrap_err();
        assert!(err.to_string().contains("never moved"), "{err}");
    }
}
