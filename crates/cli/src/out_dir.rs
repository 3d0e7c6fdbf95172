//! The command line's side of the one output policy (`output::out_dir`, which `evigrid.run` in
//! Python follows too): its refusals as bad input (exit 2), in the words of the flags.

use std::fs;
use std::path::Path;

use anyhow::Result;
use output::out_dir::{self, OutDirError};

use crate::exit::BadInput;

/// A refusal as one line naming `--out` and, for a folder of someone else's files, the remedy.
fn bad(error: OutDirError) -> anyhow::Error {
    match error {
        OutDirError::NotOurs { .. } => BadInput::new(format!(
            "--out {error}; choose another --out or add --force"
        )),
        other => BadInput::new(format!("--out {other}")),
    }
}

/// An output folder checked and ready for writing; [`OutDir::finish`] records what was written.
#[derive(Debug)]
pub struct OutDir {
    inner: out_dir::OutDir,
    /// Set by [`OutDir::finish`]; dropped without it, the folder is marked incomplete.
    finished: std::sync::atomic::AtomicBool,
}

impl OutDir {
    /// Checks, without creating or changing anything, that [`OutDir::prepare`] will succeed
    /// with these `inputs`.
    ///
    /// # Errors
    /// Bad input naming `path`, as [`OutDir::prepare`] would give.
    pub fn check(path: &Path, inputs: &[&Path], force: bool) -> Result<()> {
        out_dir::OutDir::check_inputs(path, inputs).map_err(bad)?;
        out_dir::OutDir::check(path, force).map_err(bad)
    }

    /// Checks `path` as the output folder of `command` reading `inputs` (none of which it may
    /// hold, [`out_dir::OutDir::check_inputs`]) and prepares it ([`out_dir::OutDir::prepare`]).
    ///
    /// # Errors
    /// Bad input naming `path`.
    pub fn prepare(path: &Path, inputs: &[&Path], force: bool, command: &str) -> Result<Self> {
        out_dir::OutDir::check_inputs(path, inputs).map_err(bad)?;
        let prepared = out_dir::OutDir::prepare(path, force, command).map_err(bad)?;
        // A process that ends at once on a signal removes its temporaries here and marks the
        // folder interrupted.
        crate::interrupt::remove_temporaries_on_exit(path, Some(&path.join(out_dir::MARKER)));
        Ok(Self {
            inner: prepared,
            finished: std::sync::atomic::AtomicBool::new(false),
        })
    }

    /// Records in the marker the files written since [`OutDir::prepare`].
    ///
    /// # Errors
    /// If the marker cannot be written (naming it).
    pub fn finish(&self) -> Result<()> {
        self.inner
            .finish()
            .map_err(|e| BadInput::new(e.to_string()))?;
        self.finished
            .store(true, std::sync::atomic::Ordering::Relaxed);
        Ok(())
    }
}

impl OutDir {
    /// [`OutDir::finish`] for a command that stopped on a signal after writing what it had:
    /// the marker also says `incomplete: true` and which signal stopped it.
    ///
    /// # Errors
    /// If the marker cannot be written (naming it).
    pub fn finish_interrupted(&self) -> Result<()> {
        self.finish()?;
        let marker = self.inner.path().join(out_dir::MARKER);
        let mut file = fs::OpenOptions::new()
            .append(true)
            .open(&marker)
            .map_err(|e| anyhow::anyhow!("{}: {e}", marker.display()))?;
        std::io::Write::write_all(&mut file, b"incomplete: true\n")
            .map_err(|e| anyhow::anyhow!("{}: {e}", marker.display()))?;
        crate::interrupt::mark_received(&marker);
        Ok(())
    }

    /// Finishes the folder of a command that ran to its end (`complete`: [`OutDir::finish`]),
    /// or that a signal stopped ([`OutDir::finish_interrupted`], then the
    /// [`Interrupted`](crate::interrupt::Interrupted) error with the context `stopped` words:
    /// how far it got, where its outputs are).
    ///
    /// # Errors
    /// If the marker cannot be written (naming it); [`Interrupted`](crate::interrupt::Interrupted)
    /// when not `complete`.
    pub fn finish_or_stopped(
        &self,
        complete: bool,
        stopped: impl FnOnce() -> String,
    ) -> Result<()> {
        if !complete {
            self.finish_interrupted()?;
            return Err(anyhow::Error::new(crate::interrupt::Interrupted).context(stopped()));
        }
        self.finish()
    }
}

