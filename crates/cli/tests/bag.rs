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
