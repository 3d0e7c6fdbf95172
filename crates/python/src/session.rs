//! `evigrid.Session`: the pipeline over a drive's frames, stepped from Python, and what a step
//! gives as numpy arrays.
//!
//! The session is the session crate's ([`session::Session`]): the same defaults, the same
//! totals and summary as `evigrid run`. A step runs with the GIL released, so sessions in other
//! threads run meanwhile. Its result copies nothing: each grid is copied out of the session, in
//! world order, when it is first read, and kept; reading it after the session has stepped again
//! is an error rather than the next frame's numbers under this frame's name.

use std::sync::{Arc, Mutex};

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use numpy::{PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyModule;

use crate::arrays::readonly;
use crate::drive::{Frame, Placed, lock};
use crate::error::{input_error, session_error, summary_dict, to_python};
use crate::options;

/// The session and how far it has gone.
struct State {
    session: session::Session,
    /// Steps taken: a result reads the grids only while this is still its own.
    steps: u64,
    /// Index the next frame made from arrays gets.
    next_index: usize,
    /// The drive whose frames are being stepped, once one is.
    drive: Option<Arc<Placed>>,
    /// How many of that drive's skipped scans the session has been told of.
    drive_skipped_told: usize,
}

/// Keeps the session's summary in step with the drive whose frame comes next, as `evigrid run`
/// makes it: on the drive's first frame, its labels, path, pose refinement (none for the lidar
/// odometry's poses) and the scans its odometry pass left out; then each scan found unreadable
/// while iterating, once.
fn follow_drive(
    state: &mut State,
    drive: Arc<Placed>,
) -> PyResult<Result<(), session::SessionError>> {
    let same = state.drive.as_ref().is_some_and(|d| Arc::ptr_eq(d, &drive));
    if !same {
        if let Err(error) = state
            .session
            .begin_drive(drive.labels.clone(), drive.pose_origin())
        {
            return Ok(Err(error));
        }
        state.session.set_path(drive.path.to_vec());
        let skipped = lock(&drive.skipped)?;
        for scan in &skipped[..drive.skipped_before_frames] {
            state.session.skipped_before(scan.clone());
        }
        state.drive_skipped_told = drive.skipped_before_frames;
        drop(skipped);
        state.drive = Some(drive);
    }
    let Some(drive) = state.drive.clone() else {
        return Ok(Ok(()));
    };
    let skipped = lock(&drive.skipped)?;
    let new: Vec<_> = skipped[state.drive_skipped_told.min(skipped.len())..].to_vec();
    state.drive_skipped_told = skipped.len();
    drop(skipped);
    for scan in new {
        state.session.skip(scan);
    }
    Ok(Ok(()))
}

/// The pipeline of `evigrid run`, one frame at a time.
///
/// `config` is a TOML file in the SPEC §7 layout or a dict in the same layout (any subset of
/// the keys); `method` is `"evigrid"` (with motion evidence, the default) or `"kurdej2013"`;
/// `map` a vector map file (OSM PBF or XML, GeoJSON) whose prior the grids fuse; `origin`
/// `(lat, lon)` the local frame's origin. By default, the defaults of `evigrid run`.
#[pyclass(frozen, module = "evigrid")]
pub struct Session {
    state: Mutex<State>,
}

#[pymethods]
impl Session {
    #[new]
    #[pyo3(signature = (config=None, *, method="evigrid", map=None, origin=None, strict=false))]
    fn new(
        py: Python<'_>,
        config: Option<&Bound<'_, PyAny>>,
        method: &str,
        map: Option<&Bound<'_, PyAny>>,
        origin: Option<&Bound<'_, PyAny>>,
        strict: bool,
    ) -> PyResult<Self> {
        let mut config = options::session_config(config, method, map, origin)?;
        config.strict = strict;
        let session = py
            .detach(|| session::Session::new(config))
            .map_err(|e| session_error(py, e))?;
        Ok(Self {
            state: Mutex::new(State {
                session,
                steps: 0,
                next_index: 0,
                drive: None,
                drive_skipped_told: 0,
            }),
        })
    }

    /// Processes one frame: `step(frame)` with a frame of `evigrid.open_drive`, or
    /// `step(points, pose, time)` with points N × 3 or N × 4 (x, y, z, intensity; metres, sensor
    /// frame), `pose` the 4 × 4 world-from-sensor matrix and `time` in seconds.
    ///
    /// The GIL is released while the frame is processed. Raises `evigrid.InputError` for
    /// arrays of the wrong shape or type, a pose that is not a rigid transform, or a frame the
    /// pipeline refuses (its time going back, a jump beyond the window); the grids are then
    /// unchanged, and the summary lists the frame as skipped.
    #[pyo3(signature = (frame, pose=None, time=None, *, name=None))]
    fn step(
        slf: &Bound<'_, Self>,
        frame: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        time: Option<f64>,
        name: Option<String>,
    ) -> PyResult<StepResult> {
        let py = slf.py();
        let this = slf.get();
        let given;
        let (inner, drive) = if let Ok(frame) = frame.cast::<Frame>() {
            if pose.is_some() || time.is_some() || name.is_some() {
                return Err(input_error(
                    "step(frame): a frame carries its pose, time and name; give them only with \
                     points",
                ));
            }
            let frame = frame.get();
            (&frame.inner, frame.drive.clone())
        } else {
            let (Some(pose), Some(time)) = (pose, time) else {
                return Err(input_error(
                    "step: give a frame of evigrid.open_drive, or points, pose and time",
                ));
            };
            let index = lock(&this.state)?.next_index;
            given = frame_from_arrays(frame, pose, time, index, name)?;
            (&given, None)
        };
        let stepped = py.detach(|| -> PyResult<Result<_, session::SessionError>> {
            let mut state = lock(&this.state)?;
            if let Some(drive) = drive
                && let Err(error) = follow_drive(&mut state, drive)?
            {
                return Ok(Err(error));
            }
            state.next_index = inner.index + 1;
            let result = state.session.step(inner).map(|result| {
                let window = result.window();
                let geometry = Geometry {
                    origin_m: result.origin_m(),
                    cell_size_m: result.cell_size_m(),
                    width: window.width(),
                    height: window.height(),
                };
                (result.record, geometry)
            });
            if result.is_ok() {
                state.steps += 1;
            }
            Ok(result.map(|(record, geometry)| (record, geometry, state.steps)))
        })?;
        let (record, geometry, step) = stepped.map_err(|e| session_error(py, e))?;
        Ok(StepResult {
            session: slf.clone().unbind(),
            step,
            index: inner.index,
            name: inner.name.clone(),
            time_s: inner.time_s,
            record,
            geometry,
            grids: Grids::new(),
        })
    }

    /// The summary as the session stands: the same dict as `summary.json` (marked complete).
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let summary = py.detach(|| lock(&self.state).map(|s| s.session.summary()))?;
        summary_dict(py, &summary)
    }

    /// Frames processed so far.
    #[getter]
    fn frames(&self) -> PyResult<usize> {
        Ok(lock(&self.state)?.session.frames())
    }

    fn __repr__(&self) -> PyResult<String> {
        Ok(format!("<evigrid.Session, {} frames>", self.frames()?))
    }
}

