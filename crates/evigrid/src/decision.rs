//! Decision and pignistic probability per cell (SPEC §6, eq 15).
//!
//! ```
//! use evigrid::{Label, betp, decide};
//! use evigrid::class::{F, M, S};
//!
//! let mut m = [0.0_f32; 32];
//! m[F] = 0.1;
//! m[S | M] = 0.6; // split evenly between S and M
//! m[M] = 0.1;
//! m[31] = 0.2; // Ω, a fifth to each class
//! let p = betp(&m);
//! assert!((p[4] - (0.1 + 0.3 + 0.04)).abs() < 1e-6); // M
//! assert_eq!(decide(&m, true, 0.5), Label::M);
//! assert_eq!(decide(&m, false, 0.5), Label::Unknown); // never observed
//! ```

use crate::grids::{N_SETS, OMEGA, PerceptionGrid};
use crate::label::Label;
use rayon::prelude::*;

/// Below this, 1 − m(∅) is treated as zero: the cell is in total conflict and has no betP.
const MIN_NORMAL_MASS: f32 = 1e-6;

/// Pignistic probability of each class F, I, U, S, M (eq 15): every focal set A shares its mass
/// equally among its classes. A subnormal m (m(∅) > 0, `keep` policy) is divided by 1 − m(∅);
/// if nothing is left (m(∅) = 1) every probability is 0.
///
/// # References
/// Smets & Kennes 1994; Kurdej et al. 2013 eq 15; SPEC §1, §6.
pub fn betp(m: &[f32; N_SETS]) -> [f32; 5] {
    let mut p = [0.0_f32; 5];
    for (set, &mass) in m.iter().enumerate().skip(1) {
        let share = mass * INVERSE_SIZE[set];
        for (k, pk) in p.iter_mut().enumerate() {
            if set & (1 << k) != 0 {
                *pk += share;
            }
        }
    }
    let normal = 1.0 - m[0];
    if normal <= MIN_NORMAL_MASS {
        return [0.0; 5];
    }
    p.map(|pk| pk / normal)
}

/// [`betp`] of the cells `cells` (storage indices) of `grid`, bit for bit, class by class:
/// `out[k]` is cleared, then holds class k's probability for each cell of the range, in order.
/// Each focal set's plane is read once over the range (a plane of zeros is skipped) instead of
/// gathering 32 planes per cell, and the sums run along the cells, where they vectorise. What
/// writes the pignistic probabilities of a whole grid (a recording's grid, a picture) should use
/// this: on KITTI 0013's 320 × 320 window it is several times quicker than [`betp`] of each
/// cell's [`PerceptionGrid::cell_masses`].
///
/// # Panics
/// If `cells` does not lie within the grid.
///
/// # References
/// As [`betp`].
pub fn betp_cells(grid: &PerceptionGrid, cells: std::ops::Range<usize>, out: &mut [Vec<f32>; 5]) {
    for pk in out.iter_mut() {
        pk.clear();
        pk.resize(cells.len(), 0.0);
    }
    // Sets in ascending order, as `betp` adds them: each class gets the same sums.
    for (set, &inverse) in INVERSE_SIZE.iter().enumerate().skip(1) {
        let masses = &grid.plane(set)[cells.clone()];
        // Adding ±0 changes no sum that starts at +0. (Folded without an early exit, so
        // that the test runs on whole vectors.)
        if !masses.iter().fold(false, |any, &m| any | (m != 0.0)) {
            continue;
        }
        for (k, pk) in out.iter_mut().enumerate() {
            if set & (1 << k) != 0 {
                for (p, &mass) in pk.iter_mut().zip(masses) {
                    *p += mass * inverse;
                }
            }
        }
    }
    // Class by class along the cells (each cell's value is its own: the order changes no
    // bit), so that the division runs on whole vectors.
    let empty = &grid.plane(0)[cells];
    for pk in out.iter_mut() {
        for (p, &empty) in pk.iter_mut().zip(empty) {
            let normal = 1.0 - empty;
            *p = if normal <= MIN_NORMAL_MASS {
                0.0
            } else {
                *p / normal
            };
        }
    }
}

