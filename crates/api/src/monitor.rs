//! The monitor's jobs on files.
//!
//! - Blind condition estimates of image files (what `fogline monitor estimate` runs): each
//!   PNG or JPEG is decoded to RGB8 and measured by `fogline_monitor::estimate_frame` —
//!   Gaussian noise σ, photometric gain and fog opacity, each with its standard error.
//! - The runtime ODD monitor over frames or clips ([`run_monitor`], what `fogline monitor
//!   run` runs): an `odd.json` and a scenario, then `fogline_monitor::Monitor::step_frame`
//!   per frame, one `MonitorRecord` per frame as a JSON line.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use fogline_monitor::{ConditionParams, Monitor, MonitorParams, MonitorRecord, estimate_frame};
use fogline_types::clip::CameraId;
use fogline_types::odd::OddSpec;
use serde::Serialize;

/// The estimates of one image.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageEstimate {
    /// The file, as given.
    pub path: String,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Gaussian noise σ, 0–255 scale (`noise_<σ>`).
    pub noise_sigma: f64,
    /// Standard error of `noise_sigma`.
    pub noise_sigma_se: f64,
    /// Photometric gain (1 = as the reference; `dark` 0.4, `bright` 1.6).
    pub gain: f64,
    /// Standard error of `gain`.
    pub gain_se: f64,
    /// Fog opacity α in [0, 1] (`fog_07`: 0.7).
    pub fog: f64,
    /// Standard error of `fog`.
    pub fog_se: f64,
    /// Share of the noise residuals left out because a pixel in them clipped.
    pub clipped_share: f64,
    /// Milliseconds the estimates took (decoding excluded), one thread.
    pub ms: f64,
}

/// Decodes and measures one image; the error names the file.
pub fn estimate_image(path: &Path, params: &ConditionParams) -> Result<ImageEstimate> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let img = fogline_io::image::decode_rgb(&bytes)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("{} is not a readable PNG or JPEG image", path.display()))?;
    let (w, h) = (img.width as usize, img.height as usize);
    let start = Instant::now();
    let e = estimate_frame(&img.rgb, w, h, params)
        .with_context(|| format!("cannot measure {}", path.display()))?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    Ok(ImageEstimate {
        path: path.display().to_string(),
        width: img.width,
        height: img.height,
        noise_sigma: e.noise.sigma,
        noise_sigma_se: e.noise.sigma_se,
        gain: e.condition.gain,
        gain_se: e.condition.gain_se,
        fog: e.condition.fog,
        fog_se: e.condition.fog_se,
        clipped_share: e.noise.clipped_share,
        ms,
    })
}

/// Measures every image in order (one thread, so `ms` is a one-thread figure); a file that
/// cannot be read or decoded gives its error in its place, the others are still measured.
pub fn estimate_images(paths: &[PathBuf], params: &ConditionParams) -> Vec<Result<ImageEstimate>> {
    paths.iter().map(|p| estimate_image(p, params)).collect()
}

/// Writes one result: a JSON object on one line with `json`, else a row of the table
/// (after [`write_header`]).
pub fn write_row(e: &ImageEstimate, json: bool, out: &mut dyn Write) -> Result<()> {
    if json {
        writeln!(out, "{}", serde_json::to_string(e)?)?;
    } else {
        writeln!(
            out,
            "{:>6.2} ±{:<5.2} {:>5.2} ±{:<5.2} {:>5.2} ±{:<5.2} {:>7.2}  {}",
            e.noise_sigma, e.noise_sigma_se, e.gain, e.gain_se, e.fog, e.fog_se, e.ms, e.path
        )?;
    }
    Ok(())
}

/// The table's header (nothing with `json`).
pub fn write_header(json: bool, out: &mut dyn Write) -> Result<()> {
    if !json {
        writeln!(
            out,
            "{:>6} {:6} {:>5} {:6} {:>5} {:6} {:>7}  path",
            "sigma", "±", "gain", "±", "fog", "±", "ms"
        )?;
    }
    Ok(())
}

/// What `fogline monitor run` takes.
#[derive(Debug, Clone)]
pub struct MonitorRun {
    /// PNG/JPEG images (one stream, in the order given), clip directories (one stream
    /// each: the camera's frames in order) or corpus directories (each clip in them).
    pub inputs: Vec<PathBuf>,
    /// The envelope's `odd.json`.
    pub odd: PathBuf,
    /// The scenario whose entry is used (images need it; a clip's own label otherwise).
    pub scenario: Option<String>,
    /// The camera of a clip that is monitored.
    pub camera: CameraId,
    /// The monitor's policy.
    pub params: MonitorParams,
}

/// What a monitor run did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct MonitorRunSummary {
    /// Streams monitored (the image stream counts as one; each clip as one).
    pub streams: usize,
    /// Frames stepped (records written).
    pub frames: usize,
    /// Records out of the envelope.
    pub frames_out: usize,
    /// Streams whose last record is out of the envelope.
    pub streams_out: usize,
    /// Streams that stopped on an error, each error with its cause chain (`{:#}`); the
    /// other streams still ran.
    pub errors: Vec<String>,
}

