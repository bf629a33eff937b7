//! Pixel access, pooling and the photometric tests of classical perception.
//!
//! A [`View`] is one camera frame with its calibration, a summed-area table (so the mean of
//! any pixel rectangle costs four look-ups per channel) and the frame's measured quality: its
//! noise level σ̂ and its white level (both from [`fogline_monitor`], from the pixels alone).
//!
//! Every test here is *relative* and *noise-aware*:
//! - colours are compared with the scene's own references (the asphalt colour at that
//!   distance, the frame's white level), never with fixed 0–255 values, so darkness and
//!   fog shift the references with the image instead of tripping fixed thresholds;
//! - a measurement is the mean over a patch of `n` pixels, whose noise is `σ̂/√n` per
//!   channel; thresholds add a multiple of that, so noise costs sensitivity (far and
//!   low-contrast things are missed first) rather than producing phantoms.

use fogline_types::clip::CameraCalib;

/// A colour, 0–255 per channel (a pooled mean, so fractional).
pub type Rgb = [f32; 3];

/// One camera frame, pooled.
pub struct View<'a> {
    /// Calibration.
    pub calib: &'a CameraCalib,
    /// RGB8 pixels.
    pub rgb: &'a [u8],
    /// Summed-area table, `(w + 1) × (h + 1)`, row-major, the three channels packed in one
    /// word (see [`pack`]); empty for a view that sums its (few) patches directly.
    sat: Vec<u64>,
    /// Estimated noise σ per channel, 0–255 scale.
    pub sigma: f32,
    /// The frame's white level (99.5th percentile of the brightest channel).
    pub white: f32,
    /// Undoes the clipping bias of noisy means (`None` on clean frames).
    censor: Option<fogline_monitor::Censoring>,
    /// The camera's axes (`CameraCalib::axes`), computed once: projection is the inner loop
    /// of every reading.
    axes: [[f64; 3]; 3],
    /// Whether the noise is weak enough that every pooled reading is the least patch,
    /// 2 × 2 pixels, whatever its limits ([`pool_size`] at σ̂ ≤ 2·[`TARGET_NOISE`]).
    least_patch: bool,
}

thread_local! {
    /// Summed-area tables are large (1.5 MB at 576 × 320): their buffers are reused per
    /// thread instead of being allocated, zeroed and faulted in for every frame.
    static SAT_BUFFERS: std::cell::RefCell<Vec<Vec<u64>>> = const { std::cell::RefCell::new(Vec::new()) };
    /// The column sums a summed-area table is built from (one row of them).
    static COLUMN_SUMS: std::cell::RefCell<Vec<u64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Bits of a packed channel sum: red in bits 0–20, green in 21–41, blue in 42–63.
const LANE_BITS: u32 = 21;

/// The most pixels one packed look-up sums exactly: every channel's sum over them stays
/// below `2^21`, so it fits its lane (`8224 × 255 < 2^21`).
const PACKED_MAX_PIXELS: usize = ((1 << LANE_BITS) - 1) / 255;

/// One pixel's channels packed into a word. Sums of packed words are taken modulo `2^64`;
/// since packing is linear, a rectangle's packed sum (four corners, wrapping) equals the
/// packing of its three channel sums whenever each fits its lane — at most
/// [`PACKED_MAX_PIXELS`] pixels, so larger rectangles are summed in bands. A third less
/// memory than three 32-bit tables, and one load per corner instead of three.
#[inline(always)]
fn pack(p: &[u8]) -> u64 {
    u64::from(p[0]) | u64::from(p[1]) << LANE_BITS | u64::from(p[2]) << (2 * LANE_BITS)
}

/// The three channel sums of a packed sum (each below `2^21`).
#[inline(always)]
fn unpack(s: u64) -> [u64; 3] {
    let lane = (1u64 << LANE_BITS) - 1;
    [s & lane, (s >> LANE_BITS) & lane, s >> (2 * LANE_BITS)]
}

impl Drop for View<'_> {
    fn drop(&mut self) {
        let buf = std::mem::take(&mut self.sat);
        if buf.capacity() > 0 {
            SAT_BUFFERS.with(|b| {
                let mut b = b.borrow_mut();
                if b.len() < 4 {
                    b.push(buf);
                }
            });
        }
    }
}

impl<'a> View<'a> {
    /// Pools `rgb` (validated by the caller to be `width × height × 3` bytes) and measures
    /// its quality; `sigma` overrides the noise estimate (frames of one camera share it).
    pub fn new(calib: &'a CameraCalib, rgb: &'a [u8], sigma: Option<f32>) -> Self {
        Self::plain(calib, rgb, sigma).pooled()
    }

