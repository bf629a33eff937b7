//! Scene builders, one per scenario class, and the privileged expert that drives each scene.
//!
//! Every builder draws its parameters from one seeded stream, lays out roads and solids, and
//! asks the expert for the ground-truth future. The expert plans with the same motion
//! primitives as the reference planner ([`fogline_types::motion`]) but from the true scene:
//! true distances, true speeds, true light states.

use crate::objects::{self, LightState};
use crate::scene::{Bar, Centre, Draw, EgoMotion, Look, Mark, ObjectClass, Scene, Solid, Strip};
use fogline_types::clip::{Decision, Trajectory};
use fogline_types::motion::{
    EGO_FRONT_M, EGO_WIDTH_M, Idm, Lateral, Lead, Path, cruise, follow, rollout, slow_for_turn,
    stop_within,
};
use serde_json::{Map, Value, json};
use std::f64::consts::{FRAC_PI_2, PI};

/// A built scene with the expert's answer.
pub struct Built {
    /// The scene.
    pub scene: Scene,
    /// The expert's decision.
    pub decision: Decision,
    /// The expert's future.
    pub truth: Trajectory,
    /// Scene facts.
    pub facts: Map<String, Value>,
}

const WHITE: [f32; 3] = [232.0, 232.0, 226.0];
const YELLOW: [f32; 3] = [226.0, 186.0, 40.0];
/// Speed at which the expert takes a right turn, m/s.
pub const TURN_SPEED: f64 = 5.0;

/// Cross-section of a road around the ego lane's centreline (`d = 0`).
#[derive(Debug, Clone, Copy)]
struct Road {
    /// Lane width.
    w: f64,
    /// Same-direction lanes left of the ego lane.
    left: usize,
    /// Oncoming lanes.
    oncoming: usize,
    /// Shoulder beyond the edge lines.
    shoulder: f64,
    /// Sidewalk width (0 for a rural road).
    walk: f64,
}

impl Road {
    fn d_min(&self) -> f64 {
        -self.w / 2.0 - self.shoulder
    }
    fn d_max(&self) -> f64 {
        self.w / 2.0 + (self.left + self.oncoming) as f64 * self.w + self.shoulder
    }
    /// Centre of lane `k` (0 = ego, 1.. = further left).
    fn lane(&self, k: usize) -> f64 {
        k as f64 * self.w
    }
    fn marks(&self) -> Vec<Mark> {
        let line = |d: f64, dash: Option<(f64, f64)>, color| Mark {
            d,
            width: 0.15,
            dash,
            color,
            s_min: f64::NEG_INFINITY,
            s_max: f64::INFINITY,
        };
        let mut m = vec![line(-self.w / 2.0, None, WHITE)];
        let mut d = self.w / 2.0;
        for _ in 0..self.left {
            m.push(line(d, Some((3.0, 10.0)), WHITE));
            d += self.w;
        }
        if self.oncoming > 0 {
            m.push(line(d - 0.12, None, YELLOW));
            m.push(line(d + 0.12, None, YELLOW));
            for _ in 1..self.oncoming {
                d += self.w;
                m.push(line(d, Some((3.0, 10.0)), WHITE));
            }
            d += self.w;
        }
        m.push(line(d, None, WHITE));
        m
    }
    fn strip(&self, centre: Centre, s_min: f64, s_max: f64) -> Strip {
        Strip {
            centre,
            s_min,
            s_max,
            d_min: self.d_min(),
            d_max: self.d_max(),
            walk: self.walk,
            marks: self.marks(),
            bars: Vec::new(),
        }
    }
}

/// The ego road's centreline for curvature `kappa` (through the origin, heading +x).
fn ego_centre(kappa: f64) -> Centre {
    if kappa.abs() < 1e-9 {
        Centre::Line {
            origin: [0.0, 0.0],
            dir: [1.0, 0.0],
        }
    } else if kappa > 0.0 {
        Centre::Arc {
            centre: [0.0, 1.0 / kappa],
            radius: 1.0 / kappa,
            left: true,
            start: -FRAC_PI_2,
        }
    } else {
        Centre::Arc {
            centre: [0.0, 1.0 / kappa],
            radius: -1.0 / kappa,
            left: false,
            start: FRAC_PI_2,
        }
    }
}

/// The arc-length range a road of curvature `kappa` can span without wrapping.
fn arc_range(kappa: f64) -> (f64, f64) {
    if kappa.abs() < 1e-9 {
        (-250.0, 400.0)
    } else {
        let r = 1.0 / kappa.abs();
        (-(r * 0.6).min(250.0), (r * 2.2).min(400.0))
    }
}

