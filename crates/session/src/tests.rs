#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use drive::{Drive, DriveSpec, PoseSource};
use output::OutputError;
use output::sink::{FinalView, FrameSink, FrameView};

use super::*;

fn fixture_bag() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../drive/tests/fixtures/kitti-0013.mcap")
}

fn bag() -> Drive {
    Drive::open(&DriveSpec::Bag {
        path: fixture_bag(),
        cloud_topic: None,
        pose_source: PoseSource::Auto,
    })
    .unwrap()
}

/// A sink that records what it is called with, and fails on frame `fail_at` if given.
#[derive(Default)]
struct Recorder {
    frames: Vec<(usize, String, usize)>,
    records: Vec<serde_json::Value>,
    finished: Vec<(usize, f64)>,
    fail_at: Option<usize>,
}

impl FrameSink for Recorder {
    fn on_frame(&mut self, frame: &FrameView<'_>) -> Result<(), OutputError> {
        if self.fail_at == Some(frame.index) {
            return Err(OutputError::Io {
                path: PathBuf::from("disk"),
                source: std::io::Error::other("full"),
            });
        }
        self.frames.push((
            frame.index,
            frame.name.to_string(),
            frame.points_in_sensor.len(),
        ));
        Ok(())
    }

    fn on_record(&mut self, record_json: &str) -> Result<(), OutputError> {
        self.records
            .push(serde_json::from_str(record_json).unwrap());
        Ok(())
    }

    fn finish(&mut self, last: &FinalView<'_>) -> Result<(), OutputError> {
        self.finished.push((last.driven.len(), last.time_s));
        Ok(())
    }
}

#[test]
fn every_frame_goes_to_every_sink_and_each_is_finished_once() {
    let drive = bag();
    let times = drive.times().unwrap().to_vec();
    let (mut a, mut b) = (Recorder::default(), Recorder::default());
    let summary = run_drive(
        drive,
        SessionConfig::default(),
        &mut [&mut a, &mut b],
        &AtomicBool::new(false),
    )
    .unwrap();
    assert!(summary.complete && summary.stopped.is_none());
    assert_eq!(summary.frames, 4);
    assert_eq!(summary.pose_matching, "time");
    for sink in [&a, &b] {
        let indices: Vec<usize> = sink.frames.iter().map(|f| f.0).collect();
        assert_eq!(indices, [0, 1, 2, 3]);
        assert_eq!(sink.frames[2].1, "kitti-0013.mcap#000002");
        assert!(sink.frames.iter().all(|f| f.2 > 0));
        // One record per frame, in order, whose points add up to the summary's.
        assert_eq!(sink.records.len(), 4);
        assert_eq!(sink.records[3]["scan"], "kitti-0013.mcap#000003");
        let points: u64 = sink
            .records
            .iter()
            .map(|r| r["stats"]["sensor"]["points"].as_u64().unwrap())
            .sum();
        assert_eq!(points as usize, summary.points);
        // Finished once, with the path of the four scans reached and the last one's time.
        assert_eq!(sink.finished, vec![(4, times[3])]);
    }
}

#[test]
fn a_failing_sink_ends_the_session_with_an_incomplete_summary() {
    let mut failing = Recorder {
        fail_at: Some(1),
        ..Recorder::default()
    };
    let error = run_drive(
        bag(),
        SessionConfig::default(),
        &mut [&mut failing],
        &AtomicBool::new(false),
    )
    .unwrap_err();
    assert!(!error.is_bad_input() && !error.is_interrupted());
    let SessionError::Stopped { summary, cause } = error else {
        panic!("not stopped: {error}");
    };
    assert!(matches!(*cause, SessionError::Output(_)));
    assert!(!summary.complete);
    let stopped = summary.stopped.unwrap();
    assert!(
        stopped.contains("frame 1") && stopped.contains("disk"),
        "{stopped}"
    );
    // Frame 0 was done; frame 1 was processed but not counted; the sink is still finished.
    assert_eq!(summary.frames, 1);
    assert_eq!(failing.frames.len(), 1);
    assert_eq!(failing.finished.len(), 1);
}

