//! `evigrid.open_drive`: a drive as an iterable of frames, and the frames as numpy arrays.
//!
//! The drive is opened and placed by the session crate ([`session::place`]: the drive's own
//! poses, or the lidar odometry's for scans without any), exactly as `evigrid run` places it.
//! Iterating reads the scans on a thread of their own, one frame ahead, so that reading the next
//! scan overlaps the caller's work on this one; the frames arrive in order.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Arc, Mutex};

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;

use crate::arrays::readonly;
use crate::error::{input_error, session_error};
use crate::options::{self, DriveArgs};

/// A drive opened and placed: its scans, one pose per scan, and the ego's path.
pub struct Placed {
    /// How the drive was named, to open it again (`evigrid.run`).
    pub spec: drive::DriveSpec,
    drive: drive::Drive,
    poses: drive::Poses,
    /// The ego's path, metres (east, north): every pose known, one per scan.
    pub path: Arc<Vec<[f64; 2]>>,
    /// Scans left out: by the odometry pass, or unreadable when iterated.
    pub skipped: Mutex<Vec<session::SkippedScan>>,
    /// How many of `skipped` the odometry pass left out (before the first frame).
    pub skipped_before_frames: usize,
    /// How a session's summary names the drive.
    pub labels: session::DriveLabels,
    strict: bool,
}

impl Placed {
    /// Where the poses came from.
    pub fn pose_origin(&self) -> &drive::PoseOrigin {
        &self.poses.origin
    }
}

/// A drive: iterate it for its frames, in order; `len()` is their number.
///
/// Made by `evigrid.open_drive`. Each iteration reads the scans again from the start.
#[pyclass(frozen, module = "evigrid")]
pub struct Drive {
    placed: Arc<Placed>,
}

impl Drive {
    /// How the drive was named.
    pub fn spec(&self) -> &drive::DriveSpec {
        &self.placed.spec
    }
}

/// Opens a drive: a KITTI raw drive folder, a folder of scans (PCD or KITTI `.bin`) with or
/// without a pose file, or a ROS 2 recording (`.mcap`), as `evigrid run` reads them.
///
/// The scans are placed as `evigrid run` places them: by the drive's own poses (KITTI's OXTS,
/// the pose file matched by time or line order, the recording's tf / odometry / NavSatFix) in
/// the local frame of `map` (else `origin`, else the drive's first GNSS fix), or, without poses,
/// by the lidar odometry over the scans, which runs here, before the first frame.
///
/// Raises `evigrid.InputError` for a drive that cannot be used (no scans, poses that do not
/// match, an unknown option value) and `evigrid.FileError` for a path that does not exist;
/// messages name the file.
#[pyfunction]
#[pyo3(signature = (
    path, *, poses=None, pose_format=None, calib=None, times=None, mounting=None,
    cloud_topic=None, pose_source=None, map=None, origin=None, max_frames=None, strict=false,
))]
#[allow(clippy::too_many_arguments)]
pub fn open_drive(
    py: Python<'_>,
    path: &Bound<'_, PyAny>,
    poses: Option<&Bound<'_, PyAny>>,
    pose_format: Option<&str>,
    calib: Option<&Bound<'_, PyAny>>,
    times: Option<&Bound<'_, PyAny>>,
    mounting: Option<&Bound<'_, PyAny>>,
    cloud_topic: Option<&str>,
    pose_source: Option<&str>,
    map: Option<&Bound<'_, PyAny>>,
    origin: Option<&Bound<'_, PyAny>>,
    max_frames: Option<usize>,
    strict: bool,
) -> PyResult<Drive> {
    let path: PathBuf = options::path_arg(path, "path")?;
    let args = DriveArgs {
        poses,
        pose_format,
        calib,
        times,
        mounting,
        cloud_topic,
        pose_source,
    };
    let spec = options::drive_spec(&path, &args)?;
    let mut config = options::session_config(None, "evigrid", map, origin)?;
    config.max_frames = max_frames;
    config.strict = strict;
    let placement = py
        .detach(|| {
            let opened = drive::Drive::open(&spec)?;
            session::place(opened, &config, &AtomicBool::new(false), &mut ())
        })
        .map_err(|e| session_error(py, e))?;
    if let Some(error) = placement.stopped {
        return Err(session_error(py, error));
    }
    let labels = session::DriveLabels::new(
        &placement.drive,
        &placement.poses.origin,
        placement.odometry_seconds,
    );
    Ok(Drive {
        placed: Arc::new(Placed {
            spec,
            drive: placement.drive,
            poses: placement.poses,
            path: Arc::new(placement.path),
            skipped_before_frames: placement.skipped.len(),
            skipped: Mutex::new(placement.skipped),
            labels,
            strict,
        }),
    })
}

