//! The conjunctive rule (unnormalised, TBM).

use super::{Combination, conjunctive_values};
use crate::{BeliefError, Mass, Real};

/// The conjunctive rule `∩`: `(m1 ∩ m2)(A) = Σ_{B∩C=A} m1(B)·m2(C)`, conflict left on ∅.
///
/// For two reliable, independent sources. Commutative and associative; the vacuous mass function is
/// its neutral element.
///
/// # Examples
///
/// ```
/// use belief::{Combination, Conjunctive, Frame, Mass};
///
/// let frame = Frame::new(["a", "b"])?;
/// let m1 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
/// let m2 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.7), (&["b"], 0.1), (&["a", "b"], 0.2)])?;
/// let m = Conjunctive.combine(&m1, &m2)?;
/// // SPEC §1 (Table I corrected): ∅ 0.44, a 0.32, b 0.20, Ω 0.04.
/// let expected = [0.44, 0.32, 0.20, 0.04];
/// assert!(m.values().iter().zip(expected).all(|(x, y)| (x - y).abs() < 1e-12));
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// Paper eq 8; SPEC §1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Conjunctive;

impl<R: Real> Combination<R> for Conjunctive {
    fn combine(&self, a: &Mass<R>, b: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        a.check_same_frame(b)?;
        Ok(Mass::from_computed(
            a.frame(),
            conjunctive_values(a.values(), b.values()),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Frame;
    use crate::testing::{arb_mass, arb_mass_pair, arb_mass_triple, assert_close, assert_valid};
    use proptest::prelude::*;

    #[test]
    fn table_one_corrected() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let m1 = Mass::from_values(&frame, vec![0.0, 0.2, 0.6, 0.2])?;
        let m2 = Mass::from_values(&frame, vec![0.0, 0.7, 0.1, 0.2])?;
        let m = Conjunctive.combine(&m1, &m2)?;
        // ∅: a·b + b·a = 0.2·0.1 + 0.6·0.7 = 0.02 + 0.42 = 0.44
        // a: a·a + a·Ω + Ω·a = 0.14 + 0.04 + 0.14 = 0.32   (the paper prints 0.34)
        // b: b·b + b·Ω + Ω·b = 0.06 + 0.12 + 0.02 = 0.20   (the paper prints 0.18)
        // Ω: Ω·Ω = 0.04
        assert_close(m.values(), &[0.44, 0.32, 0.20, 0.04], 1e-15);
        Ok(())
    }

    #[test]
    fn f32_masses_give_the_same_numbers_to_f32_precision() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let m1 = Mass::<f32>::from_values(&frame, vec![0.0, 0.2, 0.6, 0.2])?;
        let m2 = Mass::<f32>::from_values(&frame, vec![0.0, 0.7, 0.1, 0.2])?;
        let m = Conjunctive.combine(&m1, &m2)?;
        for (got, want) in m.values().iter().zip([0.44_f32, 0.32, 0.20, 0.04]) {
            assert!((got - want).abs() < 1e-6, "{got} vs {want}");
        }
        assert_eq!(crate::check_masses(m.values()), Ok(()));
        Ok(())
    }

    #[test]
    fn mismatched_frames_are_an_error() -> Result<(), BeliefError> {
        let ab = Frame::new(["a", "b"])?;
        let ac = Frame::new(["a", "c"])?;
        let r = Conjunctive.combine(&Mass::<f64>::vacuous(&ab), &Mass::vacuous(&ac));
        assert!(matches!(r, Err(BeliefError::MismatchedFrames { .. })));
        Ok(())
    }

    proptest! {
        #[test]
        fn output_is_valid((a, b) in arb_mass_pair(1..=6)) {
            assert_valid(&Conjunctive.combine(&a, &b)?);
        }

        #[test]
        fn commutative((a, b) in arb_mass_pair(1..=6)) {
            assert_close(
                Conjunctive.combine(&a, &b)?.values(),
                Conjunctive.combine(&b, &a)?.values(),
                1e-12,
            );
        }

        #[test]
        fn associative((a, b, c) in arb_mass_triple(1..=6)) {
            let left = Conjunctive.combine(&Conjunctive.combine(&a, &b)?, &c)?;
            let right = Conjunctive.combine(&a, &Conjunctive.combine(&b, &c)?)?;
            assert_close(left.values(), right.values(), 1e-12);
            assert_close(Conjunctive.combine_all(&[a, b, c])?.values(), left.values(), 1e-12);
        }

        #[test]
        fn vacuous_is_neutral(a in arb_mass(1..=6)) {
            let vacuous = Mass::vacuous(a.frame());
            assert_close(Conjunctive.combine(&a, &vacuous)?.values(), a.values(), 0.0);
        }

        #[test]
        fn equals_product_of_commonalities((a, b) in arb_mass_pair(1..=6)) {
            // q_{a∩b} = q_a · q_b, the classical characterisation of the conjunctive rule.
            let qa = a.commonality();
            let qb = b.commonality();
            let q = Conjunctive.combine(&a, &b)?.commonality();
            for set in a.frame().subsets() {
                prop_assert!((q.get(set) - qa.get(set) * qb.get(set)).abs() < 1e-12);
            }
        }
    }
}
