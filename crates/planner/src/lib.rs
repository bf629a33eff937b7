//! The reference planner: a camera-only driver that sees what a real camera planner sees —
//! the frames of its cameras and the ego history — and nothing else. The crate depends on
//! `fogline-types` only, so the crate graph itself proves it cannot read the scene.

use fogline_types::clip::{PlannerInput, PlannerOutput};

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

    /// Plans from `input`.
    pub fn plan(&self, input: &PlannerInput<'_>) -> Result<PlannerOutput, PlannerError> {
        let _ = input;
        Err(PlannerError::Input("the planner is being written".into()))
    }
}
