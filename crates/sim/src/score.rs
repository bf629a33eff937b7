//! CARLA Leaderboard 1.0 scoring: route completion, the infraction score with the official
//! coefficients, the driving score per route and over routes, and the criteria that end a
//! route (agent blocked, route deviation, timeout) or record an infraction (collisions, red
//! lights, stop signs, driving outside the route's lanes).
//!
//! Every criterion is a small state machine fed once per simulation tick with the ego's
//! state; none of them knows the simulator, so each is unit-tested on its own. The rules
//! follow `leaderboard/utils/statistics_manager.py` and
//! `srunner/scenariomanager/scenarioatomics/atomic_criteria.py` of the `leaderboard-1.0`
//! branches (not the 2.x `master`):
//!
//! | criterion | rule |
//! |---|---|
//! | route completion | a dense route point `i` (from the current index, the next two too) is passed when `dot(ego − wp_i, forward_i) > 0`; `RC = 100 · accumulated length to the index / total length`; completed when `RC > 99` and the ego is within 10 m of the last point (then `RC = 100`) |
//! | infraction score | `IS = Π factor` over the events: pedestrian ×0.50, vehicle ×0.60, layout ×0.65, red light ×0.70, stop sign ×0.80 (configurable), outside route lanes ×(1 − percent/100) |
//! | driving score | `DS = max(RC · IS, 0)`; over routes, every metric is averaged separately |
//! | blocked | speed < 0.1 m/s for more than 180 s of game time |
//! | route deviation | the nearest route point among the current index and the next 5 is ≥ 30 m away, or more than 30 % of the route was advanced while > 15 m away |
//! | timeout | `int(0.8 s/m · route length + 5)` s of game time |
//! | collisions | a collision within 3 m of a registered one is ignored (registrations are forgotten once the ego is > 5 m away); the same actor is ignored for 5 s |

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::SimError;

/// What happened: the infractions of Leaderboard 1.0 and the events that end a route.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A collision with a pedestrian or a cyclist.
    CollisionPedestrian,
    /// A collision with a vehicle.
    CollisionVehicle,
    /// A collision with the static layout (buildings, poles, signs).
    CollisionLayout,
    /// Crossing a stop line while the light is red.
    RedLight,
    /// Leaving a stop sign's area without having stopped.
    StopSign,
    /// Driving outside the route's lanes (one event per route, with the percentage).
    OutsideRouteLanes,
    /// The route ended because the ego left it.
    RouteDeviation,
    /// The route ended because its game-time budget ran out.
    Timeout,
    /// The route ended because the ego stood still too long.
    AgentBlocked,
    /// The route ended at the configured game-time limit.
    GameTimeLimit,
    /// The route ended at the configured system-time limit.
    SystemTimeLimit,
}

impl EventKind {
    /// A collision (with a pedestrian or cyclist, a vehicle, or the layout).
    pub fn is_collision(self) -> bool {
        matches!(
            self,
            EventKind::CollisionPedestrian
                | EventKind::CollisionVehicle
                | EventKind::CollisionLayout
        )
    }

    /// Every kind, in report order.
    pub const ALL: [EventKind; 11] = [
        EventKind::CollisionPedestrian,
        EventKind::CollisionVehicle,
        EventKind::CollisionLayout,
        EventKind::RedLight,
        EventKind::StopSign,
        EventKind::OutsideRouteLanes,
        EventKind::RouteDeviation,
        EventKind::Timeout,
        EventKind::AgentBlocked,
        EventKind::GameTimeLimit,
        EventKind::SystemTimeLimit,
    ];

    /// The snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            EventKind::CollisionPedestrian => "collision_pedestrian",
            EventKind::CollisionVehicle => "collision_vehicle",
            EventKind::CollisionLayout => "collision_layout",
            EventKind::RedLight => "red_light",
            EventKind::StopSign => "stop_sign",
            EventKind::OutsideRouteLanes => "outside_route_lanes",
            EventKind::RouteDeviation => "route_deviation",
            EventKind::Timeout => "timeout",
            EventKind::AgentBlocked => "agent_blocked",
            EventKind::GameTimeLimit => "game_time_limit",
            EventKind::SystemTimeLimit => "system_time_limit",
        }
    }

    /// Whether the event ends the route (it then carries no penalty factor).
    pub fn ends_route(self) -> bool {
        matches!(
            self,
            EventKind::RouteDeviation
                | EventKind::Timeout
                | EventKind::AgentBlocked
                | EventKind::GameTimeLimit
                | EventKind::SystemTimeLimit
        )
    }
}

/// One recorded event.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Event {
    /// What happened.
    pub kind: EventKind,
    /// Game time, s.
    pub t_s: f64,
    /// Where (world frame), m.
    pub x_m: f64,
    /// Where (world frame), m.
    pub y_m: f64,
    /// The other actor, when there is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actor: Option<u64>,
    /// For [`EventKind::OutsideRouteLanes`]: the percentage of the route driven outside.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub percent: Option<f64>,
}

