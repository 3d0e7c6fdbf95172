//! `evigrid run`: the perception pipeline over a drive, with or without a map.
//!
//! ```text
//! evigrid run --drive 2011_09_26/ --out out/                       KITTI raw: scans, OXTS, calib
//! evigrid run --scans scans/ --poses poses.txt --map city.osm.pbf --out out/
//! evigrid run --scans scans/ --out out/                            poses from the lidar odometry
//! ```
//!
//! Wiring only: reading files, the progress bar, writing pictures and the summary. The work is
//! `evigrid::Pipeline`'s; poses are matched to scans in `crate::drive_input`.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use drive::poses::{Mounting, PoseFormat};
use evigrid::Params;
use evigrid::ego_path::{
    CellVelocity, EGO_PATH_LENGTH_M, EGO_PATH_RADIUS_M, EgoPathCheck, ShareSpread, ShareTracker,
    cells_near_path, path_ahead,
};
use evigrid::{FrameStats, Pipeline, PoseRefinement, RefinementOutcome};
use odometry::OdometryParams;
use output::mcap::{GnssFix, McapFrame, McapRecorder};
use output::{
    ClassColours, GridExports, count_decisions, decision_image, write_grid_exports, write_png,
};
use serde::Serialize;

use crate::drive_input::{
    PoseFileOptions, ScanPoses, open_kitti_raw, open_scans, poses_from_file, poses_from_odometry,
    poses_from_oxts, to_pipeline,
};
use crate::exit::BadInput;
use crate::input::read_params;

/// Arguments of `evigrid run`.
#[derive(Debug, Args)]
#[command(after_long_help = POSES_HELP)]
pub struct RunArgs {
    /// Vector map: OSM PBF, OSM XML (optionally gzipped) or GeoJSON. Without one the map prior is
    /// vacuous (the `no-map` variant) and the summary says so.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Directory of scans: PCD v0.7 (ascii or binary) or KITTI `.bin`, processed in file-name
    /// order (a folder holding a KITTI raw drive is read as --drive).
    #[arg(
        long,
        required_unless_present_any = ["drive", "bag"],
        conflicts_with_all = ["drive", "bag"]
    )]
    scans: Option<PathBuf>,
    /// A KITTI raw drive: its `<date>_drive_<NNNN>_sync` folder, or the date folder holding one.
    /// Scans, their timestamps, the OXTS poses and `calib_imu_to_velo.txt` are read from it.
    #[arg(long, conflicts_with = "bag")]
    drive: Option<PathBuf>,
    /// A ROS 2 recording (MCAP): `sensor_msgs/PointCloud2` scans with poses from tf, an
    /// Odometry or a NavSatFix topic (see --pose-source), or from the lidar odometry.
    #[arg(long, conflicts_with_all = ["poses", "times", "calib", "mounting"])]
    bag: Option<PathBuf>,
    /// The bag's PointCloud2 topic (default: the only one).
    #[arg(long, requires = "bag", value_name = "TOPIC")]
    cloud_topic: Option<String>,
    /// Where a bag's poses come from: auto (tf, else odometry, else NavSatFix, else the lidar
    /// odometry), none (the lidar odometry), tf[:FIXED_FRAME], odom[:TOPIC], navsat[:TOPIC].
    #[arg(long, requires = "bag", value_name = "SOURCE")]
    pose_source: Option<String>,
    /// Pose file: evigrid (7 columns), TUM (8) or KITTI odometry (12), matched to scans by time
    /// (see below). Without it, a KITTI raw drive's OXTS poses, or else the lidar odometry.
    #[arg(long)]
    poses: Option<PathBuf>,
    /// Pose file format: `evigrid`, `tum` or `kitti`; by default from its column count.
    #[arg(long, value_name = "FORMAT")]
    pose_format: Option<String>,
    /// KITTI odometry `calib.txt` (its `Tr`, camera 0 from Velodyne) for KITTI odometry pose
    /// files; without it they are read as the sensor's own poses.
    #[arg(long)]
    calib: Option<PathBuf>,
    /// Scan times: a KITTI raw `timestamps.txt` or a KITTI odometry `times.txt`, one per scan.
    /// By default a `timestamps.txt` beside or in the scan folder, if any.
    #[arg(long)]
    times: Option<PathBuf>,
    /// Where the sensor sits on the vehicle whose poses --poses gives, `x,y,z,roll,pitch,yaw`
    /// (metres, radians; vehicle x forward, y left, z up).
    #[arg(long, value_name = "X,Y,Z,ROLL,PITCH,YAW", allow_hyphen_values = true)]
    mounting: Option<String>,
    /// Process only the first N scans.
    #[arg(long, value_name = "N")]
    max_frames: Option<usize>,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Parameters (TOML, any subset of SPEC §7's layout); defaults otherwise.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Origin of the map's local frame as `LAT,LON` in degrees; by default the map's centre, or
    /// a KITTI raw drive's first OXTS fix. Without a map, WGS84 poses need it.
    #[arg(long, value_name = "LAT,LON", allow_hyphen_values = true)]
    origin: Option<String>,
    /// Print the summary as JSON on standard output (and no per-frame lines).
    #[arg(long)]
    json: bool,
    /// The fusion: `evigrid` (the paper's method with motion evidence, docs/motion.md) or
    /// `kurdej2013` (the paper's method exactly, SPEC §5).
    #[arg(long, default_value = "evigrid", value_parser = ["evigrid", "kurdej2013"])]
    method: String,
    /// Stop at the first unreadable scan or refused pose instead of skipping it.
    #[arg(long)]
    strict: bool,
    /// Write into an existing --out folder that is not an evigrid output folder.
    #[arg(long)]
    force: bool,
    /// Do not write the Foxglove recording `run.mcap` (written by default).
    #[arg(long)]
    no_mcap: bool,
}

