//! What the cameras see: the scene around the ego assembled for the world crate's renderer,
//! weather and daylight, and the perception deficits (objects of one class blacked out with
//! a red outline by the perturbation crate whenever they are visible).
//!
//! The renderer draws a scene in the rig frame at the ego's pose: every nearby ground strip
//! and solid is moved into the ego's frame before each frame (strips within 160 m, solids
//! within 130 m and not more than 25 m behind). One consequence: the renderer's fine ground
//! texture (±7 grey levels in 0.25 m cells) is fixed to the camera rather than to the road;
//! markings, kerbs and objects move correctly.

use std::f64::consts::PI;

use fogline_perturb::deficit::DeficitRegion;
use fogline_perturb::frame::{DepthMap, Frame, FrameKey, ObjectBox};
use fogline_perturb::perturbation::{FrameInput, Perturbation, Prepared};
use fogline_types::clip::CameraCalib;
use fogline_world::objects::{self, LightState};
use fogline_world::render::render;
use fogline_world::scene::{Centre, Draw, EgoMotion, Look, ObjectClass, Part, Scene, Solid, Strip};
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::geom::{P2, dist};
use crate::town::{Light, Town};
use crate::traffic::Traffic;
use crate::vehicle::VehicleState;

/// Longest6's weathers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weather {
    /// Cloudy.
    Cloudy,
    /// Wet road.
    Wet,
    /// Moderate rain.
    MidRain,
    /// Wet road, cloudy.
    WetCloudy,
    /// Heavy rain.
    HardRain,
    /// Light rain.
    SoftRain,
}

impl Weather {
    /// All six, in Longest6's order.
    pub const ALL: [Weather; 6] = [
        Weather::Cloudy,
        Weather::Wet,
        Weather::MidRain,
        Weather::WetCloudy,
        Weather::HardRain,
        Weather::SoftRain,
    ];

    /// The snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            Weather::Cloudy => "cloudy",
            Weather::Wet => "wet",
            Weather::MidRain => "mid_rain",
            Weather::WetCloudy => "wet_cloudy",
            Weather::HardRain => "hard_rain",
            Weather::SoftRain => "soft_rain",
        }
    }

    /// The RCO controller's weather.
    pub fn rco(self) -> fogline_rco::Weather {
        match self {
            Weather::Cloudy => fogline_rco::Weather::Cloudy,
            Weather::Wet => fogline_rco::Weather::Wet,
            Weather::MidRain => fogline_rco::Weather::MidRain,
            Weather::WetCloudy => fogline_rco::Weather::WetCloudy,
            Weather::HardRain => fogline_rco::Weather::HardRain,
            Weather::SoftRain => fogline_rco::Weather::SoftRain,
        }
    }

    /// The atmosphere as a perturbation (Koschmieder fog by visibility), if any.
    pub fn condition(self) -> Option<&'static str> {
        match self {
            Weather::SoftRain => Some("visibility_400"),
            Weather::MidRain => Some("visibility_220"),
            Weather::HardRain => Some("visibility_120"),
            _ => None,
        }
    }

    fn cloudy(self) -> bool {
        !matches!(self, Weather::Wet)
    }

    fn wet(self) -> bool {
        matches!(
            self,
            Weather::Wet | Weather::WetCloudy | Weather::MidRain | Weather::HardRain
        )
    }
}

/// Longest6's daylights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Daylight {
    /// Night.
    Night,
    /// Twilight.
    Twilight,
    /// Dawn.
    Dawn,
    /// Morning.
    Morning,
    /// Noon.
    Noon,
    /// Sunset.
    Sunset,
}

impl Daylight {
    /// All six, in Longest6's order.
    pub const ALL: [Daylight; 6] = [
        Daylight::Night,
        Daylight::Twilight,
        Daylight::Dawn,
        Daylight::Morning,
        Daylight::Noon,
        Daylight::Sunset,
    ];

    /// The snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            Daylight::Night => "night",
            Daylight::Twilight => "twilight",
            Daylight::Dawn => "dawn",
            Daylight::Morning => "morning",
            Daylight::Noon => "noon",
            Daylight::Sunset => "sunset",
        }
    }

    /// The RCO controller's daylight.
    pub fn rco(self) -> fogline_rco::Daylight {
        match self {
            Daylight::Night => fogline_rco::Daylight::Night,
            Daylight::Twilight | Daylight::Dawn | Daylight::Sunset => fogline_rco::Daylight::Sunset,
            Daylight::Morning | Daylight::Noon => fogline_rco::Daylight::Day,
        }
    }
}

