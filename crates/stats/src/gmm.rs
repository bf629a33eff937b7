//! 1-D Gaussian mixtures fitted by EM, with BIC model selection over the number of components
//! and k-fold cross-validation: the severity bands of the envelope analysis (paper §5.2).
//!
//! [`Gmm1d::fit`] matches scikit-learn's
//! `GaussianMixture(k, covariance_type="full", n_init, reg_covar, tol, max_iter).fit(x[:, None])`
//! on 1-D data: k-means initialisation (k-means++ seeding, Lloyd iterations, as scikit-learn's
//! `KMeans`), `n_init` starts keeping the one with the best final lower bound, EM stopped when
//! the mean log-likelihood per sample changes by less than `tol`. Random streams differ from
//! NumPy's, so a single fit matches scikit-learn's only where both land on the same k-means
//! partition; on the golden data sets (`tests/golden/gmm.json`, clear structure) the fits at
//! the chosen k agree with scikit-learn's to about 1e-14 relative and the minimum BIC over 20
//! restarts to 2e-5 for every k up to the true one (the tests assert 1 % and 0.1 %). Above
//! [`SKLEARN_KMEANS_MAX_N`] samples the k-means initialisation runs to convergence instead
//! (much faster, see there).
//!
//! [`select_k`] runs the paper's procedure: `restarts` fits for every `k = 1..=k_max`, BIC per
//! fit, the k chosen per restart, the modal k, BIC gains and 5-fold held-out log-likelihood.
//!
//! ```
//! use fogline_stats::gmm::{Gmm1d, GmmParams, SelectParams, select_k};
//!
//! // Two groups (3/4 near 5, 1/4 near 20) with roughly normal noise: a sum of four
//! // scrambled uniforms.
//! let x: Vec<f64> = (0..400)
//!     .map(|i: usize| {
//!         let z: f64 = (1..=4).map(|m| ((i * 7919 * m + 13 * m) % 1000) as f64 / 1000.0).sum();
//!         (if i % 4 == 0 { 20.0 } else { 5.0 }) + z - 2.0
//!     })
//!     .collect();
//! let sel = select_k(&x, &SelectParams { k_max: 4, restarts: 4, ..SelectParams::default() }).unwrap();
//! assert_eq!(sel.chosen_k, 2);
//! let g = Gmm1d::fit(&x, &GmmParams { n_components: 2, ..GmmParams::default() }).unwrap();
//! assert!((g.weights[1] - 0.25).abs() < 1e-9);
//! assert_eq!(g.predict(&[4.0, 21.0]).unwrap(), vec![0, 1]);
//! ```
//!
//! Cost: one EM iteration is one fused pass over the data, `O(n·k)` with no per-point storage
//! (about 3 ns per point and component on one core in release builds for the default x86-64
//! target, i.e. SSE2; components negligible at every point of a block of sorted data are
//! skipped); k-means works on the sorted data with prefix sums in `O(k log n)` per iteration.
//! Fits whose k-means starts land on the same partition share one EM run, which changes no
//! result.

mod em;
mod kernel;
mod kmeans;
mod select;

use serde::{Deserialize, Serialize};

pub use select::{CrossValidation, SelectParams, Selection, select_k, select_k_fixed};

use crate::error::check_finite;
use crate::{Result, StatsError};
use em::{EmFit, Settings, fit_many, mean_loglik};
use kernel::{KMAX, Model};
use kmeans::Data;

/// The largest number of components supported (the EM kernel's static maximum).
pub const MAX_COMPONENTS: usize = KMAX;

