//! One route under one configuration: the closed loop at 20 Hz.
//!
//! Every tick (50 ms of game time): the agent's planning step when due (5 Hz by default:
//! render the front-wide and front-tele frames, apply the weather and the deficit, run the
//! planner), the RCO controller's step when due (10 Hz) and a deficit is present in the
//! agent's frames, the control (RCO's while it has taken over, else the baseline's), the
//! bicycle model, the traffic (10 Hz), then every Leaderboard 1.0 criterion.
//!
//! **Frame spacing.** The reference planner reads motion from its last four frames, which it
//! takes to be 0.1 s apart. At an agent rate below 10 Hz the frames are `1/rate` apart; the
//! planner is given the ego history at the same spacing and the ego speed scaled by
//! `0.1 s · rate⁻¹ / 0.1 s`, i.e. it sees a consistently time-lapsed world; the agent scales
//! the perceived speeds back (distances are unaffected). At 10 Hz nothing is scaled.
//!
//! **Time.** Game time advances 50 ms per tick. System time is game time plus the time the
//! agents' queries cost: the RCO backend's measured latency, or a configured latency per
//! LLM call. The run records a timeline (every 0.5 s of game time: route completion, LLM
//! calls, measured latency) and every event's game time, so any game- or system-time limit
//! can be applied afterwards ([`RouteRecord::limited`]): ending a run at a time limit does
//! not change what happened before it.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::Instant;

use fogline_monitor::Monitor;
use fogline_perturb::frame::{Frame, FrameKey};
use fogline_planner::detect::ObjectSeen;
use fogline_planner::perceive::{Lost, ObjectKind};
use fogline_rco::{
    EgoState, NavDirection, Navigation, Observation, PixelBox, Rco, RoadGeometry, RoadLayout,
    Surroundings, TrafficEnv, TrafficObject, View,
};
use fogline_types::clip::{CameraCalib, CameraId, CameraInput, EgoPose};
use fogline_types::odd::OddSpec;
use fogline_types::planner::Planner;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::agent::{AgentInput, AgentParams, Baseline, JunctionAhead};
use crate::config::Config;
use crate::geom::{Obb, P2, dist, dot, sub, within};
use crate::ramp::{
    GuardMode, RAMP_SCENARIOS, Ramp, RampAxis, RampLens, calibrated_monitor, inside, mosaic,
    ramp_scenario, reference_odd,
};
use crate::route::Route;
use crate::score::{
    BlockedMonitor, CollisionFilter, Event, EventKind, OutsideLanesMonitor, RedLightMonitor,
    RouteCompletion, RouteDeviationMonitor, RouteScore, ScoringParams, StopSignMonitor, TimeLimits,
    route_timeout_s,
};
use crate::sense::{Daylight, Lens, PartsCache, Seen, Surround, Weather, look, scene_at, see};
pub use crate::suite::RouteCase;
use crate::town::{Control, LANE_W_M, Light, Town, ZONE_M};
use crate::traffic::{EgoView, Traffic, TrafficParams, ego_box};
use crate::vehicle::{BicycleParams, VehicleControl, VehicleState, step as bike_step};

/// Cameras and rates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorParams {
    /// Image width of every camera, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Horizontal field of view of the front-wide camera, degrees (the cross cameras keep
    /// 120°, the telephoto 30°).
    pub wide_fov_deg: f64,
    /// Agent steps per second (frames, planner, RCO); divides 20.
    pub agent_hz: f64,
    /// Image width of the cross cameras (the RCO controller's side views), px (height
    /// keeps the aspect ratio).
    pub side_width: u32,
    /// Image width of the telephoto camera, px (height keeps the aspect ratio).
    pub tele_width: u32,
}

impl SensorParams {
    /// Width of the telephoto camera.
    pub fn tele_width(&self) -> u32 {
        self.tele_width.clamp(32, 1920)
    }

    /// Height of the telephoto camera.
    pub fn tele_height(&self) -> u32 {
        ((f64::from(self.tele_width()) * f64::from(self.height) / f64::from(self.width)).round()
            as u32)
            .clamp(24, 1080)
    }

    /// Width of the side views.
    pub fn side_width(&self) -> u32 {
        self.side_width.clamp(32, self.width.max(32))
    }

    /// Height of the side views.
    pub fn side_height(&self) -> u32 {
        ((f64::from(self.side_width()) * f64::from(self.height) / f64::from(self.width)).round()
            as u32)
            .max(24)
    }

    /// The closed loop's cameras: the override's views (cross-left, front-wide,
    /// cross-right, see [`crate::sense::rco_cameras`]) and the agent's front-tele camera.
    pub fn cameras(&self) -> ([CameraCalib; 3], CameraCalib) {
        let views = crate::sense::rco_cameras(
            self.width,
            self.height,
            self.wide_fov_deg,
            self.side_width(),
            self.side_height(),
        );
        let tele =
            CameraCalib::standard(CameraId::FrontTele, self.tele_width(), self.tele_height());
        (views, tele)
    }
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            width: 192,
            height: 144,
            wide_fov_deg: 90.0,
            agent_hz: 2.5,
            side_width: 96,
            tele_width: 256,
        }
    }
}

impl SensorParams {
    /// Checks the sizes and rates.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(32..=1920).contains(&self.width) || !(24..=1080).contains(&self.height) {
            return Err(SimError::Params(format!(
                "sensors: image size {}x{} must be within 32x24 ..= 1920x1080",
                self.width, self.height
            )));
        }
        let hz = self.agent_hz;
        let every = TICK_HZ / hz;
        if !(hz.is_finite() && hz > 0.0 && hz <= 10.0 && (every - every.round()).abs() < 1e-9) {
            return Err(SimError::Params(format!(
                "sensors.agent_hz = {hz}: must be at most 10 and divide the simulation rate of 20 Hz"
            )));
        }
        if !(self.wide_fov_deg.is_finite() && (30.0..=150.0).contains(&self.wide_fov_deg)) {
            return Err(SimError::Params(format!(
                "sensors.wide_fov_deg = {}: must be within 30..=150",
                self.wide_fov_deg
            )));
        }
        Ok(())
    }
}

/// Simulation ticks per second.
pub const TICK_HZ: f64 = 20.0;
/// The traffic is updated every this many ticks (5 Hz).
const TRAFFIC_EVERY: u64 = 4;
const DT: f64 = 1.0 / TICK_HZ;
const FRAMES: usize = 4;
/// Ego poses given to the planner: four, the fewest its motion estimate uses, so that its
/// curvature estimate (first to last pose) follows the car through junction turns.
const HISTORY: usize = 4;

