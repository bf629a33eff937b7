//! Pixel access and the colour tests of classical perception.
//!
//! A [`View`] is one camera frame with its calibration; it answers "what colour is the ground
//! point / the 3-D point here", averaging a 2×2 pixel patch (a little smoothing, as any camera
//! pipeline does). The colour classes are deliberately simple: road surface (close to the
//! asphalt reference the planner measures in front of the car), painted markings (bright and
//! grey, or yellow), and lit lamps (red, amber, green: saturated and bright).

use fogline_types::clip::CameraCalib;

/// One camera frame.
#[derive(Clone, Copy)]
pub struct View<'a> {
    /// Calibration.
    pub calib: &'a CameraCalib,
    /// RGB8 pixels.
    pub rgb: &'a [u8],
}

impl<'a> View<'a> {
    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.calib.width as usize
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.calib.height as usize
    }

    /// The colour at pixel position `(u, v)` (2×2 average), or `None` outside the image.
    #[inline]
    pub fn at(&self, u: f64, v: f64) -> Option<[f32; 3]> {
        let (w, h) = (self.width(), self.height());
        let x = (u - 0.5).floor();
        let y = (v - 0.5).floor();
        if x < 0.0 || y < 0.0 || x + 1.0 >= w as f64 || y + 1.0 >= h as f64 {
            return None;
        }
        let (x, y) = (x as usize, y as usize);
        let mut acc = [0f32; 3];
        for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            let i = ((y + dy) * w + x + dx) * 3;
            for c in 0..3 {
                acc[c] += f32::from(self.rgb[i + c]);
            }
        }
        Some([acc[0] / 4.0, acc[1] / 4.0, acc[2] / 4.0])
    }

    /// The mean colour of the `k × k` pixels around `(u, v)` (a larger patch for large
    /// structures: the road surface and objects on it), or `None` outside the image.
    #[inline]
    pub fn at_k(&self, u: f64, v: f64, k: usize) -> Option<[f32; 3]> {
        let (w, h) = (self.width(), self.height());
        let half = k as f64 / 2.0;
        let x = (u - half).round();
        let y = (v - half).round();
        if x < 0.0 || y < 0.0 || x + k as f64 > w as f64 || y + k as f64 > h as f64 {
            return None;
        }
        let (x, y) = (x as usize, y as usize);
        let mut acc = [0f32; 3];
        for dy in 0..k {
            let row = ((y + dy) * w + x) * 3;
            for px in self.rgb[row..row + 3 * k].chunks_exact(3) {
                acc[0] += f32::from(px[0]);
                acc[1] += f32::from(px[1]);
                acc[2] += f32::from(px[2]);
            }
        }
        let n = (k * k) as f32;
        Some([acc[0] / n, acc[1] / n, acc[2] / n])
    }

    /// [`View::at_k`] at a rig-frame point.
    #[inline]
    pub fn at_point_k(&self, p: [f64; 3], k: usize) -> Option<[f32; 3]> {
        let (u, v, _) = self.calib.project(p)?;
        self.at_k(u, v, k)
    }

    /// The mean of the 2×2 pixels whose top-left is `(x, y)` (clamped at the image edge).
    #[inline]
    pub fn patch2(&self, x: usize, y: usize) -> [f32; 3] {
        let (w, h) = (self.width(), self.height());
        let (x, y) = (x.min(w.saturating_sub(2)), y.min(h.saturating_sub(2)));
        let mut acc = [0f32; 3];
        for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            let c = self.pixel(x + dx, y + dy);
            acc[0] += c[0];
            acc[1] += c[1];
            acc[2] += c[2];
        }
        [acc[0] / 4.0, acc[1] / 4.0, acc[2] / 4.0]
    }

    /// The single pixel at integer position, no averaging.
    #[inline]
    pub fn pixel(&self, x: usize, y: usize) -> [f32; 3] {
        let i = (y * self.width() + x) * 3;
        [
            f32::from(self.rgb[i]),
            f32::from(self.rgb[i + 1]),
            f32::from(self.rgb[i + 2]),
        ]
    }

    /// The colour seen at rig-frame point `p`, or `None` when it is not in view.
    #[inline]
    pub fn at_point(&self, p: [f64; 3]) -> Option<[f32; 3]> {
        let (u, v, _) = self.calib.project(p)?;
        self.at(u, v)
    }

    /// Pixel position of rig-frame point `p`.
    pub fn project(&self, p: [f64; 3]) -> Option<(f64, f64)> {
        self.calib
            .project(p)
            .map(|(u, v, _)| (u, v))
            .filter(|&(u, v)| {
                u >= 0.0 && v >= 0.0 && u < self.width() as f64 && v < self.height() as f64
            })
    }
}

/// Luminance (mean of the channels).
#[inline]
pub fn lum(c: [f32; 3]) -> f32 {
    (c[0] + c[1] + c[2]) / 3.0
}

/// Spread between the largest and smallest channel.
#[inline]
pub fn chroma(c: [f32; 3]) -> f32 {
    c[0].max(c[1]).max(c[2]) - c[0].min(c[1]).min(c[2])
}

/// A painted white marking: brighter than the road by a margin, and grey.
#[inline]
pub fn is_white_paint(c: [f32; 3], road: f32) -> bool {
    lum(c) > road + 55.0 && chroma(c) < 45.0
}

/// Yellow paint.
#[inline]
pub fn is_yellow_paint(c: [f32; 3], road: f32) -> bool {
    c[0] > road + 40.0 && c[1] > road + 20.0 && c[0] - c[2] > 70.0 && c[1] - c[2] > 50.0
}

/// Road surface: close to the asphalt reference and grey, or paint on it.
#[inline]
pub fn is_road(c: [f32; 3], road: f32) -> bool {
    ((lum(c) - road).abs() < 28.0 && chroma(c) < 30.0)
        || is_white_paint(c, road)
        || is_yellow_paint(c, road)
}

/// A lit red lamp (brake light, red signal).
#[inline]
pub fn is_red_lamp(c: [f32; 3]) -> bool {
    c[0] > 200.0 && c[1] < 110.0 && c[2] < 100.0
}

/// A lit green signal.
#[inline]
pub fn is_green_lamp(c: [f32; 3]) -> bool {
    c[1] > 190.0 && c[0] < 130.0 && c[1] - c[0] > 90.0
}

/// A lit amber signal.
#[inline]
pub fn is_amber_lamp(c: [f32; 3]) -> bool {
    c[0] > 200.0 && (120.0..215.0).contains(&c[1]) && c[2] < 90.0
}

/// Sign red: saturated red, not necessarily bright.
#[inline]
pub fn is_sign_red(c: [f32; 3]) -> bool {
    c[0] > 60.0 && c[0] > 2.2 * c[1] && c[0] > 2.2 * c[2]
}
