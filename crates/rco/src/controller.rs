//! The plan/act loop of equations 1–2 and the decision of every tick.
//!
//! Every tick ([`Rco::step`]):
//!
//! 1. The observation is validated (an invalid one gets the fallback) and joins the history
//!    of the last `history_frames` observations.
//! 2. The verifier assesses it: per-view hazard states, consistency with the previous tick.
//! 3. Every `safety.refresh_ticks` ticks the safety constraints are asked for again.
//! 4. **Act**: the head `(C_t, A_t)` of the sequence `S_t` is verified — consistent deficits
//!    (no change since the previous tick, same counts as when the plan was made; a plan made
//!    this tick is consistent by construction) and every view in the state `C_t` names. If it
//!    holds, `A_t` runs and leaves the sequence (equation 2). Wait steps of a
//!    stop-observe-move (standing still) run unchecked; its final move trigger, once it holds, starts
//!    a new round of motion planning (`move`), and while it does not the ego holds still
//!    (after `max_hold_ticks` a full replan).
//! 5. **Plan** when `S_t` is empty or the verifier refused (equation 1): hazard inference
//!    (equation 4), then the short-term motion planner (equation 5). At most one planning
//!    round per tick: if the fresh plan's head is refused as well, the tick falls back.
//! 6. The action becomes a control (table 4, steering PID), then the safety constraints
//!    transform it (equations 7–10).
//!
//! **Fallback** (any backend error or timeout, any answer rejected by validation, a fresh
//! plan refused at once, an invalid observation): the action is `stop` +
//! `deceleration_to_zero` (throttle 0, brake 0.8, then the safety constraints), the sequence
//! is emptied so the next tick replans, and the decision says why. A failed safety-constraint
//! query also installs [`SafetyConstraints::conservative`] until the next refresh.
//!
//! **Module switches** (the ablation of table 3): without hazard inference the planner is
//! told the hazard is unknown and the strategy is `move`; without the motion planner the
//! plan is one built-in step (the observed states, the route's behaviour — lane changes
//! become `move_forward` —, `constant_speed`) or, under stop-observe-move, a wait of
//! `min(10, wait_limit)` ticks and a trigger of clear front views; without the verifier
//! every step runs unchecked until the sequence is empty; without the safety constraints the
//! control is not transformed.

use std::collections::{BTreeMap, VecDeque};
use std::time::Instant;

use fogline_types::clip::CameraId;
use serde::{Deserialize, Serialize};

use crate::RcoError;
use crate::action::{
    Action, Behavior, Condition, Hazard, HazardInference, HazardState, SpeedControl, Strategy,
};
use crate::backend::answer::{self, AnswerError};
use crate::backend::rules::RulesBackend;
use crate::backend::{Backend, BackendError, Query, QueryContext, Task, prompt};
use crate::control::{Control, PidParams, SteerPid, pedals};
use crate::observation::{NavDirection, Observation};
use crate::safety::{self, SafetyConstraints, SafetyParams, Triggers};
use crate::verifier::{self, Assessment, Refusal, VerifierParams, ViewAssessment};

/// Which modules run (table 3's ablation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct Modules {
    /// HI: hazard inference.
    pub hazard_inference: bool,
    /// ST: the short-term motion planner.
    pub motion_planner: bool,
    /// AV: the action condition verifier.
    pub verifier: bool,
    /// SC: the safety constraint generator.
    pub safety_constraints: bool,
}

impl Default for Modules {
    fn default() -> Self {
        Self {
            hazard_inference: true,
            motion_planner: true,
            verifier: true,
            safety_constraints: true,
        }
    }
}

