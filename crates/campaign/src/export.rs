//! Export: the runs table and the clean-vs-perturbed pairs table (the input of
//! `fogline envelope`), as CSV and Parquet, written atomically and sorted, so the same store
//! always gives byte-identical files.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, RecordBatch, StringArray, UInt64Array};
use arrow_schema::{DataType, Field, Schema};
use fogline_perturb::Perturbation;
use fogline_types::clip::Trajectory;

use crate::CampaignError;
use crate::store::{Outcome, RunRecord};

/// A column of an exported table.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// Text.
    Str(Vec<Option<String>>),
    /// Real numbers.
    F64(Vec<Option<f64>>),
    /// Counts and seeds.
    U64(Vec<Option<u64>>),
}

impl Column {
    fn len(&self) -> usize {
        match self {
            Column::Str(v) => v.len(),
            Column::F64(v) => v.len(),
            Column::U64(v) => v.len(),
        }
    }

    fn cell(&self, i: usize) -> String {
        match self {
            Column::Str(v) => v[i].clone().unwrap_or_default(),
            Column::F64(v) => v[i].map(|x| format!("{x}")).unwrap_or_default(),
            Column::U64(v) => v[i].map(|x| x.to_string()).unwrap_or_default(),
        }
    }
}

/// A table: named columns of equal length.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// `(name, column)` in order.
    pub columns: Vec<(&'static str, Column)>,
}

impl Table {
    /// The number of rows.
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, |(_, c)| c.len())
    }

    /// The table as CSV (header row; empty cells for missing values).
    pub fn write_csv(&self, w: impl Write) -> Result<(), String> {
        let mut out = csv::Writer::from_writer(w);
        out.write_record(self.columns.iter().map(|(n, _)| *n))
            .map_err(|e| e.to_string())?;
        for i in 0..self.rows() {
            out.write_record(self.columns.iter().map(|(_, c)| c.cell(i)))
                .map_err(|e| e.to_string())?;
        }
        out.flush().map_err(|e| e.to_string())
    }

    /// The table as one Arrow record batch.
    pub fn to_arrow(&self) -> Result<RecordBatch, String> {
        let mut fields = Vec::new();
        let mut arrays: Vec<ArrayRef> = Vec::new();
        for (name, col) in &self.columns {
            let (dt, nullable, array): (DataType, bool, ArrayRef) = match col {
                Column::Str(v) => (
                    DataType::Utf8,
                    v.iter().any(Option::is_none),
                    Arc::new(StringArray::from(v.clone())),
                ),
                Column::F64(v) => (
                    DataType::Float64,
                    v.iter().any(Option::is_none),
                    Arc::new(Float64Array::from(v.clone())),
                ),
                Column::U64(v) => (
                    DataType::UInt64,
                    v.iter().any(Option::is_none),
                    Arc::new(UInt64Array::from(v.clone())),
                ),
            };
            fields.push(Field::new(*name, dt, nullable));
            arrays.push(array);
        }
        RecordBatch::try_new(Arc::new(Schema::new(fields)), arrays).map_err(|e| e.to_string())
    }

    /// The table as a Parquet file compressed with `codec`.
    pub fn write_parquet(&self, w: impl Write + Send, codec: ParquetCodec) -> Result<(), String> {
        let batch = self.to_arrow()?;
        let props = parquet::file::properties::WriterProperties::builder()
            .set_compression(codec.compression())
            .set_created_by(format!("fogline {}", env!("CARGO_PKG_VERSION")))
            .build();
        let mut writer = parquet::arrow::ArrowWriter::try_new(w, batch.schema(), Some(props))
            .map_err(|e| e.to_string())?;
        writer.write(&batch).map_err(|e| e.to_string())?;
        writer.close().map_err(|e| e.to_string())?;
        Ok(())
    }
}

/// The family and level of a condition as the pairs table names them: single steps by their
/// family and level (`noise_30` → `gaussian_noise`, 30), the clean reference as `clean` 0, a
/// chain as its own family (its name) at level 1.
pub fn family_level(condition: &str) -> (String, f64) {
    match Perturbation::parse(condition) {
        Ok(p) if p.is_identity() => ("clean".into(), 0.0),
        Ok(p) => match p.condition() {
            Some(c) => (c.family.name().to_string(), c.level),
            None => (p.name.clone(), 1.0),
        },
        Err(_) => (condition.to_string(), 1.0),
    }
}