const POSES_HELP: &str = "\
Where poses come from:
  --poses FILE          a pose file (formats below)
  --drive DIR           without --poses: the OXTS GNSS/INS poses of the KITTI raw drive, with the
                        Velodyne's lever arm from calib_imu_to_velo.txt
  neither               the lidar odometry, run over the scans first (poses in the first scan's
                        frame, so no --map)

Pose file formats (--poses, detected from the column count, or --pose-format):
  evigrid  t x y z roll pitch yaw      metres in the map's local frame (x east, y north, z up),
                                       radians, R = Rz(yaw)·Ry(pitch)·Rx(roll); after a line
                                       `# frame: wgs84`: t lat lon alt roll pitch yaw (degrees)
  tum      t x y z qx qy qz qw         unit quaternion of world_from_sensor
  kitti    12 numbers, the 3x4 world_from_cam0 matrix per line, no times; with --calib the
           sequence's calib.txt turns it into the Velodyne's poses, without it the matrix is the
           sensor's pose itself (as `evigrid odometry --format kitti` writes it)
  With --mounting the file gives the vehicle's poses and the sensor sits there on it.

Matching poses to scans:
  Scans have times from a KITTI raw drive, from --times, or from a timestamps.txt beside the scan
  folder (KITTI raw's velodyne_points/{data/, timestamps.txt}) or in it (also times.txt). Then
  each scan takes the pose at its time, interpolated between the two poses around it (linear
  position, slerp rotation); a scan outside the poses' time span (beyond 1 ms) is an error naming
  it. Scans without times take pose line k for scan k (the counts must agree) and its time; KITTI
  odometry files have no times and then take the scans 0.1 s apart.

Outputs (in --out):
  frames/decision-NNNNNN.png   decision map per frame (north up, one pixel per cell)
  decision.png                 final decision map for people: enlarged (>= 800 px), Okabe-Ito
                               colours, legend, scale bar, north arrow, map outlines, ego path
  pignistic.png                final betP colour mix;  trace.png  moving objects over the drive
                               (both drawn as decision.png)
  run.mcap                     Foxglove recording: per frame the decision grid, the pose, the scan,
                               the GNSS fix (KITTI raw); the map's outlines (not with --no-mcap)
  occupancy.json               final decided grid, ROS 2 nav_msgs/OccupancyGrid as JSON
  classes.json                 final decided class per cell (0 unknown, 1 F, 2 I, 3 U, 4 S, 5 M)
  masses.json, masses.bin      final masses, one little-endian float32 field per focal set
                               (foxglove.Grid JSON layout)
  map.pgm, map.yaml            final decided grid for nav2's map_server (trinary)
  decision-map.png, .pgw, .prj final decision map georeferenced for QGIS (with a local frame)
  frames.jsonl                 one JSON object per frame, written as the run goes: timing, counts,
                               ground and obstacle shares, the ego-path check, the objects judged
                               moving (id, position, velocity)
  summary.json                 parameters, totals over the drive (complete: false and stopped: why
                               when it ended early), skipped scans";

/// Per-frame record of the summary.
#[derive(Debug, Serialize)]
struct FrameRecord {
    scan: String,
    time_s: f64,
    /// The sensor's position in the world frame, metres: the pose the grids were built with
    /// (after the `[localisation]` refinement).
    position: [f64; 3],
    /// The position as given (pose file, bag, OXTS, odometry), metres.
    given_position: [f64; 3],
    read_ms: f64,
    process_ms: f64,
    render_ms: f64,
    stats: FrameStats,
    /// Cells per decision: unknown, F, I, U, S, M.
    classes: [usize; 6],
    /// Ground points over the scan's points.
    ground_share: f64,
    /// Obstacle points over the scan's points.
    obstacle_share: f64,
    /// Obstacle points over the finite points within the sensor's range.
    obstacle_share_in_range: f64,
    /// Cells the scan marked occupied over the cells it observed (occupied or free): an area
    /// measure, which a wall beside the car does not inflate as it does the point shares.
    obstacle_cell_share: f64,
    /// Cells within `EGO_PATH_RADIUS_M` of the ego's path over the next `EGO_PATH_LENGTH_M`.
    ego_path: EgoPathCheck,
    /// Of the observed ego-path cells, the share decided I, U, S or M (`null`: none observed).
    ego_path_share: Option<f64>,
    /// The objects the `evigrid` method judged moving, with their velocity (empty for
    /// `kurdej2013`).
    moving_objects: Vec<evigrid::motion::MovingObject>,
}

/// Totals of the ego-path check over the drive.
#[derive(Debug, Serialize)]
struct EgoPathTotals {
    length_m: f64,
    radius_m: f64,
    /// Observed ego-path cells summed over the frames.
    cell_frames: usize,
    occupied: usize,
    moving: usize,
    /// Of `moving`, the cells whose velocity this frame points along the path (within 45°):
    /// traffic ahead going the ego's way. `null` for `kurdej2013`, which estimates no velocity.
    moving_along_path: Option<usize>,
    /// `occupied + moving`.
    decided_occupied_or_moving: usize,
    /// `decided_occupied_or_moving / cell_frames`.
    share: Option<f64>,
    /// `moving / cell_frames`.
    moving_share: Option<f64>,
    /// `(moving - moving_along_path) / cell_frames`: the moving cells the path must not hold
    /// (not traffic ahead). `null` for `kurdej2013`.
    moving_apart_from_traffic_share: Option<f64>,
}

/// A scan the run skipped, and why.
#[derive(Debug, Serialize)]
struct SkippedScan {
    scan: String,
    error: String,
}

/// The summary written to `summary.json` (and to stdout with `--json`).
#[derive(Debug, Serialize)]
struct Summary {
    /// False when the run stopped early (`stopped` says why): the grids and pictures are those
    /// of the last frame processed.
    complete: bool,
    /// Why the run stopped before the last scan (a signal, an error); `null` when complete.
    stopped: Option<String>,
    /// Scans left out (unreadable, or their pose refused), with the reason; the run goes on
    /// without them unless `--strict`.
    skipped_scans: Vec<SkippedScan>,
    /// The map, or `null` for a run without one.
    map: Option<String>,
    /// The fusion: `evigrid` (with motion evidence) or `kurdej2013` (SPEC §5 exactly).
    method: String,
    /// `map`, or `vacuous (no map)`: what the GISGrid held.
    prior: &'static str,
    map_stats: Option<geodata::MapStats>,
    scans: String,
    /// The pose file, or where the poses came from (`OXTS of …`, `lidar odometry`).
    poses: String,
    /// How scans met poses: `time` (interpolated at the scan times) or `line order`.
    pose_matching: &'static str,
    params: Params,
    frames: usize,
    points: usize,
    dropped_non_finite: usize,
    dropped_out_of_range: usize,
    dropped_outside_window: usize,
    /// Obstacle returns of a 3-D lidar dropped as stray (`sensor.min_neighbourhood_returns`).
    stray_obstacle_points: usize,
    total_seconds: f64,
    /// Seconds of the odometry's first pass (0 when poses were given).
    odometry_seconds: f64,
    mean_process_ms: f64,
    /// Final cells per decision: unknown, F, I, U, S, M.
    final_classes: [usize; 6],
    moving_trace_cells: usize,
    ego_path: EgoPathTotals,
    /// Median over frames of `obstacle_share` and the worst frame's ratio to it.
    obstacle_share: Option<ShareSpread>,
    /// The same for `obstacle_share_in_range`.
    obstacle_share_in_range: Option<ShareSpread>,
    /// The same for `obstacle_cell_share`.
    obstacle_cell_share: Option<ShareSpread>,
    /// What the pose refinement did (`[localisation]`); `null` when it is off.
    pose_refinement: Option<RefinementTotals>,
    /// The per-frame records, one JSON object per line, written as the run goes (so that an
    /// interrupted run keeps them, and memory does not grow with the drive).
    frames_file: &'static str,
    /// The output folder.
    out: String,
}

/// The pose refinement over the drive.
#[derive(Debug, Serialize)]
struct RefinementTotals {
    /// Frames per outcome: `refined`, `first`, or why the pose was kept as given
    /// (`kept_too_far`, `kept_failed`, `kept_low_overlap`, `kept_no_data`).
    outcomes: BTreeMap<String, usize>,
    /// Over the refined frames: the median horizontal correction, metres, the largest and its
    /// frame (0-based).
    median_correction_m: Option<f64>,
    largest_correction_m: Option<f64>,
    largest_correction_frame: Option<usize>,
}

/// What the summary adds up over the frames, kept as the run goes (constant memory).
#[derive(Debug, Default)]
struct RunningTotals {
    frames: usize,
    points: usize,
    dropped_non_finite: usize,
    dropped_out_of_range: usize,
    dropped_outside_window: usize,
    stray_obstacle_points: usize,
    process_ms: f64,
    ego_path: EgoPathCheck,
    obstacle_share: ShareTracker,
    obstacle_share_in_range: ShareTracker,
    obstacle_cell_share: ShareTracker,
    refinement_outcomes: BTreeMap<String, usize>,
    /// Corrections as a fraction of `max_correction_m` (the gate bounds them), NaN for frames
    /// not refined.
    refinement_corrections: ShareTracker,
    /// `[localisation] max_correction_m`.
    max_correction_m: f64,
}

impl RunningTotals {
    fn add(&mut self, f: &FrameRecord) {
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
}

/// Name of the per-frame records in the output folder.
const FRAMES_FILE: &str = "frames.jsonl";

/// Runs `evigrid run`.
pub fn run(args: RunArgs) -> Result<()> {
    let started = Instant::now();
    // Validated as it is read: the defaults are valid by construction.
    let mut params = read_params(args.config.as_deref())?;
    let origin = args.origin.as_deref().map(parse_origin).transpose()?;
    let pose_format = args
        .pose_format
        .as_deref()
        .map(|f| {
            f.parse::<PoseFormat>()
                .map_err(|e| BadInput::new(format!("--pose-format: {e}")))
        })
        .transpose()?;
    let mounting = args
        .mounting
        .as_deref()
        .map(|m| {
            m.parse::<Mounting>()
                .map_err(|e| BadInput::new(format!("--mounting: {e}")))
        })
        .transpose()?;
    if args.poses.is_none() {
        for (given, flag) in [
            (mounting.is_some(), "--mounting"),
            (pose_format.is_some(), "--pose-format"),
            (args.calib.is_some(), "--calib"),
        ] {
            if given {
                return Err(BadInput::new(format!(
                    "{flag} describes --poses, not given"
                )));
            }
        }
    }
    if args.max_frames == Some(0) {
        return Err(BadInput::new("--max-frames must be at least 1"));
    }
    let bag = match &args.bag {
        Some(path) => Some(crate::drive_input::open_bag(
            path,
            args.cloud_topic.clone(),
            args.pose_source.as_deref(),
        )?),
        None => None,
    };
    let mut scans = match (&bag, &args.drive, &args.scans) {
        (Some(bag), _, _) => crate::drive_input::bag_scan_set(bag),
        (None, Some(dir), _) => {
            if args.times.is_some() {
                return Err(BadInput::new(
                    "--times: a KITTI raw --drive has its own scan timestamps",
                ));
            }
            open_kitti_raw(dir)?
        }
        (None, None, Some(dir)) => open_scans(dir, args.times.as_deref())?,
        (None, None, None) => return Err(BadInput::new("give --scans, --drive or --bag")),
    };
    let scans_name = args
        .drive
        .as_ref()
        .or(args.scans.as_ref())
        .or(args.bag.as_ref())
        .map(|p| p.display().to_string())
        .unwrap_or_default();

    // Checked before any work (a wrong --out must not cost the run), created once every input
    // has been checked (a bad input leaves no folder behind).
    crate::out_dir::OutDir::check(&args.out, args.force)?;
    let interrupt = crate::interrupt::Interrupt::install();

    let loaded = match &args.map {
        Some(map) => Some(
            geodata::load_map(map, &geodata::LoadOptions { origin })
                .map_err(|e| BadInput::new(e.to_string()))?,
        ),
        None => None,
    };
    if let Some(loaded) = &loaded {
        let e = &loaded.stats.extent_m;
        tracing::info!(
            "map: {} buildings, {} road polygons, {:.0} m x {:.0} m",
            loaded.stats.buildings,
            loaded.map.roads.len(),
            e.width_m,
            e.height_m
        );
    }
    let raster = loaded
        .as_ref()
        .map(|loaded| geodata::ContextRaster::new(&loaded.map));
    // The local frame: the map's; else --origin; else a KITTI raw drive's first fix.
    let first_fix = scans
        .kitti
        .as_ref()
        .and_then(|d| d.oxts().first().map(|p| (p.lat_deg, p.lon_deg)));
    let projection = match (&loaded, origin.or(first_fix)) {
        (Some(loaded), _) => Some(loaded.projection),
        (None, Some((lat, lon))) => Some(
            geodata::TransverseMercator::new(lat, lon)
                .map_err(|e| BadInput::new(format!("origin of the local frame: {e}")))?,
        ),
        (None, None) => None,
    };
    let project = |lat: f64, lon: f64| match &projection {
        Some(p) => p.forward(lat, lon),
        None => (f64::NAN, f64::NAN),
    };
    let project_dyn: &dyn Fn(f64, f64) -> (f64, f64) = &project;

    let mut odometry_seconds = 0.0;
    let mut odometry_skipped: Vec<(PathBuf, String)> = Vec::new();
    let mut early_stop: Option<(String, anyhow::Error)> = None;
    let (poses, poses_name, pose_matching): (ScanPoses, String, &str) = match (&args.poses, &bag) {
        (Some(path), _) => {
            let options = PoseFileOptions {
                path,
                format: pose_format,
                calib: args.calib.as_deref(),
                mounting,
            };
            let matching = if scans.times.is_some() {
                "time"
            } else {
                "line order"
            };
            let poses = poses_from_file(
                &scans,
                &options,
                projection.is_some().then_some(project_dyn),
                args.max_frames.unwrap_or(usize::MAX),
            )?;
            (poses, path.display().to_string(), matching)
        }
        (None, Some(bag)) if !matches!(bag.poses(), drive::bag::BagPoses::None) => {
            let poses = crate::drive_input::poses_from_bag(
                bag,
                projection.is_some().then_some(project_dyn),
                args.max_frames.unwrap_or(usize::MAX),
            )?;
            (
                poses,
                format!("{} of {}", bag.pose_source(), bag.path().display()),
                "time",
            )
        }
        (None, _) => match &scans.kitti {
            Some(drive) => (
                poses_from_oxts(drive, project_dyn)?,
                format!("OXTS of {}", drive.drive_dir().display()),
                "time",
            ),
            None => {
                if let Some(map) = &args.map {
                    return Err(BadInput::new(format!(
                        "--map {}: poses from the lidar odometry are in the first scan's frame, \
                         not the map's; give --poses",
                        map.display()
                    )));
                }
                if let Some(n) = args.max_frames {
                    scans.truncate(n);
                }
                let bar = crate::progress::bar(scans.paths.len() as u64, "odometry");
                let t0 = Instant::now();
                let registered = match &bag {
                    Some(bag) => crate::drive_input::poses_from_bag_odometry(
                        bag,
                        OdometryParams::default(),
                        scans.paths.len(),
                        &|| interrupt.requested(),
                        |_| bar.inc(1),
                    ),
                    None => poses_from_odometry(
                        &mut scans,
                        OdometryParams::default(),
                        args.strict,
                        &mut odometry_skipped,
                        &|| interrupt.requested(),
                        |_| bar.inc(1),
                    ),
                };
                let poses = match registered {
                    Ok(poses) => poses,
                    // Stopped in the first pass (a signal, or a bad scan with --strict): no
                    // frame is run, and the summary still says so.
                    Err(error) => {
                        early_stop = Some((format!("odometry pass: {error}"), error));
                        ScanPoses {
                            times: Vec::new(),
                            world_from_sensor: Vec::new(),
                        }
                    }
                };
                bar.finish_and_clear();
                odometry_seconds = t0.elapsed().as_secs_f64();
                (poses, "lidar odometry".to_string(), "odometry")
            }
        },
    };
    let ScanPoses {
        mut times,
        world_from_sensor: mut nalgebra_poses,
    } = poses;
    // The ego's path: every pose is known before the run, those after --max-frames too.
    let positions: Vec<[f64; 2]> = nalgebra_poses
        .iter()
        .map(|p| [p.translation.x, p.translation.y])
        .collect();
    if let Some(n) = args.max_frames {
        scans.truncate(n);
        times.truncate(n);
        nalgebra_poses.truncate(n);
    }
    let poses: Vec<evigrid::Isometry3> = nalgebra_poses.iter().map(to_pipeline).collect();
    // Poses from the lidar odometry are already registrations of these scans: refining them
    // against a second map of the same scans would spend a registration to change nothing.
    if pose_matching == "odometry" && params.localisation.refinement != PoseRefinement::None {
        params.localisation.refinement = PoseRefinement::None;
        tracing::info!("poses from the lidar odometry: [localisation] refinement is not applied");
    }

    if let Some(loaded) = &loaded {
        check_poses_on_map(&poses, &loaded.map.extent).map_err(|e| {
            BadInput::new(format!(
                "{poses_name}: {e} of the map {}",
                args.map.as_deref().unwrap_or(Path::new("")).display()
            ))
        })?;
    }

    tracing::info!(
        "{} scans from {scans_name}; poses: {poses_name} (matched by {pose_matching}); prior: {}",
        scans.paths.len(),
        if loaded.is_some() {
            "map"
        } else {
            "vacuous (no map)"
        }
    );
    let out_dir = crate::out_dir::OutDir::prepare(&args.out, args.force, "run")?;
    let frames_dir = args.out.join("frames");
    fs::create_dir_all(&frames_dir)
        .with_context(|| format!("cannot create {}", frames_dir.display()))?;
    let method = if args.method == "kurdej2013" {
        evigrid::Method::Kurdej2013
    } else {
        evigrid::Method::Evigrid
    };
    let mut pipeline = Pipeline::with_method(params.clone(), raster, method)
        .map_err(|e| BadInput::new(format!("{}: {e}", config_name(&args))))?;

    let mut recorder = if args.no_mcap {
        None
    } else {
        Some(McapRecorder::create(
            &args.out.join("run.mcap"),
            loaded.as_ref().map(|l| &l.map),
        )?)
    };
    let progress = crate::progress::bar(scans.paths.len() as u64, "run");
    let mut totals = RunningTotals {
        max_correction_m: params.localisation.max_correction_m,
        ..RunningTotals::default()
    };
    let frames_path = args.out.join(FRAMES_FILE);
    let mut frames_log = std::io::BufWriter::new(
        fs::File::create(&frames_path)
            .with_context(|| format!("cannot create {}", frames_path.display()))?,
    );
    let mut skipped: Vec<SkippedScan> = odometry_skipped
        .into_iter()
        .map(|(path, error)| SkippedScan {
            scan: file_name(&path),
            error,
        })
        .collect();
    // Why the run stopped early, and the error to return once what was done is written.
    let mut stopped: Option<(String, anyhow::Error)> = early_stop;
    // Scans reached (processed or skipped): the ego's path so far, for the final figures.
    let mut reached = 0;
    let mut reader = crate::drive_input::ScanReader::new(bag.as_ref())?;
    for (k, ((path, pose), &time_s)) in scans.paths.iter().zip(&poses).zip(&times).enumerate() {
        if interrupt.requested() {
            stopped = Some((
                "interrupted (SIGINT or SIGTERM)".into(),
                crate::interrupt::Interrupted.into(),
            ));
            break;
        }
        reached = k + 1;
        let t0 = Instant::now();
        // A bad scan or a refused pose is the input's fault: skipped (or, with --strict, the
        // end of the run); anything else stops the run.
        let frame = reader.read(path).and_then(|scan| {
            let t1 = Instant::now();
            pipeline
                .process(&scan.points_in_sensor, pose, time_s)
                .map(|stats| (stats, t1, scan))
                .map_err(|e| format!("{poses_name}: pose of scan {}: {e}", path.display()))
        });
        let (stats, t1, scan) = match frame {
            Ok(frame) => frame,
            Err(error) => {
                if args.strict {
                    stopped = Some((error.clone(), BadInput::new(error)));
                    break;
                }
                tracing::debug!("skipped: {error}");
                skipped.push(SkippedScan {
                    scan: file_name(path),
                    error,
                });
                progress.inc(1);
                continue;
            }
        };
        let t2 = Instant::now();
        if let Some(recorder) = &mut recorder {
            let fix = scans.kitti.as_ref().and_then(|d| {
                let (packet, &time_s) = d.oxts().get(k).zip(d.oxts_times().get(k))?;
                Some(GnssFix {
                    time_s,
                    lat_deg: packet.lat_deg,
                    lon_deg: packet.lon_deg,
                    alt_m: packet.alt_m,
                })
            });
            let recorded = recorder.write_frame(&McapFrame {
                time_s,
                window: pipeline.window(),
                decisions: pipeline.decisions(),
                perception: pipeline.perception(),
                world_from_sensor: pipeline.front_end().world_from_sensor(),
                points_in_sensor: &scan.points_in_sensor,
                fix,
            });
            if let Err(error) = recorded {
                stopped = Some((format!("recording frame {k}: {error}"), error.into()));
                break;
            }
        }
        let ego_polyline = path_ahead(&positions, k, EGO_PATH_LENGTH_M);
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
        let written = decision_image(
            pipeline.window(),
            pipeline.decisions(),
            &ClassColours::THREE_CLASSES,
        )
        .and_then(|image| write_png(&image, &frames_dir.join(format!("decision-{k:06}.png"))));
        if let Err(error) = written {
            stopped = Some((format!("writing frame {k}: {error}"), error.into()));
            break;
        }
        let t3 = Instant::now();
        let s = &stats.sensor;
        let share = |n: usize, of: usize| if of > 0 { n as f64 / of as f64 } else { 0.0 };
        let in_range = s
            .points
            .saturating_sub(s.dropped_non_finite + s.dropped_out_of_range);
        let record = FrameRecord {
            scan: file_name(path),
            time_s,
            position: pipeline.front_end().world_from_sensor().translation,
            given_position: pose.translation,
            read_ms: ms(t1 - t0),
            process_ms: ms(t2 - t1),
            render_ms: ms(t3 - t2),
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
        };
        if !args.json {
            let line = frame_line(k, &record);
            progress.suspend(|| println!("{line}"));
        }
        let logged = serde_json::to_writer(&mut frames_log, &record)
            .map_err(std::io::Error::from)
            .and_then(|()| std::io::Write::write_all(&mut frames_log, b"\n"));
        if let Err(error) = logged {
            let why = format!("{}: {error}", frames_path.display());
            stopped = Some((why.clone(), anyhow::anyhow!(why)));
            break;
        }
        tracing::debug!(
            "frame {k}: read {:.1} ms, process {:.1} ms, render {:.1} ms",
            record.read_ms,
            record.process_ms,
            record.render_ms
        );
        totals.add(&record);
        progress.inc(1);
    }
    progress.finish_and_clear();
    if let Err(error) = std::io::Write::flush(&mut frames_log)
        && stopped.is_none()
    {
        let why = format!("{}: {error}", frames_path.display());
        stopped = Some((why.clone(), anyhow::anyhow!(why)));
    }
    drop(frames_log);
    if totals.frames == 0
        && stopped.is_none()
        && let Some(first) = skipped.first()
    {
        let error = format!(
            "no scan could be used ({} skipped; the first: {})",
            skipped.len(),
            first.error
        );
        stopped = Some((error.clone(), BadInput::new(error)));
    }
    // The final pictures and grids are written even after an early stop (they are the last
    // processed frame's); a failure here is kept, and the summary is still attempted.
    // The recording is closed even after an early stop: what it holds stays readable.
    if let Some(recorder) = recorder.take()
        && let Err(error) = recorder.finish()
        && stopped.is_none()
    {
        stopped = Some((format!("closing run.mcap: {error}"), error.into()));
    }
    let driven = &positions[..reached.min(positions.len())];
    let exports_time_s = times[..reached.min(times.len())]
        .last()
        .copied()
        .unwrap_or(0.0);
    if let Err(error) = write_final_outputs(
        &pipeline,
        &args.out,
        driven,
        exports_time_s,
        projection.as_ref(),
    ) && stopped.is_none()
    {
        stopped = Some((format!("writing the final outputs: {error}"), error));
    }

    let ego_total = &totals.ego_path;
    let refining = params.localisation.refinement != PoseRefinement::None;
    // Only the motion stage (`evigrid`, not `kurdej2013`) gives cells a velocity.
    let estimates_velocity = pipeline.fusion().motion().is_some();
    let summary = Summary {
        complete: stopped.is_none(),
        stopped: stopped.as_ref().map(|(why, _)| why.clone()),
        skipped_scans: skipped,
        map: args.map.as_ref().map(|m| m.display().to_string()),
        method: args.method.clone(),
        prior: if loaded.is_some() {
            "map"
        } else {
            "vacuous (no map)"
        },
        map_stats: loaded.map(|loaded| loaded.stats),
        scans: scans_name,
        poses: poses_name,
        pose_matching,
        params,
        frames: totals.frames,
        points: totals.points,
        dropped_non_finite: totals.dropped_non_finite,
        dropped_out_of_range: totals.dropped_out_of_range,
        dropped_outside_window: totals.dropped_outside_window,
        stray_obstacle_points: totals.stray_obstacle_points,
        total_seconds: started.elapsed().as_secs_f64(),
        odometry_seconds,
        mean_process_ms: if totals.frames == 0 {
            0.0
        } else {
            totals.process_ms / totals.frames as f64
        },
        final_classes: count_decisions(pipeline.decisions()),
        moving_trace_cells: pipeline.trace().count(),
        ego_path: EgoPathTotals {
            length_m: EGO_PATH_LENGTH_M,
            radius_m: EGO_PATH_RADIUS_M,
            cell_frames: ego_total.observed_cells,
            occupied: ego_total.occupied_cells,
            moving: ego_total.moving_cells,
            moving_along_path: estimates_velocity.then_some(ego_total.moving_along_path),
            decided_occupied_or_moving: ego_total.decided_occupied_or_moving(),
            share: ego_total.share(),
            moving_share: ego_total.moving_share(),
            moving_apart_from_traffic_share: ego_total
                .moving_apart_from_traffic_share()
                .filter(|_| estimates_velocity),
        },
        obstacle_share: totals.obstacle_share.spread(),
        obstacle_share_in_range: totals.obstacle_share_in_range.spread(),
        obstacle_cell_share: totals.obstacle_cell_share.spread(),
        pose_refinement: refining.then(|| {
            let spread = totals.refinement_corrections.spread();
            let scale = totals.max_correction_m;
            RefinementTotals {
                outcomes: totals.refinement_outcomes.clone(),
                median_correction_m: spread.map(|s| s.median * scale),
                largest_correction_m: spread.map(|s| s.worst * scale),
                largest_correction_frame: spread.map(|s| s.worst_frame),
            }
        }),
        frames_file: FRAMES_FILE,
        out: args.out.display().to_string(),
    };
    let text = serde_json::to_string_pretty(&summary)?;
    let summary_path = args.out.join("summary.json");
    let summary_written = output::write_atomic(&summary_path, |file| {
        std::io::Write::write_all(file, text.as_bytes())
    });
    if let Some((why, error)) = stopped {
        // The summary says what was done; the error says why the run ended.
        let _ = why;
        let frames = format!(
            "run stopped after {} of {} frames",
            summary.frames,
            scans.paths.len()
        );
        let note = match summary_written {
            Ok(()) => format!(
                "{frames}, summary in {} (marked incomplete)",
                summary_path.display()
            ),
            Err(e) => format!("{frames}; the summary could not be written either ({e})"),
        };
        let _ = out_dir.finish();
        return Err(error.context(note));
    }
    summary_written?;
    out_dir.finish()?;
    if !summary.skipped_scans.is_empty() {
        eprintln!(
            "evigrid: {} scan(s) skipped, the first: {} (all in skipped_scans of {})",
            summary.skipped_scans.len(),
            summary.skipped_scans[0].error,
            summary_path.display()
        );
    }
    if args.json {
        println!("{text}");
    } else {
        let [unknown, f, i, u, s, m] = summary.final_classes;
        println!(
            "{} frames, {:.1} ms per frame; final cells: {f} free, {i} mapped infrastructure, \
             {u} unmapped infrastructure, {s} stopped, {m} moving, {unknown} unknown; prior: {}; \
             poses: {} (matched by {}); outputs in {}",
            summary.frames,
            summary.mean_process_ms,
            summary.prior,
            summary.poses,
            summary.pose_matching,
            args.out.display()
        );
        let e = &summary.ego_path;
        println!(
            "ego path ({} m ahead, {} m either side): {} of {} observed cell-frames decided \
             occupied or moving ({}; {} occupied, {} moving ({}){})",
            e.length_m,
            e.radius_m,
            e.decided_occupied_or_moving,
            e.cell_frames,
            percent(e.share),
            e.occupied,
            e.moving,
            percent(e.moving_share),
            e.moving_along_path
                .zip(e.moving_apart_from_traffic_share)
                .map(|(n, rest)| format!(
                    ", {n} of them traffic moving along the path, {} not ({} of the observed)",
                    e.moving.saturating_sub(n),
                    percent(Some(rest))
                ))
                .unwrap_or_default()
        );
        if let Some(r) = &summary.pose_refinement {
            let refined = r.outcomes.get("refined").copied().unwrap_or(0);
            let kept: Vec<String> = r
                .outcomes
                .iter()
                .filter(|(name, _)| name.starts_with("kept_"))
                .map(|(name, n)| {
                    format!("{n} {}", name.trim_start_matches("kept_").replace('_', " "))
                })
                .collect();
            let kept = if kept.is_empty() {
                String::new()
            } else {
                format!(", kept as given: {}", kept.join(", "))
            };
            let corrections = match (
                r.median_correction_m,
                r.largest_correction_m,
                r.largest_correction_frame,
            ) {
                (Some(median), Some(largest), Some(frame)) => format!(
                    "; correction median {median:.3} m, largest {largest:.3} m (frame {frame})"
                ),
                _ => String::new(),
            };
            println!(
                "pose refinement: {refined} of {} poses refined{kept}{corrections}",
                summary.frames
            );
        }
        for (spread, what) in [
            (&summary.obstacle_share, "of a scan's points are obstacles"),
            (
                &summary.obstacle_cell_share,
                "of the observed cells are occupied",
            ),
        ] {
            if let Some(spread) = spread {
                println!(
                    "median {:.1} % {what}; worst frame {} at {:.1} %, {} the median",
                    100.0 * spread.median,
                    spread.worst_frame,
                    100.0 * spread.worst,
                    spread
                        .worst_to_median
                        .map_or_else(|| "n/a ×".to_string(), |r| format!("{r:.2}×"))
                );
            }
        }
    }
    Ok(())
}

/// The final views and grids: decision, betP and trace pictures, the occupancy grid and masses.
fn write_final_outputs(
    pipeline: &Pipeline,
    out: &Path,
    driven: &[[f64; 2]],
    time_s: f64,
    projection: Option<&geodata::TransverseMercator>,
) -> Result<()> {
    let window = pipeline.window();
    // Figures for people: enlarged, legend, scale bar, north arrow, map outlines, the path so far.
    let views = output::run_figures::Views {
        window,
        perception: pipeline.perception(),
        decisions: pipeline.decisions(),
        trace: pipeline.trace(),
        motion: pipeline.fusion().motion(),
    };
    let gis = pipeline.has_map().then(|| pipeline.gis());
    for (name, image) in output::run_figures::final_figures(&views, gis, driven)? {
        write_png(&image, &out.join(name))?;
    }
    // For the tools of the field: ROS OccupancyGrid, classes, masses, nav2, georeferenced map.
    write_grid_exports(
        out,
        &GridExports {
            window,
            decisions: pipeline.decisions(),
            perception: pipeline.perception(),
            time_s,
            projection,
        },
    )?;
    Ok(())
}

/// The file name of a scan, for the summary.
fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// One frame's numbers on one line.
fn frame_line(k: usize, f: &FrameRecord) -> String {
    format!(
        "frame {k:>4} {}: points {:.1} % ground, {:.1} % obstacle; cells {:.1} % occupied; {} \
         cells decided moving; ego path {}/{} observed cells occupied or moving ({})",
        f.scan,
        100.0 * f.ground_share,
        100.0 * f.obstacle_share,
        100.0 * f.obstacle_cell_share,
        f.classes[5],
        f.ego_path.decided_occupied_or_moving(),
        f.ego_path.observed_cells,
        percent(f.ego_path_share)
    )
}

fn percent(share: Option<f64>) -> String {
    share.map_or_else(|| "n/a".to_string(), |s| format!("{:.2} %", 100.0 * s))
}

/// How far a pose may lie outside the map's extent: the sensor sees about this far, so a pose
/// farther out sees nothing of the map (a wrong map, origin or pose frame).
const MAP_MARGIN_M: f64 = 100.0;

/// The first pose farther than [`MAP_MARGIN_M`] outside the map's extent, as an error.
fn check_poses_on_map(
    poses: &[evigrid::Isometry3],
    extent: &geo::Rect<f64>,
) -> std::result::Result<(), String> {
    let (min, max) = (extent.min(), extent.max());
    for (k, pose) in poses.iter().enumerate() {
        let [x, y, _] = pose.translation;
        let dx = (min.x - x).max(x - max.x).max(0.0);
        let dy = (min.y - y).max(y - max.y).max(0.0);
        let distance_m = dx.hypot(dy);
        if distance_m > MAP_MARGIN_M || !distance_m.is_finite() {
            return Err(format!(
                "pose {} (scan {}) lies {distance_m:.0} m outside the extent",
                k + 1,
                k + 1
            ));
        }
    }
    Ok(())
}

fn config_name(args: &RunArgs) -> String {
    args.config.as_ref().map_or_else(
        || "default parameters".to_string(),
        |p| p.display().to_string(),
    )
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Parses `LAT,LON` in degrees.
fn parse_origin(text: &str) -> Result<(f64, f64)> {
    let bad = || BadInput::new(format!("--origin {text}: expected LAT,LON in degrees"));
    let (lat, lon) = text.split_once(',').ok_or_else(bad)?;
    let lat: f64 = lat.trim().parse().map_err(|_| bad())?;
    let lon: f64 = lon.trim().parse().map_err(|_| bad())?;
    if !((-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon)) {
        return Err(bad());
    }
    Ok((lat, lon))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn origin_is_lat_comma_lon() {
        assert_eq!(parse_origin("60.17, 24.94").unwrap(), (60.17, 24.94));
        assert!(parse_origin("60.17").is_err());
        assert!(parse_origin("95,0").is_err());
    }
}
