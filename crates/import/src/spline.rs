//! The interpolation of the PhysicalAI-AV devkit (`physical_ai_av.utils.interpolation`),
//! written out so that fogline's trajectories agree with it to rounding:
//!
//! - positions: SciPy's `CubicSpline(t, xyz)` with its default not-a-knot end conditions
//!   (the slopes solved from SciPy's tridiagonal system by LAPACK's `gtsv` elimination with
//!   partial pivoting, then SciPy's Hermite coefficients and power-sum evaluation), no
//!   extrapolation;
//! - orientations: SciPy's `Slerp(t, rotations)`: `R_i · exp(α · log(R_i⁻¹ R_{i+1}))`, the
//!   interval found as SciPy does (a time equal to a knot other than the first uses the
//!   interval that ends there, `α = 1`);
//! - velocities: linear interpolation (the devkit's `make_interp_spline(k=1)`).
//!
//! Times are `f64` microseconds relative to the first sample, as in the devkit. Quaternions
//! are `[x, y, z, w]` (SciPy's order), rotations composed as SciPy composes them.
//!
//! ```
//! use fogline_import::spline::CubicSpline;
//!
//! // A cubic is reproduced exactly by a not-a-knot spline (four or more samples).
//! let t = [0.0, 1.0, 2.5, 3.0, 4.0];
//! let y: Vec<[f64; 3]> = t.iter().map(|&x| [x * x * x, 2.0 * x, 1.0]).collect();
//! let s = CubicSpline::fit(&t, &y)?;
//! let v = s.eval(1.7).ok_or("1.7 s is inside the samples")?;
//! assert!((v[0] - 1.7f64.powi(3)).abs() < 1e-12 && (v[1] - 3.4).abs() < 1e-12);
//! assert!(s.eval(4.5).is_none()); // no extrapolation
//! # Ok::<(), String>(())
//! ```

/// A cubic spline through 3-vectors with not-a-knot end conditions (SciPy's default).
#[derive(Debug, Clone)]
pub struct CubicSpline {
    x: Vec<f64>,
    /// Per interval, the coefficients `c0 … c3` of `c0 s³ + c1 s² + c2 s + c3`, `s = x − x_i`.
    c: Vec<[[f64; 3]; 4]>,
}

impl CubicSpline {
    /// Fits the spline; `x` strictly increasing, at least two samples. `Err` names the
    /// problem (too few samples, times not increasing, a singular system).
    pub fn fit(x: &[f64], y: &[[f64; 3]]) -> Result<Self, String> {
        let n = x.len();
        if n != y.len() {
            return Err(format!("{} times but {} values", n, y.len()));
        }
        if n < 2 {
            return Err(format!("{n} sample(s); a spline needs at least 2"));
        }
        if let Some(i) = (1..n).find(|&i| x[i] <= x[i - 1] || !(x[i] - x[i - 1]).is_finite()) {
            return Err(format!(
                "times not strictly increasing at sample {} ({} after {})",
                i + 1,
                x[i],
                x[i - 1]
            ));
        }
        let dx: Vec<f64> = (0..n - 1).map(|i| x[i + 1] - x[i]).collect();
        let slope: Vec<[f64; 3]> = (0..n - 1)
            .map(|i| std::array::from_fn(|k| (y[i + 1][k] - y[i][k]) / dx[i]))
            .collect();
        let s: Vec<[f64; 3]> = if n == 2 {
            // SciPy turns not-a-knot into "first derivative = the chord's slope": a line.
            vec![slope[0], slope[0]]
        } else if n == 3 {
            // Both ends not-a-knot with three samples: the parabola through them.
            parabola_slopes(&dx, &slope)
        } else {
            let mut dl = vec![0.0; n - 1];
            let mut d = vec![0.0; n];
            let mut du = vec![0.0; n - 1];
            let mut b = vec![[0.0; 3]; n];
            for i in 1..n - 1 {
                d[i] = 2.0 * (dx[i - 1] + dx[i]);
                du[i] = dx[i - 1];
                dl[i - 1] = dx[i];
                for k in 0..3 {
                    b[i][k] = 3.0 * (dx[i] * slope[i - 1][k] + dx[i - 1] * slope[i][k]);
                }
            }
            let d0 = x[2] - x[0];
            d[0] = dx[1];
            du[0] = d0;
            for k in 0..3 {
                b[0][k] =
                    ((dx[0] + 2.0 * d0) * dx[1] * slope[0][k] + dx[0] * dx[0] * slope[1][k]) / d0;
            }
            let dn = x[n - 1] - x[n - 3];
            d[n - 1] = dx[n - 3];
            dl[n - 2] = dn;
            for k in 0..3 {
                b[n - 1][k] = (dx[n - 2] * dx[n - 2] * slope[n - 3][k]
                    + (2.0 * dn + dx[n - 2]) * dx[n - 3] * slope[n - 2][k])
                    / dn;
            }
            gtsv(dl, d, du, b)?
        };
        let c = (0..n - 1)
            .map(|i| {
                let mut c = [[0.0; 3]; 4];
                for k in 0..3 {
                    let t = (s[i][k] + s[i + 1][k] - 2.0 * slope[i][k]) / dx[i];
                    c[0][k] = t / dx[i];
                    c[1][k] = (slope[i][k] - s[i][k]) / dx[i] - t;
                    c[2][k] = s[i][k];
                    c[3][k] = y[i][k];
                }
                c
            })
            .collect();
        Ok(Self { x: x.to_vec(), c })
    }

