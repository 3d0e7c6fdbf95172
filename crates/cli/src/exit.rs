//! Exit codes: 0 success, 1 failure of the tool itself, 2 bad input (Unix habit, as grep).

use std::fmt;
use std::process::ExitCode;

/// Marks an error as the user's input being wrong, so that the process exits with status 2.
///
/// Wrap any error that names a file, an argument or a value the user gave:
/// `Err(BadInput::new(format!("{path}: {e}")))?`.
#[derive(Debug)]
pub struct BadInput(pub String);

impl BadInput {
    /// A bad-input error with a one-line message that names the input and the problem.
    // Returns the anyhow::Error every command propagates, so call sites stay `Err(BadInput::new(..))?`.
    #[allow(clippy::new_ret_no_self)]
    pub fn new(message: impl Into<String>) -> anyhow::Error {
        anyhow::Error::new(BadInput(message.into()))
    }
}

impl fmt::Display for BadInput {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadInput {}

/// Prints the error chain on one line to standard error and chooses the exit status.
pub fn report(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            let message = error
                .chain()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(": ");
            eprintln!("evigrid: {message}");
            if error.chain().any(|cause| cause.is::<BadInput>()) {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}
