//! The vocabulary of plans: actions (driving behaviour × speed control, appendix A.1),
//! per-view conditions, hazards `[object, motion]` (equation 3) and the two strategies.

use std::collections::BTreeMap;
use std::fmt;

use fogline_types::clip::CameraId;
use serde::{Deserialize, Serialize};

/// A driving behaviour (the paper's six).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Behavior {
    /// Keep going along the route.
    MoveForward,
    /// Change to the left lane.
    ChangeLaneToLeft,
    /// Change to the right lane.
    ChangeLaneToRight,
    /// Turn left.
    TurnLeft,
    /// Turn right.
    TurnRight,
    /// Stop.
    Stop,
}

impl Behavior {
    /// All six, in the prompt's order.
    pub const ALL: [Behavior; 6] = [
        Behavior::MoveForward,
        Behavior::ChangeLaneToLeft,
        Behavior::ChangeLaneToRight,
        Behavior::TurnLeft,
        Behavior::TurnRight,
        Behavior::Stop,
    ];

    /// The snake-case name used in prompts and answers.
    pub fn name(self) -> &'static str {
        match self {
            Behavior::MoveForward => "move_forward",
            Behavior::ChangeLaneToLeft => "change_lane_to_left",
            Behavior::ChangeLaneToRight => "change_lane_to_right",
            Behavior::TurnLeft => "turn_left",
            Behavior::TurnRight => "turn_right",
            Behavior::Stop => "stop",
        }
    }

    /// Parses [`Behavior::name`].
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|b| b.name() == s)
    }
}

/// A speed control (the paper's six; table 4 maps each to throttle and brake).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpeedControl {
    /// `throttle = 0.7, brake = 0`.
    ConstantSpeed,
    /// `throttle = max(0, throttle' − 0.2), brake = 0.2`.
    Deceleration,
    /// `throttle = max(0, throttle' − 0.4), brake = 0.4`.
    QuickDeceleration,
    /// `throttle = 0, brake = 0.8`.
    DecelerationToZero,
    /// `throttle = min(1, throttle' + 0.2), brake = 0`.
    Acceleration,
    /// `throttle = min(1, throttle' + 0.4), brake = 0`.
    QuickAcceleration,
}

impl SpeedControl {
    /// All six, in the prompt's order.
    pub const ALL: [SpeedControl; 6] = [
        SpeedControl::ConstantSpeed,
        SpeedControl::Deceleration,
        SpeedControl::QuickDeceleration,
        SpeedControl::DecelerationToZero,
        SpeedControl::Acceleration,
        SpeedControl::QuickAcceleration,
    ];

    /// The snake-case name used in prompts and answers.
    pub fn name(self) -> &'static str {
        match self {
            SpeedControl::ConstantSpeed => "constant_speed",
            SpeedControl::Deceleration => "deceleration",
            SpeedControl::QuickDeceleration => "quick_deceleration",
            SpeedControl::DecelerationToZero => "deceleration_to_zero",
            SpeedControl::Acceleration => "acceleration",
            SpeedControl::QuickAcceleration => "quick_acceleration",
        }
    }

    /// Parses [`SpeedControl::name`].
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == s)
    }

    /// Whether the control slows the vehicle (the only ones allowed with `stop`).
    pub fn decelerates(self) -> bool {
        matches!(
            self,
            SpeedControl::Deceleration
                | SpeedControl::QuickDeceleration
                | SpeedControl::DecelerationToZero
        )
    }
}

/// An action: a driving behaviour and a speed control.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Action {
    /// The driving behaviour.
    pub behavior: Behavior,
    /// The speed control.
    pub speed: SpeedControl,
}

impl Action {
    /// The safe fallback: `stop` with `deceleration_to_zero`.
    pub const STOP: Action = Action {
        behavior: Behavior::Stop,
        speed: SpeedControl::DecelerationToZero,
    };
}

impl fmt::Display for Action {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.behavior.name(), self.speed.name())
    }
}

/// What a condition asks of one view (always together with `consistent_deficit`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HazardState {
    /// The view's deficit and traffic-object area ratio is at or below the threshold.
    NoImmediateHazard,
    /// The ratio exceeds the threshold (a hazard near the vehicle), or the view is missing.
    ImmediateHazard,
}

impl HazardState {
    /// The snake-case name used in prompts and answers.
    pub fn name(self) -> &'static str {
        match self {
            HazardState::NoImmediateHazard => "no_immediate_hazard",
            HazardState::ImmediateHazard => "immediate_hazard",
        }
    }

    /// Parses [`HazardState::name`].
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "no_immediate_hazard" => Some(HazardState::NoImmediateHazard),
            "immediate_hazard" => Some(HazardState::ImmediateHazard),
            _ => None,
        }
    }
}

/// An execution condition `C_t`: `consistent_deficit` and, per view, the hazard state that
/// must be observed.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Condition {
    /// The required state of each view.
    pub views: BTreeMap<CameraId, HazardState>,
}

impl fmt::Display for Condition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self
            .views
            .iter()
            .map(|(c, s)| format!("{}={}", c.short(), s.name()))
            .collect();
        write!(f, "consistent_deficit & {}", parts.join(" & "))
    }
}

/// A condition-action pair `(C_t, A_t)`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlanStep {
    /// When the action may run.
    pub condition: Condition,
    /// The action.
    pub action: Action,
}

/// A hazard `[object, motion]` inferred in a deficit region (equation 3).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Hazard {
    /// The object possibly hidden, e.g. `pedestrian`.
    pub object: String,
    /// Its motion, e.g. `crossing paths with the ego vehicle`.
    pub motion: String,
    /// The view of the deficit region, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraId>,
}

/// The planning strategy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Strategy {
    /// Proceed cautiously with a short plan ahead.
    #[serde(rename = "move")]
    Move,
    /// Stop, wait and observe, then move when the move trigger holds.
    #[serde(rename = "stop-observe-move")]
    StopObserveMove,
}

impl Strategy {
    /// The name used in prompts and answers (`move`, `stop-observe-move`).
    pub fn name(self) -> &'static str {
        match self {
            Strategy::Move => "move",
            Strategy::StopObserveMove => "stop-observe-move",
        }
    }
}

/// The hazard inference module's result (equation 4).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct HazardInference {
    /// The hazards, possibly none.
    pub hazards: Vec<Hazard>,
    /// The strategy.
    pub strategy: Strategy,
    /// A short rationale (kept for the record, never interpreted).
    pub rationale: String,
}

impl HazardInference {
    /// No hazard inferred, strategy `move` (the hazard module switched off).
    pub fn none() -> Self {
        Self {
            hazards: Vec::new(),
            strategy: Strategy::Move,
            rationale: "hazard inference is off".into(),
        }
    }
}

/// A stop-observe-move plan: wait, then move when the trigger holds.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StopObserveMove {
    /// Ticks to stand still (1 ..= the wait limit).
    pub wait_steps: u32,
    /// The condition `C_move` under which a new round of motion planning starts.
    pub move_trigger: Condition,
}