/// 1 / |A| for every focal set A (0 for ∅): the pignistic share of each of its classes. A
/// product, not a division, so that [`decide_lanes`] vectorises cheaply and still gives
/// [`betp`]'s values.
const INVERSE_SIZE: [f32; N_SETS] = {
    const INVERSE: [f32; 6] = [0.0, 1.0, 1.0 / 2.0, 1.0 / 3.0, 1.0 / 4.0, 1.0 / 5.0];
    let mut table = [0.0; N_SETS];
    let mut set = 0;
    while set < N_SETS {
        table[set] = INVERSE[set.count_ones() as usize];
        set += 1;
    }
    table
};

/// The 16 focal sets of Ω_PG that contain each class, in increasing order.
const SETS_WITH_CLASS: [[u8; 16]; 5] = {
    let mut table = [[0; 16]; 5];
    let mut k = 0;
    while k < 5 {
        let (mut set, mut j) = (0, 0);
        while set < N_SETS {
            if set & (1 << k) != 0 {
                table[k][j] = set as u8;
                j += 1;
            }
            set += 1;
        }
        k += 1;
    }
    table
};

/// betP values closer than this are a tie (f32 rounding of equal shares differs in the last bits).
const TIE_TOLERANCE: f32 = 1e-6;

/// Class indices (F = 0 … M = 4) in the order that wins a betP tie: U, M, S, I, F.
///
/// Ties are not rare: mass on O = {I, U, S, M} or {I, U, S} gives its classes equal betP, and
/// only the map (I), the conflict ∅_FO (M) or the accumulator (S) ever separate them. A tie
/// therefore means "occupied, and nothing says which kind", and the order says what that is:
/// - U before I: a mapped building (I) is only claimed where the map says so; without a map an
///   obstacle is unmapped infrastructure, never a building;
/// - M before S: S gains mass only through the accumulator's evidence that the object stays
///   (eq 28-29), so an {S, M} tie means no such evidence yet;
/// - U before M: a tie of U with M comes from static mass on O with no appearance conflict
///   (∅_FO, which would favour M strictly);
/// - F last, and a tie of F with the best occupied class is not broken at all: the cell is
///   unknown (see [`decide`]).
const TIE_ORDER: [usize; 5] = [2, 4, 3, 1, 0];

/// F's index in [`TIE_ORDER`]'s class numbering.
const FREE: usize = 0;

/// The decided class (SPEC §6): `Unknown` where the cell was never `seen`, where
/// m(Ω) > `unknown_threshold`, or in total conflict; otherwise the class of largest betP, ties
/// (within 1e-6) among occupied classes broken in the order U, M, S, I (see `TIE_ORDER` for why).
///
/// A tie between F and the best occupied class is `Unknown`: the evidence does not say whether
/// the cell is free. It is what a cell out of view for long becomes under SPEC §5, which fuses the
/// map prior into it at every step: its own evidence fades, the prior piles up on G = {F,U,S,M}
/// or {F,S,M}, and betP splits that mass evenly between F and the occupied classes of G. Broken
/// in favour of an occupied class, every such cell was decided U (pavement) or M (road), a third
/// of the free cells of a one-minute drive.
pub fn decide(m: &[f32; N_SETS], seen: bool, unknown_threshold: f64) -> Label {
    // Compared in f32, the grid's precision: m(Ω) = 0.6_f32 is not above a threshold of 0.6.
    if !seen || m[OMEGA] > unknown_threshold as f32 || 1.0 - m[0] <= MIN_NORMAL_MASS {
        return Label::Unknown;
    }
    let p = betp(m);
    let mut best = TIE_ORDER[0];
    for &k in &TIE_ORDER[1..] {
        if p[k] > p[best] + TIE_TOLERANCE {
            best = k;
        }
    }
    if best != FREE && p[FREE] + TIE_TOLERANCE >= p[best] {
        return Label::Unknown;
    }
    Label::from_class(best)
}

/// Cells [`decide_grid`] decides together: 32 planes of 64 lanes (8 KiB) stay in L1.
const DECIDE_BLOCK: usize = 64;

