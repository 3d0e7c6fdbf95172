//! Reading and writing mass functions as JSON, and the `--table` form for people.
//!
//! Input: `{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.2}, {"set": ["a", "b"], "m": 0.8}]}`,
//! `[]` being the empty set. Output uses the same shape, focal sets in increasing bitmask order,
//! every f64 printed to full (round-trip) precision, zeros omitted.

use std::io::Read;
use std::path::Path;

use belief::{Frame, Mass, Set, SetFunction};
use serde::Deserialize;

use crate::exit::BadInput;

/// One input file as written by the user.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MassFile {
    frame: Vec<String>,
    mass: Vec<FocalEntry>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FocalEntry {
    set: Vec<String>,
    m: f64,
}

/// A mass function read from a file, with the name to use in messages.
#[derive(Debug)]
pub struct Input {
    /// The path as given, or `<stdin>` for `-`.
    pub label: String,
    /// The mass function.
    pub mass: Mass<f64>,
}

/// Reads and checks one input; `-` is standard input. Every problem is a [`BadInput`] naming the
/// file.
pub fn read_input(path: &Path) -> anyhow::Result<Input> {
    let (label, text) = if path == Path::new("-") {
        let mut text = String::new();
        // Bounded like a file: a pipe that never ends must not grow memory without bound.
        std::io::stdin()
            .take(crate::input::MAX_TEXT_BYTES + 1)
            .read_to_string(&mut text)
            .map_err(|e| BadInput::new(format!("<stdin>: cannot read: {e}")))?;
        if text.len() as u64 > crate::input::MAX_TEXT_BYTES {
            return Err(BadInput::new(format!(
                "<stdin>: larger than {} MiB; expected a mass function",
                crate::input::MAX_TEXT_BYTES >> 20
            )));
        }
        ("<stdin>".to_owned(), text)
    } else {
        let label = path.display().to_string();
        let text = crate::input::read_text(path)?;
        (label, text)
    };
    let mass = parse_mass(&text).map_err(|problem| BadInput::new(format!("{label}: {problem}")))?;
    Ok(Input { label, mass })
}

/// Parses and checks the text of one input; the error is the problem, without the file name.
fn parse_mass(text: &str) -> Result<Mass<f64>, String> {
    let file: MassFile = serde_json::from_str(text).map_err(|e| format!("malformed JSON: {e}"))?;
    let frame = Frame::new(file.frame).map_err(|e| format!("bad frame: {e}"))?;
    let mut listed: Vec<Set> = Vec::with_capacity(file.mass.len());
    for entry in &file.mass {
        let set = frame.set(&entry.set).map_err(|e| e.describe_in(&frame))?;
        if listed.contains(&set) {
            return Err(format!("set {} is listed twice", frame.set_label(set)));
        }
        listed.push(set);
    }
    let focal = listed.into_iter().zip(file.mass.iter().map(|e| e.m));
    Mass::from_focal(&frame, focal).map_err(|e| e.describe_in(&frame))
}

#[derive(serde::Serialize)]
struct FocalOut<'a> {
    set: Vec<&'a str>,
    m: f64,
}

#[derive(serde::Serialize)]
struct ValueOut<'a> {
    set: Vec<&'a str>,
    v: f64,
}

/// A JSON object with one key per line and each value compact on its line; a list value gets one
/// item per line. People can read it and every JSON parser takes it.
fn json_object(entries: &[(&str, Field)]) -> anyhow::Result<String> {
    let mut out = String::from("{\n");
    for (k, (key, field)) in entries.iter().enumerate() {
        out.push_str(&format!("  {}: ", serde_json::to_string(key)?));
        match field {
            Field::Value(value) => out.push_str(value),
            Field::List(items) => {
                out.push_str("[\n");
                for (i, item) in items.iter().enumerate() {
                    let comma = if i + 1 < items.len() { "," } else { "" };
                    out.push_str(&format!("    {item}{comma}\n"));
                }
                out.push_str("  ]");
            }
        }
        out.push_str(if k + 1 < entries.len() { ",\n" } else { "\n" });
    }
    out.push('}');
    Ok(out)
}

/// The value of one key of [`json_object`], already serialised.
enum Field {
    Value(String),
    List(Vec<String>),
}

