//! `evigrid run` end to end on real KITTI scans and a real OSM map (from the shared data).
//!
//! The KITTI street is not in any of the shared OSM files, so the drive is placed on the
//! Bavarian village's map along a made-up straight line: this checks the command's wiring,
//! outputs and statistics, not the method's accuracy.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::read_png;

fn shared() -> Option<PathBuf> {
    geodata::testdata::shared_file("data/lidar/kitti-city-22")?;
    geodata::testdata::shared_file("data/osm/bavarian-village.osm")?;
    geodata::testdata::shared_dir()
}

/// Links the first `n` KITTI scans into `dir` (no copy of the data).
fn link_scans(shared: &Path, dir: &Path, n: usize) -> Vec<PathBuf> {
    let source = shared.join("data/lidar/kitti-city-22");
    let mut names: Vec<_> = std::fs::read_dir(&source)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    std::fs::create_dir_all(dir).unwrap();
    names
        .into_iter()
        .take(n)
        .map(|p| {
            let link = dir.join(p.file_name().unwrap());
            std::os::unix::fs::symlink(&p, &link).unwrap();
            link
        })
        .collect()
}

fn evigrid() -> Command {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
}

#[test]
fn runs_end_to_end_on_real_scans() {
    let Some(shared) = shared() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let scans = tmp.path().join("scans");
    link_scans(&shared, &scans, 3);
    // 10 Hz, 1 m per scan eastwards (36 km/h), the lidar 1.73 m above the map's ground.
    let poses =
        "# time x y z roll pitch yaw\n0.0 0 0 1.73 0 0 0\n0.1 1 0 1.73 0 0 0\n0.2 2 0 1.73 0 0 0\n";
    std::fs::write(tmp.path().join("poses.txt"), poses).unwrap();
    // The poses are made up: the default pose refinement would move them towards what the
    // real scans show, and the window's shift below tests the poses as given.
    std::fs::write(
        tmp.path().join("p.toml"),
        "[window]\nwidth_cells = 200\nheight_cells = 160\n[localisation]\nrefinement = \"none\"\n",
    )
    .unwrap();
    let out = tmp.path().join("out");
    let output = evigrid()
        .args(["run", "--json", "--map"])
        .arg(shared.join("data/osm/bavarian-village.osm"))
        .arg("--scans")
        .arg(&scans)
        .arg("--poses")
        .arg(tmp.path().join("poses.txt"))
        .arg("--config")
        .arg(tmp.path().join("p.toml"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let mut summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(summary["frames"], 3);
    // What wrote the run, and how to run it again.
    assert_eq!(
        summary["tool"],
        concat!("evigrid ", env!("CARGO_PKG_VERSION"))
    );
    let command = summary["command_line"].as_str().unwrap();
    assert!(
        command.contains(" run --json --map ") && command.contains("bavarian-village.osm"),
        "{command}"
    );
    // The per-frame records are streamed to frames.jsonl, one object per line.
    let frames: Vec<serde_json::Value> = std::fs::read_to_string(out.join("frames.jsonl"))
        .unwrap()
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    assert_eq!(frames.len(), 3);
    // Every record lists the objects judged moving (the default method has a motion stage).
    assert!(
        frames.iter().all(|f| f["moving_objects"].is_array()),
        "{frames:?}"
    );
    summary["per_frame"] = frames.into();
    assert_eq!(summary["params"]["window"]["width_cells"], 200);
    let classes: Vec<u64> = serde_json::from_value(summary["final_classes"].clone()).unwrap();
    assert_eq!(classes.iter().sum::<u64>(), 200 * 160);
    // Most of a city street around the car is seen free; something is occupied.
    let [_unknown, free, i, u, s, m] = classes[..] else {
        panic!("six classes")
    };
    assert!(free > 2000, "{classes:?}");
    assert!(i + u + s + m > 100, "{classes:?}");
    let frame0 = &summary["per_frame"][0]["stats"]["sensor"];
    assert_eq!(frame0["points"], 119_978);
    // The default ground model is the local one: no plane, and most of a street scan is ground.
    assert!(frame0["ground_plane"].is_null());
    let ground = summary["per_frame"][0]["ground_share"].as_f64().unwrap();
    let obstacles = summary["per_frame"][0]["obstacle_share"].as_f64().unwrap();
    assert!(ground > 0.4 && obstacles < 0.5, "{ground} {obstacles}");
    assert_eq!(summary["per_frame"][1]["stats"]["entered_cells"], 2 * 160);
    for name in [
        "frames/decision-000000.png",
        "frames/decision-000002.png",
        "decision.png",
        "pignistic.png",
        "trace.png",
        "occupancy.json",
        "masses.json",
        "masses.bin",
        "summary.json",
    ] {
        assert!(out.join(name).is_file(), "{name} missing");
    }
    // A frame's picture: the 200 × 160 map, the ego marked, a legend strip under it.
    let (width, height, colour, pixels) = read_png(&out.join("frames/decision-000000.png"));
    assert_eq!((width, height), (200, 160 + output::STRIP_PX));
    assert_eq!(colour, png::ColorType::Rgb);
    assert!(
        pixels.chunks_exact(3).any(|p| p == output::PATH.0),
        "the ego is marked"
    );
    let occupancy: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("occupancy.json")).unwrap()).unwrap();
    assert_eq!(occupancy["data"].as_array().unwrap().len(), 200 * 160);
    assert_eq!(
        std::fs::metadata(out.join("masses.bin")).unwrap().len(),
        200 * 160 * 35 * 4
    );
}

