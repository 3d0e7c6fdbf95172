//! Baselines from the literature, for comparison with the map-aided evidential grid.
//!
//! Both consume the same [`SensorGrid`] as evigrid's step (m(F), m(O) per cell, in the window's
//! storage layout) and decide each cell in the metrics' label space
//! ([`Predicted`]): F, M, O (occupied and static — a two-class method cannot say whether it is a
//! building, street furniture or a stopped car) or unknown. The metrics score O as "static
//! occupied": wrong for I, U and S in the five-class view, right for all three in the coarse view
//! (see [`crate::metrics`]).
//!
//! - [`Moras2011`]: two-class credibilist grid with discounting and conjunctive fusion, moving
//!   where the conflict "free before, occupied now" exceeds a threshold.
//! - [`LogOdds`]: a Bayesian occupancy grid with OctoMap's default sensor model, moving where a
//!   cell flips from free to occupied.

use crate::metrics::Predicted;
use evigrid::SensorGrid;
use std::ops::Range;

pub mod log_odds;
pub mod moras2011;

pub use log_odds::{LogOdds, LogOddsParams};
pub use moras2011::{Moras2011, Moras2011Params};

/// A per-cell dynamic-occupancy method fed scan by scan.
pub trait Baseline {
    /// Short name for reports.
    fn name(&self) -> &'static str;
    /// Makes the storage cells in `range` unknown (they just entered the window).
    fn reset_range(&mut self, range: Range<usize>);
    /// Fuses one scan's sensor grid, `dt_s` after the previous one.
    fn update(&mut self, sensor: &SensorGrid, dt_s: f64);
    /// Writes the decision of every storage cell.
    fn decide(&self, out: &mut [Predicted]);
}
