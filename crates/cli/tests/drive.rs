//! `evigrid run` and `evigrid odometry` on the shared KITTI raw frames (drive 0013, frames
//! 80–119): the drive folder as published, pose files in each format matched by time, poses
//! from the odometry, and the errors a user meets. Skipped when the shared data is absent.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use drive::KittiRawDrive;
use drive::poses::{PoseTrack, read_kitti_odometry, read_kitti_times, read_tum, write_tum};

const DATE: &str = "data/lidar/kitti-raw-0013/2011_09_26";
const SYNC: &str = "2011_09_26_drive_0013_sync";

fn date_dir() -> Option<PathBuf> {
    geodata::testdata::shared_file(&format!("{DATE}/calib_imu_to_velo.txt"))?;
    geodata::testdata::shared_file(DATE)
}

fn evigrid() -> Command {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
}

fn json(output: &Output) -> serde_json::Value {
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    with_frames(serde_json::from_slice(&output.stdout).unwrap())
}

/// The summary with its per-frame records (`frames.jsonl` beside it) as `per_frame`.
fn with_frames(mut summary: serde_json::Value) -> serde_json::Value {
    if summary["frames_file"].is_null() {
        return summary; // not a run's summary
    }
    let file =
        Path::new(summary["out"].as_str().unwrap()).join(summary["frames_file"].as_str().unwrap());
    let frames: Vec<serde_json::Value> = std::fs::read_to_string(file)
        .unwrap()
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    summary["per_frame"] = frames.into();
    summary
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// The Velodyne's track at the OXTS packet times (not the scan times), in the frame `run`
/// uses for a drive without a map: transverse Mercator at the first fix.
fn velodyne_at_packet_times(drive: &KittiRawDrive) -> PoseTrack {
    let first = drive.oxts()[0];
    let projection = geodata::TransverseMercator::new(first.lat_deg, first.lon_deg).unwrap();
    drive
        .world_from_imu(&|lat: f64, lon: f64| projection.forward(lat, lon))
        .unwrap()
        .then(&drive.imu_from_velo())
}

fn positions(summary: &serde_json::Value) -> Vec<[f64; 3]> {
    summary["per_frame"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| serde_json::from_value(f["given_position"].clone()).unwrap())
        .collect()
}

fn assert_close(a: &[[f64; 3]], b: &[[f64; 3]], tolerance_m: f64) {
    assert_eq!(a.len(), b.len());
    for (k, (p, q)) in a.iter().zip(b).enumerate() {
        let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
        assert!(d <= tolerance_m, "frame {k}: {p:?} vs {q:?} ({d} m)");
    }
}

/// Links frames `frames` of the drive's scans into `dir` and writes their times beside them as
/// a KITTI odometry `times.txt`.
fn link_frames(date: &Path, dir: &Path, frames: std::ops::Range<usize>) -> PathBuf {
    let data = date.join(SYNC).join("velodyne_points/data");
    let drive = KittiRawDrive::open(&date.join(SYNC)).unwrap();
    std::fs::create_dir_all(dir).unwrap();
    let mut times = String::new();
    for k in frames {
        let name = format!("{k:010}.bin");
        std::os::unix::fs::symlink(data.join(&name), dir.join(&name)).unwrap();
        times += &format!("{}\n", drive.scan_times()[k]);
    }
    std::fs::write(dir.join("times.txt"), times).unwrap();
    dir.to_path_buf()
}

#[test]
fn a_kitti_raw_drive_without_a_map_keeps_the_ego_path_free() {
    let Some(date) = date_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    // KITTI's car: its hood, up to 2.8 m ahead of the Velodyne, is not an obstacle (README).
    let config = tmp.path().join("kitti.toml");
    std::fs::write(&config, "[sensor]\nmin_range_m = 3.0\n").unwrap();
    // The date folder, no other input.
    let summary = json(
        &evigrid()
            .args(["run", "--json", "--drive"])
            .arg(&date)
            .arg("--config")
            .arg(&config)
            .arg("--out")
            .arg(tmp.path().join("out"))
            .output()
            .unwrap(),
    );
    assert_eq!(summary["frames"], 40);
    assert_eq!(summary["prior"], "vacuous (no map)");
    assert_eq!(summary["pose_matching"], "time");
    assert!(summary["poses"].as_str().unwrap().starts_with("OXTS of "));
    let ego = &summary["ego_path"];
    let cell_frames = ego["cell_frames"].as_u64().unwrap();
    let decided = ego["decided_occupied_or_moving"].as_u64().unwrap();
    // Over a hundred path cells per frame are seen; the drive issue's target is at most 2 %.
    // Measured 73 of 5 592 (1.31 %), all in frames 0–9 on the vehicle ahead; 89 (1.59 %)
    // before stray returns were dropped, 18 of them the lidar's phantoms 3–17 m ahead.
    assert!(cell_frames > 40 * 100, "{ego}");
    assert!(decided * 1000 <= cell_frames * 14, "{ego}");
    // Moving path cells are traffic going the ego's way: measured 62 of 63 with a velocity
    // along the path; at most 0.1 % of the path cells move otherwise.
    let moving = ego["moving"].as_u64().unwrap();
    let along = ego["moving_along_path"].as_u64().unwrap();
    assert!(
        along <= moving && (moving - along) * 1000 <= cell_frames,
        "{ego}"
    );
    // The summary states the same as shares (measured 1.13 % moving, 0.02 % apart from traffic).
    // (JSON reading may round the last bit.)
    let share_of = |key: &str| ego[key].as_f64().unwrap() * cell_frames as f64;
    assert!(
        (share_of("moving_share") - moving as f64).abs() < 1e-6,
        "{ego}"
    );
    let apart = share_of("moving_apart_from_traffic_share");
    assert!((apart - (moving - along) as f64).abs() < 1e-6, "{ego}");
    // The stray returns dropped are totalled (measured about 180 a frame).
    let stray = summary["stray_obstacle_points"].as_u64().unwrap();
    assert!((40..40 * 1000).contains(&stray), "{stray}");
    assert_eq!(summary["params"]["sensor"]["ground_model"], "local");
    // The ground model holds: no frame's share of occupied cells far above the drive's median
    // (measured 1.17×).
    let cells = &summary["obstacle_cell_share"];
    assert!(cells["worst_to_median"].as_f64().unwrap() <= 1.6, "{cells}");
    // The OXTS poses are refined: the position used is the registered one, within the gate of
    // the given one (measured 0.07 m median).
    let used: Vec<[f64; 3]> = summary["per_frame"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| serde_json::from_value(f["position"].clone()).unwrap())
        .collect();
    let moved: Vec<f64> = used
        .iter()
        .zip(positions(&summary))
        .map(|(u, g)| ((u[0] - g[0]).powi(2) + (u[1] - g[1]).powi(2)).sqrt())
        .collect();
    assert!(moved.iter().all(|&m| m <= 0.5), "{moved:?}");
    assert!(moved.iter().filter(|&&m| m > 0.0).count() > 30, "{moved:?}");
    // The summary says so: 39 of 40 refined (the first starts the map), median 0.066 m.
    let refinement = &summary["pose_refinement"];
    assert!(
        refinement["outcomes"]["refined"].as_u64().unwrap() > 30,
        "{refinement}"
    );
    assert_eq!(refinement["outcomes"]["first"], 1, "{refinement}");
    let median = refinement["median_correction_m"].as_f64().unwrap();
    let largest = refinement["largest_correction_m"].as_f64().unwrap();
    assert!(
        0.0 < median && median <= largest && largest <= 0.5,
        "{refinement}"
    );
    // About 1.2 m per frame (43 km/h), heading roughly one way.
    let p = positions(&summary);
    let travelled = ((p[39][0] - p[0][0]).powi(2) + (p[39][1] - p[0][1]).powi(2)).sqrt();
    assert!((30.0..60.0).contains(&travelled), "{travelled} m");
    for frame in summary["per_frame"].as_array().unwrap() {
        let (ground, obstacles) = (
            frame["ground_share"].as_f64().unwrap(),
            frame["obstacle_share"].as_f64().unwrap(),
        );
        assert!(
            ground > 0.3 && obstacles < 0.5 && ground + obstacles <= 1.0,
            "{frame}"
        );
    }
    assert!(tmp.path().join("out/frames/decision-000039.png").is_file());
}

/// Issue 30's checks of the moving-object list on the real drive, with the defaults: no speed
/// above `max_speed_mps` (a faster registration is refused, not clamped), every listed object with
/// a velocity, σ, age, hits and existence probability, ids unique in a frame, blips (ids listed
/// moving in at most two frames) at most 10 % of the object-frames, and the car ahead one track.
/// Measured on these 40 frames: 213 object-frames from 11 ids, none faster than 15.2 m/s, blips
/// 0.5 %, the five longest tracks 37, 37, 37, 37 and 31 frames.
#[test]
fn a_kitti_raw_drive_with_the_defaults_lists_moving_objects_a_user_can_use() {
    let Some(date) = date_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let summary = json(
        &evigrid()
            .args(["run", "--json", "--drive"])
            .arg(&date)
            .arg("--out")
            .arg(tmp.path().join("out"))
            .output()
            .unwrap(),
    );
    let max_speed = summary["params"]["motion"]["max_speed_mps"]
        .as_f64()
        .unwrap();
    let mut frames_of_id = std::collections::BTreeMap::<u64, usize>::new();
    for frame in summary["per_frame"].as_array().unwrap() {
        let mut ids_in_frame = std::collections::BTreeSet::new();
        for object in frame["moving_objects"].as_array().unwrap() {
            let id = object["id"].as_u64().unwrap();
            assert!(
                ids_in_frame.insert(id),
                "id {id} twice in {}",
                frame["scan"]
            );
            if object["held_back"].as_bool().unwrap() {
                continue;
            }
            let velocity: [f64; 2] = serde_json::from_value(object["velocity_mps"].clone())
                .unwrap_or_else(|_| panic!("no velocity: {object}"));
            assert!(velocity[0].hypot(velocity[1]) <= max_speed, "{object}");
            for key in ["sigma_mps", "age_s", "existence_probability"] {
                assert!(
                    object[key].as_f64().is_some_and(f64::is_finite),
                    "{key}: {object}"
                );
            }
            assert!(object["hits"].as_u64().unwrap() >= 1, "{object}");
            *frames_of_id.entry(id).or_default() += 1;
        }
    }
    let object_frames: usize = frames_of_id.values().sum();
    let blips: usize = frames_of_id.values().filter(|&&n| n <= 2).sum();
    assert!(object_frames >= 100, "{frames_of_id:?}");
    assert!(blips * 10 <= object_frames, "{frames_of_id:?}");
    // The car ahead is in view through the 40 frames: one id, listed moving in most of them.
    let longest = frames_of_id.values().max().copied().unwrap_or(0);
    assert!(longest >= 30, "{frames_of_id:?}");
}

#[test]
fn the_drive_folder_itself_and_a_missing_calibration() {
    let Some(date) = date_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let run = |drive: &Path| {
        evigrid()
            .args(["run", "--json", "--max-frames", "2", "--drive"])
            .arg(drive)
            .arg("--out")
            .arg(tmp.path().join("out"))
            .output()
            .unwrap()
    };
    let summary = json(&run(&date.join(SYNC)));
    assert_eq!(summary["frames"], 2);
    // A copy of the layout without calib_imu_to_velo.txt.
    let copy = tmp.path().join("2011_09_26");
    std::fs::create_dir_all(&copy).unwrap();
    std::os::unix::fs::symlink(date.join(SYNC), copy.join(SYNC)).unwrap();
    let output = run(&copy);
    assert_eq!(output.status.code(), Some(2));
    let message = stderr(&output);
    assert!(
        message.contains("calib_imu_to_velo.txt") && message.contains("missing"),
        "{message}"
    );
    // A folder that is no drive at all.
    let output = run(tmp.path());
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("no KITTI raw drive here"));
}

