//! One output policy for every writer of an output folder (the command line's commands, the
//! Python package's `evigrid.run`), checked before any work.
//!
//! - An output folder is created if missing. An existing folder is reused only if it is empty or
//!   holds evigrid's marker file (written by an earlier run); any other folder is refused unless
//!   forced, so a typo never mixes results into, or overwrites, a user's own files.
//! - Reusing an evigrid folder first removes what the previous run listed in its marker, so an old
//!   `summary.json` never sits beside new frames.
//! - An output folder never is, nor holds, one of the command's inputs ([`OutDir::check_inputs`]):
//!   its files are cleared and written, so a recording replayed from its own folder would be
//!   destroyed while it is read.
//! - An output file ([`check_out_file`], and the side files written beside it) is never one of
//!   the command's inputs, also through a symbolic or a hard link; never a special file
//!   (`/dev/full`, a FIFO: the atomic rename would replace the device node itself); and an
//!   existing file is replaced only when forced.
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
    /// An output that is one of the inputs (or a file of a folder input), through any link;
    /// refused whether forced or not.
    #[error("{}: is the input {}; writing it would destroy it", path.display(), input.display())]
    IsInput {
        /// The output.
        path: PathBuf,
        /// The input it is.
        input: PathBuf,
    },
    /// An output folder holding one of the inputs; refused whether forced or not.
    #[error(
        "{}: holds the input {}; an output folder is cleared and written, choose another",
        path.display(),
        input.display()
    )]
    HoldsInput {
        /// The folder.
        path: PathBuf,
        /// The input inside it.
        input: PathBuf,
    },
    /// An existing output file (or a symbolic link), not forced: the caller names its remedy.
    #[error("{}: {}", path.display(), if *link { "is an existing link" } else { "exists" })]
    Exists {
        /// The file.
        path: PathBuf,
        /// True when `path` is a symbolic link.
        link: bool,
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

    /// Checks that the output folder `path` is none of `inputs` and holds none of them (each
    /// input and the folder compared by their real paths, links resolved), whatever `force`
    /// says: [`OutDir::prepare`] clears the last run's files and the run writes new ones, so an
    /// input inside (a recording replayed from its own folder, a pose file beside the outputs)
    /// could be replaced or removed while it is read. A folder that does not exist yet holds
    /// nothing.
    ///
    /// # Errors
    /// [`OutDirError::IsInput`] when `path` is an input, [`OutDirError::HoldsInput`] when it
    /// holds one, each naming the folder and the input.
    pub fn check_inputs(path: &Path, inputs: &[&Path]) -> Result<()> {
        let Ok(folder) = fs::canonicalize(path) else {
            return Ok(());
        };
        for input in inputs {
            let Ok(real) = fs::canonicalize(input) else {
                continue;
            };
            let (path, input) = (path.to_path_buf(), input.to_path_buf());
            if real == folder {
                return Err(OutDirError::IsInput { path, input });
            }
            if real.starts_with(&folder) {
                return Err(OutDirError::HoldsInput { path, input });
            }
        }
        Ok(())
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
/// [`OutDirError::IsInput`], [`OutDirError::Exists`] (not forced), or
/// [`OutDirError::Refused`] for a special file or a folder that is missing or not writable.
pub fn check_out_file(path: &Path, inputs: &[&Path], force: bool) -> Result<()> {
    let bad = |why: &str| refused(path, why);
    if let Ok(link) = fs::symlink_metadata(path) {
        match fs::metadata(path) {
            Ok(meta) if !meta.is_file() => {
                return Err(bad(
                    "exists and is not a regular file; evigrid writes regular files only",
                ));
            }
            Ok(meta) => {
                if let Some(input) = input_with_identity(inputs, identity(&meta)) {
                    return Err(OutDirError::IsInput {
                        path: path.to_path_buf(),
                        input,
                    });
                }
            }
            // A link to nothing: replacing the link loses nothing but the link.
            Err(_) => {}
        }
        if !force {
            return Err(OutDirError::Exists {
                path: path.to_path_buf(),
                link: link.file_type().is_symlink(),
            });
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
        assert_eq!(
            message(check_out_file(&same, &[&input], true)),
            format!(
                "{}: is the input {}; writing it would destroy it",
                same.display(),
                input.display()
            )
        );
        assert_eq!(
            message(check_out_file(Path::new("/dev/full"), &[], true)),
            "/dev/full: exists and is not a regular file; evigrid writes regular files only"
        );
        let missing = tmp.path().join("no/such/x.png");
        assert!(
            message(check_out_file(&missing, &[], false)).ends_with(&format!(
                "the folder {} does not exist",
                tmp.path().join("no/such").display()
            ))
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
            match check_out_file(out, &[&drive], true) {
                Err(OutDirError::IsInput { input: found, .. }) => assert_eq!(&found, input),
                other => panic!("{out:?}: {other:?}"),
            }
        }
        assert_eq!(fs::read_to_string(&scan)?, "scan");
        Ok(())
    }

    #[test]
    fn an_existing_user_file_is_replaced_only_when_forced() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let notes = tmp.path().join("notes.txt");
        fs::write(&notes, "mine")?;
        assert_eq!(
            message(check_out_file(&notes, &[], false)),
            format!("{}: exists", notes.display())
        );
        check_out_file(&notes, &[], true)?;
        let link = tmp.path().join("link.txt");
        std::os::unix::fs::symlink(&notes, &link)?;
        assert!(matches!(
            check_out_file(&link, &[], false),
            Err(OutDirError::Exists { link: true, .. })
        ));
        // A link to nothing is replaced when forced: only the link is lost.
        let dangling = tmp.path().join("dangling.txt");
        std::os::unix::fs::symlink(tmp.path().join("gone"), &dangling)?;
        check_out_file(&dangling, &[], true)?;
        Ok(())
    }

    #[test]
    fn an_unwritable_folder_is_refused_before_the_work() {
        let refused = message(check_out_file(Path::new("/proc/poses.txt"), &[], false));
        assert!(refused.contains("cannot write here"), "{refused}");
    }

    #[test]
    fn an_output_folder_never_holds_an_input() -> Result<()> {
        let tmp = tempfile::tempdir()?;
        let out = tmp.path().join("out");
        fs::create_dir(&out)?;
        let bag = out.join("run.mcap");
        fs::write(&bag, "a recording of an earlier run")?;
        let refused = message(OutDir::check_inputs(&out, &[&bag]));
        assert_eq!(
            refused,
            format!(
                "{}: holds the input {}; an output folder is cleared and written, choose another",
                out.display(),
                bag.display()
            )
        );
        // The folder itself as the input, and through a link to it.
        let link = tmp.path().join("link");
        std::os::unix::fs::symlink(&out, &link)?;
        assert!(matches!(
            OutDir::check_inputs(&link, &[&out]),
            Err(OutDirError::IsInput { .. })
        ));
        // Beside it, or above it (a drive folder holding the output folder), is fine.
        let poses = tmp.path().join("poses.txt");
        fs::write(&poses, "0 0 0 0 0 0 0 1")?;
        OutDir::check_inputs(&out, &[&poses, tmp.path()])?;
        // A folder not yet created holds nothing.
        OutDir::check_inputs(&tmp.path().join("new"), &[&bag])?;
        Ok(())
    }
}