/// World pose at arc length `s` and lateral offset `d` along a path.
fn on_path(path: &Path, s: f64, d: f64) -> ([f64; 2], f64) {
    let (x, y, h) = path.pose_at(s);
    ([x - d * h.sin(), y + d * h.cos()], h)
}

/// Scene assembly state.
struct Ctx {
    draw: Draw,
    solids: Vec<Solid>,
    next_track: u64,
    facts: Map<String, Value>,
}

impl Ctx {
    fn track(&mut self) -> u64 {
        self.next_track += 1;
        self.next_track
    }

    fn add(&mut self, solid: Solid) {
        self.solids.push(solid);
    }

    fn fact(&mut self, k: &str, v: Value) {
        self.facts.insert(k.to_string(), v);
    }

    /// A vehicle at `(s, d)` on `path`, `dir` = +1 along the path or −1 against it.
    #[allow(clippy::too_many_arguments)]
    fn vehicle_on(
        &mut self,
        path: &Path,
        s: f64,
        d: f64,
        dir: f64,
        speed: f64,
        accel: f64,
        truck: bool,
        braking: bool,
    ) -> f64 {
        let parts = objects::vehicle(&mut self.draw, truck, braking);
        let (pos, h) = on_path(path, s, d);
        let yaw = if dir > 0.0 { h } else { h + PI };
        self.push_vehicle(parts, pos, yaw, speed, accel, truck)
    }

    /// A lead vehicle in the ego lane, its rear bumper `gap` m ahead of the ego's front.
    #[allow(clippy::too_many_arguments)]
    fn lead_on(
        &mut self,
        path: &Path,
        gap: f64,
        speed: f64,
        accel: f64,
        truck: bool,
        braking: bool,
    ) {
        let parts = objects::vehicle(&mut self.draw, truck, braking);
        let centre_s = EGO_FRONT_M + gap + length_of(&parts) / 2.0;
        let (pos, h) = on_path(path, centre_s, 0.0);
        self.push_vehicle(parts, pos, h, speed, accel, truck);
    }

    /// Adds a tracked car or truck; returns its length.
    fn push_vehicle(
        &mut self,
        parts: Vec<crate::scene::Part>,
        pos: [f64; 2],
        yaw: f64,
        speed: f64,
        accel: f64,
        truck: bool,
    ) -> f64 {
        let class = if truck {
            ObjectClass::Truck
        } else {
            ObjectClass::Car
        };
        let tag = Some((class, self.track()));
        let len = length_of(&parts);
        self.add(Solid {
            parts,
            pos,
            yaw,
            speed,
            accel,
            tag,
        });
        len
    }

    /// Trees or buildings along both sides of the road, avoiding `[gap_from, gap_to]`.
    fn roadside(
        &mut self,
        path: &Path,
        road: &Road,
        s0: f64,
        s1: f64,
        urban: bool,
        gaps: &[(f64, f64)],
    ) {
        for side in [-1.0, 1.0] {
            let edge = if side < 0.0 {
                road.d_min()
            } else {
                road.d_max()
            } + side * road.walk;
            let mut s = s0 + self.draw.range(0.0, 10.0);
            while s < s1 {
                let free = gaps.iter().all(|&(a, b)| s < a || s > b);
                if free {
                    if urban && self.draw.chance(0.7) {
                        let len = self.draw.range(10.0, 22.0);
                        let depth = self.draw.range(8.0, 14.0);
                        let off = edge + side * (self.draw.range(1.5, 4.0) + depth / 2.0);
                        if gaps
                            .iter()
                            .all(|&(a, b)| s + len / 2.0 + 2.0 < a || s - len / 2.0 - 2.0 > b)
                        {
                            let (pos, h) = on_path(path, s, off);
                            let parts = objects::building(&mut self.draw, len, depth);
                            self.add(objects::at_rest(parts, pos, h, None));
                        }
                        s += len + self.draw.range(2.0, 8.0);
                        continue;
                    }
                    let off = edge + side * self.draw.range(1.5, 5.0);
                    let (pos, h) = on_path(path, s, off);
                    let parts = objects::tree(&mut self.draw);
                    self.add(objects::at_rest(parts, pos, h, None));
                }
                s += self.draw.range(7.0, 18.0);
            }
        }
    }

    /// Some pedestrians standing or walking on the sidewalks.
    fn walkers(&mut self, path: &Path, road: &Road, s0: f64, s1: f64, n: usize) {
        if road.walk <= 0.0 {
            return;
        }
        for _ in 0..n {
            let side = if self.draw.chance(0.5) { -1.0 } else { 1.0 };
            let edge = if side < 0.0 {
                road.d_min()
            } else {
                road.d_max()
            };
            let s = self.draw.range(s0, s1);
            let off = edge + side * self.draw.range(0.8, road.walk - 0.4);
            let (pos, h) = on_path(path, s, off);
            let parts = objects::pedestrian(&mut self.draw);
            let dir = if self.draw.chance(0.5) { 0.0 } else { PI };
            let speed = if self.draw.chance(0.6) {
                self.draw.range(0.9, 1.5)
            } else {
                0.0
            };
            let tag = Some((ObjectClass::Pedestrian, self.track()));
            self.add(Solid {
                parts,
                pos,
                yaw: h + dir,
                speed,
                accel: 0.0,
                tag,
            });
        }
    }
}

