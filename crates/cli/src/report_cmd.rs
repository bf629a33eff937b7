//! `fogline report ENVELOPE_DIR [--sim SIM_DIR] --out report.html`: the self-contained HTML
//! report of an envelope (figures as inline SVG, the paper's tables, a plain-language
//! summary, parameters, checksum and conventions), and [`write_report`], which `fogline
//! envelope` and `fogline demo` call to write it next to `envelope.json`. See
//! `docs/report.md`.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::Args;
use fogline_envelope::{Envelope, PairTable, ReadOptions};
use fogline_report::{ClosedLoop, ReportInput, ReportParams};

/// Arguments of `fogline report`.
#[derive(Args)]
pub struct ReportArgs {
    /// Directory holding `envelope.json` (as written by `fogline envelope` or `fogline demo`).
    pub envelope_dir: PathBuf,
    /// Closed-loop results: a directory holding `closed_loop.json`.
    #[arg(long, value_name = "SIM_DIR")]
    pub sim: Option<PathBuf>,
    /// The HTML file to write [default: ENVELOPE_DIR/report.html].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The pairs table the envelope was computed from, for the L2 histogram of figure 2a
    /// [default: the envelope's input path, then ENVELOPE_DIR/<its file name>; used when its
    /// checksum matches].
    #[arg(long, conflicts_with = "no_pairs")]
    pub pairs: Option<PathBuf>,
    /// Do not read the pairs table (figure 2a then shows the mixture without the histogram).
    #[arg(long)]
    pub no_pairs: bool,
    /// Page title [default: "Safety envelope — <input file name>"].
    #[arg(long)]
    pub title: Option<String>,
}

/// Runs `fogline report`: prints the path of the page it wrote.
pub fn report(a: ReportArgs) -> Result<ExitCode> {
    let json_path = a.envelope_dir.join("envelope.json");
    let text = std::fs::read_to_string(&json_path)
        .with_context(|| format!("cannot read {}", json_path.display()))?;
    let mut input = ReportInput::from_envelope_json(&text, &json_path.display().to_string())?;
    if !a.no_pairs {
        input = attach_pairs(input, &a)?;
    }
    if let Some(dir) = &a.sim {
        let path = dir.join("closed_loop.json");
        let text = std::fs::read_to_string(&path).with_context(|| {
            format!(
                "cannot read {} (the closed-loop evaluation writes it)",
                path.display()
            )
        })?;
        let cl = ClosedLoop::from_json(&text, &path.display().to_string())?;
        input = input.with_closed_loop(cl)?;
    }
    let params = ReportParams {
        title: a.title.clone(),
        ..ReportParams::default()
    };
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| a.envelope_dir.join("report.html"));
    write_input(&input, &params, &out)?;
    writeln!(std::io::stdout().lock(), "{}", out.display())?;
    Ok(ExitCode::SUCCESS)
}

/// Writes the report of an envelope to `out` (atomically: a temporary file in the same
/// directory, renamed into place). `pairs`, the table the envelope was computed from, adds
/// the L2 histogram to figure 2a. This is what `fogline envelope` and `fogline demo` call.
pub fn write_report(envelope: &Envelope, pairs: Option<&PairTable>, out: &Path) -> Result<()> {
    write_report_with(envelope, pairs, None, out)
}

/// [`write_report`] with the closed-loop results of `sim_dir` (its `closed_loop.json`), as
/// `fogline demo` writes it.
pub fn write_report_with(
    envelope: &Envelope,
    pairs: Option<&PairTable>,
    sim_dir: Option<&Path>,
    out: &Path,
) -> Result<()> {
    let mut input = ReportInput::from_envelope(envelope)?;
    if let Some(t) = pairs {
        input = input.with_pairs(t)?;
    }
    if let Some(dir) = sim_dir {
        let path = dir.join("closed_loop.json");
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let cl = ClosedLoop::from_json(&text, &path.display().to_string())?;
        input = input.with_closed_loop(cl)?;
    }
    write_input(&input, &ReportParams::default(), out)
}

fn write_input(input: &ReportInput, params: &ReportParams, out: &Path) -> Result<()> {
    let report = fogline_report::render(input, params)?;
    for f in report.figures.iter().filter(|f| !f.drawn) {
        log::info!(
            "report: {} ({}) not drawn; the page says why",
            f.id,
            f.title
        );
    }
    write_file_atomic(out, report.html.as_bytes())
}

/// Finds and reads the pairs table for the histogram. An explicit `--pairs` must match the
/// envelope; an implicit candidate that is missing or different is skipped with a warning.
fn attach_pairs(input: ReportInput, a: &ReportArgs) -> Result<ReportInput> {
    let opts = ReadOptions {
        allow_incomplete: input.envelope.corpus.n_incomplete_clips > 0,
        ..ReadOptions::default()
    };
    if let Some(p) = &a.pairs {
        let table = fogline_envelope::read_pairs(p, &opts)?;
        return Ok(input.with_pairs(&table)?);
    }
    let recorded = PathBuf::from(&input.envelope.input.path);
    let mut candidates = vec![recorded.clone()];
    if let Some(name) = recorded.file_name() {
        candidates.push(a.envelope_dir.join(name));
    }
    for c in candidates {
        if !c.is_file() {
            continue;
        }
        match fogline_envelope::read_pairs(&c, &opts) {
            Ok(table) => match input.clone().with_pairs(&table) {
                Ok(with) => {
                    log::info!("report: L2 histogram from {}", c.display());
                    return Ok(with);
                }
                Err(e) => log::warn!("report: not using {}: {e}", c.display()),
            },
            Err(e) => log::warn!("report: cannot read {}: {e:#}", c.display()),
        }
    }
    log::warn!(
        "report: the pairs table {} was not found; figure 2a shows the mixture without the histogram (--pairs PATH)",
        input.envelope.input.path
    );
    Ok(input)
}

/// `bytes` to `path` through a temporary file in the same directory.
fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        bail!(
            "cannot write {}: {} is not a directory",
            path.display(),
            dir.display()
        );
    }
    crate::write_atomic(path, bytes)
}
