//! Whole files or none: every file of the workspace's outputs is written here.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::raster::RgbImage;

use crate::error::OutputError;

/// Writes a file at `path` through a temporary file in the same directory and a rename, so that
/// a reader never sees half a file. `write` fills the temporary file; on any error (creating,
/// writing, flushing or renaming) the temporary file is removed and `path` is left as it was.
///
/// The temporary name is hidden and names the process (`.NAME.tmp-PID`), so that concurrent
/// runs writing the same file do not share one.
///
/// # Errors
///
/// [`OutputError::Io`] naming `path`; `path` without a file name (`/`, `..`) is refused with
/// [`std::io::ErrorKind::InvalidInput`].
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut fs::File) -> std::io::Result<()>,
) -> Result<(), OutputError> {
    let (guard, mut file) = AtomicFile::create(path)?;
    if let Err(source) = write(&mut file) {
        // Dropping the guard removes the temporary.
        return Err(OutputError::Io {
            path: path.to_path_buf(),
            source,
        });
    }
    // Not synced: a run writes hundreds of these, and a crash before the rename leaves only a
    // hidden temporary, never half a file under the target's name.
    guard.finish(file, false)
}

/// The streaming form of [`write_atomic`], for a file written over a whole run (the MCAP
/// recording): the same hidden temporary beside the target, renamed by [`AtomicFile::commit`];
/// dropped without a commit (an error, a panic) it removes the temporary and leaves `path` as it
/// was.
#[derive(Debug)]
pub struct AtomicFile {
    temporary: PathBuf,
    target: PathBuf,
    committed: bool,
}

/// Whether this process still creates temporaries; held while one is created.
static CREATING: std::sync::Mutex<bool> = std::sync::Mutex::new(true);

/// Stops this process from creating temporary files, for good. On return no temporary is being
/// created, so a process about to end on a signal can remove the ones it finds knowing that no
/// thread adds another; [`AtomicFile::create`] (and so every writer here) fails from then on.
pub fn stop_temporaries() {
    let mut creating = CREATING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    *creating = false;
}

impl AtomicFile {
    /// Creates the temporary for `path` and returns it open for writing.
    ///
    /// # Errors
    ///
    /// [`OutputError::Io`] naming `path`, as [`write_atomic`]; also after [`stop_temporaries`].
    pub fn create(path: &Path) -> Result<(Self, fs::File), OutputError> {
        let io = |source| OutputError::Io {
            path: path.to_path_buf(),
            source,
        };
        let temporary = temporary_path(path).ok_or_else(|| {
            io(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "not a file name",
            ))
        })?;
        let file = {
            let creating = CREATING
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            if !*creating {
                return Err(io(std::io::Error::new(
                    std::io::ErrorKind::Interrupted,
                    "the process is ending on a signal",
                )));
            }
            fs::File::create(&temporary).map_err(io)?
        };
        Ok((
            Self {
                temporary,
                target: path.to_path_buf(),
                committed: false,
            },
            file,
        ))
    }

    /// Renames the temporary onto the target. `file`, the handle [`AtomicFile::create`] gave,
    /// is flushed to disk and closed first.
    ///
    /// # Errors
    ///
    /// [`OutputError::Io`] naming the target; the temporary is then removed.
    pub fn commit(self, file: fs::File) -> Result<(), OutputError> {
        self.finish(file, true)
    }

    /// Flushes `file` (and syncs it to disk if `sync`), closes it and renames the temporary onto
    /// the target; on failure Drop removes the temporary.
    fn finish(mut self, mut file: fs::File, sync: bool) -> Result<(), OutputError> {
        let result = file
            .flush()
            .and_then(|()| if sync { file.sync_all() } else { Ok(()) })
            .and_then(|()| {
                drop(file);
                fs::rename(&self.temporary, &self.target)
            })
            .map_err(|source| OutputError::Io {
                path: self.target.clone(),
                source,
            });
        // On success there is nothing left to remove; on failure Drop removes the temporary.
        self.committed = result.is_ok();
        result
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.committed {
            // Best effort: the error that led here is the one to report.
            let _ = fs::remove_file(&self.temporary);
        }
    }
}

