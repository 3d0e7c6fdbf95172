//! The one label type of a cell, for truth and for predictions alike.
//!
//! The numbering is that of [`evigrid::Decision`] (0 unknown, then F, I, U, S, M in the frame
//! order of Ω_PG), so a decision of the paper's method converts by its code, and O (occupied and
//! static, class not resolved) follows as the one label evigrid never decides: a two-class
//! baseline says it of an occupied cell that is not moving. `Edge` is truth only: a cell a
//! building covers in part but not at its centre (the boundary band, see [`crate::truth`]).
//!
//! ```
//! use sim::Label;
//! assert_eq!(Label::from(evigrid::Decision::S), Label::S);
//! assert_eq!(Label::from_code(4), Some(Label::S));
//! assert_eq!(Label::O.name(), "O");
//! ```

use evigrid::Decision;
use serde::{Deserialize, Serialize};

/// The class of a cell: in truth one of F, I, U, S, M, `Edge` (the boundary band of a building),
/// or `Unknown` for a cell not to be scored; as a prediction any but `Edge`.
#[repr(u8)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Label {
    /// No decision (prediction), or excluded from scoring (truth: the cells under the ego).
    #[default]
    Unknown = 0,
    /// Free.
    F = 1,
    /// Mapped infrastructure (buildings present in the map).
    I = 2,
    /// Unmapped infrastructure (street furniture, buildings missing from the map).
    U = 3,
    /// Stopped object.
    S = 4,
    /// Moving object.
    M = 5,
    /// Occupied and static, class not resolved (two-class baselines only).
    O = 6,
    /// Truth only: a cell partly covered by a building whose centre is outside it (the
    /// boundary band). Static, but free or infrastructure are both defensible there.
    Edge = 7,
}

impl Label {
    /// Every label, in code order.
    pub const ALL: [Label; 8] = [
        Label::Unknown,
        Label::F,
        Label::I,
        Label::U,
        Label::S,
        Label::M,
        Label::O,
        Label::Edge,
    ];

    /// The five classes of Ω_PG that truth uses, in frame order.
    pub const CLASSES: [Label; 5] = [Label::F, Label::I, Label::U, Label::S, Label::M];

    /// The label of code `code` (its discriminant), if any.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }

    /// Short name: `unknown`, `edge`, or the class letter.
    pub fn name(self) -> &'static str {
        ["unknown", "F", "I", "U", "S", "M", "O", "edge"][self as usize]
    }
}

impl From<Decision> for Label {
    /// The same class, with the same code: [`Label`] numbers its classes as [`Decision`] does,
    /// so this compiles to a copy.
    fn from(decision: Decision) -> Self {
        match decision {
            Decision::Unknown => Label::Unknown,
            Decision::F => Label::F,
            Decision::I => Label::I,
            Decision::U => Label::U,
            Decision::S => Label::S,
            Decision::M => Label::M,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decisions_keep_their_code_and_name() {
        for decision in [
            Decision::Unknown,
            Decision::F,
            Decision::I,
            Decision::U,
            Decision::S,
            Decision::M,
        ] {
            let label = Label::from(decision);
            assert_eq!(label as u8, decision as u8);
            assert_eq!(label.name(), decision.name());
        }
        for (code, label) in Label::ALL.iter().enumerate() {
            assert_eq!(Label::from_code(code as u8), Some(*label));
        }
        assert_eq!(Label::from_code(7), Some(Label::Edge));
        assert_eq!(Label::from_code(8), None);
    }
}
