//! The import job: a PhysicalAI-AV tree in, clips in fogline's clip format out (what
//! `fogline clips import physicalai-av` runs).
//!
//! For every selected clip of the index and every decision time `t0`: the frames of each
//! camera at `t0 − 0.3, −0.2, −0.1, t0` (the last frame at or before each time, decoded and
//! resized by ffmpeg), the ego history and the ground-truth future from the egomotion, the
//! scenario from the user's labels (else `OTHER`), fogline's standard pinhole calibration at
//! the output size. Each clip is written atomically as soon as it is made; `import.json`,
//! the manifest, is written last (atomically), so its presence means the run completed.

use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::{Path, PathBuf};

use fogline_io::{Progress, write_atomic};
use fogline_perturb::frame::Frame;
use fogline_types::clip::{CameraCalib, CameraId, FRAMES};
use fogline_world::{CameraClip, CameraFrame, Clip, SceneInfo};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::egomotion::{EgoInterpolator, Egomotion, STEP_US, secs};
use crate::error::{ImportError, Result};
use crate::labels::{UNLABELLED, read_labels};
use crate::layout::{Archive, EGOMOTION, IndexRow, Layout, camera_feature};
use crate::table::Table;
use crate::video::{Ffmpeg, frame_index};

/// The manifest an import writes last.
pub const MANIFEST: &str = "import.json";

/// The default decision time: 5.1 s into the clip, Alpamayo R1's default (it leaves 1.5 s of
/// history before and 6.4 s of future after it in a 20 s clip).
pub const DEFAULT_T0_US: i64 = 5_100_000;

/// What to import and how.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImportParams {
    /// The root of the PhysicalAI-AV tree (holding `clip_index.parquet`).
    pub root: PathBuf,
    /// The output directory: one clip directory per clip and `t0`, then `import.json`.
    pub out: PathBuf,
    /// Decision times, µs on the dataset's clock (its timestamps start near 0 at the start
    /// of a clip); one fogline clip per dataset clip and time.
    pub t0_us: Vec<i64>,
    /// The cameras to import, in the clip's order.
    pub cameras: Vec<CameraId>,
    /// Output frame width, px.
    pub width: u32,
    /// Output frame height, px.
    pub height: u32,
    /// A CSV of scenario labels (`clip_id,scenario`); clips it does not name are `OTHER`.
    pub labels: Option<PathBuf>,
    /// Only these dataset clips (all of the index when empty).
    pub clip_ids: Vec<String>,
    /// Only the clips of these chunks (all when empty).
    pub chunks: Vec<i64>,
    /// At most this many dataset clips (in the index's order).
    pub limit: Option<usize>,
    /// Also import the clips the index marks invalid (`clip_is_valid = false`).
    pub include_invalid: bool,
    /// Record a clip that fails and go on (else the first failure stops the import).
    pub keep_going: bool,
    /// The ffmpeg binary (default: found as [`Ffmpeg::locate`] says).
    pub ffmpeg: Option<PathBuf>,
    /// Dataset clips imported in parallel (default: the current thread pool's size).
    pub jobs: Option<usize>,
}

impl Default for ImportParams {
    fn default() -> Self {
        Self {
            root: PathBuf::new(),
            out: PathBuf::new(),
            t0_us: vec![DEFAULT_T0_US],
            cameras: CameraId::ALL.to_vec(),
            width: 576,
            height: 320,
            labels: None,
            clip_ids: Vec::new(),
            chunks: Vec::new(),
            limit: None,
            include_invalid: false,
            keep_going: false,
            ffmpeg: None,
            jobs: None,
        }
    }
}

