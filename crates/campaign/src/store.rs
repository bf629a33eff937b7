//! The campaign store: one SQLite file in WAL mode. Every finished run (success or failure) is
//! one row, committed in a transaction together with the hash of the configuration that
//! produced it, so a killed campaign loses at most the runs in flight and a resumed one redoes
//! nothing that was committed.
//!
//! Tables: `meta(key, value)` (schema version, config hash and identity, shard) and `runs`
//! keyed by `(clip_index, condition_index, seed)`.
//!
//! `runs.explanation_embedding` (nullable; a run's explanation as a unit vector of f32, the
//! sentence embedding of `fogline-embed`) was added after schema version 1 was released: a
//! store made before it has no such column and reads as runs without embeddings; the column is
//! added the first time an embedding is written into it. Readers that do not know the column
//! ignore it, so the schema version stays 1.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use rusqlite::{Connection, OpenFlags, OptionalExtension, params};

use crate::CampaignError;

/// The store schema version.
pub const SCHEMA_VERSION: &str = "1";

/// A slice of the work: clip `i` belongs to shard `i mod count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0 ≤ index < count`.
    pub index: u32,
    /// The number of shards.
    pub count: u32,
}

impl Shard {
    /// The whole campaign.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Parses `i/N` (0-based `i`, as Kubernetes' completion index; Slurm arrays can start at 0).
    pub fn parse(s: &str) -> Result<Self, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("--shard {s:?}: expected i/N, e.g. 0/3"))?;
        let index: u32 = i
            .trim()
            .parse()
            .map_err(|_| format!("--shard {s:?}: {i:?} is not a shard index"))?;
        let count: u32 = n
            .trim()
            .parse()
            .map_err(|_| format!("--shard {s:?}: {n:?} is not a shard count"))?;
        if count == 0 || index >= count {
            return Err(format!(
                "--shard {s:?}: expected 0 ≤ i < N (shards are numbered from 0)"
            ));
        }
        Ok(Self { index, count })
    }

    /// Whether clip `clip_index` is in this shard.
    pub fn contains(&self, clip_index: usize) -> bool {
        clip_index % self.count as usize == self.index as usize
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// The planner answered with a valid plan.
    Ok {
        /// The 64 waypoints.
        trajectory: Vec<[f64; 2]>,
        /// The explanation.
        explanation: String,
        /// The stated decision, if any.
        decision: Option<String>,
        /// ADE against the clip's ground truth, m.
        ade_m: f64,
        /// FDE against the clip's ground truth, m.
        fde_m: f64,
        /// The explanation's sentence embedding (unit length; `fogline-embed`), when the
        /// model was available.
        embedding: Option<Vec<f32>>,
    },
    /// The run failed after its retries.
    Failed {
        /// The failure kind (`timeout`, `unavailable`, `remote_error`, `invalid_answer`,
        /// `input`, `clip`, `perturbation`).
        kind: String,
        /// What happened.
        reason: String,
    },
}

/// One finished run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRecord {
    /// Index of the clip in the corpus.
    pub clip_index: u32,
    /// Index of the condition in run order (0 = clean).
    pub condition_index: u32,
    /// The perturbation seed.
    pub seed: u64,
    /// The clip id.
    pub clip_id: String,
    /// The clip's scenario label.
    pub scenario: String,
    /// The condition name.
    pub condition: String,
    /// The result.
    pub outcome: Outcome,
    /// Planner calls made (1 + retries used).
    pub attempts: u32,
    /// Wall time of the last planner call, ms (not part of any exported table by default).
    pub latency_ms: f64,
    /// The privileged expert's decision, for generated clips.
    pub expert_decision: Option<String>,
}

impl RunRecord {
    /// The run's key.
    pub fn key(&self) -> (u32, u32, u64) {
        (self.clip_index, self.condition_index, self.seed)
    }
}

/// What a store was made for.
#[derive(Debug, Clone, PartialEq)]
pub struct StoreMeta {
    /// SHA-256 of the configuration's identity.
    pub config_hash: String,
    /// The identity itself (canonical JSON), to explain a mismatch.
    pub identity: String,
    /// The shard (a merged store records the shards it holds in `merged`).
    pub shard: Shard,
    /// For a merged store: the shard indices it holds.
    pub merged: Vec<u32>,
}

