//! Scoring a backend on a data set (the paper's figure 6): every sample's five frames go
//! through the controller's own hazard inference query
//! (`fogline_rco::backend::prompt::hazard_query`, 15 images: three views × five frames) to
//! a [`Backend`]; the answer is parsed and validated exactly as the controller does
//! (`fogline_rco::backend::answer::parse_hazard`). Then, as the controller does, the
//! short-term motion planner's query for the strategy the hazard inference chose
//! (`move_query` or `som_query`, the last frame's three views, told the hazards inferred)
//! goes to the same backend, its answer is validated (`parse_move`, `parse_som`) and a move
//! plan's first step is verified against the last frame (`verifier::check_states`). A
//! failed call or a rejected answer is counted as invalid (and wrong on the tasks it
//! answers); it never stops the evaluation.
//!
//! The hazard answered for the sample is the first one in the view that shows the hidden
//! object at the last frame (the front view when it does), else the first hazard. Its
//! object and motion are read into the label vocabulary with
//! [`HiddenClass::classify`](fogline_rco::deficit_eval::HiddenClass::classify) and
//! [`MotionLabel::classify`](fogline_rco::deficit_eval::MotionLabel::classify). The plan's
//! strategy is what the controller does with it at once
//! ([`SampleAnswer::plan_strategy`](fogline_rco::deficit_eval::SampleAnswer::plan_strategy)).
//!
//! Intervals: Wilson 95 % for every accuracy and recall (`fogline_stats::proportion`), the
//! normal approximation for the mean latency.

use std::path::{Path, PathBuf};
use std::time::Instant;

use fogline_io::{FileSet, Progress};
use fogline_rco::action::HazardInference;
use fogline_rco::backend::answer::{parse_hazard, parse_move, parse_som};
use fogline_rco::backend::{Backend, Task};
use fogline_rco::deficit_eval::{
    DeficitEval, EvalRow, HiddenClass, Latency, MotionLabel, PromptLatency, Rate, SampleAnswer,
};
use fogline_rco::verifier::{Assessment, check_states};
use fogline_rco::{Behavior, Observation, SpeedControl, Strategy};
use fogline_stats::proportion::wilson;
use rayon::prelude::*;

use crate::DatasetError;
use crate::observe::{
    PLAN_LIMIT, VIEWS, WAIT_LIMIT, assessment, hazard_query, observations, plan_query,
};
use crate::sample::{Manifest, SampleRecord, Split, read_samples};

/// Settings of an evaluation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EvalParams {
    /// The split scored (`None`: every sample).
    pub split: Option<Split>,
    /// At most this many samples (the first ones of the split).
    pub limit: Option<usize>,
    /// Concurrent calls (each worker has its own backend).
    pub jobs: usize,
}

impl Default for EvalParams {
    fn default() -> Self {
        Self {
            split: Some(Split::Test),
            limit: None,
            jobs: 1,
        }
    }
}

/// Makes a backend per worker.
pub type BackendFactory<'a> = dyn Fn() -> Result<Box<dyn Backend>, DatasetError> + Sync + 'a;

