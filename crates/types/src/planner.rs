//! The planner interface every fogline crate can implement and drive: [`Planner`] (frames
//! and ego history in, a 64-waypoint trajectory and an explanation out), its request and its
//! failures. The reference planner, the remote clients (AlpaSim's egodriver gRPC contract,
//! HTTP/JSON) and your own planners implement it; campaigns and servers consume it.

use crate::clip::{PlannerInput, PlannerOutput};

/// One planning request: the planner's input plus what identifies the run to a remote
/// policy (a scene id and a random seed, which AlpaSim's `start_session` carries).
#[derive(Debug, Clone)]
pub struct PlanRequest<'a> {
    /// The scene (clip) identifier, e.g. `clip-000042`; sent as `debug_info.scene_id`.
    pub scene_id: &'a str,
    /// The random seed for the planner's own sampling; sent as `random_seed`.
    pub seed: u64,
    /// The cameras' frames and the ego history.
    pub input: PlannerInput<'a>,
}

/// What went wrong with one planning call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum FailureKind {
    /// No answer within the request timeout.
    Timeout,
    /// The endpoint could not be reached, or the connection dropped.
    Unavailable,
    /// The planner answered with an error (a gRPC status, an HTTP error status).
    Remote,
    /// The planner answered, but the answer is not a valid plan (garbage bytes, NaN, the
    /// wrong number of waypoints, a trajectory that does not cover the horizon).
    InvalidAnswer,
    /// The request itself could not be built (e.g. a frame that cannot be encoded).
    Input,
}

impl FailureKind {
    /// A short stable name (`timeout`, `unavailable`, `remote_error`, `invalid_answer`,
    /// `input`), used in stores and reports.
    pub fn name(self) -> &'static str {
        match self {
            FailureKind::Timeout => "timeout",
            FailureKind::Unavailable => "unavailable",
            FailureKind::Remote => "remote_error",
            FailureKind::InvalidAnswer => "invalid_answer",
            FailureKind::Input => "input",
        }
    }

    /// Whether trying again may help (timeouts, unreachable endpoints, remote errors).
    pub fn retryable(self) -> bool {
        matches!(
            self,
            FailureKind::Timeout | FailureKind::Unavailable | FailureKind::Remote
        )
    }
}

/// A failed planning call: what kind of failure, and a message that says what happened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlanFailure {
    /// The kind of failure.
    pub kind: FailureKind,
    /// What happened, for a person.
    pub message: String,
}

impl PlanFailure {
    /// A failure of `kind`.
    pub fn new(kind: FailureKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
}

/// A driving planner: frames and ego history in, a 64-waypoint trajectory and an
/// explanation out. Implementations are shared across worker threads.
pub trait Planner: Send + Sync {
    /// A one-line description (`builtin reference planner`, `egodriver at 127.0.0.1:50051`).
    fn describe(&self) -> String;

    /// Plans once. A returned output has been validated (64 finite waypoints).
    fn plan(&self, request: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure>;

    /// The cameras this planner looks at, when it knows (`None`: every camera it is given).
    /// A campaign renders and perturbs only these; the answer must not change when the
    /// others are left out.
    fn cameras(&self) -> Option<Vec<crate::clip::CameraId>> {
        None
    }
}

impl std::fmt::Display for PlanFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.kind.name(), self.message)
    }
}

impl std::error::Error for PlanFailure {}