/// The hidden temporary beside `path`, or `None` if `path` does not end in a file name.
fn temporary_path(path: &Path) -> Option<PathBuf> {
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name()?);
    name.push(format!(".tmp-{}", std::process::id()));
    Some(path.with_file_name(name))
}

/// Encodes `image` as PNG ([`RgbImage::to_png`]: 8-bit RGB, fast deflate, an adaptive filter
/// per row) and writes it atomically ([`write_atomic`]).
///
/// # Errors
///
/// [`OutputError::Png`] or [`OutputError::Io`], naming `path`.
pub fn write_png(image: &RgbImage, path: &Path) -> Result<(), OutputError> {
    let encoded = image.to_png().map_err(|source| OutputError::Png {
        path: path.to_path_buf(),
        source,
    })?;
    write_atomic(path, |file| file.write_all(&encoded))
}

/// The same as [`write_png`], whose compression is already the fast one
/// (`png::Compression::Fast`); kept for the callers that name the speed they rely on.
///
/// # Errors
///
/// As [`write_png`].
pub fn write_png_fast(image: &RgbImage, path: &Path) -> Result<(), OutputError> {
    write_png(image, path)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// Names in `dir`, sorted.
    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_written_file_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomic(&path, |f| f.write_all(b"old")).unwrap();
        write_atomic(&path, |f| f.write_all(b"new")).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        assert_eq!(names(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_failed_write_removes_the_temporary_and_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        fs::write(&path, b"old").unwrap();
        let error = write_atomic(&path, |f| {
            f.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(error.to_string().contains("disk full"), "{error}");
        assert!(error.to_string().contains("a.txt"), "{error}");
        assert_eq!(fs::read(&path).unwrap(), b"old");
        assert_eq!(names(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_failed_rename_removes_the_temporary() {
        // The target is a non-empty directory: the temporary is written, the rename fails.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("taken");
        fs::create_dir(&path).unwrap();
        fs::write(path.join("inside"), b"x").unwrap();
        let error = write_atomic(&path, |f| f.write_all(b"data")).unwrap_err();
        assert!(matches!(error, OutputError::Io { .. }), "{error}");
        assert_eq!(names(dir.path()), ["taken"]);
    }

    #[test]
    fn a_streamed_file_appears_only_on_commit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let (atomic, mut file) = AtomicFile::create(&path).unwrap();
        file.write_all(b"frames").unwrap();
        assert!(!path.exists());
        atomic.commit(file).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"frames");
        assert_eq!(names(dir.path()), ["run.mcap"]);
        // Dropped without a commit: no file, no temporary.
        let other = dir.path().join("other.mcap");
        let (atomic, mut file) = AtomicFile::create(&other).unwrap();
        file.write_all(b"half").unwrap();
        drop(atomic);
        assert_eq!(names(dir.path()), ["run.mcap"]);
    }

    #[test]
    fn a_picture_png_cannot_hold_is_an_error_naming_the_file_and_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("empty.png");
        let error = write_png(&RgbImage::new(0, 4), &path).unwrap_err();
        assert!(matches!(error, OutputError::Png { .. }), "{error}");
        let message = error.to_string();
        assert!(message.contains("empty.png: PNG encoder: "), "{message}");
        assert!(!message.contains('\n'), "{message}");
        assert!(names(dir.path()).is_empty());
    }

    #[test]
    fn a_missing_directory_or_a_path_without_file_name_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let error = write_atomic(&dir.path().join("no/such/a.txt"), |_| Ok(())).unwrap_err();
        assert!(matches!(error, OutputError::Io { .. }), "{error}");
        let error = write_atomic(Path::new("/"), |_| Ok(())).unwrap_err();
        assert!(matches!(
            error,
            OutputError::Io { ref source, .. } if source.kind() == std::io::ErrorKind::InvalidInput
        ));
        assert!(names(dir.path()).is_empty());
    }
}