#[test]
fn bad_input_exits_with_status_2_naming_the_file() {
    let Some(shared) = shared() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let scans = tmp.path().join("scans");
    link_scans(&shared, &scans, 2);
    let poses = tmp.path().join("poses.txt");
    std::fs::write(&poses, "0.0 0 0 1.73 0 0 0\n").unwrap();
    let run = |map: &Path, poses: &Path| {
        evigrid()
            .args(["run", "--map"])
            .arg(map)
            .arg("--scans")
            .arg(&scans)
            .arg("--poses")
            .arg(poses)
            .arg("--out")
            .arg(tmp.path().join("out"))
            .output()
            .unwrap()
    };
    let map = shared.join("data/osm/bavarian-village.osm");
    let output = run(&map, &poses);
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("poses.txt") && stderr.contains("1 poses for 2 scans"),
        "{stderr}"
    );
    let output = run(&tmp.path().join("nope.osm"), &poses);
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("nope.osm"));
    std::fs::write(&poses, "0.0 0 0 1.73 0 0 0\nzero 1 0 1.73 0 0 0\n").unwrap();
    let output = run(&map, &poses);
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("poses.txt:2"));
}

/// Three scans with poses 1 m apart eastwards, written into `dir`; returns the scans folder and
/// the pose file.
fn small_drive(shared: &Path, dir: &Path, x0_m: f64) -> (PathBuf, PathBuf) {
    let scans = dir.join("scans");
    link_scans(shared, &scans, 3);
    let poses = dir.join("poses.txt");
    let lines: String = (0..3)
        .map(|k| {
            format!(
                "{} {} 0 1.73 0 0 0\n",
                0.1 * f64::from(k),
                x0_m + f64::from(k)
            )
        })
        .collect();
    std::fs::write(&poses, lines).unwrap();
    (scans, poses)
}

#[test]
fn runs_without_a_map_and_says_so() {
    let Some(shared) = shared() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (scans, poses) = small_drive(&shared, tmp.path(), 0.0);
    std::fs::write(
        tmp.path().join("p.toml"),
        "[window]\nwidth_cells = 200\nheight_cells = 160\n",
    )
    .unwrap();
    let output = evigrid()
        .args(["run", "--json", "--scans"])
        .arg(&scans)
        .arg("--poses")
        .arg(&poses)
        .arg("--config")
        .arg(tmp.path().join("p.toml"))
        .arg("--out")
        .arg(tmp.path().join("out"))
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(summary["frames"], 3);
    assert!(summary["map"].is_null());
    assert_eq!(summary["prior"], "vacuous (no map)");
    // Without a map nothing can be mapped infrastructure.
    assert_eq!(summary["final_classes"][2], 0);
    assert!(summary["final_classes"][1].as_u64().unwrap() > 2000);
}

#[test]
fn poses_far_from_the_map_are_an_error_naming_the_first() {
    let Some(shared) = shared() else { return };
    let tmp = tempfile::tempdir().unwrap();
    // 50 km east of the village's centre.
    let (scans, poses) = small_drive(&shared, tmp.path(), 50_000.0);
    let output = evigrid()
        .args(["run", "--map"])
        .arg(shared.join("data/osm/bavarian-village.osm"))
        .arg("--scans")
        .arg(&scans)
        .arg("--poses")
        .arg(&poses)
        .arg("--out")
        .arg(tmp.path().join("out"))
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("poses.txt")
            && stderr.contains("pose 1 (scan 1)")
            && stderr.contains("m outside the extent")
            && stderr.contains("give that point as --origin LAT,LON"),
        "{stderr}"
    );
    assert!(output.stdout.is_empty());
    assert!(!tmp.path().join("out").exists());
}

#[test]
fn wgs84_poses_without_a_map_need_an_origin() {
    let Some(shared) = shared() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (scans, poses) = small_drive(&shared, tmp.path(), 0.0);
    std::fs::write(
        &poses,
        "# frame: wgs84\n0 -33.9 151.2 0 0 0 0\n0.1 -33.9 151.2 0 0 0 0\n0.2 -33.9 151.2 0 0 0 0\n",
    )
    .unwrap();
    let run = |origin: Option<&str>| {
        let mut command = evigrid();
        command
            .args(["run", "--scans"])
            .arg(&scans)
            .arg("--poses")
            .arg(&poses)
            .arg("--out")
            .arg(tmp.path().join("out"));
        if let Some(origin) = origin {
            command.args(["--origin", origin]);
        }
        command.output().unwrap()
    };
    let without = run(None);
    assert_eq!(without.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&without.stderr).contains("need --map or --origin"));
    // A southern, eastern origin is a value, not an option.
    let with = run(Some("-33.9,151.2"));
    assert!(
        with.status.success(),
        "{}",
        String::from_utf8_lossy(&with.stderr)
    );
}
