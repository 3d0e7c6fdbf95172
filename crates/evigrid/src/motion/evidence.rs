//! The motion belief of a track and its combination with a cell's mass function on Ω_PG.
//!
//! A track's velocity v (per-axis variances σ²) gives the statistic χ² = vx²/σx² + vy²/σy²,
//! whose χ²(2) distribution under "v = 0" gives the confidence that the object moves,
//! c = 1 − exp(−χ²/2). Then, on the cells of the track's cluster in this frame:
//! - moving (|v| ≥ `min_speed_mps`, and at least `moving_after_measurements` registrations
//!   of the track): m({M}) = `mu_moving` · c, the rest on Ω;
//! - static (|v| < `min_speed_mps` and √(σx² + σy²) < `static_sigma_mps`: slow and known
//!   well enough): m(Ω∖{M}) = `mu_static`, the rest on Ω: "not moving", which says nothing
//!   about I, U or S;
//! - otherwise (never registered, or too uncertain): vacuous.
//!
//! The cell's mass function m is combined with it by the conjunctive rule on Ω_PG, and the
//! conflict it creates follows the fusion's residual policy (SPEC §5 step 4): mass on {M}
//! meets m(A) for A ∌ M as conflict, mass on Ω∖{M} meets m({M}) as conflict. Mass on a set A
//! goes only to A ∩ {M} or A∖{M}, so a grid whose masses lie on the sets the step can reach
//! keeps them there.

use crate::grids::{N_SETS, OMEGA, class};
use crate::params::{MotionParams, ResidualPolicy};

use super::tracks::Track;

/// The motion evidence on one cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MotionMass {
    /// No evidence: m(Ω) = 1.
    Vacuous,
    /// m({M}) = the value, the rest on Ω.
    Moving(f32),
    /// m(Ω∖{M}) = the value, the rest on Ω.
    Static(f32),
}

/// The evidence a track gives its cells.
pub(crate) fn track_mass(track: &Track, params: &MotionParams) -> MotionMass {
    if track.measurements == 0 {
        return MotionMass::Vacuous;
    }
    let [x, y] = track.velocity;
    let speed = x.mean_mps.hypot(y.mean_mps);
    if speed >= params.min_speed_mps {
        if (track.measurements as usize) < params.moving_after_measurements {
            return MotionMass::Vacuous;
        }
        let chi_sq = x.mean_mps * x.mean_mps / x.variance + y.mean_mps * y.mean_mps / y.variance;
        let confidence = 1.0 - (-0.5 * chi_sq).exp();
        MotionMass::Moving((params.mu_moving * confidence) as f32)
    } else if (x.variance + y.variance).sqrt() < params.static_sigma_mps {
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
    use class::{F, M, S};

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

    fn track(v: [f64; 2], variance: f64, measurements: u32) -> Track {
        Track {
            position_m: [0.0; 2],
            velocity: v.map(|v| VelocityFilter::new(v, variance)),
            last_seen_s: 0.0,
            measurements,
        }
    }

    #[test]
    fn a_track_gives_moving_static_or_no_evidence() {
        let p = MotionParams::default();
        // 3 m/s east with σ = 1 m/s per axis: χ² = 9, c = 1 − e^{−4.5}.
        let expected = (0.8 * (1.0 - (-4.5f64).exp())) as f32;
        assert_eq!(
            track_mass(&track([3.0, 0.0], 1.0, 2), &p),
            MotionMass::Moving(expected)
        );
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
            MotionMass::Moving(expected)
        );
    }
}
