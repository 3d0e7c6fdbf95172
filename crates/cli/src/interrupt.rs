//! Ctrl-C and SIGTERM as a request to stop: long commands check [`Interrupt::requested`] between
//! frames, stop, and still write what they have (the summary marked incomplete). A second signal
//! ends the process at once, for a run that does not stop quickly enough.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use signal_hook::consts::{SIGINT, SIGTERM};

/// The exit status after an interruption (128 + SIGINT), as shells report it.
pub const INTERRUPTED_EXIT: u8 = 130;

/// Set once SIGINT or SIGTERM arrives.
#[derive(Clone, Debug)]
pub struct Interrupt(Arc<AtomicBool>);

impl Interrupt {
    /// Installs the handlers. If they cannot be installed, the signals keep their default
    /// action (the process ends), which loses the summary but nothing else.
    pub fn install() -> Self {
        let flag = Arc::new(AtomicBool::new(false));
        for signal in [SIGINT, SIGTERM] {
            // Registered first, so that it sees the flag as the previous signal left it: the
            // second signal exits.
            let _ = signal_hook::flag::register_conditional_shutdown(
                signal,
                i32::from(INTERRUPTED_EXIT),
                Arc::clone(&flag),
            );
            let _ = signal_hook::flag::register(signal, Arc::clone(&flag));
        }
        Self(flag)
    }

    /// The flag a signal raises, for a library that polls it between frames.
    pub fn flag(&self) -> &AtomicBool {
        &self.0
    }
}

/// The error a command returns when it stopped on a signal (after writing what it had).
#[derive(Debug)]
pub struct Interrupted;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("interrupted by SIGINT or SIGTERM")
    }
}

impl std::error::Error for Interrupted {}
