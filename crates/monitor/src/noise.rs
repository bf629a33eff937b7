//! Blind estimates of additive Gaussian noise: the fast one the planner uses and the
//! precise one corrected for clipping.

use crate::{MonitorError, TARGET_SAMPLES, check, normal_cdf, normal_pdf};

/// A blind estimate of additive, pixel-independent noise.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct NoiseEstimate {
    /// Standard deviation of the noise per channel, 0–255 scale.
    pub sigma: f64,
    /// Standard error of `sigma` from the sampling of the residuals (the spread the estimate
    /// would have over frames of the same scene with fresh noise); it does not include the
    /// upward bias of texture and edges, which dominates below σ ≈ 2.
    pub sigma_se: f64,
    /// Residuals the estimate is made of.
    pub samples: usize,
    /// Share of the sampled neighbourhoods left out because a value in them sat at 0 or 255
    /// (there the noise is censored and would read low).
    pub clipped_share: f64,
}

/// The Laplacian-difference mask `[[1,−2,1],[−2,4,−2],[1,−2,1]]` has a squared norm of 36.
const MASK_NORM: f64 = 6.0;
/// The median of |z| for a standard normal z.
const MEDIAN_ABS_NORMAL: f64 = 0.674_489_750_196_081_7;

/// Estimates the standard deviation of additive Gaussian-like noise in an RGB8 frame.
///
/// Every sampled pixel's 3×3 neighbourhood is convolved, per channel, with Immerkær's
/// Laplacian-difference mask, which cancels any locally planar signal; for independent noise
/// of standard deviation σ the residual has standard deviation 6σ. The estimate is the
/// median absolute residual over 6 · 0.6745 — the median, not the mean, so that the edges
/// of a scene (a minority of neighbourhoods) do not inflate it. Neighbourhoods holding a
/// 0 or a 255 are left out: clipping censors the noise there. Where most of a frame clips
/// (strong noise on a dark or bright scene) the remaining neighbourhoods are the ones the
/// noise happened to keep in range, so the estimate reads somewhat low at very high σ.
///
/// Pixels are sampled on a regular grid of about 4,000 points; the result depends on the
/// pixels only.
pub fn estimate_noise(
    rgb: &[u8],
    width: usize,
    height: usize,
) -> Result<NoiseEstimate, MonitorError> {
    check(rgb, width, height)?;
    let inner = (width - 2) * (height - 2);
    let step = ((inner as f64 / TARGET_SAMPLES as f64).sqrt().floor() as usize).max(1);
    // |residual| ≤ 16 · 255; a histogram gives the exact median without sorting.
    let mut hist = vec![0u32; 16 * 255 + 1];
    let (mut n, mut clipped, mut seen) = (0usize, 0usize, 0usize);
    let stride = width * 3;
    let mut y = 1;
    while y + 1 < height {
        let mut x = 1 + (y / step) % step; // staggered rows: no aliasing with vertical stripes
        while x + 1 < width {
            seen += 1;
            let c = y * stride + x * 3;
            // The 3 × 3 neighbourhood's rows, 9 bytes each (three RGB pixels).
            let (a, m, d) = (
                &rgb[c - stride - 3..c - stride + 6],
                &rgb[c - 3..c + 6],
                &rgb[c + stride - 3..c + stride + 6],
            );
            // 0 and 255 are the bytes that wrap to 255 and 254 less one (no early exit:
            // the 27 comparisons are vectorised).
            let extreme = |row: &[u8]| {
                row.iter()
                    .fold(false, |e, &q| e | (q.wrapping_sub(1) >= 254))
            };
            if extreme(a) | extreme(m) | extreme(d) {
                clipped += 1;
            } else {
                for ch in 0..3 {
                    let v = |row: &[u8], k: usize| i32::from(row[k * 3 + ch]);
                    let r = v(a, 0) - 2 * v(a, 1) + v(a, 2) - 2 * v(m, 0) + 4 * v(m, 1)
                        - 2 * v(m, 2)
                        + v(d, 0)
                        - 2 * v(d, 1)
                        + v(d, 2);
                    hist[r.unsigned_abs() as usize] += 1;
                    n += 1;
                }
            }
            x += step;
        }
        y += step;
    }
    let clipped_share = if seen > 0 {
        clipped as f64 / seen as f64
    } else {
        0.0
    };
    if n == 0 {
        return Ok(NoiseEstimate {
            sigma: 0.0,
            sigma_se: 0.0,
            samples: 0,
            clipped_share,
        });
    }
    let sigma = median_of_histogram(&hist, n) / (MASK_NORM * MEDIAN_ABS_NORMAL);
    // The median of |z| has standard error ½ / (2φ(0.6745) · √n) for a normal z.
    let density = 2.0 * normal_pdf(MEDIAN_ABS_NORMAL);
    Ok(NoiseEstimate {
        sigma,
        sigma_se: sigma * 0.5 / (density * MEDIAN_ABS_NORMAL * (n as f64).sqrt()),
        samples: n,
        clipped_share,
    })
}

