//! Locating the shared test data (`../shared` next to the workspace), for this crate's tests and
//! as the one rule other crates copy.
//!
//! The directory is `$EVIGRID_SHARED` if set, else `<workspace>/../shared` resolved from this
//! crate's manifest directory. When it is missing, tests skip with a note — unless
//! `EVIGRID_REQUIRE_SHARED=1`, in which case they fail.

use std::path::PathBuf;

/// The shared data directory, or `None` (after printing a note) when it is absent and not
/// required.
///
/// # Panics
/// When the directory is absent and `EVIGRID_REQUIRE_SHARED=1`: that is the test failure the
/// variable asks for.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("EVIGRID_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared"));
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