/// The renderer's palette for a weather and daylight.
pub fn look(weather: Weather, daylight: Daylight) -> Look {
    let norm = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    let (light, horizon, zenith, sun) = match daylight {
        Daylight::Noon => (
            1.0,
            [206.0, 218.0, 232.0],
            [92.0, 148.0, 214.0],
            [0.2, 0.1, 0.95],
        ),
        Daylight::Morning => (
            0.92,
            [214.0, 214.0, 220.0],
            [110.0, 150.0, 205.0],
            [0.6, 0.3, 0.6],
        ),
        Daylight::Dawn => (
            0.75,
            [236.0, 190.0, 160.0],
            [96.0, 110.0, 160.0],
            [0.8, 0.2, 0.3],
        ),
        Daylight::Sunset => (
            0.65,
            [232.0, 164.0, 116.0],
            [72.0, 82.0, 128.0],
            [-0.7, 0.2, 0.3],
        ),
        // Twilight and night: the streets are lit (street lamps, headlights), the sky is not.
        Daylight::Twilight => (
            0.6,
            [150.0, 130.0, 150.0],
            [40.0, 48.0, 90.0],
            [-0.6, 0.0, 0.1],
        ),
        Daylight::Night => (
            0.55,
            [48.0, 52.0, 70.0],
            [12.0, 14.0, 28.0],
            [0.0, 0.0, 1.0],
        ),
    };
    let cloud = weather.cloudy();
    let (light, horizon, zenith, sun) = if cloud {
        let grey = |c: [f32; 3], k: f32| {
            let m = (c[0] + c[1] + c[2]) / 3.0;
            [
                (c[0] + (m - c[0]) * 0.7) * k,
                (c[1] + (m - c[1]) * 0.7) * k,
                (c[2] + (m - c[2]) * 0.7) * k,
            ]
        };
        (
            light * 0.88,
            grey(horizon, 0.95),
            grey(zenith, 1.1),
            [0.0, 0.0, 1.0],
        )
    } else {
        (light, horizon, zenith, sun)
    };
    let asphalt = if weather.wet() {
        [70.0, 70.0, 76.0]
    } else {
        [90.0, 90.0, 95.0]
    };
    Look {
        light,
        sky_horizon: horizon,
        sky_zenith: zenith,
        asphalt,
        walk: [172.0, 170.0, 164.0],
        terrain: [86.0, 118.0, 58.0],
        sun: norm(sun),
    }
}

/// The object classes a deficit can hide (the paper's four).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeficitKind {
    /// Traffic lights.
    TrafficLight,
    /// Stop signs.
    StopSign,
    /// Pedestrians.
    Pedestrian,
    /// Bicycles (cyclists).
    Bicycle,
}

impl DeficitKind {
    /// All four, in the paper's order.
    pub const ALL: [DeficitKind; 4] = [
        DeficitKind::TrafficLight,
        DeficitKind::StopSign,
        DeficitKind::Pedestrian,
        DeficitKind::Bicycle,
    ];

    /// The snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            DeficitKind::TrafficLight => "traffic_light",
            DeficitKind::StopSign => "stop_sign",
            DeficitKind::Pedestrian => "pedestrian",
            DeficitKind::Bicycle => "bicycle",
        }
    }

    /// Parses [`DeficitKind::name`] (also `bicycles`, `cyclist`, `lights`, `signs`, …).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "traffic_light" | "traffic_lights" | "light" | "lights" => Some(Self::TrafficLight),
            "stop_sign" | "stop_signs" | "sign" | "signs" => Some(Self::StopSign),
            "pedestrian" | "pedestrians" => Some(Self::Pedestrian),
            "bicycle" | "bicycles" | "cyclist" | "cyclists" => Some(Self::Bicycle),
            _ => None,
        }
    }

    /// The box class it hides (the world's labels).
    pub fn class(self) -> ObjectClass {
        match self {
            DeficitKind::TrafficLight => ObjectClass::TrafficLight,
            DeficitKind::StopSign => ObjectClass::StopSign,
            DeficitKind::Pedestrian => ObjectClass::Pedestrian,
            DeficitKind::Bicycle => ObjectClass::Cyclist,
        }
    }

    /// The perturbation condition (`mask_class_<label>`).
    pub fn condition(self) -> String {
        format!("mask_class_{}", self.class().label())
    }
}

