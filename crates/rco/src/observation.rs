//! What the controller sees every tick: the camera views with their deficit regions and the
//! detected traffic objects, the ego measurements, the navigation and the surroundings
//! (the paper's `E_t = [Perception_t, Navi_t, Surrounding_t]` plus the measurements of
//! appendix A.2).
//!
//! Frames: pixel `(u, v)` with `u` to the right and `v` down, origin top-left. Ego frame:
//! `x` forward, `y` left, metres; yaw rates left positive, radians per second.

use std::fmt;
use std::sync::Arc;

use fogline_types::clip::{CameraCalib, CameraId};
use serde::{Deserialize, Serialize};

use crate::RcoError;

/// Largest accepted image side, px.
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// An axis-aligned box in pixels (origin top-left, `x` right, `y` down).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PixelBox {
    /// Left edge, px.
    pub x_px: f64,
    /// Top edge, px.
    pub y_px: f64,
    /// Width, px (>= 0).
    pub width_px: f64,
    /// Height, px (>= 0).
    pub height_px: f64,
}

impl PixelBox {
    /// The bounding boxes of the connected regions (8-neighbourhood) of a `width × height`
    /// row-major mask whose non-zero entries mark lost pixels: a segmentation-style deficit
    /// mask as a CARLA agent or a dataset gives it, turned into the regions the controller
    /// reasons about. Regions come in the order of their first pixel (top to bottom, left to
    /// right). `None` when `mask` does not hold `width × height` entries.
    pub fn from_mask(mask: &[u8], width: usize, height: usize) -> Option<Vec<PixelBox>> {
        if width.checked_mul(height) != Some(mask.len()) {
            return None;
        }
        // Union-find over the set pixels, one row at a time (classic two-pass labelling).
        let mut parent: Vec<u32> = Vec::new();
        let mut label = vec![u32::MAX; mask.len()];
        fn root(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                let p = parent[i as usize];
                parent[i as usize] = parent[p as usize];
                i = p;
            }
            i
        }
        for y in 0..height {
            for x in 0..width {
                let i = y * width + x;
                if mask[i] == 0 {
                    continue;
                }
                let mut mine = u32::MAX;
                let neighbours = [
                    (x > 0).then(|| i - 1),
                    (y > 0 && x > 0).then(|| i - width - 1),
                    (y > 0).then(|| i - width),
                    (y > 0 && x + 1 < width).then(|| i - width + 1),
                ];
                for n in neighbours.into_iter().flatten() {
                    let l = label[n];
                    if l == u32::MAX {
                        continue;
                    }
                    let r = root(&mut parent, l);
                    if mine == u32::MAX {
                        mine = r;
                    } else if r != mine {
                        let (lo, hi) = (mine.min(r), mine.max(r));
                        parent[hi as usize] = lo;
                        mine = lo;
                    }
                }
                if mine == u32::MAX {
                    mine = parent.len() as u32;
                    parent.push(mine);
                }
                label[i] = mine;
            }
        }
        // Bounds per root, in the order roots were created (first pixel order).
        let mut bounds: Vec<Option<[usize; 4]>> = vec![None; parent.len()];
        for (i, &l) in label.iter().enumerate() {
            if l == u32::MAX {
                continue;
            }
            let r = root(&mut parent, l) as usize;
            let (x, y) = (i % width, i / width);
            let b = bounds[r].get_or_insert([x, y, x, y]);
            *b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        }
        Some(
            bounds
                .into_iter()
                .flatten()
                .map(|[x0, y0, x1, y1]| {
                    PixelBox::new(
                        x0 as f64,
                        y0 as f64,
                        (x1 - x0 + 1) as f64,
                        (y1 - y0 + 1) as f64,
                    )
                })
                .collect(),
        )
    }

    /// A box from its left, top, width and height.
    pub fn new(x_px: f64, y_px: f64, width_px: f64, height_px: f64) -> Self {
        Self {
            x_px,
            y_px,
            width_px,
            height_px,
        }
    }

    /// Right edge, px.
    pub fn x_end_px(&self) -> f64 {
        self.x_px + self.width_px
    }

    /// Bottom edge, px.
    pub fn y_end_px(&self) -> f64 {
        self.y_px + self.height_px
    }

    /// Centre `(u, v)`, px.
    pub fn center(&self) -> (f64, f64) {
        (
            self.x_px + self.width_px / 2.0,
            self.y_px + self.height_px / 2.0,
        )
    }

    /// Area, px².
    pub fn area(&self) -> f64 {
        self.width_px.max(0.0) * self.height_px.max(0.0)
    }

    /// The box clipped to a `width × height` image (possibly empty).
    pub fn clipped(&self, width: u32, height: u32) -> PixelBox {
        let (w, h) = (f64::from(width), f64::from(height));
        let x0 = self.x_px.clamp(0.0, w);
        let y0 = self.y_px.clamp(0.0, h);
        let x1 = self.x_end_px().clamp(0.0, w);
        let y1 = self.y_end_px().clamp(0.0, h);
        PixelBox::new(x0, y0, (x1 - x0).max(0.0), (y1 - y0).max(0.0))
    }

    /// Area of the intersection with `other`, px².
    pub fn intersection_area(&self, other: &PixelBox) -> f64 {
        let w = self.x_end_px().min(other.x_end_px()) - self.x_px.max(other.x_px);
        let h = self.y_end_px().min(other.y_end_px()) - self.y_px.max(other.y_px);
        w.max(0.0) * h.max(0.0)
    }

    /// The box grown by `margin_px` on every side.
    pub fn expanded(&self, margin_px: f64) -> PixelBox {
        PixelBox::new(
            self.x_px - margin_px,
            self.y_px - margin_px,
            self.width_px + 2.0 * margin_px,
            self.height_px + 2.0 * margin_px,
        )
    }

    /// Whether the point `(u, v)` lies inside (`[x, x + w) × [y, y + h)`).
    pub fn contains(&self, u: f64, v: f64) -> bool {
        u >= self.x_px && u < self.x_end_px() && v >= self.y_px && v < self.y_end_px()
    }

    fn check(&self, what: &str) -> Result<(), String> {
        let vals = [self.x_px, self.y_px, self.width_px, self.height_px];
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(format!("{what}: box values must be finite"));
        }
        if self.width_px < 0.0 || self.height_px < 0.0 {
            return Err(format!(
                "{what}: box size {}x{} must not be negative",
                self.width_px, self.height_px
            ));
        }
        Ok(())
    }
}

