//! Reading what the user gave, and saying which input an error comes from.

use std::fs;
use std::path::Path;

use anyhow::Result;
use evigrid::Params;

use crate::exit::BadInput;

/// The parameters of `--config FILE` (SPEC §7 layout), or the defaults without one.
pub fn read_params(path: Option<&Path>) -> Result<Params> {
    let Some(path) = path else {
        return Ok(Params::default());
    };
    let text =
        fs::read_to_string(path).map_err(|e| BadInput::new(format!("{}: {e}", path.display())))?;
    Params::from_toml_str(&text).map_err(|e| BadInput::new(format!("{}: {e}", path.display())))
}

/// `message` on one line: the TOML parser's messages quote the offending line below the message.
pub fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Prefixes `message` with the file's path unless it already names it.
pub fn with_path(path: &Path, message: &str) -> String {
    let shown = path.display().to_string();
    if message.contains(&shown) {
        message.to_string()
    } else {
        format!("{shown}: {message}")
    }
}

/// The command line as typed, quoted for a POSIX shell where needed (for reports that say how
/// to reproduce them).
pub fn command_line() -> String {
    std::env::args()
        .map(|a| {
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./=,:+@%".contains(c));
            if plain {
                a
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_joins_the_parser_quote() {
        assert_eq!(
            one_line("bad value\n  |\n1 | x = 2\n"),
            "bad value | 1 | x = 2"
        );
    }

    #[test]
    fn with_path_names_the_file_once() {
        let path = Path::new("a/b.toml");
        assert_eq!(with_path(path, "no roads"), "a/b.toml: no roads");
        assert_eq!(with_path(path, "a/b.toml: no roads"), "a/b.toml: no roads");
    }

    #[test]
    fn a_missing_config_is_bad_input_naming_it() {
        let error = read_params(Some(Path::new("/no/such/params.toml")));
        let message = error.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(message.starts_with("/no/such/params.toml: "), "{message}");
    }
}
