//! [`Session`]: the pipeline over a drive's frames, one [`Session::step`] at a time, with the
//! running totals, the ego-path check and the summary.

use std::path::Path;
use std::time::Instant;

use drive::{Frame, PoseOrigin};
use evigrid::ego_path::{
    CellVelocity, EGO_PATH_LENGTH_M, EGO_PATH_RADIUS_M, EgoPathCheck, cells_near_path, path_ahead,
};
use evigrid::motion::MovingObject;
use evigrid::{
    IsometryMatrix3, Label, Method, Params, PerceptionGrid, Pipeline, PoseRefinement, Window,
};
use output::count_decisions;
use output::sink::{FinalView, FrameSink, FrameView};

use crate::SessionError;
use crate::summary::{FRAMES_FILE, FrameRecord, RunningTotals, SkippedScan, Summary};

/// A vector map loaded for a session, with the name the summary gives it.
pub struct Map {
    /// The map in local metres, its projection and counts.
    pub loaded: geodata::LoadedMap,
    /// The name the summary gives it (the file as given).
    pub name: String,
}

impl Map {
    /// Loads a map file (OSM PBF, OSM XML optionally gzipped, GeoJSON); `origin` `(lat, lon)`
    /// in degrees is its local frame's origin (by default the map's centre).
    ///
    /// # Errors
    ///
    /// [`SessionError::Map`] naming the file.
    pub fn load(path: &Path, origin: Option<(f64, f64)>) -> Result<Self, SessionError> {
        let loaded = geodata::load_map(path, &geodata::LoadOptions { origin })?;
        Ok(Self {
            loaded,
            name: path.display().to_string(),
        })
    }
}

impl std::fmt::Debug for Map {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Map")
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

/// What a session is built from. By default: the default parameters, the `evigrid` method (as
/// `evigrid run`), no map, no origin, skipping bad scans, every frame.
#[derive(Debug)]
pub struct SessionConfig {
    /// The method's parameters (SPEC §7).
    pub params: Params,
    /// The fusion: [`Method::Evigrid`] (the default) or [`Method::Kurdej2013`].
    pub method: Method,
    /// The map; without one the prior is vacuous.
    pub map: Option<Map>,
    /// Origin of the local frame `(lat, lon)` in degrees when there is no map: places WGS84
    /// poses. [`crate::run_drive`] takes a KITTI raw drive's first fix when neither is given.
    pub origin: Option<(f64, f64)>,
    /// Stop at the first unreadable scan or refused pose instead of skipping it.
    pub strict: bool,
    /// Process only the first N scans (the poses of later ones still give the path ahead).
    pub max_frames: Option<usize>,
    /// The output folder, as the summary names it (empty: none).
    pub out: String,
}

impl SessionConfig {
    /// Fits the configuration to where the drive's poses came from. Poses from the lidar
    /// odometry are already registrations of these scans: refining them against a second map
    /// of the same scans would spend a registration to change nothing, so refinement is off.
    pub fn adapt_to_poses(&mut self, origin: &PoseOrigin) {
        self.params.localisation.refinement =
            refinement_for(origin, self.params.localisation.refinement);
    }
}

/// The pose refinement a drive's poses get: none for the lidar odometry's, else `configured`.
fn refinement_for(origin: &PoseOrigin, configured: PoseRefinement) -> PoseRefinement {
    if *origin == PoseOrigin::Odometry && configured != PoseRefinement::None {
        tracing::info!("poses from the lidar odometry: [localisation] refinement is not applied");
        PoseRefinement::None
    } else {
        configured
    }
}

impl Default for SessionConfig {
    fn default() -> Self {
        Self {
            params: Params::default(),
            method: Method::Evigrid,
            map: None,
            origin: None,
            strict: false,
            max_frames: None,
            out: String::new(),
        }
    }
}

/// The name a method has in summaries and on command lines: `evigrid`, `kurdej2013`.
pub fn method_name(method: Method) -> &'static str {
    match method {
        Method::Evigrid => "evigrid",
        Method::Kurdej2013 => "kurdej2013",
    }
}