/// Asks `backend` about one sample — hazard inference, then the planning prompt for the
/// strategy it chose — and scores the answers.
pub fn score_sample(
    manifest: &Manifest,
    dir: &Path,
    sample: &SampleRecord,
    backend: &mut dyn Backend,
) -> Result<SampleAnswer, DatasetError> {
    let history = observations(manifest, sample, Some(dir))?;
    let a = assessment(&history);
    let query = hazard_query(&history, &a);
    let clock = Instant::now();
    let reply = backend.answer(&query);
    let latency_ms = clock.elapsed().as_secs_f64() * 1000.0;
    let mut out = SampleAnswer {
        id: sample.id.clone(),
        class: sample.class,
        motion: sample.motion,
        strategy: sample.strategy,
        answer_object: None,
        answer_motion: None,
        answer_strategy: None,
        answer_rationale: None,
        invalid: None,
        object_ok: false,
        motion_ok: false,
        strategy_ok: false,
        latency_ms,
        plan_prompt: None,
        plan_strategy: None,
        plan_summary: None,
        plan_invalid: None,
        plan_ok: false,
        plan_latency_ms: None,
    };
    let parsed = match reply {
        Err(e) => Err(format!("no answer: {e}")),
        Ok(text) => parse_hazard(&text, &VIEWS).map_err(|e| format!("rejected: {e}")),
    };
    let h = match parsed {
        Err(why) => {
            out.invalid = Some(why);
            out.plan_invalid = Some("no hazard inference to plan from".into());
            return Ok(out);
        }
        Ok(h) => h,
    };
    let camera = sample.target_camera();
    let hazard = h
        .hazards
        .iter()
        .find(|z| camera.is_some() && z.camera == camera)
        .or_else(|| h.hazards.first());
    if let Some(z) = hazard {
        out.object_ok = HiddenClass::classify(&z.object) == Some(sample.class);
        out.motion_ok = MotionLabel::classify(&z.motion) == Some(sample.motion);
        out.answer_object = Some(z.object.clone());
        out.answer_motion = Some(z.motion.clone());
    }
    out.strategy_ok = h.strategy == sample.strategy;
    out.answer_strategy = Some(h.strategy);
    out.answer_rationale = Some(h.rationale.clone());
    plan_sample(&history, &a, &h, backend, &mut out);
    Ok(out)
}

/// What a plan does at once: its strategy and a summary.
struct Planned {
    strategy: Strategy,
    summary: String,
}

/// The planning prompt after `h` (the controller's `make_plan`), scored into `out`.
fn plan_sample(
    history: &[Observation],
    a: &Assessment,
    h: &HazardInference,
    backend: &mut dyn Backend,
    out: &mut SampleAnswer,
) {
    let query = plan_query(history, a, h);
    out.plan_prompt = Some(query.task.name().into());
    let clock = Instant::now();
    let reply = backend.answer(&query);
    out.plan_latency_ms = Some(clock.elapsed().as_secs_f64() * 1000.0);
    let planned = match reply {
        Err(e) => Err(format!("no answer: {e}")),
        Ok(text) => read_plan(&text, query.task, a),
    };
    match planned {
        Err(why) => out.plan_invalid = Some(why),
        Ok(p) => {
            out.plan_ok = p.strategy == out.strategy;
            out.plan_strategy = Some(p.strategy);
            out.plan_summary = Some(p.summary);
        }
    }
}

/// Validates a planning answer as the controller does and reads what it does at once.
fn read_plan(text: &str, task: Task, a: &Assessment) -> Result<Planned, String> {
    let rejected = |e: fogline_rco::backend::answer::AnswerError| format!("rejected: {e}");
    if task == Task::StopObserveMovePlan {
        let som = parse_som(text, &VIEWS, WAIT_LIMIT).map_err(rejected)?;
        return Ok(Planned {
            strategy: Strategy::StopObserveMove,
            summary: format!(
                "wait {} ticks, then move when {}",
                som.wait_steps, som.move_trigger
            ),
        });
    }
    let steps = parse_move(text, &VIEWS, PLAN_LIMIT).map_err(rejected)?;
    let head = steps.first().ok_or("rejected: no step")?;
    check_states(&head.condition, a)
        .map_err(|r| format!("refused by the verifier at its first step: {r}"))?;
    let stops = head.action.behavior == Behavior::Stop
        || head.action.speed == SpeedControl::DecelerationToZero;
    let actions: Vec<String> = steps
        .iter()
        .map(|s| format!("{}/{}", s.action.behavior.name(), s.action.speed.name()))
        .collect();
    Ok(Planned {
        strategy: if stops {
            Strategy::StopObserveMove
        } else {
            Strategy::Move
        },
        summary: format!(
            "{} step{}: {}",
            steps.len(),
            if steps.len() == 1 { "" } else { "s" },
            actions.join(", ")
        ),
    })
}