#[test]
fn tum_and_kitti_pose_files_are_interpolated_at_the_scan_times() {
    let Some(date) = date_dir() else { return };
    let drive = KittiRawDrive::open(&date.join(SYNC)).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    // Poses at the OXTS packet times, 12–22 ms after each scan: every scan between two packets
    // takes an interpolated pose.
    let track = velodyne_at_packet_times(&drive);
    let tum = tmp.path().join("oxts.tum");
    write_tum(&mut std::fs::File::create(&tum).unwrap(), &track).unwrap();
    let scans = link_frames(&date, &tmp.path().join("scans"), 1..6);
    let run = |poses: &Path, extra: &[&str]| {
        evigrid()
            .args(["run", "--json", "--scans"])
            .arg(&scans)
            .arg("--poses")
            .arg(poses)
            .args(extra)
            .arg("--out")
            .arg(tmp.path().join("out"))
            .output()
            .unwrap()
    };
    let from_tum = json(&run(&tum, &[]));
    assert_eq!(from_tum["pose_matching"], "time");
    // The drive's own poses of frames 1–5 (interpolated the same way).
    let reference = json(
        &evigrid()
            .args(["run", "--json", "--max-frames", "6", "--drive"])
            .arg(&date)
            .arg("--out")
            .arg(tmp.path().join("out-drive"))
            .output()
            .unwrap(),
    );
    let expected = &positions(&reference)[1..6];
    // The drive interpolates the IMU's poses and then adds the lever arm, the file holds the
    // Velodyne's: the two differ by the lever arm's turn within 0.1 s (micrometres).
    assert_close(&positions(&from_tum), expected, 1e-4);

    // The same poses as a KITTI odometry file (the sensor's own poses: no --calib), its format
    // named rather than detected.
    let kitti = tmp.path().join("oxts.kitti");
    drive::poses::write_kitti_odometry(
        &mut std::fs::File::create(&kitti).unwrap(),
        &track,
        &nalgebra::Isometry3::identity(),
    )
    .unwrap();
    // Its times are the packets': give the scan folder the packets' times instead, so that
    // line k is scan k's pose.
    let packet_times = tmp.path().join("packets.txt");
    drive::poses::write_kitti_times(
        &mut std::fs::File::create(&packet_times).unwrap(),
        track.times(),
    )
    .unwrap();
    let all = link_frames(&date, &tmp.path().join("all"), 0..40);
    let from_kitti = json(
        &evigrid()
            .args(["run", "--json", "--max-frames", "3", "--scans"])
            .arg(&all)
            .arg("--times")
            .arg(&packet_times)
            .args(["--pose-format", "kitti", "--poses"])
            .arg(&kitti)
            .arg("--out")
            .arg(tmp.path().join("out-kitti"))
            .output()
            .unwrap(),
    );
    let at_packets: Vec<[f64; 3]> = track.poses()[..3]
        .iter()
        .map(|p| p.translation.vector.into())
        .collect();
    assert_close(&positions(&from_kitti), &at_packets, 1e-6);
}

