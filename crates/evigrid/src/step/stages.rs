//! The stages of SPEC §5 that `fuse_block` (in `fuse`) runs on a block, one function each:
//! discounting (step 3), the modified conjunctive rule with SG' (step 4, with the map's half of
//! SG' and Dempster's normalisation of step 2), the residual policy on ∅, and the accumulator ζ
//! (step 5). Each is a pass over sets outside and lanes inside, as in `passes`.

use super::constants::{Discount, StepConstants};
use super::evidence::SensorEvidence;
use super::lanes::for_each_bit;
use super::passes::{
    BLOCK, BlockMasses, Lanes, Live, TOO_SMALL_TO_RESCALE, add_class, is_live, sum_sets,
};
use crate::grids::{N_SETS, OMEGA, PlaneBits, class};
use crate::params::ResidualPolicy;
use geodata::MapContext;

/// Step 3 alone: the discounting of every cell of the block.
#[inline(always)]
pub(super) fn discount_only(m: &mut BlockMasses, discount: &Discount, live: Live) {
    match discount {
        Discount::ToOmega(rate_per_set) => discount_to_omega(m, rate_per_set, live),
        Discount::Mercier(rate_per_class) => {
            for (bit, &alpha) in rate_per_class.iter().enumerate() {
                add_class(m, 1 << bit, alpha);
            }
        }
    }
}

/// Every A ≠ Ω gives `rate[A]`·m(A) to Ω: the discounting of
/// [`discount_and_combine_with_refined_sensor`] alone, with the same operations in the same
/// order (so a cell's result does not depend on its block's other cells).
#[inline(always)]
pub(super) fn discount_to_omega(m: &mut BlockMasses, rate_per_set: &[f32; N_SETS], live: Live) {
    let mut to_omega = [0.0; BLOCK];
    for_each_bit(PlaneBits::from(live & !(1 << OMEGA)), |set| {
        discount_in_place(&mut m[set], rate_per_set[set], &mut to_omega);
    });
    for i in 0..BLOCK {
        m[OMEGA][i] += to_omega[i];
    }
}

/// m(A) discounted at `rate`, in place (a copy returned and stored back costs a `memcpy`); what
/// it loses is added to `to_omega`. The same operations as [`discounted`].
#[inline(always)]
fn discount_in_place(masses: &mut Lanes, rate: f32, to_omega: &mut Lanes) {
    for i in 0..BLOCK {
        let moved = rate * masses[i];
        masses[i] -= moved;
        to_omega[i] += moved;
    }
}

/// m(A) discounted at A's rate; what it loses is added to `to_omega`.
#[inline(always)]
fn discounted(
    m: &BlockMasses,
    set: usize,
    rate_per_set: &[f32; N_SETS],
    to_omega: &mut Lanes,
) -> Lanes {
    let (rate, mut kept) = (rate_per_set[set], m[set]);
    for i in 0..BLOCK {
        let moved = rate * kept[i];
        kept[i] -= moved;
        to_omega[i] += moved;
    }
    kept
}

/// What [`discount_and_combine_with_refined_sensor`] read of the discounted grid PG^α before
/// combining it.
pub(super) struct BeforeSensor {
    /// m^α({F}), for ∅_FO (eq 22).
    pub(super) free: Lanes,
    /// m^α(O) = Σ_{∅ ≠ A ⊆ O} m^α(A), for ∅_OF (eq 23).
    pub(super) occupied: Lanes,
    /// Σ_A m^α(A), for Dempster's normalisation of SG'.
    pub(super) total: Lanes,
}

