//! `fogline`: the safety of driving planners when their perception degrades.
//!
//! A thin binary over the library crates: it parses flags, reads and writes files, logs on
//! stderr and prints its primary output on stdout. Exit codes: 0 success, 1 a gate failed
//! (e.g. a scenario rejected under `--pi-star`), 2 error (the whole error chain is printed).

mod backend_args;
mod bench_campaign;
mod campaign_cmd;
mod clips_cmd;
mod dataset_cmd;
mod guard_cmd;
mod monitor_cmd;
mod perturb_cmd;
mod planner_cmd;
mod rco_cmd;
mod report_cmd;
mod serve_cmd;
mod sim_cmd;
mod world_cmd;

/// mimalloc keeps freed pages: glibc's malloc unmapped each call's frame buffers (3 of 10 ms).
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use fogline_envelope::{
    Bands, BootstrapMethod, EnvelopeParams, ReadOptions, TaxonomyChoice, ThresholdRule,
};

#[derive(Parser)]
#[command(
    name = "fogline",
    version,
    about = "When does a camera-driven planner start to fail, how severely, and what should the car do meanwhile",
    after_help = "Examples:\n  fogline demo\n  fogline envelope pairs.csv --out envelope/\n  fogline envelope pairs.parquet --out envelope/ --pi-star 0.08 --budgets 0.10,0.15,0.20"
)]
struct Cli {
    /// More log output on stderr (-v debug, -vv trace).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Only warnings and errors on stderr.
    #[arg(short, long, global = true)]
    quiet: bool,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, global = true)]
    threads: Option<usize>,
    /// https:// endpoints (the LLM backend, remote planners): also trust the CA
    /// certificates of this PEM file (a private CA).
    #[arg(long, global = true, value_name = "FILE")]
    ca_cert: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Analyse a pairs table: per-scenario thresholds, severity bands, the 2-D ODD entry.
    #[command(
        after_help = "Examples:\n  fogline envelope pairs.csv --out envelope/\n  fogline envelope pairs.jsonl --out out/ --rule max-passing --bootstrap 2000 --seed 7"
    )]
    Envelope(Box<EnvelopeArgs>),
    /// Run the whole pipeline offline on built-in data and write a report.
    #[command(after_help = "Example:\n  fogline demo --out fogline-demo")]
    Demo(DemoArgs),
    /// Perturb a directory of frames (PNG/JPEG): noise, gain, fog, blur, JPEG, masks, faults.
    #[command(
        after_help = "Examples:\n  fogline perturb --input frames/ --output frames-noise30/ --condition noise_30 --seed 7\n  fogline perturb --input frames/ --output masked/ --condition mask_class_pedestrian --boxes boxes.jsonl\n  fogline perturb --input frames/ --output fog/ --condition fog_07 --depth depth/"
    )]
    Perturb(Box<perturb_cmd::PerturbArgs>),
    /// Benchmarks.
    Bench(perturb_cmd::BenchArgs),
    /// The synthetic driving world: generate a corpus of clips, or show (and check) one clip.
    World(world_cmd::WorldArgs),
    /// Real clips: import a dataset (PhysicalAI-AV) into the clip format.
    Clips(clips_cmd::ClipsArgs),
    /// Blind estimates of image quality (noise σ, gain, fog) from the pixels alone.
    Monitor(monitor_cmd::MonitorArgs),
    /// The reference planner: evaluate it on generated clips, clean and perturbed.
    Planner(planner_cmd::PlannerArgs),
    /// Campaigns: clips × conditions × seeds against a planner, in a crash-safe store.
    Campaign(campaign_cmd::CampaignArgs),
    /// DriveLM-Deficit: labelled deficit clips from the world, with fine-tuning exports.
    Dataset(dataset_cmd::DatasetArgs),
    /// The LLM-RCO controller: replay recorded observations through it, time it, or score a
    /// backend on DriveLM-Deficit.
    #[command(
        after_help = "Examples:\n  fogline rco replay crates/rco/tests/data/observations.jsonl\n  fogline rco bench"
    )]
    Rco(rco_cmd::RcoArgs),
    /// Closed-loop evaluation: the route suite, perception deficits, the RCO take-over and
    /// Leaderboard-1.0 scores.
    #[command(
        after_help = "Examples:\n  fogline sim run --quick --out sim/\n  fogline sim run --out sim/            # the full suite: 36 routes × 9 configurations"
    )]
    Sim(sim_cmd::SimArgs),
    /// Serve the reference planner over AlpaSim's egodriver gRPC contract or HTTP/JSON.
    #[command(
        after_help = "Examples:\n  fogline serve egodriver --addr 127.0.0.1:50051\n  fogline serve http --addr 127.0.0.1:8080"
    )]
    Serve(serve_cmd::ServeArgs),
    /// Guard an egodriver driver: monitor every frame against odd.json, answer with the RCO out of the envelope.
    #[command(
        after_help = "Examples:\n  fogline guard --driver http://127.0.0.1:50051 --odd fogline-demo/odd.json --scenario LANE_KEEPING --log guard.jsonl"
    )]
    Guard(guard_cmd::GuardArgs),
    /// Write the self-contained HTML report (figures and tables) of an envelope directory.
    #[command(
        after_help = "Examples:\n  fogline report envelope/ --out report.html\n  fogline report fogline-demo/\n  fogline report envelope/ --sim closed-loop/ --out report.html"
    )]
    Report(report_cmd::ReportArgs),
}

