//! The per-frame pipeline: a front end (window, map prior, sensor grid: SPEC §2-§4) and the
//! paper's method behind it (fusion step, decision, trace of moving cells: SPEC §5-§6).
//!
//! - [`FrontEnd`] turns each scan into what any grid method consumes: it moves the world-fixed
//!   window with the vehicle, keeps the map prior (GISGrid) of the cells in it and builds the
//!   frame's SensorGrid, and says which cells are new in the window ([`NewCells`]).
//! - [`Fusion`] is Kurdej et al.'s method on that output: the PerceptionGrid, the fusion step,
//!   the decision per cell and the moving trace. It fuses the front end's map prior
//!   ([`Prior::Map`]) or a vacuous one ([`Prior::Vacuous`], the method without a map).
//! - [`Pipeline`] composes one of each for one drive; feed it scans in time order with
//!   [`Pipeline::process`].
//!
//! The split exists so that several methods can share one front end: the sensor model runs once
//! per scan however many methods are compared on it (the evaluation does exactly that). Every
//! structure is sized by the window, so memory does not depend on the drive's length.
//!
//! ```
//! use evigrid::Pipeline;
//! use evigrid::{GroundModel, IsometryMatrix3};
//! use evigrid::{Label, Params};
//!
//! let mut params = Params::default();
//! params.window.width_cells = 40;
//! params.window.height_cells = 40;
//! params.sensor.ground_model = GroundModel::None; // a planar scanner
//! let mut pipeline = Pipeline::new(params, None)?;
//! // A wall 6 m east of a scanner at the origin, seen twice.
//! let wall: Vec<[f32; 3]> = (-10..=10).map(|k| [6.0, k as f32 * 0.2, 0.0]).collect();
//! for time_s in [0.0, 0.1] {
//!     pipeline.process(&wall, &IsometryMatrix3::identity(), time_s)?;
//! }
//! let window = pipeline.window();
//! let ahead = window.storage_index_of_point(3.0, 0.1).expect("in the window");
//! assert_eq!(pipeline.decisions()[ahead], Label::F);
//! # Ok::<(), evigrid::PipelineError>(())
//! ```
//!
//! Two methods on one front end, with and without the map prior:
//!
//! ```
//! use evigrid::{FrontEnd, Fusion, Prior};
//! use evigrid::{GroundModel, IsometryMatrix3};
//! use evigrid::{Label, Params};
//!
//! let mut params = Params::default();
//! params.window.width_cells = 40;
//! params.window.height_cells = 40;
//! params.sensor.ground_model = GroundModel::None;
//! let mut front_end = FrontEnd::new(&params, None)?;
//! let mut with_map = Fusion::new(params.clone(), Prior::Map)?;
//! let mut without_map = Fusion::new(params, Prior::Vacuous)?;
//! let wall: Vec<[f32; 3]> = (-10..=10).map(|k| [6.0, k as f32 * 0.2, 0.0]).collect();
//! for time_s in [0.0, 0.1] {
//!     front_end.process(&wall, &IsometryMatrix3::identity(), time_s)?; // one sensor model run
//!     with_map.update(&front_end)?;
//!     without_map.update(&front_end)?;
//! }
//! // No map was given, so both priors are vacuous and the two agree.
//! assert_eq!(with_map.decisions(), without_map.decisions());
//! let ahead = front_end.window().storage_index_of_point(3.0, 0.1).expect("in the window");
//! assert_eq!(with_map.decisions()[ahead], Label::F);
//! # Ok::<(), evigrid::PipelineError>(())
//! ```

use std::ops::Range;
use std::time::Instant;

use geodata::ContextRaster;
use serde::Serialize;

use crate::grids::{GisGrid, PerceptionGrid, SensorGrid};
use crate::label::Label;
use crate::map_prior::MapPrior;
use crate::motion::{MotionStage, MotionStats};
use crate::params::{Params, ParamsError, PoseRefinement};
use crate::pose::{IsometryMatrix3, PoseExt};
use crate::sensor_model::{SensorModel, SensorStats};
use crate::step::{StepStats, step_and_decide};
use crate::trace::MovingTrace;
use crate::window::{Entered, Window, WindowError};

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
        world_from_sensor: IsometryMatrix3,
    },
    /// A back end was fed a front end whose window has another size than its grids.
    #[error(
        "front end window is {front_end:?} cells but the back end's grids are {back_end:?} (width, height)"
    )]
    WindowSize {
        /// The front end's window, (width, height) in cells.
        front_end: (usize, usize),
        /// The back end's grids, (width, height) in cells.
        back_end: (usize, usize),
    },
}

/// The cells that are new in the window after a frame: they start vacuous in every grid.
#[derive(Clone, Debug, PartialEq)]
pub enum NewCells {
    /// The first frame placed the window (or no frame yet): every cell is new.
    All,
    /// The cells the window's move uncovered (none if it did not move).
    Entered(Entered),
}

impl NewCells {
    /// Number of new cells in `window`.
    pub fn cell_count(&self, window: &Window) -> usize {
        match self {
            NewCells::All => window.len(),
            NewCells::Entered(entered) => entered.cell_count(),
        }
    }

    /// Storage ranges covering the new cells of `window`, each cell once.
    pub fn storage_spans<'a>(
        &'a self,
        window: &'a Window,
    ) -> impl Iterator<Item = Range<usize>> + 'a {
        let (all, entered) = match self {
            NewCells::All => (Some(0..window.len()), None),
            NewCells::Entered(entered) => (None, Some(entered)),
        };
        all.into_iter().chain(
            entered
                .into_iter()
                .flat_map(|e| e.blocks())
                .flat_map(|block| window.storage_spans(block)),
        )
    }
}

/// What the front end did in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrontEndStats {
    /// Seconds since the previous frame (0 for the first).
    pub dt_s: f64,
    /// Cells that entered the window (all of them on the first frame).
    pub entered_cells: usize,
    /// The sensor model's counts.
    pub sensor: SensorStats,
    /// Wall time of the stages, milliseconds: window move, map prior of the cells that
    /// entered, sensor grid.
    pub window_ms: f64,
    /// See `window_ms`.
    pub prior_ms: f64,
    /// See `window_ms`.
    pub sensor_ms: f64,
    /// What the pose refinement did (`[localisation]`), its time included.
    pub pose_refinement: RefinementStats,
}

/// How the front end's pose refinement treated a frame (`[localisation]`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RefinementOutcome {
    /// Refinement is off: the pose given was used.
    #[default]
    Off,
    /// The first frame with points: the pose given, which starts the local map.
    First,
    /// The registered pose (gated, pulled towards the pose given) was used.
    Refined,
    /// The pose given was used: the scan had no usable point or the map none near it.
    KeptNoData,
    /// The pose given was used: the registration failed or did not converge.
    KeptFailed,
    /// The pose given was used: too few of the scan's points matched the map.
    KeptLowOverlap,
    /// The pose given was used: the registration moved it beyond the correction bounds.
    KeptTooFar,
}

/// What the pose refinement did in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RefinementStats {
    /// How the pose was obtained.
    pub outcome: RefinementOutcome,
    /// Horizontal distance between the pose used and the pose given, metres.
    pub correction_m: f64,
    /// Heading difference between the pose used and the pose given, degrees (signed,
    /// counter-clockwise).
    pub correction_deg: f64,
    /// Scan points matched to the map in the registration's last iteration.
    pub correspondences: usize,
    /// Gauss–Newton iterations the registration ran (0 when it did not run): what its time
    /// grows with.
    pub iterations: usize,
    /// Wall time, milliseconds.
    pub ms: f64,
}

