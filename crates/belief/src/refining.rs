//! Refining a mass function from a coarse frame to a finer one.

use crate::{BeliefError, Frame, Mass, Real, Set};

/// A refining `r` from a coarse frame Ω₁ to a finer frame Ω₂: each coarse element maps to a
/// non-empty set of fine elements, the images are disjoint and cover Ω₂ (eq 4-6), and a set maps
/// to the union of its elements' images (eq 7).
///
/// # Examples
///
/// ```
/// use belief::{Frame, Mass, Refining};
///
/// // SPEC §5 step 1: the SensorGrid frame {F, O} into the PerceptionGrid frame {F, I, U, S, M}.
/// let sensor = Frame::new(["F", "O"])?;
/// let perception = Frame::new(["F", "I", "U", "S", "M"])?;
/// let r = Refining::from_names(&sensor, &perception, &[&["F"], &["I", "U", "S", "M"]])?;
/// let m = Mass::<f64>::from_named(&sensor, &[(&["O"], 0.8), (&["F", "O"], 0.2)])?;
/// let refined = r.apply(&m)?;
/// assert_eq!(refined.get(perception.set(&["I", "U", "S", "M"])?), 0.8);
/// assert_eq!(refined.get(perception.omega()), 0.2);
/// # Ok::<(), belief::BeliefError>(())
/// ```
///
/// # References
///
/// Paper eq 4-7 and 16-20; SPEC §1 and §5 step 1.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refining {
    coarse: Frame,
    fine: Frame,
    images: Vec<Set>,
}

impl Refining {
    /// The refining with `images[k]` the image of coarse element `k`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::WrongLength`] unless there is one image per coarse element;
    /// [`BeliefError::SetOutsideFrame`] for an image outside the fine frame;
    /// [`BeliefError::InvalidRefining`] for an empty or overlapping image, or images that do not
    /// cover the fine frame.
    pub fn new(coarse: &Frame, fine: &Frame, images: Vec<Set>) -> Result<Self, BeliefError> {
        if images.len() != coarse.len() {
            return Err(BeliefError::WrongLength {
                expected: coarse.len(),
                found: images.len(),
            });
        }
        let mut covered = Set::EMPTY;
        for (k, &image) in images.iter().enumerate() {
            fine.check_set(image)?;
            if image.is_empty() || !image.intersection(covered).is_empty() {
                return Err(BeliefError::InvalidRefining { element: Some(k) });
            }
            covered = covered.union(image);
        }
        if covered != fine.omega() {
            return Err(BeliefError::InvalidRefining { element: None });
        }
        Ok(Self {
            coarse: coarse.clone(),
            fine: fine.clone(),
            images,
        })
    }

    /// The refining with the image of coarse element `k` given by the fine element names
    /// `images[k]`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::UnknownElement`], or as [`Refining::new`].
    pub fn from_names(
        coarse: &Frame,
        fine: &Frame,
        images: &[&[&str]],
    ) -> Result<Self, BeliefError> {
        let images = images
            .iter()
            .map(|names| fine.set(names))
            .collect::<Result<Vec<_>, _>>()?;
        Self::new(coarse, fine, images)
    }

    /// The coarse frame Ω₁.
    pub fn coarse(&self) -> &Frame {
        &self.coarse
    }

    /// The fine frame Ω₂.
    pub fn fine(&self) -> &Frame {
        &self.fine
    }

    /// `r(A) = ∪_{ω∈A} r(ω)` (eq 7); elements beyond the coarse frame are ignored.
    pub fn image(&self, set: Set) -> Set {
        self.images
            .iter()
            .enumerate()
            .filter(|&(k, _)| set.contains(k))
            .fold(Set::EMPTY, |acc, (_, &image)| acc.union(image))
    }

    /// The refined mass function, `m'(r(A)) = m(A)` (eq 20).
    ///
    /// # Errors
    ///
    /// [`BeliefError::MismatchedFrames`] unless `m` is on the coarse frame.
    pub fn apply<R: Real>(&self, m: &Mass<R>) -> Result<Mass<R>, BeliefError> {
        self.coarse.check_same(m.frame())?;
        let mut values = vec![R::ZERO; self.fine.size()];
        for (set, mass) in m.focal_sets() {
            values[self.image(set).index()] += mass;
        }
        Ok(Mass::from_computed(&self.fine, values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{arb_mass, assert_close};
    use crate::{Combination, Conjunctive};
    use proptest::prelude::*;

    fn sensor_to_perception() -> Result<Refining, BeliefError> {
        Refining::from_names(
            &Frame::new(["F", "O"])?,
            &Frame::new(["F", "I", "U", "S", "M"])?,
            &[&["F"], &["I", "U", "S", "M"]],
        )
    }

    #[test]
    fn paper_refining_maps_the_sensor_frame() -> Result<(), BeliefError> {
        let r = sensor_to_perception()?;
        // F → {F} = bit 0; O → {I,U,S,M} = bits 1-4 = 0b11110; Ω → 0b11111 (eq 17-19).
        assert_eq!(r.image(Set::from_bits(0b01)), Set::from_bits(0b00001));
        assert_eq!(r.image(Set::from_bits(0b10)), Set::from_bits(0b11110));
        assert_eq!(r.image(Set::from_bits(0b11)), Set::from_bits(0b11111));
        assert_eq!(r.image(Set::EMPTY), Set::EMPTY);
        let m = Mass::from_values(r.coarse(), vec![0.0, 0.7, 0.0, 0.3])?;
        let refined = r.apply(&m)?;
        assert_eq!(refined.get(Set::from_bits(1)), 0.7);
        assert_eq!(refined.get(Set::from_bits(31)), 0.3);
        Ok(())
    }

    #[test]
    fn images_must_partition_the_fine_frame() -> Result<(), BeliefError> {
        let coarse = Frame::new(["x", "y"])?;
        let fine = Frame::new(["a", "b", "c"])?;
        let overlap = Refining::from_names(&coarse, &fine, &[&["a", "b"], &["b", "c"]]);
        assert_eq!(
            overlap,
            Err(BeliefError::InvalidRefining { element: Some(1) })
        );
        let empty = Refining::from_names(&coarse, &fine, &[&[], &["a", "b", "c"]]);
        assert_eq!(
            empty,
            Err(BeliefError::InvalidRefining { element: Some(0) })
        );
        let gap = Refining::from_names(&coarse, &fine, &[&["a"], &["b"]]);
        assert_eq!(gap, Err(BeliefError::InvalidRefining { element: None }));
        let short = Refining::from_names(&coarse, &fine, &[&["a", "b", "c"]]);
        assert!(matches!(short, Err(BeliefError::WrongLength { .. })));
        let r = Refining::from_names(&coarse, &fine, &[&["a"], &["b", "c"]])?;
        assert!(matches!(
            r.apply(&Mass::<f64>::vacuous(&fine)),
            Err(BeliefError::MismatchedFrames { .. })
        ));
        Ok(())
    }

    proptest! {
        #[test]
        fn refining_commutes_with_conjunctive_combination(
            a in arb_mass(2..=2),
            b in arb_mass(2..=2),
        ) {
            // r(a ∩ b) = r(a) ∩ r(b): refining preserves intersections of images of a partition.
            let r = Refining::new(a.frame(), &crate::testing::frame_of(5), vec![
                Set::from_bits(0b00001), Set::from_bits(0b11110),
            ])?;
            let left = r.apply(&Conjunctive.combine(&a, &b)?)?;
            let right = Conjunctive.combine(&r.apply(&a)?, &r.apply(&b)?)?;
            assert_close(left.values(), right.values(), 1e-12);
        }
    }
}