/// m ← m^α ∩ r(SG_t) in place, in one pass over the pairs (A, A ∪ {F}) with F ∉ A.
///
/// Discounting (step 3): every A ≠ Ω keeps 1 − α_A of its mass and gives the rest to Ω
/// (eq 13-14 with one rate; class-rate discounting with one per set). `rate_per_set` is all 0
/// when the grid was discounted before (Mercier's discounting is not to Ω): then m^α = m,
/// exactly.
///
/// Combination: m ∩ r(SG) = m_Ω·m + m_O·(m restricted to O) + m_F·(m restricted to {F}).
/// Restricting to O gives A ⊆ O its own mass and that of A ∪ {F}; restricting to {F} puts
/// pl(F) = Σ_{A∋F} m(A) on {F} and the rest on ∅. So per pair, A gets m_Ω·m(A) +
/// m_O·(m(A) + m(A ∪ {F})) and A ∪ {F} keeps m_Ω·m(A ∪ {F}). Ω's pair waits until every set
/// has given Ω its share, and (∅, {F}) until the sums for the m_F terms are known.
///
/// Combining with SG' = (r(SG) ∩ GG − K·δ_∅) / (1 − K) instead follows by associativity:
/// m ∩ SG' = (m ∩ r(SG) ∩ GG − K·Σm·δ_∅) / (1 − K), since m ∩ δ_∅ is all of m's mass on ∅
/// ([`combine_with_map_prior`], then [`remove_sensor_map_conflict`]).
#[inline(always)]
pub(super) fn discount_and_combine_with_refined_sensor(
    m: &mut BlockMasses,
    rate_per_set: &[f32; N_SETS],
    sensor: &SensorEvidence,
    live: Live,
) -> BeforeSensor {
    let (s_free, s_occupied, s_omega) = (&sensor.free, &sensor.occupied, &sensor.omega);
    let mut to_omega = [0.0; BLOCK];
    let empty = discounted(m, 0, rate_per_set, &mut to_omega);
    let free = discounted(m, class::F, rate_per_set, &mut to_omega);
    let mut occupied = [0.0; BLOCK];
    let mut with_free = free;
    for set in (2..N_SETS).step_by(2) {
        // A pair that holds no mass stays empty (the last pair, Ω's, always holds some).
        if !is_live(live, set) && !is_live(live, set | class::F) {
            continue;
        }
        let a = discounted(m, set, rate_per_set, &mut to_omega);
        let a_and_f = if set | class::F == OMEGA {
            // The last pair: every other set has given Ω its share by now.
            let mut omega = m[OMEGA];
            for i in 0..BLOCK {
                omega[i] += to_omega[i];
            }
            omega
        } else {
            discounted(m, set | class::F, rate_per_set, &mut to_omega)
        };
        for i in 0..BLOCK {
            occupied[i] += a[i];
            with_free[i] += a_and_f[i];
        }
        // A vacuous r(SG) (m_Ω = 1, m_F = m_O = 0) leaves every discounted mass exactly as it
        // is: a block the scan did not reach is only discounted.
        if sensor.any_observed {
            for i in 0..BLOCK {
                m[set][i] = s_omega[i] * a[i] + s_occupied[i] * (a[i] + a_and_f[i]);
                m[set | class::F][i] = s_omega[i] * a_and_f[i];
            }
        } else {
            m[set] = a;
            m[set | class::F] = a_and_f;
        }
    }
    let mut before = BeforeSensor {
        free,
        occupied,
        total: [0.0; BLOCK],
    };
    for i in 0..BLOCK {
        let without_free = empty[i] + occupied[i];
        m[0][i] =
            s_omega[i] * empty[i] + s_occupied[i] * (empty[i] + free[i]) + s_free[i] * without_free;
        m[class::F][i] = s_omega[i] * free[i] + s_free[i] * with_free[i];
        before.total[i] = without_free + with_free[i];
    }
    before
}

/// m ← m ∩ GG in place: for each map context in the block, its restriction to G with share β
/// in that context's cells and 0 elsewhere ([`Restriction`](super::passes::Restriction)). A
/// block inside one context, the usual case, makes one pass; cells where the map says nothing
/// (G = Ω) make none.
#[inline(always)]
pub(super) fn combine_with_map_prior(
    m: &mut BlockMasses,
    context: &[MapContext; BLOCK],
    sensor: &SensorEvidence,
    k: &StepConstants,
    live: Live,
) {
    for (index, prior) in k.context_priors.iter().enumerate() {
        if sensor.contexts_present & (1 << index) == 0 || !prior.is_informative() {
            continue;
        }
        let restriction = prior.restriction.for_live(live);
        if sensor.contexts_present == 1 << index {
            // Every cell is in this context.
            restriction.apply(m, &sensor.beta, live);
            continue;
        }
        let mut share = [0.0; BLOCK];
        for i in 0..BLOCK {
            share[i] = if context[i] as u8 == index as u8 {
                sensor.beta[i]
            } else {
                0.0
            };
        }
        restriction.apply(m, &share, live);
    }
}