    /// This view with its summed-area table built (for frames read all over, through
    /// patches of any size).
    pub fn pooled(mut self) -> Self {
        let (w, h) = (self.width(), self.height());
        let rgb = self.rgb;
        let stride = w + 1;
        let mut sat = SAT_BUFFERS
            .with(|b| b.borrow_mut().pop())
            .unwrap_or_default();
        // A reused buffer keeps its contents: every entry is written below (row 0 and column
        // 0 as zeros), so it is not cleared (1.5 MB per frame at 576 × 320).
        sat.resize(stride * (h + 1), 0);
        sat[..stride].fill(0);
        // Column sums down to the current row (vectorised), then their running sums along
        // the row: one dependent add per entry. Packed, so wrapping (see `pack`).
        let mut cols = COLUMN_SUMS.with(|c| std::mem::take(&mut *c.borrow_mut()));
        cols.clear();
        cols.resize(w, 0);
        for y in 0..h {
            let row = &rgb[y * w * 3..(y + 1) * w * 3];
            for (c, p) in cols.iter_mut().zip(row.chunks_exact(3)) {
                *c = c.wrapping_add(pack(p));
            }
            let cur = &mut sat[(y + 1) * stride..(y + 2) * stride];
            cur[0] = 0;
            let mut run = 0u64;
            for (dst, c) in cur[1..].iter_mut().zip(&cols) {
                run = run.wrapping_add(*c);
                *dst = run;
            }
        }
        COLUMN_SUMS.with(|c| *c.borrow_mut() = cols);
        self.sat = sat;
        self
    }

    /// A view without a summed-area table, for frames read at a few points only: patch
    /// means are summed directly.
    pub fn plain(calib: &'a CameraCalib, rgb: &'a [u8], sigma: Option<f32>) -> Self {
        let (w, h) = (calib.width as usize, calib.height as usize);
        let sigma = sigma.unwrap_or_else(|| {
            fogline_monitor::estimate_noise(rgb, w, h).map_or(0.0, |e| e.sigma as f32)
        });
        let white = fogline_monitor::exposure(rgb, w, h).map_or(255.0, |e| e.white as f32);
        Self {
            calib,
            rgb,
            sat: Vec::new(),
            sigma,
            white,
            censor: fogline_monitor::Censoring::new(f64::from(sigma)),
            axes: calib.axes(),
            least_patch: f64::from((sigma / TARGET_NOISE).powi(2)) <= 4.0,
        }
    }

