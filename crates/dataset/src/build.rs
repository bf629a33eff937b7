//! Building a data set from fogline's world: plans drawn per sample, rendered over five
//! seconds on the RCO's three views at the closed loop's sizes, the hidden object masked by
//! the perturbation crate (black fill, red outline) whenever the closed loop's detector
//! model would find it, labelled by the privileged expert, written with the exports.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use fogline_io::{FileSet, ImageFormat, Progress};
use fogline_perturb::{FrameInput, FrameKey, Perturbation, Prepared};
use fogline_sim::run::SensorParams;
use fogline_sim::sense::{Weather, detected, rco_cameras};
use fogline_stats::seed::child;
use fogline_types::clip::CameraCalib;
use fogline_world::render::render;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::DatasetError;
use crate::export;
use crate::sample::{
    BoxRecord, FRAME_TIMES_S, FrameRecord, MANIFEST_JSON, Manifest, SAMPLES_JSONL, SampleRecord,
    Split, SplitCounts, ViewRecord,
};
use crate::scene::{HORIZON_S, ScenePlan, TARGET_TRACK, draw_plan, label, scene_of};

/// How many plans a sample may draw before its hidden object is seen often enough.
pub const MAX_ATTEMPTS: u64 = 64;
/// The hidden object must be masked in at least this many of the five frames (the last
/// one always).
pub const MIN_MASKED_FRAMES: usize = 2;

/// Image files: PNG (lossless) or JPEG.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImageKind {
    /// PNG.
    Png,
    /// JPEG.
    Jpeg,
}

impl ImageKind {
    /// The file extension.
    pub fn ext(self) -> &'static str {
        match self {
            ImageKind::Png => "png",
            ImageKind::Jpeg => "jpg",
        }
    }
}

/// Settings of a build.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BuildParams {
    /// Samples.
    pub samples: u64,
    /// The seed.
    pub seed: u64,
    /// Clips per town (the split unit).
    pub clips_per_town: u64,
    /// Shares of the towns in train, val and test (sum 1).
    pub split_fractions: [f64; 3],
    /// Image files.
    pub image: ImageKind,
    /// JPEG quality, 1–100.
    pub jpeg_quality: u8,
    /// Worker threads (0: as many as the current rayon pool, by default all cores).
    pub threads: usize,
}

impl Default for BuildParams {
    fn default() -> Self {
        Self {
            samples: 1000,
            seed: 0,
            clips_per_town: 4,
            split_fractions: [0.8, 0.1, 0.1],
            image: ImageKind::Png,
            jpeg_quality: 90,
            threads: 0,
        }
    }
}

impl BuildParams {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), DatasetError> {
        if self.samples == 0 {
            return Err(DatasetError::Params("samples must be at least 1".into()));
        }
        if self.clips_per_town == 0 {
            return Err(DatasetError::Params(
                "clips_per_town must be at least 1".into(),
            ));
        }
        let f = self.split_fractions;
        if f.iter().any(|v| !v.is_finite() || *v < 0.0)
            || (f.iter().sum::<f64>() - 1.0).abs() > 1e-6
        {
            return Err(DatasetError::Params(format!(
                "split fractions {f:?} must be >= 0 and sum to 1"
            )));
        }
        if !(1..=100).contains(&self.jpeg_quality) {
            return Err(DatasetError::Params(format!(
                "jpeg_quality {} is not in 1..=100",
                self.jpeg_quality
            )));
        }
        Ok(())
    }

    fn format(&self) -> ImageFormat {
        match self.image {
            ImageKind::Png => ImageFormat::Png,
            ImageKind::Jpeg => ImageFormat::Jpeg {
                quality: self.jpeg_quality,
            },
        }
    }
}

