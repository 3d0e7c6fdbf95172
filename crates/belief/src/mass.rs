//! Mass functions: dense arrays of `2^n` masses, with their validity checks.

use crate::{BeliefError, Frame, Real, Set};

/// A mass function (basic belief assignment) on a [`Frame`]: `m(A)` for every subset `A`, stored
/// densely and indexed by bitmask, `m(∅)` first (SPEC §1, eq 1-2).
///
/// Every `Mass` is valid: its values are finite, non-negative and sum to one within
/// [`Real::TOLERANCE`]. The constructors check this; the operations of the crate keep it. The
/// mass on ∅ may be positive (a *subnormal* mass function, the open world of the TBM).
///
/// # Examples
///
/// ```
/// use belief::{Frame, Mass};
///
/// let frame = Frame::new(["a", "b"])?;
/// let m = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
/// assert_eq!(m.get(frame.set(&["b"])?), 0.6);
/// assert!(m.is_normal());
/// assert_eq!(m.focal_sets().count(), 3);
/// # Ok::<(), belief::BeliefError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Mass<R: Real> {
    frame: Frame,
    values: Vec<R>,
}

impl<R: Real> Mass<R> {
    /// The vacuous mass function, `m(Ω) = 1`: total ignorance.
    pub fn vacuous(frame: &Frame) -> Self {
        Self::categorical_unchecked(frame, frame.omega())
    }

    /// The categorical mass function `m(set) = 1`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::SetOutsideFrame`] if `set` is not a subset of the frame.
    pub fn categorical(frame: &Frame, set: Set) -> Result<Self, BeliefError> {
        frame.check_set(set)?;
        Ok(Self::categorical_unchecked(frame, set))
    }

    fn categorical_unchecked(frame: &Frame, set: Set) -> Self {
        let mut values = vec![R::ZERO; frame.size()];
        values[set.index()] = R::ONE;
        Self {
            frame: frame.clone(),
            values,
        }
    }

    /// A mass function from its dense array, `values[A.bits()] = m(A)`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::WrongLength`] unless there are `2^n` values; otherwise as
    /// [`check_masses`].
    pub fn from_values(frame: &Frame, values: Vec<R>) -> Result<Self, BeliefError> {
        if values.len() != frame.size() {
            return Err(BeliefError::WrongLength {
                expected: frame.size(),
                found: values.len(),
            });
        }
        check_masses(&values)?;
        Ok(Self {
            frame: frame.clone(),
            values,
        })
    }

    /// A mass function from its focal sets; sets not listed have mass zero.
    ///
    /// # Errors
    ///
    /// [`BeliefError::SetOutsideFrame`], [`BeliefError::RepeatedSet`], or as [`check_masses`].
    pub fn from_focal<I>(frame: &Frame, focal: I) -> Result<Self, BeliefError>
    where
        I: IntoIterator<Item = (Set, R)>,
    {
        let mut values = vec![R::ZERO; frame.size()];
        let mut listed = vec![false; frame.size()];
        for (set, mass) in focal {
            frame.check_set(set)?;
            if std::mem::replace(&mut listed[set.index()], true) {
                return Err(BeliefError::RepeatedSet { set });
            }
            values[set.index()] = mass;
        }
        check_masses(&values)?;
        Ok(Self {
            frame: frame.clone(),
            values,
        })
    }

    /// A mass function from focal sets given by element names (`&[]` is ∅).
    ///
    /// # Errors
    ///
    /// [`BeliefError::UnknownElement`], or as [`Mass::from_focal`].
    pub fn from_named(frame: &Frame, focal: &[(&[&str], R)]) -> Result<Self, BeliefError> {
        let focal = focal
            .iter()
            .map(|&(names, mass)| Ok((frame.set(names)?, mass)))
            .collect::<Result<Vec<_>, BeliefError>>()?;
        Self::from_focal(frame, focal)
    }

    /// Wraps values computed by an operation of this crate from valid inputs. Such values are
    /// valid up to rounding, which the property tests bound.
    pub(crate) fn from_computed(frame: &Frame, values: Vec<R>) -> Self {
        debug_assert_eq!(values.len(), frame.size());
        Self {
            frame: frame.clone(),
            values,
        }
    }

