//! Where a session's frames go: one trait, [`FrameSink`], and the sinks `evigrid run` writes
//! (the Foxglove recording, the per-frame decision pictures, `frames.jsonl`, the final figures
//! and grids). A caller picks the sinks it wants; a new output is a new implementation, not an
//! edit of the frame loop.
//!
//! The session calls, per processed frame, [`FrameSink::on_frame`] on every sink in order, then
//! [`FrameSink::on_record`] with the frame's numbers as one line of JSON; at the end (also after
//! an early stop) [`FrameSink::finish`] on every sink. A sink's error ends the session as an
//! I/O error does: the summary is marked incomplete and says why.

use std::io::Write;
use std::path::{Path, PathBuf};

use evigrid::motion::MotionStage;
use evigrid::{GisGrid, IsometryMatrix3, Label, MovingTrace, PerceptionGrid, SensorGrid, Window};

use crate::mcap::{GnssFix, McapFrame, McapGrid, McapRecorder};
use crate::run_figures::{Views, final_figures};
use crate::{
    COLOURS, GridExports, OutputError, WholeLines, frame_picture, write_grid_exports,
    write_indexed_png, write_png,
};

/// One processed frame, as the grids stand after it (borrowed: nothing is copied).
#[derive(Clone, Copy)]
pub struct FrameView<'a> {
    /// Frame number in the session, from 0 (skipped scans count).
    pub index: usize,
    /// The scan's name.
    pub name: &'a str,
    /// The scan's time, seconds.
    pub time_s: f64,
    /// The window.
    pub window: &'a Window,
    /// Decisions, storage order.
    pub decisions: &'a [Label],
    /// Masses.
    pub perception: &'a PerceptionGrid,
    /// The scan's own evidence.
    pub sensor_grid: &'a SensorGrid,
    /// The motion stage (the `evigrid` method), with cell velocities and moving objects.
    pub motion: Option<&'a MotionStage>,
    /// The pose the grids were built with (after any refinement).
    pub world_from_sensor: &'a IsometryMatrix3,
    /// The scan, sensor frame.
    pub points_in_sensor: &'a [[f32; 3]],
    /// The intensity of each point, or empty when the scan has none.
    pub intensity: &'a [f32],
    /// The sensor's height above the ground under it, metres (`sensor.ground.sensor_height_m`):
    /// where the recording draws the grid below the sensor.
    pub sensor_height_m: f64,
    /// The GNSS fix taken with the scan, if any.
    pub fix: Option<GnssFix>,
}

/// The grids as a session ends (after its last processed frame).
#[derive(Clone, Copy)]
pub struct FinalView<'a> {
    /// The window.
    pub window: &'a Window,
    /// Decisions, storage order.
    pub decisions: &'a [Label],
    /// Masses.
    pub perception: &'a PerceptionGrid,
    /// Every cell ever decided moving.
    pub trace: &'a MovingTrace,
    /// The motion stage (the `evigrid` method).
    pub motion: Option<&'a MotionStage>,
    /// The map's contexts, when there is a map.
    pub gis: Option<&'a GisGrid>,
    /// The ego's path over the scans reached, metres (east, north).
    pub driven: &'a [[f64; 2]],
    /// Time of the last scan reached, seconds (0 when none).
    pub time_s: f64,
    /// The local frame's projection, when the session has one.
    pub projection: Option<&'a geodata::TransverseMercator>,
}

