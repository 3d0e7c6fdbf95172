//! Baselines from the literature, for comparison with the map-aided evidential grid.
//!
//! Both are [`GridMethod`](crate::GridMethod)s: they consume the same SensorGrid as evigrid's
//! step (m(F), m(O) per cell, in the window's storage layout, from the shared front end) and
//! decide each cell as a [`Label`](crate::Label): F, M, O (occupied and static — a two-class
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
