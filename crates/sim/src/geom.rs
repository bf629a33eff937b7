//! Plane geometry: polylines with arc length, oriented boxes and their overlap.

/// A point or vector in the world frame (x east, y north), m.
pub type P2 = [f64; 2];

/// `a + k·b`.
#[inline]
pub fn add(a: P2, b: P2, k: f64) -> P2 {
    [a[0] + k * b[0], a[1] + k * b[1]]
}

/// `a − b`.
#[inline]
pub fn sub(a: P2, b: P2) -> P2 {
    [a[0] - b[0], a[1] - b[1]]
}

/// Dot product.
#[inline]
pub fn dot(a: P2, b: P2) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// Distance.
#[inline]
pub fn dist(a: P2, b: P2) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Squared distance (no square root: for comparisons in hot loops).
#[inline]
pub fn dist2(a: P2, b: P2) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// Whether `a` and `b` are closer than `r`.
#[inline]
pub fn within(a: P2, b: P2, r: f64) -> bool {
    dist2(a, b) < r * r
}

/// The unit vector at heading `yaw`.
#[inline]
pub fn unit(yaw: f64) -> P2 {
    [yaw.cos(), yaw.sin()]
}

/// The vector rotated 90° to the right (`(y, −x)`).
#[inline]
pub fn right_of(u: P2) -> P2 {
    [u[1], -u[0]]
}

/// A polyline with its accumulated arc length.
#[derive(Debug, Clone, PartialEq)]
pub struct Poly {
    /// Points.
    pub pts: Vec<P2>,
    /// Arc length at each point (`s[0] = 0`).
    pub s: Vec<f64>,
}

impl Poly {
    /// A polyline through `pts` (duplicate consecutive points are dropped).
    pub fn new(pts: Vec<P2>) -> Self {
        let mut out: Vec<P2> = Vec::with_capacity(pts.len());
        let mut s = Vec::with_capacity(pts.len());
        for p in pts {
            match out.last() {
                Some(&q) => {
                    let d = dist(p, q);
                    if d > 1e-6 {
                        s.push(s.last().copied().unwrap_or(0.0) + d);
                        out.push(p);
                    }
                }
                None => {
                    s.push(0.0);
                    out.push(p);
                }
            }
        }
        Self { pts: out, s }
    }

    /// A straight segment sampled about every `step` m.
    pub fn line(a: P2, b: P2, step: f64) -> Self {
        let n = ((dist(a, b) / step).ceil() as usize).max(1);
        Self::new(
            (0..=n)
                .map(|k| {
                    let t = k as f64 / n as f64;
                    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
                })
                .collect(),
        )
    }

    /// A circular arc from `p0` with heading `u0` turning by `angle` (left positive) with
    /// radius `r`, sampled about every `step` m.
    pub fn arc(p0: P2, u0: P2, r: f64, angle: f64, step: f64) -> Self {
        let left = angle > 0.0;
        let n_vec = if left { [-u0[1], u0[0]] } else { right_of(u0) };
        let c = add(p0, n_vec, r);
        let a0 = (p0[1] - c[1]).atan2(p0[0] - c[0]);
        let len = r * angle.abs();
        let n = ((len / step).ceil() as usize).max(1);
        Self::new(
            (0..=n)
                .map(|k| {
                    let a = a0 + angle * k as f64 / n as f64;
                    [c[0] + r * a.cos(), c[1] + r * a.sin()]
                })
                .collect(),
        )
    }

    /// Length, m.
    pub fn length(&self) -> f64 {
        self.s.last().copied().unwrap_or(0.0)
    }

    /// Appends `other` (its first point is dropped when it repeats the last one).
    pub fn extend(&mut self, other: &Poly) {
        for &p in &other.pts {
            match self.pts.last() {
                Some(&q) => {
                    let d = dist(p, q);
                    if d > 1e-6 {
                        let s = self.s.last().copied().unwrap_or(0.0) + d;
                        self.s.push(s);
                        self.pts.push(p);
                    }
                }
                None => {
                    self.s.push(0.0);
                    self.pts.push(p);
                }
            }
        }
    }

    /// The segment index containing arc length `s` (clamped).
    fn seg(&self, s: f64) -> usize {
        let n = self.pts.len();
        if n < 2 {
            return 0;
        }
        match self.s.binary_search_by(|v| v.total_cmp(&s)) {
            Ok(i) => i.min(n - 2),
            Err(i) => i.saturating_sub(1).min(n - 2),
        }
    }

    /// Position and unit direction at arc length `s` (clamped to the ends, extrapolated
    /// along the last segment beyond the end).
    pub fn pose(&self, s: f64) -> (P2, P2) {
        let n = self.pts.len();
        if n == 0 {
            return ([0.0, 0.0], [1.0, 0.0]);
        }
        if n == 1 {
            return (self.pts[0], [1.0, 0.0]);
        }
        let i = self.seg(s);
        let (a, b) = (self.pts[i], self.pts[i + 1]);
        let len = self.s[i + 1] - self.s[i];
        let u = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
        let t = s.max(0.0) - self.s[i];
        (add(a, u, t), u)
    }