#[test]
fn a_scan_outside_the_poses_time_span_is_named() {
    let Some(date) = date_dir() else { return };
    let drive = KittiRawDrive::open(&date.join(SYNC)).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let tum = tmp.path().join("oxts.tum");
    write_tum(
        &mut std::fs::File::create(&tum).unwrap(),
        &velodyne_at_packet_times(&drive),
    )
    .unwrap();
    // Scan 0 is taken 12–22 ms before the first packet: outside the file's span.
    let output = evigrid()
        .args(["run", "--drive"])
        .arg(&date)
        .arg("--poses")
        .arg(&tum)
        .arg("--out")
        .arg(tmp.path().join("out"))
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    let message = stderr(&output);
    assert!(
        message.contains("0000000000.bin") && message.contains("outside the poses' span"),
        "{message}"
    );
}

#[test]
fn a_malformed_pose_line_exits_2_naming_file_and_line() {
    let Some(date) = date_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let scans = link_frames(&date, &tmp.path().join("scans"), 0..2);
    let run = |poses: &Path| {
        evigrid()
            .args(["run", "--scans"])
            .arg(&scans)
            .arg("--poses")
            .arg(poses)
            .arg("--out")
            .arg(tmp.path().join("out"))
            .output()
            .unwrap()
    };
    for (name, text, line) in [
        (
            "bad.tum",
            "# t x y z qx qy qz qw\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 x\n",
            3,
        ),
        (
            "bad.kitti",
            "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n",
            2,
        ),
        ("bad.poses", "0 0 0 0 0 0 0\n\n0.1 0 0 0 0 0 0 0 9\n", 3),
    ] {
        let path = tmp.path().join(name);
        std::fs::write(&path, text).unwrap();
        let output = run(&path);
        assert_eq!(output.status.code(), Some(2), "{name}");
        let message = stderr(&output);
        assert!(message.contains(&format!("{name}:{line}")), "{message}");
    }
    let bad_format = evigrid()
        .args(["run", "--pose-format", "utm", "--scans"])
        .arg(&scans)
        .arg("--poses")
        .arg(tmp.path().join("bad.tum"))
        .arg("--out")
        .arg(tmp.path().join("out"))
        .output()
        .unwrap();
    assert_eq!(bad_format.status.code(), Some(2));
    assert!(stderr(&bad_format).contains("unknown pose format `utm`"));
}