/// Everything a run needs besides the route and the configuration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunParams {
    /// Cameras and rates.
    pub sensors: SensorParams,
    /// The baseline agent.
    pub agent: AgentParams,
    /// The ego's dynamics.
    pub bicycle: BicycleParams,
    /// The traffic.
    pub traffic: TrafficParams,
    /// The stop-sign penalty factor (Leaderboard 1.0: 0.8; Longest6's fork: 1.0).
    pub stop_sign_penalty: f64,
}

impl Default for RunParams {
    fn default() -> Self {
        Self {
            sensors: SensorParams::default(),
            agent: AgentParams::default(),
            bicycle: BicycleParams::default(),
            traffic: TrafficParams::default(),
            stop_sign_penalty: 0.8,
        }
    }
}

/// How the run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The route was completed.
    Completed,
    /// Agent blocked.
    AgentBlocked,
    /// Route deviation.
    RouteDeviation,
    /// The route's timeout.
    Timeout,
    /// A game-time limit.
    GameTimeLimit,
    /// A system-time limit.
    SystemTimeLimit,
}

impl Termination {
    fn of(kind: EventKind) -> Self {
        match kind {
            EventKind::AgentBlocked => Self::AgentBlocked,
            EventKind::RouteDeviation => Self::RouteDeviation,
            EventKind::GameTimeLimit => Self::GameTimeLimit,
            EventKind::SystemTimeLimit => Self::SystemTimeLimit,
            _ => Self::Timeout,
        }
    }
}

/// What the ego did at the signals of its route.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SignalStats {
    /// Signalised approaches of the route the ego reached (its stop line crossed or the run
    /// ended within 40 m of it).
    pub approaches: u32,
    /// Approaches where the light was red while the ego was within 40 m of the stop line.
    pub red_encounters: u32,
    /// Of those, approaches where the ego stood still before the line during red.
    pub stopped_at_red: u32,
    /// Stop lines crossed on red (the red-light infractions of the route's approaches).
    pub crossed_on_red: u32,
}

/// The RCO controller's activity in a run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RcoStats {
    /// Its backend.
    pub backend: String,
    /// Ticks it controlled the car.
    pub ticks: u64,
    /// Take-over episodes.
    pub episodes: u32,
    /// LLM (backend) calls.
    pub llm_calls: u64,
    /// Measured backend latency, ms.
    pub llm_latency_ms: f64,
    /// Planning rounds.
    pub replans: u64,
    /// Refused condition-action pairs.
    pub refusals: u64,
    /// Fallbacks (decelerate to a stop and replan), by kind.
    pub fallbacks: BTreeMap<String, u64>,
    /// The first fallback's message, if any.
    pub first_fallback: Option<String>,
}

impl RcoStats {
    /// Total fallbacks.
    pub fn fallbacks_total(&self) -> u64 {
        self.fallbacks.values().sum()
    }
}

/// Everything recorded about one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RouteRecord {
    /// The configuration's name.
    pub config: String,
    /// Route index in the suite.
    pub route: usize,
    /// Town index.
    pub town: usize,
    /// The seed of the run.
    pub seed: u64,
    /// Route length, m.
    pub length_m: f64,
    /// Weather.
    pub weather: Weather,
    /// Daylight.
    pub daylight: Daylight,
    /// Scores (with the route's own timeout, no experiment-wide limit).
    pub score: RouteScore,
    /// How it ended.
    pub termination: Termination,
    /// Game time, s.
    pub game_time_s: f64,
    /// System time with the measured latency, s.
    pub system_time_s: f64,
    /// Average speed: route length driven (RC/100 · length) over game time, m/s.
    pub avg_speed_mps: f64,
    /// Distance the ego drove, m.
    pub odometer_m: f64,
    /// Events in order (infractions, then the one that ended the route, if any).
    pub events: Vec<Event>,
    /// Signal behaviour.
    pub signals: SignalStats,
    /// Game time with a deficit present in the agent's frames, s; in a ramps configuration,
    /// game time with the true condition outside the envelope.
    pub deficit_s: f64,
    /// Game time the RCO controller drove, s.
    pub takeover_s: f64,
    /// The route's condition ramp (ramps configurations).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ramp: Option<Ramp>,
    /// RCO activity (configurations with RCO).
    pub rco: Option<RcoStats>,
    /// Times the baseline's unstick rule fired.
    pub unstick: u32,
    /// Planner calls.
    pub plans: u64,
    /// Planner calls that failed (the agent braked on them): a planner under test that
    /// timed out, could not be reached or answered with an error.
    #[serde(default)]
    pub plan_errors: u64,
    /// Crossing events fired.
    pub crossing_events: usize,
    /// Every 0.5 s of game time: `[game s, route completion %, LLM calls, latency ms]`.
    pub timeline: Vec<[f64; 4]>,
    /// Wall-clock time of the run, s (not deterministic).
    pub wall_s: f64,
    /// Wall-clock time by part: scene + render + lens, planner, RCO, traffic, s (not
    /// deterministic).
    pub wall_parts_s: [f64; 4],
}

/// A time limit applied after the fact.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Limit {
    /// Game-time limit, s.
    pub game_time_s: Option<f64>,
    /// System-time limit, s.
    pub system_time_s: Option<f64>,
    /// Latency counted per LLM call for system time, ms (`None`: the measured latency).
    pub llm_latency_ms: Option<f64>,
}

impl Limit {
    /// No experiment-wide limit.
    pub const NONE: Limit = Limit {
        game_time_s: None,
        system_time_s: None,
        llm_latency_ms: None,
    };
}