    /// The spline at `t`, or `None` outside `[x_0, x_last]` (no extrapolation).
    pub fn eval(&self, t: f64) -> Option<[f64; 3]> {
        let i = interval(&self.x, t)?;
        let s = t - self.x[i];
        let c = &self.c[i];
        // SciPy's PPoly: a power sum from the constant term up, not Horner's scheme.
        Some(std::array::from_fn(|k| {
            let mut z = 1.0;
            let mut res = 0.0;
            for p in (0..4).rev() {
                res += c[p][k] * z;
                z *= s;
            }
            res
        }))
    }
}

/// SciPy PPoly's interval: `x_i ≤ t < x_{i+1}`, the last interval closed on the right.
fn interval(x: &[f64], t: f64) -> Option<usize> {
    let n = x.len();
    if n < 2 || !(t >= x[0] && t <= x[n - 1]) {
        return None;
    }
    let i = x.partition_point(|&v| v <= t);
    Some(i.saturating_sub(1).min(n - 2))
}

/// The slopes of the parabola through three samples (SciPy's 3×3 system, solved directly).
fn parabola_slopes(dx: &[f64], slope: &[[f64; 3]]) -> Vec<[f64; 3]> {
    // A parabola's slope changes linearly: its second derivative is
    // 2 (slope1 − slope0) / (dx0 + dx1), and it has the chord's slope at each mid-interval.
    let mut s = vec![[0.0; 3]; 3];
    for k in 0..3 {
        let curv = 2.0 * (slope[1][k] - slope[0][k]) / (dx[0] + dx[1]);
        s[0][k] = slope[0][k] - curv * dx[0] / 2.0;
        s[1][k] = slope[0][k] + curv * dx[0] / 2.0;
        s[2][k] = slope[1][k] + curv * dx[1] / 2.0;
    }
    s
}

/// LAPACK's `dgtsv`: Gaussian elimination of a tridiagonal system with partial pivoting
/// (`dl` below, `d` on, `du` above the diagonal), then back substitution; three right-hand
/// sides, each eliminated exactly as alone.
fn gtsv(
    mut dl: Vec<f64>,
    mut d: Vec<f64>,
    mut du: Vec<f64>,
    mut b: Vec<[f64; 3]>,
) -> Result<Vec<[f64; 3]>, String> {
    let n = d.len();
    let singular = || "the spline's system is singular".to_string();
    // `du2` is the second superdiagonal that row interchanges fill in (kept in `dl`, as
    // LAPACK does).
    for i in 0..n - 1 {
        if d[i].abs() >= dl[i].abs() {
            if d[i] == 0.0 {
                return Err(singular());
            }
            let fact = dl[i] / d[i];
            d[i + 1] -= fact * du[i];
            for k in 0..3 {
                b[i + 1][k] -= fact * b[i][k];
            }
            dl[i] = 0.0;
        } else {
            let fact = d[i] / dl[i];
            d[i] = dl[i];
            let temp = d[i + 1];
            d[i + 1] = du[i] - fact * temp;
            if i + 1 < n - 1 {
                dl[i] = du[i + 1];
                du[i + 1] = -fact * dl[i];
            }
            du[i] = temp;
            for k in 0..3 {
                let temp = b[i][k];
                b[i][k] = b[i + 1][k];
                b[i + 1][k] = temp - fact * b[i + 1][k];
            }
        }
    }
    if d[n - 1] == 0.0 {
        return Err(singular());
    }
    for k in 0..3 {
        b[n - 1][k] /= d[n - 1];
        if n > 1 {
            b[n - 2][k] = (b[n - 2][k] - du[n - 2] * b[n - 1][k]) / d[n - 2];
        }
        for i in (0..n.saturating_sub(2)).rev() {
            b[i][k] = (b[i][k] - du[i] * b[i + 1][k] - dl[i] * b[i + 2][k]) / d[i];
        }
    }
    Ok(b)
}