/// Decides every cell of `pg` into `out` (same storage order), in parallel; the same decisions
/// as [`decide`] cell by cell.
///
/// # Panics
/// If `out.len() != pg.len()`.
pub fn decide_grid(pg: &PerceptionGrid, unknown_threshold: f64, out: &mut [Label]) {
    assert_eq!(out.len(), pg.len(), "decision buffer size");
    let unknown_threshold = unknown_threshold as f32;
    out.par_chunks_mut(DECIDE_BLOCK)
        .enumerate()
        .with_min_len(64)
        .for_each(|(block, out)| {
            let cells = block * DECIDE_BLOCK..block * DECIDE_BLOCK + out.len();
            let mut m = [[0.0; DECIDE_BLOCK]; N_SETS];
            for (set, lanes) in m.iter_mut().enumerate() {
                lanes[..out.len()].copy_from_slice(&pg.plane(set)[cells.clone()]);
            }
            let mut seen = [0; DECIDE_BLOCK];
            seen[..out.len()].copy_from_slice(&pg.seen()[cells]);
            decide_lanes(&m, u32::MAX, &seen, unknown_threshold, out);
        });
}

/// [`decide`] on `N` cells held as lanes (`m[set][lane]`, +0 on the sets outside the bit mask
/// `live`), written to `out` (at most `N` cells):
/// the same operations in the same order per cell, so the same decisions, in loops over lanes
/// that the compiler vectorises. The fusion step calls it on its block of cells while they are
/// still in cache.
#[inline(always)]
#[allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays alike"
)]
pub(crate) fn decide_lanes<const N: usize>(
    m: &[[f32; N]; N_SETS],
    live: u32,
    seen: &[u8; N],
    unknown_threshold: f32,
    out: &mut [Label],
) {
    // A block no cell of which was ever seen, the usual case far from the vehicle, is unknown
    // without computing anything. (A fold, not `Iterator::any`: without an early exit it
    // vectorises.)
    if !seen.iter().fold(false, |any, &seen| any | (seen != 0)) {
        out.fill(Label::Unknown);
        return;
    }
    // betP before the division by 1 − m(∅): per class, the shares of the 16 sets that contain
    // it, added in increasing set order as `betp` does (eq 15).
    let mut p = [[0.0_f32; N]; 5];
    for (pk, sets) in p.iter_mut().zip(&SETS_WITH_CLASS) {
        // A local sum, stored once: the compiler keeps it in registers.
        let mut sum = [0.0_f32; N];
        // Sets outside `live` hold +0: adding their share would change nothing.
        for &set in sets.iter().filter(|&&set| live & (1 << set) != 0) {
            let (plane, inverse) = (&m[usize::from(set)], INVERSE_SIZE[usize::from(set)]);
            for i in 0..N {
                sum[i] += plane[i] * inverse;
            }
        }
        *pk = sum;
    }
    let mut decided = [0_u8; N];
    for i in 0..N {
        let normal = 1.0 - m[0][i];
        let unknown = seen[i] == 0 || m[OMEGA][i] > unknown_threshold || normal <= MIN_NORMAL_MASS;
        let mut best = TIE_ORDER[0];
        let mut best_p = p[best][i] / normal;
        for &k in &TIE_ORDER[1..] {
            let pk = p[k][i] / normal;
            if pk > best_p + TIE_TOLERANCE {
                best = k;
                best_p = pk;
            }
        }
        let free_ties = best != FREE && p[FREE][i] / normal + TIE_TOLERANCE >= best_p;
        decided[i] = if unknown || free_ties {
            0
        } else {
            best as u8 + 1
        };
    }
    for (out, &index) in out.iter_mut().zip(&decided) {
        // `index` is a class index + 1 (0: unknown): the label of that code.
        *out = Label::ALL[usize::from(index)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grids::class::{F, I, M, O, S, U};

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() < 1e-6
    }

    #[test]
    fn betp_cells_is_betp_of_each_cell_bit_for_bit() {
        let mut grid = PerceptionGrid::new(7, 5);
        let mut state = 7_u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        for idx in 0..grid.len() {
            // Mass on a few sets (set 9 never: a plane of zeros is skipped), normalised.
            let mut m = [0.0_f32; N_SETS];
            for set in [1, 3, 6, 17, 24, 30, OMEGA] {
                m[set] = next();
            }
            m[0] = if idx % 4 == 0 { next() } else { 0.0 };
            let total: f32 = m.iter().sum();
            grid.set_cell_masses(idx, &m.map(|v| v / total));
        }
        // Total conflict: no betP.
        let mut conflict = [0.0_f32; N_SETS];
        conflict[0] = 1.0;
        grid.set_cell_masses(12, &conflict);
        let mut out: [Vec<f32>; 5] = std::array::from_fn(|_| vec![9.0; 3]);
        betp_cells(&grid, 5..31, &mut out);
        for (i, idx) in (5..31).enumerate() {
            let expected = betp(&grid.cell_masses(idx));
            let p: [f32; 5] = std::array::from_fn(|k| out[k][i]);
            assert_eq!(
                p.map(f32::to_bits),
                expected.map(f32::to_bits),
                "cell {idx}"
            );
        }
        assert!(out.iter().all(|pk| pk.len() == 26 && pk[12 - 5] == 0.0));
    }

    #[test]
    fn betp_shares_each_set_among_its_classes() {
        // m({F}) = 0.2, m({I,U}) = 0.4, m(O) = 0.2, m(Ω) = 0.2:
        // F = 0.2 + 0.2/5 = 0.24; I = U = 0.2 + 0.05 + 0.04 = 0.29; S = M = 0.05 + 0.04 = 0.09.
        let mut m = [0.0; N_SETS];
        m[F] = 0.2;
        m[I | U] = 0.4;
        m[O] = 0.2;
        m[OMEGA] = 0.2;
        let p = betp(&m);
        for (got, want) in p.iter().zip([0.24, 0.29, 0.29, 0.09, 0.09]) {
            assert!(close(*got, want), "{p:?}");
        }
        assert!(close(p.iter().sum(), 1.0));
    }

    #[test]
    fn sets_with_a_class_are_the_sixteen_that_contain_it_in_order() {
        for (k, sets) in SETS_WITH_CLASS.iter().enumerate() {
            let listed: Vec<usize> = sets.iter().map(|&s| usize::from(s)).collect();
            let wanted: Vec<usize> = (0..N_SETS).filter(|set| set & (1 << k) != 0).collect();
            assert_eq!(listed, wanted, "class {k}");
        }
    }

    #[test]
    fn betp_of_subnormal_mass_is_normalised() {
        // m(∅) = 0.5, m({S}) = 0.3, m({S,M}) = 0.2: S = (0.3 + 0.1)/0.5 = 0.8, M = 0.1/0.5 = 0.2.
        let mut m = [0.0; N_SETS];
        m[0] = 0.5;
        m[S] = 0.3;
        m[S | M] = 0.2;
        let p = betp(&m);
        assert!(close(p[3], 0.8) && close(p[4], 0.2), "{p:?}");
        m = [0.0; N_SETS];
        m[0] = 1.0;
        assert_eq!(betp(&m), [0.0; 5]);
    }

    #[test]
    fn decision_is_unknown_when_ignorant_unseen_or_in_total_conflict() {
        let mut m = [0.0; N_SETS];
        m[F] = 0.4;
        m[OMEGA] = 0.6;
        assert_eq!(decide(&m, true, 0.5), Label::Unknown); // m(Ω) = 0.6 > 0.5
        assert_eq!(decide(&m, true, 0.6), Label::F); // not above
        assert_eq!(decide(&m, false, 0.9), Label::Unknown);
        let mut conflict = [0.0; N_SETS];
        conflict[0] = 1.0;
        assert_eq!(decide(&conflict, true, 0.5), Label::Unknown);
    }

    #[test]
    fn decision_is_argmax_betp_with_ties_in_order_u_m_s_i_f() {
        // {I,U} 0.8 splits into I 0.4 + U 0.4 (+ Ω 0.2/5 each): a tie, won by U.
        let mut m = [0.0; N_SETS];
        m[I | U] = 0.8;
        m[OMEGA] = 0.2;
        assert_eq!(decide(&m, true, 0.5), Label::U);
        // I 0.1 + 0.35 = 0.45 > U 0.35: no tie, I.
        m[I] = 0.1;
        m[I | U] = 0.7;
        assert_eq!(decide(&m, true, 0.5), Label::I);
        // O = {I,U,S,M} 0.8: I = U = S = M = 0.2 + 0.04; U wins (no map says "building").
        let mut o = [0.0; N_SETS];
        o[O] = 0.8;
        o[OMEGA] = 0.2;
        assert_eq!(decide(&o, true, 0.5), Label::U);
        // {S,M} 0.9: S = M = 0.45 + 0.02; M wins (no evidence that the object stays).
        let mut sm = [0.0; N_SETS];
        sm[S | M] = 0.9;
        sm[OMEGA] = 0.1;
        assert_eq!(decide(&sm, true, 0.5), Label::M);
        // {I,S} 0.9: I = S; S wins over I.
        let mut is = [0.0; N_SETS];
        is[I | S] = 0.9;
        is[OMEGA] = 0.1;
        assert_eq!(decide(&is, true, 0.5), Label::S);
        // {F,M} 0.9: F = M; free or occupied is not known.
        let mut fm = [0.0; N_SETS];
        fm[F | M] = 0.9;
        fm[OMEGA] = 0.1;
        assert_eq!(decide(&fm, true, 0.5), Label::Unknown);
        // The map prior alone on pavement, {F,U,S,M} 0.97 (a cell long out of view): F = U = S
        // = M, unknown; with a trace of {F} left, F.
        let mut pavement = [0.0; N_SETS];
        pavement[F | U | S | M] = 0.97;
        pavement[OMEGA] = 0.03;
        assert_eq!(decide(&pavement, true, 0.5), Label::Unknown);
        pavement[F] = 0.01;
        pavement[F | U | S | M] = 0.96;
        assert_eq!(decide(&pavement, true, 0.5), Label::F);
    }

    #[test]
    fn grid_decision_matches_cell_decision() {
        let mut pg = PerceptionGrid::new(3, 1);
        let mut m = [0.0; N_SETS];
        m[M] = 0.9;
        m[OMEGA] = 0.1;
        pg.set_cell_masses(1, &m);
        let mut out = [Label::F; 3];
        decide_grid(&pg, 0.5, &mut out);
        // Never seen: unknown everywhere, whatever the masses.
        assert_eq!(out, [Label::Unknown; 3]);
        pg.seen_mut().fill(1);
        decide_grid(&pg, 0.5, &mut out);
        // Cells 0 and 2 are vacuous (m(Ω) = 1 > 0.5); cell 1 is moving.
        assert_eq!(out, [Label::Unknown, Label::M, Label::Unknown]);
        assert_eq!(out[1], decide(&pg.cell_masses(1), true, 0.5));
    }

    /// Masses with many exact ties (shares of 0.1 on few sets) and some arbitrary ones.
    fn arb_masses() -> impl proptest::strategy::Strategy<Value = ([f32; N_SETS], bool)> {
        use proptest::prelude::*;
        (
            proptest::collection::vec((0..N_SETS, 1..=10_u8), 1..5),
            proptest::collection::vec(0.0_f32..1.0, N_SETS),
            any::<bool>(),
            any::<bool>(),
        )
            .prop_map(|(tied, arbitrary, use_ties, seen)| {
                let mut m = [0.0; N_SETS];
                if use_ties {
                    for (set, tenths) in tied {
                        m[set] += f32::from(tenths) / 10.0;
                    }
                } else {
                    m.copy_from_slice(&arbitrary);
                }
                let total: f32 = m.iter().sum();
                (m.map(|x| x / total.max(1e-3)), seen)
            })
    }

    proptest::proptest! {
        #[test]
        fn grid_decisions_equal_cell_decisions(
            cells in proptest::collection::vec(arb_masses(), 1..150),
            threshold in 0.3_f64..1.0,
        ) {
            let mut pg = PerceptionGrid::new(cells.len(), 1);
            for (idx, (m, seen)) in cells.iter().enumerate() {
                pg.set_cell_masses(idx, m);
                pg.seen_mut()[idx] = u8::from(*seen);
            }
            let mut out = vec![Label::Unknown; cells.len()];
            decide_grid(&pg, threshold, &mut out);
            for (idx, (m, seen)) in cells.iter().enumerate() {
                proptest::prop_assert_eq!(out[idx], decide(m, *seen, threshold), "cell {}", idx);
            }
        }
    }
}
