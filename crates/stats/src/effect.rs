//! Effect sizes and power: Cohen's d with pooled standard deviation, and the power of a
//! two-sided two-sample test (normal approximation).

use crate::Result;
use crate::describe::Moments;
use crate::error::{StatsError, check_finite};
use crate::special::{norm_cdf, norm_ppf};

/// Cohen's d: `(x̄ - ȳ) / s_p` with the pooled variance
/// `s_p² = ((n_x-1) s_x² + (n_y-1) s_y²) / (n_x + n_y - 2)` (sample variances, ddof = 1).
///
/// Positive when `x` has the larger mean. Matches the same formula over
/// `numpy.mean`/`numpy.var(ddof=1)` to 1e-9 relative. Needs `n_x, n_y >= 1` and
/// `n_x + n_y >= 3` (`TooFewSamples`); both samples constant (zero pooled variance) is
/// `ConstantSample`; non-finite values are `NonFinite`. Cost O(n_x + n_y), no allocation.
pub fn cohens_d(x: &[f64], y: &[f64]) -> Result<f64> {
    if x.is_empty() {
        return Err(StatsError::TooFewSamples {
            what: "cohens_d x",
            needed: 1,
            got: 0,
        });
    }
    if y.is_empty() {
        return Err(StatsError::TooFewSamples {
            what: "cohens_d y",
            needed: 1,
            got: 0,
        });
    }
    let total = x.len() + y.len();
    if total < 3 {
        return Err(StatsError::TooFewSamples {
            what: "cohens_d (both samples)",
            needed: 3,
            got: total,
        });
    }
    check_finite("cohens_d x", x)?;
    check_finite("cohens_d y", y)?;
    let mx = Moments::of(x);
    let my = Moments::of(y);
    // Undo the power-of-two scaling (exact) before combining the samples.
    let (mean_x, mean_y) = (mx.mean / mx.scale, my.mean / my.scale);
    let ss = mx.s2 / mx.scale / mx.scale + my.s2 / my.scale / my.scale;
    let pooled_var = ss / (total - 2) as f64;
    if pooled_var <= 0.0 {
        return Err(StatsError::ConstantSample {
            what: "cohens_d (pooled)",
        });
    }
    let d = (mean_x - mean_y) / pooled_var.sqrt();
    if pooled_var.is_finite() && d.is_finite() {
        Ok(d)
    } else {
        Err(StatsError::Undefined {
            what: "cohens_d",
            reason: "the pooled variance overflows f64".to_string(),
        })
    }
}

/// Power of a two-sided two-sample test of standardized effect size `d` at level `alpha`,
/// by the **normal approximation**: with `n_eff = n_x n_y / (n_x + n_y)`,
/// `λ = |d| √n_eff` and `z = Φ⁻¹(1 - α/2)` (computed as `-Φ⁻¹(α/2)`),
/// `power = Φ(λ - z) + Φ(-λ - z)`.
///
/// This is not statsmodels' `TTestIndPower`, which uses the noncentral t; the two agree to
/// ~1e-3 for `n_eff >= 50` and the normal version slightly overstates power for small
/// samples. Matches the formula evaluated with `scipy.stats.norm` to 1e-9 relative. `d = 0`
/// gives `alpha`. Errors: `d` not finite or `alpha` outside (0, 1) (`InvalidParam`),
/// `n_x` or `n_y` zero (`TooFewSamples`). Cost O(1).
pub fn two_sample_power(d: f64, n_x: usize, n_y: usize, alpha: f64) -> Result<f64> {
    if !d.is_finite() {
        return Err(StatsError::InvalidParam {
            name: "d",
            reason: format!("must be finite, got {d}"),
        });
    }
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(StatsError::InvalidParam {
            name: "alpha",
            reason: format!("must be in (0, 1), got {alpha}"),
        });
    }
    if n_x == 0 {
        return Err(StatsError::TooFewSamples {
            what: "two_sample_power n_x",
            needed: 1,
            got: 0,
        });
    }
    if n_y == 0 {
        return Err(StatsError::TooFewSamples {
            what: "two_sample_power n_y",
            needed: 1,
            got: 0,
        });
    }
    let (nx, ny) = (n_x as f64, n_y as f64);
    let n_eff = nx * ny / (nx + ny);
    let lambda = d.abs() * n_eff.sqrt();
    let z = -norm_ppf(0.5 * alpha);
    let power = norm_cdf(lambda - z) + norm_cdf(-lambda - z);
    Ok(power.min(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d_and_power() {
        let d = cohens_d(&[1.0, 2.0, 3.0], &[2.0, 3.0, 4.0]).expect("valid input");
        assert!((d + 1.0).abs() < 1e-15);
        assert!(matches!(
            cohens_d(&[1.0, 1.0], &[1.0]),
            Err(StatsError::ConstantSample { .. })
        ));
        assert!(matches!(
            cohens_d(&[1.0], &[2.0]),
            Err(StatsError::TooFewSamples { .. })
        ));
        let p0 = two_sample_power(0.0, 20, 20, 0.05).expect("valid input");
        assert!((p0 - 0.05).abs() < 1e-15);
        let p = two_sample_power(0.5, 64, 64, 0.05).expect("valid input");
        assert!((p - 0.807).abs() < 0.01);
        assert!(two_sample_power(0.5, 64, 64, 1.0).is_err());
    }
}
