//! Photometric families: gain, contrast, saturation, colour quantisation, glare; and fog
//! (homogeneous and Koschmieder).
//!
//! Every formula rounds to nearest (`⌊v + ½⌋`, ties up, see [`floor_guarded`]) and clips to
//! [0, 255]; `J` is the input
//! sample, `A` the airlight, all on the 0–255 scale.

use crate::bytemap::{ByteMap, floor_guarded, floor_guarded_u8};
use crate::frame::{DepthMap, Frame};

/// Gain: `out = min(255, ⌊g·J + ½⌋)`. `dark` is `g = 0.4`, `bright` is `g = 1.6`.
pub fn gain_map(g: f64) -> ByteMap {
    ByteMap::affine(g, 0.5)
}

/// Homogeneous fog: `out = ⌊(1 − α)·J + α·A + ½⌋`.
pub fn fog_map(alpha: f64, airlight: f64) -> ByteMap {
    ByteMap::affine(1.0 - alpha, alpha * airlight + 0.5)
}

/// Contrast around the grey `m`: `out = clip(⌊m + c·(J − m) + ½⌋)`.
pub fn contrast_map(c: f64, m: f64) -> ByteMap {
    ByteMap::affine(c, (1.0 - c) * m + 0.5)
}

/// Colour quantisation to `bits` per channel: `L = 2^bits − 1`,
/// `out = ⌊⌊J·L/255 + ½⌋ · 255/L + ½⌋`.
pub fn quantize_map(bits: u32) -> ByteMap {
    let levels = f64::from((1u32 << bits) - 1);
    let mut t = [0u8; 256];
    for (j, v) in t.iter_mut().enumerate() {
        let q = floor_guarded(j as f64 * levels / 255.0 + 0.5);
        *v = floor_guarded(q * 255.0 / levels + 0.5).clamp(0.0, 255.0) as u8;
    }
    ByteMap::new(t, None)
}

/// The mean of all samples of a frame (the grey that contrast scales around).
pub fn mean_level(frame: &Frame) -> f64 {
    let sum: u64 = frame
        .data()
        .chunks(1 << 16)
        .map(|c| c.iter().map(|&v| u64::from(v)).sum::<u64>())
        .sum();
    sum as f64 / frame.data().len() as f64
}

/// Saturation: with the luma `L = 0.299·R + 0.587·G + 0.114·B` (ITU-R BT.601) of each pixel,
/// `out_c = clip(⌊L + s·(J_c − L) + ½⌋)`; `s = 0` is greyscale, `s = 1` the identity.
pub(crate) fn saturation(src: &Frame, dst: &mut Frame, s: f64) {
    for (o, x) in dst
        .data_mut()
        .chunks_exact_mut(3)
        .zip(src.data().chunks_exact(3))
    {
        let l = 0.299 * f64::from(x[0]) + 0.587 * f64::from(x[1]) + 0.114 * f64::from(x[2]);
        for c in 0..3 {
            o[c] = floor_guarded_u8(l + s * (f64::from(x[c]) - l) + 0.5);
        }
    }
}

/// Glare: a veiling bright spot. With the frame diagonal `D`, the spot centre
/// `(cx·W, cy·H)` and radius `ρ = radius·D`, the weight of pixel `(x, y)` (centre at
/// `x + ½, y + ½`) is `w = s · gx(x) · gy(y)`, `gx(x) = exp(−(x + ½ − cx·W)² / (2ρ²))`
/// (likewise `gy`), and `out = ⌊J + (255 − J)·w + ½⌋` (a screen blend towards white).
pub(crate) fn glare(src: &Frame, dst: &mut Frame, s: f64, centre: [f64; 2], radius: f64) {
    let (w, h) = (f64::from(src.width()), f64::from(src.height()));
    let rho = radius * (w * w + h * h).sqrt();
    let g = |p: f64, c: f64| (-(p + 0.5 - c).powi(2) / (2.0 * rho * rho)).exp();
    let gx: Vec<f64> = (0..src.width())
        .map(|x| g(f64::from(x), centre[0] * w))
        .collect();
    let stride = src.stride();
    for (y, (o, i)) in dst
        .data_mut()
        .chunks_exact_mut(stride)
        .zip(src.data().chunks_exact(stride))
        .enumerate()
    {
        let gy = g(y as f64, centre[1] * h);
        for ((o3, i3), &gxx) in o.chunks_exact_mut(3).zip(i.chunks_exact(3)).zip(&gx) {
            let wt = s * gxx * gy;
            for c in 0..3 {
                let j = f64::from(i3[c]);
                o3[c] = (j + (255.0 - j) * wt + 0.5).min(255.0) as u8;
            }
        }
    }
}

