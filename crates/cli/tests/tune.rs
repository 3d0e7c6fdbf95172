//! `evigrid tune` end to end on a real OSM map (the shared Bavarian village, small and fast) with
//! one-second scenarios written to a temporary directory, and its bad-input paths.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn shared_map() -> Option<PathBuf> {
    geodata::testdata::shared_file("data/osm/bavarian-village.osm")
}

/// One second (10 scans) with a little traffic; the route is drawn from the seed.
const SCENARIO: &str = "seed = 4\nduration_s = 1.0\n[traffic]\nmoving_cars = 3\nparked_cars = 2\n\
pedestrians = 2\ninfrastructure = 3\n";
/// A small window keeps the test fast; the search must leave it as it is.
const PARAMS: &str = "[window]\nwidth_cells = 120\nheight_cells = 120\n";

fn tune(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .arg("tune")
        .args(args)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap()
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

#[test]
fn tunes_writes_the_best_parameters_and_compares_on_held_out_drives() {
    let Some(map) = shared_map() else { return };
    let map = map.display().to_string();
    let tmp = tempfile::tempdir().unwrap();
    let scenario = write(tmp.path(), "s.toml", SCENARIO);
    let params = write(tmp.path(), "p.toml", PARAMS);
    let output = tune(
        tmp.path(),
        &[
            "--map",
            &map,
            "--scenario",
            &scenario,
            "--holdout-map",
            &map,
            "--holdout-scenario",
            &scenario,
            "--seeds",
            "1",
            "--holdout-seeds",
            "1",
            "--rounds",
            "1",
            "--config",
            &params,
            "--json",
        ],
    );
    assert!(
        output.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    // Tuning on seed 4, held out on the next seed.
    assert_eq!(json["tuning_drives"][0][1], serde_json::json!([4]));
    assert_eq!(json["holdout_drives"][0][1], serde_json::json!([5]));
    let candidates = json["search"]["candidates"].as_array().unwrap();
    // The start and at least one move per searched parameter (14) in one round.
    assert!(candidates.len() > 14, "{} candidates", candidates.len());
    let objective = |c: &serde_json::Value| c["objective"].as_f64().unwrap();
    let best = candidates
        .iter()
        .rev()
        .find(|c| c["accepted"] == true)
        .unwrap();
    assert!(objective(best) >= objective(&candidates[0]));
    // Every variant on both sets.
    let rows = json["comparison"].as_array().unwrap();
    assert_eq!(rows.len(), 2 * eval::Variant::ALL.len());
    assert!(rows.iter().any(|r| r["set"] == "held-out"));

    // tuned.toml is a complete parameter file that keeps what was not searched.
    let tuned = evigrid::Params::from_toml_str(
        &std::fs::read_to_string(tmp.path().join("out/tuned.toml")).unwrap(),
    )
    .unwrap();
    assert_eq!(tuned.window.width_cells, 120);
    assert_eq!(
        tuned.accumulator.delta_inc,
        best["values"][10].as_f64().unwrap(),
        "values follow the search space order; δ_inc is the 11th"
    );
    let report = std::fs::read_to_string(tmp.path().join("out/report.md")).unwrap();
    assert!(report.contains("| held-out | kurdej2013 |"), "{report}");
}

#[test]
fn bad_input_exits_2_with_one_line_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = write(tmp.path(), "s.toml", SCENARIO);
    let bad_scenario = write(tmp.path(), "bad.toml", "duration_s = -1.0\n");
    let bad_params = write(tmp.path(), "bad-params.toml", "[map]\nbeta_road = 2.0\n");
    let missing = tmp.path().join("missing.osm").display().to_string();
    let map = shared_map().map(|p| p.display().to_string());
    let mut cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "--map".into(),
                missing.clone(),
                "--scenario".into(),
                scenario.clone(),
            ],
            "missing.osm",
        ),
        (
            vec![
                "--map".into(),
                missing.clone(),
                "--scenario".into(),
                scenario.clone(),
                "--seeds".into(),
                "0".into(),
            ],
            "--seeds",
        ),
        (
            vec![
                "--map".into(),
                missing.clone(),
                "--map".into(),
                missing.clone(),
                "--scenario".into(),
                scenario.clone(),
                "--scenario".into(),
                scenario.clone(),
                "--scenario".into(),
                scenario.clone(),
            ],
            "--map given 2 times",
        ),
        (
            vec![
                "--map".into(),
                missing.clone(),
                "--scenario".into(),
                scenario.clone(),
                "--holdout-map".into(),
                missing.clone(),
            ],
            "--holdout-map given without --holdout-scenario",
        ),
        (
            vec![
                "--map".into(),
                missing.clone(),
                "--scenario".into(),
                scenario.clone(),
                "--config".into(),
                bad_params,
            ],
            "map.beta_road",
        ),
        (
            vec![
                "--map".into(),
                missing.clone(),
                "--scenario".into(),
                scenario.clone(),
                "--variant".into(),
                "octomap".into(),
            ],
            "--variant: unknown variant \"octomap\"",
        ),
    ];
    if let Some(map) = map {
        cases.push((
            vec!["--map".into(), map, "--scenario".into(), bad_scenario],
            "bad.toml",
        ));
    }
    for (args, needle) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let output = tune(tmp.path(), &args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
        assert!(output.stdout.is_empty());
        assert!(!tmp.path().join("out").exists(), "no output on bad input");
    }
}
