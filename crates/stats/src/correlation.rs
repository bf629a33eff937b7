//! Correlation coefficients with two-sided p-values: Pearson, Spearman, point-biserial; and
//! average ranks.
//!
//! All follow SciPy's conventions: `n < 2` is an error, `n == 2` gives `r = ±1` exactly and
//! `p = 1`, a constant input (every value equal to the first, SciPy's test) is an error where
//! SciPy warns and returns NaN, and `|r|` is clamped to 1.

use crate::Result;
use crate::describe::{max_abs, pow2_scale, sum_map, sum_map2};
use crate::error::{StatsError, check_finite};
use crate::special::{beta_inc_pair, t_sf};

/// A correlation coefficient and its two-sided p-value.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Correlation {
    /// The coefficient, in [-1, 1].
    pub r: f64,
    /// Two-sided p-value of the null hypothesis of no correlation, in [0, 1].
    pub p_value: f64,
    /// Number of pairs.
    pub n: usize,
}

fn check_pairs(what: &'static str, nx: usize, ny: usize) -> Result<()> {
    if nx != ny {
        return Err(StatsError::LengthMismatch {
            what,
            left: nx,
            right: ny,
        });
    }
    if nx < 2 {
        return Err(StatsError::TooFewSamples {
            what,
            needed: 2,
            got: nx,
        });
    }
    Ok(())
}

fn is_constant(x: &[f64]) -> bool {
    x.iter().all(|&v| v == x[0])
}

/// Pearson's r of two finite, non-constant samples of equal length >= 2, clamped to [-1, 1].
/// Each sample is rescaled by an exact power of two when its magnitude is extreme.
fn pearson_r(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (sx, sy) = (pow2_scale(max_abs(x)), pow2_scale(max_abs(y)));
    let [sum_x, sum_y] = sum_map2(x, y, |a, b| [a * sx, b * sy]);
    let (mx, my) = (sum_x / n, sum_y / n);
    let [sxx, syy, sxy] = sum_map2(x, y, |a, b| {
        let dx = a * sx - mx;
        let dy = b * sy - my;
        [dx * dx, dy * dy, dx * dy]
    });
    clamp_r(sxy / (sxx * syy).sqrt())
}

fn clamp_r(r: f64) -> f64 {
    r.clamp(-1.0, 1.0)
}

/// Two-sided p-value of Pearson's r under normality, as `scipy.stats.pearsonr`:
/// `r` is Beta(n/2 - 1, n/2 - 1) on [-1, 1], so `p = 2 I_{(1-|r|)/2}(n/2-1, n/2-1)`.
/// `n == 2` gives 1 (SciPy's convention). Both beta arguments are formed without cancellation.
fn pearson_p(r: f64, n: usize) -> f64 {
    if n == 2 {
        return 1.0;
    }
    let ab = n as f64 / 2.0 - 1.0;
    let ar = r.abs();
    let (tail, _) = beta_inc_pair(ab, ab, 0.5 * (1.0 - ar), 0.5 * (1.0 + ar));
    (2.0 * tail).min(1.0)
}

/// The coefficient to report for `n == 2`: exactly ±1 (SciPy rounds it).
fn finish(r: f64, p: f64, n: usize) -> Correlation {
    let r = if n == 2 { r.round() } else { r };
    Correlation { r, p_value: p, n }
}

