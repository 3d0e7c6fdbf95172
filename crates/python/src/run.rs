//! `evigrid.run`: a whole drive as `evigrid run` runs it, every output file written, with the
//! GIL released and Ctrl-C honoured between frames.
//!
//! The drive runs on a thread of its own ([`session::run_drive`] with the sinks `evigrid run`
//! writes); the calling thread waits with the GIL released and, every 50 ms, takes it back to
//! let Python see signals. On Ctrl-C it raises the session's stop flag: the session stops
//! between frames, finishes every output (the summary marked incomplete), and only then is
//! `KeyboardInterrupt` raised, carrying that summary.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use output::out_dir::{OutDir, OutDirError};
use output::sink::{DecisionFrames, FinalOutputs, FrameSink, FramesLog, McapSink};
use pyo3::prelude::*;

use crate::drive::Drive;
use crate::error::{file_error, session_error, summary_dict};
use crate::options::{self, DriveArgs};

/// How often the waiting thread looks for signals.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Runs a whole drive as `evigrid run` does and returns its summary (the dict `summary.json`
/// holds).
///
/// `source` is a drive path (as `evigrid.open_drive` takes it, with the same keyword options)
/// or a drive `evigrid.open_drive` returned. Every output file of `evigrid run` is written into
/// `out` (the command's output policy: a new or empty folder, or one evigrid wrote before;
/// `force=True` writes into any folder); `out=None` writes nothing and only returns the
/// summary. `mcap=False` leaves out the Foxglove recording `run.mcap`.
///
/// The GIL is released while the drive runs, so other threads run meanwhile. Ctrl-C stops the
/// drive between frames; the outputs are finished (the summary marked incomplete) before
/// `KeyboardInterrupt` is raised, with the summary as its `summary` attribute. A drive that
/// cannot be used raises `evigrid.InputError`, an output that cannot be written
/// `evigrid.FileError`; when frames had run, the exception's `summary` says what was done.
#[pyfunction]
#[pyo3(signature = (
    source, *, out, config=None, method="evigrid", map=None, origin=None, poses=None,
    pose_format=None, calib=None, times=None, mounting=None, cloud_topic=None, pose_source=None,
    max_frames=None, strict=false, force=false, mcap=true,
))]
#[allow(clippy::too_many_arguments)]
pub fn run<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    out: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
    method: &str,
    map: Option<&Bound<'py, PyAny>>,
    origin: Option<&Bound<'py, PyAny>>,
    poses: Option<&Bound<'py, PyAny>>,
    pose_format: Option<&str>,
    calib: Option<&Bound<'py, PyAny>>,
    times: Option<&Bound<'py, PyAny>>,
    mounting: Option<&Bound<'py, PyAny>>,
    cloud_topic: Option<&str>,
    pose_source: Option<&str>,
    max_frames: Option<usize>,
    strict: bool,
    force: bool,
    mcap: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let spec = if let Ok(drive) = source.cast::<Drive>() {
        let given = [poses, calib, times, mounting]
            .iter()
            .any(|v| v.is_some_and(|v| !v.is_none()))
            || pose_format.is_some()
            || cloud_topic.is_some()
            || pose_source.is_some();
        if given {
            return Err(crate::error::input_error(
                "run(drive): the drive was opened with its options; give them to open_drive",
            ));
        }
        drive.get().spec().clone()
    } else {
        let path = options::path_arg(source, "source")?;
        let args = DriveArgs {
            poses,
            pose_format,
            calib,
            times,
            mounting,
            cloud_topic,
            pose_source,
        };
        options::drive_spec(&path, &args)?
    };
    let mut config = options::session_config(config, method, map, origin)?;
    config.max_frames = max_frames;
    config.strict = strict;
    let out_dir = match out.filter(|o| !o.is_none()) {
        Some(out) => {
            let path = options::path_arg(out, "out")?;
            let prepared = OutDir::prepare(&path, force, "run").map_err(|e| match e {
                OutDirError::NotOurs { .. } => crate::error::input_error(format!(
                    "out {e}; choose another out or pass force=True"
                )),
                other => crate::error::input_error(format!("out {other}")),
            })?;
            config.out = path.display().to_string();
            Some(prepared)
        }
        None => None,
    };
    let drive = py
        .detach(|| drive::Drive::open(&spec))
        .map_err(|e| session_error(py, e.into()))?;
    let mut sinks = match &out_dir {
        Some(dir) => sinks_of_run(dir.path(), config.map.as_ref(), mcap)?,
        None => Vec::new(),
    };
    let stop = AtomicBool::new(false);
    let mut interrupted: Option<PyErr> = None;
    let result = std::thread::scope(|scope| {
        let (done, finished) = mpsc::channel();
        let stop = &stop;
        scope.spawn(move || {
            let mut borrowed: Vec<&mut dyn FrameSink> =
                sinks.iter_mut().map(|s| &mut **s as &mut dyn FrameSink).collect();
            let _ = done.send(session::run_drive(drive, config, &mut borrowed, stop));
        });
        loop {
            match py.detach(|| finished.recv_timeout(SIGNAL_POLL)) {
                Ok(result) => return Ok(result),
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(pyo3::exceptions::PyRuntimeError::new_err(
                        "evigrid.run: the drive's thread ended without a result",
                    ));
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
            if interrupted.is_none()
                && let Err(error) = py.check_signals()
            {
                stop.store(true, Ordering::Relaxed);
                interrupted = Some(error);
            }
        }
    })?;
    let summary = match &result {
        Ok(summary) => Some(summary),
        Err(session::SessionError::Stopped { summary, .. }) => Some(&**summary),
        Err(_) => None,
    };
    if let (Some(dir), Some(summary)) = (&out_dir, summary) {
        write_summary(dir, summary)?;
    }
    match result {
        Ok(summary) => summary_dict(py, &summary),
        Err(error) => {
            if let Some(raised) = interrupted {
                // The signal's own exception (KeyboardInterrupt, or what a Python handler
                // raised), with what was done.
                if let Some(summary) = summary_of(&error) {
                    let _ = raised.value(py).setattr("summary", summary_dict(py, summary)?);
                }
                return Err(raised);
            }
            Err(session_error(py, error))
        }
    }
}