impl Event {
    /// An event of `kind` at `t_s` and `(x_m, y_m)`.
    pub fn new(kind: EventKind, t_s: f64, x_m: f64, y_m: f64) -> Self {
        Self {
            kind,
            t_s,
            x_m,
            y_m,
            actor: None,
            percent: None,
        }
    }
}

/// The penalty coefficients (Leaderboard 1.0 by default). A factor of 1 excludes an
/// infraction from the score (it is still recorded): the paper's traffic-light and stop-sign
/// deficit runs exclude red lights and stop signs, and Longest6's fork disables the
/// stop-sign penalty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ScoringParams {
    /// Collision with a pedestrian or cyclist.
    pub pedestrian: f64,
    /// Collision with a vehicle.
    pub vehicle: f64,
    /// Collision with the static layout.
    pub layout: f64,
    /// Running a red light.
    pub red_light: f64,
    /// Running a stop sign.
    pub stop_sign: f64,
}

impl Default for ScoringParams {
    fn default() -> Self {
        Self {
            pedestrian: 0.50,
            vehicle: 0.60,
            layout: 0.65,
            red_light: 0.70,
            stop_sign: 0.80,
        }
    }
}

impl ScoringParams {
    /// Checks every coefficient is within `[0, 1]`.
    pub fn validate(&self) -> Result<(), SimError> {
        for (name, v) in [
            ("pedestrian", self.pedestrian),
            ("vehicle", self.vehicle),
            ("layout", self.layout),
            ("red_light", self.red_light),
            ("stop_sign", self.stop_sign),
        ] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(SimError::Params(format!(
                    "scoring.{name} = {v}: a penalty factor must be within [0, 1]"
                )));
            }
        }
        Ok(())
    }

    /// The factor an event multiplies the infraction score by.
    pub fn factor(&self, e: &Event) -> f64 {
        match e.kind {
            EventKind::CollisionPedestrian => self.pedestrian,
            EventKind::CollisionVehicle => self.vehicle,
            EventKind::CollisionLayout => self.layout,
            EventKind::RedLight => self.red_light,
            EventKind::StopSign => self.stop_sign,
            EventKind::OutsideRouteLanes => {
                (1.0 - e.percent.unwrap_or(0.0).clamp(0.0, 100.0) / 100.0).max(0.0)
            }
            _ => 1.0,
        }
    }

    /// The infraction score of a route's events: the product of their factors.
    pub fn infraction_score(&self, events: &[Event]) -> f64 {
        events.iter().map(|e| self.factor(e)).product()
    }
}

/// Route completion, infraction score and driving score of one route.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RouteScore {
    /// Route completion, 0–100.
    pub route_completion: f64,
    /// Infraction score, 0–1.
    pub infraction_score: f64,
    /// Driving score `max(RC · IS, 0)`, 0–100.
    pub driving_score: f64,
}

impl RouteScore {
    /// The scores of a route that reached `route_completion` with `events`.
    pub fn of(route_completion: f64, events: &[Event], params: &ScoringParams) -> Self {
        let rc = route_completion.clamp(0.0, 100.0);
        let is = params.infraction_score(events);
        Self {
            route_completion: rc,
            infraction_score: is,
            driving_score: (rc * is).max(0.0),
        }
    }
}

/// A mean with its sample standard deviation (`n − 1`; 0 for a single value).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    /// The mean.
    pub mean: f64,
    /// The sample standard deviation.
    pub std: f64,
    /// Values.
    pub n: usize,
}

impl MeanStd {
    /// Mean and sample standard deviation of `values` (`None` when empty).
    pub fn of(values: &[f64]) -> Option<Self> {
        let n = values.len();
        if n == 0 {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let std = if n > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Some(Self { mean, std, n })
    }
}

/// Scores over routes: every metric averaged separately (global DS = mean(RC_i · IS_i),
/// never mean(RC) · mean(IS)).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GlobalScore {
    /// Mean driving score.
    pub driving_score: MeanStd,
    /// Mean route completion.
    pub route_completion: MeanStd,
    /// Mean infraction score.
    pub infraction_score: MeanStd,
}

impl GlobalScore {
    /// The global scores of `routes` (`None` when empty).
    pub fn of(routes: &[RouteScore]) -> Option<Self> {
        let pick = |f: fn(&RouteScore) -> f64| routes.iter().map(f).collect::<Vec<f64>>();
        Some(Self {
            driving_score: MeanStd::of(&pick(|r| r.driving_score))?,
            route_completion: MeanStd::of(&pick(|r| r.route_completion))?,
            infraction_score: MeanStd::of(&pick(|r| r.infraction_score))?,
        })
    }
}

