//! The safety constraint module (section 4, appendix A.2): the constraints
//! `SC_t = {v_max, d_min, ac_max, de_max, ψ_max, d_brake}` (equation 6, produced by the
//! backend from the driving context) and the transformations of equations 7–9 (table 5)
//! applied to the verified action's control.
//!
//! | constraint | trigger | transformation |
//! |---|---|---|
//! | max speed | `v ≥ v_max` | `throttle − Δ_throttle` |
//! | min following distance | `d_follow < d_min` | `throttle − Δ_throttle` |
//! | max acceleration | `a_x > ac_max` | `throttle − Δ_throttle · (a_x − ac_max)` |
//! | max deceleration | `a_x < −de_max` | `brake − Δ_brake · (−de_max − a_x)` |
//! | max yaw rate | `|ω_z| > ψ_max` | `steer · ψ_max / |ω_z|` |
//! | min braking distance | `v² / (2 de_max) > d_brake` | `brake + Δ_brake` |
//!
//! The terms add up (equations 7 and 8), and the result is clamped to the control ranges
//! (equation 10's `A_t` must be a valid control). `d_min` is the answer's time gap times the
//! speed plus a standstill gap (the paper's prompt asks the following distance in seconds).
//! The deceleration row follows table 5: equation 8 prints `(a_x − de_max)`, which would
//! *add* brake only through a double negative; the table's `(−de_max − a_x)` is the excess
//! deceleration and is what is implemented.

use serde::{Deserialize, Serialize};

use crate::RcoError;
use crate::control::Control;
use crate::observation::{EgoState, TrafficEnv};

/// The safety constraints `SC_t`, in the units of the paper's prompt.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SafetyConstraints {
    /// Max speed limit `v_max`, km/h.
    pub max_speed_kmh: f64,
    /// Minimum following distance, seconds of time gap (`d_min = gap · v + standstill`).
    pub min_following_distance_s: f64,
    /// Max acceleration rate limit `ac_max`, m/s².
    pub max_acceleration_mps2: f64,
    /// Max deceleration rate limit `de_max`, m/s².
    pub max_deceleration_mps2: f64,
    /// Max yaw rate limit `ψ_max`, degrees per second.
    pub max_yaw_rate_dps: f64,
    /// Minimum safe braking distance `d_brake`, m.
    pub min_braking_distance_m: f64,
}

/// Accepted range of each constraint (answers outside are rejected).
pub const RANGES: [(&str, f64, f64); 6] = [
    ("max_speed_kmh", 5.0, 130.0),
    ("min_following_distance_s", 0.5, 10.0),
    ("max_acceleration_mps2", 0.3, 6.0),
    ("max_deceleration_mps2", 0.5, 12.0),
    ("max_yaw_rate_dps", 1.0, 90.0),
    ("min_braking_distance_m", 1.0, 300.0),
];

impl SafetyConstraints {
    /// The conservative set used when no valid answer is available: 30 km/h, 3 s gap,
    /// 1.0 m/s², 3.0 m/s², 10 °/s, 15 m.
    pub fn conservative() -> Self {
        Self {
            max_speed_kmh: 30.0,
            min_following_distance_s: 3.0,
            max_acceleration_mps2: 1.0,
            max_deceleration_mps2: 3.0,
            max_yaw_rate_dps: 10.0,
            min_braking_distance_m: 15.0,
        }
    }

    /// The values in the order of [`RANGES`].
    pub fn values(&self) -> [f64; 6] {
        [
            self.max_speed_kmh,
            self.min_following_distance_s,
            self.max_acceleration_mps2,
            self.max_deceleration_mps2,
            self.max_yaw_rate_dps,
            self.min_braking_distance_m,
        ]
    }

    /// Checks every value is finite and within [`RANGES`]; the error names the field.
    pub fn validate(&self) -> Result<(), String> {
        for ((name, lo, hi), v) in RANGES.iter().zip(self.values()) {
            if !v.is_finite() {
                return Err(format!("{name} is not finite"));
            }
            if v < *lo || v > *hi {
                return Err(format!("{name} = {v} is outside [{lo}, {hi}]"));
            }
        }
        Ok(())
    }

    /// `v_max`, m/s.
    pub fn max_speed_mps(&self) -> f64 {
        self.max_speed_kmh / 3.6
    }

    /// `d_min` at `speed_mps`, m: the time gap times the speed plus `standstill_gap_m`.
    pub fn min_following_distance_m(&self, speed_mps: f64, standstill_gap_m: f64) -> f64 {
        self.min_following_distance_s * speed_mps.max(0.0) + standstill_gap_m
    }
}

