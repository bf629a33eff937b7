//! Noise families: exact Gaussian noise, shot (Poisson) noise, impulse (salt-and-pepper)
//! noise.
//!
//! All three are independent per pixel *and channel*, drawn from one [`WyRand`] stream per
//! image row (`child(step_seed, [row])`), so a frame's noise does not depend on how its rows
//! or frames are scheduled.
//!
//! # Gaussian noise, exactly
//!
//! The condition `noise_σ` adds `N(0, σ²)` (σ on the 0–255 scale) to every sample, rounds to
//! the nearest integer and clips to [0, 255]. Because pixel values are integers,
//! `round(x + n) = x + round(n)`, so the added noise is the integer `K` with
//!
//! ```text
//! P(K = k) = Φ((k + ½)/σ) − Φ((k − ½)/σ)
//! ```
//!
//! and the output is `clip(x + K, 0, 255)`. fogline samples that discrete law directly; it
//! never draws a floating-point normal:
//!
//! - `K = S·M` with `M = |K|` and an independent fair sign `S` (the law is symmetric);
//!   `P(M = 0) = P(K = 0)`, `P(M = m) = 2·P(K = m)` for `1 <= m <= 254`, and `M = 255`
//!   carries the whole tail `P(|K| >= 255)`, which clipping maps to 0 or 255 from any `x`.
//! - `M` is the inverse CDF of a uniform 64-bit `U`: `M = #{m : T_m <= U}` with thresholds
//!   `T_m = 2^64 − round(2^64 · P(M > m))` and `P(M > m) = 2·Q((m + ½)/σ)` computed as an upper
//!   tail (Cody's `erfc`), so the sampled law equals the rounded-Gaussian law to 2^-64 per
//!   value plus the double-precision error of `Q`.
//! - Speed: a 2^16-entry guide table (64 KiB) maps the top 16 bits of `U` to `M` whenever all
//!   `U` with those bits give the same `M`. Only the few buckets that straddle a threshold
//!   (0.07 % of draws at σ = 10, 0.42 % at σ = 70) draw 48 more bits from a second stream and
//!   search the thresholds. One 64-bit word serves four samples; one more word gives the
//!   signs of 64 samples. The sign and the clip are a saturating add or subtract, done 16
//!   samples at a time (SSE2).
//!
//! Stream layout: row `r` of a frame draws from `main = WyRand(row_seed)` with
//! `row_seed = child(step_seed, [r])`, and from `aux = WyRand(child(row_seed, [1]))`. The row
//! is cut into blocks of 256 samples (the last one shorter); for a block of `n` samples `main`
//! yields `⌈n/64⌉` sign words (bit `i % 64` of word `i / 64` set means `S = −1` for sample `i`
//! of the block), then `⌈n/4⌉` index words (sample `i` takes the 16-bit field at bits
//! `16·(i % 4)` of word `i / 4` as the top 16 bits of `U`); a straddling sample takes the
//! next word `w` of `aux` and uses `U = field << 48 | w >> 16`.
//!
//! On a mid-grey (128) frame this gives a mean shift of 0 (exactly `−Φ(−127.5/σ)`: −0.034 at
//! σ = 70, because 128 is one level further from 0 than from 255) and standard deviations
//! 10.00, 30.00, 49.51 and 65.75 for σ = 10, 30, 50, 70 (the last two lowered by clipping);
//! the integration tests check samples against this law with moments and a χ² test. Cost:
//! about one cycle per sample plus a vectorised pass; the tables are built once per condition
//! (`Perturbation::prepare`).

use crate::frame::Frame;
use crate::rng::{WyRand, child, probability_threshold};
use fogline_stats::special::norm_sf;

/// Bits of `U` that index the guide table.
const GUIDE_BITS: u32 = 16;
/// Entries of the guide table.
const GUIDE_LEN: usize = 1 << GUIDE_BITS;
/// Guide entry meaning "straddles a threshold: resolve with more bits".
const RESOLVE: u8 = 255;
/// Samples of a row processed together (a multiple of 64).
const BLOCK: usize = 256;

/// The sampling tables of Gaussian noise with one σ (built once, used for every frame).
#[derive(Debug, Clone)]
pub struct GaussianTable {
    sigma: f64,
    /// `T_0 … T_254`: `M = #{m : T_m <= U}`.
    thresholds: Box<[u64; 255]>,
    /// `M` for each value of the top 14 bits of `U`, or [`RESOLVE`].
    guide: Box<[u8; GUIDE_LEN]>,
    /// The smallest `M` of each bucket (where the slow path starts searching).
    start: Box<[u8; GUIDE_LEN]>,
}