impl RouteRecord {
    /// Scores, events and termination as if the run had been limited by `limit`.
    pub fn limited(
        &self,
        limit: &Limit,
        scoring: &ScoringParams,
    ) -> (RouteScore, Vec<Event>, Termination) {
        let system = |p: &[f64; 4]| match limit.llm_latency_ms {
            Some(ms) => p[0] + p[2] * ms / 1000.0,
            None => p[0] + p[3] / 1000.0,
        };
        let cut = self.timeline.iter().position(|p| {
            limit.game_time_s.is_some_and(|l| p[0] > l)
                || limit.system_time_s.is_some_and(|l| system(p) > l)
        });
        let Some(k) = cut else {
            return (self.score, self.events.clone(), self.termination);
        };
        let p = self.timeline[k];
        let kind = if limit.game_time_s.is_some_and(|l| p[0] > l) {
            EventKind::GameTimeLimit
        } else {
            EventKind::SystemTimeLimit
        };
        let t_cut = p[0];
        // Route completion at the last sample within the limit.
        let rc = if k == 0 { 0.0 } else { self.timeline[k - 1][1] };
        let mut events: Vec<Event> = self
            .events
            .iter()
            .filter(|e| e.t_s < t_cut && !e.kind.ends_route())
            .cloned()
            .collect();
        events.push(Event::new(kind, t_cut, f64::NAN, f64::NAN));
        for e in &mut events {
            if e.x_m.is_nan() {
                e.x_m = 0.0;
                e.y_m = 0.0;
            }
        }
        let score = RouteScore::of(rc, &events, scoring);
        (score, events, Termination::of(kind))
    }
}

struct SignalTrack {
    node: usize,
    din: usize,
    s_line: f64,
    reached: bool,
    saw_red: bool,
    stopped: bool,
}

/// Drives `case` under `config`: the closed loop until the route is completed or ended.
pub fn run_route(
    town: &Town,
    case: &RouteCase,
    config: &Config,
    params: &RunParams,
    seed: u64,
) -> Result<RouteRecord, SimError> {
    run_route_with(town, case, config, params, seed, None)
}