impl Modules {
    /// Parses a comma-separated list of the modules that are on: `hi,st,av,sc` (all),
    /// `none`, or any subset.
    pub fn parse(list: &str) -> Result<Self, RcoError> {
        let mut m = Modules {
            hazard_inference: false,
            motion_planner: false,
            verifier: false,
            safety_constraints: false,
        };
        for part in list.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match part.to_ascii_lowercase().as_str() {
                "hi" => m.hazard_inference = true,
                "st" => m.motion_planner = true,
                "av" => m.verifier = true,
                "sc" => m.safety_constraints = true,
                "none" => {}
                other => {
                    return Err(RcoError::Params(format!(
                        "unknown module {other:?} (hi, st, av, sc or none)"
                    )));
                }
            }
        }
        Ok(m)
    }
}

/// Settings of the controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RcoParams {
    /// The views used, in order (default: cross-left, front-wide, cross-right).
    pub views: Vec<CameraId>,
    /// `k + 1`: observations kept for hazard inference (the paper's clips have 5 frames).
    pub history_frames: usize,
    /// The largest number of steps of a move plan (the paper's planning length limit).
    pub plan_limit: usize,
    /// The largest wait of a stop-observe-move plan, ticks.
    pub wait_limit: u32,
    /// Ticks to hold still while a move trigger does not hold before a full replan.
    pub max_hold_ticks: u32,
    /// The most images in one query (the newest are kept).
    pub max_images: usize,
    /// Seconds per tick (the PID's time step).
    pub dt_s: f64,
    /// Module switches.
    pub modules: Modules,
    /// The verifier.
    pub verifier: VerifierParams,
    /// The safety constraint module.
    pub safety: SafetyParams,
    /// The steering PID.
    pub steer: PidParams,
}

impl Default for RcoParams {
    fn default() -> Self {
        Self {
            views: vec![
                CameraId::CrossLeft,
                CameraId::FrontWide,
                CameraId::CrossRight,
            ],
            history_frames: 5,
            plan_limit: 5,
            wait_limit: 30,
            max_hold_ticks: 50,
            max_images: 15,
            dt_s: 0.1,
            modules: Modules::default(),
            verifier: VerifierParams::default(),
            safety: SafetyParams::default(),
            steer: PidParams::default(),
        }
    }
}

impl RcoParams {
    /// Checks every setting; the error names the field.
    pub fn validate(&self) -> Result<(), RcoError> {
        let bad = |m: String| Err(RcoError::Params(m));
        if self.views.is_empty() {
            return bad("views must name at least one camera".into());
        }
        for (i, v) in self.views.iter().enumerate() {
            if self.views[..i].contains(v) {
                return bad(format!("views: {} appears twice", v.short()));
            }
        }
        if !(1..=32).contains(&self.history_frames) {
            return bad(format!(
                "history_frames {} must be within 1..=32",
                self.history_frames
            ));
        }
        if !(1..=64).contains(&self.plan_limit) {
            return bad(format!(
                "plan_limit {} must be within 1..=64",
                self.plan_limit
            ));
        }
        if !(1..=600).contains(&self.wait_limit) {
            return bad(format!(
                "wait_limit {} must be within 1..=600",
                self.wait_limit
            ));
        }
        if !(self.dt_s.is_finite() && self.dt_s > 0.0) {
            return bad(format!("dt_s {} must be finite and > 0", self.dt_s));
        }
        self.verifier.validate()?;
        self.safety.validate()?;
        self.steer.validate()
    }
}

/// Where the executed action came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// A verified condition-action pair of the plan.
    Plan,
    /// A wait step of a stop-observe-move.
    Wait,
    /// Holding still: the move trigger does not hold yet.
    Hold,
    /// The safe fallback.
    Fallback,
}

/// Why a planning round ran.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReplanReason {
    /// The sequence was empty.
    Empty,
    /// The verifier refused the head of the sequence.
    Refused,
    /// The move trigger of a stop-observe-move held.
    TriggerHeld,
    /// The move trigger did not hold for `max_hold_ticks`.
    HoldExpired,
}

/// What went wrong when the tick fell back.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FallbackKind {
    /// The observation failed validation.
    InvalidObservation,
    /// The backend gave no answer (timeout, connection, HTTP status, refusal, …).
    Backend,
    /// The answer failed parsing or validation.
    Answer,
    /// The head of a plan made this tick was refused.
    RefusedAfterReplan,
}

