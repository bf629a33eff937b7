//! The ego's dynamics: the kinematic bicycle model tuned for CARLA (DriveLM's PDM-Lite,
//! `pdm_lite/team_code/kinematic_bicycle_model.py`), stepped at 20 Hz.
//!
//! Per step `dt` with CARLA's control `(throttle, brake, steer)`:
//!
//! ```text
//! wheel = steering_gain · steer
//! slip  = atan(rear / (front + rear) · tan(wheel))
//! x    += v · cos(yaw − slip) · dt
//! y    += v · sin(yaw − slip) · dt
//! yaw  −= v / rear · sin(slip) · dt
//! v    += dt · (brake > 0 ? brake · brake_accel : throttle · throttle_accel),  v ≥ 0
//! ```
//!
//! Our world frame has `y` to the left and yaw positive to the left, CARLA's has `y` to the
//! right; CARLA's steer is positive to the right. Hence the signs: a positive steer turns the
//! car right (its yaw decreases). PDM-Lite brakes with a boolean; an analogue brake `b` here
//! gives `b · brake_accel` (so `b = 1` is the reference's braking), and braking wins over the
//! throttle as in the reference. There is no drag: with neither pedal the speed holds.

use serde::{Deserialize, Serialize};

use crate::SimError;

/// The model's constants (the reference's by default).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BicycleParams {
    /// Time step, s (1/20).
    pub dt_s: f64,
    /// Front wheel base, m (the fitted value is slightly negative).
    pub front_wheel_base_m: f64,
    /// Rear wheel base, m.
    pub rear_wheel_base_m: f64,
    /// Wheel angle per unit steer, rad.
    pub steering_gain: f64,
    /// Acceleration at full brake, m/s² (negative).
    pub brake_accel_mps2: f64,
    /// Acceleration per unit throttle, m/s².
    pub throttle_accel_mps2: f64,
}

impl Default for BicycleParams {
    fn default() -> Self {
        Self {
            dt_s: 1.0 / 20.0,
            front_wheel_base_m: -0.090_769_015,
            rear_wheel_base_m: 1.417_827_5,
            steering_gain: 0.368_483_36,
            brake_accel_mps2: -4.952_399,
            throttle_accel_mps2: 0.563_383_7,
        }
    }
}

impl BicycleParams {
    /// Checks the constants.
    pub fn validate(&self) -> Result<(), SimError> {
        let ok = self.dt_s.is_finite()
            && self.dt_s > 0.0
            && self.rear_wheel_base_m.is_finite()
            && self.rear_wheel_base_m > 0.0
            && (self.front_wheel_base_m + self.rear_wheel_base_m) > 0.0
            && self.steering_gain.is_finite()
            && self.brake_accel_mps2.is_finite()
            && self.brake_accel_mps2 < 0.0
            && self.throttle_accel_mps2.is_finite()
            && self.throttle_accel_mps2 >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(SimError::Params(
                "vehicle: the bicycle model's constants must be finite, dt and wheel bases > 0, brake acceleration < 0".into(),
            ))
        }
    }

    /// The curvature (1/m, left positive) a steady `steer` drives.
    pub fn curvature(&self, steer: f64) -> f64 {
        let slip = self.slip(steer);
        -slip.sin() / self.rear_wheel_base_m
    }

    /// The steer (clamped to `[−1, 1]`) that drives curvature `kappa` (1/m, left positive).
    pub fn steer_for_curvature(&self, kappa: f64) -> f64 {
        let s = (-kappa * self.rear_wheel_base_m).clamp(-0.999, 0.999);
        let slip = s.asin();
        let ratio = self.rear_wheel_base_m / (self.front_wheel_base_m + self.rear_wheel_base_m);
        let wheel = (slip.tan() / ratio).atan();
        (wheel / self.steering_gain).clamp(-1.0, 1.0)
    }

    fn slip(&self, steer: f64) -> f64 {
        let wheel = self.steering_gain * steer;
        let ratio = self.rear_wheel_base_m / (self.front_wheel_base_m + self.rear_wheel_base_m);
        (ratio * wheel.tan()).atan()
    }
}

/// CARLA's vehicle control.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleControl {
    /// Throttle, 0 ..= 1.
    pub throttle: f64,
    /// Brake, 0 ..= 1.
    pub brake: f64,
    /// Steer, −1 ..= 1, positive right.
    pub steer: f64,
}

impl VehicleControl {
    /// Every component clamped to its range (NaN becomes 0).
    pub fn clamped(self) -> Self {
        let c = |v: f64, lo: f64, hi: f64| if v.is_nan() { 0.0 } else { v.clamp(lo, hi) };
        Self {
            throttle: c(self.throttle, 0.0, 1.0),
            brake: c(self.brake, 0.0, 1.0),
            steer: c(self.steer, -1.0, 1.0),
        }
    }
}

/// The ego's state: the rear-axle centre, heading and speed.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleState {
    /// Position, world frame, m.
    pub x_m: f64,
    /// Position, world frame, m.
    pub y_m: f64,
    /// Heading, rad, left positive.
    pub yaw_rad: f64,
    /// Speed, m/s (≥ 0).
    pub speed_mps: f64,
}

impl VehicleState {
    /// Standing at `pos`, heading along `dir` (a route's pose).
    pub fn standing(pos: [f64; 2], dir: [f64; 2]) -> Self {
        Self {
            x_m: pos[0],
            y_m: pos[1],
            yaw_rad: dir[1].atan2(dir[0]),
            speed_mps: 0.0,
        }
    }

