//! `fogline perturb` (a directory of frames in, the perturbed directory out) and
//! `fogline bench perturb` (per-family cost on a synthetic frame, optionally next to the Python
//! peers).

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use clap::{Args, Subcommand};
use fogline_perturb::rng::{WyRand, name_id};
use fogline_perturb::{
    DeficitRegion, DepthMap, Frame, FrameInput, FrameKey, FrameSource, ObjectBox, Outline,
    PerturbError, Perturbation, Prepared, Step,
};
use image::ColorType;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::write_atomic;
use fogline_io::Progress;

/// Name of the manifest written last into the output directory.
const MANIFEST: &str = "perturb.json";

#[derive(Args)]
pub struct PerturbArgs {
    /// Directory of frames: PNG or JPEG, 8-bit RGB, searched recursively. Each directory is a
    /// clip; its frames are its image files in name order.
    #[arg(long)]
    input: PathBuf,
    /// Output directory (created if missing): the same relative paths and names, plus
    /// perturb.json (written last, so its presence means the run completed).
    #[arg(long)]
    output: PathBuf,
    /// Condition: noise_30, dark, bright, fog_07, jpeg_20, mask_class_pedestrian,
    /// drop_0.1, noise_30+fog_03, … (see docs/perturb.md).
    #[arg(long)]
    condition: String,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Object boxes for deficit masks: JSON Lines, one box per line:
    /// {"frame": "clip/0001.png", "class": "car", "track_id": 3, "x": 10, "y": 20,
    /// "width": 40, "height": 30} (pixels, origin top-left; frame relative to --input).
    #[arg(long)]
    boxes: Option<PathBuf>,
    /// Depth maps for Koschmieder fog: a directory mirroring --input with one 16-bit grey PNG
    /// per frame (same relative path, extension .png); 0 means no return (sky).
    #[arg(long)]
    depth: Option<PathBuf>,
    /// Metres per unit of the depth PNGs.
    #[arg(long, default_value_t = 0.001)]
    depth_scale: f64,
    /// Outline of masked boxes: a colour RRGGBB, or `none`.
    #[arg(long, default_value = "ff0000")]
    outline: String,
    /// Outline width in pixels.
    #[arg(long, default_value_t = 2)]
    outline_width: u32,
    /// Quality of JPEG outputs (JPEG inputs are written back as JPEG).
    #[arg(long, default_value_t = 95)]
    jpeg_quality: u8,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    what: BenchCommand,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Per-family ms/frame of the perturbation engine on a synthetic frame, one thread, next to
    /// the memory floor (and, with --peers, next to the Python libraries).
    #[command(
        after_help = "Examples:\n  fogline bench perturb\n  fogline bench perturb --width 640 --height 360 --runs 3 --json\n  scripts/perturb-peers.sh    # installs the Python peers, then runs --peers"
    )]
    Perturb(BenchPerturbArgs),
    /// Generating + rendering clips in memory on every core (s, clips/s, ms/clip), then the
    /// reference planner's time per clip on one thread (median, p95), next to their goals.
    #[command(
        after_help = "Examples:\n  fogline bench world                    # 1,996 clips at 576x320\n  fogline bench world --clips 200 --json"
    )]
    World(crate::planner_cmd::BenchWorldArgs),
    /// The paper-size campaign with the built-in planner (s, runs/s), and the runner's
    /// overhead per remote call (egodriver gRPC and HTTP on loopback, PNG and JPEG).
    #[command(
        after_help = "Examples:\n  fogline bench campaign                  # 1,996 clips × 9 conditions, then 200 calls per path\n  fogline bench campaign --clips 0 --calls 500"
    )]
    Campaign(crate::bench_campaign::BenchCampaignArgs),
}

