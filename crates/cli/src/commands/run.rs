//! `evigrid run`: the perception pipeline over a directory of scans, with a map.
//!
//! ```text
//! evigrid run --map city.osm.pbf --scans scans/ --poses poses.txt --out out/ [--config p.toml]
//! ```
//!
//! Wiring only: reading files, the progress bar, writing pictures and the summary. The work is
//! `evigrid::Pipeline`'s.

use std::fs;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use drive::{list_scans, read_scan};
use evigrid::Isometry3;
use evigrid::Params;
use evigrid::{FrameStats, Pipeline};
use output::{
    ClassColours, OccupancyGridExport, count_decisions, decision_image, pignistic_image,
    trace_image, write_masses, write_png,
};
use serde::Serialize;

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
    /// order.
    #[arg(long)]
    scans: PathBuf,
    /// Pose file: one line per scan, `timestamp x y z roll pitch yaw` in the map's local frame
    /// (seconds, metres, radians), or WGS84 after a `# frame: wgs84` line (see below).
    #[arg(long)]
    poses: PathBuf,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Parameters (TOML, any subset of SPEC §7's layout); defaults otherwise.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Origin of the map's local frame as `LAT,LON` in degrees; by default the map's centre.
    /// Without a map, WGS84 poses need it.
    #[arg(long, value_name = "LAT,LON", allow_hyphen_values = true)]
    origin: Option<String>,
    /// Print the summary as JSON on standard output.
    #[arg(long)]
    json: bool,
}

const POSES_HELP: &str = "\
Pose file (--poses):
  One line per scan, in the order of the scan files, blank lines and other `#` lines ignored:
    timestamp x y z roll pitch yaw
  with the sensor's position x (east), y (north), z (up) in metres in the map's local frame and
  roll, pitch, yaw in radians (ROS convention: R = Rz(yaw)·Ry(pitch)·Rx(roll), sensor x forward).
  A first line `# frame: wgs84` switches to
    timestamp lat lon alt roll pitch yaw
  with latitude and longitude in degrees, projected with the map's projection.

Outputs (in --out):
  frames/decision-NNNNNN.png   decision map per frame (north up, one pixel per cell)
  decision.png                 final decision map, I, U, S in three shades of blue
  pignistic.png                final betP colour mix;  trace.png  moving objects over the drive
  occupancy.json               final decided grid, ROS nav_msgs/OccupancyGrid layout
  masses.json, masses.bin      final masses, one float32 field per focal set (foxglove.Grid layout)
  summary.json                 parameters, per-frame timing and counts, final class counts";

/// One line of the pose file, in the map's local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PoseLine {
    time_s: f64,
    world_from_sensor: Isometry3,
}

/// Per-frame record of the summary.
#[derive(Debug, Serialize)]
struct FrameRecord {
    scan: String,
    time_s: f64,
    read_ms: f64,
    process_ms: f64,
    render_ms: f64,
    stats: FrameStats,
    /// Cells per decision: unknown, F, I, U, S, M.
    classes: [usize; 6],
}

/// The summary written to `summary.json` (and to stdout with `--json`).
#[derive(Debug, Serialize)]
struct Summary {
    /// The map, or `null` for a run without one.
    map: Option<String>,
    /// `map`, or `vacuous (no map)`: what the GISGrid held.
    prior: &'static str,
    map_stats: Option<geodata::MapStats>,
    scans: String,
    poses: String,
    params: Params,
    frames: usize,
    points: usize,
    dropped_non_finite: usize,
    dropped_out_of_range: usize,
    dropped_outside_window: usize,
    total_seconds: f64,
    mean_process_ms: f64,
    /// Final cells per decision: unknown, F, I, U, S, M.
    final_classes: [usize; 6],
    moving_trace_cells: usize,
    per_frame: Vec<FrameRecord>,
}

