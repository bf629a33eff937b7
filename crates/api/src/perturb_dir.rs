//! Perturbing a directory of frames (what `fogline perturb` runs): PNG/JPEG frames in, the
//! same tree perturbed out, with depth maps for Koschmieder fog, object boxes for deficit
//! masks, temporal faults per clip (a clip is a directory) and the manifest `perturb.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use fogline_io::{Progress, write_atomic};
use fogline_perturb::rng::name_id;
use fogline_perturb::{
    DeficitRegion, DepthMap, Frame, FrameInput, FrameKey, FrameSource, ObjectBox, Outline,
    PerturbError, Perturbation, Prepared, Step,
};
use image::ColorType;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Name of the manifest written last into the output directory.
pub const MANIFEST: &str = "perturb.json";

/// A directory job: what `fogline perturb` takes.
#[derive(Debug, Clone)]
pub struct PerturbDir {
    /// Directory of frames: PNG or JPEG, 8-bit RGB, searched recursively. Each directory is a
    /// clip; its frames are its image files in name order.
    pub input: PathBuf,
    /// Output directory (created if missing): the same relative paths and names, plus
    /// `perturb.json`.
    pub output: PathBuf,
    /// Condition (`noise_30`, `dark`, `fog_07`, `mask_class_pedestrian`, `drop_0.1`,
    /// `noise_30+fog_03`, …).
    pub condition: String,
    /// Seed of every random draw.
    pub seed: u64,
    /// Object boxes for deficit masks: JSON Lines, one box per line (`frame`, `class`,
    /// optional `track_id`, `x`, `y`, `width`, `height`; frame relative to `input`).
    pub boxes: Option<PathBuf>,
    /// Depth maps: a directory mirroring `input` with one 16-bit grey PNG per frame.
    pub depth: Option<PathBuf>,
    /// Metres per unit of the depth PNGs.
    pub depth_scale: f64,
    /// Outline of masked boxes: a colour `RRGGBB`, or `none`.
    pub outline: String,
    /// Outline width in pixels.
    pub outline_width: u32,
    /// Quality of JPEG outputs (JPEG inputs are written back as JPEG).
    pub jpeg_quality: u8,
}

impl Default for PerturbDir {
    fn default() -> Self {
        Self {
            input: PathBuf::new(),
            output: PathBuf::new(),
            condition: "clean".into(),
            seed: 0,
            boxes: None,
            depth: None,
            depth_scale: 0.001,
            outline: "ff0000".into(),
            outline_width: 2,
            jpeg_quality: 95,
        }
    }
}

/// What a finished directory job reports.
#[derive(Debug, Clone, Serialize)]
pub struct PerturbDirSummary {
    /// The output directory.
    pub output: PathBuf,
    /// Its manifest.
    pub manifest: PathBuf,
    /// Frames written.
    pub n_frames: usize,
    /// The condition's name.
    pub condition: String,
    /// Its family, for a single step of the paper's grid.
    pub family: Option<String>,
    /// Its level, for a single step of the paper's grid.
    pub level: Option<f64>,
    /// The seed.
    pub seed: u64,
}

/// An image file under the input directory.
#[derive(Clone)]
struct Input {
    /// Path relative to the input directory, `/`-separated.
    rel: String,
    path: PathBuf,
}

/// What one output frame is made of.
struct Task {
    out: Input,
    clip: u64,
    source: FrameSource,
    /// The clip's files, to resolve `source`.
    clip_files: std::sync::Arc<Vec<Input>>,
}

/// `perturb.json`: what a directory job made, written last into the output directory (its
/// presence means the run completed). One typed definition for its writer and readers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// [`Manifest::SCHEMA_VERSION`].
    pub schema_version: u32,
    /// [`Manifest::KIND`].
    pub kind: String,
    /// The producing tool and version.
    pub generated_by: String,
    /// The condition's name.
    pub condition: String,
    /// Its family, for a single step of the paper's grid.
    pub family: Option<String>,
    /// Its level, for a single step of the paper's grid.
    pub level: Option<f64>,
    /// Its steps with every parameter.
    pub steps: Vec<Step>,
    /// The seed.
    pub seed: u64,
    /// The input directory.
    pub input: PathBuf,
    /// The output directory.
    pub output: PathBuf,
    /// The depth directory, if any.
    pub depth: Option<PathBuf>,
    /// The boxes file, if any.
    pub boxes: Option<PathBuf>,
    /// Frames written.
    pub n_frames: usize,
    /// One record per frame written.
    pub frames: Vec<FrameRecord>,
}

