//! What the step derives from the parameters once, before touching a cell: the discount rates
//! for this step's `dt` (SPEC §5 step 3), the map prior of each context as the passes apply it
//! (SPEC §4), the accumulator's thresholds (eq 24-27) and the specialisation's transfers.

use super::evidence::CellEvidence;
use super::passes::{ALL_SETS, Live, REACHABLE, Restriction};
use crate::grids::{N_SETS, OMEGA, class};
use crate::params::{DiscountMode, Params, ResidualPolicy, SetRate, UnobservedCells};
use geodata::MapContext;

/// Everything the step derives from the parameters once, before touching a cell.
#[derive(Clone, Debug)]
pub(super) struct StepConstants {
    pub(super) discount: Discount,
    /// The GISGrid mass function of each map context, indexed by `MapContext as u8`.
    pub(super) map_prior: [MapPrior; 4],
    pub(super) residual: ResidualPolicy,
    pub(super) delta_inc: f32,
    pub(super) delta_dec: f32,
    pub(super) gamma_occupied: f32,
    pub(super) gamma_conflict: f32,
    /// SG' of a cell the scan did not reach, per map context.
    pub(super) unobserved_evidence: [CellEvidence; 4],
    /// SPEC §6: above this m(Ω) a cell is decided unknown.
    pub(super) unknown_threshold: f32,
    pub(super) unobserved: UnobservedCells,
    /// The transfers of the specialisation (step 6): A ∋ M to A∖{M}.
    pub(super) specialisation: Restrictions,
}

/// The discounting of step 3, as rates for this step's `dt`.
#[derive(Clone, Debug)]
pub(super) enum Discount {
    /// Classical and class-rate discounting: the rate α_A(dt) of every focal set, to Ω.
    ToOmega([f32; N_SETS]),
    /// Mercier contextual discounting: the rate α_θ(dt) of each class context {θ}.
    Mercier([f32; 5]),
}

/// The GISGrid of one map context: β on the focal set G, 1 − β on Ω (eq 34-38), with the
/// indicators SG' needs, as 0/1 factors.
#[derive(Clone, Copy, Debug)]
pub(super) struct MapPrior {
    /// The focal set G.
    pub(super) g: usize,
    /// The transfers of m ∩ GG, for blocks on the reachable sets and for any block.
    pub(super) restriction: Restrictions,
    pub(super) beta: f32,
    /// [F ∈ G], [O ∩ G ≠ ∅], [G = {F}], [∅ ≠ G ⊆ O].
    pub(super) free_in_g: f32,
    pub(super) occupied_meets_g: f32,
    pub(super) g_is_free: f32,
    pub(super) g_within_occupied: f32,
}

impl MapPrior {
    fn new(g: usize, beta: f64) -> Self {
        let indicator = |condition: bool| if condition { 1.0 } else { 0.0 };
        MapPrior {
            g,
            restriction: Restrictions::new(g),
            beta: beta as f32,
            free_in_g: indicator(g & class::F != 0),
            occupied_meets_g: indicator(g & class::O != 0),
            g_is_free: indicator(g == class::F),
            g_within_occupied: indicator(g != 0 && g & class::F == 0),
        }
    }

    /// Whether combining with this prior can change a mass function.
    pub(super) fn is_informative(&self) -> bool {
        self.g != OMEGA && self.beta > 0.0
    }
}

/// The [`Restriction`] to one focal set G, for the two families of live sets a block can have.
#[derive(Clone, Copy, Debug)]
pub(super) struct Restrictions {
    reachable: Restriction,
    all: Restriction,
}

impl Restrictions {
    fn new(g: usize) -> Self {
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
        let map = &params.map;
        let mut map_prior = [MapPrior::new(OMEGA, 0.0); 4];
        map_prior[MapContext::Other as usize] =
            MapPrior::new(class::F | class::U | class::S | class::M, map.beta_other);
        map_prior[MapContext::Road as usize] =
            MapPrior::new(class::F | class::S | class::M, map.beta_road);
        map_prior[MapContext::Building as usize] = MapPrior::new(class::I, map.beta_building);
        let acc = &params.accumulator;
        StepConstants {
            discount,
            map_prior,
            residual: fusion.residual,
            delta_inc: acc.delta_inc as f32,
            delta_dec: acc.delta_dec as f32,
            gamma_occupied: acc.gamma_occupied as f32,
            gamma_conflict: acc.gamma_conflict as f32,
            unobserved_evidence: map_prior.map(|prior| CellEvidence::unobserved(&prior)),
            unknown_threshold: params.decision.unknown_threshold as f32,
            unobserved: fusion.unobserved,
            specialisation: Restrictions::new(OMEGA ^ class::M),
        }
    }
}
