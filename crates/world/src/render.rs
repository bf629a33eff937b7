//! The renderer: one camera, one instant → RGB image, depth map and 2-D boxes.
//!
//! - **Ground** (`z = 0`): for a level camera without roll, every image row below the horizon
//!   meets the ground at one depth, and the ground point moves linearly along the row, so the
//!   ground costs a few additions per pixel plus the strip lookup. The lookup only visits the
//!   strips, markings and bars that may touch a block of [`BLOCK`] pixels (conservative
//!   ranges of the strip coordinates over the block; the others could not change the pixel).
//!   Markings are shaded by their exact coverage of the pixel's footprint (no aliasing sparkle
//!   on thin lines). The ground is drawn after the solids and shaded only where it wins the
//!   depth test: the same image as drawing it first.
//! - **Sky**: a vertical gradient; depth `+inf`.
//! - **Solids**: every visible face of every cuboid and plate is clipped at the near plane,
//!   projected and scan-converted with a depth test (`1/z` is affine in the image).
//! - **Depth**: Euclidean distance from the camera centre, metres (the per-pixel factors from
//!   depth along the axis are computed once per calibration).
//! - **Boxes**: the bounding box of the pixels each tracked object wins in the depth test (the
//!   visible part), objects with fewer than [`MIN_BOX_PIXELS`] visible pixels left out.

use crate::scene::{Bar, Centre, Mark, Part, Rgb, Scene, Strip};
use fogline_perturb::frame::{DepthMap, Frame, ObjectBox};
use fogline_types::clip::CameraCalib;
use std::f64::consts::{PI, TAU};
use std::sync::{Arc, Mutex, PoisonError};

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
    // Solids first, then the ground only where it wins the depth test: the same pixels, depths
    // and ids as drawing the ground first (see `draw_ground`), without shading hidden ground.
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
    draw_ground(scene, &cam, &mut rgb, &mut zbuf, &mut ids);
    let boxes = boxes_of(scene, &ids, cam.w, cam.h);
    let depth = with_depth.then(|| {
        let mut dist = zbuf;
        let factors = depth_factors(&cam);
        for (z, &k) in dist.iter_mut().zip(factors.iter()) {
            // `+inf` (sky) stays `+inf`: the same as leaving it alone (there is no NaN).
            *z = (f64::from(*z) * k) as f32;
        }
        DepthMap::new(calib.width, calib.height, dist).expect("sizes match by construction")
    });
    View {
        image: Frame::new(calib.width, calib.height, rgb).expect("sizes match by construction"),
        depth,
        boxes,
    }
}

/// Per-pixel factors from depth along the axis to distance from the camera centre.
type Factors = Arc<[f64]>;

/// The factors `sqrt(1 + a² + b²)` of a calibration's pixels (row-major), the same bits as
/// computing them per frame; computed once per calibration and kept for the most recent ones
/// (the rig's four cameras, and more), up to [`FACTORS_KEPT`] values in all.
fn depth_factors(cam: &Cam) -> Factors {
    type Cache = Vec<([u64; 6], Factors)>;
    static CACHE: Mutex<Cache> = Mutex::new(Vec::new());
    let key = [
        cam.fx.to_bits(),
        cam.fy.to_bits(),
        cam.cx.to_bits(),
        cam.cy.to_bits(),
        cam.w as u64,
        cam.h as u64,
    ];
    let lock = || CACHE.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((_, f)) = lock().iter().find(|(k, _)| *k == key) {
        return Arc::clone(f);
    }
    // a² per column once (the same bits as computing it per pixel).
    let aa: Vec<f64> = (0..cam.w)
        .map(|u| {
            let a = (u as f64 + 0.5 - cam.cx) / cam.fx;
            a * a
        })
        .collect();
    let mut f = Vec::with_capacity(cam.w * cam.h);
    for v in 0..cam.h {
        let b = (v as f64 + 0.5 - cam.cy) / cam.fy;
        let bb = b * b;
        f.extend(aa.iter().map(|&aa| (1.0 + aa + bb).sqrt()));
    }
    let f: Factors = f.into();
    let mut cache = lock();
    if !cache.iter().any(|(k, _)| *k == key) {
        // Oldest first out.
        while !cache.is_empty()
            && cache.iter().map(|(_, f)| f.len()).sum::<usize>() + f.len() > FACTORS_KEPT
        {
            cache.remove(0);
        }
        cache.push((key, Arc::clone(&f)));
    }
    f
}