/// An open store.
pub struct Store {
    conn: Connection,
    path: PathBuf,
    meta: StoreMeta,
    /// Whether `runs` has the `explanation_embedding` column (stores made before it do not).
    has_embeddings: bool,
}

impl std::fmt::Debug for Store {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Store")
            .field("path", &self.path)
            .field("meta", &self.meta)
            .finish()
    }
}

const SCHEMA: &str = "
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL) WITHOUT ROWID;
CREATE TABLE runs (
    clip_index      INTEGER NOT NULL,
    condition_index INTEGER NOT NULL,
    seed            INTEGER NOT NULL,
    clip_id         TEXT NOT NULL,
    scenario        TEXT NOT NULL,
    condition       TEXT NOT NULL,
    status          TEXT NOT NULL CHECK (status IN ('ok', 'failed')),
    failure_kind    TEXT,
    reason          TEXT,
    attempts        INTEGER NOT NULL,
    decision        TEXT,
    explanation     TEXT,
    ade_m           REAL,
    fde_m           REAL,
    trajectory      BLOB,
    expert_decision TEXT,
    latency_ms      REAL NOT NULL,
    config_hash     TEXT NOT NULL,
    explanation_embedding BLOB,
    PRIMARY KEY (clip_index, condition_index, seed)
) WITHOUT ROWID;
";

