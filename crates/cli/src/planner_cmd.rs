//! `fogline planner eval` and `fogline bench world`: their arguments and output; the
//! evaluation is `fogline_api::planner_eval`, the benchmark `fogline_bench::world`.

use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use fogline_api::planner_eval::{ConfusionCell, EvalReport, FAILED, NONE, PlannerEval, evaluate};

use fogline_types::clip::Decision;

use super::write_atomic;

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
        write_atomic(path, &bytes)?;
        log::info!("wrote {}", path.display());
    }
    print_eval(&report)?;
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

fn fmt_m(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.2}"))
}

fn fmt_pct(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{:.1}%", 100.0 * v))
}

fn fmt_ms(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.2}"))
}

fn print_eval(r: &EvalReport) -> Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "fogline planner eval: {} clips (seed {}), {}x{}, {} cameras x {} frames, perturb seed {}, {} threads, {:.1} s",
        r.clips,
        r.seed,
        r.width,
        r.height,
        r.cameras,
        r.frames_per_camera,
        r.perturb_seed,
        r.threads,
        r.wall_s
    )?;
    for c in &r.conditions {
        writeln!(out)?;
        writeln!(
            out,
            "condition {}{}: plan() {} ms/clip median, {} p95",
            c.condition,
            if c.reference { " (reference)" } else { "" },
            fmt_ms(c.plan_time.median_ms),
            fmt_ms(c.plan_time.p95_ms)
        )?;
        writeln!(
            out,
            "{:<14} {:>5} {:>6} {:>8} {:>8} {:>7} {:>9} {:>8}",
            "scenario", "n", "failed", "ADE med", "ADE mean", "agree", "L2 clean", "CoC chg"
        )?;
        for row in c.scenarios.iter().chain(std::iter::once(&c.overall)) {
            writeln!(
                out,
                "{:<14} {:>5} {:>6} {:>8} {:>8} {:>7} {:>9} {:>8}",
                row.scenario,
                row.n,
                row.failed,
                fmt_m(row.ade_median_m),
                fmt_m(row.ade_mean_m),
                fmt_pct(row.agreement),
                fmt_m(row.l2_vs_clean_mean_m),
                fmt_pct(row.explanation_changed),
            )?;
        }
        for f in &c.failures {
            writeln!(out, "failed on {} clips: {}", f.clips, f.reason)?;
        }
    }
    if r.conditions.len() > 1 {
        writeln!(out)?;
        writeln!(out, "all scenarios, by condition")?;
        writeln!(
            out,
            "{:<22} {:>6} {:>8} {:>8} {:>7} {:>9} {:>8} {:>8}",
            "condition", "failed", "ADE med", "ADE mean", "agree", "L2 clean", "CoC chg", "plan ms"
        )?;
        for c in &r.conditions {
            let o = &c.overall;
            writeln!(
                out,
                "{:<22} {:>6} {:>8} {:>8} {:>7} {:>9} {:>8} {:>8}",
                c.condition,
                o.failed,
                fmt_m(o.ade_median_m),
                fmt_m(o.ade_mean_m),
                fmt_pct(o.agreement),
                fmt_m(o.l2_vs_clean_mean_m),
                fmt_pct(o.explanation_changed),
                fmt_ms(c.plan_time.median_ms),
            )?;
        }
    }
    print_confusion(&mut out, &r.clean_confusion)?;
    Ok(())
}

fn print_confusion(out: &mut impl std::io::Write, cells: &[ConfusionCell]) -> Result<()> {
    let mut rows: Vec<&str> = Vec::new();
    let mut cols: Vec<&str> = Vec::new();
    for c in cells {
        if !rows.contains(&c.expert.as_str()) {
            rows.push(&c.expert);
        }
    }
    // Columns: every decision seen on either side (in Decision::ALL order), then none, failed.
    for d in Decision::ALL {
        if cells
            .iter()
            .any(|c| c.expert == d.name() || c.planner == d.name())
        {
            cols.push(d.name());
        }
    }
    for extra in [NONE, FAILED] {
        if cells.iter().any(|c| c.planner == extra) {
            cols.push(extra);
        }
    }
    writeln!(out)?;
    writeln!(
        out,
        "decisions, clean: expert (rows) -> planner (columns), clips"
    )?;
    write!(out, "{:<19}", "expert")?;
    for c in &cols {
        write!(out, " {:>6}", short(c))?;
    }
    writeln!(out)?;
    for r in &rows {
        write!(out, "{r:<19}")?;
        for c in &cols {
            let n = cells
                .iter()
                .find(|x| x.expert == *r && x.planner == *c)
                .map_or(0, |x| x.clips);
            if n == 0 {
                write!(out, " {:>6}", ".")?;
            } else {
                write!(out, " {n:>6}")?;
            }
        }
        writeln!(out)?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// fogline bench world
// ---------------------------------------------------------------------------------------------

/// Column labels of the printed confusion matrix.
fn short(name: &str) -> &str {
    match name {
        "keep_lane" => "keep",
        "follow_lead" => "follow",
        "slow_for_lead" => "slow",
        "nudge_right" => "nudge",
        "pass_left" => "pass",
        "turn_right" => "turn_r",
        "stop_for_sign" => "sign",
        "stop_for_red_light" => "red",
        "proceed_on_green" => "green",
        "yield_to_crossing" => "yield",
        other => other,
    }
}