/// Pearson's product-moment correlation `r = Σ(x-x̄)(y-ȳ) / √(Σ(x-x̄)² Σ(y-ȳ)²)` with the
/// two-sided p-value `2 I_{(1-|r|)/2}(n/2-1, n/2-1)` (exact under bivariate normality).
///
/// Matches `scipy.stats.pearsonr(x, y)` (statistic and two-sided p-value) to 1e-9 relative,
/// including p-values down to ~1e-300 (unless `|r|` is within ~1e-12 of 1, where `r`'s last
/// bit decides the p-value in any implementation). Errors: different lengths
/// (`LengthMismatch`), `n < 2` (`TooFewSamples`), a non-finite value (`NonFinite`), a
/// constant input (`ConstantSample`; SciPy warns and returns NaN). `n == 2` gives `r = ±1`,
/// `p = 1`. Cost O(n), no allocation.
pub fn pearson(x: &[f64], y: &[f64]) -> Result<Correlation> {
    check_pairs("pearson", x.len(), y.len())?;
    check_finite("pearson x", x)?;
    check_finite("pearson y", y)?;
    if is_constant(x) {
        return Err(StatsError::ConstantSample { what: "pearson x" });
    }
    if is_constant(y) {
        return Err(StatsError::ConstantSample { what: "pearson y" });
    }
    let n = x.len();
    let r = pearson_r(x, y);
    Ok(finish(r, pearson_p(r, n), n))
}

/// Average ranks, 1-based, ties sharing the mean of the ranks they span: equals
/// `scipy.stats.rankdata(x, method='average')` exactly (ranks are exact halves).
///
/// `-0.0` and `0.0` tie. NaN (which the statistics reject before ranking) is ordered by
/// `f64::total_cmp` and never ties, where SciPy would return all-NaN ranks. Cost O(n log n)
/// time, one O(n) buffer of (value, index) pairs besides the output.
pub fn rank_average(x: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; x.len()];
    let mut buf = Vec::with_capacity(x.len());
    rank_into(x, &mut buf, &mut out);
    out
}

/// Writes the average ranks of `x` into `out`, using `buf` as scratch.
fn rank_into(x: &[f64], buf: &mut Vec<(f64, usize)>, out: &mut [f64]) {
    buf.clear();
    buf.extend(x.iter().copied().zip(0..));
    buf.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let n = buf.len();
    let mut i = 0;
    while i < n {
        let v = buf[i].0;
        let mut j = i + 1;
        while j < n && buf[j].0 == v {
            j += 1;
        }
        // Ranks i+1 ..= j share their mean.
        let rank = (i + j + 1) as f64 / 2.0;
        for &(_, idx) in &buf[i..j] {
            out[idx] = rank;
        }
        i = j;
    }
}

/// Spearman's rank correlation: Pearson's r of the average ranks ([`rank_average`]), with
/// SciPy's t-approximation p-value `2 · t_sf(|t|, n-2)`, `t = r √((n-2) / ((r+1)(1-r)))`.
///
/// Matches `scipy.stats.spearmanr(x, y)` to 1e-9 relative (statistic and p-value, ties
/// included). `|r| = 1` with `n > 2` gives `p = 0`, as SciPy. For `n == 2` this returns
/// `r = ±1`, `p = 1` (pearsonr's convention; SciPy's spearmanr returns p = NaN there).
/// Errors as [`pearson`]. Cost O(n log n) time, three O(n) buffers.
pub fn spearman(x: &[f64], y: &[f64]) -> Result<Correlation> {
    check_pairs("spearman", x.len(), y.len())?;
    check_finite("spearman x", x)?;
    check_finite("spearman y", y)?;
    if is_constant(x) {
        return Err(StatsError::ConstantSample { what: "spearman x" });
    }
    if is_constant(y) {
        return Err(StatsError::ConstantSample { what: "spearman y" });
    }
    let n = x.len();
    let mut buf = Vec::with_capacity(n);
    let mut rx = vec![0.0; n];
    let mut ry = vec![0.0; n];
    rank_into(x, &mut buf, &mut rx);
    rank_into(y, &mut buf, &mut ry);
    drop(buf);
    let r = pearson_r(&rx, &ry);
    if n == 2 {
        return Ok(finish(r, 1.0, n));
    }
    let dof = (n - 2) as f64;
    let den = (r + 1.0) * (1.0 - r);
    let t = if den > 0.0 {
        r * (dof / den).sqrt()
    } else {
        f64::INFINITY
    };
    let p = (2.0 * t_sf(t.abs(), dof)).min(1.0);
    Ok(finish(r, p, n))
}

