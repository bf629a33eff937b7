//! The on-disk format of a data set: `manifest.json` and `samples.jsonl` (one
//! [`SampleRecord`] per line, in sample order), the frames as image files under `images/`.
//! See `docs/dataset.md`.

use std::collections::BTreeMap;
use std::path::Path;

use fogline_rco::Strategy;
use fogline_rco::deficit_eval::{HiddenClass, MotionLabel};
use fogline_sim::sense::{Daylight, Weather};
use fogline_types::clip::{CameraCalib, CameraId};
use serde::{Deserialize, Serialize};

use crate::DatasetError;
use crate::scene::{Rationale, Target};

/// The manifest's file name.
pub const MANIFEST_JSON: &str = "manifest.json";
/// The samples' file name.
pub const SAMPLES_JSONL: &str = "samples.jsonl";
/// The frame times, s relative to the last frame: five frames at 1 fps.
pub const FRAME_TIMES_S: [f64; 5] = [-4.0, -3.0, -2.0, -1.0, 0.0];

/// Which split a sample is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Split {
    /// Training.
    Train,
    /// Validation.
    Val,
    /// Test.
    Test,
}

impl Split {
    /// All three.
    pub const ALL: [Split; 3] = [Split::Train, Split::Val, Split::Test];

    /// The name.
    pub fn name(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Val => "val",
            Split::Test => "test",
        }
    }

    /// Parses [`Split::name`].
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|x| x.name() == s)
    }
}

/// A road user's box in a frame (visible, never hidden).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoxRecord {
    /// `car`, `pedestrian`, `cyclist`, …
    pub class: String,
    /// Its track.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub track_id: Option<u64>,
    /// `[x0, y0, x1, y1]`, px.
    pub bbox: [f64; 4],
}

/// One camera's frame of a sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewRecord {
    /// The camera.
    pub camera: CameraId,
    /// The image file, relative to the data set directory.
    pub image: String,
    /// The deficit regions `[x0, y0, x1, y1)` in whole pixels (black fill, red outline).
    pub deficits: Vec<[u32; 4]>,
    /// The visible road users.
    #[serde(default)]
    pub objects: Vec<BoxRecord>,
}

/// One instant of a sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// Time relative to the last frame, s.
    pub t_s: f64,
    /// The ego's speed, m/s.
    pub ego_speed_mps: f64,
    /// The views, in the RCO's order.
    pub views: Vec<ViewRecord>,
}

/// One sample (a line of `samples.jsonl`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleRecord {
    /// Its id (`c0000042`).
    pub id: String,
    /// Its index.
    pub index: u64,
    /// Its town (the split unit).
    pub town: u64,
    /// Its split.
    pub split: Split,
    /// The hidden class.
    pub class: HiddenClass,
    /// Its motion.
    pub motion: MotionLabel,
    /// The expert's strategy.
    pub strategy: Strategy,
    /// The rationale sentences.
    pub rationale: Rationale,
    /// The weather.
    pub weather: Weather,
    /// The daylight.
    pub daylight: Daylight,
    /// The hidden object's ground truth (imported logs: `None`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<Target>,
    /// The five frames, oldest first.
    pub frames: Vec<FrameRecord>,
}

impl SampleRecord {
    /// The view that shows the hidden object at the last frame: the front view when it
    /// does, else the first view with a deficit.
    pub fn target_camera(&self) -> Option<CameraId> {
        let last = self.frames.last()?;
        let with: Vec<CameraId> = last
            .views
            .iter()
            .filter(|v| !v.deficits.is_empty())
            .map(|v| v.camera)
            .collect();
        with.iter()
            .copied()
            .find(|c| *c == CameraId::FrontWide)
            .or_else(|| with.first().copied())
    }
}

/// Counts of one class (figure 5b).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ClassCounts {
    /// Samples.
    pub samples: u64,
    /// Labelled `move`.
    #[serde(rename = "move")]
    pub move_: u64,
    /// Labelled `stop-observe-move`.
    pub stop_observe_move: u64,
    /// Per motion label.
    pub by_motion: BTreeMap<String, u64>,
}

/// Counts of one split.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SplitCounts {
    /// Samples.
    pub samples: u64,
    /// Towns.
    pub towns: u64,
    /// Per class.
    pub by_class: BTreeMap<String, ClassCounts>,
}

impl SplitCounts {
    /// Adds one sample.
    pub fn add(&mut self, s: &SampleRecord) {
        self.samples += 1;
        let c = self.by_class.entry(s.class.name().into()).or_default();
        c.samples += 1;
        match s.strategy {
            Strategy::Move => c.move_ += 1,
            Strategy::StopObserveMove => c.stop_observe_move += 1,
        }
        *c.by_motion.entry(s.motion.name().into()).or_default() += 1;
    }
}

/// A data set's manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Always [`Manifest::FORMAT`].
    pub format: String,
    /// Schema version.
    pub version: u32,
    /// What wrote it.
    pub generated_by: String,
    /// `world` (built by fogline) or `import` (from a log).
    pub source: String,
    /// The seed.
    pub seed: u64,
    /// Samples.
    pub samples: u64,
    /// Clips per town.
    pub clips_per_town: u64,
    /// Train, val, test shares of the towns.
    pub split_fractions: [f64; 3],
    /// `png` or `jpeg`.
    pub image_format: String,
    /// The cameras (the RCO's views at the closed loop's sizes).
    pub cameras: Vec<CameraCalib>,
    /// Frame times, s.
    pub frame_times_s: Vec<f64>,
    /// The expert's horizon, s.
    pub horizon_s: f64,
    /// Counts per split (`train`, `val`, `test`) and `all`.
    pub counts: BTreeMap<String, SplitCounts>,
}

impl Manifest {
    /// The `format` tag.
    pub const FORMAT: &'static str = "fogline-deficit-dataset";
    /// The schema version.
    pub const VERSION: u32 = 1;

    /// Reads `dir/manifest.json`.
    pub fn read(dir: &Path) -> Result<Self, DatasetError> {
        let path = dir.join(MANIFEST_JSON);
        let bytes = std::fs::read(&path).map_err(|e| DatasetError::io(&path, e))?;
        let m: Manifest = serde_json::from_slice(&bytes)
            .map_err(|e| DatasetError::invalid(&path, 0, e.to_string()))?;
        if m.format != Self::FORMAT {
            return Err(DatasetError::invalid(
                &path,
                0,
                format!("format is {:?}, expected {:?}", m.format, Self::FORMAT),
            ));
        }
        if m.version != Self::VERSION {
            return Err(DatasetError::invalid(
                &path,
                0,
                format!(
                    "version {} is not supported (expected {})",
                    m.version,
                    Self::VERSION
                ),
            ));
        }
        Ok(m)
    }

    /// The calibration of `camera`.
    pub fn calib(&self, camera: CameraId) -> Option<&CameraCalib> {
        self.cameras.iter().find(|c| c.id == camera)
    }
}

/// Reads `dir/samples.jsonl` (an error names the line).
pub fn read_samples(dir: &Path) -> Result<Vec<SampleRecord>, DatasetError> {
    let path = dir.join(SAMPLES_JSONL);
    let text = std::fs::read_to_string(&path).map_err(|e| DatasetError::io(&path, e))?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str::<SampleRecord>(l)
                .map_err(|e| DatasetError::invalid(&path, i + 1, e.to_string()))
        })
        .collect()
}