/// Where the window lies after a step.
#[derive(Clone, Copy)]
struct Geometry {
    origin_m: [f64; 2],
    cell_size_m: f64,
    width: usize,
    height: usize,
}

/// The grids of a result, each made on first access.
struct Grids {
    classes: PyOnceLock<Py<PyAny>>,
    masses: PyOnceLock<Py<PyAny>>,
    betp: PyOnceLock<Py<PyAny>>,
    velocity: PyOnceLock<Py<PyAny>>,
}

impl Grids {
    fn new() -> Self {
        Self {
            classes: PyOnceLock::new(),
            masses: PyOnceLock::new(),
            betp: PyOnceLock::new(),
            velocity: PyOnceLock::new(),
        }
    }
}

/// What one step gives: the decision and the masses of every cell of the window, their
/// pignistic probabilities, cell velocities, the moving objects, and the frame's record.
///
/// Grids are numpy arrays in world order: row 0 is the southernmost row of the window, column
/// 0 the westernmost (`origin` is the south-west corner of cell (0, 0)), as `classes.json`
/// lists them; plot them with `origin="lower"`. Each is copied out of the session when first
/// read, then kept (read-only): a step copies no grid. Read them before the session's next
/// step: after it, reading one not yet read raises `evigrid.InputError`.
#[pyclass(frozen, module = "evigrid")]
pub struct StepResult {
    session: Py<Session>,
    step: u64,
    index: usize,
    name: String,
    time_s: f64,
    record: session::FrameRecord,
    geometry: Geometry,
    grids: Grids,
}