/// The frame of the pose refinement's local map that a scan was placed in
/// ([`FrontEnd::map_frame`]): `world_from_map` in the plane, and which map it belongs to.
///
/// Two scans placed in frames of one map put a static point apart by the change of the frame
/// between them (`docs/motion.md`, "The map frame's move"), plus their registrations' errors:
/// the pull towards the given poses moves the frame, not the map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapFrame {
    /// Which map (the refiner counts the maps it started): frames of two maps are unrelated.
    pub map: usize,
    /// `world_from_map`'s translation east, metres.
    pub east_m: f64,
    /// `world_from_map`'s translation north, metres.
    pub north_m: f64,
    /// `world_from_map`'s turn about the vertical, radians (counter-clockwise).
    pub heading_rad: f64,
}

impl MapFrame {
    /// The frame of `refiner`'s current map: its `world_from_map`, in the plane.
    fn of_current_map(refiner: &odometry::PoseRefiner) -> Self {
        let frame = refiner.world_from_map();
        let rotation = frame.rotation.to_rotation_matrix();
        Self {
            map: refiner.map_starts(),
            east_m: frame.translation.x,
            north_m: frame.translation.y,
            heading_rad: rotation[(1, 0)].atan2(rotation[(0, 0)]),
        }
    }

    /// Where the point `(x, y)` (world metres) placed in the frame `from` is placed in this
    /// frame: `self · from⁻¹ · (x, y)`.
    pub fn moved_from(&self, from: &MapFrame, x: f64, y: f64) -> (f64, f64) {
        let (sin_f, cos_f) = from.heading_rad.sin_cos();
        // In the map: from⁻¹ · p.
        let (px, py) = (x - from.east_m, y - from.north_m);
        let (mx, my) = (cos_f * px + sin_f * py, -sin_f * px + cos_f * py);
        let (sin_s, cos_s) = self.heading_rad.sin_cos();
        (
            cos_s * mx - sin_s * my + self.east_m,
            sin_s * mx + cos_s * my + self.north_m,
        )
    }
}

/// The per-frame front end (SPEC §2-§4): the window that follows the vehicle, the GISGrid of the
/// map prior kept in it, and each scan's SensorGrid.
///
/// Back ends ([`Fusion`], or any other grid method) read its state after every
/// [`FrontEnd::process`]: [`FrontEnd::window`], [`FrontEnd::new_cells`] (which cells to reset),
/// [`FrontEnd::sensor_grid`], [`FrontEnd::gis`] and [`FrontEnd::dt_s`].
#[derive(Debug)]
pub struct FrontEnd {
    window: Window,
    sensor_model: SensorModel,
    sensor: SensorGrid,
    /// The SensorGrid with returns placed by cell centre (`[motion] return_depth_cells` > 0),
    /// for [`Method::Evigrid`].
    placed: Option<SensorGrid>,
    gis: GisGrid,
    map_prior: MapPrior,
    new_cells: NewCells,
    dt_s: f64,
    /// Time of the last frame; `None` before the first, when the window is not placed yet.
    last_time_s: Option<f64>,
    /// The pose refinement (`[localisation] refinement = "scan_to_map"`).
    refiner: Option<odometry::PoseRefiner>,
    /// The pose the last SensorGrid was built with.
    world_from_sensor: IsometryMatrix3,
    /// How far the refinement moves the given poses ([`FrontEnd::pose_sigma`]).
    corrections: CorrectionSpread,
    /// The map frame the last scan was placed in ([`FrontEnd::map_frame`]).
    map_frame: Option<MapFrame>,
}

/// The running mean square of the refinement's corrections (`docs/motion.md`, "Gating by the
/// pose's own error"): over the first [`CorrectionSpread::MEMORY`] refined scans the plain
/// mean, then an exponential mean with that memory, so that it follows a localisation whose
/// quality changes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct CorrectionSpread {
    /// Mean of correction_m², m² (horizontal distance between the pose used and the one given).
    mean_sq_m: f64,
    /// Mean of the heading correction², rad².
    mean_sq_rad: f64,
    /// Refined scans counted, up to `MEMORY`.
    count: usize,
}

impl CorrectionSpread {
    /// Scans the exponential mean remembers.
    const MEMORY: usize = 50;

    fn observe(&mut self, correction_m: f64, correction_rad: f64) {
        if !(correction_m.is_finite() && correction_rad.is_finite()) {
            return;
        }
        self.count = (self.count + 1).min(Self::MEMORY);
        let w = 1.0 / self.count as f64;
        self.mean_sq_m += w * (correction_m * correction_m - self.mean_sq_m);
        self.mean_sq_rad += w * (correction_rad * correction_rad - self.mean_sq_rad);
    }

    /// (σ per axis, metres; σ of the heading, radians): a horizontal correction of mean square
    /// c² is two axes of variance c²/2 each.
    fn sigma(&self) -> (f64, f64) {
        ((0.5 * self.mean_sq_m).sqrt(), self.mean_sq_rad.sqrt())
    }
}

impl FrontEnd {
    /// A front end with the window and sensor model of `params` and, optionally, a map. The
    /// grids are vacuous; the window is placed on the first frame.
    ///
    /// # Errors
    ///
    /// [`PipelineError::Params`] if the parameters are out of range.
    pub fn new(params: &Params, map: Option<ContextRaster>) -> Result<Self, PipelineError> {
        params.validate()?;
        let window = Window::new(
            params.window.width_cells,
            params.window.height_cells,
            params.grid.cell_size_m,
        )?;
        let (w, h) = (window.width(), window.height());
        let refiner = match params.localisation.refinement {
            PoseRefinement::None => None,
            PoseRefinement::ScanToMap => Some(
                odometry::PoseRefiner::new(params.localisation.refine_params(&params.sensor))
                    // Validated above, so not reached; named should the two checks part.
                    .map_err(|e| {
                        PipelineError::Params(ParamsError::Parse {
                            message: format!("localisation: {e}"),
                        })
                    })?,
            ),
        };
        let mut sensor_model = SensorModel::new(params.sensor.clone());
        let return_depth_cells = params.motion.return_depth_cells;
        sensor_model.set_return_depth_m(return_depth_cells * params.grid.cell_size_m);
        sensor_model.set_placed_by_surface(
            params.motion.placed_by_surface,
            params.motion.surface_depth_cells * params.grid.cell_size_m,
            params.motion.surface_pose_sigmas,
            params.motion.surface_silhouette_faces,
            params.motion.surface_convex_corners,
        );
        Ok(Self {
            sensor_model,
            sensor: SensorGrid::new(w, h),
            placed: (return_depth_cells > 0.0).then(|| SensorGrid::new(w, h)),
            gis: GisGrid::new(w, h),
            map_prior: MapPrior::new(map),
            window,
            new_cells: NewCells::All,
            dt_s: 0.0,
            last_time_s: None,
            refiner,
            world_from_sensor: IsometryMatrix3::identity(),
            corrections: CorrectionSpread::default(),
            map_frame: None,
        })
    }

