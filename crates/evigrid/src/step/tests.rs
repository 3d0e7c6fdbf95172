//! Tests of the step: each stage on one cell with hand-computed numbers, the kernel against the
//! f64 reference on random cells, and thread-count independence.

#![allow(clippy::unwrap_used)]

use super::constants::StepConstants;
use super::*;
use crate::grids::class::{F, I, M, O, S, U};
use crate::grids::{N_SETS, OMEGA};
use crate::params::{ClassRates, DiscountMode, Params, ResidualPolicy, SetRate, UnobservedCells};
use crate::reference::{CellState, reference_step_traced};
use geodata::MapContext;
use proptest::prelude::*;

/// One cell's state and what the step reported.
struct Cell {
    m: [f32; N_SETS],
    zeta: f32,
    fo: f32,
    of: f32,
    seen: bool,
    stats: StepStats,
}

/// Runs one step on a 1×1 grid from `prior` (masses by set), ζ = `zeta`.
fn one_step(
    prior: &[(usize, f32)],
    zeta: f32,
    sensor: (f32, f32),
    context: MapContext,
    params: &Params,
    dt_s: f64,
) -> Cell {
    let mut pg = PerceptionGrid::new(1, 1);
    let mut m = [0.0; N_SETS];
    for &(set, mass) in prior {
        m[set] = mass;
    }
    pg.set_cell_masses(0, &m);
    pg.zeta_mut()[0] = zeta;
    let mut sg = SensorGrid::new(1, 1);
    (sg.m_free_mut()[0], sg.m_occupied_mut()[0]) = sensor;
    let mut gg = GisGrid::new(1, 1);
    gg.context[0] = context;
    let stats = step(&mut pg, &sg, &gg, params, dt_s);
    Cell {
        m: pg.cell_masses(0),
        zeta: pg.zeta()[0],
        fo: pg.conflict_fo()[0],
        of: pg.conflict_of()[0],
        seen: pg.seen()[0] != 0,
        stats,
    }
}

/// Asserts that the cell's masses are exactly `expected` (within 1e-6), all others 0.
#[track_caller]
fn assert_masses(cell: &Cell, expected: &[(usize, f32)]) {
    let mut want = [0.0; N_SETS];
    for &(set, mass) in expected {
        want[set] += mass;
    }
    for set in 0..N_SETS {
        assert!(
            (cell.m[set] - want[set]).abs() < 1e-6,
            "m({set:05b}) = {}, expected {} (all: {:?})",
            cell.m[set],
            want[set],
            cell.m
        );
    }
}

/// The parameters the hand-computed numbers below assume, pinned so that tuning the defaults
/// does not change them: β_B 0.9, β_R 0.8, β_T 0.7, and the default rates and accumulator.
fn hand_params() -> Params {
    let mut p = Params::default();
    (p.map.beta_building, p.map.beta_road, p.map.beta_other) = (0.9, 0.8, 0.7);
    p.fusion.discount_per_second = ClassRates {
        free: 0.5,
        mapped_infrastructure: 0.05,
        unmapped_infrastructure: 0.2,
        stopped: 0.3,
        moving: 0.9,
    };
    p.fusion.set_rate = SetRate::Max;
    p.fusion.residual = ResidualPolicy::ToOmega;
    (p.accumulator.delta_inc, p.accumulator.delta_dec) = (0.1, 0.3);
    (p.accumulator.gamma_occupied, p.accumulator.gamma_conflict) = (0.5, 0.2);
    p
}

/// Parameters that leave ζ at 0 and do not discount, to look at one stage alone.
fn still_params() -> Params {
    let mut p = hand_params();
    p.fusion.discount_per_second = ClassRates::uniform(0.0);
    p.accumulator.delta_inc = 0.0;
    p.accumulator.delta_dec = 0.0;
    p
}

const VACUOUS: &[(usize, f32)] = &[(OMEGA, 1.0)];
const NO_SENSOR: (f32, f32) = (0.0, 0.0);

#[test]
fn refining_maps_free_and_occupied_into_the_perception_frame() {
    // Vacuous past, no map: the result is r(SG) itself (eq 16-20).
    let p = still_params();
    let free = one_step(VACUOUS, 0.0, (0.7, 0.0), MapContext::Unknown, &p, 0.1);
    assert_masses(&free, &[(F, 0.7), (OMEGA, 0.3)]);
    let occupied = one_step(VACUOUS, 0.0, (0.0, 0.8), MapContext::Unknown, &p, 0.1);
    assert_masses(&occupied, &[(O, 0.8), (OMEGA, 0.2)]);
    let mixed = one_step(VACUOUS, 0.0, (0.25, 0.5), MapContext::Unknown, &p, 0.1);
    assert_masses(&mixed, &[(F, 0.25), (O, 0.5), (OMEGA, 0.25)]);
    assert!(free.seen && occupied.seen && mixed.seen);
}

#[test]
fn dempster_with_building_prior_normalises_the_conflict() {
    // r(SG) {F} 0.7, Ω 0.3 ⊕ GG {I} 0.9, Ω 0.1: K = 0.7·0.9 = 0.63;
    // {F} 0.07/0.37, {I} 0.27/0.37, Ω 0.03/0.37.
    let p = still_params();
    let cell = one_step(VACUOUS, 0.0, (0.7, 0.0), MapContext::Building, &p, 0.1);
    assert_masses(
        &cell,
        &[(F, 0.07 / 0.37), (I, 0.27 / 0.37), (OMEGA, 0.03 / 0.37)],
    );
    // Occupied: O∩{I} = {I} 0.72, O 0.08, Ω∩{I} = {I} 0.18, Ω 0.02; K = 0.
    let cell = one_step(VACUOUS, 0.0, (0.0, 0.8), MapContext::Building, &p, 0.1);
    assert_masses(&cell, &[(I, 0.9), (O, 0.08), (OMEGA, 0.02)]);
    assert_eq!(cell.stats.total_map_conflicts, 0);
}

#[test]
fn dempster_with_road_prior() {
    // GG {F,S,M} 0.8: free {F} 0.56 + 0.14 = 0.7, {F,S,M} 0.3·0.8 = 0.24, Ω 0.06.
    let p = still_params();
    let cell = one_step(VACUOUS, 0.0, (0.7, 0.0), MapContext::Road, &p, 0.1);
    assert_masses(&cell, &[(F, 0.7), (F | S | M, 0.24), (OMEGA, 0.06)]);
    // Occupied: {S,M} 0.64, O 0.16, {F,S,M} 0.16, Ω 0.04.
    let cell = one_step(VACUOUS, 0.0, (0.0, 0.8), MapContext::Road, &p, 0.1);
    assert_masses(
        &cell,
        &[(S | M, 0.64), (O, 0.16), (F | S | M, 0.16), (OMEGA, 0.04)],
    );
}

