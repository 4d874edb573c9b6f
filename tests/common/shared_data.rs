//! The shared real logs (`../shared/data` beside the checkout): found, or
//! skipped with a note on a user's machine, or a failure in CI.

use std::path::PathBuf;

/// Overrides the directory of the shared data (default: `../shared/data`
/// beside the crate's manifest).
pub const DIR_VAR: &str = "DELAYNAV_SHARED_DATA";

/// The shared data directory: `$DELAYNAV_SHARED_DATA`, else
/// `../shared/data` beside the crate.
pub fn dir() -> PathBuf {
    std::env::var_os(DIR_VAR).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
        PathBuf::from,
    )
}

/// `relative` under [`dir`], or `None` with a note when it is absent. When
/// the environment has `CI=true` its absence panics: CI must not report a
/// real-log test as passed that did not run.
pub fn shared(relative: &str) -> Option<PathBuf> {
    let path = dir().join(relative);
    if path.exists() {
        return Some(path);
    }
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!(
            "CI=true but {} is missing: the real-log tests cannot run",
            path.display()
        );
    }
    println!(
        "skipped: {} not found (the shared real logs; {DIR_VAR} sets their directory)",
        path.display()
    );
    None
}