/// The median of the values a histogram counts (the mean of the two middle ones for an even
/// count).
fn median_of_histogram(hist: &[u32], n: usize) -> f64 {
    let value_at = |rank: usize| -> f64 {
        let mut acc = 0usize;
        for (v, &c) in hist.iter().enumerate() {
            acc += c as usize;
            if acc > rank {
                return v as f64;
            }
        }
        (hist.len() - 1) as f64
    };
    if n % 2 == 1 {
        value_at(n / 2)
    } else {
        0.5 * (value_at(n / 2 - 1) + value_at(n / 2))
    }
}

/// The share of residuals [`estimate_noise_precise`] fits its model to.
const SHARE: f64 = 0.7;
/// The 0.7 quantile of |z| for a standard normal z (Φ⁻¹(0.85)).
const QUANTILE_ABS_NORMAL: f64 = 1.036_433_389_493_79;
/// Tiles (3×3 pixels) [`estimate_noise_precise`] samples.
const TILES: usize = 40_000;
/// Tiles on each side of a tile that give its level.
const LEVEL_TILES: usize = 3;
/// Level bins of [`estimate_noise_precise`], 4 levels each.
const LEVEL_BINS: usize = 64;
/// Residuals are counted up to this absolute value (larger ones are edges: the 0.7
/// quantile of the two-dimensional residual of noise σ = 80 is 6 · 1.036 · 80 ≈ 497).
const RESIDUAL_BINS: usize = 512;
/// Immerkær's mask `[[1,−2,1],[−2,4,−2],[1,−2,1]]`: √Σw² (the residual of independent
/// noise σ has standard deviation 6σ).
const MASK_NORM_2D: f64 = 6.0;
/// Σw³ / (Σw²)^{3/2}: the residual's skewness over one sample's.
const MASK_SKEW: f64 = 36.0 / 216.0;
/// Σw⁴ / (Σw²)²: the residual's excess kurtosis over one sample's.
const MASK_KURTOSIS: f64 = 324.0 / 1296.0;
/// Pixels the mask reads (all must be unclipped for a residual to be kept).
const MASK_PIXELS: i32 = 9;

/// Residuals binned by the level around them.
struct Binned {
    /// `LEVEL_BINS × RESIDUAL_BINS` counts of |residual| (the last column: that or more).
    hist: Vec<u32>,
    /// Residuals counted.
    n: usize,
    /// Residuals formed, kept or not.
    seen: usize,
    /// Pixels the level of a residual is the mean of.
    level_px: f64,
}

