//! Blind estimates of how degraded a camera frame is, from its pixels alone.
//!
//! Nothing here knows the scene or the condition that was applied: a perception stack uses
//! these figures to size its pooling and to lower its confidence, and the runtime ODD
//! monitor compares them with the envelope's thresholds.
//!
//! - [`estimate_noise`]: the standard deviation of additive noise on the 0–255 scale
//!   (Immerkær's Laplacian-difference residual, taken robustly through its median).
//! - [`estimate_noise_precise`]: the same, corrected for the clipping at 0 and 255 that
//!   makes it read low at high σ, on a denser sample (about 30 times the cost).
//! - [`exposure`]: the frame's white level and mean luminance, the photometric scale that
//!   colour tests are made relative to.
//! - [`Censoring`]: the true level behind a mean of noisy pixels clipped at 0 and 255.
//!
//! ```
//! // A flat grey frame has no noise and a white level of its grey.
//! let rgb = vec![120u8; 64 * 48 * 3];
//! let n = fogline_monitor::estimate_noise(&rgb, 64, 48)?;
//! assert_eq!(n.sigma, 0.0);
//! assert_eq!(fogline_monitor::estimate_noise_precise(&rgb, 64, 48)?.sigma, 0.0);
//! let e = fogline_monitor::exposure(&rgb, 64, 48)?;
//! assert_eq!(e.white, 120.0);
//! # Ok::<(), fogline_monitor::MonitorError>(())
//! ```

/// Why a frame could not be measured.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MonitorError {
    /// The buffer does not hold `width × height` RGB8 pixels.
    #[error("frame of {width}x{height} needs {expected} bytes (RGB8), got {got}")]
    Size {
        /// Width, px.
        width: usize,
        /// Height, px.
        height: usize,
        /// `width × height × 3`.
        expected: usize,
        /// The buffer's length.
        got: usize,
    },
    /// Smaller than 3×3 pixels: no residual can be formed.
    #[error("frame of {width}x{height} is too small (at least 3x3 pixels)")]
    TooSmall {
        /// Width, px.
        width: usize,
        /// Height, px.
        height: usize,
    },
}

fn check(rgb: &[u8], width: usize, height: usize) -> Result<(), MonitorError> {
    let expected = width * height * 3;
    if rgb.len() != expected {
        return Err(MonitorError::Size {
            width,
            height,
            expected,
            got: rgb.len(),
        });
    }
    if width < 3 || height < 3 {
        return Err(MonitorError::TooSmall { width, height });
    }
    Ok(())
}

/// A blind estimate of additive, pixel-independent noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseEstimate {
    /// Standard deviation of the noise per channel, 0–255 scale.
    pub sigma: f64,
    /// Residuals the estimate is the median of.
    pub samples: usize,
    /// Share of the sampled neighbourhoods left out because a value in them sat at 0 or 255
    /// (there the noise is censored and would read low).
    pub clipped_share: f64,
}

