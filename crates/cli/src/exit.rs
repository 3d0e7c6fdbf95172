//! Exit codes: 0 success, 1 the environment failed (a full disk, a write error), 2 bad input or
//! usage (Unix habit, as grep), 128 + n ended by signal n (130 SIGINT, 143 SIGTERM, 129 SIGHUP).

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

/// The error chain on one line, `outer: inner: …`, leaving out a cause whose text the message
/// before it already ends with (I/O errors wrapped with their own text would print twice: "No
/// space left on device (os error 28): No space left on device (os error 28)").
pub fn one_line_chain(error: &anyhow::Error) -> String {
    let mut message = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if message.ends_with(&text) {
            continue;
        }
        if !message.is_empty() {
            message.push_str(": ");
        }
        message.push_str(&text);
    }
    message.replace('\n', " ")
}

/// Prints the error chain on one line to standard error and chooses the exit status.
pub fn report(result: anyhow::Result<()>) -> ExitCode {
    // A command that did its work but could not print it failed all the same.
    let result = result.and_then(|()| match crate::stdout::failure() {
        Some(failure) => Err(anyhow::anyhow!(failure)),
        None => Ok(()),
    });
    // Once a second signal is ending the process, the ending exits, with the signal's status
    // (the error may be its own refusal to create a file).
    crate::interrupt::wait_if_ending();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            let message = one_line_chain(&error);
            crate::errln!("evigrid: {message}");
            if error
                .chain()
                .any(|cause| cause.is::<crate::interrupt::Interrupted>())
            {
                ExitCode::from(crate::interrupt::interrupted_exit())
            } else if error.chain().any(|cause| cause.is::<BadInput>()) {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context;

    #[test]
    fn a_cause_repeating_its_wrapper_is_printed_once() {
        let full = std::io::Error::from_raw_os_error(28);
        let text = full.to_string();
        let error = Err::<(), _>(std::io::Error::other(full))
            .context("out/masses.bin")
            .err()
            .map(|e| one_line_chain(&e));
        assert_eq!(error, Some(format!("out/masses.bin: {text}")));
    }

    #[test]
    fn the_chain_is_one_line() {
        let error = anyhow::anyhow!("line one\nline two").context("file.toml");
        assert_eq!(one_line_chain(&error), "file.toml: line one line two");
    }
}