/// Length (x extent) of a solid's parts.
fn length_of(parts: &[crate::scene::Part]) -> f64 {
    let mut lo = 0.0f64;
    let mut hi = 0.0f64;
    for p in parts {
        if let crate::scene::Part::Cuboid { centre, half, .. } = p {
            lo = lo.min(centre[0] - half[0]);
            hi = hi.max(centre[0] + half[0]);
        }
    }
    hi - lo
}

fn look(draw: &mut Draw, facts: &mut Map<String, Value>) -> Look {
    let tod = {
        let u = draw.unit();
        if u < 0.55 {
            "day"
        } else if u < 0.8 {
            "overcast"
        } else {
            "dusk"
        }
    };
    facts.insert("time_of_day".into(), json!(tod));
    let a = draw.range(-8.0, 8.0) as f32;
    let asphalt = [90.0 + a, 90.0 + a, 95.0 + a];
    let terrain = draw.pick(&[
        [78.0, 118.0, 54.0],
        [96.0, 120.0, 60.0],
        [120.0, 112.0, 84.0],
    ]);
    let n = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    match tod {
        "day" => Look {
            light: 1.0,
            sky_horizon: [206.0, 218.0, 232.0],
            sky_zenith: [92.0, 148.0, 214.0],
            asphalt,
            walk: [172.0, 170.0, 164.0],
            terrain,
            sun: n([draw.range(-0.6, 0.6), draw.range(-0.6, 0.6), 0.8]),
        },
        "overcast" => Look {
            light: 0.82,
            sky_horizon: [192.0, 194.0, 198.0],
            sky_zenith: [150.0, 155.0, 166.0],
            asphalt,
            walk: [172.0, 170.0, 164.0],
            terrain,
            sun: [0.0, 0.0, 1.0],
        },
        _ => Look {
            light: 0.6,
            sky_horizon: [232.0, 164.0, 116.0],
            sky_zenith: [72.0, 82.0, 128.0],
            asphalt,
            walk: [172.0, 170.0, 164.0],
            terrain,
            sun: n([-0.7, draw.range(-0.5, 0.5), 0.3]),
        },
    }
}

/// Builds a scene of `scenario` from `seed`.
pub fn build(scenario: &str, seed: u64) -> Built {
    let mut ctx = Ctx {
        draw: Draw::new(seed, &[0x5CE4E]),
        solids: Vec::new(),
        next_track: 0,
        facts: Map::new(),
    };
    let look = look(&mut ctx.draw, &mut ctx.facts);
    let (strips, kappa, v0, decision, truth) = match scenario {
        "LANE_KEEPING" => lane_keeping(&mut ctx, false),
        "NUDGE_RIGHT" => nudge_right(&mut ctx),
        "FOLLOW_VEHICLE" => follow_vehicle(&mut ctx),
        "PASSING" => passing(&mut ctx),
        "TURN_RIGHT" => turn_right(&mut ctx),
        "STOP_SIGNAL" => junction(&mut ctx, JunctionKind::Stop),
        "INTERSECTION" => junction(&mut ctx, JunctionKind::Signal),
        _ => lane_keeping(&mut ctx, true),
    };
    ctx.fact("ego_speed_mps", json!(round3(v0)));
    ctx.fact("curvature", json!(round3(kappa * 1000.0) / 1000.0));
    Built {
        scene: Scene {
            strips,
            solids: ctx.solids,
            look,
            ego: EgoMotion { speed: v0, kappa },
            texture_seed: fogline_stats::seed::child(seed, &[0x7E47]),
        },
        decision,
        truth,
        facts: ctx.facts,
    }
}

fn round3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

type Layout = (Vec<Strip>, f64, f64, Decision, Trajectory);

fn lane_width(ctx: &mut Ctx) -> f64 {
    let w = ctx.draw.range(3.3, 3.7);
    ctx.fact("lane_width_m", json!(round3(w)));
    w
}

