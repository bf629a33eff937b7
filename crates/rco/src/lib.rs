//! LLM-RCO: risk-averse control under perception deficits (the paper
//! `llm-rco-risk-averse-control`, sections 3–6 and appendix A.1, A.2, A.4), as a library a
//! simulator, the CLI or a CARLA agent drives tick by tick.
//!
//! Use it when parts of the camera images are lost (masked objects, dead sensor areas,
//! attacks) and the vehicle should neither stop blindly nor drive on as if nothing happened.
//! Every tick, [`Rco::step`] takes an [`Observation`] — the views (left, front, right by
//! default) with their deficit regions and detected traffic objects, the ego measurements,
//! the navigation and the surroundings — and returns a [`Decision`]: throttle, brake and
//! steer, the action and condition executed, whether and why it replanned or fell back, and
//! counters of backend calls.
//!
//! The four modules, each switchable ([`Modules`], the paper's ablation):
//!
//! - **hazard inference** (equations 3–4): the objects possibly hidden in the deficit regions,
//!   their motion, and the strategy `move` or `stop-observe-move`;
//! - **short-term motion planner** (equation 5): a variable-length sequence of
//!   condition-action pairs, or a wait and a move trigger;
//! - **action condition verifier** ([`verifier`]): deficit consistency across frames and the
//!   0.05 area ratio of immediate hazards; an action runs only when its condition holds;
//! - **safety constraint generator** ([`safety`], equations 6–10, table 5).
//!
//! The plan/act loop (equations 1–2) is in [`controller`], the control mapping (table 4 and
//! the steering PID) in [`control`]. The modules ask a [`Backend`]: [`RulesBackend`]
//! (offline, deterministic, the default) or [`OpenAiBackend`] (any OpenAI-compatible
//! server). Every answer is validated; anything wrong leads to the safe fallback (decelerate
//! to a stop and replan), counted in the decision.
//!
//! ```
//! use fogline_rco::{Rco, RcoParams, synth};
//!
//! let mut rco = Rco::with_rules(RcoParams::default()).unwrap();
//! for obs in synth::story() {
//!     let d = rco.step(&obs);
//!     assert!(d.control.in_range());
//!     assert!(d.fallback.is_none());
//! }
//! ```

pub mod action;
pub mod backend;
pub mod control;
pub mod controller;
pub mod deficit_eval;
pub mod observation;
pub mod replay;
pub mod safety;
pub mod synth;
pub mod verifier;

pub use action::{
    Action, Behavior, Condition, Hazard, HazardState, PlanStep, SpeedControl, Strategy,
};
pub use backend::hostile::HostileBackend;
pub use backend::openai::{OpenAiBackend, OpenAiParams, StructuredOutput};
pub use backend::rules::{RulesBackend, RulesParams, is_signal as is_signal_object};
pub use backend::{Backend, BackendError, Query, QueryContext, Task};
pub use control::Control;
pub use controller::{
    Counters, Decision, Fallback, FallbackKind, Modules, Rco, RcoParams, ReplanReason, Source,
};
pub use observation::{
    Daylight, EgoState, NavDirection, Navigation, Observation, PixelBox, RoadGeometry, RoadLayout,
    Surroundings, TrafficEnv, TrafficObject, View, Weather,
};
pub use safety::{SafetyConstraints, SafetyParams};
pub use verifier::VerifierParams;

/// Errors of the controller's setup and inputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RcoError {
    /// A setting is invalid.
    #[error("invalid parameters: {0}")]
    Params(String),
    /// An observation is invalid.
    #[error("observation at tick {tick}: {reason}")]
    Observation {
        /// Its tick.
        tick: u64,
        /// What is wrong.
        reason: String,
    },
    /// A line of a recorded observations file is invalid.
    #[error("line {line}: {reason}")]
    Replay {
        /// The line, from 1.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A backend cannot be set up.
    #[error("backend: {0}")]
    Backend(String),
}
