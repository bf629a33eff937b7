//! EM from a k-means partition, and batches of fits that share EM runs across identical
//! initial partitions.

use std::collections::HashMap;

use rayon::prelude::*;

use super::kernel::{KMAX, Model, Suff, pass};
use super::kmeans::{Data, SKLEARN_REL_TOL, kmeans};
use crate::seed;

/// scikit-learn adds `10·eps` to every component's responsibility sum so an empty component
/// never divides by zero.
const NK_GUARD: f64 = 10.0 * f64::EPSILON;

/// The EM settings shared by every start.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settings {
    pub n_init: usize,
    pub reg_covar: f64,
    pub tol: f64,
    pub max_iter: usize,
    pub sklearn_kmeans_max_n: usize,
}

/// One EM run's result, components ascending by mean.
#[derive(Debug, Clone)]
pub(crate) struct EmFit {
    pub weights: Vec<f64>,
    pub means: Vec<f64>,
    pub variances: Vec<f64>,
    pub lower_bound: f64,
    pub n_iter: usize,
    pub converged: bool,
}

impl EmFit {
    pub fn model(&self) -> Model {
        Model::new(&self.weights, &self.means, &self.variances)
    }
}

/// Mean log-likelihood per sample of `xs` under `m` (`xs` non-empty).
pub(crate) fn mean_loglik(m: &Model, xs: &[f64]) -> f64 {
    pass::<false>(m, xs).ll / xs.len() as f64
}

/// The M-step (scikit-learn's `_estimate_gaussian_parameters` + weight normalisation) from the
/// sufficient statistics about the old means: `N_j = Σr + 10·eps`, `μ_j = μ_old + Σr·d/N_j`,
/// `σ_j² = Σr·(x − μ_j)²/N_j + reg_covar` with `Σr·(x − μ_j)² = Σr·d² − 2δΣr·d + δ²Σr`,
/// `δ = μ_j − μ_old`, `w_j = N_j / Σ N`.
fn m_step(k: usize, s: &Suff, reg: f64, w: &mut [f64], mu: &mut [f64], var: &mut [f64]) {
    let mut total = 0.0;
    for j in 0..k {
        let nk = s.r[j] + NK_GUARD;
        let delta = s.d1[j] / nk;
        let ss = s.d2[j] - 2.0 * delta * s.d1[j] + delta * delta * s.r[j];
        mu[j] += delta;
        var[j] = ss.max(0.0) / nk + reg;
        w[j] = nk;
        total += nk;
    }
    for wj in w.iter_mut().take(k) {
        *wj /= total;
    }
}

/// EM as scikit-learn's `GaussianMixture.fit` for one start: responsibilities one-hot from the
/// partition `b` of the ascending `xs`, initial parameters from them (`weights = N_j / n`),
/// then E/M iterations until the change of the mean log-likelihood (computed in the E-step,
/// before the M-step) is below `tol`, at most `max_iter` iterations.
pub(crate) fn em(xs: &[f64], b: &[usize], s: &Settings) -> EmFit {
    let n = xs.len();
    let k = (b.len() - 1).min(KMAX);
    let (mut w, mut mu, mut var) = (vec![0.0; k], vec![0.0; k], vec![0.0; k]);
    for j in 0..k {
        let seg = &xs[b[j]..b[j + 1]];
        let nk = seg.len() as f64 + NK_GUARD;
        let mean = if seg.is_empty() {
            xs[b[j].min(n - 1)]
        } else {
            seg.iter().sum::<f64>() / nk
        };
        let ss: f64 = seg.iter().map(|&v| (v - mean) * (v - mean)).sum();
        w[j] = nk / n as f64;
        mu[j] = mean;
        var[j] = ss / nk + s.reg_covar;
    }
    let mut lower_bound = f64::NEG_INFINITY;
    let (mut n_iter, mut converged) = (0, false);
    for it in 1..=s.max_iter {
        let prev = lower_bound;
        let st = pass::<true>(&Model::new(&w, &mu, &var), xs);
        lower_bound = st.ll / n as f64;
        m_step(k, &st, s.reg_covar, &mut w, &mut mu, &mut var);
        n_iter = it;
        if (lower_bound - prev).abs() < s.tol {
            converged = true;
            break;
        }
    }
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &c| mu[a].total_cmp(&mu[c]).then(a.cmp(&c)));
    EmFit {
        weights: order.iter().map(|&j| w[j]).collect(),
        means: order.iter().map(|&j| mu[j]).collect(),
        variances: order.iter().map(|&j| var[j]).collect(),
        lower_bound,
        n_iter,
        converged,
    }
}

/// Runs a batch of fits `(k, seed)` on `d`, each as `Gmm1d::fit` with `n_components = k` and
/// `seed`: start `i` is initialised by k-means with stream `seed::rng(seed, &[i])`, and the
/// start with the greatest final lower bound wins (the first on ties). Lloyd iterations stop by
/// scikit-learn's rule when `n ≤ sklearn_kmeans_max_n` and run until the labels repeat
/// otherwise. EM runs once per
/// distinct (k, partition); all k-means runs and all EM runs go in parallel and are collected
/// in index order, so results do not depend on the thread count.
///
/// Returns the distinct EM results and, per fit, the index of its winning result.
pub(crate) fn fit_many(d: &Data, fits: &[(usize, u64)], s: &Settings) -> (Vec<EmFit>, Vec<usize>) {
    let rel_tol = if d.xs.len() <= s.sklearn_kmeans_max_n {
        SKLEARN_REL_TOL
    } else {
        0.0
    };
    let parts: Vec<Vec<Vec<usize>>> = fits
        .par_iter()
        .map(|&(k, sd)| {
            (0..s.n_init)
                .into_par_iter()
                .map(|i| kmeans(d, k, &mut seed::rng(sd, &[i as u64]), rel_tol))
                .collect()
        })
        .collect();
    let mut index: HashMap<&[usize], usize> = HashMap::new();
    let mut unique: Vec<&[usize]> = Vec::new();
    let ids: Vec<Vec<usize>> = parts
        .iter()
        .map(|starts| {
            starts
                .iter()
                .map(|b| {
                    *index.entry(b.as_slice()).or_insert_with(|| {
                        unique.push(b.as_slice());
                        unique.len() - 1
                    })
                })
                .collect()
        })
        .collect();
    let results: Vec<EmFit> = unique.par_iter().map(|b| em(&d.xs, b, s)).collect();
    let pick = ids
        .iter()
        .map(|starts| {
            let mut best = starts[0];
            for &u in &starts[1..] {
                if results[u].lower_bound > results[best].lower_bound {
                    best = u;
                }
            }
            best
        })
        .collect();
    (results, pick)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_component_is_the_sample_moments() {
        let xs: Vec<f64> = (0..1001)
            .map(|i| ((i * 7919) % 1009) as f64 / 17.0 + 3.0)
            .collect();
        let d = Data::new(xs.clone());
        let f = em(
            &d.xs,
            &[0, xs.len()],
            &Settings {
                n_init: 1,
                reg_covar: 1e-6,
                tol: 1e-3,
                max_iter: 200,
                sklearn_kmeans_max_n: 0,
            },
        );
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = xs.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
        assert!((f.means[0] - mean).abs() < 1e-12 * mean.abs());
        assert!((f.variances[0] - var - 1e-6).abs() < 1e-12 * var);
        assert_eq!(f.weights, vec![1.0]);
        assert!(f.converged);
        assert_eq!(f.n_iter, 2);
    }
}
