//! Generating a corpus of clips on disk (what `fogline world generate` runs): one directory
//! per clip in the documented clip format, then the typed manifest `corpus.json`, written
//! last.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result, bail};
use fogline_io::{Progress, write_atomic};
use fogline_world::corpus::{CORPUS_FILE, Corpus, CorpusClip};
use fogline_world::{Clip, WorldConfig};
use rayon::prelude::*;

/// Generates every clip of `config` into `out` (created if needed) on `jobs` threads (default:
/// all cores), with a progress bar, then writes `corpus.json`. A manifest left by an earlier
/// run is removed first, so a failed run leaves none; clip directories of an earlier run
/// that this corpus does not hold are left alone and warned about.
pub fn generate_corpus(config: &WorldConfig, out: &Path, jobs: Option<usize>) -> Result<Corpus> {
    if jobs == Some(0) {
        bail!("--jobs must be at least 1");
    }
    config
        .validate()
        .context("invalid world parameters (--width, --height, --scenario)")?;
    if out.exists() && !out.is_dir() {
        bail!("--out {} exists and is not a directory", out.display());
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    // A manifest from an earlier run would claim that this one completed.
    let manifest = out.join(CORPUS_FILE);
    if manifest.exists() {
        std::fs::remove_file(&manifest)
            .with_context(|| format!("cannot remove the old {}", manifest.display()))?;
    }
    let total = config.mix.total();
    let pool = match jobs {
        Some(j) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(j)
                .build()
                .context("cannot start the worker threads")?,
        ),
        None => None,
    };
    let threads = pool
        .as_ref()
        .map_or_else(rayon::current_num_threads, |p| p.current_num_threads());
    log::info!(
        "world generate: {total} clips, seed {}, {}x{}{}, {threads} jobs, into {}",
        config.seed,
        config.width,
        config.height,
        if config.depth { " + depth" } else { "" },
        out.display()
    );
    let progress = Progress::new(total, "clips");
    let work = || -> Result<Vec<CorpusClip>> {
        (0..total)
            .into_par_iter()
            .map(|i| {
                let clip = fogline_world::generate_clip(config, i)
                    .with_context(|| format!("cannot generate clip {i}"))?;
                fogline_world::write_clip(out, &clip)
                    .with_context(|| format!("cannot write clip {}", clip.id))?;
                progress.inc();
                Ok(CorpusClip {
                    id: clip.id,
                    scenario: clip.scenario,
                })
            })
            .collect()
    };
    let clips = match &pool {
        Some(p) => p.install(work),
        None => work(),
    };
    progress.finish();
    let clips = clips?;

    let ids: BTreeSet<&str> = clips.iter().map(|c| c.id.as_str()).collect();
    let stale = fogline_world::list_clips(out)?
        .iter()
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_none_or(|n| !ids.contains(n))
        })
        .count();
    if stale > 0 {
        log::warn!(
            "{} holds {stale} clip directories from an earlier run that are not in this corpus \
             (corpus.json lists only this run's clips)",
            out.display()
        );
    }
    let corpus = Corpus::new(
        &format!("fogline {}", env!("CARGO_PKG_VERSION")),
        config.clone(),
        clips,
    );
    let mut bytes = serde_json::to_vec_pretty(&corpus)?;
    bytes.push(b'\n');
    write_atomic(&manifest, &bytes)?;
    Ok(corpus)
}

/// Reads the clip directory `dir` (checking it against the clip format; a corpus directory
/// given by mistake is named as such) and writes the summary `fogline world show` prints.
pub fn show_clip(dir: &Path, out: &mut dyn Write) -> Result<Clip> {
    let clip = fogline_world::read_clip(dir).with_context(|| {
        // A corpus directory given by mistake: say so.
        let clips = if dir.join(fogline_world::format::CLIP_JSON).exists() {
            0
        } else {
            fogline_world::list_clips(dir).map_or(0, |v| v.len())
        };
        if clips > 0 {
            format!(
                "{} is not a clip but holds {clips} clip directories: give one of them",
                dir.display()
            )
        } else {
            format!("{} is not a valid clip", dir.display())
        }
    })?;
    write_summary(out, dir, &clip)?;
    Ok(clip)
}

/// The summary `world show` prints (`+ 0.0` turns a `-0` time into `0`).
fn write_summary(out: &mut dyn Write, dir: &Path, clip: &Clip) -> Result<()> {
    let times: Vec<String> = clip
        .cameras
        .first()
        .map(|c| {
            c.frames
                .iter()
                .map(|f| format!("{}", f.t_s + 0.0))
                .collect()
        })
        .unwrap_or_default();
    writeln!(out, "clip          {} ({})", clip.id, dir.display())?;
    writeln!(out, "scenario      {}", clip.scenario)?;
    writeln!(
        out,
        "frames        {} per camera at t = {} s",
        times.len(),
        times.join(", ")
    )?;
    writeln!(
        out,
        "{:<28} {:>10} {:>6}  boxes per frame",
        "camera", "size", "depth"
    )?;
    for cam in &clip.cameras {
        let boxes: Vec<String> = cam
            .frames
            .iter()
            .map(|f| f.boxes.len().to_string())
            .collect();
        let depth = cam.frames.iter().all(|f| f.depth.is_some());
        writeln!(
            out,
            "{:<28} {:>10} {:>6}  {}",
            cam.calib.id.name(),
            format!("{}x{}", cam.calib.width, cam.calib.height),
            if depth { "yes" } else { "no" },
            boxes.join(" ")
        )?;
    }
    if let (Some(first), Some(last)) = (clip.ego_history.first(), clip.ego_history.last()) {
        writeln!(
            out,
            "ego history   {} poses, t = {} … {} s, speed at t0 {:.2} m/s",
            clip.ego_history.len(),
            first.t_s + 0.0,
            last.t_s + 0.0,
            last.speed_mps
        )?;
    }
    if let (Some(a), Some(b)) = (clip.ground_truth.xy.first(), clip.ground_truth.xy.last()) {
        writeln!(
            out,
            "ground truth  {} waypoints: first ({:.2}, {:.2}) m, last ({:.2}, {:.2}) m",
            clip.ground_truth.xy.len(),
            a[0],
            a[1],
            b[0],
            b[1]
        )?;
    }
    writeln!(
        out,
        "decision      {}",
        clip.scene
            .decision
            .map_or_else(|| "(not given)".to_string(), |d| d.name().to_string())
    )?;
    if !clip.scene.facts.is_empty() {
        let facts: Vec<String> = clip
            .scene
            .facts
            .iter()
            .map(|(k, v)| match v {
                serde_json::Value::String(s) => format!("{k}={s}"),
                other => format!("{k}={other}"),
            })
            .collect();
        writeln!(out, "facts         {}", facts.join(", "))?;
    }
    Ok(())
}
