//! Class-rate discounting: one rate per class, mass moves to Ω.

use super::{Discounting, check_rate};
use crate::{BeliefError, Frame, Mass, Real, Set, real::reciprocal};

/// How the rate of a set is derived from the rates of the classes it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SetRate {
    /// The smallest class rate: a set fades as slowly as its most durable class (optimistic).
    Min,
    /// The largest class rate: a set fades as fast as its most fleeting class (conservative).
    Max,
    /// The mean of the class rates (proportional).
    Mean,
}

/// Class-rate discounting: class `θ` has rate `α_θ`; each set `A ≠ Ω` keeps `(1 − α_A)` of its
/// mass and gives the rest to Ω, with `α_A` the [`SetRate`] of the rates of the classes in `A`.
///
/// With equal rates this is exactly classical discounting. The empty set holds no class;
/// *decision* (SPEC is silent): `α_∅` is the set rate of all classes, i.e. the rate of Ω's
/// classes, so that equal rates still give classical discounting on subnormal masses.
///
/// # Examples
///
/// ```
/// use belief::{ClassRateDiscount, Discounting, Frame, Mass, SetRate};
///
/// let frame = Frame::new(["F", "M"])?;
/// let m = Mass::<f64>::from_named(&frame, &[(&["F"], 0.5), (&["M"], 0.5)])?;
/// // Free space fades at 0.1, moving objects at 0.5.
/// let d = ClassRateDiscount::new(vec![0.1, 0.5], SetRate::Max)?.discount(&m)?;
/// // F keeps 0.9·0.5 = 0.45, M keeps 0.5·0.5 = 0.25, Ω gets 0.05 + 0.25 = 0.30.
/// assert!((d.get(frame.set(&["F"])?) - 0.45).abs() < 1e-12);
/// assert!((d.get(frame.set(&["M"])?) - 0.25).abs() < 1e-12);
/// assert!((d.get(frame.omega()) - 0.30).abs() < 1e-12);
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// SPEC §5 step 3 `class_rates`; M. Kurdej, V. Cherfaoui, "Conservative, proportional and
/// optimistic contextual discounting in the belief functions theory", FUSION 2013.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassRateDiscount<R: Real> {
    class_rates: Vec<R>,
    set_rate: SetRate,
}

impl<R: Real> ClassRateDiscount<R> {
    /// Discounting with `class_rates[k]` the rate of element `k`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::RateOutOfRange`] unless every rate is in `[0, 1]`,
    /// [`BeliefError::FrameTooLarge`] for more than eight rates, [`BeliefError::EmptyFrame`] for
    /// none.
    pub fn new(class_rates: Vec<R>, set_rate: SetRate) -> Result<Self, BeliefError> {
        if class_rates.is_empty() {
            return Err(BeliefError::EmptyFrame);
        }
        if class_rates.len() > Frame::MAX_LEN {
            return Err(BeliefError::FrameTooLarge {
                len: class_rates.len(),
            });
        }
        for &rate in &class_rates {
            check_rate(rate)?;
        }
        Ok(Self {
            class_rates,
            set_rate,
        })
    }

    /// The rate of each class.
    pub fn class_rates(&self) -> &[R] {
        &self.class_rates
    }

    /// How set rates are derived.
    pub fn set_rate(&self) -> SetRate {
        self.set_rate
    }

    /// The rate `α_A` applied to the mass of `set` (for ∅, the rate of all classes together).
    /// Elements beyond the class rates are ignored.
    pub fn rate_of(&self, set: Set) -> R {
        let all = Set::from_bits(((1_u16 << self.class_rates.len()) - 1) as u8);
        let classes = if set.is_empty() {
            all
        } else {
            set.intersection(all)
        };
        let mut rates = self
            .class_rates
            .iter()
            .enumerate()
            .filter(|&(k, _)| classes.contains(k))
            .map(|(_, &rate)| rate);
        let Some(first) = rates.next() else {
            return R::ZERO;
        };
        match self.set_rate {
            SetRate::Min => rates.fold(first, |a, b| if b < a { b } else { a }),
            SetRate::Max => rates.fold(first, |a, b| if b > a { b } else { a }),
            SetRate::Mean => (first + rates.sum::<R>()) * reciprocal::<R>(classes.len()),
        }
    }
}

