//! `fogline rco replay FILE` (recorded observations through the LLM-RCO controller, its
//! decisions on stdout) and `fogline rco bench` (the per-tick cost of the rule-based path and
//! of the verifier for three 576×320 views, next to the goal of 1 ms per tick). See
//! `docs/rco.md`.

use std::collections::BTreeMap;
use std::io::{BufReader, Write as _};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand, ValueEnum};
use fogline_rco::synth::BenchScene;
use fogline_rco::{
    Backend, Modules, OpenAiBackend, OpenAiParams, Rco, RcoParams, RulesBackend, Source, replay,
    verifier,
};
use serde::Serialize;

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
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum BackendArg {
    /// Offline, deterministic commonsense rules.
    Rules,
    /// An OpenAI-compatible /v1/chat/completions server.
    Openai,
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
    /// openai: the server's base URL (http only).
    #[arg(long, default_value = "http://127.0.0.1:8000")]
    url: String,
    /// openai: the model name.
    #[arg(long, default_value = "Qwen/Qwen2-VL-2B-Instruct")]
    model: String,
    /// openai: the environment variable holding the API key (never printed).
    #[arg(long, default_value = "OPENAI_API_KEY")]
    api_key_env: String,
    /// openai: the time limit of one call, ms.
    #[arg(long, default_value_t = 20_000)]
    timeout_ms: u64,
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
        RcoCommand::Bench(b) => bench(b),
    }
}

fn replay_cmd(a: ReplayArgs) -> Result<ExitCode> {
    let file = std::fs::File::open(&a.file)
        .with_context(|| format!("cannot open {}", a.file.display()))?;
    let observations = replay::read_observations(BufReader::new(file))
        .with_context(|| format!("{}", a.file.display()))?;
    if observations.is_empty() {
        bail!("{}: no observation", a.file.display());
    }
    let mut params = RcoParams {
        modules: Modules::parse(&a.modules).context("--modules")?,
        plan_limit: a.plan_limit,
        ..RcoParams::default()
    };
    params.verifier.hazard_ratio = a.hazard_ratio;
    let backend: Box<dyn Backend> = match a.backend {
        BackendArg::Rules => Box::new(RulesBackend::default()),
        BackendArg::Openai => Box::new(
            OpenAiBackend::new(OpenAiParams {
                base_url: a.url.clone(),
                model: a.model.clone(),
                api_key_env: a.api_key_env.clone(),
                timeout_ms: a.timeout_ms,
                ..OpenAiParams::default()
            })
            .context("--backend openai")?,
        ),
    };
    let mut rco = Rco::new(params, backend).context("invalid controller settings")?;
    log::info!(
        "{} observations from {} through {} ({})",
        observations.len(),
        a.file.display(),
        rco.backend(),
        a.modules
    );
    let mut out = std::io::stdout().lock();
    let mut speeds: BTreeMap<&'static str, usize> = BTreeMap::new();
    let mut sources: BTreeMap<&'static str, usize> = BTreeMap::new();
    let mut last = None;
    for obs in &observations {
        let d = rco.step(obs);
        if a.json {
            writeln!(out, "{}", serde_json::to_string(&d)?)?;
        } else {
            writeln!(out, "{}", d.summary())?;
        }
        *speeds.entry(d.action.speed.name()).or_default() += 1;
        let s = match d.source {
            Source::Plan => "plan",
            Source::Wait => "wait",
            Source::Hold => "hold",
            Source::Fallback => "fallback",
        };
        *sources.entry(s).or_default() += 1;
        last = Some(d);
    }
    if let (false, Some(d)) = (a.json, last) {
        let c = d.counters;
        let n = observations.len();
        writeln!(out)?;
        writeln!(
            out,
            "{n} ticks: {} planning rounds, {} refusals, {} fallbacks; {} backend calls, {:.3} ms mean latency",
            c.replans_total,
            c.refusals_total,
            c.fallbacks_total,
            c.llm_calls_total,
            if c.llm_calls_total > 0 {
                c.llm_latency_ms_total / c.llm_calls_total as f64
            } else {
                0.0
            }
        )?;
        let share = |m: &BTreeMap<&str, usize>| {
            m.iter()
                .map(|(k, v)| format!("{k} {:.0}%", 100.0 * *v as f64 / n as f64))
                .collect::<Vec<_>>()
                .join(", ")
        };
        writeln!(out, "sources: {}", share(&sources))?;
        writeln!(out, "speed controls: {}", share(&speeds))?;
    }
    Ok(ExitCode::SUCCESS)
}

