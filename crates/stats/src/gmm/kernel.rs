//! The EM hot loop: a branch-free vectorisable `exp` and the fused E/M pass over the data.
//!
//! One pass computes, for every point, the weighted log-densities of all components, their
//! log-sum-exp, the responsibilities and the M-step sufficient statistics
//! `Σr`, `Σr·(x−μ_old)`, `Σr·(x−μ_old)²`, storing nothing per point. Points are processed in
//! chunks of [`LANES`] with fixed-size arrays (structure of arrays), so the compiler turns the
//! per-chunk loops into SIMD code; lane accumulators are flushed into `f64` totals every
//! [`BLOCK_CHUNKS`] chunks in a fixed order, so results never depend on threads.
//!
//! On sorted data most chunks see few components: a component more than 40 nats below the best
//! at every point of the chunk is skipped, and one that is the best at every point needs no
//! `exp` (its ratio is exactly 1).

use rayon::prelude::*;

/// The largest number of components the kernel supports.
pub(crate) const KMAX: usize = 16;

/// Points per chunk.
const LANES: usize = 16;

/// Points per parallel piece of a pass over a large sample (a multiple of [`LANES`]).
const PAR_POINTS: usize = 1 << 16;

/// Chunks per block: lane accumulators are flushed into the totals after each block. The
/// product of the per-point normalisers (each in `[1, KMAX]`) over one block stays below
/// `16^64 = 2^256`, far from overflow.
const BLOCK_CHUNKS: usize = 64;

/// Components whose log-density is this far below the best one at every point of a chunk are
/// skipped there: `e^-40 < 4.3e-18`, below the rounding of the normaliser (≥ 1).
const SKIP_BELOW: f64 = -40.0;

/// Log-densities are floored here so a point absurdly far from every component still has a
/// finite log-likelihood (and never NaN).
const LOG_FLOOR: f64 = -1e300;

/// Inputs below this give 0 (the true value is below 3.3e-308).
const EXP_LO: f64 = -708.0;

/// `e^x` for `x ≤ 709` to about 2e-16 relative (see the unit test against `f64::exp`),
/// branch-free so it vectorises. The kernel only needs `x ≤ 0`.
///
/// Range reduction `x = n·ln2 + r`, `|r| ≤ ln2/2` (Cody–Waite split of ln 2, `n` found with the
/// 1.5·2^52 rounding trick), then a degree-11 near-minimax polynomial for `e^r` (Chebyshev fit,
/// truncation error 3e-18, evaluated by Estrin's scheme) and scaling by `2^n` built from the
/// exponent bits. Inputs below −708 return 0; NaN gives NaN; inputs above 709 give garbage.
#[inline(always)]
pub(crate) fn exp_fast(x: f64) -> f64 {
    const LOG2E: f64 = std::f64::consts::LOG2_E;
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    const SHIFTER: f64 = 6_755_399_441_055_744.0; // 1.5 * 2^52
    const C2: f64 = 0.500_000_000_000_001_9;
    const C3: f64 = 0.166_666_666_666_666_8;
    const C4: f64 = 0.041_666_666_666_488_1;
    const C5: f64 = 0.008_333_333_333_319_601;
    const C6: f64 = 0.001_388_888_895_231_477_5;
    const C7: f64 = 0.000_198_412_698_900_471_13;
    const C8: f64 = 2.480_148_548_232_849_4e-5;
    const C9: f64 = 2.755_724_091_857_897e-6;
    const C10: f64 = 2.763_263_963_904_103e-7;
    const C11: f64 = 2.511_003_760_596_377_7e-8;
    let xc = if x < EXP_LO { EXP_LO } else { x };
    let t = xc * LOG2E + SHIFTER;
    let n = t - SHIFTER;
    let r = (xc - n * LN2_HI) - n * LN2_LO;
    // Estrin's scheme: a short dependency chain, so independent lanes overlap.
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let p01 = 1.0 + r;
    let p23 = C2 + C3 * r;
    let p45 = C4 + C5 * r;
    let p67 = C6 + C7 * r;
    let p89 = C8 + C9 * r;
    let p1011 = C10 + C11 * r;
    let p03 = p01 + r2 * p23;
    let p47 = p45 + r2 * p67;
    let p811 = p89 + r2 * p1011;
    let p = (p03 + r4 * p47) + r8 * p811;
    // The low mantissa bits of `t` hold 2^51 + n; adding the bias and shifting puts n + 1023
    // (in [2, 2046] after clamping) into the exponent field.
    let scale = f64::from_bits(t.to_bits().wrapping_add(1023) << 52);
    let y = p * scale;
    if x < EXP_LO { 0.0 } else { y }
}

/// Per-component constants of a mixture: `log p_j(x) = c_j + h_j·(x − μ_j)²` with
/// `c_j = ln w_j − ½ ln(2π σ_j²)` and `h_j = −1 / (2σ_j²)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Model {
    pub k: usize,
    pub mu: [f64; KMAX],
    pub c: [f64; KMAX],
    pub h: [f64; KMAX],
}

