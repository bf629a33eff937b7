//! Descriptive statistics of one sample: mean, variance, bias-corrected skewness and excess
//! kurtosis, and the bimodality coefficient.
//!
//! All are two-pass (mean first, then central moments), summed in blocks of 1024 values with
//! four lanes per block and compensated (Neumaier) summation across blocks, so rounding error
//! grows like that of NumPy's pairwise sums rather than with `n`. Samples whose magnitude is
//! outside [1e-150, 1e150] are rescaled by an exact power of two first, so moments neither
//! overflow nor underflow. Cost O(n) time, O(1) extra memory.

use crate::Result;
use crate::error::{StatsError, check_finite};

/// Values per block of the blocked summation.
const BLOCK: usize = 1024;

/// Neumaier's compensated accumulator.
#[derive(Debug, Default, Clone, Copy)]
struct Compensated {
    sum: f64,
    c: f64,
}

impl Compensated {
    #[inline]
    fn add(&mut self, v: f64) {
        let t = self.sum + v;
        if self.sum.abs() >= v.abs() {
            self.c += (self.sum - t) + v;
        } else {
            self.c += (v - t) + self.sum;
        }
        self.sum = t;
    }

    #[inline]
    fn value(self) -> f64 {
        self.sum + self.c
    }
}

/// Sums `K` functions of paired elements of `x` and `y` (equal lengths): blocks of
/// [`BLOCK`] values are summed in four lanes, block sums are added with compensation.
#[inline]
pub(crate) fn sum_map2<const K: usize>(
    x: &[f64],
    y: &[f64],
    f: impl Fn(f64, f64) -> [f64; K],
) -> [f64; K] {
    debug_assert_eq!(x.len(), y.len());
    let mut total = [Compensated::default(); K];
    for (bx, by) in x.chunks(BLOCK).zip(y.chunks(BLOCK)) {
        let mut lanes = [[0.0f64; 4]; K];
        let cx = bx.chunks_exact(4);
        let cy = by.chunks_exact(4);
        let (rx, ry) = (cx.remainder(), cy.remainder());
        for (qx, qy) in cx.zip(cy) {
            for l in 0..4 {
                let v = f(qx[l], qy[l]);
                for k in 0..K {
                    lanes[k][l] += v[k];
                }
            }
        }
        let mut part = [0.0f64; K];
        for k in 0..K {
            part[k] = (lanes[k][0] + lanes[k][1]) + (lanes[k][2] + lanes[k][3]);
        }
        for (&a, &b) in rx.iter().zip(ry) {
            let v = f(a, b);
            for k in 0..K {
                part[k] += v[k];
            }
        }
        for k in 0..K {
            total[k].add(part[k]);
        }
    }
    total.map(Compensated::value)
}

/// [`sum_map2`] for one slice.
#[inline]
pub(crate) fn sum_map<const K: usize>(x: &[f64], f: impl Fn(f64) -> [f64; K]) -> [f64; K] {
    sum_map2(x, x, |a, _| f(a))
}

/// Largest absolute value (0 for an empty slice); inputs are finite.
pub(crate) fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

/// An exact power of two that brings `max_abs` near 1 when it lies outside [1e-150, 1e150]
/// (so squares and fourth powers cannot overflow or underflow), else 1.
pub(crate) fn pow2_scale(max_abs: f64) -> f64 {
    if max_abs == 0.0 || (1e-150..=1e150).contains(&max_abs) {
        return 1.0;
    }
    let e = (max_abs.log2().floor() as i64).clamp(-1000, 1000);
    // 2^-e built from its bits: exact.
    f64::from_bits(((1023 - e) as u64) << 52)
}

/// Mean and biased central moment sums of one sample, in the rescaled domain.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Moments {
    /// Sample size.
    pub n: f64,
    /// Mean of the scaled sample.
    pub mean: f64,
    /// Σ d², d = x·scale - mean.
    pub s2: f64,
    /// Σ d³.
    pub s3: f64,
    /// Σ d⁴.
    pub s4: f64,
    /// The power-of-two scale applied.
    pub scale: f64,
}

