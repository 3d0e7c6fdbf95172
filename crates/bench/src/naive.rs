//! The naive baseline: SPEC §5 as a straightforward per-cell program.
//!
//! An array of structs (one [`NaiveCell`] of 32 masses per cell) and every combination as a dense
//! loop over all pairs of focal sets, the way one writes the step from the equations before
//! thinking about speed. It does the same arithmetic as the library's kernel, so the bench checks
//! the two against each other on random cells before timing them; it is the `naive` row of
//! `evigrid bench`, the baseline the kernel's speed is stated against.

use evigrid::{
    DiscountMode, GisGrid, N_SETS, OMEGA, Params, PerceptionGrid, ResidualPolicy, SensorGrid,
    UnobservedCells, class, prior_beta, prior_focal_set, rate_for_step, set_rate_per_second,
};
use geodata::MapContext;

/// Below this 1 − K the sensor and the map are in total conflict (the kernel's margin).
const TOTAL_CONFLICT_MARGIN: f64 = 1e-6;
/// Below this, a mass left to rescale under `normalise` counts as zero (the kernel's threshold).
const TOO_SMALL_TO_RESCALE: f32 = 1e-6;

/// One cell of the naive grid: the PerceptionGrid's state, as a struct.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NaiveCell {
    /// Masses indexed by focal-set bitmask (F = bit 0 … M = bit 4).
    pub m: [f32; N_SETS],
    /// The accumulator ζ.
    pub zeta: f32,
    /// ∅_FO of the last step.
    pub conflict_fo: f32,
    /// ∅_OF of the last step.
    pub conflict_of: f32,
}

impl NaiveCell {
    /// The vacuous cell: m(Ω) = 1, ζ = 0.
    pub fn vacuous() -> Self {
        let mut m = [0.0; N_SETS];
        m[OMEGA] = 1.0;
        NaiveCell {
            m,
            zeta: 0.0,
            conflict_fo: 0.0,
            conflict_of: 0.0,
        }
    }
}

/// The naive grid: one struct per cell, in storage order.
#[derive(Clone, Debug)]
pub struct NaiveGrid {
    /// The cells.
    pub cells: Vec<NaiveCell>,
}

impl NaiveGrid {
    /// A copy of a library PerceptionGrid in the naive layout.
    pub fn from_perception(pg: &PerceptionGrid) -> Self {
        let cells = (0..pg.len())
            .map(|idx| NaiveCell {
                m: pg.cell_masses(idx),
                zeta: pg.zeta()[idx],
                conflict_fo: pg.conflict_fo()[idx],
                conflict_of: pg.conflict_of()[idx],
            })
            .collect();
        NaiveGrid { cells }
    }

    /// One step of SPEC §5 on every cell, one thread, dense loops.
    pub fn step(&mut self, sg: &SensorGrid, gg: &GisGrid, params: &Params, dt_s: f64) {
        let rates = Rates::new(params, dt_s);
        for (idx, cell) in self.cells.iter_mut().enumerate() {
            step_cell(
                cell,
                sg.m_free()[idx],
                sg.m_occupied()[idx],
                gg.context[idx],
                params,
                &rates,
            );
        }
    }
}

/// The discount rates of this step, per focal set or per class context.
struct Rates {
    per_set: [f32; N_SETS],
    per_class: [f32; 5],
}

impl Rates {
    fn new(params: &Params, dt_s: f64) -> Self {
        let dt_s = dt_s.max(0.0);
        let fusion = &params.fusion;
        let class_rates = fusion.discount_per_second.as_array();
        let per_set = std::array::from_fn(|set| {
            let set = if fusion.discount_mode == DiscountMode::Classical {
                OMEGA
            } else {
                set
            };
            rate_for_step(
                set_rate_per_second(set, &class_rates, fusion.set_rate),
                dt_s,
            ) as f32
        });
        let per_class = class_rates.map(|rate| rate_for_step(rate, dt_s) as f32);
        Rates { per_set, per_class }
    }
}

/// Dense conjunctive rule: every pair (A, B) gives m1(A)·m2(B) to A ∩ B (eq 8).
fn conjunctive(m1: &[f32; N_SETS], m2: &[f32; N_SETS]) -> [f32; N_SETS] {
    let mut out = [0.0; N_SETS];
    for a in 0..N_SETS {
        for b in 0..N_SETS {
            out[a & b] += m1[a] * m2[b];
        }
    }
    out
}

/// Dense disjunctive rule: every pair (A, B) gives m1(A)·m2(B) to A ∪ B (eq 12).
fn disjunctive(m1: &[f32; N_SETS], m2: &[f32; N_SETS]) -> [f32; N_SETS] {
    let mut out = [0.0; N_SETS];
    for a in 0..N_SETS {
        for b in 0..N_SETS {
            out[a | b] += m1[a] * m2[b];
        }
    }
    out
}

/// The GISGrid mass function of a map context (SPEC §4, eq 34-38), dense.
fn map_prior(context: MapContext, params: &Params) -> [f32; N_SETS] {
    let (set, beta) = (prior_focal_set(context), prior_beta(context, &params.map));
    let mut m = [0.0; N_SETS];
    m[set] += beta as f32;
    m[OMEGA] += 1.0 - beta as f32;
    m
}

