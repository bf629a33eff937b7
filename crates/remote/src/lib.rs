//! Planners behind an endpoint, both ways round.
//!
//! - [`Planner`]: the one interface a campaign drives — the reference planner in-process, a
//!   remote policy over AlpaSim's `egodriver.EgodriverService` gRPC contract
//!   ([`egodriver`]), or a planner behind the small HTTP/JSON protocol ([`http`]).
//! - Servers: any [`Planner`] can be served over either protocol, so fogline's reference
//!   planner can be driven by AlpaSim-style runtimes and CARLA bridges.
//!
//! Conventions (those of `fogline_types::clip`): frames are RGB8 row-major, oldest first, at
//! `t0 − 0.1·(n−1−j)` s; the ego history ends at `t0` and is expressed in the rig frame at
//! `t0` (x forward, y left, metres); the answer is 64 waypoints at `t0 + 0.1 … t0 + 6.4` s
//! in the same frame.

use fogline_types::clip::{PlannerInput, PlannerOutput};

pub mod egodriver;
pub mod http;

mod codec;
mod geom;
mod serving;

pub use serving::ServerHandle;

/// How a client encodes camera frames for the wire: PNG (lossless, the default: the planner
/// sees exactly the pixels fogline produced) or JPEG at a quality of 1–100 (smaller, lossy;
/// AlpaSim's renderers send JPEG too).
pub use fogline_io::ImageFormat;

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
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: {message}", kind.name())]
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
    fn cameras(&self) -> Option<Vec<fogline_types::clip::CameraId>> {
        None
    }
}