/// A mass function as JSON: `{"frame": [...], "mass": [{"set": [...], "m": ...}, ...]}`.
pub fn mass_json(mass: &Mass<f64>) -> anyhow::Result<String> {
    let frame = mass.frame();
    let focal = mass
        .focal_sets()
        .map(|(set, m)| {
            serde_json::to_string(&FocalOut {
                set: frame.names_of(set),
                m,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    json_object(&[
        ("frame", Field::Value(serde_json::to_string(frame.names())?)),
        ("mass", Field::List(focal)),
    ])
}

/// A mass function as an aligned table, one focal set per line.
pub fn mass_table(mass: &Mass<f64>) -> String {
    let rows = mass
        .focal_sets()
        .map(|(set, m)| (mass.frame().set_label(set), m))
        .collect();
    table(("set", "m"), rows)
}

/// Pignistic probabilities as JSON: `{"frame": [...], "betp": {"a": ..., ...}}`, in frame order.
pub fn pignistic_json(frame: &Frame, betp: &[f64]) -> anyhow::Result<String> {
    let pairs = frame
        .names()
        .iter()
        .zip(betp)
        .map(|(name, p)| {
            Ok(format!(
                "{}: {}",
                serde_json::to_string(name)?,
                serde_json::to_string(p)?
            ))
        })
        .collect::<Result<Vec<_>, serde_json::Error>>()?;
    json_object(&[
        ("frame", Field::Value(serde_json::to_string(frame.names())?)),
        ("betp", Field::Value(format!("{{{}}}", pairs.join(", ")))),
    ])
}

/// Pignistic probabilities as a table, one element per line.
pub fn pignistic_table(frame: &Frame, betp: &[f64]) -> String {
    let rows = frame
        .names()
        .iter()
        .cloned()
        .zip(betp.iter().copied())
        .collect();
    table(("element", "betP"), rows)
}

/// A set function as JSON, every subset listed:
/// `{"frame": [...], "<name>": [{"set": [...], "v": ...}, ...]}`.
pub fn set_function_json(name: &str, function: &SetFunction<f64>) -> anyhow::Result<String> {
    let frame = function.frame();
    let values = frame
        .subsets()
        .map(|set| {
            serde_json::to_string(&ValueOut {
                set: frame.names_of(set),
                v: function.get(set),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    json_object(&[
        ("frame", Field::Value(serde_json::to_string(frame.names())?)),
        (name, Field::List(values)),
    ])
}

/// A set function as a table, every subset listed.
pub fn set_function_table(name: &str, function: &SetFunction<f64>) -> String {
    let frame = function.frame();
    let rows = frame
        .subsets()
        .map(|set| (frame.set_label(set), function.get(set)))
        .collect();
    table(("set", name), rows)
}

/// Two left-aligned columns; values rounded to 12 decimals for reading (JSON keeps every digit),
/// so that `0.31999999999999995` reads `0.32`.
fn table(header: (&str, &str), rows: Vec<(String, f64)>) -> String {
    let width = rows
        .iter()
        .map(|(label, _)| label.chars().count())
        .chain([header.0.len()])
        .max()
        .unwrap_or(0);
    let mut out = format!("{:<width$}  {}\n", header.0, header.1);
    for (label, value) in rows {
        out.push_str(&format!("{label:<width$}  {}\n", rounded(value)));
    }
    out
}

/// `value` to 12 decimals without trailing zeros: `0.32`, `1`, `0.000000000001`.
fn rounded(value: f64) -> String {
    let text = format!("{value:.12}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

/// Writes a result to standard output, with one final newline.
pub fn print(text: &str) -> anyhow::Result<()> {
    crate::outln!("{}", text.trim_end());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_prints_in_bitmask_order() -> anyhow::Result<()> {
        let m = parse_mass(
            r#"{"frame": ["a", "b"], "mass": [{"set": ["b", "a"], "m": 0.8}, {"set": ["a"], "m": 0.2}]}"#,
        )
        .map_err(anyhow::Error::msg)?;
        let json: serde_json::Value = serde_json::from_str(&mass_json(&m)?)?;
        assert_eq!(
            json,
            serde_json::json!({"frame": ["a", "b"], "mass": [
                {"set": ["a"], "m": 0.2}, {"set": ["a", "b"], "m": 0.8}
            ]})
        );
        assert_eq!(mass_table(&m), "set     m\n[a]     0.2\n[a, b]  0.8\n");
        Ok(())
    }

    #[test]
    fn problems_name_the_sets() {
        let parse = |text: &str| parse_mass(text).err().unwrap_or_default();
        assert_eq!(
            parse(
                r#"{"frame": ["a"], "mass": [{"set": ["a"], "m": 1.2}, {"set": [], "m": -0.2}]}"#
            ),
            "negative mass -0.2 on set []"
        );
        assert_eq!(
            parse(
                r#"{"frame": ["a", "b"], "mass": [{"set": ["a", "b"], "m": 0.5}, {"set": ["b", "a"], "m": 0.5}]}"#
            ),
            "set [a, b] is listed twice"
        );
        assert_eq!(
            parse(r#"{"frame": ["a"], "mass": [{"set": ["c"], "m": 1}]}"#),
            "element \"c\" is not in the frame {a}"
        );
        assert!(
            parse(r#"{"frame": ["a"], "mass": [{"set": ["a"], "m": 0.9}]}"#)
                .starts_with("masses sum to 0.9, not 1")
        );
        assert!(parse(r#"{"frame": ["a"], "masses": []}"#).starts_with("malformed JSON"));
    }

    #[test]
    fn table_values_are_rounded_for_reading() {
        assert_eq!(rounded(0.31999999999999995), "0.32");
        assert_eq!(rounded(1.0), "1");
        assert_eq!(rounded(0.0), "0");
        assert_eq!(rounded(1e-12), "0.000000000001");
        assert_eq!(rounded(0.5714285714285713), "0.571428571429");
    }

    #[test]
    fn pignistic_keys_follow_the_frame() -> anyhow::Result<()> {
        let frame = Frame::new(["z", "a"])?;
        let text = pignistic_json(&frame, &[0.25, 0.75])?;
        assert!(text.find("\"z\"") < text.find("\"a\""), "{text}");
        assert!(text.find("\"frame\"") < text.find("\"betp\""), "{text}");
        Ok(())
    }
}