/// Point-biserial correlation between a binary flag and a continuous variable: Pearson's r
/// of (`flag` as 0/1, `y`) and its p-value, as `scipy.stats.pointbiserialr(flags, y)`.
///
/// Computed in closed form without converting the flags: with `p` the fraction of `true`,
/// `Σ(x-x̄)² = n p (1-p)` and `Σ(x-x̄)(y-ȳ) = (1-p) Σ_{true}(y-ȳ) - p Σ_{false}(y-ȳ)`.
/// Matches SciPy to 1e-9 relative. Errors: different lengths, `n < 2`, non-finite `y`, all
/// flags equal or constant `y` (`ConstantSample`). `n == 2` gives `r = ±1`, `p = 1`.
/// Cost O(n), no allocation.
pub fn point_biserial(flags: &[bool], y: &[f64]) -> Result<Correlation> {
    check_pairs("point_biserial", flags.len(), y.len())?;
    check_finite("point_biserial y", y)?;
    let n = y.len();
    let n1 = flags.iter().filter(|&&f| f).count();
    if n1 == 0 || n1 == n {
        return Err(StatsError::ConstantSample {
            what: "point_biserial flags",
        });
    }
    if is_constant(y) {
        return Err(StatsError::ConstantSample {
            what: "point_biserial y",
        });
    }
    let sy = pow2_scale(max_abs(y));
    let [sum_y] = sum_map(y, |b| [b * sy]);
    let my = sum_y / n as f64;
    // Σ dy² and Σ_{true} dy, Σ_{false} dy in one pass (flags mapped to 0/1 alongside y).
    let mut syy = 0.0;
    let mut s1 = 0.0;
    let mut s0 = 0.0;
    for (fs, ys) in flags.chunks(1024).zip(y.chunks(1024)) {
        let (mut b_yy, mut b1, mut b0) = (0.0, 0.0, 0.0);
        for (&f, &b) in fs.iter().zip(ys) {
            let dy = b * sy - my;
            b_yy += dy * dy;
            if f {
                b1 += dy;
            } else {
                b0 += dy;
            }
        }
        syy += b_yy;
        s1 += b1;
        s0 += b0;
    }
    let p = n1 as f64 / n as f64;
    let sxx = n as f64 * p * (1.0 - p);
    let sxy = (1.0 - p) * s1 - p * s0;
    let r = clamp_r(sxy / (sxx * syy).sqrt());
    Ok(finish(r, pearson_p(r, n), n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_with_ties() {
        assert_eq!(
            rank_average(&[3.0, 1.0, 3.0, 2.0, -0.0, 0.0]),
            vec![5.5, 3.0, 5.5, 4.0, 1.5, 1.5]
        );
        assert!(rank_average(&[]).is_empty());
    }

    #[test]
    fn edge_cases() {
        let c = pearson(&[1.0, 2.0], &[5.0, 3.0]).expect("valid input");
        assert_eq!((c.r, c.p_value), (-1.0, 1.0));
        assert!(matches!(
            pearson(&[1.0], &[1.0]),
            Err(StatsError::TooFewSamples { .. })
        ));
        assert!(matches!(
            pearson(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]),
            Err(StatsError::ConstantSample { .. })
        ));
        assert!(matches!(
            spearman(&[1.0, 2.0], &[1.0]),
            Err(StatsError::LengthMismatch { .. })
        ));
        let s = spearman(&[1.0, 2.0, 3.0, 4.0], &[1.0, 4.0, 9.0, 16.0]).expect("valid input");
        assert_eq!((s.r, s.p_value), (1.0, 0.0));
        let pb = point_biserial(&[true, false, true, false], &[2.0, 1.0, 2.0, 1.0])
            .expect("valid input");
        assert_eq!(pb.r, 1.0);
    }
}