/// LANE_KEEPING (straight or gentle curve, traffic in other lanes) and OTHER (sharp curves,
/// a merging ramp, empty rural roads).
fn lane_keeping(ctx: &mut Ctx, other: bool) -> Layout {
    let w = lane_width(ctx);
    let variant = if other {
        ctx.draw.pick(&["curve", "curve", "merge", "rural"])
    } else {
        "lane"
    };
    ctx.fact("variant", json!(variant));
    let d = &mut ctx.draw;
    let kappa = match variant {
        "curve" => {
            let k = d.range(1.0 / 150.0, 1.0 / 70.0);
            if d.chance(0.5) { k } else { -k }
        }
        "lane" if d.chance(0.45) => {
            let k = d.range(1.0 / 500.0, 1.0 / 220.0);
            if d.chance(0.5) { k } else { -k }
        }
        "rural" => d.range(-1.0 / 400.0, 1.0 / 400.0),
        _ => 0.0,
    };
    let v0 = match variant {
        "curve" => d.range(7.0, 11.0),
        _ => d.range(9.0, 15.0),
    };
    let urban = variant == "lane" && d.chance(0.5);
    let road = Road {
        w,
        left: if variant == "rural" { 0 } else { 1 },
        oncoming: if variant == "rural" || d.chance(0.7) {
            1
        } else {
            0
        },
        shoulder: d.range(0.3, 0.8),
        walk: if urban { 3.0 } else { 0.0 },
    };
    let path = Path::arc(kappa);
    let (s0, s1) = arc_range(kappa);
    let mut strips = Vec::new();
    if variant == "merge" {
        // A ramp joining from the right at a shallow angle.
        let join = ctx.draw.range(40.0, 80.0);
        let ang = ctx.draw.range(0.06, 0.1);
        let dir = [ang.cos(), ang.sin()];
        let origin = [join, -w];
        strips.push(Strip {
            centre: Centre::Line { origin, dir },
            s_min: -160.0,
            s_max: 0.0,
            d_min: -w / 2.0 - road.shoulder,
            d_max: w / 2.0,
            walk: 0.0,
            marks: vec![Mark {
                d: -w / 2.0,
                width: 0.15,
                dash: None,
                color: WHITE,
                s_min: f64::NEG_INFINITY,
                s_max: f64::INFINITY,
            }],
            bars: Vec::new(),
        });
        ctx.fact("merge_at_m", json!(round3(join)));
        if ctx.draw.chance(0.6) {
            let sp = ctx.draw.range(8.0, 13.0);
            let along = ctx.draw.range(-60.0, -20.0);
            let parts = objects::vehicle(&mut ctx.draw, false, false);
            let tag = Some((ObjectClass::Car, ctx.track()));
            ctx.add(Solid {
                parts,
                pos: [origin[0] + along * dir[0], origin[1] + along * dir[1]],
                yaw: ang,
                speed: sp,
                accel: 0.0,
                tag,
            });
        }
    }
    strips.push(road.strip(ego_centre(kappa), s0, s1));
    // Traffic in the other lanes, never in the ego lane ahead.
    if road.left > 0 && variant != "rural" {
        let n = ctx.draw.index(3);
        for _ in 0..n {
            let s = ctx.draw.range(-15.0, 80.0);
            let sp = v0 + ctx.draw.range(-1.0, 2.5);
            let truck = ctx.draw.chance(0.15);
            ctx.vehicle_on(&path, s, road.lane(1), 1.0, sp, 0.0, truck, false);
        }
    }
    if road.oncoming > 0 && variant != "rural" {
        let n = ctx.draw.index(4);
        let lane = road.lane(road.left + 1);
        for _ in 0..n {
            let s = ctx.draw.range(15.0, 160.0);
            let sp = ctx.draw.range(8.0, 14.0);
            let truck = ctx.draw.chance(0.15);
            ctx.vehicle_on(&path, s, lane, -1.0, sp, 0.0, truck, false);
        }
    }
    ctx.roadside(&path, &road, s0.max(-40.0), s1.min(220.0), urban, &[]);
    ctx.walkers(&path, &road, 0.0, 80.0, 3);
    let truth = rollout(&path, &Lateral::none(), &cruise(v0));
    (strips, kappa, v0, Decision::KeepLane, truth)
}