impl Model {
    /// Constants of the mixture (`weights`, `means`, `variances` of equal length ≤ [`KMAX`]).
    pub fn new(weights: &[f64], means: &[f64], variances: &[f64]) -> Model {
        let k = means.len().min(KMAX);
        let mut m = Model {
            k,
            mu: [0.0; KMAX],
            c: [0.0; KMAX],
            h: [0.0; KMAX],
        };
        for j in 0..k {
            m.mu[j] = means[j];
            m.c[j] = weights[j].ln() - 0.5 * (std::f64::consts::TAU * variances[j]).ln();
            m.h[j] = -0.5 / variances[j];
        }
        m
    }
}

/// Totals of one pass: the sum of per-point log-likelihoods and, when statistics were asked
/// for, `Σr_j`, `Σr_j·(x−μ_j)` and `Σr_j·(x−μ_j)²` with the model's (old) means `μ_j`.
#[derive(Debug, Clone)]
pub(crate) struct Suff {
    pub ll: f64,
    pub r: [f64; KMAX],
    pub d1: [f64; KMAX],
    pub d2: [f64; KMAX],
}

impl Suff {
    fn zero() -> Suff {
        Suff {
            ll: 0.0,
            r: [0.0; KMAX],
            d1: [0.0; KMAX],
            d2: [0.0; KMAX],
        }
    }
}

struct LaneAcc {
    r: [[f64; LANES]; KMAX],
    d1: [[f64; LANES]; KMAX],
    d2: [[f64; LANES]; KMAX],
    mx: [f64; LANES],
    prod: [f64; LANES],
}

impl LaneAcc {
    fn new() -> LaneAcc {
        LaneAcc {
            r: [[0.0; LANES]; KMAX],
            d1: [[0.0; LANES]; KMAX],
            d2: [[0.0; LANES]; KMAX],
            mx: [0.0; LANES],
            prod: [1.0; LANES],
        }
    }

    fn flush<const STATS: bool>(&self, k: usize, tot: &mut Suff) {
        let mut ll = 0.0;
        for l in 0..LANES {
            ll += self.mx[l] + self.prod[l].ln();
        }
        tot.ll += ll;
        if STATS {
            for j in 0..k {
                tot.r[j] += lane_sum(&self.r[j]);
                tot.d1[j] += lane_sum(&self.d1[j]);
                tot.d2[j] += lane_sum(&self.d2[j]);
            }
        }
    }
}

#[inline(always)]
fn lane_sum(v: &[f64; LANES]) -> f64 {
    v.iter().sum()
}

/// Per-chunk log-densities, then densities, of every component (written before read).
type Scratch = [[f64; LANES]; KMAX];

/// One chunk of [`LANES`] points; `w` is 1 for real points and 0 for padding.
///
/// A component whose log-density is below the chunk's per-point maximum by more than
/// [`SKIP_BELOW`] at every point of the chunk is skipped (responsibility 0 instead of less than
/// 4e-18; the normaliser, at least 1, is unchanged to rounding).
#[inline(always)]
fn chunk<const STATS: bool>(
    m: &Model,
    x: &[f64; LANES],
    w: &[f64; LANES],
    acc: &mut LaneAcc,
    e: &mut Scratch,
) {
    let k = m.k.min(KMAX);
    let mut mx = [f64::NEG_INFINITY; LANES];
    for j in 0..k {
        let (mu, c, h) = (m.mu[j], m.c[j], m.h[j]);
        let ej = &mut e[j];
        for l in 0..LANES {
            let d = x[l] - mu;
            let v = c + h * (d * d);
            let v = if v < LOG_FLOOR { LOG_FLOOR } else { v };
            ej[l] = v;
            mx[l] = if v > mx[l] { v } else { mx[l] };
        }
    }
    // Per component: skipped (negligible at every point), the maximum at every point (density
    // ratio exactly e^0 = 1, no `exp` needed), or general.
    let mut active = [0usize; KMAX];
    let mut is_top = [false; KMAX];
    let mut na = 0;
    for j in 0..k {
        let ej = &e[j];
        let (mut top, mut bot) = (f64::NEG_INFINITY, f64::INFINITY);
        for l in 0..LANES {
            let v = ej[l] - mx[l];
            top = if v > top { v } else { top };
            bot = if v < bot { v } else { bot };
        }
        if top >= SKIP_BELOW {
            active[na] = j;
            is_top[na] = bot >= 0.0;
            na += 1;
        }
    }
    let active = &active[..na];
    let mut s = [0.0f64; LANES];
    for (&j, &one) in active.iter().zip(&is_top) {
        let ej = &mut e[j];
        if one {
            for l in 0..LANES {
                ej[l] = 1.0;
                s[l] += 1.0;
            }
        } else {
            for l in 0..LANES {
                let v = exp_fast(ej[l] - mx[l]);
                ej[l] = v;
                s[l] += v;
            }
        }
    }
    let mut inv = [0.0f64; LANES];
    for l in 0..LANES {
        inv[l] = w[l] / s[l];
        acc.mx[l] += w[l] * mx[l];
        acc.prod[l] *= w[l] * s[l] + (1.0 - w[l]);
    }
    if STATS {
        for &j in active {
            let mu = m.mu[j];
            let (ej, ar, a1, a2) = (&e[j], &mut acc.r[j], &mut acc.d1[j], &mut acc.d2[j]);
            for l in 0..LANES {
                let r = ej[l] * inv[l];
                let d = x[l] - mu;
                let rd = r * d;
                ar[l] += r;
                a1[l] += rd;
                a2[l] += rd * d;
            }
        }
    }
}