/// Parameters of [`Gmm1d::fit`]: `n_components`, `n_init`, `reg_covar`, `tol` and `max_iter` are
/// scikit-learn's `GaussianMixture` arguments of the same names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GmmParams {
    /// Number of components `k`, in `1..=`[`MAX_COMPONENTS`].
    pub n_components: usize,
    /// Number of k-means-initialised starts; the one with the greatest final lower bound is
    /// kept (default 3, ≥ 1).
    pub n_init: usize,
    /// Added to every variance (default 1e-6; must be > 0, unlike scikit-learn's ≥ 0, so a
    /// component on a single value keeps a finite density).
    pub reg_covar: f64,
    /// EM stops when the mean log-likelihood per sample changes by less than this
    /// (default 1e-3, ≥ 0).
    pub tol: f64,
    /// EM iterations per start at most (default 200, ≥ 1).
    pub max_iter: usize,
    /// Seed: start `i` uses the stream `seed::rng(seed, &[i])`.
    pub seed: u64,
    /// Largest `n` for which the k-means initialisation stops its Lloyd iterations by
    /// scikit-learn's rule (squared centre shift ≤ 1e-4·var(x)); above it they run until the
    /// labels repeat (default [`SKLEARN_KMEANS_MAX_N`]). See [`SKLEARN_KMEANS_MAX_N`].
    pub sklearn_kmeans_max_n: usize,
}

/// Default of `sklearn_kmeans_max_n` in [`GmmParams`] and [`SelectParams`]: 50,000.
///
/// Up to this many samples the k-means initialisation stops exactly as scikit-learn's `KMeans`
/// does, so fits follow scikit-learn's closely. Above it Lloyd iterations run to convergence
/// (labels repeat): different seeds then land on the same few partitions, and starts that share
/// a partition share one EM run, which at n = 3.4 million makes [`select_k`] about 10 times
/// faster. The price is less diversity among starts (slightly worse local optima are possible
/// for k below the true number of components). Set `usize::MAX` for scikit-learn's rule at every
/// n, 0 for convergence at every n.
pub const SKLEARN_KMEANS_MAX_N: usize = 50_000;

impl Default for GmmParams {
    fn default() -> Self {
        GmmParams {
            n_components: 1,
            n_init: 3,
            reg_covar: 1e-6,
            tol: 1e-3,
            max_iter: 200,
            seed: 0,
            sklearn_kmeans_max_n: SKLEARN_KMEANS_MAX_N,
        }
    }
}

impl GmmParams {
    /// Checks every field's range; called first by [`Gmm1d::fit`].
    pub fn validate(&self) -> Result<()> {
        check_k("n_components", self.n_components)?;
        check_em(
            "n_init",
            self.n_init,
            self.reg_covar,
            self.tol,
            self.max_iter,
        )
    }

    fn settings(&self) -> Settings {
        Settings {
            n_init: self.n_init,
            reg_covar: self.reg_covar,
            tol: self.tol,
            max_iter: self.max_iter,
            sklearn_kmeans_max_n: self.sklearn_kmeans_max_n,
        }
    }
}

pub(crate) fn check_k(name: &'static str, k: usize) -> Result<()> {
    if k == 0 || k > KMAX {
        return Err(StatsError::InvalidParam {
            name,
            reason: format!("must be in 1..={KMAX}, got {k}"),
        });
    }
    Ok(())
}

pub(crate) fn check_em(
    init_name: &'static str,
    n_init: usize,
    reg_covar: f64,
    tol: f64,
    max_iter: usize,
) -> Result<()> {
    if n_init == 0 {
        return Err(StatsError::InvalidParam {
            name: init_name,
            reason: "must be at least 1".into(),
        });
    }
    if !(reg_covar > 0.0 && reg_covar.is_finite()) {
        return Err(StatsError::InvalidParam {
            name: "reg_covar",
            reason: format!("must be finite and > 0, got {reg_covar}"),
        });
    }
    if !(tol >= 0.0 && tol.is_finite()) {
        return Err(StatsError::InvalidParam {
            name: "tol",
            reason: format!("must be finite and >= 0, got {tol}"),
        });
    }
    if max_iter == 0 {
        return Err(StatsError::InvalidParam {
            name: "max_iter",
            reason: "must be at least 1".into(),
        });
    }
    Ok(())
}