/// The runs table: one row per run, successful or failed. With `timing`, the last call's
/// wall time and the attempts are added (they differ between runs of the same campaign).
pub fn runs_table(runs: &[RunRecord], timing: bool) -> Table {
    let mut fl: HashMap<&str, (String, f64)> = HashMap::new();
    for r in runs {
        fl.entry(&r.condition)
            .or_insert_with(|| family_level(&r.condition));
    }
    let s = |f: &dyn Fn(&RunRecord) -> Option<String>| Column::Str(runs.iter().map(f).collect());
    let x = |f: &dyn Fn(&RunRecord) -> Option<f64>| Column::F64(runs.iter().map(f).collect());
    let ok = |r: &RunRecord| match &r.outcome {
        Outcome::Ok {
            explanation,
            decision,
            ade_m,
            fde_m,
            ..
        } => Some((explanation.clone(), decision.clone(), *ade_m, *fde_m)),
        Outcome::Failed { .. } => None,
    };
    let failed = |r: &RunRecord| match &r.outcome {
        Outcome::Failed { kind, reason } => Some((kind.clone(), reason.clone())),
        Outcome::Ok { .. } => None,
    };
    let mut columns = vec![
        ("clip_id", s(&|r| Some(r.clip_id.clone()))),
        (
            "clip_index",
            Column::U64(runs.iter().map(|r| Some(r.clip_index as u64)).collect()),
        ),
        ("scenario", s(&|r| Some(r.scenario.clone()))),
        ("condition", s(&|r| Some(r.condition.clone()))),
        ("family", s(&|r| Some(fl[r.condition.as_str()].0.clone()))),
        ("level", x(&|r| Some(fl[r.condition.as_str()].1))),
        (
            "seed",
            Column::U64(runs.iter().map(|r| Some(r.seed)).collect()),
        ),
        (
            "status",
            s(&|r| Some(if ok(r).is_some() { "ok" } else { "failed" }.to_string())),
        ),
        ("failure_kind", s(&|r| failed(r).map(|f| f.0))),
        ("reason", s(&|r| failed(r).map(|f| f.1))),
        ("decision", s(&|r| ok(r).and_then(|o| o.1))),
        ("expert_decision", s(&|r| r.expert_decision.clone())),
        ("ade", x(&|r| ok(r).map(|o| o.2))),
        ("fde", x(&|r| ok(r).map(|o| o.3))),
        ("explanation", s(&|r| ok(r).map(|o| o.0))),
    ];
    if timing {
        columns.push((
            "attempts",
            Column::U64(runs.iter().map(|r| Some(r.attempts as u64)).collect()),
        ));
        columns.push(("latency_ms", x(&|r| Some(r.latency_ms))));
    }
    Table { columns }
}

/// What the pairs table left out, and why.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PairCounts {
    /// Pairs written.
    pub pairs: usize,
    /// Perturbed runs left out because they failed.
    pub attacked_failed: usize,
    /// Perturbed runs left out because their clean run failed.
    pub clean_failed: usize,
    /// Perturbed runs left out because their clean run is not in the store (yet).
    pub clean_missing: usize,
    /// Pairs with a `coc_cosine` (both runs' explanations embedded).
    pub with_cosine: usize,
}

