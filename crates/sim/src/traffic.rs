//! Everyone but the ego: vehicles that obey the rules, pedestrians and cyclists.
//!
//! **Vehicles** drive along lanes and the paths through junctions with the intelligent
//! driver model behind whatever is on their path (another vehicle, the ego, a pedestrian),
//! stop for red and amber lights (amber only when they can), stop at stop lines for at least
//! a second, enter a junction only when no one on a crossing path is inside it, the first
//! arrival going first at stop signs, turn left at a signal only when no oncoming vehicle is
//! near, and keep the junction clear when their exit is full. They choose straight (weight 2),
//! left or right at random at every junction. The population lives around the ego: vehicles
//! that end up more than 230 m away reappear 110–190 m away on a free stretch of lane. As
//! CARLA's traffic manager does, a vehicle that has stood (below 0.8 m/s) for 90 s, not
//! held at a red or amber light, is stuck: the one stuck longest is taken out of the town
//! (at most one every 10 s) and another appears elsewhere. Without this, queues that block
//! each other across a junction stand for good, and so does the ego behind them.
//!
//! **Pedestrians** (some of them cyclists) walk the sidewalks from corner to corner and cross
//! at the zebras, at signals only while their street's traffic has red and enough time is
//! left. **Crossing events** (Longest6's scenario 3) start when the ego comes near: someone
//! steps off the sidewalk in front of it and crosses the road.
//!
//! Everything draws from seeded streams; the order of updates is fixed (by id), so a run is
//! a function of its seed.

use std::collections::VecDeque;

use fogline_world::objects;
use fogline_world::scene::{Draw, ObjectClass, Part};

use crate::geom::{Obb, P2, Stream, add, dist, dot, sub, unit, within};
use crate::route::{CrossingEvent, Route};
use crate::town::{Control, LINE_TO_ZONE_M, Light, Town, WALK_MID_M, ZEBRA_M, ZONE_M, turn_of};
use crate::vehicle::VehicleState;

/// Half length and width of the ego's box, and the box centre ahead of the rear axle, m.
pub const EGO_HALF_LENGTH_M: f64 = 2.45;
/// Half width of the ego, m.
pub const EGO_HALF_WIDTH_M: f64 = 0.95;
/// Box centre ahead of the rear axle, m (front bumper 3.7 m ahead of it).
pub const EGO_CENTRE_AHEAD_M: f64 = 3.7 - EGO_HALF_LENGTH_M;

/// The ego's footprint.
pub fn ego_box(s: &VehicleState) -> Obb {
    Obb {
        c: s.point(EGO_CENTRE_AHEAD_M, 0.0),
        yaw: s.yaw_rad,
        hl: EGO_HALF_LENGTH_M,
        hw: EGO_HALF_WIDTH_M,
    }
}

/// Settings of the traffic.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrafficParams {
    /// Vehicles around the ego.
    pub vehicles: usize,
    /// Pedestrians and cyclists on the sidewalks around the ego.
    pub pedestrians: usize,
    /// Share of sidewalk users who ride bicycles.
    pub cyclist_share: f64,
    /// Crossing events per km of route.
    pub events_per_km: f64,
}

