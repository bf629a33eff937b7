//! Motion primitives shared by the world's privileged expert and the reference planner: a
//! path (straights and arcs from the ego at `t0`), a lateral offset profile along it, and
//! longitudinal speed profiles sampled at the trajectory's 64 times.
//!
//! Both drivers plan with the same primitives; they differ only in what they know: the
//! expert reads the scene, the planner its perception of the pixels.
//!
//! ```
//! use fogline_types::motion::{Lateral, Path, cruise, rollout, stop_within};
//!
//! let path = Path::straight();
//! let traj = rollout(&path, &Lateral::none(), &cruise(10.0));
//! assert!((traj.xy[9][0] - 10.0).abs() < 1e-9); // 1 s at 10 m/s
//! let stop = stop_within(10.0, 20.0);
//! assert!((stop[63] - 20.0).abs() < 1e-9); // comes to rest exactly 20 m ahead
//! ```

use crate::clip::{DT_S, HORIZON, Trajectory};

/// Distance from the rig origin (rear axle) to the ego's front bumper, m.
pub const EGO_FRONT_M: f64 = 3.7;
/// The ego's width, m.
pub const EGO_WIDTH_M: f64 = 1.9;

/// A path from the rig origin at `t0` (heading 0): segments in order; the last one continues
/// indefinitely.
#[derive(Debug, Clone, PartialEq)]
pub struct Path {
    /// The segments: `(length m, curvature 1/m, left positive)`.
    pub segments: Vec<(f64, f64)>,
}

impl Path {
    /// Straight ahead.
    pub fn straight() -> Self {
        Self {
            segments: vec![(f64::INFINITY, 0.0)],
        }
    }

    /// A constant-curvature arc (`kappa` 1/m, left positive).
    pub fn arc(kappa: f64) -> Self {
        Self {
            segments: vec![(f64::INFINITY, kappa)],
        }
    }

    /// Straight for `before` m, a right turn of 90° with radius `radius`, then straight.
    pub fn right_turn(before: f64, radius: f64) -> Self {
        Self {
            segments: vec![
                (before.max(0.0), 0.0),
                (radius * std::f64::consts::FRAC_PI_2, -1.0 / radius),
                (f64::INFINITY, 0.0),
            ],
        }
    }

    /// Pose `(x, y, heading)` at arc length `s` (negative `s` extends the first segment
    /// backwards).
    pub fn pose_at(&self, s: f64) -> (f64, f64, f64) {
        let (mut x, mut y, mut h) = (0.0, 0.0, 0.0);
        let mut rest = s;
        if s < 0.0 {
            let k = self.segments.first().map_or(0.0, |seg| seg.1);
            return advance(x, y, h, s, k);
        }
        for (i, &(len, k)) in self.segments.iter().enumerate() {
            let last = i + 1 == self.segments.len();
            let step = if last { rest } else { rest.min(len) };
            (x, y, h) = advance(x, y, h, step, k);
            rest -= step;
            if rest <= 0.0 {
                break;
            }
        }
        (x, y, h)
    }
}

/// Moves along an arc of curvature `k` by `s` from `(x, y, h)`.
fn advance(x: f64, y: f64, h: f64, s: f64, k: f64) -> (f64, f64, f64) {
    if k.abs() < 1e-9 {
        (x + s * h.cos(), y + s * h.sin(), h)
    } else {
        let h2 = h + k * s;
        (
            x + (h2.sin() - h.sin()) / k,
            y - (h2.cos() - h.cos()) / k,
            h2,
        )
    }
}

/// A lateral offset (left positive, m) along the path: a sum of smooth steps, each moving the
/// offset by `delta` between arc lengths `from` and `to` (a cosine ramp).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Lateral {
    /// `(from m, to m, delta m)`.
    pub ramps: Vec<(f64, f64, f64)>,
}

impl Lateral {
    /// No offset.
    pub fn none() -> Self {
        Self::default()
    }

    /// The offset at arc length `s`.
    pub fn offset_at(&self, s: f64) -> f64 {
        self.ramps
            .iter()
            .map(|&(a, b, delta)| {
                if s <= a {
                    0.0
                } else if s >= b || b <= a {
                    delta
                } else {
                    let u = (s - a) / (b - a);
                    delta * 0.5 * (1.0 - (std::f64::consts::PI * u).cos())
                }
            })
            .sum()
    }
}

/// Distances travelled at the [`HORIZON`] waypoint times (`0.1 … 6.4 s`).
pub type Distances = [f64; HORIZON];

