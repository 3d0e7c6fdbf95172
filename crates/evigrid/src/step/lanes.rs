//! Helpers over the lanes of a block: reductions written so that the compiler vectorises them,
//! and iteration over the bits of a plane mask.

use super::passes::Lanes;
use crate::grids::PlaneBits;

/// Whether `test` holds for any lane. A fold with `|`, not `Iterator::any`: no early exit, so
/// the compiler vectorises it.
#[inline(always)]
pub(super) fn any_lane<T: Copy, const N: usize>(lanes: &[T; N], test: impl Fn(T) -> bool) -> bool {
    lanes.iter().fold(false, |any, &x| any | test(x))
}

/// Calls `f` with the index of every set bit of `bits`, lowest first.
#[inline(always)]
pub(super) fn for_each_bit(mut bits: PlaneBits, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// Whether any lane is not +0 (a -0 counts): the bits OR-ed eight lanes at a time, which the
/// compiler keeps in one vector register (a plain fold became 64 scalar ORs).
#[inline(always)]
pub(super) fn any_bits(lanes: &Lanes) -> bool {
    let mut bits = [0u32; 8];
    for chunk in lanes.chunks_exact(8) {
        for (acc, x) in bits.iter_mut().zip(chunk) {
            *acc |= x.to_bits();
        }
    }
    bits.iter().fold(0, |all, &b| all | b) != 0
}

/// Flags set.
#[inline(always)]
pub(super) fn count(flags: &[u8]) -> u64 {
    flags.iter().map(|&f| u64::from(f)).sum()
}

/// Flags set in both `flags` and `mask`.
#[inline(always)]
pub(super) fn count_where(flags: &[u8], mask: &[u8]) -> u64 {
    flags
        .iter()
        .zip(mask)
        .map(|(&f, &m)| u64::from(f & m))
        .sum()
}