#[test]
fn dempster_with_intermediate_space_prior() {
    // GG {F,U,S,M} 0.7, occupied 0.8: {U,S,M} 0.56, O 0.24, {F,U,S,M} 0.14, Ω 0.06.
    let p = still_params();
    let cell = one_step(VACUOUS, 0.0, (0.0, 0.8), MapContext::Other, &p, 0.1);
    let t = F | U | S | M;
    assert_masses(
        &cell,
        &[(U | S | M, 0.56), (O, 0.24), (t, 0.14), (OMEGA, 0.06)],
    );
}

#[test]
fn beside_a_building_free_stays_free_and_a_return_is_the_building() {
    // GG {F,I} 0.9. Free 0.7: {F} 0.7 (no conflict, F ∈ G), {F,I} 0.3·0.9 = 0.27, Ω 0.03.
    let p = still_params();
    let cell = one_step(VACUOUS, 0.0, (0.7, 0.0), MapContext::BuildingEdge, &p, 0.1);
    assert_masses(&cell, &[(F, 0.7), (F | I, 0.27), (OMEGA, 0.03)]);
    // Occupied 0.8: O∩{F,I} = {I} 0.72, O 0.08, {F,I} 0.18, Ω 0.02; K = 0.
    let cell = one_step(VACUOUS, 0.0, (0.0, 0.8), MapContext::BuildingEdge, &p, 0.1);
    assert_masses(&cell, &[(I, 0.72), (O, 0.08), (F | I, 0.18), (OMEGA, 0.02)]);
    assert_eq!(cell.stats.total_map_conflicts, 0);
}

#[test]
fn total_conflict_with_the_map_keeps_the_sensor_and_is_counted() {
    // β_B = 1 and m(F) = 1: K = 1. SG' = r(SG) = {F} 1.
    let mut p = still_params();
    p.map.beta_building = 1.0;
    let cell = one_step(VACUOUS, 0.0, (1.0, 0.0), MapContext::Building, &p, 0.1);
    assert_masses(&cell, &[(F, 1.0)]);
    assert_eq!(cell.stats.total_map_conflicts, 1);
}

/// Prior for the discounting tests: {F} 0.5, {S,M} 0.3, Ω 0.2, seen through a vacuous sensor
/// (the fusion is then the identity, m(O) = 0.3 < γ_O and there is no conflict).
const PRIOR: &[(usize, f32)] = &[(F, 0.5), (S | M, 0.3), (OMEGA, 0.2)];

fn discount_params(mode: DiscountMode, set_rate: SetRate, rates: ClassRates) -> Params {
    let mut p = still_params();
    p.fusion.discount_mode = mode;
    p.fusion.set_rate = set_rate;
    p.fusion.discount_per_second = rates;
    p
}

#[test]
fn classical_discounting_and_rate_per_second() {
    // α = 0.5 per second over 1 s: every set keeps half; Ω = 0.2 + 0.25 + 0.15.
    let p = discount_params(
        DiscountMode::Classical,
        SetRate::Max,
        ClassRates::uniform(0.5),
    );
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 1.0);
    assert_masses(&cell, &[(F, 0.25), (S | M, 0.15), (OMEGA, 0.6)]);
    // Over 0.5 s: α = 1 − 0.5^0.5 = 0.292893, kept 0.707107: F 0.353553, SM 0.212132.
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 0.5);
    assert_masses(
        &cell,
        &[(F, 0.353553), (S | M, 0.212132), (OMEGA, 0.434315)],
    );
    // Two steps of 0.5 s equal one of 1 s: kept 0.707107² = 0.5.
    assert!((rate_for_step(rate_for_step(0.5, 0.5), 2.0) - 0.5).abs() < 1e-12);
    // With unequal class rates, classical uses their set_rate aggregate: max = 0.9.
    let p = discount_params(DiscountMode::Classical, SetRate::Max, ClassRates::default());
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 1.0);
    assert_masses(&cell, &[(F, 0.05), (S | M, 0.03), (OMEGA, 0.92)]);
}

#[test]
fn class_rate_discounting_each_set_rate() {
    // Rates F 0.5, I 0.05, U 0.2, S 0.3, M 0.9 per second, dt = 1 s. {F} keeps 0.25.
    let rates = ClassRates::default();
    // max: α_{S,M} = 0.9 → 0.03; Ω = 0.2 + 0.25 + 0.27 = 0.72.
    let p = discount_params(DiscountMode::ClassRates, SetRate::Max, rates);
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 1.0);
    assert_masses(&cell, &[(F, 0.25), (S | M, 0.03), (OMEGA, 0.72)]);
    // min: α_{S,M} = 0.3 → 0.21; Ω = 0.2 + 0.25 + 0.09 = 0.54.
    let p = discount_params(DiscountMode::ClassRates, SetRate::Min, rates);
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 1.0);
    assert_masses(&cell, &[(F, 0.25), (S | M, 0.21), (OMEGA, 0.54)]);
    // mean: α_{S,M} = 0.6 → 0.12; Ω = 0.2 + 0.25 + 0.18 = 0.63.
    let p = discount_params(DiscountMode::ClassRates, SetRate::Mean, rates);
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 1.0);
    assert_masses(&cell, &[(F, 0.25), (S | M, 0.12), (OMEGA, 0.63)]);
    // mean over 0.5 s: the set's rate per second is converted, α = 1 − 0.4^0.5, kept 0.632456:
    // {S,M} 0.189737; {F} 0.353553; Ω 0.456710.
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 0.5);
    assert_masses(
        &cell,
        &[(F, 0.353553), (S | M, 0.189737), (OMEGA, 0.456710)],
    );
}

#[test]
fn class_rates_with_equal_rates_is_classical() {
    let rates = ClassRates::uniform(0.3);
    for set_rate in [SetRate::Min, SetRate::Max, SetRate::Mean] {
        let a = discount_params(DiscountMode::ClassRates, set_rate, rates);
        let b = discount_params(DiscountMode::Classical, set_rate, rates);
        let ca = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &a, 0.7);
        let cb = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &b, 0.7);
        assert_eq!(ca.m, cb.m);
    }
}

