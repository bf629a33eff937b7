//! Integration tests of fogline-rco: the "must show" list of issue 6.

#![allow(clippy::unwrap_used)]

mod controller;
mod mock_server;
mod modules;
mod openai;
mod properties;
mod replay;
mod structured_output;
mod tls;
#[path = "../../../remote/tests/it/tls_support.rs"]
mod tls_support;

use fogline_rco::backend::{Backend, BackendError, Query, Task};
use fogline_rco::{
    Daylight, EgoState, NavDirection, Navigation, Observation, PixelBox, RoadGeometry, RoadLayout,
    Surroundings, TrafficEnv, View, Weather,
};
use fogline_types::clip::CameraId;
use std::sync::{Arc, Mutex};

/// The default views.
pub const VIEWS: [CameraId; 3] = [
    CameraId::CrossLeft,
    CameraId::FrontWide,
    CameraId::CrossRight,
];

/// A clean observation of the three default views (576×320, no pixels) at `tick`.
pub fn clean(tick: u64) -> Observation {
    Observation {
        tick,
        views: VIEWS.iter().map(|&c| View::new(c, 576, 320)).collect(),
        ego: EgoState {
            speed_mps: 5.0,
            accel_x_mps2: 0.0,
            yaw_rate_rps: 0.0,
            follow_distance_m: None,
        },
        navigation: Navigation {
            direction: NavDirection::FollowLane,
            target_x_m: 10.0,
            target_y_m: 0.0,
            road: RoadGeometry {
                layout: RoadLayout::Straight,
                two_way: true,
                lanes: 1,
            },
        },
        surroundings: Surroundings {
            weather: Weather::Clear,
            daylight: Daylight::Day,
            traffic_env: TrafficEnv::Urban,
            traffic_density: 3,
        },
    }
}

/// `obs` with a deficit added to the view of `camera`.
pub fn with_deficit(mut obs: Observation, camera: CameraId, b: PixelBox) -> Observation {
    for v in &mut obs.views {
        if v.camera == camera {
            v.deficits.push(b);
        }
    }
    obs
}

/// A backend answering from a script: per task, a list of answers used in turn (the last
/// one repeats).
#[derive(Debug, Clone, Default)]
pub struct Scripted {
    /// Hazard inference answers.
    pub hazard: Vec<Result<String, BackendError>>,
    /// Move plan answers.
    pub plan: Vec<Result<String, BackendError>>,
    /// Stop-observe-move answers.
    pub som: Vec<Result<String, BackendError>>,
    /// Safety constraint answers.
    pub constraints: Vec<Result<String, BackendError>>,
    /// The tasks asked, in order (shared, to read after the backend moved into a controller).
    pub calls: Arc<Mutex<Vec<Task>>>,
}

fn take(list: &mut Vec<Result<String, BackendError>>) -> Result<String, BackendError> {
    match list.len() {
        0 => Err(BackendError::Protocol("no scripted answer".into())),
        1 => list[0].clone(),
        _ => list.remove(0),
    }
}

impl Backend for Scripted {
    fn describe(&self) -> String {
        "scripted".into()
    }

    fn answer(&mut self, q: &Query<'_>) -> Result<String, BackendError> {
        self.calls.lock().unwrap().push(q.task);
        match q.task {
            Task::HazardInference => take(&mut self.hazard),
            Task::MovePlan => take(&mut self.plan),
            Task::StopObserveMovePlan => take(&mut self.som),
            Task::SafetyConstraints => take(&mut self.constraints),
        }
    }
}

/// A good safety-constraints answer (the paper's example).
pub const GOOD_SC: &str = r#"{"max_speed_kmh": 40, "min_following_distance_s": 3, "max_acceleration_mps2": 1.5, "max_deceleration_mps2": 3.0, "max_yaw_rate_dps": 10, "min_braking_distance_m": 25}"#;

/// A hazard answer with no hazard and strategy `strategy`.
pub fn hazard_answer(strategy: &str) -> String {
    format!(r#"{{"hazards": [], "strategy": "{strategy}", "rationale": "test"}}"#)
}

/// A move plan of `n` identical steps requiring `states` (left, front, right).
pub fn plan_answer(n: usize, states: [&str; 3], behavior: &str, speed: &str) -> String {
    let step = format!(
        r#"{{"conditions": {{"cross_left": "{}", "front_wide": "{}", "cross_right": "{}"}}, "behavior": "{behavior}", "speed": "{speed}"}}"#,
        states[0], states[1], states[2]
    );
    format!(
        r#"{{"steps": [{}], "rationale": "test"}}"#,
        vec![step; n].join(", ")
    )
}

/// A stop-observe-move answer.
pub fn som_answer(wait: u32, states: [&str; 3]) -> String {
    format!(
        r#"{{"wait_steps": {wait}, "move_trigger": {{"cross_left": "{}", "front_wide": "{}", "cross_right": "{}"}}, "rationale": "test"}}"#,
        states[0], states[1], states[2]
    )
}

/// `no_immediate_hazard`.
pub const N: &str = "no_immediate_hazard";
/// `immediate_hazard`.
pub const I: &str = "immediate_hazard";
