//! The renderer: one camera, one instant → RGB image, depth map and 2-D boxes.
//!
//! - **Ground** (`z = 0`): for a level camera without roll, every image row below the horizon
//!   meets the ground at one depth, and the ground point moves linearly along the row, so the
//!   ground costs a few additions per pixel plus the strip lookup. Markings are shaded by
//!   their exact coverage of the pixel's footprint (no aliasing sparkle on thin lines).
//! - **Sky**: a vertical gradient; depth `+inf`.
//! - **Solids**: every visible face of every cuboid and plate is clipped at the near plane,
//!   projected and scan-converted with a depth test (`1/z` is affine in the image).
//! - **Depth**: Euclidean distance from the camera centre, metres.
//! - **Boxes**: the bounding box of the pixels each tracked object wins in the depth test (the
//!   visible part), objects with fewer than [`MIN_BOX_PIXELS`] visible pixels left out.

use crate::scene::{Part, Rgb, Scene};
use fogline_perturb::frame::{DepthMap, Frame, ObjectBox};
use fogline_types::clip::CameraCalib;

/// Objects with fewer visible pixels get no box.
pub const MIN_BOX_PIXELS: u32 = 4;
/// Beyond this distance (along the axis) the ground is drawn as haze.
const FAR_M: f64 = 500.0;
/// Near clipping plane, m.
const NEAR_M: f64 = 0.05;

/// One rendered view.
pub struct View {
    /// RGB image.
    pub image: Frame,
    /// Distances, when asked for.
    pub depth: Option<DepthMap>,
    /// Boxes of the visible tracked objects.
    pub boxes: Vec<ObjectBox>,
}

/// The camera placed in the world at an instant.
struct Cam {
    c: [f64; 3],
    f: [f64; 3],
    r: [f64; 3],
    d: [f64; 3],
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    w: usize,
    h: usize,
}