impl GaussianTable {
    /// The tables for standard deviation `sigma` (> 0, finite) on the 0–255 scale.
    pub fn new(sigma: f64) -> Self {
        assert!(
            sigma > 0.0 && sigma.is_finite(),
            "sigma validated by the caller"
        );
        let mut thresholds = Box::new([0u64; 255]);
        for (m, t) in thresholds.iter_mut().enumerate() {
            let tail = 2.0 * norm_sf((m as f64 + 0.5) / sigma); // P(M > m)
            let scaled = (tail * 18_446_744_073_709_551_616.0).round() as u128;
            let v = (1u128 << 64) - scaled.min(1u128 << 64);
            *t = v.min(u128::from(u64::MAX)) as u64;
        }
        let mut table = Self {
            sigma,
            thresholds,
            guide: Box::new([0u8; GUIDE_LEN]),
            start: Box::new([0u8; GUIDE_LEN]),
        };
        let shift = 64 - GUIDE_BITS;
        for b in 0..GUIDE_LEN as u64 {
            let lo = b << shift;
            let hi = lo | ((1u64 << shift) - 1);
            let (m_lo, m_hi) = (table.magnitude(lo), table.magnitude(hi));
            table.start[b as usize] = m_lo;
            table.guide[b as usize] = if m_lo == m_hi && m_lo != RESOLVE {
                m_lo
            } else {
                RESOLVE
            };
        }
        table
    }

    /// σ on the 0–255 scale.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// `M` for the uniform 64-bit value `u` (the exact inverse CDF).
    #[inline]
    fn magnitude(&self, u: u64) -> u8 {
        self.thresholds.partition_point(|&t| t <= u) as u8
    }

    /// The law the sampler realises, exactly: `P(K = k)` for `k` in −255..=255 (index
    /// `k + 255`), with the tails beyond ±255 lumped at ±255. Computed from the 64-bit
    /// thresholds, so it is what the tables produce, not what they approximate.
    pub fn sampled_law(&self) -> Vec<f64> {
        let mut p_m = [0f64; 256];
        let mut prev = 0u128;
        for m in 0..256 {
            let t = if m < 255 {
                u128::from(self.thresholds[m])
            } else {
                1u128 << 64
            };
            p_m[m] = (t - prev) as f64 / 18_446_744_073_709_551_616.0;
            prev = t;
        }
        let mut law = vec![0f64; 511];
        law[255] = p_m[0];
        for m in 1..256 {
            law[255 + m] = p_m[m] / 2.0;
            law[255 - m] = p_m[m] / 2.0;
        }
        law
    }

    /// Fraction of guide buckets that need the slow path (the share of draws that do).
    pub fn resolve_share(&self) -> f64 {
        self.guide.iter().filter(|&&g| g == RESOLVE).count() as f64 / GUIDE_LEN as f64
    }

    /// Adds the noise to `src` into `dst` (same size), one stream per row under `stream`.
    pub(crate) fn apply(&self, src: &Frame, dst: &mut Frame, stream: u64) {
        let stride = src.stride();
        let mut scratch = RowScratch::new(BLOCK);
        for (row, (s, d)) in src
            .data()
            .chunks_exact(stride)
            .zip(dst.data_mut().chunks_exact_mut(stride))
            .enumerate()
        {
            self.apply_row(s, d, child(stream, &[row as u64]), &mut scratch);
        }
    }

    fn apply_row(&self, src: &[u8], dst: &mut [u8], row_seed: u64, sc: &mut RowScratch) {
        let mut main = WyRand::new(row_seed);
        let mut aux = WyRand::new(child(row_seed, &[1]));
        for (s, d) in src.chunks(BLOCK).zip(dst.chunks_mut(BLOCK)) {
            self.apply_block(s, d, &mut main, &mut aux, sc);
        }
    }

