//! Clips as a camera planner sees them: cameras and their calibration, ego history,
//! trajectories in the paper's convention, and the planner's decision vocabulary.
//!
//! Conventions (those of Alpamayo R1 and the PhysicalAI-AV data):
//!
//! - **Rig frame** at `t0`: origin at the rear-axle centre on the ground, `x` forward, `y` left,
//!   `z` up, metres, radians (yaw positive to the left).
//! - **Trajectory**: [`HORIZON`] = 64 waypoints at `t0 + 0.1 … t0 + 6.4 s` ([`DT_S`] = 0.1 s),
//!   `(x, y)` in the rig frame at `t0`.
//! - **Ego history**: [`HISTORY`] = 16 poses at `t0 − 1.5 … t0` (0.1 s apart), also in the rig
//!   frame at `t0` (so the last pose is the origin with yaw 0).
//! - **Cameras**: pinhole, no distortion, pixel `(u, v)` with `u` to the right and `v` down,
//!   pixel centres at half-integers (the pixel in column `i` covers `u ∈ [i, i + 1)`).
//!   A camera sits at `(x, y, z)` in the rig frame with a yaw (left positive) and a pitch (down
//!   positive); it has no roll.
//!
//! ```
//! use fogline_types::clip::{CameraCalib, CameraId};
//!
//! let cam = CameraCalib::standard(CameraId::FrontWide, 576, 320);
//! // A point 20 m ahead on the ground projects below the horizon, on the centre column.
//! let (u, v, dist) = cam.project([20.0 + cam.x_m, 0.0, 0.0]).unwrap();
//! assert!((u - 288.0).abs() < 1e-9 && v > 160.0);
//! // ...and the pixel maps back to the same ground point.
//! let g = cam.ground_point(u, v).unwrap();
//! assert!((g[0] - 20.0 - cam.x_m).abs() < 1e-9 && g[1].abs() < 1e-9);
//! assert!((dist - (20.0f64.powi(2) + cam.z_m.powi(2)).sqrt()).abs() < 1e-9);
//! ```

use serde::{Deserialize, Serialize};
use std::fmt;

/// Waypoints of a planned or ground-truth future.
pub const HORIZON: usize = 64;
/// Poses of the ego history.
pub const HISTORY: usize = 16;
/// Time between waypoints, poses and frames, seconds.
pub const DT_S: f64 = 0.1;
/// Frames per camera in a clip (at `t0 − 0.3, −0.2, −0.1, t0`).
pub const FRAMES: usize = 4;

/// The four cameras of Alpamayo R1, in its input order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CameraId {
    /// Cross-left, 120° field of view, looking left-forward.
    CrossLeft,
    /// Front wide, 120°.
    FrontWide,
    /// Cross-right, 120°, looking right-forward.
    CrossRight,
    /// Front telephoto, 30°.
    FrontTele,
}

impl CameraId {
    /// All four, in Alpamayo's order.
    pub const ALL: [CameraId; 4] = [
        CameraId::CrossLeft,
        CameraId::FrontWide,
        CameraId::CrossRight,
        CameraId::FrontTele,
    ];

    /// The PhysicalAI-AV camera name (`camera_front_wide_120fov`, …), also the directory name
    /// in the clip format.
    pub fn name(self) -> &'static str {
        match self {
            CameraId::CrossLeft => "camera_cross_left_120fov",
            CameraId::FrontWide => "camera_front_wide_120fov",
            CameraId::CrossRight => "camera_cross_right_120fov",
            CameraId::FrontTele => "camera_front_tele_30fov",
        }
    }

    /// Parses [`CameraId::name`] or the short snake-case form (`front_wide`).
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|c| c.name() == s || c.short() == s)
    }

    /// The short snake-case name (`cross_left`, `front_wide`, `cross_right`, `front_tele`).
    pub fn short(self) -> &'static str {
        match self {
            CameraId::CrossLeft => "cross_left",
            CameraId::FrontWide => "front_wide",
            CameraId::CrossRight => "cross_right",
            CameraId::FrontTele => "front_tele",
        }
    }

    /// Index in [`CameraId::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// Horizontal field of view of the standard rig, degrees.
    pub fn hfov_deg(self) -> f64 {
        match self {
            CameraId::FrontTele => 30.0,
            _ => 120.0,
        }
    }

    /// Yaw of the standard rig, radians (left positive).
    pub fn yaw_rad(self) -> f64 {
        match self {
            CameraId::CrossLeft => 60f64.to_radians(),
            CameraId::CrossRight => -(60f64.to_radians()),
            _ => 0.0,
        }
    }
}

