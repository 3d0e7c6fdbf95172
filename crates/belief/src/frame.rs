//! Frames of discernment and their subsets.
//!
//! A frame has at most eight named elements; element `k` is bit `k`, so a subset is a `u8`
//! bitmask and a mass function a dense array of `2^n` values indexed by that mask (SPEC §1).

use std::fmt;
use std::sync::Arc;

use crate::BeliefError;

/// A frame of discernment: up to [`Frame::MAX_LEN`] distinct named elements, in order.
///
/// Cloning is cheap (the names are shared), so every [`Mass`](crate::Mass) carries its frame and
/// operations can refuse to mix frames.
///
/// # Examples
///
/// ```
/// use belief::{Frame, Set};
///
/// let frame = Frame::new(["F", "I", "U", "S", "M"])?;
/// assert_eq!(frame.len(), 5);
/// assert_eq!(frame.size(), 32);
/// assert_eq!(frame.set(&["S", "M"])?, Set::from_bits(0b11000));
/// assert_eq!(frame.omega(), Set::from_bits(0b11111));
/// # Ok::<(), belief::BeliefError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Frame {
    names: Arc<[String]>,
}

impl Frame {
    /// The largest number of elements a frame can hold (a subset must fit in a `u8`).
    pub const MAX_LEN: usize = 8;

    /// A frame with the given element names; element `k` is the `k`-th name.
    ///
    /// # Errors
    ///
    /// [`BeliefError::EmptyFrame`], [`BeliefError::FrameTooLarge`] beyond eight elements, and
    /// [`BeliefError::DuplicateElement`] when a name repeats.
    pub fn new<I, S>(names: I) -> Result<Self, BeliefError>
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        let names: Vec<String> = names.into_iter().map(Into::into).collect();
        if names.is_empty() {
            return Err(BeliefError::EmptyFrame);
        }
        if names.len() > Self::MAX_LEN {
            return Err(BeliefError::FrameTooLarge { len: names.len() });
        }
        for (k, name) in names.iter().enumerate() {
            if names[..k].contains(name) {
                return Err(BeliefError::DuplicateElement { name: name.clone() });
            }
        }
        Ok(Self {
            names: names.into(),
        })
    }

    /// The number of elements `n`.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Always `false`: a frame has at least one element. (Present because `len` is.)
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The number of subsets, `2^n`: the length of a mass function's dense array.
    pub fn size(&self) -> usize {
        1 << self.names.len()
    }

    /// The element names, element `k` at index `k`.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The whole frame Ω as a set.
    pub fn omega(&self) -> Set {
        // For n = 8 this is 0xFF; computed in u16 so the shift cannot overflow.
        Set(((1_u16 << self.names.len()) - 1) as u8)
    }

    /// The index of the element called `name`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::UnknownElement`] if no element has that name.
    pub fn element(&self, name: &str) -> Result<usize, BeliefError> {
        self.names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| BeliefError::UnknownElement {
                name: name.to_owned(),
                frame: self.clone(),
            })
    }

    /// The singleton `{k}`.
    ///
    /// # Errors
    ///
    /// [`BeliefError::ElementOutOfRange`] if `k` is not an element index of this frame.
    pub fn singleton(&self, k: usize) -> Result<Set, BeliefError> {
        if k < self.len() {
            Ok(Set(1 << k))
        } else {
            Err(BeliefError::ElementOutOfRange {
                element: k,
                frame_len: self.len(),
            })
        }
    }

    /// The set of the named elements (order and repetition do not matter; `&[]` is ∅).
    ///
    /// # Errors
    ///
    /// [`BeliefError::UnknownElement`] for the first name not in the frame.
    pub fn set<S: AsRef<str>>(&self, names: &[S]) -> Result<Set, BeliefError> {
        names.iter().try_fold(Set::EMPTY, |set, name| {
            let k = self.element(name.as_ref())?;
            Ok(set.union(Set(1 << k)))
        })
    }

    /// Checks that `set` holds only elements of this frame.
    ///
    /// # Errors
    ///
    /// [`BeliefError::SetOutsideFrame`] otherwise.
    pub fn check_set(&self, set: Set) -> Result<(), BeliefError> {
        if set.is_subset_of(self.omega()) {
            Ok(())
        } else {
            Err(BeliefError::SetOutsideFrame {
                set,
                frame_len: self.len(),
            })
        }
    }

    /// `set` as its element names in brackets, `[a, b]`, and `[]` for ∅: the notation of the
    /// mass files, used in messages.
    pub fn set_label(&self, set: Set) -> String {
        format!("[{}]", self.names_of(set).join(", "))
    }

    /// The names of the elements of `set`, in frame order (bits beyond the frame are ignored).
    pub fn names_of(&self, set: Set) -> Vec<&str> {
        self.names
            .iter()
            .enumerate()
            .filter(|&(k, _)| set.contains(k))
            .map(|(_, name)| name.as_str())
            .collect()
    }

    /// All `2^n` subsets in increasing bitmask order, ∅ first and Ω last.
    pub fn subsets(&self) -> impl Iterator<Item = Set> + use<> {
        (0..self.size()).map(|bits| Set(bits as u8))
    }

    /// Checks that two operands share this frame.
    pub(crate) fn check_same(&self, other: &Frame) -> Result<(), BeliefError> {
        if self == other {
            Ok(())
        } else {
            Err(BeliefError::MismatchedFrames {
                left: self.clone(),
                right: other.clone(),
            })
        }
    }
}

