//! Specialisation: moving mass from sets to their subsets.

use crate::{BeliefError, Frame, Mass, Real, Set, discounting::check_rate};

/// A specialisation matrix `S`: `m'(A) = Σ_B S(A, B)·m(B)`, where column `B` shares the mass of
/// `B` among subsets of `B` (`S(A, B) ≥ 0`, non-zero only for `A ⊆ B`, each column sums to one).
///
/// The grids use the fast rule [`specialise_without`]; the matrix is the general form and the
/// reference it is tested against.
///
/// # Examples
///
/// ```
/// use belief::{Frame, Mass, Specialisation};
///
/// let frame = Frame::new(["S", "M"])?;
/// let m = Mass::<f64>::from_named(&frame, &[(&["M"], 0.5), (&["S", "M"], 0.5)])?;
/// // Eq 29 with ζ = 0.4: {S,M} gives 0.4 of its mass to {S}, {M} gives 0.4 to ∅.
/// let s = Specialisation::without(&frame, frame.element("M")?, 0.4)?;
/// let m2 = s.apply(&m)?;
/// assert!((m2.get(frame.set(&["S"])?) - 0.2).abs() < 1e-12);
/// assert!((m2.conflict() - 0.2).abs() < 1e-12);
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// Paper eq 28-29; SPEC §1 and §5 step 6.
#[derive(Clone, Debug, PartialEq)]
pub struct Specialisation<R: Real> {
    frame: Frame,
    /// Row-major: `matrix[a * 2^n + b] = S(A, B)`.
    matrix: Vec<R>,
}

impl<R: Real> Specialisation<R> {
    /// A specialisation from its dense row-major matrix, `matrix[A.index() * 2^n + B.index()] =
    /// S(A, B)`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::WrongLength`] unless there are `4^n` entries;
    /// [`BeliefError::InvalidSpecialisation`] for the first column with a NaN or negative entry,
    /// an entry outside the subsets of its set, or a sum other than one.
    pub fn new(frame: &Frame, matrix: Vec<R>) -> Result<Self, BeliefError> {
        let size = frame.size();
        if matrix.len() != size * size {
            return Err(BeliefError::WrongLength {
                expected: size * size,
                found: matrix.len(),
            });
        }
        for column in frame.subsets() {
            let mut sum = R::ZERO;
            for row in frame.subsets() {
                let entry = matrix[row.index() * size + column.index()];
                let allowed = row.is_subset_of(column) || entry == R::ZERO;
                if !entry.is_finite() || entry < R::ZERO || !allowed {
                    return Err(BeliefError::InvalidSpecialisation { column });
                }
                sum += entry;
            }
            if (sum - R::ONE).abs() > R::TOLERANCE {
                return Err(BeliefError::InvalidSpecialisation { column });
            }
        }
        Ok(Self {
            frame: frame.clone(),
            matrix,
        })
    }

    /// The identity: no mass moves.
    pub fn identity(frame: &Frame) -> Self {
        Self::moving_unchecked(frame, R::ZERO, |set| set)
    }

    /// The rule "move fraction `fraction` of `m(A)` to `target(A)`" for every `A` (SPEC §1).
    ///
    /// # Errors
    ///
    /// [`BeliefError::RateOutOfRange`] unless `0 ≤ fraction ≤ 1`;
    /// [`BeliefError::InvalidSpecialisation`] for the first `A` whose target is not a subset of
    /// `A`.
    pub fn moving(
        frame: &Frame,
        fraction: R,
        target: impl Fn(Set) -> Set,
    ) -> Result<Self, BeliefError> {
        check_rate(fraction)?;
        if let Some(column) = frame.subsets().find(|&set| !target(set).is_subset_of(set)) {
            return Err(BeliefError::InvalidSpecialisation { column });
        }
        Ok(Self::moving_unchecked(frame, fraction, target))
    }

    /// Eq 29: for every `A` containing `element`, `S(A \ {element}, A) = ζ` and `S(A, A) = 1 − ζ`;
    /// other sets stay where they are.
    ///
    /// # Errors
    ///
    /// [`BeliefError::ElementOutOfRange`], [`BeliefError::RateOutOfRange`] unless `0 ≤ ζ ≤ 1`.
    pub fn without(frame: &Frame, element: usize, zeta: R) -> Result<Self, BeliefError> {
        let removed = frame.singleton(element)?;
        Self::moving(frame, zeta, |set| set.difference(removed))
    }

    fn moving_unchecked(frame: &Frame, fraction: R, target: impl Fn(Set) -> Set) -> Self {
        let size = frame.size();
        let mut matrix = vec![R::ZERO; size * size];
        for column in frame.subsets() {
            let to = target(column);
            if to == column {
                matrix[column.index() * size + column.index()] = R::ONE;
            } else {
                matrix[column.index() * size + column.index()] = R::ONE - fraction;
                matrix[to.index() * size + column.index()] = fraction;
            }
        }
        Self {
            frame: frame.clone(),
            matrix,
        }
    }

    /// The frame.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// `S(a, b)`: the share of `m(b)` that goes to `a` (zero outside the frame).
    pub fn get(&self, a: Set, b: Set) -> R {
        self.matrix
            .get(a.index() * self.frame.size() + b.index())
            .copied()
            .filter(|_| b.index() < self.frame.size())
            .unwrap_or(R::ZERO)
    }