/// Checks the data: finite values, and a range small enough that `(x − μ)²/reg_covar` cannot
/// overflow (range² / (2·reg_covar) < 1e300).
pub(crate) fn check_data(x: &[f64], reg_covar: f64) -> Result<()> {
    check_finite("gaussian mixture", x)?;
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    let range = hi - lo;
    let representable = range * range * 0.5 / reg_covar < 1e300;
    if !x.is_empty() && !representable {
        return Err(StatsError::Undefined {
            what: "gaussian mixture",
            reason: format!(
                "the data span {range:e}, too wide for reg_covar {reg_covar:e}; rescale the data"
            ),
        });
    }
    Ok(())
}

pub(crate) fn too_few_distinct(k: usize, n_distinct: usize) -> StatsError {
    StatsError::Undefined {
        what: "gaussian mixture",
        reason: format!(
            "{k} components need at least {k} distinct values, the data have {n_distinct}"
        ),
    }
}

/// A fitted 1-D Gaussian mixture `p(x) = Σ_j w_j N(x; μ_j, σ_j²)`, components ascending by
/// mean.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gmm1d {
    /// Mixing weights `w_j` (positive, sum 1 within 1e-15).
    pub weights: Vec<f64>,
    /// Component means `μ_j`, ascending.
    pub means: Vec<f64>,
    /// Component variances `σ_j²` (each ≥ `reg_covar`).
    pub variances: Vec<f64>,
    /// scikit-learn's `lower_bound_`: the mean log-likelihood per sample computed in the last
    /// E-step, i.e. of the parameters *before* the last M-step (so it differs slightly from
    /// [`Gmm1d::score`] on the training data).
    pub lower_bound: f64,
    /// EM iterations of the kept start (scikit-learn's `n_iter_`).
    pub n_iter: usize,
    /// Whether the kept start converged before `max_iter` (scikit-learn's `converged_`).
    pub converged: bool,
    /// Number of samples fitted.
    pub n_samples: usize,
}

impl Gmm1d {
    fn from_em(f: &EmFit, n_samples: usize) -> Gmm1d {
        Gmm1d {
            weights: f.weights.clone(),
            means: f.means.clone(),
            variances: f.variances.clone(),
            lower_bound: f.lower_bound,
            n_iter: f.n_iter,
            converged: f.converged,
            n_samples,
        }
    }

    /// Fits a `k`-component mixture to `x` by EM, as scikit-learn's
    /// `GaussianMixture(k, covariance_type="full", n_init, reg_covar, tol, max_iter).fit(x[:, None])`.
    ///
    /// Each of the `n_init` starts runs k-means on the data (k-means++ seeding with
    /// `2 + ⌊ln k⌋` local trials, then Lloyd iterations until the labels repeat or the squared
    /// centre shift is at most `1e-4·var(x)`, at most 300) with its own stream
    /// `seed::rng(params.seed, &[start])`, takes one-hot responsibilities from the labels, and
    /// iterates: E-step `r_ij = w_j N(x_i; μ_j, σ_j²) / Σ_l w_l N(x_i; μ_l, σ_l²)` (log-sum-exp),
    /// lower bound `L = mean_i ln Σ_j w_j N(x_i; μ_j, σ_j²)`, M-step `N_j = Σ_i r_ij + 10·eps`,
    /// `w_j = N_j / Σ N`, `μ_j = Σ_i r_ij x_i / N_j`, `σ_j² = Σ_i r_ij (x_i − μ_j)² / N_j + reg_covar`,
    /// until `|ΔL| < tol`. The start with the greatest final `L` is kept (the first on ties);
    /// components are returned ascending by mean. Data are sorted first, so the result does not
    /// depend on the order of `x`.
    ///
    /// Tolerance against scikit-learn: on data with clear structure, means, standard deviations
    /// and weights within 1 % (the random streams differ, so a start may land on a different
    /// local optimum). With `k = 1` the fit is the sample mean and the population variance plus
    /// `reg_covar` to 1e-12 relative.
    ///
    /// Errors: invalid parameters ([`GmmParams::validate`]); `x.len() < k`
    /// ([`StatsError::TooFewSamples`]); a non-finite value ([`StatsError::NonFinite`]); fewer
    /// than `k` distinct values, or a data range so wide that densities would overflow
    /// ([`StatsError::Undefined`]). All-identical data fit with `k = 1` (variance `reg_covar`)
    /// and are an error for `k > 1`. No result is ever NaN: empty components keep a finite mean
    /// and variance `reg_covar`.
    ///
    /// Cost: `O(n log n)` to sort, then per start `O(n·k)` per EM iteration; starts run in
    /// parallel (rayon) and the result is the same for any number of threads.
    pub fn fit(x: &[f64], params: &GmmParams) -> Result<Gmm1d> {
        params.validate()?;
        let k = params.n_components;
        if x.len() < k {
            return Err(StatsError::TooFewSamples {
                what: "gaussian mixture",
                needed: k,
                got: x.len(),
            });
        }
        check_data(x, params.reg_covar)?;
        let d = Data::new(x.to_vec());
        if d.n_distinct < k {
            return Err(too_few_distinct(k, d.n_distinct));
        }
        let (fits, pick) = fit_many(&d, &[(k, params.seed)], &params.settings());
        Ok(Gmm1d::from_em(&fits[pick[0]], x.len()))
    }