    /// The unit heading vector.
    pub fn heading(&self) -> [f64; 2] {
        [self.yaw_rad.cos(), self.yaw_rad.sin()]
    }

    /// A point `fwd` m ahead of and `left` m left of the rear axle.
    pub fn point(&self, fwd: f64, left: f64) -> [f64; 2] {
        let (s, c) = self.yaw_rad.sin_cos();
        [self.x_m + fwd * c - left * s, self.y_m + fwd * s + left * c]
    }
}

/// One step of the model.
pub fn step(p: &BicycleParams, s: &VehicleState, control: VehicleControl) -> VehicleState {
    let c = control.clamped();
    let dt = p.dt_s;
    let slip = p.slip(c.steer);
    let v = s.speed_mps;
    let x = s.x_m + v * (s.yaw_rad - slip).cos() * dt;
    let y = s.y_m + v * (s.yaw_rad - slip).sin() * dt;
    let yaw = wrap_angle(s.yaw_rad - v / p.rear_wheel_base_m * slip.sin() * dt);
    let accel = if c.brake > 0.0 {
        c.brake * p.brake_accel_mps2
    } else {
        c.throttle * p.throttle_accel_mps2
    };
    VehicleState {
        x_m: x,
        y_m: y,
        yaw_rad: yaw,
        speed_mps: (v + dt * accel).max(0.0),
    }
}

/// An angle wrapped to `(−π, π]`.
pub fn wrap_angle(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let mut a = a % tau;
    if a > std::f64::consts::PI {
        a -= tau;
    } else if a <= -std::f64::consts::PI {
        a += tau;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_constants() {
        let p = BicycleParams::default();
        assert_eq!(p.dt_s, 0.05);
        assert_eq!(p.front_wheel_base_m, -0.090769015);
        assert_eq!(p.rear_wheel_base_m, 1.4178275);
        assert_eq!(p.steering_gain, 0.36848336);
        assert_eq!(p.brake_accel_mps2, -4.952399);
        assert_eq!(p.throttle_accel_mps2, 0.5633837);
        assert!(p.validate().is_ok());
    }

    #[test]
    fn straight_throttle_brake_and_no_reverse() {
        let p = BicycleParams::default();
        let mut s = VehicleState {
            speed_mps: 5.0,
            ..Default::default()
        };
        s = step(
            &p,
            &s,
            VehicleControl {
                throttle: 1.0,
                brake: 0.0,
                steer: 0.0,
            },
        );
        // Position moves with the old speed, then the speed grows by dt·throttle_accel.
        assert!((s.x_m - 0.25).abs() < 1e-12 && s.y_m.abs() < 1e-12);
        assert!((s.speed_mps - (5.0 + 0.05 * 0.5633837)).abs() < 1e-12);
        // The brake wins over the throttle.
        let b = step(
            &p,
            &s,
            VehicleControl {
                throttle: 1.0,
                brake: 1.0,
                steer: 0.0,
            },
        );
        assert!((b.speed_mps - (s.speed_mps - 0.05 * 4.952399)).abs() < 1e-12);
        // Half brake: half the deceleration. Coasting holds the speed.
        let h = step(
            &p,
            &s,
            VehicleControl {
                throttle: 0.0,
                brake: 0.5,
                steer: 0.0,
            },
        );
        assert!((h.speed_mps - (s.speed_mps - 0.025 * 4.952399)).abs() < 1e-12);
        let c = step(&p, &s, VehicleControl::default());
        assert_eq!(c.speed_mps, s.speed_mps);
        // Never backwards.
        let mut slow = VehicleState {
            speed_mps: 0.1,
            ..Default::default()
        };
        slow = step(
            &p,
            &slow,
            VehicleControl {
                throttle: 0.0,
                brake: 1.0,
                steer: 0.0,
            },
        );
        assert_eq!(slow.speed_mps, 0.0);
    }

    #[test]
    fn positive_steer_turns_right_with_the_reference_slip() {
        let p = BicycleParams::default();
        let s0 = VehicleState {
            speed_mps: 4.0,
            ..Default::default()
        };
        let s1 = step(
            &p,
            &s0,
            VehicleControl {
                throttle: 0.0,
                brake: 0.0,
                steer: 0.5,
            },
        );
        let wheel: f64 = 0.36848336 * 0.5;
        let slip = (1.4178275 / (1.4178275 - 0.090769015) * wheel.tan()).atan();
        assert!((s1.yaw_rad + 4.0 / 1.4178275 * slip.sin() * 0.05).abs() < 1e-12);
        assert!(s1.y_m < 0.0, "moves to the right");
        // Steady state: the curvature helper agrees with the integration.
        let k = p.curvature(0.5);
        assert!(k < 0.0);
        assert!((p.steer_for_curvature(k) - 0.5).abs() < 1e-9);
        // Full lock: a radius of about 3.7 m.
        let r = 1.0 / p.curvature(1.0).abs();
        assert!((3.5..4.0).contains(&r), "{r}");
    }

    #[test]
    fn wrap_angle_range() {
        for k in -20..20 {
            let a = k as f64 * 0.9;
            let w = wrap_angle(a);
            assert!(w > -std::f64::consts::PI && w <= std::f64::consts::PI);
            assert!((w.sin() - a.sin()).abs() < 1e-9 && (w.cos() - a.cos()).abs() < 1e-9);
        }
    }
}