/// The pairs table of `seed`: one row per (clip, perturbed condition) whose perturbed and
/// clean runs both succeeded — `ade_clean`/`ade_attacked` against the ground truth, `l2` the
/// Euclidean norm of the stacked xy difference of the two predictions, `coc_cosine` the
/// cosine similarity of the two explanations' sentence embeddings (empty where either run
/// has none; [`crate::similarity`]) — in the column contract of `docs/envelope.md`.
pub fn pairs_table(runs: &[RunRecord], seed: u64) -> (Table, PairCounts) {
    let clean: HashMap<u32, &RunRecord> = runs
        .iter()
        .filter(|r| r.seed == seed && r.condition_index == 0)
        .map(|r| (r.clip_index, r))
        .collect();
    let mut counts = PairCounts::default();
    let mut rows: Vec<(&RunRecord, &RunRecord)> = Vec::new();
    for r in runs
        .iter()
        .filter(|r| r.seed == seed && r.condition_index != 0)
    {
        let Outcome::Ok { .. } = r.outcome else {
            counts.attacked_failed += 1;
            continue;
        };
        match clean.get(&r.clip_index) {
            None => counts.clean_missing += 1,
            Some(c) if matches!(c.outcome, Outcome::Failed { .. }) => counts.clean_failed += 1,
            Some(c) => rows.push((c, r)),
        }
    }
    counts.pairs = rows.len();
    let parts = |r: &RunRecord| match &r.outcome {
        Outcome::Ok {
            trajectory,
            explanation,
            decision,
            ade_m,
            ..
        } => (
            trajectory.clone(),
            explanation.clone(),
            decision.clone(),
            *ade_m,
        ),
        Outcome::Failed { .. } => (Vec::new(), String::new(), None, f64::NAN),
    };
    fn embedding(r: &RunRecord) -> Option<&[f32]> {
        match &r.outcome {
            Outcome::Ok {
                embedding: Some(e), ..
            } => Some(e.as_slice()),
            _ => None,
        }
    }
    let mut fl: HashMap<&str, (String, f64)> = HashMap::new();
    let mut col_s: [Vec<Option<String>>; 9] = Default::default();
    let mut col_f: [Vec<Option<f64>>; 4] = Default::default();
    let mut cosines = Vec::new();
    let mut seeds = Vec::new();
    for (c, a) in &rows {
        let cosine = embedding(c)
            .zip(embedding(a))
            .map(|(x, y)| fogline_embed::cosine(x, y));
        counts.with_cosine += usize::from(cosine.is_some());
        cosines.push(cosine);
        let (tc, ec, dc, adec) = parts(c);
        let (ta, ea, da, adea) = parts(a);
        let (family, level) = fl
            .entry(&a.condition)
            .or_insert_with(|| family_level(&a.condition))
            .clone();
        let l2 = Trajectory { xy: tc }.l2(&Trajectory { xy: ta });
        for (k, v) in [
            Some(a.clip_id.clone()),
            Some(a.scenario.clone()),
            Some(a.condition.clone()),
            Some(family),
            Some(ec),
            Some(ea),
            dc,
            da,
            a.expert_decision.clone(),
        ]
        .into_iter()
        .enumerate()
        {
            col_s[k].push(v);
        }
        for (k, v) in [level, adec, adea, l2].into_iter().enumerate() {
            col_f[k].push(Some(v));
        }
        seeds.push(Some(a.seed));
    }
    let [
        clip_id,
        scenario,
        condition,
        family,
        coc_clean,
        coc_attacked,
        dec_c,
        dec_a,
        expert,
    ] = col_s;
    let [level, ade_clean, ade_attacked, l2] = col_f;
    let table = Table {
        columns: vec![
            ("clip_id", Column::Str(clip_id)),
            ("scenario", Column::Str(scenario)),
            ("condition", Column::Str(condition)),
            ("family", Column::Str(family)),
            ("level", Column::F64(level)),
            ("seed", Column::U64(seeds)),
            ("ade_clean", Column::F64(ade_clean)),
            ("ade_attacked", Column::F64(ade_attacked)),
            ("l2", Column::F64(l2)),
            ("coc_clean", Column::Str(coc_clean)),
            ("coc_attacked", Column::Str(coc_attacked)),
            ("coc_cosine", Column::F64(cosines)),
            ("decision_clean", Column::Str(dec_c)),
            ("decision_attacked", Column::Str(dec_a)),
            ("expert_decision", Column::Str(expert)),
        ],
    };
    (table, counts)
}

/// The compression of the Parquet files written: every codec the readers of fogline's
/// users write (pyarrow and pandas default to Snappy, polars to zstd). Reading accepts all
/// of them whatever this is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ParquetCodec {
    /// zstd at level 3 (the default, as polars writes).
    #[default]
    Zstd,
    /// Snappy.
    Snappy,
    /// gzip at level 6.
    Gzip,
    /// LZ4 (the raw block format of current Parquet writers).
    Lz4,
    /// Brotli at level 1.
    Brotli,
    /// Uncompressed.
    None,
}

impl ParquetCodec {
    /// Every codec, in the order their names are listed.
    pub const ALL: [ParquetCodec; 6] = [
        ParquetCodec::Zstd,
        ParquetCodec::Snappy,
        ParquetCodec::Gzip,
        ParquetCodec::Lz4,
        ParquetCodec::Brotli,
        ParquetCodec::None,
    ];