    /// An earlier frame of the same camera, read directly: it shares this view's measured
    /// quality (σ̂, white level and the clipping inverse), which a clip's frames have in
    /// common, instead of measuring it again.
    pub fn sibling(&self, rgb: &'a [u8]) -> Self {
        Self {
            calib: self.calib,
            rgb,
            sat: Vec::new(),
            sigma: self.sigma,
            white: self.white,
            censor: self.censor.clone(),
            axes: self.axes,
            least_patch: self.least_patch,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.calib.width as usize
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.calib.height as usize
    }

    /// The mean colour of the pixels `[x0, x1) × [y0, y1)` (clamped to the image) and their
    /// count, or `None` when the rectangle misses the image.
    #[inline]
    pub fn rect(&self, x0: isize, y0: isize, x1: isize, y1: isize) -> Option<(Rgb, usize)> {
        let (w, h) = (self.width() as isize, self.height() as isize);
        let (x0, y0) = (x0.clamp(0, w) as usize, y0.clamp(0, h) as usize);
        let (x1, y1) = (x1.clamp(0, w) as usize, y1.clamp(0, h) as usize);
        if x1 <= x0 || y1 <= y0 {
            return None;
        }
        let n = (x1 - x0) * (y1 - y0);
        let mut out = [0f32; 3];
        if self.sat.is_empty() {
            let mut acc = [0u32; 3];
            for y in y0..y1 {
                let row = &self.rgb[(y * self.width() + x0) * 3..(y * self.width() + x1) * 3];
                for px in row.chunks_exact(3) {
                    acc[0] += u32::from(px[0]);
                    acc[1] += u32::from(px[1]);
                    acc[2] += u32::from(px[2]);
                }
            }
            for c in 0..3 {
                out[c] = acc[c] as f32 / count_f32(n);
            }
            return Some((self.uncensor(out), n));
        }
        // Packed sums are exact up to `PACKED_MAX_PIXELS`: larger rectangles are summed in
        // bands of rows that each stay within it.
        let band = (PACKED_MAX_PIXELS / (x1 - x0)).max(1);
        let mut acc = [0u64; 3];
        let mut y = y0;
        while y < y1 {
            let y_end = (y + band).min(y1);
            let s = self.packed_sum(x0, y, x1, y_end);
            for (a, c) in acc.iter_mut().zip(unpack(s)) {
                *a += c;
            }
            y = y_end;
        }
        for k in 0..3 {
            out[k] = acc[k] as f32 / count_f32(n);
        }
        Some((self.uncensor(out), n))
    }

    /// The packed sum of `[x0, x1) × [y0, y1)` (inside the image) from the four corners of
    /// the summed-area table.
    #[inline(always)]
    fn packed_sum(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> u64 {
        let stride = self.width() + 1;
        let at = |y: usize, x: usize| self.sat.get(y * stride + x).copied().unwrap_or(0);
        at(y1, x1)
            .wrapping_add(at(y0, x0))
            .wrapping_sub(at(y0, x1))
            .wrapping_sub(at(y1, x0))
    }

    /// A patch mean with the clipping bias removed (see [`fogline_monitor::Censoring`]).
    #[inline(always)]
    fn uncensor(&self, c: Rgb) -> Rgb {
        match &self.censor {
            Some(k) => [k.true_mean(c[0]), k.true_mean(c[1]), k.true_mean(c[2])],
            None => c,
        }
    }

    /// The mean over a `kw × kh` patch centred on pixel position `(u, v)` (clamped to the
    /// image), or `None` when `(u, v)` is outside it.
    #[inline]
    pub fn patch(&self, u: f64, v: f64, kw: usize, kh: usize) -> Option<Sample> {
        if !(u >= 0.0 && v >= 0.0 && u < self.width() as f64 && v < self.height() as f64) {
            return None;
        }
        let x0 = round_px(u - index_f64(kw) / 2.0);
        let y0 = round_px(v - index_f64(kh) / 2.0);
        self.rect_sample(x0, y0, x0 + kw.max(1) as isize, y0 + kh.max(1) as isize)
    }

    /// [`View::rect`] as a [`Sample`]: the mean and its noise `σ̂/√n`.
    #[inline]
    pub fn rect_sample(&self, x0: isize, y0: isize, x1: isize, y1: isize) -> Option<Sample> {
        self.rect(x0, y0, x1, y1).map(|(c, n)| Sample {
            c,
            s: self.sigma / count_f32(n).sqrt(),
        })
    }

    /// The single pixel at integer position, no averaging.
    #[inline]
    pub fn pixel(&self, x: usize, y: usize) -> Rgb {
        let i = (y * self.width() + x) * 3;
        [
            f32::from(self.rgb[i]),
            f32::from(self.rgb[i + 1]),
            f32::from(self.rgb[i + 2]),
        ]
    }

    /// `CameraCalib::project` with the axes computed once per view:
    /// `(u, v, range)` of rig-frame point `p`, or `None` behind the camera; the point may
    /// lie outside the image.
    #[inline]
    pub fn project_any(&self, p: [f64; 3]) -> Option<(f64, f64, f64)> {
        self.calib.project_with(&self.axes, p)
    }

    /// The projection of points `[x, y0 + y, z]` on the rig-frame plane at distance `x`
    /// (lateral offset `y` from `y0`, height `z`) as seen from a rig at pose `[x, y, yaw]`
    /// in that frame: coefficients that take `(y, z)` to pixels with three multiply-adds
    /// and one division each ([`PlaneProjector::uv`]), for matching many samples of a face.
    pub fn plane(&self, x: f64, y0: f64, pose: [f64; 3]) -> PlaneProjector {
        let (s, c) = pose[2].sin_cos();
        let (dx, dy) = (x - pose[0], y0 - pose[1]);
        let base = [
            c * dx + s * dy - self.calib.x_m,
            -s * dx + c * dy - self.calib.y_m,
            -self.calib.z_m,
        ];
        let unit_y = [s, c, 0.0];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let row = |axis: [f64; 3]| [dot(base, axis), dot(unit_y, axis), axis[2]];
        let [f, r, d] = self.axes;
        PlaneProjector {
            depth: row(f),
            across: row(r).map(|a| a * self.calib.fx),
            down: row(d).map(|a| a * self.calib.fy),
            centre: (self.calib.cx, self.calib.cy),
        }
    }

    /// Pixel position and range `(u, v, range)` of rig-frame point `p` when it is in the
    /// image.
    #[inline]
    pub fn project(&self, p: [f64; 3]) -> Option<(f64, f64, f64)> {
        self.project_any(p).filter(|&(u, v, _)| {
            u >= 0.0 && v >= 0.0 && u < self.width() as f64 && v < self.height() as f64
        })
    }

    /// The mean over a patch around ground-level or 3-D point `p`, sized to cover about
    /// `lat_m` across and `dep_m` along the line of sight (a flat patch on the ground: its
    /// depth extent maps to image rows), at least 2 × 2 pixels and as many more as the
    /// noise asks for within those limits.
    #[inline]
    pub fn around(&self, p: [f64; 3], lat_m: f64, dep_m: f64) -> Option<Sample> {
        let proj = self.project_any(p)?;
        self.around_at(p, proj, lat_m, dep_m)
    }

    /// [`View::around`] with `p`'s projection `(u, v, range)` already known.
    #[inline]
    pub fn around_at(
        &self,
        p: [f64; 3],
        (u, v, range): (f64, f64, f64),
        lat_m: f64,
        dep_m: f64,
    ) -> Option<Sample> {
        if self.least_patch {
            // `pool_size` gives 2 × 2 whatever the limits when σ̂ needs no more.
            return self.patch(u, v, 2, 2);
        }
        let x = (p[0] - self.calib.x_m).max(0.5);
        let px_per_m = self.calib.fx / range.max(0.5);
        let kw_max = (lat_m * px_per_m).max(2.0);
        // A ground patch's depth extent covers fy·h·Δx/x² rows; a vertical face's covers fy·Δz/x.
        let rows_per_m = if p[2] < 0.05 {
            self.calib.fy * self.calib.z_m / (x * x)
        } else {
            self.calib.fy / x
        };
        let kh_max = (dep_m * rows_per_m).max(2.0);
        let (kw, kh) = pool_size(self.sigma, kw_max, kh_max);
        self.patch(u, v, kw, kh)
    }
}

/// `x.round() as isize` (half away from zero) without the library call that `f64::round`
/// becomes on CPUs without SSE4.1's rounding instruction (the baseline x86-64 target): pixel
/// coordinates are rounded in the inner loop of every reading.
#[inline]
pub fn round_px(x: f64) -> isize {
    if x >= 0.0 {
        (x + 0.5) as isize
    } else {
        (x - 0.5) as isize
    }
}

/// `x.round() as isize` (half away from zero, exactly) without the library call; the
/// fraction `x − trunc(x)` is exact in floating point. Beyond ±4·10¹⁵ (never passed) it falls
/// back to the library.
#[inline]
pub fn round_exact(x: f64) -> isize {
    if x.abs() < 4.0e15 {
        let t = x as isize;
        let f = x - t as f64;
        t + isize::from(f >= 0.5) - isize::from(f <= -0.5)
    } else {
        x.round() as isize
    }
}

/// `x.round() as usize` for `x ≥ 0` (half away from zero, exactly), without the library
/// call: the fraction `x − ⌊x⌋` is exact in floating point. Negative or non-finite `x`
/// (never passed) fall back to the library.
#[inline]
pub fn round_pos(x: f64) -> usize {
    if (0.0..4.0e15).contains(&x) {
        let t = x as i64;
        t as usize + usize::from(x - t as f64 >= 0.5)
    } else {
        x.round() as usize
    }
}

/// A pixel count as `f32` (exact below 2^24, as every patch is), converted through `i32`:
/// baseline x86-64 converts `i32` in one instruction and `usize` in a branchy sequence,
/// and patch means are the inner loop of every reading.
#[inline(always)]
fn count_f32(n: usize) -> f32 {
    n as i32 as f32
}

/// A pixel index or size as `f64`, through `i64` (one instruction; `usize` needs a branchy
/// sequence on baseline x86-64). Exact, as the value is far below 2^53.
#[inline(always)]
fn index_f64(n: usize) -> f64 {
    n as i64 as f64
}

/// A patch mean and the standard deviation of its noise per channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Mean colour.
    pub c: Rgb,
    /// Noise of the mean per channel: `σ̂ / √n`.
    pub s: f32,
}

/// The residual noise a pooled measurement aims for, per channel (0–255 scale).
pub const TARGET_NOISE: f32 = 3.0;

/// Pixels to pool for noise `sigma` within `kw_max × kh_max`: enough for [`TARGET_NOISE`]
/// when the limits allow — about twice as wide as tall, then taller where the width is
/// limited.
#[inline]
pub fn pool_size(sigma: f32, kw_max: f64, kh_max: f64) -> (usize, usize) {
    let need = f64::from((sigma / TARGET_NOISE).powi(2)).max(4.0);
    let kh = (need / 2.0).sqrt().clamp(2.0, kh_max.max(2.0));
    let kw = (need / kh).clamp(2.0, kw_max.max(2.0));
    // Narrow limits across: make up for it along.
    let kh = (need / kw).clamp(kh, kh_max.max(2.0));
    (round_pos(kw), round_pos(kh))
}

/// Luminance (mean of the channels).
#[inline]
pub fn lum(c: Rgb) -> f32 {
    (c[0] + c[1] + c[2]) / 3.0
}

/// Spread between the largest and smallest channel.
#[inline]
pub fn chroma(c: Rgb) -> f32 {
    c[0].max(c[1]).max(c[2]) - c[0].min(c[1]).min(c[2])
}

/// Noise of the luminance of a mean whose channels have noise `s` each.
#[inline]
fn lum_noise(s: f32) -> f32 {
    s / 3f32.sqrt()
}

/// The scene's photometric references at one distance: the asphalt's colour there and the
/// contrast scale of the frame (1 in daylight; lower when the frame is darker).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refs {
    /// Asphalt colour expected at this distance.
    pub road: Rgb,
    /// Exposure scale: the white level over a daylight white level, in [0.2, 1.1].
    pub gain: f32,
}

