//! `fogline planner eval` and `fogline bench world`: their arguments and output; the
//! evaluation is `fogline_api::planner_eval`, the benchmark `fogline_bench::world`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use fogline_api::planner_eval::{PlannerEval, evaluate};

#[derive(Args)]
pub struct PlannerArgs {
    #[command(subcommand)]
    what: PlannerCommand,
}

#[derive(Subcommand)]
enum PlannerCommand {
    /// Run the reference planner on generated clips (in memory), clean and under perturbed
    /// conditions: ADE vs the expert's ground truth, decision agreement, clean-vs-perturbed L2
    /// and explanation changes, per scenario.
    #[command(
        after_help = "Examples:\n  fogline planner eval                                   # 1,996 clips, clean\n  fogline planner eval --conditions noise_10,noise_30,noise_50,noise_70 --json eval.json\n  fogline planner eval --clips 200 --conditions dark,fog_07 --seed 3"
    )]
    Eval(EvalArgs),
}

#[derive(Args)]
struct EvalArgs {
    /// Clips, the paper's scenario mix scaled to this number.
    #[arg(long, default_value_t = 1996)]
    clips: usize,
    /// World seed: clip i is drawn from (seed, i) alone.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Conditions, comma-separated (`clean`, `noise_30`, `dark`, `fog_07`, chains like
    /// `noise_30+fog_03`, …). `clean` is always evaluated: it is the reference of the L2 and
    /// explanation-change columns.
    #[arg(long, value_delimiter = ',', default_value = "clean")]
    conditions: Vec<String>,
    /// Seed of the perturbations' random streams.
    #[arg(long, default_value_t = 0)]
    perturb_seed: u64,
    /// Also write every figure as JSON to this file (atomically).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Image width of every camera, pixels (16..=1920).
    #[arg(long, default_value_t = 576)]
    width: u32,
    /// Image height of every camera, pixels (16..=1080).
    #[arg(long, default_value_t = 320)]
    height: u32,
}

/// Arguments of `fogline bench world`.
#[derive(Args)]
pub struct BenchWorldArgs {
    /// Clips generated (the paper's scenario mix scaled to this number).
    #[arg(long, default_value_t = 1996)]
    clips: usize,
    /// Clips the planner is timed on (default: --clips); they are generated again, untimed.
    #[arg(long)]
    plan_clips: Option<usize>,
    /// World seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Image width of every camera, pixels.
    #[arg(long, default_value_t = 576)]
    width: u32,
    /// Image height of every camera, pixels.
    #[arg(long, default_value_t = 320)]
    height: u32,
    /// Conditions the planner is timed under, comma-separated (`clean` is always timed,
    /// first); the perturbation itself is untimed.
    #[arg(long, value_delimiter = ',', default_value = "noise_30")]
    plan_conditions: Vec<String>,
    /// Seed of the perturbations' random streams.
    #[arg(long, default_value_t = 0)]
    perturb_seed: u64,
    /// Print the results as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// Runs `fogline planner …`.
pub fn planner(a: PlannerArgs) -> Result<ExitCode> {
    match a.what {
        PlannerCommand::Eval(e) => eval(e),
    }
}

/// Runs `fogline planner eval`: the evaluation is `fogline_api::planner_eval`.
fn eval(a: EvalArgs) -> Result<ExitCode> {
    let report = evaluate(&PlannerEval {
        clips: a.clips,
        seed: a.seed,
        conditions: a.conditions,
        perturb_seed: a.perturb_seed,
        width: a.width,
        height: a.height,
    })?;
    if let Some(path) = &a.json {
        let bytes = serde_json::to_vec_pretty(&report).context("cannot serialise the figures")?;
        fogline_io::write_atomic(path, &bytes)?;
        log::info!("wrote {}", path.display());
    }
    report.write_text(&mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}

/// Runs `fogline bench world`: the benchmark is `fogline_bench::world`.
pub fn bench_world(a: BenchWorldArgs) -> Result<ExitCode> {
    let opts = fogline_bench::world::WorldBench {
        clips: a.clips,
        plan_clips: a.plan_clips,
        seed: a.seed,
        width: a.width,
        height: a.height,
        plan_conditions: a.plan_conditions,
        perturb_seed: a.perturb_seed,
        json: a.json,
    };
    fogline_bench::world::run(&opts, &mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}