    /// The specialised mass function `m'(A) = Σ_B S(A, B)·m(B)` (eq 28).
    ///
    /// # Errors
    ///
    /// [`BeliefError::MismatchedFrames`] unless `m` is on this frame.
    pub fn apply(&self, m: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        self.frame.check_same(m.frame())?;
        let size = self.frame.size();
        let mut values = vec![R::ZERO; size];
        for (b, mass) in m.focal_sets() {
            // Only subsets of B can receive from column B.
            for a in self.frame.subsets().filter(|a| a.is_subset_of(b)) {
                values[a.index()] += self.matrix[a.index() * size + b.index()] * mass;
            }
        }
        Ok(Mass::from_computed(&self.frame, values))
    }
}

/// The fast form of eq 28-29: for every `A` containing `element`, move `ζ·m(A)` to
/// `A \ {element}`, in `2^n` steps instead of a `4^n` matrix product. (For `A = {element}` the
/// target is ∅.)
///
/// # Errors
///
/// [`BeliefError::ElementOutOfRange`], [`BeliefError::RateOutOfRange`] unless `0 ≤ ζ ≤ 1`.
///
/// # Examples
///
/// ```
/// use belief::{specialise_without, Frame, Mass};
///
/// let frame = Frame::new(["F", "I", "U", "S", "M"])?;
/// let m = Mass::<f64>::from_named(&frame, &[(&["S", "M"], 0.6), (&["F", "I", "U", "S", "M"], 0.4)])?;
/// let m2 = specialise_without(&m, frame.element("M")?, 0.25)?;
/// // {S,M} → {S}: 0.25·0.6 = 0.15; Ω → {F,I,U,S}: 0.25·0.4 = 0.1.
/// assert!((m2.get(frame.set(&["S"])?) - 0.15).abs() < 1e-12);
/// assert!((m2.get(frame.set(&["F", "I", "U", "S"])?) - 0.1).abs() < 1e-12);
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// Paper eq 28-29; SPEC §5 step 6.
pub fn specialise_without<R: Real>(
    m: &Mass<R>,
    element: usize,
    zeta: R,
) -> Result<Mass<R>, BeliefError> {
    let removed = m.frame().singleton(element)?;
    check_rate(zeta)?;
    let mut values = m.values().to_vec();
    for set in m.frame().subsets().filter(|set| set.contains(element)) {
        let moved = zeta * values[set.index()];
        values[set.index()] -= moved;
        values[set.difference(removed).index()] += moved;
    }
    Ok(Mass::from_computed(m.frame(), values))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass, assert_close, assert_valid};
    use proptest::prelude::*;

    #[test]
    fn rejects_matrices_that_are_not_specialisations() -> Result<(), BeliefError> {
        let frame = Frame::new(["a"])?;
        // Columns: ∅ = (S(∅,∅), S(a,∅)), a = (S(∅,a), S(a,a)); row-major [S(∅,∅), S(∅,a), S(a,∅), S(a,a)].
        assert!(Specialisation::new(&frame, vec![1.0, 0.3, 0.0, 0.7]).is_ok());
        // ∅ cannot give to {a} ⊄ ∅.
        assert_eq!(
            Specialisation::new(&frame, vec![0.5, 0.0, 0.5, 1.0]),
            Err(BeliefError::InvalidSpecialisation { column: Set::EMPTY })
        );
        // Column {a} sums to 0.9.
        assert!(Specialisation::new(&frame, vec![1.0, 0.2, 0.0, 0.7]).is_err());
        assert!(Specialisation::new(&frame, vec![1.0, -0.1, 0.0, 1.1]).is_err());
        assert!(Specialisation::new(&frame, vec![1.0; 3]).is_err());
        // A target that is not a subset.
        assert!(Specialisation::moving(&frame, 0.5, |_| Set::from_bits(1)).is_err());
        assert!(specialise_without(&Mass::<f64>::vacuous(&frame), 1, 0.5).is_err());
        Ok(())
    }

    #[test]
    fn eq_29_on_the_perception_frame() -> Result<(), BeliefError> {
        let frame = Frame::new(["F", "I", "U", "S", "M"])?;
        let s = Specialisation::without(&frame, 4, 0.3)?;
        let sm = frame.set(&["S", "M"])?;
        let s_only = frame.set(&["S"])?;
        // S(A \ {M}, A) = ζ, S(A, A) = 1 − ζ for A ∋ M; S(A, A) = 1 otherwise.
        assert_eq!(s.get(s_only, sm), 0.3);
        assert_eq!(s.get(sm, sm), 0.7);
        assert_eq!(s.get(s_only, s_only), 1.0);
        assert_eq!(s.get(sm, s_only), 0.0);
        Ok(())
    }

    proptest! {
        #[test]
        fn fast_rule_equals_matrix(m in arb_mass(1..=6), zeta in 0.0..=1.0_f64, pick in 0_usize..6) {
            let element = pick % m.frame().len();
            let fast = specialise_without(&m, element, zeta)?;
            let slow = Specialisation::without(m.frame(), element, zeta)?.apply(&m)?;
            assert_valid(&fast);
            assert_close(fast.values(), slow.values(), 1e-12);
            assert_close(Specialisation::identity(m.frame()).apply(&m)?.values(), m.values(), 0.0);
        }
    }
}