#[derive(Args)]
struct AnalysisArgs {
    /// ADE budgets (relative), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.10,0.15,0.20")]
    budgets: Vec<f64>,
    /// The headline budget (must be one of --budgets).
    #[arg(long, default_value_t = 0.15)]
    headline: f64,
    /// Threshold rule: `first-violation` or `max-passing`.
    #[arg(long, default_value = "first-violation")]
    rule: ThresholdRule,
    /// Clip-level bootstrap resamples (0 = off).
    #[arg(long, default_value_t = 10_000)]
    bootstrap: usize,
    /// Bootstrap resampling: `multinomial` (classic), `poisson` (clip weights), or `auto`
    /// (multinomial up to 100,000 clips).
    #[arg(long, default_value = "auto")]
    bootstrap_method: BootstrapMethod,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Largest number of mixture components.
    #[arg(long, default_value_t = 8)]
    k_max: usize,
    /// Restart seeds of the BIC study.
    #[arg(long, default_value_t = 20)]
    restarts: usize,
    /// Starts per GMM fit.
    #[arg(long, default_value_t = 3)]
    n_init: usize,
    /// Number of severity bands: `auto` (BIC) or a fixed K.
    #[arg(long, default_value = "auto")]
    bands: Bands,
    /// How many top bands count as high severity.
    #[arg(long, default_value_t = 2)]
    high_bands: usize,
    /// Residual-risk budget π* on P(high | changed, s); enables acceptance (and the exit-1 gate).
    #[arg(long)]
    pi_star: Option<f64>,
    /// Operating level σ_op for acceptance (default: the all-clips aggregate threshold).
    #[arg(long)]
    sigma_op: Option<f64>,
    /// Scenarios with fewer clips are marked pilot.
    #[arg(long, default_value_t = 30)]
    min_clips: usize,
    /// How L2 was aggregated upstream (recorded in the output).
    #[arg(
        long,
        default_value = "euclidean norm of the stacked xy waypoint differences (m)"
    )]
    l2: String,
    /// Family whose threshold forms the ODD entry.
    #[arg(long, default_value = "gaussian_noise")]
    odd_family: String,
    /// Scenario taxonomy: `auto` (the paper's seven classes + OTHER when the data uses
    /// them, else the data's labels), `paper`, or `data` (the labels found, OTHER excluded).
    #[arg(long, default_value = "auto")]
    taxonomy: TaxonomyChoice,
    /// TOML file of action keyword rules (`[[action]]` tables with `name` and `keywords`).
    #[arg(long)]
    actions: Option<PathBuf>,
    /// Accept clips that lack some conditions.
    #[arg(long)]
    allow_incomplete: bool,
}

#[derive(Args)]
struct EnvelopeArgs {
    /// Pairs table: .csv, .parquet or .jsonl (one row per clip × perturbed condition).
    pairs: PathBuf,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    analysis: AnalysisArgs,
}

