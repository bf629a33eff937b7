//! Synthetic observations: the recorded story behind the replay example (boxes and
//! measurements, no pixels) and textured three-view scenes for the benchmark. Deterministic:
//! the textures come from a SplitMix64 hash of an explicit seed.

use std::sync::Arc;

use fogline_types::clip::CameraId;

use crate::observation::{
    Daylight, EgoState, NavDirection, Navigation, Observation, PixelBox, RoadGeometry, RoadLayout,
    Surroundings, TrafficEnv, TrafficObject, View, Weather,
};

/// Image width of the synthetic views, px.
pub const WIDTH: u32 = 576;
/// Image height of the synthetic views, px.
pub const HEIGHT: u32 = 320;

const VIEWS: [CameraId; 3] = [
    CameraId::CrossLeft,
    CameraId::FrontWide,
    CameraId::CrossRight,
];

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn surroundings() -> Surroundings {
    // The paper's example context (appendix A.4).
    Surroundings {
        weather: Weather::MidRain,
        daylight: Daylight::Sunset,
        traffic_env: TrafficEnv::Urban,
        traffic_density: 12,
    }
}

fn road() -> RoadGeometry {
    RoadGeometry {
        layout: RoadLayout::Straight,
        two_way: true,
        lanes: 2,
    }
}

fn obj(class: &str, track: u64, b: PixelBox) -> TrafficObject {
    TrafficObject {
        class: class.into(),
        track_id: Some(track),
        rect: b,
    }
}

/// The recorded story of the replay example: 80 ticks at 10 Hz on a straight urban road in
/// moderate rain at sunset.
///
/// - ticks 0–9: clean; a car ahead, a pedestrian walking in from the right of the front view;
/// - 10–24: the pedestrian is masked (a deficit that moves with them, crossing);
/// - 25–31: the pedestrian is visible again, left of the path;
/// - 32–55: a traffic light ahead is masked (a tall, narrow region high in the image);
/// - 60–79: dirt on the right camera (a large fixed region: an immediate hazard there);
/// - 64–72: the route changes to the left lane;
/// - 75–76: the front camera drops out.
pub fn story() -> Vec<Observation> {
    let mut out = Vec::with_capacity(80);
    let mut speed: f64 = 6.0;
    for t in 0..80u64 {
        let ti = t as f64;
        let target_speed = match t {
            0..=9 => 6.0,
            10..=24 => (6.0 - 0.4 * (ti - 9.0)).max(0.0),
            25..=31 => 0.3 * (ti - 24.0),
            32..=52 => (2.1 - 0.35 * (ti - 31.0)).max(0.0),
            _ => (0.2 * (ti - 52.0)).min(6.0),
        };
        // Short decimals, so that the JSON text reads back bit for bit.
        let round = |x: f64| (x * 1000.0).round() / 1000.0;
        let target_speed = round(target_speed);
        let accel = round((target_speed - speed) / 0.1);
        speed = target_speed;
        let lane_change = (64..=72).contains(&t);
        let mut front = View::new(CameraId::FrontWide, WIDTH, HEIGHT);
        front
            .objects
            .push(obj("car", 1, PixelBox::new(262.0, 150.0, 52.0, 38.0)));
        let ped = PixelBox::new(500.0 - 10.0 * ti, 150.0, 18.0, 44.0);
        if (10..=24).contains(&t) {
            front.deficits.push(ped.expanded(4.0));
        } else if t < 32 {
            front.objects.push(obj("pedestrian", 2, ped));
        }
        if (32..=55).contains(&t) {
            let k = ti - 32.0;
            front
                .deficits
                .push(PixelBox::new(330.0 + k, 40.0 - 0.5 * k, 14.0, 34.0));
        }
        let left = View::new(CameraId::CrossLeft, WIDTH, HEIGHT);
        let mut right = View::new(CameraId::CrossRight, WIDTH, HEIGHT);
        if t >= 60 {
            right
                .deficits
                .push(PixelBox::new(400.0, 200.0, 120.0, 90.0));
        }
        let mut views = vec![left];
        if !(75..=76).contains(&t) {
            views.push(front);
        }
        views.push(right);
        out.push(Observation {
            tick: t,
            views,
            ego: EgoState {
                speed_mps: speed,
                accel_x_mps2: if t == 0 { 0.0 } else { accel },
                yaw_rate_rps: if lane_change { 0.05 } else { 0.0 },
                follow_distance_m: Some(20.0),
            },
            navigation: Navigation {
                direction: if lane_change {
                    NavDirection::ChangeLaneLeft
                } else {
                    NavDirection::FollowLane
                },
                target_x_m: 10.0,
                target_y_m: if lane_change { 3.0 } else { 0.0 },
                road: road(),
            },
            surroundings: surroundings(),
        });
    }
    out
}

/// A textured three-view scene for the benchmark: 576×320 RGB frames whose texture moves by
/// `flow_px_per_tick` columns per tick (the ego's motion), a deficit attached to the
/// background in the front view (it moves with the texture, so it is consistent, and a flow
/// above the verifier's shift limit makes the verifier match the background), a fixed dirt
/// region on the right camera, and a car ahead.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchScene {
    /// Texture seed.
    pub seed: u64,
    /// Background motion, px per tick.
    pub flow_px_per_tick: u32,
}

impl BenchScene {
    /// The observation at `tick` (the front deficit wraps around every 16 ticks).
    pub fn observation(&self, tick: u64) -> Observation {
        let flow = i64::from(self.flow_px_per_tick);
        let shift = flow * tick as i64;
        let views = VIEWS
            .iter()
            .enumerate()
            .map(|(ci, &camera)| {
                let key = splitmix(self.seed ^ (ci as u64) << 32);
                let mut px = Vec::with_capacity((WIDTH * HEIGHT * 3) as usize);
                for y in 0..i64::from(HEIGHT) {
                    for x in 0..i64::from(WIDTH) {
                        let xs = x + shift;
                        let h = splitmix(key ^ ((xs.div_euclid(2) as u64) << 20) ^ (y / 2) as u64);
                        let base = (y * 255 / i64::from(HEIGHT)) as u64;
                        let v = ((h & 0x7F) + base / 2).min(255) as u8;
                        px.extend_from_slice(&[v, v.wrapping_add(7), v / 2 + 40]);
                    }
                }
                let mut v = View::new(camera, WIDTH, HEIGHT);
                v.rgb = Some(Arc::from(px));
                match camera {
                    CameraId::FrontWide => {
                        let x = 420.0 - (flow * (tick % 16) as i64) as f64;
                        v.deficits.push(PixelBox::new(x, 110.0, 30.0, 60.0));
                        v.objects
                            .push(obj("car", 1, PixelBox::new(262.0, 150.0, 52.0, 38.0)));
                    }
                    CameraId::CrossRight => {
                        v.deficits.push(PixelBox::new(60.0, 40.0, 50.0, 40.0));
                    }
                    _ => {}
                }
                v
            })
            .collect();
        Observation {
            tick,
            views,
            ego: EgoState {
                speed_mps: 5.0,
                accel_x_mps2: 0.0,
                yaw_rate_rps: 0.0,
                follow_distance_m: Some(25.0),
            },
            navigation: Navigation {
                direction: NavDirection::FollowLane,
                target_x_m: 10.0,
                target_y_m: 0.2,
                road: road(),
            },
            surroundings: surroundings(),
        }
    }
}
