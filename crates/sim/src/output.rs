//! Writing results: `results.json` (settings, summaries and every record), `records.jsonl`
//! (one route record per line), `tables.md` (tables 1–3, the step-limit sweep, red-light
//! behaviour, timing) and `closed_loop.json` (the report's closed-loop section). Files are
//! written atomically (a temporary file, then a rename).

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use serde_json::json;

use crate::SimError;
use crate::experiment::{ConfigSummary, Metrics, RampsSummary, Results, Stat};
use crate::sense::DeficitKind;

/// The paths written.
#[derive(Debug, Clone)]
pub struct Written {
    /// `results.json`.
    pub results: PathBuf,
    /// `records.jsonl`.
    pub records: PathBuf,
    /// `tables.md`.
    pub tables: PathBuf,
    /// `closed_loop.json`.
    pub closed_loop: PathBuf,
}

/// A write error as the sim reports it (the file and the cause).
fn io_err(fallback: &Path) -> impl Fn(std::io::Error) -> SimError + '_ {
    move |e| {
        let (path, source) = match fogline_io::atomic::WriteError::of(&e) {
            Some(w) => (
                w.path.display().to_string(),
                std::io::Error::new(w.source.kind(), w.source.to_string()),
            ),
            None => (fallback.display().to_string(), e),
        };
        SimError::Io { path, source }
    }
}

/// Writes every output file into `dir` (created if needed).
pub fn write_all(results: &Results, dir: &Path) -> Result<Written, SimError> {
    std::fs::create_dir_all(dir).map_err(|source| SimError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    let w = Written {
        results: dir.join("results.json"),
        records: dir.join("records.jsonl"),
        tables: dir.join("tables.md"),
        closed_loop: dir.join("closed_loop.json"),
    };
    let json_err = |e: serde_json::Error| SimError::Params(format!("cannot serialise: {e}"));
    let doc = json!({
        "kind": "fogline.sim_results",
        "schema_version": 1,
        "params": results.params,
        "summary": results.summary,
        "wall_s": results.wall_s,
        "threads": results.threads,
        "records": results.records,
    });
    // One set: a failure anywhere leaves the previous files in place.
    let mut set = fogline_io::FileSet::new();
    set.write(
        &w.results,
        serde_json::to_string_pretty(&doc)
            .map_err(json_err)?
            .as_bytes(),
    )
    .map_err(io_err(dir))?;
    set.write_with(&w.records, |out| {
        for r in &results.records {
            serde_json::to_writer(&mut *out, r)?;
            out.write_all(b"\n")?;
        }
        Ok(())
    })
    .map_err(io_err(dir))?;
    set.write(&w.tables, markdown(results).as_bytes())
        .map_err(io_err(dir))?;
    set.write(
        &w.closed_loop,
        serde_json::to_string_pretty(&closed_loop(results))
            .map_err(json_err)?
            .as_bytes(),
    )
    .map_err(io_err(dir))?;
    set.commit().map_err(io_err(dir))?;
    Ok(w)
}

/// `closed_loop.json`: leaderboard-style scores per configuration, what the report's
/// closed-loop section shows. One typed definition for its writer (this crate) and its
/// readers (`fogline-report`, through `fogline_report::closed_loop_from_json`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClosedLoop {
    /// What produced the rows (tool and version, suite name), shown under the section title.
    pub source: String,
    /// One row per configuration, in the order to show.
    pub configurations: Vec<ClosedLoopRow>,
    /// Remarks to show under the figure.
    #[serde(default)]
    pub notes: Vec<String>,
}

/// Leaderboard-style scores of one configuration, averaged over its routes.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClosedLoopRow {
    /// Configuration name (e.g. `no deficit`, `pedestrian + RCO`).
    pub configuration: String,
    /// Routes driven.
    pub n_routes: usize,
    /// Mean driving score, 0–100 (route completion × infraction score, per route).
    pub driving_score: f64,
    /// Mean route completion, 0–100 (%).
    pub route_completion: f64,
    /// Mean infraction score (penalty product), 0–1.
    pub infraction_score: f64,
}