    /// The frame.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// `m(set)`; zero for a set outside the frame.
    pub fn get(&self, set: Set) -> R {
        self.values.get(set.index()).copied().unwrap_or(R::ZERO)
    }

    /// The dense array, `values()[A.bits()] = m(A)`.
    pub fn values(&self) -> &[R] {
        &self.values
    }

    /// The dense array, by value.
    pub fn into_values(self) -> Vec<R> {
        self.values
    }

    /// The focal sets (those with non-zero mass) and their masses, in increasing bitmask order.
    pub fn focal_sets(&self) -> impl Iterator<Item = (Set, R)> + '_ {
        self.values
            .iter()
            .enumerate()
            .filter(|&(_, &m)| m != R::ZERO)
            .map(|(bits, &m)| (Set::from_bits(bits as u8), m))
    }

    /// The mass on the empty set, `m(∅)`: the conflict of a conjunctive combination.
    pub fn conflict(&self) -> R {
        self.values[0]
    }

    /// `true` if `m(∅) = 0` (eq 3).
    pub fn is_normal(&self) -> bool {
        self.values[0] == R::ZERO
    }

    /// `true` if `m(∅) > 0`.
    pub fn is_subnormal(&self) -> bool {
        self.values[0] > R::ZERO
    }

    /// `true` if `m(Ω) = 1`.
    pub fn is_vacuous(&self) -> bool {
        self.get(self.frame.omega()) == R::ONE
    }

    /// Dempster's normalisation: `m(A) / (1 − m(∅))` for `A ≠ ∅` and `m(∅) = 0` (eq 9-11).
    ///
    /// # Errors
    ///
    /// [`BeliefError::TotalConflict`] when no mass is on a non-empty set.
    pub fn normalised(&self) -> Result<Self, BeliefError> {
        // The non-conflicting mass is summed rather than taken as 1 − m(∅): for K close to one
        // the subtraction would cancel most significant digits.
        let normaliser: R = self.values[1..].iter().copied().sum();
        if normaliser <= R::ZERO {
            return Err(BeliefError::TotalConflict);
        }
        let mut values = self.values.clone();
        values[0] = R::ZERO;
        for v in &mut values[1..] {
            *v = *v / normaliser;
        }
        Ok(Self::from_computed(&self.frame, values))
    }

    /// The same mass function in another float type. The values are converted one by one and not
    /// checked again: the conversion moves their sum by at most the rounding of the narrower type.
    pub fn cast<S: Real>(&self) -> Mass<S> {
        Mass {
            frame: self.frame.clone(),
            values: self
                .values
                .iter()
                .map(|&v| S::from_f64(v.to_f64()))
                .collect(),
        }
    }

    /// Checks that `other` is on the same frame.
    pub(crate) fn check_same_frame(&self, other: &Mass<R>) -> Result<(), BeliefError> {
        self.frame.check_same(&other.frame)
    }
}

