//! The mass transfers the step is made of, each on a block of [`BLOCK`] cells at once.
//!
//! A block holds one lane array per focal set of Ω_PG (`m[set][cell]`, set = bitmask). Every pass
//! is a loop over sets outside and cells inside, so the inner loop is a straight-line operation
//! on `BLOCK` floats that the compiler vectorises; per-cell choices (map context, ζ) enter as
//! per-cell factors, never as branches.
//!
//! Every stage is a combination with a mass function of one or two focal sets, and each is one
//! kind of pass, a transfer of a per-cell share of m(A) from each source set A to one target:
//! - `restrict_to` ([`Restriction`]): conjunctive combination with "s on G, 1 − s on Ω". For B ⊆ Ω:
//!   (m ∩ m_s)(B) = (1 − s)·m(B) + s·Σ_{A ∩ G = B} m(A): every A ⊄ G gives s·m(A) to A ∩ G.
//!   With G = Ω∖{θ} (`remove_class`) it removes one class: the specialisation (θ = M, s = ζ,
//!   eq 28-29, whose matrix is exactly this combination); with G the map context's focal set and
//!   s = β it is the map prior (eq 34-38).
//! - [`add_class`]: disjunctive combination with "1 − α on ∅, α on {θ}" (one Mercier context).
//!   (m ∪ m_α)(B) = (1 − α)·m(B) + α·Σ_{A ∪ {θ} = B} m(A): every A ∌ θ gives α·m(A) to A ∪ {θ}.
//!
//! Discounting to Ω and the refined sensor r(SG), whose three focal sets pair each A ∌ F with
//! A ∪ {F}, make one pass of their own (`discount_and_combine_with_refined_sensor` in
//! `stages`).

use crate::grids::{N_SETS, OMEGA};

/// Cells per block: 64 lanes of f32 are eight AVX registers per plane, so each pass's loop
/// overhead is spread over enough work, and a block of 32 planes (8 KiB) with its scratch stays
/// in L1. (Measured with `evigrid bench`: 32 was as fast, 128 slower.)
pub(crate) const BLOCK: usize = crate::grids::CELLS_PER_BLOCK;

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
#[cfg(test)]
pub(crate) fn remove_class(m: &mut BlockMasses, class_bit: usize, s: &Lanes, live: Live) {
    restrict_to(m, OMEGA ^ class_bit, s, live);
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

/// m ∩ "s on G, 1 − s on Ω" for a focal set `g` (`s` per cell): every A ⊄ G gives s·m(A) to
/// A ∩ G (possibly ∅). The kernel keeps the [`Restriction`] of each G it uses; this builds it.
#[cfg(test)]
pub(crate) fn restrict_to(m: &mut BlockMasses, g: usize, s: &Lanes, live: Live) {
    Restriction::new(g, live).apply(m, s, live);
}

/// The transfers of m ∩ "s on G, 1 − s on Ω" for one focal set G, listed once for the sets that
/// may hold mass, so that a pass visits nothing else.
///
/// This is the map prior's half of SG' = r(SG) ∩ GG (eq 21, 34-38): (m ∩ m_GG)(B) =
/// (1 − β)·m(B) + β·Σ_{A ∩ G = B} m(A), and the specialisation (G = Ω∖{M}, s = ζ). Sources
/// (A ⊄ G) and targets (A ∩ G ⊆ G) never coincide, so the transfers commute. They are made
/// target by target: the sources of T ⊆ G are T ∪ X' for every non-empty X' ⊆ Ω∖G, and what
/// they give is summed before T is touched once. A cell whose `s` is 0 (another map context,
/// ζ = 0) is left exactly as it was.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Restriction {
    /// (target, index of its first source in `sources`, number of sources), for every target
    /// with a live source.
    targets: [(u8, u8, u8); N_SETS / 2],
    target_count: u8,
    sources: [u8; N_SETS],
}