impl StepResult {
    /// A grid of the session as it stands after this step, made by `make` from its pipeline
    /// with the GIL released, as a read-only array of `shape`; cached in `cell`.
    fn grid<'py, T: numpy::Element + Send>(
        &self,
        py: Python<'py>,
        cell: &PyOnceLock<Py<PyAny>>,
        depth: usize,
        make: impl Fn(&evigrid::Pipeline) -> Option<Vec<T>> + Send + Sync,
    ) -> PyResult<Bound<'py, PyAny>> {
        let array = cell.get_or_try_init(py, || {
            let session = self.session.get();
            let values = py.detach(|| -> PyResult<Option<Vec<T>>> {
                let state = lock(&session.state)?;
                if state.steps != self.step {
                    return Err(input_error(format!(
                        "the result of frame {} ({}) is stale: the session has stepped since; \
                         read its grids before the next step",
                        self.index, self.name
                    )));
                }
                Ok(make(state.session.pipeline()))
            })?;
            match values {
                Some(values) => {
                    let g = self.geometry;
                    let mut shape = vec![g.height, g.width];
                    if depth > 1 {
                        shape.push(depth);
                    }
                    readonly(py, values, &shape).map(Bound::unbind)
                }
                None => Ok(py.None()),
            }
        })?;
        Ok(array.bind(py).clone())
    }
}

/// `per_cell` of every storage cell, in world order.
fn world_order<T>(
    pipeline: &evigrid::Pipeline,
    depth: usize,
    mut per_cell: impl FnMut(usize, &mut Vec<T>),
) -> Vec<T> {
    let window = pipeline.window();
    let mut values = Vec::with_capacity(window.len() * depth);
    for span in window.world_order_spans() {
        for cell in span {
            per_cell(cell, &mut values);
        }
    }
    values
}

#[pymethods]
impl StepResult {
    /// The decision of each cell (SPEC §6): numpy uint8, H × W, the codes of `classes.json`:
    /// 0 unknown, 1 F free, 2 I mapped infrastructure, 3 U unmapped infrastructure, 4 S
    /// stopped, 5 M moving.
    #[getter]
    fn classes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.grid(py, &self.grids.classes, 1, |pipeline| {
            let decisions = pipeline.decisions();
            Some(world_order(pipeline, 1, |cell, out| {
                out.push(decisions[cell] as u8);
            }))
        })
    }

    /// The mass of every focal set of Ω = {F, I, U, S, M}: numpy float32, H × W × 32, set k
    /// being the bitmask k over (F, I, U, S, M) (k = 0 is ∅, 1 {F}, 2 {I}, 3 {F, I}, ..., 31 Ω),
    /// as `masses.json` orders its fields. Each cell's masses sum to 1.
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.grid(py, &self.grids.masses, evigrid::N_SETS, |pipeline| {
            let perception = pipeline.perception();
            let planes: Vec<&[f32]> = (0..evigrid::N_SETS).map(|k| perception.plane(k)).collect();
            Some(world_order(pipeline, evigrid::N_SETS, |cell, out| {
                out.extend(planes.iter().map(|plane| plane[cell]));
            }))
        })
    }

    /// The pignistic probability of F, I, U, S, M in each cell: numpy float32, H × W × 5.
    #[getter]
    fn betp<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.grid(py, &self.grids.betp, 5, |pipeline| {
            let perception = pipeline.perception();
            Some(world_order(pipeline, 5, |cell, out| {
                out.extend(evigrid::betp(&perception.cell_masses(cell)));
            }))
        })
    }

    /// Each cell's velocity east and north in m/s: numpy float32, H × W × 2; `None` for the
    /// method `kurdej2013`, which estimates none.
    #[getter]
    fn velocity<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.grid(py, &self.grids.velocity, 2, |pipeline| {
            let motion = pipeline.fusion().motion()?;
            let (east, north) = (motion.velocity_east(), motion.velocity_north());
            Some(world_order(pipeline, 2, |cell, out| {
                out.extend([east[cell], north[cell]]);
            }))
        })
    }

    /// The objects judged moving this frame: dicts with `id`, `position_m` (east, north),
    /// `velocity_mps`, `sigma_mps` and `cells`, as `frames.jsonl` records them.
    #[getter]
    fn objects<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &self.record.moving_objects)
    }

    /// The frame's record: the line `frames.jsonl` gets (times, shares, counts, the ego-path
    /// check), as a dict.
    #[getter]
    fn record<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &self.record)
    }

    /// The south-west corner of cell (0, 0): (east, north) in metres, in the local frame.
    #[getter]
    fn origin(&self) -> (f64, f64) {
        let [east, north] = self.geometry.origin_m;
        (east, north)
    }

    /// Side of a cell, metres.
    #[getter]
    fn cell_size(&self) -> f64 {
        self.geometry.cell_size_m
    }

    /// The frame's scan name.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// The frame's index in its drive.
    #[getter]
    fn index(&self) -> usize {
        self.index
    }

    /// The frame's time, seconds.
    #[getter]
    fn time(&self) -> f64 {
        self.time_s
    }

    fn __repr__(&self) -> String {
        let g = self.geometry;
        format!(
            "<evigrid.StepResult {} #{}: {} × {} cells of {} m>",
            self.name, self.index, g.height, g.width, g.cell_size_m
        )
    }
}

