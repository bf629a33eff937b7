//! Photometric families: gain, contrast, saturation, colour quantisation, glare; and fog
//! (homogeneous and Koschmieder).
//!
//! Every formula rounds to nearest (`⌊v + ½⌋`, ties up, see [`floor_guarded`]) and clips to
//! [0, 255]; `J` is the input
//! sample, `A` the airlight, all on the 0–255 scale.

use crate::bytemap::{ByteMap, floor_guarded, floor_guarded_u8};
use crate::frame::{DepthMap, FrameMut, FrameRef};

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
pub fn mean_level(frame: FrameRef<'_>) -> f64 {
    let sum: u64 = frame
        .data()
        .chunks(1 << 16)
        .map(|c| c.iter().map(|&v| u64::from(v)).sum::<u64>())
        .sum();
    sum as f64 / frame.data().len() as f64
}

/// Saturation: with the luma `L = 0.299·R + 0.587·G + 0.114·B` (ITU-R BT.601) of each pixel,
/// `out_c = clip(⌊L + s·(J_c − L) + ½⌋)`; `s = 0` is greyscale, `s = 1` the identity.
pub(crate) fn saturation(src: FrameRef<'_>, dst: &mut FrameMut<'_>, s: f64) {
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
pub(crate) fn glare(
    src: FrameRef<'_>,
    dst: &mut FrameMut<'_>,
    s: f64,
    centre: [f64; 2],
    radius: f64,
) {
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
/// Computed in single precision: `t = 2^(k·d)` with `k = −β·log₂e`, by [`exp2_neg`] (relative
/// error below 3e-7), then `A + (J − A)·t` rounded to nearest, 16 samples at a time with SSE2
/// on x86-64 (the same operations one sample at a time elsewhere and at the row ends, so the
/// result does not depend on the path). The output equals the double-precision formula except
/// where that formula lies within ~1e-4 of a rounding boundary, where it may differ by one
/// level (the tests check this). `d = +inf` (sky) gives pure airlight, and so does every
/// `d > 0` when `α = 1`; `d = 0` keeps the pixel.
pub(crate) fn koschmieder(
    src: FrameRef<'_>,
    dst: &mut FrameMut<'_>,
    depth: &DepthMap,
    beta: f64,
    a: f64,
) {
    // k = −β·log₂e; a finite β keeps k·0 = 0 (t = 1 at zero distance) even for opaque fog.
    let k = (-beta * std::f64::consts::LOG2_E).max(f64::from(f32::MIN)) as f32;
    let a = a as f32;
    let width = src.width() as usize;
    let stride = src.stride();
    // Segments of SEG pixels keep the transmissions in L1 and let the out-of-order core
    // overlap the exponentials of one segment with the blend of the previous.
    const SEG: usize = 128;
    let mut t = [0f32; SEG];
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
            let t = &mut t[..d.len()];
            transmissions(d, k, t);
            blend_segment(o, i, t, a);
        }
    }
}

/// `t = 2^(k·d)` for each distance.
fn transmissions(d: &[f32], k: f32, t: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    let done = {
        let kv = safe_arch::set_splat_m128(k);
        for (t4, d4) in t.chunks_exact_mut(4).zip(d.chunks_exact(4)) {
            let d4: &[f32; 4] = d4.try_into().expect("4");
            let y = safe_arch::mul_m128(safe_arch::load_unaligned_m128(d4), kv);
            t4.copy_from_slice(&sse::exp2_neg4(y).to_array());
        }
        d.len() / 4 * 4
    };
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    for (tt, &dd) in t[done..].iter_mut().zip(&d[done..]) {
        *tt = exp2_neg(dd * k);
    }
}

/// `A + (J − A)·t` for a segment: `o`, `i` hold 3 samples per transmission in `t`.
fn blend_segment(o: &mut [u8], i: &[u8], t: &[f32], a: f32) {
    #[cfg(target_arch = "x86_64")]
    let done = {
        let av = safe_arch::set_splat_m128(a);
        let groups = t.len() / 16;
        for ((o48, i48), t16) in o
            .chunks_exact_mut(48)
            .zip(i.chunks_exact(48))
            .zip(t.chunks_exact(16))
            .take(groups)
        {
            sse::blend48(o48, i48, t16, av);
        }
        groups * 48
    };
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    for (k, (o, &j)) in o.iter_mut().zip(i).enumerate().skip(done) {
        *o = blend(j, t[k / 3], a);
    }
}