#[derive(Args)]
struct BenchPerturbArgs {
    /// Frame width in pixels.
    #[arg(long, default_value_t = 1920)]
    width: u32,
    /// Frame height in pixels.
    #[arg(long, default_value_t = 1080)]
    height: u32,
    /// Timed runs per family (the median is reported), after one warm-up.
    #[arg(long, default_value_t = 9)]
    runs: usize,
    /// Only conditions whose name contains this.
    #[arg(long)]
    filter: Option<String>,
    /// Also time the Python peers (numpy, OpenCV, albumentations, imagecorruptions) on the same
    /// frame and print every ratio.
    #[arg(long)]
    peers: bool,
    /// Python interpreter for --peers (default: $FOGLINE_PYTHON, else
    /// target/perturb-peers-venv/bin/python when it exists, else python3).
    #[arg(long)]
    python: Option<PathBuf>,
    /// The peers script (default: scripts/perturb_peers.py of this source tree).
    #[arg(long)]
    peers_script: Option<PathBuf>,
    /// Print the results as JSON on stdout.
    #[arg(long)]
    json: bool,
}

// ---------------------------------------------------------------------------------------------
// fogline perturb
// ---------------------------------------------------------------------------------------------

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

/// One line of the manifest.
#[derive(Serialize)]
struct FrameRecord {
    path: String,
    /// The captured frame delivered here (`null`: a black frame).
    source: Option<String>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    deficits: Vec<DeficitRegion>,
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

pub fn perturb(a: PerturbArgs) -> Result<ExitCode> {
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
    let job = Job {
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
            let r = process(&job, t);
            progress.inc();
            r
        })
        .collect::<Result<_>>()?;
    progress.finish();

