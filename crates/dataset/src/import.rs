//! Samples from a user's own driving logs (CARLA, a real car): per-frame images of the
//! RCO's views, per-frame object boxes with track ids, and the expert's brake state. The
//! layout (`docs/dataset.md`):
//!
//! ```text
//! LOGS/<log>/log.json      one directory per log; a log is a "town": its samples share a split
//! LOGS/<log>/<images>      paths relative to the log's directory
//! ```
//!
//! `log.json`: `{"format": "fogline-deficit-log", "version": 1, "cameras": [calibration …],
//! "frames": [{"t_s", "ego_speed_mps", "brake", "images": {"front_wide": "…", …},
//! "objects": [{"camera", "class", "track_id", "bbox": [x0, y0, x1, y1], "motion"}]}]}`.
//!
//! Frames are taken five at a time (1 fps: consecutive frames 1 ± 0.25 s apart; a window
//! starts every `stride_frames` frames). Every track of the four classes boxed in the
//! window's last frame makes one sample: that track is masked (black fill, red outline) in
//! every view and frame it is boxed in; its class is the box class, its motion the box's
//! `motion` at the last frame; the strategy is `stop-observe-move` when the expert brakes at
//! the last frame (the paper's rule), else `move`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

use fogline_perturb::{FrameInput, FrameKey, ObjectBox, Perturbation};
use fogline_rco::Strategy;
use fogline_rco::deficit_eval::{HiddenClass, MotionLabel};
use fogline_sim::sense::{Daylight, Weather};
use fogline_types::clip::{CameraCalib, CameraId};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::DatasetError;
use crate::build::{Built, ImageKind, finish, in_staging, town_splits};
use crate::sample::{BoxRecord, FRAME_TIMES_S, FrameRecord, Manifest, SampleRecord, ViewRecord};
use crate::scene::{HORIZON_S, Rationale, motion_phrase};

/// The log file's name.
pub const LOG_JSON: &str = "log.json";

/// Settings of an import.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImportParams {
    /// The split seed.
    pub seed: u64,
    /// Shares of the logs in train, val and test.
    pub split_fractions: [f64; 3],
    /// Image files.
    pub image: ImageKind,
    /// JPEG quality.
    pub jpeg_quality: u8,
    /// A window starts every this many frames.
    pub stride_frames: usize,
}

impl Default for ImportParams {
    fn default() -> Self {
        Self {
            seed: 0,
            split_fractions: [0.8, 0.1, 0.1],
            image: ImageKind::Png,
            jpeg_quality: 90,
            stride_frames: 5,
        }
    }
}

/// A box in a log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogObject {
    /// The camera (`front_wide`, …).
    pub camera: CameraId,
    /// `traffic_light`, `traffic_sign` (`stop_sign`), `pedestrian`, `bicycle` (`cyclist`),
    /// or any other class (kept as a visible road user).
    pub class: String,
    /// Its track.
    pub track_id: u64,
    /// `[x0, y0, x1, y1]`, px.
    pub bbox: [f64; 4],
    /// `crossing`, `oncoming`, `leading` or `static` (needed for the four classes).
    #[serde(default)]
    pub motion: Option<String>,
}

/// A frame of a log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogFrame {
    /// Time, s.
    pub t_s: f64,
    /// The ego's speed, m/s.
    pub ego_speed_mps: f64,
    /// Whether the expert brakes.
    pub brake: bool,
    /// Image per camera (short name → path relative to the log directory).
    pub images: std::collections::BTreeMap<String, String>,
    /// The boxes.
    #[serde(default)]
    pub objects: Vec<LogObject>,
}

/// A log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Log {
    /// Always `fogline-deficit-log`.
    pub format: String,
    /// 1.
    pub version: u32,
    /// The cameras, in the RCO's order.
    pub cameras: Vec<CameraCalib>,
    /// The frames, in time order.
    pub frames: Vec<LogFrame>,
}

