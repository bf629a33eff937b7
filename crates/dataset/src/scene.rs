//! A sample's scene as a plan (plain data a test can write by hand), the seeded drawing of
//! plans, the world scene a plan renders to, and the privileged expert that labels it.
//!
//! Frame of reference: the ego's rig frame at the last frame (`t = 0`): `x` ahead, `y` left,
//! metres; the ego drives along `y = 0` at a constant speed over the five seconds before.
//! Every road user moves at a constant velocity.

use std::f64::consts::{FRAC_PI_2, PI};

use fogline_rco::Strategy;
use fogline_rco::deficit_eval::{HiddenClass, MotionLabel};
use fogline_sim::sense::{Daylight, Weather, detector_parts, look};
use fogline_stats::seed::child;
use fogline_types::motion::{EGO_FRONT_M, EGO_WIDTH_M};
use fogline_world::objects::{self, LightState};
use fogline_world::scene::{Bar, Centre, Draw, EgoMotion, Mark, ObjectClass, Scene, Solid, Strip};
use serde::{Deserialize, Serialize};

/// The track id of the hidden object.
pub const TARGET_TRACK: u64 = 1;
/// The expert's look-ahead, s.
pub const HORIZON_S: f64 = 3.0;
/// The expert's comfortable deceleration, m/s².
pub const COMFORT_DECEL_MPS2: f64 = 2.5;
/// Half the width the expert keeps clear around the ego's path, m.
pub const CORRIDOR_HALF_M: f64 = EGO_WIDTH_M / 2.0 + 0.7;
/// Shoulder beyond the edge lines, m.
const SHOULDER_M: f64 = 0.5;
/// Sidewalk width, m.
const WALK_M: f64 = 3.0;
const WHITE: [f32; 3] = [232.0, 232.0, 226.0];
const YELLOW: [f32; 3] = [226.0, 186.0, 40.0];

/// A traffic light's colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LightColor {
    /// Red.
    Red,
    /// Amber.
    Amber,
    /// Green.
    Green,
}

impl LightColor {
    fn state(self) -> LightState {
        match self {
            LightColor::Red => LightState::Red,
            LightColor::Amber => LightState::Amber,
            LightColor::Green => LightState::Green,
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        self.state().name()
    }
}

/// What a group of samples shares (the "town"): road cross-section, weather, daylight,
/// roadside. Splits are drawn by town, so no road, palette or roadside is in two splits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Town {
    /// The town's seed (roadside and texture).
    pub seed: u64,
    /// Lane width, m.
    pub lane_width_m: f64,
    /// Lanes in the ego's direction left of the ego lane (0 or 1).
    pub left_lanes: u8,
    /// Buildings (urban) or trees along the road.
    pub urban: bool,
    /// The closed loop's weather.
    pub weather: Weather,
    /// The closed loop's daylight.
    pub daylight: Daylight,
}

impl Town {
    /// Draws a town from its seed.
    pub fn draw(seed: u64) -> Self {
        let mut d = Draw::new(seed, &[0x70A7]);
        Self {
            seed,
            lane_width_m: d.range(3.3, 3.7),
            left_lanes: u8::from(d.chance(0.3)),
            urban: d.chance(0.6),
            weather: d.pick(&Weather::ALL),
            daylight: d.pick(&Daylight::ALL),
        }
    }

    /// Right edge of the asphalt, m (negative).
    pub fn right_edge_m(&self) -> f64 {
        -self.lane_width_m / 2.0 - SHOULDER_M
    }

    /// Centre of the oncoming lane, m.
    pub fn oncoming_lane_m(&self) -> f64 {
        (f64::from(self.left_lanes) + 1.0) * self.lane_width_m
    }

    /// Left edge of the asphalt, m.
    pub fn left_edge_m(&self) -> f64 {
        self.oncoming_lane_m() + self.lane_width_m / 2.0 + SHOULDER_M
    }
}

/// The hidden object at `t = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Target {
    /// Its class.
    pub class: HiddenClass,
    /// Position ahead, m (for a light or a sign: its pole).
    pub x_m: f64,
    /// Position left, m.
    pub y_m: f64,
    /// Heading, rad (0: the ego's direction).
    pub heading_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// A traffic light's colour.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light: Option<LightColor>,
}

