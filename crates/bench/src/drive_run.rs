//! The `drive` case: a whole drive run as `evigrid run --drive` runs it by default, in this
//! process, with every default output on (the Foxglove recording, the per-frame pictures,
//! `frames.jsonl`, the final figures and grids, `summary.json`), into a folder the caller gives
//! (a temporary one). It measures the process's CPU time (user + sys, every thread) over the
//! run, from opening the drive to the last file, and prints the drive's duration over it: the
//! brief's "real time on a CPU with every output on" is `drive_s / cpu_s` ≥ 2 (issue 29: at most
//! 0.5 CPU-seconds per second of drive). Run it on one core (`taskset -c 0`), as the goal is
//! stated for one.
//!
//! The per-stage shares come from the run's own per-frame timings (`frames.jsonl`): each
//! stage's milliseconds summed over the frames, over the run's wall time; what no frame's
//! timing covers (opening the drive, placing the poses, the final figures and exports) is the
//! `start and end` share.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use output::sink::{DecisionFrames, FinalOutputs, FrameSink, FramesLog, McapSink};
use serde::Serialize;

/// Clock ticks per second of `/proc/self/stat`'s CPU times (`USER_HZ`, 100 on Linux whatever
/// the kernel's own tick rate).
const USER_HZ: f64 = 100.0;

/// The goal: seconds of drive per CPU-second, at least (0.5 CPU-s per second of drive).
pub const TARGET_DRIVE_PER_CPU: f64 = 2.0;

/// What a `drive` run measured.
#[derive(Clone, Debug, Serialize)]
pub struct DriveRunReport {
    /// The drive's folder.
    pub drive: String,
    /// Frames processed.
    pub frames: usize,
    /// The drive's duration, seconds: last scan time − first + one mean scan period
    /// ([`drive_seconds`]).
    pub drive_s: f64,
    /// The process's CPU time over the run, user + sys, seconds (resolution 0.01 s).
    pub cpu_s: f64,
    /// The run's wall time, seconds.
    pub wall_s: f64,
    /// `drive_s / cpu_s`: seconds of drive per CPU-second (target ≥ 2).
    pub drive_per_cpu: f64,
    /// Where the wall time went, by stage, in the order of [`STAGES`] then `start and end`.
    pub stages: Vec<StageShare>,
}

/// One stage's part of the run.
#[derive(Clone, Debug, Serialize)]
pub struct StageShare {
    /// The stage.
    pub stage: &'static str,
    /// Its milliseconds, summed over the frames.
    pub ms: f64,
    /// Its share of the run's wall time.
    pub share: f64,
}

/// The stages of a frame's timings: name and the field of a `frames.jsonl` record (a path of
/// keys). `other processing` is `process_ms` less the four stages inside it.
pub const STAGES: [(&str, &[&str]); 7] = [
    ("reading", &["read_ms"]),
    ("sensor model", &["stats", "sensor_ms"]),
    ("pose refinement", &["stats", "pose_refinement", "ms"]),
    ("fusion step", &["stats", "step_ms"]),
    ("motion stage", &["stats", "motion_ms"]),
    ("other processing", &["process_ms"]),
    ("outputs per frame", &["render_ms"]),
];