/// A rendered, perturbed camera frame.
#[derive(Debug, Clone)]
pub struct Seen {
    /// The frame as the agent gets it.
    pub frame: Frame,
    /// Boxes of every visible tracked object (ground truth of the renderer).
    pub boxes: Vec<ObjectBox>,
    /// The regions a deficit hid.
    pub deficits: Vec<DeficitRegion>,
}

/// The perturbation of a run: the weather's atmosphere, then the deficit's mask.
#[derive(Debug, Clone)]
pub struct Lens {
    prepared: Option<Prepared>,
    needs_depth: bool,
}

impl Lens {
    /// For `weather` and an optional deficit.
    pub fn new(weather: Weather, deficit: Option<DeficitKind>) -> Result<Self, SimError> {
        let mut steps: Vec<String> = Vec::new();
        if let Some(c) = weather.condition() {
            steps.push(c.to_string());
        }
        if let Some(d) = deficit {
            steps.push(d.condition());
        }
        if steps.is_empty() {
            return Ok(Self {
                prepared: None,
                needs_depth: false,
            });
        }
        let name = steps.join("+");
        let p = Perturbation::parse(&name)
            .and_then(|p| p.prepare(0))
            .map_err(|e| SimError::Params(format!("condition {name}: {e}")))?;
        let needs_depth = p.perturbation().needs_depth();
        Ok(Self {
            prepared: Some(p),
            needs_depth,
        })
    }

    /// Whether frames need depth maps.
    pub fn needs_depth(&self) -> bool {
        self.needs_depth
    }

    fn apply(
        &self,
        frame: Frame,
        depth: Option<&DepthMap>,
        boxes: &[ObjectBox],
        key: FrameKey,
    ) -> (Frame, Vec<DeficitRegion>) {
        let Some(p) = &self.prepared else {
            return (frame, Vec::new());
        };
        let input = FrameInput {
            frame: frame.view(),
            key,
            depth,
            boxes,
        };
        match p.apply(&input) {
            Ok(a) => (a.frame, a.deficits),
            // The renderer's boxes always lie inside the frame and depth maps match it.
            Err(_) => (frame, Vec::new()),
        }
    }
}

/// Parts drawn once per run.
#[derive(Debug, Clone)]
pub struct PartsCache {
    buildings: Vec<Vec<Part>>,
    /// Per light state: the pole and arm (untagged), the head with its lamps (tagged).
    lights: [(Vec<Part>, Vec<Part>); 3],
    /// The sign's pole (untagged) and face (tagged).
    sign: (Vec<Part>, Vec<Part>),
}

impl PartsCache {
    /// Draws the town's static parts.
    pub fn new(town: &Town) -> Self {
        let arm = town.lights.first().map_or(3.25, |l| l.arm_m);
        Self {
            buildings: town
                .buildings
                .iter()
                .map(|b| {
                    let mut d = Draw::new(b.seed, &[0xB1D]);
                    objects::building(&mut d, 2.0 * b.obb.hl, 2.0 * b.obb.hw)
                })
                .collect(),
            lights: [
                detector_parts(objects::traffic_light(LightState::Red, arm), 2),
                detector_parts(objects::traffic_light(LightState::Amber, arm), 2),
                detector_parts(objects::traffic_light(LightState::Green, arm), 2),
            ],
            sign: detector_parts(objects::stop_sign(), 1),
        }
    }
}

/// A traffic light's or stop sign's parts as the closed loop draws them: the untagged
/// support (the first `support` parts: 2 for a light's pole and arm, 1 for a sign's pole) and
/// the tagged rest (the signal head, the sign face), which is what a detector boxes and a
/// deficit hides. The world's objects are single solids; a YOLO-class detector's `traffic
/// light` and `stop sign` boxes cover the head and the face only, so they are drawn as two
/// solids with only the second tagged.
pub fn detector_parts(mut parts: Vec<Part>, support: usize) -> (Vec<Part>, Vec<Part>) {
    let rest = parts.split_off(support.min(parts.len()));
    (parts, rest)
}

/// Culling distances, m.
const STRIP_RANGE_M: f64 = 130.0;
const SOLID_RANGE_M: f64 = 130.0;
const BEHIND_M: f64 = 25.0;