/// The Laplacian-difference mask `[[1,−2,1],[−2,4,−2],[1,−2,1]]` has a squared norm of 36.
const MASK_NORM: f64 = 6.0;
/// The median of |z| for a standard normal z.
const MEDIAN_ABS_NORMAL: f64 = 0.674_489_750_196_081_7;
/// About this many pixels are sampled per frame (a regular grid).
const TARGET_SAMPLES: usize = 4_000;

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
            samples: 0,
            clipped_share,
        });
    }
    let sigma = median_of_histogram(&hist, n) / (MASK_NORM * MEDIAN_ABS_NORMAL);
    Ok(NoiseEstimate {
        sigma,
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

/// [`estimate_noise_precise`] samples a regular grid of about this many pixels.
const PRECISE_SAMPLES: usize = 40_000;
/// Level bins of [`estimate_noise_precise`], 4 levels each.
const LEVEL_BINS: usize = 64;
/// Residuals are counted up to this absolute value (larger ones are edges: the median of
/// noise of σ ≤ 120 lies below 6 · 0.6745 · 120 ≈ 486).
const RESIDUAL_BINS: usize = 512;
/// Marks a sampled neighbourhood that holds a 0 or a 255.
const CLIPPED: i16 = i16::MIN;

/// Estimates additive Gaussian noise like [`estimate_noise`], correcting for the clipping
/// at 0 and 255 that makes that one read low at high σ (mean absolute error ≈ 1 at σ = 70
/// on photographs, ≤ 0.2 up to σ = 50), at about 30 times the cost (≈ 1.5–1.7 ms a 1080p
/// frame on one core; docs/monitor.md).
///
/// The residual is the same (Immerkær's mask on each channel's 3×3 neighbourhood) on a
/// regular grid of about 40,000 pixels, each channel apart, without the neighbourhoods that
/// hold a 0 or a 255. Those kept are neighbourhoods where the noise happened to stay in
/// range: given the true level `J`, each of their samples is `J + K` with `K` a normal
/// *truncated* to `[0.5 − J, 254.5 − J]`, of standard deviation `σ · ρ(σ, J)`,
/// `ρ² = 1 + (αφ(α) − βφ(β))/Z − ((φ(α) − φ(β))/Z)²`, `α = (0.5 − J)/σ`,
/// `β = (254.5 − J)/σ`, `Z = Φ(β) − Φ(α)`. `J` is read from the eight neighbouring grid
/// points' neighbourhoods (72 pixels, clipped ones included, so independent of the residual's
/// own noise): their mean is the censored mean `g(J)` of [`Censoring`], inverted for the
/// σ being tried. Residuals are binned by that mean (4 levels a bin); σ is the value at
/// which half of all residuals lie within `6 · 0.6745 · σ · ρ(σ, J_bin)` (bisection; counts
/// interpolated between integer residuals). Without clipping `ρ = 1` and this is the median
/// of [`estimate_noise`] on a denser sample.
///
/// Edges bias it upward as they do [`estimate_noise`]; the result depends on the pixels only.
pub fn estimate_noise_precise(
    rgb: &[u8],
    width: usize,
    height: usize,
) -> Result<NoiseEstimate, MonitorError> {
    check(rgb, width, height)?;
    let inner = (width - 2) * (height - 2);
    let step = ((inner as f64 / PRECISE_SAMPLES as f64).sqrt().floor() as usize).max(3);
    let (nx, ny) = ((width - 2).div_ceil(step), (height - 2).div_ceil(step));
    // Pass 1: per grid point and channel, the neighbourhood's sum and residual.
    let mut sums = vec![[0u16; 3]; nx * ny];
    let mut res = vec![[CLIPPED; 3]; nx * ny];
    let stride = width * 3;
    for gy in 0..ny {
        let y = 1 + gy * step;
        for gx in 0..nx {
            let c = y * stride + (1 + gx * step) * 3;
            let (a, m, d) = (
                &rgb[c - stride - 3..c - stride + 6],
                &rgb[c - 3..c + 6],
                &rgb[c + stride - 3..c + stride + 6],
            );
            let (s, r) = (&mut sums[gy * nx + gx], &mut res[gy * nx + gx]);
            for ch in 0..3 {
                let q = [
                    a[ch],
                    a[ch + 3],
                    a[ch + 6],
                    m[ch],
                    m[ch + 3],
                    m[ch + 6],
                    d[ch],
                    d[ch + 3],
                    d[ch + 6],
                ];
                let i = q.map(i32::from);
                s[ch] = i.iter().sum::<i32>() as u16;
                if !q.iter().fold(false, |e, &p| e | (p.wrapping_sub(1) >= 254)) {
                    r[ch] = (i[0] - 2 * i[1] + i[2] - 2 * i[3] + 4 * i[4] - 2 * i[5] + i[6]
                        - 2 * i[7]
                        + i[8]) as i16;
                }
            }
        }
    }
    // Pass 2: the kept residuals binned by their eight neighbours' mean level.
    let mut hist = vec![0u32; LEVEL_BINS * RESIDUAL_BINS];
    let (mut n, mut seen) = (0usize, 0usize);
    for gy in 1..ny.saturating_sub(1) {
        for gx in 1..nx.saturating_sub(1) {
            let at = gy * nx + gx;
            for ch in 0..3 {
                seen += 1;
                let r = res[at][ch];
                if r == CLIPPED {
                    continue;
                }
                let around: u32 = [
                    at - nx - 1,
                    at - nx,
                    at - nx + 1,
                    at - 1,
                    at + 1,
                    at + nx - 1,
                    at + nx,
                    at + nx + 1,
                ]
                .iter()
                .map(|&k| u32::from(sums[k][ch]))
                .sum();
                let bin = ((around / (72 * 4)) as usize).min(LEVEL_BINS - 1);
                hist[bin * RESIDUAL_BINS + (r.unsigned_abs() as usize).min(RESIDUAL_BINS - 1)] += 1;
                n += 1;
            }
        }
    }
    let clipped_share = if seen > 0 {
        1.0 - n as f64 / seen as f64
    } else {
        0.0
    };
    if n == 0 {
        return Ok(NoiseEstimate {
            sigma: 0.0,
            samples: 0,
            clipped_share,
        });
    }
    // Per bin: how many residuals lie at or below each value (prefix sums).
    let mut counts = vec![0u32; LEVEL_BINS];
    for (b, row) in hist.chunks_exact_mut(RESIDUAL_BINS).enumerate() {
        let mut acc = 0u32;
        for c in row.iter_mut() {
            acc += *c;
            *c = acc;
        }
        counts[b] = acc;
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
    let half = n as f64 / 2.0;
    let share_within = |sigma: f64| -> f64 {
        let rho = truncation_ratios(sigma);
        let scale = MASK_NORM * MEDIAN_ABS_NORMAL * sigma;
        hist.chunks_exact(RESIDUAL_BINS)
            .enumerate()
            .filter(|(b, _)| counts[*b] > 0)
            .map(|(b, row)| below(row, scale * rho[b]))
            .sum::<f64>()
    };
    // Half the residuals zero: no noise to speak of (a flat or synthetic frame).
    if hist
        .chunks_exact(RESIDUAL_BINS)
        .map(|row| f64::from(row[0]))
        .sum::<f64>()
        >= half
    {
        return Ok(NoiseEstimate {
            sigma: 0.0,
            samples: n,
            clipped_share,
        });
    }
    // The plain median (ρ = 1) brackets σ closely; widen the bracket if it does not, then
    // bisect (the share within the threshold grows with σ).
    let mut total = vec![0f64; RESIDUAL_BINS];
    for row in hist.chunks_exact(RESIDUAL_BINS) {
        for (t, &c) in total.iter_mut().zip(row) {
            *t += f64::from(c);
        }
    }
    let median = total
        .iter()
        .position(|&c| c >= half)
        .unwrap_or(RESIDUAL_BINS - 1);
    let plain = (median as f64).max(0.5) / (MASK_NORM * MEDIAN_ABS_NORMAL);
    let (mut lo, mut hi) = (0.8 * plain, 1.6 * plain + 1.0);
    while share_within(lo) > half && lo > 1e-3 {
        lo *= 0.5;
    }
    while share_within(hi) < half && hi < 1e4 {
        hi *= 2.0;
    }
    for _ in 0..24 {
        let mid = 0.5 * (lo + hi);
        if share_within(mid) < half {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(NoiseEstimate {
        sigma: 0.5 * (lo + hi),
        samples: n,
        clipped_share,
    })
}

/// For noise `sigma` and each level bin of [`estimate_noise_precise`]: the ratio ρ of the
/// standard deviation of a sample kept in [0.5, 254.5] to σ, at the true level whose censored
/// mean `g(J)` is the bin's centre.
fn truncation_ratios(sigma: f64) -> [f64; LEVEL_BINS] {
    let mut rho = [1.0; LEVEL_BINS];
    if sigma < 0.5 {
        return rho;
    }
    // (censored mean, effective ρ) on a grid of true levels; the censored mean increases
    // with J. The effective ρ also moves the median of |residual| for the truncated shape
    // (Edgeworth: the residual's excess kurtosis is κ/4 and skewness γ/6 of one sample's).
    const GRID: usize = 64;
    let (j0, j1) = (-1.5 * sigma, 255.0 + 1.5 * sigma);
    let dj = (j1 - j0) / GRID as f64;
    let (he3, he5) = (-1.716_6, 7.189);
    let table: Vec<(f64, f64)> = (0..=GRID)
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
            let (gamma, kappa) = (mu3 / (var * var.sqrt()), mu4 / (var * var) - 3.0);
            let q =
                MEDIAN_ABS_NORMAL + kappa / 4.0 / 24.0 * he3 + (gamma / 6.0).powi(2) / 72.0 * he5;
            // E[clip(J + K)]: 0 below, 255 above, the truncated mean between.
            let censored = 255.0 * (1.0 - cb) + z * (j + sigma * m1);
            (censored, var.sqrt() * q / MEDIAN_ABS_NORMAL)
        })
        .collect();
    // ρ at a true level, interpolated on the grid.
    let at = |j: f64| -> f64 {
        let u = ((j - j0) / dj).clamp(0.0, GRID as f64 - 1e-9);
        let i = u.floor() as usize;
        table[i].1 + (u - i as f64) * (table[i + 1].1 - table[i].1)
    };
    // The level is read from 72 noisy pixels: average ρ over its error (three-point
    // Gauss–Hermite, ±√3 standard errors).
    let err = sigma / 72f64.sqrt() * 3f64.sqrt();
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
        *r = (4.0 * at(j) + at(j - err) + at(j + err)) / 6.0;
    }
    rho
}

/// The photometric scale of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exposure {
    /// The white level: the 99.5th percentile of the brightest channel of each pixel
    /// (sky, white paint, lit lamps), 0–255. Colour tests divide by it.
    pub white: f64,
    /// Mean luminance (mean of the channels) over the frame, 0–255.
    pub mean_luma: f64,
}

/// Measures a frame's white level and mean luminance on a grid of about 4,000 pixels.
pub fn exposure(rgb: &[u8], width: usize, height: usize) -> Result<Exposure, MonitorError> {
    check(rgb, width, height)?;
    let step = (((width * height) as f64 / TARGET_SAMPLES as f64)
        .sqrt()
        .floor() as usize)
        .max(1);
    let mut hist = [0u32; 256];
    let (mut n, mut sum) = (0usize, 0u64);
    for y in (0..height).step_by(step) {
        for x in (0..width).step_by(step) {
            let i = (y * width + x) * 3;
            let (r, g, b) = (rgb[i], rgb[i + 1], rgb[i + 2]);
            hist[usize::from(r.max(g).max(b))] += 1;
            sum += u64::from(r) + u64::from(g) + u64::from(b);
            n += 1;
        }
    }
    let rank = (n as f64 * 0.995).floor() as usize;
    let mut acc = 0usize;
    let mut white = 255.0;
    for (v, &c) in hist.iter().enumerate() {
        acc += c as usize;
        if acc > rank.min(n - 1) {
            white = v as f64;
            break;
        }
    }
    Ok(Exposure {
        white,
        mean_luma: sum as f64 / (3 * n) as f64,
    })
}

/// The standard normal distribution function Φ (Abramowitz & Stegun 7.1.26 for erf,
/// absolute error below 1.5 × 10⁻⁷).
pub fn normal_cdf(z: f64) -> f64 {
    let x = z.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let erf = 1.0 - poly * (-x * x).exp();
    if z >= 0.0 {
        0.5 * (1.0 + erf)
    } else {
        0.5 * (1.0 - erf)
    }
}

/// The standard normal density φ.
fn normal_pdf(z: f64) -> f64 {
    (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// Undoes the bias that clipping at 0 and 255 puts into the mean of noisy pixels.
///
/// A sample is `clip(J + K)` with `K ~ N(0, σ²)`: near the ends of the range the clipped
/// noise no longer averages to zero (a lamp at 255 under σ = 70 averages about 227; a
/// dark paint at 30 averages about 45). For a patch of constant true value `μ` the mean
/// of its clipped samples tends to `g(μ) = E[clip(μ + K, 0, 255)]`, which is increasing in
/// `μ`; [`Censoring::true_mean`] inverts it, so photometric tests compare true levels.
#[derive(Debug, Clone)]
pub struct Censoring {
    /// Per observed level `i` = 0, …, 254: `true_mean` at `i` and its rise to `i + 1`, the
    /// linear piece over `[i, i + 1]` (255 is the end of the last piece). A fixed-size
    /// array: the look-up is the inner loop of every pooled reading.
    pieces: Box<[[f32; 2]; 255]>,
}

impl Censoring {
    /// The inverse for noise `sigma`, or `None` when the noise is too weak to matter
    /// (σ < 3: the bias is below 0.1 level above 9 and below 246).
    pub fn new(sigma: f64) -> Option<Self> {
        if sigma.is_nan() || sigma < 3.0 {
            return None;
        }
        let g = |mu: f64| -> f64 {
            let hi = (mu - 255.0) / sigma;
            let lo = mu / sigma;
            let over = (mu - 255.0) * normal_cdf(hi) + sigma * normal_pdf(hi);
            let under = -mu * normal_cdf(-lo) + sigma * normal_pdf(lo);
            mu - over + under
        };
        // g on a fine grid of true levels, then inverted at each observed level by linear
        // interpolation between the grid points that bracket it (g is increasing).
        let (lo_mu, hi_mu) = (-3.0 * sigma, 255.0 + 3.0 * sigma);
        const GRID: usize = 1024;
        let mus: Vec<f64> = (0..=GRID)
            .map(|i| lo_mu + (hi_mu - lo_mu) * i as f64 / GRID as f64)
            .collect();
        let gs: Vec<f64> = mus.iter().map(|&m| g(m)).collect();
        let mut j = 0;
        let table: Vec<f32> = (0..=255)
            .map(|m| {
                let target = f64::from(m);
                while j + 1 < GRID && gs[j + 1] < target {
                    j += 1;
                }
                let (g0, g1) = (gs[j], gs[j + 1]);
                let f = if g1 > g0 {
                    ((target - g0) / (g1 - g0)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (mus[j] + f * (mus[j + 1] - mus[j])) as f32
            })
            .collect();
        let mut pieces = Box::new([[0f32; 2]; 255]);
        for (i, p) in pieces.iter_mut().enumerate() {
            *p = [table[i], table[i + 1] - table[i]];
        }
        Some(Self { pieces })
    }

    /// The true level whose clipped noisy samples average `observed` (0–255).
    #[inline]
    pub fn true_mean(&self, observed: f32) -> f32 {
        let x = observed.clamp(0.0, 255.0);
        // `x` is non-negative, so truncation is its floor (without a library call).
        // Through `i32`: baseline x86-64 converts between `f32` and `i32` in one
        // instruction each, but needs a branchy sequence for `usize`.
        let i = (x as i32).clamp(0, 254);
        let f = x - i as f32;
        let [t, rise] = self.pieces[i as usize];
        t + f * rise
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic normal stream (Box–Muller on a 64-bit LCG), for the tests only.
    struct Normal(u64);
    impl Normal {
        fn unit(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn next(&mut self) -> f64 {
            let (a, b) = (self.unit(), self.unit());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        }
    }

    /// A scene with structure: vertical bands and a diagonal edge, values 60–200.
    fn scene(w: usize, h: usize) -> Vec<u8> {
        let mut v = vec![0u8; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                let base: u8 = if x * 3 < w {
                    70
                } else if x + y < w {
                    180
                } else {
                    120
                };
                for c in 0..3 {
                    v[(y * w + x) * 3 + c] = base + (c as u8) * 5;
                }
            }
        }
        v
    }

    fn noisy(clean: &[u8], sigma: f64, seed: u64) -> Vec<u8> {
        let mut g = Normal(seed);
        clean
            .iter()
            .map(|&p| (f64::from(p) + sigma * g.next()).round().clamp(0.0, 255.0) as u8)
            .collect()
    }

    #[test]
    fn a_clean_scene_reads_zero_and_noise_reads_its_sigma() {
        let (w, h) = (320, 200);
        let clean = scene(w, h);
        assert_eq!(estimate_noise(&clean, w, h).unwrap().sigma, 0.0);
        for (sigma, tol) in [(3.0, 0.5), (10.0, 0.8), (30.0, 2.5), (50.0, 6.0)] {
            let est = estimate_noise(&noisy(&clean, sigma, 7), w, h).unwrap();
            assert!(
                (est.sigma - sigma).abs() < tol,
                "sigma {sigma}: estimated {}",
                est.sigma
            );
        }
    }

    /// A textured scene over the whole range: a horizontal ramp 0–255, a vertical
    /// sinusoid of ±40 levels (period 50 px), channels 12 levels apart, and a dark and a
    /// bright band (12 and 243) where clipping censors the noise.
    fn textured(w: usize, h: usize) -> Vec<u8> {
        let mut v = vec![0u8; w * h * 3];
        for y in 0..h {
            let wave = 40.0 * (std::f64::consts::TAU * y as f64 / 50.0).sin();
            for x in 0..w {
                for c in 0..3 {
                    let level = if y < h / 8 {
                        12.0
                    } else if y >= h - h / 8 {
                        243.0
                    } else {
                        255.0 * x as f64 / w as f64 + wave + 12.0 * c as f64
                    };
                    v[(y * w + x) * 3 + c] = level.round().clamp(0.0, 255.0) as u8;
                }
            }
        }
        v
    }

    #[test]
    fn the_precise_estimate_reads_sigma_on_a_clipped_textured_scene() {
        let (w, h) = (960, 540);
        let clean = textured(w, h);
        assert!(estimate_noise_precise(&clean, w, h).unwrap().sigma < 0.5);
        for (sigma, tol) in [
            (5.0, 0.4),
            (10.0, 0.5),
            (20.0, 0.8),
            (30.0, 1.0),
            (50.0, 1.5),
            (70.0, 2.5),
        ] {
            let frame = noisy(&clean, sigma, 11);
            let est = estimate_noise_precise(&frame, w, h).unwrap();
            assert!(
                (est.sigma - sigma).abs() < tol,
                "sigma {sigma}: estimated {:.2}",
                est.sigma
            );
            assert!(est.samples > 10_000 && est.clipped_share < 0.9, "{est:?}");
            if sigma >= 50.0 {
                // The uncorrected median reads far low here: what the correction is for.
                let fast = estimate_noise(&frame, w, h).unwrap().sigma;
                assert!(sigma - fast > 2.0 * tol, "sigma {sigma}: fast {fast:.2}");
            }
        }
    }

    #[test]
    fn the_estimate_grows_with_the_noise() {
        let (w, h) = (200, 120);
        let clean = scene(w, h);
        let s: Vec<f64> = [0.0, 10.0, 30.0, 50.0, 70.0]
            .iter()
            .map(|&sigma| {
                estimate_noise(&noisy(&clean, sigma, 3), w, h)
                    .unwrap()
                    .sigma
            })
            .collect();
        assert!(s.windows(2).all(|p| p[1] > p[0]), "{s:?}");
    }

    #[test]
    fn censoring_recovers_the_true_level_of_clipped_means() {
        assert!(Censoring::new(1.0).is_none());
        assert!((normal_cdf(1.96) - 0.975_002_1).abs() < 1e-6);
        for sigma in [30.0, 70.0] {
            let c = Censoring::new(sigma).unwrap();
            for level in [10u8, 40, 128, 230, 255] {
                let flat = vec![level; 300 * 300];
                let obs: f64 = noisy(&flat, sigma, 5)
                    .iter()
                    .map(|&p| f64::from(p))
                    .sum::<f64>()
                    / flat.len() as f64;
                let back = f64::from(c.true_mean(obs as f32));
                assert!(
                    (back - f64::from(level)).abs() < 2.5,
                    "σ {sigma}, level {level}: observed {obs:.1}, recovered {back:.1}"
                );
            }
        }
    }

    #[test]
    fn bad_sizes_are_errors() {
        assert!(matches!(
            estimate_noise(&[0u8; 10], 2, 2),
            Err(MonitorError::Size { expected: 12, .. })
        ));
        assert!(matches!(
            estimate_noise(&[0u8; 12], 2, 2),
            Err(MonitorError::TooSmall { .. })
        ));
        assert!(estimate_noise_precise(&[0u8; 12], 2, 2).is_err());
        assert!(estimate_noise_precise(&[0u8; 11], 2, 2).is_err());
        assert!(exposure(&[0u8; 5], 3, 3).is_err());
    }

    #[test]
    fn exposure_scales_with_gain() {
        let (w, h) = (100, 80);
        let a = scene(w, h);
        let dark: Vec<u8> = a
            .iter()
            .map(|&p| (f64::from(p) * 0.4).round() as u8)
            .collect();
        let (ea, ed) = (exposure(&a, w, h).unwrap(), exposure(&dark, w, h).unwrap());
        assert_eq!(ea.white, 190.0);
        assert_eq!(ed.white, 76.0);
        assert!((ed.mean_luma / ea.mean_luma - 0.4).abs() < 0.01);
    }
}
