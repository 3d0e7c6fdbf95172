//! eval: scores grid methods against the simulator's truth, side by side on the same drives.
//!
//! **What.** [`evaluate`] drives a [`sim::Drive`] and feeds every scan to one shared
//! [`FrontEnd`](evigrid::FrontEnd) (window, map prior, SensorGrid), then to each
//! [`Variant`]'s [`GridMethod`]: evigrid's method with and without the map prior, and two
//! [`baselines`] from the literature. Every method decides each cell in one label type
//! ([`Label`], shared with the truth); [`metrics`] accumulates confusion matrices, scores,
//! remanence and latency in constant memory; [`plots`] draws them; [`tune`] searches evigrid's
//! parameters on these scores.
//!
//! **Why.** The paper shows pictures; this gives numbers, with per-cell truth of moving,
//! stopped and infrastructure cells that no public lidar data set gives together with an
//! OpenStreetMap prior.
//!
//! **Key design decision.** The front end runs once per scan and every method reads the same
//! SensorGrid in the same window: methods differ only in what they do with it, so their scores
//! and timings compare like with like, and no method can drift to another window.
//!
//! ```
//! use eval::{EvalConfig, Variant, evaluate};
//! use sim::testing::{small_scenario, town};
//!
//! let mut scenario = small_scenario(3);
//! scenario.duration_s = 1.0;
//! let mut config = EvalConfig::default();
//! config.params.window.width_cells = 240;
//! config.params.window.height_cells = 240;
//! let report = evaluate(&town(), &scenario, &Variant::ALL, &[3], &config, &mut |_| {})?;
//! assert_eq!(report.frames_per_seed, 10);
//! assert!(report.variants.iter().all(|v| v.confusion.total() > 0));
//! # Ok::<(), eval::EvalError>(())
//! ```

#![deny(missing_docs)]

pub mod baselines;
pub mod method;
pub mod metrics;
pub mod plots;
pub mod report;
pub mod runner;
pub mod tune;
pub mod variant;

pub use method::GridMethod;
pub use plots::{confusion_heatmap, per_class_iou_chart};
pub use report::{EvalReport, SeedScores, VariantReport};
pub use runner::{
    EvalConfig, FusionFrame, Progress, Variant, evaluate, evaluate_observed, evaluate_until,
};
pub use sim::Label;

use sim::SimError;

/// Errors of the evaluation and of the tuner.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// The simulator refused the scenario or the map.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// evigrid refused the parameters or a frame.
    #[error(transparent)]
    Pipeline(#[from] evigrid::PipelineError),
    /// A variant name is not one of [`Variant::ALL`]'s (nor a deprecated name).
    #[error("unknown variant {name:?} (expected one of {expected})")]
    UnknownVariant {
        /// The name given.
        name: String,
        /// The names accepted, comma-separated.
        expected: String,
    },
    /// An evaluation was asked with no seed.
    #[error("no seed to evaluate")]
    NoSeeds,
    /// An evaluation was asked with no variant.
    #[error("no variant to evaluate")]
    NoVariants,
    /// A tuning option is out of range (an empty search space, a box outside [0, 1], a step
    /// that is not positive).
    #[error("tuning: {field} = {value} is out of range")]
    InvalidTuneOption {
        /// The offending option.
        field: &'static str,
        /// Its value.
        value: f64,
    },
}
