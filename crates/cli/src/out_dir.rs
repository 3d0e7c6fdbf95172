//! The command line's side of the one output policy (`output::out_dir`, which `evigrid.run` in
//! Python follows too): its refusals as bad input (exit 2), in the words of the flags.

use std::fs;
use std::path::{Path, PathBuf};

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

/// Creates and removes a probe file in `dir`: the only sure test that a folder is writable.
fn probe_writable(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(format!(".evigrid-probe-{}", std::process::id()));
    fs::write(&probe, b"")?;
    fs::remove_file(&probe)
}

/// Checks a single output file before any work; the same rule holds for the side files a
/// command writes beside it (`odometry`'s `.times.txt`):
///
/// - never one of `inputs`, also through a symbolic or a hard link (compared by device and
///   inode; a folder input stands for every file in it, and a KITTI raw drive's `calib_*.txt`
///   beside it), whatever `force` says;
/// - never a special file or a folder;
/// - an existing file is replaced only with `force` (the replacement is an atomic rename, so a
///   symbolic link is replaced, never the file it points to);
/// - its folder exists and can be written in.
///
/// # Errors
/// Bad input naming `path`.
pub fn check_out_file(path: &Path, inputs: &[&Path], force: bool) -> Result<()> {
    check_file("--out ", path, inputs, force)
}

/// [`check_out_file`] for a side file written beside the `--out` file.
///
/// # Errors
/// Bad input naming `path`.
pub fn check_side_file(path: &Path, inputs: &[&Path], force: bool) -> Result<()> {
    check_file("", path, inputs, force)
}