/// One pass over `xs`: the summed log-likelihood `Σ_i ln Σ_j w_j N(x_i; μ_j, σ_j²)` and, if
/// `STATS`, the M-step sufficient statistics. Cost `O(n·k)`. Samples of at least
/// `2·PAR_POINTS` points are cut into pieces of [`PAR_POINTS`] processed in parallel (rayon)
/// and summed in order, so the result depends on `n` only, never on the thread count.
pub(crate) fn pass<const STATS: bool>(m: &Model, xs: &[f64]) -> Suff {
    if xs.len() < 2 * PAR_POINTS {
        return pass_seq::<STATS>(m, xs);
    }
    let parts: Vec<Suff> = xs
        .par_chunks(PAR_POINTS)
        .map(|p| pass_seq::<STATS>(m, p))
        .collect();
    let mut tot = Suff::zero();
    for p in &parts {
        tot.ll += p.ll;
        for j in 0..m.k.min(KMAX) {
            tot.r[j] += p.r[j];
            tot.d1[j] += p.d1[j];
            tot.d2[j] += p.d2[j];
        }
    }
    tot
}

fn pass_seq<const STATS: bool>(m: &Model, xs: &[f64]) -> Suff {
    let mut tot = Suff::zero();
    let (chunks, tail) = xs.as_chunks::<LANES>();
    const ONES: [f64; LANES] = [1.0; LANES];
    let mut e: Scratch = [[0.0; LANES]; KMAX];
    for block in chunks.chunks(BLOCK_CHUNKS) {
        let mut acc = LaneAcc::new();
        for x in block {
            chunk::<STATS>(m, x, &ONES, &mut acc, &mut e);
        }
        acc.flush::<STATS>(m.k, &mut tot);
    }
    if let Some(&first) = tail.first() {
        let mut x = [first; LANES];
        let mut w = [0.0; LANES];
        for (i, &v) in tail.iter().enumerate() {
            x[i] = v;
            w[i] = 1.0;
        }
        let mut acc = LaneAcc::new();
        chunk::<STATS>(m, &x, &w, &mut acc, &mut e);
        acc.flush::<STATS>(m.k, &mut tot);
    }
    tot
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_fast_matches_std_exp() {
        let mut worst = 0.0f64;
        let mut x = -708.0;
        while x <= 709.0 {
            let (a, b) = (exp_fast(x), x.exp());
            worst = worst.max(((a - b) / b).abs());
            x += 0.000_731_3;
        }
        for i in 0..200_000 {
            let x = -1.0 + i as f64 * 1e-5;
            let (a, b) = (exp_fast(x), x.exp());
            worst = worst.max(((a - b) / b).abs());
        }
        assert!(worst < 5e-16, "worst relative error {worst:e}");
        assert_eq!(exp_fast(0.0), 1.0);
        assert_eq!(exp_fast(-709.0), 0.0);
        assert_eq!(exp_fast(f64::NEG_INFINITY), 0.0);
        assert!(exp_fast(f64::NAN).is_nan());
    }

    #[test]
    fn pass_matches_direct_computation() {
        let xs: Vec<f64> = (0..1003)
            .map(|i| ((i * 37) % 101) as f64 * 0.1 - 2.0)
            .collect();
        let (w, mu, var) = ([0.2, 0.5, 0.3], [-1.0, 1.5, 4.0], [0.5, 1.2, 2.0]);
        let m = Model::new(&w, &mu, &var);
        let s = pass::<true>(&m, &xs);
        let (mut ll, mut r, mut d1, mut d2) = (0.0, [0.0; 3], [0.0; 3], [0.0; 3]);
        for &x in &xs {
            let p: Vec<f64> = (0..3)
                .map(|j| {
                    w[j] * (-(x - mu[j]) * (x - mu[j]) / (2.0 * var[j])).exp()
                        / (std::f64::consts::TAU * var[j]).sqrt()
                })
                .collect();
            let tot: f64 = p.iter().sum();
            ll += tot.ln();
            for j in 0..3 {
                r[j] += p[j] / tot;
                d1[j] += p[j] / tot * (x - mu[j]);
                d2[j] += p[j] / tot * (x - mu[j]) * (x - mu[j]);
            }
        }
        assert!((s.ll - ll).abs() < 1e-9 * ll.abs());
        for j in 0..3 {
            assert!((s.r[j] - r[j]).abs() < 1e-9 * r[j]);
            assert!((s.d1[j] - d1[j]).abs() < 1e-9 * (1.0 + d1[j].abs()));
            assert!((s.d2[j] - d2[j]).abs() < 1e-9 * d2[j]);
        }
        let s0 = pass::<false>(&m, &xs);
        assert_eq!(s0.ll, s.ll);
    }
}