/// `A + (J − A)·t` rounded to nearest: adding 1.5·2^23 leaves the rounded value in the low
/// mantissa bits (exact ties, which need `t = ½` exactly, round to even).
#[inline(always)]
fn blend(j: u8, t: f32, a: f32) -> u8 {
    ((a + (f32::from(j) - a) * t) + SHIFTER).to_bits() as u8
}

/// 1.5·2^23: adding it to a float of magnitude below 2^22 rounds it to an integer, which then
/// sits in the low mantissa bits.
const SHIFTER: f32 = 12_582_912.0;

/// Coefficients of `2^f` on [−½, ½] after the constant 1 (a weighted least-squares fit on
/// Chebyshev nodes; relative error 1.8e-7 evaluated in single precision).
const EXP2_C: [f32; 5] = [
    0.693_146_9,
    0.240_222_38,
    0.055_508_93,
    0.009_671_698,
    0.001_321_867_2,
];

/// `2^y` for `y <= 0` (and `−inf`), single precision, relative error below 3e-7; below −126
/// it returns `2^−126 ≈ 1.2e-38` (which no blend can tell from 0). `n = round(y)`,
/// `f = y − n` (exact), `2^f` by a degree-5 polynomial with `p(0) = 1`, then `2^n` through
/// the exponent bits. The SSE2 version performs the same operations lane by lane.
#[inline(always)]
pub(crate) fn exp2_neg(y: f32) -> f32 {
    let y = y.max(-126.0);
    let m = y + SHIFTER;
    let n = m - SHIFTER;
    let f = y - n;
    let mut p = EXP2_C[3] + f * EXP2_C[4];
    p = EXP2_C[2] + f * p;
    p = EXP2_C[1] + f * p;
    p = EXP2_C[0] + f * p;
    p = 1.0 + f * p;
    let e = (m.to_bits() as i32).wrapping_sub(0x4B40_0000) + 127;
    p * f32::from_bits((e as u32) << 23)
}

/// The SSE2 kernels (x86-64 always has SSE2), through `safe_arch`'s safe wrappers.
#[cfg(target_arch = "x86_64")]
mod sse {
    use super::{EXP2_C, SHIFTER};
    use safe_arch::*;

    /// [`super::exp2_neg`] on 4 lanes (`maxps` returns the constant for a NaN lane, as
    /// `f32::max` does).
    #[inline(always)]
    pub(super) fn exp2_neg4(y: m128) -> m128 {
        let c = set_splat_m128;
        let sh = c(SHIFTER);
        let y = max_m128(y, c(-126.0));
        let m = add_m128(y, sh);
        let n = sub_m128(m, sh);
        let f = sub_m128(y, n);
        let mut p = add_m128(c(EXP2_C[3]), mul_m128(f, c(EXP2_C[4])));
        p = add_m128(c(EXP2_C[2]), mul_m128(f, p));
        p = add_m128(c(EXP2_C[1]), mul_m128(f, p));
        p = add_m128(c(EXP2_C[0]), mul_m128(f, p));
        p = add_m128(c(1.0), mul_m128(f, p));
        let e = add_i32_m128i(
            sub_i32_m128i(cast_to_m128i_from_m128(m), set_splat_i32_m128i(0x4B40_0000)),
            set_splat_i32_m128i(127),
        );
        mul_m128(p, cast_to_m128_from_m128i(shl_imm_u32_m128i::<23>(e)))
    }

