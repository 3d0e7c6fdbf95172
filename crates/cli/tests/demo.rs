//! `evigrid demo` end to end: the embedded map and scenario, a few frames, every output checked.

#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::process::Command;

const FRAMES: usize = 3;

mod common;
use common::read_png;

/// Decodes the GIF `bytes` with the `gif` decoder: (screen width, height, frame count).
fn read_gif(bytes: &[u8]) -> (u16, u16, usize) {
    let mut decoder = gif::DecodeOptions::new()
        .read_info(std::io::Cursor::new(bytes))
        .unwrap();
    let mut frames = 0;
    while decoder.read_next_frame().unwrap().is_some() {
        frames += 1;
    }
    (decoder.width(), decoder.height(), frames)
}

fn run_demo(out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(["demo", "--frames", &FRAMES.to_string(), "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn demo_writes_the_gif_the_final_views_and_the_report() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    let output = run_demo(&out, &[]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(stdout.contains("evigrid"), "{stdout}");
    assert!(stdout.contains("kurdej2013"), "{stdout}");
    assert!(stdout.contains("no-map"), "{stdout}");
    assert!(stdout.contains("OpenStreetMap contributors"), "{stdout}");
    assert!(stdout.contains(&format!("{FRAMES} frames")), "{stdout}");

    // No per-frame PNG: the page shows the drive as the GIF, which has exactly FRAMES frames
    // (--frames limits the drive).
    assert!(
        !out.join("frames").exists(),
        "per-frame files the page does not use"
    );
    let gif = std::fs::read(out.join("decision.gif")).unwrap();
    assert!(gif.starts_with(b"GIF89a"));
    let (gif_width, _, count) = read_gif(&gif);
    assert_eq!(count, FRAMES);

    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    let names: Vec<&str> = metrics["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["variant"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["evigrid", "kurdej2013", "no-map"]);
    assert_eq!(metrics["frames_per_seed"], FRAMES);
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.starts_with("# evigrid demo"), "{report}");
    assert!(report.contains("OpenStreetMap contributors, ODbL"));
    for png in [
        "confusion-evigrid.png",
        "confusion-kurdej2013.png",
        "confusion-no-map.png",
        "per-class-iou.png",
    ] {
        assert!(out.join(png).is_file(), "{png}");
    }

    // Truth beside prediction: the final figure holds two panels of at least 800 px, the GIF
    // two panels at 1 px a cell.
    let (width, height, _, _) = read_png(&out.join("decision.png"));
    assert!(width > 2 * 800 && height > 800);
    assert!(gif_width >= 640);

    // index.html: every picture and link it names is in the folder (relative, no network).
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    for needle in [
        "decision.gif",
        "per-class-iou.png",
        "<table>",
        "M  moving object",
    ] {
        assert!(html.contains(needle), "{needle} not in index.html");
    }
    let mut targets = 0;
    for attr in ["src=\"", "href=\""] {
        for part in html.split(attr).skip(1) {
            let target = &part[..part.find('"').unwrap()];
            assert!(
                !target.contains("//") && !target.starts_with('/'),
                "{target}"
            );
            assert!(
                out.join(target).exists(),
                "index.html names missing {target}"
            );
            targets += 1;
        }
    }
    assert!(targets >= 10, "{targets} links");
}

#[test]
fn demo_json_prints_the_metrics() {
    let tmp = tempfile::tempdir().unwrap();
    let output = run_demo(&tmp.path().join("demo"), &["--json"]);
    assert!(output.status.success());
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(json["variants"].as_array().unwrap().len(), 3);
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

/// The embedded scenario is a minute long and its ego stays on the embedded crop the whole time:
/// inside the map's extent with room for the scanner to see mapped streets, never inside a
/// building, and moving (a loop of about 480 m, not a car parked at a snapped waypoint).
#[test]
fn demo_drive_is_a_minute_on_the_embedded_map() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let map_bytes = std::fs::read(dir.join("helsinki-demo.geojson")).unwrap();
    // The origin of the full Helsinki extract, as `evigrid demo` loads the crop.
    let options = geodata::LoadOptions {
        origin: Some((60.171_634_0, 24.944_295_4)),
    };
    let map = geodata::load_map_from_bytes(&map_bytes, &options)
        .unwrap()
        .map;
    let text = std::fs::read_to_string(dir.join("demo-scenario.toml")).unwrap();
    let scenario = sim::Scenario::from_toml(&text).unwrap();
    assert_eq!(scenario.frame_count(), 600, "one minute at 10 Hz");
    let mut drive = sim::Drive::new(&map, &scenario).unwrap();
    let extent = map.extent;
    let margin_m = 15.0;
    let mut path_m = 0.0;
    let mut last = drive.ego_pose().position_m;
    while drive.next_frame().is_some() {
        let p = drive.ego_pose().position_m;
        assert!(
            p.x > extent.min().x + margin_m
                && p.x < extent.max().x - margin_m
                && p.y > extent.min().y + margin_m
                && p.y < extent.max().y - margin_m,
            "ego at ({:.1}, {:.1}) leaves the crop {extent:?}",
            p.x,
            p.y
        );
        assert!(
            drive.world().building_at(p).is_none(),
            "ego in a building at {p:?}"
        );
        path_m += ((p.x - last.x).powi(2) + (p.y - last.y).powi(2)).sqrt();
        last = p;
    }
    assert!(
        path_m > 300.0,
        "the ego drove only {path_m:.0} m in a minute"
    );
}
