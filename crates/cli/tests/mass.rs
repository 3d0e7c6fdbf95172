//! `evigrid mass` from the command line: the shared belief vectors reproduced through the binary,
//! and every kind of bad input rejected with status 2, one line on stderr and nothing on stdout.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use serde_json::{Value, json};

const EPSILON: f64 = 1e-9;

fn evigrid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .output()
        .expect("the evigrid binary runs")
}

fn evigrid_with_stdin(args: &[&str], stdin: &str) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the evigrid binary runs");
    child
        .stdin
        .take()
        .expect("piped stdin")
        .write_all(stdin.as_bytes())
        .expect("stdin written");
    child.wait_with_output().expect("evigrid finishes")
}

fn stdout_json(output: &Output) -> Result<Value, String> {
    if !output.status.success() {
        return Err(format!(
            "exit {:?}: {}",
            output.status.code(),
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    serde_json::from_slice(&output.stdout).map_err(|e| format!("stdout is not JSON: {e}"))
}

fn write_json(dir: &Path, name: &str, value: &Value) -> String {
    let path = dir.join(name);
    std::fs::write(&path, value.to_string()).expect("temp file written");
    path.to_str().expect("UTF-8 temp path").to_owned()
}

/// `[{"set": [...], key: x}]` as a map from the sorted set to x.
fn by_set(list: &Value, key: &str) -> Result<Vec<(Vec<String>, f64)>, String> {
    let mut out: Vec<(Vec<String>, f64)> = list
        .as_array()
        .ok_or(format!("not a list: {list}"))?
        .iter()
        .map(|entry| {
            let mut set: Vec<String> = entry["set"]
                .as_array()
                .ok_or(format!("no set in {entry}"))?
                .iter()
                .map(|n| n.as_str().unwrap_or_default().to_owned())
                .collect();
            set.sort();
            let value = entry[key].as_f64().ok_or(format!("no {key} in {entry}"))?;
            Ok((set, value))
        })
        .collect::<Result<_, String>>()?;
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

fn same_sets(got: &Value, want: &Value, key: &str) -> Result<(), String> {
    let (g, w) = (by_set(got, key)?, by_set(want, key)?);
    let same = g.len() == w.len()
        && g.iter()
            .zip(&w)
            .all(|((gs, gv), (ws, wv))| gs == ws && (gv - wv).abs() <= EPSILON);
    if same {
        Ok(())
    } else {
        Err(format!("got {g:?}, expected {w:?}"))
    }
}

/// Runs one vector through the calculator; the error says what differed.
fn check_vector(dir: &Path, index: usize, vector: &Value) -> Result<(), String> {
    let frame = &vector["frame"];
    let files: Vec<String> = vector["inputs"]
        .as_array()
        .ok_or("no inputs")?
        .iter()
        .enumerate()
        .map(|(k, input)| {
            write_json(
                dir,
                &format!("v{index}-{k}.json"),
                &json!({"frame": frame, "mass": input}),
            )
        })
        .collect();
    let op = vector["op"].as_str().ok_or("no op")?;
    let files: Vec<&str> = files.iter().map(String::as_str).collect();
    let run = |mut args: Vec<String>| {
        args.extend(files.iter().map(|f| f.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        stdout_json(&evigrid(&args))
    };
    let words = |words: &[&str]| words.iter().map(|w| w.to_string()).collect::<Vec<_>>();
    let rule = match op {
        "conjunctive" | "dempster" | "disjunctive" | "yager" => Some(op.to_owned()),
        "dubois_prade" => Some("dubois-prade".to_owned()),
        _ => None,
    };
    if let Some(rule) = rule {
        let out = run(words(&["mass", "combine", "--rule", &rule]))?;
        return same_sets(&out["mass"], &vector["expected"], "m");
    }
    match op {
        "discount" => {
            let alpha = vector["params"]["alpha"].to_string();
            let out = run(words(&["mass", "discount", "--alpha", &alpha]))?;
            same_sets(&out["mass"], &vector["expected"], "m")
        }
        "contextual_discount" => {
            let mut args = words(&["mass", "discount"]);
            for context in vector["params"]["contexts"]
                .as_array()
                .ok_or("no contexts")?
            {
                let names: Vec<&str> = context["set"]
                    .as_array()
                    .ok_or("no context set")?
                    .iter()
                    .filter_map(Value::as_str)
                    .collect();
                args.push("--context".into());
                args.push(format!("{}={}", names.join("+"), context["alpha"]));
            }
            let out = run(args)?;
            same_sets(&out["mass"], &vector["expected"], "m")
        }
        "pignistic" => {
            let out = run(words(&["mass", "pignistic"]))?;
            let want = vector["expected_singletons"].as_object().ok_or("no betP")?;
            let got = out["betp"].as_object().ok_or("no betp in output")?;
            let keys_in_frame_order: Vec<&String> = got.keys().collect();
            for (name, p) in want {
                let g = got
                    .get(name)
                    .and_then(Value::as_f64)
                    .ok_or(format!("no {name}"))?;
                if (g - p.as_f64().unwrap_or(f64::NAN)).abs() > EPSILON {
                    return Err(format!("betP({name}) = {g}, expected {p}"));
                }
            }
            if keys_in_frame_order.len() != want.len() {
                return Err(format!("betp has keys {keys_in_frame_order:?}"));
            }
            Ok(())
        }
        "transforms" => {
            for name in ["belief", "plausibility", "commonality", "implicability"] {
                let out = run(words(&["mass", "transform", "--to", name]))?;
                let expected = &vector[format!("expected_{name}")];
                same_sets(&out[name], expected, "v").map_err(|e| format!("{name}: {e}"))?;
            }
            Ok(())
        }
        other => Err(format!("unknown op {other}")),
    }
}

#[test]
fn calculator_reproduces_every_shared_vector() {
    let Some(path) = geodata::testdata::shared_file("vectors/belief-vectors.json") else {
        return;
    };
    let text = std::fs::read_to_string(&path).expect("vector file readable");
    let file: Value = serde_json::from_str(&text).expect("vector file is JSON");
    let vectors = file["vectors"].as_array().expect("a vectors array");
    let dir = tempfile::tempdir().expect("temp dir");
    let failures: Vec<String> = vectors
        .iter()
        .enumerate()
        .filter_map(|(index, vector)| {
            check_vector(dir.path(), index, vector).err().map(|e| {
                format!(
                    "vector {index} ({}, op {}): {e}",
                    vector["source"], vector["op"]
                )
            })
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} vectors failed:\n{}",
        failures.len(),
        vectors.len(),
        failures.join("\n")
    );
}

/// Status 2, nothing on stdout, exactly one line on stderr that contains every `needles`.
fn assert_bad_input(case: &str, output: &Output, needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{case}: stderr {stderr}");
    assert!(output.stdout.is_empty(), "{case}: stdout not empty");
    assert_eq!(stderr.lines().count(), 1, "{case}: stderr {stderr:?}");
    for needle in needles {
        assert!(
            stderr.contains(needle),
            "{case}: {needle:?} not in {stderr:?}"
        );
    }
}

#[test]
fn bad_inputs_exit_2_with_one_line_naming_file_and_problem() {
    let dir = tempfile::tempdir().expect("temp dir");
    let file = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("written");
        path.to_str().expect("UTF-8").to_owned()
    };
    let good = file(
        "good.json",
        r#"{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 1}]}"#,
    );
    let only_b = file(
        "only-b.json",
        r#"{"frame": ["a", "b"], "mass": [{"set": ["b"], "m": 1}]}"#,
    );
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "negative mass",
            file(
                "negative.json",
                r#"{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": -0.2}, {"set": ["b"], "m": 1.2}]}"#,
            ),
            vec!["negative.json", "negative mass -0.2 on set [a]"],
        ),
        (
            "sum off by 2e-9",
            file(
                "sum.json",
                r#"{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.2}, {"set": ["b"], "m": 0.800000002}]}"#,
            ),
            vec!["sum.json", "masses sum to 1.000000002, not 1"],
        ),
        (
            "unknown element",
            file(
                "unknown.json",
                r#"{"frame": ["a", "b"], "mass": [{"set": ["c"], "m": 1}]}"#,
            ),
            vec!["unknown.json", "element \"c\" is not in the frame {a, b}"],
        ),
        (
            "repeated set",
            file(
                "repeated.json",
                r#"{"frame": ["a", "b"], "mass": [{"set": ["a", "b"], "m": 0.5}, {"set": ["b", "a"], "m": 0.5}]}"#,
            ),
            vec!["repeated.json", "set [a, b] is listed twice"],
        ),
        (
            "malformed JSON",
            file(
                "malformed.json",
                r#"{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 1}"#,
            ),
            vec!["malformed.json", "malformed JSON"],
        ),
        (
            "unknown field",
            file("field.json", r#"{"frame": ["a"], "masses": []}"#),
            vec!["field.json", "malformed JSON", "masses"],
        ),
        (
            "frame repeats an element",
            file(
                "frame.json",
                r#"{"frame": ["a", "a"], "mass": [{"set": ["a"], "m": 1}]}"#,
            ),
            vec!["frame.json", "bad frame", "appears twice"],
        ),
        (
            "missing file",
            dir.path()
                .join("missing.json")
                .to_str()
                .expect("UTF-8")
                .to_owned(),
            vec!["missing.json", "cannot read"],
        ),
    ];
    for (case, path, needles) in &cases {
        for args in [
            vec!["mass", "pignistic", path.as_str()],
            vec![
                "mass",
                "combine",
                "--rule",
                "conjunctive",
                good.as_str(),
                path.as_str(),
            ],
        ] {
            assert_bad_input(case, &evigrid(&args), needles);
        }
    }

    let other_frame = file(
        "other.json",
        r#"{"frame": ["a", "c"], "mass": [{"set": ["a"], "m": 1}]}"#,
    );
    assert_bad_input(
        "different frames",
        &evigrid(&["mass", "combine", "--rule", "dempster", &good, &other_frame]),
        &[
            "other.json",
            "frame {a, c} differs from frame {a, b} of",
            "good.json",
        ],
    );
    assert_bad_input(
        "total conflict",
        &evigrid(&["mass", "combine", "--rule", "dempster", &good, &only_b]),
        &["good.json", "only-b.json", "total conflict"],
    );
    assert_bad_input(
        "alpha out of range",
        &evigrid(&["mass", "discount", "--alpha", "1.5", &good]),
        &["--alpha 1.5", "not in [0, 1]"],
    );
    assert_bad_input(
        "context element not in frame",
        &evigrid(&["mass", "discount", "--context", "a+x=0.5", &good]),
        &["--context a+x=0.5", "\"x\"", "good.json"],
    );
    assert_bad_input(
        "context rate not a number",
        &evigrid(&["mass", "discount", "--context", "a=much", &good]),
        &["--context a=much", "not a number"],
    );
    assert_bad_input(
        "missing class rate",
        &evigrid(&["mass", "discount", "--class-rate", "a=0.5", &good]),
        &["--class-rate", "no rate for element b"],
    );
    assert_bad_input(
        "set rate without class rates",
        &evigrid(&[
            "mass",
            "discount",
            "--set-rate",
            "min",
            "--alpha",
            "0.1",
            &good,
        ]),
        &["--set-rate", "--class-rate"],
    );
    assert_bad_input(
        "pignistic of all-conflict mass",
        &evigrid(&[
            "mass",
            "pignistic",
            &file(
                "empty.json",
                r#"{"frame": ["a"], "mass": [{"set": [], "m": 1}]}"#,
            ),
        ]),
        &["empty.json", "m(∅) = 1"],
    );
    assert_bad_input(
        "bad stdin",
        &evigrid_with_stdin(&["mass", "pignistic", "-"], "not json"),
        &["<stdin>", "malformed JSON"],
    );
}

#[test]
fn sum_within_tolerance_is_accepted() -> Result<(), String> {
    // Off by 5e-10 < 1e-9: accepted and passed through unchanged (α = 0 is the identity).
    let output = evigrid_with_stdin(
        &["mass", "discount", "--alpha", "0", "-"],
        r#"{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.2}, {"set": ["b"], "m": 0.8000000005}]}"#,
    );
    let out = stdout_json(&output)?;
    same_sets(
        &out["mass"],
        &json!([{"set": ["a"], "m": 0.2}, {"set": ["b"], "m": 0.8000000005}]),
        "m",
    )
}

#[test]
fn class_rate_discount_by_hand() -> Result<(), String> {
    let input = r#"{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.2}, {"set": ["b"], "m": 0.6}, {"set": ["a", "b"], "m": 0.2}]}"#;
    let args = [
        "mass",
        "discount",
        "--class-rate",
        "a=0.1",
        "--class-rate",
        "b=0.2",
        "--set-rate",
        "mean",
        "-",
    ];
    // a keeps 0.9·0.2 = 0.18, b keeps 0.8·0.6 = 0.48, Ω: 0.2 + 0.02 + 0.12 = 0.34.
    let out = stdout_json(&evigrid_with_stdin(&args, input))?;
    same_sets(
        &out["mass"],
        &json!([{"set": ["a"], "m": 0.18}, {"set": ["b"], "m": 0.48}, {"set": ["a", "b"], "m": 0.34}]),
        "m",
    )
}

#[test]
fn yager_three_inputs_use_the_n_ary_form() -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    let a = write_json(
        dir.path(),
        "a.json",
        &json!({"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.5}, {"set": ["a", "b"], "m": 0.5}]}),
    );
    let b = write_json(
        dir.path(),
        "b.json",
        &json!({"frame": ["a", "b"], "mass": [{"set": ["b"], "m": 0.5}, {"set": ["a", "b"], "m": 0.5}]}),
    );
    // a ∩ b ∩ a: ∅ 0.375, {a} 0.375, {b} 0.125, Ω 0.125; the conflict goes to Ω once: Ω 0.5.
    // (Folding the binary rule would give {a} 0.5, {b} 0.125, Ω 0.375.)
    let out = stdout_json(&evigrid(&[
        "mass", "combine", "--rule", "yager", &a, &b, &a,
    ]))?;
    same_sets(
        &out["mass"],
        &json!([{"set": ["a"], "m": 0.375}, {"set": ["b"], "m": 0.125}, {"set": ["a", "b"], "m": 0.5}]),
        "m",
    )
}

#[test]
fn output_lists_focal_sets_in_bitmask_order_and_table_aligns() -> Result<(), String> {
    let input = r#"{"frame": ["a", "b"], "mass": [{"set": ["a", "b"], "m": 0.2}, {"set": ["b"], "m": 0.6}, {"set": ["a"], "m": 0.2}]}"#;
    let out = stdout_json(&evigrid_with_stdin(
        &["mass", "discount", "--alpha", "0", "-"],
        input,
    ))?;
    assert_eq!(
        out,
        json!({"frame": ["a", "b"], "mass": [
            {"set": ["a"], "m": 0.2}, {"set": ["b"], "m": 0.6}, {"set": ["a", "b"], "m": 0.2}
        ]})
    );
    let table = evigrid_with_stdin(&["mass", "discount", "--alpha", "0", "--table", "-"], input);
    assert_eq!(
        String::from_utf8_lossy(&table.stdout),
        "set     m\n[a]     0.2\n[b]     0.6\n[a, b]  0.2\n"
    );
    Ok(())
}
