//! The whole pipeline offline on built-in data (what `fogline demo` runs): a synthetic corpus
//! in the paper's scenario mix, the campaign (clean + the paper's eight conditions) with the
//! reference planner into a fresh SQLite store, the runs and pairs tables, the envelope
//! analysis with its files and report, and the quick closed loop.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use fogline_campaign::export::{ExportSummary, Formats, ParquetCodec};
use fogline_campaign::{CampaignConfig, RunSummary, Shard};
use fogline_envelope::{Envelope, EnvelopeParams, PairTable, ReadOptions};
use fogline_io::{FileSet, write_atomic};
use fogline_sim::config::{BackendSetup, ConfigSet, configs};
use fogline_sim::experiment::{ExperimentParams, Results, run_experiment};
use fogline_sim::output::write_all;
use fogline_sim::run::RunParams;
use fogline_sim::sense::DeficitKind;
use fogline_sim::suite::SuiteParams;

use crate::envelope::{Written, write_outputs};

/// What `fogline demo` takes.
#[derive(Debug, Clone)]
pub struct DemoJob {
    /// Clips of the synthetic corpus (the paper's has 1,996).
    pub clips: usize,
    /// Seed of the corpus, the analysis and the closed loop.
    pub seed: u64,
    /// Output directory (created if needed; its store is started afresh).
    pub out: PathBuf,
    /// Also run the quick closed loop.
    pub closed_loop: bool,
}

/// What a demo produced, for the front-end to report.
#[derive(Debug)]
pub struct DemoOutcome {
    /// The campaign's store.
    pub store: PathBuf,
    /// The campaign run.
    pub run: RunSummary,
    /// The exported tables.
    pub exported: ExportSummary,
    /// The pairs table analysed.
    pub table: PairTable,
    /// The analysis.
    pub envelope: Envelope,
    /// Its files.
    pub written: Written,
    /// The closed loop's results, directory and seconds, when it ran.
    pub closed_loop: Option<(Results, PathBuf, f64)>,
    /// Wall time of the whole demo, s.
    pub seconds: f64,
    /// The output directory.
    pub out: PathBuf,
}

/// Runs the demo (progress on stderr through the log and the progress bars).
pub fn run(job: &DemoJob) -> Result<DemoOutcome> {
    if job.clips == 0 {
        bail!("--clips must be at least 1");
    }
    let t = Instant::now();
    std::fs::create_dir_all(&job.out)
        .with_context(|| format!("cannot create {}", job.out.display()))?;
    // Everything is made in a staging directory inside `out` and moved into place as one
    // set at the end: a demo that fails or is killed leaves the previous demo's files whole.
    let staging = job.out.join(".fogline-demo.staging");
    if staging.exists() {
        std::fs::remove_dir_all(&staging)
            .with_context(|| format!("cannot remove {}", staging.display()))?;
    }
    std::fs::create_dir_all(&staging)
        .with_context(|| format!("cannot create {}", staging.display()))?;
    let made = make(job, &staging);
    let (run, exported, table, envelope, written, closed_loop) = match made {
        Ok(m) => m,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(e);
        }
    };
    // The previous demo's store may have left its write-ahead log beside it (a killed run):
    // it must not be paired with the new store.
    let store = job.out.join("campaign.sqlite");
    for suffix in ["-wal", "-shm"] {
        let p = PathBuf::from(format!("{}{suffix}", store.display()));
        if p.exists() {
            std::fs::remove_file(&p).with_context(|| format!("cannot remove {}", p.display()))?;
        }
    }
    let mut set = FileSet::new();
    set.adopt_dir(&staging, &job.out)?;
    set.commit()?;
    let _ = std::fs::remove_dir_all(&staging);
    // Every path reported is the committed one.
    let moved = |p: &Path| match p.strip_prefix(&staging) {
        Ok(rel) => job.out.join(rel),
        Err(_) => p.to_path_buf(),
    };
    let exported = ExportSummary {
        files: exported.files.iter().map(|p| moved(p)).collect(),
        ..exported
    };
    let written = Written {
        json: moved(&written.json),
        markdown: moved(&written.markdown),
        odd: moved(&written.odd),
        report: moved(&written.report),
    };
    Ok(DemoOutcome {
        store,
        run,
        exported,
        table,
        envelope,
        written,
        closed_loop: closed_loop.map(|(r, dir, secs)| (r, moved(&dir), secs)),
        seconds: t.elapsed().as_secs_f64(),
        out: job.out.clone(),
    })
}

/// What the demo makes in `dir` before it is committed.
type Made = (
    RunSummary,
    ExportSummary,
    PairTable,
    Envelope,
    Written,
    Option<(Results, PathBuf, f64)>,
);

