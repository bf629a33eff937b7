//! The reference planner as a [`Planner`]: in-process, no encoding, no network.

use fogline_planner::ReferencePlanner;
use fogline_remote::{FailureKind, PlanFailure, PlanRequest, Planner};
use fogline_types::clip::{CameraId, PlannerOutput};

/// The built-in reference planner behind the [`Planner`] interface.
#[derive(Debug, Clone, Default)]
pub struct BuiltinPlanner {
    inner: ReferencePlanner,
}

impl BuiltinPlanner {
    /// The reference planner with its default settings.
    pub fn new() -> Self {
        Self::default()
    }
}

impl Planner for BuiltinPlanner {
    fn describe(&self) -> String {
        "builtin reference planner".into()
    }

    /// The reference planner perceives with the front-wide and front-tele cameras only.
    fn cameras(&self) -> Option<Vec<CameraId>> {
        Some(vec![CameraId::FrontWide, CameraId::FrontTele])
    }

    fn plan(&self, request: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        let out = self
            .inner
            .plan(&request.input)
            .map_err(|e| PlanFailure::new(FailureKind::Input, e.to_string()))?;
        out.trajectory
            .validate()
            .map_err(|e| PlanFailure::new(FailureKind::InvalidAnswer, e))?;
        Ok(out)
    }
}