/// Why the tick fell back.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fallback {
    /// The kind.
    pub kind: FallbackKind,
    /// The query concerned, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub task: Option<Task>,
    /// The details.
    pub message: String,
}

/// Counters of backend calls and outcomes.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Counters {
    /// Backend calls this tick.
    pub llm_calls: u32,
    /// Their latency this tick, ms.
    pub llm_latency_ms: f64,
    /// Backend calls since the start.
    pub llm_calls_total: u64,
    /// Their latency since the start, ms.
    pub llm_latency_ms_total: f64,
    /// Planning rounds since the start.
    pub replans_total: u64,
    /// Refused condition-action pairs since the start.
    pub refusals_total: u64,
    /// Fallback ticks since the start.
    pub fallbacks_total: u64,
}

/// What the controller decided at one tick.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decision {
    /// The observation's tick.
    pub tick: u64,
    /// The control to apply (after the safety constraints).
    pub control: Control,
    /// The control of the action before the safety constraints.
    pub raw_control: Control,
    /// The action executed.
    pub action: Action,
    /// Its condition (`None` for waits and the fallback).
    pub condition: Option<Condition>,
    /// Where the action came from.
    pub source: Source,
    /// Whether the behaviour agrees with the route (steering always follows the route).
    pub behavior_follows_route: bool,
    /// Whether a planning round ran this tick.
    pub replanned: bool,
    /// Why it ran.
    pub replan_reason: Option<ReplanReason>,
    /// The pair the verifier refused this tick, and why.
    pub refusal: Option<Refusal>,
    /// Why the tick fell back, if it did.
    pub fallback: Option<Fallback>,
    /// The strategy in force.
    pub strategy: Option<Strategy>,
    /// The hazards in force.
    pub hazards: Vec<Hazard>,
    /// The verifier's per-view assessment.
    pub observed: Vec<ViewAssessment>,
    /// Whether the deficits are consistent with the previous tick.
    pub consistent: bool,
    /// The safety constraints applied (`None` when the module is off).
    pub constraints: Option<SafetyConstraints>,
    /// Which constraints triggered.
    pub triggers: Triggers,
    /// Whether the shield overrode the action: a front view showed an immediate hazard in
    /// its pixels and the action was not a stop, so the car stops (quick deceleration)
    /// whatever the plan said.
    pub shielded: bool,
    /// Steps left in the sequence.
    pub plan_remaining: usize,
    /// Counters.
    pub counters: Counters,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Move,
    Wait,
    Trigger,
}

#[derive(Debug, Clone, PartialEq)]
struct Queued {
    kind: Kind,
    condition: Option<Condition>,
    action: Action,
}

/// The LLM-RCO controller.
pub struct Rco {
    params: RcoParams,
    backend: Box<dyn Backend>,
    history: Vec<Observation>,
    plan: VecDeque<Queued>,
    plan_tick: u64,
    plan_counts: BTreeMap<CameraId, Option<usize>>,
    hazard: Option<HazardInference>,
    constraints: Option<SafetyConstraints>,
    constraints_tick: u64,
    stop_done_tick: Option<u64>,
    stopped_for: Vec<Hazard>,
    hold_ticks: u32,
    prev_throttle: f64,
    pid: SteerPid,
    counters: Counters,
}

