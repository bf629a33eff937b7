//! The error type of fogline-dataset.

use std::path::{Path, PathBuf};

/// Why a data set could not be built, read or evaluated.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DatasetError {
    /// A setting is invalid.
    #[error("invalid parameters: {0}")]
    Params(String),
    /// A file or directory could not be read or written.
    #[error("cannot access {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A file's content is invalid.
    #[error("{}{}: {reason}", path.display(), if *line > 0 { format!(" line {line}") } else { String::new() })]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The line, from 1 (0: the whole file).
        line: usize,
        /// What is wrong (the field and what was expected).
        reason: String,
    },
    /// A sample could not be made.
    #[error("sample {index}: {reason}")]
    Sample {
        /// Its index.
        index: u64,
        /// Why.
        reason: String,
    },
    /// The backend could not be set up.
    #[error("backend: {0}")]
    Backend(String),
}

impl DatasetError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn invalid(path: &Path, line: usize, reason: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.to_path_buf(),
            line,
            reason: reason.into(),
        }
    }
}
