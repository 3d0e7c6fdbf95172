//! Classical discounting (Shafer).

use super::{Discounting, check_rate};
use crate::{BeliefError, Mass, Real};

/// Classical discounting at rate `α`: every set keeps `(1 − α)` of its mass and `α` goes to Ω,
/// `ᵅm(A) = (1 − α)·m(A)` for `A ⊊ Ω`, `ᵅm(Ω) = (1 − α)·m(Ω) + α`.
///
/// `α = 0` leaves `m` unchanged; `α = 1` gives the vacuous mass function.
///
/// # Examples
///
/// ```
/// use belief::{ClassicalDiscount, Discounting, Frame, Mass};
///
/// let frame = Frame::new(["a", "b"])?;
/// let m = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
/// let d = ClassicalDiscount::new(0.1)?.discount(&m)?;
/// // Paper Table I: a 0.18, b 0.54, Ω 0.9·0.2 + 0.1 = 0.28.
/// let expected = [0.0, 0.18, 0.54, 0.28];
/// assert!(d.values().iter().zip(expected).all(|(x, y)| (x - y).abs() < 1e-12));
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// Paper eq 13-14; SPEC §5 step 3 `classical`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClassicalDiscount<R: Real> {
    alpha: R,
}

impl<R: Real> ClassicalDiscount<R> {
    /// Discounting at rate `alpha`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::RateOutOfRange`] unless `0 ≤ alpha ≤ 1`.
    pub fn new(alpha: R) -> Result<Self, BeliefError> {
        check_rate(alpha)?;
        Ok(Self { alpha })
    }

    /// The rate `α`.
    pub fn alpha(&self) -> R {
        self.alpha
    }
}

impl<R: Real> Discounting<R> for ClassicalDiscount<R> {
    fn discount(&self, m: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        let keep = R::ONE - self.alpha;
        let mut values: Vec<R> = m.values().iter().map(|&v| keep * v).collect();
        values[m.frame().omega().index()] += self.alpha;
        Ok(Mass::from_computed(m.frame(), values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass, assert_close, assert_valid};
    use proptest::prelude::*;

    #[test]
    fn mercier_example_on_three_elements() -> Result<(), BeliefError> {
        let frame = crate::Frame::new(["a", "h", "r"])?;
        let m = Mass::from_named(&frame, &[(&["a"], 0.5), (&["r"], 0.5)])?;
        // α = 0.4: a 0.6·0.5 = 0.3, r 0.3, Ω 0.4.
        let d = ClassicalDiscount::new(0.4)?.discount(&m)?;
        assert_close(d.values(), &[0.0, 0.3, 0.0, 0.0, 0.3, 0.0, 0.0, 0.4], 1e-15);
        Ok(())
    }

    #[test]
    fn rates_outside_unit_interval_are_rejected() {
        assert_eq!(
            ClassicalDiscount::new(1.5),
            Err(BeliefError::RateOutOfRange { value: 1.5 })
        );
        assert!(ClassicalDiscount::new(f64::NAN).is_err());
        assert!(ClassicalDiscount::new(-0.1_f32).is_err());
    }

    proptest! {
        #[test]
        fn valid_identity_at_zero_vacuous_at_one(m in arb_mass(1..=6), alpha in 0.0..=1.0_f64) {
            assert_valid(&ClassicalDiscount::new(alpha)?.discount(&m)?);
            assert_close(ClassicalDiscount::new(0.0)?.discount(&m)?.values(), m.values(), 0.0);
            assert_close(
                ClassicalDiscount::new(1.0)?.discount(&m)?.values(),
                Mass::vacuous(m.frame()).values(),
                0.0,
            );
        }
    }
}
