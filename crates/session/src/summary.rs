//! What a session reports: one [`FrameRecord`] per frame (`frames.jsonl`) and the [`Summary`]
//! over the drive (`summary.json`), with the totals kept as it goes (constant memory).

use std::collections::BTreeMap;

use evigrid::ego_path::{EgoPathCheck, ShareSpread, ShareTracker};
use evigrid::{FrameStats, Params, RefinementOutcome};
use serde::Serialize;

/// Per-frame record (one line of `frames.jsonl`).
#[derive(Clone, Debug, Serialize)]
pub struct FrameRecord {
    /// The scan's name.
    pub scan: String,
    /// The scan's time, seconds.
    pub time_s: f64,
    /// The sensor's position in the world frame, metres: the pose the grids were built with
    /// (after the `[localisation]` refinement).
    pub position: [f64; 3],
    /// The position as given (pose file, bag, OXTS, odometry), metres.
    pub given_position: [f64; 3],
    /// Reading the scan, milliseconds.
    pub read_ms: f64,
    /// The pipeline's work on it, milliseconds.
    pub process_ms: f64,
    /// The ego-path check and the sinks' per-frame work, milliseconds.
    pub render_ms: f64,
    /// The pipeline's counts.
    pub stats: FrameStats,
    /// Cells per decision: unknown, F, I, U, S, M.
    pub classes: [usize; 6],
    /// Ground points over the scan's points.
    pub ground_share: f64,
    /// Obstacle points over the scan's points.
    pub obstacle_share: f64,
    /// Obstacle points over the finite points within the sensor's range.
    pub obstacle_share_in_range: f64,
    /// Cells the scan marked occupied over the cells it observed (occupied or free): an area
    /// measure, which a wall beside the car does not inflate as it does the point shares.
    pub obstacle_cell_share: f64,
    /// Cells within `EGO_PATH_RADIUS_M` of the ego's path over the next `EGO_PATH_LENGTH_M`.
    pub ego_path: EgoPathCheck,
    /// Of the observed ego-path cells, the share decided I, U, S or M (`null`: none observed).
    pub ego_path_share: Option<f64>,
    /// The objects the `evigrid` method judged moving, with their velocity (empty for
    /// `kurdej2013`).
    pub moving_objects: Vec<evigrid::motion::MovingObject>,
}

/// Totals of the ego-path check over the drive.
#[derive(Clone, Debug, Serialize)]
pub struct EgoPathTotals {
    /// Length of the path ahead checked, metres.
    pub length_m: f64,
    /// Distance either side of it, metres.
    pub radius_m: f64,
    /// Observed ego-path cells summed over the frames.
    pub cell_frames: usize,
    /// Of those, decided occupied (I, U, S).
    pub occupied: usize,
    /// Of those, decided moving.
    pub moving: usize,
    /// Of `moving`, the cells whose velocity this frame points along the path (within 45°):
    /// traffic ahead going the ego's way. `null` for `kurdej2013`, which estimates no velocity.
    pub moving_along_path: Option<usize>,
    /// `occupied + moving`.
    pub decided_occupied_or_moving: usize,
    /// `decided_occupied_or_moving / cell_frames`.
    pub share: Option<f64>,
    /// `moving / cell_frames`.
    pub moving_share: Option<f64>,
    /// `(moving - moving_along_path) / cell_frames`: the moving cells the path must not hold
    /// (not traffic ahead). `null` for `kurdej2013`.
    pub moving_apart_from_traffic_share: Option<f64>,
}

/// A scan the session skipped, and why.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct SkippedScan {
    /// The scan's name.
    pub scan: String,
    /// Why (the message names the scan or its file).
    pub error: String,
}

/// The pose refinement over the drive.
#[derive(Clone, Debug, Serialize)]
pub struct RefinementTotals {
    /// Frames per outcome: `refined`, `first`, or why the pose was kept as given
    /// (`kept_too_far`, `kept_failed`, `kept_low_overlap`, `kept_no_data`).
    pub outcomes: BTreeMap<String, usize>,
    /// Over the refined frames: the median horizontal correction, metres.
    pub median_correction_m: Option<f64>,
    /// The largest correction, metres.
    pub largest_correction_m: Option<f64>,
    /// Its frame (0-based).
    pub largest_correction_frame: Option<usize>,
}