/// Infractions per kilometre driven: counts per kind over `Σ RC_i/100 · length_i`.
pub fn infractions_per_km(
    routes: &[(&[Event], f64, f64)], // (events, route completion, route length m)
) -> BTreeMap<EventKind, f64> {
    let km: f64 = routes
        .iter()
        .map(|(_, rc, len)| rc.clamp(0.0, 100.0) / 100.0 * len / 1000.0)
        .sum();
    let mut counts: BTreeMap<EventKind, f64> = BTreeMap::new();
    for (events, _, _) in routes {
        for e in events.iter() {
            *counts.entry(e.kind).or_default() += 1.0;
        }
    }
    let km = km.max(1e-9);
    counts.into_iter().map(|(k, n)| (k, n / km)).collect()
}

/// Collisions (vehicles, pedestrians, layout) per km: the sum of those kinds in
/// `per_km` ([`infractions_per_km`]'s result), 0 when there are none.
pub fn collisions_per_km(per_km: &BTreeMap<EventKind, f64>) -> f64 {
    per_km
        .iter()
        .filter(|(k, _)| k.is_collision())
        .map(|(_, v)| v)
        // An empty sum is −0.0; + 0.0 makes it 0.
        .sum::<f64>()
        + 0.0
}

// ---------------------------------------------------------------------------------------
// The dense route and route completion.

/// A dense route: points about a metre apart, their forward unit vectors and the length
/// accumulated up to each.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseRoute {
    /// Points, world frame, m.
    pub points: Vec<[f64; 2]>,
    /// Forward unit vector at each point.
    pub forward: Vec<[f64; 2]>,
    /// Accumulated length at each point, m (`accum[0] = 0`).
    pub accum: Vec<f64>,
}

impl DenseRoute {
    /// A route through `points` (at least two, consecutive points distinct).
    pub fn new(points: Vec<[f64; 2]>) -> Result<Self, SimError> {
        if points.len() < 2 {
            return Err(SimError::Params("a route needs at least two points".into()));
        }
        let n = points.len();
        let mut accum = Vec::with_capacity(n);
        let mut forward = Vec::with_capacity(n);
        accum.push(0.0);
        for i in 1..n {
            let d = dist(points[i], points[i - 1]);
            if !(d.is_finite() && d > 1e-9) {
                return Err(SimError::Params(format!(
                    "route points {} and {i} coincide or are not finite",
                    i - 1
                )));
            }
            accum.push(accum[i - 1] + d);
        }
        for i in 0..n {
            let (a, b) = if i + 1 < n { (i, i + 1) } else { (i - 1, i) };
            let d = dist(points[b], points[a]);
            forward.push([
                (points[b][0] - points[a][0]) / d,
                (points[b][1] - points[a][1]) / d,
            ]);
        }
        Ok(Self {
            points,
            forward,
            accum,
        })
    }

    /// Total length, m.
    pub fn length_m(&self) -> f64 {
        self.accum.last().copied().unwrap_or(0.0)
    }

    /// Points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the route has no points (never, once built).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Route completion (`RouteCompletionTest`).
#[derive(Debug, Clone, PartialEq)]
pub struct RouteCompletion {
    index: usize,
    percent: f64,
    completed: bool,
}

/// Points checked beyond the current index.
const COMPLETION_WINDOW: usize = 2;
/// Distance to the last point within which a route at > 99 % is completed, m.
const COMPLETION_DISTANCE_M: f64 = 10.0;

impl Default for RouteCompletion {
    fn default() -> Self {
        Self::new()
    }
}

impl RouteCompletion {
    /// At the start of the route.
    pub fn new() -> Self {
        Self {
            index: 0,
            percent: 0.0,
            completed: false,
        }
    }

    /// Updates with the ego's position; returns the completion in percent.
    pub fn update(&mut self, route: &DenseRoute, ego: [f64; 2]) -> f64 {
        if self.completed {
            return 100.0;
        }
        let total = route.length_m();
        let end = (self.index + COMPLETION_WINDOW + 1).min(route.len());
        for i in self.index..end {
            let wp = route.points[i];
            let f = route.forward[i];
            if (ego[0] - wp[0]) * f[0] + (ego[1] - wp[1]) * f[1] > 0.0 {
                self.index = i;
                self.percent = 100.0 * route.accum[i] / total;
            }
        }
        let last = route.points[route.len() - 1];
        if self.percent > 99.0 && dist(ego, last) < COMPLETION_DISTANCE_M {
            self.completed = true;
            self.percent = 100.0;
        }
        self.percent
    }

    /// The current route index.
    pub fn index(&self) -> usize {
        self.index
    }

    /// Completion, percent.
    pub fn percent(&self) -> f64 {
        self.percent
    }