#[test]
fn mercier_discounting_moves_mass_to_supersets() {
    // Rates F 0.5, I 0.05, U 0.2, S 0.3, M 0.9, dt = 1 s. Each missing class θ joins a set with
    // probability α_θ, independently:
    // {F} keeps 0.5·(0.95·0.8·0.7·0.1) = 0.0266;
    // {S,M} keeps 0.3·(0.5·0.95·0.8) = 0.114;
    // {F,S,M} gets 0.3·0.5·0.95·0.8 = 0.114 from {S,M} and 0.5·0.3·0.9·0.95·0.8 = 0.1026 from {F};
    // Ω gets 0.5·0.05·0.2·0.3·0.9 = 0.00135 from {F} and 0.3·0.5·0.05·0.2 = 0.0015 from {S,M}.
    let p = discount_params(DiscountMode::Mercier, SetRate::Max, ClassRates::default());
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 1.0);
    assert!((cell.m[F] - 0.0266).abs() < 1e-6);
    assert!((cell.m[S | M] - 0.114).abs() < 1e-6);
    assert!((cell.m[F | S | M] - 0.2166).abs() < 1e-6);
    assert!((cell.m[OMEGA] - 0.20285).abs() < 1e-6);
    assert!((cell.m.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    // Equal rates are not classical discounting: {F} also goes to {F,I} etc., not only to Ω.
    let p = discount_params(
        DiscountMode::Mercier,
        SetRate::Max,
        ClassRates::uniform(0.5),
    );
    let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, 1.0);
    assert!((cell.m[F | I] - 0.5 * 0.5 * 0.125).abs() < 1e-6);
}

#[test]
fn negative_or_nan_dt_does_not_discount() {
    let p = discount_params(
        DiscountMode::Classical,
        SetRate::Max,
        ClassRates::uniform(0.5),
    );
    for dt in [-1.0, f64::NAN, 0.0] {
        let cell = one_step(PRIOR, 0.0, NO_SENSOR, MapContext::Unknown, &p, dt);
        assert_masses(&cell, PRIOR);
    }
}

#[test]
fn conflict_fo_goes_to_moving() {
    // Past {F} 0.6, {S} 0.3, Ω 0.1; sensor occupied 0.8, no map, no discount, ζ = 0.5.
    // c: F∩O = ∅ 0.48, {F} 0.12, {S} 0.24 + 0.06, O 0.08, Ω 0.02.
    // ∅_FO = 0.6·0.8 = 0.48 → {M}; ∅_OF = m(O)·m'(F) = 0.3·0 = 0; no residual.
    // Accumulator: conflict 0.48 > γ_∅ = 0.2 → ζ = 0.5 − 0.3 = 0.2.
    // Specialisation ζ = 0.2: {M} 0.48 → 0.384 + ∅ 0.096 (→ Ω under to_omega);
    // O 0.08 → {I,U,S} 0.016 + O 0.064; Ω 0.02 → {F,I,U,S} 0.004 + Ω 0.016 (+ 0.096 = 0.112).
    let mut p = hand_params();
    p.fusion.discount_per_second = ClassRates::uniform(0.0);
    let prior = [(F, 0.6), (S, 0.3), (OMEGA, 0.1)];
    let cell = one_step(&prior, 0.5, (0.0, 0.8), MapContext::Unknown, &p, 0.1);
    assert!((cell.fo - 0.48).abs() < 1e-6 && cell.of == 0.0);
    assert!((cell.zeta - 0.2).abs() < 1e-6);
    assert_masses(
        &cell,
        &[
            (F, 0.12),
            (S, 0.3),
            (M, 0.384),
            (I | U | S, 0.016),
            (O, 0.064),
            (F | I | U | S, 0.004),
            (OMEGA, 0.112),
        ],
    );
}

#[test]
fn conflict_of_goes_to_omega() {
    // Past {S} 0.7, Ω 0.3; sensor free 0.7. c: S∩F = ∅ 0.49, {S} 0.21, {F} 0.21, Ω 0.09.
    // ∅_OF = 0.7·0.7 = 0.49 → Ω = 0.58; ∅_FO = 0.
    let p = still_params();
    let prior = [(S, 0.7), (OMEGA, 0.3)];
    let cell = one_step(&prior, 0.0, (0.7, 0.0), MapContext::Unknown, &p, 0.1);
    assert!((cell.of - 0.49).abs() < 1e-6 && cell.fo == 0.0);
    assert_masses(&cell, &[(S, 0.21), (F, 0.21), (OMEGA, 0.58)]);
}

/// Past {I} 0.5, {F} 0.2, Ω 0.3; a road cell seen occupied (SG' {S,M} 0.64, O 0.16,
/// {F,S,M} 0.16, Ω 0.04). c(∅) = 0.32 + 0.08 + 0.128 + 0.032 = 0.56; {I} 0.1, {F} 0.04,
/// {S,M} 0.192, O 0.048, {F,S,M} 0.048, Ω 0.012. ∅_FO = 0.2·0.8 = 0.16 → {M}; ∅_OF = 0.
/// Residual 0.56 − 0.16 = 0.40.
fn residual_case(policy: ResidualPolicy) -> Cell {
    let mut p = still_params();
    p.fusion.residual = policy;
    let prior = [(I, 0.5), (F, 0.2), (OMEGA, 0.3)];
    one_step(&prior, 0.0, (0.0, 0.8), MapContext::Road, &p, 0.1)
}

const RESIDUAL_COMMON: [(usize, f32); 6] = [
    (I, 0.1),
    (F, 0.04),
    (S | M, 0.192),
    (O, 0.048),
    (F | S | M, 0.048),
    (M, 0.16),
];

#[test]
fn residual_conflict_to_omega() {
    let cell = residual_case(ResidualPolicy::ToOmega);
    let mut expected = RESIDUAL_COMMON.to_vec();
    expected.push((OMEGA, 0.012 + 0.4));
    assert_masses(&cell, &expected);
    assert!((cell.fo - 0.16).abs() < 1e-6);
}

#[test]
fn residual_conflict_kept_on_empty_set() {
    let cell = residual_case(ResidualPolicy::Keep);
    let mut expected = RESIDUAL_COMMON.to_vec();
    expected.extend([(OMEGA, 0.012), (0, 0.4)]);
    assert_masses(&cell, &expected);
}

