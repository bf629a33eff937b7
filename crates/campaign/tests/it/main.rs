//! Campaign integration tests: determinism, resume, shards and merge, failures recorded.
#![allow(clippy::unwrap_used)]

mod faults;
mod runs;
mod similarity;

use std::path::Path;

use fogline_campaign::export::{ExportSummary, Formats, ParquetCodec, export};
use fogline_campaign::store::RunRecord;

/// Exports `runs` into `dir` as CSV and Parquet (the default codec), without timing columns.
fn export_all(runs: &[RunRecord], dir: &Path) -> ExportSummary {
    let formats = Formats {
        csv: true,
        parquet: true,
        codec: ParquetCodec::default(),
    };
    export(runs, dir, formats, false).unwrap()
}
