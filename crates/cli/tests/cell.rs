//! `evigrid cell`: one cell through a sequence of observations.

use std::process::{Command, Output};

type TestResult = Result<(), Box<dyn std::error::Error>>;

fn evigrid(args: &[&str]) -> std::io::Result<Output> {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .output()
}

fn json_steps(args: &[&str]) -> Result<Vec<serde_json::Value>, Box<dyn std::error::Error>> {
    let out = evigrid(args)?;
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let value: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    Ok(value.as_array().cloned().unwrap_or_default())
}

fn number(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// The parameters the hand-computed numbers below use, written out so that the tests do not
/// move when the tuned defaults do (docs/tuning.md). Returns the directory (kept alive by the
/// caller) and the file's path.
fn hand_params() -> Result<(tempfile::TempDir, String), Box<dyn std::error::Error>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("hand.toml");
    std::fs::write(
        &path,
        "[sensor]\nmu_free = 0.7\nmu_occupied = 0.8\n\
         [map]\nbeta_building = 0.9\nbeta_road = 0.8\nbeta_other = 0.7\n\
         [accumulator]\ndelta_inc = 0.1\ndelta_dec = 0.3\ngamma_occupied = 0.5\ngamma_conflict = 0.2\n",
    )?;
    let path = path.to_str().unwrap_or_default().to_string();
    Ok((dir, path))
}

/// Mass of the set named by `letters` in one step's `mass` list (0 if absent).
fn mass_of(step: &serde_json::Value, letters: &[&str]) -> f64 {
    step["mass"]
        .as_array()
        .into_iter()
        .flatten()
        .find(|entry| {
            let set: Vec<&str> = entry["set"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|s| s.as_str())
                .collect();
            set == letters
        })
        .map_or(0.0, |entry| number(&entry["m"]))
}

#[test]
fn road_cell_free_then_car_arrives_and_stays() -> TestResult {
    let (_dir, params) = hand_params()?;
    let steps = json_steps(&[
        "cell",
        "--config",
        &params,
        "--context",
        "road",
        "--observe",
        "free*2,occupied*10,free",
        "--json",
    ])?;
    assert_eq!(steps.len(), 13);
    // Step 1, vacuous past: r(SG) ⊕ GG on a road = {F} 0.7, {F,S,M} 0.24, Ω 0.06.
    let first = &steps[0];
    assert_eq!(first["step"], 1);
    assert_eq!(number(&first["observation"]["free"]), 0.7);
    assert!((mass_of(first, &["F"]) - 0.7).abs() < 1e-6);
    assert!((mass_of(first, &["F", "S", "M"]) - 0.24).abs() < 1e-6);
    assert!((mass_of(first, &["F", "I", "U", "S", "M"]) - 0.06).abs() < 1e-6);
    assert_eq!(first["decision"], "F");
    // Step 3: free before, occupied now: ∅_FO > 0 goes to M, which wins.
    let arrival = &steps[2];
    assert!(number(&arrival["conflict_fo"]) > 0.3);
    assert_eq!(arrival["decision"], "M");
    // Ten occupied scans: ζ grows and the mass moves from M to S (a stopped car).
    let parked = &steps[11];
    assert!(number(&parked["zeta"]) > 0.5);
    assert_eq!(parked["decision"], "S");
    // The car leaves: ∅_OF.
    assert!(number(&steps[12]["conflict_of"]) > 0.3);
    // betP is a probability.
    let b = &parked["betp"];
    let total: f64 = ["F", "I", "U", "S", "M"]
        .iter()
        .map(|c| number(&b[*c]))
        .sum();
    assert!((total - 1.0).abs() < 1e-5);
    Ok(())
}

#[test]
fn never_observed_cell_is_unknown() -> TestResult {
    let steps = json_steps(&["cell", "--observe", "none*3", "--json"])?;
    assert_eq!(steps.len(), 3);
    assert!(steps.iter().all(|s| s["decision"] == "unknown"));
    Ok(())
}