impl std::fmt::Debug for Rco {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rco")
            .field("backend", &self.backend.describe())
            .field("plan_remaining", &self.plan.len())
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

struct TickStats {
    calls: u32,
    latency_ms: f64,
}

fn ask(
    backend: &mut dyn Backend,
    q: &Query<'_>,
    stats: &mut TickStats,
) -> Result<String, BackendError> {
    let t0 = Instant::now();
    let r = backend.answer(q);
    stats.calls += 1;
    stats.latency_ms += t0.elapsed().as_secs_f64() * 1e3;
    r
}

fn backend_fallback(task: Task, e: &BackendError) -> Fallback {
    Fallback {
        kind: FallbackKind::Backend,
        task: Some(task),
        message: e.to_string(),
    }
}

fn answer_fallback(task: Task, e: &AnswerError) -> Fallback {
    Fallback {
        kind: FallbackKind::Answer,
        task: Some(task),
        message: e.to_string(),
    }
}

fn route_behavior(dir: NavDirection) -> Behavior {
    match dir {
        NavDirection::Left => Behavior::TurnLeft,
        NavDirection::Right => Behavior::TurnRight,
        _ => Behavior::MoveForward,
    }
}

fn follows_route(b: Behavior, dir: NavDirection) -> bool {
    match b {
        Behavior::MoveForward | Behavior::Stop => true,
        Behavior::TurnLeft => dir == NavDirection::Left,
        Behavior::TurnRight => dir == NavDirection::Right,
        Behavior::ChangeLaneToLeft => dir == NavDirection::ChangeLaneLeft,
        Behavior::ChangeLaneToRight => dir == NavDirection::ChangeLaneRight,
    }
}

impl Rco {
    /// A controller with `backend`; the parameters are validated first.
    pub fn new(params: RcoParams, backend: Box<dyn Backend>) -> Result<Self, RcoError> {
        params.validate()?;
        Ok(Self {
            pid: SteerPid::new(params.steer),
            params,
            backend,
            history: Vec::new(),
            plan: VecDeque::new(),
            plan_tick: 0,
            plan_counts: BTreeMap::new(),
            hazard: None,
            constraints: None,
            constraints_tick: 0,
            stop_done_tick: None,
            stopped_for: Vec::new(),
            hold_ticks: 0,
            prev_throttle: 0.0,
            counters: Counters::default(),
        })
    }

    /// A controller with the offline `rules` backend.
    pub fn with_rules(params: RcoParams) -> Result<Self, RcoError> {
        Self::new(params, Box::new(RulesBackend::default()))
    }

    /// The settings.
    pub fn params(&self) -> &RcoParams {
        &self.params
    }

    /// The backend's description.
    pub fn backend(&self) -> String {
        self.backend.describe()
    }

    /// How the backend's answers are structured, when it negotiates that with a server
    /// ([`Backend::structured_output`]).
    pub fn structured_output(&self) -> Option<String> {
        self.backend.structured_output()
    }

    /// The safety constraints in force, if any.
    pub fn constraints(&self) -> Option<&SafetyConstraints> {
        self.constraints.as_ref()
    }

    /// Steps left in the sequence.
    pub fn plan_len(&self) -> usize {
        self.plan.len()
    }

    /// Forgets the history, the plan, the constraints, the PID state and the counters.
    pub fn reset(&mut self) {
        self.history.clear();
        self.plan.clear();
        self.plan_counts.clear();
        self.hazard = None;
        self.constraints = None;
        self.stop_done_tick = None;
        self.stopped_for.clear();
        self.hold_ticks = 0;
        self.prev_throttle = 0.0;
        self.pid.reset();
        self.counters = Counters::default();
    }

