//! The one conversion from the drive's poses (nalgebra) to the pipeline's.

use nalgebra::Isometry3;

/// The pose as the pipeline takes it: the same transform, as a row-major rotation matrix and a
/// translation.
pub(crate) fn to_pipeline(pose: &Isometry3<f64>) -> evigrid::Isometry3 {
    let r = pose.rotation.to_rotation_matrix();
    let m = r.matrix();
    let t = pose.translation.vector;
    evigrid::Isometry3 {
        rotation: [
            [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
        ],
        translation: [t.x, t.y, t.z],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pipeline_pose_is_the_same_transform() {
        let pose = Isometry3::from_parts(
            nalgebra::Translation3::new(1.0, 2.0, 3.0),
            nalgebra::UnitQuaternion::from_euler_angles(0.1, -0.2, 1.3),
        );
        let ours = to_pipeline(&pose);
        let expected = evigrid::Isometry3::from_xyz_rpy(1.0, 2.0, 3.0, 0.1, -0.2, 1.3);
        for (a, b) in ours
            .rotation
            .iter()
            .flatten()
            .zip(expected.rotation.iter().flatten())
        {
            assert!((a - b).abs() < 1e-12);
        }
        let p = pose.transform_point(&nalgebra::Point3::new(4.0, -5.0, 6.0));
        let q = ours.transform_point([4.0, -5.0, 6.0]);
        assert!(
            (p.x - q[0]).abs() < 1e-12 && (p.y - q[1]).abs() < 1e-12 && (p.z - q[2]).abs() < 1e-12
        );
    }
}