fn follow_vehicle(ctx: &mut Ctx) -> Layout {
    let w = lane_width(ctx);
    let d = &mut ctx.draw;
    let kappa = if d.chance(0.7) {
        0.0
    } else {
        let k = d.range(1.0 / 500.0, 1.0 / 260.0);
        if d.chance(0.5) { k } else { -k }
    };
    let v0 = d.range(8.0, 14.0);
    let braking = d.chance(0.4);
    let idm = Idm::urban(v0);
    let (gap, lead_speed, accel) = if braking {
        (
            idm.steady_gap(v0) * d.range(0.95, 1.3),
            v0 + d.range(-0.5, 0.5),
            -d.range(2.0, 3.2),
        )
    } else {
        (
            idm.steady_gap(v0) * d.range(0.9, 1.4),
            v0 + d.range(-0.6, 0.6),
            0.0,
        )
    };
    let urban = d.chance(0.5);
    let road = Road {
        w,
        left: 1,
        oncoming: usize::from(d.chance(0.6)),
        shoulder: d.range(0.3, 0.8),
        walk: if urban { 3.0 } else { 0.0 },
    };
    let path = Path::arc(kappa);
    let (s0, s1) = arc_range(kappa);
    let truck = ctx.draw.chance(0.2);
    ctx.lead_on(&path, gap, lead_speed, accel, truck, braking);
    ctx.fact("lead_gap_m", json!(round3(gap)));
    ctx.fact("lead_speed_mps", json!(round3(lead_speed)));
    ctx.fact("lead_accel_mps2", json!(round3(accel)));
    if ctx.draw.chance(0.5) {
        let s = ctx.draw.range(-10.0, 50.0);
        let sp = v0 + ctx.draw.range(-1.0, 1.0);
        ctx.vehicle_on(&path, s, road.lane(1), 1.0, sp, 0.0, false, false);
    }
    if road.oncoming > 0 {
        let n = ctx.draw.index(3);
        for _ in 0..n {
            let s = ctx.draw.range(15.0, 150.0);
            let sp = ctx.draw.range(8.0, 14.0);
            ctx.vehicle_on(&path, s, road.lane(2), -1.0, sp, 0.0, false, false);
        }
    }
    ctx.roadside(&path, &road, s0.max(-40.0), s1.min(220.0), urban, &[]);
    ctx.walkers(&path, &road, 0.0, 80.0, 2);
    let dist = follow(
        v0,
        Lead {
            gap_m: gap,
            speed_mps: lead_speed,
            accel_mps2: accel,
        },
        &idm,
    );
    let truth = rollout(&path, &Lateral::none(), &dist);
    let decision = if braking {
        Decision::SlowForLead
    } else {
        Decision::FollowLead
    };
    (
        vec![road.strip(ego_centre(kappa), s0, s1)],
        kappa,
        v0,
        decision,
        truth,
    )
}

fn passing(ctx: &mut Ctx) -> Layout {
    let w = lane_width(ctx);
    let d = &mut ctx.draw;
    let v0 = d.range(11.0, 15.0);
    let lead_speed = v0 * d.range(0.3, 0.5);
    let gap = d.range(24.0, 40.0);
    let urban = d.chance(0.3);
    let road = Road {
        w,
        left: 1,
        oncoming: usize::from(d.chance(0.6)),
        shoulder: d.range(0.3, 0.8),
        walk: if urban { 3.0 } else { 0.0 },
    };
    let path = Path::straight();
    let truck = ctx.draw.chance(0.35);
    ctx.lead_on(&path, gap, lead_speed, 0.0, truck, false);
    ctx.fact("lead_gap_m", json!(round3(gap)));
    ctx.fact("lead_speed_mps", json!(round3(lead_speed)));
    if road.oncoming > 0 {
        let n = ctx.draw.index(3);
        for _ in 0..n {
            let s = ctx.draw.range(40.0, 160.0);
            let sp = ctx.draw.range(8.0, 14.0);
            ctx.vehicle_on(&path, s, road.lane(2), -1.0, sp, 0.0, false, false);
        }
    }
    ctx.roadside(&path, &road, -40.0, 220.0, urban, &[]);
    let start = 2.0;
    let lateral = Lateral {
        ramps: vec![(start, start + v0 * 3.0, w)],
    };
    let truth = rollout(&path, &lateral, &cruise(v0));
    (
        vec![road.strip(ego_centre(0.0), -250.0, 400.0)],
        0.0,
        v0,
        Decision::PassLeft,
        truth,
    )
}