/// What one step gives: the frame's record and the grids after it, borrowed from the session
/// (nothing is copied).
pub struct StepResult<'a> {
    session: &'a Session,
    /// The frame's record (the line `frames.jsonl` gets).
    pub record: FrameRecord,
}

impl<'a> StepResult<'a> {
    /// The window: size, cell size, where it lies in the world.
    pub fn window(&self) -> &'a Window {
        self.session.pipeline.window()
    }

    /// World position of the window's south-west corner, metres (east, north).
    pub fn origin_m(&self) -> [f64; 2] {
        let window = self.window();
        let s = window.cell_size_m();
        [window.first_col() as f64 * s, window.first_row() as f64 * s]
    }

    /// Cell side, metres.
    pub fn cell_size_m(&self) -> f64 {
        self.window().cell_size_m()
    }

    /// Decisions, storage order ([`Window::world_order_spans`] gives world order).
    pub fn decisions(&self) -> &'a [Label] {
        self.session.pipeline.decisions()
    }

    /// The masses on every focal set (`perception().plane(set)`, storage order).
    pub fn perception(&self) -> &'a PerceptionGrid {
        self.session.pipeline.perception()
    }

    /// The pignistic probability of the cell at storage index `cell` over F, I, U, S, M.
    pub fn pignistic(&self, cell: usize) -> [f32; 5] {
        evigrid::betp(&self.perception().cell_masses(cell))
    }

    /// Cell velocities east and north, m/s, storage order (the `evigrid` method only).
    pub fn velocity(&self) -> Option<(&'a [f32], &'a [f32])> {
        self.session
            .pipeline
            .fusion()
            .motion()
            .map(|m| (m.velocity_east(), m.velocity_north()))
    }

    /// The objects judged moving this frame (the `evigrid` method only; empty otherwise).
    pub fn moving_objects(&self) -> &'a [MovingObject] {
        self.session
            .pipeline
            .fusion()
            .motion()
            .map_or(&[], |m| m.moving_objects())
    }
}

/// The pipeline over one drive, frame by frame.
pub struct Session {
    pipeline: Pipeline,
    params: Params,
    method: Method,
    map: Option<Map>,
    projection: Option<geodata::TransverseMercator>,
    strict: bool,
    out: String,
    totals: RunningTotals,
    skipped: Vec<SkippedScan>,
    /// The ego's path, metres: every pose known ahead of time, or the positions stepped so far.
    path: Vec<[f64; 2]>,
    /// Frames reached (processed or skipped): the path so far.
    reached: usize,
    /// Time of the last frame reached.
    last_time_s: f64,
    started: Instant,
    /// How the summary names the drive ([`Session::begin_drive`]).
    labels: DriveLabels,
    stopped: Option<String>,
}

/// How the summary names the drive whose frames a session steps.
#[derive(Clone, Debug, Default)]
pub struct DriveLabels {
    /// The drive as given (`scans` in the summary).
    pub scans: String,
    /// Where the poses came from (`poses`).
    pub poses: String,
    /// How scans met poses (`pose_matching`): `time`, `line order` or `odometry`.
    pub pose_matching: &'static str,
    /// Seconds of the odometry pass that placed the scans, 0 when the drive had poses.
    pub odometry_seconds: f64,
}

impl DriveLabels {
    /// The labels of a placed drive.
    pub fn new(drive: &drive::Drive, origin: &PoseOrigin, odometry_seconds: f64) -> Self {
        Self {
            scans: drive.given_path().display().to_string(),
            poses: origin.to_string(),
            pose_matching: origin.matching().name(),
            odometry_seconds,
        }
    }
}