#[derive(Serialize)]
struct Figures {
    case: String,
    ticks: u64,
    median_us: f64,
    p95_us: f64,
    max_us: f64,
    mean_us: f64,
    goal_us: f64,
    met: bool,
}

fn figures(case: &str, mut us: Vec<f64>) -> Figures {
    us.sort_by(f64::total_cmp);
    let n = us.len().max(1);
    let q = |p: f64| {
        us.get(((n as f64 - 1.0) * p).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    let p95 = q(0.95);
    Figures {
        case: case.into(),
        ticks: us.len() as u64,
        median_us: q(0.5),
        p95_us: p95,
        max_us: us.last().copied().unwrap_or(0.0),
        mean_us: us.iter().sum::<f64>() / n as f64,
        goal_us: 1000.0,
        met: p95 <= 1000.0,
    }
}

fn bench(a: BenchArgs) -> Result<ExitCode> {
    if a.ticks == 0 {
        bail!("--ticks must be at least 1");
    }
    let params = RcoParams::default();
    let warm = 10u64;
    let mut rows = Vec::new();
    // 3 px/tick: the deficits stay within the shift limit (image-space check only);
    // 14 px/tick: above the 11.5 px limit, so the verifier matches the background every tick.
    for flow in [3u32, 14] {
        let scene = BenchScene {
            seed: a.seed,
            flow_px_per_tick: flow,
        };
        log::info!(
            "rendering and timing {} ticks at {flow} px/tick",
            a.ticks + warm
        );
        let mut verifier_us = Vec::new();
        let mut tick_us = Vec::new();
        let mut rco = Rco::with_rules(params.clone())?;
        let mut prev = None;
        for t in 0..a.ticks + warm {
            let obs = scene.observation(t);
            let t0 = Instant::now();
            let s = verifier::assess(prev.as_ref(), &obs, &params.views, &params.verifier);
            let v = t0.elapsed().as_secs_f64() * 1e6;
            std::hint::black_box(&s);
            let t0 = Instant::now();
            let d = rco.step(&obs);
            let r = t0.elapsed().as_secs_f64() * 1e6;
            std::hint::black_box(&d);
            if t >= warm {
                verifier_us.push(v);
                tick_us.push(r);
            }
            prev = Some(obs);
        }
        rows.push(figures(
            &format!("verifier, scene flow {flow} px/tick"),
            verifier_us,
        ));
        rows.push(figures(
            &format!("rules tick (step), scene flow {flow} px/tick"),
            tick_us,
        ));
    }
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&rows)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(
        out,
        "three 576x320 views (cross-left, front-wide, cross-right), {} timed ticks per case, one thread",
        a.ticks
    )?;
    writeln!(
        out,
        "{:<44} {:>10} {:>10} {:>10} {:>10}  goal",
        "case", "median µs", "p95 µs", "max µs", "mean µs"
    )?;
    for r in &rows {
        writeln!(
            out,
            "{:<44} {:>10.1} {:>10.1} {:>10.1} {:>10.1}  ≤ {:.0} µs per tick: {}",
            r.case,
            r.median_us,
            r.p95_us,
            r.max_us,
            r.mean_us,
            r.goal_us,
            if r.met { "met (p95)" } else { "NOT met (p95)" }
        )?;
    }
    if cfg!(debug_assertions) {
        writeln!(
            out,
            "(a debug build: run `cargo run --release -- rco bench` for the real figures)"
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