/// The trajectory that travels `distances` along `path` with `lateral` offset.
pub fn rollout(path: &Path, lateral: &Lateral, distances: &Distances) -> Trajectory {
    Trajectory {
        xy: distances
            .iter()
            .map(|&s| {
                let (x, y, h) = path.pose_at(s);
                let o = lateral.offset_at(s);
                [x - o * h.sin(), y + o * h.cos()]
            })
            .collect(),
    }
}

/// Waypoint time `k` (0-based): `0.1·(k+1)` s.
pub fn time_of(k: usize) -> f64 {
    DT_S * (k + 1) as f64
}

/// Constant speed `v0`.
pub fn cruise(v0: f64) -> Distances {
    std::array::from_fn(|k| v0 * time_of(k))
}

/// Constant deceleration from `v0` to rest exactly `dist` m ahead (at once, as hard as that
/// takes; `dist <= 0` stands still).
pub fn stop_within(v0: f64, dist: f64) -> Distances {
    if dist <= 0.0 || v0 <= 0.0 {
        return [0.0; HORIZON];
    }
    let a = v0 * v0 / (2.0 * dist);
    let t_stop = v0 / a;
    std::array::from_fn(|k| {
        let t = time_of(k).min(t_stop);
        v0 * t - 0.5 * a * t * t
    })
}

/// Speed changes at a constant rate `accel` (signed, m/s²) from `v0` until it reaches
/// `v_target`, then holds it.
pub fn ramp_speed(v0: f64, v_target: f64, accel: f64) -> Distances {
    let mut out = [0.0; HORIZON];
    let (mut s, mut v) = (0.0, v0);
    let sub = 10;
    let dt = DT_S / sub as f64;
    for o in out.iter_mut() {
        for _ in 0..sub {
            let v_next = if v < v_target {
                (v + accel.abs() * dt).min(v_target)
            } else {
                (v - accel.abs() * dt).max(v_target)
            };
            s += 0.5 * (v + v_next) * dt;
            v = v_next;
        }
        *o = s;
    }
    out
}

/// Slows at `decel` (> 0) so as to reach `v_turn` at arc length `s_turn` (not before it is
/// needed), holds `v_turn` for `hold` m, then accelerates at `accel` back up to `v_after`.
pub fn slow_for_turn(
    v0: f64,
    v_turn: f64,
    decel: f64,
    s_turn: f64,
    hold: f64,
    accel: f64,
    v_after: f64,
) -> Distances {
    let sub = 10;
    let dt = DT_S / sub as f64;
    let (mut s, mut v) = (0.0f64, v0);
    let mut out = [0.0; HORIZON];
    for o in out.iter_mut() {
        for _ in 0..sub {
            // Braking distance to v_turn from the current speed.
            let need = if v > v_turn {
                (v * v - v_turn * v_turn) / (2.0 * decel)
            } else {
                0.0
            };
            let a = if s < s_turn {
                if s + need >= s_turn - 1e-9 && v > v_turn {
                    -decel
                } else {
                    0.0
                }
            } else if s < s_turn + hold {
                if v > v_turn { -decel } else { 0.0 }
            } else if v < v_after {
                accel
            } else {
                0.0
            };
            let mut v_next = (v + a * dt).max(0.0);
            if a < 0.0 && s >= s_turn {
                v_next = v_next.max(v_turn.min(v));
            }
            if a > 0.0 {
                v_next = v_next.min(v_after);
            }
            s += 0.5 * (v + v_next) * dt;
            v = v_next;
        }
        *o = s;
    }
    out
}

/// The intelligent driver model's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Idm {
    /// Desired speed, m/s.
    pub v_desired: f64,
    /// Time headway, s.
    pub headway_s: f64,
    /// Standstill gap, m.
    pub min_gap_m: f64,
    /// Maximum acceleration, m/s².
    pub accel: f64,
    /// Comfortable deceleration, m/s².
    pub decel: f64,
}

impl Idm {
    /// Urban defaults with desired speed `v_desired`.
    pub fn urban(v_desired: f64) -> Self {
        Self {
            v_desired,
            headway_s: 1.2,
            min_gap_m: 4.0,
            accel: 1.5,
            decel: 3.0,
        }
    }

    /// The equilibrium bumper-to-bumper gap at speed `v` behind a lead at the same speed
    /// (ignoring the free-road term).
    pub fn steady_gap(&self, v: f64) -> f64 {
        self.min_gap_m + v * self.headway_s
    }
}