    /// The nearest point's arc length and signed lateral offset (left positive), searched
    /// over `[s_from, s_to]`.
    pub fn project(&self, p: P2, s_from: f64, s_to: f64) -> (f64, f64) {
        let n = self.pts.len();
        if n < 2 {
            return (0.0, 0.0);
        }
        let i0 = self.seg(s_from);
        let i1 = self.seg(s_to);
        let mut best = (0.0, 0.0, f64::INFINITY);
        for i in i0..=i1 {
            let (a, b) = (self.pts[i], self.pts[i + 1]);
            let len = self.s[i + 1] - self.s[i];
            let u = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
            let t = dot(sub(p, a), u).clamp(0.0, len);
            let q = add(a, u, t);
            let d = dist(p, q);
            if d < best.2 {
                let lat = u[0] * (p[1] - a[1]) - u[1] * (p[0] - a[0]);
                best = (self.s[i] + t, lat, d);
            }
        }
        (best.0, best.1)
    }
}

/// An oriented rectangle: centre, heading, half length and half width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obb {
    /// Centre, m.
    pub c: P2,
    /// Heading, rad.
    pub yaw: f64,
    /// Half length (along the heading), m.
    pub hl: f64,
    /// Half width, m.
    pub hw: f64,
}

impl Obb {
    fn axes(&self) -> (P2, P2) {
        let u = unit(self.yaw);
        (u, [-u[1], u[0]])
    }

    /// Whether two rectangles overlap (separating axis test).
    pub fn overlaps(&self, o: &Obb) -> bool {
        let (a0, a1) = self.axes();
        let (b0, b1) = o.axes();
        let d = sub(o.c, self.c);
        for ax in [a0, a1, b0, b1] {
            let ra = self.hl * dot(a0, ax).abs() + self.hw * dot(a1, ax).abs();
            let rb = o.hl * dot(b0, ax).abs() + o.hw * dot(b1, ax).abs();
            if dot(d, ax).abs() > ra + rb {
                return false;
            }
        }
        true
    }

    /// Whether a disc of radius `r` at `p` overlaps the rectangle.
    pub fn overlaps_disc(&self, p: P2, r: f64) -> bool {
        let (a0, a1) = self.axes();
        let d = sub(p, self.c);
        let x = dot(d, a0).clamp(-self.hl, self.hl);
        let y = dot(d, a1).clamp(-self.hw, self.hw);
        let q = add(add(self.c, a0, x), a1, y);
        dist(q, p) <= r
    }
}

/// A small seeded stream of uniform draws (Xoshiro256++ from `stats::seed`), cloneable: the
/// world's scene-building stream.
pub type Stream = fogline_world::scene::Draw;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poly_pose_and_projection() {
        let p = Poly::line([0.0, 0.0], [10.0, 0.0], 1.0);
        assert_eq!(p.pts.len(), 11);
        let (q, u) = p.pose(3.5);
        assert!((q[0] - 3.5).abs() < 1e-12 && q[1] == 0.0 && u == [1.0, 0.0]);
        let (s, lat) = p.project([4.2, 1.5], 0.0, 10.0);
        assert!((s - 4.2).abs() < 1e-12 && (lat - 1.5).abs() < 1e-12);
        let (_, lat) = p.project([4.2, -2.0], 0.0, 10.0);
        assert!((lat + 2.0).abs() < 1e-12);
        // Beyond the end: extrapolated.
        let (q, _) = p.pose(12.0);
        assert!((q[0] - 12.0).abs() < 1e-12);
    }

    #[test]
    fn arcs_turn_the_right_way() {
        // Right turn of 90° with radius 6 from the origin heading +x: ends at (6, −6).
        let a = Poly::arc(
            [0.0, 0.0],
            [1.0, 0.0],
            6.0,
            -std::f64::consts::FRAC_PI_2,
            0.5,
        );
        let end = *a.pts.last().unwrap();
        assert!((end[0] - 6.0).abs() < 1e-9 && (end[1] + 6.0).abs() < 1e-9);
        assert!((a.length() - 6.0 * std::f64::consts::FRAC_PI_2).abs() < 0.05);
        let l = Poly::arc(
            [0.0, 0.0],
            [1.0, 0.0],
            9.5,
            std::f64::consts::FRAC_PI_2,
            0.5,
        );
        let end = *l.pts.last().unwrap();
        assert!((end[0] - 9.5).abs() < 1e-9 && (end[1] - 9.5).abs() < 1e-9);
        let mut c = Poly::line([-5.0, 0.0], [0.0, 0.0], 1.0);
        c.extend(&a);
        assert!((c.length() - 5.0 - a.length()).abs() < 1e-9);
    }

    #[test]
    fn box_overlaps() {
        let a = Obb {
            c: [0.0, 0.0],
            yaw: 0.0,
            hl: 2.0,
            hw: 1.0,
        };
        let b = Obb {
            c: [3.9, 0.0],
            yaw: 0.0,
            hl: 2.0,
            hw: 1.0,
        };
        assert!(a.overlaps(&b));
        let c = Obb { c: [4.1, 0.0], ..b };
        assert!(!a.overlaps(&c));
        let d = Obb {
            c: [2.5, 2.5],
            yaw: std::f64::consts::FRAC_PI_4,
            hl: 2.0,
            hw: 0.5,
        };
        assert!(a.overlaps(&d));
        assert!(a.overlaps_disc([2.2, 0.0], 0.3));
        assert!(!a.overlaps_disc([2.4, 1.4], 0.3));
    }
}