    /// Processes one scan: `points_in_sensor` in the sensor frame, taken at `time_s` (seconds,
    /// any origin, non-decreasing) from the pose `world_from_sensor` in the map's local frame.
    /// With pose refinement on, that pose is the prior of a registration against the previous
    /// scans and the SensorGrid is built with the refined pose ([`FrontEnd::world_from_sensor`]).
    ///
    /// # Errors
    ///
    /// [`PipelineError::Time`] for a time that is not finite or goes back,
    /// [`PipelineError::Pose`] for a non-finite pose, [`PipelineError::Window`] for a position
    /// too far to index. The front end is unchanged on error.
    pub fn process(
        &mut self,
        points_in_sensor: &[[f32; 3]],
        world_from_sensor: &IsometryMatrix3,
        time_s: f64,
    ) -> Result<FrontEndStats, PipelineError> {
        let previous_s = self.last_time_s.unwrap_or(time_s);
        if !(time_s.is_finite() && time_s >= previous_s) {
            return Err(PipelineError::Time { time_s, previous_s });
        }
        if !world_from_sensor.is_finite() {
            return Err(PipelineError::Pose {
                world_from_sensor: *world_from_sensor,
            });
        }
        let ms = |start: Instant| start.elapsed().as_secs_f64() * 1e3;

        // Pose refinement: registered now, added to the map once the frame is accepted.
        let start = Instant::now();
        let refinement = self.refiner.as_ref().map(|refiner| {
            refiner.refine(
                points_in_sensor,
                &with_quaternion(world_from_sensor),
                time_s,
            )
        });
        let (world_from_sensor, pose_refinement) = match &refinement {
            None => (*world_from_sensor, RefinementStats::default()),
            Some(refinement) => refined_pose(world_from_sensor, refinement, ms(start)),
        };
        let world_from_sensor = &world_from_sensor;
        let (x_m, y_m) = (
            world_from_sensor.translation.x,
            world_from_sensor.translation.y,
        );

        // Follow the vehicle: whole-cell shift of the window (SPEC §2).
        let start = Instant::now();
        let entered = self.window.recentre(x_m, y_m)?;
        self.new_cells = if self.last_time_s.is_none() {
            NewCells::All
        } else {
            NewCells::Entered(entered)
        };
        let window_ms = ms(start);

        // Map prior of the cells that entered (all of them on the first frame) (SPEC §4).
        let start = Instant::now();
        match &self.new_cells {
            NewCells::All => self.map_prior.fill_window(&self.window, &mut self.gis),
            NewCells::Entered(entered) => {
                self.map_prior
                    .fill_entered(&self.window, entered, &mut self.gis);
            }
        }
        let prior_ms = ms(start);

        // Sensor grid from the scan (SPEC §3).
        let start = Instant::now();
        let sensor = self.sensor_model.build(
            points_in_sensor,
            world_from_sensor,
            &self.window,
            &mut self.sensor,
        );
        // The same scan with returns placed by cell centre, for the `evigrid` method.
        if let Some(placed) = &mut self.placed {
            self.sensor_model
                .build_placed(&self.window, self.corrections.sigma(), placed);
        }
        let sensor_ms = ms(start);

        let mut pose_refinement = pose_refinement;
        if pose_refinement.outcome == RefinementOutcome::Refined {
            self.corrections.observe(
                pose_refinement.correction_m,
                pose_refinement.correction_deg.to_radians(),
            );
        }
        self.map_frame = None;
        if let (Some(refiner), Some(refinement)) = (&mut self.refiner, &refinement) {
            let start = Instant::now();
            let maps = refiner.map_starts();
            refiner.insert(refinement);
            pose_refinement.ms += ms(start);
            // The scan joined the map (registered, the first, or starting a new map): it was
            // placed at `world_from_map · map_from_sensor`.
            let joined = matches!(
                refinement.outcome,
                odometry::RefineOutcome::Refined | odometry::RefineOutcome::First
            ) || refiner.map_starts() != maps;
            if joined {
                self.map_frame = Some(MapFrame::of_current_map(refiner));
            }
        }
        self.world_from_sensor = *world_from_sensor;
        self.dt_s = time_s - previous_s;
        self.last_time_s = Some(time_s);
        Ok(FrontEndStats {
            dt_s: self.dt_s,
            entered_cells: self.new_cells.cell_count(&self.window),
            sensor,
            window_ms,
            prior_ms,
            sensor_ms,
            pose_refinement,
        })
    }

    /// The pose the last SensorGrid was built with: the one given, or its refinement
    /// (`[localisation]`). The identity before the first frame.
    pub fn world_from_sensor(&self) -> &IsometryMatrix3 {
        &self.world_from_sensor
    }

    /// The frame of the pose refinement's local map the last scan was placed in: `None`
    /// without refinement, and for a scan that did not join the map (its given pose was used:
    /// a refused registration, or no data).
    pub fn map_frame(&self) -> Option<MapFrame> {
        self.map_frame
    }

    /// An estimate of the error of the pose used, from the pose refinement: (σ per axis,
    /// metres; σ of the heading, radians), the root mean square of the corrections the
    /// refinement applied to the given poses over the last 50 refined scans or so. Both 0
    /// without refinement or before a scan was refined. It reads the given pose's error as
    /// the error left: on the simulated planar scanner the refinement takes away a third of
    /// the scan-to-scan error at most (`docs/motion.md`, "Pose refinement").
    pub fn pose_sigma(&self) -> (f64, f64) {
        self.corrections.sigma()
    }

    /// The window (world ↔ storage mapping of every grid).
    pub fn window(&self) -> &Window {
        &self.window
    }

    /// The cells new in the window since the previous frame.
    pub fn new_cells(&self) -> &NewCells {
        &self.new_cells
    }

    /// Storage ranges of the cells new in the window since the previous frame.
    pub fn new_cell_spans(&self) -> impl Iterator<Item = Range<usize>> + '_ {
        self.new_cells.storage_spans(&self.window)
    }

    /// The last frame's SensorGrid, in storage order.
    pub fn sensor_grid(&self) -> &SensorGrid {
        &self.sensor
    }

    /// The SensorGrid [`Method::Evigrid`] fuses: each return's occupied evidence in the cell of
    /// the return moved `[motion] return_depth_cells` further along its ray, the rays' free
    /// space extended by as much (a cell is occupied when its centre lies behind the surface,
    /// seen from the sensor); [`FrontEnd::sensor_grid`] when that parameter is 0.
    pub fn placed_sensor_grid(&self) -> &SensorGrid {
        self.placed.as_ref().unwrap_or(&self.sensor)
    }

    /// The last scan's visible obstacle returns: with the surface placement (`[motion]
    /// placed_by_surface`), the nearest return of each 0.1° sector; else every return the
    /// stray filter kept. Each with the storage index of its cell and its position, world
    /// metres (x east, y north).
    pub fn obstacle_returns(&self) -> impl Iterator<Item = (usize, [f64; 2])> + '_ {
        let [x, y, _]: [f64; 3] = self.world_from_sensor.translation.vector.into();
        self.sensor_model.visible_returns().filter_map(move |q| {
            let p = [x + q[0], y + q[1]];
            Some((self.window.storage_index_of_point(p[0], p[1])?, p))
        })
    }

    /// The GISGrid (vacuous without a map), in storage order.
    pub fn gis(&self) -> &GisGrid {
        &self.gis
    }

    /// Seconds between the last two frames (0 after the first).
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Time of the last frame, seconds; `None` before the first.
    pub fn time_s(&self) -> Option<f64> {
        self.last_time_s
    }

    /// True if a map was given.
    pub fn has_map(&self) -> bool {
        self.map_prior.has_map()
    }
}