#[test]
fn building_context_explicit_pair_and_dt() -> TestResult {
    // 0.6/0.1 on a building: r(SG) {F} 0.6, O 0.1, Ω 0.3; GG {I} 0.9. K = 0.54;
    // {F} 0.06/0.46, {I} (0.09 + 0.27)/0.46, O 0.01/0.46, Ω 0.03/0.46. m(O) ≥ γ_O without
    // conflict, so ζ = 0.1 and the specialisation keeps 0.9 of O (the rest goes to {I,U,S}).
    let (_dir, params) = hand_params()?;
    let steps = json_steps(&[
        "cell",
        "--config",
        &params,
        "--context",
        "building",
        "--observe",
        "0.6/0.1",
        "--dt",
        "0.5",
        "--json",
    ])?;
    let s = &steps[0];
    assert!((mass_of(s, &["F"]) - 0.06 / 0.46).abs() < 1e-6);
    assert!((mass_of(s, &["I"]) - 0.36 / 0.46).abs() < 1e-6);
    assert!((mass_of(s, &["I", "U", "S", "M"]) - 0.9 * 0.01 / 0.46).abs() < 1e-6);
    assert!((mass_of(s, &["I", "U", "S"]) - 0.1 * 0.01 / 0.46).abs() < 1e-6);
    assert!((number(&s["zeta"]) - 0.1).abs() < 1e-6);
    assert_eq!(s["decision"], "I");
    Ok(())
}

#[test]
fn config_file_changes_parameters() -> TestResult {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("p.toml");
    std::fs::write(&path, "[sensor]\nmu_free = 0.5\n")?;
    let steps = json_steps(&[
        "cell",
        "--config",
        path.to_str().unwrap_or_default(),
        "--observe",
        "free",
        "--json",
    ])?;
    assert!((mass_of(&steps[0], &["F"]) - 0.5).abs() < 1e-6);
    Ok(())
}

#[test]
fn table_has_a_header_and_a_row_per_step() -> TestResult {
    let out = evigrid(&["cell", "--context", "other", "--observe", "occupied*2,free"])?;
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout)?;
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4, "{text}");
    assert!(lines[0].contains("decision") && lines[0].contains("masses"));
    assert!(lines[1].trim_start().starts_with('1'));
    assert!(lines[1].contains("{U,S,M}="), "{text}");
    Ok(())
}

#[track_caller]
fn assert_bad_input(args: &[&str], named: &str) {
    let out = match evigrid(args) {
        Ok(out) => out,
        Err(e) => panic!("cannot run evigrid: {e}"),
    };
    assert_eq!(out.status.code(), Some(2), "{args:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains(named), "{args:?}: {stderr}");
}

#[test]
fn bad_observations_exit_with_status_2_naming_the_argument() {
    assert_bad_input(&["cell", "--observe", "free,blocked"], "--observe");
    assert_bad_input(&["cell", "--observe", "0.7/0.4"], "--observe");
    assert_bad_input(&["cell", "--observe", "-0.1/0.2"], "--observe");
    assert_bad_input(&["cell", "--observe", "free*zero"], "--observe");
    assert_bad_input(&["cell", "--observe", "free", "--dt", "-1"], "--dt");
}

#[test]
fn bad_config_exits_with_status_2_naming_the_file() -> TestResult {
    let dir = tempfile::tempdir()?;
    let unknown = dir.path().join("unknown.toml");
    std::fs::write(&unknown, "[sensor]\nmu_fre = 0.5\n")?;
    let range = dir.path().join("range.toml");
    std::fs::write(&range, "[map]\nbeta_road = 1.5\n")?;
    for (path, named) in [(&unknown, "mu_fre"), (&range, "map.beta_road")] {
        let p = path.to_str().unwrap_or_default();
        assert_bad_input(&["cell", "--config", p, "--observe", "free"], named);
        assert_bad_input(&["cell", "--config", p, "--observe", "free"], p);
    }
    let missing = dir.path().join("missing.toml");
    let p = missing.to_str().unwrap_or_default();
    assert_bad_input(&["cell", "--config", p, "--observe", "free"], p);
    Ok(())
}
