//! evigrid: evidential occupancy grids fused with geo-referenced maps.
//!
//! This crate implements Kurdej, Moras, Cherfaoui & Bonnifait (2013): each cell of a world-fixed
//! grid holds a mass function on Ω_PG = {F, I, U, S, M} (free, mapped infrastructure, unmapped
//! infrastructure, stopped, moving). Every scan gives a SensorGrid on {F, O}; the map gives a
//! GISGrid prior; a fusion step discounts the past, combines, and uses the conflict between past
//! and present to tell moving objects from static ones. What is computed is specified equation by
//! equation in the project's `SPEC.md`.
//!
//! The key design decision: the grids are structure-of-arrays of `f32`, one plane per focal set,
//! and the step is a dedicated block kernel whose passes are derived from the belief-function
//! operations rather than calling them; [`reference`](mod@crate::reference) evaluates the same
//! step on one cell in f64 with the generic `belief` crate, and the tests hold the kernel to it.
//!
//! # The API
//!
//! The modules are private; what a user needs is re-exported here, flat:
//! - the per-frame loop: [`Pipeline`] for one drive, or its two halves, the [`FrontEnd`]
//!   (window, map prior, SensorGrid; SPEC §2-§4) and the [`Fusion`] of the paper's method
//!   (SPEC §5-§6), so that other grid methods can share one front end;
//! - [`Params`] (SPEC §7) and one type per section;
//! - the cell labels ([`Label`], one numbering for decisions, truth and baselines), [`decide`],
//!   [`decide_grid`] and [`betp`] (SPEC §6);
//! - the stages, for callers that drive them one by one: the grids ([`PerceptionGrid`],
//!   [`SensorGrid`], [`GisGrid`], the focal sets in [`class`]) on a world-fixed [`Window`], the
//!   [`SensorModel`] with poses as [`IsometryMatrix3`] (nalgebra's, with [`PoseExt`]), the
//!   [`MapPrior`] and its SPEC §4 table ([`prior_focal_set`], [`prior_beta`]), the fusion
//!   [`step()`], the [`MovingTrace`];
//! - [`reference`](mod@reference), the f64 yardstick.
//!
//! The method reads no file and writes none: scans and poses come from the `evigrid-drive`
//! crate, maps from `geodata`, pictures and exports go through the `evigrid-output` crate. See
//! `examples/scan_and_map.rs` for a scan and a map through [`Pipeline`] to a decision.
//!
//! ```
//! use evigrid::{GisGrid, Params, PerceptionGrid, SensorGrid, Label, decide};
//! use geodata::MapContext;
//!
//! let params = Params::default();
//! let (mut pg, mut sg, mut gg) = (PerceptionGrid::new(1, 1), SensorGrid::new(1, 1), GisGrid::new(1, 1));
//! gg.context[0] = MapContext::Road;
//! // A road cell seen free, then occupied: the object appeared, so its mass goes to M.
//! sg.m_free_mut()[0] = 0.7;
//! for _ in 0..3 {
//!     evigrid::step(&mut pg, &sg, &gg, &params, 0.1);
//! }
//! sg.m_free_mut()[0] = 0.0;
//! sg.m_occupied_mut()[0] = 0.8;
//! evigrid::step(&mut pg, &sg, &gg, &params, 0.1);
//! let decided = decide(&pg.cell_masses(0), pg.seen()[0] != 0, params.decision.unknown_threshold);
//! assert_eq!(decided, Label::M);
//! ```

#![deny(missing_docs)]

mod decision;
pub mod ego_path;
mod grids;
mod label;
mod map_prior;
pub mod motion;
mod params;
mod pipeline;
mod pose;
pub mod reference;
mod sensor_model;
mod step;
mod trace;
mod window;

// The per-frame pipeline: what an embedding uses first.
pub use pipeline::{
    FrameStats, FrontEnd, FrontEndStats, Fusion, FusionStats, MapFrame, Method, NewCells, Pipeline,
    PipelineError, Prior, RefinementOutcome, RefinementStats,
};
// Parameters (SPEC §7), one type per `[section]`.
pub use params::{
    AccumulatorParams, ClassRates, DecisionParams, DiscountMode, FusionParams, GridParams,
    GroundModel, LocalisationParams, MEMORY_BUDGET_BYTES, MIN_CELL_SIZE_M, MapParams, MotionParams,
    Params, ParamsError, PoseRefinement, PriorSigmaSource, RefinementBlend, RefinementStart,
    ResidualPolicy, SensorParams, SetRate, UnobservedCells, WINDOW_BYTES_PER_CELL, WindowParams,
    check_window_size,
};
// The labels, the decision and the pignistic probability (SPEC §6).
pub use decision::{betp, betp_cells, decide, decide_grid};
pub use label::Label;
// The grids and the world-fixed window they share.
pub use grids::{GisGrid, N_SETS, OMEGA, PerceptionGrid, SensorGrid, class};
pub use window::{Entered, GlobalCell, Window, WindowError};
// The stages, for callers that drive them one by one.
pub use map_prior::{MAP_CONTEXTS, MapPrior, prior_beta, prior_focal_set};
/// nalgebra, whose isometry the poses are: its version, for callers that build or read them.
pub use nalgebra;
pub use pose::{IsometryMatrix3, PoseExt};
pub use sensor_model::{GroundPlane, SensorModel, SensorStats};
pub use step::{StepStats, rate_for_step, set_rate_per_second, step, step_and_decide};
pub use trace::MovingTrace;
