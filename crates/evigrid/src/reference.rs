//! The step of SPEC §5 on one cell, in f64, written with the generic operations of the `belief`
//! crate: refining, Dempster's rule, the three discountings, the conjunctive rule and the
//! specialisation.
//!
//! It is slow (dense 32 × 32 combinations and heap-allocated mass functions) and serves as the
//! yardstick the grid kernel of [`step`](crate::step()) is tested against; read it to see the
//! method written as the paper writes it.
//!
//! ```
//! use evigrid::{Params, reference::{CellState, reference_step}};
//! use geodata::MapContext;
//!
//! let params = Params::default();
//! let cell = reference_step(&CellState::vacuous(), 0.7, 0.0, MapContext::Road, &params, 0.1)?;
//! assert!((cell.masses[1] - 0.7).abs() < 1e-12); // m({F})
//! # Ok::<(), belief::BeliefError>(())
//! ```

use crate::grids::{N_SETS, OMEGA, class};
use crate::params::{DiscountMode, MapParams, Params, ResidualPolicy, UnobservedCells};
use belief::{
    BeliefError, ClassRateDiscount, ClassicalDiscount, Combination, Conjunctive,
    ContextualDiscount, Dempster, Discounting, Frame, Mass, Refining, Set, specialise_without,
};
use geodata::MapContext;

/// The state of one PerceptionGrid cell, in f64.
#[derive(Clone, Debug, PartialEq)]
pub struct CellState {
    /// m(A) for every A ⊆ Ω_PG, indexed by bitmask.
    pub masses: [f64; N_SETS],
    /// The accumulator ζ.
    pub zeta: f64,
    /// ∅_FO of the last step.
    pub conflict_fo: f64,
    /// ∅_OF of the last step.
    pub conflict_of: f64,
    /// Whether the sensor ever said something about the cell.
    pub seen: bool,
}

impl CellState {
    /// A cell that just entered the window: m(Ω) = 1, ζ = 0, never seen.
    pub fn vacuous() -> Self {
        let mut masses = [0.0; N_SETS];
        masses[OMEGA] = 1.0;
        CellState {
            masses,
            zeta: 0.0,
            conflict_fo: 0.0,
            conflict_of: 0.0,
            seen: false,
        }
    }
}

/// The frame Ω_PG = {F, I, U, S, M}, in bit order.
pub fn perception_frame() -> Result<Frame, BeliefError> {
    Frame::new(["F", "I", "U", "S", "M"])
}

/// The GISGrid mass function of a map context (eq 34-38).
pub fn map_prior(
    frame: &Frame,
    context: MapContext,
    map: &MapParams,
) -> Result<Mass<f64>, BeliefError> {
    let (focal, beta) = match context {
        MapContext::Unknown => return Ok(Mass::vacuous(frame)),
        MapContext::Building => (class::I, map.beta_building),
        MapContext::BuildingEdge => (class::F | class::I, map.beta_building),
        MapContext::Road => (class::F | class::S | class::M, map.beta_road),
        MapContext::Other => (class::F | class::U | class::S | class::M, map.beta_other),
    };
    let mut values = vec![0.0; N_SETS];
    values[focal] = beta;
    values[OMEGA] += 1.0 - beta;
    Mass::from_values(frame, values)
}

/// One step of SPEC §5 on one cell: `state` at t − 1, the SensorGrid masses `m_free`, `m_occupied`
/// of this cell, its map `context`, `dt_s` seconds since the previous step.
///
/// `state.masses` may come from the f32 grid: they are rescaled to sum exactly to 1 first.
///
/// # Errors
/// A [`BeliefError`] if the masses or parameters are not valid mass functions or rates (the
/// parameters should have passed [`Params::validate`]).
pub fn reference_step(
    state: &CellState,
    m_free: f64,
    m_occupied: f64,
    context: MapContext,
    params: &Params,
    dt_s: f64,
) -> Result<CellState, BeliefError> {
    reference_step_traced(state, m_free, m_occupied, context, params, dt_s).map(|(cell, _)| cell)
}

/// The quantities the accumulator compared with its thresholds (eq 24-27).
#[derive(Clone, Copy, Debug)]
#[cfg_attr(not(test), allow(dead_code))]
pub(crate) struct Trace {
    /// m_PG,t(O) before the specialisation.
    pub(crate) occupied: f64,
    /// ∅_FO + ∅_OF.
    pub(crate) conflict: f64,
}