/// Why the `drive` case could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DriveRunError {
    /// The drive could not be opened or read.
    #[error(transparent)]
    Drive(#[from] drive::SourceError),
    /// The session failed.
    #[error(transparent)]
    Session(#[from] session::SessionError),
    /// An output could not be written.
    #[error(transparent)]
    Output(#[from] output::OutputError),
    /// `summary.json` could not be written.
    #[error("writing summary.json: {0}")]
    Summary(String),
    /// This system gives no process CPU time (`/proc/self/stat`).
    #[error("no process CPU time on this system (/proc/self/stat)")]
    NoCpuTime,
    /// The drive has fewer than two frames: no duration.
    #[error("{0}: fewer than two frames, no drive duration")]
    TooShort(String),
}

/// Runs the KITTI raw drive in `drive_dir` with the defaults of `evigrid run --drive` (method
/// `evigrid`, default parameters, no map) and every default output, written into `out` (an
/// existing folder), and measures it.
///
/// # Errors
/// The drive, the session or an output failing; no CPU time on this system; a drive of fewer
/// than two frames.
pub fn run_drive(drive_dir: &Path, out: &Path) -> Result<DriveRunReport, DriveRunError> {
    let cpu_start = process_cpu_s().ok_or(DriveRunError::NoCpuTime)?;
    let wall_start = Instant::now();
    let drive = drive::Drive::open(&drive::DriveSpec::KittiRaw {
        dir: drive_dir.to_path_buf(),
        poses: None,
    })?;
    let config = session::SessionConfig {
        params: evigrid::Params::default(),
        method: evigrid::Method::Evigrid,
        map: None,
        origin: None,
        strict: false,
        max_frames: None,
        out: out.display().to_string(),
    };
    let stop = AtomicBool::new(false);
    let placement = session::place(drive, &config, &stop, &mut ())?;
    let mut mcap = McapSink::create(&out.join("run.mcap"), None)?;
    let mut frames = DecisionFrames::create(&out.join("frames"))?;
    let mut log = FramesLog::create(&out.join(session::FRAMES_FILE))?;
    let mut last = FinalOutputs::new(out);
    let mut timings = Timings::default();
    let outcome = {
        let mut sinks: [&mut dyn FrameSink; 5] =
            [&mut mcap, &mut frames, &mut log, &mut last, &mut timings];
        session::run_placed(placement, config, &mut sinks, &stop, &mut ())?
    };
    if let Some(error) = outcome.error {
        return Err(error.into());
    }
    let text = serde_json::to_string_pretty(&outcome.summary)
        .map_err(|e| DriveRunError::Summary(e.to_string()))?;
    output::write_atomic(&out.join("summary.json"), |file| {
        std::io::Write::write_all(file, text.as_bytes())
    })
    .map_err(|e| DriveRunError::Summary(e.to_string()))?;
    let wall_s = wall_start.elapsed().as_secs_f64();
    let cpu_s = process_cpu_s().ok_or(DriveRunError::NoCpuTime)? - cpu_start;
    let drive_s = drive_seconds(&timings.times_s)
        .ok_or_else(|| DriveRunError::TooShort(drive_dir.display().to_string()))?;
    Ok(DriveRunReport {
        drive: drive_dir.display().to_string(),
        frames: timings.times_s.len(),
        drive_s,
        cpu_s,
        wall_s,
        drive_per_cpu: drive_per_cpu(drive_s, cpu_s),
        stages: timings.shares(wall_s * 1000.0),
    })
}

/// A drive's duration from its scan times, seconds: last − first plus one mean period (the
/// last scan lasts one too). `None` with fewer than two scans or times out of order.
pub fn drive_seconds(times_s: &[f64]) -> Option<f64> {
    let (first, last) = (*times_s.first()?, *times_s.last()?);
    let span = last - first;
    (times_s.len() >= 2 && span > 0.0).then(|| span + span / (times_s.len() - 1) as f64)
}

/// Seconds of drive per CPU-second: `drive_s / cpu_s`; infinite for no CPU time.
pub fn drive_per_cpu(drive_s: f64, cpu_s: f64) -> f64 {
    if cpu_s > 0.0 {
        drive_s / cpu_s
    } else {
        f64::INFINITY
    }
}

/// This process's CPU time so far, user + sys, every thread, seconds (`/proc/self/stat`);
/// `None` where there is none (not Linux).
pub fn process_cpu_s() -> Option<f64> {
    cpu_s_of_stat(&std::fs::read_to_string("/proc/self/stat").ok()?)
}

/// User + sys, seconds, of a `/proc/<pid>/stat` line: fields 14 and 15 (`utime`, `stime`, in
/// clock ticks), counted after the command name, which may hold spaces and parentheses.
fn cpu_s_of_stat(stat: &str) -> Option<f64> {
    let after_name = &stat[stat.rfind(')')? + 1..];
    // Field 3 (the state) is the first after the name: utime is the 12th, stime the 13th.
    let mut fields = after_name.split_whitespace().skip(11);
    let utime: u64 = fields.next()?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    Some((utime + stime) as f64 / USER_HZ)
}

/// The sink that keeps each frame's time and stage timings from its record.
#[derive(Default)]
struct Timings {
    times_s: Vec<f64>,
    /// Per stage of [`STAGES`], milliseconds summed over the frames.
    ms: [f64; STAGES.len()],
}

impl Timings {
    /// The stages' shares of `wall_ms`, `other processing` less the stages inside it, and the
    /// rest as `start and end`.
    fn shares(&self, wall_ms: f64) -> Vec<StageShare> {
        let mut ms = self.ms;
        // `process_ms` holds the sensor model, refinement, step and motion stage.
        ms[5] = (ms[5] - ms[1] - ms[2] - ms[3] - ms[4]).max(0.0);
        let rest = (wall_ms - ms.iter().sum::<f64>()).max(0.0);
        let share = |v: f64| if wall_ms > 0.0 { v / wall_ms } else { 0.0 };
        STAGES
            .iter()
            .zip(ms)
            .map(|(&(stage, _), ms)| (stage, ms))
            .chain([("start and end", rest)])
            .map(|(stage, ms)| StageShare {
                stage,
                ms,
                share: share(ms),
            })
            .collect()
    }
}

impl FrameSink for Timings {
    fn on_frame(&mut self, frame: &output::sink::FrameView<'_>) -> Result<(), output::OutputError> {
        self.times_s.push(frame.time_s);
        Ok(())
    }

    fn on_record(&mut self, record_json: &str) -> Result<(), output::OutputError> {
        let Ok(record) = serde_json::from_str::<serde_json::Value>(record_json) else {
            return Ok(());
        };
        for (sum, (_, path)) in self.ms.iter_mut().zip(STAGES) {
            let value = path.iter().try_fold(&record, |v, key| v.get(key));
            *sum += value.and_then(serde_json::Value::as_f64).unwrap_or(0.0);
        }
        Ok(())
    }

    fn finish(&mut self, _: &output::sink::FinalView<'_>) -> Result<(), output::OutputError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drive_lasts_its_span_plus_one_mean_period() {
        // KITTI raw 0013: 40 scans over 4.0391 s, one period 4.0391 / 39 = 0.103567 s.
        let times: Vec<f64> = (0..40).map(|i| 100.0 + 4.0391 * i as f64 / 39.0).collect();
        let drive_s = drive_seconds(&times).unwrap_or_default();
        assert!((drive_s - 4.142667).abs() < 1e-6, "{drive_s}");
        // Two scans 0.1 s apart: 0.2 s of drive.
        assert!((drive_seconds(&[5.0, 5.1]).unwrap_or_default() - 0.2).abs() < 1e-12);
        assert_eq!(drive_seconds(&[5.0]), None);
        assert_eq!(drive_seconds(&[]), None);
        assert_eq!(drive_seconds(&[5.0, 4.0]), None);
    }

    #[test]
    fn the_ratio_is_drive_seconds_per_cpu_second() {
        // 4.1426 s of drive in 1.70 CPU-s: 2.4368 s of drive per CPU-s (0.41 CPU-s per s).
        assert!((drive_per_cpu(4.1426, 1.70) - 2.436823).abs() < 1e-6);
        assert!(drive_per_cpu(4.1426, 2.5) < TARGET_DRIVE_PER_CPU);
        assert_eq!(drive_per_cpu(1.0, 0.0), f64::INFINITY);
    }

    #[test]
    fn cpu_time_is_read_after_the_command_name() {
        // utime 150 and stime 23 ticks: 1.73 s; the name holds a space and a parenthesis.
        let stat = "4242 (evi grid) x) R 1 4242 4242 0 -1 4194304 2512 0 0 0 150 23 0 0 20 0 3";
        assert!((cpu_s_of_stat(stat).unwrap_or_default() - 1.73).abs() < 1e-12);
        assert_eq!(cpu_s_of_stat("4242 (evigrid) R 1 2"), None);
        assert_eq!(cpu_s_of_stat("no name"), None);
        // This process has a CPU time on Linux.
        if cfg!(target_os = "linux") {
            assert!(process_cpu_s().is_some_and(|s| s >= 0.0));
        }
    }

    #[test]
    fn each_record_adds_its_stage_timings() {
        // Two records as `frames.jsonl` writes them (fields trimmed); the second has no
        // refinement timing, which adds nothing.
        let mut timings = Timings::default();
        let first = r#"{"read_ms":1.5,"process_ms":30.0,"render_ms":6.0,"stats":{"sensor_ms":10.0,"step_ms":1.0,"motion_ms":2.0,"pose_refinement":{"ms":12.0}}}"#;
        let second = r#"{"read_ms":0.5,"process_ms":20.0,"render_ms":4.0,"stats":{"sensor_ms":9.0,"step_ms":1.0,"motion_ms":3.0,"pose_refinement":null}}"#;
        for record in [first, second, "not json"] {
            assert!(timings.on_record(record).is_ok());
        }
        assert_eq!(timings.ms, [2.0, 19.0, 12.0, 2.0, 5.0, 50.0, 10.0]);
        // Over 100 ms of wall: other processing 50 − 19 − 12 − 2 − 5 = 12 ms, and 100 − 2 − 19
        // − 12 − 2 − 5 − 12 − 10 = 38 ms at start and end.
        let shares = timings.shares(100.0);
        assert!((shares[5].ms - 12.0).abs() < 1e-12 && (shares[7].ms - 38.0).abs() < 1e-12);
    }

    #[test]
    fn shares_split_the_processing_and_leave_the_rest_to_start_and_end() {
        // Over 1000 ms of wall: reading 10, sensor 200, refinement 300, step 50, motion 40,
        // processing 650 in all (60 other), outputs 200: 860 ms in frames, 140 at start and end.
        let timings = Timings {
            times_s: vec![],
            ms: [10.0, 200.0, 300.0, 50.0, 40.0, 650.0, 200.0],
        };
        let shares = timings.shares(1000.0);
        let got: Vec<(&str, f64)> = shares.iter().map(|s| (s.stage, s.share)).collect();
        let want = [
            ("reading", 0.01),
            ("sensor model", 0.2),
            ("pose refinement", 0.3),
            ("fusion step", 0.05),
            ("motion stage", 0.04),
            ("other processing", 0.06),
            ("outputs per frame", 0.2),
            ("start and end", 0.14),
        ];
        assert_eq!(got.len(), want.len());
        for ((stage, share), (want_stage, want_share)) in got.iter().zip(want) {
            assert_eq!(*stage, want_stage);
            assert!((share - want_share).abs() < 1e-12, "{stage} {share}");
        }
    }
}