/// The scene around the ego in its rig frame, every strip and solid with a bounding circle
/// so that each camera renders only what its field of view can reach.
#[derive(Debug, Clone)]
pub struct Surround {
    strips: Vec<([f64; 2], f64, Strip)>,
    solids: Vec<([f64; 2], f64, Solid)>,
    look: Look,
    texture_seed: u64,
}

impl Surround {
    /// The scene one camera renders: the strips and solids whose bounding circle meets its
    /// horizontal field of view (with a margin), nearest strips first.
    pub fn for_camera(&self, calib: &CameraCalib) -> Scene {
        let half = (f64::from(calib.width) / 2.0 / calib.fx).atan() + 0.05;
        let (cx, cy) = (calib.x_m, calib.y_m);
        let sees = |c: [f64; 2], r: f64| {
            let (dx, dy) = (c[0] - cx, c[1] - cy);
            let d = dx.hypot(dy);
            if d <= r + 1.0 {
                return true;
            }
            let a = crate::vehicle::wrap_angle(dy.atan2(dx) - calib.yaw_rad).abs();
            a <= half + (r / d).min(1.0).asin()
        };
        Scene {
            strips: self
                .strips
                .iter()
                .filter(|(c, r, _)| sees(*c, *r))
                .map(|(_, _, s)| s.clone())
                .collect(),
            solids: self
                .solids
                .iter()
                .filter(|(c, r, _)| sees(*c, *r))
                .map(|(_, _, s)| s.clone())
                .collect(),
            look: self.look,
            ego: EgoMotion {
                speed: 0.0,
                kappa: 0.0,
            },
            texture_seed: self.texture_seed,
        }
    }
}

/// The scene around the ego, in its rig frame.
pub fn scene_at(
    town: &Town,
    traffic: &Traffic,
    cache: &PartsCache,
    ego: &VehicleState,
    t_s: f64,
    look: Look,
) -> Surround {
    let (s, c) = ego.yaw_rad.sin_cos();
    let o = [ego.x_m, ego.y_m];
    let to_local = |p: P2| {
        let (dx, dy) = (p[0] - o[0], p[1] - o[1]);
        [c * dx + s * dy, -s * dx + c * dy]
    };
    let rot = |u: P2| [c * u[0] + s * u[1], -s * u[0] + c * u[1]];
    let visible = |p: P2, extra: f64| {
        let q = to_local(p);
        q[0] > -BEHIND_M - extra && dist(p, o) < SOLID_RANGE_M + extra
    };
    let mut strips: Vec<(f64, [f64; 2], f64, Strip)> = Vec::new();
    for ps in &town.strips {
        let d = dist(ps.centre, o);
        if d - ps.radius > STRIP_RANGE_M {
            continue;
        }
        let mut strip = ps.strip.clone();
        if let Centre::Line { origin, dir } = strip.centre {
            strip.centre = Centre::Line {
                origin: to_local(origin),
                dir: rot(dir),
            };
        }
        strips.push((d - ps.radius, to_local(ps.centre), ps.radius, strip));
    }
    // Nearest first: a ground pixel usually finds its strip early.
    strips.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut solids: Vec<([f64; 2], f64, Solid)> = Vec::new();
    let mut put = |parts: Vec<Part>, p: P2, r: f64, yaw: f64, tag: Option<(ObjectClass, u64)>| {
        let local = to_local(p);
        solids.push((
            local,
            r,
            Solid {
                parts,
                pos: local,
                yaw: yaw - ego.yaw_rad,
                speed: 0.0,
                accel: 0.0,
                tag,
            },
        ));
    };
    for (b, parts) in town.buildings.iter().zip(&cache.buildings) {
        if visible(b.obb.c, b.obb.hl) {
            put(
                parts.clone(),
                b.obb.c,
                b.obb.hl.hypot(b.obb.hw),
                b.obb.yaw,
                None,
            );
        }
    }
    for l in &town.lights {
        if visible(l.pos, 10.0) {
            let k = match town.light(l.node, l.din, t_s) {
                Light::Red => 0,
                Light::Amber => 1,
                Light::Green => 2,
            };
            put(cache.lights[k].0.clone(), l.pos, l.arm_m + 0.5, l.yaw, None);
            put(
                cache.lights[k].1.clone(),
                l.pos,
                l.arm_m + 0.5,
                l.yaw,
                Some((ObjectClass::TrafficLight, l.id)),
            );
        }
    }
    for sg in &town.signs {
        if visible(sg.pos, 0.0) {
            put(cache.sign.0.clone(), sg.pos, 0.6, sg.yaw, None);
            put(
                cache.sign.1.clone(),
                sg.pos,
                0.6,
                sg.yaw,
                Some((ObjectClass::StopSign, sg.id)),
            );
        }
    }
    for n in &traffic.npcs {
        if visible(n.pos, n.half_len_m) {
            let mut parts = n.parts.clone();
            if n.braking() {
                light_brakes(&mut parts);
            }
            put(
                parts,
                n.pos,
                n.half_len_m + 0.5,
                n.yaw,
                Some((n.class(), n.id)),
            );
        }
    }
    for w in &traffic.walkers {
        if visible(w.pos, 0.0) {
            put(w.parts.clone(), w.pos, 1.0, w.yaw, Some((w.class(), w.id)));
        }
    }
    Surround {
        strips: strips.into_iter().map(|(_, c, r, s)| (c, r, s)).collect(),
        solids,
        look,
        texture_seed: town.texture_seed,
    }
}

