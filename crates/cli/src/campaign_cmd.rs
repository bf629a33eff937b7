//! `fogline campaign run | status | export | merge | init`.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
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
    /// Formats: csv, parquet or csv,parquet.
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
    let mut out = std::io::stdout().lock();
    if a.json {
        let v = serde_json::json!({
            "store": a.store,
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
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(out, "store    {}", a.store.display())?;
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
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "merged {} runs of shards {:?} (of {}) into {}{}",
        s.runs,
        s.shards,
        s.count,
        a.out.display(),
        if s.complete() {
            ""
        } else {
            " — not every shard is there yet"
        }
    )?;
    Ok(ExitCode::SUCCESS)
}

/// The configuration `fogline campaign init` writes.
pub(crate) const TEMPLATE: &str = r#"# A fogline campaign: clips × conditions × seeds against a planner.
# Run it with:  fogline campaign run campaign.toml --export out/

[clips]
source = "world"      # "world" (generated) or "dir" (clips in the documented clip format)
count = 200           # world: number of clips
seed = 0              # world: corpus seed
mix = "paper"         # world: "paper" (the paper's proportions), "uniform", or one scenario label
width = 576           # world: image size, px (up to 1920×1080)
height = 320
# path = "clips/"     # dir: the directory of clips (relative to this file)

[conditions]
# clean is always run. Any condition of `fogline perturb` works, chains with "+".
names = ["noise_10", "noise_30", "noise_50", "noise_70", "dark", "bright", "fog_03", "fog_07"]
seeds = [0]

[planner]
kind = "builtin"      # "builtin", "egodriver" (AlpaSim gRPC) or "http" (docs/remote.md)
# endpoint = "127.0.0.1:50051"          # egodriver: host:port
# endpoint = "http://127.0.0.1:8080"    # http: base URL
# image_format = "png"                  # remote planners: "png" or "jpeg"
# jpeg_quality = 95
# explanation_fields = ["coc", "reasoning", "explanation"]

[run]
concurrency = 0       # runs in flight; 0 = cores (builtin) or 8 (remote)
timeout_s = 60        # per request to a remote planner
retries = 2           # retries of timeouts, unreachable endpoints and remote errors
backoff_ms = 250      # first retry delay; doubles each retry
"#;

fn init(a: InitArgs) -> Result<ExitCode> {
    if a.config.exists() {
        bail!("{} already exists; not overwriting it", a.config.display());
    }
    CampaignConfig::from_toml(TEMPLATE).context("the built-in template is invalid")?;
    fogline_campaign::export::write_atomic(&a.config, |w| {
        w.write_all(TEMPLATE.as_bytes()).map_err(|e| e.to_string())
    })?;
    writeln!(
        std::io::stdout().lock(),
        "wrote {}; run it with: fogline campaign run {} --export out/",
        a.config.display(),
        a.config.display()
    )?;
    Ok(ExitCode::SUCCESS)
}
