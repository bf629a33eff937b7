//! The reference planner: a camera-only driver that sees what a real camera planner sees —
//! the frames of its cameras and the ego history — and nothing else. The crate depends on
//! `fogline-types` and `fogline-monitor` (image quality from the pixels) only, so the crate
//! graph itself proves it cannot read the scene.
//!
//! Perception is classical vision on the front-wide and front-tele cameras through their
//! calibration and flat-ground geometry ([`perceive`]): lane markings fitted as a parabola
//! (curvature fused with the ego history's), the occupancy of the ego lane and the lane to its
//! left per 0.1 m lateral bin, the lead object (distance from its ground contact, speed from
//! four frames, brake lamps, width at cabin height to tell vehicles from people), stop lines
//! and zebra crossings, stop signs, lit signal lamps, and the end of the road at a junction.
//! Planning ([`plan`]) turns that into one of the [`Decision`]s, a 64-waypoint trajectory with
//! the shared motion primitives, and a one-sentence explanation whose wording depends only on
//! what was perceived.
//!
//! Under perturbation it fails for perceptual reasons only: every reading is pooled as much as
//! the measured noise asks for, so noise costs sensitivity (far, narrow and low-contrast
//! things are lost first); fog washes out paint and lamps at range; darkness pushes
//! low-contrast things into the quantisation floor.
//!
//! What it detects is an API too ([`ReferencePlanner::detect`], [`detect`]): the road users in
//! the ego lane and the lane to its left with image boxes and tracks, and the deficit regions
//! (black fill, red outline) recognised in each camera's latest frame.

pub mod detect;
pub mod perceive;
pub mod plan;
pub mod vision;

use fogline_types::clip::{Decision, PlannerInput, PlannerOutput};

pub use perceive::Perception;

/// The reference planner behind the shared [`Planner`](fogline_types::planner::Planner)
/// interface: in-process, no encoding, no network (what campaigns call `builtin`).
impl fogline_types::planner::Planner for ReferencePlanner {
    fn describe(&self) -> String {
        "builtin reference planner".into()
    }

    /// The reference planner perceives with the front-wide and front-tele cameras only.
    fn cameras(&self) -> Option<Vec<fogline_types::clip::CameraId>> {
        Some(vec![
            fogline_types::clip::CameraId::FrontWide,
            fogline_types::clip::CameraId::FrontTele,
        ])
    }

    fn plan(
        &self,
        request: &fogline_types::planner::PlanRequest<'_>,
    ) -> Result<PlannerOutput, fogline_types::planner::PlanFailure> {
        use fogline_types::planner::{FailureKind, PlanFailure};
        let out = ReferencePlanner::plan(self, &request.input)
            .map_err(|e| PlanFailure::new(FailureKind::Input, e.to_string()))?;
        out.trajectory
            .validate()
            .map_err(|e| PlanFailure::new(FailureKind::InvalidAnswer, e))?;
        Ok(out)
    }
}

/// Why the planner could not run on an input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlannerError {
    /// An input that does not describe camera frames.
    #[error("invalid planner input: {0}")]
    Input(String),
}

/// The reference planner.
#[derive(Debug, Clone, Default)]
pub struct ReferencePlanner {}

impl ReferencePlanner {
    /// A planner with the default settings.
    pub fn new() -> Self {
        Self::default()
    }

    /// Plans from `input`: needs the front-wide camera (front-tele extends the range), at
    /// least one frame per camera of `width × height × 3` bytes, and an ego history.
    pub fn plan(&self, input: &PlannerInput<'_>) -> Result<PlannerOutput, PlannerError> {
        let (p, plan) = self.plan_with_perception(input)?;
        let _ = p;
        Ok(PlannerOutput {
            trajectory: plan.trajectory,
            explanation: plan.explanation,
            decision: Some(plan.decision),
        })
    }

    /// What the perception detects in `input`: the nearest road user in the ego lane and in
    /// the lane to its left (kind, contact, extents, speed, track over the frames, and its
    /// box in the camera it was read from), and the deficit regions in the latest frame of
    /// every camera. Costs a planning call plus the left lane's object and the deficit scan.
    pub fn detect(&self, input: &PlannerInput<'_>) -> Result<detect::Detections, PlannerError> {
        validate(input)?;
        let p = perceive::perceive_objects(input);
        let objects = detect::objects(&p, input);
        let mut deficits = Vec::new();
        for cam in &input.cameras {
            let Some(frame) = cam.frames.last() else {
                continue;
            };
            let (w, h) = (cam.calib.width as usize, cam.calib.height as usize);
            for d in detect::find_deficits(frame, w, h)? {
                deficits.push((cam.calib.id, d));
            }
        }
        Ok(detect::Detections { objects, deficits })
    }

    /// Plans knowing what the frames and the history alone do not say (see
    /// [`perceive::Knowing`]): which pixels are lost (deficit regions, e.g. from
    /// [`detect::find_deficits`]: a lamp or a sign read inside a lost region does not count;
    /// an override that has recognised a deficit drives the planner this way, a planner that
    /// is not told keeps reading what the pixels show), and the navigation's curvature for a
    /// car that stands or creeps, whose history has none.
    pub fn plan_knowing(
        &self,
        input: &PlannerInput<'_>,
        knowing: &perceive::Knowing<'_>,
    ) -> Result<(Perception, plan::Plan), PlannerError> {
        validate(input)?;
        let p = perceive::perceive_knowing(input, knowing);
        let plan = plan::plan(&p);
        Ok((p, plan))
    }

    /// Plans and returns the perception behind the plan (for inspection and tests).
    pub fn plan_with_perception(
        &self,
        input: &PlannerInput<'_>,
    ) -> Result<(Perception, plan::Plan), PlannerError> {
        validate(input)?;
        let p = perceive::perceive(input);
        let plan = plan::plan(&p);
        Ok((p, plan))
    }
}

fn validate(input: &PlannerInput<'_>) -> Result<(), PlannerError> {
    use fogline_types::clip::CameraId;
    if !input
        .cameras
        .iter()
        .any(|c| c.calib.id == CameraId::FrontWide)
    {
        return Err(PlannerError::Input(
            "the front-wide camera (camera_front_wide_120fov) is required".into(),
        ));
    }
    for cam in &input.cameras {
        cam.calib.validate().map_err(PlannerError::Input)?;
        if cam.frames.is_empty() {
            return Err(PlannerError::Input(format!("{}: no frames", cam.calib.id)));
        }
        let expected = cam.calib.width as usize * cam.calib.height as usize * 3;
        for (k, f) in cam.frames.iter().enumerate() {
            if f.len() != expected {
                return Err(PlannerError::Input(format!(
                    "{} frame {k}: {} bytes, expected {expected} ({}x{} RGB8)",
                    cam.calib.id,
                    f.len(),
                    cam.calib.width,
                    cam.calib.height
                )));
            }
        }
    }
    if input.ego_history.is_empty() {
        return Err(PlannerError::Input("the ego history is empty".into()));
    }
    if input
        .ego_history
        .iter()
        .any(|p| !(p.x_m.is_finite() && p.y_m.is_finite() && p.yaw_rad.is_finite()))
    {
        return Err(PlannerError::Input(
            "the ego history has a non-finite pose".into(),
        ));
    }
    Ok(())
}

/// Every decision the planner can take (re-exported for convenience).
pub const DECISIONS: [Decision; 10] = Decision::ALL;