/// [`reference_step`], also returning what the accumulator compared.
pub(crate) fn reference_step_traced(
    state: &CellState,
    m_free: f64,
    m_occupied: f64,
    context: MapContext,
    params: &Params,
    dt_s: f64,
) -> Result<(CellState, Trace), BeliefError> {
    let pg_frame = perception_frame()?;
    let sg_frame = Frame::new(["F", "O"])?;
    let policy = params.fusion.residual;
    // 1. Refine SG into Ω_PG: F → {F}, O → {I,U,S,M} (eq 16-20).
    let sg = Mass::from_values(
        &sg_frame,
        vec![0.0, m_free, m_occupied, 1.0 - m_free - m_occupied],
    )?;
    let refining = Refining::new(&sg_frame, &pg_frame, vec![set(class::F), set(class::O)])?;
    let refined = refining.apply(&sg)?;
    // 2. SG' = r(SG) ⊕ GG; on total conflict keep r(SG) (eq 21, SPEC §5 step 2).
    let gg = map_prior(&pg_frame, context, &params.map)?;
    let sg_prime = match Dempster.combine(&refined, &gg) {
        Err(BeliefError::TotalConflict) => refined,
        other => other?,
    };
    // 3. Discount the previous grid.
    let total: f64 = state.masses.iter().sum();
    let previous = Mass::from_values(&pg_frame, state.masses.map(|m| m / total).to_vec())?;
    let dt_s = dt_s.max(0.0);
    let fusion = &params.fusion;
    let rates_1s = fusion.discount_per_second.as_array();
    let set_rates = ClassRateDiscount::new(rates_1s.to_vec(), belief_set_rate(fusion.set_rate))?;
    let discounted = match fusion.discount_mode {
        DiscountMode::Classical => {
            let alpha = rate_for_step(set_rates.rate_of(pg_frame.omega()), dt_s);
            ClassicalDiscount::new(alpha)?.discount(&previous)?
        }
        DiscountMode::ClassRates => {
            // α_A per second from the class rates (belief crate), then converted to dt:
            // aggregating before converting keeps every set's rate a true rate per second.
            let mut values = previous.values().to_vec();
            for s in pg_frame.subsets().filter(|&s| s != pg_frame.omega()) {
                let moved = rate_for_step(set_rates.rate_of(s), dt_s) * values[s.index()];
                values[s.index()] -= moved;
                values[OMEGA] += moved;
            }
            Mass::from_values(&pg_frame, values)?
        }
        DiscountMode::Mercier => {
            let rates = rates_1s.map(|rate| rate_for_step(rate, dt_s));
            ContextualDiscount::singletons(&rates)?.discount(&previous)?
        }
    };
    let observed = m_free + m_occupied > 0.0;
    if fusion.unobserved == UnobservedCells::DiscountOnly && !observed {
        let occupied = occupied_mass(&discounted);
        let mut masses = [0.0; N_SETS];
        masses.copy_from_slice(discounted.values());
        let cell = CellState {
            masses,
            conflict_fo: 0.0,
            conflict_of: 0.0,
            ..*state
        };
        let trace = Trace {
            occupied,
            conflict: 0.0,
        };
        return Ok((cell, trace));
    }
    // 4. Modified conjunctive rule (eq 22-23, 30-31).
    let combined = Conjunctive.combine(&discounted, &sg_prime)?;
    let conflict_fo = discounted.get(set(class::F)) * occupied_mass(&sg_prime);
    let conflict_of = occupied_mass(&discounted) * sg_prime.get(set(class::F));
    let mut values = combined.values().to_vec();
    values[class::M] += conflict_fo;
    values[OMEGA] += conflict_of;
    values[0] = (values[0] - conflict_fo - conflict_of).max(0.0);
    let values = settle_empty_set(&pg_frame, values, policy)?;
    // 5. Accumulator (eq 24-27).
    let acc = &params.accumulator;
    let occupied: f64 = (1..N_SETS)
        .filter(|s| s & class::F == 0)
        .map(|s| values[s])
        .sum();
    let conflict = conflict_fo + conflict_of;
    let zeta = if occupied >= acc.gamma_occupied && conflict <= acc.gamma_conflict {
        (state.zeta + acc.delta_inc).min(1.0)
    } else if conflict > acc.gamma_conflict {
        (state.zeta - acc.delta_dec).max(0.0)
    } else {
        state.zeta
    };
    // 6. Specialise (eq 28-29); what {M} gives to ∅ follows the residual policy.
    let fused = Mass::from_values(&pg_frame, values)?;
    let specialised = specialise_without(&fused, 4, zeta)?;
    let values = settle_empty_set(&pg_frame, specialised.into_values(), policy)?;
    let mut masses = [0.0; N_SETS];
    masses.copy_from_slice(&values);
    let cell = CellState {
        masses,
        zeta,
        conflict_fo,
        conflict_of,
        seen: state.seen || observed,
    };
    Ok((cell, Trace { occupied, conflict }))
}