/// Samples about `tiles_wanted` tiles of 3×3 pixels in whole bands of three rows spread
/// evenly down the frame, and bins each tile's residual per channel by the mean of the
/// `LEVEL_TILES` tiles on each side (pixels independent of the residual's own, clipped ones
/// included). Every pass over a band runs over contiguous samples (vectorised); only the
/// binning reads one sample in nine.
fn sample(rgb: &[u8], width: usize, height: usize, tiles_wanted: usize) -> Binned {
    let tiles = width / 3;
    let bands = height / 3;
    let stride = width * 3;
    let used = (tiles_wanted / tiles.max(1)).clamp(1, bands);
    let k = LEVEL_TILES.min(tiles.saturating_sub(1) / 2);
    let level_px = 2 * k * 9;
    let mut hist = vec![0u32; LEVEL_BINS * RESIDUAL_BINS];
    let (mut n, mut seen) = (0usize, 0usize);
    if k == 0 {
        return Binned {
            hist,
            n,
            seen,
            level_px: 1.0,
        };
    }
    let to_bin = 1.0 / (level_px as f32 * 4.0);
    let len = tiles * 9;
    let w = len - 6;
    // Per band, per sample of its rows (tile t, channel c at 9t + c): the column sums of the
    // band, then their sums over three pixels (tile sums); the residuals and their
    // clipped flags.
    let mut col = vec![0u16; len];
    let mut tile_sum = vec![0u16; w];
    let mut res = vec![0i16; w];
    let mut flag = vec![0u8; w];
    let (mut vd, mut vf) = (vec![0i16; len], vec![0u8; len]);
    // 0 and 255 are the bytes that wrap to 255 and 254 less one.
    let ext = |q: u8| u8::from(q.wrapping_sub(1) >= 254);
    for i in 0..used {
        let y = (2 * i + 1) * bands / (2 * used) * 3;
        let row = |r: usize| &rgb[(y + r) * stride..(y + r) * stride + len];
        let (a, m, d) = (row(0), row(1), row(2));
        for (i, o) in col.iter_mut().enumerate() {
            *o = u16::from(a[i]) + u16::from(m[i]) + u16::from(d[i]);
        }
        let (c0, c3, c6) = (&col[..w], &col[3..3 + w], &col[6..6 + w]);
        for (i, s) in tile_sum.iter_mut().enumerate() {
            *s = c0[i] + c3[i] + c6[i];
        }
        // The vertical second difference, then its horizontal one (the residual).
        for (i, o) in vd.iter_mut().enumerate() {
            *o = i16::from(a[i]) - 2 * i16::from(m[i]) + i16::from(d[i]);
        }
        for (i, f) in vf.iter_mut().enumerate() {
            *f = ext(a[i]) | ext(m[i]) | ext(d[i]);
        }
        let (v0, v3, v6) = (&vd[..w], &vd[3..3 + w], &vd[6..6 + w]);
        for (i, o) in res.iter_mut().enumerate() {
            *o = v0[i] - 2 * v3[i] + v6[i];
        }
        let (f0, f3, f6) = (&vf[..w], &vf[3..3 + w], &vf[6..6 + w]);
        for (i, f) in flag.iter_mut().enumerate() {
            *f = f0[i] | f3[i] | f6[i];
        }
        for c in 0..3 {
            let at = |t: usize| 9 * t + c;
            // The sum of the 2k + 1 tiles centred on tile t.
            let mut window: u32 = (0..=2 * k).map(|u| u32::from(tile_sum[at(u)])).sum();
            for t in k..tiles - k {
                if t > k {
                    window += u32::from(tile_sum[at(t + k)]);
                    window -= u32::from(tile_sum[at(t - k - 1)]);
                }
                if flag[at(t)] != 0 {
                    continue;
                }
                let around = (window - u32::from(tile_sum[at(t)])) as f32;
                let bin = ((around * to_bin) as usize).min(LEVEL_BINS - 1);
                let r = usize::from(res[at(t)].unsigned_abs());
                hist[bin * RESIDUAL_BINS + r.min(RESIDUAL_BINS - 1)] += 1;
            }
            seen += tiles - 2 * k;
        }
    }
    n += hist.iter().map(|&c| c as usize).sum::<usize>();
    Binned {
        hist,
        n,
        seen,
        level_px: level_px as f64,
    }
}

/// Estimates additive Gaussian noise like [`estimate_noise`], correcting for the clipping
/// at 0 and 255 that makes that one read low at high σ (mean absolute error ≤ 0.8 on
/// photographs and world frames from σ 5 to 70; docs/monitor.md), at about 15 times its
/// cost (≈ 0.8–1.5 ms a 1080p frame on one core).
///
/// **Residuals.** Tiles of 3×3 pixels are taken side by side in bands of three rows spread
/// evenly down the frame (about 40,000 tiles). Each channel of a tile gives Immerkær's
/// residual `[[1,−2,1],[−2,4,−2],[1,−2,1]]`, which cancels locally planar signal; a tile
/// holding a 0 or a 255 in that channel is left out. Every pass over a band reads
/// contiguous samples (the compiler vectorises it); only the binning reads one in nine.
///
/// **Clipping.** A kept residual is one whose nine pixels all stayed in range: given the
/// true level `J`, each is `J + K` with `K` a normal *truncated* to `[0.5 − J, 254.5 − J]`,
/// of standard deviation `σ · ρ(σ, J)`, `ρ² = 1 + (αφ(α) − βφ(β))/Z − ((φ(α) − φ(β))/Z)²`,
/// `α = (0.5 − J)/σ`, `β = (254.5 − J)/σ`, `Z = Φ(β) − Φ(α)`; the quantile of the
/// residual's magnitude is moved for the truncated shape (Edgeworth, from the sample's
/// skewness and kurtosis times the mask's weight factors). `J` is read from the three tiles
/// on each side (54 pixels, clipped ones included, independent of the residual's own):
/// their mean is the censored mean `g(J)` of [`Censoring`](crate::Censoring), inverted for
/// the σ being tried. That reading has an error (≈ σ/√54), so ρ is averaged over it
/// (three-point Gauss–Hermite), each point weighted by `Z(J)⁹`, the chance that all nine
/// pixels stay in range: residuals are kept more often where less of their noise clips,
/// which tilts the true levels behind a bin toward the middle of the range (without that
/// weight the estimate read ≈ +0.5 high at σ 70). Residuals are binned by the level (4
/// levels a bin); σ is the value at which 70 % of them lie within
/// `6 · 1.0364 · σ · ρ(σ, J_bin)` (bisection; counts interpolated between integer
/// residuals). The 0.7 quantile rather than the median: its scale estimate has about 1.5
/// times less variance for normal residuals, and the few edges of a frame still lie above
/// it.
///
/// `sigma_se` is the sampling standard error, from the binomial spread of the count within
/// the thresholds and the slope of that count in σ. Edges and texture bias the estimate
/// upward (≈ 0.3 on photographs at σ 0); the result depends on the pixels only.
pub fn estimate_noise_precise(
    rgb: &[u8],
    width: usize,
    height: usize,
) -> Result<NoiseEstimate, MonitorError> {
    check(rgb, width, height)?;
    let b = sample(rgb, width, height, TILES);
    let clipped_share = if b.seen > 0 {
        1.0 - b.n as f64 / b.seen as f64
    } else {
        0.0
    };
    let (sigma, sigma_se) = fit(&b);
    Ok(NoiseEstimate {
        sigma,
        sigma_se,
        samples: b.n,
        clipped_share,
    })
}

