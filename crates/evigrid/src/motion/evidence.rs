//! The motion belief of a track and its combination with a cell's mass function on Ω_PG.
//!
//! A track's velocity v (per-axis variances σ²) gives the confidence that the object moves
//! faster than `min_speed_mps` (the truth's "moving"), c = erf(z/√2), z = (|v| −
//! `min_speed_mps`)/σ_r, σ_r the standard deviation of the speed along v. Then, on the cells
//! of the track's cluster in this frame:
//! - moving (|v| ≥ `min_speed_mps`, at least `moving_after_measurements` registrations of
//!   the track, and a net registered displacement beyond what the pose's error explains,
//!   `displaced_pose_sigmas`): m({M}) = `mu_moving` · c, the rest on Ω;
//! - static (|v| < `min_speed_mps` and √(σx² + σy²) < `static_sigma_mps`: slow and known
//!   well enough), and the track has travelled `mobile_after_travel_m` while moving (net), for
//!   at least `mobile_after_moving_s`, and its cluster touches no mapped building: m({S}) = `mu_static`, the rest on Ω: a mobile
//!   object standing still, "not moving" and "a road user" at once;
//! - static otherwise: m(Ω∖{M}) = `mu_static`, the rest on Ω: "not moving", which says
//!   nothing about I, U or S (street furniture and a standing pedestrian are alike in size);
//! - otherwise (never registered, or too uncertain): vacuous.
//!
//! The cell's mass function m is combined with it by the conjunctive rule on Ω_PG, and the
//! conflict it creates follows the fusion's residual policy (SPEC §5 step 4): mass on {M}
//! meets m(A) for A ∌ M as conflict, mass on Ω∖{M} meets m({M}) as conflict, mass on {S}
//! meets m(A) for A ∌ S as conflict. Mass on a set A goes only to A ∩ {M}, A∖{M} or
//! A ∩ {S}, so a grid whose masses lie on the sets the step can reach keeps them there (they
//! are closed under intersection and hold {S}).

use geodata::MapContext;

use crate::grids::{N_SETS, OMEGA, class};
use crate::params::{MotionParams, ResidualPolicy};

use super::kalman::VelocityFilter;
use super::tracks::{Track, is_moving};

/// The motion evidence on one cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MotionMass {
    /// No evidence: m(Ω) = 1.
    Vacuous,
    /// m({M}) = the value, the rest on Ω.
    Moving(f32),
    /// m(Ω∖{M}) = the value, the rest on Ω.
    Static(f32),
    /// m({S}) = the value, the rest on Ω: a mobile object (its track has moved) standing still.
    Stopped(f32),
}

/// The evidence a track gives its cells.
pub(crate) fn track_mass(track: &Track, params: &MotionParams) -> MotionMass {
    if track.measurements == 0 {
        return MotionMass::Vacuous;
    }
    let [x, y] = track.velocity;
    let speed = x.mean_mps.hypot(y.mean_mps);
    if speed >= params.min_speed_mps {
        if (track.measurements as usize) < params.moving_after_measurements || !track.displaced {
            return MotionMass::Vacuous;
        }
        let confidence = moving_confidence(x, y, speed, params.min_speed_mps);
        MotionMass::Moving((params.mu_moving * confidence) as f32)
    } else if (x.variance + y.variance).sqrt() < params.static_sigma_mps {
        let [dx, dy] = track.travel_m;
        if dx.hypot(dy) >= params.mobile_after_travel_m
            && track.moving_s >= params.mobile_after_moving_s
        {
            MotionMass::Stopped(params.mu_static as f32)
        } else {
            MotionMass::Static(params.mu_static as f32)
        }
    } else {
        MotionMass::Vacuous
    }
}

/// Whether the track is fast and registered often enough to move, but its net registered
/// displacement is within what the pose's error explains (`displaced_pose_sigmas`): it gives
/// no evidence ([`track_mass`]).
pub(crate) fn within_pose_error(track: &Track, params: &MotionParams) -> bool {
    is_moving(track, params) && !track.displaced
}

