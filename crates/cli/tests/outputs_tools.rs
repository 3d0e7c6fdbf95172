//! Every export of `evigrid run` and `evigrid demo` read back by tools that are not evigrid's:
//! `scripts/check_outputs.py` with the Python `mcap` reader, `jsonschema`, a nav2-rules PGM
//! loader, Pillow and pyproj (see its docstring for the checks).
//!
//! The Python interpreter is `$EVIGRID_PYTHON` (`.ci/run` sets it to a venv holding the
//! packages), else `python3`. Without the packages the tests skip with a note, unless
//! `EVIGRID_REQUIRE_PYTHON=1` (CI), where a skip is a failure.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// Exit code of the script when a Python package is missing.
const MISSING_PACKAGE: i32 = 77;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn evigrid(args: &[&str]) {
    let output = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "evigrid {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Runs the checker on `out`; `false` if it was skipped for a missing package.
fn check_outputs(out: &Path, args: &[&str]) -> bool {
    let python = std::env::var("EVIGRID_PYTHON").unwrap_or_else(|_| "python3".to_string());
    let required = std::env::var("EVIGRID_REQUIRE_PYTHON").is_ok_and(|v| v == "1");
    let result = Command::new(&python)
        .arg(repo().join("scripts/check_outputs.py"))
        .arg(out)
        .args(args)
        .output();
    let output = match result {
        Ok(output) => output,
        Err(error) => {
            assert!(!required, "{python}: {error} (EVIGRID_REQUIRE_PYTHON=1)");
            eprintln!("note: {python} cannot run ({error}); skipping the output checks");
            return false;
        }
    };
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    if output.status.code() == Some(MISSING_PACKAGE) {
        assert!(!required, "{stderr} (EVIGRID_REQUIRE_PYTHON=1)");
        eprintln!("note: {}; skipping the output checks", stderr.trim());
        return false;
    }
    assert!(
        output.status.success(),
        "check_outputs.py {}:\n{stdout}\n{stderr}",
        out.display()
    );
    assert!(stdout.contains("all checks passed"), "{stdout}");
    print!("{stdout}");
    true
}

#[test]
fn demo_outputs_open_in_foreign_tools() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let out_text = out.to_str().unwrap();
    evigrid(&["demo", "--frames", "5", "--out", out_text]);
    let geojson = repo().join("crates/cli/assets/helsinki-demo.geojson");
    // The demo's local frame: the full Helsinki extract's origin (demo.rs's FULL_MAP_ORIGIN).
    check_outputs(
        &out,
        &[
            "--frames",
            "5",
            "--origin",
            "60.1716340,24.9442954",
            "--geojson",
            geojson.to_str().unwrap(),
        ],
    );
}

#[test]
fn kitti_run_outputs_open_in_foreign_tools() {
    let Some(drive) = geodata::testdata::shared_file("data/lidar/kitti-raw-0013/2011_09_26") else {
        return;
    };
    // The local frame's origin is the drive's first OXTS fix: read here from the file itself.
    let sync = std::fs::read_dir(&drive)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with("_sync"))
        .unwrap();
    let first = std::fs::read_to_string(sync.join("oxts/data/0000000000.txt")).unwrap();
    let fields: Vec<&str> = first.split_whitespace().take(2).collect();
    let origin = fields.join(",");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let drive_text = drive.to_str().unwrap();
    evigrid(&[
        "run",
        "--drive",
        drive_text,
        "--max-frames",
        "5",
        "--out",
        out.to_str().unwrap(),
    ]);
    check_outputs(
        &out,
        &[
            "--frames",
            "5",
            "--origin",
            &origin,
            "--kitti-drive",
            drive_text,
            "--no-map",
        ],
    );
}

#[test]
fn no_mcap_leaves_the_recording_out() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    evigrid(&[
        "demo",
        "--frames",
        "2",
        "--no-mcap",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!out.join("run.mcap").exists());
    assert!(out.join("occupancy.json").exists() && out.join("map.yaml").exists());
}