/// Daylight white level the base thresholds are stated for.
pub const DAY_WHITE: f32 = 235.0;

/// Exposure scale of a frame with white level `white`.
#[inline]
pub fn gain_of(white: f32) -> f32 {
    (white / DAY_WHITE).clamp(0.2, 1.1)
}

/// Painted white marking: brighter than the asphalt by a clear margin, and grey.
#[inline]
pub fn is_white_paint(x: Sample, r: &Refs) -> bool {
    let d = lum(x.c) - lum(r.road);
    d > 45.0 * r.gain + 3.0 * lum_noise(x.s) && chroma(x.c) < 45.0 * r.gain.max(0.5) + 3.5 * x.s
}

/// Yellow paint: red and green above the asphalt, blue well below them.
#[inline]
pub fn is_yellow_paint(x: Sample, r: &Refs) -> bool {
    let c = x.c;
    let g = r.gain;
    let m = 3.0 * x.s;
    c[0] > r.road[0] + 35.0 * g + m
        && c[1] > r.road[1] + 18.0 * g + m
        && c[0] - c[2] > 65.0 * g + m
        && c[1] - c[2] > 45.0 * g + m
}

/// How far a colour is from the asphalt, in units of its threshold (> 1: not asphalt):
/// the larger of the luminance and the chromatic differences, each over its threshold.
#[inline]
pub fn road_distance(x: Sample, r: &Refs) -> f32 {
    let d = [x.c[0] - r.road[0], x.c[1] - r.road[1], x.c[2] - r.road[2]];
    let dl = lum(d).abs() / (26.0 * r.gain + 3.5 * lum_noise(x.s));
    let dc = chroma(d) / (28.0 * r.gain.max(0.4) + 4.5 * x.s);
    // Brightness and hue together: a change of both, each below its own threshold, is
    // still not asphalt.
    let de = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() / (42.0 * r.gain + 3.5 * x.s);
    dl.max(dc).max(de)
}