impl Target {
    /// Position at time `t_s` (s relative to the last frame).
    pub fn pos_at(&self, t_s: f64) -> [f64; 2] {
        let s = self.speed_mps * t_s;
        [
            self.x_m + s * self.heading_rad.cos(),
            self.y_m + s * self.heading_rad.sin(),
        ]
    }
}

/// Another road user, visible (never hidden).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Other {
    /// `car` or `pedestrian`.
    pub pedestrian: bool,
    /// Position ahead, m.
    pub x_m: f64,
    /// Position left, m.
    pub y_m: f64,
    /// Heading, rad.
    pub heading_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
}

/// Everything a sample's scene is made from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScenePlan {
    /// The town.
    pub town: Town,
    /// The seed of the clip's own parts (people's clothes, car paint).
    pub clip_seed: u64,
    /// The ego's speed, m/s.
    pub ego_speed_mps: f64,
    /// The stop line of a junction ahead, m (lights and signs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_line_m: Option<f64>,
    /// The hidden object.
    pub target: Target,
    /// The other road users.
    #[serde(default)]
    pub others: Vec<Other>,
}

/// A label's short rationale sentences.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Rationale {
    /// Why this object.
    pub object: String,
    /// Why this motion.
    pub motion: String,
    /// Why this strategy.
    pub strategy: String,
}

/// A sample's labels, from ground truth.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Labels {
    /// The hidden class.
    pub class: HiddenClass,
    /// Its motion.
    pub motion: MotionLabel,
    /// The expert's strategy.
    pub strategy: Strategy,
    /// One sentence each.
    pub rationale: Rationale,
}

/// The motion of a target: static below 0.2 m/s; crossing when it moves more across the
/// road than along it; else oncoming (towards the ego) or leading (the ego's way).
pub fn motion_of(t: &Target) -> MotionLabel {
    if t.speed_mps < 0.2
        || matches!(
            t.class,
            HiddenClass::TrafficLight | HiddenClass::TrafficSign
        )
    {
        MotionLabel::Static
    } else if t.heading_rad.sin().abs() > t.heading_rad.cos().abs() {
        MotionLabel::Crossing
    } else if t.heading_rad.cos() < 0.0 {
        MotionLabel::Oncoming
    } else {
        MotionLabel::Leading
    }
}

/// The words a rationale and an answer use for a motion.
pub fn motion_phrase(m: MotionLabel) -> &'static str {
    match m {
        MotionLabel::Crossing => "crossing the road",
        MotionLabel::Oncoming => "oncoming, moving towards the ego vehicle",
        MotionLabel::Leading => "leading, moving ahead in the same direction",
        MotionLabel::Static => "static",
    }
}

fn side(town: &Town, y_m: f64) -> &'static str {
    let w = town.lane_width_m;
    if y_m < -w / 2.0 {
        "on the right"
    } else if y_m <= w / 2.0 {
        "in the ego lane"
    } else if y_m < town.left_edge_m() {
        "on the left of the road"
    } else {
        "on the left"
    }
}

/// Whether the privileged expert brakes because of a road user within [`HORIZON_S`]:
/// ego and object each continue at constant velocity; it brakes when, at some instant of
/// the horizon (every 0.1 s), the object is inside the ego's corridor (|y| ≤
/// [`CORRIDOR_HALF_M`]) between 1 m behind the ego's front and a gap of `3 m + 1 s × v`
/// ahead of it.
pub fn road_user_brakes(plan: &ScenePlan) -> Option<f64> {
    let v = plan.ego_speed_mps;
    let gap = 3.0 + v;
    (0..=(HORIZON_S * 10.0).round() as usize).find_map(|k| {
        let tau = k as f64 * 0.1;
        let front = v * tau + EGO_FRONT_M;
        let p = plan.target.pos_at(tau);
        let ahead = p[0] - front;
        (p[1].abs() <= CORRIDOR_HALF_M && (-1.0..=gap).contains(&ahead)).then_some(tau)
    })
}

/// The distance within which the expert starts braking for a stop line: what it covers in
/// [`HORIZON_S`] plus its comfortable stopping distance, plus 2 m.
fn reach_m(v: f64) -> f64 {
    v * HORIZON_S + v * v / (2.0 * COMFORT_DECEL_MPS2) + 2.0
}