/// The pose with a quaternion rotation, as the odometry crate takes it.
fn with_quaternion(pose: &IsometryMatrix3) -> nalgebra::Isometry3<f64> {
    let rotation = nalgebra::UnitQuaternion::from_rotation_matrix(&pose.rotation);
    nalgebra::Isometry3::from_parts(pose.translation, rotation)
}

/// The pose to build the SensorGrid with after a refinement of `given`, and its stats. A kept
/// prior is `given` itself, bit for bit, not its round trip through nalgebra.
fn refined_pose(
    given: &IsometryMatrix3,
    refinement: &odometry::Refinement,
    ms: f64,
) -> (IsometryMatrix3, RefinementStats) {
    use odometry::{KeptReason, RefineOutcome};
    let outcome = match refinement.outcome {
        RefineOutcome::First => RefinementOutcome::First,
        RefineOutcome::Refined => RefinementOutcome::Refined,
        RefineOutcome::KeptPrior(KeptReason::NoData) => RefinementOutcome::KeptNoData,
        RefineOutcome::KeptPrior(KeptReason::LowOverlap) => RefinementOutcome::KeptLowOverlap,
        RefineOutcome::KeptPrior(KeptReason::TooFar) => RefinementOutcome::KeptTooFar,
        RefineOutcome::KeptPrior(_) => RefinementOutcome::KeptFailed,
        _ => RefinementOutcome::KeptFailed,
    };
    let mut stats = RefinementStats {
        outcome,
        correspondences: refinement.correspondences,
        iterations: refinement.iterations,
        ms,
        ..RefinementStats::default()
    };
    if outcome != RefinementOutcome::Refined {
        return (*given, stats);
    }
    let pose = refinement.world_from_sensor;
    let used = IsometryMatrix3::from_parts(pose.translation, pose.rotation.to_rotation_matrix());
    let heading = |r: &nalgebra::Rotation3<f64>| r[(1, 0)].atan2(r[(0, 0)]);
    let mut turn = heading(&used.rotation) - heading(&given.rotation);
    turn = (turn + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    stats.correction_m =
        (used.translation.x - given.translation.x).hypot(used.translation.y - given.translation.y);
    stats.correction_deg = turn.to_degrees();
    (used, stats)
}

/// Which map prior a [`Fusion`] combines with the sensor (SPEC §5 step 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Prior {
    /// The front end's GISGrid (vacuous where it has no map).
    Map,
    /// A vacuous GISGrid everywhere: the method without a map, whatever the front end holds.
    Vacuous,
}

/// Which method a [`Fusion`] runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum Method {
    /// Kurdej et al. 2013 exactly as SPEC §5-§6 specify (evaluation variant `full`).
    #[default]
    Kurdej2013,
    /// The SPEC §5 step followed by the motion stage ([`crate::motion`]): registration-based
    /// motion evidence combined into the PerceptionGrid, with the boundary-aware map prior
    /// (`docs/motion.md`; evaluation variant `evigrid`).
    Evigrid,
}

/// What the fusion back end did in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FusionStats {
    /// The step's counts.
    pub step: StepStats,
    /// The motion stage's counts ([`Method::Evigrid`] only).
    pub motion: Option<MotionStats>,
    /// Wall time of the stages, milliseconds: resetting the cells new in the window, fusion
    /// step with the decision, trace of moving cells.
    pub reset_ms: f64,
    /// See `reset_ms`.
    pub step_ms: f64,
    /// See `reset_ms`.
    pub trace_ms: f64,
}

/// The paper's method as a back end of a [`FrontEnd`] (SPEC §5-§6): the PerceptionGrid, the
/// fusion step, the decision of every cell and the trace of moving cells.
#[derive(Debug)]
pub struct Fusion {
    params: Params,
    prior: Prior,
    perception: PerceptionGrid,
    decisions: Vec<Label>,
    trace: MovingTrace,
    /// The prior of [`Prior::Vacuous`]: a GISGrid nothing ever writes.
    vacuous_gis: Option<GisGrid>,
    /// The motion stage of [`Method::Evigrid`].
    motion: Option<Box<MotionStage>>,
}

impl Fusion {
    /// A vacuous PerceptionGrid of the window size of `params`, fusing `prior`.
    ///
    /// # Errors
    ///
    /// [`PipelineError::Params`] if the parameters are out of range.
    pub fn new(params: Params, prior: Prior) -> Result<Self, PipelineError> {
        Self::with_method(params, prior, Method::Kurdej2013)
    }

    /// A vacuous PerceptionGrid of the window size of `params`, fusing `prior` by `method`.
    ///
    /// # Errors
    ///
    /// [`PipelineError::Params`] if the parameters are out of range.
    pub fn with_method(
        params: Params,
        prior: Prior,
        method: Method,
    ) -> Result<Self, PipelineError> {
        params.validate()?;
        let (w, h) = (params.window.width_cells, params.window.height_cells);
        Ok(Self {
            motion: (method == Method::Evigrid).then(|| Box::new(MotionStage::new(&params, w, h))),
            params,
            prior,
            perception: PerceptionGrid::new(w, h),
            decisions: vec![Label::Unknown; w * h],
            trace: MovingTrace::new(w * h),
            vacuous_gis: (prior == Prior::Vacuous).then(|| GisGrid::new(w, h)),
        })
    }

    /// Fuses the front end's last frame: cells new in the window start vacuous, then the step
    /// and the decision of every cell, then the trace. Call it once after every
    /// [`FrontEnd::process`].
    ///
    /// # Errors
    ///
    /// [`PipelineError::WindowSize`] if the front end's window is not the size of this back
    /// end's grids; nothing is changed then.
    pub fn update(&mut self, front_end: &FrontEnd) -> Result<FusionStats, PipelineError> {
        let window = front_end.window();
        let back_end = (self.perception.width(), self.perception.height());
        if (window.width(), window.height()) != back_end {
            return Err(PipelineError::WindowSize {
                front_end: (window.width(), window.height()),
                back_end,
            });
        }
        let ms = |start: Instant| start.elapsed().as_secs_f64() * 1e3;

        // Cells that entered the window start vacuous, and off the trace.
        let start = Instant::now();
        self.reset_new_cells(front_end);
        let reset_ms = ms(start);

        // Refine, combine with the map prior, discount the past, fuse, accumulate, specialise
        // (SPEC §5), and decide every cell (SPEC §6) while its block is in cache.
        let start = Instant::now();
        let gis = match (&self.vacuous_gis, &self.motion) {
            (Some(vacuous), _) => vacuous,
            (None, Some(motion)) => motion.prior(),
            (None, None) => front_end.gis(),
        };
        // The paper's method fuses the SPEC §3 grid; `evigrid` the grid placed by cell centre.
        let sensor_grid = match self.motion {
            Some(_) => front_end.placed_sensor_grid(),
            None => front_end.sensor_grid(),
        };
        let step = step_and_decide(
            &mut self.perception,
            sensor_grid,
            gis,
            &self.params,
            front_end.dt_s(),
            &mut self.decisions,
        );
        let step_ms = ms(start);

        // Motion evidence combined into the grid, its cells decided again.
        let motion = self.motion.as_mut().and_then(|motion| {
            let position = front_end.world_from_sensor().translation;
            let (sigma_m, sigma_rad) = front_end.pose_sigma();
            motion.set_pose(position.x, position.y, sigma_m, sigma_rad);
            // With the surface placement, registered on the returns' own cells (the SPEC §3
            // grid), the placed cells taking the evidence.
            let returns = if self.params.motion.placed_by_surface
                && self.params.motion.surface_register_on_returns
            {
                front_end.sensor_grid()
            } else {
                sensor_grid
            };
            if self.params.motion.object_layer {
                motion.set_returns(front_end.obstacle_returns());
            }
            Some(motion.update_registering(
                window,
                sensor_grid,
                returns,
                front_end.time_s()?,
                front_end.dt_s(),
                &mut self.perception,
                &mut self.decisions,
            ))
        });

        // Add this frame's moving cells to the trace.
        let start = Instant::now();
        self.trace.record(&self.decisions);
        let trace_ms = ms(start);

        Ok(FusionStats {
            step,
            motion,
            reset_ms,
            step_ms,
            trace_ms,
        })
    }

