//! A rosbag2 folder given where a recording is expected: `ros2 bag record` writes a folder
//! holding `metadata.yaml` and the recording's files, and that folder is what people pass.
//!
//! The folder is read as its one MCAP file: the file `metadata.yaml` lists under
//! `relative_file_paths`, else the folder's only `.mcap`. A recording split into several files,
//! or stored as SQLite (`.db3`), is refused with what to do about it.

use std::fs;
use std::path::{Path, PathBuf};

use super::BagError;

/// `path` itself when it is not a folder; for a rosbag2 folder, the path of its MCAP file.
///
/// # Errors
///
/// [`BagError::Folder`] for a folder without exactly one MCAP file, [`BagError::Io`] when the
/// folder cannot be listed.
pub fn recording_file(path: &Path) -> Result<PathBuf, BagError> {
    if !path.is_dir() {
        return Ok(path.to_path_buf());
    }
    let refuse = |message: String| BagError::Folder {
        path: path.to_path_buf(),
        message,
    };
    let listed = fs::read_to_string(path.join("metadata.yaml"))
        .map(|text| listed_files(&text))
        .unwrap_or_default();
    let mut files = if listed.is_empty() {
        let entries = fs::read_dir(path).map_err(|source| BagError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut names: Vec<String> = entries
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    } else {
        listed
    };
    let db3 = files.iter().any(|f| f.ends_with(".db3"));
    files.retain(|f| f.ends_with(".mcap"));
    match files.as_slice() {
        [one] => Ok(path.join(one)),
        [] if db3 => Err(refuse(
            "a rosbag2 folder in SQLite storage (.db3); evigrid reads MCAP: convert it with \
             `ros2 bag convert` (storage_id: mcap) or record with `--storage mcap`"
                .to_owned(),
        )),
        [] => Err(refuse(
            "a folder without metadata.yaml or a .mcap file; pass a rosbag2 folder or an .mcap \
             file"
                .to_owned(),
        )),
        many => Err(refuse(format!(
            "a rosbag2 recording split into {} files ({}); evigrid reads one: merge them with \
             `mcap merge` or pass one file",
            many.len(),
            many.join(", ")
        ))),
    }
}

/// The file names `metadata.yaml` lists under `relative_file_paths` (block list, one `- name`
/// a line, as rosbag2 writes it).
fn listed_files(metadata: &str) -> Vec<String> {
    let mut files = Vec::new();
    let mut inside = false;
    for line in metadata.lines() {
        let text = line.trim();
        if text.starts_with("relative_file_paths:") {
            inside = true;
            continue;
        }
        if inside {
            match text.strip_prefix("- ") {
                Some(name) => files.push(name.trim().trim_matches(['"', '\'']).to_owned()),
                None if text.is_empty() => {}
                None => break,
            }
        }
    }
    files
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn a_rosbag2_folder_is_read_as_its_mcap_file() {
        let dir = tempfile::tempdir().unwrap();
        let bag = dir.path().join("drive_0");
        fs::create_dir(&bag).unwrap();
        // As ros2 bag record writes it: the file listed in metadata.yaml.
        fs::write(
            bag.join("metadata.yaml"),
            "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  \
             relative_file_paths:\n    - drive_0_0.mcap\n  duration:\n    nanoseconds: 5\n",
        )
        .unwrap();
        fs::write(bag.join("drive_0_0.mcap"), b"").unwrap();
        fs::write(bag.join("notes.mcap"), b"").unwrap();
        assert_eq!(recording_file(&bag).unwrap(), bag.join("drive_0_0.mcap"));
        // A file is itself.
        let file = bag.join("notes.mcap");
        assert_eq!(recording_file(&file).unwrap(), file);
        // Without metadata.yaml, the only .mcap.
        fs::remove_file(bag.join("metadata.yaml")).unwrap();
        fs::remove_file(bag.join("notes.mcap")).unwrap();
        assert_eq!(recording_file(&bag).unwrap(), bag.join("drive_0_0.mcap"));
    }

    #[test]
    fn split_sqlite_and_empty_folders_say_what_to_do() {
        let dir = tempfile::tempdir().unwrap();
        let bag = dir.path();
        fs::write(
            bag.join("metadata.yaml"),
            "  relative_file_paths:\n    - a_0.mcap\n    - a_1.mcap\n  starting_time: 1\n",
        )
        .unwrap();
        let split = recording_file(bag).unwrap_err().to_string();
        assert!(
            split.contains("split into 2 files (a_0.mcap, a_1.mcap)"),
            "{split}"
        );
        assert!(split.contains("mcap merge"), "{split}");
        fs::write(
            bag.join("metadata.yaml"),
            "relative_file_paths:\n- 'a_0.db3'\n",
        )
        .unwrap();
        let sqlite = recording_file(bag).unwrap_err().to_string();
        assert!(
            sqlite.contains("SQLite") && sqlite.contains("ros2 bag convert"),
            "{sqlite}"
        );
        fs::remove_file(bag.join("metadata.yaml")).unwrap();
        let empty = recording_file(bag).unwrap_err().to_string();
        assert!(
            empty.contains("without metadata.yaml or a .mcap file"),
            "{empty}"
        );
        assert!(!empty.contains('\n'));
    }
}
