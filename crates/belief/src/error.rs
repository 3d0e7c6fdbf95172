//! The one error type of the crate.

use std::fmt;

use crate::{Frame, Set};

/// Why an operation on belief functions could not be done.
///
/// Every variant carries the offending values. No operation of this crate panics or returns NaN on
/// bad input: it returns one of these instead.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum BeliefError {
    /// A frame needs at least one element.
    EmptyFrame,
    /// A frame holds at most [`Frame::MAX_LEN`] elements; this one had `len`.
    FrameTooLarge {
        /// Number of elements asked for.
        len: usize,
    },
    /// Two elements of a frame have the same name.
    DuplicateElement {
        /// The repeated name.
        name: String,
    },
    /// A name that is not an element of the frame.
    UnknownElement {
        /// The name looked up.
        name: String,
        /// The frame it was looked up in.
        frame: Frame,
    },
    /// An element index at or beyond the frame's length.
    ElementOutOfRange {
        /// The index given.
        element: usize,
        /// The frame's number of elements.
        frame_len: usize,
    },
    /// A set that holds elements beyond the frame's last one.
    SetOutsideFrame {
        /// The set given.
        set: Set,
        /// The frame's number of elements.
        frame_len: usize,
    },
    /// A dense array whose length does not fit the frame (a mass function on n elements has 2^n
    /// values).
    WrongLength {
        /// Length the frame calls for.
        expected: usize,
        /// Length given.
        found: usize,
    },
    /// A mass, rate or matrix entry that is NaN or infinite.
    NotFinite {
        /// The set the value belongs to (for a rate, the context set or class).
        set: Set,
        /// The value.
        value: f64,
    },
    /// A negative mass.
    NegativeMass {
        /// The set holding it.
        set: Set,
        /// The mass.
        value: f64,
    },
    /// Masses that do not sum to one (within [`Real::TOLERANCE`](crate::Real::TOLERANCE)).
    InvalidSum {
        /// Their sum.
        sum: f64,
    },
    /// The same focal set given twice.
    RepeatedSet {
        /// The set.
        set: Set,
    },
    /// Two mass functions on different frames.
    MismatchedFrames {
        /// The frame of the first operand.
        left: Frame,
        /// The frame of the other operand.
        right: Frame,
    },
    /// Normalisation by `1 - m(∅)` with `m(∅) = 1` (Dempster's rule, pignistic probability): no
    /// mass at all is left on a non-empty set.
    TotalConflict,
    /// A discount rate or fraction outside `[0, 1]`.
    RateOutOfRange {
        /// The value.
        value: f64,
    },
    /// An n-ary combination of no mass function at all.
    NoInputs,
    /// A mapping that is not a refining (eq 4-6): an element's image is empty, two images overlap
    /// (`element` is the later one) or the images do not cover the finer frame (`element` is
    /// `None`).
    InvalidRefining {
        /// The element of the coarse frame whose image is at fault, if one is.
        element: Option<usize>,
    },
    /// A matrix that is not a specialisation matrix (eq 28): in column `column` either an entry
    /// outside the subsets of the column's set is non-zero, an entry is negative, or the column
    /// does not sum to one.
    InvalidSpecialisation {
        /// The column (the set whose mass is being moved).
        column: Set,
    },
}

impl fmt::Display for BeliefError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EmptyFrame => f.write_str("a frame needs at least one element"),
            Self::FrameTooLarge { len } => write!(
                f,
                "a frame holds at most {} elements, not {len}",
                Frame::MAX_LEN
            ),
            Self::DuplicateElement { name } => {
                write!(f, "element {name:?} appears twice in the frame")
            }
            Self::UnknownElement { name, frame } => {
                write!(f, "element {name:?} is not in the frame {frame}")
            }
            Self::ElementOutOfRange { element, frame_len } => write!(
                f,
                "element index {element} is beyond a frame of {frame_len} elements"
            ),
            Self::SetOutsideFrame { set, frame_len } => write!(
                f,
                "set {set} holds elements beyond a frame of {frame_len} elements"
            ),
            Self::WrongLength { expected, found } => {
                write!(f, "expected {expected} values, found {found}")
            }
            Self::NotFinite { set, value } => write!(f, "value {value} on set {set} is not finite"),
            Self::NegativeMass { set, value } => write!(f, "negative mass {value} on set {set}"),
            Self::InvalidSum { sum } => write!(f, "masses sum to {sum}, not 1"),
            Self::RepeatedSet { set } => write!(f, "set {set} is given twice"),
            Self::MismatchedFrames { left, right } => {
                write!(f, "frames differ: {left} and {right}")
            }
            Self::TotalConflict => f.write_str("total conflict: all mass is on the empty set"),
            Self::RateOutOfRange { value } => write!(f, "rate {value} is not in [0, 1]"),
            Self::NoInputs => f.write_str("no mass function to combine"),
            Self::InvalidRefining {
                element: Some(element),
            } => write!(
                f,
                "not a refining: the image of element {element} is empty or overlaps another"
            ),
            Self::InvalidRefining { element: None } => {
                f.write_str("not a refining: the images do not cover the finer frame")
            }
            Self::InvalidSpecialisation { column } => write!(
                f,
                "not a specialisation matrix: column {column} is negative, sums to other than 1 \
                 or moves mass outside the subsets of {column}"
            ),
        }
    }
}

