//! The closed-loop evaluation (what `fogline sim run` runs): the experiment on all cores
//! with progress in the log, its output files, and the summary the CLI prints.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use fogline_sim::experiment::{ExperimentParams, Results, run_experiment};
use fogline_sim::output::{Written, markdown, write_all};

/// Runs the experiment of `params` and writes its files into `out`.
pub fn run(params: &ExperimentParams, out: &Path) -> Result<(Results, Written)> {
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
    let results = run_experiment(params, 0, &progress)?;
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
