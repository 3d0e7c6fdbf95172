//! Belief, plausibility, commonality and implicability functions, and back, by fast transforms.
//!
//! Each function is a sum of masses over subsets or supersets, computed with the fast zeta
//! transform in `n·2^(n−1)` additions instead of `4^n`; the inverse is the fast Möbius transform.
//! The four kernels work in place on any dense array of `2^n` values, so grid code can use them on
//! its own storage.

use crate::{BeliefError, Frame, Mass, Real, Set};

/// A function of the subsets of a frame, `f(A)` for every `A`, stored densely by bitmask like a
/// [`Mass`]: what [`Mass::belief`] and its siblings return.
#[derive(Clone, Debug, PartialEq)]
pub struct SetFunction<R: Real> {
    frame: Frame,
    values: Vec<R>,
}

impl<R: Real> SetFunction<R> {
    /// A set function from its dense array, `values[A.bits()] = f(A)`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::WrongLength`] unless there are `2^n` values; [`BeliefError::NotFinite`] for
    /// a NaN or infinite value.
    pub fn from_values(frame: &Frame, values: Vec<R>) -> Result<Self, BeliefError> {
        if values.len() != frame.size() {
            return Err(BeliefError::WrongLength {
                expected: frame.size(),
                found: values.len(),
            });
        }
        if let Some((bits, &value)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(BeliefError::NotFinite {
                set: Set::from_bits(bits as u8),
                value: value.to_f64(),
            });
        }
        Ok(Self {
            frame: frame.clone(),
            values,
        })
    }

    /// The frame.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// `f(set)`; zero for a set outside the frame.
    pub fn get(&self, set: Set) -> R {
        self.values.get(set.index()).copied().unwrap_or(R::ZERO)
    }

    /// The dense array, `values()[A.bits()] = f(A)`.
    pub fn values(&self) -> &[R] {
        &self.values
    }
}

impl<R: Real> Mass<R> {
    /// The implicability `b(A) = Σ_{B⊆A} m(B)`, which counts `m(∅)`: `b(A) = bel(A) + m(∅)`.
    ///
    /// # References
    ///
    /// Smets, "The application of the matrix calculus to belief functions", IJAR 31, 2002.
    pub fn implicability(&self) -> SetFunction<R> {
        let mut values = self.values().to_vec();
        zeta_subsets_unchecked(&mut values);
        self.set_function(values)
    }

    /// The belief `bel(A) = Σ_{∅≠B⊆A} m(B)`.
    ///
    /// # Examples
    ///
    /// ```
    /// use belief::{Frame, Mass};
    ///
    /// let frame = Frame::new(["C1", "C2"])?;
    /// let m = Mass::<f64>::from_named(&frame, &[(&[], 0.2), (&["C1"], 0.3), (&["C2"], 0.4), (&["C1", "C2"], 0.1)])?;
    /// let bel = m.belief();
    /// assert_eq!(bel.values()[0], 0.0);
    /// assert!((bel.get(frame.omega()) - 0.8).abs() < 1e-12);
    /// let back = Mass::from_belief(&bel)?;
    /// assert!(back.values().iter().zip(m.values()).all(|(x, y)| (x - y).abs() < 1e-12));
    /// # Ok::<(), belief::BeliefError>(())
    /// ```
    pub fn belief(&self) -> SetFunction<R> {
        let empty = self.conflict();
        let mut values = self.values().to_vec();
        zeta_subsets_unchecked(&mut values);
        for v in &mut values {
            *v -= empty;
        }
        values[0] = R::ZERO;
        self.set_function(values)
    }

    /// The plausibility `pl(A) = Σ_{B∩A≠∅} m(B) = 1 − b(Ā)`.
    pub fn plausibility(&self) -> SetFunction<R> {
        let implicability = self.implicability();
        let omega = self.frame().omega();
        let values = self
            .frame()
            .subsets()
            .map(|set| {
                if set.is_empty() {
                    R::ZERO
                } else {
                    R::ONE - implicability.get(omega.difference(set))
                }
            })
            .collect();
        self.set_function(values)
    }

    /// The commonality `q(A) = Σ_{B⊇A} m(B)`.
    pub fn commonality(&self) -> SetFunction<R> {
        let mut values = self.values().to_vec();
        zeta_supersets_unchecked(&mut values);
        self.set_function(values)
    }

    /// The mass function whose implicability is `b`.
    ///
    /// # Errors
    ///
    /// As [`check_masses`](crate::check_masses) if `b` is not an implicability function (negative
    /// Möbius coefficients beyond rounding, `b(Ω) ≠ 1`).
    pub fn from_implicability(b: &SetFunction<R>) -> Result<Self, BeliefError> {
        let mut values = b.values().to_vec();
        mobius_subsets_unchecked(&mut values);
        Self::from_inverse(b.frame(), values)
    }

