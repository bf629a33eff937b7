//! The reference planner on generated clips, clean and perturbed (what `fogline planner
//! eval` runs): ADE, decision agreement with the expert, clean-vs-perturbed L2 and
//! explanation changes per scenario, and the per-clip pieces `fogline bench world` times.
//!
//! The per-clip work is [`evaluate_clip`]: one clip, every condition, one planner call each,
//! plain records out. It holds no I/O and no aggregation, so a campaign runner can call (or
//! mirror) it and store the records instead of summarising them.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Write;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use fogline_io::Progress;
use fogline_perturb::{Frame, Perturbation, Prepared};
use fogline_planner::ReferencePlanner;
use fogline_types::clip::{Decision, PlannerOutput, Trajectory};
use fogline_world::{Clip, ScenarioMix, WorldConfig, generate_clip};
use rayon::prelude::*;
use serde::Serialize;

/// Kind and version of the report (`fogline planner eval --json`).
pub const EVAL_KIND: &str = "fogline.planner_eval";
/// Schema version of the report.
pub const EVAL_SCHEMA: u32 = 1;
/// The row label of the all-scenario aggregate.
pub const ALL: &str = "ALL";

/// What `fogline planner eval` evaluates.
#[derive(Debug, Clone)]
pub struct PlannerEval {
    /// Clips, the paper's scenario mix scaled to this number.
    pub clips: usize,
    /// World seed: clip i is drawn from (seed, i) alone.
    pub seed: u64,
    /// Conditions (`clean` is always evaluated, first: the reference of the L2 and
    /// explanation-change columns).
    pub conditions: Vec<String>,
    /// Seed of the perturbations' random streams.
    pub perturb_seed: u64,
    /// Image width of every camera, pixels.
    pub width: u32,
    /// Image height of every camera, pixels.
    pub height: u32,
}

/// What the planner answered on one clip under one condition.
#[derive(Debug, Clone)]
pub struct Answer {
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
pub struct RunRecord {
    /// The answer, or the failure reason (a planner error or an invalid trajectory).
    pub result: std::result::Result<Answer, String>,
    /// Wall time of the `plan()` call alone, ms.
    pub plan_ms: f64,
}

/// Every condition's run on one clip.
#[derive(Debug, Clone)]
pub struct ClipEval {
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
pub fn condition_frames<'c>(
    clip: &'c Clip,
    key: u64,
    cond: &Prepared,
) -> Result<Vec<Vec<Cow<'c, Frame>>>> {
    fogline_campaign::runner::condition_frames(clip, key, cond).map_err(anyhow::Error::msg)
}