impl<R: Real> Discounting<R> for ClassRateDiscount<R> {
    fn discount(&self, m: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        if self.class_rates.len() != m.frame().len() {
            return Err(BeliefError::WrongLength {
                expected: m.frame().len(),
                found: self.class_rates.len(),
            });
        }
        let omega = m.frame().omega();
        let mut values = m.values().to_vec();
        let mut to_omega = R::ZERO;
        for set in m.frame().subsets().filter(|&set| set != omega) {
            let moved = self.rate_of(set) * values[set.index()];
            values[set.index()] -= moved;
            to_omega += moved;
        }
        values[omega.index()] += to_omega;
        Ok(Mass::from_computed(m.frame(), values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ClassicalDiscount;
    use crate::testing::{arb_mass, assert_close, assert_valid, frame_of};
    use proptest::prelude::*;

    #[test]
    fn set_rates_by_hand() -> Result<(), BeliefError> {
        // Classes F, I, U, S, M at 0.1, 0.0, 0.2, 0.3, 0.8; A = {S, M}.
        let rates = vec![0.1, 0.0, 0.2, 0.3, 0.8];
        let sm = Set::from_bits(0b11000);
        assert_eq!(
            ClassRateDiscount::new(rates.clone(), SetRate::Min)?.rate_of(sm),
            0.3
        );
        assert_eq!(
            ClassRateDiscount::new(rates.clone(), SetRate::Max)?.rate_of(sm),
            0.8
        );
        let mean = ClassRateDiscount::new(rates.clone(), SetRate::Mean)?;
        // (0.3 + 0.8)/2 = 0.55; ∅ uses all five: (0.1 + 0 + 0.2 + 0.3 + 0.8)/5 = 0.28.
        assert!((mean.rate_of(sm) - 0.55).abs() < 1e-15);
        assert!((mean.rate_of(Set::EMPTY) - 0.28).abs() < 1e-15);
        Ok(())
    }

    #[test]
    fn moves_discounted_mass_to_omega_only() -> Result<(), BeliefError> {
        let frame = Frame::new(["F", "I", "M"])?;
        let m = Mass::from_named(
            &frame,
            &[(&["F"], 0.3), (&["I", "M"], 0.5), (&["F", "I", "M"], 0.2)],
        )?;
        let d = ClassRateDiscount::new(vec![0.1, 0.2, 0.6], SetRate::Mean)?.discount(&m)?;
        // F keeps 0.9·0.3 = 0.27; {I,M} rate (0.2 + 0.6)/2 = 0.4 keeps 0.6·0.5 = 0.30;
        // Ω: 0.2 + 0.03 + 0.20 = 0.43.
        assert_close(
            d.values(),
            &[0.0, 0.27, 0.0, 0.0, 0.0, 0.0, 0.30, 0.43],
            1e-15,
        );
        Ok(())
    }

    #[test]
    fn number_of_rates_must_match_frame() -> Result<(), BeliefError> {
        let d = ClassRateDiscount::new(vec![0.1, 0.2], SetRate::Max)?;
        assert_eq!(
            d.discount(&Mass::<f64>::vacuous(&frame_of(3))),
            Err(BeliefError::WrongLength {
                expected: 3,
                found: 2
            })
        );
        assert!(ClassRateDiscount::new(vec![0.1, 1.2], SetRate::Max).is_err());
        assert!(ClassRateDiscount::<f64>::new(vec![], SetRate::Max).is_err());
        Ok(())
    }

    proptest! {
        #[test]
        fn equal_rates_are_classical(m in arb_mass(1..=6), alpha in 0.0..=1.0_f64) {
            let classical = ClassicalDiscount::new(alpha)?.discount(&m)?;
            for set_rate in [SetRate::Min, SetRate::Max, SetRate::Mean] {
                let rates = vec![alpha; m.frame().len()];
                let d = ClassRateDiscount::new(rates, set_rate)?.discount(&m)?;
                assert_valid(&d);
                assert_close(d.values(), classical.values(), 1e-12);
            }
        }

        #[test]
        fn valid_for_any_rates(
            m in arb_mass(5..=5),
            rates in prop::collection::vec(0.0..=1.0_f64, 5),
        ) {
            for set_rate in [SetRate::Min, SetRate::Max, SetRate::Mean] {
                assert_valid(&ClassRateDiscount::new(rates.clone(), set_rate)?.discount(&m)?);
            }
        }
    }
}
