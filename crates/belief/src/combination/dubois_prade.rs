//! The Dubois–Prade rule: conflicting products go to the union.

use super::{Combination, common_frame};
use crate::{BeliefError, Mass, Real};

/// The Dubois–Prade rule: `m1(B)·m2(C)` goes to `B ∩ C` when that is not empty, and to `B ∪ C`
/// when it is; no mass is lost to ∅ and the conflict is turned into imprecision.
///
/// Commutative but not associative, so [`Combination::combine_all`] uses the n-ary form: a tuple
/// of focal sets `(B_1, …, B_k)` sends its product to `∩ B_i` if not empty, else to `∪ B_i`.
/// (Only an input with mass on ∅ can leave mass on ∅, when every set of the tuple is ∅.)
///
/// # Examples
///
/// ```
/// use belief::{Combination, DuboisPrade, Frame, Mass};
///
/// let frame = Frame::new(["C1", "C2"])?;
/// let m1 = Mass::<f64>::from_named(&frame, &[(&["C1"], 0.3), (&["C2"], 0.7)])?;
/// let m2 = Mass::<f64>::from_named(&frame, &[(&["C1"], 0.5), (&["C2"], 0.4), (&["C1", "C2"], 0.1)])?;
/// let m = DuboisPrade.combine(&m1, &m2)?;
/// // C1∩C2 = ∅, so 0.3·0.4 + 0.7·0.5 = 0.47 goes to C1∪C2.
/// assert!((m.get(frame.omega()) - 0.47).abs() < 1e-12);
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// D. Dubois, H. Prade, "Representation and combination of uncertainty with belief functions and
/// possibility measures", Computational Intelligence 4, 1988; SPEC §1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DuboisPrade;

impl<R: Real> Combination<R> for DuboisPrade {
    fn combine(&self, a: &Mass<R>, b: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        self.combine_all(&[a.clone(), b.clone()])
    }

    fn combine_all(&self, masses: &[Mass<R>]) -> Result<Mass<R>, BeliefError> {
        let frame = common_frame(masses)?.clone();
        let size = frame.size();
        // The running combination is a distribution over pairs (∩ so far, ∪ so far), stored densely
        // at `intersection * size + union`: at most 4^8 = 65,536 cells, whatever the number of
        // inputs, where enumerating tuples would grow as (2^n)^k.
        let mut pairs = vec![R::ZERO; size * size];
        let mut next = vec![R::ZERO; size * size];
        let (first, rest) = masses.split_first().ok_or(BeliefError::NoInputs)?;
        for (set, m) in first.focal_sets() {
            pairs[set.index() * size + set.index()] = m;
        }
        for source in rest {
            next.fill(R::ZERO);
            for (cell, &weight) in pairs.iter().enumerate().filter(|&(_, &w)| w != R::ZERO) {
                let (inter, union) = (cell / size, cell % size);
                for (set, m) in source.focal_sets() {
                    next[(inter & set.index()) * size + (union | set.index())] += weight * m;
                }
            }
            std::mem::swap(&mut pairs, &mut next);
        }
        let mut values = vec![R::ZERO; size];
        for (cell, &weight) in pairs.iter().enumerate().filter(|&(_, &w)| w != R::ZERO) {
            let (inter, union) = (cell / size, cell % size);
            values[if inter != 0 { inter } else { union }] += weight;
        }
        Ok(Mass::from_computed(&frame, values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass_pair, arb_mass_triple, assert_close, assert_valid};
    use crate::{Conjunctive, Frame};
    use proptest::prelude::*;

    #[test]
    fn three_sources_by_hand() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b", "c"])?;
        let a = Mass::from_named(&frame, &[(&["a"], 1.0)])?;
        let b = Mass::from_named(&frame, &[(&["b"], 0.5), (&["a", "b"], 0.5)])?;
        let c = Mass::from_named(&frame, &[(&["c"], 1.0)])?;
        // Tuples: (a, b, c) 0.5 → ∩ = ∅ → ∪ = {a,b,c}; (a, ab, c) 0.5 → ∩ = ∅ → ∪ = {a,b,c}.
        // The binary fold would first make (a DP b) = {a} .5 (from a∩ab) + {a,b} .5 (a∪b),
        // then with c: {a,c} .5, {a,b,c} .5.
        let all = DuboisPrade.combine_all(&[a.clone(), b.clone(), c.clone()])?;
        assert_eq!(all.get(frame.omega()), 1.0);
        let fold = DuboisPrade.combine(&DuboisPrade.combine(&a, &b)?, &c)?;
        assert_eq!(fold.get(frame.set(&["a", "c"])?), 0.5);
        assert_eq!(fold.get(frame.omega()), 0.5);
        Ok(())
    }

    proptest! {
        #[test]
        fn valid_and_agrees_with_conjunctive_off_conflict((a, b) in arb_mass_pair(1..=6)) {
            let dp = DuboisPrade.combine(&a, &b)?;
            assert_valid(&dp);
            // Where the inputs are normal, nothing is left on ∅ and every conjunctive mass on a
            // non-empty set is kept.
            let conj = Conjunctive.combine(&a, &b)?;
            if a.is_normal() && b.is_normal() {
                prop_assert_eq!(dp.conflict(), 0.0);
            }
            for set in a.frame().subsets().filter(|s| !s.is_empty()) {
                prop_assert!(dp.get(set) >= conj.get(set) - 1e-15);
            }
        }

        #[test]
        fn commutative_n_ary((a, b, c) in arb_mass_triple(1..=5)) {
            let abc = DuboisPrade.combine_all(&[a.clone(), b.clone(), c.clone()])?;
            let cab = DuboisPrade.combine_all(&[c, a, b])?;
            assert_valid(&abc);
            assert_close(abc.values(), cab.values(), 1e-12);
        }
    }
}
