//! Locating the shared test data (`../shared` next to the workspace): the one fixture loader of
//! every crate's tests (`belief`, which has no dependencies, repeats the rule).
//!
//! The directory is `$EVIGRID_SHARED` if set (a relative value is taken from the workspace root,
//! as the README says, not from the crate directory cargo runs tests in), else
//! `<workspace>/../shared`. When it is missing, tests skip with a note — unless
//! `EVIGRID_REQUIRE_SHARED=1`, in which case they fail.

use std::path::PathBuf;

/// The shared data directory, or `None` (after printing a note) when it is absent and not
/// required.
///
/// # Panics
/// When the directory is absent and `EVIGRID_REQUIRE_SHARED=1`: that is the test failure the
/// variable asks for.
pub fn shared_dir() -> Option<PathBuf> {
    let workspace = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = match std::env::var_os("EVIGRID_SHARED") {
        Some(dir) => workspace.join(dir),
        None => workspace.join("../shared"),
    };
    if dir.is_dir() {
        return Some(dir);
    }
    let required = std::env::var("EVIGRID_REQUIRE_SHARED").is_ok_and(|v| v == "1");
    assert!(
        !required,
        "shared data required (EVIGRID_REQUIRE_SHARED=1) but {} is missing",
        dir.display()
    );
    eprintln!(
        "note: shared data not found at {}; skipping (set EVIGRID_SHARED)",
        dir.display()
    );
    None
}

/// A file under `<shared>/data/osm/`, or `None` when the shared directory is absent (see
/// [`shared_dir`]).
pub fn osm_file(name: &str) -> Option<PathBuf> {
    shared_dir().map(|dir| dir.join("data/osm").join(name))
}

/// A file or folder under the shared directory (`relative` such as
/// `data/lidar/kitti-city-22/0000000000.pcd`), or `None` when it is absent and not required.
///
/// # Panics
/// When it is absent and `EVIGRID_REQUIRE_SHARED=1`.
pub fn shared_file(relative: &str) -> Option<PathBuf> {
    let path = shared_dir()?.join(relative);
    if path.exists() {
        return Some(path);
    }
    let required = std::env::var("EVIGRID_REQUIRE_SHARED").is_ok_and(|v| v == "1");
    assert!(
        !required,
        "shared data required (EVIGRID_REQUIRE_SHARED=1) but {} is missing",
        path.display()
    );
    eprintln!("note: {} not found; skipping", path.display());
    None
}