impl Drop for OutDir {
    /// A command that ends on an error (a full disk, a bad input found late) leaves its folder
    /// marked: `incomplete: true` in the marker, which the next run into it clears.
    fn drop(&mut self) {
        if self.finished.load(std::sync::atomic::Ordering::Relaxed) {
            return;
        }
        let marker = self.inner.path().join(out_dir::MARKER);
        if let Ok(mut file) = fs::OpenOptions::new().append(true).open(&marker) {
            let _ = std::io::Write::write_all(&mut file, b"incomplete: true\n");
        }
    }
}

/// Checks a single output file before any work ([`out_dir::check_out_file`]: never an input,
/// never a special file, an existing file only with `--force`).
///
/// # Errors
/// Bad input naming `--out` and the file.
pub fn check_out_file(path: &Path, inputs: &[&Path], force: bool) -> Result<()> {
    out_dir::check_out_file(path, inputs, force).map_err(|e| bad_file("--out ", e))
}

/// [`check_out_file`] for a side file written beside the `--out` file.
///
/// # Errors
/// Bad input naming the file.
pub fn check_side_file(path: &Path, inputs: &[&Path], force: bool) -> Result<()> {
    out_dir::check_out_file(path, inputs, force).map_err(|e| bad_file("", e))
}

/// A refused output file as one line, after `label`, with the remedy when there is one.
fn bad_file(label: &str, error: OutDirError) -> anyhow::Error {
    match error {
        OutDirError::Exists { .. } => BadInput::new(format!(
            "{label}{error}; evigrid replaces a file only with --force (and never an input)"
        )),
        other => BadInput::new(format!("{label}{other}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_name_the_flags_as_before() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        std::fs::write(tmp.path().join("thesis.tex"), "precious")?;
        let refused = OutDir::prepare(tmp.path(), &[], false, "run")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert_eq!(
            refused,
            format!(
                "--out {}: exists and is not an evigrid output folder (no .evigrid-output \
                 file); choose another --out or add --force",
                tmp.path().display()
            )
        );
        let file = tmp.path().join("thesis.tex/x");
        let message = OutDir::check(&file, &[], false)
            .err()
            .map(|e| e.to_string());
        assert!(message.is_some_and(|m| m.starts_with(&format!("--out {}: ", file.display()))));
        Ok(())
    }

    fn message(result: Result<impl std::fmt::Debug>) -> String {
        result.err().map(|e| e.to_string()).unwrap_or_default()
    }

    #[test]
    fn file_refusals_name_the_flag_and_the_remedy() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let notes = tmp.path().join("notes.txt");
        fs::write(&notes, "mine")?;
        assert_eq!(
            message(check_out_file(&notes, &[], false)),
            format!(
                "--out {}: exists; evigrid replaces a file only with --force (and never an input)",
                notes.display()
            )
        );
        assert_eq!(
            message(check_side_file(&notes, &[], false)),
            format!(
                "{}: exists; evigrid replaces a file only with --force (and never an input)",
                notes.display()
            )
        );
        assert_eq!(
            message(check_out_file(&notes, &[&notes], true)),
            format!(
                "--out {0}: is the input {0}; writing it would destroy it",
                notes.display()
            )
        );
        check_out_file(&notes, &[], true)?;
        Ok(())
    }

    #[test]
    fn an_output_folder_holding_an_input_is_refused_even_with_force() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let bag = tmp.path().join("run.mcap");
        fs::write(&bag, "recording")?;
        let refused = message(OutDir::prepare(tmp.path(), &[&bag], true, "run"));
        assert!(
            refused.starts_with(&format!("--out {}: holds the input ", tmp.path().display())),
            "{refused}"
        );
        assert!(!tmp.path().join(out_dir::MARKER).exists());
        Ok(())
    }
}
