//! `corpus.json`: what `fogline world generate` wrote into a corpus directory, deterministic
//! (no times, no paths), written last so its presence means the corpus is complete. One
//! typed definition for its writer and its readers.

use serde::{Deserialize, Serialize};

use crate::config::WorldConfig;

/// The manifest's file name.
pub const CORPUS_FILE: &str = "corpus.json";

/// One clip of the corpus.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CorpusClip {
    /// The clip's id (its directory name).
    pub id: String,
    /// Its scenario label.
    pub scenario: String,
}

/// The contents of `corpus.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Corpus {
    /// [`Corpus::FORMAT`].
    pub format: String,
    /// [`Corpus::VERSION`].
    pub version: u32,
    /// The producing tool and version.
    pub generated_by: String,
    /// What was generated.
    pub config: WorldConfig,
    /// Clips.
    pub n_clips: usize,
    /// Every clip, in index order.
    pub clips: Vec<CorpusClip>,
}

impl Corpus {
    /// The `format` of a corpus manifest.
    pub const FORMAT: &'static str = "fogline-corpus";
    /// The version written and read.
    pub const VERSION: u32 = 1;

    /// A manifest of `clips` generated under `config`.
    pub fn new(generated_by: &str, config: WorldConfig, clips: Vec<CorpusClip>) -> Self {
        Self {
            format: Self::FORMAT.into(),
            version: Self::VERSION,
            generated_by: generated_by.into(),
            config,
            n_clips: clips.len(),
            clips,
        }
    }

    /// Reads a manifest, checking its format and version; errors name the file.
    pub fn read(path: &std::path::Path) -> Result<Self, crate::WorldError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| crate::WorldError::file(path, format!("cannot read: {e}")))?;
        let c: Corpus = serde_json::from_str(&text)
            .map_err(|e| crate::WorldError::file(path, format!("not a corpus manifest: {e}")))?;
        if c.format != Self::FORMAT || c.version != Self::VERSION {
            return Err(crate::WorldError::file(
                path,
                format!(
                    "format {:?} version {} (expected {:?} version {})",
                    c.format,
                    c.version,
                    Self::FORMAT,
                    Self::VERSION
                ),
            ));
        }
        if c.n_clips != c.clips.len() {
            return Err(crate::WorldError::file(
                path,
                format!("n_clips {} but {} clips listed", c.n_clips, c.clips.len()),
            ));
        }
        Ok(c)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_manifest_round_trips_and_a_wrong_one_is_refused() {
        let dir = std::env::temp_dir().join(format!("fogline-corpus-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let c = Corpus::new(
            "fogline test",
            WorldConfig::default(),
            vec![CorpusClip {
                id: "lane_keeping_00000".into(),
                scenario: "LANE_KEEPING".into(),
            }],
        );
        let path = dir.join(CORPUS_FILE);
        std::fs::write(&path, serde_json::to_vec_pretty(&c).unwrap()).unwrap();
        assert_eq!(Corpus::read(&path).unwrap(), c);
        let mut wrong = c.clone();
        wrong.n_clips = 3;
        std::fs::write(&path, serde_json::to_vec(&wrong).unwrap()).unwrap();
        assert!(
            Corpus::read(&path)
                .unwrap_err()
                .to_string()
                .contains("n_clips 3")
        );
        std::fs::write(&path, b"{\"format\": \"x\"}").unwrap();
        assert!(
            Corpus::read(&path)
                .unwrap_err()
                .to_string()
                .contains("not a corpus manifest")
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
