//! The error type of fogline-envelope.

use std::path::PathBuf;

use fogline_stats::StatsError;

/// Why a pairs table could not be read or analysed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EnvelopeError {
    /// The file could not be opened or read.
    #[error("cannot read {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file's extension names no supported format.
    #[error("{path}: unsupported extension; expected .csv, .parquet, .jsonl or .ndjson")]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The file's content is not what its extension says.
    #[error("{path}: not a valid {expected} file: {detail}")]
    NotFormat {
        /// The file.
        path: PathBuf,
        /// The format its extension promised.
        expected: &'static str,
        /// What was wrong.
        detail: String,
    },
    /// A required column is absent.
    #[error("{path}: missing column `{column}`{}; columns found: {}", suggestion_text(.suggestion), .found.join(", "))]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The required column.
        column: String,
        /// The columns the file has.
        found: Vec<String>,
        /// A close match among `found`, if any.
        suggestion: Option<String>,
    },
    /// A cell holds a value the analysis cannot use.
    #[error("{path}: row {row}, column `{column}`: got {value:?}, expected {expected}")]
    BadValue {
        /// The file.
        path: PathBuf,
        /// The row (line number for CSV and JSONL, 1-based data row for Parquet).
        row: u64,
        /// The column.
        column: String,
        /// The value as found.
        value: String,
        /// What was expected.
        expected: String,
    },
    /// The same (clip, condition) appears twice.
    #[error(
        "{path}: row {row} repeats clip {clip_id:?} under condition {condition:?} (first at row {first_row})"
    )]
    DuplicatePair {
        /// The file.
        path: PathBuf,
        /// The repeating row.
        row: u64,
        /// The earlier row.
        first_row: u64,
        /// The clip.
        clip_id: String,
        /// The condition.
        condition: String,
    },
    /// A clip carries two scenario labels.
    #[error(
        "{path}: row {row}: clip {clip_id:?} has scenario {second:?} but earlier rows say {first:?}"
    )]
    ScenarioConflict {
        /// The file.
        path: PathBuf,
        /// The conflicting row.
        row: u64,
        /// The clip.
        clip_id: String,
        /// The label seen first.
        first: String,
        /// The conflicting label.
        second: String,
    },
    /// Some clips lack some conditions.
    #[error(
        "{path}: {n_incomplete} of {n_clips} clips lack some conditions (e.g. {examples}); \
         every clip must be tested under every condition, or pass --allow-incomplete"
    )]
    IncompleteClips {
        /// The file.
        path: PathBuf,
        /// Clips lacking a condition.
        n_incomplete: usize,
        /// All clips.
        n_clips: usize,
        /// A few examples, `clip: missing a, b`.
        examples: String,
    },
    /// The file holds no data rows.
    #[error("{path}: no data rows")]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// An analysis parameter is out of range.
    #[error("parameter {name}: {reason}")]
    InvalidParam {
        /// The parameter.
        name: &'static str,
        /// What was expected.
        reason: String,
    },
    /// The action-rules file is invalid.
    #[error("{path}: {detail}")]
    ActionRules {
        /// The rules file.
        path: PathBuf,
        /// What was wrong.
        detail: String,
    },
    /// A statistic failed where the analysis cannot go on without it.
    #[error("{what}")]
    Stats {
        /// What was being computed.
        what: String,
        /// The cause.
        #[source]
        source: StatsError,
    },
}

fn suggestion_text(s: &Option<String>) -> String {
    match s {
        Some(s) => format!(" (did you mean `{s}`?)"),
        None => String::new(),
    }
}

/// Result alias of this crate.
pub type Result<T, E = EnvelopeError> = std::result::Result<T, E>;