impl Default for TrafficParams {
    fn default() -> Self {
        Self {
            vehicles: 40,
            pedestrians: 24,
            cyclist_share: 0.15,
            events_per_km: 4.0,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Seg {
    Lane {
        node: usize,
        d: usize,
    },
    Conn {
        node: usize,
        din: usize,
        dout: usize,
    },
}

fn seg_poly(town: &Town, seg: Seg) -> &crate::geom::Poly {
    // Segments are only ever built from existing lanes and connectors.
    match seg {
        Seg::Lane { node, d } => town.lane(node, d),
        Seg::Conn { node, din, dout } => town.connector(node, din, dout),
    }
    .unwrap_or_else(|| unreachable!("segments come from the town"))
}

/// A vehicle of the traffic.
#[derive(Debug, Clone)]
pub struct Npc {
    /// Id (also its track id).
    pub id: u64,
    /// A truck (else a car).
    pub truck: bool,
    /// Its parts (drawn once).
    pub parts: Vec<Part>,
    /// Half length, m.
    pub half_len_m: f64,
    /// Half width, m.
    pub half_width_m: f64,
    segs: VecDeque<Seg>,
    /// Centre position along the first segment, m.
    s_m: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Acceleration of the last update, m/s².
    pub accel_mps2: f64,
    v_desired: f64,
    /// Centre, m.
    pub pos: P2,
    /// Heading, rad.
    pub yaw: f64,
    stopped_at_line_s: Option<f64>,
    arrived_s: Option<f64>,
    admitted: Option<usize>,
    braking: bool,
    /// Since when it has stood (speed at most [`STUCK_MPS`], not held at a light), s;
    /// `None` before its first update.
    idle_since_s: Option<f64>,
    draw: Stream,
}

impl Npc {
    /// Its box.
    pub fn obb(&self) -> Obb {
        Obb {
            c: self.pos,
            yaw: self.yaw,
            hl: self.half_len_m,
            hw: self.half_width_m,
        }
    }

    /// Whether its brake lamps are lit.
    pub fn braking(&self) -> bool {
        self.braking
    }

    /// The class of its boxes.
    pub fn class(&self) -> ObjectClass {
        if self.truck {
            ObjectClass::Truck
        } else {
            ObjectClass::Car
        }
    }

    fn seg_len(&self, town: &Town, k: usize) -> f64 {
        seg_poly(town, self.segs[k]).length()
    }

    fn update_pose(&mut self, town: &Town) {
        let (p, u) = seg_poly(town, self.segs[0]).pose(self.s_m);
        self.pos = p;
        self.yaw = u[1].atan2(u[0]);
    }

    /// Extends the path until it reaches `ahead` m beyond the vehicle.
    fn extend(&mut self, town: &Town, ahead: f64) {
        loop {
            let mut total = -self.s_m;
            for k in 0..self.segs.len() {
                total += self.seg_len(town, k);
            }
            if total >= ahead {
                return;
            }
            let last = self.segs[self.segs.len() - 1];
            let next = match last {
                Seg::Lane { node, d } => {
                    let Some(b) = town.neighbor(node, d) else {
                        return;
                    };
                    let exits = town.exits(b, d);
                    if exits.is_empty() {
                        return;
                    }
                    let w: Vec<f64> = exits
                        .iter()
                        .map(|&o| if o == d { 2.0 } else { 1.0 })
                        .collect();
                    let mut u = self.draw.unit() * w.iter().sum::<f64>();
                    let mut dout = exits[exits.len() - 1];
                    for (k, wk) in w.iter().enumerate() {
                        if u < *wk {
                            dout = exits[k];
                            break;
                        }
                        u -= wk;
                    }
                    Seg::Conn {
                        node: b,
                        din: d,
                        dout,
                    }
                }
                Seg::Conn { node, dout, .. } => Seg::Lane { node, d: dout },
            };
            self.segs.push_back(next);
        }
    }

    /// Samples the path ahead of the front bumper every metre up to `ahead` m:
    /// `(distance from the front bumper, point, direction)`.
    fn probes(&self, town: &Town, ahead: f64) -> Vec<(f64, P2, P2)> {
        let mut out = Vec::with_capacity(ahead as usize + 2);
        let mut k = 0;
        let mut s = self.s_m + self.half_len_m;
        let mut travelled = 0.0;
        while travelled <= ahead && k < self.segs.len() {
            let poly = seg_poly(town, self.segs[k]);
            let len = poly.length();
            while s <= len && travelled <= ahead {
                let (p, u) = poly.pose(s);
                out.push((travelled, p, u));
                s += 1.0;
                travelled += 1.0;
            }
            s -= len;
            k += 1;
        }
        out
    }
}

/// A pedestrian or cyclist.
#[derive(Debug, Clone)]
pub struct Walker {
    /// Id (also its track id).
    pub id: u64,
    /// Rides a bicycle.
    pub cyclist: bool,
    /// Its parts.
    pub parts: Vec<Part>,
    /// Position, m.
    pub pos: P2,
    /// Heading, rad.
    pub yaw: f64,
    /// Speed when moving, m/s.
    pub pace_mps: f64,
    /// Current speed, m/s.
    pub speed_mps: f64,
    target: P2,
    /// Node, corner quadrant and kerb it is heading to (`None`: a free walk, e.g. an event).
    corner: Option<(usize, usize, usize)>,
    crossing: Option<(usize, usize)>,
    waiting: bool,
    /// An event actor (ends its walk and stands still).
    pub event: bool,
    draw: Stream,
}

impl Walker {
    /// Its footprint radius, m.
    pub fn radius_m(&self) -> f64 {
        if self.cyclist { 0.45 } else { 0.3 }
    }

    /// Its box (a cyclist is long).
    pub fn obb(&self) -> Obb {
        if self.cyclist {
            Obb {
                c: self.pos,
                yaw: self.yaw,
                hl: 0.85,
                hw: 0.3,
            }
        } else {
            Obb {
                c: self.pos,
                yaw: self.yaw,
                hl: 0.2,
                hw: 0.3,
            }
        }
    }

    /// Class of its boxes.
    pub fn class(&self) -> ObjectClass {
        if self.cyclist {
            ObjectClass::Cyclist
        } else {
            ObjectClass::Pedestrian
        }
    }
}

/// A walker's next leg: the node, corner quadrant and kerb it goes to, and the crossing it
/// uses (node, street axis), if any.
type Leg = (usize, usize, usize, Option<(usize, usize)>);

/// Kerb point of `node`'s corner in quadrant `q` (0: +x+y, 1: −x+y, 2: −x−y, 3: +x−y):
/// `k = 0` on the east-west street's sidewalk at its zebra (where one crosses that street),
/// `k = 1` on the north-south street's sidewalk at its zebra.
fn corner(town: &Town, node: usize, q: usize, k: usize) -> P2 {
    let (sx, sy) = match q {
        0 => (1.0, 1.0),
        1 => (-1.0, 1.0),
        2 => (-1.0, -1.0),
        _ => (1.0, -1.0),
    };
    let p = town.nodes[node].pos;
    if k == 0 {
        [p[0] + sx * ZEBRA_M, p[1] + sy * WALK_MID_M]
    } else {
        [p[0] + sx * WALK_MID_M, p[1] + sy * ZEBRA_M]
    }
}

/// Everything the ego shares the town with.
#[derive(Debug, Clone)]
pub struct Traffic {
    /// Vehicles, by id.
    pub npcs: Vec<Npc>,
    /// Pedestrians and cyclists, by id.
    pub walkers: Vec<Walker>,
    params: TrafficParams,
    draw: Stream,
    next_id: u64,
    fired: Vec<bool>,
    /// When a stuck vehicle was last taken out, s.
    last_removal_s: f64,
    /// The ego's turn at an all-way stop: the route junction it stopped before (its index
    /// in the route's junctions) and when it stood at the line, s; kept until it has left
    /// the junction.
    ego_stop: Option<(usize, f64)>,
}

/// What the traffic needs to know about the ego each update.
#[derive(Debug, Clone, Copy)]
pub struct EgoView {
    /// The ego's state.
    pub state: VehicleState,
    /// Its progress along its route, m.
    pub route_s_m: f64,
}

const IDM_T_S: f64 = 1.2;
const IDM_S0_M: f64 = 2.5;
const IDM_A: f64 = 1.5;
const IDM_B: f64 = 3.0;
const MAX_BRAKE: f64 = 8.0;
/// A vehicle slower than this stands, for the stuck rule (CARLA's traffic manager:
/// `STOPPED_VELOCITY_THRESHOLD`), m/s.
pub const STUCK_MPS: f64 = 0.8;
/// A vehicle that has stood this long, not held at a light, is stuck
/// (`BLOCKED_TIME_THRESHOLD`), s.
pub const STUCK_AFTER_S: f64 = 90.0;
/// At most one stuck vehicle is taken out per this interval
/// (`DELTA_TIME_BETWEEN_DESTRUCTIONS`), s.
pub const STUCK_REMOVAL_EVERY_S: f64 = 10.0;
/// A vehicle this close to the stop line of a red or amber light is held at it, m.
const AT_LIGHT_M: f64 = 10.0;
const SPAWN_MIN_M: f64 = 110.0;
const SPAWN_MAX_M: f64 = 190.0;
const DESPAWN_M: f64 = 230.0;
const WALKER_SPAWN_MIN_M: f64 = 50.0;
const WALKER_SPAWN_MAX_M: f64 = 120.0;
const WALKER_DESPAWN_M: f64 = 150.0;

fn idm(v: f64, v0: f64, gap: f64, dv: f64) -> f64 {
    let free = 1.0 - (v / v0.max(0.1)).powi(4);
    if !gap.is_finite() {
        return IDM_A * free;
    }
    let s_star = IDM_S0_M + (v * IDM_T_S + v * dv / (2.0 * (IDM_A * IDM_B).sqrt())).max(0.0);
    let g = gap.max(0.1);
    IDM_A * (free - (s_star / g).powi(2))
}

impl Traffic {
    /// Populates the town around the ego's start.
    pub fn new(town: &Town, route: &Route, params: TrafficParams, seed: u64) -> Self {
        let mut t = Self {
            npcs: Vec::new(),
            walkers: Vec::new(),
            params,
            draw: Stream::new(seed, &[0x7AFF]),
            next_id: 1,
            fired: vec![false; route.events.len()],
            last_removal_s: f64::NEG_INFINITY,
            ego_stop: None,
        };
        let (ego_p, _) = route.pose(0.0);
        for _ in 0..params.vehicles {
            t.spawn_vehicle(town, ego_p, 20.0, SPAWN_MAX_M, route);
        }
        for _ in 0..params.pedestrians {
            t.spawn_walker(town, ego_p, 15.0, WALKER_SPAWN_MAX_M);
        }
        t
    }

    fn new_id(&mut self) -> u64 {
        self.next_id += 1;
        self.next_id
    }

    /// A vehicle on a free stretch of lane between `r0` and `r1` m from `centre`, never
    /// on the ego's first 40 m of route.
    fn spawn_vehicle(&mut self, town: &Town, centre: P2, r0: f64, r1: f64, route: &Route) {
        for _ in 0..40 {
            let node = self.draw.index(town.nodes.len());
            let d = self.draw.index(4);
            let Some(lane) = town.lane(node, d) else {
                continue;
            };
            let s = self.draw.range(4.0, (lane.length() - 4.0).max(4.5));
            let (p, u) = lane.pose(s);
            let r = dist(p, centre);
            if r < r0 || r > r1 {
                continue;
            }
            // Never right in front of the ego at the start.
            let (p0, _) = route.pose(0.0);
            let (p40, _) = route.pose(40.0);
            if dist(p, p0) < 15.0 || dist(p, p40) < 30.0 {
                continue;
            }
            if self.npcs.iter().any(|n| dist(n.pos, p) < 12.0) {
                continue;
            }
            let id = self.new_id();
            let vseed = self.draw.bits();
            let mut draw = Stream::new(vseed, &[id]);
            let truck = draw.chance(0.12);
            let parts = objects::vehicle(&mut Draw::new(vseed, &[id, 1]), truck, false);
            let (hl, hw) = extent(&parts);
            let v = draw.range(7.0, 9.5);
            let mut npc = Npc {
                id,
                truck,
                parts,
                half_len_m: hl,
                half_width_m: hw,
                segs: VecDeque::from([Seg::Lane { node, d }]),
                s_m: s,
                speed_mps: v * 0.8,
                accel_mps2: 0.0,
                v_desired: v,
                pos: p,
                yaw: u[1].atan2(u[0]),
                stopped_at_line_s: None,
                arrived_s: None,
                admitted: None,
                braking: false,
                idle_since_s: None,
                draw,
            };
            npc.extend(town, 80.0);
            npc.update_pose(town);
            self.npcs.push(npc);
            return;
        }
    }

    fn spawn_walker(&mut self, town: &Town, centre: P2, r0: f64, r1: f64) {
        for _ in 0..40 {
            let node = self.draw.index(town.nodes.len());
            let q = self.draw.index(4);
            let k = self.draw.index(2);
            let c = corner(town, node, q, k);
            let r = dist(c, centre);
            if r < r0 || r > r1 {
                continue;
            }
            let id = self.new_id();
            let cyclist = self.draw.chance(self.params.cyclist_share);
            let w = self.make_walker(id, cyclist, c, None);
            let mut w = w;
            w.corner = Some((node, q, k));
            w.target = c;
            self.walkers.push(w);
            return;
        }
    }

    fn make_walker(&mut self, id: u64, cyclist: bool, pos: P2, target: Option<P2>) -> Walker {
        let wseed = self.draw.bits();
        let mut draw = Stream::new(wseed, &[id]);
        let mut looks = Draw::new(wseed, &[id, 1]);
        let parts = if cyclist {
            objects::cyclist(&mut looks)
        } else {
            objects::pedestrian(&mut looks)
        };
        let pace = if cyclist {
            draw.range(3.0, 4.5)
        } else {
            draw.range(1.0, 1.6)
        };
        Walker {
            id,
            cyclist,
            parts,
            pos,
            yaw: 0.0,
            pace_mps: pace,
            speed_mps: 0.0,
            target: target.unwrap_or(pos),
            corner: None,
            crossing: None,
            waiting: false,
            event: false,
            draw,
        }
    }

    /// Starts the crossing events the ego has come close to.
    fn fire_events(&mut self, route: &Route, ego: &EgoView) {
        for (k, e) in route.events.iter().enumerate() {
            if self.fired[k] || ego.route_s_m < e.s_m - e.trigger_m {
                continue;
            }
            self.fired[k] = true;
            if ego.route_s_m > e.s_m - 5.0 {
                continue; // the ego is already there (e.g. it jumped ahead): skip
            }
            let (a, b) = route.event_endpoints(e);
            let id = self.new_id();
            let mut w = self.make_walker(id, e.cyclist, a, Some(b));
            w.pace_mps = e.speed_mps;
            w.speed_mps = e.speed_mps;
            w.event = true;
            let u = sub(b, a);
            w.yaw = u[1].atan2(u[0]);
            self.walkers.push(w);
        }
    }

    /// Crossing events fired so far.
    pub fn events_fired(&self) -> usize {
        self.fired.iter().filter(|f| **f).count()
    }

    /// One update of `dt` seconds at game time `t_s`.
    pub fn step(&mut self, town: &Town, route: &Route, ego: &EgoView, t_s: f64, dt: f64) {
        self.fire_events(route, ego);
        self.ego_stop = ego_stop_turn(self.ego_stop, route, ego, t_s);
        let ego_turn = self.ego_stop.and_then(|(j, t0)| {
            route
                .junctions
                .get(j)
                .map(|rj| (rj.node, (rj.din, rj.dout), t0))
        });
        let ego_approach = ego_approach(route, ego);
        self.step_vehicles(town, ego, ego_turn, ego_approach, t_s, dt);
        self.step_walkers(town, ego, t_s, dt);
    }

    /// `ego_turn`: the node of the all-way stop the ego stood at, its path through it and
    /// when it stood at the line (see [`ego_stop_turn`]); `ego_approach`: the junction the
    /// ego approaches or crosses (see [`ego_approach`]).
    fn step_vehicles(
        &mut self,
        town: &Town,
        ego: &EgoView,
        ego_turn: Option<(usize, (usize, usize), f64)>,
        ego_approach: Option<(usize, usize, f64, f64)>,
        t_s: f64,
        dt: f64,
    ) {
        let ego_box = ego_box(&ego.state);
        let ego_pts = [
            ego.state.point(-1.2, 0.0),
            ego.state.point(1.25, 0.0),
            ego.state.point(3.7, 0.0),
        ];
        let ego_vel = {
            let h = ego.state.heading();
            [h[0] * ego.state.speed_mps, h[1] * ego.state.speed_mps]
        };
        // Snapshot of everyone's state for this update (so the order does not matter).
        struct Body {
            id: u64,
            pts: [P2; 3],
            vel: P2,
            half_w: f64,
            half_l: f64,
        }
        let mut bodies: Vec<Body> = self
            .npcs
            .iter()
            .map(|n| {
                let u = unit(n.yaw);
                Body {
                    id: n.id,
                    pts: [
                        add(n.pos, u, -n.half_len_m * 0.8),
                        n.pos,
                        add(n.pos, u, n.half_len_m * 0.8),
                    ],
                    vel: [u[0] * n.speed_mps, u[1] * n.speed_mps],
                    half_w: n.half_width_m,
                    half_l: n.half_len_m,
                }
            })
            .collect();
        bodies.push(Body {
            id: 0,
            pts: ego_pts,
            vel: ego_vel,
            half_w: EGO_HALF_WIDTH_M,
            half_l: EGO_HALF_LENGTH_M,
        });
        for w in &self.walkers {
            let u = unit(w.yaw);
            bodies.push(Body {
                id: w.id,
                pts: [w.pos, w.pos, w.pos],
                vel: [u[0] * w.speed_mps, u[1] * w.speed_mps],
                half_w: w.radius_m() + 0.3,
                half_l: w.radius_m(),
            });
        }
        // Junction occupancy: who is on a path through which node, and who is admitted.
        let mut occupancy: Vec<(usize, usize, usize, u64)> = self
            .npcs
            .iter()
            .filter_map(|n| match n.segs[0] {
                Seg::Conn { node, din, dout } => Some((node, din, dout, n.id)),
                Seg::Lane { .. } => n.admitted.and_then(|node| {
                    n.segs.iter().find_map(|s| match *s {
                        Seg::Conn { node: m, din, dout } if m == node => {
                            Some((node, din, dout, n.id))
                        }
                        _ => None,
                    })
                }),
            })
            .collect();
        // Vehicles waiting at stop lines: (node, arrival time, id).
        let waiting: Vec<(usize, f64, u64)> = self
            .npcs
            .iter()
            .filter_map(|n| match (n.segs[0], n.arrived_s, n.admitted) {
                (Seg::Lane { node, d }, Some(t), None) => {
                    town.neighbor(node, d).map(|b| (b, t, n.id))
                }
                _ => None,
            })
            .collect();
        // Vehicles near the start of each lane (for exit space): (node, d, s).
        let lane_starts: Vec<(usize, usize, f64)> = self
            .npcs
            .iter()
            .filter_map(|n| match n.segs[0] {
                Seg::Lane { node, d } => Some((node, d, n.s_m - n.half_len_m)),
                _ => None,
            })
            .collect();
        // Vehicles approaching each node: (node, din, distance to its stop line, speed) —
        // the ego's included, so that a car turning left at a signal yields to it as to any
        // oncoming vehicle.
        let approaching: Vec<(usize, usize, f64, f64)> = self
            .npcs
            .iter()
            .filter_map(|n| match n.segs[0] {
                Seg::Lane { node, d } => town.neighbor(node, d).map(|b| {
                    let len = n.seg_len(town, 0);
                    (
                        b,
                        d,
                        len - LINE_TO_ZONE_M - n.s_m - n.half_len_m,
                        n.speed_mps,
                    )
                }),
                _ => None,
            })
            .chain(ego_approach)
            .collect();
        let ego_pos = ego_box.c;
        for n in &mut self.npcs {
            let v = n.speed_mps;
            let look = (12.0 + 3.0 * v).min(45.0);
            n.extend(town, look + 40.0);
            let probes = n.probes(town, look);
            // Nearest body on the path.
            let mut gap = f64::INFINITY;
            let mut lead_v = 0.0;
            let centre = n.pos;
            for b in &bodies {
                if b.id == n.id || !within(b.pts[1], centre, look + n.half_len_m + 8.0) {
                    continue;
                }
                if b.id == 0 {
                    // The ego: the vehicle's body (0.25 m wider either side) moved along its
                    // path against the ego's body. Discs round three points of each are
                    // too coarse across a turn: a vehicle turning past the nose of a
                    // standing ego would wait for it, while the ego waits for it.
                    for &(s, p, u) in &probes {
                        if path_body(p, u, n.half_len_m, n.half_width_m).overlaps(&ego_box)
                            && dot(sub(ego_box.c, centre), unit(n.yaw)) >= 0.0
                        {
                            if s < gap {
                                gap = s;
                                lead_v = dot(b.vel, u).max(0.0);
                            }
                            break;
                        }
                    }
                    continue;
                }
                'probe: for &(s, p, u) in &probes {
                    for q in b.pts {
                        if within(p, q, n.half_width_m + b.half_w + 0.25) {
                            // Only what is ahead (not something alongside behind the bumper).
                            if dot(sub(q, centre), unit(n.yaw)) < 0.0 {
                                continue;
                            }
                            let g = (s - b.half_l * 0.5).max(0.0);
                            if g < gap {
                                gap = g;
                                lead_v = dot(b.vel, u).max(0.0);
                            }
                            break 'probe;
                        }
                    }
                }
            }
            // Junction ahead.
            let mut held_at_light = false;
            let mut v0 = n.v_desired;
            let mut line_gap = f64::INFINITY;
            if let Seg::Lane { node, d } = n.segs[0] {
                let len = n.seg_len(town, 0);
                let to_line = len - LINE_TO_ZONE_M - n.s_m - n.half_len_m;
                let to_zone = len - n.s_m - n.half_len_m;
                if let (Some(b), Some(Seg::Conn { din, dout, .. })) =
                    (town.neighbor(node, d), n.segs.get(1).copied())
                {
                    if turn_of(din, dout) != 0 && to_zone < 30.0 {
                        v0 = v0.min(if turn_of(din, dout) == 3 { 4.0 } else { 5.5 });
                    }
                    let control = town.nodes[b].control;
                    // Green where there is no signal.
                    let light = town.light(b, din, t_s);
                    held_at_light =
                        n.admitted != Some(b) && to_line < AT_LIGHT_M && light != Light::Green;
                    if n.admitted != Some(b) && to_line < 40.0 {
                        let mut must_stop = false;
                        match control {
                            Control::Signal => match light {
                                Light::Red => must_stop = true,
                                Light::Amber => must_stop = to_line > v * v / (2.0 * 3.5),
                                Light::Green => {}
                            },
                            Control::Stop => {
                                if v < 0.1 && to_line < 2.5 {
                                    n.arrived_s.get_or_insert(t_s);
                                    n.stopped_at_line_s.get_or_insert(t_s);
                                } else if v >= 0.1 {
                                    n.stopped_at_line_s = None;
                                }
                                let waited = n.stopped_at_line_s.is_some_and(|t0| t_s - t0 >= 1.0);
                                must_stop = !waited;
                                if waited {
                                    let arrived = n.arrived_s.unwrap_or(t_s);
                                    let first = waiting
                                        .iter()
                                        .filter(|w| w.0 == b && w.2 != n.id)
                                        .all(|w| w.1 >= arrived);
                                    // The ego takes its turn too: one that stood at
                                    // this junction's line first goes first, on a
                                    // crossing path, until it has left the junction.
                                    let ego_first = ego_turn.is_some_and(|(m, path, t0)| {
                                        m == b
                                            && t0 <= arrived
                                            && town.conflicts(b, (din, dout), path)
                                    });
                                    must_stop = !first || ego_first;
                                }
                            }
                            Control::None => {}
                        }
                        if !must_stop && to_line < 12.0 + v * v / (2.0 * IDM_B) {
                            // Admission: crossing paths free, exit free, ego clear.
                            let busy = occupancy.iter().any(|&(m, di, do_, id)| {
                                m == b && id != n.id && town.conflicts(b, (din, dout), (di, do_))
                            });
                            let exit_full = lane_starts
                                .iter()
                                .any(|&(m, dd, s)| m == b && dd == dout && s < 9.0);
                            let conn = seg_poly(town, Seg::Conn { node: b, din, dout });
                            let ego_in = ego_holds(
                                ego_pos,
                                ego.state.speed_mps,
                                (n.pos, n.yaw, n.half_width_m),
                                town.nodes[b].pos,
                                &conn.pts,
                            );
                            let oncoming = control == Control::Signal
                                && turn_of(din, dout) == 1
                                && approaching.iter().any(|&(m, di, dl, sp)| {
                                    m == b && di == (din + 2) % 4 && dl < 35.0 && sp > 1.5
                                });
                            if busy || exit_full || ego_in || oncoming {
                                if log::log_enabled!(log::Level::Trace)
                                    && within(n.pos, ego_pos, 90.0)
                                {
                                    let by: Vec<u64> = occupancy
                                        .iter()
                                        .filter(|&&(m, di, do_, id)| {
                                            m == b
                                                && id != n.id
                                                && town.conflicts(b, (din, dout), (di, do_))
                                        })
                                        .map(|o| o.3)
                                        .collect();
                                    log::trace!(
                                        "truth t {t_s:.1} npc {} held at node {b}: busy {by:?} exit_full {exit_full} ego_in {ego_in} oncoming {oncoming}",
                                        n.id
                                    );
                                }
                                must_stop = true;
                            } else {
                                n.admitted = Some(b);
                                occupancy.push((b, din, dout, n.id));
                            }
                        }
                        if must_stop {
                            line_gap = to_line.max(0.0);
                        }
                    }
                }
            }
            let a_lead = idm(v, v0, gap, v - lead_v);
            let a_line = idm(v, v0, line_gap + IDM_S0_M - 0.5, v);
            let a = a_lead.min(a_line).clamp(-MAX_BRAKE, IDM_A);
            n.accel_mps2 = a;
            n.braking = a < -0.5 || (v < 0.1 && (gap < 8.0 || line_gap < 3.0));
            let v_new = (v + a * dt).max(0.0);
            n.s_m += 0.5 * (v + v_new) * dt;
            n.speed_mps = v_new;
            if n.idle_since_s.is_none() || v_new > STUCK_MPS || held_at_light {
                n.idle_since_s = Some(t_s);
            }
            while n.segs.len() > 1 {
                let len = n.seg_len(town, 0);
                if n.s_m <= len {
                    break;
                }
                n.s_m -= len;
                let left = n.segs.pop_front();
                if let Some(Seg::Conn { .. }) = left {
                    n.admitted = None;
                }
                if let Some(Seg::Lane { .. }) = left {
                    n.arrived_s = None;
                    n.stopped_at_line_s = None;
                }
            }
            n.update_pose(town);
        }
        self.remove_stuck(t_s);
        // Respawn those that drifted away.
        let far: Vec<usize> = (0..self.npcs.len())
            .filter(|&k| !within(self.npcs[k].pos, ego_pos, DESPAWN_M))
            .collect();
        for k in far.into_iter().rev() {
            self.npcs.remove(k);
        }
    }

    /// Takes out the vehicle that has been stuck longest (see the module's documentation),
    /// if any has been for [`STUCK_AFTER_S`] and none was taken out in the last
    /// [`STUCK_REMOVAL_EVERY_S`]; [`Traffic::refill`] puts another in elsewhere.
    fn remove_stuck(&mut self, t_s: f64) {
        if t_s - self.last_removal_s < STUCK_REMOVAL_EVERY_S {
            return;
        }
        let longest = self
            .npcs
            .iter()
            .enumerate()
            .filter_map(|(k, n)| n.idle_since_s.map(|t0| (k, t0)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, t0)) = longest
            && t_s - t0 >= STUCK_AFTER_S
        {
            log::trace!(
                "truth t {t_s:.1} npc {} stuck for {:.0} s: taken out",
                self.npcs[k].id,
                t_s - t0
            );
            self.npcs.remove(k);
            self.last_removal_s = t_s;
        }
    }

    /// Fills the population back up (called once a second).
    pub fn refill(&mut self, town: &Town, route: &Route, ego: &EgoView) {
        let c = ego.state.point(0.0, 0.0);
        while self.npcs.len() < self.params.vehicles {
            let before = self.npcs.len();
            self.spawn_vehicle(town, c, SPAWN_MIN_M, SPAWN_MAX_M, route);
            if self.npcs.len() == before {
                break;
            }
        }
        self.npcs.sort_by_key(|n| n.id);
        let roaming = self.walkers.iter().filter(|w| !w.event).count();
        for _ in roaming..self.params.pedestrians {
            let before = self.walkers.len();
            self.spawn_walker(town, c, WALKER_SPAWN_MIN_M, WALKER_SPAWN_MAX_M);
            if self.walkers.len() == before {
                break;
            }
        }
    }

    fn step_walkers(&mut self, town: &Town, ego: &EgoView, t_s: f64, dt: f64) {
        let ego_p = ego.state.point(EGO_CENTRE_AHEAD_M, 0.0);
        let vehicles: Vec<(P2, f64)> = self
            .npcs
            .iter()
            .map(|n| (n.pos, n.speed_mps))
            .chain(std::iter::once((ego_p, ego.state.speed_mps)))
            .collect();
        for w in &mut self.walkers {
            if w.waiting {
                // At the kerb of a crossing: wait for the signal and for near vehicles.
                let Some((cn, axis)) = w.crossing else {
                    w.waiting = false;
                    continue;
                };
                let need = dist(w.pos, w.target) / w.pace_mps + 1.0;
                // Crossing the x-street (its traffic travels along x): go while the y-axis
                // has green long enough; and the other way round.
                let allowed = match town.nodes[cn].control {
                    Control::Signal => {
                        let perpendicular = if axis == 0 { 1 } else { 0 };
                        town.light(cn, perpendicular, t_s) == Light::Green
                            && town.green_left_s(cn, perpendicular, t_s) > need
                    }
                    _ => true,
                };
                if allowed && !walker_waits(&vehicles, w.pos, w.target) {
                    w.waiting = false;
                } else {
                    w.speed_mps = 0.0;
                    continue;
                }
            } else if dist(w.pos, w.target) < 0.05 {
                if w.event {
                    w.speed_mps = 0.0;
                    continue;
                }
                // At a kerb: pick the next leg.
                let Some((node, q, k)) = w.corner else {
                    w.speed_mps = 0.0;
                    continue;
                };
                // Options: cross the street of this kerb, walk along it to the next junction,
                // or go round the corner to the other kerb.
                let mut opts: Vec<Leg> = Vec::new();
                let arms = town.nodes[node].arms;
                let controlled = town.nodes[node].control != Control::None;
                // The x-street's arm on this corner's side, and the y-street's.
                let x_side = if q == 0 || q == 3 { 0 } else { 2 };
                let y_side = if q == 0 || q == 1 { 1 } else { 3 };
                if k == 0 {
                    let across = match q {
                        0 => 3,
                        1 => 2,
                        2 => 1,
                        _ => 0,
                    };
                    if arms[x_side] && controlled {
                        opts.push((node, across, 0, Some((node, 0))));
                    }
                    if let Some(m) = town.neighbor(node, x_side) {
                        opts.push((m, along(q, true), 0, None));
                    }
                } else {
                    let across = match q {
                        0 => 1,
                        1 => 0,
                        2 => 3,
                        _ => 2,
                    };
                    if arms[y_side] && controlled {
                        opts.push((node, across, 1, Some((node, 1))));
                    }
                    if let Some(m) = town.neighbor(node, y_side) {
                        opts.push((m, along(q, false), 1, None));
                    }
                }
                opts.push((node, q, 1 - k, None));
                let pick = opts[w.draw.index(opts.len())];
                w.corner = Some((pick.0, pick.1, pick.2));
                w.crossing = pick.3;
                w.target = corner(town, pick.0, pick.1, pick.2);
                w.waiting = pick.3.is_some();
                w.speed_mps = 0.0;
                continue;
            }
            let to = sub(w.target, w.pos);
            let d = to[0].hypot(to[1]);
            if d < 1e-9 {
                continue;
            }
            w.yaw = to[1].atan2(to[0]);
            w.speed_mps = w.pace_mps;
            let step = (w.pace_mps * dt).min(d);
            w.pos = add(w.pos, [to[0] / d, to[1] / d], step);
        }
        let far: Vec<usize> = (0..self.walkers.len())
            .filter(|&k| !within(self.walkers[k].pos, ego_p, WALKER_DESPAWN_M))
            .collect();
        for k in far.into_iter().rev() {
            self.walkers.remove(k);
        }
    }

    /// Crossing events of the route (for tests and records).
    pub fn events<'a>(&self, route: &'a Route) -> &'a [CrossingEvent] {
        &route.events
    }
}

