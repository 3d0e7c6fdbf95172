//! Belief functions (Dempster–Shafer theory) on small frames of discernment.
//!
//! This crate computes what SPEC §1 lists: combination rules (conjunctive, Dempster, disjunctive,
//! Yager, Dubois–Prade), discounting (classical, contextual, class-rate), belief, plausibility,
//! commonality and implicability functions and their inverses, the pignistic probability,
//! refinings and specialisations. The evidential grids of `evigrid` use it as their reference:
//! each grid cell holds one mass function on a frame of two or five classes.
//!
//! **Key design decision**: a frame has at most eight elements, so a subset is a `u8` bitmask
//! ([`Set`]) and a mass function is a dense array of `2^n` values indexed by that mask ([`Mass`]).
//! Set operations are single instructions, combinations are double loops over two short arrays,
//! and the transforms are the fast zeta/Möbius butterflies in `O(n·2^n)`. Everything is generic
//! over [`Real`] (`f32` for grids, `f64` for the calculator), has no dependencies beyond `std`,
//! and returns a [`BeliefError`] on bad input: no panic, no NaN.
//!
//! Interchangeable rules are values implementing one trait: [`Combination`] for the rules,
//! [`Discounting`] for the discounting modes.
//!
//! # Example
//!
//! The paper's Table I (Kurdej et al. 2013), with the corrected conjunctive and Dempster rows of
//! SPEC §1:
//!
//! ```
//! use belief::{ClassicalDiscount, Combination, Conjunctive, Dempster, Discounting, Disjunctive, Frame, Mass};
//!
//! let frame = Frame::new(["a", "b"])?;
//! let m1 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
//! let m2 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.7), (&["b"], 0.1), (&["a", "b"], 0.2)])?;
//! let close = |m: &Mass<f64>, want: [f64; 4]| {
//!     m.values().iter().zip(want).all(|(x, y)| (x - y).abs() < 1e-3)
//! };
//!
//! //                                   ∅     a      b      Ω
//! assert!(close(&Conjunctive.combine(&m1, &m2)?, [0.44, 0.32, 0.20, 0.04]));
//! assert!(close(&Dempster.combine(&m1, &m2)?, [0.0, 0.571, 0.357, 0.071]));
//! assert!(close(&Disjunctive.combine(&m1, &m2)?, [0.0, 0.14, 0.06, 0.8]));
//! assert!(close(&ClassicalDiscount::new(0.1)?.discount(&m1)?, [0.0, 0.18, 0.54, 0.28]));
//! let betp = m1.pignistic()?;
//! assert!((betp[0] - 0.3).abs() < 1e-12 && (betp[1] - 0.7).abs() < 1e-12);
//! # Ok::<(), belief::BeliefError>(())
//! ```
//!
//! # References
//!
//! SPEC §1 (`../shared/SPEC.md`); paper eq 1-15 (M. Kurdej, J. Moras, V. Cherfaoui, P. Bonnifait,
//! "Enhancing Mobile Object Classification Using Geo-referenced Maps and Evidential Grids", 2013).
#![deny(missing_docs)]

mod combination;
mod discounting;
mod error;
mod frame;
mod mass;
mod pignistic;
mod real;
mod refining;
mod specialisation;
mod transform;

#[cfg(test)]
mod testing;

/// Combination rules and the trait they share.
pub use combination::{Combination, Conjunctive, Dempster, Disjunctive, DuboisPrade, Yager};
/// Discounting modes and the trait they share.
pub use discounting::{
    ClassRateDiscount, ClassicalDiscount, ContextualDiscount, Discounting, SetRate,
};
/// The error type.
pub use error::BeliefError;
/// Frames and subsets.
pub use frame::{Frame, Set};
/// Mass functions and their validity check.
pub use mass::{Mass, check_masses};
/// The float types.
pub use real::Real;
/// Refining between frames.
pub use refining::Refining;
/// Specialisation by a matrix or by the fast rule.
pub use specialisation::{Specialisation, specialise_without};
/// Set functions and the fast zeta/Möbius transforms.
pub use transform::{SetFunction, mobius_subsets, mobius_supersets, zeta_subsets, zeta_supersets};