#[test]
fn residual_conflict_normalised() {
    // The non-empty masses sum to 0.6 and are divided by it.
    let cell = residual_case(ResidualPolicy::Normalise);
    let mut expected: Vec<(usize, f32)> = RESIDUAL_COMMON
        .iter()
        .map(|&(set, m)| (set, m / 0.6))
        .collect();
    expected.push((OMEGA, 0.012 / 0.6));
    assert_masses(&cell, &expected);
}

#[test]
fn accumulator_increases_when_steadily_occupied() {
    // Past {S} 0.8, Ω 0.2, ζ 0.5; occupied 0.8, no map: {S} 0.8, O 0.16, Ω 0.04, no conflict;
    // m(O) = 0.96 ≥ γ_O → ζ = 0.6. Specialisation 0.6: O → {I,U,S} 0.096 + O 0.064,
    // Ω → {F,I,U,S} 0.024 + Ω 0.016.
    let mut p = hand_params();
    p.fusion.discount_per_second = ClassRates::uniform(0.0);
    let prior = [(S, 0.8), (OMEGA, 0.2)];
    let cell = one_step(&prior, 0.5, (0.0, 0.8), MapContext::Unknown, &p, 0.1);
    assert!((cell.zeta - 0.6).abs() < 1e-6);
    assert_masses(
        &cell,
        &[
            (S, 0.8),
            (I | U | S, 0.096),
            (O, 0.064),
            (F | I | U | S, 0.024),
            (OMEGA, 0.016),
        ],
    );
    // Capped at 1: ζ 0.95 + 0.1 → 1, and everything leaves M.
    let cell = one_step(&prior, 0.95, (0.0, 0.8), MapContext::Unknown, &p, 0.1);
    assert_eq!(cell.zeta, 1.0);
    assert_masses(&cell, &[(S, 0.8), (I | U | S, 0.16), (F | I | U | S, 0.04)]);
}

#[test]
fn accumulator_decreases_on_conflict_floored_at_zero() {
    // As `conflict_fo_goes_to_moving`: conflict 0.48 > 0.2, ζ 0.1 − 0.3 → 0: nothing specialised.
    let mut p = hand_params();
    p.fusion.discount_per_second = ClassRates::uniform(0.0);
    let prior = [(F, 0.6), (S, 0.3), (OMEGA, 0.1)];
    let cell = one_step(&prior, 0.1, (0.0, 0.8), MapContext::Unknown, &p, 0.1);
    assert_eq!(cell.zeta, 0.0);
    assert_masses(
        &cell,
        &[(F, 0.12), (S, 0.3), (M, 0.48), (O, 0.08), (OMEGA, 0.02)],
    );
}

#[test]
fn accumulator_unchanged_otherwise() {
    // Past {F} 0.7, Ω 0.3, ζ 0.4, vacuous sensor: m(O) = 0 < γ_O, no conflict → ζ stays 0.4.
    // Specialisation 0.4 moves Ω → {F,I,U,S} 0.12.
    let p = hand_params();
    let prior = [(F, 0.7), (OMEGA, 0.3)];
    let cell = one_step(&prior, 0.4, NO_SENSOR, MapContext::Unknown, &p, 0.0);
    assert!((cell.zeta - 0.4).abs() < 1e-7);
    assert_masses(&cell, &[(F, 0.7), (F | I | U | S, 0.12), (OMEGA, 0.18)]);
    assert!(!cell.seen);
}

/// Past {M} 0.6, {S,M} 0.2, {F} 0.2, ζ 0.5 kept (δ = 0), vacuous sensor, no discount.
/// Specialisation: {M} → {M} 0.3 + ∅ 0.3; {S,M} → {S,M} 0.1 + {S} 0.1; {F} stays 0.2.
fn specialisation_case(policy: ResidualPolicy) -> Cell {
    let mut p = still_params();
    p.fusion.residual = policy;
    let prior = [(M, 0.6), (S | M, 0.2), (F, 0.2)];
    one_step(&prior, 0.5, NO_SENSOR, MapContext::Unknown, &p, 0.1)
}

#[test]
fn specialisation_of_moving_to_empty_set_follows_to_omega() {
    let cell = specialisation_case(ResidualPolicy::ToOmega);
    assert_masses(
        &cell,
        &[(F, 0.2), (S, 0.1), (M, 0.3), (S | M, 0.1), (OMEGA, 0.3)],
    );
}

#[test]
fn specialisation_of_moving_to_empty_set_follows_keep() {
    let cell = specialisation_case(ResidualPolicy::Keep);
    assert_masses(
        &cell,
        &[(F, 0.2), (S, 0.1), (M, 0.3), (S | M, 0.1), (0, 0.3)],
    );
}

#[test]
fn specialisation_of_moving_to_empty_set_follows_normalise() {
    // The rest sums to 0.7: {F} 0.2/0.7, {S} 0.1/0.7, {M} 0.3/0.7, {S,M} 0.1/0.7.
    let cell = specialisation_case(ResidualPolicy::Normalise);
    assert_masses(
        &cell,
        &[
            (F, 0.2 / 0.7),
            (S, 0.1 / 0.7),
            (M, 0.3 / 0.7),
            (S | M, 0.1 / 0.7),
        ],
    );
    assert_eq!(cell.stats.normalisation_fallbacks, 0);
}

#[test]
fn normalise_with_nothing_left_falls_back_to_vacuous() {
    // {M} 1 with ζ = 1: everything goes to ∅; normalising is impossible, the cell becomes
    // vacuous and the event is counted.
    let mut p = still_params();
    p.fusion.residual = ResidualPolicy::Normalise;
    let cell = one_step(&[(M, 1.0)], 1.0, NO_SENSOR, MapContext::Unknown, &p, 0.1);
    assert_masses(&cell, &[(OMEGA, 1.0)]);
    assert_eq!(cell.stats.normalisation_fallbacks, 1);
}

#[test]
fn invalid_sensor_masses_are_clamped_not_propagated() {
    let p = still_params();
    let cell = one_step(VACUOUS, 0.0, (f32::NAN, 0.8), MapContext::Unknown, &p, 0.1);
    assert_masses(&cell, &[(O, 0.8), (OMEGA, 0.2)]);
    let cell = one_step(VACUOUS, 0.0, (0.7, 0.9), MapContext::Unknown, &p, 0.1);
    assert_masses(&cell, &[(F, 0.7), (O, 0.3)]);
    let cell = one_step(
        VACUOUS,
        0.0,
        (-1.0, f32::INFINITY),
        MapContext::Unknown,
        &p,
        0.1,
    );
    assert_masses(&cell, &[(O, 1.0)]);
}

