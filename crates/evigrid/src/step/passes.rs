//! The mass transfers the step is made of, each on a block of [`BLOCK`] cells at once.
//!
//! A block holds one lane array per focal set of Ω_PG (`m[set][cell]`, set = bitmask). Every pass
//! is a loop over sets outside and cells inside, so the inner loop is a straight-line operation
//! on `BLOCK` floats that the compiler vectorises; per-cell choices (map context, ζ) enter as
//! per-cell factors, never as branches.
//!
//! Two elementary passes suffice for every stage, because each stage is a combination with a
//! mass function whose focal sets differ from Ω by one class:
//! - [`remove_class`]: conjunctive combination with the simple mass function "s on Ω∖{θ}, 1 − s on
//!   Ω". For B ⊆ Ω: (m ∩ m_s)(B) = (1 − s)·m(B) + s·Σ_{A∖{θ} = B} m(A), i.e. every A ∋ θ gives
//!   s·m(A) to A∖{θ}. With s ∈ {0, 1} per cell it restricts to Ω∖{θ} or does nothing.
//! - [`add_class`]: disjunctive combination with "1 − α on ∅, α on {θ}" (one Mercier context).
//!   (m ∪ m_α)(B) = (1 − α)·m(B) + α·Σ_{A ∪ {θ} = B} m(A): every A ∌ θ gives α·m(A) to A ∪ {θ}.

use crate::grids::{N_SETS, OMEGA};

/// Cells per block: 16 lanes of f32 are four SSE or two AVX registers, and a block of 32 planes
/// (2 KiB) and its copy stay in L1.
pub(crate) const BLOCK: usize = 16;

/// One value per cell of a block.
pub(crate) type Lanes = [f32; BLOCK];

/// The 32 masses of every cell of a block: `m[set][cell]`.
pub(crate) type BlockMasses = [Lanes; N_SETS];

/// Below this, a mass left to rescale is treated as zero (f32 cannot resolve it from rounding).
pub(crate) const TOO_SMALL_TO_RESCALE: f32 = 1e-6;

/// Gives `moved[cell] = s[cell]·m[from][cell]` from set `from` to set `to` (`to < from`
/// or `to > from`, never equal).
#[inline(always)]
fn transfer(m: &mut BlockMasses, from: usize, to: usize, s: &Lanes) {
    let source = m[from];
    let mut kept = source;
    let target = &mut m[to];
    for i in 0..BLOCK {
        let moved = s[i] * source[i];
        target[i] += moved;
        kept[i] = source[i] - moved;
    }
    m[from] = kept;
}

/// m ∩ "s on Ω∖{θ}, 1 − s on Ω": every A ∋ θ gives s·m(A) to A∖{θ} (`class_bit` = θ's bit).
///
/// Used for the map prior's restriction (s ∈ {0, 1}), for the refined sensor's O
/// (θ = F, s = 1), and for the specialisation (θ = M, s = ζ, eq 28-29, whose matrix is exactly
/// this combination).
#[inline(always)]
pub(crate) fn remove_class(m: &mut BlockMasses, class_bit: usize, s: &Lanes) {
    for set in 0..N_SETS {
        if set & class_bit != 0 {
            transfer(m, set, set ^ class_bit, s);
        }
    }
}

/// m ∪ "1 − α on ∅, α on {θ}": every A ∌ θ gives α·m(A) to A ∪ {θ} (Mercier contextual
/// discounting with context {θ}).
#[inline(always)]
pub(crate) fn add_class(m: &mut BlockMasses, class_bit: usize, alpha: f32) {
    let s = [alpha; BLOCK];
    // Sources lack θ and targets have it, so no set is both and the order does not matter.
    for set in 0..N_SETS {
        if set & class_bit == 0 {
            transfer(m, set, set | class_bit, &s);
        }
    }
}

/// Discounting by a rate per focal set: every A ≠ Ω gives `rate[A]`·m(A) to Ω (eq 13-14 when all
/// rates are equal; the class-rate discounting otherwise).
#[inline(always)]
pub(crate) fn discount_to_omega(m: &mut BlockMasses, rate_per_set: &[f32; N_SETS]) {
    for (set, &rate) in rate_per_set.iter().enumerate().take(OMEGA) {
        transfer(m, set, OMEGA, &[rate; BLOCK]);
    }
}