/// α(dt) = 1 − (1 − α_1s)^dt (SPEC §5 step 3). Written here rather than taken from the kernel,
/// so that the yardstick shares no code with what it measures.
fn rate_for_step(rate_per_second: f64, dt_s: f64) -> f64 {
    1.0 - (1.0 - rate_per_second).powf(dt_s)
}

fn set(bits: usize) -> Set {
    Set::from_bits(bits as u8)
}

/// m(O): the mass of the non-empty subsets of {I, U, S, M} (eq 22-23).
fn occupied_mass(m: &Mass<f64>) -> f64 {
    m.focal_sets()
        .filter(|(s, _)| !s.is_empty() && s.is_subset_of(set(class::O)))
        .map(|(_, mass)| mass)
        .sum()
}

fn belief_set_rate(rate: crate::params::SetRate) -> belief::SetRate {
    match rate {
        crate::params::SetRate::Min => belief::SetRate::Min,
        crate::params::SetRate::Max => belief::SetRate::Max,
        crate::params::SetRate::Mean => belief::SetRate::Mean,
    }
}

/// The residual policy applied to the mass on ∅.
fn settle_empty_set(
    frame: &Frame,
    mut values: Vec<f64>,
    policy: ResidualPolicy,
) -> Result<Vec<f64>, BeliefError> {
    match policy {
        ResidualPolicy::Keep => return Ok(values),
        ResidualPolicy::Normalise => match Mass::from_values(frame, values.clone())?.normalised() {
            Ok(m) => return Ok(m.into_values()),
            Err(BeliefError::TotalConflict) => {}
            Err(e) => return Err(e),
        },
        ResidualPolicy::ToOmega => {}
    }
    values[OMEGA] += values[0];
    values[0] = 0.0;
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::ResidualPolicy;

    type TestResult = Result<(), Box<dyn std::error::Error>>;

    #[test]
    fn observing_a_vacuous_building_cell_free_is_conflict_normalised() -> TestResult {
        // r(SG): {F} 0.7, Ω 0.3; GG: {I} 0.9, Ω 0.1. K = 0.7·0.9 = 0.63, 1 − K = 0.37:
        // {F} 0.07/0.37, {I} 0.27/0.37, Ω 0.03/0.37. (δ_inc = 0 keeps ζ at 0: no specialisation.)
        let mut params = Params::default();
        params.accumulator.delta_inc = 0.0;
        let cell = reference_step(
            &CellState::vacuous(),
            0.7,
            0.0,
            MapContext::Building,
            &params,
            0.1,
        )?;
        assert!((cell.masses[class::F] - 0.07 / 0.37).abs() < 1e-12);
        assert!((cell.masses[class::I] - 0.27 / 0.37).abs() < 1e-12);
        assert!((cell.masses[OMEGA] - 0.03 / 0.37).abs() < 1e-12);
        assert!(cell.seen);
        Ok(())
    }

    #[test]
    fn the_map_prior_table_agrees_with_the_reference_in_every_context() -> TestResult {
        // Distinct β, so that a context given another's β shows; 1 and 0 at the ends.
        let frame = perception_frame()?;
        for betas in [(0.9, 0.6, 0.7), (0.25, 0.5, 0.75), (1.0, 0.0, 1.0)] {
            let mut map = MapParams::default();
            (map.beta_building, map.beta_road, map.beta_other) = betas;
            for context in crate::map_prior::MAP_CONTEXTS {
                let focal = crate::map_prior::prior_focal_set(context);
                let beta = crate::map_prior::prior_beta(context, &map);
                let mut table = vec![0.0; N_SETS];
                table[focal] += beta;
                table[OMEGA] += 1.0 - beta;
                let reference = map_prior(&frame, context, &map)?;
                assert_eq!(reference.values(), &table[..], "{context:?}, β {betas:?}");
            }
        }
        Ok(())
    }

    #[test]
    fn keep_policy_leaves_mass_on_empty_set() -> TestResult {
        // PG {F} 1 (no discount), SG occupied 0.8 on an unknown-context cell:
        // c = {∅: 0.8, F: 0.2}; ∅_FO = 1·0.8 → {M}; the residual is 0.
        let mut params = Params::default();
        params.fusion.residual = ResidualPolicy::Keep;
        params.fusion.discount_per_second = crate::params::ClassRates::uniform(0.0);
        let mut state = CellState::vacuous();
        state.masses = [0.0; N_SETS];
        state.masses[class::F] = 1.0;
        let cell = reference_step(&state, 0.0, 0.8, MapContext::Unknown, &params, 0.1)?;
        assert!((cell.masses[class::M] - 0.8).abs() < 1e-12);
        assert!((cell.masses[class::F] - 0.2).abs() < 1e-12);
        assert!(cell.masses[0].abs() < 1e-12);
        assert!((cell.conflict_fo - 0.8).abs() < 1e-12);
        Ok(())
    }
}