    /// Whether the route is completed.
    pub fn completed(&self) -> bool {
        self.completed
    }
}

// ---------------------------------------------------------------------------------------
// Termination rules.

/// Speed below which the ego counts as standing still, m/s.
pub const BLOCKED_SPEED_MPS: f64 = 0.1;
/// Standing still longer than this blocks the agent, s of game time.
pub const BLOCKED_TIME_S: f64 = 180.0;

/// Agent blocked (`ActorSpeedAboveThresholdTest`): speed below 0.1 m/s for more than 180 s.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockedMonitor {
    since_s: Option<f64>,
    limit_s: f64,
}

impl Default for BlockedMonitor {
    fn default() -> Self {
        Self::new(BLOCKED_TIME_S)
    }
}

impl BlockedMonitor {
    /// A monitor ending the route after `limit_s` of standing still.
    pub fn new(limit_s: f64) -> Self {
        Self {
            since_s: None,
            limit_s,
        }
    }

    /// Updates at game time `t_s` with the ego's speed; `true` when the agent is blocked.
    pub fn update(&mut self, t_s: f64, speed_mps: f64) -> bool {
        if speed_mps < BLOCKED_SPEED_MPS {
            let since = *self.since_s.get_or_insert(t_s);
            t_s - since > self.limit_s
        } else {
            self.since_s = None;
            false
        }
    }

    /// Seconds stood still so far (0 when moving).
    pub fn stopped_for_s(&self, t_s: f64) -> f64 {
        self.since_s.map_or(0.0, |s| t_s - s)
    }
}

/// Route deviation (`InRouteTest`).
#[derive(Debug, Clone, PartialEq)]
pub struct RouteDeviationMonitor {
    index: usize,
    out_route_m: f64,
    in_safe_route: bool,
}

/// Look-ahead window of the deviation test, points.
const DEVIATION_WINDOW: usize = 5;
/// Beyond this distance from the route, the route deviates at once, m.
pub const OFFROAD_MAX_M: f64 = 30.0;
/// Beyond this distance, advancing along the route counts as driven off it, m.
pub const OFFROAD_MIN_M: f64 = 15.0;
/// Largest share of the route advanced off it, percent.
pub const MAX_OFF_ROUTE_PERCENT: f64 = 30.0;

impl Default for RouteDeviationMonitor {
    fn default() -> Self {
        Self::new()
    }
}

impl RouteDeviationMonitor {
    /// At the start of the route.
    pub fn new() -> Self {
        Self {
            index: 0,
            out_route_m: 0.0,
            in_safe_route: true,
        }
    }

    /// Updates with the ego's position; `true` when the ego has deviated from the route.
    pub fn update(&mut self, route: &DenseRoute, ego: [f64; 2]) -> bool {
        let end = (self.index + DEVIATION_WINDOW + 1).min(route.len());
        let mut best = (self.index, f64::INFINITY);
        for i in self.index..end {
            let d = dist(ego, route.points[i]);
            if d <= best.1 {
                best = (i, d);
            }
        }
        let (closest, shortest) = best;
        let mut off_route = true;
        if shortest < OFFROAD_MAX_M {
            off_route = false;
            self.in_safe_route = shortest < OFFROAD_MIN_M;
        }
        if closest != self.index {
            let advanced = route.accum[closest] - route.accum[self.index];
            if !self.in_safe_route {
                self.out_route_m += advanced;
                if 100.0 * self.out_route_m / route.length_m() > MAX_OFF_ROUTE_PERCENT {
                    off_route = true;
                }
            }
            self.index = closest;
        }
        off_route
    }

    /// Metres of route advanced while more than 15 m away.
    pub fn out_route_m(&self) -> f64 {
        self.out_route_m
    }
}

/// Seconds of game time per metre of route.
pub const TIMEOUT_S_PER_M: f64 = 0.8;
/// Seconds of game time added to every route.
pub const TIMEOUT_DELAY_S: f64 = 5.0;

/// The route's game-time budget: `int(0.8 s/m · length + 5)` s.
pub fn route_timeout_s(route_length_m: f64) -> f64 {
    (TIMEOUT_S_PER_M * route_length_m + TIMEOUT_DELAY_S).floor()
}

/// Time limits of a run: the route's timeout (game time) and the optional limits of the
/// experiment (game time, or system time = game time + the agents' compute time as counted,
/// e.g. the LLM latency).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeLimits {
    /// The route's timeout, s of game time.
    pub route_timeout_s: f64,
    /// An experiment-wide game-time limit, s.
    pub game_time_limit_s: Option<f64>,
    /// An experiment-wide system-time limit, s.
    pub system_time_limit_s: Option<f64>,
}