impl Moments {
    /// Two-pass moments of `x` (finite, non-empty).
    pub(crate) fn of(x: &[f64]) -> Moments {
        let scale = pow2_scale(max_abs(x));
        let n = x.len() as f64;
        let [sum] = sum_map(x, |v| [v * scale]);
        let mean = sum / n;
        let [s2, s3, s4] = sum_map(x, |v| {
            let d = v * scale - mean;
            let d2 = d * d;
            [d2, d2 * d, d2 * d2]
        });
        Moments {
            n,
            mean,
            s2,
            s3,
            s4,
            scale,
        }
    }

    /// SciPy's test for a (numerically) constant sample in `skew`/`kurtosis`:
    /// `m2 <= (eps · mean)²`.
    fn is_constant(&self) -> bool {
        let m2 = self.s2 / self.n;
        m2 <= (f64::EPSILON * self.mean) * (f64::EPSILON * self.mean)
    }

    /// Bias-corrected skewness `G1`.
    fn skewness(&self) -> f64 {
        let n = self.n;
        let m2 = self.s2 / n;
        let m3 = self.s3 / n;
        ((n - 1.0) * n).sqrt() / (n - 2.0) * m3 / (m2 * m2.sqrt())
    }

    /// Bias-corrected excess kurtosis `G2`.
    fn excess_kurtosis(&self) -> f64 {
        let n = self.n;
        let m2 = self.s2 / n;
        let m4 = self.s4 / n;
        1.0 / (n - 2.0) / (n - 3.0) * ((n * n - 1.0) * m4 / (m2 * m2) - 3.0 * (n - 1.0) * (n - 1.0))
    }
}

fn need(what: &'static str, needed: usize, got: usize) -> Result<()> {
    if got < needed {
        Err(StatsError::TooFewSamples { what, needed, got })
    } else {
        Ok(())
    }
}

fn finite_or_overflow(what: &'static str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(StatsError::Undefined {
            what,
            reason: "the result overflows f64".to_string(),
        })
    }
}

/// Arithmetic mean `Σx / n`.
///
/// Matches `numpy.mean` to 1e-9 relative (in practice ~1e-15 unless the mean nearly cancels).
/// Errors: empty sample (`TooFewSamples`), a non-finite value (`NonFinite`). Values near
/// `f64::MAX` are rescaled by a power of two, so the sum cannot overflow. Cost O(n).
pub fn mean(x: &[f64]) -> Result<f64> {
    need("mean", 1, x.len())?;
    check_finite("mean", x)?;
    let scale = pow2_scale(max_abs(x));
    let [sum] = sum_map(x, |v| [v * scale]);
    Ok(sum / x.len() as f64 / scale)
}

/// Variance with `ddof` delta degrees of freedom: `Σ(x - x̄)² / (n - ddof)` (two-pass).
///
/// `ddof = 0` is the population variance, `ddof = 1` the unbiased sample variance; matches
/// `numpy.var(x, ddof=ddof)` to 1e-9 relative. A constant sample gives 0 (not an error).
/// Errors: `n <= ddof` (`TooFewSamples`), a non-finite value, or a variance beyond `f64::MAX`
/// (`Undefined`). Cost O(n).
pub fn variance(x: &[f64], ddof: usize) -> Result<f64> {
    need("variance", ddof + 1, x.len())?;
    check_finite("variance", x)?;
    let m = Moments::of(x);
    let v = m.s2 / (x.len() - ddof) as f64 / m.scale / m.scale;
    finite_or_overflow("variance", v)
}

/// Bias-corrected sample skewness `G1 = √(n(n-1)) / (n-2) · m3 / m2^{3/2}`, with `m_k` the
/// biased central moments.
///
/// Equals `scipy.stats.skew(x, bias=False)` to 1e-9 relative. Needs `n >= 3`. A constant
/// sample, judged as SciPy does (`m2 <= (ε·mean)²`), is `ConstantSample` (SciPy returns NaN).
/// Cost O(n).
pub fn skewness(x: &[f64]) -> Result<f64> {
    need("skewness", 3, x.len())?;
    check_finite("skewness", x)?;
    let m = Moments::of(x);
    if m.is_constant() {
        return Err(StatsError::ConstantSample { what: "skewness" });
    }
    finite_or_overflow("skewness", m.skewness())
}

