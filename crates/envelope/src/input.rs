//! Reading a pairs table (CSV, Parquet or JSON lines) into a compact columnar [`PairTable`].
//!
//! Columns (one row per clip × perturbed condition):
//!
//! | column | required | meaning |
//! |---|---|---|
//! | `clip_id` | yes | clip identifier |
//! | `scenario` | yes | scenario label of the clip (the same on every row of a clip) |
//! | `attack` or `condition` | yes | condition name (`noise_30`, `dark`, `bright`, `fog_07`, …) |
//! | `ade_clean`, `ade_attacked` | yes | ADE of the clean / perturbed prediction vs ground truth (m, finite, ≥ 0) |
//! | `l2` | yes | deviation of the perturbed from the clean prediction (m, finite, ≥ 0) |
//! | `coc_clean`, `coc_attacked` | yes | Chain-of-Causation texts |
//! | `family`, `level` | no | family and level of the condition; needed for names other than the paper's grid |
//! | `coc_changed` | no | overrides the computed change flag (`true/false/1/0`) |
//! | `jaccard` | no | overrides the computed token Jaccard (in [0, 1]) |
//! | `coc_cosine` | no | cosine similarity of the two CoC texts' sentence embeddings (in [−1, 1]; empty or null where unknown), as `fogline campaign export` writes it with all-MiniLM-L6-v2 |
//!
//! `ade_clean_m`, `ade_attacked_m` and `l2_m` are accepted for the three distances. Other
//! columns are ignored. The format is chosen by extension (`.csv`, `.parquet`, `.jsonl` /
//! `.ndjson`); content that does not match its extension is an error that says what the file
//! looks like. Every error names the file, the row (CSV/JSONL: line number; Parquet: 1-based
//! data row) and the column.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use fogline_types::{Condition, Family};
use rustc_hash::FxHashMap as HashMap;
use sha2::{Digest, Sha256};

use crate::error::{EnvelopeError, Result};
use crate::text::{ActionRules, TextFeatures, TextScratch};

/// How to read a pairs table.
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// Accept clips that lack some conditions (otherwise an error).
    pub allow_incomplete: bool,
    /// Keyword rules mapping CoC texts to actions.
    pub actions: ActionRules,
}

/// The file formats a pairs table can come in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Comma-separated values with a header row.
    Csv,
    /// Apache Parquet.
    Parquet,
    /// One JSON object per line.
    Jsonl,
    /// Arrow record batches in memory (a DataFrame or Arrow table handed over through the
    /// Arrow C stream interface; [`read_pairs_arrow`]).
    Arrow,
}

impl Format {
    /// The format a path's extension names.
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        match ext.as_str() {
            "csv" => Ok(Self::Csv),
            "parquet" | "pq" => Ok(Self::Parquet),
            "jsonl" | "ndjson" => Ok(Self::Jsonl),
            _ => Err(EnvelopeError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// The name `envelope.json` writes (`csv`, `parquet`, `jsonl`, `arrow`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Csv => "csv",
            Self::Parquet => "parquet",
            Self::Jsonl => "jsonl",
            Self::Arrow => "arrow",
        }
    }

    fn label(self) -> &'static str {
        match self {
            Self::Csv => "CSV",
            Self::Parquet => "Parquet",
            Self::Jsonl => "JSON lines",
            Self::Arrow => "Arrow record batches",
        }
    }
}

/// Where the table came from.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct InputInfo {
    /// The file as given.
    pub path: String,
    /// Its format.
    pub format: Format,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
    /// Data rows read.
    pub n_rows: usize,
}

/// A condition found in the table.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ConditionInfo {
    /// Name as written.
    pub name: String,
    /// Family.
    pub family: Family,
    /// Level within the family.
    pub level: f64,
}

/// A pairs table in columnar form: ids interned, texts reduced to their features.
#[derive(Debug, Clone)]
pub struct PairTable {
    /// Where it came from.
    pub input: InputInfo,
    /// Clip ids, indexed by clip number.
    pub clip_ids: Vec<String>,
    /// Scenario number of each clip.
    pub clip_scenario: Vec<u32>,
    /// Scenario labels, indexed by scenario number (first-seen order).
    pub scenarios: Vec<String>,
    /// Conditions, indexed by condition number (first-seen order).
    pub conditions: Vec<ConditionInfo>,
    /// Action labels (see [`ActionRules::labels`]).
    pub action_labels: Vec<String>,
    /// Per row: clip number.
    pub clip: Vec<u32>,
    /// Per row: condition number.
    pub condition: Vec<u32>,
    /// Per row: ADE of the clean prediction (m).
    pub ade_clean_m: Vec<f64>,
    /// Per row: ADE of the perturbed prediction (m).
    pub ade_attacked_m: Vec<f64>,
    /// Per row: L2 deviation between the predictions (m).
    pub l2_m: Vec<f64>,
    /// Per row: whether the CoC changed.
    pub changed: Vec<bool>,
    /// Per row: token Jaccard of the two CoC texts.
    pub jaccard: Vec<f64>,
    /// Per row: cosine similarity of the two CoC texts' sentence embeddings, when the table
    /// has it (`coc_cosine`).
    pub cosine: Vec<Option<f64>>,
    /// Per row: action of the clean CoC.
    pub action_clean: Vec<u16>,
    /// Per row: action of the perturbed CoC.
    pub action_attacked: Vec<u16>,
    /// Clips lacking at least one condition (0 unless `allow_incomplete`).
    pub n_incomplete_clips: usize,
}

