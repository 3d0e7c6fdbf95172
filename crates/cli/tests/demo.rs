//! `evigrid demo` end to end: the embedded map and scenario, a few frames, every output checked.

#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::process::Command;

const FRAMES: usize = 3;

fn run_demo(out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(["demo", "--frames", &FRAMES.to_string(), "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn demo_writes_every_view_per_frame_the_gif_and_the_report() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    let output = run_demo(&out, &[]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(stdout.contains("full"), "{stdout}");
    assert!(stdout.contains("no-map"), "{stdout}");
    assert!(stdout.contains("OpenStreetMap contributors"), "{stdout}");
    assert!(stdout.contains(&format!("{FRAMES} frames")), "{stdout}");

    // Exactly FRAMES of each view: --frames limits the drive.
    for view in ["pignistic", "decision", "trace"] {
        for k in 0..FRAMES {
            let png = out.join("frames").join(format!("{view}-{k:06}.png"));
            let bytes = std::fs::read(&png).unwrap();
            assert!(bytes.starts_with(b"\x89PNG"), "{}", png.display());
        }
        let missing = out.join("frames").join(format!("{view}-{FRAMES:06}.png"));
        assert!(!missing.exists(), "{} exists", missing.display());
    }
    let gif = std::fs::read(out.join("decision.gif")).unwrap();
    assert!(gif.starts_with(b"GIF89a"));
    let frames = image::codecs::gif::GifDecoder::new(std::io::Cursor::new(gif)).unwrap();
    let count = image::AnimationDecoder::into_frames(frames).count();
    assert_eq!(count, FRAMES);

    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    let names: Vec<&str> = metrics["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["variant"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["full", "no-map"]);
    assert_eq!(metrics["frames_per_seed"], FRAMES);
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.starts_with("# evigrid demo"), "{report}");
    assert!(report.contains("OpenStreetMap contributors, ODbL"));
    for png in [
        "confusion-full.png",
        "confusion-no-map.png",
        "per-class-iou.png",
    ] {
        assert!(out.join(png).is_file(), "{png}");
    }
}

#[test]
fn demo_json_prints_the_metrics() {
    let tmp = tempfile::tempdir().unwrap();
    let output = run_demo(&tmp.path().join("demo"), &["--json"]);
    assert!(output.status.success());
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(json["variants"].as_array().unwrap().len(), 2);
}

#[test]
fn demo_rejects_zero_frames() {
    let tmp = tempfile::tempdir().unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(["demo", "--frames", "0", "--out"])
        .arg(tmp.path())
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("--frames"));
}