impl ImportParams {
    /// Checks the parameters (before anything is read or written).
    pub fn validate(&self) -> Result<()> {
        if self.root.as_os_str().is_empty() {
            return Err(ImportError::invalid(
                "root",
                "\"\"",
                "the dataset's directory",
            ));
        }
        if self.out.as_os_str().is_empty() {
            return Err(ImportError::invalid("out", "\"\"", "an output directory"));
        }
        if self.t0_us.is_empty() || self.t0_us.len() > 1000 {
            return Err(ImportError::invalid(
                "t0_us",
                format!("{} times", self.t0_us.len()),
                "1 to 1000 decision times",
            ));
        }
        if self.t0_us.iter().collect::<BTreeSet<_>>().len() != self.t0_us.len() {
            return Err(ImportError::invalid(
                "t0_us",
                format!("{:?}", self.t0_us),
                "distinct times",
            ));
        }
        if let Some(t) = self
            .t0_us
            .iter()
            .find(|t| t.unsigned_abs() > 1_000_000_000_000)
        {
            return Err(ImportError::invalid(
                "t0_us",
                t,
                "a time within ±10⁶ s of the clip's start",
            ));
        }
        let cams: BTreeSet<_> = self.cameras.iter().collect();
        if self.cameras.is_empty() || cams.len() != self.cameras.len() {
            return Err(ImportError::invalid(
                "cameras",
                format!("{:?}", self.cameras),
                "1 to 4 distinct cameras",
            ));
        }
        if !(16..=1920).contains(&self.width) || !(16..=1080).contains(&self.height) {
            return Err(ImportError::invalid(
                "width x height",
                format!("{}x{}", self.width, self.height),
                "16..=1920 x 16..=1080",
            ));
        }
        if self.limit == Some(0) {
            return Err(ImportError::invalid("limit", 0, "at least 1"));
        }
        if self.jobs == Some(0) {
            return Err(ImportError::invalid("jobs", 0, "at least 1"));
        }
        Ok(())
    }
}

/// One imported clip, as the manifest lists it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ImportedClip {
    /// The fogline clip id (`<dataset clip id>_t<t0 in s>s`), its directory's name.
    pub id: String,
    /// The dataset's clip id.
    pub source_clip_id: String,
    /// Its chunk.
    pub chunk: i64,
    /// The decision time, µs.
    pub t0_us: i64,
    /// The scenario label.
    pub scenario: String,
}

/// A dataset clip that could not be imported (with `keep_going`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FailedClip {
    /// The dataset's clip id.
    pub source_clip_id: String,
    /// Why (the whole error chain).
    pub error: String,
}

/// Dataset clips left out, by reason.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Skipped {
    /// Marked invalid by the index (`clip_is_valid = false`).
    pub invalid: usize,
    /// In chunks whose files are not under the root (not downloaded).
    pub not_downloaded: usize,
    /// Beyond `limit`.
    pub beyond_limit: usize,
}

/// The manifest `import.json` and what the command prints. It holds no times and no paths:
/// the same tree and parameters give the same bytes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImportSummary {
    /// Always `fogline-import`.
    pub format: String,
    /// Always 1.
    pub version: u32,
    /// `fogline <version>`.
    pub generated_by: String,
    /// Always `physicalai-av`.
    pub source: String,
    /// The first line of `ffmpeg -version`.
    pub ffmpeg: String,
    /// Whether the tree's `features.csv` gave the layout (else the documented default).
    pub features_csv: bool,
    /// Decision times, µs.
    pub t0_us: Vec<i64>,
    /// The cameras.
    pub cameras: Vec<CameraId>,
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// Rows of the labels CSV (0 without one).
    pub labels: usize,
    /// Dataset clips imported.
    pub n_source_clips: usize,
    /// Clips written.
    pub n_clips: usize,
    /// The clips written, in the index's order, then by `t0`.
    pub clips: Vec<ImportedClip>,
    /// Dataset clips left out before reading them.
    pub skipped: Skipped,
    /// Dataset clips that failed (only with `keep_going`).
    pub failed: Vec<FailedClip>,
}

impl ImportSummary {
    /// The summary `fogline clips import` prints: counts, clips per scenario, the manifest.
    pub fn write_text(&self, out_dir: &Path, w: &mut dyn Write) -> std::io::Result<()> {
        writeln!(
            w,
            "{} clips from {} PhysicalAI-AV clips (t0 {} s; {} at {}x{}) into {}",
            self.n_clips,
            self.n_source_clips,
            self.t0_us
                .iter()
                .map(|&t| secs(t))
                .collect::<Vec<_>>()
                .join(", "),
            self.cameras
                .iter()
                .map(|c| c.short())
                .collect::<Vec<_>>()
                .join(", "),
            self.width,
            self.height,
            out_dir.display()
        )?;
        let mut per: BTreeMap<&str, usize> = BTreeMap::new();
        for c in &self.clips {
            *per.entry(c.scenario.as_str()).or_default() += 1;
        }
        writeln!(w, "{:<16} {:>6}", "scenario", "clips")?;
        for (s, n) in per {
            writeln!(w, "{s:<16} {n:>6}")?;
        }
        let s = &self.skipped;
        if s.invalid + s.not_downloaded + s.beyond_limit > 0 {
            writeln!(
                w,
                "left out: {} marked invalid, {} in chunks not downloaded, {} beyond --limit",
                s.invalid, s.not_downloaded, s.beyond_limit
            )?;
        }
        if !self.failed.is_empty() {
            writeln!(
                w,
                "failed: {} clips (listed with their errors in {MANIFEST})",
                self.failed.len()
            )?;
        }
        writeln!(w, "{}", out_dir.join(MANIFEST).display())
    }
}