/// Sum of the masses of the non-empty subsets of O = {I, U, S, M} (eq 22-23).
fn occupied(m: &[f32; N_SETS]) -> f32 {
    (1..N_SETS)
        .filter(|set| set & class::F == 0)
        .map(|set| m[set])
        .sum()
}

/// The residual policy on m(∅).
fn settle_empty_set(m: &mut [f32; N_SETS], policy: ResidualPolicy) {
    match policy {
        ResidualPolicy::ToOmega => {
            m[OMEGA] += m[0];
            m[0] = 0.0;
        }
        ResidualPolicy::Normalise => {
            let rest: f32 = m[1..].iter().sum();
            if rest > TOO_SMALL_TO_RESCALE {
                for x in &mut m[1..] {
                    *x /= rest;
                }
            } else {
                m[OMEGA] += m[0];
            }
            m[0] = 0.0;
        }
        _ => {}
    }
}

fn step_cell(
    cell: &mut NaiveCell,
    m_free: f32,
    m_occupied: f32,
    context: MapContext,
    params: &Params,
    rates: &Rates,
) {
    // 1. Refine the sensor's {F, O} masses into Ω_PG (eq 16-20).
    let free = m_free.clamp(0.0, 1.0);
    let occ = m_occupied.clamp(0.0, 1.0 - free);
    let mut refined = [0.0; N_SETS];
    refined[class::F] = free;
    refined[class::O] = occ;
    refined[OMEGA] = 1.0 - free - occ;
    // 2. Dempster's rule with the map prior (eq 21).
    let combined = conjunctive(&refined, &map_prior(context, params));
    let k = combined[0];
    let sensor = if f64::from(k) >= 1.0 - TOTAL_CONFLICT_MARGIN {
        refined
    } else {
        let mut normalised = combined.map(|x| x / (1.0 - k));
        normalised[0] = 0.0;
        normalised
    };
    // 3. Discount the previous grid.
    let mut past = cell.m;
    match params.fusion.discount_mode {
        DiscountMode::Mercier => {
            for (bit, &alpha) in rates.per_class.iter().enumerate() {
                let mut context_mass = [0.0; N_SETS];
                context_mass[0] = 1.0 - alpha;
                context_mass[1 << bit] = alpha;
                past = disjunctive(&past, &context_mass);
            }
        }
        _ => {
            for set in 0..OMEGA {
                let moved = rates.per_set[set] * past[set];
                past[set] -= moved;
                past[OMEGA] += moved;
            }
        }
    }
    if params.fusion.unobserved == UnobservedCells::DiscountOnly && free + occ <= 0.0 {
        cell.m = past;
        cell.conflict_fo = 0.0;
        cell.conflict_of = 0.0;
        return;
    }
    // 4. The modified conjunctive rule (eq 22-23, 30-31).
    let sensor_occupied = occupied(&sensor);
    let conflict_fo = past[class::F] * sensor_occupied;
    let conflict_of = occupied(&past) * sensor[class::F];
    let mut m = conjunctive(&past, &sensor);
    m[class::M] += conflict_fo;
    m[OMEGA] += conflict_of;
    m[0] = (m[0] - conflict_fo - conflict_of).max(0.0);
    settle_empty_set(&mut m, params.fusion.residual);
    // 5. The accumulator (eq 24-27).
    let acc = &params.accumulator;
    let conflict = conflict_fo + conflict_of;
    if occupied(&m) >= acc.gamma_occupied as f32 && conflict <= acc.gamma_conflict as f32 {
        cell.zeta = (cell.zeta + acc.delta_inc as f32).min(1.0);
    } else if conflict > acc.gamma_conflict as f32 {
        cell.zeta = (cell.zeta - acc.delta_dec as f32).max(0.0);
    }
    // 6. Specialisation by the matrix of eq 29.
    let mut matrix = [[0.0f32; N_SETS]; N_SETS];
    for (a, row) in matrix.iter_mut().enumerate() {
        if a & class::M != 0 {
            row[a] = 1.0 - cell.zeta;
        } else {
            row[a] = 1.0;
            row[a | class::M] = cell.zeta;
        }
    }
    let mut specialised = [0.0; N_SETS];
    for (a, row) in matrix.iter().enumerate() {
        for b in 0..N_SETS {
            specialised[a] += row[b] * m[b];
        }
    }
    settle_empty_set(&mut specialised, params.fusion.residual);
    cell.m = specialised;
    cell.conflict_fo = conflict_fo;
    cell.conflict_of = conflict_of;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The naive step and the library's kernel agree on random cells, in every mode.
    #[test]
    fn naive_matches_the_library_kernel() {
        let mut params = Params::default();
        for mode in [
            DiscountMode::ClassRates,
            DiscountMode::Classical,
            DiscountMode::Mercier,
        ] {
            for residual in [
                ResidualPolicy::ToOmega,
                ResidualPolicy::Keep,
                ResidualPolicy::Normalise,
            ] {
                for unobserved in [UnobservedCells::Fuse, UnobservedCells::DiscountOnly] {
                    params.fusion.discount_mode = mode;
                    params.fusion.residual = residual;
                    params.fusion.unobserved = unobserved;
                    let worst = crate::workload::max_difference_after_steps(&params, 40, 30, 7);
                    assert!(
                        worst < 1e-5,
                        "{mode:?}/{residual:?}/{unobserved:?}: differs by {worst}"
                    );
                }
            }
        }
    }
}
