//! `evigrid bench`: the report's shape and its errors (timings themselves are not tested: they
//! belong to the machine, not to the code).

use std::process::{Command, Output};

type TestResult = Result<(), Box<dyn std::error::Error>>;

fn evigrid(args: &[&str]) -> std::io::Result<Output> {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .output()
}

const SMALL: [&str; 6] = [
    "bench",
    "--sizes",
    "24",
    "--rounds",
    "2",
    "--synthetic-only",
];

#[test]
fn a_small_run_prints_every_step_case_ratio_and_the_scaling_line() -> TestResult {
    let out = evigrid(&SMALL)?;
    let stdout = String::from_utf8(out.stdout)?;
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let threads = std::thread::available_parallelism()?.get();
    for case in [
        "copy@1".to_string(),
        "step@1".into(),
        format!("step@{threads}"),
        format!("apart@{threads}"),
        format!("apart-fastest@{threads}"),
        format!("ideal@{threads}"),
        "step@1/step@N".into(),
        "step@1/ideal@N".into(),
        "ideal@N/step@N".into(),
        "all threads: when every core stepped its own grid".into(),
    ] {
        assert!(stdout.contains(&case), "no {case:?} in\n{stdout}");
    }
    Ok(())
}

#[test]
fn json_holds_the_ratios_with_their_targets() -> TestResult {
    let mut args = SMALL.to_vec();
    args.push("--json");
    let out = evigrid(&args)?;
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let window = &report["windows"][0];
    assert_eq!(window["size"], 24);
    let ratio = |name: &str| {
        window["ratios"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|pair| pair[0] == name)
            .and_then(|pair| pair[1].as_f64())
    };
    for name in ["step@1/step@N", "step@1/ideal@N", "ideal@N/step@N"] {
        let value = ratio(name);
        assert!(
            value.is_some_and(|v| v.is_finite() && v > 0.0),
            "{name}: {value:?}"
        );
    }
    let checks = window["checks"].as_array().map_or(0, Vec::len);
    assert!(checks >= 3, "targets checked: {checks}");
    Ok(())
}

#[test]
fn bad_options_exit_2_with_one_line_naming_the_option() -> TestResult {
    for (args, named) in [
        (
            vec!["bench", "--rounds", "0", "--synthetic-only"],
            "--rounds",
        ),
        (vec!["bench", "--sizes", "0", "--synthetic-only"], "--sizes"),
        (vec!["bench", "--cell-size=-1"], "--cell-size"),
        (
            vec!["bench", "--sizes", "24", "--scan", "/nonexistent/scan.pcd"],
            "/nonexistent/scan.pcd: scan file not found",
        ),
    ] {
        let out = evigrid(&args)?;
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(out.stdout.is_empty(), "{args:?} printed results");
        assert!(stderr.contains(named), "{args:?}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    }
    Ok(())
}

#[test]
fn the_drive_case_refuses_a_missing_folder_and_skips_without_the_shared_data() -> TestResult {
    for (args, named) in [
        (
            vec!["bench", "--drive-only", "--drive", "/nonexistent/drive"],
            "--drive /nonexistent/drive: not a folder",
        ),
        (
            vec!["bench", "--drive-only", "--synthetic-only"],
            "--synthetic-only",
        ),
    ] {
        let out = evigrid(&args)?;
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(named), "{args:?}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    }
    // No shared data: a note on standard error, nothing measured, success; with `--json` the
    // one document says `"drive": null`.
    let empty = tempfile::tempdir()?;
    for json in [false, true] {
        let mut args = vec!["bench", "--drive-only"];
        if json {
            args.push("--json");
        }
        let out = Command::new(env!("CARGO_BIN_EXE_evigrid"))
            .args(&args)
            .env("EVIGRID_SHARED", empty.path())
            .output()?;
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(stderr.contains("drive case skipped"), "{stderr}");
        if json {
            let report: serde_json::Value = serde_json::from_slice(&out.stdout)?;
            assert!(report["drive"].is_null(), "{report}");
        } else {
            assert!(out.stdout.is_empty());
        }
    }
    Ok(())
}

#[test]
fn real_cases_time_the_ground_and_the_odometry_against_the_step() -> TestResult {
    let drive =
        "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync/velodyne_points/data";
    let (Some(scans), Some(map)) = (
        geodata::testdata::shared_file(drive),
        geodata::testdata::shared_file("data/osm/bavarian-village.osm"),
    ) else {
        return Ok(());
    };
    let scan = scans.join("0000000000.bin");
    let args = [
        "bench",
        "--json",
        "--sizes",
        "32",
        "--rounds",
        "2",
        "--naive-rounds",
        "0",
        "--scan",
        scan.to_str().ok_or("path")?,
        "--map",
        map.to_str().ok_or("path")?,
        "--odometry-scans",
        scans.to_str().ok_or("path")?,
    ];
    let out = evigrid(&args)?;
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let window = &report["windows"][0];
    for case in ["ground@1", "odometry@1"] {
        let timed = window["timings"]
            .as_array()
            .into_iter()
            .flatten()
            .any(|t| t["case"] == case && t["median_ms"].as_f64().is_some_and(|ms| ms > 0.0));
        assert!(timed, "no {case} in {window}");
    }
    for ratio in ["ground@1/step@1", "odometry@1/step@1"] {
        let found = window["ratios"]
            .as_array()
            .into_iter()
            .flatten()
            .any(|pair| pair[0] == ratio && pair[1].as_f64().is_some_and(|v| v > 0.0));
        assert!(found, "no {ratio} in {window}");
    }
    Ok(())
}
