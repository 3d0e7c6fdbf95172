//! What every method under evaluation is: a per-cell classifier fed by the shared front end.
//!
//! A method keeps its own state in the window's storage layout. After each
//! [`FrontEnd::process`] the runner calls [`GridMethod::process`] with the front end, from which
//! the method reads what it needs: the cells new in the window (to forget), the SensorGrid, the
//! map prior, the time step. Then [`GridMethod::decide`] writes one [`Label`] per storage cell.
//! evigrid's [`Fusion`] is one (with the map prior or a vacuous one); the two-class
//! [`baselines`](crate::baselines) are others.
//!
//! ```
//! use eval::{GridMethod, Label};
//! use eval::baselines::{LogOdds, LogOddsParams};
//! use evigrid::{FrontEnd, Fusion, Prior};
//! use evigrid::{GroundModel, IsometryMatrix3};
//!
//! let mut params = evigrid::Params::default();
//! (params.window.width_cells, params.window.height_cells) = (40, 40);
//! params.sensor.ground_model = GroundModel::None;
//! let mut front_end = FrontEnd::new(&params, None)?;
//! let mut methods: Vec<Box<dyn GridMethod>> = vec![
//!     Box::new(Fusion::new(params.clone(), Prior::Vacuous)?),
//!     Box::new(LogOdds::new(40 * 40, LogOddsParams::default())),
//! ];
//! let wall: Vec<[f32; 3]> = (-10..=10).map(|k| [6.0, k as f32 * 0.2, 0.0]).collect();
//! let mut labels = vec![Label::Unknown; 40 * 40];
//! front_end.process(&wall, &IsometryMatrix3::identity(), 0.0)?; // one sensor model run for both
//! let ahead = front_end.window().storage_index_of_point(3.0, 0.1).expect("in the window");
//! for method in &mut methods {
//!     method.process(&front_end)?;
//!     method.decide(&mut labels);
//!     assert_eq!(labels[ahead], Label::F, "{}", method.name());
//! }
//! # Ok::<(), eval::EvalError>(())
//! ```

use evigrid::{FrontEnd, Fusion, Method, Prior};

use crate::EvalError;
use crate::Label;

/// A dynamic-occupancy method fed frame by frame from a shared [`FrontEnd`].
pub trait GridMethod {
    /// Short name for reports.
    fn name(&self) -> &'static str;

    /// Follows the front end's last frame: forgets the cells new in its window, then fuses its
    /// SensorGrid (and its map prior, if the method uses one). Call it once after every
    /// [`FrontEnd::process`].
    ///
    /// # Errors
    /// [`EvalError::Pipeline`] when the method cannot follow this front end (a window of
    /// another size).
    fn process(&mut self, front_end: &FrontEnd) -> Result<(), EvalError>;

    /// Writes the decision of every storage cell into `out` (window storage order).
    fn decide(&self, out: &mut [Label]);
}

/// evigrid's method: `kurdej2013` (SPEC §5) with [`Prior::Map`], `no-map` with [`Prior::Vacuous`], `evigrid`
/// with the motion stage ([`Method::Evigrid`]).
impl GridMethod for Fusion {
    fn name(&self) -> &'static str {
        match (self.method(), self.prior()) {
            (Method::Evigrid, Prior::Map) => "evigrid",
            (Method::Evigrid, Prior::Vacuous) => "evigrid-no-map",
            (Method::Kurdej2013, Prior::Map) => "kurdej2013",
            (Method::Kurdej2013, Prior::Vacuous) => "no-map",
        }
    }

    fn process(&mut self, front_end: &FrontEnd) -> Result<(), EvalError> {
        self.update(front_end)?;
        Ok(())
    }

    fn decide(&self, out: &mut [Label]) {
        for (label, &decision) in out.iter_mut().zip(self.decisions()) {
            *label = decision;
        }
    }
}