fn rate(hits: usize, n: usize) -> Rate {
    match wilson(hits as u64, n as u64, 0.05) {
        Ok(ci) => Rate {
            hits: hits as u64,
            n: n as u64,
            value: Some(ci.estimate),
            ci_low: Some(ci.low),
            ci_high: Some(ci.high),
        },
        Err(_) => Rate {
            hits: hits as u64,
            n: n as u64,
            ..Rate::default()
        },
    }
}

/// The figure-6 row of a group of answers.
pub fn row(group: &str, answers: &[&SampleAnswer]) -> EvalRow {
    let n = answers.len();
    let count = |f: &dyn Fn(&SampleAnswer) -> bool| answers.iter().filter(|a| f(a)).count();
    let recall = |s: Strategy, ok: &dyn Fn(&SampleAnswer) -> bool| {
        let of: Vec<&&SampleAnswer> = answers.iter().filter(|a| a.strategy == s).collect();
        rate(of.iter().filter(|a| ok(a)).count(), of.len())
    };
    EvalRow {
        group: group.into(),
        samples: n as u64,
        object: rate(count(&|a| a.object_ok), n),
        motion: rate(count(&|a| a.motion_ok), n),
        strategy: rate(count(&|a| a.strategy_ok), n),
        move_recall: recall(Strategy::Move, &|a| a.strategy_ok),
        som_recall: recall(Strategy::StopObserveMove, &|a| a.strategy_ok),
        invalid: rate(count(&|a| a.invalid.is_some()), n),
        plan_strategy: rate(count(&|a| a.plan_ok), n),
        plan_move_recall: recall(Strategy::Move, &|a| a.plan_ok),
        plan_som_recall: recall(Strategy::StopObserveMove, &|a| a.plan_ok),
        plan_invalid: rate(count(&|a| a.plan_strategy.is_none()), n),
    }
}

/// Latency statistics of the hazard inference calls.
pub fn latency(answers: &[SampleAnswer]) -> Latency {
    latency_of(answers.iter().map(|a| a.latency_ms).collect())
}

/// Latency statistics of the planning calls of `prompt` (`move_plan`,
/// `stop_observe_move_plan`).
pub fn plan_latency(answers: &[SampleAnswer], prompt: &str) -> PromptLatency {
    PromptLatency {
        prompt: prompt.into(),
        latency: latency_of(
            answers
                .iter()
                .filter(|a| a.plan_prompt.as_deref() == Some(prompt))
                .filter_map(|a| a.plan_latency_ms)
                .collect(),
        ),
    }
}

