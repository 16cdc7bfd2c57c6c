//! The material-nn library's error type. Every variant names the file (or setting) and the
//! problem, so the binary can report it as one line.

use std::path::PathBuf;

/// Errors of the material-nn library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file-level error (I/O, invalid contents) in the renderer's error type, which names
    /// its file: MERL tables, latent files and material-nn's own files alike.
    #[error(transparent)]
    Renderer(#[from] renderer::Error),
    /// A configuration value, argument or data set is unusable for the named reason.
    #[error("{0}")]
    Invalid(String),
}

impl Error {
    /// A file whose contents are invalid for the named reason.
    pub fn invalid_file(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        Error::Renderer(renderer::Error::invalid_file(path, reason))
    }

    /// A file that could not be opened, read or written.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Renderer(renderer::Error::io(path, source))
    }
}

/// Result alias of the material-nn library.
pub type Result<T, E = Error> = std::result::Result<T, E>;