/// Σ of m(A) over the sets A for which `select(A)` holds, per cell, in increasing set order (so
/// that the result does not depend on how cells are grouped).
#[inline(always)]
pub(crate) fn sum_sets(m: &BlockMasses, select: impl Fn(usize) -> bool) -> Lanes {
    let mut total = [0.0; BLOCK];
    for (set, plane) in m.iter().enumerate() {
        if select(set) {
            for i in 0..BLOCK {
                total[i] += plane[i];
            }
        }
    }
    total
}

/// Σ of m(A) over the non-empty A ⊆ {I, U, S, M}: m(O) as eq 22-23 define it.
#[inline(always)]
pub(crate) fn occupied_mass(m: &BlockMasses) -> Lanes {
    sum_sets(m, |set| set != 0 && set & crate::grids::class::F == 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grids::class::{F, I, M, O, S, U};

    fn block_of(cell: &[(usize, f32)]) -> BlockMasses {
        let mut m = [[0.0; BLOCK]; N_SETS];
        for &(set, mass) in cell {
            m[set] = [mass; BLOCK];
        }
        m
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() < 1e-6
    }

    #[test]
    fn remove_class_moves_a_fraction_to_the_set_without_the_class() {
        // m({S,M}) = 0.6, m({M}) = 0.1, m(Ω) = 0.3, s = 0.5 on class M:
        // {S,M} → {S}: 0.3 stays, 0.3 moves; {M} → ∅: 0.05 each; Ω → {F,I,U,S}: 0.15 each.
        let mut m = block_of(&[(S | M, 0.6), (M, 0.1), (OMEGA, 0.3)]);
        remove_class(&mut m, M, &[0.5; BLOCK]);
        assert!(close(m[S | M][0], 0.3) && close(m[S][0], 0.3));
        assert!(close(m[M][0], 0.05) && close(m[0][0], 0.05));
        assert!(close(m[OMEGA][0], 0.15) && close(m[OMEGA ^ M][0], 0.15));
    }

    #[test]
    fn remove_class_factor_is_per_cell() {
        let mut m = block_of(&[(F | I, 1.0)]);
        let mut s = [0.0; BLOCK];
        s[3] = 1.0;
        remove_class(&mut m, F, &s);
        assert_eq!((m[F | I][0], m[I][0]), (1.0, 0.0));
        assert_eq!((m[F | I][3], m[I][3]), (0.0, 1.0));
    }

    #[test]
    fn add_class_is_a_mercier_context() {
        // Mercier et al. 2008 vector (belief-vectors.json, frame a,h,r mapped to F,I,U):
        // m(a) = m(r) = 0.5, context {h} at α = 0.6 → a 0.2, {a,h} 0.3, r 0.2, {h,r} 0.3.
        let mut m = block_of(&[(F, 0.5), (U, 0.5)]);
        add_class(&mut m, I, 0.6);
        assert!(close(m[F][0], 0.2) && close(m[F | I][0], 0.3));
        assert!(close(m[U][0], 0.2) && close(m[I | U][0], 0.3));
    }

    #[test]
    fn discount_to_omega_keeps_the_complement_of_each_rate() {
        // m(F) = 0.5 at rate 0.2 keeps 0.4; m(O) = 0.5 at rate 0.6 keeps 0.2; Ω gets 0.1 + 0.3.
        let mut m = block_of(&[(F, 0.5), (O, 0.5)]);
        let mut rate = [0.0; N_SETS];
        rate[F] = 0.2;
        rate[O] = 0.6;
        discount_to_omega(&mut m, &rate);
        assert!(close(m[F][0], 0.4) && close(m[O][0], 0.2) && close(m[OMEGA][0], 0.4));
    }

    #[test]
    fn occupied_mass_sums_nonempty_subsets_of_o() {
        let m = block_of(&[
            (0, 0.05),
            (F, 0.1),
            (I, 0.2),
            (S | M, 0.3),
            (F | M, 0.15),
            (O, 0.2),
        ]);
        assert!(close(occupied_mass(&m)[0], 0.7));
    }
}