    /// 16 pixels: 48 samples of `o`/`i`, 16 transmissions.
    #[inline(always)]
    pub(super) fn blend48(o: &mut [u8], i: &[u8], t: &[f32], a: m128) {
        let tv: [m128; 4] = core::array::from_fn(|q| {
            load_unaligned_m128(t[4 * q..4 * q + 4].try_into().expect("4"))
        });
        // Three copies of each transmission: [t0 t0 t0 t1] [t1 t1 t2 t2] [t2 t3 t3 t3].
        let mut e = [tv[0]; 12];
        for q in 0..4 {
            e[3 * q] = shuffle_abi_f32_all_m128::<0b01_00_00_00>(tv[q], tv[q]);
            e[3 * q + 1] = shuffle_abi_f32_all_m128::<0b10_10_01_01>(tv[q], tv[q]);
            e[3 * q + 2] = shuffle_abi_f32_all_m128::<0b11_11_11_10>(tv[q], tv[q]);
        }
        for c in 0..3 {
            let oc: &mut [u8; 16] = (&mut o[16 * c..16 * c + 16]).try_into().expect("16");
            let ic: &[u8; 16] = i[16 * c..16 * c + 16].try_into().expect("16");
            blend16(
                oc,
                ic,
                [e[4 * c], e[4 * c + 1], e[4 * c + 2], e[4 * c + 3]],
                a,
            );
        }
    }

    /// [`super::blend`] on 16 samples.
    #[inline(always)]
    fn blend16(o: &mut [u8; 16], j: &[u8; 16], t: [m128; 4], a: m128) {
        let shifter = set_splat_m128(SHIFTER);
        let bias = set_splat_i32_m128i(SHIFTER.to_bits() as i32);
        let z = zeroed_m128i();
        let jv = load_unaligned_m128i(j);
        let lo = unpack_low_i8_m128i(jv, z);
        let hi = unpack_high_i8_m128i(jv, z);
        let js = [
            unpack_low_i16_m128i(lo, z),
            unpack_high_i16_m128i(lo, z),
            unpack_low_i16_m128i(hi, z),
            unpack_high_i16_m128i(hi, z),
        ];
        // The rounded values 0..=255 as i32 (the bits above the shifter's), packed to bytes.
        let k: [m128i; 4] = core::array::from_fn(|q| {
            let jf = convert_to_m128_from_i32_m128i(js[q]);
            let y = add_m128(add_m128(a, mul_m128(sub_m128(jf, a), t[q])), shifter);
            sub_i32_m128i(cast_to_m128i_from_m128(y), bias)
        });
        let w = pack_i16_to_u8_m128i(
            pack_i32_to_i16_m128i(k[0], k[1]),
            pack_i32_to_i16_m128i(k[2], k[3]),
        );
        store_unaligned_m128i(o, w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp2_neg_is_accurate_and_the_sse_path_agrees() {
        let mut y = 0.0f32;
        while y > -120.0 {
            let want = f64::from(y).exp2();
            let got = f64::from(exp2_neg(y));
            assert!((got - want).abs() <= 3e-7 * want, "{y}: {got} vs {want}");
            #[cfg(target_arch = "x86_64")]
            {
                let v = sse::exp2_neg4(safe_arch::set_splat_m128(y)).to_array();
                assert_eq!(v[0].to_bits(), exp2_neg(y).to_bits());
            }
            y -= 0.01237;
        }
        assert_eq!(exp2_neg(0.0), 1.0);
        assert_eq!(exp2_neg(-0.0), 1.0);
        assert!(exp2_neg(f32::NEG_INFINITY) < 1.2e-38);
        assert!(exp2_neg(-300.0) < 1.2e-38);
    }

    #[test]
    fn the_sse_blend_equals_the_scalar_blend() {
        // Every J against a spread of transmissions, through both paths.
        let t: Vec<f32> = (0..256).map(|k| exp2_neg(-(k as f32) * 0.037)).collect();
        let i: Vec<u8> = (0..768).map(|k| ((k * 97 + k / 3) % 256) as u8).collect();
        for a in [0.0f32, 204.0, 255.0, 17.5] {
            let mut o = vec![0u8; 768];
            blend_segment(&mut o, &i, &t, a);
            for (k, (&got, &j)) in o.iter().zip(&i).enumerate() {
                assert_eq!(got, blend(j, t[k / 3], a), "sample {k}, A = {a}");
            }
        }
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