/// [`run_route`] with a planner under test in the driver's seat instead of the baseline's
/// rules (`None`: the baseline; see [`Baseline::driven_by`]). Its requests carry the scene
/// id `sim-<seed>-route-<id>` and the run's seed.
pub fn run_route_with(
    town: &Town,
    case: &RouteCase,
    config: &Config,
    params: &RunParams,
    seed: u64,
    driver: Option<&Arc<dyn Planner>>,
) -> Result<RouteRecord, SimError> {
    params.sensors.validate()?;
    params.bicycle.validate()?;
    let wall = Instant::now();
    let route = &case.route;
    let scoring = config.scoring(params.stop_sign_penalty);
    scoring.validate()?;
    let lens = Lens::new(case.weather, config.deficit)?;
    // A ramps configuration: the route's condition ramp, the envelope it is judged by, and
    // the monitor when it drives the guard.
    let mut ramp: Option<RampLens> = config.guard.map(|_| {
        RampLens::new(
            Ramp::for_route(seed, case.id),
            fogline_stats::seed::child(seed, &[case.seed, 0x7a3c]),
        )
    });
    let odd: Option<Arc<OddSpec>> = match (&config.guard, &config.odd) {
        (None, _) => None,
        (Some(_), Some(o)) => Some(Arc::clone(o)),
        (Some(_), None) => Some(Arc::new(reference_odd()?)),
    };
    let mut monitor = match (config.guard, &odd) {
        (Some(GuardMode::Monitor), Some(o)) => Some(
            Monitor::new(
                o,
                RAMP_SCENARIOS[0],
                calibrated_monitor(case.weather, case.daylight, &params.sensors.cameras().0[1])?,
            )
            .map_err(|e| SimError::Params(format!("the guard's monitor: {e}")))?,
        ),
        _ => None,
    };
    // The true condition is outside the envelope (ramps).
    let mut condition_out = false;
    let lk = look(case.weather, case.daylight);
    let cache = PartsCache::new(town);
    let run_seed = fogline_stats::seed::child(seed, &[case.seed, 0x5151]);
    let mut traffic = Traffic::new(town, route, params.traffic, run_seed);
    let mut rco: Option<Rco> = match &config.rco {
        Some(setup) => Some(setup.build(params.sensors.agent_hz)?),
        None => None,
    };
    let mut rco_stats = config.rco.as_ref().map(|s| RcoStats {
        backend: s.backend.describe(),
        ..RcoStats::default()
    });
    let (p0, u0) = route.pose(0.0);
    let mut ego = VehicleState::standing(p0, u0);
    let s = &params.sensors;
    let ([left, wide, right], tele) = s.cameras();
    let agent_every = (TICK_HZ / s.agent_hz).round() as u64;
    let speed_scale = (1.0 / s.agent_hz) / 0.1;
    let mut agent = match driver {
        Some(planner) => Baseline::driven_by(
            params.agent,
            Arc::clone(planner),
            format!("sim-{seed}-route-{}", case.id),
            run_seed,
        ),
        None => Baseline::new(params.agent),
    };
    let mut wide_frames: VecDeque<Frame> = VecDeque::new();
    // The agent's looks to the sides at a stop sign's line: the cross cameras at the
    // front camera's resolution, rendered only while it stands there; the previous pair
    // and when it was taken.
    let looks = [
        CameraCalib::standard(CameraId::CrossLeft, s.width, s.height),
        CameraCalib::standard(CameraId::CrossRight, s.width, s.height),
    ];
    let mut looked: Option<([Frame; 2], f64)> = None;
    let mut tele_frames: VecDeque<Frame> = VecDeque::new();
    let mut history: VecDeque<VehicleState> = VecDeque::new();
    // Criteria.
    let mut completion = RouteCompletion::new();
    let mut deviation = RouteDeviationMonitor::new();
    let mut blocked = BlockedMonitor::default();
    let limits = TimeLimits {
        route_timeout_s: route_timeout_s(route.length_m()),
        game_time_limit_s: None,
        system_time_limit_s: None,
    };
    let mut collisions = CollisionFilter::new();
    let mut red = RedLightMonitor::new();
    let mut stops = StopSignMonitor::new();
    let mut outside = OutsideLanesMonitor::new();
    let mut events: Vec<Event> = Vec::new();
    let mut signals: Vec<SignalTrack> = route
        .junctions
        .iter()
        .filter(|j| j.control == Control::Signal)
        .map(|j| SignalTrack {
            node: j.node,
            din: j.din,
            s_line: j.s_stop_line_m,
            reached: false,
            saw_red: false,
            stopped: false,
        })
        .collect();
    let mut rco_control: Option<VehicleControl> = None;
    let mut deficit_agent = false;
    let mut deficit_side = false;
    // When the override last found a lost region (a new take-over more than 1 s later
    // starts with a reset controller).
    let mut last_present_t = f64::NEG_INFINITY;
    let mut rco_active = false;
    let mut rco_tick: u64 = 0;
    let mut timeline: Vec<[f64; 4]> = Vec::new();
    let mut t = 0.0f64;
    let mut tick: u64 = 0;
    let mut odometer = 0.0;
    let mut deficit_s = 0.0;
    let mut takeover_s = 0.0;
    let mut prev_speed = 0.0;
    let mut prev_yaw = ego.yaw_rad;
    let mut tail_prev = ego.point(-1.2, 0.0);
    let mut route_s = 0.0f64;
    let mut termination = None;
    let mut llm_calls = 0u64;
    let mut llm_ms = 0.0f64;
    let mut parts = [0.0f64; 4];
    let mut was_idle = false;
    loop {
        // ---- Sensing, the agent and the RCO take-over --------------------------------------
        let clock = Instant::now();
        // Standing still with nothing to do, the agent looks four times less often.
        let idle = !rco_active
            && ego.speed_mps < 0.05
            && agent.target_now(odometer) < 0.05
            && !agent.unsticking();
        let every = if idle { 4 * agent_every } else { agent_every };
        if idle != was_idle {
            // The planner's frames must be evenly spaced: start the series again.
            wide_frames.clear();
            tele_frames.clear();
            history.clear();
            was_idle = idle;
        }
        if tick.is_multiple_of(every) {
            let sc = scene_at(town, &traffic, &cache, &ego, t, lk);
            let key = |cam: CameraId| FrameKey::new(case.id as u64, cam.index() as u64, tick);
            let w = see_at(&sc, &wide, &lens, &mut ramp, t, key(CameraId::FrontWide))?;
            let te = see_at(&sc, &tele, &lens, &mut ramp, t, key(CameraId::FrontTele))?;
            deficit_agent = !w.deficits.is_empty() || !te.deficits.is_empty();
            push_frame(&mut wide_frames, w.frame.clone());
            let te_frame = te.frame;
            push_frame(&mut tele_frames, te_frame.clone());
            history.push_back(ego);
            while history.len() > HISTORY {
                history.pop_front();
            }
            parts[0] += clock.elapsed().as_secs_f64();
            // Take-over is decided from pixels: a lost region (black, red outline) in the
            // override's front view, or, once in control, in any of its views. Whoever
            // drives, the override tells the agent which regions of its frames are lost (a
            // walker masked far ahead in the tele view does not hand over, but its outline
            // is no red lamp either).
            let mut present = false;
            if let (Some(mode), Some(r), Some(odd)) =
                (config.guard, ramp.as_ref().map(|l| *l.ramp()), &odd)
            {
                // Ramps: the guard decides from the frames (the monitor), or the true
                // condition does (the oracle), under the envelope of the situation.
                let clock = Instant::now();
                let scenario = ramp_scenario(route, route_s, agent.intent().lead_gap_m);
                let level = r.level(t);
                condition_out = odd.entry(scenario).map_or(level != r.axis.identity(), |e| {
                    !inside(e.threshold(r.axis.name()).as_ref(), r.axis, level)
                });
                present = match mode {
                    GuardMode::None => false,
                    GuardMode::Oracle => condition_out,
                    GuardMode::Always => level != r.axis.identity(),
                    GuardMode::Monitor => match monitor.as_mut() {
                        Some(m) => {
                            // A situation without an entry keeps the one in use.
                            let _ = m.set_scenario(scenario);
                            // The three ground-level cameras as one mosaic: a global
                            // condition darkens, fogs or noises all of them, a dark car
                            // filling one view shifts a third of the pixels.
                            let [l, r_] = &looks;
                            let sides = [
                                see_at(&sc, l, &lens, &mut ramp, t, key(l.id))?.frame,
                                see_at(&sc, r_, &lens, &mut ramp, t, key(r_.id))?.frame,
                            ];
                            let (px, mw, mh) = mosaic(&[&w.frame, &sides[0], &sides[1]]);
                            let rec = m.step_frame(&px, mw, mh).map_err(|e| {
                                SimError::Params(format!("the guard's monitor: {e}"))
                            })?;
                            if log::log_enabled!(log::Level::Trace) {
                                log::trace!(
                                    "monitor t {t:.1} {scenario} {} {:?} {} {level}",
                                    rec.in_envelope,
                                    rec.axes
                                        .iter()
                                        .map(|a| (
                                            a.axis.as_str(),
                                            a.estimate.map(|e| (e * 100.0).round() / 100.0),
                                            (a.bound * 100.0).round() / 100.0
                                        ))
                                        .collect::<Vec<_>>(),
                                    r.axis.name()
                                );
                            }
                            if rec.switched && log::log_enabled!(log::Level::Debug) {
                                log::debug!(
                                    "guard route {} t {t:.1} {scenario}: {} ({}; {} {level})",
                                    case.id,
                                    if rec.in_envelope { "in" } else { "out" },
                                    rec.reason,
                                    r.axis.name()
                                );
                            }
                            !rec.in_envelope
                        }
                        None => false,
                    },
                };
                parts[2] += clock.elapsed().as_secs_f64();
            } else if rco.is_some() {
                let clock = Instant::now();
                let lost = lost_in(&[(&wide, &w.frame), (&tele, &te_frame)]);
                let wide_lost = lost.iter().any(|(c, _)| *c == CameraId::FrontWide);
                present = wide_lost || (rco_active && deficit_side);
                if present && log::log_enabled!(log::Level::Trace) {
                    log::trace!("lost t {t:.1}: {lost:?}");
                }
                agent.set_lost(lost);
                parts[2] += clock.elapsed().as_secs_f64();
            }
            // The agent plans on its frames at every step, whoever drives: while the
            // override is in control it still keeps its distance, stops for lights and signs
            // it sees, and the override's command only ever makes it more cautious.
            {
                let clock = Instant::now();
                let nav_kappa = route_kappa(route, route_s, &ego);
                let hist = rig_history(&history, speed_scale, nav_kappa);
                let turn_cap = turn_cap(route, route_s, &params.agent);
                let cams = vec![
                    CameraInput {
                        calib: wide,
                        frames: wide_frames.iter().map(|f| f.data()).collect(),
                    },
                    CameraInput {
                        calib: tele,
                        frames: tele_frames.iter().map(|f| f.data()).collect(),
                    },
                ];
                agent.plan(
                    AgentInput {
                        cameras: cams,
                        history: &hist,
                        time_s: t,
                        nav_kappa,
                        junction: route.next_junction(route_s).map(|j| JunctionAhead {
                            entry_m: j.s_entry_m - route_s,
                            left_turn: j.turn() == 1,
                        }),
                    },
                    ego.speed_mps,
                    turn_cap,
                    odometer,
                    speed_scale,
                );
                parts[1] += clock.elapsed().as_secs_f64();
            }
            if agent.wants_look(ego.speed_mps, odometer) {
                let clock = Instant::now();
                let [l, r] = &looks;
                let now = [
                    see_at(&sc, l, &lens, &mut ramp, t, key(l.id))?.frame,
                    see_at(&sc, r, &lens, &mut ramp, t, key(r.id))?.frame,
                ];
                let moved = looked.as_ref().map(|(before, _)| {
                    looks
                        .iter()
                        .zip(before.iter().zip(now.iter()))
                        .flat_map(|(c, (b, n))| {
                            // Both frames come from the same calibration, so the sizes agree.
                            fogline_planner::detect::movers(b.data(), n.data(), c)
                                .unwrap_or_default()
                        })
                        .collect::<Vec<_>>()
                });
                // The time the two looks span (0.4 s at 2.5 Hz; 1.6 s while the car stands
                // with nothing to do, when the agent looks four times less often).
                let span = looked.as_ref().map_or(0.0, |(_, at)| t - at);
                agent.look(moved.as_deref(), span);
                looked = Some((now, t));
                parts[1] += clock.elapsed().as_secs_f64();
            } else {
                looked = None;
            }
            if log::log_enabled!(log::Level::Trace) {
                trace_truth(t, &ego, &traffic);
            }
            match rco.as_mut() {
                Some(ctl) => {
                    let clock = Instant::now();
                    if present {
                        if !rco_active {
                            if t - last_present_t > 1.0 {
                                ctl.reset();
                            }
                            rco_active = true;
                            if let Some(st) = rco_stats.as_mut() {
                                st.episodes += 1;
                            }
                        }
                        let views_seen = [
                            (
                                left,
                                see_at(&sc, &left, &lens, &mut ramp, t, key(CameraId::CrossLeft))?
                                    .frame,
                            ),
                            (wide, w.frame.clone()),
                            (
                                right,
                                see_at(
                                    &sc,
                                    &right,
                                    &lens,
                                    &mut ramp,
                                    t,
                                    key(CameraId::CrossRight),
                                )?
                                .frame,
                            ),
                        ];
                        let mut views: Vec<View> = views_seen
                            .iter()
                            .map(|(calib, frame)| pixel_view(calib, frame, agent.objects()))
                            .collect();
                        if ramp.is_some() {
                            // Global degradation: each view is one lost region, whole.
                            for v in &mut views {
                                v.deficits = vec![PixelBox::new(
                                    0.0,
                                    0.0,
                                    f64::from(v.width),
                                    f64::from(v.height),
                                )];
                            }
                        }
                        deficit_side = views
                            .iter()
                            .any(|v| v.camera != CameraId::FrontWide && !v.deficits.is_empty());
                        let mut obs = observation(
                            rco_tick,
                            views,
                            &ego,
                            prev_speed,
                            prev_yaw,
                            1.0 / s.agent_hz,
                            route,
                            route_s,
                            town,
                            case,
                            agent.intent().lead_gap_m,
                            agent.objects().len(),
                        );
                        if let Some(lens) = ramp.as_ref() {
                            // The degraded axis is what the override is told of the
                            // surroundings, as the guard does.
                            match lens.ramp().axis {
                                RampAxis::Fog => {
                                    obs.surroundings.weather = fogline_rco::Weather::Fog
                                }
                                RampAxis::Darken => {
                                    obs.surroundings.daylight = fogline_rco::Daylight::Night;
                                }
                                RampAxis::GaussianNoise => {}
                            }
                        }
                        rco_tick += 1;
                        let d = ctl.step(&obs);
                        if log::log_enabled!(log::Level::Trace) {
                            log::trace!("rco t {t:.1} v {:.2}: {}", ego.speed_mps, d.summary());
                        }
                        agent.set_hidden_signal(d.hazards.iter().any(|h| {
                            h.camera.is_some_and(|c| c.yaw_rad() == 0.0)
                                && fogline_rco::is_signal_object(&h.object)
                        }));
                        if let Some(st) = rco_stats.as_mut() {
                            st.llm_calls += u64::from(d.counters.llm_calls);
                            st.llm_latency_ms += d.counters.llm_latency_ms;
                            llm_calls += u64::from(d.counters.llm_calls);
                            llm_ms += d.counters.llm_latency_ms;
                            st.replans += u64::from(d.replanned);
                            st.refusals += u64::from(d.refusal.is_some());
                            if let Some(f) = &d.fallback {
                                let kind = serde_json::to_value(f.kind)
                                    .ok()
                                    .and_then(|v| v.as_str().map(str::to_string))
                                    .unwrap_or_else(|| "fallback".into());
                                *st.fallbacks.entry(kind).or_default() += 1;
                                if st.first_fallback.is_none() {
                                    st.first_fallback = Some(f.message.clone());
                                }
                            }
                        }
                        rco_control = Some(VehicleControl {
                            throttle: d.control.throttle,
                            brake: d.control.brake,
                            steer: d.control.steer,
                        });
                    } else {
                        rco_active = false;
                        rco_control = None;
                        deficit_side = false;
                        agent.set_hidden_signal(false);
                    }
                    parts[2] += clock.elapsed().as_secs_f64();
                }
                None => {
                    rco_active = false;
                    rco_control = None;
                }
            }
            if present {
                last_present_t = t;
            }
            prev_speed = ego.speed_mps;
            prev_yaw = ego.yaw_rad;
        }
        if (ramp.is_none() && (deficit_agent || (rco_active && deficit_side)))
            || (ramp.is_some() && condition_out)
        {
            deficit_s += DT;
        }
        // ---- Control and dynamics -------------------------------------------------------
        let base = agent.control(
            &ego,
            &route.dense,
            completion.index(),
            DT,
            odometer,
            &params.bicycle,
        );
        let control = match (rco_active, rco_control) {
            (true, Some(c)) => {
                takeover_s += DT;
                if let Some(st) = rco_stats.as_mut() {
                    st.ticks += 1;
                }
                supervise(base, c)
            }
            _ => base,
        };
        let before = ego;
        ego = bike_step(&params.bicycle, &ego, control);
        odometer += dist([before.x_m, before.y_m], [ego.x_m, ego.y_m]);
        t += DT;
        tick += 1;
        let ev = EgoView {
            state: ego,
            route_s_m: route_s,
        };
        let clock = Instant::now();
        if tick.is_multiple_of(TRAFFIC_EVERY) {
            traffic.step(town, route, &ev, t, TRAFFIC_EVERY as f64 * DT);
        }
        if tick.is_multiple_of(20) {
            traffic.refill(town, route, &ev);
        }
        parts[3] += clock.elapsed().as_secs_f64();
        // ---- Criteria -------------------------------------------------------------------
        let pos = [ego.x_m, ego.y_m];
        let rc = completion.update(&route.dense, pos);
        route_s = route.dense.accum[completion.index()];
        let ebox = ego_box(&ego);
        collisions.tick(ebox.c);
        for n in &traffic.npcs {
            if within(n.pos, ebox.c, 8.0)
                && ebox.overlaps(&n.obb())
                && collisions.contact(n.id, ebox.c, t)
            {
                if log::log_enabled!(log::Level::Debug) {
                    debug_collision(
                        t,
                        &format!("vehicle {}", n.id),
                        &ego,
                        n.pos,
                        n.speed_mps,
                        (&agent, rco_active),
                    );
                }
                let mut e = Event::new(EventKind::CollisionVehicle, t, n.pos[0], n.pos[1]);
                e.actor = Some(n.id);
                events.push(e);
            }
        }
        for w in &traffic.walkers {
            if within(w.pos, ebox.c, 6.0)
                && ebox.overlaps(&w.obb())
                && collisions.contact(w.id, ebox.c, t)
            {
                // A bicycle is a vehicle in CARLA; a walker is a pedestrian.
                let kind = if w.cyclist {
                    EventKind::CollisionVehicle
                } else {
                    EventKind::CollisionPedestrian
                };
                if log::log_enabled!(log::Level::Debug) {
                    // Which way it walked relative to the car: across to its left or
                    // right, or along.
                    let across = (w.yaw - ego.yaw_rad).sin();
                    let way = if across > 0.5 {
                        "to the left"
                    } else if across < -0.5 {
                        "to the right"
                    } else {
                        "along"
                    };
                    let what = format!("{kind:?} walker {} event {} walking {way}", w.id, w.event);
                    debug_collision(t, &what, &ego, w.pos, w.speed_mps, (&agent, rco_active));
                }
                let mut e = Event::new(kind, t, w.pos[0], w.pos[1]);
                e.actor = Some(w.id);
                events.push(e);
            }
        }
        for (k, b) in town.buildings.iter().enumerate() {
            if within(b.obb.c, ebox.c, b.obb.hl + 6.0)
                && ebox.overlaps(&b.obb)
                && collisions.contact(500_000 + k as u64, ebox.c, t)
            {
                events.push(Event::new(EventKind::CollisionLayout, t, pos[0], pos[1]));
            }
        }
        for (id, p, r) in town
            .lights
            .iter()
            .map(|l| (l.id, l.pos, 0.15))
            .chain(town.signs.iter().map(|s| (s.id, s.pos, 0.1)))
        {
            if within(p, ebox.c, 5.0)
                && ebox.overlaps_disc(p, r)
                && collisions.contact(id, ebox.c, t)
            {
                events.push(Event::new(EventKind::CollisionLayout, t, p[0], p[1]));
            }
        }
        // Red lights: every signalised approach near the ego.
        let tail = ego.point(-1.2, 0.0);
        for l in &town.lights {
            let line = town.stop_line(l.node, l.din);
            if !within(line.centre(), tail, 20.0) {
                continue;
            }
            let is_red = town.light(l.node, l.din, t) == Light::Red;
            if red.check(l.id, &line, is_red, tail_prev, tail, ego.heading()) {
                events.push(Event::new(EventKind::RedLight, t, pos[0], pos[1]));
            }
        }
        tail_prev = tail;
        // Stop signs: the front bumper inside an approach's area (6 m before the line to
        // 2 m past it, across the lane).
        let front = ego.point(3.7, 0.0);
        let area = town.signs.iter().find_map(|sg| {
            let c = town.stop_line_centre(sg.node, sg.din);
            let u = crate::town::DIRS[sg.din];
            let d = sub(front, c);
            let along = dot(d, u);
            let across = -u[1] * d[0] + u[0] * d[1];
            ((-6.0..=2.0).contains(&along) && across.abs() <= LANE_W_M / 2.0).then_some(sg.id)
        });
        if let Some(id) = stops.update(area, ego.speed_mps) {
            let mut e = Event::new(EventKind::StopSign, t, pos[0], pos[1]);
            e.actor = Some(id);
            events.push(e);
        }
        // Signal behaviour on the route's approaches.
        for sg in &mut signals {
            let before_line = sg.s_line - route_s;
            if (0.0..=40.0).contains(&before_line) {
                sg.reached = true;
                let is_red = town.light(sg.node, sg.din, t) == Light::Red;
                sg.saw_red |= is_red;
                sg.stopped |= is_red && ego.speed_mps < 0.1;
            }
        }
        // Outside the route's lanes: more than 2.5 m from the route's lane centre.
        let (_, lat) = route
            .path
            .project(pos, (route_s - 5.0).max(0.0), route_s + 10.0);
        outside.update(&route.dense, completion.index(), lat.abs() > 2.5);
        if tick.is_multiple_of(10) {
            timeline.push([t, rc, llm_calls as f64, llm_ms]);
        }
        if tick.is_multiple_of(20) && log::log_enabled!(log::Level::Trace) {
            let i = agent.intent();
            log::trace!(
                "t {t:6.1} s {route_s:7.1} lat {:+.2} dyaw {:+.2} v {:5.2} target {:5.2}/{:5.2} {:?} deficit {} rco {} ctl {:.2}/{:.2}/{:+.2} | {}",
                route
                    .path
                    .project(pos, (route_s - 5.0).max(0.0), route_s + 10.0)
                    .1,
                {
                    let (_, u) = route.pose(route_s);
                    crate::vehicle::wrap_angle(ego.yaw_rad - u[1].atan2(u[0]))
                },
                ego.speed_mps,
                i.target_mps,
                agent.target_now(odometer),
                i.decision,
                deficit_agent,
                rco_active,
                control.throttle,
                control.brake,
                control.steer,
                agent.debug
            );
        }
        // ---- Termination ----------------------------------------------------------------
        if completion.completed() {
            termination = Some(Termination::Completed);
        } else if blocked.update(t, ego.speed_mps) {
            events.push(Event::new(EventKind::AgentBlocked, t, pos[0], pos[1]));
            termination = Some(Termination::AgentBlocked);
        } else if deviation.update(&route.dense, pos) {
            events.push(Event::new(EventKind::RouteDeviation, t, pos[0], pos[1]));
            termination = Some(Termination::RouteDeviation);
        } else if let Some(kind) = limits.check(t, t + llm_ms / 1000.0) {
            events.push(Event::new(kind, t, pos[0], pos[1]));
            termination = Some(Termination::of(kind));
        }
        if termination.is_some() {
            break;
        }
    }
    timeline.push([t, completion.percent(), llm_calls as f64, llm_ms]);
    let pct = outside.percent(&route.dense);
    if pct > 0.0 {
        let mut e = Event::new(EventKind::OutsideRouteLanes, t, ego.x_m, ego.y_m);
        e.percent = Some(pct);
        // Before the terminating event, if any (infractions first).
        let at = events
            .iter()
            .position(|e| e.kind.ends_route())
            .unwrap_or(events.len());
        events.insert(at, e);
    }
    let rc = completion.percent();
    let score = RouteScore::of(rc, &events, &scoring);
    let mut sig = SignalStats::default();
    for sg in &signals {
        if sg.reached {
            sig.approaches += 1;
            sig.red_encounters += u32::from(sg.saw_red);
            sig.stopped_at_red += u32::from(sg.saw_red && sg.stopped);
        }
    }
    sig.crossed_on_red = events
        .iter()
        .filter(|e| e.kind == EventKind::RedLight)
        .count() as u32;
    Ok(RouteRecord {
        config: config.name.clone(),
        route: case.id,
        town: case.town,
        seed,
        length_m: route.length_m(),
        weather: case.weather,
        daylight: case.daylight,
        score,
        termination: termination.unwrap_or(Termination::Timeout),
        game_time_s: t,
        system_time_s: t + llm_ms / 1000.0,
        avg_speed_mps: rc / 100.0 * route.length_m() / t.max(1e-9),
        odometer_m: odometer,
        events,
        signals: sig,
        deficit_s,
        takeover_s,
        ramp: ramp.as_ref().map(|l| *l.ramp()),
        rco: rco_stats,
        unstick: agent.unstick_count,
        plans: agent.plans,
        plan_errors: agent.plan_errors,
        crossing_events: traffic.events_fired(),
        timeline,
        wall_s: wall.elapsed().as_secs_f64(),
        wall_parts_s: parts,
    })
}