/// Road surface: close to the asphalt, or paint on it.
#[inline]
pub fn is_road(x: Sample, r: &Refs) -> bool {
    road_distance(x, r) <= 1.0 || is_white_paint(x, r) || is_yellow_paint(x, r)
}

/// Clearly not the asphalt (a tighter test than [`is_road`], for points above the ground,
/// where there is no paint).
#[inline]
pub fn is_object(x: Sample, r: &Refs) -> bool {
    let d = [x.c[0] - r.road[0], x.c[1] - r.road[1], x.c[2] - r.road[2]];
    lum(d).abs() > 14.0 * r.gain + 3.5 * lum_noise(x.s)
        || chroma(d) > 22.0 * r.gain.max(0.4) + 4.5 * x.s
        || (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() > 26.0 * r.gain + 3.5 * x.s
}

/// Lamp colours a lit lamp can show.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LampColour {
    /// Red (signal, brake lamp).
    Red,
    /// Amber.
    Amber,
    /// Green.
    Green,
}

/// A lit lamp: an emitter as bright as the frame's white level in its dominant channel,
/// with the hue of a signal. `white` is the frame's white level. Means are taken with the
/// clipping bias removed, so a saturated lamp reads at full level under any noise.
#[inline]
pub fn lamp_colour(x: Sample, white: f32) -> Option<LampColour> {
    let [r, g, b] = x.c;
    let m = 2.0 * x.s;
    let top = r.max(g);
    // Emitters reach the white level; diffuse paint of the same hue stays well below it.
    if top + m < 0.9 * white {
        return None;
    }
    let bright = |v: f32, k: f32| v + m > k * white;
    if bright(r, 0.9) && g + m < 0.5 * r && b + m < 0.45 * r {
        return Some(LampColour::Red);
    }
    if bright(r, 0.9) && g > 0.5 * r + m && g + m < 0.86 * r && b + m < 0.3 * r {
        return Some(LampColour::Amber);
    }
    if bright(g, 0.88) && r + m < 0.55 * g && b + m < 0.75 * g {
        return Some(LampColour::Green);
    }
    None
}