/// The report's closed-loop document: one row per configuration (unlimited game time).
pub fn closed_loop(results: &Results) -> ClosedLoop {
    ClosedLoop {
        source: format!(
            "fogline sim {} — suite {}, {} route(s), seed(s) {:?}",
            env!("CARGO_PKG_VERSION"),
            results.params.suite.name,
            results.params.suite.n_routes(),
            results.params.seeds
        ),
        configurations: results
            .summary
            .configs
            .iter()
            .map(|c| ClosedLoopRow {
                configuration: c.config.clone(),
                n_routes: c.unlimited.runs,
                driving_score: c.unlimited.driving_score.by_route.mean,
                route_completion: c.unlimited.route_completion.by_route.mean,
                infraction_score: c.unlimited.infraction_score.by_route.mean,
            })
            .collect(),
        notes: notes(results),
    }
}

fn notes(results: &Results) -> Vec<String> {
    let p = &results.params;
    let mut n: Vec<String> = results.warnings.clone();
    n.extend([
        "Leaderboard 1.0 scoring; red lights are not scored under the traffic-light deficit, nor stop signs under the stop-sign deficit (as in the paper).".to_string(),
        "AS (average speed) = route length driven (RC/100 × length) / game time.".to_string(),
        format!(
            "The agent: the reference planner on front-wide ({:.0}°) and front-tele cameras at {}x{}, {} Hz, speed PID, pure pursuit on the route, unstick after 55 s.",
            p.run.sensors.wide_fov_deg, p.run.sensors.width, p.run.sensors.height, p.run.sensors.agent_hz
        ),
    ]);
    if p.seeds.len() < 2 {
        n.push("± is the sample standard deviation over routes (one seed).".into());
    } else {
        n.push(format!(
            "± is the sample standard deviation over the {} seeds' route means.",
            p.seeds.len()
        ));
    }
    if let Some(r) = &results.summary.ramps {
        let guard = crate::ramp::GuardMode::Monitor.config_name();
        if let (Some(out_s), Some(over_s)) = (
            r.mean_over_routes(|x| x.out_s),
            r.mean_over_routes(|x| x.override_s.get(guard).copied()),
        ) {
            n.push(format!(
                "Condition ramps (ramps/…): each route's noise, darkness or fog rises past the reference planner's envelope and clears; the runtime monitor's guard (ramps/guard) kept the car in override {over_s:.1} s per route while the true condition was outside the envelope {out_s:.1} s{}.",
                r.guard_to_oracle
                    .map_or(String::new(), |g| format!("; its mean DS is {:.1} % of the oracle hand-over's", 100.0 * g))
            ));
        }
    }
    for c in &results.summary.configs {
        if c.fallbacks > 0 {
            n.push(format!(
                "{}: the RCO controller fell back to decelerate-to-stop {} time(s) (backend errors or rejected answers); see the records' rco.fallbacks.",
                c.config, c.fallbacks
            ));
        }
    }
    n
}

