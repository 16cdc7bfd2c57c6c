//! The renderer library's error type. Every variant names the file (or flag) and the problem,
//! so a binary can report it as one line.

use std::path::PathBuf;

/// Errors of the renderer library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be opened, read or written. The I/O error is part of the message
    /// (not a `source`, so a report of the error chain names it once).
    #[error("{}: {error}", path.display())]
    Io { path: PathBuf, error: std::io::Error },
    /// A file was read but its contents are invalid for the named reason.
    #[error("{}: {reason}", path.display())]
    InvalidFile { path: PathBuf, reason: String },
    /// A name given by the user (camera, material, binding) does not exist.
    #[error("{what} '{name}' not found{}", if available.is_empty() { String::new() } else { format!(" (available: {})", available.join(", ")) })]
    UnknownName {
        what: &'static str,
        name: String,
        available: Vec<String>,
    },
    /// A command-line option or configuration value is out of range or malformed.
    #[error("invalid value for {flag}: {reason}")]
    InvalidArgument { flag: String, reason: String },
    /// The running CPU lacks instruction-set features this build was compiled for (see
    /// [`crate::support::cpu::missing_build_features`]).
    #[error("this CPU lacks {}, which this build was compiled for; rebuild for it with RUSTFLAGS=\"-C target-cpu=native\" set (cargo build --release, or pip install of the Python package)", missing.join(", "))]
    UnsupportedCpu { missing: Vec<&'static str> },
}

impl Error {
    /// Shorthand for [`Error::InvalidFile`].
    pub fn invalid_file(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        Error::InvalidFile {
            path: path.into(),
            reason: reason.into(),
        }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, error: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            error,
        }
    }
}

/// Result alias of the renderer library.
pub type Result<T, E = Error> = std::result::Result<T, E>;