impl fmt::Display for CameraId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A pinhole camera: intrinsics in pixels and its pose in the rig frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraCalib {
    /// Which camera.
    pub id: CameraId,
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Focal length along `u`, px.
    pub fx: f64,
    /// Focal length along `v`, px.
    pub fy: f64,
    /// Principal point `u`, px.
    pub cx: f64,
    /// Principal point `v`, px.
    pub cy: f64,
    /// Position in the rig frame, m.
    pub x_m: f64,
    /// Position in the rig frame, m.
    pub y_m: f64,
    /// Height above the ground, m.
    pub z_m: f64,
    /// Yaw, radians, left positive.
    pub yaw_rad: f64,
    /// Pitch, radians, down positive.
    pub pitch_rad: f64,
}

/// Height of the standard rig's cameras above the ground, m.
pub const CAMERA_HEIGHT_M: f64 = 1.6;
/// Forward offset of the standard rig's cameras from the rear axle, m.
pub const CAMERA_X_M: f64 = 1.8;

impl CameraCalib {
    /// The standard rig: all cameras at `(1.8, 0, 1.6)` m, level, square pixels, principal
    /// point at the image centre, yaw ±60° for the cross cameras.
    pub fn standard(id: CameraId, width: u32, height: u32) -> Self {
        let f = f64::from(width) / 2.0 / (id.hfov_deg().to_radians() / 2.0).tan();
        Self {
            id,
            width,
            height,
            fx: f,
            fy: f,
            cx: f64::from(width) / 2.0,
            cy: f64::from(height) / 2.0,
            x_m: CAMERA_X_M,
            y_m: 0.0,
            z_m: CAMERA_HEIGHT_M,
            yaw_rad: id.yaw_rad(),
            pitch_rad: 0.0,
        }
    }

    /// Camera axes in the rig frame: forward, right, down.
    pub fn axes(&self) -> [[f64; 3]; 3] {
        let (sy, cy) = self.yaw_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        [
            [cy * cp, sy * cp, -sp],
            [sy, -cy, 0.0],
            [-sp * cy, -sp * sy, -cp],
        ]
    }

    /// Projects a rig-frame point: `(u, v, distance)` with the Euclidean distance from the
    /// camera, or `None` behind the camera (depth along the axis ≤ 1 cm).
    pub fn project(&self, p: [f64; 3]) -> Option<(f64, f64, f64)> {
        self.project_with(&self.axes(), p)
    }

    /// [`CameraCalib::project`] with the camera's [`CameraCalib::axes`] computed once by the
    /// caller (projection is an inner loop of image readers; the axes cost a sine and a
    /// cosine of the yaw and the pitch).
    #[inline]
    pub fn project_with(&self, axes: &[[f64; 3]; 3], p: [f64; 3]) -> Option<(f64, f64, f64)> {
        let [f, r, d] = *axes;
        let q = [p[0] - self.x_m, p[1] - self.y_m, p[2] - self.z_m];
        let zc = dot(q, f);
        if zc <= 0.01 {
            return None;
        }
        let u = self.cx + self.fx * dot(q, r) / zc;
        let v = self.cy + self.fy * dot(q, d) / zc;
        Some((u, v, dot(q, q).sqrt()))
    }

    /// The (unnormalised) ray through pixel position `(u, v)`, in the rig frame, with unit
    /// component along the optical axis.
    pub fn ray(&self, u: f64, v: f64) -> [f64; 3] {
        let [f, r, d] = self.axes();
        let a = (u - self.cx) / self.fx;
        let b = (v - self.cy) / self.fy;
        [
            f[0] + a * r[0] + b * d[0],
            f[1] + a * r[1] + b * d[1],
            f[2] + a * r[2] + b * d[2],
        ]
    }

