//! Blind estimates of the photometric condition of a frame: gain (the `dark` / `bright`
//! family) and homogeneous fog (the `fog_<α>` family).
//!
//! Both act on every sample through an affine map: gain `g` gives `g·J`, fog of opacity `α`
//! and airlight `A` gives `(1 − α)·J + α·A`, and the two together `g·((1 − α)·J + α·A)`.
//! One frame cannot tell a dark scene from a dark camera, so the frame's luminance quantiles
//! are compared with a *reference profile*: the quantiles a clean frame of the same camera
//! and daylight has (by default, fogline's world; [`ConditionParams::from_clean_frames`]
//! measures one from a user's own clean frames).

use serde::{Deserialize, Serialize};

use crate::{MonitorError, check};

/// The luminance quantiles the profile holds: 5 %, 10 %, …, 95 %.
pub const PROFILE_QUANTILES: [f64; 19] = [
    0.05, 0.10, 0.15, 0.20, 0.25, 0.30, 0.35, 0.40, 0.45, 0.50, 0.55, 0.60, 0.65, 0.70, 0.75, 0.80,
    0.85, 0.90, 0.95,
];

/// Parameters of [`estimate_condition`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ConditionParams {
    /// The reference profile: the median over clean frames of each luminance quantile of
    /// [`PROFILE_QUANTILES`] (luminance = mean of the three channels, 0–255).
    pub reference: Vec<f64>,
    /// The scene-to-scene spread of each reference quantile, relative (standard deviation
    /// over the clean frames ÷ the median): the weights of the fit and its uncertainty.
    pub spread: Vec<f64>,
    /// The airlight `A` fog blends toward, 0–255 (fogline's default is 204).
    pub airlight: f64,
}

impl Default for ConditionParams {
    /// fogline's world: 192 clean frames (12 clips of world seed 99, 4 cameras × 4 frames,
    /// 960×540; a seed the benchmark does not use), airlight 204 (`fogline perturb`'s).
    fn default() -> Self {
        Self {
            reference: vec![
                44.8, 64.2, 74.7, 76.2, 76.8, 80.7, 83.3, 85.0, 87.8, 90.7, 95.3, 102.0, 123.2,
                152.7, 159.2, 162.7, 167.0, 171.0, 179.7,
            ],
            spread: vec![
                0.47, 0.32, 0.24, 0.22, 0.18, 0.14, 0.14, 0.14, 0.15, 0.17, 0.28, 0.31, 0.25, 0.18,
                0.12, 0.10, 0.09, 0.08, 0.08,
            ],
            airlight: 204.0,
        }
    }
}

impl ConditionParams {
    /// Checks lengths and ranges.
    pub fn validate(&self) -> Result<(), MonitorError> {
        let n = PROFILE_QUANTILES.len();
        let bad =
            |what: &'static str, expected: &'static str| MonitorError::Params { what, expected };
        if self.reference.len() != n || self.spread.len() != n {
            return Err(bad(
                "reference, spread",
                "19 values each (5 %, 10 %, …, 95 %)",
            ));
        }
        if !self
            .reference
            .iter()
            .all(|v| v.is_finite() && (0.0..=255.0).contains(v))
            || self.reference.windows(2).any(|p| p[1] < p[0])
            || self.reference[n - 1] <= self.reference[0]
        {
            return Err(bad(
                "reference",
                "non-decreasing levels in [0, 255], not all equal",
            ));
        }
        if !self.spread.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(bad("spread", "positive numbers"));
        }
        if !(self.airlight.is_finite() && self.airlight > 0.0 && self.airlight <= 255.0) {
            return Err(bad("airlight", "a level in (0, 255]"));
        }
        Ok(())
    }

    /// A reference measured on clean frames (`(rgb, width, height)` each): per quantile the
    /// median over the frames and its relative spread (floored at 0.05). Keeps `airlight`.
    pub fn from_clean_frames<'a>(
        frames: impl IntoIterator<Item = (&'a [u8], usize, usize)>,
        airlight: f64,
    ) -> Result<Self, MonitorError> {
        let mut profiles: Vec<[f64; 19]> = Vec::new();
        for (rgb, w, h) in frames {
            profiles.push(luma_profile(rgb, w, h)?);
        }
        if profiles.len() < 2 {
            return Err(MonitorError::Params {
                what: "frames",
                expected: "at least 2 clean frames",
            });
        }
        let n = profiles.len() as f64;
        let (mut reference, mut spread) = (Vec::new(), Vec::new());
        for i in 0..PROFILE_QUANTILES.len() {
            let mut v: Vec<f64> = profiles.iter().map(|p| p[i]).collect();
            v.sort_by(f64::total_cmp);
            let median = v[v.len() / 2];
            let mean = v.iter().sum::<f64>() / n;
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            reference.push(median);
            spread.push((sd / median.max(1.0)).max(0.05));
        }
        let p = Self {
            reference,
            spread,
            airlight,
        };
        p.validate()?;
        Ok(p)
    }
}

