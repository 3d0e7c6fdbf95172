//! Baselines from the literature, for comparison with the map-aided evidential grid.
//!
//! Both are [`GridMethod`]s: they consume the same SensorGrid as evigrid's
//! step (m(F), m(O) per cell, in the window's storage layout, from the shared front end) and
//! decide each cell as a [`Label`]: F, M, O (occupied and static — a two-class
//! method cannot say whether it is a building, street furniture or a stopped car) or unknown. The metrics score O as "static
//! occupied": wrong for I, U and S in the five-class view, right for all three in the coarse view
//! (see [`crate::metrics`]).
//!
//! - [`Moras2011`]: two-class credibilist grid with discounting and conjunctive fusion, moving
//!   where the conflict "free before, occupied now" exceeds a threshold.
//! - [`LogOdds`]: a Bayesian occupancy grid with OctoMap's default sensor model, moving where a
//!   cell flips from free to occupied.

pub mod log_odds;
pub mod moras2011;

pub use log_odds::{LogOdds, LogOddsParams};
pub use moras2011::{Moras2011, Moras2011Params};

use std::ops::Range;

use evigrid::{FrontEnd, SensorGrid};

use crate::{EvalError, GridMethod, Label};

/// A baseline with its own per-cell state, in the window's storage layout, fed the shared
/// front end's SensorGrid: what both baselines are. Each says how a cell is reset, updated and
/// decided; following the front end is written once, in the [`GridMethod`] every such baseline
/// is.
pub trait SensorGridBaseline {
    /// Short name for reports.
    const NAME: &'static str;

    /// Makes the storage cells in `range` unknown (they just entered the window).
    fn reset_range(&mut self, range: Range<usize>);

    /// Fuses one scan's SensorGrid, `dt_s` after the previous one.
    fn update(&mut self, sensor: &SensorGrid, dt_s: f64);

    /// Writes the decision of every storage cell into `out` (window storage order).
    fn decide(&self, out: &mut [Label]);
}

impl<B: SensorGridBaseline> GridMethod for B {
    fn name(&self) -> &'static str {
        B::NAME
    }

    fn process(&mut self, front_end: &FrontEnd) -> Result<(), EvalError> {
        for span in front_end.new_cell_spans() {
            self.reset_range(span);
        }
        self.update(front_end.sensor_grid(), front_end.dt_s());
        Ok(())
    }

    fn decide(&self, out: &mut [Label]) {
        SensorGridBaseline::decide(self, out);
    }
}