/// The split of every town: towns ordered by a seeded hash, the first `round(f_train ·
/// towns)` to train, the next `round(f_val · towns)` to val, the rest to test. Exact shares,
/// and a town (with all its clips) is in exactly one split.
pub fn town_splits(seed: u64, towns: u64, fractions: [f64; 3]) -> Vec<Split> {
    let mut order: Vec<(u64, u64)> = (0..towns)
        .map(|t| (child(seed, &[0x5B117, t]), t))
        .collect();
    order.sort_unstable();
    let n_train = (fractions[0] * towns as f64).round() as usize;
    let n_val = ((fractions[1] * towns as f64).round() as usize)
        .min(order.len() - n_train.min(order.len()));
    let mut out = vec![Split::Test; towns as usize];
    for (rank, (_, t)) in order.iter().enumerate() {
        out[*t as usize] = if rank < n_train {
            Split::Train
        } else if rank < n_train + n_val {
            Split::Val
        } else {
            Split::Test
        };
    }
    out
}

/// One rendered view of a clip.
#[derive(Debug, Clone)]
pub struct RenderedView {
    /// Its calibration.
    pub calib: CameraCalib,
    /// RGB8 pixels.
    pub rgb: Vec<u8>,
    /// The deficit regions `[x0, y0, x1, y1)`.
    pub deficits: Vec<[u32; 4]>,
    /// The visible road users' boxes.
    pub objects: Vec<BoxRecord>,
}

/// The perturbations of each weather (its atmosphere, then the target's mask).
pub struct Lenses {
    prepared: Vec<(Weather, Prepared)>,
}

impl Lenses {
    /// Prepares all six.
    pub fn new(seed: u64) -> Result<Self, DatasetError> {
        let mut prepared = Vec::new();
        for w in Weather::ALL {
            let mut name = String::new();
            if let Some(c) = w.condition() {
                name.push_str(c);
                name.push('+');
            }
            name.push_str(&format!("mask_track_{TARGET_TRACK}"));
            let p = Perturbation::parse(&name)
                .and_then(|p| p.prepare(seed))
                .map_err(|e| DatasetError::Params(format!("condition {name}: {e}")))?;
            prepared.push((w, p));
        }
        Ok(Self { prepared })
    }

    fn get(&self, w: Weather) -> Option<&Prepared> {
        self.prepared.iter().find(|(x, _)| *x == w).map(|(_, p)| p)
    }
}

/// Renders a plan's five frames on `cameras`; `[frame][camera]`.
pub fn render_plan(
    plan: &ScenePlan,
    cameras: &[CameraCalib],
    lenses: &Lenses,
    clip_key: u64,
) -> Result<Vec<Vec<RenderedView>>, String> {
    let scene = scene_of(plan);
    let lens = lenses
        .get(plan.town.weather)
        .ok_or("no lens for the weather")?;
    let depth = lens.perturbation().needs_depth();
    let mut frames = Vec::with_capacity(FRAME_TIMES_S.len());
    for (k, &t) in FRAME_TIMES_S.iter().enumerate() {
        let mut views = Vec::with_capacity(cameras.len());
        for calib in cameras {
            let view = render(&scene, calib, t, depth);
            let boxes = detected(view.boxes, calib);
            let input = FrameInput {
                frame: view.image.view(),
                key: FrameKey::new(clip_key, calib.id.index() as u64, k as u64),
                depth: view.depth.as_ref(),
                boxes: &boxes,
            };
            let applied = lens.apply(&input).map_err(|e| e.to_string())?;
            views.push(RenderedView {
                calib: *calib,
                rgb: applied.frame.into_data(),
                deficits: applied
                    .deficits
                    .iter()
                    .map(|d| [d.rect.x0, d.rect.y0, d.rect.x1, d.rect.y1])
                    .collect(),
                objects: boxes
                    .iter()
                    .filter(|b| b.track_id != Some(TARGET_TRACK))
                    .map(|b| BoxRecord {
                        class: b.class.clone(),
                        track_id: b.track_id,
                        bbox: [b.x_px, b.y_px, b.x_px + b.width_px, b.y_px + b.height_px],
                    })
                    .collect(),
            });
        }
        frames.push(views);
    }
    Ok(frames)
}

