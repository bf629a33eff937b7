//! DriveLM-Deficit: building a data set (`fogline dataset deficit`, `dataset import`) and
//! scoring a backend on it (`fogline rco eval`: `eval.json`, `eval.md` and `report.html`,
//! the report's section with a gallery of samples). The work is in `fogline-dataset` and
//! `fogline-report`; this module picks the backend, loads the gallery's frames, writes the
//! files as one set and formats what the front-ends print. Behind the `dataset` feature
//! (part of `jobs`), which the Python package turns on.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use fogline_dataset::DatasetError;
use fogline_dataset::eval::{evaluate, write_eval_with};
use fogline_dataset::observe::observations;
use fogline_dataset::sample::{Manifest, read_samples};

pub use fogline_dataset::eval::{EvalParams, markdown};
pub use fogline_dataset::{BuildParams, Built, ImageKind, ImportParams, Split};
use fogline_rco::backend::Backend;
use fogline_rco::deficit_eval::DeficitEval;
use fogline_rco::{OpenAiBackend, OpenAiParams, RulesBackend};
use fogline_report::deficit::{DeficitSection, GalleryFrame, GallerySample, pick_gallery};

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
    /// Where `eval.json`, `eval.md` and `report.html` go (default: `data/eval`).
    pub out: Option<PathBuf>,
    /// The backend.
    pub backend: EvalBackend,
    /// Split, limit, concurrency.
    pub params: EvalParams,
    /// Samples in the report's gallery (0: none).
    pub gallery: usize,
}

/// The default number of samples in the report's gallery (two per hidden class: the first
/// answered wrongly, the first answered right).
pub const GALLERY: usize = 8;

/// What an evaluation wrote.
#[derive(Debug, Clone)]
pub struct EvalOutput {
    /// The result.
    pub eval: DeficitEval,
    /// `eval.json`, `eval.md`, `report.html`.
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

/// Scores the backend on the data set and writes `eval.json`, `eval.md` and `report.html`
/// (the figure-6 tables and a gallery of `job.gallery` samples) as one set.
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
    let section = deficit_section(e, &job.data, job.gallery)?;
    let html = fogline_report::deficit::render_page(&section, None)
        .context("the evaluation's report.html")?;
    let files = write_eval_with(&section.eval, &out, &[("report.html", html.as_bytes())])?;
    Ok(EvalOutput {
        eval: section.eval,
        files,
    })
}

/// The report section of an evaluation: `e` with a gallery of up to `gallery` samples
/// ([`pick_gallery`]), their frames read from the data set in `data` (as the backend saw
/// them) with the expert's strategy rationale.
pub fn deficit_section(e: DeficitEval, data: &Path, gallery: usize) -> Result<DeficitSection> {
    let picks = pick_gallery(&e, gallery);
    let mut samples = Vec::with_capacity(picks.len());
    if !picks.is_empty() {
        let manifest = Manifest::read(data)?;
        let records = read_samples(data)?;
        for i in picks {
            let id = &e.answers[i].id;
            let record = records.iter().find(|r| &r.id == id).with_context(|| {
                format!(
                    "gallery: sample {id} of the evaluation is not in {}",
                    data.join(fogline_dataset::sample::SAMPLES_JSONL).display()
                )
            })?;
            let history = observations(&manifest, record, Some(data))?;
            let mut frames = Vec::new();
            for cam in fogline_dataset::observe::VIEWS {
                for (obs, rec) in history.iter().zip(&record.frames) {
                    if let Some(v) = obs.view(cam)
                        && let Some(rgb) = &v.rgb
                    {
                        frames.push(GalleryFrame {
                            camera: cam.short().to_string(),
                            t_s: rec.t_s,
                            width: v.width,
                            height: v.height,
                            rgb: rgb.to_vec(),
                        });
                    }
                }
            }
            samples.push(GallerySample {
                id: id.clone(),
                expert_rationale: Some(record.rationale.strategy.clone()),
                frames,
            });
        }
    }
    Ok(DeficitSection::new(e, samples)?)
}

/// Reads `dir/eval.json` (as `fogline rco eval` wrote it) into the report's section, with a
/// gallery of `gallery` samples from the data set it names (or, when that path does not hold
/// one, the data set `dir` sits in: `rco eval` writes into `DATA/eval` by default); when
/// neither can be read the section has no gallery (and says so) and a warning is logged.
pub fn read_section(dir: &Path, gallery: usize) -> Result<DeficitSection> {
    let path = dir.join("eval.json");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let e = fogline_report::deficit::deficit_eval_from_json(&text, &path.display().to_string())?;
    let has_manifest = |d: &Path| d.join(fogline_dataset::sample::MANIFEST_JSON).is_file();
    let recorded = PathBuf::from(&e.data);
    let data = match dir.parent() {
        Some(parent) if !has_manifest(&recorded) && has_manifest(parent) => parent.to_path_buf(),
        _ => recorded,
    };
    match deficit_section(e.clone(), &data, gallery) {
        Ok(s) => Ok(s),
        Err(err) => {
            log::warn!("report: no gallery: {err:#}");
            Ok(DeficitSection::new(e, Vec::new())?)
        }
    }
}