    /// Starts the cells new in the front end's window vacuous and off the trace (every cell
    /// when the window jumped), in the motion stage too, whose boundary-aware map prior is
    /// refreshed where the window moved.
    fn reset_new_cells(&mut self, front_end: &FrontEnd) {
        let window = front_end.window();
        match front_end.new_cells() {
            NewCells::All => {
                self.perception.reset_all();
                self.trace = MovingTrace::new(window.len());
                if let Some(motion) = &mut self.motion {
                    motion.reset_all();
                }
            }
            NewCells::Entered(_) => {
                for span in front_end.new_cell_spans() {
                    self.perception.reset_range(span.clone());
                    if let Some(motion) = &mut self.motion {
                        motion.reset_range(span.clone());
                    }
                    self.trace.reset_range(span);
                }
            }
        }
        // The variant's boundary-aware map prior, where the window moved.
        if let (Some(motion), Prior::Map) = (&mut self.motion, self.prior) {
            let entered = match front_end.new_cells() {
                NewCells::All => None,
                NewCells::Entered(entered) => Some(entered),
            };
            motion.refresh_prior(front_end.gis(), window, entered);
        }
    }

    /// The parameters in use.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The prior it fuses.
    pub fn prior(&self) -> Prior {
        self.prior
    }

    /// The method it runs.
    pub fn method(&self) -> Method {
        if self.motion.is_some() {
            Method::Evigrid
        } else {
            Method::Kurdej2013
        }
    }

    /// The motion stage ([`Method::Evigrid`] only): the velocity planes, the boundary-aware
    /// map prior.
    pub fn motion(&self) -> Option<&MotionStage> {
        self.motion.as_deref()
    }

    /// The PerceptionGrid, in storage order.
    pub fn perception(&self) -> &PerceptionGrid {
        &self.perception
    }

    /// The decision per cell after the last frame, in storage order.
    pub fn decisions(&self) -> &[Label] {
        &self.decisions
    }

    /// Cells decided moving at any frame while they were in the window.
    pub fn trace(&self) -> &MovingTrace {
        &self.trace
    }
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
    /// Wall time of the motion stage, milliseconds ([`Method::Evigrid`]; 0 otherwise).
    pub motion_ms: f64,
    /// What the pose refinement did (`[localisation]`), its time included.
    pub pose_refinement: RefinementStats,
}

/// The whole perception loop for one drive: a [`FrontEnd`] and the [`Fusion`] of its map prior.
#[derive(Debug)]
pub struct Pipeline {
    front_end: FrontEnd,
    fusion: Fusion,
}

impl Pipeline {
    /// A pipeline with these parameters and, optionally, a map. Every grid is vacuous; the window
    /// is placed on the first frame.
    ///
    /// # Errors
    ///
    /// [`PipelineError::Params`] if the parameters are out of range.
    pub fn new(params: Params, map: Option<ContextRaster>) -> Result<Self, PipelineError> {
        Self::with_method(params, map, Method::Kurdej2013)
    }