impl Manifest {
    /// The schema version written and read.
    pub const SCHEMA_VERSION: u32 = 1;
    /// The `kind` of a `perturb.json`.
    pub const KIND: &'static str = "fogline.perturb";

    /// Reads a `perturb.json`, checking its kind and version; errors name the file.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let m: Manifest = serde_json::from_str(&text)
            .with_context(|| format!("{} is not a perturb.json manifest", path.display()))?;
        if m.kind != Self::KIND || m.schema_version != Self::SCHEMA_VERSION {
            bail!(
                "{}: kind {:?} version {} (expected {:?} version {})",
                path.display(),
                m.kind,
                m.schema_version,
                Self::KIND,
                Self::SCHEMA_VERSION
            );
        }
        Ok(m)
    }
}

/// One frame of the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// Output path, relative to the output directory.
    pub path: String,
    /// The captured frame delivered here (`null`: a black frame).
    pub source: Option<String>,
    /// The regions hidden by deficit steps.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub deficits: Vec<DeficitRegion>,
}

#[derive(Deserialize)]
struct BoxRow {
    frame: String,
    class: String,
    #[serde(default)]
    track_id: Option<u64>,
    x: f64,
    y: f64,
    width: f64,
    height: f64,
}

/// Boxes per frame (relative path), each with its line in the boxes file.
type Boxes = BTreeMap<String, Vec<(usize, ObjectBox)>>;

struct Job<'a> {
    prepared: &'a Prepared,
    output_dir: &'a Path,
    depth_dir: Option<&'a Path>,
    depth_scale: f64,
    boxes: Option<(&'a Path, &'a Boxes)>,
    jpeg_quality: u8,
}

