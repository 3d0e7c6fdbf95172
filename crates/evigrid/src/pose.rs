//! Rigid transforms: where a sensor is in the world.

/// A rigid transform in 3-D (rotation then translation), in `f64`.
///
/// Named by what it maps, as `world_from_sensor`: `world_from_sensor.transform_point(p_sensor)`
/// gives the point in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Isometry3 {
    /// Rotation matrix, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation, metres: where the source frame's origin lies in the target frame.
    pub translation: [f64; 3],
}

impl Isometry3 {
    /// The identity transform.
    pub const IDENTITY: Self = Self {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0; 3],
    };

    /// From a position (metres) and roll, pitch, yaw (radians) in the ROS convention: rotations
    /// about the fixed x, y, z axes in that order, so `R = Rz(yaw) · Ry(pitch) · Rx(roll)`.
    pub fn from_xyz_rpy(x_m: f64, y_m: f64, z_m: f64, roll: f64, pitch: f64, yaw: f64) -> Self {
        let (sr, cr) = roll.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        let (sy, cy) = yaw.sin_cos();
        Self {
            rotation: [
                [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                [-sp, cp * sr, cp * cr],
            ],
            translation: [x_m, y_m, z_m],
        }
    }

    /// Rotates a vector (no translation).
    #[inline]
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [
            r[0][0] * v[0] + r[0][1] * v[1] + r[0][2] * v[2],
            r[1][0] * v[0] + r[1][1] * v[1] + r[1][2] * v[2],
            r[2][0] * v[0] + r[2][1] * v[1] + r[2][2] * v[2],
        ]
    }

    /// Maps a point: `R · p + t`.
    #[inline]
    pub fn transform_point(&self, p: [f64; 3]) -> [f64; 3] {
        let v = self.rotate(p);
        [
            v[0] + self.translation[0],
            v[1] + self.translation[1],
            v[2] + self.translation[2],
        ]
    }

    /// True if every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.rotation
            .iter()
            .flatten()
            .chain(&self.translation)
            .all(|v| v.is_finite())
    }
}