/// The σ at which [`SHARE`] of the binned residuals lie within their bins' thresholds, and
/// its standard error; (0, 0) when there are no residuals or most are zero.
fn fit(b: &Binned) -> (f64, f64) {
    let n = b.n;
    if n == 0 {
        return (0.0, 0.0);
    }
    // Per bin: how many residuals lie at or below each value (prefix sums).
    let mut cum = b.hist.clone();
    let mut counts = [0u32; LEVEL_BINS];
    for (row, count) in cum.chunks_exact_mut(RESIDUAL_BINS).zip(counts.iter_mut()) {
        let mut acc = 0u32;
        for c in row.iter_mut() {
            acc += *c;
            *c = acc;
        }
        *count = acc;
    }
    // Half the residuals zero: no noise to speak of (a flat or synthetic frame).
    let zeros: f64 = cum
        .chunks_exact(RESIDUAL_BINS)
        .map(|row| f64::from(row[0]))
        .sum();
    if zeros >= n as f64 / 2.0 {
        return (0.0, 0.0);
    }
    // Residuals within `t`: an integer residual k ≥ 1 spread evenly over [k − ½, k + ½],
    // a zero over [0, ½].
    let below = |row: &[u32], t: f64| -> f64 {
        if t <= 0.0 {
            return 0.0;
        }
        if t < 0.5 {
            return f64::from(row[0]) * 2.0 * t;
        }
        let k = (t + 0.5).floor() as usize;
        if k >= RESIDUAL_BINS {
            return f64::from(row[RESIDUAL_BINS - 1]);
        }
        let lo = f64::from(row[k - 1]);
        lo + (f64::from(row[k]) - lo) * (t + 0.5 - k as f64)
    };
    let target = n as f64 * SHARE;
    let within = |sigma: f64| -> f64 {
        let rho = truncation_ratios(sigma, b.level_px);
        let scale = MASK_NORM_2D * QUANTILE_ABS_NORMAL * sigma;
        cum.chunks_exact(RESIDUAL_BINS)
            .zip(rho.iter().zip(&counts))
            .filter(|(_, (_, c))| **c > 0)
            .map(|(row, (r, _))| below(row, scale * r))
            .sum::<f64>()
    };
    // The plain quantile (ρ = 1) brackets σ closely; widen the bracket if it does not, then
    // bisect (the share within the threshold grows with σ).
    let mut total = [0f64; RESIDUAL_BINS];
    for row in cum.chunks_exact(RESIDUAL_BINS) {
        for (t, &c) in total.iter_mut().zip(row) {
            *t += f64::from(c);
        }
    }
    let q = total
        .iter()
        .position(|&c| c >= target)
        .unwrap_or(RESIDUAL_BINS - 1);
    let plain = (q as f64).max(0.5) / (MASK_NORM_2D * QUANTILE_ABS_NORMAL);
    let (mut lo, mut hi) = (0.8 * plain, 1.6 * plain + 1.0);
    while within(lo) > target && lo > 1e-3 {
        lo *= 0.5;
    }
    while within(hi) < target && hi < 1e4 {
        hi *= 2.0;
    }
    for _ in 0..16 {
        let mid = 0.5 * (lo + hi);
        if within(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let sigma = 0.5 * (lo + hi);
    // The count within has binomial spread √(n p (1 − p)); its slope in σ turns that into σ.
    let h = 0.02 * sigma + 0.01;
    let slope = (within(sigma + h) - within(sigma - h)) / (2.0 * h);
    let se = if slope > 0.0 {
        (n as f64 * SHARE * (1.0 - SHARE)).sqrt() / slope
    } else {
        sigma
    };
    (sigma, se)
}

/// For noise `sigma` and each level bin: the ratio ρ of the spread of the kept residuals to
/// that of unclipped noise, at the true levels whose censored mean `g(J)` is the bin's
/// centre (read from `level_px` pixels).
fn truncation_ratios(sigma: f64, level_px: f64) -> [f64; LEVEL_BINS] {
    let mut rho = [1.0; LEVEL_BINS];
    if sigma < 0.5 {
        return rho;
    }
    // (censored mean, effective ρ, Z) on a grid of true levels; the censored mean increases
    // with J. The effective ρ also moves the quantile of |residual| for the truncated shape
    // (Edgeworth: the residual's excess kurtosis and skewness are the sample's times the
    // mask's factors).
    const GRID: usize = 64;
    let (j0, j1) = (-1.5 * sigma, 255.0 + 1.5 * sigma);
    let dj = (j1 - j0) / GRID as f64;
    let q = QUANTILE_ABS_NORMAL;
    let (he3, he5) = (q.powi(3) - 3.0 * q, q.powi(5) - 10.0 * q.powi(3) + 15.0 * q);
    let table: Vec<(f64, f64, f64)> = (0..=GRID)
        .map(|i| {
            let j = j0 + dj * i as f64;
            let (al, be) = ((0.5 - j) / sigma, (254.5 - j) / sigma);
            let (ca, cb) = (normal_cdf(al), normal_cdf(be));
            let z = (cb - ca).max(1e-12);
            let (pa, pb) = (normal_pdf(al), normal_pdf(be));
            let m1 = (pa - pb) / z;
            let m2 = 1.0 + (al * pa - be * pb) / z;
            let m3 = 2.0 * m1 + (al * al * pa - be * be * pb) / z;
            let m4 = 3.0 * m2 + (al.powi(3) * pa - be.powi(3) * pb) / z;
            let var = (m2 - m1 * m1).max(1e-6);
            let mu3 = m3 - 3.0 * m1 * m2 + 2.0 * m1.powi(3);
            let mu4 = m4 - 4.0 * m1 * m3 + 6.0 * m1 * m1 * m2 - 3.0 * m1.powi(4);
            let gamma = mu3 / (var * var.sqrt()) * MASK_SKEW;
            let kappa = (mu4 / (var * var) - 3.0) * MASK_KURTOSIS;
            let shifted = q + kappa / 24.0 * he3 + gamma * gamma / 72.0 * he5;
            // E[clip(J + K)]: 0 below, 255 above, the truncated mean between.
            let censored = 255.0 * (1.0 - cb) + z * (j + sigma * m1);
            (censored, var.sqrt() * shifted / q, z)
        })
        .collect();
    // (ρ, chance that the mask's pixels all stay in range) at a true level.
    let at = |j: f64| -> (f64, f64) {
        let u = ((j - j0) / dj).clamp(0.0, GRID as f64 - 1e-9);
        let i = u.floor() as usize;
        let f = u - i as f64;
        let r = table[i].1 + f * (table[i + 1].1 - table[i].1);
        let z = table[i].2 + f * (table[i + 1].2 - table[i].2);
        (r, z.powi(MASK_PIXELS))
    };
    // The level is read from `level_px` noisy pixels: average ρ over its error (three-point
    // Gauss–Hermite, ±√3 standard errors), weighted by the chance of being kept.
    let err = sigma / level_px.sqrt() * 3f64.sqrt();
    let mut k = 0;
    for (b, r) in rho.iter_mut().enumerate() {
        let centre = 4.0 * b as f64 + 2.0;
        while k + 2 < table.len() && table[k + 1].0 < centre {
            k += 1;
        }
        let (m0, m1) = (table[k].0, table[k + 1].0);
        let f = if m1 > m0 {
            ((centre - m0) / (m1 - m0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let j = j0 + dj * (k as f64 + f);
        let pts = [(4.0, at(j)), (1.0, at(j - err)), (1.0, at(j + err))];
        let (num, den) = pts
            .iter()
            .fold((0.0, 0.0), |(a, b), (w, (r, z))| (a + w * z * r, b + w * z));
        *r = if den > 0.0 { num / den } else { at(j).0 };
    }
    rho
}
