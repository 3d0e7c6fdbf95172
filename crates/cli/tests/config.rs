//! `evigrid config` and the global `-v`/`-q` flags.

use std::process::{Command, Output};

fn evigrid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("evigrid runs")
}

#[test]
fn the_printed_defaults_read_back_as_the_defaults() {
    let printed = evigrid(&["config", "--print"]);
    assert!(printed.status.success());
    let text = String::from_utf8(printed.stdout).expect("UTF-8");
    let params = evigrid::Params::from_toml_str(&text).expect("valid TOML");
    assert_eq!(params, evigrid::Params::default());
}

#[test]
fn the_example_config_is_valid_and_differs_from_the_defaults() {
    let checked = evigrid(&["config", "--check", "../../examples/config.toml", "--json"]);
    assert!(
        checked.status.success(),
        "{}",
        String::from_utf8_lossy(&checked.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&checked.stdout).expect("JSON");
    assert_eq!(json["window"]["width_cells"], 400);
    assert_eq!(json["sensor"]["min_range_m"], 3.0);
}

#[test]
fn a_bad_config_is_bad_input_and_quiet_keeps_the_one_line() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, "[map]\nbeta_road = 1.5\n").expect("written");
    let path = path.to_str().expect("UTF-8");
    for flags in [
        &["config", "--check", path][..],
        &["-q", "config", "--check", path],
    ] {
        let output = evigrid(flags);
        assert_eq!(output.status.code(), Some(2));
        assert!(output.stdout.is_empty());
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains("map.beta_road = 1.5"), "{stderr}");
    }
    let both = evigrid(&["-q", "-v", "config", "--print"]);
    assert_eq!(both.status.code(), Some(2), "-q and -v conflict");
}
