//! Explanation similarity: embeddings stored with the runs, `coc_cosine` in the pairs table,
//! stores made before the embedding column, and campaigns without the model.

use std::path::Path;
use std::sync::Arc;

use arrow_array::Array;

use fogline_campaign::export::pairs_table;
use fogline_campaign::runner::Silent;
use fogline_campaign::store::{Outcome, RunRecord, StoreMeta};
use fogline_campaign::{BuiltinPlanner, Campaign, CampaignConfig, Shard, Store, run, run_options};

fn config() -> CampaignConfig {
    CampaignConfig::from_toml(
        "[clips]\ncount = 4\nseed = 5\nwidth = 192\nheight = 108\n\
         [conditions]\nnames = [\"noise_70\", \"fog_07\"]\n",
    )
    .unwrap()
}

/// Runs the campaign of `cfg` for `shard` into a new store at `path`, with the embedding model
/// (which must be found) or without it.
fn run_into(cfg: &CampaignConfig, path: &Path, shard: Shard, embed: bool) -> Store {
    let campaign = Campaign::new(cfg.clone()).unwrap();
    let mut store = Store::create(path, &campaign.store_meta(shard)).unwrap();
    let mut opts = run_options(cfg, shard);
    if embed {
        assert!(opts.embedder.is_some(), "the model is found");
    } else {
        opts.embedder = None;
    }
    run(
        &campaign,
        &mut store,
        &BuiltinPlanner::new(),
        &opts,
        &Silent,
    )
    .unwrap();
    store
}

/// The model the README's test command installs (fails, never skips, when it is missing).
fn embedder() -> Arc<fogline_embed::CachedEmbedder> {
    fogline_campaign::similarity::shared()
        .unwrap_or_else(|e| panic!("{e} (scripts/python-peers.sh installs it)"))
}

fn cosine_column(csv: &str) -> Vec<String> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let at = header.iter().position(|h| *h == "coc_cosine").unwrap();
    // The built-in planner's explanations hold no commas or quotes.
    lines
        .map(|l| l.split(',').nth(at).unwrap().to_string())
        .collect()
}

#[test]
fn runs_store_their_explanation_embedding_and_pairs_carry_the_cosine() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.sqlite");
    drop(run_into(&config(), &path, Shard::ALL, true));
    let runs = Store::open(&path).unwrap().runs().unwrap();
    let model = embedder();
    for r in &runs {
        let Outcome::Ok {
            explanation,
            embedding: Some(e),
            ..
        } = &r.outcome
        else {
            panic!("no embedding: {r:?}");
        };
        assert_eq!(e.len(), 384);
        assert_eq!(
            &e[..],
            &model.model().embed(explanation)[..],
            "{explanation}"
        );
    }
    let (table, counts) = pairs_table(&runs, 0);
    assert_eq!(counts.with_cosine, counts.pairs);
    let (_, cos) = table
        .columns
        .iter()
        .find(|(n, _)| *n == "coc_cosine")
        .unwrap();
    let fogline_campaign::export::Column::F64(cos) = cos else {
        panic!("{cos:?}");
    };
    let texts = |name: &str| -> Vec<String> {
        let (_, c) = table.columns.iter().find(|(n, _)| *n == name).unwrap();
        let fogline_campaign::export::Column::Str(v) = c else {
            panic!()
        };
        v.iter().map(|s| s.clone().unwrap()).collect()
    };
    let (clean, attacked) = (texts("coc_clean"), texts("coc_attacked"));
    for i in 0..cos.len() {
        let c = cos[i].unwrap();
        let want = model.model().similarity(&clean[i], &attacked[i]);
        assert!((c - want).abs() < 1e-6, "{c} vs {want}");
        if clean[i] == attacked[i] {
            assert!((c - 1.0).abs() < 1e-6, "{c}");
        } else {
            assert!(c < 0.9999, "{:?} vs {:?}: {c}", clean[i], attacked[i]);
        }
    }
    // The exported CSV has the column, every cell filled.
    let s = crate::export_all(&runs, &dir.path().join("out"));
    assert!(s.cosine_missing.is_none());
    let csv = std::fs::read_to_string(dir.path().join("out/pairs.csv")).unwrap();
    let cells = cosine_column(&csv);
    assert_eq!(cells.len(), counts.pairs);
    assert!(cells.iter().all(|c| c.parse::<f64>().is_ok()), "{cells:?}");
}