/// Writes the frame as `{a, b}`.
impl fmt::Display for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{{{}}}", self.names.join(", "))
    }
}

/// A subset of a frame as a bitmask: element `k` is in the set when bit `k` is one.
///
/// A `Set` does not know its frame; [`Frame::set`] builds one from names and [`Frame::names_of`]
/// reads it back.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Set(u8);

impl Set {
    /// The empty set ∅.
    pub const EMPTY: Set = Set(0);

    /// The set whose bitmask is `bits`.
    pub const fn from_bits(bits: u8) -> Set {
        Set(bits)
    }

    /// The bitmask.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// The position of this set in a dense mass array.
    pub const fn index(self) -> usize {
        self.0 as usize
    }

    /// `true` if element `k` is in the set (`false` for any `k ≥ 8`).
    pub const fn contains(self, k: usize) -> bool {
        k < 8 && self.0 & (1 << k) != 0
    }

    /// The cardinality `|A|`.
    pub const fn len(self) -> u32 {
        self.0.count_ones()
    }

    /// `true` for ∅.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// `A ∪ B`.
    pub const fn union(self, other: Set) -> Set {
        Set(self.0 | other.0)
    }

    /// `A ∩ B`.
    pub const fn intersection(self, other: Set) -> Set {
        Set(self.0 & other.0)
    }

    /// `A \ B`.
    pub const fn difference(self, other: Set) -> Set {
        Set(self.0 & !other.0)
    }

    /// `A ⊆ B`.
    pub const fn is_subset_of(self, other: Set) -> bool {
        self.0 & !other.0 == 0
    }
}

/// Writes the element indices, `{0, 2}`; use [`Frame::names_of`] for names.
impl fmt::Display for Set {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("{")?;
        let mut first = true;
        for k in 0..8 {
            if self.contains(k) {
                if !first {
                    f.write_str(", ")?;
                }
                write!(f, "{k}")?;
                first = false;
            }
        }
        f.write_str("}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_rejects_bad_element_lists() {
        assert_eq!(
            Frame::new(Vec::<String>::new()),
            Err(BeliefError::EmptyFrame)
        );
        assert_eq!(
            Frame::new((0..9).map(|k| k.to_string())),
            Err(BeliefError::FrameTooLarge { len: 9 })
        );
        assert_eq!(
            Frame::new(["a", "b", "a"]),
            Err(BeliefError::DuplicateElement { name: "a".into() })
        );
    }

    #[test]
    fn eight_element_frame_uses_every_bit() -> Result<(), BeliefError> {
        let frame = Frame::new((0..8).map(|k| format!("e{k}")))?;
        assert_eq!(frame.omega(), Set::from_bits(0xFF));
        assert_eq!(frame.size(), 256);
        assert_eq!(frame.subsets().count(), 256);
        assert_eq!(frame.subsets().last(), Some(frame.omega()));
        Ok(())
    }

    #[test]
    fn names_and_sets_convert_both_ways() -> Result<(), BeliefError> {
        let frame = Frame::new(["a", "h", "r"])?;
        let hr = frame.set(&["r", "h", "r"])?;
        assert_eq!(hr, Set::from_bits(0b110));
        assert_eq!(frame.names_of(hr), ["h", "r"]);
        assert_eq!(frame.set::<&str>(&[])?, Set::EMPTY);
        assert!(matches!(
            frame.set(&["x"]),
            Err(BeliefError::UnknownElement { name, .. }) if name == "x"
        ));
        assert_eq!(
            frame.check_set(Set::from_bits(0b1000)),
            Err(BeliefError::SetOutsideFrame {
                set: Set::from_bits(0b1000),
                frame_len: 3
            })
        );
        assert_eq!(hr.to_string(), "{1, 2}");
        assert_eq!(frame.to_string(), "{a, h, r}");
        Ok(())
    }

    #[test]
    fn set_algebra_on_bitmasks() {
        let a = Set::from_bits(0b0110);
        let b = Set::from_bits(0b0011);
        assert_eq!(a.union(b), Set::from_bits(0b0111));
        assert_eq!(a.intersection(b), Set::from_bits(0b0010));
        assert_eq!(a.difference(b), Set::from_bits(0b0100));
        assert!(Set::from_bits(0b0100).is_subset_of(a));
        assert!(!b.is_subset_of(a));
        assert_eq!(a.len(), 2);
        assert!(!a.contains(0) && a.contains(1) && !a.contains(9));
    }
}