    let cond = perturbation.condition();
    let summary = serde_json::json!({
        "schema_version": 1,
        "kind": "fogline.perturb",
        "generated_by": format!("fogline {}", env!("CARGO_PKG_VERSION")),
        "condition": perturbation.name,
        "family": cond.as_ref().map(|c| c.family.name().to_string()),
        "level": cond.as_ref().map(|c| c.level),
        "steps": perturbation.steps,
        "seed": a.seed,
        "input": a.input,
        "output": a.output,
        "depth": a.depth,
        "boxes": a.boxes,
        "n_frames": records.len(),
        "frames": records,
    });
    write_atomic(&manifest, &serde_json::to_vec_pretty(&summary)?)?;
    log::info!(
        "wrote {} frames in {:.2} s",
        records.len(),
        t0.elapsed().as_secs_f64()
    );
    let mut out = std::io::stdout().lock();
    if a.json {
        let v = serde_json::json!({
            "output": a.output,
            "manifest": manifest,
            "n_frames": records.len(),
            "condition": perturbation.name,
            "family": cond.as_ref().map(|c| c.family.name().to_string()),
            "level": cond.as_ref().map(|c| c.level),
            "seed": a.seed,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(
            out,
            "{} frames perturbed with {} (seed {}) into {}",
            records.len(),
            perturbation.name,
            a.seed,
            a.output.display()
        )?;
        writeln!(out, "{}", manifest.display())?;
    }
    Ok(ExitCode::SUCCESS)
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

// ---------------------------------------------------------------------------------------------
// fogline bench perturb
// ---------------------------------------------------------------------------------------------

pub fn bench(a: BenchArgs) -> Result<ExitCode> {
    match a.what {
        BenchCommand::Perturb(p) => bench_perturb(p),
        BenchCommand::World(w) => crate::planner_cmd::bench_world(w),
        BenchCommand::Campaign(c) => crate::bench_campaign::bench_campaign(c),
    }
}

/// The conditions timed, with `@depth` (Koschmieder, with the synthetic depth map) and
/// `@boxes` (the 10 synthetic boxes) marking what they are given.
const BENCH_CONDITIONS: [&str; 30] = [
    "noise_10",
    "noise_30",
    "noise_50",
    "noise_70",
    "dark",
    "bright",
    "fog_03",
    "fog_07",
    "fog_07@depth",
    "visibility_150@depth",
    "shot_4",
    "impulse_0.03",
    "contrast_0.4",
    "saturation_0.2",
    "quantize_3",
    "glare_0.8",
    "defocus_3",
    "motion_15",
    "pixelate_8",
    "jpeg_25",
    "dead_0.001",
    "dirt_5",
    "mask_all@boxes",
    "noise_30+fog_03",
    "noise_20.4",
    "noise_30.6",
    "noise_66.3",
    "shot_4.25",
    "dark+noise_10+jpeg_25",
    "clean",
];

struct Bench {
    frame: Frame,
    depth: DepthMap,
    boxes: Vec<ObjectBox>,
    out: Frame,
    flush: Vec<u8>,
    runs: usize,
}

impl Bench {
    /// Evicts the caches: one write per 64-byte line of a 64 MiB buffer.
    fn flush(&mut self) {
        for (i, b) in self.flush.iter_mut().enumerate().step_by(64) {
            *b = b.wrapping_add(i as u8);
        }
        std::hint::black_box(&self.flush);
    }

    /// Median and minimum ms of `runs` timed calls after one warm-up, caches flushed before
    /// each.
    fn time(&mut self, mut f: impl FnMut(&mut Self) -> Result<()>) -> Result<Timing> {
        f(self)?;
        let mut ms = Vec::with_capacity(self.runs);
        for _ in 0..self.runs {
            self.flush();
            let t = Instant::now();
            f(self)?;
            ms.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(&self.out);
        }
        ms.sort_by(f64::total_cmp);
        Ok(Timing {
            median_ms: ms[ms.len() / 2],
            min_ms: ms[0],
        })
    }

    fn copy(&mut self) -> Result<Timing> {
        self.time(|b| {
            b.out.clone_from(&b.frame);
            Ok(())
        })
    }

    fn condition(&mut self, spec: &str) -> Result<(Timing, Prepared)> {
        let (name, extra) = spec.split_once('@').unwrap_or((spec, ""));
        let p = Perturbation::parse(name)?.prepare(0)?;
        let ms = self.time(|b| {
            let input = FrameInput {
                frame: b.frame.view(),
                key: FrameKey::new(1, 0, 0),
                depth: (extra == "depth").then_some(&b.depth),
                boxes: if extra == "boxes" { &b.boxes } else { &[] },
            };
            p.apply_into(&input, &mut b.out)?;
            Ok(())
        })?;
        Ok((ms, p))
    }
}

/// The synthetic scene: sky above the horizon (depth +inf), a textured ground plane below
/// (depth `1.5 m · H / (y − H/2 + ½)`), coloured boxes standing in for cars.
fn synthetic(w: u32, h: u32) -> Result<(Frame, DepthMap, Vec<ObjectBox>)> {
    let mut rng = WyRand::new(0);
    let mut data = Vec::with_capacity((w * h * 3) as usize);
    let mut depth = Vec::with_capacity((w * h) as usize);
    let horizon = h / 2;
    for y in 0..h {
        for x in 0..w {
            let r = rng.next_u64();
            let tex = (r & 31) as u32;
            let px = if y < horizon {
                let t = 120 * y / horizon.max(1);
                [
                    (90 + t / 2 + tex / 4) as u8,
                    (130 + t / 2) as u8,
                    (200 + tex / 8) as u8,
                ]
            } else {
                let lane = (x * 16 / w).is_multiple_of(4) && ((y - horizon) / 8).is_multiple_of(2);
                let g = if lane { 220 } else { 70 + tex * 3 };
                [g as u8, g as u8, (g + 5).min(255) as u8]
            };
            data.extend_from_slice(&px);
            depth.push(if y < horizon {
                f32::INFINITY
            } else {
                1.5 * h as f32 / ((y - horizon) as f32 + 0.5)
            });
        }
    }
    let mut frame = Frame::new(w, h, data)?;
    let boxes: Vec<ObjectBox> = (0..10u32)
        .map(|i| ObjectBox {
            class: if i % 3 == 0 { "pedestrian" } else { "car" }.into(),
            track_id: Some(u64::from(i)),
            x_px: f64::from(w * (5 + 8 * i) / 100),
            y_px: f64::from(h * 46 / 100),
            width_px: f64::from((w * 4 / 100).max(1)),
            height_px: f64::from((h * 11 / 100).max(1)),
        })
        .collect();
    // Paint the objects so that masking has something to hide.
    let stride = w as usize * 3;
    for (i, b) in boxes.iter().enumerate() {
        let r = b.pixel_rect();
        let colour = [[200, 30, 30], [30, 30, 200], [230, 230, 230]][i % 3];
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let o = y as usize * stride + x as usize * 3;
                frame.data_mut()[o..o + 3].copy_from_slice(&colour);
            }
        }
    }
    Ok((frame, DepthMap::new(w, h, depth)?, boxes))
}

/// Median and minimum of a benchmark's runs.
#[derive(Clone, Copy)]
struct Timing {
    median_ms: f64,
    min_ms: f64,
}

#[derive(Serialize)]
struct BenchRow {
    condition: String,
    family: String,
    /// Median ms/frame.
    ms: f64,
    min_ms: f64,
    vs_copy: f64,
}

#[derive(Serialize, Deserialize)]
struct PeerRow {
    op: String,
    peer: String,
    fogline: String,
    ms: f64,
    #[serde(default)]
    min_ms: f64,
    runs: usize,
    #[serde(default)]
    note: String,
}

#[derive(Serialize, Deserialize)]
struct PeerSkip {
    peer: String,
    why: String,
}

#[derive(Deserialize)]
struct PeerReport {
    python: String,
    versions: BTreeMap<String, String>,
    results: Vec<PeerRow>,
    skipped: Vec<PeerSkip>,
}

/// The source tree this binary was built from (for the peers script and its venv).
fn repo_root() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    p.canonicalize().unwrap_or(p)
}

