//! The agent under test: a camera-driven baseline built from the reference planner, a speed
//! PID, a pure-pursuit steering controller on the route, and an "unstick" rule.
//!
//! Every agent step (5 Hz by default) the planner gets the front-wide and front-tele frames
//! (the last four, oldest first) and the ego history, and answers with a decision and its
//! perception. The agent turns that into a target speed:
//!
//! | planner decision | target speed |
//! |---|---|
//! | keep lane, proceed on green, nudge, pass, turn right | the cruise speed (8 m/s), lower before a turn of the route (see below) |
//! | follow or slow for the lead | the cruise speed, capped by the lead rule below |
//! | stop for a red light, a stop sign, or yield to a crossing | `√(2 · 2.5 m/s² · d)`, recomputed every control step, with `d` the distance left to the planner's stop point ([`fogline_planner::plan::Plan::stop_at`]), or to 5.5 m before a zebra crossing the planner sees short of it |
//!
//! **The road user ahead**, whatever the decision: the target is capped by the intelligent
//! driver model behind the perceived lead in the ego lane (gap, speed; braking lamps:
//! −1 m/s² more), projected 0.5 s ahead. The agent steers along its route and never leaves
//! its lane, so a stop, a turn or a pass is driven behind whoever is in front.
//!
//! **Crossings**: a zebra crossing the planner sees within 20 m caps the target at 4 m/s (a
//! walker about to step onto it is small in the frames until close; a slower car sees them
//! in more frames before it is there).
//!
//! **Red lights**: once the planner decided to stop for a red or amber light, the agent keeps
//! that stop point (in distance driven; the latest estimate while the light is seen, as the
//! stop line is found only close up) until the planner reports a green light or the car is
//! more than 1 m past it — the signal head leaves the cameras' view as the car gets close;
//! only a stop point within [`RED_MEMORY_REACH_M`] is kept ([`red_memory`]), and a zebra
//! crossing counts for a red light only when it lies less than
//! [`fogline_planner::plan::LIGHT_TO_LINE_MAX_M`] short of the head.
//!
//! Before a turn of the route the target is capped so that the car reaches 4 m/s (right) or
//! 5.5 m/s (left) at the junction, braking at 2 m/s². A speed PID (kp 0.8, ki 0.1 1/s,
//! throttle ≤ 1) tracks the target; the brake is `0.8·(v − target)` when the car is more
//! than 0.3 m/s too fast, and 1 when it should stand still.
//!
//! **Stop signs**: a stop-sign decision's stop point (the latest estimate while the sign is
//! seen) is kept (the sign leaves the cameras' view as the car gets close) until the car has
//! stood still (< 0.1 m/s) for 1.5 s within 3 m of it and its looks to the sides (two
//! cross cameras, rendered only then) have seen no vehicle moving for [`LOOK_QUIET_S`]
//! ([`Baseline::wants_look`], [`Baseline::look`]), or is more than 1 m past it. The
//! planner stops for any stop sign it sees, also once it has stopped: after that stop the
//! agent treats stop-sign decisions as "keep lane" for the next 30 m driven.
//!
//! **Junctions** ([`JunctionGap`]): a car within 15 m of the entry to its route's next
//! junction that is slower than 3 m/s (starting after a stop sign, a red light or a queue),
//! or that turns left there, accepts a gap first. The perception then also looks at the
//! oncoming lane, and the car holds short of the entry while a vehicle is seen moving across
//! its path ahead or in the oncoming lane (for a left turn: any oncoming vehicle within 45 m
//! not seen standing), and for 1.2 s after — not at a green light unless it turns left, and
//! at most 10 s at one junction.
//!
//! **Unstick** (like TransFuser's creeping): after 55 s standing still, the agent ignores the
//! planner for 4 s and drives at up to 4 m/s; the count restarts once it moves. At a signal
//! read green since the car stood still (a working one), it waits for the green
//! ([`UnstickSignal`]).
//!
//! **A planner under test** ([`Baseline::driven_by`], `fogline sim run --planner URL`) takes
//! the rules' place: the car follows its trajectory's speed profile and stops where the
//! trajectory comes to rest ([`trajectory_intent`]); the lead, stop and unstick rules above
//! are off.
//!
//! **Steering**: pure pursuit on the dense route, look-ahead `0.8·v + 2` m (3.5–10 m) from the
//! rear axle, the steer that the bicycle model needs for the pursuit curvature — the agent
//! gets the route as CARLA agents get their global plan.

use std::sync::Arc;

use fogline_planner::ReferencePlanner;
use fogline_planner::detect::{MoverSeen, ObjectSeen};
use fogline_planner::perceive::{Lamp, LeadSeen, Lost, ObjectKind};
use fogline_planner::plan::LIGHT_TO_LINE_MAX_M;
use fogline_types::clip::{CameraInput, Decision, EgoPose, PlannerInput};
use fogline_types::motion::EGO_FRONT_M;
use fogline_types::planner::{PlanRequest, Planner};
use serde::{Deserialize, Serialize};

use crate::geom::{dist, dot, sub};
use crate::score::DenseRoute;
use crate::vehicle::{BicycleParams, VehicleControl, VehicleState};

/// Settings of the baseline agent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AgentParams {
    /// Cruise speed, m/s.
    pub cruise_mps: f64,
    /// Speed through right turns, m/s.
    pub right_turn_mps: f64,
    /// Speed through left turns, m/s.
    pub left_turn_mps: f64,
    /// Deceleration planned before turns, m/s².
    pub turn_decel_mps2: f64,
    /// Deceleration towards a planned stop, m/s².
    pub stop_decel_mps2: f64,
    /// Standing still this long triggers the unstick rule, s.
    pub unstick_after_s: f64,
    /// The unstick rule drives this long, s.
    pub unstick_for_s: f64,
    /// Speed of the unstick rule, m/s.
    pub unstick_mps: f64,
    /// Distance during which a passed stop sign is ignored, m.
    pub sign_memory_m: f64,
    /// Speed over a crossing the planner sees within `ZEBRA_CAUTION_M`, m/s.
    pub zebra_mps: f64,
}

impl Default for AgentParams {
    fn default() -> Self {
        Self {
            cruise_mps: 8.0,
            right_turn_mps: 4.0,
            left_turn_mps: 5.5,
            turn_decel_mps2: 2.0,
            stop_decel_mps2: 2.5,
            unstick_after_s: 55.0,
            unstick_for_s: 4.0,
            unstick_mps: 4.0,
            sign_memory_m: 30.0,
            zebra_mps: 4.0,
        }
    }
}

/// What the agent concluded at its last planning step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Intent {
    /// The planner's decision.
    pub decision: Option<Decision>,
    /// The target speed, m/s.
    pub target_mps: f64,
    /// Where to stand, in distance driven (the target speed follows the braking profile to
    /// it every control step), m.
    pub stop_at_m: Option<f64>,
    /// The perceived vehicle ahead: gap, m.
    pub lead_gap_m: Option<f64>,
    /// Whether the planner failed (the agent then brakes).
    pub failed: bool,
    /// Where the unstick rule must stand, in distance driven, m: short of the vehicle
    /// ahead (seen, or remembered standing) by [`UNSTICK_CLEAR_M`] when it was seen driving,
    /// else by [`UNSTICK_KEEP_M`].
    pub unstick_stop_at_m: Option<f64>,
}

/// What a planned trajectory asks of the car: its waypoints `xy` (in the rig frame now,
/// 0.1 s apart in the planner's time, which runs `speed_scale` times faster than the
/// simulation's when the agent plans below 10 Hz — see [`crate::run`]) give the speed it
/// plans half a second ahead (from its path between 0.3 s and 0.7 s), capped at `cap_mps`,
/// and, when it comes to rest within its horizon (it moves less than
/// [`TRAJECTORY_REST_M`] over its last second or more), the point where it stands, in
/// distance driven from `odometer_m`: the agent brakes to it as to any stop point.
pub fn trajectory_intent(
    xy: &[[f64; 2]],
    decision: Option<Decision>,
    odometer_m: f64,
    cap_mps: f64,
    speed_scale: f64,
) -> Intent {
    let mut arc = Vec::with_capacity(xy.len() + 1);
    arc.push(0.0);
    let mut prev = [0.0, 0.0];
    for q in xy {
        let last = arc.last().copied().unwrap_or(0.0);
        arc.push(last + (q[0] - prev[0]).hypot(q[1] - prev[1]));
        prev = *q;
    }
    let total = arc.last().copied().unwrap_or(0.0);
    let at = |k: usize| arc.get(k).copied().unwrap_or(total);
    let planned = (at(7) - at(3)) / (0.4 * speed_scale.max(1e-9));
    // The first waypoint from which the trajectory no longer moves; it rests there when
    // that is at least a second (ten waypoints) before its end.
    let rest = arc.iter().position(|&a| total - a < TRAJECTORY_REST_M);
    let stop_at_m = rest
        .filter(|&k| k + 10 <= xy.len())
        .map(|k| odometer_m + at(k));
    Intent {
        decision,
        target_mps: if planned.is_finite() {
            planned.clamp(0.0, cap_mps)
        } else {
            0.0
        },
        stop_at_m,
        lead_gap_m: None,
        failed: false,
        unstick_stop_at_m: None,
    }
}

/// The baseline agent's state.
#[derive(Debug, Clone)]
pub struct Baseline {
    params: AgentParams,
    planner: ReferencePlanner,
    intent: Intent,
    integral: f64,
    stopped_s: f64,
    sign_stop_s: f64,
    sign_free_until_m: f64,
    unstick_left_s: f64,
    /// Times the unstick rule fired.
    pub unstick_count: u32,
    /// Planner calls.
    pub plans: u64,
    /// Planner errors.
    pub plan_errors: u64,
    /// The last perception, in words (filled when debug logging is on).
    pub debug: String,
    red_stop_at_m: Option<f64>,
    sign_stop_at_m: Option<f64>,
    lead_memory: LeadMemory,
    hidden_signal: bool,
    lost: Vec<Lost>,
    /// The stop at the line is for a hidden signal (it ends only once cross traffic has
    /// stopped passing).
    hidden_stop: bool,
    /// Seconds since a vehicle was last seen crossing the ego's path ahead.
    cross_quiet_s: f64,
    /// Seconds the looks to the sides have found no vehicle moving, standing at a stop
    /// sign's line (see [`Baseline::look`]).
    look_quiet_s: f64,
    /// The road user on the right kerb over the steps.
    kerb: KerbWatch,
    junction_gap: JunctionGap,
    /// Where the latest crossing seen lies, in distance driven, m.
    zebra_at_m: Option<f64>,
    /// The signal ahead reads red or amber at the latest planning step.
    signal_stop: bool,
    /// The signal ahead was read green since the car last stood still: it is a working
    /// signal, and the unstick rule waits for its green (see [`UnstickSignal`]).
    signal_cycled: bool,
    objects: Vec<ObjectSeen>,
    /// A planner under test that drives instead of the baseline's rules.
    driver: Option<Driver>,
}

/// A planner under test in the driver's seat ([`Baseline::driven_by`]).
#[derive(Clone)]
struct Driver {
    planner: Arc<dyn Planner>,
    scene_id: String,
    seed: u64,
}

impl std::fmt::Debug for Driver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Driver")
            .field("planner", &self.planner.describe())
            .field("scene_id", &self.scene_id)
            .finish_non_exhaustive()
    }
}

/// A planned trajectory that moves less than this over its remaining waypoints has come to
/// rest there, m.
pub const TRAJECTORY_REST_M: f64 = 0.3;

/// At a hidden signal the car goes only after no vehicle has crossed its path ahead for
/// this long (the cross street's green has ended), s.
pub const HIDDEN_SIGNAL_QUIET_S: f64 = 4.0;

/// A hidden signal's stop line farther than this is not stopped for yet, m.
pub const HIDDEN_SIGNAL_REACH_M: f64 = 30.0;

/// A red light's stop point is remembered (kept while the head leaves the cameras' view)
/// only within this distance, m.
pub const RED_MEMORY_REACH_M: f64 = 50.0;

/// The red light's stop point to remember (in distance driven) after a red-light decision
/// whose stop point is `ahead_m` ahead at `odometer_m`, `kept` the one remembered so far: the
/// latest estimate while the light is seen (the stop line is found only as the car gets
/// close, and an early guess from the light's distance alone can be metres short), but only
/// within [`RED_MEMORY_REACH_M`] — a far one is read again on the way, and one remembered
/// far ahead could hold the car where no light is.
pub fn red_memory(kept: Option<f64>, odometer_m: f64, ahead_m: f64) -> Option<f64> {
    if ahead_m <= RED_MEMORY_REACH_M {
        Some(odometer_m + ahead_m)
    } else {
        kept
    }
}