/// Perturbs every frame under `job.input` into `job.output` (all cores, a progress bar on
/// stderr) and writes the manifest `perturb.json` last, so its presence means the run
/// completed.
pub fn run(job: &PerturbDir) -> Result<PerturbDirSummary> {
    let a = job;
    let t0 = Instant::now();
    let mut perturbation = Perturbation::parse(&a.condition)
        .with_context(|| format!("--condition {:?}", a.condition))?;
    let outline = parse_outline(&a.outline, a.outline_width)?;
    for s in &mut perturbation.steps {
        if let Step::DeficitMask(d) = s {
            d.outline = outline;
        }
    }
    let prepared = perturbation
        .prepare(a.seed)
        .context("invalid condition parameters")?;
    if !(1..=100).contains(&a.jpeg_quality) {
        bail!("--jpeg-quality must be in [1, 100]");
    }
    if !(a.depth_scale.is_finite() && a.depth_scale > 0.0) {
        bail!("--depth-scale must be a positive number of metres per unit");
    }
    if perturbation.needs_depth() && a.depth.is_none() {
        bail!(
            "condition {:?} needs depth maps: give --depth DIR",
            perturbation.name
        );
    }
    if perturbation.uses_boxes() && a.boxes.is_none() {
        bail!(
            "condition {:?} masks objects: give --boxes FILE",
            perturbation.name
        );
    }
    if !a.input.is_dir() {
        bail!("--input {} is not a directory", a.input.display());
    }
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("cannot create {}", a.output.display()))?;
    let input_dir = a.input.canonicalize()?;
    let output_dir = a.output.canonicalize()?;
    if output_dir.starts_with(&input_dir) {
        bail!(
            "--output {} is inside --input {}: choose a directory outside it",
            a.output.display(),
            a.input.display()
        );
    }
    // A manifest from an earlier run would claim that this one completed.
    let manifest = a.output.join(MANIFEST);
    if manifest.exists() {
        std::fs::remove_file(&manifest)
            .with_context(|| format!("cannot remove the old {}", manifest.display()))?;
    }

    let files = find_images(&a.input)?;
    if files.is_empty() {
        bail!("no PNG or JPEG files under {}", a.input.display());
    }
    let boxes = match &a.boxes {
        Some(p) => {
            let b = read_boxes(p)?;
            let unknown = b
                .keys()
                .filter(|k| !files.iter().any(|f| &f.rel == *k))
                .count();
            if unknown > 0 {
                log::warn!(
                    "{} frames named in {} are not under {}",
                    unknown,
                    p.display(),
                    a.input.display()
                );
            }
            if !perturbation.uses_boxes() {
                log::warn!("--boxes is unused: {:?} masks nothing", perturbation.name);
            }
            Some(b)
        }
        None => None,
    };

    // Clips: the files of each directory, in name order.
    let mut clips: BTreeMap<String, Vec<Input>> = BTreeMap::new();
    for f in files {
        let dir = f.rel.rsplit_once('/').map_or("", |(d, _)| d).to_string();
        clips.entry(dir).or_default().push(f);
    }
    let mut tasks = Vec::new();
    for (dir, list) in clips {
        let clip = name_id(&dir);
        let plan = prepared.plan_clip(clip, 0, list.len());
        let list = std::sync::Arc::new(list);
        for (i, source) in plan.into_iter().enumerate() {
            tasks.push(Task {
                out: list[i].clone(),
                clip,
                source,
                clip_files: list.clone(),
            });
        }
    }
    log::info!(
        "perturb: {} frames, condition {}, seed {}, {} threads",
        tasks.len(),
        perturbation.name,
        a.seed,
        rayon::current_num_threads()
    );
    let work = Job {
        prepared: &prepared,
        output_dir: &a.output,
        depth_dir: a.depth.as_deref(),
        depth_scale: a.depth_scale,
        boxes: a.boxes.as_deref().zip(boxes.as_ref()),
        jpeg_quality: a.jpeg_quality,
    };
    let progress = Progress::new(tasks.len(), "frames");
    let records: Vec<FrameRecord> = tasks
        .par_iter()
        .map(|t| {
            let r = process(&work, t);
            progress.inc();
            r
        })
        .collect::<Result<_>>()?;
    progress.finish();

    let cond = perturbation.condition();
    let summary = Manifest {
        schema_version: Manifest::SCHEMA_VERSION,
        kind: Manifest::KIND.into(),
        generated_by: format!("fogline {}", env!("CARGO_PKG_VERSION")),
        condition: perturbation.name.clone(),
        family: cond.as_ref().map(|c| c.family.name().to_string()),
        level: cond.as_ref().map(|c| c.level),
        steps: perturbation.steps.clone(),
        seed: a.seed,
        input: a.input.clone(),
        output: a.output.clone(),
        depth: a.depth.clone(),
        boxes: a.boxes.clone(),
        n_frames: records.len(),
        frames: records,
    };
    write_atomic(&manifest, &serde_json::to_vec_pretty(&summary)?)?;
    log::info!(
        "wrote {} frames in {:.2} s",
        summary.n_frames,
        t0.elapsed().as_secs_f64()
    );
    Ok(PerturbDirSummary {
        output: a.output.clone(),
        manifest,
        n_frames: summary.n_frames,
        condition: perturbation.name.clone(),
        family: cond.as_ref().map(|c| c.family.name().to_string()),
        level: cond.as_ref().map(|c| c.level),
        seed: a.seed,
    })
}

fn parse_outline(s: &str, width_px: u32) -> Result<Option<Outline>> {
    if s == "none" {
        return Ok(None);
    }
    let hex = s.trim_start_matches('#');
    let bad = || anyhow!("--outline: expected RRGGBB (e.g. ff0000) or none, got {s:?}");
    if hex.len() != 6 {
        return Err(bad());
    }
    let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| bad());
    if width_px == 0 {
        bail!("--outline-width must be at least 1 (use --outline none for no outline)");
    }
    Ok(Some(Outline {
        rgb: [byte(0)?, byte(2)?, byte(4)?],
        width_px,
    }))
}