    /// One block of at most [`BLOCK`] samples of a row (small blocks keep the buffers in L1 and
    /// let the out-of-order core overlap one block's lookups with the previous block's output).
    fn apply_block(
        &self,
        src: &[u8],
        dst: &mut [u8],
        main: &mut WyRand,
        aux: &mut WyRand,
        sc: &mut RowScratch,
    ) {
        let n = src.len();
        let (n_signs, n_words) = (n.div_ceil(64), n.div_ceil(4));
        for (w, negs) in sc.signs[..n_signs]
            .iter_mut()
            .zip(sc.negs.chunks_exact_mut(64))
        {
            *w = main.next_u64();
            // Byte masks, written 8 at a time and read back 16 at a time much later (reading
            // them straight from the two 8-byte stores would stall store forwarding).
            for (k, b) in w.to_le_bytes().iter().enumerate() {
                negs[8 * k..8 * k + 8].copy_from_slice(&SIGN_MASKS[*b as usize].to_le_bytes());
            }
        }
        let guide: &[u8; GUIDE_LEN] = &self.guide;
        const MASK: u64 = (GUIDE_LEN - 1) as u64;
        for (w, m4) in sc.words[..n_words]
            .iter_mut()
            .zip(sc.mags.chunks_exact_mut(4))
        {
            let r = main.next_u64();
            *w = r;
            m4[0] = guide[(r & MASK) as usize];
            m4[1] = guide[((r >> 16) & MASK) as usize];
            m4[2] = guide[((r >> 32) & MASK) as usize];
            m4[3] = guide[(r >> 48) as usize];
        }
        let full = n / 16 * 16;
        // Bit c: chunk c of 16 samples has a straddling draw. Collected without branches and
        // walked afterwards, so a rare slow draw costs one mispredicted branch, not three.
        let mut flagged = 0u64;
        for (c, (((o, x), m), neg)) in dst[..full]
            .chunks_exact_mut(16)
            .zip(src[..full].chunks_exact(16))
            .zip(sc.mags[..full].chunks_exact(16))
            .zip(sc.negs[..full].chunks_exact(16))
            .enumerate()
        {
            let o: &mut [u8; 16] = o.try_into().expect("16");
            let x: [u8; 16] = x.try_into().expect("16");
            let m: [u8; 16] = m.try_into().expect("16");
            let neg: [u8; 16] = neg.try_into().expect("16");
            flagged |= u64::from(combine16(o, x, m, neg)) << c;
        }
        while flagged != 0 {
            let c = flagged.trailing_zeros() as usize;
            flagged &= flagged - 1;
            for half in [c * 16, c * 16 + 8] {
                let w = u64::from_le_bytes(sc.mags[half..half + 8].try_into().expect("8"));
                let mut lanes = bytes_equal_to_ff(w);
                while lanes != 0 {
                    let i = half + (lanes.trailing_zeros() / 8) as usize;
                    lanes &= lanes - 1;
                    dst[i] = self.resolve(sc.field(i), src[i], sc.negs[i] != 0, aux);
                }
            }
        }
        for i in full..n {
            let negative = sc.negs[i] != 0;
            let m = sc.mags[i];
            dst[i] = if m == RESOLVE {
                self.resolve(sc.field(i), src[i], negative, aux)
            } else if negative {
                src[i].saturating_sub(m)
            } else {
                src[i].saturating_add(m)
            };
        }
    }

    /// The slow path: `U = field << 48 | w >> 16` with `w` the next auxiliary word, searched
    /// from the first magnitude of the field's guide bucket.
    #[inline]
    fn resolve(&self, field: u64, x: u8, negative: bool, aux: &mut WyRand) -> u8 {
        let u = (field << 48) | (aux.next_u64() >> 16);
        let mut m = usize::from(self.start[(field >> (16 - GUIDE_BITS)) as usize]);
        while m < 255 && self.thresholds[m] <= u {
            m += 1;
        }
        debug_assert_eq!(m, usize::from(self.magnitude(u)));
        if negative {
            x.saturating_sub(m as u8)
        } else {
            x.saturating_add(m as u8)
        }
    }
}

/// Per-row buffers of the Gaussian kernel.
struct RowScratch {
    signs: Vec<u64>,
    /// `0xFF` where the sample's sign is negative.
    negs: Vec<u8>,
    words: Vec<u64>,
    mags: Vec<u8>,
}

impl RowScratch {
    /// The 16-bit field of sample `i`.
    #[inline]
    fn field(&self, i: usize) -> u64 {
        (self.words[i / 4] >> (16 * (i % 4))) & 0xFFFF
    }

