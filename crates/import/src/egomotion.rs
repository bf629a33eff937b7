//! The ego vehicle's motion: a clip's egomotion table (`{clip}.egomotion.parquet`: `timestamp`
//! in µs, position `x y z` in m, orientation `qx qy qz qw`, velocity `vx vy vz` in m/s, in a
//! fixed frame of the clip), interpolated as the dataset's devkit interpolates it, and the
//! planner's inputs derived from it at a decision time `t0`: the ego history and the
//! ground-truth future in the rig frame at `t0`.
//!
//! With `p(t)` the spline-interpolated position and `R(t)` the slerped orientation, a pose at
//! `t` seen from `t0` is `x_local = R(t0)⁻¹ · (p(t) − p(t0))` (its `x` forward and `y` left
//! are the trajectory's coordinates) and its heading is the yaw of `R(t0)⁻¹ · R(t)`,
//! `atan2(m₁₀, m₀₀)` of its matrix; the speed is `|v(t)|` with `v` interpolated linearly.
//! These are the formulas of Alpamayo R1's loader (`load_physical_aiavdataset.py`).

use fogline_types::clip::{EgoPose, HISTORY, HORIZON, Trajectory};

use crate::error::{ImportError, Result};
use crate::spline::{self, CubicSpline, Quat, Slerp};
use crate::table::Table;

/// Microseconds between the poses of the history and the waypoints of the future.
pub const STEP_US: i64 = 100_000;

/// The rows of one clip's egomotion table.
#[derive(Debug, Clone, PartialEq)]
pub struct Egomotion {
    /// Sample times, µs, strictly increasing.
    pub timestamps_us: Vec<i64>,
    /// Positions, m.
    pub xyz: Vec<[f64; 3]>,
    /// Orientations, unit quaternions `[x, y, z, w]`.
    pub quat: Vec<Quat>,
    /// Velocities, m/s.
    pub velocity: Vec<[f64; 3]>,
}

impl Egomotion {
    /// Reads the columns the import needs (`timestamp`, `x y z`, `qx qy qz qw`, `vx vy vz`;
    /// others, such as the accelerations and the curvature, are not read) and checks them:
    /// at least two rows, times strictly increasing, finite values, non-zero quaternions.
    pub fn from_table(t: &Table) -> Result<Self> {
        let timestamps_us = t.i64_column("timestamp")?;
        let col = |n: &str| t.f64_column(n);
        let (x, y, z) = (col("x")?, col("y")?, col("z")?);
        let (qx, qy, qz, qw) = (col("qx")?, col("qy")?, col("qz")?, col("qw")?);
        let (vx, vy, vz) = (col("vx")?, col("vy")?, col("vz")?);
        if timestamps_us.len() < 2 {
            return Err(ImportError::data(
                t.location(),
                format!(
                    "{} row(s); the egomotion of a clip has at least 2",
                    timestamps_us.len()
                ),
            ));
        }
        if let Some(i) =
            (1..timestamps_us.len()).find(|&i| timestamps_us[i] <= timestamps_us[i - 1])
        {
            return Err(ImportError::cell(
                t.location(),
                i as u64 + 1,
                "timestamp",
                format!(
                    "{} after {}: timestamps must be strictly increasing",
                    timestamps_us[i],
                    timestamps_us[i - 1]
                ),
            ));
        }
        let n = timestamps_us.len();
        let mut quat = Vec::with_capacity(n);
        for i in 0..n {
            let q = spline::normalize([qx[i], qy[i], qz[i], qw[i]]).ok_or_else(|| {
                ImportError::cell(
                    t.location(),
                    i as u64 + 1,
                    "qx, qy, qz, qw",
                    "a zero quaternion; expected an orientation",
                )
            })?;
            quat.push(q);
        }
        Ok(Self {
            xyz: (0..n).map(|i| [x[i], y[i], z[i]]).collect(),
            velocity: (0..n).map(|i| [vx[i], vy[i], vz[i]]).collect(),
            timestamps_us,
            quat,
        })
    }

