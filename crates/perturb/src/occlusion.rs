//! Sensor defects fixed to a camera: dead pixels and lens dirt.
//!
//! Both draw from the *camera* stream `child(seed, [clip, camera, condition, step])`, which
//! has no frame index: a dead pixel or a speck of dirt stays where it is in every frame of
//! the clip, as on a real sensor.

use serde::{Deserialize, Serialize};

use crate::frame::FrameMut;
use crate::rng::{WyRand, probability_threshold};

/// Dead pixels: each pixel independently (probability `p`, exact to 2^-64, one draw per
/// pixel from the camera stream's row `y` sub-stream) shows `rgb` in every frame.
pub(crate) fn dead_pixels(frame: &mut FrameMut<'_>, p: f64, rgb: [u8; 3], camera_stream: u64) {
    let t = probability_threshold(p);
    let stride = frame.stride();
    for (y, row) in frame.data_mut().chunks_exact_mut(stride).enumerate() {
        let mut rng = WyRand::at(camera_stream, &[y as u64]);
        for px in row.chunks_exact_mut(3) {
            if rng.next_u64() < t {
                px.copy_from_slice(&rgb);
            }
        }
    }
}

/// Lens dirt: `n_blobs` opaque discs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DirtParams {
    /// Number of blobs (0 = identity).
    pub n_blobs: u32,
    /// Smallest radius, as a fraction of `min(width, height)`.
    pub radius_min: f64,
    /// Largest radius, as a fraction of `min(width, height)`.
    pub radius_max: f64,
    /// Colour of the dirt.
    pub rgb: [u8; 3],
}

impl Default for DirtParams {
    fn default() -> Self {
        Self {
            n_blobs: 5,
            radius_min: 0.02,
            radius_max: 0.06,
            rgb: [40, 34, 28],
        }
    }
}

/// A blob of lens dirt in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blob {
    /// Centre column (continuous, px).
    pub cx: f64,
    /// Centre row (continuous, px).
    pub cy: f64,
    /// Radius, px.
    pub r: f64,
}

/// The blobs of a `width × height` camera: blob `i` draws from `child(camera_stream, [i])`
/// the centre `(u₁·W, u₂·H)` and the radius `(r_min + (r_max − r_min)·u₃)·min(W, H)`.
pub(crate) fn blobs(p: &DirtParams, width: u32, height: u32, camera_stream: u64) -> Vec<Blob> {
    let (w, h) = (f64::from(width), f64::from(height));
    (0..p.n_blobs)
        .map(|i| {
            let mut rng = WyRand::at(camera_stream, &[u64::from(i)]);
            let cx = rng.next_f64() * w;
            let cy = rng.next_f64() * h;
            let r = (p.radius_min + (p.radius_max - p.radius_min) * rng.next_f64()) * w.min(h);
            Blob { cx, cy, r }
        })
        .collect()
}

/// Paints every pixel whose centre `(x + ½, y + ½)` lies within a blob.
pub(crate) fn lens_dirt(frame: &mut FrameMut<'_>, p: &DirtParams, camera_stream: u64) {
    let (w, h) = (frame.width(), frame.height());
    let stride = frame.stride();
    let data = frame.data_mut();
    for b in blobs(p, w, h, camera_stream) {
        let y0 = (b.cy - b.r).floor().max(0.0) as u32;
        let y1 = ((b.cy + b.r).ceil().max(0.0) as u32).min(h);
        let x0 = (b.cx - b.r).floor().max(0.0) as u32;
        let x1 = ((b.cx + b.r).ceil().max(0.0) as u32).min(w);
        for y in y0..y1 {
            let dy = f64::from(y) + 0.5 - b.cy;
            for x in x0..x1 {
                let dx = f64::from(x) + 0.5 - b.cx;
                if dx * dx + dy * dy <= b.r * b.r {
                    let i = y as usize * stride + x as usize * 3;
                    data[i..i + 3].copy_from_slice(&p.rgb);
                }
            }
        }
    }
}
