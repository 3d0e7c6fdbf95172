//! The pignistic probability.

use crate::{BeliefError, Mass, Real, real::reciprocal};

impl<R: Real> Mass<R> {
    /// The pignistic probability of each element,
    /// `betP(ω) = Σ_{A∋ω} m(A) / (|A| · (1 − m(∅)))`, indexed like the frame's elements.
    ///
    /// A subnormal mass function is normalised by `1 − m(∅)` first (SPEC §1), so the result always
    /// sums to one.
    ///
    /// # Errors
    ///
    /// [`BeliefError::TotalConflict`] if `m(∅) = 1`: there is nothing to share out.
    ///
    /// # Examples
    ///
    /// ```
    /// use belief::{Frame, Mass};
    ///
    /// let frame = Frame::new(["a", "b"])?;
    /// let m = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
    /// // Paper Table I: betP(a) = 0.2 + 0.2/2 = 0.3, betP(b) = 0.6 + 0.2/2 = 0.7.
    /// let betp = m.pignistic()?;
    /// assert!((betp[0] - 0.3).abs() < 1e-12 && (betp[1] - 0.7).abs() < 1e-12);
    /// # Ok::<(), belief::BeliefError>(())
    /// ```
    ///
    /// # References
    ///
    /// Paper eq 15; Smets & Kennes, "The transferable belief model", AI 66, 1994.
    pub fn pignistic(&self) -> Result<Vec<R>, BeliefError> {
        let mut betp = vec![R::ZERO; self.frame().len()];
        let mut normaliser = R::ZERO;
        for (set, mass) in self.focal_sets().filter(|(set, _)| !set.is_empty()) {
            normaliser += mass;
            let share = mass * reciprocal::<R>(set.len());
            for (k, p) in betp.iter_mut().enumerate() {
                if set.contains(k) {
                    *p += share;
                }
            }
        }
        // As in Dempster's normalisation, 1 − m(∅) is summed, not subtracted, to keep its digits.
        if normaliser <= R::ZERO {
            return Err(BeliefError::TotalConflict);
        }
        for p in &mut betp {
            *p = *p / normaliser;
        }
        Ok(betp)
    }
}

#[cfg(test)]
mod tests {
    use crate::testing::{arb_mass, assert_close};
    use crate::{BeliefError, Frame, Mass, Set};
    use proptest::prelude::*;

    #[test]
    fn pyds_four_elements() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b", "c", "d"])?;
        let m = Mass::from_named(
            &frame,
            &[
                (&["a"], 0.4),
                (&["b"], 0.2),
                (&["a", "d"], 0.1),
                (&["a", "b", "c", "d"], 0.3),
            ],
        )?;
        // a: 0.4 + 0.1/2 + 0.3/4 = 0.525; b: 0.2 + 0.075 = 0.275; c: 0.075; d: 0.05 + 0.075 = 0.125
        assert_close(&m.pignistic()?, &[0.525, 0.275, 0.075, 0.125], 1e-15);
        Ok(())
    }

    #[test]
    fn subnormal_input_is_normalised() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        // Table I conjunctive result: betP(a) = (0.32 + 0.02)/0.56 = 0.607143,
        // betP(b) = (0.20 + 0.02)/0.56 = 0.392857.
        let m = Mass::from_values(&frame, vec![0.44, 0.32, 0.2, 0.04])?;
        assert_close(&m.pignistic()?, &[0.34 / 0.56, 0.22 / 0.56], 1e-15);
        let empty = Mass::<f32>::categorical(&frame, Set::EMPTY)?;
        assert_eq!(empty.pignistic(), Err(BeliefError::TotalConflict));
        Ok(())
    }

    proptest! {
        #[test]
        fn sums_to_one_and_is_non_negative(m in arb_mass(1..=6)) {
            match m.pignistic() {
                Ok(betp) => {
                    prop_assert!((betp.iter().sum::<f64>() - 1.0).abs() < 1e-12);
                    prop_assert!(betp.iter().all(|&p| p >= 0.0));
                }
                Err(e) => {
                    prop_assert_eq!(e, BeliefError::TotalConflict);
                    prop_assert_eq!(m.conflict(), 1.0);
                }
            }
        }
    }
}
