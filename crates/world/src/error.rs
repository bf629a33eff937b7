//! The error type of fogline-world.

use std::path::PathBuf;

/// Why a clip could not be generated, read or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WorldError {
    /// A world or scene parameter outside its valid range.
    #[error("invalid world parameter {parameter} = {value}: expected {expected}")]
    InvalidParameter {
        /// The parameter.
        parameter: String,
        /// The value given.
        value: String,
        /// What is valid.
        expected: String,
    },
    /// A file of a clip directory that is missing, unreadable or malformed.
    #[error("{}: {reason}", path.display())]
    ClipFile {
        /// The file.
        path: PathBuf,
        /// What was wrong and what was expected.
        reason: String,
    },
    /// A clip that cannot be written because it breaks the clip format's rules (see
    /// [`crate::format::validate_clip`]).
    #[error("invalid clip {clip:?}: {reason}")]
    InvalidClip {
        /// The clip id.
        clip: String,
        /// What was wrong.
        reason: String,
    },
    /// An I/O failure on a path.
    #[error("{}: {source}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The failure.
        source: std::io::Error,
    },
}

impl WorldError {
    /// An [`WorldError::InvalidParameter`].
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

    /// A [`WorldError::ClipFile`].
    pub fn file(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        Self::ClipFile {
            path: path.into(),
            reason: reason.into(),
        }
    }
}