    /// Number of components `k`.
    pub fn n_components(&self) -> usize {
        self.means.len()
    }

    /// Number of free parameters, `3k − 1` in 1-D (k means, k variances, k − 1 weights), as in
    /// scikit-learn's `_n_parameters`.
    pub fn n_parameters(&self) -> usize {
        3 * self.n_components() - 1
    }

    /// Component standard deviations `σ_j`.
    pub fn stds(&self) -> Vec<f64> {
        self.variances.iter().map(|v| v.sqrt()).collect()
    }

    fn model(&self) -> Result<Model> {
        let k = self.means.len();
        let bad = |reason: String| StatsError::InvalidParam {
            name: "gmm model",
            reason,
        };
        if k == 0 || k > KMAX || self.weights.len() != k || self.variances.len() != k {
            return Err(bad(format!(
                "needs 1..={KMAX} components with as many weights, means and variances, got {}, {k}, {}",
                self.weights.len(),
                self.variances.len()
            )));
        }
        let ok = (0..k).all(|j| {
            self.weights[j] > 0.0
                && self.weights[j].is_finite()
                && self.means[j].is_finite()
                && self.variances[j] > 0.0
                && self.variances[j].is_finite()
        });
        if !ok {
            return Err(bad(
                "weights and variances must be finite and > 0, means finite".into(),
            ));
        }
        Ok(Model::new(&self.weights, &self.means, &self.variances))
    }

    fn check_input(&self, x: &[f64]) -> Result<Model> {
        if x.is_empty() {
            return Err(StatsError::TooFewSamples {
                what: "gaussian mixture scoring",
                needed: 1,
                got: 0,
            });
        }
        check_finite("gaussian mixture scoring", x)?;
        self.model()
    }

    /// Mean log-likelihood per sample, `(1/n) Σ_i ln Σ_j w_j N(x_i; μ_j, σ_j²)`: scikit-learn's
    /// `score(x[:, None])` to about 1e-13 relative (summation order differs).
    ///
    /// Errors: empty `x`, a non-finite value, or an invalid model (wrong lengths, more than
    /// [`MAX_COMPONENTS`] components, non-positive weights or variances). Cost `O(n·k)`.
    pub fn score(&self, x: &[f64]) -> Result<f64> {
        let m = self.check_input(x)?;
        Ok(mean_loglik(&m, x))
    }

    /// Bayesian information criterion `−2·score(x)·n + (3k − 1)·ln n`: scikit-learn's
    /// `bic(x[:, None])` to about 1e-13 relative. Lower is better. Errors as [`Gmm1d::score`].
    pub fn bic(&self, x: &[f64]) -> Result<f64> {
        let s = self.score(x)?;
        let n = x.len() as f64;
        Ok(-2.0 * s * n + self.n_parameters() as f64 * n.ln())
    }

    fn log_joint(&self, x: f64, out: &mut [f64]) {
        for (j, o) in out.iter_mut().enumerate() {
            let d = x - self.means[j];
            *o = self.weights[j].ln()
                - 0.5 * (std::f64::consts::TAU * self.variances[j]).ln()
                - 0.5 * d * d / self.variances[j];
        }
    }

