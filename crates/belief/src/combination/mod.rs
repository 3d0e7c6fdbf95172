//! Combination rules: each rule is a value implementing [`Combination`].
//!
//! Rules are interchangeable, so code that fuses sources takes `&impl Combination<R>` (or
//! `&dyn Combination<R>`) and the caller picks `Dempster`, `Yager`, … All rules check that their
//! operands share a frame.

mod conjunctive;
mod dempster;
mod disjunctive;
mod dubois_prade;
mod yager;

pub use conjunctive::Conjunctive;
pub use dempster::Dempster;
pub use disjunctive::Disjunctive;
pub use dubois_prade::DuboisPrade;
pub use yager::Yager;

use crate::{BeliefError, Frame, Mass, Real};

/// A rule that combines mass functions on the same frame.
///
/// # Examples
///
/// ```
/// use belief::{Combination, Conjunctive, Dempster, Frame, Mass, Yager};
///
/// let frame = Frame::new(["a", "b"])?;
/// let m1 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.2), (&["b"], 0.6), (&["a", "b"], 0.2)])?;
/// let m2 = Mass::<f64>::from_named(&frame, &[(&["a"], 0.7), (&["b"], 0.1), (&["a", "b"], 0.2)])?;
///
/// // Any rule, chosen at run time.
/// let rules: [&dyn Combination<f64>; 3] = [&Conjunctive, &Dempster, &Yager];
/// let conflicts: Vec<f64> = rules
///     .iter()
///     .map(|rule| rule.combine(&m1, &m2).map(|m| m.conflict()))
///     .collect::<Result<_, _>>()?;
/// // K = 0.2·0.1 + 0.6·0.7 = 0.44 stays on ∅ only under the conjunctive rule.
/// assert!((conflicts[0] - 0.44).abs() < 1e-12);
/// assert_eq!(&conflicts[1..], &[0.0, 0.0]);
/// # Ok::<(), belief::BeliefError>(())
/// ```
pub trait Combination<R: Real> {
    /// Combines two mass functions.
    ///
    /// # Errors
    ///
    /// [`BeliefError::MismatchedFrames`] if the frames differ; a rule may add its own (Dempster:
    /// [`BeliefError::TotalConflict`]).
    fn combine(&self, a: &Mass<R>, b: &Mass<R>) -> Result<Mass<R>, BeliefError>;

    /// Combines any number of mass functions. By default this folds [`Combination::combine`] from
    /// left to right, which is the rule itself for associative rules; rules that are not
    /// associative (Yager, Dubois–Prade) use their n-ary form instead.
    ///
    /// # Errors
    ///
    /// [`BeliefError::NoInputs`] for an empty slice, otherwise as [`Combination::combine`].
    fn combine_all(&self, masses: &[Mass<R>]) -> Result<Mass<R>, BeliefError> {
        let (first, rest) = masses.split_first().ok_or(BeliefError::NoInputs)?;
        rest.iter()
            .try_fold(first.clone(), |acc, m| self.combine(&acc, m))
    }
}

/// The common frame of all `masses`.
fn common_frame<R: Real>(masses: &[Mass<R>]) -> Result<&Frame, BeliefError> {
    let (first, rest) = masses.split_first().ok_or(BeliefError::NoInputs)?;
    for m in rest {
        first.check_same_frame(m)?;
    }
    Ok(first.frame())
}

/// `(a ∩ b)(A) = Σ_{B∩C=A} a(B)·b(C)` over dense arrays of the same length (eq 8).
fn conjunctive_values<R: Real>(a: &[R], b: &[R]) -> Vec<R> {
    combine_by(a, b, |x, y| x & y)
}

/// `(a ∪ b)(A) = Σ_{B∪C=A} a(B)·b(C)` over dense arrays of the same length (eq 12).
fn disjunctive_values<R: Real>(a: &[R], b: &[R]) -> Vec<R> {
    combine_by(a, b, |x, y| x | y)
}

/// The double sum over pairs of focal sets, sending `a(B)·b(C)` to `set_op(B, C)`. Zero masses
/// are skipped, so sparse mass functions (the usual case) cost far less than `4^n`.
fn combine_by<R: Real>(a: &[R], b: &[R], set_op: impl Fn(usize, usize) -> usize) -> Vec<R> {
    let mut out = vec![R::ZERO; a.len()];
    // The focal sets of `b` once, so the inner loop runs over them only, without a branch.
    let b_focal: Vec<(usize, R)> = b
        .iter()
        .enumerate()
        .filter(|&(_, &m)| m != R::ZERO)
        .map(|(y, &m)| (y, m))
        .collect();
    for (x, &ma) in a.iter().enumerate().filter(|&(_, &m)| m != R::ZERO) {
        for &(y, mb) in &b_focal {
            out[set_op(x, y)] += ma * mb;
        }
    }
    out
}

/// The conjunctive combination of all `masses` as a dense array, with their common frame.
fn conjunctive_all<R: Real>(masses: &[Mass<R>]) -> Result<(Frame, Vec<R>), BeliefError> {
    let frame = common_frame(masses)?.clone();
    let (first, rest) = masses.split_first().ok_or(BeliefError::NoInputs)?;
    let values = rest.iter().fold(first.values().to_vec(), |acc, m| {
        conjunctive_values(&acc, m.values())
    });
    Ok((frame, values))
}
