//! The closed-loop evaluation (what `fogline sim run` runs): the experiment on all cores
//! with progress in the log, its output files, and the summary the CLI prints.

use std::io::Write;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use fogline_campaign::config::PlannerConfig;
use fogline_campaign::planner_from;
use fogline_sim::compare::{Comparison, compare, read_records};
use fogline_sim::config::{BackendSetup, Config, ConfigSet, configs};
use fogline_sim::experiment::{ExperimentParams, Results, run_experiment_with};
use fogline_sim::output::{Written, markdown, write_all};
use fogline_sim::ramp::RAMP_SCENARIOS;
use fogline_sim::sense::DeficitKind;
use fogline_types::odd::OddSpec;
use fogline_types::planner::Planner;

/// The routes `spec` names, for `fogline sim run --routes`: comma-separated route indices
/// and inclusive ranges, 0-based (`0,5,10-13` is routes 0, 5, 10, 11, 12 and 13), in the
/// order given, each once.
///
/// ```
/// assert_eq!(fogline_api::sim::parse_routes("0,5,10-12").unwrap(), vec![0, 5, 10, 11, 12]);
/// assert!(fogline_api::sim::parse_routes("3-1").is_err());
/// ```
pub fn parse_routes(spec: &str) -> Result<Vec<usize>> {
    let mut out: Vec<usize> = Vec::new();
    for part in spec.split(',').map(str::trim) {
        let index = |s: &str| {
            s.trim().parse::<usize>().map_err(|_| {
                anyhow::anyhow!(
                    "--routes {spec:?}: {part:?} is not a route index or a range A-B (0-based)"
                )
            })
        };
        let (first, last) = match part.split_once('-') {
            Some((a, b)) => (index(a)?, index(b)?),
            None => {
                let i = index(part)?;
                (i, i)
            }
        };
        if last < first {
            anyhow::bail!("--routes {spec:?}: the range {part:?} ends before it starts");
        }
        for r in first..=last {
            if !out.contains(&r) {
                out.push(r);
            }
        }
    }
    Ok(out)
}

/// The deficits `names` lists, for `fogline sim run --deficits`: `traffic_light`,
/// `stop_sign`, `pedestrian`, `bicycle`, each once in the order given; `none` adds none
/// (the no-deficit configuration runs either way).
///
/// ```
/// use fogline_sim::sense::DeficitKind;
/// let d = fogline_api::sim::parse_deficits(&["bicycle", "none", "bicycle"]).unwrap();
/// assert_eq!(d, vec![DeficitKind::Bicycle]);
/// assert!(fogline_api::sim::parse_deficits(&["fog"]).is_err());
/// ```
pub fn parse_deficits<S: AsRef<str>>(names: &[S]) -> Result<Vec<DeficitKind>> {
    let mut out = Vec::new();
    for d in names.iter().map(AsRef::as_ref).filter(|d| *d != "none") {
        let k = DeficitKind::parse(d).with_context(|| {
            format!(
                "--deficits: unknown deficit {d:?} (traffic_light, stop_sign, pedestrian, bicycle, or none)"
            )
        })?;
        if !out.contains(&k) {
            out.push(k);
        }
    }
    Ok(out)
}