/// Mean (with its 95 % normal interval), median, p95 and maximum of call times, ms.
fn latency_of(mut ms: Vec<f64>) -> Latency {
    if ms.is_empty() {
        return Latency::default();
    }
    ms.sort_by(f64::total_cmp);
    let n = ms.len() as f64;
    let mean = ms.iter().sum::<f64>() / n;
    let var = if ms.len() > 1 {
        ms.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    let half = 1.959_963_984_540_054 * (var / n).sqrt();
    let at = |q: f64| ms[((q * n).ceil() as usize).clamp(1, ms.len()) - 1];
    Latency {
        calls: ms.len() as u64,
        mean_ms: mean,
        ci_low_ms: (mean - half).max(0.0),
        ci_high_ms: mean + half,
        p50_ms: at(0.5),
        p95_ms: at(0.95),
        max_ms: ms[ms.len() - 1],
    }
}

/// Scores `describe`'s backends (one per worker, from `factory`) on the data set in `dir`.
pub fn evaluate(
    dir: &Path,
    params: &EvalParams,
    describe: &str,
    factory: &BackendFactory<'_>,
) -> Result<DeficitEval, DatasetError> {
    let clock = Instant::now();
    let manifest = Manifest::read(dir)?;
    let samples: Vec<SampleRecord> = read_samples(dir)?
        .into_iter()
        .filter(|s| params.split.is_none_or(|sp| s.split == sp))
        .take(params.limit.unwrap_or(usize::MAX))
        .collect();
    if samples.is_empty() {
        return Err(DatasetError::Params(format!(
            "{}: no sample in split {}",
            dir.display(),
            params.split.map_or("all", Split::name)
        )));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(params.jobs.max(1))
        .build()
        .map_err(|e| DatasetError::Params(format!("cannot start the worker threads: {e}")))?;
    let progress = Progress::new(samples.len(), "samples");
    let answers: Vec<SampleAnswer> = pool.install(|| {
        samples
            .par_iter()
            .map_init(factory, |backend, s| {
                let b = backend
                    .as_mut()
                    .map_err(|e| DatasetError::Backend(e.to_string()))?;
                let a = score_sample(&manifest, dir, s, b.as_mut());
                progress.inc();
                a
            })
            .collect::<Result<Vec<_>, DatasetError>>()
    })?;
    progress.finish();
    let all: Vec<&SampleAnswer> = answers.iter().collect();
    let by = |f: &dyn Fn(&SampleAnswer) -> bool| -> Vec<&SampleAnswer> {
        answers.iter().filter(|a| f(a)).collect()
    };
    Ok(DeficitEval {
        format: DeficitEval::FORMAT.into(),
        version: DeficitEval::VERSION,
        backend: describe.into(),
        data: dir.display().to_string(),
        split: params.split.map_or("all", Split::name).into(),
        samples: answers.len() as u64,
        overall: row("all", &all),
        by_class: HiddenClass::ALL
            .iter()
            .map(|c| row(c.name(), &by(&|a| a.class == *c)))
            .collect(),
        by_motion: MotionLabel::ALL
            .iter()
            .map(|m| row(m.name(), &by(&|a| a.motion == *m)))
            .collect(),
        by_strategy: [Strategy::Move, Strategy::StopObserveMove]
            .iter()
            .map(|s| row(s.name(), &by(&|a| a.strategy == *s)))
            .collect(),
        latency: latency(&answers),
        plan_latency: [Task::MovePlan, Task::StopObserveMovePlan]
            .iter()
            .map(|t| plan_latency(&answers, t.name()))
            .collect(),
        elapsed_s: clock.elapsed().as_secs_f64(),
        answers,
    })
}

fn cell(r: &Rate) -> String {
    match (r.value, r.ci_low, r.ci_high) {
        (Some(v), Some(lo), Some(hi)) => {
            format!("{:.1} [{:.1}, {:.1}]", v * 100.0, lo * 100.0, hi * 100.0)
        }
        _ => "–".into(),
    }
}

/// The figure-6 tables as Markdown (percentages with 95 % Wilson intervals): per hidden
/// class, motion label and expert strategy, the hazard inference prompt's three tasks; then
/// the strategy the planning prompt's answer carries out; then the latency per prompt.
pub fn markdown(e: &DeficitEval) -> String {
    let mut s = format!(
        "# Backbone evaluation on DriveLM-Deficit (figure 6)\n\nBackend: {}. Data: `{}`, split `{}`, {} samples. Accuracy in %, [95 % Wilson interval].\n",
        e.backend, e.data, e.split, e.samples
    );
    let table = |s: &mut String, title: &str, rows: &[&EvalRow]| {
        s.push_str(&format!(
            "\n## {title}\n\n| group | n | object | motion | strategy | move recall | stop-observe-move recall | invalid |\n|---|---:|---:|---:|---:|---:|---:|---:|\n"
        ));
        for r in rows {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} |\n",
                r.group,
                r.samples,
                cell(&r.object),
                cell(&r.motion),
                cell(&r.strategy),
                cell(&r.move_recall),
                cell(&r.som_recall),
                cell(&r.invalid)
            ));
        }
    };
    let groups = groups(e);
    for (title, rows) in &groups {
        table(&mut s, &format!("Hazard inference prompt: {title}"), rows);
    }
    s.push_str(
        "\n## Planning prompt: the strategy the plan carries out\n\n| group | n | strategy | move recall | stop-observe-move recall | no valid plan |\n|---|---:|---:|---:|---:|---:|\n",
    );
    for r in groups.iter().flat_map(|(_, rows)| rows) {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            r.group,
            r.samples,
            cell(&r.plan_strategy),
            cell(&r.plan_move_recall),
            cell(&r.plan_som_recall),
            cell(&r.plan_invalid)
        ));
    }
    s.push_str("\n## Latency per call\n\n| prompt | calls | mean ms [95 % CI] | median ms | p95 ms | max ms |\n|---|---:|---:|---:|---:|---:|\n");
    for (prompt, l) in latencies(e) {
        s.push_str(&format!(
            "| {prompt} | {} | {:.2} [{:.2}, {:.2}] | {:.2} | {:.2} | {:.2} |\n",
            l.calls, l.mean_ms, l.ci_low_ms, l.ci_high_ms, l.p50_ms, l.p95_ms, l.max_ms
        ));
    }
    s.push_str(&format!("\nEvaluation wall time {:.1} s.\n", e.elapsed_s));
    s
}