/// fogline's hard limits: the envelope every set of safety constraints is held inside,
/// whoever produced it. An answer can tighten them, never loosen them: the model that plans
/// is not trusted to set the bounds that check its plans (docs/security.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct HardLimits {
    /// The road speed limit of each traffic environment, km/h: urban, suburban, rural,
    /// highway (CARLA's town limits; the rules backend's base speeds).
    pub speed_limit_kmh: [f64; 4],
    /// The shortest following time gap an answer may set, s.
    pub min_gap_s: f64,
    /// The highest acceleration limit an answer may set, m/s².
    pub max_acceleration_mps2: f64,
    /// The deceleration limit `de_max` an answer may set lies in this range, m/s²: below it
    /// a model would take braking authority away (table 5's deceleration row lowers the
    /// brake past `de_max`), above it it would assume braking the car does not have.
    pub deceleration_mps2: [f64; 2],
    /// The highest yaw-rate limit an answer may set, °/s.
    pub max_yaw_rate_dps: f64,
}

impl Default for HardLimits {
    fn default() -> Self {
        Self {
            speed_limit_kmh: [50.0, 60.0, 80.0, 100.0],
            min_gap_s: 1.0,
            max_acceleration_mps2: 2.5,
            deceleration_mps2: [2.5, 8.0],
            max_yaw_rate_dps: 30.0,
        }
    }
}

impl HardLimits {
    /// The road speed limit in `env`, km/h.
    pub fn speed_limit(&self, env: TrafficEnv) -> f64 {
        self.speed_limit_kmh[match env {
            TrafficEnv::Urban => 0,
            TrafficEnv::Suburban => 1,
            TrafficEnv::Rural => 2,
            TrafficEnv::Highway => 3,
        }]
    }

    /// Checks the limits are physically meaningful.
    pub fn validate(&self) -> Result<(), RcoError> {
        let [lo, hi] = self.deceleration_mps2;
        let ok = self
            .speed_limit_kmh
            .iter()
            .chain([
                &self.min_gap_s,
                &self.max_acceleration_mps2,
                &lo,
                &hi,
                &self.max_yaw_rate_dps,
            ])
            .all(|v| v.is_finite() && *v > 0.0)
            && lo <= hi;
        if ok {
            Ok(())
        } else {
            Err(RcoError::Params(format!(
                "safety.hard: every limit must be finite and > 0, and the deceleration range \
                 ordered: {self:?}"
            )))
        }
    }
}

impl SafetyConstraints {
    /// These constraints held inside `hard` in traffic environment `env`: each one tightened
    /// to the hard limit where it is looser (the speed to the road limit, the gap up to the
    /// minimum gap, the acceleration and yaw-rate limits down, the deceleration limit into
    /// its range, the braking distance down to what the speed and deceleration kept imply),
    /// and the names of those that were changed.
    pub fn within(&self, hard: &HardLimits, env: TrafficEnv) -> (Self, Vec<&'static str>) {
        let mut changed = Vec::new();
        let mut pick = |name: &'static str, v: f64, bounded: f64| {
            if bounded != v {
                changed.push(name);
            }
            bounded
        };
        let [de_lo, de_hi] = hard.deceleration_mps2;
        let max_speed_kmh = pick(
            "max_speed_kmh",
            self.max_speed_kmh,
            self.max_speed_kmh.min(hard.speed_limit(env)),
        );
        let max_deceleration_mps2 = pick(
            "max_deceleration_mps2",
            self.max_deceleration_mps2,
            self.max_deceleration_mps2.clamp(de_lo, de_hi),
        );
        // The braking distance the kept speed and deceleration need, in the rules
        // backend's 5 m steps (at least 5 m): a longer one would trigger braking later.
        let v = max_speed_kmh / 3.6;
        let d_need = ((v * v / (2.0 * max_deceleration_mps2)) / 5.0).ceil() * 5.0;
        let out = Self {
            max_speed_kmh,
            min_following_distance_s: pick(
                "min_following_distance_s",
                self.min_following_distance_s,
                self.min_following_distance_s.max(hard.min_gap_s),
            ),
            max_acceleration_mps2: pick(
                "max_acceleration_mps2",
                self.max_acceleration_mps2,
                self.max_acceleration_mps2.min(hard.max_acceleration_mps2),
            ),
            max_deceleration_mps2,
            max_yaw_rate_dps: pick(
                "max_yaw_rate_dps",
                self.max_yaw_rate_dps,
                self.max_yaw_rate_dps.min(hard.max_yaw_rate_dps),
            ),
            min_braking_distance_m: pick(
                "min_braking_distance_m",
                self.min_braking_distance_m,
                self.min_braking_distance_m.min(d_need.max(5.0)),
            ),
        };
        (out, changed)
    }
}