/// Lights the rear lamps of a vehicle's parts.
fn light_brakes(parts: &mut [Part]) {
    for p in parts.iter_mut() {
        if let Part::Plate {
            facing,
            color,
            emissive,
            ..
        } = p
            && (*facing - PI).abs() < 1e-9
            && *color == objects::BRAKE_OFF
        {
            *color = objects::BRAKE_ON;
            *emissive = true;
        }
    }
}

/// The calibrations of the views the RCO controller sees in the closed loop, in its order
/// (cross-left, front-wide, cross-right): the front-wide camera at `width × height` with a
/// horizontal field of view of `wide_fov_deg`, the cross cameras at `side_width ×
/// side_height` (what `run` builds from its `SensorParams`: pass `width`, `height`,
/// `wide_fov_deg`, `side_width()`, `side_height()`).
pub fn rco_cameras(
    width: u32,
    height: u32,
    wide_fov_deg: f64,
    side_width: u32,
    side_height: u32,
) -> [CameraCalib; 3] {
    use fogline_types::clip::CameraId;
    let mut wide = CameraCalib::standard(CameraId::FrontWide, width, height);
    wide.fx = f64::from(width) / 2.0 / (wide_fov_deg.to_radians() / 2.0).tan();
    wide.fy = wide.fx;
    [
        CameraCalib::standard(CameraId::CrossLeft, side_width, side_height),
        wide,
        CameraCalib::standard(CameraId::CrossRight, side_width, side_height),
    ]
}

/// Smallest box the modelled detector finds: this share of the image height.
pub const DETECT_MIN_HEIGHT_FRAC: f64 = 0.03;
/// Smallest box width the modelled detector finds, px.
pub const DETECT_MIN_WIDTH_PX: f64 = 2.0;

/// The boxes the modelled detector finds among a rendered view's `boxes` for `calib`: at
/// least [`DETECT_MIN_HEIGHT_FRAC`] of the image high and [`DETECT_MIN_WIDTH_PX`] wide.
pub fn detected(boxes: Vec<ObjectBox>, calib: &CameraCalib) -> Vec<ObjectBox> {
    let min_h = DETECT_MIN_HEIGHT_FRAC * f64::from(calib.height);
    boxes
        .into_iter()
        .filter(|b| b.height_px >= min_h && b.width_px >= DETECT_MIN_WIDTH_PX)
        .collect()
}

/// Renders the surroundings through `calib` and applies the run's lens. The deficit hides
/// the objects of its class that the paper's detector (YOLO11) would find: boxes at least 3 %
/// of the image high and 2 px wide (a YOLO-class detector misses objects of a few pixels);
/// `boxes` lists those detectable boxes.
pub fn see(around: &Surround, calib: &CameraCalib, lens: &Lens, key: FrameKey) -> Seen {
    let scene = around.for_camera(calib);
    let view = render(&scene, calib, 0.0, lens.needs_depth());
    let boxes = detected(view.boxes, calib);
    let (frame, deficits) = lens.apply(view.image, view.depth.as_ref(), &boxes, key);
    Seen {
        frame,
        boxes,
        deficits,
    }
}