/// A vehicle's body with its front bumper at `front`, heading `u` (a unit vector), 0.25 m
/// wider either side: where it would be at a point of its path, for testing against the
/// ego's body.
pub fn path_body(front: P2, u: P2, half_len: f64, half_width: f64) -> Obb {
    Obb {
        c: add(front, u, -half_len),
        yaw: u[1].atan2(u[0]),
        hl: half_len,
        hw: half_width + 0.25,
    }
}

/// Whether the ego keeps a vehicle (`(position, yaw, half width)`) from entering the
/// junction at `node` along the path `path`: the ego is ahead of it, near the junction,
/// and on or near the path. A moving ego is given room (3.5 m beyond its half length: it
/// may drive into the path); a standing one holds the vehicle only where its body is on
/// the path (its half length, the vehicle's half width and 0.5 m), else both would wait
/// for each other for good. An ego queued behind the vehicle is not in its way.
pub fn ego_holds(
    ego_pos: P2,
    ego_speed_mps: f64,
    (pos, yaw, half_width): (P2, f64, f64),
    node: P2,
    path: &[P2],
) -> bool {
    let ahead = dot(sub(ego_pos, pos), unit(yaw)) > 0.0;
    let room = if ego_speed_mps < 0.5 {
        EGO_HALF_LENGTH_M + half_width + 0.5
    } else {
        3.5 + EGO_HALF_LENGTH_M
    };
    ahead && dist(ego_pos, node) < ZONE_M + 6.0 && path.iter().any(|&p| within(p, ego_pos, room))
}