/// Bias-corrected excess kurtosis
/// `G2 = [(n² - 1) m4/m2² - 3(n-1)²] / ((n-2)(n-3))`.
///
/// Equals `scipy.stats.kurtosis(x, fisher=True, bias=False)` to 1e-9 relative. Needs
/// `n >= 4`; a constant sample (SciPy's test, as in [`skewness`]) is `ConstantSample`.
/// Cost O(n).
pub fn excess_kurtosis(x: &[f64]) -> Result<f64> {
    need("excess_kurtosis", 4, x.len())?;
    check_finite("excess_kurtosis", x)?;
    let m = Moments::of(x);
    if m.is_constant() {
        return Err(StatsError::ConstantSample {
            what: "excess_kurtosis",
        });
    }
    finite_or_overflow("excess_kurtosis", m.excess_kurtosis())
}

/// Sample bimodality coefficient (Pfister et al. 2013, SAS's definition)
/// `BC = (G1² + 1) / (G2 + 3(n-1)² / ((n-2)(n-3)))`, with `G1`, `G2` the bias-corrected
/// skewness and excess kurtosis of [`skewness`] and [`excess_kurtosis`].
///
/// Values above 5/9 ≈ 0.555 (the uniform distribution's) suggest bimodality. Matches the same
/// formula over `scipy.stats.skew(x, bias=False)` and `scipy.stats.kurtosis(x, bias=False)`
/// to 1e-9 relative. Needs `n >= 4`; a constant sample is `ConstantSample`. The denominator
/// equals `(n²-1) m4 / (m2² (n-2)(n-3)) > 0`, so the result is always finite. Cost O(n).
pub fn bimodality_coefficient(x: &[f64]) -> Result<f64> {
    need("bimodality_coefficient", 4, x.len())?;
    check_finite("bimodality_coefficient", x)?;
    let m = Moments::of(x);
    if m.is_constant() {
        return Err(StatsError::ConstantSample {
            what: "bimodality_coefficient",
        });
    }
    let n = m.n;
    let g = m.skewness();
    let k = m.excess_kurtosis();
    let bc = (g * g + 1.0) / (k + 3.0 * (n - 1.0) * (n - 1.0) / ((n - 2.0) * (n - 3.0)));
    finite_or_overflow("bimodality_coefficient", bc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_examples() {
        assert_eq!(mean(&[1.0, 2.0, 3.0, 4.0]).expect("valid input"), 2.5);
        assert_eq!(
            variance(&[1.0, 2.0, 3.0, 4.0], 1).expect("valid input"),
            5.0 / 3.0
        );
        assert_eq!(
            skewness(&[1.0, 2.0, 3.0, 4.0, 5.0]).expect("valid input"),
            0.0
        );
        assert!(matches!(
            skewness(&[2.0; 5]),
            Err(StatsError::ConstantSample { .. })
        ));
        assert!(matches!(
            excess_kurtosis(&[1.0, 2.0, 3.0]),
            Err(StatsError::TooFewSamples { .. })
        ));
        assert!(matches!(
            variance(&[1.0], 1),
            Err(StatsError::TooFewSamples { .. })
        ));
        assert!(matches!(
            mean(&[1.0, f64::NAN]),
            Err(StatsError::NonFinite { index: 1, .. })
        ));
    }

    #[test]
    fn extreme_magnitudes_do_not_overflow() {
        let x = [1e300, -1e300, 3e299, 5e299];
        let big = skewness(&x).expect("valid input");
        let unit = skewness(&[1.0, -1.0, 0.3, 0.5]).expect("valid input");
        assert!((big - unit).abs() < 1e-12);
        assert_eq!(mean(&[f64::MAX, f64::MAX]).expect("valid input"), f64::MAX);
        assert!(variance(&x, 1).is_err());
        let tiny = [1e-300, 2e-300, 4e-300, 8e-300];
        assert!(bimodality_coefficient(&tiny).is_ok());
    }

    #[test]
    fn blocked_sum_is_accurate() {
        // 1e6 copies of 0.1: naive summation drifts by ~1e-10 relative.
        let x = vec![0.1; 1_000_000];
        let m = mean(&x).expect("valid input");
        assert!((m - 0.1).abs() < 1e-15);
    }
}