/// A blind estimate of gain and fog, each with its standard error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ConditionEstimate {
    /// Photometric gain `g` (1 = as the reference; `dark` is 0.4, `bright` 1.6).
    pub gain: f64,
    /// Standard error of `gain` (from the reference's scene-to-scene spread).
    pub gain_se: f64,
    /// Fog opacity `α` in [0, 1] (0 = clear; `fog_07` is 0.7).
    pub fog: f64,
    /// Standard error of `fog`.
    pub fog_se: f64,
    /// Quantiles the fit used (those neither at 0 nor at 255).
    pub quantiles_used: usize,
}

/// The frame's luminance at [`PROFILE_QUANTILES`], from a grid of about 16,000 pixels.
pub fn luma_profile(rgb: &[u8], width: usize, height: usize) -> Result<[f64; 19], MonitorError> {
    check(rgb, width, height)?;
    let step = (((width * height) as f64 / 16_000.0).sqrt().floor() as usize).max(1);
    // Luminance in thirds of a level (the channel sum, 0–765).
    let mut hist = [0u32; 766];
    let mut n = 0usize;
    for y in (0..height).step_by(step) {
        for x in (0..width).step_by(step) {
            let i = (y * width + x) * 3;
            let s = u16::from(rgb[i]) + u16::from(rgb[i + 1]) + u16::from(rgb[i + 2]);
            hist[usize::from(s)] += 1;
            n += 1;
        }
    }
    let mut out = [0.0; 19];
    let mut acc = 0usize;
    let mut v = 0usize;
    for (q, o) in PROFILE_QUANTILES.iter().zip(out.iter_mut()) {
        let rank = ((q * n as f64).floor() as usize).min(n - 1);
        while acc + hist[v] as usize <= rank {
            acc += hist[v] as usize;
            v += 1;
        }
        *o = v as f64 / 3.0;
    }
    Ok(out)
}

