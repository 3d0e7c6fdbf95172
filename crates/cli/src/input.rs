//! Reading what the user gave, and saying which input an error comes from.

use std::path::Path;

use anyhow::Result;
use evigrid::Params;

use crate::exit::BadInput;

/// Largest text input read (parameters, scenarios, mass functions, pose lists): these are
/// hand-written files of a few kB; a larger one is a wrong path.
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// Reads a small text input whole, as bad input naming it when it is not a regular file
/// (checked before opening: opening a FIFO with no writer blocks forever), larger than
/// [`MAX_TEXT_BYTES`] (bounded while reading: devices report no size) or not UTF-8.
pub fn read_text(path: &Path) -> Result<String> {
    drive::read_text_limited(path, MAX_TEXT_BYTES).map_err(|e| match e {
        drive::ReadError::Io { path, source } => {
            BadInput::new(format!("{}: cannot read: {source}", path.display()))
        }
        other => BadInput::new(other.to_string()),
    })
}

/// The parameters of `--config FILE` (SPEC §7 layout), or the defaults without one.
pub fn read_params(path: Option<&Path>) -> Result<Params> {
    let Some(path) = path else {
        return Ok(Params::default());
    };
    let text = read_text(path)?;
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
    fn special_files_are_refused_without_reading_them() {
        // /dev/zero never ends; a FIFO with no writer would block the open itself.
        for path in ["/dev/zero", "/dev/null", "/"] {
            let message = read_text(Path::new(path))
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert_eq!(message, format!("{path}: not a regular file"));
        }
    }

    #[test]
    fn a_missing_config_is_bad_input_naming_it() {
        let error = read_params(Some(Path::new("/no/such/params.toml")));
        let message = error.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(message.starts_with("/no/such/params.toml: "), "{message}");
    }
}