fn check_file(label: &str, path: &Path, inputs: &[&Path], force: bool) -> Result<()> {
    let bad = |why: &str| BadInput::new(format!("{label}{}: {why}", path.display()));
    if let Ok(link) = fs::symlink_metadata(path) {
        match fs::metadata(path) {
            Ok(meta) if !meta.is_file() => {
                return Err(bad(
                    "exists and is not a regular file; evigrid writes regular files only",
                ));
            }
            Ok(meta) => {
                if let Some(input) = input_with_identity(inputs, identity(&meta)) {
                    return Err(bad(&format!(
                        "is the input {}; writing it would destroy it",
                        input.display()
                    )));
                }
            }
            // A link to nothing: replacing the link loses nothing but the link.
            Err(_) => {}
        }
        if !force {
            let what = if link.file_type().is_symlink() {
                "is an existing link"
            } else {
                "exists"
            };
            return Err(bad(&format!(
                "{what}; evigrid replaces a file only with --force (and never an input)"
            )));
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
    probe_writable(parent).map_err(|e| bad(&format!("cannot write here: {e}")))
}

/// A file's identity: device and inode, the same through any link.
fn identity(meta: &fs::Metadata) -> (u64, u64) {
    use std::os::unix::fs::MetadataExt;
    (meta.dev(), meta.ino())
}

/// Folders deeper than this under a folder input are not searched for the output file.
const INPUT_DEPTH: usize = 4;

/// Entries visited at most under the folder inputs.
const INPUT_ENTRIES: usize = 200_000;

/// The input (or the file of a folder input) whose identity is `target`.
fn input_with_identity(inputs: &[&Path], target: (u64, u64)) -> Option<PathBuf> {
    let mut budget = INPUT_ENTRIES;
    for input in inputs {
        let Ok(meta) = fs::metadata(input) else {
            continue;
        };
        if identity(&meta) == target {
            return Some(input.to_path_buf());
        }
        if meta.is_dir() {
            if let Some(found) = file_with_identity(input, target, 0, &mut budget) {
                return Some(found);
            }
            // A KITTI raw drive folder reads its calibration from the folder above it.
            let calib = input.parent().and_then(|date| fs::read_dir(date).ok());
            for entry in calib.into_iter().flatten().flatten() {
                let name = entry.file_name();
                let name = name.to_string_lossy();
                if name.starts_with("calib_")
                    && name.ends_with(".txt")
                    && fs::metadata(entry.path()).is_ok_and(|m| identity(&m) == target)
                {
                    return Some(entry.path());
                }
            }
        }
    }
    None
}

/// The file under `dir` (links to files followed, links to folders not) whose identity is
/// `target`.
fn file_with_identity(
    dir: &Path,
    target: (u64, u64),
    depth: usize,
    budget: &mut usize,
) -> Option<PathBuf> {
    for entry in fs::read_dir(dir).ok()?.flatten() {
        if *budget == 0 {
            return None;
        }
        *budget -= 1;
        let path = entry.path();
        let Ok(kind) = entry.file_type() else {
            continue;
        };
        if kind.is_dir() {
            if depth < INPUT_DEPTH
                && let Some(found) = file_with_identity(&path, target, depth + 1, budget)
            {
                return Some(found);
            }
        } else if fs::metadata(&path).is_ok_and(|m| identity(&m) == target) {
            return Some(path);
        }
    }
    None
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

    fn message(result: Result<impl std::fmt::Debug>) -> String {
        result.err().map(|e| e.to_string()).unwrap_or_default()
    }

    #[test]
    fn an_output_file_is_never_an_input_or_a_device() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let input = tmp.path().join("map.osm.pbf");
        fs::write(&input, "pbf")?;
        let same = tmp.path().join("./map.osm.pbf");
        assert!(message(check_out_file(&same, &[&input], true)).contains("is the input"));
        assert!(
            message(check_out_file(Path::new("/dev/full"), &[], true))
                .contains("not a regular file")
        );
        assert!(
            message(check_out_file(
                &tmp.path().join("no/such/x.png"),
                &[],
                false
            ))
            .contains("does not exist")
        );
        check_out_file(&tmp.path().join("new.png"), &[&input], false)?;
        Ok(())
    }

    #[test]
    fn an_input_is_never_replaced_through_a_link_or_inside_a_folder_even_with_force() -> Result<()>
    {
        let tmp = tempfile::tempdir()?;
        let date = tmp.path().join("2011_09_26");
        let drive = date.join("drive_0001_sync");
        fs::create_dir_all(drive.join("velodyne_points/data"))?;
        let scan = drive.join("velodyne_points/data/0000000000.bin");
        let calib = date.join("calib_imu_to_velo.txt");
        fs::write(&scan, "scan")?;
        fs::write(&calib, "calib")?;
        let link = tmp.path().join("link.bin");
        std::os::unix::fs::symlink(&scan, &link)?;
        let hard = tmp.path().join("hard.txt");
        fs::hard_link(&calib, &hard)?;
        for (out, input) in [
            (&scan, &scan),
            (&link, &scan),
            (&hard, &calib),
            (&calib, &calib),
        ] {
            let refused = message(check_out_file(out, &[&drive], true));
            assert!(
                refused.contains(&format!("is the input {}", input.display())),
                "{refused}"
            );
        }
        assert_eq!(fs::read_to_string(&scan)?, "scan");
        Ok(())
    }

    #[test]
    fn an_existing_user_file_is_replaced_only_with_force() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let notes = tmp.path().join("notes.txt");
        fs::write(&notes, "mine")?;
        let refused = message(check_out_file(&notes, &[], false));
        assert!(refused.contains("exists; evigrid replaces a file only with --force"));
        check_out_file(&notes, &[], true)?;
        let side = message(check_side_file(&notes, &[], false));
        assert!(
            side.starts_with(&format!("{}: exists", notes.display())),
            "{side}"
        );
        Ok(())
    }

    #[test]
    fn an_unwritable_folder_is_bad_input() {
        let refused = message(check_out_file(Path::new("/proc/poses.txt"), &[], false));
        assert!(refused.contains("cannot write here"), "{refused}");
    }
}