/// How a configuration's runs ended: `completed 30, agent_blocked 6`.
fn terminations(c: &ConfigSummary) -> String {
    c.terminations
        .iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn ms(s: &Stat, prec: usize) -> String {
    let m = s.shown();
    if m.n == 0 {
        return "-".into();
    }
    format!("{:.*} ± {:.*}", prec, m.mean, prec, m.std)
}

fn metric_rows(
    out: &mut String,
    label: &str,
    cols: &[Option<&ConfigSummary>],
    pick: &dyn Fn(&ConfigSummary) -> &Metrics,
    with_as: bool,
) {
    let mut names = vec![("RC", 2usize), ("IS", 3), ("DS", 2)];
    if with_as {
        names.push(("AS", 2));
    }
    for (k, (name, prec)) in names.iter().enumerate() {
        let first = if k == 0 { label } else { "" };
        let _ = write!(out, "| {first} | {name} |");
        for c in cols {
            let cell = match c {
                Some(c) => {
                    let m = pick(c);
                    let s = match *name {
                        "RC" => &m.route_completion,
                        "IS" => &m.infraction_score,
                        "DS" => &m.driving_score,
                        _ => &m.avg_speed_mps,
                    };
                    ms(s, *prec)
                }
                None => "-".into(),
            };
            let _ = write!(out, " {cell} |");
        }
        out.push('\n');
    }
}

fn main_table(out: &mut String, results: &Results, limited: bool) {
    let s = &results.summary;
    let deficits: Vec<DeficitKind> = DeficitKind::ALL
        .into_iter()
        .filter(|k| s.configs.iter().any(|c| c.deficit == Some(*k)))
        .collect();
    if deficits.is_empty() && s.config("no_deficit").is_none() {
        out.push_str("(no configuration of this table ran)\n");
        return;
    }
    let pick: &dyn Fn(&ConfigSummary) -> &Metrics = if limited {
        &|c| &c.system_limited
    } else {
        &|c| &c.unlimited
    };
    let none = s.config("no_deficit");
    if deficits.is_empty() {
        // Only the baseline ran (`--deficits none`): one column.
        out.push_str("| Experiment | Metric | All routes |\n|---|---|---|\n");
        metric_rows(out, "No deficit", &[none], pick, !limited);
        return;
    }
    let _ = write!(out, "| Experiment | Metric |");
    for k in &deficits {
        let _ = write!(out, " {} |", title(*k));
    }
    out.push('\n');
    out.push_str("|---|---|");
    for _ in &deficits {
        out.push_str("---|");
    }
    out.push('\n');
    let row: Vec<Option<&ConfigSummary>> = deficits.iter().map(|_| none).collect();
    metric_rows(out, "No deficit", &row, pick, !limited);
    let row: Vec<Option<&ConfigSummary>> = deficits
        .iter()
        .map(|k| s.config(&format!("{}/no_rco", k.name())))
        .collect();
    metric_rows(out, "Deficit, no RCO", &row, pick, !limited);
    let row: Vec<Option<&ConfigSummary>> = deficits
        .iter()
        .map(|k| s.config(&format!("{}/rco", k.name())))
        .collect();
    metric_rows(out, "Deficit, RCO", &row, pick, !limited);
}

fn title(k: DeficitKind) -> &'static str {
    match k {
        DeficitKind::TrafficLight => "Traffic light",
        DeficitKind::StopSign => "Stop sign",
        DeficitKind::Pedestrian => "Pedestrian",
        DeficitKind::Bicycle => "Bicycle",
    }
}

fn ramps_section(out: &mut String, s: &crate::experiment::Summary, r: &RampsSummary) {
    out.push_str(
        "\n## Condition ramps: the guard against no guard (unlimited game time)\n\n\
         Each route's condition (sensor noise, darkness or fog, by route) rises and falls \
         mid-route past the reference planner's envelope. `ramps/guard`: the runtime monitor \
         on the front-wide and cross cameras hands the car to the override while it reads \
         the condition outside the envelope; `ramps/oracle`: the true condition does; \
         `ramps/rco`: the override drives while the condition differs from clean. Out of \
         envelope and in override: mean game time per route.\n\n\
         | Configuration | Runs | RC | IS | DS | Collisions per km | Red lights per km | Out of envelope, s | In override, s | Terminations |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    for mode in crate::ramp::GuardMode::ALL {
        let Some(c) = s.config(mode.config_name()) else {
            continue;
        };
        let mean_of = |f: &dyn Fn(&crate::experiment::RampRoute) -> Option<f64>| {
            r.mean_over_routes(f)
                .map_or("-".to_string(), |m| format!("{m:.1}"))
        };
        let u = &c.unlimited;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.2} | {:.2} | {} | {} | {} |",
            c.config,
            u.runs,
            ms(&u.route_completion, 2),
            ms(&u.infraction_score, 3),
            ms(&u.driving_score, 2),
            crate::score::collisions_per_km(&c.infractions_per_km),
            c.signals.red_lights_per_km,
            mean_of(&|x| x.out_s),
            if mode == crate::ramp::GuardMode::None {
                "0.0".to_string()
            } else {
                mean_of(&|x| x.override_s.get(mode.config_name()).copied())
            },
            terminations(c)
        );
    }
    if !r.paired.is_empty() {
        out.push_str(
            "\nPaired by route against `ramps/no_guard`: mean ΔDS with its 95 % percentile \
             bootstrap interval (10,000 resamples of the routes, fixed seed); collisions per km \
             without and with the guard.\n\n\
             | Configuration | Pairs | ΔDS | 95 % CI | Collisions per km (no guard → this) |\n|---|---|---|---|---|\n",
        );
        for p in &r.paired {
            let _ = writeln!(
                out,
                "| {} | {} | {:+.2} | [{:+.2}, {:+.2}] | {:.2} → {:.2} |",
                p.config,
                p.pairs,
                p.mean,
                p.ci95[0],
                p.ci95[1],
                p.collisions_per_km[0],
                p.collisions_per_km[1]
            );
        }
    }
    if let Some(g) = r.guard_to_oracle {
        let _ = writeln!(
            out,
            "\nThe monitor-driven guard's mean DS is {:.1} % of the oracle hand-over's.",
            100.0 * g
        );
    }
    out.push_str(
        "\n### Per route: the ramp, time out of the envelope and in override, DS\n\n\
         | Seed | Route | Axis | Peak | Rise → clear, s | Out of envelope, s | In override, s (guard / oracle / rco) | DS (no guard / guard / oracle / rco) |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    let cell = |m: &std::collections::BTreeMap<String, f64>, mode: crate::ramp::GuardMode| {
        m.get(mode.config_name())
            .map_or("-".to_string(), |v| format!("{v:.1}"))
    };
    use crate::ramp::GuardMode as G;
    for x in &r.routes {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {:.0} → {:.0} | {} | {} / {} / {} | {} / {} / {} / {} |",
            x.seed,
            x.route,
            x.ramp.axis.name(),
            x.ramp.peak,
            x.ramp.start_s,
            x.ramp.end_s(),
            x.out_s.map_or("-".to_string(), |v| format!("{v:.1}")),
            cell(&x.override_s, G::Monitor),
            cell(&x.override_s, G::Oracle),
            cell(&x.override_s, G::Always),
            cell(&x.driving_score, G::None),
            cell(&x.driving_score, G::Monitor),
            cell(&x.driving_score, G::Oracle),
            cell(&x.driving_score, G::Always),
        );
    }
}

