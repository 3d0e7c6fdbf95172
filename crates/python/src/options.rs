//! What a Python caller passes, as the session and drive crates take it: parameters, method,
//! map, origin, and the drive's description. Every problem is an `InputError` naming the
//! argument as the caller wrote it.

use std::path::{Path, PathBuf};

use drive::DriveSpec;
use drive::bag::PoseSource;
use drive::poses::{Mounting, PoseFormat};
use drive::source::PoseFileSpec;
use evigrid::{Method, Params};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use session::{Map, SessionConfig};

use crate::error::{file_error, input_error};

/// The largest parameter file read (a TOML of a few dozen keys is about 2 KiB).
const MAX_CONFIG_BYTES: u64 = 1 << 20;

/// A path argument: `str` or `os.PathLike`.
pub fn path_arg(value: &Bound<'_, PyAny>, what: &str) -> PyResult<PathBuf> {
    value
        .extract::<PathBuf>()
        .map_err(|_| input_error(format!("{what}: expected a path (str or os.PathLike)")))
}

/// The parameters: `None` for the defaults, a TOML file in the SPEC §7 layout, or a dict in
/// the same layout (any subset of the keys).
pub fn params(config: Option<&Bound<'_, PyAny>>) -> PyResult<Params> {
    let Some(config) = config.filter(|c| !c.is_none()) else {
        return Ok(Params::default());
    };
    if let Ok(dict) = config.cast::<PyDict>() {
        let py = config.py();
        let text: String = py
            .import("json")?
            .call_method1("dumps", (dict,))
            .and_then(|t| t.extract())
            .map_err(|e| input_error(format!("config: not in the TOML layout: {e}")))?;
        let params: Params =
            serde_json::from_str(&text).map_err(|e| input_error(format!("config: {e}")))?;
        params
            .validate()
            .map_err(|e| input_error(format!("config: {e}")))?;
        return Ok(params);
    }
    let path = path_arg(config, "config")?;
    let text = drive::read_text_limited(&path, MAX_CONFIG_BYTES).map_err(|e| {
        let message = format!("config {}: {e}", path.display());
        if path.is_file() {
            input_error(message)
        } else {
            file_error(message)
        }
    })?;
    Params::from_toml_str(&text).map_err(|e| input_error(format!("{}: {e}", path.display())))
}

/// The method by its name: `evigrid` or `kurdej2013`.
pub fn method(name: &str) -> PyResult<Method> {
    match name {
        "evigrid" => Ok(Method::Evigrid),
        "kurdej2013" => Ok(Method::Kurdej2013),
        other => Err(input_error(format!(
            "method {other:?}: expected \"evigrid\" or \"kurdej2013\""
        ))),
    }
}

/// An origin `(lat, lon)` in degrees: a pair of numbers or the text `"LAT,LON"`.
pub fn origin(value: Option<&Bound<'_, PyAny>>) -> PyResult<Option<(f64, f64)>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    let bad = || input_error("origin: expected (lat, lon) in degrees, or \"LAT,LON\"");
    let (lat, lon) = if value.is_instance_of::<PyString>() {
        let text: String = value.extract()?;
        let (lat, lon) = text.split_once(',').ok_or_else(bad)?;
        let number = |s: &str| s.trim().parse::<f64>().map_err(|_| bad());
        (number(lat)?, number(lon)?)
    } else {
        value.extract::<(f64, f64)>().map_err(|_| bad())?
    };
    if !(-90.0..=90.0).contains(&lat) || !(-180.0..=180.0).contains(&lon) {
        return Err(input_error(format!(
            "origin ({lat}, {lon}): latitude must lie in [-90, 90] and longitude in [-180, 180]"
        )));
    }
    Ok(Some((lat, lon)))
}

/// The map file, loaded in the frame of `origin` (by default the map's centre).
pub fn map(value: Option<&Bound<'_, PyAny>>, origin: Option<(f64, f64)>) -> PyResult<Option<Map>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    let path = path_arg(value, "map")?;
    let py = value.py();
    let loaded = py.detach(|| Map::load(&path, origin));
    loaded
        .map(Some)
        .map_err(|e| crate::error::session_error(py, e))
}

/// A session's configuration from the Python arguments.
pub fn session_config(
    config: Option<&Bound<'_, PyAny>>,
    method_name: &str,
    map_path: Option<&Bound<'_, PyAny>>,
    origin_value: Option<&Bound<'_, PyAny>>,
) -> PyResult<SessionConfig> {
    let params = params(config)?;
    let method = method(method_name)?;
    let origin = origin(origin_value)?;
    let map = map(map_path, origin)?;
    Ok(SessionConfig {
        params,
        method,
        map,
        origin,
        ..SessionConfig::default()
    })
}