/// Settings of the safety constraint module.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SafetyParams {
    /// `Δ_throttle`, the throttle transformation factor.
    pub delta_throttle: f64,
    /// `Δ_brake`, the brake transformation factor.
    pub delta_brake: f64,
    /// Gap added to `gap · v` for `d_min`, m.
    pub standstill_gap_m: f64,
    /// Ticks between two constraint refreshes (the constraints change slowly).
    pub refresh_ticks: u64,
    /// The envelope every answer's constraints are held inside ([`HardLimits`]).
    pub hard: HardLimits,
}

impl Default for SafetyParams {
    fn default() -> Self {
        Self {
            delta_throttle: 0.2,
            delta_brake: 0.2,
            standstill_gap_m: 2.0,
            refresh_ticks: 50,
            hard: HardLimits::default(),
        }
    }
}

impl SafetyParams {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), RcoError> {
        for (name, v) in [
            ("delta_throttle", self.delta_throttle),
            ("delta_brake", self.delta_brake),
            ("standstill_gap_m", self.standstill_gap_m),
        ] {
            if !v.is_finite() || v < 0.0 {
                return Err(RcoError::Params(format!(
                    "safety.{name} {v} must be finite and >= 0"
                )));
            }
        }
        if self.refresh_ticks == 0 {
            return Err(RcoError::Params("safety.refresh_ticks must be >= 1".into()));
        }
        self.hard.validate()
    }
}

/// Which constraints triggered at this tick (table 5's trigger conditions).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Triggers {
    /// `v ≥ v_max`.
    pub max_speed: bool,
    /// `d_follow < d_min`.
    pub min_following_distance: bool,
    /// `a_x > ac_max`.
    pub max_acceleration: bool,
    /// `a_x < −de_max`.
    pub max_deceleration: bool,
    /// `|ω_z| > ψ_max`.
    pub max_yaw_rate: bool,
    /// `v² / (2 de_max) > d_brake`.
    pub min_braking_distance: bool,
}

impl Triggers {
    /// Whether any constraint triggered.
    pub fn any(&self) -> bool {
        self.max_speed
            || self.min_following_distance
            || self.max_acceleration
            || self.max_deceleration
            || self.max_yaw_rate
            || self.min_braking_distance
    }
}

/// The triggers of `sc` for the measurements `ego`.
pub fn triggers(ego: &EgoState, sc: &SafetyConstraints, params: &SafetyParams) -> Triggers {
    let v = ego.speed_mps;
    let ax = ego.accel_x_mps2;
    let wz_dps = ego.yaw_rate_rps.abs().to_degrees();
    Triggers {
        max_speed: v >= sc.max_speed_mps(),
        min_following_distance: ego
            .follow_distance_m
            .is_some_and(|d| d < sc.min_following_distance_m(v, params.standstill_gap_m)),
        max_acceleration: ax > sc.max_acceleration_mps2,
        max_deceleration: ax < -sc.max_deceleration_mps2,
        max_yaw_rate: wz_dps > sc.max_yaw_rate_dps,
        min_braking_distance: v * v / (2.0 * sc.max_deceleration_mps2) > sc.min_braking_distance_m,
    }
}

