//! Standard output and standard error that never panic: what `println!` and `eprintln!` do,
//! without their panic when the stream is closed or full.
//!
//! - A closed pipe (`evigrid run … | head -c 10`) is the reader's choice, not a failure: the
//!   first `EPIPE` silences standard output for the rest of the process, the command goes on
//!   and finishes its files on disk, and ends as it would have, quietly (as ripgrep does).
//! - Any other write error (`>/dev/full`) is remembered and standard output silenced too; the
//!   command still finishes its files, then [`crate::exit::report`] turns it into the one-line
//!   error of exit 1 ([`failure`]).
//!
//! The macros [`outln!`](crate::outln), [`out!`](crate::out) and [`errln!`](crate::errln) are
//! the only way the commands print.

use std::io::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// Set once standard output failed or was closed: nothing more is written to it.
static SILENCED: AtomicBool = AtomicBool::new(false);

/// The first write error on standard output other than a closed pipe.
static FAILURE: Mutex<Option<String>> = Mutex::new(None);

/// Writes `text` to standard output and flushes it; after a closed pipe or a failure, does
/// nothing.
pub fn write(text: &str) {
    if SILENCED.load(Ordering::Relaxed) {
        return;
    }
    let mut stdout = std::io::stdout().lock();
    let written = stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush());
    if let Err(error) = written {
        record(&error);
    }
}

/// Writes `text` to standard error; a closed or failing standard error is ignored (there is
/// nowhere left to say so).
pub fn write_err(text: &str) {
    let _ = std::io::stderr().lock().write_all(text.as_bytes());
}

/// Silences standard output after `error`, remembering it unless it is a closed pipe.
fn record(error: &std::io::Error) {
    SILENCED.store(true, Ordering::Relaxed);
    if error.kind() == std::io::ErrorKind::BrokenPipe {
        return;
    }
    if let Ok(mut failure) = FAILURE.lock()
        && failure.is_none()
    {
        *failure = Some(error.to_string());
    }
}

/// The write error standard output met, other than a closed pipe, as one line.
pub fn failure() -> Option<String> {
    let failure = FAILURE.lock().ok()?.clone()?;
    Some(format!("standard output: {failure}"))
}

/// `println!` without the panic: a line on standard output (see the module docs).
#[macro_export]
macro_rules! outln {
    () => {
        $crate::stdout::write("\n")
    };
    ($($arg:tt)*) => {
        $crate::stdout::write(&format!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` without the panic: text on standard output (see the module docs).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::stdout::write(&format!($($arg)*))
    };
}

/// `eprintln!` without the panic: a line on standard error, dropped if standard error is closed.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::stdout::write_err(&format!("{}\n", format_args!($($arg)*)))
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_closed_pipe_silences_without_a_failure_and_other_errors_are_kept() {
        // One test touches the process-wide state, in order.
        record(&std::io::Error::from(std::io::ErrorKind::BrokenPipe));
        assert!(SILENCED.load(Ordering::Relaxed));
        assert_eq!(failure(), None);
        record(&std::io::Error::from_raw_os_error(28));
        record(&std::io::Error::from_raw_os_error(5));
        let kept = failure().unwrap_or_default();
        assert!(kept.starts_with("standard output: No space left"), "{kept}");
    }
}