    /// The ground point (`z = 0`) seen at pixel position `(u, v)`, or `None` at or above the
    /// horizon.
    pub fn ground_point(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        let ray = self.ray(u, v);
        if ray[2] >= -1e-9 {
            return None;
        }
        let t = -self.z_m / ray[2];
        Some([self.x_m + t * ray[0], self.y_m + t * ray[1]])
    }

    /// Checks the calibration: positive size and focal lengths, finite values, camera above
    /// the ground.
    pub fn validate(&self) -> Result<(), String> {
        let vals = [
            self.fx,
            self.fy,
            self.cx,
            self.cy,
            self.x_m,
            self.y_m,
            self.z_m,
            self.yaw_rad,
            self.pitch_rad,
        ];
        if self.width == 0 || self.height == 0 {
            return Err(format!(
                "{}: image size {}x{} must be positive",
                self.id, self.width, self.height
            ));
        }
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(format!("{}: calibration values must be finite", self.id));
        }
        if self.fx <= 0.0 || self.fy <= 0.0 {
            return Err(format!("{}: focal lengths must be positive", self.id));
        }
        if self.z_m <= 0.0 {
            return Err(format!("{}: camera height z_m must be positive", self.id));
        }
        Ok(())
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// One pose of the ego history, in the rig frame at `t0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EgoPose {
    /// Time relative to `t0`, s (−1.5 … 0).
    pub t_s: f64,
    /// Position, m.
    pub x_m: f64,
    /// Position, m.
    pub y_m: f64,
    /// Heading, radians, left positive.
    pub yaw_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
}

/// A planned or ground-truth future: [`HORIZON`] waypoints `(x, y)` at `t0 + 0.1·(k+1)` s in the
/// rig frame at `t0`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// The waypoints, m.
    pub xy: Vec<[f64; 2]>,
}

impl Trajectory {
    /// Checks that there are [`HORIZON`] finite waypoints.
    pub fn validate(&self) -> Result<(), String> {
        if self.xy.len() != HORIZON {
            return Err(format!(
                "a trajectory has {HORIZON} waypoints, found {}",
                self.xy.len()
            ));
        }
        if let Some(i) = self
            .xy
            .iter()
            .position(|p| !p[0].is_finite() || !p[1].is_finite())
        {
            return Err(format!("waypoint {i} is not finite"));
        }
        Ok(())
    }

    /// Average displacement error: the mean over waypoints of the `xy` distance to `other`
    /// (both must have the same length).
    pub fn ade(&self, other: &Trajectory) -> f64 {
        let n = self.xy.len().min(other.xy.len()).max(1);
        self.xy
            .iter()
            .zip(&other.xy)
            .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
            .sum::<f64>()
            / n as f64
    }

    /// Final displacement error: the distance between the last waypoints.
    pub fn fde(&self, other: &Trajectory) -> f64 {
        match (self.xy.last(), other.xy.last()) {
            (Some(a), Some(b)) => (a[0] - b[0]).hypot(a[1] - b[1]),
            _ => 0.0,
        }
    }

    /// L2 deviation: the Euclidean norm of the stacked `xy` differences.
    pub fn l2(&self, other: &Trajectory) -> f64 {
        self.xy
            .iter()
            .zip(&other.xy)
            .map(|(a, b)| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

/// What a planner decided, the shared vocabulary of the expert and the reference planner
/// (decision agreement compares these).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Decision {
    /// Keep the lane at the current speed.
    KeepLane,
    /// Follow the lead vehicle at its speed.
    FollowLead,
    /// Slow down behind a braking lead vehicle.
    SlowForLead,
    /// Shift right within the lane to clear an obstacle on the left.
    NudgeRight,
    /// Change to the left lane to overtake a slower vehicle.
    PassLeft,
    /// Turn right at the junction ahead.
    TurnRight,
    /// Stop at the line of a stop sign.
    StopForSign,
    /// Stop at the line of a red light.
    StopForRedLight,
    /// Proceed through the junction on green.
    ProceedOnGreen,
    /// Stop for a pedestrian or cyclist crossing the lane ahead.
    YieldToCrossing,
}

impl Decision {
    /// Every decision.
    pub const ALL: [Decision; 10] = [
        Decision::KeepLane,
        Decision::FollowLead,
        Decision::SlowForLead,
        Decision::NudgeRight,
        Decision::PassLeft,
        Decision::TurnRight,
        Decision::StopForSign,
        Decision::StopForRedLight,
        Decision::ProceedOnGreen,
        Decision::YieldToCrossing,
    ];

    /// The snake-case name (`keep_lane`, …).
    pub fn name(self) -> &'static str {
        match self {
            Decision::KeepLane => "keep_lane",
            Decision::FollowLead => "follow_lead",
            Decision::SlowForLead => "slow_for_lead",
            Decision::NudgeRight => "nudge_right",
            Decision::PassLeft => "pass_left",
            Decision::TurnRight => "turn_right",
            Decision::StopForSign => "stop_for_sign",
            Decision::StopForRedLight => "stop_for_red_light",
            Decision::ProceedOnGreen => "proceed_on_green",
            Decision::YieldToCrossing => "yield_to_crossing",
        }
    }

    /// Parses [`Decision::name`].
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|d| d.name() == s)
    }
}