/// The confidence that a track whose estimated speed `speed` is at least `min_speed_mps` moves
/// faster than that: P(|v| > v_min) = Φ(z) with z = (|v̂| − v_min)/σ_r, σ_r the standard
/// deviation of the speed along the estimated velocity, rescaled from [½, 1] to [0, 1]:
/// 2Φ(z) − 1 = erf(z/√2). Moving is a speed above v_min (the truth's threshold), not any
/// speed: a car crawling into a stop at 0.6 ± 0.4 m/s gets 0.20, a walker at 1.3 ± 0.4 m/s
/// 0.95.
fn moving_confidence(x: VelocityFilter, y: VelocityFilter, speed: f64, min_speed_mps: f64) -> f64 {
    let along = (x.mean_mps * x.mean_mps * x.variance + y.mean_mps * y.mean_mps * y.variance)
        / (speed * speed);
    let z = (speed - min_speed_mps) / along.sqrt();
    erf(z / std::f64::consts::SQRT_2).max(0.0)
}

/// The error function, within 1.5e-7 (Abramowitz & Stegun 7.1.26).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let value = 1.0 - poly * (-x * x).exp();
    if x < 0.0 { -value } else { value }
}

/// The evidence of a cluster whose track says nothing (`mass` vacuous: never registered, or
/// slow but too uncertain to be static) when a share `entered_share` of its cells was seen
/// free in the frames kept: it entered space seen empty, m({M}) = `mu_moving` · share if the
/// share reaches `match_fraction`. Any other evidence is kept.
pub(crate) fn entered_seen_free(
    mass: MotionMass,
    entered_share: f64,
    params: &MotionParams,
) -> MotionMass {
    if mass == MotionMass::Vacuous && entered_share >= params.match_fraction {
        MotionMass::Moving((params.mu_moving * entered_share) as f32)
    } else {
        mass
    }
}

/// Stopped evidence only for a cluster clear of mapped buildings: one touching a building or
/// the band beside one is (part of) the building, whose visible face slid as the ego passed, not a road
/// user; it keeps "not moving" (m(Ω∖{M})). `contexts` are its cells' map contexts.
pub(crate) fn off_buildings(
    mass: MotionMass,
    mut contexts: impl Iterator<Item = Option<MapContext>>,
) -> MotionMass {
    match mass {
        MotionMass::Stopped(b)
            if contexts
                .any(|c| matches!(c, Some(MapContext::Building | MapContext::BuildingEdge))) =>
        {
            MotionMass::Static(b)
        }
        other => other,
    }
}

/// The evidence for a cell of this frame's clusters that takes no moving evidence (its track
/// gives none, or it holds a return the placed grid does not occupy) and is decided M: that M
/// is the SPEC §5 step's own free→occupied conflict, which a static surface shifted by the
/// pose's error makes as well as a mover does. With `unsupported_pose_sigmas` = k > 0, when
/// k · `displacement_sigma_m` (the σ of the apparent shift of a static object at the cluster's
/// range between two scans) reaches half a cell, the shift moves a surface into the next cell
/// and the cell takes m(Ω∖{M}) = `mu_static`; otherwise (and with k = 0) nothing.
pub(crate) fn unsupported_by_motion(
    displacement_sigma_m: f64,
    cell_size_m: f64,
    params: &MotionParams,
) -> MotionMass {
    let k = params.unsupported_pose_sigmas;
    if k > 0.0 && k * displacement_sigma_m >= 0.5 * cell_size_m {
        MotionMass::Static(params.mu_static as f32)
    } else {
        MotionMass::Vacuous
    }
}