    /// Index (into the components ascending by mean) of the component with the greatest
    /// posterior `w_j N(x; μ_j, σ_j²)` for every value: scikit-learn's `predict` up to the
    /// component order (ties go to the lower index). Errors as [`Gmm1d::score`]. Cost `O(n·k)`.
    pub fn predict(&self, x: &[f64]) -> Result<Vec<usize>> {
        self.check_input(x)?;
        let mut lj = vec![0.0; self.n_components()];
        Ok(x.iter()
            .map(|&v| {
                self.log_joint(v, &mut lj);
                let mut best = 0;
                for j in 1..lj.len() {
                    if lj[j] > lj[best] {
                        best = j;
                    }
                }
                best
            })
            .collect())
    }

    /// Posterior probabilities `r_ij = w_j N(x_i; μ_j, σ_j²) / Σ_l w_l N(x_i; μ_l, σ_l²)`, one
    /// row of `k` per value (each row sums to 1): scikit-learn's `predict_proba` up to the
    /// component order, to about 1e-15 absolute. Errors as [`Gmm1d::score`]. Cost `O(n·k)`.
    pub fn predict_proba(&self, x: &[f64]) -> Result<Vec<Vec<f64>>> {
        self.check_input(x)?;
        let k = self.n_components();
        let mut lj = vec![0.0; k];
        Ok(x.iter()
            .map(|&v| {
                self.log_joint(v, &mut lj);
                let mx = lj.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b));
                let e: Vec<f64> = lj.iter().map(|&l| (l - mx).exp()).collect();
                let s: f64 = e.iter().sum();
                e.iter().map(|v| v / s).collect()
            })
            .collect())
    }

    /// Mixture density `p(x) = Σ_j w_j exp(−(x − μ_j)²/(2σ_j²)) / √(2π σ_j²)` at one point (for
    /// plots): `exp(score_samples)` in scikit-learn. 0 for `x = ±∞`, NaN for NaN. Cost `O(k)`.
    pub fn pdf(&self, x: f64) -> f64 {
        (0..self.n_components())
            .map(|j| {
                let v = self.variances[j];
                let d = x - self.means[j];
                self.weights[j] * (-0.5 * d * d / v).exp() / (std::f64::consts::TAU * v).sqrt()
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> Vec<f64> {
        (0..600)
            .map(|i| if i % 3 == 0 { 10.0 } else { 0.0 } + ((i * 37) % 101) as f64 / 50.0)
            .collect()
    }

    #[test]
    fn fit_is_independent_of_input_order() {
        let x = data();
        let mut y = x.clone();
        y.reverse();
        let p = GmmParams {
            n_components: 2,
            seed: 7,
            ..GmmParams::default()
        };
        assert_eq!(
            Gmm1d::fit(&x, &p).expect("valid input"),
            Gmm1d::fit(&y, &p).expect("valid input")
        );
    }

    #[test]
    fn score_bic_predict_are_consistent() {
        let x = data();
        let g = Gmm1d::fit(
            &x,
            &GmmParams {
                n_components: 2,
                ..GmmParams::default()
            },
        )
        .expect("valid input");
        let s = g.score(&x).expect("valid input");
        let direct: f64 = x.iter().map(|&v| g.pdf(v).ln()).sum::<f64>() / x.len() as f64;
        assert!((s - direct).abs() < 1e-12 * direct.abs());
        let n = x.len() as f64;
        assert!(
            (g.bic(&x).expect("valid input") - (-2.0 * direct * n + 5.0 * n.ln())).abs() < 1e-9
        );
        let proba = g.predict_proba(&x).expect("valid input");
        let labels = g.predict(&x).expect("valid input");
        for (row, &l) in proba.iter().zip(&labels) {
            assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(row[l] >= row[1 - l]);
        }
        assert!(g.score(&[]).is_err());
        assert!(g.predict(&[f64::NAN]).is_err());
    }
}