impl fmt::Display for Decision {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The frames of one camera, oldest first (`t0 − 0.3 … t0`), each RGB8 row-major,
/// `width × height × 3` bytes.
#[derive(Debug, Clone)]
pub struct CameraInput<'a> {
    /// The camera.
    pub calib: CameraCalib,
    /// The frames, oldest first.
    pub frames: Vec<&'a [u8]>,
}

/// Everything a camera planner gets: the cameras' frames and the ego history.
#[derive(Debug, Clone)]
pub struct PlannerInput<'a> {
    /// One entry per camera (any subset of the rig, any order).
    pub cameras: Vec<CameraInput<'a>>,
    /// The ego history, oldest first, ending at `t0`.
    pub ego_history: &'a [EgoPose],
}

/// What a planner answers: a trajectory and, when it gives one, an explanation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannerOutput {
    /// The planned future.
    pub trajectory: Trajectory,
    /// The Chain-of-Causation explanation, one sentence.
    pub explanation: String,
    /// The planner's decision, when it states one.
    pub decision: Option<Decision>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cross_cameras_look_sideways() {
        let left = CameraCalib::standard(CameraId::CrossLeft, 576, 320);
        // A point far to the left-front is in the left camera's view, on its centre column
        // when it lies on the camera's axis.
        let (s, c) = left.yaw_rad.sin_cos();
        let p = [left.x_m + 10.0 * c, 10.0 * s, left.z_m];
        let (u, v, d) = left.project(p).unwrap();
        assert!((u - 288.0).abs() < 1e-9 && (v - 160.0).abs() < 1e-9 && (d - 10.0).abs() < 1e-9);
        // A point to the right of the axis lands right of centre.
        let (u2, _, _) = left.project([left.x_m + 10.0, 0.0, 1.0]).unwrap();
        assert!(u2 > 288.0);
        assert!(left.project([left.x_m - 5.0, -5.0, 0.0]).is_none());
    }

    #[test]
    fn trajectory_metrics() {
        let a = Trajectory {
            xy: (0..HORIZON).map(|k| [k as f64, 0.0]).collect(),
        };
        let b = Trajectory {
            xy: (0..HORIZON).map(|k| [k as f64, 3.0]).collect(),
        };
        assert!((a.ade(&b) - 3.0).abs() < 1e-12);
        assert!((a.fde(&b) - 3.0).abs() < 1e-12);
        assert!((a.l2(&b) - (9.0 * HORIZON as f64).sqrt()).abs() < 1e-12);
        assert!(a.validate().is_ok());
        let short = Trajectory {
            xy: vec![[0.0, 0.0]],
        };
        assert!(short.validate().unwrap_err().contains("64"));
    }

    #[test]
    fn names_round_trip() {
        for c in CameraId::ALL {
            assert_eq!(CameraId::parse(c.name()), Some(c));
        }
        assert_eq!(CameraId::parse("front_tele"), Some(CameraId::FrontTele));
        for d in Decision::ALL {
            assert_eq!(Decision::parse(d.name()), Some(d));
        }
    }
}
