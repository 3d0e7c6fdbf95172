//! `evigrid eval` end to end on a real OSM map (the shared Bavarian village, small and fast) with
//! a one-second scenario written to a temporary directory.

#![allow(clippy::unwrap_used)]

use std::path::PathBuf;
use std::process::{Command, Output};

mod common;
use common::read_png;

fn shared_map() -> Option<PathBuf> {
    geodata::testdata::shared_file("data/osm/bavarian-village.osm")
}

/// One second (10 scans) with a little traffic; the route is drawn from the seed.
const SCENARIO: &str = "seed = 4\nduration_s = 1.0\n[traffic]\nmoving_cars = 2\nparked_cars = 2\n\
pedestrians = 2\ninfrastructure = 3\n";
/// A small window keeps the test fast.
const PARAMS: &str = "[window]\nwidth_cells = 160\nheight_cells = 160\n";

struct Setup {
    _tmp: tempfile::TempDir,
    dir: PathBuf,
    map: PathBuf,
    scenario: PathBuf,
    params: PathBuf,
    out: PathBuf,
}

fn setup() -> Option<Setup> {
    let map = shared_map()?;
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    let scenario = dir.join("scenario.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let params = dir.join("params.toml");
    std::fs::write(&params, PARAMS).unwrap();
    let out = dir.join("out");
    Some(Setup {
        _tmp: tmp,
        dir,
        map,
        scenario,
        params,
        out,
    })
}

fn eval(s: &Setup, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .arg("eval")
        .arg("--map")
        .arg(&s.map)
        .arg("--scenario")
        .arg(&s.scenario)
        .arg("--config")
        .arg(&s.params)
        .arg("--out")
        .arg(&s.out)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn writes_metrics_report_and_plots_for_every_variant() {
    let Some(s) = setup() else { return };
    let output = eval(&s, &["--seeds", "2", "--json"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "stderr: {stderr}");

    // --json prints the same report that metrics.json holds.
    let printed: eval::EvalReport = serde_json::from_slice(&output.stdout).unwrap();
    let text = std::fs::read_to_string(s.out.join("metrics.json")).unwrap();
    let report: eval::EvalReport = serde_json::from_str(&text).unwrap();
    assert_eq!(printed, report);
    assert_eq!(report.seeds, vec![4, 5]);
    assert_eq!(report.frames_per_seed, 10);
    let names: Vec<&str> = report.variants.iter().map(|v| v.variant.name()).collect();
    assert_eq!(
        names,
        ["evigrid", "kurdej2013", "no-map", "moras2011", "log-odds"]
    );
    for v in &report.variants {
        assert!(
            v.confusion.total() > 0,
            "{} scored nothing",
            v.variant.name()
        );
        assert_eq!(v.per_seed.len(), 2);
        let png = s.out.join(format!("confusion-{}.png", v.variant.name()));
        let (width, height, _, _) = read_png(&png);
        assert!(width > 100 && height > 100);
    }
    let (chart_width, _, _, _) = read_png(&s.out.join("per-class-iou.png"));
    assert!(chart_width > 100);

    let md = std::fs::read_to_string(s.out.join("report.md")).unwrap();
    assert!(md.contains("| kurdej2013 |") && md.contains("| log-odds |"));
    assert!(md.contains("[window]") && md.contains("width_cells = 160"));
    assert!(md.contains("ground_model = \"none\""));
    assert!(md.contains("--seeds 2"));
    // No temporary file is left behind by the atomic writes.
    for entry in std::fs::read_dir(&s.out).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        assert!(!name.contains(".tmp"), "left over: {name}");
    }
}

#[test]
fn table_lists_the_requested_variants_only() {
    let Some(s) = setup() else { return };
    // `full`, the paper's variant's former name, is still accepted, with a warning.
    let output = eval(&s, &["--variants", "log-odds,full"]);
    assert!(output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("`full` is deprecated, use `kurdej2013`"),
        "{stderr}"
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert!(lines[0].starts_with("variant") && lines[0].contains("macro-F1"));
    assert!(lines[0].contains("M prec") && lines[0].contains("occ-st"));
    assert!(lines[1].starts_with("log-odds"));
    assert!(lines[2].starts_with("kurdej2013"));
    assert!(lines[3].contains("cells in view"));
    assert!(!stdout.contains("no-map") && !stdout.contains("moras2011"));
    let report: eval::EvalReport =
        serde_json::from_str(&std::fs::read_to_string(s.out.join("metrics.json")).unwrap())
            .unwrap();
    assert_eq!(report.variants.len(), 2);
    assert!(s.out.join("confusion-log-odds.png").is_file());
    assert!(!s.out.join("confusion-no-map.png").exists());
}

/// Runs with one input broken; expects exit status 2, a one-line message naming `needle`, and no
/// output directory.
fn assert_bad_input(s: &Setup, output: Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "stderr: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "stderr: {stderr}");
    assert!(stderr.contains(needle), "{needle:?} not in {stderr}");
    assert!(!s.out.exists(), "outputs written on bad input");
}

#[test]
fn bad_inputs_exit_2_and_write_nothing() {
    let Some(s) = setup() else { return };

    let out = eval(&s, &["--seeds", "0"]);
    assert_bad_input(&s, out, "--seeds");

    let out = eval(&s, &["--variants", "full,octomap"]);
    assert_bad_input(&s, out, "octomap");

    let out = eval(&s, &["--variants", "full,full"]);
    assert_bad_input(&s, out, "--variants");

    let bad_config = s.dir.join("bad-params.toml");
    std::fs::write(&bad_config, "[sensor]\nmu_free = 1.5\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(["eval", "--map"])
        .arg(&s.map)
        .arg("--scenario")
        .arg(&s.scenario)
        .arg("--config")
        .arg(&bad_config)
        .arg("--out")
        .arg(&s.out)
        .output()
        .unwrap();
    assert_bad_input(&s, out, "bad-params.toml");

    let missing_map = s.dir.join("no-such-map.osm");
    let out = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(["eval", "--map"])
        .arg(&missing_map)
        .arg("--scenario")
        .arg(&s.scenario)
        .arg("--out")
        .arg(&s.out)
        .output()
        .unwrap();
    assert_bad_input(&s, out, "no-such-map.osm");

    for (name, text) in [
        ("broken.toml", "seed = [\n"),
        ("unknown-key.toml", "colour = 3\n"),
        ("negative.toml", "duration_s = -2.0\n"),
    ] {
        let scenario = s.dir.join(name);
        std::fs::write(&scenario, text).unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_evigrid"))
            .args(["eval", "--map"])
            .arg(&s.map)
            .arg("--scenario")
            .arg(&scenario)
            .arg("--out")
            .arg(&s.out)
            .output()
            .unwrap();
        assert_bad_input(&s, out, name);
    }
    let out = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(["eval", "--map"])
        .arg(&s.map)
        .arg("--scenario")
        .arg(s.dir.join("missing.toml"))
        .arg("--out")
        .arg(&s.out)
        .output()
        .unwrap();
    assert_bad_input(&s, out, "missing.toml");
}
