//! JPEG compression artefacts: the lossy half of a baseline JPEG round trip, in memory.
//!
//! Entropy coding is lossless, so a JPEG encode + decode at quality `q` changes pixels only
//! through these steps, which this module performs directly (no codec, no file):
//!
//! 1. RGB → Y Cb Cr (JFIF, full range), each rounded to 8 bits (all roundings here are to
//!    nearest, ties to even);
//! 2. with 4:2:0 subsampling (the default, as libjpeg's), Cb and Cr averaged over 2×2 blocks
//!    (rounded; odd edges replicate);
//! 3. each plane, padded to a multiple of 8 by replicating its edge, in 8×8 blocks: level
//!    shift by −128, forward DCT-II, quantisation `round(F / Q)·Q` with the Annex K tables
//!    scaled as libjpeg does (`s = 5000/q` below 50, else `200 − 2q`; `Q = clip(⌊(Q_K·s +
//!    50)/100⌋, 1, 255)`), inverse DCT, +128, rounded and clipped;
//! 4. chroma upsampled by replication, Y Cb Cr → RGB, rounded and clipped.
//!
//! The DCTs run in single precision with a cosine table, so the result is bit-identical on a
//! platform; it differs from libjpeg's integer DCTs and its "fancy" chroma upsampling by at
//! most a few levels per sample, the artefacts (blocking, ringing, colour bleeding) are the
//! same. Quality 100 is not the identity (chroma subsampling and 8-bit colour conversion still
//! lose information).

use crate::frame::{FrameMut, FrameRef};
use fogline_io::jpeg::{CHROMA_Q, LUMA_Q};

/// The quantisation table of `base` at `quality` (1–100), libjpeg's scaling (the encoder's
/// own: [`fogline_io::jpeg::scaled_table`]).
pub(crate) fn scaled_table(base: &[u16; 64], quality: u32) -> [f32; 64] {
    fogline_io::jpeg::scaled_table(base, quality).map(f32::from)
}

/// An 8-bit plane.
struct Plane {
    w: usize,
    h: usize,
    v: Vec<u8>,
}

/// Adding 1.5·2^23 to a float below 2^22 in magnitude rounds it to the nearest integer (ties
/// to even) in its low mantissa bits — no call to the maths library without SSE4.1.
const SHIFTER: f32 = 12_582_912.0;

/// `v` rounded to nearest and clipped to [0, 255].
#[inline(always)]
fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 255.0) + SHIFTER).to_bits() as u8
}

/// `v` rounded to nearest (ties to even), `|v| < 2^22`.
#[inline(always)]
fn round(v: f32) -> f32 {
    (v + SHIFTER) - SHIFTER
}

/// The JPEG round trip of `src` at `quality` into `dst`.
pub(crate) fn jpeg(src: FrameRef<'_>, dst: &mut FrameMut<'_>, quality: u32, subsample: bool) {
    let (w, h) = (src.width() as usize, src.height() as usize);
    let mut y = Plane {
        w,
        h,
        v: vec![0; w * h],
    };
    let mut cb = Plane {
        w,
        h,
        v: vec![0; w * h],
    };
    let mut cr = Plane {
        w,
        h,
        v: vec![0; w * h],
    };
    for (i, p) in src.data().chunks_exact(3).enumerate() {
        let (r, g, b) = (f32::from(p[0]), f32::from(p[1]), f32::from(p[2]));
        y.v[i] = to_u8(0.299 * r + 0.587 * g + 0.114 * b);
        cb.v[i] = to_u8(-0.168_736 * r - 0.331_264 * g + 0.5 * b + 128.0);
        cr.v[i] = to_u8(0.5 * r - 0.418_688 * g - 0.081_312 * b + 128.0);
    }
    if subsample {
        cb = halve(&cb);
        cr = halve(&cr);
    }
    let cos = cos_table();
    let lq = scaled_table(&LUMA_Q, quality);
    let cq = scaled_table(&CHROMA_Q, quality);
    round_trip(&mut y, &lq, &cos);
    round_trip(&mut cb, &cq, &cos);
    round_trip(&mut cr, &cq, &cos);
    let sh = usize::from(subsample);
    let out = dst.data_mut();
    for yy in 0..h {
        for xx in 0..w {
            let i = yy * w + xx;
            let ci = (yy >> sh) * cb.w + (xx >> sh);
            let l = f32::from(y.v[i]);
            let b = f32::from(cb.v[ci]) - 128.0;
            let r = f32::from(cr.v[ci]) - 128.0;
            out[i * 3] = to_u8(l + 1.402 * r);
            out[i * 3 + 1] = to_u8(l - 0.344_136 * b - 0.714_136 * r);
            out[i * 3 + 2] = to_u8(l + 1.772 * b);
        }
    }
}