#[test]
fn seen_flag_stays_once_set() {
    let p = hand_params();
    let (mut pg, mut sg, gg) = (
        PerceptionGrid::new(2, 1),
        SensorGrid::new(2, 1),
        GisGrid::new(2, 1),
    );
    sg.m_occupied_mut()[1] = 0.8;
    let stats = step(&mut pg, &sg, &gg, &p, 0.1);
    assert_eq!((stats.cells, stats.observed_cells), (2, 1));
    assert_eq!(pg.seen(), &[0, 1]);
    sg.clear();
    step(&mut pg, &sg, &gg, &p, 0.1);
    assert_eq!(pg.seen(), &[0, 1]);
}

#[test]
fn moving_object_crossing_a_road_cell() {
    // A scenario over many steps: free road, a car arrives (M), stays (ζ grows, mass moves
    // from M to S), leaves (conflict ∅_OF, ζ falls), road free again.
    use crate::{decision::decide, label::Label};
    let p = hand_params();
    let (mut pg, mut sg, mut gg) = (
        PerceptionGrid::new(1, 1),
        SensorGrid::new(1, 1),
        GisGrid::new(1, 1),
    );
    gg.context[0] = MapContext::Road;
    let mut run = |pg: &mut PerceptionGrid, free: f32, occupied: f32, n: usize| {
        sg.m_free_mut()[0] = free;
        sg.m_occupied_mut()[0] = occupied;
        for _ in 0..n {
            step(pg, &sg, &gg, &p, 0.1);
        }
        decide(&pg.cell_masses(0), pg.seen()[0] != 0, 0.5)
    };
    assert_eq!(run(&mut pg, 0.7, 0.0, 5), Label::F);
    assert_eq!(run(&mut pg, 0.0, 0.8, 1), Label::M);
    assert_eq!(run(&mut pg, 0.0, 0.8, 30), Label::S);
    assert!(pg.zeta()[0] > 0.9);
    assert_eq!(run(&mut pg, 0.7, 0.0, 10), Label::F);
}

// ---- the kernel against the f64 reference ----

fn arb_params() -> impl Strategy<Value = Params> {
    let modes = prop_oneof![
        Just(DiscountMode::Classical),
        Just(DiscountMode::ClassRates),
        Just(DiscountMode::Mercier)
    ];
    let set_rates = prop_oneof![Just(SetRate::Min), Just(SetRate::Max), Just(SetRate::Mean)];
    let policies = prop_oneof![
        Just(ResidualPolicy::ToOmega),
        Just(ResidualPolicy::Keep),
        Just(ResidualPolicy::Normalise)
    ];
    let unobserved = prop_oneof![
        Just(UnobservedCells::Fuse),
        Just(UnobservedCells::DiscountOnly)
    ];
    (
        (modes, set_rates, policies, unobserved),
        prop::array::uniform5(0.0..=1.0_f64),
        prop::array::uniform3(0.0..=0.95_f64),
        prop::array::uniform4(0.0..=1.0_f64),
    )
        .prop_map(
            |((mode, set_rate, policy, unobserved), rates, betas, acc)| {
                let mut p = Params::default();
                p.fusion.unobserved = unobserved;
                p.fusion.discount_mode = mode;
                p.fusion.set_rate = set_rate;
                p.fusion.residual = policy;
                p.fusion.discount_per_second = ClassRates {
                    free: rates[0],
                    mapped_infrastructure: rates[1],
                    unmapped_infrastructure: rates[2],
                    stopped: rates[3],
                    moving: rates[4],
                };
                (p.map.beta_building, p.map.beta_road, p.map.beta_other) =
                    (betas[0], betas[1], betas[2]);
                p.accumulator.delta_inc = acc[0];
                p.accumulator.delta_dec = acc[1];
                p.accumulator.gamma_occupied = acc[2];
                p.accumulator.gamma_conflict = acc[3];
                p
            },
        )
}

/// A random cell: previous masses (sparse), ζ, sensor masses, map context.
#[derive(Clone, Debug)]
struct RandomCell {
    masses: [f32; N_SETS],
    zeta: f32,
    m_free: f32,
    m_occupied: f32,
    context: MapContext,
}