/// The row groups of the tables: per hidden class (with all samples), per motion label,
/// per expert strategy.
pub fn groups(e: &DeficitEval) -> Vec<(&'static str, Vec<&EvalRow>)> {
    let mut by_class: Vec<&EvalRow> = e.by_class.iter().collect();
    by_class.push(&e.overall);
    vec![
        (
            "per hidden class (figure 6a: object; 6b: strategy)",
            by_class,
        ),
        ("per motion label", e.by_motion.iter().collect()),
        ("per expert strategy", e.by_strategy.iter().collect()),
    ]
}

/// The latency of every prompt: hazard inference, then each planning prompt.
pub fn latencies(e: &DeficitEval) -> Vec<(&str, &Latency)> {
    let mut out = vec![(Task::HazardInference.name(), &e.latency)];
    out.extend(
        e.plan_latency
            .iter()
            .map(|p| (p.prompt.as_str(), &p.latency)),
    );
    out
}

/// Writes `eval.json` and `eval.md` into `out` as one set; returns their paths.
pub fn write_eval(e: &DeficitEval, out: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    write_eval_with(e, out, &[])
}

/// Writes `eval.json`, `eval.md` and `extra` files (name in `out`, bytes; e.g. the HTML
/// report) into `out` as one set (all or none of them replaced); returns their paths.
pub fn write_eval_with(
    e: &DeficitEval,
    out: &Path,
    extra: &[(&str, &[u8])],
) -> Result<Vec<PathBuf>, DatasetError> {
    let json = out.join("eval.json");
    let md = out.join("eval.md");
    let mut set = FileSet::new();
    set.write(&json, &crate::pretty_json(e)?)
        .map_err(|err| DatasetError::io(&json, err))?;
    set.write(&md, markdown(e).as_bytes())
        .map_err(|err| DatasetError::io(&md, err))?;
    let mut files = vec![json, md];
    for (name, bytes) in extra {
        let path = out.join(name);
        set.write(&path, bytes)
            .map_err(|err| DatasetError::io(&path, err))?;
        files.push(path);
    }
    set.commit().map_err(|err| DatasetError::io(out, err))?;
    Ok(files)
}

/// Reads an `eval.json` back.
pub fn read_eval(path: &Path) -> Result<DeficitEval, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    serde_json::from_slice(&bytes).map_err(|e| DatasetError::invalid(path, 0, e.to_string()))
}
