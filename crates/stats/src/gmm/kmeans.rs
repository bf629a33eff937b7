//! Sorted 1-D data with prefix sums, and k-means on it (k-means++ seeding, Lloyd iterations)
//! as scikit-learn's `KMeans(n_clusters=k, n_init=1)` does it, in `O(k log n)` per step.
//!
//! In 1-D the nearest-centre cells of sorted centres are intervals split at the midpoints, so
//! on sorted data every clustering is a list of `k + 1` boundaries and every cluster sum or
//! squared-distance sum comes from prefix sums. The result is a *partition* (the boundaries);
//! the EM initialisation depends only on it, which lets callers run EM once per distinct
//! partition.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Lloyd iterations at most (scikit-learn's `KMeans` default `max_iter`).
const LLOYD_MAX_ITER: usize = 300;
/// scikit-learn's `KMeans` stopping rule: Lloyd stops when the squared centre shift is at most
/// this times the data variance (`tol=1e-4`, scaled by the mean feature variance).
pub(crate) const SKLEARN_REL_TOL: f64 = 1e-4;

/// Data sorted ascending with prefix sums of `x − shift` and `(x − shift)²`.
#[derive(Debug, Clone)]
pub(crate) struct Data {
    /// The values, ascending.
    pub xs: Vec<f64>,
    /// The number of distinct values.
    pub n_distinct: usize,
    /// Population variance of the values.
    pub var: f64,
    shift: f64,
    p1: Vec<f64>,
    p2: Vec<f64>,
}

impl Data {
    /// Sorts `xs` (finite values) and builds the prefix sums. Cost `O(n log n)`.
    pub fn new(mut xs: Vec<f64>) -> Data {
        xs.sort_unstable_by(f64::total_cmp);
        let n = xs.len();
        let n_distinct = if n == 0 {
            0
        } else {
            1 + xs.windows(2).filter(|w| w[0] != w[1]).count()
        };
        let shift = if n == 0 {
            0.0
        } else {
            xs.iter().sum::<f64>() / n as f64
        };
        let var = if n == 0 {
            0.0
        } else {
            xs.iter().map(|&v| (v - shift) * (v - shift)).sum::<f64>() / n as f64
        };
        let mut p1 = Vec::with_capacity(n + 1);
        let mut p2 = Vec::with_capacity(n + 1);
        let (mut s1, mut s2) = (0.0, 0.0);
        p1.push(0.0);
        p2.push(0.0);
        for &v in &xs {
            let d = v - shift;
            s1 += d;
            s2 += d * d;
            p1.push(s1);
            p2.push(s2);
        }
        Data {
            xs,
            n_distinct,
            var,
            shift,
            p1,
            p2,
        }
    }

    /// `Σ_{i∈[a,b)} (x_i − c)²`, clamped at 0.
    fn cost(&self, a: usize, b: usize, c: f64) -> f64 {
        let cs = c - self.shift;
        let s1 = self.p1[b] - self.p1[a];
        let s2 = self.p2[b] - self.p2[a];
        (s2 - 2.0 * cs * s1 + (b - a) as f64 * cs * cs).max(0.0)
    }

    /// Mean of `x` over `[a, b)` (non-empty).
    fn mean(&self, a: usize, b: usize) -> f64 {
        self.shift + (self.p1[b] - self.p1[a]) / (b - a) as f64
    }

    /// Boundaries `b[0] = 0 ≤ … ≤ b[k] = n` of the nearest-centre cells of the ascending
    /// `centres`: cluster `j` is `xs[b[j]..b[j+1]]` (a point on a midpoint goes up).
    pub fn boundaries(&self, centres: &[f64]) -> Vec<usize> {
        let mut b = Vec::with_capacity(centres.len() + 1);
        b.push(0);
        for w in centres.windows(2) {
            let mid = 0.5 * w[0] + 0.5 * w[1];
            b.push(self.xs.partition_point(|&v| v < mid));
        }
        b.push(self.xs.len());
        b
    }