    /// One control tick: verify and act, or plan (see the module documentation).
    pub fn step(&mut self, obs: &Observation) -> Decision {
        let mut stats = TickStats {
            calls: 0,
            latency_ms: 0.0,
        };
        if let Err(e) = obs.validate() {
            self.plan.clear();
            self.counters.fallbacks_total += 1;
            let control = Control {
                throttle: 0.0,
                brake: 0.8,
                steer: 0.0,
            };
            self.prev_throttle = 0.0;
            return Decision {
                tick: obs.tick,
                control,
                raw_control: control,
                action: Action::STOP,
                condition: None,
                source: Source::Fallback,
                behavior_follows_route: true,
                replanned: false,
                replan_reason: None,
                refusal: None,
                fallback: Some(Fallback {
                    kind: FallbackKind::InvalidObservation,
                    task: None,
                    message: e.to_string(),
                }),
                strategy: self.hazard.as_ref().map(|h| h.strategy),
                hazards: self
                    .hazard
                    .as_ref()
                    .map(|h| h.hazards.clone())
                    .unwrap_or_default(),
                observed: Vec::new(),
                consistent: false,
                constraints: self.constraints,
                triggers: Triggers::default(),
                shielded: false,
                plan_remaining: 0,
                counters: self.counters_now(&stats),
            };
        }
        self.history.push(obs.clone());
        if self.history.len() > self.params.history_frames {
            let extra = self.history.len() - self.params.history_frames;
            self.history.drain(..extra);
        }
        let n = self.history.len();
        let prev = (n >= 2).then(|| &self.history[n - 2]);
        let assessment = verifier::assess(prev, obs, &self.params.views, &self.params.verifier);

        let mut fallback = None;
        if self.params.modules.safety_constraints {
            let due = match self.constraints {
                None => true,
                Some(_) => {
                    obs.tick < self.constraints_tick
                        || obs.tick - self.constraints_tick >= self.params.safety.refresh_ticks
                }
            };
            if due {
                let r = self.query_constraints(&assessment, &mut stats);
                self.constraints_tick = obs.tick;
                match r {
                    Ok(sc) => {
                        // Held inside fogline's hard limits: an answer only tightens them.
                        let env = obs.surroundings.traffic_env;
                        let (kept, changed) = sc.within(&self.params.safety.hard, env);
                        if !changed.is_empty() {
                            log::debug!(
                                "tick {}: the answer's {} tightened to the hard limits",
                                obs.tick,
                                changed.join(", ")
                            );
                        }
                        self.constraints = Some(kept);
                    }
                    Err(f) => {
                        self.constraints = Some(SafetyConstraints::conservative());
                        fallback = Some(f);
                    }
                }
            }
        }

        let mut replanned = false;
        let mut replan_reason = None;
        let mut refusal: Option<Refusal> = None;
        let mut executed: Option<(Source, Action, Option<Condition>)> = None;
        let verify = self.params.modules.verifier;
        while fallback.is_none() && executed.is_none() {
            let Some(head) = self.plan.front().cloned() else {
                if replanned {
                    // A validated plan has at least one step; be safe anyway.
                    fallback = Some(Fallback {
                        kind: FallbackKind::Answer,
                        task: None,
                        message: "the new plan is empty".into(),
                    });
                    break;
                }
                replan_reason.get_or_insert(ReplanReason::Empty);
                if let Err(f) = self.make_plan(&assessment, true, &mut stats) {
                    fallback = Some(f);
                }
                replanned = true;
                continue;
            };
            let consistency = if !verify || (replanned && self.plan_tick == obs.tick) {
                Ok(())
            } else {
                verifier::check_consistency(&self.plan_counts, &assessment)
            };
            // Standing still is safe whatever the deficits do: the wait steps and the hold
            // before the move trigger run without the consistency check (a change there
            // would only restart the observation); the trigger's own states decide the move.
            let verdict = match (head.kind, &head.condition) {
                (Kind::Move, Some(c)) if verify => {
                    consistency.and_then(|()| verifier::check_states(c, &assessment))
                }
                (Kind::Wait | Kind::Trigger, _) => Ok(()),
                _ => consistency,
            };
            if let Err(r) = verdict {
                self.counters.refusals_total += 1;
                self.plan.clear();
                self.hold_ticks = 0;
                if replanned {
                    fallback = Some(Fallback {
                        kind: FallbackKind::RefusedAfterReplan,
                        task: None,
                        message: r.to_string(),
                    });
                    refusal = Some(r);
                    break;
                }
                refusal = Some(r);
                replan_reason = Some(ReplanReason::Refused);
                if let Err(f) = self.make_plan(&assessment, true, &mut stats) {
                    fallback = Some(f);
                }
                replanned = true;
                continue;
            }
            match head.kind {
                Kind::Move => {
                    self.plan.pop_front();
                    executed = Some((Source::Plan, head.action, head.condition));
                }
                Kind::Wait => {
                    self.plan.pop_front();
                    executed = Some((Source::Wait, head.action, None));
                }
                Kind::Trigger => {
                    let holds = !verify
                        || head
                            .condition
                            .as_ref()
                            .is_some_and(|c| verifier::check_states(c, &assessment).is_ok());
                    if holds && !replanned {
                        self.plan.clear();
                        self.hold_ticks = 0;
                        self.stop_done_tick = Some(obs.tick);
                        self.stopped_for = self
                            .hazard
                            .as_ref()
                            .map(|h| h.hazards.clone())
                            .unwrap_or_default();
                        replan_reason = Some(ReplanReason::TriggerHeld);
                        if let Err(f) = self.make_plan(&assessment, false, &mut stats) {
                            fallback = Some(f);
                        }
                        replanned = true;
                    } else if self.hold_ticks >= self.params.max_hold_ticks && !replanned {
                        self.plan.clear();
                        self.hold_ticks = 0;
                        replan_reason = Some(ReplanReason::HoldExpired);
                        if let Err(f) = self.make_plan(&assessment, true, &mut stats) {
                            fallback = Some(f);
                        }
                        replanned = true;
                    } else {
                        self.hold_ticks += 1;
                        executed = Some((Source::Hold, Action::STOP, head.condition));
                    }
                }
            }
        }
        if fallback.is_some() {
            self.plan.clear();
            self.counters.fallbacks_total += 1;
            executed = None;
        }
        let (source, planned, condition) =
            executed.unwrap_or((Source::Fallback, Action::STOP, None));
        // The shield: an immediate hazard in a front view's pixels always brakes, whatever
        // the backend planned (a plan made before it appeared, or an answer that ignores it).
        let stopping = planned.behavior == Behavior::Stop
            && matches!(
                planned.speed,
                SpeedControl::QuickDeceleration | SpeedControl::DecelerationToZero
            );
        let hazard_ahead = assessment.front_immediate();
        let shielded = hazard_ahead && !stopping;
        let action = if shielded {
            Action {
                behavior: Behavior::Stop,
                speed: SpeedControl::QuickDeceleration,
            }
        } else {
            planned
        };

        let p = pedals(action.speed, self.prev_throttle);
        let nav = &obs.navigation;
        let steer = self
            .pid
            .step(nav.target_x_m, nav.target_y_m, self.params.dt_s);
        let raw = Control {
            throttle: p.throttle,
            brake: p.brake,
            steer,
        }
        .clamped();
        let (control, triggers, constraints) =
            match (self.params.modules.safety_constraints, self.constraints) {
                (true, Some(sc)) => {
                    let env = obs.surroundings.traffic_env;
                    let (sc, _) = sc.within(&self.params.safety.hard, env);
                    let (mut c, t) = safety::apply(raw, &obs.ego, &sc, &self.params.safety);
                    if hazard_ahead {
                        // With a hazard ahead the constraints may only add braking.
                        c.brake = c.brake.max(raw.brake);
                        c.throttle = c.throttle.min(raw.throttle);
                    }
                    (c, t, Some(sc))
                }
                _ => (raw, Triggers::default(), None),
            };
        self.prev_throttle = control.throttle;
        Decision {
            tick: obs.tick,
            control,
            raw_control: raw,
            action,
            condition,
            source,
            behavior_follows_route: follows_route(action.behavior, nav.direction),
            replanned,
            replan_reason: if replanned { replan_reason } else { None },
            refusal,
            fallback,
            strategy: self.hazard.as_ref().map(|h| h.strategy),
            hazards: self
                .hazard
                .as_ref()
                .map(|h| h.hazards.clone())
                .unwrap_or_default(),
            consistent: assessment.change.is_none(),
            observed: assessment.views,
            constraints,
            triggers,
            shielded,
            plan_remaining: self.plan.len(),
            counters: self.counters_now(&stats),
        }
    }