#[test]
fn odometry_poses_round_trip_and_feed_a_run() {
    let Some(date) = date_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let odometry = |format: &str, out: &Path| {
        json(
            &evigrid()
                .args([
                    "odometry",
                    "--json",
                    "--max-frames",
                    "8",
                    "--format",
                    format,
                ])
                .arg(&date)
                .arg("--out")
                .arg(out)
                .output()
                .unwrap(),
        )
    };
    let tum = tmp.path().join("odometry.tum");
    let summary = odometry("tum", &tum);
    assert_eq!(summary["frames"], 8);
    assert_eq!(summary["registered"], 7);
    // About 1.2 m per frame on this stretch.
    let path = summary["path_length_m"].as_f64().unwrap();
    assert!((6.0..11.0).contains(&path), "{path} m");
    let kitti = tmp.path().join("odometry.kitti");
    let summary = odometry("kitti", &kitti);
    let times_file = PathBuf::from(summary["times_file"].as_str().unwrap());
    assert_eq!(times_file, tmp.path().join("odometry.times.txt"));

    // Both files read back to the same track, at the scan times.
    let from_tum = read_tum(&tum).unwrap();
    let times = read_kitti_times(&times_file).unwrap();
    let from_kitti = read_kitti_odometry(&kitti, &times, &nalgebra::Isometry3::identity()).unwrap();
    let drive = KittiRawDrive::open(&date).unwrap();
    assert_eq!(from_tum.times(), &drive.scan_times()[..8]);
    assert_eq!(from_kitti.times(), from_tum.times());
    for (a, b) in from_tum.poses().iter().zip(from_kitti.poses()) {
        assert!((a.translation.vector - b.translation.vector).norm() < 1e-12);
        assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
    }

    // A run on those poses, and a run that computes them itself, are given the same poses (the
    // first refines them, by default; the second does not).
    let with_file = json(
        &evigrid()
            .args(["run", "--json", "--max-frames", "8", "--drive"])
            .arg(&date)
            .arg("--poses")
            .arg(&tum)
            .arg("--out")
            .arg(tmp.path().join("out-file"))
            .output()
            .unwrap(),
    );
    let scans = link_frames(&date, &tmp.path().join("scans"), 0..8);
    let by_itself = json(
        &evigrid()
            .args(["run", "--json", "--scans"])
            .arg(&scans)
            .arg("--out")
            .arg(tmp.path().join("out-odometry"))
            .output()
            .unwrap(),
    );
    assert_eq!(by_itself["poses"], "lidar odometry");
    assert_eq!(by_itself["pose_matching"], "odometry");
    // The odometry's poses are registrations already: not refined again. Poses from a file are.
    assert_eq!(by_itself["params"]["localisation"]["refinement"], "none");
    assert!(by_itself["pose_refinement"].is_null());
    assert_eq!(
        with_file["params"]["localisation"]["refinement"],
        "scan_to_map"
    );
    let outcome = |summary: &serde_json::Value, frame: usize| {
        summary["per_frame"][frame]["stats"]["pose_refinement"]["outcome"].clone()
    };
    assert_eq!(outcome(&by_itself, 3), "off");
    assert_eq!(outcome(&with_file, 0), "first");
    assert_close(&positions(&with_file), &positions(&by_itself), 1e-9);
}

#[test]
fn a_mounting_places_the_sensor_on_the_vehicle() {
    let Some(date) = date_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let scans = link_frames(&date, &tmp.path().join("scans"), 0..2);
    let times: Vec<f64> = read_kitti_times(&scans.join("times.txt")).unwrap();
    // The vehicle drives north (yaw 90°) at ground level; the sensor sits 0.5 m ahead of its
    // origin, 1.73 m up.
    let vehicle: String = times
        .iter()
        .enumerate()
        .map(|(k, t)| format!("{t} 0 {} 0 0 0 1.5707963267948966\n", k as f64))
        .collect();
    let poses = tmp.path().join("vehicle.txt");
    std::fs::write(&poses, vehicle).unwrap();
    let summary = json(
        &evigrid()
            .args(["run", "--json", "--mounting", "0.5,0,1.73,0,0,0", "--scans"])
            .arg(&scans)
            .arg("--poses")
            .arg(&poses)
            .arg("--out")
            .arg(tmp.path().join("out"))
            .output()
            .unwrap(),
    );
    assert_close(
        &positions(&summary),
        &[[0.0, 0.5, 1.73], [0.0, 1.5, 1.73]],
        1e-9,
    );
}