/// A detected traffic object (car, truck, bus, bicycle, pedestrian, motorcycle, …).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrafficObject {
    /// Class label (`car`, `pedestrian`, …).
    pub class: String,
    /// Track id (the same object across ticks), when the detector tracks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub track_id: Option<u64>,
    /// The object's box.
    pub rect: PixelBox,
}

/// One camera's view at this tick.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
pub struct View {
    /// The camera.
    pub camera: CameraId,
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// The frame, RGB8 row-major, `width × height × 3` bytes (base64 in JSON). Optional: without
    /// pixels the verifier measures deficit shifts in image space only and the `openai`
    /// backend sends text only.
    #[serde(default, with = "rgb_base64", skip_serializing_if = "Option::is_none")]
    pub rgb: Option<Arc<[u8]>>,
    /// The perception-deficit regions (pixels the perception lost).
    #[serde(default)]
    pub deficits: Vec<PixelBox>,
    /// The traffic objects the detector still sees.
    #[serde(default)]
    pub objects: Vec<TrafficObject>,
    /// The camera's calibration, when known: hazard inference then places a region's ground
    /// contact on the road ([`View::ground_point`]) and measures its motion over the ground,
    /// the ego's own motion removed. Without it, motion is read in image space.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calib: Option<CameraCalib>,
}

impl fmt::Debug for View {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("View")
            .field("camera", &self.camera)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("rgb_bytes", &self.rgb.as_ref().map(|p| p.len()))
            .field("deficits", &self.deficits)
            .field("objects", &self.objects)
            .finish()
    }
}

impl View {
    /// A view without pixels.
    pub fn new(camera: CameraId, width: u32, height: u32) -> Self {
        Self {
            camera,
            width,
            height,
            rgb: None,
            deficits: Vec::new(),
            objects: Vec::new(),
            calib: None,
        }
    }

    /// Where the pixel `(u, v)` meets a flat road, in the rig frame (`x` ahead of the rear
    /// axle, `y` left, m), from [`View::calib`]; `None` without a calibration or for a pixel
    /// at or above the horizon (its ray never meets the road within 200 m).
    pub fn ground_point(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        let c = self.calib.as_ref()?;
        let [f, r, d] = c.axes();
        let (a, b) = ((u - c.cx) / c.fx, (v - c.cy) / c.fy);
        let ray = [
            f[0] + a * r[0] + b * d[0],
            f[1] + a * r[1] + b * d[1],
            f[2] + a * r[2] + b * d[2],
        ];
        if ray[2] >= -1e-6 {
            return None;
        }
        let t = c.z_m / -ray[2];
        let p = [c.x_m + t * ray[0], c.y_m + t * ray[1]];
        (t.is_finite() && p[0].hypot(p[1]) <= 200.0).then_some(p)
    }

    /// Image area, px².
    pub fn area(&self) -> f64 {
        f64::from(self.width) * f64::from(self.height)
    }