/// Labels a plan from its ground truth (the privileged expert; see `docs/dataset.md`):
///
/// - pedestrian, bicycle: `stop-observe-move` when [`road_user_brakes`], else `move`;
/// - traffic light: `stop-observe-move` when red (or amber and the line can be reached with
///   at most 3.5 m/s²) and the stop line is no further than the expert's reach
///   (`v·3 s + v²/(2·2.5 m/s²) + 2 m`) and not behind the front; green → `move`;
/// - stop sign: `stop-observe-move` when the line is within reach, unless the ego is
///   already standing (below 0.3 m/s) at it: it has stopped and may go → `move`.
pub fn label(plan: &ScenePlan) -> Labels {
    let t = &plan.target;
    let class = t.class;
    let motion = motion_of(t);
    let v = plan.ego_speed_mps;
    let where_ = format!(
        "{} about {:.0} m ahead",
        side(&plan.town, t.y_m),
        (t.x_m - EGO_FRONT_M).max(0.0)
    );
    let phrase = class.phrase();
    let object = match class {
        HiddenClass::TrafficLight => format!(
            "The masked region hangs over the road at a junction {where_}, where a traffic light's head would be."
        ),
        HiddenClass::TrafficSign => format!(
            "The masked region sits on a pole at the roadside before a junction {where_}, where a traffic sign would be."
        ),
        HiddenClass::Pedestrian => {
            format!("The masked region is tall and narrow, {where_}, the shape of a pedestrian.")
        }
        HiddenClass::Bicycle => format!(
            "The masked region is about a person's height and longer than wide, {where_}, the shape of a bicycle and its rider."
        ),
    };
    let motion_text = match (class, motion) {
        (HiddenClass::TrafficLight, _) => format!(
            "It is static: a traffic light showing {}.",
            t.light.map_or("an unknown colour", LightColor::name)
        ),
        (HiddenClass::TrafficSign, _) => "It is static: a stop sign facing the ego vehicle.".into(),
        (_, MotionLabel::Static) => format!("The {phrase} is not moving."),
        (_, MotionLabel::Crossing) => format!(
            "The {phrase} is crossing the road towards the {} at {:.1} m/s.",
            if t.heading_rad.sin() > 0.0 {
                "left"
            } else {
                "right"
            },
            t.speed_mps
        ),
        (_, MotionLabel::Oncoming) => format!(
            "The {phrase} is oncoming, moving towards the ego vehicle at {:.1} m/s.",
            t.speed_mps
        ),
        (_, MotionLabel::Leading) => format!(
            "The {phrase} is leading, moving ahead in the ego's direction at {:.1} m/s.",
            t.speed_mps
        ),
    };
    let (strategy, why) = match class {
        HiddenClass::TrafficLight => {
            let line = plan.stop_line_m.unwrap_or(t.x_m) - EGO_FRONT_M;
            let color = t.light.unwrap_or(LightColor::Red);
            let stoppable = match color {
                LightColor::Red => true,
                LightColor::Amber => line > 0.0 && v * v / (2.0 * line) <= 3.5,
                LightColor::Green => false,
            };
            if stoppable && line > -0.5 && line <= reach_m(v) {
                (
                    Strategy::StopObserveMove,
                    format!(
                        "The ego vehicle should stop because the invisible region may contain a traffic light that is {}.",
                        color.name()
                    ),
                )
            } else if color == LightColor::Green {
                (
                    Strategy::Move,
                    "There is no reason for the ego vehicle to brake: the hidden traffic light is green.".into(),
                )
            } else {
                (
                    Strategy::Move,
                    "There is no reason for the ego vehicle to brake yet: the stop line is beyond the next few seconds.".into(),
                )
            }
        }
        HiddenClass::TrafficSign => {
            let line = plan.stop_line_m.unwrap_or(t.x_m) - EGO_FRONT_M;
            if v < 0.3 && line <= 6.0 {
                (
                    Strategy::Move,
                    "The ego vehicle has already stopped at the stop sign and may proceed with care.".into(),
                )
            } else if line > -0.5 && line <= reach_m(v) {
                (
                    Strategy::StopObserveMove,
                    "The ego vehicle should stop because the invisible region may contain a stop sign.".into(),
                )
            } else {
                (
                    Strategy::Move,
                    "There is no reason for the ego vehicle to brake yet: the stop line is beyond the next few seconds.".into(),
                )
            }
        }
        HiddenClass::Pedestrian | HiddenClass::Bicycle => match road_user_brakes(plan) {
            Some(tau) => (
                Strategy::StopObserveMove,
                format!(
                    "The ego vehicle should stop because the invisible region may contain a {phrase} that is {}, in the ego's path within {tau:.1} s.",
                    motion_phrase(motion)
                ),
            ),
            None => (
                Strategy::Move,
                format!(
                    "There is no reason for the ego vehicle to brake: the hidden {phrase} stays out of the ego's path for the next {HORIZON_S:.0} s."
                ),
            ),
        },
    };
    Labels {
        class,
        motion,
        strategy,
        rationale: Rationale {
            object,
            motion: motion_text,
            strategy: why,
        },
    }
}

