//! DriveLM-Deficit: building a data set (`fogline dataset deficit`) and scoring a backend on
//! it (`fogline rco eval`). The work is in `fogline-dataset`; this module picks the backend
//! and formats what the CLI prints.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use fogline_dataset::eval::{EvalParams, evaluate, markdown, write_eval};
use fogline_dataset::{BuildParams, Built, DatasetError};
use fogline_rco::backend::Backend;
use fogline_rco::deficit_eval::DeficitEval;
use fogline_rco::{OpenAiBackend, OpenAiParams, RulesBackend};

/// Builds a data set into `out` (see `docs/dataset.md`).
pub fn deficit(params: &BuildParams, out: &Path) -> Result<Built> {
    fogline_dataset::build(params, out)
        .with_context(|| format!("dataset deficit into {}", out.display()))
}

/// Imports the logs under `logs` into a data set in `out` (see `docs/dataset.md`).
pub fn import(params: &fogline_dataset::ImportParams, logs: &Path, out: &Path) -> Result<Built> {
    fogline_dataset::import(params, logs, out).with_context(|| {
        format!(
            "dataset import of {} into {}",
            logs.display(),
            out.display()
        )
    })
}

/// Who answers the evaluation's queries.
#[derive(Debug, Clone, PartialEq)]
pub enum EvalBackend {
    /// The offline rules.
    Rules,
    /// An OpenAI-compatible server.
    OpenAi(OpenAiParams),
}

/// An evaluation job.
#[derive(Debug, Clone)]
pub struct EvalJob {
    /// The data set directory.
    pub data: PathBuf,
    /// Where `eval.json` and `eval.md` go (default: `data/eval`).
    pub out: Option<PathBuf>,
    /// The backend.
    pub backend: EvalBackend,
    /// Split, limit, concurrency.
    pub params: EvalParams,
}

/// What an evaluation wrote.
#[derive(Debug, Clone)]
pub struct EvalOutput {
    /// The result.
    pub eval: DeficitEval,
    /// `eval.json`, `eval.md`.
    pub files: Vec<PathBuf>,
}

impl EvalOutput {
    /// The figure-6 tables and the files, as the CLI prints them.
    pub fn write_text(&self, out: &mut dyn Write) -> std::io::Result<()> {
        out.write_all(markdown(&self.eval).as_bytes())?;
        for f in &self.files {
            writeln!(out, "{}", f.display())?;
        }
        Ok(())
    }
}

/// Scores the backend on the data set and writes `eval.json` and `eval.md`.
pub fn eval(job: &EvalJob) -> Result<EvalOutput> {
    let (describe, factory): (String, Box<fogline_dataset::eval::BackendFactory<'_>>) =
        match &job.backend {
            EvalBackend::Rules => (
                RulesBackend::default().describe(),
                Box::new(|| Ok(Box::new(RulesBackend::default()) as Box<dyn Backend>)),
            ),
            EvalBackend::OpenAi(p) => {
                let first = OpenAiBackend::new(p.clone()).context("--backend openai")?;
                let p = p.clone();
                (
                    first.describe(),
                    Box::new(move || {
                        let b = OpenAiBackend::new(p.clone())
                            .map_err(|e| DatasetError::Backend(e.to_string()))?;
                        Ok(Box::new(b) as Box<dyn Backend>)
                    }),
                )
            }
        };
    let e = evaluate(&job.data, &job.params, &describe, factory.as_ref())
        .with_context(|| format!("rco eval of {}", job.data.display()))?;
    let out = job.out.clone().unwrap_or_else(|| job.data.join("eval"));
    let files = write_eval(&e, &out)?;
    Ok(EvalOutput { eval: e, files })
}
