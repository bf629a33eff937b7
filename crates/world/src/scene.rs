//! The scene: roads (as ground strips with markings), solids (cuboids and flat polygons, some
//! of them tracked objects that move), lighting, and the ego's own motion.

use fogline_stats::seed::Xoshiro256pp;

/// An RGB colour, linear 0–255 floats.
pub type Rgb = [f32; 3];

/// A road piece's centreline, in world coordinates (the rig frame at `t0`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Centre {
    /// A straight line through `origin` along the unit vector `dir`.
    Line {
        /// Point at `s = 0`.
        origin: [f64; 2],
        /// Unit direction of travel.
        dir: [f64; 2],
    },
    /// A circular arc around `centre`: radius `radius`; `left` when it curves left (the centre
    /// lies on the left of travel); `s = 0` at polar angle `start`.
    Arc {
        /// Circle centre.
        centre: [f64; 2],
        /// Centreline radius.
        radius: f64,
        /// Curving left.
        left: bool,
        /// Polar angle at `s = 0`.
        start: f64,
    },
}

impl Centre {
    /// `(s, d)`: arc length along the centreline and lateral offset (left positive).
    #[inline]
    pub fn local(&self, p: [f64; 2]) -> (f64, f64) {
        match *self {
            Centre::Line { origin, dir } => {
                let (rx, ry) = (p[0] - origin[0], p[1] - origin[1]);
                (rx * dir[0] + ry * dir[1], dir[0] * ry - dir[1] * rx)
            }
            Centre::Arc {
                centre,
                radius,
                left,
                start,
            } => {
                let (rx, ry) = (p[0] - centre[0], p[1] - centre[1]);
                let dist = (rx * rx + ry * ry).sqrt();
                let mut a = fast_atan2(ry, rx) - start;
                if left {
                    a = wrap(a);
                    (radius * a, radius - dist)
                } else {
                    a = wrap(-a);
                    (radius * a, dist - radius)
                }
            }
        }
    }
}

fn wrap(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    // `a % tau` is `a` itself when |a| < tau (the usual case): skip the fmod call.
    let mut a = if a.abs() < tau { a } else { a % tau };
    if a > std::f64::consts::PI {
        a -= tau;
    } else if a <= -std::f64::consts::PI {
        a += tau;
    }
    a
}

/// `atan2` to about 1e-5 rad (enough for dash phases; the exact one is slow per pixel).
#[inline]
pub fn fast_atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    if ax == 0.0 && ay == 0.0 {
        return 0.0;
    }
    let (mn, mx) = if ax < ay { (ax, ay) } else { (ay, ax) };
    let a = mn / mx;
    let s = a * a;
    // Minimax polynomial for atan on [0, 1].
    let mut r = ((((-0.013_480_470 * s + 0.057_477_314) * s - 0.121_239_071) * s + 0.195_635_925)
        * s
        - 0.332_994_597)
        * s
        * a
        + 0.999_995_630 * a;
    if ay > ax {
        r = std::f64::consts::FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = std::f64::consts::PI - r;
    }
    if y < 0.0 { -r } else { r }
}

/// A longitudinal marking: a line at lateral offset `d`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mark {
    /// Lateral position, m.
    pub d: f64,
    /// Width, m.
    pub width: f64,
    /// `(dash length, period)` in m for a dashed line, `None` for a solid one.
    pub dash: Option<(f64, f64)>,
    /// Colour.
    pub color: Rgb,
    /// Extent along the strip.
    pub s_min: f64,
    /// Extent along the strip.
    pub s_max: f64,
}

/// A transverse marking: a stop line (solid bar) or a zebra crossing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bar {
    /// Extent along the strip.
    pub s_min: f64,
    /// Extent along the strip.
    pub s_max: f64,
    /// Lateral extent.
    pub d_min: f64,
    /// Lateral extent.
    pub d_max: f64,
    /// Stripes along `d` (`stripe width`, `period`) for a zebra, `None` for a solid bar.
    pub stripes: Option<(f64, f64)>,
}

/// A piece of road: asphalt between `d_min` and `d_max` for `s` in `[s_min, s_max]`, a
/// sidewalk of width `walk` beyond each edge, its markings.
#[derive(Debug, Clone, PartialEq)]
pub struct Strip {
    /// The centreline.
    pub centre: Centre,
    /// Extent along the centreline.
    pub s_min: f64,
    /// Extent along the centreline.
    pub s_max: f64,
    /// Right edge of the asphalt (negative).
    pub d_min: f64,
    /// Left edge of the asphalt.
    pub d_max: f64,
    /// Sidewalk width beyond each edge (0 for none).
    pub walk: f64,
    /// Longitudinal markings.
    pub marks: Vec<Mark>,
    /// Transverse markings.
    pub bars: Vec<Bar>,
}

/// What a tracked object is (its box class).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectClass {
    /// A car.
    Car,
    /// A truck or van.
    Truck,
    /// A pedestrian.
    Pedestrian,
    /// A cyclist with a bicycle.
    Cyclist,
    /// A stop sign.
    StopSign,
    /// A traffic light.
    TrafficLight,
    /// A traffic cone or barrier.
    Barrier,
}

impl ObjectClass {
    /// The box class label.
    pub fn label(self) -> &'static str {
        match self {
            ObjectClass::Car => "car",
            ObjectClass::Truck => "truck",
            ObjectClass::Pedestrian => "pedestrian",
            ObjectClass::Cyclist => "cyclist",
            ObjectClass::StopSign => "stop_sign",
            ObjectClass::TrafficLight => "traffic_light",
            ObjectClass::Barrier => "barrier",
        }
    }
}

