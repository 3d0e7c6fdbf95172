//! One output policy for every writer of an output folder (the command line's commands, the
//! Python package's `evigrid.run`), checked before any work.
//!
//! - An output folder is created if missing. An existing folder is reused only if it is empty or
//!   holds evigrid's marker file (written by an earlier run); any other folder is refused unless
//!   forced, so a typo never mixes results into, or overwrites, a user's own files.
//! - Reusing an evigrid folder first removes what the previous run listed in its marker, so an old
//!   `summary.json` never sits beside new frames.
//! - An output file must not be one of the command's inputs, nor a special file (`/dev/full`, a
//!   FIFO): it is replaced by an atomic rename, which would replace the device node itself.
//! - Every problem is an [`OutDirError`] naming the path, found before the work starts; the
//!   caller words the remedy (`--force`, `force=True`).

use std::fs;
use std::path::{Path, PathBuf};

/// Name of the marker file evigrid leaves in every output folder it writes.
pub const MARKER: &str = ".evigrid-output";

/// Why a folder or file cannot be written as an output.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutDirError {
    /// A folder holding files that no evigrid run wrote (and not forced).
    #[error("{}: exists and is not an evigrid output folder (no .evigrid-output file)", path.display())]
    NotOurs {
        /// The folder.
        path: PathBuf,
    },
    /// Any other problem: `why` says it.
    #[error("{}: {why}", path.display())]
    Refused {
        /// The folder or file.
        path: PathBuf,
        /// What is wrong.
        why: String,
    },
}

type Result<T> = std::result::Result<T, OutDirError>;

fn refused(path: &Path, why: impl Into<String>) -> OutDirError {
    OutDirError::Refused {
        path: path.to_path_buf(),
        why: why.into(),
    }
}

/// Creates and removes a probe file in `dir`: the only sure test that a folder is writable.
fn probe_writable(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(format!(".evigrid-probe-{}", std::process::id()));
    fs::write(&probe, b"")?;
    fs::remove_file(&probe)
}

/// An output folder checked and ready for writing; [`OutDir::finish`] records what was written.
#[derive(Debug)]
pub struct OutDir {
    path: PathBuf,
    command: String,
    /// When the folder was prepared: files modified since are this run's.
    started: std::time::SystemTime,
}

