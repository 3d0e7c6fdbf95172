//! `evigrid.run`: a whole drive as `evigrid run` runs it, every output file written, with the
//! GIL released and Ctrl-C honoured between frames.
//!
//! The drive runs on a thread of its own (the session crate's [`session::place`] and
//! [`session::run_placed`] with the sinks `evigrid run` writes); the calling thread waits with
//! the GIL released and, every 50 ms, takes it back to let Python see signals. On Ctrl-C it
//! raises the session's stop flag: the session stops between frames, finishes every output (the
//! summary marked incomplete), and only then is `KeyboardInterrupt` raised, carrying that
//! summary. The caller's `stop` callable, asked at the same moments, stops the drive the same
//! way without a signal; the summary is then returned (a stop that was asked for is no error).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use output::out_dir::{OutDir, OutDirError};
use output::sink::{DecisionFrames, FinalOutputs, FrameSink, FramesLog, McapSink};
use pyo3::prelude::*;
use session::{SessionConfig, SessionError, Summary};

use crate::drive::Drive;
use crate::error::{file_error, input_error, session_error, summary_dict};
use crate::options::{self, DriveArgs};

/// How often the waiting thread looks for signals.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Runs a whole drive as `evigrid run` does and returns its summary (the dict `summary.json`
/// holds).
///
/// `source` is a drive path (as `evigrid.open_drive` takes it, with the same keyword options)
/// or a drive `evigrid.open_drive` returned. Every output file of `evigrid run` is written into
/// `out` (the command's output policy: a new or empty folder, or one evigrid wrote before;
/// `force=True` writes into any folder, but never into one that holds an input, nor onto a
/// file); `out=None` writes nothing and only returns the summary. A refused `out` raises
/// `evigrid.InputError` before any work. `mcap=False` leaves out the Foxglove recording `run.mcap`.
///
/// The GIL is released while the drive runs, so other threads run meanwhile. Ctrl-C stops the
/// drive between frames; the outputs are finished (the summary marked incomplete) before
/// `KeyboardInterrupt` is raised, with the summary as its `summary` attribute. `stop`, a
/// callable without arguments, is called every 50 ms while the drive runs (on the calling
/// thread, with the GIL); once it returns a true value the drive stops between frames in the
/// same way, and the summary, marked incomplete, is returned; an exception it raises stops the
/// drive and is raised after the outputs are finished, as a signal handler's would be.
/// `threads`: the drive runs on a thread pool of that many threads, kept for the next runs with
/// the same `threads` (default: evigrid's shared pool, one thread per CPU or
/// `RAYON_NUM_THREADS`); the outputs do not depend on it. A drive that cannot be used raises
/// `evigrid.InputError`, an output that cannot be written `evigrid.FileError`; when frames had
/// run, the exception's `summary` says what was done.
#[pyfunction]
#[pyo3(signature = (
    source, *, out, config=None, method="evigrid", map=None, origin=None, poses=None,
    pose_format=None, calib=None, times=None, mounting=None, cloud_topic=None, pose_source=None,
    max_frames=None, strict=false, force=false, mcap=true, stop=None, threads=None,
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
    stop: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    let asked = stop.filter(|s| !s.is_none());
    if let Some(asked) = asked
        && !asked.is_callable()
    {
        return Err(input_error(
            "stop: must be a callable without arguments (e.g. threading.Event().is_set)",
        ));
    }
    let pool = threads.map(thread_pool).transpose()?;
    let args = DriveArgs {
        poses,
        pose_format,
        calib,
        times,
        mounting,
        cloud_topic,
        pose_source,
    };
    let spec = spec_of(source, &args)?;
    let mut config = options::session_config(config, method, map, origin)?;
    config.max_frames = max_frames;
    config.strict = strict;
    let out = match out.filter(|o| !o.is_none()) {
        Some(out) => Some(check_out(out, map, &spec, (force, mcap), &mut config)?),
        None => None,
    };
    let stop = AtomicBool::new(false);
    let mut interrupted: Option<PyErr> = None;
    let ran = run_detached(
        py,
        (&spec, config, out.as_ref(), pool.as_ref()),
        (&stop, asked),
        &mut interrupted,
    )?;
    let (summary, error) = match ran {
        Ok(ran) => ran,
        Err(RunError::OutDir(e)) => return Err(out_dir_error(e)),
        Err(RunError::Output(e)) => return Err(file_error(e.to_string())),
        Err(RunError::Session(e)) => return Err(interrupted.unwrap_or(session_error(py, e))),
    };
    // Stopped as `stop` asked: what was done, marked incomplete, is the result.
    let asked_stop = stop.load(Ordering::Relaxed) && interrupted.is_none();
    let Some(error) = error.filter(|e| !(asked_stop && e.is_interrupted())) else {
        return summary_dict(py, &summary);
    };
    // The signal's own exception (KeyboardInterrupt, or what a Python handler raised), or the
    // session's, with what was done.
    let raised = match interrupted {
        Some(raised) if error.is_interrupted() => raised,
        _ => session_error(py, error),
    };
    let _ = raised
        .value(py)
        .setattr("summary", summary_dict(py, &summary)?);
    Err(raised)
}

