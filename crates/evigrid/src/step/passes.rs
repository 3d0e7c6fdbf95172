//! The mass transfers the step is made of, each on a block of [`BLOCK`] cells at once.
//!
//! A block holds one lane array per focal set of Ω_PG (`m[set][cell]`, set = bitmask). Every pass
//! is a loop over sets outside and cells inside, so the inner loop is a straight-line operation
//! on `BLOCK` floats that the compiler vectorises; per-cell choices (map context, ζ) enter as
//! per-cell factors, never as branches.
//!
//! Every stage is a combination with a mass function of one or two focal sets, and each is one
//! kind of pass, a transfer of a per-cell share of m(A) from each source set A to one target:
//! - [`restrict_to`]: conjunctive combination with "s on G, 1 − s on Ω". For B ⊆ Ω:
//!   (m ∩ m_s)(B) = (1 − s)·m(B) + s·Σ_{A ∩ G = B} m(A): every A ⊄ G gives s·m(A) to A ∩ G.
//!   With G = Ω∖{θ} ([`remove_class`]) it removes one class: the specialisation (θ = M, s = ζ,
//!   eq 28-29, whose matrix is exactly this combination); with G the map context's focal set and
//!   s = β it is the map prior (eq 34-38).
//! - [`add_class`]: disjunctive combination with "1 − α on ∅, α on {θ}" (one Mercier context).
//!   (m ∪ m_α)(B) = (1 − α)·m(B) + α·Σ_{A ∪ {θ} = B} m(A): every A ∌ θ gives α·m(A) to A ∪ {θ}.
//! - [`discount_to_omega`]: every A ≠ Ω gives a rate of its mass to Ω.
//!
//! The refined sensor r(SG) has three focal sets and is combined in one pass of its own
//! (`combine_with_refined_sensor` in the parent module).

use crate::grids::{N_SETS, OMEGA};

/// Cells per block: 16 lanes of f32 are four SSE or two AVX registers, and a block of 32 planes
/// (2 KiB) and its copy stay in L1.
pub(crate) const BLOCK: usize = 32;

/// One value per cell of a block.
pub(crate) type Lanes = [f32; BLOCK];

/// The 32 masses of every cell of a block: `m[set][cell]`.
pub(crate) type BlockMasses = [Lanes; N_SETS];

/// Below this, a mass left to rescale is treated as zero (f32 cannot resolve it from rounding).
pub(crate) const TOO_SMALL_TO_RESCALE: f32 = 1e-6;

/// Gives `moved[cell] = s[cell]·m[from][cell]` from set `from` to set `to` (never equal).
#[inline(always)]
fn transfer(m: &mut BlockMasses, from: usize, to: usize, s: &Lanes) {
    // Local copies, not two borrows into `m`: the compiler then knows that nothing aliases and
    // keeps the lanes in vector registers.
    let (mut source, mut target, share) = (m[from], m[to], *s);
    for i in 0..BLOCK {
        let moved = share[i] * source[i];
        target[i] += moved;
        source[i] -= moved;
    }
    m[from] = source;
    m[to] = target;
}

/// m ∩ "s on Ω∖{θ}, 1 − s on Ω": every A ∋ θ gives s·m(A) to A∖{θ} (`class_bit` = θ's bit).
///
/// The specialisation of eq 28-29 with θ = M and s = ζ.
#[inline(always)]
pub(crate) fn remove_class(m: &mut BlockMasses, class_bit: usize, s: &Lanes) {
    restrict_to(m, OMEGA ^ class_bit, s);
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
///
/// What Ω gains is summed in four partial sums, so that 31 additions are four short dependency
/// chains instead of one long one.
#[inline(always)]
pub(crate) fn discount_to_omega(m: &mut BlockMasses, rate_per_set: &[f32; N_SETS]) {
    let mut gained = [[0.0; BLOCK]; 4];
    for (set, &rate) in rate_per_set.iter().enumerate().take(OMEGA) {
        let plane = &mut m[set];
        let partial = &mut gained[set % 4];
        for i in 0..BLOCK {
            let moved = rate * plane[i];
            plane[i] -= moved;
            partial[i] += moved;
        }
    }
    for i in 0..BLOCK {
        m[OMEGA][i] += (gained[0][i] + gained[1][i]) + (gained[2][i] + gained[3][i]);
    }
}

/// m ∩ "s on G, 1 − s on Ω" for a focal set `g` (`s` per cell): every A ⊄ G gives s·m(A) to
/// A ∩ G (possibly ∅).
///
/// This is the map prior's half of SG' = r(SG) ∩ GG (eq 21, 34-38): (m ∩ m_GG)(B) =
/// (1 − β)·m(B) + β·Σ_{A ∩ G = B} m(A). Sources (A ⊄ G) and targets (A ∩ G ⊆ G) never coincide,
/// so one transfer per source set, in any order, is the whole combination; a cell whose `s` is 0
/// (another map context) is left exactly as it was.
#[inline(always)]
pub(crate) fn restrict_to(m: &mut BlockMasses, g: usize, s: &Lanes) {
    for set in 0..N_SETS {
        let target = set & g;
        if target != set {
            transfer(m, set, target, s);
        }
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
    fn restrict_to_moves_the_share_s_to_the_intersection_with_g() {
        // G = {F,S,M} (road), s = 0.8: {I,S} 0.5 → {S} 0.4; Ω 0.3 → G 0.24; {I} 0.2 → ∅ 0.16;
        // what stays is 1 − s of each source; {S} and G (⊆ G) do not move.
        let g = F | S | M;
        let mut m = block_of(&[(I | S, 0.5), (OMEGA, 0.3), (I, 0.2)]);
        let mut s = [0.8; BLOCK];
        s[1] = 0.0; // another context: untouched
        restrict_to(&mut m, g, &s);
        assert!(close(m[S][0], 0.4) && close(m[I | S][0], 0.1));
        assert!(close(m[g][0], 0.24) && close(m[OMEGA][0], 0.06));
        assert!(close(m[0][0], 0.16) && close(m[I][0], 0.04));
        assert_eq!((m[I | S][1], m[OMEGA][1], m[I][1]), (0.5, 0.3, 0.2));
        assert_eq!((m[S][1], m[g][1], m[0][1]), (0.0, 0.0, 0.0));
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
