//! Dempster's rule: conjunctive, then normalised.

use super::{Combination, conjunctive_all, conjunctive_values};
use crate::{BeliefError, Mass, Real};

/// Dempster's rule `⊕`: the conjunctive combination divided by `1 − K`, `K` its mass on ∅.
///
/// Commutative and associative. Total conflict (`K = 1`) is the error
/// [`BeliefError::TotalConflict`], never a NaN.
///
/// # Examples
///
/// ```
/// use belief::{Combination, Dempster, Frame, Mass};
///
/// let frame = Frame::new(["a", "b"])?;
/// let m1 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
/// let m2 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.7), (&["b"], 0.1), (&["a", "b"], 0.2)])?;
/// let m = Dempster.combine(&m1, &m2)?;
/// // SPEC §1: 0.32/0.56 = 0.571, 0.20/0.56 = 0.357, 0.04/0.56 = 0.071.
/// assert!((m.get(frame.set(&["a"])?) - 0.571_428_571_4).abs() < 1e-10);
/// assert!((m.get(frame.set(&["b"])?) - 0.357_142_857_1).abs() < 1e-10);
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// Paper eq 9-11; SPEC §1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dempster;

impl<R: Real> Combination<R> for Dempster {
    fn combine(&self, a: &Mass<R>, b: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        a.check_same_frame(b)?;
        Mass::from_computed(a.frame(), conjunctive_values(a.values(), b.values())).normalised()
    }

    /// Conjunctive combination of all inputs, normalised once: equal to folding the binary rule
    /// (the rule is associative), with one division instead of `n − 1`.
    fn combine_all(&self, masses: &[Mass<R>]) -> Result<Mass<R>, BeliefError> {
        let (frame, values) = conjunctive_all(masses)?;
        Mass::from_computed(&frame, values).normalised()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass_pair, arb_mass_triple, assert_close, assert_valid};
    use crate::{Conjunctive, Frame};
    use proptest::prelude::*;

    #[test]
    fn table_one_corrected() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let m1 = Mass::from_values(&frame, vec![0.0, 0.2, 0.6, 0.2])?;
        let m2 = Mass::from_values(&frame, vec![0.0, 0.7, 0.1, 0.2])?;
        // K = 0.44, 1 − K = 0.56; a: 0.32/0.56 = 0.571428…, b: 0.20/0.56 = 0.357142…,
        // Ω: 0.04/0.56 = 0.071428… (the paper prints 0.61 and 0.32).
        let m = Dempster.combine(&m1, &m2)?;
        assert_close(
            m.values(),
            &[
                0.0,
                0.571_428_571_428_6,
                0.357_142_857_142_9,
                0.071_428_571_428_6,
            ],
            1e-12,
        );
        Ok(())
    }

    #[test]
    fn total_conflict_is_an_error_not_nan() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let a = Mass::<f64>::categorical(&frame, frame.set(&["a"])?)?;
        let b = Mass::<f64>::categorical(&frame, frame.set(&["b"])?)?;
        assert_eq!(Dempster.combine(&a, &b), Err(BeliefError::TotalConflict));
        assert_eq!(
            Dempster.combine_all(&[a.clone(), Mass::vacuous(&frame), b]),
            Err(BeliefError::TotalConflict)
        );
        assert_eq!(
            Combination::<f64>::combine_all(&Dempster, &[]),
            Err(BeliefError::NoInputs)
        );
        Ok(())
    }

    proptest! {
        #[test]
        fn equals_normalised_conjunctive((a, b) in arb_mass_pair(1..=6)) {
            match (Dempster.combine(&a, &b), Conjunctive.combine(&a, &b)?.normalised()) {
                (Ok(d), Ok(c)) => {
                    assert_valid(&d);
                    prop_assert!(d.is_normal());
                    assert_close(d.values(), c.values(), 1e-12);
                }
                (Err(BeliefError::TotalConflict), Err(BeliefError::TotalConflict)) => {}
                (d, c) => prop_assert!(false, "Dempster {d:?} vs normalised conjunctive {c:?}"),
            }
        }

        #[test]
        fn n_ary_equals_left_fold((a, b, c) in arb_mass_triple(1..=5)) {
            let fold = Dempster.combine(&a, &b).and_then(|ab| Dempster.combine(&ab, &c));
            let all = Dempster.combine_all(&[a, b, c]);
            match (fold, all) {
                (Ok(fold), Ok(all)) => assert_close(fold.values(), all.values(), 1e-9),
                (Err(e1), Err(e2)) => prop_assert_eq!(e1, e2),
                (fold, all) => prop_assert!(false, "fold {fold:?} vs n-ary {all:?}"),
            }
        }
    }
}
