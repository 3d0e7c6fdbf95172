//! Rigid transforms: where a sensor is in the world.
//!
//! A pose is nalgebra's isometry with a rotation matrix, [`IsometryMatrix3`] (in `f64`); there
//! is no pose type of evigrid's own. [`PoseExt`] adds the three things the method needs that
//! nalgebra spells otherwise: the ROS roll-pitch-yaw constructor, point maps on the `[f64; 3]`
//! the hot loops use, and a finiteness check for refusing a bad pose.

/// A rigid transform in 3-D (rotation then translation), in `f64`: nalgebra's isometry with a
/// rotation matrix.
///
/// Named by what it maps, as `world_from_sensor`: `world_from_sensor.transform_xyz(p_sensor)`
/// gives the point in the world frame. The rotation is stored as a matrix, not a quaternion,
/// because every point of every scan is mapped with it: nine products, no conversion per point.
/// The drives' poses (`evigrid-drive`, the odometry) are nalgebra's quaternion `Isometry3<f64>`,
/// which interpolates by slerp; one becomes the other with
/// `IsometryMatrix3::from_parts(pose.translation, pose.rotation.to_rotation_matrix())`.
///
/// ```
/// use evigrid::{IsometryMatrix3, PoseExt};
///
/// // A sensor 1.73 m above (10, 5), facing north (yaw 90°).
/// let world_from_sensor =
///     IsometryMatrix3::from_xyz_rpy(10.0, 5.0, 1.73, 0.0, 0.0, std::f64::consts::FRAC_PI_2);
/// // A return 2 m ahead of the sensor, on the ground.
/// let [x, y, z] = world_from_sensor.transform_xyz([2.0, 0.0, -1.73]);
/// assert!((x - 10.0).abs() < 1e-12 && (y - 7.0).abs() < 1e-12 && z.abs() < 1e-12);
/// ```
pub type IsometryMatrix3 = nalgebra::IsometryMatrix3<f64>;

/// What the method needs of an [`IsometryMatrix3`] beyond nalgebra's own methods.
///
/// The maps take and give `[f64; 3]` (not nalgebra's `Point3`) and sum each row's products left
/// to right, the arithmetic the sensor model has always used, so results stay bit for bit.
pub trait PoseExt: Sized {
    /// From a position (metres) and roll, pitch, yaw (radians) in the ROS convention: rotations
    /// about the fixed x, y, z axes in that order, so `R = Rz(yaw) · Ry(pitch) · Rx(roll)`
    /// (nalgebra's `Rotation3::from_euler_angles`).
    fn from_xyz_rpy(x_m: f64, y_m: f64, z_m: f64, roll: f64, pitch: f64, yaw: f64) -> Self;

    /// Rotates a vector (no translation): `R · v`.
    fn rotate_xyz(&self, v: [f64; 3]) -> [f64; 3];

    /// Maps a point: `R · p + t`.
    fn transform_xyz(&self, p: [f64; 3]) -> [f64; 3];

    /// True if every entry of the rotation and of the translation is finite.
    fn is_finite(&self) -> bool;
}

impl PoseExt for IsometryMatrix3 {
    fn from_xyz_rpy(x_m: f64, y_m: f64, z_m: f64, roll: f64, pitch: f64, yaw: f64) -> Self {
        Self::from_parts(
            nalgebra::Translation3::new(x_m, y_m, z_m),
            nalgebra::Rotation3::from_euler_angles(roll, pitch, yaw),
        )
    }

    #[inline]
    fn rotate_xyz(&self, v: [f64; 3]) -> [f64; 3] {
        let r = self.rotation.matrix();
        [
            r.m11 * v[0] + r.m12 * v[1] + r.m13 * v[2],
            r.m21 * v[0] + r.m22 * v[1] + r.m23 * v[2],
            r.m31 * v[0] + r.m32 * v[1] + r.m33 * v[2],
        ]
    }

    #[inline]
    fn transform_xyz(&self, p: [f64; 3]) -> [f64; 3] {
        let v = self.rotate_xyz(p);
        let t = &self.translation.vector;
        [v[0] + t.x, v[1] + t.y, v[2] + t.z]
    }