impl PairTable {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.clip.len()
    }

    /// Whether the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.clip.is_empty()
    }

    /// Scenario number of a row.
    pub fn row_scenario(&self, row: usize) -> u32 {
        self.clip_scenario[self.clip[row] as usize]
    }
}

/// Reads a pairs table from a file, the format chosen by its extension.
pub fn read_pairs(path: &Path, opts: &ReadOptions) -> Result<PairTable> {
    let format = Format::from_path(path)?;
    let io = |source| EnvelopeError::Io {
        path: path.to_path_buf(),
        source,
    };
    // Hash the file on one core while the other parses it.
    let hash = || -> Result<String> {
        let mut f = File::open(path).map_err(io)?;
        let mut hasher = Sha256::new();
        let mut buf = vec![0u8; 1 << 20];
        loop {
            let n = f.read(&mut buf).map_err(io)?;
            if n == 0 {
                break;
            }
            hasher.update(&buf[..n]);
        }
        Ok(hex(&hasher.finalize()))
    };
    let parse = || -> Result<Builder<'_>> {
        let mut b = Builder::new(path, opts);
        let file = File::open(path).map_err(io)?;
        match format {
            Format::Csv => read_csv(file, &mut b)?,
            Format::Jsonl => read_jsonl(file, &mut b)?,
            Format::Parquet => read_parquet(file, &mut b)?,
            Format::Arrow => {
                return Err(EnvelopeError::UnknownFormat {
                    path: path.to_path_buf(),
                });
            }
        }
        Ok(b)
    };
    let (sha256, b) = rayon::join(hash, parse);
    let b = b?;
    let sha256 = sha256?;
    b.finish(InputInfo {
        path: path.display().to_string(),
        format,
        sha256,
        n_rows: 0,
    })
}

/// Reads a pairs table from bytes in memory (`name` is used in messages).
pub fn read_pairs_bytes(
    name: &str,
    format: Format,
    bytes: &[u8],
    opts: &ReadOptions,
) -> Result<PairTable> {
    let path = Path::new(name);
    let mut b = Builder::new(path, opts);
    match format {
        Format::Csv => read_csv(bytes, &mut b)?,
        Format::Jsonl => read_jsonl(bytes, &mut b)?,
        Format::Parquet => read_parquet(bytes::Bytes::copy_from_slice(bytes), &mut b)?,
        Format::Arrow => {
            return Err(EnvelopeError::InvalidParam {
                name: "format",
                reason: "Arrow data is read from record batches (read_pairs_arrow), not bytes"
                    .into(),
            });
        }
    }
    b.finish(InputInfo {
        path: name.to_string(),
        format,
        sha256: hex(&Sha256::digest(bytes)),
        n_rows: 0,
    })
}

/// One row given in memory (for generators and adapters that hold typed values).
#[derive(Debug, Clone, Copy)]
pub struct RowRef<'a> {
    /// Clip id.
    pub clip_id: &'a str,
    /// Scenario label.
    pub scenario: &'a str,
    /// Condition name (of the paper's grid).
    pub condition: &'a str,
    /// Clean ADE (m).
    pub ade_clean: f64,
    /// Perturbed ADE (m).
    pub ade_attacked: f64,
    /// L2 deviation (m).
    pub l2: f64,
    /// Clean CoC.
    pub coc_clean: &'a str,
    /// Perturbed CoC.
    pub coc_attacked: &'a str,
}