#[pymethods]
impl Drive {
    fn __len__(&self) -> usize {
        self.placed.poses.len().min(self.placed.drive.len())
    }

    fn __iter__(&self) -> PyResult<Frames> {
        Frames::start(Arc::clone(&self.placed))
    }

    fn __repr__(&self) -> String {
        format!(
            "<evigrid.Drive {} ({} frames, poses: {})>",
            self.placed.drive.given_path().display(),
            self.__len__(),
            self.placed.poses.origin
        )
    }

    /// The path the drive was opened from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.placed.drive.given_path().to_path_buf()
    }

    /// Where the poses came from, as the summary names it (`OXTS of ...`, a pose file,
    /// `lidar odometry`, ...).
    #[getter]
    fn poses(&self) -> String {
        self.placed.poses.origin.to_string()
    }

    /// How scans met their poses: `time`, `line order` or `odometry`.
    #[getter]
    fn pose_matching(&self) -> &'static str {
        self.placed.poses.origin.matching().name()
    }

    /// The ego's path: every known position, east and north in metres, one row per scan
    /// (numpy float64, N × 2, read-only).
    #[getter]
    fn ego_path<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let path = &self.placed.path;
        let values = path.iter().flatten().copied().collect();
        readonly(py, values, &[path.len(), 2])
    }

    /// Scans left out so far, as `{"scan": name, "error": message}`: by the odometry pass, or
    /// unreadable when the drive was iterated.
    #[getter]
    fn skipped<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let skipped = lock(&self.placed.skipped)?;
        crate::error::to_python(py, &*skipped)
    }
}

/// The mutex's data; a poisoned lock (a panic elsewhere) is an error, not a second panic.
pub fn lock<T>(mutex: &Mutex<T>) -> PyResult<std::sync::MutexGuard<'_, T>> {
    mutex.lock().map_err(|_| {
        pyo3::exceptions::PyRuntimeError::new_err("evigrid: internal state lost after a panic")
    })
}

/// What the reading thread sends.
enum Item {
    Frame(Box<drive::Frame>),
    Skipped(drive::source::SkippedScan),
    Failed(String),
}

/// The frames of a drive, in order (one iteration of a `Drive`).
#[pyclass(module = "evigrid")]
pub struct Frames {
    placed: Arc<Placed>,
    receiver: Mutex<Receiver<Item>>,
}

impl Frames {
    fn start(placed: Arc<Placed>) -> PyResult<Self> {
        // One frame read ahead: the next scan is read while the caller works on this one.
        let (sender, receiver) = sync_channel(1);
        let reader = Arc::clone(&placed);
        std::thread::Builder::new()
            .name("evigrid-drive-reader".into())
            .spawn(move || read_frames(&reader, &sender))
            .map_err(|e| crate::error::file_error(format!("cannot start the scan reader: {e}")))?;
        Ok(Self {
            placed,
            receiver: Mutex::new(receiver),
        })
    }
}