/// A crossing the planner sees closer than this caps the speed at `zebra_mps`, m.
pub const ZEBRA_CAUTION_M: f64 = 20.0;

/// Gap kept before a crossing when stopping, m.
pub const CROSSING_GAP_M: f64 = 5.5;
/// A walker whose contact is more than this beyond the near edge of a crossing is not on
/// it, m (a crossing is about 4 m deep).
pub const WALKER_ON_CROSSING_M: f64 = 6.0;

/// A crossing seen closer than this has the perception read the oncoming lane too, for a
/// walker on the crossing's far half ([`walker_on_far_crossing`]), m.
pub const FAR_CROSSING_REACH_M: f64 = 30.0;

/// Whether the road user read in the lane to the left (`left`; speeds perceived at
/// `speed_scale` times the true ones) is a walker on the crossing ahead (its near edge
/// `zebra` m ahead) who has the way: on it (contact within its 4 m depth, 1 m of slack), seen
/// in two frames or more, and either walking towards the ego's lane (across at 0.5 m/s or
/// more, slower than 2 m/s along the lane) or standing on it (along the lane within 1 m/s
/// beyond two standard errors). A
/// vehicle coming through moves along the lane; one waiting at its own side stands beyond
/// the crossing. The ego lane's reading already holds the car for a walker on its own half.
pub fn walker_on_far_crossing(
    left: Option<&LeadSeen>,
    zebra: Option<f64>,
    speed_scale: f64,
) -> bool {
    let (Some(l), Some(z)) = (left, zebra) else {
        return false;
    };
    let on = l.contact_x > z - 1.0 && l.contact_x < z + 5.0;
    let seen = l.frames_seen() >= 2;
    // A walker, not a vehicle read with a sideways scatter: slower than 2 m/s along the
    // lane (beyond two standard errors).
    let slow = l.speed.abs() - 2.0 * l.speed_se < 2.0 * speed_scale;
    let towards = slow && l.lateral_speed <= -0.5 * speed_scale;
    let standing =
        l.speed.abs() - 2.0 * l.speed_se < speed_scale && l.lateral_speed.abs() < 0.5 * speed_scale;
    on && seen && (towards || standing)
}

/// Half the width of the car's path for [`stepping_off_kerb`]: the car's half-width and a
/// margin, m.
pub const PATH_HALF_M: f64 = fogline_types::motion::EGO_WIDTH_M / 2.0 + 0.3;

/// How long after the car has passed a walker stepping off the kerb it may still reach the
/// car's path and be yielded to, s (a walker who gets there later crosses behind the car).
pub const KERB_MARGIN_S: f64 = 2.0;

/// Speed towards the lane from which someone on the kerb is stepping off it, m/s (a walker
/// crosses at 1–1.5 m/s).
pub const KERB_STEP_MPS: f64 = 0.5;

/// How far back [`KerbWatch`] compares readings, s (two or three planning steps).
pub const KERB_WATCH_S: f64 = 0.9;

/// Readings of the kerb this far apart along the road are taken for the same road user, m.
pub const KERB_SAME_M: f64 = 1.5;

/// The road user on the right kerb followed over the planning steps
/// ([`fogline_planner::perceive::Perception::kerb_object`] is read from one step's frames):
/// where its contact was (odometer position, m), its edge nearest the lane (m from the
/// lane centre, left positive) and when (game time, s).
#[derive(Debug, Default, Clone)]
pub struct KerbWatch {
    readings: std::collections::VecDeque<(f64, f64, f64)>,
}

impl KerbWatch {
    /// Takes this step's reading (`at_m`, `edge_m`; `None` when nothing stands on the kerb)
    /// at game time `t_s`, and returns how fast the road user moves towards the lane, m/s:
    /// from the earliest reading within [`KERB_WATCH_S`] at the same place along the road
    /// (within [`KERB_SAME_M`]), at least 0.3 s before; `None` without one.
    pub fn update(&mut self, t_s: f64, reading: Option<(f64, f64)>) -> Option<f64> {
        while self
            .readings
            .front()
            .is_some_and(|r| r.2 < t_s - KERB_WATCH_S - 1e-9)
        {
            self.readings.pop_front();
        }
        let (at, edge) = reading?;
        let towards = self
            .readings
            .iter()
            .find(|r| (r.0 - at).abs() < KERB_SAME_M && t_s - r.2 >= 0.3)
            .map(|r| (edge - r.1) / (t_s - r.2));
        self.readings.push_back((at, edge, t_s));
        towards
    }
}

/// Whether someone on the right kerb is stepping off it into the car's path: moving towards
/// the lane at [`KERB_STEP_MPS`] or more (`towards`, from [`KerbWatch`]), and due to reach
/// the car's path (half-width [`PATH_HALF_M`]) from its edge nearest the lane (`edge`, m
/// from the lane centre) before the car, driving at `speed_mps`, has passed its contact
/// (`contact_x`, m ahead of the rear axle) by [`KERB_MARGIN_S`]. Someone standing at the
/// kerb, or walking along the sidewalk, is not.
pub fn stepping_off_kerb(towards: f64, edge: f64, contact_x: f64, speed_mps: f64) -> bool {
    if towards < KERB_STEP_MPS {
        return false;
    }
    let to_path = (-PATH_HALF_M - edge).max(0.0) / towards;
    let to_pass = (contact_x - EGO_FRONT_M).max(0.0) / speed_mps.max(0.5);
    to_path < to_pass + KERB_MARGIN_S
}

/// What the planner is given each step.
pub struct AgentInput<'a> {
    /// Cameras with their frames, oldest first.
    pub cameras: Vec<CameraInput<'a>>,
    /// The ego history in the rig frame now.
    pub history: &'a [EgoPose],
    /// Game time of the newest frames, s.
    pub time_s: f64,
    /// The navigation's curvature (the arc to the route point ahead, 1/m, left positive):
    /// the history carries it in its headings while the car moves; standing, the planner
    /// gets it this way.
    pub nav_kappa: f64,
    /// The route's next junction, as the global plan gives it (CARLA agents get their
    /// route's turns the same way).
    pub junction: Option<JunctionAhead>,
}

/// The route's next junction seen from the car.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JunctionAhead {
    /// Route distance left to where the path through the junction starts, m (negative once
    /// inside it).
    pub entry_m: f64,
    /// The route turns left there (across the oncoming lane).
    pub left_turn: bool,
}

/// A car slower than this, within [`JUNCTION_YIELD_REACH_M`] of a junction's entry, is
/// entering it from (near) a standstill — after a stop sign, a red light or a queue — and
/// accepts a gap first: it does not enter while a vehicle is seen moving across its path
/// or in the oncoming lane, m/s.
pub const JUNCTION_START_MPS: f64 = 3.0;

/// How far before a junction's entry the gap check applies, m (the stop line is 9 m
/// before it).
pub const JUNCTION_YIELD_REACH_M: f64 = 15.0;

/// A car entering a junction from a standstill goes once no vehicle has been seen moving
/// across its path or in the oncoming lane for this long, s.
pub const JUNCTION_QUIET_S: f64 = 1.2;

/// The gap check holds the car at most this long at one junction (a vehicle read as moving
/// that never leaves must not hold it for good; traffic yields to a car that has stood at
/// its line longer), s.
pub const JUNCTION_HOLD_MAX_S: f64 = 10.0;

/// A vehicle seen moving faster than this (along or across its lane) holds a car waiting
/// to enter a junction, m/s.
pub const JUNCTION_MOVING_MPS: f64 = 1.0;

/// Gap acceptance at a junction entered from (near) a standstill (see
/// [`JUNCTION_START_MPS`]): the car does not enter while a vehicle is seen moving across its
/// path ahead or in the oncoming lane — one that stopped at its line before the car and now
/// takes its turn, one turning across, one coming through — unless a green light gives it
/// the way and it does not turn across; it goes once none has been seen for
/// [`JUNCTION_QUIET_S`], or after [`JUNCTION_HOLD_MAX_S`] held at that junction. An
/// oncoming-lane conflict counts once seen on two planning steps running (a reading in one
/// frame only — a car glimpsed far off, paint or shadow read as one — does not hold the
/// car; a car coming on stays in view).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JunctionGap {
    /// Seconds since a vehicle was last seen moving across the path or in the oncoming
    /// lane.
    pub quiet_s: f64,
    /// Seconds held at the junction at `at_m`.
    pub held_s: f64,
    /// The junction's entry in distance driven, m.
    pub at_m: f64,
    /// The previous planning step saw a conflict in the oncoming lane.
    pub oncoming_before: bool,
}

impl Default for JunctionGap {
    fn default() -> Self {
        Self {
            quiet_s: 0.0,
            held_s: 0.0,
            at_m: f64::NEG_INFINITY,
            oncoming_before: false,
        }
    }
}

impl JunctionGap {
    /// Whether the vehicle ahead (`lead`) moves across the path within 30 m, and whether the
    /// one in the oncoming lane (`left`) within [`ONCOMING_REACH_M`] is a conflict: moving
    /// (tracked over three frames or more and faster than [`JUNCTION_MOVING_MPS`]; the
    /// oncoming one's speed along its lane beyond two standard errors) — or, for a car about
    /// to turn left across that lane (`left_turn`), any oncoming vehicle not seen standing:
    /// one coming at speed moves too far between frames to be tracked, and the turn needs
    /// the lane clear (the towns' traffic turns left on the same terms). Perceived speeds
    /// are `speed_scale` times the true ones (see [`crate::run`]).
    pub fn conflicts(
        lead: Option<&LeadSeen>,
        left: Option<&LeadSeen>,
        left_turn: bool,
        speed_scale: f64,
    ) -> (bool, bool) {
        let tracked = |l: &LeadSeen| l.frames_seen() >= 3;
        let moving = JUNCTION_MOVING_MPS * speed_scale;
        let across = lead.is_some_and(|l| {
            l.kind == ObjectKind::Vehicle
                && l.contact_x < 30.0
                && tracked(l)
                && l.lateral_speed.abs() > moving
        });
        let oncoming = left.is_some_and(|l| {
            let seen_moving = tracked(l)
                && (l.speed.abs() > moving + 2.0 * l.speed_se || l.lateral_speed.abs() > moving);
            let seen_standing = tracked(l) && !seen_moving;
            l.kind == ObjectKind::Vehicle
                && l.contact_x < ONCOMING_REACH_M
                && (seen_moving || (left_turn && !seen_standing))
        });
        (across, oncoming)
    }

    /// One planning step `dt_s` long before the junction whose entry is at `entry_at_m` in
    /// distance driven: `across` and `oncoming` are what [`JunctionGap::conflicts`] saw (an
    /// oncoming conflict counts when the step before saw one too), `given_way` a green light
    /// for a car that does not turn across. Whether to hold the car.
    pub fn step(
        &mut self,
        entry_at_m: f64,
        (across, oncoming): (bool, bool),
        given_way: bool,
        dt_s: f64,
    ) -> bool {
        if (entry_at_m - self.at_m).abs() > 5.0 {
            *self = Self {
                at_m: entry_at_m,
                ..Self::default()
            };
        }
        let conflict = across || (oncoming && self.oncoming_before);
        self.oncoming_before = oncoming;
        self.quiet_s = if conflict { 0.0 } else { self.quiet_s + dt_s };
        let hold =
            !given_way && self.quiet_s < JUNCTION_QUIET_S && self.held_s < JUNCTION_HOLD_MAX_S;
        if hold {
            self.held_s += dt_s;
        }
        hold
    }

    /// The car is not waiting to enter a junction (too fast, or not near one): what it saw
    /// before counts no longer.
    pub fn leave(&mut self) {
        self.quiet_s = 0.0;
        self.oncoming_before = false;
    }
}

/// Oncoming vehicles farther than this do not hold a car at a junction's entry, m (the far
/// side's stop line is about 30 m from a car at its own).
pub const ONCOMING_REACH_M: f64 = 45.0;

/// Standing at a stop sign's line (seen, or a hidden signal's), the car goes only after its
/// looks to the sides have found no vehicle moving for this long, s: a car that will reach
/// the junction within the next five seconds or so is in view and moving now.
pub const LOOK_QUIET_S: f64 = 1.2;

/// A mover the side looks find within this bearing of straight ahead is the front
/// camera's concern (the junction-gap check and the car ahead), not cross traffic, degrees.
pub const LOOK_AHEAD_DEG: f64 = 12.0;

