//! `fogline report ENVELOPE_DIR [--sim SIM_DIR] [--deficit EVAL_DIR] --out report.html`: its arguments; the
//! report (figures as inline SVG, the paper's tables, a plain-language summary) is written by
//! `fogline_api::envelope::report_dir`. See `docs/report.md`.

use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;

/// Arguments of `fogline report`.
#[derive(Args)]
pub struct ReportArgs {
    /// Directory holding `envelope.json` (as written by `fogline envelope` or `fogline demo`).
    pub envelope_dir: PathBuf,
    /// Closed-loop results: a directory holding `closed_loop.json`.
    #[arg(long, value_name = "SIM_DIR")]
    pub sim: Option<PathBuf>,
    /// A DriveLM-Deficit evaluation: a directory holding `eval.json` (`fogline rco eval`).
    #[arg(long, value_name = "EVAL_DIR")]
    pub deficit: Option<PathBuf>,
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
    let out = fogline_api::envelope::report_dir(&fogline_api::envelope::ReportJob {
        envelope_dir: a.envelope_dir,
        sim: a.sim,
        out: a.out,
        pairs: a.pairs,
        no_pairs: a.no_pairs,
        title: a.title,
        deficit: a.deficit,
    })?;
    writeln!(std::io::stdout().lock(), "{}", out.display())?;
    Ok(ExitCode::SUCCESS)
}