fn make(job: &DemoJob, dir: &Path) -> Result<Made> {
    // The campaign: the paper's eight conditions + clean on a synthetic corpus, the
    // reference planner in-process.
    let config_text = format!(
        "# Written by `fogline demo`; rerun with `fogline campaign run`.\n\
         [clips]\nsource = \"world\"\ncount = {}\nseed = {}\nmix = \"paper\"\n\
         width = 576\nheight = 320\n\n[planner]\nkind = \"builtin\"\n",
        job.clips, job.seed
    );
    let config = CampaignConfig::from_toml(&config_text)?;
    write_atomic(&dir.join("campaign.toml"), config_text.as_bytes())?;
    let store = dir.join("campaign.sqlite");
    log::info!(
        "demo: {} synthetic clips × 9 conditions with the reference planner",
        job.clips
    );
    let (_, run) = fogline_campaign::run_into_store(config, &store, Shard::ALL, false, false)?;
    let runs = fogline_campaign::Store::open(&store)?.runs()?;
    let exported = fogline_campaign::export::export(
        &runs,
        dir,
        Formats {
            csv: true,
            parquet: true,
            codec: ParquetCodec::default(),
        },
        false,
    )?;
    let mut table = fogline_envelope::read_pairs(&dir.join("pairs.csv"), &ReadOptions::default())?;
    // The envelope names the table where it will be, once committed.
    table.input.path = job.out.join("pairs.csv").display().to_string();
    let t1 = Instant::now();
    let envelope = fogline_envelope::analyze(
        &table,
        &EnvelopeParams {
            seed: job.seed,
            ..EnvelopeParams::default()
        },
    )?;
    log::info!(
        "analysed {} pairs in {:.2} s",
        table.len(),
        t1.elapsed().as_secs_f64()
    );
    // The closed loop: the quick suite, no deficit and each deficit with and without the
    // override; it runs before the files are written so the report is written once, with it.
    let closed_loop = if job.closed_loop {
        let sim_dir = dir.join("closed-loop");
        let t2 = Instant::now();
        log::info!(
            "demo: the quick closed loop (2 towns x 2 routes; no deficit, each deficit with and without RCO; condition ramps with and without the guard)"
        );
        let results = quick_closed_loop(job.seed, &sim_dir)?;
        Some((results, sim_dir, t2.elapsed().as_secs_f64()))
    } else {
        None
    };
    let sim_dir = closed_loop.as_ref().map(|(_, d, _)| d.as_path());
    let written = write_outputs(&envelope, &table, dir, sim_dir)?;
    Ok((run, exported, table, envelope, written, closed_loop))
}

impl DemoOutcome {
    /// What `fogline demo` prints: the campaign run and export, the envelope summary, the
    /// closed loop's scores and where everything is.
    pub fn write_text(&self, out: &mut dyn std::io::Write) -> Result<()> {
        let d = self;
        d.run.write_text(out, &d.store)?;
        d.exported.write_text(out)?;
        crate::envelope::write_summary(&d.envelope, &d.written, false, out)?;
        if let Some((results, dir, secs)) = &d.closed_loop {
            writeln!(
                out,
                "closed loop ({} runs in {secs:.1} s): driving score, mean of the routes",
                results.records.len()
            )?;
            for c in &results.summary.configs {
                let m = &c.unlimited;
                writeln!(
                    out,
                    "  {:<22} DS {:6.2}  RC {:6.2}  IS {:.3}",
                    c.config,
                    m.driving_score.by_route.mean,
                    m.route_completion.by_route.mean,
                    m.infraction_score.by_route.mean
                )?;
            }
            writeln!(out, "{}", dir.display())?;
        }
        writeln!(
            out,
            "demo finished in {:.1} s; everything is in {}",
            d.seconds,
            d.out.display()
        )?;
        Ok(())
    }
}

/// The quick closed loop: the quick suite (2 towns × 2 routes), every main configuration (no
/// deficit; each deficit with and without RCO, rules backend) and the condition ramps (no
/// guard, the monitor-driven guard, the oracle hand-over, the override always on; the
/// reference planner's envelope), seed `seed`, all cores; the outputs written to `out`.
pub fn quick_closed_loop(seed: u64, out: &Path) -> Result<Results> {
    let params = ExperimentParams {
        suite: SuiteParams::quick(),
        seeds: vec![seed],
        configs: configs(
            &[ConfigSet::Main, ConfigSet::Ramps],
            &DeficitKind::ALL,
            &BackendSetup::Rules,
        ),
        run: RunParams::default(),
        system_time_limit_s: 1800.0,
        llm_latency_ms: Some(1000.0),
        routes: None,
    };
    params.validate()?;
    let results = run_experiment(&params, 0, &|_, _| {})?;
    write_all(&results, out).with_context(|| format!("writing results to {}", out.display()))?;
    Ok(results)
}