/// Builds a table from rows in memory, with the same validation as the file readers
/// (`name` is used in messages; rows are numbered from 1).
pub fn table_from_rows<'a>(
    name: &str,
    opts: &ReadOptions,
    rows: impl IntoIterator<Item = RowRef<'a>>,
) -> Result<PairTable> {
    let mut b = Builder::new(Path::new(name), opts);
    for (i, r) in rows.into_iter().enumerate() {
        b.push(i as u64 + 1, &|c| match c {
            Col::ClipId => Cell::Str(r.clip_id),
            Col::Scenario => Cell::Str(r.scenario),
            Col::Condition => Cell::Str(r.condition),
            Col::AdeClean => Cell::Num(r.ade_clean),
            Col::AdeAttacked => Cell::Num(r.ade_attacked),
            Col::L2 => Cell::Num(r.l2),
            Col::CocClean => Cell::Str(r.coc_clean),
            Col::CocAttacked => Cell::Str(r.coc_attacked),
            _ => Cell::Null,
        })?;
    }
    b.finish(InputInfo {
        path: name.to_string(),
        format: Format::Csv,
        sha256: String::new(),
        n_rows: 0,
    })
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

// ---------------------------------------------------------------------------------------------
// Columns

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Col {
    ClipId,
    Scenario,
    Condition,
    AdeClean,
    AdeAttacked,
    L2,
    CocClean,
    CocAttacked,
    Family,
    Level,
    CocChanged,
    Jaccard,
    Cosine,
}

const N_COLS: usize = 13;
const REQUIRED: [Col; 8] = [
    Col::ClipId,
    Col::Scenario,
    Col::Condition,
    Col::AdeClean,
    Col::AdeAttacked,
    Col::L2,
    Col::CocClean,
    Col::CocAttacked,
];

impl Col {
    fn name(self) -> &'static str {
        match self {
            Col::ClipId => "clip_id",
            Col::Scenario => "scenario",
            Col::Condition => "attack",
            Col::AdeClean => "ade_clean",
            Col::AdeAttacked => "ade_attacked",
            Col::L2 => "l2",
            Col::CocClean => "coc_clean",
            Col::CocAttacked => "coc_attacked",
            Col::Family => "family",
            Col::Level => "level",
            Col::CocChanged => "coc_changed",
            Col::Jaccard => "jaccard",
            Col::Cosine => "coc_cosine",
        }
    }

    /// The column kind of a header: case-insensitive, surrounding whitespace and a leading
    /// byte-order mark ignored.
    fn from_header(h: &str) -> Option<Col> {
        let h = h.trim_start_matches('\u{feff}').trim().to_ascii_lowercase();
        Some(match h.as_str() {
            "clip_id" => Col::ClipId,
            "scenario" => Col::Scenario,
            "attack" | "condition" => Col::Condition,
            "ade_clean" | "ade_clean_m" => Col::AdeClean,
            "ade_attacked" | "ade_attacked_m" => Col::AdeAttacked,
            "l2" | "l2_m" => Col::L2,
            "coc_clean" => Col::CocClean,
            "coc_attacked" => Col::CocAttacked,
            "family" => Col::Family,
            "level" => Col::Level,
            "coc_changed" => Col::CocChanged,
            "jaccard" => Col::Jaccard,
            "coc_cosine" => Col::Cosine,
            _ => return None,
        })
    }

    fn all_names() -> [&'static str; 15] {
        [
            "clip_id",
            "scenario",
            "attack",
            "condition",
            "ade_clean",
            "ade_attacked",
            "l2",
            "coc_clean",
            "coc_attacked",
            "family",
            "level",
            "coc_changed",
            "jaccard",
            "coc_cosine",
            "l2_m",
        ]
    }
}

/// Maps column kinds to positions in the file's header.
fn map_header<'h>(
    path: &Path,
    headers: impl Iterator<Item = &'h str>,
) -> Result<[Option<usize>; N_COLS]> {
    let mut map = [None; N_COLS];
    let found: Vec<String> = headers
        .map(|h| h.trim_start_matches('\u{feff}').trim().to_string())
        .collect();
    for (i, h) in found.iter().enumerate() {
        if let Some(c) = Col::from_header(h)
            && map[c as usize].is_none()
        {
            map[c as usize] = Some(i);
        }
    }
    for c in REQUIRED {
        if map[c as usize].is_none() {
            let column = if c == Col::Condition {
                "attack (or condition)".to_string()
            } else {
                c.name().to_string()
            };
            let suggestion = found
                .iter()
                .filter(|f| Col::from_header(f).is_none())
                .map(|f| (edit_distance(&f.to_ascii_lowercase(), c.name()), f))
                .filter(|(d, _)| *d <= 2)
                .min_by_key(|(d, _)| *d)
                .map(|(_, f)| f.clone());
            return Err(EnvelopeError::MissingColumn {
                path: path.to_path_buf(),
                column,
                found,
                suggestion,
            });
        }
    }
    let _ = Col::all_names;
    Ok(map)
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != *cb))
                .min(prev[j + 1] + 1)
                .min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

/// A cell as a reader found it.
#[derive(Debug, Clone, Copy)]
enum Cell<'a> {
    Null,
    Str(&'a str),
    Num(f64),
    Bool(bool),
}

