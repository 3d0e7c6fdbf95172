//! The one label type of a cell, for truth and for predictions alike: evigrid's [`Label`],
//! re-exported so that the simulator's truth, the method's decisions and the baselines'
//! predictions share one numbering (0 unknown, 1–5 F, I, U, S, M, 6 O).
//!
//! Truth holds `Unknown` (not scored), one of [`Label::CLASSES`] or `Edge` (the boundary band of
//! a building, see [`crate::truth`]); O is a prediction of the two-class baselines only.
//!
//! ```
//! use sim::Label;
//! assert_eq!(Label::from_code(4), Some(Label::S));
//! assert_eq!(Label::O.name(), "O");
//! ```

pub use evigrid::Label;