/// Equations 7–10: the control after the safety constraints, and which ones triggered.
pub fn apply(
    control: Control,
    ego: &EgoState,
    sc: &SafetyConstraints,
    params: &SafetyParams,
) -> (Control, Triggers) {
    let t = triggers(ego, sc, params);
    let ax = ego.accel_x_mps2;
    let dt = params.delta_throttle;
    let db = params.delta_brake;
    let ind = |b: bool| if b { 1.0 } else { 0.0 };
    // Equation 7.
    let throttle = control.throttle
        - ind(t.max_speed) * dt
        - ind(t.min_following_distance) * dt
        - ind(t.max_acceleration) * dt * (ax - sc.max_acceleration_mps2);
    // Equation 8 (table 5's sign for the deceleration row).
    let brake = control.brake + ind(t.min_braking_distance) * db
        - ind(t.max_deceleration) * db * (-sc.max_deceleration_mps2 - ax);
    // Equation 9.
    let wz_dps = ego.yaw_rate_rps.abs().to_degrees();
    let steer = if t.max_yaw_rate {
        control.steer * (sc.max_yaw_rate_dps / wz_dps)
    } else {
        control.steer
    };
    (
        Control {
            throttle,
            brake,
            steer,
        }
        .clamped(),
        t,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ego(v: f64, ax: f64, wz: f64, d: Option<f64>) -> EgoState {
        EgoState {
            speed_mps: v,
            accel_x_mps2: ax,
            yaw_rate_rps: wz,
            follow_distance_m: d,
        }
    }

    const C: Control = Control {
        throttle: 0.7,
        brake: 0.2,
        steer: 0.5,
    };

    fn sc() -> SafetyConstraints {
        // The paper's example answer (appendix A.4).
        SafetyConstraints {
            max_speed_kmh: 40.0,
            min_following_distance_s: 3.0,
            max_acceleration_mps2: 1.5,
            max_deceleration_mps2: 3.0,
            max_yaw_rate_dps: 10.0,
            min_braking_distance_m: 25.0,
        }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn nothing_triggers_in_calm_driving() {
        let p = SafetyParams::default();
        let (c, t) = apply(C, &ego(5.0, 0.0, 0.0, None), &sc(), &p);
        assert!(!t.any());
        assert_eq!(c, C);
    }

    #[test]
    fn row_max_speed() {
        let p = SafetyParams::default();
        let v = 40.0 / 3.6; // exactly v_max: triggers (≥)
        let (c, t) = apply(C, &ego(v, 0.0, 0.0, None), &sc(), &p);
        assert!(t.max_speed && !t.min_braking_distance);
        assert!(close(c.throttle, 0.5));
        let (_, t) = apply(C, &ego(v - 0.01, 0.0, 0.0, None), &sc(), &p);
        assert!(!t.max_speed);
    }

    #[test]
    fn row_min_following_distance() {
        let p = SafetyParams::default();
        // d_min = 3 s · 5 m/s + 2 m = 17 m.
        let (c, t) = apply(C, &ego(5.0, 0.0, 0.0, Some(16.9)), &sc(), &p);
        assert!(t.min_following_distance);
        assert!(close(c.throttle, 0.5));
        let (_, t) = apply(C, &ego(5.0, 0.0, 0.0, Some(17.0)), &sc(), &p);
        assert!(!t.min_following_distance);
    }

    #[test]
    fn row_max_acceleration() {
        let p = SafetyParams::default();
        let (c, t) = apply(C, &ego(5.0, 2.5, 0.0, None), &sc(), &p);
        assert!(t.max_acceleration);
        // 0.7 − 0.2 · (2.5 − 1.5) = 0.5
        assert!(close(c.throttle, 0.5));
    }

    #[test]
    fn row_max_deceleration() {
        let p = SafetyParams::default();
        let (c, t) = apply(C, &ego(5.0, -4.0, 0.0, None), &sc(), &p);
        assert!(t.max_deceleration);
        // 0.2 − 0.2 · (−3 − (−4)) = 0.0
        assert!(close(c.brake, 0.0));
        let (_, t) = apply(C, &ego(5.0, -3.0, 0.0, None), &sc(), &p);
        assert!(!t.max_deceleration);
    }

    #[test]
    fn row_max_yaw_rate() {
        let p = SafetyParams::default();
        let wz = 20f64.to_radians(); // twice ψ_max
        let (c, t) = apply(C, &ego(5.0, 0.0, -wz, None), &sc(), &p);
        assert!(t.max_yaw_rate);
        assert!(close(c.steer, 0.25));
    }

    #[test]
    fn row_min_braking_distance() {
        let p = SafetyParams::default();
        // v²/(2·3) > 25 ⇔ v > √150 ≈ 12.25 m/s (also above v_max here).
        let (c, t) = apply(C, &ego(12.5, 0.0, 0.0, None), &sc(), &p);
        assert!(t.min_braking_distance && t.max_speed);
        assert!(close(c.brake, 0.4));
        assert!(close(c.throttle, 0.5));
    }

    #[test]
    fn terms_add_up_and_clamp() {
        let p = SafetyParams::default();
        let (c, t) = apply(C, &ego(13.0, 4.0, 0.0, Some(1.0)), &sc(), &p);
        assert!(t.max_speed && t.min_following_distance && t.max_acceleration);
        // 0.7 − 0.2 − 0.2 − 0.2·2.5 < 0 → 0
        assert_eq!(c.throttle, 0.0);
    }

    #[test]
    fn ranges_reject_out_of_range_and_non_finite() {
        assert!(sc().validate().is_ok());
        assert!(SafetyConstraints::conservative().validate().is_ok());
        let mut s = sc();
        s.max_speed_kmh = f64::NAN;
        assert!(s.validate().unwrap_err().contains("max_speed_kmh"));
        let mut s = sc();
        s.max_deceleration_mps2 = 0.0;
        assert!(s.validate().unwrap_err().contains("max_deceleration"));
    }
}
