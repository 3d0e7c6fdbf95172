//! Contextual discounting (Mercier, Quost & Denœux 2008).

use super::{Discounting, check_rate};
use crate::{BeliefError, Frame, Mass, Real, Set};

/// Contextual discounting: `m ∪ m_1 ∪ … ∪ m_L`, where context `l` is a set `A_l` with rate `α_l`
/// and `m_l(∅) = 1 − α_l`, `m_l(A_l) = α_l`.
///
/// Each context moves `α_l` of the mass of every set `B` to `B ∪ A_l`, not to Ω. The single
/// context Ω is classical discounting; the singleton contexts `{ω}` at rates `α_ω` are the
/// `mercier` mode of SPEC §5 step 3 (which, with equal rates, is *not* classical discounting on
/// more than two elements).
///
/// # Examples
///
/// ```
/// use belief::{ContextualDiscount, Discounting, Frame, Mass};
///
/// let frame = Frame::new(["a", "h", "r"])?;
/// let m = Mass::<f64>::from_named(&frame, &[(&["a"], 0.5), (&["r"], 0.5)])?;
/// let d = ContextualDiscount::new([(frame.set(&["h"])?, 0.6)])?.discount(&m)?;
/// // Mercier et al. 2008: a 0.2, {a,h} 0.3, r 0.2, {h,r} 0.3.
/// assert!((d.get(frame.set(&["a", "h"])?) - 0.3).abs() < 1e-12);
/// assert!((d.get(frame.set(&["r"])?) - 0.2).abs() < 1e-12);
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// D. Mercier, B. Quost, T. Denœux, "Refined modeling of sensor reliability in the belief
/// function framework using contextual discounting", Information Fusion 9, 2008; SPEC §1 and §5
/// step 3 `mercier`.
#[derive(Clone, Debug, PartialEq)]
pub struct ContextualDiscount<R: Real> {
    contexts: Vec<(Set, R)>,
}

impl<R: Real> ContextualDiscount<R> {
    /// Discounting with the given contexts `(A_l, α_l)`, any sets, in any number.
    ///
    /// # Errors
    ///
    /// [`BeliefError::RateOutOfRange`] unless every `0 ≤ α_l ≤ 1`.
    pub fn new<I: IntoIterator<Item = (Set, R)>>(contexts: I) -> Result<Self, BeliefError> {
        let contexts: Vec<(Set, R)> = contexts.into_iter().collect();
        for &(_, rate) in &contexts {
            check_rate(rate)?;
        }
        Ok(Self { contexts })
    }

    /// The singleton contexts `{ω_k}` at rates `rates[k]`: the `mercier` mode of SPEC §5.
    ///
    /// # Errors
    ///
    /// [`BeliefError::FrameTooLarge`] for more than eight rates, otherwise as
    /// [`ContextualDiscount::new`].
    pub fn singletons(rates: &[R]) -> Result<Self, BeliefError> {
        if rates.len() > Frame::MAX_LEN {
            return Err(BeliefError::FrameTooLarge { len: rates.len() });
        }
        Self::new(
            rates
                .iter()
                .enumerate()
                .map(|(k, &rate)| (Set::from_bits(1 << k), rate)),
        )
    }

    /// The contexts `(A_l, α_l)`.
    pub fn contexts(&self) -> &[(Set, R)] {
        &self.contexts
    }
}

impl<R: Real> Discounting<R> for ContextualDiscount<R> {
    fn discount(&self, m: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        for &(set, _) in &self.contexts {
            m.frame().check_set(set)?;
        }
        let mut values = m.values().to_vec();
        let mut next = vec![R::ZERO; values.len()];
        // The disjunctive combination with a two-focal-set mass function, done directly:
        // 2^n products per context instead of a general 4^n combination.
        for &(context, rate) in &self.contexts {
            next.fill(R::ZERO);
            for (set, &mass) in values.iter().enumerate() {
                next[set] += (R::ONE - rate) * mass;
                next[set | context.index()] += rate * mass;
            }
            std::mem::swap(&mut values, &mut next);
        }
        Ok(Mass::from_computed(m.frame(), values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass, assert_close, assert_valid};
    use crate::{ClassicalDiscount, Combination, Disjunctive};
    use proptest::prelude::*;

    #[test]
    fn mercier_two_contexts_by_hand() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "h", "r"])?;
        let m = Mass::from_named(&frame, &[(&["a"], 0.5), (&["r"], 0.5)])?;
        let d = ContextualDiscount::new([(frame.set(&["a"])?, 0.4), (frame.set(&["h"])?, 0.6)])?
            .discount(&m)?;
        // Context {a} at 0.4: {a} stays {a} (0.5); {r} → {r} 0.3, {a,r} 0.2.
        // Context {h} at 0.6: each set B keeps 0.4 and sends 0.6 to B ∪ {h}:
        // {a} 0.2, {a,h} 0.3, {r} 0.12, {h,r} 0.18, {a,r} 0.08, {a,h,r} 0.12.
        let expected = [0.0, 0.2, 0.0, 0.3, 0.12, 0.08, 0.18, 0.12];
        assert_close(d.values(), &expected, 1e-15);
        Ok(())
    }

    #[test]
    fn context_outside_frame_is_an_error() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let d = ContextualDiscount::new([(Set::from_bits(0b100), 0.5)])?;
        assert!(matches!(
            d.discount(&Mass::<f64>::vacuous(&frame)),
            Err(BeliefError::SetOutsideFrame { .. })
        ));
        assert!(ContextualDiscount::new([(Set::EMPTY, 2.0)]).is_err());
        Ok(())
    }

    #[test]
    fn equal_singleton_rates_are_not_classical_on_three_elements() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "h", "r"])?;
        let m = Mass::from_named(&frame, &[(&["a"], 1.0)])?;
        // Singletons at 0.5: {a} stays {a}, then h and r each double the sets:
        // {a} 0.25, {a,h} 0.25, {a,r} 0.25, Ω 0.25, where classical gives {a} 0.5, Ω 0.5.
        let mercier = ContextualDiscount::singletons(&[0.5, 0.5, 0.5])?.discount(&m)?;
        assert_close(
            mercier.values(),
            &[0.0, 0.25, 0.0, 0.25, 0.0, 0.25, 0.0, 0.25],
            1e-15,
        );
        Ok(())
    }

    proptest! {
        #[test]
        fn single_context_omega_is_classical(m in arb_mass(1..=6), alpha in 0.0..=1.0_f64) {
            let contextual = ContextualDiscount::new([(m.frame().omega(), alpha)])?.discount(&m)?;
            let classical = ClassicalDiscount::new(alpha)?.discount(&m)?;
            assert_valid(&contextual);
            assert_close(contextual.values(), classical.values(), 1e-12);
        }

        #[test]
        fn equals_disjunctive_with_context_masses(
            m in arb_mass(3..=3),
            contexts in prop::collection::vec((0_u8..8, 0.0..=1.0_f64), 0..4),
        ) {
            let contexts: Vec<(Set, f64)> =
                contexts.into_iter().map(|(bits, a)| (Set::from_bits(bits), a)).collect();
            let fast = ContextualDiscount::new(contexts.clone())?.discount(&m)?;
            let mut slow = m.clone();
            for (set, alpha) in contexts {
                let ml = Mass::from_focal(m.frame(), [(Set::EMPTY, 1.0 - alpha), (set, alpha)])
                    .or_else(|_| Mass::categorical(m.frame(), set))?;
                slow = Disjunctive.combine(&slow, &ml)?;
            }
            assert_close(fast.values(), slow.values(), 1e-12);
        }
    }
}