/// Whether the hidden object is masked in the last frame and in at least
/// [`MIN_MASKED_FRAMES`] frames.
pub fn seen_enough(frames: &[Vec<RenderedView>]) -> bool {
    let masked = |f: &Vec<RenderedView>| f.iter().any(|v| !v.deficits.is_empty());
    frames.last().is_some_and(masked)
        && frames.iter().filter(|f| masked(f)).count() >= MIN_MASKED_FRAMES
}

/// The id of sample `index`.
pub fn sample_id(index: u64) -> String {
    format!("c{index:07}")
}

/// An encoded frame of a sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EncodedImage {
    /// Its path, relative to the data set directory.
    pub path: String,
    /// PNG or JPEG bytes.
    pub bytes: Vec<u8>,
}

/// A made sample: its record and its encoded frames.
#[derive(Debug, Clone, PartialEq)]
pub struct MadeSample {
    /// The record.
    pub record: SampleRecord,
    /// The frames.
    pub images: Vec<EncodedImage>,
}

/// Makes sample `index`: its record, and its frames encoded.
pub fn make_sample(
    params: &BuildParams,
    index: u64,
    split: Split,
    cameras: &[CameraCalib],
    lenses: &Lenses,
) -> Result<MadeSample, DatasetError> {
    let id = sample_id(index);
    let fail = |reason: String| DatasetError::Sample { index, reason };
    for attempt in 0..MAX_ATTEMPTS {
        let plan = draw_plan(params.seed, index, params.clips_per_town, attempt);
        let frames = render_plan(&plan, cameras, lenses, index).map_err(fail)?;
        if !seen_enough(&frames) {
            continue;
        }
        let labels = label(&plan);
        let mut files = Vec::new();
        let mut records = Vec::with_capacity(frames.len());
        for (k, views) in frames.into_iter().enumerate() {
            let mut vr = Vec::with_capacity(views.len());
            for v in views {
                let path = format!(
                    "images/{id}/{}_{k}.{}",
                    v.calib.id.short(),
                    params.image.ext()
                );
                let bytes =
                    fogline_io::encode(&v.rgb, v.calib.width, v.calib.height, params.format())
                        .map_err(fail)?;
                files.push(EncodedImage {
                    path: path.clone(),
                    bytes,
                });
                vr.push(ViewRecord {
                    camera: v.calib.id,
                    image: path,
                    deficits: v.deficits,
                    objects: v.objects,
                });
            }
            records.push(FrameRecord {
                t_s: FRAME_TIMES_S[k],
                ego_speed_mps: plan.ego_speed_mps,
                views: vr,
            });
        }
        let record = SampleRecord {
            id,
            index,
            town: index / params.clips_per_town,
            split,
            class: labels.class,
            motion: labels.motion,
            strategy: labels.strategy,
            rationale: labels.rationale,
            weather: plan.town.weather,
            daylight: plan.town.daylight,
            target: Some(plan.target),
            frames: records,
        };
        return Ok(MadeSample {
            record,
            images: files,
        });
    }
    Err(fail(format!(
        "the hidden object was not seen in {MIN_MASKED_FRAMES} frames in {MAX_ATTEMPTS} scenes"
    )))
}

/// What a build wrote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Built {
    /// The directory.
    pub dir: PathBuf,
    /// Samples.
    pub samples: u64,
    /// Counts per split and `all`.
    pub counts: BTreeMap<String, SplitCounts>,
    /// Worker threads.
    pub threads: usize,
    /// Wall time of the samples (render, label, encode, write), s.
    pub samples_s: f64,
    /// Wall time of everything, s.
    pub elapsed_s: f64,
    /// The files besides the images, relative to `dir`.
    pub files: Vec<String>,
}

impl Built {
    /// The summary the CLI prints.
    pub fn write_text(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        writeln!(
            out,
            "{} samples in {} ({:.1} s: {:.0} samples/s on {} threads; samples {:.1} s)",
            self.samples,
            self.dir.display(),
            self.elapsed_s,
            self.samples as f64 / self.elapsed_s.max(1e-9),
            self.threads,
            self.samples_s
        )?;
        out.write_all(export::balance_markdown(&self.counts).as_bytes())?;
        for f in &self.files {
            writeln!(out, "{}", self.dir.join(f).display())?;
        }
        Ok(())
    }
}