impl Cell<'_> {
    fn shown(&self) -> String {
        match self {
            Cell::Null => "null".into(),
            Cell::Str(s) => s.chars().take(60).collect(),
            Cell::Num(x) => x.to_string(),
            Cell::Bool(b) => b.to_string(),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The builder all readers feed

struct Builder<'o> {
    path: PathBuf,
    opts: &'o ReadOptions,
    clip_index: HashMap<String, u32>,
    clip_ids: Vec<String>,
    clip_scenario: Vec<u32>,
    clip_first_row: Vec<u64>,
    scenario_index: HashMap<String, u32>,
    scenarios: Vec<String>,
    condition_index: HashMap<String, u32>,
    conditions: Vec<ConditionInfo>,
    condition_first_row: Vec<u64>,
    /// Per clip, the conditions it has (bit per condition, 64 per word).
    clip_mask: Vec<Vec<u64>>,
    rows: Vec<u64>,
    /// The last row's clip, scenario and condition numbers (rows usually come grouped).
    last: Option<(u32, u32, u32)>,
    clip: Vec<u32>,
    condition: Vec<u32>,
    ade_clean: Vec<f64>,
    ade_attacked: Vec<f64>,
    l2: Vec<f64>,
    changed: Vec<bool>,
    jaccard: Vec<f64>,
    cosine: Vec<Option<f64>>,
    action_clean: Vec<u16>,
    action_attacked: Vec<u16>,
    scratch: TextScratch,
}

impl<'o> Builder<'o> {
    fn new(path: &Path, opts: &'o ReadOptions) -> Self {
        Self {
            path: path.to_path_buf(),
            opts,
            clip_index: HashMap::default(),
            clip_ids: Vec::new(),
            clip_scenario: Vec::new(),
            clip_first_row: Vec::new(),
            scenario_index: HashMap::default(),
            scenarios: Vec::new(),
            condition_index: HashMap::default(),
            conditions: Vec::new(),
            condition_first_row: Vec::new(),
            clip_mask: Vec::new(),
            rows: Vec::new(),
            last: None,
            clip: Vec::new(),
            condition: Vec::new(),
            ade_clean: Vec::new(),
            ade_attacked: Vec::new(),
            l2: Vec::new(),
            changed: Vec::new(),
            jaccard: Vec::new(),
            cosine: Vec::new(),
            action_clean: Vec::new(),
            action_attacked: Vec::new(),
            scratch: TextScratch::default(),
        }
    }

    fn bad(&self, row: u64, col: Col, cell: &Cell<'_>, expected: &str) -> EnvelopeError {
        EnvelopeError::BadValue {
            path: self.path.clone(),
            row,
            column: col.name().to_string(),
            value: cell.shown(),
            expected: expected.to_string(),
        }
    }

    fn text<'c>(&self, row: u64, col: Col, cell: Cell<'c>, allow_empty: bool) -> Result<&'c str> {
        match cell {
            Cell::Str(s) if allow_empty || !s.trim().is_empty() => Ok(s),
            _ => Err(self.bad(
                row,
                col,
                &cell,
                if allow_empty {
                    "text"
                } else {
                    "non-empty text"
                },
            )),
        }
    }

    fn number(&self, row: u64, col: Col, cell: Cell<'_>) -> Result<f64> {
        let v = match cell {
            Cell::Num(x) => Some(x),
            Cell::Str(s) => s.trim().parse::<f64>().ok(),
            _ => None,
        };
        match v {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.bad(row, col, &cell, "a finite number")),
        }
    }

    fn distance(&self, row: u64, col: Col, cell: Cell<'_>) -> Result<f64> {
        let x = self.number(row, col, cell)?;
        // A trajectory error beyond 100 km is not a measurement but a corrupt cell.
        if !(0.0..=MAX_DISTANCE_M).contains(&x) {
            return Err(self.bad(row, col, &cell, "a distance in metres (0 to 100000)"));
        }
        Ok(x)
    }

    /// Adds one data row; `get` returns the cell of a column kind (Null when absent).
    fn push<'c>(&mut self, row: u64, get: &dyn Fn(Col) -> Cell<'c>) -> Result<()> {
        let clip_id = self.text(row, Col::ClipId, get(Col::ClipId), false)?;
        let scenario = self
            .text(row, Col::Scenario, get(Col::Scenario), false)?
            .trim();
        let cond_name = self
            .text(row, Col::Condition, get(Col::Condition), false)?
            .trim();
        let ade_clean = self.distance(row, Col::AdeClean, get(Col::AdeClean))?;
        let ade_attacked = self.distance(row, Col::AdeAttacked, get(Col::AdeAttacked))?;
        let l2 = self.distance(row, Col::L2, get(Col::L2))?;
        let coc_clean = self.text(row, Col::CocClean, get(Col::CocClean), true)?;
        let coc_attacked = self.text(row, Col::CocAttacked, get(Col::CocAttacked), true)?;

        // Condition: explicit family/level win over the name's grid meaning.
        let last = self.last;
        let cond = match last
            .filter(|l| self.conditions[l.2 as usize].name == cond_name)
            .map(|l| l.2)
            .or_else(|| self.condition_index.get(cond_name).copied())
        {
            Some(c) => {
                self.check_condition_consistent(row, c, get)?;
                c
            }
            None => {
                let info = self.condition_info(row, cond_name, get)?;
                let c = self.conditions.len() as u32;
                self.conditions.push(info);
                self.condition_first_row.push(row);
                self.condition_index.insert(cond_name.to_string(), c);
                c
            }
        };

        let scen = match last
            .filter(|l| self.scenarios[l.1 as usize] == scenario)
            .map(|l| l.1)
            .or_else(|| self.scenario_index.get(scenario).copied())
        {
            Some(s) => s,
            None => {
                let s = self.scenarios.len() as u32;
                self.scenarios.push(scenario.to_string());
                self.scenario_index.insert(scenario.to_string(), s);
                s
            }
        };
        let clip = match last
            .filter(|l| self.clip_ids[l.0 as usize] == clip_id)
            .map(|l| l.0)
            .or_else(|| self.clip_index.get(clip_id).copied())
        {
            Some(k) => {
                if self.clip_scenario[k as usize] != scen {
                    return Err(EnvelopeError::ScenarioConflict {
                        path: self.path.clone(),
                        row,
                        clip_id: clip_id.to_string(),
                        first: self.scenarios[self.clip_scenario[k as usize] as usize].clone(),
                        second: scenario.to_string(),
                    });
                }
                k
            }
            None => {
                let k = self.clip_ids.len() as u32;
                self.clip_ids.push(clip_id.to_string());
                self.clip_scenario.push(scen);
                self.clip_first_row.push(row);
                self.clip_mask.push(Vec::new());
                self.clip_index.insert(clip_id.to_string(), k);
                k
            }
        };
        let (word, bit) = (cond as usize / 64, cond as usize % 64);
        let mask = &mut self.clip_mask[clip as usize];
        if mask.len() <= word {
            mask.resize(word + 1, 0);
        }
        if mask[word] & (1 << bit) != 0 {
            let first_row = self
                .clip
                .iter()
                .zip(&self.condition)
                .position(|(&k, &c)| k == clip && c == cond)
                .map_or(0, |i| self.rows[i]);
            return Err(EnvelopeError::DuplicatePair {
                path: self.path.clone(),
                row,
                first_row,
                clip_id: clip_id.to_string(),
                condition: cond_name.to_string(),
            });
        }
        mask[word] |= 1 << bit;
        self.last = Some((clip, scen, cond));

        let mut f = TextFeatures::compute(
            coc_clean,
            coc_attacked,
            &self.opts.actions,
            &mut self.scratch,
        );
        match get(Col::CocChanged) {
            Cell::Null => {}
            Cell::Bool(b) => f.changed = b,
            Cell::Num(x) if x == 0.0 || x == 1.0 => f.changed = x == 1.0,
            c @ Cell::Str(s) => match s.trim().to_ascii_lowercase().as_str() {
                "" => {}
                "true" | "1" | "yes" | "t" => f.changed = true,
                "false" | "0" | "no" | "f" => f.changed = false,
                _ => return Err(self.bad(row, Col::CocChanged, &c, "true/false or 1/0")),
            },
            c => return Err(self.bad(row, Col::CocChanged, &c, "true/false or 1/0")),
        }
        match get(Col::Jaccard) {
            Cell::Null => {}
            Cell::Str(s) if s.trim().is_empty() => {}
            c => {
                let j = self.number(row, Col::Jaccard, c)?;
                if !(0.0..=1.0).contains(&j) {
                    return Err(self.bad(row, Col::Jaccard, &c, "a similarity in [0, 1]"));
                }
                f.jaccard = j;
            }
        }

        let cosine = match get(Col::Cosine) {
            Cell::Null => None,
            Cell::Str(s) if s.trim().is_empty() => None,
            c => {
                let v = self.number(row, Col::Cosine, c)?;
                // f32 embeddings can put a cosine a hair beyond ±1.
                if !(-1.0 - 1e-6..=1.0 + 1e-6).contains(&v) {
                    return Err(self.bad(row, Col::Cosine, &c, "a cosine similarity in [-1, 1]"));
                }
                Some(v.clamp(-1.0, 1.0))
            }
        };

        self.rows.push(row);
        if self.rows.len().is_multiple_of(2_000_000) {
            log::info!("{}: {} rows read", self.path.display(), self.rows.len());
        }
        self.clip.push(clip);
        self.condition.push(cond);
        self.ade_clean.push(ade_clean);
        self.ade_attacked.push(ade_attacked);
        self.l2.push(l2);
        self.changed.push(f.changed);
        self.jaccard.push(f.jaccard);
        self.cosine.push(cosine);
        self.action_clean.push(f.action_clean as u16);
        self.action_attacked.push(f.action_attacked as u16);
        Ok(())
    }

    fn explicit_family_level<'c>(
        &self,
        row: u64,
        get: &dyn Fn(Col) -> Cell<'c>,
    ) -> Result<Option<(Family, f64)>> {
        let fam = match get(Col::Family) {
            Cell::Str(s) if !s.trim().is_empty() => Some(s.trim()),
            _ => None,
        };
        let lvl_cell = get(Col::Level);
        let lvl_present = !matches!(lvl_cell, Cell::Null)
            && !matches!(lvl_cell, Cell::Str(s) if s.trim().is_empty());
        match (fam, lvl_present) {
            (None, false) => Ok(None),
            (Some(f), true) => Ok(Some((
                Family::from_name(f),
                self.number(row, Col::Level, lvl_cell)?,
            ))),
            (Some(_), false) => {
                Err(self.bad(row, Col::Level, &lvl_cell, "a level next to the family"))
            }
            (None, true) => Err(self.bad(
                row,
                Col::Family,
                &get(Col::Family),
                "a family next to the level",
            )),
        }
    }

    fn condition_info<'c>(
        &self,
        row: u64,
        name: &str,
        get: &dyn Fn(Col) -> Cell<'c>,
    ) -> Result<ConditionInfo> {
        if let Some((family, level)) = self.explicit_family_level(row, get)? {
            return Ok(ConditionInfo {
                name: name.to_string(),
                family,
                level,
            });
        }
        match Condition::parse(name) {
            Ok(c) => Ok(ConditionInfo {
                name: c.name,
                family: c.family,
                level: c.level,
            }),
            Err(e) => Err(EnvelopeError::BadValue {
                path: self.path.clone(),
                row,
                column: Col::Condition.name().to_string(),
                value: name.to_string(),
                expected: format!(
                    "a condition name of the paper's grid ({e}), or `family` and `level` columns"
                )
                .replace(&format!("condition {name:?} is not one of "), ""),
            }),
        }
    }

    fn check_condition_consistent<'c>(
        &self,
        row: u64,
        c: u32,
        get: &dyn Fn(Col) -> Cell<'c>,
    ) -> Result<()> {
        if let Some((family, level)) = self.explicit_family_level(row, get)? {
            let known = &self.conditions[c as usize];
            if known.family != family || known.level != level {
                return Err(EnvelopeError::BadValue {
                    path: self.path.clone(),
                    row,
                    column: "family/level".into(),
                    value: format!("{family}/{level}"),
                    expected: format!(
                        "{}/{} as for condition {:?} at row {}",
                        known.family, known.level, known.name, self.condition_first_row[c as usize]
                    ),
                });
            }
        }
        Ok(())
    }

    fn finish(self, mut input: InputInfo) -> Result<PairTable> {
        if self.clip.is_empty() {
            return Err(EnvelopeError::Empty { path: self.path });
        }
        let n_cond = self.conditions.len();
        let mut incomplete = Vec::new();
        for (k, mask) in self.clip_mask.iter().enumerate() {
            let have: usize = mask.iter().map(|w| w.count_ones() as usize).sum();
            if have < n_cond {
                incomplete.push(k);
            }
        }
        if !incomplete.is_empty() && !self.opts.allow_incomplete {
            let examples = incomplete
                .iter()
                .take(3)
                .map(|&k| {
                    let mask = &self.clip_mask[k];
                    let missing: Vec<&str> = (0..n_cond)
                        .filter(|&c| mask.get(c / 64).is_none_or(|w| w & (1 << (c % 64)) == 0))
                        .map(|c| self.conditions[c].name.as_str())
                        .collect();
                    format!(
                        "{} (row {}): missing {}",
                        self.clip_ids[k],
                        self.clip_first_row[k],
                        missing.join(", ")
                    )
                })
                .collect::<Vec<_>>()
                .join("; ");
            return Err(EnvelopeError::IncompleteClips {
                path: self.path,
                n_incomplete: incomplete.len(),
                n_clips: self.clip_ids.len(),
                examples,
            });
        }
        input.n_rows = self.clip.len();
        Ok(PairTable {
            input,
            clip_ids: self.clip_ids,
            clip_scenario: self.clip_scenario,
            scenarios: self.scenarios,
            conditions: self.conditions,
            action_labels: self.opts.actions.labels(),
            clip: self.clip,
            condition: self.condition,
            ade_clean_m: self.ade_clean,
            ade_attacked_m: self.ade_attacked,
            l2_m: self.l2,
            changed: self.changed,
            jaccard: self.jaccard,
            cosine: self.cosine,
            action_clean: self.action_clean,
            action_attacked: self.action_attacked,
            n_incomplete_clips: incomplete.len(),
        })
    }
}