/// How a drive's scans and poses are found, as `open_drive` and `run` take them.
#[derive(Default)]
pub struct DriveArgs<'a, 'py> {
    /// A pose file.
    pub poses: Option<&'a Bound<'py, PyAny>>,
    /// Its format: `evigrid`, `tum` or `kitti`.
    pub pose_format: Option<&'a str>,
    /// KITTI odometry `calib.txt`.
    pub calib: Option<&'a Bound<'py, PyAny>>,
    /// Scan times.
    pub times: Option<&'a Bound<'py, PyAny>>,
    /// Where the sensor sits on the vehicle whose poses the file gives.
    pub mounting: Option<&'a Bound<'py, PyAny>>,
    /// A recording's PointCloud2 topic.
    pub cloud_topic: Option<&'a str>,
    /// A recording's pose source: `auto`, `none`, `tf[:FRAME]`, `odom[:TOPIC]`,
    /// `navsat[:TOPIC]`.
    pub pose_source: Option<&'a str>,
}

impl DriveArgs<'_, '_> {
    /// True when any option is given.
    pub fn any_given(&self) -> bool {
        [self.poses, self.calib, self.times, self.mounting]
            .iter()
            .any(|v| some(*v).is_some())
            || self.pose_format.is_some()
            || self.cloud_topic.is_some()
            || self.pose_source.is_some()
    }
}

fn some<'a, 'py>(value: Option<&'a Bound<'py, PyAny>>) -> Option<&'a Bound<'py, PyAny>> {
    value.filter(|v| !v.is_none())
}

/// The drive `path` names: a ROS 2 recording (a `.mcap` file), a KITTI raw drive folder (its
/// `*_sync` folder or the date folder holding one), or a folder of scans.
pub fn drive_spec(path: &Path, args: &DriveArgs<'_, '_>) -> PyResult<DriveSpec> {
    let is_bag = path.is_file()
        && path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("mcap"));
    if is_bag {
        let file_options = [
            (some(args.poses).is_some(), "poses"),
            (args.pose_format.is_some(), "pose_format"),
            (some(args.calib).is_some(), "calib"),
            (some(args.times).is_some(), "times"),
            (some(args.mounting).is_some(), "mounting"),
        ];
        if let Some((_, name)) = file_options.iter().find(|(given, _)| *given) {
            return Err(input_error(format!(
                "{name}: a ROS 2 recording ({}) carries its own poses and times; use \
                 pose_source and cloud_topic",
                path.display()
            )));
        }
        let pose_source = match args.pose_source {
            Some(text) => text
                .parse::<PoseSource>()
                .map_err(|e| input_error(format!("pose_source {text:?}: {e}")))?,
            None => PoseSource::default(),
        };
        return Ok(DriveSpec::Bag {
            path: path.to_path_buf(),
            cloud_topic: args.cloud_topic.map(str::to_owned),
            pose_source,
        });
    }
    if let Some((_, name)) = [
        (args.cloud_topic.is_some(), "cloud_topic"),
        (args.pose_source.is_some(), "pose_source"),
    ]
    .iter()
    .find(|(given, _)| *given)
    {
        return Err(input_error(format!(
            "{name}: applies only to a ROS 2 recording (.mcap), not {}",
            path.display()
        )));
    }
    if !path.is_dir() {
        let problem = if path.exists() {
            "is neither a folder of scans or a KITTI raw drive nor a ROS 2 recording (.mcap)"
        } else {
            "does not exist"
        };
        return Err(file_error(format!("{}: {problem}", path.display())));
    }
    let poses = match some(args.poses) {
        Some(value) => Some(PoseFileSpec {
            path: path_arg(value, "poses")?,
            format: args
                .pose_format
                .map(|text| {
                    text.parse::<PoseFormat>()
                        .map_err(|e| input_error(format!("pose_format {text:?}: {e}")))
                })
                .transpose()?,
            calib: some(args.calib).map(|c| path_arg(c, "calib")).transpose()?,
            mounting: some(args.mounting).map(mounting).transpose()?,
        }),
        None => {
            let needs_poses = [
                (args.pose_format.is_some(), "pose_format"),
                (some(args.calib).is_some(), "calib"),
                (some(args.mounting).is_some(), "mounting"),
            ];
            if let Some((_, name)) = needs_poses.iter().find(|(given, _)| *given) {
                return Err(input_error(format!("{name}: applies only with poses")));
            }
            None
        }
    };
    Ok(DriveSpec::ScanFolder {
        dir: path.to_path_buf(),
        times: some(args.times).map(|t| path_arg(t, "times")).transpose()?,
        poses,
    })
}

/// The sensor's mounting: `"x,y,z,roll,pitch,yaw"` (metres, degrees) or six numbers.
fn mounting(value: &Bound<'_, PyAny>) -> PyResult<Mounting> {
    let text = if value.is_instance_of::<PyString>() {
        value.extract::<String>()?
    } else {
        let numbers: Vec<f64> = value.extract().map_err(|_| {
            input_error("mounting: expected \"x,y,z,roll,pitch,yaw\" or six numbers")
        })?;
        numbers
            .iter()
            .map(|n| format!("{n:?}"))
            .collect::<Vec<_>>()
            .join(",")
    };
    text.parse::<Mounting>()
        .map_err(|e| input_error(format!("mounting: {e}")))
}
