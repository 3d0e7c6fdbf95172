//! The command line's side of the one output policy (`output::out_dir`, which `evigrid.run` in
//! Python follows too): its refusals as bad input (exit 2), in the words of the flags.

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
pub struct OutDir(out_dir::OutDir);

impl OutDir {
    /// Checks, without creating or changing anything, that [`OutDir::prepare`] will succeed.
    ///
    /// # Errors
    /// Bad input naming `path`, as [`OutDir::prepare`] would give.
    pub fn check(path: &Path, force: bool) -> Result<()> {
        out_dir::OutDir::check(path, force).map_err(bad)
    }

    /// Checks `path` as the output folder of `command` and prepares it
    /// ([`out_dir::OutDir::prepare`]).
    ///
    /// # Errors
    /// Bad input naming `path`.
    pub fn prepare(path: &Path, force: bool, command: &str) -> Result<Self> {
        out_dir::OutDir::prepare(path, force, command)
            .map(Self)
            .map_err(bad)
    }

    /// Records in the marker the files written since [`OutDir::prepare`].
    ///
    /// # Errors
    /// If the marker cannot be written (naming it).
    pub fn finish(&self) -> Result<()> {
        self.0.finish().map_err(|e| BadInput::new(e.to_string()))
    }
}

/// Checks that `path` may be written as a single output file ([`out_dir::check_out_file`]).
///
/// # Errors
/// Bad input naming `path`.
pub fn check_out_file(path: &Path, inputs: &[&Path]) -> Result<()> {
    out_dir::check_out_file(path, inputs).map_err(bad)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_name_the_flags_as_before() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        std::fs::write(tmp.path().join("thesis.tex"), "precious")?;
        let refused = OutDir::prepare(tmp.path(), false, "run")
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
        let message = OutDir::check(&file, false).err().map(|e| e.to_string());
        assert!(message.is_some_and(|m| m.starts_with(&format!("--out {}: ", file.display()))));
        Ok(())
    }
}