fn looks_like(head: &[u8]) -> &'static str {
    if head.starts_with(b"PAR1") {
        "it looks like Parquet"
    } else if head.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{') {
        "it looks like JSON"
    } else if head.contains(&0) || std::str::from_utf8(head).is_err() {
        "it looks like binary data"
    } else {
        "it looks like text in another layout"
    }
}

// ---------------------------------------------------------------------------------------------
// CSV

fn read_csv<R: Read>(src: R, b: &mut Builder<'_>) -> Result<()> {
    let mut src = BufReader::with_capacity(1 << 20, src);
    let head = src.fill_buf().map_err(|source| EnvelopeError::Io {
        path: b.path.clone(),
        source,
    })?;
    let head: Vec<u8> = head[..head.len().min(4096)].to_vec();
    let path = b.path.clone();
    let not_csv = |detail: String| EnvelopeError::NotFormat {
        path: path.clone(),
        expected: Format::Csv.label(),
        detail,
    };
    if head.starts_with(b"PAR1") || head.first() == Some(&b'{') || head.contains(&0) {
        return Err(not_csv(looks_like(&head).to_string()));
    }
    let mut rdr = csv::ReaderBuilder::new().has_headers(true).from_reader(src);
    let headers = rdr
        .byte_headers()
        .map_err(|e| not_csv(format!("header: {e}")))?
        .clone();
    let header_strs: Vec<&str> = headers
        .iter()
        .map(std::str::from_utf8)
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| {
            not_csv(format!(
                "the header row is not UTF-8 text; {}",
                looks_like(&head)
            ))
        })?;
    if header_strs.len() < 2 {
        return Err(not_csv(format!(
            "the header row has {} column(s); {}",
            header_strs.len(),
            looks_like(&head)
        )));
    }
    let map = map_header(&b.path, header_strs.iter().copied())?;
    let mut rec = csv::ByteRecord::new();
    loop {
        match rdr.read_byte_record(&mut rec) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => {
                let line = e.position().map_or(0, |p| p.line());
                return Err(not_csv(format!("line {line}: {e}")));
            }
        }
        let line = rec.position().map_or(0, |p| p.line());
        let mut cells: [Cell<'_>; N_COLS] = [Cell::Null; N_COLS];
        for (k, slot) in map.iter().enumerate() {
            if let Some(i) = slot {
                let raw = rec.get(*i).unwrap_or_default();
                cells[k] = match std::str::from_utf8(raw) {
                    Ok(s) => Cell::Str(s),
                    Err(_) => {
                        return Err(EnvelopeError::BadValue {
                            path: b.path.clone(),
                            row: line,
                            column: header_strs[*i].to_string(),
                            value: String::from_utf8_lossy(raw).chars().take(60).collect(),
                            expected: "UTF-8 text".into(),
                        });
                    }
                };
            }
        }
        b.push(line, &|c| cells[c as usize])?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// JSON lines

fn read_jsonl<R: Read>(src: R, b: &mut Builder<'_>) -> Result<()> {
    let mut src = BufReader::with_capacity(1 << 20, src);
    let mut line = String::new();
    let mut line_no = 0u64;
    let mut map: Option<[Option<String>; N_COLS]> = None;
    loop {
        line.clear();
        let n = match src.read_line(&mut line) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                return Err(EnvelopeError::NotFormat {
                    path: b.path.clone(),
                    expected: Format::Jsonl.label(),
                    detail: format!("line {}: not UTF-8 text", line_no + 1),
                });
            }
            Err(source) => {
                return Err(EnvelopeError::Io {
                    path: b.path.clone(),
                    source,
                });
            }
        };
        if n == 0 {
            break;
        }
        line_no += 1;
        if line.trim().is_empty() {
            continue;
        }
        let obj: serde_json::Map<String, serde_json::Value> = match serde_json::from_str(&line) {
            Ok(serde_json::Value::Object(o)) => o,
            Ok(_) | Err(_) => {
                let detail = match serde_json::from_str::<serde_json::Value>(&line) {
                    Ok(_) => "expected one JSON object per line".to_string(),
                    Err(e) => e.to_string(),
                };
                let detail = if line_no == 1 {
                    format!("line 1: {detail}; {}", looks_like(line.as_bytes()))
                } else {
                    format!("line {line_no}: {detail}")
                };
                return Err(EnvelopeError::NotFormat {
                    path: b.path.clone(),
                    expected: Format::Jsonl.label(),
                    detail,
                });
            }
        };
        if map.is_none() {
            let idx = map_header(&b.path, obj.keys().map(String::as_str))?;
            let keys: Vec<&String> = obj.keys().collect();
            map = Some(std::array::from_fn(|k| idx[k].map(|i| keys[i].clone())));
        }
        let Some(keys) = &map else { continue };
        let cell_of = |c: Col| -> Cell<'_> {
            let key = keys[c as usize].as_deref();
            match key.and_then(|k| obj.get(k)) {
                None | Some(serde_json::Value::Null) => Cell::Null,
                Some(serde_json::Value::String(s)) => Cell::Str(s),
                Some(serde_json::Value::Number(x)) => x.as_f64().map_or(Cell::Null, Cell::Num),
                Some(serde_json::Value::Bool(v)) => Cell::Bool(*v),
                Some(_) => Cell::Str("<array or object>"),
            }
        };
        for c in REQUIRED {
            if matches!(cell_of(c), Cell::Null) {
                return Err(b.bad(
                    line_no,
                    c,
                    &Cell::Null,
                    "a value (the key is missing on this line)",
                ));
            }
        }
        b.push(line_no, &cell_of)?;
    }
    Ok(())
}