/// [`see`], then the run's condition ramp at game time `t`, when it has one.
fn see_at(
    sc: &Surround,
    calib: &CameraCalib,
    lens: &Lens,
    ramp: &mut Option<RampLens>,
    t: f64,
    key: FrameKey,
) -> Result<Seen, SimError> {
    let mut seen = see(sc, calib, lens, key);
    if let Some(r) = ramp.as_mut() {
        seen.frame = r.apply(seen.frame, t, key)?;
    }
    Ok(seen)
}

fn push_frame(q: &mut VecDeque<Frame>, f: Frame) {
    q.push_back(f);
    while q.len() > FRAMES {
        q.pop_front();
    }
}

/// The ego history in the rig frame now, oldest first, at the agent's spacing (labelled
/// 0.1 s apart, speeds scaled by `speed_scale`). Positions are the true ones; the headings
/// carry the navigation: the planner reads its path curvature from the history (first to
/// last heading over the path length), so the headings are set to the curvature of the arc
/// that reaches the route [`NAV_AHEAD_M`] ahead — the baseline's only route input besides
/// the steering target, as TransFuser is conditioned on its target point.
fn rig_history(h: &VecDeque<VehicleState>, speed_scale: f64, nav_kappa: f64) -> Vec<EgoPose> {
    let Some(now) = h.back() else {
        return Vec::new();
    };
    let (s, c) = now.yaw_rad.sin_cos();
    let n = h.len();
    // Path length from each pose to the last.
    let mut to_end = vec![0.0; n];
    for k in (0..n.saturating_sub(1)).rev() {
        let (a, b) = (&h[k], &h[k + 1]);
        to_end[k] = to_end[k + 1] + (b.x_m - a.x_m).hypot(b.y_m - a.y_m);
    }
    h.iter()
        .enumerate()
        .map(|(k, p)| {
            let (dx, dy) = (p.x_m - now.x_m, p.y_m - now.y_m);
            EgoPose {
                t_s: -0.1 * (n - 1 - k) as f64,
                x_m: c * dx + s * dy,
                y_m: -s * dx + c * dy,
                yaw_rad: -nav_kappa * to_end[k],
                speed_mps: p.speed_mps * speed_scale,
            }
        })
        .collect()
}