/// A lead vehicle on the path: bumper-to-bumper gap at `t0` (m), speed (m/s) and a constant
/// acceleration (m/s², negative = braking; it stops at rest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lead {
    /// Gap at `t0`, m.
    pub gap_m: f64,
    /// Speed at `t0`, m/s.
    pub speed_mps: f64,
    /// Acceleration, m/s².
    pub accel_mps2: f64,
}

/// Car following: the ego at `v0` behind `lead`, driven by the intelligent driver model
/// (simulated at 10 ms steps, speeds never negative).
pub fn follow(v0: f64, lead: Lead, idm: &Idm) -> Distances {
    let sub = 10;
    let dt = DT_S / sub as f64;
    let (mut s, mut v) = (0.0f64, v0.max(0.0));
    let (mut ls, mut lv) = (lead.gap_m, lead.speed_mps.max(0.0));
    let mut out = [0.0; HORIZON];
    for o in out.iter_mut() {
        for _ in 0..sub {
            let gap = (ls - s).max(0.1);
            let dv = v - lv;
            let s_star = idm.min_gap_m
                + (v * idm.headway_s + v * dv / (2.0 * (idm.accel * idm.decel).sqrt())).max(0.0);
            let free = 1.0 - (v / idm.v_desired.max(0.1)).powi(4);
            let a = (idm.accel * (free - (s_star / gap).powi(2))).max(-9.0);
            let v_next = (v + a * dt).max(0.0);
            s += 0.5 * (v + v_next) * dt;
            v = v_next;
            let lv_next = (lv + lead.accel_mps2 * dt).max(0.0);
            ls += 0.5 * (lv + lv_next) * dt;
            lv = lv_next;
        }
        *o = s;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arcs_and_turns() {
        let p = Path::arc(0.01);
        // A quarter circle of radius 100 ends at (100, 100) heading +90°.
        let (x, y, h) = p.pose_at(100.0 * std::f64::consts::FRAC_PI_2);
        assert!((x - 100.0).abs() < 1e-9 && (y - 100.0).abs() < 1e-9);
        assert!((h - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let t = Path::right_turn(20.0, 10.0);
        let (x, y, h) = t.pose_at(20.0 + 10.0 * std::f64::consts::FRAC_PI_2 + 5.0);
        assert!((x - 30.0).abs() < 1e-9 && (y + 15.0).abs() < 1e-9);
        assert!((h + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let (x, _, _) = t.pose_at(-3.0);
        assert!((x + 3.0).abs() < 1e-12);
    }

    #[test]
    fn lateral_ramps_are_smooth_steps() {
        let l = Lateral {
            ramps: vec![(10.0, 20.0, -1.0), (30.0, 40.0, 1.0)],
        };
        assert_eq!(l.offset_at(5.0), 0.0);
        assert!((l.offset_at(15.0) + 0.5).abs() < 1e-12);
        assert_eq!(l.offset_at(25.0), -1.0);
        assert!(l.offset_at(45.0).abs() < 1e-12);
        let tr = rollout(&Path::straight(), &l, &cruise(5.0));
        assert!((tr.xy[49][1] + 1.0).abs() < 1e-12); // s = 25 m
    }

    #[test]
    fn speed_profiles() {
        let s = stop_within(10.0, 25.0);
        assert!((s[63] - 25.0).abs() < 1e-9);
        assert!(s.windows(2).all(|w| w[1] >= w[0]));
        let r = ramp_speed(5.0, 10.0, 1.0);
        // 5 s of acceleration (37.5 m) then 1.4 s at 10 m/s.
        assert!((r[63] - (37.5 + 14.0)).abs() < 1e-6);
        let idm = Idm::urban(12.0);
        // A lead at the same speed at the steady gap keeps the ego near cruise.
        let f = follow(
            10.0,
            Lead {
                gap_m: idm.steady_gap(10.0) + 8.0,
                speed_mps: 10.0,
                accel_mps2: 0.0,
            },
            &idm,
        );
        assert!((f[63] - 64.0).abs() < 4.0, "{}", f[63]);
        // A lead braking to rest: the ego stops behind it.
        let b = follow(
            10.0,
            Lead {
                gap_m: 16.0,
                speed_mps: 10.0,
                accel_mps2: -3.0,
            },
            &idm,
        );
        let lead_stop = 16.0 + 100.0 / 6.0;
        assert!(
            b[63] < lead_stop - 1.0 && b[63] > lead_stop - 10.0,
            "{}",
            b[63]
        );
        let t = slow_for_turn(10.0, 5.0, 2.0, 30.0, 15.0, 1.0, 8.0);
        assert!(t.windows(2).all(|w| w[1] >= w[0]));
    }
}
