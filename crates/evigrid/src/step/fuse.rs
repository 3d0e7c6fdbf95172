//! SPEC §5 on one block, as the sequence of its steps: which focal sets the block must visit,
//! then the sensor's evidence, the fusion of steps 3-7 (or the discounting alone, for cells the
//! scan did not reach under `discount_only`), and the events the step counts. The stages
//! themselves are in `stages`.

use super::StepStats;
use super::constants::{Discount, StepConstants};
use super::evidence::SensorEvidence;
use super::lanes::{any_lane, count, count_where, for_each_bit};
use super::memory::Block;
use super::passes::{
    ALL_SETS, BLOCK, BlockMasses, Live, REACHABLE, add_class, is_live, occupied_mass,
};
use super::stages::{
    BeforeSensor, combine_with_map_prior, discount_and_combine_with_refined_sensor, discount_only,
    discount_to_omega, remove_sensor_map_conflict, settle_empty_set, update_accumulator,
};
use crate::grids::{MASS_BITS, N_SETS, OMEGA, PlaneBits, class};
use crate::params::{ResidualPolicy, UnobservedCells};

/// SPEC §5 on one block: PG_{t−1}, ζ_{t−1} in the block become PG_t, ζ_t.
#[inline(always)]
pub(super) fn step_block(
    block: &mut Block,
    k: &StepConstants,
    known_live: Option<Live>,
) -> StepStats {
    // 1-2. The sensor's evidence, refined to Ω_PG and combined with the map prior by Dempster's
    //      rule: SG'_t = r(SG_t) ⊕ GG (eq 16-21), per cell in compact form.
    block.sensor.fill(
        &block.sensor_free,
        &block.sensor_occupied,
        &block.context,
        &k.context_priors,
        &k.unobserved_evidence,
    );
    block.live = known_live.unwrap_or_else(|| live_sets(&block.m, &k.discount));
    if !block.sensor.any_observed && matches!(k.discount, Discount::ToOmega(_)) {
        // Far from the sensor a block holds mass on a few sets, and the step can only reach a
        // few more: passes visit those alone.
        block.live &= reachable_this_step(block.stored_masses, &block.sensor, k);
    }
    if k.unobserved == UnobservedCells::Fuse || block.sensor.all_observed {
        return fuse_block(block, k);
    }
    // `discount_only`: cells the scan did not reach are only discounted (step 3).
    if !block.sensor.any_observed {
        discount_only(&mut block.m, &k.discount, block.live);
        block.conflict_fo = [0.0; BLOCK];
        block.conflict_of = [0.0; BLOCK];
        return StepStats {
            cells: block.len as u64,
            ..StepStats::default()
        };
    }
    // Some of each: every cell fused, then the unobserved ones given their discounted past.
    let (mut discounted, zeta) = (block.m, block.zeta);
    discount_only(&mut discounted, &k.discount, block.live);
    let stats = fuse_block(block, k);
    let observed = &block.sensor.observed;
    for (plane, past) in block.m.iter_mut().zip(&discounted) {
        for i in 0..BLOCK {
            plane[i] = if observed[i] != 0 { plane[i] } else { past[i] };
        }
    }
    for i in 0..BLOCK {
        let keep = observed[i] != 0;
        block.zeta[i] = if keep { block.zeta[i] } else { zeta[i] };
        block.conflict_fo[i] = if keep { block.conflict_fo[i] } else { 0.0 };
        block.conflict_of[i] = if keep { block.conflict_of[i] } else { 0.0 };
    }
    stats
}

/// The focal sets that can hold mass after a step of a block the scan did not reach, whose
/// masses before lie on `before` (its non-zero plane bits), with discounting to Ω.
///
/// Those sets, Ω (discounting, ∅_OF), A ∩ G for the map context's G (the map prior), ∅ and {M}
/// (the conflicts), then A∖{M} of all of these (the specialisation). A pass may skip every
/// other set: its mass is +0 before and after.
#[inline(always)]
fn reachable_this_step(before: PlaneBits, sensor: &SensorEvidence, k: &StepConstants) -> Live {
    let mut live = (before & MASS_BITS) as Live | 1 << OMEGA;
    let mut restricted = live;
    for (c, prior) in k.context_priors.iter().enumerate() {
        if sensor.contexts_present & (1 << c) != 0 && prior.is_informative() {
            for_each_bit(PlaneBits::from(live), |set| {
                restricted |= 1 << (set & prior.g)
            });
        }
    }
    live = restricted | 1 << class::M | 1;
    let mut specialised = live;
    for_each_bit(PlaneBits::from(live), |set| {
        specialised |= 1 << (set & !class::M)
    });
    specialised
}

/// The focal sets a step of this block must visit: the 17 [`REACHABLE`] ones when every mass
/// outside them is +0 and the discounting moves mass to Ω only (Mercier's moves it to any
/// superset), else all 32. The usual grid, started vacuous, never leaves them.
#[inline(always)]
fn live_sets(m: &BlockMasses, discount: &Discount) -> Live {
    if matches!(discount, Discount::Mercier(_)) {
        return ALL_SETS;
    }
    // The bits of every mass outside, OR-ed: 0 only if all are +0.0 (not -0.0, whose sign bit a
    // skipped pass could have changed).
    let mut bits = [0u32; BLOCK];
    for (set, plane) in m.iter().enumerate() {
        if !is_live(REACHABLE, set) {
            for i in 0..BLOCK {
                bits[i] |= plane[i].to_bits();
            }
        }
    }
    if any_lane(&bits, |b| b != 0) {
        ALL_SETS
    } else {
        REACHABLE
    }
}