    fn check(&self) -> Result<(), String> {
        let cam = self.camera.short();
        if self.width == 0
            || self.height == 0
            || self.width > MAX_IMAGE_SIDE
            || self.height > MAX_IMAGE_SIDE
        {
            return Err(format!(
                "view {cam}: image size {}x{} must be within 1..={MAX_IMAGE_SIDE}",
                self.width, self.height
            ));
        }
        if let Some(rgb) = &self.rgb {
            let want = self.width as usize * self.height as usize * 3;
            if rgb.len() != want {
                return Err(format!(
                    "view {cam}: {} RGB bytes, expected {want} ({}x{}x3)",
                    rgb.len(),
                    self.width,
                    self.height
                ));
            }
        }
        for (i, d) in self.deficits.iter().enumerate() {
            d.check(&format!("view {cam}, deficit {i}"))?;
        }
        for (i, o) in self.objects.iter().enumerate() {
            o.rect
                .check(&format!("view {cam}, object {i} ({})", o.class))?;
        }
        if let Some(c) = &self.calib {
            let finite = [
                c.fx,
                c.fy,
                c.cx,
                c.cy,
                c.x_m,
                c.y_m,
                c.z_m,
                c.yaw_rad,
                c.pitch_rad,
            ]
            .iter()
            .all(|v| v.is_finite());
            if !finite || c.fx <= 0.0 || c.fy <= 0.0 || c.z_m <= 0.0 {
                return Err(format!(
                    "view {cam}: calib needs finite numbers, positive focal lengths and a camera above the road (z_m > 0)"
                ));
            }
        }
        Ok(())
    }
}

/// The ego measurements (speedometer and IMU).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EgoState {
    /// Speed `v`, m/s.
    pub speed_mps: f64,
    /// Longitudinal acceleration `a_x`, m/s² (negative while braking).
    pub accel_x_mps2: f64,
    /// Yaw rate `ω_z`, rad/s, left positive.
    pub yaw_rate_rps: f64,
    /// Distance to the vehicle ahead `d_follow`, m (`None`: nobody ahead).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub follow_distance_m: Option<f64>,
}

/// The route planner's direction at this point (CARLA's road options).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NavDirection {
    /// Follow the current lane.
    FollowLane,
    /// Go straight through the junction.
    Straight,
    /// Turn left at the junction.
    Left,
    /// Turn right at the junction.
    Right,
    /// Change to the left lane.
    ChangeLaneLeft,
    /// Change to the right lane.
    ChangeLaneRight,
}

impl NavDirection {
    /// The snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            NavDirection::FollowLane => "follow_lane",
            NavDirection::Straight => "straight",
            NavDirection::Left => "left",
            NavDirection::Right => "right",
            NavDirection::ChangeLaneLeft => "change_lane_left",
            NavDirection::ChangeLaneRight => "change_lane_right",
        }
    }
}

/// The shape of the road at the ego.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RoadLayout {
    /// A straight road.
    Straight,
    /// A bend.
    Curve,
    /// A junction.
    Junction,
    /// A roundabout.
    Roundabout,
}

/// Road geometry (`#road_geometry`, e.g. "straight 2-way road").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RoadGeometry {
    /// The layout.
    pub layout: RoadLayout,
    /// Traffic in both directions.
    pub two_way: bool,
    /// Lanes in the ego's direction.
    pub lanes: u8,
}

impl fmt::Display for RoadGeometry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let layout = match self.layout {
            RoadLayout::Straight => "straight",
            RoadLayout::Curve => "curved",
            RoadLayout::Junction => "junction on a",
            RoadLayout::Roundabout => "roundabout on a",
        };
        let way = if self.two_way { "2-way" } else { "1-way" };
        write!(
            f,
            "{layout} {way} road, {} lane(s) in our direction",
            self.lanes
        )
    }
}

/// `Navi_t`: the direction, the next target point and the road geometry.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Navigation {
    /// The route's direction.
    pub direction: NavDirection,
    /// The next navigation target point, ego frame, m (forward).
    pub target_x_m: f64,
    /// The next navigation target point, ego frame, m (left).
    pub target_y_m: f64,
    /// The road geometry.
    pub road: RoadGeometry,
}

/// Weather (CARLA's presets, without the time of day).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weather {
    /// Clear sky.
    Clear,
    /// Cloudy.
    Cloudy,
    /// Wet road.
    Wet,
    /// Wet road, cloudy.
    WetCloudy,
    /// Light rain.
    SoftRain,
    /// Moderate rain.
    MidRain,
    /// Heavy rain.
    HardRain,
    /// Fog.
    Fog,
    /// Snow.
    Snow,
}