/// The drive `source` names: a drive `open_drive` returned (then no drive option may be
/// given: it was opened with its own), or a path with the options `args`.
fn spec_of(source: &Bound<'_, PyAny>, args: &DriveArgs<'_, '_>) -> PyResult<drive::DriveSpec> {
    if let Ok(drive) = source.cast::<Drive>() {
        if args.any_given() {
            return Err(input_error(
                "run(drive): the drive was opened with its options; give them to open_drive",
            ));
        }
        Ok(drive.get().spec().clone())
    } else {
        options::drive_spec(&options::path_arg(source, "source")?, args)
    }
}

/// The output folder `out`, checked before any work so that a bad folder costs nothing, and
/// noted in `config`; `(force, mcap)` as `run` was given them.
fn check_out(
    out: &Bound<'_, PyAny>,
    map: Option<&Bound<'_, PyAny>>,
    spec: &drive::DriveSpec,
    (force, mcap): (bool, bool),
    config: &mut SessionConfig,
) -> PyResult<Outputs> {
    let path = options::path_arg(out, "out")?;
    // The folder never holds an input, whatever `force` says (it is cleared and written while
    // the drive is read).
    let map_path = map.and_then(|m| options::path_arg(m, "map").ok());
    let mut inputs = spec.input_paths();
    inputs.extend(map_path.as_deref());
    OutDir::check_inputs(&path, &inputs).map_err(out_dir_error)?;
    OutDir::check(&path, force).map_err(out_dir_error)?;
    config.out = path.display().to_string();
    Ok(Outputs { path, force, mcap })
}

