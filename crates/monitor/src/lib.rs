//! Blind estimates of how degraded a camera frame is, from its pixels alone.
//!
//! Nothing here knows the scene or the condition that was applied: a perception stack uses
//! these figures to size its pooling and to lower its confidence, and the runtime ODD
//! monitor compares them with the envelope's thresholds.
//!
//! - [`estimate_noise`]: the standard deviation of additive noise on the 0–255 scale
//!   (Immerkær's Laplacian-difference residual, taken robustly through its median).
//! - [`estimate_noise_precise`]: the same, corrected for the clipping at 0 and 255 that
//!   makes it read low at high σ, on a denser sample (about 15 times the cost).
//!
//! Every estimate carries its uncertainty (a standard error, or for the temporal faults the
//! measured evidence next to its threshold).
//! - [`estimate_condition`]: the photometric gain (`dark` / `bright`) and the fog opacity
//!   (`fog_<α>`) against a reference profile of clean frames ([`ConditionParams`]).
//! - [`TemporalMonitor`]: blackout, dropped and frozen frames of one camera's stream.
//! - [`estimate_frame`]: noise (precise), gain and fog of one frame together.
//! - [`exposure`]: the frame's white level and mean luminance, the photometric scale that
//!   colour tests are made relative to.
//! - [`Censoring`]: the true level behind a mean of noisy pixels clipped at 0 and 255.
//! - [`Monitor`] (module [`runtime`]): the runtime ODD monitor — these estimates smoothed
//!   over time against a scenario's entry of the envelope's `odd.json`
//!   ([`fogline_types::odd::OddSpec`]) → in / out of the envelope with the entry's severity
//!   quadrant, hysteresis and a minimum dwell; one [`MonitorRecord`] per frame (the
//!   JSON-lines log of `fogline monitor run`). The hand-over policy lives here so that every
//!   consumer (the CLI, the Python package, the closed loop) applies the same one.
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
    /// A parameter is out of its range.
    #[error("invalid {what}: expected {expected}")]
    Params {
        /// The parameter.
        what: &'static str,
        /// What it must be.
        expected: &'static str,
    },
    /// The `odd.json` has no entry for the scenario.
    #[error("odd.json has no entry for scenario {scenario:?} (entries: {known})")]
    Scenario {
        /// The scenario asked for.
        scenario: String,
        /// The entries' scenarios, comma-separated.
        known: String,
    },
    /// The scenario's entry has no threshold on any axis the monitor watches.
    #[error("odd.json entry {scenario:?} has no threshold on any watched axis ({axes})")]
    NoEnvelope {
        /// The scenario.
        scenario: String,
        /// The watched axes, comma-separated.
        axes: String,
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

mod condition;
mod noise;
pub mod runtime;
mod temporal;

/// About this many pixels are sampled per frame by the fast measures (a regular grid).
const TARGET_SAMPLES: usize = 4_000;

pub use condition::{
    ConditionEstimate, ConditionParams, PROFILE_QUANTILES, estimate_condition, luma_profile,
};
pub use noise::{NoiseEstimate, estimate_noise, estimate_noise_precise};
pub use runtime::{
    AxisReading, ESTIMATED_AXES, Monitor, MonitorParams, MonitorRecord, NullAxis, NullProfile,
    Observation,
};
pub use temporal::{TemporalMonitor, TemporalParams, TemporalReading};

/// The blind estimates of one frame: noise (by [`estimate_noise_precise`]), gain and fog.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FrameEstimate {
    /// Gaussian noise σ, 0–255 scale.
    pub noise: NoiseEstimate,
    /// Photometric gain and fog opacity.
    pub condition: ConditionEstimate,
}

/// Noise, gain and fog of one RGB8 frame (≈ 0.8 ms at 1080p on one core).
pub fn estimate_frame(
    rgb: &[u8],
    width: usize,
    height: usize,
    params: &ConditionParams,
) -> Result<FrameEstimate, MonitorError> {
    Ok(FrameEstimate {
        noise: estimate_noise_precise(rgb, width, height)?,
        condition: estimate_condition(rgb, width, height, params)?,
    })
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
pub(crate) fn normal_pdf(z: f64) -> f64 {
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
            // The standard error is positive and small next to σ.
            assert!(est.sigma_se > 0.0 && est.sigma_se < 0.03 * sigma, "{est:?}");
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