/// The unstick rule and the signal ahead. A car held longer than
/// [`AgentParams::unstick_after_s`] (a walker who stands at the kerb and never crosses, a
/// reading that never clears) moves on by the unstick rule — but not through a working
/// signal's red: when the signal ahead has been read green since the car stood still, it
/// is a working signal, and the rule waits while it reads red or amber and moves on its
/// green. A signal read red throughout (a lamp the car cannot read, a mask's red outline
/// taken for a lamp) does not hold the rule.
#[derive(Debug, Clone, Copy)]
pub struct UnstickSignal;

impl UnstickSignal {
    /// At a planning step: the lamp read ahead (if any) and the car's speed, and whether
    /// the signal had been read green since the car last stood still. Returns (the signal
    /// reads red or amber now, it has been read green since the car stood still).
    pub fn read(lamp: Option<Lamp>, speed_mps: f64, cycled: bool) -> (bool, bool) {
        let stop = matches!(lamp, Some(Lamp::Red | Lamp::Amber));
        let cycled = if speed_mps >= 0.1 {
            false
        } else {
            cycled || lamp == Some(Lamp::Green)
        };
        (stop, cycled)
    }

    /// Whether the unstick rule waits.
    pub fn waits(stop: bool, cycled: bool) -> bool {
        stop && cycled
    }
}

impl Baseline {
    /// A fresh agent.
    pub fn new(params: AgentParams) -> Self {
        Self {
            params,
            planner: ReferencePlanner::new(),
            intent: Intent::default(),
            integral: 0.0,
            stopped_s: 0.0,
            sign_stop_s: 0.0,
            sign_free_until_m: f64::NEG_INFINITY,
            unstick_left_s: 0.0,
            unstick_count: 0,
            plans: 0,
            plan_errors: 0,
            debug: String::new(),
            red_stop_at_m: None,
            sign_stop_at_m: None,
            lead_memory: LeadMemory::default(),
            hidden_signal: false,
            lost: Vec::new(),
            hidden_stop: false,
            cross_quiet_s: 0.0,
            look_quiet_s: 0.0,
            kerb: KerbWatch::default(),
            junction_gap: JunctionGap::default(),
            zebra_at_m: None,
            signal_stop: false,
            signal_cycled: false,
            objects: Vec::new(),
            driver: None,
        }
    }

    /// An agent whose speed a planner under test decides — any [`Planner`]: a remote
    /// policy behind AlpaSim's egodriver contract or HTTP, or your own — instead of the
    /// baseline's rules. Every step the planner gets the same frames and ego history as the
    /// reference planner would (with `scene_id` and `seed` as its request's identity), and
    /// the agent follows its trajectory's speed profile ([`trajectory_intent`]) along the
    /// route, capped by the cruise and turn speeds; a failed call brakes. The baseline's own
    /// rules (lead keeping, stop memories, the unstick rule) are off: the planner answers for
    /// them. The reference perception still runs on the frames, as the override's detector
    /// ([`Baseline::objects`]), not as a driver.
    pub fn driven_by(
        params: AgentParams,
        planner: Arc<dyn Planner>,
        scene_id: String,
        seed: u64,
    ) -> Self {
        Self {
            driver: Some(Driver {
                planner,
                scene_id,
                seed,
            }),
            ..Self::new(params)
        }
    }

    /// Tells the agent whether a traffic light or sign ahead is hidden in a region its
    /// perception lost (the override's hazard inference says so). While it is, the agent
    /// reads no lamp state (the lamp it sees may be the mask) and treats the junction as an
    /// all-way stop, as drivers treat a dark signal: it stops at the stop line it perceives
    /// (or where it would stop for the light), waits as at a stop sign, then proceeds.
    pub fn set_hidden_signal(&mut self, hidden: bool) {
        if hidden && !self.hidden_signal {
            self.red_stop_at_m = None;
        }
        self.hidden_signal = hidden;
    }

    /// Whether the agent wants to look to the sides now: it stands at a stop sign's line
    /// (seen, or the all-way stop of a hidden signal), where it must see the cross street
    /// before it goes. The caller then gives it what its side cameras see ([`Self::look`]).
    pub fn wants_look(&self, speed_mps: f64, odometer_m: f64) -> bool {
        self.driver.is_none()
            && speed_mps < 0.1
            && self.sign_stop_at_m.is_some_and(|m| odometer_m > m - 3.0)
    }

    /// What the side cameras show at a look, `dt_s` after the previous one (the time the
    /// two frames span): the vehicles that moved between the two frames
    /// ([`fogline_planner::detect::movers`], both cameras), or `None` for the first look
    /// (nothing to compare yet). A mover more than [`LOOK_AHEAD_DEG`] to a side is cross
    /// traffic: the stop at the line ends only after [`LOOK_QUIET_S`] of looks without one.
    pub fn look(&mut self, movers: Option<&[MoverSeen]>, dt_s: f64) {
        let Some(movers) = movers else {
            return;
        };
        let cross = movers
            .iter()
            .any(|m| m.bearing_rad.abs() > LOOK_AHEAD_DEG.to_radians());
        if cross {
            if self.look_quiet_s > 0.0 {
                log::debug!("cross traffic in the side looks: {movers:?}");
            }
            self.look_quiet_s = 0.0;
        } else {
            self.look_quiet_s += dt_s;
        }
    }

    /// Tells the agent which regions of its latest frames are lost (the override recognised
    /// them as deficits): its lamp and sign readers ignore them. Empty when nobody knows.
    pub fn set_lost(&mut self, lost: Vec<Lost>) {
        self.lost = lost;
    }

    /// The road users found at the last planning step, with their boxes in the frames (the
    /// perception's pixel-based detections).
    pub fn objects(&self) -> &[ObjectSeen] {
        &self.objects
    }

    /// The last intent.
    pub fn intent(&self) -> Intent {
        self.intent
    }

    /// The target speed now: the last intent's, capped by the braking profile to its stop
    /// point, m/s.
    pub fn target_now(&self, odometer_m: f64) -> f64 {
        let profile = |at: Option<f64>| {
            at.map_or(f64::INFINITY, |m| {
                let d = m - odometer_m - 0.3;
                if d < 0.3 {
                    0.0
                } else {
                    (2.0 * self.params.stop_decel_mps2 * d).sqrt()
                }
            })
        };
        self.intent
            .target_mps
            .min(profile(self.intent.stop_at_m))
            .min(profile(self.red_stop_at_m))
            .min(profile(self.sign_stop_at_m))
    }

    /// The deceleration that stops the car at the nearest of its stop points from speed
    /// `v`, m/s² (0 without one).
    pub fn needed_decel(&self, odometer_m: f64, v: f64) -> f64 {
        [
            self.intent.stop_at_m,
            self.red_stop_at_m,
            self.sign_stop_at_m,
        ]
        .into_iter()
        .flatten()
        .map(|m| {
            let d = m - odometer_m - 0.3;
            v * v / (2.0 * d.max(0.05))
        })
        .fold(0.0, f64::max)
    }

    /// Whether the unstick rule is driving.
    pub fn unsticking(&self) -> bool {
        self.unstick_left_s > 0.0
    }