#[test]
fn without_embeddings_the_cosine_column_is_empty() {
    let dir = tempfile::tempdir().unwrap();
    let store = run_into(&config(), &dir.path().join("s.sqlite"), Shard::ALL, false);
    let runs = store.runs().unwrap();
    assert!(runs.iter().all(|r| matches!(
        r.outcome,
        Outcome::Ok {
            embedding: None,
            ..
        }
    )));
    let (table, counts) = pairs_table(&runs, 0);
    assert_eq!((counts.pairs, counts.with_cosine), (8, 0));
    let mut csv = Vec::new();
    table.write_csv(&mut csv).unwrap();
    let cells = cosine_column(&String::from_utf8(csv).unwrap());
    assert_eq!(cells.len(), 8);
    assert!(cells.iter().all(String::is_empty), "{cells:?}");
    // The Parquet column is nullable Float64, all null.
    let batch = table.to_arrow().unwrap();
    let col = batch.column_by_name("coc_cosine").unwrap();
    assert_eq!(col.null_count(), 8);
    // With the model, the export embeds what the store lacks.
    let filled = fogline_campaign::similarity::fill_missing(&runs, Some(&embedder()));
    let (_, counts) = pairs_table(&filled, 0);
    assert_eq!(counts.with_cosine, 8);
}

fn run_record(clip: u32, cond: u32, explanation: &str, embedding: Option<Vec<f32>>) -> RunRecord {
    RunRecord {
        clip_index: clip,
        condition_index: cond,
        seed: 0,
        clip_id: format!("c{clip}"),
        scenario: "LANE_KEEPING".into(),
        condition: if cond == 0 { "clean" } else { "noise_30" }.into(),
        outcome: Outcome::Ok {
            trajectory: vec![[1.0, 0.0]; 64],
            explanation: explanation.into(),
            decision: None,
            ade_m: 0.5,
            fde_m: 1.0,
            embedding,
        },
        attempts: 1,
        latency_ms: 1.0,
        expert_decision: None,
    }
}

#[test]
fn a_store_made_before_the_embedding_column_still_reads_and_takes_embeddings() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.sqlite");
    let meta = StoreMeta {
        config_hash: "h".into(),
        identity: "{}".into(),
        shard: Shard::ALL,
        merged: Vec::new(),
    };
    // A current store with the embedding column dropped is the store as fogline wrote it
    // before the column (the same schema version).
    drop(Store::create(&path, &meta).unwrap());
    {
        let conn = rusqlite::Connection::open(&path).unwrap();
        conn.execute_batch("ALTER TABLE runs DROP COLUMN explanation_embedding")
            .unwrap();
        let traj: Vec<u8> = [1.0f64, 0.0]
            .repeat(64)
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        conn.execute(
            "INSERT INTO runs VALUES (0, 0, 0, 'c0', 'LANE_KEEPING', 'clean', 'ok', NULL, NULL, \
             1, NULL, 'Keep lane.', 0.5, 1.0, ?1, NULL, 1.0, 'h')",
            [traj],
        )
        .unwrap();
    }
    let mut store = Store::resume(&path, &meta).unwrap();
    let runs = store.runs().unwrap();
    assert_eq!(runs.len(), 1);
    assert!(matches!(
        runs[0].outcome,
        Outcome::Ok {
            embedding: None,
            ..
        }
    ));
    // A run without an embedding goes in as before; one with an embedding adds the column.
    store
        .insert(&[run_record(1, 0, "Keep lane.", None)])
        .unwrap();
    store
        .insert(&[run_record(0, 1, "Stop now.", Some(vec![0.6, 0.8]))])
        .unwrap();
    drop(store);
    let runs = Store::open(&path).unwrap().runs().unwrap();
    assert_eq!(runs.len(), 3);
    let embeddings: Vec<Option<Vec<f32>>> = runs
        .iter()
        .map(|r| match &r.outcome {
            Outcome::Ok { embedding, .. } => embedding.clone(),
            Outcome::Failed { .. } => None,
        })
        .collect();
    assert_eq!(embeddings, vec![None, Some(vec![0.6, 0.8]), None]);
    // The pair of clip 0 has one embedding only: no cosine, until both runs have one.
    let (_, counts) = pairs_table(&runs, 0);
    assert_eq!((counts.pairs, counts.with_cosine), (1, 0));
}

#[test]
fn merged_stores_keep_the_embeddings() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config();
    let mut shards = Vec::new();
    for i in 0..2 {
        let path = dir.path().join(format!("s{i}.sqlite"));
        drop(run_into(&cfg, &path, Shard { index: i, count: 2 }, true));
        shards.push(path);
    }
    let merged = dir.path().join("m.sqlite");
    fogline_campaign::merge::merge(&merged, &shards).unwrap();
    let runs = Store::open(&merged).unwrap().runs().unwrap();
    assert_eq!(runs.len(), 12);
    assert!(runs.iter().all(|r| matches!(
        r.outcome,
        Outcome::Ok {
            embedding: Some(_),
            ..
        }
    )));
}