/// A lit lamp seen through a veil (fog, heavy rain): the veil adds the same airlight to
/// the lamp and to the dark housing around it, which washes the lamp's hue out towards
/// grey (an amber lamp in hard rain reads (233, 188, 100), its housing (92, 92, 92)). What
/// the lamp adds to its housing, `x − housing`, carries the lamp's own hue, so the hue
/// tests of [`lamp_colour`] are made on that difference; the brightness test stays on the
/// lamp itself. The housing must be a dark, nearly grey box (darker than 60 % of the lamp's
/// brightest channel); what the lamp adds must be a quarter of the white level or more and
/// a signal's pure colour (its weakest channel at most 15 % of its strongest; red with
/// green and blue under 30 % of it), which a lit surface beside a shadow is not.
#[inline]
pub fn lamp_colour_over(x: Sample, housing: Sample, white: f32) -> Option<LampColour> {
    let top = x.c[0].max(x.c[1]);
    if top + 2.0 * x.s < 0.9 * white {
        return None;
    }
    let [hr, hg, hb] = housing.c;
    let h_top = hr.max(hg).max(hb);
    let h_grey = h_top - hr.min(hg).min(hb) < 0.1 * white + 3.0 * housing.s;
    if !(h_grey && h_top < 0.6 * top) {
        return None;
    }
    let [r, g, b] = [x.c[0] - hr, x.c[1] - hg, x.c[2] - hb];
    // The housing is the darkest of several readings, biased low by about two of its
    // standard errors under noise: that bias is added to the margin.
    let m = 2.0 * x.s.hypot(housing.s) + 2.0 * housing.s;
    // What the lamp adds is a signal's saturated colour: next to nothing in its weakest
    // channel (a lit surface's hue is not that pure).
    if r.max(g) < 0.25 * white + m || r.min(g).min(b) > 0.15 * r.max(g) + m {
        return None;
    }
    // A signal red adds red alone (a tan or brown surface adds some green as well).
    if g + m < 0.3 * r && b + m < 0.3 * r {
        return Some(LampColour::Red);
    }
    if g > 0.5 * r + m && g + m < 0.86 * r && b + m < 0.3 * r {
        return Some(LampColour::Amber);
    }
    if r + m < 0.55 * g && b + m < 0.75 * g {
        return Some(LampColour::Green);
    }
    None
}

/// Sign red: saturated red (red well above 1.8 times green and blue), not necessarily
/// bright. The margin is 2.5 standard errors of `r − 1.8·max(g, b)`.
#[inline]
pub fn is_sign_red(x: Sample, gain: f32) -> bool {
    let [r, g, b] = x.c;
    let m = 2.5 * x.s * (1.0f32 + 1.8 * 1.8).sqrt();
    r > 45.0 * gain + 2.5 * x.s && r - 1.8 * g.max(b) > m && r > 2.0 * g.max(b)
}

/// Stop-sign red seen through haze or in shade: the red channel exceeds green and blue by
/// a margin (20 at daylight exposure, scaled by the exposure `gain`), and green and blue
/// are alike — they differ by under 0.3 of that margin: a red, not the orange of a cone,
/// the brown of brick or the pink of a dusk sky (0.5–0.7 for those). Fog adds the same grey
/// airlight to every channel (Koschmieder), which lowers the channels' ratios —
/// [`is_sign_red`]'s test fails for a shaded face 20 m away in mid rain at twilight,
/// (101, 66, 68) — but scales their differences only by the transmission, so the hue test
/// holds at any visibility.
#[inline]
pub fn is_sign_red_hazed(x: Sample, gain: f32) -> bool {
    let [r, g, b] = x.c;
    let top = g.max(b);
    let m = 3.0 * x.s * std::f32::consts::SQRT_2;
    r - top > 20.0 * gain + m && (g - b).abs() < 0.3 * (r - top) + m
}

/// A box-filtered reading of part of a frame, between pixel centres: what registration
/// compares. Each pixel reads as the mean of the `k × k` pixels around it (clamped to the
/// frame), which divides the noise by `k` and turns a hard edge into a ramp `k` pixels wide,
/// whose position a bilinear read follows to a fraction of a pixel. The rectangle is
/// filtered once, through a summed-area table of it and its margin: a face's samples, at
/// every offset searched, cover most of it.
pub struct Smoothed {
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
    /// Filtered pixels, row-major.
    px: Vec<Rgb>,
}