    /// A planning step: runs the planner on the frames and updates the target speed.
    /// `turn_cap_mps` is the cap before the route's next turn; `odometer_m` the distance
    /// driven so far; `speed_scale` converts the planner's perceived speeds back to m/s when
    /// the frames are spaced wider than 0.1 s (see [`crate::run`]).
    pub fn plan(
        &mut self,
        input: AgentInput<'_>,
        speed_mps: f64,
        turn_cap_mps: f64,
        odometer_m: f64,
        speed_scale: f64,
    ) -> Intent {
        self.plans += 1;
        let t_s = input.time_s;
        let pin = PlannerInput {
            cameras: input.cameras,
            ego_history: input.history,
        };
        let p = &self.params;
        let cruise = p.cruise_mps.min(turn_cap_mps);
        // About to enter a junction from (near) a standstill: the perception looks at the
        // oncoming lane too, for the gap check below.
        let entering = input.junction.filter(|j| {
            self.driver.is_none()
                && (speed_mps < JUNCTION_START_MPS || j.left_turn)
                && j.entry_m > 0.5
                && j.entry_m < JUNCTION_YIELD_REACH_M
        });
        let knowing = fogline_planner::perceive::Knowing {
            lost: &self.lost,
            nav_kappa: Some(input.nav_kappa),
            left_lane: entering.is_some()
                || self.zebra_at_m.is_some_and(|z| {
                    z - odometer_m > -2.0 && z - odometer_m < FAR_CROSSING_REACH_M
                }),
            kerb: self.driver.is_none(),
        };
        let out = self.planner.plan_knowing(&pin, &knowing);
        if let Some(driver) = &self.driver {
            // The reference perception is the override's detector here, not the driver.
            self.objects = match &out {
                Ok((perc, _)) => fogline_planner::detect::objects(perc, &pin),
                Err(_) => Vec::new(),
            };
            let request = PlanRequest {
                scene_id: &driver.scene_id,
                seed: driver.seed,
                input: pin,
            };
            self.intent = match driver.planner.plan(&request) {
                Ok(answer) => trajectory_intent(
                    &answer.trajectory.xy,
                    answer.decision,
                    odometer_m,
                    cruise,
                    speed_scale,
                ),
                Err(e) => {
                    self.plan_errors += 1;
                    log::debug!("planner under test at {odometer_m:.1} m: {e}");
                    Intent {
                        failed: true,
                        ..Intent::default()
                    }
                }
            };
            return self.intent;
        }
        let (perc, plan) = match out {
            Ok(x) => x,
            Err(_) => {
                self.plan_errors += 1;
                self.objects.clear();
                self.intent = Intent {
                    decision: None,
                    target_mps: 0.0,
                    stop_at_m: None,
                    lead_gap_m: None,
                    failed: true,
                    unstick_stop_at_m: None,
                };
                return self.intent;
            }
        };
        if log::log_enabled!(log::Level::Debug) {
            self.debug = format!(
                "lead {:?} kerb {:?} zebra {:?} line {:?} light {:?} sign {:?} end {:?} lane {:?} road {:.0}",
                perc.lead.map(|l| (
                    (l.contact_x * 10.0).round() / 10.0,
                    l.kind,
                    (l.width_m * 10.0).round() / 10.0,
                    (l.speed * 10.0).round() / 10.0,
                    (l.speed_se * 10.0).round() / 10.0,
                    (l.right_edge * 10.0).round() / 10.0,
                    (l.left_edge * 10.0).round() / 10.0,
                    (l.confidence * 100.0).round() / 100.0
                )),
                perc.kerb_object.map(|k| (
                    (k.contact_x * 10.0).round() / 10.0,
                    (k.right_edge * 10.0).round() / 10.0,
                    (k.left_edge * 10.0).round() / 10.0,
                )),
                perc.zebra,
                perc.stop_line,
                perc.light,
                perc.stop_sign,
                perc.road_end,
                perc.lane.map(|l| (
                    (l.offset * 100.0).round() / 100.0,
                    (l.width * 100.0).round() / 100.0,
                    (l.heading * 1000.0).round() / 1000.0
                )),
                perc.road_lum
            );
        }
        self.objects = fogline_planner::detect::objects(&perc, &pin);
        // The signal ahead, for the unstick rule: whether it reads red or amber now, and
        // whether it has been read green since the car stood still.
        // A lamp in a lost region is no reading.
        let lamp = perc.light.map(|(l, _)| l).filter(|_| !self.hidden_signal);
        (self.signal_stop, self.signal_cycled) =
            UnstickSignal::read(lamp, speed_mps, self.signal_cycled);
        // Cross traffic: a vehicle ahead moving across the ego's path.
        let crossing = perc.lead.is_some_and(|l| {
            l.kind == ObjectKind::Vehicle && l.contact_x < 40.0 && l.lateral_speed.abs() > 1.0
        });
        self.cross_quiet_s = if crossing {
            0.0
        } else {
            self.cross_quiet_s + 0.1 * speed_scale
        };
        let mut decision = plan.decision;
        let mut planned_stop = plan.stop_at;
        if self.hidden_signal {
            // The lamp or sign sits in a lost region: its reading is no evidence. An unknown
            // signal is an all-way stop at the line.
            self.red_stop_at_m = None;
            // The stop line it sees, else where a line would be before the approach's
            // crossing it sees (5 m short of it: the same point), else the planner's stop
            // for the lamp or sign (traced: a junction whose line the car did not see, a red
            // read from an unmasked far head one step and not the next, and the car never
            // stopped). A point more than a metre behind the car is passed.
            let stop_decision =
                matches!(decision, Decision::StopForRedLight | Decision::StopForSign);
            let line = perc
                .stop_line
                .map(|l| l - EGO_FRONT_M - 0.5)
                .or(perc
                    .zebra
                    // The approach's own crossing, before the junction the route enters
                    // (not the far one, seen from inside the junction).
                    .filter(|&z| input.junction.is_some_and(|j| z <= j.entry_m + 1.0))
                    .map(|z| z - CROSSING_GAP_M - EGO_FRONT_M))
                .or(plan.stop_at.filter(|_| stop_decision))
                .filter(|&a| a > -1.0);
            if let Some(at) = line.filter(|&a| a < HIDDEN_SIGNAL_REACH_M) {
                decision = Decision::StopForSign;
                planned_stop = Some(at);
                self.hidden_stop = true;
            } else if matches!(
                decision,
                Decision::StopForRedLight | Decision::StopForSign | Decision::ProceedOnGreen
            ) {
                decision = Decision::KeepLane;
            }
        }
        if decision == Decision::StopForSign && odometer_m < self.sign_free_until_m {
            decision = Decision::KeepLane;
        }
        // A walker in the lane well beyond the nearest crossing is not on it: the car
        // yields short of where the walker is, as to any road user in its lane, not at a
        // crossing it can pass.
        let walker_beyond = decision == Decision::YieldToCrossing
            && perc
                .lead
                .zip(perc.zebra)
                .is_some_and(|(l, z)| l.contact_x > z + WALKER_ON_CROSSING_M);
        if walker_beyond {
            planned_stop = perc
                .lead
                .map(|l| l.contact_x - fogline_planner::plan::WALKER_GAP_M - EGO_FRONT_M);
        }
        // A walker on the crossing's far half, walking towards the car's lane or standing
        // on it, has the way too: the car stops before the crossing (where it stops for
        // one on its own half).
        if let Some(z) = perc.zebra {
            self.zebra_at_m = Some(odometer_m + z);
        }
        let far_walker = walker_on_far_crossing(perc.left_object.as_ref(), perc.zebra, speed_scale);
        if far_walker
            && !matches!(
                decision,
                Decision::StopForRedLight | Decision::StopForSign | Decision::YieldToCrossing
            )
        {
            decision = Decision::YieldToCrossing;
            planned_stop = perc.zebra.map(|z| z - CROSSING_GAP_M - EGO_FRONT_M);
            log::debug!(
                "walker on the far half of the crossing {:.1} m ahead: {:?}",
                perc.zebra.unwrap_or(f64::NAN),
                perc.left_object
                    .map(|l| (l.contact_x, l.speed, l.lateral_speed))
            );
        }
        // Someone stepping off the right kerb into the car's path: the car yields short of
        // where they are, as to a walker in its lane (or stops at its nearer stop point).
        let towards = self.kerb.update(
            t_s,
            perc.kerb_object
                .map(|k| (odometer_m + k.contact_x, k.left_edge)),
        );
        if let Some((k, v)) = perc.kerb_object.zip(towards)
            && stepping_off_kerb(v, k.left_edge, k.contact_x, speed_mps)
        {
            let at = k.contact_x - fogline_planner::plan::WALKER_GAP_M - EGO_FRONT_M;
            let stops = matches!(
                decision,
                Decision::StopForRedLight | Decision::StopForSign | Decision::YieldToCrossing
            );
            if !stops || planned_stop.is_none_or(|p| at < p) {
                decision = Decision::YieldToCrossing;
                planned_stop = Some(at);
            }
            log::debug!(
                "walker stepping off the kerb {:.1} m ahead: across {v:.1} m/s, edge {:.1} m",
                k.contact_x,
                k.left_edge
            );
        }
        // The planned stop point, or further back: 5.5 m before a crossing the planner sees
        // short of it (where the stop line is; this keeps the crossing's stripes out of the
        // planner's road-brightness reference while the car waits).
        let stop_dist = || {
            // The perceived stop point (the trajectory's end falls short of it when the
            // horizon is short: standing still, it is where the car stands).
            let planned = planned_stop.map_or_else(
                || plan.trajectory.xy.last().map_or(0.0, |q| q[0].hypot(q[1])),
                |d| d.max(0.0),
            );
            // A crossing short of the red light's head by more than a junction's width is
            // another junction's (traced: a head read 70–110 m down the road put the stop
            // before the crossing of the stop-sign junction the car had just stopped at, and
            // the car waited there for a green it could not see).
            let before_zebra = perc
                .zebra
                .filter(|&z| {
                    perc.light
                        .is_none_or(|(_, d)| z < d && d - z < LIGHT_TO_LINE_MAX_M)
                })
                .map(|z| z - CROSSING_GAP_M - EGO_FRONT_M);
            match before_zebra {
                Some(b) if b < planned + 8.0 && !walker_beyond => planned.min(b.max(0.0)),
                _ => planned,
            }
        };
        let lead_gap = perc
            .lead
            .filter(|l| l.kind == ObjectKind::Vehicle)
            .map(|l| l.gap);
        // Red-light memory: a red or amber light keeps the car at its stop point until green
        // is seen (the head may leave the cameras' view as the car gets close).
        match decision {
            // The latest estimate while the light is seen: the stop line is found only as
            // the car gets close, and an early guess from the light's distance alone can be
            // metres short.
            Decision::StopForRedLight => {
                self.red_stop_at_m = red_memory(self.red_stop_at_m, odometer_m, stop_dist());
            }
            Decision::ProceedOnGreen => self.red_stop_at_m = None,
            _ => {}
        }
        if perc.light.is_some_and(|(l, _)| l == Lamp::Green) {
            self.red_stop_at_m = None;
        }
        if self.red_stop_at_m.is_some_and(|m| odometer_m > m + 1.0) {
            self.red_stop_at_m = None;
        }
        if self.sign_stop_at_m.is_some_and(|m| odometer_m > m + 1.0) {
            self.sign_stop_at_m = None;
            self.hidden_stop = false;
        }
        let mut stop_at = None;
        let target = match decision {
            Decision::StopForRedLight | Decision::StopForSign | Decision::YieldToCrossing => {
                let at = odometer_m + stop_dist();
                stop_at = Some(at);
                if decision == Decision::StopForSign {
                    // The latest estimate while the sign is seen (as for red lights).
                    self.sign_stop_at_m = Some(at);
                }
                cruise
            }
            _ => cruise,
        };
        // Gap acceptance at a junction entered from (near) a standstill: not while a vehicle
        // is seen moving across the path ahead or in the oncoming lane (one that stopped at
        // its line before the car and now takes its turn, one turning across, one coming
        // through), unless a green light gives the way and the car does not turn across.
        match entering {
            Some(j) => {
                let (across, oncoming) = JunctionGap::conflicts(
                    perc.lead.as_ref(),
                    perc.left_object.as_ref(),
                    j.left_turn,
                    speed_scale,
                );
                let green = perc.light.is_some_and(|(l, _)| l == Lamp::Green);
                let hold = self.junction_gap.step(
                    odometer_m + j.entry_m,
                    (across, oncoming),
                    green && !j.left_turn,
                    0.1 * speed_scale,
                );
                if hold {
                    let here = odometer_m + 0.6 + speed_mps * speed_mps / (2.0 * p.stop_decel_mps2);
                    stop_at = Some(stop_at.map_or(here, |s: f64| s.min(here)));
                    log::debug!(
                        "junction gap at {odometer_m:.1} m: entry in {:.1} m, across {across}, \
                         oncoming {oncoming}, {:?}; left {:?}",
                        j.entry_m,
                        self.junction_gap,
                        perc.left_object.map(|l| (
                            (l.contact_x * 10.0).round() / 10.0,
                            (l.speed * 10.0).round() / 10.0,
                            (l.speed_se * 10.0).round() / 10.0,
                            (l.lateral_speed * 10.0).round() / 10.0,
                            l.frames_seen()
                        ))
                    );
                }
            }
            None => self.junction_gap.leave(),
        }
        // Whatever the decision, the car keeps its distance to the road user ahead in its
        // lane: the agent steers along its route and never leaves the lane, so a stop, a
        // turn or a pass is driven behind whoever is in front.
        // A vehicle standing (or crawling) ahead is remembered: close up it can drop out of
        // the frames (its contact below the wide camera's view, or on paint that reads
        // like it), and a car that no longer sees it must not drive into it.
        self.lead_memory
            .update(perc.lead.as_ref(), odometer_m, self.plans, t_s, speed_scale);
        let clear_m = perc.lead.as_ref().map_or_else(
            || perc.road_end.map_or(f64::INFINITY, |x| x - EGO_FRONT_M),
            |l| l.gap,
        );
        self.lead_memory.seen_clear(odometer_m, clear_m);
        let remembered = perc
            .lead
            .is_none()
            .then(|| self.lead_memory.recall(odometer_m))
            .flatten();
        // A lead whose face could not be followed between frames carries the car's own
        // speed (the perception's placeholder), and behind it the car would close in as if
        // it drove away at that speed (traced: seed 0 route 25, a car standing at a red read
        // untracked from 21 m in, driven into once it dropped out of view). The car takes
        // it at the speed of its positions over the last planning steps (a vehicle's range
        // rate), else as standing: an unknown speed is not the car's own.
        let judged = perc
            .lead
            .map(|l| untracked_speed(l, self.lead_memory.range_rate(), speed_scale));
        let ahead = judged.as_ref().or(remembered.as_ref());
        let target = target.min(follow_cap(ahead, speed_mps, cruise, speed_scale));
        // What the unstick rule keeps clear of: the vehicle ahead seen beyond
        // `UNSTICK_KEEP_M`, else the one remembered (which may be closer by now).
        let vehicle_gap = perc
            .lead
            .filter(|l| l.kind == ObjectKind::Vehicle && l.gap >= UNSTICK_KEEP_M)
            .map(|l| l.gap)
            .or(self.lead_memory.gap(odometer_m));
        // A crossing close ahead is crossed slowly: a walker about to step onto it is small
        // in the frames until close, and a slower car sees them in more frames before it is
        // there.
        let target = target.min(crossing_cap(perc.zebra, p));
        if log::log_enabled!(log::Level::Debug) {
            use std::fmt::Write as _;
            let _ = write!(
                self.debug,
                " | mem red {:?} sign {:?} recall {:?} follow {:.1} xing {:.1}",
                self.red_stop_at_m.map(|m| (m - odometer_m).round()),
                self.sign_stop_at_m.map(|m| (m - odometer_m).round()),
                remembered.map(|l| (l.gap * 10.0).round() / 10.0),
                follow_cap(ahead, speed_mps, cruise, speed_scale),
                crossing_cap(perc.zebra, p),
            );
        }
        self.intent = Intent {
            decision: Some(plan.decision),
            target_mps: target,
            stop_at_m: stop_at,
            lead_gap_m: lead_gap,
            failed: false,
            unstick_stop_at_m: vehicle_gap.map(|g| {
                let clear = if self.lead_memory.seen_driving() {
                    UNSTICK_CLEAR_M
                } else {
                    UNSTICK_KEEP_M
                };
                odometer_m + g - clear
            }),
        };
        self.intent
    }