    /// A pipeline running `method` ([`Pipeline::new`] runs [`Method::Kurdej2013`]).
    ///
    /// # Errors
    ///
    /// [`PipelineError::Params`] if the parameters are out of range.
    pub fn with_method(
        params: Params,
        map: Option<ContextRaster>,
        method: Method,
    ) -> Result<Self, PipelineError> {
        // The paper's method needs no grid placed by cell centre.
        let mut front_end_params = params.clone();
        if method == Method::Kurdej2013 {
            front_end_params.motion.return_depth_cells = 0.0;
        }
        Ok(Self {
            front_end: FrontEnd::new(&front_end_params, map)?,
            fusion: Fusion::with_method(params, Prior::Map, method)?,
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
        world_from_sensor: &IsometryMatrix3,
        time_s: f64,
    ) -> Result<FrameStats, PipelineError> {
        // Window, map prior and sensor grid (SPEC §2-§4).
        let front = self
            .front_end
            .process(points_in_sensor, world_from_sensor, time_s)?;
        // Fusion step, decision and trace (SPEC §5-§6).
        let back = self.fusion.update(&self.front_end)?;
        Ok(FrameStats {
            dt_s: front.dt_s,
            entered_cells: front.entered_cells,
            sensor: front.sensor,
            step_cells: back.step.cells,
            observed_cells: back.step.observed_cells,
            total_map_conflicts: back.step.total_map_conflicts,
            window_ms: front.window_ms + front.prior_ms + back.reset_ms,
            sensor_ms: front.sensor_ms,
            step_ms: back.step_ms,
            trace_ms: back.trace_ms,
            motion_ms: back.motion.map_or(0.0, |m| m.ms),
            pose_refinement: front.pose_refinement,
        })
    }

    /// The front end: window, SensorGrid, GISGrid.
    pub fn front_end(&self) -> &FrontEnd {
        &self.front_end
    }

    /// The back end: PerceptionGrid, decisions, trace.
    pub fn fusion(&self) -> &Fusion {
        &self.fusion
    }

    /// The parameters in use.
    pub fn params(&self) -> &Params {
        self.fusion.params()
    }

    /// The window (world ↔ storage mapping of every grid below).
    pub fn window(&self) -> &Window {
        self.front_end.window()
    }

    /// The PerceptionGrid, in storage order.
    pub fn perception(&self) -> &PerceptionGrid {
        self.fusion.perception()
    }

    /// The last frame's SensorGrid, in storage order.
    pub fn sensor_grid(&self) -> &SensorGrid {
        self.front_end.sensor_grid()
    }

    /// The GISGrid, in storage order.
    pub fn gis(&self) -> &GisGrid {
        self.front_end.gis()
    }

    /// The decision per cell after the last frame, in storage order.
    pub fn decisions(&self) -> &[Label] {
        self.fusion.decisions()
    }

    /// Cells decided moving at any frame while they were in the window.
    pub fn trace(&self) -> &MovingTrace {
        self.fusion.trace()
    }

    /// True if a map was given.
    pub fn has_map(&self) -> bool {
        self.front_end.has_map()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::params::{GroundModel, PriorSigmaSource};

    #[test]
    fn the_pose_sigma_is_the_root_mean_square_of_the_corrections() {
        let mut spread = CorrectionSpread::default();
        assert_eq!(spread.sigma(), (0.0, 0.0));
        // Corrections of 0.2 m and 0 m: mean square 0.02 m², two axes of 0.01 m² each, σ 0.1 m.
        // Headings 0.01 and 0.03 rad: mean square 0.0005 rad², σ 0.022 36 rad.
        spread.observe(0.2, 0.01);
        spread.observe(0.0, 0.03);
        // Not finite: not counted.
        spread.observe(f64::NAN, 0.0);
        let (sigma_m, sigma_rad) = spread.sigma();
        assert!((sigma_m - 0.1).abs() < 1e-12, "{sigma_m}");
        assert!((sigma_rad - 0.0005f64.sqrt()).abs() < 1e-12, "{sigma_rad}");
        // After 50 scans the mean forgets: 50 corrections of 0.2 m, then one of 0, weighs the
        // last by 1/50: mean square 0.04 · 49/50 = 0.0392 m², σ = √0.0196 = 0.14 m.
        let mut spread = CorrectionSpread::default();
        for _ in 0..50 {
            spread.observe(0.2, 0.0);
        }
        spread.observe(0.0, 0.0);
        assert!(
            (spread.sigma().0 - 0.14).abs() < 1e-12,
            "{:?}",
            spread.sigma()
        );
    }

    fn params() -> Params {
        let mut p = Params::default();
        p.window.width_cells = 20;
        p.window.height_cells = 20;
        p.sensor.ground_model = GroundModel::None;
        p
    }

    /// A planar scan (z = 0) from `(x, y, heading)` of a street: façades at y = 8 and y = -9
    /// and poles every 4 m on both pavements, one ray every 0.25° all around.
    fn street_scan(pose: (f64, f64, f64)) -> Vec<[f32; 3]> {
        let mut boxes = vec![(-30.0, 8.0, 60.0, 8.2), (-30.0, -9.2, 60.0, -9.0)];
        for k in -7..15 {
            let x = f64::from(k) * 4.0;
            boxes.push((x, 6.0, x + 0.3, 6.3));
            boxes.push((x + 2.0, -7.3, x + 2.3, -7.0));
        }
        (0..1440)
            .filter_map(|k| {
                let bearing = f64::from(k) * 0.25_f64.to_radians();
                let (sin, cos) = (pose.2 + bearing).sin_cos();
                // Slab test of the ray against each box; the nearest entry.
                let range = boxes
                    .iter()
                    .filter_map(|&(x0, y0, x1, y1)| {
                        let slab = |o: f64, d: f64, lo: f64, hi: f64| {
                            if d.abs() < 1e-12 {
                                if (lo..=hi).contains(&o) {
                                    (f64::NEG_INFINITY, f64::INFINITY)
                                } else {
                                    (f64::INFINITY, f64::NEG_INFINITY)
                                }
                            } else {
                                let (a, b) = ((lo - o) / d, (hi - o) / d);
                                (a.min(b), a.max(b))
                            }
                        };
                        let (ax, bx) = slab(pose.0, cos, x0, x1);
                        let (ay, by) = slab(pose.1, sin, y0, y1);
                        let (near, far) = (ax.max(ay), bx.min(by));
                        (near <= far && near > 0.0).then_some(near)
                    })
                    .fold(f64::INFINITY, f64::min);
                let (bs, bc) = bearing.sin_cos();
                (range < 60.0).then_some([(range * bc) as f32, (range * bs) as f32, 0.0])
            })
            .collect()
    }

    #[test]
    fn a_map_frame_carries_a_point_by_its_change() {
        // The point (3, 0) placed in the frame (1, 0, 0°) lies at (2, 0) in the map; in the
        // frame (1, 0, 90°) that map point is placed at (1 − 0, 0 + 2) = (1, 2).
        let then = MapFrame {
            map: 1,
            east_m: 1.0,
            north_m: 0.0,
            heading_rad: 0.0,
        };
        let now = MapFrame {
            heading_rad: std::f64::consts::FRAC_PI_2,
            ..then
        };
        let (x, y) = now.moved_from(&then, 3.0, 0.0);
        assert!(
            (x - 1.0).abs() < 1e-12 && (y - 2.0).abs() < 1e-12,
            "{x} {y}"
        );
        // An unchanged frame leaves every point where it was.
        let (x, y) = then.moved_from(&then, -4.5, 7.25);
        assert!(
            (x + 4.5).abs() < 1e-12 && (y - 7.25).abs() < 1e-12,
            "{x} {y}"
        );
    }

    #[test]
    fn the_map_frame_is_known_only_for_scans_that_joined_the_map() -> Result<(), PipelineError> {
        let mut none = params();
        none.localisation.refinement = PoseRefinement::None;
        let mut off = FrontEnd::new(&none, None)?;
        off.process(
            &street_scan((0.0, 0.0, 0.0)),
            &IsometryMatrix3::identity(),
            0.0,
        )?;
        assert_eq!(off.map_frame(), None);
        let mut on = params();
        on.localisation.refinement = PoseRefinement::ScanToMap;
        let mut refined = FrontEnd::new(&on, None)?;
        // The first scan starts the map in the world's frame.
        refined.process(
            &street_scan((0.0, 0.0, 0.0)),
            &IsometryMatrix3::identity(),
            0.0,
        )?;
        let first = refined.map_frame();
        assert_eq!(
            first,
            Some(MapFrame {
                map: 1,
                east_m: 0.0,
                north_m: 0.0,
                heading_rad: 0.0
            })
        );
        // The next, 0.8 m on and given 0.1 m off across the street: registered, and the pull
        // towards the given pose moves the frame by less than that.
        let prior = IsometryMatrix3::from_xyz_rpy(0.8, 0.1, 0.0, 0.0, 0.0, 0.0);
        let stats = refined.process(&street_scan((0.8, 0.0, 0.0)), &prior, 0.1)?;
        assert_eq!(stats.pose_refinement.outcome, RefinementOutcome::Refined);
        let frame = refined.map_frame().unwrap_or(MapFrame {
            map: 0,
            east_m: f64::NAN,
            north_m: f64::NAN,
            heading_rad: f64::NAN,
        });
        assert_eq!(frame.map, 1);
        assert!(
            frame.north_m.abs() < 0.1 && frame.east_m.abs() < 0.1,
            "{frame:?}"
        );
        Ok(())
    }

    #[test]
    fn refinement_brings_noisy_poses_back_towards_the_truth() -> Result<(), PipelineError> {
        let mut on = params();
        on.localisation.refinement = PoseRefinement::ScanToMap;
        let mut refined = FrontEnd::new(&on, None)?;
        let mut off = params();
        off.localisation.refinement = PoseRefinement::None;
        let mut given = FrontEnd::new(&off, None)?;
        // Driving east at 0.8 m a scan; the reported pose off by a fixed pattern of errors of
        // the size of a good GNSS/INS's (0.1 m, 0.2°).
        let errors: [(f64, f64, f64); 4] = [
            (0.12, -0.08, 0.2),
            (-0.1, 0.1, -0.25),
            (0.05, 0.12, 0.15),
            (-0.12, -0.05, -0.2),
        ];
        // Errors between consecutive scans, what makes a static object jump a cell: given and
        // used, position (m) and heading (rad).
        let (mut before_sq, mut after_sq) = (0.0, 0.0);
        let mut last: Option<((f64, f64, f64), [f64; 3])> = None;
        // The used pose's mean error over the last 12 scans (three cycles of the pattern).
        let mut late_sum = [0.0; 3];
        for k in 0..24_u32 {
            let x = f64::from(k) * 0.8;
            let (ex, ey, eh) = errors[k as usize % errors.len()];
            let prior = IsometryMatrix3::from_xyz_rpy(x + ex, ey, 0.0, 0.0, 0.0, eh.to_radians());
            let scan = street_scan((x, 0.0, 0.0));
            let stats = refined.process(&scan, &prior, f64::from(k) * 0.1)?;
            given.process(&scan, &prior, f64::from(k) * 0.1)?;
            assert_eq!(given.world_from_sensor(), &prior);
            let pose = *refined.world_from_sensor();
            let heading = pose.rotation[(1, 0)].atan2(pose.rotation[(0, 0)]);
            let error = [pose.translation.x - x, pose.translation.y, heading];
            if k == 0 {
                assert_eq!(stats.pose_refinement.outcome, RefinementOutcome::First);
                assert_eq!(stats.pose_refinement.iterations, 0);
            } else {
                assert_eq!(
                    stats.pose_refinement.outcome,
                    RefinementOutcome::Refined,
                    "{k}"
                );
                // What the registration's time grows with, reported and bounded.
                let iterations = stats.pose_refinement.iterations;
                assert!((1..=100).contains(&iterations), "{k}: {iterations}");
                assert!(pose.translation.z.abs() < 1e-9 && pose.rotation[(2, 2)] > 1.0 - 1e-12);
            }
            if let Some((given_error, used_error)) = last {
                let (gx, gy, gh) = given_error;
                before_sq +=
                    (ex - gx).powi(2) + (ey - gy).powi(2) + (20.0 * (eh - gh).to_radians()).powi(2);
                after_sq += (error[0] - used_error[0]).powi(2)
                    + (error[1] - used_error[1]).powi(2)
                    + (20.0 * (error[2] - used_error[2])).powi(2);
            }
            last = Some(((ex, ey, eh), error));
            if k >= 12 {
                for (sum, e) in late_sum.iter_mut().zip(error) {
                    *sum += e / 12.0;
                }
            }
        }
        // Heading weighs as the displacement it causes 20 m away. The pull towards the priors
        // moves each pose by a tenth of its prior's error, a jitter the registration alone
        // would not have; it is what removes the first scan's error (below).
        let (before, after) = ((before_sq / 23.0).sqrt(), (after_sq / 23.0).sqrt());
        assert!(after < 0.35 * before, "RMS {before} m -> {after} m");
        // No lasting bias: the map was started at the first scan's error (0.12 m, -0.08 m,
        // 0.2°), the poses used end near the priors' mean error (-0.0125 m, 0.0225 m, -0.025°).
        let [bx, by, bh] = late_sum;
        assert!(
            (bx + 0.0125).abs() < 0.04 && (by - 0.0225).abs() < 0.04,
            "{late_sum:?}"
        );
        assert!((bh.to_degrees() + 0.025).abs() < 0.08, "{late_sum:?}");
        Ok(())
    }

    /// The largest distance between the pose used and the exact pose given, over scans 12 to
    /// 23 of a drive east at 0.8 m a scan (metres, degrees), with `prior_sigma`.
    fn exact_drive_error(prior_sigma: PriorSigmaSource) -> Result<(f64, f64), PipelineError> {
        let mut on = params();
        on.localisation.refinement = PoseRefinement::ScanToMap;
        on.localisation.prior_sigma = prior_sigma;
        let mut refined = FrontEnd::new(&on, None)?;
        let (mut worst_m, mut worst_deg) = (0.0_f64, 0.0_f64);
        for k in 0..24_u32 {
            let x = f64::from(k) * 0.8;
            let exact = IsometryMatrix3::from_xyz_rpy(x, 0.0, 0.0, 0.0, 0.0, 0.0);
            refined.process(&street_scan((x, 0.0, 0.0)), &exact, f64::from(k) * 0.1)?;
            let pose = refined.world_from_sensor();
            if k >= 12 {
                let heading = pose.rotation[(1, 0)].atan2(pose.rotation[(0, 0)]);
                worst_m = worst_m.max((pose.translation.x - x).hypot(pose.translation.y));
                worst_deg = worst_deg.max(heading.to_degrees().abs());
            }
        }
        Ok((worst_m, worst_deg))
    }

    #[test]
    fn exact_poses_are_kept_once_their_jitter_is_seen() -> Result<(), PipelineError> {
        // Exact poses at a constant speed: every second difference is 0, so from the 12th
        // scan on (10 second differences) the given pose's σ is 1 mm and 0.001°, and the
        // pose used is the given one to within a millimetre.
        let (estimated_m, estimated_deg) = exact_drive_error(PriorSigmaSource::Estimated)?;
        assert!(estimated_m < 1e-3, "{estimated_m} m");
        assert!(estimated_deg < 1e-3, "{estimated_deg}°");
        // With the configured 0.2 m and 0.5° the registration's scatter is used instead.
        let (fixed_m, _) = exact_drive_error(PriorSigmaSource::Fixed)?;
        assert!(
            fixed_m > 2.0 * estimated_m,
            "{fixed_m} m against {estimated_m} m"
        );
        Ok(())
    }

    #[test]
    fn refinement_off_uses_the_pose_given_and_reports_off() -> Result<(), PipelineError> {
        let mut off = params();
        off.localisation.refinement = PoseRefinement::None;
        let mut front_end = FrontEnd::new(&off, None)?;
        let pose = IsometryMatrix3::from_xyz_rpy(1.0, 2.0, 0.0, 0.0, 0.0, 0.3);
        let stats = front_end.process(&street_scan((0.0, 0.0, 0.0)), &pose, 0.0)?;
        assert_eq!(front_end.world_from_sensor(), &pose);
        assert_eq!(stats.pose_refinement, RefinementStats::default());
        Ok(())
    }

    #[test]
    fn the_memory_budget_counts_every_per_cell_allocation() -> Result<(), PipelineError> {
        let mut params = params();
        (params.window.width_cells, params.window.height_cells) = (128, 96);
        let cells = 128 * 96;
        // The `evigrid` method: the paper's grids and the motion stage's.
        let pipeline = Pipeline::with_method(params, None, Method::Evigrid)?;
        let motion = pipeline
            .fusion()
            .motion()
            .map_or(0, MotionStage::heap_bytes);
        assert!(motion > 0);
        let per_cell = (motion
            + pipeline.perception().heap_bytes()
            + pipeline.sensor_grid().heap_bytes()
            + pipeline.gis().heap_bytes()
            + std::mem::size_of_val(pipeline.decisions())
            + pipeline.trace().as_slice().len()) as f64
            / cells as f64;
        assert!(
            per_cell <= crate::params::WINDOW_BYTES_PER_CELL as f64,
            "{per_cell} bytes per cell"
        );
        Ok(())
    }

    #[test]
    fn refuses_time_going_back_and_bad_poses() {
        let mut pipeline = Pipeline::new(params(), None).unwrap();
        pipeline
            .process(&[], &IsometryMatrix3::identity(), 1.0)
            .unwrap();
        assert!(matches!(
            pipeline.process(&[], &IsometryMatrix3::identity(), 0.5),
            Err(PipelineError::Time { .. })
        ));
        assert!(
            pipeline
                .process(&[], &IsometryMatrix3::identity(), f64::NAN)
                .is_err()
        );
        let nan = IsometryMatrix3::from_xyz_rpy(f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0);
        assert!(matches!(
            pipeline.process(&[], &nan, 2.0),
            Err(PipelineError::Pose { .. })
        ));
        let far = IsometryMatrix3::from_xyz_rpy(1e300, 0.0, 0.0, 0.0, 0.0, 0.0);
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
        let first = pipeline
            .process(&[], &IsometryMatrix3::identity(), 0.0)
            .unwrap();
        assert_eq!(first.entered_cells, 400);
        assert_eq!(first.dt_s, 0.0);
        let pose = IsometryMatrix3::from_xyz_rpy(1.2, 0.0, 0.0, 0.0, 0.0, 0.0);
        let second = pipeline.process(&[], &pose, 0.5).unwrap();
        // 1.2 m east at 0.5 m cells: two columns of 20 cells entered.
        assert_eq!(second.entered_cells, 40);
        assert_eq!(second.dt_s, 0.5);
    }

    /// A building on x ∈ [2, 6], y ∈ [0, 4] and a road y ∈ [−2, 0] across the map.
    fn raster() -> ContextRaster {
        use geo::{Rect, coord, polygon};
        let building =
            polygon![(x: 2.0, y: 0.0), (x: 6.0, y: 0.0), (x: 6.0, y: 4.0), (x: 2.0, y: 4.0)];
        let road = polygon![(x: -20.0, y: -2.0), (x: 20.0, y: -2.0), (x: 20.0, y: 0.0), (x: -20.0, y: 0.0)];
        let extent = Rect::new(coord! { x: -20.0, y: -20.0 }, coord! { x: 20.0, y: 20.0 });
        ContextRaster::new(&geodata::LocalMap::new(vec![building], vec![road], extent))
    }

    /// A short drive east along the road past the building, with a wall north of it and an
    /// object that appears on the road.
    fn drive() -> Vec<(Vec<[f32; 3]>, IsometryMatrix3, f64)> {
        (0..8)
            .map(|k| {
                let x_m = 0.4 * k as f64;
                // The building's south face (y = 0) is 1 m north of the sensor.
                let mut points: Vec<[f32; 3]> =
                    (-10..=10).map(|j| [j as f32 * 0.3, 1.0, 0.0]).collect();
                if k >= 4 {
                    points.push([3.0, 0.5, 0.0]);
                }
                let pose = IsometryMatrix3::from_xyz_rpy(x_m, -1.0, 0.0, 0.0, 0.0, 0.0);
                (points, pose, 0.1 * k as f64)
            })
            .collect()
    }

    #[test]
    fn back_ends_on_one_front_end_match_their_own_pipelines() {
        // `full` and `no-map` of the evaluation: one front end with the map, a fusion of its
        // prior and one of a vacuous prior; each must match a pipeline of its own.
        let mut with_map = Pipeline::new(params(), Some(raster())).unwrap();
        let mut without_map = Pipeline::new(params(), None).unwrap();
        let mut front_end = FrontEnd::new(&params(), Some(raster())).unwrap();
        let mut map_fusion = Fusion::new(params(), Prior::Map).unwrap();
        let mut vacuous_fusion = Fusion::new(params(), Prior::Vacuous).unwrap();
        for (points, pose, time_s) in drive() {
            with_map.process(&points, &pose, time_s).unwrap();
            without_map.process(&points, &pose, time_s).unwrap();
            front_end.process(&points, &pose, time_s).unwrap();
            map_fusion.update(&front_end).unwrap();
            vacuous_fusion.update(&front_end).unwrap();
            assert_eq!(front_end.window(), with_map.window());
            assert_eq!(front_end.sensor_grid(), with_map.sensor_grid());
            assert_eq!(front_end.gis(), with_map.gis());
            assert_eq!(map_fusion.perception(), with_map.perception());
            assert_eq!(map_fusion.decisions(), with_map.decisions());
            assert_eq!(map_fusion.trace(), with_map.trace());
            assert_eq!(vacuous_fusion.perception(), without_map.perception());
            assert_eq!(vacuous_fusion.decisions(), without_map.decisions());
            assert_eq!(vacuous_fusion.trace(), without_map.trace());
        }
        // The map changed something, or the comparison above proves nothing.
        assert_ne!(with_map.decisions(), without_map.decisions());
    }

    #[test]
    fn the_evigrid_method_changes_only_what_its_motion_stage_touches() {
        // Kurdej2013 through `with_method` is `new`, bit for bit; Evigrid reports its stage.
        let mut paper = Pipeline::new(params(), Some(raster())).unwrap();
        let mut named =
            Pipeline::with_method(params(), Some(raster()), Method::Kurdej2013).unwrap();
        let mut evigrid = Pipeline::with_method(params(), Some(raster()), Method::Evigrid).unwrap();
        assert_eq!(paper.fusion().method(), Method::Kurdej2013);
        assert_eq!(evigrid.fusion().method(), Method::Evigrid);
        assert!(paper.fusion().motion().is_none());
        for (points, pose, time_s) in drive() {
            paper.process(&points, &pose, time_s).unwrap();
            named.process(&points, &pose, time_s).unwrap();
            let stats = evigrid.process(&points, &pose, time_s).unwrap();
            assert_eq!(paper.perception(), named.perception());
            assert_eq!(paper.decisions(), named.decisions());
            assert!(stats.step_cells > 0);
        }
        let motion = evigrid.fusion().motion().unwrap();
        assert_eq!(motion.velocity_east().len(), 400);
        // The wall north of the road is static: never moving in the evigrid variant.
        let window = evigrid.window();
        let wall = window.storage_index_of_point(1.0, 0.1).unwrap();
        assert_ne!(evigrid.decisions()[wall], crate::Label::M);
    }

    #[test]
    fn new_cells_are_the_whole_window_first_then_what_entered() {
        let mut front_end = FrontEnd::new(&params(), None).unwrap();
        assert_eq!(front_end.new_cells(), &NewCells::All);
        front_end
            .process(&[], &IsometryMatrix3::identity(), 0.0)
            .unwrap();
        assert_eq!(front_end.new_cell_spans().collect::<Vec<_>>(), vec![0..400]);
        let pose = IsometryMatrix3::from_xyz_rpy(0.6, 0.0, 0.0, 0.0, 0.0, 0.0);
        front_end.process(&[], &pose, 0.1).unwrap();
        // One column of 20 cells entered, one storage cell per row.
        let spans: Vec<_> = front_end.new_cell_spans().collect();
        assert_eq!(spans.len(), 20);
        assert!(spans.iter().all(|s| s.len() == 1));
        assert_eq!(front_end.new_cells().cell_count(front_end.window()), 20);
        assert_eq!(front_end.dt_s(), 0.1);
    }

    #[test]
    fn a_back_end_refuses_a_front_end_of_another_size() {
        let mut front_end = FrontEnd::new(&params(), None).unwrap();
        front_end
            .process(&[], &IsometryMatrix3::identity(), 0.0)
            .unwrap();
        let mut other = params();
        other.window.width_cells = 30;
        let mut fusion = Fusion::new(other, Prior::Map).unwrap();
        assert!(matches!(
            fusion.update(&front_end),
            Err(PipelineError::WindowSize {
                front_end: (20, 20),
                back_end: (30, 20)
            })
        ));
    }
}
