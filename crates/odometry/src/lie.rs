//! The exponential and logarithm of SE(3), tangent vectors ordered (translation, rotation).
//!
//! ICP updates and the constant-velocity model live in the tangent space: a screw motion can be
//! scaled (a velocity over a different time, a fraction of a sweep) and then mapped back.

use nalgebra::{Isometry3, Matrix3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};

/// Below this rotation angle (radians) the series forms are used: the closed forms divide by
/// powers of the angle.
const SMALL_ANGLE: f64 = 1e-5;

/// The cross-product matrix: `skew(v) · u = v × u`.
pub(crate) fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// `exp` of a twist `(ρ, ω)`: rotation `exp(ω)`, translation `V(ω) ρ`.
pub(crate) fn exp(twist: &Vector6<f64>) -> Isometry3<f64> {
    let rho = twist.fixed_rows::<3>(0).into_owned();
    let omega = twist.fixed_rows::<3>(3).into_owned();
    let theta_sq = omega.norm_squared();
    let theta = theta_sq.sqrt();
    let (a, b) = if theta < SMALL_ANGLE {
        (0.5 - theta_sq / 24.0, 1.0 / 6.0 - theta_sq / 120.0)
    } else {
        (
            (1.0 - theta.cos()) / theta_sq,
            (theta - theta.sin()) / (theta_sq * theta),
        )
    };
    let w = skew(&omega);
    let v = Matrix3::identity() + w * a + w * w * b;
    Isometry3::from_parts(
        Translation3::from(v * rho),
        UnitQuaternion::from_scaled_axis(omega),
    )
}

/// The constant twist per second (body frame, as [`exp`] takes it) that carries `from` to `to`
/// in `seconds`: the velocity a constant-velocity prediction extrapolates with
/// `to · exp(velocity · Δt)`.
pub(crate) fn velocity(from: &Isometry3<f64>, to: &Isometry3<f64>, seconds: f64) -> Vector6<f64> {
    log(&(from.inverse() * to)) / seconds
}

/// The adjoint of a rigid motion `(R, t)` on twists ordered (translation, rotation),
/// `[[R, [t]× R], [0, R]]`: `motion · exp(ξ) · motion⁻¹ = exp(adjoint(motion) · ξ)`, which carries
/// a twist from the frame the motion leads to into the frame it starts from.
pub(crate) fn adjoint(motion: &Isometry3<f64>) -> Matrix6<f64> {
    let rotation = motion.rotation.to_rotation_matrix().into_inner();
    let mut adjoint = Matrix6::zeros();
    adjoint.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation);
    adjoint
        .fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(skew(&motion.translation.vector) * rotation));
    adjoint.fixed_view_mut::<3, 3>(3, 3).copy_from(&rotation);
    adjoint
}

/// `log` of a rigid motion, the inverse of [`exp`] for rotations below π.
pub(crate) fn log(motion: &Isometry3<f64>) -> Vector6<f64> {
    let omega = motion.rotation.scaled_axis();
    let theta_sq = omega.norm_squared();
    let theta = theta_sq.sqrt();
    let c = if theta < SMALL_ANGLE {
        1.0 / 12.0 + theta_sq / 720.0
    } else {
        (1.0 - theta * theta.sin() / (2.0 * (1.0 - theta.cos()))) / theta_sq
    };
    let w = skew(&omega);
    let v_inv = Matrix3::identity() - w * 0.5 + w * w * c;
    let rho = v_inv * motion.translation.vector;
    Vector6::new(rho.x, rho.y, rho.z, omega.x, omega.y, omega.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    #[test]
    fn exp_of_pure_translation_and_pure_rotation() {
        let t = exp(&Vector6::new(1.0, 2.0, 3.0, 0.0, 0.0, 0.0));
        assert_relative_eq!(t.translation.vector, Vector3::new(1.0, 2.0, 3.0));
        let r = exp(&Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.5));
        assert_relative_eq!(r.rotation.angle(), 0.5, epsilon = 1e-12);
        assert_relative_eq!(r.translation.vector.norm(), 0.0);
    }

    #[test]
    fn a_screw_along_z_turns_in_a_circle() {
        // Moving 1 m forward while turning by π/2 ends on a quarter circle of radius 2/π.
        let quarter = exp(&Vector6::new(
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            std::f64::consts::FRAC_PI_2,
        ));
        let radius = 2.0 / std::f64::consts::PI;
        assert_relative_eq!(
            quarter.translation.vector,
            Vector3::new(radius, radius, 0.0),
            epsilon = 1e-12
        );
    }

    proptest! {
        #[test]
        fn log_inverts_exp(
            rho in prop::array::uniform3(-5.0f64..5.0),
            omega in prop::array::uniform3(-1.5f64..1.5),
            tiny in prop::bool::ANY,
        ) {
            let k = if tiny { 1e-7 } else { 1.0 };
            let twist = Vector6::new(rho[0], rho[1], rho[2], k * omega[0], k * omega[1], k * omega[2]);
            let back = log(&exp(&twist));
            prop_assert!((back - twist).norm() < 1e-9, "{twist} -> {back}");
        }

        #[test]
        fn the_adjoint_moves_a_twist_between_frames(
            rho in prop::array::uniform3(-5.0f64..5.0),
            omega in prop::array::uniform3(-1.0f64..1.0),
            motion_rho in prop::array::uniform3(-50.0f64..50.0),
            motion_omega in prop::array::uniform3(-1.5f64..1.5),
        ) {
            let twist = Vector6::new(rho[0], rho[1], rho[2], omega[0], omega[1], omega[2]);
            let motion = exp(&Vector6::new(
                motion_rho[0], motion_rho[1], motion_rho[2],
                motion_omega[0], motion_omega[1], motion_omega[2],
            ));
            let conjugated = motion * exp(&twist) * motion.inverse();
            let moved = exp(&(adjoint(&motion) * twist));
            prop_assert!((conjugated.translation.vector - moved.translation.vector).norm() < 1e-9);
            prop_assert!(conjugated.rotation.angle_to(&moved.rotation) < 1e-9);
        }

        #[test]
        fn halves_compose_to_the_whole(
            rho in prop::array::uniform3(-5.0f64..5.0),
            omega in prop::array::uniform3(-1.0f64..1.0),
        ) {
            let motion = exp(&Vector6::new(rho[0], rho[1], rho[2], omega[0], omega[1], omega[2]));
            let half = exp(&(log(&motion) * 0.5));
            let whole = half * half;
            prop_assert!((whole.translation.vector - motion.translation.vector).norm() < 1e-9);
            prop_assert!(whole.rotation.angle_to(&motion.rotation) < 1e-9);
        }
    }
}