impl Cam {
    fn to_cam(&self, p: [f64; 3]) -> [f64; 3] {
        let q = [p[0] - self.c[0], p[1] - self.c[1], p[2] - self.c[2]];
        [dot(q, self.r), dot(q, self.d), dot(q, self.f)]
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Renders `scene` through `calib` at time `t` (s relative to `t0`).
pub fn render(scene: &Scene, calib: &CameraCalib, t: f64, with_depth: bool) -> View {
    let (ex, ey, eh) = scene.ego.pose_at(t);
    let (sh, ch) = eh.sin_cos();
    let mut placed = *calib;
    placed.yaw_rad += eh;
    let [f, r, d] = placed.axes();
    let cam = Cam {
        c: [
            ex + ch * calib.x_m - sh * calib.y_m,
            ey + sh * calib.x_m + ch * calib.y_m,
            calib.z_m,
        ],
        f,
        r,
        d,
        fx: calib.fx,
        fy: calib.fy,
        cx: calib.cx,
        cy: calib.cy,
        w: calib.width as usize,
        h: calib.height as usize,
    };
    let n = cam.w * cam.h;
    let mut rgb = vec![0u8; n * 3];
    let mut zbuf = vec![f32::INFINITY; n];
    let mut ids = vec![0u16; n];
    draw_ground(scene, &cam, &mut rgb, &mut zbuf);
    for (i, solid) in scene.solids.iter().enumerate() {
        let id = if solid.tag.is_some() {
            (i + 1) as u16
        } else {
            0
        };
        let (pos, yaw) = solid.pose_at(t);
        for part in &solid.parts {
            draw_part(
                scene, &cam, part, pos, yaw, id, &mut rgb, &mut zbuf, &mut ids,
            );
        }
    }
    let boxes = boxes_of(scene, &ids, cam.w, cam.h);
    let depth = with_depth.then(|| {
        let mut dist = zbuf;
        // a² per column once (the same bits as computing it per pixel).
        let aa: Vec<f64> = (0..cam.w)
            .map(|u| {
                let a = (u as f64 + 0.5 - cam.cx) / cam.fx;
                a * a
            })
            .collect();
        for v in 0..cam.h {
            let b = (v as f64 + 0.5 - cam.cy) / cam.fy;
            let bb = b * b;
            for (z, &aa) in dist[v * cam.w..(v + 1) * cam.w].iter_mut().zip(&aa) {
                if z.is_finite() {
                    *z = (f64::from(*z) * (1.0 + aa + bb).sqrt()) as f32;
                }
            }
        }
        DepthMap::new(calib.width, calib.height, dist).expect("sizes match by construction")
    });
    View {
        image: Frame::new(calib.width, calib.height, rgb).expect("sizes match by construction"),
        depth,
        boxes,
    }
}

#[inline]
fn put(rgb: &mut [u8], i: usize, c: Rgb) {
    rgb[3 * i] = to_u8(c[0]);
    rgb[3 * i + 1] = to_u8(c[1]);
    rgb[3 * i + 2] = to_u8(c[2]);
}

/// `x.clamp(0, 255).round() as u8`, bit for bit, without a call to `roundf` (which is not
/// inlined on baseline x86-64): for `0 ≤ x < 2^24` the fractional part `x − trunc(x)` is exact,
/// and rounding is half away from zero. NaN gives 0, as `round` does.
#[inline]
fn to_u8(x: f32) -> u8 {
    let x = x.clamp(0.0, 255.0);
    let i = x as u32;
    (i + u32::from(x - i as f32 >= 0.5)) as u8
}

/// `x.floor() as i64`, exactly, for `|x| < 2^62` (no call to `floor`).
#[inline]
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x { t - 1 } else { t }
}

#[inline]
fn mix(a: Rgb, b: Rgb, t: f32) -> Rgb {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

#[inline]
fn scale(a: Rgb, k: f32) -> Rgb {
    [a[0] * k, a[1] * k, a[2] * k]
}

/// A hash of a ground cell, uniform in `[-1, 1)`.
#[inline]
fn cell_noise(seed: u64, x: f64, y: f64) -> f32 {
    let (ix, iy) = (floor_i64(x * 4.0) as u64, floor_i64(y * 4.0) as u64);
    let mut h =
        seed ^ ix.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ iy.wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    ((h >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
}

/// Coverage of a band of half-width `half` at distance `dist` from its centre line, for a
/// pixel footprint `fp` (box filter).
#[inline]
fn coverage(dist: f64, half: f64, fp: f64) -> f32 {
    let fp = fp.max(1e-6);
    let a = (dist - fp * 0.5).max(-half);
    let b = (dist + fp * 0.5).min(half);
    ((b - a) / fp).clamp(0.0, 1.0) as f32
}

fn draw_ground(scene: &Scene, cam: &Cam, rgb: &mut [u8], zbuf: &mut [f32]) {
    let look = &scene.look;
    let light = look.light;
    let haze = scale(look.sky_horizon, 0.92);
    for v in 0..cam.h {
        let b = (v as f64 + 0.5 - cam.cy) / cam.fy;
        let rz = cam.f[2] + b * cam.d[2];
        let row = v * cam.w;
        if rz >= -1e-9 || cam.c[2] / -rz > FAR_M {
            // Sky (or ground too far to resolve: haze at its distance).
            let far = rz < -1e-9;
            let above = ((cam.cy - (v as f64 + 0.5)) / cam.cy).clamp(0.0, 1.0) as f32;
            let sky = mix(look.sky_horizon, look.sky_zenith, above.sqrt());
            let c = if far { haze } else { sky };
            let z = if far {
                (cam.c[2] / -rz) as f32
            } else {
                f32::INFINITY
            };
            for u in 0..cam.w {
                put(rgb, row + u, c);
                zbuf[row + u] = z;
            }
            continue;
        }
        let tt = cam.c[2] / -rz;
        let a0 = (0.5 - cam.cx) / cam.fx;
        let ray0 = [
            cam.f[0] + a0 * cam.r[0] + b * cam.d[0],
            cam.f[1] + a0 * cam.r[1] + b * cam.d[1],
        ];
        let (mut gx, mut gy) = (cam.c[0] + tt * ray0[0], cam.c[1] + tt * ray0[1]);
        let (sx, sy) = (tt * cam.r[0] / cam.fx, tt * cam.r[1] / cam.fx);
        let fp_lat = tt / cam.fx;
        let fp_long = tt * tt / (cam.fy * cam.c[2]);
        let tex_amp = (1.0 / (1.0 + tt / 30.0)) as f32;
        let aerial = ((tt / FAR_M) as f32).min(1.0) * 0.6;
        for u in 0..cam.w {
            let c = ground_color(scene, gx, gy, fp_lat, fp_long, tex_amp);
            let c = mix(scale(c, light), haze, aerial);
            put(rgb, row + u, c);
            zbuf[row + u] = tt as f32;
            gx += sx;
            gy += sy;
        }
    }
}

const WHITE: Rgb = [232.0, 232.0, 226.0];
const KERB: Rgb = [196.0, 194.0, 188.0];

#[inline]
fn ground_color(scene: &Scene, x: f64, y: f64, fp_lat: f64, fp_long: f64, tex: f32) -> Rgb {
    let look = &scene.look;
    let p = [x, y];
    for strip in &scene.strips {
        let (s, d) = strip.centre.local(p);
        if s < strip.s_min || s > strip.s_max {
            continue;
        }
        if d < strip.d_min - strip.walk || d > strip.d_max + strip.walk {
            continue;
        }
        let n = cell_noise(scene.texture_seed, x, y) * tex;
        if d < strip.d_min || d > strip.d_max {
            let edge = (d - strip.d_min).abs().min((d - strip.d_max).abs());
            let base = if edge < 0.25 { KERB } else { look.walk };
            return [base[0] + 6.0 * n, base[1] + 6.0 * n, base[2] + 6.0 * n];
        }
        let mut c = [
            look.asphalt[0] + 7.0 * n,
            look.asphalt[1] + 7.0 * n,
            look.asphalt[2] + 7.0 * n,
        ];
        for m in &strip.marks {
            if s < m.s_min || s > m.s_max {
                continue;
            }
            let mut cov = coverage(d - m.d, m.width * 0.5, fp_lat);
            if cov <= 0.0 {
                continue;
            }
            if let Some((len, period)) = m.dash {
                let ph = s.rem_euclid(period) - len * 0.5;
                cov *= coverage(ph, len * 0.5, fp_long);
            }
            c = mix(c, m.color, cov);
        }
        for bar in &strip.bars {
            if d < bar.d_min || d > bar.d_max || s < bar.s_min - fp_long || s > bar.s_max + fp_long
            {
                continue;
            }
            let mid = 0.5 * (bar.s_min + bar.s_max);
            let mut cov = coverage(s - mid, 0.5 * (bar.s_max - bar.s_min), fp_long);
            if let Some((w, period)) = bar.stripes {
                let ph = (d - bar.d_min).rem_euclid(period) - w * 0.5;
                cov *= coverage(ph, w * 0.5, fp_lat);
            }
            c = mix(c, WHITE, cov);
        }
        return c;
    }
    let n = cell_noise(scene.texture_seed ^ 0x55, x, y) * tex;
    [
        look.terrain[0] + 12.0 * n,
        look.terrain[1] + 16.0 * n,
        look.terrain[2] + 8.0 * n,
    ]
}

/// A polygon in camera coordinates with its colour, ready for clipping and scan conversion.
#[allow(clippy::too_many_arguments)]
fn draw_part(
    scene: &Scene,
    cam: &Cam,
    part: &Part,
    pos: [f64; 2],
    yaw: f64,
    id: u16,
    rgb: &mut [u8],
    zbuf: &mut [f32],
    ids: &mut [u16],
) {
    let (sy, cy) = yaw.sin_cos();
    let to_world = |p: [f64; 3]| {
        [
            pos[0] + cy * p[0] - sy * p[1],
            pos[1] + sy * p[0] + cy * p[1],
            p[2],
        ]
    };
    let light = scene.look.light;
    match *part {
        Part::Cuboid {
            centre,
            half,
            color,
        } => {
            let wc = to_world(centre);
            // Quick reject: entirely behind the camera.
            let cc = cam.to_cam(wc);
            let rad = (half[0] * half[0] + half[1] * half[1] + half[2] * half[2]).sqrt();
            if cc[2] < -rad {
                return;
            }
            // Faces: (local normal, the 4 corners in order).
            const FACES: [([f64; 3], [[f64; 3]; 4]); 6] = [
                (
                    [1.0, 0.0, 0.0],
                    [
                        [1.0, -1.0, -1.0],
                        [1.0, 1.0, -1.0],
                        [1.0, 1.0, 1.0],
                        [1.0, -1.0, 1.0],
                    ],
                ),
                (
                    [-1.0, 0.0, 0.0],
                    [
                        [-1.0, 1.0, -1.0],
                        [-1.0, -1.0, -1.0],
                        [-1.0, -1.0, 1.0],
                        [-1.0, 1.0, 1.0],
                    ],
                ),
                (
                    [0.0, 1.0, 0.0],
                    [
                        [1.0, 1.0, -1.0],
                        [-1.0, 1.0, -1.0],
                        [-1.0, 1.0, 1.0],
                        [1.0, 1.0, 1.0],
                    ],
                ),
                (
                    [0.0, -1.0, 0.0],
                    [
                        [-1.0, -1.0, -1.0],
                        [1.0, -1.0, -1.0],
                        [1.0, -1.0, 1.0],
                        [-1.0, -1.0, 1.0],
                    ],
                ),
                (
                    [0.0, 0.0, 1.0],
                    [
                        [-1.0, -1.0, 1.0],
                        [1.0, -1.0, 1.0],
                        [1.0, 1.0, 1.0],
                        [-1.0, 1.0, 1.0],
                    ],
                ),
                (
                    [0.0, 0.0, -1.0],
                    [
                        [-1.0, 1.0, -1.0],
                        [1.0, 1.0, -1.0],
                        [1.0, -1.0, -1.0],
                        [-1.0, -1.0, -1.0],
                    ],
                ),
            ];
            for (nl, corners) in FACES {
                let nw = [cy * nl[0] - sy * nl[1], sy * nl[0] + cy * nl[1], nl[2]];
                let fc = to_world([
                    centre[0] + nl[0] * half[0],
                    centre[1] + nl[1] * half[1],
                    centre[2] + nl[2] * half[2],
                ]);
                let to_face = [fc[0] - cam.c[0], fc[1] - cam.c[1], fc[2] - cam.c[2]];
                if dot(to_face, nw) >= 0.0 {
                    continue;
                }
                let shade = 0.5 + 0.5 * dot(nw, scene.look.sun).max(0.0) as f32;
                let col = scale(color, shade * light);
                let poly: Vec<[f64; 3]> = corners
                    .iter()
                    .map(|k| {
                        cam.to_cam(to_world([
                            centre[0] + k[0] * half[0],
                            centre[1] + k[1] * half[1],
                            centre[2] + k[2] * half[2],
                        ]))
                    })
                    .collect();
                fill_polygon(cam, &poly, col, id, rgb, zbuf, ids);
            }
        }
        Part::Plate {
            centre,
            radius,
            sides,
            facing,
            color,
            emissive,
        } => {
            let a = yaw + facing;
            let nw = [a.cos(), a.sin(), 0.0];
            let wc = to_world(centre);
            let to_face = [wc[0] - cam.c[0], wc[1] - cam.c[1], wc[2] - cam.c[2]];
            if dot(to_face, nw) >= 0.0 {
                return;
            }
            // In-plane axes: horizontal (left of the facing direction) and up.
            let hx = [-nw[1], nw[0]];
            let poly: Vec<[f64; 3]> = (0..sides)
                .map(|k| {
                    let th = std::f64::consts::TAU * (k as f64 + 0.5) / f64::from(sides);
                    let (s, c) = th.sin_cos();
                    cam.to_cam([
                        wc[0] + radius * c * hx[0],
                        wc[1] + radius * c * hx[1],
                        wc[2] + radius * s,
                    ])
                })
                .collect();
            let col = if emissive {
                color
            } else {
                scale(
                    color,
                    light * (0.55 + 0.45 * dot(nw, scene.look.sun).max(0.0) as f32),
                )
            };
            fill_polygon(cam, &poly, col, id, rgb, zbuf, ids);
        }
    }
}

/// Clips a convex polygon (camera coordinates) at the near plane and scan-converts it.
fn fill_polygon(
    cam: &Cam,
    poly: &[[f64; 3]],
    col: Rgb,
    id: u16,
    rgb: &mut [u8],
    zbuf: &mut [f32],
    ids: &mut [u16],
) {
    // Near-plane clip (Sutherland–Hodgman on z >= NEAR).
    let mut clipped: Vec<[f64; 3]> = Vec::with_capacity(poly.len() + 2);
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        let (ina, inb) = (a[2] >= NEAR_M, b[2] >= NEAR_M);
        if ina {
            clipped.push(a);
        }
        if ina != inb {
            let t = (NEAR_M - a[2]) / (b[2] - a[2]);
            clipped.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), NEAR_M]);
        }
    }
    if clipped.len() < 3 {
        return;
    }
    // Plane n·X = k in camera coordinates (for 1/z per pixel).
    let e1 = sub(clipped[1], clipped[0]);
    let e2 = sub(clipped[2], clipped[0]);
    let mut nrm = cross(e1, e2);
    if dot(nrm, nrm) < 1e-18 {
        // Degenerate first triple: find any non-collinear one.
        let mut found = false;
        for k in 3..clipped.len() {
            nrm = cross(e1, sub(clipped[k], clipped[0]));
            if dot(nrm, nrm) >= 1e-18 {
                found = true;
                break;
            }
        }
        if !found {
            return;
        }
    }
    let k = dot(nrm, clipped[0]);
    if k.abs() < 1e-12 {
        return; // seen edge-on
    }
    let pts: Vec<(f64, f64)> = clipped
        .iter()
        .map(|p| (cam.cx + cam.fx * p[0] / p[2], cam.cy + cam.fy * p[1] / p[2]))
        .collect();
    let vmin = pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let vmax = pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let y0 = ((vmin - 0.5).ceil().max(0.0)) as usize;
    let y1 = (vmax - 0.5).floor().min(cam.h as f64 - 1.0);
    if y1 < 0.0 {
        return;
    }
    let y1 = y1 as usize;
    let c8 = [to_u8(col[0]), to_u8(col[1]), to_u8(col[2])];
    // 1/z = (n.x·a + n.y·b + n.z)/k with a = (u - cx)/fx, b = (v - cy)/fy.
    let (ia, ib, ic) = (nrm[0] / (k * cam.fx), nrm[1] / (k * cam.fy), nrm[2] / k);
    let ic = ic - ia * cam.cx - ib * cam.cy;
    for y in y0..=y1.min(cam.h.saturating_sub(1)) {
        let vc = y as f64 + 0.5;
        let (mut umin, mut umax) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..pts.len() {
            let (p, q) = (pts[i], pts[(i + 1) % pts.len()]);
            if (p.1 <= vc && q.1 >= vc) || (q.1 <= vc && p.1 >= vc) {
                let u = if (q.1 - p.1).abs() < 1e-12 {
                    umin = umin.min(p.0.min(q.0));
                    umax = umax.max(p.0.max(q.0));
                    continue;
                } else {
                    p.0 + (vc - p.1) * (q.0 - p.0) / (q.1 - p.1)
                };
                umin = umin.min(u);
                umax = umax.max(u);
            }
        }
        if umin > umax {
            continue;
        }
        let x0 = (umin - 0.5).ceil().max(0.0);
        let x1 = (umax - 0.5).floor().min(cam.w as f64 - 1.0);
        if x1 < x0 {
            continue;
        }
        let row = y * cam.w;
        for x in x0 as usize..=x1 as usize {
            let inv_z = ia * (x as f64 + 0.5) + ib * vc + ic;
            if inv_z <= 0.0 {
                continue;
            }
            let z = (1.0 / inv_z) as f32;
            let i = row + x;
            if z < zbuf[i] {
                zbuf[i] = z;
                ids[i] = id;
                rgb[3 * i..3 * i + 3].copy_from_slice(&c8);
            }
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn boxes_of(scene: &Scene, ids: &[u16], w: usize, h: usize) -> Vec<ObjectBox> {
    let n = scene.solids.len();
    // (x0, y0, x1, y1, count) per solid.
    let mut acc = vec![(usize::MAX, usize::MAX, 0usize, 0usize, 0u32); n];
    for y in 0..h {
        for (x, &id) in ids[y * w..(y + 1) * w].iter().enumerate() {
            if id != 0 {
                let a = &mut acc[usize::from(id) - 1];
                a.0 = a.0.min(x);
                a.1 = a.1.min(y);
                a.2 = a.2.max(x);
                a.3 = a.3.max(y);
                a.4 += 1;
            }
        }
    }
    let mut out = Vec::new();
    for (i, a) in acc.iter().enumerate() {
        if a.4 < MIN_BOX_PIXELS {
            continue;
        }
        if let Some((class, track)) = scene.solids[i].tag {
            out.push(ObjectBox {
                class: class.label().to_string(),
                track_id: Some(track),
                x_px: a.0 as f64,
                y_px: a.1 as f64,
                width_px: (a.2 - a.0 + 1) as f64,
                height_px: (a.3 - a.1 + 1) as f64,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_rounding_and_floor_match_the_library_bit_for_bit() {
        let mut x = -3.0f32;
        while x < 260.0 {
            let up = f32::from_bits(x.to_bits().wrapping_add(1));
            let down = f32::from_bits(x.to_bits().wrapping_sub(1));
            for v in [x, up, down, x + 0.5, x - 0.5] {
                assert_eq!(to_u8(v), v.clamp(0.0, 255.0).round() as u8, "{v}");
            }
            x += 0.031_25;
        }
        for v in [
            0.499_999_97_f32,
            0.5,
            254.5,
            255.49,
            f32::NAN,
            f32::INFINITY,
            -0.0,
        ] {
            assert_eq!(to_u8(v), v.clamp(0.0, 255.0).round() as u8, "{v}");
        }
        let mut y = -1e6f64;
        while y < 1e6 {
            for v in [y, y + 1e-9, y - 1e-9, y.trunc(), -y.trunc()] {
                assert_eq!(floor_i64(v), v.floor() as i64, "{v}");
            }
            y += 977.123;
        }
    }
}