/// Everything the import reads once: the layout, the labels, ffmpeg.
struct Context<'a> {
    params: &'a ImportParams,
    layout: Layout,
    labels: BTreeMap<String, String>,
    ffmpeg: Ffmpeg,
}

/// Imports the clips `params` selects (see the module's documentation); returns the
/// manifest it wrote. Nothing is written before the parameters, ffmpeg, the layout, the
/// labels and the clip index have been read and checked.
pub fn import_physicalai_av(params: &ImportParams) -> Result<ImportSummary> {
    params.validate()?;
    let ffmpeg = Ffmpeg::locate(params.ffmpeg.as_deref())?;
    let layout = Layout::open(&params.root)?;
    let labels = match &params.labels {
        Some(p) => read_labels(p)?,
        None => BTreeMap::new(),
    };
    let index = layout.clip_index()?;
    let ctx = Context {
        params,
        layout,
        labels,
        ffmpeg,
    };
    let (rows, skipped) = ctx.select(index)?;
    log::info!(
        "import: {} PhysicalAI-AV clips × {} t0 from {} ({}), {}, {} cameras at {}x{}",
        rows.len(),
        params.t0_us.len(),
        params.root.display(),
        if ctx.layout.from_features_csv() {
            "layout from features.csv"
        } else {
            "default layout"
        },
        ctx.ffmpeg.version(),
        params.cameras.len(),
        params.width,
        params.height
    );
    let out = &params.out;
    if out.exists() && !out.is_dir() {
        return Err(ImportError::invalid(
            "out",
            out.display(),
            "a directory (it exists and is not one)",
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| ImportError::io(out, e))?;
    let manifest = out.join(MANIFEST);
    if manifest.exists() {
        // A manifest from an earlier run would claim that this one completed.
        std::fs::remove_file(&manifest).map_err(|e| ImportError::io(&manifest, e))?;
    }
    let progress = Progress::new(rows.len(), "clips");
    let one = |row: &IndexRow| -> Result<Vec<ImportedClip>> {
        let clips = ctx.clip(row)?;
        let mut done = Vec::with_capacity(clips.len());
        for (clip, t0) in clips {
            fogline_world::write_clip(out, &clip).map_err(|e| ImportError::Write {
                clip_id: clip.id.clone(),
                source: e,
            })?;
            done.push(ImportedClip {
                id: clip.id,
                source_clip_id: row.clip_id.clone(),
                chunk: row.chunk,
                t0_us: t0,
                scenario: clip.scenario,
            });
        }
        Ok(done)
    };
    let work = || -> Result<Vec<std::result::Result<Vec<ImportedClip>, FailedClip>>> {
        rows.par_iter()
            .map(|row| match one(row) {
                Ok(v) => {
                    progress.inc();
                    Ok(Ok(v))
                }
                Err(e) if params.keep_going => {
                    progress.inc_failed();
                    let error = error_chain(&e);
                    log::warn!("clip {} failed: {error}", row.clip_id);
                    Ok(Err(FailedClip {
                        source_clip_id: row.clip_id.clone(),
                        error,
                    }))
                }
                Err(e) => Err(e),
            })
            .collect()
    };
    let results = match params.jobs {
        Some(j) => rayon::ThreadPoolBuilder::new()
            .num_threads(j)
            .build()
            .map_err(|e| ImportError::invalid("jobs", j, format!("a usable thread count ({e})")))?
            .install(work),
        None => work(),
    };
    progress.finish();
    let results = results?;
    let mut clips = Vec::new();
    let mut failed = Vec::new();
    for r in results {
        match r {
            Ok(v) => clips.extend(v),
            Err(f) => failed.push(f),
        }
    }
    let imported: BTreeSet<&str> = clips.iter().map(|c| c.source_clip_id.as_str()).collect();
    let unused = ctx
        .labels
        .keys()
        .filter(|k| !imported.contains(k.as_str()))
        .count();
    if unused > 0 {
        log::info!("{unused} labelled clips of the labels CSV were not imported");
    }
    let summary = ImportSummary {
        format: "fogline-import".into(),
        version: 1,
        generated_by: format!("fogline {}", env!("CARGO_PKG_VERSION")),
        source: "physicalai-av".into(),
        ffmpeg: ctx.ffmpeg.version().to_string(),
        features_csv: ctx.layout.from_features_csv(),
        t0_us: params.t0_us.clone(),
        cameras: params.cameras.clone(),
        width: params.width,
        height: params.height,
        labels: ctx.labels.len(),
        n_source_clips: imported.len(),
        n_clips: clips.len(),
        clips,
        skipped,
        failed,
    };
    let mut bytes = serde_json::to_vec_pretty(&summary).map_err(|e| {
        ImportError::data(
            manifest.display().to_string(),
            format!("cannot encode: {e}"),
        )
    })?;
    bytes.push(b'\n');
    write_atomic(&manifest, &bytes).map_err(|e| ImportError::io(&manifest, e))?;
    Ok(summary)
}

/// `{e:#}` for an error without anyhow: the message and its causes.
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cur = c.source();
    }
    s
}