/// The largest distance a pairs table may hold, m: a displacement error beyond it is not a
/// measurement of a 6.4 s trajectory but a corrupt value.
pub const MAX_DISTANCE_M: f64 = 100_000.0;

// ---------------------------------------------------------------------------------------------
// Parquet

fn read_parquet<T: parquet::file::reader::ChunkReader + 'static>(
    src: T,
    b: &mut Builder<'_>,
) -> Result<()> {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

    let path = b.path.clone();
    let not_parquet = |detail: String| EnvelopeError::NotFormat {
        path: path.clone(),
        expected: Format::Parquet.label(),
        detail,
    };
    let builder =
        // Ignore the embedded Arrow schema so dictionary-encoded (e.g. pandas categorical)
        // text columns decode as plain strings.
        ParquetRecordBatchReaderBuilder::try_new_with_options(
            src,
            parquet::arrow::arrow_reader::ArrowReaderOptions::new().with_skip_arrow_metadata(true),
        )
        .map_err(|e| not_parquet(e.to_string()))?;
    let schema = builder.schema().clone();
    let reader = builder
        .with_batch_size(65_536)
        .build()
        .map_err(|e| not_parquet(e.to_string()))?;
    push_batches(
        b,
        &schema,
        reader.map(|r| r.map_err(|e| not_parquet(e.to_string()))),
        None,
    )
}

