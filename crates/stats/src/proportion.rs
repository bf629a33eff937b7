//! Confidence intervals of a binomial proportion.
//!
//! [`wilson`]: the Wilson score interval of `k` successes in `n` trials at confidence `1 − α`,
//!
//! ```text
//! p̂ = k / n,  z = Φ⁻¹(1 − α/2)
//! centre = (p̂ + z²/(2n)) / (1 + z²/n)
//! half   = z / (1 + z²/n) · sqrt(p̂(1 − p̂)/n + z²/(4n²))
//! ```
//!
//! It is the formula of `statsmodels.stats.proportion.proportion_confint(k, n, alpha,
//! method="wilson")` (the bounds clamped to [0, 1]); the tests check it against the formula
//! evaluated independently in Python to 1e-9. Unlike the normal (Wald) interval it stays
//! inside [0, 1] and is not degenerate at `k = 0` or `k = n`, which accuracy tables with few
//! samples per cell need. Edge cases: `n = 0` is [`StatsError::TooFewSamples`], `k > n` or
//! `α` outside (0, 1) is [`StatsError::InvalidParam`]. Cost O(1).
//!
//! ```
//! use fogline_stats::proportion::wilson;
//!
//! let ci = wilson(8, 10, 0.05).unwrap();
//! assert!((ci.low - 0.4901625).abs() < 1e-6 && (ci.high - 0.9433178).abs() < 1e-6);
//! ```

use crate::special::norm_ppf;
use crate::{Result, StatsError};

/// A proportion with its confidence interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProportionCi {
    /// `k / n`.
    pub estimate: f64,
    /// Lower bound.
    pub low: f64,
    /// Upper bound.
    pub high: f64,
}

/// The Wilson score interval of `successes` out of `trials` at confidence `1 − alpha`.
pub fn wilson(successes: u64, trials: u64, alpha: f64) -> Result<ProportionCi> {
    if trials == 0 {
        return Err(StatsError::TooFewSamples {
            what: "wilson interval",
            needed: 1,
            got: 0,
        });
    }
    if successes > trials {
        return Err(StatsError::InvalidParam {
            name: "successes",
            reason: format!("{successes} successes exceed {trials} trials"),
        });
    }
    if !(alpha.is_finite() && alpha > 0.0 && alpha < 1.0) {
        return Err(StatsError::InvalidParam {
            name: "alpha",
            reason: format!("{alpha} is not in (0, 1)"),
        });
    }
    let n = trials as f64;
    let p = successes as f64 / n;
    let z = norm_ppf(1.0 - alpha / 2.0);
    let z2 = z * z;
    let denom = 1.0 + z2 / n;
    let centre = (p + z2 / (2.0 * n)) / denom;
    let half = z / denom * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    // The interval contains p; clamping keeps rounding from putting a bound on its wrong
    // side (at 0 successes the lower bound is exactly 0, at n successes the upper one 1).
    Ok(ProportionCi {
        estimate: p,
        low: (centre - half).clamp(0.0, p),
        high: (centre + half).clamp(p, 1.0),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_statsmodels() {
        // The formula evaluated in Python with `statistics.NormalDist().inv_cdf(0.975)` (the
        // formula of statsmodels' `proportion_confint(k, n, 0.05, method="wilson")`).
        let cases = [
            (0, 10, 0.0, 0.27753279986288),
            (10, 10, 0.72246720013712, 1.0),
            (37, 50, 0.6044684273515117, 0.8412847250644762),
        ];
        for (k, n, lo, hi) in cases {
            let ci = wilson(k, n, 0.05).unwrap();
            assert!((ci.low - lo).abs() < 1e-9, "{k}/{n}: {} vs {lo}", ci.low);
            assert!((ci.high - hi).abs() < 1e-9, "{k}/{n}: {} vs {hi}", ci.high);
        }
        // The bounds never cross the estimate, even by rounding.
        for n in 1..=200 {
            assert_eq!(wilson(0, n, 0.05).unwrap().low, 0.0, "0/{n}");
            assert_eq!(wilson(n, n, 0.05).unwrap().high, 1.0, "{n}/{n}");
            for k in 0..=n {
                let ci = wilson(k, n, 0.05).unwrap();
                assert!(ci.low <= ci.estimate && ci.estimate <= ci.high, "{k}/{n}");
            }
        }
        assert!(wilson(0, 0, 0.05).is_err());
        assert!(wilson(3, 2, 0.05).is_err());
        assert!(wilson(1, 2, 1.5).is_err());
    }
}
