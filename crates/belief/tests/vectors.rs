//! Conformance suite: every vector of `vectors/belief-vectors.json` in the shared data (one test
//! per vector file, in the manner of geo's JTS runner). Failures name the vector's index, source
//! and operation.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use belief::{
    BeliefError, ClassicalDiscount, Combination, Conjunctive, ContextualDiscount, Dempster,
    Discounting, Disjunctive, DuboisPrade, Frame, Mass, Set, SetFunction, Yager,
};
use serde_json::Value;

/// Masses in the file are given to 12 decimals.
const EPSILON: f64 = 1e-9;

/// The shared data directory: `$EVIGRID_SHARED` (relative paths are taken from the workspace
/// root), else `../shared` next to the workspace.
fn shared_dir() -> PathBuf {
    let workspace = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    match std::env::var_os("EVIGRID_SHARED") {
        Some(dir) => workspace.join(dir),
        None => workspace.join("../shared"),
    }
}

#[test]
fn belief_vectors() {
    let path = shared_dir().join("vectors/belief-vectors.json");
    let Ok(text) = std::fs::read_to_string(&path) else {
        assert!(
            std::env::var("EVIGRID_REQUIRE_SHARED").as_deref() != Ok("1"),
            "EVIGRID_REQUIRE_SHARED=1 but {} cannot be read",
            path.display()
        );
        eprintln!(
            "skipping: {} not found (set EVIGRID_SHARED)",
            path.display()
        );
        return;
    };
    let file: Value = serde_json::from_str(&text).expect("vector file is JSON");
    let vectors = file["vectors"].as_array().expect("a `vectors` array");
    assert!(!vectors.is_empty());
    let failures: Vec<String> = vectors
        .iter()
        .enumerate()
        .filter_map(|(index, vector)| {
            check_vector(vector).err().map(|problem| {
                format!(
                    "vector {index} ({}, op {}): {problem}",
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

fn check_vector(vector: &Value) -> Result<(), String> {
    let frame = Frame::new(strings(&vector["frame"])?).map_err(|e| e.to_string())?;
    let inputs = vector["inputs"]
        .as_array()
        .ok_or("no inputs")?
        .iter()
        .map(|input| mass(&frame, input))
        .collect::<Result<Vec<_>, _>>()?;
    let op = vector["op"].as_str().ok_or("no op")?;
    let combined = |rule: &dyn Combination<f64>| rule.combine_all(&inputs);
    let result = match op {
        "conjunctive" => combined(&Conjunctive),
        "dempster" => combined(&Dempster),
        "disjunctive" => combined(&Disjunctive),
        "yager" => combined(&Yager),
        "dubois_prade" => combined(&DuboisPrade),
        "discount" => {
            let alpha = vector["params"]["alpha"].as_f64().ok_or("no alpha")?;
            ClassicalDiscount::new(alpha).and_then(|d| d.discount(&inputs[0]))
        }
        "contextual_discount" => {
            let contexts = vector["params"]["contexts"]
                .as_array()
                .ok_or("no contexts")?
                .iter()
                .map(|c| {
                    let set = set(&frame, &c["set"])?;
                    Ok((set, c["alpha"].as_f64().ok_or("no alpha")?))
                })
                .collect::<Result<Vec<_>, String>>()?;
            ContextualDiscount::new(contexts).and_then(|d| d.discount(&inputs[0]))
        }
        "pignistic" => return check_pignistic(&frame, &inputs[0], &vector["expected_singletons"]),
        "transforms" => return check_transforms(&frame, &inputs[0], vector),
        other => return Err(format!("unknown op {other:?}")),
    };
    let result = result.map_err(|e| format!("error {e}"))?;
    let expected = mass_values(&frame, &vector["expected"], "m")?;
    compare(result.values(), &expected)
}

fn check_pignistic(frame: &Frame, m: &Mass<f64>, expected: &Value) -> Result<(), String> {
    let betp = m.pignistic().map_err(|e: BeliefError| e.to_string())?;
    let expected = frame
        .names()
        .iter()
        .map(|name| expected[name].as_f64().ok_or(format!("no betP for {name}")))
        .collect::<Result<Vec<_>, _>>()?;
    compare(&betp, &expected)
}

fn check_transforms(frame: &Frame, m: &Mass<f64>, vector: &Value) -> Result<(), String> {
    let functions: [(&str, SetFunction<f64>); 4] = [
        ("belief", m.belief()),
        ("plausibility", m.plausibility()),
        ("commonality", m.commonality()),
        ("implicability", m.implicability()),
    ];
    for (name, function) in functions {
        let expected = mass_values(frame, &vector[format!("expected_{name}")], "v")?;
        compare(function.values(), &expected).map_err(|e| format!("{name}: {e}"))?;
    }
    Ok(())
}

fn compare(got: &[f64], want: &[f64]) -> Result<(), String> {
    let close =
        got.len() == want.len() && got.iter().zip(want).all(|(g, w)| (g - w).abs() <= EPSILON);
    if close {
        Ok(())
    } else {
        Err(format!("got {got:?}, expected {want:?}"))
    }
}

fn strings(value: &Value) -> Result<Vec<String>, String> {
    value
        .as_array()
        .ok_or(format!("not a list: {value}"))?
        .iter()
        .map(|v| {
            v.as_str()
                .map(str::to_owned)
                .ok_or(format!("not a name: {v}"))
        })
        .collect()
}

fn set(frame: &Frame, value: &Value) -> Result<Set, String> {
    frame.set(&strings(value)?).map_err(|e| e.to_string())
}

/// A dense array from a list of `{"set": [...], key: value}`; unlisted sets are zero.
fn mass_values(frame: &Frame, list: &Value, key: &str) -> Result<Vec<f64>, String> {
    let mut values = vec![0.0; frame.size()];
    for entry in list.as_array().ok_or(format!("not a list: {list}"))? {
        let value = entry[key].as_f64().ok_or(format!("no {key} in {entry}"))?;
        values[set(frame, &entry["set"])?.index()] = value;
    }
    Ok(values)
}

fn mass(frame: &Frame, list: &Value) -> Result<Mass<f64>, String> {
    Mass::from_values(frame, mass_values(frame, list, "m")?).map_err(|e| e.to_string())
}
