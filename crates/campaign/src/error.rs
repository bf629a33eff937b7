//! The campaign's errors: each names the file, field or store and what was expected.

use std::path::PathBuf;

/// What can go wrong in a campaign (not a failed run: those are recorded in the store).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CampaignError {
    /// An invalid configuration.
    #[error("{file}: {reason}")]
    Config {
        /// The configuration file.
        file: String,
        /// The field and what was expected.
        reason: String,
    },
    /// A store that cannot be used as asked.
    #[error("{}: {reason}", path.display())]
    Store {
        /// The store file.
        path: PathBuf,
        /// What is wrong and what to do.
        reason: String,
    },
    /// An SQLite failure on a store.
    #[error("{}: {source}", path.display())]
    Sqlite {
        /// The store file.
        path: PathBuf,
        /// The failure.
        source: rusqlite::Error,
    },
    /// The clips could not be listed or generated.
    #[error("clips: {0}")]
    Clips(#[from] fogline_world::WorldError),
    /// The planner could not be set up.
    #[error("planner: {0}")]
    Planner(String),
    /// An I/O failure on a path.
    #[error("{}: {source}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The failure.
        source: std::io::Error,
    },
    /// An export that could not be written.
    #[error("{}: {reason}", path.display())]
    Export {
        /// The output file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
}