/// Runs the drive on a thread of its own ([`run_drive`]) while this one waits with the GIL
/// released, taking it back every [`SIGNAL_POLL`] to let Python see signals and to ask the
/// caller's `asked` callable: the first signal, or what `asked` raised, raises `stop` and is kept
/// in `interrupted`; a true answer of `asked` raises `stop` alone.
fn run_detached(
    py: Python<'_>,
    (spec, config, out, pool): (
        &drive::DriveSpec,
        SessionConfig,
        Option<&Outputs>,
        Option<&Arc<rayon::ThreadPool>>,
    ),
    (stop, asked): (&AtomicBool, Option<&Bound<'_, PyAny>>),
    interrupted: &mut Option<PyErr>,
) -> PyResult<Result<(Summary, Option<SessionError>), RunError>> {
    std::thread::scope(|scope| {
        let (done, finished) = mpsc::channel();
        // Waited on with the GIL released, from this thread only.
        let finished = std::sync::Mutex::new(finished);
        scope.spawn(move || {
            let ran = match pool {
                Some(pool) => pool.install(|| run_drive(spec, config, out, stop)),
                None => run_drive(spec, config, out, stop),
            };
            let _ = done.send(ran);
        });
        loop {
            let waited = py.detach(|| match finished.lock() {
                Ok(finished) => finished.recv_timeout(SIGNAL_POLL),
                Err(_) => Err(mpsc::RecvTimeoutError::Disconnected),
            });
            match waited {
                Ok(ran) => return Ok(ran),
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
                *interrupted = Some(error);
            }
            if let Some(asked) = asked
                && !stop.load(Ordering::Relaxed)
            {
                match asked.call0().and_then(|answer| answer.is_truthy()) {
                    Ok(false) => {}
                    Ok(true) => stop.store(true, Ordering::Relaxed),
                    Err(error) => {
                        stop.store(true, Ordering::Relaxed);
                        *interrupted = Some(error);
                    }
                }
            }
        }
    })
}

/// The thread pools of `run(threads=...)` by size, kept for the next runs as the shared pool is
/// (rather than starting a drive's threads again for every drive).
static POOLS: Mutex<BTreeMap<usize, Arc<rayon::ThreadPool>>> = Mutex::new(BTreeMap::new());

/// The thread pool of `threads` threads (started on first use, then kept), or why not.
fn thread_pool(threads: usize) -> PyResult<Arc<rayon::ThreadPool>> {
    if threads == 0 {
        return Err(input_error("threads 0: must be 1 or more"));
    }
    let mut pools = POOLS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(pool) = pools.get(&threads) {
        return Ok(Arc::clone(pool));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(move |k| format!("evigrid-p{threads}-{k}"))
        .build()
        .map_err(|e| {
            pyo3::exceptions::PyRuntimeError::new_err(format!(
                "threads {threads}: the thread pool cannot be started: {e}"
            ))
        })?;
    let pool = Arc::new(pool);
    pools.insert(threads, Arc::clone(&pool));
    Ok(pool)
}

/// Where the outputs go, when they do.
struct Outputs {
    path: PathBuf,
    force: bool,
    mcap: bool,
}

/// Why a run ended before its summary.
enum RunError {
    Session(SessionError),
    OutDir(OutDirError),
    Output(output::OutputError),
}

/// Places the drive, prepares the output folder, runs the frames through the sinks and writes
/// the summary: the summary, and the error that stopped the frames early, if any.
fn run_drive(
    spec: &drive::DriveSpec,
    config: SessionConfig,
    out: Option<&Outputs>,
    stop: &AtomicBool,
) -> Result<(Summary, Option<SessionError>), RunError> {
    let drive = drive::Drive::open(spec).map_err(|e| RunError::Session(e.into()))?;
    let placement = session::place(drive, &config, stop, &mut ()).map_err(RunError::Session)?;
    let Some(out) = out else {
        let outcome = session::run_placed(placement, config, &mut [], stop, &mut ())
            .map_err(RunError::Session)?;
        return Ok((outcome.summary, outcome.error));
    };
    let dir = OutDir::prepare(&out.path, out.force, "run").map_err(RunError::OutDir)?;
    let mut sinks =
        sinks_of_run(&out.path, config.map.as_ref(), out.mcap).map_err(RunError::Output)?;
    let mut sinks: Vec<&mut dyn FrameSink> = sinks
        .iter_mut()
        .map(|sink| &mut **sink as &mut dyn FrameSink)
        .collect();
    let outcome = session::run_placed(placement, config, &mut sinks, stop, &mut ())
        .map_err(RunError::Session)?;
    let written = write_summary(&out.path, &outcome.summary);
    // The folder records what was written, even after an early stop.
    let finished = dir.finish();
    written.map_err(RunError::Output)?;
    finished.map_err(RunError::OutDir)?;
    Ok((outcome.summary, outcome.error))
}

/// An output folder refused, in the words of the Python arguments.
fn out_dir_error(error: OutDirError) -> PyErr {
    match error {
        OutDirError::NotOurs { .. } => input_error(format!(
            "out {error}; choose another out or pass force=True"
        )),
        other => input_error(format!("out {other}")),
    }
}

/// The sinks of `evigrid run`, in its order: the recording (unless `mcap` is false), the
/// decision of every frame, the frame records, the final figures and grids.
fn sinks_of_run(
    dir: &Path,
    map: Option<&session::Map>,
    mcap: bool,
) -> Result<Vec<Box<dyn FrameSink + Send>>, output::OutputError> {
    let mut sinks: Vec<Box<dyn FrameSink + Send>> = Vec::new();
    if mcap {
        let local = map.map(|m| &m.loaded.map);
        sinks.push(Box::new(McapSink::create(&dir.join("run.mcap"), local)?));
    }
    sinks.push(Box::new(DecisionFrames::create(&dir.join("frames"))?));
    sinks.push(Box::new(FramesLog::create(
        &dir.join(session::FRAMES_FILE),
    )?));
    sinks.push(Box::new(FinalOutputs::new(dir)));
    Ok(sinks)
}

/// `summary.json`, written atomically, as `evigrid run` writes it.
fn write_summary(dir: &Path, summary: &Summary) -> Result<(), output::OutputError> {
    let path = dir.join("summary.json");
    let text =
        serde_json::to_string_pretty(summary).map_err(|source| output::OutputError::Json {
            path: path.clone(),
            source,
        })?;
    output::write_atomic(&path, |file| {
        std::io::Write::write_all(file, text.as_bytes())
    })
}