impl TimeLimits {
    /// Which limit, if any, ends the run at game time `game_s` and system time `system_s`
    /// (the route timeout first, then the game-time limit, then the system-time limit).
    pub fn check(&self, game_s: f64, system_s: f64) -> Option<EventKind> {
        if game_s > self.route_timeout_s {
            return Some(EventKind::Timeout);
        }
        if self.game_time_limit_s.is_some_and(|l| game_s > l) {
            return Some(EventKind::GameTimeLimit);
        }
        if self.system_time_limit_s.is_some_and(|l| system_s > l) {
            return Some(EventKind::SystemTimeLimit);
        }
        None
    }
}

// ---------------------------------------------------------------------------------------
// Infraction criteria.

/// Collisions within this distance of a registered one are ignored, m.
pub const COLLISION_RADIUS_M: f64 = 3.0;
/// Registered collisions are forgotten once the ego is this far away, m.
pub const COLLISION_FORGET_M: f64 = 5.0;
/// The same actor is ignored for this long, s.
pub const COLLISION_ACTOR_S: f64 = 5.0;

/// The collision filter (`CollisionTest`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CollisionFilter {
    registered: Vec<[f64; 2]>,
    last_actor: Option<(u64, f64)>,
}

impl CollisionFilter {
    /// A filter with nothing registered.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets registrations the ego has left (call every tick with its position).
    pub fn tick(&mut self, ego: [f64; 2]) {
        self.registered
            .retain(|&p| dist(p, ego) <= COLLISION_FORGET_M);
    }

    /// A contact with `actor` while the ego is at `at` (game time `t_s`): `true` when it
    /// counts as a new collision (and registers it). As in CARLA's `CollisionTest`, the
    /// location registered is the ego's, so a contact that lasts while the ego stands
    /// counts once.
    pub fn contact(&mut self, actor: u64, at: [f64; 2], t_s: f64) -> bool {
        if let Some((a, t)) = self.last_actor
            && a == actor
            && t_s - t < COLLISION_ACTOR_S
        {
            return false;
        }
        if self
            .registered
            .iter()
            .any(|&p| dist(p, at) <= COLLISION_RADIUS_M)
        {
            return false;
        }
        self.registered.push(at);
        self.last_actor = Some((actor, t_s));
        true
    }
}

/// Distance from a light's stop line within which red-light crossings count, m.
pub const RED_LIGHT_DISTANCE_M: f64 = 15.0;

/// Whether the segment `a0 → a1` crosses the segment `b0 → b1` (proper or touching).
pub fn segments_cross(a0: [f64; 2], a1: [f64; 2], b0: [f64; 2], b1: [f64; 2]) -> bool {
    let orient = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
    };
    let d1 = orient(b0, b1, a0);
    let d2 = orient(b0, b1, a1);
    let d3 = orient(a0, a1, b0);
    let d4 = orient(a0, a1, b1);
    ((d1 > 0.0 && d2 <= 0.0) || (d1 < 0.0 && d2 >= 0.0) || (d1 == 0.0 && d2 != 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0) || d3 == 0.0 || d4 == 0.0)
}

/// A stop line of one approach lane: its two ends and the direction traffic crosses it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StopLine {
    /// One end (right edge of the lane), m.
    pub a: [f64; 2],
    /// The other end (left edge of the lane), m.
    pub b: [f64; 2],
    /// Direction of travel across the line (unit).
    pub forward: [f64; 2],
}

impl StopLine {
    /// The line's midpoint.
    pub fn centre(&self) -> [f64; 2] {
        [(self.a[0] + self.b[0]) / 2.0, (self.a[1] + self.b[1]) / 2.0]
    }

    /// Signed distance of `p` past the line along `forward` (negative before it).
    pub fn past(&self, p: [f64; 2]) -> f64 {
        let c = self.centre();
        (p[0] - c[0]) * self.forward[0] + (p[1] - c[1]) * self.forward[1]
    }
}

/// Red lights (`RunningRedLightTest`): the ego's tail crossing a stop line forwards while the
/// light is red and the line's centre is within 15 m; one infraction per light until another
/// light is run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RedLightMonitor {
    last_light: Option<u64>,
}

impl RedLightMonitor {
    /// A monitor that has seen no infraction.
    pub fn new() -> Self {
        Self::default()
    }

    /// Checks one light: the ego's tail moved from `tail_prev` to `tail_now` (heading
    /// `heading`, unit) while `line`'s light (id `light`) is `red`. `true` on an infraction.
    pub fn check(
        &mut self,
        light: u64,
        line: &StopLine,
        red: bool,
        tail_prev: [f64; 2],
        tail_now: [f64; 2],
        heading: [f64; 2],
    ) -> bool {
        if !red || self.last_light == Some(light) {
            return false;
        }
        if dist(line.centre(), tail_now) > RED_LIGHT_DISTANCE_M {
            return false;
        }
        let aligned = heading[0] * line.forward[0] + heading[1] * line.forward[1] > 0.0;
        if aligned && segments_cross(tail_prev, tail_now, line.a, line.b) {
            self.last_light = Some(light);
            return true;
        }
        false
    }
}

