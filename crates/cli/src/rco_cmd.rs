//! `fogline rco replay FILE` (recorded observations through the LLM-RCO controller, its
//! decisions on stdout) and `fogline rco bench` (the per-tick cost of the rule-based path and
//! of the verifier for three 576×320 views, next to the goal of 1 ms per tick). See
//! `docs/rco.md`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};

use crate::backend_args::{BackendArg, OpenAiArgs};

/// Arguments of `fogline rco`.
#[derive(Args)]
pub struct RcoArgs {
    #[command(subcommand)]
    what: RcoCommand,
}

#[derive(Subcommand)]
enum RcoCommand {
    /// Feed recorded observations (JSON Lines, one per tick) through the controller and print
    /// its decisions.
    #[command(
        after_help = "Examples:\n  fogline rco replay crates/rco/tests/data/observations.jsonl\n  fogline rco replay crates/rco/tests/data/observations.jsonl --modules hi,st,av --json\n  fogline rco replay obs.jsonl --backend openai --url http://127.0.0.1:8000 --model Qwen/Qwen2-VL-2B-Instruct"
    )]
    Replay(ReplayArgs),
    /// Per-tick cost of the rule-based path and of the verifier for three 576x320 views, next
    /// to the goal of 1 ms per tick.
    #[command(
        after_help = "Examples:\n  fogline rco bench\n  fogline rco bench --ticks 1000 --json"
    )]
    Bench(BenchArgs),
    /// Score a backend's hazard inference and planning on a DriveLM-Deficit directory (figure 6).
    #[command(
        after_help = "Examples:\n  fogline rco eval --data deficit/ --backend rules\n  fogline rco eval --data deficit/ --backend openai --url http://127.0.0.1:8000 --model Qwen/Qwen2-VL-2B-Instruct --limit 200"
    )]
    Eval(EvalArgs),
}

#[derive(Args)]
struct EvalArgs {
    /// The data set (`fogline dataset deficit --out`).
    #[arg(long)]
    data: PathBuf,
    /// Who answers: rules or openai.
    #[arg(long, value_enum, default_value = "rules")]
    backend: BackendArg,
    /// The split scored: train, val, test or all.
    #[arg(long, default_value = "test")]
    split: String,
    /// At most this many samples.
    #[arg(long)]
    limit: Option<usize>,
    /// Concurrent calls.
    #[arg(long, default_value_t = 1)]
    jobs: usize,
    /// Where eval.json, eval.md and report.html go (default: DATA/eval).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Samples in report.html's gallery.
    #[arg(long, default_value_t = fogline_api::dataset::GALLERY)]
    gallery: usize,
    #[command(flatten)]
    openai: OpenAiArgs,
}

#[derive(Args)]
struct ReplayArgs {
    /// Recorded observations: JSON Lines, one observation per line.
    file: PathBuf,
    /// Who answers the controller's queries.
    #[arg(long, value_enum, default_value = "rules")]
    backend: BackendArg,
    /// The modules that are on, comma-separated: hi (hazard inference), st (motion planner),
    /// av (verifier), sc (safety constraints), or `none`.
    #[arg(long, default_value = "hi,st,av,sc")]
    modules: String,
    /// The largest number of steps of a move plan.
    #[arg(long, default_value_t = 5)]
    plan_limit: usize,
    /// Area ratio above which a view has an immediate hazard.
    #[arg(long, default_value_t = 0.05)]
    hazard_ratio: f64,
    /// Print every decision as one JSON line instead of the table.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    openai: OpenAiArgs,
}

#[derive(Args)]
struct BenchArgs {
    /// Ticks timed per case (after 10 untimed ones).
    #[arg(long, default_value_t = 300)]
    ticks: u64,
    /// Seed of the synthetic textures.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
}

/// Runs `fogline rco …`.
pub fn rco(a: RcoArgs) -> Result<ExitCode> {
    match a.what {
        RcoCommand::Replay(r) => replay_cmd(r),
        RcoCommand::Eval(e) => eval_cmd(e),
        RcoCommand::Bench(b) => {
            let opts = fogline_bench::rco::RcoBench {
                ticks: b.ticks,
                seed: b.seed,
                json: b.json,
            };
            fogline_bench::rco::run(&opts, &mut std::io::stdout().lock())?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

fn eval_cmd(a: EvalArgs) -> Result<ExitCode> {
    use fogline_api::dataset::{EvalBackend, EvalJob, eval};
    let split = match a.split.as_str() {
        "all" => None,
        s => Some(fogline_dataset::Split::parse(s).context("--split: train, val, test or all")?),
    };
    let backend = match a.backend {
        BackendArg::Rules => EvalBackend::Rules,
        BackendArg::Openai => EvalBackend::OpenAi(a.openai.params()?),
        _ => bail!("--backend: rco eval takes rules or openai"),
    };
    let params = fogline_dataset::EvalParams {
        split,
        limit: a.limit,
        jobs: a.jobs,
    };
    let job = EvalJob {
        data: a.data,
        out: a.out,
        backend,
        params,
        gallery: a.gallery,
    };
    eval(&job)?.write_text(&mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}

fn replay_cmd(a: ReplayArgs) -> Result<ExitCode> {
    use fogline_api::rco::{ReplayBackend, ReplayJob, replay_file};
    let backend = match a.backend {
        BackendArg::Rules => ReplayBackend::Rules,
        BackendArg::Openai => ReplayBackend::OpenAi(a.openai.params()?),
        BackendArg::Hostile => ReplayBackend::Hostile { weak_brakes: false },
        BackendArg::HostileWeakBrakes => ReplayBackend::Hostile { weak_brakes: true },
    };
    let job = ReplayJob {
        file: a.file,
        modules: a.modules,
        plan_limit: a.plan_limit,
        hazard_ratio: a.hazard_ratio,
        json: a.json,
        backend,
    };
    let usable = replay_file(&job, &mut std::io::stdout().lock())?;
    Ok(if usable {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