impl Restriction {
    /// The transfers to A ∩ G from the sets of `live` (a family closed under intersection, so
    /// a target outside it has no live source).
    pub(crate) fn new(g: usize, live: Live) -> Self {
        let mut plan = Restriction {
            targets: [(0, 0, 0); N_SETS / 2],
            target_count: 0,
            sources: [0; N_SETS],
        };
        let excluded = OMEGA & !g;
        if excluded == 0 {
            return plan;
        }
        let mut source_count = 0;
        // Subsets of a mask in decreasing order: `subset = (subset − 1) & mask` down to 0.
        let mut target = g;
        loop {
            let first = source_count;
            let mut extra = excluded;
            while extra != 0 {
                if is_live(live, target | extra) && is_live(live, target) {
                    plan.sources[source_count] = (target | extra) as u8;
                    source_count += 1;
                }
                extra = (extra - 1) & excluded;
            }
            if source_count > first {
                plan.targets[usize::from(plan.target_count)] =
                    (target as u8, first as u8, (source_count - first) as u8);
                plan.target_count += 1;
            }
            if target == 0 {
                return plan;
            }
            target = (target - 1) & g;
        }
    }

    /// Applies the transfers with share `s` per cell, from the sources in `live` (a subset of
    /// the family the plan was made for: the others hold +0 and give nothing). Each source
    /// keeps (1 − s) of its mass; s times the sum of a target's sources goes to it. The sum
    /// starts from the first source itself (the same value as 0 + it), and a target with one
    /// source takes it directly.
    #[inline(always)]
    pub(crate) fn apply(&self, m: &mut BlockMasses, s: &Lanes, live: Live) {
        let share = *s;
        let mut kept_share = [0.0; BLOCK];
        for i in 0..BLOCK {
            kept_share[i] = 1.0 - share[i];
        }
        for &(target, first, count) in &self.targets[..usize::from(self.target_count)] {
            let sources = &self.sources[usize::from(first)..usize::from(first + count)];
            let target = usize::from(target);
            if let [only] = sources {
                let only = usize::from(*only);
                if !is_live(live, only) {
                    continue;
                }
                let (mut source, mut masses) = (m[only], m[target]);
                for i in 0..BLOCK {
                    masses[i] += share[i] * source[i];
                    source[i] *= kept_share[i];
                }
                m[only] = source;
                m[target] = masses;
                continue;
            }
            let mut sum = [0.0; BLOCK];
            let mut any_source = false;
            for set in sources.iter().map(|&set| usize::from(set)) {
                if !is_live(live, set) {
                    continue;
                }
                let source = &mut m[set];
                if any_source {
                    for i in 0..BLOCK {
                        sum[i] += source[i];
                    }
                } else {
                    sum = *source;
                    any_source = true;
                }
                for i in 0..BLOCK {
                    source[i] *= kept_share[i];
                }
            }
            if any_source {
                let masses = &mut m[target];
                for i in 0..BLOCK {
                    masses[i] += share[i] * sum[i];
                }
            }
        }
    }
}

/// The [`Restriction`] to one focal set G, for the two families of live sets a block can have.
#[derive(Clone, Copy, Debug)]
pub(super) struct Restrictions {
    reachable: Restriction,
    all: Restriction,
}

impl Restrictions {
    pub(super) fn new(g: usize) -> Self {
        Restrictions {
            reachable: Restriction::new(g, REACHABLE),
            all: Restriction::new(g, ALL_SETS),
        }
    }

    /// The transfers for a block whose live sets are `live`: those among the [`REACHABLE`] sets
    /// if `live` lies within them, else all.
    #[inline(always)]
    pub(super) fn for_live(&self, live: Live) -> &Restriction {
        if live & !REACHABLE == 0 {
            &self.reachable
        } else {
            &self.all
        }
    }
}

/// Σ of m(A) over the sets A for which `select(A)` holds, per cell, in increasing set order (so
/// that the result does not depend on how cells are grouped).
#[inline(always)]
pub(crate) fn sum_sets(m: &BlockMasses, live: Live, select: impl Fn(usize) -> bool) -> Lanes {
    let mut total = [0.0; BLOCK];
    for (set, plane) in m.iter().enumerate() {
        if select(set) && is_live(live, set) {
            for i in 0..BLOCK {
                total[i] += plane[i];
            }
        }
    }
    total
}

