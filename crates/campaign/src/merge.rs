//! Shard stores merged into one, and the status of a store.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::CampaignError;
use crate::store::{Outcome, Shard, Store, StoreMeta};

/// What [`merge`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MergeSummary {
    /// Runs copied.
    pub runs: usize,
    /// The shards the merged store holds.
    pub shards: Vec<u32>,
    /// The shard count of the campaign.
    pub count: u32,
}

impl MergeSummary {
    /// Whether every shard is present (the merged store is then a whole campaign, and can be
    /// resumed like an unsharded one).
    pub fn complete(&self) -> bool {
        self.shards.len() as u32 == self.count
    }
}

fn shard_set(meta: &StoreMeta) -> Vec<u32> {
    if meta.merged.is_empty() {
        if meta.shard.count == 1 {
            vec![0]
        } else {
            vec![meta.shard.index]
        }
    } else {
        meta.merged.clone()
    }
}

impl MergeSummary {
    /// What `fogline campaign merge` prints about a merge into `out`.
    pub fn write_text(&self, out_path: &Path, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        writeln!(
            out,
            "merged {} runs of shards {:?} (of {}) into {}{}",
            self.runs,
            self.shards,
            self.count,
            out_path.display(),
            if self.complete() {
                ""
            } else {
                " — not every shard is there yet"
            }
        )
    }
}

/// Merges shard stores of one campaign into a new store at `out`. The inputs must come from
/// the same configuration and the same shard count, and hold different shards; the result is
/// run for run what one store running those shards would hold.
pub fn merge(out: &Path, inputs: &[PathBuf]) -> Result<MergeSummary, CampaignError> {
    let store_err = |path: &Path, reason: String| CampaignError::Store {
        path: path.to_path_buf(),
        reason,
    };
    if inputs.is_empty() {
        return Err(store_err(
            out,
            "nothing to merge: give the shard stores".into(),
        ));
    }
    let stores: Vec<Store> = inputs
        .iter()
        .map(|p| Store::open(p))
        .collect::<Result<_, _>>()?;
    let first = stores[0].meta().clone();
    let mut owner: BTreeMap<u32, &Path> = BTreeMap::new();
    for s in &stores {
        let m = s.meta();
        if m.config_hash != first.config_hash {
            return Err(store_err(
                s.path(),
                format!(
                    "made by a different campaign configuration than {} (hash {} vs {})",
                    stores[0].path().display(),
                    m.config_hash,
                    first.config_hash
                ),
            ));
        }
        if m.shard.count != first.shard.count {
            return Err(store_err(
                s.path(),
                format!(
                    "cut into {} shards, {} into {}",
                    m.shard.count,
                    stores[0].path().display(),
                    first.shard.count
                ),
            ));
        }
        for i in shard_set(m) {
            if let Some(other) = owner.insert(i, s.path()) {
                return Err(store_err(
                    s.path(),
                    format!("shard {i}/{} is also in {}", m.shard.count, other.display()),
                ));
            }
        }
    }
    let shards: Vec<u32> = owner.keys().copied().collect();
    let count = first.shard.count;
    let complete = shards.len() as u32 == count;
    let meta = StoreMeta {
        config_hash: first.config_hash.clone(),
        identity: first.identity.clone(),
        shard: if complete {
            Shard::ALL
        } else {
            Shard {
                index: shards[0],
                count,
            }
        },
        merged: if complete { Vec::new() } else { shards.clone() },
    };
    // Build next to `out` and rename, so a failed merge leaves no half store behind.
    let dir = out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = out
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or("merged.sqlite");
    let tmp = dir.join(format!(".{name}.merging-{}", std::process::id()));
    if out.exists() {
        return Err(store_err(
            out,
            "already exists; merge into a new file".into(),
        ));
    }
    let _ = std::fs::remove_file(&tmp);
    let result = (|| {
        let mut merged = Store::create(&tmp, &meta)?;
        let mut runs = 0;
        for s in &stores {
            let rows = s.runs()?;
            runs += rows.len();
            merged.insert(&rows)?;
        }
        drop(merged);
        std::fs::rename(&tmp, out).map_err(|e| CampaignError::Io {
            path: out.to_path_buf(),
            source: e,
        })?;
        Ok(runs)
    })();
    match result {
        Ok(runs) => {
            for suffix in ["-wal", "-shm"] {
                let _ = std::fs::remove_file(format!("{}{suffix}", tmp.display()));
            }
            Ok(MergeSummary {
                runs,
                shards,
                count,
            })
        }
        Err(e) => {
            for suffix in ["", "-wal", "-shm"] {
                let _ = std::fs::remove_file(format!("{}{suffix}", tmp.display()));
            }
            Err(e)
        }
    }
}

/// A store's state.
#[derive(Debug, Clone, PartialEq)]
pub struct Status {
    /// What the store was made for.
    pub meta: StoreMeta,
    /// Runs the store's shard(s) plan, when the identity says.
    pub planned: Option<usize>,
    /// Successful runs.
    pub ok: usize,
    /// Failed runs.
    pub failed: usize,
    /// Per condition (run order): (name, ok, failed).
    pub by_condition: Vec<(String, usize, usize)>,
    /// Failures per kind.
    pub failures: Vec<(String, usize)>,
    /// Up to five failure reasons, as examples.
    pub examples: Vec<String>,
}