/// Reads a pairs table from Arrow record batches in memory: a pandas or polars DataFrame or
/// a pyarrow Table handed over through the Arrow C stream interface, or batches a Rust
/// caller holds. The columns and their validation are the file readers'; rows are numbered
/// from 1 across batches, and `name` stands for the file in messages. The input's `sha256`
/// is a digest of the cells read (text, numbers, booleans and nulls of the mapped columns),
/// so the same data gives the same digest however it is chunked.
pub fn read_pairs_arrow<E: std::fmt::Display>(
    name: &str,
    schema: &arrow_schema::Schema,
    batches: impl IntoIterator<Item = std::result::Result<arrow_array::RecordBatch, E>>,
    opts: &ReadOptions,
) -> Result<PairTable> {
    let path = Path::new(name);
    let mut b = Builder::new(path, opts);
    let bad = |e: E| EnvelopeError::NotFormat {
        path: path.to_path_buf(),
        expected: Format::Arrow.label(),
        detail: e.to_string(),
    };
    let mut hasher = Sha256::new();
    push_batches(
        &mut b,
        schema,
        batches.into_iter().map(|r| r.map_err(bad)),
        Some(&mut hasher),
    )?;
    b.finish(InputInfo {
        path: name.to_string(),
        format: Format::Arrow,
        sha256: hex(&hasher.finalize()),
        n_rows: 0,
    })
}