/// Image files under `root`, sorted by relative path; hidden entries are skipped.
fn find_images(root: &Path) -> Result<Vec<Input>> {
    fn walk(dir: &Path, rel: &str, out: &mut Vec<Input>) -> Result<()> {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .with_context(|| format!("cannot list {}", dir.display()))?
            .collect::<std::io::Result<_>>()
            .with_context(|| format!("cannot list {}", dir.display()))?;
        entries.sort_by_key(|e| e.file_name());
        for e in entries {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') {
                continue;
            }
            let path = e.path();
            let r = if rel.is_empty() {
                name.clone()
            } else {
                format!("{rel}/{name}")
            };
            if path.is_dir() {
                walk(&path, &r, out)?;
            } else if image_format(&path).is_some() {
                out.push(Input { rel: r, path });
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(root, "", &mut out)?;
    Ok(out)
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Png,
    Jpeg,
}

fn image_format(p: &Path) -> Option<Format> {
    let ext = p.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "png" => Some(Format::Png),
        "jpg" | "jpeg" => Some(Format::Jpeg),
        _ => None,
    }
}

fn read_boxes(path: &Path) -> Result<Boxes> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut out = Boxes::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let row: BoxRow = serde_json::from_str(line).with_context(|| {
            format!(
                "{}:{}: expected a JSON object with frame, class, x, y, width, height \
                 (and optionally track_id)",
                path.display(),
                i + 1
            )
        })?;
        let frame = row
            .frame
            .replace('\\', "/")
            .trim_start_matches("./")
            .to_string();
        out.entry(frame).or_default().push((
            i + 1,
            ObjectBox {
                class: row.class,
                track_id: row.track_id,
                x_px: row.x,
                y_px: row.y,
                width_px: row.width,
                height_px: row.height,
            },
        ));
    }
    Ok(out)
}

