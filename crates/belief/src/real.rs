//! The floating-point types masses are stored in.
//!
//! The grids keep millions of cells and store `f32`; the calculator and the reference checks use
//! `f64`. Every operation of this crate is written once, generic over [`Real`], which is
//! implemented for exactly these two types (the trait is sealed so that methods can be added
//! without breaking anyone).

use std::fmt::{Debug, Display};
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Sub, SubAssign};

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// A floating-point type masses can be stored in: `f32` or `f64`.
pub trait Real:
    sealed::Sealed
    + Copy
    + Default
    + PartialEq
    + PartialOrd
    + Debug
    + Display
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + Sum
{
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// How far the sum of a mass function may be from one and still be accepted, and how far
    /// below zero a value computed by an inverse transform may fall from rounding alone.
    ///
    /// `1e-9` for `f64` (SPEC §1); `1e-5` for `f32`, whose machine epsilon is about `1.2e-7` and
    /// whose sums over 32 focal sets lose a few units of that.
    const TOLERANCE: Self;

    /// Converts from `f64`, rounding to the nearest value of `Self`.
    fn from_f64(value: f64) -> Self;
    /// Converts to `f64` exactly.
    fn to_f64(self) -> f64;
    /// `true` unless the value is NaN or infinite.
    fn is_finite(self) -> bool;
    /// The absolute value.
    fn abs(self) -> Self;
}

impl Real for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const TOLERANCE: Self = 1e-9;

    fn from_f64(value: f64) -> Self {
        value
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    fn abs(self) -> Self {
        f64::abs(self)
    }
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const TOLERANCE: Self = 1e-5;

    fn from_f64(value: f64) -> Self {
        // Rounding to the nearest f32 is the documented intent of this conversion.
        value as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    fn abs(self) -> Self {
        f32::abs(self)
    }
}

/// `1 / count` for a set cardinality, exact in both types for the cardinalities of frames of up to
/// 8 elements up to the rounding of the division itself.
pub(crate) fn reciprocal<R: Real>(count: u32) -> R {
    R::ONE / R::from_f64(f64::from(count))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_round_trip_through_f64() {
        assert_eq!(<f64 as Real>::from_f64(0.1).to_f64(), 0.1);
        // 0.1 is not representable in f32: the round trip lands on the nearest f32.
        assert_eq!(<f32 as Real>::from_f64(0.1), 0.1_f32);
        assert_eq!(reciprocal::<f64>(4), 0.25);
        assert!(!<f64 as Real>::is_finite(f64::NAN));
    }
}
