//! The one label type of a cell: what the method decides, what truth says, what a baseline
//! predicts.
//!
//! The codes are written to files (the occupancy export's `classes`, the evaluation's label
//! rasters), so they are fixed: 0 unknown, then F, I, U, S, M in the frame order of Ω_PG (code =
//! class index + 1), then O = 6 and Edge = 7. O, occupied with its class not resolved, is the
//! occupied element of the sensor's frame Ω_SG = {F, O}: the method never decides it (SPEC §6
//! decides among the five classes of Ω_PG) and truth never holds it; a two-class baseline
//! predicts it of an occupied cell that is not moving. Edge is truth only: a cell a building
//! covers in part but not at its centre (the boundary band, see `docs/evaluation.md`).
//!
//! ```
//! use evigrid::Label;
//! assert_eq!(Label::from_class(3), Label::S);
//! assert_eq!(Label::S as u8, 4);
//! assert_eq!(Label::from_code(6), Some(Label::O));
//! assert_eq!(Label::O.name(), "O");
//! ```

use serde::{Deserialize, Serialize};

/// The class of a cell. As a decision of the method: `Unknown` or one of F, I, U, S, M. As
/// truth: one of F, I, U, S, M, `Edge` (the boundary band of a building), or `Unknown` for a
/// cell not to be scored. As a prediction of a two-class baseline: also O.
#[repr(u8)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Label {
    /// Never observed, too little evidence (m(Ω) above the threshold) or total conflict; in
    /// truth, a cell excluded from scoring (under the ego vehicle).
    #[default]
    Unknown = 0,
    /// Free space.
    F = 1,
    /// Mapped infrastructure (buildings present in the map).
    I = 2,
    /// Unmapped infrastructure (street furniture, buildings missing from the map).
    U = 3,
    /// Stopped object.
    S = 4,
    /// Moving object.
    M = 5,
    /// Occupied and static, class not resolved: predicted by two-class baselines only, never
    /// decided by the method nor held by truth.
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

    /// The five classes of Ω_PG, in frame order: what the method decides and truth holds.
    pub const CLASSES: [Label; 5] = [Label::F, Label::I, Label::U, Label::S, Label::M];

    /// The label of class `k` of Ω_PG in frame order (0 = F … 4 = M); `Unknown` otherwise.
    pub fn from_class(k: usize) -> Label {
        Self::CLASSES.get(k).copied().unwrap_or(Label::Unknown)
    }

    /// The label of code `code` (its discriminant), if any.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.get(usize::from(code)).copied()
    }

    /// Short name: `unknown`, `edge`, or the class letter `F`, `I`, `U`, `S`, `M`, `O`.
    pub fn name(self) -> &'static str {
        ["unknown", "F", "I", "U", "S", "M", "O", "edge"][self as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_fixed_and_round_trip() {
        // Written to files: these numbers must not change.
        let codes: Vec<u8> = Label::ALL.iter().map(|&l| l as u8).collect();
        assert_eq!(codes, [0, 1, 2, 3, 4, 5, 6, 7]);
        for (code, label) in Label::ALL.iter().enumerate() {
            assert_eq!(Label::from_code(code as u8), Some(*label));
        }
        assert_eq!(Label::from_code(7), Some(Label::Edge));
        assert_eq!(Label::from_code(8), None);
        for (k, class) in Label::CLASSES.iter().enumerate() {
            assert_eq!(Label::from_class(k), *class);
            assert_eq!(*class as usize, k + 1);
            assert_eq!(class.name(), crate::grids::class::LETTERS[k].to_string());
        }
        assert_eq!(Label::from_class(5), Label::Unknown);
        // The method decides through `from_class`: never O.
        assert!((0..64).all(|k| !matches!(Label::from_class(k), Label::O | Label::Edge)));
    }
}