/// Distance to the route point the navigation curvature aims at, m.
pub const NAV_AHEAD_M: f64 = 8.0;

/// The curvature of the arc from the ego (its heading) to the route point
/// [`NAV_AHEAD_M`] ahead (pure pursuit; 1/m, left positive).
fn route_kappa(route: &Route, s: f64, ego: &VehicleState) -> f64 {
    let (p, _) = route.pose(s + NAV_AHEAD_M);
    let h = ego.heading();
    let d = sub(p, [ego.x_m, ego.y_m]);
    let x = dot(d, h);
    let y = -h[1] * d[0] + h[0] * d[1];
    2.0 * y / (x * x + y * y).max(1.0)
}

/// The speed cap before the route's next turn.
fn turn_cap(route: &Route, s: f64, p: &AgentParams) -> f64 {
    let Some(j) = route.next_junction(s) else {
        return f64::INFINITY;
    };
    let v_turn = match j.turn() {
        1 => p.left_turn_mps,
        3 => p.right_turn_mps,
        _ => return f64::INFINITY,
    };
    let d = (j.s_entry_m - s).max(0.0);
    (v_turn * v_turn + 2.0 * p.turn_decel_mps2 * d).sqrt()
}

/// The override's command applied to the agent's: per pedal the more cautious of the two
/// (the lower throttle, the harder brake), the agent's steering (both follow the route).
/// The override can slow the car down, hold it or stop it; it never makes it faster than
/// the agent would drive, so the agent's own stops (the car ahead, a red light, a walker
/// it sees) stay in force while the override is in control.
pub fn supervise(agent: VehicleControl, rco: VehicleControl) -> VehicleControl {
    VehicleControl {
        throttle: agent.throttle.min(rco.throttle),
        brake: agent.brake.max(rco.brake),
        steer: agent.steer,
    }
}