/// Runs `evigrid run`.
pub fn run(args: RunArgs) -> Result<()> {
    let started = Instant::now();
    // Validated as it is read: the defaults are valid by construction.
    let params = read_params(args.config.as_deref())?;
    let origin = args.origin.as_deref().map(parse_origin).transpose()?;
    let loaded = match &args.map {
        Some(map) => Some(
            geodata::load_map(map, &geodata::LoadOptions { origin })
                .map_err(|e| BadInput::new(e.to_string()))?,
        ),
        None => None,
    };
    let raster = loaded
        .as_ref()
        .map(|loaded| geodata::ContextRaster::new(&loaded.map));
    let projection = match (&loaded, origin) {
        (Some(loaded), _) => Some(loaded.projection),
        (None, Some((lat, lon))) => Some(
            geodata::TransverseMercator::new(lat, lon)
                .map_err(|e| BadInput::new(format!("--origin: {e}")))?,
        ),
        (None, None) => None,
    };
    let project = |lat: f64, lon: f64| {
        let (x, y) = projection.as_ref()?.forward(lat, lon);
        (x.is_finite() && y.is_finite()).then_some((x, y))
    };

    let scan_paths = list_scans(&args.scans).map_err(|e| BadInput::new(e.to_string()))?;
    if scan_paths.is_empty() {
        return Err(BadInput::new(format!(
            "{}: no .pcd or .bin scans in this directory",
            args.scans.display()
        )));
    }
    let pose_text = fs::read_to_string(&args.poses)
        .map_err(|e| BadInput::new(format!("{}: {e}", args.poses.display())))?;
    let poses = parse_poses(&pose_text, &project)
        .map_err(|e| BadInput::new(format!("{}: {e}", args.poses.display())))?;
    if poses.len() != scan_paths.len() {
        return Err(BadInput::new(format!(
            "{}: {} poses for {} scans in {}",
            args.poses.display(),
            poses.len(),
            scan_paths.len(),
            args.scans.display()
        )));
    }

    if let Some(loaded) = &loaded {
        check_poses_on_map(&poses, &loaded.map.extent).map_err(|e| {
            BadInput::new(format!(
                "{}: {e} of the map {}",
                args.poses.display(),
                args.map
                    .as_deref()
                    .unwrap_or(std::path::Path::new(""))
                    .display()
            ))
        })?;
    }

    let frames_dir = args.out.join("frames");
    fs::create_dir_all(&frames_dir)
        .with_context(|| format!("cannot create {}", frames_dir.display()))?;
    let mut pipeline = Pipeline::new(params.clone(), raster)
        .map_err(|e| BadInput::new(format!("{}: {e}", config_name(&args))))?;

    let progress = crate::progress::bar(scan_paths.len() as u64, "run");
    let mut per_frame = Vec::with_capacity(scan_paths.len());
    for (k, (path, pose)) in scan_paths.iter().zip(&poses).enumerate() {
        let t0 = Instant::now();
        let scan = read_scan(path).map_err(|e| BadInput::new(e.to_string()))?;
        let t1 = Instant::now();
        let stats = pipeline
            .process(&scan.points_in_sensor, &pose.world_from_sensor, pose.time_s)
            .map_err(|e| {
                BadInput::new(format!(
                    "{}: line for scan {}: {e}",
                    args.poses.display(),
                    k + 1
                ))
            })?;
        let t2 = Instant::now();
        let image = decision_image(
            pipeline.window(),
            pipeline.decisions(),
            &ClassColours::THREE_CLASSES,
        )?;
        write_png(&image, &frames_dir.join(format!("decision-{k:06}.png")))?;
        let t3 = Instant::now();
        per_frame.push(FrameRecord {
            scan: path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            time_s: pose.time_s,
            read_ms: ms(t1 - t0),
            process_ms: ms(t2 - t1),
            render_ms: ms(t3 - t2),
            stats,
            classes: count_decisions(pipeline.decisions()),
        });
        progress.inc(1);
    }
    progress.finish_and_clear();

    let window = pipeline.window();
    let five = ClassColours::FIVE_CLASSES;
    write_png(
        &decision_image(window, pipeline.decisions(), &five)?,
        &args.out.join("decision.png"),
    )?;
    write_png(
        &pignistic_image(window, pipeline.perception(), &five)?,
        &args.out.join("pignistic.png"),
    )?;
    write_png(
        &trace_image(
            window,
            pipeline.decisions(),
            pipeline.trace(),
            &ClassColours::THREE_CLASSES,
        )?,
        &args.out.join("trace.png"),
    )?;
    OccupancyGridExport::new(window, pipeline.decisions(), "map")?
        .write(&args.out.join("occupancy.json"))?;
    write_masses(
        window,
        pipeline.perception(),
        "map",
        &args.out.join("masses.json"),
    )?;

    let sum = |f: fn(&FrameRecord) -> usize| per_frame.iter().map(f).sum::<usize>();
    let summary = Summary {
        map: args.map.as_ref().map(|m| m.display().to_string()),
        prior: if loaded.is_some() {
            "map"
        } else {
            "vacuous (no map)"
        },
        map_stats: loaded.map(|loaded| loaded.stats),
        scans: args.scans.display().to_string(),
        poses: args.poses.display().to_string(),
        params,
        frames: per_frame.len(),
        points: sum(|f| f.stats.sensor.points),
        dropped_non_finite: sum(|f| f.stats.sensor.dropped_non_finite),
        dropped_out_of_range: sum(|f| f.stats.sensor.dropped_out_of_range),
        dropped_outside_window: sum(|f| f.stats.sensor.dropped_outside_window),
        total_seconds: started.elapsed().as_secs_f64(),
        mean_process_ms: per_frame.iter().map(|f| f.process_ms).sum::<f64>()
            / per_frame.len() as f64,
        final_classes: count_decisions(pipeline.decisions()),
        moving_trace_cells: pipeline.trace().count(),
        per_frame,
    };
    let text = serde_json::to_string_pretty(&summary)?;
    let summary_path = args.out.join("summary.json");
    output::write_atomic(&summary_path, |file| {
        std::io::Write::write_all(file, text.as_bytes())
    })?;
    if args.json {
        println!("{text}");
    } else {
        let [unknown, f, i, u, s, m] = summary.final_classes;
        println!(
            "{} frames, {:.1} ms per frame; final cells: {f} free, {i} mapped infrastructure, \
             {u} unmapped infrastructure, {s} stopped, {m} moving, {unknown} unknown; prior: {}; \
             outputs in {}",
            summary.frames,
            summary.mean_process_ms,
            summary.prior,
            args.out.display()
        );
    }
    Ok(())
}