/// Combines `m` conjunctively with the motion evidence, the new conflict following `residual`.
pub fn combine(m: &mut [f32; N_SETS], evidence: MotionMass, residual: ResidualPolicy) {
    let mut out = [0.0f32; N_SETS];
    out[0] = m[0];
    let mut conflict = 0.0f32;
    match evidence {
        MotionMass::Vacuous => return,
        MotionMass::Moving(a) => {
            for (set, &mass) in m.iter().enumerate().skip(1) {
                out[set] += (1.0 - a) * mass;
                if set & class::M != 0 {
                    out[class::M] += a * mass;
                } else {
                    conflict += a * mass;
                }
            }
        }
        MotionMass::Static(b) => {
            for (set, &mass) in m.iter().enumerate().skip(1) {
                if set & class::M == 0 {
                    out[set] += mass;
                } else {
                    out[set] += (1.0 - b) * mass;
                    match set & !class::M {
                        0 => conflict += b * mass,
                        rest => out[rest] += b * mass,
                    }
                }
            }
        }
        MotionMass::Stopped(b) => {
            for (set, &mass) in m.iter().enumerate().skip(1) {
                out[set] += (1.0 - b) * mass;
                if set & class::S != 0 {
                    out[class::S] += b * mass;
                } else {
                    conflict += b * mass;
                }
            }
        }
    }
    match residual {
        ResidualPolicy::ToOmega => out[OMEGA] += conflict,
        ResidualPolicy::Keep => out[0] += conflict,
        ResidualPolicy::Normalise => {
            let kept: f32 = out[1..].iter().sum();
            let before = 1.0 - m[0];
            if kept > 0.0 {
                for v in &mut out[1..] {
                    *v *= before / kept;
                }
            } else {
                out[OMEGA] += conflict;
            }
        }
    }
    *m = out;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::kalman::VelocityFilter;
    use class::{F, I, M, S, U};

    fn cell(pairs: &[(usize, f32)]) -> [f32; N_SETS] {
        let mut m = [0.0; N_SETS];
        for &(set, v) in pairs {
            m[set] = v;
        }
        m
    }

    fn close(a: &[f32; N_SETS], b: &[f32; N_SETS]) {
        for set in 0..N_SETS {
            assert!((a[set] - b[set]).abs() < 1e-6, "set {set}: {a:?} vs {b:?}");
        }
    }

    #[test]
    fn moving_evidence_turns_a_stopped_or_moving_tie_into_moving() {
        // m({S,M}) = 0.8, m(Ω) = 0.2 (a face in cells never seen free) with m({M}) = 0.5.
        let mut m = cell(&[(S | M, 0.8), (OMEGA, 0.2)]);
        combine(&mut m, MotionMass::Moving(0.5), ResidualPolicy::ToOmega);
        close(&m, &cell(&[(M, 0.5), (S | M, 0.4), (OMEGA, 0.1)]));
        let betp = crate::decision::betp(&m);
        assert!((betp[4] - 0.72).abs() < 1e-6, "{betp:?}");
    }

    #[test]
    fn moving_evidence_on_a_free_cell_is_conflict_under_each_policy() {
        let free = cell(&[(F, 0.3), (OMEGA, 0.7)]);
        let mut m = free;
        combine(&mut m, MotionMass::Moving(0.5), ResidualPolicy::ToOmega);
        close(&m, &cell(&[(M, 0.35), (F, 0.15), (OMEGA, 0.5)]));
        let mut m = free;
        combine(&mut m, MotionMass::Moving(0.5), ResidualPolicy::Keep);
        close(&m, &cell(&[(0, 0.15), (M, 0.35), (F, 0.15), (OMEGA, 0.35)]));
        let mut m = free;
        combine(&mut m, MotionMass::Moving(0.5), ResidualPolicy::Normalise);
        close(
            &m,
            &cell(&[(M, 0.35 / 0.85), (F, 0.15 / 0.85), (OMEGA, 0.35 / 0.85)]),
        );
    }

    #[test]
    fn static_evidence_removes_m_like_the_specialisation() {
        let mut m = cell(&[(M, 0.5), (S | M, 0.3), (OMEGA, 0.2)]);
        combine(&mut m, MotionMass::Static(0.6), ResidualPolicy::ToOmega);
        close(
            &m,
            &cell(&[
                (M, 0.2),
                (S | M, 0.12),
                (S, 0.18),
                (OMEGA, 0.08 + 0.3),
                (OMEGA & !M, 0.12),
            ]),
        );
        assert!((m.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn stopped_evidence_turns_pavement_infrastructure_or_stopped_into_stopped() {
        // A pavement cell (context T, focal {F,U,S,M}) holding a return: m({U,S}) = 0.6,
        // m({F,U,S,M}) = 0.3, m(Ω) = 0.1, with m({S}) = 0.9 and no conflict: every set holds S.
        let mut m = cell(&[(U | S, 0.6), (F | U | S | M, 0.3), (OMEGA, 0.1)]);
        combine(&mut m, MotionMass::Stopped(0.9), ResidualPolicy::ToOmega);
        close(
            &m,
            &cell(&[
                (S, 0.9),
                (U | S, 0.06),
                (F | U | S | M, 0.03),
                (OMEGA, 0.01),
            ]),
        );
        // betP(S) = 0.9 + 0.06/2 + 0.03/4 + 0.01/5, betP(U) = 0.03 + 0.0075 + 0.002.
        let betp = crate::decision::betp(&m);
        assert!((betp[3] - 0.9395).abs() < 1e-6, "{betp:?}");
        assert!((betp[2] - 0.0395).abs() < 1e-6, "{betp:?}");
    }

    #[test]
    fn stopped_evidence_on_a_set_without_s_is_conflict_under_each_policy() {
        // m({I}) = 0.5, m({S,M}) = 0.2, m(Ω) = 0.3 with m({S}) = 0.6: {I} keeps 0.2 and
        // sends 0.3 to the conflict; {S,M} keeps 0.08, gives 0.12 to {S}; Ω keeps 0.12,
        // gives 0.18 to {S}.
        let start = cell(&[(I, 0.5), (S | M, 0.2), (OMEGA, 0.3)]);
        let mut m = start;
        combine(&mut m, MotionMass::Stopped(0.6), ResidualPolicy::ToOmega);
        close(
            &m,
            &cell(&[(I, 0.2), (S | M, 0.08), (S, 0.3), (OMEGA, 0.12 + 0.3)]),
        );
        let mut m = start;
        combine(&mut m, MotionMass::Stopped(0.6), ResidualPolicy::Keep);
        close(
            &m,
            &cell(&[(0, 0.3), (I, 0.2), (S | M, 0.08), (S, 0.3), (OMEGA, 0.12)]),
        );
        let mut m = start;
        combine(&mut m, MotionMass::Stopped(0.6), ResidualPolicy::Normalise);
        close(
            &m,
            &cell(&[
                (I, 0.2 / 0.7),
                (S | M, 0.08 / 0.7),
                (S, 0.3 / 0.7),
                (OMEGA, 0.12 / 0.7),
            ]),
        );
    }

    /// The m({M}) of moving evidence; a panic for any other.
    fn moving_mass(evidence: MotionMass) -> f32 {
        match evidence {
            MotionMass::Moving(m) => m,
            other => panic!("not moving: {other:?}"),
        }
    }

    #[test]
    fn the_steps_own_m_is_not_moving_where_the_pose_error_shifts_a_surface_by_half_a_cell() {
        // σ = 0.1 m per axis, σ_θ = 0.002 rad at 20 m: the apparent shift of a static object
        // has σ = √2 · √(0.1² + 0.04²) = √2 · 0.107703 = 0.152315 m.
        let pose = super::super::tracks::PoseError {
            sensor_xy_m: [0.0, 0.0],
            sigma_m: 0.1,
            sigma_rad: 0.002,
        };
        let sigma = pose.displacement_sigma_m([12.0, 16.0]);
        assert!((sigma - 0.152_315).abs() < 1e-6, "{sigma}");
        let mut params = MotionParams::default();
        // 6 σ by default: 0.914 m.
        assert_eq!(
            unsupported_by_motion(sigma, 0.5, &params),
            MotionMass::Static(0.9)
        );
        // Off.
        params.unsupported_pose_sigmas = 0.0;
        assert_eq!(
            unsupported_by_motion(sigma, 0.5, &params),
            MotionMass::Vacuous
        );
        // 2 σ = 0.3046 m reaches half a 0.5 m cell: m(Ω∖{M}) = mu_static = 0.9.
        params.unsupported_pose_sigmas = 2.0;
        assert_eq!(
            unsupported_by_motion(sigma, 0.5, &params),
            MotionMass::Static(0.9)
        );
        // Not half a 0.8 m cell (0.4 m); 1 σ = 0.1523 m not half a 0.5 m cell either.
        assert_eq!(
            unsupported_by_motion(sigma, 0.8, &params),
            MotionMass::Vacuous
        );
        params.unsupported_pose_sigmas = 1.0;
        assert_eq!(
            unsupported_by_motion(sigma, 0.5, &params),
            MotionMass::Vacuous
        );
        // Exact poses (σ 0) never.
        params.unsupported_pose_sigmas = 100.0;
        assert_eq!(
            unsupported_by_motion(0.0, 0.5, &params),
            MotionMass::Vacuous
        );
    }

    #[test]
    fn erf_matches_its_table() {
        for (x, want) in [
            (0.0, 0.0),
            (0.5, 0.520_499_877_8),
            (1.0, 0.842_700_792_9),
            (-1.0, -0.842_700_792_9),
            (2.0, 0.995_322_265_0),
            (3.0, 0.999_977_909_5),
        ] {
            assert!((erf(x) - want).abs() < 2e-7, "erf({x}) = {}", erf(x));
        }
    }

    #[test]
    fn moving_means_faster_than_the_threshold() {
        let params = MotionParams::default();
        // 1.3 m/s east, σ 0.4 along it: z = (1.3 − 0.5)/0.4 = 2, erf(2/√2) = 0.9545,
        // m({M}) = mu_moving · 0.9545 = 0.9545 (mu_moving 1 by default).
        let walker = moving_mass(track_mass(&track([1.3, 0.0], 0.16, 3), &params));
        assert!((walker - 0.954_50).abs() < 1e-4, "{walker}");
        // 0.6 ± 0.4 m/s, a car crawling into a stop: z = 0.25, erf(0.177) = 0.197.
        let crawl = moving_mass(track_mass(&track([0.6, 0.0], 0.16, 3), &params));
        assert!((crawl - 0.197_4).abs() < 1e-3, "{crawl}");
        // Below the threshold it is not moving at all.
        assert!(!matches!(
            track_mass(&track([0.4, 0.0], 0.16, 3), &params),
            MotionMass::Moving(_)
        ));
    }

    #[test]
    fn a_cluster_on_a_building_is_not_stopped() {
        let on = [Some(MapContext::Road), Some(MapContext::Building)];
        let off = [Some(MapContext::Road), Some(MapContext::Other), None];
        let stopped = MotionMass::Stopped(0.9);
        assert_eq!(
            off_buildings(stopped, on.into_iter()),
            MotionMass::Static(0.9)
        );
        assert_eq!(off_buildings(stopped, off.into_iter()), stopped);
        let moving = MotionMass::Moving(0.5);
        assert_eq!(off_buildings(moving, on.into_iter()), moving);
    }

    fn track(v: [f64; 2], variance: f64, measurements: u32) -> Track {
        Track {
            id: 1,
            position_m: [0.0; 2],
            velocity: v.map(|v| VelocityFilter::new(v, variance)),
            last_seen_s: 0.0,
            first_seen_s: 0.0,
            measurements,
            travel_m: [0.0; 2],
            hits: measurements + 1,
            misses: 0,
            moving_frames: 0,
            moving_s: 0.0,
            registered_m: [0.0; 2],
            displaced: true,
        }
    }

    #[test]
    fn a_track_gives_moving_static_or_no_evidence() {
        let p = MotionParams::default();
        // 3 m/s east with σ = 1 m/s per axis: z = (3 − 0.5)/1, c = erf(2.5/√2) = 0.98758,
        // m({M}) = mu_moving (1) · c.
        let moving = moving_mass(track_mass(&track([3.0, 0.0], 1.0, 2), &p));
        assert!((moving - 0.987_581).abs() < 1e-5, "{moving}");
        // Slow and well known (σ = 0.14 m/s): static, m(Ω∖{M}) = mu_static = 0.9.
        assert_eq!(
            track_mass(&track([0.1, 0.0], 0.01, 1), &p),
            MotionMass::Static(0.9)
        );
        // Slow but uncertain (σ = √2 m/s), or never measured: nothing.
        assert_eq!(
            track_mass(&track([0.1, 0.0], 1.0, 3), &p),
            MotionMass::Vacuous
        );
        assert_eq!(
            track_mass(&track([3.0, 0.0], 1.0, 0), &p),
            MotionMass::Vacuous
        );
        // Moving after one registration only, when two are asked for: not yet.
        let two = MotionParams {
            moving_after_measurements: 2,
            ..p.clone()
        };
        assert_eq!(
            track_mass(&track([3.0, 0.0], 1.0, 1), &two),
            MotionMass::Vacuous
        );
        assert_eq!(
            track_mass(&track([3.0, 0.0], 1.0, 1), &p),
            MotionMass::Moving(moving)
        );
    }

    #[test]
    fn a_fast_track_within_the_pose_error_gives_nothing_and_a_slow_one_stays_static() {
        let p = MotionParams::default();
        let held = |t: Track| Track {
            displaced: false,
            ..t
        };
        // 3 m/s, registered twice, not displaced: no evidence, and held by the pose.
        let fast = held(track([3.0, 0.0], 1.0, 2));
        assert_eq!(track_mass(&fast, &p), MotionMass::Vacuous);
        assert!(within_pose_error(&fast, &p));
        // Displaced: moving, and not held.
        let free = track([3.0, 0.0], 1.0, 2);
        assert!(matches!(track_mass(&free, &p), MotionMass::Moving(_)));
        assert!(!within_pose_error(&free, &p));
        // Slow and well known, displaced or not: static, never held (the test is about M).
        let slow = held(track([0.1, 0.0], 0.01, 1));
        assert_eq!(track_mass(&slow, &p), MotionMass::Static(0.9));
        assert!(!within_pose_error(&slow, &p));
        // Never registered: nothing, and not held either.
        assert!(!within_pose_error(&held(track([3.0, 0.0], 1.0, 0)), &p));
    }

    #[test]
    fn a_silent_track_that_entered_cells_seen_free_is_moving() {
        let params = MotionParams::default();
        // Registered once, no shift, σ² = 0.8 (m/s)² per axis: √1.6 ≥ static_sigma_mps = 1,
        // too uncertain to be static; three of its four cells seen free: m({M}) = mu_moving
        // (1) · 0.75.
        let slow = track([0.0, 0.0], 0.8, 1);
        let mass = track_mass(&slow, &params);
        assert_eq!(mass, MotionMass::Vacuous);
        assert_eq!(
            entered_seen_free(mass, 0.75, &params),
            MotionMass::Moving(0.75)
        );
        // One cell of four: below match_fraction, nothing.
        assert_eq!(entered_seen_free(mass, 0.25, &params), MotionMass::Vacuous);
        // A track known static keeps its evidence whatever its cells.
        let still = track([0.0, 0.0], 0.1, 5);
        let mass = track_mass(&still, &params);
        assert_eq!(mass, MotionMass::Static(0.9));
        assert_eq!(entered_seen_free(mass, 1.0, &params), mass);
    }

    #[test]
    fn a_static_track_that_travelled_is_stopped() {
        let p = MotionParams::default();
        assert_eq!(p.mobile_after_travel_m, 2.0);
        assert_eq!(p.mobile_after_moving_s, 1.0);
        let mut t = track([0.1, 0.0], 0.01, 4);
        // 1.2 m east and 1.6 m north: 2 m in all, over 1 s moving: a mobile object standing
        // still.
        t.travel_m = [1.2, 1.6];
        t.moving_s = 1.0;
        assert_eq!(track_mass(&t, &p), MotionMass::Stopped(0.9));
        // The same 2 m in 0.9 s of moving (a short track, such as a static area's face
        // sliding for a few frames as the ego passes): only "not moving", never S.
        t.moving_s = 0.9;
        assert_eq!(track_mass(&t, &p), MotionMass::Static(0.9));
        t.moving_s = 1.0;
        // 1.9 m: not enough, only "not moving".
        t.travel_m = [1.9, 0.0];
        assert_eq!(track_mass(&t, &p), MotionMass::Static(0.9));
        // Travelled, but moving now: moving, whatever it did before.
        let mut fast = track([3.0, 0.0], 1.0, 2);
        fast.travel_m = [5.0, 0.0];
        assert!(matches!(track_mass(&fast, &p), MotionMass::Moving(_)));
        // Travelled, but too uncertain now: nothing.
        let mut unsure = track([0.1, 0.0], 1.0, 3);
        unsure.travel_m = [5.0, 0.0];
        assert_eq!(track_mass(&unsure, &p), MotionMass::Vacuous);
    }
}