    fn potential(&self, centres: &[f64]) -> f64 {
        let b = self.boundaries(centres);
        (0..centres.len())
            .map(|j| self.cost(b[j], b[j + 1], centres[j]))
            .sum()
    }

    /// The point farthest from its nearest centre (ascending `centres`).
    fn farthest(&self, centres: &[f64], b: &[usize]) -> f64 {
        let mut best = (f64::NEG_INFINITY, self.xs[0]);
        for j in 0..centres.len() {
            if b[j] < b[j + 1] {
                for v in [self.xs[b[j]], self.xs[b[j + 1] - 1]] {
                    let d = (v - centres[j]).abs();
                    if d > best.0 {
                        best = (d, v);
                    }
                }
            }
        }
        best.1
    }

    /// The point where the cumulative squared distance to the nearest centre first reaches
    /// `u` (scikit-learn's `searchsorted(cumsum(closest_dist_sq), u)`).
    fn sample(&self, centres: &[f64], u: f64) -> f64 {
        let b = self.boundaries(centres);
        let mut acc = 0.0;
        for j in 0..centres.len() {
            let (a, e, c) = (b[j], b[j + 1], centres[j]);
            let seg = self.cost(a, e, c);
            if seg > 0.0 && acc + seg >= u {
                let target = u - acc;
                let (mut lo, mut hi) = (0, e - a);
                while lo < hi {
                    let mid = lo + (hi - lo) / 2;
                    if self.cost(a, a + mid + 1, c) < target {
                        lo = mid + 1;
                    } else {
                        hi = mid;
                    }
                }
                return self.xs[(a + lo).min(e - 1)];
            }
            acc += seg;
        }
        self.farthest(centres, &b)
    }
}

fn insert_sorted(centres: &[f64], v: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(centres.len() + 1);
    let at = centres.partition_point(|&c| c < v);
    out.extend_from_slice(&centres[..at]);
    out.push(v);
    out.extend_from_slice(&centres[at..]);
    out
}

/// Greedy k-means++ seeding (scikit-learn's `_kmeans_plusplus`, `2 + ⌊ln k⌋` local trials):
/// the first centre uniformly at random, each next one the best of the trials drawn with
/// probability proportional to the squared distance to the nearest centre. Returns the
/// centres ascending.
fn plusplus(d: &Data, k: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let n = d.xs.len();
    let mut centres = vec![d.xs[rng.random_range(0..n)]];
    let mut pot = d.potential(&centres);
    let trials = 2 + (k as f64).ln() as usize;
    for _ in 1..k {
        let mut best: Option<(f64, Vec<f64>)> = None;
        for _ in 0..trials {
            let u: f64 = rng.random::<f64>() * pot;
            let cand = if pot > 0.0 && pot.is_finite() {
                d.sample(&centres, u)
            } else {
                d.farthest(&centres, &d.boundaries(&centres))
            };
            let cs = insert_sorted(&centres, cand);
            let pc = d.potential(&cs);
            if best.as_ref().is_none_or(|(bp, _)| pc < *bp) {
                best = Some((pc, cs));
            }
        }
        if let Some((bp, cs)) = best {
            pot = bp;
            centres = cs;
        }
    }
    centres
}