    /// Its name: `zstd`, `snappy`, `gzip`, `lz4`, `brotli`, `none`.
    pub fn name(self) -> &'static str {
        match self {
            ParquetCodec::Zstd => "zstd",
            ParquetCodec::Snappy => "snappy",
            ParquetCodec::Gzip => "gzip",
            ParquetCodec::Lz4 => "lz4",
            ParquetCodec::Brotli => "brotli",
            ParquetCodec::None => "none",
        }
    }

    /// The writer's setting.
    pub fn compression(self) -> parquet::basic::Compression {
        use parquet::basic::{BrotliLevel, Compression, GzipLevel, ZstdLevel};
        match self {
            ParquetCodec::Zstd => Compression::ZSTD(ZstdLevel::default()),
            ParquetCodec::Snappy => Compression::SNAPPY,
            ParquetCodec::Gzip => Compression::GZIP(GzipLevel::default()),
            ParquetCodec::Lz4 => Compression::LZ4_RAW,
            ParquetCodec::Brotli => Compression::BROTLI(BrotliLevel::default()),
            ParquetCodec::None => Compression::UNCOMPRESSED,
        }
    }
}

impl std::str::FromStr for ParquetCodec {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                format!("{s:?} is not a Parquet codec (expected zstd, snappy, gzip, lz4, brotli or none)")
            })
    }
}

/// The output formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Formats {
    /// Write `.csv`.
    pub csv: bool,
    /// Write `.parquet`.
    pub parquet: bool,
    /// The Parquet files' compression.
    pub codec: ParquetCodec,
}

impl Formats {
    /// Parses `csv`, `parquet` or `csv,parquet`; `parquet:CODEC` picks the Parquet
    /// compression ([`ParquetCodec`]; zstd by default).
    pub fn parse(s: &str) -> Result<Self, String> {
        let mut f = Formats {
            csv: false,
            parquet: false,
            codec: ParquetCodec::default(),
        };
        for part in s.split(',').map(str::trim) {
            match part.split_once(':') {
                None if part == "csv" => f.csv = true,
                None if part == "parquet" => f.parquet = true,
                Some(("parquet", codec)) => {
                    f.parquet = true;
                    f.codec = codec.parse().map_err(|e| format!("--format: {e}"))?;
                }
                _ => {
                    return Err(format!(
                        "--format: {part:?} is not a format (expected csv, parquet, parquet:CODEC or a comma-separated list)"
                    ));
                }
            }
        }
        Ok(f)
    }
}

/// What [`export`] wrote.
#[derive(Debug, Clone, Default)]
pub struct ExportSummary {
    /// Every file written.
    pub files: Vec<PathBuf>,
    /// Runs exported.
    pub runs: usize,
    /// Of those, failed.
    pub failed: usize,
    /// Per seed: the pair counts.
    pub pairs: Vec<(u64, PairCounts)>,
    /// Why `coc_cosine` is empty on some pairs, when it is (the model is missing).
    pub cosine_missing: Option<String>,
}

/// Writes `runs.{csv,parquet}` and the pairs table into `dir`: `pairs.{csv,parquet}` when the
/// runs have one seed, `pairs-seed-<S>.{csv,parquet}` per seed otherwise (the envelope
/// analysis takes one run per clip and condition). Successful runs stored without an
/// explanation embedding (a store made without the model, or before fogline had one) are
/// embedded now when the model is found ([`crate::similarity::shared`]).
pub fn export(
    runs: &[RunRecord],
    dir: &Path,
    formats: Formats,
    timing: bool,
) -> Result<ExportSummary, CampaignError> {
    let mut cosine_missing = None;
    let runs = if crate::similarity::any_missing(runs) {
        match crate::similarity::shared() {
            Ok(e) => crate::similarity::fill_missing(runs, Some(&e)),
            Err(why) => {
                cosine_missing = Some(why);
                std::borrow::Cow::Borrowed(runs)
            }
        }
    } else {
        std::borrow::Cow::Borrowed(runs)
    };
    let runs: &[RunRecord] = &runs;
    std::fs::create_dir_all(dir).map_err(|e| CampaignError::Io {
        path: dir.to_path_buf(),
        source: e,
    })?;
    let mut summary = ExportSummary {
        runs: runs.len(),
        failed: runs
            .iter()
            .filter(|r| matches!(r.outcome, Outcome::Failed { .. }))
            .count(),
        cosine_missing,
        ..ExportSummary::default()
    };
    let mut seeds: Vec<u64> = runs.iter().map(|r| r.seed).collect();
    seeds.sort_unstable();
    seeds.dedup();
    let mut tables = vec![("runs".to_string(), runs_table(runs, timing))];
    for &seed in &seeds {
        let (t, counts) = pairs_table(runs, seed);
        let name = if seeds.len() == 1 {
            "pairs".to_string()
        } else {
            format!("pairs-seed-{seed}")
        };
        tables.push((name, t));
        summary.pairs.push((seed, counts));
    }
    // One set: the tables of one export are replaced together or not at all.
    let mut set = fogline_io::FileSet::new();
    for (name, table) in &tables {
        if formats.csv {
            let p = dir.join(format!("{name}.csv"));
            stage(&mut set, &p, |w| table.write_csv(w))?;
            summary.files.push(p);
        }
        if formats.parquet {
            let p = dir.join(format!("{name}.parquet"));
            stage(&mut set, &p, |w| table.write_parquet(w, formats.codec))?;
            summary.files.push(p);
        }
    }
    set.commit().map_err(|e| export_err(dir, &e))?;
    Ok(summary)
}

