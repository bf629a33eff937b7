//! The envelope analysis's files (what `fogline envelope` and `fogline demo` write) and the
//! HTML report of an envelope directory (what `fogline report` writes).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use fogline_envelope::{Envelope, PairTable, ReadOptions};
use fogline_io::{FileSet, write_atomic};
use fogline_report::{ClosedLoop, ReportInput, ReportParams};

/// Reads the pairs table at `pairs` and analyses it with `params` (a `Given` taxonomy
/// without classes takes the data's labels), logging the time each takes.
pub fn analyze_file(
    pairs: &Path,
    opts: &ReadOptions,
    mut params: fogline_envelope::EnvelopeParams,
) -> Result<(PairTable, Envelope)> {
    let t0 = std::time::Instant::now();
    log::info!("reading {}", pairs.display());
    let table = fogline_envelope::read_pairs(pairs, opts)?;
    log::info!(
        "read {} pairs of {} clips in {:.2} s",
        table.len(),
        table.clip_ids.len(),
        t0.elapsed().as_secs_f64()
    );
    params.take_labels_from(&table);
    let t1 = std::time::Instant::now();
    let env = fogline_envelope::analyze(&table, &params)?;
    log::info!("analysed in {:.2} s", t1.elapsed().as_secs_f64());
    Ok((table, env))
}

/// The well-sampled scenarios rejected under π* (the acceptance gate: `fogline envelope`
/// exits 1 when there is any).
pub fn rejected(env: &Envelope) -> Vec<&str> {
    env.odd
        .iter()
        .filter(|o| o.accepted == Some(false) && !o.pilot)
        .map(|o| o.scenario.as_str())
        .collect()
}

/// The files an analysis writes into its directory.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Written {
    /// `envelope.json`: every figure.
    pub json: PathBuf,
    /// `envelope.md`: the tables for people.
    pub markdown: PathBuf,
    /// `odd.json`: what a runtime monitor loads.
    pub odd: PathBuf,
    /// `report.html`: the self-contained report.
    pub report: PathBuf,
}

/// Writes `envelope.json`, `envelope.md`, `odd.json` and `report.html` into `dir` (created if
/// needed), each atomically; the report includes the closed loop of `sim_dir` when given.
pub fn write_outputs(
    env: &Envelope,
    table: &PairTable,
    dir: &Path,
    sim_dir: Option<&Path>,
) -> Result<Written> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let json = serde_json::to_vec_pretty(env).context("cannot serialise the envelope")?;
    let md = fogline_envelope::markdown::render(env);
    let odd = env.odd_spec().to_json();
    let w = Written {
        json: dir.join("envelope.json"),
        markdown: dir.join("envelope.md"),
        odd: dir.join("odd.json"),
        report: dir.join("report.html"),
    };
    let html = render_report(env, Some(table), sim_dir)?;
    // One set: a failure anywhere leaves the previous four files in place.
    let mut set = FileSet::new();
    set.write(&w.json, &json)?;
    set.write(&w.markdown, md.as_bytes())?;
    set.write(&w.odd, odd.as_bytes())?;
    set.write(&w.report, html.as_bytes())?;
    set.commit()?;
    Ok(w)
}

/// Writes the HTML report of `envelope` (with the L2 histogram of `pairs` and the closed
/// loop of `sim_dir`'s `closed_loop.json`, when given) to `out`.
pub fn write_report(
    envelope: &Envelope,
    pairs: Option<&PairTable>,
    sim_dir: Option<&Path>,
    out: &Path,
) -> Result<()> {
    let html = render_report(envelope, pairs, sim_dir)?;
    check_dir(out)?;
    Ok(write_atomic(out, html.as_bytes())?)
}

fn render_report(
    envelope: &Envelope,
    pairs: Option<&PairTable>,
    sim_dir: Option<&Path>,
) -> Result<String> {
    let mut input = ReportInput::from_envelope(envelope)?;
    if let Some(t) = pairs {
        input = input.with_pairs(t)?;
    }
    if let Some(dir) = sim_dir {
        input = input.with_closed_loop(read_closed_loop(dir)?)?;
    }
    render_input(&input, &ReportParams::default())
}

