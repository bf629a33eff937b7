//! The report's error type.

/// What can go wrong while building a report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// `envelope.json` does not read into the envelope model
    /// ([`fogline_envelope::Envelope::from_json`]: the message names the file and the field).
    #[error(transparent)]
    Envelope(#[from] fogline_envelope::EnvelopeError),
    /// A closed-loop summary does not parse as its documented schema.
    #[error("{what}: does not match its schema at `{path}`")]
    Schema {
        /// Which document.
        what: String,
        /// The JSON path of the offending value.
        path: String,
        /// The parser's error.
        #[source]
        source: serde_json::Error,
    },
    /// An in-memory envelope has a schema version this report does not read (a file with
    /// another version is refused by [`fogline_envelope::Envelope::from_json`]).
    #[error(
        "envelope schema version {found} is not supported (this report reads version {expected})"
    )]
    SchemaVersion {
        /// Version in the file.
        found: u32,
        /// Version understood here.
        expected: u32,
    },
    /// The pairs table given for the histogram is not the one the envelope was computed from.
    #[error(
        "the pairs table {pairs} (sha256 {pairs_sha256}) is not the envelope's input (sha256 {envelope_sha256})"
    )]
    PairsMismatch {
        /// The pairs table's path.
        pairs: String,
        /// Its checksum.
        pairs_sha256: String,
        /// The checksum recorded in the envelope.
        envelope_sha256: String,
    },
    /// A value of the input is outside what the schema allows.
    #[error("{what}: {reason}")]
    Invalid {
        /// Which field.
        what: String,
        /// What is wrong.
        reason: String,
    },
    /// A report parameter is invalid.
    #[error("invalid report parameter `{name}`: {reason}")]
    InvalidParam {
        /// Parameter.
        name: &'static str,
        /// What is expected.
        reason: String,
    },
}

/// Result with [`ReportError`].
pub type Result<T> = std::result::Result<T, ReportError>;
