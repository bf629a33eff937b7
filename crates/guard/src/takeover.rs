//! The guard's own answer: the RCO's command under a frame-wide deficit, or a safe stop,
//! integrated with a kinematic bicycle into a trajectory.
//!
//! Under global degradation (noise, darkness, fog) no region of the frame is lost more than
//! another, so the monitored view is handed to the RCO as **one deficit region covering the
//! whole frame**, with no detected objects. The RCO's rules backend then infers a possible
//! hidden hazard ahead, chooses `stop-observe-move`, decelerates to a stop, waits and moves
//! on slowly only when its move trigger holds (measured in
//! `r20_a_frame_wide_deficit_stops_and_holds` and in `docs/monitor.md`). The
//! degraded axis sets the surroundings the RCO is told (`fog` → fog, `darken` → night).
//!
//! The command `[throttle, brake, steer]` is held over the horizon and integrated with a
//! kinematic bicycle at `dt_s`: `a = throttle·max_accel − brake·max_decel` (speed clamped at
//! 0), `ω = −v·tan(steer·max_steer)/wheelbase` (CARLA's steer is positive to the right).

use fogline_rco::{
    Control, Daylight, EgoState, NavDirection, Navigation, Observation, PixelBox, Rco,
    RoadGeometry, RoadLayout, Surroundings, TrafficEnv, View, Weather,
};
use fogline_types::clip::CameraId;
use serde::{Deserialize, Serialize};

use crate::GuardError;

/// The vehicle model and horizon of the guard's answers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleParams {
    /// Acceleration at full throttle, m/s².
    pub max_accel_mps2: f64,
    /// Deceleration at full brake, m/s².
    pub max_decel_mps2: f64,
    /// The deceleration of a safe stop, m/s².
    pub safe_stop_decel_mps2: f64,
    /// Wheelbase, m.
    pub wheelbase_m: f64,
    /// Road-wheel angle at full steer, rad.
    pub max_steer_rad: f64,
    /// Horizon of the answer, s.
    pub horizon_s: f64,
    /// Time step of the answer's poses, s.
    pub dt_s: f64,
}

impl Default for VehicleParams {
    fn default() -> Self {
        Self {
            max_accel_mps2: 3.0,
            max_decel_mps2: 8.0,
            safe_stop_decel_mps2: 3.0,
            wheelbase_m: 2.9,
            max_steer_rad: 0.6,
            horizon_s: 6.4,
            dt_s: 0.1,
        }
    }
}

impl VehicleParams {
    /// Checks that every number is finite and positive, and the horizon holds a step.
    pub fn validate(&self) -> Result<(), GuardError> {
        let all = [
            self.max_accel_mps2,
            self.max_decel_mps2,
            self.safe_stop_decel_mps2,
            self.wheelbase_m,
            self.max_steer_rad,
            self.horizon_s,
            self.dt_s,
        ];
        if !all.iter().all(|v| v.is_finite() && *v > 0.0) || self.horizon_s < self.dt_s {
            return Err(GuardError::Params {
                what: "vehicle",
                expected: "positive finite numbers, horizon_s at least dt_s".into(),
            });
        }
        Ok(())
    }
}

/// The ego as the guard knows it at a `drive` call.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EgoNow {
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Longitudinal acceleration, m/s².
    pub accel_x_mps2: f64,
    /// Yaw rate, rad/s (left positive).
    pub yaw_rate_rps: f64,
}

/// What the guard answered in the driver's place (part of its log record).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TakeoverAnswer {
    /// `override` (the RCO) or `safe_stop`.
    pub kind: String,
    /// The RCO's action (`behaviour/speed`), or `stop/safe_stop`.
    pub action: String,
    /// The RCO's strategy in force (`move`, `stop-observe-move`), if any.
    pub strategy: Option<String>,
    /// The command held over the horizon.
    pub throttle: f64,
    /// Brake, 0–1.
    pub brake: f64,
    /// Steer, −1–1, positive right.
    pub steer: f64,
    /// Speed at the end of the horizon, m/s.
    pub end_speed_mps: f64,
    /// The trajectory, rig frame at the call (x forward, y left, m), one point per `dt_s`.
    #[serde(skip)]
    pub xy_yaw: Vec<[f64; 3]>,
}

