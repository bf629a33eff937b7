//! Intraclass correlation of a complete targets × raters matrix (two-way ANOVA).

use crate::Result;
use crate::error::StatsError;

/// Result of [`icc`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Icc {
    /// ICC(2,1): two-way random effects, absolute agreement, single rater.
    pub icc2_1: f64,
    /// ICC(3,1): two-way mixed effects, consistency, single rater.
    pub icc3_1: f64,
    /// Number of targets n (rows).
    pub n_targets: usize,
    /// Number of raters k (columns).
    pub n_raters: usize,
    /// Mean square between targets `k Σ(row mean - grand mean)² / (n - 1)`.
    pub ms_rows: f64,
    /// Mean square between raters `n Σ(column mean - grand mean)² / (k - 1)`.
    pub ms_cols: f64,
    /// Residual mean square `Σ(x - row mean - column mean + grand mean)² / ((n-1)(k-1))`.
    pub ms_error: f64,
}

/// Intraclass correlations ICC(2,1) and ICC(3,1) of a complete matrix whose rows are targets
/// (clips) and whose columns are raters (conditions), from the two-way ANOVA without
/// replication (Shrout & Fleiss 1979; Koo & Li 2016):
///
/// - `ICC(2,1) = (MSR - MSE) / (MSR + (k-1) MSE + k (MSC - MSE) / n)`
/// - `ICC(3,1) = (MSR - MSE) / (MSR + (k-1) MSE)`
///
/// with MSR, MSC, MSE as documented on [`Icc`] (MSE summed directly from the residuals, not as
/// a difference of sums of squares). Matches `pingouin.intraclass_corr` (rows `ICC2` and
/// `ICC3`) to 1e-9 relative. Values can be negative when targets differ less than noise.
/// Errors: fewer than 2 rows or 2 columns (`TooFewSamples`), ragged rows (`LengthMismatch`,
/// row 0's length vs the first ragged row's), a non-finite value (`NonFinite`, row-major
/// index), all values equal or any zero denominator (`Undefined`). Cost O(n·k), O(k) extra
/// memory.
pub fn icc(matrix: &[Vec<f64>]) -> Result<Icc> {
    const WHAT: &str = "icc";
    let n = matrix.len();
    if n < 2 {
        return Err(StatsError::TooFewSamples {
            what: "icc targets (rows)",
            needed: 2,
            got: n,
        });
    }
    let k = matrix[0].len();
    if k < 2 {
        return Err(StatsError::TooFewSamples {
            what: "icc raters (columns)",
            needed: 2,
            got: k,
        });
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (i, row) in matrix.iter().enumerate() {
        if row.len() != k {
            return Err(StatsError::LengthMismatch {
                what: "icc rows (row 0 vs a later row)",
                left: k,
                right: row.len(),
            });
        }
        for (j, &v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(StatsError::NonFinite {
                    what: WHAT,
                    index: i * k + j,
                });
            }
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if lo == hi {
        return Err(StatsError::Undefined {
            what: WHAT,
            reason: "all values are equal".to_string(),
        });
    }
    let (nf, kf) = (n as f64, k as f64);
    let mut col_mean = vec![0.0f64; k];
    let mut grand = 0.0;
    for row in matrix {
        for (c, &v) in col_mean.iter_mut().zip(row) {
            *c += v;
        }
    }
    for c in &mut col_mean {
        grand += *c;
        *c /= nf;
    }
    grand /= nf * kf;
    let mut ss_rows = 0.0;
    let mut ss_err = 0.0;
    for row in matrix {
        let rm = row.iter().sum::<f64>() / kf;
        ss_rows += (rm - grand) * (rm - grand);
        for (&v, &cm) in row.iter().zip(&col_mean) {
            let e = v - rm - cm + grand;
            ss_err += e * e;
        }
    }
    let ss_cols: f64 = col_mean.iter().map(|&cm| (cm - grand) * (cm - grand)).sum();
    let ms_rows = kf * ss_rows / (nf - 1.0);
    let ms_cols = nf * ss_cols / (kf - 1.0);
    let ms_error = ss_err / ((nf - 1.0) * (kf - 1.0));
    let den2 = ms_rows + (kf - 1.0) * ms_error + kf * (ms_cols - ms_error) / nf;
    let den3 = ms_rows + (kf - 1.0) * ms_error;
    if den2.is_nan() || den2 <= 0.0 || den3.is_nan() || den3 <= 0.0 {
        return Err(StatsError::Undefined {
            what: WHAT,
            reason: "a denominator of the ICC is zero".to_string(),
        });
    }
    let icc2_1 = (ms_rows - ms_error) / den2;
    let icc3_1 = (ms_rows - ms_error) / den3;
    if !(icc2_1.is_finite() && icc3_1.is_finite()) {
        return Err(StatsError::Undefined {
            what: WHAT,
            reason: "the mean squares overflow f64".to_string(),
        });
    }
    Ok(Icc {
        icc2_1,
        icc3_1,
        n_targets: n,
        n_raters: k,
        ms_rows,
        ms_cols,
        ms_error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfect_agreement_and_errors() {
        let m = vec![vec![1.0, 1.0], vec![2.0, 2.0], vec![3.0, 3.0]];
        let r = icc(&m).expect("valid input");
        assert_eq!((r.icc2_1, r.icc3_1), (1.0, 1.0));
        // A constant rater offset lowers absolute agreement but not consistency.
        let m = vec![vec![1.0, 2.0], vec![2.0, 3.0], vec![3.0, 4.0]];
        let r = icc(&m).expect("valid input");
        assert_eq!(r.icc3_1, 1.0);
        assert!(r.icc2_1 < 1.0);
        assert!(matches!(
            icc(&[vec![1.0, 1.0], vec![1.0, 1.0]]),
            Err(StatsError::Undefined { .. })
        ));
        assert!(matches!(
            icc(&[vec![1.0, 2.0]]),
            Err(StatsError::TooFewSamples { .. })
        ));
        assert!(matches!(
            icc(&[vec![1.0, 2.0], vec![1.0]]),
            Err(StatsError::LengthMismatch { .. })
        ));
    }
}