/// Koschmieder fog over a depth map: `t = exp(−β·d)`, `out = round(A + (J − A)·t)`.
///
/// Computed in single precision, 4 pixels at a time, with an `exp` accurate to 4e-7 relative
/// (Cody–Waite reduction, degree-6 polynomial): the output equals the double-precision
/// formula except where that formula lies within ~1e-4 of a rounding boundary, where it may
/// differ by one level (the tests check this). `d = +inf` (sky) gives pure airlight, and so
/// does every `d > 0` when `α = 1`; `d = 0` keeps the pixel.
pub(crate) fn koschmieder(src: &Frame, dst: &mut Frame, depth: &DepthMap, beta: f64, a: f64) {
    // A finite β keeps −β·0 = 0 (t = 1 at zero distance) even for opaque fog (α = 1).
    let beta = (beta as f32).min(f32::MAX);
    let a = a as f32;
    let width = src.width() as usize;
    let stride = src.stride();
    // Segments of SEG pixels keep the transmission buffers in L1 and let the out-of-order
    // core overlap the exp of one segment with the blend of the previous.
    const SEG: usize = 128;
    let mut t = [0f32; SEG];
    let mut t3 = [0f32; SEG * 3];
    for ((o, i), d) in dst
        .data_mut()
        .chunks_exact_mut(stride)
        .zip(src.data().chunks_exact(stride))
        .zip(depth.depth_m().chunks_exact(width))
    {
        for ((o, i), d) in o
            .chunks_mut(SEG * 3)
            .zip(i.chunks(SEG * 3))
            .zip(d.chunks(SEG))
        {
            for (tt, &dd) in t.iter_mut().zip(d) {
                *tt = exp_neg(-beta * dd);
            }
            // One transmission per sample: three copies per pixel.
            for (t12, t4) in t3.chunks_exact_mut(12).zip(t.chunks_exact(4)) {
                t12.copy_from_slice(&[
                    t4[0], t4[0], t4[0], t4[1], t4[1], t4[1], t4[2], t4[2], t4[2], t4[3], t4[3],
                    t4[3],
                ]);
            }
            for ((o, &j), &tt) in o.iter_mut().zip(i).zip(&t3) {
                *o = blend(j, tt, a);
            }
        }
    }
}

/// `A + (J − A)·t` rounded to nearest: adding 1.5·2^23 leaves the rounded value in the low
/// mantissa bits (exact ties, which need `t = ½` exactly, round to even).
#[inline(always)]
fn blend(j: u8, t: f32, a: f32) -> u8 {
    const SHIFTER: f32 = 12_582_912.0;
    ((a + (f32::from(j) - a) * t) + SHIFTER).to_bits() as u8
}

/// `exp(x)` for `x <= 0` (and `-inf`), single precision, relative error < 4e-7; below −87
/// it returns `exp(−87) ≈ 1.6e-38` (which no blend can tell from 0).
#[inline(always)]
pub(crate) fn exp_neg(x: f32) -> f32 {
    const SHIFTER: f32 = 12_582_912.0; // 1.5·2^23: adding it rounds to an integer
    let x = x.max(-87.0);
    let m = x * std::f32::consts::LOG2_E + SHIFTER;
    let n = m - SHIFTER;
    let r = x - n * 0.693_145_75 - n * 1.428_606_8e-6;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (0.166_666_67
                    + r * (0.041_666_668 + r * (0.008_333_334 + r * 0.001_388_889)))));
    let e = (m.to_bits() as i32).wrapping_sub(0x4B40_0000) + 127;
    p * f32::from_bits((e as u32) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_neg_is_accurate() {
        let mut x = 0.0f32;
        while x > -80.0 {
            let want = f64::from(x).exp();
            let got = f64::from(exp_neg(x));
            assert!((got - want).abs() <= 4e-7 * want, "{x}: {got} vs {want}");
            x -= 0.01237;
        }
        assert_eq!(exp_neg(0.0), 1.0);
        assert!(exp_neg(f32::NEG_INFINITY) < 1e-37);
        assert!(exp_neg(-100.0) < 1e-37);
    }

    #[test]
    fn quantize_keeps_the_extremes_and_has_the_levels() {
        let m = quantize_map(1);
        assert_eq!(m.table()[0], 0);
        assert_eq!(m.table()[255], 255);
        assert_eq!(m.table()[127], 0);
        assert_eq!(m.table()[128], 255);
        assert!(quantize_map(8).is_identity());
        let mut levels: Vec<u8> = quantize_map(3).table().to_vec();
        levels.dedup();
        assert_eq!(levels.len(), 8);
    }
}
