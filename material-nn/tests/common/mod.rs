//! Helpers shared by the material-nn command-line tests.

use std::path::Path;
use std::process::Output;

/// A temporary path as a command-line argument.
pub fn path_str(p: &Path) -> &str {
    p.to_str().expect("UTF-8 temporary path")
}

/// The one-line error of a failed run (exit code 2).
pub fn error_line(out: &Output) -> String {
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr).trim().to_string();
    assert!(stderr.starts_with("error: ") && !stderr.contains('\n'), "{stderr}");
    stderr
}
