//! `evigrid bag` from the outside, on the drive crate's ROS 2 MCAP fixture.

use std::path::PathBuf;
use std::process::{Command, Output};

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../drive/tests/fixtures/kitti-0013.mcap")
}

fn evigrid(args: &[&str]) -> std::io::Result<Output> {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .output()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn info_lists_topics_and_the_drive() -> Result<(), Box<dyn std::error::Error>> {
    let path = fixture();
    let path = path.to_str().ok_or("path")?;
    let output = evigrid(&["bag", "info", path])?;
    assert!(output.status.success(), "{}", text(&output.stderr));
    let stdout = text(&output.stdout);
    for needle in [
        "messages: 125 over",
        "/velodyne_points  sensor_msgs/msg/PointCloud2        4  cdr",
        "/tf_static",
        "4 scans on /velodyne_points (frame velodyne), poses: tf odom -> velodyne (40 samples)",
    ] {
        assert!(stdout.contains(needle), "{needle} not in {stdout}");
    }
    let output = evigrid(&["bag", "info", path, "--json"])?;
    assert!(output.status.success());
    let json: serde_json::Value = serde_json::from_slice(&output.stdout)?;
    assert_eq!(json["messages"], 125);
    assert_eq!(json["topics"][1]["topic"], "/odom");
    assert_eq!(json["topics"][1]["count"], 40);
    assert_eq!(json["drive"]["scans"], 4);
    assert!(json["end_s"].as_f64().ok_or("end")? > json["start_s"].as_f64().ok_or("start")?);
    Ok(())
}

#[test]
fn a_file_that_is_not_mcap_is_bad_input() -> Result<(), Box<dyn std::error::Error>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("x.mcap");
    std::fs::write(&path, b"not an mcap file at all")?;
    let output = evigrid(&["bag", "info", path.to_str().ok_or("path")?])?;
    assert_eq!(output.status.code(), Some(2));
    let stderr = text(&output.stderr);
    assert!(stderr.contains("x.mcap"), "{stderr}");
    Ok(())
}

/// `evigrid run --bag`: the recording's scans at the poses of tf or the odometry topic (the same
/// trajectory, so the same positions), or of the lidar odometry when asked for none.
#[test]
fn run_reads_a_recording_with_each_pose_source() -> Result<(), Box<dyn std::error::Error>> {
    let path = fixture();
    let path = path.to_str().ok_or("path")?;
    let tmp = tempfile::tempdir()?;
    let run = |source: &str| -> Result<
        (serde_json::Value, Vec<serde_json::Value>),
        Box<dyn std::error::Error>,
    > {
        let out = tmp.path().join(source);
        let out_str = out.to_str().ok_or("out")?;
        let output = evigrid(&[
            "run",
            "--json",
            "--no-mcap",
            "--bag",
            path,
            "--pose-source",
            source,
            "--out",
            out_str,
        ])?;
        assert!(
            output.status.success(),
            "{source}: {}",
            text(&output.stderr)
        );
        let summary: serde_json::Value = serde_json::from_slice(&output.stdout)?;
        let frames = std::fs::read_to_string(out.join("frames.jsonl"))?
            .lines()
            .map(serde_json::from_str)
            .collect::<Result<Vec<serde_json::Value>, _>>()?;
        Ok((summary, frames))
    };
    let (tf, tf_frames) = run("tf")?;
    assert_eq!(tf["frames"], 4);
    assert_eq!(tf["pose_matching"], "time");
    assert!(
        tf["poses"].as_str().ok_or("poses")?.starts_with("tf "),
        "{}",
        tf["poses"]
    );
    let (odom, odom_frames) = run("odom")?;
    for (a, b) in tf_frames.iter().zip(&odom_frames) {
        for axis in 0..3 {
            let (p, q) = (
                a["given_position"][axis].as_f64().ok_or("x")?,
                b["given_position"][axis].as_f64().ok_or("x")?,
            );
            assert!((p - q).abs() < 1e-3, "tf {p} vs odom {q}");
        }
    }
    assert_eq!(odom["frames"], 4);
    let (none, _) = run("none")?;
    assert_eq!(none["poses"], "lidar odometry");
    assert_eq!(none["frames"], 4);
    // NavSatFix poses need a local frame to be placed in.
    let output = evigrid(&[
        "run",
        "--bag",
        path,
        "--pose-source",
        "navsat",
        "--out",
        "x",
    ])?;
    assert_eq!(output.status.code(), Some(2));
    assert!(text(&output.stderr).contains("need --map or --origin"));
    Ok(())
}

/// A rosbag2 folder (as `ros2 bag record` writes it) is read as its MCAP file; before, `--bag`
/// and `bag info` failed on it with "Is a directory (os error 21)".
#[test]
fn a_rosbag2_folder_is_read_as_its_recording() -> Result<(), Box<dyn std::error::Error>> {
    let dir = tempfile::tempdir()?;
    let bag = dir.path().join("kitti_0013");
    std::fs::create_dir(&bag)?;
    std::fs::copy(fixture(), bag.join("kitti_0013_0.mcap"))?;
    std::fs::write(
        bag.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  \
         relative_file_paths:\n    - kitti_0013_0.mcap\n",
    )?;
    let output = evigrid(&["bag", "info", bag.to_str().ok_or("path")?, "--json"])?;
    assert!(output.status.success(), "{}", text(&output.stderr));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout)?;
    assert_eq!(json["messages"], 125);
    assert_eq!(json["drive"]["scans"], 4);
    // A folder of SQLite storage says what to do, in one line, as bad input.
    let sqlite = dir.path().join("old");
    std::fs::create_dir(&sqlite)?;
    std::fs::write(sqlite.join("old_0.db3"), b"")?;
    let output = evigrid(&["bag", "info", sqlite.to_str().ok_or("path")?])?;
    assert_eq!(output.status.code(), Some(2));
    let stderr = text(&output.stderr);
    assert!(stderr.contains("ros2 bag convert"), "{stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    Ok(())
}