/// Pushes the rows of record batches of `schema` into `b` (and their cells into `digest`).
fn push_batches(
    b: &mut Builder<'_>,
    schema: &arrow_schema::Schema,
    batches: impl Iterator<Item = Result<arrow_array::RecordBatch>>,
    mut digest: Option<&mut Sha256>,
) -> Result<()> {
    use arrow_array::{Array, cast::AsArray};
    use arrow_schema::DataType;

    let map = map_header(&b.path, schema.fields().iter().map(|f| f.name().as_str()))?;
    let mut row0 = 0u64;
    for batch in batches {
        let batch = batch?;
        if batch.num_columns() != schema.fields().len() {
            return Err(EnvelopeError::NotFormat {
                path: b.path.clone(),
                expected: Format::Arrow.label(),
                detail: format!(
                    "a batch has {} columns where the schema has {}",
                    batch.num_columns(),
                    schema.fields().len()
                ),
            });
        }
        let cols: Vec<Option<&dyn Array>> = map
            .iter()
            .map(|m| m.map(|i| batch.column(i).as_ref()))
            .collect();
        for (k, col) in cols.iter().enumerate() {
            if let Some(a) = col {
                let ok = matches!(
                    a.data_type(),
                    DataType::Utf8
                        | DataType::LargeUtf8
                        | DataType::Utf8View
                        | DataType::Float64
                        | DataType::Float32
                        | DataType::Int64
                        | DataType::Int32
                        | DataType::Int16
                        | DataType::Int8
                        | DataType::UInt64
                        | DataType::UInt32
                        | DataType::UInt16
                        | DataType::UInt8
                        | DataType::Boolean
                        | DataType::Null
                );
                if !ok {
                    return Err(EnvelopeError::BadValue {
                        path: b.path.clone(),
                        row: row0 + 1,
                        column: schema.field(map[k].unwrap_or_default()).name().clone(),
                        value: format!("a column of type {}", a.data_type()),
                        expected: "text, numbers or booleans".into(),
                    });
                }
            }
        }
        fn cell(a: &dyn Array, i: usize) -> Cell<'_> {
            if a.is_null(i) {
                return Cell::Null;
            }
            match a.data_type() {
                DataType::Utf8 => Cell::Str(a.as_string::<i32>().value(i)),
                DataType::LargeUtf8 => Cell::Str(a.as_string::<i64>().value(i)),
                DataType::Utf8View => Cell::Str(a.as_string_view().value(i)),
                DataType::Float64 => {
                    Cell::Num(a.as_primitive::<arrow_array::types::Float64Type>().value(i))
                }
                DataType::Float32 => Cell::Num(f64::from(
                    a.as_primitive::<arrow_array::types::Float32Type>().value(i),
                )),
                DataType::Int64 => {
                    Cell::Num(a.as_primitive::<arrow_array::types::Int64Type>().value(i) as f64)
                }
                DataType::Int32 => Cell::Num(f64::from(
                    a.as_primitive::<arrow_array::types::Int32Type>().value(i),
                )),
                DataType::Int16 => Cell::Num(f64::from(
                    a.as_primitive::<arrow_array::types::Int16Type>().value(i),
                )),
                DataType::Int8 => Cell::Num(f64::from(
                    a.as_primitive::<arrow_array::types::Int8Type>().value(i),
                )),
                DataType::UInt64 => {
                    Cell::Num(a.as_primitive::<arrow_array::types::UInt64Type>().value(i) as f64)
                }
                DataType::UInt32 => Cell::Num(f64::from(
                    a.as_primitive::<arrow_array::types::UInt32Type>().value(i),
                )),
                DataType::UInt16 => Cell::Num(f64::from(
                    a.as_primitive::<arrow_array::types::UInt16Type>().value(i),
                )),
                DataType::UInt8 => Cell::Num(f64::from(
                    a.as_primitive::<arrow_array::types::UInt8Type>().value(i),
                )),
                DataType::Boolean => Cell::Bool(a.as_boolean().value(i)),
                _ => Cell::Null,
            }
        }
        for i in 0..batch.num_rows() {
            let row = row0 + i as u64 + 1;
            let get = |c: Col| cols[c as usize].map_or(Cell::Null, |a| cell(a, i));
            if let Some(h) = digest.as_deref_mut() {
                for c in cols.iter().flatten() {
                    match cell(*c, i) {
                        Cell::Null => h.update([0u8]),
                        Cell::Str(v) => {
                            h.update([1u8]);
                            h.update((v.len() as u64).to_le_bytes());
                            h.update(v.as_bytes());
                        }
                        Cell::Num(v) => {
                            h.update([2u8]);
                            h.update(v.to_bits().to_le_bytes());
                        }
                        Cell::Bool(v) => h.update([3u8, u8::from(v)]),
                    }
                }
            }
            b.push(row, &get)?;
        }
        row0 += batch.num_rows() as u64;
    }
    Ok(())
}