/// The summary written to `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// False when the session stopped early (`stopped` says why): the grids and pictures are
    /// those of the last frame processed.
    pub complete: bool,
    /// Why the session stopped before the last scan (a signal, an error); `null` when complete.
    pub stopped: Option<String>,
    /// Scans left out (unreadable, or their pose refused), with the reason; the session goes
    /// on without them unless `strict`.
    pub skipped_scans: Vec<SkippedScan>,
    /// The map, or `null` for a session without one.
    pub map: Option<String>,
    /// The fusion: `evigrid` (with motion evidence) or `kurdej2013` (SPEC §5 exactly).
    pub method: String,
    /// `map`, or `vacuous (no map)`: what the GISGrid held.
    pub prior: &'static str,
    /// The map's counts and extent.
    pub map_stats: Option<geodata::MapStats>,
    /// The drive as given.
    pub scans: String,
    /// The pose file, or where the poses came from (`OXTS of …`, `lidar odometry`).
    pub poses: String,
    /// How scans met poses: `time`, `line order` or `odometry`.
    pub pose_matching: &'static str,
    /// The parameters the pipeline ran with.
    pub params: Params,
    /// Frames processed.
    pub frames: usize,
    /// Points over the frames.
    pub points: usize,
    /// Non-finite points dropped.
    pub dropped_non_finite: usize,
    /// Points beyond the sensor's range dropped.
    pub dropped_out_of_range: usize,
    /// Points outside the window dropped.
    pub dropped_outside_window: usize,
    /// Obstacle returns of a 3-D lidar dropped as stray (`sensor.min_neighbourhood_returns`).
    pub stray_obstacle_points: usize,
    /// Wall time of the whole session, seconds.
    pub total_seconds: f64,
    /// Seconds of the odometry's first pass (0 when poses were given).
    pub odometry_seconds: f64,
    /// Mean `process_ms` over the frames.
    pub mean_process_ms: f64,
    /// Final cells per decision: unknown, F, I, U, S, M.
    pub final_classes: [usize; 6],
    /// Cells ever decided moving.
    pub moving_trace_cells: usize,
    /// The ego-path check over the drive.
    pub ego_path: EgoPathTotals,
    /// Median over frames of `obstacle_share` and the worst frame's ratio to it.
    pub obstacle_share: Option<ShareSpread>,
    /// The same for `obstacle_share_in_range`.
    pub obstacle_share_in_range: Option<ShareSpread>,
    /// The same for `obstacle_cell_share`.
    pub obstacle_cell_share: Option<ShareSpread>,
    /// What the pose refinement did (`[localisation]`); `null` when it is off.
    pub pose_refinement: Option<RefinementTotals>,
    /// The per-frame records, one JSON object per line, written as the session goes.
    pub frames_file: &'static str,
    /// The output folder.
    pub out: String,
}

/// Name of the per-frame records in the output folder.
pub const FRAMES_FILE: &str = "frames.jsonl";

/// What the summary adds up over the frames, kept as the session goes (constant memory).
#[derive(Debug, Default)]
pub(crate) struct RunningTotals {
    pub(crate) frames: usize,
    pub(crate) points: usize,
    pub(crate) dropped_non_finite: usize,
    pub(crate) dropped_out_of_range: usize,
    pub(crate) dropped_outside_window: usize,
    pub(crate) stray_obstacle_points: usize,
    pub(crate) process_ms: f64,
    pub(crate) ego_path: EgoPathCheck,
    pub(crate) obstacle_share: ShareTracker,
    pub(crate) obstacle_share_in_range: ShareTracker,
    pub(crate) obstacle_cell_share: ShareTracker,
    pub(crate) refinement_outcomes: BTreeMap<String, usize>,
    /// Corrections as a fraction of `max_correction_m` (the gate bounds them), NaN for frames
    /// not refined.
    pub(crate) refinement_corrections: ShareTracker,
    /// `[localisation] max_correction_m`.
    pub(crate) max_correction_m: f64,
}

impl RunningTotals {
    pub(crate) fn add(&mut self, f: &FrameRecord) {
        let refinement = &f.stats.pose_refinement;
        let outcome = serde_json::to_value(refinement.outcome)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        self.refinement_corrections
            .push(if refinement.outcome == RefinementOutcome::Refined {
                refinement.correction_m / self.max_correction_m
            } else {
                f64::NAN
            });
        *self.refinement_outcomes.entry(outcome).or_default() += 1;
        let s = &f.stats.sensor;
        self.frames += 1;
        self.points += s.points;
        self.dropped_non_finite += s.dropped_non_finite;
        self.dropped_out_of_range += s.dropped_out_of_range;
        self.dropped_outside_window += s.dropped_outside_window;
        self.stray_obstacle_points += s.stray_obstacle_points;
        self.process_ms += f.process_ms;
        self.ego_path.add(&f.ego_path);
        self.obstacle_share.push(f.obstacle_share);
        self.obstacle_share_in_range.push(f.obstacle_share_in_range);
        self.obstacle_cell_share.push(f.obstacle_cell_share);
    }

    /// The pose refinement's totals.
    pub(crate) fn refinement(&self) -> RefinementTotals {
        let spread = self.refinement_corrections.spread();
        let scale = self.max_correction_m;
        RefinementTotals {
            outcomes: self.refinement_outcomes.clone(),
            median_correction_m: spread.map(|s| s.median * scale),
            largest_correction_m: spread.map(|s| s.worst * scale),
            largest_correction_frame: spread.map(|s| s.worst_frame),
        }
    }

    /// The ego-path totals; `estimates_velocity` for the method with a motion stage.
    pub(crate) fn ego_path(&self, estimates_velocity: bool) -> EgoPathTotals {
        let e = &self.ego_path;
        EgoPathTotals {
            length_m: evigrid::ego_path::EGO_PATH_LENGTH_M,
            radius_m: evigrid::ego_path::EGO_PATH_RADIUS_M,
            cell_frames: e.observed_cells,
            occupied: e.occupied_cells,
            moving: e.moving_cells,
            moving_along_path: estimates_velocity.then_some(e.moving_along_path),
            decided_occupied_or_moving: e.decided_occupied_or_moving(),
            share: e.share(),
            moving_share: e.moving_share(),
            moving_apart_from_traffic_share: e
                .moving_apart_from_traffic_share()
                .filter(|_| estimates_velocity),
        }
    }
}