/// The Markdown tables.
pub fn markdown(results: &Results) -> String {
    let p = &results.params;
    let s = &results.summary;
    let mut out = String::new();
    let _ = writeln!(out, "# Closed-loop evaluation (`fogline sim run`)\n");
    let _ = writeln!(
        out,
        "Suite `{}`: {} route(s), seed(s) {:?}; driven by {}; RCO backend {}; system-time limit {:.0} s with {}.\n",
        p.suite.name,
        p.suite.n_routes(),
        p.seeds,
        results.driver,
        p.configs
            .iter()
            .find_map(|c| c.rco.as_ref().map(|r| r.backend.describe()))
            .unwrap_or_else(|| "-".into()),
        p.system_time_limit_s,
        match p.llm_latency_ms {
            Some(ms) => format!("{ms:.0} ms counted per LLM call"),
            None => "the measured LLM latency".into(),
        }
    );
    for n in notes(results) {
        let _ = writeln!(out, "- {n}");
    }
    out.push('\n');
    out.push_str("## Table 1: unlimited game time (each route's own timeout only)\n\n");
    main_table(&mut out, results, false);
    out.push_str("\n## Table 2: with the system-time limit\n\n");
    main_table(&mut out, results, true);
    if !s.paired.is_empty() {
        out.push_str(
            "\n## RCO against no RCO, paired by route (DS, unlimited game time)\n\n\
             Mean of the per-route differences with its 95 % percentile bootstrap interval \
             (10,000 resamples of the routes, fixed seed); collisions per km without and with RCO.\n\n\
             | Deficit | Pairs | ΔDS | 95 % CI | Collisions per km (no RCO → RCO) |\n|---|---|---|---|---|\n",
        );
        for p in &s.paired {
            let _ = writeln!(
                out,
                "| {} | {} | {:+.2} | [{:+.2}, {:+.2}] | {:.2} → {:.2} |",
                title(p.deficit),
                p.pairs,
                p.mean,
                p.ci95[0],
                p.ci95[1],
                p.collisions_per_km[0],
                p.collisions_per_km[1]
            );
        }
    }
    if let Some(r) = &s.ramps {
        ramps_section(&mut out, s, r);
    }
    let ablation: Vec<&ConfigSummary> = s
        .configs
        .iter()
        .filter(|c| c.deficit == Some(DeficitKind::Bicycle) && c.plan_limit.is_none_or(|l| l == 5))
        .collect();
    if ablation.len() > 2 {
        out.push_str("\n## Table 3: module ablation (bicycle deficit, system-time limit)\n\n");
        out.push_str("| HI | ST | AV | SC | RC | IS | DS | RC (unlimited) | IS (unlimited) | DS (unlimited) |\n|---|---|---|---|---|---|---|---|---|---|\n");
        for c in &ablation {
            let m = c.rco_modules.clone().unwrap_or_else(|| "no RCO".into());
            let on = |k: &str| {
                if m.split('+').any(|x| x == k) {
                    "✓"
                } else {
                    "✗"
                }
            };
            let (hi, st, av, sc) = if c.rco_modules.is_none() {
                ("-", "-", "-", "-")
            } else {
                (on("HI"), on("ST"), on("AV"), on("SC"))
            };
            let l = &c.system_limited;
            let u = &c.unlimited;
            let _ = writeln!(
                out,
                "| {hi} | {st} | {av} | {sc} | {} | {} | {} | {} | {} | {} |",
                ms(&l.route_completion, 2),
                ms(&l.infraction_score, 3),
                ms(&l.driving_score, 2),
                ms(&u.route_completion, 2),
                ms(&u.infraction_score, 3),
                ms(&u.driving_score, 2)
            );
        }
    }
    if !s.sweep.is_empty() {
        out.push_str("\n## Figure 8: planning step limit (change against the same deficit without RCO; means over routes)\n\n");
        out.push_str("| Deficit | Step limit | ΔRC | ΔIS | ΔDS | ΔRC (unlimited) | ΔIS (unlimited) | ΔDS (unlimited) |\n|---|---|---|---|---|---|---|---|\n");
        for r in &s.sweep {
            let _ = writeln!(
                out,
                "| {} | {} | {:+.2} | {:+.3} | {:+.2} | {:+.2} | {:+.3} | {:+.2} |",
                title(r.deficit),
                r.plan_limit,
                r.delta_limited[0],
                r.delta_limited[1],
                r.delta_limited[2],
                r.delta_unlimited[0],
                r.delta_unlimited[1],
                r.delta_unlimited[2]
            );
        }
    }
    out.push_str("\n## Red-light behaviour on the routes' signalised approaches\n\n");
    out.push_str("Counted also where the scoring excludes red lights.\n\n");
    out.push_str("| Configuration | Approaches | Red encounters | Stopped at red | Stop rate | Red-light infractions | per km |\n|---|---|---|---|---|---|---|\n");
    for c in &s.configs {
        let g = &c.signals;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {:.2} |",
            c.config,
            g.approaches,
            g.red_encounters,
            g.stopped_at_red,
            g.stop_rate
                .map_or("-".into(), |r| format!("{:.1} %", 100.0 * r)),
            g.red_light_infractions,
            g.red_lights_per_km
        );
    }
    out.push_str("\n## Runs\n\n");
    out.push_str("| Configuration | Runs | Deficit present | RCO drove | LLM calls | ms/call | Fallbacks | Unstick (per run) | Terminations | Infractions per km |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for c in &s.configs {
        let inf: Vec<String> = c
            .infractions_per_km
            .iter()
            .filter(|(k, _)| !k.ends_route())
            .map(|(k, v)| format!("{} {:.2}", k.name(), v))
            .collect();
        let _ = writeln!(
            out,
            "| {} | {} | {:.1} % | {:.1} % | {} | {} | {} | {} ({:.2}) | {} | {} |",
            c.config,
            c.unlimited.runs,
            100.0 * c.deficit_share,
            100.0 * c.takeover_share,
            c.llm_calls,
            c.llm_ms_per_call.map_or("-".into(), |m| format!("{m:.3}")),
            c.fallbacks,
            c.unstick,
            c.unstick as f64 / c.unlimited.runs.max(1) as f64,
            terminations(c),
            if inf.is_empty() {
                "-".into()
            } else {
                inf.join(", ")
            }
        );
    }
    out.push_str("\n## Timing (wall clock; not part of the results)\n\n");
    let _ = writeln!(
        out,
        "{} runs in {:.1} s on {} thread(s); the runs with a deficit took {:.1} s of worker time ({:.1} s on {} threads).",
        results.records.len(),
        results.wall_s,
        results.threads,
        s.deficit_runs_wall_s,
        s.deficit_runs_wall_s / results.threads.max(1) as f64,
        results.threads
    );
    out
}