/// How far a pose may lie outside the map's extent: the sensor sees about this far, so a pose
/// farther out sees nothing of the map (a wrong map, origin or pose frame).
const MAP_MARGIN_M: f64 = 100.0;

/// The first pose farther than [`MAP_MARGIN_M`] outside the map's extent, as an error.
fn check_poses_on_map(
    poses: &[PoseLine],
    extent: &geo::Rect<f64>,
) -> std::result::Result<(), String> {
    let (min, max) = (extent.min(), extent.max());
    for (k, pose) in poses.iter().enumerate() {
        let [x, y, _] = pose.world_from_sensor.translation;
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

/// Parses the pose file; `project` maps WGS84 (lat, lon) in degrees to local (x, y) metres.
fn parse_poses(
    text: &str,
    project: &dyn Fn(f64, f64) -> Option<(f64, f64)>,
) -> std::result::Result<Vec<PoseLine>, String> {
    let mut wgs84 = false;
    let mut poses = Vec::new();
    for (number, line) in text.lines().enumerate().map(|(i, l)| (i + 1, l.trim())) {
        if line.is_empty() {
            continue;
        }
        if let Some(comment) = line.strip_prefix('#') {
            if let Some(frame) = comment.trim().strip_prefix("frame:") {
                wgs84 = match frame.trim() {
                    "wgs84" => true,
                    "local" => false,
                    other => {
                        return Err(format!(
                            "line {number}: unknown frame `{other}` (wgs84 or local)"
                        ));
                    }
                };
            }
            continue;
        }
        let values: Vec<f64> = line
            .split_whitespace()
            .map(|w| {
                w.parse::<f64>()
                    .map_err(|_| format!("line {number}: `{w}` is not a number"))
            })
            .collect::<std::result::Result<_, _>>()?;
        let [time_s, a, b, z, roll, pitch, yaw] = values[..] else {
            return Err(format!(
                "line {number}: expected 7 numbers, found {}",
                values.len()
            ));
        };
        if !values.iter().all(|v| v.is_finite()) {
            return Err(format!("line {number}: values must be finite"));
        }
        let (x, y) = if wgs84 {
            project(a, b).ok_or_else(|| {
                format!(
                    "line {number}: cannot project lat {a}, lon {b} (WGS84 poses need --map or \
                         --origin)"
                )
            })?
        } else {
            (a, b)
        };
        poses.push(PoseLine {
            time_s,
            world_from_sensor: Isometry3::from_xyz_rpy(x, y, z, roll, pitch, yaw),
        });
    }
    Ok(poses)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn poses_in_local_and_wgs84_frames() {
        let local = "# a comment\n0.0 1 2 3 0 0 0\n\n0.1 1.5 2 3 0 0 1.5707963267948966\n";
        let poses = parse_poses(local, &|_, _| None).unwrap();
        assert_eq!(poses.len(), 2);
        assert_eq!(poses[1].time_s, 0.1);
        assert_eq!(poses[1].world_from_sensor.translation, [1.5, 2.0, 3.0]);
        let wgs = "# frame: wgs84\n5.0 60.17 24.94 10 0 0 0\n";
        let poses = parse_poses(wgs, &|lat, lon| Some((lon * 10.0, lat * 10.0))).unwrap();
        assert_eq!(poses[0].world_from_sensor.translation, [249.4, 601.7, 10.0]);
        assert!(
            parse_poses("0 1 2 3\n", &|_, _| None)
                .unwrap_err()
                .contains("line 1")
        );
        assert!(
            parse_poses("0 1 2 x 0 0 0\n", &|_, _| None)
                .unwrap_err()
                .contains("`x`")
        );
        assert!(parse_poses("# frame: utm\n", &|_, _| None).is_err());
        assert!(parse_poses("# frame: wgs84\n0 1 2 3 0 0 0\n", &|_, _| None).is_err());
    }

    #[test]
    fn origin_is_lat_comma_lon() {
        assert_eq!(parse_origin("60.17, 24.94").unwrap(), (60.17, 24.94));
        assert!(parse_origin("60.17").is_err());
        assert!(parse_origin("95,0").is_err());
    }
}
