//! One time step of the fusion (SPEC §5, eq 16-31), for every cell of the window.
//!
//! The PerceptionGrid is updated in place. Cells are processed in blocks of 64 loaded from
//! the mass planes into a small stack buffer; every stage is a pass over the block (module
//! `passes`, each derived there), so the work per cell is a fixed sequence of vectorisable
//! multiply-adds without per-cell branches or allocation. Per-block branches only skip work that
//! is exactly a no-op. Tasks of whole blocks run in parallel with rayon; each cell is computed
//! alone and the statistics are integer counts, so the result is bit-identical whatever the
//! number of threads (ARCHITECTURE.md, "The fusion kernel").
//!
//! Where each concern lives:
//! - this file: the entry points [`step`] and [`step_and_decide`], and [`StepStats`];
//! - `constants`: what the step derives from [`Params`] once: the rates for `dt`
//!   ([`rate_for_step`]), each map context's prior, the thresholds;
//! - `schedule`: tasks, tiles and blocks, and the choice between the AVX2 and the portable
//!   build;
//! - `memory`: the grids' planes over a run of cells, the stack buffer of one block loaded from
//!   them and stored back, and memory brought in ahead of the work;
//! - `evidence`: the map prior of each context, and the sensor's evidence SG' of a block (steps
//!   1-2);
//! - `fuse`: the sequence of SPEC §5 on one block; `stages`: its stages, one function each;
//! - `passes`: the mass transfers the stages are made of; `lanes`: lane reductions.
//!
//! ```
//! use evigrid::{GisGrid, Params, PerceptionGrid, SensorGrid, step};
//! use evigrid::class;
//! use geodata::MapContext;
//!
//! let mut pg = PerceptionGrid::new(2, 1);
//! let mut sg = SensorGrid::new(2, 1);
//! let mut gg = GisGrid::new(2, 1);
//! sg.m_free_mut()[0] = 0.7; // the sensor sees cell 0 free …
//! gg.context[0] = MapContext::Road; // … on a road
//! let mut params = Params::default();
//! params.map.beta_road = 0.8;
//! let stats = step(&mut pg, &sg, &gg, &params, 0.1);
//! assert_eq!(stats.observed_cells, 1);
//! // r(SG) ⊕ GG on a road: {F} 0.7, {F,S,M} 0.8·0.3 = 0.24, Ω 0.06; the vacuous past changes nothing.
//! assert!((pg.mass(class::F, 0) - 0.7).abs() < 1e-6);
//! assert!((pg.mass(class::F | class::S | class::M, 0) - 0.24).abs() < 1e-6);
//! assert_eq!(pg.mass(31, 1), 1.0); // cell 1 was not observed: still vacuous
//! ```

// Lane loops index several arrays by the same cell index `i`: that is the form the compiler
// vectorises, and zipped iterators over five arrays would only hide it.
#![allow(clippy::needless_range_loop)]

mod constants;
mod evidence;
mod fuse;
mod lanes;
mod memory;
mod passes;
mod schedule;
mod stages;

pub use constants::{rate_for_step, set_rate_per_second};

use crate::grids::{GisGrid, PerceptionGrid, SensorGrid};
use crate::label::Label;
use crate::params::Params;
use constants::{Discount, StepConstants};
use memory::CellRun;
use rayon::iter::{IndexedParallelIterator, IntoParallelIterator, ParallelIterator};

/// What happened during one step, counted over the window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct StepStats {
    /// Cells updated.
    pub cells: u64,
    /// Cells whose SensorGrid was not vacuous.
    pub observed_cells: u64,
    /// Cells where the sensor and the map were in total conflict (K = 1, SPEC §5 step 2): the
    /// refined sensor grid r(SG) was used there without the map.
    pub total_map_conflicts: u64,
    /// Times the `normalise` residual policy had nothing left to rescale and fell back to
    /// `to_omega` (fusion or specialisation; a cell may count twice).
    pub normalisation_fallbacks: u64,
    /// Bytes of grid state the step read and wrote: the planes of each block it could not skip
    /// (see [`PerceptionGrid`]), with the SensorGrid and GisGrid planes.
    pub state_bytes_moved: u64,
}

