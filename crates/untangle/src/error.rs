//! Typed errors for bad input. Every message names *where* (file and line, or element index) and
//! *what* is wrong, in one line, so the CLI can print it as is.

use std::path::PathBuf;

/// Errors the library reports for user data. It never panics on bad input.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The input is malformed or violates a requirement; `place` is e.g. `shirt.obj:12`.
    #[error("{place}: {message}")]
    Input {
        /// Where: `file:line`, or a description such as `mesh 'shirt', triangle 7`.
        place: String,
        /// What is wrong.
        message: String,
    },
    /// A parameter given by the caller is out of its valid range.
    #[error("invalid parameter: {0}")]
    Parameter(String),
}

impl Error {
    /// Shorthand for [`Error::Input`].
    pub fn input(place: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Input {
            place: place.into(),
            message: message.into(),
        }
    }
}

/// Result alias of the library.
pub type Result<T> = std::result::Result<T, Error>;
