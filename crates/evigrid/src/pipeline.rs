//! The per-frame pipeline: window, map prior, sensor grid, fusion step, decision (SPEC §2-§6).
//!
//! A [`Pipeline`] owns everything one drive needs — the window, the three grids, the map
//! rasteriser, the sensor model's buffers, the decisions and the trace of moving objects — all
//! sized by the window, so memory does not depend on the drive's length. Feed it scans in time
//! order with [`Pipeline::process`].
//!
//! ```
//! use evigrid::pipeline::Pipeline;
//! use evigrid::sensor_model::{GroundModel, Isometry3};
//! use evigrid::{Decision, Params};
//!
//! let mut params = Params::default();
//! params.window.width_cells = 40;
//! params.window.height_cells = 40;
//! params.sensor.ground_model = GroundModel::None; // a planar scanner
//! let mut pipeline = Pipeline::new(params, None)?;
//! // A wall 6 m east of a scanner at the origin, seen twice.
//! let wall: Vec<[f32; 3]> = (-10..=10).map(|k| [6.0, k as f32 * 0.2, 0.0]).collect();
//! for time_s in [0.0, 0.1] {
//!     pipeline.process(&wall, &Isometry3::IDENTITY, time_s)?;
//! }
//! let window = pipeline.window();
//! let ahead = window.storage_index_of_point(3.0, 0.1).expect("in the window");
//! assert_eq!(pipeline.decisions()[ahead], Decision::F);
//! # Ok::<(), evigrid::pipeline::PipelineError>(())
//! ```

use std::time::Instant;

use geodata::ContextRaster;
use serde::Serialize;

use crate::decision::Decision;
use crate::grids::{GisGrid, PerceptionGrid, SensorGrid};
use crate::map_prior::MapPrior;
use crate::params::{Params, ParamsError};
use crate::sensor_model::{Isometry3, SensorModel, SensorStats};
use crate::step::{StepStats, step_and_decide};
use crate::trace::MovingTrace;
use crate::window::{Window, WindowError};

/// Why a frame (or the pipeline) was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// The parameters are out of range.
    #[error(transparent)]
    Params(#[from] ParamsError),
    /// The window geometry is invalid or the pose cannot be placed on the grid.
    #[error(transparent)]
    Window(#[from] WindowError),
    /// A frame's time is not finite or earlier than the previous frame's.
    #[error("frame time {time_s} s is not finite or is before the previous frame's {previous_s} s")]
    Time {
        /// The refused time, seconds.
        time_s: f64,
        /// The previous frame's time, seconds.
        previous_s: f64,
    },
    /// The pose has a NaN or infinite entry.
    #[error("sensor pose is not finite: {world_from_sensor:?}")]
    Pose {
        /// The refused pose.
        world_from_sensor: Isometry3,
    },
}

/// What happened in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrameStats {
    /// Seconds since the previous frame (0 for the first).
    pub dt_s: f64,
    /// Cells that entered the window and were reset.
    pub entered_cells: usize,
    /// The sensor model's counts.
    pub sensor: SensorStats,
    /// Cells updated by the step.
    pub step_cells: u64,
    /// Cells the sensor observed.
    pub observed_cells: u64,
    /// Cells in total conflict between sensor and map (SPEC §5 step 2).
    pub total_map_conflicts: u64,
    /// Wall time of the stages, milliseconds: window move with resets and map prior, sensor
    /// grid, fusion step with the decision, trace of moving cells.
    pub window_ms: f64,
    /// See `window_ms`.
    pub sensor_ms: f64,
    /// See `window_ms`.
    pub step_ms: f64,
    /// See `window_ms`.
    pub trace_ms: f64,
}

/// The whole perception loop for one drive.
#[derive(Debug)]
pub struct Pipeline {
    params: Params,
    window: Window,
    perception: PerceptionGrid,
    sensor: SensorGrid,
    gis: GisGrid,
    map_prior: MapPrior,
    sensor_model: SensorModel,
    decisions: Vec<Decision>,
    trace: MovingTrace,
    /// Time of the last frame; `None` before the first, when the window is not placed yet.
    last_time_s: Option<f64>,
}

impl Pipeline {
    /// A pipeline with these parameters and, optionally, a map. Every grid is vacuous; the window
    /// is placed on the first frame.
    ///
    /// # Errors
    ///
    /// [`PipelineError::Params`] if the parameters are out of range.
    pub fn new(params: Params, map: Option<ContextRaster>) -> Result<Self, PipelineError> {
        params.validate()?;
        let window = Window::new(
            params.window.width_cells,
            params.window.height_cells,
            params.grid.cell_size_m,
        )?;
        let (w, h) = (window.width(), window.height());
        Ok(Self {
            sensor_model: SensorModel::new(params.sensor.clone()),
            params,
            perception: PerceptionGrid::new(w, h),
            sensor: SensorGrid::new(w, h),
            gis: GisGrid::new(w, h),
            map_prior: MapPrior::new(map),
            decisions: vec![Decision::Unknown; w * h],
            trace: MovingTrace::new(w * h),
            window,
            last_time_s: None,
        })
    }