#[derive(Args)]
struct DemoArgs {
    /// Output directory.
    #[arg(long, default_value = "fogline-demo")]
    out: PathBuf,
    /// Clips in the synthetic corpus (the paper's corpus has 1,996: `--clips 1996`).
    #[arg(long, default_value_t = 300)]
    clips: usize,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Skip the quick closed loop (no deficit; each deficit with and without RCO).
    #[arg(long)]
    no_closed_loop: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let level = if cli.quiet {
        log::LevelFilter::Warn
    } else {
        match cli.verbose {
            0 => log::LevelFilter::Info,
            1 => log::LevelFilter::Debug,
            _ => log::LevelFilter::Trace,
        }
    };
    env_logger::Builder::new()
        .filter_level(level)
        .format_timestamp(None)
        .format_target(false)
        .target(env_logger::Target::Stderr)
        .init();
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    if let Some(n) = cli.threads {
        if n == 0 {
            bail!("--threads must be at least 1");
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("cannot start the worker threads")?;
    }
    if let Some(path) = &cli.ca_cert {
        fogline_io::http::set_default_ca_cert(Some(path))
            .with_context(|| format!("--ca-cert {}", path.display()))?;
    }
    match cli.command {
        Command::Envelope(a) => envelope(*a),
        Command::Demo(a) => demo(a),
        Command::Perturb(a) => perturb_cmd::perturb(*a),
        Command::Bench(a) => perturb_cmd::bench(a),
        Command::World(a) => world_cmd::world(a),
        Command::Clips(a) => clips_cmd::clips(a),
        Command::Planner(a) => planner_cmd::planner(a),
        Command::Monitor(a) => monitor_cmd::monitor(a),
        Command::Serve(a) => serve_cmd::serve(a),
        Command::Guard(a) => guard_cmd::guard(a),
        Command::Campaign(a) => campaign_cmd::campaign(a),
        Command::Dataset(a) => dataset_cmd::dataset(a),
        Command::Rco(a) => rco_cmd::rco(a),
        Command::Sim(a) => sim_cmd::sim(a),
        Command::Report(a) => report_cmd::report(a),
    }
}

fn params(a: &AnalysisArgs) -> Result<EnvelopeParams> {
    let p = EnvelopeParams {
        budgets: a.budgets.clone(),
        headline_budget: a.headline,
        rule: a.rule,
        bootstrap: a.bootstrap,
        bootstrap_method: a.bootstrap_method,
        seed: a.seed,
        k_max: a.k_max,
        restarts: a.restarts,
        n_init: a.n_init,
        bands: a.bands,
        high_bands: a.high_bands,
        pi_star: a.pi_star,
        sigma_op: a.sigma_op,
        min_clips: a.min_clips,
        l2_aggregation: a.l2.clone(),
        odd_family: a.odd_family.clone(),
        taxonomy: a.taxonomy.clone(),
        ..EnvelopeParams::default()
    };
    p.validate().context("invalid analysis parameters")?;
    Ok(p)
}

fn envelope(a: EnvelopeArgs) -> Result<ExitCode> {
    let mut opts = ReadOptions {
        allow_incomplete: a.analysis.allow_incomplete,
        ..ReadOptions::default()
    };
    if let Some(path) = &a.analysis.actions {
        opts.actions = fogline_envelope::text::ActionRules::from_toml_file(path)?;
    }
    let (table, env) = fogline_api::envelope::analyze_file(&a.pairs, &opts, params(&a.analysis)?)?;
    let written = fogline_api::envelope::write_outputs(&env, &table, &a.out, None)?;
    fogline_api::envelope::write_summary(&env, &written, a.json, &mut std::io::stdout().lock())?;
    // Exit 1 when acceptance was asked for and a well-sampled scenario is rejected.
    let rejected = fogline_api::envelope::rejected(&env);
    if rejected.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    log::warn!("gate failed: rejected under π*: {}", rejected.join(", "));
    Ok(ExitCode::from(1))
}

fn demo(a: DemoArgs) -> Result<ExitCode> {
    let d = fogline_api::demo::run(&fogline_api::demo::DemoJob {
        clips: a.clips,
        seed: a.seed,
        out: a.out.clone(),
        closed_loop: !a.no_closed_loop,
    })?;
    d.write_text(&mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}