fn class_of(s: &str) -> Option<HiddenClass> {
    match s.trim().to_ascii_lowercase().replace(' ', "_").as_str() {
        "traffic_light" => Some(HiddenClass::TrafficLight),
        "traffic_sign" | "stop_sign" => Some(HiddenClass::TrafficSign),
        "pedestrian" | "person" => Some(HiddenClass::Pedestrian),
        "bicycle" | "cyclist" => Some(HiddenClass::Bicycle),
        _ => None,
    }
}

/// Reads and checks a log (errors name the file, the frame and the field).
pub fn read_log(path: &Path) -> Result<Log, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    let log: Log = serde_json::from_slice(&bytes)
        .map_err(|e| DatasetError::invalid(path, 0, e.to_string()))?;
    let bad = |reason: String| DatasetError::invalid(path, 0, reason);
    if log.format != "fogline-deficit-log" || log.version != 1 {
        return Err(bad(format!(
            "format {:?} version {}: expected \"fogline-deficit-log\" version 1",
            log.format, log.version
        )));
    }
    if log.cameras.is_empty() {
        return Err(bad("cameras: at least one camera is needed".into()));
    }
    for (i, f) in log.frames.iter().enumerate() {
        if !f.t_s.is_finite() || !f.ego_speed_mps.is_finite() {
            return Err(bad(format!(
                "frames[{i}]: t_s and ego_speed_mps must be finite"
            )));
        }
        if i > 0 && f.t_s <= log.frames[i - 1].t_s {
            return Err(bad(format!("frames[{i}].t_s: times must increase")));
        }
        for c in &log.cameras {
            if !f.images.contains_key(c.id.short()) {
                return Err(bad(format!(
                    "frames[{i}].images: no image of {}",
                    c.id.short()
                )));
            }
        }
        for (j, o) in f.objects.iter().enumerate() {
            let Some(calib) = log.cameras.iter().find(|c| c.id == o.camera) else {
                return Err(bad(format!(
                    "frames[{i}].objects[{j}].camera: {} is not in cameras",
                    o.camera.short()
                )));
            };
            let [x0, y0, x1, y1] = o.bbox;
            if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite())
                || x0 < 0.0
                || y0 < 0.0
                || x1 < x0
                || y1 < y0
                || x1 > f64::from(calib.width)
                || y1 > f64::from(calib.height)
            {
                return Err(bad(format!(
                    "frames[{i}].objects[{j}].bbox {:?}: must lie inside {}x{}",
                    o.bbox, calib.width, calib.height
                )));
            }
            if class_of(&o.class).is_some() {
                match o.motion.as_deref().map(MotionLabel::parse) {
                    Some(Some(_)) => {}
                    _ => {
                        return Err(bad(format!(
                            "frames[{i}].objects[{j}].motion: {:?} is not one of crossing, oncoming, leading, static",
                            o.motion
                        )));
                    }
                }
            }
        }
    }
    Ok(log)
}

/// The windows of five frames at 1 fps (first frame indices).
fn windows(log: &Log, stride: usize) -> Vec<usize> {
    let n = FRAME_TIMES_S.len();
    let mut out = Vec::new();
    let mut i = 0;
    while i + n <= log.frames.len() {
        let ok = (1..n).all(|k| {
            let dt = log.frames[i + k].t_s - log.frames[i + k - 1].t_s;
            (dt - 1.0).abs() <= 0.25
        });
        if ok {
            out.push(i);
            i += stride.max(1);
        } else {
            i += 1;
        }
    }
    out
}

struct Job {
    log_dir: PathBuf,
    log: usize,
    start: usize,
    track: u64,
    class: HiddenClass,
}