/// The configurations of `fogline sim run`: the sets `sets` names (`main`, `ablation`,
/// `sweep`, `ramps`), the deficits `deficits` names ([`parse_deficits`]), the override's
/// `backend`; the ramps' guard and oracle judge by the envelope in `odd` (an `odd.json`),
/// else by the reference planner's ([`fogline_sim::ramp::reference_odd`]).
///
/// ```
/// use fogline_sim::config::BackendSetup;
/// let c = fogline_api::sim::experiment_configs(&["ramps"], &["none"], &BackendSetup::Rules, None).unwrap();
/// let names: Vec<&str> = c.iter().map(|c| c.name.as_str()).collect();
/// assert_eq!(names, ["ramps/no_guard", "ramps/guard", "ramps/oracle", "ramps/rco"]);
/// assert!(fogline_api::sim::experiment_configs(&["ramp"], &["none"], &BackendSetup::Rules, None).is_err());
/// ```
pub fn experiment_configs<S: AsRef<str>, D: AsRef<str>>(
    sets: &[S],
    deficits: &[D],
    backend: &BackendSetup,
    odd: Option<&Path>,
) -> Result<Vec<Config>> {
    let mut parsed = Vec::new();
    for c in sets.iter().map(AsRef::as_ref) {
        parsed.push(ConfigSet::parse(c).with_context(|| {
            format!("--configs: unknown set {c:?} (main, ablation, sweep or ramps)")
        })?);
    }
    let deficits = parse_deficits(deficits)?;
    let odd = odd
        .map(|p| -> Result<Arc<OddSpec>> {
            let spec = OddSpec::read(p).with_context(|| format!("--odd {}", p.display()))?;
            let missing: Vec<&str> = RAMP_SCENARIOS
                .iter()
                .copied()
                .filter(|s| spec.entry(s).is_none())
                .collect();
            if !missing.is_empty() {
                anyhow::bail!(
                    "--odd {}: no entry for {} (the ramps look the envelope up by {})",
                    p.display(),
                    missing.join(", "),
                    RAMP_SCENARIOS.join(", ")
                );
            }
            Ok(Arc::new(spec))
        })
        .transpose()?;
    let mut out = configs(&parsed, &deficits, backend);
    for c in out.iter_mut().filter(|c| c.guard.is_some()) {
        c.odd = odd.clone();
    }
    Ok(out)
}

/// What `fogline sim compare` prints: the runs of two `fogline sim run --out` directories
/// (or their `records.jsonl`) compared configuration by configuration
/// ([`fogline_sim::compare`]); an error when no run of the first has a match in the second.
pub fn compare_runs(before: &Path, after: &Path) -> Result<Comparison> {
    let c = compare(&read_records(before)?, &read_records(after)?);
    if c.configs.is_empty() {
        anyhow::bail!(
            "no run of {} has a match (same configuration, seed and route) in {}",
            before.display(),
            after.display()
        );
    }
    Ok(c)
}

/// The planner under test that `spec` names, for `fogline sim run --planner`: `builtin`
/// (the reference planner, followed by its trajectory instead of the baseline's rules),
/// `http://HOST:PORT[/PREFIX]` or `https://HOST[:PORT][/PREFIX]` (fogline's HTTP/JSON
/// planner contract; TLS trusts the process's CA certificate file too) or
/// `egodriver://HOST:PORT` (AlpaSim's egodriver gRPC contract; `egodriver+https://HOST[:PORT]`
/// over TLS); PNG frames, `timeout_s` per request.
pub fn planner_at(spec: &str, timeout_s: f64) -> Result<Arc<dyn Planner>> {
    let (kind, endpoint) = if spec == "builtin" {
        ("builtin", None)
    } else if spec.starts_with("http://") || spec.starts_with("https://") {
        ("http", Some(spec.to_string()))
    } else if let Some(rest) = spec.strip_prefix("egodriver://") {
        ("egodriver", Some(rest.to_string()))
    } else if let Some(rest) = spec.strip_prefix("egodriver+https://") {
        ("egodriver", Some(format!("https://{rest}")))
    } else {
        anyhow::bail!(
            "--planner {spec:?}: expected `builtin`, `http://HOST:PORT`, `https://HOST[:PORT]`, `egodriver://HOST:PORT` or `egodriver+https://HOST[:PORT]`"
        );
    };
    if !(timeout_s.is_finite() && timeout_s > 0.0) {
        anyhow::bail!("planner timeout {timeout_s} s: expected a positive number of seconds");
    }
    let config = PlannerConfig {
        kind: kind.into(),
        endpoint,
        ..PlannerConfig::default()
    };
    planner_from(&config, Duration::from_secs_f64(timeout_s))
        .with_context(|| format!("--planner {spec}"))
}