#[test]
fn a_raised_stop_flag_ends_the_session_before_the_next_frame() {
    let mut sink = Recorder::default();
    let error = run_drive(
        bag(),
        SessionConfig::default(),
        &mut [&mut sink],
        &AtomicBool::new(true),
    )
    .unwrap_err();
    assert!(error.is_interrupted());
    let SessionError::Stopped { summary, .. } = error else {
        panic!("not stopped");
    };
    assert_eq!(summary.frames, 0);
    assert!(summary.stopped.unwrap().contains("interrupted"));
    assert!(sink.frames.is_empty());
    assert_eq!(sink.finished, vec![(0, 0.0)]);
}

/// A sink that raises the stop flag as it receives frame `at`.
struct StopAt<'a> {
    at: usize,
    stop: &'a AtomicBool,
    seen: usize,
}

impl FrameSink for StopAt<'_> {
    fn on_frame(&mut self, frame: &FrameView<'_>) -> Result<(), OutputError> {
        self.seen += 1;
        if frame.index == self.at {
            self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        }
        Ok(())
    }

    fn finish(&mut self, _last: &FinalView<'_>) -> Result<(), OutputError> {
        Ok(())
    }
}

#[test]
fn a_stop_flag_raised_during_the_last_frame_leaves_a_complete_drive() {
    let frames = bag().times().unwrap().len();
    let stop = AtomicBool::new(false);
    let mut sink = StopAt {
        at: frames - 1,
        stop: &stop,
        seen: 0,
    };
    let summary = run_drive(bag(), SessionConfig::default(), &mut [&mut sink], &stop)
        .expect("every frame was done before the flag was looked at");
    assert!(summary.complete);
    assert_eq!(summary.frames, frames);
    assert_eq!(sink.seen, frames);
}

#[test]
fn a_stop_flag_raised_during_an_earlier_frame_interrupts_before_the_next() {
    let frames = bag().times().unwrap().len();
    assert!(frames >= 2, "the test drive has {frames} frames");
    let stop = AtomicBool::new(false);
    let mut sink = StopAt {
        at: frames - 2,
        stop: &stop,
        seen: 0,
    };
    let error = run_drive(bag(), SessionConfig::default(), &mut [&mut sink], &stop).unwrap_err();
    assert!(error.is_interrupted());
    assert_eq!(sink.seen, frames - 1);
}

#[test]
fn stepping_frame_by_frame_gives_the_whole_drive_s_figures() {
    let config = SessionConfig::default;
    let whole = run_drive(bag(), config(), &mut [], &AtomicBool::new(false)).unwrap();

    let drive = bag();
    let poses = drive.place(None, usize::MAX).unwrap();
    let mut session = Session::new(config()).unwrap();
    session.set_path(poses.positions());
    for frame in drive.frames(&poses).unwrap() {
        let frame = frame.unwrap();
        let step = session.step(&frame).unwrap();
        let window = step.window();
        assert_eq!(step.decisions().len(), window.width() * window.height());
        assert_eq!(step.cell_size_m(), window.cell_size_m());
        let (east, north) = step.velocity().unwrap();
        assert_eq!(east.len(), step.decisions().len());
        assert_eq!(north.len(), east.len());
        let p = step.pignistic(0);
        let total: f32 = p.iter().sum();
        assert!((total - 1.0).abs() < 1e-4, "{p:?}");
        assert!(step.moving_objects().iter().all(|o| o.cells > 0));
        assert_eq!(step.record.scan, frame.name);
    }
    let stepped = session.summary();
    assert_eq!(stepped.frames, whole.frames);
    assert_eq!(stepped.points, whole.points);
    assert_eq!(stepped.final_classes, whole.final_classes);
    assert_eq!(stepped.moving_trace_cells, whole.moving_trace_cells);
    assert_eq!(stepped.ego_path.cell_frames, whole.ego_path.cell_frames);
}