/// Σ of m(A) over the non-empty A ⊆ {I, U, S, M}: m(O) as eq 22-23 define it. These are the
/// even sets (F is bit 0) from 2 on, summed in increasing order.
#[inline(always)]
pub(crate) fn occupied_mass(m: &BlockMasses, live: Live) -> Lanes {
    let mut total = [0.0; BLOCK];
    for (set, plane) in m.iter().enumerate().skip(2).step_by(2) {
        if is_live(live, set) {
            for i in 0..BLOCK {
                total[i] += plane[i];
            }
        }
    }
    total
}

/// The focal sets that may hold mass in a block, as a bit per set: a pass may skip the others,
/// whose masses are +0 and stay +0 (adding or scaling them changes no bit of the result).
pub(crate) type Live = u32;

/// Every focal set.
pub(crate) const ALL_SETS: Live = u32::MAX;

/// The 17 focal sets that discounting to Ω, the refined sensor ({F}, O, Ω), the five map
/// priors (G = Ω, {F,U,S,M}, {F,S,M}, {I}, and {F,I} beside a building), ∅_FO on {M} and the
/// specialisation (A → A∖{M}) can reach from a vacuous grid: the closure of those sets under
/// intersection and removal of M (`reachable_sets_are_closed` checks it). A block whose masses
/// all lie on them stays on them, and every pass skips the other 15.
pub(crate) const REACHABLE: Live = {
    const SETS: [usize; 17] = [0, 1, 2, 3, 8, 9, 12, 13, 14, 15, 16, 24, 25, 28, 29, 30, 31];
    let mut mask = 0;
    let mut k = 0;
    while k < SETS.len() {
        mask |= 1 << SETS[k];
        k += 1;
    }
    mask
};

/// Whether `set` is in `live`.
#[inline(always)]
pub(crate) fn is_live(live: Live, set: usize) -> bool {
    live & (1 << set) != 0
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
        remove_class(&mut m, M, &[0.5; BLOCK], ALL_SETS);
        assert!(close(m[S | M][0], 0.3) && close(m[S][0], 0.3));
        assert!(close(m[M][0], 0.05) && close(m[0][0], 0.05));
        assert!(close(m[OMEGA][0], 0.15) && close(m[OMEGA ^ M][0], 0.15));
    }

    #[test]
    fn remove_class_factor_is_per_cell() {
        let mut m = block_of(&[(F | I, 1.0)]);
        let mut s = [0.0; BLOCK];
        s[3] = 1.0;
        remove_class(&mut m, F, &s, ALL_SETS);
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
    fn restrict_to_moves_the_share_s_to_the_intersection_with_g() {
        // G = {F,S,M} (road), s = 0.8: {I,S} 0.5 → {S} 0.4; Ω 0.3 → G 0.24; {I} 0.2 → ∅ 0.16;
        // what stays is 1 − s of each source; {S} and G (⊆ G) do not move.
        let g = F | S | M;
        let mut m = block_of(&[(I | S, 0.5), (OMEGA, 0.3), (I, 0.2)]);
        let mut s = [0.8; BLOCK];
        s[1] = 0.0; // another context: untouched
        restrict_to(&mut m, g, &s, ALL_SETS);
        assert!(close(m[S][0], 0.4) && close(m[I | S][0], 0.1));
        assert!(close(m[g][0], 0.24) && close(m[OMEGA][0], 0.06));
        assert!(close(m[0][0], 0.16) && close(m[I][0], 0.04));
        assert_eq!((m[I | S][1], m[OMEGA][1], m[I][1]), (0.5, 0.3, 0.2));
        assert_eq!((m[S][1], m[g][1], m[0][1]), (0.0, 0.0, 0.0));
    }

    #[test]
    fn reachable_sets_are_closed() {
        let generators = [0, F, O, OMEGA, F | U | S | M, F | S | M, I, F | I, M];
        for g in generators {
            assert!(is_live(REACHABLE, g), "generator {g:05b}");
        }
        for a in (0..N_SETS).filter(|&a| is_live(REACHABLE, a)) {
            assert!(is_live(REACHABLE, a & !M), "{a:05b} without M");
            for b in (0..N_SETS).filter(|&b| is_live(REACHABLE, b)) {
                assert!(is_live(REACHABLE, a & b), "{a:05b} ∩ {b:05b}");
            }
        }
        assert_eq!(REACHABLE.count_ones(), 17);
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
        assert!(close(occupied_mass(&m, ALL_SETS)[0], 0.7));
    }
}