/// Reads the drive's frames in order into `sender` until they end or the receiver is gone.
fn read_frames(placed: &Placed, sender: &SyncSender<Item>) {
    let frames = match placed.drive.frames(&placed.poses) {
        Ok(frames) => frames,
        Err(error) => {
            let _ = sender.send(Item::Failed(error.to_string()));
            return;
        }
    };
    for frame in frames {
        let item = match frame {
            Ok(frame) => Item::Frame(Box::new(frame)),
            Err(skipped) => Item::Skipped(skipped),
        };
        if sender.send(item).is_err() {
            return; // the iterator was dropped
        }
    }
}

#[pymethods]
impl Frames {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&self, py: Python<'_>) -> PyResult<Option<Frame>> {
        loop {
            let item = py.detach(|| lock(&self.receiver).map(|r| r.recv().ok()))?;
            match item {
                None => return Ok(None),
                Some(Item::Frame(frame)) => {
                    return Ok(Some(Frame {
                        inner: *frame,
                        drive: Some(Arc::clone(&self.placed)),
                        points: PyOnceLock::new(),
                    }));
                }
                Some(Item::Failed(error)) => return Err(input_error(error)),
                Some(Item::Skipped(skipped)) => {
                    if self.placed.strict {
                        return Err(input_error(skipped.error));
                    }
                    lock(&self.placed.skipped)?.push(session::SkippedScan {
                        scan: skipped.name,
                        error: skipped.error,
                    });
                }
            }
        }
    }
}

/// One scan with its pose: `.points`, `.pose`, `.time`, `.name`, `.index`.
#[pyclass(frozen, module = "evigrid")]
pub struct Frame {
    pub(crate) inner: drive::Frame,
    /// The drive the frame came from: its ego path (the session's ego-path check looks along
    /// it), its labels and its skipped scans, for the session's summary.
    pub(crate) drive: Option<Arc<Placed>>,
    points: PyOnceLock<Py<PyAny>>,
}

impl Frame {
    /// A frame made from the caller's arrays (`Session.step(points, pose, time)`).
    pub fn new(inner: drive::Frame) -> Self {
        Self {
            inner,
            drive: None,
            points: PyOnceLock::new(),
        }
    }
}

#[pymethods]
impl Frame {
    /// The points in the sensor frame: numpy float32, N × 4 (x, y, z in metres, intensity),
    /// intensity NaN where the source has none. Read-only; made on first access and kept.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let array = self.points.get_or_try_init(py, || {
            let frame = &self.inner;
            let mut values = Vec::with_capacity(frame.points_in_sensor.len() * 4);
            for (k, p) in frame.points_in_sensor.iter().enumerate() {
                let intensity = frame.intensity.get(k).copied().unwrap_or(f32::NAN);
                values.extend_from_slice(&[p[0], p[1], p[2], intensity]);
            }
            let n = frame.points_in_sensor.len();
            readonly(py, values, &[n, 4]).map(Bound::unbind)
        })?;
        Ok(array.bind(py).clone())
    }

    /// Where the sensor was: world from sensor, numpy float64 4 × 4 (rotation and translation
    /// in metres, last row 0, 0, 0, 1), a new array on each access.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let matrix = self.inner.world_from_sensor.to_homogeneous();
        // nalgebra stores columns first; numpy rows first.
        let values = matrix.transpose().as_slice().to_vec();
        readonly(py, values, &[4, 4])
    }

    /// Time of the scan, seconds.
    #[getter]
    fn time(&self) -> f64 {
        self.inner.time_s
    }

    /// The scan's name: its file name, `<bag>#NNNNNN` for a recording.
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// Index of the scan in its drive, from 0.
    #[getter]
    fn index(&self) -> usize {
        self.inner.index
    }

    fn __len__(&self) -> usize {
        self.inner.points_in_sensor.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "<evigrid.Frame {} #{} at {:.3} s, {} points>",
            self.inner.name,
            self.inner.index,
            self.inner.time_s,
            self.inner.points_in_sensor.len()
        )
    }
}