/// A frame from the caller's arrays: points N × 3 or N × 4, a 4 × 4 rigid transform, a time.
fn frame_from_arrays(
    points: &Bound<'_, PyAny>,
    pose: &Bound<'_, PyAny>,
    time_s: f64,
    index: usize,
    name: Option<String>,
) -> PyResult<drive::Frame> {
    let py = points.py();
    let numpy = py.import("numpy")?;
    let points = as_array(&numpy, points, "float32", "points")?;
    let points: PyReadonlyArray2<'_, f32> = points.extract().map_err(|_| {
        input_error("points: expected an N × 3 or N × 4 array (x, y, z[, intensity])")
    })?;
    let columns = points.shape()[1];
    if columns != 3 && columns != 4 {
        return Err(input_error(format!(
            "points: {} columns; expected 3 (x, y, z) or 4 (x, y, z, intensity)",
            columns
        )));
    }
    let values = points
        .as_slice()
        .map_err(|e| input_error(format!("points: {e}")))?;
    let points_in_sensor: Vec<[f32; 3]> = values
        .chunks_exact(columns)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    let mut intensity: Vec<f32> = if columns == 4 {
        values.chunks_exact(4).map(|p| p[3]).collect()
    } else {
        Vec::new()
    };
    if intensity.iter().all(|i| i.is_nan()) {
        intensity.clear();
    }
    if !time_s.is_finite() {
        return Err(input_error(format!(
            "time {time_s}: not a finite number of seconds"
        )));
    }
    let pose = as_array(&numpy, pose, "float64", "pose")?;
    let pose: PyReadonlyArray2<'_, f64> = pose
        .extract()
        .map_err(|_| input_error("pose: expected a 4 × 4 matrix"))?;
    if pose.shape() != [4, 4] {
        return Err(input_error(format!(
            "pose: shape {:?}; expected a 4 × 4 matrix (world from sensor)",
            pose.shape()
        )));
    }
    let m = pose.as_array();
    let world_from_sensor = rigid(|r, c| m[[r, c]])?;
    Ok(drive::Frame {
        index,
        name: name.unwrap_or_else(|| format!("frame {index}")),
        time_s,
        points_in_sensor,
        intensity,
        world_from_sensor,
        fix: None,
    })
}

/// `value` as a C-contiguous numpy array of `dtype` (a copy only when it is not one already).
fn as_array<'py>(
    numpy: &Bound<'py, PyModule>,
    value: &Bound<'py, PyAny>,
    dtype: &str,
    what: &str,
) -> PyResult<Bound<'py, PyAny>> {
    numpy
        .call_method1("ascontiguousarray", (value, dtype))
        .map_err(|e| input_error(format!("{what}: not an array of numbers: {e}")))
}

/// The rigid transform of a 4 × 4 matrix given entry by entry, checked: finite, rotation part
/// orthonormal with determinant +1 (within 1e-6), last row (0, 0, 0, 1).
fn rigid(entry: impl Fn(usize, usize) -> f64) -> PyResult<Isometry3<f64>> {
    if (0..4).any(|r| (0..4).any(|c| !entry(r, c).is_finite())) {
        return Err(input_error("pose: holds a value that is not finite"));
    }
    let last = [entry(3, 0), entry(3, 1), entry(3, 2), entry(3, 3)];
    if last != [0.0, 0.0, 0.0, 1.0] {
        return Err(input_error(format!(
            "pose: last row {last:?}; a rigid transform's is [0, 0, 0, 1]"
        )));
    }
    let rotation = Matrix3::from_fn(&entry);
    let error = (rotation.transpose() * rotation - Matrix3::identity())
        .abs()
        .max();
    if error > 1e-6 || rotation.determinant() <= 0.0 {
        return Err(input_error(
            "pose: the upper-left 3 × 3 block is not a rotation (orthonormal, determinant +1)",
        ));
    }
    let rotation =
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
    let translation = Translation3::new(entry(0, 3), entry(1, 3), entry(2, 3));
    Ok(Isometry3::from_parts(translation, rotation))
}