impl Store {
    fn sqlite(path: &Path) -> impl Fn(rusqlite::Error) -> CampaignError + '_ {
        move |e| CampaignError::Sqlite {
            path: path.to_path_buf(),
            source: e,
        }
    }

    fn store_err(path: &Path, reason: impl Into<String>) -> CampaignError {
        CampaignError::Store {
            path: path.to_path_buf(),
            reason: reason.into(),
        }
    }

    fn pragmas(conn: &Connection, path: &Path) -> Result<(), CampaignError> {
        // WAL: a commit is one append to the log; a killed process loses nothing committed.
        // synchronous=NORMAL keeps that guarantee against process crashes (only a power loss
        // can drop the last commits), at a fraction of FULL's fsyncs.
        conn.pragma_update(None, "journal_mode", "WAL")
            .map_err(Self::sqlite(path))?;
        conn.pragma_update(None, "synchronous", "NORMAL")
            .map_err(Self::sqlite(path))?;
        conn.busy_timeout(std::time::Duration::from_secs(10))
            .map_err(Self::sqlite(path))?;
        Ok(())
    }

    /// Creates a new store at `path`; refuses when a file is already there.
    pub fn create(path: &Path, meta: &StoreMeta) -> Result<Self, CampaignError> {
        if path.exists() {
            return Err(Self::store_err(
                path,
                "a store already exists here: continue it with --resume (nothing finished \
                 is redone), or choose another --store",
            ));
        }
        if let Some(dir) = path.parent()
            && !dir.as_os_str().is_empty()
        {
            std::fs::create_dir_all(dir).map_err(|e| CampaignError::Io {
                path: dir.to_path_buf(),
                source: e,
            })?;
        }
        // The store is made whole under a temporary name and renamed into place, so a kill
        // during creation never leaves a file at `path` that later runs refuse: a killed
        // creation leaves only the temporary, which the next one replaces.
        let name = path
            .file_name()
            .map_or_else(|| "store".into(), |n| n.to_string_lossy());
        let tmp = path.with_file_name(format!(".{name}.creating"));
        for suffix in ["", "-journal", "-wal", "-shm"] {
            let p = PathBuf::from(format!("{}{suffix}", tmp.display()));
            match std::fs::remove_file(&p) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(CampaignError::Io { path: p, source: e });
                }
                _ => {}
            }
        }
        Self::write_new(&tmp, meta)?;
        std::fs::rename(&tmp, path).map_err(|e| CampaignError::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        #[cfg(unix)]
        if let Some(dir) = path.parent()
            && let Ok(d) = std::fs::File::open(if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            })
        {
            let _ = d.sync_all();
        }
        // Read back as any later run reads it.
        Self::open(path)
    }

    /// Writes a complete new store (schema and metadata, rollback journal, synced) at `path`
    /// and closes it.
    fn write_new(path: &Path, meta: &StoreMeta) -> Result<(), CampaignError> {
        let mut conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_CREATE,
        )
        .map_err(Self::sqlite(path))?;
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(Self::sqlite(path))?;
        let tx = conn.transaction().map_err(Self::sqlite(path))?;
        tx.execute_batch(SCHEMA).map_err(Self::sqlite(path))?;
        let merged = meta
            .merged
            .iter()
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(",");
        for (k, v) in [
            ("schema_version", SCHEMA_VERSION.to_string()),
            ("config_hash", meta.config_hash.clone()),
            ("identity", meta.identity.clone()),
            ("shard", meta.shard.to_string()),
            ("merged", merged),
            (
                "created_by",
                format!("fogline {}", env!("CARGO_PKG_VERSION")),
            ),
        ] {
            tx.execute(
                "INSERT INTO meta (key, value) VALUES (?1, ?2)",
                params![k, v],
            )
            .map_err(Self::sqlite(path))?;
        }
        tx.commit().map_err(Self::sqlite(path))?;
        conn.close().map_err(|(_, e)| Self::sqlite(path)(e))?;
        Ok(())
    }

    /// Opens an existing store.
    pub fn open(path: &Path) -> Result<Self, CampaignError> {
        if !path.is_file() {
            return Err(Self::store_err(
                path,
                "no such store (expected an SQLite file made by `fogline campaign run`)",
            ));
        }
        let conn = Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_WRITE)
            .map_err(Self::sqlite(path))?;
        Self::pragmas(&conn, path).map_err(|_| {
            Self::store_err(
                path,
                "not a fogline campaign store (not an SQLite database)",
            )
        })?;
        let get = |k: &str| -> Result<String, CampaignError> {
            conn.query_row("SELECT value FROM meta WHERE key = ?1", [k], |r| r.get(0))
                .optional()
                .map_err(|_| Self::store_err(path, "not a fogline campaign store (no meta table)"))?
                .ok_or_else(|| Self::store_err(path, format!("store meta lacks {k:?}")))
        };
        let version = get("schema_version")?;
        if version != SCHEMA_VERSION {
            return Err(Self::store_err(
                path,
                format!("store schema version {version}, this fogline reads {SCHEMA_VERSION}"),
            ));
        }
        let shard = Shard::parse(&get("shard")?)
            .map_err(|e| Self::store_err(path, format!("store meta: {e}")))?;
        let merged_text = get("merged")?;
        let merged = if merged_text.is_empty() {
            Vec::new()
        } else {
            merged_text
                .split(',')
                .map(|s| {
                    s.parse().map_err(|_| {
                        Self::store_err(path, format!("store meta: merged {merged_text:?}"))
                    })
                })
                .collect::<Result<_, _>>()?
        };
        let meta = StoreMeta {
            config_hash: get("config_hash")?,
            identity: get("identity")?,
            shard,
            merged,
        };
        let has_embeddings = Self::has_column(&conn, path, "explanation_embedding")?;
        Ok(Self {
            conn,
            path: path.to_path_buf(),
            meta,
            has_embeddings,
        })
    }

    fn has_column(conn: &Connection, path: &Path, column: &str) -> Result<bool, CampaignError> {
        let mut st = conn
            .prepare("SELECT name FROM pragma_table_info('runs')")
            .map_err(Self::sqlite(path))?;
        let names = st
            .query_map([], |r| r.get::<_, String>(0))
            .map_err(Self::sqlite(path))?
            .collect::<Result<Vec<_>, _>>()
            .map_err(Self::sqlite(path))?;
        if names.is_empty() {
            return Err(Self::store_err(
                path,
                "not a fogline campaign store (no runs table)",
            ));
        }
        Ok(names.iter().any(|n| n == column))
    }

    /// Opens a store to continue a campaign: the configuration and the shard must be the ones
    /// it was made with.
    pub fn resume(path: &Path, meta: &StoreMeta) -> Result<Self, CampaignError> {
        let s = Self::open(path)?;
        if s.meta.config_hash != meta.config_hash {
            return Err(Self::store_err(
                path,
                format!(
                    "this store was made by a different campaign configuration (hash {}…, \
                     now {}…); changed: {}. Run the original configuration, or start a new \
                     store with --store",
                    &s.meta.config_hash[..12.min(s.meta.config_hash.len())],
                    &meta.config_hash[..12.min(meta.config_hash.len())],
                    identity_diff(&s.meta.identity, &meta.identity)
                ),
            ));
        }
        if s.meta.shard != meta.shard || !s.meta.merged.is_empty() {
            return Err(Self::store_err(
                path,
                format!(
                    "this store holds shard {}{}, not shard {}",
                    s.meta.shard,
                    if s.meta.merged.is_empty() {
                        ""
                    } else {
                        " (merged)"
                    },
                    meta.shard
                ),
            ));
        }
        Ok(s)
    }

    /// The store file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What the store was made for.
    pub fn meta(&self) -> &StoreMeta {
        &self.meta
    }

    /// The keys of every finished run; with `failed = false`, of the successful ones only.
    pub fn keys(&self, failed: bool) -> Result<HashSet<(u32, u32, u64)>, CampaignError> {
        let sql = if failed {
            "SELECT clip_index, condition_index, seed FROM runs"
        } else {
            "SELECT clip_index, condition_index, seed FROM runs WHERE status = 'ok'"
        };
        let mut st = self.conn.prepare(sql).map_err(Self::sqlite(&self.path))?;
        let rows = st
            .query_map([], |r| {
                Ok((
                    r.get::<_, u32>(0)?,
                    r.get::<_, u32>(1)?,
                    r.get::<_, i64>(2)? as u64,
                ))
            })
            .map_err(Self::sqlite(&self.path))?;
        rows.collect::<Result<_, _>>()
            .map_err(Self::sqlite(&self.path))
    }

    /// Deletes the failed runs (so that they run again); returns how many.
    pub fn delete_failed(&mut self) -> Result<usize, CampaignError> {
        self.conn
            .execute("DELETE FROM runs WHERE status = 'failed'", [])
            .map_err(Self::sqlite(&self.path))
    }

    /// Commits `runs` in one transaction (each run is one row: all of it or nothing).
    pub fn insert(&mut self, runs: &[RunRecord]) -> Result<(), CampaignError> {
        let path = self.path.clone();
        let hash = self.meta.config_hash.clone();
        let embeds = runs.iter().any(|r| {
            matches!(
                r.outcome,
                Outcome::Ok {
                    embedding: Some(_),
                    ..
                }
            )
        });
        let tx = self.conn.transaction().map_err(Self::sqlite(&path))?;
        if embeds && !self.has_embeddings {
            // A store made before the column: add it (nullable; old runs keep NULL).
            tx.execute_batch("ALTER TABLE runs ADD COLUMN explanation_embedding BLOB")
                .map_err(Self::sqlite(&path))?;
        }
        {
            let embedding_column = if embeds || self.has_embeddings {
                ", explanation_embedding) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, \
                 ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19)"
            } else {
                ") VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, \
                 ?17, ?18)"
            };
            let mut st = tx
                .prepare_cached(&format!(
                    "INSERT INTO runs (clip_index, condition_index, seed, clip_id, scenario, \
                     condition, status, failure_kind, reason, attempts, decision, explanation, \
                     ade_m, fde_m, trajectory, expert_decision, latency_ms, config_hash\
                     {embedding_column}"
                ))
                .map_err(Self::sqlite(&path))?;
            for r in runs {
                let (status, kind, reason, decision, explanation, ade, fde, traj, emb) =
                    match &r.outcome {
                        Outcome::Ok {
                            trajectory,
                            explanation,
                            decision,
                            ade_m,
                            fde_m,
                            embedding,
                        } => (
                            "ok",
                            None,
                            None,
                            decision.clone(),
                            Some(explanation.clone()),
                            Some(*ade_m),
                            Some(*fde_m),
                            Some(encode_trajectory(trajectory)),
                            embedding.as_deref().map(encode_embedding),
                        ),
                        Outcome::Failed { kind, reason } => (
                            "failed",
                            Some(kind.clone()),
                            Some(reason.clone()),
                            None,
                            None,
                            None,
                            None,
                            None,
                            None,
                        ),
                    };
                let seed = r.seed as i64;
                let mut values: Vec<&dyn rusqlite::ToSql> = vec![
                    &r.clip_index,
                    &r.condition_index,
                    &seed,
                    &r.clip_id,
                    &r.scenario,
                    &r.condition,
                    &status,
                    &kind,
                    &reason,
                    &r.attempts,
                    &decision,
                    &explanation,
                    &ade,
                    &fde,
                    &traj,
                    &r.expert_decision,
                    &r.latency_ms,
                    &hash,
                ];
                if embeds || self.has_embeddings {
                    values.push(&emb);
                }
                st.execute(values.as_slice()).map_err(|e| match e {
                    rusqlite::Error::SqliteFailure(f, _)
                        if f.code == rusqlite::ErrorCode::ConstraintViolation =>
                    {
                        Self::store_err(
                            &path,
                            format!(
                                "run {} × {} × seed {} is already in the store",
                                r.clip_id, r.condition, r.seed
                            ),
                        )
                    }
                    e => Self::sqlite(&path)(e),
                })?;
            }
        }
        tx.commit().map_err(Self::sqlite(&path))?;
        self.has_embeddings |= embeds;
        Ok(())
    }

    /// Every run, ordered by clip, condition and seed.
    pub fn runs(&self) -> Result<Vec<RunRecord>, CampaignError> {
        let path = &self.path;
        // A store made before the embedding column reads as runs without embeddings.
        let embedding = if self.has_embeddings {
            "explanation_embedding"
        } else {
            "NULL"
        };
        let mut st = self
            .conn
            .prepare(&format!(
                "SELECT clip_index, condition_index, seed, clip_id, scenario, condition, status, \
                 failure_kind, reason, attempts, decision, explanation, ade_m, fde_m, \
                 trajectory, expert_decision, latency_ms, config_hash, {embedding} FROM runs \
                 ORDER BY clip_index, condition_index, seed"
            ))
            .map_err(Self::sqlite(path))?;
        let rows = st
            .query_map([], |r| {
                let status: String = r.get(6)?;
                let hash: String = r.get(17)?;
                let outcome = if status == "ok" {
                    let blob: Vec<u8> = r.get(14)?;
                    Outcome::Ok {
                        trajectory: decode_trajectory(&blob),
                        explanation: r.get::<_, Option<String>>(11)?.unwrap_or_default(),
                        decision: r.get(10)?,
                        ade_m: r.get(12)?,
                        fde_m: r.get(13)?,
                        embedding: r
                            .get::<_, Option<Vec<u8>>>(18)?
                            .map(|b| decode_embedding(&b)),
                    }
                } else {
                    Outcome::Failed {
                        kind: r.get::<_, Option<String>>(7)?.unwrap_or_default(),
                        reason: r.get::<_, Option<String>>(8)?.unwrap_or_default(),
                    }
                };
                Ok((
                    hash,
                    RunRecord {
                        clip_index: r.get(0)?,
                        condition_index: r.get(1)?,
                        seed: r.get::<_, i64>(2)? as u64,
                        clip_id: r.get(3)?,
                        scenario: r.get(4)?,
                        condition: r.get(5)?,
                        outcome,
                        attempts: r.get(9)?,
                        expert_decision: r.get(15)?,
                        latency_ms: r.get(16)?,
                    },
                ))
            })
            .map_err(Self::sqlite(path))?;
        let mut out = Vec::new();
        for row in rows {
            let (hash, run) = row.map_err(Self::sqlite(path))?;
            if hash != self.meta.config_hash {
                return Err(Self::store_err(
                    path,
                    format!(
                        "run {} × {} × seed {} was made by another configuration ({hash})",
                        run.clip_id, run.condition, run.seed
                    ),
                ));
            }
            if let Outcome::Ok {
                embedding: Some(e), ..
            } = &run.outcome
                && (e.is_empty() || e.iter().any(|v| !v.is_finite()))
            {
                return Err(Self::store_err(
                    path,
                    format!(
                        "run {} × {} × seed {}: a stored explanation embedding is damaged",
                        run.clip_id, run.condition, run.seed
                    ),
                ));
            }
            if let Outcome::Ok { trajectory, .. } = &run.outcome
                && (trajectory.len() != fogline_types::clip::HORIZON
                    || trajectory.iter().flatten().any(|v| !v.is_finite()))
            {
                return Err(Self::store_err(
                    path,
                    format!(
                        "run {} × {} × seed {}: a stored trajectory is damaged",
                        run.clip_id, run.condition, run.seed
                    ),
                ));
            }
            out.push(run);
        }
        Ok(out)
    }

    /// The number of runs, successful and failed.
    pub fn counts(&self) -> Result<(usize, usize), CampaignError> {
        self.conn
            .query_row(
                "SELECT COALESCE(SUM(status = 'ok'), 0), COALESCE(SUM(status = 'failed'), 0) FROM runs",
                [],
                |r| Ok((r.get::<_, i64>(0)? as usize, r.get::<_, i64>(1)? as usize)),
            )
            .map_err(Self::sqlite(&self.path))
    }
}