/// The lost regions the perception finds in a frame (black inside a red outline), from its
/// pixels alone.
fn lost_regions(frame: &Frame) -> Vec<fogline_planner::detect::DeficitSeen> {
    // A frame always has the size its calibration gives, so the scan cannot fail; an error
    // would mean nothing was found.
    fogline_planner::detect::find_deficits(
        frame.data(),
        frame.width() as usize,
        frame.height() as usize,
    )
    .unwrap_or_default()
}

/// The lost regions the perception finds in each camera's frame, as the planner takes
/// them (camera, pixel box `[x0, y0, x1, y1]`).
pub fn lost_in(views: &[(&CameraCalib, &Frame)]) -> Vec<Lost> {
    views
        .iter()
        .flat_map(|(calib, frame)| {
            lost_regions(frame).into_iter().map(|d| {
                (
                    calib.id,
                    [
                        f64::from(d.x0),
                        f64::from(d.y0),
                        f64::from(d.x1),
                        f64::from(d.y1),
                    ],
                )
            })
        })
        .collect()
}

/// One view of the override's observation, from pixels only: the frame, the lost regions
/// found in it, the road users the agent's perception found in it (no track ids: the
/// override tracks them itself), and the camera's calibration.
pub fn pixel_view(calib: &CameraCalib, frame: &Frame, objects: &[ObjectSeen]) -> View {
    View {
        camera: calib.id,
        width: frame.width(),
        height: frame.height(),
        rgb: Some(Arc::from(frame.data())),
        deficits: lost_regions(frame)
            .iter()
            .map(|d| {
                PixelBox::new(
                    f64::from(d.x0),
                    f64::from(d.y0),
                    f64::from(d.x1 - d.x0),
                    f64::from(d.y1 - d.y0),
                )
            })
            .collect(),
        objects: objects
            .iter()
            .filter(|o| o.camera == calib.id)
            .map(|o| TrafficObject {
                class: match o.seen.kind {
                    ObjectKind::Vehicle => "car".into(),
                    ObjectKind::Person => "pedestrian".into(),
                },
                track_id: None,
                rect: PixelBox::new(
                    o.bbox[0],
                    o.bbox[1],
                    o.bbox[2] - o.bbox[0],
                    o.bbox[3] - o.bbox[1],
                ),
            })
            .collect(),
        calib: Some(*calib),
    }
}