/// One stream: its frames and the scenario it is monitored under.
struct Stream {
    frames: Vec<PathBuf>,
    scenario: String,
}

/// Runs the monitor over `job.inputs`, writing one [`MonitorRecord`] per frame to `out` as a
/// JSON line (its `source` the frame's file). The `odd.json` and the options are checked
/// first (an error stops the run); a stream that fails (an unreadable frame, a clip without
/// the camera, a scenario without an entry) stops with its error in the summary and the
/// others still run.
pub fn run_monitor(job: &MonitorRun, out: &mut dyn Write) -> Result<MonitorRunSummary> {
    let odd = OddSpec::read(&job.odd).map_err(anyhow::Error::msg)?;
    job.params
        .validate()
        .context("invalid monitor parameters")?;
    if let Some(s) = &job.scenario {
        // Checked up front: a misspelt scenario is one error, not one per stream.
        Monitor::new(&odd, s, job.params.clone())
            .with_context(|| format!("{}: --scenario {s}", job.odd.display()))?;
    }
    let (images, dirs): (Vec<&PathBuf>, Vec<&PathBuf>) =
        job.inputs.iter().partition(|p| !p.is_dir());
    let mut summary = MonitorRunSummary::default();
    let mut streams: Vec<Result<Stream>> = Vec::new();
    if !images.is_empty() {
        streams.push(match &job.scenario {
            Some(s) => Ok(Stream {
                frames: images.into_iter().cloned().collect(),
                scenario: s.clone(),
            }),
            None => Err(anyhow::anyhow!(
                "images need --scenario (the entries of {}: {})",
                job.odd.display(),
                odd.entries
                    .iter()
                    .map(|e| e.scenario.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
        });
    }
    for dir in dirs {
        let clips = if dir.join("clip.json").is_file() {
            vec![dir.clone()]
        } else {
            match fogline_world::format::list_clips(dir) {
                Ok(c) if !c.is_empty() => c,
                Ok(_) => {
                    streams.push(Err(anyhow::anyhow!(
                        "{} holds no clip (a clip directory has a clip.json)",
                        dir.display()
                    )));
                    continue;
                }
                Err(e) => {
                    streams.push(Err(e.into()));
                    continue;
                }
            }
        };
        for clip in clips {
            streams.push(clip_stream(&clip, job));
        }
    }
    for stream in streams {
        summary.streams += 1;
        let r = stream.and_then(|s| {
            let mut m = Monitor::new(&odd, &s.scenario, job.params.clone())
                .with_context(|| format!("{}", job.odd.display()))?;
            let mut last = None;
            for f in &s.frames {
                let rec = step_file(&mut m, f)?;
                summary.frames += 1;
                summary.frames_out += usize::from(!rec.in_envelope);
                writeln!(out, "{}", serde_json::to_string(&rec)?)?;
                last = Some(rec.in_envelope);
            }
            Ok(last)
        });
        match r {
            Ok(Some(false)) => summary.streams_out += 1,
            Ok(_) => {}
            Err(e) => summary.errors.push(format!("{e:#}")),
        }
    }
    Ok(summary)
}

/// A clip's stream: the camera's frame files in order and the scenario.
fn clip_stream(clip: &Path, job: &MonitorRun) -> Result<Stream> {
    let meta = fogline_world::format::read_meta(clip)?;
    if !meta.cameras.iter().any(|c| c.id == job.camera) {
        bail!(
            "{}: the clip has no {} camera (it has {})",
            clip.display(),
            job.camera.short(),
            meta.cameras
                .iter()
                .map(|c| c.id.short())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let cam = clip.join(job.camera.name());
    Ok(Stream {
        frames: (0..meta.frames_t_s.len())
            .map(|k| cam.join(format!("frame_{k}.png")))
            .collect(),
        scenario: job.scenario.clone().unwrap_or(meta.scenario),
    })
}

/// Decodes one frame and steps the monitor; the error names the file.
fn step_file(m: &mut Monitor, path: &Path) -> Result<MonitorRecord> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let img = fogline_io::image::decode_rgb(&bytes)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("{} is not a readable PNG or JPEG image", path.display()))?;
    let mut rec = m
        .step_frame(&img.rgb, img.width as usize, img.height as usize)
        .with_context(|| format!("cannot measure {}", path.display()))?;
    rec.source = Some(path.display().to_string());
    Ok(rec)
}

/// The line `fogline monitor run` prints on stderr at the end.
pub fn write_run_summary(s: &MonitorRunSummary, out: &mut dyn Write) -> Result<()> {
    writeln!(
        out,
        "monitor: {} frames in {} streams, {} frames out of the envelope, {} streams ending out{}",
        s.frames,
        s.streams,
        s.frames_out,
        s.streams_out,
        if s.errors.is_empty() {
            String::new()
        } else {
            format!(", {} streams failed", s.errors.len())
        }
    )?;
    Ok(())
}
