//! Test helpers shared by the unit tests: random mass functions and comparisons.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::ops::RangeInclusive;

use proptest::prelude::*;

use crate::{Frame, Mass, check_masses};

/// The frame `{e0, …, e(n−1)}`; equal `n` gives equal frames.
pub(crate) fn frame_of(n: usize) -> Frame {
    Frame::new((0..n).map(|k| format!("e{k}"))).expect("n ≤ 8")
}

/// Weights for the `2^n` subsets: about half of them zero (sparse, as real masses are), the
/// empty set positive only in about half of the cases (so normal and subnormal masses both occur).
fn arb_values(n: usize) -> impl Strategy<Value = Vec<f64>> {
    let weight = prop_oneof![Just(0.0), 0.0..1.0_f64];
    (prop::collection::vec(weight, 1 << n), any::<bool>()).prop_map(|(mut weights, normal)| {
        if normal {
            weights[0] = 0.0;
        }
        let sum: f64 = weights.iter().sum();
        if sum == 0.0 {
            let last = weights.len() - 1;
            weights[last] = 1.0;
            return weights;
        }
        weights.iter().map(|w| w / sum).collect()
    })
}

fn mass_from(n: usize, values: Vec<f64>) -> Mass<f64> {
    Mass::from_values(&frame_of(n), values).expect("normalised weights")
}

/// A random mass function on a frame of `n ∈ sizes` elements.
pub(crate) fn arb_mass(sizes: RangeInclusive<usize>) -> impl Strategy<Value = Mass<f64>> {
    sizes.prop_flat_map(|n| arb_values(n).prop_map(move |v| mass_from(n, v)))
}

/// Two random mass functions on the same frame.
pub(crate) fn arb_mass_pair(
    sizes: RangeInclusive<usize>,
) -> impl Strategy<Value = (Mass<f64>, Mass<f64>)> {
    sizes.prop_flat_map(|n| {
        (arb_values(n), arb_values(n)).prop_map(move |(a, b)| (mass_from(n, a), mass_from(n, b)))
    })
}

/// Three random mass functions on the same frame.
pub(crate) fn arb_mass_triple(
    sizes: RangeInclusive<usize>,
) -> impl Strategy<Value = (Mass<f64>, Mass<f64>, Mass<f64>)> {
    sizes.prop_flat_map(|n| {
        (arb_values(n), arb_values(n), arb_values(n))
            .prop_map(move |(a, b, c)| (mass_from(n, a), mass_from(n, b), mass_from(n, c)))
    })
}

/// Panics unless the two arrays have the same length and agree within `epsilon` everywhere.
pub(crate) fn assert_close(got: &[f64], want: &[f64], epsilon: f64) {
    assert_eq!(got.len(), want.len(), "lengths differ: {got:?} vs {want:?}");
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= epsilon,
            "index {k}: {g} vs {w} (epsilon {epsilon})\n got  {got:?}\n want {want:?}"
        );
    }
}

/// Panics unless `m` passes the validity check of fresh input (non-negative, sum one).
pub(crate) fn assert_valid(m: &Mass<f64>) {
    assert_eq!(check_masses(m.values()), Ok(()), "{m:?}");
}