/// What receives a session's frames.
pub trait FrameSink {
    /// Called after each processed frame, in frame order.
    ///
    /// # Errors
    ///
    /// The sink's [`OutputError`]; the session stops after it.
    fn on_frame(&mut self, frame: &FrameView<'_>) -> Result<(), OutputError>;

    /// Called after [`FrameSink::on_frame`] of every sink, with the frame's record: one JSON
    /// object, no newline. Nothing by default.
    ///
    /// # Errors
    ///
    /// The sink's [`OutputError`]; the session stops after it.
    fn on_record(&mut self, record_json: &str) -> Result<(), OutputError> {
        let _ = record_json;
        Ok(())
    }

    /// Called once at the end, also after an early stop.
    ///
    /// # Errors
    ///
    /// The sink's [`OutputError`]; the summary is marked incomplete.
    fn finish(&mut self, last: &FinalView<'_>) -> Result<(), OutputError>;
}

/// The Foxglove recording (`run.mcap`): per frame the decision grid, the pose, the scan and the
/// GNSS fix; the map's outlines once ([`McapRecorder`]).
pub struct McapSink {
    recorder: Option<McapRecorder>,
}

impl McapSink {
    /// Starts the recording at `path` (written atomically when finished).
    ///
    /// # Errors
    ///
    /// [`OutputError`] if the file cannot be created.
    pub fn create(path: &Path, map: Option<&geodata::LocalMap>) -> Result<Self, OutputError> {
        Ok(Self {
            recorder: Some(McapRecorder::create(path, map)?),
        })
    }
}

impl FrameSink for McapSink {
    fn on_frame(&mut self, frame: &FrameView<'_>) -> Result<(), OutputError> {
        let Some(recorder) = &mut self.recorder else {
            return Ok(());
        };
        recorder.write_frame(&McapFrame {
            time_s: frame.time_s,
            window: frame.window,
            decisions: frame.decisions,
            perception: frame.perception,
            world_from_sensor: frame.world_from_sensor,
            points_in_sensor: frame.points_in_sensor,
            intensity: frame.intensity,
            sensor_height_m: frame.sensor_height_m,
            fix: frame.fix,
        })
    }

    fn finish(&mut self, last: &FinalView<'_>) -> Result<(), OutputError> {
        // Closed even after an early stop: what it holds stays readable.
        match self.recorder.take() {
            // The final grid, if the recorder's interval skipped the last frame's.
            Some(recorder) => recorder
                .finish(Some(&McapGrid {
                    window: last.window,
                    decisions: last.decisions,
                    perception: last.perception,
                }))
                .map(|_| ()),
            None => Ok(()),
        }
    }
}

/// The decision map of every frame, `decision-NNNNNN.png` (north up, one pixel per cell, the
/// one palette, the ego marked, a legend strip under it: [`frame_picture`]).
pub struct DecisionFrames {
    dir: PathBuf,
}

impl DecisionFrames {
    /// Pictures in `dir`, created if missing.
    ///
    /// # Errors
    ///
    /// [`OutputError::Io`] if the folder cannot be created.
    pub fn create(dir: &Path) -> Result<Self, OutputError> {
        std::fs::create_dir_all(dir).map_err(|source| OutputError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        Ok(Self {
            dir: dir.to_path_buf(),
        })
    }
}

impl FrameSink for DecisionFrames {
    fn on_frame(&mut self, frame: &FrameView<'_>) -> Result<(), OutputError> {
        let (x, y) = (
            frame.world_from_sensor.translation.x,
            frame.world_from_sensor.translation.y,
        );
        let image = frame_picture(frame.window, frame.decisions, [x, y], &COLOURS)?;
        let name = format!("decision-{:06}.png", frame.index);
        // A palette PNG (the picture has a few dozen colours): the same pixels as RGB with a
        // third of the bytes or fewer to filter and deflate (docs/benchmarks.md).
        write_indexed_png(&image, &self.dir.join(name))
    }

    fn finish(&mut self, _last: &FinalView<'_>) -> Result<(), OutputError> {
        Ok(())
    }
}

/// The per-frame records, one JSON object per line, written as the session goes (so that an
/// interrupted run keeps them, and memory does not grow with the drive).
pub struct FramesLog {
    path: PathBuf,
    /// Whole records only: a process that ends at once on a signal never leaves a torn line.
    file: WholeLines<std::fs::File>,
}

impl FramesLog {
    /// Creates the log at `path` (the caller's output policy has decided it may be written).
    ///
    /// # Errors
    ///
    /// [`OutputError::Io`] if the file cannot be created.
    pub fn create(path: &Path) -> Result<Self, OutputError> {
        let file = std::fs::File::create(path).map_err(|source| OutputError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            file: WholeLines::new(file),
        })
    }

    fn io(&self, source: std::io::Error) -> OutputError {
        OutputError::Io {
            path: self.path.clone(),
            source,
        }
    }
}

impl FrameSink for FramesLog {
    fn on_frame(&mut self, _frame: &FrameView<'_>) -> Result<(), OutputError> {
        Ok(())
    }

    fn on_record(&mut self, record_json: &str) -> Result<(), OutputError> {
        self.file
            .write_all(record_json.as_bytes())
            .and_then(|()| self.file.write_all(b"\n"))
            .map_err(|e| self.io(e))
    }

    fn finish(&mut self, _last: &FinalView<'_>) -> Result<(), OutputError> {
        self.file.flush().map_err(|e| self.io(e))
    }
}

/// The final figures (`decision.png`, `pignistic.png`, `trace.png`) and the grids in the
/// field's formats ([`write_grid_exports`]), written in one folder when the session ends.
pub struct FinalOutputs {
    dir: PathBuf,
}

impl FinalOutputs {
    /// Final outputs in `dir` (which must exist).
    pub fn new(dir: &Path) -> Self {
        Self {
            dir: dir.to_path_buf(),
        }
    }
}

impl FrameSink for FinalOutputs {
    fn on_frame(&mut self, _frame: &FrameView<'_>) -> Result<(), OutputError> {
        Ok(())
    }

    fn finish(&mut self, last: &FinalView<'_>) -> Result<(), OutputError> {
        // Figures for people: enlarged, legend, scale bar, north arrow, map outlines, the path
        // so far.
        let views = Views {
            window: last.window,
            perception: last.perception,
            decisions: last.decisions,
            trace: last.trace,
            motion: last.motion,
        };
        for (name, image) in final_figures(&views, last.gis, last.driven)? {
            write_png(&image, &self.dir.join(name))?;
        }
        // For the tools of the field: ROS OccupancyGrid, classes, masses, nav2, georeferenced.
        write_grid_exports(
            &self.dir,
            &GridExports {
                window: last.window,
                decisions: last.decisions,
                perception: last.perception,
                time_s: last.time_s,
                projection: last.projection,
            },
        )?;
        Ok(())
    }
}