/// Builds a data set of `params.samples` samples into `out` (all files replaced at once at
/// the end; an interrupted build leaves `out` as it was).
pub fn build(params: &BuildParams, out: &Path) -> Result<Built, DatasetError> {
    params.validate()?;
    let clock = Instant::now();
    let built = in_staging(out, |staging| make_all(params, staging))?;
    log::info!(
        "dataset deficit: samples {:.1} s, files and commit {:.1} s",
        built.samples_s,
        clock.elapsed().as_secs_f64() - built.samples_s
    );
    Ok(Built {
        elapsed_s: clock.elapsed().as_secs_f64(),
        ..built
    })
}

/// Runs `make` in a staging directory inside `out`, then moves everything it wrote into
/// `out` as one set (nothing of a failed run is left).
pub(crate) fn in_staging(
    out: &Path,
    make: impl FnOnce(&Path) -> Result<Built, DatasetError>,
) -> Result<Built, DatasetError> {
    if out.exists() && !out.is_dir() {
        return Err(DatasetError::Params(format!(
            "--out {} exists and is not a directory",
            out.display()
        )));
    }
    std::fs::create_dir_all(out).map_err(|e| DatasetError::io(out, e))?;
    let staging = out.join(".fogline-dataset.staging");
    if staging.exists() {
        std::fs::remove_dir_all(&staging).map_err(|e| DatasetError::io(&staging, e))?;
    }
    std::fs::create_dir_all(&staging).map_err(|e| DatasetError::io(&staging, e))?;
    let built = match make(&staging) {
        Ok(b) => b,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(e);
        }
    };
    let committed = commit(&staging, out);
    let _ = std::fs::remove_dir_all(&staging);
    committed?;
    Ok(Built {
        dir: out.to_path_buf(),
        ..built
    })
}

/// Moves a finished staging directory into `out`: the image tree as one directory rename
/// (the old one moved aside first, put back if anything fails), the other files as one
/// [`FileSet`]. One rename instead of one per image keeps 150,000 images cheap.
fn commit(staging: &Path, out: &Path) -> Result<(), DatasetError> {
    let (new_images, images) = (staging.join("images"), out.join("images"));
    let aside = out.join(format!(".images.old-{}", std::process::id()));
    let had_images = images.exists();
    let moved = new_images.exists();
    if moved {
        if had_images {
            std::fs::rename(&images, &aside).map_err(|e| DatasetError::io(&images, e))?;
        }
        if let Err(e) = std::fs::rename(&new_images, &images) {
            if had_images {
                let _ = std::fs::rename(&aside, &images);
            }
            return Err(DatasetError::io(&images, e));
        }
    }
    let mut set = FileSet::new();
    let adopted = set.adopt_dir(staging, out).and_then(|()| set.commit());
    if let Err(e) = adopted {
        if moved {
            let _ = std::fs::rename(&images, &new_images);
            if had_images {
                let _ = std::fs::rename(&aside, &images);
            }
        }
        return Err(DatasetError::io(out, e));
    }
    if moved && had_images {
        let _ = std::fs::remove_dir_all(&aside);
    }
    Ok(())
}