/// The junction of its route the ego approaches or is crossing, as the vehicles' own
/// approaches are listed for the left-turn check: (node, travel direction in, distance from
/// its front to the stop line — negative past it —, speed). `None` beyond the route's
/// last junction.
pub fn ego_approach(route: &Route, ego: &EgoView) -> Option<(usize, usize, f64, f64)> {
    let s = ego.route_s_m;
    route
        .junctions
        .iter()
        .find(|rj| s <= rj.s_exit_m)
        .map(|rj| {
            (
                rj.node,
                rj.din,
                rj.s_stop_line_m - s - EGO_CENTRE_AHEAD_M - EGO_HALF_LENGTH_M,
                ego.state.speed_mps,
            )
        })
}

/// The ego's turn at an all-way stop, updated: it takes one when it stands (below
/// 0.1 m/s) within 6 m before the stop line of a route junction with stop signs (`t_s`
/// then), and keeps it until its route progress passes the junction's exit, or it is no
/// longer before or in that junction. `None`: no turn taken.
pub fn ego_stop_turn(
    turn: Option<(usize, f64)>,
    route: &Route,
    ego: &EgoView,
    t_s: f64,
) -> Option<(usize, f64)> {
    let s = ego.route_s_m;
    if let Some((j, t0)) = turn
        && let Some(rj) = route.junctions.get(j)
        && s >= rj.s_stop_line_m - 8.0
        && s <= rj.s_exit_m
    {
        return Some((j, t0));
    }
    (ego.state.speed_mps < 0.1)
        .then(|| {
            route.junctions.iter().position(|rj| {
                rj.control == Control::Stop
                    && s >= rj.s_stop_line_m - 6.0
                    && s <= rj.s_stop_line_m + 1.0
            })
        })
        .flatten()
        .map(|j| (j, t_s))
}

