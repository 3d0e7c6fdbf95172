//! The flags of `evigrid run`, and the drive they name.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use drive::DriveSpec;
use drive::poses::{Mounting, PoseFormat};
use drive::source::PoseFileSpec;

use crate::exit::BadInput;

/// The fusion a run uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// The paper's method with motion evidence (docs/motion.md).
    Evigrid,
    /// The paper's method exactly (SPEC §5).
    Kurdej2013,
}

impl From<MethodArg> for evigrid::Method {
    fn from(method: MethodArg) -> Self {
        match method {
            MethodArg::Evigrid => evigrid::Method::Evigrid,
            MethodArg::Kurdej2013 => evigrid::Method::Kurdej2013,
        }
    }
}

/// Arguments of `evigrid run`.
#[derive(Debug, Args)]
#[command(after_long_help = POSES_HELP)]
pub struct RunArgs {
    /// Vector map: OSM PBF, OSM XML (optionally gzipped) or GeoJSON. Without one the map prior is
    /// vacuous (the `no-map` variant) and the summary says so.
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Directory of scans: PCD v0.7 (ascii or binary) or KITTI `.bin`, processed in file-name
    /// order (a folder holding a KITTI raw drive is read as --drive).
    #[arg(
        long,
        required_unless_present_any = ["drive", "bag"],
        conflicts_with_all = ["drive", "bag"]
    )]
    pub scans: Option<PathBuf>,
    /// A KITTI raw drive: its `<date>_drive_<NNNN>_sync` folder, or the date folder holding one.
    /// Scans, their timestamps, the OXTS poses and `calib_imu_to_velo.txt` are read from it.
    #[arg(long, conflicts_with = "bag")]
    pub drive: Option<PathBuf>,
    /// A ROS 2 recording (an MCAP file, or the rosbag2 folder holding one):
    /// `sensor_msgs/PointCloud2` scans with poses from tf, an
    /// Odometry or a NavSatFix topic (see --pose-source), or from the lidar odometry.
    #[arg(long, conflicts_with_all = ["poses", "times", "calib", "mounting"])]
    pub bag: Option<PathBuf>,
    /// The bag's PointCloud2 topic (default: the only one).
    #[arg(long, requires = "bag", value_name = "TOPIC")]
    pub cloud_topic: Option<String>,
    /// Where a bag's poses come from: auto (tf, else odometry, else NavSatFix, else the lidar
    /// odometry), none (the lidar odometry), tf[:FIXED_FRAME], odom[:TOPIC], navsat[:TOPIC].
    #[arg(long, requires = "bag", value_name = "SOURCE")]
    pub pose_source: Option<String>,
    /// Pose file: evigrid (7 columns), TUM (8) or KITTI odometry (12), matched to scans by time
    /// (see below). Without it, a KITTI raw drive's OXTS poses, or else the lidar odometry.
    #[arg(long)]
    pub poses: Option<PathBuf>,
    /// Pose file format: `evigrid`, `tum` or `kitti`; by default from its column count.
    #[arg(long, value_name = "FORMAT")]
    pub pose_format: Option<String>,
    /// KITTI odometry `calib.txt` (its `Tr`, camera 0 from Velodyne) for KITTI odometry pose
    /// files; without it they are read as the sensor's own poses.
    #[arg(long)]
    pub calib: Option<PathBuf>,
    /// Scan times: a KITTI raw `timestamps.txt` or a KITTI odometry `times.txt`, one per scan.
    /// By default a `timestamps.txt` beside or in the scan folder, if any.
    #[arg(long)]
    pub times: Option<PathBuf>,
    /// Where the sensor sits on the vehicle whose poses --poses gives, `x,y,z,roll,pitch,yaw`
    /// (metres, radians; vehicle x forward, y left, z up).
    #[arg(long, value_name = "X,Y,Z,ROLL,PITCH,YAW", allow_hyphen_values = true)]
    pub mounting: Option<String>,
    /// Process only the first N scans.
    #[arg(long, value_name = "N")]
    pub max_frames: Option<usize>,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Parameters (TOML, any subset of SPEC §7's layout); defaults otherwise.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Origin of the map's local frame as `LAT,LON` in degrees; by default the map's centre, or
    /// a KITTI raw drive's first OXTS fix. Without a map, WGS84 poses need it.
    #[arg(long, value_name = "LAT,LON", allow_hyphen_values = true)]
    pub origin: Option<String>,
    /// Print the summary as JSON on standard output (and no per-frame lines).
    #[arg(long)]
    pub json: bool,
    /// The fusion.
    #[arg(long, value_enum, default_value = "evigrid")]
    pub method: MethodArg,
    /// Stop at the first unreadable scan or refused pose instead of skipping it.
    #[arg(long)]
    pub strict: bool,
    /// Write into an existing --out folder that is not an evigrid output folder.
    #[arg(long)]
    pub force: bool,
    /// Do not write the Foxglove recording `run.mcap` (written by default).
    #[arg(long)]
    pub no_mcap: bool,
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
  run.mcap                     Foxglove recording: per frame the pose, the scan, the GNSS fix
                               (KITTI raw); the decision grid at 2 Hz and the last frame's; the
                               map's outlines (not with --no-mcap)
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

impl RunArgs {
    /// Every file or folder the flags name as an input, for the output policy.
    pub fn input_paths(&self) -> Vec<&Path> {
        [
            &self.map,
            &self.scans,
            &self.drive,
            &self.bag,
            &self.poses,
            &self.calib,
            &self.times,
            &self.config,
        ]
        .into_iter()
        .flatten()
        .map(PathBuf::as_path)
        .collect()
    }

    /// The drive the flags name, checked: the pose-file flags need `--poses`, `--times` is not
    /// for a KITTI raw drive, at least one frame.
    pub fn drive_spec(&self) -> anyhow::Result<DriveSpec> {
        let bad = |flag: &str, e: &dyn std::fmt::Display| BadInput::new(format!("{flag}: {e}"));
        let format = self
            .pose_format
            .as_deref()
            .map(|f| {
                f.parse::<PoseFormat>()
                    .map_err(|e| bad("--pose-format", &e))
            })
            .transpose()?;
        let mounting = self
            .mounting
            .as_deref()
            .map(|m| m.parse::<Mounting>().map_err(|e| bad("--mounting", &e)))
            .transpose()?;
        if self.poses.is_none() {
            for (given, flag) in [
                (mounting.is_some(), "--mounting"),
                (format.is_some(), "--pose-format"),
                (self.calib.is_some(), "--calib"),
            ] {
                if given {
                    return Err(BadInput::new(format!(
                        "{flag} describes --poses, not given"
                    )));
                }
            }
        }
        if self.max_frames == Some(0) {
            return Err(BadInput::new("--max-frames must be at least 1"));
        }
        let poses = self.poses.as_ref().map(|path| PoseFileSpec {
            path: path.clone(),
            format,
            calib: self.calib.clone(),
            mounting,
        });
        Ok(match (&self.bag, &self.drive, &self.scans) {
            (Some(path), _, _) => DriveSpec::Bag {
                path: path.clone(),
                cloud_topic: self.cloud_topic.clone(),
                pose_source: match &self.pose_source {
                    Some(text) => text.parse().map_err(|e: String| bad("--pose-source", &e))?,
                    None => drive::PoseSource::Auto,
                },
            },
            (None, Some(dir), _) => {
                if self.times.is_some() {
                    return Err(BadInput::new(
                        "--times: a KITTI raw --drive has its own scan timestamps",
                    ));
                }
                DriveSpec::KittiRaw {
                    dir: dir.clone(),
                    poses,
                }
            }
            (None, None, Some(dir)) => DriveSpec::ScanFolder {
                dir: dir.clone(),
                times: self.times.clone(),
                poses,
            },
            (None, None, None) => return Err(BadInput::new("give --scans, --drive or --bag")),
        })
    }
}