impl OutDir {
    /// Checks, without creating or changing anything, that [`OutDir::prepare`] will succeed:
    /// for commands that read and check all their inputs first, so that a bad input leaves no
    /// output folder behind.
    ///
    /// # Errors
    /// Bad input naming `path`, as [`OutDir::prepare`] would give.
    pub fn check(path: &Path, force: bool) -> Result<()> {
        let bad = |why: &str| refused(path, why);
        if path.is_dir() {
            if !force && !path.join(MARKER).is_file() && !is_empty_dir(path) {
                return Err(OutDirError::NotOurs {
                    path: path.to_path_buf(),
                });
            }
            return probe_writable(path).map_err(|e| bad(&format!("cannot write here: {e}")));
        }
        if fs::symlink_metadata(path).is_ok() {
            return Err(bad("exists and is not a folder"));
        }
        // Created later: the nearest existing ancestor must be a folder we can write in.
        let ancestor = path
            .ancestors()
            .skip(1)
            .find(|a| a.as_os_str().is_empty() || fs::symlink_metadata(a).is_ok())
            .map(|a| {
                if a.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    a
                }
            })
            .unwrap_or(Path::new("."));
        if !ancestor.is_dir() {
            return Err(bad(&format!("{} is not a folder", ancestor.display())));
        }
        probe_writable(ancestor).map_err(|e| bad(&format!("cannot create: {e}")))
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Checks `path` as the output folder of `command` and prepares it: creates it, or reuses an
    /// empty or evigrid folder (removing the files the previous run listed), or with `force` any
    /// folder. The folder must not contain any of `inputs` when it is cleared.
    ///
    /// # Errors
    /// Bad input naming `path`: not a folder, a folder of someone else's files without `force`,
    /// cannot be created or written.
    pub fn prepare(path: &Path, force: bool, command: &str) -> Result<Self> {
        let clock = std::time::SystemTime::now();
        let bad = |why: &str| refused(path, why);
        match fs::symlink_metadata(path) {
            Ok(meta) if meta.is_dir() => {
                let marker = path.join(MARKER);
                if marker.is_file() {
                    remove_listed(path, &marker);
                } else if !force && !is_empty_dir(path) {
                    return Err(OutDirError::NotOurs {
                        path: path.to_path_buf(),
                    });
                }
            }
            Ok(meta) if meta.file_type().is_symlink() && path.is_dir() => {
                // A link to a folder: follow it, with the same rules.
                let target = fs::canonicalize(path).map_err(|e| bad(&e.to_string()))?;
                return Self::prepare(&target, force, command).map(|dir| Self {
                    path: path.to_path_buf(),
                    ..dir
                });
            }
            Ok(_) => return Err(bad("exists and is not a folder")),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                fs::create_dir_all(path).map_err(|e| bad(&format!("cannot create: {e}")))?;
            }
            Err(e) => return Err(bad(&e.to_string())),
        }
        // Writable? Find out now, not after the work: write the marker (it says which command
        // owns the folder, and is rewritten with the file list at the end).
        let marker = path.join(MARKER);
        fs::write(&marker, format!("command: {command}\n"))
            .map_err(|e| bad(&format!("cannot write here: {e}")))?;
        // The run's files are those modified since the marker, by the filesystem's own clock:
        // its timestamps are coarser than `SystemTime::now()` (a kernel tick), so a file written
        // right after a `now()` can carry an earlier time and be missed.
        let started = fs::metadata(&marker)
            .and_then(|m| m.modified())
            .map_or(clock, |written| written.min(clock));
        Ok(Self {
            path: path.to_path_buf(),
            command: command.to_string(),
            started,
        })
    }

    /// Records the files this run wrote (modified since [`OutDir::prepare`]) in the marker, so
    /// that the next run into this folder removes exactly them.
    ///
    /// # Errors
    /// The marker cannot be written.
    pub fn finish(&self) -> Result<()> {
        let mut text = format!("command: {}\n", self.command);
        let mut files = Vec::new();
        collect_files_since(&self.path, self.started, &mut files);
        files.sort();
        for file in files {
            if let Ok(relative) = file.strip_prefix(&self.path)
                && relative != Path::new(MARKER)
            {
                text.push_str(&format!("file: {}\n", relative.display()));
            }
        }
        let marker = self.path.join(MARKER);
        crate::write_atomic(&marker, |file| {
            std::io::Write::write_all(file, text.as_bytes())
        })
        .map_err(|e| refused(&marker, e.to_string()))
    }
}

/// Regular files under `dir` (not following links) modified at or after `since`.
fn collect_files_since(dir: &Path, since: std::time::SystemTime, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let Ok(meta) = entry.metadata() else { continue };
        if meta.is_dir() {
            collect_files_since(&entry.path(), since, out);
        } else if meta.is_file() && meta.modified().is_ok_and(|m| m >= since) {
            out.push(entry.path());
        }
    }
}

/// Removes the files listed in an earlier run's marker: only plain relative paths inside the
/// folder, only regular files, and then the folders they leave empty.
fn remove_listed(dir: &Path, marker: &Path) {
    let Ok(text) = fs::read_to_string(marker) else {
        return;
    };
    let mut parents = Vec::new();
    for line in text.lines() {
        let Some(relative) = line.strip_prefix("file: ").map(Path::new) else {
            continue;
        };
        let inside = relative
            .components()
            .all(|c| matches!(c, std::path::Component::Normal(_)));
        if !inside {
            continue;
        }
        let file = dir.join(relative);
        if fs::symlink_metadata(&file).is_ok_and(|m| m.is_file()) {
            let _ = fs::remove_file(&file);
            if let Some(parent) = file.parent().filter(|p| *p != dir) {
                parents.push(parent.to_path_buf());
            }
        }
    }
    parents.sort();
    parents.dedup();
    for parent in parents.iter().rev() {
        // Fails, as it should, when the folder still holds other files.
        let _ = fs::remove_dir(parent);
    }
}

fn is_empty_dir(path: &Path) -> bool {
    fs::read_dir(path).is_ok_and(|mut entries| entries.next().is_none())
}

