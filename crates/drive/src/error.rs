//! The one error type of the text readers ([`timestamp`](crate::timestamp),
//! [`calib`](crate::calib), [`oxts`](crate::oxts), [`poses`](crate::poses)).
//!
//! One shared type rather than one per format because every text reader fails the same few ways
//! (cannot read, too big, a bad line, a bad file as a whole), and a caller that reads a drive
//! touches several formats: it should not have to wrap four error types to report "file:line:
//! what". Every variant names the file; line-level variants carry the 1-based line.

use std::path::PathBuf;

/// Largest text input read, in bytes (1 GiB): far above any real pose, timestamp or calibration
/// file (a 100 Hz TUM trajectory of ten hours is about 400 MB), and a bound on what a hostile or
/// mistaken path (a device, a huge binary) can make a reader allocate.
pub const MAX_TEXT_BYTES: u64 = 1 << 30;

/// Why a text file (timestamps, calibration, OXTS packet, pose file) could not be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReadError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file is larger than the readers' bound, [`MAX_TEXT_BYTES`].
    #[error("{path}: {len} bytes or more, above the {max}-byte limit for a text input")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Bytes seen (at least this many).
        len: u64,
        /// The limit.
        max: u64,
    },
    /// One line is malformed.
    #[error("{path}:{line}: {message}")]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong, and what was expected.
        message: String,
    },
    /// A data line has a column count that matches no pose format.
    #[error(
        "{path}:{line}: {found} columns{hint}; a pose file has 7 (evigrid: `t x y z roll pitch \
         yaw`, or `t lat lon alt roll pitch yaw` after `# frame: wgs84`), 8 (TUM: `t x y z qx qy \
         qz qw`) or 12 (KITTI odometry: a 3x4 row-major matrix)"
    )]
    Columns {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Columns found.
        found: usize,
        /// Why the count may be wrong, with a leading space (empty when there is no clue): a
        /// comma-separated line is one column, since columns are separated by white space.
        hint: String,
    },
    /// A time does not increase on the previous data line's.
    #[error("{path}:{line}: time {time} s does not increase on the previous time {previous} s")]
    NotIncreasing {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the offending time.
        line: usize,
        /// The time on that line.
        time: f64,
        /// The time before it.
        previous: f64,
    },
    /// The file as a whole is wrong (a required key is missing, counts disagree, no data).
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong, and what was expected.
        message: String,
    },
}