    /// The interpolator of these samples.
    pub fn interpolator(&self) -> std::result::Result<EgoInterpolator, String> {
        let first = self.timestamps_us.first().copied().unwrap_or_default();
        let rel: Vec<f64> = self
            .timestamps_us
            .iter()
            .map(|&t| (t - first) as f64)
            .collect();
        Ok(EgoInterpolator {
            first_us: first,
            last_us: self.timestamps_us.last().copied().unwrap_or_default(),
            position: CubicSpline::fit(&rel, &self.xyz)?,
            orientation: Slerp::new(&rel, &self.quat)?,
            velocity: self.velocity.clone(),
            rel,
        })
    }
}

/// A pose of the ego vehicle in the clip's fixed frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldPose {
    /// Position, m.
    pub xyz: [f64; 3],
    /// Orientation, unit quaternion `[x, y, z, w]`.
    pub quat: Quat,
    /// Velocity, m/s.
    pub velocity: [f64; 3],
}

/// Egomotion interpolated at any time inside its samples (never extrapolated).
#[derive(Debug, Clone)]
pub struct EgoInterpolator {
    first_us: i64,
    last_us: i64,
    rel: Vec<f64>,
    position: CubicSpline,
    orientation: Slerp,
    velocity: Vec<[f64; 3]>,
}

/// The planner's view of the ego's motion at `t0`.
#[derive(Debug, Clone, PartialEq)]
pub struct EgoWindow {
    /// [`HISTORY`] poses at `t0 − 1.5 … t0`, rig frame at `t0`.
    pub history: Vec<EgoPose>,
    /// [`HORIZON`] waypoints at `t0 + 0.1 … t0 + 6.4 s`, rig frame at `t0`.
    pub ground_truth: Trajectory,
}

impl EgoInterpolator {
    /// The first and last sample times, µs.
    pub fn span_us(&self) -> (i64, i64) {
        (self.first_us, self.last_us)
    }

    /// The pose at `t_us`, or `None` outside the samples.
    pub fn at(&self, t_us: i64) -> Option<WorldPose> {
        let t = t_us.checked_sub(self.first_us)? as f64;
        Some(WorldPose {
            xyz: self.position.eval(t)?,
            quat: self.orientation.eval(t)?,
            velocity: spline::linear(&self.rel, &self.velocity, t)?,
        })
    }