impl Session {
    /// Builds the pipeline from the parameters, the method and the map.
    ///
    /// # Errors
    ///
    /// [`SessionError::Input`] for parameters out of range or an origin off the globe.
    pub fn new(config: SessionConfig) -> Result<Self, SessionError> {
        let projection = match (&config.map, config.origin) {
            (Some(map), _) => Some(map.loaded.projection),
            (None, Some((lat, lon))) => Some(
                geodata::TransverseMercator::new(lat, lon)
                    .map_err(|e| SessionError::Input(format!("origin of the local frame: {e}")))?,
            ),
            (None, None) => None,
        };
        let raster = config
            .map
            .as_ref()
            .map(|map| geodata::ContextRaster::new(&map.loaded.map));
        let pipeline = Pipeline::with_method(config.params.clone(), raster, config.method)
            .map_err(|e| SessionError::Input(format!("parameters: {e}")))?;
        Ok(Self {
            pipeline,
            totals: RunningTotals {
                max_correction_m: config.params.localisation.max_correction_m,
                ..RunningTotals::default()
            },
            params: config.params,
            method: config.method,
            map: config.map,
            projection,
            strict: config.strict,
            out: config.out,
            skipped: Vec::new(),
            path: Vec::new(),
            reached: 0,
            last_time_s: 0.0,
            started: Instant::now(),
            labels: DriveLabels::default(),
            stopped: None,
        })
    }

    /// The local frame's projection (the map's, or the origin's): how a drive's WGS84 poses
    /// are placed ([`drive::Drive::place`]).
    pub fn projection(&self) -> Option<&geodata::TransverseMercator> {
        self.projection.as_ref()
    }

    /// The pipeline (window, grids, motion stage).
    pub fn pipeline(&self) -> &Pipeline {
        &self.pipeline
    }

    /// The ego's path, metres (east, north), one position per scan, known ahead of the frames:
    /// the ego-path check looks along it. Without it, the path is the positions stepped so far.
    pub fn set_path(&mut self, path: Vec<[f64; 2]>) {
        self.path = path;
    }

