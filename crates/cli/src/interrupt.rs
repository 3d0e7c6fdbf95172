//! SIGINT, SIGTERM and SIGHUP, handled alike.
//!
//! - **The first signal stops between units of work**: every long command (`run`, `odometry`,
//!   `demo`, `eval`, `tune`, `bench`) calls [`Interrupt::install`] and hands [`Interrupt::flag`]
//!   to its library, which checks it between frames (drives, candidates, rounds): the command
//!   stops there and still writes what it has, marked incomplete (the summary, the pose file,
//!   the report; an output folder's marker by [`crate::out_dir::OutDir::finish_interrupted`]),
//!   and exits 128 + the signal.
//! - **A second signal ends at once**: the temporary files of the output folders registered with
//!   [`remove_temporaries_on_exit`] are removed, the folders' markers say the run was
//!   interrupted, and the process exits 128 + the signal (130 SIGINT, 143 SIGTERM, 129 SIGHUP).
//!   A record being written ([`output::WholeLines`]) is finished first, so no file ends in a torn
//!   record.
//!
//! The signals are received by a thread of their own (`signal_hook`'s iterator), not in a
//! signal handler, so removing files and taking a lock are allowed.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};

/// The signals a long command handles, all alike.
const HANDLED: [i32; 3] = [SIGINT, SIGTERM, SIGHUP];

/// The first signal received (0: none).
static RECEIVED: AtomicI32 = AtomicI32::new(0);

/// Raised with [`RECEIVED`]: the stop flag the libraries poll between frames.
static STOP: AtomicBool = AtomicBool::new(false);

/// Raised when a second signal starts ending the process ([`end_now`]).
static ENDING: AtomicBool = AtomicBool::new(false);

/// Output folders whose temporary files are removed when the process ends on a signal, each
/// with the marker (if any) that then says the run was interrupted.
static FOLDERS: Mutex<Vec<(PathBuf, Option<PathBuf>)>> = Mutex::new(Vec::new());

/// The exit status after `signal`, as shells report it: 128 + its number.
pub fn exit_status(signal: i32) -> u8 {
    u8::try_from(128 + signal).unwrap_or(255)
}

/// The exit status of a command that stopped on the signal received (130, SIGINT, if none was).
pub fn interrupted_exit() -> u8 {
    match RECEIVED.load(Ordering::Relaxed) {
        0 => exit_status(SIGINT),
        signal => exit_status(signal),
    }
}

/// Waits, if a second signal is ending the process, for [`end_now`] to finish: it removes the
/// temporaries and exits 128 + the signal. A command whose last write that ending refused
/// must not exit first, with its own status and the temporaries still there.
pub fn wait_if_ending() {
    while ENDING.load(Ordering::SeqCst) {
        std::thread::park_timeout(std::time::Duration::from_millis(100));
    }
}

/// The signal's name, for messages.
fn name(signal: i32) -> &'static str {
    match signal {
        SIGINT => "SIGINT",
        SIGTERM => "SIGTERM",
        SIGHUP => "SIGHUP",
        _ => "a signal",
    }
}

/// A handle on the stop request of the handled signals.
#[derive(Clone, Debug)]
pub struct Interrupt(());

impl Interrupt {
    /// The first signal asks the command to stop ([`Interrupt::flag`]); a second ends the
    /// process at once. If the handlers cannot be installed, the signals keep their default
    /// action (the process ends), which loses the summary but nothing else.
    pub fn install() -> Self {
        listen();
        Self(())
    }

    /// The flag the first signal raises, for a library that polls it between frames.
    pub fn flag(&self) -> &'static AtomicBool {
        &STOP
    }
}

/// Starts the thread that receives the signals.
fn listen() {
    let Ok(mut signals) = signal_hook::iterator::Signals::new(HANDLED) else {
        return;
    };
    let started = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            for signal in signals.forever() {
                let first = RECEIVED
                    .compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst)
                    .is_ok();
                STOP.store(true, Ordering::SeqCst);
                if !first {
                    end_now(signal);
                }
            }
        });
    // Without the thread the signals would be caught and never acted on: give them back their
    // default action.
    if started.is_err() {
        for signal in HANDLED {
            let _ = signal_hook::low_level::emulate_default_handler(signal);
        }
    }
}

