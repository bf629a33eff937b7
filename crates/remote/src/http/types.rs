//! The JSON bodies of the protocol.

use fogline_types::clip::EgoPose;
use serde::{Deserialize, Serialize};

/// `POST /v1/plan` request. The client writes each frame's JSON on the thread that encoded
/// it (`F` = its raw JSON, [`FrameJson`]), so the body is assembled without scanning a
/// megabyte of base64 for characters to escape on one thread; the server reads
/// [`FrameBody`].
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct PlanBody<F = FrameBody> {
    pub scene_id: String,
    pub seed: u64,
    /// The absolute time of `t0`, µs, when the caller has one; informational.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t0_us: Option<u64>,
    pub cameras: Vec<CameraBody<F>>,
    pub ego_history: Vec<EgoPose>,
}

#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct CameraBody<F = FrameBody> {
    /// A PhysicalAI camera name (`camera_front_wide_120fov`) or its short form.
    pub id: String,
    pub calibration: CalibrationBody,
    pub frames: Vec<F>,
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub(crate) struct CalibrationBody {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
    pub yaw_rad: f64,
    pub pitch_rad: f64,
}

#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct FrameBody {
    /// Time relative to `t0`, s (≤ 0).
    pub t_s: f64,
    /// `png` or `jpeg`.
    pub image_format: String,
    /// The encoded image, standard base64 with padding.
    pub data: String,
}

/// A [`FrameBody`] already written as JSON.
pub(crate) type FrameJson = Box<serde_json::value::RawValue>;

/// `200` answer of `POST /v1/plan` (what the server writes; the client reads it loosely
/// to report precise errors).
#[derive(Debug, Serialize)]
pub(crate) struct AnswerBody<'a> {
    pub trajectory: &'a [[f64; 2]],
    pub explanation: &'a str,
    pub decision: Option<&'a str>,
}

/// Any error answer.
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct ErrorBody {
    pub error: String,
    /// The failure kind's name when the planner failed (`input`, `timeout`, …).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<String>,
}
