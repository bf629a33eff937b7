//! Spatial families: defocus blur, motion blur, pixelation.
//!
//! All three average integer samples and round half up: `out = ⌊(Σ + n/2) / n⌋` in integer
//! arithmetic, so they are exact and platform-independent. Neighbours outside the frame are
//! the nearest edge pixel (replicate padding), so every output averages exactly `n` samples.

use crate::frame::{FrameMut, FrameRef};

/// Defocus: the mean over a disk, every offset `(dx, dy)` with `dx² + dy² <= r²`
/// (`n = Σ_dy (2·⌊√(r² − dy²)⌋ + 1)` samples). Row runs are summed from per-row prefix sums,
/// so the cost is `O(W·H·(2r + 1))`. `r < 1` is the identity.
pub(crate) fn defocus(src: FrameRef<'_>, dst: &mut FrameMut<'_>, radius: f64) {
    let rr = radius.floor() as usize;
    let half: Vec<usize> = (0..=rr)
        .map(|dy| {
            let v = radius * radius - (dy * dy) as f64;
            v.max(0.0).sqrt().floor() as usize
        })
        .collect();
    let n: u32 = (0..=2 * rr)
        .map(|k| 2 * half[k.abs_diff(rr)] as u32 + 1)
        .sum();
    let (w, h) = (src.width() as usize, src.height() as usize);
    let wp = w + 2 * rr + 1; // prefix length of a padded row
    // prefix[(y * 3 + c) * wp + k] = sum of the first k padded samples of row y, channel c
    let mut prefix = vec![0u32; h * 3 * wp];
    let data = src.data();
    for y in 0..h {
        let row = &data[y * w * 3..(y + 1) * w * 3];
        for c in 0..3 {
            let p = &mut prefix[(y * 3 + c) * wp..(y * 3 + c + 1) * wp];
            let mut acc = 0u32;
            for k in 0..wp - 1 {
                let x = (k as isize - rr as isize).clamp(0, w as isize - 1) as usize;
                p[k] = acc;
                acc += u32::from(row[x * 3 + c]);
            }
            p[wp - 1] = acc;
        }
    }
    let div = RoundDiv::new(n, 255 * n);
    let out = dst.data_mut();
    let mut acc = vec![0u32; w];
    for y in 0..h {
        for c in 0..3 {
            acc.fill(0);
            for k in 0..=2 * rr {
                let yy = (y + k).saturating_sub(rr).min(h - 1);
                let hw = half[k.abs_diff(rr)];
                let p = &prefix[(yy * 3 + c) * wp..(yy * 3 + c + 1) * wp];
                // padded index of x is x + rr; the run is [x + rr − hw, x + rr + hw]
                let hi = &p[rr + hw + 1..rr + hw + 1 + w];
                let lo = &p[rr - hw..rr - hw + w];
                for ((a, &h1), &l1) in acc.iter_mut().zip(hi).zip(lo) {
                    *a += h1 - l1;
                }
            }
            for (x, &a) in acc.iter().enumerate() {
                out[(y * w + x) * 3 + c] = div.apply(a);
            }
        }
    }
}

/// `⌊(a + n/2) / n⌋` for `a <= max`, by table when the table is small.
struct RoundDiv {
    n: u32,
    table: Vec<u8>,
}

impl RoundDiv {
    fn new(n: u32, max: u32) -> Self {
        let table = if max < 1 << 20 {
            (0..=max).map(|a| ((a + n / 2) / n) as u8).collect()
        } else {
            Vec::new()
        };
        Self { n, table }
    }

    #[inline]
    fn apply(&self, a: u32) -> u8 {
        match self.table.get(a as usize) {
            Some(&q) => q,
            None => ((a + self.n / 2) / self.n) as u8,
        }
    }
}

/// The pixel offsets of a motion-blur line: `length` taps `t = i − (length − 1)/2`,
/// `(dx, dy) = (round(t·cos θ), −round(t·sin θ))` (θ counter-clockwise from the x axis,
/// y pointing down).
pub(crate) fn motion_taps(length: u32, angle_deg: f64) -> Vec<(i64, i64)> {
    let (s, c) = angle_deg.to_radians().sin_cos();
    (0..length)
        .map(|i| {
            let t = f64::from(i) - f64::from(length - 1) / 2.0;
            ((t * c).round() as i64, -((t * s).round() as i64))
        })
        .collect()
}

