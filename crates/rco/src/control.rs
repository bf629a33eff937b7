//! Control mapping (appendix A.1): speed control → throttle and brake exactly as table 4,
//! steering from a PID controller towards the next navigation target point.
//!
//! Steering follows CARLA's convention: positive steers right. The ego frame has `y` to the
//! left, so the heading error `atan2(y, x)` of the target point is left positive and the
//! steer is its negated PID output.

use serde::{Deserialize, Serialize};

use crate::RcoError;
use crate::action::SpeedControl;

/// Vehicle control `A_t = [throttle, brake, steer] ∈ [0,1] × [0,1] × [−1,1]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Control {
    /// Throttle, 0 ..= 1.
    pub throttle: f64,
    /// Brake, 0 ..= 1.
    pub brake: f64,
    /// Steer, −1 ..= 1, positive right (CARLA).
    pub steer: f64,
}

impl Control {
    /// Clamps every component to its range (NaN becomes 0).
    pub fn clamped(self) -> Control {
        let c = |v: f64, lo: f64, hi: f64| if v.is_nan() { 0.0 } else { v.clamp(lo, hi) };
        Control {
            throttle: c(self.throttle, 0.0, 1.0),
            brake: c(self.brake, 0.0, 1.0),
            steer: c(self.steer, -1.0, 1.0),
        }
    }

    /// Whether every component is finite and in range.
    pub fn in_range(&self) -> bool {
        (0.0..=1.0).contains(&self.throttle)
            && (0.0..=1.0).contains(&self.brake)
            && (-1.0..=1.0).contains(&self.steer)
    }
}

/// Throttle and brake of one speed control.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pedals {
    /// Throttle, 0 ..= 1.
    pub throttle: f64,
    /// Brake, 0 ..= 1.
    pub brake: f64,
}

/// Table 4: the throttle and brake of `speed` given the previous tick's throttle
/// (`prev_throttle`, clamped to `[0, 1]` first).
///
/// | speed control | throttle | brake |
/// |---|---|---|
/// | constant speed | 0.7 | 0 |
/// | deceleration | max(0, throttle' − 0.2) | 0.2 |
/// | quick deceleration | max(0, throttle' − 0.4) | 0.4 |
/// | deceleration to zero | 0 | 0.8 |
/// | acceleration | min(1, throttle' + 0.2) | 0 |
/// | quick acceleration | min(1, throttle' + 0.4) | 0 |
pub fn pedals(speed: SpeedControl, prev_throttle: f64) -> Pedals {
    let prev = if prev_throttle.is_nan() {
        0.0
    } else {
        prev_throttle.clamp(0.0, 1.0)
    };
    let (throttle, brake) = match speed {
        SpeedControl::ConstantSpeed => (0.7, 0.0),
        SpeedControl::Deceleration => ((prev - 0.2).max(0.0), 0.2),
        SpeedControl::QuickDeceleration => ((prev - 0.4).max(0.0), 0.4),
        SpeedControl::DecelerationToZero => (0.0, 0.8),
        SpeedControl::Acceleration => ((prev + 0.2).min(1.0), 0.0),
        SpeedControl::QuickAcceleration => ((prev + 0.4).min(1.0), 0.0),
    };
    Pedals { throttle, brake }
}

/// Gains of the steering PID (on the heading error in radians).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PidParams {
    /// Proportional gain, steer per radian.
    pub kp: f64,
    /// Integral gain, steer per radian-second.
    pub ki: f64,
    /// Derivative gain, steer per radian/second.
    pub kd: f64,
    /// Bound of the integral term's state, radian-seconds (anti-windup).
    pub integral_limit: f64,
}

impl Default for PidParams {
    fn default() -> Self {
        Self {
            kp: 1.0,
            ki: 0.05,
            kd: 0.1,
            integral_limit: 1.0,
        }
    }
}

impl PidParams {
    /// Checks the gains: finite and non-negative.
    pub fn validate(&self) -> Result<(), RcoError> {
        let ok = [self.kp, self.ki, self.kd, self.integral_limit]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0);
        if ok {
            Ok(())
        } else {
            Err(RcoError::Params(
                "steer PID gains must be finite and >= 0".into(),
            ))
        }
    }
}

/// A PID controller on the heading error towards the navigation target point.
#[derive(Debug, Clone, PartialEq)]
pub struct SteerPid {
    params: PidParams,
    integral: f64,
    prev_error: Option<f64>,
}

impl SteerPid {
    /// A controller at rest.
    pub fn new(params: PidParams) -> Self {
        Self {
            params,
            integral: 0.0,
            prev_error: None,
        }
    }

    /// The heading error of the target point `(x, y)` (ego frame), radians, left positive;
    /// 0 for the origin or a non-finite point.
    pub fn heading_error(target_x_m: f64, target_y_m: f64) -> f64 {
        let e = target_y_m.atan2(target_x_m);
        if e.is_finite() { e } else { 0.0 }
    }

    /// The steer (positive right, in `[−1, 1]`) after `dt_s` seconds towards the target.
    pub fn step(&mut self, target_x_m: f64, target_y_m: f64, dt_s: f64) -> f64 {
        let e = Self::heading_error(target_x_m, target_y_m);
        let lim = self.params.integral_limit;
        self.integral = (self.integral + e * dt_s).clamp(-lim, lim);
        let de = match self.prev_error {
            Some(p) if dt_s > 0.0 => (e - p) / dt_s,
            _ => 0.0,
        };
        self.prev_error = Some(e);
        let u = self.params.kp * e + self.params.ki * self.integral + self.params.kd * de;
        if u.is_finite() {
            // `0.0 − u` rather than `−u`: no negative zero.
            (0.0 - u).clamp(-1.0, 1.0)
        } else {
            0.0
        }
    }

    /// Forgets the integral and the previous error.
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.prev_error = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_4_row_by_row() {
        let cases = [
            (SpeedControl::ConstantSpeed, 0.3, 0.7, 0.0),
            (SpeedControl::Deceleration, 0.5, 0.3, 0.2),
            (SpeedControl::Deceleration, 0.1, 0.0, 0.2),
            (SpeedControl::QuickDeceleration, 0.7, 0.3, 0.4),
            (SpeedControl::QuickDeceleration, 0.2, 0.0, 0.4),
            (SpeedControl::DecelerationToZero, 0.9, 0.0, 0.8),
            (SpeedControl::Acceleration, 0.5, 0.7, 0.0),
            (SpeedControl::Acceleration, 0.9, 1.0, 0.0),
            (SpeedControl::QuickAcceleration, 0.5, 0.9, 0.0),
            (SpeedControl::QuickAcceleration, 0.7, 1.0, 0.0),
        ];
        for (sc, prev, t, b) in cases {
            let p = pedals(sc, prev);
            assert!(
                (p.throttle - t).abs() < 1e-12 && (p.brake - b).abs() < 1e-12,
                "{sc:?} after {prev}: {p:?}"
            );
        }
    }

    #[test]
    fn pid_steers_towards_the_target() {
        let mut pid = SteerPid::new(PidParams::default());
        // Target to the left: steer left (negative in CARLA's convention).
        assert!(pid.step(10.0, 3.0, 0.1) < 0.0);
        pid.reset();
        assert!(pid.step(10.0, -3.0, 0.1) > 0.0);
        pid.reset();
        assert_eq!(pid.step(10.0, 0.0, 0.1), 0.0);
        // Behind and to the side saturates.
        pid.reset();
        assert_eq!(pid.step(-5.0, 1.0, 0.1), -1.0);
    }
}