/// The quadrant reached when walking along a block side from quadrant `q` (along x when
/// `along_x`): the same side of the street, the other end of the block.
fn along(q: usize, along_x: bool) -> usize {
    if along_x {
        match q {
            0 => 1,
            1 => 0,
            2 => 3,
            _ => 2,
        }
    } else {
        match q {
            0 => 3,
            1 => 2,
            2 => 1,
            _ => 0,
        }
    }
}

/// Half length and half width of a solid's parts (its x and y extent).
pub fn extent(parts: &[Part]) -> (f64, f64) {
    let (mut x0, mut x1, mut y0, mut y1) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for p in parts {
        if let Part::Cuboid { centre, half, .. } = p {
            x0 = x0.min(centre[0] - half[0]);
            x1 = x1.max(centre[0] + half[0]);
            y0 = y0.min(centre[1] - half[1]);
            y1 = y1.max(centre[1] + half[1]);
        }
    }
    ((x1 - x0) / 2.0, (y1 - y0) / 2.0)
}

/// A vehicle slower than this is standing for a walker at the kerb, m/s.
const STANDING_MPS: f64 = 0.3;
/// A standing vehicle whose centre is this close to a walker's line across is on the
/// crossing, m (a car's half length and a metre).
const ON_CROSSING_M: f64 = 3.5;

