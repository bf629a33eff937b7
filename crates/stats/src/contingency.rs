//! Contingency tables: Pearson's chi-square test of independence and Cramér's V.

use crate::Result;
use crate::error::StatsError;
use crate::special::chi2_sf;

/// Result of [`chi2_contingency`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ChiSquare {
    /// Pearson's statistic `Σ (O - E)² / E` over the reduced table.
    pub statistic: f64,
    /// Degrees of freedom `(r - 1)(c - 1)` of the reduced table.
    pub dof: usize,
    /// `P(χ²_dof > statistic)`.
    pub p_value: f64,
    /// Total count `n`.
    pub n: f64,
    /// Cramér's V `√(χ² / (n (min(r, c) - 1)))`, in [0, 1].
    pub cramers_v: f64,
    /// Rows with a nonzero total (r).
    pub rows_used: usize,
    /// Columns with a nonzero total (c).
    pub cols_used: usize,
}

/// Pearson's chi-square test of independence on an r×c table of counts, without Yates'
/// correction, and Cramér's V.
///
/// Rows and columns whose total is zero are **dropped first** (SciPy raises on them, since
/// their expected counts are zero); the reduced table must keep at least 2 rows and 2
/// columns. With row totals `R_i`, column totals `C_j` and `n = Σ R_i`, expected counts are
/// `E_ij = R_i C_j / n`, `χ² = Σ (O_ij - E_ij)² / E_ij`, `dof = (r-1)(c-1)`,
/// `p = chi2_sf(χ², dof)`, `V = √(χ² / (n (min(r, c) - 1)))` clamped to 1.
///
/// Matches `scipy.stats.chi2_contingency(reduced, correction=False)` (statistic, dof, p) and
/// `scipy.stats.contingency.association(reduced, method='cramer')` to 1e-9 relative,
/// including p-values near 1e-300. Counts need not be integers. Errors: ragged rows
/// (`LengthMismatch`, naming the first ragged row's length), a non-finite count (`NonFinite`,
/// index into the row-major flattened table), a negative count (`InvalidParam`, naming row
/// and column), fewer than 2 non-empty rows or columns (`Undefined`). Cost O(r·c).
pub fn chi2_contingency(table: &[Vec<f64>]) -> Result<ChiSquare> {
    const WHAT: &str = "chi2_contingency";
    let ncols = table.first().map_or(0, Vec::len);
    for (i, row) in table.iter().enumerate() {
        if row.len() != ncols {
            return Err(StatsError::LengthMismatch {
                what: "chi2_contingency rows (row 0 vs a later row)",
                left: ncols,
                right: row.len(),
            });
        }
        for (j, &v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(StatsError::NonFinite {
                    what: WHAT,
                    index: i * ncols + j,
                });
            }
            if v < 0.0 {
                return Err(StatsError::InvalidParam {
                    name: "table",
                    reason: format!("count at row {i}, column {j} is negative ({v})"),
                });
            }
        }
    }
    let row_tot: Vec<f64> = table.iter().map(|r| r.iter().sum()).collect();
    let mut col_tot = vec![0.0f64; ncols];
    for row in table {
        for (c, &v) in col_tot.iter_mut().zip(row) {
            *c += v;
        }
    }
    let rows: Vec<usize> = (0..table.len()).filter(|&i| row_tot[i] > 0.0).collect();
    let cols: Vec<usize> = (0..ncols).filter(|&j| col_tot[j] > 0.0).collect();
    if rows.len() < 2 || cols.len() < 2 {
        return Err(StatsError::Undefined {
            what: WHAT,
            reason: format!(
                "needs at least 2 rows and 2 columns with nonzero totals, got {} and {}",
                rows.len(),
                cols.len()
            ),
        });
    }
    let n: f64 = rows.iter().map(|&i| row_tot[i]).sum();
    let mut statistic = 0.0;
    for &i in &rows {
        for &j in &cols {
            let expected = row_tot[i] * col_tot[j] / n;
            let d = table[i][j] - expected;
            statistic += d * d / expected;
        }
    }
    let (r, c) = (rows.len(), cols.len());
    let dof = (r - 1) * (c - 1);
    let p_value = chi2_sf(statistic, dof as f64);
    let cramers_v = (statistic / n / (r.min(c) - 1) as f64).sqrt().min(1.0);
    if !statistic.is_finite() || !cramers_v.is_finite() {
        return Err(StatsError::Undefined {
            what: WHAT,
            reason: "the statistic overflows f64".to_string(),
        });
    }
    Ok(ChiSquare {
        statistic,
        dof,
        p_value,
        n,
        cramers_v,
        rows_used: r,
        cols_used: c,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_by_two_and_errors() {
        let t = vec![vec![10.0, 0.0], vec![0.0, 10.0]];
        let c = chi2_contingency(&t).expect("valid input");
        assert_eq!((c.statistic, c.dof, c.cramers_v), (20.0, 1, 1.0));
        let zero_row = vec![
            vec![10.0, 5.0, 0.0],
            vec![0.0, 0.0, 0.0],
            vec![3.0, 7.0, 0.0],
        ];
        let c = chi2_contingency(&zero_row).expect("valid input");
        assert_eq!((c.rows_used, c.cols_used, c.dof), (2, 2, 1));
        assert!(matches!(
            chi2_contingency(&[vec![1.0, 2.0]]),
            Err(StatsError::Undefined { .. })
        ));
        assert!(matches!(
            chi2_contingency(&[vec![1.0, 2.0], vec![1.0]]),
            Err(StatsError::LengthMismatch { .. })
        ));
        assert!(matches!(
            chi2_contingency(&[vec![1.0, -2.0], vec![1.0, 1.0]]),
            Err(StatsError::InvalidParam { .. })
        ));
        assert!(matches!(
            chi2_contingency(&[vec![1.0, 2.0], vec![f64::NAN, 1.0]]),
            Err(StatsError::NonFinite { index: 2, .. })
        ));
        assert!(matches!(
            chi2_contingency(&[]),
            Err(StatsError::Undefined { .. })
        ));
    }
}