/// Checks a single output file before any work: not one of `inputs`, not a special file or a
/// folder, and its folder exists. An existing regular file is replaced (the user named it).
///
/// # Errors
/// Bad input naming `path`.
pub fn check_out_file(path: &Path, inputs: &[&Path]) -> Result<()> {
    let bad = |why: &str| refused(path, why);
    if let Ok(meta) = fs::metadata(path) {
        if !meta.is_file() {
            return Err(bad(
                "exists and is not a regular file; evigrid writes new files only",
            ));
        }
        let target = fs::canonicalize(path).ok();
        for input in inputs {
            if target.is_some() && fs::canonicalize(input).ok() == target {
                return Err(bad(&format!(
                    "is the input {}; writing it would destroy it",
                    input.display()
                )));
            }
        }
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        return Err(bad(&format!(
            "the folder {} does not exist",
            parent.display()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

    fn message<T: std::fmt::Debug>(result: super::Result<T>) -> String {
        result.err().map(|e| e.to_string()).unwrap_or_default()
    }

    #[test]
    fn check_changes_nothing_and_agrees_with_prepare() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let out = tmp.path().join("a/b");
        OutDir::check(&out, false)?;
        assert!(!tmp.path().join("a").exists());
        fs::write(tmp.path().join("mine.txt"), "x")?;
        assert!(message(OutDir::check(tmp.path(), false)).contains("not an evigrid output"));
        OutDir::check(tmp.path(), true)?;
        assert!(
            message(OutDir::check(&tmp.path().join("mine.txt/x"), false))
                .contains("is not a folder")
        );
        assert!(
            message(OutDir::check(Path::new("/proc/evigrid-out"), false)).contains("cannot create")
        );
        let entries = fs::read_dir(tmp.path())?.count();
        assert_eq!(entries, 1, "a probe file was left behind");
        Ok(())
    }

    #[test]
    fn a_new_folder_is_created_and_marked() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let out = tmp.path().join("a/b");
        OutDir::prepare(&out, false, "run")?;
        assert!(out.join(MARKER).is_file());
        Ok(())
    }

    #[test]
    fn a_folder_of_user_files_is_refused_unless_forced() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        fs::write(tmp.path().join("thesis.tex"), "precious")?;
        let refused = message(OutDir::prepare(tmp.path(), false, "run"));
        assert!(
            refused.contains("is not an evigrid output folder"),
            "{refused}"
        );
        OutDir::prepare(tmp.path(), true, "run")?;
        assert_eq!(
            fs::read_to_string(tmp.path().join("thesis.tex"))?,
            "precious"
        );
        Ok(())
    }

    #[test]
    fn reuse_removes_only_what_the_last_run_wrote() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let dir = OutDir::prepare(tmp.path(), false, "run")?;
        let at = |name: &str| tmp.path().join(name);
        fs::create_dir(at("frames"))?;
        let written = [at("summary.json"), at("frames/f-000001.png")];
        for file in &written {
            fs::write(file, "old")?;
        }
        dir.finish()?;
        fs::write(at("notes.txt"), "mine, written after the run")?;
        let marker = fs::read_to_string(at(MARKER))?;
        assert_eq!(
            marker,
            "command: run\nfile: frames/f-000001.png\nfile: summary.json\n"
        );
        OutDir::prepare(tmp.path(), false, "run")?;
        assert!(!tmp.path().join("summary.json").exists());
        assert!(!tmp.path().join("frames").exists());
        assert!(tmp.path().join("notes.txt").exists());
        Ok(())
    }

    #[test]
    fn a_marker_cannot_remove_files_outside_the_folder() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let outside = tmp.path().join("outside.txt");
        fs::write(&outside, "keep")?;
        let out = tmp.path().join("out");
        fs::create_dir(&out)?;
        fs::write(
            out.join(MARKER),
            format!("file: ../outside.txt\nfile: {}\n", outside.display()),
        )?;
        OutDir::prepare(&out, false, "run")?;
        assert!(outside.exists());
        Ok(())
    }

    #[test]
    fn a_file_or_device_is_not_an_output_folder() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let file = tmp.path().join("f");
        fs::write(&file, "")?;
        assert!(
            message(OutDir::prepare(&file, true, "run")).ends_with("exists and is not a folder")
        );
        assert!(
            message(OutDir::prepare(Path::new("/dev/null"), true, "run"))
                .ends_with("exists and is not a folder")
        );
        Ok(())
    }

    #[test]
    fn an_output_file_is_never_an_input_or_a_device() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let input = tmp.path().join("map.osm.pbf");
        fs::write(&input, "pbf")?;
        let same = tmp.path().join("./map.osm.pbf");
        assert!(message(check_out_file(&same, &[&input])).contains("is the input"));
        assert!(
            message(check_out_file(Path::new("/dev/full"), &[])).contains("not a regular file")
        );
        assert!(
            message(check_out_file(&tmp.path().join("no/such/x.png"), &[]))
                .contains("does not exist")
        );
        check_out_file(&tmp.path().join("new.png"), &[&input])?;
        Ok(())
    }
}