/// The RCO observation of this tick: the views (from [`pixel_view`]), the ego's
/// measurements and route, the case's weather and daylight, and `density` road users the
/// agent detected.
#[allow(clippy::too_many_arguments)]
fn observation(
    tick: u64,
    views: Vec<View>,
    ego: &VehicleState,
    prev_speed: f64,
    prev_yaw: f64,
    dt: f64,
    route: &Route,
    route_s: f64,
    town: &Town,
    case: &RouteCase,
    lead_gap: Option<f64>,
    density: usize,
) -> Observation {
    let (target, _) = route.pose(route_s + 10.0);
    let h = ego.heading();
    let d = sub(target, [ego.x_m, ego.y_m]);
    let direction = match route.next_junction(route_s) {
        Some(j) if j.s_entry_m - route_s < 25.0 => match j.turn() {
            1 => NavDirection::Left,
            3 => NavDirection::Right,
            _ => NavDirection::Straight,
        },
        _ => NavDirection::FollowLane,
    };
    let near_node = town
        .nodes
        .iter()
        .any(|n| dist(n.pos, [ego.x_m, ego.y_m]) < ZONE_M + 2.0);
    Observation {
        tick,
        views,
        ego: EgoState {
            speed_mps: ego.speed_mps,
            accel_x_mps2: (ego.speed_mps - prev_speed) / dt,
            yaw_rate_rps: crate::vehicle::wrap_angle(ego.yaw_rad - prev_yaw) / dt,
            follow_distance_m: lead_gap,
        },
        navigation: Navigation {
            direction,
            target_x_m: dot(d, h),
            target_y_m: -h[1] * d[0] + h[0] * d[1],
            road: RoadGeometry {
                layout: if near_node {
                    RoadLayout::Junction
                } else {
                    RoadLayout::Straight
                },
                two_way: true,
                lanes: 1,
            },
        },
        surroundings: Surroundings {
            weather: case.weather.rco(),
            daylight: case.daylight.rco(),
            traffic_env: TrafficEnv::Urban,
            traffic_density: density as u32,
        },
    }
}

/// Trace lines of the ground truth around the ego (vehicles and walkers ahead), for
/// reading a `-vv` log next to what the agent perceived.
fn trace_truth(t: f64, ego: &VehicleState, traffic: &Traffic) {
    for n in &traffic.npcs {
        let (ax, ay) = ego_frame(ego, n.pos);
        if (0.0..90.0).contains(&ax) && ay.abs() < 20.0 {
            log::trace!(
                "truth t {t:.1} npc {} at {ax:.1} {ay:+.1} v {:.1} a {:.1}",
                n.id,
                n.speed_mps,
                n.accel_mps2
            );
        }
    }
    for w in &traffic.walkers {
        let (ax, ay) = ego_frame(ego, w.pos);
        if (3.0..45.0).contains(&ax) && (-4.0..8.0).contains(&ay) {
            log::trace!(
                "truth t {t:.1} walker {} event {} at {ax:.1} {ay:+.1} moving {:.1}",
                w.id,
                w.event,
                w.speed_mps
            );
        }
    }
}

/// Whether `obb` overlaps any building of `town` (for tests of the layout).
pub fn hits_building(town: &Town, obb: &Obb) -> bool {
    town.buildings.iter().any(|b| b.obb.overlaps(obb))
}

/// `p` in the ego's frame: metres ahead of and left of its rear axle.
fn ego_frame(ego: &VehicleState, p: P2) -> (f64, f64) {
    let h = ego.heading();
    let d = sub(p, ego.point(0.0, 0.0));
    (dot(d, h), -h[1] * d[0] + h[0] * d[1])
}

/// A debug line for a collision: who, the speeds, where the other was, what the agent meant
/// to do (for tracing why it happened).
/// `driver`: the agent, and whether the override was in control.
fn debug_collision(
    t: f64,
    what: &str,
    ego: &VehicleState,
    at: P2,
    speed: f64,
    driver: (&Baseline, bool),
) {
    let (ahead, left) = ego_frame(ego, at);
    let i = driver.0.intent();
    log::debug!(
        "collision t {t:.1} {what} v {:.2} other v {speed:.2} at ahead {ahead:+.2} left {left:+.2} target {:.2} {:?} lead gap {:?} rco {}",
        ego.speed_mps,
        i.target_mps,
        i.decision,
        i.lead_gap_m,
        driver.1
    );
}