    /// A control step (every simulation tick): speed PID on the current target, pure
    /// pursuit on the route. `route_s` is the ego's progress index on the dense route.
    pub fn control(
        &mut self,
        state: &VehicleState,
        route: &DenseRoute,
        route_index: usize,
        dt: f64,
        odometer_m: f64,
        bike: &BicycleParams,
    ) -> VehicleControl {
        let p = self.params;
        let v = state.speed_mps;
        // Stop-sign memory and the unstick rule.
        if v < 0.1 {
            self.stopped_s += dt;
            // Only a stop at the line counts (one in a queue further back does not).
            let at_sign = self.sign_stop_at_m.is_some_and(|m| odometer_m > m - 3.0);
            if at_sign {
                self.sign_stop_s += dt;
                let clear = (!self.hidden_stop || self.cross_quiet_s >= HIDDEN_SIGNAL_QUIET_S)
                    && self.look_quiet_s >= LOOK_QUIET_S - 1e-9;
                if self.sign_stop_s >= 1.5 && clear {
                    self.hidden_stop = false;
                    self.sign_free_until_m = odometer_m + p.sign_memory_m;
                    self.sign_stop_at_m = None;
                    self.sign_stop_s = 0.0;
                }
            }
        } else {
            self.stopped_s = 0.0;
            self.sign_stop_s = 0.0;
            self.look_quiet_s = 0.0;
        }
        if self.unstick_left_s > 0.0 {
            self.unstick_left_s -= dt;
        } else if self.stopped_s >= p.unstick_after_s
            && self.driver.is_none()
            && !UnstickSignal::waits(self.signal_stop, self.signal_cycled)
        {
            self.unstick_left_s = p.unstick_for_s;
            self.unstick_count += 1;
            log::debug!(
                "unstick at {odometer_m:.1} m: {:?}, room {:?}, lead seen driving {} | {}",
                self.intent.decision,
                self.intent.unstick_stop_at_m.map(|m| m - odometer_m),
                self.lead_memory.seen_driving(),
                self.debug
            );
            self.stopped_s = 0.0;
        }
        let target = if self.unstick_left_s > 0.0 {
            p.unstick_mps.min(unstick_cap(
                self.intent.unstick_stop_at_m.map(|m| m - odometer_m),
                p.stop_decel_mps2,
            ))
        } else {
            self.target_now(odometer_m)
        };
        let steer = pursuit_steer(state, route, route_index, bike);
        // A stop point closer than the planned deceleration allows (a walker stepping out,
        // a light turning): brake as hard as it takes, up to full braking. The unstick rule
        // ignores the planner's stop points but not the vehicle ahead.
        let need = if self.unstick_left_s <= 0.0 {
            self.needed_decel(odometer_m, v)
        } else {
            self.intent
                .unstick_stop_at_m
                .map_or(0.0, |m| v * v / (2.0 * (m - odometer_m).max(0.05)))
        };
        if let Some(brake) = emergency_brake(need, p.stop_decel_mps2, bike) {
            self.integral = 0.0;
            return VehicleControl {
                throttle: 0.0,
                brake,
                steer,
            };
        }
        speed_control(&mut self.integral, v, target, dt, steer)
    }
}

/// The speed PID: throttle towards `target`, brake when too fast or when it should stand.
pub fn speed_control(
    integral: &mut f64,
    v: f64,
    target: f64,
    dt: f64,
    steer: f64,
) -> VehicleControl {
    let e = target - v;
    if target < 0.05 {
        *integral = 0.0;
        return VehicleControl {
            throttle: 0.0,
            brake: 1.0,
            steer,
        };
    }
    if e < -0.3 {
        *integral = 0.0;
        return VehicleControl {
            throttle: 0.0,
            brake: (0.8 * -e).clamp(0.05, 1.0),
            steer,
        };
    }
    *integral = (*integral + e * dt).clamp(-2.0, 5.0);
    VehicleControl {
        throttle: (0.8 * e + 0.1 * *integral).clamp(0.0, 1.0),
        brake: 0.0,
        steer,
    }
}

/// Pure pursuit on the dense route from `index`.
pub fn pursuit_steer(
    state: &VehicleState,
    route: &DenseRoute,
    index: usize,
    bike: &BicycleParams,
) -> f64 {
    let look = (0.8 * state.speed_mps + 2.0).clamp(3.5, 10.0);
    let o = [state.x_m, state.y_m];
    let mut k = index;
    while k + 1 < route.len() && dist(route.points[k], o) < look {
        k += 1;
    }
    let target = route.points[k];
    let h = state.heading();
    let d = sub(target, o);
    let x = dot(d, h);
    let y = -h[1] * d[0] + h[0] * d[1];
    let l2 = (x * x + y * y).max(1.0);
    let kappa = 2.0 * y / l2;
    bike.steer_for_curvature(kappa)
}

/// The speed cap before a zebra crossing seen `zebra` m ahead (`None`: none seen):
/// `zebra_mps` within [`ZEBRA_CAUTION_M`], else none.
pub fn crossing_cap(zebra: Option<f64>, p: &AgentParams) -> f64 {
    match zebra {
        Some(z) if z < ZEBRA_CAUTION_M => p.zebra_mps,
        _ => f64::INFINITY,
    }
}

/// The unstick rule escapes what only looks like an obstacle (static clutter read as a
/// car: a kerb across a turn, paint at night), but it does not drive into a vehicle standing
/// ahead: it stops this far short of one that was never seen to move, by the remembered
/// position once the car is too close to see it, m. A vehicle read closer than this without
/// first being seen farther away is taken for a misreading and ignored.
pub const UNSTICK_KEEP_M: f64 = 2.0;

/// ... and this far short of one that was seen driving before it stood (a queue: as an
/// adaptive cruise control's radar keeps a stopped target it tracked while moving but
/// treats one never seen moving as clutter), m. Close up the perceived gap runs about a
/// metre long (traced on seed 0 route 30: 4.3 m read, 3.1 m true), and a queue that has
/// not moved in 55 s does not move for a car that closes up on it.
pub const UNSTICK_CLEAR_M: f64 = 4.0;

/// A vehicle ahead whose position (in distance driven) spread over more than this while it
/// was followed was seen driving, m (well above the spread of a standing one's readings).
pub const LEAD_DROVE_M: f64 = 3.0;

/// Consecutive sightings of the vehicle ahead farther apart than this (in distance driven)
/// are of different vehicles, m (a car at 15 m/s moves 6 m between planning steps).
pub const LEAD_SAME_M: f64 = 6.0;

/// The unstick rule's speed cap with `room` m left to where it must stand (`None`: no
/// vehicle ahead): its braking profile.
pub fn unstick_cap(room: Option<f64>, decel: f64) -> f64 {
    match room {
        Some(r) => (2.0 * decel * r.max(0.0)).sqrt(),
        None => f64::INFINITY,
    }
}

/// A vehicle ahead slower than this is remembered when it drops out of view, m/s.
pub const LEAD_MEMORY_MPS: f64 = 1.0;
/// Readings of the followed vehicle's position kept for its range rate (2 s at 2.5 Hz)...
pub const LEAD_RATE_READINGS: usize = 5;
/// ... which is read once at least three of them span this long, s (the slope of readings
/// scattered by ±0.5 m is then good to about ±0.5 m/s).
pub const LEAD_RATE_SPAN_S: f64 = 0.75;
/// For this long without seeing it again, s ...
pub const LEAD_MEMORY_S: f64 = 4.0;
/// ... unless it is closer than this, m: so close, a car's contact is below the wide
/// camera's view or on paint that reads like it, and not seeing it is weak evidence that
/// it left (a car that drives straight off is seen again as it pulls away; one that turns
/// away close ahead is not) ...
pub const LEAD_BLIND_M: f64 = 5.0;
/// ... when it is kept until the lane is seen clear this far past its rear, m (a car's
/// length and a margin).
pub const LEAD_CLEAR_PAST_M: f64 = 5.5;
/// A standing vehicle is remembered once seen twice, at most this many planning steps
/// apart ...
pub const LEAD_CONFIRM_PLANS: u64 = 3;
/// ... at positions (in distance driven) this close, m.
pub const LEAD_CONFIRM_M: f64 = 3.0;

/// The brake for a stop point that needs `need` m/s² (see [`Baseline::needed_decel`]):
/// `None` while the planned deceleration `planned` suffices (the speed PID follows the
/// braking profile), else the brake that gives `need` plus a margin, up to full braking.
pub fn emergency_brake(need: f64, planned: f64, bike: &BicycleParams) -> Option<f64> {
    (need > planned).then(|| (need / bike.brake_accel_mps2.abs() + 0.1).min(1.0))
}

/// The vehicle ahead last seen standing or crawling, remembered while it is out of view:
/// close up, its ground contact drops below the wide camera's view (or onto paint that
/// reads like it), and a car that no longer sees it must not drive into it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LeadMemory {
    /// Where its rear is, in distance driven, m; and when it was last seen, s.
    seen: Option<(f64, f64)>,
    /// A standing vehicle seen once and not yet confirmed: where, and the planning step.
    candidate: Option<(f64, u64)>,
    /// The vehicle ahead followed over consecutive steps: the least and greatest of its
    /// positions (in distance driven), the last one, and the step it was last seen, m.
    track: Option<(f64, f64, f64, u64)>,
    /// The followed vehicle's latest positions (in distance driven, m) with their times (s),
    /// newest last: its range rate, independent of the planner's speed reading.
    recent: [Option<(f64, f64)>; LEAD_RATE_READINGS],
}

impl LeadMemory {
    /// Updates the memory with planning step `plan`'s lead (`None`: none seen) at time
    /// `t_s`. A vehicle slower than [`LEAD_MEMORY_MPS`] seen at least [`UNSTICK_KEEP_M`]
    /// away is remembered once confirmed — seen again within [`LEAD_CONFIRM_PLANS`] steps
    /// and [`LEAD_CONFIRM_M`] of where it was, as a tracker confirms a track before acting
    /// on it (a one-off reading of clutter across a turn held cars for minutes) — and a
    /// consistent reading refreshes it; one read closer than that counts as none (such a
    /// reading alone is taken for a misreading: a kerb across a turn read so could hold
    /// the car for good); a moving vehicle replaces it. Without a lead it is forgotten once
    /// the car has reached it or, beyond [`LEAD_BLIND_M`], after [`LEAD_MEMORY_S`] — in
    /// time, not planning steps: a car standing idle looks less often. Within
    /// [`LEAD_BLIND_M`] only the lane seen clear past it forgets it
    /// ([`LeadMemory::seen_clear`]).
    pub fn update(
        &mut self,
        lead: Option<&LeadSeen>,
        odometer_m: f64,
        plan: u64,
        t_s: f64,
        speed_scale: f64,
    ) {
        if let Some(l) = lead.filter(|l| l.kind == ObjectKind::Vehicle && l.gap >= UNSTICK_KEEP_M) {
            let at = odometer_m + l.gap;
            self.track = Some(match self.track {
                Some((lo, hi, last, k))
                    if (at - last).abs() <= LEAD_SAME_M && plan.saturating_sub(k) <= 3 =>
                {
                    self.recent.rotate_left(1);
                    (lo.min(at), hi.max(at), at, plan)
                }
                _ => {
                    self.recent = [None; LEAD_RATE_READINGS];
                    (at, at, at, plan)
                }
            });
            self.recent[LEAD_RATE_READINGS - 1] = Some((at, t_s));
        }
        // Standing by either reading: the planner's speed (from the motion of the car's
        // face between frames) or the range rate of its tracked position, as a radar
        // tracker's range rate backs its Doppler. Closing on a standing car, the face's
        // registration can read it as moving with the ego (traced: seed 0 route 16, a car
        // read at the ego's 8 m/s was forgotten and driven into once out of view).
        let standing = |l: &LeadSeen| {
            l.speed / speed_scale < LEAD_MEMORY_MPS
                || self.range_rate().is_some_and(|v| v < LEAD_MEMORY_MPS)
        };
        match lead.filter(|l| l.kind == ObjectKind::Vehicle) {
            Some(l) if l.gap >= UNSTICK_KEEP_M && standing(l) => {
                let at = odometer_m + l.gap;
                let near = |a: f64| (a - at).abs() <= LEAD_CONFIRM_M;
                let confirmed = self.seen.is_some_and(|(a, _)| near(a))
                    || self.candidate.is_some_and(|(a, k)| {
                        near(a) && plan.saturating_sub(k) <= LEAD_CONFIRM_PLANS
                    });
                if confirmed {
                    self.seen = Some((at, t_s));
                    self.candidate = None;
                } else {
                    self.candidate = Some((at, plan));
                }
            }
            Some(l) if l.gap >= UNSTICK_KEEP_M => {
                self.seen = None;
                self.candidate = None;
            }
            // None, or a reading too close to trust alone: neither moves nor refreshes it.
            // Out of view close ahead it stays until the lane is seen clear past it
            // ([`LeadMemory::seen_clear`]); farther on, not seeing it is evidence enough.
            _ => {
                if self.seen.is_some_and(|(at, seen_s)| {
                    at < odometer_m
                        || (at - odometer_m >= LEAD_BLIND_M && t_s - seen_s > LEAD_MEMORY_S)
                }) {
                    self.seen = None;
                }
            }
        }
    }

    /// Forgets the remembered vehicle once the frames show the ego lane free of anything
    /// for `clear_m` m ahead of the bumper (the perceived lead's gap, else the road's end,
    /// else the perception's reach) and that reaches a car's length past where it stood:
    /// the ground it stood on is seen, so it has gone. This is the only way a vehicle
    /// remembered within [`LEAD_BLIND_M`] is forgotten (forgotten after 30 s instead, a car
    /// that stood ahead through a long red, its contact out of view and its body read as
    /// the road's end, was driven into: seed 0 route 1 at 387 s).
    pub fn seen_clear(&mut self, odometer_m: f64, clear_m: f64) {
        if self
            .seen
            .is_some_and(|(at, _)| clear_m > at - odometer_m + LEAD_CLEAR_PAST_M)
        {
            self.seen = None;
        }
    }