fn summary_of(error: &session::SessionError) -> Option<&session::Summary> {
    match error {
        session::SessionError::Stopped { summary, .. } => Some(summary),
        _ => None,
    }
}

/// The sinks of `evigrid run`: the recording, the decision of every frame, the frame records,
/// the final figures and grids.
fn sinks_of_run(
    dir: &Path,
    map: Option<&session::Map>,
    mcap: bool,
) -> PyResult<Vec<Box<dyn FrameSink + Send>>> {
    let failed = |e: output::OutputError| file_error(e.to_string());
    let mut sinks: Vec<Box<dyn FrameSink + Send>> = Vec::new();
    if mcap {
        let local = map.map(|m| &m.loaded.map);
        sinks.push(Box::new(
            McapSink::create(&dir.join("run.mcap"), local).map_err(failed)?,
        ));
    }
    sinks.push(Box::new(
        DecisionFrames::create(&dir.join("frames")).map_err(failed)?,
    ));
    sinks.push(Box::new(
        FramesLog::create(&dir.join(session::FRAMES_FILE)).map_err(failed)?,
    ));
    sinks.push(Box::new(FinalOutputs::new(dir)));
    Ok(sinks)
}

/// `summary.json`, written atomically, and the folder's record of what was written.
fn write_summary(dir: &OutDir, summary: &session::Summary) -> PyResult<()> {
    let path = dir.path().join("summary.json");
    let text = serde_json::to_string_pretty(summary)
        .map_err(|e| file_error(format!("{}: {e}", path.display())))?;
    output::write_atomic(&path, |file| std::io::Write::write_all(file, text.as_bytes()))
        .map_err(|e| file_error(format!("{}: {e}", path.display())))?;
    dir.finish().map_err(|e| file_error(e.to_string()))
}