    /// Processes one frame and gives its record and the grids after it.
    ///
    /// # Errors
    ///
    /// [`SessionError::Input`] when the pipeline refuses the frame's pose or time (the grids
    /// are unchanged); the scan is recorded as skipped unless the session is `strict`.
    pub fn step(&mut self, frame: &Frame) -> Result<StepResult<'_>, SessionError> {
        let record = self.step_into(frame, 0.0, &mut [])?;
        Ok(StepResult {
            session: self,
            record,
        })
    }

    /// Names the drive whose frames come next, as the summary shows it, and fits the pose
    /// refinement to where its poses came from ([`SessionConfig::adapt_to_poses`]) while no
    /// frame has been processed yet: [`crate::run_placed`] does this for a whole drive, and a
    /// caller that steps a placed drive's frames itself does the same.
    ///
    /// # Errors
    ///
    /// [`SessionError::Input`] if the pipeline cannot be rebuilt (not for parameters that
    /// built it once).
    pub fn begin_drive(
        &mut self,
        labels: DriveLabels,
        origin: &PoseOrigin,
    ) -> Result<(), SessionError> {
        self.labels = labels;
        let refinement = refinement_for(origin, self.params.localisation.refinement);
        if self.reached == 0 && refinement != self.params.localisation.refinement {
            self.params.localisation.refinement = refinement;
            let raster = self
                .map
                .as_ref()
                .map(|map| geodata::ContextRaster::new(&map.loaded.map));
            self.pipeline = Pipeline::with_method(self.params.clone(), raster, self.method)
                .map_err(|e| SessionError::Input(format!("parameters: {e}")))?;
        }
        Ok(())
    }

    /// Records a scan left out before the frames (by the odometry pass).
    pub fn skipped_before(&mut self, scan: SkippedScan) {
        self.skipped.push(scan);
    }

    /// Counts the summary's `total_seconds` from `started` (when the drive was placed).
    pub(crate) fn started_at(&mut self, started: Instant) {
        self.started = started;
    }

    /// Records a scan that could not be read, as the summary lists it.
    pub fn skip(&mut self, scan: SkippedScan) {
        self.reached += 1;
        self.skipped.push(scan);
    }

    /// Processes one frame, hands it to `sinks` and adds it to the totals; `read_ms` is the
    /// time its scan took to read. A sink's error is returned after the totals are updated.
    pub(crate) fn step_into(
        &mut self,
        frame: &Frame,
        read_ms: f64,
        sinks: &mut [&mut dyn FrameSink],
    ) -> Result<FrameRecord, SessionError> {
        self.reached = frame.index + 1;
        self.last_time_s = frame.time_s;
        let position = [
            frame.world_from_sensor.translation.x,
            frame.world_from_sensor.translation.y,
        ];
        if self.path.len() <= frame.index {
            self.path.resize(frame.index + 1, position);
        }
        let t1 = Instant::now();
        // The drive's rotation is a quaternion (poses are interpolated by slerp); the method maps
        // every point with the matrix.
        let world_from_sensor = IsometryMatrix3::from_parts(
            frame.world_from_sensor.translation,
            frame.world_from_sensor.rotation.to_rotation_matrix(),
        );
        let stats =
            match self
                .pipeline
                .process(&frame.points_in_sensor, &world_from_sensor, frame.time_s)
            {
                Ok(stats) => stats,
                Err(e) => {
                    let error = format!("{}: pose of scan {}: {e}", self.labels.poses, frame.name);
                    if !self.strict {
                        self.skipped.push(SkippedScan {
                            scan: frame.name.clone(),
                            error: error.clone(),
                        });
                    }
                    return Err(SessionError::Input(error));
                }
            };
        let t2 = Instant::now();
        let ego_path = self.ego_path_check(frame.index);
        let pipeline = &self.pipeline;
        let view = FrameView {
            index: frame.index,
            name: &frame.name,
            time_s: frame.time_s,
            window: pipeline.window(),
            decisions: pipeline.decisions(),
            perception: pipeline.perception(),
            sensor_grid: pipeline.sensor_grid(),
            motion: pipeline.fusion().motion(),
            world_from_sensor: pipeline.front_end().world_from_sensor(),
            points_in_sensor: &frame.points_in_sensor,
            intensity: &frame.intensity,
            sensor_height_m: self.params.sensor.ground.sensor_height_m,
            fix: frame.fix.map(|f| output::mcap::GnssFix {
                time_s: f.time_s,
                lat_deg: f.lat_deg,
                lon_deg: f.lon_deg,
                alt_m: f.alt_m,
            }),
        };
        let mut sunk = Ok(());
        for sink in sinks.iter_mut() {
            sunk = sink.on_frame(&view);
            if sunk.is_err() {
                break;
            }
        }
        let t3 = Instant::now();
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        let record = self.record(frame, stats, ego_path, [read_ms, ms(t2 - t1), ms(t3 - t2)]);
        if let Err(error) = sunk {
            return Err(SessionError::Output(error));
        }
        if !sinks.is_empty() {
            let line = serde_json::to_string(&record).unwrap_or_default();
            for sink in sinks.iter_mut() {
                sink.on_record(&line)?;
            }
        }
        self.totals.add(&record);
        Ok(record)
    }

    /// The ego-path check of frame `k`: cells near the path ahead, and of the moving ones those
    /// whose velocity follows it.
    fn ego_path_check(&self, k: usize) -> EgoPathCheck {
        let pipeline = &self.pipeline;
        let ego_polyline = path_ahead(&self.path, k, EGO_PATH_LENGTH_M);
        let path_cells = cells_near_path(pipeline.window(), &ego_polyline, EGO_PATH_RADIUS_M);
        let mut ego_path =
            EgoPathCheck::count(&path_cells, pipeline.sensor_grid(), pipeline.decisions());
        if let Some(motion) = pipeline.fusion().motion() {
            ego_path.count_traffic_ahead(
                &path_cells,
                pipeline.sensor_grid(),
                pipeline.decisions(),
                pipeline.window(),
                &ego_polyline,
                CellVelocity {
                    east: motion.velocity_east(),
                    north: motion.velocity_north(),
                },
            );
        }
        ego_path
    }

    /// The frame's record; `ms` are the read, process and render times.
    fn record(
        &self,
        frame: &Frame,
        stats: evigrid::FrameStats,
        ego_path: EgoPathCheck,
        [read_ms, process_ms, render_ms]: [f64; 3],
    ) -> FrameRecord {
        let pipeline = &self.pipeline;
        let s = &stats.sensor;
        let share = |n: usize, of: usize| if of > 0 { n as f64 / of as f64 } else { 0.0 };
        let in_range = s
            .points
            .saturating_sub(s.dropped_non_finite + s.dropped_out_of_range);
        let given = frame.world_from_sensor.translation;
        FrameRecord {
            scan: frame.name.clone(),
            time_s: frame.time_s,
            position: pipeline
                .front_end()
                .world_from_sensor()
                .translation
                .vector
                .into(),
            given_position: [given.x, given.y, given.z],
            read_ms,
            process_ms,
            render_ms,
            ground_share: share(s.ground_points, s.points),
            obstacle_share: share(s.obstacle_points, s.points),
            obstacle_share_in_range: share(s.obstacle_points, in_range),
            obstacle_cell_share: share(s.occupied_cells, s.occupied_cells + s.free_cells),
            ego_path_share: ego_path.share(),
            ego_path,
            moving_objects: pipeline
                .fusion()
                .motion()
                .map(|m| m.moving_objects().to_vec())
                .unwrap_or_default(),
            stats,
            classes: count_decisions(pipeline.decisions()),
        }
    }

    /// Marks the session stopped early, and why (the summary says so).
    pub fn stop(&mut self, why: impl Into<String>) {
        if self.stopped.is_none() {
            self.stopped = Some(why.into());
        }
    }

    /// True once [`Session::stop`] was called.
    pub fn is_stopped(&self) -> bool {
        self.stopped.is_some()
    }

    /// Frames processed so far.
    pub fn frames(&self) -> usize {
        self.totals.frames
    }

    /// Scans skipped so far.
    pub fn skipped(&self) -> &[SkippedScan] {
        &self.skipped
    }

    /// The grids as they stand, for the sinks' [`FrameSink::finish`].
    pub fn final_view(&self) -> FinalView<'_> {
        let pipeline = &self.pipeline;
        FinalView {
            window: pipeline.window(),
            decisions: pipeline.decisions(),
            perception: pipeline.perception(),
            trace: pipeline.trace(),
            motion: pipeline.fusion().motion(),
            gis: pipeline.has_map().then(|| pipeline.gis()),
            driven: &self.path[..self.reached.min(self.path.len())],
            time_s: self.last_time_s,
            projection: self.projection.as_ref(),
        }
    }

    /// The summary as the session stands (complete unless stopped).
    pub fn summary(&self) -> Summary {
        let pipeline = &self.pipeline;
        let totals = &self.totals;
        let refining = self.params.localisation.refinement != PoseRefinement::None;
        // Only the motion stage (`evigrid`, not `kurdej2013`) gives cells a velocity.
        let estimates_velocity = pipeline.fusion().motion().is_some();
        Summary {
            complete: self.stopped.is_none(),
            stopped: self.stopped.clone(),
            skipped_scans: self.skipped.clone(),
            map: self.map.as_ref().map(|m| m.name.clone()),
            method: method_name(self.method).to_string(),
            prior: if self.map.is_some() {
                "map"
            } else {
                "vacuous (no map)"
            },
            map_stats: self.map.as_ref().map(|m| m.loaded.stats.clone()),
            scans: self.labels.scans.clone(),
            poses: self.labels.poses.clone(),
            pose_matching: self.labels.pose_matching,
            params: self.params.clone(),
            frames: totals.frames,
            points: totals.points,
            dropped_non_finite: totals.dropped_non_finite,
            dropped_out_of_range: totals.dropped_out_of_range,
            dropped_outside_window: totals.dropped_outside_window,
            stray_obstacle_points: totals.stray_obstacle_points,
            total_seconds: self.started.elapsed().as_secs_f64(),
            odometry_seconds: self.labels.odometry_seconds,
            mean_process_ms: if totals.frames == 0 {
                0.0
            } else {
                totals.process_ms / totals.frames as f64
            },
            final_classes: count_decisions(pipeline.decisions()),
            moving_trace_cells: pipeline.trace().count(),
            ego_path: totals.ego_path(estimates_velocity),
            obstacle_share: totals.obstacle_share.spread(),
            obstacle_share_in_range: totals.obstacle_share_in_range.spread(),
            obstacle_cell_share: totals.obstacle_cell_share.spread(),
            pose_refinement: refining.then(|| totals.refinement()),
            frames_file: FRAMES_FILE,
            out: self.out.clone(),
        }
    }
}