/// Daylight.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Daylight {
    /// Day.
    Day,
    /// Sunset (low sun, glare).
    Sunset,
    /// Night.
    Night,
}

/// Traffic environment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrafficEnv {
    /// City streets.
    Urban,
    /// Suburbs.
    Suburban,
    /// Country roads.
    Rural,
    /// Motorway.
    Highway,
}

/// `Surrounding_t`: weather, daylight, traffic environment and density.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Surroundings {
    /// Weather.
    pub weather: Weather,
    /// Daylight.
    pub daylight: Daylight,
    /// Traffic environment.
    pub traffic_env: TrafficEnv,
    /// Moving objects within 50 m of the ego.
    pub traffic_density: u32,
}

/// Everything the controller gets at one tick.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Observation {
    /// The control tick (increasing by one per call in a normal run).
    pub tick: u64,
    /// The views (any subset of cameras, any order; the controller uses those it is
    /// configured with).
    pub views: Vec<View>,
    /// Ego measurements.
    pub ego: EgoState,
    /// Navigation.
    pub navigation: Navigation,
    /// Surroundings.
    pub surroundings: Surroundings,
}

impl Observation {
    /// The view of `camera`, if present.
    pub fn view(&self, camera: CameraId) -> Option<&View> {
        self.views.iter().find(|v| v.camera == camera)
    }

    /// Checks sizes, finiteness and uniqueness of the views.
    pub fn validate(&self) -> Result<(), RcoError> {
        let bad = |reason: String| RcoError::Observation {
            tick: self.tick,
            reason,
        };
        for (i, v) in self.views.iter().enumerate() {
            if self.views[..i].iter().any(|w| w.camera == v.camera) {
                return Err(bad(format!("view {} appears twice", v.camera.short())));
            }
            v.check().map_err(bad)?;
        }
        let e = &self.ego;
        if ![e.speed_mps, e.accel_x_mps2, e.yaw_rate_rps]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(bad("ego measurements must be finite".into()));
        }
        if let Some(d) = e.follow_distance_m
            && (!d.is_finite() || d < 0.0)
        {
            return Err(bad(format!(
                "follow_distance_m {d} must be finite and >= 0"
            )));
        }
        let n = &self.navigation;
        if !n.target_x_m.is_finite() || !n.target_y_m.is_finite() {
            return Err(bad("the navigation target point must be finite".into()));
        }
        Ok(())
    }

    /// Whether any view has a deficit region.
    pub fn has_deficit(&self) -> bool {
        self.views.iter().any(|v| !v.deficits.is_empty())
    }
}

/// `Option<Arc<[u8]>>` as an optional base64 string.
mod rgb_base64 {
    use std::sync::Arc;

    use base64::Engine as _;
    use base64::engine::general_purpose::STANDARD;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &Option<Arc<[u8]>>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(bytes) => s.serialize_str(&STANDARD.encode(bytes)),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Arc<[u8]>>, D::Error> {
        let text: Option<String> = Option::deserialize(d)?;
        match text {
            None => Ok(None),
            Some(t) => STANDARD
                .decode(t.as_bytes())
                .map(|b| Some(Arc::from(b)))
                .map_err(serde::de::Error::custom),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::PixelBox;

    #[test]
    fn mask_regions_become_their_bounding_boxes() {
        #[rustfmt::skip]
        let mask: [u8; 7 * 5] = [
            0, 1, 1, 0, 0, 0, 0,
            0, 1, 0, 0, 0, 0, 1,
            0, 0, 0, 0, 0, 1, 0, // diagonal neighbours join (8-neighbourhood)
            1, 0, 0, 0, 1, 0, 0,
            1, 1, 0, 0, 0, 0, 0,
        ];
        let boxes = PixelBox::from_mask(&mask, 7, 5).expect("sizes fit");
        assert_eq!(
            boxes,
            vec![
                PixelBox::new(1.0, 0.0, 2.0, 2.0),
                PixelBox::new(4.0, 1.0, 3.0, 3.0),
                PixelBox::new(0.0, 3.0, 2.0, 2.0),
            ]
        );
        // A U shape is one region even though its arms meet only at the bottom.
        #[rustfmt::skip]
        let u: [u8; 4 * 3] = [
            1, 0, 0, 1,
            1, 0, 0, 1,
            1, 1, 1, 1,
        ];
        assert_eq!(
            PixelBox::from_mask(&u, 4, 3),
            Some(vec![PixelBox::new(0.0, 0.0, 4.0, 3.0)])
        );
        assert_eq!(PixelBox::from_mask(&[0; 12], 4, 3), Some(vec![]));
        assert_eq!(PixelBox::from_mask(&[0; 11], 4, 3), None);
    }
}