    fn new(n: usize) -> Self {
        let n_words = n.div_ceil(4);
        Self {
            signs: vec![0; n.div_ceil(64)],
            negs: vec![0; n.div_ceil(64) * 64],
            words: vec![0; n_words],
            mags: vec![0; n_words * 4],
        }
    }
}

/// `out = x −sat m` where `neg`, else `x +sat m`; returns whether any `m` is [`RESOLVE`].
/// (Written so that the compiler emits one SSE2 instruction per line, `pmovmskb` for the
/// test.)
#[inline(always)]
fn combine16(o: &mut [u8; 16], x: [u8; 16], m: [u8; 16], neg: [u8; 16]) -> bool {
    let mut any = false;
    for j in 0..16 {
        any |= m[j] == RESOLVE;
        let up = x[j].saturating_add(m[j]);
        let down = x[j].saturating_sub(m[j]);
        o[j] = (down & neg[j]) | (up & !neg[j]);
    }
    any
}

/// Bit 7 of each byte of the result is set exactly where `w` has a byte `0xFF` (exact, no
/// false positives).
#[inline]
fn bytes_equal_to_ff(w: u64) -> u64 {
    const LOW7: u64 = 0x7F7F_7F7F_7F7F_7F7F;
    let t = !w; // bytes that were 0xFF are now 0
    !(((t & LOW7) + LOW7) | t | LOW7)
}

/// Byte masks of the 256 bit patterns of a byte.
static SIGN_MASKS: [u64; 256] = {
    let mut t = [0u64; 256];
    let mut b = 0;
    while b < 256 {
        let mut v = 0u64;
        let mut j = 0;
        while j < 8 {
            if (b >> j) & 1 == 1 {
                v |= 0xFF << (8 * j);
            }
            j += 1;
        }
        t[b] = v;
        b += 1;
    }
    t
};

/// Shot (photon) noise with `s` intensity units per photon.
///
/// `out = clip(round(s · N), 0, 255)` with `N ~ Poisson(x / s)`: the variance at intensity
/// `x` is `s·x` (so `shot_4` gives a standard deviation of 22.6 at mid-grey). Sampled exactly
/// like the Gaussian: for each input value `x` the law of `out` is tabulated as 64-bit
/// inverse-CDF thresholds from the Poisson probabilities (computed in log space with exact
/// `ln n!` sums), one 64-bit draw per sample. imagecorruptions' `shot_noise` with `c` photons
/// at full scale is `s = 255 / c` (severity 1–5: 4.25, 10.2, 21.3, 51, 85), but it floors.
#[derive(Debug, Clone)]
pub struct ShotTable {
    /// Per input value: thresholds `T_v` for `v = 0..=254`; `out = #{v : T_v <= U}`.
    thresholds: Vec<[u64; 255]>,
    /// Per input value: the output for the smallest `U` with each top byte (where the search
    /// starts).
    start: Vec<[u8; 256]>,
}

impl ShotTable {
    /// The tables for `s` (> 0) intensity units per photon.
    pub fn new(s: f64) -> Self {
        assert!(s > 0.0 && s.is_finite(), "validated by the caller");
        let n_cap = (254.5 / s).ceil() as usize + 1;
        // ln n! for n = 0..=n_cap
        let mut ln_fact = Vec::with_capacity(n_cap + 1);
        let mut acc = 0f64;
        ln_fact.push(0.0);
        for n in 1..=n_cap {
            acc += (n as f64).ln();
            ln_fact.push(acc);
        }
        let mut thresholds = Vec::with_capacity(256);
        for x in 0..256usize {
            let lambda = x as f64 / s;
            let mut p_v = [0f64; 256];
            if x == 0 {
                p_v[0] = 1.0;
            } else {
                let ln_l = lambda.ln();
                for (n, lf) in ln_fact.iter().enumerate() {
                    let v = (s * n as f64 + 0.5).floor();
                    if v >= 255.0 {
                        break;
                    }
                    p_v[v as usize] += (n as f64 * ln_l - lambda - lf).exp();
                }
            }
            let mut t = [0u64; 255];
            let mut cum = 0f64;
            for v in 0..255 {
                cum += p_v[v];
                t[v] = probability_threshold(cum);
            }
            thresholds.push(t);
        }
        let start = thresholds
            .iter()
            .map(|t| {
                let mut g = [0u8; 256];
                for (b, v) in g.iter_mut().enumerate() {
                    *v = t.partition_point(|&th| th <= (b as u64) << 56) as u8;
                }
                g
            })
            .collect();
        Self { thresholds, start }
    }