/// A unit quaternion `[x, y, z, w]`.
pub type Quat = [f64; 4];

/// Normalises `q`; `None` for a zero or non-finite quaternion (SciPy refuses those too).
pub fn normalize(q: Quat) -> Option<Quat> {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if !n.is_finite() || n == 0.0 {
        return None;
    }
    Some([q[0] / n, q[1] / n, q[2] / n, q[3] / n])
}

/// The composition `p · q` (apply `q`, then `p`), as SciPy's `Rotation.__mul__`.
pub fn compose(p: Quat, q: Quat) -> Quat {
    let cross = [
        p[1] * q[2] - p[2] * q[1],
        p[2] * q[0] - p[0] * q[2],
        p[0] * q[1] - p[1] * q[0],
    ];
    [
        p[3] * q[0] + q[3] * p[0] + cross[0],
        p[3] * q[1] + q[3] * p[1] + cross[1],
        p[3] * q[2] + q[3] * p[2] + cross[2],
        p[3] * q[3] - (p[0] * q[0] + p[1] * q[1] + p[2] * q[2]),
    ]
}

/// The inverse rotation.
pub fn inverse(q: Quat) -> Quat {
    [-q[0], -q[1], -q[2], q[3]]
}

/// The rotation vector (axis × angle, angle in `[0, π]`), as SciPy's `as_rotvec`.
pub fn to_rotvec(q: Quat) -> [f64; 3] {
    let q = if q[3] < 0.0 {
        [-q[0], -q[1], -q[2], -q[3]]
    } else {
        q
    };
    let angle = 2.0 * (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt().atan2(q[3]);
    let scale = if angle <= 1e-3 {
        let a2 = angle * angle;
        2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0
    } else {
        angle / (angle / 2.0).sin()
    };
    [scale * q[0], scale * q[1], scale * q[2]]
}

/// The rotation of a rotation vector, as SciPy's `from_rotvec`.
pub fn from_rotvec(v: [f64; 3]) -> Quat {
    let angle = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let scale = if angle <= 1e-3 {
        let a2 = angle * angle;
        0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    } else {
        (angle / 2.0).sin() / angle
    };
    [
        scale * v[0],
        scale * v[1],
        scale * v[2],
        (angle / 2.0).cos(),
    ]
}

/// The rotation matrix (rows), as SciPy's `as_matrix`.
pub fn to_matrix(q: Quat) -> [[f64; 3]; 3] {
    let [x, y, z, w] = q;
    let (x2, y2, z2, w2) = (x * x, y * y, z * z, w * w);
    let (xy, zw, xz, yw, yz, xw) = (x * y, z * w, x * z, y * w, y * z, x * w);
    [
        [x2 - y2 - z2 + w2, 2.0 * (xy - zw), 2.0 * (xz + yw)],
        [2.0 * (xy + zw), -x2 + y2 - z2 + w2, 2.0 * (yz - xw)],
        [2.0 * (xz - yw), 2.0 * (yz + xw), -x2 - y2 + z2 + w2],
    ]
}

/// Spherical linear interpolation between key rotations (SciPy's `Slerp`).
#[derive(Debug, Clone)]
pub struct Slerp {
    times: Vec<f64>,
    rotations: Vec<Quat>,
    rotvecs: Vec<[f64; 3]>,
}

impl Slerp {
    /// Key rotations (unit quaternions) at strictly increasing times, at least two.
    pub fn new(times: &[f64], rotations: &[Quat]) -> Result<Self, String> {
        if times.len() != rotations.len() || times.len() < 2 {
            return Err(format!(
                "{} times and {} rotations; slerp needs at least 2 of each",
                times.len(),
                rotations.len()
            ));
        }
        let rotvecs = rotations
            .windows(2)
            .map(|w| to_rotvec(compose(inverse(w[0]), w[1])))
            .collect();
        Ok(Self {
            times: times.to_vec(),
            rotations: rotations.to_vec(),
            rotvecs,
        })
    }

    /// The rotation at `t`, or `None` outside the key times.
    pub fn eval(&self, t: f64) -> Option<Quat> {
        let n = self.times.len();
        if !(t >= self.times[0] && t <= self.times[n - 1]) {
            return None;
        }
        // numpy.searchsorted(times, t) − 1 (side "left"), 0 at the first time.
        let i = self.times.partition_point(|&v| v < t).saturating_sub(1);
        let i = i.min(n - 2);
        let alpha = (t - self.times[i]) / (self.times[i + 1] - self.times[i]);
        let v = self.rotvecs[i];
        Some(compose(
            self.rotations[i],
            from_rotvec([v[0] * alpha, v[1] * alpha, v[2] * alpha]),
        ))
    }
}

/// Linear interpolation of 3-vectors at strictly increasing times; `None` outside them.
pub fn linear(x: &[f64], y: &[[f64; 3]], t: f64) -> Option<[f64; 3]> {
    let i = interval(x, t)?;
    let f = (t - x[i]) / (x[i + 1] - x[i]);
    Some(std::array::from_fn(|k| {
        y[i][k] + f * (y[i + 1][k] - y[i][k])
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spline_matches_scipy() {
        // scipy.interpolate.CubicSpline(x, y)(q) with SciPy 1.17.1 (not-a-knot):
        //   x = [0, 1, 3, 4, 7, 8.5], y = sin(x) (three columns: y, 2y, x²)
        let x = [0.0, 1.0, 3.0, 4.0, 7.0, 8.5];
        let y: Vec<[f64; 3]> = x
            .iter()
            .map(|&v: &f64| [v.sin(), 2.0 * v.sin(), v * v])
            .collect();
        let s = CubicSpline::fit(&x, &y).unwrap();
        let want = [
            (0.5, 0.540_281_878_022_756_2),
            (2.2, 0.734_183_770_742_240_7),
            (5.0, -0.781_970_333_537_631_6),
            (8.5, 0.798_487_112_623_490_1),
        ];
        for (q, v) in want {
            let got = s.eval(q).unwrap();
            assert!((got[0] - v).abs() < 1e-12, "{q}: {} vs {v}", got[0]);
            assert!((got[1] - 2.0 * v).abs() < 1e-12);
            // x² is a cubic: reproduced exactly.
            assert!((got[2] - q * q).abs() < 1e-9, "{q}: {}", got[2]);
        }
        assert!(s.eval(-0.1).is_none() && s.eval(8.6).is_none());
        // Knots give the samples back exactly.
        assert_eq!(s.eval(3.0).unwrap()[0], 3f64.sin());
        // Two samples: a line; three: the parabola.
        let l = CubicSpline::fit(&[0.0, 2.0], &[[0.0; 3], [4.0, 2.0, 0.0]]).unwrap();
        assert_eq!(l.eval(0.5).unwrap(), [1.0, 0.5, 0.0]);
        let p = CubicSpline::fit(
            &[0.0, 1.0, 3.0],
            &[[0.0; 3], [1.0, 0.0, 0.0], [9.0, 0.0, 0.0]],
        )
        .unwrap();
        assert!((p.eval(2.0).unwrap()[0] - 4.0).abs() < 1e-12);
        assert!(CubicSpline::fit(&[0.0, 1.0, 1.0], &[[0.0; 3]; 3]).is_err());
        assert!(CubicSpline::fit(&[0.0], &[[0.0; 3]]).is_err());
    }

    #[test]
    fn slerp_and_quaternions() {
        let yaw = |a: f64| [0.0, 0.0, (a / 2.0).sin(), (a / 2.0).cos()];
        let s = Slerp::new(&[0.0, 10.0, 20.0], &[yaw(0.0), yaw(1.0), yaw(3.0)]).unwrap();
        let m = to_matrix(s.eval(5.0).unwrap());
        assert!((m[1][0].atan2(m[0][0]) - 0.5).abs() < 1e-12);
        let m = to_matrix(s.eval(15.0).unwrap());
        assert!((m[1][0].atan2(m[0][0]) - 2.0).abs() < 1e-12);
        assert!(s.eval(20.5).is_none());
        // A rotation vector round-trips, small angles included.
        for v in [[0.3, -0.2, 1.1], [1e-5, 2e-5, -1e-5], [0.0, 0.0, 0.0]] {
            let w = to_rotvec(from_rotvec(v));
            for k in 0..3 {
                assert!((w[k] - v[k]).abs() < 1e-14, "{v:?} {w:?}");
            }
        }
        assert!(normalize([0.0; 4]).is_none());
        let q = normalize([0.1, 0.2, 0.3, 0.9]).unwrap();
        let i = compose(inverse(q), q);
        assert!((i[3] - 1.0).abs() < 1e-15);
        assert_eq!(
            linear(&[0.0, 1.0], &[[0.0; 3], [2.0, 4.0, 6.0]], 0.25),
            Some([0.5, 1.0, 1.5])
        );
    }
}
