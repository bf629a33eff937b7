//! Backends: who answers the controller's queries (hazard inference, motion planning, safety
//! constraints).
//!
//! Every backend gets the same [`Query`]: the task, the system and user prompts (the paper's
//! appendix A.4 adapted to our JSON schemas), the images, the JSON schema of the answer, and
//! the structured context the prompt was written from. A backend answers with the JSON text
//! of the schema; the controller parses and validates every answer the same way
//! ([`answer`]) whichever backend wrote it, and falls back safely when it cannot.
//!
//! - [`rules::RulesBackend`] (default): offline, deterministic commonsense rules over the
//!   structured context.
//! - [`openai::OpenAiBackend`]: any OpenAI-compatible `/v1/chat/completions` server, over
//!   HTTP or HTTPS, its structured output mode negotiated.

pub mod answer;
pub mod hostile;
pub mod openai;
pub mod prompt;
pub mod rules;

use fogline_types::clip::CameraId;
use serde::{Deserialize, Serialize};

use crate::action::{Hazard, HazardInference};
use crate::observation::{Observation, View};
use crate::safety::SafetyConstraints;
use crate::verifier::Assessment;

/// What a query asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Task {
    /// Equation 4: hazards in the deficit regions and the strategy.
    HazardInference,
    /// Equation 5 under `move`: a sequence of condition-action pairs.
    MovePlan,
    /// Equation 5 under `stop-observe-move`: the wait and the move trigger.
    StopObserveMovePlan,
    /// Equation 6: the safety constraints.
    SafetyConstraints,
}

impl Task {
    /// The snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            Task::HazardInference => "hazard_inference",
            Task::MovePlan => "move_plan",
            Task::StopObserveMovePlan => "stop_observe_move_plan",
            Task::SafetyConstraints => "safety_constraints",
        }
    }
}

/// The structured facts a query's prompt was written from.
#[derive(Debug, Clone, Copy)]
pub struct QueryContext<'a> {
    /// The last observations, oldest first; the last one is now (never empty).
    pub history: &'a [Observation],
    /// The views the controller uses, in order.
    pub views: &'a [CameraId],
    /// The verifier's assessment of now.
    pub assessment: &'a Assessment,
    /// The hazard inference result (planning queries; `None` when hazard inference is off).
    pub hazard: Option<&'a HazardInference>,
    /// The largest number of steps of a move plan.
    pub plan_limit: usize,
    /// The largest wait of a stop-observe-move plan, ticks.
    pub wait_limit: u32,
    /// The constraints in force.
    pub constraints: Option<&'a SafetyConstraints>,
    /// Ticks since the last stop-observe-move finished (its trigger held), if any.
    pub ticks_since_stop: Option<u64>,
    /// The hazards that stop-observe-move was for.
    pub stopped_for: &'a [Hazard],
    /// The verifier's hazard ratio threshold.
    pub hazard_ratio: f64,
    /// Seconds per tick.
    pub dt_s: f64,
}

impl QueryContext<'_> {
    /// The current observation.
    pub fn now(&self) -> &Observation {
        // The controller never builds a context from an empty history.
        &self.history[self.history.len() - 1]
    }
}

/// An image attached to a query.
#[derive(Debug, Clone, Copy)]
pub struct QueryImage<'a> {
    /// The camera.
    pub camera: CameraId,
    /// How many ticks old the frame is (0: now).
    pub ticks_ago: usize,
    /// The view (it has pixels).
    pub view: &'a View,
}

/// One question to a backend.
#[derive(Debug, Clone)]
pub struct Query<'a> {
    /// The task.
    pub task: Task,
    /// The system prompt.
    pub system: String,
    /// The user prompt.
    pub user: String,
    /// The frames to show, oldest first.
    pub images: Vec<QueryImage<'a>>,
    /// The schema's name.
    pub schema_name: &'static str,
    /// The JSON schema the answer must follow.
    pub schema: serde_json::Value,
    /// The structured context.
    pub context: QueryContext<'a>,
}

/// Why a backend gave no answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BackendError {
    /// No complete answer within the time limit.
    #[error("no answer within {timeout_ms} ms")]
    Timeout {
        /// The limit, ms.
        timeout_ms: u64,
    },
    /// The server could not be reached or the connection broke.
    #[error("cannot reach {url}: {reason}")]
    Unavailable {
        /// The server.
        url: String,
        /// What failed.
        reason: String,
    },
    /// The server answered with an error status.
    #[error("HTTP status {status}: {body}")]
    Status {
        /// The status code.
        status: u16,
        /// The start of the body.
        body: String,
    },
    /// The reply is not a chat completion.
    #[error("the reply is not a chat completion: {0}")]
    Protocol(String),
    /// The model refused to answer.
    #[error("the model refused: {0}")]
    Refused(String),
    /// The answer was cut at the token limit.
    #[error("the answer was cut at the token limit")]
    Truncated,
}

/// Who answers the controller's queries.
pub trait Backend: Send {
    /// A short description (`rules`, `openai model at URL`).
    fn describe(&self) -> String;

    /// The JSON text answering `query` (validated by the caller).
    fn answer(&mut self, query: &Query<'_>) -> Result<String, BackendError>;

    /// How the answer's schema reaches the model, when the backend negotiates it with a
    /// server (`json_object (the server refused json_schema)`); `None` for backends that
    /// answer in-process.
    fn structured_output(&self) -> Option<String> {
        None
    }
}