/// 2×2 mean (rounded), odd edges replicated.
fn halve(p: &Plane) -> Plane {
    let (w2, h2) = (p.w.div_ceil(2), p.h.div_ceil(2));
    let mut v = vec![0u8; w2 * h2];
    for y in 0..h2 {
        for x in 0..w2 {
            let mut s = 0u32;
            for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let yy = (2 * y + dy).min(p.h - 1);
                let xx = (2 * x + dx).min(p.w - 1);
                s += u32::from(p.v[yy * p.w + xx]);
            }
            v[y * w2 + x] = ((s + 2) / 4) as u8;
        }
    }
    Plane { w: w2, h: h2, v }
}

/// `c[u][x] = C(u)/2 · cos((2x + 1)uπ/16)`, `C(0) = 1/√2`, `C(u) = 1` otherwise.
fn cos_table() -> [[f32; 8]; 8] {
    let mut c = [[0f32; 8]; 8];
    for (u, row) in c.iter_mut().enumerate() {
        let cu = if u == 0 {
            std::f64::consts::FRAC_1_SQRT_2
        } else {
            1.0
        };
        for (x, v) in row.iter_mut().enumerate() {
            let a = ((2 * x + 1) * u) as f64 * std::f64::consts::PI / 16.0;
            *v = (cu / 2.0 * a.cos()) as f32;
        }
    }
    c
}

/// `Σ_k w[k] · m[k]`: a row vector times a matrix.
#[inline(always)]
fn rows_times(w: &[f32; 8], m: &[[f32; 8]; 8]) -> [f32; 8] {
    let mut r = [0f32; 8];
    for k in 0..8 {
        for x in 0..8 {
            r[x] += w[k] * m[k][x];
        }
    }
    r
}

/// DCT, quantise, dequantise, inverse DCT, every 8×8 block of `p`, in place.
fn round_trip(p: &mut Plane, q: &[f32; 64], c: &[[f32; 8]; 8]) {
    let mut ct = [[0f32; 8]; 8];
    for (i, row) in c.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            ct[j][i] = v;
        }
    }
    let mut block = [[0f32; 8]; 8];
    let mut tmp = [[0f32; 8]; 8];
    for by in (0..p.h).step_by(8) {
        for bx in (0..p.w).step_by(8) {
            for (y, row) in block.iter_mut().enumerate() {
                let yy = (by + y).min(p.h - 1);
                for (x, v) in row.iter_mut().enumerate() {
                    let xx = (bx + x).min(p.w - 1);
                    *v = f32::from(p.v[yy * p.w + xx]) - 128.0;
                }
            }
            // Every product below is a sum of scaled rows, which the compiler vectorises.
            // forward: T = C · B, then F = T · Cᵀ
            for u in 0..8 {
                tmp[u] = rows_times(&c[u], &block);
            }
            for u in 0..8 {
                block[u] = rows_times(&tmp[u], &ct);
            }
            for u in 0..8 {
                for v in 0..8 {
                    let k = q[u * 8 + v];
                    block[u][v] = round(block[u][v] / k) * k;
                }
            }
            // inverse: T = Cᵀ · F, then B = T · C
            for y in 0..8 {
                tmp[y] = rows_times(&ct[y], &block);
            }
            for y in 0..8 {
                block[y] = rows_times(&tmp[y], c);
            }
            for y in 0..8 {
                let yy = by + y;
                if yy >= p.h {
                    break;
                }
                for x in 0..8 {
                    let xx = bx + x;
                    if xx >= p.w {
                        break;
                    }
                    p.v[yy * p.w + xx] = to_u8(block[y][x] + 128.0);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Frame;

    #[test]
    fn tables_scale_like_libjpeg() {
        assert_eq!(scaled_table(&LUMA_Q, 50)[0], 16.0);
        assert_eq!(scaled_table(&LUMA_Q, 100)[63], 1.0);
        assert_eq!(scaled_table(&LUMA_Q, 10)[0], 80.0);
        assert_eq!(scaled_table(&LUMA_Q, 1)[63], 255.0);
    }

    #[test]
    fn flat_grey_survives_and_detail_degrades_with_quality() {
        let flat = Frame::filled(16, 16, [128, 128, 128]).unwrap();
        let mut out = flat.clone();
        jpeg(flat.view(), &mut out.view_mut(), 10, true);
        assert_eq!(out, flat);
        let data: Vec<u8> = (0..32 * 32 * 3).map(|i| ((i * 97) % 256) as u8).collect();
        let src = Frame::new(32, 32, data).unwrap();
        let err = |q| {
            let mut o = src.clone();
            jpeg(src.view(), &mut o.view_mut(), q, true);
            o.data()
                .iter()
                .zip(src.data())
                .map(|(&a, &b)| (f64::from(a) - f64::from(b)).abs())
                .sum::<f64>()
        };
        assert!(err(10) > err(50));
        assert!(err(50) > err(95));
    }
}