fn nudge_right(ctx: &mut Ctx) -> Layout {
    let w = lane_width(ctx);
    let d = &mut ctx.draw;
    let v0 = d.range(7.0, 11.0);
    let intrusion = d.range(0.7, 1.2);
    let rear = d.range(20.0, 36.0);
    let urban = d.chance(0.5);
    let road = Road {
        w,
        left: 1,
        oncoming: usize::from(d.chance(0.5)),
        shoulder: d.range(0.4, 0.9),
        walk: if urban { 3.0 } else { 0.0 },
    };
    let path = Path::straight();
    // A stopped van in the left lane, its right side `intrusion` m into the ego lane.
    let parts = objects::vehicle(&mut ctx.draw, true, false);
    let (len, half_w) = (length_of(&parts), 1.1);
    let right_edge = w / 2.0 - intrusion;
    let tag = Some((ObjectClass::Truck, ctx.track()));
    ctx.add(objects::at_rest(
        parts,
        [rear + len / 2.0, right_edge + half_w],
        0.0,
        tag,
    ));
    // Cones behind it.
    for k in 1..=2 {
        let tag = Some((ObjectClass::Barrier, ctx.track()));
        ctx.add(objects::at_rest(
            objects::cone(),
            [rear - 2.5 * k as f64, right_edge + 0.3 + 0.25 * k as f64],
            0.0,
            tag,
        ));
    }
    ctx.fact("obstacle_rear_m", json!(round3(rear)));
    ctx.fact("intrusion_m", json!(round3(intrusion)));
    ctx.roadside(&path, &road, -40.0, 220.0, urban, &[]);
    ctx.walkers(&path, &road, 0.0, 80.0, 2);
    let offset = nudge_offset(w, right_edge);
    let cone_rear = rear - 5.0 - 0.2;
    let front = rear + len;
    let lateral = Lateral {
        ramps: vec![
            (cone_rear - 16.0, cone_rear - 3.0, offset),
            (front + 3.0, front + 16.0, -offset),
        ],
    };
    let truth = rollout(&path, &lateral, &cruise(v0));
    (
        vec![road.strip(ego_centre(0.0), -250.0, 400.0)],
        0.0,
        v0,
        Decision::NudgeRight,
        truth,
    )
}

/// The lateral shift (negative = right) that keeps 0.5 m between the ego's left side and an
/// obstacle edge at lateral position `edge` (the ego lane's centre is 0), never leaving the
/// lane by more than 0.3 m.
pub fn nudge_offset(w: f64, edge: f64) -> f64 {
    let want = edge - 0.5 - EGO_WIDTH_M / 2.0;
    want.clamp(-(w / 2.0 - EGO_WIDTH_M / 2.0 + 0.3), 0.0)
}