    /// The mass function whose belief function is `bel`; `m(∅) = 1 − bel(Ω)`.
    ///
    /// # Errors
    ///
    /// As [`Mass::from_implicability`].
    pub fn from_belief(bel: &SetFunction<R>) -> Result<Self, BeliefError> {
        let empty = R::ONE - bel.get(bel.frame().omega());
        let mut values: Vec<R> = bel.values().iter().map(|&v| v + empty).collect();
        values[0] = empty;
        mobius_subsets_unchecked(&mut values);
        Self::from_inverse(bel.frame(), values)
    }

    /// The mass function whose plausibility function is `pl`, through `b(A) = 1 − pl(Ā)`.
    ///
    /// # Errors
    ///
    /// As [`Mass::from_implicability`].
    pub fn from_plausibility(pl: &SetFunction<R>) -> Result<Self, BeliefError> {
        let omega = pl.frame().omega();
        let mut values: Vec<R> = pl
            .frame()
            .subsets()
            .map(|set| R::ONE - pl.get(omega.difference(set)))
            .collect();
        mobius_subsets_unchecked(&mut values);
        Self::from_inverse(pl.frame(), values)
    }

    /// The mass function whose commonality function is `q`.
    ///
    /// # Errors
    ///
    /// As [`Mass::from_implicability`].
    pub fn from_commonality(q: &SetFunction<R>) -> Result<Self, BeliefError> {
        let mut values = q.values().to_vec();
        mobius_supersets_unchecked(&mut values);
        Self::from_inverse(q.frame(), values)
    }

    fn set_function(&self, values: Vec<R>) -> SetFunction<R> {
        SetFunction {
            frame: self.frame().clone(),
            values,
        }
    }

    /// Masses out of a Möbius transform: exact zeros come back as `±1e-17`-size residues of the
    /// subtractions, which are rounding, not negative masses, and are set to zero.
    fn from_inverse(frame: &Frame, mut values: Vec<R>) -> Result<Self, BeliefError> {
        for v in &mut values {
            if *v < R::ZERO && *v >= R::ZERO - R::TOLERANCE {
                *v = R::ZERO;
            }
        }
        Mass::from_values(frame, values)
    }
}

/// Length check shared by the public in-place kernels.
fn check_length<R>(values: &[R]) -> Result<(), BeliefError> {
    let len = values.len();
    if len.is_power_of_two() && len <= 1 << Frame::MAX_LEN {
        Ok(())
    } else {
        Err(BeliefError::WrongLength {
            expected: len.next_power_of_two().min(1 << Frame::MAX_LEN),
            found: len,
        })
    }
}

/// Runs `update(values[lower], values[upper])` for every pair of sets that differ by one element,
/// `lower = A`, `upper = A ∪ {k}`, one element `k` at a time: the butterfly of all four transforms.
fn butterfly<R: Real>(values: &mut [R], update: impl Fn(&mut R, &mut R)) {
    let mut bit = 1;
    while bit < values.len() {
        // Blocks of 2·bit: the first half lacks element k, the second half has it.
        for block in values.chunks_exact_mut(2 * bit) {
            let (without, with) = block.split_at_mut(bit);
            for (lower, upper) in without.iter_mut().zip(with) {
                update(lower, upper);
            }
        }
        bit <<= 1;
    }
}

fn zeta_subsets_unchecked<R: Real>(values: &mut [R]) {
    butterfly(values, |lower, upper| *upper += *lower);
}

fn mobius_subsets_unchecked<R: Real>(values: &mut [R]) {
    butterfly(values, |lower, upper| *upper -= *lower);
}

fn zeta_supersets_unchecked<R: Real>(values: &mut [R]) {
    butterfly(values, |lower, upper| *lower += *upper);
}

fn mobius_supersets_unchecked<R: Real>(values: &mut [R]) {
    butterfly(values, |lower, upper| *lower -= *upper);
}

/// In place, `f(A) ← Σ_{B⊆A} f(B)`: the fast zeta transform over subsets (mass → implicability).
///
/// # Errors
///
/// [`BeliefError::WrongLength`] unless the length is `2^n`, `n ≤ 8`.
///
/// # Examples
///
/// ```
/// let mut f = [0.0, 0.2, 0.6, 0.2];
/// belief::zeta_subsets(&mut f)?;
/// assert_eq!(f, [0.0, 0.2, 0.6, 1.0]);
/// belief::mobius_subsets(&mut f)?;
/// assert_eq!(f, [0.0, 0.2, 0.6, 0.2]);
/// # Ok::<(), belief::BeliefError>(())
/// ```
pub fn zeta_subsets<R: Real>(values: &mut [R]) -> Result<(), BeliefError> {
    check_length(values)?;
    zeta_subsets_unchecked(values);
    Ok(())
}

/// In place, the inverse of [`zeta_subsets`] (Möbius transform over subsets).
///
/// # Errors
///
/// [`BeliefError::WrongLength`] unless the length is `2^n`, `n ≤ 8`.
pub fn mobius_subsets<R: Real>(values: &mut [R]) -> Result<(), BeliefError> {
    check_length(values)?;
    mobius_subsets_unchecked(values);
    Ok(())
}

