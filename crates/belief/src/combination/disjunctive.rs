//! The disjunctive rule.

use super::{Combination, disjunctive_values};
use crate::{BeliefError, Mass, Real};

/// The disjunctive rule `∪`: `(m1 ∪ m2)(A) = Σ_{B∪C=A} m1(B)·m2(C)`.
///
/// For independent sources of which at least one is reliable, without knowing which. Commutative
/// and associative; the mass function `m(∅) = 1` is its neutral element.
///
/// # Examples
///
/// ```
/// use belief::{Combination, Disjunctive, Frame, Mass};
///
/// let frame = Frame::new(["a", "b"])?;
/// let m1 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
/// let m2 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.7), (&["b"], 0.1), (&["a", "b"], 0.2)])?;
/// let m = Disjunctive.combine(&m1, &m2)?;
/// // Paper Table I: a 0.14, b 0.06, Ω 0.8.
/// let expected = [0.0, 0.14, 0.06, 0.8];
/// assert!(m.values().iter().zip(expected).all(|(x, y)| (x - y).abs() < 1e-12));
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// Paper eq 12; SPEC §1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Disjunctive;

impl<R: Real> Combination<R> for Disjunctive {
    fn combine(&self, a: &Mass<R>, b: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        a.check_same_frame(b)?;
        Ok(Mass::from_computed(
            a.frame(),
            disjunctive_values(a.values(), b.values()),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass, arb_mass_pair, arb_mass_triple, assert_close, assert_valid};
    use crate::{Frame, Set};
    use proptest::prelude::*;

    #[test]
    fn table_one() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let m1 = Mass::from_values(&frame, vec![0.0, 0.2, 0.6, 0.2])?;
        let m2 = Mass::from_values(&frame, vec![0.0, 0.7, 0.1, 0.2])?;
        // a: a∪a = 0.2·0.7 = 0.14; b: b∪b = 0.6·0.1 = 0.06; Ω: everything else = 0.8.
        assert_close(
            Disjunctive.combine(&m1, &m2)?.values(),
            &[0.0, 0.14, 0.06, 0.8],
            1e-15,
        );
        Ok(())
    }

    proptest! {
        #[test]
        fn output_is_valid((a, b) in arb_mass_pair(1..=6)) {
            assert_valid(&Disjunctive.combine(&a, &b)?);
        }

        #[test]
        fn commutative((a, b) in arb_mass_pair(1..=6)) {
            assert_close(
                Disjunctive.combine(&a, &b)?.values(),
                Disjunctive.combine(&b, &a)?.values(),
                1e-12,
            );
        }

        #[test]
        fn associative((a, b, c) in arb_mass_triple(1..=6)) {
            let left = Disjunctive.combine(&Disjunctive.combine(&a, &b)?, &c)?;
            let right = Disjunctive.combine(&a, &Disjunctive.combine(&b, &c)?)?;
            assert_close(left.values(), right.values(), 1e-12);
        }

        #[test]
        fn empty_set_mass_is_neutral(a in arb_mass(1..=6)) {
            let neutral = Mass::categorical(a.frame(), Set::EMPTY)?;
            assert_close(Disjunctive.combine(&a, &neutral)?.values(), a.values(), 0.0);
        }

        #[test]
        fn equals_product_of_implicabilities((a, b) in arb_mass_pair(1..=6)) {
            let ba = a.implicability();
            let bb = b.implicability();
            let bab = Disjunctive.combine(&a, &b)?.implicability();
            for set in a.frame().subsets() {
                prop_assert!((bab.get(set) - ba.get(set) * bb.get(set)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn frames_checked() -> Result<(), BeliefError> {
        let r = Disjunctive.combine(
            &Mass::<f64>::vacuous(&Frame::new(["a"])?),
            &Mass::vacuous(&Frame::new(["a", "b"])?),
        );
        assert!(matches!(r, Err(BeliefError::MismatchedFrames { .. })));
        Ok(())
    }
}
