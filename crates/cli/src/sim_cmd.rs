//! `fogline sim run`: the closed-loop experiments of the LLM-RCO paper (sections 6–7) on the
//! built-in world — a route suite, the camera-driven baseline, perception deficits, the RCO
//! take-over, CARLA Leaderboard 1.0 scores — written as tables and per-route records. See
//! `docs/sim.md`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use fogline_sim::config::BackendSetup;
use fogline_sim::experiment::ExperimentParams;
use fogline_sim::run::RunParams;
use fogline_sim::suite::SuiteParams;

use crate::backend_args::{BackendArg, OpenAiArgs};

/// Arguments of `fogline sim`.
#[derive(Args)]
pub struct SimArgs {
    #[command(subcommand)]
    what: SimCommand,
}

#[derive(Subcommand)]
enum SimCommand {
    /// Drive the route suite under every configuration and write tables 1–3 and per-route
    /// records.
    #[command(
        after_help = "Examples:\n  fogline sim run --quick --out sim-quick\n  fogline sim run --out sim-results\n  fogline sim run --configs main,ablation,sweep --seeds 3 --out sim-all\n  fogline sim run --configs ramps --seeds 3 --out sim-ramps\n  fogline sim run --quick --backend openai --url http://127.0.0.1:8000 --model Qwen/Qwen2-VL-2B-Instruct"
    )]
    Run(Box<RunArgs>),
    /// Compare two sets of runs of the same suite, configuration by configuration: runs
    /// paired by seed and route, the mean change of the driving score with its 95 %
    /// bootstrap interval, collisions per km, and how many runs are identical.
    #[command(
        after_help = "Examples:\n  fogline sim compare sim-before/ sim-after/\n  fogline sim compare sim-before/records.jsonl sim-after/records.jsonl --json\n  fogline sim compare sim-before/ sim-after/ --require-identical   # exit 1 unless every run is the same"
    )]
    Compare(CompareArgs),
}

#[derive(Args)]
struct CompareArgs {
    /// The runs before: a `fogline sim run --out` directory or its `records.jsonl`.
    before: PathBuf,
    /// The runs after, likewise.
    after: PathBuf,
    /// Print the comparison as JSON on stdout instead of the table.
    #[arg(long)]
    json: bool,
    /// Exit with status 1 unless both sets hold the same runs and every pair is identical
    /// (wall-clock times aside): for a change that must not alter results.
    #[arg(long)]
    require_identical: bool,
}

#[derive(Args)]
struct RunArgs {
    /// The quick suite (2 towns × 2 routes of about 450 m) for CI and the demo.
    #[arg(long, conflicts_with = "suite")]
    quick: bool,
    /// A suite file (TOML or JSON; see docs/sim.md). Default: the Longest6-like suite (36
    /// routes, about 1.5 km each).
    #[arg(long)]
    suite: Option<PathBuf>,
    /// Configuration sets, comma-separated: main (tables 1 and 2), ablation (table 3), sweep
    /// (the planning step-limit sweep), ramps (condition ramps: no guard, the monitor-driven
    /// guard, the oracle hand-over, the override always on).
    #[arg(long, value_delimiter = ',', default_value = "main")]
    configs: Vec<String>,
    /// The envelope (`odd.json`) the ramps' guard judges by. Default: the reference planner's.
    #[arg(long)]
    odd: Option<PathBuf>,
    /// Deficits, comma-separated: traffic_light, stop_sign, pedestrian, bicycle; `none` runs
    /// the no-deficit configuration only (main set).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "traffic_light,stop_sign,pedestrian,bicycle"
    )]
    deficits: Vec<String>,
    /// Only these routes of the suite, 0-based, comma-separated indices and ranges
    /// (`0,5,10-13`; one route with `-vv` to trace the agent). Default: all.
    #[arg(long)]
    routes: Option<String>,
    /// The first seed (towns, routes, traffic).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Number of seeds (seed, seed+1, …).
    #[arg(long, default_value_t = 1)]
    seeds: u64,
    /// Output directory.
    #[arg(long, default_value = "sim-results")]
    out: PathBuf,
    /// Who answers the RCO controller's queries.
    #[arg(long, value_enum, default_value = "rules")]
    backend: BackendArg,
    #[command(flatten)]
    openai: OpenAiArgs,
    /// Latency counted per LLM call for system time, ms, or `measured`.
    #[arg(long, default_value = "1000")]
    llm_latency_ms: String,
    /// Table 2's system-time limit, s (the paper's 30 minutes).
    #[arg(long, default_value_t = 1800.0)]
    system_time_limit_s: f64,
    /// The stop-sign penalty factor (Leaderboard 1.0: 0.8; Longest6's fork: 1.0).
    #[arg(long, default_value_t = 0.8)]
    stop_sign_penalty: f64,
    /// Image width of the front cameras, px.
    #[arg(long, default_value_t = 192)]
    width: u32,
    /// Image height of the front cameras, px.
    #[arg(long, default_value_t = 144)]
    height: u32,
    /// Image width of the telephoto camera, px (same aspect ratio).
    #[arg(long, default_value_t = 256)]
    tele_width: u32,
    /// Image width of the side cameras (the RCO controller's side views), px.
    #[arg(long, default_value_t = 96)]
    side_width: u32,
    /// Agent steps per second (frames, planner, RCO); must divide 20.
    #[arg(long, default_value_t = 2.5)]
    agent_hz: f64,
    /// A planner under test driving instead of the baseline's rules: `builtin`,
    /// `http://HOST:PORT`, `https://HOST[:PORT]`, `egodriver://HOST:PORT` or
    /// `egodriver+https://HOST[:PORT]` (60 s per request; docs/sim.md).
    #[arg(long)]
    planner: Option<String>,
    /// Print the summary as JSON on stdout instead of the tables.
    #[arg(long)]
    json: bool,
}