/// Dempster's normalisation of SG' (eq 21), applied to m ∩ r(SG) ∩ GG: removes K·Σm from ∅ and
/// divides by 1 − K. K·Σm, not K: equal in exact arithmetic, but with K alone the f32 rounding
/// in Σm grew by 1/(1 − K) at every step.
#[inline(always)]
pub(super) fn remove_sensor_map_conflict(
    m: &mut BlockMasses,
    sensor: &SensorEvidence,
    total: &Lanes,
    live: Live,
) {
    for i in 0..BLOCK {
        m[0][i] -= sensor.conflict[i] * total[i];
    }
    for (_, plane) in m
        .iter_mut()
        .enumerate()
        .filter(|(set, _)| is_live(live, *set))
    {
        for i in 0..BLOCK {
            plane[i] *= sensor.inv_normaliser[i];
        }
    }
}

/// Applies the residual policy to the mass on ∅; returns 1 per cell where `normalise` had
/// nothing to rescale and fell back to `to_omega`.
///
/// - `to_omega`: m(Ω) += m(∅), m(∅) = 0.
/// - `keep`: m(∅) stays.
/// - `normalise`: every other mass is divided by their sum, m(∅) = 0.
#[inline(always)]
pub(super) fn settle_empty_set(
    m: &mut BlockMasses,
    policy: ResidualPolicy,
    live: Live,
) -> [u8; BLOCK] {
    let mut fallback = [0; BLOCK];
    match policy {
        ResidualPolicy::ToOmega => {
            for i in 0..BLOCK {
                m[OMEGA][i] += m[0][i];
                m[0][i] = 0.0;
            }
        }
        ResidualPolicy::Keep => {}
        ResidualPolicy::Normalise => {
            let rest = sum_sets(m, live, |set| set != 0);
            let mut scale = [1.0; BLOCK];
            let mut to_omega = [0.0; BLOCK];
            for i in 0..BLOCK {
                let enough = rest[i] > TOO_SMALL_TO_RESCALE;
                scale[i] = if enough { 1.0 / rest[i] } else { 1.0 };
                to_omega[i] = if enough { 0.0 } else { m[0][i] };
                fallback[i] = u8::from(!enough);
            }
            for plane in m.iter_mut().skip(1) {
                for i in 0..BLOCK {
                    plane[i] *= scale[i];
                }
            }
            for i in 0..BLOCK {
                m[OMEGA][i] += to_omega[i];
                m[0][i] = 0.0;
            }
        }
    }
    fallback
}

/// ζ += δ_inc (capped at 1) if m(O) ≥ γ_O and ∅_FO + ∅_OF ≤ γ_∅; ζ −= δ_dec (floored at 0) if
/// ∅_FO + ∅_OF > γ_∅; else unchanged (eq 24-27).
#[inline(always)]
pub(super) fn update_accumulator(
    zeta: &mut Lanes,
    occupied: &Lanes,
    conflict_fo: &Lanes,
    conflict_of: &Lanes,
    k: &StepConstants,
) {
    for i in 0..BLOCK {
        let conflict = conflict_fo[i] + conflict_of[i];
        let increase = occupied[i] >= k.gamma_occupied && conflict <= k.gamma_conflict;
        let decrease = conflict > k.gamma_conflict;
        let raised = (zeta[i] + k.delta_inc).min(1.0);
        let lowered = (zeta[i] - k.delta_dec).max(0.0);
        zeta[i] = if increase {
            raised
        } else if decrease {
            lowered
        } else {
            zeta[i]
        };
    }
}
