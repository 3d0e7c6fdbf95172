//! Why a session could not start, or stopped.

use drive::SourceError;
use output::OutputError;

/// A session's error. [`SessionError::is_bad_input`] tells the input's fault (a command exits
/// with its bad-input code) from an I/O failure or an interruption.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SessionError {
    /// The drive cannot be opened or placed.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// The map cannot be read.
    #[error(transparent)]
    Map(#[from] geodata::MapError),
    /// A bad input the session found: parameters out of range, an origin off the globe, poses
    /// off the map, a scan refused with `strict`, no usable scan.
    #[error("{0}")]
    Input(String),
    /// A sink failed (the message names the file).
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The caller's stop flag was raised. The session does not know why (a signal, Ctrl-C in
    /// Python); a caller that knows says so in the summary's `stopped`.
    #[error("interrupted (stop requested)")]
    Interrupted,
    /// The session ended early ([`crate::run_drive`]): the summary says what was done (marked
    /// incomplete), `cause` why it ended.
    #[error("{cause}")]
    Stopped {
        /// The summary of what was done.
        summary: Box<crate::Summary>,
        /// Why the session stopped.
        cause: Box<SessionError>,
    },
}

impl SessionError {
    /// True when the caller's stop flag ended the session.
    pub fn is_interrupted(&self) -> bool {
        match self {
            Self::Interrupted => true,
            Self::Stopped { cause, .. } => cause.is_interrupted(),
            _ => false,
        }
    }

    /// True when the input is at fault (not the machine, not the user's interruption).
    pub fn is_bad_input(&self) -> bool {
        match self {
            Self::Source(_) | Self::Map(_) | Self::Input(_) => true,
            Self::Stopped { cause, .. } => cause.is_bad_input(),
            Self::Output(_) | Self::Interrupted => false,
        }
    }
}