/// In place, `f(A) ← Σ_{B⊇A} f(B)`: the fast zeta transform over supersets (mass → commonality).
///
/// # Errors
///
/// [`BeliefError::WrongLength`] unless the length is `2^n`, `n ≤ 8`.
pub fn zeta_supersets<R: Real>(values: &mut [R]) -> Result<(), BeliefError> {
    check_length(values)?;
    zeta_supersets_unchecked(values);
    Ok(())
}

/// In place, the inverse of [`zeta_supersets`] (Möbius transform over supersets).
///
/// # Errors
///
/// [`BeliefError::WrongLength`] unless the length is `2^n`, `n ≤ 8`.
pub fn mobius_supersets<R: Real>(values: &mut [R]) -> Result<(), BeliefError> {
    check_length(values)?;
    mobius_supersets_unchecked(values);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass, assert_close, frame_of};
    use proptest::prelude::*;

    /// The definitions as double loops over all pairs of subsets.
    fn naive(m: &Mass<f64>) -> [Vec<f64>; 4] {
        let subsets: Vec<Set> = m.frame().subsets().collect();
        let sum = |keep: &dyn Fn(Set, Set) -> bool| -> Vec<f64> {
            subsets
                .iter()
                .map(|&a| {
                    subsets
                        .iter()
                        .filter(|&&b| keep(a, b))
                        .map(|&b| m.get(b))
                        .sum()
                })
                .collect()
        };
        [
            sum(&|a, b| !b.is_empty() && b.is_subset_of(a)),
            sum(&|a, b| !a.intersection(b).is_empty()),
            sum(&|a, b| a.is_subset_of(b)),
            sum(&|a, b| b.is_subset_of(a)),
        ]
    }

    #[test]
    fn bft_test1_by_hand() -> Result<(), BeliefError> {
        let frame = Frame::new(["C1", "C2"])?;
        let m = Mass::from_values(&frame, vec![0.2, 0.3, 0.4, 0.1])?;
        // bel: ∅ 0, C1 0.3, C2 0.4, Ω 0.3+0.4+0.1 = 0.8
        assert_close(m.belief().values(), &[0.0, 0.3, 0.4, 0.8], 1e-15);
        // pl: C1 0.3+0.1 = 0.4, C2 0.4+0.1 = 0.5, Ω 0.8
        assert_close(m.plausibility().values(), &[0.0, 0.4, 0.5, 0.8], 1e-15);
        // q: ∅ 1, C1 0.3+0.1 = 0.4, C2 0.4+0.1 = 0.5, Ω 0.1
        assert_close(m.commonality().values(), &[1.0, 0.4, 0.5, 0.1], 1e-15);
        // b: ∅ 0.2, C1 0.5, C2 0.6, Ω 1
        assert_close(m.implicability().values(), &[0.2, 0.5, 0.6, 1.0], 1e-15);
        Ok(())
    }

    #[test]
    fn kernels_reject_lengths_that_are_not_powers_of_two() {
        let mut three = [0.0; 3];
        assert_eq!(
            zeta_subsets(&mut three),
            Err(BeliefError::WrongLength {
                expected: 4,
                found: 3
            })
        );
        let mut too_long = vec![0.0; 512];
        assert!(mobius_supersets(&mut too_long).is_err());
    }

    #[test]
    fn inverse_of_a_non_belief_function_is_an_error() -> Result<(), BeliefError> {
        let frame = frame_of(2);
        // q(∅) must be 1 and q decreasing; this one gives m({e0}) = 0.2 − 0.9 < 0.
        let q = SetFunction::from_values(&frame, vec![1.0, 0.2, 0.5, 0.9])?;
        assert!(matches!(
            Mass::from_commonality(&q),
            Err(BeliefError::NegativeMass { .. })
        ));
        Ok(())
    }

    proptest! {
        #[test]
        fn fast_transforms_agree_with_naive_double_loop(m in arb_mass(1..=6)) {
            let [bel, pl, q, b] = naive(&m);
            assert_close(m.belief().values(), &bel, 1e-12);
            assert_close(m.plausibility().values(), &pl, 1e-12);
            assert_close(m.commonality().values(), &q, 1e-12);
            assert_close(m.implicability().values(), &b, 1e-12);
        }

        #[test]
        fn every_transform_round_trips(m in arb_mass(1..=6)) {
            assert_close(Mass::from_belief(&m.belief())?.values(), m.values(), 1e-12);
            assert_close(Mass::from_plausibility(&m.plausibility())?.values(), m.values(), 1e-12);
            assert_close(Mass::from_commonality(&m.commonality())?.values(), m.values(), 1e-12);
            assert_close(Mass::from_implicability(&m.implicability())?.values(), m.values(), 1e-12);
        }
    }
}
