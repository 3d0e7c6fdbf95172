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
//! ```
//! use evigrid::{GisGrid, Params, PerceptionGrid, SensorGrid, decision::{Decision, decide}};
//! use geodata::MapContext;
//!
//! let params = Params::default();
//! let (mut pg, mut sg, mut gg) = (PerceptionGrid::new(1, 1), SensorGrid::new(1, 1), GisGrid::new(1, 1));
//! gg.context[0] = MapContext::Road;
//! // A road cell seen free, then occupied: the object appeared, so its mass goes to M.
//! sg.m_free_mut()[0] = 0.7;
//! for _ in 0..3 {
//!     evigrid::step::step(&mut pg, &sg, &gg, &params, 0.1);
//! }
//! sg.m_free_mut()[0] = 0.0;
//! sg.m_occupied_mut()[0] = 0.8;
//! evigrid::step::step(&mut pg, &sg, &gg, &params, 0.1);
//! let decided = decide(&pg.cell_masses(0), pg.seen()[0] != 0, params.decision.unknown_threshold);
//! assert_eq!(decided, Decision::M);
//! ```

pub mod decision;
pub mod grids;
pub mod map_prior;
pub mod motion;
pub mod params;
pub mod pipeline;
pub mod pose;
pub mod reference;
pub mod render;
pub mod sensor_model;
pub mod step;
pub mod trace;
pub mod window;

pub use decision::Decision;
pub use grids::{GisGrid, PerceptionGrid, SensorGrid};
pub use params::{Params, ParamsError};
pub use pipeline::Pipeline;
pub use step::{StepStats, step};
pub use window::Window;