    fn counters_now(&mut self, stats: &TickStats) -> Counters {
        self.counters.llm_calls = stats.calls;
        self.counters.llm_latency_ms = stats.latency_ms;
        self.counters.llm_calls_total += u64::from(stats.calls);
        self.counters.llm_latency_ms_total += stats.latency_ms;
        self.counters
    }

    fn query_constraints(
        &mut self,
        assessment: &Assessment,
        stats: &mut TickStats,
    ) -> Result<SafetyConstraints, Fallback> {
        let task = Task::SafetyConstraints;
        let ctx = context_of(
            &self.history,
            &self.params,
            None,
            self.stop_done_tick,
            &self.stopped_for,
            assessment,
            None,
        );
        let q = prompt::constraints_query(ctx);
        let text = ask_split(&mut self.backend, &q, stats);
        let text = text.map_err(|e| backend_fallback(task, &e))?;
        answer::parse_constraints(&text).map_err(|e| answer_fallback(task, &e))
    }

    /// One planning round: hazard inference when `full`, then the motion planner.
    fn make_plan(
        &mut self,
        assessment: &Assessment,
        full: bool,
        stats: &mut TickStats,
    ) -> Result<(), Fallback> {
        self.plan.clear();
        self.hold_ticks = 0;
        self.counters.replans_total += 1;
        let m = self.params.modules;
        if full || self.hazard.is_none() {
            let hazard = if m.hazard_inference {
                let task = Task::HazardInference;
                let ctx = context_of(
                    &self.history,
                    &self.params,
                    self.constraints.as_ref(),
                    self.stop_done_tick,
                    &self.stopped_for,
                    assessment,
                    None,
                );
                let q = prompt::hazard_query(ctx, self.params.max_images);
                let text = ask_split(&mut self.backend, &q, stats);
                let text = text.map_err(|e| backend_fallback(task, &e))?;
                answer::parse_hazard(&text, &self.params.views)
                    .map_err(|e| answer_fallback(task, &e))?
            } else {
                HazardInference::none()
            };
            self.hazard = Some(hazard);
        }
        let strategy = if full {
            self.hazard.as_ref().map_or(Strategy::Move, |h| h.strategy)
        } else {
            Strategy::Move
        };
        let hz = if m.hazard_inference {
            self.hazard.as_ref()
        } else {
            None
        };
        let ctx = context_of(
            &self.history,
            &self.params,
            self.constraints.as_ref(),
            self.stop_done_tick,
            &self.stopped_for,
            assessment,
            hz,
        );
        let now_tick = self.history.last().map_or(0, |o| o.tick);
        let mut queue = VecDeque::new();
        match (strategy, m.motion_planner) {
            (Strategy::Move, true) => {
                let task = Task::MovePlan;
                let q = prompt::move_query(ctx);
                let text = ask_split(&mut self.backend, &q, stats);
                let text = text.map_err(|e| backend_fallback(task, &e))?;
                let steps = answer::parse_move(&text, &self.params.views, self.params.plan_limit)
                    .map_err(|e| answer_fallback(task, &e))?;
                queue.extend(steps.into_iter().map(|s| Queued {
                    kind: Kind::Move,
                    condition: Some(s.condition),
                    action: s.action,
                }));
            }
            (Strategy::StopObserveMove, true) => {
                let task = Task::StopObserveMovePlan;
                let q = prompt::som_query(ctx);
                let text = ask_split(&mut self.backend, &q, stats);
                let text = text.map_err(|e| backend_fallback(task, &e))?;
                let som = answer::parse_som(&text, &self.params.views, self.params.wait_limit)
                    .map_err(|e| answer_fallback(task, &e))?;
                push_som(&mut queue, som.wait_steps, som.move_trigger);
            }
            (Strategy::Move, false) => {
                let dir = self
                    .history
                    .last()
                    .map_or(NavDirection::FollowLane, |o| o.navigation.direction);
                queue.push_back(Queued {
                    kind: Kind::Move,
                    condition: Some(assessment.observed()),
                    action: Action {
                        behavior: route_behavior(dir),
                        speed: SpeedControl::ConstantSpeed,
                    },
                });
            }
            (Strategy::StopObserveMove, false) => {
                let mut trigger = assessment.observed();
                for (c, s) in trigger.views.iter_mut() {
                    if c.yaw_rad() == 0.0 {
                        *s = HazardState::NoImmediateHazard;
                    }
                }
                push_som(&mut queue, self.params.wait_limit.min(10), trigger);
            }
        }
        self.plan = queue;
        self.plan_tick = now_tick;
        self.plan_counts = assessment.counts();
        Ok(())
    }
}

/// The context of a query, from the controller's fields (so that the backend, another
/// field, can be borrowed mutably while the query lives).
fn context_of<'a>(
    history: &'a [Observation],
    params: &'a RcoParams,
    constraints: Option<&'a SafetyConstraints>,
    stop_done_tick: Option<u64>,
    stopped_for: &'a [Hazard],
    assessment: &'a Assessment,
    hazard: Option<&'a HazardInference>,
) -> QueryContext<'a> {
    let now = history.last().map_or(0, |o| o.tick);
    QueryContext {
        history,
        views: &params.views,
        assessment,
        hazard,
        plan_limit: params.plan_limit,
        wait_limit: params.wait_limit,
        constraints,
        ticks_since_stop: stop_done_tick.map(|t| now.saturating_sub(t)),
        stopped_for,
        hazard_ratio: params.verifier.hazard_ratio,
        dt_s: params.dt_s,
    }
}