/// Integrates `control` from the ego's state over the horizon: points `(x, y, yaw)` at
/// `dt_s, 2·dt_s, …` in the rig frame at the call, and the final speed.
pub fn integrate(control: &Control, ego: &EgoNow, v: &VehicleParams) -> (Vec<[f64; 3]>, f64) {
    let c = control.clamped();
    let accel = c.throttle * v.max_accel_mps2 - c.brake * v.max_decel_mps2;
    let n = (v.horizon_s / v.dt_s).round() as usize;
    let (mut x, mut y, mut yaw, mut speed) = (0.0, 0.0, 0.0, ego.speed_mps.max(0.0));
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let next = (speed + accel * v.dt_s).max(0.0);
        let mean = 0.5 * (speed + next);
        let omega = -mean * (c.steer * v.max_steer_rad).tan() / v.wheelbase_m;
        let mid = yaw + 0.5 * omega * v.dt_s;
        x += mean * mid.cos() * v.dt_s;
        y += mean * mid.sin() * v.dt_s;
        yaw += omega * v.dt_s;
        speed = next;
        out.push([x, y, yaw]);
    }
    (out, speed)
}

/// A safe stop: full stop at `safe_stop_decel_mps2` along the current heading.
pub fn safe_stop(ego: &EgoNow, v: &VehicleParams) -> TakeoverAnswer {
    let brake = (v.safe_stop_decel_mps2 / v.max_decel_mps2).min(1.0);
    let control = Control {
        throttle: 0.0,
        brake,
        steer: 0.0,
    };
    let (xy_yaw, end) = integrate(&control, ego, v);
    TakeoverAnswer {
        kind: "safe_stop".into(),
        action: "stop/safe_stop".into(),
        strategy: None,
        throttle: 0.0,
        brake,
        steer: 0.0,
        end_speed_mps: end,
        xy_yaw,
    }
}

/// The RCO's observation of one `drive` call under global degradation: the monitored view
/// (`width × height`) as one frame-wide deficit, the ego, the route's next target point
/// (rig frame; 20 m ahead when the route is unknown) and the degraded axes.
pub fn observation(
    tick: u64,
    width: u32,
    height: u32,
    ego: &EgoNow,
    target_xy_m: Option<[f64; 2]>,
    degraded_axes: &[String],
) -> Observation {
    let mut view = View::new(CameraId::FrontWide, width.max(1), height.max(1));
    view.deficits = vec![PixelBox::new(
        0.0,
        0.0,
        f64::from(width.max(1)),
        f64::from(height.max(1)),
    )];
    let [tx, ty] = target_xy_m.unwrap_or([20.0, 0.0]);
    let has = |a: &str| degraded_axes.iter().any(|d| d == a);
    Observation {
        tick,
        views: vec![view],
        ego: EgoState {
            speed_mps: ego.speed_mps,
            accel_x_mps2: ego.accel_x_mps2,
            yaw_rate_rps: ego.yaw_rate_rps,
            follow_distance_m: None,
        },
        navigation: Navigation {
            direction: NavDirection::FollowLane,
            target_x_m: tx,
            target_y_m: ty,
            road: RoadGeometry {
                layout: RoadLayout::Straight,
                two_way: true,
                lanes: 1,
            },
        },
        surroundings: Surroundings {
            weather: if has("fog") {
                Weather::Fog
            } else {
                Weather::Clear
            },
            daylight: if has("darken") {
                Daylight::Night
            } else {
                Daylight::Day
            },
            traffic_env: TrafficEnv::Urban,
            traffic_density: 0,
        },
    }
}

