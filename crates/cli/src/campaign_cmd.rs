//! `fogline campaign run | status | export | merge | init`.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::{Args, Subcommand};
use fogline_campaign::export::Formats;
use fogline_campaign::{CampaignConfig, Shard, Store};

/// Arguments of `fogline campaign`.
#[derive(Args)]
pub struct CampaignArgs {
    #[command(subcommand)]
    what: CampaignCommand,
}

#[derive(Subcommand)]
enum CampaignCommand {
    /// Run clips × conditions × seeds against a planner; every run is committed to the store.
    #[command(
        after_help = "Examples:\n  fogline campaign init campaign.toml\n  fogline campaign run campaign.toml --export out/\n  fogline campaign run campaign.toml --resume\n  fogline campaign run campaign.toml --shard 0/3 --resume"
    )]
    Run(RunArgs),
    /// Show what a store holds: runs done and failed, per condition, failure reasons.
    Status(StatusArgs),
    /// Write the runs table and the pairs table (the input of `fogline envelope`).
    #[command(
        after_help = "Example:\n  fogline campaign export campaign.sqlite --out out/ --format csv,parquet"
    )]
    Export(ExportArgs),
    /// Merge shard stores of one campaign into one store.
    #[command(
        after_help = "Example:\n  fogline campaign merge --out all.sqlite c.shard-0-of-3.sqlite c.shard-1-of-3.sqlite c.shard-2-of-3.sqlite"
    )]
    Merge(MergeArgs),
    /// Write a commented campaign configuration to start from.
    Init(InitArgs),
}

#[derive(Args)]
struct RunArgs {
    /// The campaign configuration (TOML; see `fogline campaign init`).
    config: PathBuf,
    /// The store (default: the config's name with `.sqlite`, or `.shard-I-of-N.sqlite`).
    #[arg(long)]
    store: Option<PathBuf>,
    /// Continue an existing store (creates it when missing): finished runs are not redone.
    #[arg(long)]
    resume: bool,
    /// With --resume: run the failed runs again.
    #[arg(long, requires = "resume")]
    retry_failed: bool,
    /// Run slice I of N (0-based): clip i belongs to shard i mod N.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Runs in flight (overrides `run.concurrency`).
    #[arg(long)]
    concurrency: Option<usize>,
    /// Export the tables into this directory when the run ends.
    #[arg(long, value_name = "DIR")]
    export: Option<PathBuf>,
    /// Export formats: csv, parquet or csv,parquet.
    #[arg(long, default_value = "csv,parquet")]
    format: String,
}

#[derive(Args)]
struct StatusArgs {
    /// The store.
    store: PathBuf,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct ExportArgs {
    /// The store.
    store: PathBuf,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Formats: csv, parquet or csv,parquet; `parquet:CODEC` picks the compression (zstd,
    /// the default, snappy, gzip, lz4, brotli, none).
    #[arg(long, default_value = "csv,parquet")]
    format: String,
    /// Add `attempts` and `latency_ms` to the runs table (they vary between identical runs).
    #[arg(long)]
    timing: bool,
}

#[derive(Args)]
struct MergeArgs {
    /// The merged store to create.
    #[arg(long)]
    out: PathBuf,
    /// The shard stores.
    #[arg(required = true)]
    stores: Vec<PathBuf>,
}

#[derive(Args)]
struct InitArgs {
    /// Where to write the configuration.
    config: PathBuf,
}

/// Runs `fogline campaign …`.
pub fn campaign(a: CampaignArgs) -> Result<ExitCode> {
    match a.what {
        CampaignCommand::Run(r) => run(r),
        CampaignCommand::Status(s) => status(s),
        CampaignCommand::Export(e) => export(e),
        CampaignCommand::Merge(m) => merge(m),
        CampaignCommand::Init(i) => init(i),
    }
}

/// The default store of `config` for `shard`.
fn default_store(config: &Path, shard: Shard) -> PathBuf {
    if shard == Shard::ALL {
        config.with_extension("sqlite")
    } else {
        config.with_extension(format!("shard-{}-of-{}.sqlite", shard.index, shard.count))
    }
}

fn run(a: RunArgs) -> Result<ExitCode> {
    let mut config = CampaignConfig::from_file(&a.config)?;
    if let Some(c) = a.concurrency {
        if c == 0 {
            bail!("--concurrency must be at least 1");
        }
        config.run.concurrency = c;
    }
    let formats = Formats::parse(&a.format).map_err(anyhow::Error::msg)?;
    let shard = match &a.shard {
        Some(s) => Shard::parse(s).map_err(anyhow::Error::msg)?,
        None => Shard::ALL,
    };
    let store_path = a.store.unwrap_or_else(|| default_store(&a.config, shard));
    let (_, summary) =
        fogline_campaign::run_into_store(config, &store_path, shard, a.resume, a.retry_failed)?;
    let mut out = std::io::stdout().lock();
    summary.write_text(&mut out, &store_path)?;
    if let Some(dir) = &a.export {
        let store = Store::open(&store_path)?;
        let s = fogline_campaign::export::export(&store.runs()?, dir, formats, false)?;
        s.write_text(&mut out)?;
    }
    Ok(ExitCode::SUCCESS)
}

fn status(a: StatusArgs) -> Result<ExitCode> {
    let s = fogline_campaign::merge::status(&a.store)?;
    s.write_text(&a.store, a.json, &mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}

fn export(a: ExportArgs) -> Result<ExitCode> {
    let formats = Formats::parse(&a.format).map_err(anyhow::Error::msg)?;
    let store = Store::open(&a.store)?;
    let s = fogline_campaign::export::export(&store.runs()?, &a.out, formats, a.timing)?;
    s.write_text(&mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}

fn merge(a: MergeArgs) -> Result<ExitCode> {
    let s = fogline_campaign::merge::merge(&a.out, &a.stores)?;
    s.write_text(&a.out, &mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}

fn init(a: InitArgs) -> Result<ExitCode> {
    if a.config.exists() {
        bail!("{} already exists; not overwriting it", a.config.display());
    }
    fogline_io::write_atomic(&a.config, fogline_campaign::config::TEMPLATE.as_bytes())?;
    writeln!(
        std::io::stdout().lock(),
        "wrote {}; run it with: fogline campaign run {} --export out/",
        a.config.display(),
        a.config.display()
    )?;
    Ok(ExitCode::SUCCESS)
}
