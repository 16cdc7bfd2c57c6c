//! The material-nn library's error type. Every variant names the file (or setting) and the
//! problem, so the binary can report it as one line.

use std::path::PathBuf;

/// Errors of the material-nn library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An error of the renderer library (MERL tables, latent files), which names its file.
    #[error(transparent)]
    Renderer(#[from] renderer::Error),
    /// A file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file was read but its contents are invalid for the named reason.
    #[error("{}: {reason}", path.display())]
    InvalidFile { path: PathBuf, reason: String },
    /// A configuration value, argument or data set is unusable for the named reason.
    #[error("{0}")]
    Invalid(String),
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
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result alias of the material-nn library.
pub type Result<T, E = Error> = std::result::Result<T, E>;