thread_local! {
    /// Buffers of [`Smoothed`] readings and their tables, reused per thread (fresh ones per
    /// face read would be faulted in page by page).
    static SMOOTHED_BUFFERS: std::cell::RefCell<(Vec<Vec<Rgb>>, Vec<u32>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

impl Drop for Smoothed {
    fn drop(&mut self) {
        let buf = std::mem::take(&mut self.px);
        SMOOTHED_BUFFERS.with(|b| {
            let mut b = b.borrow_mut();
            if b.0.len() < 4 {
                b.0.push(buf);
            }
        });
    }
}

impl Smoothed {
    /// The pixels of `view` within `[u0, u1) × [v0, v1)` (clamped to the frame), filtered
    /// with a `k × k` box; `None` when the rectangle misses the frame.
    pub fn new(view: &View<'_>, (u0, v0, u1, v1): (f64, f64, f64, f64), k: usize) -> Option<Self> {
        let (fw, fh) = (view.width(), view.height());
        let clamp = |a: f64, hi: usize| (a as isize).clamp(0, hi as isize) as usize;
        let (x0, y0) = (clamp(u0.floor(), fw), clamp(v0.floor(), fh));
        let (x1, y1) = (clamp(u1.ceil(), fw), clamp(v1.ceil(), fh));
        if x1 <= x0 + 1 || y1 <= y0 + 1 {
            return None;
        }
        let (w, h) = (x1 - x0, y1 - y0);
        let r = k.max(1) / 2;
        // The table covers the rectangle and its margin within the frame: entry (i, j) sums
        // the pixels [ax, ax + i) × [ay, ay + j).
        let (ax, ay) = (x0.saturating_sub(r), y0.saturating_sub(r));
        let (bx, by) = ((x1 + r).min(fw), (y1 + r).min(fh));
        let stride = (bx - ax + 1) * 3;
        SMOOTHED_BUFFERS.with(|b| {
            let mut b = b.borrow_mut();
            let mut px = b.0.pop().unwrap_or_default();
            let sat = &mut b.1;
            // Every entry is written (row 0 and column 0 as zeros): no clearing.
            sat.resize(stride * (by - ay + 1), 0);
            sat[..stride].fill(0);
            for y in ay..by {
                let row = &view.rgb[(y * fw + ax) * 3..(y * fw + bx) * 3];
                let j = y - ay;
                let (prev, cur) = sat[j * stride..(j + 2) * stride].split_at_mut(stride);
                cur[..3].fill(0);
                let mut acc = [0u32; 3];
                for (dst, p) in cur[3..].chunks_exact_mut(3).zip(row.chunks_exact(3)) {
                    for ((a, d), &b) in acc.iter_mut().zip(dst.iter_mut()).zip(p) {
                        *a += u32::from(b);
                        *d = *a;
                    }
                }
                for (d, p) in cur.iter_mut().zip(prev.iter()) {
                    *d += *p;
                }
            }
            px.clear();
            px.reserve(w * h);
            for y in y0..y1 {
                let (c0, c1) = (y.saturating_sub(r).max(ay) - ay, (y + r + 1).min(by) - ay);
                // The table's two rows that bound this output row, sliced once.
                let (top, bottom) = (
                    &sat[c0 * stride..(c0 + 1) * stride],
                    &sat[c1 * stride..(c1 + 1) * stride],
                );
                let entry = |row: &[u32], i: usize| -> [u32; 3] {
                    row.get(i * 3..i * 3 + 3)
                        .and_then(|e| e.try_into().ok())
                        .unwrap_or([0; 3])
                };
                for x in x0..x1 {
                    let (a0, a1) = (x.saturating_sub(r).max(ax) - ax, (x + r + 1).min(bx) - ax);
                    let n = count_f32((a1 - a0) * (c1 - c0));
                    let (p, q, t, u) = (
                        entry(bottom, a1),
                        entry(top, a0),
                        entry(top, a1),
                        entry(bottom, a0),
                    );
                    let mut v = [0f32; 3];
                    for (c, o) in v.iter_mut().enumerate() {
                        let s = p[c] + q[c] - t[c] - u[c];
                        *o = s as f32 / n;
                    }
                    px.push(v);
                }
            }
            Some(Self { x0, y0, w, h, px })
        })
    }

    /// The filtered colour at continuous frame position `(u, v)` (pixel `i`'s centre at
    /// `i + 0.5`), interpolated between the four nearest pixels; `None` outside the
    /// rectangle.
    #[inline(always)]
    pub fn bilinear(&self, u: f64, v: f64) -> Option<Rgb> {
        let (x, y) = (u - 0.5 - index_f64(self.x0), v - 0.5 - index_f64(self.y0));
        if !(x >= 0.0 && y >= 0.0 && x < index_f64(self.w - 1) && y < index_f64(self.h - 1)) {
            return None;
        }
        // Both are non-negative and below the rectangle's size here.
        let (xi, yi) = (x as i64, y as i64);
        let (fx, fy) = ((x - xi as f64) as f32, (y - yi as f64) as f32);
        let (xi, yi) = (xi as usize, yi as usize);
        // The four neighbours, from one bounds-checked window.
        let i = yi * self.w + xi;
        let q = &self.px[i..i + self.w + 2];
        let (a, b, c, d) = (q[0], q[1], q[self.w], q[self.w + 1]);
        let mut out = [0f32; 3];
        for (ch, o) in out.iter_mut().enumerate() {
            let top = a[ch] + (b[ch] - a[ch]) * fx;
            let bottom = c[ch] + (d[ch] - c[ch]) * fx;
            *o = top + (bottom - top) * fy;
        }
        Some(out)
    }
}

/// A plane's projection into one camera (see [`View::plane`]).
#[derive(Debug, Clone, Copy)]
pub struct PlaneProjector {
    depth: [f64; 3],
    across: [f64; 3],
    down: [f64; 3],
    centre: (f64, f64),
}

impl PlaneProjector {
    /// Pixel position `(u, v)` of the plane's point at lateral offset `y` and height `z`, or
    /// `None` behind the camera.
    #[inline(always)]
    pub fn uv(&self, y: f64, z: f64) -> Option<(f64, f64)> {
        let depth = self.depth[0] + y * self.depth[1] + z * self.depth[2];
        if depth <= 0.01 {
            return None;
        }
        let inv = 1.0 / depth;
        Some((
            self.centre.0 + (self.across[0] + y * self.across[1] + z * self.across[2]) * inv,
            self.centre.1 + (self.down[0] + y * self.down[1] + z * self.down[2]) * inv,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(c: Rgb) -> Sample {
        Sample { c, s: 0.0 }
    }

    /// A view whose noise needs no pooling reads every point through the least patch,
    /// without working out its limits: the same patch `pool_size` gives for any limits.
    #[test]
    fn weak_noise_reads_the_least_patch_whatever_the_limits() {
        let limits = [0.0, 0.4, 1.0, 2.0, 2.6, 7.5, 40.0, f64::NAN, f64::INFINITY];
        for sigma in [0.0f32, 1.0, 3.0, 5.5, 5.999, 6.0] {
            for kw in limits {
                for kh in limits {
                    assert_eq!(pool_size(sigma, kw, kh), (2, 2), "σ {sigma} {kw} × {kh}");
                }
            }
        }
        // Beyond it the limits matter, so the view does work them out.
        assert_ne!(pool_size(9.0, 40.0, 40.0), (2, 2));
        let mut calib = CameraCalib::standard(fogline_types::clip::CameraId::FrontWide, 64, 48);
        calib.fx = 32.0;
        calib.fy = 32.0;
        let rgb: Vec<u8> = (0..64 * 48 * 3).map(|i| (i * 7919 % 253) as u8).collect();
        for (sigma, least) in [(0.0, true), (6.0, true), (6.01, false), (20.0, false)] {
            let view = View::plain(&calib, &rgb, Some(sigma)).pooled();
            assert_eq!(view.least_patch, least, "σ {sigma}");
            for p in [
                [3.0, 0.4, 0.0],
                [9.0, -1.0, 0.0],
                [5.0, 0.2, 1.2],
                [30.0, 2.0, 0.0],
            ] {
                let Some(proj) = view.project(p) else {
                    continue;
                };
                for (lat, dep) in [(0.06, 1.0), (0.25, 0.5), (1.5, 3.0)] {
                    let got = view.around_at(p, proj, lat, dep);
                    // What the limits give, worked out as `around_at` does without the
                    // shortcut.
                    let x = (p[0] - calib.x_m).max(0.5);
                    let kw_max = (lat * calib.fx / proj.2.max(0.5)).max(2.0);
                    let rows = if p[2] < 0.05 {
                        calib.fy * calib.z_m / (x * x)
                    } else {
                        calib.fy / x
                    };
                    let (kw, kh) = pool_size(sigma, kw_max, (dep * rows).max(2.0));
                    assert_eq!(got, view.patch(proj.0, proj.1, kw, kh), "σ {sigma} {p:?}");
                }
            }
        }
    }

    /// Pixels read from rendered frames: a signal head in mid rain at sunset (white level
    /// 204), and the surfaces that the test must not take for lamps (from clear and dark
    /// planner-eval clips).
    #[test]
    fn a_lamp_washed_out_by_a_veil_is_read_against_its_housing() {
        let amber = at([233.0, 188.0, 100.0]);
        let red = at([231.0, 118.0, 112.0]);
        let housing = at([92.0, 92.0, 92.0]);
        // The veil lifts the amber lamp's blue above what a lit amber lamp shows.
        assert_eq!(lamp_colour(amber, 204.0), None);
        assert_eq!(
            lamp_colour_over(amber, housing, 204.0),
            Some(LampColour::Amber)
        );
        assert_eq!(
            lamp_colour_over(red, at([101.0, 101.0, 101.0]), 204.0),
            Some(LampColour::Red)
        );
        // The grey sky beside the head is no lamp; nor is a lamp over a housing as bright
        // as itself or over a coloured one.
        assert_eq!(lamp_colour_over(at([204.0; 3]), housing, 204.0), None);
        assert_eq!(lamp_colour_over(amber, at([150.0; 3]), 204.0), None);
        assert_eq!(lamp_colour_over(amber, at([92.0, 60.0, 60.0]), 204.0), None);
        // Tan and brown surfaces beside a shadow, in a clear and in a dark frame.
        for (x, h, white) in [
            ([205.0, 150.0, 118.0], [115.0, 115.0, 114.0], 208.0),
            ([178.0, 136.0, 120.0], [101.0, 104.0, 106.0], 193.0),
            ([85.0, 62.0, 47.0], [28.0, 29.0, 30.0], 85.0),
        ] {
            assert_eq!(lamp_colour_over(at(x), at(h), white), None, "{x:?}");
        }
        // Noise widens the margins: a lamp that barely passes clean fails under heavy noise.
        let noisy = Sample {
            c: amber.c,
            s: 40.0,
        };
        assert_eq!(
            lamp_colour_over(
                noisy,
                Sample {
                    c: housing.c,
                    s: 40.0
                },
                204.0
            ),
            None
        );
    }
}
