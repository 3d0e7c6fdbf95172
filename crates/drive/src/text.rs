//! Bounded reading of text inputs and the small parsing helpers the readers share.

use crate::error::{MAX_TEXT_BYTES, ReadError};
use std::io::Read;
use std::path::Path;

/// Reads a whole text file, refusing more than [`MAX_TEXT_BYTES`] and non-UTF-8 content (with
/// the line of the first bad byte).
pub(crate) fn read_text(path: &Path) -> Result<String, ReadError> {
    read_text_limited(path, MAX_TEXT_BYTES)
}

/// Reads a whole text file of at most `max_bytes`, refusing what is not a regular file (checked
/// before opening), more bytes (bounded while reading too: devices report no size) and
/// non-UTF-8 content (with the line of the first bad byte).
///
/// # Errors
///
/// [`ReadError::File`] for a special file, [`ReadError::Io`], [`ReadError::TooLarge`],
/// [`ReadError::Line`] for bytes that are not UTF-8.
pub fn read_text_limited(path: &Path, max_bytes: u64) -> Result<String, ReadError> {
    let io = |source| ReadError::Io {
        path: path.to_path_buf(),
        source,
    };
    // Checked before opening: opening a FIFO with no writer blocks forever.
    if let Ok(meta) = std::fs::metadata(path)
        && !meta.is_file()
    {
        return Err(ReadError::File {
            path: path.to_path_buf(),
            message: "not a regular file".into(),
        });
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let too_large = |len| ReadError::TooLarge {
        path: path.to_path_buf(),
        len,
        max: max_bytes,
    };
    if let Ok(meta) = file.metadata()
        && meta.len() > max_bytes
    {
        return Err(too_large(meta.len()));
    }
    // `take` also bounds what is read from files whose metadata lies (devices, pipes, growing
    // files).
    let mut bytes = Vec::new();
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large(bytes.len() as u64));
    }
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let line = 1 + e.as_bytes()[..valid]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        ReadError::Line {
            path: path.to_path_buf(),
            line,
            message: "not valid UTF-8 text".into(),
        }
    })
}

/// The data lines of a text: `(1-based line number, trimmed line)`, skipping blank lines and
/// lines whose first non-blank character is `#`.
pub(crate) fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// Parses exactly `N` whitespace-separated finite numbers. On a wrong count, `Err(Ok(found))`;
/// on a bad word, `Err(Err(message))`. Never allocates in proportion to the line.
pub(crate) fn numbers<const N: usize>(line: &str) -> Result<[f64; N], Result<usize, String>> {
    let mut out = [0.0; N];
    let mut found = 0usize;
    for word in line.split_whitespace() {
        if found < N {
            out[found] = number(word).map_err(Err)?;
        }
        found += 1;
    }
    if found == N { Ok(out) } else { Err(Ok(found)) }
}

/// One finite number, or a message saying why not.
pub(crate) fn number(word: &str) -> Result<f64, String> {
    match word.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("`{word}` is not finite")),
        Err(_) => Err(format!("`{word}` is not a number")),
    }
}

/// A [`ReadError::Line`].
pub(crate) fn line_error(path: &Path, line: usize, message: impl Into<String>) -> ReadError {
    ReadError::Line {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// A number for a message: as written for ordinary magnitudes, in exponent form for huge or tiny
/// ones (`1e308`, not 309 digits).
pub(crate) fn show(value: f64) -> String {
    if value == 0.0 || !value.is_finite() || (1e-4..1e9).contains(&value.abs()) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

/// A [`ReadError::File`].
pub(crate) fn file_error(path: &Path, message: impl Into<String>) -> ReadError {
    ReadError::File {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// [`numbers`] with its errors turned into [`ReadError::Line`]; `what` names the expected
/// content for the wrong-count message.
pub(crate) fn numbers_on_line<const N: usize>(
    path: &Path,
    line_number: usize,
    line: &str,
    what: &str,
) -> Result<[f64; N], ReadError> {
    numbers::<N>(line).map_err(|e| match e {
        Ok(found) => line_error(
            path,
            line_number,
            format!("expected {N} numbers ({what}), found {found}"),
        ),
        Err(message) => line_error(path, line_number, message),
    })
}