    pub(crate) fn apply(&self, src: &Frame, dst: &mut Frame, stream: u64) {
        let stride = src.stride();
        for (row, (s, d)) in src
            .data()
            .chunks_exact(stride)
            .zip(dst.data_mut().chunks_exact_mut(stride))
            .enumerate()
        {
            let mut rng = WyRand::at(stream, &[row as u64]);
            for (o, &x) in d.iter_mut().zip(s) {
                let u = rng.next_u64();
                let t = &self.thresholds[x as usize];
                let mut v = usize::from(self.start[x as usize][(u >> 56) as usize]);
                while v < 255 && t[v] <= u {
                    v += 1;
                }
                *o = v as u8;
            }
        }
    }
}

/// Impulse (salt-and-pepper) noise: each sample independently becomes 0 with probability
/// `p/2`, 255 with probability `p/2`, and keeps its value otherwise (exact to 2^-32; one
/// 32-bit draw per sample). As skimage's `s&p` mode behind imagecorruptions'
/// `impulse_noise` (amounts .03/.06/.09/.17/.27 for severity 1–5).
pub(crate) fn impulse(src: &Frame, dst: &mut Frame, p: f64, stream: u64) {
    // An even threshold so that salt and pepper are exactly equally likely.
    let t = 2 * ((p.clamp(0.0, 1.0) * 2_147_483_648.0).round() as u64).min(1 << 31);
    let stride = src.stride();
    for (row, (s, d)) in src
        .data()
        .chunks_exact(stride)
        .zip(dst.data_mut().chunks_exact_mut(stride))
        .enumerate()
    {
        let mut rng = WyRand::at(stream, &[row as u64]);
        for (o2, x2) in d.chunks_mut(2).zip(s.chunks(2)) {
            let r = rng.next_u64();
            for (j, (o, &x)) in o2.iter_mut().zip(x2).enumerate() {
                let u = (r >> (32 * j)) & 0xFFFF_FFFF;
                // Branch-free: the hit is rare and unpredictable.
                let hit = 0u8.wrapping_sub(u8::from(u < t));
                let salt = 0u8.wrapping_sub((u & 1) as u8);
                *o = (salt & hit) | (x & !hit);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tables_realise_the_rounded_gaussian_law() {
        for sigma in [0.3, 1.0, 10.0, 30.0, 50.0, 70.0, 200.0] {
            let t = GaussianTable::new(sigma);
            let law = t.sampled_law();
            for k in -254i32..=254 {
                let exact =
                    norm_sf((f64::from(k) - 0.5) / sigma) - norm_sf((f64::from(k) + 0.5) / sigma);
                let got = law[(k + 255) as usize];
                assert!(
                    (got - exact).abs() <= 1e-15 + 1e-12 * exact,
                    "sigma {sigma} k {k}: {got} vs {exact}"
                );
            }
            let tail = norm_sf(254.5 / sigma);
            assert!((law[510] - tail).abs() <= 1e-15 + 1e-12 * tail);
            assert!((law.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn the_guide_agrees_with_the_thresholds() {
        let t = GaussianTable::new(30.0);
        let mut r = WyRand::new(3);
        for _ in 0..100_000 {
            let u = r.next_u64();
            let g = t.guide[(u >> (64 - GUIDE_BITS)) as usize];
            if g != RESOLVE {
                assert_eq!(g, t.magnitude(u));
            }
        }
        assert!(t.resolve_share() < 0.02, "{}", t.resolve_share());
    }

    #[test]
    fn shot_tables_are_poisson() {
        // s = 1: out = N ~ Poisson(x) for x well below 255.
        let t = ShotTable::new(1.0);
        let p = |x: usize, v: usize| {
            let hi = if v < 255 {
                t.thresholds[x][v]
            } else {
                u64::MAX
            };
            let lo = if v == 0 { 0 } else { t.thresholds[x][v - 1] };
            (hi - lo) as f64 / 18_446_744_073_709_551_616.0
        };
        // P(N = 3 | λ = 4) = e^-4 4^3 / 3!
        let want = (-4f64).exp() * 64.0 / 6.0;
        assert!((p(4, 3) - want).abs() < 1e-12);
        assert_eq!(p(0, 0), 1.0);
    }
}