/// A stop sign's area (`RunningStopTest`): while the ego is inside it must drop below
/// 0.1 m/s once, otherwise leaving the area is an infraction.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StopSignMonitor {
    inside: Option<u64>,
    stopped: bool,
}

impl StopSignMonitor {
    /// A monitor outside every area.
    pub fn new() -> Self {
        Self::default()
    }

    /// Updates with the area the ego is in (`None`: none) and its speed; returns the sign
    /// run when the ego left an area without stopping.
    pub fn update(&mut self, area: Option<u64>, speed_mps: f64) -> Option<u64> {
        let mut run = None;
        if self.inside != area {
            if let Some(prev) = self.inside
                && !self.stopped
            {
                run = Some(prev);
            }
            self.inside = area;
            self.stopped = false;
        }
        if self.inside.is_some() && speed_mps < BLOCKED_SPEED_MPS {
            self.stopped = true;
        }
        run
    }
}

/// Driving outside the route's lanes (`OutsideRouteLanesTest`): the share of the route's
/// length advanced while outside, reported as one event at the end.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct OutsideLanesMonitor {
    outside_m: f64,
    last_index: usize,
}

impl OutsideLanesMonitor {
    /// Nothing driven outside yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Updates with the route-completion index and whether the ego is outside the route's
    /// lanes now.
    pub fn update(&mut self, route: &DenseRoute, index: usize, outside: bool) {
        if index > self.last_index {
            if outside {
                self.outside_m += route.accum[index] - route.accum[self.last_index];
            }
            self.last_index = index;
        }
    }