/// Estimates gain and fog from one frame against the reference profile.
///
/// The frame's luminance quantiles `q_i` are fitted as `a·r_i + b` (the affine map the
/// condition applies to the reference's quantiles `r_i`) by weighted least squares, each
/// quantile weighted by `1 / (a·r_i·s_i)²` with `s_i` its relative scene-to-scene spread
/// (two passes: `a` from the first). Quantiles at or below 1 or at or above 254 are left
/// out (clipped: a bright gain saturates the top ones). With the airlight `A`, the model
/// `g·((1 − α)·J + α·A)` gives `a = g·(1 − α)` and `b = g·α·A`, so `g = a + b/A` and
/// `α = (b/A) / g` (clamped to [0, 1]; a negative `b` reads as no fog). The standard errors
/// follow from the fit's covariance by the delta method, plus a component common to all
/// quantiles (the smallest relative spread of those used: a scene darker than the
/// reference as a whole); they describe how much a scene can differ from the reference,
/// not the pixels' noise (noise moves quantiles little).
/// With fewer than three usable quantiles (a black or a fully saturated frame) the gain is
/// the ratio of the medians, the fog 0, and both errors as large as the estimate.
///
/// Cost: one pass over about 16,000 pixels (≈ 0.02 ms a 1080p frame).
pub fn estimate_condition(
    rgb: &[u8],
    width: usize,
    height: usize,
    params: &ConditionParams,
) -> Result<ConditionEstimate, MonitorError> {
    params.validate()?;
    let q = luma_profile(rgb, width, height)?;
    let r = &params.reference;
    let usable: Vec<usize> = (0..q.len())
        .filter(|&i| q[i] > 1.0 && q[i] < 254.0)
        .collect();
    if usable.len() < 3 {
        let gain = q[9] / r[9].max(1.0);
        return Ok(ConditionEstimate {
            gain,
            gain_se: gain.max(1.0),
            fog: 0.0,
            fog_se: 1.0,
            quantiles_used: usable.len(),
        });
    }
    // Weighted least squares of q on r, twice (the weights depend on a).
    let mut a = 1.0;
    let mut fit = (1.0, 0.0, [[0.0; 2]; 2]);
    for _ in 0..2 {
        let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &i in &usable {
            let sd = (a * r[i] * params.spread[i]).max(1.0);
            let w = 1.0 / (sd * sd);
            sw += w;
            sx += w * r[i];
            sy += w * q[i];
            sxx += w * r[i] * r[i];
            sxy += w * r[i] * q[i];
        }
        let det = sw * sxx - sx * sx;
        if det <= 0.0 {
            break;
        }
        let slope = (sw * sxy - sx * sy) / det;
        let icpt = (sy - slope * sx) / sw;
        // Covariance of (slope, intercept) with the weights as inverse variances.
        let cov = [[sw / det, -sx / det], [-sx / det, sxx / det]];
        fit = (slope, icpt, cov);
        a = slope.max(0.05);
    }
    let (slope, icpt, cov) = fit;
    // A whole scene darker or brighter than the reference moves every quantile together,
    // which no number of quantiles averages away: the best-known quantile's relative spread
    // is added to both errors as a common component.
    let scene = usable
        .iter()
        .map(|&i| params.spread[i])
        .fold(f64::INFINITY, f64::min);
    let big_a = params.airlight;
    let b = icpt.max(0.0);
    let gain = (slope + b / big_a).max(0.0);
    // gain = slope + b/A: gradient (1, 1/A).
    let var_g = cov[0][0] + cov[1][1] / (big_a * big_a) + 2.0 * cov[0][1] / big_a;
    let (fog, fog_se) = if gain > 1e-6 {
        let f = b / big_a / gain;
        // α = (b/A) / (slope + b/A): ∂α/∂slope = −α/g, ∂α/∂b = (1 − α)/(A·g).
        let (ds, db) = (-f / gain, (1.0 - f) / (big_a * gain));
        let var = ds * ds * cov[0][0] + db * db * cov[1][1] + 2.0 * ds * db * cov[0][1];
        let f = f.clamp(0.0, 1.0);
        (f, (var.max(0.0) + ((1.0 - f) * scene).powi(2)).sqrt())
    } else {
        (0.0, 1.0)
    };
    Ok(ConditionEstimate {
        gain,
        gain_se: (var_g.max(0.0) + (gain * scene).powi(2)).sqrt(),
        fog,
        fog_se,
        quantiles_used: usable.len(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A grey frame whose luminance quantiles are the default reference's (levels spread
    /// between the reference quantiles, in a scrambled order).
    fn reference_scene(w: usize, h: usize) -> Vec<u8> {
        let r = ConditionParams::default().reference;
        let n = w * h;
        let mut v = vec![0u8; n * 3];
        for i in 0..n {
            // Position in the distribution, then the reference interpolated there.
            let p = ((i * 7919) % n) as f64 / n as f64;
            let u = ((p - 0.05) / 0.05).clamp(0.0, 18.0);
            let k = (u.floor() as usize).min(17);
            let level = r[k] + (u - k as f64) * (r[k + 1] - r[k]);
            let level = if p < 0.05 { level * p / 0.05 } else { level };
            v[i * 3..i * 3 + 3].fill(level.round() as u8);
        }
        v
    }

    #[test]
    fn r20_gain_and_fog_are_read_back_on_the_reference_scene() {
        let (w, h) = (320, 200);
        let clean = reference_scene(w, h);
        let p = ConditionParams::default();
        let e = estimate_condition(&clean, w, h, &p).unwrap();
        assert!((e.gain - 1.0).abs() < 0.03 && e.fog < 0.03, "{e:?}");
        for g in [0.4, 0.7, 1.3] {
            let f: Vec<u8> = clean
                .iter()
                .map(|&j| (g * f64::from(j) + 0.5).floor().min(255.0) as u8)
                .collect();
            let e = estimate_condition(&f, w, h, &p).unwrap();
            assert!((e.gain - g).abs() < 0.05, "gain {g}: {e:?}");
            assert!(e.fog < 0.05 && e.gain_se > 0.0, "gain {g}: {e:?}");
        }
        for alpha in [0.3, 0.7] {
            let f: Vec<u8> = clean
                .iter()
                .map(|&j| ((1.0 - alpha) * f64::from(j) + alpha * 204.0 + 0.5).floor() as u8)
                .collect();
            let e = estimate_condition(&f, w, h, &p).unwrap();
            assert!((e.fog - alpha).abs() < 0.05, "fog {alpha}: {e:?}");
            assert!(
                (e.gain - 1.0).abs() < 0.05 && e.fog_se > 0.0,
                "fog {alpha}: {e:?}"
            );
        }
    }

    #[test]
    fn degenerate_frames_and_bad_params() {
        let (w, h) = (40, 30);
        let black = vec![0u8; w * h * 3];
        let e = estimate_condition(&black, w, h, &ConditionParams::default()).unwrap();
        assert_eq!((e.gain, e.fog, e.quantiles_used), (0.0, 0.0, 0));
        assert!(e.gain_se >= 1.0, "{e:?}");
        let mut bad = ConditionParams::default();
        bad.reference.pop();
        assert!(estimate_condition(&black, w, h, &bad).is_err());
        let bad = ConditionParams {
            airlight: 0.0,
            ..ConditionParams::default()
        };
        assert!(bad.validate().is_err());
        assert!(ConditionParams::from_clean_frames([(&black[..], w, h)], 204.0).is_err());
        let scene = reference_scene(w, h);
        let p = ConditionParams::from_clean_frames([(&scene[..], w, h), (&scene[..], w, h)], 204.0)
            .unwrap();
        assert!(p.spread.iter().all(|&s| s == 0.05), "{p:?}");
    }
}
