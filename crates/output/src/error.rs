//! The one error type of the crate, and the size check every view and export makes first.

use std::path::PathBuf;

use evigrid::Window;

/// Why a picture or an export could not be made or written. Every variant but `Size` names the
/// file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// Writing or renaming the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Encoding the PNG failed.
    #[error("{path}: PNG encoder: {source}")]
    Png {
        /// The file.
        path: PathBuf,
        /// The encoder's error.
        source: png::EncodingError,
    },
    /// Serialising JSON failed.
    #[error("{path}: {source}")]
    Json {
        /// The file.
        path: PathBuf,
        /// The serialiser's error.
        source: serde_json::Error,
    },
    /// A figure would be too large to hold (window × enlargement beyond [`MAX_FIGURE_PIXELS`]).
    #[error("a figure of {width} × {height} px is too large (at most {MAX_FIGURE_PIXELS} px)")]
    FigureTooLarge {
        /// Width it would have, pixels.
        width: u64,
        /// Height it would have, pixels.
        height: u64,
    },
    /// Writing the MCAP recording failed.
    #[error("{path}: {source}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// The MCAP writer's error.
        source: ::mcap::McapError,
    },
    /// A time cannot be recorded (negative, not finite, or from the year 2540 on).
    #[error("{path}: time {time_s} s cannot be recorded")]
    Time {
        /// The file.
        path: PathBuf,
        /// The time, seconds.
        time_s: f64,
    },
    /// A buffer does not have one entry per window cell.
    #[error("{what} holds {len} cells, the window {expected}")]
    Size {
        /// Which buffer.
        what: &'static str,
        /// Its length.
        len: usize,
        /// The window's cell count.
        expected: usize,
    },
}

/// The most pixels a figure may have (2^28, 768 MiB of RGB).
pub const MAX_FIGURE_PIXELS: u64 = 1 << 28;

/// `Ok` if a buffer of `len` entries has one per cell of `window`.
pub(crate) fn check_len(
    what: &'static str,
    len: usize,
    window: &Window,
) -> Result<(), OutputError> {
    if len == window.len() {
        Ok(())
    } else {
        Err(OutputError::Size {
            what,
            len,
            expected: window.len(),
        })
    }
}
