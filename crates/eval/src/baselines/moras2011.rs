//! Moras, Cherfaoui & Bonnifait, "Credibilist occupancy grids for vehicle perception in dynamic
//! environments", ICRA 2011: a two-class evidential grid on Ω = {F, O}.
//!
//! Per scan and cell: discount the previous grid classically (eq 13-14 of Kurdej et al.; rate per
//! second, α(dt) = 1 − (1 − α_1s)^dt as SPEC §5), combine with the sensor grid by the
//! conjunctive rule, and read the two conflicts: ∅_FO = m_prev(F)·m_SG(O) (free before, occupied
//! now: something moved in) and ∅_OF = m_prev(O)·m_SG(F). Both go to Ω (Yager-like, as SPEC's
//! default residual policy), so the grid stays normal. No map, no accumulator.
//!
//! Decision: M where ∅_FO of this scan exceeds `moving_conflict_threshold`; otherwise unknown if
//! never observed or m(Ω) > `unknown_threshold`; otherwise F if m(F) ≥ m(O) (the larger
//! pignistic probability), else O.

use super::SensorGridBaseline;
use crate::Label;
use evigrid::SensorGrid;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Parameters. By default: μ as the sensor model gives them, discount 0.5 per second (the paper
/// gives a per-step factor for its own rate; 0.5/s keeps about 93 % per 10 Hz scan), moving
/// threshold 0.3 (below the ∅_FO ≈ 0.5 that a cell believed free at m(F) ≈ 0.7 gets when a 0.8
/// occupied return lands in it, above what noise on a half-known cell gives), unknown above
/// m(Ω) = 0.5 as evigrid's decision.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Moras2011Params {
    /// Classical discount rate per second.
    pub discount_per_second: f64,
    /// ∅_FO above which a cell is moving.
    pub moving_conflict_threshold: f32,
    /// m(Ω) above which a cell is unknown.
    pub unknown_threshold: f32,
}

impl Default for Moras2011Params {
    fn default() -> Self {
        Self {
            discount_per_second: 0.5,
            moving_conflict_threshold: 0.3,
            unknown_threshold: 0.5,
        }
    }
}

/// The grid state (structure of arrays, window storage layout).
#[derive(Clone, Debug)]
pub struct Moras2011 {
    params: Moras2011Params,
    m_free: Vec<f32>,
    m_occupied: Vec<f32>,
    conflict_fo: Vec<f32>,
    seen: Vec<bool>,
}

/// Clamps a sensor mass pair into a valid mass function (NaN → 0).
fn sanitise(f: f32, o: f32) -> (f32, f32) {
    let f = if f.is_nan() { 0.0 } else { f.clamp(0.0, 1.0) };
    let o = if o.is_nan() {
        0.0
    } else {
        o.clamp(0.0, 1.0 - f)
    };
    (f, o)
}

impl Moras2011 {
    /// A grid of `len` cells, all unknown.
    pub fn new(len: usize, params: Moras2011Params) -> Self {
        Self {
            params,
            m_free: vec![0.0; len],
            m_occupied: vec![0.0; len],
            conflict_fo: vec![0.0; len],
            seen: vec![false; len],
        }
    }
    /// m(F), m(O) and ∅_FO of a cell.
    pub fn cell(&self, idx: usize) -> Option<(f32, f32, f32)> {
        Some((
            *self.m_free.get(idx)?,
            self.m_occupied[idx],
            self.conflict_fo[idx],
        ))
    }

    /// Makes the storage cells in `range` unknown (they just entered the window).
    pub fn reset_range(&mut self, range: Range<usize>) {
        let r = range.start.min(self.seen.len())..range.end.min(self.seen.len());
        self.m_free[r.clone()].fill(0.0);
        self.m_occupied[r.clone()].fill(0.0);
        self.conflict_fo[r.clone()].fill(0.0);
        self.seen[r].fill(false);
    }

    /// Fuses one scan's SensorGrid, `dt_s` after the previous one.
    pub fn update(&mut self, sensor: &SensorGrid, dt_s: f64) {
        let keep =
            (1.0 - self.params.discount_per_second.clamp(0.0, 1.0)).powf(dt_s.max(0.0)) as f32;
        let cells = self
            .m_free
            .iter_mut()
            .zip(self.m_occupied.iter_mut())
            .zip(self.conflict_fo.iter_mut())
            .zip(self.seen.iter_mut())
            .zip(sensor.m_free().iter().zip(sensor.m_occupied()));
        for ((((mf, mo), cfo), seen), (&sf, &so)) in cells {
            let (sf, so) = sanitise(sf, so);
            let sw = 1.0 - sf - so;
            // Discount: every focal set but Ω keeps `keep` of its mass.
            let pf = *mf * keep;
            let po = *mo * keep;
            let pw = 1.0 - pf - po;
            // Conjunctive combination on {F, O}.
            let fo = pf * so;
            *mf = pf * sf + pf * sw + pw * sf;
            *mo = po * so + po * sw + pw * so;
            // Both conflicts (and pw·sw) end on Ω, which is implicit.
            *cfo = fo;
            *seen |= sf > 0.0 || so > 0.0;
        }
    }
}