/// Stages `path`'s content in `set` (see [`fogline_io::FileSet`]).
fn stage(
    set: &mut fogline_io::FileSet,
    path: &Path,
    fill: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> Result<(), String>,
) -> Result<(), CampaignError> {
    set.write_with(path, |w| fill(w).map_err(std::io::Error::other))
        .map_err(|e| export_err(path, &e))
}

fn export_err(fallback: &Path, e: &std::io::Error) -> CampaignError {
    match fogline_io::atomic::WriteError::of(e) {
        Some(w) => CampaignError::Export {
            path: w.path.clone(),
            reason: w.source.to_string(),
        },
        None => CampaignError::Export {
            path: fallback.to_path_buf(),
            reason: e.to_string(),
        },
    }
}

impl ExportSummary {
    /// What `fogline campaign export` prints.
    pub fn write_text(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        let s = self;
        writeln!(out, "exported {} runs ({} failed)", s.runs, s.failed)?;
        for (seed, c) in &s.pairs {
            write!(out, "pairs (seed {seed}): {}", c.pairs)?;
            let excluded = c.attacked_failed + c.clean_failed + c.clean_missing;
            if excluded > 0 {
                write!(
                    out,
                    "; excluded {excluded}: {} failed perturbed runs, {} whose clean run failed, {} whose clean run is missing",
                    c.attacked_failed, c.clean_failed, c.clean_missing
                )?;
            }
            if c.pairs > 0 {
                write!(out, "; coc_cosine on {}", c.with_cosine)?;
            }
            writeln!(out)?;
        }
        if let Some(why) = &s.cosine_missing {
            writeln!(
                out,
                "coc_cosine is empty where runs have no embedding: {why}"
            )?;
        }
        for f in &s.files {
            writeln!(out, "wrote {}", f.display())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn families_and_levels_follow_the_condition_names() {
        assert_eq!(family_level("noise_30"), ("gaussian_noise".into(), 30.0));
        assert_eq!(family_level("dark"), ("brightness".into(), 0.4));
        assert_eq!(family_level("fog_07"), ("fog".into(), 0.7));
        assert_eq!(family_level("clean"), ("clean".into(), 0.0));
        let (f, l) = family_level("noise_30+jpeg_20");
        assert_eq!((f.as_str(), l), ("noise_30+jpeg_20", 1.0));
    }

    #[test]
    fn formats_parse() {
        assert_eq!(
            Formats::parse("csv,parquet").unwrap(),
            Formats {
                csv: true,
                parquet: true,
                codec: ParquetCodec::Zstd,
            }
        );
        assert_eq!(
            Formats::parse("parquet:brotli").unwrap(),
            Formats {
                csv: false,
                parquet: true,
                codec: ParquetCodec::Brotli,
            }
        );
        for c in ParquetCodec::ALL {
            assert_eq!(c.name().parse::<ParquetCodec>(), Ok(c));
        }
        assert!(Formats::parse("xlsx").is_err());
        assert!(Formats::parse("csv:zstd").is_err());
        let e = Formats::parse("parquet:lzo").unwrap_err();
        assert!(e.contains("\"lzo\" is not a Parquet codec"), "{e}");
    }
}
