//! A Bayesian occupancy grid in log-odds with OctoMap's default sensor model (Hornung et al.,
//! "OctoMap: an efficient probabilistic 3D mapping framework based on octrees", Autonomous Robots
//! 2013; defaults of `OccupancyOcTreeBase`: hit 0.7, miss 0.4, clamping 0.1192 / 0.971,
//! occupancy threshold 0.5).
//!
//! A sensor-grid cell whose m(O) exceeds its m(F) is a hit, one with m(F) > 0 otherwise is a
//! miss, a vacuous one is not updated. Decision: unknown if never updated, occupied where
//! log-odds ≥ logit(threshold), free otherwise.
//!
//! Moving: a cell that goes from decided free (previous scan) to decided occupied is M on that
//! scan and, while it stays occupied, for `moving_hold_s` after it (by default 0.5 s: five scans
//! at 10 Hz, about the time a car at 10 m/s takes to drive over a cell's worth of its own
//! length); then it is occupied-static (O). Without the hold only the leading edge of a moving
//! car would be M.

use super::SensorGridBaseline;
use crate::Label;
use evigrid::SensorGrid;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Parameters; by default OctoMap's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LogOddsParams {
    /// Probability of occupancy given a hit.
    pub prob_hit: f64,
    /// Probability of occupancy given a miss.
    pub prob_miss: f64,
    /// Lower clamping probability.
    pub clamp_min: f64,
    /// Upper clamping probability.
    pub clamp_max: f64,
    /// Occupied at or above this probability.
    pub occupancy_threshold: f64,
    /// How long a flip from free to occupied stays M, seconds.
    pub moving_hold_s: f64,
}

impl Default for LogOddsParams {
    fn default() -> Self {
        Self {
            prob_hit: 0.7,
            prob_miss: 0.4,
            clamp_min: 0.1192,
            clamp_max: 0.971,
            occupancy_threshold: 0.5,
            moving_hold_s: 0.5,
        }
    }
}

fn logit(p: f64) -> f32 {
    let p = p.clamp(1e-6, 1.0 - 1e-6);
    (p / (1.0 - p)).ln() as f32
}

const UNSEEN: u8 = 0;
const FREE: u8 = 1;
const OCCUPIED: u8 = 2;

/// The grid state (window storage layout).
#[derive(Clone, Debug)]
pub struct LogOdds {
    params: LogOddsParams,
    log_odds: Vec<f32>,
    state: Vec<u8>,
    moving_left: Vec<u16>,
}

impl LogOdds {
    /// A grid of `len` cells, all unknown.
    pub fn new(len: usize, params: LogOddsParams) -> Self {
        Self {
            params,
            log_odds: vec![0.0; len],
            state: vec![UNSEEN; len],
            moving_left: vec![0; len],
        }
    }
    /// Log-odds of a cell.
    pub fn log_odds(&self, idx: usize) -> Option<f32> {
        self.log_odds.get(idx).copied()
    }

    /// Makes the storage cells in `range` unknown (they just entered the window).
    pub fn reset_range(&mut self, range: Range<usize>) {
        let r = range.start.min(self.state.len())..range.end.min(self.state.len());
        self.log_odds[r.clone()].fill(0.0);
        self.state[r.clone()].fill(UNSEEN);
        self.moving_left[r].fill(0);
    }