/// The status of the store at `path`.
pub fn status(path: &Path) -> Result<Status, CampaignError> {
    let store = Store::open(path)?;
    let runs = store.runs()?;
    let meta = store.meta().clone();
    let mut by_condition: BTreeMap<u32, (String, usize, usize)> = BTreeMap::new();
    let mut failures: BTreeMap<String, usize> = BTreeMap::new();
    let mut examples = Vec::new();
    let (mut ok, mut failed) = (0, 0);
    for r in &runs {
        let e = by_condition
            .entry(r.condition_index)
            .or_insert_with(|| (r.condition.clone(), 0, 0));
        match &r.outcome {
            Outcome::Ok { .. } => {
                ok += 1;
                e.1 += 1;
            }
            Outcome::Failed { kind, reason } => {
                failed += 1;
                e.2 += 1;
                *failures.entry(kind.clone()).or_default() += 1;
                if examples.len() < 5 {
                    examples.push(format!(
                        "{} × {} × seed {}: {kind}: {reason}",
                        r.clip_id, r.condition, r.seed
                    ));
                }
            }
        }
    }
    Ok(Status {
        planned: planned(&meta),
        meta,
        ok,
        failed,
        by_condition: by_condition.into_values().collect(),
        failures: failures.into_iter().collect(),
        examples,
    })
}

/// The runs a store plans, from its identity: clips of its shard(s) × conditions × seeds.
fn planned(meta: &StoreMeta) -> Option<usize> {
    let v: serde_json::Value = serde_json::from_str(&meta.identity).ok()?;
    let clips = match v["clips"]["count"].as_u64() {
        Some(n) => n as usize,
        None => v["clips"]["clip_ids"].as_array()?.len(),
    };
    let names = v["conditions"]["names"].as_array()?;
    let conditions = 1 + names
        .iter()
        .filter(|n| !matches!(n.as_str(), Some("clean" | "identity")))
        .count();
    let seeds = v["conditions"]["seeds"].as_array()?.len();
    let shards = shard_set(meta);
    let in_shards = (0..clips)
        .filter(|&i| shards.contains(&((i % meta.shard.count as usize) as u32)))
        .count();
    Some(in_shards * conditions * seeds)
}

impl Status {
    /// What `fogline campaign status` prints about the store at `store` (`json`: one JSON
    /// object instead).
    pub fn write_text(
        &self,
        store: &Path,
        json: bool,
        out: &mut dyn std::io::Write,
    ) -> std::io::Result<()> {
        let s = self;
        if json {
            let v = serde_json::json!({
                "store": store,
                "config_hash": s.meta.config_hash,
                "shard": s.meta.shard.to_string(),
                "merged_shards": s.meta.merged,
                "planned": s.planned,
                "ok": s.ok,
                "failed": s.failed,
                "pending": s.planned.map(|p| p.saturating_sub(s.ok + s.failed)),
                "by_condition": s.by_condition.iter().map(|(n, ok, f)| serde_json::json!({"condition": n, "ok": ok, "failed": f})).collect::<Vec<_>>(),
                "failures": s.failures.iter().map(|(k, n)| serde_json::json!({"kind": k, "count": n})).collect::<Vec<_>>(),
                "examples": s.examples,
            });
            writeln!(
                out,
                "{}",
                serde_json::to_string_pretty(&v).map_err(std::io::Error::other)?
            )?;
            return Ok(());
        }
        writeln!(out, "store    {}", store.display())?;
        writeln!(out, "config   {}", s.meta.config_hash)?;
        if s.meta.merged.is_empty() {
            writeln!(out, "shard    {}", s.meta.shard)?;
        } else {
            writeln!(
                out,
                "shards   {:?} of {} (merged)",
                s.meta.merged, s.meta.shard.count
            )?;
        }
        let finished = s.ok + s.failed;
        match s.planned {
            Some(p) => writeln!(
                out,
                "runs     {finished} of {p} finished ({:.1} %): {} ok, {} failed, {} pending",
                100.0 * finished as f64 / p.max(1) as f64,
                s.ok,
                s.failed,
                p.saturating_sub(finished)
            )?,
            None => writeln!(out, "runs     {finished}: {} ok, {} failed", s.ok, s.failed)?,
        }
        writeln!(out, "\n{:<24} {:>8} {:>8}", "condition", "ok", "failed")?;
        for (n, ok, f) in &s.by_condition {
            writeln!(out, "{n:<24} {ok:>8} {f:>8}")?;
        }
        if !s.failures.is_empty() {
            writeln!(out, "\nfailures by kind:")?;
            for (k, n) in &s.failures {
                writeln!(out, "  {k}: {n}")?;
            }
            writeln!(out, "examples:")?;
            for e in &s.examples {
                writeln!(out, "  {e}")?;
            }
        }
        Ok(())
    }
}