/// Imports every log under `logs` into a data set in `out`.
pub fn import(params: &ImportParams, logs: &Path, out: &Path) -> Result<Built, DatasetError> {
    let clock = Instant::now();
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(logs)
        .map_err(|e| DatasetError::io(logs, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join(LOG_JSON).is_file())
        .collect();
    dirs.sort();
    if dirs.is_empty() {
        return Err(DatasetError::Params(format!(
            "{}: no <log>/{LOG_JSON} found",
            logs.display()
        )));
    }
    let read: Vec<Log> = dirs
        .iter()
        .map(|d| read_log(&d.join(LOG_JSON)))
        .collect::<Result<_, _>>()?;
    let cameras = read[0].cameras.clone();
    for (d, l) in dirs.iter().zip(&read) {
        if l.cameras != cameras {
            return Err(DatasetError::invalid(
                &d.join(LOG_JSON),
                0,
                "cameras: every log must have the first log's cameras",
            ));
        }
    }
    let splits = town_splits(params.seed, dirs.len() as u64, params.split_fractions);
    let mut jobs = Vec::new();
    for (li, (d, l)) in dirs.iter().zip(&read).enumerate() {
        for start in windows(l, params.stride_frames) {
            let last = &l.frames[start + FRAME_TIMES_S.len() - 1];
            let tracks: BTreeSet<(u64, HiddenClass)> = last
                .objects
                .iter()
                .filter_map(|o| class_of(&o.class).map(|c| (o.track_id, c)))
                .collect();
            for (track, class) in tracks {
                jobs.push(Job {
                    log_dir: d.clone(),
                    log: li,
                    start,
                    track,
                    class,
                });
            }
        }
    }
    let built = in_staging(out, |dir| {
        let records: Vec<SampleRecord> = jobs
            .par_iter()
            .enumerate()
            .map(|(i, j)| import_one(params, &read[j.log], j, i as u64, splits[j.log], dir))
            .collect::<Result<_, _>>()?;
        let (counts, files) = finish(
            dir,
            Manifest {
                format: Manifest::FORMAT.into(),
                version: Manifest::VERSION,
                generated_by: format!("fogline-dataset {}", env!("CARGO_PKG_VERSION")),
                source: "import".into(),
                seed: params.seed,
                samples: 0,
                clips_per_town: 0,
                split_fractions: params.split_fractions,
                image_format: params.image.ext().into(),
                cameras: cameras.clone(),
                frame_times_s: FRAME_TIMES_S.to_vec(),
                horizon_s: HORIZON_S,
                counts: Default::default(),
            },
            &records,
        )?;
        Ok(Built {
            dir: dir.to_path_buf(),
            samples: records.len() as u64,
            counts,
            threads: rayon::current_num_threads(),
            samples_s: clock.elapsed().as_secs_f64(),
            elapsed_s: 0.0,
            files,
        })
    })?;
    Ok(Built {
        elapsed_s: clock.elapsed().as_secs_f64(),
        ..built
    })
}

fn import_one(
    params: &ImportParams,
    log: &Log,
    job: &Job,
    index: u64,
    split: crate::Split,
    dir: &Path,
) -> Result<SampleRecord, DatasetError> {
    let id = format!("c{index:07}");
    let fail = |reason: String| DatasetError::Sample { index, reason };
    let mask = Perturbation::parse(&format!("mask_track_{}", job.track))
        .and_then(|p| p.prepare(0))
        .map_err(|e| fail(e.to_string()))?;
    let format = match params.image {
        ImageKind::Png => fogline_io::ImageFormat::Png,
        ImageKind::Jpeg => fogline_io::ImageFormat::Jpeg {
            quality: params.jpeg_quality,
        },
    };
    let n = FRAME_TIMES_S.len();
    let mut frames = Vec::with_capacity(n);
    std::fs::create_dir_all(dir.join("images").join(&id))
        .map_err(|e| DatasetError::io(&dir.join("images"), e))?;
    for k in 0..n {
        let f = &log.frames[job.start + k];
        let mut views = Vec::with_capacity(log.cameras.len());
        for calib in &log.cameras {
            let cam = calib.id.short();
            let src = job
                .log_dir
                .join(f.images.get(cam).map_or("", String::as_str));
            let bytes = std::fs::read(&src).map_err(|e| DatasetError::io(&src, e))?;
            let img =
                fogline_io::decode_rgb(&bytes).map_err(|e| DatasetError::invalid(&src, 0, e))?;
            if (img.width, img.height) != (calib.width, calib.height) {
                return Err(DatasetError::invalid(
                    &src,
                    0,
                    format!(
                        "{}x{} px, camera {cam} is {}x{}",
                        img.width, img.height, calib.width, calib.height
                    ),
                ));
            }
            let boxes: Vec<ObjectBox> = f
                .objects
                .iter()
                .filter(|o| o.camera == calib.id)
                .map(|o| ObjectBox {
                    class: o.class.clone(),
                    track_id: Some(o.track_id),
                    x_px: o.bbox[0],
                    y_px: o.bbox[1],
                    width_px: o.bbox[2] - o.bbox[0],
                    height_px: o.bbox[3] - o.bbox[1],
                })
                .collect();
            let frame = fogline_perturb::Frame::new(img.width, img.height, img.rgb)
                .map_err(|e| DatasetError::invalid(&src, 0, e.to_string()))?;
            let applied = mask
                .apply(&FrameInput {
                    frame: frame.view(),
                    key: FrameKey::new(index, calib.id.index() as u64, k as u64),
                    depth: None,
                    boxes: &boxes,
                })
                .map_err(|e| DatasetError::invalid(&src, 0, e.to_string()))?;
            let rel = format!("images/{id}/{cam}_{k}.{}", params.image.ext());
            let encoded =
                fogline_io::encode(applied.frame.data(), calib.width, calib.height, format)
                    .map_err(fail)?;
            let path = dir.join(&rel);
            std::fs::write(&path, encoded).map_err(|e| DatasetError::io(&path, e))?;
            views.push(ViewRecord {
                camera: calib.id,
                image: rel,
                deficits: applied
                    .deficits
                    .iter()
                    .map(|d| [d.rect.x0, d.rect.y0, d.rect.x1, d.rect.y1])
                    .collect(),
                objects: f
                    .objects
                    .iter()
                    .filter(|o| o.camera == calib.id && o.track_id != job.track)
                    .map(|o| BoxRecord {
                        class: o.class.clone(),
                        track_id: Some(o.track_id),
                        bbox: o.bbox,
                    })
                    .collect(),
            });
        }
        frames.push(FrameRecord {
            t_s: FRAME_TIMES_S[k],
            ego_speed_mps: f.ego_speed_mps,
            views,
        });
    }
    let last = &log.frames[job.start + n - 1];
    let motion = last
        .objects
        .iter()
        .find(|o| o.track_id == job.track)
        .and_then(|o| o.motion.as_deref())
        .and_then(MotionLabel::parse)
        .unwrap_or(MotionLabel::Static);
    let phrase = job.class.phrase();
    let strategy = if last.brake {
        Strategy::StopObserveMove
    } else {
        Strategy::Move
    };
    let why = match strategy {
        Strategy::StopObserveMove => format!(
            "The ego vehicle should stop because the invisible region may contain a {phrase} that is {}.",
            motion_phrase(motion)
        ),
        Strategy::Move => "There is no reason for the ego vehicle to brake.".into(),
    };
    Ok(SampleRecord {
        id,
        index,
        town: job.log as u64,
        split,
        class: job.class,
        motion,
        strategy,
        rationale: Rationale {
            object: format!("The masked region is where the log boxes a {phrase}."),
            motion: format!("The {phrase} is {}.", motion_phrase(motion)),
            strategy: why,
        },
        weather: Weather::Cloudy,
        daylight: Daylight::Noon,
        target: None,
        frames,
    })
}