/// 64 × (x, y) as little-endian f64.
fn encode_trajectory(t: &[[f64; 2]]) -> Vec<u8> {
    t.iter().flatten().flat_map(|v| v.to_le_bytes()).collect()
}

/// An embedding as little-endian f32.
fn encode_embedding(e: &[f32]) -> Vec<u8> {
    e.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// The embedding of a blob; a blob whose length is no multiple of 4 decodes to NaN, which
/// [`Store::runs`] reports as damaged.
fn decode_embedding(b: &[u8]) -> Vec<f32> {
    if !b.len().is_multiple_of(4) {
        return vec![f32::NAN];
    }
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

fn decode_trajectory(b: &[u8]) -> Vec<[f64; 2]> {
    b.chunks_exact(16)
        .map(|c| {
            let mut x = [0u8; 8];
            let mut y = [0u8; 8];
            x.copy_from_slice(&c[..8]);
            y.copy_from_slice(&c[8..]);
            [f64::from_le_bytes(x), f64::from_le_bytes(y)]
        })
        .collect()
}

/// The top-level entries of two identity JSONs that differ, e.g. `clips.count 10 → 20`.
fn identity_diff(old: &str, new: &str) -> String {
    let (Ok(a), Ok(b)) = (
        serde_json::from_str::<serde_json::Value>(old),
        serde_json::from_str::<serde_json::Value>(new),
    ) else {
        return "(unreadable identity)".into();
    };
    let mut out = Vec::new();
    diff_into("", &a, &b, &mut out);
    if out.is_empty() {
        "(nothing visible)".into()
    } else {
        out.join("; ")
    }
}

fn diff_into(prefix: &str, a: &serde_json::Value, b: &serde_json::Value, out: &mut Vec<String>) {
    use serde_json::Value;
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                diff_into(
                    &p,
                    x.get(k).unwrap_or(&Value::Null),
                    y.get(k).unwrap_or(&Value::Null),
                    out,
                );
            }
        }
        _ if a != b => out.push(format!("{prefix} {a} → {b}")),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn shards_parse_and_partition() {
        assert_eq!(Shard::parse("1/3").unwrap(), Shard { index: 1, count: 3 });
        for bad in ["3/3", "1", "a/3", "0/0", "-1/2"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
        let shards: Vec<Shard> = (0..3).map(|i| Shard { index: i, count: 3 }).collect();
        for clip in 0..100 {
            assert_eq!(shards.iter().filter(|s| s.contains(clip)).count(), 1);
        }
    }

    #[test]
    fn trajectories_round_trip_bit_exactly() {
        let t: Vec<[f64; 2]> = (0..64)
            .map(|i| [i as f64 * 0.1 + 1e-17, -(i as f64) / 3.0])
            .collect();
        assert_eq!(decode_trajectory(&encode_trajectory(&t)), t);
        let e = vec![0.5f32, -0.25, 1e-7, 0.0];
        assert_eq!(decode_embedding(&encode_embedding(&e)), e);
        assert!(decode_embedding(&[0, 0, 0]).iter().all(|v| v.is_nan()));
    }

    #[test]
    fn identity_diff_names_the_changed_field() {
        let d = identity_diff(
            r#"{"clips":{"count":10},"x":1}"#,
            r#"{"clips":{"count":20},"x":1}"#,
        );
        assert_eq!(d, "clips.count 10 → 20");
    }
}