/// The summary `fogline envelope` prints: the corpus, the aggregate threshold, the ODD entry
/// per scenario and the files written (`json`: the same as one JSON object).
pub fn write_summary(env: &Envelope, w: &Written, json: bool, out: &mut dyn Write) -> Result<()> {
    if json {
        let v = serde_json::json!({
            "envelope": w.json,
            "markdown": w.markdown,
            "odd": w.odd,
            "report": w.report,
            "n_pairs": env.corpus.n_pairs,
            "n_changed": env.corpus.n_changed,
            "chosen_k": env.severity.chosen_k,
            "odd_entries": env.odd,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(());
    }
    let agg = env.thresholds.iter().find(|t| {
        t.scenario == fogline_envelope::model::AGG_ALL
            && env.odd.first().is_some_and(|o| o.axis == t.axis)
            && t.budget == env.parameters.headline_budget
    });
    writeln!(
        out,
        "{} pairs, {} clips, {} changed CoC; {} severity bands; aggregate threshold ≤ {}",
        env.corpus.n_pairs,
        env.corpus.n_clips,
        env.corpus.n_changed,
        env.severity
            .chosen_k
            .map_or("undefined".into(), |k| k.to_string()),
        agg.and_then(|t| t.sigma_star)
            .map_or("none".into(), |v| v.to_string())
    )?;
    writeln!(
        out,
        "{:<16} {:>6} {:>8} {:>14} {:>8}  quadrant",
        "scenario", "clips", "sigma*", "95% CI", "P(high)"
    )?;
    for o in &env.odd {
        let lvl = |x: Option<f64>| x.map_or("none".into(), |v| v.to_string());
        writeln!(
            out,
            "{:<16} {:>6} {:>8} {:>14} {:>8}  {}{}{}",
            o.scenario,
            o.n_clips,
            format!(
                "{}{}",
                lvl(o.sigma_star),
                if o.right_censored { "+" } else { "" }
            ),
            o.ci95
                .map_or("-".into(), |[a, b]| format!("[{}, {}]", lvl(a), lvl(b))),
            o.p_high
                .map_or("-".into(), |v| format!("{:.1}%", 100.0 * v)),
            o.quadrant,
            if o.pilot { " (pilot)" } else { "" },
            match o.accepted {
                Some(true) => " ACCEPTED",
                Some(false) => " REJECTED",
                None => "",
            }
        )?;
    }
    writeln!(out, "{}", w.json.display())?;
    writeln!(out, "{}", w.markdown.display())?;
    writeln!(out, "{}", w.odd.display())?;
    writeln!(out, "{}", w.report.display())?;
    Ok(())
}

/// What `fogline report` takes.
#[derive(Debug, Clone, Default)]
pub struct ReportJob {
    /// The directory holding `envelope.json`.
    pub envelope_dir: PathBuf,
    /// A closed-loop output directory (holding `closed_loop.json`) to add.
    pub sim: Option<PathBuf>,
    /// Where to write (default `<envelope_dir>/report.html`).
    pub out: Option<PathBuf>,
    /// The pairs table for the L2 histogram (default: the one `envelope.json` names, or its
    /// namesake in `envelope_dir`).
    pub pairs: Option<PathBuf>,
    /// Draw no histogram.
    pub no_pairs: bool,
    /// The page title.
    pub title: Option<String>,
    /// A `fogline rco eval` output directory (holding `eval.json`) to add as the
    /// DriveLM-Deficit section, with a gallery from the data set it names.
    pub deficit: Option<PathBuf>,
}

/// Writes the report of an envelope directory; returns the file written.
pub fn report_dir(job: &ReportJob) -> Result<PathBuf> {
    let json_path = job.envelope_dir.join("envelope.json");
    let text = std::fs::read_to_string(&json_path)
        .with_context(|| format!("cannot read {}", json_path.display()))?;
    let mut input = ReportInput::from_envelope_json(&text, &json_path.display().to_string())?;
    if !job.no_pairs {
        input = attach_pairs(input, job)?;
    }
    if let Some(dir) = &job.sim {
        input = input.with_closed_loop(read_closed_loop(dir)?)?;
    }
    if let Some(dir) = &job.deficit {
        input = input.with_deficit(crate::dataset::read_section(dir, crate::dataset::GALLERY)?);
    }
    let params = ReportParams {
        title: job.title.clone(),
        ..ReportParams::default()
    };
    let out = job
        .out
        .clone()
        .unwrap_or_else(|| job.envelope_dir.join("report.html"));
    let html = render_input(&input, &params)?;
    check_dir(&out)?;
    write_atomic(&out, html.as_bytes())?;
    Ok(out)
}

fn read_closed_loop(dir: &Path) -> Result<ClosedLoop> {
    let path = dir.join("closed_loop.json");
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "cannot read {} (the closed-loop evaluation writes it)",
            path.display()
        )
    })?;
    Ok(fogline_report::closed_loop_from_json(
        &text,
        &path.display().to_string(),
    )?)
}

fn render_input(input: &ReportInput, params: &ReportParams) -> Result<String> {
    let report = fogline_report::render(input, params)?;
    for f in report.figures.iter().filter(|f| !f.drawn) {
        log::info!(
            "report: {} ({}) not drawn; the page says why",
            f.id,
            f.title
        );
    }
    Ok(report.html)
}

/// An early, clear error when `out`'s directory does not exist.
fn check_dir(out: &Path) -> Result<()> {
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        bail!(
            "cannot write {}: {} is not a directory",
            out.display(),
            dir.display()
        );
    }
    Ok(())
}

/// The pairs table behind the L2 histogram: the one given, else the one `envelope.json`
/// names, else its namesake next to it; without one the figure shows the mixture alone.
fn attach_pairs(input: ReportInput, job: &ReportJob) -> Result<ReportInput> {
    let opts = ReadOptions {
        allow_incomplete: input.envelope.corpus.n_incomplete_clips > 0,
        ..ReadOptions::default()
    };
    if let Some(p) = &job.pairs {
        let table = fogline_envelope::read_pairs(p, &opts)?;
        return Ok(input.with_pairs(&table)?);
    }
    let recorded = PathBuf::from(&input.envelope.input.path);
    let mut candidates = vec![recorded.clone()];
    if let Some(name) = recorded.file_name() {
        candidates.push(job.envelope_dir.join(name));
    }
    for c in candidates {
        if !c.is_file() {
            continue;
        }
        match fogline_envelope::read_pairs(&c, &opts) {
            Ok(table) => match input.clone().with_pairs(&table) {
                Ok(with) => {
                    log::info!("report: L2 histogram from {}", c.display());
                    return Ok(with);
                }
                Err(e) => log::warn!("report: not using {}: {e}", c.display()),
            },
            Err(e) => log::warn!("report: cannot read {}: {e:#}", c.display()),
        }
    }
    log::warn!(
        "report: the pairs table {} was not found; figure 2a shows the mixture without the histogram (--pairs PATH)",
        input.envelope.input.path
    );
    Ok(input)
}