impl std::error::Error for BeliefError {}

impl BeliefError {
    /// The error in the words of a user who named the sets of `frame`: sets as their element
    /// names (`[F, O]`, [`Frame::set_label`]) rather than bitmasks, and a sum with the tolerance
    /// it missed. One line, for the command line's and the Python package's messages alike.
    ///
    /// ```
    /// use belief::{BeliefError, Frame};
    ///
    /// let frame = Frame::new(["F", "O"])?;
    /// let error = BeliefError::NegativeMass { set: frame.set(&["O"])?, value: -0.5 };
    /// assert_eq!(error.describe_in(&frame), "negative mass -0.5 on set [O]");
    /// # Ok::<(), BeliefError>(())
    /// ```
    pub fn describe_in(&self, frame: &Frame) -> String {
        match self {
            Self::NegativeMass { set, value } => {
                format!("negative mass {value} on set {}", frame.set_label(*set))
            }
            Self::NotFinite { set, value } => {
                format!(
                    "mass {value} on set {} is not finite",
                    frame.set_label(*set)
                )
            }
            Self::InvalidSum { sum } => format!(
                "masses sum to {sum}, not 1 (tolerance {})",
                <f64 as crate::Real>::TOLERANCE
            ),
            Self::RepeatedSet { set } => {
                format!("set {} is listed twice", frame.set_label(*set))
            }
            Self::SetOutsideFrame { set, .. } => {
                format!("set {set} is not a subset of the frame {frame}")
            }
            other => other.to_string(),
        }
    }

    /// [`Self::describe_in`] for an error of combining masses: total conflict named as
    /// Dempster's rule meets it.
    pub fn describe_combination_in(&self, frame: &Frame) -> String {
        match self {
            Self::TotalConflict => {
                "total conflict (K = 1): Dempster's rule is undefined".to_owned()
            }
            other => other.describe_in(frame),
        }
    }

    /// [`Self::describe_in`] for an error of the pignistic transform: total conflict named as
    /// what it leaves undefined.
    pub fn describe_pignistic_in(&self, frame: &Frame) -> String {
        match self {
            Self::TotalConflict => "m(∅) = 1, so the pignistic probability is undefined".to_owned(),
            other => other.describe_in(frame),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn total_conflict_is_named_by_what_it_leaves_undefined() -> Result<(), BeliefError> {
        let frame = Frame::new(["F", "O"])?;
        let conflict = BeliefError::TotalConflict;
        assert_eq!(
            conflict.describe_combination_in(&frame),
            "total conflict (K = 1): Dempster's rule is undefined"
        );
        assert_eq!(
            conflict.describe_pignistic_in(&frame),
            "m(∅) = 1, so the pignistic probability is undefined"
        );
        let sum = BeliefError::InvalidSum { sum: 0.5 };
        assert_eq!(sum.describe_combination_in(&frame), sum.describe_in(&frame));
        assert_eq!(sum.describe_pignistic_in(&frame), sum.describe_in(&frame));
        Ok(())
    }

    #[test]
    fn described_in_a_frame_sets_are_named_by_their_elements() -> Result<(), BeliefError> {
        let frame = Frame::new(["F", "O", "M"])?;
        let fo = Set::from_bits(0b011);
        let cases = [
            (
                BeliefError::NegativeMass {
                    set: fo,
                    value: -0.25,
                },
                "negative mass -0.25 on set [F, O]",
            ),
            (
                BeliefError::NotFinite {
                    set: Set::EMPTY,
                    value: f64::INFINITY,
                },
                "mass inf on set [] is not finite",
            ),
            (
                BeliefError::InvalidSum { sum: 0.5 },
                "masses sum to 0.5, not 1 (tolerance 0.000000001)",
            ),
            (
                BeliefError::RepeatedSet {
                    set: Set::from_bits(0b100),
                },
                "set [M] is listed twice",
            ),
            (
                BeliefError::SetOutsideFrame {
                    set: Set::from_bits(0b1001),
                    frame_len: 3,
                },
                "set {0, 3} is not a subset of the frame {F, O, M}",
            ),
            // Without sets to name: the plain message.
            (BeliefError::NoInputs, "no mass function to combine"),
        ];
        for (error, expected) in cases {
            assert_eq!(error.describe_in(&frame), expected);
        }
        Ok(())
    }
}