/// Motion blur: the mean over the taps of [`motion_taps`] (`n = length`). `length = 1` is the
/// identity.
pub(crate) fn motion(src: FrameRef<'_>, dst: &mut FrameMut<'_>, length: u32, angle_deg: f64) {
    let taps = motion_taps(length, angle_deg);
    let div = RoundDiv::new(length, 255 * length);
    let (w, h) = (src.width() as i64, src.height() as i64);
    let stride = src.stride();
    let data = src.data();
    let out = dst.data_mut();
    let mut acc = vec![0u32; stride];
    for y in 0..h {
        acc.fill(0);
        for &(dx, dy) in &taps {
            let yy = (y + dy).clamp(0, h - 1) as usize;
            let row = &data[yy * stride..(yy + 1) * stride];
            // Columns x with 0 <= x + dx < w read in place; the others read the edge pixel.
            let a = (-dx).clamp(0, w) as usize;
            let b = (w - dx).clamp(0, w) as usize;
            let (a, b) = (a.min(b), b);
            for x in (0..a).chain(b..w as usize) {
                let xx = (x as i64 + dx).clamp(0, w - 1) as usize;
                for c in 0..3 {
                    acc[x * 3 + c] += u32::from(row[xx * 3 + c]);
                }
            }
            if a < b {
                let shift = (a as i64 + dx) as usize * 3;
                for (s, &v) in acc[a * 3..b * 3]
                    .iter_mut()
                    .zip(&row[shift..shift + (b - a) * 3])
                {
                    *s += u32::from(v);
                }
            }
        }
        for (o, &s) in out[y as usize * stride..(y as usize + 1) * stride]
            .iter_mut()
            .zip(&acc)
        {
            *o = div.apply(s);
        }
    }
}

/// Pixelation: the frame is cut into `block × block` tiles from the top-left corner (edge
/// tiles are smaller) and every pixel takes its tile's mean. `block = 1` is the identity.
pub(crate) fn pixelate(src: FrameRef<'_>, dst: &mut FrameMut<'_>, block: u32) {
    let b = block as usize;
    let (w, h) = (src.width() as usize, src.height() as usize);
    let data = src.data();
    let out = dst.data_mut();
    for ty in (0..h).step_by(b) {
        let y1 = (ty + b).min(h);
        for tx in (0..w).step_by(b) {
            let x1 = (tx + b).min(w);
            let n = ((y1 - ty) * (x1 - tx)) as u32;
            let mut sum = [0u32; 3];
            for y in ty..y1 {
                for x in tx..x1 {
                    for c in 0..3 {
                        sum[c] += u32::from(data[(y * w + x) * 3 + c]);
                    }
                }
            }
            let mean = sum.map(|s| ((s + n / 2) / n) as u8);
            for y in ty..y1 {
                for x in tx..x1 {
                    out[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&mean);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Frame;

    fn frame(w: u32, h: u32) -> Frame {
        let data = (0..w * h * 3).map(|i| (i * 37 % 251) as u8).collect();
        Frame::new(w, h, data).unwrap()
    }

    #[test]
    fn defocus_matches_a_direct_disk_average() {
        let src = frame(9, 7);
        let mut dst = src.clone();
        let r = 2.5;
        defocus(src.view(), &mut dst.view_mut(), r);
        for y in 0..7i64 {
            for x in 0..9i64 {
                for c in 0..3 {
                    let (mut s, mut n) = (0u32, 0u32);
                    for dy in -3i64..=3 {
                        for dx in -3i64..=3 {
                            if (dx * dx + dy * dy) as f64 <= r * r {
                                let xx = (x + dx).clamp(0, 8) as u32;
                                let yy = (y + dy).clamp(0, 6) as u32;
                                s += u32::from(src.pixel(xx, yy)[c]);
                                n += 1;
                            }
                        }
                    }
                    assert_eq!(
                        dst.pixel(x as u32, y as u32)[c],
                        ((s + n / 2) / n) as u8,
                        "({x}, {y}, {c})"
                    );
                }
            }
        }
    }

    #[test]
    fn motion_matches_a_direct_line_average() {
        let src = frame(11, 6);
        for (len, angle) in [(5, 0.0), (4, 30.0), (7, 90.0), (15, 200.0)] {
            let mut dst = src.clone();
            motion(src.view(), &mut dst.view_mut(), len, angle);
            let taps = motion_taps(len, angle);
            for y in 0..6i64 {
                for x in 0..11i64 {
                    for c in 0..3 {
                        let s: u32 = taps
                            .iter()
                            .map(|&(dx, dy)| {
                                let xx = (x + dx).clamp(0, 10) as u32;
                                let yy = (y + dy).clamp(0, 5) as u32;
                                u32::from(src.pixel(xx, yy)[c])
                            })
                            .sum();
                        assert_eq!(
                            dst.pixel(x as u32, y as u32)[c],
                            ((s + len / 2) / len) as u8,
                            "len {len} angle {angle} ({x}, {y}, {c})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn motion_taps_are_a_centred_line() {
        assert_eq!(motion_taps(3, 0.0), vec![(-1, 0), (0, 0), (1, 0)]);
        assert_eq!(motion_taps(3, 90.0), vec![(0, 1), (0, 0), (0, -1)]);
        assert_eq!(motion_taps(1, 33.0), vec![(0, 0)]);
    }

    #[test]
    fn pixelate_averages_tiles() {
        let src = Frame::new(3, 1, vec![0, 0, 0, 10, 10, 10, 255, 255, 255]).unwrap();
        let mut dst = src.clone();
        pixelate(src.view(), &mut dst.view_mut(), 2);
        assert_eq!(dst.data(), &[5, 5, 5, 5, 5, 5, 255, 255, 255]);
    }
}