/// Ends the process on `signal`: waits for the record being written, removes the registered
/// folders' temporary files, marks the folders interrupted, exits 128 + `signal`.
fn end_now(signal: i32) -> ! {
    ENDING.store(true, Ordering::SeqCst);
    // Waits for the record being written; none is started after it.
    output::stop_records();
    // Then no thread (the demo's encoder) creates a temporary after they are removed.
    output::stop_temporaries();
    let folders = FOLDERS.lock().map(|f| f.clone()).unwrap_or_default();
    let suffix = format!(".tmp-{}", std::process::id());
    for (folder, marker) in &folders {
        remove_temporaries(folder, &suffix, 0);
        if let Some(marker) = marker {
            mark_interrupted(marker, signal);
        }
    }
    let _ = std::io::stderr().lock().write_all(
        format!(
            "evigrid: interrupted by {}: stopped at once, outputs incomplete\n",
            name(signal)
        )
        .as_bytes(),
    );
    signal_hook::low_level::exit(i32::from(exit_status(signal)))
}

/// Registers an output folder: when the process ends on a signal, the temporary files this
/// process left in it are removed and its `marker`, if given, says the run was interrupted.
pub fn remove_temporaries_on_exit(folder: &Path, marker: Option<&Path>) {
    if let Ok(mut folders) = FOLDERS.lock() {
        folders.push((folder.to_path_buf(), marker.map(Path::to_path_buf)));
    }
}

/// Removes the files under `dir` whose names end with `suffix` (this process's temporaries),
/// not following links, at most 8 folders deep.
fn remove_temporaries(dir: &Path, suffix: &str, depth: usize) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let Ok(kind) = entry.file_type() else {
            continue;
        };
        if kind.is_dir() && depth < 8 {
            remove_temporaries(&entry.path(), suffix, depth + 1);
        } else if kind.is_file() && entry.file_name().to_string_lossy().ends_with(suffix) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Adds `interrupted: SIGNAL` (the first signal received) to an output folder's marker, for a
/// command that stopped on it and finished its outputs.
pub fn mark_received(marker: &Path) {
    mark_interrupted(marker, RECEIVED.load(Ordering::Relaxed));
}

/// Adds `interrupted: SIGNAL` to an output folder's marker, if it is there.
fn mark_interrupted(marker: &Path, signal: i32) {
    if marker.is_file()
        && let Ok(mut file) = std::fs::OpenOptions::new().append(true).open(marker)
    {
        let _ = writeln!(file, "interrupted: {}", name(signal));
    }
}

/// The error a command returns when it stopped on a signal (after writing what it had).
#[derive(Debug)]
pub struct Interrupted;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "interrupted by {}",
            name(match RECEIVED.load(Ordering::Relaxed) {
                0 => SIGINT,
                signal => signal,
            })
        )
    }
}

impl std::error::Error for Interrupted {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_statuses_are_128_plus_the_signal() {
        assert_eq!(exit_status(SIGINT), 130);
        assert_eq!(exit_status(SIGTERM), 143);
        assert_eq!(exit_status(SIGHUP), 129);
    }

    #[test]
    fn only_this_process_temporaries_are_removed() -> std::io::Result<()> {
        let tmp = tempfile::tempdir()?;
        let suffix = format!(".tmp-{}", std::process::id());
        std::fs::create_dir(tmp.path().join("frames"))?;
        let ours = tmp.path().join(format!("frames/.a.png{suffix}"));
        let other = tmp.path().join(".b.png.tmp-1");
        let kept = tmp.path().join("summary.json");
        for file in [&ours, &other, &kept] {
            std::fs::write(file, "x")?;
        }
        remove_temporaries(tmp.path(), &suffix, 0);
        assert!(!ours.exists());
        assert!(other.exists() && kept.exists());
        Ok(())
    }
}