    fn is_finite(&self) -> bool {
        self.rotation
            .matrix()
            .iter()
            .chain(self.translation.vector.iter())
            .all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ROS matrix `Rz(yaw) · Ry(pitch) · Rx(roll)` written out, row by row, as evigrid's own
    /// pose type computed it before it was replaced by nalgebra's.
    fn ros_rows(roll: f64, pitch: f64, yaw: f64) -> [[f64; 3]; 3] {
        let (sr, cr) = roll.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        let (sy, cy) = yaw.sin_cos();
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    }

    #[test]
    fn roll_pitch_yaw_give_the_ros_matrix_bit_for_bit() {
        let (roll, pitch, yaw) = (0.1, -0.2, 1.3);
        let pose = IsometryMatrix3::from_xyz_rpy(1.0, -2.0, 0.5, roll, pitch, yaw);
        let rows = ros_rows(roll, pitch, yaw);
        for (r, row) in rows.iter().enumerate() {
            for (c, entry) in row.iter().enumerate() {
                assert_eq!(
                    pose.rotation[(r, c)].to_bits(),
                    entry.to_bits(),
                    "({r}, {c})"
                );
            }
        }
        assert_eq!(
            pose.translation.vector,
            nalgebra::Vector3::new(1.0, -2.0, 0.5)
        );
    }

    #[test]
    fn a_quarter_turn_of_yaw_maps_east_to_north() {
        // Hand-computed: yaw 90° sends x to y; the sensor sits at (1, 2, 3).
        let pose =
            IsometryMatrix3::from_xyz_rpy(1.0, 2.0, 3.0, 0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let [x, y, z] = pose.transform_xyz([4.0, 0.0, 0.0]);
        assert!((x - 1.0).abs() < 1e-12 && (y - 6.0).abs() < 1e-12 && (z - 3.0).abs() < 1e-12);
        let [x, y, z] = pose.rotate_xyz([0.0, 4.0, 0.0]);
        assert!((x + 4.0).abs() < 1e-12 && y.abs() < 1e-12 && z.abs() < 1e-12);
    }

    #[test]
    fn the_array_maps_are_the_row_sums_bit_for_bit_and_agree_with_nalgebra() {
        let (roll, pitch, yaw) = (0.1, -0.2, 1.3);
        let pose = IsometryMatrix3::from_xyz_rpy(1.0, -2.0, 0.5, roll, pitch, yaw);
        let rows = ros_rows(roll, pitch, yaw);
        let p = [4.0, -5.0, 6.0];
        let expected = rows.map(|row| row[0] * p[0] + row[1] * p[1] + row[2] * p[2]);
        assert_eq!(
            pose.rotate_xyz(p).map(f64::to_bits),
            expected.map(f64::to_bits)
        );
        let t = [1.0, -2.0, 0.5];
        let expected = [expected[0] + t[0], expected[1] + t[1], expected[2] + t[2]];
        assert_eq!(
            pose.transform_xyz(p).map(f64::to_bits),
            expected.map(f64::to_bits)
        );

        let point = pose.transform_point(&nalgebra::Point3::new(4.0, -5.0, 6.0));
        let vector = pose.transform_vector(&nalgebra::Vector3::new(4.0, -5.0, 6.0));
        for k in 0..3 {
            assert!((point[k] - pose.transform_xyz(p)[k]).abs() < 1e-12);
            assert!((vector[k] - pose.rotate_xyz(p)[k]).abs() < 1e-12);
        }
    }

    #[test]
    fn a_non_finite_entry_anywhere_is_not_finite() {
        assert!(IsometryMatrix3::identity().is_finite());
        assert!(!IsometryMatrix3::from_xyz_rpy(0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0).is_finite());
        assert!(!IsometryMatrix3::from_xyz_rpy(0.0, 0.0, 0.0, f64::INFINITY, 0.0, 0.0).is_finite());
        assert!(
            !IsometryMatrix3::from_xyz_rpy(f64::NEG_INFINITY, 0.0, 0.0, 0.0, 0.0, 0.0).is_finite()
        );
    }
}