/// Runs the planner once on `frames` (one list per camera of `clip`) and the clip's ego
/// history, timing the `plan()` call alone.
pub fn run_planner(
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
pub fn evaluate_clip(
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
pub struct Row {
    /// The scenario, or `ALL`.
    pub scenario: String,
    /// Clips.
    pub n: usize,
    /// Clips the planner answered (valid trajectory).
    pub answered: usize,
    /// Clips it failed on.
    pub failed: usize,
    /// Median ADE vs the ground truth over answered clips, m.
    pub ade_median_m: Option<f64>,
    /// Mean ADE vs the ground truth over answered clips, m.
    pub ade_mean_m: Option<f64>,
    /// Share of answered clips whose decision equals the expert's, in [0, 1].
    pub agreement: Option<f64>,
    /// Mean L2 between the clean and this condition's trajectory over clips answered in both,
    /// m (`null` for the clean condition).
    pub l2_vs_clean_mean_m: Option<f64>,
    /// Share of clips answered in both whose explanation text differs from the clean one.
    pub explanation_changed: Option<f64>,
}

/// Order statistics of per-clip times (none when nothing was timed).
#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    /// Median, ms.
    pub median_ms: Option<f64>,
    /// 95th percentile, ms.
    pub p95_ms: Option<f64>,
    /// Mean, ms.
    pub mean_ms: Option<f64>,
}

/// A reason the planner failed and on how many clips.
#[derive(Debug, Clone, Serialize)]
pub struct Failure {
    /// Why.
    pub reason: String,
    /// Clips.
    pub clips: usize,
}

/// The figures of one condition.
#[derive(Debug, Clone, Serialize)]
pub struct ConditionReport {
    /// Its name.
    pub condition: String,
    /// Whether this is the clean reference.
    pub reference: bool,
    /// Time inside `plan()` per clip (all calls, answered or not).
    pub plan_time: Timing,
    /// All clips.
    pub overall: Row,
    /// One row per scenario, in the mix order.
    pub scenarios: Vec<Row>,
    /// Why the planner failed, on how many clips.
    pub failures: Vec<Failure>,
}

/// One cell of the expert-vs-planner decision table.
#[derive(Debug, Clone, Serialize)]
pub struct ConfusionCell {
    /// The expert's decision.
    pub expert: String,
    /// The planner's decision, `none` (no decision stated) or `failed`.
    pub planner: String,
    /// Clips.
    pub clips: usize,
}

/// The evaluation's figures (`fogline planner eval --json` writes them).
#[derive(Debug, Clone, Serialize)]
pub struct EvalReport {
    /// [`EVAL_KIND`].
    pub kind: String,
    /// [`EVAL_SCHEMA`].
    pub schema_version: u32,
    /// The producing tool and version.
    pub generated_by: String,
    /// Clips.
    pub clips: usize,
    /// World seed.
    pub seed: u64,
    /// Seed of the perturbations.
    pub perturb_seed: u64,
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Cameras per clip.
    pub cameras: usize,
    /// Frames per camera.
    pub frames_per_camera: usize,
    /// Worker threads.
    pub threads: usize,
    /// Wall time, s.
    pub wall_s: f64,
    /// The scenario mix.
    pub mix: Vec<MixEntry>,
    /// One report per condition, `clean` first.
    pub conditions: Vec<ConditionReport>,
    /// Expert → planner decision counts on the clean condition.
    pub clean_confusion: Vec<ConfusionCell>,
}

/// A scenario of the mix and its clips.
#[derive(Debug, Clone, Serialize)]
pub struct MixEntry {
    /// The scenario.
    pub scenario: String,
    /// Clips.
    pub clips: usize,
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

/// Median, p95 and mean of per-call times, ms.
pub fn timing(mut ms: Vec<f64>) -> Timing {
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

/// The planner column of clips where it stated no decision.
pub const NONE: &str = "none";
/// The planner column of clips it failed on.
pub const FAILED: &str = "failed";

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

// ---------------------------------------------------------------------------------------------
// fogline planner eval
// ---------------------------------------------------------------------------------------------

/// Parses `--conditions`: the clean reference first, then the others in the given order.
/// `clean` first, then the named conditions, prepared with `seed` (no repeats).
pub fn parse_conditions(names: &[String], seed: u64) -> Result<Vec<Prepared>> {
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

/// The world of `clips` clips in the paper's mix, scaled (errors name the flag).
pub fn world_config(clips: usize, seed: u64, width: u32, height: u32) -> Result<WorldConfig> {
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

/// Evaluates the reference planner on `o.clips` generated clips under every condition
/// (all cores; the records do not depend on the number of threads, only the timings do).
pub fn evaluate(o: &PlannerEval) -> Result<EvalReport> {
    let a = o;
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
        kind: EVAL_KIND.into(),
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
    Ok(report)
}

/// The world speed goal: 1,996 clips in at most this many seconds on two cores.
pub const WORLD_GOAL_S: f64 = 60.0;
/// The planner speed goal, ms per clip on one thread.
pub const PLAN_GOAL_MS: f64 = 5.0;
/// The paper's corpus size, the world goal's unit.
pub const PAPER_CLIPS: usize = 1996;

// ---------------------------------------------------------------------------------------------
// The report as text
// ---------------------------------------------------------------------------------------------

fn fmt_m(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.2}"))
}

fn fmt_pct(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{:.1}%", 100.0 * v))
}

fn fmt_ms(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.2}"))
}

impl EvalReport {
    /// The report as the tables `fogline planner eval` prints.
    pub fn write_text(&self, out: &mut dyn Write) -> Result<()> {
        write_eval(self, out)
    }
}

fn write_eval(r: &EvalReport, out: &mut dyn Write) -> Result<()> {
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
    print_confusion(out, &r.clean_confusion)?;
    Ok(())
}

fn print_confusion(out: &mut dyn Write, cells: &[ConfusionCell]) -> Result<()> {
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
