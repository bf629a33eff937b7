//! A clip: what the world produces and what the clip format stores.

use fogline_perturb::frame::{DepthMap, Frame, ObjectBox};
use fogline_types::clip::{CameraCalib, Decision, EgoPose, Trajectory};
use serde::{Deserialize, Serialize};

/// One frame of one camera.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraFrame {
    /// Time relative to `t0`, s (−0.3, −0.2, −0.1, 0 for the standard 4 frames).
    pub t_s: f64,
    /// The RGB image.
    pub image: Frame,
    /// Distance from the camera per pixel, m (`+inf` for sky); absent in data without depth.
    pub depth: Option<DepthMap>,
    /// The 2-D boxes of the visible objects (the visible part, clipped to the image).
    pub boxes: Vec<ObjectBox>,
}

/// One camera of a clip: its calibration and its frames, oldest first.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraClip {
    /// Intrinsics and pose in the rig frame.
    pub calib: CameraCalib,
    /// The frames, oldest first, ending at `t0`.
    pub frames: Vec<CameraFrame>,
}

/// What the world knows about a generated scene beyond the pixels (kept for analysis, never
/// given to a planner).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct SceneInfo {
    /// The expert's decision.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decision: Option<Decision>,
    /// Free-form scene facts (time of day, light state, distances …).
    #[serde(default, skip_serializing_if = "serde_json::Map::is_empty")]
    pub facts: serde_json::Map<String, serde_json::Value>,
}

/// A clip: cameras with frames, ego history, ground-truth future, scenario label.
#[derive(Debug, Clone, PartialEq)]
pub struct Clip {
    /// The clip id (unique within a corpus; used as the directory name).
    pub id: String,
    /// The scenario label (the paper's taxonomy or the user's own).
    pub scenario: String,
    /// The cameras, in the rig's order.
    pub cameras: Vec<CameraClip>,
    /// The ego history, 16 poses oldest first, ending at `t0`.
    pub ego_history: Vec<EgoPose>,
    /// The ground-truth future.
    pub ground_truth: Trajectory,
    /// Scene facts (present for generated clips).
    pub scene: SceneInfo,
}