    /// The followed vehicle's speed from its tracked positions (least-squares slope over
    /// the last [`LEAD_RATE_READINGS`]), m/s; `None` until at least three readings span
    /// [`LEAD_RATE_SPAN_S`].
    pub fn range_rate(&self) -> Option<f64> {
        let pts: Vec<(f64, f64)> = self.recent.iter().flatten().copied().collect();
        let (first, last) = (pts.first()?, pts.last()?);
        if pts.len() < 3 || last.1 - first.1 < LEAD_RATE_SPAN_S {
            return None;
        }
        let n = pts.len() as f64;
        let tm = pts.iter().map(|p| p.1).sum::<f64>() / n;
        let xm = pts.iter().map(|p| p.0).sum::<f64>() / n;
        let (sxy, sxx) = pts.iter().fold((0.0, 0.0), |(a, b), p| {
            (a + (p.1 - tm) * (p.0 - xm), b + (p.1 - tm) * (p.1 - tm))
        });
        Some(sxy / sxx)
    }

    /// Whether the vehicle ahead (the last one followed) was seen driving: its position
    /// spread over more than [`LEAD_DROVE_M`] while it was followed.
    pub fn seen_driving(&self) -> bool {
        self.track
            .is_some_and(|(lo, hi, _, _)| hi - lo > LEAD_DROVE_M)
    }

    /// The remembered gap at `odometer_m`, m.
    pub fn gap(&self, odometer_m: f64) -> Option<f64> {
        self.seen.map(|(at, _)| at - odometer_m)
    }

    /// The remembered vehicle as a standing lead at `odometer_m`.
    pub fn recall(&self, odometer_m: f64) -> Option<LeadSeen> {
        let gap = self.gap(odometer_m)?;
        Some(LeadSeen {
            contact_x: gap + EGO_FRONT_M,
            gap,
            speed: 0.0,
            speed_se: 0.0,
            lateral_speed: 0.0,
            braking: false,
            kind: ObjectKind::Vehicle,
            width_m: 1.8,
            right_edge: -0.9,
            left_edge: 0.9,
            confidence: 0.0,
            track: [None; 4],
        })
    }
}

/// `lead` as the car judges its speed: as perceived when its face was followed between
/// frames; otherwise (the perception then reports the car's own speed as a placeholder) a
/// vehicle at `range_rate` (m/s, the speed of its positions over the last planning steps,
/// [`LeadMemory::range_rate`]) when there is one, and anything else as standing.
/// `speed_scale` converts m/s to the planner's speeds.
pub fn untracked_speed(lead: LeadSeen, range_rate: Option<f64>, speed_scale: f64) -> LeadSeen {
    if lead.frames_seen() >= 2 {
        return lead;
    }
    let rate = range_rate.filter(|_| lead.kind == ObjectKind::Vehicle);
    LeadSeen {
        speed: rate.map_or(0.0, |v| v.max(0.0)) * speed_scale,
        ..lead
    }
}

/// The speed cap behind the perceived road user ahead in the ego lane (`None`: no cap):
/// the intelligent driver model's acceleration behind it (−1 m/s² more when its brake lamps
/// are lit), projected 0.5 s ahead, within `[0, cruise]`. `speed_scale` converts the
/// planner's perceived speed back to m/s.
pub fn follow_cap(lead: Option<&LeadSeen>, speed_mps: f64, cruise: f64, speed_scale: f64) -> f64 {
    lead.map_or(f64::INFINITY, |l| {
        let lead_v = l.speed / speed_scale;
        let a =
            idm(speed_mps, cruise, l.gap, speed_mps - lead_v) + if l.braking { -1.0 } else { 0.0 };
        (speed_mps + 0.5 * a).clamp(0.0, cruise)
    })
}