    /// Processes one scan: `points_in_sensor` in the sensor frame, taken at `time_s` (seconds,
    /// any origin, non-decreasing) from the pose `world_from_sensor` in the map's local frame.
    ///
    /// # Errors
    ///
    /// [`PipelineError::Time`] for a time that is not finite or goes back,
    /// [`PipelineError::Pose`] for a non-finite pose, [`PipelineError::Window`] for a position
    /// too far to index. The grids are unchanged on error.
    pub fn process(
        &mut self,
        points_in_sensor: &[[f32; 3]],
        world_from_sensor: &Isometry3,
        time_s: f64,
    ) -> Result<FrameStats, PipelineError> {
        let previous_s = self.last_time_s.unwrap_or(time_s);
        if !(time_s.is_finite() && time_s >= previous_s) {
            return Err(PipelineError::Time { time_s, previous_s });
        }
        if !world_from_sensor.is_finite() {
            return Err(PipelineError::Pose {
                world_from_sensor: *world_from_sensor,
            });
        }
        let [x_m, y_m, _] = world_from_sensor.translation;
        let ms = |start: Instant| start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();

        // Follow the vehicle: whole-cell shift of the window; cells that enter start vacuous and
        // get their map prior (all cells on the first frame).
        let entered = self.window.recentre(x_m, y_m)?;
        let entered_cells = if self.last_time_s.is_none() {
            self.perception.reset_all();
            self.map_prior.fill_window(&self.window, &mut self.gis);
            self.trace = MovingTrace::new(self.window.len());
            self.window.len()
        } else {
            for block in entered.blocks() {
                for span in self.window.storage_spans(block) {
                    self.perception.reset_range(span);
                }
            }
            self.map_prior
                .fill_entered(&self.window, &entered, &mut self.gis);
            self.trace.reset_entered(&self.window, &entered);
            entered.cell_count()
        };

        let window_ms = ms(start);

        // Sensor grid from the scan (SPEC §3).
        let start = Instant::now();
        let sensor = self.sensor_model.build(
            points_in_sensor,
            world_from_sensor,
            &self.window,
            &mut self.sensor,
        );

        // Refine, combine with the map prior, discount the past, fuse, accumulate, specialise
        // (SPEC §5), and decide every cell (SPEC §6) while its block is in cache.
        let sensor_ms = ms(start);
        let start = Instant::now();
        let dt_s = time_s - previous_s;
        let step_stats: StepStats = step_and_decide(
            &mut self.perception,
            &self.sensor,
            &self.gis,
            &self.params,
            dt_s,
            &mut self.decisions,
        );
        let step_ms = ms(start);

        // Add this frame's moving cells to the trace.
        let start = Instant::now();
        self.trace.record(&self.decisions);
        let trace_ms = ms(start);

        self.last_time_s = Some(time_s);
        Ok(FrameStats {
            dt_s,
            entered_cells,
            sensor,
            step_cells: step_stats.cells,
            observed_cells: step_stats.observed_cells,
            total_map_conflicts: step_stats.total_map_conflicts,
            window_ms,
            sensor_ms,
            step_ms,
            trace_ms,
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The window (world ↔ storage mapping of every grid below).
    pub fn window(&self) -> &Window {
        &self.window
    }

    /// The PerceptionGrid, in storage order.
    pub fn perception(&self) -> &PerceptionGrid {
        &self.perception
    }

    /// The last frame's SensorGrid, in storage order.
    pub fn sensor_grid(&self) -> &SensorGrid {
        &self.sensor
    }

    /// The GISGrid, in storage order.
    pub fn gis(&self) -> &GisGrid {
        &self.gis
    }

    /// The decision per cell after the last frame, in storage order.
    pub fn decisions(&self) -> &[Decision] {
        &self.decisions
    }

    /// Cells decided moving at any frame while they were in the window.
    pub fn trace(&self) -> &MovingTrace {
        &self.trace
    }

    /// True if a map was given.
    pub fn has_map(&self) -> bool {
        self.map_prior.has_map()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::sensor_model::GroundModel;

    fn params() -> Params {
        let mut p = Params::default();
        p.window.width_cells = 20;
        p.window.height_cells = 20;
        p.sensor.ground_model = GroundModel::None;
        p
    }

    #[test]
    fn refuses_time_going_back_and_bad_poses() {
        let mut pipeline = Pipeline::new(params(), None).unwrap();
        pipeline.process(&[], &Isometry3::IDENTITY, 1.0).unwrap();
        assert!(matches!(
            pipeline.process(&[], &Isometry3::IDENTITY, 0.5),
            Err(PipelineError::Time { .. })
        ));
        assert!(
            pipeline
                .process(&[], &Isometry3::IDENTITY, f64::NAN)
                .is_err()
        );
        let nan = Isometry3::from_xyz_rpy(f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0);
        assert!(matches!(
            pipeline.process(&[], &nan, 2.0),
            Err(PipelineError::Pose { .. })
        ));
        let far = Isometry3::from_xyz_rpy(1e300, 0.0, 0.0, 0.0, 0.0, 0.0);
        assert!(matches!(
            pipeline.process(&[], &far, 2.0),
            Err(PipelineError::Window(_))
        ));
        let mut bad = params();
        bad.sensor.mu_free = 1.5;
        assert!(matches!(
            Pipeline::new(bad, None),
            Err(PipelineError::Params(_))
        ));
    }

    #[test]
    fn first_frame_resets_everything_and_later_frames_only_what_entered() {
        let mut pipeline = Pipeline::new(params(), None).unwrap();
        let first = pipeline.process(&[], &Isometry3::IDENTITY, 0.0).unwrap();
        assert_eq!(first.entered_cells, 400);
        assert_eq!(first.dt_s, 0.0);
        let pose = Isometry3::from_xyz_rpy(1.2, 0.0, 0.0, 0.0, 0.0, 0.0);
        let second = pipeline.process(&[], &pose, 0.5).unwrap();
        // 1.2 m east at 0.5 m cells: two columns of 20 cells entered.
        assert_eq!(second.entered_cells, 40);
        assert_eq!(second.dt_s, 0.5);
    }
}