/// Decodes an 8-bit RGB PNG or JPEG; anything else is an error naming the file.
fn read_rgb(path: &Path) -> Result<Frame> {
    let img = image::ImageReader::open(path)
        .with_context(|| format!("cannot open {}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("cannot read {}", path.display()))?
        .decode()
        .with_context(|| format!("cannot decode {} (truncated or corrupt?)", path.display()))?;
    let (w, h) = (img.width(), img.height());
    match img.color() {
        ColorType::Rgb8 => {}
        other => bail!(
            "{}: {} image; expected 8-bit RGB",
            path.display(),
            describe(other)
        ),
    }
    Frame::new(w, h, img.into_rgb8().into_raw()).with_context(|| format!("{}", path.display()))
}

fn describe(c: ColorType) -> &'static str {
    match c {
        ColorType::L8 => "an 8-bit grey",
        ColorType::La8 => "an 8-bit grey + alpha",
        ColorType::Rgba8 => "an 8-bit RGBA (alpha channel)",
        ColorType::L16 => "a 16-bit grey",
        ColorType::La16 => "a 16-bit grey + alpha",
        ColorType::Rgb16 => "a 16-bit RGB",
        ColorType::Rgba16 => "a 16-bit RGBA",
        ColorType::Rgb32F | ColorType::Rgba32F => "a floating-point",
        _ => "an unsupported",
    }
}

/// A 16-bit grey PNG depth map in `scale` metres per unit (0 = sky).
fn read_depth(path: &Path, scale: f64) -> Result<DepthMap> {
    let img = image::ImageReader::open(path)
        .with_context(|| format!("cannot open the depth map {}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("cannot read {}", path.display()))?
        .decode()
        .with_context(|| format!("cannot decode the depth map {}", path.display()))?;
    if img.color() != ColorType::L16 {
        bail!(
            "{}: {} image; a depth map is a 16-bit grey PNG",
            path.display(),
            describe(img.color())
        );
    }
    let (w, h) = (img.width(), img.height());
    let d = img
        .into_luma16()
        .into_raw()
        .into_iter()
        .map(|v| {
            if v == 0 {
                f32::INFINITY
            } else {
                (f64::from(v) * scale) as f32
            }
        })
        .collect();
    DepthMap::new(w, h, d).with_context(|| format!("{}", path.display()))
}

fn encode(frame: &Frame, format: Format, jpeg_quality: u8) -> Result<Vec<u8>> {
    let format = match format {
        Format::Png => fogline_io::ImageFormat::Png,
        Format::Jpeg => fogline_io::ImageFormat::Jpeg {
            quality: jpeg_quality,
        },
    };
    fogline_io::encode(frame.data(), frame.width(), frame.height(), format).map_err(|e| anyhow!(e))
}

fn process(job: &Job<'_>, t: &Task) -> Result<FrameRecord> {
    let out_path = job.output_dir.join(&t.out.rel);
    let format = image_format(&t.out.path).unwrap_or(Format::Png);
    let (frame, source, deficits) = match t.source {
        FrameSource::Black => {
            let (w, h) = image::image_dimensions(&t.out.path)
                .with_context(|| format!("cannot read {}", t.out.path.display()))?;
            let black = Frame::filled(w, h, [0, 0, 0])
                .with_context(|| format!("{}", t.out.path.display()))?;
            (black, None, Vec::new())
        }
        FrameSource::Captured(j) => {
            let src = &t.clip_files[j];
            let frame = read_rgb(&src.path)?;
            let depth = match job.depth_dir {
                Some(dir) => {
                    let p = dir.join(&src.rel).with_extension("png");
                    let d = read_depth(&p, job.depth_scale)?;
                    d.check_size(&frame).with_context(|| {
                        format!(
                            "depth map {} does not fit frame {}",
                            p.display(),
                            src.path.display()
                        )
                    })?;
                    Some(d)
                }
                None => None,
            };
            let (boxes, lines): (Vec<ObjectBox>, Vec<usize>) = job
                .boxes
                .and_then(|(_, b)| b.get(&src.rel))
                .map(|v| v.iter().map(|(l, b)| (b.clone(), *l)).unzip())
                .unwrap_or_default();
            let input = FrameInput {
                frame: frame.view(),
                key: FrameKey::new(t.clip, 0, name_id(&src.rel)),
                depth: depth.as_ref(),
                boxes: &boxes,
            };
            let applied = job.prepared.apply(&input).map_err(|e| {
                let what = match (&e, job.boxes) {
                    (
                        PerturbError::BoxOutside { index, .. }
                        | PerturbError::BoxSize { index, .. },
                        Some((file, _)),
                    ) => format!(
                        "{}:{} (boxes of frame {})",
                        file.display(),
                        lines[*index],
                        src.path.display()
                    ),
                    _ => format!("frame {}", src.path.display()),
                };
                anyhow::Error::new(e).context(what)
            })?;
            (applied.frame, Some(src.rel.clone()), applied.deficits)
        }
    };
    let bytes = encode(&frame, format, job.jpeg_quality)
        .with_context(|| format!("cannot encode {}", out_path.display()))?;
    if let Some(parent) = out_path.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    write_atomic(&out_path, &bytes)?;
    Ok(FrameRecord {
        path: t.out.rel.clone(),
        source,
        deficits,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_directory_job_writes_frames_and_a_manifest_that_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in");
        std::fs::create_dir_all(input.join("clip")).unwrap();
        for k in 0..3u8 {
            let rgb: Vec<u8> = (0..(16 * 12 * 3))
                .map(|i| (i as u8).wrapping_mul(k + 1))
                .collect();
            let png = fogline_io::encode(&rgb, 16, 12, fogline_io::ImageFormat::Png).unwrap();
            std::fs::write(input.join(format!("clip/{k:04}.png")), png).unwrap();
        }
        let job = PerturbDir {
            input: input.clone(),
            output: dir.path().join("out"),
            condition: "noise_30+drop_0.5".into(),
            seed: 3,
            ..PerturbDir::default()
        };
        let s = run(&job).unwrap();
        assert_eq!((s.n_frames, s.condition.as_str()), (3, "noise_30+drop_0.5"));
        let m = Manifest::read(&s.manifest).unwrap();
        assert_eq!(m.n_frames, 3);
        assert_eq!(m.frames.len(), 3);
        assert_eq!(m.frames[0].path, "clip/0000.png");
        assert_eq!(m.steps.len(), 2);
        for f in &m.frames {
            assert!(job.output.join(&f.path).is_file());
        }
        // Bad jobs fail with a clear error and write no manifest.
        let bad = PerturbDir {
            output: dir.path().join("out2"),
            condition: "nois_30".into(),
            ..job.clone()
        };
        let e = run(&bad).unwrap_err().to_string();
        assert!(e.contains("nois_30"), "{e}");
        assert!(!dir.path().join("out2").join(MANIFEST).exists());
        assert!(Manifest::read(&input.join("clip/0000.png")).is_err());
    }
}