/// The intelligent driver model's acceleration (urban settings of the planner).
pub fn idm(v: f64, v0: f64, gap: f64, dv: f64) -> f64 {
    let (a, b, t, s0): (f64, f64, f64, f64) = (1.5, 3.0, 1.2, 4.0);
    let free = 1.0 - (v / v0.max(0.1)).powi(4);
    let s_star = s0 + (v * t + v * dv / (2.0 * (a * b).sqrt())).max(0.0);
    a * (free - (s_star / gap.max(0.1)).powi(2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_trajectory_gives_its_speed_half_a_second_ahead_and_where_it_rests() {
        // 0.8 m a waypoint at a quarter of the planner's rate: 2 m/s in simulation time.
        let cruising: Vec<[f64; 2]> = (1..=64).map(|k| [0.8 * f64::from(k), 0.0]).collect();
        let i = trajectory_intent(&cruising, None, 100.0, 8.0, 4.0);
        assert!((i.target_mps - 2.0).abs() < 1e-12, "{i:?}");
        assert_eq!(i.stop_at_m, None);
        assert!(!i.failed);
        // Capped by the route's speed.
        assert_eq!(
            trajectory_intent(&cruising, None, 0.0, 1.5, 4.0).target_mps,
            1.5
        );
        // Along a curve the path length counts, not the straight line.
        let arc: Vec<[f64; 2]> = (1..=64)
            .map(|k| {
                let a = 0.02 * f64::from(k);
                [20.0 * a.sin(), 20.0 * (1.0 - a.cos())]
            })
            .collect();
        let i = trajectory_intent(&arc, None, 0.0, 99.0, 1.0);
        assert!((i.target_mps - 4.0).abs() < 1e-3, "{i:?}");
        // Comes to rest 10 m ahead (from waypoint 10 on) and stands there: stop 10 m on.
        let stopping: Vec<[f64; 2]> = (1..=64).map(|k| [f64::from(k.min(10)), 0.0]).collect();
        let i = trajectory_intent(&stopping, Some(Decision::StopForSign), 50.0, 8.0, 1.0);
        assert_eq!(i.stop_at_m, Some(60.0));
        assert_eq!(i.decision, Some(Decision::StopForSign));
        // Still creeping at its end: no stop point.
        let creeping: Vec<[f64; 2]> = (1..=64).map(|k| [0.05 * f64::from(k), 0.0]).collect();
        assert_eq!(
            trajectory_intent(&creeping, None, 0.0, 8.0, 1.0).stop_at_m,
            None
        );
        // Standing still: target 0 and the stop point where it stands.
        let i = trajectory_intent(&[[0.0, 0.0]; 64], None, 7.0, 8.0, 4.0);
        assert_eq!((i.target_mps, i.stop_at_m), (0.0, Some(7.0)));
    }

    #[test]
    fn speed_pid_brakes_and_accelerates() {
        let mut i = 0.0;
        let c = speed_control(&mut i, 5.0, 8.0, 0.05, 0.0);
        assert!(c.throttle > 0.0 && c.brake == 0.0);
        let c = speed_control(&mut i, 8.0, 5.0, 0.05, 0.0);
        assert!(c.brake > 0.0 && c.throttle == 0.0);
        let c = speed_control(&mut i, 0.0, 0.0, 0.05, 0.0);
        assert_eq!(c.brake, 1.0);
    }

    #[test]
    fn pursuit_steers_towards_the_route() {
        let route = DenseRoute::new((0..50).map(|i| [i as f64, 0.0]).collect()).unwrap();
        let bike = BicycleParams::default();
        // Left of the route: steer right (positive).
        let s = VehicleState {
            x_m: 0.0,
            y_m: 1.0,
            yaw_rad: 0.0,
            speed_mps: 5.0,
        };
        assert!(pursuit_steer(&s, &route, 0, &bike) > 0.0);
        let s = VehicleState { y_m: -1.0, ..s };
        assert!(pursuit_steer(&s, &route, 0, &bike) < 0.0);
    }

    #[test]
    fn the_car_ahead_caps_the_speed_whatever_the_decision() {
        let lead = vehicle;
        assert_eq!(follow_cap(None, 8.0, 8.0, 1.0), f64::INFINITY);
        // A car standing 20 m ahead: slow down; closer, harder; 5 m ahead: stop.
        let standing = follow_cap(Some(&lead(20.0, 0.0)), 8.0, 8.0, 1.0);
        assert!(standing < 7.0, "{standing}");
        let closer = follow_cap(Some(&lead(12.0, 0.0)), 8.0, 8.0, 1.0);
        assert!(closer < standing - 1.0, "{closer} vs {standing}");
        assert_eq!(follow_cap(Some(&lead(5.0, 0.0)), 8.0, 8.0, 1.0), 0.0);
        // Far and as fast: free.
        let free = follow_cap(Some(&lead(60.0, 8.0)), 8.0, 8.0, 1.0);
        assert!(free > 7.5, "{free}");
        // Perceived speeds are time-lapsed by `speed_scale`: 32 "m/s" at scale 4 is 8 m/s.
        let lapsed = follow_cap(Some(&lead(20.0, 32.0)), 8.0, 8.0, 4.0);
        let plain = follow_cap(Some(&lead(20.0, 8.0)), 8.0, 8.0, 1.0);
        assert!((lapsed - plain).abs() < 1e-9);
        // Standing behind a standing car: stay.
        assert_eq!(follow_cap(Some(&lead(4.0, 0.0)), 0.0, 8.0, 1.0), 0.0);
    }

    #[test]
    fn a_lead_of_unknown_speed_is_taken_at_its_range_rate_or_as_standing() {
        // Untracked (no earlier frame matched), read at the car's own 8 m/s, 20 m ahead.
        let mut l = vehicle(20.0, 8.0 * 4.0);
        l.track = [Some(24.0), None, None, None];
        // Behind a lead taken at the car's speed the car would hardly slow; taken as
        // standing it brakes at once.
        let at_own = follow_cap(Some(&l), 8.0, 8.0, 4.0);
        assert!(at_own > 7.5, "{at_own}");
        let judged = untracked_speed(l, None, 4.0);
        assert_eq!(judged.speed, 0.0);
        let standing = follow_cap(Some(&judged), 8.0, 8.0, 4.0);
        assert!(standing < at_own - 1.0, "{standing}");
        // With a range rate from its tracked positions: that speed (never negative).
        assert_eq!(untracked_speed(l, Some(5.0), 4.0).speed, 20.0);
        assert_eq!(untracked_speed(l, Some(-1.0), 4.0).speed, 0.0);
        // A walker's range rate is a vehicle's, stale: a walker untracked stands.
        let walker = LeadSeen {
            kind: ObjectKind::Person,
            ..l
        };
        assert_eq!(untracked_speed(walker, Some(5.0), 4.0).speed, 0.0);
        // Tracked: as perceived.
        l.track[2] = Some(24.8);
        assert_eq!(untracked_speed(l, None, 4.0).speed, 32.0);
    }

    #[test]
    fn a_near_crossing_caps_the_speed() {
        let p = AgentParams::default();
        assert_eq!(crossing_cap(None, &p), f64::INFINITY);
        assert_eq!(crossing_cap(Some(35.0), &p), f64::INFINITY);
        assert_eq!(crossing_cap(Some(8.0), &p), p.zebra_mps);
        assert!(p.zebra_mps < p.cruise_mps);
    }

    fn vehicle(gap: f64, speed: f64) -> LeadSeen {
        LeadSeen {
            contact_x: gap + 4.0,
            gap,
            speed,
            speed_se: 0.1,
            lateral_speed: 0.0,
            braking: false,
            kind: ObjectKind::Vehicle,
            width_m: 1.8,
            right_edge: -0.9,
            left_edge: 0.9,
            confidence: 1.0,
            track: [None; 4],
        }
    }

    #[test]
    fn a_car_enters_a_junction_only_once_nothing_moves_across_it_or_towards_it() {
        // Frames 0.4 s apart read as 0.1 s: perceived speeds are four times the true ones.
        let scale = 4.0;
        let tracked = |mut l: LeadSeen, frames: usize| {
            for (k, t) in l.track.iter_mut().enumerate().take(frames) {
                *t = Some(l.contact_x + 0.1 * k as f64);
            }
            l
        };
        // Across the junction at its own line, standing (its speed read with some scatter):
        // no conflict; starting towards the car at 1.5 m/s, or coming through: a conflict.
        let standing = tracked(vehicle(26.0, 0.8 * scale), 4);
        let starting = tracked(vehicle(26.0, -1.5 * scale), 4);
        assert_eq!(
            JunctionGap::conflicts(None, Some(&standing), false, scale),
            (false, false)
        );
        assert_eq!(
            JunctionGap::conflicts(None, Some(&starting), false, scale),
            (false, true)
        );
        // Not when seen in fewer than three frames, nor beyond the reach, nor a person.
        let glimpse = tracked(vehicle(26.0, -6.0 * scale), 2);
        assert_eq!(
            JunctionGap::conflicts(None, Some(&glimpse), false, scale),
            (false, false)
        );
        let far = tracked(vehicle(ONCOMING_REACH_M + 1.0, -6.0 * scale), 4);
        assert_eq!(
            JunctionGap::conflicts(None, Some(&far), false, scale),
            (false, false)
        );
        let walker = LeadSeen {
            kind: ObjectKind::Person,
            ..starting
        };
        assert_eq!(
            JunctionGap::conflicts(None, Some(&walker), false, scale),
            (false, false)
        );
        // A vehicle crossing the path ahead; one ahead driving away is no conflict.
        let crossing = LeadSeen {
            lateral_speed: -4.0 * scale,
            ..tracked(vehicle(12.0, 0.0), 3)
        };
        assert_eq!(
            JunctionGap::conflicts(Some(&crossing), None, false, scale),
            (true, false)
        );
        let away = tracked(vehicle(12.0, 5.0 * scale), 4);
        assert_eq!(
            JunctionGap::conflicts(Some(&away), None, false, scale),
            (false, false)
        );

        // Turning left across the oncoming lane: an oncoming vehicle too quick to track is
        // a conflict, one seen standing is not.
        assert_eq!(
            JunctionGap::conflicts(None, Some(&glimpse), true, scale),
            (false, true)
        );
        assert_eq!(
            JunctionGap::conflicts(None, Some(&standing), true, scale),
            (false, false)
        );

        // Held while the conflict lasts and for JUNCTION_QUIET_S after it.
        let dt = 0.4;
        let mut gap = JunctionGap::default();
        for _ in 0..5 {
            assert!(gap.step(200.0, (true, false), false, dt));
        }
        let mut quiet_steps = 0;
        while gap.step(200.2, (false, false), false, dt) {
            quiet_steps += 1;
            assert!(quiet_steps < 10);
        }
        let quiet = |steps: usize| steps as f64 * dt;
        assert!(quiet(quiet_steps) < JUNCTION_QUIET_S);
        assert!(quiet(quiet_steps + 1) >= JUNCTION_QUIET_S - 1e-9);
        // A green light gives the way (to a car that does not turn across).
        let mut gap = JunctionGap::default();
        assert!(!gap.step(300.0, (true, false), true, dt));
        // A conflict that never ends holds the car at most JUNCTION_HOLD_MAX_S.
        let mut gap = JunctionGap::default();
        let mut held = 0.0;
        while gap.step(400.0, (true, false), false, dt) {
            held += dt;
            assert!(held <= JUNCTION_HOLD_MAX_S + dt);
        }
        assert!(held >= JUNCTION_HOLD_MAX_S - 1e-9);
        // The next junction starts afresh.
        assert!(gap.step(520.0, (true, false), false, dt));

        // The oncoming lane: a reading on one planning step does not hold the car (after
        // quiet steps it goes), two running do.
        let mut gap = JunctionGap::default();
        let quiet_start = (JUNCTION_QUIET_S / dt).ceil() as usize;
        for _ in 0..quiet_start {
            gap.step(600.0, (false, false), false, dt);
        }
        assert!(!gap.step(600.0, (false, true), false, dt), "a glimpse");
        assert!(!gap.step(600.0, (false, false), false, dt));
        assert!(
            !gap.step(600.0, (false, true), false, dt),
            "another glimpse"
        );
        assert!(
            gap.step(600.0, (false, true), false, dt),
            "seen twice running"
        );
        // Leaving the junction's approach forgets the reading.
        gap.leave();
        for _ in 0..quiet_start {
            gap.step(600.0, (false, false), false, dt);
        }
        assert!(!gap.step(600.0, (false, true), false, dt));
    }

    #[test]
    fn someone_stepping_off_the_kerb_is_yielded_to_and_someone_walking_along_it_is_not() {
        // Read every 0.4 s (the closed loop's planning steps), 25 m ahead of a car at 8 m/s.
        let watch = |edge: &dyn Fn(f64) -> f64, at: &dyn Fn(f64) -> f64| {
            let mut w = KerbWatch::default();
            (0..4)
                .map(|k| {
                    let t = 100.0 + 0.4 * f64::from(k);
                    w.update(t, Some((at(t - 100.0), edge(t - 100.0))))
                })
                .collect::<Vec<_>>()
        };
        // Walking towards the lane at 1.3 m/s: measured from the second reading on.
        let v = watch(&|t| -3.5 + 1.3 * t, &|_| 500.0);
        assert_eq!(v[0], None);
        for got in &v[1..] {
            assert!(got.is_some_and(|x| (x - 1.3).abs() < 1e-6), "{v:?}");
        }
        assert!(stepping_off_kerb(1.3, -3.5 + 1.3 * 1.2, 25.0, 8.0));
        // Walking along the sidewalk at 1.4 m/s (the edge stays), or standing at the kerb.
        let along = watch(&|_| -2.6, &|t| 500.0 - 1.4 * t);
        assert!(along[1..].iter().all(|x| x.is_some_and(|x| x.abs() < 1e-6)));
        assert!(!stepping_off_kerb(0.0, -2.6, 25.0, 8.0));
        // Readings in different places are different road users: no speed.
        let two = watch(&|t| -3.5 + 1.3 * t, &|t| 500.0 + 10.0 * t);
        assert!(two.iter().all(Option::is_none), "{two:?}");
        // A gap of more than KERB_WATCH_S between readings: no speed either.
        let mut w = KerbWatch::default();
        assert_eq!(w.update(0.0, Some((500.0, -3.5))), None);
        assert_eq!(w.update(1.0, None), None);
        assert_eq!(w.update(1.4, Some((500.0, -2.0))), None);
        // Someone slow, far from the path, close ahead: the car has long passed when they
        // get there; the same walker 30 m ahead, or one close to the path, is yielded to.
        assert!(!stepping_off_kerb(0.6, -4.0, 8.0, 8.0));
        assert!(stepping_off_kerb(0.6, -4.0, 30.0, 8.0));
        assert!(stepping_off_kerb(1.3, -1.5, 8.0, 8.0));
        assert!(!stepping_off_kerb(0.4, -1.5, 8.0, 8.0));
    }

    #[test]
    fn a_walker_on_the_far_half_of_a_crossing_has_the_way() {
        let scale = 4.0;
        let zebra = Some(10.0);
        let seen = |mut l: LeadSeen| {
            l.track[0] = Some(l.contact_x);
            l.track[1] = Some(l.contact_x);
            l.kind = ObjectKind::Person;
            l
        };
        // Walking towards the car's lane at 1.2 m/s on the crossing, or standing on it
        // (`vehicle` takes the gap: the contact is 4 m farther).
        let towards = LeadSeen {
            lateral_speed: -1.2 * scale,
            ..seen(vehicle(7.0, 0.0))
        };
        let standing = LeadSeen {
            speed_se: 0.3 * scale,
            ..seen(vehicle(8.5, 0.5 * scale))
        };
        assert!(walker_on_far_crossing(Some(&towards), zebra, scale));
        assert!(walker_on_far_crossing(Some(&standing), zebra, scale));
        // Walking away from the lane, a car coming through, beyond the crossing, before it,
        // seen in one frame, no crossing, nobody: the car goes on.
        let away = LeadSeen {
            lateral_speed: 1.2 * scale,
            ..towards
        };
        let through = seen(vehicle(7.0, -8.0 * scale));
        let through_scattered = LeadSeen {
            lateral_speed: -2.0 * scale,
            ..through
        };
        let beyond = seen(vehicle(12.0, 0.0));
        let before = seen(vehicle(4.5, 0.0));
        let once = LeadSeen {
            track: [Some(11.0), None, None, None],
            ..towards
        };
        for l in [away, through, through_scattered, beyond, before, once] {
            assert!(!walker_on_far_crossing(Some(&l), zebra, scale), "{l:?}");
        }
        assert!(!walker_on_far_crossing(Some(&towards), None, scale));
        assert!(!walker_on_far_crossing(None, zebra, scale));
    }

    #[test]
    fn the_unstick_rule_waits_for_a_working_signals_green() {
        // Standing at a light read red throughout (a mask's outline, a lamp misread): the
        // rule does not wait.
        let mut cycled = false;
        for _ in 0..200 {
            let (stop, c) = UnstickSignal::read(Some(Lamp::Red), 0.0, cycled);
            cycled = c;
            assert!(stop && !UnstickSignal::waits(stop, cycled));
        }
        // Read green while standing (held by a walker at the kerb), then red again: a
        // working signal; the rule waits through red and amber and goes on green.
        let (_, c) = UnstickSignal::read(Some(Lamp::Green), 0.0, cycled);
        cycled = c;
        for lamp in [Lamp::Amber, Lamp::Red] {
            let (stop, c) = UnstickSignal::read(Some(lamp), 0.0, cycled);
            cycled = c;
            assert!(UnstickSignal::waits(stop, cycled), "{lamp:?}");
        }
        let (stop, c) = UnstickSignal::read(Some(Lamp::Green), 0.0, cycled);
        assert!(!UnstickSignal::waits(stop, c));
        // No signal read now: nothing to wait for.
        let (stop, c) = UnstickSignal::read(None, 0.0, c);
        assert!(!UnstickSignal::waits(stop, c));
        // Moving forgets the cycle: the next stop starts afresh.
        let (_, c) = UnstickSignal::read(Some(Lamp::Red), 3.0, true);
        assert!(!c);
        let (stop, c) = UnstickSignal::read(Some(Lamp::Red), 0.0, c);
        assert!(!UnstickSignal::waits(stop, c));
    }

    #[test]
    fn a_red_lights_stop_point_is_remembered_only_when_near() {
        // Seen at 30 m: remembered; a closer estimate replaces it.
        let m = red_memory(None, 100.0, 30.0);
        assert_eq!(m, Some(130.0));
        assert_eq!(red_memory(m, 110.0, 18.5), Some(128.5));
        // A red 'seen' 700 m off (a phantom) neither sets a memory nor moves the near one.
        assert_eq!(red_memory(None, 100.0, 700.0), None);
        assert_eq!(red_memory(Some(128.5), 112.0, 700.0), Some(128.5));
    }

    #[test]
    fn a_standing_car_is_remembered_out_of_view() {
        // Planning step `k` at 2.5 Hz.
        let at = |k: u64| 0.4 * k as f64;
        let mut m = LeadMemory::default();
        // Seen standing 6 m ahead at odometer 100, then 5.5 m ahead at 100.5: confirmed,
        // remembered at 106.
        m.update(Some(&vehicle(6.0, 0.0)), 100.0, 1, at(1), 1.0);
        assert_eq!(m.gap(100.0), None, "one sighting is not yet a car");
        m.update(Some(&vehicle(5.5, 0.0)), 100.5, 2, at(2), 1.0);
        assert_eq!(m.gap(103.0), Some(3.0));
        // Out of view while the car closes in: still there, as a standing lead that stops
        // the car.
        m.update(None, 103.0, 3, at(3), 1.0);
        let r = m.recall(103.0).unwrap();
        assert_eq!((r.gap, r.speed, r.kind), (3.0, 0.0, ObjectKind::Vehicle));
        assert_eq!(follow_cap(Some(&r), 2.0, 8.0, 1.0), 0.0);
        // 3 m behind it (too close to see it), the car does not forget it after
        // `LEAD_MEMORY_S`...
        m.update(None, 103.0, 20, at(2) + LEAD_MEMORY_S + 1.0, 1.0);
        assert_eq!(m.gap(103.0), Some(3.0));
        // ... nor after minutes (a reading 1 m away, too close to trust alone, neither
        // moves nor refreshes it), nor when the lane reads blocked just beyond it (its body
        // taken for the road's end) ...
        m.update(Some(&vehicle(1.0, 0.0)), 103.0, 21, at(2) + 10.0, 1.0);
        m.update(None, 103.0, 22, at(2) + 300.0, 1.0);
        m.seen_clear(103.0, 3.0 + LEAD_CLEAR_PAST_M - 0.1);
        assert_eq!(m.gap(103.0), Some(3.0));
        // ... but once the lane is seen clear past it, or once past where it was.
        m.seen_clear(103.0, 3.0 + LEAD_CLEAR_PAST_M + 0.1);
        assert_eq!(m.gap(103.0), None);
        m.update(Some(&vehicle(6.0, 0.0)), 100.0, 1, at(1), 1.0);
        m.update(Some(&vehicle(6.0, 0.0)), 100.0, 2, at(2), 1.0);
        m.update(None, 106.5, 3, at(3), 1.0);
        assert_eq!(m.gap(106.5), None);
        // Unseen where it would be in view: forgotten after `LEAD_MEMORY_S`.
        m.update(Some(&vehicle(8.0, 0.0)), 100.0, 30, at(30), 1.0);
        m.update(Some(&vehicle(8.0, 0.0)), 100.0, 31, at(31), 1.0);
        m.update(None, 100.0, 32, at(31) + LEAD_MEMORY_S - 0.1, 1.0);
        assert_eq!(m.gap(100.0), Some(8.0));
        m.update(None, 100.0, 33, at(31) + LEAD_MEMORY_S + 0.1, 1.0);
        assert_eq!(m.gap(100.0), None);
        // ... or once it drives off (seen moving), or a close reading alone: never stored.
        m.update(Some(&vehicle(6.0, 0.0)), 100.0, 1, at(1), 1.0);
        m.update(Some(&vehicle(6.0, 0.0)), 100.0, 2, at(2), 1.0);
        m.update(Some(&vehicle(9.0, 16.0)), 100.0, 3, at(3), 4.0);
        assert_eq!(m.gap(100.0), None);
        m.update(Some(&vehicle(0.3, 0.0)), 100.0, 4, at(4), 1.0);
        m.update(Some(&vehicle(0.3, 0.0)), 100.0, 5, at(5), 1.0);
        assert_eq!(m.gap(100.0), None);
    }

    #[test]
    fn a_standing_car_seen_once_or_in_two_places_is_not_remembered() {
        let at = |k: u64| 0.4 * k as f64;
        let mut m = LeadMemory::default();
        // A one-off reading (clutter across a turn read as a car) holds nobody up ...
        m.update(Some(&vehicle(20.0, 0.0)), 100.0, 1, at(1), 1.0);
        m.update(None, 101.0, 2, at(2), 1.0);
        assert_eq!(m.gap(101.0), None);
        // ... nor do two readings far apart, or too many steps apart.
        m.update(Some(&vehicle(20.0, 0.0)), 110.0, 10, at(10), 1.0);
        m.update(Some(&vehicle(12.0, 0.0)), 111.0, 11, at(11), 1.0);
        assert_eq!(m.gap(111.0), None);
        m.update(Some(&vehicle(12.0, 0.0)), 111.0, 15, at(15), 1.0);
        assert_eq!(m.gap(111.0), None);
        // A remembered car is kept through a stray reading elsewhere.
        m.update(Some(&vehicle(12.0, 0.0)), 111.0, 16, at(16), 1.0);
        assert_eq!(m.gap(111.0), Some(12.0));
        m.update(Some(&vehicle(30.0, 0.0)), 111.0, 17, at(17), 1.0);
        assert_eq!(m.gap(111.0), Some(12.0));
    }

    #[test]
    fn unstick_stops_short_of_a_car_and_brakes_hard_when_it_must() {
        let p = AgentParams::default();
        assert_eq!(unstick_cap(None, p.stop_decel_mps2), f64::INFINITY);
        assert_eq!(unstick_cap(Some(0.0), p.stop_decel_mps2), 0.0);
        assert_eq!(unstick_cap(Some(-0.5), p.stop_decel_mps2), 0.0);
        assert!(unstick_cap(Some(1.0), p.stop_decel_mps2) < p.unstick_mps);
        assert!(unstick_cap(Some(10.0), p.stop_decel_mps2) > p.unstick_mps);
        let bike = BicycleParams::default();
        // The planned 2.5 m/s² suffices: the PID follows the profile.
        assert_eq!(emergency_brake(2.0, p.stop_decel_mps2, &bike), None);
        // 8 m/s with 8 m left needs 4 m/s²: most of the brake; more than the car has: full.
        let b = emergency_brake(64.0 / 16.0, p.stop_decel_mps2, &bike).unwrap();
        assert!(b * bike.brake_accel_mps2.abs() >= 4.0 && b < 1.0, "{b}");
        assert_eq!(emergency_brake(9.0, p.stop_decel_mps2, &bike), Some(1.0));
    }

    #[test]
    fn a_car_read_as_moving_but_not_getting_away_is_standing() {
        // Closing at 8 m/s on a car standing at 140 m whose speed reads 8 m/s (its face
        // registered as moving with the ego), readings scattered by ±0.4 m.
        let mut m = LeadMemory::default();
        for k in 0..4u64 {
            let (odo, t) = (100.0 + 3.2 * k as f64, 0.4 * k as f64);
            let noise = if k % 2 == 0 { 0.4 } else { -0.4 };
            m.update(
                Some(&vehicle(40.0 + noise - 3.2 * k as f64, 8.0)),
                odo,
                k,
                t,
                1.0,
            );
        }
        let v = m.range_rate().expect("three readings over 0.75 s");
        assert!(v.abs() < 1.0, "{v}");
        // Remembered where it stands: out of view, the car stops behind it.
        assert!((m.gap(120.0).unwrap() - 20.0).abs() < 0.5);
        m.update(None, 136.0, 4, 1.6, 1.0);
        let r = m.recall(136.0).expect("remembered");
        assert!(r.gap < 5.0 && r.speed == 0.0, "{r:?}");
        assert_eq!(follow_cap(Some(&r), 3.0, 8.0, 1.0), 0.0);
        // Without the range rate (the speed reading alone) it would have been forgotten as
        // seen moving: only two readings, too few for a rate.
        let mut f = LeadMemory::default();
        f.update(Some(&vehicle(40.0, 0.0)), 100.0, 0, 0.0, 1.0);
        f.update(Some(&vehicle(36.8, 8.0)), 103.2, 1, 0.4, 1.0);
        assert_eq!(f.gap(103.2), None);
        // A car driving away at 6 m/s, read so: its range rate agrees, it is not
        // remembered, and its reading is kept.
        let mut d = LeadMemory::default();
        for k in 0..5u64 {
            let (odo, t) = (8.0 * 0.4 * k as f64, 0.4 * k as f64);
            d.update(Some(&vehicle(20.0 + (6.0 - 8.0) * t, 6.0)), odo, k, t, 1.0);
        }
        assert!((d.range_rate().unwrap() - 6.0).abs() < 1e-9);
        assert_eq!(d.gap(10.0), None);
        // Two readings, or three within half a second: no range rate yet.
        let mut e = LeadMemory::default();
        e.update(Some(&vehicle(20.0, 8.0)), 0.0, 0, 0.0, 1.0);
        e.update(Some(&vehicle(19.0, 8.0)), 1.0, 1, 0.2, 1.0);
        assert_eq!(e.range_rate(), None);
        e.update(Some(&vehicle(18.0, 8.0)), 2.0, 2, 0.4, 1.0);
        assert_eq!(e.range_rate(), None);
    }

    #[test]
    fn a_vehicle_followed_while_it_drove_counts_as_seen_driving() {
        // A car followed into a queue: its position (distance driven + gap) moves 8 m.
        let mut m = LeadMemory::default();
        for k in 0..10u64 {
            let at = 20.0 + (k.min(4) as f64) * 2.0;
            let odo = k as f64;
            m.update(Some(&vehicle(at - odo, 0.0)), odo, k, 0.4 * (k) as f64, 1.0);
        }
        assert!(m.seen_driving());
        // Clutter read as a car: the same place, give or take half a metre of reading
        // noise, all along.
        let mut c = LeadMemory::default();
        for k in 0..30u64 {
            let odo = k as f64 * 0.3;
            let noise = if k % 2 == 0 { 0.5 } else { -0.5 };
            c.update(
                Some(&vehicle(30.0 + noise - odo, 0.0)),
                odo,
                k,
                0.4 * (k) as f64,
                1.0,
            );
        }
        assert!(!c.seen_driving());
        // A new reading far from the last, or after a gap of steps, starts a new track.
        m.update(Some(&vehicle(60.0, 0.0)), 10.0, 10, 0.4 * (10) as f64, 1.0);
        assert!(!m.seen_driving());
    }

    #[test]
    fn at_a_stop_sign_the_car_goes_only_once_its_side_looks_see_no_vehicle_moving() {
        let mover = |deg: f64| MoverSeen {
            x0: 10,
            y0: 80,
            x1: 30,
            y1: 86,
            changed: 40,
            bearing_rad: deg.to_radians(),
        };
        let route = DenseRoute::new((0..50).map(|i| [i as f64, 0.0]).collect()).unwrap();
        let bike = BicycleParams::default();
        let standing = VehicleState::default();
        // Standing at the line (0.5 m short of the stop point); planning steps 0.4 s apart,
        // control steps 0.05 s; cross traffic passing in the left look for 4 s.
        let run = |cross_until_s: f64, ahead_only: bool| {
            let mut a = Baseline::new(AgentParams::default());
            a.sign_stop_at_m = Some(0.5);
            for step in 0..200 {
                let t = step as f64 * 0.4;
                assert!(a.wants_look(0.0, 0.0), "at {t} s");
                let seen = if t < cross_until_s {
                    if ahead_only {
                        vec![mover(8.0), mover(-11.0)]
                    } else {
                        vec![mover(80.0), mover(-40.0)]
                    }
                } else {
                    Vec::new()
                };
                a.look((step > 0).then_some(seen.as_slice()), 0.4);
                for _ in 0..8 {
                    a.control(&standing, &route, 0, 0.05, 0.0, &bike);
                }
                if a.sign_stop_at_m.is_none() {
                    return Some(t);
                }
            }
            None
        };
        // Quiet looks: the stop ends in the step from 1.2 s, once the car has stood 1.5 s
        // at the line and three comparisons (from the second look on) make 1.2 s of quiet.
        let quiet = run(0.0, false).unwrap();
        assert!((quiet - 1.2).abs() < 1e-9, "{quiet}");
        // Cross traffic until 3.6 s: the stop lasts until three quiet looks after it.
        let busy = run(4.0, false).unwrap();
        assert!((busy - 4.8).abs() < 1e-9, "{busy}");
        // A mover straight ahead (within 12°) is the front camera's business, not the look's.
        assert_eq!(run(4.0, true), Some(quiet));
        // A car that moves no longer looks: it is not at the line.
        let mut a = Baseline::new(AgentParams::default());
        a.sign_stop_at_m = Some(0.5);
        assert!(!a.wants_look(2.0, 0.0));
        assert!(!a.wants_look(0.0, -5.0));
    }

    #[test]
    fn unstick_after_standing_still() {
        let mut a = Baseline::new(AgentParams::default());
        let route = DenseRoute::new((0..50).map(|i| [i as f64, 0.0]).collect()).unwrap();
        let bike = BicycleParams::default();
        let s = VehicleState::default();
        let mut fired = None;
        for k in 0..2000 {
            let c = a.control(&s, &route, 0, 0.05, 0.0, &bike);
            if c.throttle > 0.0 {
                fired = Some(k);
                break;
            }
        }
        let k = fired.unwrap();
        assert!((k as f64 * 0.05 - 55.0).abs() < 0.1, "{k}");
        assert_eq!(a.unstick_count, 1);
    }

    #[test]
    fn unstick_brakes_for_the_vehicle_ahead() {
        // A car seen standing 7 m ahead when the rule fires (it was seen driving: the rule
        // stands 4 m short of it, at 3 m): it creeps towards it, then brakes hard, though
        // the planner's stop points are ignored.
        let mut a = Baseline::new(AgentParams::default());
        a.intent.unstick_stop_at_m = Some(7.0 - UNSTICK_CLEAR_M);
        a.intent.stop_at_m = Some(0.0);
        let route = DenseRoute::new((0..50).map(|i| [i as f64, 0.0]).collect()).unwrap();
        let bike = BicycleParams::default();
        let standing = VehicleState::default();
        let mut c = a.control(&standing, &route, 0, 0.05, 0.0, &bike);
        for _ in 0..1200 {
            if a.unsticking() {
                break;
            }
            c = a.control(&standing, &route, 0, 0.05, 0.0, &bike);
        }
        assert!(a.unsticking() && c.throttle > 0.0, "{c:?}");
        // 2.5 m on at 2 m/s: 0.5 m left to the clearance, needing 4 m/s² → hard braking.
        let rolling = VehicleState {
            x_m: 2.5,
            speed_mps: 2.0,
            ..VehicleState::default()
        };
        let c = a.control(&rolling, &route, 2, 0.05, 2.5, &bike);
        assert!(c.throttle == 0.0 && c.brake > 0.5, "{c:?}");
        // Nothing ahead: the rule drives on.
        a.intent.unstick_stop_at_m = None;
        let c = a.control(&rolling, &route, 2, 0.05, 2.5, &bike);
        assert!(c.throttle > 0.0, "{c:?}");
    }
}