impl StepStats {
    pub(super) fn merged(self, other: StepStats) -> StepStats {
        StepStats {
            cells: self.cells + other.cells,
            observed_cells: self.observed_cells + other.observed_cells,
            total_map_conflicts: self.total_map_conflicts + other.total_map_conflicts,
            normalisation_fallbacks: self.normalisation_fallbacks + other.normalisation_fallbacks,
            state_bytes_moved: self.state_bytes_moved + other.state_bytes_moved,
        }
    }
}

/// Runs one time step (SPEC §5) on every cell: fuses the SensorGrid `sg` of this scan and the
/// map prior `gg` into the PerceptionGrid `pg`, `dt_s` seconds after the previous step.
///
/// `params` should have passed [`Params::validate`]. A negative or NaN `dt_s` counts as 0 (no
/// discounting). Runs on the current rayon pool (use `ThreadPool::install` to choose one).
///
/// # Panics
/// If the three grids do not have the same width and height, or a SensorGrid or GisGrid plane
/// does not hold `width · height` values.
///
/// # References
/// SPEC §5; Kurdej et al. 2013, eq 16-31.
pub fn step(
    pg: &mut PerceptionGrid,
    sg: &SensorGrid,
    gg: &GisGrid,
    params: &Params,
    dt_s: f64,
) -> StepStats {
    step_cells(pg, sg, gg, params, dt_s, None, |run, k| run.step(k))
}

/// [`step`], then the decision of every cell (SPEC §6, as [`decide_grid`]) into `decisions`,
/// made while each block of cells is still in cache: one pass over the grid instead of two.
///
/// # Panics
/// As [`step`], and if `decisions.len()` is not the number of cells.
///
/// [`decide_grid`]: crate::decision::decide_grid
pub fn step_and_decide(
    pg: &mut PerceptionGrid,
    sg: &SensorGrid,
    gg: &GisGrid,
    params: &Params,
    dt_s: f64,
    decisions: &mut [Label],
) -> StepStats {
    assert_eq!(decisions.len(), pg.len(), "decision buffer size");
    step_cells(pg, sg, gg, params, dt_s, Some(decisions), |run, k| {
        run.step(k)
    })
}

fn step_cells(
    pg: &mut PerceptionGrid,
    sg: &SensorGrid,
    gg: &GisGrid,
    params: &Params,
    dt_s: f64,
    decisions: Option<&mut [Label]>,
    kernel: impl Fn(CellRun<'_>, &StepConstants) -> StepStats + Sync,
) -> StepStats {
    let (width, len) = (pg.width(), pg.len());
    assert!(
        (sg.width, sg.height, gg.width, gg.height) == (width, pg.height(), width, pg.height()),
        "grid sizes differ: PerceptionGrid {width}×{}, SensorGrid {}×{}, GisGrid {}×{}",
        pg.height(),
        sg.width,
        sg.height,
        gg.width,
        gg.height
    );
    assert!(
        sg.m_free().len() == len && sg.m_occupied().len() == len && gg.context.len() == len,
        "a SensorGrid or GisGrid plane does not hold {len} cells"
    );
    let constants = StepConstants::new(params, dt_s);
    // A grid that only ever held mass on the 17 reachable sets keeps it there under discounting
    // to Ω: its other 15 planes are +0 and need not even be read. Mercier's discounting moves
    // mass anywhere.
    let to_omega = matches!(constants.discount, Discount::ToOmega(_));
    let reachable_only = to_omega && !pg.may_leave_reachable();
    if !to_omega {
        pg.note_may_leave_reachable();
    }
    let cells = CellRun {
        reachable_only,
        pg: pg.planes_mut(),
        m_free: sg.m_free(),
        m_occupied: sg.m_occupied(),
        sensor_blocks: sg.may_hold_mass(),
        context: &gg.context,
        decisions,
    };
    cells
        .into_tasks()
        .into_par_iter()
        .with_max_len(1)
        .map(|run| kernel(run, &constants))
        .reduce(StepStats::default, StepStats::merged)
}

#[cfg(test)]
mod tests;