/// The fogline clip id of dataset clip `clip_id` at `t0_us`: `<clip_id>_t<seconds>s`.
pub fn clip_name(clip_id: &str, t0_us: i64) -> String {
    format!("{clip_id}_t{}s", secs(t0_us))
}

impl Context<'_> {
    /// The rows to import, and those left out.
    fn select(&self, index: Vec<IndexRow>) -> Result<(Vec<IndexRow>, Skipped)> {
        let p = self.params;
        let index_loc = self.layout.root().join(crate::layout::CLIP_INDEX);
        let known: BTreeSet<&str> = index.iter().map(|r| r.clip_id.as_str()).collect();
        if let Some(missing) = p.clip_ids.iter().find(|c| !known.contains(c.as_str())) {
            return Err(ImportError::data(
                index_loc.display().to_string(),
                format!("no clip {missing} in the index"),
            ));
        }
        let wanted: BTreeSet<&str> = p.clip_ids.iter().map(String::as_str).collect();
        let chunks: BTreeSet<i64> = p.chunks.iter().copied().collect();
        let mut skipped = Skipped::default();
        let mut present: BTreeMap<i64, Option<PathBuf>> = BTreeMap::new();
        let mut rows = Vec::new();
        let mut seen = BTreeSet::new();
        for row in index {
            if (!wanted.is_empty() && !wanted.contains(row.clip_id.as_str()))
                || (!chunks.is_empty() && !chunks.contains(&row.chunk))
            {
                continue;
            }
            if !seen.insert(row.clip_id.clone()) {
                return Err(ImportError::data(
                    index_loc.display().to_string(),
                    format!("clip {} is listed twice", row.clip_id),
                ));
            }
            if row.valid == Some(false) && !p.include_invalid {
                skipped.invalid += 1;
                continue;
            }
            let missing = match present.get(&row.chunk) {
                Some(m) => m.clone(),
                None => {
                    let m = self.missing_chunk_file(row.chunk)?;
                    present.insert(row.chunk, m.clone());
                    m
                }
            };
            if let Some(file) = missing {
                if wanted.contains(row.clip_id.as_str()) {
                    return Err(ImportError::clip(
                        &row.clip_id,
                        format!("its chunk {} has no {}", row.chunk, file.display()),
                    ));
                }
                skipped.not_downloaded += 1;
                continue;
            }
            if p.limit.is_some_and(|l| rows.len() >= l) {
                skipped.beyond_limit += 1;
                continue;
            }
            rows.push(row);
        }
        if rows.is_empty() {
            return Err(ImportError::data(
                self.layout.root().display().to_string(),
                format!(
                    "no clip to import: of the clips of the index that the selection keeps, \
                     {} are marked invalid and {} are in chunks whose files are not here \
                     (a chunk needs its egomotion zip and the zip of every camera asked for, \
                     e.g. {} for chunk 0)",
                    skipped.invalid,
                    skipped.not_downloaded,
                    self.layout
                        .chunk_file(EGOMOTION, 0)
                        .map(|p| p.display().to_string())
                        .unwrap_or_else(|_| "its egomotion zip".into())
                ),
            ));
        }
        Ok((rows, skipped))
    }

    /// The first chunk file of `chunk` that is not there, if any.
    fn missing_chunk_file(&self, chunk: i64) -> Result<Option<PathBuf>> {
        let mut files = vec![self.layout.chunk_file(EGOMOTION, chunk)?];
        for &cam in &self.params.cameras {
            files.push(self.layout.chunk_file(camera_feature(cam), chunk)?);
        }
        Ok(files.into_iter().find(|f| !f.is_file()))
    }

    /// The fogline clips of one dataset clip, one per `t0`, with their `t0`.
    fn clip(&self, row: &IndexRow) -> Result<Vec<(Clip, i64)>> {
        let p = self.params;
        let id = &row.clip_id;
        for &t0 in &p.t0_us {
            fogline_world::format::check_clip_id(&clip_name(id, t0))
                .map_err(|e| ImportError::clip(id, format!("cannot name its clip: {e}")))?;
        }
        // Egomotion: the history and the future at every t0.
        let ego = self.egomotion(row)?;
        let windows = p
            .t0_us
            .iter()
            .map(|&t0| ego.window(t0).map_err(|e| ImportError::clip(id, e)))
            .collect::<Result<Vec<_>>>()?;
        // Cameras: the frames at every t0, cameras decoded in parallel.
        let cameras = p
            .cameras
            .par_iter()
            .map(|&cam| self.camera(row, cam))
            .collect::<Result<Vec<_>>>()?;
        let mut out = Vec::with_capacity(p.t0_us.len());
        for (k, (&t0, window)) in p.t0_us.iter().zip(windows).enumerate() {
            let mut frame_times = serde_json::Map::new();
            let mut cams = Vec::with_capacity(cameras.len());
            for (cam, per_t0) in p.cameras.iter().zip(&cameras) {
                let (frames, times) = &per_t0[k];
                frame_times.insert(cam.short().to_string(), serde_json::json!(times));
                cams.push(CameraClip {
                    calib: CameraCalib::standard(*cam, p.width, p.height),
                    frames: frames.clone(),
                });
            }
            let mut facts = serde_json::Map::new();
            facts.insert("source".into(), "physicalai-av".into());
            facts.insert("source_clip_id".into(), id.clone().into());
            facts.insert("chunk".into(), row.chunk.into());
            if let Some(s) = &row.split {
                facts.insert("split".into(), s.clone().into());
            }
            facts.insert("t0_us".into(), t0.into());
            facts.insert("frame_timestamps_us".into(), frame_times.into());
            facts.insert(
                "calibration".into(),
                "fogline's standard pinhole rig, not the dataset's".into(),
            );
            out.push((
                Clip {
                    id: clip_name(id, t0),
                    scenario: self
                        .labels
                        .get(id)
                        .cloned()
                        .unwrap_or_else(|| UNLABELLED.to_string()),
                    cameras: cams,
                    ego_history: window.history,
                    ground_truth: window.ground_truth,
                    scene: SceneInfo {
                        decision: None,
                        facts,
                    },
                },
                t0,
            ));
        }
        Ok(out)
    }

    /// The clip's egomotion, interpolated.
    fn egomotion(&self, row: &IndexRow) -> Result<EgoInterpolator> {
        let zip = self.layout.chunk_file(EGOMOTION, row.chunk)?;
        let member = self.layout.member(EGOMOTION, EGOMOTION, &row.clip_id)?;
        let mut a = Archive::open(&zip)?;
        let loc = a.location(&member);
        let table = Table::read(&loc, a.read(&member)?)?;
        Egomotion::from_table(&table)?
            .interpolator()
            .map_err(|e| ImportError::data(loc, e))
    }

    /// One camera's frames and their timestamps, per `t0`.
    #[allow(clippy::type_complexity)]
    fn camera(&self, row: &IndexRow, cam: CameraId) -> Result<Vec<(Vec<CameraFrame>, Vec<i64>)>> {
        let p = self.params;
        let feature = camera_feature(cam);
        let zip = self.layout.chunk_file(feature, row.chunk)?;
        let ts_member = self
            .layout
            .member(feature, "frame_timestamps", &row.clip_id)?;
        let video_member = self.layout.member(feature, "video", &row.clip_id)?;
        let mut a = Archive::open(&zip)?;
        let ts_loc = a.location(&ts_member);
        let ts = Table::read(&ts_loc, a.read(&ts_member)?)?.i64_column("timestamp")?;
        if let Some(i) = (1..ts.len()).find(|&i| ts[i] <= ts[i - 1]) {
            return Err(ImportError::cell(
                ts_loc,
                i as u64 + 1,
                "timestamp",
                format!(
                    "{} after {}: frame timestamps must be strictly increasing",
                    ts[i],
                    ts[i - 1]
                ),
            ));
        }
        // The frame shown at each requested time, for every t0.
        let mut wanted: Vec<Vec<usize>> = Vec::with_capacity(p.t0_us.len());
        for &t0 in &p.t0_us {
            let mut v = Vec::with_capacity(FRAMES);
            for k in 0..FRAMES as i64 {
                let t = t0 - (FRAMES as i64 - 1 - k) * STEP_US;
                let i = frame_index(&ts, t).ok_or_else(|| {
                    ImportError::clip(
                        &row.clip_id,
                        format!(
                            "{feature} has frames from {} to {} s ({}); t0 = {} s needs one at \
                             or before {} s",
                            ts.first().map_or("-".into(), |&t| secs(t)),
                            ts.last().map_or("-".into(), |&t| secs(t)),
                            ts_loc,
                            secs(t0),
                            secs(t)
                        ),
                    )
                })?;
                v.push(i);
            }
            wanted.push(v);
        }
        let unique: Vec<usize> = wanted
            .iter()
            .flatten()
            .copied()
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect();
        let video_loc = a.location(&video_member);
        let mp4 = a.read(&video_member)?;
        let decoded = self
            .ffmpeg
            .decode(&video_loc, &mp4, &unique, p.width, p.height)?;
        let by_index: BTreeMap<usize, &Vec<u8>> = unique.iter().copied().zip(&decoded).collect();
        wanted
            .iter()
            .map(|idx| {
                let mut frames = Vec::with_capacity(FRAMES);
                for (k, i) in idx.iter().enumerate() {
                    let rgb = by_index.get(i).map(|v| (*v).clone()).unwrap_or_default();
                    let image = Frame::new(p.width, p.height, rgb).map_err(|e| {
                        ImportError::data(&video_loc, format!("decoded frame {i}: {e}"))
                    })?;
                    frames.push(CameraFrame {
                        t_s: -((FRAMES - 1 - k) as f64) / 10.0,
                        image,
                        depth: None,
                        boxes: Vec::new(),
                    });
                }
                Ok((frames, idx.iter().map(|&i| ts[i]).collect()))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_are_checked_first() {
        let ok = ImportParams {
            root: "r".into(),
            out: "o".into(),
            ..ImportParams::default()
        };
        assert!(ok.validate().is_ok());
        let bad = |f: &dyn Fn(&mut ImportParams), what: &str| {
            let mut p = ok.clone();
            f(&mut p);
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        };
        bad(&|p| p.t0_us.clear(), "t0_us");
        bad(&|p| p.t0_us = vec![1, 1], "distinct");
        bad(&|p| p.cameras = vec![CameraId::FrontWide; 2], "cameras");
        bad(&|p| p.width = 8, "width x height");
        bad(&|p| p.jobs = Some(0), "jobs");
        bad(&|p| p.limit = Some(0), "limit");
        bad(&|p| p.out = PathBuf::new(), "out");
    }

    #[test]
    fn clip_names() {
        assert_eq!(clip_name("25cd-4769", 5_100_000), "25cd-4769_t5.1s");
        assert_eq!(clip_name("a", 12_000_000), "a_t12s");
        assert!(fogline_world::format::check_clip_id(&clip_name("25cd-4769", 5_100_000)).is_ok());
    }
}
