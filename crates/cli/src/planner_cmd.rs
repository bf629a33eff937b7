//! `fogline planner eval` (the reference planner on generated clips, clean and perturbed: ADE,
//! decision agreement with the expert, clean-vs-perturbed L2 and explanation changes per
//! scenario) and `fogline bench world` (world generation speed and the planner's time per
//! clip).
//!
//! The per-clip work is [`evaluate_clip`]: one clip, every condition, one planner call each,
//! plain records out. It holds no I/O and no aggregation, so a campaign runner can call (or
//! mirror) it and store the records instead of summarising them.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use fogline_perturb::{Frame, Perturbation, Prepared};
use fogline_planner::ReferencePlanner;
use fogline_types::clip::{Decision, PlannerOutput, Trajectory};
use fogline_world::{Clip, ScenarioMix, WorldConfig, generate_clip};
use rayon::prelude::*;
use serde::Serialize;

use super::write_atomic;
use fogline_io::Progress;

/// Kind and version of the `--json` file of `fogline planner eval`.
const EVAL_KIND: &str = "fogline.planner_eval";
const EVAL_SCHEMA: u32 = 1;
/// The row label of the all-scenario aggregate.
const ALL: &str = "ALL";

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

// ---------------------------------------------------------------------------------------------
// The per-clip evaluation
// ---------------------------------------------------------------------------------------------

/// What the planner answered on one clip under one condition.
#[derive(Debug, Clone)]
pub(crate) struct Answer {
    /// The planned trajectory (validated: 64 finite waypoints).
    pub trajectory: Trajectory,
    /// The explanation.
    pub explanation: String,
    /// The stated decision.
    pub decision: Option<Decision>,
    /// ADE against the clip's ground truth, m.
    pub ade_m: f64,
}

/// One planner call: its answer or why it failed, and the time spent in `plan()`.
#[derive(Debug, Clone)]
pub(crate) struct RunRecord {
    /// The answer, or the failure reason (a planner error or an invalid trajectory).
    pub result: std::result::Result<Answer, String>,
    /// Wall time of the `plan()` call alone, ms.
    pub plan_ms: f64,
}

/// Every condition's run on one clip.
#[derive(Debug, Clone)]
pub(crate) struct ClipEval {
    /// Index of the clip in the corpus.
    pub index: usize,
    /// The scenario label.
    pub scenario: String,
    /// The expert's decision.
    pub expert: Option<Decision>,
    /// One record per condition, in the order given to [`evaluate_clip`].
    pub runs: Vec<RunRecord>,
}

/// The frames the planner sees of every camera of `clip` under `cond` (see
/// [`fogline_campaign::runner::condition_frames`]).
pub(crate) fn condition_frames<'c>(
    clip: &'c Clip,
    key: u64,
    cond: &Prepared,
) -> Result<Vec<Vec<Cow<'c, Frame>>>> {
    fogline_campaign::runner::condition_frames(clip, key, cond).map_err(anyhow::Error::msg)
}

