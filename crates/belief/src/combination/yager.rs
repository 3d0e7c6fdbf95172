//! Yager's rule: conjunctive, then the conflict to Ω.

use super::{Combination, conjunctive_all};
use crate::{BeliefError, Mass, Real};

/// Yager's rule: the conjunctive combination with its conflict `m(∅)` moved to Ω (ignorance).
///
/// Commutative but not associative, so [`Combination::combine_all`] uses the n-ary form: the
/// conjunctive combination of all sources, then the conflict to Ω once (SPEC §1).
///
/// # Examples
///
/// ```
/// use belief::{Combination, Frame, Mass, Yager};
///
/// let frame = Frame::new(["a", "b"])?;
/// let m1 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
/// let m2 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.7), (&["b"], 0.1), (&["a", "b"], 0.2)])?;
/// let m = Yager.combine(&m1, &m2)?;
/// // Conjunctive (0.44, 0.32, 0.20, 0.04) with K = 0.44 added to Ω: 0.04 + 0.44 = 0.48.
/// assert!((m.get(frame.omega()) - 0.48).abs() < 1e-12);
/// assert_eq!(m.conflict(), 0.0);
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// R. R. Yager, "On the Dempster–Shafer framework and new combination rules", Information Sciences
/// 41, 1987; SPEC §1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Yager;

impl<R: Real> Combination<R> for Yager {
    fn combine(&self, a: &Mass<R>, b: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        self.combine_all(&[a.clone(), b.clone()])
    }

    fn combine_all(&self, masses: &[Mass<R>]) -> Result<Mass<R>, BeliefError> {
        let (frame, mut values) = conjunctive_all(masses)?;
        let conflict = std::mem::replace(&mut values[0], R::ZERO);
        values[frame.omega().index()] += conflict;
        Ok(Mass::from_computed(&frame, values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass_pair, arb_mass_triple, assert_close, assert_valid};
    use crate::{Combination, Conjunctive, Frame};
    use proptest::prelude::*;

    #[test]
    fn bft_rules_test1() -> Result<(), BeliefError> {
        let frame = Frame::new(["C1", "C2"])?;
        let m1 = Mass::from_values(&frame, vec![0.0, 0.3, 0.7, 0.0])?;
        let m2 = Mass::from_values(&frame, vec![0.0, 0.5, 0.4, 0.1])?;
        // Conjunctive: C1 = 0.3·0.5 + 0.3·0.1 = 0.18; C2 = 0.7·0.4 + 0.7·0.1 = 0.35;
        // ∅ = 0.3·0.4 + 0.7·0.5 = 0.47, which Yager moves to Ω.
        assert_close(
            Yager.combine(&m1, &m2)?.values(),
            &[0.0, 0.18, 0.35, 0.47],
            1e-15,
        );
        Ok(())
    }

    #[test]
    fn n_ary_form_is_not_a_fold() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let a = Mass::from_values(&frame, vec![0.0, 0.5, 0.0, 0.5])?;
        let b = Mass::from_values(&frame, vec![0.0, 0.0, 0.5, 0.5])?;
        // n-ary: a ∩ b ∩ a = ∅ 0.25, {a} 0.5·0.5 + ... computed by hand:
        // a∩b: ∅ .25, {a} .25, {b} .25, Ω .25; ∩a: ∅ .25+.125 = .375, {a} .25+.125 = .375,
        // {b} .125, Ω .125. Yager: Ω gets .125 + .375 = .5.
        let all = Yager.combine_all(&[a.clone(), b.clone(), a.clone()])?;
        assert_close(all.values(), &[0.0, 0.375, 0.125, 0.5], 1e-15);
        // Folding Yager twice: (a Y b) = {a} .25, {b} .25, Ω .5; Y a: ∅ .125 → Ω;
        // {a} .125+.125+.25 = .5, {b} .125, Ω .25 + .125 = .375.
        let fold = Yager.combine(&Yager.combine(&a, &b)?, &a)?;
        assert_close(fold.values(), &[0.0, 0.5, 0.125, 0.375], 1e-15);
        Ok(())
    }

    proptest! {
        #[test]
        fn valid_and_conflict_goes_to_omega((a, b, c) in arb_mass_triple(1..=6)) {
            let y = Yager.combine_all(&[a.clone(), b.clone(), c.clone()])?;
            let conj = Conjunctive.combine_all(&[a, b, c])?;
            assert_valid(&y);
            prop_assert!(y.is_normal());
            let omega = y.frame().omega();
            for set in y.frame().subsets().filter(|s| !s.is_empty() && *s != omega) {
                prop_assert_eq!(y.get(set), conj.get(set));
            }
        }

        #[test]
        fn commutative((a, b) in arb_mass_pair(1..=6)) {
            assert_close(Yager.combine(&a, &b)?.values(), Yager.combine(&b, &a)?.values(), 1e-12);
        }
    }
}
