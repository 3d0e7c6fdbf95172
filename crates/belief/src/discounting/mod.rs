//! Discounting: weakening a mass function that may be out of date or unreliable.
//!
//! Each mode is a value implementing [`Discounting`], so the fusion step can hold any of them
//! (SPEC §5 step 3): [`ClassicalDiscount`] (one rate), [`ContextualDiscount`] (Mercier et al.,
//! mass moves to supersets) and [`ClassRateDiscount`] (one rate per class, mass moves to Ω).

mod class_rates;
mod classical;
mod contextual;

pub use class_rates::{ClassRateDiscount, SetRate};
pub use classical::ClassicalDiscount;
pub use contextual::ContextualDiscount;

use crate::{BeliefError, Mass, Real};

/// A way of discounting a mass function.
///
/// # Examples
///
/// ```
/// use belief::{ClassicalDiscount, ContextualDiscount, Discounting, Frame, Mass};
///
/// let frame = Frame::new(["a", "h", "r"])?;
/// let m = Mass::<f64>::from_named(&frame, &[(&["a"], 0.5), (&["r"], 0.5)])?;
/// let modes: [Box<dyn Discounting<f64>>; 2] = [
///     Box::new(ClassicalDiscount::new(0.4)?),
///     Box::new(ContextualDiscount::new([(frame.omega(), 0.4)])?),
/// ];
/// // The single context Ω is classical discounting: 0.4 of every mass goes to Ω.
/// for mode in &modes {
///     assert!((mode.discount(&m)?.get(frame.omega()) - 0.4).abs() < 1e-12);
/// }
/// # Ok::<(), belief::BeliefError>(())
/// ```
pub trait Discounting<R: Real> {
    /// The discounted mass function.
    ///
    /// # Errors
    ///
    /// When the mode's parameters do not fit the frame of `m` (a context set outside it, a number
    /// of class rates other than its number of elements).
    fn discount(&self, m: &Mass<R>) -> Result<Mass<R>, BeliefError>;
}

/// Checks that a rate lies in `[0, 1]` (and is not NaN).
pub(crate) fn check_rate<R: Real>(rate: R) -> Result<(), BeliefError> {
    if (R::ZERO..=R::ONE).contains(&rate) {
        Ok(())
    } else {
        Err(BeliefError::RateOutOfRange {
            value: rate.to_f64(),
        })
    }
}