    /// The ego history and the ground-truth future at `t0_us`; `Err` says which times the
    /// samples do not cover.
    pub fn window(&self, t0_us: i64) -> std::result::Result<EgoWindow, String> {
        let start = t0_us.checked_sub((HISTORY as i64 - 1) * STEP_US);
        let end = t0_us.checked_add(HORIZON as i64 * STEP_US);
        let (Some(start), Some(end)) = (start, end) else {
            return Err(format!("t0 {t0_us} µs is out of range"));
        };
        if start < self.first_us || end > self.last_us {
            return Err(format!(
                "its egomotion covers {} … {} s; t0 = {} s needs {} … {} s (1.5 s of history, \
                 6.4 s of future)",
                secs(self.first_us),
                secs(self.last_us),
                secs(t0_us),
                secs(start),
                secs(end)
            ));
        }
        let pose = |t: i64| {
            self.at(t)
                .ok_or_else(|| format!("no egomotion at {} s", secs(t)))
        };
        let p0 = pose(t0_us)?;
        let inv0 = spline::inverse(p0.quat);
        let m = spline::to_matrix(inv0);
        let local = |p: &WorldPose| -> [f64; 3] {
            let d = [
                p.xyz[0] - p0.xyz[0],
                p.xyz[1] - p0.xyz[1],
                p.xyz[2] - p0.xyz[2],
            ];
            std::array::from_fn(|r| m[r][0] * d[0] + m[r][1] * d[1] + m[r][2] * d[2])
        };
        let mut history = Vec::with_capacity(HISTORY);
        for k in 0..HISTORY as i64 {
            let back = HISTORY as i64 - 1 - k;
            let p = pose(t0_us - back * STEP_US)?;
            let xyz = local(&p);
            let rot = spline::to_matrix(spline::compose(inv0, p.quat));
            let v = p.velocity;
            history.push(EgoPose {
                t_s: -(back as f64) / 10.0,
                x_m: xyz[0],
                y_m: xyz[1],
                yaw_rad: rot[1][0].atan2(rot[0][0]),
                speed_mps: (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt(),
            });
        }
        let mut xy = Vec::with_capacity(HORIZON);
        for k in 1..=HORIZON as i64 {
            let xyz = local(&pose(t0_us + k * STEP_US)?);
            xy.push([xyz[0], xyz[1]]);
        }
        Ok(EgoWindow {
            history,
            ground_truth: Trajectory { xy },
        })
    }
}

/// Microseconds as seconds for messages (`5.1`, `-0.000001`).
pub fn secs(us: i64) -> String {
    let sign = if us < 0 { "-" } else { "" };
    let a = us.unsigned_abs();
    let frac = format!("{:06}", a % 1_000_000);
    let frac = frac.trim_end_matches('0');
    if frac.is_empty() {
        format!("{sign}{}", a / 1_000_000)
    } else {
        format!("{sign}{}.{frac}", a / 1_000_000)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A car driving a circle of radius 50 m at 10 m/s, heading along the circle, sampled
    /// every `dt_us`, in a frame rotated and shifted away from the rig.
    fn circle(dt_us: i64, n: usize) -> Egomotion {
        let (r, v, yaw0) = (50.0f64, 10.0f64, 0.7f64);
        let mut e = Egomotion {
            timestamps_us: vec![],
            xyz: vec![],
            quat: vec![],
            velocity: vec![],
        };
        for i in 0..n {
            let t = i as i64 * dt_us;
            let a = v * t as f64 * 1e-6 / r;
            let h = yaw0 + a;
            // Position on the circle whose centre is r to the left of the start.
            let (x, y) = (
                1000.0 + r * (h.sin() - yaw0.sin()),
                -500.0 - r * (h.cos() - yaw0.cos()),
            );
            e.timestamps_us.push(t);
            e.xyz.push([x, y, 3.0]);
            e.quat.push([0.0, 0.0, (h / 2.0).sin(), (h / 2.0).cos()]);
            e.velocity.push([v * h.cos(), v * h.sin(), 0.0]);
        }
        e
    }

    #[test]
    fn window_in_the_rig_frame_at_t0() {
        let e = circle(10_000, 1_201); // 100 Hz for 12 s
        let ip = e.interpolator().unwrap();
        let w = ip.window(5_100_000).unwrap();
        assert_eq!(w.history.len(), HISTORY);
        assert_eq!(w.ground_truth.xy.len(), HORIZON);
        let last = w.history[HISTORY - 1];
        assert_eq!((last.t_s, last.x_m, last.y_m), (0.0, 0.0, 0.0));
        assert!(last.yaw_rad.abs() < 1e-12 && (last.speed_mps - 10.0).abs() < 1e-9);
        assert_eq!(w.history[0].t_s, -1.5);
        // On a left circle seen from t0: x = r sin(a), y = r (1 − cos a), a = v t / r.
        for (k, p) in w.ground_truth.xy.iter().enumerate() {
            let a = 10.0 * 0.1 * (k + 1) as f64 / 50.0;
            assert!((p[0] - 50.0 * a.sin()).abs() < 1e-6, "{k}: {p:?}");
            assert!((p[1] - 50.0 * (1.0 - a.cos())).abs() < 1e-6, "{k}: {p:?}");
        }
        let h0 = w.history[0];
        let a: f64 = -1.5 * 10.0 / 50.0;
        assert!((h0.x_m - 50.0 * a.sin()).abs() < 1e-6 && (h0.yaw_rad - a).abs() < 1e-9);
        // Coverage: 1.5 s of history and 6.4 s of future inside the samples.
        let err = ip.window(1_000_000).unwrap_err();
        assert!(
            err.contains("covers 0 … 12 s") && err.contains("-0.5 … 7.4 s"),
            "{err}"
        );
        assert!(ip.window(6_000_000).is_err());
        assert!(ip.window(i64::MAX).is_err());
    }

    #[test]
    fn seconds_for_messages() {
        assert_eq!(secs(5_100_000), "5.1");
        assert_eq!(secs(-1_000_001), "-1.000001");
        assert_eq!(secs(0), "0");
    }
}