/// Draws the plan of sample `index`, attempt `attempt` (a new attempt when the hidden
/// object is not seen often enough): the class cycles through the four in order, so every
/// run of four samples (and so every town of a multiple of four clips) is balanced; the
/// motion is drawn from the class's variants.
pub fn draw_plan(seed: u64, index: u64, clips_per_town: u64, attempt: u64) -> ScenePlan {
    let town_index = index / clips_per_town.max(1);
    let town = Town::draw(child(seed, &[0x70A7, town_index]));
    let clip_seed = child(seed, &[0xC119, index, attempt]);
    let mut d = Draw::new(clip_seed, &[1]);
    let class = HiddenClass::ALL[(index % 4) as usize];
    let w = town.lane_width_m;
    let right = town.right_edge_m();
    let left = town.left_edge_m();
    let mut ego_speed_mps = d.range(3.0, 9.0);
    let mut stop_line_m = None;
    let sidewalk = |d: &mut Draw| {
        if d.chance(0.5) {
            right - d.range(0.8, WALK_M - 0.4)
        } else {
            left + d.range(0.8, WALK_M - 0.4)
        }
    };
    let target = match class {
        HiddenClass::TrafficLight => {
            let line = d.range(8.0, 24.0);
            stop_line_m = Some(line);
            let light = if d.chance(0.45) {
                LightColor::Green
            } else if d.chance(0.25) {
                LightColor::Amber
            } else {
                LightColor::Red
            };
            if light != LightColor::Green && d.chance(0.2) {
                // Waiting at the line.
                ego_speed_mps = 0.0;
            }
            Target {
                class,
                x_m: line + 0.5,
                y_m: right - 1.0,
                heading_rad: 0.0,
                speed_mps: 0.0,
                light: Some(light),
            }
        }
        HiddenClass::TrafficSign => {
            let line = if d.chance(0.3) {
                ego_speed_mps = 0.0;
                EGO_FRONT_M + d.range(0.5, 2.5)
            } else {
                d.range(6.0, 18.0)
            };
            stop_line_m = Some(line);
            Target {
                class,
                x_m: line + 0.4,
                y_m: right - 0.9,
                heading_rad: 0.0,
                speed_mps: 0.0,
                light: None,
            }
        }
        HiddenClass::Pedestrian | HiddenClass::Bicycle => {
            let bike = class == HiddenClass::Bicycle;
            let (lo, hi) = if bike { (2.0, 5.5) } else { (0.8, 1.6) };
            let x_m = d.range(EGO_FRONT_M + 4.0, 30.0);
            match d.index(4) {
                0 => {
                    // Crossing: from anywhere between the sidewalks, either way.
                    let y_m = d.range(right - 2.5, left + 2.5);
                    let heading_rad = if d.chance(0.5) { FRAC_PI_2 } else { -FRAC_PI_2 };
                    Target {
                        class,
                        x_m,
                        y_m,
                        heading_rad,
                        speed_mps: d.range(lo, hi),
                        light: None,
                    }
                }
                1 => {
                    // Oncoming: on the far sidewalk (walkers) or in the oncoming lane.
                    let y_m = if bike {
                        town.oncoming_lane_m() + d.range(-0.4, 0.9)
                    } else {
                        sidewalk(&mut d)
                    };
                    Target {
                        class,
                        x_m: x_m + 5.0,
                        y_m,
                        heading_rad: PI,
                        speed_mps: d.range(lo, hi),
                        light: None,
                    }
                }
                2 => {
                    // Leading: a cyclist at the right of the ego lane (or in the next lane),
                    // a walker on a sidewalk or on the shoulder.
                    let y_m = if bike {
                        if town.left_lanes > 0 && d.chance(0.3) {
                            w + d.range(-0.5, 0.5)
                        } else {
                            -w / 2.0 + d.range(0.5, 1.3)
                        }
                    } else if d.chance(0.3) {
                        right + d.range(0.2, 0.6)
                    } else {
                        sidewalk(&mut d)
                    };
                    Target {
                        class,
                        x_m,
                        y_m,
                        heading_rad: 0.0,
                        speed_mps: d.range(lo, hi),
                        light: None,
                    }
                }
                _ => {
                    // Static: on a sidewalk, at the kerb, or standing in the road.
                    let y_m = match d.index(3) {
                        0 => sidewalk(&mut d),
                        1 => right + d.range(0.2, 0.8),
                        _ => d.range(-w / 2.0, w / 2.0),
                    };
                    Target {
                        class,
                        x_m,
                        y_m,
                        heading_rad: if d.chance(0.5) { FRAC_PI_2 } else { 0.0 },
                        speed_mps: 0.0,
                        light: None,
                    }
                }
            }
        }
    };
    let mut others = Vec::new();
    for _ in 0..d.index(3) {
        others.push(Other {
            pedestrian: false,
            x_m: d.range(15.0, 90.0),
            y_m: town.oncoming_lane_m(),
            heading_rad: PI,
            speed_mps: d.range(5.0, 10.0),
        });
    }
    if class != HiddenClass::Pedestrian && town.urban {
        for _ in 0..d.index(3) {
            others.push(Other {
                pedestrian: true,
                x_m: d.range(6.0, 40.0),
                y_m: sidewalk(&mut d),
                heading_rad: if d.chance(0.5) { 0.0 } else { PI },
                speed_mps: if d.chance(0.5) {
                    d.range(0.9, 1.4)
                } else {
                    0.0
                },
            });
        }
    }
    ScenePlan {
        town,
        clip_seed,
        ego_speed_mps,
        stop_line_m,
        target,
        others,
    }
}