/// A part of a solid, in the solid's local frame (x forward, y left, z up).
#[derive(Debug, Clone, PartialEq)]
pub enum Part {
    /// A box: centre, half extents.
    Cuboid {
        /// Centre.
        centre: [f64; 3],
        /// Half extents along x, y, z.
        half: [f64; 3],
        /// Colour.
        color: Rgb,
    },
    /// A flat regular polygon (disc, octagon, square lamp) facing along local yaw `facing`.
    Plate {
        /// Centre.
        centre: [f64; 3],
        /// Circumradius.
        radius: f64,
        /// Number of sides.
        sides: u32,
        /// Direction the face looks to, local yaw (0 = +x).
        facing: f64,
        /// Colour.
        color: Rgb,
        /// Emits light (not shaded, not dimmed by dusk).
        emissive: bool,
    },
}

/// A rigid body in the scene: parts, a pose at `t0`, constant acceleration along its heading.
#[derive(Debug, Clone, PartialEq)]
pub struct Solid {
    /// Parts in the local frame.
    pub parts: Vec<Part>,
    /// Position at `t0`.
    pub pos: [f64; 2],
    /// Heading.
    pub yaw: f64,
    /// Speed at `t0`, m/s (along the heading).
    pub speed: f64,
    /// Acceleration, m/s² (along the heading).
    pub accel: f64,
    /// Class and track id when the object gets boxes.
    pub tag: Option<(ObjectClass, u64)>,
}

impl Solid {
    /// Position and heading at time `t` (s relative to `t0`).
    pub fn pose_at(&self, t: f64) -> ([f64; 2], f64) {
        let s = self.speed * t + 0.5 * self.accel * t * t;
        (
            [
                self.pos[0] + s * self.yaw.cos(),
                self.pos[1] + s * self.yaw.sin(),
            ],
            self.yaw,
        )
    }
}

/// Ground and sky palette plus the light level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Look {
    /// Diffuse light level (1 = noon, lower at dusk).
    pub light: f32,
    /// Sky colour at the horizon.
    pub sky_horizon: Rgb,
    /// Sky colour at the top of the image.
    pub sky_zenith: Rgb,
    /// Asphalt.
    pub asphalt: Rgb,
    /// Sidewalk.
    pub walk: Rgb,
    /// Off-road ground.
    pub terrain: Rgb,
    /// Unit vector to the sun.
    pub sun: [f64; 3],
}

/// The ego's motion over the history: constant speed along a path through the origin.
#[derive(Debug, Clone, PartialEq)]
pub struct EgoMotion {
    /// Speed, m/s.
    pub speed: f64,
    /// Curvature of the path behind `t0`, 1/m (left positive).
    pub kappa: f64,
}

impl EgoMotion {
    /// Pose `(x, y, yaw)` at time `t <= 0`.
    pub fn pose_at(&self, t: f64) -> (f64, f64, f64) {
        let s = self.speed * t;
        if self.kappa.abs() < 1e-9 {
            (s, 0.0, 0.0)
        } else {
            let h = self.kappa * s;
            (h.sin() / self.kappa, (1.0 - h.cos()) / self.kappa, h)
        }
    }
}

/// A whole scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Road strips, in priority order (the first containing a point decides it).
    pub strips: Vec<Strip>,
    /// Solids.
    pub solids: Vec<Solid>,
    /// Palette and light.
    pub look: Look,
    /// The ego's motion over the history.
    pub ego: EgoMotion,
    /// Texture seed.
    pub texture_seed: u64,
}

/// Uniform draws for scene building (and the closed-loop simulator's streams).
#[derive(Debug, Clone)]
pub struct Draw(Xoshiro256pp);

impl Draw {
    /// A stream for `(seed, path)`.
    pub fn new(seed: u64, path: &[u64]) -> Self {
        Self(Xoshiro256pp::new(seed, path))
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[a, b)`.
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.unit()
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }

    /// An integer in `[0, n)`.
    pub fn index(&mut self, n: usize) -> usize {
        ((self.unit() * n as f64) as usize).min(n.saturating_sub(1))
    }

    /// One of `items`.
    pub fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.index(items.len())]
    }

    /// 64 raw bits.
    pub fn bits(&mut self) -> u64 {
        self.0.next_u64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_atan2_is_close() {
        for i in 0..2000 {
            let a = i as f64 * 0.0031 - 3.1;
            let (y, x) = (a.sin() * 7.0, a.cos() * 7.0);
            assert!((fast_atan2(y, x) - y.atan2(x)).abs() < 2e-5, "{a}");
        }
    }

    #[test]
    fn arc_local_coordinates() {
        // A left curve of radius 50 starting at the origin heading +x: centre (0, 50).
        let c = Centre::Arc {
            centre: [0.0, 50.0],
            radius: 50.0,
            left: true,
            start: -std::f64::consts::FRAC_PI_2,
        };
        let (s, d) = c.local([0.0, 1.0]);
        assert!(s.abs() < 1e-4 && (d - 1.0).abs() < 1e-9);
        let q = std::f64::consts::FRAC_PI_4;
        let (s, d) = c.local([50.0 * q.sin(), 50.0 - 50.0 * q.cos()]);
        assert!((s - 50.0 * q).abs() < 1e-3 && d.abs() < 1e-9);
        let r = Centre::Arc {
            centre: [0.0, -50.0],
            radius: 50.0,
            left: false,
            start: std::f64::consts::FRAC_PI_2,
        };
        let (s, d) = r.local([50.0 * q.sin(), -50.0 + 50.0 * q.cos()]);
        assert!((s - 50.0 * q).abs() < 1e-3 && d.abs() < 1e-9);
        let (_, d) = r.local([0.0, -1.0]);
        assert!((d + 1.0).abs() < 1e-9);
    }
}