/// At most this many depth factors (64 MiB) are kept across frames.
const FACTORS_KEPT: usize = 1 << 23;

/// `x.clamp(0, 255).round() as u8`, bit for bit, without a call to `roundf` (which is not
/// inlined on baseline x86-64) and in float arithmetic only (so that [`to_u8_row`] vectorises):
/// for `0 ≤ x ≤ 255`, adding and taking away 2^23 gives the nearest integer exactly, one less
/// when above `x` is `floor(x)`; the fractional part `x − floor(x)` is exact, and rounding is
/// half away from zero. NaN gives 0, as `round` does (a test checks every `f32` in
/// [¼, 512) and a stride through all other bit patterns).
#[inline]
fn to_u8(x: f32) -> u8 {
    const MAGIC: f32 = 8_388_608.0;
    // Not `clamp`, which keeps NaN: NaN → 0 here (one `maxps`, one `minps`).
    let x = if x > 0.0 { x } else { 0.0 };
    let x = if x < 255.0 { x } else { 255.0 };
    let r = (x + MAGIC) - MAGIC;
    let floor = if r > x { r - 1.0 } else { r };
    let v = if x - floor >= 0.5 { floor + 1.0 } else { floor };
    // `v + 2^23` holds the integer `v` in its low mantissa bits.
    (v + MAGIC).to_bits() as u8
}