/// Lloyd iterations as scikit-learn's `_kmeans_single_lloyd`: stop when the labels repeat
/// (strict convergence) or the squared centre shift is at most `rel_tol·var(x)` (scikit-learn:
/// [`SKLEARN_REL_TOL`]; 0 runs until the labels repeat), at most 300 iterations; then label
/// by the final centres. An empty cluster is moved to the point farthest from its centre.
/// Returns the cluster boundaries.
fn lloyd(d: &Data, mut c: Vec<f64>, rel_tol: f64) -> Vec<usize> {
    let tol = rel_tol * d.var;
    let k = c.len();
    let mut old: Option<Vec<usize>> = None;
    for _ in 0..LLOYD_MAX_ITER {
        let b = d.boundaries(&c);
        if old.as_ref() == Some(&b) {
            return b;
        }
        let mut cn = c.clone();
        let mut empty = false;
        for j in 0..k {
            if b[j] < b[j + 1] {
                cn[j] = d.mean(b[j], b[j + 1]);
            } else {
                empty = true;
            }
        }
        if empty {
            // Move empty clusters to the points farthest from their centres, one point each
            // (scikit-learn's `_relocate_empty_clusters`; in 1-D the candidates are the ends of
            // the non-empty clusters).
            let mut far: Vec<(f64, f64)> = Vec::new();
            for j in 0..k {
                if b[j] < b[j + 1] {
                    for v in [d.xs[b[j]], d.xs[b[j + 1] - 1]] {
                        far.push(((v - c[j]).abs(), v));
                    }
                }
            }
            far.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.total_cmp(&b.1)));
            far.dedup_by(|a, b| a.1 == b.1);
            let mut next = far.iter();
            for j in 0..k {
                if b[j] == b[j + 1]
                    && let Some(&(_, v)) = next.next()
                {
                    cn[j] = v;
                }
            }
        }
        let shift: f64 = c.iter().zip(&cn).map(|(a, b)| (a - b) * (a - b)).sum();
        cn.sort_unstable_by(f64::total_cmp);
        c = cn;
        if shift <= tol && !empty {
            break;
        }
        old = Some(b);
    }
    d.boundaries(&c)
}

/// k-means partition of `d` into `k` clusters (`1 ≤ k ≤ d.n_distinct`): boundaries
/// `b[0] = 0 ≤ … ≤ b[k] = n`; `rel_tol` as in [`lloyd`]. Cost `O(k² log n)` per seeding step
/// and `O(k log n)` per Lloyd iteration, after the `O(n log n)` of [`Data::new`].
pub(crate) fn kmeans(d: &Data, k: usize, rng: &mut ChaCha8Rng, rel_tol: f64) -> Vec<usize> {
    let centres = plusplus(d, k, rng);
    lloyd(d, centres, rel_tol)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn separates_clear_clusters() {
        let mut xs = Vec::new();
        for i in 0..100 {
            xs.push(i as f64 * 0.01);
            xs.push(10.0 + i as f64 * 0.01);
            xs.push(20.0 + i as f64 * 0.01);
        }
        let d = Data::new(xs);
        for s in 0..20 {
            let b = kmeans(&d, 3, &mut ChaCha8Rng::seed_from_u64(s), SKLEARN_REL_TOL);
            assert_eq!(b, vec![0, 100, 200, 300]);
        }
    }

    #[test]
    fn cost_and_sample_agree_with_direct_sums() {
        let d = Data::new(vec![3.0, 1.0, 2.0, 7.0, 8.0]);
        assert_eq!(d.xs, vec![1.0, 2.0, 3.0, 7.0, 8.0]);
        assert!((d.cost(0, 5, 4.0) - (9.0 + 4.0 + 1.0 + 9.0 + 16.0)).abs() < 1e-12);
        assert_eq!(d.boundaries(&[2.0, 7.5]), vec![0, 3, 5]);
        // Cumulative distances to centre 2.0 over [1, 2, 3]: 1, 1, 2; then 7.5: 0.25, 0.25.
        assert_eq!(d.sample(&[2.0, 7.5], 0.5), 1.0);
        assert_eq!(d.sample(&[2.0, 7.5], 1.5), 3.0);
        assert_eq!(d.sample(&[2.0, 7.5], 2.1), 7.0);
        assert_eq!(d.n_distinct, 5);
    }

    #[test]
    fn handles_duplicates() {
        let d = Data::new(vec![1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 5.0]);
        assert_eq!(d.n_distinct, 3);
        for s in 0..20 {
            let b = kmeans(&d, 3, &mut ChaCha8Rng::seed_from_u64(s), SKLEARN_REL_TOL);
            assert_eq!(b, vec![0, 4, 6, 7]);
        }
    }
}