    /// Percentage of the route driven outside its lanes.
    pub fn percent(&self, route: &DenseRoute) -> f64 {
        100.0 * self.outside_m / route.length_m().max(1e-9)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(len: usize) -> DenseRoute {
        DenseRoute::new((0..=len).map(|i| [i as f64, 0.0]).collect()).unwrap()
    }

    fn ev(kind: EventKind) -> Event {
        Event::new(kind, 0.0, 0.0, 0.0)
    }

    #[test]
    fn golden_completed_route_without_events() {
        let s = RouteScore::of(100.0, &[], &ScoringParams::default());
        assert_eq!(s.route_completion, 100.0);
        assert_eq!(s.infraction_score, 1.0);
        assert_eq!(s.driving_score, 100.0);
    }

    #[test]
    fn golden_vehicle_collision_and_red_light() {
        let e = [ev(EventKind::CollisionVehicle), ev(EventKind::RedLight)];
        let s = RouteScore::of(100.0, &e, &ScoringParams::default());
        assert!((s.infraction_score - 0.42).abs() < 1e-12);
        assert!((s.driving_score - 42.0).abs() < 1e-9);
    }

    #[test]
    fn golden_two_pedestrian_collisions() {
        let e = [
            ev(EventKind::CollisionPedestrian),
            ev(EventKind::CollisionPedestrian),
        ];
        let s = RouteScore::of(100.0, &e, &ScoringParams::default());
        assert!((s.infraction_score - 0.25).abs() < 1e-12);
    }

    #[test]
    fn golden_timeout_at_sixty_percent() {
        let e = [ev(EventKind::Timeout)];
        let s = RouteScore::of(60.0, &e, &ScoringParams::default());
        assert_eq!(s.route_completion, 60.0);
        assert_eq!(s.infraction_score, 1.0);
        assert!((s.driving_score - 60.0).abs() < 1e-12);
    }

    #[test]
    fn golden_global_score_averages_each_metric() {
        let a = RouteScore {
            route_completion: 100.0,
            infraction_score: 0.5,
            driving_score: 50.0,
        };
        let b = RouteScore {
            route_completion: 50.0,
            infraction_score: 1.0,
            driving_score: 50.0,
        };
        let g = GlobalScore::of(&[a, b]).unwrap();
        assert!((g.driving_score.mean - 50.0).abs() < 1e-12);
        let naive = g.route_completion.mean * g.infraction_score.mean;
        assert!((naive - 56.25).abs() < 1e-12);
        assert_eq!(g.driving_score.std, 0.0);
        assert!((g.route_completion.std - 1250f64.sqrt()).abs() < 1e-9);
    }

    #[test]
    fn every_coefficient_and_exclusion() {
        let p = ScoringParams::default();
        let f = |k| p.factor(&ev(k));
        assert_eq!(f(EventKind::CollisionPedestrian), 0.5);
        assert_eq!(f(EventKind::CollisionVehicle), 0.6);
        assert_eq!(f(EventKind::CollisionLayout), 0.65);
        assert_eq!(f(EventKind::RedLight), 0.7);
        assert_eq!(f(EventKind::StopSign), 0.8);
        for k in [
            EventKind::RouteDeviation,
            EventKind::Timeout,
            EventKind::AgentBlocked,
            EventKind::GameTimeLimit,
            EventKind::SystemTimeLimit,
        ] {
            assert_eq!(f(k), 1.0);
            assert!(k.ends_route());
        }
        let mut out = ev(EventKind::OutsideRouteLanes);
        out.percent = Some(12.5);
        assert!((p.factor(&out) - 0.875).abs() < 1e-12);
        let excluded = ScoringParams {
            red_light: 1.0,
            stop_sign: 1.0,
            ..p
        };
        let e = [ev(EventKind::RedLight), ev(EventKind::StopSign)];
        assert_eq!(excluded.infraction_score(&e), 1.0);
        assert!(
            ScoringParams {
                stop_sign: 1.2,
                ..p
            }
            .validate()
            .is_err()
        );
    }

    #[test]
    fn driving_score_is_never_negative_and_rc_is_clamped() {
        let s = RouteScore::of(130.0, &[], &ScoringParams::default());
        assert_eq!(s.route_completion, 100.0);
        let s = RouteScore::of(-5.0, &[], &ScoringParams::default());
        assert_eq!(s.driving_score, 0.0);
    }

    #[test]
    fn infractions_per_km_use_the_driven_distance() {
        let e1 = [ev(EventKind::RedLight), ev(EventKind::RedLight)];
        let e2 = [ev(EventKind::CollisionVehicle)];
        // 50 % of 2 km + 100 % of 1 km = 2 km driven.
        let per = infractions_per_km(&[(&e1, 50.0, 2000.0), (&e2, 100.0, 1000.0)]);
        assert!((per[&EventKind::RedLight] - 1.0).abs() < 1e-12);
        assert!((per[&EventKind::CollisionVehicle] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn route_completion_advances_by_at_most_three_points_per_tick() {
        let r = straight(100);
        let mut rc = RouteCompletion::new();
        // A jump far ahead only advances through the window (current index and two more).
        assert!((rc.update(&r, [50.0, 0.0]) - 2.0).abs() < 1e-12);
        assert_eq!(rc.index(), 2);
        for _ in 0..100 {
            rc.update(&r, [50.5, 0.0]);
        }
        assert!((rc.percent() - 50.0).abs() < 1e-12);
        // Not completed until within 10 m of the end and above 99 %.
        let mut x = 50.5;
        while x < 100.5 {
            x += 1.0;
            rc.update(&r, [x, 0.0]);
        }
        assert!(rc.completed());
        assert_eq!(rc.percent(), 100.0);
    }

    #[test]
    fn route_completion_needs_to_be_near_the_end() {
        let r = straight(100);
        let mut rc = RouteCompletion::new();
        for i in 0..=100 {
            // 11 m to the side: every point passed, never within 10 m of the last one.
            rc.update(&r, [i as f64 + 0.5, 11.0]);
        }
        assert!(!rc.completed());
        assert!(rc.percent() > 99.0);
    }

    #[test]
    fn blocked_after_more_than_180_seconds_still() {
        let mut b = BlockedMonitor::default();
        let dt = 0.05;
        let mut t = 0.0;
        // Moving: never blocked.
        for _ in 0..100 {
            assert!(!b.update(t, 5.0));
            t += dt;
        }
        let start = t;
        let mut blocked_at = None;
        for _ in 0..4000 {
            if b.update(t, 0.05) {
                blocked_at = Some(t);
                break;
            }
            t += dt;
        }
        let at = blocked_at.unwrap();
        assert!(at - start > 180.0 && at - start < 180.0 + 2.0 * dt);
        // Moving again resets the clock.
        let mut b = BlockedMonitor::default();
        assert!(!b.update(0.0, 0.0));
        assert!(!b.update(179.0, 0.0));
        assert!(!b.update(179.5, 0.2));
        assert!(!b.update(200.0, 0.0));
        assert!(!b.update(379.0, 0.0));
        assert!(b.update(380.01, 0.0));
    }

    #[test]
    fn route_deviation_at_thirty_metres_at_once() {
        let r = straight(200);
        let mut m = RouteDeviationMonitor::new();
        assert!(!m.update(&r, [0.0, 29.0]));
        let mut m = RouteDeviationMonitor::new();
        assert!(m.update(&r, [0.0, 30.0]));
    }

    #[test]
    fn route_deviation_after_thirty_percent_driven_beyond_fifteen_metres() {
        let r = straight(100);
        let mut m = RouteDeviationMonitor::new();
        let mut deviated_at = None;
        for i in 0..=100 {
            // 20 m beside the route: not beyond 30 m, but not in the safe corridor.
            if m.update(&r, [i as f64, 20.0]) {
                deviated_at = Some(i);
                break;
            }
        }
        // It deviates once more than 30 m of the 100 m route were advanced outside.
        let at = deviated_at.unwrap();
        assert!((30..=33).contains(&at), "{at}");
        // Within 15 m the same drive never deviates.
        let mut m = RouteDeviationMonitor::new();
        for i in 0..=100 {
            assert!(!m.update(&r, [i as f64, 14.0]));
        }
        assert_eq!(m.out_route_m(), 0.0);
    }

    #[test]
    fn timeout_formula_and_time_limits() {
        assert_eq!(route_timeout_s(1500.0), 1205.0);
        assert_eq!(route_timeout_s(686.4), 554.0);
        let l = TimeLimits {
            route_timeout_s: 100.0,
            game_time_limit_s: None,
            system_time_limit_s: None,
        };
        assert_eq!(l.check(100.0, 1e9), None);
        assert_eq!(l.check(100.05, 0.0), Some(EventKind::Timeout));
        let l = TimeLimits {
            route_timeout_s: 100.0,
            game_time_limit_s: Some(50.0),
            system_time_limit_s: Some(60.0),
        };
        assert_eq!(l.check(50.0, 50.0), None);
        assert_eq!(l.check(50.1, 50.1), Some(EventKind::GameTimeLimit));
        // System time includes the LLM's latency: it can run out first.
        assert_eq!(l.check(20.0, 60.5), Some(EventKind::SystemTimeLimit));
    }

    #[test]
    fn collision_filter_rules() {
        let mut f = CollisionFilter::new();
        assert!(f.contact(1, [0.0, 0.0], 0.0));
        // Same actor within 5 s: ignored, wherever.
        assert!(!f.contact(1, [50.0, 0.0], 4.9));
        // Another actor within 3 m of the registered location: ignored.
        assert!(!f.contact(2, [2.0, 0.0], 1.0));
        // Once the ego is more than 5 m away the location is forgotten.
        f.tick([5.5, 0.0]);
        assert!(f.contact(2, [2.0, 0.0], 1.0));
        // The same actor again after 5 s, far from registrations: counts.
        f.tick([40.0, 0.0]);
        assert!(f.contact(2, [40.0, 0.0], 6.1));
        // A car resting against a standing ego for a minute: one collision.
        let mut f = CollisionFilter::new();
        let mut counted = 0;
        for k in 0..1200 {
            f.tick([100.0, 0.0]);
            counted += usize::from(f.contact(7, [100.0, 0.0], k as f64 * 0.05));
        }
        assert_eq!(counted, 1);
    }

    #[test]
    fn red_light_only_when_crossing_forwards_on_red_near_the_line() {
        let line = StopLine {
            a: [10.0, -2.0],
            b: [10.0, 2.0],
            forward: [1.0, 0.0],
        };
        let mut m = RedLightMonitor::new();
        let h = [1.0, 0.0];
        // Green: nothing.
        assert!(!m.check(7, &line, false, [9.9, 0.0], [10.1, 0.0], h));
        // Red, crossing: one infraction, then the same light is not counted again.
        assert!(m.check(7, &line, true, [9.9, 0.0], [10.1, 0.0], h));
        assert!(!m.check(7, &line, true, [9.9, 0.0], [10.1, 0.0], h));
        // Another light counts.
        assert!(m.check(8, &line, true, [9.9, 0.0], [10.1, 0.0], h));
        // Backwards or not crossing: nothing.
        let mut m = RedLightMonitor::new();
        assert!(!m.check(7, &line, true, [10.1, 0.0], [9.9, 0.0], [-1.0, 0.0]));
        assert!(!m.check(7, &line, true, [9.0, 0.0], [9.5, 0.0], h));
        // Beside the lane: the segment is missed.
        assert!(!m.check(7, &line, true, [9.9, 3.0], [10.1, 3.0], h));
    }

    #[test]
    fn stop_sign_needs_a_stop_inside_the_area() {
        let mut m = StopSignMonitor::new();
        assert_eq!(m.update(None, 5.0), None);
        assert_eq!(m.update(Some(3), 4.0), None);
        assert_eq!(m.update(Some(3), 0.5), None);
        assert_eq!(m.update(None, 3.0), Some(3));
        // Stopping inside clears it.
        assert_eq!(m.update(Some(4), 2.0), None);
        assert_eq!(m.update(Some(4), 0.05), None);
        assert_eq!(m.update(Some(4), 2.0), None);
        assert_eq!(m.update(None, 4.0), None);
    }

    #[test]
    fn outside_lanes_share() {
        let r = straight(100);
        let mut m = OutsideLanesMonitor::new();
        for i in 0..=100 {
            m.update(&r, i, (20..40).contains(&i));
        }
        assert!((m.percent(&r) - 20.0).abs() < 1e-9);
    }

    #[test]
    fn mean_std_is_the_sample_std() {
        let m = MeanStd::of(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert!((m.mean - 2.5).abs() < 1e-12);
        assert!((m.std - (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!(MeanStd::of(&[]).is_none());
    }
}
