//! The error type of fogline-import.

use std::path::PathBuf;

/// Why an import could not be done. Every variant names where the problem is: the file (and,
/// inside a zip, the member), the row and the column where there is one, and what was
/// expected.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// An import parameter outside its valid range.
    #[error("invalid import parameter {parameter} = {value}: expected {expected}")]
    InvalidParameter {
        /// The parameter.
        parameter: String,
        /// The value given.
        value: String,
        /// What is valid.
        expected: String,
    },
    /// A file or directory that cannot be read or written.
    #[error("cannot access {}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The failure.
        #[source]
        source: std::io::Error,
    },
    /// A file, or a member of a zip, that is missing or not what the layout says.
    #[error("{location}: {detail}")]
    Data {
        /// The file, or `archive.zip: member`.
        location: String,
        /// What was wrong and what was expected.
        detail: String,
    },
    /// A cell of a table (Parquet or CSV) that is missing, null or out of range.
    #[error("{location}: row {row}, column `{column}`: {detail}")]
    Cell {
        /// The file, or `archive.zip: member`.
        location: String,
        /// The data row, from 1.
        row: u64,
        /// The column.
        column: String,
        /// What was found and what was expected.
        detail: String,
    },
    /// ffmpeg could not be found or run.
    #[error("ffmpeg: {detail}")]
    Ffmpeg {
        /// What failed and how to fix it.
        detail: String,
    },
    /// A clip whose data do not cover what the import needs (times, cameras).
    #[error("clip {clip_id}: {detail}")]
    Clip {
        /// The dataset's clip id.
        clip_id: String,
        /// What was missing.
        detail: String,
    },
    /// An imported clip that could not be written in the clip format.
    #[error("cannot write clip {clip_id}")]
    Write {
        /// The clip id.
        clip_id: String,
        /// The failure.
        #[source]
        source: fogline_world::WorldError,
    },
}

impl ImportError {
    /// An [`ImportError::InvalidParameter`].
    pub fn invalid(
        parameter: impl Into<String>,
        value: impl std::fmt::Display,
        expected: impl Into<String>,
    ) -> Self {
        Self::InvalidParameter {
            parameter: parameter.into(),
            value: value.to_string(),
            expected: expected.into(),
        }
    }

    /// An [`ImportError::Data`].
    pub fn data(location: impl Into<String>, detail: impl Into<String>) -> Self {
        Self::Data {
            location: location.into(),
            detail: detail.into(),
        }
    }

    /// An [`ImportError::Cell`].
    pub fn cell(
        location: impl Into<String>,
        row: u64,
        column: impl Into<String>,
        detail: impl Into<String>,
    ) -> Self {
        Self::Cell {
            location: location.into(),
            row,
            column: column.into(),
            detail: detail.into(),
        }
    }

    /// An [`ImportError::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }

    /// An [`ImportError::Clip`].
    pub fn clip(clip_id: impl Into<String>, detail: impl Into<String>) -> Self {
        Self::Clip {
            clip_id: clip_id.into(),
            detail: detail.into(),
        }
    }
}

/// The result type of fogline-import.
pub type Result<T, E = ImportError> = std::result::Result<T, E>;