/// [`to_u8`] over a row of channels (a loop the compiler vectorises).
#[inline]
fn to_u8_row(src: &[f32], dst: &mut [u8]) {
    for (d, &x) in dst.iter_mut().zip(src) {
        *d = to_u8(x);
    }
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

/// Pixels per block of a ground row for the strip culling.
const BLOCK: usize = 16;
/// Slack on the conservative `(s, d)` ranges of a block, m (float error is ~1e-10 m).
const SLACK_M: f64 = 1e-3;
/// Slack on polar angles, rad (`fast_atan2` is within 2e-5 rad).
const SLACK_RAD: f64 = 1e-3;

/// Conservative ranges of `(s, d)` (as [`Centre::local`] computes them) over the ground points
/// of a block of pixels: the segment from `p0` to `p1`.
struct Span {
    s: (f64, f64),
    d: (f64, f64),
}

fn span(centre: &Centre, p0: [f64; 2], p1: [f64; 2]) -> Span {
    match *centre {
        Centre::Line { .. } => {
            // Affine along the segment: the extremes are at its ends.
            let (s0, d0) = centre.local(p0);
            let (s1, d1) = centre.local(p1);
            let es = SLACK_M + 1e-9 * (s0.abs() + s1.abs());
            let ed = SLACK_M + 1e-9 * (d0.abs() + d1.abs());
            Span {
                s: (s0.min(s1) - es, s0.max(s1) + es),
                d: (d0.min(d1) - ed, d0.max(d1) + ed),
            }
        }
        Centre::Arc {
            centre: c,
            radius,
            left,
            start,
        } => {
            let v0 = [p0[0] - c[0], p0[1] - c[1]];
            let v1 = [p1[0] - c[0], p1[1] - c[1]];
            let e = [p1[0] - p0[0], p1[1] - p0[1]];
            let l2 = e[0] * e[0] + e[1] * e[1];
            let t = if l2 > 0.0 {
                (-(v0[0] * e[0] + v0[1] * e[1]) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = [v0[0] + t * e[0], v0[1] + t * e[1]];
            let dmin = (q[0] * q[0] + q[1] * q[1]).sqrt();
            let dmax = (v0[0] * v0[0] + v0[1] * v0[1])
                .sqrt()
                .max((v1[0] * v1[0] + v1[1] * v1[1]).sqrt());
            let ed = SLACK_M + 1e-9 * (radius.abs() + dmax);
            let d = if left {
                (radius - dmax - ed, radius - dmin + ed)
            } else {
                (dmin - radius - ed, dmax - radius + ed)
            };
            let mut s = (f64::NEG_INFINITY, f64::INFINITY);
            if dmin > SLACK_M {
                // The polar angle is monotonic along a segment that misses the centre, and
                // sweeps less than π: from a0 to a0 + th.
                let a0 = v0[1].atan2(v0[0]);
                let th = (v0[0] * v1[1] - v0[1] * v1[0]).atan2(v0[0] * v1[0] + v0[1] * v1[1]);
                let (lo, hi) = (a0.min(a0 + th) - start, a0.max(a0 + th) - start);
                let (lo, hi) = if left { (lo, hi) } else { (-hi, -lo) };
                let (lo, hi) = (lo - SLACK_RAD, hi + SLACK_RAD);
                // `wrap` maps the angle into (-π, π]: the shift that does so for the whole
                // range, when one does.
                let k = ((lo + hi) * 0.5 / TAU).round();
                let (lo, hi) = (lo - k * TAU, hi - k * TAU);
                if lo > -PI + SLACK_RAD && hi < PI - SLACK_RAD {
                    let es = SLACK_M + 1e-8 * radius.abs();
                    let (a, b) = (radius * lo, radius * hi);
                    s = (a.min(b) - es, a.max(b) + es);
                }
            }
            Span { s, d }
        }
    }
}

/// A strip that may contain some point of a block, with the markings that may touch it.
struct Cand<'a> {
    strip: &'a Strip,
    marks: std::ops::Range<usize>,
    bars: std::ops::Range<usize>,
    /// Every point of the block is on the strip's asphalt.
    asphalt: bool,
}

/// The strips (in order), markings and bars that may matter for a block of pixels: the others
/// cannot contain its points (strips) or touch them (markings: zero coverage; bars: outside).
#[derive(Default)]
struct Culled<'a> {
    cands: Vec<Cand<'a>>,
    marks: Vec<&'a Mark>,
    bars: Vec<&'a Bar>,
}

impl<'a> Culled<'a> {
    /// The candidates of `scene` for the ground points from `p0` to `p1`.
    fn fill(&mut self, scene: &'a Scene, p0: [f64; 2], p1: [f64; 2], fp_lat: f64, fp_long: f64) {
        self.cands.clear();
        self.marks.clear();
        self.bars.clear();
        // Coverage is 0 beyond half a marking's width plus half the footprint.
        let half_fp = fp_lat.max(1e-6) * 0.5;
        for strip in &scene.strips {
            let r = span(&strip.centre, p0, p1);
            if r.s.1 < strip.s_min
                || r.s.0 > strip.s_max
                || r.d.1 < strip.d_min - strip.walk
                || r.d.0 > strip.d_max + strip.walk
            {
                continue;
            }
            let m0 = self.marks.len();
            self.marks.extend(strip.marks.iter().filter(|m| {
                let reach = m.width * 0.5 + half_fp;
                !(r.s.1 < m.s_min || r.s.0 > m.s_max || r.d.0 - m.d > reach || r.d.1 - m.d < -reach)
            }));
            let b0 = self.bars.len();
            self.bars.extend(strip.bars.iter().filter(|bar| {
                !(r.d.1 < bar.d_min
                    || r.d.0 > bar.d_max
                    || r.s.1 < bar.s_min - fp_long
                    || r.s.0 > bar.s_max + fp_long)
            }));
            self.cands.push(Cand {
                strip,
                marks: m0..self.marks.len(),
                bars: b0..self.bars.len(),
                asphalt: r.s.0 > strip.s_min
                    && r.s.1 < strip.s_max
                    && r.d.0 > strip.d_min
                    && r.d.1 < strip.d_max,
            });
        }
    }
}

/// Draws the ground and the sky where they win the depth test against the solids already
/// drawn. Drawn first, the ground would set every pixel's depth and the solids would replace
/// it where strictly nearer (first solid first on ties): so the ground wins exactly where its
/// depth is not above the solids' (`ids` back to 0 there).
fn draw_ground(scene: &Scene, cam: &Cam, rgb: &mut [u8], zbuf: &mut [f32], ids: &mut [u16]) {
    let look = &scene.look;
    let light = look.light;
    let haze = scale(look.sky_horizon, 0.92);
    let w = cam.w;
    let mut xs = vec![0.0f64; w];
    let mut ys = vec![0.0f64; w];
    let mut col = vec![0.0f32; 3 * w];
    let mut culled = Culled::default();
    for v in 0..cam.h {
        let b = (v as f64 + 0.5 - cam.cy) / cam.fy;
        let rz = cam.f[2] + b * cam.d[2];
        let row = v * w;
        let zrow = &mut zbuf[row..row + w];
        let idrow = &mut ids[row..row + w];
        let rgbrow = &mut rgb[3 * row..3 * (row + w)];
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
            let c8 = [to_u8(c[0]), to_u8(c[1]), to_u8(c[2])];
            for ((zp, idp), px) in zrow
                .iter_mut()
                .zip(idrow.iter_mut())
                .zip(rgbrow.chunks_exact_mut(3))
            {
                // (Neither depth is ever NaN.)
                if z <= *zp {
                    *zp = z;
                    *idp = 0;
                    px.copy_from_slice(&c8);
                }
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
        for (x, y) in xs.iter_mut().zip(ys.iter_mut()) {
            *x = gx;
            *y = gy;
            gx += sx;
            gy += sy;
        }
        let fp_lat = tt / cam.fx;
        let fp_long = tt * tt / (cam.fy * cam.c[2]);
        let tex_amp = (1.0 / (1.0 + tt / 30.0)) as f32;
        let aerial = ((tt / FAR_M) as f32).min(1.0) * 0.6;
        let tz = tt as f32;
        for u0 in (0..w).step_by(BLOCK) {
            let u1 = (u0 + BLOCK).min(w);
            let mut block_culled = false;
            for u in u0..u1 {
                let px = &mut col[3 * u..3 * u + 3];
                if zrow[u] < tz {
                    // A solid is nearer: keep its colour (exact through f32).
                    let old = &rgbrow[3 * u..3 * u + 3];
                    px[0] = f32::from(old[0]);
                    px[1] = f32::from(old[1]);
                    px[2] = f32::from(old[2]);
                    continue;
                }
                zrow[u] = tz;
                idrow[u] = 0;
                if !block_culled {
                    let (p0, p1) = ([xs[u0], ys[u0]], [xs[u1 - 1], ys[u1 - 1]]);
                    culled.fill(scene, p0, p1, fp_lat, fp_long);
                    block_culled = true;
                }
                let c = ground_color(scene, &culled, xs[u], ys[u], fp_lat, fp_long, tex_amp);
                let c = mix(scale(c, light), haze, aerial);
                px.copy_from_slice(&c);
            }
        }
        to_u8_row(&col, rgbrow);
    }
}

const WHITE: Rgb = [232.0, 232.0, 226.0];
const KERB: Rgb = [196.0, 194.0, 188.0];

/// The ground colour at `(x, y)`: the first strip containing the point decides. Only the
/// candidate strips, markings and bars are looked at (the others cannot contain or touch the
/// point), with the same arithmetic as looking at all of them.
#[inline]
fn ground_color(
    scene: &Scene,
    culled: &Culled,
    x: f64,
    y: f64,
    fp_lat: f64,
    fp_long: f64,
    tex: f32,
) -> Rgb {
    let Culled { cands, marks, bars } = culled;
    let look = &scene.look;
    if let [first, ..] = cands.as_slice()
        && first.asphalt
        && first.marks.is_empty()
        && first.bars.is_empty()
    {
        // The first strip that may contain the point surely does, on its asphalt, with no
        // marking near: its colour without `(s, d)`.
        let n = cell_noise(scene.texture_seed, x, y) * tex;
        return [
            look.asphalt[0] + 7.0 * n,
            look.asphalt[1] + 7.0 * n,
            look.asphalt[2] + 7.0 * n,
        ];
    }
    let p = [x, y];
    for cand in cands {
        let strip = cand.strip;
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
        for m in &marks[cand.marks.clone()] {
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
        for bar in &bars[cand.bars.clone()] {
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
        // `ia * (x + 0.5) + ib * vc + ic` with `ib * vc` hoisted (the same bits); the depths of
        // a run of pixels first (a loop that vectorises), then the depth test.
        let bv = ib * vc;
        let (x0, x1) = (x0 as usize, x1 as usize + 1);
        let mut zs = [0.0f32; RUN];
        for start in (x0..x1).step_by(RUN) {
            let end = (start + RUN).min(x1);
            let zs = &mut zs[..end - start];
            for (k, z) in zs.iter_mut().enumerate() {
                let inv_z = ia * (f64::from((start + k) as u32) + 0.5) + bv + ic;
                // NaN where the plane is behind (`inv_z <= 0`): it fails the depth test.
                *z = if inv_z > 0.0 {
                    (1.0 / inv_z) as f32
                } else {
                    f32::NAN
                };
            }
            for (i, &z) in (row + start..row + end).zip(zs.iter()) {
                if z < zbuf[i] {
                    zbuf[i] = z;
                    ids[i] = id;
                    rgb[3 * i..3 * i + 3].copy_from_slice(&c8);
                }
            }
        }
    }
}

/// Pixels per run of a polygon's span whose depths are computed together.
const RUN: usize = 64;

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
        let row = &ids[y * w..(y + 1) * w];
        // Most rows hold no object: one vectorised pass tells.
        if row.iter().fold(0, |a, &b| a | b) == 0 {
            continue;
        }
        for (x, &id) in row.iter().enumerate() {
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
    fn fast_rounding_matches_the_library_for_every_f32_that_can_round_either_way() {
        // Every f32 in [0.25, 512) (all the values whose rounding is not decided by the clamp
        // or by being below ½), and a stride through all other bit patterns (negatives,
        // tiny values, NaNs, infinities, large values).
        let (lo, hi) = (0.25f32.to_bits(), 512.0f32.to_bits());
        for bits in lo..hi {
            let v = f32::from_bits(bits);
            assert_eq!(to_u8(v), v.clamp(0.0, 255.0).round() as u8, "{bits:#x}");
        }
        for bits in (0..=u32::MAX).step_by(4099) {
            let v = f32::from_bits(bits);
            assert_eq!(to_u8(v), v.clamp(0.0, 255.0).round() as u8, "{bits:#x}");
        }
    }

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

    /// Random strips (lines and arcs, finite and infinite extents, markings and bars) around
    /// the origin.
    fn random_strips(d: &mut crate::scene::Draw) -> Vec<Strip> {
        (0..1 + d.index(8))
            .map(|_| {
                let centre = if d.chance(0.5) {
                    let a: f64 = d.range(-3.2, 3.2);
                    Centre::Line {
                        origin: [d.range(-60.0, 60.0), d.range(-60.0, 60.0)],
                        dir: [a.cos(), a.sin()],
                    }
                } else {
                    Centre::Arc {
                        centre: [d.range(-100.0, 100.0), d.range(-100.0, 100.0)],
                        radius: if d.chance(0.1) {
                            d.range(1e5, 1e9)
                        } else {
                            d.range(2.0, 150.0)
                        },
                        left: d.chance(0.5),
                        start: d.range(-12.0, 12.0),
                    }
                };
                let (s_min, s_max) = if d.chance(0.2) {
                    (f64::NEG_INFINITY, f64::INFINITY)
                } else {
                    let a = d.range(-200.0, 200.0);
                    (a, a + d.range(0.0, 300.0))
                };
                let (d_min, d_max) = (-d.range(0.5, 12.0), d.range(0.5, 16.0));
                let marks = (0..d.index(8))
                    .map(|_| Mark {
                        d: d.range(d_min - 1.0, d_max + 1.0),
                        width: d.range(0.05, 0.6),
                        dash: d
                            .chance(0.4)
                            .then(|| (d.range(0.5, 4.0), d.range(4.0, 12.0))),
                        color: [255.0, 200.0, 40.0],
                        s_min: if d.chance(0.5) {
                            -50.0
                        } else {
                            f64::NEG_INFINITY
                        },
                        s_max: if d.chance(0.5) { 50.0 } else { f64::INFINITY },
                    })
                    .collect();
                let bars = (0..d.index(4))
                    .map(|_| {
                        let (a, b) = (d.range(-100.0, 100.0), d.range(d_min, d_max));
                        Bar {
                            s_min: a,
                            s_max: a + d.range(0.2, 5.0),
                            d_min: b,
                            d_max: b + d.range(0.5, 8.0),
                            stripes: d
                                .chance(0.5)
                                .then(|| (d.range(0.3, 0.8), d.range(0.9, 2.0))),
                        }
                    })
                    .collect();
                Strip {
                    centre,
                    s_min,
                    s_max,
                    d_min,
                    d_max,
                    walk: if d.chance(0.3) {
                        0.0
                    } else {
                        d.range(0.5, 5.0)
                    },
                    marks,
                    bars,
                }
            })
            .collect()
    }

    #[test]
    fn culling_gives_the_same_colours_as_looking_at_every_strip() {
        let mut d = crate::scene::Draw::new(5, &[1]);
        let base = crate::scenarios::build("INTERSECTION", 3).scene;
        let (mut culled_out, mut fast) = (0usize, 0usize);
        for _ in 0..400 {
            let scene = Scene {
                strips: random_strips(&mut d),
                ..base.clone()
            };
            // Everything, in order: the lookup without culling.
            let mut all = Culled {
                marks: scene.strips.iter().flat_map(|s| &s.marks).collect(),
                bars: scene.strips.iter().flat_map(|s| &s.bars).collect(),
                ..Culled::default()
            };
            let (mut m, mut b) = (0, 0);
            for strip in &scene.strips {
                all.cands.push(Cand {
                    strip,
                    marks: m..m + strip.marks.len(),
                    bars: b..b + strip.bars.len(),
                    asphalt: false,
                });
                m += strip.marks.len();
                b += strip.bars.len();
            }
            let mut culled = Culled::default();
            for _ in 0..20 {
                // A block: BLOCK points from p0 by a step, as a ground row makes them.
                let (mut x, mut y) = (d.range(-150.0, 150.0), d.range(-150.0, 150.0));
                let step = d.range(0.001, 3.0);
                let a: f64 = d.range(-3.2, 3.2);
                let (sx, sy) = (step * a.cos(), step * a.sin());
                let (fp_lat, fp_long) = (d.range(0.0, 0.5), d.range(0.0, 5.0));
                let pts: Vec<[f64; 2]> = (0..BLOCK)
                    .map(|_| {
                        let p = [x, y];
                        x += sx;
                        y += sy;
                        p
                    })
                    .collect();
                culled.fill(&scene, pts[0], pts[BLOCK - 1], fp_lat, fp_long);
                culled_out += scene.strips.len() - culled.cands.len();
                fast += usize::from(culled.cands.first().is_some_and(|c| c.asphalt));
                for p in &pts {
                    let want = ground_color(&scene, &all, p[0], p[1], fp_lat, fp_long, 0.7);
                    let got = ground_color(&scene, &culled, p[0], p[1], fp_lat, fp_long, 0.7);
                    assert_eq!(want.map(f32::to_bits), got.map(f32::to_bits), "{p:?}");
                }
            }
        }
        // The test looks at culled strips and sure-asphalt blocks, not only at trivial ones.
        assert!(culled_out > 1000 && fast > 100, "{culled_out} {fast}");
    }
}