/// Runs the experiment of `params` and writes its files into `out`; `driver`, when given,
/// drives every run instead of the baseline's rules ([`planner_at`]).
pub fn run(
    params: &ExperimentParams,
    driver: Option<Arc<dyn Planner>>,
    out: &Path,
) -> Result<(Results, Written)> {
    params.validate()?;
    let n_routes = params
        .routes
        .as_ref()
        .map_or(params.suite.n_routes(), Vec::len);
    let n_runs = n_routes * params.configs.len() * params.seeds.len();
    log::info!(
        "sim run: suite {} ({} routes) x {} configuration(s) x {} seed(s) = {n_runs} runs on {} thread(s)",
        params.suite.name,
        params.suite.n_routes(),
        params.configs.len(),
        params.seeds.len(),
        rayon::current_num_threads()
    );
    let start = Instant::now();
    let step = (n_runs / 20).max(1);
    let progress = move |done: usize, total: usize| {
        if done.is_multiple_of(step) || done == total {
            log::info!(
                "{done}/{total} runs, {:.0} s",
                start.elapsed().as_secs_f64()
            );
        }
    };
    if let Some(d) = &driver {
        log::info!("sim run: driven by {}", d.describe());
    }
    let results = run_experiment_with(params, driver, 0, &progress)?;
    let written = write_all(&results, out)
        .with_context(|| format!("writing results to {}", out.display()))?;
    Ok((results, written))
}

/// The summary `fogline sim run` prints (`json`: one JSON object instead): the tables, the
/// speed of the deficit runs against the full suite's goal, warnings, the files written.
pub fn write_summary(
    params: &ExperimentParams,
    results: &Results,
    written: &Written,
    json: bool,
    out: &mut dyn Write,
) -> Result<()> {
    if json {
        let doc = serde_json::json!({
            "summary": results.summary,
            "wall_s": results.wall_s,
            "threads": results.threads,
            "warnings": results.warnings,
            "driver": results.driver,
            "plans": results.records.iter().map(|r| r.plans).sum::<u64>(),
            "plan_errors": results.records.iter().map(|r| r.plan_errors).sum::<u64>(),
            "files": {
                "results": written.results,
                "records": written.records,
                "tables": written.tables,
                "closed_loop": written.closed_loop,
            },
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&doc)?)?;
        return Ok(());
    }
    write!(out, "{}", markdown(results))?;
    // The speed goal: the full suite's deficit runs (36 routes × 4 deficits × with/without
    // RCO, one seed) within 10 minutes on two cores.
    let deficit_runs = results
        .records
        .iter()
        .filter(|r| params.is_deficit_run(r))
        .count();
    let elapsed_deficit = results.summary.deficit_runs_wall_s / results.threads.max(1) as f64;
    writeln!(
        out,
        "\nfogline sim run: {} runs in {:.1} s ({} thread(s)); {} deficit runs: {:.1} s of worker time, about {:.1} s elapsed (goal for the full suite, 288 runs on 2 cores: <= 600 s{})",
        results.records.len(),
        results.wall_s,
        results.threads,
        deficit_runs,
        results.summary.deficit_runs_wall_s,
        elapsed_deficit,
        if deficit_runs == 288 && results.threads == 2 {
            if elapsed_deficit <= 600.0 {
                ": met"
            } else {
                ": NOT met"
            }
        } else {
            ""
        }
    )?;
    let plans: u64 = results.records.iter().map(|r| r.plans).sum();
    let failed: u64 = results.records.iter().map(|r| r.plan_errors).sum();
    if failed > 0 {
        writeln!(
            out,
            "warning: {failed} of {plans} planner calls failed (the car braked on them; `plan_errors` in records.jsonl, `-v` logs why)"
        )?;
    }
    for w in &results.warnings {
        writeln!(out, "warning: {w}")?;
    }
    writeln!(
        out,
        "wrote {}, {}, {}, {}",
        written.tables.display(),
        written.results.display(),
        written.records.display(),
        written.closed_loop.display()
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_routes;

    #[test]
    fn routes_are_indices_and_inclusive_ranges_each_once() {
        assert_eq!(parse_routes("4").unwrap(), vec![4]);
        assert_eq!(parse_routes("3, 1-2,2").unwrap(), vec![3, 1, 2]);
        assert_eq!(parse_routes("7-7").unwrap(), vec![7]);
        for (bad, says) in [
            ("1,x", "\"x\" is not a route index"),
            ("5-2", "ends before it starts"),
            ("-3", "\"-3\" is not a route index"),
            ("", "\"\" is not a route index"),
            ("1-2-3", "is not a route index"),
        ] {
            let e = parse_routes(bad).unwrap_err().to_string();
            assert!(e.contains(says) && e.contains("--routes"), "{bad}: {e}");
        }
    }
}