/// Checks a dense array of masses: `2^n` values with `n ≤ 8`, each finite and non-negative, summing
/// to one within [`Real::TOLERANCE`] (SPEC §1, eq 1-2).
///
/// This is the validity check for arrays that do not live in a [`Mass`], such as a grid cell.
///
/// # Errors
///
/// [`BeliefError::WrongLength`] (not a power of two up to 256), [`BeliefError::NotFinite`],
/// [`BeliefError::NegativeMass`] (for the first offending set) or [`BeliefError::InvalidSum`].
///
/// # Examples
///
/// ```
/// use belief::{check_masses, BeliefError};
///
/// assert_eq!(check_masses(&[0.0, 0.3, 0.7, 0.0]), Ok(()));
/// assert_eq!(check_masses(&[0.0, 0.3, 0.6, 0.0]), Err(BeliefError::InvalidSum { sum: 0.8999999999999999 }));
/// ```
pub fn check_masses<R: Real>(values: &[R]) -> Result<(), BeliefError> {
    if !values.len().is_power_of_two() || values.len() > 1 << Frame::MAX_LEN {
        return Err(BeliefError::WrongLength {
            expected: values.len().next_power_of_two().min(1 << Frame::MAX_LEN),
            found: values.len(),
        });
    }
    for (bits, &value) in values.iter().enumerate() {
        let set = Set::from_bits(bits as u8);
        if !value.is_finite() {
            return Err(BeliefError::NotFinite {
                set,
                value: value.to_f64(),
            });
        }
        if value < R::ZERO {
            return Err(BeliefError::NegativeMass {
                set,
                value: value.to_f64(),
            });
        }
    }
    let sum: R = values.iter().copied().sum();
    if (sum - R::ONE).abs() > R::TOLERANCE {
        return Err(BeliefError::InvalidSum { sum: sum.to_f64() });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constructors_reject_invalid_masses() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let a = frame.set(&["a"])?;
        assert_eq!(
            Mass::from_focal(&frame, [(a, -0.2), (frame.omega(), 1.2)]),
            Err(BeliefError::NegativeMass {
                set: a,
                value: -0.2
            })
        );
        assert_eq!(
            Mass::from_focal(&frame, [(a, 0.5), (a, 0.5)]),
            Err(BeliefError::RepeatedSet { set: a })
        );
        assert_eq!(
            Mass::from_focal(&frame, [(Set::from_bits(4), 1.0)]),
            Err(BeliefError::SetOutsideFrame {
                set: Set::from_bits(4),
                frame_len: 2
            })
        );
        assert_eq!(
            Mass::from_values(&frame, vec![0.0, 1.0]),
            Err(BeliefError::WrongLength {
                expected: 4,
                found: 2
            })
        );
        assert!(matches!(
            Mass::from_values(&frame, vec![0.0, f64::NAN, 0.0, 1.0]),
            Err(BeliefError::NotFinite { .. })
        ));
        // Off by 2e-9 > 1e-9: rejected; off by 5e-10: accepted (SPEC §1 tolerance).
        assert!(matches!(
            Mass::from_values(&frame, vec![0.0, 0.5, 0.5, 2e-9]),
            Err(BeliefError::InvalidSum { .. })
        ));
        assert!(Mass::from_values(&frame, vec![0.0, 0.5, 0.5, 5e-10]).is_ok());
        Ok(())
    }

    #[test]
    fn normal_and_subnormal_predicates() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let subnormal = Mass::from_values(&frame, vec![0.44, 0.32, 0.2, 0.04])?;
        assert!(subnormal.is_subnormal() && !subnormal.is_normal());
        assert_eq!(subnormal.conflict(), 0.44);
        let vacuous = Mass::<f32>::vacuous(&frame);
        assert!(vacuous.is_normal() && vacuous.is_vacuous());
        Ok(())
    }

    #[test]
    fn normalising_table_one_conjunctive_gives_dempster() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        // SPEC §1: m1 ∩ m2 = (0.44, 0.32, 0.20, 0.04); 1 − K = 0.56;
        // 0.32/0.56 = 0.571429, 0.20/0.56 = 0.357143, 0.04/0.56 = 0.071429.
        let m = Mass::from_values(&frame, vec![0.44, 0.32, 0.2, 0.04])?.normalised()?;
        let expected = [0.0, 0.32 / 0.56, 0.2 / 0.56, 0.04 / 0.56];
        for (got, want) in m.values().iter().zip(expected) {
            approx::assert_abs_diff_eq!(*got, want, epsilon = 1e-15);
        }
        approx::assert_abs_diff_eq!(m.get(Set::from_bits(1)), 0.571_428_571_4, epsilon = 1e-10);
        let all_conflict = Mass::<f64>::categorical(&frame, Set::EMPTY)?;
        assert_eq!(all_conflict.normalised(), Err(BeliefError::TotalConflict));
        Ok(())
    }

    #[test]
    fn cast_keeps_values_to_f32_precision() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "b"])?;
        let m = Mass::from_values(&frame, vec![0.0, 0.2, 0.6, 0.2])?;
        let narrow: Mass<f32> = m.cast();
        assert_eq!(narrow.values(), &[0.0, 0.2, 0.6, 0.2]);
        assert!(check_masses(narrow.values()).is_ok());
        Ok(())
    }
}
