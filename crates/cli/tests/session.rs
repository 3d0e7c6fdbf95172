//! The command line and the library give the same figures for the same drive: `evigrid run`
//! over the bag fixture against `session::run_drive` over the same drive.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::AtomicBool;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../drive/tests/fixtures/kitti-0013.mcap")
}

#[test]
fn the_cli_and_the_library_give_the_same_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let output = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(["run", "--json", "--no-mcap", "--bag"])
        .arg(fixture())
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let cli: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();

    let drive = drive::Drive::open(&drive::DriveSpec::Bag {
        path: fixture(),
        cloud_topic: None,
        pose_source: drive::PoseSource::Auto,
    })
    .unwrap();
    let summary = session::run_drive(
        drive,
        session::SessionConfig::default(),
        &mut [],
        &AtomicBool::new(false),
    )
    .unwrap();
    // Through text as the command line's figures are: serde_json's default float parsing can
    // land one unit in the last place off the printed value (0.09644027127196961 read back as
    // 0.0964402712719696), which compares the parsers, not the figures.
    let library: serde_json::Value =
        serde_json::from_str(&serde_json::to_string(&summary).unwrap()).unwrap();

    assert_eq!(cli["frames"], 4);
    for key in [
        "complete",
        "method",
        "prior",
        "poses",
        "pose_matching",
        "params",
        "frames",
        "points",
        "dropped_non_finite",
        "dropped_out_of_range",
        "dropped_outside_window",
        "stray_obstacle_points",
        "final_classes",
        "moving_trace_cells",
        "ego_path",
        "obstacle_share",
        "obstacle_share_in_range",
        "obstacle_cell_share",
        "pose_refinement",
        "skipped_scans",
    ] {
        assert_eq!(cli[key], library[key], "{key}");
    }
}