/// Whether a walker at the kerb, about to cross from `from` to `to`, waits for `vehicles`
/// (box centre, speed): for a moving vehicle within 8 m (plus 2 s of its travel) of the
/// crossing's middle, or a standing one on the crossing. A vehicle standing short of the
/// crossing is yielding to the walker, who goes: when walkers waited for any vehicle near,
/// a car that stopped for them held them, and they it, for good.
fn walker_waits(vehicles: &[(P2, f64)], from: P2, to: P2) -> bool {
    let mid = [(from[0] + to[0]) / 2.0, (from[1] + to[1]) / 2.0];
    let d = sub(to, from);
    let len2 = dot(d, d).max(1e-9);
    vehicles.iter().any(|&(p, sp)| {
        if sp < STANDING_MPS {
            let k = (dot(sub(p, from), d) / len2).clamp(0.0, 1.0);
            within(p, add(from, d, k), ON_CROSSING_M)
        } else {
            within(p, mid, 8.0 + 2.0 * sp)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ego_takes_its_turn_at_an_all_way_stop_and_keeps_it_through_the_junction() {
        let town = Town::generate(crate::town::TownParams::default(), 1, 0);
        let mut draw = Draw::new(5, &[1]);
        let (route, j) = (0..50)
            .find_map(|_| {
                let r = crate::route::generate(&town, 1500.0, 6.0, &mut draw).ok()?;
                let j = r
                    .junctions
                    .iter()
                    .position(|rj| rj.control == Control::Stop)?;
                Some((r, j))
            })
            .expect("a route through an all-way stop");
        let rj = route.junctions[j];
        let at = |s: f64, v: f64| EgoView {
            state: VehicleState {
                speed_mps: v,
                ..VehicleState::default()
            },
            route_s_m: s,
        };
        // Rolling up to the line, or standing 10 m short of it: no turn.
        assert_eq!(
            ego_stop_turn(None, &route, &at(rj.s_stop_line_m - 2.0, 3.0), 10.0),
            None
        );
        assert_eq!(
            ego_stop_turn(None, &route, &at(rj.s_stop_line_m - 10.0, 0.0), 10.0),
            None
        );
        // Standing 2 m before it: the turn, from then; kept while it drives through.
        let turn = ego_stop_turn(None, &route, &at(rj.s_stop_line_m - 2.0, 0.0), 10.0);
        assert_eq!(turn, Some((j, 10.0)));
        let mid = 0.5 * (rj.s_entry_m + rj.s_exit_m);
        assert_eq!(ego_stop_turn(turn, &route, &at(mid, 4.0), 14.0), turn);
        // Out of the junction: given up.
        assert_eq!(
            ego_stop_turn(turn, &route, &at(rj.s_exit_m + 1.0, 6.0), 16.0),
            None
        );
    }

    #[test]
    fn the_ego_is_listed_as_approaching_the_next_junction_of_its_route() {
        let town = Town::generate(crate::town::TownParams::default(), 1, 0);
        let route = crate::route::generate(&town, 1500.0, 6.0, &mut Draw::new(5, &[1])).unwrap();
        assert!(route.junctions.len() >= 2);
        let (a, b) = (route.junctions[0], route.junctions[1]);
        let at = |s: f64, v: f64| EgoView {
            state: VehicleState {
                speed_mps: v,
                ..VehicleState::default()
            },
            route_s_m: s,
        };
        // 20 m before the first stop line (its front 3.7 m ahead of the reference point).
        let (node, din, to_line, v) =
            ego_approach(&route, &at(a.s_stop_line_m - 20.0, 7.0)).expect("an approach");
        assert_eq!((node, din, v), (a.node, a.din, 7.0));
        assert!((to_line - (20.0 - EGO_CENTRE_AHEAD_M - EGO_HALF_LENGTH_M)).abs() < 1e-9);
        // Inside the junction: still that one, past its line.
        let mid = 0.5 * (a.s_entry_m + a.s_exit_m);
        let inside = ego_approach(&route, &at(mid, 5.0)).expect("an approach");
        assert_eq!(inside.0, a.node);
        assert!(inside.2 < 0.0);
        // Out of it: the next one; past the last one: none.
        assert_eq!(
            ego_approach(&route, &at(a.s_exit_m + 0.5, 5.0)).map(|x| x.0),
            Some(b.node)
        );
        let last = route.junctions[route.junctions.len() - 1];
        assert_eq!(ego_approach(&route, &at(last.s_exit_m + 1.0, 5.0)), None);
    }

    #[test]
    fn the_vehicle_stuck_longest_is_taken_out_one_at_a_time() {
        let town = Town::generate(crate::town::TownParams::default(), 1, 0);
        let route = crate::route::generate(&town, 600.0, 6.0, &mut Draw::new(5, &[1])).unwrap();
        let mut t = Traffic::new(&town, &route, TrafficParams::default(), 3);
        assert!(t.npcs.len() > 3);
        for n in &mut t.npcs {
            n.idle_since_s = Some(200.0);
        }
        let (a, b) = (t.npcs[1].id, t.npcs[2].id);
        t.npcs[1].idle_since_s = Some(100.0);
        t.npcs[2].idle_since_s = Some(105.0);
        let n0 = t.npcs.len();
        // Stood 89 s: not yet.
        t.remove_stuck(189.0);
        assert_eq!(t.npcs.len(), n0);
        // 90 s: the one standing longest goes; the next only 10 s later.
        t.remove_stuck(190.0);
        assert_eq!(t.npcs.len(), n0 - 1);
        assert!(t.npcs.iter().all(|n| n.id != a));
        t.remove_stuck(199.0);
        assert_eq!(t.npcs.len(), n0 - 1);
        t.remove_stuck(200.0);
        assert_eq!(t.npcs.len(), n0 - 2);
        assert!(t.npcs.iter().all(|n| n.id != b));
        // The rest stood since 200 s: none is stuck at 250 s.
        t.remove_stuck(250.0);
        assert_eq!(t.npcs.len(), n0 - 2);
    }

    #[test]
    fn a_walker_crosses_in_front_of_a_car_standing_for_them_not_of_one_on_the_crossing() {
        // A crossing from (0, -5) to (0, 5); a car heading +x.
        let (from, to) = ([0.0, -5.0], [0.0, 5.0]);
        // Standing with its nose 1 m short of the crossing's 3 m band: the walker goes.
        assert!(!walker_waits(
            &[([-1.5 - 1.0 - 2.45, -1.75], 0.0)],
            from,
            to
        ));
        // Standing over the crossing: the walker waits.
        assert!(walker_waits(&[([-1.0, -1.75], 0.0)], from, to));
        // Moving towards it 10 m off at 5 m/s, or 7 m off at 1 m/s: the walker waits.
        assert!(walker_waits(&[([-10.0, -1.75], 5.0)], from, to));
        assert!(walker_waits(&[([-7.0, -1.75], 1.0)], from, to));
        // Far, or none: the walker goes.
        assert!(!walker_waits(&[([-30.0, -1.75], 5.0)], from, to));
        assert!(!walker_waits(&[], from, to));
    }

    #[test]
    fn a_standing_ego_holds_a_vehicle_only_where_it_stands_on_its_path() {
        // A vehicle at its stop line at (-12, -1.75), heading +x through a junction at
        // the origin, its path straight on along y = -1.75.
        let path: Vec<P2> = (0..=24).map(|k| [-12.0 + k as f64, -1.75]).collect();
        let npc = ([-14.0, -1.75], 0.0, 0.9);
        let node = [0.0, 0.0];
        // An ego across the path, standing or moving: held.
        assert!(ego_holds([0.0, -1.0], 0.0, npc, node, &path));
        assert!(ego_holds([0.0, -1.0], 5.0, npc, node, &path));
        // An ego 5 m beside the path: room enough when it stands, not when it moves.
        assert!(!ego_holds([-2.0, 3.25], 0.0, npc, node, &path));
        assert!(ego_holds([-2.0, 3.25], 5.0, npc, node, &path));
        // An ego queued behind the vehicle never holds it.
        assert!(!ego_holds([-20.0, -1.75], 0.0, npc, node, &path));
        assert!(!ego_holds([-20.0, -1.75], 5.0, npc, node, &path));
        // Far from the junction: no.
        assert!(!ego_holds([30.0, -1.75], 5.0, npc, [60.0, 0.0], &path));
    }

    #[test]
    fn a_vehicle_turning_past_a_standing_egos_nose_is_not_held_by_it() {
        // The ego stands at the origin heading +x; its nose is 2.45 m ahead of its centre.
        let ego = Obb {
            c: [0.0, 0.0],
            yaw: 0.0,
            hl: EGO_HALF_LENGTH_M,
            hw: EGO_HALF_WIDTH_M,
        };
        // A car (2.3 × 0.9 m half sizes) crossing in front of it, heading -y, its front
        // bumper 3.8 m ahead of the ego's centre and 1.2 m left of it: its body (with the
        // 0.25 m margin) spans x 2.65–4.95 m, clear of the ego's nose at 2.45 m, though a
        // disc of 2.1 m round its front point reaches the nose.
        let front = [3.8, 1.2];
        let body = path_body(front, [0.0, -1.0], 2.3, 0.9);
        assert_eq!(body.c, [3.8, 3.5]);
        assert!(!body.overlaps(&ego));
        assert!(within(
            front,
            [EGO_HALF_LENGTH_M, 0.0],
            0.9 + EGO_HALF_WIDTH_M + 0.25
        ));
        // With its front at (3.4, 0.5) its body spans x 2.25–4.55 m and y 0.5–5.1 m: over
        // the ego's nose.
        let closer = path_body([3.4, 0.5], [0.0, -1.0], 2.3, 0.9);
        assert!(closer.overlaps(&ego));
    }
}