impl SensorGridBaseline for Moras2011 {
    const NAME: &'static str = "moras2011";

    fn reset_range(&mut self, range: Range<usize>) {
        Moras2011::reset_range(self, range);
    }

    fn update(&mut self, sensor: &SensorGrid, dt_s: f64) {
        Moras2011::update(self, sensor, dt_s);
    }

    fn decide(&self, out: &mut [Label]) {
        let p = &self.params;
        for (k, d) in out.iter_mut().enumerate().take(self.seen.len()) {
            let (mf, mo) = (self.m_free[k], self.m_occupied[k]);
            *d = if self.conflict_fo[k] > p.moving_conflict_threshold {
                Label::M
            } else if !self.seen[k] || 1.0 - mf - mo > p.unknown_threshold {
                Label::Unknown
            } else if mf >= mo {
                Label::F
            } else {
                Label::O
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn sg(f: f32, o: f32) -> SensorGrid {
        let mut sg = SensorGrid::new(1, 1);
        sg.m_free_mut()[0] = f;
        sg.m_occupied_mut()[0] = o;
        sg
    }

    #[test]
    fn free_then_occupied_is_moving_by_the_fo_conflict() {
        // No discount (rate 0) to keep the numbers simple.
        let params = Moras2011Params {
            discount_per_second: 0.0,
            ..Moras2011Params::default()
        };
        let mut g = Moras2011::new(1, params);
        let mut d = [Label::Unknown];
        g.decide(&mut d);
        assert_eq!(d[0], Label::Unknown);
        // Scan 1 free (0.7): m(F) = 0.7, m(Ω) = 0.3 → F.
        g.update(&sg(0.7, 0.0), 0.1);
        g.decide(&mut d);
        assert_eq!(d[0], Label::F);
        // Scan 2 free: m(F) = 0.7 + 0.3·0.7 = 0.91.
        g.update(&sg(0.7, 0.0), 0.1);
        assert_relative_eq!(g.cell(0).map_or(0.0, |c| c.0), 0.91, epsilon = 1e-6);
        // Scan 3 occupied (0.8): ∅_FO = 0.91·0.8 = 0.728 > 0.3 → M;
        // m(F) = 0.91·0.2 = 0.182, m(O) = 0.09·0.8 = 0.072.
        g.update(&sg(0.0, 0.8), 0.1);
        let (mf, mo, fo) = g.cell(0).unwrap_or_default();
        assert_relative_eq!(fo, 0.728, epsilon = 1e-6);
        assert_relative_eq!(mf, 0.182, epsilon = 1e-6);
        assert_relative_eq!(mo, 0.072, epsilon = 1e-6);
        g.decide(&mut d);
        assert_eq!(d[0], Label::M);
        // Scans 4, 5 occupied: ∅_FO = 0.182·0.8 = 0.1456 → not M; m(O) grows to
        // 0.072 + 0.746·0.8 = 0.6688 after scan 4 (pw = 1 − 0.182 − 0.072 = 0.746),
        // m(F) = 0.182·0.2 = 0.0364 → O.
        g.update(&sg(0.0, 0.8), 0.1);
        let (mf, mo, fo) = g.cell(0).unwrap_or_default();
        assert_relative_eq!(fo, 0.1456, epsilon = 1e-6);
        assert_relative_eq!(mo, 0.6688, epsilon = 1e-6);
        assert_relative_eq!(mf, 0.0364, epsilon = 1e-6);
        g.decide(&mut d);
        assert_eq!(d[0], Label::O);
        g.reset_range(0..1);
        g.decide(&mut d);
        assert_eq!(d[0], Label::Unknown);
    }

    #[test]
    fn discount_follows_the_per_second_rate() {
        // α_1s = 0.75 over dt = 0.5 s keeps (0.25)^0.5 = 0.5: m(F) 0.7 → 0.35, then a vacuous scan
        // leaves it there.
        let mut g = Moras2011::new(
            1,
            Moras2011Params {
                discount_per_second: 0.75,
                ..Moras2011Params::default()
            },
        );
        g.update(&sg(0.7, 0.0), 0.5);
        g.update(&sg(0.0, 0.0), 0.5);
        assert_relative_eq!(g.cell(0).map_or(0.0, |c| c.0), 0.35, epsilon = 1e-6);
        // m(Ω) = 0.65 > 0.5 → unknown again.
        let mut d = [Label::F];
        g.decide(&mut d);
        assert_eq!(d[0], Label::Unknown);
    }
}