/// Steps 3-7 of SPEC §5 on every cell of the block, with SG' already in `block.sensor`.
#[inline(always)]
fn fuse_block(block: &mut Block, k: &StepConstants) -> StepStats {
    let sensor = &block.sensor;
    let m = &mut block.m;
    // 3. Discount the previous grid, so that old information fades; 4. the modified conjunctive
    //    rule (eq 22-23, 30-31). c = PG^α ∩ SG' = (PG^α ∩ r(SG) ∩ GG − K·Σm·δ_∅) / (1 − K): the
    //    discounting and the sensor's three focal sets in one pass, then the map's restriction,
    //    then Dempster's normalisation of SG' (see `discount_and_combine_with_refined_sensor`
    //    for why this order is exact). ∅_FO = m^α({F})·m'(O) and ∅_OF = m^α(O)·m'({F}) are read
    //    on the way.
    let rate_per_set = match &k.discount {
        Discount::ToOmega(rate_per_set) => rate_per_set,
        Discount::Mercier(rate_per_class) => {
            for (bit, &alpha) in rate_per_class.iter().enumerate() {
                add_class(m, 1 << bit, alpha);
            }
            &[0.0; N_SETS]
        }
    };
    let before = if sensor.any_observed || sensor.any_sensor_free {
        discount_and_combine_with_refined_sensor(m, rate_per_set, sensor, block.live)
    } else {
        // r(SG) is vacuous in every cell, so its combination changes nothing; m_SG'({F}) = 0
        // makes ∅_OF = 0 and K = 0 needs no Σm.
        discount_to_omega(m, rate_per_set, block.live);
        BeforeSensor {
            free: m[class::F],
            occupied: [0.0; BLOCK],
            total: [0.0; BLOCK],
        }
    };
    let mut conflict_fo = [0.0; BLOCK];
    let mut conflict_of = [0.0; BLOCK];
    for i in 0..BLOCK {
        conflict_fo[i] = before.free[i] * sensor.sg_occupied[i];
        conflict_of[i] = before.occupied[i] * sensor.sg_free[i];
    }
    combine_with_map_prior(m, &block.context, sensor, k, block.live);
    if sensor.any_sensor_map_conflict {
        remove_sensor_map_conflict(m, sensor, &before.total, block.live);
    }
    //    ∅_FO goes to {M} (an object appeared), ∅_OF to Ω (an object left), the residual conflict
    //    to the policy.
    for i in 0..BLOCK {
        m[class::M][i] += conflict_fo[i];
        m[OMEGA][i] += conflict_of[i];
        m[0][i] = (m[0][i] - conflict_fo[i] - conflict_of[i]).max(0.0);
    }
    let fallbacks_fusion = settle_empty_set(m, k.residual, block.live);
    // 5. Update the accumulator ζ with m(O) and ∅_FO + ∅_OF of this step (eq 24-27).
    update_accumulator(
        &mut block.zeta,
        &occupied_mass(m, block.live),
        &conflict_fo,
        &conflict_of,
        k,
    );
    // 6. Specialise (eq 28-29): every A ∋ M gives ζ·m(A) to A∖{M}; what {M} gives to ∅ follows
    //    the residual policy.
    //    With ζ = 0 in every cell (no cell of the block has been steadily occupied) this moves
    //    nothing, exactly, and is skipped. The residual policy still runs: under `normalise` it
    //    rescales again, and a cell must get the same bits whatever its neighbours' ζ.
    if any_lane(&block.zeta, |zeta| zeta > 0.0) {
        // The restriction to Ω∖{M}: the specialisation is that combination (passes.rs).
        k.specialisation
            .for_live(block.live)
            .apply(m, &block.zeta, block.live);
    }
    let fallbacks_specialisation = settle_empty_set(m, k.residual, block.live);
    // 7. Keep the conflict masses for display, and whether the sensor ever saw the cell.
    block.conflict_fo = conflict_fo;
    block.conflict_of = conflict_of;
    for i in 0..BLOCK {
        block.seen[i] |= sensor.observed[i];
    }
    let real = block.len;
    let counted = match k.unobserved {
        UnobservedCells::Fuse => [1; BLOCK],
        UnobservedCells::DiscountOnly => sensor.observed,
    };
    // Only observed cells are counted or in total conflict (K needs sensor mass), and only
    // `normalise` falls back.
    let (observed, total_conflicts) = if sensor.any_observed {
        (
            count(&sensor.observed[..real]),
            count(&sensor.total_conflict[..real]),
        )
    } else {
        (0, 0)
    };
    let fallbacks = if k.residual == ResidualPolicy::Normalise {
        // Under `discount_only` the unobserved cells' fusion is discarded, and so are its events.
        count_where(&fallbacks_fusion[..real], &counted[..real])
            + count_where(&fallbacks_specialisation[..real], &counted[..real])
    } else {
        0
    };
    StepStats {
        cells: real as u64,
        observed_cells: observed,
        total_map_conflicts: total_conflicts,
        normalisation_fallbacks: fallbacks,
        state_bytes_moved: 0,
    }
}