/// Calls the backend for a query that borrows other fields of the controller.
fn ask_split(
    backend: &mut Box<dyn Backend>,
    q: &Query<'_>,
    stats: &mut TickStats,
) -> Result<String, BackendError> {
    ask(backend.as_mut(), q, stats)
}

fn push_som(queue: &mut VecDeque<Queued>, wait: u32, trigger: Condition) {
    for _ in 0..wait {
        queue.push_back(Queued {
            kind: Kind::Wait,
            condition: None,
            action: Action::STOP,
        });
    }
    queue.push_back(Queued {
        kind: Kind::Trigger,
        condition: Some(trigger),
        action: Action::STOP,
    });
}

impl Decision {
    /// One line for humans: tick, source, action, control, replan and fallback reasons,
    /// backend calls.
    pub fn summary(&self) -> String {
        let source = match self.source {
            Source::Plan => "plan",
            Source::Wait => "wait",
            Source::Hold => "hold",
            Source::Fallback => "fallback",
        };
        let mut s = format!(
            "{:>5} {:<8} {:<36} thr {:.2} brk {:.2} str {:+.2}",
            self.tick,
            source,
            self.action.to_string(),
            self.control.throttle,
            self.control.brake,
            self.control.steer
        );
        if let Some(st) = self.strategy {
            s.push_str(&format!(" [{}]", st.name()));
        }
        if self.replanned {
            let why = match self.replan_reason {
                Some(ReplanReason::Empty) => "plan empty",
                Some(ReplanReason::Refused) => "refused",
                Some(ReplanReason::TriggerHeld) => "move trigger held",
                Some(ReplanReason::HoldExpired) => "hold expired",
                None => "",
            };
            s.push_str(&format!(" replan: {why}"));
        }
        if let Some(r) = &self.refusal {
            s.push_str(&format!(" ({r})"));
        }
        if let Some(f) = &self.fallback {
            s.push_str(&format!(" FALLBACK: {}", f.message));
        }
        if self.counters.llm_calls > 0 {
            s.push_str(&format!(" calls {}", self.counters.llm_calls));
        }
        s
    }
}
