//! What the step derives from the parameters once, before touching a cell: the discount rates
//! for this step's `dt` (SPEC §5 step 3), the map prior of each context as the passes apply it
//! and the evidence of a cell the scan did not reach (SPEC §4-5), the accumulator's thresholds
//! (eq 24-27) and the specialisation's transfers.

use super::evidence::{CellEvidence, ContextPrior, N_CONTEXTS};
use super::passes::Restrictions;
use crate::grids::{N_SETS, OMEGA, class};
use crate::map_prior::{MAP_CONTEXTS, prior_beta, prior_focal_set};
use crate::params::{DiscountMode, Params, ResidualPolicy, SetRate, UnobservedCells};

/// Everything the step derives from the parameters once, before touching a cell.
#[derive(Clone, Debug)]
pub(super) struct StepConstants {
    pub(super) discount: Discount,
    /// The map prior of each map context, indexed by `MapContext as usize`.
    pub(super) context_priors: [ContextPrior; N_CONTEXTS],
    pub(super) residual: ResidualPolicy,
    pub(super) delta_inc: f32,
    pub(super) delta_dec: f32,
    pub(super) gamma_occupied: f32,
    pub(super) gamma_conflict: f32,
    /// SG' of a cell the scan did not reach, per map context.
    pub(super) unobserved_evidence: [CellEvidence; N_CONTEXTS],
    /// SPEC §6: above this m(Ω) a cell is decided unknown.
    pub(super) unknown_threshold: f32,
    pub(super) unobserved: UnobservedCells,
    /// The transfers of the specialisation (step 6): A ∋ M to A∖{M}.
    pub(super) specialisation: Restrictions,
}

impl StepConstants {
    pub(super) fn new(params: &Params, dt_s: f64) -> Self {
        let dt_s = if dt_s > 0.0 { dt_s } else { 0.0 };
        let fusion = &params.fusion;
        let class_rates = fusion.discount_per_second.as_array();
        let discount = match fusion.discount_mode {
            DiscountMode::Classical => {
                let rate = set_rate_per_second(OMEGA, &class_rates, fusion.set_rate);
                Discount::ToOmega([rate_for_step(rate, dt_s) as f32; N_SETS])
            }
            DiscountMode::ClassRates => Discount::ToOmega(std::array::from_fn(|set| {
                let rate = set_rate_per_second(set, &class_rates, fusion.set_rate);
                rate_for_step(rate, dt_s) as f32
            })),
            DiscountMode::Mercier => {
                Discount::Mercier(class_rates.map(|rate| rate_for_step(rate, dt_s) as f32))
            }
        };
        let context_priors = MAP_CONTEXTS.map(|context| {
            ContextPrior::new(prior_focal_set(context), prior_beta(context, &params.map))
        });
        let acc = &params.accumulator;
        StepConstants {
            discount,
            context_priors,
            residual: fusion.residual,
            delta_inc: acc.delta_inc as f32,
            delta_dec: acc.delta_dec as f32,
            gamma_occupied: acc.gamma_occupied as f32,
            gamma_conflict: acc.gamma_conflict as f32,
            unobserved_evidence: context_priors.map(|prior| CellEvidence::unobserved(&prior)),
            unknown_threshold: params.decision.unknown_threshold as f32,
            unobserved: fusion.unobserved,
            specialisation: Restrictions::new(OMEGA ^ class::M),
        }
    }
}

/// The discounting of step 3, as rates for this step's `dt`.
#[derive(Clone, Debug)]
pub(super) enum Discount {
    /// Classical and class-rate discounting: the rate α_A(dt) of every focal set, to Ω.
    ToOmega([f32; N_SETS]),
    /// Mercier contextual discounting: the rate α_θ(dt) of each class context {θ}.
    Mercier([f32; 5]),
}

/// α(dt) = 1 − (1 − α_1s)^dt: a rate per second applied over `dt_s` seconds (SPEC §5 step 3).
pub fn rate_for_step(rate_per_second: f64, dt_s: f64) -> f64 {
    1.0 - (1.0 - rate_per_second).powf(dt_s)
}

/// α_A per second from the rates of the classes in A (`class_rates` and `classical` modes).
///
/// For A = ∅ (mass kept on ∅ by the `keep` policy) the classes of Ω are used, so that equal rates
/// give classical discounting on every set, ∅ included (eq 13).
pub fn set_rate_per_second(set: usize, class_rates: &[f64; 5], set_rate: SetRate) -> f64 {
    let members = if set == 0 { OMEGA } else { set };
    let rates = (0..5)
        .filter(|k| members & (1 << k) != 0)
        .map(|k| class_rates[k]);
    match set_rate {
        SetRate::Min => rates.fold(f64::INFINITY, f64::min),
        SetRate::Max => rates.fold(f64::NEG_INFINITY, f64::max),
        SetRate::Mean => {
            let count = members.count_ones() as f64;
            rates.sum::<f64>() / count
        }
    }
}