fn arb_cell() -> impl Strategy<Value = RandomCell> {
    let weight = prop_oneof![2 => Just(0.0_f64), 1 => 0.0..1.0_f64];
    let sensor = prop_oneof![
        Just((0.0, 0.0)),
        Just((0.7, 0.0)),
        Just((0.0, 0.8)),
        (0.0..=0.95_f64, 0.0..=1.0_f64).prop_map(|(f, o)| (f, o * (0.95 - f).max(0.0))),
    ];
    let context = prop_oneof![
        Just(MapContext::Unknown),
        Just(MapContext::Other),
        Just(MapContext::Road),
        Just(MapContext::Building),
        Just(MapContext::BuildingEdge)
    ];
    (
        prop::collection::vec(weight, N_SETS),
        0.0..=1.0_f64,
        sensor,
        context,
    )
        .prop_map(|(weights, zeta, (m_free, m_occupied), context)| {
            let total: f64 = weights.iter().sum();
            let mut masses = [0.0_f32; N_SETS];
            if total > 0.0 {
                for (m, w) in masses.iter_mut().zip(&weights) {
                    *m = (w / total) as f32;
                }
            } else {
                masses[OMEGA] = 1.0;
            }
            RandomCell {
                masses,
                zeta: zeta as f32,
                m_free: m_free as f32,
                m_occupied: m_occupied as f32,
                context,
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// The grid kernel agrees with the f64 reference built from the belief crate's operations
    /// within 1e-5, for every mode and policy, on random cells in one grid (so that blocks are
    /// partly filled and contexts mixed).
    #[test]
    fn kernel_matches_reference(
        params in arb_params(),
        cells in prop::collection::vec(arb_cell(), 1..40),
        dt_s in prop_oneof![Just(0.1_f64), 0.0..2.0_f64],
    ) {
        let width = cells.len();
        let mut pg = PerceptionGrid::new(width, 1);
        let mut sg = SensorGrid::new(width, 1);
        let mut gg = GisGrid::new(width, 1);
        for (idx, cell) in cells.iter().enumerate() {
            let mut masses = cell.masses;
            if params.fusion.residual != ResidualPolicy::Keep {
                // Only `keep` ever leaves mass on ∅.
                masses[OMEGA] += masses[0];
                masses[0] = 0.0;
            }
            pg.set_cell_masses(idx, &masses);
            pg.zeta_mut()[idx] = cell.zeta;
            sg.m_free_mut()[idx] = cell.m_free;
            sg.m_occupied_mut()[idx] = cell.m_occupied;
            gg.context[idx] = cell.context;
        }
        let before = pg.clone();
        step(&mut pg, &sg, &gg, &params, dt_s);
        for (idx, cell) in cells.iter().enumerate() {
            let state = CellState {
                masses: before.cell_masses(idx).map(f64::from),
                zeta: f64::from(cell.zeta),
                conflict_fo: 0.0,
                conflict_of: 0.0,
                seen: false,
            };
            let (want, trace) = reference_step_traced(
                &state,
                f64::from(cell.m_free),
                f64::from(cell.m_occupied),
                cell.context,
                &params,
                dt_s,
            ).unwrap();
            // f32 rounding can flip a threshold comparison exactly at γ: skip those cells.
            let acc = &params.accumulator;
            if (trace.occupied - acc.gamma_occupied).abs() < 1e-4
                || (trace.conflict - acc.gamma_conflict).abs() < 1e-4
            {
                continue;
            }
            let got = pg.cell_masses(idx);
            for set in 0..N_SETS {
                prop_assert!(
                    (f64::from(got[set]) - want.masses[set]).abs() < 1e-5,
                    "cell {} m({:05b}): kernel {} reference {}", idx, set, got[set], want.masses[set]
                );
            }
            prop_assert!((f64::from(pg.zeta()[idx]) - want.zeta).abs() < 1e-5);
            prop_assert!((f64::from(pg.conflict_fo()[idx]) - want.conflict_fo).abs() < 1e-5);
            prop_assert!((f64::from(pg.conflict_of()[idx]) - want.conflict_of).abs() < 1e-5);
            prop_assert_eq!(pg.seen()[idx] != 0, want.seen);
        }
    }

    /// Each step keeps a valid mass function: non-negative masses summing to 1, ζ in [0, 1].
    #[test]
    fn step_keeps_mass_functions_valid(
        params in arb_params(),
        cells in prop::collection::vec(arb_cell(), 1..20),
        steps in 1..6_usize,
    ) {
        let width = cells.len();
        let mut pg = PerceptionGrid::new(width, 1);
        let mut sg = SensorGrid::new(width, 1);
        let mut gg = GisGrid::new(width, 1);
        for (idx, cell) in cells.iter().enumerate() {
            sg.m_free_mut()[idx] = cell.m_free;
            sg.m_occupied_mut()[idx] = cell.m_occupied;
            gg.context[idx] = cell.context;
        }
        for _ in 0..steps {
            step(&mut pg, &sg, &gg, &params, 0.1);
        }
        for idx in 0..width {
            let m = pg.cell_masses(idx);
            prop_assert!(m.iter().all(|&x| x >= 0.0 && x.is_finite()), "{:?}", m);
            prop_assert!((m.iter().sum::<f32>() - 1.0).abs() < 1e-4, "{:?}", m);
            prop_assert!((0.0..=1.0).contains(&pg.zeta()[idx]));
        }
    }
}

// ---- parallelism ----

/// A pseudo-random scene (an LCG: deterministic and dependency-free).
/// Whether two planes hold the same bits (+0 and -0 differ, NaNs compare).
fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

fn scene(width: usize, height: usize, seed: u64) -> (PerceptionGrid, SensorGrid, GisGrid) {
    let mut state = seed;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut pg = PerceptionGrid::new(width, height);
    let mut sg = SensorGrid::new(width, height);
    let mut gg = GisGrid::new(width, height);
    for idx in 0..width * height {
        let r = next();
        (sg.m_free_mut()[idx], sg.m_occupied_mut()[idx]) = if r < 0.3 {
            (0.7, 0.0)
        } else if r < 0.5 {
            (0.0, 0.8)
        } else {
            (0.0, 0.0)
        };
        gg.context[idx] = match (next() * 5.0) as u8 {
            0 => MapContext::Unknown,
            1 => MapContext::Other,
            2 => MapContext::Road,
            3 => MapContext::Building,
            _ => MapContext::BuildingEdge,
        };
        pg.zeta_mut()[idx] = next();
    }
    (pg, sg, gg)
}

#[test]
fn result_is_bit_identical_whatever_the_thread_count() -> Result<(), rayon::ThreadPoolBuildError> {
    let (pg0, sg, gg) = scene(300, 200, 7);
    let mut params = Params::default();
    params.fusion.residual = ResidualPolicy::Normalise;
    let run = |threads: usize| -> Result<(PerceptionGrid, StepStats), rayon::ThreadPoolBuildError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        let mut pg = pg0.clone();
        let mut stats = StepStats::default();
        pool.install(|| {
            for _ in 0..3 {
                stats = stats.merged(step(&mut pg, &sg, &gg, &params, 0.1));
            }
        });
        Ok((pg, stats))
    };
    let (one, stats_one) = run(1)?;
    let (many, stats_many) = run(4)?;
    assert_eq!(stats_one, stats_many);
    assert_eq!(stats_one.cells, 3 * 300 * 200);
    for set in 0..N_SETS {
        let a: Vec<u32> = one.plane(set).iter().map(|x| x.to_bits()).collect();
        let b: Vec<u32> = many.plane(set).iter().map(|x| x.to_bits()).collect();
        assert!(a == b, "plane {set} differs");
    }
    assert!(same_bits(one.zeta(), many.zeta()));
    Ok(())
}

#[test]
fn grid_cells_equal_single_cell_steps() {
    // Every cell of a 37×3 grid (blocks split across rows and a partial last block) is what a
    // 1×1 grid gives for the same inputs.
    let (mut pg, sg, gg) = scene(37, 3, 11);
    let params = Params::default();
    let before = pg.clone();
    step(&mut pg, &sg, &gg, &params, 0.1);
    for idx in 0..pg.len() {
        let mut one = PerceptionGrid::new(1, 1);
        one.set_cell_masses(0, &before.cell_masses(idx));
        one.zeta_mut()[0] = before.zeta()[idx];
        let mut s = SensorGrid::new(1, 1);
        s.m_free_mut()[0] = sg.m_free()[idx];
        s.m_occupied_mut()[0] = sg.m_occupied()[idx];
        let mut g = GisGrid::new(1, 1);
        g.context[0] = gg.context[idx];
        step(&mut one, &s, &g, &params, 0.1);
        assert_eq!(one.cell_masses(0), pg.cell_masses(idx), "cell {idx}");
        assert_eq!(one.zeta()[0], pg.zeta()[idx]);
    }
}

#[test]
fn shortcuts_taken_per_block_give_each_cell_what_it_gets_alone() {
    // Map contexts in runs of 70 cells, a scan that reaches only cells 200..260, ζ = 0 in the
    // first half: whole blocks take the shortcuts (one context, nothing observed, ζ = 0, never
    // seen), others not, and a 1×1 grid never does. Every mode must give the same bits.
    let (mut pg, mut sg, mut gg) = scene(150, 4, 3);
    let contexts = [
        MapContext::Road,
        MapContext::Building,
        MapContext::Other,
        MapContext::Unknown,
        MapContext::BuildingEdge,
    ];
    for idx in 0..pg.len() {
        gg.context[idx] = contexts[(idx / 70) % contexts.len()];
        if !(200..260).contains(&idx) {
            (sg.m_free_mut()[idx], sg.m_occupied_mut()[idx]) = (0.0, 0.0);
        }
        if idx < 300 {
            pg.zeta_mut()[idx] = 0.0;
        }
        // Mass on every focal set, so that the order of every sum shows in the last bits; in
        // the blocks from cell 384 on, only on the 17 sets a grid started vacuous can reach
        // (the step then visits only those), with a cell of all 32 sets every 100.
        let mut m = [0.0; N_SETS];
        let mut state = idx as u64 + 1;
        let only_reachable = idx >= 384 && idx % 100 != 0;
        for (set, x) in m.iter_mut().enumerate() {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            if !only_reachable || super::passes::is_live(super::passes::REACHABLE, set) {
                *x = 0.05 + (state >> 40) as f32 / (1u64 << 24) as f32;
            }
        }
        let total: f32 = m.iter().sum();
        pg.set_cell_masses(idx, &m.map(|x| x / total));
        pg.seen_mut()[idx] = u8::from(idx % 3 == 0);
    }
    let mut variants = vec![hand_params()];
    for (mode, residual, unobserved) in [
        (
            DiscountMode::Mercier,
            ResidualPolicy::Keep,
            UnobservedCells::Fuse,
        ),
        (
            DiscountMode::Classical,
            ResidualPolicy::Normalise,
            UnobservedCells::Fuse,
        ),
        (
            DiscountMode::ClassRates,
            ResidualPolicy::ToOmega,
            UnobservedCells::DiscountOnly,
        ),
    ] {
        let mut p = hand_params();
        (p.fusion.discount_mode, p.fusion.residual) = (mode, residual);
        p.fusion.unobserved = unobserved;
        variants.push(p);
    }
    for params in &variants {
        let mut grid = pg.clone();
        for _ in 0..2 {
            step(&mut grid, &sg, &gg, params, 0.1);
        }
        for idx in (0..pg.len()).step_by(7) {
            let mut one = PerceptionGrid::new(1, 1);
            one.set_cell_masses(0, &pg.cell_masses(idx));
            one.zeta_mut()[0] = pg.zeta()[idx];
            let mut s = SensorGrid::new(1, 1);
            (s.m_free_mut()[0], s.m_occupied_mut()[0]) = (sg.m_free()[idx], sg.m_occupied()[idx]);
            let mut g = GisGrid::new(1, 1);
            g.context[0] = gg.context[idx];
            for _ in 0..2 {
                step(&mut one, &s, &g, params, 0.1);
            }
            let mode = &params.fusion;
            assert_eq!(
                one.cell_masses(0),
                grid.cell_masses(idx),
                "cell {idx}, {mode:?}"
            );
            assert_eq!(one.zeta()[0], grid.zeta()[idx], "cell {idx}, {mode:?}");
        }
    }
}

#[test]
fn the_vector_code_for_this_cpu_equals_the_portable_code_bit_for_bit() {
    // On a CPU with AVX2 `step` runs code compiled for it; `step_blocks` is the portable code.
    // Without FMA contraction both do the same IEEE operations lane by lane.
    let params = Params::default();
    let (mut dispatched, sg, gg) = scene(67, 23, 5);
    let mut portable = dispatched.clone();
    for _ in 0..4 {
        step(&mut dispatched, &sg, &gg, &params, 0.1);
        step_cells(&mut portable, &sg, &gg, &params, 0.1, None, |run, k| {
            run.step_blocks(k, None::<fn(*const i8)>)
        });
    }
    for set in 0..N_SETS {
        assert!(
            same_bits(dispatched.plane(set), portable.plane(set)),
            "set {set} differs"
        );
    }
    assert_eq!(dispatched.zeta(), portable.zeta());
}

#[test]
fn planes_skipped_as_zero_give_the_same_bits_as_planes_read() {
    // Far from the sensor a cell holds mass on two or three sets; the step reads and writes only
    // the planes a block's bits name. A grid whose bits name every plane before each step
    // (nothing skipped) must end with the same bits, and the bits of the other must keep their promise: a clear bit is
    // a plane of +0 in every cell of its block.
    let (width, height) = (300, 120);
    let (_, mut sg, mut gg) = scene(width, height, 17);
    for row in 0..height {
        for col in 0..width {
            let idx = row * width + col;
            // The sensor sees a disc; the map is in bands of 50 columns, as streets are.
            let (dx, dy) = (col as f32 - 150.0, row as f32 - 60.0);
            if dx * dx + dy * dy > 40.0 * 40.0 {
                (sg.m_free_mut()[idx], sg.m_occupied_mut()[idx]) = (0.0, 0.0);
            }
            gg.context[idx] = [
                MapContext::Other,
                MapContext::Road,
                MapContext::Building,
                MapContext::Unknown,
                MapContext::BuildingEdge,
            ][col / 50 % 5];
        }
    }
    for unobserved in [UnobservedCells::Fuse, UnobservedCells::DiscountOnly] {
        for residual in [ResidualPolicy::ToOmega, ResidualPolicy::Normalise] {
            let mut params = hand_params();
            params.fusion.unobserved = unobserved;
            params.fusion.residual = residual;
            let mut skipping = PerceptionGrid::new(width, height);
            let mut reading = skipping.clone();
            for _ in 0..6 {
                reading.mark_every_plane_nonzero();
                let skipped = step(&mut skipping, &sg, &gg, &params, 0.1);
                let read = step(&mut reading, &sg, &gg, &params, 0.1);
                assert!(skipped.state_bytes_moved < read.state_bytes_moved / 2);
            }
            let case = format!("{unobserved:?}, {residual:?}");
            assert_eq!(skipping, reading, "{case}");
            let same = (0..N_SETS).all(|set| same_bits(skipping.plane(set), reading.plane(set)));
            assert!(same, "{case}");
            for (block, &bits) in skipping.nonzero_bits().iter().enumerate() {
                let cells = block * 64..((block + 1) * 64).min(width * height);
                let zero = |plane: &[f32]| plane[cells.clone()].iter().all(|x| x.to_bits() == 0);
                for set in (0..N_SETS).filter(|set| bits & (1 << set) == 0) {
                    assert!(
                        zero(skipping.plane(set)),
                        "{case}: block {block}, set {set}"
                    );
                }
                if bits & crate::grids::ZETA_BIT == 0 {
                    assert!(zero(skipping.zeta()), "{case}: block {block}, ζ");
                }
                if bits & crate::grids::CONFLICT_FO_BIT == 0 {
                    assert!(zero(skipping.conflict_fo()), "{case}: block {block}, ∅_FO");
                }
                if bits & crate::grids::CONFLICT_OF_BIT == 0 {
                    assert!(zero(skipping.conflict_of()), "{case}: block {block}, ∅_OF");
                }
            }
        }
    }
}

#[test]
fn step_and_decide_decides_as_decide_grid_after_step() {
    let params = Params::default();
    let (mut fused, sg, gg) = scene(41, 37, 9);
    let mut separate = fused.clone();
    let mut fused_decisions = vec![crate::Label::Unknown; fused.len()];
    let mut separate_decisions = fused_decisions.clone();
    for _ in 0..3 {
        step_and_decide(&mut fused, &sg, &gg, &params, 0.1, &mut fused_decisions);
        step(&mut separate, &sg, &gg, &params, 0.1);
    }
    let threshold = params.decision.unknown_threshold;
    crate::decision::decide_grid(&separate, threshold, &mut separate_decisions);
    assert_eq!(fused_decisions, separate_decisions);
    assert!(fused_decisions.iter().any(|d| *d != crate::Label::Unknown));
}

#[test]
fn a_grid_kept_on_the_reachable_sets_skips_the_others_with_the_same_bits() {
    // Started vacuous and stepped with discounting to Ω, a grid never holds mass outside the 17
    // reachable sets, so the step leaves those planes unread. A clone whose planes were handed
    // out for writing (so the step must check every block) must end with the same bits.
    let (_, sg, gg) = scene(131, 40, 9);
    let mut skipping = PerceptionGrid::new(131, 40);
    let mut checking = skipping.clone();
    let _ = checking.plane_mut(0);
    assert!(!skipping.may_leave_reachable() && checking.may_leave_reachable());
    for policy in [ResidualPolicy::ToOmega, ResidualPolicy::Normalise] {
        let mut params = hand_params();
        params.fusion.residual = policy;
        for _ in 0..4 {
            step(&mut skipping, &sg, &gg, &params, 0.1);
            step(&mut checking, &sg, &gg, &params, 0.1);
        }
    }
    assert!(!skipping.may_leave_reachable());
    for set in 0..N_SETS {
        assert!(
            same_bits(skipping.plane(set), checking.plane(set)),
            "set {set:05b} differs"
        );
        if !super::passes::is_live(super::passes::REACHABLE, set) {
            assert!(skipping.plane(set).iter().all(|x| x.to_bits() == 0));
        }
    }
    // Mercier's discounting moves mass to any superset: the grid is then checked block by block.
    let mut params = hand_params();
    params.fusion.discount_mode = DiscountMode::Mercier;
    step(&mut skipping, &sg, &gg, &params, 0.1);
    assert!(skipping.may_leave_reachable());
}

#[test]
fn the_evidence_of_an_unobserved_cell_differs_between_contexts_in_three_values_only() {
    // `SensorEvidence::select_unobserved` broadcasts one context's evidence and selects only β,
    // m_SG'({F}) and m_SG'(O) per context: the other values must be the same in every context.
    for beta in [0.0, 0.3, 1.0] {
        let mut params = Params::default();
        params.map.beta_other = beta;
        params.map.beta_road = beta;
        params.map.beta_building = beta;
        let k = StepConstants::new(&params, 0.1);
        for v in &k.unobserved_evidence {
            let same = [v.free, v.occupied, v.omega, v.conflict, v.inv_normaliser];
            assert_eq!(
                same.map(f32::to_bits),
                [0.0f32, 0.0, 1.0, 0.0, 1.0].map(f32::to_bits)
            );
            assert!(!v.observed && !v.total_conflict);
        }
    }
}

#[test]
fn sensor_blocks_known_vacuous_are_skipped_with_the_same_bits() {
    // A SensorGrid written through `set_free`/`set_occupied` (as the sensor model writes) knows
    // which blocks hold no mass, and the step does not read them; one written through
    // `m_free_mut` is read everywhere. Both must give the same grid.
    let (width, height) = (300, 50);
    let mut noted = SensorGrid::new(width, height);
    for idx in (0..width * height).filter(|idx| idx % 97 < 3 && idx / width < 20) {
        noted.set_free(idx, 0.7);
        if idx % 2 == 0 {
            noted.set_occupied(idx, 0.2);
        }
    }
    assert!(noted.may_hold_mass().iter().any(|&b| b) && noted.may_hold_mass().iter().any(|&b| !b));
    for block in (0..noted.may_hold_mass().len()).filter(|&b| !noted.may_hold_mass()[b]) {
        let cells = block * 64..((block + 1) * 64).min(width * height);
        assert!(noted.m_free()[cells.clone()].iter().all(|&m| m == 0.0));
        assert!(noted.m_occupied()[cells].iter().all(|&m| m == 0.0));
    }
    let mut read = noted.clone();
    let _ = read.m_free_mut();
    assert!(read.may_hold_mass().iter().all(|&b| b));
    let (_, _, gg) = scene(width, height, 23);
    let params = hand_params();
    let mut skipping = PerceptionGrid::new(width, height);
    let mut reading = skipping.clone();
    for _ in 0..3 {
        let skipped = step(&mut skipping, &noted, &gg, &params, 0.1);
        let all = step(&mut reading, &read, &gg, &params, 0.1);
        assert!(skipped.state_bytes_moved < all.state_bytes_moved);
    }
    assert_eq!(skipping, reading);
    noted.clear();
    assert!(noted.may_hold_mass().iter().all(|&b| !b));
}