/// Runs `fogline sim`.
pub fn sim(a: SimArgs) -> Result<ExitCode> {
    match a.what {
        SimCommand::Run(r) => run(*r),
        SimCommand::Compare(c) => compare(&c),
    }
}

fn compare(a: &CompareArgs) -> Result<ExitCode> {
    let c = fogline_api::sim::compare_runs(&a.before, &a.after)?;
    let text = if a.json {
        serde_json::to_string_pretty(&c)? + "\n"
    } else {
        c.markdown()
    };
    std::io::Write::write_all(&mut std::io::stdout().lock(), text.as_bytes())?;
    if a.require_identical && !c.all_identical() {
        eprintln!("error: the runs differ (--require-identical)");
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

fn run(a: RunArgs) -> Result<ExitCode> {
    let suite = match (&a.suite, a.quick) {
        (Some(path), _) => SuiteParams::read(path)?,
        (None, true) => SuiteParams::quick(),
        (None, false) => SuiteParams::longest6(),
    };
    if a.seeds == 0 {
        bail!("--seeds must be at least 1");
    }
    let llm_latency_ms = match a.llm_latency_ms.as_str() {
        "measured" => None,
        v => Some(v.parse::<f64>().with_context(|| {
            format!("--llm-latency-ms: expected a number of ms or `measured`, got {v:?}")
        })?),
    };
    let backend = match a.backend {
        BackendArg::Rules => BackendSetup::Rules,
        BackendArg::Hostile => BackendSetup::Hostile { weak_brakes: false },
        BackendArg::HostileWeakBrakes => BackendSetup::Hostile { weak_brakes: true },
        BackendArg::Openai => BackendSetup::Openai(a.openai.params()?),
    };
    let mut run_params = RunParams {
        stop_sign_penalty: a.stop_sign_penalty,
        ..RunParams::default()
    };
    run_params.sensors.width = a.width;
    run_params.sensors.height = a.height;
    run_params.sensors.agent_hz = a.agent_hz;
    run_params.sensors.side_width = a.side_width;
    run_params.sensors.tele_width = a.tele_width;
    let params = ExperimentParams {
        suite,
        seeds: (a.seed..a.seed + a.seeds).collect(),
        configs: fogline_api::sim::experiment_configs(
            &a.configs,
            &a.deficits,
            &backend,
            a.odd.as_deref(),
        )?,
        run: run_params,
        system_time_limit_s: a.system_time_limit_s,
        llm_latency_ms,
        routes: (a.routes.as_deref())
            .map(fogline_api::sim::parse_routes)
            .transpose()?,
    };
    let driver = (a.planner.as_deref())
        .map(|spec| fogline_api::sim::planner_at(spec, 60.0))
        .transpose()?;
    let (results, written) = fogline_api::sim::run(&params, driver, &a.out)?;
    fogline_api::sim::write_summary(
        &params,
        &results,
        &written,
        a.json,
        &mut std::io::stdout().lock(),
    )?;
    Ok(ExitCode::SUCCESS)
}