fn make_all(params: &BuildParams, dir: &Path) -> Result<Built, DatasetError> {
    let s = SensorParams::default();
    let cameras = rco_cameras(
        s.width,
        s.height,
        s.wide_fov_deg,
        s.side_width(),
        s.side_height(),
    )
    .to_vec();
    let lenses = Lenses::new(params.seed)?;
    let towns = params.samples.div_ceil(params.clips_per_town);
    let splits = town_splits(params.seed, towns, params.split_fractions);
    let threads = match params.threads {
        0 => rayon::current_num_threads(),
        n => n,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| DatasetError::Params(format!("cannot start the worker threads: {e}")))?;
    let threads = pool.current_num_threads();
    log::info!(
        "dataset deficit: {} samples, seed {}, {} threads, into {}",
        params.samples,
        params.seed,
        threads,
        dir.display()
    );
    let progress = Progress::new(params.samples as usize, "samples");
    let clock = Instant::now();
    let records: Vec<SampleRecord> = pool.install(|| {
        (0..params.samples)
            .into_par_iter()
            .map(|i| {
                let split = splits[(i / params.clips_per_town) as usize];
                let MadeSample { record, images } =
                    make_sample(params, i, split, &cameras, &lenses)?;
                let folder = dir.join("images").join(&record.id);
                std::fs::create_dir_all(&folder).map_err(|e| DatasetError::io(&folder, e))?;
                for img in images {
                    let path = dir.join(&img.path);
                    std::fs::write(&path, img.bytes).map_err(|e| DatasetError::io(&path, e))?;
                }
                progress.inc();
                Ok(record)
            })
            .collect::<Result<Vec<_>, DatasetError>>()
    })?;
    progress.finish();
    let samples_s = clock.elapsed().as_secs_f64();
    let (counts, files) = finish(
        dir,
        Manifest {
            format: Manifest::FORMAT.into(),
            version: Manifest::VERSION,
            generated_by: format!("fogline-dataset {}", env!("CARGO_PKG_VERSION")),
            source: "world".into(),
            seed: params.seed,
            samples: params.samples,
            clips_per_town: params.clips_per_town,
            split_fractions: params.split_fractions,
            image_format: params.image.ext().into(),
            cameras,
            frame_times_s: FRAME_TIMES_S.to_vec(),
            horizon_s: HORIZON_S,
            counts: BTreeMap::new(),
        },
        &records,
    )?;
    Ok(Built {
        dir: dir.to_path_buf(),
        samples: params.samples,
        counts,
        threads,
        samples_s,
        elapsed_s: 0.0,
        files,
    })
}

/// Counts the records per split into `manifest` and writes the metadata and exports.
pub(crate) fn finish(
    dir: &Path,
    mut manifest: Manifest,
    records: &[SampleRecord],
) -> Result<(BTreeMap<String, SplitCounts>, Vec<String>), DatasetError> {
    let mut counts: BTreeMap<String, SplitCounts> = BTreeMap::new();
    let mut towns_in: BTreeMap<String, std::collections::BTreeSet<u64>> = BTreeMap::new();
    for r in records {
        for key in [r.split.name(), "all"] {
            counts.entry(key.into()).or_default().add(r);
            towns_in.entry(key.into()).or_default().insert(r.town);
        }
    }
    for (k, c) in counts.iter_mut() {
        c.towns = towns_in.get(k).map_or(0, |t| t.len() as u64);
    }
    manifest.samples = records.len() as u64;
    manifest.counts = counts.clone();
    let files = write_metadata(dir, &manifest, records)?;
    Ok((counts, files))
}

/// Writes `manifest.json`, `samples.jsonl` and the exports into `dir`; returns their
/// relative paths.
pub fn write_metadata(
    dir: &Path,
    manifest: &Manifest,
    records: &[SampleRecord],
) -> Result<Vec<String>, DatasetError> {
    let mut out: Vec<(String, Vec<u8>)> = Vec::new();
    out.push((MANIFEST_JSON.into(), crate::pretty_json(manifest)?));
    let mut lines = Vec::new();
    for r in records {
        let l = serde_json::to_vec(r).map_err(|e| DatasetError::Params(e.to_string()))?;
        lines.extend_from_slice(&l);
        lines.push(b'\n');
    }
    out.push((SAMPLES_JSONL.into(), lines));
    out.extend(export::exports(manifest, records)?);
    let mut names = Vec::new();
    for (rel, bytes) in out {
        let path = dir.join(&rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| DatasetError::io(parent, e))?;
        }
        std::fs::write(&path, bytes).map_err(|e| DatasetError::io(&path, e))?;
        names.push(rel);
    }
    Ok(names)
}
