//! Recorded observations through the LLM-RCO controller (what `fogline rco replay` runs):
//! the file read and checked, the controller built with the chosen backend, every decision
//! written, then the summary and, for a server backend, the structured output mode in use.

use std::io::{BufReader, Write};
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use fogline_rco::{
    Backend, HostileBackend, Modules, OpenAiBackend, OpenAiParams, Rco, RcoParams, RulesBackend,
    replay,
};

/// Who answers the controller's queries.
#[derive(Debug, Clone, PartialEq)]
pub enum ReplayBackend {
    /// The offline rules.
    Rules,
    /// An OpenAI-compatible server.
    OpenAi(OpenAiParams),
    /// The red-team backend (`weak_brakes`: also asking for a weaker deceleration limit).
    Hostile {
        /// Ask for a deceleration limit that would weaken braking.
        weak_brakes: bool,
    },
}

/// A replay: the file, the controller's settings and the backend.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayJob {
    /// Recorded observations, JSON Lines.
    pub file: PathBuf,
    /// The modules that are on (`hi,st,av,sc`, `none`, …).
    pub modules: String,
    /// The largest number of steps of a move plan.
    pub plan_limit: usize,
    /// The verifier's area ratio of an immediate hazard.
    pub hazard_ratio: f64,
    /// Every decision as one JSON line instead of the table.
    pub json: bool,
    /// Who answers.
    pub backend: ReplayBackend,
}

/// Runs `job`, writing to `out`; the result says whether the backend gave at least one
/// usable answer (false: every tick fell back, so the replay measured the fallback; the
/// message for the user is logged as an error).
pub fn replay_file(job: &ReplayJob, out: &mut dyn Write) -> Result<bool> {
    let path = job.file.display();
    let file = std::fs::File::open(&job.file).with_context(|| format!("cannot open {path}"))?;
    let observations =
        replay::read_observations(BufReader::new(file)).with_context(|| format!("{path}"))?;
    if observations.is_empty() {
        bail!("{path}: no observation");
    }
    let mut params = RcoParams {
        modules: Modules::parse(&job.modules).context("--modules")?,
        plan_limit: job.plan_limit,
        ..RcoParams::default()
    };
    params.verifier.hazard_ratio = job.hazard_ratio;
    let backend: Box<dyn Backend> = match &job.backend {
        ReplayBackend::Rules => Box::new(RulesBackend::default()),
        ReplayBackend::OpenAi(p) => {
            Box::new(OpenAiBackend::new(p.clone()).context("--backend openai")?)
        }
        ReplayBackend::Hostile { weak_brakes } => Box::new(HostileBackend {
            weak_brakes: *weak_brakes,
        }),
    };
    let mut rco = Rco::new(params, backend).context("invalid controller settings")?;
    log::info!(
        "{} observations from {path} through {} ({})",
        observations.len(),
        rco.backend(),
        job.modules
    );
    let replayed = replay::run(&mut rco, &observations, job.json, out)?;
    if replayed.all_fell_back() {
        log::error!(
            "all {} ticks fell back to the safe default: {} never gave a usable answer \
             (run with -v to see why)",
            replayed.ticks,
            rco.backend()
        );
        return Ok(false);
    }
    Ok(true)
}