fn bench_perturb(a: BenchPerturbArgs) -> Result<ExitCode> {
    if a.width < 16 || a.height < 16 || a.width > 16_384 || a.height > 16_384 {
        bail!("--width and --height must be in [16, 16384]");
    }
    if a.runs == 0 {
        bail!("--runs must be at least 1");
    }
    let (frame, depth, boxes) = synthetic(a.width, a.height)?;
    let mut b = Bench {
        out: frame.clone(),
        frame,
        depth,
        boxes,
        flush: vec![0u8; 64 << 20],
        runs: a.runs,
    };
    let mb = f64::from(a.width) * f64::from(a.height) * 3.0 / 1e6;
    log::info!(
        "bench perturb: {}×{} RGB ({mb:.1} MB), one thread, median of {} runs, caches flushed before each",
        a.width,
        a.height,
        a.runs
    );
    // Let the clock and the caches settle before the first measurement (the first family
    // timed would otherwise pay for it): ~0.3 s of the kind of work measured.
    let settle = Instant::now();
    let warm = Perturbation::parse("noise_30")?.prepare(0)?;
    while settle.elapsed() < Duration::from_millis(300) {
        warm.apply_into(&FrameInput::new(&b.frame, FrameKey::default()), &mut b.out)?;
        b.flush();
    }
    let copy = b.copy()?;
    let copy_ms = copy.median_ms;
    let mut rows: Vec<BenchRow> = Vec::new();
    let mut measured: BTreeMap<String, f64> = BTreeMap::new();
    measured.insert("copy".into(), copy_ms);
    for spec in BENCH_CONDITIONS {
        if a.filter.as_deref().is_some_and(|f| !spec.contains(f)) {
            continue;
        }
        let (t, p) = b.condition(spec)?;
        log::debug!("{spec}: {:.3} ms", t.median_ms);
        rows.push(BenchRow {
            condition: spec.to_string(),
            family: family_of(p.perturbation()),
            ms: t.median_ms,
            min_ms: t.min_ms,
            vs_copy: t.median_ms / copy_ms,
        });
        measured.insert(spec.to_string(), t.median_ms);
    }

    let peers = if a.peers {
        let report = run_peers(&a, &b)?;
        // Time any fogline condition a peer compares with that the list above lacks.
        for r in &report.results {
            if !measured.contains_key(&r.fogline) {
                let (t, _) = b.condition(&r.fogline)?;
                measured.insert(r.fogline.clone(), t.median_ms);
            }
        }
        Some(report)
    } else {
        None
    };

    let get = |name: &str| measured.get(name).copied();
    let max_of = |names: &[&str]| {
        names
            .iter()
            .filter_map(|n| get(n))
            .fold(None, |acc: Option<f64>, v| {
                Some(acc.map_or(v, |a| a.max(v)))
            })
    };
    // The millisecond goals are for 1080p frames.
    let full_hd = (a.width, a.height) == (1920, 1080);
    let noise_ms = max_of(&["noise_10", "noise_30", "noise_50", "noise_70"]).filter(|_| full_hd);
    let lut_ms = max_of(&["dark", "bright", "fog_03", "fog_07"]);
    let depth_ms = get("fog_07@depth").filter(|_| full_hd);
    let ratio_min = |peer: &str| -> Option<f64> {
        peers.as_ref().and_then(|p| {
            p.results
                .iter()
                .filter(|r| r.peer.starts_with(peer) && r.fogline.starts_with("noise_"))
                .filter_map(|r| get(&r.fogline).map(|f| r.ms / f))
                .fold(None, |acc: Option<f64>, v| {
                    Some(acc.map_or(v, |a| a.min(v)))
                })
        })
    };
    let numpy_ratio = ratio_min("numpy default_rng");
    let albu_ratio = ratio_min("albumentations GaussNoise");
    let goals = [
        ("gaussian noise <= 3 ms/frame", noise_ms, 3.0, false, "ms"),
        (
            "gain and uniform fog <= 1.5x copy",
            lut_ms.map(|v| v / copy_ms),
            1.5,
            false,
            "x copy",
        ),
        ("depth fog <= 3 ms/frame", depth_ms, 3.0, false, "ms"),
        ("noise >= 25x numpy", numpy_ratio, 25.0, true, "x"),
        ("noise >= 13x albumentations", albu_ratio, 13.0, true, "x"),
    ];

    let mut out = std::io::stdout().lock();
    if a.json {
        let peer_rows: Vec<serde_json::Value> = peers
            .iter()
            .flat_map(|p| &p.results)
            .map(|r| {
                let f = get(&r.fogline);
                serde_json::json!({
                    "op": r.op, "peer": r.peer, "peer_ms": r.ms, "peer_min_ms": r.min_ms,
                    "peer_runs": r.runs,
                    "fogline": r.fogline, "fogline_ms": f, "ratio": f.map(|f| r.ms / f),
                    "note": r.note,
                })
            })
            .collect();
        let v = serde_json::json!({
            "width": a.width,
            "height": a.height,
            "runs": a.runs,
            "threads": 1,
            "caches": "flushed (64 MiB sweep) before every timed run",
            "gaussian_kernel": fogline_perturb::noise::GaussianTable::kernel_name(),
            "copy_ms": copy_ms,
            "copy_min_ms": copy.min_ms,
            "families": rows,
            "goals": goals.iter().map(|(name, v, target, at_least, _)| serde_json::json!({
                "goal": name, "value": v, "target": target,
                "met": v.map(|v| if *at_least { v >= *target } else { v <= *target }),
            })).collect::<Vec<_>>(),
            "peers": peers.as_ref().map(|p| serde_json::json!({
                "python": p.python, "versions": p.versions, "threads": 1,
                "results": peer_rows, "skipped": p.skipped,
            })),
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(
        out,
        "fogline bench perturb: {}x{} RGB frame ({mb:.1} MB), one thread, median of {} runs, caches flushed before each run; Gaussian-noise kernel: {}",
        a.width,
        a.height,
        a.runs,
        fogline_perturb::noise::GaussianTable::kernel_name()
    )?;
    writeln!(
        out,
        "{:<16} {:<24} {:>10} {:>8} {:>8}",
        "family", "condition", "ms/frame", "min", "x copy"
    )?;
    writeln!(
        out,
        "{:<16} {:<24} {:>10.3} {:>8.3} {:>8.2}",
        "copy floor", "(memcpy)", copy_ms, copy.min_ms, 1.0
    )?;
    for r in &rows {
        writeln!(
            out,
            "{:<16} {:<24} {:>10.3} {:>8.3} {:>8.2}",
            r.family, r.condition, r.ms, r.min_ms, r.vs_copy
        )?;
    }
    for (name, v, target, at_least, unit) in &goals {
        if let Some(v) = v {
            let met = if *at_least { v >= target } else { v <= target };
            writeln!(
                out,
                "goal  {name:<36} {v:>8.2} {unit:<7} {}",
                if met { "met" } else { "NOT met" }
            )?;
        }
    }
    if let Some(p) = &peers {
        let versions: Vec<String> = p.versions.iter().map(|(k, v)| format!("{k} {v}")).collect();
        writeln!(
            out,
            "peers: python {} ({}), one thread, same frame, median of up to {} runs",
            p.python,
            versions.join(", "),
            a.runs
        )?;
        writeln!(
            out,
            "{:<30} {:<48} {:>10} {:<22} {:>10} {:>9}",
            "operation", "peer", "peer ms", "fogline", "fogline ms", "ratio"
        )?;
        for r in &p.results {
            let f = get(&r.fogline);
            writeln!(
                out,
                "{:<30} {:<48} {:>10.2} {:<22} {:>10.3} {:>9}{}",
                r.op,
                r.peer,
                r.ms,
                r.fogline,
                f.unwrap_or(f64::NAN),
                f.map_or("-".into(), |f| format!("{:.1}x", r.ms / f)),
                if r.note.is_empty() {
                    String::new()
                } else {
                    format!("  ({})", r.note)
                }
            )?;
        }
        for s in &p.skipped {
            writeln!(out, "peer skipped: {}: {}", s.peer, s.why)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn family_of(p: &Perturbation) -> String {
    match p.steps.as_slice() {
        [] => "identity".into(),
        [s] => s.family().into(),
        _ => "composite".into(),
    }
}

/// Writes the frame, depth and boxes to a temporary directory, runs the peers script on them
/// and reads its JSON report.
fn run_peers(a: &BenchPerturbArgs, b: &Bench) -> Result<PeerReport> {
    let root = repo_root();
    let python = a
        .python
        .clone()
        .or_else(|| std::env::var_os("FOGLINE_PYTHON").map(PathBuf::from))
        .unwrap_or_else(|| {
            let venv = root.join("target/perturb-peers-venv/bin/python");
            if venv.exists() {
                venv
            } else {
                PathBuf::from("python3")
            }
        });
    let script = a
        .peers_script
        .clone()
        .unwrap_or_else(|| root.join("scripts/perturb_peers.py"));
    let dir = std::env::temp_dir().join(format!("fogline-bench-perturb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let result = (|| -> Result<PeerReport> {
        let frame_path = dir.join("frame.rgb");
        let depth_path = dir.join("depth.f32");
        let boxes_path = dir.join("boxes.json");
        std::fs::write(&frame_path, b.frame.data())?;
        let depth_bytes: Vec<u8> = b
            .depth
            .depth_m()
            .iter()
            .flat_map(|d| d.to_le_bytes())
            .collect();
        std::fs::write(&depth_path, depth_bytes)?;
        let boxes: Vec<[u32; 4]> = b
            .boxes
            .iter()
            .map(|o| {
                let r = o.pixel_rect();
                [r.x0, r.y0, r.x1 - r.x0, r.y1 - r.y0]
            })
            .collect();
        std::fs::write(&boxes_path, serde_json::to_vec(&boxes)?)?;
        log::info!(
            "running the Python peers: {} {}",
            python.display(),
            script.display()
        );
        let o = std::process::Command::new(&python)
            .arg(&script)
            .args(["--width", &a.width.to_string()])
            .args(["--height", &a.height.to_string()])
            .args(["--runs", &a.runs.to_string()])
            .arg("--frame")
            .arg(&frame_path)
            .arg("--depth")
            .arg(&depth_path)
            .arg("--boxes")
            .arg(&boxes_path)
            .env("OMP_NUM_THREADS", "1")
            .env("OPENBLAS_NUM_THREADS", "1")
            .env("MKL_NUM_THREADS", "1")
            .output()
            .with_context(|| {
                format!(
                    "cannot run {} (install the peers with scripts/perturb-peers.sh)",
                    python.display()
                )
            })?;
        if !o.status.success() {
            let err = String::from_utf8_lossy(&o.stderr);
            let tail: Vec<&str> = err.lines().rev().take(5).collect();
            bail!(
                "the peers script failed ({}): {}",
                o.status,
                tail.into_iter().rev().collect::<Vec<_>>().join("\n")
            );
        }
        serde_json::from_slice(&o.stdout).context("the peers script printed no JSON report")
    })();
    let _ = std::fs::remove_dir_all(&dir);
    result
}