    /// Fuses one scan's SensorGrid, `dt_s` after the previous one.
    pub fn update(&mut self, sensor: &SensorGrid, dt_s: f64) {
        let p = &self.params;
        let (hit, miss) = (logit(p.prob_hit), logit(p.prob_miss));
        let (lo, hi) = (logit(p.clamp_min), logit(p.clamp_max));
        let threshold = logit(p.occupancy_threshold);
        let hold = if dt_s > 0.0 {
            (p.moving_hold_s / dt_s).round().clamp(1.0, 60_000.0) as u16
        } else {
            1
        };
        let cells = self
            .log_odds
            .iter_mut()
            .zip(self.state.iter_mut())
            .zip(self.moving_left.iter_mut())
            .zip(sensor.m_free().iter().zip(sensor.m_occupied()));
        for (((l, state), left), (&sf, &so)) in cells {
            let (sf, so) = (
                if sf.is_nan() { 0.0 } else { sf },
                if so.is_nan() { 0.0 } else { so },
            );
            let before = *state;
            if so > sf && so > 0.0 {
                *l = (*l + hit).clamp(lo, hi);
            } else if sf > 0.0 {
                *l = (*l + miss).clamp(lo, hi);
            } else if before == UNSEEN {
                continue;
            }
            let now = if *l >= threshold { OCCUPIED } else { FREE };
            *left = if now != OCCUPIED {
                0
            } else if before == FREE {
                hold
            } else {
                left.saturating_sub(1)
            };
            *state = now;
        }
    }
}

impl SensorGridBaseline for LogOdds {
    const NAME: &'static str = "log-odds";

    fn reset_range(&mut self, range: Range<usize>) {
        LogOdds::reset_range(self, range);
    }

    fn update(&mut self, sensor: &SensorGrid, dt_s: f64) {
        LogOdds::update(self, sensor, dt_s);
    }

    fn decide(&self, out: &mut [Label]) {
        for (k, d) in out.iter_mut().enumerate().take(self.state.len()) {
            *d = match self.state[k] {
                UNSEEN => Label::Unknown,
                FREE => Label::F,
                _ if self.moving_left[k] > 0 => Label::M,
                _ => Label::O,
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
    fn octomap_updates_clamp_and_flip_to_moving() {
        let mut g = LogOdds::new(1, LogOddsParams::default());
        let mut d = [Label::F];
        g.decide(&mut d);
        assert_eq!(d[0], Label::Unknown);
        // logit(0.4) = −0.405465; five misses would reach −2.03 but clamp at logit(0.1192) = −2.000028.
        for _ in 0..5 {
            g.update(&sg(0.7, 0.0), 0.1);
        }
        assert_relative_eq!(g.log_odds(0).unwrap_or(0.0), -2.000_028, epsilon = 1e-4);
        g.decide(&mut d);
        assert_eq!(d[0], Label::F);
        // Hits add logit(0.7) = 0.847298: −1.15273, −0.30543 (still free), +0.54187 → occupied,
        // and it was free the scan before → M, held 0.5 s / 0.1 s = 5 scans.
        g.update(&sg(0.0, 0.8), 0.1);
        g.update(&sg(0.0, 0.8), 0.1);
        g.decide(&mut d);
        assert_eq!(d[0], Label::F);
        g.update(&sg(0.0, 0.8), 0.1);
        assert_relative_eq!(g.log_odds(0).unwrap_or(0.0), 0.541_866, epsilon = 1e-4);
        let mut decisions = Vec::new();
        for _ in 0..6 {
            g.decide(&mut d);
            decisions.push(d[0]);
            g.update(&sg(0.0, 0.8), 0.1);
        }
        // Flip scan + 4 more = 5 scans of M, then O.
        assert_eq!(
            decisions,
            vec![Label::M, Label::M, Label::M, Label::M, Label::M, Label::O]
        );
        // Clamped at logit(0.971) = 3.511031.
        assert_relative_eq!(g.log_odds(0).unwrap_or(0.0), 3.511_031, epsilon = 1e-4);
    }

    #[test]
    fn vacuous_cells_are_not_updated_and_occupied_from_unseen_is_static() {
        let mut g = LogOdds::new(1, LogOddsParams::default());
        g.update(&sg(0.0, 0.0), 0.1);
        let mut d = [Label::F];
        g.decide(&mut d);
        assert_eq!(d[0], Label::Unknown);
        // First ever observation occupied: unseen → occupied is not a flip from free.
        g.update(&sg(0.0, 0.8), 0.1);
        g.decide(&mut d);
        assert_eq!(d[0], Label::O);
    }
}