/// One step of the RCO on `obs`, integrated into the guard's answer.
pub fn rco_answer(
    rco: &mut Rco,
    obs: &Observation,
    ego: &EgoNow,
    v: &VehicleParams,
) -> TakeoverAnswer {
    let d = rco.step(obs);
    let control = d.control.clamped();
    let (xy_yaw, end) = integrate(&control, ego, v);
    TakeoverAnswer {
        kind: "override".into(),
        action: d.action.to_string(),
        strategy: d.strategy.map(|s| s.name().to_string()),
        throttle: control.throttle,
        brake: control.brake,
        steer: control.steer,
        end_speed_mps: end,
        xy_yaw,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::print_stdout)]
    use super::*;
    use fogline_rco::RcoParams;

    #[test]
    fn the_bicycle_stops_and_turns_the_right_way() {
        let v = VehicleParams::default();
        let ego = EgoNow {
            speed_mps: 6.0,
            ..EgoNow::default()
        };
        let (pts, end) = integrate(
            &Control {
                throttle: 0.0,
                brake: 1.0,
                steer: 0.0,
            },
            &ego,
            &v,
        );
        assert_eq!(pts.len(), 64);
        assert_eq!(end, 0.0);
        // v²/(2a) = 36/16 = 2.25 m, within a step's rounding.
        let last = pts[pts.len() - 1];
        assert!((last[0] - 2.25).abs() < 0.05 && last[1] == 0.0, "{last:?}");
        let (pts, _) = integrate(
            &Control {
                throttle: 0.2,
                brake: 0.0,
                steer: 0.3,
            },
            &ego,
            &v,
        );
        assert!(
            pts[63][1] < -1.0 && pts[63][2] < 0.0,
            "steer right: {:?}",
            pts[63]
        );
        let s = safe_stop(&ego, &v);
        assert_eq!((s.kind.as_str(), s.end_speed_mps), ("safe_stop", 0.0));
        assert!(
            VehicleParams {
                dt_s: 0.0,
                ..v.clone()
            }
            .validate()
            .is_err()
        );
    }

    /// What the RCO does under a frame-wide deficit, driven closed-loop by its own answers
    /// at 10 Hz from 8 m/s: it stops (stop-observe-move) and never commands beyond its
    /// limits. The printed table is the measurement `docs/monitor.md` quotes.
    #[test]
    fn r20_a_frame_wide_deficit_stops_and_holds() {
        let v = VehicleParams::default();
        let mut rco = Rco::with_rules(RcoParams::default()).unwrap();
        let mut ego = EgoNow {
            speed_mps: 8.0,
            ..EgoNow::default()
        };
        let mut travelled = 0.0;
        let mut stopped_at = None;
        let mut rows = Vec::new();
        for tick in 0..200u64 {
            let obs = observation(tick, 576, 320, &ego, None, &["fog".to_string()]);
            let a = rco_answer(&mut rco, &obs, &ego, &v);
            assert!(a.throttle >= 0.0 && a.brake <= 1.0 && a.steer.abs() <= 1.0);
            // Follow the answer for one step (its first point).
            let first = a.xy_yaw[0];
            travelled += first[0].hypot(first[1]);
            let accel = a.throttle * v.max_accel_mps2 - a.brake * v.max_decel_mps2;
            let next = (ego.speed_mps + accel * v.dt_s).max(0.0);
            ego = EgoNow {
                speed_mps: next,
                accel_x_mps2: accel,
                yaw_rate_rps: 0.0,
            };
            if stopped_at.is_none() && next < 0.05 {
                stopped_at = Some((tick, travelled));
            }
            if tick % 20 == 0 || tick == 199 {
                rows.push(format!(
                    "t {:>4.1} s  v {:>5.2} m/s  {:<32} {:<18} thr {:.2} brk {:.2}",
                    tick as f64 * v.dt_s,
                    next,
                    a.action,
                    a.strategy.as_deref().unwrap_or("-"),
                    a.throttle,
                    a.brake
                ));
            }
        }
        println!("frame-wide deficit (fog), from 8 m/s, 20 s at 10 Hz:");
        for r in &rows {
            println!("  {r}");
        }
        let (t, d) = stopped_at.expect("the RCO never stopped under a frame-wide deficit");
        println!(
            "stopped after {:.1} s and {d:.1} m; {travelled:.1} m in 20 s",
            t as f64 * v.dt_s
        );
        assert!(d < 20.0, "stopped only after {d} m");
    }
}