fn turn_right(ctx: &mut Ctx) -> Layout {
    let w = lane_width(ctx);
    let d = &mut ctx.draw;
    let v0 = d.range(7.0, 10.0);
    let radius = d.range(7.5, 9.5);
    let x_c = d.range(14.0, 34.0);
    let sh = d.range(0.3, 0.6);
    let urban = d.chance(0.6);
    let road = Road {
        w,
        left: 0,
        oncoming: 1,
        shoulder: sh,
        walk: if urban { 3.0 } else { 0.0 },
    };
    // The exit road runs along -y; its right lane (ours after the turn) is centred at
    // x_c + radius, so the road's centre is half a lane further on.
    let x_j = x_c + radius + w / 2.0;
    let half_c = w + sh;
    let exit = Road {
        w,
        left: 0,
        oncoming: 1,
        shoulder: sh,
        walk: road.walk,
    };
    let mut exit_strip = exit.strip(
        Centre::Line {
            origin: [x_j - w / 2.0, 0.0],
            dir: [0.0, -1.0],
        },
        -road.d_max(),
        300.0,
    );
    for m in &mut exit_strip.marks {
        m.s_min = -road.d_min();
    }
    let fillet = Strip {
        centre: Centre::Arc {
            centre: [x_c, -radius],
            radius,
            left: false,
            start: FRAC_PI_2,
        },
        s_min: 0.0,
        s_max: radius * FRAC_PI_2,
        d_min: -w / 2.0 - sh,
        d_max: w / 2.0,
        walk: 0.0,
        marks: Vec::new(),
        bars: Vec::new(),
    };
    let ego_road = road.strip(ego_centre(0.0), -250.0, x_j - half_c);
    let path = Path::straight();
    ctx.roadside(
        &path,
        &road,
        -40.0,
        x_j - half_c - road.walk - 4.0,
        urban,
        &[],
    );
    // Across the top of the T: buildings or trees facing the driver.
    let far = x_j + half_c + road.walk + 3.0;
    let mut y = -40.0;
    while y < 40.0 {
        let parts = if urban {
            objects::building(&mut ctx.draw, 14.0, 10.0)
        } else {
            objects::tree(&mut ctx.draw)
        };
        let dx = if urban { 5.0 } else { ctx.draw.range(0.0, 4.0) };
        ctx.add(objects::at_rest(parts, [far + dx, y], FRAC_PI_2, None));
        y += if urban {
            15.0
        } else {
            ctx.draw.range(5.0, 9.0)
        };
    }
    // Along the exit road, on its far side.
    for k in 0..6 {
        let yy = -(road.d_max() + 10.0 + 14.0 * k as f64);
        let parts = objects::tree(&mut ctx.draw);
        ctx.add(objects::at_rest(
            parts,
            [x_j + half_c + road.walk + 3.0, yy],
            0.0,
            None,
        ));
        let parts = objects::tree(&mut ctx.draw);
        ctx.add(objects::at_rest(
            parts,
            [x_j - half_c - road.walk - 3.0, yy - 6.0],
            0.0,
            None,
        ));
    }
    // Perhaps a car coming up the exit road in its other lane.
    if ctx.draw.chance(0.5) {
        let parts = objects::vehicle(&mut ctx.draw, false, false);
        let tag = Some((ObjectClass::Car, ctx.track()));
        let sp = ctx.draw.range(6.0, 10.0);
        let yy = -ctx.draw.range(25.0, 70.0);
        ctx.add(Solid {
            parts,
            pos: [x_j + w / 2.0, yy],
            yaw: FRAC_PI_2,
            speed: sp,
            accel: 0.0,
            tag,
        });
    }
    ctx.fact("turn_start_m", json!(round3(x_c)));
    ctx.fact("turn_radius_m", json!(round3(radius)));
    let turn = Path::right_turn(x_c, radius);
    let dist = slow_for_turn(v0, TURN_SPEED, 2.0, x_c, radius * FRAC_PI_2, 1.0, 8.0);
    let truth = rollout(&turn, &Lateral::none(), &dist);
    (
        vec![fillet, ego_road, exit_strip],
        0.0,
        v0,
        Decision::TurnRight,
        truth,
    )
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum JunctionKind {
    /// A stop sign or a red light.
    Stop,
    /// A green light, perhaps someone on the crossing.
    Signal,
}

fn junction(ctx: &mut Ctx, kind: JunctionKind) -> Layout {
    let w = lane_width(ctx);
    let d = &mut ctx.draw;
    let v0 = d.range(8.0, 13.0);
    let sh = d.range(0.3, 0.6);
    let road = Road {
        w,
        left: usize::from(d.chance(0.4)),
        oncoming: 1,
        shoulder: sh,
        walk: 3.0,
    };
    let cross = Road {
        w,
        left: 0,
        oncoming: 1,
        shoulder: sh,
        walk: 3.0,
    };
    let half_c = w + sh;
    // Distances from the junction's near edge: zebra [−3.5, −0.5], stop line at −4.5.
    let sign = kind == JunctionKind::Stop && d.chance(0.5);
    let crossing_agent = kind == JunctionKind::Signal && d.chance(0.35);
    let (x_line, x_stop) = match kind {
        JunctionKind::Stop => {
            let a = d.range(1.2, 3.2);
            let x_stop = v0 * v0 / (2.0 * a);
            (x_stop + EGO_FRONT_M + 0.5, x_stop)
        }
        JunctionKind::Signal if crossing_agent => {
            let a = d.range(1.3, 3.0);
            let x_stop = v0 * v0 / (2.0 * a);
            // Stop 1 m before the zebra.
            (x_stop + EGO_FRONT_M + 1.0 - 1.0, x_stop)
        }
        JunctionKind::Signal => {
            let x_line = d.range(18.0, 55.0);
            (x_line, f64::NAN)
        }
    };
    let near_edge = x_line + 4.5;
    let x_j = near_edge + half_c;
    let far_edge = x_j + half_c;
    let mut before = road.strip(ego_centre(0.0), -250.0, near_edge);
    before.bars.push(Bar {
        s_min: near_edge - 3.5,
        s_max: near_edge - 0.5,
        d_min: road.d_min() + sh,
        d_max: road.d_max() - sh,
        stripes: Some((0.5, 1.0)),
    });
    before.bars.push(Bar {
        s_min: x_line - 0.25,
        s_max: x_line + 0.25,
        d_min: -w / 2.0,
        d_max: w / 2.0 + road.left as f64 * w,
        stripes: None,
    });
    let after = road.strip(ego_centre(0.0), far_edge, 400.0);
    let boxs = Strip {
        centre: Centre::Line {
            origin: [near_edge, 0.0],
            dir: [1.0, 0.0],
        },
        s_min: 0.0,
        s_max: 2.0 * half_c,
        d_min: road.d_min(),
        d_max: road.d_max(),
        walk: 0.0,
        marks: Vec::new(),
        bars: Vec::new(),
    };
    // The crossing road, travelling +y, its centre line through x_j: left of +y is −x.
    let mut cross_left = cross.strip(
        Centre::Line {
            origin: [x_j + w / 2.0, 0.0],
            dir: [0.0, 1.0],
        },
        road.d_max(),
        300.0,
    );
    let mut cross_right = cross.strip(
        Centre::Line {
            origin: [x_j + w / 2.0, 0.0],
            dir: [0.0, 1.0],
        },
        -300.0,
        road.d_min(),
    );
    cross_left.bars.clear();
    cross_right.bars.clear();
    let path = Path::straight();
    ctx.roadside(
        &path,
        &road,
        -40.0,
        220.0,
        true,
        &[(near_edge - road.walk - 6.0, far_edge + road.walk + 6.0)],
    );
    ctx.walkers(&path, &road, 0.0, near_edge - 6.0, 3);
    // Cross-road buildings.
    for side in [-1.0, 1.0] {
        for k in 0..3 {
            let yy = side * (road.d_max().max(-road.d_min()) + road.walk + 12.0 + 20.0 * k as f64);
            for xs in [near_edge - road.walk - 9.0, far_edge + road.walk + 9.0] {
                let parts = objects::building(&mut ctx.draw, 14.0, 12.0);
                ctx.add(objects::at_rest(parts, [xs, yy], FRAC_PI_2, None));
            }
        }
    }
    let decision;
    let truth;
    let light_for_ego = match kind {
        JunctionKind::Stop if sign => None,
        JunctionKind::Stop => Some(LightState::Red),
        JunctionKind::Signal => Some(LightState::Green),
    };
    if sign {
        let tag = Some((ObjectClass::StopSign, ctx.track()));
        ctx.add(objects::at_rest(
            objects::stop_sign(),
            [x_line + 0.4, road.d_min() - 0.9],
            0.0,
            tag,
        ));
        ctx.fact("control", json!("stop_sign"));
    }
    if let Some(state) = light_for_ego {
        let arm = -road.d_min() + 1.0;
        let tag = Some((ObjectClass::TrafficLight, ctx.track()));
        ctx.add(objects::at_rest(
            objects::traffic_light(state, arm),
            [far_edge + 1.2, road.d_min() - 1.0],
            0.0,
            tag,
        ));
        ctx.fact("control", json!("traffic_light"));
        ctx.fact("light", json!(state.name()));
    }
    ctx.fact("stop_line_m", json!(round3(x_line)));
    ctx.fact("junction_m", json!(round3(x_j)));
    // Cross traffic: moving through on its green when ours is red or a stop sign; waiting at
    // its stop line when ours is green.
    let cross_moving = kind == JunctionKind::Stop;
    let n = 1 + ctx.draw.index(3);
    for k in 0..n {
        let dir = if k % 2 == 0 { 1.0 } else { -1.0 };
        let lane_x = x_j + dir * (w / 2.0);
        let (yy, sp) = if cross_moving {
            (ctx.draw.range(-50.0, 50.0), ctx.draw.range(7.0, 12.0))
        } else {
            let wait =
                road.d_max().max(-road.d_min()) + road.walk + 2.0 + 3.0 + 7.0 * (k / 2) as f64;
            (-dir * wait, 0.0)
        };
        let parts = objects::vehicle(&mut ctx.draw, false, !cross_moving);
        let tag = Some((ObjectClass::Car, ctx.track()));
        ctx.add(Solid {
            parts,
            pos: [lane_x, yy],
            yaw: if dir > 0.0 { FRAC_PI_2 } else { -FRAC_PI_2 },
            speed: sp,
            accel: 0.0,
            tag,
        });
    }
    match kind {
        JunctionKind::Stop => {
            decision = if sign {
                Decision::StopForSign
            } else {
                Decision::StopForRedLight
            };
            truth = rollout(&path, &Lateral::none(), &stop_within(v0, x_stop));
        }
        JunctionKind::Signal if crossing_agent => {
            let cyc = ctx.draw.chance(0.3);
            let dir = if ctx.draw.chance(0.5) { 1.0 } else { -1.0 };
            let y0 = ctx.draw.range(-1.3, 1.3);
            let sp = if cyc {
                ctx.draw.range(1.5, 2.5)
            } else {
                ctx.draw.range(0.8, 1.3)
            };
            let parts = if cyc {
                objects::cyclist(&mut ctx.draw)
            } else {
                objects::pedestrian(&mut ctx.draw)
            };
            let class = if cyc {
                ObjectClass::Cyclist
            } else {
                ObjectClass::Pedestrian
            };
            let tag = Some((class, ctx.track()));
            ctx.add(Solid {
                parts,
                pos: [near_edge - 2.0, y0],
                yaw: dir * FRAC_PI_2,
                speed: sp,
                accel: 0.0,
                tag,
            });
            ctx.fact("crossing", json!(class.label()));
            decision = Decision::YieldToCrossing;
            truth = rollout(&path, &Lateral::none(), &stop_within(v0, x_stop));
        }
        JunctionKind::Signal => {
            decision = Decision::ProceedOnGreen;
            truth = rollout(&path, &Lateral::none(), &cruise(v0));
        }
    }
    (
        vec![boxs, before, after, cross_left, cross_right],
        0.0,
        v0,
        decision,
        truth,
    )
}