fn marks(town: &Town) -> Vec<Mark> {
    let w = town.lane_width_m;
    let line = |d: f64, dash: Option<(f64, f64)>, color| Mark {
        d,
        width: 0.15,
        dash,
        color,
        s_min: f64::NEG_INFINITY,
        s_max: f64::INFINITY,
    };
    let mut m = vec![line(-w / 2.0, None, WHITE)];
    let mut d = w / 2.0;
    for _ in 0..town.left_lanes {
        m.push(line(d, Some((3.0, 10.0)), WHITE));
        d += w;
    }
    m.push(line(d - 0.12, None, YELLOW));
    m.push(line(d + 0.12, None, YELLOW));
    m.push(line(d + w, None, WHITE));
    m
}

fn strip(town: &Town, centre: Centre, s_min: f64, s_max: f64) -> Strip {
    Strip {
        centre,
        s_min,
        s_max,
        d_min: town.right_edge_m(),
        d_max: town.left_edge_m(),
        walk: WALK_M,
        marks: marks(town),
        bars: Vec::new(),
    }
}

const X_AXIS: Centre = Centre::Line {
    origin: [0.0, 0.0],
    dir: [1.0, 0.0],
};

/// The world scene of a plan: the road (with a junction, zebra and stop line when the plan
/// has a stop line), the town's roadside, the other road users and the target, tagged
/// [`TARGET_TRACK`] (a light's head and a sign's face only, as the closed loop tags them).
pub fn scene_of(plan: &ScenePlan) -> Scene {
    let town = &plan.town;
    let w = town.lane_width_m;
    let mut strips = Vec::new();
    let mut gap = (f64::INFINITY, f64::INFINITY);
    match plan.stop_line_m {
        Some(line) => {
            let near = line + 4.5;
            let half_c = w + SHOULDER_M;
            let far = near + 2.0 * half_c;
            let x_j = near + half_c;
            gap = (near - WALK_M - 6.0, far + WALK_M + 6.0);
            strips.push(Strip {
                centre: Centre::Line {
                    origin: [near, 0.0],
                    dir: [1.0, 0.0],
                },
                s_min: 0.0,
                s_max: 2.0 * half_c,
                d_min: town.right_edge_m(),
                d_max: town.left_edge_m(),
                walk: 0.0,
                marks: Vec::new(),
                bars: Vec::new(),
            });
            let mut before = strip(town, X_AXIS, -250.0, near);
            before.bars.push(Bar {
                s_min: near - 3.5,
                s_max: near - 0.5,
                d_min: -w / 2.0,
                d_max: town.left_edge_m() - SHOULDER_M,
                stripes: Some((0.5, 1.0)),
            });
            before.bars.push(Bar {
                s_min: line - 0.25,
                s_max: line + 0.25,
                d_min: -w / 2.0,
                d_max: w / 2.0 + f64::from(town.left_lanes) * w,
                stripes: None,
            });
            strips.push(before);
            strips.push(strip(town, X_AXIS, far, 400.0));
            let cross = Town {
                left_lanes: 0,
                ..*town
            };
            let cc = Centre::Line {
                origin: [x_j + w / 2.0, 0.0],
                dir: [0.0, 1.0],
            };
            strips.push(strip(&cross, cc, town.left_edge_m(), 300.0));
            strips.push(strip(&cross, cc, -300.0, town.right_edge_m()));
        }
        None => strips.push(strip(town, X_AXIS, -250.0, 400.0)),
    }
    let mut solids = Vec::new();
    // The town's roadside: the same for every clip of the town.
    let mut rd = Draw::new(town.seed, &[0x51DE]);
    for side in [-1.0, 1.0] {
        let edge = if side < 0.0 {
            town.right_edge_m()
        } else {
            town.left_edge_m()
        } + side * WALK_M;
        let mut x = -60.0 + rd.range(0.0, 10.0);
        while x < 160.0 {
            let free = x < gap.0 - 8.0 || x > gap.1 + 8.0;
            if town.urban {
                let len = rd.range(10.0, 22.0);
                let depth = rd.range(8.0, 14.0);
                let off = edge + side * (rd.range(1.5, 4.0) + depth / 2.0);
                let parts = objects::building(&mut rd, len, depth);
                if free && (x + len / 2.0 < gap.0 || x - len / 2.0 > gap.1) {
                    solids.push(objects::at_rest(parts, [x, off], 0.0, None));
                }
                x += len + rd.range(2.0, 8.0);
            } else {
                let off = edge + side * rd.range(1.5, 5.0);
                let parts = objects::tree(&mut rd);
                if free {
                    solids.push(objects::at_rest(parts, [x, off], 0.0, None));
                }
                x += rd.range(7.0, 18.0);
            }
        }
    }
    let mut cd = Draw::new(plan.clip_seed, &[2]);
    for (k, o) in plan.others.iter().enumerate() {
        let (parts, class) = if o.pedestrian {
            (objects::pedestrian(&mut cd), ObjectClass::Pedestrian)
        } else {
            (objects::vehicle(&mut cd, false, false), ObjectClass::Car)
        };
        solids.push(Solid {
            parts,
            pos: [o.x_m, o.y_m],
            yaw: o.heading_rad,
            speed: o.speed_mps,
            accel: 0.0,
            tag: Some((class, TARGET_TRACK + 1 + k as u64)),
        });
    }
    let t = &plan.target;
    let tag = |c| Some((c, TARGET_TRACK));
    match t.class {
        HiddenClass::TrafficLight => {
            let arm = -t.y_m;
            let color = t.light.unwrap_or(LightColor::Red);
            let (support, head) = detector_parts(objects::traffic_light(color.state(), arm), 2);
            solids.push(objects::at_rest(support, [t.x_m, t.y_m], 0.0, None));
            solids.push(objects::at_rest(
                head,
                [t.x_m, t.y_m],
                0.0,
                tag(ObjectClass::TrafficLight),
            ));
        }
        HiddenClass::TrafficSign => {
            let (support, face) = detector_parts(objects::stop_sign(), 1);
            solids.push(objects::at_rest(support, [t.x_m, t.y_m], 0.0, None));
            solids.push(objects::at_rest(
                face,
                [t.x_m, t.y_m],
                0.0,
                tag(ObjectClass::StopSign),
            ));
        }
        HiddenClass::Pedestrian | HiddenClass::Bicycle => {
            let (parts, class) = if t.class == HiddenClass::Pedestrian {
                (objects::pedestrian(&mut cd), ObjectClass::Pedestrian)
            } else {
                (objects::cyclist(&mut cd), ObjectClass::Cyclist)
            };
            solids.push(Solid {
                parts,
                pos: [t.x_m, t.y_m],
                yaw: t.heading_rad,
                speed: t.speed_mps,
                accel: 0.0,
                tag: tag(class),
            });
        }
    }
    Scene {
        strips,
        solids,
        look: look(town.weather, town.daylight),
        ego: EgoMotion {
            speed: plan.ego_speed_mps,
            kappa: 0.0,
        },
        texture_seed: child(town.seed, &[0x7E47]),
    }
}