/// Runs the planner once on `frames` (one list per camera of `clip`) and the clip's ego
/// history, timing the `plan()` call alone.
pub(crate) fn run_planner(
    planner: &ReferencePlanner,
    clip: &Clip,
    frames: &[Vec<Cow<'_, Frame>>],
) -> RunRecord {
    let input = fogline_campaign::runner::planner_input(clip, frames);
    let t = Instant::now();
    let out = planner.plan(&input);
    let plan_ms = t.elapsed().as_secs_f64() * 1e3;
    RunRecord {
        result: answer(out.map_err(|e| e.to_string()), &clip.ground_truth),
        plan_ms,
    }
}

fn answer(
    out: std::result::Result<PlannerOutput, String>,
    truth: &Trajectory,
) -> std::result::Result<Answer, String> {
    let out = out?;
    out.trajectory
        .validate()
        .map_err(|e| format!("invalid trajectory: {e}"))?;
    Ok(Answer {
        ade_m: out.trajectory.ade(truth),
        trajectory: out.trajectory,
        explanation: out.explanation,
        decision: out.decision,
    })
}

/// Evaluates the planner on one clip under every condition (one `plan()` call each).
/// Perturbation errors are errors; planner errors are recorded as failed runs.
pub(crate) fn evaluate_clip(
    planner: &ReferencePlanner,
    clip: &Clip,
    index: usize,
    conditions: &[Prepared],
) -> Result<ClipEval> {
    let key = fogline_campaign::runner::clip_key(index);
    let runs = conditions
        .iter()
        .map(|cond| {
            let frames = condition_frames(clip, key, cond)?;
            Ok(run_planner(planner, clip, &frames))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(ClipEval {
        index,
        scenario: clip.scenario.clone(),
        expert: clip.scene.decision,
        runs,
    })
}

// ---------------------------------------------------------------------------------------------
// Figures
// ---------------------------------------------------------------------------------------------

/// One row of a condition's table (a scenario, or all clips).
#[derive(Debug, Clone, Serialize)]
struct Row {
    scenario: String,
    /// Clips.
    n: usize,
    /// Clips the planner answered (valid trajectory).
    answered: usize,
    /// Clips it failed on.
    failed: usize,
    /// Median / mean ADE vs the ground truth over answered clips, m.
    ade_median_m: Option<f64>,
    ade_mean_m: Option<f64>,
    /// Share of answered clips whose decision equals the expert's, in [0, 1].
    agreement: Option<f64>,
    /// Mean L2 between the clean and this condition's trajectory over clips answered in both,
    /// m (`null` for the clean condition).
    l2_vs_clean_mean_m: Option<f64>,
    /// Share of clips answered in both whose explanation text differs from the clean one.
    explanation_changed: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
struct Timing {
    median_ms: Option<f64>,
    p95_ms: Option<f64>,
    mean_ms: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
struct Failure {
    reason: String,
    clips: usize,
}

#[derive(Debug, Clone, Serialize)]
struct ConditionReport {
    condition: String,
    /// Whether this is the clean reference.
    reference: bool,
    /// Time inside `plan()` per clip (all calls, answered or not).
    plan_time: Timing,
    overall: Row,
    /// One row per scenario, in the mix order.
    scenarios: Vec<Row>,
    failures: Vec<Failure>,
}

#[derive(Debug, Clone, Serialize)]
struct ConfusionCell {
    expert: String,
    /// The planner's decision, `none` (no decision stated) or `failed`.
    planner: String,
    clips: usize,
}

#[derive(Debug, Clone, Serialize)]
struct EvalReport {
    kind: &'static str,
    schema_version: u32,
    generated_by: String,
    clips: usize,
    seed: u64,
    perturb_seed: u64,
    width: u32,
    height: u32,
    cameras: usize,
    frames_per_camera: usize,
    threads: usize,
    wall_s: f64,
    mix: Vec<MixEntry>,
    conditions: Vec<ConditionReport>,
    /// Expert → planner decision counts on the clean condition.
    clean_confusion: Vec<ConfusionCell>,
}

#[derive(Debug, Clone, Serialize)]
struct MixEntry {
    scenario: String,
    clips: usize,
}

fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// Nearest-rank percentile (`q` in (0, 1]).
fn percentile(v: &mut [f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    Some(v[rank - 1])
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn share(hits: usize, n: usize) -> Option<f64> {
    (n > 0).then(|| hits as f64 / n as f64)
}

fn timing(mut ms: Vec<f64>) -> Timing {
    Timing {
        mean_ms: mean(&ms),
        p95_ms: percentile(&mut ms, 0.95),
        median_ms: median(&mut ms),
    }
}

/// The row over `evals` for condition `c` (0 is the clean reference).
fn row(scenario: &str, evals: &[&ClipEval], c: usize) -> Row {
    let mut ades = Vec::new();
    let (mut agree, mut with_expert) = (0, 0);
    let mut l2 = Vec::new();
    let (mut changed, mut both) = (0, 0);
    for e in evals {
        let Ok(a) = &e.runs[c].result else { continue };
        ades.push(a.ade_m);
        if let Some(x) = e.expert {
            with_expert += 1;
            agree += usize::from(a.decision == Some(x));
        }
        if c > 0
            && let Ok(clean) = &e.runs[0].result
        {
            both += 1;
            l2.push(clean.trajectory.l2(&a.trajectory));
            changed += usize::from(clean.explanation != a.explanation);
        }
    }
    let answered = ades.len();
    Row {
        scenario: scenario.to_string(),
        n: evals.len(),
        answered,
        failed: evals.len() - answered,
        ade_mean_m: mean(&ades),
        ade_median_m: median(&mut ades),
        agreement: share(agree, with_expert),
        l2_vs_clean_mean_m: (c > 0).then(|| mean(&l2)).flatten(),
        explanation_changed: (c > 0).then(|| share(changed, both)).flatten(),
    }
}

fn condition_report(
    name: &str,
    mix: &ScenarioMix,
    evals: &[ClipEval],
    c: usize,
) -> ConditionReport {
    let all: Vec<&ClipEval> = evals.iter().collect();
    let scenarios = mix
        .counts
        .iter()
        .filter(|(_, n)| *n > 0)
        .map(|(s, _)| {
            let of: Vec<&ClipEval> = evals.iter().filter(|e| &e.scenario == s).collect();
            row(s, &of, c)
        })
        .collect();
    let mut failures: BTreeMap<&str, usize> = BTreeMap::new();
    for e in evals {
        if let Err(why) = &e.runs[c].result {
            *failures.entry(why).or_default() += 1;
        }
    }
    let mut failures: Vec<Failure> = failures
        .into_iter()
        .map(|(reason, clips)| Failure {
            reason: reason.to_string(),
            clips,
        })
        .collect();
    failures.sort_by(|a, b| b.clips.cmp(&a.clips).then_with(|| a.reason.cmp(&b.reason)));
    ConditionReport {
        condition: name.to_string(),
        reference: c == 0,
        plan_time: timing(evals.iter().map(|e| e.runs[c].plan_ms).collect()),
        overall: row(ALL, &all, c),
        scenarios,
        failures,
    }
}

const NONE: &str = "none";
const FAILED: &str = "failed";

fn confusion(evals: &[ClipEval]) -> Vec<ConfusionCell> {
    let mut counts: BTreeMap<(String, String), usize> = BTreeMap::new();
    for e in evals {
        let expert = e.expert.map_or(NONE, Decision::name).to_string();
        let planner = match &e.runs[0].result {
            Ok(a) => a.decision.map_or(NONE, Decision::name),
            Err(_) => FAILED,
        };
        *counts.entry((expert, planner.to_string())).or_default() += 1;
    }
    // Order rows and columns as Decision::ALL, then none, then failed.
    let rank = |s: &str| {
        Decision::ALL
            .iter()
            .position(|d| d.name() == s)
            .unwrap_or(if s == NONE { 10 } else { 11 })
    };
    let mut cells: Vec<ConfusionCell> = counts
        .into_iter()
        .map(|((expert, planner), clips)| ConfusionCell {
            expert,
            planner,
            clips,
        })
        .collect();
    cells.sort_by_key(|c| (rank(&c.expert), rank(&c.planner)));
    cells
}

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

// ---------------------------------------------------------------------------------------------
// fogline planner eval
// ---------------------------------------------------------------------------------------------

/// Parses `--conditions`: the clean reference first, then the others in the given order.
fn parse_conditions(names: &[String], seed: u64) -> Result<Vec<Prepared>> {
    let mut out = vec![Perturbation::identity()];
    for name in names {
        let p = Perturbation::parse(name).with_context(|| format!("--conditions: {name:?}"))?;
        if p.name == "clean" || p.name == "identity" {
            continue;
        }
        if out.iter().any(|q| q.name == p.name) {
            bail!("--conditions: {} is listed twice", p.name);
        }
        out.push(p);
    }
    out.iter()
        .map(|p| {
            p.prepare(seed)
                .with_context(|| format!("--conditions: {}", p.name))
        })
        .collect()
}

fn world_config(clips: usize, seed: u64, width: u32, height: u32) -> Result<WorldConfig> {
    if clips == 0 {
        bail!("--clips must be at least 1");
    }
    let cfg = WorldConfig {
        seed,
        width,
        height,
        depth: true,
        mix: ScenarioMix::paper_scaled(clips),
    };
    cfg.validate().context("invalid world settings")?;
    Ok(cfg)
}

fn eval(a: EvalArgs) -> Result<ExitCode> {
    let cfg = world_config(a.clips, a.seed, a.width, a.height)?;
    let conditions = parse_conditions(&a.conditions, a.perturb_seed)?;
    let names: Vec<String> = conditions
        .iter()
        .map(|p| p.perturbation().name.clone())
        .collect();
    let planner = ReferencePlanner::new();
    let threads = rayon::current_num_threads();
    log::info!(
        "planner eval: {} clips (seed {}), {}x{}, conditions {} (perturb seed {}), {threads} threads",
        a.clips,
        a.seed,
        a.width,
        a.height,
        names.join(", "),
        a.perturb_seed
    );
    let t0 = Instant::now();
    let progress = Progress::new(a.clips, "clips");
    // An indexed parallel iterator collects in index order: the records do not depend on the
    // number of threads (only the timings do).
    let evals = (0..a.clips)
        .into_par_iter()
        .map(|i| {
            let clip =
                generate_clip(&cfg, i).with_context(|| format!("cannot generate clip {i}"))?;
            let e = evaluate_clip(&planner, &clip, i, &conditions);
            progress.inc();
            e
        })
        .collect::<Result<Vec<ClipEval>>>();
    progress.finish();
    let mut evals = evals?;
    evals.sort_by_key(|e| e.index);
    let wall_s = t0.elapsed().as_secs_f64();
    log::info!("evaluated {} clips in {wall_s:.1} s", evals.len());

    let report = EvalReport {
        kind: EVAL_KIND,
        schema_version: EVAL_SCHEMA,
        generated_by: format!("fogline {}", env!("CARGO_PKG_VERSION")),
        clips: a.clips,
        seed: a.seed,
        perturb_seed: a.perturb_seed,
        width: a.width,
        height: a.height,
        cameras: fogline_types::clip::CameraId::ALL.len(),
        frames_per_camera: fogline_types::clip::FRAMES,
        threads,
        wall_s,
        mix: cfg
            .mix
            .counts
            .iter()
            .map(|(s, n)| MixEntry {
                scenario: s.clone(),
                clips: *n,
            })
            .collect(),
        conditions: names
            .iter()
            .enumerate()
            .map(|(c, name)| condition_report(name, &cfg.mix, &evals, c))
            .collect(),
        clean_confusion: confusion(&evals),
    };
    if let Some(path) = &a.json {
        let bytes = serde_json::to_vec_pretty(&report).context("cannot serialise the figures")?;
        write_atomic(path, &bytes)?;
        log::info!("wrote {}", path.display());
    }
    print_eval(&report)?;
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

/// The world speed goal: 1,996 clips in at most this many seconds on two cores.
const WORLD_GOAL_S: f64 = 60.0;
/// The planner speed goal, ms per clip on one thread.
const PLAN_GOAL_MS: f64 = 5.0;
/// The paper's corpus size, the world goal's unit.
const PAPER_CLIPS: usize = 1996;

/// Runs `fogline bench world`.
pub fn bench_world(a: BenchWorldArgs) -> Result<ExitCode> {
    let cfg = world_config(a.clips, a.seed, a.width, a.height)?;
    let plan_clips = a.plan_clips.unwrap_or(a.clips).min(a.clips);
    let threads = rayon::current_num_threads();
    log::info!(
        "bench world: {} clips at {}x{} (4 cameras x 4 frames, RGB + depth + boxes), {threads} threads; then the planner on {plan_clips} clips, one thread",
        a.clips,
        a.width,
        a.height
    );

    // (a) generation + rendering on every core. One clip first, untimed, to warm up.
    std::hint::black_box(generate_clip(&cfg, 0)?);
    let progress = Progress::new(a.clips, "clips");
    let t = Instant::now();
    let bytes: usize = (0..a.clips)
        .into_par_iter()
        .map(|i| {
            let clip = generate_clip(&cfg, i)?;
            progress.inc();
            Ok(std::hint::black_box(clip)
                .cameras
                .iter()
                .flat_map(|c| &c.frames)
                .map(|f| f.image.data().len())
                .sum::<usize>())
        })
        .collect::<Result<Vec<usize>, fogline_world::WorldError>>()?
        .into_iter()
        .sum();
    let world_s = t.elapsed().as_secs_f64();
    progress.finish();
    let clips_per_s = a.clips as f64 / world_s;
    let ms_per_clip = world_s * 1e3 / a.clips as f64;
    let projected_s = world_s * PAPER_CLIPS as f64 / a.clips as f64;
    log::info!(
        "generated {} clips ({:.1} MB of RGB) in {world_s:.2} s",
        a.clips,
        bytes as f64 / 1e6
    );

    // (b) the planner, one thread, under each condition: clips are generated in parallel in
    // small batches (untimed), perturbed (untimed), then planned one after the other on this
    // thread while the pool is idle.
    let conditions = parse_conditions(&a.plan_conditions, a.perturb_seed)?;
    let planner = ReferencePlanner::new();
    let mut plan_ms: Vec<Vec<f64>> = vec![Vec::with_capacity(plan_clips); conditions.len()];
    let mut failures: BTreeMap<(usize, String), usize> = BTreeMap::new();
    let batch = (2 * threads).max(1);
    let progress = Progress::new(plan_clips, "clips planned");
    let mut warmed = false;
    for start in (0..plan_clips).step_by(batch) {
        let end = (start + batch).min(plan_clips);
        let clips = (start..end)
            .into_par_iter()
            .map(|i| generate_clip(&cfg, i))
            .collect::<Result<Vec<Clip>, _>>()?;
        for (clip, i) in clips.iter().zip(start..end) {
            let key = fogline_campaign::runner::clip_key(i);
            for (c, cond) in conditions.iter().enumerate() {
                let frames = condition_frames(clip, key, cond)?;
                if !warmed {
                    std::hint::black_box(run_planner(&planner, clip, &frames));
                    warmed = true;
                }
                let rec = run_planner(&planner, clip, &frames);
                match rec.result {
                    Ok(_) => plan_ms[c].push(rec.plan_ms),
                    Err(why) => *failures.entry((c, why)).or_default() += 1,
                }
            }
            progress.inc();
        }
    }
    progress.finish();
    let names: Vec<String> = conditions
        .iter()
        .map(|p| p.perturbation().name.clone())
        .collect();
    let answered: Vec<usize> = plan_ms.iter().map(Vec::len).collect();
    let plans: Vec<Timing> = plan_ms.into_iter().map(timing).collect();

    let world_met = projected_s <= WORLD_GOAL_S;
    let met = |t: &Timing| t.median_ms.map(|m| m <= PLAN_GOAL_MS);
    let mut out = std::io::stdout().lock();
    if a.json {
        let v = serde_json::json!({
            "world": {
                "clips": a.clips,
                "width": a.width,
                "height": a.height,
                "cameras": fogline_types::clip::CameraId::ALL.len(),
                "frames_per_camera": fogline_types::clip::FRAMES,
                "depth": true,
                "threads": threads,
                "wall_s": world_s,
                "clips_per_s": clips_per_s,
                "ms_per_clip": ms_per_clip,
                "core_ms_per_clip": ms_per_clip * threads as f64,
                "projected_1996_clips_s": projected_s,
                "goal": format!("{PAPER_CLIPS} clips <= {WORLD_GOAL_S} s on two cores"),
                "goal_s": WORLD_GOAL_S,
                "met": world_met,
            },
            "planner": names.iter().enumerate().map(|(c, name)| serde_json::json!({
                "condition": name,
                "clips": plan_clips,
                "answered": answered[c],
                "threads": 1,
                "median_ms": plans[c].median_ms,
                "p95_ms": plans[c].p95_ms,
                "mean_ms": plans[c].mean_ms,
                "goal": format!("<= {PLAN_GOAL_MS} ms per clip, one thread"),
                "goal_ms": PLAN_GOAL_MS,
                "met": met(&plans[c]),
                "failures": failures.iter().filter(|((k, _), _)| *k == c).map(|((_, reason), clips)| serde_json::json!({
                    "reason": reason, "clips": clips,
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(
        out,
        "fogline bench world: {} clips, {}x{}, 4 cameras x 4 frames, RGB + depth + boxes, in memory",
        a.clips, a.width, a.height
    )?;
    writeln!(
        out,
        "world    {threads} threads: {world_s:.2} s wall, {clips_per_s:.1} clips/s, {ms_per_clip:.1} ms/clip ({:.1} core-ms/clip)",
        ms_per_clip * threads as f64
    )?;
    writeln!(
        out,
        "goal     {PAPER_CLIPS} clips <= {WORLD_GOAL_S:.0} s on two cores: {projected_s:.1} s at {threads} threads{}  {}",
        if a.clips == PAPER_CLIPS {
            ""
        } else {
            " (projected)"
        },
        if world_met { "met" } else { "NOT met" }
    )?;
    for (c, name) in names.iter().enumerate() {
        let plan = &plans[c];
        writeln!(
            out,
            "planner  {name}, one thread, {} of {plan_clips} clips answered: {} ms/clip median, {} p95, {} mean; goal <= {PLAN_GOAL_MS:.0} ms/clip median: {}",
            answered[c],
            fmt_ms(plan.median_ms),
            fmt_ms(plan.p95_ms),
            fmt_ms(plan.mean_ms),
            match met(plan) {
                Some(true) => "met",
                Some(false) => "NOT met",
                None => "not measured (no clip answered)",
            }
        )?;
    }
    for ((c, reason), clips) in &failures {
        writeln!(
            out,
            "planner failed under {} on {clips} clips: {reason}",
            names[*c]
        )?;
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_statistics() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&mut []), None);
        let mut v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&mut v, 0.95), Some(95.0));
        assert_eq!(percentile(&mut [7.0], 0.95), Some(7.0));
    }

    #[test]
    fn conditions_put_clean_first_and_refuse_repeats() {
        let c = parse_conditions(&["noise_30".into(), "clean".into(), "dark".into()], 0).unwrap();
        let names: Vec<&str> = c.iter().map(|p| p.perturbation().name.as_str()).collect();
        assert_eq!(names, ["clean", "noise_30", "dark"]);
        assert!(parse_conditions(&["dark".into(), "dark".into()], 0).is_err());
        assert!(parse_conditions(&["bogus_1".into()], 0).is_err());
    }
}
